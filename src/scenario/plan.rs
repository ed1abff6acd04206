//! `cncsim plan`: a scenario's program through its planner only — cycle time, per-move
//! durations, and the velocity, acceleration and jerk the setpoints ask of each machine axis
//! and of the tool tip on the workpiece (from finite differences of the sampled positions).

use super::{load_checked_program, plan_settings, ProfileName, RunError, Scenario};
use crate::diagnostics::FileError;
use crate::kinematics::{self, AxisMap};
use crate::machine::Machine;
use crate::plan::{
    finite_difference_extremes, plan_program, AxisExtremes, AxisKind, AxisLimits, AxisSpec,
    Setpoints,
};

/// What planning a scenario produced.
#[derive(Debug, Clone)]
pub struct PlanReport {
    pub profile: ProfileName,
    pub setpoints: Setpoints,
    /// Machine axes (kinds for unit conversion; limits as planned, or zero if none apply).
    pub axes: Vec<AxisSpec>,
    /// Per machine axis: max |v|, |a|, |j| (SI).
    pub axis_extremes: Vec<AxisExtremes>,
    /// Tool tip in workpiece coordinates: per x, y, z, max |v|, |a|, |j| (SI).
    pub tool_extremes: Vec<AxisExtremes>,
    /// Per program move that moved: (move index, source line, duration in s).
    pub move_durations: Vec<(u32, u32, f64)>,
    /// Tool tip on the workpiece at every sample (m).
    pub tool_path: Vec<[f64; 3]>,
}

pub fn plan_scenario(s: &Scenario, profile: Option<ProfileName>) -> Result<PlanReport, RunError> {
    let machine = Machine::load(&s.machine)?;
    let axis_map = AxisMap::cartesian(&machine)
        .map_err(|e| FileError::new(&s.machine, None, e.to_string()))?;
    let program = load_checked_program(s, &machine)?;
    let profile = profile.unwrap_or(s.planner.profile);
    let mut settings = plan_settings(s, &machine, profile)?;
    // Corner tolerances at the tool tip, as the program's author reads them.
    settings.tool_lever_arms = crate::plan::tool_lever_arms(&machine, &program, &axis_map);
    let setpoints =
        plan_program(&program, &axis_map, &settings).map_err(|source| RunError::Plan {
            path: program.source.clone(),
            source,
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

    // Tool tip on the workpiece at every sample, as a 3-axis stream for the same differences.
    let mut tool = Setpoints::new(setpoints.period, 3);
    let zeros = [0.0; 3];
    let mut tool_path = Vec::with_capacity(setpoints.len());
    for k in 0..setpoints.len() {
        let p = kinematics::tool_in_workpiece(&machine, setpoints.position(k));
        tool.push(&[p.x, p.y, p.z], &zeros, &zeros, setpoints.segment[k]);
        tool_path.push([p.x, p.y, p.z]);
    }

    let mut move_durations = Vec::new();
    let mut previous_end = 0usize;
    for k in 1..setpoints.len() {
        let last_of_segment =
            k + 1 == setpoints.len() || setpoints.segment[k + 1] != setpoints.segment[k];
        if last_of_segment {
            let index = setpoints.segment[k];
            let line = program.moves.get(index as usize).map_or(0, |m| m.span.line);
            move_durations.push((index, line, (k - previous_end) as f64 * setpoints.period));
            previous_end = k;
        }
    }
    Ok(PlanReport {
        profile,
        axis_extremes: finite_difference_extremes(&setpoints),
        tool_extremes: finite_difference_extremes(&tool),
        setpoints,
        axes,
        move_durations,
        tool_path,
    })
}

impl PlanReport {
    /// The report as text, in program units (mm, deg, s).
    pub fn text(&self) -> String {
        let mut out = format!(
            "profile {:?}: cycle time {:.6} s ({} samples at T = {} ms)\n",
            self.profile,
            self.setpoints.duration(),
            self.setpoints.len(),
            self.setpoints.period * 1e3
        );
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
