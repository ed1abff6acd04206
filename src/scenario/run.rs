//! One scenario end to end: the assembly (machine → program → setpoints → wired loop), the
//! run, and the report. A run that stops early (divergence, following-error fault, Ctrl-C)
//! still writes everything it computed and says where it stopped.

use super::assemble::{Assembly, MakeController, MakePlant, RunError};
use super::{check, Verdict};
use crate::command::{Ending, Report, WriteError};
use crate::control::ActuatorKind;
use crate::diagnostics::FileError;
use crate::program::PathGeometry;
use crate::report::{
    metrics_table, Envelope, Metrics, PathTracker, RecordingSetup, ReportError, ReportSetup,
    RunReport,
};
use crate::sim::{Observer, Observers, Outcome, Stop, Trace, TraceRecorder};
use std::path::PathBuf;

/// How a run is carried out and what it keeps besides its figures: where its files go, whether
/// every tick is kept in memory, who else watches it, and whose controller runs. Built with
/// [`RunOptions::new`] (nothing written) or [`RunOptions::write_to`] and the methods below.
#[derive(Default)]
pub struct RunOptions<'a> {
    /// Folder for `metrics.json` and, as the scenario's `[recording]` says, `trace.csv` and
    /// `run.rrd`; `None`: nothing is written.
    out_dir: Option<PathBuf>,
    keep_trace: bool,
    observers: Vec<&'a mut dyn Observer>,
    progress: Option<&'a mut dyn FnMut(usize, usize) -> bool>,
    controller: Option<&'a MakeController<'a>>,
    plant: Option<&'a MakePlant<'a>>,
}

impl<'a> RunOptions<'a> {
    /// A run that writes no files.
    pub fn new() -> Self {
        Self::default()
    }

    /// A run that writes its report into `out_dir` (created if needed).
    pub fn write_to(out_dir: impl Into<PathBuf>) -> Self {
        RunOptions {
            out_dir: Some(out_dir.into()),
            ..Self::default()
        }
    }

    /// Keeps every tick of every lane in memory ([`RunOutput::trace`], [`RunOutput::analytic`]).
    pub fn traced(mut self) -> Self {
        self.keep_trace = true;
        self
    }

    /// One more observer of every tick (e.g. a shared A/B recording).
    pub fn observer(mut self, observer: &'a mut dyn Observer) -> Self {
        self.observers.push(observer);
        self
    }

    /// Called with (done, total) ticks as the run goes; returning `false` interrupts it.
    pub fn progress(mut self, progress: &'a mut dyn FnMut(usize, usize) -> bool) -> Self {
        self.progress = Some(progress);
        self
    }

    /// Runs a controller of one's own instead of the scenario's: `make` builds a fresh one for
    /// every lane.
    pub fn controller(mut self, make: &'a MakeController<'a>) -> Self {
        self.controller = Some(make);
        self
    }

    /// Runs a plant of one's own in each lane instead of the scenario's: `make(lane, start)`
    /// builds it at rest at `start` (joint units, the machine's axis order). The lane keeps its
    /// name in the report and the recording.
    pub fn plant(mut self, make: &'a MakePlant<'a>) -> Self {
        self.plant = Some(make);
        self
    }
}

/// What a run produced.
#[derive(Debug, Clone)]
pub struct RunOutput {
    /// The run's figures: contour, path-speed and per-axis errors, torques, times.
    pub metrics: Metrics,
    /// The metrics as written to `metrics.json` ([`Metrics::to_json`]), with the `ballbar`
    /// and `frequency_response` figures when the scenario has them; what the `[expect]`
    /// bounds are checked against.
    pub metrics_json: serde_json::Value,
    /// How each lane ended and what it cost.
    pub outcome: Outcome,
    /// The physics, tick by tick, when asked for ([`RunOptions::traced`]).
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
    /// The part as cut, where the scenario cuts (also in the metrics under `part`).
    pub part: Option<PartAsCut>,
}

impl RunOutput {
    /// Why the run stopped before the end of its program (its first lane, the physics, stopped
    /// early); `None` when it ran to the end.
    pub fn stop(&self) -> Option<&Stop> {
        self.outcome.stop()
    }
}

/// `cncsim run`: one scenario's run as the command reports it.
#[derive(Debug, Clone)]
pub struct ScenarioRun {
    /// The scenario file.
    pub path: PathBuf,
    /// What the run produced.
    pub output: RunOutput,
}

impl Report for ScenarioRun {
    /// The run wrote its files as it went.
    fn write(&self) -> Result<Vec<PathBuf>, WriteError> {
        Ok(self.output.files.clone())
    }

    fn text(&self) -> String {
        metrics_table(&self.output.metrics)
    }

    fn json(&self) -> Option<serde_json::Value> {
        Some(self.output.metrics_json.clone())
    }

    fn messages(&self) -> Vec<String> {
        self.output
            .warnings
            .iter()
            .map(|w| format!("warning: {w}"))
            .collect()
    }

    fn ending(&self) -> Ending {
        match self.output.stop() {
            Some(stop) => Ending::Failed(Some(format!("{}: {stop}", self.path.display()))),
            None => Ending::Done,
        }
    }
}

impl Assembly {
    /// Runs the scenario through the servo loop and reports it: the metrics, the verdict on
    /// its `[expect]` bounds, and with [`RunOptions::write_to`] `metrics.json` (also when the
    /// run stops early: `completed = false` and the stop) and, as its `[recording]` says, the
    /// CSV trace and the Rerun recording, all written as the run goes.
    pub fn run(&self, options: RunOptions<'_>) -> Result<RunOutput, RunError> {
        let RunOptions {
            out_dir,
            keep_trace,
            observers: mut extra,
            progress,
            controller,
            plant,
        } = options;
        let s = &self.scenario;
        let recording = &s.recording;
        if let Some(dir) = &out_dir {
            std::fs::create_dir_all(dir).map_err(|source| ReportError::Io {
                path: dir.clone(),
                source,
            })?;
        }
        let lanes = self.lane_kinds();
        let file =
            |name: &str, wanted: bool| out_dir.as_ref().filter(|_| wanted).map(|d| d.join(name));
        let (csv, rrd) = (
            file("trace.csv", recording.csv),
            file("run.rrd", recording.rrd),
        );
        let mut report = RunReport::new(
            report_setup(self),
            csv.as_deref(),
            rrd.as_deref()
                .map(|rrd| (rrd, recording_setup(self, &lanes))),
            recording.decimation,
        )?;
        let mut recorder =
            TraceRecorder::new(s.timing.servo_period, self.labels.len(), lanes.len());
        let mut lanes_run = self.lanes_with(plant, controller)?;
        let mut keep_going = |_: usize, _: usize| true;
        let progress = progress.unwrap_or(&mut keep_going);
        let ballbar_spec = match &s.program.source {
            super::ProgramSource::Ballbar(spec) => Some(spec),
            _ => None,
        };
        let outcome = {
            let mut observers: Vec<&mut dyn Observer> = vec![&mut report];
            // The ballbar figures are read from the trace after the run.
            if keep_trace || ballbar_spec.is_some() {
                observers.push(&mut recorder);
            }
            // Reborrowed for this block only: the caller's observers outlive it.
            observers.extend(extra.iter_mut().map(|o| &mut **o as &mut dyn Observer));
            self.simulate(&mut lanes_run, &mut Observers(observers), progress)
        };
        let mut metrics = report.metrics(&outcome);
        let mut warnings = warnings_of(self);
        let inconsistency = metrics
            .inconsistent_figures
            .as_ref()
            .map(inconsistency_text);
        if let Some(text) = &inconsistency {
            warnings.push(FileError::new(&s.path, None, text.clone()));
        }
        let part = match &self.cut {
            Some(setup) => lanes_run[0].plant.take_cut().map(|cut| {
                warnings.extend(cut_warnings(self, &cut));
                part_as_cut(self, setup, cut, outcome.ticks)
            }),
            None => None,
        };
        if let Some(p) = &part {
            metrics.part = Some(p.metrics);
        }
        let mut metrics_json = metrics.to_json();
        let ballbar = match ballbar_spec {
            Some(spec) => {
                let completed = outcome.stop().is_none();
                let run = super::ballbar::ballbar_of_run(
                    self,
                    spec,
                    recorder.lane(0),
                    &metrics,
                    completed,
                    out_dir.as_deref(),
                )?;
                metrics_json["ballbar"] = run.metrics_json();
                Some(run)
            }
            None => None,
        };
        // The frequency responses the scenario asks for, measured after the program (each
        // from rest, on its own machine); a sweep that stops leaves its figures out, so their
        // bounds fail as not produced.
        let mut bode_files = Vec::new();
        if !s.frequency_response.is_empty() && outcome.stop().is_none() {
            let figures =
                self.frequency_responses(out_dir.as_deref(), progress, &mut bode_files)?;
            metrics_json["frequency_response"] = figures;
        }
        let verdict = check(s, &metrics_json);

        // Everything computed so far is written, whether or not the run completed.
        let mut files = Vec::new();
        if let Some(dir) = &out_dir {
            files.push(write_metrics(dir, &metrics_json)?);
        }
        let contour_envelope = report.contour_envelope().clone();
        let end = outcome.ticks as f64 * s.timing.servo_period;
        let mut notes: Vec<(f64, &'static str, String)> = verdict
            .breaches
            .iter()
            .map(|b| (end, "ERROR", format!("bound breached: {b}")))
            .collect();
        let mut summary = summary_markdown(self, &metrics, &verdict);
        if let (Some(text), Some(found)) = (&inconsistency, &metrics.inconsistent_figures) {
            notes.push((found.first_time_s, "WARN", text.clone()));
            summary += &format!("\n**Warning:** {text}\n");
        }
        if let Some(p) = &part {
            if let Some(dir) = &out_dir {
                files.push(write_part(dir, p)?);
            }
            if let Some(note) = report.log_part(end, &p.machined, &p.comparison) {
                summary += &format!("\n{note}\n");
            }
        }
        files.extend(report.finish(&outcome, &notes, &summary)?);
        if let Some(b) = &ballbar {
            files.extend(b.files.iter().cloned());
        }
        files.extend(bode_files);
        let mut traces = recorder.into_traces().into_iter();
        let (trace, analytic) = if keep_trace {
            (traces.next(), traces.next().filter(|_| lanes.len() > 1))
        } else {
            (None, None)
        };
        Ok(RunOutput {
            outcome,
            metrics,
            metrics_json,
            trace,
            analytic,
            contour_envelope,
            verdict,
            files,
            warnings,
            ballbar,
            part,
        })
    }
}

impl Assembly {
    /// The frequency responses `[frequency_response]` asks for, each measured from rest on
    /// its own machine: their figures by axis, their files (under `out_dir`) pushed to `files`.
    /// A sweep that stops leaves its figures out.
    fn frequency_responses(
        &self,
        out_dir: Option<&std::path::Path>,
        progress: &mut dyn FnMut(usize, usize) -> bool,
        files: &mut Vec<PathBuf>,
    ) -> Result<serde_json::Value, RunError> {
        let mut figures = serde_json::Map::new();
        for f in &self.scenario.frequency_response {
            let mut options = super::BodeOptions::new(&f.axis, f.lp);
            options.from = f.from_hz;
            options.to = f.to_hz;
            options.per_decade = f.per_decade;
            match super::bode::bode_on(self, &options, progress) {
                Ok(run) => {
                    figures.insert(f.axis.clone(), run.figures.metrics_json());
                    if let Some(dir) = out_dir {
                        let out = dir.join(format!(
                            "frequency_response_{}_{}",
                            f.axis,
                            super::loop_name(f.lp)
                        ));
                        let written = crate::command::Report::write(&super::BodeOutput {
                            run,
                            out: out.clone(),
                        })
                        .map_err(|e| FileError::new(&out, None, e.to_string()))?;
                        files.extend(written);
                    }
                }
                Err(super::BodeError::Failed(_)) => {}
                Err(super::BodeError::Input(e)) => return Err(e),
            }
        }
        Ok(serde_json::Value::Object(figures))
    }
}

/// `metrics.json` in `dir`.
fn write_metrics(dir: &std::path::Path, metrics: &serde_json::Value) -> Result<PathBuf, RunError> {
    let path = dir.join("metrics.json");
    let text = serde_json::to_string_pretty(metrics).expect("JSON of plain values");
    std::fs::write(&path, text + "\n").map_err(|source| ReportError::Io {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}

/// `part.stl` (binary) in `dir`: the machined part.
fn write_part(dir: &std::path::Path, part: &PartAsCut) -> Result<PathBuf, RunError> {
    let stl = dir.join("part.stl");
    // Streamed: the part's mesh is never whole in memory (at 0.1 mm it outweighs the stock).
    crate::cutting::write_binary_stl_triangles(&stl, part.machined.surface_triangles(), true)
        .map_err(|source| ReportError::Io {
            path: stl.clone(),
            source,
        })?;
    Ok(stl)
}

/// What a cut did that deserves a word: a program that never touches the stock, a plunge
/// with a tool that does not cut at its centre.
fn cut_warnings(assembly: &Assembly, cut: &crate::cutting::Cut) -> Vec<FileError> {
    let program = &assembly.program().source;
    let mut warnings = Vec::new();
    if cut.totals().engaged_steps == 0 {
        warnings.push(FileError::new(
            program,
            None,
            "the tool never touched the stock ([cutting.stock]): the run cut air; check the stock's box against the program's coordinates (work_offset_mm)",
        ));
    }
    if let Some(p) = cut.plunged_at() {
        warnings.push(FileError::new(
            program,
            None,
            format!(
                "the {} tool plunges into the stock at [{:.3}, {:.3}, {:.3}] mm (stock frame): an end mill that does not cut at its centre cannot drill; its bottom is not modelled (ramp in, or use a ball end mill)",
                match cut.tool().shape {
                    crate::cutting::ToolShape::Bull { .. } => "bull-nose",
                    _ => "flat",
                },
                p.x * 1e3,
                p.y * 1e3,
                p.z * 1e3
            ),
        ));
    }
    warnings
}

/// The part a run cut, its nominal part and how they differ.
#[derive(Debug, Clone)]
pub struct PartAsCut {
    /// The stock as the physics cut it.
    pub machined: crate::cutting::Stock,
    /// The same stock cut by the programmed path, without dynamics, for as long as the run
    /// went.
    pub nominal: crate::cutting::Stock,
    /// The machined surface against the nominal one.
    pub comparison: crate::cutting::SurfaceComparison,
    /// Its figures, as `metrics.json` has them under `part`.
    pub metrics: crate::report::PartMetrics,
}

/// What a run whose figures contradict each other says, in its warnings, summary and
/// recording.
fn inconsistency_text(found: &crate::report::Inconsistency) -> String {
    format!(
        "the figures cannot all be true: from t = {:.3} s ({} ticks; the worst at t = {:.3} s, {:.4} mm where at most {:.4} mm is explained) {}",
        found.first_time_s,
        found.ticks,
        found.worst_time_s,
        found.measured_mm,
        found.explained_mm,
        found.likely_cause
    )
}

/// The part as the physics lane cut it (`cut`, after `ticks` program ticks), compared with the
/// nominal part: the starting stock cut by the programmed tool path over the same ticks, as
/// the setpoints put the tool through the machine's forward kinematics, without dynamics.
fn part_as_cut(
    assembly: &Assembly,
    setup: &super::assemble::CutSetup,
    cut: crate::cutting::Cut,
    ticks: usize,
) -> PartAsCut {
    let mut nominal = setup.cut();
    let mut stream = assembly.setpoints();
    let mut sample = crate::plan::SetpointSample::zeros(stream.axes());
    let mut k = 0;
    while k < ticks && stream.next_sample(&mut sample) {
        let (tip, axis) = setup.placement.tool_at(&assembly.machine, &sample.position);
        nominal.sweep_to(&crate::cutting::cut::pose(tip, axis));
        k += 1;
    }
    nominal.finish();
    let nominal = nominal.into_stock();
    let machined = cut.into_stock();
    // Both stocks come from the same starting stock: the lattices match.
    let comparison = crate::cutting::compare(&machined, &nominal, &setup.stock)
        .expect("the machined and nominal stocks share the starting stock's lattice");
    let original = setup.stock.volume();
    let mm3 = 1e9;
    let signed = |sign: f64| {
        comparison
            .points
            .iter()
            .map(|p| sign * p.error)
            .fold(0.0, f64::max)
            * 1e3
    };
    let metrics = crate::report::PartMetrics {
        max_surface_error_mm: comparison.max_error * 1e3,
        rms_surface_error_mm: comparison.rms_error * 1e3,
        max_undercut_mm: signed(1.0),
        max_overcut_mm: signed(-1.0),
        removed_volume_mm3: (original - machined.volume()) * mm3,
        nominal_removed_volume_mm3: (original - nominal.volume()) * mm3,
    };
    PartAsCut {
        machined,
        nominal,
        comparison,
        metrics,
    }
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
        period: s.timing.servo_period,
        path: path_tracker(assembly),
        peak_velocity: assembly.overview().peak_velocity.clone(),
        ticks: assembly.plan.len(),
        lanes: assembly.lane_kinds(),
        backlash: machine.axes.iter().map(|a| a.drive.backlash).collect(),
        move_sources: assembly
            .program()
            .moves
            .iter()
            .map(|m| (m.span.line, m.span.byte_offset))
            .collect(),
        cutting: assembly.cut.is_some(),
    }
}

/// What the figures of the tool against the program compare with: the programmed path of the
/// tool point in the program frame (where rotary axes carry the tool, through the machine's
/// kinematics: the program's X Y Z are then joint coordinates, not the tool's), with what the
/// consistency check of every tick needs.
fn path_tracker(assembly: &Assembly) -> PathTracker {
    use crate::kinematics::tool_path::{programmed_tool_path, rotary_axes_carry_tool};
    let machine = &assembly.machine;
    let program = assembly.program();
    let carried = rotary_axes_carry_tool(machine, &assembly.frame);
    let geometry = if carried {
        programmed_tool_path(machine, &assembly.frame, &assembly.axis_map, program)
    } else {
        PathGeometry::of(program)
    };
    let arms = crate::plan::tool_lever_arms(machine, program, &assembly.axis_map);
    let tool_reach = (0..machine.axes.len())
        .map(|i| {
            if assembly.axis_map.is_rotary(i) {
                arms[i]
            } else {
                1.0
            }
        })
        .collect();
    PathTracker {
        geometry,
        frame: assembly.frame.clone(),
        linear_axes: ["x", "y", "z"].map(|n| machine.axis_index(n)),
        machine: machine.clone(),
        tool_reach,
        corner_tolerance: corner_tolerances(program, assembly.plan.settings()),
        rotary_axes_carry_tool: carried,
    }
}

/// Per move, how far the corners at its two ends let the setpoints leave the programmed path
/// (m): the larger of the two corners' G64 P (with Q, whose joined lines may leave it by that
/// much more), 0 at exact stops; `None` where a corner is rounded without a bound.
fn corner_tolerances(
    program: &crate::program::Program,
    settings: &crate::plan::PlanSettings,
) -> Vec<Option<f64>> {
    use crate::plan::BlendChoice;
    use crate::program::Blend;
    let joined = |q: &Option<f64>| settings.naive_cam_tolerance.or(*q).unwrap_or(0.0);
    let corner = |b: &Blend| match (&settings.blend, b) {
        (BlendChoice::ExactStop, _) | (BlendChoice::Program, Blend::ExactStop) => Some(0.0),
        (BlendChoice::Continuous { tolerance }, b) => {
            let q = match b {
                Blend::Continuous { naive_cam, .. } => joined(naive_cam),
                Blend::ExactStop => joined(&None),
            };
            tolerance.map(|p| p + q)
        }
        (
            BlendChoice::Program,
            Blend::Continuous {
                tolerance,
                naive_cam,
            },
        ) => tolerance.map(|p| p + joined(naive_cam)),
    };
    let corners: Vec<Option<f64>> = program.moves.iter().map(|m| corner(&m.blend)).collect();
    (0..corners.len())
        .map(|m| {
            let before = if m == 0 { Some(0.0) } else { corners[m - 1] };
            Some(before?.max(corners[m]?))
        })
        .collect()
}

/// The recording's view of an assembled scenario, with the programmed tool path on the
/// workpiece.
pub fn recording_setup<'a>(
    assembly: &'a Assembly,
    lanes: &'a [crate::sim::LaneKind],
) -> RecordingSetup<'a> {
    let machine = &assembly.machine;
    RecordingSetup {
        name: &assembly.scenario.name,
        machine,
        labels: &assembly.labels,
        dc_motor: assembly.actuator == ActuatorKind::DcMotor,
        decimation: assembly.scenario.recording.decimation,
        lanes,
        programmed_path: assembly.overview().programmed_path.clone(),
        variant: None,
        stock_frame: assembly.cut.as_ref().map(|c| c.placement.stock_in_part),
        duration: assembly.plan.len() as f64 * assembly.scenario.timing.servo_period,
    }
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
    let controller = s.controller_type().map_or("none", |c| c.name());
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
        s.timing.servo_period * 1e3,
        s.timing.physics_step() * 1e3,
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
