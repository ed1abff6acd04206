//! Discrete PID in the two forms of the source documents (seed digest §1.1–1.2).
//!
//! Positional:  u(k) = Kp·e(k) + Ki·T·Σ e(i) + Kd·(e(k) − e(k−1))/T
//! Incremental: m(k) = m(k−1) + K0·e(k) + K1·e(k−1) + K2·e(k−2),
//!              K0 = Kp + Ki·T + Kd/T, K1 = −Kp − 2Kd/T, K2 = Kd/T
//! Unclamped, both give the same output for the same error sequence. With an output limit the
//! positional form stops integrating while the output is saturated in the direction of the
//! error (conditional integration); the incremental form clamps its accumulated output, which
//! is anti-windup by construction.

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidGains {
    pub kp: f64,
    pub ki: f64,
    pub kd: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PidForm {
    #[default]
    Positional,
    Incremental,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Pid {
    gains: PidGains,
    form: PidForm,
    period: f64,
    /// Symmetric output limit (|u| ≤ limit); infinite for none.
    limit: f64,
    /// e(k−1), e(k−2).
    previous: [f64; 2],
    /// Positional form: T·Σe. Incremental form: unused.
    integral: f64,
    /// Last output m(k−1).
    output: f64,
}

impl Pid {
    pub fn new(gains: PidGains, form: PidForm, period: f64, limit: f64) -> Self {
        Pid {
            gains,
            form,
            period,
            limit,
            previous: [0.0; 2],
            integral: 0.0,
            output: 0.0,
        }
    }

    /// One servo tick: error e(k) in, output u(k) out.
    pub fn update(&mut self, error: f64) -> f64 {
        let PidGains { kp, ki, kd } = self.gains;
        let t = self.period;
        let [e1, e2] = self.previous;
        let u = match self.form {
            PidForm::Positional => {
                let integral = self.integral + t * error;
                let unclamped = kp * error + ki * integral + kd * (error - e1) / t;
                let u = unclamped.clamp(-self.limit, self.limit);
                // Integrate unless saturated with the error pushing further into the limit.
                let winding_up = u != unclamped && error.signum() == unclamped.signum();
                if !winding_up {
                    self.integral = integral;
                }
                u
            }
            PidForm::Incremental => {
                let k0 = kp + ki * t + kd / t;
                let k1 = -kp - 2.0 * kd / t;
                let k2 = kd / t;
                (self.output + k0 * error + k1 * e1 + k2 * e2).clamp(-self.limit, self.limit)
            }
        };
        self.previous = [error, e1];
        self.output = u;
        u
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

    #[test]
    fn positional_and_incremental_forms_agree_unclamped() {
        let gains = PidGains {
            kp: 3000.0,
            ki: 2.0e4,
            kd: 25.0,
        };
        let mut a = Pid::new(gains, PidForm::Positional, 1e-3, f64::INFINITY);
        let mut b = Pid::new(gains, PidForm::Incremental, 1e-3, f64::INFINITY);
        let mut worst: f64 = 0.0;
        for e in errors() {
            let (ua, ub) = (a.update(e), b.update(e));
            worst = worst.max((ua - ub).abs() / ua.abs().max(1.0));
        }
        // Only rounding separates the two (the incremental form accumulates sums).
        assert!(worst < 1e-9, "forms differ by {worst}");
    }

    #[test]
    fn positional_form_matches_its_formula() {
        let gains = PidGains {
            kp: 2.0,
            ki: 5.0,
            kd: 0.1,
        };
        let t = 0.004;
        let mut pid = Pid::new(gains, PidForm::Positional, t, f64::INFINITY);
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
    fn clamped_output_recovers_without_windup() {
        // A long saturating error, then the error reverses: an integrator that wound up would
        // hold the output at the limit long after the reversal.
        for form in [PidForm::Positional, PidForm::Incremental] {
            let mut pid = Pid::new(
                PidGains {
                    kp: 1.0,
                    ki: 10.0,
                    kd: 0.0,
                },
                form,
                1e-3,
                1.0,
            );
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
