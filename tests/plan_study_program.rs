//! The 5-axis study's program (docs/sources.md §3.3) on a plain five-axis Cartesian machine with
//! per-axis limits v = 150, a = 1000, j = 1000 in mm and degree units.

mod common;

use std::f64::consts::PI;

use cncsim::plan::{
    plan, AxisKind, AxisLimits, AxisPath, AxisSpec, Blend, Geometry, PathSegment, Plan,
};
use common::*;

/// Machine coordinates X Y Z (mm) A C (deg) of points 1–5; point 0 is the origin.
const TABLE: [[f64; 5]; 5] = [
    [20.0, 10.0, 30.0, 10.0, 50.0],
    [-40.0, 20.0, 0.0, 10.0, 30.0],
    [10.0, 30.0, -30.0, 20.0, 10.0],
    [50.0, 40.0, 0.0, 20.0, -10.0],
    [60.0, 50.0, 30.0, 20.0, -30.0],
];

/// Segment durations measured in exact stop (s), each the jerk-limited closed form
/// 4·(L/2J)^(1/3) of the axis with the largest displacement (in its own units).
const EXACT_STOP_SEGMENTS: [f64; 5] = [1.169607, 1.242893, 1.169607, 1.085767, 0.986485];
const EXACT_STOP_TOTAL: f64 = 5.654359;

fn axes() -> Vec<AxisSpec> {
    [
        ("x", AxisKind::Linear),
        ("y", AxisKind::Linear),
        ("z", AxisKind::Linear),
        ("a", AxisKind::Rotary),
        ("c", AxisKind::Rotary),
    ]
    .iter()
    .map(|&(name, kind)| AxisSpec {
        name: name.into(),
        kind,
        limits: AxisLimits::from_program_units(kind, 150.0, 1000.0, 1000.0),
    })
    .collect()
}

fn to_si(p: &[f64; 5]) -> Vec<f64> {
    let deg = PI / 180.0;
    vec![
        p[0] * 1e-3,
        p[1] * 1e-3,
        p[2] * 1e-3,
        p[3] * deg,
        p[4] * deg,
    ]
}

/// F = 150 mm/s applied to the Euclidean norm of all axis deltas in mm and degrees (the
/// study's rule): weight 1 on the linear axes (m), (1e-3 m/mm)/(π/180 rad/deg) on the rotary.
fn study_path(blend: Blend) -> AxisPath {
    let rotary = 1e-3 / (PI / 180.0);
    AxisPath {
        axes: axes(),
        start: vec![0.0; 5],
        segments: TABLE
            .iter()
            .enumerate()
            .map(|(k, p)| PathSegment {
                geometry: Geometry::Line { end: to_si(p) },
                feed: Some(0.15),
                feed_metric: vec![1.0, 1.0, 1.0, rotary, rotary],
                blend,
                source_index: k as u32 + 1,
            })
            .collect(),
        tool_lever_arms: Vec::new(),
    }
}

fn check_stream(plan: &Plan) {
    let axes = axes();
    assert_within_limits(&fine(plan), &axes, 1e-9);
    // At the servo rate (1 kHz) in program units: nothing above 150 / 1000 / 1000.
    let sp = plan.sample(1e-3);
    for (axis, e) in axes
        .iter()
        .zip(cncsim::plan::finite_difference_extremes(&sp))
    {
        let k = axis.kind.program_units_per_si();
        assert!(e.velocity * k <= 150.0 * (1.0 + 1e-9));
        assert!(e.acceleration * k <= 1000.0 * (1.0 + 1e-9));
        assert!(
            e.jerk * k <= 1000.0 * (1.0 + 1e-6),
            "{}: {}",
            axis.name,
            e.jerk * k
        );
    }
}

#[test]
fn exact_stop_segment_durations_and_total() {
    let plan = plan(&study_path(Blend::ExactStop)).unwrap();
    let timings = plan.segment_timings();
    let mut previous = [0.0; 5];
    for (k, (timing, point)) in timings.iter().zip(&TABLE).enumerate() {
        assert_eq!(timing.source_index, k as u32 + 1);
        assert!(
            (timing.duration - EXACT_STOP_SEGMENTS[k]).abs() < 5e-7,
            "{k}: {}",
            timing.duration
        );
        // Cross-check: the limiting axis alone, rest to rest, in its own units (all axes have
        // the same numbers in mm or deg), is the closed form; it is jerk-limited here since
        // A²/J = 1000 > any peak velocity reached.
        let limiting = point
            .iter()
            .zip(&previous)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let alone = closed_form_duration(limiting, 150.0, 1000.0, 1000.0);
        assert!((alone - 4.0 * (limiting / 2000.0).cbrt()).abs() < 1e-12);
        assert!(
            (timing.duration - alone).abs() < 1e-12,
            "{k}: {} vs {alone}",
            timing.duration
        );
        previous = *point;
    }
    assert!(
        (plan.duration() - EXACT_STOP_TOTAL).abs() < 5e-7,
        "{}",
        plan.duration()
    );
    check_stream(&plan);
    // Every programmed point is passed (at rest); the programmed coordinates are untouched.
    let sp = dense(&plan);
    for point in TABLE.iter().map(to_si) {
        assert!(closest_approach(&sp, &point) < 1e-9);
    }
    assert_eq!(sp.position(sp.len() - 1), to_si(&TABLE[4]).as_slice());
}

#[test]
fn continuous_with_five_hundredths_of_a_millimetre() {
    // Within 0.05 mm the corners could only be passed at 0.6–3 mm/s: the jerk limit of
    // 1000 mm/s³ makes turning the velocity at that speed take longer than stopping and
    // starting again, so the planner stops at every corner and the total equals exact stop.
    let plan = plan(&study_path(Blend::Continuous {
        tolerance: Some(0.05e-3),
    }))
    .unwrap();
    assert!(
        (plan.duration() - EXACT_STOP_TOTAL).abs() < 5e-7,
        "{}",
        plan.duration()
    );
    assert!(plan.junction_speeds().iter().all(|&v| v == 0.0));
    check_stream(&plan);
    // A looser tolerance (5 mm) is worth blending and is faster, still within every limit and
    // within the tolerance of every programmed point.
    let loose = cncsim::plan::plan(&study_path(Blend::Continuous {
        tolerance: Some(5e-3),
    }))
    .unwrap();
    assert!(
        loose.duration() < EXACT_STOP_TOTAL - 0.1,
        "{}",
        loose.duration()
    );
    check_stream(&loose);
    let sp = dense(&loose);
    for point in TABLE.iter().map(to_si) {
        assert!(closest_approach(&sp, &point) <= 5e-3 + 1e-8);
    }
}

#[test]
fn csv_recording_checks_jerk_from_its_own_numbers() {
    let plan = plan(&study_path(Blend::ExactStop)).unwrap();
    let sp = plan.sample(1e-3);
    let mut buffer = Vec::new();
    cncsim::plan::write_setpoints_csv(&mut buffer, &sp, &axes()).unwrap();
    let text = String::from_utf8(buffer).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t_s,x,y,z,a,c"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), sp.len());
    // Program units, full precision: the last row is the programmed point 5 in mm and deg.
    let last = rows.last().unwrap();
    for (value, expected) in last[1..].iter().zip(TABLE[4]) {
        assert!((value - expected).abs() < 1e-12, "{value} vs {expected}");
    }
    // Third differences of the file's numbers: within 1000 mm/s³ and 1000 °/s³.
    for axis in 1..6 {
        let q: Vec<f64> = rows.iter().map(|r| r[axis]).collect();
        let jerk = max_difference(&q, 3, 1e-3);
        assert!(jerk <= 1000.0 * (1.0 + 1e-6), "column {axis}: {jerk}");
        assert!(max_difference(&q, 2, 1e-3) <= 1000.0 * (1.0 + 1e-9));
        assert!(max_difference(&q, 1, 1e-3) <= 150.0 * (1.0 + 1e-9));
    }
    // The time column is k·T.
    assert!(rows
        .iter()
        .enumerate()
        .all(|(k, r)| r[0] == k as f64 * 1e-3));
}
