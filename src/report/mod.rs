//! Everything a run leaves behind: metrics (terminal table and `metrics.json`), the trace as
//! CSV, and the Rerun recording. Units turn into mm, µm and degrees here, at the edge.

mod ballbar;
mod blueprint;
mod bode;
mod csv;
mod events;
mod metrics;
mod path;
mod plot;
mod recording;
mod run_report;
mod table;
mod thin;

pub(crate) use ballbar::golden;
pub use ballbar::{
    analyse as analyse_ballbar, ballbar_pairs, least_squares_circle, minimum_zone_circle,
    write_polar_plot, BallbarInput, BallbarPass, BallbarReport, BallbarRun, DirectionFigures,
    ReversalSpike, ServoMismatch, Vibration,
};
pub use blueprint::{ab_blueprint, run_blueprint};
pub use bode::{BodeRun, Curve, Figures, Points, MIN_COHERENCE, PROMINENCE_DB};
pub use csv::CsvWriter;
pub use events::{Event, EventDetector, MAX_EVENTS_PER_KIND};
pub use metrics::{
    AxisMetrics, CuttingMetrics, Inconsistency, Metrics, MetricsAccumulator, PartMetrics,
    StallCounter,
};
pub use path::{PathSample, PathTracker};
pub use plot::{
    write_bar_plot, write_contour_error_plot, write_line_plot, BarSeries, ContourSeries, PLOT_SIZE,
};
pub use recording::{magnification, write_setpoints_recording, RecordingSetup, RrdWriter};
pub use run_report::{Envelope, ReportSetup, RunReport};
pub use table::metrics_table;
pub use thin::{Thinned, ThinnedPath};

/// Report errors: only I/O and the recorder can fail here.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file or folder could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file or folder.
        path: std::path::PathBuf,
        /// What the operating system reported.
        source: std::io::Error,
    },
    /// The Rerun recording could not be written.
    #[error("cannot write the Rerun recording {path}: {message}")]
    Recording {
        /// The recording's file.
        path: std::path::PathBuf,
        /// What the recorder reported.
        message: String,
    },
}

/// How a machine axis is shown: linear axes in mm (errors in µm), rotary ones in degrees.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisLabel {
    /// The axis's program letter (e.g. `x`, `a`).
    pub name: String,
    /// Whether the axis is rotary (shown in degrees, else in mm).
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

    /// The display unit: "mm" or "deg".
    pub fn unit(&self) -> &'static str {
        if self.rotary {
            "deg"
        } else {
            "mm"
        }
    }
}
