//! Degenerate paths and invalid input.

mod common;

use cncsim::plan::{plan, AxisPath, Blend, Geometry, PathError, PathSegment};
use common::*;

fn axes() -> Vec<cncsim::plan::AxisSpec> {
    linear_axes(&[(0.1, 1.0, 10.0), (0.1, 1.0, 10.0)])
}

#[test]
fn empty_path_holds_the_start() {
    let path = AxisPath {
        axes: axes(),
        start: vec![0.01, 0.02],
        segments: vec![],
        tool_lever_arms: Vec::new(),
    };
    let plan = plan(&path).unwrap();
    assert_eq!(plan.duration(), 0.0);
    let sp = plan.sample(1e-3);
    assert_eq!(sp.len(), 1);
    assert_eq!(sp.position(0), &[0.01, 0.02]);
}

#[test]
fn repeated_points_take_no_time_and_break_nothing() {
    let blend = Blend::Continuous {
        tolerance: Some(1e-4),
    };
    let path = AxisPath {
        axes: axes(),
        start: vec![0.0, 0.0],
        segments: vec![
            line(&[0.01, 0.0], None, blend, 0),
            line(&[0.01, 0.0], None, blend, 1),
            line(&[0.01, 0.01], None, blend, 2),
        ],
        tool_lever_arms: Vec::new(),
    };
    let plan = plan(&path).unwrap();
    let timings = plan.segment_timings();
    assert_eq!(timings[1].duration, 0.0);
    let sp = fine(&plan);
    assert_within_limits(&sp, &path.axes, 1e-9);
    assert_eq!(sp.position(sp.len() - 1), &[0.01, 0.01]);
    // The zero-length block sits at the corner, which is therefore passed at rest.
    assert!(closest_approach(&dense(&plan), &[0.01, 0.0]) < 1e-12);
}

#[test]
fn invalid_input_is_reported() {
    let mut bad_limits = axes();
    bad_limits[1].limits.jerk = 0.0;
    let path = AxisPath {
        axes: bad_limits,
        start: vec![0.0; 2],
        segments: vec![],
        tool_lever_arms: Vec::new(),
    };
    assert_eq!(
        plan(&path).unwrap_err(),
        PathError::InvalidLimits { axis: 1 }
    );

    let path = AxisPath {
        axes: axes(),
        start: vec![0.0; 2],
        segments: vec![line(&[0.01, 0.0, 0.0], None, Blend::ExactStop, 0)],
        tool_lever_arms: Vec::new(),
    };
    assert!(matches!(
        plan(&path),
        Err(PathError::AxisCountMismatch {
            segment: Some(0),
            ..
        })
    ));

    let path = AxisPath {
        axes: axes(),
        start: vec![0.0; 2],
        segments: vec![line(&[f64::NAN, 0.0], None, Blend::ExactStop, 0)],
        tool_lever_arms: Vec::new(),
    };
    assert!(matches!(plan(&path), Err(PathError::InvalidValue { .. })));

    // Arc whose end is not on the circle through the start.
    let arc = |end: Vec<f64>, plane: [usize; 2]| AxisPath {
        axes: axes(),
        start: vec![0.01, 0.0],
        segments: vec![PathSegment {
            geometry: Geometry::Arc {
                plane,
                center: [0.0, 0.0],
                clockwise: false,
                turns: 0,
                end,
            },
            feed: None,
            feed_metric: vec![1.0; 2],
            blend: Blend::ExactStop,
            source_index: 0,
        }],
        tool_lever_arms: Vec::new(),
    };
    assert!(matches!(
        plan(&arc(vec![0.0, 0.02], [0, 1])),
        Err(PathError::InvalidArcRadius { segment: 0, .. })
    ));
    assert!(matches!(
        plan(&arc(vec![0.0, 0.01], [0, 0])),
        Err(PathError::InvalidArcPlane { segment: 0 })
    ));
    // A full circle: start = end.
    let full = plan(&arc(vec![0.01, 0.0], [0, 1])).unwrap();
    let sp = dense(&full);
    let min_x = (0..sp.len())
        .map(|k| sp.position(k)[0])
        .fold(f64::INFINITY, f64::min);
    assert!((min_x + 0.01).abs() < 1e-9, "went round: {min_x}");
    // Negative feed or tolerance.
    let mut path = arc(vec![0.0, 0.01], [0, 1]);
    path.segments[0].feed = Some(-1.0);
    assert!(matches!(
        plan(&path),
        Err(PathError::InvalidValue { what: "feed", .. })
    ));
    path.segments[0].feed = None;
    path.segments[0].blend = Blend::Continuous {
        tolerance: Some(-1.0),
    };
    assert!(matches!(
        plan(&path),
        Err(PathError::InvalidValue {
            what: "tolerance",
            ..
        })
    ));
}
