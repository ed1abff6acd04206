//! The trace as CSV: one row per recorded servo tick, display units in the column names.

use super::{AxisLabel, Derived, ReportError};
use crate::sim::Trace;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes every `decimation`-th tick of the trace.
pub fn write_trace_csv(
    path: &Path,
    trace: &Trace,
    derived: &Derived,
    labels: &[AxisLabel],
    decimation: usize,
) -> Result<(), ReportError> {
    let io = |source| ReportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::create(path).map_err(io)?;
    let mut w = BufWriter::new(file);
    let mut header = vec!["t_s".to_string()];
    for l in labels {
        let (u, e) = if l.rotary {
            ("deg", "deg")
        } else {
            ("mm", "um")
        };
        header.extend([
            format!("{}_commanded_{u}", l.name),
            format!("{}_actual_{u}", l.name),
            format!("{}_following_error_{e}", l.name),
            format!("{}_controller_output", l.name),
            format!("{}_torque_nm", l.name),
            format!("{}_voltage_v", l.name),
        ]);
    }
    header.extend(
        [
            "tool_x_mm",
            "tool_y_mm",
            "tool_z_mm",
            "contour_error_um",
            "path_speed_commanded_mm_s",
            "path_speed_actual_mm_s",
        ]
        .map(String::from),
    );
    writeln!(w, "{}", header.join(",")).map_err(io)?;
    let n = trace.axes;
    for k in (0..trace.len()).step_by(decimation.max(1)) {
        let mut row = format!("{:.6}", trace.time[k]);
        for (i, l) in labels.iter().enumerate() {
            let s = l.scale();
            let err_scale = if l.rotary { s } else { 1e6 };
            let c = Trace::at(&trace.commanded, n, k, i);
            let a = Trace::at(&trace.actual, n, k, i);
            row.push_str(&format!(
                ",{:.9},{:.9},{:.6},{:.9},{:.9},{:.6}",
                c * s,
                a * s,
                (c - a) * err_scale,
                Trace::at(&trace.command, n, k, i),
                Trace::at(&trace.torque, n, k, i),
                Trace::at(&trace.voltage, n, k, i)
            ));
        }
        let p = trace.tool_point[k];
        row.push_str(&format!(
            ",{:.9},{:.9},{:.9},{:.6},{:.6},{:.6}",
            p[0] * 1e3,
            p[1] * 1e3,
            p[2] * 1e3,
            derived.contour_error[k] * 1e6,
            derived.commanded_speed[k] * 1e3,
            derived.actual_speed[k] * 1e3
        ));
        writeln!(w, "{row}").map_err(io)?;
    }
    w.flush().map_err(io)
}
