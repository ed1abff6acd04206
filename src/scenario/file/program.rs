//! `[program]`: where the part program comes from (a file, or a built-in circle or polyline),
//! how the file is read, where program zero is, and how the machine reaches the first point.

use super::limits;
use super::source::{InFile, Num};
use crate::diagnostics::{check_range, FileError, LineColumn};
use crate::program::{
    parse_tool_table, CircleSpec, ClWriter, FeedRule, LengthUnit, PolylineSpec, ReadOptions,
};
use serde::Deserialize;
use std::path::PathBuf;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawProgram {
    file: Option<Spanned<String>>,
    circle: Option<Spanned<RawCircle>>,
    polyline: Option<Spanned<RawPolyline>>,
    /// The ISO 230-4 circular test as the program (src/scenario/ballbar.rs).
    ballbar: Option<Spanned<RawBallbar>>,
    /// Path speed of the built-in paths (mm/s).
    feed_mm_s: Option<Num>,
    /// How a program file's feed applies to moves with rotary axes.
    #[serde(default)]
    feed_rule: RawFeedRule,
    /// HPGL: pen heights (mm), lenient decoding of damaged files, pen-up travel optimisation.
    pen_up_z_mm: Option<f64>,
    pen_down_z_mm: Option<f64>,
    #[serde(default)]
    lenient: bool,
    #[serde(default)]
    optimise_pen_up: bool,
    /// HPGL: plot only this page (from 1); default every page, one over another.
    page: Option<Spanned<i64>>,
    /// CL data: the CAM system whose conventions apply; default the one its header names.
    cl_writer: Option<Spanned<String>>,
    /// Where the machine is before the program: it reaches the program's first point by an
    /// untraced straight move from here (mm), as a real machine comes from home.
    approach_from_mm: Option<Spanned<[f64; 3]>>,
    /// Speed of that move (mm/s); default: the planner's rapid speed.
    approach_feed_mm_s: Option<Num>,
    /// Program zero, as G54 sets it: its machine coordinates along X, Y, Z (mm); default:
    /// where the tool is with every axis at its home.
    work_offset_mm: Option<Spanned<[f64; 3]>>,
    /// G-code: a LinuxCNC tool table file (lengths in mm) and the G28/G30 positions (mm).
    tool_table: Option<Spanned<String>>,
    g28_home_mm: Option<[f64; 3]>,
    g30_home_mm: Option<[f64; 3]>,
    /// What the program's words mean: joint coordinates (default) or the tool tip on the part
    /// with the rotary axes' angles (G43.4, TRAORI, TCPM).
    kinematics: Option<Spanned<String>>,
    /// How far the tool tip may stray from the programmed path in a tool-tip program (mm).
    tcp_tolerance_mm: Option<Num>,
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "kebab-case")]
enum RawFeedRule {
    #[default]
    Linuxcnc,
    EuclideanAllAxes,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCircle {
    center_mm: [f64; 2],
    radius_mm: f64,
    #[serde(default)]
    start_angle_deg: f64,
    #[serde(default)]
    direction: Direction,
    #[serde(default)]
    z_mm: f64,
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum Direction {
    #[default]
    Ccw,
    Cw,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBallbar {
    radius_mm: f64,
    feed_mm_min: f64,
    #[serde(default)]
    plane: crate::scenario::BallbarPlane,
    center_mm: Option<[f64; 3]>,
    #[serde(default = "default_overshoot")]
    overshoot_deg: f64,
}

fn default_overshoot() -> f64 {
    45.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPolyline {
    points_mm: Vec<[f64; 3]>,
}

/// What a program's X Y Z and rotary words mean.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProgramKinematics {
    /// Joint coordinates of the machine's axes (LinuxCNC's trivial kinematics).
    Joint,
    /// X Y Z: the tool tip in part coordinates; rotary words: the axes' angles. The tip is
    /// held within `tolerance` (m) of the programmed path while the rotary axes turn.
    ToolTip {
        /// Largest distance of the tip from the programmed path (m).
        tolerance: f64,
    },
}

/// Where the program comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ProgramSource {
    /// The built-in circle (`[program] circle = { … }`).
    Circle(CircleSpec),
    /// The built-in polyline (`[program] polyline = { … }`).
    Polyline(PolylineSpec),
    /// The ISO 230-4 circular test (`cncsim ballbar`'s program): its figures join the metrics
    /// under `ballbar`.
    Ballbar(crate::scenario::BallbarSpec),
    /// The reader settings are boxed: with the G-code tool table they outweigh the others.
    File {
        /// The program file, resolved against the scenario file's folder.
        path: PathBuf,
        /// How to read it (G-code, HPGL or APT settings, tool table, feed rule).
        options: Box<ReadOptions>,
    },
}

/// The machine's way to the program: a straight move from `from` at `speed`, run before the
/// settle and not traced, identically in the physics and the analytic model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach {
    /// Start point in program coordinates (m).
    pub from: [f64; 3],
    /// Path speed (m/s).
    pub speed: f64,
}

/// The `[program]` section, SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgramSettings {
    /// Where the program comes from.
    pub source: ProgramSource,
    /// Start of the untraced approach to the first point (m), where one is asked for.
    pub approach_from: Option<[f64; 3]>,
    /// Its speed (m/s); `None`: the planner's rapid speed.
    pub approach_speed: Option<f64>,
    /// Machine coordinates of program zero along X, Y, Z (m): the work offset (G54).
    pub work_offset: [f64; 3],
    /// What the program's words mean, and where that was said.
    pub kinematics: ProgramKinematics,
    /// Where `kinematics` is set, if it is.
    pub kinematics_at: Option<LineColumn>,
    /// Where the `[program]` table is.
    pub at: Option<LineColumn>,
}

impl TryFrom<InFile<'_, &RawProgram>> for ProgramSettings {
    type Error = FileError;

    fn try_from(InFile { raw: p, file }: InFile<'_, &RawProgram>) -> Result<Self, FileError> {
        let count = p.file.is_some() as u8
            + p.circle.is_some() as u8
            + p.polyline.is_some() as u8
            + p.ballbar.is_some() as u8;
        let at = file.table("[program]");
        if count != 1 {
            return Err(file.error_at(
                at,
                format!(
                    "[program] needs exactly one of `file`, `circle`, `polyline` or `ballbar`, found {count}"
                ),
            ));
        }
        let source = p.source(file, at)?;
        let (approach_from, approach_speed) = match &p.approach_from_mm {
            None => {
                if let Some(f) = &p.approach_feed_mm_s {
                    return Err(
                        file.error(f.span(), "approach_feed_mm_s applies with approach_from_mm")
                    );
                }
                (None, None)
            }
            Some(from) => {
                let from = point_mm(file, from, "approach_from_mm")?;
                let speed = file.ranged_opt(
                    p.approach_feed_mm_s.as_ref(),
                    "approach_feed_mm_s",
                    "mm/s",
                    limits::SPEED_MM_S,
                )?;
                (Some(from), speed.map(|v| v * 1e-3))
            }
        };
        let work_offset = match &p.work_offset_mm {
            None => [0.0; 3],
            Some(offset) => point_mm(file, offset, "work_offset_mm")?,
        };
        if let Some(v) = &p.feed_mm_s {
            warn_if_fast(file, "feed_mm_s", v);
        }
        let (kinematics, kinematics_at) = p.kinematics(file)?;
        Ok(ProgramSettings {
            source,
            approach_from,
            approach_speed,
            work_offset,
            kinematics,
            kinematics_at,
            at,
        })
    }
}

/// A point of the program in mm, within the coordinate limit, to metres.
fn point_mm(
    file: &super::source::Source<'_>,
    v: &Spanned<[f64; 3]>,
    key: &str,
) -> Result<[f64; 3], FileError> {
    let c_mm = limits::COORDINATE_MM;
    let p = v.get_ref();
    if p.iter().all(|x| x.is_finite() && x.abs() <= c_mm) {
        Ok(p.map(|x| x * 1e-3))
    } else {
        Err(file.error(
            v.span(),
            format!("{key} = {p:?}: expected coordinates within ±{c_mm:?} mm"),
        ))
    }
}

impl RawProgram {
    /// Where the program comes from: a file and how to read it, or a built-in path.
    fn source(
        &self,
        file: &super::source::Source<'_>,
        at: Option<LineColumn>,
    ) -> Result<ProgramSource, FileError> {
        let p = self;
        let feed = || self.feed(file, at);
        let c_mm = limits::COORDINATE_MM;
        let source = if let Some(f) = &p.file {
            self.file_source(f, file, at)?
        } else if let Some(c) = &p.circle {
            let v = c.get_ref();
            let nums = [
                v.center_mm[0],
                v.center_mm[1],
                v.radius_mm,
                v.start_angle_deg,
                v.z_mm,
            ];
            let in_reach = nums.iter().all(|x| x.is_finite() && x.abs() <= c_mm);
            if !in_reach || v.radius_mm <= 0.0 {
                return Err(file.error(
                    c.span(),
                    format!("circle: expected numbers within ±{c_mm:?} mm and radius_mm > 0, found center_mm = {:?}, radius_mm = {:?}, start_angle_deg = {:?}, z_mm = {:?}", v.center_mm, v.radius_mm, v.start_angle_deg, v.z_mm),
                ));
            }
            ProgramSource::Circle(CircleSpec {
                center: [v.center_mm[0] * 1e-3, v.center_mm[1] * 1e-3],
                radius: v.radius_mm * 1e-3,
                start_angle: v.start_angle_deg.to_radians(),
                clockwise: matches!(v.direction, Direction::Cw),
                z: v.z_mm * 1e-3,
                speed: feed()?,
            })
        } else if let Some(b) = &p.ballbar {
            if let Some(feed) = &p.feed_mm_s {
                return Err(file.error(
                    feed.span(),
                    "feed_mm_s applies to circle and polyline; the ballbar test takes feed_mm_min",
                ));
            }
            let v = b.get_ref();
            let (lo, hi) = limits::SPEED_MM_S;
            let centre_ok = v
                .center_mm
                .is_none_or(|c| c.iter().all(|x| x.is_finite() && x.abs() <= c_mm));
            let in_range = v.radius_mm > 0.0
                && v.radius_mm <= c_mm
                && v.feed_mm_min >= lo * 60.0
                && v.feed_mm_min <= hi * 60.0
                && v.overshoot_deg > 0.0
                && v.overshoot_deg <= 180.0
                && centre_ok;
            if !in_range {
                return Err(file.error(
                    b.span(),
                    format!("ballbar: expected 0 < radius_mm ≤ {c_mm:?}, feed_mm_min within [{}, {}], 0 < overshoot_deg ≤ 180 and center_mm within ±{c_mm:?} mm, found radius_mm = {:?}, feed_mm_min = {:?}, overshoot_deg = {:?}, center_mm = {:?}", lo * 60.0, hi * 60.0, v.radius_mm, v.feed_mm_min, v.overshoot_deg, v.center_mm),
                ));
            }
            ProgramSource::Ballbar(crate::scenario::BallbarSpec {
                radius: v.radius_mm * 1e-3,
                feed: v.feed_mm_min / 60e3,
                plane: v.plane.into(),
                centre: v.center_mm.map(|c| c.map(|x| x * 1e-3)),
                overshoot: v.overshoot_deg.to_radians(),
            })
        } else {
            let pl = p.polyline.as_ref().expect("counted above");
            let pts = &pl.get_ref().points_mm;
            if pts.len() < 2
                || !pts
                    .iter()
                    .flatten()
                    .all(|x| x.is_finite() && x.abs() <= c_mm)
            {
                return Err(file.error(
                    pl.span(),
                    format!(
                        "polyline: expected at least 2 points with coordinates within ±{c_mm:?} mm, found {} points",
                        pts.len()
                    ),
                ));
            }
            ProgramSource::Polyline(PolylineSpec {
                points: pts.iter().map(|p| p.map(|v| v * 1e-3)).collect(),
                speed: feed()?,
            })
        };
        Ok(source)
    }

    /// The path speed of the built-in paths (m/s).
    fn feed(
        &self,
        file: &super::source::Source<'_>,
        at: Option<LineColumn>,
    ) -> Result<f64, FileError> {
        match &self.feed_mm_s {
            Some(v) => Ok(file.ranged(v, "feed_mm_s", "mm/s", limits::SPEED_MM_S)? * 1e-3),
            None => Err(file.error_at(at, "[program] feed_mm_s is required for a built-in path")),
        }
    }

    /// A program file and how to read it: G-code, HPGL and CL reader settings, tool table.
    fn file_source(
        &self,
        f: &Spanned<String>,
        file: &super::source::Source<'_>,
        at: Option<LineColumn>,
    ) -> Result<ProgramSource, FileError> {
        let p = self;
        let c_mm = limits::COORDINATE_MM;
        let path = file.resolve(f.get_ref());
        if !path.is_file() {
            return Err(file.error(
                f.span(),
                format!(
                    "program file '{}' not found (looked for {})",
                    f.get_ref(),
                    path.display()
                ),
            ));
        }
        let mut options = ReadOptions {
            feed_rule: match p.feed_rule {
                RawFeedRule::Linuxcnc => FeedRule::LinuxCnc,
                RawFeedRule::EuclideanAllAxes => FeedRule::EuclideanAllAxes,
            },
            ..ReadOptions::default()
        };
        for (value, target) in [
            (p.pen_up_z_mm, &mut options.hpgl.pen_up_z),
            (p.pen_down_z_mm, &mut options.hpgl.pen_down_z),
        ] {
            if let Some(v) = value {
                check_range("pen height", v, "mm", -c_mm, c_mm)
                    .map_err(|m| file.error_at(at, m))?;
                *target = v * 1e-3;
            }
        }
        options.hpgl.lenient = p.lenient;
        options.hpgl.optimise_pen_up = p.optimise_pen_up;
        // With a file, feed_mm_s is the feed of CL data that programs no FEDRAT (the
        // reader refuses it for G-code and HPGL, which program their own).
        if p.feed_mm_s.is_some() {
            options.apt.default_feed = Some(self.feed(file, at)?);
        }
        if let Some(name) = &p.cl_writer {
            options.apt.writer = Some(ClWriter::from_name(name.get_ref()).ok_or_else(|| {
                file.error(
                    name.span(),
                    format!(
                        "cl_writer: expected one of {}, found '{}'",
                        ClWriter::names(),
                        name.get_ref()
                    ),
                )
            })?);
        }
        if let Some(page) = &p.page {
            let n = *page.get_ref();
            options.hpgl.page = Some(u32::try_from(n).ok().filter(|&n| n >= 1).ok_or_else(|| {
                file.error(
                    page.span(),
                    format!("page: expected a page number from 1 (pages are counted at each PG, FR, AF, AH), found {n}"),
                )
            })?);
        }
        if let Some(table) = &p.tool_table {
            let table_path = file.resolve(table.get_ref());
            let text = std::fs::read_to_string(&table_path).map_err(|error| {
                file.error(
                    table.span(),
                    format!("tool table '{}': {error}", table_path.display()),
                )
            })?;
            options.gcode.tools = parse_tool_table(&text, &table_path, LengthUnit::Millimetre)
                .map_err(|errors| file.error(table.span(), errors.to_string()))?;
        }
        for (value, target, key) in [
            (p.g28_home_mm, &mut options.gcode.g28_home, "g28_home_mm"),
            (p.g30_home_mm, &mut options.gcode.g30_home, "g30_home_mm"),
        ] {
            if let Some(home) = value {
                if !home.iter().all(|v| v.is_finite()) {
                    return Err(file.error_at(at, format!("{key}: expected finite numbers")));
                }
                target.linear = home.map(|v| v * 1e-3);
            }
        }
        Ok(ProgramSource::File {
            path,
            options: Box::new(options),
        })
    }

    /// What the program's words mean, and where that is said.
    fn kinematics(
        &self,
        file: &super::source::Source<'_>,
    ) -> Result<(ProgramKinematics, Option<LineColumn>), FileError> {
        let p = self;
        let kinematics_at = p.kinematics.as_ref().and_then(|k| file.place(k.span()));
        let kinematics = match p.kinematics.as_ref().map(|k| (k.get_ref().as_str(), k.span())) {
            None | Some(("joint", _)) => {
                if let Some(t) = &p.tcp_tolerance_mm {
                    return Err(file.error(t.span(), "tcp_tolerance_mm applies with kinematics = \"tcp\""));
                }
                ProgramKinematics::Joint
            }
            Some(("tcp", _)) => ProgramKinematics::ToolTip {
                tolerance: file
                    .ranged_opt(p.tcp_tolerance_mm.as_ref(), "tcp_tolerance_mm", "mm", (1e-6, 1.0))?
                    .unwrap_or(1e-3)
                    * 1e-3,
            },
            Some((other, span)) => {
                return Err(file.error(
                    span,
                    format!("kinematics: expected \"joint\" (the words are joint coordinates) or \"tcp\" (X Y Z the tool tip on the part), found '{other}'"),
                ))
            }
        };
        Ok((kinematics, kinematics_at))
    }
}

/// A speed above what few machines reach loads with a warning at its place.
pub(super) fn warn_if_fast(file: &super::source::Source<'_>, key: &str, v: &Num) {
    if *v.get_ref() > limits::SUSPECT_SPEED_MM_S {
        file.warn(file.error(
            v.span(),
            format!(
                "{key} = {:?} mm/s is more than {:?} mm/s: few machines move that fast",
                v.get_ref(),
                limits::SUSPECT_SPEED_MM_S
            ),
        ));
    }
}
