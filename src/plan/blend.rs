//! Corner blends between two lines (G64): the corner is rounded inside by a curve along which
//! the direction turns with a jerk-limited shape, without touching the programmed points.
//!
//! At a corner `C` between lines with directions `u1 = dq/ds` (in) and `u2` (out), the blend of
//! length `L` (in the path coordinate σ) is
//!
//! ```text
//!   g(σ) = P_in + u1·σ + (u2 − u1)·L·Σ(σ/L),    Σ(x) = ∫₀ˣ σ̂,    P_in = C − u1·L/2
//! ```
//!
//! where σ̂ rises from 0 to 1 with a derivative shaped like a trapezoid (ramps of `r` each, peak
//! `h = 1/(1−r)`). `σ̂` is point-symmetric (`σ̂(x) + σ̂(1−x) = 1`), so `Σ(1) = 1/2` and the
//! blend ends on the outgoing line at `C + u2·L/2`; its midpoint `C + L·Σ(1/2)·(u2 − u1)`, with
//! `Σ(1/2) = h·(1/8 − r/4 + r²/6)`, is the point nearest the corner.
//!
//! Along the blend `g' = u1 + (u2 − u1)·σ̂` stays between the two directions, `g'' = (u2 − u1)·σ̂'/L`
//! and `g''' = (u2 − u1)·σ̂''/L²`, so axis `i` has `|g''_i| ≤ h·|Δu_i|/L` and
//! `|g'''_i| ≤ h·|Δu_i|/(r·L²)`: the bounds the planner turns into the blend's speed ceiling and
//! path limits. Passed at constant speed `v` this is a time-optimal jerk-limited velocity change
//! of duration `L/v` on the limiting axis; the planner may also speed up or slow down on it.

use super::geometry::{AxisJet, PathPoint};

/// The normalised direction-change shape σ̂ on [0, 1] with ramp fraction r.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct TurnShape {
    ramp: f64,
    peak: f64,
}

impl TurnShape {
    pub fn new(ramp: f64) -> Self {
        TurnShape {
            ramp,
            peak: 1.0 / (1.0 - ramp),
        }
    }

    /// Peak of σ̂' (h).
    pub fn peak(&self) -> f64 {
        self.peak
    }

    /// Peak of |σ̂''| (h/r).
    pub fn peak_rate(&self) -> f64 {
        self.peak / self.ramp
    }

    /// Σ(1/2): how far the midpoint lies from the corner, per unit of L·|Δu|.
    pub fn midpoint_integral(&self) -> f64 {
        let r = self.ramp;
        self.peak * (1.0 / 8.0 - r / 4.0 + r * r / 6.0)
    }

    /// σ̂'(x), σ̂(x), Σ(x) = ∫₀ˣ σ̂, and σ̂''(x).
    pub fn eval(&self, x: f64) -> (f64, f64, f64, f64) {
        let (r, h) = (self.ramp, self.peak);
        if x > 0.5 {
            // Point symmetry: σ̂(x) = 1 − σ̂(1−x), σ̂'(x) = σ̂'(1−x), Σ(x) = x − 1/2 + Σ(1−x).
            let (d, s, i, dd) = self.eval(1.0 - x);
            return (d, 1.0 - s, x - 0.5 + i, -dd);
        }
        if x <= r {
            (
                h * x / r,
                h * x * x / (2.0 * r),
                h * x * x * x / (6.0 * r),
                h / r,
            )
        } else {
            let m = x - 0.5 * r;
            (
                h,
                h * m,
                h * r * r / 6.0 + 0.5 * h * (m * m - 0.25 * r * r),
                0.0,
            )
        }
    }
}

/// A corner blend: where it starts, the two directions and its size. The vectors live in the
/// plan's arena (`P_in`, `u1`, `Δu = u2 − u1`, one entry per axis each).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct CornerBlend {
    /// Blend length L in the path coordinate.
    pub length: f64,
    pub shape: TurnShape,
}

impl CornerBlend {
    /// Axis positions, velocities and accelerations at `sigma ∈ [0, L]` moving with `σ̇`, `σ̈`;
    /// `data` holds `P_in`, `u1` and `Δu`.
    pub fn eval(&self, data: &[f64], at: PathPoint, out: AxisJet) {
        let (sigma, sigma_dot, sigma_ddot) = at.parts();
        let (position, velocity, acceleration) = out.parts();
        let n = position.len();
        let (start, rest) = data.split_at(n);
        let (u1, du) = rest.split_at(n);
        let l = self.length;
        let sigma = sigma.clamp(0.0, l);
        let (d, s, i, _) = self.shape.eval(sigma / l);
        for k in 0..n {
            let slope = u1[k] + du[k] * s;
            position[k] = start[k] + u1[k] * sigma + du[k] * l * i;
            velocity[k] = slope * sigma_dot;
            acceleration[k] = du[k] * d / l * sigma_dot * sigma_dot + slope * sigma_ddot;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shape_is_consistent() {
        for r in [0.05, 0.2, 0.5] {
            let shape = TurnShape::new(r);
            let (_, s1, i1, _) = shape.eval(1.0);
            assert!((s1 - 1.0).abs() < 1e-14 && (i1 - 0.5).abs() < 1e-14);
            // Midpoint integral in closed form.
            assert!((shape.eval(0.5).2 - shape.midpoint_integral()).abs() < 1e-15);
            // σ̂ and Σ are integrals of σ̂' and σ̂ (midpoint rule on a fine grid); the peaks hold.
            let n = 20000;
            let (mut s, mut i) = (0.0, 0.0);
            for k in 0..n {
                let x = (k as f64 + 0.5) / n as f64;
                let (d, sx, _, dd) = shape.eval(x);
                assert!(d <= shape.peak() * (1.0 + 1e-15) && dd.abs() <= shape.peak_rate());
                s += d / n as f64;
                i += sx / n as f64;
            }
            assert!((s - 1.0).abs() < 1e-6 && (i - 0.5).abs() < 1e-6, "{s} {i}");
        }
    }

    #[test]
    fn blend_starts_and_ends_on_the_lines_and_its_midpoint_is_nearest_the_corner() {
        // 90° corner at the origin: in along +x, out along +y.
        let blend = CornerBlend {
            length: 0.2,
            shape: TurnShape::new(0.3),
        };
        let data = [-0.1, 0.0, 1.0, 0.0, -1.0, 1.0];
        let (mut p, mut v, mut a) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        blend.eval(
            &data,
            PathPoint::new(0.0, 1.0, 0.0),
            AxisJet::new(&mut p, &mut v, &mut a),
        );
        assert_eq!(p, [-0.1, 0.0]);
        assert_eq!(v, [1.0, 0.0]);
        blend.eval(
            &data,
            PathPoint::new(0.2, 1.0, 0.0),
            AxisJet::new(&mut p, &mut v, &mut a),
        );
        assert!((p[0]).abs() < 1e-15 && (p[1] - 0.1).abs() < 1e-15, "{p:?}");
        assert!(v[0].abs() < 1e-15 && (v[1] - 1.0).abs() < 1e-15);
        blend.eval(
            &data,
            PathPoint::new(0.1, 1.0, 0.0),
            AxisJet::new(&mut p, &mut v, &mut a),
        );
        let mid = 0.2 * blend.shape.midpoint_integral();
        assert!(
            (p[0] + mid).abs() < 1e-15 && (p[1] - mid).abs() < 1e-15,
            "{p:?}"
        );
    }
}
