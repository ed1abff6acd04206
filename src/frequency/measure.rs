//! The stepped-sine measurement on a plant through the servo loop: the excitation (a setpoint
//! stream, or a signal added to the controller output), the samples it records, and the
//! transfer functions estimated from them.

use super::estimate::{h1, Segment};
use super::linear::C64;
use crate::control::{Controller, ControllerInput};
use crate::plan::{SetpointSample, SetpointStream, Setpoints};
use crate::sim::{self, Lane, LoopSettings, Observer, Stop, TickRecord};
use std::f64::consts::TAU;

/// Where the excitation enters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Injection {
    /// Added to the controller output of the axis (the plant input).
    ControllerOutput,
    /// The position setpoint of the axis (sine about where it starts).
    PositionSetpoint,
    /// The velocity setpoint of the axis (cosine; the position setpoint is its integral).
    VelocitySetpoint,
}

/// A stepped-sine excitation of one axis; the other axes hold where the machine starts.
#[derive(Debug, Clone, PartialEq)]
pub struct Excitation {
    /// Index of the excited axis, in the machine's axis order.
    pub axis: usize,
    /// Where the excitation enters.
    pub injection: Injection,
    /// Amplitude in the units of what is excited (command units, m or rad, m/s or rad/s).
    pub amplitude: f64,
    /// The sweep's frequencies, in the order they are run.
    pub segments: Vec<Segment>,
    /// Where every axis starts and holds (joint units).
    pub start: Vec<f64>,
    /// Servo period (s): one tick of the sweep.
    pub period: f64,
}

impl Excitation {
    /// Ticks of the whole sweep.
    pub fn len(&self) -> usize {
        self.segments.iter().map(Segment::len).sum()
    }

    /// Whether the sweep has no ticks.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The segment tick `k` belongs to and the tick within it.
    fn locate(&self, mut k: usize) -> Option<(&Segment, usize)> {
        for s in &self.segments {
            if k < s.len() {
                return Some((s, k));
            }
            k -= s.len();
        }
        None
    }

    /// The excitation signal at tick `k` (zero past the end): a·sin(ωt') for the controller
    /// output and the position setpoint, a·cos(ωt') for the velocity setpoint, t' the time
    /// since the segment started. Segments are whole periods, so the signal is continuous.
    pub fn signal(&self, k: usize) -> f64 {
        let Some((s, i)) = self.locate(k) else {
            return 0.0;
        };
        let phase = TAU * s.periods as f64 * (i % s.block) as f64 / s.block as f64;
        match self.injection {
            Injection::VelocitySetpoint => self.amplitude * phase.cos(),
            _ => self.amplitude * phase.sin(),
        }
    }

    /// The setpoint sample at tick `k`.
    fn setpoint(&self, k: usize, out: &mut SetpointSample) {
        out.position.copy_from_slice(&self.start);
        out.velocity.iter_mut().for_each(|v| *v = 0.0);
        out.acceleration.iter_mut().for_each(|v| *v = 0.0);
        let Some((s, i)) = self.locate(k) else {
            return;
        };
        let w = TAU * s.frequency;
        let phase = TAU * s.periods as f64 * (i % s.block) as f64 / s.block as f64;
        let (sin, cos) = phase.sin_cos();
        let a = self.amplitude;
        let (x, v, acc) = match self.injection {
            Injection::ControllerOutput => return,
            Injection::PositionSetpoint => (a * sin, a * w * cos, -a * w * w * sin),
            Injection::VelocitySetpoint => (a / w * sin, a * cos, -a * w * sin),
        };
        out.position[self.axis] += x;
        out.velocity[self.axis] = v;
        out.acceleration[self.axis] = acc;
        out.segment = 0;
    }

    /// The excitation as a setpoint stream.
    pub fn stream(&self) -> ExcitationStream<'_> {
        ExcitationStream {
            excitation: self,
            next: 0,
        }
    }
}

/// The setpoints of an [`Excitation`], computed as they are read.
pub struct ExcitationStream<'a> {
    excitation: &'a Excitation,
    next: usize,
}

impl SetpointStream for ExcitationStream<'_> {
    fn axes(&self) -> usize {
        self.excitation.start.len()
    }

    fn period(&self) -> f64 {
        self.excitation.period
    }

    fn len(&self) -> usize {
        self.excitation.len()
    }

    fn next_sample(&mut self, out: &mut SetpointSample) -> bool {
        if self.next >= self.len() {
            return false;
        }
        self.excitation.setpoint(self.next, out);
        self.next += 1;
        true
    }
}

/// A controller with the excitation added to one axis's output during the sweep (after its
/// own limit: the plant input is what the amplifier gets).
pub struct Injected<'a> {
    /// The controller whose output the excitation is added to.
    pub inner: Box<dyn Controller + 'a>,
    /// The excitation added to its output on `excitation.axis`.
    pub excitation: &'a Excitation,
    /// Ticks from the start of the loop (settle included) to the sweep's first tick.
    pub lead_in: usize,
    tick: usize,
}

impl<'a> Injected<'a> {
    /// `inner` with `excitation` added once the sweep starts, `lead_in` ticks after the loop
    /// starts.
    pub fn new(
        inner: Box<dyn Controller + 'a>,
        excitation: &'a Excitation,
        lead_in: usize,
    ) -> Self {
        Injected {
            inner,
            excitation,
            lead_in,
            tick: 0,
        }
    }
}

impl Controller for Injected<'_> {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        self.inner.update(input, command);
        if let Some(k) = self.tick.checked_sub(self.lead_in) {
            command[self.excitation.axis] += self.excitation.signal(k);
        }
        self.tick += 1;
    }

    fn reset(&mut self) {
        self.inner.reset();
        self.tick = 0;
    }
}

/// What the sweep recorded of the excited axis, one entry per program tick.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Samples {
    /// The excitation signal.
    pub excitation: Vec<f64>,
    /// The plant input (controller output plus any injection), command units.
    pub command: Vec<f64>,
    /// The position loop's feedback device (after the encoder), joint units.
    pub feedback: Vec<f64>,
    /// The motor encoder (drive side), joint units.
    pub motor: Vec<f64>,
    /// The controller output alone (command minus injection).
    pub controller: Vec<f64>,
}

struct Recorder<'a> {
    excitation: &'a Excitation,
    samples: Samples,
    stop: Option<Stop>,
}

impl Observer for Recorder<'_> {
    fn tick(&mut self, lane: usize, r: &TickRecord<'_>) {
        if lane != 0 {
            return;
        }
        let a = self.excitation.axis;
        let e = self.excitation.signal(r.k);
        let s = &mut self.samples;
        s.excitation.push(e);
        s.command.push(r.command[a]);
        s.feedback.push(r.measured[a]);
        s.motor.push(r.motor[a]);
        s.controller.push(match self.excitation.injection {
            Injection::ControllerOutput => r.command[a] - e,
            _ => r.command[a],
        });
    }

    fn stopped(&mut self, lane: usize, stop: &Stop) {
        if lane == 0 {
            self.stop = Some(stop.clone());
        }
    }
}

/// Runs the sweep through the servo loop on `lane` (its controller already wrapped in
/// [`Injected`] for [`Injection::ControllerOutput`]). `settings` are the scenario's; the
/// machine settles at `excitation.start` for their settle time before the sweep.
pub fn run_sweep(
    settings: &LoopSettings,
    lane: Lane<'_>,
    excitation: &Excitation,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> (Samples, Option<Stop>) {
    let settings = LoopSettings {
        approach: Setpoints::new(settings.servo_period, excitation.start.len()),
        ..settings.clone()
    };
    let mut recorder = Recorder {
        excitation,
        samples: Samples::default(),
        stop: None,
    };
    let mut lanes = [lane];
    sim::run(
        &settings,
        &mut lanes,
        &mut excitation.stream(),
        &mut recorder,
        progress,
    );
    (recorder.samples, recorder.stop)
}

/// Ticks the loop runs before the sweep's first tick (the settle).
pub fn lead_in(settings: &LoopSettings) -> usize {
    (settings.settle_time / settings.servo_period).round() as usize
}

/// The transfer functions estimated at one frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The segment's excitation frequency (Hz).
    pub frequency: f64,
    /// The closed loop excitation → response (position loop: x_fb/r; velocity loop: v/v_cmd;
    /// controller output: the complementary sensitivity L/(1 + L) = −c/d).
    pub closed: C64,
    /// From an injection at the controller output: the plant u → x_fb and u → x_motor and the
    /// open loop L = −c/u; `None` for a setpoint sweep.
    pub plant_feedback: Option<C64>,
    /// The plant from its input to the motor encoder, u → x_motor; `None` for a setpoint sweep.
    pub plant_motor: Option<C64>,
    /// The open loop L = −c/u broken at the plant input; `None` for a setpoint sweep.
    pub open: Option<C64>,
    /// Coherence of the response with the excitation.
    pub coherence: f64,
    /// Largest |plant input| over the measured blocks (command units).
    pub peak_command: f64,
}

/// The estimates of every segment of a recorded sweep (samples from the sweep's first tick).
pub fn estimates(excitation: &Excitation, samples: &Samples) -> Vec<Estimate> {
    let mut out = Vec::new();
    let mut offset = 0;
    for s in &excitation.segments {
        let from = offset + s.block * s.settle_blocks;
        let to = offset + s.len();
        offset = to;
        if to > samples.excitation.len() {
            break;
        }
        let e = &samples.excitation[from..to];
        let w = TAU * s.frequency;
        let peak_command = samples.command[from..to]
            .iter()
            .fold(0.0f64, |m, u| m.max(u.abs()));
        let estimate = match excitation.injection {
            Injection::ControllerOutput => {
                let (du, _) = h1(e, &samples.command[from..to], s);
                let (dy, coherence) = h1(e, &samples.feedback[from..to], s);
                let (dm, _) = h1(e, &samples.motor[from..to], s);
                let (dc, _) = h1(e, &samples.controller[from..to], s);
                Estimate {
                    frequency: s.frequency,
                    closed: -dc,
                    plant_feedback: Some(dy / du),
                    plant_motor: Some(dm / du),
                    open: Some(-dc / du),
                    coherence,
                    peak_command,
                }
            }
            Injection::PositionSetpoint => {
                let (h, coherence) = h1(e, &samples.feedback[from..to], s);
                Estimate {
                    frequency: s.frequency,
                    closed: h,
                    plant_feedback: None,
                    plant_motor: None,
                    open: None,
                    coherence,
                    peak_command,
                }
            }
            Injection::VelocitySetpoint => {
                let (h, coherence) = h1(e, &samples.motor[from..to], s);
                Estimate {
                    frequency: s.frequency,
                    closed: C64::new(0.0, w) * h,
                    plant_feedback: None,
                    plant_motor: None,
                    open: None,
                    coherence,
                    peak_command,
                }
            }
        };
        out.push(estimate);
    }
    out
}
