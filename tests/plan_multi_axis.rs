//! Synchronised multi-axis straight moves in exact stop.

mod common;

use cncsim::plan::{plan, AxisPath, Blend, Limits, Profile};
use common::*;

fn three_axes() -> Vec<cncsim::plan::AxisSpec> {
    // Different limits on every axis so that different axes bind v, a and j.
    linear_axes(&[(0.5, 2.0, 20.0), (0.2, 5.0, 10.0), (1.0, 1.0, 50.0)])
}

#[test]
fn straight_move_stays_on_the_line_and_axes_finish_together() {
    let axes = three_axes();
    let start = vec![0.01, -0.02, 0.03];
    let end = vec![0.31, 0.08, -0.17];
    let path = AxisPath {
        axes: axes.clone(),
        start: start.clone(),
        segments: vec![line(&end, None, Blend::ExactStop, 4)],
        tool_lever_arms: Vec::new(),
    };
    let plan = plan(&path).unwrap();
    let sp = fine(&plan);
    assert_within_limits(&sp, &axes, 1e-9);
    let delta: Vec<f64> = start.iter().zip(&end).map(|(s, e)| e - s).collect();
    let mut first_motion = vec![usize::MAX; 3];
    let mut last_motion = vec![0; 3];
    for k in 0..sp.len() {
        let p = sp.position(k);
        // On the line: every axis at the same fraction of its own displacement.
        let fraction = (p[0] - start[0]) / delta[0];
        for i in 0..3 {
            assert!((p[i] - (start[i] + fraction * delta[i])).abs() < 1e-15);
            if k > 0 && p[i] != sp.position(k - 1)[i] {
                first_motion[i] = first_motion[i].min(k);
                last_motion[i] = k;
            }
        }
    }
    assert!(
        first_motion.iter().all(|&k| k == first_motion[0]),
        "{first_motion:?}"
    );
    assert!(
        last_motion.iter().all(|&k| k == last_motion[0]),
        "{last_motion:?}"
    );
    assert_eq!(sp.position(sp.len() - 1), end.as_slice());
    assert!(sp.segment.iter().all(|&s| s == 4));
}

#[test]
fn duration_is_the_closed_form_of_the_path_limits_and_no_axis_could_be_faster() {
    let axes = three_axes();
    let start = [0.0, 0.0, 0.0];
    let end = [0.3, 0.1, -0.2];
    let path = AxisPath {
        axes: axes.clone(),
        start: start.to_vec(),
        segments: vec![line(&end, None, Blend::ExactStop, 0)],
        tool_lever_arms: Vec::new(),
    };
    let plan = plan(&path).unwrap();
    // Path limits along the unit direction u: min over axes of limit_i / |u_i|.
    let length = (0.09_f64 + 0.01 + 0.04).sqrt();
    let u: Vec<f64> = end.iter().map(|e| (e / length).abs()).collect();
    let min = |f: &dyn Fn(usize) -> f64| (0..3).map(f).fold(f64::INFINITY, f64::min);
    let v = min(&|i| axes[i].limits.velocity / u[i]);
    let a = min(&|i| axes[i].limits.acceleration / u[i]);
    let j = min(&|i| axes[i].limits.jerk / u[i]);
    let expected = closed_form_duration(length, v, a, j);
    assert!((plan.duration() - expected).abs() < 1e-12 * expected);
    // Every axis alone would need at least its own time-optimal duration; the synchronised
    // move can't beat the slowest of them.
    for (i, axis) in axes.iter().enumerate() {
        let l = axis.limits;
        let alone = Profile::rest_to_rest(end[i], &Limits::new(l.velocity, l.acceleration, l.jerk));
        assert!(plan.duration() >= alone.duration() * (1.0 - 1e-12));
    }
}

#[test]
fn feed_limits_the_path_speed_in_its_metric() {
    let axes = three_axes();
    // Feed metric on the first two axes only: path speed = sqrt(q̇0² + q̇1²) ≤ 0.05.
    let mut segment = line(&[0.6, 0.8, 0.5], Some(0.05), Blend::ExactStop, 0);
    segment.feed_metric = vec![1.0, 1.0, 0.0];
    let path = AxisPath {
        axes: axes.clone(),
        start: vec![0.0; 3],
        segments: vec![segment],
        tool_lever_arms: Vec::new(),
    };
    let plan = plan(&path).unwrap();
    let sp = plan.sample(1e-3);
    let mut peak = 0.0_f64;
    for k in 1..sp.len() {
        let (p, q) = (sp.position(k - 1), sp.position(k));
        peak = peak.max(((q[0] - p[0]).hypot(q[1] - p[1])) / 1e-3);
    }
    assert!(
        peak <= 0.05 * (1.0 + 1e-9) && peak > 0.05 * (1.0 - 1e-6),
        "{peak}"
    );
    // Metric length 1 at 0.05 plus the ramps.
    assert!(plan.duration() > 20.0 && plan.duration() < 21.0);
}

#[test]
fn rotary_only_move_under_a_linear_feed_metric_is_not_limited_by_the_feed() {
    let mut axes = three_axes();
    axes[2].kind = cncsim::plan::AxisKind::Rotary;
    let mut segment = line(&[0.0, 0.0, 1.0], Some(1e-3), Blend::ExactStop, 0);
    segment.feed_metric = vec![1.0, 1.0, 0.0];
    let path = AxisPath {
        axes: axes.clone(),
        start: vec![0.0; 3],
        segments: vec![segment],
        tool_lever_arms: Vec::new(),
    };
    let plan = plan(&path).unwrap();
    let l = axes[2].limits;
    let expected = closed_form_duration(1.0, l.velocity, l.acceleration, l.jerk);
    assert!((plan.duration() - expected).abs() < 1e-12 * expected);
}
