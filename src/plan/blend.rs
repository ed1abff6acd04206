//! Corner blends for continuous mode (G64): the corner between two lines is rounded by a
//! jerk-limited change of the axis velocity vector, without stopping and without touching the
//! programmed points.
//!
//! At a corner `C` between lines with unit-speed directions `u1 = dq/ds` (in) and `u2` (out),
//! passed at path speed `v`, every axis changes its velocity from `v·u1_i` to `v·u2_i` over the
//! same duration `τ`, all following one normalised shape `σ(x)`, `x = t/τ`, which rises from 0
//! to 1 with an acceleration that is a trapezoid (ramps of `r·τ`, peak `h = 1/(1−r)`):
//!
//! ```text
//!   q(t) = P_in + v·u1·t + v·(u2 − u1)·τ·Σ(t/τ),    Σ(x) = ∫₀ˣ σ
//! ```
//!
//! `σ` is point-symmetric (`σ(x) + σ(1−x) = 1`), so `Σ(1) = 1/2` and the blend ends at
//! `P_in + (v·τ/2)·(u1 + u2)`: starting at `P_in = C − (v·τ/2)·u1` it ends exactly on the
//! outgoing line at `C + (v·τ/2)·u2`. The curve is symmetric about the corner's bisector; its
//! midpoint is `C + v·τ·Σ(1/2)·(u2 − u1)` with `Σ(1/2) = h·(1/8 − r/4 + r²/6)`, the point
//! nearest the corner, so the blend passes `v·τ·Σ(1/2)·|u2 − u1|` from `C`.
//!
//! Axis `i` changes its velocity by `Δ_i = v·|u2_i − u1_i|`; its peak acceleration is
//! `Δ_i·h/τ` and its jerk `Δ_i·h/(r·τ²)`. With `A = max_i Δ_i/a_i` and
//! `B = max_i sqrt(Δ_i/j_i)` the shortest `τ` meeting both on every axis is
//! `τ = A + B²/A` with `r = B²/(A² + B²)` when `B ≤ A` (the limiting axes reach their
//! acceleration limit), else `τ = 2B` with `r = 1/2` (jerk only) — for a single axis these are
//! the time-optimal velocity changes of [`super::profile::VelocityChange`]. The velocities stay
//! between `v·u1_i` and `v·u2_i`, within the axis limit when `v` is within both lines' limits.

use super::path::AxisSpec;
use super::profile::{largest_at_most, Limits, VelocityChange};

/// The direction change at a corner, `turn = u2 − u1`, with what it demands of the axes per
/// unit of path speed (computed once per corner; every speed tried is then O(1)).
#[derive(Debug, Clone, PartialEq)]
pub struct CornerTurn {
    pub turn: Vec<f64>,
    /// |u2 − u1|.
    norm: f64,
    /// max_i |Δu_i| / a_i, so that A = v · this.
    accel_per_speed: f64,
    /// max_i sqrt(|Δu_i| / j_i), so that B = sqrt(v) · this.
    jerk_per_root_speed: f64,
}

impl CornerTurn {
    pub fn new(turn: Vec<f64>, axes: &[AxisSpec]) -> Self {
        let mut accel_per_speed: f64 = 0.0;
        let mut jerk_per_root_speed: f64 = 0.0;
        for (du, axis) in turn.iter().zip(axes) {
            accel_per_speed = accel_per_speed.max(du.abs() / axis.limits.acceleration);
            jerk_per_root_speed = jerk_per_root_speed.max((du.abs() / axis.limits.jerk).sqrt());
        }
        let norm = turn.iter().map(|x| x * x).sum::<f64>().sqrt();
        CornerTurn {
            turn,
            norm,
            accel_per_speed,
            jerk_per_root_speed,
        }
    }

    /// Shortest blend at path speed `speed`.
    pub fn timing(&self, speed: f64) -> CornerTiming {
        let a = speed * self.accel_per_speed;
        let b = speed.sqrt() * self.jerk_per_root_speed;
        if b == 0.0 {
            CornerTiming {
                duration: 0.0,
                ramp_fraction: 0.5,
            }
        } else if b <= a {
            CornerTiming {
                duration: a + b * b / a,
                ramp_fraction: b * b / (a * a + b * b),
            }
        } else {
            CornerTiming {
                duration: 2.0 * b,
                ramp_fraction: 0.5,
            }
        }
    }

    /// Distance from the corner to the blend's midpoint at `speed`.
    pub fn corner_distance(&self, speed: f64) -> f64 {
        let timing = self.timing(speed);
        speed * timing.duration * Shape::new(timing.ramp_fraction).integral(0.5) * self.norm
    }
}

/// Duration and shape of a blend.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CornerTiming {
    /// τ (s).
    pub duration: f64,
    /// r: each jerk ramp lasts r·τ (0 < r ≤ 1/2).
    pub ramp_fraction: f64,
}

impl CornerTiming {
    /// Length of each line used by the blend (in the path coordinate) at `speed`.
    pub fn cut_length(&self, speed: f64) -> f64 {
        0.5 * speed * self.duration
    }
}

/// Highest path speed at a corner (≤ `speed_cap`) whose blend passes within `tolerance` of the
/// corner and cuts at most `max_cut` off each line. The corner distance and the cut length both
/// grow with the speed, so the answer is found by a bracketing search.
pub fn max_corner_speed(turn: &CornerTurn, tolerance: f64, max_cut: f64, speed_cap: f64) -> f64 {
    // The larger of the two uses of the allowance, as a fraction: 1 is the limit.
    let usage = |speed: f64| {
        let deviation = turn.corner_distance(speed);
        let deviation = if deviation == 0.0 {
            0.0
        } else {
            deviation / tolerance
        };
        deviation.max(turn.timing(speed).cut_length(speed) / max_cut)
    };
    if usage(speed_cap) <= 1.0 {
        speed_cap
    } else if tolerance == 0.0 {
        0.0
    } else {
        largest_at_most(usage, 1.0, 0.0, speed_cap)
    }
}

/// One line next to a corner, as the corner-speed choice sees it: its path limits and the speed
/// it would cruise at without the corner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CornerSide {
    pub limits: Limits,
    pub cruise: f64,
}

/// Time lost at a corner passed at `speed`, against cruising through it on both sides: the
/// blend's duration, less the time the cut lengths would take at cruise, plus for each side the
/// time lost slowing from cruise to `speed` (a change lasting T covers the distance at the mean
/// speed, so it loses T·(cruise − speed)/(2·cruise)). At speed 0 this is the cost of a stop.
pub fn corner_time_loss(speed: f64, turn: &CornerTurn, sides: &[CornerSide; 2]) -> f64 {
    let timing = turn.timing(speed);
    let cut = timing.cut_length(speed);
    let mut loss = timing.duration;
    for side in sides {
        let cruise = side.cruise.max(speed);
        if cruise <= 0.0 {
            continue;
        }
        let change =
            VelocityChange::new(cruise - speed, side.limits.acceleration, side.limits.jerk);
        loss += change.duration() * (cruise - speed) / (2.0 * cruise) - cut / cruise;
    }
    loss
}

/// The corner speed in `[0, speed_cap]` that loses least time by [`corner_time_loss`].
///
/// With a jerk limit, turning the velocity vector at speed v takes a time growing like √v
/// (jerk-limited blend) while slowing down less saves a time growing like v: just above zero a
/// blend costs more than a stop, and a corner whose tolerance only allows a crawl is faster
/// taken as an exact stop. The loss is not unimodal, so it is scanned on a grid and refined by
/// golden section around the best grid point.
pub fn best_corner_speed(turn: &CornerTurn, speed_cap: f64, sides: &[CornerSide; 2]) -> f64 {
    const GRID: usize = 16;
    let loss = |speed: f64| corner_time_loss(speed, turn, sides);
    let (mut best, mut best_loss) = (0.0, loss(0.0));
    for i in 1..=GRID {
        let speed = speed_cap * i as f64 / GRID as f64;
        let l = loss(speed);
        if l < best_loss {
            (best, best_loss) = (speed, l);
        }
    }
    if best == 0.0 {
        return 0.0;
    }
    // Golden section between the neighbouring grid points, one new evaluation per step.
    let step = speed_cap / GRID as f64;
    let (mut lo, mut hi) = (best - step, (best + step).min(speed_cap));
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (hi - ratio * (hi - lo), lo + ratio * (hi - lo));
    let (mut l1, mut l2) = (loss(x1), loss(x2));
    for _ in 0..30 {
        if l1 <= l2 {
            (hi, x2, l2) = (x2, x1, l1);
            x1 = hi - ratio * (hi - lo);
            l1 = loss(x1);
        } else {
            (lo, x1, l1) = (x1, x2, l2);
            x2 = lo + ratio * (hi - lo);
            l2 = loss(x2);
        }
    }
    let (refined, refined_loss) = if l1 <= l2 { (x1, l1) } else { (x2, l2) };
    if refined_loss < best_loss {
        refined
    } else {
        best
    }
}

/// The normalised velocity-change shape σ on [0, 1] with ramp fraction r.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Shape {
    ramp: f64,
    peak: f64,
}

impl Shape {
    fn new(ramp: f64) -> Self {
        Shape {
            ramp,
            peak: 1.0 / (1.0 - ramp),
        }
    }

    /// σ'(x), σ(x), Σ(x) = ∫₀ˣ σ, and σ''(x).
    fn eval(&self, x: f64) -> (f64, f64, f64, f64) {
        let (r, h) = (self.ramp, self.peak);
        if x > 0.5 {
            // Point symmetry: σ(x) = 1 − σ(1−x), σ'(x) = σ'(1−x), Σ(x) = x − 1/2 + Σ(1−x).
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

    fn integral(&self, x: f64) -> f64 {
        self.eval(x).2
    }
}

/// A planned corner blend.
#[derive(Debug, Clone, PartialEq)]
pub struct CornerBlend {
    /// Where the blend leaves the incoming line (P_in).
    pub start: Vec<f64>,
    /// Axis velocities on entry (v·u1).
    pub entry_velocity: Vec<f64>,
    /// Change of axis velocities (v·(u2 − u1)).
    pub velocity_change: Vec<f64>,
    pub timing: CornerTiming,
}

impl CornerBlend {
    pub fn duration(&self) -> f64 {
        self.timing.duration
    }

    /// Axis positions, velocities and accelerations at time `t` into the blend.
    pub fn eval(
        &self,
        t: f64,
        position: &mut [f64],
        velocity: &mut [f64],
        acceleration: &mut [f64],
    ) {
        let tau = self.timing.duration;
        let t = t.clamp(0.0, tau);
        let (d, s, i, _) = Shape::new(self.timing.ramp_fraction).eval(t / tau);
        for k in 0..self.start.len() {
            let (v0, dv) = (self.entry_velocity[k], self.velocity_change[k]);
            position[k] = self.start[k] + v0 * t + dv * tau * i;
            velocity[k] = v0 + dv * s;
            acceleration[k] = dv * d / tau;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shape_is_consistent() {
        for r in [0.05, 0.2, 0.5] {
            let shape = Shape::new(r);
            let (_, s1, i1, _) = shape.eval(1.0);
            assert!((s1 - 1.0).abs() < 1e-14 && (i1 - 0.5).abs() < 1e-14);
            // Midpoint integral in closed form.
            let closed = shape.peak * (1.0 / 8.0 - r / 4.0 + r * r / 6.0);
            assert!((shape.integral(0.5) - closed).abs() < 1e-15);
            // σ and Σ are integrals of σ' and σ (midpoint rule on a fine grid).
            let n = 20000;
            let (mut s, mut i) = (0.0, 0.0);
            for k in 0..n {
                let x = (k as f64 + 0.5) / n as f64;
                let (d, sx, ..) = shape.eval(x);
                s += d / n as f64;
                i += sx / n as f64;
            }
            assert!((s - 1.0).abs() < 1e-6 && (i - 0.5).abs() < 1e-6, "{s} {i}");
        }
    }
}
