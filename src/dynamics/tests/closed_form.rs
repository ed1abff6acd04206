//! One- and two-joint machines with textbook answers, and model validation.

use super::support::{base_link, joint, link, pose, tree, GRAVITY};
use crate::dynamics::{DynamicsError, DynamicsModel};
use crate::machine::JointKind;
use nalgebra::{DMatrix, Matrix3, Vector3};
use std::f64::consts::PI;

/// A slide along a tilted axis carrying a carriage and, on a fixed joint, a spindle head:
/// `M` is the total moved mass, `g = −m gᵀ a_world`, and there are no velocity terms.
#[test]
fn prismatic_axis_moves_total_mass_against_gravity() {
    let (m1, m2) = (120.0, 35.0);
    let origin = pose([0.2, -0.1, 0.5], [0.3, -0.2, 0.7]);
    let axis = Vector3::new(1.0, 2.0, 2.0) / 3.0;
    let t = tree(
        vec![
            base_link(),
            link(
                "carriage",
                m1,
                [0.1, 0.2, 0.0],
                Matrix3::from_diagonal_element(2.0),
            ),
            link(
                "head",
                m2,
                [0.0, 0.0, -0.3],
                Matrix3::from_diagonal_element(0.5),
            ),
        ],
        vec![
            joint("X", JointKind::Prismatic, 0, 1, origin, axis),
            joint(
                "mount",
                JointKind::Fixed,
                1,
                2,
                pose([0.0, 0.4, 0.1], [0.0, 1.0, 0.0]),
                Vector3::z(),
            ),
        ],
    );
    let mut model = DynamicsModel::new(&t, GRAVITY).unwrap();
    let mut ws = model.workspace();
    let (q, qd, qdd) = ([0.37], [1.5], [-4.0]);
    let mut m = DMatrix::zeros(1, 1);
    let (mut tau, mut c, mut g) = ([0.0], [0.0], [0.0]);
    model.mass_matrix(&mut ws, &q, &mut m);
    model.coriolis_forces(&mut ws, &q, &qd, &mut c);
    model.gravity_forces(&mut ws, &q, &mut g);
    model.inverse_dynamics(&mut ws, &q, &qd, &qdd, &mut tau);

    let total = m1 + m2;
    let axis_in_base = origin.rotation * axis;
    let holding = -total * GRAVITY.dot(&axis_in_base);
    assert!((m[(0, 0)] - total).abs() < 1e-10, "M = {}", m[(0, 0)]);
    assert!(c[0].abs() < 1e-10, "C qd = {}", c[0]);
    assert!(
        (g[0] - holding).abs() < 1e-10,
        "g = {} want {holding}",
        g[0]
    );
    assert!((tau[0] - (total * qdd[0] + holding)).abs() < 1e-9);

    // Vertical axis: the textbook m·g.
    let vertical = tree(
        vec![base_link(), link("z", m1, [0.0; 3], Matrix3::identity())],
        vec![joint(
            "Z",
            JointKind::Prismatic,
            0,
            1,
            pose([0.0; 3], [0.0; 3]),
            Vector3::z(),
        )],
    );
    let vmodel = DynamicsModel::new(&vertical, GRAVITY).unwrap();
    vmodel.gravity_forces(&mut vmodel.workspace(), &[0.0], &mut g);
    assert!((g[0] - m1 * 9.81).abs() < 1e-10);

    // Armature adds to M's diagonal and to τ through q̈ only.
    model.set_armature(&[7.5]).unwrap();
    model.mass_matrix(&mut ws, &q, &mut m);
    assert!((m[(0, 0)] - (total + 7.5)).abs() < 1e-10);
    let mut tau_arm = [0.0];
    model.inverse_dynamics(&mut ws, &q, &qd, &qdd, &mut tau_arm);
    assert!((tau_arm[0] - tau[0] - 7.5 * qdd[0]).abs() < 1e-9);
}

/// A pendulum about y: bob of mass m at distance l below the axis, with its own inertia
/// `I_yy` about its centre, and viscous damping d. The joint origin's offset is irrelevant.
/// τ = (I_yy + m l²) q̈ + d q̇ + m g l sin q.
#[test]
fn pendulum_matches_closed_form() {
    let (m, l, i_yy, d, g0) = (3.0, 0.8, 0.002, 0.4, 9.81);
    let mut pivot = joint(
        "P",
        JointKind::Revolute,
        0,
        1,
        pose([1.0, 2.0, 3.0], [0.0; 3]),
        Vector3::y(),
    );
    pivot.damping = d;
    let t = tree(
        vec![
            base_link(),
            link(
                "bob",
                m,
                [0.0, 0.0, -l],
                Matrix3::new(0.001, 0.0, 0.0, 0.0, i_yy, 0.0, 0.0, 0.0, 0.003),
            ),
        ],
        vec![pivot],
    );
    let model = DynamicsModel::new(&t, GRAVITY).unwrap();
    let mut ws = model.workspace();
    for &(q, qd, qdd) in &[
        (0.0, 0.0, 0.0),
        (0.7, 2.0, -3.0),
        (-2.5, -1.0, 5.0),
        (PI / 2.0, 0.3, 0.0),
    ] {
        let mut tau = [0.0];
        model.inverse_dynamics(&mut ws, &[q], &[qd], &[qdd], &mut tau);
        let expected = (i_yy + m * l * l) * qdd + d * qd + m * g0 * l * q.sin();
        assert!(
            (tau[0] - expected).abs() < 1e-10,
            "q={q}: τ = {} want {expected}",
            tau[0]
        );
        let mut c = [0.0];
        model.coriolis_forces(&mut ws, &[q], &[qd], &mut c);
        assert!(
            c[0].abs() < 1e-12,
            "one joint has no Coriolis force, got {}",
            c[0]
        );
    }
}

/// Two-link planar arm (point-like masses at the link tips, joints about z, gravity along −y
/// in the plane): the textbook M, C q̇ and g.
#[test]
fn planar_two_link_arm_matches_closed_form() {
    let (m1, m2, l1, l2, g0) = (2.0, 1.5, 0.6, 0.4, 9.81);
    let tiny = Matrix3::from_diagonal_element(1e-9);
    let t = tree(
        vec![
            base_link(),
            link("l1", m1, [l1, 0.0, 0.0], tiny),
            link("l2", m2, [l2, 0.0, 0.0], tiny),
        ],
        vec![
            joint(
                "q1",
                JointKind::Revolute,
                0,
                1,
                pose([0.0; 3], [0.0; 3]),
                Vector3::z(),
            ),
            joint(
                "q2",
                JointKind::Revolute,
                1,
                2,
                pose([l1, 0.0, 0.0], [0.0; 3]),
                Vector3::z(),
            ),
        ],
    );
    let model = DynamicsModel::new(&t, Vector3::new(0.0, -g0, 0.0)).unwrap();
    let mut ws = model.workspace();
    let (q, qd): ([f64; 2], [f64; 2]) = ([0.4, -1.1], [1.3, 0.7]);
    let (c1, s2, c2, c12) = (q[0].cos(), q[1].sin(), q[1].cos(), (q[0] + q[1]).cos());
    let m11 = m1 * l1 * l1 + m2 * (l1 * l1 + l2 * l2 + 2.0 * l1 * l2 * c2);
    let m12 = m2 * (l2 * l2 + l1 * l2 * c2);
    let m22 = m2 * l2 * l2;
    let h = m2 * l1 * l2 * s2;
    let coriolis = [
        -h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]),
        h * qd[0] * qd[0],
    ];
    let gravity = [
        (m1 + m2) * g0 * l1 * c1 + m2 * g0 * l2 * c12,
        m2 * g0 * l2 * c12,
    ];

    let mut m = DMatrix::zeros(2, 2);
    let (mut c, mut g) = ([0.0; 2], [0.0; 2]);
    model.mass_matrix(&mut ws, &q, &mut m);
    model.coriolis_forces(&mut ws, &q, &qd, &mut c);
    model.gravity_forces(&mut ws, &q, &mut g);
    let want = DMatrix::from_row_slice(2, 2, &[m11, m12, m12, m22]);
    // The 1e-9 kg·m² link inertias are the only departure from point masses.
    assert!((&m - &want).amax() < 1e-8, "M = {m}, want {want}");
    for i in 0..2 {
        assert!(
            (c[i] - coriolis[i]).abs() < 1e-10,
            "C qd = {c:?}, want {coriolis:?}"
        );
        assert!(
            (g[i] - gravity[i]).abs() < 1e-10,
            "g = {g:?}, want {gravity:?}"
        );
    }
}

#[test]
fn rejects_trees_without_dynamics() {
    let fixed_only = tree(
        vec![base_link(), link("a", 1.0, [0.0; 3], Matrix3::identity())],
        vec![joint(
            "f",
            JointKind::Fixed,
            0,
            1,
            pose([0.0; 3], [0.0; 3]),
            Vector3::z(),
        )],
    );
    assert_eq!(
        DynamicsModel::new(&fixed_only, GRAVITY),
        Err(DynamicsError::NoMovingJoint)
    );

    let massless = tree(
        vec![base_link(), base_link_named("frame")],
        vec![joint(
            "X",
            JointKind::Prismatic,
            0,
            1,
            pose([0.0; 3], [0.0; 3]),
            Vector3::x(),
        )],
    );
    let err = DynamicsModel::new(&massless, GRAVITY).unwrap_err();
    assert!(
        matches!(err, DynamicsError::MasslessBody { ref joint, .. } if joint == "X"),
        "{err}"
    );

    // A massless frame between two slides with a carriage beyond: the mass matrix is positive
    // definite, the model builds (reduced coordinates need no mass on every body) …
    let slides = |second_axis: Vector3<f64>| {
        tree(
            vec![
                base_link(),
                base_link_named("frame"),
                link("carriage", 2.0, [0.0; 3], Matrix3::identity() * 0.01),
            ],
            vec![
                joint(
                    "X",
                    JointKind::Prismatic,
                    0,
                    1,
                    pose([0.0; 3], [0.0; 3]),
                    Vector3::x(),
                ),
                joint(
                    "Y",
                    JointKind::Prismatic,
                    1,
                    2,
                    pose([0.0; 3], [0.0; 3]),
                    second_axis,
                ),
            ],
        )
    };
    let model = DynamicsModel::new(&slides(Vector3::y()), GRAVITY).unwrap();
    let mut mass = nalgebra::DMatrix::zeros(2, 2);
    model.mass_matrix(&mut model.workspace(), &[0.0, 0.0], &mut mass);
    assert!((mass - nalgebra::DMatrix::identity(2, 2) * 2.0).norm() < 1e-12);
    // … but two slides along one line with nothing between them are one coordinate too many.
    let err = DynamicsModel::new(&slides(Vector3::x()), GRAVITY).unwrap_err();
    assert!(
        matches!(err, DynamicsError::MasslessBody { ref joint, .. } if joint == "X"),
        "{err}"
    );

    let mut not_pd = fixed_only.clone();
    not_pd.joints[0].kind = JointKind::Revolute;
    not_pd.links[1].inertia = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.1));
    let err = DynamicsModel::new(&not_pd, GRAVITY).unwrap_err();
    assert!(matches!(err, DynamicsError::BadLink { .. }), "{err}");

    // Children listed before their parents: the recursions would read unset data.
    let out_of_order = tree(
        vec![
            base_link(),
            link("a", 1.0, [0.0; 3], Matrix3::identity()),
            link("b", 1.0, [0.0; 3], Matrix3::identity()),
        ],
        vec![
            joint(
                "j2",
                JointKind::Revolute,
                1,
                2,
                pose([0.0; 3], [0.0; 3]),
                Vector3::z(),
            ),
            joint(
                "j1",
                JointKind::Revolute,
                0,
                1,
                pose([0.0; 3], [0.0; 3]),
                Vector3::z(),
            ),
        ],
    );
    let err = DynamicsModel::new(&out_of_order, GRAVITY).unwrap_err();
    assert!(matches!(err, DynamicsError::MalformedTree(_)), "{err}");

    let ok = {
        let mut t = fixed_only.clone();
        t.joints[0].kind = JointKind::Revolute;
        t
    };
    let model = DynamicsModel::new(&ok, GRAVITY).unwrap();
    assert!(matches!(
        model.clone().with_armature(&[1.0, 2.0]),
        Err(DynamicsError::WrongLength { .. })
    ));
    assert!(matches!(
        model.clone().with_armature(&[-1.0]),
        Err(DynamicsError::Negative { .. })
    ));
    assert!(matches!(
        DynamicsModel::new(&ok, Vector3::new(0.0, f64::NAN, 0.0)),
        Err(DynamicsError::BadGravity(_))
    ));
}

fn base_link_named(name: &str) -> crate::machine::Link {
    crate::machine::Link {
        name: name.into(),
        ..base_link()
    }
}

/// A NaN configuration makes the mass matrix NaN (here the elbow term), which the
/// factorisation reports instead of returning garbage accelerations.
#[test]
fn forward_dynamics_reports_non_finite_configuration() {
    let t = tree(
        vec![
            base_link(),
            link("a", 1.0, [0.1, 0.0, 0.0], Matrix3::identity()),
            link("b", 1.0, [0.1, 0.0, 0.0], Matrix3::identity()),
        ],
        vec![
            joint(
                "R1",
                JointKind::Revolute,
                0,
                1,
                pose([0.0; 3], [0.0; 3]),
                Vector3::z(),
            ),
            joint(
                "R2",
                JointKind::Revolute,
                1,
                2,
                pose([0.5, 0.0, 0.0], [0.0; 3]),
                Vector3::z(),
            ),
        ],
    );
    let model = DynamicsModel::new(&t, GRAVITY).unwrap();
    let mut ws = model.workspace();
    let mut qdd = [0.0; 2];
    let r = model.forward_dynamics(&mut ws, &[0.0, f64::NAN], &[0.0; 2], &[0.0; 2], &mut qdd);
    assert!(
        matches!(r, Err(DynamicsError::MassMatrixNotPositiveDefinite { .. })),
        "{r:?}"
    );
    // And a finite state still works with the same workspace afterwards.
    model
        .forward_dynamics(&mut ws, &[0.0, 0.3], &[0.0; 2], &[0.0; 2], &mut qdd)
        .unwrap();
    assert!(qdd.iter().all(|a| a.is_finite()));
}
