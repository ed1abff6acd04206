//! Segment geometry parameterised by a path coordinate `s`, and the limits on `s` that keep
//! every axis within its own limits.
//!
//! For a curve `q(s)` the axis derivatives follow from the path derivatives (ṡ, s̈, s⃛):
//!
//! ```text
//!   q̇ = q'·ṡ
//!   q̈ = q''·ṡ² + q'·s̈
//!   q⃛ = q'''·ṡ³ + 3·q''·ṡ·s̈ + q'·s⃛
//! ```
//!
//! On a line `q'` is constant and `q'' = q''' = 0`, so the path limits are exactly
//! `limit_i / |q'_i|` (minimised over axes): planning along `s` is time-optimal and keeps the tool
//! on the line. On an arc the curvature terms use part of each axis's budget; see
//! [`SegmentShape::path_limits`].

use std::f64::consts::TAU;

use super::path::{AxisKind, AxisSpec, Geometry, PathError, PathSegment, ARC_RADIUS_MISMATCH};
use super::profile::{Limits, Profile};

/// Shares of an arc's axis acceleration and jerk budgets that may go to the centripetal terms
/// (the rest is for speeding up and slowing down along the arc); see
/// [`SegmentShape::path_limits`].
const ARC_CENTRIPETAL_SHARES: [f64; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];

/// A segment's geometry with its path parameterisation.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SegmentShape {
    pub start: Vec<f64>,
    pub end: Vec<f64>,
    /// Length in the path coordinate `s` (the feed metric, or plain SI length when the feed
    /// metric gives zero).
    pub length: f64,
    /// Whether `ṡ` is the programmed path speed (the feed metric measured the segment).
    pub feed_applies: bool,
    pub curve: Curve,
}

#[derive(Debug, Clone, PartialEq)]
pub(super) enum Curve {
    /// q(s) = start + (end − start)·s/length.
    Line {
        /// dq/ds.
        direction: Vec<f64>,
    },
    /// Plane axes: q = centre + r(θ)·(cos φ, sin φ), φ = φ0 + turn·θ, r = r0 + dr·θ, θ = s/scale;
    /// the other axes move linearly with θ.
    Arc {
        plane: [usize; 2],
        center: [f64; 2],
        start_radius: f64,
        /// dr/dθ (non-zero only to absorb rounding between the programmed radii).
        radius_rate: f64,
        start_angle: f64,
        /// +1 counter-clockwise, −1 clockwise.
        turn: f64,
        /// Unsigned angle swept (rad).
        sweep: f64,
        /// ds/dθ.
        scale: f64,
        /// dq/dθ of the non-plane axes (zero on the plane axes).
        helix: Vec<f64>,
    },
}

impl SegmentShape {
    /// Builds segment `index` starting at `start`.
    pub fn new(
        index: usize,
        start: &[f64],
        segment: &PathSegment,
        axes: &[AxisSpec],
    ) -> Result<Self, PathError> {
        let n = axes.len();
        let end = segment.geometry.end().to_vec();
        let weights = &segment.feed_metric;
        let delta: Vec<f64> = start.iter().zip(&end).map(|(s, e)| e - s).collect();
        let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
        match &segment.geometry {
            Geometry::Line { .. } => {
                let weighted = norm(&mut delta.iter().zip(weights).map(|(d, w)| d * w));
                let (length, feed_applies) = if weighted > 0.0 {
                    (weighted, true)
                } else {
                    (norm(&mut delta.iter().copied()), false)
                };
                let direction = if length > 0.0 {
                    delta.iter().map(|d| d / length).collect()
                } else {
                    vec![0.0; n]
                };
                Ok(SegmentShape {
                    start: start.to_vec(),
                    end,
                    length,
                    feed_applies,
                    curve: Curve::Line { direction },
                })
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
                let (r1, phi1) = polar(&end);
                if !(r0 > 0.0 && r1 > 0.0) || (r1 - r0).abs() > ARC_RADIUS_MISMATCH * r0.max(r1) {
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
                let helix: Vec<f64> = (0..n)
                    .map(|k| {
                        if k == i || k == j {
                            0.0
                        } else {
                            delta[k] / sweep
                        }
                    })
                    .collect();
                // Plane speed per radian is sqrt(dr² + r²) ≤ plane_rate.
                let plane_rate = radius_rate.hypot(r0.max(r1));
                let w_plane = weights[i].abs().max(weights[j].abs());
                let weighted = (w_plane * plane_rate)
                    .hypot(norm(&mut helix.iter().zip(weights).map(|(h, w)| h * w)));
                let (scale, feed_applies) = if weighted > 0.0 {
                    (weighted, true)
                } else {
                    (plane_rate.hypot(norm(&mut helix.iter().copied())), false)
                };
                Ok(SegmentShape {
                    start: start.to_vec(),
                    end,
                    length: scale * sweep,
                    feed_applies,
                    curve: Curve::Arc {
                        plane: *plane,
                        center: *center,
                        start_radius: r0,
                        radius_rate,
                        start_angle: phi0,
                        turn,
                        sweep,
                        scale,
                        helix,
                    },
                })
            }
        }
    }

    /// dq/ds of a line (None for an arc).
    pub fn line_direction(&self) -> Option<&[f64]> {
        match &self.curve {
            Curve::Line { direction } => Some(direction),
            Curve::Arc { .. } => None,
        }
    }

    /// Axis positions, velocities and accelerations at path coordinate `s` moving with `ṡ`,
    /// `s̈`. At `s ≥ length` the position is the programmed end point itself.
    pub fn eval(
        &self,
        s: f64,
        s_dot: f64,
        s_ddot: f64,
        position: &mut [f64],
        velocity: &mut [f64],
        acceleration: &mut [f64],
    ) {
        let at_end = s >= self.length;
        match &self.curve {
            Curve::Line { direction } => {
                let fraction = if self.length > 0.0 {
                    s / self.length
                } else {
                    1.0
                };
                for k in 0..self.start.len() {
                    position[k] = if at_end {
                        self.end[k]
                    } else {
                        self.start[k] + (self.end[k] - self.start[k]) * fraction
                    };
                    velocity[k] = direction[k] * s_dot;
                    acceleration[k] = direction[k] * s_ddot;
                }
            }
            Curve::Arc {
                plane: [i, j],
                center,
                start_radius,
                radius_rate,
                start_angle,
                turn,
                sweep,
                scale,
                helix,
            } => {
                let theta = (s / scale).clamp(0.0, *sweep);
                let (theta_dot, theta_ddot) = (s_dot / scale, s_ddot / scale);
                for k in 0..self.start.len() {
                    position[k] = if at_end {
                        self.end[k]
                    } else {
                        self.start[k] + helix[k] * theta
                    };
                    velocity[k] = helix[k] * theta_dot;
                    acceleration[k] = helix[k] * theta_ddot;
                }
                let phi = start_angle + turn * theta;
                let r = start_radius + radius_rate * theta;
                let (sin, cos) = phi.sin_cos();
                // First and second derivatives of the plane coordinates with respect to θ.
                let d1 = [
                    radius_rate * cos - turn * r * sin,
                    radius_rate * sin + turn * r * cos,
                ];
                let d2 = [
                    -2.0 * turn * radius_rate * sin - r * cos,
                    2.0 * turn * radius_rate * cos - r * sin,
                ];
                if !at_end {
                    position[*i] = center[0] + r * cos;
                    position[*j] = center[1] + r * sin;
                }
                for (axis, c) in [(*i, 0), (*j, 1)] {
                    velocity[axis] = d1[c] * theta_dot;
                    acceleration[axis] = d2[c] * theta_dot * theta_dot + d1[c] * theta_ddot;
                }
            }
        }
    }

    /// Position at path coordinate `s`.
    pub fn position(&self, s: f64, out: &mut [f64]) {
        let n = out.len();
        let (mut v, mut a) = (vec![0.0; n], vec![0.0; n]);
        self.eval(s, 0.0, 0.0, out, &mut v, &mut a);
    }

    /// Limits on the path coordinate (ṡ, s̈, s⃛) under which every axis stays within its limits,
    /// with the programmed feed as a further bound on ṡ when it applies.
    ///
    /// Line: exact, `limit_i / |q'_i|`. Arc: with bounds K1 ≥ |q'|, K2 ≥ |q''|, K3 ≥ |q'''| on
    /// the plane axes, the centripetal terms get a share ρ of each budget,
    /// `K2·ṡ² ≤ ρ·a_i` and `K3·ṡ³ ≤ ρ·j_i` (this caps ṡ); the tangential terms get the rest,
    /// `K1·s̈ ≤ (1−ρ)·a_i`, `3·K2·ṡ·s̈ ≤ (1−ρ)·j_i/2` and `K1·s⃛ ≤ (1−ρ)·j_i/2`, so the sum in
    /// the jerk equation above stays within `j_i` wherever the profile stays within the caps.
    /// Any ρ in (0, 1) is safe; arcs are passed rest to rest, so ρ is chosen from a grid to give
    /// the shortest rest-to-rest profile over the arc (a long arc wants speed, a short one
    /// acceleration).
    pub fn path_limits(&self, axes: &[AxisSpec], feed: Option<f64>) -> Limits {
        let mut v = f64::INFINITY;
        let mut a = f64::INFINITY;
        let mut j = f64::INFINITY;
        if self.feed_applies {
            if let Some(feed) = feed {
                v = v.min(feed);
            }
        }
        // Axes that move linearly in s: the line, or the non-plane axes of a helix.
        let linear_rates: Vec<f64> = match &self.curve {
            Curve::Line { direction } => direction.clone(),
            Curve::Arc { helix, scale, .. } => helix.iter().map(|h| h / scale).collect(),
        };
        for (rate, axis) in linear_rates.iter().zip(axes) {
            let rate = rate.abs();
            if rate > 0.0 {
                v = v.min(axis.limits.velocity / rate);
                a = a.min(axis.limits.acceleration / rate);
                j = j.min(axis.limits.jerk / rate);
            }
        }
        if let Curve::Arc { .. } = &self.curve {
            let straight = Limits::new(v, a, j);
            let duration = |l: &Limits| Profile::rest_to_rest(self.length, l).duration();
            let best = ARC_CENTRIPETAL_SHARES
                .iter()
                .map(|&share| self.arc_limits(axes, straight, share))
                .min_by(|x, y| duration(x).total_cmp(&duration(y)));
            return best.unwrap_or(straight);
        }
        if !v.is_finite() {
            // A segment that moves no axis: any positive limits do.
            return Limits::new(1.0, 1.0, 1.0);
        }
        Limits::new(v, a, j)
    }

    /// An arc's path limits with centripetal share `share`, on top of the limits `other` from
    /// the feed and the helix axes.
    fn arc_limits(&self, axes: &[AxisSpec], other: Limits, share: f64) -> Limits {
        let Curve::Arc {
            plane,
            start_radius,
            radius_rate,
            sweep,
            scale,
            ..
        } = &self.curve
        else {
            return other;
        };
        let r = start_radius.max(start_radius + radius_rate * sweep);
        let dr = radius_rate.abs();
        let k1 = dr.hypot(r) / scale;
        let k2 = (2.0 * dr).hypot(r) / (scale * scale);
        let k3 = (3.0 * dr).hypot(r) / (scale * scale * scale);
        let (mut v, mut a, mut j) = (other.velocity, other.acceleration, other.jerk);
        for &axis in plane {
            let l = axes[axis].limits;
            v = v
                .min(l.velocity / k1)
                .min((share * l.acceleration / k2).sqrt())
                .min((share * l.jerk / k3).cbrt());
        }
        for &axis in plane {
            let l = axes[axis].limits;
            let tangential_jerk = (1.0 - share) * l.jerk / 2.0;
            a = a
                .min((1.0 - share) * l.acceleration / k1)
                .min(tangential_jerk / (3.0 * k2 * v));
            j = j.min(tangential_jerk / k1);
        }
        Limits::new(v, a, j)
    }
}
