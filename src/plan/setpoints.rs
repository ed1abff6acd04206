//! The planner's output: a setpoint stream at the servo period, per machine axis.

/// Most setpoint samples one plan may have: 10⁸, a program of 27.8 hours at a 1 ms servo
/// period. Every planner counts the samples a plan needs from the move timings before it
/// samples anything, and refuses a longer plan ([`super::PlanError::TooManySamples`]), so that
/// a tiny feed or limit cannot make a run take forever or exhaust memory.
pub const MAX_SETPOINT_SAMPLES: usize = 100_000_000;

/// Number of samples of a motion lasting `duration` at `period` (`sample_times`), or `Err`
/// with the number it would need (as a float: it may exceed any integer) when that is more
/// than [`MAX_SETPOINT_SAMPLES`].
pub fn sample_count(duration: f64, period: f64) -> Result<usize, f64> {
    let needed = ticks(duration, period) + 1.0;
    if needed <= MAX_SETPOINT_SAMPLES as f64 {
        Ok(needed as usize)
    } else {
        Err(needed)
    }
}

/// Whole periods up to the first tick at or after `duration` (a tick within rounding of the end
/// counts as the end: 2.5 s at 4 ms is 625 ticks, not 626). Not finite for a non-finite ratio.
fn ticks(duration: f64, period: f64) -> f64 {
    let ticks = (duration / period * (1.0 - 1e-12)).ceil().max(0.0);
    if ticks.is_nan() {
        f64::INFINITY
    } else {
        ticks
    }
}

/// Sample times 0, T, 2T, … up to the first tick at or after `duration` (at least one sample),
/// the last one at the end or later, so that the last sample is exactly on the target. Only
/// for motions whose [`sample_count`] is within the limit.
pub(super) fn sample_times(duration: f64, period: f64) -> impl Iterator<Item = f64> {
    let ticks = ticks(duration, period).min(MAX_SETPOINT_SAMPLES as f64) as usize;
    (0..=ticks).map(move |k| sample_time(k, ticks, duration, period))
}

/// Time of sample `k` of `ticks + 1` (`sample_times`).
pub(super) fn sample_time(k: usize, ticks: usize, duration: f64, period: f64) -> f64 {
    if k == ticks {
        (k as f64 * period).max(duration)
    } else {
        k as f64 * period
    }
}

/// Setpoints sampled at a fixed period, row-major: sample `k` of axis `i` is at `k * axes + i`.
/// Units are SI per axis (m for linear axes, rad for rotary ones).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Setpoints {
    /// Sample period T (s). Sample k is at time k·T.
    pub period: f64,
    /// Number of machine axes per sample.
    pub axes: usize,
    /// Positions, row-major (m, or rad on a rotary axis).
    pub position: Vec<f64>,
    /// Velocities, row-major (m/s, or rad/s on a rotary axis).
    pub velocity: Vec<f64>,
    /// Accelerations, row-major (m/s², or rad/s² on a rotary axis).
    pub acceleration: Vec<f64>,
    /// Index of the program move each sample belongs to (for contour metrics and reports).
    pub segment: Vec<u32>,
}

impl Setpoints {
    /// No samples yet, at period `period` (s) on `axes` machine axes.
    pub fn new(period: f64, axes: usize) -> Self {
        Setpoints {
            period,
            axes,
            ..Default::default()
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.segment.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.segment.is_empty()
    }

    /// Appends one sample; the slices must have `axes` entries.
    pub fn push(&mut self, position: &[f64], velocity: &[f64], acceleration: &[f64], segment: u32) {
        debug_assert_eq!(position.len(), self.axes);
        self.position.extend_from_slice(position);
        self.velocity.extend_from_slice(velocity);
        self.acceleration.extend_from_slice(acceleration);
        self.segment.push(segment);
    }

    /// Position of sample `k`, one entry per axis (m, or rad on a rotary axis).
    pub fn position(&self, k: usize) -> &[f64] {
        &self.position[k * self.axes..(k + 1) * self.axes]
    }

    /// Velocity of sample `k`, one entry per axis (m/s, or rad/s on a rotary axis).
    pub fn velocity(&self, k: usize) -> &[f64] {
        &self.velocity[k * self.axes..(k + 1) * self.axes]
    }

    /// Acceleration of sample `k`, one entry per axis (m/s², or rad/s² on a rotary axis).
    pub fn acceleration(&self, k: usize) -> &[f64] {
        &self.acceleration[k * self.axes..(k + 1) * self.axes]
    }

    /// Appends a stream that starts where this one ends, dropping its first sample (the
    /// shared point). An empty `self` takes all of `next`.
    pub fn append_continuing(&mut self, next: &Setpoints) {
        debug_assert_eq!(self.axes, next.axes);
        let skip = usize::from(!self.is_empty()).min(next.len());
        let n = self.axes;
        self.position.extend_from_slice(&next.position[skip * n..]);
        self.velocity.extend_from_slice(&next.velocity[skip * n..]);
        self.acceleration
            .extend_from_slice(&next.acceleration[skip * n..]);
        self.segment.extend_from_slice(&next.segment[skip..]);
    }

    /// Holds the last position at rest for `ticks` more samples (a dwell).
    pub fn hold(&mut self, ticks: usize, segment: u32) {
        if self.is_empty() {
            return;
        }
        let last = self.position(self.len() - 1).to_vec();
        let zeros = vec![0.0; self.axes];
        for _ in 0..ticks {
            self.push(&last, &zeros, &zeros, segment);
        }
    }

    /// Time of the last sample (s).
    pub fn duration(&self) -> f64 {
        self.len().saturating_sub(1) as f64 * self.period
    }
}

/// One setpoint sample per machine axis (SI), as the co-simulation loop reads it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SetpointSample {
    /// Position per axis (m, or rad on a rotary axis).
    pub position: Vec<f64>,
    /// Velocity per axis (m/s, or rad/s on a rotary axis).
    pub velocity: Vec<f64>,
    /// Acceleration per axis (m/s², or rad/s² on a rotary axis).
    pub acceleration: Vec<f64>,
    /// Index of the program move the sample belongs to.
    pub segment: u32,
}

impl SetpointSample {
    /// A sample of `axes` zeros.
    pub fn zeros(axes: usize) -> Self {
        SetpointSample {
            position: vec![0.0; axes],
            velocity: vec![0.0; axes],
            acceleration: vec![0.0; axes],
            segment: 0,
        }
    }
}

/// A setpoint stream at the servo period: what the co-simulation loop consumes, one sample per
/// tick. Its length is known before the first sample (every move is timed before any is
/// sampled), so the work of a run is bounded before it starts; the samples themselves may be
/// computed as they are read, so memory need not grow with the program's duration.
pub trait SetpointStream {
    /// Machine axes per sample.
    fn axes(&self) -> usize;
    /// Sample period T (s); sample k is at time k·T.
    fn period(&self) -> f64;
    /// Number of samples the stream yields in all.
    fn len(&self) -> usize;
    /// Whether the stream yields no samples at all.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Writes the next sample into `out` (whose vectors have `axes()` entries); `false` once
    /// all `len()` samples have been read.
    fn next_sample(&mut self, out: &mut SetpointSample) -> bool;
    /// What the jerk-limited planner's look-ahead did with chains longer than it (nothing for
    /// other planners).
    fn look_ahead(&self) -> LookAhead {
        LookAhead::default()
    }
}

/// How the jerk-limited planner's look-ahead of
/// [`LOOKAHEAD_SEGMENTS`](super::planner::LOOKAHEAD_SEGMENTS) blocks passed chains longer than
/// it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LookAhead {
    /// Handoffs between windows while moving.
    pub handoffs: usize,
    /// Of those, the ones made more slowly than the window before planned, at the speed the
    /// next window admits.
    pub slowed: usize,
    /// Stops the look-ahead added where no handoff could be made (at a window's last
    /// programmed point; the program asks for none there).
    pub stops_added: usize,
}

impl LookAhead {
    /// A line for reports; `None` when no chain was longer than the look-ahead.
    pub fn summary(&self) -> Option<String> {
        (*self != LookAhead::default()).then(|| {
            let slowed = if self.slowed > 0 {
                format!(" ({} slowed to what the next window admits)", self.slowed)
            } else {
                String::new()
            };
            format!(
                "look-ahead {} blocks: {} inside longer chains{slowed}, {} added where no \
                 handoff could be made",
                super::planner::LOOKAHEAD_SEGMENTS,
                counted(self.handoffs, "handoff"),
                counted(self.stops_added, "stop")
            )
        })
    }

    /// A warning when the look-ahead made the motion stop where the program does not ask it to.
    pub fn warning(&self) -> Option<String> {
        (self.stops_added > 0).then(|| {
            format!(
                "the planner's look-ahead ({} blocks) added {} inside chains longer than it, \
                 where no handoff to the next window could be made: the cycle time and the \
                 motion there are not those of a continuous pass",
                super::planner::LOOKAHEAD_SEGMENTS,
                counted(self.stops_added, "stop")
            )
        })
    }
}

/// `n` and the noun, plural but for one.
fn counted(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

impl std::ops::AddAssign for LookAhead {
    fn add_assign(&mut self, other: LookAhead) {
        self.handoffs += other.handoffs;
        self.slowed += other.slowed;
        self.stops_added += other.stops_added;
    }
}

/// Reads a materialised [`Setpoints`] as a stream.
#[derive(Debug, Clone)]
pub struct SetpointCursor<'a> {
    setpoints: &'a Setpoints,
    next: usize,
}

impl Setpoints {
    /// This setpoint list as a stream, from its first sample.
    pub fn stream(&self) -> SetpointCursor<'_> {
        SetpointCursor {
            setpoints: self,
            next: 0,
        }
    }
}

impl SetpointStream for SetpointCursor<'_> {
    fn axes(&self) -> usize {
        self.setpoints.axes
    }

    fn period(&self) -> f64 {
        self.setpoints.period
    }

    fn len(&self) -> usize {
        self.setpoints.len()
    }

    fn next_sample(&mut self, out: &mut SetpointSample) -> bool {
        let s = self.setpoints;
        let k = self.next;
        if k >= s.len() {
            return false;
        }
        out.position.copy_from_slice(s.position(k));
        out.velocity.copy_from_slice(s.velocity(k));
        out.acceleration.copy_from_slice(s.acceleration(k));
        out.segment = s.segment[k];
        self.next += 1;
        true
    }
}

/// The first `limit` samples of a stream.
pub struct FirstSamples<S> {
    stream: S,
    left: usize,
    len: usize,
}

impl<S: SetpointStream> FirstSamples<S> {
    /// `stream` cut to at most `limit` samples.
    pub fn new(stream: S, limit: usize) -> Self {
        let len = stream.len().min(limit);
        FirstSamples {
            stream,
            left: len,
            len,
        }
    }
}

impl<S: SetpointStream> SetpointStream for FirstSamples<S> {
    fn axes(&self) -> usize {
        self.stream.axes()
    }

    fn period(&self) -> f64 {
        self.stream.period()
    }

    fn len(&self) -> usize {
        self.len
    }

    fn next_sample(&mut self, out: &mut SetpointSample) -> bool {
        if self.left == 0 {
            return false;
        }
        self.left -= 1;
        self.stream.next_sample(out)
    }

    fn look_ahead(&self) -> LookAhead {
        self.stream.look_ahead()
    }
}

impl<T: SetpointStream + ?Sized> SetpointStream for Box<T> {
    fn axes(&self) -> usize {
        (**self).axes()
    }

    fn period(&self) -> f64 {
        (**self).period()
    }

    fn len(&self) -> usize {
        (**self).len()
    }

    fn next_sample(&mut self, out: &mut SetpointSample) -> bool {
        (**self).next_sample(out)
    }

    fn look_ahead(&self) -> LookAhead {
        (**self).look_ahead()
    }
}

#[cfg(test)]
mod tests {
    use super::LookAhead;

    #[test]
    fn look_ahead_reports_only_what_happened() {
        assert_eq!(LookAhead::default().summary(), None);
        assert_eq!(LookAhead::default().warning(), None);
        let handed = LookAhead {
            handoffs: 3,
            ..LookAhead::default()
        };
        assert_eq!(
            handed.summary().as_deref(),
            Some(
                "look-ahead 4096 blocks: 3 handoffs inside longer chains, 0 stops added where \
                 no handoff could be made"
            )
        );
        assert_eq!(handed.warning(), None);
        let stopped = LookAhead {
            handoffs: 2,
            slowed: 1,
            stops_added: 2,
        };
        let warning = stopped.warning().unwrap();
        assert!(warning.contains("added 2 stops"), "{warning}");
        let summary = stopped.summary().unwrap();
        assert!(
            summary.contains(
                "2 handoffs inside longer chains (1 slowed to what the next window admits)"
            ),
            "{summary}"
        );
    }
}
