//! The `cncsim dynamics` data: JSON shape, text, and input errors.

use super::support::{fixture_path, GRAVITY};
use crate::dynamics::{DynamicsError, DynamicsModel, DynamicsReport};
use crate::machine::load_urdf;

fn fixture_report() -> DynamicsReport {
    let tree = load_urdf(&fixture_path("ac_table_eccentric.urdf")).unwrap();
    DynamicsReport::evaluate(&tree, GRAVITY, &[0.3, 1.0], &[0.5, -1.0], &[2.0, 3.0]).unwrap()
}

#[test]
fn json_has_exactly_the_documented_keys() {
    let json = fixture_report().to_json();
    let object = json.as_object().unwrap();
    let mut keys: Vec<&str> = object.keys().map(String::as_str).collect();
    keys.sort_unstable();
    assert_eq!(
        keys,
        ["coriolis", "gravity", "joints", "mass_matrix", "tau"]
    );
    assert_eq!(json["joints"], serde_json::json!(["A", "C"]));
    let m = json["mass_matrix"].as_array().unwrap();
    assert_eq!(m.len(), 2);
    assert!(m.iter().all(|row| row.as_array().unwrap().len() == 2));
    // Row-major, symmetric: the off-diagonals agree and are the reference's.
    assert_eq!(m[0][1], m[1][0]);
    assert!((m[0][1].as_f64().unwrap() + 0.02026134).abs() < 1e-8);
    let tau = json["tau"].as_array().unwrap();
    assert!((tau[0].as_f64().unwrap() - 2.497425).abs() < 1e-6);
}

#[test]
fn text_names_joints_terms_and_units() {
    let text = fixture_report().to_text();
    for needle in [
        "ac_table",
        "A ",
        "C ",
        "revolute",
        "τ",
        "C·q̇",
        "g(q)",
        "N·m",
        "kg·m²",
        "2.497425",
        "0.62534219",
    ] {
        assert!(text.contains(needle), "missing {needle:?} in\n{text}");
    }
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let tree = load_urdf(&fixture_path("ac_table_eccentric.urdf")).unwrap();
    let err =
        DynamicsReport::evaluate(&tree, GRAVITY, &[0.3], &[0.0, 0.0], &[0.0, 0.0]).unwrap_err();
    assert!(
        matches!(
            err,
            DynamicsError::WrongLength {
                expected: 2,
                got: 1,
                ..
            }
        ),
        "{err}"
    );
    let message = err.to_string();
    assert!(
        message.contains("q has 1 values") && message.contains("A, C"),
        "{message}"
    );

    let err = DynamicsReport::evaluate(&tree, GRAVITY, &[0.3, 0.0], &[0.0, f64::NAN], &[0.0, 0.0])
        .unwrap_err();
    assert!(
        matches!(err, DynamicsError::NotFinite { index: 1, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("'C'"), "{err}");

    let err = DynamicsReport::evaluate(&tree, GRAVITY, &[0.0, 0.0], &[1e300, 1e300], &[0.0, 0.0])
        .unwrap_err();
    assert_eq!(err, DynamicsError::NonFiniteResult);

    let mut static_tree = tree.clone();
    static_tree
        .joints
        .iter_mut()
        .for_each(|j| j.kind = crate::machine::JointKind::Fixed);
    let err = DynamicsReport::evaluate(&static_tree, GRAVITY, &[], &[], &[]).unwrap_err();
    assert_eq!(err, DynamicsError::NoMovingJoint);
}

#[test]
fn report_from_a_model_includes_armature_and_damping() {
    let mut tree = load_urdf(&fixture_path("ac_table_eccentric.urdf")).unwrap();
    tree.joints[0].damping = 2.0;
    let model = DynamicsModel::new(&tree, GRAVITY)
        .unwrap()
        .with_armature(&[0.1, 0.0])
        .unwrap();
    let r =
        DynamicsReport::evaluate_model(&model, &tree.name, &[0.3, 1.0], &[0.5, -1.0], &[2.0, 3.0])
            .unwrap();
    assert!((r.damping[0] - 1.0).abs() < 1e-15);
    assert!((r.mass_matrix[0][0] - (0.62534219 + 0.1)).abs() < 1e-8);
    let sum = r.inertial[0] + r.coriolis[0] + r.damping[0] + r.gravity[0];
    assert!((r.tau[0] - sum).abs() < 1e-12);
}
