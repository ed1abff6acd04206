//! Property tests over random moves and limits: no limit broken, durations never longer than a
//! simple safe profile, no NaN, programmed points honoured.

mod common;

use cncsim::plan::{plan, AxisPath, Blend, Geometry, Limits, PathSegment, Profile};
use common::*;
use proptest::prelude::*;

/// A positive value spread over several decades.
fn decades(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo.log10()..hi.log10()).prop_map(|e| 10f64.powf(e))
}

fn limits() -> impl Strategy<Value = (f64, f64, f64)> {
    (decades(0.01, 1.0), decades(0.1, 20.0), decades(1.0, 1000.0))
}

/// A simple safe profile, feasible for any length: the jerk-only profile (four equal phases of
/// jerk ±J') stretched until its jerk 32L/T³, peak acceleration 8L/T² and peak velocity 2L/T
/// are all within the limits.
fn safe_duration(length: f64, l: &Limits) -> f64 {
    (32.0 * length / l.jerk)
        .cbrt()
        .max((8.0 * length / l.acceleration).sqrt())
        .max(2.0 * length / l.velocity)
}

proptest! {
    // 256 cases by default; PROPTEST_CASES=N for a longer run.
    #![proptest_config(ProptestConfig::default())]

    #[test]
    fn single_axis_profiles_are_optimal_safe_and_finite(
        (v, a, j) in limits(),
        length in decades(1e-6, 2.0),
        sign in prop::bool::ANY,
    ) {
        let limits = Limits::new(v, a, j);
        let distance = if sign { length } else { -length };
        let profile = Profile::rest_to_rest(distance, &limits);
        let t = profile.duration();
        prop_assert!(t.is_finite() && t > 0.0);
        prop_assert!(t <= safe_duration(length, &limits) * (1.0 + 1e-12));
        let expected = closed_form_duration(length, v, a, j);
        prop_assert!((t - expected).abs() <= 1e-10 * expected, "{} vs {}", t, expected);
        // Sampled state: within limits, monotone, exact at the end.
        let n = 2000;
        let mut previous = 0.0_f64;
        for k in 0..=n {
            let s = profile.state(t * k as f64 / n as f64);
            prop_assert!(s.position.is_finite() && s.velocity.is_finite());
            prop_assert!(s.velocity.abs() <= v * (1.0 + 1e-12));
            prop_assert!(s.acceleration.abs() <= a * (1.0 + 1e-9));
            prop_assert!((s.position - previous) * distance.signum() >= -1e-15 * length);
            previous = s.position;
        }
        prop_assert_eq!(profile.state(t).position, distance);
    }

    #[test]
    fn profiles_between_speeds_are_feasible_and_within_limits(
        (v, a, j) in limits(),
        length in decades(1e-5, 2.0),
        start in 0.0..1.0_f64,
        end in 0.0..1.0_f64,
    ) {
        let limits = Limits::new(v, a, j);
        let (v0, v1) = (start * v, end * v);
        match Profile::plan(length, v0, v1, &limits) {
            None => {
                // Only when the length is too short for the speed change.
                let needed = cncsim::plan::profile::transfer_distance(v0, v1, a, j);
                prop_assert!(needed > length * (1.0 - 1e-9));
            }
            Some(profile) => {
                let t = profile.duration();
                prop_assert!(t.is_finite());
                let n = 2000;
                for k in 0..=n {
                    let s = profile.state(t * k as f64 / n as f64);
                    prop_assert!(s.velocity >= -1e-12 && s.velocity <= v * (1.0 + 1e-12));
                    prop_assert!(s.acceleration.abs() <= a * (1.0 + 1e-9));
                }
                let end_state = profile.state(t);
                prop_assert_eq!(end_state.position, length);
                prop_assert!((end_state.velocity - v1).abs() <= 1e-12 * v);
            }
        }
    }

    #[test]
    fn random_polylines_respect_every_limit_and_every_point(
        axis_limits in prop::collection::vec(limits(), 2..5),
        raw_points in prop::collection::vec(prop::collection::vec(-0.05..0.05_f64, 5), 1..6),
        continuous in prop::collection::vec(prop::option::of(decades(1e-6, 1e-2)), 6),
        feed in prop::option::of(decades(0.005, 0.5)),
    ) {
        let n = axis_limits.len();
        let axes = linear_axes(&axis_limits);
        let points: Vec<Vec<f64>> = std::iter::once(vec![0.0; n])
            .chain(raw_points.iter().map(|p| p[..n].to_vec()))
            .collect();
        let blends: Vec<Blend> = continuous
            .iter()
            .map(|t| t.map_or(Blend::ExactStop, |t| Blend::Continuous { tolerance: Some(t) }))
            .collect();
        let segments = points[1..]
            .iter()
            .enumerate()
            .map(|(k, p)| line(p, feed, blends[k], k as u32))
            .collect();
        let path = AxisPath { axes: axes.clone(), start: points[0].clone(), segments, tool_lever_arms: Vec::new() };
        let planned = plan(&path).unwrap();
        let t = planned.duration();
        prop_assert!(t.is_finite());
        let sp = fine(&planned);
        assert_within_limits(&sp, &axes, 1e-9);
        prop_assert_eq!(sp.position(sp.len() - 1), points.last().unwrap().as_slice());

        // Never slower than the simple safe profile stopping at every point.
        let exact_blends: Vec<_> = path.segments.iter().map(|s| {
            let mut s = s.clone();
            s.blend = Blend::ExactStop;
            s
        }).collect();
        let exact = plan(&AxisPath { segments: exact_blends, ..path.clone() }).unwrap();
        let safe: f64 = exact.segment_timings().iter().zip(points.windows(2)).map(|(timing, w)| {
            let length = distance(&w[0], &w[1]);
            if length > 0.0 { safe_duration(length, &timing.limits) } else { 0.0 }
        }).sum();
        prop_assert!(exact.duration() <= safe * (1.0 + 1e-12) + 1e-12);
        // Continuous corners never cost time over stopping.
        prop_assert!(t <= exact.duration() * (1.0 + 1e-9) + 1e-12, "{} > {}", t, exact.duration());

        // Every programmed point: passed exactly in exact stop, within tolerance otherwise.
        let dense = planned.sample(2e-5);
        for (k, point) in points.iter().enumerate().skip(1) {
            let allowed = match path.segments[k - 1].blend {
                _ if k == points.len() - 1 => 0.0,
                Blend::ExactStop => 0.0,
                Blend::Continuous { tolerance } => tolerance.unwrap(),
            };
            // Sampling slack: at most J·(T/2)³/6 from a stop, or the chord sagitta (v·T)²/(8·d)
            // of a blend passing at distance d (taken at d ≥ 1e-6).
            let vmax = axis_limits.iter().map(|l| l.0).fold(0.0, f64::max) * (n as f64).sqrt();
            let jmax = axis_limits.iter().map(|l| l.2).fold(0.0, f64::max) * (n as f64).sqrt();
            let slack = jmax * (1e-5_f64).powi(3) / 6.0 + (vmax * 2e-5).powi(2) / (8.0 * allowed.max(1e-6));
            let found = closest_approach(&dense, point);
            prop_assert!(found <= allowed + slack + 1e-15, "point {}: {} > {}", k, found, allowed);
        }
    }

    #[test]
    fn random_helical_arcs_respect_every_limit_and_stay_on_the_circle(
        axis_limits in prop::collection::vec(limits(), 3),
        radius in decades(1e-3, 0.1),
        start_angle in 0.0..std::f64::consts::TAU,
        sweep in 0.01..std::f64::consts::TAU,
        clockwise in prop::bool::ANY,
        turns in 0u32..2,
        rise in -0.02..0.02_f64,
        feed in prop::option::of(decades(0.005, 0.5)),
    ) {
        let axes = linear_axes(&axis_limits);
        let turn = if clockwise { -1.0 } else { 1.0 };
        let end_angle = start_angle + turn * sweep;
        let start = vec![radius * start_angle.cos(), radius * start_angle.sin(), 0.0];
        let end = vec![radius * end_angle.cos(), radius * end_angle.sin(), rise];
        let path = AxisPath {
            axes: axes.clone(),
            start: start.clone(),
            segments: vec![PathSegment {
                geometry: Geometry::Arc { plane: [0, 1], center: [0.0, 0.0], clockwise, turns, end: end.clone() },
                feed,
                feed_metric: vec![1.0; 3],
                blend: Blend::ExactStop,
                source_index: 0,
            }], tool_lever_arms: Vec::new(),
        };
        let planned = plan(&path).unwrap();
        prop_assert!(planned.duration().is_finite() && planned.duration() > 0.0);
        let sp = fine(&planned);
        assert_within_limits(&sp, &axes, 1e-9);
        let total_angle = sweep + 2.0 * std::f64::consts::PI * turns as f64;
        for k in 0..sp.len() {
            let p = sp.position(k);
            prop_assert!((p[0].hypot(p[1]) - radius).abs() <= 1e-12 * (1.0 + radius));
            // z rises linearly with the angle travelled, so it is monotone.
            if k > 0 {
                prop_assert!((p[2] - sp.position(k - 1)[2]) * rise.signum() >= -1e-15);
            }
        }
        prop_assert_eq!(sp.position(sp.len() - 1), end.as_slice());
        // Never faster than the arc length at the lowest plane-axis velocity limit allows.
        let arc_length = radius * total_angle;
        let v_plane = axis_limits[0].0.max(axis_limits[1].0) * 2f64.sqrt();
        prop_assert!(planned.duration() >= arc_length / v_plane);
    }
}
