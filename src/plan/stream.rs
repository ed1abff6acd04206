//! Setpoint streams computed as they are read: a program's stretches (timed motions and
//! dwells) are planned first, so the number of samples is known before the first one, and
//! each sample is evaluated from its stretch when the loop asks for it. Memory grows with the
//! number of moves, never with the number of servo ticks; a jerk-limited motion keeps the plan
//! of one window of its moves at a time ([`PlanWindows`]).

use super::planner::PlanWindows;
use super::setpoints::{sample_time, LookAhead, SetpointSample, SetpointStream, Setpoints};
use super::trapezoid::TrapezoidProfile;

/// One stretch of a program's setpoints. Its sample 0 is where the previous stretch ended (or
/// the program start); samples `1..=ticks` follow at the servo period.
pub(super) enum Stretch<'a> {
    /// The start of the program, alone: one sample at rest.
    Start { at: Vec<f64>, segment: u32 },
    /// Holding still at `at` (a dwell).
    Hold {
        at: Vec<f64>,
        segment: u32,
        ticks: usize,
    },
    /// A jerk-limited motion planned window by window as it is read.
    Windows {
        plan: Box<PlanWindows<'a>>,
        ticks: usize,
    },
    /// A stretch read to its end, its plan let go.
    Finished,
    /// A straight move with the seed trapezoidal profile.
    Trapezoid {
        from: Vec<f64>,
        to: Vec<f64>,
        profile: TrapezoidProfile,
        segment: u32,
        ticks: usize,
    },
}

impl Stretch<'_> {
    /// Samples after sample 0.
    pub fn ticks(&self) -> usize {
        match self {
            Stretch::Start { .. } | Stretch::Finished => 0,
            Stretch::Hold { ticks, .. }
            | Stretch::Windows { ticks, .. }
            | Stretch::Trapezoid { ticks, .. } => *ticks,
        }
    }

    /// Writes sample `k` (called with increasing `k`).
    fn sample(&mut self, k: usize, period: f64, out: &mut SetpointSample) {
        match self {
            // Never sampled (sample 0 of the next stretch is its last).
            Stretch::Finished => {}
            Stretch::Start { at, segment } | Stretch::Hold { at, segment, .. } => {
                out.position.copy_from_slice(at);
                out.velocity.fill(0.0);
                out.acceleration.fill(0.0);
                out.segment = *segment;
            }
            Stretch::Windows { plan, ticks } => {
                let t = sample_time(k, *ticks, plan.duration(), period);
                out.segment = plan.eval(
                    t,
                    &mut out.position,
                    &mut out.velocity,
                    &mut out.acceleration,
                );
            }
            Stretch::Trapezoid {
                from,
                to,
                profile,
                segment,
                ticks,
            } => {
                let t = sample_time(k, *ticks, profile.duration(), period);
                let (s, sd, sdd) = profile.state(t);
                let length = profile.distance;
                let done = t >= profile.duration();
                for i in 0..from.len() {
                    let share = if length > 0.0 {
                        (to[i] - from[i]) / length
                    } else {
                        0.0
                    };
                    // Interpolated from the start (no accumulated increments); the last sample
                    // is the programmed end itself.
                    out.position[i] = if done { to[i] } else { from[i] + share * s };
                    out.velocity[i] = share * sd;
                    out.acceleration[i] = share * sdd;
                }
                out.segment = *segment;
            }
        }
    }
}

/// Stretches played one after the other, each from where the previous one ended.
pub(super) struct StretchStream<'a> {
    axes: usize,
    period: f64,
    stretches: Vec<Stretch<'a>>,
    len: usize,
    /// What the planner's look-ahead did, over all stretches.
    look_ahead: LookAhead,
    /// The stretch being read, and its next sample.
    current: usize,
    k: usize,
}

impl<'a> StretchStream<'a> {
    /// The stream of `stretches`; the first must be a `Start` (the rest drop their sample 0).
    pub fn new(axes: usize, period: f64, stretches: Vec<Stretch<'a>>) -> Self {
        let len = 1 + stretches.iter().map(Stretch::ticks).sum::<usize>();
        let mut look_ahead = LookAhead::default();
        for stretch in &stretches {
            if let Stretch::Windows { plan, .. } = stretch {
                look_ahead += plan.look_ahead();
            }
        }
        StretchStream {
            axes,
            period,
            stretches,
            len,
            look_ahead,
            current: 0,
            k: 0,
        }
    }
}

impl SetpointStream for StretchStream<'_> {
    fn axes(&self) -> usize {
        self.axes
    }

    fn period(&self) -> f64 {
        self.period
    }

    fn len(&self) -> usize {
        self.len
    }

    fn look_ahead(&self) -> LookAhead {
        self.look_ahead
    }

    fn next_sample(&mut self, out: &mut SetpointSample) -> bool {
        while let Some(stretch) = self.stretches.get_mut(self.current) {
            if self.k <= stretch.ticks() {
                stretch.sample(self.k, self.period, out);
                self.k += 1;
                return true;
            }
            // Its samples are all read: what it holds (a window's plan, its path) goes.
            *stretch = Stretch::Finished;
            self.current += 1;
            self.k = 1;
        }
        false
    }
}

/// Reads a whole stream into memory.
pub fn collect(stream: &mut dyn SetpointStream) -> Setpoints {
    let n = stream.axes();
    let mut out = Setpoints::new(stream.period(), n);
    let len = stream.len();
    out.position.reserve(len * n);
    out.velocity.reserve(len * n);
    out.acceleration.reserve(len * n);
    out.segment.reserve(len);
    let mut sample = SetpointSample::zeros(n);
    while stream.next_sample(&mut sample) {
        out.push(
            &sample.position,
            &sample.velocity,
            &sample.acceleration,
            sample.segment,
        );
    }
    out
}
