//! The seed trapezoidal profile (docs/sources.md §1.5).

use cncsim::plan::{trapezoid_line, TrapezoidProfile};

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * (1.0 + b.abs())
}

#[test]
fn trapezoid_phase_durations() {
    // 100 mm at V = 10 mm/s, A = 100 mm/s²: Δt1 = V/A = 0.1 s, Δs1 = A·Δt1²/2 = 0.5 mm,
    // Δs3 = V²/2A = 0.5 mm, Δs2 = 99 mm, Δt2 = 9.9 s.
    let p = TrapezoidProfile::new(0.1, 0.01, 0.1);
    assert!(!p.is_triangular());
    assert!(close(p.accel_time, 0.1) && close(p.decel_time, 0.1));
    assert!(close(p.cruise_time, 9.9));
    assert!(close(p.duration(), 10.1));
    let [s1, s2, s3] = p.phase_distances();
    assert!(close(s1, 0.0005) && close(s2, 0.099) && close(s3, 0.0005));
    assert!(close(p.peak_velocity, 0.01));
}

#[test]
fn triangle_phase_durations() {
    // 0.5 mm at V = 10 mm/s, A = 100 mm/s²: V²/A = 1 mm > 0.5 mm, so no cruise:
    // Δt1 = Δt3 = sqrt(L/A) = sqrt(0.005) s, Δs1 = Δs3 = L/2.
    let p = TrapezoidProfile::new(-0.0005, 0.01, 0.1);
    assert!(p.is_triangular());
    assert!(close(p.accel_time, 0.005_f64.sqrt()) && close(p.decel_time, 0.005_f64.sqrt()));
    assert_eq!(p.cruise_time, 0.0);
    let [s1, s2, s3] = p.phase_distances();
    assert!(close(s1, 0.00025) && s2.abs() < 1e-18 && close(s3, 0.00025));
    // Peak velocity sqrt(L·A) stays below V.
    assert!(close(p.peak_velocity, (0.0005_f64 * 0.1).sqrt()));
    // Negative distance: moves down.
    assert!(p.state(p.accel_time).1 < 0.0);
}

#[test]
fn boundary_between_trapezoid_and_triangle() {
    // Exactly |L| = V²/A: a trapezoid with a zero cruise, same as the triangle.
    let p = TrapezoidProfile::new(0.001, 0.01, 0.1);
    assert!(close(p.accel_time, 0.1) && p.cruise_time.abs() < 1e-12);
}

#[test]
fn sampled_profile_ends_exactly_on_target_and_is_continuous() {
    let p = TrapezoidProfile::new(0.1, 0.01, 0.1);
    let samples = p.sample_positions(0.004);
    // 10.1 s at 4 ms: 2525 periods, 2526 samples.
    assert_eq!(samples.len(), 2526);
    assert_eq!(*samples.last().unwrap(), 0.1);
    assert_eq!(samples[0], 0.0);
    // Monotone, steps never above V·T, and velocity continuous (second difference ≤ A·T²).
    for w in samples.windows(2) {
        assert!(w[1] >= w[0] && w[1] - w[0] <= 0.01 * 0.004 * (1.0 + 1e-9));
    }
    for w in samples.windows(3) {
        assert!((w[2] - 2.0 * w[1] + w[0]).abs() <= 0.1 * 0.004 * 0.004 * (1.0 + 1e-6));
    }
    // The cruise is at V·T per tick (0.04 mm, the digest's figure at 10 mm/s and 4 ms).
    assert!((samples[1000] - samples[999] - 4e-5).abs() < 1e-15);
    // A duration that is not a multiple of T still ends on the target.
    let q = TrapezoidProfile::new(0.0123, 0.01, 0.1);
    assert_eq!(*q.sample_positions(0.004).last().unwrap(), 0.0123);
}

#[test]
fn multi_axis_trapezoid_line_is_synchronised() {
    let sp = trapezoid_line(&[0.0, 0.0, 0.1], &[0.03, -0.04, 0.1], 0.01, 0.1, 0.001, 7);
    let last = sp.position(sp.len() - 1);
    assert_eq!(last, &[0.03, -0.04, 0.1]);
    for k in 0..sp.len() {
        let p = sp.position(k);
        // On the line: 4·x + 3·y = 0, z constant.
        assert!((4.0 * p[0] + 3.0 * p[1]).abs() < 1e-15 && p[2] == 0.1);
    }
    assert!(sp.segment.iter().all(|&s| s == 7));
    // 50 mm at 10 mm/s with 0.1 s ramps: 5.1 s.
    assert!((sp.duration() - 5.1).abs() < 1e-9);
}
