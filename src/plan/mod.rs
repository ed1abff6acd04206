//! Motion planning: program moves → setpoints at the servo period per machine axis.

mod constant_velocity;
mod setpoints;

pub use constant_velocity::{constant_velocity, PlanError};
pub use setpoints::Setpoints;
