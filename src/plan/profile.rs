//! One-dimensional jerk-limited motion profiles (the "double S" / seven-phase profile).
//!
//! A profile moves a coordinate `s` from 0 to a distance `L ≥ 0` starting at velocity `v0` and
//! ending at velocity `v1`, with zero acceleration at both ends, under the limits
//! `|ṡ| ≤ V`, `|s̈| ≤ A`, `|s⃛| ≤ J`. Its seven phases are
//!
//! ```text
//!   phase   1     2     3     4      5     6     7
//!   jerk   +J     0    -J     0     -J     0    +J
//!          └─ speed-up ─┘  cruise  └─ slow-down ─┘
//! ```
//!
//! Each speed change (phases 1–3 and 5–7) is a [`VelocityChange`]: an acceleration trapezoid,
//! or a triangle when the change is too small to reach `A`. With zero acceleration at the ends,
//! the time-optimal profile is the one with the highest peak velocity `vp` whose speed-up and
//! slow-down fit in `L` (the covered distance grows monotonically with `vp`); when `V` fits,
//! the rest is cruise. Degenerate cases are phases of zero duration:
//!
//! - velocity-limited: `vp = V`, cruise > 0;
//! - acceleration-limited: `vp < V`, the speed changes hold `A` (phases 2 and 6 > 0);
//! - jerk-limited: `vp < V` and too low to reach `A` (phases 2, 4, 6 vanish).

/// Kinematic limits of a one-dimensional motion (all strictly positive).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// `V`: largest speed (coordinate units per s).
    pub velocity: f64,
    /// `A`: largest acceleration magnitude (coordinate units per s²).
    pub acceleration: f64,
    /// `J`: largest jerk magnitude (coordinate units per s³).
    pub jerk: f64,
}

impl Limits {
    /// Limits `V`, `A`, `J`, unchecked (see [`Limits::is_valid`]).
    pub fn new(velocity: f64, acceleration: f64, jerk: f64) -> Self {
        Limits {
            velocity,
            acceleration,
            jerk,
        }
    }

    /// True when every limit is finite and strictly positive.
    pub fn is_valid(&self) -> bool {
        [self.velocity, self.acceleration, self.jerk]
            .iter()
            .all(|x| x.is_finite() && *x > 0.0)
    }
}

/// The fastest change of velocity between two states of zero acceleration, under acceleration
/// and jerk limits: jerk ±J ramps (`ramp` each) around an optional hold at the peak
/// acceleration (`hold`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityChange {
    /// Duration of each of the two jerk phases (s).
    pub ramp: f64,
    /// Duration of the constant-acceleration phase between them (s).
    pub hold: f64,
    /// Magnitude of the peak acceleration reached (≤ A).
    pub peak_acceleration: f64,
}

impl VelocityChange {
    /// Fastest change of velocity by `|delta_v|` with acceleration limit `a` and jerk limit `j`.
    pub fn new(delta_v: f64, a: f64, j: f64) -> Self {
        let dv = delta_v.abs();
        if dv * j >= a * a {
            // The ramps reach A (a ramp of A/J changes the velocity by A²/2J, two of them by
            // A²/J): hold A for the rest.
            VelocityChange {
                ramp: a / j,
                hold: dv / a - a / j,
                peak_acceleration: a,
            }
        } else {
            // Triangle: two ramps of sqrt(dv/J) reach only sqrt(dv·J) < A.
            let ramp = (dv / j).sqrt();
            VelocityChange {
                ramp,
                hold: 0.0,
                peak_acceleration: j * ramp,
            }
        }
    }

    /// Total duration (s).
    pub fn duration(&self) -> f64 {
        2.0 * self.ramp + self.hold
    }

    /// Distance covered while changing from `v_from` to `v_to`. The acceleration pulse is
    /// symmetric in time, so the mean velocity is exactly `(v_from + v_to) / 2`.
    pub fn distance(&self, v_from: f64, v_to: f64) -> f64 {
        self.duration() * 0.5 * (v_from + v_to)
    }
}

/// Shortest distance in which a velocity change from `v_from` to `v_to` (zero acceleration at
/// both ends) can be made with acceleration and jerk limits `a`, `j`.
pub fn transfer_distance(v_from: f64, v_to: f64, a: f64, j: f64) -> f64 {
    VelocityChange::new(v_to - v_from, a, j).distance(v_from, v_to)
}

/// Highest velocity reachable from `v_from` within `distance` (zero acceleration at both ends),
/// capped at `limits.velocity`. The same function gives the highest velocity from which one can
/// slow down to `v_from` within `distance` (the transfer distance is symmetric).
///
/// In closed form: a change by Δv covers `T(Δv)·(v_from + Δv/2)`, with `T = Δv/A + A/J` once
/// it reaches A (Δv ≥ A²/J: a quadratic in Δv) and `T = 2·sqrt(Δv/J)` below (a cubic in
/// sqrt(Δv), solved by Cardano's formula and polished by Newton steps). The result never needs
/// more than `distance` (checked; rounding is taken off the top). Never below
/// `min(v_from, limits.velocity)`.
pub fn reachable_velocity(v_from: f64, distance: f64, limits: &Limits) -> f64 {
    let (a, j) = (limits.acceleration, limits.jerk);
    if transfer_distance(v_from, limits.velocity, a, j) <= distance {
        return limits.velocity;
    }
    if distance.is_nan() || distance <= 0.0 {
        return v_from.min(limits.velocity);
    }
    let switch = a * a / j;
    let covered_at_switch = transfer_distance(v_from, v_from + switch, a, j);
    let dv = if distance >= covered_at_switch {
        // (Δv + A²/J)·(2·v0 + Δv) = 2·A·d.
        let b = 2.0 * v_from + switch;
        let c = 2.0 * a * (v_from * a / j - distance);
        -2.0 * c / (b + (b * b - 4.0 * c).sqrt())
    } else {
        // x³ + 2·v0·x − d·sqrt(J) = 0 with x = sqrt(Δv).
        let (p, q) = (2.0 * v_from, -distance * j.sqrt());
        let u = (-0.5 * q + (0.25 * q * q + p * p * p / 27.0).sqrt()).cbrt();
        let mut x = if u > 0.0 { u - p / (3.0 * u) } else { 0.0 };
        for _ in 0..2 {
            x -= (x * x * x + p * x + q) / (3.0 * x * x + p);
        }
        x.max(0.0) * x.max(0.0)
    };
    let mut v = (v_from + dv).min(limits.velocity);
    // Rounding may leave the change a few ulps too long for the distance: take it off.
    for _ in 0..4 {
        if transfer_distance(v_from, v, a, j) <= distance {
            return v;
        }
        v = v_from + (v - v_from) * (1.0 - 1e-12);
    }
    largest_at_most(
        |v| transfer_distance(v_from, v, a, j),
        distance,
        v_from,
        limits.velocity,
    )
}

/// Largest `x` in `[lo, hi]` with `f(x) ≤ target`, for `f` continuous and non-decreasing with
/// `f(lo) ≤ target < f(hi)`.
///
/// Regula falsi in its Illinois form (the value kept at an end that survives twice is halved):
/// the bracket always holds the answer and shrinks superlinearly, about ten evaluations to a
/// few ulps where bisection needs fifty. The returned point is the lower end, so `f(x) ≤ target`
/// holds exactly, not just to within a tolerance.
pub(super) fn largest_at_most(
    f: impl Fn(f64) -> f64,
    target: f64,
    mut lo: f64,
    mut hi: f64,
) -> f64 {
    let mut f_lo = f(lo) - target;
    let mut f_hi = f(hi) - target;
    let mut last_moved = 0; // −1: lo moved last, +1: hi moved last
    for _ in 0..100 {
        if hi - lo <= 4.0 * f64::EPSILON * hi.abs() {
            break;
        }
        let mut x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
        if !(x > lo && x < hi) {
            x = 0.5 * (lo + hi);
            if !(x > lo && x < hi) {
                break;
            }
        }
        let fx = f(x) - target;
        if fx <= 0.0 {
            (lo, f_lo) = (x, fx);
            if last_moved == -1 {
                f_hi *= 0.5;
            }
            last_moved = -1;
        } else {
            (hi, f_hi) = (x, fx);
            if last_moved == 1 {
                f_lo *= 0.5;
            }
            last_moved = 1;
        }
    }
    lo
}

/// Position, velocity and acceleration of a profile at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State {
    /// Distance from the profile's start (signed).
    pub position: f64,
    /// Velocity (per s).
    pub velocity: f64,
    /// Acceleration (per s²).
    pub acceleration: f64,
}

/// A seven-phase jerk-limited profile from 0 to `distance` (see the module docs). Phases of zero
/// duration are kept so that the phase structure is always the same.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    /// Phase durations (s).
    durations: [f64; 7],
    /// Jerk in each phase (signed).
    jerks: [f64; 7],
    /// Start time of each phase, and the end time at index 7.
    times: [f64; 8],
    /// State at the start of each phase, and the end state at index 7.
    states: [State; 8],
    /// Target distance (signed for single-axis moves); reached exactly at the end.
    distance: f64,
    /// Peak velocity (signed like the distance).
    peak_velocity: f64,
}

/// Which limit shapes a rest-to-rest profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Regime {
    /// Zero-length move.
    Stationary,
    /// Cruise at the velocity limit.
    VelocityLimited,
    /// Reaches the acceleration limit but not the velocity limit.
    AccelerationLimited,
    /// Reaches neither: jerk phases only.
    JerkLimited,
}

/// What determines a profile: the boundary and peak velocities, the cruise and the limits.
/// Small (a plan keeps one per stretch); [`Recipe::build`] expands it into the phases.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Recipe {
    /// +1 or −1: the direction of a single-axis move.
    pub sign: f64,
    /// Distance to cover (≥ 0, unsigned).
    pub length: f64,
    /// Speed at the start (≥ 0; the velocity is `sign` times it).
    pub v_start: f64,
    /// Peak speed, held during the cruise (≥ 0).
    pub peak: f64,
    /// Speed at the end (≥ 0).
    pub v_end: f64,
    /// Cruise duration at the peak (s).
    pub cruise: f64,
    /// The limits the profile was planned under (its acceleration and jerk shape the phases).
    pub limits: Limits,
}

impl Recipe {
    /// Time-optimal rest-to-rest motion over a signed `distance`, in closed form.
    pub fn rest_to_rest(distance: f64, limits: &Limits) -> Recipe {
        let (v, a, j) = (limits.velocity, limits.acceleration, limits.jerk);
        let length = distance.abs();
        let (peak, cruise) = match Profile::rest_to_rest_regime(length, limits) {
            Regime::Stationary => (0.0, 0.0),
            Regime::VelocityLimited => {
                let full = 2.0 * VelocityChange::new(v, a, j).distance(0.0, v);
                (v, (length - full) / v)
            }
            // Speed-up and slow-down both hold A: L = vp²/A + vp·A/J.
            Regime::AccelerationLimited => {
                let b = a / j;
                (0.5 * a * (-b + (b * b + 4.0 * length / a).sqrt()), 0.0)
            }
            // Two jerk triangles: L = 2·vp·sqrt(vp/J).
            Regime::JerkLimited => ((0.5 * length * j.sqrt()).powf(2.0 / 3.0), 0.0),
        };
        Recipe {
            sign: if distance < 0.0 { -1.0 } else { 1.0 },
            length,
            v_start: 0.0,
            peak,
            v_end: 0.0,
            cruise,
            limits: *limits,
        }
    }

    /// Time-optimal motion over `length ≥ 0` from `v_start` to `v_end` (zero acceleration at
    /// both ends). `None` when the velocities exceed the limit or `length` is too short to
    /// change from one to the other (see [`transfer_distance`]).
    pub fn plan(length: f64, v_start: f64, v_end: f64, limits: &Limits) -> Option<Recipe> {
        Self::plan_with_changes(length, v_start, v_end, limits).map(|(recipe, _)| recipe)
    }

    /// [`Self::plan`] and the recipe's [`Self::duration`] (the same number, from the speed
    /// changes the plan computes anyway).
    pub fn plan_timed(
        length: f64,
        v_start: f64,
        v_end: f64,
        limits: &Limits,
    ) -> Option<(Recipe, f64)> {
        Self::plan_with_changes(length, v_start, v_end, limits).map(|(recipe, changes)| {
            let duration = match changes {
                Some((up, down)) => recipe.duration_of(up, down),
                None => recipe.duration(),
            };
            (recipe, duration)
        })
    }

    /// [`Self::plan`], with its speed-up and slow-down when it computed them (not from rest to
    /// rest).
    #[allow(clippy::type_complexity)]
    fn plan_with_changes(
        length: f64,
        v_start: f64,
        v_end: f64,
        limits: &Limits,
    ) -> Option<(Recipe, Option<(VelocityChange, VelocityChange)>)> {
        let (v, a, j) = (limits.velocity, limits.acceleration, limits.jerk);
        let slack = 1e-12 * v;
        if length.is_nan()
            || length < 0.0
            || v_start < 0.0
            || v_end < 0.0
            || v_start.max(v_end) > v + slack
        {
            return None;
        }
        let (v_start, v_end) = (v_start.min(v), v_end.min(v));
        if v_start == 0.0 && v_end == 0.0 {
            return Some((Self::rest_to_rest(length, limits), None));
        }
        let covered = |peak: f64| {
            VelocityChange::new(peak - v_start, a, j).distance(v_start, peak)
                + VelocityChange::new(peak - v_end, a, j).distance(peak, v_end)
        };
        let lowest = v_start.max(v_end);
        if covered(lowest) > length * (1.0 + 1e-12) + 1e-15 {
            return None;
        }
        let peak = if covered(v) <= length {
            v
        } else {
            // When both speed changes reach A they cover
            // (2p² − v0² − v1²)/(2A) + (A/2J)·(2p + v0 + v1): a quadratic in the peak p.
            let ramp = a / j;
            let c = -(v_start * v_start + v_end * v_end) / (2.0 * a)
                + 0.5 * ramp * (v_start + v_end)
                - length;
            let p = 0.5 * a * (-ramp + (ramp * ramp - 4.0 * c / a).sqrt());
            let both_reach_a = p - lowest >= a * ramp;
            let mut fits = None;
            if both_reach_a && p.is_finite() && p <= v {
                // Rounding may leave it a few ulps too long for the length: take them off.
                let mut p = p;
                for _ in 0..4 {
                    if covered(p) <= length {
                        fits = Some(p);
                        break;
                    }
                    p = lowest + (p - lowest) * (1.0 - 1e-12);
                }
            }
            // Otherwise the covered distance grows with the peak: take the largest that fits.
            fits.unwrap_or_else(|| peak_within(length, v_start, v_end, lowest, limits))
        };
        // Whatever the speed changes leave (the cruise, or the last ulps of the bisection) is
        // covered at the peak velocity.
        let up = VelocityChange::new(peak - v_start, a, j);
        let down = VelocityChange::new(peak - v_end, a, j);
        let cruise = if peak > 0.0 {
            ((length - (up.distance(v_start, peak) + down.distance(peak, v_end))) / peak).max(0.0)
        } else {
            0.0
        };
        let recipe = Recipe {
            sign: 1.0,
            length,
            v_start,
            peak,
            v_end,
            cruise,
            limits: *limits,
        };
        Some((recipe, Some((up, down))))
    }

    /// Total duration (s), without building the phases (summed phase by phase, as the built
    /// profile sums it, so the two agree exactly).
    pub fn duration(&self) -> f64 {
        let (a, j) = (self.limits.acceleration, self.limits.jerk);
        let up = VelocityChange::new(self.peak - self.v_start, a, j);
        let down = VelocityChange::new(self.peak - self.v_end, a, j);
        self.duration_of(up, down)
    }

    /// [`Self::duration`] with the speed-up and the slow-down given.
    fn duration_of(&self, up: VelocityChange, down: VelocityChange) -> f64 {
        [
            up.ramp,
            up.hold,
            up.ramp,
            self.cruise,
            down.ramp,
            down.hold,
            down.ramp,
        ]
        .iter()
        .fold(0.0, |t, d| t + d)
    }

    /// The profile's phases.
    pub fn build(&self) -> Profile {
        Profile::from_peak(
            self.sign,
            self.length,
            self.v_start,
            self.peak,
            self.v_end,
            self.cruise,
            &self.limits,
        )
    }
}

/// Distance covered changing from `v0` to `p ≥ v0` (zero acceleration at both ends) and its
/// derivative with respect to `p`.
fn covered_and_slope(v0: f64, p: f64, a: f64, j: f64) -> (f64, f64) {
    let dv = p - v0;
    if dv * j >= a * a {
        let t = dv / a + a / j;
        (0.5 * t * (v0 + p), 0.5 * (v0 + p) / a + 0.5 * t)
    } else if dv > 0.0 {
        let root = (dv / j).sqrt();
        let t = 2.0 * root;
        (0.5 * t * (v0 + p), 0.5 * (v0 + p) / (j * root) + 0.5 * t)
    } else {
        (0.0, f64::INFINITY)
    }
}

/// The largest peak velocity in `[lowest, limits.velocity]` whose speed-up from `v_start` and
/// slow-down to `v_end` fit in `length` (which the lowest does and the limit does not): Newton
/// steps on the covered distance, kept inside a bracket that always holds the answer (a step
/// leaving it bisects instead). Returns the bracket's lower end, which fits.
fn peak_within(length: f64, v_start: f64, v_end: f64, lowest: f64, limits: &Limits) -> f64 {
    let (a, j) = (limits.acceleration, limits.jerk);
    let covered = |p: f64| {
        let (d0, s0) = covered_and_slope(v_start, p, a, j);
        let (d1, s1) = covered_and_slope(v_end, p, a, j);
        (d0 + d1 - length, s0 + s1)
    };
    let (mut lo, mut hi) = (lowest, limits.velocity);
    // Start from the peak without a jerk limit, (p² − v0²)/2A + (p² − v1²)/2A = length: close
    // when the changes hold A, and a bound from above either way.
    let guess = (0.5 * (v_start * v_start + v_end * v_end) + a * length).sqrt();
    let mut x = if guess > lo && guess < hi { guess } else { hi };
    for _ in 0..100 {
        let (f, slope) = covered(x);
        if f <= 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let newton = x - f / slope;
        if hi - lo <= 4.0 * f64::EPSILON * hi || (newton - x).abs() <= 4.0 * f64::EPSILON * x {
            break;
        }
        x = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
    }
    // Newton converges from one side: the last point may be a few ulps over.
    let mut p = x;
    for _ in 0..4 {
        if p <= lo || covered(p).0 <= 0.0 {
            return p.max(lo);
        }
        p -= 4.0 * f64::EPSILON * p;
    }
    lo
}

/// Duration of the time-optimal rest-to-rest motion over `length` (closed form).
pub fn rest_to_rest_duration(length: f64, limits: &Limits) -> f64 {
    Recipe::rest_to_rest(length, limits).duration()
}

impl Profile {
    /// Time-optimal rest-to-rest profile over a signed `distance`, in closed form.
    pub fn rest_to_rest(distance: f64, limits: &Limits) -> Profile {
        Recipe::rest_to_rest(distance, limits).build()
    }

    /// The regime of the time-optimal rest-to-rest profile over `length ≥ 0`.
    pub fn rest_to_rest_regime(length: f64, limits: &Limits) -> Regime {
        let (v, a, j) = (limits.velocity, limits.acceleration, limits.jerk);
        if length <= 0.0 {
            return Regime::Stationary;
        }
        // Distance to reach V and stop again.
        let full = 2.0 * VelocityChange::new(v, a, j).distance(0.0, v);
        if length >= full {
            Regime::VelocityLimited
        } else if length >= 2.0 * a * a * a / (j * j) {
            // At vp = A²/J the speed changes just touch A; they cover 2·(A²/J)·(A/J). If V < A²/J
            // then `full` is below this threshold, so this branch implies vp ≤ V.
            Regime::AccelerationLimited
        } else {
            Regime::JerkLimited
        }
    }

    /// Time-optimal profile over `length ≥ 0` from `v_start` to `v_end` (zero acceleration at
    /// both ends); see [`Recipe::plan`].
    pub fn plan(length: f64, v_start: f64, v_end: f64, limits: &Limits) -> Option<Profile> {
        Recipe::plan(length, v_start, v_end, limits).map(|r| r.build())
    }

    /// Builds the phases from the boundary and peak velocities and the cruise duration.
    fn from_peak(
        sign: f64,
        length: f64,
        v_start: f64,
        peak: f64,
        v_end: f64,
        cruise: f64,
        limits: &Limits,
    ) -> Profile {
        let (a, j) = (limits.acceleration, limits.jerk);
        let up = VelocityChange::new(peak - v_start, a, j);
        let down = VelocityChange::new(peak - v_end, a, j);
        let durations = [
            up.ramp, up.hold, up.ramp, cruise, down.ramp, down.hold, down.ramp,
        ];
        let jerks = [j, 0.0, -j, 0.0, -j, 0.0, j].map(|x| x * sign);
        let mut times = [0.0; 8];
        let mut states = [State::default(); 8];
        states[0] = State {
            position: 0.0,
            velocity: sign * v_start,
            acceleration: 0.0,
        };
        for phase in 0..7 {
            times[phase + 1] = times[phase] + durations[phase];
            states[phase + 1] = advance(states[phase], jerks[phase], durations[phase]);
        }
        // The ramps end at zero acceleration by construction; remove the rounding residue so
        // that the cruise and the end state are exact.
        states[3].acceleration = 0.0;
        states[3].velocity = sign * peak;
        states[4].acceleration = 0.0;
        states[4].velocity = sign * peak;
        states[7] = State {
            position: sign * length,
            velocity: sign * v_end,
            acceleration: 0.0,
        };
        Profile {
            durations,
            jerks,
            times,
            states,
            distance: sign * length,
            peak_velocity: sign * peak,
        }
    }

    /// Total duration (s).
    pub fn duration(&self) -> f64 {
        self.times[7]
    }

    /// Target distance (signed).
    pub fn distance(&self) -> f64 {
        self.distance
    }

    /// Peak velocity (signed like the distance).
    pub fn peak_velocity(&self) -> f64 {
        self.peak_velocity
    }

    /// Phase durations (s), phases 1–7.
    pub fn phase_durations(&self) -> [f64; 7] {
        self.durations
    }

    /// Velocity at the start and at the end.
    pub fn boundary_velocities(&self) -> (f64, f64) {
        (self.states[0].velocity, self.states[7].velocity)
    }

    /// Time at which the profile reaches `distance` (unsigned, between 0 and |target|). The
    /// position never decreases along the profile, so this is found by bisection.
    pub fn time_at(&self, distance: f64) -> f64 {
        let target = distance.abs();
        let reached = |t: f64| self.state(t).position.abs() >= target;
        let (mut lo, mut hi) = (0.0, self.duration());
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if reached(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        hi
    }

    /// State at time `t` (clamped to the profile: before 0 the start, after the end exactly the
    /// target at the end velocity).
    pub fn state(&self, t: f64) -> State {
        if t <= 0.0 {
            return self.states[0];
        }
        if t >= self.times[7] {
            // Continue at the end velocity (zero when at rest): the end state is exact.
            let end = self.states[7];
            let dt = t - self.times[7];
            return State {
                position: end.position + end.velocity * dt,
                ..end
            };
        }
        let phase = (0..7).rev().find(|&p| t >= self.times[p]).unwrap_or(0);
        advance(self.states[phase], self.jerks[phase], t - self.times[phase])
    }
}

/// Integrates constant jerk `jerk` for `dt` from `state`.
fn advance(state: State, jerk: f64, dt: f64) -> State {
    let State {
        position: p,
        velocity: v,
        acceleration: a,
    } = state;
    State {
        position: p + dt * (v + dt * (a / 2.0 + dt * jerk / 6.0)),
        velocity: v + dt * (a + dt * jerk / 2.0),
        acceleration: a + dt * jerk,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> Limits {
        Limits::new(2.0, 10.0, 100.0)
    }

    #[test]
    fn velocity_change_regimes() {
        // A²/J = 1: a change of 3 holds A for 3/10 − 10/100 = 0.2 s.
        let c = VelocityChange::new(3.0, 10.0, 100.0);
        assert!((c.ramp - 0.1).abs() < 1e-15 && (c.hold - 0.2).abs() < 1e-15);
        // A change of 0.25 < A²/J: triangle of ramps sqrt(0.25/100) = 0.05, peak 5.
        let c = VelocityChange::new(-0.25, 10.0, 100.0);
        assert!((c.ramp - 0.05).abs() < 1e-15 && c.hold == 0.0);
        assert!((c.peak_acceleration - 5.0).abs() < 1e-12);
    }

    #[test]
    fn profile_ends_on_target_in_every_regime() {
        for length in [0.0, 1e-6, 0.01, 0.2, 0.5, 3.0, 10.0] {
            for sign in [1.0, -1.0] {
                let p = Profile::rest_to_rest(sign * length, &limits());
                let end = p.state(p.duration());
                assert_eq!(end.position, sign * length);
                // The integrated phases land within rounding of the target as well.
                let integrated = advance(p.states[6], p.jerks[6], p.durations[6]);
                assert!((integrated.position - sign * length).abs() < 1e-12 * (1.0 + length));
                assert!(integrated.velocity.abs() < 1e-12 && integrated.acceleration.abs() < 1e-9);
            }
        }
    }

    #[test]
    fn plan_with_boundary_velocities_is_continuous_and_exact() {
        let l = limits();
        let p = Profile::plan(1.0, 0.5, 1.5, &l).unwrap();
        assert!((p.state(0.0).velocity - 0.5).abs() < 1e-15);
        let integrated = advance(p.states[6], p.jerks[6], p.durations[6]);
        assert!((integrated.position - 1.0).abs() < 1e-12);
        assert!((integrated.velocity - 1.5).abs() < 1e-12);
        // Infeasible: cannot stop from V = 2 within a millimetre.
        assert!(Profile::plan(1e-3, 2.0, 0.0, &l).is_none());
        // Velocity above the limit.
        assert!(Profile::plan(1.0, 2.5, 0.0, &l).is_none());
    }

    #[test]
    fn largest_at_most_brackets_from_below() {
        // x³ = 2 on [0, 2]: the answer is the largest float with x³ ≤ 2.
        let x = largest_at_most(|x| x * x * x, 2.0, 0.0, 2.0);
        assert!(x * x * x <= 2.0);
        assert!((x - 2f64.cbrt()).abs() < 1e-15);
        // A function with a kink and a flat part.
        let x = largest_at_most(|x: f64| (x - 1.0).max(0.0).sqrt(), 0.5, 0.0, 10.0);
        assert!((x - 1.25).abs() < 1e-14 && (x - 1.0).max(0.0).sqrt() <= 0.5);
    }

    #[test]
    fn reachable_velocity_closed_form_matches_the_search() {
        let mut worst: f64 = 0.0;
        for &(v, a, j) in &[
            (2.0, 10.0, 100.0),
            (0.2, 2.0, 50.0),
            (0.2, 2.0, 1e8),
            (1.0, 0.1, 0.05),
        ] {
            let l = Limits::new(v, a, j);
            for k in 0..200 {
                let v0 = v * (k % 10) as f64 / 10.0;
                let d = 1e-6 * 1.13f64.powi(k);
                let fast = reachable_velocity(v0, d, &l);
                let slow = largest_at_most(|x| transfer_distance(v0, x, a, j), d, v0, v);
                let slow = if transfer_distance(v0, v, a, j) <= d {
                    v
                } else {
                    slow
                };
                assert!(transfer_distance(v0, fast, a, j) <= d, "{v0} {d}");
                worst = worst.max((fast - slow).abs() / v);
            }
        }
        assert!(worst < 1e-12, "{worst}");
    }

    #[test]
    fn peak_search_matches_the_bracketing_search() {
        let l = Limits::new(2.0, 10.0, 100.0);
        let mut worst: f64 = 0.0;
        for k in 0..400 {
            let (v0, v1) = (0.05 * (k % 20) as f64, 0.07 * (k / 20) as f64);
            let length = transfer_distance(v0.min(v1), v0.max(v1), 10.0, 100.0)
                * (1.0 + 0.05 * (k % 7) as f64)
                + 1e-4 * (k % 5) as f64;
            let covered = |p: f64| {
                VelocityChange::new(p - v0, 10.0, 100.0).distance(v0, p)
                    + VelocityChange::new(p - v1, 10.0, 100.0).distance(p, v1)
            };
            let lowest = v0.max(v1);
            if covered(2.0) <= length {
                continue;
            }
            let fast = peak_within(length, v0, v1, lowest, &l);
            let slow = largest_at_most(covered, length, lowest, 2.0);
            assert!(covered(fast) <= length);
            worst = worst.max((fast - slow).abs());
        }
        assert!(worst < 1e-12, "{worst}");
    }

    #[test]
    fn reachable_velocity_matches_transfer_distance() {
        let l = limits();
        let d = transfer_distance(0.3, 1.1, l.acceleration, l.jerk);
        let v = reachable_velocity(0.3, d, &l);
        assert!((v - 1.1).abs() < 1e-12, "{v}");
        assert_eq!(reachable_velocity(0.0, 100.0, &l), 2.0);
    }
}
