//! One scenario end to end: the assembly (machine → program → setpoints → wired loop), the
//! run, and the report. A run that stops early (divergence, following-error fault, Ctrl-C)
//! still writes everything it computed and says where it stopped.

use super::assemble::{Assembly, RunError};
use super::file::ControllerType;
use super::Scenario;
use crate::control::ActuatorKind;
use crate::diagnostics::FileError;
use crate::kinematics;
use crate::machine::Machine;
use crate::program::PathGeometry;
use crate::report::{self, AxisLabel, Derived, Metrics, RecordingContent, ReportError};
use crate::sim::{Stop, Trace, TraceRecorder};
use std::path::{Path, PathBuf};

/// What a run produced.
#[derive(Debug, Clone)]
pub struct RunOutput {
    pub metrics: Metrics,
    pub metrics_json: serde_json::Value,
    pub stop: Option<Stop>,
    /// The physics, tick by tick.
    pub trace: Trace,
    /// The analytic reference model, tick by tick, when the scenario runs it.
    pub analytic: Option<Trace>,
    /// Per-sample figures derived from the trace (contour error, path speed).
    pub derived: Derived,
    /// Files written, in the order written.
    pub files: Vec<PathBuf>,
    /// The machine's plausibility warnings (values that loaded but look wrong).
    pub warnings: Vec<FileError>,
}

pub fn run_scenario(
    s: &Scenario,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<RunOutput, RunError> {
    run_assembly(&Assembly::new(s)?, out_dir, progress)
}

/// [`run_scenario`] on a machine given in memory.
pub fn run_scenario_with(
    s: &Scenario,
    machine: Machine,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<RunOutput, RunError> {
    run_assembly(&Assembly::with_machine(s, machine)?, out_dir, progress)
}

/// Runs an assembled scenario and writes its report into `out_dir`.
pub fn run_assembly(
    assembly: &Assembly,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<RunOutput, RunError> {
    let s = &assembly.scenario;
    let machine = &assembly.machine;
    let labels = &assembly.labels;
    let mut recorder = TraceRecorder::new(s.servo_period, labels.len(), 1);
    let outcome = assembly.run(&mut recorder, progress)?;
    let mut traces = recorder.into_traces().into_iter();
    let trace = traces.next().unwrap_or_default();
    let analytic = traces.next();
    let stop = outcome.stop().cloned();

    // Report: everything computed so far, whether or not the run completed.
    let zeros = vec![0.0; machine.axes.len()];
    let program_origin = kinematics::tool_point(machine, &zeros);
    let linear_axes = ["x", "y", "z"].map(|n| machine.axis_index(n));
    let derived = Derived::compute(
        &trace,
        &PathGeometry::of(&assembly.program),
        &program_origin,
        linear_axes,
    );
    let dc_motor = assembly.actuator == ActuatorKind::DcMotor;
    let mut metrics = Metrics::compute(
        &s.name,
        &trace,
        &derived,
        labels,
        dc_motor,
        outcome.lanes[0].steps,
        outcome.wall_time,
        stop.as_ref().map(|e| e.to_string()),
    );
    if let Some(reference) = &analytic {
        metrics.add_analytic_comparison(&trace, &reference.actual, labels);
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
        report::write_trace_csv(&p, &trace, &derived, labels, s.decimation)?;
        files.push(p);
    }
    if s.record_rrd {
        let p = out_dir.join("run.rrd");
        let poses = |k: usize| {
            kinematics::link_poses(machine, &trace.actual[k * trace.axes..(k + 1) * trace.axes])
        };
        let setpoints = &assembly.setpoints;
        let programmed_path = (0..setpoints.len())
            .step_by(s.decimation)
            .chain(setpoints.len().checked_sub(1))
            .map(|k| {
                let p = assembly.axis_map.program_position(setpoints.position(k));
                (program_origin + nalgebra::Vector3::from(p.linear)).into()
            })
            .collect();
        let content = RecordingContent {
            name: &s.name,
            machine,
            labels,
            link_poses: &poses,
            programmed_path,
            dc_motor,
            decimation: s.decimation,
            analytic: analytic.as_ref(),
        };
        report::write_recording(&p, &trace, &derived, &content)?;
        files.push(p);
    }
    Ok(RunOutput {
        metrics,
        metrics_json,
        stop,
        trace,
        analytic,
        derived,
        files,
        warnings: machine.warnings.clone(),
    })
}

/// Axis names in the scenario must be the machine's; the chosen controller needs settings for
/// every axis; compensation units must fit the axis kind; every bound must name a real metric.
pub(crate) fn validate_against_machine(
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
    for axis in s.cascade.keys() {
        if !names.contains(&axis.as_str()) {
            return Err(FileError::new(
                &s.path,
                s.cascade[axis].at,
                format!(
                    "controller.cascade.{axis}: the machine '{}' has no axis '{axis}' (its axes: {})",
                    machine.name,
                    names.join(", ")
                ),
            ));
        }
    }
    for axis in &names {
        let (has, what) = match s.controller {
            Some(ControllerType::Pid) => (
                s.gains.contains_key(*axis),
                "[controller.axes] has no gains",
            ),
            Some(ControllerType::Cascade) => (
                s.cascade.contains_key(*axis),
                "[controller.cascade] has no loop settings",
            ),
            _ => (true, ""),
        };
        if !has {
            return Err(FileError::new(
                &s.path,
                s.controller_at,
                format!("{what} for axis '{axis}' of machine '{}'", machine.name),
            ));
        }
    }
    for (axis, c) in &s.compensation {
        let Some(i) = machine.axis_index(axis) else {
            return Err(FileError::new(
                &s.path,
                c.at,
                format!(
                    "compensation.{axis}: the machine '{}' has no axis '{axis}' (its axes: {})",
                    machine.name,
                    names.join(", ")
                ),
            ));
        };
        if let Some(rotary) = c.rotary_units {
            if rotary != labels[i].rotary {
                let (kind, keys) = if labels[i].rotary {
                    ("rotary", "backlash_deg and backlash_rate_deg_s")
                } else {
                    ("linear", "backlash_mm and backlash_rate_mm_s")
                };
                return Err(FileError::new(
                    &s.path,
                    c.at,
                    format!("compensation.{axis}: axis '{axis}' is {kind}: expected {keys}"),
                ));
            }
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
