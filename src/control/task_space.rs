//! Task-space inverse dynamics (resolved acceleration) for a table-tilting A-C mill.
//!
//! The task is where the tool is on the part: the tool tip in workpiece coordinates (3) and
//! the tool-axis direction there (a unit vector: 2 DOF), x = [p; u] = f(q) from the URDF chain.
//! Desired motion comes from the joint setpoints through the same kinematics:
//!
//!   x_d = f(q_d),  ẋ_d = J(q_d)·q̇_d,  ẍ_d = J(q_d)·q̈_d + J̇(q_d, q̇_d)·q̇_d
//!   a = ẍ_d + K_D(ẋ_d − ẋ) + K_P(x_d − x)
//!   q̈ = J⁺(a − J̇q̇) + (I − J⁺J)·ν_joint
//!
//! The tool axis being a unit vector, the part of a along it is unreachable (it is of the order
//! of the squared errors) and the least-squares inverse drops it.
//!
//! J⁺ is a damped least-squares inverse whose damping acts only on singular values below λ.
//! At A = 0 the C axis turns the part about the tool axis, so C no longer moves the tool axis
//! and J loses rank; there the null-space term ν_joint (the joint-space computed-torque
//! acceleration) keeps C on its setpoint instead of letting it drift or blow up. On track
//! (x = x_d, ẋ = ẋ_d) the law gives q̈ = q̈_d exactly, singular or not, since J⁺J + (I − J⁺J) = I.
//!
//! J and J̇q̇ are central finite differences of the closed-form forward kinematics: the chain
//! is five joints, so ten pose evaluations cost well under a microsecond, and the steps are
//! chosen so that truncation and rounding both stay below 10⁻⁸ of the values.

use crate::kinematics::{AcAxes, AcAxis, AcTableKinematics};
use nalgebra::{SMatrix, SVector, Vector3};

type Task = SVector<f64, 6>;
type Joints = SVector<f64, 5>;
type Jacobian = SMatrix<f64, 6, 5>;

/// Step of the Jacobian's central differences (m or rad).
const JACOBIAN_STEP: f64 = 1e-6;
/// Largest joint displacement of the second difference that gives J̇q̇ (m or rad).
const CURVATURE_STEP: f64 = 1e-4;

/// The task-space law of a table-tilting A-C mill: resolves the acceleration at the tool tip
/// and tool axis through a damped least-squares inverse of J (see the module documentation).
pub struct TaskSpace {
    kinematics: AcTableKinematics,
    /// Machine-axis index of X, Y, Z, A, C.
    index: [usize; 5],
    damping: f64,
}

impl TaskSpace {
    /// `damping` λ: a singular value σ of J below λ is inverted as σ/λ² (falling to zero with
    /// σ, continuous with 1/σ at λ) and hands its direction to the joint-space law in
    /// proportion 1 − σ²/λ²; those above λ are inverted exactly.
    pub fn new(kinematics: AcTableKinematics, damping: f64) -> Self {
        let index = AcAxis::ALL.map(|a| kinematics.machine_axis(a));
        TaskSpace {
            kinematics,
            index,
            damping,
        }
    }

    fn gather(&self, machine: &[f64]) -> Joints {
        Joints::from_fn(|i, _| machine[self.index[i]])
    }

    /// x = [tool tip in the workpiece frame (m); tool axis there (unit)].
    pub fn task(&self, q: &Joints) -> Task {
        let cl = self
            .kinematics
            .forward(&AcAxes::from_array([q[0], q[1], q[2], q[3], q[4]]));
        let (p, u): (Vector3<f64>, Vector3<f64>) = (cl.point.coords, cl.axis);
        Task::new(p.x, p.y, p.z, u.x, u.y, u.z)
    }

    /// J = ∂x/∂q at joints `q` (X, Y, Z, A, C), 6×5, by central differences of
    /// [`TaskSpace::task`].
    pub fn jacobian(&self, q: &Joints) -> Jacobian {
        let mut j = Jacobian::zeros();
        for i in 0..5 {
            let mut plus = *q;
            let mut minus = *q;
            plus[i] += JACOBIAN_STEP;
            minus[i] -= JACOBIAN_STEP;
            j.set_column(
                i,
                &((self.task(&plus) - self.task(&minus)) / (2.0 * JACOBIAN_STEP)),
            );
        }
        j
    }

    /// J̇(q, q̇)·q̇ = d²/ds² f(q + s·q̇) at s = 0.
    pub fn jacobian_rate_times_velocity(&self, q: &Joints, qd: &Joints) -> Task {
        let peak = qd.amax();
        if peak == 0.0 {
            return Task::zeros();
        }
        let h = CURVATURE_STEP / peak;
        (self.task(&(q + qd * h)) - 2.0 * self.task(q) + self.task(&(q - qd * h))) / (h * h)
    }

    /// The joint accelerations (machine-axis order, into `out`) that impose the task-space
    /// error dynamics with gains `kp`, `kd`; `joint_nu` is the joint-space law's acceleration,
    /// used in the directions the task does not determine.
    #[allow(clippy::too_many_arguments)] // the loop's state and setpoints, each a slice
    pub fn acceleration(
        &self,
        q: &[f64],
        qd: &[f64],
        q_set: &[f64],
        qd_set: &[f64],
        qdd_set: &[f64],
        kp: f64,
        kd: f64,
        joint_nu: &[f64],
        out: &mut [f64],
    ) {
        let (q, qd) = (self.gather(q), self.gather(qd));
        let (q_d, qd_d, qdd_d) = (
            self.gather(q_set),
            self.gather(qd_set),
            self.gather(qdd_set),
        );
        let j_d = self.jacobian(&q_d);
        let x_d = self.task(&q_d);
        let xd_d = j_d * qd_d;
        let xdd_d = j_d * qdd_d + self.jacobian_rate_times_velocity(&q_d, &qd_d);
        let j = self.jacobian(&q);
        let x = self.task(&q);
        let xd = j * qd;
        let a = xdd_d + (xd_d - xd) * kd + (x_d - x) * kp;
        let b = a - self.jacobian_rate_times_velocity(&q, &qd);

        let svd = j.svd(true, true);
        let (u, v_t) = (svd.u.expect("requested"), svd.v_t.expect("requested"));
        let lambda2 = self.damping * self.damping;
        // J⁺b and the projector (I − J⁺J) = V·diag(1 − σ·f(σ))·Vᵀ.
        let mut qdd = Joints::zeros();
        let mut free = Joints::zeros();
        let nu = self.gather(joint_nu);
        for k in 0..5 {
            let s = svd.singular_values[k];
            let damp = if s < self.damping {
                lambda2 - s * s
            } else {
                0.0
            };
            let f = if s > 0.0 { s / (s * s + damp) } else { 0.0 };
            let v = v_t.row(k).transpose();
            qdd += v * (f * u.column(k).dot(&b));
            free += v * ((1.0 - s * f) * v.dot(&nu));
        }
        qdd += free;
        for (i, &m) in self.index.iter().enumerate() {
            out[m] = qdd[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::Machine;

    fn mill() -> TaskSpace {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ac_mill.urdf");
        let machine = Machine::load(&path).expect("ac_mill loads");
        TaskSpace::new(AcTableKinematics::new(&machine).unwrap(), 0.05)
    }

    /// Machine-order vector from X Y Z A C values.
    fn machine(t: &TaskSpace, v: [f64; 5]) -> Vec<f64> {
        let mut out = vec![0.0; 5];
        for (i, &m) in t.index.iter().enumerate() {
            out[m] = v[i];
        }
        out
    }

    fn accel(t: &TaskSpace, q: [f64; 5], qd: [f64; 5], set: [[f64; 5]; 3], nu: [f64; 5]) -> Joints {
        let mut out = vec![0.0; 5];
        let m = |v| machine(t, v);
        t.acceleration(
            &m(q),
            &m(qd),
            &m(set[0]),
            &m(set[1]),
            &m(set[2]),
            400.0,
            40.0,
            &m(nu),
            &mut out,
        );
        t.gather(&out)
    }

    #[test]
    fn the_rate_term_is_the_derivative_of_the_jacobian_along_the_motion() {
        let t = mill();
        let q = Joints::from([0.02, -0.01, 0.03, 0.4, 0.9]);
        let qd = Joints::from([0.1, 0.05, -0.08, 1.5, -2.0]);
        let d = 1e-5;
        let reference =
            (t.jacobian(&(q + qd * d)) * qd - t.jacobian(&(q - qd * d)) * qd) / (2.0 * d);
        let rate = t.jacobian_rate_times_velocity(&q, &qd);
        assert!(
            (rate - reference).norm() < 1e-5 * reference.norm().max(1.0),
            "{rate} vs {reference}"
        );
        // Tool axis rows: the axis stays a unit vector, so J_u·q̇ ⟂ u.
        let x = t.task(&q);
        let u = x.fixed_rows::<3>(3);
        assert!((t.jacobian(&q) * qd).fixed_rows::<3>(3).dot(&u).abs() < 1e-9);
    }

    #[test]
    fn on_track_the_law_returns_the_setpoint_acceleration_even_at_a_zero() {
        let t = mill();
        for a in [0.4, 1e-3, 0.0] {
            let q = [0.02, -0.01, 0.03, a, 0.9];
            let qd = [0.1, 0.05, -0.08, 1.5, -2.0];
            let qdd = [1.0, -2.0, 0.5, 3.0, 4.0];
            let out = accel(&t, q, qd, [q, qd, qdd], qdd);
            let expected = Joints::from(qdd);
            assert!(
                (out - expected).norm() < 1e-5 * expected.norm(),
                "A = {a}: {out} vs {expected}"
            );
        }
    }

    #[test]
    fn away_from_the_singularity_the_task_error_dynamics_hold() {
        let t = mill();
        let q_d = [0.02, -0.01, 0.03, 0.4, 0.9];
        let qd_d = [0.1, 0.05, -0.08, 1.5, -2.0];
        let qdd_d = [1.0, -2.0, 0.5, 3.0, 4.0];
        let q = [0.0201, -0.0102, 0.0299, 0.401, 0.899];
        let qd = [0.101, 0.049, -0.081, 1.49, -2.01];
        // The null-space input must not matter here: J has full rank.
        let nu = [1e3; 5];
        let qdd = accel(&t, q, qd, [q_d, qd_d, qdd_d], nu);
        let g = |v: [f64; 5]| Joints::from(v);
        let (jq, jd) = (t.jacobian(&g(q)), t.jacobian(&g(q_d)));
        let achieved = jq * qdd + t.jacobian_rate_times_velocity(&g(q), &g(qd));
        let wanted = jd * g(qdd_d)
            + t.jacobian_rate_times_velocity(&g(q_d), &g(qd_d))
            + (jd * g(qd_d) - jq * g(qd)) * 40.0
            + (t.task(&g(q_d)) - t.task(&g(q))) * 400.0;
        // The tool axis is a unit vector: no joint acceleration changes its length, so only the
        // part of the wanted ü across the axis is reachable (the least-squares solution drops
        // the radial part, of the order of the squared errors).
        let u = t.task(&g(q)).fixed_rows::<3>(3).into_owned();
        let mut miss = achieved - wanted;
        let radial = miss.fixed_rows::<3>(3).dot(&u);
        miss.fixed_rows_mut::<3>(3).axpy(-radial, &u, 1.0);
        assert!(
            miss.norm() < 1e-6 * wanted.norm(),
            "{miss} radial {radial} u {u}"
        );
    }

    #[test]
    fn at_a_zero_c_follows_the_joint_law_and_nothing_blows_up() {
        let t = mill();
        let q_d = [0.0, 0.0, 0.0, 0.0, 0.3];
        let zero = [0.0; 5];
        // C off its setpoint: invisible to the task at A = 0 (it turns the part about the
        // tool axis, the tool tip being on that axis at X = Y = 0).
        let q = [0.0, 0.0, 0.0, 0.0, 0.29];
        let nu = [0.0, 0.0, 0.0, 0.0, 4.0];
        for a in [0.0, 1e-6, 1e-3] {
            let mut qa = q;
            qa[3] = a;
            let out = accel(&t, qa, zero, [q_d, zero, zero], nu);
            assert!(out.iter().all(|v| v.is_finite()), "A = {a}: {out}");
            assert!(out.amax() < 10.0, "A = {a}: {out}");
            assert!((out[4] - 4.0).abs() < 0.5, "A = {a}: C gets {}", out[4]);
        }
    }
}
