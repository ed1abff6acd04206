//! The setpoint stream the co-simulation loop reads: its length is known before the first
//! sample, its samples are computed as they are read, and they are bit-identical to the
//! materialised setpoints, for every planner.

mod common;

use std::path::Path;

use cncsim::kinematics::AxisMap;
use cncsim::machine::Machine;
use cncsim::plan::{
    jerk_limited_plans, plan_program, plan_program_stream, AxisKind, AxisLimits, BlendChoice,
    PlanSettings, Planner, SetpointSample, SetpointStream, Setpoints,
};
use cncsim::program::{parse_gcode, Motion, Program, ReadOptions};
use common::{assert_stream_equals, bits};

/// Lines, arcs, dwells and a rapid, in both blend modes.
const PROGRAM: &str = "G21 G90 G64 P0.05
G0 X10 Y0 Z5
G1 Z0 F600
G1 X40 F1200
G2 X60 Y20 I0 J20
G4 P0.3
G1 X60 Y40
G3 X40 Y60 I-20 J0
G61
G1 X10 Y60
G4 P0.1
G0 Z5
M2
";

/// The same without arcs (the seed trapezoid profile is defined on straight moves only).
const LINES: &str = "G21 G90
G0 X10 Y0 Z5
G1 Z0 F600
G1 X40 F1200
G4 P0.3
G1 X40 Y30
G1 X10 Y60
G4 P0.1
G0 Z5
M2
";

fn machine() -> (Machine, AxisMap) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine = Machine::load(&root.join("models/xyz_table.urdf")).unwrap();
    let axes = AxisMap::new(&machine).unwrap();
    (machine, axes)
}

fn program(text: &str) -> Program {
    parse_gcode(text, "stream-test.ngc", &ReadOptions::default()).unwrap()
}

fn settings(machine: &Machine, planner: Planner, blend: BlendChoice) -> PlanSettings {
    PlanSettings {
        planner,
        period: 1e-3,
        rapid_speed: 0.05,
        blend,
        axis_names: machine.axes.iter().map(|a| a.name.clone()).collect(),
        naive_cam_tolerance: None,
        tool_lever_arms: Vec::new(),
    }
}

fn jerk_limited() -> Planner {
    Planner::JerkLimited {
        limits: vec![AxisLimits::from_program_units(AxisKind::Linear, 200.0, 2000.0, 50_000.0); 3],
    }
}

/// Every planner and blend mode on the program it accepts.
fn cases(machine: &Machine) -> Vec<(&'static str, Program, PlanSettings)> {
    vec![
        (
            "constant velocity",
            program(PROGRAM),
            settings(machine, Planner::ConstantVelocity, BlendChoice::Program),
        ),
        (
            "trapezoid",
            program(LINES),
            settings(
                machine,
                Planner::Trapezoid { acceleration: 1.0 },
                BlendChoice::Program,
            ),
        ),
        (
            "jerk-limited, as programmed",
            program(PROGRAM),
            settings(machine, jerk_limited(), BlendChoice::Program),
        ),
        (
            "jerk-limited, exact stop",
            program(PROGRAM),
            settings(machine, jerk_limited(), BlendChoice::ExactStop),
        ),
    ]
}

#[test]
fn streamed_and_materialised_setpoints_are_bit_identical() {
    let (machine, axes) = machine();
    for (what, program, settings) in cases(&machine) {
        let materialised = plan_program(&program, &axes, &settings).unwrap();
        assert!(materialised.len() > 1000, "{what}");
        // Two streams read in turn: no state is shared between them or with the first plan.
        let mut a = plan_program_stream(&program, &axes, &settings).unwrap();
        let mut b = plan_program_stream(&program, &axes, &settings).unwrap();
        let mut first = SetpointSample::zeros(3);
        for _ in 0..100 {
            assert!(a.next_sample(&mut first));
        }
        assert_stream_equals(b.as_mut(), &materialised, 0, what);
        // The first stream continues where it was.
        let mut rest = SetpointSample::zeros(3);
        let mut k = 100;
        while a.next_sample(&mut rest) {
            assert_eq!(
                bits(&rest.position),
                bits(materialised.position(k)),
                "{what}"
            );
            k += 1;
        }
        assert_eq!(k, materialised.len());
    }
}

#[test]
fn jerk_limited_stream_is_each_motion_sampled_and_each_dwell_held() {
    // Independently of the stream: the plans of the two motions between the dwells, each
    // sampled on its own from t = 0, joined (the second starts where the first ended), with
    // the dwells' whole periods of rest in between.
    let (machine, axes) = machine();
    let program = program(PROGRAM);
    let settings = settings(&machine, jerk_limited(), BlendChoice::Program);
    let plans = jerk_limited_plans(&program, &axes, &settings)
        .unwrap()
        .unwrap();
    assert_eq!(
        plans.len(),
        3,
        "motions before, between and after the dwells"
    );
    // The dwells: (move index, whole periods, rounded up).
    let dwells: Vec<(u32, usize)> = program
        .moves
        .iter()
        .enumerate()
        .filter_map(|(i, m)| match m.motion {
            Motion::Dwell { seconds } => Some((i as u32, (seconds / 1e-3).ceil() as usize)),
            _ => None,
        })
        .collect();
    assert_eq!(dwells.len(), 2);
    let mut expected = Setpoints::new(1e-3, 3);
    for (i, (_, plan)) in plans.iter().enumerate() {
        let part = plan.sample(1e-3);
        let skip = usize::from(i > 0);
        for k in skip..part.len() {
            expected.push(
                part.position(k),
                part.velocity(k),
                part.acceleration(k),
                part.segment[k],
            );
        }
        if let Some(&(dwell, ticks)) = dwells.get(i) {
            let at = part.position(part.len() - 1).to_vec();
            for _ in 0..ticks {
                expected.push(&at, &[0.0; 3], &[0.0; 3], dwell);
            }
        }
    }
    let mut stream = plan_program_stream(&program, &axes, &settings).unwrap();
    assert_stream_equals(stream.as_mut(), &expected, 0, "jerk-limited");
}

#[test]
fn a_ten_hour_program_streams_without_materialising() {
    // 36 million samples: materialised they would take 3.5 GB; the stream holds the moves.
    let (machine, axes) = machine();
    let program = program("G21 G90\nG1 X10 F600\nG4 P36000\nG1 X0\nM2\n");
    for planner in [Planner::ConstantVelocity, jerk_limited()] {
        let settings = settings(&machine, planner, BlendChoice::Program);
        let mut stream = plan_program_stream(&program, &axes, &settings).unwrap();
        assert!(stream.len() > 36_000_000 && stream.len() < 36_100_000);
        let mut sample = SetpointSample::zeros(3);
        for _ in 0..5000 {
            assert!(stream.next_sample(&mut sample));
        }
        assert!(sample.position[0] > 0.0);
    }
}

/// A bare machine-axis path's stream is its start at rest, then the whole plan's samples.
#[test]
fn path_stream_samples_the_whole_plan_bit_identically() {
    use cncsim::plan::{plan, plan_path_stream, AxisPath, AxisSpec, Blend, Geometry, PathSegment};
    let limits = AxisLimits::from_program_units(AxisKind::Linear, 200.0, 2000.0, 50_000.0);
    let axes: Vec<AxisSpec> = ["x", "y"]
        .iter()
        .map(|name| AxisSpec {
            name: name.to_string(),
            kind: AxisKind::Linear,
            limits,
        })
        .collect();
    // A zigzag of gentle corners with a sharp one every 50 moves: 2000 segments, so that the
    // stream plans many windows and cuts chains off at their ends.
    let segments = (0..2000)
        .map(|k| PathSegment {
            geometry: Geometry::Line {
                end: vec![
                    1e-3 * (k + 1) as f64,
                    if k % 50 == 49 {
                        -2e-3
                    } else {
                        1e-4 * (k % 2) as f64
                    },
                ],
            },
            feed: Some(0.05),
            feed_metric: vec![1.0, 1.0],
            blend: Blend::Continuous {
                tolerance: Some(1e-5),
            },
            source_index: k as u32,
        })
        .collect();
    let path = AxisPath {
        axes,
        start: vec![0.0, 0.0],
        segments,
        tool_lever_arms: Vec::new(),
    };
    let period = 1e-3;
    let expected = plan(&path).unwrap().sample(period);
    // Sample 0 is the path's start at rest; the rest are the plan's.
    let mut stream = plan_path_stream(path.clone(), period).unwrap();
    let mut sample = SetpointSample::zeros(2);
    assert!(stream.next_sample(&mut sample));
    assert_eq!(sample.position, path.start);
    assert_eq!(sample.velocity, [0.0; 2]);
    assert_eq!(sample.acceleration, [0.0; 2]);
    let mut stream = plan_path_stream(path, period).unwrap();
    assert_stream_equals(stream.as_mut(), &expected, 1, "path stream");
}
