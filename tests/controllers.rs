//! The controller structures against closed-form expectations, through the one servo loop (on
//! the analytic model, which has every controller because there is only one loop, and on the
//! physics):
//! - PID with exact model feed-forward (FF1 = c/b, FF2 = m/b) follows a jerk-limited move with
//!   a far smaller error than the plain PID;
//! - the cascade with velocity and inertia feed-forward likewise;
//! - backlash compensation removes the lost motion of a semi-closed loop (motor encoder) at a
//!   reversal, to within 10 % of what it was without;
//! - a friction pulse at the reversal shortens the stall that Coulomb friction causes there.

use cncsim::scenario::{limits, Assembly, Override, RunOptions, Scenario};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The XYZ table in current mode on a jerk-limited out-and-back move along X (25 mm each way,
/// 20 mm/s), analytic model beside the physics, no recording.
const BASE: &str = r#"
name = "controllers"
machine = "MODEL"
[program]
polyline = { points_mm = [[100.0, 100.0, 0.0], [125.0, 100.0, 0.0], [100.0, 100.0, 0.0]] }
feed_mm_s = 20.0
[planner]
profile = "jerk-limited"
blend = "exact-stop"
limits.x = { velocity = 20.0, acceleration = 200.0, jerk = 4000.0 }
limits.y = { velocity = 20.0, acceleration = 200.0, jerk = 4000.0 }
limits.z = { velocity = 20.0, acceleration = 200.0, jerk = 4000.0 }
[timing]
servo_period_ms = 1.0
physics_step_ms = 0.25
settle_s = 0.5
[mechanics]
friction = false
backlash = false
[actuator]
model = "dc-motor"
amplifier_mode = "current"
[controller]
type = "pid"
axes.x = { kp = 2000.0, ki = 20000.0, kd = 40.0, output_limit = 6.0 }
axes.y = { kp = 2000.0, ki = 20000.0, kd = 40.0, output_limit = 6.0 }
axes.z = { kp = 2000.0, ki = 20000.0, kd = 40.0, output_limit = 3.125 }
cascade.x = { position_kp = 61.7, velocity_kp = 208.0, velocity_ki = 12840.0, output_limit = 6.0 }
cascade.y = { position_kp = 61.9, velocity_kp = 206.3, velocity_ki = 12780.0, output_limit = 6.0 }
cascade.z = { position_kp = 61.0, velocity_kp = 97.0, velocity_ki = 5920.0, output_limit = 3.125 }
[analytic]
enabled = true
[recording]
rrd = false
csv = false
"#;

fn scenario(dir: &Path, overrides: &[&str]) -> Scenario {
    let text = BASE.replace(
        "MODEL",
        &root().join("models/xyz_table.urdf").display().to_string(),
    );
    let path = dir.join("s.toml");
    std::fs::write(&path, text).unwrap();
    let overrides: Vec<Override> = overrides
        .iter()
        .map(|o| Override::parse(o).unwrap())
        .collect();
    Scenario::load_with_overrides(&path, &overrides, "--a").unwrap()
}

/// Max following error of X (µm) on the physics and on the analytic model.
fn x_error(dir: &Path, overrides: &[&str]) -> (f64, f64) {
    let s = scenario(dir, overrides);
    let run = Assembly::new(&s)
        .unwrap()
        .run(RunOptions::write_to(dir.join("out")).traced())
        .unwrap();
    assert!(run.stop().is_none(), "{overrides:?}: {:?}", run.stop());
    let analytic = run.analytic.as_ref().expect("analytic lane");
    let worst = |t: &cncsim::sim::Trace| {
        (0..t.len())
            .map(|k| (t.commanded[k * t.axes] - t.actual[k * t.axes]).abs())
            .fold(0.0, f64::max)
            * 1e6
    };
    (worst(run.trace.as_ref().unwrap()), worst(analytic))
}

/// X's linear velocity-loop plant in current mode: b = k·K_m·K_a/R (N per V), m (kg), c.
fn x_plant() -> (f64, f64, f64) {
    let m = cncsim::machine::Machine::load(&root().join("models/xyz_table.urdf")).unwrap();
    let x = &m.axes[m.axis_index("x").unwrap()].drive;
    let k = x.ratio();
    let b = k * x.motor.torque_constant_nm_per_a * x.amplifier_gain / x.motor.resistance_ohm;
    let moved: f64 = ["x_carriage", "y_carriage", "z_column", "z_slide"]
        .iter()
        .map(|l| m.links[m.link_index(l).unwrap()].mass)
        .sum();
    (b, x.reflected_inertia() + moved, x.reflected_damping())
}

#[test]
fn exact_feed_forward_makes_the_following_error_far_smaller() {
    let dir = tempfile::tempdir().unwrap();
    let (b, m, c) = x_plant();
    let (pid, pid_analytic) = x_error(dir.path(), &[]);
    let ff = [
        format!("controller.axes.x.ff1={}", c / b),
        format!("controller.axes.x.ff2={}", m / b),
    ];
    let ff: Vec<&str> = ff.iter().map(String::as_str).collect();
    let (with_ff, with_ff_analytic) = x_error(dir.path(), &ff);
    println!("X max following error: PID {pid:.3} µm (analytic {pid_analytic:.3}), PID + FF {with_ff:.4} µm (analytic {with_ff_analytic:.4})");
    // The feed-forward supplies the force the move needs; what is left is the force the
    // current's lag (L/R = 2.1 ms) and the hold (T/2) hold back while the force ramps at the
    // jerk limit: m·j·(L/R + T/2) = 649 kg · 4 m/s³ · 2.6 ms ≈ 6.7 N, which the loop answers
    // with an error of that over Kp·b = 2000 V/m · 800 N/V: ≈ 4 µm.
    let residual = m * 4.0 * (2.3e-3 / 1.1 + 0.5e-3) / (2000.0 * b) * 1e6;
    println!("residual expected from the current lag and the hold: {residual:.2} µm");
    assert!(with_ff < 0.1 * pid, "{with_ff} vs {pid}");
    assert!(with_ff_analytic < 0.1 * pid_analytic);
    assert!(
        with_ff < 2.0 * residual && with_ff > 0.5 * residual,
        "{with_ff} vs {residual}"
    );
    let (cascade, cascade_analytic) = x_error(
        dir.path(),
        &[
            "controller=cascade",
            "controller.cascade.x.velocity_ff=1.0",
            "controller.cascade.x.acceleration_ff=1.0",
        ],
    );
    let (cascade_no_ff, _) = x_error(dir.path(), &["controller=cascade"]);
    println!("cascade: {cascade_no_ff:.3} µm without feed-forward, {cascade:.4} µm with (analytic {cascade_analytic:.4})");
    assert!(
        cascade < 0.1 * cascade_no_ff,
        "{cascade} vs {cascade_no_ff}"
    );
    assert!(cascade < 0.1 * pid);
}

/// X's error on the second leg, once the reversal's transient has passed (µm), and the
/// position error of the carriage at the end of each leg: their difference is the lost motion.
fn lost_motion(dir: &Path, overrides: &[&str]) -> f64 {
    let mut all = vec![
        "mechanics.backlash=true",
        "mechanics.friction=true",
        "feedback.position=\"motor\"",
        "planner.limits.x.velocity=5.0",
        "program.feed_mm_s=5.0",
    ];
    all.extend_from_slice(overrides);
    let s = scenario(dir, &all);
    let run = Assembly::new(&s)
        .unwrap()
        .run(RunOptions::write_to(dir.join("out")).traced())
        .unwrap();
    let t = run.trace.as_ref().unwrap();
    // Error of the carriage in the middle of each leg (cruising, settled).
    let at = |time: f64| {
        let k = (time / s.timing.servo_period).round() as usize;
        t.commanded[k * t.axes] - t.actual[k * t.axes]
    };
    let duration = t.len() as f64 * s.timing.servo_period;
    at(0.25 * duration) - at(0.75 * duration)
}

#[test]
fn backlash_compensation_removes_the_lost_motion() {
    let dir = tempfile::tempdir().unwrap();
    let b = 0.32e-3;
    let without = lost_motion(dir.path(), &[]);
    // The motor encoder holds the drive on the setpoint: the carriage trails by b/2 each way.
    assert!(
        (without - b).abs() < 0.05 * b,
        "lost motion {without} vs b = {b}"
    );
    let with = lost_motion(
        dir.path(),
        &[
            "compensation.x.backlash_mm=0.32",
            "compensation.x.backlash_rate_mm_s=20.0",
        ],
    );
    println!(
        "lost motion at the reversal: {:.1} µm without, {:.2} µm with compensation",
        without * 1e6,
        with * 1e6
    );
    assert!(with.abs() < 0.1 * without.abs(), "{with} vs {without}");
}

#[test]
fn new_controller_keys_are_validated_with_their_place() {
    let dir = tempfile::tempdir().unwrap();
    let model = root().join("models/xyz_table.urdf").display().to_string();
    for (edit, words) in [
        (("cascade.x = { position_kp = 61.7,", "cascade.x = { position_kp = -61.7,"), "controller.cascade.x: position_kp = -61.7: expected a value from 0.0 to"),
        (("cascade.x = { position_kp = 61.7,", "cascade.x = { position_kp = 61.7, velocity_ff = 5.0,"), "velocity_ff = 5.0: expected a value from 0.0 to 2.0"),
        (("axes.x = { kp = 2000.0,", "axes.x = { kp = 2000.0, deadband = -1.0,"), "controller.axes.x: deadband = -1.0: expected a value from 0.0 to 1.0"),
        (("axes.x = { kp = 2000.0,", "axes.x = { kp = 2000.0, max_error_d = 0.0,"), "max_error_d = 0.0: expected a value"),
        (("[analytic]", "[compensation]\nx = { backlash_deg = 0.1, backlash_rate_deg_s = 1.0 }\n[analytic]"), "compensation.x: axis 'x' is linear: expected backlash_mm and backlash_rate_mm_s"),
        (("[analytic]", "[compensation]\nx = { backlash_mm = 0.1 }\n[analytic]"), "backlash compensation takes backlash_mm with backlash_rate_mm_s"),
        (("[analytic]", "[compensation]\nw = { friction_pulse = 0.5, friction_decay_ms = 10.0 }\n[analytic]"), "compensation.w: the machine 'xyz_table' has no axis 'w'"),
        (("type = \"pid\"", "type = \"pid\"\nform = \"incremental\""), ""),
        (("type = \"pid\"", "type = \"cascade\"\nvelocity_filter_hz = -5.0"), "velocity_filter_hz = -5.0 Hz: expected a value from 0.0"),
    ] {
        let text = BASE.replace("MODEL", &model).replacen(edit.0, edit.1, 1);
        assert_ne!(text, BASE.replace("MODEL", &model), "{edit:?} did not apply");
        let path = dir.path().join("bad.toml");
        std::fs::write(&path, &text).unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_cncsim"))
            .args(["run", path.to_str().unwrap(), "--out"])
            .arg(dir.path().join("o"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        if words.is_empty() {
            // A valid variant: the incremental form runs.
            assert_eq!(out.status.code(), Some(0), "{edit:?}: {stderr}");
            continue;
        }
        assert_eq!(out.status.code(), Some(2), "{edit:?}: {stderr}");
        assert!(stderr.contains(words), "{edit:?}: {stderr}");
        assert!(stderr.contains("bad.toml:"), "{edit:?} names no file: {stderr}");
    }
    // max_error_i has no meaning in the incremental form.
    let text = BASE
        .replace("MODEL", &model)
        .replacen(
            "type = \"pid\"",
            "type = \"pid\"\nform = \"incremental\"",
            1,
        )
        .replacen(
            "axes.x = { kp = 2000.0,",
            "axes.x = { kp = 2000.0, max_error_i = 0.01,",
            1,
        );
    let path = dir.path().join("inc.toml");
    std::fs::write(&path, text).unwrap();
    let e = Scenario::load(&path).unwrap_err().to_string();
    assert!(
        e.contains("max_error_i limits the integral of the positional form"),
        "{e}"
    );
    let _ = limits::MAX_GAIN;
}
