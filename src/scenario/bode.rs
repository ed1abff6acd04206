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

use super::assemble::{Assembly, ControllerRecipe, RunError, GRAVITY};
use super::file::ControllerType;
use super::Scenario;
use crate::control::ActuatorKind;
use crate::diagnostics::FileError;
use crate::frequency::{
    estimates, log_grid, run_sweep, segments, AxisPlant, Estimate, Excitation, Injected, Injection,
    LinearController, Loop, SampledPlant, Segment, SweepTiming, Transmission, C64,
};
use crate::report::{BodeRun, Curve, Figures};
use crate::sim::analytic::AxisModel;
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
    let models = AxisModel::for_machine(machine, GRAVITY, ideal).map_err(|e| {
        bad(format!(
            "bode lays the linear model of the axis over the measurement and sizes the excitation by it, and the axis model cannot be built: {e}"
        ))
    })?;
    let drive = &machine.axes[axis].drive;
    let model = &models[axis];
    let moved = model.effective_mass() - drive.reflected_inertia();
    let joint_damping = model.effective_damping() - drive.reflected_damping();
    let transmission = drive
        .compliance()
        .map_or(Transmission::RIGID, |c| Transmission {
            stiffness: c.stiffness,
            damping: c.damping,
        });
    let plant = AxisPlant::from_drive(drive, moved, joint_damping, transmission, assembly.actuator);
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
            let fc = c.cascade.velocity_filter_hz;
            let smoothing = if fc > 0.0 {
                1.0 - (-std::f64::consts::TAU * fc * period).exp()
            } else {
                1.0
            };
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

/// What one sweep measured.
struct Measured {
    excitation: Excitation,
    estimates: Vec<Estimate>,
    ticks: usize,
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
        let r = model
            .controller
            .response(sweep.lp, &model.plant, &model.sampled, s.frequency);
        let (u, x) = match sweep.injection {
            // Injected at the plant input: u = d/(1 + L), x = P·d/(1 + L).
            Injection::ControllerOutput => {
                let s = 1.0 / (1.0 + r.open);
                (s, r.plant.feedback * s)
            }
            _ => (r.command, r.displacement),
        };
        command = command.max(u.norm());
        displacement = displacement.max(x.norm());
    }
    let by_command = COMMAND_SHARE * model.command_limit / command;
    let by_displacement = max_disp / displacement;
    by_command.min(by_displacement)
}

fn measure(
    assembly: &Assembly,
    model: &AxisLinearModel,
    axis: usize,
    sweep: &Sweep,
    segs: &[Segment],
    kind: LaneKind,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<Measured, BodeError> {
    let rotary = assembly.labels[axis].rotary;
    let excitation = Excitation {
        axis,
        injection: sweep.injection,
        amplitude: amplitude(model, sweep, segs, rotary),
        segments: segs.to_vec(),
        start: assembly.start(),
        period: assembly.scenario.timing.servo_period,
    };
    let settings = &assembly.loop_settings;
    let plant = assembly.plant(kind, &excitation.start)?;
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
        kind,
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
        excitation,
        estimates,
    })
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

/// [`run_bode`] on a scenario already assembled.
pub fn bode_on(
    assembly: &Assembly,
    options: &BodeOptions,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<BodeRun, BodeError> {
    let started = Instant::now();
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
    let model = axis_linear_model(assembly, axis)?;
    let period = s.timing.servo_period;
    let from = options.from.unwrap_or(DEFAULT_FROM_HZ);
    let to = options.to.unwrap_or(DEFAULT_TO_SHARE / period);
    check_range(from, to, period).map_err(bad)?;
    if !(1..=MAX_PER_DECADE).contains(&options.per_decade) {
        return Err(bad(format!(
            "--per-decade {}: must be from 1 to {MAX_PER_DECADE}",
            options.per_decade
        )));
    }
    let decades = (to / from).log10();
    let count = ((decades * options.per_decade as f64).ceil() as usize + 1).max(2);
    let segs = segments(&log_grid(from, to, count), period, &SweepTiming::default());

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
    let sweeps: Vec<Sweep> = match options.lp {
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
    };
    let mut measured = Vec::new();
    for sweep in &sweeps {
        measured.push(measure(
            assembly,
            &model,
            axis,
            sweep,
            &segs,
            options.plant,
            progress,
        )?);
    }
    // Zoom: around every peak or dip of the feature response (the plant, or the open loop)
    // that the coarse sweep or the model shows, a fine sweep (±25 %, steps of 2 %), so that
    // a sharp resonance is located to a percent and not to the coarse grid's spacing.
    let feature_lp = if options.lp == Loop::Velocity {
        Loop::Velocity
    } else {
        Loop::Plant
    };
    let feature_of = |e: &Estimate| match options.lp {
        Loop::Plant => e.plant_feedback,
        _ => e.open,
    };
    let coarse = &measured.last().expect("one sweep at least").estimates;
    let cf: Vec<f64> = coarse.iter().map(|e| e.frequency).collect();
    let cm: Vec<f64> = coarse
        .iter()
        .map(|e| feature_of(e).map_or(f64::NAN, |h| 20.0 * h.norm().log10()))
        .collect();
    let cc: Vec<f64> = coarse.iter().map(|e| e.coherence).collect();
    let mut centres: Vec<f64> = [true, false]
        .iter()
        .flat_map(|&peaks| crate::frequency::extrema(&cf, &cm, &cc, peaks, 1.0, 0.8))
        .collect();
    let model_grid = log_grid(from, to, 2000);
    let model_mag: Vec<f64> = model_grid
        .iter()
        .map(|&f| {
            let r = model
                .controller
                .response(feature_lp, &model.plant, &model.sampled, f);
            let h = if options.lp == Loop::Plant {
                r.plant.feedback
            } else {
                r.open
            };
            20.0 * h.norm().log10()
        })
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
        .filter(|&f| f > from && f < to)
        .collect();
    fine.sort_by(f64::total_cmp);
    let fine_segs: Vec<Segment> = segments(&fine, period, &SweepTiming::default())
        .into_iter()
        .filter(|s| {
            !segs
                .iter()
                .any(|c| (c.frequency / s.frequency - 1.0).abs() < 1e-9)
        })
        .collect();
    if !fine_segs.is_empty() {
        for (sweep, m) in sweeps.iter().zip(measured.iter_mut()) {
            let more = measure(
                assembly,
                &model,
                axis,
                sweep,
                &fine_segs,
                options.plant,
                progress,
            )?;
            m.ticks += more.ticks;
            m.estimates.extend(more.estimates);
            m.estimates
                .sort_by(|a, b| a.frequency.total_cmp(&b.frequency));
        }
    }
    let main = &measured[0];
    let injected = measured.last().expect("at least one sweep");

    // The model's loop for the open loop: in velocity mode, the velocity loop alone.
    let open_lp = if options.lp == Loop::Velocity {
        Loop::Velocity
    } else {
        Loop::Plant
    };
    let respond = |lp: Loop, f: f64| {
        model
            .controller
            .response(lp, &model.plant, &model.sampled, f)
    };
    let label = &assembly.labels[axis];
    let (unit, scale) = (label.unit(), label.scale());
    let command_unit = if assembly.actuator == ActuatorKind::IdealTorque {
        "N·m"
    } else {
        "V"
    };
    // The main response: measured, and the model's at the same frequencies and densely.
    let freq: Vec<f64> = main.estimates.iter().map(|e| e.frequency).collect();
    let (measured_main, model_main): (Vec<C64>, Box<dyn Fn(f64) -> C64 + '_>) = match options.lp {
        Loop::Plant => (
            main.estimates
                .iter()
                .map(|e| e.plant_feedback.expect("injection"))
                .collect(),
            Box::new(move |f| respond(Loop::Plant, f).plant.feedback),
        ),
        lp => (
            main.estimates.iter().map(|e| e.closed).collect(),
            Box::new(move |f| respond(lp, f).closed),
        ),
    };
    let (response, magnitude_unit, main_scale) = match options.lp {
        Loop::Plant => (
            "plant: feedback position / command".to_string(),
            format!("dB re 1 {unit}/{command_unit}"),
            scale,
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
    };
    let dense = log_grid(from, to, MODEL_POINTS);
    let model_main_dense: Vec<C64> = dense.iter().map(|&f| model_main(f)).collect();
    let model_open_dense: Vec<C64> = dense.iter().map(|&f| respond(open_lp, f).open).collect();
    let model_main_points: Vec<C64> = freq.iter().map(|&f| model_main(f)).collect();
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
        .map(|&f| respond(open_lp, f).open)
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
    // closed loop; margins of the open loop.
    let closed_measured: Vec<C64> = match options.lp {
        Loop::Plant => injected.estimates.iter().map(|e| e.closed).collect(),
        _ => main.estimates.iter().map(|e| e.closed).collect(),
    };
    let feature = match options.lp {
        Loop::Plant => measured_main.clone(),
        _ => open_measured.clone(),
    };
    let figures = Figures::of(
        &freq,
        &feature,
        &closed_measured,
        &open_measured,
        &injected_coherence,
    );
    let model_closed: Vec<C64> = match options.lp {
        Loop::Plant => dense
            .iter()
            .map(|&f| respond(Loop::Plant, f).closed)
            .collect(),
        _ => model_main_dense.clone(),
    };
    let model_feature = match options.lp {
        Loop::Plant => model_main_dense.clone(),
        _ => model_open_dense.clone(),
    };
    let model_figures = Figures::of(
        &dense,
        &model_feature,
        &model_closed,
        &model_open_dense,
        &vec![1.0; dense.len()],
    );

    let peak_command = measured
        .iter()
        .flat_map(|m| m.estimates.iter().map(|e| e.peak_command))
        .fold(0.0, f64::max);
    let mut notes = Vec::new();
    if peak_command >= 0.999 * model.command_limit {
        notes.push(format!(
            "the command reached its limit {:.3} {command_unit}: the points where it did are not linear",
            model.command_limit
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
    let drive = &machine.axes[axis].drive;
    if drive.backlash > 0.0 {
        notes.push(format!(
            "the axis has {:.3} {unit} of backlash, which the linear model leaves out",
            drive.backlash * scale
        ));
    }
    if drive.guide.is_some() {
        notes.push(
            "the axis's guide has Coulomb friction, which the linear model leaves out".into(),
        );
    }
    let (excitation, amplitude_unit) = match main.excitation.injection {
        Injection::ControllerOutput => (
            "sine added to the controller output",
            command_unit.to_string(),
        ),
        Injection::PositionSetpoint => ("sine on the position setpoint", unit.to_string()),
        Injection::VelocitySetpoint => ("cosine on the velocity command", format!("{unit}/s")),
    };
    let amplitude_scale = match main.excitation.injection {
        Injection::ControllerOutput => 1.0,
        _ => scale,
    };
    let ticks: usize = measured.iter().map(|m| m.ticks).sum();
    let runs = sweeps.len() * if fine_segs.is_empty() { 1 } else { 2 };
    let settle = crate::frequency::measure::lead_in(&assembly.loop_settings) * runs;
    Ok(BodeRun {
        scenario: s.name.clone(),
        axis: options.axis.clone(),
        loop_name: loop_name(options.lp).to_string(),
        plant: options.plant.name().to_string(),
        response,
        magnitude_unit,
        servo_period_s: period,
        excitation: excitation.to_string(),
        amplitude: main.excitation.amplitude * amplitude_scale,
        amplitude_unit,
        frequencies_hz: freq,
        magnitude_db: measured_curve.magnitude_db,
        phase_deg: measured_curve.phase_deg,
        coherence,
        open_loop: open_curve,
        figures,
        model: model_curve,
        model_open_loop: model_open_curve,
        model_figures,
        model_at_points: model_points_curve,
        peak_command,
        command_limit: model.command_limit,
        simulated_time_s: (ticks + settle) as f64 * period,
        wall_time_s: started.elapsed().as_secs_f64(),
        notes,
    })
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
