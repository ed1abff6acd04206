//! Runs of short lines smoothed through their programmed points: each line of the run becomes
//! a quintic Hermite curve from its start point to its end point, with the tangent `t` and
//! second derivative `k` (along the path coordinate) given at both points. Neighbouring curves
//! share the data at the point between them, so the path is curvature-continuous through every
//! programmed point and passes exactly through it.
//!
//! At a point inside a run the data are the derivatives of the parabola through the point and
//! its two neighbours (over the path lengths between them): on points sampled from a smooth
//! curve, as CAM systems write them, they approximate that curve's tangent and curvature, so
//! the speed may stay high and the jerk low where a corner blend per point would turn the
//! velocity vector sharply at every point. Where the run meets a line that is not smoothed the
//! data are the line's direction and zero curvature, where it meets an arc the arc's own
//! derivatives.
//!
//! With `x = σ/h` on a line of length `h`:
//!
//! ```text
//!   q(σ) = H0·p0 + h·H1·t0 + h²·H2·k0 + H3·p1 + h·H4·t1 + h²·H5·k1
//!   H0 = 1 − 10x³ + 15x⁴ − 6x⁵     H3 = 10x³ − 15x⁴ + 6x⁵
//!   H1 = x − 6x³ + 8x⁴ − 3x⁵       H4 = −4x³ + 7x⁴ − 3x⁵
//!   H2 = (x² − 3x³ + 3x⁴ − x⁵)/2   H5 = (x³ − 2x⁴ + x⁵)/2
//! ```
//!
//! Per axis `q` is a polynomial of degree five in σ, so `q'''` is a quadratic and `q''` a
//! cubic whose extremes on the segment are found exactly; `|q'|` is bounded from a grid and
//! the bound on `q''`.

use super::geometry::{AxisJet, Metric, PathPoint};

/// Coefficients per axis: `q_i(σ) = Σ_m c[6·i + m]·σ^m`.
pub(super) const COEFFICIENTS: usize = 6;

/// Power-basis coefficients (in x) of H0…H5.
const BASIS: [[f64; 6]; 6] = [
    [1.0, 0.0, 0.0, -10.0, 15.0, -6.0],
    [0.0, 1.0, 0.0, -6.0, 8.0, -3.0],
    [0.0, 0.0, 0.5, -1.5, 1.5, -0.5],
    [0.0, 0.0, 0.0, 10.0, -15.0, 6.0],
    [0.0, 0.0, 0.0, -4.0, 7.0, -3.0],
    [0.0, 0.0, 0.0, 0.5, -1.0, 0.5],
];

/// Position and derivatives at a point of a run.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Knot {
    pub position: Vec<f64>,
    pub tangent: Vec<f64>,
    pub curvature: Vec<f64>,
}

impl Knot {
    /// The least-squares parabola `a + b·d + c·d²/2` through `points` at path coordinates
    /// `s` (d = s − s[at]), evaluated at `points[at]`: position `a`, tangent `b`, second
    /// derivative `c`. Through three points it interpolates them; through more (a window of
    /// points written with the rounding of CAM output) it smooths their noise, which would
    /// otherwise show as curvature.
    pub fn fit(points: &[&[f64]], s: &[f64], at: usize) -> Knot {
        let n = points[at].len();
        let d: Vec<f64> = s.iter().map(|x| x - s[at]).collect();
        // Normal equations of the basis (1, d, d²/2), shared by every axis.
        let mut m = [[0.0; 3]; 3];
        for &x in &d {
            let basis = [1.0, x, 0.5 * x * x];
            for r in 0..3 {
                for c in 0..3 {
                    m[r][c] += basis[r] * basis[c];
                }
            }
        }
        let det = |m: &[[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let full = det(&m);
        let mut knot = Knot {
            position: vec![0.0; n],
            tangent: vec![0.0; n],
            curvature: vec![0.0; n],
        };
        for i in 0..n {
            let mut rhs = [0.0; 3];
            for (p, &x) in points.iter().zip(&d) {
                let basis = [1.0, x, 0.5 * x * x];
                for r in 0..3 {
                    rhs[r] += basis[r] * p[i];
                }
            }
            // Cramer's rule: replace column c by the right-hand side.
            let solve = |c: usize| {
                let mut mc = m;
                for r in 0..3 {
                    mc[r][c] = rhs[r];
                }
                det(&mc) / full
            };
            knot.position[i] = solve(0);
            knot.tangent[i] = solve(1);
            knot.curvature[i] = solve(2);
        }
        knot
    }
}

/// Writes the coefficients of the curve of length `h` between the two knots.
pub(super) fn coefficients(k0: &Knot, k1: &Knot, h: f64, out: &mut Vec<f64>) {
    for i in 0..k0.position.len() {
        let data = [
            k0.position[i],
            h * k0.tangent[i],
            h * h * k0.curvature[i],
            k1.position[i],
            h * k1.tangent[i],
            h * h * k1.curvature[i],
        ];
        let mut scale = 1.0;
        for m in 0..6 {
            let c: f64 = BASIS.iter().zip(&data).map(|(basis, d)| basis[m] * d).sum();
            out.push(c / scale);
            scale *= h;
        }
    }
}

/// Value and first two derivatives of one axis's polynomial at σ.
fn jet(c: &[f64], s: f64) -> (f64, f64, f64) {
    let q = c[0] + s * (c[1] + s * (c[2] + s * (c[3] + s * (c[4] + s * c[5]))));
    let d1 = c[1] + s * (2.0 * c[2] + s * (3.0 * c[3] + s * (4.0 * c[4] + s * 5.0 * c[5])));
    let d2 = 2.0 * c[2] + s * (6.0 * c[3] + s * (12.0 * c[4] + s * 20.0 * c[5]));
    (q, d1, d2)
}

/// Axis positions, velocities and accelerations at σ moving with `σ̇`, `σ̈`.
pub(super) fn eval(coefficients: &[f64], at: PathPoint, out: AxisJet) {
    let (sigma, sigma_dot, sigma_ddot) = at.parts();
    let (position, velocity, acceleration) = out.parts();
    for (i, c) in coefficients.chunks_exact(COEFFICIENTS).enumerate() {
        let (q, d1, d2) = jet(c, sigma);
        position[i] = q;
        velocity[i] = d1 * sigma_dot;
        acceleration[i] = d2 * sigma_dot * sigma_dot + d1 * sigma_ddot;
    }
}

/// Largest |a + b·σ + c·σ²| for σ in [0, h].
fn max_abs_quadratic(a: f64, b: f64, c: f64, h: f64) -> f64 {
    let f = |s: f64| (a + s * (b + s * c)).abs();
    let mut m = f(0.0).max(f(h));
    if c != 0.0 {
        let s = -b / (2.0 * c);
        if s > 0.0 && s < h {
            m = m.max(f(s));
        }
    }
    m
}

/// Real roots of a + b·σ + c·σ² in (0, h).
fn quadratic_roots(a: f64, b: f64, c: f64, h: f64) -> [Option<f64>; 2] {
    let inside = |s: f64| (s > 0.0 && s < h).then_some(s);
    if c == 0.0 {
        return [if b != 0.0 { inside(-a / b) } else { None }, None];
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return [None, None];
    }
    let root = disc.sqrt();
    // Numerically stable pair.
    let q = -0.5 * (b + b.signum() * root);
    let (r1, r2) = if q != 0.0 { (q / c, a / q) } else { (0.0, 0.0) };
    [inside(r1), inside(r2)]
}

/// Per-axis bounds on |q'|, |q''|, |q'''| over [0, h].
pub(super) fn bounds(coefficients: &[f64], h: f64, k1: &mut [f64], k2: &mut [f64], k3: &mut [f64]) {
    const GRID: usize = 32;
    for (i, c) in coefficients.chunks_exact(COEFFICIENTS).enumerate() {
        // q''' = 6c3 + 24c4·σ + 60c5·σ²: exact.
        k3[i] = max_abs_quadratic(6.0 * c[3], 24.0 * c[4], 60.0 * c[5], h);
        // q'' is a cubic: its extremes are at the ends or where q''' vanishes.
        let d2 = |s: f64| jet(c, s).2.abs();
        let mut m2 = d2(0.0).max(d2(h));
        for s in quadratic_roots(6.0 * c[3], 24.0 * c[4], 60.0 * c[5], h)
            .into_iter()
            .flatten()
        {
            m2 = m2.max(d2(s));
        }
        k2[i] = m2;
        // |q'| on a grid, plus what q'' can add between grid points.
        let m1 = (0..=GRID)
            .map(|g| jet(c, h * g as f64 / GRID as f64).1.abs())
            .fold(0.0, f64::max);
        k1[i] = m1 + 0.5 * h / GRID as f64 * m2;
    }
}

/// How far the curve strays from the programmed polyline through `points` (in the tolerance
/// metric): the larger of the distance of any point of the curve from the polyline (from a
/// grid, plus what the speed along the curve allows between grid points) and of any
/// programmed point from the curve (from the grid: an upper bound).
pub(super) fn deviation(
    coefficients: &[f64],
    h: f64,
    points: &[&[f64]],
    k1: &[f64],
    metric: &Metric,
) -> f64 {
    let n = points[0].len();
    let grid = 32 * (points.len() - 1);
    let mut q = vec![0.0; n];
    let mut from_polyline: f64 = 0.0;
    let mut to_points = vec![f64::INFINITY; points.len()];
    for g in 0..=grid {
        let s = h * g as f64 / grid as f64;
        for (i, c) in coefficients.chunks_exact(COEFFICIENTS).enumerate() {
            q[i] = jet(c, s).0;
        }
        let mut nearest = f64::INFINITY;
        for w in points.windows(2) {
            let (a, b) = (w[0], w[1]);
            let ab2: f64 = (0..n).map(|i| (b[i] - a[i]).powi(2)).sum();
            let t = if ab2 > 0.0 {
                ((0..n).map(|i| (q[i] - a[i]) * (b[i] - a[i])).sum::<f64>() / ab2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            nearest = nearest.min(metric.norm_of(n, |i| q[i] - a[i] - t * (b[i] - a[i])));
        }
        from_polyline = from_polyline.max(nearest);
        for (d, p) in to_points.iter_mut().zip(points) {
            *d = d.min(metric.norm_of(n, |i| q[i] - p[i]));
        }
    }
    // Between grid points the curve moves at most K1·h/(2·grid) in each axis.
    let slack = metric.norm_of(n, |i| k1[i]) * 0.5 * h / grid as f64;
    to_points.into_iter().fold(from_polyline + slack, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hermite_data_hold_at_both_ends_and_bounds_are_not_exceeded() {
        let p0 = [0.0, 0.0];
        let p1 = [1.0, 0.2];
        let a = Knot {
            position: p0.to_vec(),
            tangent: vec![0.99, 0.1],
            curvature: vec![-0.1, 0.5],
        };
        let b = Knot {
            position: p1.to_vec(),
            tangent: vec![0.95, 0.3],
            curvature: vec![-0.3, 0.8],
        };
        let h = 1.05;
        let mut c = Vec::new();
        coefficients(&a, &b, h, &mut c);
        for i in 0..2 {
            let axis = &c[6 * i..6 * i + 6];
            let (q, d1, d2) = jet(axis, 0.0);
            assert!((q - p0[i]).abs() < 1e-15 && (d1 - a.tangent[i]).abs() < 1e-14);
            assert!((d2 - a.curvature[i]).abs() < 1e-13);
            let (q, d1, d2) = jet(axis, h);
            assert!((q - p1[i]).abs() < 1e-14 && (d1 - b.tangent[i]).abs() < 1e-13);
            assert!((d2 - b.curvature[i]).abs() < 1e-12, "{d2}");
        }
        let (mut k1, mut k2, mut k3) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        bounds(&c, h, &mut k1, &mut k2, &mut k3);
        for i in 0..2 {
            let axis = &c[6 * i..6 * i + 6];
            for g in 0..=10_000 {
                let s = h * g as f64 / 10_000.0;
                let (_, d1, d2) = jet(axis, s);
                let d3 = 6.0 * axis[3] + s * (24.0 * axis[4] + s * 60.0 * axis[5]);
                assert!(d1.abs() <= k1[i] && d2.abs() <= k2[i] * (1.0 + 1e-12));
                assert!(d3.abs() <= k3[i] * (1.0 + 1e-12));
            }
        }
    }

    #[test]
    fn points_on_a_line_give_its_direction_and_no_curvature() {
        let s = [0.0, 0.5, 1.5];
        let knot = Knot::fit(&[&[0.0, 0.0], &[0.3, 0.4], &[0.9, 1.2]], &s, 1);
        assert!((knot.tangent[0] - 0.6).abs() < 1e-14 && (knot.tangent[1] - 0.8).abs() < 1e-14);
        assert!(knot.curvature.iter().all(|k| k.abs() < 1e-12));
        assert!((knot.position[0] - 0.3).abs() < 1e-15);
        // On a circle of radius 1: tangent and curvature of the circle to second order, and
        // with five points a least-squares fit that stays on the circle at the middle point.
        let angle = |a: f64| [a.cos(), a.sin()];
        let points = [
            angle(-0.02),
            angle(-0.01),
            angle(0.0),
            angle(0.01),
            angle(0.02),
        ];
        let refs: Vec<&[f64]> = points.iter().map(|p| p.as_slice()).collect();
        let s = [-0.02, -0.01, 0.0, 0.01, 0.02];
        let knot = Knot::fit(&refs[1..4], &s[1..4], 1);
        assert!((knot.tangent[1] - 1.0).abs() < 1e-4 && knot.tangent[0].abs() < 1e-12);
        assert!((knot.curvature[0] + 1.0).abs() < 1e-4 && knot.curvature[1].abs() < 1e-12);
        let knot = Knot::fit(&refs, &s, 2);
        assert!((knot.position[0] - 1.0).abs() < 1e-7 && knot.position[1].abs() < 1e-12);
        assert!((knot.curvature[0] + 1.0).abs() < 1e-3);
    }
}
