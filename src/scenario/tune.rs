//! `cncsim tune`: Ziegler–Nichols gains for one axis of a scenario, found on the scenario's own
//! simulated machine (or on the analytic reference model of it).
//!
//! Each trial is the scenario's loop as `run` wires it (machine, actuator, servo period,
//! physics step, encoder), with one change: the tuned axis is under P control at the trial
//! gain (I and D off, the scenario's output limit kept), while the other axes stay under the
//! scenario's own controller, so they are held as in a real run and couple as they would. The
//! axis starts at rest at the program's first point and its setpoint steps by `step` at t = 0.

use super::assemble::{machine_for, Assembly, RunError, GRAVITY};
use super::file::ControllerType;
use super::Scenario;
use crate::control::{ActuatorKind, Controller, ControllerInput, Pid, PidForm, PidSettings};
use crate::diagnostics::FileError;
use crate::frequency::AxisPlant;
use crate::machine::Machine;
use crate::plan::Setpoints;
use crate::sim::LaneKind;
use crate::sim::{self, Lane, LoopSettings, Trace, TraceRecorder};
use crate::tune::{
    continuous_ultimate, design_cascade, discrete_ultimate, find_ultimate, CascadeDesign,
    LoopShape, Response, SearchError, SearchSettings, Trial, Ultimate, UltimateCycle,
    ZieglerNichols,
};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// What to tune and how (SI units: the step in m or rad).
#[derive(Debug, Clone, PartialEq)]
pub struct TuneOptions {
    /// Name of the axis to tune (as the machine names it, e.g. `x`).
    pub axis: String,
    /// Setpoint step (m or rad, > 0).
    pub step: f64,
    /// Relative width of the final gain bracket.
    pub tolerance: f64,
    /// Simulated time per trial (s).
    pub trial_time: f64,
    /// First gain tried; default the scenario's own Kp for the axis.
    pub start_gain: Option<f64>,
    /// Most simulations for the whole tune, retries with a longer trial time included.
    pub max_simulations: usize,
}

impl TuneOptions {
    /// Tuning `axis` by a step of `step` (m or rad), the rest at defaults: tolerance 0.5 %, 1 s
    /// per trial, the scenario's Kp to start from, at most 60 simulations.
    pub fn new(axis: &str, step: f64) -> Self {
        TuneOptions {
            axis: axis.to_string(),
            step,
            tolerance: 0.005,
            trial_time: 1.0,
            start_gain: None,
            max_simulations: 60,
        }
    }
}

/// Swings the oscillating bound of the search must show before its verdict is trusted
/// (four periods); fewer, and the trial time is doubled.
const MIN_BOUNDARY_EXTREMA: usize = 8;

/// The longest trial accepted: a tune is meant to take seconds, not to run a long program.
const MAX_TRIAL_TIME: f64 = 60.0;

/// Why `tune` found no gains.
#[derive(Debug, thiserror::Error)]
pub enum TuneError {
    /// Bad input: the scenario, the machine or the options.
    #[error(transparent)]
    Input(#[from] RunError),
    /// The search ran and could not find the boundary.
    #[error("{path}: axis '{axis}': {source}")]
    Search {
        /// The scenario file.
        path: PathBuf,
        /// Name of the axis tuned.
        axis: String,
        /// What stopped the search.
        source: SearchError,
    },
}

impl From<FileError> for TuneError {
    fn from(e: FileError) -> Self {
        TuneError::Input(RunError::File(e))
    }
}

/// The ultimate cycle of the linear model of the axis (no friction, no backlash, no limits).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinearPrediction {
    /// The linear model: drive side and carriage, transmission, actuator, feedback device.
    pub axis: AxisPlant,
    /// Of the sampled loop (ZOH at the servo period): what the search should find.
    pub sampled: UltimateCycle,
    /// Continuous-time (T → 0) ultimate gain, where the continuous loop has one (not a rigid
    /// axis under the ideal torque actuator).
    pub continuous_gain: Option<f64>,
    /// Continuous-time ultimate period (s), likewise.
    pub continuous_period: Option<f64>,
}

/// Everything `tune` found, for the terminal and for `--json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TuneReport {
    /// The scenario's name.
    pub scenario: String,
    /// Name of the axis tuned.
    pub axis: String,
    /// Whether the axis is rotary (step and errors in rad, else m).
    pub rotary: bool,
    /// "physics" or "analytic".
    pub plant: &'static str,
    /// The actuator model of the trials: "dc-motor" or "ideal-torque".
    pub actuator: &'static str,
    /// The tuned drive's amplifier mode ("voltage" or "current"; dc-motor actuator only).
    pub amplifier_mode: Option<&'static str>,
    /// Whether the tuned axis had guide friction and backlash in the trials (`tune --linear`
    /// removes both).
    pub friction: bool,
    /// Whether the tuned axis had backlash in the trials.
    pub backlash: bool,
    /// Unit of the controller output: "V" (amplifier input) or "N·m".
    pub output_unit: &'static str,
    /// Servo period of the loop (s).
    pub servo_period_s: f64,
    /// Physics step (s): the servo period over the scenario's substeps.
    pub physics_step_s: f64,
    /// Simulated time per trial of the final search (s), after any doubling.
    pub trial_time_s: f64,
    /// The search's settings (step, start gain, saturation, hysteresis, budget).
    pub settings: SearchSettings,
    /// The scenario's output limit for the axis (kept during the search); `None` = none.
    pub output_limit: Option<f64>,
    /// The actuator's own limit in output units (supply / K_a, or peak torque).
    pub actuator_limit: f64,
    /// The boundary found: K_cr, P_cr and the trials of the final search.
    pub ultimate: Ultimate,
    /// The Ziegler–Nichols gains from K_cr and P_cr.
    pub gains: ZieglerNichols,
    /// `axes.<axis> = { kp = …, ki = …, kd = …, output_limit = … }`
    pub toml: String,
    /// The linear model's prediction, where the machine's rigid-body model can be built
    /// (no passive joint) and the sampled P loop has an ultimate gain.
    pub linear: Option<LinearPrediction>,
    /// Simulations run, retries with a longer trial time included.
    pub simulations: usize,
    /// Simulated time of all of them (s).
    pub simulated_time_s: f64,
    /// Wall-clock time of the tune (s).
    pub wall_time_s: f64,
}

/// Finds the ultimate gain and period of `options.axis` and the Ziegler–Nichols gains.
/// `progress` hears about every trial.
pub fn tune_scenario(
    s: &Scenario,
    options: &TuneOptions,
    plant: LaneKind,
    progress: &mut dyn FnMut(&Trial),
) -> Result<TuneReport, TuneError> {
    tune_scenario_with(s, machine_for(s)?, options, plant, progress)
}

/// [`tune_scenario`] on a machine given in memory (e.g. during a calibration).
pub fn tune_scenario_with(
    s: &Scenario,
    machine: Machine,
    options: &TuneOptions,
    plant: LaneKind,
    progress: &mut dyn FnMut(&Trial),
) -> Result<TuneReport, TuneError> {
    let started = Instant::now();
    let bad = |m: String| TuneError::from(FileError::new(&s.path, None, m));
    let assembly = Assembly::with_machine(s, machine)?;
    if let Some(kind) = s.controller_type().filter(|&c| c != ControllerType::Pid) {
        return Err(bad(format!("tune designs PID gains for one axis while the scenario's PID holds the others; this scenario's controller is type = \"{}\" (use a scenario with type = \"pid\")", kind.name())));
    }
    let machine = &assembly.machine;
    let labels = &assembly.labels;
    let actuator = assembly.actuator;
    let Some(axis) = machine.axis_index(&options.axis) else {
        let names: Vec<&str> = machine.axes.iter().map(|a| a.name.as_str()).collect();
        return Err(bad(format!(
            "--axis {}: the machine '{}' has no such axis (its axes: {})",
            options.axis,
            machine.name,
            names.join(", ")
        )));
    };
    let rotary = labels[axis].rotary;
    check_options(s, options, rotary).map_err(bad)?;

    let drive = &machine.axes[axis].drive;
    // Assembled with a PID (checked above): every axis has its gains.
    let gains = &s
        .controller
        .as_ref()
        .expect("assembled with a controller")
        .pid
        .axes[&options.axis];
    let output_limit = gains.output_limit();
    let (actuator_limit, actuator_name, output_unit) = match actuator {
        ActuatorKind::DcMotor => (
            drive.supply_voltage_v / drive.amplifier_gain,
            "dc-motor",
            "V",
        ),
        ActuatorKind::IdealTorque => (drive.peak_torque_nm, "ideal-torque", "N·m"),
    };
    let resolution = assembly.loop_settings.encoder.resolution[axis].unwrap_or(0.0);
    let settings = SearchSettings {
        servo_period: s.timing.servo_period,
        step: options.step,
        start_gain: options.start_gain.unwrap_or(gains.settings.kp),
        growth: 2.0,
        tolerance: options.tolerance,
        saturation: output_limit.min(actuator_limit),
        // Two encoder counts (a count of dither is not an oscillation), and at least 10⁻⁴ of
        // the step so that numerical noise makes no peaks.
        hysteresis: (2.0 * resolution).max(1e-4 * options.step),
        max_simulations: options.max_simulations,
    };
    if settings.start_gain <= 0.0 {
        return Err(bad(format!(
            "controller.axes.{}: kp = 0 gives no start gain for the search; pass --start-gain",
            options.axis
        )));
    }

    let search = UltimateSearch {
        assembly: &assembly,
        plant,
        axis,
        options,
        settings: &settings,
        output_limit,
    };
    let (ultimate, ticks, simulations, simulated_time) = search.run(progress)?;
    let gains = ZieglerNichols::from_ultimate(ultimate.gain, ultimate.period);
    let linear = linear_prediction(
        machine,
        axis,
        &assembly.start(),
        actuator,
        s.timing.servo_period,
    );
    Ok(TuneReport {
        scenario: s.name.clone(),
        axis: options.axis.clone(),
        rotary,
        plant: match plant {
            LaneKind::Physics => "physics",
            LaneKind::Analytic => "analytic",
        },
        actuator: actuator_name,
        amplifier_mode: match actuator {
            ActuatorKind::DcMotor => Some(machine.axes[axis].drive.amplifier_mode.name()),
            ActuatorKind::IdealTorque => None,
        },
        friction: machine.axes[axis].drive.guide.is_some(),
        backlash: machine.axes[axis].drive.backlash > 0.0,
        output_unit,
        servo_period_s: s.timing.servo_period,
        physics_step_s: s.timing.servo_period / s.timing.substeps as f64,
        trial_time_s: ticks as f64 * s.timing.servo_period,
        settings,
        output_limit: output_limit.is_finite().then_some(output_limit),
        actuator_limit,
        toml: toml_line(&options.axis, &gains, output_limit),
        gains,
        ultimate,
        linear,
        simulations,
        simulated_time_s: simulated_time,
        wall_time_s: started.elapsed().as_secs_f64(),
    })
}

/// The search for the ultimate gain of one axis, repeated with longer trials until the
/// oscillating bound shows enough swings.
struct UltimateSearch<'a> {
    assembly: &'a Assembly,
    plant: LaneKind,
    axis: usize,
    options: &'a TuneOptions,
    settings: &'a SearchSettings,
    output_limit: f64,
}

impl UltimateSearch<'_> {
    /// The ultimate cycle found, the trial length (ticks), the simulations run and the time
    /// they simulated (s).
    fn run(
        &self,
        progress: &mut dyn FnMut(&Trial),
    ) -> Result<(Ultimate, usize, usize, f64), TuneError> {
        let (assembly, plant, axis, options) = (self.assembly, self.plant, self.axis, self.options);
        let (settings, output_limit) = (self.settings, self.output_limit);
        let s = &assembly.scenario;
        let loop_settings = LoopSettings {
            settle_time: 0.0,
            approach: Setpoints::default(),
            ..assembly.loop_settings.clone()
        };
        // A boundary judged on a handful of peaks is a guess: a slow loop (an ultimate period
        // near the trial time) can look settled or growing by chance. The search is repeated
        // with twice the trial time until the oscillating bound shows enough swings.
        // Trials start at rest at the program's first point.
        let program_start = assembly
            .plan
            .first_position()
            .map_or_else(|| vec![0.0; assembly.labels.len()], <[f64]>::to_vec);
        let mut trial_time = options.trial_time;
        let (mut simulations, mut simulated_time) = (0, 0.0);
        let mut previous = None;
        let (ultimate, ticks) = loop {
            let ticks = (trial_time / s.timing.servo_period).round() as usize;
            let trial_setpoints = step_setpoints(
                &program_start,
                s.timing.servo_period,
                axis,
                options.step,
                ticks,
            );
            let probe = Probe {
                assembly,
                plant,
                axis,
                setpoints: &trial_setpoints,
                loop_settings: &loop_settings,
                output_limit,
            };
            let mut simulate = |gain: f64| probe.trial(gain);
            // The simulation budget is for the whole tune, retries included.
            let settings = SearchSettings {
                max_simulations: options.max_simulations.saturating_sub(simulations),
                ..settings.clone()
            };
            let ultimate = match find_ultimate(&settings, &mut simulate, progress) {
                Ok(u) => u,
                // A longer retry that cannot finish keeps the result it was to confirm (a loop
                // that friction stops makes few peaks however long it runs).
                Err(_) if previous.is_some() => break previous.expect("checked"),
                Err(source) => {
                    return Err(TuneError::Search {
                        path: s.path.clone(),
                        axis: options.axis.clone(),
                        source,
                    })
                }
            };
            simulations += ultimate.trials.len();
            simulated_time += (ultimate.trials.len() * ticks) as f64 * s.timing.servo_period;
            // A limit cycle (backlash in the loop) is judged by its constant swing, not by growth
            // over many periods: no retry for it.
            if ultimate.upper.oscillation.extrema >= MIN_BOUNDARY_EXTREMA
                || ultimate.limit_cycle
                || 2.0 * trial_time > MAX_TRIAL_TIME
                || simulations >= options.max_simulations
            {
                break (ultimate, ticks);
            }
            previous = Some((ultimate, ticks));
            trial_time *= 2.0;
        };

        Ok((ultimate, ticks, simulations, simulated_time))
    }
}

/// The linear model's prediction of the ultimate gain and period (the axis at joint position
/// `q`), where the axis has one.
fn linear_prediction(
    machine: &Machine,
    axis: usize,
    q: &[f64],
    actuator: ActuatorKind,
    period: f64,
) -> Option<LinearPrediction> {
    let plant = AxisPlant::of_axis(machine, axis, q, actuator).ok()?;
    let continuous = continuous_ultimate(&plant);
    Some(LinearPrediction {
        axis: plant,
        sampled: discrete_ultimate(&plant, period)?,
        continuous_gain: continuous.map(|c| c.gain),
        continuous_period: continuous.map(|c| c.period),
    })
}

/// The trial's setpoints: at rest at the program's first point (one sample there, which both
/// loops take as the rest position), then the tuned axis's setpoint steps by `step`.
fn step_setpoints(
    start: &[f64],
    servo_period: f64,
    axis: usize,
    step: f64,
    ticks: usize,
) -> Setpoints {
    let start = start.to_vec();
    let n = start.len();
    let mut target = start.clone();
    target[axis] += step;
    let mut trial = Setpoints::new(servo_period, n);
    let zeros = vec![0.0; n];
    trial.push(&start, &zeros, &zeros, 0);
    for _ in 0..ticks {
        trial.push(&target, &zeros, &zeros, 0);
    }
    trial
}

fn check_options(s: &Scenario, o: &TuneOptions, rotary: bool) -> Result<(), String> {
    let (unit, scale, limit) = if rotary {
        (
            "deg",
            180.0 / std::f64::consts::PI,
            s.feedback.following_error_limit_rotary,
        )
    } else {
        ("mm", 1e3, s.feedback.following_error_limit_linear)
    };
    if !(o.step.is_finite() && o.step > 0.0 && o.step < limit) {
        return Err(format!(
            "step {} {unit}: expected a number > 0 and below the following-error limit {} {unit}",
            o.step * scale,
            limit * scale
        ));
    }
    if !(o.tolerance > 0.0 && o.tolerance < 1.0) {
        return Err(format!(
            "tolerance {}: expected a relative width between 0 and 1 (e.g. 0.005)",
            o.tolerance
        ));
    }
    if !(o.trial_time >= 10.0 * s.timing.servo_period && o.trial_time <= MAX_TRIAL_TIME) {
        return Err(format!(
            "trial time {} s: expected between 10 servo periods ({} s) and {MAX_TRIAL_TIME} s",
            o.trial_time,
            10.0 * s.timing.servo_period
        ));
    }
    if let Some(g) = o.start_gain {
        if !(g.is_finite() && g > 0.0) {
            return Err(format!("start gain {g}: expected a number > 0"));
        }
    }
    if o.max_simulations == 0 {
        return Err("max simulations: expected at least 1".into());
    }
    Ok(())
}

/// Everything a trial needs, shared by all trials.
struct Probe<'a> {
    assembly: &'a Assembly,
    plant: LaneKind,
    axis: usize,
    setpoints: &'a Setpoints,
    loop_settings: &'a LoopSettings,
    output_limit: f64,
}

impl Probe<'_> {
    /// One trial: the scenario's loop with the tuned axis under P control at `gain`, on the
    /// chosen plant, at rest at the trial's start.
    fn trial(&self, gain: f64) -> Result<Response, String> {
        let a = self.assembly;
        let s = &a.scenario;
        let hold = a.controller();
        let p = PidSettings::plain(
            crate::control::PidGains {
                kp: gain,
                ki: 0.0,
                kd: 0.0,
            },
            self.output_limit,
        );
        let controller = ProportionalOn {
            hold,
            axis: self.axis,
            pid: Pid::new(p, PidForm::Positional, s.timing.servo_period),
        };
        let start = self.setpoints.position(0);
        let mut lanes = [Lane {
            kind: self.plant,
            plant: a.plant(self.plant, start).map_err(|e| e.to_string())?,
            controller: Box::new(controller),
        }];
        let mut recorder = TraceRecorder::new(s.timing.servo_period, start.len(), 1);
        let outcome = sim::run(
            self.loop_settings,
            &mut lanes,
            &mut self.setpoints.stream(),
            &mut recorder,
            &mut |_, _| true,
        );
        let mut r = self.response(recorder.lane(0));
        r.stopped = outcome.stop().map(|e| e.to_string());
        Ok(r)
    }

    /// The tuned axis's error and command from the step on (the rest sample before it left
    /// out).
    fn response(&self, trace: &Trace) -> Response {
        let (n, i) = (trace.axes, self.axis);
        Response {
            error: (1..trace.len())
                .map(|k| Trace::at(&trace.commanded, n, k, i) - Trace::at(&trace.actual, n, k, i))
                .collect(),
            command: (1..trace.len())
                .map(|k| Trace::at(&trace.command, n, k, i))
                .collect(),
            stopped: None,
        }
    }
}

/// The hold controller for every axis, its output replaced on one axis by a P loop.
struct ProportionalOn<'a> {
    hold: Box<dyn Controller + 'a>,
    axis: usize,
    pid: Pid,
}

impl Controller for ProportionalOn<'_> {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        self.hold.update(input, command);
        let i = self.axis;
        command[i] = self
            .pid
            .update(input.setpoint_position[i] - input.measured_position[i]);
    }

    fn reset(&mut self) {
        self.hold.reset();
        self.pid.reset();
    }
}

/// `axes.x = { kp = …, ki = …, kd = …, output_limit = … }` with four significant digits.
fn toml_line(axis: &str, g: &ZieglerNichols, output_limit: f64) -> String {
    let mut line = format!(
        "axes.{axis} = {{ kp = {}, ki = {}, kd = {}",
        toml_number(g.kp),
        toml_number(g.ki),
        toml_number(g.kd)
    );
    if output_limit.is_finite() {
        line += &format!(", output_limit = {}", toml_number(output_limit));
    }
    line + " }"
}

/// A TOML float (always with a '.' or an exponent) rounded to four significant digits.
fn toml_number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return "0.0".into();
    }
    let scale = 10f64.powi(3 - x.abs().log10().floor() as i32);
    let rounded = (x * scale).round() / scale;
    let text = format!("{rounded:?}");
    if text.contains(['.', 'e', 'E']) {
        text
    } else {
        text + ".0"
    }
}

impl TuneReport {
    /// The report for the terminal.
    pub fn text(&self) -> String {
        let u = &self.ultimate;
        let (err_unit, step_text) = if self.rotary {
            ("rad", format!("{:.4} deg", self.settings.step.to_degrees()))
        } else {
            ("m", format!("{:.4} mm", self.settings.step * 1e3))
        };
        let out = self.output_unit;
        let gain_unit = format!("{out}/{err_unit}");
        let mut t = String::new();
        let plant = match self.plant {
            "physics" => format!(
                "physics (Rapier), servo period {} ms, physics step {} ms",
                self.servo_period_s * 1e3,
                self.physics_step_s * 1e3
            ),
            _ => format!(
                "analytic reference model, servo period {} ms",
                self.servo_period_s * 1e3
            ),
        };
        let amplifier = self
            .amplifier_mode
            .map(|m| format!(" ({m}-mode amplifier)"))
            .unwrap_or_default();
        let mechanics = match (self.friction, self.backlash) {
            (true, true) => "",
            (false, false) => ", linear part (friction and backlash off)",
            (false, true) => ", friction off",
            (true, false) => ", backlash off",
        };
        t += &format!(
            "Ziegler–Nichols ultimate cycle: {} axis {} on {plant}, {} actuator{amplifier}{mechanics}\n",
            self.scenario, self.axis, self.actuator
        );
        t += &format!(
            "  excitation   setpoint step of {step_text} from rest at the program start; other axes held by the scenario's PID; {} s per run\n",
            self.trial_time_s
        );
        t += &format!(
            "  search       P only (I, D off), K ×{} from {} until oscillation, bisection to {} %: {} simulations, {:.1} s simulated, {:.2} s wall\n",
            self.settings.growth,
            toml_number(self.settings.start_gain),
            self.settings.tolerance * 100.0,
            self.simulations,
            self.simulated_time_s,
            self.wall_time_s
        );
        for (name, trial) in [("lower bound", &u.lower), ("upper bound", &u.upper)] {
            t += &format!(
                "  {name}  K = {:.5e} {gain_unit}: {}, swing ratio per period {}, {} peaks, max |u| = {:.3} {out}\n",
                trial.gain,
                outcome_text(trial),
                trial
                    .oscillation
                    .ratio
                    .map_or("-".into(), |r| format!("{r:.4}")),
                trial.oscillation.extrema,
                trial.max_command
            );
        }
        let limit = match self.output_limit {
            Some(l) => format!("controller output limit {} {out} (kept)", toml_number(l)),
            None => "no controller output limit".into(),
        };
        t += &format!(
            "  saturation   {limit}; the actuator saturates at {:.4} {out}; runs are judged only before the first saturated sample\n",
            self.actuator_limit
        );
        t += &format!(
            "  ultimate     K_cr = {:.5e} {gain_unit}, P_cr = {:.3} ms\n",
            u.gain,
            u.period * 1e3
        );
        if u.limit_cycle {
            t += "  WARNING      a run ended in a limit cycle (constant amplitude set by friction or backlash, not by the gain): K_cr is not the linear ultimate gain\n";
        }
        if let Some(l) = &self.linear {
            t += &format!(
                "  linear model sampled (ZOH) loop: K_cr = {:.5e} {gain_unit}, P_cr = {:.3} ms (search/model: {:+.2} %, {:+.2} %)",
                l.sampled.gain,
                l.sampled.period * 1e3,
                (u.gain / l.sampled.gain - 1.0) * 100.0,
                (u.period / l.sampled.period - 1.0) * 100.0
            );
            if let (Some(k), Some(p)) = (l.continuous_gain, l.continuous_period) {
                t += &format!(
                    "; continuous time: K_cr = {k:.5e} {gain_unit}, P_cr = {:.3} ms",
                    p * 1e3
                );
            }
            t += "\n";
        }
        let g = &self.gains;
        t += &format!(
            "Ziegler–Nichols gains (error in {err_unit}, output in {out}{}):\n",
            if out == "V" {
                " at the amplifier input"
            } else {
                " of motor torque"
            }
        );
        t += &format!(
            "  Kp = {:.5e}  T_i = {:.4} s  T_d = {:.5} s  Ki = {:.5e}  Kd = {:.5e}\n",
            g.kp, g.ti, g.td, g.ki, g.kd
        );
        t += &format!("  {}\n", self.toml);
        t
    }

    /// The report as JSON (`--json`).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("plain numbers and strings")
    }
}

/// One trial's outcome in words, for progress lines and the report.
pub fn outcome_text(t: &Trial) -> String {
    let mut s = format!("{:?}", t.outcome).to_lowercase();
    if s == "limitcycle" {
        s = "limit cycle".into();
    }
    if let Some(at) = t.saturated_at {
        s += &format!(" (saturated at {:.3} s)", at);
    }
    if let Some(why) = &t.stopped {
        s += &format!(" ({why})");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn toml_numbers_are_floats_with_four_digits() {
        assert_eq!(toml_number(19876.5), "19880.0");
        assert_eq!(toml_number(6.0), "6.0");
        assert_eq!(toml_number(0.0012345), "0.001235");
        assert_eq!(toml_number(6.1e5), "610000.0");
        assert!(toml_number(1.2345e-9).parse::<f64>().unwrap() == 1.235e-9);
    }
}

/// What `cncsim tune --cascade` found for one axis: the design from the axis's linear model,
/// and a check on the simulated plant (a velocity step through the velocity loop alone).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CascadeTuneReport {
    /// The scenario's name.
    pub scenario: String,
    /// Name of the axis designed.
    pub axis: String,
    /// Whether the axis is rotary (gains per rad, else per m).
    pub rotary: bool,
    /// Plant of the check: "physics" or "analytic".
    pub plant: &'static str,
    /// Servo period of the loop (s).
    pub servo_period_s: f64,
    /// The scenario's velocity-feedback filter (Hz; 0 = none).
    pub velocity_filter_hz: f64,
    /// The design, from the axis's linear model at the program's first point.
    pub design: CascadeDesign,
    /// Velocity step response of the simulated axis under the designed velocity loop: rise
    /// time 10–90 % (s) and overshoot (fraction of the step).
    pub step_rise_time_s: Option<f64>,
    /// Overshoot of that response (fraction of the step); `None` when it never reached 90 %.
    pub step_overshoot: Option<f64>,
    /// `cascade.<axis> = { … }`
    pub toml: String,
}

/// Designs the cascade of `axis` (see [`crate::tune::cascade`]) on the scenario's machine and
/// checks it on the simulated plant. The axis's inertia is the rigid-body model's at the
/// program's first point (armature included), its damping the drive's and the joint's.
pub fn tune_cascade(
    s: &Scenario,
    machine: Machine,
    axis_name: &str,
    bandwidth_hz: Option<f64>,
    plant: LaneKind,
) -> Result<CascadeTuneReport, TuneError> {
    let bad = |m: String| TuneError::from(FileError::new(&s.path, None, m));
    let assembly = Assembly::with_machine(s, machine)?;
    let machine = &assembly.machine;
    let Some(axis) = machine.axis_index(axis_name) else {
        let names: Vec<&str> = machine.axes.iter().map(|a| a.name.as_str()).collect();
        return Err(bad(format!(
            "--axis {axis_name}: the machine '{}' has no such axis (its axes: {})",
            machine.name,
            names.join(", ")
        )));
    };
    let start = assembly.start();
    let linear = AxisPlant::of_axis(machine, axis, &start, assembly.actuator).map_err(bad)?;
    let velocity_filter_hz = s
        .controller
        .as_ref()
        .map_or(0.0, |c| c.cascade.velocity_filter_hz);
    // The command filters the scenario gives this axis, and its drive train.
    let torque_filters = s
        .controller
        .as_ref()
        .and_then(|c| c.cascade.axes.get(axis_name))
        .map_or_else(Default::default, |a| a.settings.filters);
    let shape = LoopShape {
        velocity_filter_hz,
        torque_filters,
    };
    let design = design_cascade(&linear, s.timing.servo_period, &shape, bandwidth_hz)
        .map_err(|m| bad(format!("--axis {axis_name}: {m}")))?;

    // The check: the velocity loop alone (no position loop) on a setpoint that ramps from rest
    // at a modest speed: its velocity feed-forward is a velocity step.
    let rotary = assembly.labels[axis].rotary;
    let speed = if rotary { 0.05 } else { 0.005 };
    let ticks =
        ((10.0 / design.velocity_bandwidth_hz.max(0.1)) / s.timing.servo_period).ceil() as usize;
    let ticks = ticks.clamp(20, 200_000);
    let n = start.len();
    let mut setpoints = Setpoints::new(s.timing.servo_period, n);
    let zeros = vec![0.0; n];
    setpoints.push(&start, &zeros, &zeros, 0);
    let mut velocity = zeros.clone();
    velocity[axis] = speed;
    for k in 1..=ticks {
        let mut p = start.clone();
        p[axis] += speed * k as f64 * s.timing.servo_period;
        setpoints.push(&p, &velocity, &zeros, 0);
    }
    let mut loop_axis = design.axis;
    loop_axis.position_kp = 0.0;
    let hold = assembly.controller();
    let drives: Vec<_> = machine.axes.iter().map(|a| a.drive.clone()).collect();
    let model =
        crate::dynamics::AxisDynamics::of_machine(machine, nalgebra::Vector3::from(GRAVITY))
            .map_err(|e| bad(format!("the machine's rigid-body model: {e}")))?;
    let cascade = crate::control::Cascade::new(
        vec![loop_axis; n],
        velocity_filter_hz,
        model,
        &drives,
        assembly.actuator,
        s.timing.servo_period,
    );
    let controller = OneAxis {
        hold,
        axis,
        on_axis: Box::new(cascade),
        scratch: vec![0.0; n],
    };
    let loop_settings = LoopSettings {
        settle_time: 0.0,
        approach: Setpoints::default(),
        ..assembly.loop_settings.clone()
    };
    let mut lanes = [Lane {
        kind: plant,
        plant: assembly.plant(plant, &start)?,
        controller: Box::new(controller),
    }];
    let mut recorder = TraceRecorder::new(s.timing.servo_period, n, 1);
    sim::run(
        &loop_settings,
        &mut lanes,
        &mut setpoints.stream(),
        &mut recorder,
        &mut |_, _| true,
    );
    let trace = recorder.lane(0);
    let v: Vec<f64> = (0..trace.len())
        .map(|k| Trace::at(&trace.actual_velocity, n, k, axis))
        .collect();
    let (rise, overshoot) = step_figures(&v, speed, s.timing.servo_period);
    let a = &design.axis;
    let mut filters = String::new();
    if let Some(hz) = a.filters.lowpass_hz {
        filters += &format!(", torque_lowpass_hz = {}", toml_number(hz));
    }
    if let Some(n) = a.filters.notch {
        filters += &format!(
            ", notch_hz = {}, notch_width_hz = {}, notch_depth = {}",
            toml_number(n.hz),
            toml_number(n.width_hz),
            toml_number(n.depth)
        );
    }
    let toml = format!(
        "cascade.{axis_name} = {{ position_kp = {}, velocity_kp = {}, velocity_ki = {}, velocity_ff = 1.0, acceleration_ff = 1.0{filters} }}",
        toml_number(a.position_kp),
        toml_number(a.velocity_kp),
        toml_number(a.velocity_ki)
    );
    Ok(CascadeTuneReport {
        scenario: s.name.clone(),
        axis: axis_name.to_string(),
        rotary,
        plant: match plant {
            LaneKind::Physics => "physics",
            LaneKind::Analytic => "analytic",
        },
        servo_period_s: s.timing.servo_period,
        velocity_filter_hz,
        design,
        step_rise_time_s: rise,
        step_overshoot: overshoot,
        toml,
    })
}

/// Rise time 10–90 % and overshoot of a step response `v` to `target`, sampled every `t`.
fn step_figures(v: &[f64], target: f64, t: f64) -> (Option<f64>, Option<f64>) {
    let first = |level: f64| v.iter().position(|x| *x >= level * target);
    let rise = match (first(0.1), first(0.9)) {
        (Some(a), Some(b)) => Some((b - a) as f64 * t),
        _ => None,
    };
    let peak = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let overshoot = (peak.is_finite() && rise.is_some()).then(|| (peak / target - 1.0).max(0.0));
    (rise, overshoot)
}

/// The scenario's controller on every axis but one, which another controller drives.
struct OneAxis {
    hold: Box<dyn Controller>,
    axis: usize,
    on_axis: Box<dyn Controller>,
    scratch: Vec<f64>,
}

impl Controller for OneAxis {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        self.hold.update(input, command);
        self.on_axis.update(input, &mut self.scratch);
        command[self.axis] = self.scratch[self.axis];
    }

    fn reset(&mut self) {
        self.hold.reset();
        self.on_axis.reset();
    }
}

impl CascadeTuneReport {
    /// The report for the terminal.
    pub fn text(&self) -> String {
        let d = &self.design;
        let (unit, speed) = if self.rotary {
            ("rad", "rad/s")
        } else {
            ("m", "m/s")
        };
        let mut t = format!(
            "Cascade design: {} axis {}, servo period {} ms, velocity filter {}\n",
            self.scenario,
            self.axis,
            self.servo_period_s * 1e3,
            if self.velocity_filter_hz > 0.0 {
                format!("{} Hz", self.velocity_filter_hz)
            } else {
                "none".into()
            }
        );
        t += &format!(
            "  plant        the axis's linear model sampled at the servo period: {:.5e} kg moved (drive side included), {:.5e} N per command unit, {:.5e} N·s/{unit} at low frequency\n",
            d.mass, d.force_per_command, d.damping
        );
        t += &format!(
            "  velocity     PI, crossover {:.2} Hz with {:.1}° phase margin (hold, current, drive train, velocity estimate, filters and PI zero in the loop): Kpv = {:.5e} per {speed}, Kiv = {:.5e} per {unit}\n",
            d.velocity_bandwidth_hz, d.phase_margin_deg, d.axis.velocity_kp, d.axis.velocity_ki
        );
        if let (Some(r), Some(a)) = (d.resonance_hz, d.antiresonance_hz) {
            t += &format!(
                "  drive train  compliant: resonance {r:.2} Hz, antiresonance {a:.2} Hz (seen from the motor); the crossover is the largest below the antiresonance (unless a notch takes the resonance out) that crosses once with at least {:.0}° of phase and {:.0} dB of gain margin\n",
                crate::tune::PHASE_MARGIN_DEG,
                crate::tune::GAIN_MARGIN_DB
            );
        }
        t += &format!(
            "  margins      phase {:.1}°, gain {} (read off the open loop's frequency response)\n",
            d.phase_margin_deg,
            if d.gain_margin_db.is_finite() {
                format!("{:.1} dB", d.gain_margin_db)
            } else {
                "infinite".into()
            }
        );
        t += &format!(
            "  position     P at a quarter of it: Kpp = {:.4} 1/s ({:.2} Hz), velocity and acceleration feed-forward 1\n",
            d.axis.position_kp, d.position_bandwidth_hz
        );
        match (self.step_rise_time_s, self.step_overshoot) {
            (Some(r), Some(o)) => {
                t += &format!(
                    "  check        velocity step through the velocity loop alone on the {} model: rise 10–90 % {:.2} ms, overshoot {:.1} %\n",
                    self.plant,
                    r * 1e3,
                    o * 100.0
                );
            }
            _ => {
                t += &format!(
                "  check        the velocity step on the {} model did not reach 90 % of the step\n",
                self.plant
            )
            }
        }
        t += &format!("  {}\n", self.toml);
        t += &format!(
            "  the same model's PID feed-forward (FF1 = c/b, FF2 = m/b): axes.{} ff1 = {}, ff2 = {}\n",
            self.axis,
            toml_number(d.damping / d.force_per_command),
            toml_number(d.mass / d.force_per_command)
        );
        t
    }
}

impl crate::command::Report for TuneReport {
    fn text(&self) -> String {
        TuneReport::text(self)
    }

    fn json(&self) -> Option<serde_json::Value> {
        Some(self.to_json())
    }
}

impl crate::command::Report for CascadeTuneReport {
    fn text(&self) -> String {
        CascadeTuneReport::text(self)
    }

    fn json(&self) -> Option<serde_json::Value> {
        serde_json::to_value(self).ok()
    }
}
