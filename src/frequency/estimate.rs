//! Stepped-sine excitation and the estimate of a frequency response from the sampled signals.
//!
//! Each frequency of the sweep is a segment of whole periods at the servo rate: the frequency
//! is moved to the nearest one whose period count fits a block of samples exactly (no leakage),
//! the loop first settles for whole blocks, then a number of blocks is measured. Per block b the
//! discrete Fourier projection at the excitation frequency gives the phasors E_b (excitation)
//! and Y_b (a response); the H1 estimate of the transfer function E → Y and its coherence are
//!
//! ```text
//!   H = Σ conj(E_b)·Y_b / Σ |E_b|²,     γ² = |Σ conj(E_b)·Y_b|² / (Σ |E_b|² · Σ |Y_b|²)
//! ```
//!
//! γ² = 1 when every block responds alike (a linear, settled loop); friction, backlash,
//! encoder steps, saturation or a transient left over lower it.

use super::linear::C64;
use serde::Serialize;
use std::f64::consts::TAU;

/// One frequency of a stepped-sine sweep.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Segment {
    /// The excitation frequency (Hz): a whole number of periods per block.
    pub frequency: f64,
    /// Samples per block.
    pub block: usize,
    /// Whole periods per block.
    pub periods: usize,
    /// Blocks to settle before measuring.
    pub settle_blocks: usize,
    /// Blocks measured.
    pub blocks: usize,
}

impl Segment {
    /// Samples of the whole segment.
    pub fn len(&self) -> usize {
        self.block * (self.settle_blocks + self.blocks)
    }

    /// Whether the segment has no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// How long each frequency is held.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SweepTiming {
    /// Shortest block (s).
    pub min_block: f64,
    /// Shortest settling before measuring (s), and at least `settle_periods` periods.
    pub min_settle: f64,
    /// Fewest periods of the excitation to settle over before measuring.
    pub settle_periods: f64,
    /// Blocks measured per frequency.
    pub blocks: usize,
}

impl Default for SweepTiming {
    fn default() -> Self {
        SweepTiming {
            min_block: 0.05,
            min_settle: 0.5,
            settle_periods: 3.0,
            blocks: 4,
        }
    }
}

/// `count` frequencies spaced evenly on a log scale from `from` to `to` (Hz, both included).
pub fn log_grid(from: f64, to: f64, count: usize) -> Vec<f64> {
    if count < 2 {
        return vec![from];
    }
    let (a, b) = (from.ln(), to.ln());
    (0..count)
        .map(|i| (a + (b - a) * i as f64 / (count - 1) as f64).exp())
        .collect()
}

/// The segments of a stepped-sine sweep over `frequencies` at servo period `t`: each frequency
/// moved to the nearest that fits whole periods into a block; frequencies that land on the same
/// one are measured once. Frequencies must lie below the Nyquist frequency 1/(2t).
pub fn segments(frequencies: &[f64], t: f64, timing: &SweepTiming) -> Vec<Segment> {
    let mut out: Vec<Segment> = Vec::new();
    for &f in frequencies {
        // The fewest whole periods that fill the shortest block, in the nearest whole number
        // of samples (more than two per period: below Nyquist).
        let periods = ((f * timing.min_block).ceil() as usize).max(1);
        let block = ((periods as f64 / (f * t)).round() as usize).max(2 * periods + 1);
        let frequency = periods as f64 / (block as f64 * t);
        if out
            .iter()
            .any(|s| (s.frequency / frequency - 1.0).abs() < 1e-12)
        {
            continue;
        }
        let settle = (timing.min_settle).max(timing.settle_periods / frequency);
        let settle_blocks = (settle / (block as f64 * t)).ceil().max(1.0) as usize;
        out.push(Segment {
            frequency,
            block,
            periods,
            settle_blocks,
            blocks: timing.blocks.max(1),
        });
    }
    out.sort_by(|a, b| a.frequency.total_cmp(&b.frequency));
    out
}

/// The discrete Fourier projection of `x` (one block of whole periods) at `periods` cycles per
/// block: the phasor X with `x[k] ≈ Re(X·e^{jωkT})`.
pub fn phasor(x: &[f64], periods: usize) -> C64 {
    let n = x.len() as f64;
    let step = TAU * periods as f64 / n;
    let sum: C64 = x
        .iter()
        .enumerate()
        .map(|(k, &v)| v * C64::from_polar(1.0, -step * k as f64))
        .sum();
    sum * (2.0 / n)
}

/// The H1 estimate of the transfer function from `excitation` to `response` and its coherence,
/// over the measured blocks of a segment (`excitation` and `response` hold the segment's
/// measured samples only, blocks back to back).
pub fn h1(excitation: &[f64], response: &[f64], segment: &Segment) -> (C64, f64) {
    let (mut cross, mut ee, mut yy) = (C64::new(0.0, 0.0), 0.0, 0.0);
    for b in 0..segment.blocks {
        let range = b * segment.block..(b + 1) * segment.block;
        let e = phasor(&excitation[range.clone()], segment.periods);
        let y = phasor(&response[range], segment.periods);
        cross += e.conj() * y;
        ee += e.norm_sqr();
        yy += y.norm_sqr();
    }
    let coherence = if ee > 0.0 && yy > 0.0 {
        (cross.norm_sqr() / (ee * yy)).min(1.0)
    } else {
        0.0
    };
    (cross / ee, coherence)
}

/// Phases (rad) made continuous along the frequency axis, the first one put on the branch
/// nearest `reference` (rad).
pub fn unwrap(phases: &[f64], reference: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(phases.len());
    let mut previous = reference;
    for &p in phases {
        let turns = ((previous - p) / TAU).round();
        let q = p + turns * TAU;
        out.push(q);
        previous = q;
    }
    out
}

/// Decibels of a magnitude.
pub fn db(x: f64) -> f64 {
    20.0 * x.log10()
}

/// A gain or phase crossover.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Crossover {
    /// Where the crossing is (Hz), interpolated in log-frequency.
    pub frequency_hz: f64,
    /// The margin there: dB (gain margin) or degrees (phase margin).
    pub margin: f64,
}

/// Gain and phase margins of an open loop given at increasing frequencies (Hz): the phase
/// margin 180° + ∠L at every gain crossover (|L| = 1), the smallest reported; the gain margin
/// −20·log₁₀|L| at every phase crossover (∠L = −180° modulo 360°), the smallest in magnitude
/// reported. Crossings are interpolated linearly in log-frequency between points.
pub fn margins(frequency: &[f64], open: &[C64]) -> (Option<Crossover>, Option<Crossover>) {
    let phase = unwrap(
        &open.iter().map(|l| l.arg()).collect::<Vec<_>>(),
        -std::f64::consts::PI,
    );
    let mag: Vec<f64> = open.iter().map(|l| db(l.norm())).collect();
    let lf: Vec<f64> = frequency.iter().map(|f| f.ln()).collect();
    let at = |i: usize, s: f64| (lf[i] + s * (lf[i + 1] - lf[i])).exp();
    let mut gain: Option<Crossover> = None;
    let mut phase_margin: Option<Crossover> = None;
    for i in 0..frequency.len().saturating_sub(1) {
        if (mag[i] > 0.0) != (mag[i + 1] > 0.0) {
            let s = mag[i] / (mag[i] - mag[i + 1]);
            let p = phase[i] + s * (phase[i + 1] - phase[i]);
            // 180° + ∠L, with ∠L taken on the branch nearest −180°.
            let pm = (p.to_degrees() + 180.0).rem_euclid(360.0);
            let pm = if pm > 180.0 { pm - 360.0 } else { pm };
            let c = Crossover {
                frequency_hz: at(i, s),
                margin: pm,
            };
            if phase_margin.is_none_or(|best| c.margin < best.margin) {
                phase_margin = Some(c);
            }
        }
        // Phase crossovers: where the phase passes an odd multiple of 180°.
        let (p0, p1) = (phase[i].to_degrees(), phase[i + 1].to_degrees());
        let lo = p0.min(p1);
        let hi = p0.max(p1);
        let mut k = ((lo - 180.0) / 360.0).ceil();
        while 180.0 + 360.0 * k <= hi {
            let target = 180.0 + 360.0 * k;
            if (p1 - p0).abs() > 0.0 {
                let s = (target - p0) / (p1 - p0);
                let m = mag[i] + s * (mag[i + 1] - mag[i]);
                let c = Crossover {
                    frequency_hz: at(i, s),
                    margin: -m,
                };
                if gain.is_none_or(|best| c.margin.abs() < best.margin.abs()) {
                    gain = Some(c);
                }
            }
            k += 1.0;
        }
    }
    (gain, phase_margin)
}

/// The −3 dB bandwidth of a closed loop given at increasing frequencies (Hz): the first
/// frequency where |T| falls below −3 dB (of unity), interpolated in log-frequency; `None` when
/// it never does within the sweep or starts below it.
pub fn bandwidth(frequency: &[f64], closed: &[C64]) -> Option<f64> {
    let level = -3.0103;
    let mag: Vec<f64> = closed.iter().map(|t| db(t.norm())).collect();
    if mag.first().is_none_or(|&m| m < level) {
        return None;
    }
    (0..frequency.len() - 1)
        .find(|&i| mag[i] >= level && mag[i + 1] < level)
        .map(|i| {
            let s = (mag[i] - level) / (mag[i] - mag[i + 1]);
            (frequency[i].ln() + s * (frequency[i + 1].ln() - frequency[i].ln())).exp()
        })
}

/// Local maxima (`peaks` true) or minima of a magnitude (dB) at increasing frequencies (Hz)
/// that stand out by at least `prominence` dB from the lower (higher) of the extremes on either
/// side before the curve passes them again, among points whose coherence is at least
/// `min_coherence`; each placed at the vertex of the parabola through it and its neighbours in
/// (log f, dB).
pub fn extrema(
    frequency: &[f64],
    magnitude_db: &[f64],
    coherence: &[f64],
    peaks: bool,
    prominence: f64,
    min_coherence: f64,
) -> Vec<f64> {
    let sign = if peaks { 1.0 } else { -1.0 };
    let m: Vec<f64> = magnitude_db.iter().map(|v| sign * v).collect();
    let n = m.len();
    let mut out = Vec::new();
    for i in 1..n.saturating_sub(1) {
        if !(m[i] > m[i - 1] && m[i] >= m[i + 1]) || coherence[i] < min_coherence {
            continue;
        }
        // Prominence: how far the curve falls on each side before rising above m[i].
        let side = |range: &mut dyn Iterator<Item = usize>| {
            let mut low = m[i];
            for j in range {
                if m[j] > m[i] {
                    break;
                }
                low = low.min(m[j]);
            }
            m[i] - low
        };
        let left = side(&mut (0..i).rev());
        let right = side(&mut (i + 1..n));
        if left.min(right) < prominence {
            continue;
        }
        let (x0, x1, x2) = (
            frequency[i - 1].ln(),
            frequency[i].ln(),
            frequency[i + 1].ln(),
        );
        let (y0, y1, y2) = (m[i - 1], m[i], m[i + 1]);
        let denom = (x0 - x1) * (x0 - x2) * (x1 - x2);
        let a = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / denom;
        let b = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / denom;
        let vertex = if a < 0.0 { -b / (2.0 * a) } else { x1 };
        out.push(vertex.clamp(x0, x2).exp());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_fit_whole_periods_into_blocks_below_nyquist() {
        let t = 1e-3;
        let grid = log_grid(1.0, 450.0, 30);
        let s = segments(&grid, t, &SweepTiming::default());
        for seg in &s {
            let exact = seg.periods as f64 / (seg.block as f64 * t);
            assert_eq!(seg.frequency, exact);
            assert!(seg.frequency < 0.5 / t);
            assert!(seg.block as f64 * t >= 0.05 * (1.0 - 0.01));
            assert!(seg.settle_blocks as f64 * seg.block as f64 * t >= 0.5 - 1e-12);
        }
        for w in s.windows(2) {
            assert!(w[1].frequency > w[0].frequency);
        }
        // Every requested frequency is matched within half a bin.
        for f in grid {
            let nearest = s
                .iter()
                .map(|seg| (seg.frequency / f - 1.0).abs())
                .fold(f64::INFINITY, f64::min);
            assert!(nearest < 0.011, "{f} Hz: {nearest}");
        }
    }

    #[test]
    fn h1_recovers_a_known_gain_and_phase_and_coherence_sees_noise() {
        let seg = Segment {
            frequency: 10.0,
            block: 200,
            periods: 2,
            settle_blocks: 0,
            blocks: 4,
        };
        let t = 1e-3;
        let w = TAU * seg.frequency;
        let n = seg.block * seg.blocks;
        let e: Vec<f64> = (0..n).map(|k| (w * k as f64 * t).sin()).collect();
        let y: Vec<f64> = (0..n)
            .map(|k| 3.0 * (w * k as f64 * t - 0.7).sin() + 0.5)
            .collect();
        let (h, c) = h1(&e, &y, &seg);
        assert!((h.norm() - 3.0).abs() < 1e-12 && (h.arg() + 0.7).abs() < 1e-12);
        assert!((c - 1.0).abs() < 1e-12);
        // A response that differs from block to block is not coherent with the excitation.
        let y2: Vec<f64> = (0..n)
            .map(|k| {
                let sign = if (k / seg.block).is_multiple_of(2) {
                    1.0
                } else {
                    -0.2
                };
                sign * (w * k as f64 * t).sin()
            })
            .collect();
        assert!(h1(&e, &y2, &seg).1 < 0.5);
    }

    #[test]
    fn margins_of_a_known_loop() {
        // L = K e^{-sτ}/s: |L| = 1 at ω = K, phase −90° − Kτ·180/π there; phase −180° at
        // ω = π/(2τ), where the gain margin is −20 log(2Kτ/π).
        let (k, tau) = (50.0, 0.004);
        let f = log_grid(0.5, 200.0, 4000);
        let l: Vec<C64> = f
            .iter()
            .map(|&f| {
                let w = TAU * f;
                k * C64::from_polar(1.0, -w * tau) / C64::new(0.0, w)
            })
            .collect();
        let (gm, pm) = margins(&f, &l);
        let pm = pm.unwrap();
        assert!((pm.frequency_hz - k / TAU).abs() < 1e-3 * k / TAU);
        assert!((pm.margin - (90.0 - (k * tau).to_degrees())).abs() < 0.05);
        let gm = gm.unwrap();
        let wc = std::f64::consts::PI / (2.0 * tau);
        assert!((gm.frequency_hz - wc / TAU).abs() < 1e-3 * wc / TAU);
        assert!((gm.margin + db(k / wc)).abs() < 0.01);
    }

    #[test]
    fn bandwidth_and_extrema_of_a_second_order_system() {
        let (wn, zeta) = (TAU * 30.0, 0.05);
        let f = log_grid(1.0, 300.0, 600);
        let t: Vec<C64> = f
            .iter()
            .map(|&f| {
                let s = C64::new(0.0, TAU * f);
                wn * wn / (s * s + 2.0 * zeta * wn * s + wn * wn)
            })
            .collect();
        // |T| = 1/√2 at ω² = wn²·(1 − 2ζ² + √((1 − 2ζ²)² + 1)).
        let a = 1.0 - 2.0 * zeta * zeta;
        let expected = wn * (a + (a * a + 1.0).sqrt()).sqrt() / TAU;
        let bw = bandwidth(&f, &t).unwrap();
        assert!((bw / expected - 1.0).abs() < 1e-3, "{bw} vs {expected}");
        let mag: Vec<f64> = t.iter().map(|t| db(t.norm())).collect();
        let ones = vec![1.0; f.len()];
        let peaks = extrema(&f, &mag, &ones, true, 3.0, 0.5);
        assert_eq!(peaks.len(), 1);
        let fr = wn * (1.0 - 2.0 * zeta * zeta).sqrt() / TAU;
        assert!((peaks[0] / fr - 1.0).abs() < 2e-3, "{peaks:?} vs {fr}");
        assert!(extrema(&f, &mag, &ones, false, 3.0, 0.5).is_empty());
    }
}
