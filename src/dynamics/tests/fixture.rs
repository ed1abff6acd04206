//! The A-C table reference (`tests/fixtures/ac_table_eccentric.md`): values from an
//! established rigid-body library, given to 6 decimals (M to 8).

use super::support::{fixture_path, max_abs_diff, GRAVITY};
use crate::dynamics::{DynamicsModel, DynamicsReport};
use crate::machine::load_urdf;
use nalgebra::DMatrix;

const Q: [f64; 2] = [0.3, 1.0];
const QD: [f64; 2] = [0.5, -1.0];
const QDD: [f64; 2] = [2.0, 3.0];
const TAU: [f64; 2] = [2.497425, 0.798267];
const M_QDD: [f64; 2] = [1.189900, 0.329040];
const C_QD: [f64; 2] = [0.028827, -0.000682];
const G: [f64; 2] = [1.278697, 0.469910];
const M: [f64; 4] = [0.62534219, -0.02026134, -0.02026134, 0.12318750];
/// The reference is printed to 6 decimals: agreement to rounding (5e-7) plus float noise.
const TOLERANCE: f64 = 1e-6;

fn model() -> DynamicsModel {
    let tree = load_urdf(&fixture_path("ac_table_eccentric.urdf")).unwrap();
    DynamicsModel::new(&tree, GRAVITY).unwrap()
}

#[test]
fn coordinates_are_a_then_c() {
    assert_eq!(model().joint_names(), ["A", "C"]);
}

#[test]
fn reproduces_reference_terms() {
    let model = model();
    let mut ws = model.workspace();
    let (mut tau, mut c, mut g) = ([0.0; 2], [0.0; 2], [0.0; 2]);
    let mut m = DMatrix::zeros(2, 2);
    model.inverse_dynamics(&mut ws, &Q, &QD, &QDD, &mut tau);
    model.coriolis_forces(&mut ws, &Q, &QD, &mut c);
    model.gravity_forces(&mut ws, &Q, &mut g);
    model.mass_matrix(&mut ws, &Q, &mut m);
    let m_qdd = &m * nalgebra::DVector::from_column_slice(&QDD);
    let m_row_major = m.transpose();

    let checks: [(&str, &[f64], &[f64]); 5] = [
        ("tau", &tau, &TAU),
        ("M qdd", m_qdd.as_slice(), &M_QDD),
        ("C qd", &c, &C_QD),
        ("g", &g, &G),
        ("M", m_row_major.as_slice(), &M), // transposed: column-major → row-major
    ];
    for (name, got, want) in checks {
        let err = max_abs_diff(got, want);
        assert!(
            err < TOLERANCE,
            "{name}: got {got:?}, want {want:?} (|Δ| = {err:e})"
        );
    }
}

#[test]
fn report_carries_the_same_values() {
    let tree = load_urdf(&fixture_path("ac_table_eccentric.urdf")).unwrap();
    let report = DynamicsReport::evaluate(&tree, GRAVITY, &Q, &QD, &QDD).unwrap();
    assert!(max_abs_diff(&report.tau, &TAU) < TOLERANCE);
    assert!(max_abs_diff(&report.inertial, &M_QDD) < TOLERANCE);
    assert!(max_abs_diff(&report.coriolis, &C_QD) < TOLERANCE);
    assert!(max_abs_diff(&report.gravity, &G) < TOLERANCE);
    assert!(max_abs_diff(&report.mass_matrix.concat(), &M) < TOLERANCE);
    assert_eq!(report.damping, [0.0, 0.0]);
}
