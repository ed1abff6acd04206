//! Look-ahead over many blocks: exact stop, continuous corners within tolerance, arcs.

mod common;

use std::f64::consts::PI;

use cncsim::plan::{plan, AxisPath, Blend, Geometry, PathSegment};
use common::*;

fn zigzag(blend: Blend) -> (AxisPath, Vec<Vec<f64>>) {
    let axes = linear_axes(&[(0.2, 2.0, 400.0), (0.15, 1.5, 300.0), (0.1, 1.0, 200.0)]);
    let points: Vec<Vec<f64>> = vec![
        vec![0.0, 0.0, 0.0],
        vec![0.05, 0.0, 0.0],
        vec![0.08, 0.03, 0.0],
        vec![0.08, 0.06, 0.01],
        vec![0.03, 0.07, 0.01],
        vec![0.031, 0.1, 0.0],
        vec![0.06, 0.1, 0.0],
        vec![0.1, 0.1, 0.0],
        vec![0.0, 0.1, 0.0], // reversal
        vec![0.0, 0.0, 0.0],
    ];
    let segments = points[1..]
        .iter()
        .enumerate()
        .map(|(k, p)| line(p, Some(0.1), blend, k as u32))
        .collect();
    (
        AxisPath {
            axes,
            start: points[0].clone(),
            segments,
            tool_lever_arms: Vec::new(),
        },
        points,
    )
}

#[test]
fn exact_stop_passes_through_every_point_at_rest() {
    let (path, points) = zigzag(Blend::ExactStop);
    let plan = plan(&path).unwrap();
    assert!(plan.junction_speeds().iter().all(|&v| v == 0.0));
    assert_within_limits(&fine(&plan), &path.axes, 1e-9);
    let sp = dense(&plan);
    // Near a stop the motion is at most J·t³/6 away within half a period of the sample.
    let slack = 400.0 * (sp.period / 2.0).powi(3) / 6.0 * 2.0;
    for p in &points {
        assert!(
            closest_approach(&sp, p) <= slack,
            "{p:?}: {}",
            closest_approach(&sp, p)
        );
    }
    // The path is the polyline itself.
    assert!(max_deviation_from_polyline(&sp, &points) < 1e-15);
    // Exact stop: each segment is its own rest-to-rest profile.
    let total: f64 = plan
        .segment_timings()
        .iter()
        .map(|t| {
            let l = t.limits;
            let seg = &path.segments[t.source_index as usize];
            let from = if t.source_index == 0 {
                &path.start
            } else {
                path.segments[t.source_index as usize - 1].geometry.end()
            };
            let length = distance(from, seg.geometry.end());
            let expected = closed_form_duration(length, l.velocity, l.acceleration, l.jerk);
            assert!((t.duration - expected).abs() < 1e-12 * expected);
            t.duration
        })
        .sum();
    assert!((total - plan.duration()).abs() < 1e-12);
}

#[test]
fn continuous_corners_stay_within_tolerance_and_limits_without_stopping() {
    let tolerance = 5e-5;
    let (path, points) = zigzag(Blend::Continuous {
        tolerance: Some(tolerance),
    });
    let plan = plan(&path).unwrap();
    let speeds = plan.junction_speeds();
    assert_eq!(speeds[0], 0.0);
    assert_eq!(*speeds.last().unwrap(), 0.0);
    assert_within_limits(&fine(&plan), &path.axes, 1e-9);
    let sp = dense(&plan);
    // Within the tolerance of every programmed point and of the programmed path (plus the
    // sampling slack of `dense`: v·T/2 = 0.5 µm along the path, 2.5e-9 m off the closest point).
    let slack = 1e-8;
    for p in &points {
        assert!(closest_approach(&sp, p) <= tolerance + slack);
    }
    let deviation = max_deviation_from_polyline(&sp, &points);
    assert!(deviation <= tolerance + slack, "{deviation}");
    // The tolerance is used (the blends are not needlessly small) on a corner that is not
    // limited by the segment lengths: corner 1 (90° → 45°).
    assert!(closest_approach(&sp, &points[1]) > 0.99 * tolerance);
    // From the positions alone: the tool stops only at the reversal (point 7), where stopping
    // is faster than any blend; every other corner is passed moving.
    let stops = count_stops(&sp, 1e-4);
    assert_eq!(stops, 1, "{speeds:?}");
    // Path speed at every programmed point (the start, then each segment's end): zero at the
    // start, at the reversal (point 7) and at the end only; the collinear point 6 is passed at
    // speed like the corners.
    assert_eq!(speeds.len(), 10);
    assert!(
        speeds
            .iter()
            .enumerate()
            .all(|(k, &v)| (v == 0.0) == (k == 0 || k == 7 || k == 9)),
        "{speeds:?}"
    );
    // Exactly on the last point at the end, and faster than exact stop.
    assert_eq!(sp.position(sp.len() - 1), points.last().unwrap().as_slice());
    let exact = cncsim::plan::plan(&zigzag(Blend::ExactStop).0).unwrap();
    assert!(
        plan.duration() < 0.98 * exact.duration(),
        "{} {}",
        plan.duration(),
        exact.duration()
    );
    assert_eq!(count_stops(&dense(&exact), 1e-4), 8);
}

#[test]
fn tighter_tolerance_is_slower_and_closer() {
    let mut previous = 0.0;
    let exact = cncsim::plan::plan(&zigzag(Blend::ExactStop).0)
        .unwrap()
        .duration();
    for tolerance in [1e-3, 1e-4, 1e-5, 1e-6] {
        let (path, points) = zigzag(Blend::Continuous {
            tolerance: Some(tolerance),
        });
        let plan = plan(&path).unwrap();
        assert!(plan.duration() >= previous && plan.duration() < exact);
        previous = plan.duration();
        let sp = dense(&plan);
        assert!(max_deviation_from_polyline(&sp, &points) <= tolerance + 1e-8);
    }
}

#[test]
fn collinear_blocks_are_passed_at_speed() {
    let axes = linear_axes(&[(0.1, 1.0, 10.0), (0.1, 1.0, 10.0)]);
    let blend = Blend::Continuous {
        tolerance: Some(0.0),
    };
    let segments: Vec<PathSegment> = (1..=20)
        .map(|k| line(&[0.01 * k as f64, 0.005 * k as f64], None, blend, k))
        .collect();
    let path = AxisPath {
        axes: axes.clone(),
        start: vec![0.0, 0.0],
        segments,
        tool_lever_arms: Vec::new(),
    };
    let plan = plan(&path).unwrap();
    let sp = fine(&plan);
    assert_within_limits(&sp, &axes, 1e-9);
    // Zero tolerance is fine on a straight line: no corner, nothing to round. The twenty
    // blocks are one motion: the duration of a single move over the whole length.
    assert_eq!(count_stops(&dense(&plan), 1e-4), 0);
    let l = plan.segment_timings()[0].limits;
    let single = closed_form_duration(0.2_f64.hypot(0.1), l.velocity, l.acceleration, l.jerk);
    assert!(
        (plan.duration() - single).abs() < 1e-12 * single,
        "{} vs {single}",
        plan.duration()
    );
    // Each block's timing ends when the motion crosses its end point, and the samples belong
    // to the block they are on.
    let timings = plan.segment_timings();
    assert!((timings.iter().map(|t| t.duration).sum::<f64>() - single).abs() < 1e-12);
    for k in 0..sp.len() {
        let block = sp.segment[k] as f64;
        let x = sp.position(k)[0];
        assert!(
            x >= 0.01 * (block - 1.0) - 1e-15 && x <= 0.01 * block + 1e-15,
            "{k}"
        );
    }
    // With exact stop in between, twenty rest-to-rest moves.
    let stops: Vec<PathSegment> = (1..=20)
        .map(|k| {
            line(
                &[0.01 * k as f64, 0.005 * k as f64],
                None,
                Blend::ExactStop,
                k,
            )
        })
        .collect();
    let exact = cncsim::plan::plan(&AxisPath {
        axes,
        start: vec![0.0, 0.0],
        segments: stops,
        tool_lever_arms: Vec::new(),
    });
    let each = closed_form_duration(0.01_f64.hypot(0.005), l.velocity, l.acceleration, l.jerk);
    assert!((exact.unwrap().duration() - 20.0 * each).abs() < 1e-9);
}

/// Number of times the sampled path speed drops below `threshold` between the first and the
/// last motion (interior stops).
fn count_stops(sp: &cncsim::plan::Setpoints, threshold: f64) -> usize {
    let speed: Vec<f64> = (1..sp.len())
        .map(|k| distance(sp.position(k), sp.position(k - 1)) / sp.period)
        .collect();
    let first = speed.iter().position(|&v| v >= threshold).unwrap();
    let last = speed.iter().rposition(|&v| v >= threshold).unwrap();
    (first..last)
        .filter(|&k| speed[k] >= threshold && speed[k + 1] < threshold)
        .count()
}

fn circle_path(feed: f64, turns: u32, helix_end: f64) -> AxisPath {
    let axes = linear_axes(&[(0.2, 1.0, 10.0), (0.2, 1.0, 10.0), (0.05, 0.5, 5.0)]);
    AxisPath {
        axes,
        start: vec![0.03, 0.0, 0.0],
        segments: vec![
            PathSegment {
                geometry: Geometry::Arc {
                    plane: [0, 1],
                    center: [0.0, 0.0],
                    clockwise: false,
                    turns,
                    end: vec![0.03, 0.0, helix_end],
                },
                feed: Some(feed),
                feed_metric: vec![1.0, 1.0, 1.0],
                blend: Blend::Continuous {
                    tolerance: Some(1e-5),
                },
                source_index: 0,
            },
            line(&[0.06, 0.0, helix_end], Some(feed), Blend::ExactStop, 1),
        ],
        tool_lever_arms: Vec::new(),
    }
}

#[test]
fn arcs_respect_centripetal_acceleration_and_jerk() {
    // Feed far above sqrt(a·r) = 0.17 m/s: the arc must slow down for the axes.
    let path = circle_path(1.0, 1, 0.02);
    let plan = plan(&path).unwrap();
    let checked = fine(&plan);
    assert_within_limits(&checked, &path.axes, 1e-9);
    // Two turns are long enough to be worth cruising near the centripetal limit: the arc's
    // centripetal budget share is chosen per arc, and most of the acceleration limit is used.
    let used = max_difference(&column(&checked, 0), 2, checked.period);
    assert!(used > 0.85, "{used}");
    let sp = dense(&plan);
    // Two full turns, on the helix: radius 30 mm and z proportional to the angle.
    let arc_samples = sp.segment.iter().filter(|&&s| s == 0).count();
    let mut angle = 0.0;
    let mut previous = 0.0_f64;
    for k in 0..arc_samples {
        let p = sp.position(k);
        assert!((p[0].hypot(p[1]) - 0.03).abs() < 1e-15);
        let phi = p[1].atan2(p[0]);
        let mut step = phi - previous;
        if step < -PI {
            step += 2.0 * PI;
        }
        assert!(step >= -1e-12, "turns the wrong way");
        angle += step;
        previous = phi;
        assert!((p[2] - 0.02 * angle / (4.0 * PI)).abs() < 1e-12);
    }
    assert!((angle - 4.0 * PI).abs() < 1e-6, "{angle}");
    // The arc ends on its programmed point at rest (no blend into or out of an arc), and the
    // path ends exactly on the last point.
    let arc_end = [0.03, 0.0, 0.02];
    assert!(closest_approach(&sp, &arc_end) < 1e-12);
    assert_eq!(plan.junction_speeds()[1], 0.0);
    assert_eq!(sp.position(sp.len() - 1), &[0.06, 0.0, 0.02]);
}

#[test]
fn clockwise_quarter_arc_lands_on_its_end() {
    let axes = linear_axes(&[(0.2, 1.0, 10.0), (0.2, 1.0, 10.0)]);
    let path = AxisPath {
        axes: axes.clone(),
        start: vec![0.0, 0.02],
        segments: vec![PathSegment {
            geometry: Geometry::Arc {
                plane: [0, 1],
                center: [0.0, 0.0],
                clockwise: true,
                turns: 0,
                end: vec![0.02, 0.0],
            },
            feed: Some(0.05),
            feed_metric: vec![1.0, 1.0],
            blend: Blend::ExactStop,
            source_index: 0,
        }],
        tool_lever_arms: Vec::new(),
    };
    let plan = plan(&path).unwrap();
    assert_within_limits(&fine(&plan), &axes, 1e-9);
    let sp = dense(&plan);
    // Clockwise from (0, r) to (r, 0): a quarter, staying in the first quadrant.
    for k in 0..sp.len() {
        let p = sp.position(k);
        assert!(p[0] >= -1e-15 && p[1] >= -1e-15);
    }
    assert_eq!(sp.position(sp.len() - 1), &[0.02, 0.0]);
    // Arc length π·r/2 at most at the feed: longer than the straight closed form at the feed.
    let quarter = PI * 0.02 / 2.0;
    let at_feed = closed_form_duration(quarter, 0.05, 1.0, 10.0);
    assert!(plan.duration() >= at_feed * (1.0 - 1e-12));
}

#[test]
fn servo_rate_stream_has_segments_in_order() {
    let (path, points) = zigzag(Blend::Continuous {
        tolerance: Some(1e-4),
    });
    let plan = plan(&path).unwrap();
    let sp = plan.sample(1e-3);
    assert!(sp
        .segment
        .windows(2)
        .all(|w| w[1] == w[0] || w[1] == w[0] + 1));
    assert_eq!(sp.segment[0], 0);
    assert_eq!(*sp.segment.last().unwrap(), 8);
    assert_eq!(sp.position(sp.len() - 1), points.last().unwrap().as_slice());
    // Velocity and acceleration bookkeeping agree with the positions (central differences).
    // A central difference is off by at most |q⃛|·T²/6.
    for k in 1..sp.len() - 1 {
        for i in 0..3 {
            let fd = (sp.position(k + 1)[i] - sp.position(k - 1)[i]) / 2e-3;
            assert!(
                (fd - sp.velocity(k)[i]).abs() <= 400.0 * 1e-6 / 6.0 + 1e-12,
                "{k} {i}"
            );
            let fd2 =
                (sp.position(k + 1)[i] - 2.0 * sp.position(k)[i] + sp.position(k - 1)[i]) / 1e-6;
            assert!(
                (fd2 - sp.acceleration(k)[i]).abs() <= 400.0 * 1e-3 + 1e-6,
                "{k} {i}"
            );
        }
    }
}

/// A program's own G64 P- Q- (LinuxCNC's naive-CAM tolerance): 40 lines of 1 mm zig-zagging
/// 5 µm about one line are joined under `G64 P0.05 Q0.01`, exactly as with the scenario's
/// `naive_cam_tolerance` (which overrides the program's Q, zero turning it off); a G64 Q0
/// ends the joining where it is programmed; a G64 P without Q joins within P, as LinuxCNC
/// does (its interpreter sets the naive-CAM tolerance to P).
#[test]
fn a_programs_g64_q_joins_collinear_short_lines() {
    use cncsim::kinematics::AxisMap;
    use cncsim::machine::Machine;
    use cncsim::plan::{plan_program, AxisKind, AxisLimits, BlendChoice, PlanSettings, Planner};
    use cncsim::program::{parse_gcode, ReadOptions};

    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine = Machine::load(&root.join("models/xyz_table.urdf")).unwrap();
    let axes = AxisMap::new(&machine).unwrap();
    // `header` is the G64 in effect from the start; `middle` is programmed before line 20.
    let program = |header: &str, middle: &str| {
        let mut text = format!("G21 G90 {header}\nG0 X0 Y0 Z0\nF6000\n");
        for i in 1..=40 {
            if i == 20 {
                text.push_str(middle);
                text.push('\n');
            }
            let y = if i % 2 == 1 { 0.005 } else { 0.0 };
            text.push_str(&format!("G1 X{i} Y{y}\n"));
        }
        parse_gcode(&text, "q.ngc", &ReadOptions::default()).unwrap()
    };
    let duration = |program: &cncsim::program::Program, q: Option<f64>| {
        let settings = PlanSettings {
            planner: Planner::JerkLimited {
                limits: vec![
                    AxisLimits::from_program_units(AxisKind::Linear, 200.0, 2000.0, 5e4);
                    3
                ],
            },
            period: 1e-3,
            rapid_speed: 0.05,
            blend: BlendChoice::Program,
            axis_names: machine.axes.iter().map(|a| a.name.clone()).collect(),
            naive_cam_tolerance: q,
            tool_lever_arms: Vec::new(),
        };
        plan_program(program, &axes, &settings).unwrap().duration()
    };
    let with_q = program("G64 P0.05 Q0.01", "");
    let without_q = program("G64 P0.05 Q0", "");
    let joined = duration(&with_q, None);
    let move_by_move = duration(&without_q, None);
    eprintln!("G64 P0.05 Q0.01: {joined} s; G64 P0.05 Q0: {move_by_move} s");
    // 0.490 s joined, 0.527 s move by move (the corners are blended within P either way).
    assert!(joined < move_by_move, "{joined} {move_by_move}");
    assert_eq!(duration(&without_q, Some(1e-5)), joined);
    assert_eq!(duration(&with_q, Some(0.0)), move_by_move);
    let ended = duration(&program("G64 P0.05 Q0.01", "G64 P0.05 Q0"), None);
    assert!(
        joined < ended && ended < move_by_move,
        "{joined} {ended} {move_by_move}"
    );
    let p_alone = duration(&program("G64 P0.05", ""), None);
    assert_eq!(p_alone, duration(&program("G64 P0.05 Q0.05", ""), None));
    assert!(p_alone < move_by_move, "{p_alone} {move_by_move}");
}
