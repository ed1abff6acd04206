//! One scenario end to end: machine → program → setpoints → co-simulation → report.
//! A run that stops early (divergence, following-error fault) still writes everything it
//! computed and says where it stopped.

use super::ProfileName;
use super::{ControlSpace, ProgramSource, Scenario};
use crate::control::{Actuator, ActuatorKind, ComputedTorque, Controller, Pid, PidBank, TaskSpace};
use crate::diagnostics::FileError;
use crate::dynamics::DynamicsModel;
use crate::kinematics::{self, AcAxes, AcTableKinematics, AxisMap};
use crate::machine::Machine;
use crate::model::{ModelError, Plant, PlantOptions};
use crate::plan::{plan_program, AxisKind, AxisLimits, PlanError, PlanSettings, Planner};
use crate::program::{circle, polyline, read_program, PathGeometry, Program, ProgramErrors};
use crate::report::{self, AxisLabel, Derived, Metrics, RecordingContent, ReportError};
use crate::sim::analytic::{run_reference, AxisModel, ReferenceSettings};
use crate::sim::{CoSimulation, LoopSettings, Stop, Trace, MAX_PHYSICS_STEPS, MAX_SERVO_TICKS};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("{0}")]
    File(#[from] FileError),
    #[error("{path}: {source}")]
    Model { path: PathBuf, source: ModelError },
    #[error("{path}: {source}")]
    Plan { path: PathBuf, source: PlanError },
    #[error(transparent)]
    Report(#[from] ReportError),
    #[error("{0}")]
    Program(ProgramErrors),
}

/// What a run produced.
#[derive(Debug, Clone)]
pub struct RunOutput {
    pub metrics: Metrics,
    pub metrics_json: serde_json::Value,
    pub stop: Option<Stop>,
    pub trace: Trace,
    /// Per-sample figures derived from the trace (contour error, path speed).
    pub derived: Derived,
    /// Files written, in the order written.
    pub files: Vec<PathBuf>,
    /// The machine's plausibility warnings (values that loaded but look wrong).
    pub warnings: Vec<FileError>,
}

/// Gravity in the machine base frame: URDF convention, z up.
pub(crate) const GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// Everything a run needs, wired and ready: the machine, its program and setpoints, and the
/// co-simulation (plant, controller, actuators).
pub struct Prepared {
    pub machine: Machine,
    pub labels: Vec<AxisLabel>,
    pub axis_map: AxisMap,
    pub program: Program,
    pub setpoints: crate::plan::Setpoints,
    pub encoder_resolution: Vec<Option<f64>>,
    pub actuator: ActuatorKind,
    pub cosim: CoSimulation<'static>,
}

/// The scenario's machine with its `[mechanics]`, `[feedback]` and `[actuator]` choices
/// applied.
pub fn machine_for(s: &Scenario) -> Result<Machine, RunError> {
    let mut machine = Machine::load(&s.machine)?;
    keep_mechanics(&mut machine, s.friction, s.backlash);
    for axis in &mut machine.axes {
        if let Some(feedback) = s.feedback_position {
            axis.drive.feedback = feedback;
        }
        if let Some(mode) = s.amplifier_mode {
            axis.drive.amplifier_mode = mode;
        }
    }
    Ok(machine)
}

/// Removes the guides' friction (`friction = false`) and the transmissions' backlash
/// (`backlash = false`) from every axis of `machine`; with both false, its linear part.
pub fn keep_mechanics(machine: &mut Machine, friction: bool, backlash: bool) {
    for axis in &mut machine.axes {
        if !friction {
            axis.drive.guide = None;
        }
        if !backlash {
            axis.drive.backlash = 0.0;
        }
    }
}

/// Loads, checks, plans and wires a scenario without running it.
pub fn prepare(s: &Scenario) -> Result<Prepared, RunError> {
    prepare_with(s, machine_for(s)?)
}

/// [`prepare`] on a machine given in memory (e.g. one whose parameters a calibration varies)
/// instead of the scenario's model file.
pub fn prepare_with(s: &Scenario, machine: Machine) -> Result<Prepared, RunError> {
    let (Some(actuator), true) = (
        s.actuator,
        !s.gains.is_empty() || s.inverse_dynamics.is_some(),
    ) else {
        let message = "running a scenario needs [actuator] and [controller] sections (planning with `cncsim plan` does not)";
        return Err(FileError::new(&s.path, None, message).into());
    };
    if s.analytic_steps.is_some() && s.inverse_dynamics.is_some() {
        return Err(FileError::new(
            &s.path,
            None,
            "[analytic] runs with the PID controller; turn it off for type = \"inverse-dynamics\"",
        )
        .into());
    }
    let labels: Vec<AxisLabel> = machine
        .axes
        .iter()
        .map(|a| AxisLabel {
            name: a.name.clone(),
            rotary: a.is_rotary(&machine),
        })
        .collect();
    validate_against_machine(s, &machine, &labels)?;
    let axis_map = AxisMap::cartesian(&machine)
        .map_err(|e| FileError::new(&s.machine, None, e.to_string()))?;

    let program = load_checked_program(s, &machine)?;
    let settings = plan_settings(s, &machine, s.planner.profile)?;
    let setpoints =
        plan_program(&program, &axis_map, &settings).map_err(|source| RunError::Plan {
            path: program.source.clone(),
            source,
        })?;

    check_run_length(s, setpoints.len())?;
    let plant = new_plant(s, &machine, setpoints.position(0))?;

    let encoder_resolution: Vec<Option<f64>> = machine
        .axes
        .iter()
        .map(|a| {
            let mut drive = a.drive.clone();
            if let Some((counts, _)) = s.encoder_counts_per_rev.get(&a.name) {
                drive.encoder_counts_per_rev = Some(*counts);
            }
            drive.encoder_resolution()
        })
        .collect();
    let settings = LoopSettings {
        servo_period: s.servo_period,
        substeps: s.substeps,
        settle_time: s.settle_time,
        ratios: machine.axes.iter().map(|a| a.drive.ratio()).collect(),
        encoder_resolution: encoder_resolution.clone(),
        following_error_limit: labels
            .iter()
            .map(|l| {
                if l.rotary {
                    s.following_error_limit_rotary
                } else {
                    s.following_error_limit_linear
                }
            })
            .collect(),
        axis_names: labels.iter().map(|l| l.name.clone()).collect(),
    };
    let cosim = CoSimulation {
        plant,
        controller: controller_for(s, &machine, actuator)?,
        actuators: machine
            .axes
            .iter()
            .map(|a| Actuator::new(actuator, &a.drive))
            .collect(),
        settings,
    };
    Ok(Prepared {
        machine,
        labels,
        axis_map,
        program,
        setpoints,
        encoder_resolution,
        actuator,
        cosim,
    })
}

pub fn run_scenario(
    s: &Scenario,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<RunOutput, RunError> {
    run_scenario_with(s, machine_for(s)?, out_dir, progress)
}

/// [`run_scenario`] on a machine given in memory.
pub fn run_scenario_with(
    s: &Scenario,
    machine: Machine,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<RunOutput, RunError> {
    let Prepared {
        machine,
        labels,
        axis_map,
        program,
        setpoints,
        encoder_resolution,
        actuator,
        cosim,
    } = prepare_with(s, machine)?;
    let outcome = cosim.run(&setpoints, progress);
    let analytic = match s.analytic_steps {
        Some(steps) => Some(run_analytic(
            s,
            &machine,
            &setpoints,
            &encoder_resolution,
            steps,
        )?),
        None => None,
    };

    // Report: everything computed so far, whether or not the run completed.
    let zeros = vec![0.0; machine.axes.len()];
    let program_origin = kinematics::tool_point(&machine, &zeros);
    let linear_axes = ["x", "y", "z"].map(|n| machine.axis_index(n));
    let derived = Derived::compute(
        &outcome.trace,
        &PathGeometry::of(&program),
        &program_origin,
        linear_axes,
    );
    let dc_motor = actuator == ActuatorKind::DcMotor;
    let mut metrics = Metrics::compute(
        &s.name,
        &outcome.trace,
        &derived,
        &labels,
        dc_motor,
        outcome.physics_steps,
        outcome.wall_time,
        outcome.stop.as_ref().map(|e| e.to_string()),
    );
    if let Some(reference) = &analytic {
        metrics.add_analytic_comparison(&outcome.trace, &reference.actual, &labels);
    }
    let metrics_json = metrics.to_json();

    std::fs::create_dir_all(out_dir).map_err(|source| ReportError::Io {
        path: out_dir.to_path_buf(),
        source,
    })?;
    let mut files = Vec::new();
    let metrics_path = out_dir.join("metrics.json");
    let text = serde_json::to_string_pretty(&metrics_json).expect("JSON of plain values");
    std::fs::write(&metrics_path, text + "\n").map_err(|source| ReportError::Io {
        path: metrics_path.clone(),
        source,
    })?;
    files.push(metrics_path);
    if s.record_csv {
        let p = out_dir.join("trace.csv");
        report::write_trace_csv(&p, &outcome.trace, &derived, &labels, s.decimation)?;
        files.push(p);
    }
    if s.record_rrd {
        let p = out_dir.join("run.rrd");
        let trace = &outcome.trace;
        let poses = |k: usize| {
            kinematics::link_poses(
                &machine,
                &trace.actual[k * trace.axes..(k + 1) * trace.axes],
            )
        };
        let programmed_path = (0..setpoints.len())
            .step_by(s.decimation)
            .chain(std::iter::once(setpoints.len() - 1))
            .map(|k| {
                let p = axis_map.program_position(setpoints.position(k));
                (program_origin + nalgebra::Vector3::from(p.linear)).into()
            })
            .collect();
        let content = RecordingContent {
            name: &s.name,
            machine: &machine,
            labels: &labels,
            link_poses: &poses,
            programmed_path,
            dc_motor,
            decimation: s.decimation,
            analytic: analytic.as_ref(),
        };
        report::write_recording(&p, trace, &derived, &content)?;
        files.push(p);
    }
    Ok(RunOutput {
        metrics,
        metrics_json,
        stop: outcome.stop,
        trace: outcome.trace,
        derived,
        files,
        warnings: machine.warnings.clone(),
    })
}

/// Refuses a run longer than the loop's bounds, before it starts, with the number it needs.
pub(crate) fn check_run_length(s: &Scenario, samples: usize) -> Result<(), FileError> {
    let settle = (s.settle_time / s.servo_period).round() as u64;
    let ticks = settle + samples as u64;
    let steps = ticks.saturating_mul(s.substeps as u64);
    let what = format!(
        "settle {:?} s + program {:.6} s at a servo period of {:?} ms",
        s.settle_time,
        samples.saturating_sub(1) as f64 * s.servo_period,
        s.servo_period * 1e3
    );
    if ticks > MAX_SERVO_TICKS {
        return Err(FileError::new(
            &s.path,
            None,
            format!("the run needs {ticks} servo ticks ({what}): the limit is {MAX_SERVO_TICKS}"),
        ));
    }
    if steps > MAX_PHYSICS_STEPS {
        return Err(FileError::new(
            &s.path,
            None,
            format!(
                "the run needs {steps} physics steps ({ticks} ticks of {} steps; {what}): the limit is {MAX_PHYSICS_STEPS}",
                s.substeps
            ),
        ));
    }
    Ok(())
}

/// The scenario's physics model of the machine at rest at `initial` (joint units per axis).
pub(crate) fn new_plant(
    s: &Scenario,
    machine: &Machine,
    initial: &[f64],
) -> Result<Plant, RunError> {
    let options = PlantOptions {
        step: s.servo_period / s.substeps as f64,
        gravity: GRAVITY,
        initial_positions: initial.to_vec(),
        include_drive_dynamics: true,
        solver_iterations: s.solver_iterations,
    };
    Plant::new(machine, &options).map_err(|source| RunError::Model {
        path: s.path.clone(),
        source,
    })
}

/// The analytic reference model on the same setpoints with a fresh copy of the controller.
fn run_analytic(
    s: &Scenario,
    machine: &Machine,
    setpoints: &crate::plan::Setpoints,
    encoder_resolution: &[Option<f64>],
    steps: usize,
) -> Result<Trace, RunError> {
    let fail = |m: String| RunError::File(FileError::new(&s.path, None, m));
    let ideal_actuator = s.actuator == Some(ActuatorKind::IdealTorque);
    let mut models = AxisModel::for_machine(machine, GRAVITY, ideal_actuator)
        .map_err(|e| fail(format!("[analytic]: {e}")))?;
    let mut controller = pid_bank(s, machine);
    let settings = ReferenceSettings {
        servo_period: s.servo_period,
        steps_per_period: steps,
        settle_time: s.settle_time,
        encoder_resolution: encoder_resolution.to_vec(),
    };
    let run = run_reference(&mut models, &mut controller, setpoints, &settings);
    Ok(run.trace)
}

/// The scenario's controller for this machine.
pub(crate) fn controller_for(
    s: &Scenario,
    machine: &Machine,
    actuator: ActuatorKind,
) -> Result<Box<dyn Controller>, RunError> {
    let Some(id) = s.inverse_dynamics else {
        return Ok(Box::new(pid_bank(s, machine)));
    };
    // The controller's model of the machine: the drives' reflected damping on the joints, the
    // rotor inertia as armature, and (for robustness studies) every link's mass scaled.
    let mut model_machine = machine.clone();
    for axis in &machine.axes {
        model_machine.joints[axis.joint].damping += axis.drive.reflected_damping();
    }
    for link in &mut model_machine.links {
        link.mass *= id.model_mass_scale;
        link.inertia *= id.model_mass_scale;
    }
    let model = DynamicsModel::from_machine(&model_machine, nalgebra::Vector3::from(GRAVITY))
        .and_then(|m| m.with_drive_armature(&model_machine))
        .map_err(|e| {
            FileError::new(
                &s.machine,
                None,
                format!("the inverse-dynamics controller's model: {e}"),
            )
        })?;
    let drives: Vec<_> = machine.axes.iter().map(|a| a.drive.clone()).collect();
    let controller = ComputedTorque::new(
        model,
        &drives,
        actuator,
        s.servo_period,
        id.omega_n,
        id.damping_ratio,
    );
    Ok(match id.space {
        ControlSpace::Joint => Box::new(controller),
        ControlSpace::Task => {
            let kinematics = AcTableKinematics::new(machine).map_err(|e| {
                FileError::new(
                    &s.path,
                    s.controller_at,
                    format!("controller.space = \"task\" resolves the tool tip on a table-tilting A-C machine: {e}"),
                )
            })?;
            Box::new(controller.in_task_space(TaskSpace::new(kinematics, id.task_damping)))
        }
    })
}

/// One PID loop per machine axis, with the scenario's gains.
fn pid_bank(s: &Scenario, machine: &Machine) -> PidBank {
    PidBank::new(
        machine
            .axes
            .iter()
            .map(|a| {
                let g = &s.gains[&a.name];
                Pid::new(g.gains, s.pid_form, s.servo_period, g.output_limit)
            })
            .collect(),
    )
}

/// The planner settings of a scenario for its machine, with `profile` (the scenario's own or
/// a command-line override); limits are converted to SI per axis kind.
pub fn plan_settings(
    s: &Scenario,
    machine: &Machine,
    profile: ProfileName,
) -> Result<PlanSettings, FileError> {
    let p = &s.planner;
    let planner = match profile {
        ProfileName::ConstantVelocity => Planner::ConstantVelocity,
        ProfileName::Trapezoid => Planner::Trapezoid {
            acceleration: p.acceleration.ok_or_else(|| {
                FileError::new(
                    &s.path,
                    p.at,
                    "the trapezoid profile needs [planner] acceleration_mm_s2",
                )
            })?,
        },
        ProfileName::JerkLimited => {
            for (axis, (_, place)) in &p.limits {
                if machine.axis_index(axis).is_none() {
                    return Err(FileError::new(
                        &s.path,
                        *place,
                        format!(
                            "planner.limits.{axis}: the machine '{}' has no axis '{axis}'",
                            machine.name
                        ),
                    ));
                }
            }
            let limits = machine
                .axes
                .iter()
                .map(|a| {
                    let ([v, acc, j], _) = p.limits.get(&a.name).ok_or_else(|| {
                        FileError::new(&s.path, p.at, format!("the jerk-limited profile needs planner.limits.{} (velocity, acceleration, jerk in mm or deg units)", a.name))
                    })?;
                    let kind = if a.is_rotary(machine) { AxisKind::Rotary } else { AxisKind::Linear };
                    Ok(AxisLimits::from_program_units(kind, *v, *acc, *j))
                })
                .collect::<Result<_, FileError>>()?;
            Planner::JerkLimited { limits }
        }
    };
    Ok(PlanSettings {
        planner,
        period: s.servo_period,
        rapid_speed: s.rapid_speed,
        blend: s.blend,
        axis_names: machine.axes.iter().map(|a| a.name.clone()).collect(),
    })
}

/// Reads the scenario's program (built-in path or file) and checks it against the machine.
pub fn load_checked_program(s: &Scenario, machine: &Machine) -> Result<Program, RunError> {
    let mut program = load_program(s)?;
    if program.moves.is_empty() {
        return Err(FileError::new(
            &program.source,
            None,
            "the program has no moves: there is nothing to plan or run",
        )
        .into());
    }
    if program.moves.iter().any(|m| m.tool_axis.is_some()) {
        // Cutter-location data (tool tip and axis on the workpiece): machine axes come from the
        // 5-axis inverse kinematics, starting from machine zero.
        let kinematics = AcTableKinematics::new(machine).map_err(|e| {
            FileError::new(&program.source, None, format!("the program gives tool-axis vectors (CL data), which need a table-tilting A-C machine: {e}"))
        })?;
        program = kinematics
            .program_to_machine(&program, &AcAxes::default())
            .map_err(RunError::Program)?;
    }
    check_program_axes(&program, machine)?;
    Ok(program)
}

fn load_program(s: &Scenario) -> Result<Program, RunError> {
    Ok(match &s.program {
        ProgramSource::Circle(c) => circle(c, &s.path),
        ProgramSource::Polyline(p) => polyline(p, &s.path),
        ProgramSource::File { path, options } => {
            read_program(path, options).map_err(RunError::Program)?
        }
    })
}

/// A program may only move axes the machine has.
fn check_program_axes(program: &Program, machine: &Machine) -> Result<(), FileError> {
    const NAMES: [(&str, bool, usize); 6] = [
        ("x", true, 0),
        ("y", true, 1),
        ("z", true, 2),
        ("a", false, 0),
        ("b", false, 1),
        ("c", false, 2),
    ];
    let mut at = program.start;
    for m in &program.moves {
        for (name, linear, i) in NAMES {
            let (from, to) = if linear {
                (at.linear[i], m.end.linear[i])
            } else {
                (at.rotary[i], m.end.rotary[i])
            };
            if from != to && machine.axis_index(name).is_none() {
                let place = Some(crate::diagnostics::LineColumn {
                    line: m.span.line as usize,
                    column: m.span.column as usize,
                });
                return Err(FileError::new(
                    &program.source,
                    place,
                    format!(
                        "this move drives axis {}, which the machine '{}' does not have",
                        name.to_uppercase(),
                        machine.name
                    ),
                ));
            }
        }
        at = m.end;
    }
    Ok(())
}

/// Axis names in the scenario must be the machine's; every bound must name a real metric.
fn validate_against_machine(
    s: &Scenario,
    machine: &Machine,
    labels: &[AxisLabel],
) -> Result<(), FileError> {
    let names: Vec<&str> = machine.axes.iter().map(|a| a.name.as_str()).collect();
    for axis in s.gains.keys() {
        if !names.contains(&axis.as_str()) {
            let at = s.gains[axis].at;
            return Err(FileError::new(
                &s.path,
                at,
                format!(
                    "controller.axes.{axis}: the machine '{}' has no axis '{axis}' (its axes: {})",
                    machine.name,
                    names.join(", ")
                ),
            ));
        }
    }
    for axis in names.iter().filter(|_| s.inverse_dynamics.is_none()) {
        if !s.gains.contains_key(*axis) {
            return Err(FileError::new(
                &s.path,
                s.controller_at,
                format!(
                    "[controller.axes] has no gains for axis '{axis}' of machine '{}'",
                    machine.name
                ),
            ));
        }
    }
    for (axis, (_, at)) in &s.encoder_counts_per_rev {
        if !names.contains(&axis.as_str()) {
            return Err(FileError::new(
                &s.path,
                *at,
                format!("feedback.encoder_counts_per_rev.{axis}: the machine has no axis '{axis}'"),
            ));
        }
    }
    // The metric names a run of this machine produces.
    let empty = Trace {
        period: s.servo_period,
        axes: labels.len(),
        ..Default::default()
    };
    let mut template = Metrics::compute(
        &s.name,
        &empty,
        &Derived::default(),
        labels,
        s.actuator == Some(ActuatorKind::DcMotor),
        0,
        0.0,
        None,
    );
    if s.analytic_steps.is_some() {
        template.add_analytic_comparison(&empty, &[], labels);
    }
    let template = template.to_json();
    let mut known = Vec::new();
    collect_numeric_paths(&template, "", &mut known);
    for e in &s.expect {
        if !known.contains(&e.metric) {
            return Err(FileError::new(
                &s.path,
                e.at,
                format!(
                    "expect.{}: no such metric; a run of this scenario reports: {}",
                    e.metric,
                    known.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

fn collect_numeric_paths(v: &serde_json::Value, prefix: &str, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                collect_numeric_paths(v, &p, out);
            }
        }
        serde_json::Value::Number(_) | serde_json::Value::Null => out.push(prefix.to_string()),
        _ => {}
    }
}
