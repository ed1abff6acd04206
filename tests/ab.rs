//! `cncsim ab`: PID against inverse dynamics on the A-C mill, same setpoints; two files, or
//! one file with overrides.

use std::process::Command;

fn ab(a: &str, b: &str, out: &std::path::Path) -> (std::process::Output, serde_json::Value) {
    ab_args(&[a, b], out)
}

fn ab_args(args: &[&str], out: &std::path::Path) -> (std::process::Output, serde_json::Value) {
    let output = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .arg("ab")
        .args(args)
        .args(["--out", out.to_str().unwrap()])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let json = std::fs::read_to_string(out.join("ab.json"))
        .map(|t| serde_json::from_str(&t).unwrap())
        .unwrap_or_default();
    (output, json)
}

fn row(json: &serde_json::Value, metric: &str) -> (f64, f64) {
    let r = json["rows"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["metric"] == metric)
        .unwrap_or_else(|| panic!("no row {metric}"));
    (r["a"].as_f64().unwrap(), r["b"].as_f64().unwrap())
}

#[test]
fn inverse_dynamics_beats_pid_with_an_exact_model_and_not_with_a_wrong_one() {
    let dir = tempfile::tempdir().unwrap();
    let (out, json) = ab(
        "scenarios/mill_table2_pid.toml",
        "scenarios/mill_table2_id.toml",
        &dir.path().join("exact"),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (pid, id) = row(&json, "max contour error");
    assert!(id * 10.0 < pid, "contour error: PID {pid} µm, ID {id} µm");
    for axis in ["x", "y", "z"] {
        let (pid, id) = row(&json, &format!("{axis}: max following error"));
        assert!(id * 10.0 < pid, "{axis}: PID {pid} µm, ID {id} µm");
    }
    assert!(std::fs::read_to_string(dir.path().join("exact/ab.md"))
        .unwrap()
        .contains("| max contour error | µm |"));
    assert!(
        dir.path().join("exact/a_mill_table2_pid/run.rrd").is_file()
            && dir.path().join("exact/b_mill_table2_id/run.rrd").is_file()
    );

    // The controller's model 20 % heavy: without integral action the gravity over-compensation
    // leaves Z off by about 0.2·m_z·g/(m_eff·ωn²) ≈ 35 µm, far worse than PID.
    let (out, json) = ab(
        "scenarios/mill_table2_pid.toml",
        "scenarios/mill_table2_id_mass120.toml",
        &dir.path().join("heavy"),
    );
    assert!(out.status.success());
    let (pid, id) = row(&json, "z: max following error");
    assert!(
        id > 5.0 * pid && (25.0..50.0).contains(&id),
        "z: PID {pid} µm, heavy-model ID {id} µm"
    );
}

#[test]
fn variants_with_different_setpoints_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (out, _) = ab(
        "scenarios/mill_table2_pid.toml",
        "scenarios/xyz_circle_5mms.toml",
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("do not run the same setpoints"));
}

const FAST: &str = "scenarios/mill_table2_fast.toml";

/// The run succeeded, its variants are FAST's PID and inverse dynamics, and ID's contour error
/// is under a tenth of PID's; returns both (µm).
fn assert_id_beats_pid_tenfold(run: &std::process::Output, json: &serde_json::Value) -> (f64, f64) {
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(json["a"], "mill_table2_fast controller=pid");
    assert_eq!(json["b"], "mill_table2_fast controller=inverse-dynamics");
    let (pid, id) = row(json, "max contour error");
    assert!(id * 10.0 < pid, "contour error: PID {pid} µm, ID {id} µm");
    (pid, id)
}

#[test]
fn one_scenario_with_overrides_compares_pid_and_inverse_dynamics() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ab");
    let (run, json) = ab_args(
        &[
            FAST,
            "--a",
            "controller=pid",
            "--b",
            "controller=inverse-dynamics",
        ],
        &out,
    );
    let (pid, _) = assert_id_beats_pid_tenfold(&run, &json);
    // The PID variant really is the file's PID gains (its measured figure), not ID twice.
    assert!((150.0..200.0).contains(&pid), "PID contour error {pid} µm");
    assert!(out
        .join("a_mill_table2_fast_controller=pid/run.rrd")
        .is_file());
    assert!(out
        .join("b_mill_table2_fast_controller=inverse-dynamics/metrics.json")
        .is_file());
    // The plot decodes as a PNG of the documented size with something drawn in it.
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(out.join("contour_error.png")).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let frame = reader.next_frame(&mut pixels).unwrap();
    assert_eq!((frame.width, frame.height), cncsim::report::PLOT_SIZE);
    let coloured = pixels
        .chunks(3)
        .filter(|p| p[0].abs_diff(p[1]) > 60 || p[1].abs_diff(p[2]) > 60)
        .count();
    assert!(
        coloured > 1000,
        "only {coloured} coloured pixels: no curves drawn?"
    );
    let table = std::fs::read_to_string(out.join("ab.md")).unwrap();
    assert!(
        table.contains("A: mill_table2_fast controller=pid"),
        "{table}"
    );

    // A generic dotted override changes the loop: a slower inverse-dynamics loop tracks worse.
    let (run, json) = ab_args(
        &[
            FAST,
            "--a",
            "controller.natural_frequency_hz=20",
            "--b",
            "controller.natural_frequency_hz=10",
        ],
        &dir.path().join("slow"),
    );
    assert!(run.status.success());
    let (fast, slow) = row(&json, "max contour error");
    assert!(slow > 1.5 * fast, "20 Hz {fast} µm, 10 Hz {slow} µm");
}

#[test]
fn bad_overrides_name_the_override_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    for (args, expected) in [
        (
            vec!["--a", "controller.natrual_frequency_hz=30"],
            "--a controller.natrual_frequency_hz=30: unknown key `natrual_frequency_hz`",
        ),
        (
            vec!["--b", "controller.natural_frequency_hz=fast"],
            "--b controller.natural_frequency_hz=fast: invalid type: string \"fast\", expected f64",
        ),
        (
            vec!["--a", "controller.natural_frequency_hz=-3"],
            "--a controller.natural_frequency_hz=-3: natural_frequency_hz = -3.0 Hz: expected a value from 0.001 to 10000.0 Hz",
        ),
        (
            vec!["--a", "controller=stepper"],
            "--a controller=stepper: unknown variant `stepper`",
        ),
        (
            vec!["--b", "timing=1"],
            "--b timing=1: `timing` is a table",
        ),
        (vec!["--a", "controller"], "--a controller: expected KEY=VALUE"),
    ] {
        let mut all = vec![FAST];
        all.extend(args.iter().copied());
        let (run, _) = ab_args(&all, dir.path());
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    // A file without [ab] and no overrides: nothing tells the variants apart.
    let (run, _) = ab_args(&["scenarios/mill_table2_id.toml"], dir.path());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("needs overrides to tell the variants apart"),
        "{stderr}"
    );
    // A malformed declared variant is reported where it is written.
    let text = std::fs::read_to_string(FAST)
        .unwrap()
        .replace(
            "../models/",
            concat!(env!("CARGO_MANIFEST_DIR"), "/models/"),
        )
        .replace(
            "programs/",
            concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/programs/"),
        )
        .replace("a = [\"controller=pid\"]", "a = [\"controller\"]");
    let bad = dir.path().join("bad_ab.toml");
    std::fs::write(&bad, &text).unwrap();
    let line = text.lines().position(|l| l == "[ab]").unwrap() + 2;
    let (run, _) = ab_args(&[bad.to_str().unwrap()], dir.path());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!("bad_ab.toml:{line}:"))
            && stderr.contains("ab.a: controller: expected KEY=VALUE"),
        "{stderr}"
    );
    assert!(!dir.path().join("ab.json").exists());
}

#[test]
fn variants_declared_in_the_scenario_run_without_flags() {
    let dir = tempfile::tempdir().unwrap();
    let (run, json) = ab_args(&[FAST], dir.path());
    assert_id_beats_pid_tenfold(&run, &json);
}

#[test]
fn overrides_that_change_the_setpoints_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (run, _) = ab_args(
        &[
            FAST,
            "--a",
            "controller=pid",
            "--b",
            "timing.servo_period_ms=0.5",
        ],
        dir.path(),
    );
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("do not run the same setpoints"));
}

#[test]
fn task_space_inverse_dynamics_tracks_the_study_program_through_a_zero() {
    // The program starts at A = 0, where C cannot move the tool axis and the task Jacobian
    // loses rank, and its first move turns C while A is still near zero.
    let dir = tempfile::tempdir().unwrap();
    let (run, json) = ab_args(
        &[
            FAST,
            "--a",
            "controller.space=joint",
            "--b",
            "controller.space=task",
        ],
        dir.path(),
    );
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let (joint, task) = row(&json, "max contour error");
    assert!(
        task < 1.2 * joint && task < 4.0,
        "contour error: joint {joint} µm, task {task} µm"
    );
    let (joint, task) = row(&json, "c: max following error");
    assert!(
        task < 1.2 * joint,
        "C: joint {joint} mdeg, task {task} mdeg"
    );
    let (joint, task) = row(&json, "c: peak torque");
    assert!(
        task < 1.1 * joint,
        "C torque: joint {joint}, task {task} N·m"
    );
}

/// Scenarios with the analytic model on (the paper's, for one) run it in each variant's own
/// recording; the shared A/B recording holds the physics lanes (a regression: it indexed a
/// lane it had no columns for and panicked).
#[test]
fn ab_of_scenarios_with_the_analytic_model_writes_one_recording() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ab");
    let (run, json) = ab_args(
        &[
            "scenarios/xyz_circle_5mms.toml",
            "--a",
            "controller.axes.x.kp=19800.0",
            "--b",
            "controller.axes.x.kp=9900.0",
        ],
        &out,
    );
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(out.join("ab.rrd").is_file());
    // Halving X's proportional gain lets it lag more (measured 0.076 → 0.104 µm).
    let (a, b) = row(&json, "x: max following error");
    assert!(b > 1.2 * a, "x max following error: {a} µm, then {b} µm");
    let metrics: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(
            out.join("a_xyz_circle_5mms_controller.axes.x.kp=19800.0/metrics.json"),
        )
        .unwrap(),
    )
    .unwrap();
    assert!(metrics["axes"]["x"]["max_physics_vs_analytic_mm"].is_number());
}
