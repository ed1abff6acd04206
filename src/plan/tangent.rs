//! Tangent blends: joining two segments whose tangents agree (line–arc, arc–arc, helices) without
//! stopping, although their curvatures differ.
//!
//! At such a junction the axis acceleration would jump by `ṡ²·(q''_out − q''_in)`: an infinite
//! jerk at any speed. The blend replaces a stretch of length `L` around the junction by a
//! mixture of the two segments, each extended past the junction (a line straight on, an arc
//! round its circle):
//!
//! ```text
//!   g(σ) = q_in(σ) + w(σ/L)·Δ(σ),    Δ = q_out − q_in,    w(x) = 10x³ − 15x⁴ + 6x⁵
//! ```
//!
//! with `q_in` and `q_out` parameterised so that both pass the junction at `σ = L/2`. The
//! smoothstep `w` has zero first and second derivatives at both ends, so position, direction
//! and curvature are continuous where the blend meets the segments; the blend passes through the
//! programmed junction point itself (Δ vanishes there). Before the junction it is `|w·Δ|` off
//! the incoming segment, after it `|(1−w)·Δ|` off the outgoing one.
//!
//! Bounds: with `d = σ − L/2`, Taylor's theorem bounds `|Δ^(m)(d)|` by the junction values
//! `E_m = |Δ^(m)(0)|` (m = 1, 2, 3) and a bound `M4` on the fourth derivatives of both
//! segments; products with `w` and its derivatives are bounded monomial by monomial with the
//! constants `sup |w^(m)(x)|·|x − ½|^k` below. The planner turns the resulting bounds on
//! `g'`, `g''`, `g'''` into the blend's speed ceiling and path limits, exactly as for an arc.

use super::geometry::{AxisJet, Metric, PathPoint, Shapes};
use super::profile::largest_at_most;

/// sup over x ∈ [0, ½] of w(x)·|x − ½|^k, k = 0…4 (rounded up).
const W0: [f64; 5] = [0.5, 0.035277, 0.0066644, 0.0016449, 0.00046917];
/// sup over x ∈ [0, 1] of |w'(x)|·|x − ½|^k.
const W1: [f64; 5] = [1.875, 0.26833, 0.069445, 0.021472, 0.0073243];
/// sup over x ∈ [0, 1] of |w''(x)|·|x − ½|^k.
const W2: [f64; 5] = [5.7736, 1.875, 0.69714, 0.27778, 0.11551];
/// sup over x ∈ [0, 1] of |w'''(x)|·|x − ½|^k.
const W3: [f64; 5] = [60.0, 30.0, 15.0, 7.5, 3.75];

/// The smoothstep w and its first three derivatives at x.
fn smoothstep(x: f64) -> [f64; 4] {
    let y = 1.0 - x;
    [
        x * x * x * (10.0 - 15.0 * x + 6.0 * x * x),
        30.0 * x * x * y * y,
        60.0 * x * y * (y - x),
        60.0 * (1.0 - 6.0 * x + 6.0 * x * x),
    ]
}

/// A tangent blend between segment `incoming` and segment `outgoing` (which starts where
/// `incoming` ends).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct TangentBlend {
    pub incoming: usize,
    pub outgoing: usize,
    /// Blend length L in the path coordinate, half on each side of the junction.
    pub length: f64,
}

/// Scratch space for evaluating jets of two segments: 3 rows (q, q', q'') for each side.
#[derive(Debug, Clone, Default)]
pub(super) struct JetScratch {
    rows: Vec<f64>,
}

impl JetScratch {
    pub fn new(axes: usize) -> Self {
        JetScratch {
            rows: vec![0.0; 8 * axes],
        }
    }
}

/// Jet of `shapes` segment `k` at `s` into `rows` (`orders` rows of `n`).
fn jet_into(shapes: &Shapes, k: usize, s: f64, rows: &mut [f64], orders: usize) {
    let n = shapes.n;
    let mut refs: [&mut [f64]; 4] = Default::default();
    let mut rest = rows;
    for slot in refs.iter_mut().take(orders) {
        let (head, tail) = rest.split_at_mut(n);
        *slot = head;
        rest = tail;
    }
    shapes.jet(k, s, &mut refs[..orders]);
}

impl TangentBlend {
    /// Axis positions, velocities and accelerations at `sigma ∈ [0, L]` moving with `σ̇`, `σ̈`.
    pub fn eval(&self, shapes: &Shapes, scratch: &mut JetScratch, at: PathPoint, out: AxisJet) {
        let (sigma, sigma_dot, sigma_ddot) = at.parts();
        let (position, velocity, acceleration) = out.parts();
        let n = shapes.n;
        let l = self.length;
        let sigma = sigma.clamp(0.0, l);
        let d = sigma - 0.5 * l;
        let (inc, out) = scratch.rows.split_at_mut(3 * n);
        jet_into(
            shapes,
            self.incoming,
            shapes.shapes[self.incoming].length + d,
            inc,
            3,
        );
        jet_into(shapes, self.outgoing, d, out, 3);
        let [w, w1, w2, _] = smoothstep(sigma / l);
        let (w1, w2) = (w1 / l, w2 / (l * l));
        for k in 0..n {
            let (q, q1, q2) = (inc[k], inc[n + k], inc[2 * n + k]);
            let (e0, e1, e2) = (out[k] - q, out[n + k] - q1, out[2 * n + k] - q2);
            let g1 = q1 + w * e1 + w1 * e0;
            let g2 = q2 + w * e2 + 2.0 * w1 * e1 + w2 * e0;
            position[k] = q + w * e0;
            velocity[k] = g1 * sigma_dot;
            acceleration[k] = g2 * sigma_dot * sigma_dot + g1 * sigma_ddot;
        }
    }
}

/// What a tangent junction demands of a blend: the derivative differences at the junction and
/// the bounds of both segments, per axis.
#[derive(Debug, Clone, Default)]
pub(super) struct TangentJunction {
    /// |Δ^(m)(0)| per axis for m = 1, 2, 3, and the bound M4 on |Δ''''|.
    e: [Vec<f64>; 4],
    /// The same in the tolerance metric: ‖Δ^(m)(0)‖ (m = 1, 2, 3) and ‖M4‖.
    e_norm: [f64; 4],
    /// Unit tangents' angle (rad).
    pub angle: f64,
    /// Largest second-derivative bound of either segment (1/m: the curvature scale).
    pub curvature: f64,
}

impl TangentJunction {
    /// The junction between segment `p` and segment `k` (which starts where `p` ends).
    pub fn measure(
        &mut self,
        shapes: &Shapes,
        p: usize,
        k: usize,
        metric: &Metric,
        scratch: &mut JetScratch,
    ) {
        let n = shapes.n;
        for v in self.e.iter_mut() {
            v.clear();
            v.resize(n, 0.0);
        }
        let (inc, out) = scratch.rows.split_at_mut(4 * n);
        jet_into(shapes, p, shapes.shapes[p].length, inc, 4);
        jet_into(shapes, k, 0.0, out, 4);
        self.curvature = 0.0;
        for i in 0..n {
            for m in 1..4 {
                self.e[m - 1][i] = (out[m * n + i] - inc[m * n + i]).abs();
            }
            self.e[3][i] = shapes.bound(p, i, 4) + shapes.bound(k, i, 4);
            self.curvature = self
                .curvature
                .max(shapes.bound(p, i, 2))
                .max(shapes.bound(k, i, 2));
        }
        for m in 0..4 {
            self.e_norm[m] = metric.norm(&self.e[m]);
        }
        let t_in = &inc[n..2 * n];
        let t_out = &out[n..2 * n];
        let (a, b) = (norm(t_in), norm(t_out));
        let cos = t_in.iter().zip(t_out).map(|(x, y)| x * y).sum::<f64>() / (a * b);
        self.angle = if a > 0.0 && b > 0.0 {
            cos.clamp(-1.0, 1.0).acos()
        } else {
            std::f64::consts::PI
        };
    }

    /// True when the two segments continue each other exactly (up to rounding): no blend needed.
    pub fn is_smooth(&self) -> bool {
        let scale = self.curvature.max(1e-300);
        self.e[0].iter().all(|&x| x <= 1e-12)
            && self.e[1].iter().all(|&x| x <= 1e-12 * scale)
            && self.e[2].iter().all(|&x| x <= 1e-12 * scale * scale)
    }

    /// Largest distance from the programmed path of a blend of length `l`, in the tolerance
    /// metric.
    pub fn deviation(&self, l: f64) -> f64 {
        let e = &self.e_norm;
        l * (W0[1] * e[0]
            + l * (W0[2] * e[1] / 2.0 + l * (W0[3] * e[2] / 6.0 + l * W0[4] * e[3] / 24.0)))
    }

    /// Longest blend within `tolerance` and at most `longest`.
    pub fn length_within(&self, tolerance: f64, longest: f64) -> f64 {
        if self.deviation(longest) <= tolerance {
            longest
        } else {
            largest_at_most(|l| self.deviation(l), tolerance, 0.0, longest)
        }
    }

    /// Per-axis bounds on |g'|, |g''|, |g'''| of a blend of length `l` between segments `p` and
    /// `k`.
    pub fn bounds(
        &self,
        shapes: &Shapes,
        (p, k): (usize, usize),
        l: f64,
        k1: &mut [f64],
        k2: &mut [f64],
        k3: &mut [f64],
    ) {
        let end = shapes.shapes[p].length;
        let h = 0.5 * l;
        // Each segment over the part the blend mixes in (extended past the junction).
        let base = |i: usize, m: i32| {
            shapes
                .bound_over(p, i, m, end - h, end + h)
                .max(shapes.bound_over(k, i, m, -h, h))
        };
        let lp = [1.0, l, l * l, l * l * l, l * l * l * l];
        // Σ_k c[k]·L^k·coefficient_k for the Taylor coefficients of |Δ^(m)| in |d|.
        let poly = |w: &[f64; 5], coef: &[f64]| -> f64 {
            coef.iter().enumerate().map(|(k, c)| w[k] * lp[k] * c).sum()
        };
        for i in 0..k1.len() {
            let (e1, e2, e3, m4) = (self.e[0][i], self.e[1][i], self.e[2][i], self.e[3][i]);
            let b0 = [0.0, e1, e2 / 2.0, e3 / 6.0, m4 / 24.0];
            let b1 = [e1, e2, e3 / 2.0, m4 / 6.0];
            let b2 = [e2, e3, m4 / 2.0];
            k1[i] = base(i, 1) + poly(&W1, &b0) / l;
            k2[i] = base(i, 2) + 2.0 * poly(&W1, &b1) / l + poly(&W2, &b0) / (l * l);
            k3[i] = base(i, 3)
                + 3.0 * poly(&W1, &b2) / l
                + 3.0 * poly(&W2, &b1) / (l * l)
                + poly(&W3, &b0) / (l * l * l);
        }
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bound_constants_hold_on_a_fine_grid() {
        let n = 400_000;
        let mut found = [[0.0f64; 5]; 4];
        for s in 0..=n {
            let x = s as f64 / n as f64;
            let w = smoothstep(x);
            let d = (x - 0.5).abs();
            for k in 0..5 {
                let dk = d.powi(k as i32);
                if x <= 0.5 {
                    found[0][k] = found[0][k].max(w[0] * dk);
                }
                for (f, w) in found.iter_mut().zip(&w).skip(1) {
                    f[k] = f[k].max(w.abs() * dk);
                }
            }
        }
        for (m, table) in [W0, W1, W2, W3].iter().enumerate() {
            for k in 0..5 {
                assert!(
                    table[k] >= found[m][k] && table[k] <= found[m][k] * (1.0 + 1e-4) + 1e-12,
                    "W{m}[{k}] = {} vs {}",
                    table[k],
                    found[m][k]
                );
            }
        }
        // w rises from 0 to 1 with flat ends.
        assert_eq!(smoothstep(0.0), [0.0, 0.0, 0.0, 60.0]);
        let one = smoothstep(1.0);
        assert!((one[0] - 1.0).abs() < 1e-15 && one[1] == 0.0 && one[2] == 0.0);
    }
}
