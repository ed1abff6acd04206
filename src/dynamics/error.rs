//! Why a dynamics model cannot be built, or an input cannot be evaluated.

use crate::diagnostics::FileError;

/// Why a [`DynamicsModel`](super::DynamicsModel) cannot be built from a tree, or an input
/// cannot be evaluated with it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DynamicsError {
    /// An error in a user's file (the machine description), passed through.
    #[error("{0}")]
    File(#[from] FileError),

    /// Every joint is fixed.
    #[error("the machine has no prismatic or revolute joint: there is nothing to move")]
    NoMovingJoint,

    /// The links and joints do not form one tree from the root, listed parents first (the
    /// message says how).
    #[error("the kinematic tree is malformed: {0}")]
    MalformedTree(String),

    /// A link's mass or inertia is unusable.
    #[error("link '{link}': {problem}")]
    BadLink {
        /// Name of the link.
        link: String,
        /// What is wrong with it.
        problem: String,
    },

    /// A joint's origin or axis is unusable, or an axis drives a joint the model does not move.
    #[error("joint '{joint}': {problem}")]
    BadJoint {
        /// Name of the joint (`#index` when there is no such joint).
        joint: String,
        /// What is wrong with it.
        problem: String,
    },

    /// A moving joint's body is massless and the mass matrix is singular: no mass moves with
    /// that joint that the other joints do not move the same way.
    #[error(
        "joint '{joint}' moves the massless links {links:?}, and the mass matrix is singular: \
         no mass beyond the joint moves with it apart from the other joints' motion"
    )]
    MasslessBody {
        /// Name of the joint.
        joint: String,
        /// The massless links it moves.
        links: Vec<String>,
    },

    /// An input vector does not have one value per moving joint.
    #[error("{what} has {got} values, expected {expected} (one per moving joint: {joints})")]
    WrongLength {
        /// Which input (`q`, `qd`, `qdd`, `armature`).
        what: String,
        /// Number of moving joints.
        expected: usize,
        /// Number of values given.
        got: usize,
        /// Names of the moving joints, comma-separated, in coordinate order.
        joints: String,
    },

    /// An input value is NaN or infinite.
    #[error("{what}[{index}] (joint '{joint}') is {value}: expected a finite number")]
    NotFinite {
        /// Which input (`q`, `qd`, `qdd`).
        what: String,
        /// Coordinate index of the value.
        index: usize,
        /// Name of the joint at that index.
        joint: String,
        /// The offending value.
        value: f64,
    },

    /// An input that must be finite and non-negative (the armature) is not.
    #[error("{what}[{index}] (joint '{joint}') is {value}: expected a finite value ≥ 0")]
    Negative {
        /// Which input (`armature`).
        what: String,
        /// Coordinate index of the value.
        index: usize,
        /// Name of the joint at that index.
        joint: String,
        /// The offending value.
        value: f64,
    },

    /// The gravity vector (m/s²) has a NaN or infinite component.
    #[error("the gravity vector {0:?} is not finite")]
    BadGravity([f64; 3]),

    /// The Cholesky factorisation of the mass matrix met a pivot that is not positive.
    #[error(
        "the mass matrix is not positive definite at this configuration \
         (pivot {pivot:e} at joint '{joint}')"
    )]
    MassMatrixNotPositiveDefinite {
        /// Name of the joint whose pivot failed.
        joint: String,
        /// The pivot (a diagonal entry during factorisation).
        pivot: f64,
    },

    /// The evaluation overflowed to a non-finite result.
    #[error("the result is not finite (inputs too large?)")]
    NonFiniteResult,
}
