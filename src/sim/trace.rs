//! A run kept in memory, tick by tick: for tests, tuning and short studies. Runs of any length
//! go to the streaming observers of `report` instead.

use super::{Observer, Stop, TickRecord};

/// Per-tick record of one lane; sample k of axis i at `k * axes + i`. Joint units (SI).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trace {
    /// Servo period (s).
    pub period: f64,
    /// Number of machine axes (the stride of the per-axis series).
    pub axes: usize,
    /// Program time of each sample (s).
    pub time: Vec<f64>,
    /// Setpoint position (m, or rad on a rotary axis).
    pub commanded: Vec<f64>,
    /// Setpoint velocity (m/s, or rad/s on a rotary axis).
    pub commanded_velocity: Vec<f64>,
    /// Carriage (load-side) position sampled at the start of the period (m, or rad).
    pub actual: Vec<f64>,
    /// Carriage velocity sampled at the start of the period (m/s, or rad/s).
    pub actual_velocity: Vec<f64>,
    /// Drive-side position (motor angle over the ratio); equals `actual` without backlash.
    pub drive: Vec<f64>,
    /// Controller output (N·m or V).
    pub command: Vec<f64>,
    /// Mean motor torque over the hold interval that follows the sample (N·m).
    pub torque: Vec<f64>,
    /// Armature voltage (V), zero with the ideal actuator.
    pub voltage: Vec<f64>,
    /// Armature current at the sample (A).
    pub current: Vec<f64>,
    /// Tool point and its velocity (m, m/s).
    pub tool_point: Vec<[f64; 3]>,
    /// Tool-point velocity in the machine base frame, one per sample (m/s).
    pub tool_velocity: Vec<[f64; 3]>,
    /// Program move of the setpoint.
    pub segment: Vec<u32>,
    /// What the cut did over each period (zeros for a plant that does not cut).
    pub cut: Vec<super::CutRecord>,
}

impl Trace {
    /// An empty trace of `axes` axes sampled every `period` (s).
    pub fn new(period: f64, axes: usize) -> Trace {
        Trace {
            period,
            axes,
            ..Default::default()
        }
    }

    /// Number of samples (ticks) kept.
    pub fn len(&self) -> usize {
        self.time.len()
    }

    /// Whether no tick was kept.
    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }

    /// Value of axis `i` at sample `k` of one of the per-axis series.
    pub fn at(series: &[f64], axes: usize, k: usize, i: usize) -> f64 {
        series[k * axes + i]
    }

    /// Appends one tick.
    pub fn push(&mut self, r: &TickRecord<'_>) {
        let s = r.sensors;
        self.time.push(r.time);
        self.commanded.extend_from_slice(&r.setpoint.position);
        self.commanded_velocity
            .extend_from_slice(&r.setpoint.velocity);
        self.actual.extend_from_slice(&s.position);
        self.actual_velocity.extend_from_slice(&s.velocity);
        self.drive.extend_from_slice(&s.drive_position);
        self.command.extend_from_slice(r.command);
        self.torque.extend_from_slice(&r.hold.mean_torque);
        self.voltage.extend_from_slice(&r.hold.voltage);
        self.current.extend_from_slice(&s.current);
        self.tool_point.push(s.tool_point);
        self.tool_velocity.push(s.tool_velocity);
        self.segment.push(r.setpoint.segment);
        self.cut.push(r.hold.cut);
    }
}

/// Keeps every tick of every lane as a [`Trace`], and each lane's stop.
#[derive(Debug, Clone, Default)]
pub struct TraceRecorder {
    /// Each lane's trace, in lane order.
    pub traces: Vec<Trace>,
    /// Why each lane stopped early; `None` while it runs or when it ran to the end.
    pub stops: Vec<Option<Stop>>,
    period: f64,
    axes: usize,
}

impl TraceRecorder {
    /// A recorder of `lanes` empty traces of `axes` axes at the servo period `period` (s)
    /// (lanes beyond these are added as they tick).
    pub fn new(period: f64, axes: usize, lanes: usize) -> TraceRecorder {
        TraceRecorder {
            traces: vec![Trace::new(period, axes); lanes],
            stops: vec![None; lanes],
            period,
            axes,
        }
    }

    /// The trace of lane `lane` (empty if the lane never ticked).
    pub fn lane(&self, lane: usize) -> &Trace {
        &self.traces[lane]
    }

    /// Moves the traces out, lane by lane.
    pub fn into_traces(self) -> Vec<Trace> {
        self.traces
    }

    fn ensure(&mut self, lane: usize) {
        while self.traces.len() <= lane {
            self.traces.push(Trace::new(self.period, self.axes));
            self.stops.push(None);
        }
    }
}

impl Observer for TraceRecorder {
    fn tick(&mut self, lane: usize, record: &TickRecord<'_>) {
        self.ensure(lane);
        self.traces[lane].push(record);
    }

    fn stopped(&mut self, lane: usize, stop: &Stop) {
        self.ensure(lane);
        self.stops[lane] = Some(stop.clone());
    }
}
