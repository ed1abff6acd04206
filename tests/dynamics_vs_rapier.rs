//! Our rigid-body dynamics (`src/dynamics`: CRBA mass matrix, RNEA bias forces) against Rapier's
//! own multibody dynamics on the A-C mill, at several configurations.
//!
//! Rapier is used as a black box through the plant: from a known state, one semi-implicit Euler
//! step of a short dt under joint forces τ gives the engine's acceleration Δq̇/dt =
//! M⁻¹(τ − C q̇ − F q̇ − g) at the state the step started from. Our forward dynamics must give
//! the same, column by column of M⁻¹ (unit forces) and for the bias at rest and in motion.

use cncsim::dynamics::DynamicsModel;
use cncsim::machine::Machine;
use cncsim::model::{Plant, PlantOptions};
use nalgebra::Vector3;
use std::path::Path;

const GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];
/// Short enough that the step's own change of configuration is negligible (it enters the
/// measured acceleration at O(dt·q̇·∂M/∂q)), long enough that Δq̇ is far above rounding.
const DT: f64 = 1e-6;
/// Relative to the largest acceleration of a case. Measured agreement: 2–7·10⁻⁷.
const TOLERANCE: f64 = 2e-6;

fn mill() -> Machine {
    Machine::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ac_mill.urdf"))
        .expect("bundled model loads")
}

/// Our model as the plant sees the machine: links, drive armature, joint and drive damping.
fn our_model(machine: &Machine) -> DynamicsModel {
    let mut damped = machine.clone();
    for axis in &machine.axes {
        damped.joints[axis.joint].damping += axis.drive.reflected_damping();
    }
    DynamicsModel::from_machine(&damped, Vector3::from(GRAVITY))
        .and_then(|m| m.with_drive_armature(&damped))
        .unwrap()
}

/// A plant at `q` (machine axis order), at rest or brought to speed by 20 ms of the constant
/// joint forces `spin_up`.
fn plant_at(machine: &Machine, q: &[f64], spin_up: Option<&[f64]>) -> Plant {
    let options = PlantOptions {
        step: DT,
        gravity: GRAVITY,
        initial_positions: q.to_vec(),
        include_drive_dynamics: true,
        solver_iterations: 1,
    };
    let mut plant = Plant::new(machine, &options).unwrap();
    if let Some(forces) = spin_up {
        plant.set_joint_forces(forces);
        for _ in 0..20_000 {
            plant.step();
        }
    }
    plant
}

fn state(plant: &Plant) -> (Vec<f64>, Vec<f64>) {
    let n = plant.axis_count();
    let (mut q, mut qd) = (vec![0.0; n], vec![0.0; n]);
    plant.positions(&mut q);
    plant.velocities(&mut qd);
    (q, qd)
}

/// The engine's state and acceleration under `tau`, one step from a fresh plant (each call
/// builds its own, so every case starts from the same state).
fn engine_acceleration(
    machine: &Machine,
    q: &[f64],
    spin_up: Option<&[f64]>,
    tau: &[f64],
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut plant = plant_at(machine, q, spin_up);
    let (q0, v0) = state(&plant);
    plant.set_joint_forces(tau);
    plant.step();
    let (_, v1) = state(&plant);
    let qdd = v1.iter().zip(&v0).map(|(b, a)| (b - a) / DT).collect();
    (q0, v0, qdd)
}

/// Checks every force case; returns the state of the last and the tolerance used.
fn check_configuration(q: [f64; 5], spin_up: Option<[f64; 5]>) -> (Vec<f64>, Vec<f64>, f64) {
    let machine = mill();
    let model = our_model(&machine);
    let mut ws = model.workspace();
    let n = machine.axes.len();
    let spin = spin_up.as_ref().map(|s| s.as_slice());
    let mut cases: Vec<Vec<f64>> = vec![vec![0.0; n]];
    // Unit-scale forces on each axis in turn: linear axes N, rotary N·m.
    for i in 0..n {
        let mut tau = vec![0.0; n];
        tau[i] = if machine.axes[i].name == "a" || machine.axes[i].name == "c" {
            20.0
        } else {
            2000.0
        };
        cases.push(tau);
    }
    let mut last = (vec![], vec![], 0.0);
    for tau in cases {
        let (q0, v0, engine) = engine_acceleration(&machine, &q, spin, &tau);
        let mut ours = vec![0.0; n];
        model
            .forward_dynamics(&mut ws, &q0, &v0, &tau, &mut ours)
            .unwrap();
        let scale = ours
            .iter()
            .chain(&engine)
            .fold(1.0f64, |m, v| m.max(v.abs()));
        for i in 0..n {
            assert!(
                (ours[i] - engine[i]).abs() < TOLERANCE * scale,
                "q = {q:?}, q̇ = {v0:?}, τ = {tau:?}: axis {}: ours {} vs Rapier {} (all: {ours:?} vs {engine:?})",
                machine.axes[i].name,
                ours[i],
                engine[i]
            );
        }
        last = (q0, v0, TOLERANCE * scale);
    }
    last
}

#[test]
fn mass_matrix_and_gravity_match_rapier_at_rest() {
    // Machine zero (A = 0, the singular pose of the tool axis), tilted, and at travel extremes.
    for q in [
        [0.0, 0.0, 0.0, 0.0, 0.0],
        [0.05, -0.03, 0.02, 0.5, 1.0],
        [-0.1, 0.08, -0.05, -0.9, -2.5],
    ] {
        check_configuration(q, None);
    }
}

#[test]
fn bias_forces_match_rapier_in_motion() {
    // About 0.2 m/s on X, Y, Z and 2.6 rad/s on A, 3.4 rad/s on C: the Coriolis and centrifugal
    // terms of the tilting table matter.
    let (q, qd, tolerance) = check_configuration(
        [0.02, 0.01, -0.01, 0.4, 0.8],
        Some([3000.0, -2000.0, 1500.0, 300.0, 200.0]),
    );
    // The check can fail: the Coriolis and centrifugal terms alone change q̈ far more than the
    // tolerance, so leaving them out of our model (or getting them wrong) would be caught.
    let model = our_model(&mill());
    let mut ws = model.workspace();
    let n = q.len();
    let mut coriolis = vec![0.0; n];
    model.coriolis_forces(&mut ws, &q, &qd, &mut coriolis);
    let zero = vec![0.0; n];
    let (mut with, mut without) = (vec![0.0; n], vec![0.0; n]);
    model
        .forward_dynamics(&mut ws, &q, &zero, &coriolis, &mut with)
        .unwrap();
    model
        .forward_dynamics(&mut ws, &q, &zero, &zero, &mut without)
        .unwrap();
    let effect = with
        .iter()
        .zip(&without)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        effect > 100.0 * tolerance,
        "Coriolis terms change q̈ by only {effect}, tolerance {tolerance}"
    );
}
