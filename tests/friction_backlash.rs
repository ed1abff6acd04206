//! Friction from guide contacts and backlash from a dead-band joint, measured on the Rapier
//! model of the XYZ table (issue 5). Nothing here applies a friction or backlash formula: the
//! test pushes the drives and reads what the engine does.

use cncsim::machine::{Feedback, Guide, Machine};
use cncsim::model::{Plant, PlantOptions};
use std::path::Path;

const G: f64 = 9.81;
const DT: f64 = 2.5e-4;

/// The bundled table with guide friction μ on X and Y and the given backlash (X, Y).
fn table(mu: f64, backlash: [f64; 2]) -> Machine {
    table_with(Guide::coulomb(mu), backlash)
}

/// μ_k 0.05, μ_s 0.1, falling over v_s = 2 mm/s.
fn sticky_guide() -> Guide {
    Guide {
        static_friction_coefficient: Some(0.1),
        stribeck_velocity_m_s: Some(2e-3),
        ..Guide::coulomb(0.05)
    }
}

fn table_with(guide: Guide, backlash: [f64; 2]) -> Machine {
    let mut machine =
        Machine::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/xyz_table.urdf"))
            .expect("bundled model loads");
    for (i, axis) in machine.axes.iter_mut().enumerate() {
        if i < 2 {
            axis.drive.guide = Some(guide);
            axis.drive.backlash = backlash[i];
            axis.drive.feedback = Feedback::Motor;
        }
    }
    machine
}

/// Mass carried by the guide of axis `axis` (its carriage and everything on it), from the URDF.
fn carried_mass(machine: &Machine, axis: usize) -> f64 {
    let names: &[&str] = if axis == 0 {
        &["x_carriage", "y_carriage", "z_column", "z_slide"]
    } else {
        &["y_carriage", "z_column", "z_slide"]
    };
    names
        .iter()
        .map(|l| machine.links[machine.link_index(l).unwrap()].mass)
        .sum()
}

/// A plant at x = y = 0.1 m, z = 0, with drive inertia and damping left out (so the drive
/// force is friction and nothing else at constant speed), gravity down.
fn plant(machine: &Machine, drive_dynamics: bool) -> Plant {
    let options = PlantOptions {
        step: DT,
        gravity: [0.0, 0.0, -G],
        initial_positions: vec![0.1, 0.1, 0.0],
        include_drive_dynamics: drive_dynamics,
        solver_iterations: 1,
    };
    Plant::new(machine, &options).expect("plant builds")
}

/// Runs `seconds` of physics with the forces `force(plant)` recomputed every step.
fn run(plant: &mut Plant, seconds: f64, mut force: impl FnMut(&Plant) -> [f64; 3]) {
    for _ in 0..(seconds / DT).round() as usize {
        let f = force(plant);
        plant.set_joint_forces(&f);
        plant.step();
    }
}

/// Holds the Z slide against gravity (no guide on Z) and pushes nothing else.
fn z_hold(machine: &Machine) -> f64 {
    machine.links[machine.link_index("z_slide").unwrap()].mass * G
}

#[test]
fn guides_carry_the_weight_above_them() {
    let machine = table(0.1, [0.0, 0.0]);
    let mut plant = plant(&machine, true);
    let hold = z_hold(&machine);
    run(&mut plant, 0.5, |_| [0.0, 0.0, hold]);
    let normal = plant.guide_normal_forces();
    for (axis, measured) in normal.iter().take(2).enumerate() {
        let expected = carried_mass(&machine, axis) * G;
        let measured = measured.expect("axis has a guide");
        let error = (measured - expected).abs() / expected;
        eprintln!("axis {axis}: normal {measured:.6} N vs weight {expected:.6} N");
        assert!(
            error < 0.01,
            "axis {axis}: normal force {measured:.4} N, weight {expected:.4} N ({:.3} %)",
            error * 100.0
        );
    }
    assert_eq!(normal[2], None, "Z has no guide");
    // The carriages sit on their guides: the tool is where the joint coordinates put it, up
    // to the contact's static sag.
    let mut q = [0.0; 3];
    plant.positions(&mut q);
    let sag = (plant.tool_point() - cncsim::kinematics::tool_point(&machine, &q)).norm();
    eprintln!("sag {sag:e} m");
    assert!(sag < 2e-6, "tool sags {:.3} µm into the guides", sag * 1e6);
}

/// A velocity loop (PI on the drive force) holds the carriage at constant speed; the mean
/// drive force over the last half second is the friction the engine produces. Returns it and
/// the expected N·μ(|v|).
fn force_at_constant_speed(guide: Guide, axis: usize, speed: f64) -> (f64, f64) {
    let machine = table_with(guide, [0.0, 0.0]);
    let mut plant = plant(&machine, false);
    let hold = z_hold(&machine);
    let mut v = [0.0; 3];
    let mut integral = 0.0;
    let (kp, ki) = (2.0e4, 4.0e5);
    let mut sum = 0.0;
    let mut samples = 0;
    let steps = (1.5 / DT) as usize;
    for step in 0..steps {
        plant.velocities(&mut v);
        let error = speed - v[axis];
        integral += error * DT;
        let f = kp * error + ki * integral;
        let mut forces = [0.0, 0.0, hold];
        forces[axis] = f;
        plant.set_joint_forces(&forces);
        plant.step();
        if step >= steps / 3 * 2 {
            sum += f;
            samples += 1;
        }
    }
    plant.velocities(&mut v);
    assert!(
        (v[axis] - speed).abs() < 1e-3 * speed.abs(),
        "axis {axis} did not settle at {speed} m/s: {}",
        v[axis]
    );
    let mu = guide.coefficient().sliding(speed);
    (sum / samples as f64, mu * carried_mass(&machine, axis) * G)
}

/// At each (axis, speed) the drive force equals N·μ(|v|) within 2 % and opposes the motion.
fn assert_sliding_friction(guide: Guide, cases: &[(usize, f64)]) {
    for &(axis, speed) in cases {
        let (force, expected) = force_at_constant_speed(guide, axis, speed);
        let error = (force.abs() - expected).abs() / expected;
        eprintln!("axis {axis} at {speed} m/s: force {force:.6} N vs μ(v)·N {expected:.6} N");
        assert!(
            error < 0.02,
            "axis {axis} at {speed} m/s: drive force {force:.4} N, μ(v)·N = {expected:.4} N ({:.3} %)",
            error * 100.0
        );
        assert_eq!(
            force.signum(),
            speed.signum(),
            "friction opposes the motion"
        );
    }
}

#[test]
fn sliding_friction_is_mu_times_the_load() {
    assert_sliding_friction(
        Guide::coulomb(0.1),
        &[(0, 0.005), (0, -0.02), (1, 0.005), (1, -0.01)],
    );
}

#[test]
fn no_creep_below_breakaway() {
    let mu = 0.1;
    let machine = table(mu, [0.0, 0.0]);
    for axis in 0..2 {
        let mut plant = plant(&machine, true);
        let hold = z_hold(&machine);
        let push = 0.9 * mu * carried_mass(&machine, axis) * G;
        let creep = creep_in_one_second(&mut plant, hold, axis, push);
        eprintln!("axis {axis}: creep {creep:e} m in 1 s");
        assert!(
            creep < 1e-6,
            "axis {axis}: pushed at 90 % of breakaway, crept {:.3} µm in 1 s",
            creep * 1e6
        );
        // And just above breakaway it does move.
        let mut start = [0.0; 3];
        plant.positions(&mut start);
        let mut forces = [0.0, 0.0, hold];
        forces[axis] = 1.1 * mu * carried_mass(&machine, axis) * G;
        run(&mut plant, 0.2, |_| forces);
        let mut end = [0.0; 3];
        plant.positions(&mut end);
        assert!(
            end[axis] - start[axis] > 1e-5,
            "axis {axis} should slide at 110 % of breakaway"
        );
    }
}

/// Lets the plant settle for 0.2 s, then pushes axis `axis` with `push` (N) for 1 s and
/// returns how far it moved (m).
fn creep_in_one_second(plant: &mut Plant, hold: f64, axis: usize, push: f64) -> f64 {
    run(plant, 0.2, |_| [0.0, 0.0, hold]);
    let mut start = [0.0; 3];
    plant.positions(&mut start);
    let mut forces = [0.0, 0.0, hold];
    forces[axis] = push;
    run(plant, 1.0, |_| forces);
    let mut end = [0.0; 3];
    plant.positions(&mut end);
    (end[axis] - start[axis]).abs()
}

#[test]
fn sliding_friction_follows_the_stribeck_curve() {
    // From near breakaway (0.5 mm/s: μ 0.097) through v_s to nearly kinetic (8 mm/s: μ 0.05).
    assert_sliding_friction(
        sticky_guide(),
        &[(0, 0.5e-3), (0, -1e-3), (1, 2e-3), (0, 4e-3), (1, -8e-3)],
    );
}

#[test]
fn stiction_holds_up_to_the_static_coefficient() {
    let guide = sticky_guide();
    let machine = table_with(guide, [0.0, 0.0]);
    let mu_s = guide.static_friction_coefficient.unwrap();
    for axis in 0..2 {
        // Without drive inertia, so that the carriage's acceleration is the net force over its
        // own mass.
        let mut plant = plant(&machine, false);
        let hold = z_hold(&machine);
        // Twice the kinetic friction, 90 % of breakaway: held.
        let breakaway = mu_s * carried_mass(&machine, axis) * G;
        let creep = creep_in_one_second(&mut plant, hold, axis, 0.9 * breakaway);
        eprintln!("axis {axis}: creep {creep:e} m in 1 s at 90 % of μ_s·N");
        assert!(
            creep < 1e-6,
            "axis {axis}: pushed at 90 % of static breakaway, crept {:.3} µm in 1 s",
            creep * 1e6
        );
        // Above breakaway it slides, and once moving the friction falls towards μ_k·N: the
        // push accelerates it at (1.1·μ_s − μ(v))·N / m, between 0.1·μ_s·g (friction stuck at
        // μ_s) and (1.1·μ_s − μ_k)·g, the rate it approaches once the speed passes v_s. More
        // than half the upper bound (three times the lower) after 0.2 s shows that it fell.
        let mut forces = [0.0, 0.0, hold];
        forces[axis] = 1.1 * breakaway;
        run(&mut plant, 0.2, |_| forces);
        let mut v = [0.0; 3];
        plant.velocities(&mut v);
        let upper = (1.1 * mu_s - guide.friction_coefficient) * G * 0.2;
        eprintln!(
            "axis {axis}: {:.4} m/s after 0.2 s above breakaway (≤ {upper:.4})",
            v[axis]
        );
        assert!(
            v[axis] > 0.5 * upper && v[axis] <= upper,
            "axis {axis}: {} m/s",
            v[axis]
        );
    }
}

/// Drives the drive side of X with a stiff position loop along a triangle wave (out 1 mm and
/// back) and returns (drive, carriage) positions at every step.
fn triangle(backlash: f64) -> Vec<(f64, f64)> {
    let machine = table(0.1, [backlash, 0.0]);
    let mut plant = plant(&machine, true);
    let hold = z_hold(&machine);
    let (amplitude, speed): (f64, f64) = (1.0e-3, 2.0e-3);
    let half = amplitude / speed;
    let mut out = Vec::new();
    let mut t = 0.0;
    let (mut q, mut qd, mut v) = ([0.0; 3], [0.0; 3], [0.0; 3]);
    run(&mut plant, 0.1, |_| [0.0, 0.0, hold]);
    while t < 2.0 * half + 0.2 {
        let target = 0.1
            + if t < half {
                speed * t
            } else {
                (amplitude - speed * (t - half)).max(0.0)
            };
        plant.drive_positions(&mut qd);
        plant.drive_velocities(&mut v);
        let f = 2.0e6 * (target - qd[0]) - 4.0e4 * v[0];
        plant.set_joint_forces(&[f, 0.0, hold]);
        plant.step();
        plant.positions(&mut q);
        plant.drive_positions(&mut qd);
        out.push((qd[0], q[0]));
        t += DT;
    }
    out
}

#[test]
fn backlash_is_lost_motion_at_reversal() {
    let b = 0.32e-3;
    let path = triangle(b);
    // While pushing forward the drive leads by b/2; after the reversal it trails by b/2.
    let turn = path
        .iter()
        .enumerate()
        .max_by(|x, y| x.1 .0.total_cmp(&y.1 .0))
        .unwrap()
        .0;
    let (drive_top, carriage_top) = path[turn];
    let lead = drive_top - carriage_top;
    assert!(
        (lead - b / 2.0).abs() < 0.02 * b,
        "drive leads by {:.2} µm, expected b/2",
        lead * 1e6
    );
    // The carriage stays put while the drive crosses the slack: find where it starts back.
    let moved = path[turn..]
        .iter()
        .position(|&(_, c)| carriage_top - c > 0.5e-6)
        .expect("carriage comes back")
        + turn;
    let lost = drive_top - path[moved].0;
    eprintln!(
        "lead {lead:e}, lost {lost:e}, end {:e}",
        path.last().unwrap().1 - path.last().unwrap().0
    );
    assert!(
        (lost - b).abs() < 0.02 * b,
        "lost motion {:.2} µm, backlash {:.2} µm",
        lost * 1e6,
        b * 1e6
    );
    for &(_, c) in &path[turn..moved] {
        assert!((c - carriage_top).abs() <= 0.5e-6, "carriage stood still");
    }
    let (drive_end, carriage_end) = *path.last().unwrap();
    assert!(
        (carriage_end - drive_end - b / 2.0).abs() < 0.02 * b,
        "after the return the drive trails by b/2: {:.2} µm",
        (carriage_end - drive_end) * 1e6
    );
}

#[test]
fn without_backlash_the_axis_is_stiff() {
    let path = triangle(0.0);
    let worst = path.iter().map(|(d, c)| (d - c).abs()).fold(0.0, f64::max);
    assert_eq!(worst, 0.0, "no dead band: carriage is the drive");
}
