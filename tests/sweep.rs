//! Sweeps: parallel and deterministic (the same rows with one thread or two, and from shards
//! merged), a failing run is a row with its error, Ctrl-C keeps the finished rows, plans are
//! made once per distinct setpoint stream, and the Ray driver's merged result equals the
//! single-machine sweep (when Ray is installed; required under CNCSIM_REQUIRE_ORACLES=1).

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A short scenario on the XYZ table (0.3 s of motion) and a sweep over it.
fn setup(dir: &Path, extra_variant: &str) -> PathBuf {
    let scenario = std::fs::read_to_string(root().join("scenarios/xyz_circle_5mms.toml"))
        .unwrap()
        .replace("../models/", &format!("{}/models/", root().display()))
        .replace(
            "circle = { center_mm = [100.0, 100.0], radius_mm = 30.0, start_angle_deg = 0.0, direction = \"ccw\", z_mm = 0.0 }",
            "polyline = { points_mm = [[100.0, 100.0, 0.0], [101.5, 100.0, 0.0], [101.5, 100.5, 0.0]] }",
        )
        .split("[expect]")
        .next()
        .unwrap()
        .to_string();
    std::fs::write(dir.join("short.toml"), &scenario).unwrap();
    std::fs::write(
        dir.join("other.toml"),
        scenario
            .replace("name = \"xyz_circle_5mms\"", "name = \"other\"")
            .replace("feed_mm_s = 5.0", "feed_mm_s = 10.0"),
    )
    .unwrap();
    let sweep = format!(
        r#"name = "t"
scenarios = ["short.toml", "other.toml"]
baseline = "pid"
[variants]
pid = []
slow = ["controller.axes.x.kp=9900.0"]
{extra_variant}
[grid]
"timing.servo_period_ms" = [0.5, 1.0]
[report]
metrics = ["max_contour_error_mm", "axes.x.max_following_error_mm"]
"#
    );
    let path = dir.join("t_sweep.toml");
    std::fs::write(&path, sweep).unwrap();
    path
}

fn cncsim(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// The rows of a results.json with the figures that vary from run to run (wall time) removed.
fn rows(out: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(out.join("results.json")).unwrap();
    let mut json: Value = serde_json::from_str(&text).unwrap();
    let rows = json["rows"].as_array_mut().unwrap();
    for r in rows.iter_mut() {
        let r = r.as_object_mut().unwrap();
        r.remove("wall_time_s");
        let m = r["metrics"].as_object_mut().unwrap();
        m.remove("wall_time_s");
        m.remove("real_time_factor");
    }
    rows.clone()
}

#[test]
fn one_thread_two_threads_and_merged_shards_give_the_same_rows() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sweep = setup(d, "broken = [\"controller.axes.x.kp=-1\"]");
    let sweep = sweep.to_str().unwrap();
    let one = cncsim(&["sweep", sweep, "--jobs", "1", "--out", "one"], d);
    let stderr = String::from_utf8_lossy(&one.stderr);
    // The broken variant's runs fail with their reason; the sweep goes on and exits 1.
    assert_eq!(one.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("2 scenarios × 3 variants × 2 points"),
        "{stderr}"
    );
    // Plans: 2 scenarios × 2 servo periods; the variants share them.
    assert!(stderr.contains("4 plans made for 12 runs"), "{stderr}");
    let a = rows(&d.join("one"));
    assert_eq!(a.len(), 12);
    let broken: Vec<&Value> = a.iter().filter(|r| r["variant"] == "broken").collect();
    assert_eq!(broken.len(), 4);
    for r in &broken {
        let e = r["error"].as_str().unwrap();
        assert!(e.contains("gains must be from 0 to"), "{e}");
    }
    assert!(a
        .iter()
        .filter(|r| r["variant"] != "broken")
        .all(|r| r["completed"] == true));

    let two = cncsim(&["sweep", sweep, "--jobs", "2", "--out", "two"], d);
    assert_eq!(two.status.code(), Some(1));
    assert!(a == rows(&d.join("two")), "two threads changed the rows");

    for k in ["1/3", "2/3", "3/3"] {
        let out = format!("shard{}", &k[..1]);
        let s = cncsim(&["sweep", sweep, "--shard", k, "--out", &out], d);
        assert!(s.status.code() == Some(0) || s.status.code() == Some(1));
    }
    let merged = cncsim(
        &["merge", "shard1", "shard2", "shard3", "--out", "merged"],
        d,
    );
    assert!(
        merged.status.success(),
        "{}",
        String::from_utf8_lossy(&merged.stderr)
    );
    let merged_rows = rows(&d.join("merged"));
    assert!(
        a == merged_rows,
        "merged shards differ from the sweep: indexes {:?}",
        merged_rows
            .iter()
            .map(|r| r["index"].clone())
            .collect::<Vec<_>>()
    );
    // Overlapping shards are refused.
    let twice = cncsim(&["merge", "shard1", "shard1", "--out", "bad"], d);
    assert_eq!(twice.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&twice.stderr).contains("overlapping shards"));

    // The summary marks the best and gives ratios to the baseline; the CSV has every metric.
    let summary = std::fs::read_to_string(d.join("one/summary.md")).unwrap();
    assert!(
        summary.contains("(×1.000)") && summary.contains("**"),
        "{summary}"
    );
    assert!(summary.contains("## Wins"));
    let csv = std::fs::read_to_string(d.join("one/results.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(
        header.starts_with("index,scenario,variant,point,timing.servo_period_ms,completed"),
        "{header}"
    );
    assert!(header.contains("axes.y.rms_torque_nm"));
    assert_eq!(csv.lines().count(), 13);
    assert!(d.join("one/plot_max_contour_error_mm.png").is_file());
    assert!(d
        .join("one/plot_max_contour_error_mm_vs_timing.servo_period_ms.png")
        .is_file());
}

#[test]
fn ctrl_c_keeps_the_finished_rows() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sweep = setup(d, "");
    // Many runs, one at a time: interrupt after the first few.
    let text = std::fs::read_to_string(&sweep).unwrap().replace(
        "[0.5, 1.0]",
        "[0.5, 1.0, 2.0, 0.5, 1.0, 2.0, 0.5, 1.0, 2.0, 0.5, 1.0, 2.0]",
    );
    std::fs::write(&sweep, text).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args([
            "sweep",
            sweep.to_str().unwrap(),
            "--jobs",
            "1",
            "--out",
            "o",
        ])
        .current_dir(d)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until some runs are done, then interrupt.
    let started = std::time::Instant::now();
    while !d.join("o/runs").is_dir() || std::fs::read_dir(d.join("o/runs")).unwrap().count() < 3 {
        assert!(started.elapsed().as_secs() < 120, "no runs after 120 s");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    // SAFETY: sending a signal to our own child process.
    unsafe {
        libc::kill(child.id() as i32, libc::SIGINT);
    }
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted:"), "{stderr}");
    let r = rows(&d.join("o"));
    assert!(!r.is_empty() && r.len() < 48, "{} rows", r.len());
    // Rows in the sweep's order, from the first on.
    for (i, row) in r.iter().enumerate() {
        assert_eq!(row["index"].as_u64(), Some(i as u64));
    }
}

#[test]
fn a_sweep_killed_and_resumed_gives_the_rows_of_one_never_killed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sweep = setup(d, "");
    let text = std::fs::read_to_string(&sweep)
        .unwrap()
        .replace("[0.5, 1.0]", "[0.5, 1.0, 2.0, 0.5, 1.0, 2.0]");
    std::fs::write(&sweep, text).unwrap();
    let sweep = sweep.to_str().unwrap();
    let whole = cncsim(&["sweep", sweep, "--jobs", "2", "--out", "whole"], d);
    assert_eq!(
        whole.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&whole.stderr)
    );
    // Killed outright (SIGKILL: nothing written at the end) once a few runs have records.
    let mut child = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(["sweep", sweep, "--jobs", "1", "--out", "o"])
        .current_dir(d)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let records = || -> Vec<PathBuf> {
        let Ok(entries) = std::fs::read_dir(d.join("o/runs")) else {
            return Vec::new();
        };
        entries
            .map(|e| e.unwrap().path().join("result.json"))
            .filter(|p| p.is_file())
            .collect()
    };
    let started = std::time::Instant::now();
    while records().len() < 3 {
        assert!(started.elapsed().as_secs() < 120, "no records after 120 s");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!d.join("o/results.json").exists());
    let finished: Vec<(PathBuf, std::time::SystemTime)> = records()
        .into_iter()
        .map(|p| {
            let metrics = p.with_file_name("metrics.json");
            let modified = std::fs::metadata(&metrics).unwrap().modified().unwrap();
            (metrics, modified)
        })
        .collect();
    assert!(
        finished.len() >= 3 && finished.len() < 24,
        "{}",
        finished.len()
    );
    std::thread::sleep(std::time::Duration::from_millis(50));
    let resumed = cncsim(
        &["sweep", sweep, "--jobs", "2", "--out", "o", "--resume"],
        d,
    );
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert_eq!(resumed.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "resuming: {} of 24 runs have a record",
            finished.len()
        )),
        "{stderr}"
    );
    assert_eq!(rows(&d.join("o")), rows(&d.join("whole")));
    // The runs finished before the kill were not run again.
    for (metrics, modified) in &finished {
        let now = std::fs::metadata(metrics).unwrap().modified().unwrap();
        assert_eq!(now, *modified, "{} was written again", metrics.display());
    }
    // Resuming another sweep's folder is refused by name (exit 2); nothing is run.
    let other = std::fs::read_to_string(d.join("t_sweep.toml"))
        .unwrap()
        .replace("slow = [", "slower = [");
    std::fs::write(d.join("other_sweep.toml"), other).unwrap();
    let refused = cncsim(&["sweep", "other_sweep.toml", "--out", "o", "--resume"], d);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr)
        .contains("--resume: the folder holds the runs of another sweep"));
}

#[test]
fn a_run_past_its_time_limit_is_a_row_that_says_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The `long` variant crawls along the 2 mm path for 1000 s of program time: far more than
    // 3 s of wall time; the others take well under a second.
    let sweep = setup(d, "long = [\"program.feed_mm_s=0.002\"]");
    let text = std::fs::read_to_string(&sweep)
        .unwrap()
        .replace("name = \"t\"\n", "name = \"t\"\nrun_timeout_s = 3\n");
    std::fs::write(&sweep, text).unwrap();
    let out = cncsim(
        &[
            "sweep",
            sweep.to_str().unwrap(),
            "--jobs",
            "2",
            "--out",
            "o",
        ],
        d,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    // Off a terminal, plain progress lines: the last says all are done and names the last
    // failed run.
    let last = stderr
        .lines()
        .rfind(|l| l.starts_with("sweep: "))
        .unwrap_or("");
    assert!(
        last.starts_with("sweep: 12 of 12 runs done, 4 failed, the last 000")
            && last.contains("_long_p")
            && last.contains(" s elapsed"),
        "{stderr}"
    );
    let r = rows(&d.join("o"));
    assert_eq!(r.len(), 12);
    for row in &r {
        let variant = row["variant"].as_str().unwrap();
        let error = row["error"].as_str().unwrap_or("");
        if variant == "long" {
            assert!(
                error.starts_with("timeout after 3 s (stopped at t = "),
                "{row}"
            );
            assert_eq!(row["completed"], Value::Bool(false), "{row}");
            // The figures up to the stop are kept.
            assert!(
                row["metrics"]["sim_time_s"].as_f64().unwrap() > 0.0,
                "{row}"
            );
        } else {
            assert!(
                error.is_empty() && row["completed"] == Value::Bool(true),
                "{row}"
            );
        }
    }
    // The command line's limit replaces the file's; a bad one is refused by clap (exit 2).
    let out = cncsim(
        &[
            "sweep",
            sweep.to_str().unwrap(),
            "--run-timeout-s",
            "0",
            "--out",
            "o2",
        ],
        d,
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("expected a run time limit from 0.1"));
}

#[test]
fn the_ray_driver_merges_to_the_single_machine_result() {
    let ray = Command::new("python3").args(["-c", "import ray"]).output();
    if !ray.as_ref().is_ok_and(|o| o.status.success()) {
        assert!(
            std::env::var("CNCSIM_REQUIRE_ORACLES").is_err(),
            "Ray is required here (pip install ray) but python3 cannot import it"
        );
        eprintln!("skipped: python3 cannot import ray (pip install ray)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sweep = setup(d, "");
    let sweep = sweep.to_str().unwrap();
    let single = cncsim(&["sweep", sweep, "--out", "single"], d);
    assert!(
        single.status.success(),
        "{}",
        String::from_utf8_lossy(&single.stderr)
    );
    let driver = root().join("tools/ray_sweep.py");
    let out = Command::new("python3")
        .arg(driver)
        .args([
            "--sweep",
            sweep,
            "--cncsim",
            env!("CARGO_BIN_EXE_cncsim"),
            "--shards",
            "3",
            "--num-cpus",
            "2",
            "--out",
            "ray",
        ])
        .current_dir(d)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        rows(&d.join("single")) == rows(&d.join("ray")),
        "Ray's merged sweep differs"
    );
}
