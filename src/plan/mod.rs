//! Motion planning: program moves → setpoints at the servo period per machine axis.
//!
//! - [`constant_velocity`]: the source documents' constant-velocity interpolators (equal steps
//!   V·T on lines, equal chords on circles; docs/sources.md §1.4, §1.6).
//! - [`trapezoid`]: the source documents' trapezoidal profile (docs/sources.md §1.5).
//! - [`profile`]: one-dimensional seven-phase jerk-limited profiles and their closed forms.
//! - [`path`]: the jerk-limited planner's input, a path on the machine axes (SI units).
//! - `geometry`, `blend`, `tangent`, `pieces`: the path's segments, corner blends between
//!   lines, tangent blends between curves, and the chains of pieces they form with their
//!   limits on the path coordinate.
//! - [`planner`]: look-ahead over the chains (whole up to [`planner::LOOKAHEAD_SEGMENTS`],
//!   window by window with handoffs beyond), time-optimal profiles per span; `path_reader`: the
//!   path as the windows read it, made from the program's moves as they go.
//! - [`setpoints`] and `stream`: the output, a stream at the servo period computed as it is
//!   read (every move timed first); [`PlannedProgram`]: a program planned once and streamed
//!   again for every run, no sample kept.
//! - [`metrics`]: finite-difference extremes of a setpoint stream and its CSV recording.

mod blend;
mod constant_velocity;
mod error;
mod from_program;
mod geometry;
pub mod metrics;
pub mod path;
mod path_reader;
mod pieces;
mod planned;
pub mod planner;
pub mod profile;
mod quintic;
pub mod setpoints;
mod stream;
mod tangent;
pub mod trapezoid;

pub use constant_velocity::constant_velocity;
pub use error::PlanError;
pub use from_program::{
    jerk_limited_plans, plan_path_stream, plan_program, plan_program_stream, tool_lever_arms,
    BlendChoice, PlanSettings, Planner,
};
pub use metrics::{
    finite_difference_extremes, write_setpoint_stream_csv, write_setpoints_csv, AxisExtremes,
    FiniteDifferences,
};
pub use path::{AxisKind, AxisLimits, AxisPath, AxisSpec, Blend, Geometry, PathError, PathSegment};
pub use pieces::{SMOOTH_ANGLE, TANGENT_ANGLE};
pub use planned::PlannedProgram;
pub use planner::{plan, ChainGeometry, Plan, PointFeed, SegmentTiming, SPAN_SPREAD};
pub use profile::{Limits, Profile, Recipe, Regime, VelocityChange};
pub use setpoints::{
    sample_count, FirstSamples, LookAhead, SetpointCursor, SetpointSample, SetpointStream,
    Setpoints, MAX_SETPOINT_SAMPLES,
};
pub use stream::collect;
pub use trapezoid::{trapezoid_line, TrapezoidProfile};
