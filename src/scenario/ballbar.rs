//! `cncsim ballbar`: the ISO 230-4 circular test on a scenario's machine and controller. The
//! test path (feed-in, a full circle counter-clockwise, one clockwise, each with overshoot
//! arcs, feed-out) replaces the scenario's program and runs through the scenario's planner and
//! servo loop (physics lane); `report::ballbar` reads the trace. See docs/ballbar.md.

use super::assemble::{load_checked_program, machine_for, Assembly, RunError};
use super::run::RunOptions;
use super::{folder_name, ProgramSource, Scenario};
use crate::diagnostics::FileError;
use crate::machine::Machine;
use crate::program::{
    Blend, Feed, FeedRule, Motion, Move, Plane, Position, Program, Span, Spindle,
};
use crate::report::{
    analyse_ballbar, write_polar_plot, BallbarInput, BallbarPass, BallbarReport, BallbarRun,
    ReportError,
};
use crate::sim::Trace;
use nalgebra::Point3;
use std::collections::BTreeMap;
use std::f64::consts::TAU;
use std::path::Path;

/// Radial feed-in onto the circle (m): a ballbar starts compressed and is fed out to its
/// length, as Renishaw's QC20 test does (1.5 mm).
pub const FEED_IN: f64 = 1.5e-3;

/// What `cncsim ballbar` runs: every feed at every radius, in one plane.
#[derive(Debug, Clone, PartialEq)]
pub struct BallbarOptions {
    /// Radii (m).
    pub radii: Vec<f64>,
    /// Feeds (path speed, m/s).
    pub feeds: Vec<f64>,
    /// The plane of the circle.
    pub plane: Plane,
    /// Centre in program coordinates (m, G54); `None`: chosen (see [`ballbar_centre`]).
    pub centre: Option<[f64; 3]>,
    /// Overshoot arc before and after the data (rad, 0 < o ≤ π).
    pub overshoot: f64,
}

/// The plane named on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BallbarPlane {
    /// The XY plane (G17).
    #[default]
    Xy,
    /// The YZ plane (G19).
    Yz,
    /// The ZX plane (G18).
    Zx,
}

impl From<BallbarPlane> for Plane {
    fn from(p: BallbarPlane) -> Plane {
        match p {
            BallbarPlane::Xy => Plane::XY,
            BallbarPlane::Yz => Plane::YZ,
            BallbarPlane::Zx => Plane::ZX,
        }
    }
}

/// Defaults of the test for a scenario: its own circle's radius and feed, else a 100 mm
/// ballbar (the common length) at 1000 mm/min (m, m/s).
pub fn default_radius_and_feed(s: &Scenario) -> (f64, f64) {
    match &s.program.source {
        ProgramSource::Circle(c) => (c.radius, c.speed),
        ProgramSource::Ballbar(b) => (b.radius, b.feed),
        _ => (0.1, 1000.0 / 60e3),
    }
}

/// The plane, centre (program coordinates) and overshoot of a scenario whose program is the
/// test; else the XY plane, no centre given, 45°.
pub fn default_plane_centre_overshoot(s: &Scenario) -> (Plane, Option<[f64; 3]>, f64) {
    match &s.program.source {
        ProgramSource::Ballbar(b) => (b.plane, b.centre, b.overshoot),
        _ => (Plane::XY, None, std::f64::consts::FRAC_PI_4),
    }
}

/// One test as a scenario's program (`[program] ballbar = { … }`), SI.
#[derive(Debug, Clone, PartialEq)]
pub struct BallbarSpec {
    /// Radius of the circle (m).
    pub radius: f64,
    /// Path speed (m/s).
    pub feed: f64,
    /// The plane of the circle.
    pub plane: Plane,
    /// Centre in program coordinates (m); `None`: chosen by [`ballbar_centre`].
    pub centre: Option<[f64; 3]>,
    /// Overshoot arc before and after the data (rad).
    pub overshoot: f64,
}

/// The plane's axes: indices into program X, Y, Z in its own order, and the normal axis.
pub fn plane_axes(plane: Plane) -> ([usize; 2], usize) {
    match plane {
        Plane::XY => ([0, 1], 2),
        Plane::ZX => ([2, 0], 1),
        Plane::YZ => ([1, 2], 0),
    }
}

pub fn plane_name(plane: Plane) -> &'static str {
    match plane {
        Plane::XY => "xy",
        Plane::ZX => "zx",
        Plane::YZ => "yz",
    }
}

const LETTERS: [&str; 3] = ["x", "y", "z"];

/// Travel of each program axis X, Y, Z in machine coordinates (m): from the joint limits
/// through the drive's sign and home (joint = home + sign × coordinate); `None` = unlimited
/// or no such axis.
fn travel(machine: &Machine) -> [Option<[f64; 2]>; 3] {
    let mut out = [None; 3];
    for (l, letter) in LETTERS.iter().enumerate() {
        let Some(i) = machine.axis_index(letter) else {
            continue;
        };
        let axis = &machine.axes[i];
        if let Some([lo, hi]) = machine.joints[axis.joint].limits {
            let sign = f64::from(axis.drive.sign);
            let (a, b) = ((lo - axis.drive.home) / sign, (hi - axis.drive.home) / sign);
            out[l] = Some([a.min(b), a.max(b)]);
        }
    }
    out
}

/// Whether the test path (the circle and its feed-in) about `centre` stays in the travel.
fn fits(
    centre: [f64; 3],
    reach: f64,
    in_plane: [usize; 2],
    travel: &[Option<[f64; 2]>; 3],
) -> bool {
    in_plane.iter().all(|&a| {
        travel[a].is_none_or(|[lo, hi]| {
            centre[a] - reach >= lo - 1e-12 && centre[a] + reach <= hi + 1e-12
        })
    })
}

/// The test's centre (machine coordinates, m): given (in program coordinates, moved by the
/// work offset); else the scenario's own circle's centre or its program's start point, the
/// first of them around which the test fits in the travel; else the middle of the travel.
/// Refused, naming radius and travel, when the test fits nowhere.
pub fn ballbar_centre(
    s: &Scenario,
    machine: &Machine,
    radius: f64,
    plane: Plane,
    given: Option<[f64; 3]>,
) -> Result<[f64; 3], FileError> {
    let (in_plane, normal) = plane_axes(plane);
    for &a in in_plane.iter() {
        if machine.axis_index(LETTERS[a]).is_none() {
            return Err(FileError::new(
                &s.machine,
                None,
                format!(
                    "the ballbar test in the {} plane needs axis {}, which the machine '{}' does not have",
                    plane_name(plane).to_uppercase(),
                    LETTERS[a].to_uppercase(),
                    machine.name
                ),
            ));
        }
    }
    let travel = travel(machine);
    let reach = radius + FEED_IN;
    let offset = s.program.work_offset;
    let shift = |p: [f64; 3]| [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]];
    let describe = || {
        in_plane
            .iter()
            .map(|&a| match travel[a] {
                Some([lo, hi]) => format!(
                    "{} {:.3} … {:.3} mm",
                    LETTERS[a].to_uppercase(),
                    lo * 1e3,
                    hi * 1e3
                ),
                None => format!("{} unlimited", LETTERS[a].to_uppercase()),
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let refuse = |where_: String| {
        FileError::new(
            &s.path,
            None,
            format!(
                "a ballbar circle of radius {:.3} mm (plus the {:.1} mm feed-in) does not fit the machine's travel ({}) {where_}",
                radius * 1e3,
                FEED_IN * 1e3,
                describe()
            ),
        )
    };
    if let Some(c) = given {
        let c = shift(c);
        return if fits(c, reach, in_plane, &travel) {
            Ok(c)
        } else {
            Err(refuse(format!(
                "about the centre given, ({}) mm in machine coordinates",
                c.map(|v| format!("{:.3}", v * 1e3)).join(", ")
            )))
        };
    }
    let mut candidates = Vec::new();
    if let ProgramSource::Circle(c) = &s.program.source {
        candidates.push(shift([c.center[0], c.center[1], c.z]));
    }
    // (A ballbar program has no start point of its own to offer.)
    if !matches!(s.program.source, ProgramSource::Ballbar(_)) {
        if let Ok(program) = load_checked_program(s, machine) {
            candidates.push(program.start.linear);
        }
    }
    let first = candidates.first().copied();
    let mid = {
        let mut m = first.unwrap_or([0.0; 3]);
        for a in in_plane {
            if let Some([lo, hi]) = travel[a] {
                m[a] = (lo + hi) / 2.0;
            }
        }
        if first.is_none() {
            if let Some([lo, hi]) = travel[normal] {
                m[normal] = (lo + hi) / 2.0;
            }
        }
        m
    };
    candidates.push(mid);
    candidates
        .into_iter()
        .find(|c| fits(*c, reach, in_plane, &travel))
        .ok_or_else(|| refuse("about the program's start point or the middle of the travel".into()))
}

/// The point at `angle` on the circle of `radius` about `centre` in the plane.
fn on_circle(centre: [f64; 3], in_plane: [usize; 2], radius: f64, angle: f64) -> [f64; 3] {
    let mut p = centre;
    p[in_plane[0]] += radius * angle.cos();
    p[in_plane[1]] += radius * angle.sin();
    p
}

/// The test program (machine coordinates): from the feed-in point outside the circle at
/// −o (the overshoot, 45° by default), radially onto the circle; counter-clockwise o + 360° +
/// o; back clockwise the same way; radially out. Data: the 360° from 0° of each direction. Every move stops
/// exactly (the reversals of direction lie in the overshoot arcs).
pub fn ballbar_program(
    centre: [f64; 3],
    radius: f64,
    feed: f64,
    plane: Plane,
    overshoot: f64,
    source: &Path,
) -> Program {
    let (in_plane, _) = plane_axes(plane);
    // Past a half turn each way the arcs would overlap the data twice.
    let overshoot = overshoot.clamp(f64::EPSILON, std::f64::consts::PI);
    let at = |r: f64, a: f64| Position {
        linear: on_circle(centre, in_plane, r, a),
        rotary: [0.0; 3],
    };
    let step = |motion: Motion, end: Position| Move {
        motion,
        end,
        tool_axis: None,
        feed: Feed::PathSpeed(feed),
        feed_rule: FeedRule::LinuxCnc,
        blend: Blend::ExactStop,
        tool_down: None,
        spindle: Spindle::Off,
        span: Span::default(),
    };
    let arc = |clockwise: bool| Motion::Arc {
        center: centre,
        plane,
        clockwise,
        // One extra turn: the overshoot arcs plus the full circle of data.
        turns: 1,
    };
    Program {
        source: source.to_path_buf(),
        start: at(radius + FEED_IN, -overshoot),
        moves: vec![
            step(Motion::Linear, at(radius, -overshoot)),
            step(arc(false), at(radius, overshoot)),
            step(arc(true), at(radius, -overshoot)),
            step(Motion::Linear, at(radius + FEED_IN, -overshoot)),
        ],
        warnings: Vec::new(),
        tools: Vec::new(),
        reading: None,
    }
}

/// Index of the counter-clockwise and clockwise moves of [`ballbar_program`].
const CCW_MOVE: u32 = 1;
const CW_MOVE: u32 = 2;

/// The two directions' 360° of data from a run's trace: the actual tool point (program frame)
/// in the plane, where the commanded point has travelled from the overshoot to a full turn
/// past it along its move.
pub fn ballbar_passes(
    assembly: &Assembly,
    trace: &Trace,
    centre: [f64; 3],
    plane: Plane,
    overshoot: f64,
) -> (BallbarPass, BallbarPass) {
    let (in_plane, _) = plane_axes(plane);
    let machine = &assembly.machine;
    // Machine axis and (sign, home) of each plane axis: commanded joint → machine coordinate.
    let axis: Vec<(usize, f64, f64)> = in_plane
        .iter()
        .map(|&a| {
            let i = machine
                .axis_index(LETTERS[a])
                .expect("checked with the centre");
            let d = &machine.axes[i].drive;
            (i, f64::from(d.sign), d.home)
        })
        .collect();
    let mut passes = [
        BallbarPass {
            clockwise: false,
            ..Default::default()
        },
        BallbarPass {
            clockwise: true,
            ..Default::default()
        },
    ];
    let mut travelled = [0.0f64; 2];
    let mut previous: [Option<f64>; 2] = [None, None];
    for k in 0..trace.len() {
        let which = match trace.segment[k] {
            CCW_MOVE => 0,
            CW_MOVE => 1,
            _ => continue,
        };
        let commanded: Vec<f64> = axis
            .iter()
            .map(|&(i, sign, home)| (Trace::at(&trace.commanded, trace.axes, k, i) - home) / sign)
            .collect();
        let angle = (commanded[1] - centre[in_plane[1]]).atan2(commanded[0] - centre[in_plane[0]]);
        if let Some(p) = previous[which] {
            let mut d = (angle - p).rem_euclid(TAU);
            if d > std::f64::consts::PI {
                d -= TAU;
            }
            travelled[which] += d.abs();
        }
        previous[which] = Some(angle);
        if travelled[which] < overshoot || travelled[which] >= overshoot + TAU {
            continue;
        }
        let tool = assembly
            .frame
            .program_point(&Point3::from(trace.tool_point[k]));
        let pass = &mut passes[which];
        pass.time.push(trace.time[k]);
        pass.point.push([tool[in_plane[0]], tool[in_plane[1]]]);
    }
    let [ccw, cw] = passes;
    (ccw, cw)
}

fn number(v: f64) -> String {
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// The ballbar figures of a run of a scenario whose program is the test: the passes from
/// its trace, the analysis, and `polar.png` and `polar.csv` written into `out_dir` (listed in
/// the run's `files`) when the run writes files. Called by the run itself (`Assembly::run`), so `run`, `check`, `ab`,
/// `sweep` and `cncsim ballbar` all report the same figures.
pub(crate) fn ballbar_of_run(
    assembly: &Assembly,
    spec: &BallbarSpec,
    trace: &Trace,
    metrics: &crate::report::Metrics,
    completed: bool,
    out_dir: Option<&Path>,
) -> Result<BallbarRun, RunError> {
    // The test's centre is the centre of its arcs, as planned.
    let centre = assembly
        .program()
        .moves
        .iter()
        .find_map(|m| match m.motion {
            Motion::Arc { center, .. } => Some(center),
            _ => None,
        })
        .expect("a ballbar program has its arcs");
    let (ccw, cw) = ballbar_passes(assembly, trace, centre, spec.plane, spec.overshoot);
    let (in_plane, _) = plane_axes(spec.plane);
    let stalls: BTreeMap<String, usize> = metrics
        .axes
        .iter()
        .map(|(name, a)| (name.clone(), a.stick_slip_stalls))
        .collect();
    let input = BallbarInput {
        scenario: assembly.scenario.name.clone(),
        axes: in_plane.map(|a| LETTERS[a].to_string()),
        plane: plane_name(spec.plane).into(),
        centre: in_plane.map(|a| centre[a]),
        centre_3d: centre,
        radius: spec.radius,
        feed: spec.feed,
        period: assembly.scenario.timing.servo_period,
        ccw,
        cw,
        stalls,
        completed,
    };
    if input.ccw.point.len() < 16 || input.cw.point.len() < 16 {
        let message = if completed {
            "the ballbar run traced too few samples of a circle (feed too high for the servo period?)"
        } else {
            "the ballbar run stopped before it traced both circles"
        };
        return Err(FileError::new(&assembly.scenario.path, None, message).into());
    }
    let mut run = analyse_ballbar(&input);
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| RunError::Report(ReportError::Io { path, source })
    };
    if let Some(out_dir) = out_dir {
        let polar = out_dir.join("polar.png");
        write_polar_plot(&polar, &run)?;
        let csv = out_dir.join("polar.csv");
        std::fs::write(&csv, run.polar_csv()).map_err(io(&csv))?;
        run.files = vec![polar, csv];
    }
    Ok(run)
}

/// Runs the test for every feed at every radius; each run's own outputs (metrics.json with
/// the ballbar figures under `ballbar`, trace, recording as the scenario asks, polar.png,
/// polar.csv) go to `out/F<feed>_R<radius>/`, `ballbar.json` and the polar plots' recording
/// `ballbar.rrd` to `out`.
pub fn run_ballbar(
    s: &Scenario,
    options: &BallbarOptions,
    out: &Path,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<BallbarReport, RunError> {
    let machine = machine_for(s)?;
    let mut report = BallbarReport {
        scenario: s.name.clone(),
        runs: Vec::new(),
    };
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| RunError::Report(ReportError::Io { path, source })
    };
    std::fs::create_dir_all(out).map_err(io(out))?;
    // Each radius's centre, chosen on the scenario as written (its circle, its program's
    // start), back in program coordinates; refused before anything runs if one does not fit.
    let offset = s.program.work_offset;
    let centres = options
        .radii
        .iter()
        .map(|&radius| {
            let c = ballbar_centre(s, &machine, radius, options.plane, options.centre)?;
            Ok([c[0] - offset[0], c[1] - offset[1], c[2] - offset[2]])
        })
        .collect::<Result<Vec<_>, FileError>>()?;
    for (&radius, &centre) in options.radii.iter().zip(&centres) {
        for &feed in &options.feeds {
            let mut scenario = s.clone();
            let label = format!("F{}_R{}", number(feed * 60e3), number(radius * 1e3));
            scenario.program.source = ProgramSource::Ballbar(BallbarSpec {
                radius,
                feed,
                plane: options.plane,
                centre: Some(centre),
                overshoot: options.overshoot.clamp(f64::EPSILON, std::f64::consts::PI),
            });
            // The scenario's bounds are for its own program, but for those on ballbar
            // figures; the test runs the physics lane.
            scenario.expect.retain(|e| e.metric.starts_with("ballbar."));
            scenario.analytic = None;
            let assembly = Assembly::with_machine(&scenario, machine.clone())?;
            let dir = out.join(folder_name(&label));
            let run = assembly.run(RunOptions::write_to(&dir).progress(&mut *progress))?;
            let mut ballbar = run
                .ballbar
                .expect("a ballbar program's run has its figures");
            ballbar.scenario = s.name.clone();
            // The run's files, its polar plot and data among them.
            ballbar.files = run.files.clone();
            ballbar.breaches = run.verdict.breaches.iter().map(|b| b.to_string()).collect();
            let stopped = !ballbar.completed;
            report.runs.push(ballbar);
            if stopped {
                break;
            }
        }
    }
    let json = out.join("ballbar.json");
    std::fs::write(&json, report.json()).map_err(io(&json))?;
    report.write_recording(&out.join("ballbar.rrd"))?;
    Ok(report)
}

/// `cncsim ballbar`: the test's runs, as the command reports them.
#[derive(Debug, Clone)]
pub struct BallbarOutput {
    /// The analysed runs, one per radius and feed.
    pub report: BallbarReport,
    /// The scenario file.
    pub path: std::path::PathBuf,
    /// Where `ballbar.json` and `ballbar.rrd` went.
    pub out: std::path::PathBuf,
}

impl crate::command::Report for BallbarOutput {
    /// Every run's polar plot, `ballbar.json` and the polar plots' recording `ballbar.rrd`
    /// (written as the runs went).
    fn write(&self) -> Result<Vec<std::path::PathBuf>, crate::command::WriteError> {
        let plots = (self.report.runs.iter())
            .flat_map(|run| run.files.iter())
            .filter(|f| f.extension().is_some_and(|e| e == "png"))
            .cloned();
        let mut files: Vec<_> = plots.collect();
        files.extend([self.out.join("ballbar.json"), self.out.join("ballbar.rrd")]);
        Ok(files)
    }

    fn text(&self) -> String {
        self.report.text()
    }

    fn json(&self) -> Option<serde_json::Value> {
        serde_json::from_str(&self.report.json()).ok()
    }

    fn ending(&self) -> crate::command::Ending {
        let path = self.path.display();
        let runs = &self.report.runs;
        let failure = if runs.iter().any(|r| !r.completed) {
            Some(format!(
                "{path}: a ballbar run stopped early (its figures are of what ran)"
            ))
        } else if runs.iter().any(|r| !r.breaches.is_empty()) {
            Some(format!(
                "{path}: a ballbar figure breaches an [expect] bound"
            ))
        } else {
            None
        };
        match failure {
            Some(message) => crate::command::Ending::Failed(Some(message)),
            None => crate::command::Ending::Done,
        }
    }
}
