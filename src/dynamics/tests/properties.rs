//! Random kinematic trees — branches, fixed joints between moving ones, arbitrary origins,
//! axes, centres of mass and rotated inertias — against identities that any correct
//! `M`, `C q̇`, `g` must satisfy. The energies are computed from link poses composed with
//! plain isometries, independent of the spatial algebra under test.

use super::support::{
    base_link, joint, kinetic_energy, link, max_abs, max_abs_diff, pose, potential_energy, tree,
};
use crate::dynamics::DynamicsModel;
use crate::machine::{JointKind, KinematicTree};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};
use proptest::prelude::*;
use proptest::sample::Index;
use std::f64::consts::PI;

const MAX_LINKS: usize = 6;

/// A random machine and a state for it.
#[derive(Debug, Clone)]
struct Case {
    tree: KinematicTree,
    gravity: Vector3<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    armature: Vec<f64>,
}

impl Case {
    fn model(&self) -> DynamicsModel {
        DynamicsModel::new(&self.tree, self.gravity)
            .unwrap()
            .with_armature(&self.armature)
            .unwrap()
    }
    fn mass_matrix(&self, model: &DynamicsModel, q: &[f64]) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(self.q.len(), self.q.len());
        model.mass_matrix(&mut model.workspace(), q, &mut m);
        m
    }
}

#[derive(Debug, Clone)]
struct LinkSpec {
    parent: Index,
    kind: u8,
    origin_xyz: [f64; 3],
    origin_rpy: [f64; 3],
    axis: [f64; 3],
    damping: f64,
    mass: f64,
    com: [f64; 3],
    principal_moments: [f64; 3],
    principal_axes_rpy: [f64; 3],
}

fn link_spec() -> impl Strategy<Value = LinkSpec> {
    use prop::array::uniform3;
    (
        any::<Index>(),
        0u8..4,
        uniform3(-0.5f64..0.5),
        uniform3(-PI..PI),
        uniform3(-1.0f64..1.0),
        0.0f64..2.0,
        0.1f64..20.0,
        uniform3(-0.3f64..0.3),
        uniform3(0.01f64..1.0),
        uniform3(-PI..PI),
    )
        .prop_map(
            |(parent, kind, origin_xyz, origin_rpy, axis, damping, mass, com, moments, axes)| {
                LinkSpec {
                    parent,
                    kind,
                    origin_xyz,
                    origin_rpy,
                    axis,
                    damping,
                    mass,
                    com,
                    principal_moments: moments,
                    principal_axes_rpy: axes,
                }
            },
        )
}

fn case() -> impl Strategy<Value = Case> {
    use prop::array::uniform6;
    (
        prop::collection::vec(link_spec(), 1..=MAX_LINKS),
        uniform6(-PI..PI),
        uniform6(-3.0f64..3.0),
        uniform6(-10.0f64..10.0),
        uniform6(0.0f64..0.5),
        prop::array::uniform3(-10.0f64..10.0),
    )
        .prop_map(|(specs, q, qd, qdd, armature, gravity)| {
            let mut links = vec![base_link()];
            let mut joints = Vec::new();
            for (k, s) in specs.iter().enumerate() {
                let child = k + 1;
                let kind = match s.kind {
                    _ if k == 0 && specs.iter().all(|s| s.kind == 0) => JointKind::Revolute,
                    0 => JointKind::Fixed,
                    1 => JointKind::Prismatic,
                    _ => JointKind::Revolute,
                };
                let axis = Vector3::from(s.axis);
                let axis = if axis.norm() > 0.1 {
                    axis
                } else {
                    Vector3::x()
                };
                let mut j = joint(
                    &format!("j{child}"),
                    kind,
                    s.parent.index(child),
                    child,
                    pose(s.origin_xyz, s.origin_rpy),
                    axis,
                );
                j.damping = s.damping;
                joints.push(j);
                let [a, b, c] = s.principal_moments;
                let r = Rotation3::from_euler_angles(
                    s.principal_axes_rpy[0],
                    s.principal_axes_rpy[1],
                    s.principal_axes_rpy[2],
                );
                let inertia = r.matrix()
                    * Matrix3::from_diagonal(&Vector3::new(a, b, c))
                    * r.matrix().transpose();
                links.push(link(&format!("l{child}"), s.mass, s.com, inertia));
            }
            let dof = joints.iter().filter(|j| j.kind != JointKind::Fixed).count();
            Case {
                tree: tree(links, joints),
                gravity: Vector3::from(gravity),
                q: q[..dof].to_vec(),
                qd: qd[..dof].to_vec(),
                qdd: qdd[..dof].to_vec(),
                armature: armature[..dof].to_vec(),
            }
        })
}

/// Tolerance for finite-difference identities, relative to the size of the terms involved.
fn close(a: &[f64], b: &[f64], scale: f64) -> bool {
    max_abs_diff(a, b) <= 1e-6 * (1.0 + scale)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn mass_matrix_is_symmetric_positive_definite(c in case()) {
        let model = c.model();
        let m = c.mass_matrix(&model, &c.q);
        prop_assert!((&m - m.transpose()).amax() <= 1e-12 * (1.0 + m.amax()), "M = {m}");
        let eigenvalues = m.clone().symmetric_eigenvalues();
        prop_assert!(eigenvalues.min() > 0.0, "eigenvalues {eigenvalues}");
    }

    /// Column j of M is the RNEA force for q̈ = e_j with no velocity and no gravity.
    #[test]
    fn crba_equals_rnea_columns(c in case()) {
        let mut model = c.model();
        model.set_gravity(Vector3::zeros()).unwrap();
        let n = c.q.len();
        let m = c.mass_matrix(&model, &c.q);
        let mut ws = model.workspace();
        let zero = vec![0.0; n];
        let mut column = vec![0.0; n];
        for j in 0..n {
            let mut unit = zero.clone();
            unit[j] = 1.0;
            model.inverse_dynamics(&mut ws, &c.q, &zero, &unit, &mut column);
            let want: Vec<f64> = m.column(j).iter().copied().collect();
            prop_assert!(max_abs_diff(&column, &want) < 1e-10 * (1.0 + m.amax()), "column {j}");
        }
    }

    /// τ splits into the separately computed terms: M q̈ + C q̇ + F q̇ + g.
    #[test]
    fn inverse_dynamics_is_the_sum_of_its_terms(c in case()) {
        let model = c.model();
        let n = c.q.len();
        let mut ws = model.workspace();
        let (mut tau, mut cor, mut grav, mut damp) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        model.inverse_dynamics(&mut ws, &c.q, &c.qd, &c.qdd, &mut tau);
        model.coriolis_forces(&mut ws, &c.q, &c.qd, &mut cor);
        model.gravity_forces(&mut ws, &c.q, &mut grav);
        model.damping_forces(&c.qd, &mut damp);
        let m_qdd = c.mass_matrix(&model, &c.q) * DVector::from_column_slice(&c.qdd);
        let sum: Vec<f64> = (0..n).map(|i| m_qdd[i] + cor[i] + damp[i] + grav[i]).collect();
        prop_assert!(max_abs_diff(&tau, &sum) < 1e-9 * (1.0 + max_abs(&tau)));
    }

    /// ½ q̇ᵀ M q̇ is the kinetic energy of the links, from their pose rates.
    #[test]
    fn mass_matrix_gives_kinetic_energy(c in case()) {
        let mut model = c.model();
        model.set_armature(&vec![0.0; c.q.len()]).unwrap(); // rotor energy is not in the links
        let m = c.mass_matrix(&model, &c.q);
        let qd = DVector::from_column_slice(&c.qd);
        let from_m = 0.5 * qd.dot(&(&m * &qd));
        let from_poses = kinetic_energy(&c.tree, &c.q, &c.qd);
        prop_assert!(close(&[from_m], &[from_poses], from_poses), "{from_m} vs {from_poses}");
    }

    /// g(q) = ∂V/∂q with V the links' potential energy.
    #[test]
    fn gravity_is_the_gradient_of_potential_energy(c in case()) {
        let model = c.model();
        let n = c.q.len();
        let mut g = vec![0.0; n];
        model.gravity_forces(&mut model.workspace(), &c.q, &mut g);
        let h = 1e-6;
        let gradient: Vec<f64> = (0..n)
            .map(|i| {
                let mut plus = c.q.clone();
                let mut minus = c.q.clone();
                plus[i] += h;
                minus[i] -= h;
                (potential_energy(&c.tree, &c.gravity, &plus)
                    - potential_energy(&c.tree, &c.gravity, &minus))
                    / (2.0 * h)
            })
            .collect();
        prop_assert!(close(&g, &gradient, max_abs(&g)), "g = {g:?}, ∂V/∂q = {gradient:?}");
    }

    /// Lagrange: C(q,q̇)q̇ = Ṁ q̇ − ½ ∂/∂q (q̇ᵀ M q̇), with Ṁ and ∂M/∂q by central
    /// differences of CRBA. Its contraction with q̇ is the energy identity
    /// q̇ᵀ (Ṁ − 2C) q̇ = 0 (the quadratic form of the skew-symmetric Ṁ − 2C).
    #[test]
    fn coriolis_matches_lagrangian_form(c in case()) {
        let model = c.model();
        let n = c.q.len();
        let h = 1e-5;
        let qd = DVector::from_column_slice(&c.qd);
        let shifted = |direction: &DVector<f64>, s: f64| -> Vec<f64> {
            c.q.iter().zip(direction.iter()).map(|(q, d)| q + s * d).collect()
        };
        let m_dot = (c.mass_matrix(&model, &shifted(&qd, h))
            - c.mass_matrix(&model, &shifted(&qd, -h)))
            / (2.0 * h);
        let lagrangian: Vec<f64> = (0..n)
            .map(|i| {
                let e = DVector::from_fn(n, |k, _| if k == i { 1.0 } else { 0.0 });
                let dm = (c.mass_matrix(&model, &shifted(&e, h))
                    - c.mass_matrix(&model, &shifted(&e, -h)))
                    / (2.0 * h);
                (&m_dot * &qd)[i] - 0.5 * qd.dot(&(dm * &qd))
            })
            .collect();
        let mut coriolis = vec![0.0; n];
        model.coriolis_forces(&mut model.workspace(), &c.q, &c.qd, &mut coriolis);
        let scale = max_abs(&coriolis).max(m_dot.amax() * qd.amax());
        prop_assert!(close(&coriolis, &lagrangian, scale), "C qd = {coriolis:?}, Lagrange {lagrangian:?}");

        let power = qd.dot(&(&m_dot * &qd)) - 2.0 * qd.dot(&DVector::from_column_slice(&coriolis));
        prop_assert!(power.abs() <= 1e-6 * (1.0 + scale * qd.amax()), "q̇ᵀ(Ṁ − 2C)q̇ = {power}");
    }

    /// Forward dynamics inverts inverse dynamics (damping, armature and gravity included).
    #[test]
    fn forward_dynamics_inverts_inverse_dynamics(c in case()) {
        let model = c.model();
        let n = c.q.len();
        let mut ws = model.workspace();
        let mut tau = vec![0.0; n];
        model.inverse_dynamics(&mut ws, &c.q, &c.qd, &c.qdd, &mut tau);
        let mut qdd = vec![0.0; n];
        model.forward_dynamics(&mut ws, &c.q, &c.qd, &tau, &mut qdd).unwrap();
        // Conditioning: a light, far link can make M ill-conditioned; scale by κ(M).
        let m = c.mass_matrix(&model, &c.q);
        let eig = m.symmetric_eigenvalues();
        let condition = eig.max() / eig.min();
        prop_assert!(
            max_abs_diff(&qdd, &c.qdd) < 1e-12 * condition * (1.0 + max_abs(&c.qdd)),
            "q̈ = {qdd:?}, want {:?} (κ = {condition:e})", c.qdd
        );
    }
}
