//! Accuracy and cost figures of a run, accumulated tick by tick as the loop runs (memory does
//! not grow with the run's length).

use super::path::PathSample;
use super::AxisLabel;
use crate::sim::{Outcome, TickRecord};
use serde::Serialize;
use std::collections::BTreeMap;

/// The figures of one axis, in display units: errors in mm on a linear axis and in degrees on
/// a rotary one (only the fields of the axis's kind are set).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisMetrics {
    /// Linear axes: mm; rotary axes: the `_deg` fields instead.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_following_error_mm: Option<f64>,
    /// RMS following error over the program's ticks (mm; linear axes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_following_error_mm: Option<f64>,
    /// Largest |setpoint − position| (deg; rotary axes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_following_error_deg: Option<f64>,
    /// RMS following error over the program's ticks (deg; rotary axes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_following_error_deg: Option<f64>,
    /// Time of the largest following error (s).
    pub max_following_error_time_s: f64,
    /// Where in the motion the largest following error came: `start` (before the axis first
    /// caught up with its command), `reversal` (its command slowed through zero and came back
    /// the other way, until the axis caught up again), `stop` (its command slowed and came
    /// back the same way, or stayed stopped), or `moving`.
    pub max_following_error_at: &'static str,
    /// Largest difference between the physics and the analytic reference model (when run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_physics_vs_analytic_mm: Option<f64>,
    /// Largest position difference between the physics and the analytic reference model
    /// (deg; rotary axes, when the model runs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_physics_vs_analytic_deg: Option<f64>,
    /// Largest |mean motor torque| over a servo period (N·m).
    pub peak_torque_nm: f64,
    /// RMS of the mean motor torque over the program's ticks (N·m).
    pub rms_torque_nm: f64,
    /// Largest |armature voltage| (V); only with the DC-motor actuator.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_voltage_v: Option<f64>,
    /// Stick-slip: how often the axis stalled again after it had got going, while its setpoint
    /// kept moving (see `stick_slip_stalls`).
    pub stick_slip_stalls: usize,
}

/// Longest catch-up after a start from rest that the path-speed error leaves out (s): a
/// machine that has not reached its commanded speed by then is slow, not starting.
pub const CATCH_UP_WINDOW_S: f64 = 0.5;

/// Below this fraction of the axis's peak commanded speed the setpoint is slowing through a
/// reversal (or starting, or stopping): whatever the axis does there is not stick-slip.
const STALL_COMMAND_FLOOR: f64 = 0.2;
/// The axis is moving above this fraction of its peak commanded speed ...
const STALL_MOVING: f64 = 0.2;
/// ... and has stalled below this one.
const STALL_STOPPED: f64 = 0.02;

/// Counts stick-slip stalls of one axis: how often it stalled (below 2 % of its peak
/// commanded speed) after it had got going (above 20 %), while its commanded speed stayed above
/// 20 % of that peak. An axis that stands at a reversal while the drive takes up the backlash,
/// or at the start while friction holds it, is not counted: there the command itself is slow.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StallCounter {
    /// Peak commanded speed of the axis over the whole program.
    peak: f64,
    moving: bool,
    /// Stalls counted so far.
    pub stalls: usize,
}

impl StallCounter {
    /// A counter for an axis whose peak commanded speed over the program is
    /// `peak_commanded_speed` (m/s, or rad/s; its sign is ignored).
    pub fn new(peak_commanded_speed: f64) -> StallCounter {
        StallCounter {
            peak: peak_commanded_speed.abs(),
            ..Default::default()
        }
    }

    /// Adds a tick; true when the axis stalls on it.
    pub fn observe(&mut self, commanded_velocity: f64, actual_velocity: f64) -> bool {
        if self.peak <= 0.0 {
            return false;
        }
        let actual = actual_velocity.abs();
        if commanded_velocity.abs() <= STALL_COMMAND_FLOOR * self.peak {
            self.moving = false;
        } else if actual > STALL_MOVING * self.peak {
            self.moving = true;
        } else if self.moving && actual < STALL_STOPPED * self.peak {
            self.stalls += 1;
            self.moving = false;
            return true;
        }
        false
    }
}

/// The figures of a run, in display units (mm, deg, s, N·m, V): what `metrics.json` holds
/// (see [`Metrics::to_json`]) and `[expect]` bounds refer to. Lane 0 (the physics) gives every
/// figure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    /// The scenario's name.
    pub scenario: String,
    /// True when the run reached the end of its setpoints.
    pub completed: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    /// Why the run stopped early (the stop's message); `None` when it completed.
    pub stopped: Option<String>,
    /// Largest contour error: the tool point's distance from the programmed path (mm).
    pub max_contour_error_mm: f64,
    /// RMS contour error over the program's ticks (mm).
    pub rms_contour_error_mm: f64,
    /// Largest |commanded − actual| path speed of the moving machine: left out are the ticks
    /// at which the command steps between rest and motion (there the difference is the step,
    /// not the machine) and, after a start from rest, the catch-up until the actual speed
    /// first reaches the commanded one (at most `CATCH_UP_WINDOW_S`), which
    /// `path_speed_catch_up_s` reports instead.
    pub max_path_speed_error_mm_s: f64,
    /// Longest time the actual path speed took to reach the commanded one after the command
    /// stepped from rest to motion (the window's length where it never did).
    pub path_speed_catch_up_s: f64,
    /// Simulated program time: servo ticks × servo period (s).
    pub sim_time_s: f64,
    /// Wall-clock time the loop took (s).
    pub wall_time_s: f64,
    /// Simulated over wall-clock time (infinite when the wall time is zero).
    pub real_time_factor: f64,
    /// Integration steps the first lane's plant took (physics steps for Rapier).
    pub physics_steps: u64,
    /// Program ticks observed on the first lane.
    pub servo_ticks: usize,
    /// Each axis's figures, by axis name.
    pub axes: BTreeMap<String, AxisMetrics>,
    /// The cutting process's figures, where the run cuts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cutting: Option<CuttingMetrics>,
    /// The part as cut against the nominal part, where the run cuts (set after the run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub part: Option<PartMetrics>,
    /// Largest distance of the commanded tool point (where the setpoints put the tool) from
    /// the programmed path: the planner's corner rounding at the tool (mm).
    pub max_commanded_contour_error_mm: f64,
    /// Where the figures contradict each other: a contour error larger than the following
    /// errors at the tool and the planner's rounding can explain, or setpoints further from
    /// the programmed path than its corners allow. Absent when the figures agree.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inconsistent_figures: Option<Inconsistency>,
}

/// Figures of a run that cannot all be true, with the likeliest reason.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Inconsistency {
    /// Program time of the first tick that showed it (s).
    pub first_time_s: f64,
    /// Program time of the tick that showed it most (s).
    pub worst_time_s: f64,
    /// What was measured there (mm): the contour error, or the commanded tool point's
    /// distance from the path.
    pub measured_mm: f64,
    /// What explains at most (mm): the tool's following error plus the planner's rounding,
    /// or the corners' tolerance.
    pub explained_mm: f64,
    /// Ticks that showed it.
    pub ticks: usize,
    /// The likeliest reason, in words.
    pub likely_cause: String,
}

/// A contour error is explained up to this much more (m) than the following errors and the
/// rounding add up to: the first-order lever arms and the Rapier solver's joint tolerance.
const EXPLAINED_SLACK_M: f64 = 1e-6;
/// And this share of what they add up to (the same, growing with the figures).
const EXPLAINED_SLACK_SHARE: f64 = 0.05;

/// Why a contour error exceeds what explains it.
const TOOL_NOT_WHERE_AXES_PUT_IT: &str = "the simulated tool point is not where the axes' positions put it through the machine's kinematics: a joint the axes do not drive moves the tool (a passive or compliant joint), or the tool link or tool point is not the one the figures assume";
/// Why setpoints stray from the programmed path beyond the corners' tolerance.
const PATH_NOT_IN_TOOL_COORDINATES: &str = "the setpoints put the tool further from the programmed path than the program's corner tolerance allows: the programmed path and the tool point are not in the same coordinates (rotary axes that carry the tool, a tool point off the spindle axis, or kinematics the program does not assume)";

/// The first, the worst and the count of ticks where a figure exceeded what explains it.
#[derive(Debug, Clone, Copy, Default)]
struct Exceedance {
    first_time: Option<f64>,
    worst: (f64, f64, f64),
    ticks: usize,
}

impl Exceedance {
    /// Counts a tick at `time` where `measured` exceeds `explained` beyond the slack.
    fn observe(&mut self, time: f64, measured: f64, explained: f64) {
        let limit = explained * (1.0 + EXPLAINED_SLACK_SHARE) + EXPLAINED_SLACK_M;
        // A tick without a figure (no path point near) shows nothing either way.
        if measured.is_nan() || limit.is_nan() || measured <= limit {
            return;
        }
        self.first_time.get_or_insert(time);
        self.ticks += 1;
        if measured - explained > self.worst.1 - self.worst.2 {
            self.worst = (time, measured, explained);
        }
    }

    fn report(&self, cause: &str) -> Option<Inconsistency> {
        Some(Inconsistency {
            first_time_s: self.first_time?,
            worst_time_s: self.worst.0,
            measured_mm: self.worst.1 * 1e3,
            explained_mm: self.worst.2 * 1e3,
            ticks: self.ticks,
            likely_cause: cause.to_string(),
        })
    }
}

/// The cutting process's figures over the run (the physics lane's).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct CuttingMetrics {
    /// Largest |force| of the tool on the part within any physics step (N).
    pub max_force_n: f64,
    /// Largest spindle power, mean over a servo period (W).
    pub max_spindle_power_w: f64,
    /// Largest spindle torque, mean over a servo period (N·m).
    pub max_spindle_torque_nm: f64,
    /// Program time during which the tool engaged the stock (s).
    pub engaged_time_s: f64,
}

/// The part as cut, compared with the nominal part (the same stock cut by the programmed
/// path without dynamics).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct PartMetrics {
    /// Largest normal distance of the machined from the nominal surface (mm).
    pub max_surface_error_mm: f64,
    /// RMS of that distance over the machined surface (mm).
    pub rms_surface_error_mm: f64,
    /// Largest material left standing (undercut), ≥ 0 (mm).
    pub max_undercut_mm: f64,
    /// Largest material cut away that should stand (overcut), ≥ 0 (mm).
    pub max_overcut_mm: f64,
    /// Volume the tool removed (mm³).
    pub removed_volume_mm3: f64,
    /// Volume the programmed path removes (mm³).
    pub nominal_removed_volume_mm3: f64,
}

impl Metrics {
    /// The metrics as JSON (what `metrics.json` holds and `[expect]` bounds refer to).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("metrics are plain numbers and strings")
    }

    /// Looks up a metric by its dotted path, e.g. `axes.x.max_following_error_mm`.
    pub fn lookup(json: &serde_json::Value, path: &str) -> Option<f64> {
        path.split('.')
            .try_fold(json, |v, key| v.get(key))?
            .as_f64()
    }
}

/// Where an axis is in its motion, for placing its largest error (see
/// [`AxisMetrics::max_following_error_at`]). Thresholds are shares of the axis's peak commanded
/// speed: the command is slow below 20 %; the axis has caught up when its speed is within 10 %
/// of the command's while the command is not slow.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
enum Phase {
    #[default]
    Start,
    /// The command slowed down while moving in direction `before` (±1; 0 = not yet moving).
    Slow {
        before: f64,
    },
    /// The command is back to speed after a slow phase, the axis not yet caught up; `label` is
    /// what that slow phase was.
    CatchingUp {
        label: &'static str,
    },
    Moving,
}

const SLOW: f64 = 0.2;
const CAUGHT_UP: f64 = 0.1;

/// Follows an axis through its phases; says which phase a time belongs to.
#[derive(Debug, Clone, Copy, Default)]
struct PhaseTracker {
    peak: f64,
    phase: Phase,
    direction: f64,
    /// Serial number of the current phase, and the label the largest error's phase got once
    /// it was known.
    serial: u32,
}

impl PhaseTracker {
    /// Moves on by one tick; returns a label for the phase just left, if a slow phase now
    /// knows whether it was a reversal or a stop.
    fn observe(&mut self, commanded: f64, actual: f64) -> Option<(u32, &'static str)> {
        if self.peak <= 0.0 {
            return None;
        }
        let slow = commanded.abs() < SLOW * self.peak;
        let caught_up = !slow && (actual - commanded).abs() <= CAUGHT_UP * self.peak;
        let sign = if slow { 0.0 } else { commanded.signum() };
        let (next, resolved) = match self.phase {
            Phase::Start if caught_up => (Phase::Moving, Some("start")),
            Phase::Start => (Phase::Start, None),
            Phase::Moving if slow => (
                Phase::Slow {
                    before: self.direction,
                },
                Some("moving"),
            ),
            Phase::Moving => (Phase::Moving, None),
            Phase::Slow { before } if !slow => {
                let label = if before != 0.0 && sign != before {
                    "reversal"
                } else {
                    "stop"
                };
                (Phase::CatchingUp { label }, Some(label))
            }
            Phase::Slow { .. } => (self.phase, None),
            Phase::CatchingUp { label } if caught_up => (Phase::Moving, Some(label)),
            Phase::CatchingUp { label } if slow => (
                Phase::Slow {
                    before: self.direction,
                },
                Some(label),
            ),
            Phase::CatchingUp { .. } => (self.phase, None),
        };
        if sign != 0.0 {
            self.direction = sign;
        }
        let changed = std::mem::discriminant(&next) != std::mem::discriminant(&self.phase);
        let done = resolved.filter(|_| changed).map(|l| (self.serial, l));
        if changed {
            self.serial += 1;
        }
        self.phase = next;
        done
    }

    /// The label of the current phase as far as it is known at the end of the run.
    fn final_label(&self) -> &'static str {
        match self.phase {
            Phase::Start => "start",
            Phase::Slow { .. } => "stop",
            Phase::CatchingUp { label } => label,
            Phase::Moving => "moving",
        }
    }
}

/// Running figures of one axis.
#[derive(Debug, Clone, Copy, Default)]
struct AxisSums {
    max_error: f64,
    max_error_time: f64,
    /// The phase the largest error came in: its serial, and its label once known.
    max_error_phase: u32,
    max_error_at: Option<&'static str>,
    phases: PhaseTracker,
    sum_error2: f64,
    peak_torque: f64,
    sum_torque2: f64,
    peak_voltage: f64,
    stalls: StallCounter,
    /// Largest |physics − analytic| position (when the analytic lane runs).
    max_vs_analytic: Option<f64>,
}

/// Largest of `m` and `x`, NaN once any value was NaN (a NaN must show, not vanish in a max).
fn nan_max(m: f64, x: f64) -> f64 {
    if x.is_nan() || m.is_nan() {
        f64::NAN
    } else {
        m.max(x)
    }
}

/// The metrics of a run, tick by tick: lane 0 (the physics) gives every figure; a second lane
/// (the analytic reference model) is compared with it position by position.
#[derive(Debug, Clone)]
pub struct MetricsAccumulator {
    labels: Vec<AxisLabel>,
    dc_motor: bool,
    period: f64,
    axes: Vec<AxisSums>,
    ticks: usize,
    max_contour: f64,
    sum_contour2: f64,
    max_speed_error: f64,
    /// The commanded path speed of the previous tick (0: at rest before the first).
    commanded_speed_before: f64,
    /// Time of the last step from rest to motion, while the actual speed has not caught up.
    catching_up_since: Option<f64>,
    longest_catch_up: f64,
    /// Lane 0's positions at tick `primary_tick`, for the comparison with lane 1.
    primary: Vec<f64>,
    primary_tick: Option<usize>,
    /// The cutting figures so far, where the run cuts.
    cutting: Option<CuttingMetrics>,
    max_commanded_deviation: f64,
    /// Contour errors beyond the following errors at the tool and the rounding.
    unexplained_contour: Exceedance,
    /// Setpoints further from the path than the corners allow.
    setpoints_off_path: Exceedance,
}

impl MetricsAccumulator {
    /// Accumulates the cutting figures too (a run that cuts).
    pub fn with_cutting(mut self) -> MetricsAccumulator {
        self.cutting = Some(CuttingMetrics::default());
        self
    }

    /// `peak_velocity`: the largest |commanded velocity| of each axis over the program (for
    /// the stick-slip count); `compare_analytic`: whether a second lane will be compared.
    pub fn new(
        labels: &[AxisLabel],
        dc_motor: bool,
        period: f64,
        peak_velocity: &[f64],
        compare_analytic: bool,
    ) -> MetricsAccumulator {
        MetricsAccumulator {
            labels: labels.to_vec(),
            dc_motor,
            period,
            axes: peak_velocity
                .iter()
                .map(|&peak| AxisSums {
                    stalls: StallCounter::new(peak),
                    phases: PhaseTracker {
                        peak: peak.abs(),
                        ..Default::default()
                    },
                    max_vs_analytic: compare_analytic.then_some(0.0),
                    ..Default::default()
                })
                .collect(),
            ticks: 0,
            max_contour: 0.0,
            sum_contour2: 0.0,
            max_speed_error: 0.0,
            commanded_speed_before: 0.0,
            catching_up_since: None,
            longest_catch_up: 0.0,
            primary: vec![0.0; labels.len()],
            primary_tick: None,
            cutting: None,
            max_commanded_deviation: 0.0,
            unexplained_contour: Exceedance::default(),
            setpoints_off_path: Exceedance::default(),
        }
    }

    /// Adds a tick of lane `lane` with its path figures; returns a bit per axis that stalled
    /// (stick-slip) on this tick.
    pub fn observe(&mut self, lane: usize, r: &TickRecord<'_>, path: &PathSample) -> u64 {
        let s = r.sensors;
        if lane != 0 {
            if self.primary_tick == Some(r.k) {
                for (a, (p, q)) in self
                    .axes
                    .iter_mut()
                    .zip(self.primary.iter().zip(&s.position))
                {
                    if let Some(m) = &mut a.max_vs_analytic {
                        *m = nan_max(*m, (p - q).abs());
                    }
                }
            }
            return 0;
        }
        let mut stalled = 0;
        self.ticks += 1;
        self.primary.copy_from_slice(&s.position);
        self.primary_tick = Some(r.k);
        let sp = r.setpoint;
        for (i, a) in self.axes.iter_mut().enumerate() {
            if let Some((serial, label)) = a.phases.observe(sp.velocity[i], s.velocity[i]) {
                if serial == a.max_error_phase && a.max_error_at.is_none() {
                    a.max_error_at = Some(label);
                }
            }
            let error = (sp.position[i] - s.position[i]).abs();
            if error > a.max_error || error.is_nan() {
                a.max_error = error;
                a.max_error_time = r.time;
                a.max_error_phase = a.phases.serial;
                a.max_error_at = None;
            }
            a.sum_error2 += error * error;
            let torque = r.hold.mean_torque[i];
            a.peak_torque = nan_max(a.peak_torque, torque.abs());
            a.sum_torque2 += torque * torque;
            a.peak_voltage = nan_max(a.peak_voltage, r.hold.voltage[i].abs());
            if a.stalls.observe(sp.velocity[i], s.velocity[i]) && i < 64 {
                stalled |= 1 << i;
            }
        }
        if let Some(c) = &mut self.cutting {
            let cut = &r.hold.cut;
            c.max_force_n = nan_max(c.max_force_n, cut.peak_force);
            c.max_spindle_power_w = nan_max(c.max_spindle_power_w, cut.spindle_power);
            c.max_spindle_torque_nm = nan_max(c.max_spindle_torque_nm, cut.spindle_torque);
            if cut.engaged_flutes > 0 {
                c.engaged_time_s += self.period;
            }
        }
        self.max_contour = nan_max(self.max_contour, path.contour_error);
        self.sum_contour2 += path.contour_error * path.contour_error;
        // The figures must agree: the tool's distance from the path is at most the commanded
        // point's plus how far the following errors move the tool; the commanded point's at
        // most what the corners allow.
        self.max_commanded_deviation =
            nan_max(self.max_commanded_deviation, path.commanded_deviation);
        self.unexplained_contour.observe(
            r.time,
            path.contour_error,
            path.commanded_deviation + path.tool_following_error,
        );
        if let Some(tolerance) = path.corner_tolerance {
            self.setpoints_off_path
                .observe(r.time, path.commanded_deviation, tolerance);
        }
        // A tick at which the command steps between rest and motion (the stream's first sample
        // at feed, its last at rest, an exact stop) compares a command that starts now with a
        // speed measured before it could act: that difference is the step itself, whatever
        // the machine does, so it is not counted. After a start from rest the machine needs
        // a while to reach the commanded speed; that catch-up is reported as its duration,
        // and the speed error counts from the moment the machine first reaches the command.
        // "At rest" allows for rounding in the stream's samples (1 nm/s).
        const AT_REST: f64 = 1e-9;
        let moving = path.commanded_speed > AT_REST;
        let was_moving = self.commanded_speed_before > AT_REST;
        let t = r.k as f64 * self.period;
        if moving && !was_moving {
            self.catching_up_since = Some(t);
        }
        if let Some(since) = self.catching_up_since {
            let caught_up = path.actual_speed >= path.commanded_speed;
            if caught_up || !moving || t - since >= CATCH_UP_WINDOW_S {
                self.longest_catch_up = self.longest_catch_up.max(t - since);
                self.catching_up_since = None;
            }
        }
        if moving == was_moving && self.catching_up_since.is_none() {
            self.max_speed_error = nan_max(
                self.max_speed_error,
                (path.commanded_speed - path.actual_speed).abs(),
            );
        }
        self.commanded_speed_before = path.commanded_speed;
        stalled
    }

    /// Per axis: the time and size of the largest following error so far (joint units).
    pub fn largest_errors(&self) -> Vec<(f64, f64)> {
        self.axes
            .iter()
            .map(|a| (a.max_error_time, a.max_error))
            .collect()
    }

    /// The figures of the run, in display units.
    pub fn finish(&self, scenario: &str, outcome: &Outcome) -> Metrics {
        let n = self.ticks;
        let rms = |sum: f64| if n == 0 { 0.0 } else { (sum / n as f64).sqrt() };
        let mut axes = BTreeMap::new();
        for (label, a) in self.labels.iter().zip(&self.axes) {
            let s = label.scale();
            let (worst, rms_error) = (a.max_error * s, rms(a.sum_error2) * s);
            let (mm, deg) = if label.rotary {
                (None, Some((worst, rms_error)))
            } else {
                (Some((worst, rms_error)), None)
            };
            let vs = a.max_vs_analytic.map(|m| m * s);
            axes.insert(
                label.name.clone(),
                AxisMetrics {
                    max_following_error_mm: mm.map(|v| v.0),
                    rms_following_error_mm: mm.map(|v| v.1),
                    max_following_error_deg: deg.map(|v| v.0),
                    rms_following_error_deg: deg.map(|v| v.1),
                    max_following_error_time_s: a.max_error_time,
                    max_following_error_at: a.max_error_at.unwrap_or_else(|| {
                        if a.max_error_phase == a.phases.serial {
                            a.phases.final_label()
                        } else {
                            "moving"
                        }
                    }),
                    max_physics_vs_analytic_mm: vs.filter(|_| !label.rotary),
                    max_physics_vs_analytic_deg: vs.filter(|_| label.rotary),
                    peak_torque_nm: a.peak_torque,
                    rms_torque_nm: rms(a.sum_torque2),
                    peak_voltage_v: self.dc_motor.then_some(a.peak_voltage),
                    stick_slip_stalls: a.stalls.stalls,
                },
            );
        }
        let sim_time = n as f64 * self.period;
        // A catch-up still under way when the run ended.
        let catch_up = self
            .catching_up_since
            .map_or(self.longest_catch_up, |since| {
                self.longest_catch_up.max(sim_time - since)
            });
        let wall_time = outcome.wall_time;
        let stopped = outcome.stop().map(|s| s.to_string());
        Metrics {
            scenario: scenario.to_string(),
            completed: stopped.is_none(),
            stopped,
            max_contour_error_mm: self.max_contour * 1e3,
            rms_contour_error_mm: rms(self.sum_contour2) * 1e3,
            max_path_speed_error_mm_s: self.max_speed_error * 1e3,
            path_speed_catch_up_s: catch_up,
            sim_time_s: sim_time,
            wall_time_s: wall_time,
            real_time_factor: if wall_time > 0.0 {
                sim_time / wall_time
            } else {
                f64::INFINITY
            },
            physics_steps: outcome.lanes.first().map_or(0, |l| l.steps),
            servo_ticks: n,
            axes,
            cutting: self.cutting,
            part: None,
            max_commanded_contour_error_mm: self.max_commanded_deviation * 1e3,
            inconsistent_figures: self
                .setpoints_off_path
                .report(PATH_NOT_IN_TOOL_COORDINATES)
                .or_else(|| self.unexplained_contour.report(TOOL_NOT_WHERE_AXES_PUT_IT)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stalls counted on commanded and actual velocity series (peak from the commands).
    fn stalls(commanded: &[f64], actual: &[f64]) -> usize {
        let peak = commanded.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mut counter = StallCounter::new(peak);
        for (c, a) in commanded.iter().zip(actual) {
            counter.observe(*c, *a);
        }
        counter.stalls
    }

    #[test]
    fn stalls_while_the_command_moves_are_counted() {
        let commanded = vec![5e-3; 60];
        let mut actual = vec![5e-3; 60];
        // Held at the start (not counted: it never got going), then stuck twice on the way.
        for k in (0..10).chain(20..25).chain(40..42) {
            actual[k] = 0.0;
        }
        assert_eq!(stalls(&commanded, &actual), 2);
    }

    #[test]
    fn standing_at_a_reversal_is_not_a_stall() {
        // Command through zero as on a circle; the axis stands still on both sides of the
        // reversal while the backlash is taken up, until the command is back above 25 % speed.
        let commanded: Vec<f64> = (0..200)
            .map(|k| 5e-3 * (std::f64::consts::PI * k as f64 / 100.0).cos())
            .collect();
        let actual: Vec<f64> = commanded
            .iter()
            .enumerate()
            .map(|(k, &v)| if (45..60).contains(&k) { 0.0 } else { v })
            .collect();
        assert!(commanded[59].abs() > 0.25 * 5e-3);
        assert_eq!(stalls(&commanded, &actual), 0);
    }

    /// Where the largest error of a velocity series came: errors peak where `error` says.
    fn place(commanded: &[f64], actual: &[f64], peak_at: usize) -> &'static str {
        let peak = commanded.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mut a = AxisSums {
            phases: PhaseTracker {
                peak,
                ..Default::default()
            },
            ..Default::default()
        };
        for (k, (c, v)) in commanded.iter().zip(actual).enumerate() {
            if let Some((serial, label)) = a.phases.observe(*c, *v) {
                if serial == a.max_error_phase && a.max_error_at.is_none() {
                    a.max_error_at = Some(label);
                }
            }
            if k == peak_at {
                a.max_error_phase = a.phases.serial;
                a.max_error_at = None;
            }
        }
        a.max_error_at
            .unwrap_or(if a.max_error_phase == a.phases.serial {
                a.phases.final_label()
            } else {
                "moving"
            })
    }

    #[test]
    fn largest_errors_are_placed_at_start_reversal_stop_or_moving() {
        // Forward at 1, through zero, backward at 1; the axis lags 5 ticks behind each change.
        let mut commanded = vec![1.0; 20];
        commanded.extend((0..10).map(|k| 1.0 - 0.2 * k as f64));
        commanded.extend(vec![-1.0; 30]);
        let mut actual = vec![0.0; 5];
        actual.extend(commanded[..commanded.len() - 5].iter().copied());
        assert_eq!(place(&commanded, &actual, 2), "start");
        assert_eq!(place(&commanded, &actual, 12), "moving");
        assert_eq!(place(&commanded, &actual, 27), "reversal");
        assert_eq!(place(&commanded, &actual, 33), "reversal");
        assert_eq!(place(&commanded, &actual, 55), "moving");
        // A command that slows and goes on the same way: a stop.
        let mut same: Vec<f64> = vec![1.0; 20];
        same.extend(vec![0.0; 10]);
        same.extend(vec![1.0; 20]);
        assert_eq!(place(&same, &same, 25), "stop");
    }

    #[test]
    fn an_axis_that_never_moves_has_no_stalls() {
        assert_eq!(stalls(&[0.0; 10], &[0.0; 10]), 0);
        assert_eq!(stalls(&[], &[]), 0);
    }
}
