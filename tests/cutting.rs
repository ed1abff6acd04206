//! The cutting process in the loop, end to end on the bundled machines, against closed forms
//! nobody here wrote: the average milling forces of Altintas' *Manufacturing Automation*
//! (ch. 2), the volume of a straight slot, the part's surface error against where the actual
//! tool centre went, and the physics against the analytic lane with the same cut.

use cncsim::cutting::{material, Coefficients};
use cncsim::kinematics::PartPlacement;
use cncsim::scenario::{Assembly, RunOptions, RunOutput, Scenario};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The scenario at `name` (under scenarios/) with its files off.
fn scenario(name: &str) -> Scenario {
    let mut s = Scenario::load(&root().join("scenarios").join(name)).unwrap();
    s.recording.rrd = false;
    s.recording.csv = false;
    s
}

fn run_traced(s: &Scenario) -> RunOutput {
    Assembly::new(s).unwrap().run(RunOptions::new().traced()).unwrap()
}

/// Altintas' average forces on the tool per revolution (feed +X, tool axis +Z, M3), for
/// immersion φst..φex, axial depth a, feed per tooth c, N flutes.
fn mean_forces(k: &Coefficients, n: f64, a: f64, c: f64, st: f64, ex: f64) -> [f64; 3] {
    let fx = |p: f64| {
        n * a * c / (8.0 * PI) * (k.ktc * (2.0 * p).cos() - k.krc * (2.0 * p - (2.0 * p).sin()))
            + n * a / (2.0 * PI) * (-k.kte * p.sin() + k.kre * p.cos())
    };
    let fy = |p: f64| {
        n * a * c / (8.0 * PI) * (k.ktc * (2.0 * p - (2.0 * p).sin()) + k.krc * (2.0 * p).cos())
            - n * a / (2.0 * PI) * (k.kte * p.cos() + k.kre * p.sin())
    };
    let fz = |p: f64| n * a / (2.0 * PI) * (-k.kac * c * p.cos() + k.kae * p);
    [fx(ex) - fx(st), fy(ex) - fy(st), fz(ex) - fz(st)]
}

/// The mean force of the tool on the part over the steady middle of the straight cut along X
/// (the tool fully in, 20 mm from either end of the block), and the feed per tooth the drives
/// delivered there.
fn steady_mean_force(s: &Scenario, run: &RunOutput) -> ([f64; 3], f64) {
    let trace = run.trace.as_ref().unwrap();
    let x = |k: usize| trace.actual[k * trace.axes];
    let work_x = s.program.work_offset[0];
    let steady: Vec<usize> = (0..trace.len())
        .filter(|&k| {
            let xp = x(k) - work_x;
            trace.cut[k].engaged_flutes > 0 && xp > -0.02 && xp < 0.02
        })
        .collect();
    assert!(steady.len() > 1000, "{} steady ticks", steady.len());
    let (k0, k1) = (steady[0], *steady.last().unwrap());
    let feed = (x(k1) - x(k0)) / (trace.time[k1] - trace.time[k0]);
    let rpm = 12_000.0;
    let c = feed / (3.0 * rpm / 60.0);
    let mut mean = [0.0; 3];
    for &k in &steady {
        for (m, f) in mean.iter_mut().zip(trace.cut[k].force) {
            *m += f / steady.len() as f64;
        }
    }
    (mean, c)
}

#[test]
fn milling_on_the_mill_pushes_with_the_closed_form_mean_forces() {
    // The slot, and the same pass with the block's edge on the path: material on the left
    // of the feed (up milling, φ from 0 to π/2) or on its right (down milling, π/2 to π).
    let cases = [
        ("full slot", [-30.0, 30.0], 0.0, PI),
        ("half immersion, up milling", [0.0, 30.0], 0.0, PI / 2.0),
        ("half immersion, down milling", [-30.0, 0.0], PI / 2.0, PI),
    ];
    let k = material("al7075").unwrap().coefficients;
    for (what, [y0, y1], start, exit) in cases {
        let mut s = scenario("mill_slot.toml");
        let stock = &mut s.cutting.as_mut().unwrap().stock;
        stock.min.y = y0 * 1e-3;
        stock.max.y = y1 * 1e-3;
        let run = run_traced(&s);
        assert!(run.stop().is_none(), "{what}: {:?}", run.stop());
        let (mean, c) = steady_mean_force(&s, &run);
        let closed = mean_forces(&k, 3.0, 3e-3, c, start, exit);
        let size = closed.iter().map(|f| f * f).sum::<f64>().sqrt();
        eprintln!(
            "{what}: on the part {:.3?} N, closed form on the tool {:.3?} N, c = {:.3} µm",
            mean,
            closed,
            c * 1e6
        );
        for axis in 0..3 {
            // The trace has the tool's force on the part: the reverse of the closed form's.
            let (on_part, tool) = (mean[axis], closed[axis]);
            assert!(
                (on_part + tool).abs() < 0.02 * tool.abs().max(size),
                "{what}, axis {axis}: {on_part:.3} N on the part, closed form {tool:.3} N on the tool (resultant {size:.3} N)"
            );
        }
    }
}

#[test]
fn a_full_slot_on_the_mill_removes_width_times_depth_times_length() {
    let s = scenario("mill_slot.toml");
    let run = Assembly::new(&s).unwrap().run(RunOptions::new()).unwrap();
    assert!(run.stop().is_none(), "{:?}", run.stop());
    let part = run.metrics.part.expect("the slot cuts");
    // 10 mm wide, 3 mm deep, through the 80 mm block (the tool enters and leaves outside it).
    let expected = 10.0 * 3.0 * 80.0;
    for (what, removed) in [
        ("machined", part.removed_volume_mm3),
        ("nominal", part.nominal_removed_volume_mm3),
    ] {
        assert!(
            (removed / expected - 1.0).abs() < 0.005,
            "{what}: removed {removed} mm³, expected {expected}"
        );
    }
    let cutting = run.metrics.cutting.unwrap();
    assert!(cutting.max_force_n > 50.0 && cutting.max_spindle_power_w > 100.0);
}

/// The tool point and axis in the stock's frame at the trace's actual joint coordinates.
fn actual_tool_centres(assembly: &Assembly, run: &RunOutput) -> Vec<(f64, [f64; 3])> {
    let trace = run.trace.as_ref().unwrap();
    let cut = assembly.cut.as_ref().unwrap();
    let placement: &PartPlacement = &cut.placement;
    (0..trace.len())
        .map(|k| {
            let q = &trace.actual[k * trace.axes..(k + 1) * trace.axes];
            let (p, _) = placement.tool_at(&assembly.machine, q);
            (trace.time[k], [p.x, p.y, p.z])
        })
        .collect()
}

#[test]
fn the_side_milled_wall_stands_where_the_actual_tool_centre_went() {
    for name in ["mill_contour_climb.toml", "mill_contour_conventional.toml"] {
        let s = scenario(name);
        let assembly = Assembly::new(&s).unwrap();
        let run = assembly.run(RunOptions::new().traced()).unwrap();
        assert!(run.stop().is_none(), "{name}: {:?}", run.stop());
        let part = run.part.as_ref().expect("the contour cuts");
        // The finishing pass: the tool centre on the 25 mm circle at 5 mm depth; its radius
        // against the angle, from the actual joint coordinates through the kinematics.
        // (The roughing circle at 27 mm and the moves in and out at 180° are left out by
        // radius and angle.)
        let centres = actual_tool_centres(&assembly, &run);
        let mut by_angle: Vec<(f64, f64)> = centres
            .iter()
            .filter(|(_, p)| (p[2] + 5e-3).abs() < 1e-5)
            .map(|(_, p)| (p[1].atan2(p[0]), (p[0] * p[0] + p[1] * p[1]).sqrt() - 25e-3))
            .filter(|(_, d)| d.abs() < 1e-3)
            .collect();
        by_angle.sort_by(|a, b| a.0.total_cmp(&b.0));
        assert!(by_angle.len() > 1000, "{name}: {} samples", by_angle.len());
        let deviation_at = |angle: f64| {
            let i = by_angle.partition_point(|s| s.0 < angle).min(by_angle.len() - 1);
            by_angle[i].1
        };
        // Wall points between 1 and 4 mm deep, away from where the pass starts and ends
        // (at 180°, where the tool enters and leaves the wall).
        let mut checked = 0;
        let mut worst: f64 = 0.0;
        for p in &part.comparison.points {
            let (x, y, z) = (p.position.x, p.position.y, p.position.z);
            let r = (x * x + y * y).sqrt();
            if !(z < -1e-3 && z > -4e-3 && (r - 20e-3).abs() < 0.5e-3) {
                continue;
            }
            let angle = y.atan2(x);
            if angle.abs() > PI - 0.2 {
                continue;
            }
            // Material left where the tool centre stayed outside the programmed circle.
            let expected = deviation_at(angle);
            worst = worst.max((p.error - expected).abs());
            checked += 1;
        }
        assert!(checked > 1000, "{name}: {checked} wall points");
        assert!(
            worst < 1e-6,
            "{name}: the wall's error differs from the tool centre's deviation by {:.3} µm",
            worst * 1e6
        );
    }
}

/// A small slot on the XYZ table with the analytic lane beside the physics.
fn xyz_slot(dir: &Path) -> PathBuf {
    let machine = root().join("models/xyz_table.urdf");
    let program = dir.join("slot.ngc");
    std::fs::write(
        &program,
        "G21 G90 G17 G94\nS6000 M3\nG0 X90 Y100 Z1\nG1 Z-0.5 F60\nG1 X120 F300\nG0 Z1\nM5\nM2\n",
    )
    .unwrap();
    let text = format!(
        r#"name = "xyz_slot"
machine = "{}"
[program]
file = "{}"
[planner]
profile = "trapezoid"
acceleration_mm_s2 = 200.0
rapid_mm_s = 20.0
[timing]
servo_period_ms = 1.0
physics_step_ms = 0.25
settle_s = 0.2
[mechanics]
friction = false
backlash = false
[actuator]
model = "dc-motor"
amplifier_mode = "voltage"
[controller]
type = "pid"
form = "positional"
axes.x = {{ kp = 19800.0, ki = 6.1e5, kd = 146.0, output_limit = 6.0 }}
axes.y = {{ kp = 19800.0, ki = 6.1e5, kd = 146.0, output_limit = 6.0 }}
axes.z = {{ kp = 9700.0, ki = 3.0e5, kd = 85.0, output_limit = 3.125 }}
[analytic]
steps_per_period = 16
[recording]
rrd = false
csv = false
[cutting.stock]
box_mm = [[95.0, 90.0, -5.0], [115.0, 110.0, 0.0]]
resolution_mm = 0.05
[cutting.tool]
diameter_mm = 2.0
flutes = 2
helix_deg = 30.0
flute_length_mm = 6.0
[cutting.material]
name = "al6082"
"#,
        machine.display(),
        program.display()
    );
    let path = dir.join("xyz_slot.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn physics_and_the_analytic_lane_agree_within_a_micrometre_while_cutting() {
    let dir = tempfile::tempdir().unwrap();
    let s = Scenario::load(&xyz_slot(dir.path())).unwrap();
    let run = Assembly::new(&s).unwrap().run(RunOptions::new().traced()).unwrap();
    assert!(run.stop().is_none(), "{:?}", run.stop());
    let cutting = run.metrics.cutting.unwrap();
    assert!(cutting.max_force_n > 1.0, "the slot cuts: {cutting:?}");
    // Both lanes cut: the analytic lane's own cut pushes it as the physics' pushes the table.
    let analytic = run.analytic.as_ref().unwrap();
    assert!(analytic.cut.iter().any(|c| c.engaged_flutes > 0));
    for axis in ["x", "y", "z"] {
        let d = run.metrics.axes[axis].max_physics_vs_analytic_mm.unwrap();
        assert!(d < 1e-3, "axis {axis}: physics − analytic {} µm", d * 1e3);
    }
    // The cut is felt: X lags more than it would in air.
    let mut air = s.clone();
    air.cutting = None;
    let in_air = Assembly::new(&air).unwrap().run(RunOptions::new()).unwrap();
    let (cut_x, air_x) = (
        run.metrics.axes["x"].rms_torque_nm,
        in_air.metrics.axes["x"].rms_torque_nm,
    );
    assert!(cut_x > air_x, "rms torque X: cutting {cut_x}, air {air_x}");
}
