//! Segment geometry parameterised by a path coordinate `s`: positions, derivatives with respect
//! to `s` (also beyond the segment's ends, where a tangent blend needs them), and per-axis
//! bounds on those derivatives.
//!
//! For a curve `q(s)` the axis derivatives follow from the path derivatives (ṡ, s̈, s⃛):
//!
//! ```text
//!   q̇ = q'·ṡ
//!   q̈ = q''·ṡ² + q'·s̈
//!   q⃛ = q'''·ṡ³ + 3·q''·ṡ·s̈ + q'·s⃛
//! ```
//!
//! On a line `q'` is constant and `q'' = q''' = 0`. An arc (radius `r(θ) = r0 + dr·θ`, the
//! `dr` only absorbing rounding between the programmed radii) has `|d^m z/dθ^m| = hypot(m·dr, r)`
//! in its plane, divided by `(ds/dθ)^m` per derivative along `s`.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use super::path::{AxisKind, AxisSpec, Geometry, PathError, PathSegment, ARC_RADIUS_MISMATCH};

/// A point moving along a piece of path: its coordinate σ (m) and σ̇, σ̈.
#[derive(Debug, Clone, Copy)]
pub struct PathPoint {
    pub sigma: f64,
    pub sigma_dot: f64,
    pub sigma_ddot: f64,
}

impl PathPoint {
    /// (σ, σ̇, σ̈).
    pub fn parts(self) -> (f64, f64, f64) {
        (self.sigma, self.sigma_dot, self.sigma_ddot)
    }

    pub fn new(sigma: f64, sigma_dot: f64, sigma_ddot: f64) -> Self {
        PathPoint {
            sigma,
            sigma_dot,
            sigma_ddot,
        }
    }
}

/// Where a piece's `eval` writes the axis positions, velocities and accelerations.
pub struct AxisJet<'a> {
    pub position: &'a mut [f64],
    pub velocity: &'a mut [f64],
    pub acceleration: &'a mut [f64],
}

impl<'a> AxisJet<'a> {
    /// (positions, velocities, accelerations).
    pub fn parts(self) -> (&'a mut [f64], &'a mut [f64], &'a mut [f64]) {
        (self.position, self.velocity, self.acceleration)
    }

    pub fn new(
        position: &'a mut [f64],
        velocity: &'a mut [f64],
        acceleration: &'a mut [f64],
    ) -> Self {
        AxisJet {
            position,
            velocity,
            acceleration,
        }
    }
}

/// The geometry of every segment of a path, in flat storage (no allocation per segment).
#[derive(Debug, Clone, Default)]
pub(super) struct Shapes {
    /// Axes per point.
    pub n: usize,
    /// Vertex `k` is where segment `k` starts; vertex `k + 1` where it ends.
    points: Vec<f64>,
    /// Per segment, dq/ds of the axes that move linearly in `s`: all axes of a line, the
    /// non-plane axes of a helix (zero on its plane axes).
    rates: Vec<f64>,
    pub shapes: Vec<Shape>,
}

/// One segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Shape {
    /// Length in the path coordinate `s` (the feed metric, or plain SI length when the feed
    /// metric gives zero).
    pub length: f64,
    /// Whether `ṡ` is the programmed path speed (the feed metric measured the segment).
    pub feed_applies: bool,
    /// `None` for a line.
    pub arc: Option<ArcShape>,
}

/// A circular (or helical) arc: in the plane axes `q = centre + r(θ)·(cos φ, sin φ)` with
/// `φ = φ0 + turn·θ`, `r = r0 + dr·θ`, `θ = s/scale`; the other axes move linearly in `s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ArcShape {
    pub plane: [usize; 2],
    pub center: [f64; 2],
    pub start_radius: f64,
    /// dr/dθ.
    pub radius_rate: f64,
    pub start_angle: f64,
    /// +1 counter-clockwise, −1 clockwise.
    pub turn: f64,
    /// Unsigned angle swept (rad).
    pub sweep: f64,
    /// ds/dθ.
    pub scale: f64,
}

impl ArcShape {
    /// Bound on `|d^m q/ds^m|` (m ≥ 1) of plane axis `c` (0 or 1) over `s ∈ [lo, hi]` (which
    /// may extend past the arc's ends). The m-th derivative is `C_m·e^{iφ}/scale^m` with
    /// `|C_m| = hypot(m·dr, r)` and `arg C_m = m·turn·π/2` up to `atan(m·|dr|/r)`; its
    /// component on the axis is `|C_m|·cos(φ + arg C_m − c·π/2)`, bounded by the largest
    /// |cos| over the angles the stretch turns through.
    pub fn plane_bound_over(&self, c: usize, m: i32, lo: f64, hi: f64) -> f64 {
        let (t0, t1) = (lo / self.scale, hi / self.scale);
        let r0 = self.start_radius + self.radius_rate * t0;
        let r1 = self.start_radius + self.radius_rate * t1;
        let (r_min, r_max) = (r0.min(r1).max(0.0), r0.max(r1));
        let m_dr = f64::from(m) * self.radius_rate.abs();
        let magnitude = m_dr.hypot(r_max) / self.scale.powi(m);
        let slack = if r_min > 0.0 {
            (m_dr / r_min).atan()
        } else {
            std::f64::consts::PI
        };
        let shift = f64::from(m) * self.turn * FRAC_PI_2 - c as f64 * FRAC_PI_2;
        let a = self.start_angle + self.turn * t0 + shift;
        let b = self.start_angle + self.turn * t1 + shift;
        magnitude * max_abs_cos(a.min(b) - slack, a.max(b) + slack)
    }
}

/// Largest |cos x| for x in [lo, hi].
fn max_abs_cos(lo: f64, hi: f64) -> f64 {
    if (hi - lo).is_nan() || hi - lo >= PI {
        return 1.0;
    }
    // A multiple of π inside the interval reaches 1; otherwise |cos| is largest at an end.
    if (lo / PI).ceil() <= hi / PI {
        1.0
    } else {
        lo.cos().abs().max(hi.cos().abs())
    }
}

impl Shapes {
    /// Builds the shapes of every segment of `segments`, starting at `start`.
    pub fn new(
        start: &[f64],
        segments: &[PathSegment],
        axes: &[AxisSpec],
    ) -> Result<Shapes, PathError> {
        let n = axes.len();
        let mut shapes = Shapes {
            n,
            points: Vec::with_capacity((segments.len() + 1) * n),
            rates: Vec::with_capacity(segments.len() * n),
            shapes: Vec::with_capacity(segments.len()),
        };
        shapes.points.extend_from_slice(start);
        for (index, segment) in segments.iter().enumerate() {
            shapes.push(index, segment, axes)?;
        }
        Ok(shapes)
    }

    fn push(
        &mut self,
        index: usize,
        segment: &PathSegment,
        axes: &[AxisSpec],
    ) -> Result<(), PathError> {
        let n = self.n;
        let from = self.points.len() - n;
        self.points.extend_from_slice(segment.geometry.end());
        let (start, end) = self.points[from..].split_at(n);
        let weights = &segment.feed_metric;
        let shape = match &segment.geometry {
            Geometry::Line { .. } => {
                let weighted = norm((0..n).map(|i| (end[i] - start[i]) * weights[i]));
                let (length, feed_applies) = if weighted > 0.0 {
                    (weighted, true)
                } else {
                    (norm((0..n).map(|i| end[i] - start[i])), false)
                };
                let scale = if length > 0.0 { 1.0 / length } else { 0.0 };
                for i in 0..n {
                    let rate = (end[i] - start[i]) * scale;
                    self.rates.push(rate);
                }
                Shape {
                    length,
                    feed_applies,
                    arc: None,
                }
            }
            Geometry::Arc {
                plane,
                center,
                clockwise,
                turns,
                ..
            } => {
                let [i, j] = *plane;
                if i >= n
                    || j >= n
                    || i == j
                    || axes[i].kind != AxisKind::Linear
                    || axes[j].kind != AxisKind::Linear
                {
                    return Err(PathError::InvalidArcPlane { segment: index });
                }
                let polar = |q: &[f64]| {
                    let (x, y) = (q[i] - center[0], q[j] - center[1]);
                    (x.hypot(y), y.atan2(x))
                };
                let (r0, phi0) = polar(start);
                let (r1, phi1) = polar(end);
                if !(r0 > 0.0 && r1 > 0.0 && r0.is_finite() && r1.is_finite())
                    || (r1 - r0).abs() > ARC_RADIUS_MISMATCH * r0.max(r1)
                {
                    return Err(PathError::InvalidArcRadius {
                        segment: index,
                        start_radius: r0,
                        end_radius: r1,
                    });
                }
                let turn = if *clockwise { -1.0 } else { 1.0 };
                // Angle swept in the direction of travel, in (0, 2π]: start = end is a full circle.
                let mut sweep = (turn * (phi1 - phi0)).rem_euclid(TAU);
                if sweep <= 1e-12 {
                    sweep = TAU;
                }
                sweep += TAU * f64::from(*turns);
                let radius_rate = (r1 - r0) / sweep;
                // Plane speed per radian is sqrt(dr² + r²) ≤ plane_rate.
                let plane_rate = radius_rate.hypot(r0.max(r1));
                let helix = |k: usize| {
                    if k == i || k == j {
                        0.0
                    } else {
                        (end[k] - start[k]) / sweep
                    }
                };
                let w_plane = weights[i].abs().max(weights[j].abs());
                let weighted =
                    (w_plane * plane_rate).hypot(norm((0..n).map(|k| helix(k) * weights[k])));
                let (scale, feed_applies) = if weighted > 0.0 {
                    (weighted, true)
                } else {
                    (plane_rate.hypot(norm((0..n).map(helix))), false)
                };
                for k in 0..n {
                    self.rates.push(helix(k) / scale);
                }
                Shape {
                    length: scale * sweep,
                    feed_applies,
                    arc: Some(ArcShape {
                        plane: *plane,
                        center: *center,
                        start_radius: r0,
                        radius_rate,
                        start_angle: phi0,
                        turn,
                        sweep,
                        scale,
                    }),
                }
            }
        };
        if !shape.length.is_finite() {
            return Err(PathError::InvalidValue {
                segment: Some(index),
                what: "segment length (not finite)",
            });
        }
        self.shapes.push(shape);
        Ok(())
    }

    pub fn len(&self) -> usize {
        self.shapes.len()
    }

    pub fn start(&self, k: usize) -> &[f64] {
        &self.points[k * self.n..(k + 1) * self.n]
    }

    pub fn end(&self, k: usize) -> &[f64] {
        &self.points[(k + 1) * self.n..(k + 2) * self.n]
    }

    /// dq/ds of the axes moving linearly in `s` (the whole direction of a line).
    pub fn rates(&self, k: usize) -> &[f64] {
        &self.rates[k * self.n..(k + 1) * self.n]
    }

    /// dq/ds of a line (None for an arc).
    pub fn line_direction(&self, k: usize) -> Option<&[f64]> {
        match self.shapes[k].arc {
            None => Some(self.rates(k)),
            Some(_) => None,
        }
    }

    /// Axis positions, velocities and accelerations at path coordinate `s ∈ [0, length]` moving
    /// with `ṡ`, `s̈`. At `s ≥ length` the position is the programmed end point itself.
    pub fn eval(&self, k: usize, at: PathPoint, out: AxisJet) {
        let (s, s_dot, s_ddot) = at.parts();
        let (position, velocity, acceleration) = out.parts();
        let shape = &self.shapes[k];
        let (start, end, rates) = (self.start(k), self.end(k), self.rates(k));
        let at_end = s >= shape.length;
        match &shape.arc {
            None => {
                let fraction = if shape.length > 0.0 {
                    s / shape.length
                } else {
                    1.0
                };
                for i in 0..self.n {
                    position[i] = if at_end {
                        end[i]
                    } else {
                        start[i] + (end[i] - start[i]) * fraction
                    };
                    velocity[i] = rates[i] * s_dot;
                    acceleration[i] = rates[i] * s_ddot;
                }
            }
            Some(arc) => {
                let s = s.clamp(0.0, shape.length);
                for i in 0..self.n {
                    position[i] = if at_end {
                        end[i]
                    } else {
                        start[i] + rates[i] * s
                    };
                    velocity[i] = rates[i] * s_dot;
                    acceleration[i] = rates[i] * s_ddot;
                }
                let mut d = [[0.0; 2]; 3];
                arc_plane_jet(arc, s, &mut d);
                let [i, j] = arc.plane;
                if !at_end {
                    position[i] = d[0][0];
                    position[j] = d[0][1];
                }
                for (axis, c) in [(i, 0), (j, 1)] {
                    velocity[axis] = d[1][c] * s_dot;
                    acceleration[axis] = d[2][c] * s_dot * s_dot + d[1][c] * s_ddot;
                }
            }
        }
    }

    /// Position and derivatives along `s` up to order `out.len() − 1` at any `s`, also outside
    /// `[0, length]` (the segment extended: a line straight on, an arc round its circle).
    /// `out[m]` receives `d^m q/ds^m` (one entry per axis).
    pub fn jet(&self, k: usize, s: f64, out: &mut [&mut [f64]]) {
        let shape = &self.shapes[k];
        let (start, rates) = (self.start(k), self.rates(k));
        for (m, row) in out.iter_mut().enumerate() {
            for i in 0..self.n {
                row[i] = match m {
                    0 => start[i] + rates[i] * s,
                    1 => rates[i],
                    _ => 0.0,
                };
            }
        }
        if let Some(arc) = &shape.arc {
            let mut d = [[0.0; 2]; 5];
            let orders = out.len().min(5);
            arc_plane_jet(arc, s, &mut d[..orders]);
            let [i, j] = arc.plane;
            for (m, row) in out.iter_mut().enumerate().take(orders) {
                row[i] = d[m][0];
                row[j] = d[m][1];
            }
        }
    }

    /// Per-axis bound on `|d^m q/ds^m|` over segment `k` and its extensions by half its length
    /// (m ≥ 1).
    pub fn bound(&self, k: usize, axis: usize, m: i32) -> f64 {
        let length = self.shapes[k].length;
        self.bound_over(k, axis, m, -0.5 * length, 1.5 * length)
    }

    /// Per-axis bound on `|d^m q/ds^m|` over `s ∈ [lo, hi]` of segment `k` (extended past its
    /// ends where the range reaches beyond them; m ≥ 1).
    pub fn bound_over(&self, k: usize, axis: usize, m: i32, lo: f64, hi: f64) -> f64 {
        match &self.shapes[k].arc {
            Some(arc) if arc.plane[0] == axis => arc.plane_bound_over(0, m, lo, hi),
            Some(arc) if arc.plane[1] == axis => arc.plane_bound_over(1, m, lo, hi),
            _ if m == 1 => self.rates(k)[axis].abs(),
            _ => 0.0,
        }
    }
}

/// Plane coordinates of an arc and their derivatives along `s` (`d[m]` = m-th derivative) at
/// path coordinate `s` (unclamped). With `C_m = r·(i·t)^m + m·dr·(i·t)^(m−1)`,
/// `d^m z/dθ^m = C_m·e^{iφ}`.
fn arc_plane_jet(arc: &ArcShape, s: f64, d: &mut [[f64; 2]]) {
    let theta = s / arc.scale;
    let phi = arc.start_angle + arc.turn * theta;
    let r = arc.start_radius + arc.radius_rate * theta;
    let (sin, cos) = phi.sin_cos();
    let (t, dr) = (arc.turn, arc.radius_rate);
    let mut per_theta = 1.0;
    for (m, out) in d.iter_mut().enumerate() {
        let (re, im) = match m {
            0 => (r, 0.0),
            1 => (dr, t * r),
            2 => (-r, 2.0 * t * dr),
            3 => (-3.0 * dr, -t * r),
            _ => (r, -4.0 * t * dr),
        };
        let (x, y) = (re * cos - im * sin, re * sin + im * cos);
        if m == 0 {
            *out = [arc.center[0] + x, arc.center[1] + y];
        } else {
            per_theta /= arc.scale;
            *out = [x * per_theta, y * per_theta];
        }
    }
}

/// How far apart two axis positions are for the corner tolerance: the Euclidean norm over the
/// linear axes plus, for each rotary axis with a lever arm `r` (the tool tip's distance from
/// it), `r·|δ|`, which bounds how far that axis moves the tool tip. Without lever arms every
/// axis counts in the Euclidean norm in SI units (1 rad as 1 m).
#[derive(Debug, Clone, Default)]
pub(super) struct Metric {
    /// Per axis: `None` in the Euclidean part, `Some(r)` weighted by its lever arm.
    lever: Vec<Option<f64>>,
}

impl Metric {
    pub fn new(axes: &[AxisSpec], lever_arms: &[f64]) -> Metric {
        let lever = axes
            .iter()
            .enumerate()
            .map(|(i, axis)| match (axis.kind, lever_arms.get(i)) {
                (AxisKind::Rotary, Some(&r)) => Some(r),
                _ => None,
            })
            .collect();
        Metric { lever }
    }

    pub fn norm(&self, v: &[f64]) -> f64 {
        self.norm_of(v.len(), |i| v[i])
    }

    /// The norm of the vector whose entry `i` is `value(i)`, `n` entries.
    pub fn norm_of(&self, n: usize, value: impl Fn(usize) -> f64) -> f64 {
        let (mut squares, mut weighted) = (0.0, 0.0);
        for i in 0..n {
            let x = value(i);
            match self.lever.get(i).copied().flatten() {
                Some(r) => weighted += r * x.abs(),
                None => squares += x * x,
            }
        }
        squares.sqrt() + weighted
    }
}

pub(super) fn norm(values: impl Iterator<Item = f64>) -> f64 {
    values.map(|x| x * x).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::path::{AxisLimits, Blend};

    fn axes(n: usize) -> Vec<AxisSpec> {
        (0..n)
            .map(|i| AxisSpec {
                name: format!("q{i}"),
                kind: AxisKind::Linear,
                limits: AxisLimits {
                    velocity: 1.0,
                    acceleration: 1.0,
                    jerk: 1.0,
                },
            })
            .collect()
    }

    fn helix() -> Shapes {
        let segment = PathSegment {
            geometry: Geometry::Arc {
                plane: [0, 1],
                center: [0.01, 0.0],
                clockwise: true,
                turns: 0,
                end: vec![0.01, -0.020015, 0.003],
            },
            feed: None,
            feed_metric: vec![1.0; 3],
            blend: Blend::ExactStop,
            source_index: 0,
        };
        Shapes::new(&[0.01, 0.02, 0.0], &[segment], &axes(3)).unwrap()
    }

    #[test]
    fn jet_derivatives_match_finite_differences_and_bounds() {
        let shapes = helix();
        let n = 3;
        let length = shapes.shapes[0].length;
        let mut rows = vec![vec![0.0; n]; 5];
        let jet = |s: f64, rows: &mut Vec<Vec<f64>>| {
            let mut refs: Vec<&mut [f64]> = rows.iter_mut().map(|r| r.as_mut_slice()).collect();
            shapes.jet(0, s, &mut refs);
        };
        let h = 1e-5 * length;
        for s in [-0.3 * length, 0.0, 0.4 * length, length, 1.4 * length] {
            jet(s, &mut rows);
            let here = rows.clone();
            jet(s + h, &mut rows);
            let ahead = rows.clone();
            jet(s - h, &mut rows);
            let behind = rows.clone();
            for m in 0..4 {
                for i in 0..n {
                    let fd = (ahead[m][i] - behind[m][i]) / (2.0 * h);
                    let scale = here[m + 1][i].abs().max(shapes.bound(0, i, m as i32 + 1));
                    assert!(
                        (fd - here[m + 1][i]).abs() <= 1e-5 * scale + 1e-9,
                        "s {s} order {m} axis {i}: {fd} vs {}",
                        here[m + 1][i]
                    );
                    if m < 4 {
                        assert!(
                            here[m + 1][i].abs()
                                <= shapes.bound(0, i, m as i32 + 1) * (1.0 + 1e-12)
                        );
                    }
                }
            }
        }
        // Within the segment the jet agrees with eval, and eval ends on the programmed point.
        let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        shapes.eval(
            0,
            PathPoint::new(0.3 * length, 2.0, 3.0),
            AxisJet::new(&mut p, &mut v, &mut a),
        );
        jet(0.3 * length, &mut rows);
        for i in 0..n {
            assert!((p[i] - rows[0][i]).abs() < 1e-15);
            assert!((v[i] - 2.0 * rows[1][i]).abs() < 1e-12);
            assert!((a[i] - (4.0 * rows[2][i] + 3.0 * rows[1][i])).abs() < 1e-9);
        }
        shapes.eval(
            0,
            PathPoint::new(length, 0.0, 0.0),
            AxisJet::new(&mut p, &mut v, &mut a),
        );
        assert_eq!(p, [0.01, -0.020015, 0.003]);
    }
}
