//! The co-simulation loop, written once. Read it as a block diagram sampled at the servo
//! period T:
//!
//!   setpoints ─▶ (+) ─▶ controller ─▶ hold ─▶ plant ─┐
//!                 ▲ −                                │
//!                 └── encoder ◀── trip ◀── sensors ◀─┘
//!
//! Every period each lane samples its plant's sensors, checks them (divergence, the drive's
//! following-error trip), quantises the feedback (encoder), runs its controller once and holds
//! the command over the period while the plant advances. The program's spindle speed is the
//! plant's second input, set before each period: a plant that cuts (the cutting process is a
//! block inside it, stepped at the physics step) turns its tool at that speed, and a plant
//! that cannot go on (the tool in the stock with the spindle stopped) stops its lane. A run has
//! one or more lanes on the same setpoint stream in lockstep: the Rapier machine
//! ([`PhysicsPlant`]) and, beside it, the analytic reference model ([`AnalyticPlant`]), each
//! with its own controller instance, so the two are compared sample by sample. What happens is
//! handed, tick by tick, to an [`Observer`] (metrics, CSV, recording, an in-memory [`Trace`]):
//! nothing per tick is kept here, so memory does not grow with the program's length.

pub mod analytic;
mod blocks;
pub mod cut;
mod physics;
mod plant;
mod trace;

pub use analytic::AnalyticPlant;
pub use blocks::{Encoder, FollowingErrorTrip};
pub use physics::PhysicsPlant;
pub use plant::{CutRecord, Hold, Plant, Sensors};
pub use trace::{Trace, TraceRecorder};

use crate::control::{Controller, ControllerInput};
use crate::plan::{SetpointSample, SetpointStream, Setpoints};
use std::time::Instant;

/// Most servo ticks one run may take (settle included): a four-hour program at a 1 ms servo
/// period is 1.44·10⁷; beyond 10⁸ a run is a mistake (a feed or a period off by orders of
/// magnitude), and is refused before it starts with the number it would need.
pub const MAX_SERVO_TICKS: u64 = 100_000_000;
/// Most physics steps one run may take (ticks × steps per tick).
pub const MAX_PHYSICS_STEPS: u64 = 1_000_000_000;

/// Ticks between two progress reports (and checks for an interruption).
const PROGRESS_EVERY: usize = 1024;

/// How the loop runs; the same for every lane.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopSettings {
    /// Servo period T (s).
    pub servo_period: f64,
    /// The way the machine comes to the program's first point, run after the settle and not
    /// observed; the plants start at rest at its first sample. Empty: they start at the first
    /// setpoint.
    pub approach: Setpoints,
    /// Time the loop holds the machine at rest where it starts (the approach's first sample,
    /// or the program's) before it moves (s): the machine is enabled and in position before
    /// cycle start. Not observed.
    pub settle_time: f64,
    /// How the feedback is quantised before the controller sees it.
    pub encoder: Encoder,
    /// The drive's following-error limits, and the divergence check.
    pub trip: FollowingErrorTrip,
    /// The spindle speed of each program move (none: the spindle stands).
    pub spindle: Spindles,
}

/// The spindle speed the program commands during each of its moves, and the moves' lines.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Spindles {
    /// Per program move: rad/s, > 0 turning as M3, < 0 as M4, 0 stopped.
    pub speed: Vec<f64>,
    /// Per program move: its line in the program file.
    pub line: Vec<usize>,
}

impl Spindles {
    /// The speed during move `segment` (rad/s; 0 where none is known).
    pub fn speed_at(&self, segment: u32) -> f64 {
        self.speed.get(segment as usize).copied().unwrap_or(0.0)
    }

    /// The program line of move `segment`, where known.
    pub fn line_at(&self, segment: u32) -> Option<usize> {
        self.line.get(segment as usize).copied()
    }
}

/// What a lane simulates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LaneKind {
    /// The Rapier machine.
    Physics,
    /// The analytic per-axis models of the same machine (the reference).
    Analytic,
}

impl LaneKind {
    /// The lane's name in reports, recordings and CSV columns.
    pub fn name(self) -> &'static str {
        match self {
            LaneKind::Physics => "physics",
            LaneKind::Analytic => "analytic",
        }
    }
}

impl std::fmt::Display for LaneKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One plant with its own controller.
pub struct Lane<'a> {
    /// What the lane simulates.
    pub kind: LaneKind,
    /// The plant the lane advances.
    pub plant: Box<dyn Plant + 'a>,
    /// The lane's own controller instance.
    pub controller: Box<dyn Controller + 'a>,
}

/// Why a lane stopped before the end of its setpoints.
#[derive(Debug, Clone, PartialEq, thiserror::Error, serde::Serialize, serde::Deserialize)]
pub enum Stop {
    /// An axis's sampled position or velocity is no longer finite.
    #[error("simulation diverged at t = {time:.6} s on axis '{axis}': {what}")]
    Diverged {
        /// Program time (s).
        time: f64,
        /// The axis's name.
        axis: String,
        /// Which values were not finite.
        what: String,
    },
    /// The progress callback asked the run to stop (e.g. Ctrl-C).
    #[error("interrupted at t = {time:.6} s")]
    Interrupted {
        /// Program time (s).
        time: f64,
    },
    /// An axis's |setpoint − position| exceeded its following-error limit: the drive tripped.
    #[error("following-error fault at t = {time:.6} s on axis '{axis}': |error| = {error:.6e} exceeds the limit {limit:.6e}")]
    FollowingError {
        /// Program time (s).
        time: f64,
        /// The axis's name.
        axis: String,
        /// |setpoint − position| (joint units: m, or rad on a rotary axis).
        error: f64,
        /// The axis's limit (joint units).
        limit: f64,
    },
    /// The plant could not go on (e.g. its tool engaged the stock with the spindle stopped).
    #[error("{what} at t = {time:.6} s{}", line.map_or(String::new(), |l| format!(" (program line {l})")))]
    Plant {
        /// Program time (s).
        time: f64,
        /// The program line of the move under way, where known.
        line: Option<usize>,
        /// The plant's reason.
        what: String,
    },
    /// The controller could not compute its command (e.g. a controller FMU whose step
    /// failed).
    #[error("the controller failed at t = {time:.6} s: {what}")]
    Controller {
        /// Program time (s).
        time: f64,
        /// The controller's reason.
        what: String,
    },
}

impl Stop {
    /// When the stop happened (s, program time).
    pub fn time(&self) -> f64 {
        match self {
            Stop::Diverged { time, .. }
            | Stop::Interrupted { time }
            | Stop::FollowingError { time, .. }
            | Stop::Plant { time, .. }
            | Stop::Controller { time, .. } => *time,
        }
    }
}

/// One tick of one lane, as observers see it: the setpoint and the sensors sampled at the start
/// of the period, what the controller commanded and what the actuators did over the period.
#[derive(Debug, Clone, Copy)]
pub struct TickRecord<'a> {
    /// Tick index from program start (0 = the first setpoint).
    pub k: usize,
    /// Program time (s).
    pub time: f64,
    /// The setpoint of the tick (position, velocity, acceleration per axis).
    pub setpoint: &'a SetpointSample,
    /// The plant's sensors at the start of the period.
    pub sensors: &'a Sensors,
    /// Positions the controller saw (after the encoder): of the feedback device, and of the
    /// motor encoder.
    pub measured: &'a [f64],
    /// Motor-encoder (drive-side) positions the controller saw, after the encoder.
    pub motor: &'a [f64],
    /// Controller output (V at the amplifier input, or N·m).
    pub command: &'a [f64],
    /// What the actuators did over the period (mean torque, voltage, the cut's forces).
    pub hold: &'a Hold,
    /// The stock as the plant has cut it so far (plants that cut).
    pub stock: Option<&'a crate::cutting::Stock>,
}

/// Receives what the loop does, tick by tick (lanes in order within a tick).
pub trait Observer {
    /// Lane `lane` ran one program tick (settle and approach ticks are not observed).
    fn tick(&mut self, lane: usize, record: &TickRecord<'_>);
    /// Lane `lane` stopped early (the tick it stopped on was not observed when its state was
    /// not finite, and was observed with zero command after a following-error trip).
    fn stopped(&mut self, _lane: usize, _stop: &Stop) {}
}

/// Observes nothing (benchmarks, runs judged by their outcome alone).
pub struct Unobserved;

impl Observer for Unobserved {
    fn tick(&mut self, _lane: usize, _record: &TickRecord<'_>) {}
}

/// Several observers as one.
pub struct Observers<'o>(pub Vec<&'o mut dyn Observer>);

impl Observer for Observers<'_> {
    fn tick(&mut self, lane: usize, record: &TickRecord<'_>) {
        for o in &mut self.0 {
            o.tick(lane, record);
        }
    }

    fn stopped(&mut self, lane: usize, stop: &Stop) {
        for o in &mut self.0 {
            o.stopped(lane, stop);
        }
    }
}

/// How one lane ended.
#[derive(Debug, Clone, PartialEq)]
pub struct LaneOutcome {
    /// What the lane simulated.
    pub kind: LaneKind,
    /// Why the lane stopped early; `None` when it ran to the end of the run.
    pub stop: Option<Stop>,
    /// Integration steps the plant took (physics steps for Rapier).
    pub steps: u64,
}

/// The result of a run: how each lane ended and what it cost. The run ends with the end of its
/// setpoints or when the first lane (the primary plant) stops.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Outcome {
    /// Program ticks observed on the first lane.
    pub ticks: usize,
    /// How each lane ended, in lane order.
    pub lanes: Vec<LaneOutcome>,
    /// Wall-clock time the run took (s).
    pub wall_time: f64,
}

impl Outcome {
    /// Why the primary lane stopped early, if it did.
    pub fn stop(&self) -> Option<&Stop> {
        self.lanes.first().and_then(|l| l.stop.as_ref())
    }
}

/// Per-lane scratch, reused every tick (the loop allocates nothing per tick).
struct LaneState {
    sensors: Sensors,
    measured: Vec<f64>,
    motor: Vec<f64>,
    command: Vec<f64>,
    hold: Hold,
    stop: Option<Stop>,
}

/// Runs the lanes on the setpoint stream in lockstep. `progress(done, total)` is called every
/// `PROGRESS_EVERY` ticks (settle included); when it returns `false` the run stops there as
/// interrupted, keeping everything observed so far.
pub fn run(
    settings: &LoopSettings,
    lanes: &mut [Lane<'_>],
    setpoints: &mut dyn SetpointStream,
    observer: &mut dyn Observer,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Outcome {
    let started = Instant::now();
    let n = setpoints.axes();
    let t = settings.servo_period;
    let mut state: Vec<LaneState> = lanes
        .iter()
        .map(|_| LaneState {
            sensors: Sensors::new(n),
            measured: vec![0.0; n],
            motor: vec![0.0; n],
            command: vec![0.0; n],
            hold: Hold::new(n),
            stop: None,
        })
        .collect();
    let settle_ticks = (settings.settle_time / t).round() as usize;
    let total = settings.approach.len() + settle_ticks + setpoints.len();
    let mut done = 0;
    let ticks = for_each_tick(settings, setpoints, &mut |time, setpoint, k| {
        let alive = tick_lanes(settings, lanes, &mut state, time, setpoint, k, observer);
        if !alive && k.is_none() {
            return false;
        }
        done += 1;
        if !alive {
            return false;
        }
        if done % PROGRESS_EVERY == 0 && !progress(done, total) {
            interrupt(&mut state, time, observer);
            return false;
        }
        true
    });
    progress(done, total);
    Outcome {
        ticks,
        lanes: lanes
            .iter()
            .zip(state)
            .map(|(lane, s)| LaneOutcome {
                kind: lane.kind,
                stop: s.stop,
                steps: lane.plant.steps(),
            })
            .collect(),
        wall_time: started.elapsed().as_secs_f64(),
    }
}

/// Visits the setpoint of every servo tick of a run, in order, with its time: first, not
/// observed, the settle (the machine held at rest where it starts: the approach's first sample,
/// or the program's, at zero velocity and acceleration) and the approach to the program's
/// first point; then the program (`k`, the program tick, is `Some` there). Nothing is visited
/// without a program. `visit` returns whether to go on. Returns the program ticks visited.
pub fn for_each_tick(
    settings: &LoopSettings,
    setpoints: &mut dyn SetpointStream,
    visit: &mut dyn FnMut(f64, &SetpointSample, Option<usize>) -> bool,
) -> usize {
    let n = setpoints.axes();
    let t = settings.servo_period;
    let mut sample = SetpointSample::zeros(n);
    let settle_ticks = (settings.settle_time / t).round() as usize;
    let approach = &settings.approach;
    let mut ticks = 0;
    let mut done = 0;

    // Before the program, not observed: the machine first settles at rest where it starts (the
    // approach's first point, or the program's), as an enabled machine holds position before
    // cycle start; then it comes to the program's first point along the approach.
    let has_program = setpoints.next_sample(&mut sample);
    if !has_program {
        return 0;
    }
    let mut way = approach.stream();
    let mut step = SetpointSample::zeros(n);
    let mut on_way = way.next_sample(&mut step);
    let mut hold = if on_way { step.clone() } else { sample.clone() };
    hold.velocity.iter_mut().for_each(|v| *v = 0.0);
    hold.acceleration.iter_mut().for_each(|a| *a = 0.0);
    let before = (approach.len() + settle_ticks) as f64;
    let mut settle = settle_ticks;
    while settle > 0 || on_way {
        let time = (done as f64 - before) * t;
        let target = if settle > 0 { &hold } else { &step };
        if !visit(time, target, None) {
            return 0;
        }
        done += 1;
        if settle > 0 {
            settle -= 1;
        } else {
            on_way = way.next_sample(&mut step);
        }
    }
    // The program.
    loop {
        let time = ticks as f64 * t;
        let go_on = visit(time, &sample, Some(ticks));
        ticks += 1;
        if !go_on || !setpoints.next_sample(&mut sample) {
            return ticks;
        }
    }
}

/// Stops the run as interrupted at `time`: the primary lane stops, observers hear it.
fn interrupt(state: &mut [LaneState], time: f64, observer: &mut dyn Observer) {
    let stop = Stop::Interrupted { time };
    observer.stopped(0, &stop);
    state[0].stop = Some(stop);
}

/// One servo period of every lane still running: sample, check, measure, control, hold.
/// `k` is the program tick (`None` while settling: not observed). Returns whether the primary
/// lane is still running.
fn tick_lanes(
    settings: &LoopSettings,
    lanes: &mut [Lane<'_>],
    state: &mut [LaneState],
    time: f64,
    setpoint: &SetpointSample,
    k: Option<usize>,
    observer: &mut dyn Observer,
) -> bool {
    for (index, (lane, s)) in lanes.iter_mut().zip(state.iter_mut()).enumerate() {
        if s.stop.is_some() {
            continue;
        }
        let sensed = sense(
            settings,
            lane.plant.as_mut(),
            time,
            &setpoint.position,
            &mut s.sensors,
            &mut s.measured,
            &mut s.motor,
        );
        if let Err(stop) = sensed {
            // A tripped drive disables its outputs; the sample that tripped it is evidence
            // worth keeping. A state that is not finite is not.
            if let (Some(k), Stop::FollowingError { .. }) = (k, &stop) {
                s.command.iter_mut().for_each(|c| *c = 0.0);
                s.hold.mean_torque.iter_mut().for_each(|c| *c = 0.0);
                s.hold.voltage.iter_mut().for_each(|c| *c = 0.0);
                settings
                    .encoder
                    .measure(&s.sensors, &mut s.measured, &mut s.motor);
                observer.tick(index, &record(k, time, setpoint, s, lane.plant.as_ref()));
            }
            observer.stopped(index, &stop);
            s.stop = Some(stop);
            continue;
        }
        let input = ControllerInput {
            time,
            setpoint_position: &setpoint.position,
            setpoint_velocity: &setpoint.velocity,
            setpoint_acceleration: &setpoint.acceleration,
            measured_position: &s.measured,
            motor_position: &s.motor,
        };
        lane.controller.update(&input, &mut s.command);
        if let Some(what) = lane.controller.fault() {
            // No command for this tick: it is not observed, the lane stops here.
            let stop = Stop::Controller {
                time,
                what: what.to_string(),
            };
            observer.stopped(index, &stop);
            s.stop = Some(stop);
            continue;
        }
        lane.plant
            .set_spindle(settings.spindle.speed_at(setpoint.segment));
        lane.plant.hold(&s.command, &mut s.hold);
        if let Some(k) = k {
            observer.tick(index, &record(k, time, setpoint, s, lane.plant.as_ref()));
        }
        if let Some(what) = lane.plant.fault() {
            // The period that faulted is observed (its forces are evidence); the lane stops.
            let stop = Stop::Plant {
                time,
                line: settings.spindle.line_at(setpoint.segment),
                what,
            };
            observer.stopped(index, &stop);
            s.stop = Some(stop);
        }
    }
    state[0].stop.is_none()
}

/// What the loop does with a plant at the start of every servo period: samples its sensors,
/// checks them (divergence, the following-error trip against `setpoint_position`) and, if
/// they pass, quantises the feedback into `measured` and `motor` as the controller sees it.
/// The exported plant FMU calls it too, so its outputs are the loop's.
pub fn sense(
    settings: &LoopSettings,
    plant: &mut dyn Plant,
    time: f64,
    setpoint_position: &[f64],
    sensors: &mut Sensors,
    measured: &mut [f64],
    motor: &mut [f64],
) -> Result<(), Stop> {
    plant.sample(sensors);
    settings.trip.check(time, setpoint_position, sensors)?;
    settings.encoder.measure(sensors, measured, motor);
    Ok(())
}

fn record<'a>(
    k: usize,
    time: f64,
    setpoint: &'a SetpointSample,
    s: &'a LaneState,
    plant: &'a dyn Plant,
) -> TickRecord<'a> {
    TickRecord {
        k,
        time,
        setpoint,
        sensors: &s.sensors,
        measured: &s.measured,
        motor: &s.motor,
        command: &s.command,
        hold: &s.hold,
        stock: plant.stock(),
    }
}
