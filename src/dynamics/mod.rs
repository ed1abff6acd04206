//! Rigid-body dynamics of a machine's kinematic tree, in joint space:
//!
//! `τ = M(q) q̈ + C(q,q̇) q̇ + F q̇ + g(q)`
//!
//! with `M` the mass matrix (plus drive armature on its diagonal), `C q̇` the Coriolis and
//! centripetal forces, `F` the diagonal viscous joint damping and `g` the gravity forces.
//!
//! - [`DynamicsModel`] (`model.rs`): built once from a [`crate::machine::KinematicTree`];
//!   fixed joints are merged away, one body per moving joint.
//! - [`AxisDynamics`] (`axes.rs`): the same model in the machine's axis coordinates, as the
//!   controllers use it (`<mimic>` followers substituted).
//! - `rnea.rs`: inverse dynamics, `C q̇`, `g` — recursive Newton–Euler, O(n).
//! - `crba.rs`: `M(q)` — composite-rigid-body algorithm.
//! - `forward.rs`: forward dynamics — CRBA + RNEA + a tree-sparse Cholesky (`M = LᵀL`).
//! - `spatial.rs`: the 6-D spatial vector algebra all of them are written in.
//! - `report.rs`: the validated, user-facing evaluation behind `cncsim dynamics`.
//!
//! Algorithms and notation follow Featherstone, *Rigid Body Dynamics Algorithms* (2008).
//!
//! **Joint order.** Coordinates are the non-fixed joints in the order of `tree.joints`
//! (parents before children; for a URDF listing a serial chain root to tip, URDF order).
//! [`DynamicsModel::joint_names`] gives the names in that order and
//! [`DynamicsModel::coordinate_of`] maps a name to its index.
//!
//! **Real-time use.** Evaluation methods take a [`DynamicsWorkspace`] from
//! [`DynamicsModel::workspace`] and write into caller-provided slices/matrices; they do not
//! allocate. Wrong slice lengths are programming errors and panic; user input goes through
//! [`DynamicsReport::evaluate`], which validates and returns errors instead.

mod axes;
mod crba;
mod error;
mod forward;
mod model;
mod report;
mod rnea;
pub mod spatial;

#[cfg(test)]
mod tests;

pub use axes::AxisDynamics;
pub use error::DynamicsError;
pub use model::{Body, DynamicsModel, DynamicsWorkspace, JointMotion};
pub use report::DynamicsReport;
