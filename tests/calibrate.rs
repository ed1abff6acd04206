//! `cncsim calibrate`: a known truth is recovered from its own measured trace, the answer is the
//! same with one thread or two, `--write` puts it into the scenario, a calibration killed midway
//! resumes to the uninterrupted result, and a bad spec is refused with its file, line and column
//! (exit 2) before anything runs.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The X gain of the default scenario, and the one the "real machine" runs.
const FILE_KP: f64 = 19800.0;
const TRUE_KP: f64 = 7000.0;

/// A short move on the XYZ table: 2 mm along X in 0.4 s, then 0.5 mm along Y.
fn short_scenario(dir: &Path, name: &str, kp: f64) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenarios/xyz_circle_5mms.toml"))
        .unwrap()
        .replace("../models/", &format!("{}/models/", root().display()))
        .replace(
            "circle = { center_mm = [100.0, 100.0], radius_mm = 30.0, start_angle_deg = 0.0, direction = \"ccw\", z_mm = 0.0 }",
            "polyline = { points_mm = [[100.0, 100.0, 0.0], [102.0, 100.0, 0.0], [102.0, 100.5, 0.0]] }",
        )
        .replace(
            &format!("axes.x = {{ kp = {FILE_KP:.1},"),
            &format!("axes.x = {{ kp = {kp:.1},"),
        )
        .replace("decimation = 4", "decimation = 1")
        .replace("rrd = true", "rrd = false")
        .split("[expect]")
        .next()
        .unwrap()
        .to_string();
    assert!(
        text.contains(&format!("kp = {kp:.1}")),
        "the scenario template changed"
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

fn cncsim(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

fn fresh_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cncsim_calibrate_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The "measured" trace: the truth run's X position, renamed as a logger would write it.
fn measured_trace(dir: &Path) -> PathBuf {
    short_scenario(dir, "truth", TRUE_KP);
    let out = cncsim(&["run", "truth.toml", "--out", "truth"], dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut reader = csv::Reader::from_path(dir.join("truth/trace.csv")).unwrap();
    let headers = reader.headers().unwrap().clone();
    let t = headers.iter().position(|h| h == "t_s").expect("t_s column");
    let x = headers
        .iter()
        .position(|h| h == "x_actual_mm")
        .expect("x_actual_mm column");
    let mut text = String::from("time_s,x_mm\n");
    for row in reader.records() {
        let row = row.unwrap();
        text += &format!("{},{}\n", &row[t], &row[x]);
    }
    let path = dir.join("measured.csv");
    std::fs::write(&path, text).unwrap();
    path
}

fn spec(max_evaluations: usize) -> String {
    format!(
        r#"name = "kp_from_trace"
scenario = "model.toml"
[parameters]
"controller.axes.x.kp" = {{ min = 2000.0, max = 40000.0, scale = "log", start = {FILE_KP} }}
[[target]]
trace = "measured.csv"
time_column = "time_s"
columns = {{ x_actual_mm = "x_mm" }}
tolerance_mm = 0.0001
max_shift_s = 0.0
[optimizer]
seed = 3
population = 6
max_evaluations = {max_evaluations}
sigma = 0.3
"#
    )
}

fn evaluations(dir: &Path, out: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join(out).join("evaluations.json")).unwrap())
        .unwrap()
}

#[test]
fn recovers_a_known_gain_from_a_measured_trace_and_writes_it_back() {
    let dir = fresh_dir("recover");
    measured_trace(&dir);
    short_scenario(&dir, "model", FILE_KP);
    std::fs::write(dir.join("spec.toml"), spec(96)).unwrap();
    let out = cncsim(&["calibrate", "spec.toml", "--out", "cal", "--write"], &dir);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let result = evaluations(&dir, "cal");
    let best = &result["best"];
    let kp = best["values"][0].as_f64().unwrap();
    assert!(
        (kp / TRUE_KP - 1.0).abs() < 0.02,
        "recovered kp {kp}, truth {TRUE_KP} (started at {FILE_KP})"
    );
    // The trace misfit at the truth is zero; the best candidate comes close to it.
    let rms = best["results"][0].as_f64().unwrap();
    assert!(rms < 1e-4, "RMS {rms} mm at the best candidate");
    for file in ["report.md", "evaluations.csv", "convergence.png"] {
        assert!(dir.join("cal").join(file).is_file(), "{file} missing");
    }
    assert!(stdout.contains("controller.axes.x.kp"), "{stdout}");
    // --write: the scenario now carries the recovered gain and still loads.
    let written = std::fs::read_to_string(dir.join("model.toml")).unwrap();
    let scenario = cncsim::scenario::Scenario::parse(&dir.join("model.toml"), &written).unwrap();
    let _ = scenario;
    let doc: toml::Table = written.parse().unwrap();
    let written_kp = doc["controller"]["axes"]["x"]["kp"].as_float().unwrap();
    assert!(
        (written_kp / kp - 1.0).abs() < 1e-5,
        "written {written_kp}, best {kp}"
    );
    assert!(
        written.contains("# The bundled default"),
        "comments are kept"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_same_candidates_with_one_thread_or_two() {
    let dir = fresh_dir("threads");
    measured_trace(&dir);
    short_scenario(&dir, "model", FILE_KP);
    std::fs::write(dir.join("spec.toml"), spec(12)).unwrap();
    for (jobs, out) in [("1", "one"), ("2", "two")] {
        let run = cncsim(
            &["calibrate", "spec.toml", "--jobs", jobs, "--out", out],
            &dir,
        );
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    let (one, two) = (evaluations(&dir, "one"), evaluations(&dir, "two"));
    assert_eq!(one["evaluations"], two["evaluations"]);
    assert_eq!(one["best"], two["best"]);
    // The start point, then two generations of six; the polish after them.
    let searched = one["evaluations"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["generation"].as_u64().unwrap() <= 2)
        .count();
    assert_eq!(searched, 13);
    // Scratch runs are removed; the predictions (the target scenario at the best values) stay.
    assert!(!dir.join("one/scratch").exists());
    assert!(dir.join("one/predictions").is_dir());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The complete lines of a calibration's evaluation log after its header.
fn logged(dir: &Path, out: &str) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join(out).join("evaluation_log.jsonl")).unwrap();
    let mut lines: Vec<String> = text.split_inclusive('\n').map(String::from).collect();
    if lines.last().is_some_and(|l| !l.ends_with('\n')) {
        lines.pop();
    }
    lines.split_off(1)
}

fn logged_values(line: &str) -> Value {
    serde_json::from_str::<Value>(line).unwrap()["values"].clone()
}

#[test]
fn a_calibration_killed_midway_resumes_to_the_uninterrupted_result() {
    let dir = fresh_dir("resume");
    measured_trace(&dir);
    short_scenario(&dir, "model", FILE_KP);
    std::fs::write(dir.join("spec.toml"), spec(24)).unwrap();
    let whole = cncsim(
        &["calibrate", "spec.toml", "--jobs", "2", "--out", "whole"],
        &dir,
    );
    assert!(
        whole.status.success(),
        "{}",
        String::from_utf8_lossy(&whole.stderr)
    );

    // The same calibration, killed (SIGKILL: nothing of it runs after) once it has logged 8
    // evaluations.
    let mut child = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(["calibrate", "spec.toml", "--jobs", "2", "--out", "killed"])
        .current_dir(&dir)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let log = dir.join("killed/evaluation_log.jsonl");
    let started = std::time::Instant::now();
    while std::fs::read_to_string(&log).map_or(0, |t| t.lines().count()) < 9 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the calibration ended before it could be killed"
        );
        assert!(started.elapsed().as_secs() < 600, "no evaluation logged");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let before = logged(&dir, "killed");
    assert!(before.len() >= 8);
    // A line cut short by the kill (written here to be sure of one) is dropped on resume.
    let mut text = std::fs::read_to_string(&log).unwrap();
    if !text.ends_with('\n') {
        text.push('\n');
    }
    std::fs::write(&log, text + "{\"values\":[4").unwrap();

    let resumed = cncsim(
        &[
            "calibrate",
            "spec.toml",
            "--jobs",
            "2",
            "--out",
            "killed",
            "--resume",
        ],
        &dir,
    );
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!("resuming: {} evaluations", before.len())),
        "{stderr}"
    );
    // The result of the uninterrupted calibration, every candidate alike.
    let (a, b) = (evaluations(&dir, "whole"), evaluations(&dir, "killed"));
    assert_eq!(a["evaluations"], b["evaluations"]);
    assert_eq!(a["best"], b["best"]);
    assert_eq!(a["sensitivity"], b["sensitivity"]);
    assert_eq!(a["recalled"], 0);
    assert!(b["recalled"].as_u64().unwrap() >= before.len() as u64);
    // The candidates logged before the kill were not run again: the log goes on after them
    // with other candidates only.
    let after = logged(&dir, "killed");
    assert_eq!(after[..before.len()], before[..]);
    let earlier: Vec<Value> = before.iter().map(|l| logged_values(l)).collect();
    for line in &after[before.len()..] {
        assert!(
            !earlier.contains(&logged_values(line)),
            "run again after the resume: {line}"
        );
    }
    assert!(b["evaluations"].as_array().unwrap().len() > before.len());

    // Another calibration's log is refused by name.
    std::fs::write(
        dir.join("spec.toml"),
        spec(24).replace("sigma = 0.3", "sigma = 0.2"),
    )
    .unwrap();
    let other = cncsim(
        &["calibrate", "spec.toml", "--out", "killed", "--resume"],
        &dir,
    );
    let stderr = String::from_utf8_lossy(&other.stderr);
    assert_eq!(other.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("evaluation_log.jsonl:1:1") && stderr.contains("another calibration's"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_bad_spec_is_refused_with_its_location_before_anything_runs() {
    let dir = fresh_dir("bad");
    short_scenario(&dir, "model", FILE_KP);
    let good = "name = \"t\"\nscenario = \"model.toml\"\n[parameters]\n\"controller.axes.x.kp\" = { min = 2000.0, max = 40000.0 }\n[[target]]\nmetric = \"axes.x.max_following_error_mm\"\nmeasured = 0.01\ntolerance = 0.1\n";
    let cases: [(&str, String, &str); 6] = [
        (
            "unknown key",
            good.replace("tolerance = 0.1", "tolerance = 0.1\nweight = 2"),
            "spec.toml:9:1",
        ),
        (
            "empty range",
            good.replace("max = 40000.0", "max = 1000.0"),
            "spec.toml:4:",
        ),
        (
            "unknown scenario key",
            good.replace("controller.axes.x.kp", "controller.axes.x.kq"),
            "kq",
        ),
        (
            "missing scenario",
            good.replace("model.toml", "nowhere.toml"),
            "nowhere.toml",
        ),
        (
            "a metric no run reports",
            good.replace(
                "axes.x.max_following_error_mm",
                "axes.x.max_folowing_error_mm",
            ),
            "axes.x.max_folowing_error_mm",
        ),
        (
            "a zero measurement",
            good.replace("measured = 0.01", "measured = 0.0"),
            "expected measured ≠ 0",
        ),
    ];
    for (what, text, expected) in cases {
        std::fs::write(dir.join("spec.toml"), &text).unwrap();
        let out = cncsim(&["calibrate", "spec.toml", "--out", "cal"], &dir);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{what}: {stderr}");
        assert!(
            stderr.contains(expected),
            "{what}: expected {expected:?} in\n{stderr}"
        );
        assert!(!stderr.contains("panicked"), "{what}: {stderr}");
        assert!(
            !dir.join("cal/evaluations.json").exists(),
            "{what}: nothing is evaluated"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The bundled specs load: their keys, ranges, targets and prediction scenarios are valid.
#[test]
fn the_bundled_calibration_specs_load() {
    let dir = root().join("calibrations");
    let mut specs: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    specs.sort();
    assert!(specs.len() >= 2, "{specs:?}");
    for spec in specs {
        let cal = cncsim::sweep::calibrate::Calibration::load(&spec)
            .unwrap_or_else(|e| panic!("{}: {e}", spec.display()));
        assert!(!cal.parameters.is_empty(), "{}", spec.display());
    }
}
