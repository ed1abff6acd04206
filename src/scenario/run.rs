//! One scenario end to end: the assembly (machine → program → setpoints → wired loop), the
//! run, and the report. A run that stops early (divergence, following-error fault, Ctrl-C)
//! still writes everything it computed and says where it stopped.

use super::assemble::{Assembly, RunError};
use super::file::ControllerType;
use super::{check, Scenario, Verdict};
use crate::control::ActuatorKind;
use crate::diagnostics::FileError;
use crate::machine::Machine;
use crate::program::PathGeometry;
use crate::report::{
    self, AxisLabel, Envelope, Metrics, PathTracker, RecordingSetup, ReportError, ReportSetup,
    RunReport,
};
use crate::sim::{Observer, Observers, Outcome, Stop, Trace, TraceRecorder};
use std::path::{Path, PathBuf};

/// What a run produced.
#[derive(Debug, Clone)]
pub struct RunOutput {
    pub metrics: Metrics,
    pub metrics_json: serde_json::Value,
    pub stop: Option<Stop>,
    /// The physics, tick by tick, when asked for ([`run_scenario_traced`]).
    pub trace: Option<Trace>,
    /// The analytic reference model, tick by tick, when asked for and run.
    pub analytic: Option<Trace>,
    /// The largest contour error per bin of the run (a fixed-size curve for plots).
    pub contour_envelope: Envelope,
    /// The scenario's `[expect]` bounds against the metrics.
    pub verdict: Verdict,
    /// Files written, in the order written.
    pub files: Vec<PathBuf>,
    /// The machine's plausibility warnings (values that loaded but look wrong), and the
    /// planner's (stops its look-ahead added).
    pub warnings: Vec<FileError>,
    /// The ISO 230-4 figures, when the program is the ballbar test (also in the metrics
    /// under `ballbar`).
    pub ballbar: Option<crate::report::BallbarRun>,
}

pub fn run_scenario(
    s: &Scenario,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<RunOutput, RunError> {
    run_assembly(&Assembly::new(s)?, out_dir, progress, false)
}

/// [`run_scenario`], also keeping every tick in memory (for tests and short studies).
pub fn run_scenario_traced(
    s: &Scenario,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<RunOutput, RunError> {
    run_assembly(&Assembly::new(s)?, out_dir, progress, true)
}

/// [`run_scenario`] on a machine given in memory.
pub fn run_scenario_with(
    s: &Scenario,
    machine: Machine,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<RunOutput, RunError> {
    run_assembly(
        &Assembly::with_machine(s, machine)?,
        out_dir,
        progress,
        false,
    )
}

/// What the report of an assembled scenario needs to know before the run: the path to judge
/// against, each axis's peak commanded speed, the lanes.
pub fn report_setup(assembly: &Assembly) -> ReportSetup {
    let machine = &assembly.machine;
    let s = &assembly.scenario;
    ReportSetup {
        name: s.name.clone(),
        labels: assembly.labels.clone(),
        dc_motor: assembly.actuator == ActuatorKind::DcMotor,
        period: s.servo_period,
        path: PathTracker {
            geometry: PathGeometry::of(assembly.program()),
            frame: assembly.frame.clone(),
            linear_axes: ["x", "y", "z"].map(|n| machine.axis_index(n)),
        },
        peak_velocity: assembly.overview().peak_velocity.clone(),
        ticks: assembly.plan.len(),
        lanes: lanes_of(s),
        backlash: machine.axes.iter().map(|a| a.drive.backlash).collect(),
        move_lines: assembly
            .program()
            .moves
            .iter()
            .map(|m| m.span.line)
            .collect(),
    }
}

fn lanes_of(s: &Scenario) -> Vec<&'static str> {
    if s.analytic_steps.is_some() {
        vec!["physics", "analytic"]
    } else {
        vec!["physics"]
    }
}

/// The recording's view of an assembled scenario, with the programmed tool path on the
/// workpiece.
pub fn recording_setup<'a>(
    assembly: &'a Assembly,
    lanes: &'a [&'static str],
) -> RecordingSetup<'a> {
    let machine = &assembly.machine;
    RecordingSetup {
        name: &assembly.scenario.name,
        machine,
        labels: &assembly.labels,
        dc_motor: assembly.actuator == ActuatorKind::DcMotor,
        decimation: assembly.scenario.decimation,
        lanes,
        programmed_path: assembly.overview().programmed_path.clone(),
        variant: None,
    }
}

/// Runs an assembled scenario and writes its report into `out_dir`: `metrics.json` (also when
/// the run stops early: `completed = false` and the stop), and with the scenario's
/// `[recording]` the CSV trace and the Rerun recording, all written as the run goes.
pub fn run_assembly(
    assembly: &Assembly,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
    keep_trace: bool,
) -> Result<RunOutput, RunError> {
    run_assembly_observed(assembly, out_dir, progress, keep_trace, None).map(|(run, _)| run)
}

/// [`run_assembly`] with one more observer of the run (e.g. a shared A/B recording); also
/// returns the loop's outcome.
pub fn run_assembly_observed(
    assembly: &Assembly,
    out_dir: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
    keep_trace: bool,
    extra: Option<&mut dyn Observer>,
) -> Result<(RunOutput, Outcome), RunError> {
    let s = &assembly.scenario;
    std::fs::create_dir_all(out_dir).map_err(|source| ReportError::Io {
        path: out_dir.to_path_buf(),
        source,
    })?;
    let lanes = lanes_of(s);
    let csv = out_dir.join("trace.csv");
    let rrd = out_dir.join("run.rrd");
    let mut report = RunReport::new(
        report_setup(assembly),
        s.record_csv.then_some(csv.as_path()),
        s.record_rrd
            .then(|| (rrd.as_path(), recording_setup(assembly, &lanes))),
        s.decimation,
    )?;
    let mut recorder = TraceRecorder::new(s.servo_period, assembly.labels.len(), lanes.len());
    let ballbar_spec = match &s.program {
        super::ProgramSource::Ballbar(spec) => Some(spec),
        _ => None,
    };
    let outcome = {
        let mut observers: Vec<&mut dyn Observer> = vec![&mut report];
        // The ballbar figures are read from the trace after the run.
        if keep_trace || ballbar_spec.is_some() {
            observers.push(&mut recorder);
        }
        if let Some(extra) = extra {
            observers.push(extra);
        }
        assembly.run(&mut Observers(observers), progress)?
    };
    let metrics = report.metrics(&outcome);
    let mut metrics_json = metrics.to_json();
    let ballbar = match ballbar_spec {
        Some(spec) => {
            let completed = outcome.stop().is_none();
            let run = super::ballbar::ballbar_of_run(
                assembly,
                spec,
                recorder.lane(0),
                &metrics,
                completed,
                out_dir,
            )?;
            metrics_json["ballbar"] = run.metrics_json();
            Some(run)
        }
        None => None,
    };
    let verdict = check(s, &metrics_json);

    // Everything computed so far is written, whether or not the run completed.
    let metrics_path = out_dir.join("metrics.json");
    let text = serde_json::to_string_pretty(&metrics_json).expect("JSON of plain values");
    std::fs::write(&metrics_path, text + "\n").map_err(|source| ReportError::Io {
        path: metrics_path.clone(),
        source,
    })?;
    let contour_envelope = report.contour_envelope().clone();
    let end = outcome.ticks as f64 * s.servo_period;
    let notes: Vec<(f64, &'static str, String)> = verdict
        .breaches
        .iter()
        .map(|b| (end, "ERROR", format!("bound breached: {b}")))
        .collect();
    let summary = summary_markdown(assembly, &metrics, &verdict);
    let mut files = vec![metrics_path];
    files.extend(report.finish(&outcome, &notes, &summary)?);
    if let Some(b) = &ballbar {
        files.extend(b.files.iter().cloned());
    }
    let mut traces = recorder.into_traces().into_iter();
    let (trace, analytic) = if keep_trace {
        (traces.next(), traces.next().filter(|_| lanes.len() > 1))
    } else {
        (None, None)
    };
    let output = RunOutput {
        stop: outcome.stop().cloned(),
        metrics,
        metrics_json,
        trace,
        analytic,
        contour_envelope,
        verdict,
        files,
        warnings: warnings_of(assembly),
        ballbar,
    };
    Ok((output, outcome))
}

/// What loaded or planned but looks wrong: the machine's implausible values, and stops the
/// planner's look-ahead added.
fn warnings_of(assembly: &Assembly) -> Vec<FileError> {
    let mut warnings = assembly.machine.warnings.clone();
    let machine = &assembly.machine;
    if !machine.masses_from_geometry.is_empty() {
        warnings.push(FileError::new(
            &crate::machine::DrivesFile::path_for(&machine.urdf_path),
            None,
            format!(
                "the masses and inertias of {} come from their geometry (inertia_from_geometry), not from the URDF",
                machine
                    .masses_from_geometry
                    .iter()
                    .map(|l| format!("'{l}'"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    if let Some(warning) = assembly.plan.look_ahead().warning() {
        warnings.push(FileError::new(&assembly.program().source, None, warning));
    }
    warnings
}

/// The summary document of a recording: what ran, its figures, its bounds.
pub fn summary_markdown(assembly: &Assembly, metrics: &Metrics, verdict: &Verdict) -> String {
    let s = &assembly.scenario;
    let m = &assembly.machine;
    let controller = s.controller.map_or("none", |c| c.name());
    let mut t = format!("# {}\n\n", s.name);
    if !s.description.is_empty() {
        t += &format!("{}\n\n", s.description);
    }
    t += &format!(
        "- machine: **{}** ({} axes: {})\n- controller: **{controller}**; actuator: {:?}; servo period {} ms, physics step {} ms\n- program: {} ({} moves)\n- status: **{}**\n",
        m.name,
        m.axes.len(),
        assembly.labels.iter().map(|l| l.name.as_str()).collect::<Vec<_>>().join(", "),
        assembly.actuator,
        s.servo_period * 1e3,
        s.servo_period / s.substeps as f64 * 1e3,
        assembly.program().source.display(),
        assembly.program().moves.len(),
        metrics.stopped.as_deref().unwrap_or("completed"),
    );
    if let Some(line) = assembly.plan.look_ahead().summary() {
        t += &format!("- {line}\n");
    }
    t += "\n";
    t += "| figure | value |\n|---|---:|\n";
    t += &format!(
        "| max contour error | {:.3} µm |\n",
        metrics.max_contour_error_mm * 1e3
    );
    t += &format!(
        "| rms contour error | {:.3} µm |\n",
        metrics.rms_contour_error_mm * 1e3
    );
    t += &format!(
        "| max path-speed error | {:.3} mm/s |\n| path-speed catch-up from rest | {:.0} ms |\n",
        metrics.max_path_speed_error_mm_s,
        metrics.path_speed_catch_up_s * 1e3
    );
    for (name, a) in &metrics.axes {
        match (a.max_following_error_mm, a.max_following_error_deg) {
            (Some(e), _) => {
                t += &format!(
                    "| {name}: max following error | {:.3} µm at {:.3} s |\n",
                    e * 1e3,
                    a.max_following_error_time_s
                )
            }
            (_, Some(e)) => {
                t += &format!(
                    "| {name}: max following error | {:.5} deg at {:.3} s |\n",
                    e, a.max_following_error_time_s
                )
            }
            _ => {}
        }
        if let Some(d) = a.max_physics_vs_analytic_mm {
            t += &format!("| {name}: physics vs analytic | {:.4} µm |\n", d * 1e3);
        }
        t += &format!(
            "| {name}: peak / rms torque | {:.4} / {:.4} N·m |\n",
            a.peak_torque_nm, a.rms_torque_nm
        );
    }
    t += &format!(
        "| simulated / wall time | {:.3} s / {:.3} s |\n\n",
        metrics.sim_time_s, metrics.wall_time_s
    );
    if s.expect.is_empty() {
        t += "No `[expect]` bounds.\n";
    } else if verdict.passed() {
        t += &format!("All {} `[expect]` bounds met.\n", verdict.checked);
    } else {
        t += &format!(
            "**{} of {} `[expect]` bounds breached:**\n\n",
            verdict.breaches.len(),
            verdict.checked
        );
        for b in &verdict.breaches {
            t += &format!("- {b}\n");
        }
    }
    t
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
    let template = report::MetricsAccumulator::new(
        labels,
        s.actuator == Some(ActuatorKind::DcMotor),
        s.servo_period,
        &vec![0.0; labels.len()],
        s.analytic_steps.is_some(),
    )
    .finish(&s.name, &crate::sim::Outcome::default())
    .to_json();
    let mut known = Vec::new();
    collect_numeric_paths(&template, "", &mut known);
    if let super::ProgramSource::Ballbar(b) = &s.program {
        let ([a1, a2], _) = super::ballbar::plane_axes(b.plane);
        let letters = ["x", "y", "z"];
        known.extend(crate::report::BallbarRun::metric_names([
            letters[a1],
            letters[a2],
        ]));
    }
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
