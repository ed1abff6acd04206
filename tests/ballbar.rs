//! `cncsim ballbar`, the ISO 230-4 circular test, end to end and against what is known
//! independently of it:
//! - the least-squares and minimum-zone circles and the figures G, H, F, computed by a Python
//!   oracle (numpy/scipy, `tests/oracles/ballbar_oracle.py`) on the trace cncsim wrote;
//!   skipped without numpy/scipy unless `CNCSIM_REQUIRE_ORACLES=1` (then a failure);
//! - the servo-mismatch ellipse of first-order position loops with different gains against
//!   its closed form (docs/ballbar.md);
//! - backlash written in a drive file against the backlash the diagnosis reports.

mod common;

use common::{cncsim, stderr};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Runs `cncsim ballbar ARGS --json --out OUT` and returns the report.
fn ballbar_json(args: &[&str], out: &Path) -> serde_json::Value {
    common::cncsim_json("ballbar", args, out)
}

fn num(v: &serde_json::Value, path: &str) -> f64 {
    path.split('.')
        .try_fold(v, |v, k| v.get(k))
        .and_then(|v| v.as_f64())
        .unwrap_or_else(|| panic!("no number at {path} in {v}"))
}

#[test]
fn end_to_end_series_json_and_files() {
    let dir = tempfile::tempdir().unwrap();
    let report = ballbar_json(
        &[
            "scenarios/xyz_circle_5mms.toml",
            "--radius-mm",
            "5",
            "--feed-mm-min",
            "600,1200",
        ],
        dir.path(),
    );
    let runs = report["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2, "one run per feed");
    for (run, feed) in runs.iter().zip([600.0, 1200.0]) {
        assert_eq!(num(run, "feed_mm_min"), feed);
        assert_eq!(num(run, "radius_mm"), 5.0);
        for d in ["cw", "ccw"] {
            let g = num(run, &format!("{d}.circular_deviation_um"));
            let mz = num(run, &format!("{d}.circular_deviation_min_zone_um"));
            // The minimum zone is the narrowest annulus: never wider than the one about the
            // least-squares centre.
            assert!(
                g.is_finite() && mz <= g + 1e-9,
                "{d}: G {g}, minimum zone {mz}"
            );
            // The demo table (ideal mechanics, stiff PID) follows a 5 mm circle within 1 µm.
            assert!(g < 1.0, "{d}: G {g} µm");
            assert!(
                num(run, &format!("{d}.radial_deviation_max_um"))
                    >= num(run, &format!("{d}.radial_deviation_min_um"))
            );
        }
        assert!(num(run, "circular_hysteresis_um").is_finite());
        for axis in ["x", "y"] {
            assert!(num(run, &format!("backlash_um.{axis}")).is_finite());
        }
        let spikes = run["reversal_spikes"].as_array().unwrap();
        assert_eq!(spikes.len(), 8, "two reversals per axis and direction");
        for s in spikes {
            assert!(["x", "y"].contains(&s["axis"].as_str().unwrap()));
            assert!(["cw", "ccw"].contains(&s["direction"].as_str().unwrap()));
            assert!(s["height_um"].as_f64().unwrap().is_finite());
        }
    }
    for folder in ["F600_R5", "F1200_R5"] {
        let run = dir.path().join(folder);
        let png = std::fs::read(run.join("polar.png")).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        let csv = std::fs::read_to_string(run.join("polar.csv")).unwrap();
        assert!(csv.starts_with("direction,t_s,angle_deg,radial_deviation_um,x_mm,y_mm\n"));
        // Each run's metrics carry the ballbar figures as metric keys.
        let metrics: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(run.join("metrics.json")).unwrap())
                .unwrap();
        assert!(num(&metrics, "ballbar.ccw.circular_deviation_um").is_finite());
        assert!(num(&metrics, "ballbar.circular_hysteresis_um").is_finite());
    }
    assert!(dir.path().join("ballbar.json").is_file());
    // The recording's polar view: per run the nominal circle, the rings, both directions and
    // the figures.
    let entities = common::rrd_rows(&dir.path().join("ballbar.rrd"));
    for run in ["F600_R5", "F1200_R5"] {
        for part in ["nominal", "grid", "ccw", "cw", "figures"] {
            let entity = format!("/ballbar/{run}/{part}");
            assert!(
                entities.contains_key(&entity),
                "{entity} not in {:?}",
                entities.keys()
            );
        }
    }

    // The terminal report of the same test.
    let out = dir.path().join("text");
    let o = cncsim(&[
        "ballbar",
        "scenarios/xyz_circle_5mms.toml",
        "--radius-mm",
        "5",
        "--feed-mm-min",
        "1200",
        "--plane",
        "zx",
        "--out",
        &out.display().to_string(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    for needle in [
        "plane ZX",
        "circular deviation G (least squares)",
        "circular hysteresis H",
        "backlash: Z",
        "servo mismatch",
        "reversal spikes",
        "wrote",
    ] {
        assert!(text.contains(needle), "{needle:?} missing from:\n{text}");
    }
}

#[test]
fn bad_input_exits_2_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().display().to_string();
    let cases: [(&[&str], &str); 5] = [
        (&["--radius-mm", "-5"], "--radius-mm -5: must be a positive number"),
        (&["--feed-mm-min", "0"], "--feed-mm-min 0: must be a positive number"),
        (&["--center-mm", "1,2"], "--center-mm takes 3 finite values"),
        // The table's X and Y travel is −20 … 320 mm: 200 mm about (100, 100) does not fit.
        (
            &["--radius-mm", "200"],
            "a ballbar circle of radius 200.000 mm (plus the 1.5 mm feed-in) does not fit the machine's travel (X -20.000 … 320.000 mm, Y -20.000 … 320.000 mm)",
        ),
        (
            &["--radius-mm", "30", "--center-mm", "0,0,0"],
            "does not fit the machine's travel",
        ),
    ];
    for (args, message) in cases {
        let mut all = vec!["ballbar", "scenarios/xyz_circle_5mms.toml", "--out", &out];
        all.extend_from_slice(args);
        let o = cncsim(&all);
        assert_eq!(o.status.code(), Some(2), "{all:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(message), "{all:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"));
    }
    let o = cncsim(&["ballbar", "scenarios/no_such_file.toml", "--out", &out]);
    assert_eq!(o.status.code(), Some(2));
}

/// The Python with numpy and scipy, or `None` (a failure under `CNCSIM_REQUIRE_ORACLES=1`).
fn python_with_scipy() -> Option<String> {
    common::oracle_python("import numpy, scipy.optimize", "numpy and scipy")
}

#[test]
fn least_squares_and_minimum_zone_circles_agree_with_scipy() {
    let Some(python) = python_with_scipy() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // The calibrated paper twin at 15 mm/s: hunting after every reversal, so the traces are
    // far from circles and the two centres (least squares, minimum zone) differ.
    let report = ballbar_json(&["scenarios/paper_circle_15mms.toml"], dir.path());
    let run = &report["runs"][0];
    let o = Command::new(python)
        .arg(root().join("tests/oracles/ballbar_oracle.py"))
        .arg(dir.path().join("F900_R30/polar.csv"))
        .args(["100", "100", "30"])
        .output()
        .unwrap();
    assert!(o.status.success(), "oracle failed: {}", stderr(&o));
    let oracle: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for d in ["cw", "ccw"] {
        // Least squares: both solve the same smooth problem to round-off.
        for (key, tolerance) in [
            ("circular_deviation_um", 1e-4),
            ("least_squares_radius_mm", 1e-9),
            ("radial_deviation_max_um", 1e-6),
            ("radial_deviation_min_um", 1e-6),
        ] {
            let (a, b) = (
                num(run, &format!("{d}.{key}")),
                num(&oracle, &format!("{d}.{key}")),
            );
            assert!(
                (a - b).abs() <= tolerance,
                "{d}.{key}: cncsim {a}, scipy {b}"
            );
        }
        for i in 0..2 {
            let (a, b) = (
                run[d]["least_squares_centre_offset_um"][i]
                    .as_f64()
                    .unwrap(),
                oracle[d]["least_squares_centre_offset_um"][i]
                    .as_f64()
                    .unwrap(),
            );
            assert!(
                (a - b).abs() <= 1e-4,
                "{d} centre[{i}]: cncsim {a}, scipy {b}"
            );
        }
        // Minimum zone: a nested golden-section search here, re-linearised linear programmes
        // (HiGHS) there; 0.02 µm on zones of about 2 mm (measured 0.0075 µm, cncsim's the
        // narrower).
        let key = "circular_deviation_min_zone_um";
        let (a, b) = (
            num(run, &format!("{d}.{key}")),
            num(&oracle, &format!("{d}.{key}")),
        );
        assert!((a - b).abs() <= 0.02, "{d}.{key}: cncsim {a}, scipy {b}");
        assert!(
            a < num(run, &format!("{d}.circular_deviation_um")) - 1.0,
            "the twin's zones differ"
        );
    }
    let (a, b) = (
        num(run, "circular_hysteresis_um"),
        num(&oracle, "circular_hysteresis_um"),
    );
    assert!((a - b).abs() <= 1e-3, "H: cncsim {a}, numpy {b}");
}

/// The XYZ table without friction or backlash, ideal torque drives, a cascade whose velocity
/// loop (about 300 rad/s) is far faster than its P position loop and has no feed-forward: each
/// axis follows as a first-order lag 1/(1 + s/K).
fn first_order_scenario(dir: &Path, kx: f64, ky: f64) -> PathBuf {
    let text = format!(
        r#"name = "mismatch"
machine = "{machine}"
[program]
circle = {{ center_mm = [100.0, 100.0], radius_mm = 10.0, start_angle_deg = 0.0, direction = "ccw", z_mm = 0.0 }}
feed_mm_s = 10.0
[planner]
profile = "constant-velocity"
[timing]
servo_period_ms = 1.0
physics_step_ms = 0.25
settle_s = 0.2
[mechanics]
friction = false
backlash = false
[actuator]
model = "ideal-torque"
[controller]
type = "cascade"
cascade.x = {{ position_kp = {kx}, velocity_kp = 48.0, velocity_ki = 0.0, velocity_ff = 0.0, acceleration_ff = 0.0 }}
cascade.y = {{ position_kp = {ky}, velocity_kp = 48.0, velocity_ki = 0.0, velocity_ff = 0.0, acceleration_ff = 0.0 }}
cascade.z = {{ position_kp = 20.0, velocity_kp = 48.0, velocity_ki = 0.0, velocity_ff = 0.0, acceleration_ff = 0.0 }}
[recording]
rrd = false
csv = false
"#,
        machine = root().join("models/xyz_table.urdf").display()
    );
    let path = dir.join(format!("mismatch_{kx}_{ky}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn servo_mismatch_of_first_order_loops_matches_the_closed_form() {
    let dir = tempfile::tempdir().unwrap();
    let (radius, speed) = (10e-3, 10e-3);
    let omega = speed / radius;
    for (kx, ky, lagging) in [(10.0, 20.0, "x"), (20.0, 10.0, "y")] {
        let scenario = first_order_scenario(dir.path(), kx, ky);
        let report = ballbar_json(
            &[scenario.to_str().unwrap()],
            &dir.path().join(format!("out_{kx}_{ky}")),
        );
        let m = &report["runs"][0]["servo_mismatch"];
        // docs/ballbar.md: phase lags φ = atan(ω/K) draw Δr = ±R(φx − φy)/2 · sin 2θ, the
        // sign flipping with the direction; the lag difference is (φx − φy)/ω.
        let (phx, phy) = ((omega / kx).atan(), (omega / ky).atan());
        let lag = (phx - phy) / omega;
        let ellipse = radius * (phx - phy).abs();
        let measured_lag = m["lag_difference_ms"].as_f64().unwrap() * 1e-3;
        let measured_ellipse = m["ellipse_um"].as_f64().unwrap() * 1e-6;
        assert_eq!(m["lagging_axis"], lagging);
        // 3 %: the velocity loop's own lag and the sampling (a few tenths of a percent), and
        // what the cubic of the backlash fit leaves of the ellipse (about 1 %).
        assert!(
            (measured_lag - lag).abs() <= 0.03 * lag.abs(),
            "Kx {kx}, Ky {ky}: lag difference {measured_lag} s, closed form {lag} s"
        );
        assert!(
            (measured_ellipse - ellipse).abs() <= 0.03 * ellipse,
            "Kx {kx}, Ky {ky}: ellipse {measured_ellipse} m, closed form {ellipse} m"
        );
        // Nothing else in the model: no lost motion.
        for axis in ["x", "y"] {
            let b = num(&report["runs"][0], &format!("backlash_um.{axis}"));
            assert!(b.abs() < 0.03 * ellipse * 1e6, "backlash {axis} {b} µm");
        }
    }
}

#[test]
fn backlash_in_the_drive_file_is_the_backlash_reported() {
    let dir = tempfile::tempdir().unwrap();
    // The table with other backlash than it ships with, the loops closed on the motors (a
    // lost motion the loop cannot see, as a ballbar finds it), guide friction on.
    let (bx, by) = (0.20e-3, 0.60e-3);
    std::fs::copy(
        root().join("models/xyz_table.urdf"),
        dir.path().join("xyz_table.urdf"),
    )
    .unwrap();
    let drives = std::fs::read_to_string(root().join("models/xyz_table.drives.toml")).unwrap();
    let drives = drives
        .replace("backlash = 0.32e-3", &format!("backlash = {bx:e}"))
        .replace("backlash = 0.45e-3", &format!("backlash = {by:e}"));
    assert!(
        drives.contains(&format!("backlash = {bx:e}"))
            && drives.contains(&format!("backlash = {by:e}"))
    );
    std::fs::write(dir.path().join("xyz_table.drives.toml"), drives).unwrap();
    let scenario = dir.path().join("backlash.toml");
    std::fs::write(
        &scenario,
        r#"name = "backlash"
machine = "xyz_table.urdf"
[program]
circle = { center_mm = [100.0, 100.0], radius_mm = 25.0, start_angle_deg = 0.0, direction = "ccw", z_mm = 0.0 }
feed_mm_s = 10.0
[planner]
profile = "constant-velocity"
[timing]
servo_period_ms = 1.0
physics_step_ms = 0.25
settle_s = 0.5
[mechanics]
friction = true
backlash = true
[feedback]
position = "motor"
[actuator]
model = "dc-motor"
amplifier_mode = "voltage"
[controller]
type = "pid"
axes.x = { kp = 19800.0, ki = 6.1e5, kd = 146.0, output_limit = 6.0 }
axes.y = { kp = 19800.0, ki = 6.1e5, kd = 146.0, output_limit = 6.0 }
axes.z = { kp = 9700.0, ki = 3.0e5, kd = 85.0, output_limit = 3.125 }
[recording]
rrd = false
csv = false
"#,
    )
    .unwrap();
    let report = ballbar_json(&[scenario.to_str().unwrap()], &dir.path().join("out"));
    let run = &report["runs"][0];
    for (axis, b) in [("x", bx), ("y", by)] {
        let reported = num(run, &format!("backlash_um.{axis}")) * 1e-6;
        // 3 % (measured: 0.1–0.2 % on the shipped 0.32 / 0.45 mm at r = 30 mm).
        assert!(
            (reported - b).abs() <= 0.03 * b,
            "{axis}: drive file {b} m, reported {reported} m"
        );
    }
    // A lost motion on both axes opens the two directions apart: H is at least the larger.
    assert!(num(run, "circular_hysteresis_um") * 1e-6 > 0.5 * by);
}

/// A scenario whose program is the test (`[program] ballbar`): its figures are metrics that
/// `[expect]` bounds, `ab` tables and sweep results read.
#[test]
fn ballbar_figures_are_metrics_for_expect_ab_and_sweeps() {
    let dir = tempfile::tempdir().unwrap();
    let bundled = root().join("scenarios/ballbar_xyz_servo_mismatch.toml");
    let out = dir.path().display().to_string();
    let o = cncsim(&["check", bundled.to_str().unwrap(), "--out", &out]);
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        stderr(&o)
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("PASS"));
    let metrics: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("ballbar_xyz_servo_mismatch/metrics.json"))
            .unwrap(),
    )
    .unwrap();
    assert!(num(&metrics, "ballbar.servo_mismatch_um") > 400.0);
    assert!(dir
        .path()
        .join("ballbar_xyz_servo_mismatch/polar.png")
        .is_file());

    // A bound the run breaches fails `check`, naming the figure; an unknown one is bad input.
    let text = std::fs::read_to_string(&bundled).unwrap().replace(
        "../models/",
        &format!("{}/", root().join("models").display()),
    );
    let breached = dir.path().join("breached.toml");
    std::fs::write(
        &breached,
        text.replace(
            "ballbar.servo_mismatch_um = { min = 482.2, max = 512.0 }",
            "ballbar.servo_mismatch_um = { max = 100.0 }",
        ),
    )
    .unwrap();
    let o = cncsim(&["check", breached.to_str().unwrap(), "--out", &out]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stdout).contains("ballbar.servo_mismatch_um"));
    let unknown = dir.path().join("unknown.toml");
    std::fs::write(
        &unknown,
        text.replace("ballbar.backlash_um.y =", "ballbar.backlash_um.z ="),
    )
    .unwrap();
    let o = cncsim(&["run", unknown.to_str().unwrap(), "--out", &out]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("expect.ballbar.backlash_um.z: no such metric"),
        "{}",
        stderr(&o)
    );

    // A/B: the file's [ab] matches the gains; the ballbar rows compare the two.
    let ab = dir.path().join("ab");
    let o = cncsim(&[
        "ab",
        bundled.to_str().unwrap(),
        "--out",
        ab.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ab.join("ab.json")).unwrap()).unwrap();
    let row = report["rows"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["metric"] == "ballbar servo_mismatch_um")
        .expect("a ballbar row");
    assert!(
        row["a"].as_f64().unwrap() > 400.0 && row["b"].as_f64().unwrap() < 1.0,
        "{row}"
    );

    // A sweep over the position gain of Y: its results carry the ballbar figures.
    let sweep = dir.path().join("sweep.toml");
    std::fs::write(
        &sweep,
        format!(
            r#"name = "ballbar_sweep"
scenarios = ["{}"]
[variants]
base = []
[grid]
"controller.cascade.y.position_kp" = [10.0, 40.0]
[report]
metrics = ["ballbar.servo_mismatch_um", "ballbar.ccw.circular_deviation_um"]
"#,
            bundled.display()
        ),
    )
    .unwrap();
    let sweep_out = dir.path().join("sweep_out");
    let o = cncsim(&[
        "sweep",
        sweep.to_str().unwrap(),
        "--jobs",
        "2",
        "--out",
        sweep_out.to_str().unwrap(),
    ]);
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        stderr(&o)
    );
    let csv = std::fs::read_to_string(sweep_out.join("results.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let column = header
        .iter()
        .position(|h| *h == "ballbar.servo_mismatch_um")
        .expect("a ballbar column in results.csv");
    let values: Vec<f64> = csv
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(column)?.parse().ok())
        .collect();
    assert_eq!(values.len(), 2, "{csv}");
    // Equal gains (10, 10): no ellipse; 10 against 40: a larger one than the bundled 10/20.
    let (lo, hi) = (
        values.iter().copied().fold(f64::INFINITY, f64::min),
        values.iter().copied().fold(0.0, f64::max),
    );
    assert!(lo < 1.0 && hi > 600.0, "{values:?}");
}
