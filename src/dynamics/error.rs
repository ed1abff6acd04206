//! Why a dynamics model cannot be built, or an input cannot be evaluated.

use crate::diagnostics::FileError;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DynamicsError {
    #[error("{0}")]
    File(#[from] FileError),

    #[error("the machine has no prismatic or revolute joint: there is nothing to move")]
    NoMovingJoint,

    #[error("the kinematic tree is malformed: {0}")]
    MalformedTree(String),

    #[error("link '{link}': {problem}")]
    BadLink { link: String, problem: String },

    #[error("joint '{joint}': {problem}")]
    BadJoint { joint: String, problem: String },

    #[error(
        "joint '{joint}' moves no mass (links {links:?} are massless): \
         its row of the mass matrix would be zero"
    )]
    MasslessBody { joint: String, links: Vec<String> },

    #[error("{what} has {got} values, expected {expected} (one per moving joint: {joints})")]
    WrongLength {
        what: String,
        expected: usize,
        got: usize,
        joints: String,
    },

    #[error("{what}[{index}] (joint '{joint}') is {value}: expected a finite number")]
    NotFinite {
        what: String,
        index: usize,
        joint: String,
        value: f64,
    },

    #[error("{what}[{index}] (joint '{joint}') is {value}: expected a finite value ≥ 0")]
    Negative {
        what: String,
        index: usize,
        joint: String,
        value: f64,
    },

    #[error("the gravity vector {0:?} is not finite")]
    BadGravity([f64; 3]),

    #[error(
        "the mass matrix is not positive definite at this configuration \
         (pivot {pivot:e} at joint '{joint}')"
    )]
    MassMatrixNotPositiveDefinite { joint: String, pivot: f64 },

    #[error("the result is not finite (inputs too large?)")]
    NonFiniteResult,
}
