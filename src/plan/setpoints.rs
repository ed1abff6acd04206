//! The planner's output: a setpoint stream at the servo period, per machine axis.

/// Setpoints sampled at a fixed period, row-major: sample `k` of axis `i` is at `k * axes + i`.
/// Units are SI per axis (m for linear axes, rad for rotary ones).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Setpoints {
    /// Sample period T (s). Sample k is at time k·T.
    pub period: f64,
    /// Number of machine axes per sample.
    pub axes: usize,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub acceleration: Vec<f64>,
    /// Index of the program move each sample belongs to (for contour metrics and reports).
    pub segment: Vec<u32>,
}

impl Setpoints {
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

    pub fn position(&self, k: usize) -> &[f64] {
        &self.position[k * self.axes..(k + 1) * self.axes]
    }

    pub fn velocity(&self, k: usize) -> &[f64] {
        &self.velocity[k * self.axes..(k + 1) * self.axes]
    }

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
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
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
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Writes the next sample into `out` (whose vectors have `axes()` entries); `false` once
    /// all `len()` samples have been read.
    fn next_sample(&mut self, out: &mut SetpointSample) -> bool;
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
