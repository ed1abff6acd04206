//! Everything a run leaves behind, written while it runs: the metrics (accumulated), the CSV
//! trace, the Rerun recording and its event log. It is the loop's observer; memory stays
//! bounded whatever the run's length (chunks, capped logs, a fixed-size plot envelope).

use super::csv::CsvWriter;
use super::events::{Event, EventDetector};
use super::metrics::{Metrics, MetricsAccumulator};
use super::path::{PathSample, PathTracker};
use super::recording::{RecordingSetup, RrdWriter};
use super::{AxisLabel, ReportError};
use crate::sim::{LaneKind, Observer, Outcome, Stop, TickRecord};
use std::path::{Path, PathBuf};

/// Bins of the contour-error envelope kept for plots.
const ENVELOPE_BINS: usize = 4096;

/// What the report of a run is told before it starts (plain data).
pub struct ReportSetup {
    /// The scenario's name.
    pub name: String,
    /// How each machine axis is shown, in the machine's axis order.
    pub labels: Vec<AxisLabel>,
    /// Whether the actuator is the DC-motor model (the metrics then report peak voltage).
    pub dc_motor: bool,
    /// Servo period (s).
    pub period: f64,
    /// The programmed path and program frame that contour error and path speed are measured
    /// against.
    pub path: PathTracker,
    /// Largest |commanded velocity| per axis over the program (for stick-slip).
    pub peak_velocity: Vec<f64>,
    /// Program ticks the run will have, if it completes (for the plot envelope).
    pub ticks: usize,
    /// What each lane simulates, in lane order (a second lane is compared with the first).
    pub lanes: Vec<LaneKind>,
    /// Backlash per axis (joint units) and the source line of each move, for the event log.
    pub backlash: Vec<f64>,
    /// Where each program move was programmed: its source line and byte offset (the pieces a
    /// tool-tip program makes of one move share both).
    pub move_sources: Vec<(u32, u32)>,
    /// Whether the run cuts a stock (its forces and power are then reported).
    pub cutting: bool,
}

/// The largest contour error per bin of the run's duration: a fixed-size curve for plots.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Envelope {
    /// (time of the bin's largest value, value) per bin reached so far.
    pub points: Vec<(f64, f64)>,
    ticks_per_bin: usize,
}

impl Envelope {
    fn new(ticks: usize) -> Envelope {
        Envelope {
            points: Vec::new(),
            ticks_per_bin: ticks.div_ceil(ENVELOPE_BINS).max(1),
        }
    }

    fn push(&mut self, k: usize, time: f64, value: f64) {
        let bin = k / self.ticks_per_bin;
        if bin >= self.points.len() {
            self.points.push((time, value));
        } else if value > self.points[bin].1 || value.is_nan() {
            self.points[bin] = (time, value);
        }
    }

    /// Time of each bin's largest value (s).
    pub fn times(&self) -> Vec<f64> {
        self.points.iter().map(|p| p.0).collect()
    }

    /// Each bin's largest contour error (m).
    pub fn values(&self) -> Vec<f64> {
        self.points.iter().map(|p| p.1).collect()
    }
}

/// The report of one run as it goes: the observer that accumulates its metrics and writes its
/// CSV trace, Rerun recording and event log.
pub struct RunReport {
    setup: ReportSetup,
    metrics: MetricsAccumulator,
    events: EventDetector,
    csv: Option<CsvWriter>,
    csv_decimation: usize,
    rrd: Option<RrdWriter>,
    pending: Vec<Event>,
    envelope: Envelope,
    /// Stops of lanes, in the order they came.
    stops: Vec<(usize, Stop)>,
}

impl RunReport {
    /// A report writing `csv` (every `decimation`-th tick) and `rrd` where given.
    pub fn new(
        setup: ReportSetup,
        csv: Option<&Path>,
        rrd: Option<(&Path, RecordingSetup<'_>)>,
        decimation: usize,
    ) -> Result<RunReport, ReportError> {
        let metrics = MetricsAccumulator::new(
            &setup.labels,
            setup.dc_motor,
            setup.period,
            &setup.peak_velocity,
            setup.lanes.len() > 1,
        );
        let metrics = if setup.cutting {
            metrics.with_cutting()
        } else {
            metrics
        };
        let names: Vec<String> = setup.labels.iter().map(|l| l.name.clone()).collect();
        let events = EventDetector::new(&names, &setup.backlash, setup.move_sources.clone());
        let csv = csv
            .map(|p| CsvWriter::create(p, &setup.labels, setup.cutting))
            .transpose()?;
        let rrd = rrd
            .map(|(p, recording)| RrdWriter::create(p, &recording))
            .transpose()?;
        Ok(RunReport {
            envelope: Envelope::new(setup.ticks),
            setup,
            metrics,
            events,
            csv,
            csv_decimation: decimation.max(1),
            rrd,
            pending: Vec::new(),
            stops: Vec::new(),
        })
    }

    /// A report on a variant's part of a shared recording (A/B): metrics and events only, plus
    /// the given writer.
    pub fn with_recording(setup: ReportSetup, rrd: RrdWriter) -> RunReport {
        let mut report = Self::new(setup, None, None, 1).expect("no files to create");
        report.rrd = Some(rrd);
        report
    }

    /// The metrics of the run so far.
    pub fn metrics(&self, outcome: &Outcome) -> Metrics {
        self.metrics.finish(&self.setup.name, outcome)
    }

    /// Draws the finished part in the recording (where one is written): the stock as cut and
    /// its error against the nominal part. Returns a sentence for the summary.
    pub fn log_part(
        &mut self,
        time: f64,
        stock: &crate::cutting::Stock,
        comparison: &crate::cutting::SurfaceComparison,
    ) -> Option<String> {
        self.rrd
            .as_mut()
            .map(|rrd| rrd.log_part(time, stock, comparison))
    }

    /// The contour-error envelope of the run so far.
    pub fn contour_envelope(&self) -> &Envelope {
        &self.envelope
    }

    /// Finishes every file: the run's remaining rows, the largest errors and the stop in the
    /// event log, `notes` (e.g. breached bounds) and `summary` (Markdown) in the recording.
    /// Returns the files written.
    pub fn finish(
        mut self,
        outcome: &Outcome,
        notes: &[(f64, &'static str, String)],
        summary: &str,
    ) -> Result<Vec<PathBuf>, ReportError> {
        let mut files = Vec::new();
        if let Some(csv) = self.csv.take() {
            files.push(csv.finish()?);
        }
        if let Some(mut rrd) = self.rrd.take() {
            for e in self.pending.drain(..) {
                rrd.event(e.time, e.level, &e.text);
            }
            for (i, (time, error)) in self.metrics.largest_errors().into_iter().enumerate() {
                if outcome.ticks > 0 {
                    let l = &self.setup.labels[i];
                    rrd.mark_largest_error(i, time, error);
                    let shown = error * if l.rotary { l.scale() } else { 1e6 };
                    let unit = super::recording::error_unit(l);
                    rrd.event(
                        time,
                        "INFO",
                        &format!("{}: largest following error, {shown:.3} {unit}", l.name),
                    );
                }
            }
            for (lane, stop) in &self.stops {
                let who = self.setup.lanes.get(*lane).map_or("lane", |l| l.name());
                rrd.event(stop.time(), "ERROR", &format!("{who} stopped: {stop}"));
            }
            for (time, level, text) in notes {
                rrd.event(*time, level, text);
            }
            files.push(rrd.finish(summary)?);
        }
        Ok(files)
    }
}

impl Observer for RunReport {
    fn tick(&mut self, lane: usize, r: &TickRecord<'_>) {
        let s = r.sensors;
        let path: PathSample =
            self.setup
                .path
                .sample(s.tool_point, s.tool_velocity, r.setpoint, &s.position);
        let stalled = self.metrics.observe(lane, r, &path);
        if lane == 0 {
            self.envelope.push(r.k, r.time, path.contour_error);
            if let Some(csv) = &mut self.csv {
                if r.k.is_multiple_of(self.csv_decimation) {
                    csv.row(r, &path);
                }
            }
            self.events.observe(r, stalled, &mut self.pending);
        }
        if let Some(rrd) = &mut self.rrd {
            for e in self.pending.drain(..) {
                rrd.event(e.time, e.level, &e.text);
            }
            rrd.tick(lane, r, &path);
        } else {
            self.pending.clear();
        }
    }

    fn stopped(&mut self, lane: usize, stop: &Stop) {
        self.stops.push((lane, stop.clone()));
    }
}
