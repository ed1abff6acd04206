//! The physics engine against closed-form mechanics, tightly.

use cncsim::kinematics;
use cncsim::machine::Machine;
use cncsim::model::{Plant, PlantOptions};
use std::path::Path;

/// The bundled table with its guides and backlash taken out: these checks are about rigid
/// joints (`tests/friction_backlash.rs` covers the rest).
fn table() -> Machine {
    let mut machine =
        Machine::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/xyz_table.urdf"))
            .expect("bundled model loads");
    for axis in &mut machine.axes {
        axis.drive.guide = None;
        axis.drive.backlash = 0.0;
    }
    machine
}

/// A free X axis (no damping, gravity off) pushed by a constant force F: the engine's
/// semi-implicit Euler gives x_n = (F/m)·dt²·n(n+1)/2 = F t²/(2m)·(1 + 1/n), m being the
/// moved mass plus the reflected rotor inertia J·(N/r)². We check both: the integrator to
/// rounding, and its relative deviation from the exact parabola to be exactly 1/n.
#[test]
fn free_axis_under_constant_force_follows_the_parabola() {
    // Rapier integrates each solver iteration as a substep: n steps of dt with s iterations
    // are n·s semi-implicit Euler steps of dt/s, deviating by exactly 1/(n·s).
    for iterations in [1, 4] {
        free_axis_parabola(iterations);
    }
}

fn free_axis_parabola(iterations: usize) {
    let mut machine = table();
    for a in &mut machine.axes {
        a.drive.viscous_damping_nm_s_per_rad = 0.0;
    }
    let dt = 2.5e-4;
    let options = PlantOptions {
        step: dt,
        gravity: [0.0; 3],
        initial_positions: vec![0.0; 3],
        include_drive_dynamics: true,
        solver_iterations: iterations,
    };
    let mut plant = Plant::new(&machine, &options).unwrap();
    let x = &machine.axes[0];
    let moved: f64 = ["x_carriage", "y_carriage", "z_column", "z_slide"]
        .iter()
        .map(|l| machine.links[machine.link_index(l).unwrap()].mass)
        .sum();
    // The X carriage carries the Y carriage and the Z assembly (its column's mass calibrated).
    let column = machine.links[machine.link_index("z_column").unwrap()].mass;
    assert_eq!(
        moved,
        8.0 + 3.5 + column + 0.5,
        "X moves 8 + 3.5 + {column} + 0.5 kg"
    );
    let m = moved + x.drive.reflected_inertia();
    assert!((x.drive.reflected_inertia() - 3.89e-5 * 4000.0f64.powi(2)).abs() < 1e-9);

    let force = 50.0; // N at the carriage
    plant.set_joint_forces(&[force, 0.0, 0.0]);
    let mut q = [0.0; 3];
    let n = 4000; // 1 s
    for _ in 0..n {
        plant.step();
    }
    plant.positions(&mut q);
    let exact = force / m * (n as f64 * dt).powi(2) / 2.0;
    let (nf, h) = ((n * iterations) as f64, dt / iterations as f64);
    let euler = force / m * h * h * nf * (nf + 1.0) / 2.0;
    assert!(
        (q[0] - euler).abs() <= 1e-10 * euler,
        "x = {} m, semi-implicit Euler predicts {euler} m",
        q[0]
    );
    let deviation = q[0] / exact - 1.0;
    assert!(
        (deviation - 1.0 / nf).abs() < 1e-9,
        "relative deviation {deviation}, expected 1/n = {}",
        1.0 / nf
    );
    // The other axes did not move.
    assert!(q[1].abs() < 1e-15 && q[2].abs() < 1e-15, "{q:?}");
}

/// The engine's link poses agree with the URDF forward kinematics at any configuration.
#[test]
fn physics_link_poses_match_forward_kinematics() {
    let machine = table();
    let q0 = [0.1234, 0.0567, -0.0321];
    let options = PlantOptions {
        step: 1e-3,
        gravity: [0.0, 0.0, -9.81],
        initial_positions: q0.to_vec(),
        include_drive_dynamics: true,
        solver_iterations: 1,
    };
    let plant = Plant::new(&machine, &options).unwrap();
    let physics = plant.link_poses();
    let fk = kinematics::link_poses(&machine, &q0);
    for (i, (a, b)) in physics.iter().zip(&fk).enumerate() {
        let d = (a.translation.vector - b.translation.vector).norm();
        assert!(d < 1e-12, "link {}: {d} m apart", machine.links[i].name);
        assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
    }
    let tool = kinematics::tool_point(&machine, &q0);
    assert!((plant.tool_point() - tool).norm() < 1e-12);
}

/// Gravity on the Z slide: with no drive force it falls at g·m/(m + J k²), the screw and
/// rotor inertia slowing it (the armature is part of the dynamics).
#[test]
fn z_slide_falls_slowed_by_reflected_inertia() {
    let mut machine = table();
    for a in &mut machine.axes {
        a.drive.viscous_damping_nm_s_per_rad = 0.0;
    }
    let dt = 1e-4;
    let options = PlantOptions {
        step: dt,
        gravity: [0.0, 0.0, -9.81],
        initial_positions: vec![0.0; 3],
        include_drive_dynamics: true,
        solver_iterations: 1,
    };
    let mut plant = Plant::new(&machine, &options).unwrap();
    let z = &machine.axes[2];
    let accel = -9.81 * 0.5 / (0.5 + z.drive.reflected_inertia());
    let n = 1000;
    for _ in 0..n {
        plant.step();
    }
    let mut v = [0.0; 3];
    plant.velocities(&mut v);
    let expected = accel * n as f64 * dt;
    assert!(
        (v[2] - expected).abs() < 1e-10 * expected.abs(),
        "v_z = {}, expected {expected}",
        v[2]
    );
}

/// Under constant acceleration, the tool point's velocity read from the engine matches the
/// axis velocity (the joint's generalised velocity) at the same instant.
#[test]
fn tool_velocity_is_the_axis_velocity() {
    let mut machine = table();
    for a in &mut machine.axes {
        a.drive.viscous_damping_nm_s_per_rad = 0.0;
    }
    let options = PlantOptions {
        step: 2.5e-4,
        gravity: [0.0; 3],
        initial_positions: vec![0.0; 3],
        include_drive_dynamics: true,
        solver_iterations: 1,
    };
    let mut plant = Plant::new(&machine, &options).unwrap();
    plant.set_joint_forces(&[500.0, 0.0, 0.0]);
    for _ in 0..400 {
        plant.step();
    }
    let mut v = [0.0; 3];
    plant.velocities(&mut v);
    let tool = plant.tool_velocity();
    assert!(
        (tool.x - v[0]).abs() <= 1e-12 * v[0].abs(),
        "tool {} m/s, axis {} m/s",
        tool.x,
        v[0]
    );
}

/// While moving, the engine's link poses stay those of the forward kinematics of its joint
/// coordinates (no step of lag between the two).
#[test]
fn moving_link_poses_match_joint_coordinates() {
    let machine = table();
    let options = PlantOptions {
        step: 2.5e-4,
        gravity: [0.0, 0.0, -9.81],
        initial_positions: vec![0.1, 0.1, 0.0],
        include_drive_dynamics: true,
        solver_iterations: 1,
    };
    let mut plant = Plant::new(&machine, &options).unwrap();
    plant.set_joint_forces(&[500.0, -300.0, 10.0]);
    for _ in 0..400 {
        plant.step();
    }
    let mut q = [0.0; 3];
    plant.positions(&mut q);
    let fk = kinematics::tool_point(&machine, &q);
    let d = (plant.tool_point() - fk).norm();
    assert!(
        d < 1e-12,
        "engine tool point is {d} m from the kinematics of its coordinates"
    );
}
