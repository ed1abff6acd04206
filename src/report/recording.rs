//! The Rerun recording of a run: the machine moving in 3D, commanded and actual tool paths,
//! and per-axis time series on the `sim_time` timeline.
//!
//! Entity paths (stable; tests and users rely on them):
//! - `world/machine/<link>`: link pose per recorded tick; `…/<link>/visual_<i>` its boxes
//! - `world/path/programmed`, `world/path/actual`: tool paths (m), `world/tool`: tool point
//! - `axes/<axis>/{commanded,actual}` (mm or deg), `axes/<axis>/following_error` (µm or deg),
//!   `axes/<axis>/torque` (N·m), `axes/<axis>/voltage` (V, DC-motor model only),
//!   `axes/<axis>/drive` (mm or deg: the drive side of the backlash, for axes that have one)
//! - `path/contour_error` (µm), `path/speed/{commanded,actual}` (mm/s)

use super::{AxisLabel, Derived, ReportError};
use crate::machine::Machine;
use crate::sim::Trace;
use nalgebra::Isometry3;
use rerun::{RecordingStream, TimeColumn};
use std::path::Path;

/// What goes into a recording besides the trace.
pub struct RecordingContent<'a> {
    pub name: &'a str,
    pub machine: &'a Machine,
    pub labels: &'a [AxisLabel],
    /// Link poses at each recorded tick (from the kinematics of the actual joint positions).
    pub link_poses: &'a dyn Fn(usize) -> Vec<Isometry3<f64>>,
    /// Programmed tool path in the machine frame (m).
    pub programmed_path: Vec<[f64; 3]>,
    pub dc_motor: bool,
    pub decimation: usize,
    /// Positions of the analytic reference model in the trace's layout, when it was run.
    pub analytic: Option<&'a Trace>,
}

pub fn write_recording(
    path: &Path,
    trace: &Trace,
    derived: &Derived,
    content: &RecordingContent<'_>,
) -> Result<(), ReportError> {
    let fail = |e: &dyn std::fmt::Display| ReportError::Recording {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let rec = rerun::RecordingStreamBuilder::new("cncsim")
        .recording_name(content.name)
        .save(path)
        .map_err(|e| fail(&e))?;
    log_all(&rec, trace, derived, content).map_err(|e| fail(&e))?;
    rec.flush_blocking().map_err(|e| fail(&e))?;
    Ok(())
}

fn log_all(
    rec: &RecordingStream,
    trace: &Trace,
    derived: &Derived,
    c: &RecordingContent<'_>,
) -> rerun::RecordingStreamResult<()> {
    let ticks: Vec<usize> = (0..trace.len()).step_by(c.decimation.max(1)).collect();
    let times = || TimeColumn::new_duration_secs("sim_time", ticks.iter().map(|&k| trace.time[k]));
    let n = trace.axes;

    rec.log_static("world", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;

    // Machine links: static boxes in link frames, link poses over time.
    let poses: Vec<Vec<Isometry3<f64>>> = ticks.iter().map(|&k| (c.link_poses)(k)).collect();
    for (li, link) in c.machine.links.iter().enumerate() {
        let entity = format!("world/machine/{}", link.name);
        for (bi, b) in link.boxes.iter().enumerate() {
            let child = format!("{entity}/visual_{bi}");
            rec.log_static(child.as_str(), &transform(&b.pose))?;
            let mut boxes = rerun::Boxes3D::from_half_sizes([[
                b.half_extents.x as f32,
                b.half_extents.y as f32,
                b.half_extents.z as f32,
            ]])
            .with_fill_mode(rerun::FillMode::Solid);
            if let Some([r, g, bl, a]) = b.color {
                boxes = boxes.with_colors([rerun::Color::from_unmultiplied_rgba(
                    (r * 255.0) as u8,
                    (g * 255.0) as u8,
                    (bl * 255.0) as u8,
                    (a * 255.0) as u8,
                )]);
            }
            rec.log_static(child.as_str(), &boxes)?;
        }
        let translations: Vec<[f32; 3]> = poses
            .iter()
            .map(|p| f32x3(&p[li].translation.vector))
            .collect();
        let rotations: Vec<rerun::Quaternion> = poses
            .iter()
            .map(|p| {
                let q = p[li].rotation.quaternion();
                rerun::Quaternion::from_xyzw([q.i as f32, q.j as f32, q.k as f32, q.w as f32])
            })
            .collect();
        let t = rerun::Transform3D::new()
            .with_many_translation(translations)
            .with_many_quaternion(rotations);
        rec.send_columns(entity.as_str(), [times()], t.columns_of_unit_batches()?)?;
    }

    // Tool paths and the moving tool point.
    let strip = |pts: &[[f64; 3]]| {
        pts.iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
            .collect::<Vec<_>>()
    };
    rec.log_static(
        "world/path/programmed",
        &rerun::LineStrips3D::new([strip(&c.programmed_path)])
            .with_colors([rerun::Color::from_rgb(90, 160, 255)]),
    )?;
    let actual: Vec<[f64; 3]> = ticks.iter().map(|&k| trace.tool_point[k]).collect();
    rec.log_static(
        "world/path/actual",
        &rerun::LineStrips3D::new([strip(&actual)])
            .with_colors([rerun::Color::from_rgb(255, 120, 60)]),
    )?;
    rec.send_columns(
        "world/tool",
        [times()],
        rerun::Points3D::new(strip(&actual)).columns_of_unit_batches()?,
    )?;

    // Per-axis time series.
    let series = |entity: String, values: Vec<f64>| -> rerun::RecordingStreamResult<()> {
        rec.send_columns(
            entity.as_str(),
            [times()],
            rerun::Scalars::new(values).columns_of_unit_batches()?,
        )
    };
    for (i, l) in c.labels.iter().enumerate() {
        let s = l.scale();
        let err_scale = if l.rotary { s } else { 1e6 };
        let at = |v: &[f64], k: usize| Trace::at(v, n, k, i);
        let base = format!("axes/{}", l.name);
        series(
            format!("{base}/commanded"),
            ticks.iter().map(|&k| at(&trace.commanded, k) * s).collect(),
        )?;
        series(
            format!("{base}/actual"),
            ticks.iter().map(|&k| at(&trace.actual, k) * s).collect(),
        )?;
        series(
            format!("{base}/following_error"),
            ticks
                .iter()
                .map(|&k| (at(&trace.commanded, k) - at(&trace.actual, k)) * err_scale)
                .collect(),
        )?;
        if has_slack(trace, i) {
            series(
                format!("{base}/drive"),
                ticks.iter().map(|&k| at(&trace.drive, k) * s).collect(),
            )?;
        }
        series(
            format!("{base}/torque"),
            ticks.iter().map(|&k| at(&trace.torque, k)).collect(),
        )?;
        if c.dc_motor {
            series(
                format!("{base}/voltage"),
                ticks.iter().map(|&k| at(&trace.voltage, k)).collect(),
            )?;
        }
    }
    if let Some(analytic) = c.analytic {
        // The reference model under its own entity paths, beside the physics in the viewer.
        for (i, l) in c.labels.iter().enumerate() {
            let s = l.scale();
            let err_scale = if l.rotary { s } else { 1e6 };
            let at = |k: usize| analytic.actual[k * n + i];
            if has_slack(analytic, i) {
                series(
                    format!("analytic/axes/{}/drive", l.name),
                    ticks
                        .iter()
                        .map(|&k| Trace::at(&analytic.drive, n, k, i) * s)
                        .collect(),
                )?;
            }
            let base = format!("analytic/axes/{}", l.name);
            series(
                format!("{base}/actual"),
                ticks.iter().map(|&k| at(k) * s).collect(),
            )?;
            series(
                format!("{base}/following_error"),
                ticks
                    .iter()
                    .map(|&k| (Trace::at(&trace.commanded, n, k, i) - at(k)) * err_scale)
                    .collect(),
            )?;
        }
    }
    series(
        "path/contour_error".into(),
        ticks
            .iter()
            .map(|&k| derived.contour_error[k] * 1e6)
            .collect(),
    )?;
    series(
        "path/speed/commanded".into(),
        ticks
            .iter()
            .map(|&k| derived.commanded_speed[k] * 1e3)
            .collect(),
    )?;
    series(
        "path/speed/actual".into(),
        ticks
            .iter()
            .map(|&k| derived.actual_speed[k] * 1e3)
            .collect(),
    )?;
    Ok(())
}

fn transform(p: &Isometry3<f64>) -> rerun::Transform3D {
    let q = p.rotation.quaternion();
    rerun::Transform3D::from_translation(f32x3(&p.translation.vector)).with_quaternion(
        rerun::Quaternion::from_xyzw([q.i as f32, q.j as f32, q.k as f32, q.w as f32]),
    )
}

fn f32x3(v: &nalgebra::Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// A recording of a planned setpoint stream (`cncsim plan --rrd`): per machine axis position,
/// velocity and acceleration (mm or deg units) under `setpoints/<axis>/…`, and the tool path on
/// the workpiece (`workpiece/tool_path`, m) when given.
pub fn write_setpoints_recording(
    path: &Path,
    name: &str,
    setpoints: &crate::plan::Setpoints,
    labels: &[AxisLabel],
    tool_on_workpiece: &[[f64; 3]],
) -> Result<(), ReportError> {
    let fail = |e: &dyn std::fmt::Display| ReportError::Recording {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let rec = rerun::RecordingStreamBuilder::new("cncsim")
        .recording_name(name)
        .save(path)
        .map_err(|e| fail(&e))?;
    let log = || -> rerun::RecordingStreamResult<()> {
        let n = setpoints.axes;
        let times = || {
            TimeColumn::new_duration_secs(
                "sim_time",
                (0..setpoints.len()).map(|k| k as f64 * setpoints.period),
            )
        };
        for (i, l) in labels.iter().enumerate() {
            let s = l.scale();
            for (series, values) in [
                ("position", &setpoints.position),
                ("velocity", &setpoints.velocity),
                ("acceleration", &setpoints.acceleration),
            ] {
                let column: Vec<f64> = (0..setpoints.len())
                    .map(|k| values[k * n + i] * s)
                    .collect();
                rec.send_columns(
                    format!("setpoints/{}/{series}", l.name).as_str(),
                    [times()],
                    rerun::Scalars::new(column).columns_of_unit_batches()?,
                )?;
            }
        }
        if !tool_on_workpiece.is_empty() {
            let strip: Vec<[f32; 3]> = tool_on_workpiece
                .iter()
                .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
                .collect();
            rec.log_static("workpiece", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;
            rec.log_static("workpiece/tool_path", &rerun::LineStrips3D::new([strip]))?;
        }
        Ok(())
    };
    log().map_err(|e| fail(&e))?;
    rec.flush_blocking().map_err(|e| fail(&e))?;
    Ok(())
}

/// Whether axis `i` ever had its drive side apart from its carriage (backlash): only then is
/// the drive position worth a series of its own.
fn has_slack(trace: &Trace, i: usize) -> bool {
    let n = trace.axes;
    trace.drive.len() == trace.actual.len()
        && (0..trace.len())
            .any(|k| Trace::at(&trace.drive, n, k, i) != Trace::at(&trace.actual, n, k, i))
}
