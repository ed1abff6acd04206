//! Motion planning: program moves → setpoints at the servo period per machine axis.
//!
//! - [`constant_velocity`]: the source documents' constant-velocity interpolators (equal steps
//!   V·T on lines, equal chords on circles; docs/sources.md §1.4, §1.6).
//! - [`trapezoid`]: the source documents' trapezoidal profile (docs/sources.md §1.5).
//! - [`profile`]: one-dimensional seven-phase jerk-limited profiles and their closed forms.
//! - [`path`]: the jerk-limited planner's input, a path on the machine axes (SI units).
//! - [`planner`]: look-ahead over the path, synchronised multi-axis motion, corner blends.
//! - [`metrics`]: finite-difference extremes of a setpoint stream and its CSV recording.
//! - [`setpoints`]: the output stream at the servo period.

pub mod blend;
mod constant_velocity;
mod from_program;
mod geometry;
pub mod metrics;
pub mod path;
pub mod planner;
pub mod profile;
pub mod setpoints;
pub mod trapezoid;

pub use constant_velocity::{constant_velocity, PlanError};
pub use from_program::{plan_program, BlendChoice, PlanSettings, Planner};
pub use metrics::{finite_difference_extremes, write_setpoints_csv, AxisExtremes};
pub use path::{AxisKind, AxisLimits, AxisPath, AxisSpec, Blend, Geometry, PathError, PathSegment};
pub use planner::{plan, Plan, SegmentTiming};
pub use profile::{Limits, Profile, Regime, VelocityChange};
pub use setpoints::{SetpointCursor, SetpointSample, SetpointStream, Setpoints};
pub use trapezoid::{trapezoid_line, TrapezoidProfile};
