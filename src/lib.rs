//! cncsim: a physics co-simulation testbed for CNC machines.
//!
//! The modules follow the data flow (see `docs/architecture.md`):
//! program text → [`program`] → [`kinematics`] → [`plan`] → [`sim`] (with [`control`] and the
//! Rapier [`model`]) → [`report`]; [`scenario`] ties a run together. [`machine`] is the
//! machine description every stage reads, [`dynamics`] its rigid-body dynamics (used by the
//! inverse-dynamics controller). A stage never imports a later one.
#![warn(missing_docs)]

pub mod command;
pub mod control;
pub(crate) mod convert;
pub mod cutting;
pub mod diagnostics;
pub mod dynamics;
pub mod fmi;
pub mod frequency;
pub mod kinematics;
pub mod machine;
pub mod model;
pub mod plan;
pub mod program;
pub mod report;
pub mod scenario;
pub mod sim;
pub mod sweep;
pub mod tune;
