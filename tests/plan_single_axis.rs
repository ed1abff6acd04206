//! Single-axis rest-to-rest moves: durations equal the closed-form time-optimal durations in
//! every regime, and the sampled motion respects the limits and lands on the target.

mod common;

use cncsim::plan::{plan, AxisKind, AxisPath, Blend, Limits, Profile, Regime};
use common::*;

/// Limits (V, A, J), distance, regime, expected duration by hand.
type Case = ((f64, f64, f64), f64, Regime, f64);

fn cases() -> Vec<Case> {
    let jerk_limited = 4.0 * (0.1_f64 / 16.0).cbrt();
    let accel_limited = 0.25 + (0.0625_f64 + 1.0).sqrt();
    vec![
        // V = 1, A = 2, J = 8 (A²/J = 0.5 < V): L = 2 cruises, T = L/V + V/A + A/J.
        (
            (1.0, 2.0, 8.0),
            2.0,
            Regime::VelocityLimited,
            2.0 + 0.5 + 0.25,
        ),
        // L = 0.5 < 0.75 reaches A (L ≥ 2A³/J² = 0.25): T = A/J + sqrt((A/J)² + 4L/A).
        (
            (1.0, 2.0, 8.0),
            0.5,
            Regime::AccelerationLimited,
            accel_limited,
        ),
        // L = 0.1 < 0.25: jerk phases only, T = 4·(L/2J)^(1/3).
        ((1.0, 2.0, 8.0), 0.1, Regime::JerkLimited, jerk_limited),
        // V = 0.2 < A²/J = 0.5: A is never reached; cruising, T = L/V + 2·sqrt(V/J).
        (
            (0.2, 2.0, 8.0),
            1.0,
            Regime::VelocityLimited,
            5.0 + 2.0 * (0.2_f64 / 8.0).sqrt(),
        ),
        (
            (0.2, 2.0, 8.0),
            -0.01,
            Regime::JerkLimited,
            4.0 * (0.01_f64 / 16.0).cbrt(),
        ),
    ]
}

#[test]
fn durations_equal_closed_form_in_every_regime() {
    for ((v, a, j), distance, regime, expected) in cases() {
        let limits = Limits::new(v, a, j);
        let profile = Profile::rest_to_rest(distance, &limits);
        assert_eq!(
            Profile::rest_to_rest_regime(distance.abs(), &limits),
            regime
        );
        assert!(
            (profile.duration() - expected).abs() < 1e-12 * expected,
            "{regime:?}: {} vs {expected}",
            profile.duration()
        );
        assert!((closed_form_duration(distance, v, a, j) - expected).abs() < 1e-12 * expected);
        // The general planner (v0 = v1 = 0 via the numeric path) agrees.
        let general = Profile::plan(distance.abs(), 0.0, 0.0, &limits).unwrap();
        assert!((general.duration() - expected).abs() < 1e-12 * expected);
    }
}

#[test]
fn the_binding_limit_is_reached_in_each_regime() {
    for ((v, a, j), distance, regime, _) in cases() {
        let profile = Profile::rest_to_rest(distance, &Limits::new(v, a, j));
        let n = 20_000;
        let (mut peak_v, mut peak_a) = (0.0_f64, 0.0_f64);
        for k in 0..=n {
            let s = profile.state(profile.duration() * k as f64 / n as f64);
            peak_v = peak_v.max(s.velocity.abs());
            peak_a = peak_a.max(s.acceleration.abs());
        }
        match regime {
            Regime::VelocityLimited => assert!((peak_v - v).abs() < 1e-12),
            Regime::AccelerationLimited => {
                assert!((peak_a - a).abs() < 1e-9 && peak_v < v);
            }
            Regime::JerkLimited => assert!(peak_a < a && peak_v < v),
            Regime::Stationary => unreachable!(),
        }
    }
}

#[test]
fn sweep_of_lengths_matches_closed_form() {
    let limits = [
        (1.0, 2.0, 8.0),
        (0.2, 2.0, 8.0),
        (0.05, 0.5, 100.0),
        (3.0, 1.0, 0.5),
    ];
    for (v, a, j) in limits {
        for e in -60..=40 {
            let length = 10f64.powf(e as f64 / 10.0);
            let profile = Profile::rest_to_rest(length, &Limits::new(v, a, j));
            let expected = closed_form_duration(length, v, a, j);
            assert!(
                (profile.duration() - expected).abs() <= 1e-11 * expected,
                "L = {length}: {} vs {expected}",
                profile.duration()
            );
        }
    }
}

#[test]
fn sampled_single_axis_moves_respect_limits_and_land_on_target() {
    for ((v, a, j), distance, _, expected) in cases() {
        let axes = vec![axis("x", AxisKind::Linear, v, a, j)];
        let path = AxisPath {
            axes: axes.clone(),
            start: vec![0.25],
            segments: vec![line(&[0.25 + distance], None, Blend::ExactStop, 0)],
            tool_lever_arms: Vec::new(),
        };
        let plan = plan(&path).unwrap();
        assert!((plan.duration() - expected).abs() < 1e-12 * expected);
        let sp = fine(&plan);
        assert_within_limits(&sp, &axes, 1e-9);
        assert_eq!(sp.position(sp.len() - 1)[0], 0.25 + distance);
        assert_eq!(sp.position(0)[0], 0.25);
        // The move is monotone (no overshoot).
        let q = column(&sp, 0);
        assert!(q
            .windows(2)
            .all(|w| (w[1] - w[0]) * distance.signum() >= -1e-15));
    }
}
