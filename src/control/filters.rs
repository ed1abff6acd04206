//! The filters a servo drive puts on its torque (current) command, after the velocity loop: a
//! second-order low-pass against the high-frequency modes and a notch tuned to one resonance
//! of the drive train (see `docs/compliant-drives.md`). Each is a biquad, the bilinear (Tustin)
//! image of its continuous prototype, prewarped so that its corner or centre frequency is
//! exact at the servo period.
//!
//! ```text
//!   low-pass  H(s) = ω²/(s² + √2·ω·s + ω²)
//!   notch     H(s) = (s² + 2·d·ζ·ω·s + ω²)/(s² + 2·ζ·ω·s + ω²),  ζ = width/(2·f), d = depth
//! ```
//!
//! `width` is the notch's −3 dB bandwidth (Hz, for d = 0), `depth` its gain at the centre
//! (0: a full notch).

use nalgebra::Complex;
use std::f64::consts::TAU;

/// A notch at `hz` of −3 dB width `width_hz` and gain `depth` at its centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Notch {
    /// Centre frequency (Hz).
    pub hz: f64,
    /// −3 dB bandwidth (Hz, that of the full notch, depth 0).
    pub width_hz: f64,
    /// Gain at the centre frequency (0: a full notch, 1: no notch).
    pub depth: f64,
}

/// The torque-command filters of one axis (settings; plain data).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TorqueFilters {
    /// Corner of the second-order (Butterworth) low-pass, Hz.
    pub lowpass_hz: Option<f64>,
    /// The notch, after the low-pass.
    pub notch: Option<Notch>,
}

impl TorqueFilters {
    /// Whether there is no filter (the command passes unchanged).
    pub fn is_empty(&self) -> bool {
        self.lowpass_hz.is_none() && self.notch.is_none()
    }

    /// The discrete filters at servo period `period`, in the order they act.
    pub fn biquads(&self, period: f64) -> Vec<Biquad> {
        let mut chain = Vec::new();
        if let Some(hz) = self.lowpass_hz {
            let w = TAU * hz;
            chain.push(Biquad::bilinear(
                [0.0, 0.0, w * w],
                [1.0, 2f64.sqrt() * w, w * w],
                w,
                period,
            ));
        }
        if let Some(n) = self.notch {
            let w = TAU * n.hz;
            let zeta = n.width_hz / (2.0 * n.hz);
            chain.push(Biquad::bilinear(
                [1.0, 2.0 * n.depth * zeta * w, w * w],
                [1.0, 2.0 * zeta * w, w * w],
                w,
                period,
            ));
        }
        chain
    }

    /// Frequency response of the discrete chain at ω (rad/s), for servo period `period`.
    pub fn response(&self, omega: f64, period: f64) -> Complex<f64> {
        self.biquads(period)
            .iter()
            .map(|b| b.response(omega, period))
            .product()
    }
}

/// y = (b0 + b1·z⁻¹ + b2·z⁻²)/(1 + a1·z⁻¹ + a2·z⁻²)·x, in transposed direct form II.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
    state: [f64; 2],
}

impl Biquad {
    /// The bilinear image of H(s) = (n0·s² + n1·s + n2)/(d0·s² + d1·s + d2), prewarped at
    /// `warp` rad/s.
    fn bilinear(n: [f64; 3], d: [f64; 3], warp: f64, period: f64) -> Biquad {
        // s = K·(1 − z⁻¹)/(1 + z⁻¹), K = ω/tan(ωT/2): exact at ω.
        let k = warp / (warp * period / 2.0).tan();
        let k2 = k * k;
        let numerator = [
            n[0] * k2 + n[1] * k + n[2],
            2.0 * (n[2] - n[0] * k2),
            n[0] * k2 - n[1] * k + n[2],
        ];
        let denominator = [
            d[0] * k2 + d[1] * k + d[2],
            2.0 * (d[2] - d[0] * k2),
            d[0] * k2 - d[1] * k + d[2],
        ];
        let a0 = denominator[0];
        Biquad {
            b: numerator.map(|x| x / a0),
            a: [denominator[1] / a0, denominator[2] / a0],
            state: [0.0; 2],
        }
    }

    /// Filters one sample: the output for input `x`, advancing the state by one period.
    pub fn step(&mut self, x: f64) -> f64 {
        let y = self.b[0] * x + self.state[0];
        self.state[0] = self.b[1] * x - self.a[0] * y + self.state[1];
        self.state[1] = self.b[2] * x - self.a[1] * y;
        y
    }

    /// Clears the state: the filter at rest, as before its first sample.
    pub fn reset(&mut self) {
        self.state = [0.0; 2];
    }

    /// H(e^{jωT}).
    pub fn response(&self, omega: f64, period: f64) -> Complex<f64> {
        let z1 = Complex::from_polar(1.0, -omega * period);
        let z2 = z1 * z1;
        (self.b[0] + z1 * self.b[1] + z2 * self.b[2]) / (1.0 + z1 * self.a[0] + z2 * self.a[1])
    }
}

/// Checks a filter's frequencies against the servo period: each below the Nyquist frequency.
pub fn check_filters(filters: &TorqueFilters, period: f64) -> Result<(), String> {
    let nyquist = 0.5 / period;
    let mut named = vec![];
    if let Some(hz) = filters.lowpass_hz {
        named.push(("torque_lowpass_hz", hz));
    }
    if let Some(n) = filters.notch {
        named.push(("notch_hz", n.hz));
    }
    for (name, hz) in named {
        if !(hz > 0.0 && hz < nyquist) {
            return Err(format!(
                "{name} = {hz} Hz: expected a frequency above 0 and below the Nyquist frequency {nyquist} Hz of the servo period"
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gain of a filter driven by a sine of ω until settled: the response measured in time.
    fn measured_gain(filters: &TorqueFilters, hz: f64, period: f64) -> f64 {
        let mut chain = filters.biquads(period);
        let n = (20.0 / (hz * period)).ceil() as usize;
        let mut peak: f64 = 0.0;
        for k in 0..n {
            let x = (TAU * hz * k as f64 * period).sin();
            let y = chain.iter_mut().fold(x, |v, b| b.step(v));
            if k > n / 2 {
                peak = peak.max(y.abs());
            }
        }
        peak
    }

    #[test]
    fn the_notch_removes_its_centre_and_passes_the_rest() {
        let period = 1e-3;
        let filters = TorqueFilters {
            lowpass_hz: None,
            notch: Some(Notch {
                hz: 40.0,
                width_hz: 10.0,
                depth: 0.0,
            }),
        };
        // Prewarped: exactly zero at 40 Hz; −3 dB at the band edges 40 ± ~5 Hz; 1 far away.
        assert!(filters.response(TAU * 40.0, period).norm() < 1e-9);
        assert!((filters.response(TAU * 1.0, period).norm() - 1.0).abs() < 1e-3);
        assert!((filters.response(TAU * 400.0, period).norm() - 1.0).abs() < 1e-2);
        assert!(measured_gain(&filters, 40.0, period) < 2e-2);
        let g = measured_gain(&filters, 5.0, period);
        assert!(
            (g - filters.response(TAU * 5.0, period).norm()).abs() < 5e-3,
            "{g}"
        );
    }

    #[test]
    fn the_lowpass_is_minus_three_db_at_its_corner() {
        let period = 1e-3;
        let filters = TorqueFilters {
            lowpass_hz: Some(100.0),
            notch: None,
        };
        let corner = filters.response(TAU * 100.0, period);
        assert!((corner.norm() - 0.5f64.sqrt()).abs() < 1e-9, "{corner}");
        // Phase −90° at the corner of a second-order Butterworth.
        assert!((corner.arg().to_degrees() + 90.0).abs() < 1e-6);
        assert!((filters.response(0.0, period).norm() - 1.0).abs() < 1e-12);
        let g = measured_gain(&filters, 100.0, period);
        assert!((g - 0.5f64.sqrt()).abs() < 1e-2, "{g}");
    }
}
