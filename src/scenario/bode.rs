//! `cncsim bode`: the frequency response of one axis measured on the scenario's machine
//! through its own servo loop, actuator and controller, by stepped sine (see
//! docs/frequency-response.md), with the linearised model of the axis from its drive data laid
//! over it.
//!
//! Why stepped sine: one frequency at a time, settled, projected on the excitation over whole
//! periods, it has no leakage and the best signal-to-noise ratio per frequency, and each point
//! has its own coherence, so a point spoilt by friction, backlash or saturation shows as such.
//! A multisine would be faster; a commissioning tool's few seconds are not what matters here,
//! accuracy against the model is.

use super::assemble::{Assembly, ControllerRecipe, RunError};
use super::file::ControllerType;
use super::Scenario;
use crate::control::ActuatorKind;
use crate::diagnostics::FileError;
use crate::frequency::{
    estimates, log_grid, run_sweep, segments, AxisPlant, Estimate, Excitation, Injected, Injection,
    LinearController, Loop, SampledPlant, Segment, SweepTiming, C64,
};
use crate::report::{BodeRun, Curve, Figures, Points};
use crate::sim::{Lane, LaneKind};
use std::f64::consts::PI;
use std::time::Instant;

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct BodeOptions {
    /// Name of the axis to measure, as the machine names it.
    pub axis: String,
    /// Which loop: the plant inside the closed loop, the velocity loop or the position loop.
    pub lp: Loop,
    /// Lowest and highest frequency (Hz); `None`: the defaults ([`DEFAULT_FROM_HZ`], and
    /// 0.4 of the servo rate).
    pub from: Option<f64>,
    /// Highest frequency (Hz); `None`: [`DEFAULT_TO_SHARE`] of the servo rate.
    pub to: Option<f64>,
    /// Frequencies per decade of the sweep.
    pub per_decade: usize,
    /// What is measured: the Rapier machine, or the analytic reference model.
    pub plant: LaneKind,
}

impl BodeOptions {
    /// The defaults for `axis` and `lp` on the physics.
    pub fn new(axis: &str, lp: Loop) -> Self {
        BodeOptions {
            axis: axis.to_string(),
            lp,
            from: None,
            to: None,
            per_decade: 12,
            plant: LaneKind::Physics,
        }
    }
}

/// Lowest frequency by default (Hz).
pub const DEFAULT_FROM_HZ: f64 = 2.0;
/// Highest frequency by default, as a share of the servo rate 1/T (the Nyquist frequency is
/// half of it).
pub const DEFAULT_TO_SHARE: f64 = 0.4;
/// Most frequencies per decade.
pub const MAX_PER_DECADE: usize = 200;
/// Share of the command range the excitation may use at its worst frequency (by the model).
const COMMAND_SHARE: f64 = 0.2;
/// Largest displacement the excitation may cause (m, or rad on rotary axes), by the model.
const MAX_DISPLACEMENT_LINEAR: f64 = 0.5e-3;
const MAX_DISPLACEMENT_ROTARY: f64 = 0.5 * PI / 180.0;
/// Points of the model's curve (log-spaced over the sweep).
const MODEL_POINTS: usize = 400;

/// Why `bode` gave no result.
#[derive(Debug, thiserror::Error)]
pub enum BodeError {
    /// Bad input: the scenario, the machine or the options.
    #[error(transparent)]
    Input(#[from] RunError),
    /// The measurement ran and could not finish (the loop stopped early).
    #[error("{0}")]
    Failed(String),
}

impl From<FileError> for BodeError {
    fn from(e: FileError) -> Self {
        BodeError::Input(RunError::File(e))
    }
}

/// The axis's linear plant and controller, from the drive data and the scenario.
#[derive(Debug, Clone)]
pub struct AxisLinearModel {
    /// The axis's continuous linear plant.
    pub plant: AxisPlant,
    /// `plant` sampled with the zero-order hold at the servo period.
    pub sampled: SampledPlant,
    /// The scenario's PID or cascade law for this axis, as the linear law it runs.
    pub controller: LinearController,
    /// The controller's output limit and the actuator's own (command units).
    pub command_limit: f64,
}

/// The loop name on the command line and in reports.
pub fn loop_name(lp: Loop) -> &'static str {
    match lp {
        Loop::Plant => "plant",
        Loop::Velocity => "velocity",
        Loop::Position => "position",
    }
}

/// The linearised model of axis `axis` of an assembled scenario: its drive, the mass it moves
/// and its joint damping, and its controller's linear law.
pub fn axis_linear_model(assembly: &Assembly, axis: usize) -> Result<AxisLinearModel, FileError> {
    let s = &assembly.scenario;
    let machine = &assembly.machine;
    let bad = |m: String| FileError::new(&s.path, None, m);
    let ideal = assembly.actuator == ActuatorKind::IdealTorque;
    let drive = &machine.axes[axis].drive;
    let plant = AxisPlant::of_axis(machine, axis, &assembly.start(), assembly.actuator).map_err(|e| {
        bad(format!(
            "bode lays the linear model of the axis over the measurement and sizes the excitation by it, and the model cannot be built: {e}"
        ))
    })?;
    let name = &machine.axes[axis].name;
    let c = s.controller.as_ref().expect("assembled with a controller");
    let period = s.timing.servo_period;
    let (controller, output_limit) = match c.kind {
        ControllerType::Pid => {
            let g = c.pid.axes[name].settings;
            (
                LinearController::Pid {
                    kp: g.kp,
                    ki: g.ki,
                    kd: g.kd,
                    ff0: g.ff0,
                    ff1: g.ff1,
                    ff2: g.ff2,
                },
                g.output_limit,
            )
        }
        ControllerType::Cascade => {
            let a = c.cascade.axes[name].settings;
            let smoothing =
                crate::control::velocity_smoothing(c.cascade.velocity_filter_hz, period);
            (
                LinearController::Cascade {
                    position_kp: a.position_kp,
                    position_ki: a.position_ki,
                    velocity_kp: a.velocity_kp,
                    velocity_ki: a.velocity_ki,
                    velocity_ff: a.velocity_ff,
                    acceleration_ff: a.acceleration_ff,
                    smoothing,
                    filters: a.filters,
                },
                a.output_limit,
            )
        }
        other @ (ControllerType::InverseDynamics | ControllerType::Fmu) => {
            return Err(bad(format!(
                "bode lays the linear law of PID and cascade loops over the measurement; this scenario's controller is type = \"{}\"",
                other.name()
            )))
        }
    };
    let actuator_limit = if ideal {
        drive.peak_torque_nm
    } else {
        drive.supply_voltage_v / drive.amplifier_gain
    };
    Ok(AxisLinearModel {
        sampled: plant.sampled(period),
        plant,
        controller,
        command_limit: output_limit.min(actuator_limit),
    })
}

/// Checks the frequency range against the servo period: 0 < from < to < 1/(2T).
pub fn check_range(from: f64, to: f64, period: f64) -> Result<(), String> {
    let nyquist = 0.5 / period;
    if !(from.is_finite() && from > 0.0) {
        return Err(format!("--from {from}: must be a positive frequency (Hz)"));
    }
    if !(to.is_finite() && to > 0.0) {
        return Err(format!("--to {to}: must be a positive frequency (Hz)"));
    }
    if from >= to {
        return Err(format!("--from {from} Hz must be below --to {to} Hz"));
    }
    if to >= nyquist {
        return Err(format!(
            "--to {to} Hz: at or above the Nyquist frequency {nyquist} Hz of the servo period {} ms; a sampled loop cannot be measured there",
            period * 1e3
        ));
    }
    // The lowest frequency still needs a settled period and blocks of whole periods: keep a
    // sweep to minutes of simulated time.
    if from < 0.01 {
        return Err(format!(
            "--from {from} Hz: below 0.01 Hz a stepped sine takes hours of simulated time"
        ));
    }
    Ok(())
}

/// One sweep: where the excitation enters, with which controller.
struct Sweep {
    injection: Injection,
    recipe: ControllerRecipe,
    /// The model's loop for this sweep (sizes the amplitude): its open loop for an
    /// injection.
    lp: Loop,
}

/// What one sweep measured, over one or more runs of the loop.
struct Measured {
    excitation: Excitation,
    estimates: Vec<Estimate>,
    ticks: usize,
    /// Runs of the loop (each with its lead-in).
    runs: usize,
}

impl Measured {
    /// Joins another run's points, kept in frequency order.
    fn add(&mut self, more: Measured) {
        self.ticks += more.ticks;
        self.runs += more.runs;
        self.estimates.extend(more.estimates);
        self.estimates
            .sort_by(|a, b| a.frequency.total_cmp(&b.frequency));
    }
}

/// The amplitude the model allows: the command within [`COMMAND_SHARE`] of its range and the
/// displacement within its limit at every frequency of the sweep.
fn amplitude(model: &AxisLinearModel, sweep: &Sweep, segs: &[Segment], rotary: bool) -> f64 {
    let max_disp = if rotary {
        MAX_DISPLACEMENT_ROTARY
    } else {
        MAX_DISPLACEMENT_LINEAR
    };
    let (mut command, mut displacement) = (0.0f64, 0.0f64);
    for s in segs {
        let (u, x) = excited(model, sweep, s.frequency);
        command = command.max(u.norm());
        displacement = displacement.max(x.norm());
    }
    let by_command = COMMAND_SHARE * model.command_limit / command;
    let by_displacement = max_disp / displacement;
    by_command.min(by_displacement)
}

/// Measures the frequency response `options` asks for. `progress(done, total)` hears about the
/// loop's ticks and stops the measurement when it returns `false`.
pub fn run_bode(
    s: &Scenario,
    options: &BodeOptions,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<BodeRun, BodeError> {
    bode_on(&Assembly::new(s)?, options, progress)
}

/// [`run_bode`] on a scenario already assembled: the coarse sweep, a zoom around every peak
/// and dip, a search on the physics that locates each of them, then the curves and figures.
pub fn bode_on(
    assembly: &Assembly,
    options: &BodeOptions,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<BodeRun, BodeError> {
    let started = Instant::now();
    let axis = checked_axis(assembly, options)?;
    let model = axis_linear_model(assembly, axis)?;
    let period = assembly.scenario.timing.servo_period;
    let (from, to) = (
        options.from.unwrap_or(DEFAULT_FROM_HZ),
        options.to.unwrap_or(DEFAULT_TO_SHARE / period),
    );
    let bad = |m: String| BodeError::from(FileError::new(&assembly.scenario.path, None, m));
    check_range(from, to, period).map_err(bad)?;
    if !(1..=MAX_PER_DECADE).contains(&options.per_decade) {
        return Err(bad(format!(
            "--per-decade {}: must be from 1 to {MAX_PER_DECADE}",
            options.per_decade
        )));
    }
    let sweeps = sweeps(assembly, options.lp, axis);
    let ringing = sweeps
        .iter()
        .map(|sweep| ringing_time(&model, sweep, from, to))
        .fold(0.0, f64::max);
    let timing = SweepTiming {
        min_settle: (SETTLE_TIME_CONSTANTS * ringing)
            .clamp(SweepTiming::default().min_settle, MAX_SETTLE_S),
        ..SweepTiming::default()
    };
    let meter = Meter {
        assembly,
        model: &model,
        axis,
        kind: options.plant,
        timing,
    };
    let decades = (to / from).log10();
    let count = ((decades * options.per_decade as f64).ceil() as usize + 1).max(2);
    let segs = segments(&log_grid(from, to, count), period, &timing);
    let mut measured = Vec::new();
    for sweep in &sweeps {
        measured.push(meter.measure(sweep, &segs, progress)?);
    }
    let feature = Feature {
        lp: options.lp,
        from,
        to,
    };
    let fine_segs = zoom_segments(&meter, &feature, &measured, &segs);
    if !fine_segs.is_empty() {
        for (sweep, m) in sweeps.iter().zip(measured.iter_mut()) {
            let more = meter.measure(sweep, &fine_segs, progress)?;
            m.add(more);
        }
    }
    let search = search_extrema(&meter, &feature, &sweeps, &mut measured, progress)?;
    let mut run = BodeReport::new(assembly, options, &model, axis, &measured).run(from, to);
    let runs = measured.iter().map(|m| m.runs).sum::<usize>();
    let ticks: usize = measured.iter().map(|m| m.ticks).sum();
    let settle = crate::frequency::measure::lead_in(&assembly.loop_settings) * runs;
    run.simulated_time_s = (ticks + settle) as f64 * period;
    run.wall_time_s = started.elapsed().as_secs_f64();
    run.settle_s = timing.min_settle;
    run.search_resolution = search;
    if SETTLE_TIME_CONSTANTS * ringing > MAX_SETTLE_S {
        run.notes.push(format!(
            "the loop rings with a time constant of {ringing:.1} s by the model: each frequency settled for {MAX_SETTLE_S} s only, and points near that mode may still carry its transient"
        ));
    }
    Ok(run)
}

/// The axis `options` names, and whether its loop can be measured.
fn checked_axis(assembly: &Assembly, options: &BodeOptions) -> Result<usize, BodeError> {
    let s = &assembly.scenario;
    let bad = |m: String| BodeError::from(FileError::new(&s.path, None, m));
    let machine = &assembly.machine;
    let Some(axis) = machine.axis_index(&options.axis) else {
        let names: Vec<&str> = machine.axes.iter().map(|a| a.name.as_str()).collect();
        return Err(bad(format!(
            "--axis {}: the machine '{}' has no such axis (its axes: {})",
            options.axis,
            machine.name,
            names.join(", ")
        )));
    };
    let kind = s.controller_type().expect("assembled with a controller");
    if options.lp == Loop::Velocity && kind != ControllerType::Cascade {
        return Err(bad(format!(
            "--loop velocity measures the velocity loop of a cascade; this scenario's controller is type = \"{}\" (no velocity loop of its own: use --loop plant or position)",
            kind.name()
        )));
    }
    Ok(axis)
}

/// The sweeps a loop takes: a setpoint sweep for the closed loop (position, velocity), then
/// (always last) an injection at the controller output for the plant and the open loop.
fn sweeps(assembly: &Assembly, lp: Loop, axis: usize) -> Vec<Sweep> {
    let velocity_recipe = || {
        assembly
            .controller
            .velocity_mode(axis)
            .expect("checked: a cascade")
    };
    let injection = |recipe: ControllerRecipe, lp: Loop| Sweep {
        injection: Injection::ControllerOutput,
        recipe,
        lp,
    };
    match lp {
        Loop::Plant => vec![injection(assembly.controller.clone(), Loop::Plant)],
        Loop::Position => vec![
            Sweep {
                injection: Injection::PositionSetpoint,
                recipe: assembly.controller.clone(),
                lp: Loop::Position,
            },
            injection(assembly.controller.clone(), Loop::Plant),
        ],
        Loop::Velocity => vec![
            Sweep {
                injection: Injection::VelocitySetpoint,
                recipe: velocity_recipe(),
                lp: Loop::Velocity,
            },
            injection(velocity_recipe(), Loop::Velocity),
        ],
    }
}

/// Time constants a frequency settles for: the loop's slowest ringing decays to e⁻⁵ (0.7 %)
/// of its start before the frequency is measured.
const SETTLE_TIME_CONSTANTS: f64 = 5.0;
/// Longest settling per frequency (s): a loop ringing longer is measured anyway, with a note.
const MAX_SETTLE_S: f64 = 20.0;
/// Points of the model's grid that finds the loop's ringing (a half-power width of 0.1 %
/// spans several of them over two decades).
const RINGING_GRID: usize = 8000;

/// The command and the plant output per unit of excitation by the model (injected at the plant
/// input: u = d/(1 + L), x = P·d/(1 + L); on a setpoint: the closed loop's).
fn excited(model: &AxisLinearModel, sweep: &Sweep, f: f64) -> (C64, C64) {
    let r = model
        .controller
        .response(sweep.lp, &model.plant, &model.sampled, f);
    match sweep.injection {
        Injection::ControllerOutput => {
            let s = 1.0 / (1.0 + r.open);
            (s, r.plant.feedback * s)
        }
        _ => (r.command, r.displacement),
    }
}

/// The slowest decay time (s) of the loop a sweep runs, by the model: a lightly damped peak of
/// its response to the excitation rings with τ = 1/(π·Δf), Δf its half-power width; 0 where
/// no peak stands 3 dB out within the sweep.
fn ringing_time(model: &AxisLinearModel, sweep: &Sweep, from: f64, to: f64) -> f64 {
    let grid = log_grid(from, to, RINGING_GRID);
    let mag: Vec<f64> = grid
        .iter()
        .map(|&f| crate::frequency::estimate::db(excited(model, sweep, f).1.norm()))
        .collect();
    let half = 10.0 * 2f64.log10();
    let crossing = |i: usize, j: usize, level: f64| {
        let s = (mag[i] - level) / (mag[i] - mag[j]);
        (grid[i].ln() + s * (grid[j].ln() - grid[i].ln())).exp()
    };
    let mut slowest: f64 = 0.0;
    for i in 1..grid.len() - 1 {
        if !(mag[i] > mag[i - 1] && mag[i] >= mag[i + 1]) {
            continue;
        }
        let level = mag[i] - half;
        let left = (1..=i).rev().find(|&j| mag[j - 1] < level);
        let right = (i..grid.len() - 1).find(|&j| mag[j + 1] < level);
        if let (Some(l), Some(r)) = (left, right) {
            let width = crossing(r, r + 1, level) - crossing(l, l - 1, level);
            // Between the half-power points nothing may rise above the peak: one mode.
            if mag[l..=r].iter().all(|&m| m <= mag[i]) && width > 0.0 {
                slowest = slowest.max(1.0 / (PI * width));
            }
        }
    }
    slowest
}

/// What measures: the assembled scenario, the axis's model, the plant and the sweep timing.
struct Meter<'a> {
    assembly: &'a Assembly,
    model: &'a AxisLinearModel,
    axis: usize,
    kind: LaneKind,
    timing: SweepTiming,
}

impl Meter<'_> {
    /// One run of the loop through `segs` (excited as `sweep` says), estimated.
    fn measure(
        &self,
        sweep: &Sweep,
        segs: &[Segment],
        progress: &mut dyn FnMut(usize, usize) -> bool,
    ) -> Result<Measured, BodeError> {
        let assembly = self.assembly;
        let rotary = assembly.labels[self.axis].rotary;
        let excitation = Excitation {
            axis: self.axis,
            injection: sweep.injection,
            amplitude: amplitude(self.model, sweep, segs, rotary),
            segments: segs.to_vec(),
            start: assembly.start(),
            period: assembly.scenario.timing.servo_period,
        };
        let settings = &assembly.loop_settings;
        let plant = assembly.plant(self.kind, &excitation.start)?;
        let inner = sweep.recipe.build();
        let controller: Box<dyn crate::control::Controller + '_> = match sweep.injection {
            Injection::ControllerOutput => Box::new(Injected::new(
                inner,
                &excitation,
                crate::frequency::measure::lead_in(settings),
            )),
            _ => inner,
        };
        let lane = Lane {
            kind: self.kind,
            plant,
            controller,
        };
        let (samples, stop) = run_sweep(settings, lane, &excitation, progress);
        if let Some(stop) = stop {
            return Err(BodeError::Failed(format!(
                "{}: the sweep stopped: {stop}",
                assembly.scenario.path.display()
            )));
        }
        let estimates = estimates(&excitation, &samples);
        Ok(Measured {
            ticks: samples.excitation.len(),
            runs: 1,
            excitation,
            estimates,
        })
    }
}

/// The response whose peaks and dips are the figures: the plant (plant loop) or the open loop
/// (position and velocity loops), over the sweep's range.
struct Feature {
    lp: Loop,
    from: f64,
    to: f64,
}

impl Feature {
    /// The feature as measured in an estimate.
    fn of(&self, e: &Estimate) -> Option<C64> {
        match self.lp {
            Loop::Plant => e.plant_feedback,
            _ => e.open,
        }
    }

    /// The feature by the model.
    fn model(&self, model: &AxisLinearModel, f: f64) -> C64 {
        let lp = if self.lp == Loop::Velocity {
            Loop::Velocity
        } else {
            Loop::Plant
        };
        let r = model
            .controller
            .response(lp, &model.plant, &model.sampled, f);
        if self.lp == Loop::Plant {
            r.plant.feedback
        } else {
            r.open
        }
    }
}

/// Zoom: around every peak or dip of the feature that the coarse sweep or the model shows, a
/// fine sweep (±25 %, steps of 2 %), the coarse grid's frequencies left out.
fn zoom_segments(
    meter: &Meter<'_>,
    feature: &Feature,
    measured: &[Measured],
    coarse_segs: &[Segment],
) -> Vec<Segment> {
    let coarse = &measured.last().expect("one sweep at least").estimates;
    let cf: Vec<f64> = coarse.iter().map(|e| e.frequency).collect();
    let cm: Vec<f64> = coarse
        .iter()
        .map(|e| feature.of(e).map_or(f64::NAN, |h| 20.0 * h.norm().log10()))
        .collect();
    let cc: Vec<f64> = coarse.iter().map(|e| e.coherence).collect();
    let mut centres: Vec<f64> = [true, false]
        .iter()
        .flat_map(|&peaks| crate::frequency::extrema(&cf, &cm, &cc, peaks, 1.0, 0.8))
        .collect();
    let model_grid = log_grid(feature.from, feature.to, 2000);
    let model_mag: Vec<f64> = model_grid
        .iter()
        .map(|&f| 20.0 * feature.model(meter.model, f).norm().log10())
        .collect();
    let ones = vec![1.0; model_grid.len()];
    for peaks in [true, false] {
        centres.extend(crate::frequency::extrema(
            &model_grid,
            &model_mag,
            &ones,
            peaks,
            1.0,
            0.5,
        ));
    }
    let mut fine: Vec<f64> = centres
        .iter()
        .flat_map(|&c| log_grid(c / 1.25, c * 1.25, 23))
        .filter(|&f| f > feature.from && f < feature.to)
        .collect();
    fine.sort_by(f64::total_cmp);
    let period = meter.assembly.scenario.timing.servo_period;
    segments(&fine, period, &meter.timing)
        .into_iter()
        .filter(|s| {
            !coarse_segs
                .iter()
                .any(|c| (c.frequency / s.frequency - 1.0).abs() < 1e-9)
        })
        .collect()
}

/// Relative frequency resolution the search on the physics stops at: each peak and dip is
/// then known to ±0.05 % of its frequency.
const SEARCH_RESOLUTION: f64 = 1e-3;
/// Most rounds of the search per peak or dip.
const SEARCH_ROUNDS: usize = 8;
/// Blocks measured per frequency of the search.
const SEARCH_BLOCKS: usize = 2;

/// Locates every peak and dip of the measured feature by a search on the physics: the best
/// point and its neighbours bracket it; each round measures the geometric midpoints of the
/// two gaps (in one run of the loop, with blocks long enough that each frequency lands within
/// a quarter of the gap of where it is asked) and keeps the best of the five and its
/// neighbours, until both gaps are below [`SEARCH_RESOLUTION`]. The points join the
/// measurement; returns the relative resolution reached (the widest final gap), `None`
/// where there was nothing to search.
fn search_extrema(
    meter: &Meter<'_>,
    feature: &Feature,
    sweeps: &[Sweep],
    measured: &mut [Measured],
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<Option<f64>, BodeError> {
    let sweep = sweeps.last().expect("one sweep at least");
    let found = measured.last_mut().expect("one sweep at least");
    let mut reached: Option<f64> = None;
    for peaks in [true, false] {
        let centres = {
            let (f, m, c) = feature_points(feature, &found.estimates);
            crate::frequency::extrema(
                &f,
                &m,
                &c,
                peaks,
                crate::report::PROMINENCE_DB,
                crate::report::MIN_COHERENCE,
            )
        };
        for centre in centres {
            let gap = search_one(meter, feature, sweep, found, centre, peaks, progress)?;
            if let Some(gap) = gap {
                reached = Some(reached.map_or(gap, |r: f64| r.max(gap)));
            }
        }
    }
    Ok(reached)
}

/// The feature's frequencies, magnitudes (dB, NaN where not measured) and coherences.
fn feature_points(feature: &Feature, estimates: &[Estimate]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let f = estimates.iter().map(|e| e.frequency).collect();
    let m = estimates
        .iter()
        .map(|e| {
            feature
                .of(e)
                .map_or(f64::NAN, |h| crate::frequency::estimate::db(h.norm()))
        })
        .collect();
    let c = estimates.iter().map(|e| e.coherence).collect();
    (f, m, c)
}

/// One peak (or dip) near `centre`, searched as [`search_extrema`] says; the widest final gap.
fn search_one(
    meter: &Meter<'_>,
    feature: &Feature,
    sweep: &Sweep,
    found: &mut Measured,
    centre: f64,
    peaks: bool,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<Option<f64>, BodeError> {
    let sign = if peaks { 1.0 } else { -1.0 };
    let period = meter.assembly.scenario.timing.servo_period;
    for _ in 0..SEARCH_ROUNDS {
        let (f, m, c) = feature_points(feature, &found.estimates);
        // The best coherent point near the centre and its neighbours.
        let Some(best) = (0..f.len())
            .filter(|&i| c[i] >= crate::report::MIN_COHERENCE && (f[i] / centre).ln().abs() < 0.05)
            .max_by(|&a, &b| (sign * m[a]).total_cmp(&(sign * m[b])))
        else {
            return Ok(None);
        };
        if best == 0 || best + 1 == f.len() {
            return Ok(None);
        }
        let gaps = [(f[best] / f[best - 1]).ln(), (f[best + 1] / f[best]).ln()];
        let widest = gaps[0].max(gaps[1]);
        if widest <= SEARCH_RESOLUTION {
            return Ok(Some(widest));
        }
        // Midpoints of the gaps wider than the resolution, placed within a quarter gap.
        let asked: Vec<(f64, f64)> = [(best - 1, gaps[0]), (best, gaps[1])]
            .iter()
            .filter(|(_, g)| *g > SEARCH_RESOLUTION)
            .map(|&(i, g)| ((f[i] * f[i + 1]).sqrt(), g))
            .collect();
        let mut segs = Vec::new();
        for (frequency, gap) in asked {
            let timing = SweepTiming {
                min_block: (2.0 * period / gap).max(meter.timing.min_block),
                blocks: SEARCH_BLOCKS,
                ..meter.timing
            };
            segs.extend(segments(&[frequency], period, &timing));
        }
        segs.retain(|s| !f.iter().any(|&g| (g / s.frequency - 1.0).abs() < 1e-12));
        if segs.is_empty() {
            return Ok(Some(widest));
        }
        let more = meter.measure(sweep, &segs, progress)?;
        found.add(more);
    }
    Ok(None)
}

/// The curves, figures and notes of a measurement, with the model laid over them.
struct BodeReport<'a> {
    assembly: &'a Assembly,
    options: &'a BodeOptions,
    model: &'a AxisLinearModel,
    axis: usize,
    /// Every sweep: the main response's first, the injection (plant, open loop) last.
    measured: &'a [Measured],
}

impl<'a> BodeReport<'a> {
    fn new(
        assembly: &'a Assembly,
        options: &'a BodeOptions,
        model: &'a AxisLinearModel,
        axis: usize,
        measured: &'a [Measured],
    ) -> Self {
        BodeReport {
            assembly,
            options,
            model,
            axis,
            measured,
        }
    }

    fn main(&self) -> &Measured {
        &self.measured[0]
    }

    fn injected(&self) -> &Measured {
        self.measured.last().expect("at least one sweep")
    }

    /// The model's loop for the open loop: in velocity mode, the velocity loop alone.
    fn open_lp(&self) -> Loop {
        if self.options.lp == Loop::Velocity {
            Loop::Velocity
        } else {
            Loop::Plant
        }
    }

    fn respond(&self, lp: Loop, f: f64) -> crate::frequency::LoopResponse {
        self.model
            .controller
            .response(lp, &self.model.plant, &self.model.sampled, f)
    }

    /// The model's main response at `f`.
    fn model_main(&self, f: f64) -> C64 {
        match self.options.lp {
            Loop::Plant => self.respond(Loop::Plant, f).plant.feedback,
            lp => self.respond(lp, f).closed,
        }
    }

    fn command_unit(&self) -> &'static str {
        if self.assembly.actuator == ActuatorKind::IdealTorque {
            "N·m"
        } else {
            "V"
        }
    }

    /// What the main response is, its magnitude unit and its scale (joint units to shown).
    fn main_response(&self) -> (String, String, f64) {
        let label = &self.assembly.labels[self.axis];
        match self.options.lp {
            Loop::Plant => (
                "plant: feedback position / command".to_string(),
                format!("dB re 1 {}/{}", label.unit(), self.command_unit()),
                label.scale(),
            ),
            Loop::Position => (
                "closed position loop: feedback position / setpoint".to_string(),
                "dB".to_string(),
                1.0,
            ),
            Loop::Velocity => (
                "closed velocity loop: motor velocity / velocity command".to_string(),
                "dB".to_string(),
                1.0,
            ),
        }
    }

    /// The result: curves measured and modelled, figures of both, notes.
    fn run(&self, from: f64, to: f64) -> BodeRun {
        let (main, injected) = (self.main(), self.injected());
        let lp = self.options.lp;
        let open_lp = self.open_lp();
        let (response, magnitude_unit, main_scale) = self.main_response();
        // The main response: measured, and the model's at the same frequencies and densely.
        let freq: Vec<f64> = main.estimates.iter().map(|e| e.frequency).collect();
        let measured_main: Vec<C64> = match lp {
            Loop::Plant => main
                .estimates
                .iter()
                .map(|e| e.plant_feedback.expect("injection"))
                .collect(),
            _ => main.estimates.iter().map(|e| e.closed).collect(),
        };
        let dense = log_grid(from, to, MODEL_POINTS);
        let model_main_dense: Vec<C64> = dense.iter().map(|&f| self.model_main(f)).collect();
        let model_open_dense: Vec<C64> = dense
            .iter()
            .map(|&f| self.respond(open_lp, f).open)
            .collect();
        let model_main_points: Vec<C64> = freq.iter().map(|&f| self.model_main(f)).collect();
        // Phases on the model's branch at the lowest frequency.
        let reference = model_main_dense.first().map_or(0.0, |h| h.arg());
        let reference = principal_near(reference, -PI / 2.0);
        let open_reference = principal_near(model_open_dense.first().map_or(-PI, |h| h.arg()), -PI);
        let model_curve = Curve::new(&dense, &model_main_dense, main_scale, reference);
        let model_open_curve = Curve::new(&dense, &model_open_dense, 1.0, open_reference);
        let model_points_curve = Curve::new(&freq, &model_main_points, main_scale, reference);
        let measured_curve = Curve::near(
            &freq,
            &measured_main,
            main_scale,
            &model_points_curve.phase_deg,
        );
        let open_measured: Vec<C64> = injected
            .estimates
            .iter()
            .map(|e| e.open.expect("injection"))
            .collect();
        let open_freq: Vec<f64> = injected.estimates.iter().map(|e| e.frequency).collect();
        let model_open_points: Vec<C64> = open_freq
            .iter()
            .map(|&f| self.respond(open_lp, f).open)
            .collect();
        let model_open_points = Curve::new(&open_freq, &model_open_points, 1.0, open_reference);
        let open_curve = Curve::near(
            &open_freq,
            &open_measured,
            1.0,
            &model_open_points.phase_deg,
        );
        let coherence: Vec<f64> = main.estimates.iter().map(|e| e.coherence).collect();
        let injected_coherence: Vec<f64> = injected.estimates.iter().map(|e| e.coherence).collect();

        // Figures: peaks and dips of the plant (plant loop) or the open loop; bandwidth of the
        // closed loop; margins of the open loop. The plant loop measures all three in one
        // sweep; the others measure the closed loop in the main sweep and the open loop (the
        // feature) in the injected one.
        let closed_measured: Vec<C64> = match lp {
            Loop::Plant => injected.estimates.iter().map(|e| e.closed).collect(),
            _ => main.estimates.iter().map(|e| e.closed).collect(),
        };
        let open_points = Points {
            frequency: &open_freq,
            values: &open_measured,
            coherence: &injected_coherence,
        };
        let (closed_points, feature_points) = match lp {
            Loop::Plant => (
                Points {
                    values: &closed_measured,
                    ..open_points
                },
                Points {
                    frequency: &freq,
                    values: &measured_main,
                    coherence: &coherence,
                },
            ),
            _ => (
                Points {
                    frequency: &freq,
                    values: &closed_measured,
                    coherence: &coherence,
                },
                open_points,
            ),
        };
        let figures = Figures::of(feature_points, closed_points, open_points);
        let model_closed: Vec<C64> = match lp {
            Loop::Plant => dense
                .iter()
                .map(|&f| self.respond(Loop::Plant, f).closed)
                .collect(),
            _ => model_main_dense.clone(),
        };
        let model_feature = match lp {
            Loop::Plant => model_main_dense.clone(),
            _ => model_open_dense.clone(),
        };
        let ones = vec![1.0; dense.len()];
        let model_points = |values| Points {
            frequency: &dense,
            values,
            coherence: &ones,
        };
        let mut model_figures = Figures::of(
            model_points(&model_feature),
            model_points(&model_closed),
            model_points(&model_open_dense),
        );
        self.refine_model_extrema(&mut model_figures, &dense);
        let peak_command = self
            .measured
            .iter()
            .flat_map(|m| m.estimates.iter().map(|e| e.peak_command))
            .fold(0.0, f64::max);
        let label = &self.assembly.labels[self.axis];
        let (excitation, amplitude_unit, amplitude_scale) = match main.excitation.injection {
            Injection::ControllerOutput => (
                "sine added to the controller output",
                self.command_unit().to_string(),
                1.0,
            ),
            Injection::PositionSetpoint => (
                "sine on the position setpoint",
                label.unit().to_string(),
                label.scale(),
            ),
            Injection::VelocitySetpoint => (
                "cosine on the velocity command",
                format!("{}/s", label.unit()),
                label.scale(),
            ),
        };
        BodeRun {
            scenario: self.assembly.scenario.name.clone(),
            axis: self.options.axis.clone(),
            loop_name: loop_name(lp).to_string(),
            plant: self.options.plant.name().to_string(),
            response,
            magnitude_unit,
            servo_period_s: self.assembly.scenario.timing.servo_period,
            excitation: excitation.to_string(),
            amplitude: main.excitation.amplitude * amplitude_scale,
            amplitude_unit,
            frequencies_hz: freq,
            magnitude_db: measured_curve.magnitude_db,
            phase_deg: measured_curve.phase_deg,
            notes: self.notes(&coherence, peak_command),
            coherence,
            open_loop: open_curve,
            figures,
            model: model_curve,
            model_open_loop: model_open_curve,
            model_figures,
            model_at_points: model_points_curve,
            peak_command,
            command_limit: self.model.command_limit,
            simulated_time_s: 0.0,
            wall_time_s: 0.0,
            settle_s: 0.0,
            search_resolution: None,
        }
    }

    /// The model's peaks and dips located on the model itself (golden-section search within a
    /// step of the grid either side), not on the grid's parabola.
    fn refine_model_extrema(&self, figures: &mut Figures, grid: &[f64]) {
        let feature = Feature {
            lp: self.options.lp,
            from: grid[0],
            to: grid[grid.len() - 1],
        };
        let step = (grid[1] / grid[0]).ln();
        let magnitude = |f: f64| feature.model(self.model, f).norm().ln();
        for (list, sign) in [
            (&mut figures.resonances_hz, 1.0),
            (&mut figures.antiresonances_hz, -1.0),
        ] {
            for f in list.iter_mut() {
                // 60 golden sections narrow two grid steps to 10⁻¹² of a step.
                let (at, _) = crate::report::golden(f.ln() - step, f.ln() + step, 60, &mut |x| {
                    -sign * magnitude(x.exp())
                });
                *f = at.exp();
            }
        }
    }

    /// What the measurement could not do, or leaves out.
    fn notes(&self, coherence: &[f64], peak_command: f64) -> Vec<String> {
        let mut notes = Vec::new();
        if peak_command >= 0.999 * self.model.command_limit {
            notes.push(format!(
                "the command reached its limit {:.3} {}: the points where it did are not linear",
                self.model.command_limit,
                self.command_unit()
            ));
        }
        let incoherent = coherence
            .iter()
            .filter(|&&c| c < crate::report::MIN_COHERENCE)
            .count();
        if incoherent > 0 {
            notes.push(format!(
                "{incoherent} of {} points have coherence below {}: friction, backlash, encoder steps or saturation make the response depend on more than the excitation there",
                coherence.len(),
                crate::report::MIN_COHERENCE
            ));
        }
        let drive = &self.assembly.machine.axes[self.axis].drive;
        let label = &self.assembly.labels[self.axis];
        if drive.backlash > 0.0 {
            notes.push(format!(
                "the axis has {:.3} {} of backlash, which the linear model leaves out",
                drive.backlash * label.scale(),
                label.unit()
            ));
        }
        if drive.guide.is_some() {
            notes.push(
                "the axis's guide has Coulomb friction, which the linear model leaves out".into(),
            );
        }
        notes
    }
}

/// `angle` moved by whole turns into (centre − π, centre + π].
fn principal_near(angle: f64, centre: f64) -> f64 {
    let turns = ((angle - centre) / std::f64::consts::TAU).round();
    angle - turns * std::f64::consts::TAU
}

/// A `cncsim bode` result with where its files go.
pub struct BodeOutput {
    /// The measurement, the model laid over it and what was found in them.
    pub run: BodeRun,
    /// The output folder: bode.png, bode.csv, bode.json, bode.rrd.
    pub out: std::path::PathBuf,
}

impl crate::command::Report for BodeOutput {
    fn write(&self) -> Result<Vec<std::path::PathBuf>, crate::command::WriteError> {
        std::fs::create_dir_all(&self.out)
            .map_err(|e| crate::command::cannot_write(&self.out, e))?;
        let png = self.out.join("bode.png");
        self.run.write_plot(&png)?;
        let csv = crate::command::write_file(self.out.join("bode.csv"), self.run.csv())?;
        let json = crate::command::write_file(
            self.out.join("bode.json"),
            serde_json::to_string_pretty(&self.run).expect("plain values") + "\n",
        )?;
        let rrd = self.out.join("bode.rrd");
        self.run.write_recording(&rrd)?;
        Ok(vec![png, csv, json, rrd])
    }

    fn text(&self) -> String {
        self.run.text()
    }

    fn json(&self) -> Option<serde_json::Value> {
        serde_json::to_value(&self.run).ok()
    }
}
