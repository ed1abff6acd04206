//! The shipped machine models: the whole path from `Machine::load` to forward dynamics.

use super::support::{max_abs_diff, GRAVITY};
use crate::dynamics::DynamicsModel;
use crate::machine::Machine;
use nalgebra::DMatrix;
use std::path::Path;

fn machine(name: &str) -> Machine {
    Machine::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("models")
            .join(name),
    )
    .unwrap()
}

#[test]
fn drive_armature_adds_reflected_inertia_to_the_diagonal() {
    for name in ["xyz_table.urdf", "ac_mill.urdf"] {
        let machine = machine(name);
        let rigid = DynamicsModel::from_machine(&machine, GRAVITY).unwrap();
        let driven = rigid.clone().with_drive_armature(&machine).unwrap();
        let n = rigid.dof();
        let q: Vec<f64> = (0..n).map(|i| 0.05 * (i as f64 + 1.0)).collect();
        let (mut m_rigid, mut m_driven) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
        rigid.mass_matrix(&mut rigid.workspace(), &q, &mut m_rigid);
        driven.mass_matrix(&mut driven.workspace(), &q, &mut m_driven);
        let mut expected = m_rigid.clone();
        for axis in &machine.axes {
            let i = rigid.coordinate_of_joint(axis.joint).unwrap();
            assert!(
                axis.drive.reflected_inertia() > 0.0,
                "{name}: axis {}",
                axis.name
            );
            expected[(i, i)] += axis.drive.reflected_inertia();
        }
        assert!((&m_driven - &expected).amax() < 1e-12, "{name}");

        // Forward dynamics inverts inverse dynamics on the real machine.
        let qd: Vec<f64> = (0..n).map(|i| 0.3 - 0.1 * i as f64).collect();
        let qdd: Vec<f64> = (0..n).map(|i| 1.0 + i as f64).collect();
        let mut ws = driven.workspace();
        let (mut tau, mut back) = (vec![0.0; n], vec![0.0; n]);
        driven.inverse_dynamics(&mut ws, &q, &qd, &qdd, &mut tau);
        driven
            .forward_dynamics(&mut ws, &q, &qd, &tau, &mut back)
            .unwrap();
        assert!(
            max_abs_diff(&back, &qdd) < 1e-9,
            "{name}: {back:?} vs {qdd:?}"
        );
    }
}
