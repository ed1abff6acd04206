//! One regression test per defect found by mutating the bundled inputs (issue 13): each ran
//! as a user would (the `cncsim` binary), each must now end with a clear, located error and
//! exit status 2 — never a panic, a hang, an abort or a silent nonsense result.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn bundled(name: &str) -> String {
    std::fs::read_to_string(root().join(name)).unwrap()
}

/// Runs `cncsim ARGS` in `dir`, failing the test if it takes longer than `budget`.
fn cncsim(dir: &Path, args: &[&str], budget: Duration) -> Output {
    let started = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        started.elapsed() < budget,
        "{args:?} took {:?} (budget {budget:?})",
        started.elapsed()
    );
    out
}

/// Asserts a clean bad-input exit: status 2, no panic, and the message contains `words`.
fn assert_bad_input(out: &Output, words: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    for w in words {
        assert!(stderr.contains(w), "missing {w:?} in: {stderr}");
    }
    stderr
}

/// A copy of the XYZ table (URDF and drives) in `dir`, edited, and a scenario running the
/// default circle on it; returns the scenario path.
struct Copy {
    dir: tempfile::TempDir,
}

impl Copy {
    fn new(
        urdf: impl Fn(&str) -> String,
        drives: impl Fn(&str) -> String,
        scenario: impl Fn(&str) -> String,
    ) -> Copy {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("m.urdf"), urdf(&bundled("models/xyz_table.urdf"))).unwrap();
        std::fs::write(
            d.join("m.drives.toml"),
            drives(&bundled("models/xyz_table.drives.toml")),
        )
        .unwrap();
        let s = bundled("scenarios/xyz_circle_5mms.toml")
            .replace("../models/xyz_table.urdf", "m.urdf")
            // No [expect]: these tests are about inputs, not about results.
            .split("[expect]")
            .next()
            .unwrap()
            .to_string();
        std::fs::write(d.join("s.toml"), scenario(&s)).unwrap();
        Copy { dir }
    }

    fn scenario(edit: impl Fn(&str) -> String) -> Copy {
        Copy::new(|u| u.to_string(), |d| d.to_string(), edit)
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }
}

const SHORT: Duration = Duration::from_secs(20);

#[test]
fn defect_1_tiny_feed_or_rapid_is_refused_not_a_capacity_overflow() {
    let c = Copy::scenario(|s| s.replace("feed_mm_s = 5.0", "feed_mm_s = 1e-300"));
    let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
    assert_bad_input(
        &out,
        &["s.toml:9:13: feed_mm_s = 1e-300 mm/s: expected a value from 0.001 to 20000.0 mm/s"],
    );
    let c = Copy::scenario(|s| {
        s.replace(
            "profile = \"constant-velocity\"",
            "profile = \"constant-velocity\"\nrapid_mm_s = 1e-300",
        )
    });
    let out = cncsim(c.path(), &["plan", "s.toml"], SHORT);
    assert_bad_input(
        &out,
        &["rapid_mm_s = 1e-300 mm/s: expected a value from 0.001"],
    );
}

#[test]
fn defect_2_tiny_planner_limits_are_refused_not_unbounded_memory() {
    let dir = tempfile::tempdir().unwrap();
    let text = bundled("scenarios/plan_table2_jerk.toml")
        .replace("../models/", &format!("{}/models/", root().display()))
        .replace(
            "programs/",
            &format!("{}/scenarios/programs/", root().display()),
        );
    let limit = text
        .lines()
        .find(|l| l.contains("jerk = "))
        .expect("the jerk scenario gives limits");
    let jerk = limit
        .split("jerk = ")
        .nth(1)
        .unwrap()
        .split([',', ' ', '}'])
        .next()
        .unwrap();
    let edited = text.replacen(
        limit,
        &limit.replace(&format!("jerk = {jerk}"), "jerk = 1e-300"),
        1,
    );
    std::fs::write(dir.path().join("s.toml"), edited).unwrap();
    for command in ["plan", "run", "check"] {
        let out = cncsim(dir.path(), &[command, "s.toml"], SHORT);
        assert_bad_input(
            &out,
            &["jerk = 1e-300 mm/s³ or deg/s³: expected a value from 0.001"],
        );
    }
}

#[test]
fn defect_3_deeply_nested_urdf_is_refused_before_the_recursive_reader() {
    let depth = 200_000;
    let deep = format!(
        "<robot name=\"xyz_table\">{}{}",
        "<a>".repeat(depth),
        "</a>".repeat(depth)
    );
    let c = Copy::new(
        |u| u.replacen("<robot name=\"xyz_table\">", &deep, 1),
        |d| d.to_string(),
        |s| s.to_string(),
    );
    for args in [
        vec!["run", "s.toml"],
        vec!["plan", "s.toml"],
        vec![
            "dynamics", "m.urdf", "--q", "0,0,0", "--qd", "0,0,0", "--qdd", "0,0,0",
        ],
    ] {
        let out = cncsim(c.path(), &args, Duration::from_secs(10));
        assert_bad_input(&out, &["m.urdf:11:", "nested more than 64 deep"]);
    }
}

#[test]
fn defect_4_impossible_drive_constant_is_refused() {
    // The run that stopped early and then lost its stop message to a panic while writing the
    // recording began with a pulley of 1e300 m: refused at load now. (Early stops keeping
    // everything are tested in `tests/early_stop.rs`.)
    let c = Copy::new(
        |u| u.to_string(),
        |d| d.replacen("pulley_radius_m = 0.025", "pulley_radius_m = 1e300", 1),
        |s| s.to_string(),
    );
    let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
    assert_bad_input(
        &out,
        &[
            "m.drives.toml:",
            "axis 'x': pulley_radius_m = 1e300 m: expected a value from 0.0001 to 1.0 m",
        ],
    );
}

#[test]
fn defect_5_unbounded_timing_is_refused() {
    for (from, to, words) in [
        (
            "servo_period_ms = 1.0",
            "servo_period_ms = 1e300",
            "servo_period_ms = 1e300 ms: expected a value from 0.01 to 100.0 ms",
        ),
        (
            "physics_step_ms = 0.25",
            "physics_step_ms = 1e-300",
            "physics_step_ms = 1e-300 ms: expected a value from 0.001 to 100.0 ms",
        ),
        (
            "physics_step_ms = 0.25",
            "physics_step_ms = 1e300",
            "physics_step_ms = 1e300 ms: expected a value",
        ),
        (
            "settle_s = 0.5",
            "settle_s = 1e300",
            "settle_s = 1e300 s: expected a value from 0.0 to 3600.0 s",
        ),
    ] {
        let c = Copy::scenario(|s| s.replace(from, to));
        let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
        let stderr = assert_bad_input(&out, &["s.toml:", words]);
        // Short numbers, never 301 digits.
        assert!(stderr.len() < 400, "{stderr}");
    }
}

#[test]
fn defect_5_a_run_longer_than_the_bound_says_how_many_ticks_it_needs() {
    // Each value in range, together too long: 3600 s settle at 0.01 ms is 3.6e8 ticks.
    let c = Copy::scenario(|s| {
        s.replace("servo_period_ms = 1.0", "servo_period_ms = 0.01")
            .replace("physics_step_ms = 0.25", "physics_step_ms = 0.01")
            .replace("settle_s = 0.5", "settle_s = 3600.0")
    });
    let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
    assert_bad_input(
        &out,
        &["the run needs 3", "servo ticks", "the limit is 100000000"],
    );
}

#[test]
fn defect_6_check_exits_2_on_bad_input() {
    let c = Copy::scenario(|s| s.replace("servo_period_ms = 1.0", "servo_period_ms = -1.0"));
    let out = cncsim(c.path(), &["check", "s.toml"], SHORT);
    assert_bad_input(&out, &["servo_period_ms = -1.0 ms"]);
}

#[test]
fn absurd_link_masses_are_refused() {
    let x_mass = |u: &str, to: &str| {
        u.replacen(
            "<mass value=\"8.0\"/>",
            &format!("<mass value=\"{to}\"/>"),
            1,
        )
    };
    for (mass, words) in [
        (
            "1e300",
            "mass 1e300 kg: expected 0 (a massless frame) or a mass from 1e-12 to 100000.0 kg",
        ),
        (
            "1e-300",
            "mass 1e-300 kg: expected 0 (a massless frame) or a mass from 1e-12",
        ),
        // Within range, but with the link's own inertia: a body 40 km across.
        ("2e-6", "radius of gyration"),
    ] {
        let c = Copy::new(|u| x_mass(u, mass), |d| d.to_string(), |s| s.to_string());
        let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
        assert_bad_input(&out, &["m.urdf:", "link 'x_carriage'", words]);
    }
    // A 10 t carriage is legal but suspect: it loads with a warning.
    let machine = std::fs::read_to_string(root().join("models/xyz_table.urdf")).unwrap();
    let heavy = x_mass(&machine, "10000.0");
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("m.urdf");
    std::fs::write(&urdf, &heavy).unwrap();
    std::fs::write(
        dir.path().join("m.drives.toml"),
        bundled("models/xyz_table.drives.toml"),
    )
    .unwrap();
    let m = cncsim::machine::Machine::load(&urdf).unwrap();
    assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
    assert!(m.warnings[0]
        .to_string()
        .contains("mass 10000.0 kg is more than 5000.0 kg"));
}

#[test]
fn backlash_beyond_the_travel_is_refused() {
    for backlash in ["10.0", "1e300"] {
        let c = Copy::new(
            |u| u.to_string(),
            |d| d.replacen("backlash = 0.32e-3", &format!("backlash = {backlash}"), 1),
            |s| s.to_string(),
        );
        let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
        assert_bad_input(
            &out,
            &[
                "m.drives.toml:",
                "axis 'x': backlash = ",
                "is not smaller than the travel",
            ],
        );
    }
}

#[test]
fn absurd_feed_is_refused() {
    let c = Copy::scenario(|s| s.replace("feed_mm_s = 5.0", "feed_mm_s = 1e300"));
    let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
    assert_bad_input(
        &out,
        &["feed_mm_s = 1e300 mm/s: expected a value from 0.001 to 20000.0 mm/s"],
    );
}

#[test]
fn infinite_bound_is_refused() {
    let c = Copy::scenario(|s| format!("{s}\n[expect]\nmax_contour_error_mm = {{ max = -inf }}\n"));
    let out = cncsim(c.path(), &["check", "s.toml"], SHORT);
    assert_bad_input(
        &out,
        &["expect.max_contour_error_mm.max = -inf: expected a finite number"],
    );
}

#[test]
fn empty_program_is_refused() {
    let c = Copy::scenario(|s| {
        s.replace(
            "circle = { center_mm = [100.0, 100.0], radius_mm = 30.0, start_angle_deg = 0.0, direction = \"ccw\", z_mm = 0.0 }\nfeed_mm_s = 5.0",
            "file = \"empty.ngc\"",
        )
    });
    std::fs::write(c.path().join("empty.ngc"), "").unwrap();
    let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
    assert_bad_input(&out, &["empty.ngc: the program has no moves"]);
}

#[test]
fn urdf_structure_errors_name_the_joint_and_line() {
    // A joint without a parent: the joint's name and line, not serde's "missing field".
    let machine = bundled("models/xyz_table.urdf");
    let parent = machine
        .lines()
        .find(|l| l.trim_start().starts_with("<parent link="))
        .unwrap();
    let c = Copy::new(
        |u| u.replacen(parent, "", 1),
        |d| d.to_string(),
        |s| s.to_string(),
    );
    let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
    let stderr = assert_bad_input(&out, &["m.urdf:", "has no <parent link=\"…\"/>"]);
    assert!(stderr.contains("joint '"), "{stderr}");
    // Truncated: where it ends and what is open.
    let cut = |u: &str| {
        let inertial = u.match_indices("<inertial>").nth(1).unwrap().0;
        u[..inertial + "<inertial>".len()].to_string()
    };
    let c = Copy::new(cut, |d| d.to_string(), |s| s.to_string());
    let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
    assert_bad_input(
        &out,
        &[
            "m.urdf:",
            "the file ends inside <inertial> (opened at line",
            "truncated?",
        ],
    );
}

#[test]
fn a_kinematic_cycle_names_its_joints() {
    // Make the X carriage the child of the Y carriage, which is the child of X: a cycle.
    let machine = bundled("models/xyz_table.urdf");
    let edited = machine.replacen(
        "<parent link=\"base\"/>",
        "<parent link=\"y_carriage\"/>",
        1,
    );
    assert_ne!(edited, machine, "the table's X joint hangs on the base");
    let c = Copy::new(|_| edited.clone(), |d| d.to_string(), |s| s.to_string());
    let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
    let stderr = assert_bad_input(&out, &["m.urdf:", "form a cycle"]);
    assert!(stderr.contains("'x'") && stderr.contains("'y'"), "{stderr}");
}

#[test]
fn a_far_away_circle_is_refused_with_its_numbers() {
    let c =
        Copy::scenario(|s| s.replace("center_mm = [100.0, 100.0]", "center_mm = [1e300, 100.0]"));
    let out = cncsim(c.path(), &["run", "s.toml"], SHORT);
    assert_bad_input(
        &out,
        &[
            "s.toml:8:",
            "circle: expected numbers within ±100000.0 mm",
            "center_mm = [1e300, 100.0]",
        ],
    );
}
