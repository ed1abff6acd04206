//! Everything a run leaves behind: metrics (terminal table and `metrics.json`), the trace as
//! CSV, and the Rerun recording. Units turn into mm, µm and degrees here, at the edge.

mod csv;
mod metrics;
mod plot;
mod recording;
mod table;

pub use csv::write_trace_csv;
pub use metrics::{AxisMetrics, Derived, Metrics};
pub use plot::{write_contour_error_plot, ContourSeries, PLOT_SIZE};
pub use recording::{write_recording, write_setpoints_recording, RecordingContent};
pub use table::metrics_table;

/// Report errors: only I/O and the recorder can fail here.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("cannot write {path}: {source}")]
    Io {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write the Rerun recording {path}: {message}")]
    Recording {
        path: std::path::PathBuf,
        message: String,
    },
}

/// How a machine axis is shown: linear axes in mm (errors in µm), rotary ones in degrees.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisLabel {
    pub name: String,
    pub rotary: bool,
}

impl AxisLabel {
    /// Factor from joint units (m or rad) to display units (mm or deg).
    pub fn scale(&self) -> f64 {
        if self.rotary {
            180.0 / std::f64::consts::PI
        } else {
            1e3
        }
    }

    pub fn unit(&self) -> &'static str {
        if self.rotary {
            "deg"
        } else {
            "mm"
        }
    }
}
