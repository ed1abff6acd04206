//! Inverse dynamics by the recursive Newton–Euler algorithm (RBDA Table 5.1), and the bias
//! terms it yields by zeroing parts of the state: `C(q,q̇)q̇` (q̈ = 0, no gravity) and `g(q)`
//! (q̇ = q̈ = 0). O(n) per call.

use super::model::{DynamicsModel, DynamicsWorkspace};
use super::spatial::Motion;
use nalgebra::Vector3;

impl DynamicsModel {
    /// `τ = M(q)q̈ + C(q,q̇)q̇ + F q̇ + g(q)`: the joint forces/torques that produce
    /// acceleration `qdd` at state (`q`, `qd`), including joint damping `F` and armature.
    ///
    /// All slices have [`DynamicsModel::dof`] entries (panics otherwise).
    pub fn inverse_dynamics(
        &self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) {
        self.assert_len("qd", qd.len());
        self.assert_len("qdd", qdd.len());
        rnea(self, ws, q, Some(qd), Some(qdd), &self.gravity, tau);
        for (i, body) in self.bodies.iter().enumerate() {
            tau[i] += body.damping * qd[i] + body.armature * qdd[i];
        }
    }

    /// `C(q,q̇)q̇`: Coriolis and centripetal forces (no damping, no gravity).
    pub fn coriolis_forces(
        &self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        qd: &[f64],
        out: &mut [f64],
    ) {
        self.assert_len("qd", qd.len());
        rnea(self, ws, q, Some(qd), None, &Vector3::zeros(), out);
    }

    /// `g(q)`: the joint forces that hold the machine still against gravity.
    pub fn gravity_forces(&self, ws: &mut DynamicsWorkspace, q: &[f64], out: &mut [f64]) {
        rnea(self, ws, q, None, None, &self.gravity, out);
    }

    /// `F q̇`: viscous joint damping.
    pub fn damping_forces(&self, qd: &[f64], out: &mut [f64]) {
        self.assert_len("qd", qd.len());
        self.assert_len("output", out.len());
        for ((o, body), v) in out.iter_mut().zip(&self.bodies).zip(qd) {
            *o = body.damping * v;
        }
    }

    /// `C(q,q̇)q̇ + F q̇ + g(q)`: everything but the inertial term, in one pass.
    pub fn bias_forces(&self, ws: &mut DynamicsWorkspace, q: &[f64], qd: &[f64], out: &mut [f64]) {
        self.assert_len("qd", qd.len());
        rnea(self, ws, q, Some(qd), None, &self.gravity, out);
        for (i, body) in self.bodies.iter().enumerate() {
            out[i] += body.damping * qd[i];
        }
    }
}

/// The rigid-body part of inverse dynamics (no damping, no armature). `None` rates are zero,
/// which skips their terms rather than multiplying by zero.
pub(super) fn rnea(
    model: &DynamicsModel,
    ws: &mut DynamicsWorkspace,
    q: &[f64],
    qd: Option<&[f64]>,
    qdd: Option<&[f64]>,
    gravity: &Vector3<f64>,
    tau: &mut [f64],
) {
    model.assert_len("q", q.len());
    model.assert_len("output", tau.len());
    ws.assert_fits(model);

    // Gravity as a fictitious upward acceleration of the base (RBDA §5.3): each body's
    // Newton–Euler force then includes its weight, with no separate gravity pass.
    let base_acceleration = Motion::new(Vector3::zeros(), -gravity);

    // Forward pass: velocities and accelerations, base to tips, then each body's net force.
    for (i, body) in model.bodies.iter().enumerate() {
        let x = body.parent_to_body(q[i]);
        let (parent_velocity, parent_acceleration) = match body.parent {
            Some(p) => (ws.velocity[p], ws.acceleration[p]),
            None => (Motion::ZERO, base_acceleration),
        };
        let mut v = x.transform_motion(&parent_velocity);
        let mut a = x.transform_motion(&parent_acceleration);
        if let Some(qd) = qd {
            let joint_velocity = body.subspace * qd[i];
            v += joint_velocity;
            // S is constant in the body frame, so the only velocity-product term is v × Sq̇.
            a += v.cross_motion(&joint_velocity);
        }
        if let Some(qdd) = qdd {
            a += body.subspace * qdd[i];
        }
        let inertia = &body.inertia;
        ws.force[i] = inertia.mul_motion(&a) + v.cross_force(&inertia.mul_motion(&v));
        ws.parent_to_body[i] = x;
        ws.velocity[i] = v;
        ws.acceleration[i] = a;
    }

    // Backward pass: project each body's force on its joint, pass it on to the parent.
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let f = ws.force[i];
        tau[i] = body.subspace.dot(&f);
        if let Some(p) = body.parent {
            let to_parent = ws.parent_to_body[i].inverse_transform_force(&f);
            ws.force[p] += to_parent;
        }
    }
}
