//! The run as CSV, written as it runs: one row per recorded servo tick of the physics, display
//! units in the column names.

use super::path::PathSample;
use super::{AxisLabel, ReportError};
use crate::sim::TickRecord;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes a run's CSV one physics tick at a time; a write error is kept and reported by
/// [`CsvWriter::finish`].
pub struct CsvWriter {
    path: PathBuf,
    out: BufWriter<std::fs::File>,
    labels: Vec<AxisLabel>,
    /// Whether the cutting process's columns are written.
    cutting: bool,
    /// The first error, reported when the file is finished (the loop does not stop for it).
    error: Option<std::io::Error>,
    row: String,
}

impl CsvWriter {
    /// Creates the file and writes its header; `cutting` adds the cutting process's columns.
    pub fn create(
        path: &Path,
        labels: &[AxisLabel],
        cutting: bool,
    ) -> Result<CsvWriter, ReportError> {
        let io = |source| ReportError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = std::fs::File::create(path).map_err(io)?;
        let mut out = BufWriter::new(file);
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
        if cutting {
            header.extend(
                [
                    "cutting_force_x_n",
                    "cutting_force_y_n",
                    "cutting_force_z_n",
                    "spindle_power_w",
                    "engaged_flutes",
                ]
                .map(String::from),
            );
        }
        writeln!(out, "{}", header.join(",")).map_err(io)?;
        Ok(CsvWriter {
            path: path.to_path_buf(),
            out,
            labels: labels.to_vec(),
            cutting,
            error: None,
            row: String::new(),
        })
    }

    /// Appends the row of a physics tick.
    pub fn row(&mut self, r: &TickRecord<'_>, path: &PathSample) {
        use std::fmt::Write as _;
        if self.error.is_some() {
            return;
        }
        let row = &mut self.row;
        row.clear();
        let _ = write!(row, "{:.6}", r.time);
        for (i, l) in self.labels.iter().enumerate() {
            let s = l.scale();
            let err_scale = if l.rotary { s } else { 1e6 };
            let (c, a) = (r.setpoint.position[i], r.sensors.position[i]);
            let _ = write!(
                row,
                ",{:.9},{:.9},{:.6},{:.9},{:.9},{:.6}",
                c * s,
                a * s,
                (c - a) * err_scale,
                r.command[i],
                r.hold.mean_torque[i],
                r.hold.voltage[i]
            );
        }
        let p = r.sensors.tool_point;
        let _ = write!(
            row,
            ",{:.9},{:.9},{:.9},{:.6},{:.6},{:.6}",
            p[0] * 1e3,
            p[1] * 1e3,
            p[2] * 1e3,
            path.contour_error * 1e6,
            path.commanded_speed * 1e3,
            path.actual_speed * 1e3
        );
        if self.cutting {
            let c = &r.hold.cut;
            let _ = write!(
                row,
                ",{:.6},{:.6},{:.6},{:.6},{}",
                c.force[0], c.force[1], c.force[2], c.spindle_power, c.engaged_flutes
            );
        }
        if let Err(e) = writeln!(self.out, "{row}") {
            self.error = Some(e);
        }
    }

    /// Flushes the file; the first write error, if any, is reported here.
    pub fn finish(mut self) -> Result<PathBuf, ReportError> {
        let flushed = self.out.flush();
        match self.error.take().map_or(flushed, Err) {
            Ok(()) => Ok(self.path),
            Err(source) => Err(ReportError::Io {
                path: self.path,
                source,
            }),
        }
    }
}
