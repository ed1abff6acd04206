//! Controller A/B comparisons: two scenarios that differ only in the loop (controller, gains,
//! actuator, timing of the physics) run on the same setpoints, compared side by side.

use super::assemble::{Assembly, RunError};
use super::run::{recording_setup, report_setup, RunOptions};
use super::{folder_name, RunOutput, Scenario};
use crate::command::{write_file, Ending, Report, WriteError};
use crate::report::{ab_blueprint, ReportError, RrdWriter, RunReport};
use crate::sim::LaneKind;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Colours of variants A and B in the shared recording.
const VARIANT_COLOURS: [[u8; 3]; 2] = [[40, 110, 230], [230, 50, 50]];

/// One compared figure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AbRow {
    /// What is compared, e.g. `max contour error` or `x: peak torque`.
    pub metric: String,
    /// Unit of `a` and `b` as shown (µm, mdeg, N·m, ms, s).
    pub unit: &'static str,
    /// Variant A's value, in `unit`.
    pub a: f64,
    /// Variant B's value, in `unit`.
    pub b: f64,
    /// b − a.
    pub difference: f64,
    /// b / a (NaN when a is zero, or both are below what the table shows).
    pub ratio: f64,
}

/// An A/B comparison: the two variants' names and their figures side by side.
#[derive(Debug, Clone, Serialize)]
pub struct AbReport {
    /// Name of scenario A.
    pub a: String,
    /// Name of scenario B.
    pub b: String,
    /// The compared figures: contour errors, each axis's following error and torques, the
    /// ballbar figures when both ran the test, simulated and wall time.
    pub rows: Vec<AbRow>,
}

/// Runs both variants (outputs under `out/a_<name>` and `out/b_<name>`), writes both into one
/// recording `out/ab.rrd` (entities under `a/` and `b/`, a blueprint overlaying them) and
/// compares them. The variants must run the same setpoints; that is checked before either runs.
pub fn run_ab(
    a: &Scenario,
    b: &Scenario,
    out: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<AbOutput, RunError> {
    let (aa, ab) = (Assembly::new(a)?, Assembly::new(b)?);
    if !aa.same_setpoints(&ab) {
        let message = "the two variants do not run the same setpoints (program, planner and servo period must match for an A/B comparison)";
        return Err(crate::diagnostics::FileError::new(&b.path, None, message).into());
    }
    std::fs::create_dir_all(out).map_err(|source| ReportError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let path = out.join("ab.rrd");
    let fail = |e: &dyn std::fmt::Display| -> RunError {
        ReportError::Recording {
            path: path.clone(),
            message: e.to_string(),
        }
        .into()
    };
    let rec = rerun::RecordingStreamBuilder::new("cncsim")
        .recording_name(format!("A/B: {} vs {}", a.name, b.name))
        .save(&path)
        .map_err(|e| fail(&e))?;
    let workpiece = &aa.machine.links[aa.machine.workpiece_link].name;
    let cutting = aa.cut.is_some() && ab.cut.is_some();
    ab_blueprint(
        &aa.labels,
        workpiece,
        &[("a", &a.name), ("b", &b.name)],
        cutting,
    )
    .send(&rec, rerun::blueprint::BlueprintActivation::default())
    .map_err(|e| fail(&e))?;
    let mut outputs = Vec::new();
    for (i, (assembly, prefix)) in [(&aa, "a"), (&ab, "b")].into_iter().enumerate() {
        let s = &assembly.scenario;
        let lanes = [LaneKind::Physics];
        let mut setup = recording_setup(assembly, &lanes);
        setup.variant = Some((
            format!("{}: {}", prefix.to_uppercase(), s.name),
            VARIANT_COLOURS[i],
        ));
        let writer = RrdWriter::on_stream(rec.clone(), &path, &format!("{prefix}/"), &setup)?;
        let mut shared = RunReport::with_recording(report_setup(assembly), writer);
        let folder = out.join(format!("{prefix}_{}", folder_name(&s.name)));
        let run = assembly.run(
            RunOptions::write_to(&folder)
                .observer(&mut shared)
                .progress(&mut *progress),
        )?;
        if let Some(part) = &run.part {
            let end = run.outcome.ticks as f64 * s.timing.servo_period;
            shared.log_part(end, &part.machined, &part.comparison);
        }
        shared.finish(&run.outcome, &[], "")?;
        outputs.push(run);
    }
    let rb = outputs.pop().expect("two runs");
    let ra = outputs.pop().expect("two runs");
    let report = compare(a, &ra, b, &rb);
    rec.log_static(
        "ab_summary",
        &rerun::TextDocument::new(report.markdown()).with_media_type(rerun::MediaType::markdown()),
    )
    .map_err(|e| fail(&e))?;
    rec.flush_blocking().map_err(|e| fail(&e))?;
    Ok(AbOutput {
        report,
        runs: [(a.path.clone(), ra), (b.path.clone(), rb)],
        out: out.to_path_buf(),
    })
}

/// The smallest value the table prints (six decimals of its unit).
const TABLE_RESOLUTION: f64 = 5e-7;

fn compare(a: &Scenario, ra: &RunOutput, b: &Scenario, rb: &RunOutput) -> AbReport {
    let mut rows = Vec::new();
    let mut row = |metric: String, unit: &'static str, x: f64, y: f64| {
        rows.push(AbRow {
            metric,
            unit,
            a: x,
            b: y,
            difference: y - x,
            // Two values below what the table shows (round-off, such as a balanced axis's
            // torque) have no meaningful ratio.
            ratio: if x != 0.0 && x.abs().max(y.abs()) >= TABLE_RESOLUTION {
                y / x
            } else {
                f64::NAN
            },
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
    // What reaches the part, when both cut.
    if let (Some(x), Some(y)) = (&ma.part, &mb.part) {
        row(
            "part: max surface error".into(),
            "µm",
            x.max_surface_error_mm * 1e3,
            y.max_surface_error_mm * 1e3,
        );
        row(
            "part: rms surface error".into(),
            "µm",
            x.rms_surface_error_mm * 1e3,
            y.rms_surface_error_mm * 1e3,
        );
        row(
            "part: max undercut".into(),
            "µm",
            x.max_undercut_mm * 1e3,
            y.max_undercut_mm * 1e3,
        );
        row(
            "part: max overcut".into(),
            "µm",
            x.max_overcut_mm * 1e3,
            y.max_overcut_mm * 1e3,
        );
        row(
            "part: removed volume".into(),
            "mm³",
            x.removed_volume_mm3,
            y.removed_volume_mm3,
        );
    }
    if let (Some(x), Some(y)) = (&ma.cutting, &mb.cutting) {
        row(
            "cutting: max force".into(),
            "N",
            x.max_force_n,
            y.max_force_n,
        );
        row(
            "cutting: max spindle power".into(),
            "W",
            x.max_spindle_power_w,
            y.max_spindle_power_w,
        );
    }
    // The ISO 230-4 figures, when both ran the ballbar test.
    if let (Some(x), Some(y)) = (&ra.ballbar, &rb.ballbar) {
        for (name, p, q) in crate::report::ballbar_pairs(x, y) {
            let unit = if name.ends_with("_ms") { "ms" } else { "µm" };
            row(format!("ballbar {name}"), unit, p, q);
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
            let ratio = if r.ratio.is_nan() {
                "—".to_string()
            } else {
                format!("{:.4}", r.ratio)
            };
            s.push_str(&format!(
                "| {} | {} | {:.6} | {:.6} | {:+.6} | {ratio} |\n",
                r.metric, r.unit, r.a, r.b, r.difference
            ));
        }
        s
    }
}

/// `cncsim ab`: the comparison and both runs, with the folder they were written to.
#[derive(Debug, Clone)]
pub struct AbOutput {
    /// The comparison.
    pub report: AbReport,
    /// Variant A and B: scenario file and run.
    pub runs: [(PathBuf, RunOutput); 2],
    /// The folder the runs and the comparison are written to.
    pub out: PathBuf,
}

impl Report for AbOutput {
    /// `ab.md`, `ab.json`, the shared recording `ab.rrd` (written as the runs went) and the
    /// contour errors of both over time, `contour_error.png`.
    fn write(&self) -> Result<Vec<PathBuf>, WriteError> {
        let json = serde_json::to_string_pretty(&self.report).expect("plain numbers");
        let mut files = vec![
            write_file(self.out.join("ab.md"), self.report.markdown())?,
            write_file(self.out.join("ab.json"), json + "\n")?,
            self.out.join("ab.rrd"),
        ];
        let plot = self.out.join("contour_error.png");
        let labels = [
            format!("A: {}", self.report.a),
            format!("B: {}", self.report.b),
        ];
        let curves = self
            .runs
            .each_ref()
            .map(|(_, r)| (r.contour_envelope.times(), r.contour_envelope.values()));
        let series = [0, 1].map(|i| crate::report::ContourSeries {
            label: &labels[i],
            time: &curves[i].0,
            contour_error: &curves[i].1,
        });
        crate::report::write_contour_error_plot(&plot, &series)?;
        files.push(plot);
        Ok(files)
    }

    fn text(&self) -> String {
        self.report.markdown()
    }

    fn json(&self) -> Option<serde_json::Value> {
        serde_json::to_value(&self.report).ok()
    }

    fn ending(&self) -> Ending {
        match self
            .runs
            .iter()
            .find_map(|(path, r)| r.stop().map(|s| (path, s)))
        {
            Some((path, stop)) => Ending::Failed(Some(format!("{}: {stop}", path.display()))),
            None => Ending::Done,
        }
    }
}
