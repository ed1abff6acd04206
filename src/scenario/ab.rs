//! Controller A/B comparisons: two scenarios that differ only in the loop (controller, gains,
//! actuator, timing of the physics) run on the same setpoints, compared side by side.

use super::{folder_name, run_scenario, RunError, RunOutput, Scenario};
use serde::Serialize;
use std::path::Path;

/// One compared figure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AbRow {
    pub metric: String,
    pub unit: &'static str,
    pub a: f64,
    pub b: f64,
    /// b − a.
    pub difference: f64,
    /// b / a (NaN when a is zero).
    pub ratio: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct AbReport {
    pub a: String,
    pub b: String,
    pub rows: Vec<AbRow>,
}

/// Runs both variants (outputs under `out/a_<name>` and `out/b_<name>`) and compares them.
pub fn run_ab(
    a: &Scenario,
    b: &Scenario,
    out: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<(AbReport, RunOutput, RunOutput), RunError> {
    let ra = run_scenario(
        a,
        &out.join(format!("a_{}", folder_name(&a.name))),
        progress,
    )?;
    let rb = run_scenario(
        b,
        &out.join(format!("b_{}", folder_name(&b.name))),
        progress,
    )?;
    if ra.trace.commanded != rb.trace.commanded && ra.stop.is_none() && rb.stop.is_none() {
        let message = "the two variants do not run the same setpoints (program, planner and servo period must match for an A/B comparison)";
        return Err(crate::diagnostics::FileError::new(&b.path, None, message).into());
    }
    Ok((compare(a, &ra, b, &rb), ra, rb))
}

fn compare(a: &Scenario, ra: &RunOutput, b: &Scenario, rb: &RunOutput) -> AbReport {
    let mut rows = Vec::new();
    let mut row = |metric: String, unit: &'static str, x: f64, y: f64| {
        rows.push(AbRow {
            metric,
            unit,
            a: x,
            b: y,
            difference: y - x,
            ratio: if x != 0.0 { y / x } else { f64::NAN },
        });
    };
    let (ma, mb) = (&ra.metrics, &rb.metrics);
    row(
        "max contour error".into(),
        "µm",
        ma.max_contour_error_mm * 1e3,
        mb.max_contour_error_mm * 1e3,
    );
    row(
        "rms contour error".into(),
        "µm",
        ma.rms_contour_error_mm * 1e3,
        mb.rms_contour_error_mm * 1e3,
    );
    for (name, xa) in &ma.axes {
        let Some(xb) = mb.axes.get(name) else {
            continue;
        };
        match (xa.max_following_error_mm, xb.max_following_error_mm) {
            (Some(p), Some(q)) => row(
                format!("{name}: max following error"),
                "µm",
                p * 1e3,
                q * 1e3,
            ),
            _ => {
                if let (Some(p), Some(q)) = (xa.max_following_error_deg, xb.max_following_error_deg)
                {
                    row(
                        format!("{name}: max following error"),
                        "mdeg",
                        p * 1e3,
                        q * 1e3,
                    );
                }
            }
        }
    }
    for (name, xa) in &ma.axes {
        if let Some(xb) = mb.axes.get(name) {
            row(
                format!("{name}: peak torque"),
                "N·m",
                xa.peak_torque_nm,
                xb.peak_torque_nm,
            );
            row(
                format!("{name}: rms torque"),
                "N·m",
                xa.rms_torque_nm,
                xb.rms_torque_nm,
            );
        }
    }
    row("simulated time".into(), "s", ma.sim_time_s, mb.sim_time_s);
    row("wall time".into(), "s", ma.wall_time_s, mb.wall_time_s);
    AbReport {
        a: a.name.clone(),
        b: b.name.clone(),
        rows,
    }
}

impl AbReport {
    /// The comparison as a Markdown table.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "| metric | unit | A: {} | B: {} | B − A | B / A |\n|---|---|---:|---:|---:|---:|\n",
            self.a, self.b
        );
        for r in &self.rows {
            s.push_str(&format!(
                "| {} | {} | {:.6} | {:.6} | {:+.6} | {:.4} |\n",
                r.metric, r.unit, r.a, r.b, r.difference, r.ratio
            ));
        }
        s
    }
}
