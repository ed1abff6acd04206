//! The jerk-limited planner on programs of CAM character (tangent-arc spirals, chains of 1 mm
//! lines on a smooth curve, a helix, a 5-axis chain on the A-C mill): limits are kept (third
//! differences of the sampled positions), programmed points stay within the corner tolerance at
//! the tool tip on the workpiece, and the cycle time is compared with the time-optimal,
//! acceleration-limited bound of the same geometry and programmed feeds computed by TOPP-RA (the
//! oracle).
//!
//! The bounds for the committed programs are stored in `tests/fixtures/plan/toppra_bounds.json`
//! and always checked. Where `toppra` is importable (`CNCSIM_PYTHON`, else `python3`), the bound
//! is computed live and must agree with the fixture; under `CNCSIM_REQUIRE_ORACLES=1` a missing
//! `toppra` fails the test. `CNCSIM_WRITE_FIXTURES=1` rewrites the fixture from the live oracle.
//!
//! LinuxCNC's own performance programs (`trajectory-planner/circular-arcs/nc_files/performance/`
//! under the `tests/` directory of its Debian source tarball, which `CNCSIM_LINUXCNC_CORPUS`
//! names) are checked live when that and toppra are present (required under
//! `CNCSIM_REQUIRE_ORACLES=1`).

mod common;
#[path = "common/toppra.rs"]
mod toppra;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use cncsim::kinematics::{tool_in_workpiece, AxisMap};
use cncsim::machine::Machine;
use cncsim::plan::{
    jerk_limited_plans, tool_lever_arms, AxisLimits, AxisPath, AxisSpec, BlendChoice, Plan,
    PlanSettings, Planner,
};
use cncsim::program::{read_program, Program, ReadOptions};
use common::{assert_within_limits, fine};
use nalgebra::Vector3;

/// The limits: 200 mm/s, 2000 mm/s² on every axis (deg for rotary axes), G64 P0.05.
const VELOCITY: f64 = 200.0;
const ACCELERATION: f64 = 2000.0;
const TOLERANCE: f64 = 0.05e-3;
/// The oracle's geometry: the planned path at points at most this far apart (m).
const ORACLE_STEP: f64 = 1e-4;

struct Case {
    file: PathBuf,
    machine: &'static str,
    jerk: f64,
    /// LinuxCNC's G64 Q (m), overriding the program's (zero: none).
    naive_cam: Option<f64>,
    /// Largest accepted ratio of cncsim's cycle time to the bound (measured, rounded up).
    ceiling: f64,
}

impl Case {
    fn key(&self) -> String {
        let name = self.file.file_name().unwrap().to_string_lossy();
        format!("{name} jerk {:.0e}", self.jerk)
    }
}

fn fixture(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/plan")
        .join(file)
}

/// The committed programs, each at a low and a high jerk limit (mm/s³), every line as
/// programmed (`curve_lines_1mm.ngc`'s own G64 Q0.02 turned off, as in the table of docs/planning.md).
fn committed_cases() -> Vec<Case> {
    let case = |file: &str, machine, jerk, ceiling| Case {
        file: fixture(file),
        machine,
        jerk,
        naive_cam: Some(0.0),
        ceiling,
    };
    vec![
        case("spiral_tangent_arcs.ngc", "xyz_table", 5e4, 1.45),
        case("spiral_tangent_arcs.ngc", "xyz_table", 1e6, 1.05),
        case("curve_lines_1mm.ngc", "xyz_table", 5e4, 1.75),
        case("curve_lines_1mm.ngc", "xyz_table", 1e6, 1.2),
        case("helix_chain.ngc", "xyz_table", 5e4, 1.2),
        case("helix_chain.ngc", "xyz_table", 1e6, 1.05),
        case("five_axis_chain.ngc", "ac_mill", 5e4, 1.15),
        case("five_axis_chain.ngc", "ac_mill", 1e6, 1.05),
    ]
}

struct Planned {
    /// Each motion's machine-axis path and its plan.
    plans: Vec<(AxisPath, Plan)>,
    axes: Vec<AxisSpec>,
    program: Program,
    machine: Machine,
    map: AxisMap,
}

fn plan_case(case: &Case) -> Planned {
    let urdf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("models")
        .join(format!("{}.urdf", case.machine));
    let machine = Machine::load(&urdf).unwrap();
    let map = AxisMap::new(&machine).unwrap();
    let program = read_program(&case.file, &ReadOptions::default())
        .unwrap_or_else(|e| panic!("{}: {e}", case.file.display()));
    let axes = common::uniform_axes(&machine, VELOCITY, ACCELERATION, case.jerk);
    let settings = PlanSettings {
        planner: Planner::JerkLimited {
            limits: axes.iter().map(|a| a.limits).collect(),
        },
        period: 1e-3,
        rapid_speed: 0.05,
        blend: BlendChoice::Continuous {
            tolerance: Some(TOLERANCE),
        },
        axis_names: axes.iter().map(|a| a.name.clone()).collect(),
        naive_cam_tolerance: case.naive_cam,
        tool_lever_arms: tool_lever_arms(&machine, &program, &map),
    };
    let plans = jerk_limited_plans(&program, &map, &settings)
        .unwrap()
        .expect("a jerk-limited planner");
    Planned {
        plans,
        axes,
        program,
        machine,
        map,
    }
}

fn duration(planned: &Planned) -> f64 {
    planned.plans.iter().map(|(_, p)| p.duration()).sum()
}

/// Limits from third differences of finely sampled positions.
fn assert_limits_kept(case: &Case, planned: &Planned) {
    for (_, plan) in &planned.plans {
        assert_within_limits(&fine(plan), &planned.axes, 1e-9);
    }
    eprintln!("{}: limits kept", case.key());
}

/// Every programmed point lies within the corner tolerance of the planned path, measured at
/// the tool tip on the workpiece (G64 Q points within Q + P).
fn assert_points_kept(case: &Case, planned: &Planned) {
    let m = &planned.machine;
    let tip = |q: &[f64]| tool_in_workpiece(m, q).coords;
    let path: Vec<Vector3<f64>> = planned
        .plans
        .iter()
        .flat_map(|(path, plan)| plan.chain_geometry(path, 1e-5))
        .flat_map(|chain| chain.points)
        .map(|q| tip(&q))
        .collect();
    let mut q = vec![0.0; planned.map.axes()];
    // Plus 0.1 µm for the chords of the path's 10 µm polyline.
    let allowed = TOLERANCE + case.naive_cam.unwrap_or(0.0) + 1e-7;
    let mut worst: f64 = 0.0;
    for mv in &planned.program.moves {
        planned.map.machine_axes(&mv.end, &mut q);
        let point = tip(&q);
        let d = path
            .windows(2)
            .map(|w| distance_to_segment(&point, &w[0], &w[1]))
            .fold(f64::INFINITY, f64::min);
        assert!(
            d <= allowed,
            "{}: line {}: programmed point {:?} mm is {:.2} µm from the path (allowed {:.2} µm)",
            case.key(),
            mv.span.line,
            (point * 1e3).as_slice(),
            d * 1e6,
            allowed * 1e6
        );
        worst = worst.max(d);
    }
    eprintln!(
        "{}: programmed points within {:.2} µm of the path at the tool tip",
        case.key(),
        worst * 1e6
    );
}

fn distance_to_segment(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let ab = b - a;
    let t = if ab.norm_squared() > 0.0 {
        ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + t * ab - p).norm()
}

/// cncsim's cycle time is no shorter than the bound (less 1 % for the oracle's discretisation)
/// and at most `ceiling` times it.
fn assert_ratio(case: &Case, planned: f64, bound: f64) {
    let ratio = planned / bound;
    eprintln!(
        "{}: cncsim {planned:.3} s, TOPP-RA {bound:.3} s, ratio {ratio:.3}",
        case.key()
    );
    assert!(
        ratio >= 0.99,
        "{}: {planned} s beats the time-optimal bound {bound} s",
        case.key()
    );
    assert!(
        ratio <= case.ceiling,
        "{}: {planned:.3} s is {ratio:.3} × the bound {bound:.3} s (at most {})",
        case.key(),
        case.ceiling
    );
}

fn bounds_fixture() -> PathBuf {
    fixture("toppra_bounds.json")
}

fn stored_bounds() -> BTreeMap<String, f64> {
    let text = std::fs::read_to_string(bounds_fixture()).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn live_bound(python: &str, planned: &Planned) -> f64 {
    let limits: Vec<AxisLimits> = planned.axes.iter().map(|a| a.limits).collect();
    let problem = toppra::problem_json(&planned.plans, &limits, ORACLE_STEP);
    toppra::toppra_bound(python, &problem).unwrap()
}

/// The Python with toppra, or `None` (a failure under `CNCSIM_REQUIRE_ORACLES=1`).
fn oracle() -> Option<String> {
    let python = toppra::toppra_python();
    assert!(
        python.is_some() || !toppra::oracles_required(),
        "CNCSIM_REQUIRE_ORACLES=1 but toppra is not importable (pip install toppra; \
         CNCSIM_PYTHON names the interpreter)"
    );
    python
}

#[test]
fn committed_programs_keep_limits_and_points_near_the_toppra_bound() {
    let stored = stored_bounds();
    for case in committed_cases() {
        let planned = plan_case(&case);
        assert_limits_kept(&case, &planned);
        assert_points_kept(&case, &planned);
        let bound = *stored
            .get(&case.key())
            .unwrap_or_else(|| panic!("no stored bound for {}", case.key()));
        assert_ratio(&case, duration(&planned), bound);
    }
}

#[test]
fn live_toppra_agrees_with_the_stored_bounds() {
    let Some(python) = oracle() else {
        eprintln!("toppra not importable: live oracle skipped (the stored bounds are checked)");
        return;
    };
    let write = std::env::var("CNCSIM_WRITE_FIXTURES").is_ok_and(|v| v == "1");
    let stored = if write {
        BTreeMap::new()
    } else {
        stored_bounds()
    };
    let mut live = BTreeMap::new();
    for case in committed_cases() {
        let bound = live_bound(&python, &plan_case(&case));
        if !write {
            let expected = stored[&case.key()];
            assert!(
                (bound - expected).abs() <= 1e-3 * expected,
                "{}: live TOPP-RA bound {bound} s, stored {expected} s",
                case.key()
            );
        }
        live.insert(case.key(), bound);
    }
    if write {
        let text = serde_json::to_string_pretty(&live).unwrap();
        std::fs::write(bounds_fixture(), text + "\n").unwrap();
    }
}

/// The oracle holds the programmed feed: two collinear lines at 3000 and 6000 mm/min, joined
/// (G64), on the XYZ table with the limits above. Time-optimal with acceleration a = 2000
/// mm/s² along X: up to 50 mm/s in 0.025 s (0.625 mm), 50 mm/s to the junction at 50 mm, up
/// to 100 mm/s in 0.025 s (1.875 mm), cruise, down from 100 mm/s in 0.05 s (2.5 mm):
/// 0.025 + 49.375/50 + 0.025 + 45.625/100 + 0.05 = 1.54375 s. Without the feeds the bound
/// would be 2·√(L/a) = 0.447 s (the axis speed limit of 200 mm/s is never reached).
#[test]
fn toppra_bound_holds_the_programmed_feed() {
    let Some(python) = oracle() else {
        eprintln!("toppra not importable: oracle check skipped");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("two_feeds.ngc");
    std::fs::write(
        &file,
        "G21 G90 G64 P0.05\nG1 X50 F3000\nG1 X100 F6000\nM2\n",
    )
    .unwrap();
    let case = Case {
        file,
        machine: "xyz_table",
        jerk: 1e8,
        naive_cam: None,
        ceiling: 1.01,
    };
    let planned = plan_case(&case);
    let bound = live_bound(&python, &planned);
    let exact = 1.54375;
    eprintln!("two feeds: TOPP-RA {bound:.5} s, exact {exact} s");
    assert!(
        (bound - exact).abs() <= 5e-4 * exact,
        "TOPP-RA bound {bound} s, time-optimal with the feeds {exact} s"
    );
    assert_ratio(&case, duration(&planned), bound);
}

/// A chain longer than the planner's look-ahead, planned window by window with a handoff: a
/// 6 500-line CAM raster (1 mm lines on a curve in rows of 1000, all joined, fed faster than
/// the axes allow) against the live bound. Measured: 1.03 at jerk 5·10⁴, 1.00 at 10⁶.
#[test]
fn a_chain_longer_than_the_look_ahead_stays_near_the_toppra_bound() {
    let Some(python) = oracle() else {
        eprintln!("toppra not importable: oracle check skipped");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("raster_6500.ngc");
    let text = format!(
        "G21 G90 G64 P0.05 Q0\nG0 X0 Y0 Z1\nF60000\n{}M2\n",
        common::raster_gcode(6500)
    );
    std::fs::write(&file, text).unwrap();
    for (jerk, ceiling) in [(5e4, 1.04), (1e6, 1.01)] {
        let case = Case {
            file: file.clone(),
            machine: "xyz_table",
            jerk,
            naive_cam: Some(0.0),
            ceiling,
        };
        let planned = plan_case(&case);
        let handoffs: usize = planned
            .plans
            .iter()
            .map(|(_, p)| p.look_ahead().handoffs)
            .sum();
        let stops: usize = planned
            .plans
            .iter()
            .map(|(_, p)| p.look_ahead().stops_added)
            .sum();
        assert!(handoffs >= 1, "{}: no handoff", case.key());
        assert_eq!(stops, 0, "{}", case.key());
        assert_limits_kept(&case, &planned);
        assert_ratio(&case, duration(&planned), live_bound(&python, &planned));
    }
}

/// LinuxCNC's trajectory-planner performance programs, with the settings (the line
/// chain with its own G64 Q0.03).
#[test]
fn linuxcnc_performance_programs_against_live_toppra() {
    let dir = std::env::var_os("CNCSIM_LINUXCNC_CORPUS")
        .map(|c| PathBuf::from(c).join("trajectory-planner/circular-arcs/nc_files/performance"));
    let python = oracle();
    let (Some(dir), Some(python)) = (dir, python) else {
        assert!(
            !toppra::oracles_required(),
            "CNCSIM_REQUIRE_ORACLES=1 needs CNCSIM_LINUXCNC_CORPUS (LinuxCNC's tests/ \
             directory) and toppra"
        );
        eprintln!("CNCSIM_LINUXCNC_CORPUS or toppra missing: LinuxCNC programs skipped");
        return;
    };
    let case = |file: &str, jerk, naive_cam, ceiling| Case {
        file: dir.join(file),
        machine: "xyz_table",
        jerk,
        naive_cam,
        ceiling,
    };
    for case in [
        case("spiral-circular-segments.ngc", 5e4, None, 1.3),
        case("spiral-circular-segments.ngc", 1e6, None, 1.1),
        case("line-contouring-xz.ngc", 5e4, Some(0.03e-3), 2.45),
        case("line-contouring-xz.ngc", 1e6, Some(0.03e-3), 1.2),
    ] {
        let planned = plan_case(&case);
        assert_limits_kept(&case, &planned);
        assert_points_kept(&case, &planned);
        assert_ratio(&case, duration(&planned), live_bound(&python, &planned));
    }
}
