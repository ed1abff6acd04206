//! Regression tests for the planner's part of issue 13 (items 1 and 2): feeds, rapid speeds,
//! limits and dwells so small (or large) that a plan would need unbounded samples are refused
//! before anything is sampled, with the number of samples they would need and the limit; the
//! planner never panics or allocates without bound on them.

mod common;

use std::path::Path;

use cncsim::kinematics::AxisMap;
use cncsim::machine::Machine;
use cncsim::plan::{
    plan_program, plan_program_stream, BlendChoice, PlanError, PlanSettings, Planner,
    MAX_SETPOINT_SAMPLES,
};
use cncsim::program::{circle, parse_gcode, CircleSpec, Program, ReadOptions};

fn machine(file: &str) -> (Machine, AxisMap) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine = Machine::load(&root.join("models").join(file)).unwrap();
    let axes = AxisMap::new(&machine).unwrap();
    (machine, axes)
}

fn settings(machine: &Machine, planner: Planner, rapid_speed: f64) -> PlanSettings {
    PlanSettings {
        planner,
        period: 1e-3,
        rapid_speed,
        blend: BlendChoice::Program,
        axis_names: machine.axes.iter().map(|a| a.name.clone()).collect(),
        naive_cam_tolerance: None,
        tool_lever_arms: Vec::new(),
    }
}

fn jerk_limited(machine: &Machine, v: f64, a: f64, j: f64) -> Planner {
    Planner::JerkLimited {
        limits: common::uniform_axes(machine, v, a, j)
            .iter()
            .map(|axis| axis.limits)
            .collect(),
    }
}

/// Planning must be refused with the sample count, both materialised and as a stream.
fn assert_too_many_samples(program: &Program, axes: &AxisMap, settings: &PlanSettings) {
    let error = plan_program(program, axes, settings).unwrap_err();
    let PlanError::TooManySamples { needed, .. } = error else {
        panic!("expected TooManySamples, got {error:?}");
    };
    assert!(needed > MAX_SETPOINT_SAMPLES as f64, "{needed}");
    let message = error.to_string();
    assert!(
        message.contains("setpoint samples") && message.contains(&MAX_SETPOINT_SAMPLES.to_string()),
        "{message}"
    );
    assert!(matches!(
        plan_program_stream(program, axes, settings),
        Err(PlanError::TooManySamples { .. })
    ));
}

#[test]
fn circle_at_a_feed_of_1e_minus_300_is_refused_not_a_capacity_overflow() {
    // Issue 13 item 1: `feed_mm_s = 1e-300` on the built-in circle panicked with "capacity
    // overflow" in the constant-velocity interpolator.
    let (machine, axes) = machine("xyz_table.urdf");
    let program = circle(
        &CircleSpec {
            center: [0.1, 0.1],
            radius: 0.03,
            start_angle: 0.0,
            clockwise: false,
            z: 0.0,
            speed: 1e-303,
        },
        Path::new("circle"),
    );
    for planner in [
        Planner::ConstantVelocity,
        jerk_limited(&machine, 200.0, 2000.0, 50_000.0),
    ] {
        assert_too_many_samples(&program, &axes, &settings(&machine, planner, 0.05));
    }
}

#[test]
fn rapid_speed_of_1e_minus_300_is_refused() {
    // Issue 13 item 1: `rapid_mm_s = 1e-300` with a G-code program.
    let (machine, axes) = machine("xyz_table.urdf");
    let program = parse_gcode(
        "G0 X10 Y5\nG1 X20 F600\n",
        "rapid.ngc",
        &ReadOptions::default(),
    )
    .unwrap();
    for planner in [
        Planner::ConstantVelocity,
        Planner::Trapezoid { acceleration: 1.0 },
    ] {
        assert_too_many_samples(&program, &axes, &settings(&machine, planner, 1e-303));
    }
}

#[test]
fn planner_limits_of_1e_minus_300_are_refused_not_memory_without_bound() {
    // Issue 13 item 2: a jerk, acceleration or velocity limit of 1e-300 in `[planner] limits`
    // (here on the 5-axis study's program and machine) grew memory until the allocator aborted.
    let (machine, axes) = machine("ac_mill.urdf");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let program = cncsim::program::read_program(
        &root.join("scenarios/programs/d_table2.ngc"),
        &ReadOptions::default(),
    )
    .unwrap();
    for (v, a, j) in [
        (1e-300, 1000.0, 1000.0),
        (150.0, 1e-300, 1000.0),
        (150.0, 1000.0, 1e-300),
    ] {
        let planner = jerk_limited(&machine, v, a, j);
        assert_too_many_samples(&program, &axes, &settings(&machine, planner, 0.05));
    }
}

/// `text` is refused: by the G-code reader (with its message), or else by every planner in
/// `planners` with the sample count it would need.
fn assert_program_refused(text: &str, name: &str, planners: Vec<Planner>) {
    let (machine, axes) = machine("xyz_table.urdf");
    match parse_gcode(text, name, &ReadOptions::default()) {
        Err(e) => assert!(!e.to_string().is_empty()),
        Ok(program) => {
            for planner in planners {
                assert_too_many_samples(&program, &axes, &settings(&machine, planner, 0.05));
            }
        }
    }
}

#[test]
fn dwell_of_1e300_seconds_is_refused() {
    let (machine, _) = machine("xyz_table.urdf");
    assert_program_refused(
        "G1 X10 F600\nG4 P1e300\n",
        "dwell.ngc",
        vec![
            Planner::ConstantVelocity,
            Planner::Trapezoid { acceleration: 1.0 },
            jerk_limited(&machine, 200.0, 2000.0, 50_000.0),
        ],
    );
}

#[test]
fn an_arc_of_four_billion_turns_is_refused_quickly() {
    // G2 with P4294967295: the number of turns multiplies the arc's length, not the work.
    let (machine, _) = machine("xyz_table.urdf");
    assert_program_refused(
        "G1 X10 F6000\nG2 X10 Y0 I5 J0 P4294967295\n",
        "turns.ngc",
        vec![
            Planner::ConstantVelocity,
            jerk_limited(&machine, 200.0, 2000.0, 50_000.0),
        ],
    );
}

#[test]
fn the_largest_allowed_plan_is_counted_exactly() {
    // A dwell just under the limit plans (and is not sampled here); one period more is refused.
    let (machine, axes) = machine("xyz_table.urdf");
    let seconds = (MAX_SETPOINT_SAMPLES - 1) as f64 * 1e-3;
    let program = |s: f64| {
        parse_gcode(
            format!("G4 P{s}\n"),
            "long-dwell.ngc",
            &ReadOptions::default(),
        )
        .unwrap()
    };
    let settings = settings(&machine, Planner::ConstantVelocity, 0.05);
    let longest = program(seconds - 0.5e-3);
    let stream = plan_program_stream(&longest, &axes, &settings).unwrap();
    assert_eq!(stream.len(), MAX_SETPOINT_SAMPLES);
    assert_too_many_samples(&program(seconds + 0.5e-3), &axes, &settings);
}
