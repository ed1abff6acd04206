//! The planner's input: a path on the machine axes, plain data in SI units (m, rad, s).
//!
//! It maps one-to-one onto the program representation after inverse kinematics: a program
//! `Move` with `Motion::Linear` becomes [`Geometry::Line`], `Motion::Arc` becomes
//! [`Geometry::Arc`] with the plane's two machine axes, `Feed::PathSpeed` becomes `feed`
//! (`Feed::Rapid` becomes `None`; an inverse-time feed becomes length / time), the `FeedRule`
//! becomes the per-axis `feed_metric` weights, and `Blend` maps directly.

use std::fmt;

/// Whether an axis translates (m) or rotates (rad).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisKind {
    /// Translates; coordinates in m.
    Linear,
    /// Rotates; coordinates in rad.
    Rotary,
}

impl AxisKind {
    /// Factor from SI (m, rad) to program units (mm, deg).
    pub fn program_units_per_si(self) -> f64 {
        match self {
            AxisKind::Linear => 1e3,
            AxisKind::Rotary => 180.0 / std::f64::consts::PI,
        }
    }
}

/// Per-axis kinematic limits in SI (m or rad per s, s², s³), all strictly positive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisLimits {
    /// Largest speed (m/s, or rad/s on a rotary axis).
    pub velocity: f64,
    /// Largest acceleration (m/s², or rad/s² on a rotary axis).
    pub acceleration: f64,
    /// Largest jerk (m/s³, or rad/s³ on a rotary axis).
    pub jerk: f64,
}

impl AxisLimits {
    /// Limits given in program units (mm or deg per s, s², s³), converted to SI.
    pub fn from_program_units(kind: AxisKind, velocity: f64, acceleration: f64, jerk: f64) -> Self {
        let k = 1.0 / kind.program_units_per_si();
        AxisLimits {
            velocity: velocity * k,
            acceleration: acceleration * k,
            jerk: jerk * k,
        }
    }
}

/// One machine axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisSpec {
    /// Name as written in reports and CSV headers (`x`, `y`, `z`, `a`, `c`).
    pub name: String,
    /// Whether it translates or rotates.
    pub kind: AxisKind,
    /// Its velocity, acceleration and jerk limits.
    pub limits: AxisLimits,
}

/// The geometry of one segment; it starts where the previous one ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// Straight line in all axes to `end`.
    Line {
        /// End point, one coordinate per axis (m, or rad on a rotary axis).
        end: Vec<f64>,
    },
    /// Circular arc in the plane of axes `plane = [i, j]` about `center` (coordinates on those
    /// two axes), counter-clockwise from +i towards +j unless `clockwise`, with `turns` extra
    /// full turns; every other axis moves linearly with the angle (helix). If the start and end
    /// radii differ (rounding in the program), the radius changes linearly with the angle.
    Arc {
        /// Indices of the two (linear) axes spanning the arc's plane, in order i, j.
        plane: [usize; 2],
        /// Centre on the axes `plane` names (m).
        center: [f64; 2],
        /// Turns from +j towards +i instead.
        clockwise: bool,
        /// Extra full turns beyond the first.
        turns: u32,
        /// End point, one coordinate per axis (m, or rad on a rotary axis).
        end: Vec<f64>,
    },
}

impl Geometry {
    /// End point of the segment, one coordinate per axis (m, or rad on a rotary axis).
    pub fn end(&self) -> &[f64] {
        match self {
            Geometry::Line { end } | Geometry::Arc { end, .. } => end,
        }
    }
}

/// Corner behaviour at the end of a segment (G61 / G64 P).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Blend {
    /// Stop exactly at the programmed point.
    #[default]
    ExactStop,
    /// Pass the corner without stopping, staying within `tolerance` of the programmed path
    /// (measured as [`AxisPath::tool_lever_arms`] says). `None`: no tolerance given, the
    /// corner is rounded as far as the adjacent segments allow.
    Continuous {
        /// Largest allowed deviation from the programmed corner (m at the tool tip).
        tolerance: Option<f64>,
    },
}

/// One segment of the path.
#[derive(Debug, Clone, PartialEq)]
pub struct PathSegment {
    /// Its shape and end point.
    pub geometry: Geometry,
    /// Programmed path speed (SI, in the `feed_metric`); `None` = as fast as the axes allow.
    pub feed: Option<f64>,
    /// Per-axis weights `w_i` of the feed metric: path speed = sqrt(Σ (w_i·q̇_i)²). The
    /// LinuxCNC rule is 1 on linear axes and 0 on rotary ones; the 5-axis study's rule
    /// (Euclidean over mm and deg) is 1 on linear axes and (1e-3 m/mm)/(π/180 rad/deg) on rotary
    /// ones. A segment of zero length in this metric (e.g. purely rotary under the LinuxCNC
    /// weights) is not limited by the feed.
    pub feed_metric: Vec<f64>,
    /// What to do at the end of this segment.
    pub blend: Blend,
    /// Index of the program move this segment comes from (copied into the setpoints).
    pub source_index: u32,
}

/// A path on the machine axes: where it starts and its segments.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisPath {
    /// The machine axes, in the order of every coordinate vector of the path.
    pub axes: Vec<AxisSpec>,
    /// Start point, one coordinate per axis (m, or rad on a rotary axis).
    pub start: Vec<f64>,
    /// The segments in order, each starting where the previous one ends.
    pub segments: Vec<PathSegment>,
    /// Per axis, the distance (m) of the tool tip from each rotary axis, so that corner
    /// tolerances are measured at the tool tip: a deviation δ (rad) on rotary axis i moves the
    /// tip by at most `tool_lever_arms[i]·δ`, and the tolerance norm is the Euclidean norm over
    /// the linear axes plus these terms. Empty: the Euclidean norm over all axes in SI units
    /// (1 rad counts as 1 m). Entries of linear axes are ignored.
    pub tool_lever_arms: Vec<f64>,
}

/// Why a path cannot be planned.
#[derive(Debug, Clone, PartialEq)]
pub enum PathError {
    /// An axis limit is not finite and strictly positive.
    InvalidLimits {
        /// Index of the axis in [`AxisPath::axes`].
        axis: usize,
    },
    /// A position, weight or feed has the wrong number of entries.
    AxisCountMismatch {
        /// Index of the segment; `None` for the path as a whole (start, lever arms).
        segment: Option<usize>,
        /// Number of axes.
        expected: usize,
        /// Number of entries given.
        found: usize,
    },
    /// A coordinate, feed, weight or tolerance is not finite (or negative where it must not be).
    InvalidValue {
        /// Index of the segment; `None` for the path as a whole (start, lever arms).
        segment: Option<usize>,
        /// Which value, as the message names it (`"feed"`, `"end position"`, …).
        what: &'static str,
    },
    /// The arc's plane names an axis that does not exist, the same axis twice, or a rotary axis.
    InvalidArcPlane {
        /// Index of the segment.
        segment: usize,
    },
    /// The arc starts or ends at its centre, or its start and end radii differ by more than
    /// [`ARC_RADIUS_MISMATCH`] relative.
    InvalidArcRadius {
        /// Index of the segment.
        segment: usize,
        /// Distance of the arc's start from its centre (m).
        start_radius: f64,
        /// Distance of the arc's end from its centre (m).
        end_radius: f64,
    },
    /// Internal: the look-ahead left a segment too short for its speed change (a planner bug).
    Infeasible {
        /// Index of the segment.
        segment: usize,
    },
}

/// Largest relative difference between an arc's start and end radii that is accepted as
/// rounding in the program (the radius is then interpolated along the arc).
pub const ARC_RADIUS_MISMATCH: f64 = 1e-3;

impl PathError {
    /// The same error with its segment index counted `by` segments further on.
    pub(super) fn offset(self, by: usize) -> PathError {
        match self {
            PathError::AxisCountMismatch {
                segment,
                expected,
                found,
            } => PathError::AxisCountMismatch {
                segment: segment.map(|s| s + by),
                expected,
                found,
            },
            PathError::InvalidValue { segment, what } => PathError::InvalidValue {
                segment: segment.map(|s| s + by),
                what,
            },
            PathError::InvalidArcPlane { segment } => PathError::InvalidArcPlane {
                segment: segment + by,
            },
            PathError::InvalidArcRadius {
                segment,
                start_radius,
                end_radius,
            } => PathError::InvalidArcRadius {
                segment: segment + by,
                start_radius,
                end_radius,
            },
            PathError::Infeasible { segment } => PathError::Infeasible {
                segment: segment + by,
            },
            other => other,
        }
    }
}

impl fmt::Display for PathError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PathError::InvalidLimits { axis } => {
                write!(
                    f,
                    "axis {axis}: limits must be finite and strictly positive"
                )
            }
            PathError::AxisCountMismatch {
                segment,
                expected,
                found,
            } => {
                write!(
                    f,
                    "{}: expected {expected} axis values, found {found}",
                    at(*segment)
                )
            }
            PathError::InvalidValue { segment, what } => {
                write!(f, "{}: invalid {what}", at(*segment))
            }
            PathError::InvalidArcPlane { segment } => {
                write!(
                    f,
                    "segment {segment}: the arc plane must be two distinct linear axes"
                )
            }
            PathError::InvalidArcRadius {
                segment,
                start_radius,
                end_radius,
            } => write!(
                f,
                "segment {segment}: arc radii {start_radius} m (start) and {end_radius} m (end) \
                 are zero or differ by more than {ARC_RADIUS_MISMATCH} relative"
            ),
            PathError::Infeasible { segment } => {
                write!(
                    f,
                    "segment {segment}: no feasible speed profile (planner bug)"
                )
            }
        }
    }
}

fn at(segment: Option<usize>) -> String {
    segment.map_or_else(|| "path".to_string(), |s| format!("segment {s}"))
}

impl std::error::Error for PathError {}
