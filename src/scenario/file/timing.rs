//! `[timing]`: the servo period, the physics step inside it, and the settle before the program.

use super::limits;
use super::source::{InFile, Num};
use crate::diagnostics::FileError;
use serde::Deserialize;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTiming {
    servo_period_ms: Num,
    physics_step_ms: Num,
    #[serde(default = "default_settle")]
    settle_s: Num,
    /// Rapier solver iterations per physics step (each is an integration substep).
    #[serde(default = "one")]
    solver_iterations: Spanned<i64>,
}

fn default_settle() -> Num {
    Spanned::new(0..0, 0.5)
}

fn one() -> Spanned<i64> {
    Spanned::new(0..0, 1)
}

/// The loop's timing, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Servo period (s).
    pub servo_period: f64,
    /// Physics steps per servo period.
    pub substeps: usize,
    /// Rapier solver iterations per physics step.
    pub solver_iterations: usize,
    /// Time at rest before the program starts (s).
    pub settle_time: f64,
}

impl Timing {
    /// The physics step (s).
    pub fn physics_step(&self) -> f64 {
        self.servo_period / self.substeps as f64
    }
}

impl TryFrom<InFile<'_, &RawTiming>> for Timing {
    type Error = FileError;

    /// The physics step must fit a whole number of times into the servo period.
    fn try_from(InFile { raw: t, file }: InFile<'_, &RawTiming>) -> Result<Self, FileError> {
        let servo_period_ms = file.ranged(
            &t.servo_period_ms,
            "servo_period_ms",
            "ms",
            limits::SERVO_PERIOD_MS,
        )?;
        let physics_step_ms = file.ranged(
            &t.physics_step_ms,
            "physics_step_ms",
            "ms",
            limits::PHYSICS_STEP_MS,
        )?;
        let (servo_period, physics_step) = (servo_period_ms * 1e-3, physics_step_ms * 1e-3);
        let step_error = |message: String| file.error(t.physics_step_ms.span(), message);
        if physics_step > servo_period * (1.0 + 1e-12) {
            return Err(step_error(format!("physics_step_ms = {physics_step_ms:?} is longer than servo_period_ms = {servo_period_ms:?}: the physics must step at least once per servo period")));
        }
        let ratio = servo_period / physics_step;
        let substeps = ratio.round();
        if (ratio - substeps).abs() > 1e-9 * ratio {
            return Err(step_error(format!("physics_step_ms = {physics_step_ms:?} does not divide servo_period_ms = {servo_period_ms:?} into whole steps (ratio {ratio:.6})")));
        }
        if substeps as usize > limits::MAX_SUBSTEPS {
            return Err(step_error(format!("physics_step_ms = {physics_step_ms:?} makes {substeps} physics steps per servo period: expected at most {}", limits::MAX_SUBSTEPS)));
        }
        let settle_time = file.ranged(&t.settle_s, "settle_s", "s", limits::SETTLE_S)?;
        let solver_iterations = *t.solver_iterations.get_ref();
        if !(1..=64).contains(&solver_iterations) {
            return Err(file.error(
                t.solver_iterations.span(),
                format!(
                    "solver_iterations = {solver_iterations}: expected a whole number from 1 to 64"
                ),
            ));
        }
        Ok(Timing {
            servo_period,
            substeps: substeps as usize,
            solver_iterations: solver_iterations as usize,
            settle_time,
        })
    }
}
