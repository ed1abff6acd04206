//! Timing of the servo-loop calls on the fixture. Not a benchmark, a figure for the report:
//! `cargo test --release dynamics::tests::timing -- --ignored --nocapture`.

use super::support::{fixture_path, GRAVITY};
use crate::dynamics::DynamicsModel;
use crate::machine::load_urdf;
use nalgebra::DMatrix;
use std::hint::black_box;
use std::time::Instant;

fn time_per_call(mut f: impl FnMut(usize)) -> f64 {
    const CALLS: usize = 1_000_000;
    for i in 0..CALLS / 10 {
        f(i); // warm-up
    }
    let start = Instant::now();
    for i in 0..CALLS {
        f(i);
    }
    start.elapsed().as_secs_f64() / CALLS as f64 * 1e9
}

#[test]
#[ignore = "timing; run in release with --nocapture"]
fn fixture_evaluation_time() {
    let tree = load_urdf(&fixture_path("ac_table_eccentric.urdf")).unwrap();
    let model = DynamicsModel::new(&tree, GRAVITY).unwrap();
    let mut ws = model.workspace();
    let (qd, qdd) = ([0.5, -1.0], [2.0, 3.0]);
    let mut tau = [0.0; 2];
    let mut m = DMatrix::zeros(2, 2);
    // Vary q so that nothing is hoisted out of the loop.
    let q = |i: usize| [0.3 + 1e-9 * i as f64, 1.0];
    let rnea = time_per_call(|i| {
        model.inverse_dynamics(&mut ws, black_box(&q(i)), &qd, &qdd, &mut tau);
        black_box(&tau);
    });
    let crba = time_per_call(|i| {
        model.mass_matrix(&mut ws, black_box(&q(i)), &mut m);
        black_box(&m);
    });
    let forward = time_per_call(|i| {
        model
            .forward_dynamics(&mut ws, black_box(&q(i)), &qd, &tau.clone(), &mut tau)
            .unwrap();
        black_box(&tau);
    });
    println!("fixture (2 dof): inverse dynamics {rnea:.0} ns, mass matrix {crba:.0} ns, forward dynamics {forward:.0} ns");

    let machine = crate::machine::Machine::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ac_mill.urdf"),
    )
    .unwrap();
    let model = DynamicsModel::from_machine(&machine, GRAVITY).unwrap();
    let n = model.dof();
    let mut ws = model.workspace();
    let (qd, qdd) = (vec![0.2; n], vec![1.0; n]);
    let mut tau = vec![0.0; n];
    let mut q = vec![0.1; n];
    let rnea = time_per_call(|i| {
        q[0] = 1e-9 * i as f64;
        model.inverse_dynamics(&mut ws, black_box(&q), &qd, &qdd, &mut tau);
        black_box(&tau);
    });
    println!("ac_mill ({n} dof): inverse dynamics {rnea:.0} ns");
}
