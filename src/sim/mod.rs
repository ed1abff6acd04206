//! The co-simulation loop. Read it as a block diagram sampled at the servo period T:
//!
//!   setpoints ─▶ (+) ─▶ controller ─▶ hold ─▶ actuator ─▶ transmission ─▶ plant (Rapier)
//!                 ▲ −                                                         │
//!                 └──────────────────── encoder ◀─────────────────────────────┘
//!
//! The controller runs once per T on sampled (optionally quantised) positions; its output is
//! held while the actuator and the physics advance in `substeps` steps of T/substeps.

pub mod analytic;

use crate::control::{Actuator, Controller, ControllerInput};
use crate::model::Plant;
use crate::plan::Setpoints;
use std::time::Instant;

/// Most servo ticks one run may take (settle included): a four-hour program at a 1 ms servo
/// period is 1.44·10⁷; beyond 10⁸ a run is a mistake (a feed or a period off by orders of
/// magnitude), and is refused before it starts with the number it would need.
pub const MAX_SERVO_TICKS: u64 = 100_000_000;
/// Most physics steps one run may take (ticks × steps per tick).
pub const MAX_PHYSICS_STEPS: u64 = 1_000_000_000;

/// How the loop runs, per machine axis where it says so.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopSettings {
    pub servo_period: f64,
    /// Physics steps per servo period.
    pub substeps: usize,
    /// Time the loop holds the first setpoint before the program starts (s): the machine is
    /// enabled and in position before cycle start. Not traced.
    pub settle_time: f64,
    /// Motor radians per joint unit, per axis (to turn torque into joint force, and joint
    /// speed into motor speed for the back-EMF).
    pub ratios: Vec<f64>,
    /// Encoder resolution in joint units, per axis; `None` = ideal feedback.
    pub encoder_resolution: Vec<Option<f64>>,
    /// Following-error fault limit per axis (joint units), like a drive's following-error trip.
    pub following_error_limit: Vec<f64>,
    pub axis_names: Vec<String>,
}

/// Per-tick record of a run; sample k of axis i at `k * axes + i`. Joint units (SI).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trace {
    pub period: f64,
    pub axes: usize,
    pub time: Vec<f64>,
    pub commanded: Vec<f64>,
    pub commanded_velocity: Vec<f64>,
    pub actual: Vec<f64>,
    pub actual_velocity: Vec<f64>,
    /// Drive-side position (motor angle over the ratio); equals `actual` without backlash.
    pub drive: Vec<f64>,
    /// Controller output (N·m or V).
    pub command: Vec<f64>,
    /// Mean motor torque over the hold interval that follows the sample (N·m).
    pub torque: Vec<f64>,
    /// Armature voltage (V), zero with the ideal actuator.
    pub voltage: Vec<f64>,
    /// Tool point and its velocity from the physics (m, m/s).
    pub tool_point: Vec<[f64; 3]>,
    pub tool_velocity: Vec<[f64; 3]>,
    /// Program move of the setpoint.
    pub segment: Vec<u32>,
}

impl Trace {
    pub fn len(&self) -> usize {
        self.time.len()
    }

    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }

    /// Value of axis `i` at sample `k` of one of the per-axis series.
    pub fn at(series: &[f64], axes: usize, k: usize, i: usize) -> f64 {
        series[k * axes + i]
    }
}

/// Why a run stopped before the end of its setpoints.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Stop {
    #[error("simulation diverged at t = {time:.6} s on axis '{axis}': {what}")]
    Diverged {
        time: f64,
        axis: String,
        what: String,
    },
    #[error("interrupted at t = {time:.6} s")]
    Interrupted { time: f64 },
    #[error("following-error fault at t = {time:.6} s on axis '{axis}': |error| = {error:.6e} exceeds the limit {limit:.6e}")]
    FollowingError {
        time: f64,
        axis: String,
        error: f64,
        limit: f64,
    },
}

/// The result of a run: everything traced up to where it ended, and why it ended early.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub trace: Trace,
    pub stop: Option<Stop>,
    pub physics_steps: u64,
    pub wall_time: f64,
}

/// The wired blocks of one run.
pub struct CoSimulation<'a> {
    pub plant: Plant,
    pub controller: Box<dyn Controller + 'a>,
    pub actuators: Vec<Actuator>,
    pub settings: LoopSettings,
}

impl CoSimulation<'_> {
    /// Runs the setpoints through the loop. `progress(done, total)` is called now and then; when
    /// it returns `false` the run stops there (the user interrupted it), keeping what it traced.
    pub fn run(
        mut self,
        setpoints: &Setpoints,
        progress: &mut dyn FnMut(usize, usize) -> bool,
    ) -> Outcome {
        let started = Instant::now();
        let n = setpoints.axes;
        let t = self.settings.servo_period;
        let dt = t / self.settings.substeps as f64;
        let mut trace = Trace {
            period: t,
            axes: n,
            ..Default::default()
        };
        let total = setpoints.len();
        let zeros = vec![0.0; n];
        let mut buffers = Buffers::new(n);

        let mut stop = None;
        if !setpoints.is_empty() {
            let settle_ticks = (self.settings.settle_time / t).round() as usize;
            let hold = setpoints.position(0);
            for k in 0..settle_ticks {
                let time = (k as f64 - settle_ticks as f64) * t;
                let tick = Tick {
                    time,
                    position: hold,
                    velocity: &zeros,
                    acceleration: &zeros,
                };
                if let Err(s) = self.tick(&tick, &mut buffers, dt) {
                    stop = Some(s);
                    break;
                }
            }
        }
        if stop.is_none() {
            for k in 0..total {
                let tick = Tick {
                    time: k as f64 * t,
                    position: setpoints.position(k),
                    velocity: setpoints.velocity(k),
                    acceleration: setpoints.acceleration(k),
                };
                let result = self.tick(&tick, &mut buffers, dt);
                record(&mut trace, &tick, &buffers, setpoints.segment[k]);
                if let Err(s) = result {
                    stop = Some(s);
                    break;
                }
                if k % 1024 == 0 && !progress(k, total) {
                    stop = Some(Stop::Interrupted { time: tick.time });
                    break;
                }
            }
        }
        progress(trace.len(), total);
        Outcome {
            trace,
            stop,
            physics_steps: self.plant.steps(),
            wall_time: started.elapsed().as_secs_f64(),
        }
    }

    /// One servo period: sample, check, control, then hold the command over the substeps.
    fn tick(&mut self, tick: &Tick<'_>, b: &mut Buffers, dt: f64) -> Result<(), Stop> {
        let s = &self.settings;
        self.plant.positions(&mut b.q);
        self.plant.velocities(&mut b.qd);
        self.plant.drive_positions(&mut b.drive);
        self.plant.feedback_positions(&mut b.measured);
        b.tool = self.plant.tool_point().into();
        b.tool_velocity = self.plant.tool_velocity().into();
        for i in 0..b.q.len() {
            let axis = || s.axis_names[i].clone();
            if !b.q[i].is_finite() || !b.qd[i].is_finite() {
                return Err(Stop::Diverged {
                    time: tick.time,
                    axis: axis(),
                    what: format!("position {} / velocity {} is not finite", b.q[i], b.qd[i]),
                });
            }
            let error = tick.position[i] - b.q[i];
            if error.abs() > s.following_error_limit[i] {
                return Err(Stop::FollowingError {
                    time: tick.time,
                    axis: axis(),
                    error: error.abs(),
                    limit: s.following_error_limit[i],
                });
            }
            if let Some(res) = s.encoder_resolution[i] {
                b.measured[i] = (b.measured[i] / res).round() * res;
            }
        }
        let input = ControllerInput {
            setpoint_position: tick.position,
            setpoint_velocity: tick.velocity,
            setpoint_acceleration: tick.acceleration,
            measured_position: &b.measured,
        };
        self.controller.update(&input, &mut b.command);
        b.torque.iter_mut().for_each(|v| *v = 0.0);
        for _ in 0..s.substeps {
            // The motor turns with the drive side of the transmission (back-EMF).
            self.plant.drive_velocities(&mut b.qd_live);
            for i in 0..b.q.len() {
                let out = self.actuators[i].step(b.command[i], s.ratios[i] * b.qd_live[i], dt);
                b.force[i] = out.torque * s.ratios[i];
                b.torque[i] += out.torque / s.substeps as f64;
                b.voltage[i] = out.voltage;
            }
            self.plant.set_joint_forces(&b.force);
            self.plant.step();
        }
        Ok(())
    }
}

struct Tick<'a> {
    time: f64,
    position: &'a [f64],
    velocity: &'a [f64],
    acceleration: &'a [f64],
}

/// Scratch vectors reused every tick (the loop allocates nothing).
struct Buffers {
    /// Position and velocity sampled at the start of the tick.
    q: Vec<f64>,
    drive: Vec<f64>,
    qd: Vec<f64>,
    tool: [f64; 3],
    tool_velocity: [f64; 3],
    /// Velocity during the substeps (motor speed for the back-EMF).
    qd_live: Vec<f64>,
    measured: Vec<f64>,
    command: Vec<f64>,
    force: Vec<f64>,
    torque: Vec<f64>,
    voltage: Vec<f64>,
}

impl Buffers {
    fn new(n: usize) -> Self {
        let z = || vec![0.0; n];
        Buffers {
            q: z(),
            drive: z(),
            qd: z(),
            tool: [0.0; 3],
            tool_velocity: [0.0; 3],
            qd_live: z(),
            measured: z(),
            command: z(),
            force: z(),
            torque: z(),
            voltage: z(),
        }
    }
}

/// Appends the tick: setpoint and state sampled at its start, torque over its hold interval.
fn record(trace: &mut Trace, tick: &Tick<'_>, b: &Buffers, segment: u32) {
    trace.time.push(tick.time);
    trace.commanded.extend_from_slice(tick.position);
    trace.commanded_velocity.extend_from_slice(tick.velocity);
    trace.actual.extend_from_slice(&b.q);
    trace.actual_velocity.extend_from_slice(&b.qd);
    trace.drive.extend_from_slice(&b.drive);
    trace.command.extend_from_slice(&b.command);
    trace.torque.extend_from_slice(&b.torque);
    trace.voltage.extend_from_slice(&b.voltage);
    trace.tool_point.push(b.tool);
    trace.tool_velocity.push(b.tool_velocity);
    trace.segment.push(segment);
}
