//! The ISO 230-4 circular test read as a ballbar tool reads it: a trace of the tool on a
//! circle, clockwise and counter-clockwise, in; the standard's figures (circular deviation G,
//! circular hysteresis H, radial deviation F) and a ballbar diagnosis (reversal spikes,
//! backlash, servo mismatch, stick-slip, vibration) out, as plain data that prints itself,
//! writes itself as JSON, draws its polar plot (PNG) and logs it to a Rerun recording.
//!
//! Angles are in the plane's own axis order (XY: from +X towards +Y; ZX: from +Z towards +X;
//! YZ: from +Y towards +Z), counter-clockwise positive, as G2/G3 read them. SI inside; µm, mm,
//! degrees and mm/min in what is written. `docs/ballbar.md` derives every figure.

use super::plot::{render, DrawResult, FAMILY};
use super::{ReportError, PLOT_SIZE};
use serde::Serialize;
use std::collections::BTreeMap;
use std::f64::consts::{PI, TAU};
use std::path::{Path, PathBuf};

/// Where the step of a backlash is read on either side of a reversal (degrees from it): the
/// transition, while the drive crosses the gap, is left out. A gap B is crossed within
/// acos(1 − B/R) of the reversal, so 15° covers backlash up to 3.4 % of the radius.
const BACKLASH_WINDOW_DEG: (f64, f64) = (15.0, 40.0);
/// Where a reversal spike is looked for (degrees after the reversal), and the levels it stands
/// out from: the trace before the reversal and after the spike window.
const SPIKE_WINDOW_DEG: f64 = 20.0;
const SPIKE_BEFORE_DEG: (f64, f64) = (-40.0, -3.0);
const SPIKE_AFTER_DEG: (f64, f64) = (20.0, 40.0);
/// Below this (m) a spike, an ellipse or a vibration is not resolved: round-off and the
/// trace's own numerical noise on a machine that follows its circle to the nanometre.
const RESOLUTION: f64 = 1e-9;
/// Angular resolution of the hysteresis comparison of the two directions (degrees).
const HYSTERESIS_STEP_DEG: f64 = 0.1;
/// A vibration is looked for above this multiple of the revolution frequency (below it are the
/// shape harmonics: centre offset, ellipse, reversal steps).
const VIBRATION_MIN_HARMONIC: f64 = 10.0;

/// One direction's trace over the 360° of data.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BallbarPass {
    /// Whether the pass runs clockwise (G2).
    pub clockwise: bool,
    /// Run time of each sample (s).
    pub time: Vec<f64>,
    /// The actual tool point in the plane's axes (m).
    pub point: Vec<[f64; 2]>,
}

/// What a ballbar analysis needs: the nominal circle and both traces.
#[derive(Debug, Clone, PartialEq)]
pub struct BallbarInput {
    /// The scenario's name.
    pub scenario: String,
    /// Program letters of the plane's axes, in its order (e.g. ["x", "y"], ["z", "x"]).
    pub axes: [String; 2],
    /// Plane name as given (xy, yz, zx).
    pub plane: String,
    /// Programmed centre in the plane's axes (m) and its full program coordinates (m).
    pub centre: [f64; 2],
    /// Programmed centre in full program coordinates (m).
    pub centre_3d: [f64; 3],
    /// Nominal radius (m).
    pub radius: f64,
    /// Path speed (m/s).
    pub feed: f64,
    /// Servo period of the trace (s).
    pub period: f64,
    /// The counter-clockwise pass.
    pub ccw: BallbarPass,
    /// The clockwise pass.
    pub cw: BallbarPass,
    /// Stick-slip stalls of each plane axis over the test (from the run's metrics).
    pub stalls: BTreeMap<String, usize>,
    /// Whether the run reached its end.
    pub completed: bool,
}

/// The ISO 230-4 figures of one direction.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DirectionFigures {
    /// G: radial width of the zone between two concentric circles enclosing the path, about
    /// the least-squares circle's centre (µm).
    pub circular_deviation_um: f64,
    /// The same about the minimum-zone centre, the smallest possible width (µm).
    pub circular_deviation_min_zone_um: f64,
    /// F: largest and smallest radial deviation from the nominal circle about the programmed
    /// centre (µm; F_max outward positive, F_min inward negative).
    pub radial_deviation_max_um: f64,
    /// F_min: the smallest radial deviation (µm, inward negative).
    pub radial_deviation_min_um: f64,
    /// Least-squares circle: centre offset from the programmed centre (µm, plane axes) and
    /// radius (mm).
    pub least_squares_centre_offset_um: [f64; 2],
    /// Radius of the least-squares circle (mm).
    pub least_squares_radius_mm: f64,
    /// Minimum-zone centre offset from the programmed centre (µm, plane axes).
    pub min_zone_centre_offset_um: [f64; 2],
    /// Number of traced samples the figures are computed from.
    pub samples: usize,
}

/// A spike of the radial deviation just after an axis reverses.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReversalSpike {
    /// The axis that reverses.
    pub axis: String,
    /// "cw" or "ccw".
    pub direction: &'static str,
    /// Where the axis reverses (degrees).
    pub angle_deg: f64,
    /// Peak of the radial deviation over the level around it (µm; outward positive).
    pub height_um: f64,
    /// Angular width where it is above half its height (degrees).
    pub width_deg: f64,
}

/// The 45° ellipse that different loop lags on the two axes draw (flipping with direction).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ServoMismatch {
    /// Peak-to-peak radial deviation of the ellipse (µm).
    pub ellipse_um: f64,
    /// Lag of the first plane axis minus that of the second (ms): τ₁ − τ₂ = 2m/v.
    pub lag_difference_ms: f64,
    /// The axis with the larger lag.
    pub lagging_axis: String,
}

impl ServoMismatch {
    fn lag_text(&self) -> String {
        if self.lagging_axis == "none" {
            "no axis lags".into()
        } else {
            format!(
                "{} lags by {:.3} ms",
                self.lagging_axis.to_uppercase(),
                self.lag_difference_ms.abs()
            )
        }
    }
}

/// The strongest periodic component of the radial deviation above the shape harmonics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Vibration {
    /// Frequency of that component (Hz).
    pub frequency_hz: f64,
    /// Amplitude of that component (µm).
    pub amplitude_um: f64,
}

/// One test: a feed and a radius, both directions, the figures and the diagnosis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BallbarRun {
    /// The scenario's name.
    pub scenario: String,
    /// Plane of the test as given (xy, yz, zx).
    pub plane: String,
    /// Programmed feed (mm/min).
    pub feed_mm_min: f64,
    /// Nominal radius (mm).
    pub radius_mm: f64,
    /// Programmed centre in full program coordinates (mm).
    pub centre_mm: [f64; 3],
    /// Whether the run reached its end.
    pub completed: bool,
    /// ISO 230-4 figures of the clockwise pass.
    pub cw: DirectionFigures,
    /// ISO 230-4 figures of the counter-clockwise pass.
    pub ccw: DirectionFigures,
    /// H: largest radial difference between the two directions at the same angle, both about
    /// the least-squares centre of the two together (µm).
    pub circular_hysteresis_um: f64,
    /// Lost motion per plane axis: the outward step of the radial deviation across the axis's
    /// reversals, averaged over its four reversals (µm).
    pub backlash_um: BTreeMap<String, f64>,
    /// Largest RMS residual of the step fits per axis (µm): where it is not small against
    /// the backlash, the trace shows no clean lost-motion step (hunting, stick-slip).
    pub backlash_fit_residual_um: BTreeMap<String, f64>,
    /// The spikes found after the axes' reversals, both directions.
    pub reversal_spikes: Vec<ReversalSpike>,
    /// The ellipse of unequal axis lags.
    pub servo_mismatch: ServoMismatch,
    /// Stick-slip stalls per plane axis over the test.
    pub stick_slip_stalls: BTreeMap<String, usize>,
    /// The strongest vibration above the shape harmonics, where one is resolved.
    pub vibration: Option<Vibration>,
    /// Polar plot: magnification of the deviations and the scale of one ring (µm).
    pub magnification: f64,
    /// Polar plot: the deviation one ring stands for (µm).
    pub scale_um_per_division: f64,
    /// Files written for this run (polar plot, trace, the run's own outputs).
    pub files: Vec<PathBuf>,
    /// The scenario's `[expect]` bounds on ballbar figures that this run breaches.
    pub breaches: Vec<String>,
    /// The deviation from the nominal circle by angle, per direction (degrees, µm): the polar
    /// plot's data (also written as CSV).
    #[serde(skip)]
    pub polar: [Vec<(f64, f64)>; 2],
    /// The traced points in the plane's axes (mm) and their times (s), per direction.
    #[serde(skip)]
    pub points: [Vec<[f64; 2]>; 2],
    /// Run time of each traced point (s), per direction (ccw, cw).
    #[serde(skip)]
    pub times: [Vec<f64>; 2],
}

impl BallbarRun {
    /// The dotted metric names a run in the plane of `axes` reports under `ballbar.` (what
    /// `[expect]` bounds may name).
    pub fn metric_names(axes: [&str; 2]) -> Vec<String> {
        let direction = || DirectionFigures {
            circular_deviation_um: 0.0,
            circular_deviation_min_zone_um: 0.0,
            radial_deviation_max_um: 0.0,
            radial_deviation_min_um: 0.0,
            least_squares_centre_offset_um: [0.0; 2],
            least_squares_radius_mm: 0.0,
            min_zone_centre_offset_um: [0.0; 2],
            samples: 0,
        };
        let per_axis = |v: f64| {
            axes.iter()
                .map(|a| (a.to_string(), v))
                .collect::<BTreeMap<_, _>>()
        };
        let template = BallbarRun {
            scenario: String::new(),
            plane: String::new(),
            feed_mm_min: 0.0,
            radius_mm: 0.0,
            centre_mm: [0.0; 3],
            completed: true,
            cw: direction(),
            ccw: direction(),
            circular_hysteresis_um: 0.0,
            backlash_um: per_axis(0.0),
            backlash_fit_residual_um: per_axis(0.0),
            reversal_spikes: Vec::new(),
            servo_mismatch: ServoMismatch {
                ellipse_um: 0.0,
                lag_difference_ms: 0.0,
                lagging_axis: String::new(),
            },
            stick_slip_stalls: BTreeMap::new(),
            vibration: None,
            magnification: 0.0,
            scale_um_per_division: 0.0,
            files: Vec::new(),
            breaches: Vec::new(),
            polar: [Vec::new(), Vec::new()],
            points: [Vec::new(), Vec::new()],
            times: [Vec::new(), Vec::new()],
        };
        let mut names = Vec::new();
        flatten_numbers(&template.metrics_json(), "ballbar", &mut names);
        names
    }

    /// The figures as flat metric keys (what `[expect]`, A/B and sweep tables read), under
    /// `ballbar.`.
    pub fn metrics_json(&self) -> serde_json::Value {
        let direction = |d: &DirectionFigures| {
            serde_json::json!({
                "circular_deviation_um": d.circular_deviation_um,
                "circular_deviation_min_zone_um": d.circular_deviation_min_zone_um,
                "radial_deviation_max_um": d.radial_deviation_max_um,
                "radial_deviation_min_um": d.radial_deviation_min_um,
            })
        };
        let spike_max: BTreeMap<String, f64> = self
            .backlash_um
            .keys()
            .map(|axis| {
                let h = self
                    .reversal_spikes
                    .iter()
                    .filter(|s| &s.axis == axis)
                    .map(|s| s.height_um)
                    .fold(0.0f64, |m, h| if h.abs() > m.abs() { h } else { m });
                (axis.clone(), h)
            })
            .collect();
        serde_json::json!({
            "cw": direction(&self.cw),
            "ccw": direction(&self.ccw),
            "circular_hysteresis_um": self.circular_hysteresis_um,
            "backlash_um": self.backlash_um,
            "reversal_spike_um": spike_max,
            "servo_mismatch_um": self.servo_mismatch.ellipse_um,
            "lag_difference_ms": self.servo_mismatch.lag_difference_ms,
        })
    }
}

/// Runs of one `cncsim ballbar` invocation.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct BallbarReport {
    /// The scenario's name.
    pub scenario: String,
    /// One test per feed and radius, in the order run.
    pub runs: Vec<BallbarRun>,
}

/// Dotted paths of the numbers in `v`, with their values.
fn flatten_numbers(v: &serde_json::Value, prefix: &str, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                flatten_numbers(v, &format!("{prefix}.{k}"), out);
            }
        }
        serde_json::Value::Number(_) | serde_json::Value::Null => out.push(prefix.to_string()),
        _ => {}
    }
}

/// Pairs of the ballbar figures of two runs, by dotted name (for A/B tables).
pub fn ballbar_pairs(a: &BallbarRun, b: &BallbarRun) -> Vec<(String, f64, f64)> {
    let (ja, jb) = (a.metrics_json(), b.metrics_json());
    let mut names = Vec::new();
    flatten_numbers(&ja, "", &mut names);
    names
        .into_iter()
        .filter_map(|n| {
            let get = |j: &serde_json::Value| {
                n.trim_start_matches('.')
                    .split('.')
                    .try_fold(j, |v, k| v.get(k))
                    .and_then(|v| v.as_f64())
            };
            Some((n.trim_start_matches('.').to_string(), get(&ja)?, get(&jb)?))
        })
        .collect()
}

fn um(m: f64) -> f64 {
    m * 1e6
}

/// Angle in [0, 2π).
fn wrap(a: f64) -> f64 {
    a.rem_euclid(TAU)
}

/// Angle in (−π, π].
fn signed(a: f64) -> f64 {
    let w = wrap(a);
    if w > PI {
        w - TAU
    } else {
        w
    }
}

fn radii(points: &[[f64; 2]], c: [f64; 2]) -> impl Iterator<Item = f64> + '_ {
    points.iter().map(move |p| (p[0] - c[0]).hypot(p[1] - c[1]))
}

fn zone(points: &[[f64; 2]], c: [f64; 2]) -> f64 {
    let (lo, hi) = radii(points, c).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
        (lo.min(r), hi.max(r))
    });
    hi - lo
}

/// Geometric least-squares circle (Gauss–Newton on Σ(|p − c| − ρ)², from `start`): centre and
/// radius.
pub fn least_squares_circle(points: &[[f64; 2]], start: [f64; 2]) -> ([f64; 2], f64) {
    let n = points.len().max(1) as f64;
    let mut c = start;
    for _ in 0..50 {
        let rho = radii(points, c).sum::<f64>() / n;
        // With ρ at its optimum for c, the centre's normal equations (2×2).
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut mu, mut mv) = (0.0, 0.0);
        let rows: Vec<(f64, f64, f64)> = points
            .iter()
            .map(|p| {
                let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
                let r = dx.hypot(dy).max(f64::MIN_POSITIVE);
                // ∂r/∂c = −(p − c)/r.
                (-dx / r, -dy / r, r - rho)
            })
            .collect();
        for (u, v, _) in &rows {
            mu += u;
            mv += v;
        }
        mu /= n;
        mv /= n;
        for (u, v, e) in &rows {
            // Jacobian of r − mean(r) in c: centred columns.
            let (u, v) = (u - mu, v - mv);
            a11 += u * u;
            a12 += u * v;
            a22 += v * v;
            b1 += u * e;
            b2 += v * e;
        }
        let det = a11 * a22 - a12 * a12;
        if det.abs() < f64::MIN_POSITIVE {
            break;
        }
        let dx = -(a22 * b1 - a12 * b2) / det;
        let dy = -(a11 * b2 - a12 * b1) / det;
        c = [c[0] + dx, c[1] + dy];
        if dx.hypot(dy) < 1e-15 {
            break;
        }
    }
    let rho = radii(points, c).sum::<f64>() / n;
    (c, rho)
}

/// Golden-section minimum of `f` on [a, b]: where and what.
pub(crate) fn golden(
    mut a: f64,
    mut b: f64,
    iterations: usize,
    f: &mut dyn FnMut(f64) -> f64,
) -> (f64, f64) {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let mut x1 = b - g * (b - a);
    let mut x2 = a + g * (b - a);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..iterations {
        if f1 <= f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - g * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + g * (b - a);
            f2 = f(x2);
        }
    }
    if f1 <= f2 {
        (x1, f1)
    } else {
        (x2, f2)
    }
}

/// Minimum-zone circle: the centre that minimises the radial width of the enclosing annulus,
/// searched (nested golden sections, refined twice) around `start`, within `reach` of it.
/// Near the least-squares centre the width is convex in the centre (it is the max of the
/// radii minus their min, each nearly affine in the centre there).
pub fn minimum_zone_circle(points: &[[f64; 2]], start: [f64; 2], reach: f64) -> ([f64; 2], f64) {
    let mut c = start;
    let mut reach = reach.max(1e-9);
    let mut best = zone(points, c);
    for _ in 0..3 {
        let (cx, cy) = (c[0], c[1]);
        let mut inner_y = 0.0;
        let (x, _) = golden(cx - reach, cx + reach, 48, &mut |x| {
            let (y, w) = golden(cy - reach, cy + reach, 48, &mut |y| zone(points, [x, y]));
            inner_y = y;
            w
        });
        let (y, w) = golden(cy - reach, cy + reach, 48, &mut |y| zone(points, [x, y]));
        if w <= best {
            best = w;
            c = [x, y];
        }
        reach /= 20.0;
    }
    (c, best)
}

fn direction_figures(pass: &BallbarPass, input: &BallbarInput) -> DirectionFigures {
    let (c0, r0) = (input.centre, input.radius);
    let (lsq, rho) = least_squares_circle(&pass.point, c0);
    let g = zone(&pass.point, lsq);
    let (mz, g_mz) = minimum_zone_circle(&pass.point, lsq, g);
    let (lo, hi) = radii(&pass.point, c0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(r - r0), hi.max(r - r0))
        });
    DirectionFigures {
        circular_deviation_um: um(g),
        circular_deviation_min_zone_um: um(g_mz),
        radial_deviation_max_um: um(hi),
        radial_deviation_min_um: um(lo),
        least_squares_centre_offset_um: [um(lsq[0] - c0[0]), um(lsq[1] - c0[1])],
        least_squares_radius_mm: rho * 1e3,
        min_zone_centre_offset_um: [um(mz[0] - c0[0]), um(mz[1] - c0[1])],
        samples: pass.point.len(),
    }
}

/// (angle, radial deviation) of every sample about `c` from radius `r`.
fn polar_of(pass: &BallbarPass, c: [f64; 2], r: f64) -> Vec<(f64, f64)> {
    pass.point
        .iter()
        .map(|p| {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            (wrap(dy.atan2(dx)), dx.hypot(dy) - r)
        })
        .collect()
}

/// Periodic linear interpolation of (angle, value) samples at `angle` (all in [0, 2π)),
/// `sorted` by angle.
fn interpolate(sorted: &[(f64, f64)], angle: f64) -> f64 {
    let n = sorted.len();
    let i = sorted.partition_point(|s| s.0 < angle);
    // Neighbours, across 0/2π by a turn where needed.
    let a = if i == 0 {
        (sorted[n - 1].0 - TAU, sorted[n - 1].1)
    } else {
        sorted[i - 1]
    };
    let b = if i == n {
        (sorted[0].0 + TAU, sorted[0].1)
    } else {
        sorted[i]
    };
    let span = b.0 - a.0;
    let s = if span > 0.0 {
        (angle - a.0) / span
    } else {
        0.0
    };
    a.1 + s * (b.1 - a.1)
}

fn sorted_by_angle(mut v: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

fn hysteresis(input: &BallbarInput) -> f64 {
    let all: Vec<[f64; 2]> = input
        .ccw
        .point
        .iter()
        .chain(&input.cw.point)
        .copied()
        .collect();
    let (c, rho) = least_squares_circle(&all, input.centre);
    let ccw = sorted_by_angle(polar_of(&input.ccw, c, rho));
    let cw = sorted_by_angle(polar_of(&input.cw, c, rho));
    if ccw.is_empty() || cw.is_empty() {
        return f64::NAN;
    }
    let steps = (360.0 / HYSTERESIS_STEP_DEG).round() as usize;
    (0..steps)
        .map(|k| {
            let a = (k as f64 * HYSTERESIS_STEP_DEG).to_radians();
            (interpolate(&ccw, a) - interpolate(&cw, a)).abs()
        })
        .fold(0.0, f64::max)
}

/// Samples of `polar` as (degrees travelled past `reversal`, deviation) within `range`.
fn around(polar: &[(f64, f64)], reversal: f64, s: f64, range: (f64, f64)) -> Vec<(f64, f64)> {
    polar
        .iter()
        .map(|&(a, d)| ((s * signed(a - reversal)).to_degrees(), d))
        .filter(|(phi, _)| *phi >= range.0 && *phi <= range.1)
        .collect()
}

/// The reversals of the plane's axes: (axis index, angle). Axis 1 (cos) reverses at 0° and
/// 180°, axis 2 (sin) at 90° and 270°.
const REVERSALS: [(usize, f64); 4] = [(0, 0.0), (1, 90.0), (0, 180.0), (1, 270.0)];

/// The smooth level of the radial deviation about a reversal and the step across it: a cubic
/// in the angle travelled past the reversal φ (degrees), shared by both sides, plus a lost
/// motion's step ([`step_shape`]), fitted to the samples before (`before`) and after (`after`) it (the transition
/// while a gap is crossed lies between). A cubic follows every smooth shape term (centre
/// offset, the ellipses of mismatch and scale) across ±40° to about 1 % of its size.
struct ReversalFit {
    /// Polynomial coefficients (φ in units of 10°) and the step (m).
    poly: [f64; 4],
    step: f64,
    /// RMS of what the model leaves of the samples it was fitted to (m).
    residual: f64,
}

impl ReversalFit {
    /// The level with the step taken up as a lost motion is: the axis stands while the
    /// command runs R(1 − cos φ) past its reversal, until that reaches the step.
    fn level(&self, phi_deg: f64, radius: f64) -> f64 {
        let x = phi_deg / 10.0;
        let p = &self.poly;
        let taken_up = if self.step > 0.0 {
            (radius * (1.0 - phi_deg.to_radians().cos()) / self.step).clamp(0.0, 1.0)
        } else {
            1.0
        };
        p[0] + x * (p[1] + x * (p[2] + x * p[3])) + self.step * step_shape(phi_deg) * taken_up
    }
}

/// How a lost motion B of the reversing axis shows in the radial deviation φ degrees past
/// the reversal: the axis is B behind on the other side, and the radial direction there is
/// cos φ along the axis, so the step is B·cos φ (half of it, −B/2·cos φ before and +B/2·cos φ
/// after, is the step; the smooth rest −B/2·cos φ the cubic takes).
fn step_shape(phi_deg: f64) -> f64 {
    if phi_deg > 0.0 {
        phi_deg.to_radians().cos()
    } else {
        0.0
    }
}

fn fit_reversal(
    polar: &[(f64, f64)],
    reversal: f64,
    s: f64,
    before: (f64, f64),
    after: (f64, f64),
) -> Option<ReversalFit> {
    let samples: Vec<(f64, f64)> = around(polar, reversal, s, before)
        .into_iter()
        .chain(around(polar, reversal, s, after))
        .collect();
    if samples.len() < 8 {
        return None;
    }
    let rows: Vec<Vec<f64>> = samples
        .iter()
        .map(|&(phi, _)| {
            let x = phi / 10.0;
            vec![1.0, x, x * x, x * x * x, step_shape(phi)]
        })
        .collect();
    let y: Vec<f64> = samples.iter().map(|p| p.1).collect();
    let c = regress(&rows, &y)?;
    let residual = (rows
        .iter()
        .zip(&y)
        .map(|(r, yi)| (yi - r.iter().zip(&c).map(|(a, b)| a * b).sum::<f64>()).powi(2))
        .sum::<f64>()
        / rows.len() as f64)
        .sqrt();
    Some(ReversalFit {
        poly: [c[0], c[1], c[2], c[3]],
        step: c[4],
        residual,
    })
}

/// Per plane axis: the mean step over its four reversals and the largest RMS residual of
/// those fits (a residual near the step says the trace is no clean step: hunting, stick-slip).
fn backlash(polars: &[(bool, Vec<(f64, f64)>); 2]) -> ([f64; 2], [f64; 2]) {
    let (w1, w2) = BACKLASH_WINDOW_DEG;
    let mut steps: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let mut residual = [0.0f64; 2];
    for (clockwise, polar) in polars {
        let s = if *clockwise { -1.0 } else { 1.0 };
        for (axis, at) in REVERSALS {
            if let Some(fit) = fit_reversal(
                polar,
                at.to_radians(),
                s,
                (-w2, SPIKE_BEFORE_DEG.1),
                (w1, w2),
            ) {
                steps[axis].push(fit.step);
                residual[axis] = residual[axis].max(fit.residual);
            }
        }
    }
    let mean = steps.map(|v| {
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    });
    (mean, residual)
}

fn spikes(input: &BallbarInput, polars: &[(bool, Vec<(f64, f64)>); 2]) -> Vec<ReversalSpike> {
    let mut out = Vec::new();
    for (clockwise, polar) in polars {
        let s = if *clockwise { -1.0 } else { 1.0 };
        for (axis, at) in REVERSALS {
            let r = at.to_radians();
            // The level the spike stands out from: the smooth trace with its backlash step
            // (taken up as a lost motion is), fitted before the reversal and after the spike
            // window: what is left is what the loop and the friction add.
            let Some(fit) = fit_reversal(polar, r, s, SPIKE_BEFORE_DEG, SPIKE_AFTER_DEG) else {
                continue;
            };
            let level = |phi: f64| fit.level(phi, input.radius);
            let mut window = around(polar, r, s, (0.0, SPIKE_WINDOW_DEG));
            window.sort_by(|a, b| a.0.total_cmp(&b.0));
            let Some(peak) = window
                .iter()
                .map(|&(phi, d)| (phi, d - level(phi)))
                .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            else {
                continue;
            };
            let half = peak.1 / 2.0;
            let above: Vec<f64> = window
                .iter()
                .filter(|&&(phi, d)| {
                    let e = d - level(phi);
                    e * half.signum() >= half.abs()
                })
                .map(|p| p.0)
                .collect();
            // Contiguous around the peak: from the first to the last sample above half height
            // that the peak's run of samples reaches.
            let (mut lo, mut hi) = (peak.0, peak.0);
            let step = window
                .windows(2)
                .map(|w| w[1].0 - w[0].0)
                .fold(0.0f64, f64::max)
                .max(1e-9);
            let mut sorted = above.clone();
            sorted.sort_by(f64::total_cmp);
            for &phi in sorted.iter().filter(|p| **p >= peak.0) {
                if phi - hi <= step * 1.5 {
                    hi = phi;
                }
            }
            for &phi in sorted.iter().rev().filter(|p| **p <= peak.0) {
                if lo - phi <= step * 1.5 {
                    lo = phi;
                }
            }
            out.push(ReversalSpike {
                axis: input.axes[axis].clone(),
                direction: if *clockwise { "cw" } else { "ccw" },
                angle_deg: at,
                height_um: um(peak.1),
                width_deg: if peak.1.abs() < RESOLUTION {
                    0.0
                } else {
                    hi - lo
                },
            });
        }
    }
    out
}

/// Least squares of `rows` (regressors) against `y` (nalgebra's SVD); `None` when the
/// regressors do not determine the fit (rank-deficient).
fn regress(rows: &[Vec<f64>], y: &[f64]) -> Option<Vec<f64>> {
    let k = rows.first()?.len();
    let x = nalgebra::DMatrix::from_fn(rows.len(), k, |i, j| rows[i][j]);
    let svd = x.svd(true, true);
    let largest = svd.singular_values.max();
    if svd.rank(largest * 1e-12) < k {
        return None;
    }
    let fit = svd
        .solve(&nalgebra::DVector::from_column_slice(y), largest * 1e-12)
        .ok()?;
    Some(fit.iter().copied().collect())
}

/// The sin 2θ coefficient of a direction's radial deviation (with offset, centre and cos 2θ
/// terms fitted beside it).
fn sin2_coefficient(polar: &[(f64, f64)]) -> f64 {
    let rows: Vec<Vec<f64>> = polar
        .iter()
        .map(|&(a, _)| vec![1.0, a.cos(), a.sin(), (2.0 * a).cos(), (2.0 * a).sin()])
        .collect();
    let y: Vec<f64> = polar.iter().map(|p| p.1).collect();
    regress(&rows, &y).map_or(f64::NAN, |c| c[4])
}

fn servo_mismatch(
    input: &BallbarInput,
    polars: &[(bool, Vec<(f64, f64)>); 2],
    b: [f64; 2],
) -> ServoMismatch {
    let coefficient = |clockwise: bool| {
        polars
            .iter()
            .find(|p| p.0 == clockwise)
            .map_or(f64::NAN, |p| sin2_coefficient(&p.1))
    };
    // Lags τ₁, τ₂ draw Δr = s·R·ω(τ₁ − τ₂)/2·sin 2θ (s = +1 CCW, −1 CW): the part of sin 2θ
    // that flips with the direction. A backlash step also has a sin 2θ part that flips
    // (8/3π of half the step per axis, with opposite signs for the two axes): taken out.
    let raw = (coefficient(false) - coefficient(true)) / 2.0;
    let backlash_part = if b[0].is_finite() && b[1].is_finite() {
        (b[0] - b[1]) * 4.0 / (3.0 * PI)
    } else {
        0.0
    };
    let m = raw - backlash_part;
    let lag = 2.0 * m / input.feed;
    ServoMismatch {
        ellipse_um: um(2.0 * m.abs()),
        lag_difference_ms: lag * 1e3,
        lagging_axis: if 2.0 * m.abs() < RESOLUTION {
            "none".into()
        } else {
            input.axes[if lag >= 0.0 { 0 } else { 1 }].clone()
        },
    }
}

/// The strongest component of the radial deviation's residual (after the shape harmonics up
/// to the fourth) over time, per direction, their power summed; Hann-windowed DFT.
fn vibration(input: &BallbarInput) -> Option<Vibration> {
    let period = input.period;
    let revolution = input.feed / (TAU * input.radius);
    let mut spectra: Vec<(Vec<f64>, f64)> = Vec::new();
    let mut df = f64::INFINITY;
    let passes = [&input.ccw, &input.cw];
    let mut residuals = Vec::new();
    for pass in passes {
        let polar = polar_of(pass, input.centre, input.radius);
        if polar.len() < 64 {
            return None;
        }
        let rows: Vec<Vec<f64>> = polar
            .iter()
            .map(|&(a, _)| {
                let mut r = vec![1.0];
                for h in 1..=4 {
                    r.push((h as f64 * a).cos());
                    r.push((h as f64 * a).sin());
                }
                r
            })
            .collect();
        let y: Vec<f64> = polar.iter().map(|p| p.1).collect();
        let c = regress(&rows, &y)?;
        let e: Vec<f64> = rows
            .iter()
            .zip(&y)
            .map(|(r, yi)| yi - r.iter().zip(&c).map(|(a, b)| a * b).sum::<f64>())
            .collect();
        df = df.min(1.0 / (e.len() as f64 * period));
        residuals.push(e);
    }
    let nyquist = 0.5 / period;
    let f_min = (VIBRATION_MIN_HARMONIC * revolution).max(2.0 * df);
    if f_min >= nyquist {
        return None;
    }
    let freqs: Vec<f64> = (0..)
        .map(|k| f_min + k as f64 * df)
        .take_while(|f| *f < nyquist)
        .collect();
    for e in &residuals {
        let n = e.len();
        let w: Vec<f64> = (0..n)
            .map(|i| 0.5 - 0.5 * (TAU * i as f64 / (n - 1) as f64).cos())
            .collect();
        let wsum: f64 = w.iter().sum();
        let amps: Vec<f64> = freqs
            .iter()
            .map(|f| {
                // Rotating phasor instead of sin/cos per sample.
                let (s, c) = (TAU * f * period).sin_cos();
                let (mut pr, mut pi) = (1.0f64, 0.0f64);
                let (mut re, mut im) = (0.0, 0.0);
                for (x, wi) in e.iter().zip(&w) {
                    re += x * wi * pr;
                    im += x * wi * pi;
                    let t = pr * c - pi * s;
                    pi = pr * s + pi * c;
                    pr = t;
                }
                2.0 * re.hypot(im) / wsum
            })
            .collect();
        spectra.push((amps, wsum));
    }
    let (k, power) = (0..freqs.len())
        .map(|k| (k, spectra.iter().map(|s| s.0[k].powi(2)).sum::<f64>()))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let amplitude = (power / spectra.len() as f64).sqrt();
    if amplitude < RESOLUTION {
        return None;
    }
    Some(Vibration {
        frequency_hz: freqs[k],
        amplitude_um: um((power / spectra.len() as f64).sqrt()),
    })
}

/// A "nice" ceiling: 1, 2 or 5 × 10ⁿ.
fn nice_ceiling(x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        return 1e-6;
    }
    let p = 10f64.powf(x.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|v| *v >= x * (1.0 - 1e-12))
        .unwrap_or(10.0 * p)
}

/// Share of the plot's unit radius that the largest deviation of the scale takes.
const PLOT_BAND: f64 = 0.4;

/// Analyses one test.
pub fn analyse(input: &BallbarInput) -> BallbarRun {
    let cw = direction_figures(&input.cw, input);
    let ccw = direction_figures(&input.ccw, input);
    let polars = [
        (false, polar_of(&input.ccw, input.centre, input.radius)),
        (true, polar_of(&input.cw, input.centre, input.radius)),
    ];
    let (b, residual) = backlash(&polars);
    let backlash_um: BTreeMap<String, f64> = input
        .axes
        .iter()
        .zip(b)
        .map(|(a, v)| (a.clone(), um(v)))
        .collect();
    let backlash_fit_residual_um: BTreeMap<String, f64> = input
        .axes
        .iter()
        .zip(residual)
        .map(|(a, v)| (a.clone(), um(v)))
        .collect();
    let largest = polars
        .iter()
        .flat_map(|p| p.1.iter().map(|x| x.1.abs()))
        .fold(0.0, f64::max);
    let range = nice_ceiling(largest);
    let stick_slip_stalls = input
        .axes
        .iter()
        .map(|a| (a.clone(), input.stalls.get(a).copied().unwrap_or(0)))
        .collect();
    BallbarRun {
        scenario: input.scenario.clone(),
        plane: input.plane.clone(),
        feed_mm_min: input.feed * 60e3,
        radius_mm: input.radius * 1e3,
        centre_mm: input.centre_3d.map(|v| v * 1e3),
        completed: input.completed,
        circular_hysteresis_um: um(hysteresis(input)),
        backlash_um,
        backlash_fit_residual_um,
        reversal_spikes: spikes(input, &polars),
        servo_mismatch: servo_mismatch(input, &polars, b),
        stick_slip_stalls,
        vibration: vibration(input),
        magnification: PLOT_BAND / range * input.radius,
        scale_um_per_division: um(range) / 2.0,
        cw,
        ccw,
        files: Vec::new(),
        breaches: Vec::new(),
        polar: [
            polars[0]
                .1
                .iter()
                .map(|&(a, d)| (a.to_degrees(), um(d)))
                .collect(),
            polars[1]
                .1
                .iter()
                .map(|&(a, d)| (a.to_degrees(), um(d)))
                .collect(),
        ],
        points: [&input.ccw, &input.cw]
            .map(|p| p.point.iter().map(|q| q.map(|v| v * 1e3)).collect()),
        times: [&input.ccw, &input.cw].map(|p| p.time.clone()),
    }
}

impl BallbarRun {
    /// The plot's label of this run.
    pub fn label(&self) -> String {
        format!("F{}_R{}", trim(self.feed_mm_min), trim(self.radius_mm))
    }

    /// The run as a block of the terminal report.
    pub fn text(&self) -> String {
        let [a1, a2] = self.plane_axes();
        let mut t = format!(
            "ballbar (ISO 230-4) {}: plane {}, radius {} mm, feed {} mm/min ({:.3} mm/s), centre ({}) mm{}\n",
            self.scenario,
            self.plane.to_uppercase(),
            trim(self.radius_mm),
            trim(self.feed_mm_min),
            self.feed_mm_min / 60.0,
            self.centre_mm.map(|v| format!("{v:.3}")).join(", "),
            if self.completed { "" } else { " — STOPPED EARLY" }
        );
        let row =
            |name: &str, ccw: String, cw: String| format!("  {name:<36} {ccw:>14} {cw:>14}\n");
        t += &row("", "CCW".into(), "CW".into());
        let f = |v: f64| format!("{v:.2} µm");
        t += &row(
            "circular deviation G (least squares)",
            f(self.ccw.circular_deviation_um),
            f(self.cw.circular_deviation_um),
        );
        t += &row(
            "circular deviation G (minimum zone)",
            f(self.ccw.circular_deviation_min_zone_um),
            f(self.cw.circular_deviation_min_zone_um),
        );
        t += &row(
            "radial deviation F max",
            f(self.ccw.radial_deviation_max_um),
            f(self.cw.radial_deviation_max_um),
        );
        t += &row(
            "radial deviation F min",
            f(self.ccw.radial_deviation_min_um),
            f(self.cw.radial_deviation_min_um),
        );
        let o = |d: &DirectionFigures| {
            format!(
                "{:+.1}, {:+.1}",
                d.least_squares_centre_offset_um[0], d.least_squares_centre_offset_um[1]
            )
        };
        t += &row(
            &format!(
                "centre offset {}, {} (µm)",
                a1.to_uppercase(),
                a2.to_uppercase()
            ),
            o(&self.ccw),
            o(&self.cw),
        );
        t += &format!(
            "  {:<36} {:>14}\n",
            "circular hysteresis H",
            f(self.circular_hysteresis_um)
        );
        t += "  diagnosis\n";
        t += &format!(
            "    backlash: {}\n",
            [&a1, &a2]
                .iter()
                .map(|a| {
                    let v = self.backlash_um.get(*a).copied().unwrap_or(f64::NAN);
                    let r = self
                        .backlash_fit_residual_um
                        .get(*a)
                        .copied()
                        .unwrap_or(0.0);
                    format!("{} {v:.1} µm (fit residual {r:.1} µm)", a.to_uppercase())
                })
                .collect::<Vec<_>>()
                .join(", ")
        );
        let m = &self.servo_mismatch;
        t += &format!(
            "    servo mismatch: {:.2} µm ellipse at 45°, {}\n",
            m.ellipse_um,
            m.lag_text()
        );
        t += "    reversal spikes, height µm (width °):\n";
        for dir in ["ccw", "cw"] {
            t += &format!("      {:<4}", dir.to_uppercase());
            for s in self.reversal_spikes.iter().filter(|s| s.direction == dir) {
                t += &format!(
                    "  {} {:>3.0}°: {:+.1} ({:.1}°)",
                    s.axis.to_uppercase(),
                    s.angle_deg,
                    s.height_um,
                    s.width_deg
                );
            }
            t += "\n";
        }
        t += &format!(
            "    stick-slip stalls: {}\n",
            [&a1, &a2]
                .iter()
                .map(|a| {
                    let n = self.stick_slip_stalls.get(*a).copied().unwrap_or(0);
                    format!("{} {n}", a.to_uppercase())
                })
                .collect::<Vec<_>>()
                .join(", ")
        );
        for b in &self.breaches {
            t += &format!("  BOUND BREACHED: {b}\n");
        }
        t += &match &self.vibration {
            Some(v) => format!(
                "    main vibration: {:.2} Hz, {:.2} µm amplitude\n",
                v.frequency_hz, v.amplitude_um
            ),
            None => {
                "    main vibration: none resolved (below 1 nm, or the trace too short)\n".into()
            }
        };
        t
    }

    fn plane_axes(&self) -> [String; 2] {
        let mut keys = self.backlash_um.keys().cloned();
        let order: Vec<char> = self.plane.chars().collect();
        let name = |c: char| c.to_string();
        match order.as_slice() {
            [a, b] => [name(*a), name(*b)],
            _ => [
                keys.next().unwrap_or_default(),
                keys.next().unwrap_or_default(),
            ],
        }
    }

    /// The polar data as CSV: direction, angle (deg), radial deviation from the nominal circle
    /// about the programmed centre (µm).
    pub fn polar_csv(&self) -> String {
        let [a1, a2] = self.plane_axes();
        let mut t = format!("direction,t_s,angle_deg,radial_deviation_um,{a1}_mm,{a2}_mm\n");
        for (k, dir) in ["ccw", "cw"].iter().enumerate() {
            for (((a, d), p), time) in self.polar[k]
                .iter()
                .zip(&self.points[k])
                .zip(&self.times[k])
            {
                t += &format!("{dir},{time},{a},{d},{},{}\n", p[0], p[1]);
            }
        }
        t
    }
}

/// A deviation in µm for the plot: one decimal, or four below 0.1 µm (a stiff ideal machine
/// deviates by nanometres).
fn fmt_um(v: f64) -> String {
    if v.abs() >= 0.1 || v == 0.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.4}")
    }
}

fn trim(v: f64) -> String {
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

impl BallbarReport {
    /// The report for the terminal: every run's block.
    pub fn text(&self) -> String {
        self.runs
            .iter()
            .map(|r| r.text())
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// The report as pretty-printed JSON, with a final newline.
    pub fn json(&self) -> String {
        serde_json::to_string_pretty(self).expect("plain values") + "\n"
    }

    /// The polar plots in a Rerun recording: per run, the nominal circle, both directions
    /// magnified as in the PNG (mm, the nominal circle at the test radius) and the figures.
    pub fn write_recording(&self, path: &Path) -> Result<(), ReportError> {
        let fail = |e: &dyn std::fmt::Display| ReportError::Recording {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let rec = rerun::RecordingStreamBuilder::new("cncsim")
            .recording_name(format!("ballbar: {}", self.scenario))
            .save(path)
            .map_err(|e| fail(&e))?;
        for run in &self.runs {
            let base = format!("ballbar/{}", run.label());
            let r = run.radius_mm;
            let k = run.magnification / 1e3; // mm of plot per µm of deviation
            let ring = |dev_um: f64| -> Vec<[f32; 2]> {
                (0..=360)
                    .map(|d| {
                        let a = (d as f64).to_radians();
                        let rr = r + k * dev_um;
                        [(rr * a.cos()) as f32, (rr * a.sin()) as f32]
                    })
                    .collect()
            };
            let div = run.scale_um_per_division;
            rec.log_static(
                format!("{base}/grid"),
                &rerun::LineStrips2D::new([-2.0, -1.0, 1.0, 2.0].map(|m| ring(m * div)))
                    .with_colors([rerun::Color::from_rgb(200, 200, 200)]),
            )
            .map_err(|e| fail(&e))?;
            rec.log_static(
                format!("{base}/nominal"),
                &rerun::LineStrips2D::new([ring(0.0)])
                    .with_colors([rerun::Color::from_rgb(0, 0, 0)]),
            )
            .map_err(|e| fail(&e))?;
            for ((name, colour), data) in [("ccw", CCW_COLOUR), ("cw", CW_COLOUR)]
                .iter()
                .zip(&run.polar)
            {
                let strip: Vec<[f32; 2]> = data
                    .iter()
                    .map(|&(a, d)| {
                        let a = a.to_radians();
                        let rr = r + k * d;
                        [(rr * a.cos()) as f32, (rr * a.sin()) as f32]
                    })
                    .collect();
                rec.log_static(
                    format!("{base}/{name}"),
                    &rerun::LineStrips2D::new([strip])
                        .with_colors([rerun::Color::from_rgb(colour.0, colour.1, colour.2)]),
                )
                .map_err(|e| fail(&e))?;
            }
            rec.log_static(
                format!("{base}/figures"),
                &rerun::TextDocument::new(format!(
                    "```\n{}\n```\nmagnification ×{:.0}, {:.3} µm per grid ring",
                    run.text(),
                    run.magnification,
                    div
                ))
                .with_media_type(rerun::MediaType::markdown()),
            )
            .map_err(|e| fail(&e))?;
        }
        rec.flush_blocking().map_err(|e| fail(&e))?;
        Ok(())
    }
}

const CCW_COLOUR: (u8, u8, u8) = (31, 119, 180);
const CW_COLOUR: (u8, u8, u8) = (214, 39, 40);

/// Writes the polar plot of `run` to `path`: the nominal circle, rings at each scale division,
/// both directions' radial deviation magnified, the figures beside it.
pub fn write_polar_plot(path: &Path, run: &BallbarRun) -> Result<(), ReportError> {
    render(path, |pixels| draw_polar(pixels, run))
}

/// The figures the polar plot lists beside it: (text, font size).
fn polar_figure_lines(run: &BallbarRun, [a1, a2]: [&String; 2]) -> Vec<(String, i32)> {
    let div = run.scale_um_per_division;
    let mut lines = vec![
        (format!("Ballbar test (ISO 230-4): {}", run.scenario), 24),
        (
            format!(
                "plane {}, R {} mm, F {} mm/min ({:.2} mm/s)",
                run.plane.to_uppercase(),
                trim(run.radius_mm),
                trim(run.feed_mm_min),
                run.feed_mm_min / 60.0
            ),
            19,
        ),
        (
            format!(
                "magnification ×{:.0}, {} µm/ring, about the programmed centre",
                run.magnification,
                trim(div)
            ),
            17,
        ),
        (String::new(), 10),
        (
            format!(
                "G (least squares)  CCW {} µm   CW {} µm",
                fmt_um(run.ccw.circular_deviation_um),
                fmt_um(run.cw.circular_deviation_um)
            ),
            19,
        ),
        (
            format!(
                "G (minimum zone)   CCW {} µm   CW {} µm",
                fmt_um(run.ccw.circular_deviation_min_zone_um),
                fmt_um(run.cw.circular_deviation_min_zone_um)
            ),
            19,
        ),
        (
            format!(
                "F max / min   CCW {} / {}   CW {} / {} µm",
                fmt_um(run.ccw.radial_deviation_max_um),
                fmt_um(run.ccw.radial_deviation_min_um),
                fmt_um(run.cw.radial_deviation_max_um),
                fmt_um(run.cw.radial_deviation_min_um)
            ),
            19,
        ),
        (
            format!("H (hysteresis)  {} µm", fmt_um(run.circular_hysteresis_um)),
            19,
        ),
        (String::new(), 10),
        (
            format!(
                "backlash (fit residual)  {}",
                [a1, a2]
                    .iter()
                    .map(|a| {
                        let v = run.backlash_um.get(*a).copied().unwrap_or(f64::NAN);
                        let r = run.backlash_fit_residual_um.get(*a).copied().unwrap_or(0.0);
                        format!("{} {v:.1} ({r:.1}) µm", a.to_uppercase())
                    })
                    .collect::<Vec<_>>()
                    .join(",  ")
            ),
            19,
        ),
        (
            format!(
                "servo mismatch  {:.1} µm, {}",
                run.servo_mismatch.ellipse_um,
                run.servo_mismatch.lag_text()
            ),
            19,
        ),
        (
            format!(
                "stick-slip stalls  {}",
                run.stick_slip_stalls
                    .iter()
                    .map(|(a, n)| format!("{} {n}", a.to_uppercase()))
                    .collect::<Vec<_>>()
                    .join(",  ")
            ),
            19,
        ),
        (
            match &run.vibration {
                Some(v) => format!(
                    "main vibration  {:.2} Hz, {:.1} µm",
                    v.frequency_hz, v.amplitude_um
                ),
                None => "main vibration  none resolved".into(),
            },
            19,
        ),
        (String::new(), 10),
        ("reversal spikes (µm):".into(), 19),
    ];
    for dir in ["ccw", "cw"] {
        let spikes: Vec<String> = run
            .reversal_spikes
            .iter()
            .filter(|s| s.direction == dir)
            .map(|s| {
                format!(
                    "{} {:.0}° {:+.1}",
                    s.axis.to_uppercase(),
                    s.angle_deg,
                    s.height_um
                )
            })
            .collect();
        lines.push((
            format!("  {}: {}", dir.to_uppercase(), spikes.join(",  ")),
            17,
        ));
    }
    if !run.completed {
        lines.push(("RUN STOPPED EARLY: figures of what ran".into(), 19));
    }
    lines
}

fn draw_polar(pixels: &mut [u8], run: &BallbarRun) -> DrawResult<()> {
    use plotters::prelude::*;
    let root = BitMapBackend::with_buffer(pixels, PLOT_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let (w, h) = PLOT_SIZE;
    let side = h;
    let (left, right) = root.split_horizontally(side);
    let extent = 1.0 + 2.2 * PLOT_BAND / 2.0 * 1.2;
    let mut chart = ChartBuilder::on(&left)
        .margin(30)
        .build_cartesian_2d(-extent..extent, -extent..extent)?;
    let div = run.scale_um_per_division;
    // Plot radius 1 is the nominal circle; `k` plot units per µm.
    let k = PLOT_BAND / (2.0 * div);
    let circle = |dev_um: f64| -> Vec<(f64, f64)> {
        (0..=720)
            .map(|i| {
                let a = (i as f64 / 2.0).to_radians();
                let r = 1.0 + k * dev_um;
                (r * a.cos(), r * a.sin())
            })
            .collect()
    };
    let grey = RGBColor(205, 205, 205);
    for m in [-2.0, -1.0, 1.0, 2.0] {
        chart.draw_series(LineSeries::new(circle(m * div), grey.stroke_width(1)))?;
    }
    for deg in (0..360).step_by(30) {
        let a = (deg as f64).to_radians();
        let (r0, r1) = (1.0 - 2.0 * k * div, 1.0 + 2.0 * k * div);
        chart.draw_series(LineSeries::new(
            [(r0 * a.cos(), r0 * a.sin()), (r1 * a.cos(), r1 * a.sin())],
            grey.stroke_width(1),
        ))?;
    }
    chart.draw_series(LineSeries::new(circle(0.0), BLACK.stroke_width(2)))?;
    let [a1, a2] = run.plane_axes();
    let label_style = (FAMILY, 20).into_font().color(&BLACK);
    let reach = 1.0 + 2.0 * k * div + 0.08;
    for (text, x, y) in [
        (format!("+{}", a1.to_uppercase()), reach, 0.0),
        (format!("+{}", a2.to_uppercase()), 0.0, reach),
        (
            format!("±{} µm", trim(2.0 * div)),
            (1.0 + 2.0 * k * div) * 0.72,
            -(1.0 + 2.0 * k * div) * 0.72 - 0.05,
        ),
    ] {
        chart.draw_series(std::iter::once(Text::new(
            text,
            (x - 0.05, y),
            label_style.clone(),
        )))?;
    }
    for ((name, colour), data) in [("CCW", CCW_COLOUR), ("CW", CW_COLOUR)]
        .iter()
        .zip(&run.polar)
    {
        // In the order traced: a path that doubles back in angle (hunting) stays readable.
        let points: Vec<(f64, f64)> = data
            .iter()
            .map(|&(a, d)| {
                let a = a.to_radians();
                let r = 1.0 + k * d;
                (r * a.cos(), r * a.sin())
            })
            .collect();
        let c = RGBColor(colour.0, colour.1, colour.2);
        chart
            .draw_series(LineSeries::new(points, c.stroke_width(2)))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 24, y)], c.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .label_font((FAMILY, 18))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    // The figures beside the plot.
    let lines = polar_figure_lines(run, [&a1, &a2]);
    let mut y = 40i32;
    for (text, size) in lines {
        right.draw(&Text::new(
            text,
            (10, y),
            (FAMILY, size).into_font().color(&BLACK),
        ))?;
        y += size + 12;
    }
    let _ = w;
    root.present()?;
    Ok(())
}
