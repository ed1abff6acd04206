//! `cncsim plan` on the 5-axis study's program, checked from the CSV it writes alone: the
//! programmed points are passed exactly, and third differences of the positions stay within
//! the jerk limit on every machine axis.

mod common;

use std::path::Path;
use std::process::Command;

fn plan(scenario: &str, extra: &[&str]) -> (String, Vec<Vec<f64>>, Vec<String>) {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("setpoints.csv");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut args = vec!["plan", scenario, "--csv", csv.to_str().unwrap()];
    args.extend_from_slice(extra);
    let out = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(&args)
        .current_dir(root)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (stdout, rows, header)
}

#[test]
fn study_program_in_exact_stop_respects_every_limit_and_hits_every_point() {
    let (stdout, rows, header) = plan("scenarios/plan_table2_jerk.toml", &[]);
    assert_eq!(header, ["t_s", "x", "y", "z", "a", "c"]);
    // Cycle time: the sum of the closed-form jerk-limited times of each move's longest axis,
    // 4·(L/2J)^(1/3) for L = 50, 60, 50, 40, 30 (mm or deg) and J = 1000, sampled at 1 ms.
    let exact: f64 = [50.0f64, 60.0, 50.0, 40.0, 30.0]
        .iter()
        .map(|l| 4.0 * (l / 2000.0).cbrt())
        .sum();
    let samples = rows.len() as f64;
    assert!(
        (samples - 1.0) * 1e-3 >= exact - 1e-9 && (samples - 1.0) * 1e-3 < exact + 5e-3,
        "{samples} samples for {exact} s"
    );
    assert!(stdout.contains("cycle time"), "{stdout}");

    // Every programmed point is passed at rest (exact stop). The stop instant is not a multiple
    // of T, so the nearest sample is off by at most the jerk-limited creep of one period,
    // j·T³/6 = 1.7e-7 mm (or deg).
    let creep = 1000.0 * 1e-9 / 6.0;
    let points = [
        [20.0, 10.0, 30.0, 10.0, 50.0],
        [-40.0, 20.0, 0.0, 10.0, 30.0],
        [10.0, 30.0, -30.0, 20.0, 10.0],
        [50.0, 40.0, 0.0, 20.0, -10.0],
        [60.0, 50.0, 30.0, 20.0, -30.0],
    ];
    for p in points {
        let hit = rows
            .iter()
            .any(|r| (1..6).all(|i| (r[i] - p[i - 1]).abs() <= creep));
        assert!(hit, "programmed point {p:?} is not passed");
    }
    // Limits from differences of the positions alone (mm or deg units, T = 1 ms).
    let t = 1e-3;
    for axis in 1..6 {
        let q: Vec<f64> = rows.iter().map(|r| r[axis]).collect();
        let v = q
            .windows(2)
            .map(|w| (w[1] - w[0]) / t)
            .fold(0.0f64, |m, x| m.max(x.abs()));
        let a = q
            .windows(3)
            .map(|w| (w[2] - 2.0 * w[1] + w[0]) / (t * t))
            .fold(0.0f64, |m, x| m.max(x.abs()));
        let j = q
            .windows(4)
            .map(|w| (w[3] - 3.0 * w[2] + 3.0 * w[1] - w[0]) / (t * t * t))
            .fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(
            v <= 150.0 * 1.001 && a <= 1000.0 * 1.001 && j <= 1000.0 * 1.001,
            "axis {}: v {v} a {a} j {j}",
            header[axis]
        );
    }
}

#[test]
fn constant_velocity_profile_reproduces_the_study_segment_times() {
    let (stdout, rows, _) = plan(
        "scenarios/plan_table2_jerk.toml",
        &["--profile", "constant"],
    );
    // 0.422 + 0.471 + 0.422 + 0.365 + 0.258 s = 1.938 s; each move rounds up to whole ticks.
    let duration = (rows.len() - 1) as f64 * 1e-3;
    assert!((1.938..1.944).contains(&duration), "{duration}\n{stdout}");
}

#[test]
fn plan_writes_a_recording_of_the_setpoints() {
    let dir = tempfile::tempdir().unwrap();
    let rrd = dir.path().join("plan.rrd");
    let (_, rows, _) = plan(
        "scenarios/plan_table2_jerk.toml",
        &["--rrd", rrd.to_str().unwrap()],
    );
    let recorded = common::rrd_rows(&rrd);
    for axis in ["x", "y", "z", "a", "c"] {
        for series in ["position", "velocity", "acceleration"] {
            let path = format!("/setpoints/{axis}/{series}");
            assert_eq!(
                recorded.get(&path).copied(),
                Some(rows.len()),
                "{path}: {recorded:?}"
            );
        }
    }
    assert!(
        recorded.contains_key("/workpiece/tool_path"),
        "{recorded:?}"
    );
}

/// APT cutter-location data reaches the planner through the A-C mill's inverse kinematics; a
/// point the mill cannot reach is refused with its line.
#[test]
fn cl_data_is_planned_through_the_inverse_kinematics() {
    let (stdout, rows, header) = plan("scenarios/plan_table1_cl.toml", &[]);
    assert_eq!(header, ["t_s", "x", "y", "z", "a", "c"]);
    assert!(
        stdout.contains("tool tip in workpiece coordinates"),
        "{stdout}"
    );
    // The last CL point, (50, 100, 75) mm with axis (0.2, 0.5, 0.5), in machine coordinates
    // (A = atan2(√(i²+j²), k) = 47.124°, C = atan2(i, j) = 21.801°).
    let last = rows.last().unwrap();
    let expected = [64.9934, 145.9339, -196.0821, 47.1240, 21.8014];
    assert!(
        (1..6).all(|i| (last[i] - expected[i - 1]).abs() < 1e-3),
        "{last:?}"
    );

    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("scenarios/plan_table1_cl.toml"))
        .unwrap()
        .replace(
            "programs/d_table1_reachable.apt",
            &root
                .join("scenarios/programs/d_table1.apt")
                .display()
                .to_string(),
        )
        .replace(
            "../models/ac_mill.urdf",
            &root.join("models/ac_mill.urdf").display().to_string(),
        );
    let scenario = dir.path().join("full.toml");
    std::fs::write(&scenario, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(["plan", scenario.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(
            "d_table1.apt:6:1: outside the machine's travel: axis 'a' would be at 135.000°"
        ),
        "{err}"
    );
}

/// `[planner] naive_cam_tolerance_mm` (LinuxCNC's G64 Q): a chain of short lines that zig-zag
/// within the tolerance of one straight line plans as that line, faster than move by move;
/// with exact stops the key is refused at its place.
#[test]
fn naive_cam_tolerance_joins_collinear_short_lines() {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    // 40 lines of 1 mm along X, alternately 5 µm off the line.
    let points: Vec<String> = (0..=40)
        .map(|i| format!("[{}.0, {}, 0.0]", i, if i % 2 == 1 { 0.005 } else { 0.0 }))
        .collect();
    let scenario = |extra: &str, blend: &str| {
        format!(
            r#"machine = "{}/models/xyz_table.urdf"
[program]
polyline = {{ points_mm = [{}] }}
feed_mm_s = 100.0
[planner]
profile = "jerk-limited"
blend = "{blend}"
{extra}
limits.x = {{ velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }}
limits.y = {{ velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }}
limits.z = {{ velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }}
[timing]
servo_period_ms = 1.0
physics_step_ms = 0.25
"#,
            root.display(),
            points.join(", ")
        )
    };
    let path = root.join("scenarios/q_test.toml");
    let plan = |text: &str| {
        let s = cncsim::scenario::Scenario::parse(&path, text).unwrap();
        cncsim::scenario::plan_scenario(&s, None)
            .unwrap()
            .duration()
    };
    let without = plan(&scenario("", "continuous"));
    let with = plan(&scenario("naive_cam_tolerance_mm = 0.01", "continuous"));
    eprintln!("joined {with} s, move by move {without} s");
    assert!(
        with < 0.9 * without,
        "joined: {with} s, move by move: {without} s"
    );
    let refused = cncsim::scenario::Scenario::parse(
        &path,
        &scenario("naive_cam_tolerance_mm = 0.01", "exact-stop"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        refused.contains("q_test.toml:8:") && refused.contains("naive_cam_tolerance_mm"),
        "{refused}"
    );
}

#[test]
fn a_chain_longer_than_the_look_ahead_is_reported_with_its_handoffs() {
    // 12 000 lines of 1 mm on a curve (CAM raster rows, G64 P0.05 with naive-CAM joining off):
    // one chain, three times the look-ahead.
    let dir = tempfile::tempdir().unwrap();
    let program = format!(
        "G21 G90 G64 P0.05 Q0\nG0 X0 Y0 Z1\nF6000\n{}M2\n",
        common::raster_gcode(12_000)
    );
    std::fs::write(dir.path().join("raster.ngc"), program).unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenario = format!(
        "name = \"raster\"\nmachine = \"{}\"\n[program]\nfile = \"raster.ngc\"\n\
         [planner]\nprofile = \"jerk-limited\"\n\
         limits.x = {{ velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }}\n\
         limits.y = {{ velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }}\n\
         limits.z = {{ velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }}\n\
         [timing]\nservo_period_ms = 1.0\nphysics_step_ms = 0.25\n",
        root.join("models/xyz_table.urdf").display()
    );
    let file = dir.path().join("raster.toml");
    std::fs::write(&file, scenario).unwrap();
    let (stdout, rows, _) = plan(file.to_str().unwrap(), &[]);
    assert!(
        stdout.contains(
            "look-ahead 4096 blocks: 3 handoffs inside longer chains, 0 stops added where no \
             handoff could be made"
        ),
        "{stdout}"
    );
    // 12 m at the programmed 100 mm/s: 120 s, a little more where the curve bends.
    assert!(
        (120_000..125_000).contains(&rows.len()),
        "{} samples",
        rows.len()
    );
}
