//! Bad scenario and machine files: a clear error naming the file and the line, never a panic.

use cncsim::scenario::Scenario;
use std::path::{Path, PathBuf};
use std::process::Command;

const GOOD: &str = r#"
machine = "MODEL"
[program]
polyline = { points_mm = [[10.0, 10.0, 0.0], [11.0, 10.0, 0.0]] }
feed_mm_s = 5.0
[timing]
servo_period_ms = 1.0
physics_step_ms = 0.25
[actuator]
model = "dc-motor"
[controller]
type = "pid"
axes.x = { kp = 19800.0, ki = 6.1e5, kd = 146.0 }
axes.y = { kp = 19800.0, ki = 6.1e5, kd = 146.0 }
axes.z = { kp = 9700.0, ki = 3.0e5, kd = 85.0 }
"#;

fn model() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models/xyz_table.urdf")
        .display()
        .to_string()
}

fn scenario_text(edit: impl Fn(&str) -> String) -> String {
    edit(&GOOD.replace("MODEL", &model()))
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn the_good_scenario_parses() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "good.toml", &scenario_text(|s| s.to_string()));
    Scenario::load(&p).unwrap();
}

/// Each bad input, the line it must point at, and words its message must contain.
#[test]
fn bad_scenarios_are_reported_with_file_and_line() {
    let cases: Vec<(&str, String, usize, &str)> = vec![
        (
            "unknown key",
            scenario_text(|s| s.replace("[timing]\n", "[timing]\nservo_perod_ms = 1.0\n")),
            7,
            "unknown field `servo_perod_ms`",
        ),
        (
            "wrong type",
            scenario_text(|s| s.replace("servo_period_ms = 1.0", "servo_period_ms = \"fast\"")),
            7,
            "invalid type: string \"fast\", expected f64",
        ),
        (
            "NaN",
            scenario_text(|s| s.replace("servo_period_ms = 1.0", "servo_period_ms = nan")),
            7,
            "servo_period_ms = NaN ms: expected a value from 0.01 to 100.0 ms",
        ),
        (
            "negative period",
            scenario_text(|s| s.replace("servo_period_ms = 1.0", "servo_period_ms = -1.0")),
            7,
            "servo_period_ms = -1.0 ms: expected a value from 0.01 to 100.0 ms",
        ),
        (
            "zero period",
            scenario_text(|s| s.replace("servo_period_ms = 1.0", "servo_period_ms = 0.0")),
            7,
            "servo_period_ms = 0.0 ms: expected a value from 0.01 to 100.0 ms",
        ),
        (
            "step longer than period",
            scenario_text(|s| s.replace("physics_step_ms = 0.25", "physics_step_ms = 2.0")),
            8,
            "is longer than servo_period_ms",
        ),
        (
            "step not dividing period",
            scenario_text(|s| s.replace("physics_step_ms = 0.25", "physics_step_ms = 0.3")),
            8,
            "does not divide",
        ),
        (
            "missing model",
            scenario_text(|s| s.replace(&model(), "no/such/model.urdf")),
            2,
            "machine model 'no/such/model.urdf' not found",
        ),
        (
            "bad actuator",
            scenario_text(|s| s.replace("dc-motor", "stepper")),
            10,
            "unknown variant `stepper`",
        ),
        (
            "negative gain",
            scenario_text(|s| s.replace("kp = 9700.0", "kp = -1.0")),
            15,
            "gains must be from 0 to 1000000000000.0",
        ),
        (
            "zero feed",
            scenario_text(|s| s.replace("feed_mm_s = 5.0", "feed_mm_s = 0.0")),
            5,
            "feed_mm_s = 0.0 mm/s: expected a value from 0.001 to 20000.0 mm/s",
        ),
        (
            "two programs",
            scenario_text(|s| s.replace("feed_mm_s = 5.0", "feed_mm_s = 5.0\nfile = \"x.ngc\"")),
            3,
            "needs exactly one of",
        ),
        (
            "bad bound",
            scenario_text(|s| s.to_owned() + "[expect]\nmax_contour_error_mm = 0.1\n"),
            17,
            "expected a bound such as { max = 0.01 }",
        ),
        (
            "unknown CAM system",
            scenario_text(|s| {
                let program = Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("scenarios/programs/d_table1.apt")
                    .display()
                    .to_string();
                s.replace(
                    "polyline = { points_mm = [[10.0, 10.0, 0.0], [11.0, 10.0, 0.0]] }\nfeed_mm_s = 5.0",
                    &format!("file = \"{program}\"\ncl_writer = \"gibbs\""),
                )
            }),
            5,
            "cl_writer: expected one of nx, creo, catia, solidworks, camworks, mastercam, fusion, camplete, apt, found 'gibbs'",
        ),
        (
            "unknown program kinematics",
            scenario_text(|s| s.replace("feed_mm_s = 5.0\n", "feed_mm_s = 5.0\nkinematics = \"tpc\"\n")),
            6,
            "kinematics: expected \"joint\" (the words are joint coordinates) or \"tcp\" (X Y Z the tool tip on the part), found 'tpc'",
        ),
        (
            "tool-tip tolerance without tool-tip kinematics",
            scenario_text(|s| s.replace("feed_mm_s = 5.0\n", "feed_mm_s = 5.0\ntcp_tolerance_mm = 0.01\n")),
            6,
            "tcp_tolerance_mm applies with kinematics = \"tcp\"",
        ),
        (
            "tool-tip tolerance out of range",
            scenario_text(|s| s.replace("feed_mm_s = 5.0\n", "feed_mm_s = 5.0\nkinematics = \"tcp\"\ntcp_tolerance_mm = 0.0\n")),
            7,
            "tcp_tolerance_mm",
        ),
        ("not toml", "machine = [\n".to_string(), 1, "unclosed array"),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (what, text, line, words) in cases {
        let p = write(dir.path(), "bad.toml", &text);
        let err = Scenario::load(&p).expect_err(what);
        let shown = err.to_string();
        assert!(
            shown.starts_with(&format!("{}:{line}:", p.display())),
            "{what}: expected line {line}, got: {shown}"
        );
        assert!(
            shown.contains(words),
            "{what}: message lacks {words:?}: {shown}"
        );
    }
}

/// `cncsim run SCENARIO` must fail as bad input (exit 2, no panic); returns its stderr.
fn run_expecting_bad_input(scenario: &Path, dir: &Path) -> String {
    let out = cncsim(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        dir.join("o").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn cncsim(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap()
}

#[test]
fn cli_exits_with_2_and_the_location_on_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "bad.toml",
        &scenario_text(|s| s.replace("physics_step_ms = 0.25", "physics_step_ms = 2.0")),
    );
    let err = run_expecting_bad_input(&p, dir.path());
    assert!(err.contains(&format!("{}:8:", p.display())), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn scenario_naming_a_missing_axis_or_metric_is_rejected_before_running() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "s.toml",
        &scenario_text(|s| {
            s.to_owned() + "[expect]\naxes.q.max_following_error_mm = { max = 1.0 }\n"
        }),
    );
    let err = run_expecting_bad_input(&p, dir.path());
    assert!(
        err.contains("expect.axes.q.max_following_error_mm: no such metric"),
        "{err}"
    );
    assert!(err.contains(":17:"), "{err}");

    let p = write(
        dir.path(),
        "s2.toml",
        &scenario_text(|s| s.replace("axes.z = {", "axes.w = {")),
    );
    let err = run_expecting_bad_input(&p, dir.path());
    assert!(err.contains("has no axis 'w'"), "{err}");
}

#[test]
fn bad_machine_files_name_the_element() {
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string(model()).unwrap();
    let drives =
        std::fs::read_to_string(Path::new(&model()).with_extension("drives.toml")).unwrap();
    let cases = [
        (
            "negative mass",
            src.replace("<mass value=\"8.0\"/>", "<mass value=\"-8.0\"/>"),
            "link 'x_carriage': mass -8.0 kg: expected a finite mass ≥ 0",
        ),
        (
            "bad inertia",
            src.replace("ixx=\"0.16727\"", "ixx=\"-0.1\""),
            "inertia is not positive semi-definite",
        ),
        (
            "missing parent",
            src.replace("<parent link=\"x_carriage\"/>", "<parent link=\"nope\"/>"),
            "joint 'y': parent link 'nope' does not exist",
        ),
        (
            "not xml",
            "<robot name=".to_string(),
            "not well-formed XML: syntax error: tag not closed",
        ),
    ];
    for (what, text, words) in cases {
        let urdf = write(dir.path(), "m.urdf", &text);
        write(dir.path(), "m.drives.toml", &drives);
        let err = cncsim::machine::Machine::load(&urdf)
            .expect_err(what)
            .to_string();
        assert!(
            err.starts_with(&urdf.display().to_string()),
            "{what}: {err}"
        );
        assert!(err.contains(words), "{what}: {err}");
    }
    // A drive sidecar with a negative constant points at its axis table.
    let urdf = write(dir.path(), "m.urdf", &src);
    write(
        dir.path(),
        "m.drives.toml",
        &drives.replace("amplifier_gain = 7.68", "amplifier_gain = -7.68"),
    );
    let err = cncsim::machine::Machine::load(&urdf)
        .expect_err("negative gain")
        .to_string();
    assert!(
        err.contains("m.drives.toml:") && err.contains("axis 'z': amplifier_gain = -7.68"),
        "{err}"
    );
}

/// The guide and feedback entries of a drive file: each mistake names the file, the axis and
/// what was expected.
#[test]
fn bad_guides_and_feedback_name_the_axis() {
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string(model()).unwrap();
    let drives =
        std::fs::read_to_string(Path::new(&model()).with_extension("drives.toml")).unwrap();
    // X's guide line, whatever the calibration wrote into it.
    let x_guide = drives
        .lines()
        .find(|l| l.starts_with("guide = {"))
        .expect("the X axis has a guide");
    let cases = [
        (
            drives.replacen(
                x_guide,
                "guide = { friction_coefficient = 0.1, static_friction_coefficient = 0.05, stribeck_velocity_m_s = 1e-3 }",
                1,
            ),
            "axis 'x': guide.static_friction_coefficient = 0.05: expected a value from the kinetic friction_coefficient (0.1) to 2.0",
        ),
        (
            drives.replacen(
                x_guide,
                "guide = { friction_coefficient = 0.1, static_friction_coefficient = 0.2 }",
                1,
            ),
            "axis 'x': guide.static_friction_coefficient = 0.2 exceeds the kinetic 0.1: expected stribeck_velocity_m_s",
        ),
        (
            drives.replacen(
                x_guide,
                "guide = { friction_coefficient = 0.1, static_friction_coefficient = 0.2, stribeck_velocity_m_s = 0.0 }",
                1,
            ),
            "axis 'x': guide.stribeck_velocity_m_s = 0.0 m/s: expected a value from 1e-7 to 1.0 m/s",
        ),
        (
            drives.replacen(x_guide, "guide = { friction_coefficient = -0.1 }", 1),
            "axis 'x': guide.friction_coefficient = -0.1: expected a value from 0.0 to 2.0",
        ),
        (
            drives.replacen(
                x_guide,
                "guide = { friction_coefficient = 0.1, normal = [1.0, 0.0, 0.0] }",
                1,
            ),
            "axis 'x': guide.normal = [1.0, 0.0, 0.0] is not perpendicular to the axis of joint 'x'",
        ),
        (
            drives.replacen(
                x_guide,
                "guide = { friction_coefficient = 0.1, normal = [0.0, 0.0, 0.0] }",
                1,
            ),
            "expected a finite, non-zero vector",
        ),
        (
            drives.replacen(
                x_guide,
                "guide = { friction_coefficient = 0.1, runner_spacing_m = 120.0 }",
                1,
            ),
            "axis 'x': guide.runner_spacing_m = 120.0 m: expected a value from 0.001 to 5.0 m",
        ),
        (
            drives.replacen(
                x_guide,
                "guide = { friction_coefficient = 0.1, runner_spacing_m = -0.12 }",
                1,
            ),
            "axis 'x': guide.runner_spacing_m = -0.12 m: expected a value from 0.001 to 5.0 m",
        ),
        (
            drives.replacen(x_guide, "guide = { friction_coeficient = 0.1 }", 1),
            "unknown field `friction_coeficient`",
        ),
        (
            drives.replacen("feedback = \"carriage\"", "feedback = \"scale\"", 1),
            "unknown variant `scale`",
        ),
        (
            drives.replacen(
                "amplifier_mode = \"current\"",
                "amplifier_mode = \"torque\"",
                1,
            ),
            "unknown variant `torque`, expected `voltage` or `current`",
        ),
    ];
    let urdf = write(dir.path(), "m.urdf", &src);
    for (text, words) in cases {
        write(dir.path(), "m.drives.toml", &text);
        let err = cncsim::machine::Machine::load(&urdf)
            .expect_err(words)
            .to_string();
        assert!(
            err.contains("m.drives.toml:") && err.contains(words),
            "{words}: {err}"
        );
    }
    // A scenario's [feedback] position and [mechanics] switches are checked like the rest.
    for (edit, words) in [
        (
            "[feedback]\nposition = \"encoder\"\n",
            "unknown variant `encoder`",
        ),
        (
            "[mechanics]\nfriction = 1\n",
            "invalid type: integer `1`, expected a boolean",
        ),
        ("[mechanics]\nbacklsh = false\n", "unknown field `backlsh`"),
    ] {
        let text = scenario_text(|s| s.replace("[timing]\n", &format!("{edit}\n[timing]\n")));
        let p = write(dir.path(), "s.toml", &text);
        let err = Scenario::load(&p).expect_err(words).to_string();
        assert!(
            err.contains("s.toml:") && err.contains(words),
            "{words}: {err}"
        );
    }
}

/// A scenario's amplifier mode: a known mode, and only where there is an amplifier.
#[test]
fn bad_amplifier_modes_are_reported_against_the_scenario() {
    let dir = tempfile::tempdir().unwrap();
    for (edit, line, words) in [
        (
            "model = \"dc-motor\"\namplifier_mode = \"pwm\"",
            11,
            "unknown variant `pwm`, expected `voltage` or `current`",
        ),
        (
            "model = \"ideal-torque\"\namplifier_mode = \"current\"",
            11,
            "amplifier_mode applies to model = \"dc-motor\"; the ideal-torque actuator has no amplifier",
        ),
    ] {
        let text = scenario_text(|s| s.replace("model = \"dc-motor\"", edit));
        let p = write(dir.path(), "s.toml", &text);
        let err = Scenario::load(&p).expect_err(words).to_string();
        assert!(
            err.contains(&format!("s.toml:{line}:")) && err.contains(words),
            "{words}: {err}"
        );
    }
    let text = scenario_text(|s| {
        s.replace(
            "model = \"dc-motor\"",
            "model = \"dc-motor\"\namplifier_mode = \"current\"",
        )
    });
    let p = write(dir.path(), "s.toml", &text);
    let s = Scenario::load(&p).unwrap();
    assert_eq!(
        s.actuator.and_then(|a| a.amplifier_mode),
        Some(cncsim::machine::AmplifierMode::Current)
    );
}

/// A scenario whose program file is damaged, or drives an axis the machine lacks, fails with
/// the program's file, line and column.
#[test]
fn bad_program_files_are_reported_against_the_program() {
    let dir = tempfile::tempdir().unwrap();
    let samples = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/programs");
    let with_file = |file: &Path| {
        scenario_text(|s| {
            s.replace(
                "polyline = { points_mm = [[10.0, 10.0, 0.0], [11.0, 10.0, 0.0]] }\nfeed_mm_s = 5.0",
                &format!("file = {:?}", file.display().to_string()),
            )
        })
    };
    let damaged = samples.join("b_circle_r3mm_as_printed.plt");
    let p = write(dir.path(), "damaged.toml", &with_file(&damaged));
    let err = run_expecting_bad_input(&p, dir.path());
    assert!(
        err.contains(&format!(
            "{}:1:287: expected x,y pairs after PA",
            damaged.display()
        )),
        "{err}"
    );

    let rotary = write(
        dir.path(),
        "rotary.ngc",
        "G21 G90\nG1 X1 F60\nG1 A10 F60\nM2\n",
    );
    let p = write(dir.path(), "rotary.toml", &with_file(&rotary));
    let err = run_expecting_bad_input(&p, dir.path());
    assert!(
        err.contains(&format!("{}:3:", rotary.display()))
            && err.contains("drives axis A, which the machine 'xyz_table' does not have"),
        "{err}"
    );
}

#[test]
fn a_tool_tip_program_on_a_machine_without_two_rotary_axes_is_refused_at_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let text = scenario_text(|s| {
        s.replace(
            "feed_mm_s = 5.0\n",
            "feed_mm_s = 5.0\nkinematics = \"tcp\"\n",
        )
    });
    let p = write(dir.path(), "tcp.toml", &text);
    let err = run_expecting_bad_input(&p, dir.path());
    assert!(
        err.contains(&format!("{}:6:", p.display()))
            && err.contains("kinematics = \"tcp\" reads X Y Z as the tool tip on the part: machine 'xyz_table' has no tool-tip kinematics: expected two rotary axes turning the tool relative to the part, found 0"),
        "{err}"
    );
}

/// A reader that stops early (`cncsim inspect … | head`) ends the run quietly: no panic about
/// a broken pipe.
#[cfg(unix)]
#[test]
fn a_closed_output_pipe_is_not_a_crash() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let dir = tempfile::tempdir().unwrap();
    let mut program = String::from("G21 G90 G17\nG0 X0 Y0 Z0\n");
    for i in 0..20_000 {
        program.push_str(&format!("G1 X{} Y{} F100\n", i % 50, (i * 7) % 50));
    }
    let path = write(dir.path(), "long.ngc", &program);
    let mut child = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(["inspect", "--all", path.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("program:"), "{first}");
    // stdout is dropped here: the pipe is closed with most of the listing unwritten.
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
}
