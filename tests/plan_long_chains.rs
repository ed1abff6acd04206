//! Chains longer than the planner's look-ahead: planned a window at a time and handed over
//! while moving, never stopping where the program does not ask for it, within every limit and
//! tolerance, and close to the plan of the whole chain at once.

mod common;

use cncsim::plan::planner::{plan_with_lookahead, LOOKAHEAD_SEGMENTS};
use cncsim::plan::{
    plan, plan_path_stream, AxisPath, Blend, Geometry, PathSegment, Plan, SetpointSample,
};
use common::*;
use proptest::prelude::*;

/// CAM finishing output: 1 mm lines on a smooth curve in XZ, rows 0.5 mm apart joined by a
/// blended step, G64 P0.05 (the lines are smoothed into quintics).
fn cam_raster(lines: usize, row: usize) -> AxisPath {
    let axes = linear_axes(&[(0.2, 2.0, 50.0), (0.2, 2.0, 50.0), (0.1, 1.0, 30.0)]);
    let segments = (0..lines)
        .map(|k| {
            let (r, step) = (k / row, k % row);
            let x = if r % 2 == 0 { step } else { row - 1 - step } as f64;
            let z = 2.0 * (x * 0.02).sin() + (x * 0.0031).cos();
            line(
                &[x * 1e-3, r as f64 * 0.5e-3, z * 1e-3],
                Some(0.1),
                Blend::Continuous {
                    tolerance: Some(5e-5),
                },
                k as u32,
            )
        })
        .collect();
    AxisPath {
        axes,
        start: vec![0.0, 0.0, 1e-3],
        segments,
        tool_lever_arms: Vec::new(),
    }
}

/// Arcs of 5 mm radius turning 0.3 rad each, alternately left and right: a wavy chain of
/// tangent arcs.
fn tangent_arcs(count: usize) -> AxisPath {
    let axes = linear_axes(&[(0.2, 2.0, 50.0), (0.2, 2.0, 50.0)]);
    let (radius, turn) = (5e-3, 0.3f64);
    let mut at = [0.0f64, 0.0];
    let mut heading = -0.15f64;
    let segments = (0..count)
        .map(|k| {
            let left = k % 2 == 0;
            let side = if left { 1.0 } else { -1.0 };
            // The centre lies on the left (or right) normal of the heading.
            let normal = heading + side * std::f64::consts::FRAC_PI_2;
            let center = [at[0] + radius * normal.cos(), at[1] + radius * normal.sin()];
            heading += side * turn;
            let back = heading - side * std::f64::consts::FRAC_PI_2;
            at = [
                center[0] + radius * back.cos(),
                center[1] + radius * back.sin(),
            ];
            PathSegment {
                geometry: Geometry::Arc {
                    plane: [0, 1],
                    center,
                    clockwise: !left,
                    turns: 0,
                    end: at.to_vec(),
                },
                feed: Some(0.1),
                feed_metric: vec![1.0; 2],
                blend: Blend::Continuous {
                    tolerance: Some(1e-5),
                },
                source_index: k as u32,
            }
        })
        .collect();
    AxisPath {
        axes,
        start: vec![0.0, 0.0],
        segments,
        tool_lever_arms: Vec::new(),
    }
}

/// Collinear 0.01 mm lines: too short for the look-ahead to reach cruise, with no span
/// boundary inside: every handoff is inside an accelerating span.
fn fine_collinear(count: usize) -> AxisPath {
    let axes = linear_axes(&[(0.2, 2.0, 50.0), (0.2, 2.0, 50.0)]);
    let segments = (0..count)
        .map(|k| {
            let s = (k + 1) as f64 * 1e-5;
            line(
                &[0.8 * s, 0.6 * s],
                Some(0.1),
                Blend::Continuous {
                    tolerance: Some(1e-5),
                },
                k as u32,
            )
        })
        .collect();
    AxisPath {
        axes,
        start: vec![0.0, 0.0],
        segments,
        tool_lever_arms: Vec::new(),
    }
}

/// Checks the plan of `path` with a look-ahead of `lookahead` segments against the plan of
/// each chain whole: the same chains (no stop added), at least `handoffs` handoffs, every
/// window within the look-ahead, every axis limit kept, every programmed point within its
/// tolerance; returns both plans.
fn check_against_whole(
    name: &str,
    path: &AxisPath,
    lookahead: usize,
    handoffs: usize,
) -> (Plan, Plan) {
    let windowed = plan_with_lookahead(path, lookahead).unwrap();
    let whole = plan_with_lookahead(path, usize::MAX).unwrap();
    assert_eq!(windowed.chain_count(), whole.chain_count(), "{name}");
    let look_ahead = windowed.look_ahead();
    assert!(
        look_ahead.handoffs >= handoffs,
        "{name}: {look_ahead:?}, {} chains",
        windowed.chain_count()
    );
    assert_eq!(look_ahead.stops_added, 0, "{name}");
    assert!(
        windowed.largest_window() <= lookahead,
        "{name}: {}",
        windowed.largest_window()
    );
    assert!(whole.largest_window() > lookahead, "{name}");
    // No stop inside a chain that the whole plan does not make.
    let (speeds, whole_speeds) = (windowed.junction_speeds(), whole.junction_speeds());
    for (k, (v, w)) in speeds.iter().zip(&whole_speeds).enumerate() {
        assert!(*v > 0.0 || *w == 0.0, "{name}: stops at point {k}");
    }
    assert_within_limits(&fine(&windowed), &path.axes, 1e-9);
    assert_points_within_tolerance(name, &windowed, path);
    println!(
        "{name}: {} segments, {} handoffs ({} slowed), {:.6} s with a look-ahead of {lookahead}, \
         {:.6} s whole (ratio {:.8})",
        path.segments.len(),
        look_ahead.handoffs,
        look_ahead.slowed,
        windowed.duration(),
        whole.duration(),
        windowed.duration() / whole.duration()
    );
    (windowed, whole)
}

/// The same pieces, point for point, with the same feeds.
fn assert_same_geometry(name: &str, path: &AxisPath, windowed: &Plan, whole: &Plan) {
    assert!(
        windowed.chain_geometry(path, 2e-4) == whole.chain_geometry(path, 2e-4),
        "{name}: the geometry differs"
    );
}

/// Asserts that `plan` passes every programmed point of `path` within its corner tolerance
/// (exactly at stops and at the end): the closest approach, searched from when the plan passes
/// the segment before the point to when it passes the one after.
fn assert_points_within_tolerance(name: &str, plan: &Plan, path: &AxisPath) {
    let timings = plan.segment_timings();
    let n = path.axes.len();
    let (mut p, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut distance_at = |t: f64, point: &[f64]| {
        plan.eval(t, &mut p, &mut v, &mut a);
        distance(&p, point)
    };
    for (k, segment) in path.segments.iter().enumerate() {
        let point = segment.geometry.end();
        let allowed = match segment.blend {
            _ if k + 1 == path.segments.len() => 0.0,
            Blend::ExactStop => 0.0,
            Blend::Continuous { tolerance } => tolerance.unwrap_or(0.0),
        };
        let from = timings[k].start_time;
        let to = timings
            .get(k + 1)
            .map_or(plan.duration(), |t| t.start_time + t.duration);
        // Coarsely, then by golden-section search around the closest sample.
        let steps = 64;
        let step = (to - from) / steps as f64;
        let closest = (0..=steps)
            .map(|i| from + step * i as f64)
            .min_by(|x, y| distance_at(*x, point).total_cmp(&distance_at(*y, point)))
            .unwrap();
        let (mut lo, mut hi) = ((closest - step).max(from), (closest + step).min(to));
        let ratio = (5f64.sqrt() - 1.0) / 2.0;
        for _ in 0..80 {
            let (x1, x2) = (hi - ratio * (hi - lo), lo + ratio * (hi - lo));
            if distance_at(x1, point) <= distance_at(x2, point) {
                hi = x2;
            } else {
                lo = x1;
            }
        }
        let found = distance_at(0.5 * (lo + hi), point).min(distance_at(closest, point));
        assert!(
            found <= allowed * (1.0 + 1e-9) + 1e-12,
            "{name}: point {k} passed at {found} m, tolerance {allowed} m"
        );
    }
}

#[test]
fn long_chains_are_handed_over_between_windows_without_stopping() {
    for (name, path) in [
        // The planner benchmark's path without its sharp corners (which stop).
        (
            "random walk",
            random_walk(
                3 * LOOKAHEAD_SEGMENTS,
                Blend::Continuous {
                    tolerance: Some(1e-5),
                },
                false,
            ),
        ),
        ("cam raster", cam_raster(3 * LOOKAHEAD_SEGMENTS, 1000)),
        ("tangent arcs", tangent_arcs(3 * LOOKAHEAD_SEGMENTS)),
    ] {
        let (windowed, whole) = check_against_whole(name, &path, LOOKAHEAD_SEGMENTS, 2);
        assert_same_geometry(name, &path, &windowed, &whole);
        let (windowed, whole) = (windowed.duration(), whole.duration());
        // Measured: the same to 1e-8 (handoffs where the plan passes at zero acceleration).
        assert!(
            (windowed / whole - 1.0).abs() < 1e-5,
            "{name}: {windowed} s against {whole} s whole"
        );
        assert_eq!(plan(&path).unwrap().duration(), windowed, "{name}");
    }
}

#[test]
fn a_look_ahead_too_short_to_cruise_hands_over_inside_accelerations() {
    // 0.4 mm of look-ahead past every handoff, far less than the 2.5 mm the feed needs:
    // every handoff is planned to zero acceleration inside a speed change.
    let path = fine_collinear(2000);
    let (windowed, whole) = check_against_whole("collinear", &path, 160, 2);
    assert_same_geometry("collinear", &path, &windowed, &whole);
    let (windowed, whole) = (windowed.duration(), whole.duration());
    // The look-ahead caps the speed at what stops within it (measured: 2.50 times as long).
    assert!(
        windowed > 1.5 * whole && windowed < 4.0 * whole,
        "{windowed} s against {whole} s whole"
    );
}

/// A positive value spread over several decades.
fn decades(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo.log10()..hi.log10()).prop_map(|e| 10f64.powf(e))
}

proptest! {
    // Each case plans a few hundred segments twice and samples them finely: 48 cases, or
    // PROPTEST_CASES=N for a longer run.
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|n| n.parse().ok()).unwrap_or(48)
    ))]

    #[test]
    fn random_long_chains_are_handed_over_as_they_are_planned_whole(
        axis_limits in prop::collection::vec(
            (decades(0.01, 1.0), decades(0.1, 20.0), decades(10.0, 1000.0)),
            3,
        ),
        // Per segment: length (m), turn (rad), climb (z per length), whether it is empty.
        steps in prop::collection::vec(
            (decades(2e-4, 2e-3), -0.15..0.15_f64, -0.1..0.1_f64, prop::bool::weighted(0.02)),
            250..600,
        ),
        tolerance in decades(1e-6, 1e-3),
        feeds in prop::collection::vec(prop::option::of(decades(0.01, 0.5)), 1..4),
    ) {
        let path = gentle_walk(&axis_limits, &steps, tolerance, &feeds);
        // Only paths with a chain longer than the look-ahead (the planner stops at a corner
        // where that is faster than blending it: at low limits, many do).
        let stops: Vec<usize> = plan_with_lookahead(&path, usize::MAX)
            .unwrap()
            .junction_speeds()
            .iter()
            .enumerate()
            .filter_map(|(k, v)| (*v == 0.0).then_some(k))
            .collect();
        prop_assume!(stops.windows(2).any(|w| w[1] - w[0] > 128));
        let (windowed, whole) = check_against_whole("random walk", &path, 128, 1);
        // Neither the time nor the geometry is checked against the whole chain's: a look-ahead
        // this short slows down where a quarter of it is too short to brake in (tests above),
        // a window can also be faster (each chooses its own share of the acceleration for the
        // curves), and past a handoff a window chooses the smoothing of the lines itself.
        println!(
            "same geometry as the whole chain's: {}",
            windowed.chain_geometry(&path, 2e-4) == whole.chain_geometry(&path, 2e-4)
        );
        let end = windowed.sample(1e-3);
        prop_assert_eq!(end.position(end.len() - 1), path.segments.last().unwrap().geometry.end());
    }
}

/// A walk with gentle turns: per segment its length (m), turn (rad), climb (z per length) and
/// whether it is empty (zero length); blended at every junction with `tolerance`, its feed
/// changing every 50 segments through `feeds`. Long chains: the planner stops only where
/// stopping is faster than the blend, which such corners rarely are.
fn gentle_walk(
    axis_limits: &[(f64, f64, f64)],
    steps: &[(f64, f64, f64, bool)],
    tolerance: f64,
    feeds: &[Option<f64>],
) -> AxisPath {
    let (mut at, mut heading) = ([0.0f64; 3], 0.0f64);
    let segments = steps
        .iter()
        .enumerate()
        .map(|(k, &(length, turn, climb, empty))| {
            if !empty {
                heading += turn;
                at[0] += length * heading.cos();
                at[1] += length * heading.sin();
                at[2] += length * climb;
            }
            line(
                &at,
                feeds[k / 50 % feeds.len()],
                Blend::Continuous {
                    tolerance: Some(tolerance),
                },
                k as u32,
            )
        })
        .collect();
    AxisPath {
        axes: linear_axes(axis_limits),
        start: vec![0.0; 3],
        segments,
        tool_lever_arms: Vec::new(),
    }
}

#[test]
fn handoffs_where_the_next_window_differs_are_found_elsewhere_or_more_slowly() {
    // Walks the property test above once found to stop short (shrunk, as proptest saved them
    // in plan_long_chains.proptest-regressions): the next window's smoothing differs around the
    // first places tried, or it admits only a lower speed there.
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures/plan/handoff_cases.json"),
    )
    .unwrap();
    let cases: Vec<serde_json::Value> = serde_json::from_str(&text).unwrap();
    // The first three numbers of an array.
    let triple = |v: &serde_json::Value| {
        let x: Vec<f64> = v.as_array().unwrap()[..3]
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        (x[0], x[1], x[2])
    };
    let mut slowed = 0;
    for (k, case) in cases.iter().enumerate() {
        let axis_limits: Vec<_> = case["axis_limits"]
            .as_array()
            .unwrap()
            .iter()
            .map(triple)
            .collect();
        let steps: Vec<_> = case["steps"]
            .as_array()
            .unwrap()
            .iter()
            .map(|step| {
                let s = step.as_array().unwrap();
                let (length, turn, climb) = triple(step);
                (length, turn, climb, s[3].as_bool().unwrap())
            })
            .collect();
        let feeds: Vec<Option<f64>> = case["feeds"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_f64())
            .collect();
        let path = gentle_walk(
            &axis_limits,
            &steps,
            case["tolerance"].as_f64().unwrap(),
            &feeds,
        );
        let (windowed, _) = check_against_whole(&format!("case {k}"), &path, 128, 1);
        slowed += windowed.look_ahead().slowed;
    }
    // Case 0 stops short unless a handoff is slowed to what the next window admits (one is);
    // case 1 unless the places next to one the next window does not hold are passed over.
    assert!(slowed >= 1, "{slowed} handoffs slowed");
}

#[test]
fn a_run_streams_a_long_chain_as_the_plan_samples_it() {
    let path = cam_raster(2 * LOOKAHEAD_SEGMENTS + 500, 1000);
    let period = 1e-3;
    let expected = plan(&path).unwrap().sample(period);
    // Sample 0 is the start at rest (as the plan's); the rest are the plan's.
    let mut stream = plan_path_stream(path, period).unwrap();
    assert_stream_equals(stream.as_mut(), &expected, 1, "long chain");
}

#[test]
fn a_program_with_a_long_chain_streams_as_its_whole_plan_samples_it() {
    use cncsim::kinematics::AxisMap;
    use cncsim::machine::Machine;
    use cncsim::plan::{jerk_limited_plans, plan_program_stream};
    use cncsim::program::{parse_gcode, ReadOptions};
    // CAM raster output in G-code: 9 000 lines of 1 mm on a curve, one chain (the path is made
    // from the moves as the windows read it), then a dwell and a second, short chain.
    let text = format!(
        "G21 G90 G64 P0.05\nG0 X0 Y0 Z1\nF6000\n{}G4 P0.2\nG1 X5 Y10 Z3\nG1 X10 Y12\nM2\n",
        raster_gcode(9000)
    );
    let program = parse_gcode(&text, "raster.ngc", &ReadOptions::default()).unwrap();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine = Machine::load(&root.join("models/xyz_table.urdf")).unwrap();
    let axes = AxisMap::new(&machine).unwrap();
    let settings = raster_settings(&machine);
    let mut stream = plan_program_stream(&program, &axes, &settings).unwrap();
    let look_ahead = stream.look_ahead();
    assert!(look_ahead.handoffs >= 2, "{look_ahead:?}");
    assert_eq!(look_ahead.stops_added, 0);
    // The motions planned whole (for inspection), sampled on the stream's grid.
    let plans = jerk_limited_plans(&program, &axes, &settings)
        .unwrap()
        .unwrap();
    assert_eq!(plans.len(), 2);
    assert_eq!(plans[0].0.segments.len(), 9001);
    assert_eq!(plans[0].1.look_ahead(), look_ahead);
    let first = plans[0].1.sample(1e-3);
    let mut sample = SetpointSample::zeros(3);
    let n = 3;
    for k in 0..first.len() {
        assert!(stream.next_sample(&mut sample));
        let row = k * n..(k + 1) * n;
        assert_eq!(sample.position, first.position[row.clone()], "{k}");
        assert_eq!(sample.velocity, first.velocity[row.clone()], "{k}");
        assert_eq!(sample.acceleration, first.acceleration[row], "{k}");
    }
}
