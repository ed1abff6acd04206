//! Compliant drive trains: the Rapier machine with a spring and damper between each drive side
//! and its carriage (the backlash a dead zone inside) against the analytic two-mass model, and
//! the ringing of the physics at the two-mass frequency.

use cncsim::machine::{Compliance, Machine};
use cncsim::model::{Plant, PlantOptions};
use cncsim::scenario::{Assembly, RunOptions, Scenario};
use std::path::Path;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The bundled 5 mm/s circle (PID on DC motors, no friction or backlash) with `extra` appended: read as
/// if it were a file in `scenarios/`, so its relative paths resolve as the bundled ones do.
fn circle_with(extra: &str) -> Scenario {
    let path = root().join("scenarios/xyz_circle_5mms.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut s = Scenario::parse(&path, &format!("{text}\n{extra}")).unwrap();
    s.recording.rrd = false;
    s.recording.csv = false;
    s.expect.clear();
    s
}

/// Stiff belts on X and Y (20 N/µm: a 162 Hz mode against the 622 kg the gearbox reflects,
/// above the 25 Hz loops), a ball screw on Z (1 N/µm: 225 Hz against its 0.5 kg slide).
const COMPLIANT: &str = "
[mechanics.transmission.x]
stiffness_n_per_m = 2.0e7
damping_n_s_per_m = 3900.0
[mechanics.transmission.y]
stiffness_n_per_m = 2.0e7
damping_n_s_per_m = 3900.0
[mechanics.transmission.z]
stiffness_n_per_m = 1.0e6
damping_n_s_per_m = 40.0
";

fn physics_vs_analytic_mm(s: &Scenario) -> Vec<(String, f64)> {
    let out = tempfile::tempdir().unwrap();
    let run = Assembly::new(s)
        .unwrap()
        .run(RunOptions::write_to(out.path()))
        .unwrap();
    assert!(run.stop().is_none(), "the run completes");
    ["x", "y", "z"]
        .iter()
        .map(|a| {
            let d = run.metrics.axes[*a]
                .max_physics_vs_analytic_mm
                .expect("compared");
            (a.to_string(), d)
        })
        .collect()
}

#[test]
fn physics_and_analysis_agree_on_compliant_axes() {
    // As on the rigid machine (0.58 µm, scenarios/xyz_circle_5mms.toml): the two integrators
    // differ by round-off and the engine's first-order step, not by their equations.
    let differences = physics_vs_analytic_mm(&circle_with(COMPLIANT));
    eprintln!("compliant: physics vs analytic {differences:?} mm");
    for (axis, d) in differences {
        assert!(
            d < 1e-3,
            "axis {axis}: physics and analysis differ by {d} mm"
        );
    }
}

/// The XYZ table without guides (no friction), X made compliant with stiffness `k`.
fn table_with_compliant_x(k: f64) -> Machine {
    let mut machine = Machine::load(&root().join("models/xyz_table.urdf")).unwrap();
    for axis in &mut machine.axes {
        axis.drive.guide = None;
        axis.drive.backlash = 0.0;
    }
    machine.axes[0].drive.viscous_damping_nm_s_per_rad = 0.0;
    machine.axes[0].drive.set_compliance(Some(Compliance {
        stiffness: k,
        damping: 0.0,
    }));
    machine
}

#[test]
fn the_physics_rings_at_the_two_mass_frequency() {
    // A force pulse on X's drive side, then nothing: drive and carriage swing against each
    // other at ω² = k·(1/m_d + 1/m_c), m_d = J·k² (622.4 kg), m_c all X carries.
    let k = 2.0e5;
    let machine = table_with_compliant_x(k);
    let step = 2.5e-4;
    let options = PlantOptions {
        step,
        gravity: [0.0, 0.0, 0.0],
        initial_positions: vec![0.1, 0.1, 0.0],
        include_drive_dynamics: true,
        solver_iterations: 1,
    };
    let mut plant = Plant::new(&machine, &options).unwrap();
    let md = machine.axes[0].drive.reflected_inertia();
    let mc = cncsim::model::moved_inertia(&machine, machine.axes[0].joint);
    let expected_hz = (k * (1.0 / md + 1.0 / mc)).sqrt() / std::f64::consts::TAU;
    let (mut carriage, mut drive) = (vec![0.0; 3], vec![0.0; 3]);
    let mut gaps = Vec::new();
    for i in 0..8000 {
        let push = if i < 4 { 500.0 } else { 0.0 };
        plant.set_joint_forces(&[push, 0.0, 0.0]);
        plant.step();
        plant.positions(&mut carriage);
        plant.drive_positions(&mut drive);
        gaps.push(drive[0] - carriage[0]);
    }
    // Upward zero crossings of the gap, interpolated, over the 2 s.
    let crossings: Vec<f64> = gaps
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] < 0.0 && w[1] >= 0.0)
        .map(|(i, w)| (i as f64 + w[0] / (w[0] - w[1])) * step)
        .collect();
    let periods = (crossings.len() - 1) as f64;
    let measured_hz = periods / (crossings.last().unwrap() - crossings[0]);
    eprintln!("two-mass mode: measured {measured_hz:.4} Hz, formula {expected_hz:.4} Hz");
    assert!(periods >= 20.0);
    assert!(
        (measured_hz / expected_hz - 1.0).abs() < 2e-3,
        "measured {measured_hz} Hz, expected {expected_hz} Hz"
    );
}

#[test]
fn a_step_too_long_for_the_mode_is_refused() {
    // 10⁹ N/m between 622 kg and ~20 kg: a 1.1 kHz mode that a 0.25 ms step cannot follow.
    let machine = table_with_compliant_x(1.0e9);
    let options = PlantOptions {
        step: 2.5e-4,
        gravity: [0.0, 0.0, -9.81],
        initial_positions: vec![0.1, 0.1, 0.0],
        include_drive_dynamics: true,
        solver_iterations: 1,
    };
    let message = Plant::new(&machine, &options).err().unwrap().to_string();
    assert!(message.contains("axis 'x'"), "{message}");
    assert!(message.contains("physics_step_ms"), "{message}");
}

#[test]
fn turning_compliance_off_makes_the_drive_trains_rigid_again() {
    let compliant = circle_with(COMPLIANT);
    let mut rigid = compliant.clone();
    rigid.mechanics.compliance = false;
    let plain = circle_with("");
    let run = |s: &Scenario| {
        let out = tempfile::tempdir().unwrap();
        Assembly::new(s)
            .unwrap()
            .run(RunOptions::write_to(out.path()))
            .unwrap()
            .metrics
            .axes["x"]
            .max_following_error_mm
    };
    assert_eq!(
        run(&rigid),
        run(&plain),
        "compliance = false is the rigid machine"
    );
    assert_ne!(run(&compliant), run(&plain));
}

/// The carriage's speed after its first bounce off the spring: pushed by a constant drive
/// torque across half the gap, it takes up the spring, rebounds and flies free through the gap
/// (no friction). Physics at physics step `step`, and the analytic model.
fn rebound_speed(step: f64) -> (f64, f64) {
    use cncsim::sim::analytic::{AxisModel, AxisModelOptions};
    let mut machine = table_with_compliant_x(2.0e7);
    machine.axes[0].drive.set_compliance(Some(Compliance {
        stiffness: 2.0e7,
        damping: 3900.0,
    }));
    machine.axes[0].drive.backlash = 0.32e-3;
    let options = PlantOptions {
        step,
        gravity: [0.0, 0.0, 0.0],
        initial_positions: vec![0.1, 0.1, 0.0],
        include_drive_dynamics: true,
        solver_iterations: 1,
    };
    let mut plant = Plant::new(&machine, &options).unwrap();
    let drive = machine.axes[0].drive.clone();
    let mc = cncsim::model::moved_inertia(&machine, machine.axes[0].joint);
    let mut model = AxisModel::from_drive(
        &drive,
        mc,
        0.0,
        0.0,
        AxisModelOptions {
            ideal_actuator: true,
            backlash: drive.backlash,
            compliance: drive.compliance(),
            ..Default::default()
        },
    )
    .unwrap();
    model.rest_at(0.1);
    let torque = 0.05;
    // Contact from 31 to 33 ms; at 45 ms the carriage flies free in the gap.
    for _ in 0..(0.045 / step).round() as usize {
        plant.set_joint_forces(&[torque * drive.ratio(), 0.0, 0.0]);
        plant.step();
    }
    model.advance(torque, 0.045, 450);
    let mut v = vec![0.0; 3];
    plant.velocities(&mut v);
    (v[0], model.velocity())
}

#[test]
fn through_the_dead_zone_the_physics_converges_to_the_analytic_model() {
    // The rebound off a stiff, lightly damped spring is the one place the engine's explicit
    // step is coarse: 12 steps per contact at 0.25 ms. Its error in the rebound speed (which
    // a free-flying carriage then carries through the gap) shrinks with the step.
    let errors: Vec<f64> = [2.5e-4, 5e-5, 1e-5]
        .iter()
        .map(|&h| {
            let (physics, analytic) = rebound_speed(h);
            let e = (physics / analytic - 1.0).abs();
            eprintln!(
                "step {h:e} s: rebound {physics:.6} vs {analytic:.6} m/s, {:.3} %",
                e * 100.0
            );
            e
        })
        .collect();
    assert!(errors[0] < 0.02, "{errors:?}");
    assert!(
        errors[1] < errors[0] / 3.0 && errors[2] < errors[1] / 3.0,
        "{errors:?}"
    );
    assert!(errors[2] < 2e-3, "{errors:?}");
}
