//! `[planner]`: which profile turns the program into setpoints, and its parameters.

use super::limits;
use super::program::warn_if_fast;
use super::source::{InFile, Num};
use crate::diagnostics::{check_range, FileError, LineColumn};
use crate::plan::BlendChoice;
use serde::Deserialize;
use std::collections::BTreeMap;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPlanner {
    #[serde(default)]
    profile: ProfileName,
    #[serde(default = "default_rapid")]
    rapid_mm_s: Num,
    /// Trapezoid profile: path acceleration (mm/s²).
    acceleration_mm_s2: Option<Num>,
    /// Corner behaviour: as programmed, or forced.
    #[serde(default)]
    blend: RawBlend,
    /// Tolerance of `blend = "continuous"` (mm); absent = as far as the segments allow.
    tolerance_mm: Option<Num>,
    /// Naive-CAM collinearity tolerance (LinuxCNC's G64 Q, mm): runs of short straight moves
    /// within it of one line are joined, with continuous blending.
    naive_cam_tolerance_mm: Option<Num>,
    /// Jerk-limited planner: limits per machine axis in mm or deg per s, s², s³.
    #[serde(default)]
    limits: BTreeMap<String, Spanned<RawLimits>>,
}

fn default_rapid() -> Num {
    Spanned::new(0..0, 50.0)
}

impl Default for RawPlanner {
    fn default() -> Self {
        RawPlanner {
            profile: ProfileName::default(),
            rapid_mm_s: default_rapid(),
            acceleration_mm_s2: None,
            blend: RawBlend::default(),
            tolerance_mm: None,
            naive_cam_tolerance_mm: None,
            limits: BTreeMap::new(),
        }
    }
}

/// Which planner turns the program into setpoints.
#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash, Default, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ProfileName {
    /// Seed constant-velocity interpolators (equal steps V·T, equal chords).
    #[default]
    #[value(name = "constant")]
    ConstantVelocity,
    /// Seed trapezoidal profile on straight moves (needs acceleration_mm_s2).
    Trapezoid,
    /// Jerk-limited look-ahead planner on the machine axes (needs limits per axis).
    #[value(name = "jerk")]
    JerkLimited,
}

#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[serde(rename_all = "kebab-case")]
enum RawBlend {
    #[default]
    Program,
    ExactStop,
    Continuous,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLimits {
    velocity: f64,
    acceleration: f64,
    jerk: f64,
}

/// The planner part of a scenario: the profile it names and the parameters of every profile
/// it gives (limits stay in program units: the axis kinds come from the machine).
#[derive(Debug, Clone, PartialEq)]
pub struct PlannerSettings {
    /// Which planner turns the program into setpoints.
    pub profile: ProfileName,
    /// Trapezoid path acceleration (m/s²).
    pub acceleration: Option<f64>,
    /// Jerk-limited planner, per axis: [velocity, acceleration, jerk] in mm or deg units.
    pub limits: BTreeMap<String, ([f64; 3], Option<LineColumn>)>,
    /// Corner behaviour: as programmed (G61/G64), exact stop, or continuous (`blend`, with
    /// `tolerance_mm`).
    pub blend: BlendChoice,
    /// LinuxCNC's G64 Q (m): runs of straight moves within it of one line are joined.
    pub naive_cam_tolerance: Option<f64>,
    /// Speed of rapid moves (m/s).
    pub rapid_speed: f64,
    /// Where the `[planner]` table is.
    pub at: Option<LineColumn>,
}

impl TryFrom<InFile<'_, &RawPlanner>> for PlannerSettings {
    type Error = FileError;

    fn try_from(InFile { raw: rp, file }: InFile<'_, &RawPlanner>) -> Result<Self, FileError> {
        warn_if_fast(file, "rapid_mm_s", &rp.rapid_mm_s);
        let acceleration = file
            .ranged_opt(
                rp.acceleration_mm_s2.as_ref(),
                "acceleration_mm_s2",
                "mm/s²",
                limits::ACCELERATION_MM_S2,
            )?
            .map(|a| a * 1e-3);
        let mut axis_limits = BTreeMap::new();
        for (axis, l) in &rp.limits {
            let v = l.get_ref();
            let values = [v.velocity, v.acceleration, v.jerk];
            let ranges = [
                ("velocity", "mm/s or deg/s", limits::LIMIT_VELOCITY),
                (
                    "acceleration",
                    "mm/s² or deg/s²",
                    limits::LIMIT_ACCELERATION,
                ),
                ("jerk", "mm/s³ or deg/s³", limits::LIMIT_JERK),
            ];
            for (value, (name, unit, (lo, hi))) in values.iter().zip(ranges) {
                check_range(
                    &format!("planner.limits.{axis}.{name}"),
                    *value,
                    unit,
                    lo,
                    hi,
                )
                .map_err(|m| file.error(l.span(), m))?;
            }
            axis_limits.insert(axis.clone(), (values, file.at(l.span().start)));
        }
        let tolerance = file
            .ranged_opt(
                rp.tolerance_mm.as_ref(),
                "tolerance_mm",
                "mm",
                limits::TOLERANCE_MM,
            )?
            .map(|t| t * 1e-3);
        let blend = match rp.blend {
            RawBlend::Program => BlendChoice::Program,
            RawBlend::ExactStop => BlendChoice::ExactStop,
            RawBlend::Continuous => BlendChoice::Continuous { tolerance },
        };
        if let (Some(t), false) = (&rp.tolerance_mm, rp.blend == RawBlend::Continuous) {
            return Err(file.error(t.span(), "tolerance_mm applies to blend = \"continuous\""));
        }
        let naive_cam_tolerance = match &rp.naive_cam_tolerance_mm {
            Some(q) if rp.blend == RawBlend::ExactStop => {
                return Err(file.error(
                    q.span(),
                    "naive_cam_tolerance_mm joins moves: it needs blend = \"continuous\" or \"program\"",
                ))
            }
            Some(q) => Some(
                file.ranged(q, "naive_cam_tolerance_mm", "mm", limits::TOLERANCE_MM)? * 1e-3,
            ),
            None => None,
        };
        Ok(PlannerSettings {
            profile: rp.profile,
            acceleration,
            limits: axis_limits,
            blend,
            naive_cam_tolerance,
            rapid_speed: file.ranged(&rp.rapid_mm_s, "rapid_mm_s", "mm/s", limits::SPEED_MM_S)?
                * 1e-3,
            at: file.table("[planner]"),
        })
    }
}
