//! The ultimate-cycle search (Ziegler–Nichols): raise a P gain until the loop oscillates
//! without decaying, then narrow the boundary down.
//!
//! The search does not know what it simulates: `simulate(gain)` runs the closed loop from a
//! step of the setpoint and returns the error and command traces. Bracketing multiplies the
//! gain by `growth` from `start_gain` (or divides, if that already oscillates) until the
//! verdict flips; bisection (geometric) then halves the bracket until its relative width is
//! below `tolerance`. Every simulation counts against `max_simulations`, and no gain is tried
//! whose first command (gain × step) would use more than half the actuator's range, so the
//! search always ends: with the boundary, or with an error saying how far it got.
//!
//! Saturation must not fake a limit cycle (a loop driven into its output limit oscillates at
//! a constant amplitude whatever the gain): the oscillation is judged only on the samples
//! before the command first reaches the saturation level, and a run that grows into it counts
//! as oscillating.

use super::oscillation::{analyse, Oscillation, Verdict};
use serde::Serialize;

/// One closed-loop run at one gain, sampled at the servo period.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Response {
    /// Setpoint − position of the axis (joint units).
    pub error: Vec<f64>,
    /// Controller output of the axis (its command units).
    pub command: Vec<f64>,
    /// Why the run ended early (divergence, following-error fault), if it did.
    pub stopped: Option<String>,
}

/// How the search runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SearchSettings {
    /// Servo period (s): the sample spacing of the responses.
    pub servo_period: f64,
    /// Size of the setpoint step (joint units, > 0).
    pub step: f64,
    /// First P gain tried (command units per joint unit), lowered if its first command would
    /// exceed half of `saturation`.
    pub start_gain: f64,
    /// Factor between bracketing gains (> 1).
    pub growth: f64,
    /// Relative width of the final bracket, K_hi/K_lo − 1.
    pub tolerance: f64,
    /// Command level at which the actuator saturates (controller output limit, or the
    /// amplifier's supply / the peak torque in command units, whichever is lower).
    pub saturation: f64,
    /// Smallest turn of the error that counts as a peak (joint units).
    pub hysteresis: f64,
    /// Most simulations the search may run before it gives up.
    pub max_simulations: usize,
}

/// How one run was judged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Outcome {
    /// No oscillation left to judge: the error came to rest ([`Verdict::Settled`]).
    Settled,
    /// The swings shrink (ratio per period < 1).
    Decaying,
    /// The swings grow (ratio per period ≥ 1).
    Growing,
    /// The swings converge to a constant size set by a nonlinearity ([`Verdict::LimitCycle`]).
    LimitCycle,
    /// Grew into the actuator's saturation.
    Saturated,
    /// The run stopped early (diverged, following-error fault).
    Stopped,
}

impl Outcome {
    /// Whether the run counts as oscillating, i.e. its gain is at or above the boundary:
    /// every outcome but settled and decaying.
    pub fn oscillates(self) -> bool {
        !matches!(self, Outcome::Settled | Outcome::Decaying)
    }
}

/// One simulation of the search.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Trial {
    /// The P gain of the run (command units per joint unit).
    pub gain: f64,
    /// How the run was judged.
    pub outcome: Outcome,
    /// The error's oscillation, over the samples before the command first saturated.
    pub oscillation: Oscillation,
    /// Largest |command| over the run.
    pub max_command: f64,
    /// Time of the first saturated command (s), if any.
    pub saturated_at: Option<f64>,
    /// Why the run ended early, if it did.
    pub stopped: Option<String>,
}

/// The boundary found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ultimate {
    /// Ultimate gain K_cr (command units per joint unit), interpolated between the bounds
    /// where ln(ratio) crosses 0 if both ratios are known, else their geometric mean.
    pub gain: f64,
    /// Ultimate period P_cr (s): mean peak spacing of the runs at the bounds.
    pub period: f64,
    /// Highest gain that did not oscillate and lowest that did.
    pub lower: Trial,
    /// The run at the lowest gain that oscillated.
    pub upper: Trial,
    /// Whether a run at the boundary (or any run) ended in a limit cycle: an amplitude set by
    /// a nonlinearity, so K_cr is not the linear ultimate gain.
    pub limit_cycle: bool,
    /// Every run, in the order made.
    pub trials: Vec<Trial>,
}

/// Why the search ended without a boundary.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SearchError {
    /// The simulation at `gain` failed.
    #[error("simulation at K = {gain:.6e} failed: {message}")]
    Simulation {
        /// The gain simulated (command units per joint unit).
        gain: f64,
        /// The simulator's error.
        message: String,
    },
    /// No gain oscillated up to the highest the step allows (a first command of half the
    /// actuator's range).
    #[error("no sustained oscillation up to K = {up_to:.6e} (decay ratio per period there: {ratio}); {why}")]
    NoOscillation {
        /// Highest gain tried (command units per joint unit).
        up_to: f64,
        /// Its decay ratio per period, as text (`none, <outcome>` when not measured).
        ratio: String,
        /// Why no higher gain was tried.
        why: String,
    },
    /// The loop oscillates even far below the start gain: P control cannot hold the axis.
    #[error("the loop oscillates even at K = {down_to:.6e}, {factor:.0e} times below the start gain; the axis cannot be held by P control (check the drive data)")]
    AlwaysOscillating {
        /// Lowest gain tried (command units per joint unit).
        down_to: f64,
        /// How far below the start gain the search went down (a factor).
        factor: f64,
    },
    /// The very first command saturated: the step is too large for the gain.
    #[error("the command saturates at the first sample at K = {gain:.6e} (|u| = {command:.4e} ≥ {saturation:.4e}): the step is too large for this gain; reduce the step")]
    KickSaturates {
        /// The gain simulated (command units per joint unit).
        gain: f64,
        /// Magnitude of the first command (command units).
        command: f64,
        /// The saturation level it reached (command units).
        saturation: f64,
    },
    /// The boundary was bracketed but neither run at its bounds showed a period.
    #[error("no oscillation period could be measured at the boundary K = {lower:.6e} .. {upper:.6e} (outcomes {lower_outcome:?}, {upper_outcome:?}); a longer run may show one")]
    NoPeriod {
        /// Highest gain that did not oscillate.
        lower: f64,
        /// Lowest gain that did.
        upper: f64,
        /// How the run at `lower` was judged.
        lower_outcome: Outcome,
        /// How the run at `upper` was judged.
        upper_outcome: Outcome,
    },
    /// `max_simulations` were used up before the bracket narrowed to the tolerance; holds
    /// the number run.
    #[error("stopped after {0} simulations without narrowing the boundary to the tolerance")]
    TooManySimulations(usize),
}

/// Judges one run (see the module documentation).
pub fn judge(gain: f64, r: &Response, s: &SearchSettings) -> Result<Trial, SearchError> {
    let threshold = s.saturation * (1.0 - 1e-9);
    let saturated = r.command.iter().position(|u| u.abs() >= threshold);
    if saturated == Some(0) {
        return Err(SearchError::KickSaturates {
            gain,
            command: r.command[0].abs(),
            saturation: s.saturation,
        });
    }
    let end = saturated.unwrap_or(r.error.len()).min(r.error.len());
    let oscillation = analyse(&r.error[..end], s.servo_period, s.hysteresis);
    let outcome = if r.stopped.is_some() {
        Outcome::Stopped
    } else if saturated.is_some() && oscillation.ratio.is_none_or(|q| q >= 1.0) {
        Outcome::Saturated
    } else {
        match oscillation.verdict {
            Verdict::Settled => Outcome::Settled,
            Verdict::Decaying => Outcome::Decaying,
            Verdict::Growing => Outcome::Growing,
            Verdict::LimitCycle => Outcome::LimitCycle,
        }
    };
    Ok(Trial {
        gain,
        outcome,
        oscillation,
        max_command: r.command.iter().fold(0.0, |m, u| m.max(u.abs())),
        saturated_at: saturated.map(|k| k as f64 * s.servo_period),
        stopped: r.stopped.clone(),
    })
}

/// Finds the ultimate gain and period. `simulate(gain)` runs the loop at a gain; `progress`
/// hears about every trial as it is judged.
pub fn find_ultimate(
    s: &SearchSettings,
    simulate: &mut dyn FnMut(f64) -> Result<Response, String>,
    progress: &mut dyn FnMut(&Trial),
) -> Result<Ultimate, SearchError> {
    let mut trials: Vec<Trial> = Vec::new();
    let mut run = |gain: f64, trials: &mut Vec<Trial>| -> Result<Trial, SearchError> {
        if trials.len() >= s.max_simulations {
            return Err(SearchError::TooManySimulations(trials.len()));
        }
        let response =
            simulate(gain).map_err(|message| SearchError::Simulation { gain, message })?;
        let trial = judge(gain, &response, s)?;
        progress(&trial);
        trials.push(trial.clone());
        Ok(trial)
    };
    // Half the actuator's range for the first command leaves room for the response to
    // overshoot the step without saturating while it is still being judged.
    let max_gain = 0.5 * s.saturation / s.step;
    let first = run(s.start_gain.min(max_gain), &mut trials)?;
    let (mut lower, mut upper) = if first.outcome.oscillates() {
        let mut upper = first;
        // Far enough down to cover any sensible start; each step is one simulation.
        let floor = s.start_gain * 1e-6;
        loop {
            let gain = upper.gain / s.growth;
            if gain < floor {
                return Err(SearchError::AlwaysOscillating {
                    down_to: upper.gain,
                    factor: 1e6,
                });
            }
            let t = run(gain, &mut trials)?;
            if !t.outcome.oscillates() {
                break (t, upper);
            }
            upper = t;
        }
    } else {
        let mut lower = first;
        loop {
            if lower.gain >= max_gain * (1.0 - 1e-12) {
                return Err(SearchError::NoOscillation {
                    up_to: lower.gain,
                    ratio: ratio_text(&lower),
                    why: format!(
                        "a higher gain would put more than half the actuator's range ({:.4e}) into the first command with this step of {:.4e}; a smaller step reaches higher gains",
                        s.saturation, s.step
                    ),
                });
            }
            let t = run((lower.gain * s.growth).min(max_gain), &mut trials)?;
            if t.outcome.oscillates() {
                break (lower, t);
            }
            lower = t;
        }
    };
    while upper.gain / lower.gain - 1.0 > s.tolerance {
        let t = run((lower.gain * upper.gain).sqrt(), &mut trials)?;
        if t.outcome.oscillates() {
            upper = t;
        } else {
            lower = t;
        }
    }
    let gain = match (lower.oscillation.ratio, upper.oscillation.ratio) {
        (Some(a), Some(b)) if a < 1.0 && b > 1.0 => {
            let (la, lb) = (lower.gain.ln(), upper.gain.ln());
            (la + (lb - la) * (0.0 - a.ln()) / (b.ln() - a.ln())).exp()
        }
        _ => (lower.gain * upper.gain).sqrt(),
    };
    let periods: Vec<f64> = [&lower, &upper]
        .iter()
        .filter_map(|t| t.oscillation.period)
        .collect();
    if periods.is_empty() {
        return Err(SearchError::NoPeriod {
            lower: lower.gain,
            upper: upper.gain,
            lower_outcome: lower.outcome,
            upper_outcome: upper.outcome,
        });
    }
    let period = periods.iter().sum::<f64>() / periods.len() as f64;
    let limit_cycle = trials.iter().any(|t| t.outcome == Outcome::LimitCycle);
    Ok(Ultimate {
        gain,
        period,
        lower,
        upper,
        limit_cycle,
        trials,
    })
}

fn ratio_text(t: &Trial) -> String {
    match t.oscillation.ratio {
        Some(r) => format!("{r:.4}"),
        None => format!("none, {:?}", t.outcome).to_lowercase(),
    }
}

#[cfg(test)]
mod tests {
    use super::super::linear::discrete_ultimate;
    use super::*;
    use crate::frequency::{AxisPlant, LinearActuator, Transmission};

    fn x_axis() -> AxisPlant {
        super::super::linear::xyz_table_x_axis()
    }

    fn settings() -> SearchSettings {
        SearchSettings {
            servo_period: 1e-3,
            step: 5e-5,
            start_gain: 2000.0,
            growth: 2.0,
            tolerance: 0.005,
            saturation: 6.0,
            hysteresis: 5e-8,
            max_simulations: 60,
        }
    }

    /// The exact sampled loop x⁺ = Φx + Γu, u = clamp(K·(r − q)), as a simulator.
    fn sampled_loop(
        axis: AxisPlant,
        s: &SearchSettings,
        seconds: f64,
    ) -> impl FnMut(f64) -> Result<Response, String> {
        let sampled = axis.sampled(s.servo_period);
        let (phi, gamma) = sampled.discrete();
        let (phi, gamma) = (phi.clone(), gamma.clone());
        let (step, limit, n) = (s.step, s.saturation, (seconds / s.servo_period) as usize);
        move |gain: f64| {
            let mut x = nalgebra::DVector::<f64>::zeros(phi.nrows());
            let mut r = Response::default();
            for _ in 0..n {
                let e: f64 = step - x[0];
                let u = (gain * e).clamp(-limit, limit);
                r.error.push(e);
                r.command.push(u);
                x = &phi * x + &gamma * u;
            }
            Ok(r)
        }
    }

    #[test]
    fn the_search_finds_the_sampled_loops_ultimate_cycle() {
        let s = settings();
        let exact = discrete_ultimate(&x_axis(), 1e-3).unwrap();
        let mut sim = sampled_loop(x_axis(), &s, 1.0);
        let u = find_ultimate(&s, &mut sim, &mut |_| {}).unwrap();
        assert!(
            (u.gain / exact.gain - 1.0).abs() < 1e-3,
            "{} vs {exact:?}",
            u.gain
        );
        assert!(
            (u.period / exact.period - 1.0).abs() < 5e-3,
            "{} vs {exact:?}",
            u.period
        );
        assert!(u.lower.gain <= u.gain && u.gain <= u.upper.gain);
        assert!(!u.limit_cycle);
        assert!(u.trials.len() < 20, "{} simulations", u.trials.len());
    }

    #[test]
    fn a_start_above_the_boundary_searches_downwards() {
        let s = SearchSettings {
            start_gain: 50_000.0,
            ..settings()
        };
        let exact = discrete_ultimate(&x_axis(), 1e-3).unwrap();
        let mut sim = sampled_loop(x_axis(), &s, 1.0);
        let u = find_ultimate(&s, &mut sim, &mut |_| {}).unwrap();
        assert!(u.trials[0].outcome.oscillates());
        assert!((u.gain / exact.gain - 1.0).abs() < 1e-3);
    }

    #[test]
    fn a_loop_that_never_oscillates_ends_with_an_error() {
        // Ideal torque with heavy damping: the sampled loop's crossing lies far above the gains
        // the step allows.
        let axis = AxisPlant {
            drive_mass: 0.0,
            drive_damping: 1e4,
            carriage_mass: 1.0,
            carriage_damping: 0.0,
            ratio: 1.0,
            transmission: Transmission::RIGID,
            actuator: LinearActuator::IdealTorque,
            feedback: crate::machine::Feedback::Motor,
        };
        let s = settings();
        let mut sim = sampled_loop(axis, &s, 0.3);
        let e = find_ultimate(&s, &mut sim, &mut |_| {}).unwrap_err();
        assert!(matches!(e, SearchError::NoOscillation { .. }), "{e}");
        assert!(
            e.to_string().contains("no sustained oscillation up to K"),
            "{e}"
        );
    }

    #[test]
    fn saturation_never_counts_as_a_limit_cycle() {
        // An output limit low enough that every unstable run saturates.
        let s = SearchSettings {
            saturation: 1.2,
            step: 1e-5,
            hysteresis: 1e-8,
            start_gain: 1000.0,
            ..settings()
        };
        let mut sim = sampled_loop(x_axis(), &s, 1.0);
        let u = find_ultimate(&s, &mut sim, &mut |_| {}).unwrap();
        assert!(!u.limit_cycle);
        let exact = discrete_ultimate(&x_axis(), 1e-3).unwrap();
        assert!(
            (u.gain / exact.gain - 1.0).abs() < 5e-3,
            "{} vs {exact:?}",
            u.gain
        );
    }

    #[test]
    fn the_simulation_budget_is_respected() {
        let s = SearchSettings {
            max_simulations: 3,
            ..settings()
        };
        let mut sim = sampled_loop(x_axis(), &s, 1.0);
        let mut seen = 0;
        let e = find_ultimate(&s, &mut sim, &mut |_| seen += 1).unwrap_err();
        assert_eq!(e, SearchError::TooManySimulations(3));
        assert_eq!(seen, 3);
    }
}
