//! `cncsim plan`: a scenario's program through its planner only — cycle time, per-move
//! durations, and the velocity, acceleration and jerk the setpoints ask of each machine axis
//! and of the tool tip on the workpiece (from finite differences of the sampled positions).

use super::{axis_map_for, load_checked_program, plan_settings, ProfileName, RunError, Scenario};
use crate::command::{cannot_write, Report, WriteError};
use crate::kinematics::{self, ProgramFrame};
use crate::machine::Machine;
use crate::plan::{
    AxisExtremes, AxisKind, AxisLimits, AxisSpec, FiniteDifferences, PlannedProgram, SetpointSample,
};
use crate::report::ThinnedPath;
use nalgebra::Point3;
use std::path::PathBuf;

/// Points of the tool path kept for the plan's recording (evenly thinned over the program).
const TOOL_PATH_POINTS: usize = 50_000;

/// What planning a scenario produced.
#[derive(Debug, Clone)]
pub struct PlanReport {
    /// The planner used (the scenario's, or the one asked for).
    pub profile: ProfileName,
    /// The planned program: its setpoints are streamed again to write them (no sample is kept,
    /// so a plan of any duration fits in memory).
    pub plan: PlannedProgram,
    /// Machine axes (kinds for unit conversion; limits as planned, or zero if none apply).
    pub axes: Vec<AxisSpec>,
    /// Per machine axis: max |v|, |a|, |j| (SI).
    pub axis_extremes: Vec<AxisExtremes>,
    /// Tool tip in workpiece coordinates: per x, y, z, max |v|, |a|, |j| (SI).
    pub tool_extremes: Vec<AxisExtremes>,
    /// Per program move that moved: (move index, source line, duration in s).
    pub move_durations: Vec<(u32, u32, f64)>,
    /// Tool tip on the workpiece, evenly thinned over the samples to at most 50 000 points, the
    /// last sample's included (m).
    pub tool_path: Vec<[f64; 3]>,
}

/// Plans `s`'s program on its machine with `profile` (`None`: the scenario's planner profile)
/// and measures the setpoints: per-axis and tool-tip extremes, per-move durations, the tool
/// path.
pub fn plan_scenario(s: &Scenario, profile: Option<ProfileName>) -> Result<PlanReport, RunError> {
    let machine = Machine::load(&s.machine)?;
    let axis_map = axis_map_for(s, &machine)?;
    let (frame, _) = ProgramFrame::new(&machine)?;
    let program = load_checked_program(s, &machine)?;
    let profile = profile.unwrap_or(s.planner.profile);
    let mut settings = plan_settings(s, &machine, profile)?;
    // Corner tolerances at the tool tip, as the program's author reads them.
    settings.tool_lever_arms = crate::plan::tool_lever_arms(&machine, &program, &axis_map);
    let source = program.source.clone();
    let plan =
        PlannedProgram::new(program, axis_map, settings.clone()).map_err(|source_error| {
            RunError::Plan {
                path: source,
                source: source_error,
            }
        })?;
    let limits = match &settings.planner {
        crate::plan::Planner::JerkLimited { limits } => limits.clone(),
        _ => vec![
            AxisLimits {
                velocity: 0.0,
                acceleration: 0.0,
                jerk: 0.0
            };
            machine.axes.len()
        ],
    };
    let axes = machine
        .axes
        .iter()
        .zip(limits)
        .map(|(a, limits)| AxisSpec {
            name: a.name.clone(),
            kind: if a.is_rotary(&machine) {
                AxisKind::Rotary
            } else {
                AxisKind::Linear
            },
            limits,
        })
        .collect();

    // The tool tip's motion along the program axes; where rotary axes carry the part (a
    // tilting table), on the part, along the workpiece link's axes.
    let tool_motion = |q: &[f64]| {
        if frame.carrier == machine.workpiece_link {
            let p = kinematics::tool_in_link(&machine, frame.carrier, q);
            Point3::from(frame.program_vector(&p.coords))
        } else {
            kinematics::tool_in_workpiece(&machine, q)
        }
    };
    // One pass over the samples: the machine axes' and the tool tip's finite differences, the
    // moves' durations and the tool path.
    let period = settings.period;
    let mut stream = plan.stream();
    let mut sample = SetpointSample::zeros(stream.axes());
    let mut axis_differences = FiniteDifferences::new(stream.axes(), period);
    let mut tool_differences = FiniteDifferences::new(3, period);
    let mut tool_path = ThinnedPath::new(TOOL_PATH_POINTS);
    let mut move_durations = Vec::new();
    let line_of = |index: u32| {
        plan.program()
            .moves
            .get(index as usize)
            .map_or(0, |m| m.span.line)
    };
    // A move ends at its last sample (sample 0 is the start, before any move).
    let (mut k, mut previous_end, mut previous_segment) = (0usize, 0usize, None);
    while stream.next_sample(&mut sample) {
        axis_differences.push(&sample.position);
        let v = tool_motion(&sample.position);
        tool_differences.push(&[v.x, v.y, v.z]);
        let p = kinematics::tool_in_workpiece(&machine, &sample.position);
        tool_path.push([p.x, p.y, p.z]);
        if let Some(segment) = previous_segment {
            if k >= 2 && segment != sample.segment {
                move_durations.push((
                    segment,
                    line_of(segment),
                    (k - 1 - previous_end) as f64 * period,
                ));
                previous_end = k - 1;
            }
        }
        previous_segment = Some(sample.segment);
        k += 1;
    }
    if let (Some(segment), true) = (previous_segment, k >= 2) {
        move_durations.push((
            segment,
            line_of(segment),
            (k - 1 - previous_end) as f64 * period,
        ));
    }
    drop(stream);
    Ok(PlanReport {
        profile,
        axis_extremes: axis_differences.extremes(),
        tool_extremes: tool_differences.extremes(),
        plan,
        axes,
        move_durations,
        tool_path: tool_path.into_points(),
    })
}

impl PlanReport {
    /// Cycle time: from the first sample to the last (s).
    pub fn duration(&self) -> f64 {
        self.plan.len().saturating_sub(1) as f64 * self.plan.settings().period
    }

    /// The report as text, in program units (mm, deg, s).
    pub fn text(&self) -> String {
        let mut out = format!(
            "profile {:?}: cycle time {:.6} s ({} samples at T = {} ms)\n",
            self.profile,
            self.duration(),
            self.plan.len(),
            self.plan.settings().period * 1e3
        );
        if let Some(line) = self.plan.look_ahead().summary() {
            out.push_str(&format!("  {line}\n"));
        }
        out.push_str("  move  line   duration s   (to the servo period)\n");
        for (index, line, d) in &self.move_durations {
            out.push_str(&format!("  {index:>4}  {line:>4}   {d:>10.3}\n"));
        }
        out.push_str("  axis        max |v|        max |a|        max |j|      limits v / a / j\n");
        for (spec, e) in self.axes.iter().zip(&self.axis_extremes) {
            let (u, f) = match spec.kind {
                AxisKind::Linear => ("mm", 1e3),
                AxisKind::Rotary => ("deg", 180.0 / std::f64::consts::PI),
            };
            let limits = if spec.limits.velocity > 0.0 {
                format!(
                    "{:.1} / {:.1} / {:.1}",
                    spec.limits.velocity * f,
                    spec.limits.acceleration * f,
                    spec.limits.jerk * f
                )
            } else {
                "—".into()
            };
            out.push_str(&format!(
                "  {:<4} {:>10.3} {u}/s {:>10.3} {u}/s² {:>10.3} {u}/s³   {limits}\n",
                spec.name,
                e.velocity * f,
                e.acceleration * f,
                e.jerk * f
            ));
        }
        out.push_str("  tool tip in workpiece coordinates:\n");
        for (name, e) in ["x", "y", "z"].iter().zip(&self.tool_extremes) {
            out.push_str(&format!(
                "  {:<4} {:>10.3} mm/s {:>10.3} mm/s² {:>10.3} mm/s³\n",
                name,
                e.velocity * 1e3,
                e.acceleration * 1e3,
                e.jerk * 1e3
            ));
        }
        out
    }
}

/// `cncsim plan`: the plan's report, and the files asked for.
#[derive(Debug, Clone)]
pub struct PlanOutput {
    /// What planning the scenario produced.
    pub report: PlanReport,
    /// The scenario's name (the recording's title).
    pub name: String,
    /// Every setpoint as CSV, where asked for.
    pub csv: Option<PathBuf>,
    /// The setpoints and tool path as a Rerun recording, where asked for.
    pub rrd: Option<PathBuf>,
}

impl Report for PlanOutput {
    fn write(&self) -> Result<Vec<PathBuf>, WriteError> {
        let mut files = Vec::new();
        let report = &self.report;
        if let Some(csv) = &self.csv {
            let written = std::fs::File::create(csv).and_then(|f| {
                let mut w = std::io::BufWriter::new(f);
                crate::plan::write_setpoint_stream_csv(
                    &mut w,
                    report.plan.stream().as_mut(),
                    &report.axes,
                )?;
                std::io::Write::flush(&mut w)
            });
            written.map_err(|e| cannot_write(csv, e))?;
            files.push(csv.clone());
        }
        if let Some(rrd) = &self.rrd {
            let labels: Vec<crate::report::AxisLabel> = report
                .axes
                .iter()
                .map(|a| crate::report::AxisLabel {
                    name: a.name.clone(),
                    rotary: a.kind == AxisKind::Rotary,
                })
                .collect();
            crate::report::write_setpoints_recording(
                rrd,
                &self.name,
                report.plan.stream().as_mut(),
                &labels,
                &report.tool_path,
            )?;
            files.push(rrd.clone());
        }
        Ok(files)
    }

    fn text(&self) -> String {
        self.report.text()
    }
}
