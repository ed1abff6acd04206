//! The joint-space mass matrix by the composite-rigid-body algorithm (RBDA Table 6.2).
//!
//! Column `i` of `M` is the joint-space image of the force that accelerates body `i`'s whole
//! subtree — rigid, as one composite body — at unit rate about joint `i`. So composite
//! inertias are accumulated tip to base, and each one's force `Iᶜᵢ Sᵢ` is carried down to the
//! base, projected on every ancestor joint on the way. Entries between joints on different
//! branches are zero (branch-induced sparsity).

use super::model::{DynamicsModel, DynamicsWorkspace};
use super::spatial::{SpatialInertia, Transform};
use nalgebra::DMatrix;

impl DynamicsModel {
    /// `M(q)`, including armature on the diagonal, written into `mass` (`dof × dof`).
    ///
    /// Symmetric positive definite for any `q` of a valid model.
    pub fn mass_matrix(&self, ws: &mut DynamicsWorkspace, q: &[f64], mass: &mut DMatrix<f64>) {
        self.assert_len("q", q.len());
        assert_eq!(mass.shape(), (self.dof(), self.dof()), "mass matrix shape");
        ws.assert_fits(self);
        self.crba(&mut ws.parent_to_body, &mut ws.composite_inertia, q, mass);
    }

    /// CRBA on explicit scratch slices, so that forward dynamics can write `M` into the
    /// workspace's own factor storage.
    pub(super) fn crba(
        &self,
        parent_to_body: &mut [Transform],
        composite_inertia: &mut [SpatialInertia],
        q: &[f64],
        mass: &mut DMatrix<f64>,
    ) {
        for (i, body) in self.bodies.iter().enumerate() {
            parent_to_body[i] = body.parent_to_body(q[i]);
            composite_inertia[i] = body.inertia;
        }
        // Tip to base: a parent's composite inertia takes in its children's (parents have
        // smaller indices, so each child is complete before it is added).
        for (i, body) in self.bodies.iter().enumerate().rev() {
            if let Some(p) = body.parent {
                let child = parent_to_body[i].inverse_transform_inertia(&composite_inertia[i]);
                composite_inertia[p] += child;
            }
        }

        mass.fill(0.0);
        for (i, body) in self.bodies.iter().enumerate() {
            let mut force = composite_inertia[i].mul_motion(&body.subspace);
            mass[(i, i)] = body.subspace.dot(&force) + body.armature;
            let mut j = i;
            while let Some(p) = self.bodies[j].parent {
                force = parent_to_body[j].inverse_transform_force(&force);
                j = p;
                let m_ij = self.bodies[j].subspace.dot(&force);
                mass[(i, j)] = m_ij;
                mass[(j, i)] = m_ij;
            }
        }
    }
}
