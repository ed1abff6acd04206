//! Sweeps: parallel and deterministic (the same rows with one thread or two, and from shards
//! merged), a failing run is a row with its error, Ctrl-C keeps the finished rows, plans are
//! made once per distinct setpoint stream, and the Ray driver's merged result equals the
//! single-machine sweep with its workers seeing none of the driver's paths, and it resumes
//! (when Ray is installed; required under CNCSIM_REQUIRE_ORACLES=1).

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

/// Runs `tools/ray_sweep.py ARGS` in `dir`, handing each line of its stdout to `on_line` as it
/// comes; returns its exit status, stdout and stderr.
fn ray_driver(
    dir: &Path,
    args: &[&str],
    mut on_line: impl FnMut(&str),
) -> (Option<i32>, String, String) {
    use std::io::{BufRead, Read};
    let mut child = Command::new("python3")
        .arg(root().join("tools/ray_sweep.py"))
        .args(args)
        .current_dir(dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Stderr read on a thread of its own, so that neither pipe fills while the other is read.
    let mut stderr = child.stderr.take().unwrap();
    let errors = std::thread::spawn(move || {
        let mut bytes = Vec::new();
        stderr.read_to_end(&mut bytes).unwrap();
        String::from_utf8_lossy(&bytes).into_owned()
    });
    let mut stdout = String::new();
    for line in std::io::BufReader::new(child.stdout.take().unwrap()).split(b'\n') {
        let line = String::from_utf8_lossy(&line.unwrap()).into_owned();
        on_line(line.as_str());
        stdout += &line;
        stdout.push('\n');
    }
    let status = child.wait().unwrap();
    (status.code(), stdout, errors.join().unwrap())
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
    // The sweep's files in one folder, inputs/, with relative paths only: the scenarios name
    // their machine models/xyz_table.urdf, copied beside them with its drives file.
    let inputs = d.join("inputs");
    std::fs::create_dir_all(inputs.join("models")).unwrap();
    for model in ["xyz_table.urdf", "xyz_table.drives.toml"] {
        std::fs::copy(
            root().join("models").join(model),
            inputs.join("models").join(model),
        )
        .unwrap();
    }
    setup(&inputs, "");
    for scenario in ["short.toml", "other.toml"] {
        let path = inputs.join(scenario);
        let text = std::fs::read_to_string(&path)
            .unwrap()
            .replace(&format!("{}/models/", root().display()), "models/");
        std::fs::write(&path, text).unwrap();
    }
    // Every file the sweep reads is in inputs/ (so that renaming it hides them all).
    let listed = cncsim(&["sweep", "inputs/t_sweep.toml", "--inputs"], d);
    assert!(
        listed.status.success(),
        "{}",
        String::from_utf8_lossy(&listed.stderr)
    );
    let listed = String::from_utf8_lossy(&listed.stdout).into_owned();
    let canonical = std::fs::canonicalize(&inputs).unwrap();
    assert!(
        listed.lines().any(|l| l.ends_with("xyz_table.urdf"))
            && listed.lines().all(|l| Path::new(l).starts_with(&canonical)),
        "{listed}"
    );
    let single = cncsim(&["sweep", "inputs/t_sweep.toml", "--out", "single"], d);
    assert!(
        single.status.success(),
        "{}",
        String::from_utf8_lossy(&single.stderr)
    );

    // The driver runs a copy of the binary. Once the shards are submitted, the inputs and the
    // binary are renamed away: a worker that looked for them at the driver's paths would fail;
    // the workers run what the driver shipped, in folders of their own, and the driver merges
    // with its own copy of the binary it shipped.
    let binary = d.join("cncsim");
    std::fs::copy(env!("CARGO_BIN_EXE_cncsim"), &binary).unwrap();
    let args = [
        "--sweep",
        "inputs/t_sweep.toml",
        "--cncsim",
        "cncsim",
        "--shards",
        "3",
        "--num-cpus",
        "2",
        "--out",
        "ray",
    ];
    let mut hidden = false;
    let (code, stdout, stderr) = ray_driver(d, &args, |line| {
        if line == "submitted 3 shards" {
            std::fs::rename(&inputs, d.join("inputs_gone")).unwrap();
            std::fs::rename(&binary, d.join("cncsim_gone")).unwrap();
            hidden = true;
        }
    });
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    assert!(hidden, "no line 'submitted 3 shards':\n{stdout}\n{stderr}");
    for k in 1..=3 {
        assert!(stdout.contains(&format!("shard {k}/3 on ")), "{stdout}");
    }
    assert!(
        rows(&d.join("single")) == rows(&d.join("ray")),
        "Ray's merged sweep differs"
    );

    // A resume over the finished folder submits nothing, writes no shard again and merges the
    // same rows.
    std::fs::rename(d.join("inputs_gone"), &inputs).unwrap();
    std::fs::rename(d.join("cncsim_gone"), &binary).unwrap();
    let shard_files: Vec<(PathBuf, std::time::SystemTime)> = (1..=3)
        .map(|k| {
            let path = d.join(format!("ray/shards/{k}_of_3/results.json"));
            let modified = std::fs::metadata(&path).unwrap().modified().unwrap();
            (path, modified)
        })
        .collect();
    std::thread::sleep(std::time::Duration::from_millis(50));
    let resume: Vec<&str> = args.iter().copied().chain(["--resume"]).collect();
    let (code, stdout, stderr) = ray_driver(d, &resume, |_| {});
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("resuming: 3 of 3 shards have results") && !stdout.contains("submitted"),
        "{stdout}\n{stderr}"
    );
    for (path, modified) in &shard_files {
        let now = std::fs::metadata(path).unwrap().modified().unwrap();
        assert_eq!(now, *modified, "{} was written again", path.display());
    }
    assert!(
        rows(&d.join("single")) == rows(&d.join("ray")),
        "the resumed merge differs"
    );

    // A resume with another shard count is refused by its digest (exit 2); nothing is run.
    let other: Vec<&str> = resume
        .iter()
        .map(|a| if *a == "3" { "2" } else { *a })
        .collect();
    let (code, stdout, stderr) = ray_driver(d, &other, |_| {});
    assert_eq!(code, Some(2), "{stdout}\n{stderr}");
    assert!(
        stderr.contains("--resume: the folder holds the shards of another sweep")
            && stderr.contains("digest"),
        "{stderr}"
    );
    assert!(!stdout.contains("submitted"), "{stdout}");
}

/// `--inputs` lists every file the runs read, a variant's overrides applied: the meshes and
/// package manifest of a URDF package, the program a variant names, and nothing else.
#[test]
fn inputs_are_every_file_the_runs_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scenarios = root().join("scenarios");
    let text = format!(
        "scenarios = [\"{0}/desk_router_circle.toml\", \"{0}/mill_slot.toml\"]\n[variants]\nas_is = []\n",
        scenarios.display()
    );
    std::fs::write(d.join("s.toml"), text).unwrap();
    let out = cncsim(&["sweep", "s.toml", "--inputs"], d);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let listed: Vec<&str> = stdout.lines().collect();
    let canonical = |p: PathBuf| std::fs::canonicalize(p).unwrap().display().to_string();
    assert_eq!(
        listed[0],
        canonical(d.join("s.toml")),
        "the sweep file first"
    );
    let models = root().join("models");
    let router = models.join("desk_router");
    let mut expected: Vec<String> = std::fs::read_dir(router.join("meshes"))
        .unwrap()
        .map(|e| canonical(e.unwrap().path()))
        .collect();
    expected.extend(
        [
            router.join("package.xml"),
            router.join("urdf/desk_router.urdf"),
            router.join("urdf/desk_router.drives.toml"),
            models.join("ac_mill.urdf"),
            models.join("ac_mill.drives.toml"),
            scenarios.join("desk_router_circle.toml"),
            scenarios.join("mill_slot.toml"),
            scenarios.join("programs/mill_slot.ngc"),
        ]
        .map(canonical),
    );
    expected.sort();
    let mut rest: Vec<String> = listed[1..].iter().map(|s| s.to_string()).collect();
    rest.sort();
    assert_eq!(rest, expected);

    // A variant naming another program: both programs are read.
    let text = format!(
        "scenarios = [\"{}/mill_slot.toml\"]\n[variants]\nas_is = []\nother = [\"program.file = \\\"programs/d_table2.ngc\\\"\"]\n",
        scenarios.display()
    );
    std::fs::write(d.join("s.toml"), text).unwrap();
    let out = cncsim(&["sweep", "s.toml", "--inputs"], d);
    let stdout = String::from_utf8_lossy(&out.stdout);
    for program in ["mill_slot.ngc", "d_table2.ngc"] {
        let program = canonical(scenarios.join("programs").join(program));
        assert!(stdout.lines().any(|l| l == program), "{program}: {stdout}");
    }
}
