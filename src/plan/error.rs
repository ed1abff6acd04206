//! Why a program cannot be planned.

use super::setpoints::MAX_SETPOINT_SAMPLES;

/// Why a program (or a path) cannot be planned.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum PlanError {
    /// A move's feed gives it no positive, finite duration.
    #[error("move {index} (line {line}): feed {feed} gives no positive finite duration")]
    BadFeed {
        /// Index of the move in the program, from 0.
        index: usize,
        /// Its source line.
        line: u32,
        /// The feed as programmed (m/s, or s for an inverse-time feed) or the speed derived
        /// from it (m/s).
        feed: f64,
    },
    /// An arc the constant-velocity interpolator cannot step along (zero duration or a
    /// degenerate radius).
    #[error("move {index} (line {line}): arc radius {radius} m is degenerate")]
    BadArc {
        /// Index of the move in the program, from 0.
        index: usize,
        /// Its source line.
        line: u32,
        /// Distance of the arc's start from its centre (m).
        radius: f64,
    },
    /// The servo period (s) is not positive and finite.
    #[error("the servo period must be a positive finite number of seconds, got {0}")]
    BadPeriod(f64),
    /// A move the chosen planner or the machine cannot do.
    #[error("move {index} (line {line}): {what} is not supported")]
    Unsupported {
        /// Index of the move in the program, from 0.
        index: usize,
        /// Its source line.
        line: u32,
        /// What is not supported, and why or what to use instead.
        what: &'static str,
    },
    /// The jerk-limited planner rejected a stretch of moves ([`PathError`](super::PathError)).
    #[error(
        "the stretch of moves from move {first_move} (line {line}) cannot be planned: {message}"
    )]
    Path {
        /// Index of the stretch's first move in the program (0 for a path planned directly).
        first_move: usize,
        /// Source line of that move (0 when there is none).
        line: u32,
        /// The path error's text; its segment indices count from `first_move`.
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
        /// Its source line.
        line: u32,
        /// Duration of the plan up to and including that move (s).
        duration: f64,
        /// Samples that would be needed (a float: it may exceed any integer).
        needed: f64,
        /// The servo period (s).
        period: f64,
    },
}
