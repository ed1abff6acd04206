//! Chains longer than the planner's look-ahead: planned a window at a time and handed over
//! while moving, never stopping where the program does not ask for it, within every limit and
//! tolerance, and close to the plan of the whole chain at once.

mod common;

use cncsim::plan::planner::{plan_with_lookahead, LOOKAHEAD_SEGMENTS};
use cncsim::plan::{
    plan, plan_path_stream, AxisKind, AxisLimits, AxisPath, Blend, Geometry, PathSegment,
    SetpointSample,
};
use common::*;

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
/// each chain whole: the same chains and geometry (no point moved, no stop added), every
/// window within the look-ahead, every axis limit kept; returns the two durations.
fn check_against_whole(name: &str, path: &AxisPath, lookahead: usize) -> (f64, f64) {
    let windowed = plan_with_lookahead(path, lookahead).unwrap();
    let whole = plan_with_lookahead(path, usize::MAX).unwrap();
    assert_eq!(windowed.chain_count(), whole.chain_count(), "{name}");
    assert!(
        windowed.handoffs() >= 2,
        "{name}: {} handoffs, {} chains",
        windowed.handoffs(),
        windowed.chain_count()
    );
    assert_eq!(windowed.stops_added(), 0, "{name}");
    assert!(
        windowed.largest_window() <= lookahead,
        "{name}: {}",
        windowed.largest_window()
    );
    assert!(whole.largest_window() > lookahead, "{name}");
    // The same pieces, point for point, with the same feeds.
    assert!(
        windowed.chain_geometry(path, 2e-4) == whole.chain_geometry(path, 2e-4),
        "{name}: the geometry differs"
    );
    // No stop inside a chain that the whole plan does not make.
    let (speeds, whole_speeds) = (windowed.junction_speeds(), whole.junction_speeds());
    for (k, (v, w)) in speeds.iter().zip(&whole_speeds).enumerate() {
        assert!(*v > 0.0 || *w == 0.0, "{name}: stops at point {k}");
    }
    assert_within_limits(&fine(&windowed), &path.axes, 1e-9);
    println!(
        "{name}: {} segments, {} handoffs, {:.6} s with a look-ahead of {lookahead}, {:.6} s whole \
         (ratio {:.8})",
        path.segments.len(),
        windowed.handoffs(),
        windowed.duration(),
        whole.duration(),
        windowed.duration() / whole.duration()
    );
    (windowed.duration(), whole.duration())
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
        let (windowed, whole) = check_against_whole(name, &path, LOOKAHEAD_SEGMENTS);
        // Measured: the same to 1e-7 (handoffs where the plan passes at zero acceleration).
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
    let (windowed, whole) = check_against_whole("collinear", &path, 160);
    // The look-ahead caps the speed at what stops within it (measured: 2.50 times as long).
    assert!(
        windowed > 1.5 * whole && windowed < 4.0 * whole,
        "{windowed} s against {whole} s whole"
    );
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
    use cncsim::plan::{
        jerk_limited_plans, plan_program_stream, BlendChoice, PlanSettings, Planner,
    };
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
    let axes = AxisMap::cartesian(&machine).unwrap();
    let settings = PlanSettings {
        planner: Planner::JerkLimited {
            limits: vec![AxisLimits::from_program_units(AxisKind::Linear, 200.0, 2000.0, 5e4); 3],
        },
        period: 1e-3,
        rapid_speed: 0.05,
        blend: BlendChoice::Program,
        axis_names: machine.axes.iter().map(|a| a.name.clone()).collect(),
        naive_cam_tolerance: Some(0.0),
        tool_lever_arms: Vec::new(),
    };
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
    assert_eq!(plans[0].1.handoffs(), look_ahead.handoffs);
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
