//! Checks and recordings of a setpoint stream that depend only on the sampled positions, not on
//! the planner's bookkeeping.

use std::io::{self, Write};

use super::path::AxisSpec;
use super::setpoints::{SetpointSample, SetpointStream, Setpoints};

/// Largest |velocity|, |acceleration| and |jerk| of one axis (SI units per s, s², s³).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisExtremes {
    /// Largest |velocity| (m/s, or rad/s on a rotary axis).
    pub velocity: f64,
    /// Largest |acceleration| (m/s², or rad/s² on a rotary axis).
    pub acceleration: f64,
    /// Largest |jerk| (m/s³, or rad/s³ on a rotary axis).
    pub jerk: f64,
}

/// Per-axis maxima of |v|, |a|, |j| from the first, second and third finite differences of the
/// sampled positions (divided by T, T², T³).
///
/// A k-th difference over T^k is the k-th derivative averaged with a non-negative B-spline
/// weight of unit area, so it never exceeds the largest true derivative: the figures are lower
/// bounds of the continuous-time maxima and converge to them as T shrinks (up to rounding,
/// which grows like ε·|q|/T³ for the jerk).
pub fn finite_difference_extremes(setpoints: &Setpoints) -> Vec<AxisExtremes> {
    let mut differences = FiniteDifferences::new(setpoints.axes, setpoints.period);
    for k in 0..setpoints.len() {
        differences.push(setpoints.position(k));
    }
    differences.extremes()
}

/// [`finite_difference_extremes`] of a stream, sample by sample: only the last four positions
/// are kept.
#[derive(Debug, Clone)]
pub struct FiniteDifferences {
    period: f64,
    /// The last four positions, oldest first once four have come (axis-major per sample).
    last: [Vec<f64>; 4],
    seen: usize,
    extremes: Vec<AxisExtremes>,
}

impl FiniteDifferences {
    /// Nothing seen yet, for `axes` axes sampled at `period` (s).
    pub fn new(axes: usize, period: f64) -> FiniteDifferences {
        FiniteDifferences {
            period,
            last: std::array::from_fn(|_| vec![0.0; axes]),
            seen: 0,
            extremes: vec![AxisExtremes::default(); axes],
        }
    }

    /// Adds the next sample's positions.
    pub fn push(&mut self, position: &[f64]) {
        self.last.rotate_left(1);
        self.last[3].copy_from_slice(position);
        self.seen += 1;
        let t = self.period;
        let [q0, q1, q2, q3] = &self.last;
        for (i, e) in self.extremes.iter_mut().enumerate() {
            if self.seen >= 2 {
                e.velocity = e.velocity.max(((q3[i] - q2[i]) / t).abs());
            }
            if self.seen >= 3 {
                let d2 = q3[i] - 2.0 * q2[i] + q1[i];
                e.acceleration = e.acceleration.max((d2 / (t * t)).abs());
            }
            if self.seen >= 4 {
                let d3 = q3[i] - 3.0 * q2[i] + 3.0 * q1[i] - q0[i];
                e.jerk = e.jerk.max((d3 / (t * t * t)).abs());
            }
        }
    }

    /// Per axis, the largest |v|, |a|, |j| so far.
    pub fn extremes(&self) -> Vec<AxisExtremes> {
        self.extremes.clone()
    }
}

/// Writes the setpoint stream as CSV: a header `t_s,<axis names>`, then one row per sample with
/// the time (s) and the positions in program units (mm for linear axes, deg for rotary ones),
/// every number in shortest round-trip form (full precision: jerk can be recomputed from
/// third differences of the file).
pub fn write_setpoints_csv<W: Write>(
    out: W,
    setpoints: &Setpoints,
    axes: &[AxisSpec],
) -> io::Result<()> {
    write_setpoint_stream_csv(out, &mut setpoints.stream(), axes)
}

/// [`write_setpoints_csv`] of a stream, sample by sample.
pub fn write_setpoint_stream_csv<W: Write>(
    mut out: W,
    stream: &mut dyn SetpointStream,
    axes: &[AxisSpec],
) -> io::Result<()> {
    assert_eq!(axes.len(), stream.axes(), "one axis spec per setpoint axis");
    write!(out, "t_s")?;
    for axis in axes {
        write!(out, ",{}", axis.name)?;
    }
    writeln!(out)?;
    let scale: Vec<f64> = axes.iter().map(|a| a.kind.program_units_per_si()).collect();
    let period = stream.period();
    let mut sample = SetpointSample::zeros(stream.axes());
    let mut k = 0usize;
    while stream.next_sample(&mut sample) {
        write!(out, "{:?}", k as f64 * period)?;
        for (q, s) in sample.position.iter().zip(&scale) {
            write!(out, ",{:?}", q * s)?;
        }
        writeln!(out)?;
        k += 1;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::path::{AxisKind, AxisLimits};
    use super::*;

    #[test]
    fn extremes_of_a_cubic() {
        // q = t³: third difference is exactly 6 T³.
        let mut sp = Setpoints::new(0.5, 1);
        for k in 0..5 {
            let t = k as f64 * 0.5;
            sp.push(&[t * t * t], &[0.0], &[0.0], 0);
        }
        let e = finite_difference_extremes(&sp);
        assert!((e[0].jerk - 6.0).abs() < 1e-12);
        // Largest second difference: between t = 1 and 2 (6·t at the middle: 9).
        assert!((e[0].acceleration - 9.0).abs() < 1e-12);
    }

    #[test]
    fn csv_in_program_units_round_trips() {
        let axes = vec![
            AxisSpec {
                name: "x".into(),
                kind: AxisKind::Linear,
                limits: AxisLimits {
                    velocity: 1.0,
                    acceleration: 1.0,
                    jerk: 1.0,
                },
            },
            AxisSpec {
                name: "c".into(),
                kind: AxisKind::Rotary,
                limits: AxisLimits {
                    velocity: 1.0,
                    acceleration: 1.0,
                    jerk: 1.0,
                },
            },
        ];
        let mut sp = Setpoints::new(0.001, 2);
        sp.push(
            &[0.1234567890123, std::f64::consts::PI],
            &[0.0; 2],
            &[0.0; 2],
            0,
        );
        sp.push(&[1e-9, -1.0], &[0.0; 2], &[0.0; 2], 0);
        let mut buf = Vec::new();
        write_setpoints_csv(&mut buf, &sp, &axes).unwrap();
        let text = String::from_utf8(buf).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "t_s,x,c");
        let row: Vec<f64> = lines[1].split(',').map(|f| f.parse().unwrap()).collect();
        assert_eq!(row, vec![0.0, 0.1234567890123 * 1e3, 180.0]);
        let row: Vec<f64> = lines[2].split(',').map(|f| f.parse().unwrap()).collect();
        assert_eq!(row[0], 0.001);
        assert_eq!(row[1], 1e-9 * 1e3);
        assert_eq!(row[2], -180.0 / std::f64::consts::PI);
    }
}
