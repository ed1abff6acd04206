//! Discrete PID with feed-forward, in LinuxCNC's terms (its `pid` component), in the two forms
//! of the source documents (`docs/sources.md`, the controller chapter and the HPGL table):
//!
//! ```text
//!   e  = deadband(clamp(command − feedback, ±max_error))
//!   Positional:  u(k) = Kp·e + Ki·I + Kd·D + bias + FF0·x_d + FF1·ẋ_d + FF2·ẍ_d
//!                I = clamp(I + T·e, ±max_error_i)      (not while the output saturates)
//!                D = clamp((e(k) − e(k−1))/T, ±max_error_d)
//!   Incremental: m(k) = clamp(m(k−1) + Kp·Δe + Ki·T·e + Kd·ΔD, ±output_limit)
//!                u(k) = m(k) + bias + FF0·x_d + FF1·ẋ_d + FF2·ẍ_d
//! ```
//!
//! both clamped to ±output_limit. The incremental form is the velocity form
//! Δm = K0·e(k) + K1·e(k−1) + K2·e(k−2), K0 = Kp + Ki·T + Kd/T, K1 = −Kp − 2Kd/T, K2 = Kd/T,
//! written by terms so that the derivative limit applies; unclamped, the two forms give the
//! same output for the same error sequence. The incremental form keeps its accumulated output
//! within the limit (anti-windup by construction) and has no integral of its own to limit.
//! Feed-forward comes from the setpoint stream (x_d, ẋ_d, ẍ_d), as LinuxCNC's `command-deriv`
//! inputs: FF1 = 1/(velocity gain of the plant) cancels the velocity lag, FF2 the inertia.
//! Deadband and the error limits are in joint units (m or rad), like the error itself.

/// The three gains of a plain PID.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidGains {
    /// Proportional gain (output per m, or per rad on a rotary axis).
    pub kp: f64,
    /// Integral gain (output per m·s, or per rad·s).
    pub ki: f64,
    /// Derivative gain (output per m/s, or per rad/s).
    pub kd: f64,
}

/// Every term of one axis's PID (LinuxCNC `pid` parameter names; limits `None` = none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidSettings {
    /// Proportional gain (output per m, or per rad on a rotary axis).
    pub kp: f64,
    /// Integral gain (output per m·s, or per rad·s).
    pub ki: f64,
    /// Derivative gain (output per m/s, or per rad/s).
    pub kd: f64,
    /// Feed-forward of the setpoint position, velocity and acceleration.
    pub ff0: f64,
    /// Feed-forward of the setpoint velocity (output per m/s, or per rad/s).
    pub ff1: f64,
    /// Feed-forward of the setpoint acceleration (output per m/s², or per rad/s²).
    pub ff2: f64,
    /// Constant added to the output.
    pub bias: f64,
    /// Errors within ±deadband count as zero; beyond it, the excess counts.
    pub deadband: f64,
    /// Limit on |error| before the deadband (m, or rad).
    pub max_error: Option<f64>,
    /// Limit on |I|, the positional form's error integral (m·s, or rad·s).
    pub max_error_i: Option<f64>,
    /// Limit on |D|, the error's derivative (m/s, or rad/s).
    pub max_error_d: Option<f64>,
    /// |output| limit (LinuxCNC's maxoutput); infinite for none.
    pub output_limit: f64,
}

impl PidSettings {
    /// A plain PID: the three gains and an output limit, every other term off.
    pub fn plain(gains: PidGains, output_limit: f64) -> PidSettings {
        PidSettings {
            kp: gains.kp,
            ki: gains.ki,
            kd: gains.kd,
            ff0: 0.0,
            ff1: 0.0,
            ff2: 0.0,
            bias: 0.0,
            deadband: 0.0,
            max_error: None,
            max_error_i: None,
            max_error_d: None,
            output_limit,
        }
    }

    /// Its Kp, Ki and Kd.
    pub fn gains(&self) -> PidGains {
        PidGains {
            kp: self.kp,
            ki: self.ki,
            kd: self.kd,
        }
    }
}

/// Which of the two discrete PID forms runs; unclamped, both give the same output for the
/// same error sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PidForm {
    /// u(k) = Kp·e + Ki·I + Kd·D + feed-forward, with a clamped integral I that stops while
    /// the output saturates.
    #[default]
    Positional,
    /// The velocity form: the PID output accumulates its increments within ±output_limit
    /// (anti-windup by construction), feed-forward added on top.
    Incremental,
}

/// One axis's discrete PID with feed-forward and its state.
#[derive(Debug, Clone, PartialEq)]
pub struct Pid {
    settings: PidSettings,
    form: PidForm,
    period: f64,
    /// e(k−1) after deadband and limit.
    previous_error: f64,
    /// D(k−1) (incremental form).
    previous_derivative: f64,
    /// Positional form: I = T·Σe.
    integral: f64,
    /// Incremental form: the accumulated PID output m(k−1); positional: the last output.
    output: f64,
}

impl Pid {
    /// A PID at rest with `settings` in `form`, run every `period` (s).
    pub fn new(settings: PidSettings, form: PidForm, period: f64) -> Self {
        Pid {
            settings,
            form,
            period,
            previous_error: 0.0,
            previous_derivative: 0.0,
            integral: 0.0,
            output: 0.0,
        }
    }

    /// Its terms.
    pub fn settings(&self) -> &PidSettings {
        &self.settings
    }

    /// Back to the state of a new controller.
    pub fn reset(&mut self) {
        self.previous_error = 0.0;
        self.previous_derivative = 0.0;
        self.integral = 0.0;
        self.output = 0.0;
    }

    /// One servo tick of a plain PID on error `error` (no feed-forward).
    pub fn update(&mut self, error: f64) -> f64 {
        self.update_with(error, 0.0, 0.0, 0.0)
    }

    /// One servo tick: the error `command − feedback`, and the setpoint position, velocity and
    /// acceleration for the feed-forward terms.
    pub fn update_with(
        &mut self,
        error: f64,
        position: f64,
        velocity: f64,
        acceleration: f64,
    ) -> f64 {
        let p = &self.settings;
        let t = self.period;
        let limit = p.output_limit;
        let clamp = |x: f64, l: Option<f64>| l.map_or(x, |l| x.clamp(-l, l));
        let e = deadband(clamp(error, p.max_error), p.deadband);
        let derivative = clamp((e - self.previous_error) / t, p.max_error_d);
        let feed_forward = p.bias + p.ff0 * position + p.ff1 * velocity + p.ff2 * acceleration;
        let u = match self.form {
            PidForm::Positional => {
                let integral = clamp(self.integral + t * e, p.max_error_i);
                // Kd·Δe/T in the order the source writes it (the same figures as ever when no
                // derivative limit applies).
                let d_term = match p.max_error_d {
                    None => p.kd * (e - self.previous_error) / t,
                    Some(_) => p.kd * derivative,
                };
                let unclamped = p.kp * e + p.ki * integral + d_term + feed_forward;
                let u = unclamped.clamp(-limit, limit);
                // Integrate unless saturated with the error pushing further into the limit.
                let winding_up = u != unclamped && e.signum() == unclamped.signum();
                if !winding_up {
                    self.integral = integral;
                }
                self.output = u;
                u
            }
            PidForm::Incremental => {
                let step = p.kp * (e - self.previous_error)
                    + p.ki * t * e
                    + p.kd * (derivative - self.previous_derivative);
                self.output = (self.output + step).clamp(-limit, limit);
                (self.output + feed_forward).clamp(-limit, limit)
            }
        };
        self.previous_error = e;
        self.previous_derivative = derivative;
        u
    }
}

/// LinuxCNC's deadband: zero within ±band, the excess beyond it.
fn deadband(e: f64, band: f64) -> f64 {
    if e > band {
        e - band
    } else if e < -band {
        e + band
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn errors() -> Vec<f64> {
        // A deterministic, irregular error sequence (steps, ramps, sign changes).
        (0..500)
            .map(|k| {
                let k = k as f64;
                1e-3 * (0.3 * k).sin() + 2e-4 * (k / 37.0).floor() - 5e-5 * (k * 0.013).cos()
            })
            .collect()
    }

    fn plain(kp: f64, ki: f64, kd: f64, limit: f64) -> PidSettings {
        PidSettings::plain(PidGains { kp, ki, kd }, limit)
    }

    #[test]
    fn positional_and_incremental_forms_agree_unclamped() {
        let s = plain(3000.0, 2.0e4, 25.0, f64::INFINITY);
        let mut a = Pid::new(s, PidForm::Positional, 1e-3);
        let mut b = Pid::new(s, PidForm::Incremental, 1e-3);
        let mut worst: f64 = 0.0;
        for e in errors() {
            let (ua, ub) = (a.update(e), b.update(e));
            worst = worst.max((ua - ub).abs() / ua.abs().max(1.0));
        }
        // Only rounding separates the two (the incremental form accumulates sums).
        assert!(worst < 1e-9, "forms differ by {worst}");
    }

    #[test]
    fn the_incremental_form_is_the_velocity_form_of_the_source() {
        let (kp, ki, kd, t) = (3.0, 20.0, 0.025, 1e-3);
        let mut pid = Pid::new(plain(kp, ki, kd, f64::INFINITY), PidForm::Incremental, t);
        let (k0, k1, k2) = (kp + ki * t + kd / t, -kp - 2.0 * kd / t, kd / t);
        let (mut m, mut e1, mut e2) = (0.0, 0.0, 0.0);
        for e in errors() {
            m += k0 * e + k1 * e1 + k2 * e2;
            let u = pid.update(e);
            assert!((u - m).abs() < 1e-9 * m.abs().max(1.0), "{u} vs {m}");
            (e2, e1) = (e1, e);
        }
    }

    #[test]
    fn positional_form_matches_its_formula() {
        let t = 0.004;
        let mut pid = Pid::new(plain(2.0, 5.0, 0.1, f64::INFINITY), PidForm::Positional, t);
        let es = [1.0, 0.5, -0.25];
        let mut sum = 0.0;
        let mut prev = 0.0;
        for e in es {
            sum += e;
            let expected = 2.0 * e + 5.0 * t * sum + 0.1 * (e - prev) / t;
            assert!((pid.update(e) - expected).abs() < 1e-12);
            prev = e;
        }
    }

    #[test]
    fn feed_forward_bias_and_limits_follow_linuxcnc() {
        let mut s = plain(10.0, 0.0, 0.0, 100.0);
        s.ff0 = 0.5;
        s.ff1 = 2.0;
        s.ff2 = 0.25;
        s.bias = 1.0;
        s.deadband = 0.1;
        s.max_error = Some(1.0);
        for form in [PidForm::Positional, PidForm::Incremental] {
            let mut pid = Pid::new(s, form, 1e-3);
            // Error 5 is limited to 1, then 0.1 of deadband is removed: P = 10·0.9.
            let u = pid.update_with(5.0, 2.0, 3.0, 4.0);
            assert!(
                (u - (9.0 + 1.0 + 1.0 + 6.0 + 1.0)).abs() < 1e-12,
                "{form:?}: {u}"
            );
            // Within the deadband only the feed-forward and the bias act.
            let mut pid = Pid::new(s, form, 1e-3);
            let u = pid.update_with(0.05, 0.0, 1.0, 0.0);
            assert!((u - 3.0).abs() < 1e-12, "{form:?}: {u}");
        }
    }

    #[test]
    fn integral_and_derivative_limits_hold() {
        let mut s = plain(0.0, 1.0, 0.0, f64::INFINITY);
        s.max_error_i = Some(0.01);
        let mut pid = Pid::new(s, PidForm::Positional, 1e-3);
        for _ in 0..1000 {
            pid.update(1.0);
        }
        assert!((pid.update(1.0) - 0.01).abs() < 1e-15);
        let mut s = plain(0.0, 0.0, 1.0, f64::INFINITY);
        s.max_error_d = Some(2.0);
        for form in [PidForm::Positional, PidForm::Incremental] {
            let mut pid = Pid::new(s, form, 1e-3);
            // A step of 1 in 1 ms is a derivative of 1000, limited to 2.
            assert!((pid.update(1.0) - 2.0).abs() < 1e-12, "{form:?}");
        }
    }

    #[test]
    fn clamped_output_recovers_without_windup() {
        // A long saturating error, then the error reverses: an integrator that wound up would
        // hold the output at the limit long after the reversal.
        for form in [PidForm::Positional, PidForm::Incremental] {
            let mut pid = Pid::new(plain(1.0, 10.0, 0.0, 1.0), form, 1e-3);
            for _ in 0..10_000 {
                assert!(pid.update(5.0) <= 1.0);
            }
            let after = pid.update(-0.5);
            assert!(
                after < 0.5,
                "{form:?}: output {after} after reversal, wound up"
            );
        }
    }
}
