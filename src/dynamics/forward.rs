//! Forward dynamics `q̈ = M⁻¹(τ − C q̇ − F q̇ − g)`: CRBA for `M`, RNEA for the bias, and a
//! Cholesky factorisation of `M` that follows the tree.
//!
//! The factorisation is Featherstone's `M = Lᵀ L` (RBDA §6.5, Table 6.3): eliminating from
//! the tips towards the base, `L` has non-zeros only where `M` does (joint and its ancestors),
//! so it is computed in place with no fill-in, no pivoting and no allocation. For a serial
//! chain it is an ordinary (reversed) dense Cholesky.

use super::error::DynamicsError;
use super::model::{DynamicsModel, DynamicsWorkspace};
use nalgebra::DMatrix;

impl DynamicsModel {
    /// Joint accelerations produced by joint forces `tau` at state (`q`, `qd`), into `qdd`.
    ///
    /// Errors only if the mass matrix is not positive definite, which for a valid model means
    /// a non-finite `q`.
    pub fn forward_dynamics(
        &self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<(), DynamicsError> {
        self.assert_len("tau", tau.len());
        self.assert_len("qdd", qdd.len());
        self.bias_forces(ws, q, qd, qdd);
        for (rhs, t) in qdd.iter_mut().zip(tau) {
            *rhs = t - *rhs;
        }
        let DynamicsWorkspace {
            parent_to_body,
            composite_inertia,
            mass_factor,
            ..
        } = ws;
        self.crba(parent_to_body, composite_inertia, q, mass_factor);
        self.factor_ltl(mass_factor)?;
        self.solve_ltl(mass_factor, qdd);
        Ok(())
    }

    /// In place `M = Lᵀ L`, `L` lower triangular with the tree's sparsity; only the lower
    /// triangle of `m` is meaningful afterwards.
    fn factor_ltl(&self, m: &mut DMatrix<f64>) -> Result<(), DynamicsError> {
        for k in (0..self.dof()).rev() {
            let pivot = m[(k, k)];
            if !(pivot > 0.0 && pivot.is_finite()) {
                return Err(DynamicsError::MassMatrixNotPositiveDefinite {
                    joint: self.bodies[k].joint_name.clone(),
                    pivot,
                });
            }
            let l_kk = pivot.sqrt();
            m[(k, k)] = l_kk;
            let mut i = self.bodies[k].parent;
            while let Some(a) = i {
                m[(k, a)] /= l_kk;
                i = self.bodies[a].parent;
            }
            // Schur complement on the ancestors of k (the only rows/columns k couples to).
            let mut i = self.bodies[k].parent;
            while let Some(a) = i {
                let mut j = Some(a);
                while let Some(b) = j {
                    m[(a, b)] -= m[(k, a)] * m[(k, b)];
                    j = self.bodies[b].parent;
                }
                i = self.bodies[a].parent;
            }
        }
        Ok(())
    }

    /// Solves `Lᵀ L x = b` in place (`x` holds `b` on entry).
    fn solve_ltl(&self, l: &DMatrix<f64>, x: &mut [f64]) {
        // Lᵀ y = b, tips to base.
        for i in (0..self.dof()).rev() {
            x[i] /= l[(i, i)];
            let mut j = self.bodies[i].parent;
            while let Some(a) = j {
                x[a] -= l[(i, a)] * x[i];
                j = self.bodies[a].parent;
            }
        }
        // L x = y, base to tips.
        for i in 0..self.dof() {
            let mut j = self.bodies[i].parent;
            while let Some(a) = j {
                x[i] -= l[(i, a)] * x[a];
                j = self.bodies[a].parent;
            }
            x[i] /= l[(i, i)];
        }
    }
}
