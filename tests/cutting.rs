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
    Assembly::new(s)
        .unwrap()
        .run(RunOptions::new().traced())
        .unwrap()
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
            let i = by_angle
                .partition_point(|s| s.0 < angle)
                .min(by_angle.len() - 1);
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
    let run = Assembly::new(&s)
        .unwrap()
        .run(RunOptions::new().traced())
        .unwrap();
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

/// The slot scenario's text with `edit` applied, its program `program` (G-code), written into
/// `dir`; returns the scenario's path.
fn slot_variant(dir: &Path, program: &str, edit: impl Fn(String) -> String) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenarios/mill_slot.toml")).unwrap();
    let text = text
        .replace(
            "../models/ac_mill.urdf",
            &root().join("models/ac_mill.urdf").display().to_string(),
        )
        .replace("programs/mill_slot.ngc", "part.ngc");
    std::fs::write(dir.join("part.ngc"), program).unwrap();
    let path = dir.join("slot.toml");
    std::fs::write(&path, edit(text)).unwrap();
    path
}

const SLOT: &str =
    "G21 G90 G17 G94\nS12000 M3\nG0 X-50 Y0 Z5\nG1 Z-3 F600\nG1 X50 F1200\nG0 Z5\nM5\nM2\n";

/// The line (1-based) of the first line of `text` containing `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn bad_cutting_sections_are_refused_with_file_line_and_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(&str, &str, &str, &str)> = vec![
        // (what, replace this, with this, words of the message)
        ("no flutes", "flutes = 3", "flutes = 0", "cutting.tool.flutes = 0: expected a whole number from 1 to 64"),
        ("negative diameter", "diameter_mm = 10.0", "diameter_mm = -10.0", "cutting.tool.diameter_mm = -10.0 mm"),
        ("tool wider than the stock", "diameter_mm = 10.0", "diameter_mm = 120.0", "wider than every side of the stock"),
        ("unknown shape", "shape = \"flat\"", "shape = \"chamfer\"", "expected \"flat\", \"ball\" or \"bull\""),
        ("bull without corner", "shape = \"flat\"", "shape = \"bull\"", "needs corner_radius_mm"),
        ("unknown material", "name = \"al7075\"", "name = \"unobtainium\"", "expected one of \"al7075\""),
        (
            "negative coefficient",
            "name = \"al7075\"",
            "ktc_n_mm2 = -796.0\nkrc_n_mm2 = 168.0\nkac_n_mm2 = 222.0\nkte_n_mm = 27.7\nkre_n_mm = 30.8\nkae_n_mm = 1.4",
            "K_tc",
        ),
        (
            "coefficient in the wrong unit",
            "name = \"al7075\"",
            "ktc_n_mm2 = 796.0e6\nkrc_n_mm2 = 168.0\nkac_n_mm2 = 222.0\nkte_n_mm = 27.7\nkre_n_mm = 30.8\nkae_n_mm = 1.4",
            "K_tc",
        ),
        ("five coefficients", "name = \"al7075\"", "ktc_n_mm2 = 796.0\nkrc_n_mm2 = 168.0\nkac_n_mm2 = 222.0\nkte_n_mm = 27.7\nkre_n_mm = 30.8", "found 5 of them"),
        ("zero resolution", "resolution_mm = 0.1", "resolution_mm = 0.0", "cutting.stock.resolution_mm = 0.0 mm"),
        ("inverted box", "[[-40.0, -30.0, -20.0], [40.0, 30.0, 0.0]]", "[[40.0, -30.0, -20.0], [-40.0, 30.0, 0.0]]", "must lie above the first"),
        ("missing stl", "resolution_mm = 0.1", "resolution_mm = 0.1\nstl = \"none.stl\"", "cutting.stock.stl: "),
    ];
    for (what, from, to, words) in cases {
        let path = slot_variant(dir.path(), SLOT, |t| {
            assert!(t.contains(from), "{what}: the scenario has no {from:?}");
            t.replacen(from, to, 1)
        });
        let text = std::fs::read_to_string(&path).unwrap();
        let err = Scenario::load(&path).expect_err(what).to_string();
        assert!(err.contains(words), "{what}: {err}");
        // Located at the key (or the table) that is wrong.
        let key = to.lines().next().unwrap().trim();
        let at = format!("{}:", path.display());
        assert!(err.starts_with(&at), "{what}: not located: {err}");
        let line: usize = err[at.len()..].split(':').next().unwrap().parse().unwrap();
        let expected = if what == "tool wider than the stock" {
            line_of(&text, "[cutting.tool]")
        } else if what.contains("coefficient") {
            line_of(&text, "[cutting.material]")
        } else {
            line_of(&text, key)
        };
        assert!(
            line == expected || line == expected + 1,
            "{what}: line {line}, expected {expected}: {err}"
        );
    }
}

#[test]
fn a_stock_past_the_machines_memory_is_refused_with_the_estimate_before_anything_is_allocated() {
    let dir = tempfile::tempdir().unwrap();
    let path = slot_variant(dir.path(), SLOT, |t| {
        t.replace("resolution_mm = 0.1", "resolution_mm = 0.001")
    });
    let s = Scenario::load(&path).unwrap();
    let err = match Assembly::new(&s) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("a 1 µm lattice over 80 × 60 × 20 mm was accepted"),
    };
    assert!(
        err.contains("[cutting.stock]") && err.contains(" MB"),
        "{err}"
    );
    assert!(err.contains("raise resolution_mm"), "{err}");
}

#[test]
fn the_spindle_stopped_in_the_stock_stops_the_run_with_time_and_line_and_keeps_what_it_computed() {
    let dir = tempfile::tempdir().unwrap();
    // M5 before the cut: the tool feeds into the block with the spindle standing.
    let program =
        "G21 G90 G17 G94\nS12000 M3\nG0 X-50 Y0 Z5\nG1 Z-3 F600\nM5\nG1 X50 F1200\nG0 Z5\nM2\n";
    let path = slot_variant(dir.path(), program, |t| t);
    let out = dir.path().join("out");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args([
            "run",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("the tool engaged the stock with the spindle stopped")
            && stderr.contains("program line 6"),
        "{stderr}"
    );
    // Everything computed up to the stop is written: metrics, trace, recording, the part.
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(metrics["completed"], false);
    assert!(metrics["part"]["removed_volume_mm3"].as_f64().is_some());
    for file in ["trace.csv", "run.rrd", "part.stl"] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
}

#[test]
fn a_plunge_with_a_flat_end_mill_and_a_program_that_never_cuts_are_warned_once() {
    let dir = tempfile::tempdir().unwrap();
    // Straight down into the block at its middle.
    let plunge = "G21 G90 G17 G94\nS12000 M3\nG0 X0 Y0 Z5\nG1 Z-2 F300\nG0 Z5\nM5\nM2\n";
    let path = slot_variant(dir.path(), plunge, |t| t);
    let run = Assembly::new(&Scenario::load(&path).unwrap())
        .unwrap()
        .run(RunOptions::new())
        .unwrap();
    let warnings: Vec<String> = run.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(
        warnings
            .iter()
            .filter(|w| w.contains("plunges into the stock"))
            .count(),
        1,
        "{warnings:?}"
    );
    // Above the block all the way: it runs, and says it cut air.
    let air = "G21 G90 G17 G94\nS12000 M3\nG0 X-50 Y0 Z5\nG1 X50 F1200\nM5\nM2\n";
    let path = slot_variant(dir.path(), air, |t| t);
    let run = Assembly::new(&Scenario::load(&path).unwrap())
        .unwrap()
        .run(RunOptions::new())
        .unwrap();
    assert!(run.stop().is_none());
    let warnings: Vec<String> = run.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(
        warnings
            .iter()
            .filter(|w| w.contains("never touched the stock"))
            .count(),
        1,
        "{warnings:?}"
    );
    assert_eq!(run.metrics.part.unwrap().removed_volume_mm3, 0.0);
}

#[test]
fn the_force_spectrum_peaks_at_the_tooth_passing_frequency() {
    // 3 000 rev/min and three flutes: 150 Hz, well below the servo period's Nyquist 500 Hz.
    // Half immersion (down milling): each tooth cuts 90° of its 120° pitch, so the force is a
    // pulse per tooth and its fundamental the strongest line (in a full slot the teeth overlap
    // and the second harmonic can win).
    let dir = tempfile::tempdir().unwrap();
    let slow = SLOT.replace("S12000", "S3000").replace("F1200", "F300");
    let path = slot_variant(dir.path(), &slow, |t| t);
    let mut s = Scenario::load(&path).unwrap();
    let stock = &mut s.cutting.as_mut().unwrap().stock;
    (stock.min.x, stock.max.x, stock.max.y) = (-10e-3, 10e-3, 0.0);
    let run = run_traced(&s);
    let trace = run.trace.as_ref().unwrap();
    let fy: Vec<f64> = trace
        .cut
        .iter()
        .filter(|c| c.engaged_flutes > 0)
        .map(|c| c.force[1])
        .collect();
    assert!(fy.len() > 3000, "{} engaged ticks", fy.len());
    let mean = fy.iter().sum::<f64>() / fy.len() as f64;
    let period = s.timing.servo_period;
    let power = |f: f64| {
        let (mut re, mut im) = (0.0, 0.0);
        for (k, v) in fy.iter().enumerate() {
            let phase = 2.0 * PI * f * k as f64 * period;
            re += (v - mean) * phase.cos();
            im += (v - mean) * phase.sin();
        }
        re * re + im * im
    };
    // The strongest line between 5 Hz and Nyquist, on a 1 Hz grid.
    let peak = (5..500)
        .map(|f| (f as f64, power(f as f64)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    assert!(
        (peak.0 - 150.0).abs() <= 1.0,
        "spectrum peaks at {} Hz",
        peak.0
    );
}

#[test]
fn the_tool_in_the_spindle_gives_its_table_diameter_where_the_scenario_gives_none() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tools.tbl"),
        "T1 P1 Z60.0 D6.0 ;6 mm end mill\nT2 P2 Z70.0 D12.0\n",
    )
    .unwrap();
    let program = "G21 G90 G17 G94\nT1 M6\nS12000 M3\nG0 X-50 Y0 Z5\nG1 Z-3 F600\nG1 X50 F1200\nG0 Z5\nM5\nM2\n";
    let path = slot_variant(dir.path(), program, |t| {
        t.replace("diameter_mm = 10.0\n", "").replace(
            "file = \"part.ngc\"",
            "file = \"part.ngc\"\ntool_table = \"tools.tbl\"",
        )
    });
    let assembly = Assembly::new(&Scenario::load(&path).unwrap()).unwrap();
    let tool = assembly.cut.as_ref().unwrap().tool;
    assert!((tool.diameter - 6e-3).abs() < 1e-12, "{tool:?}");
    // Without a tool in the spindle and without a diameter: refused, saying what to give.
    let path = slot_variant(dir.path(), SLOT, |t| t.replace("diameter_mm = 10.0\n", ""));
    let err = match Assembly::new(&Scenario::load(&path).unwrap()) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("a cut without a tool diameter was accepted"),
    };
    assert!(err.contains("diameter_mm"), "{err}");
}
