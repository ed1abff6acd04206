//! Gain design by the Ziegler–Nichols ultimate-cycle method (docs/sources.md §2.2) on a simulated
//! axis. This stage comes after [`sim`](crate::sim): it runs closed loops, but only through a
//! `simulate(gain)` function its caller wires (physics or analytic model), so the search and
//! its judgement of oscillation are plain functions of traces.
//!
//! - [`oscillation`]: does a trace grow, decay, settle or sit in a limit cycle (pure).
//! - [`search`]: bracket and bisect the P gain to the boundary of sustained oscillation.
//! - [`linear`]: the same boundary derived from the axis's linear model (ZOH discretisation
//!   and spectral radius), the independent check.
//! - [`cascade`]: the cascade's velocity loop by the bandwidth its margins allow on the same
//!   linear model, the position loop at a quarter of it.
//!
//! The linear model is the one `bode` lays over its measurements: [`crate::frequency::AxisPlant`].

pub mod cascade;
pub mod linear;
pub mod oscillation;
pub mod search;

pub use cascade::{design_cascade, CascadeDesign, LoopShape, GAIN_MARGIN_DB, PHASE_MARGIN_DEG};
pub use linear::{continuous_ultimate, discrete_ultimate, UltimateCycle};
pub use oscillation::{analyse, Oscillation, Verdict};
pub use search::{find_ultimate, Outcome, Response, SearchError, SearchSettings, Trial, Ultimate};

use serde::Serialize;

/// PID gains by Ziegler–Nichols from the ultimate gain and period, in the controller's form
/// u = Kp·e + Ki·∫e + Kd·ė.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ZieglerNichols {
    /// Proportional gain Kp = 0.6·K_cr (output per m, or per rad on a rotary axis).
    pub kp: f64,
    /// Integral time T_i (s) and derivative time T_d (s).
    pub ti: f64,
    /// Derivative time T_d (s).
    pub td: f64,
    /// Integral gain Ki = Kp/T_i (output per m·s, or per rad·s).
    pub ki: f64,
    /// Derivative gain Kd = Kp·T_d (output per m/s, or per rad/s).
    pub kd: f64,
}

impl ZieglerNichols {
    /// Kp = 0.6·K_cr, T_i = 0.5·P_cr, T_d = 0.125·P_cr, Ki = Kp/T_i, Kd = Kp·T_d.
    pub fn from_ultimate(gain: f64, period: f64) -> Self {
        let kp = 0.6 * gain;
        let ti = 0.5 * period;
        let td = 0.125 * period;
        ZieglerNichols {
            kp,
            ti,
            td,
            ki: kp / ti,
            kd: kp * td,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ziegler_nichols_rules() {
        // The seed's X/Y row: T_i = 0.35 s, T_d = 0.0875 s from P_cr = 0.7 s.
        let z = ZieglerNichols::from_ultimate(64.53, 0.7);
        assert!((z.kp - 38.718).abs() < 1e-9);
        assert!((z.ti - 0.35).abs() < 1e-12 && (z.td - 0.0875).abs() < 1e-12);
        assert!((z.ki - 110.623).abs() < 1e-3 && (z.kd - 3.3878).abs() < 1e-3);
    }
}
