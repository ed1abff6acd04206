//! Is a sampled signal oscillating, and does the oscillation grow, decay or hold?
//!
//! A pure function of the samples. Extrema are found with hysteresis (a turn counts only once
//! the signal has come back from it by more than `hysteresis`, so encoder steps and noise do
//! not make peaks), refined by a parabola through the three samples around each, and the
//! oscillation is measured by the peak-to-peak swings between successive extrema, which do not
//! care about a constant offset (a Z axis under P control sags by its gravity offset).
//! The growth per period is fitted over all swings (least squares on ln swing), not taken from
//! one pair, so it is robust to a single badly sampled peak.

use serde::Serialize;

/// Fewest swings (half-periods) from which a growth ratio is fitted: two periods.
pub const MIN_SWINGS: usize = 4;

/// How the oscillation behaves over the window.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// Fewer than two swings before the signal stayed within the hysteresis: no oscillation
    /// left to judge (overdamped, or stuck by friction).
    Settled,
    /// Swings shrink (ratio per period < 1).
    Decaying,
    /// Swings grow (ratio per period ≥ 1).
    Growing,
    /// Swings converge to a constant non-zero size while they first grew or decayed clearly:
    /// an amplitude set by a nonlinearity (friction, backlash), not by the loop gain.
    LimitCycle,
}

impl Verdict {
    /// Whether this counts as sustained oscillation for the ultimate-gain search.
    pub fn oscillates(self) -> bool {
        matches!(self, Verdict::Growing | Verdict::LimitCycle)
    }
}

/// What [`analyse`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Oscillation {
    /// How the oscillation behaves over the window.
    pub verdict: Verdict,
    /// Number of extrema found.
    pub extrema: usize,
    /// Growth of the swing per period over the whole window (> 1 grows); `None` with fewer
    /// than two swings.
    pub ratio: Option<f64>,
    /// Same, over the first and the second half of the swings (`None` below `MIN_SWINGS`).
    pub early_ratio: Option<f64>,
    /// Growth of the swing per period over the second half of the swings (`None` below
    /// [`MIN_SWINGS`]).
    pub late_ratio: Option<f64>,
    /// Mean period from the spacing of the extrema (s); `None` with fewer than three extrema.
    pub period: Option<f64>,
    /// Half the mean of the last two swings: the amplitude at the end of the window.
    pub final_amplitude: f64,
}

/// Late ratio within this of 1 (per period) counts as constant amplitude, and early and late
/// ratios differing by more than `LIMIT_CYCLE_CONTRAST` as a clear change of behaviour.
const LIMIT_CYCLE_FLAT: f64 = 0.03;
const LIMIT_CYCLE_CONTRAST: f64 = 0.2;

/// Analyses `signal` sampled every `period` seconds. `hysteresis` (signal units, ≥ 0) is the
/// size a turn must have to count as an extremum: above the noise or quantisation step.
pub fn analyse(signal: &[f64], period: f64, hysteresis: f64) -> Oscillation {
    let extrema = extrema(signal, hysteresis);
    let swings: Vec<f64> = extrema
        .windows(2)
        .map(|w| (w[1].1 - w[0].1).abs())
        .collect();
    let fit = |s: &[f64]| (s.len() >= 2).then(|| (2.0 * log_slope(s)).exp());
    let ratio = fit(&swings);
    let (early_ratio, late_ratio) = if swings.len() >= MIN_SWINGS {
        let half = swings.len() / 2;
        // The halves share the middle swing when the count is odd: both need two points.
        (fit(&swings[..=half]), fit(&swings[half..]))
    } else {
        (None, None)
    };
    let spacing = (extrema.len() >= 3).then(|| {
        let (first, last) = (extrema[0].0, extrema[extrema.len() - 1].0);
        2.0 * (last - first) / (extrema.len() - 1) as f64 * period
    });
    let final_amplitude = match swings.len() {
        0 => 0.0,
        1 => swings[0] / 2.0,
        n => (swings[n - 1] + swings[n - 2]) / 4.0,
    };
    let verdict = match (ratio, early_ratio, late_ratio) {
        (None, _, _) => Verdict::Settled,
        (_, Some(early), Some(late))
            if (late.ln()).abs() < LIMIT_CYCLE_FLAT
                && (early.ln() - late.ln()).abs() > LIMIT_CYCLE_CONTRAST =>
        {
            Verdict::LimitCycle
        }
        (Some(r), _, _) if r >= 1.0 => Verdict::Growing,
        (Some(_), _, _) => Verdict::Decaying,
    };
    Oscillation {
        verdict,
        extrema: extrema.len(),
        ratio,
        early_ratio,
        late_ratio,
        period: spacing,
        final_amplitude,
    }
}

/// Extrema as (fractional sample index, value), alternating max/min. The first sample is the
/// initial condition, not a turn, and a turn the signal has not yet come back from by the
/// hysteresis (at the end of the window) is not counted.
fn extrema(x: &[f64], hysteresis: f64) -> Vec<(f64, f64)> {
    let mut found = Vec::new();
    if x.len() < 3 {
        return found;
    }
    // Direction: +1 looking for a maximum, −1 for a minimum, 0 not yet known.
    let mut direction = 0.0;
    let (mut hi, mut lo) = (0, 0);
    for i in 1..x.len() {
        if direction >= 0.0 && x[i] > x[hi] {
            hi = i;
        }
        if direction <= 0.0 && x[i] < x[lo] {
            lo = i;
        }
        if direction >= 0.0 && x[i] < x[hi] - hysteresis {
            if hi > 0 {
                found.push(refine(x, hi));
            }
            direction = -1.0;
            lo = i;
        } else if direction <= 0.0 && x[i] > x[lo] + hysteresis {
            if lo > 0 {
                found.push(refine(x, lo));
            }
            direction = 1.0;
            hi = i;
        }
    }
    found
}

/// Vertex of the parabola through samples i−1, i, i+1: the peak between the samples, which
/// the samples themselves miss by up to 1 − cos(πT/P) of the amplitude.
fn refine(x: &[f64], i: usize) -> (f64, f64) {
    if i + 1 >= x.len() {
        return (i as f64, x[i]);
    }
    let (a, b, c) = (x[i - 1], x[i], x[i + 1]);
    let curvature = a - 2.0 * b + c;
    if curvature == 0.0 {
        return (i as f64, b);
    }
    let offset = (0.5 * (a - c) / curvature).clamp(-0.5, 0.5);
    (i as f64 + offset, b - 0.25 * (a - c) * offset)
}

/// Least-squares slope of ln s against the index (per swing, i.e. per half-period).
fn log_slope(s: &[f64]) -> f64 {
    let n = s.len() as f64;
    // A swing of exactly zero (a flat quantised stretch) would be −∞: floor it far below any
    // real swing.
    let floor = s.iter().cloned().fold(0.0, f64::max) * 1e-12 + f64::MIN_POSITIVE;
    let ys: Vec<f64> = s.iter().map(|v| v.max(floor).ln()).collect();
    let mean_x = (n - 1.0) / 2.0;
    let mean_y = ys.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, y) in ys.iter().enumerate() {
        let dx = i as f64 - mean_x;
        sxy += dx * (y - mean_y);
        sxx += dx * dx;
    }
    sxy / sxx
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f64 = 1e-3;

    /// e(t) = offset + a·ρ^(t/P)·cos(2πt/P), sampled at T, period not a multiple of T.
    fn damped(ratio: f64, period: f64, seconds: f64, offset: f64) -> Vec<f64> {
        let n = (seconds / T) as usize;
        (0..n)
            .map(|k| {
                let t = k as f64 * T;
                offset + 1e-4 * ratio.powf(t / period) * (std::f64::consts::TAU * t / period).cos()
            })
            .collect()
    }

    #[test]
    fn growing_decaying_and_sustained_are_told_apart() {
        let p = 0.0347;
        for (ratio, verdict) in [
            (1.3, Verdict::Growing),
            (0.7, Verdict::Decaying),
            (1.02, Verdict::Growing),
            (0.98, Verdict::Decaying),
        ] {
            let o = analyse(&damped(ratio, p, 0.5, 0.0), T, 1e-9);
            assert_eq!(o.verdict, verdict, "ratio {ratio}: {o:?}");
            let r = o.ratio.unwrap();
            assert!(
                (r / ratio - 1.0).abs() < 2e-3,
                "ratio {ratio} fitted as {r}"
            );
            assert!((o.period.unwrap() / p - 1.0).abs() < 2e-3, "{o:?}");
        }
        let o = analyse(&damped(1.0, p, 0.5, 0.0), T, 1e-9);
        assert!((o.ratio.unwrap() - 1.0).abs() < 1e-3, "{o:?}");
        assert!((o.final_amplitude / 1e-4 - 1.0).abs() < 1e-3, "{o:?}");
    }

    #[test]
    fn an_offset_changes_nothing() {
        let a = analyse(&damped(1.1, 0.04, 0.5, 0.0), T, 1e-9);
        let b = analyse(&damped(1.1, 0.04, 0.5, 3e-3), T, 1e-9);
        assert!((a.ratio.unwrap() - b.ratio.unwrap()).abs() < 1e-6);
        assert_eq!(a.extrema, b.extrema);
    }

    #[test]
    fn noise_below_the_hysteresis_makes_no_peaks() {
        // Deterministic pseudo-random noise of ±5 % of the amplitude, plus encoder-like
        // quantisation at 1 % of it.
        let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
        let mut noise = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed as f64 / u64::MAX as f64 - 0.5) * 1e-5
        };
        let q = 1e-6;
        for (ratio, verdict) in [(1.15, Verdict::Growing), (0.85, Verdict::Decaying)] {
            let signal: Vec<f64> = damped(ratio, 0.0347, 0.5, 0.0)
                .into_iter()
                .map(|v| ((v + noise()) / q).round() * q)
                .collect();
            let o = analyse(&signal, T, 2.5e-5);
            assert_eq!(o.verdict, verdict, "{o:?}");
            // 0.5 s / 34.7 ms ≈ 14.4 periods: about 28 extrema, none from the noise.
            assert!((26..=30).contains(&o.extrema), "{o:?}");
            assert!((o.ratio.unwrap() / ratio - 1.0).abs() < 0.03, "{o:?}");
        }
    }

    #[test]
    fn a_signal_that_dies_out_has_settled() {
        // Overdamped: one monotone approach to zero.
        let s: Vec<f64> = (0..500)
            .map(|k| 1e-4 * (-(k as f64) * 0.02).exp())
            .collect();
        let o = analyse(&s, T, 1e-9);
        assert_eq!(o.verdict, Verdict::Settled);
        assert!(!o.verdict.oscillates());
        // Stuck by friction: two swings then constant.
        let mut s = damped(0.3, 0.03, 0.04, 0.0);
        let last = *s.last().unwrap();
        s.extend(std::iter::repeat_n(last, 400));
        assert!(!analyse(&s, T, 1e-7).verdict.oscillates());
    }

    #[test]
    fn growth_into_a_constant_amplitude_is_a_limit_cycle() {
        // Doubles every period, then the amplitude is capped at 8× its start (a limit cycle
        // set by a nonlinearity, not by the gain).
        let p = 0.03;
        let s: Vec<f64> = (0..250)
            .map(|k| {
                let t = k as f64 * T;
                let a = (2f64.powf(t / p)).min(8.0);
                1e-4 * a * (std::f64::consts::TAU * t / p).sin()
            })
            .collect();
        let o = analyse(&s, T, 1e-9);
        assert_eq!(o.verdict, Verdict::LimitCycle, "{o:?}");
        assert!(o.verdict.oscillates());
        assert!((o.final_amplitude / 8e-4 - 1.0).abs() < 0.01, "{o:?}");
    }
}
