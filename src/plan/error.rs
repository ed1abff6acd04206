//! Why a program cannot be planned.

use super::setpoints::MAX_SETPOINT_SAMPLES;

#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum PlanError {
    #[error("move {index} (line {line}): feed {feed} gives no positive finite duration")]
    BadFeed { index: usize, line: u32, feed: f64 },
    #[error("move {index} (line {line}): arc radius {radius} m is degenerate")]
    BadArc {
        index: usize,
        line: u32,
        radius: f64,
    },
    #[error("the servo period must be a positive finite number of seconds, got {0}")]
    BadPeriod(f64),
    #[error("move {index} (line {line}): {what} is not supported")]
    Unsupported {
        index: usize,
        line: u32,
        what: &'static str,
    },
    #[error(
        "the stretch of moves from move {first_move} (line {line}) cannot be planned: {message}"
    )]
    Path {
        first_move: usize,
        line: u32,
        message: String,
    },
    /// The plan would need more setpoint samples than [`MAX_SETPOINT_SAMPLES`].
    #[error(
        "move {index} (line {line}): the program would take {duration:.4e} s up to here, \
         {needed:.4e} setpoint samples at T = {period_ms} ms; at most {limit} are allowed \
         ({hours:.1} hours at this period): check the feeds, the rapid speed, the dwells and \
         the planner limits",
        period_ms = period * 1e3,
        limit = MAX_SETPOINT_SAMPLES,
        hours = MAX_SETPOINT_SAMPLES as f64 * period / 3600.0
    )]
    TooManySamples {
        /// The move at which the count passed the limit.
        index: usize,
        line: u32,
        duration: f64,
        needed: f64,
        period: f64,
    },
}
