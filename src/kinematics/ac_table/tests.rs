//! Tests of the A-C table kinematics against the URDF tree's own forward kinematics, the
//! closed-form formulas written out independently, and the study's CL program.

use super::*;
use crate::kinematics::{link_poses, tool_in_workpiece};
use crate::machine::{Joint, Link};
use crate::program::{read_program, Blend, Feed, Motion, Move, ReadOptions, Span};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

fn crate_path(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

pub(crate) fn ac_mill() -> Machine {
    Machine::load(&crate_path("models/ac_mill.urdf")).expect("ac_mill loads")
}

fn kinematics(machine: &Machine) -> AcTableKinematics {
    AcTableKinematics::new(machine).unwrap_or_else(|e| panic!("{e}"))
}

fn joint(machine: &Machine, name: &str) -> usize {
    machine
        .joints
        .iter()
        .position(|j| j.name == name)
        .unwrap_or_else(|| panic!("no joint '{name}'"))
}

/// The A-C mill with every simplification of the real one removed: A turns about −X and
/// does not pass through the base origin, C turns about −Z and is offset sideways from A, the
/// workpiece is rotated on the table, the Y slide runs along −Y, the tool point is off the
/// tool link origin. Still an A-C table machine, so the same closed form must hold.
pub(crate) fn general_variant() -> Machine {
    let mut m = ac_mill();
    let a = joint(&m, "a");
    let c = joint(&m, "c");
    let y = joint(&m, "y");
    let mount = joint(&m, "workpiece_mount");
    m.joints[a].axis = -Vector3::x();
    m.joints[a].origin = Isometry3::translation(0.01, 0.02, -0.03);
    m.joints[c].axis = -Vector3::z();
    m.joints[c].origin = Isometry3::translation(0.0, 0.05, -0.15);
    m.joints[mount].origin = Isometry3::from_parts(
        Translation3::new(0.08, -0.03, 0.12),
        UnitQuaternion::from_euler_angles(0.3, -0.2, 0.7),
    );
    m.joints[y].axis = -Vector3::y();
    m.tool.offset_m = [0.001, -0.002, 0.003];
    m
}

/// Tool axis (tool link +Z) in the workpiece frame, from the URDF tree.
fn tree_tool_axis(machine: &Machine, q: &[f64]) -> Vector3<f64> {
    let poses = link_poses(machine, q);
    poses[machine.workpiece_link]
        .inverse_transform_vector(&(poses[machine.tool_link].rotation * Vector3::z()))
}

fn unit_from_angles(theta: f64, phi: f64) -> Vector3<f64> {
    Vector3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

fn cl_error(a: &CutterLocation, b: &CutterLocation) -> f64 {
    (a.point - b.point).norm().max((a.axis - b.axis).norm())
}

pub(crate) fn in_travel_q() -> impl Strategy<Value = AcAxes> {
    (
        -0.3..0.3f64,
        -0.3..0.3f64,
        -0.35..0.1f64,
        -2.09..2.09f64,
        -10.0..10.0f64,
    )
        .prop_map(|(x, y, z, a, c)| AcAxes { x, y, z, a, c })
}

fn any_previous() -> impl Strategy<Value = AcAxes> {
    (-2.0..2.0f64, -20.0..20.0f64).prop_map(|(a, c)| AcAxes {
        a,
        c,
        ..AcAxes::default()
    })
}

#[test]
fn reads_the_chain_of_the_ac_mill() {
    let m = ac_mill();
    let k = kinematics(&m);
    for (axis, name) in AcAxis::ALL.iter().zip(["x", "y", "z", "a", "c"]) {
        assert_eq!(m.axes[k.machine_axis(*axis)].name, name);
    }
    assert_eq!(k.limits(AcAxis::X), Some([-0.30, 0.30]));
    assert_eq!(k.limits(AcAxis::Z), Some([-0.50, 0.10]));
    assert_eq!(k.limits(AcAxis::A), Some([-2.0944, 2.0944]));
    assert_eq!(k.limits(AcAxis::C), None, "C is a continuous joint");
    // Machine zero: the tool tip (0, 0, 0.39) m in the base, the workpiece origin at
    // (0.1, 0.1, -0.05) m, so the tip sits at (-0.1, -0.1, 0.44) m on the part, axis +Z.
    let zero = k.forward(&AcAxes::default());
    assert!((zero.point - Point3::new(-0.1, -0.1, 0.44)).norm() < 1e-15);
    assert!((zero.axis - Vector3::z()).norm() < 1e-15);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// The closed-form forward kinematics is the URDF tree's, to rounding.
    #[test]
    fn forward_agrees_with_the_urdf_tree(
        x in -1.0..1.0f64, y in -1.0..1.0f64, z in -1.0..1.0f64,
        a in -7.0..7.0f64, c in -20.0..20.0f64,
    ) {
        let q = AcAxes { x, y, z, a, c };
        for machine in [ac_mill(), general_variant()] {
            let k = kinematics(&machine);
            let cl = k.forward(&q);
            let mq = k.machine_q(&q);
            prop_assert_eq!(k.axes_from_machine_q(&mq), q);
            let point = tool_in_workpiece(&machine, &mq);
            prop_assert!((cl.point - point).norm() < 1e-12, "{:?} vs {:?}", cl.point, point);
            let axis = tree_tool_axis(&machine, &mq);
            prop_assert!((cl.axis - axis).norm() < 1e-12, "{:?} vs {:?}", cl.axis, axis);
        }
    }

    /// forward(inverse(R)) = R for reachable cutter locations, from any previous position.
    #[test]
    fn forward_of_inverse_is_the_cutter_location(q in in_travel_q(), previous in any_previous()) {
        for machine in [ac_mill(), general_variant()] {
            let k = kinematics(&machine);
            let target = k.forward(&q);
            let solution = k.inverse(&target, &previous).map_err(|e| {
                TestCaseError::fail(format!("{e} for {q:?}"))
            })?;
            let reached = k.forward(&solution.axes);
            prop_assert!(cl_error(&reached, &target) < 1e-9, "{:?} vs {:?}", reached, target);
            // And the URDF tree agrees that the tool is there.
            let mq = k.machine_q(&solution.axes);
            prop_assert!((tool_in_workpiece(&machine, &mq) - target.point).norm() < 1e-9);
        }
    }

    /// Any cutter location: either the inverse reaches it, or each branch is refused for an
    /// axis that really is outside its travel.
    #[test]
    fn inverse_reaches_or_names_the_axis(
        theta in 0.0..PI, phi in -PI..PI,
        px in -0.4..0.4f64, py in -0.4..0.4f64, pz in -0.6..0.6f64,
        previous in any_previous(),
    ) {
        let k = kinematics(&ac_mill());
        let target = CutterLocation {
            point: Point3::new(px, py, pz),
            axis: unit_from_angles(theta, phi),
        };
        match k.inverse(&target, &previous) {
            Ok(solution) => {
                prop_assert!(cl_error(&k.forward(&solution.axes), &target) < 1e-9);
                for axis in AcAxis::ALL {
                    if let Some([lower, upper]) = k.limits(axis) {
                        let v = solution.axes.get(axis);
                        prop_assert!(v >= lower - 1e-9 && v <= upper + 1e-9);
                    }
                }
            }
            Err(AcInverseError::OutOfTravel { violations }) => {
                for branch in [Branch::First, Branch::Second] {
                    prop_assert!(violations.iter().any(|v| v.branch == branch));
                }
                for v in &violations {
                    prop_assert!(v.value < v.lower || v.value > v.upper, "{}", v);
                }
            }
            Err(e) => prop_assert!(false, "unexpected {e}"),
        }
    }

    /// inverse(forward(q)) = q when the previous position is near q (its branch and its
    /// turn of C, even several turns away from the principal value).
    #[test]
    fn inverse_of_forward_is_q_on_its_branch(
        q in in_travel_q(),
        da in -0.05..0.05f64, dc in -0.05..0.05f64, turns in -3i32..=3,
    ) {
        prop_assume!(q.a.abs() > 0.06);
        let k = kinematics(&ac_mill());
        let q = AcAxes { c: q.c + TAU * f64::from(turns), ..q };
        let previous = AcAxes { a: q.a + da, c: q.c + dc, ..AcAxes::default() };
        let solution = k.inverse(&k.forward(&q), &previous).unwrap();
        let expected = if q.a > 0.0 { Branch::First } else { Branch::Second };
        prop_assert_eq!(solution.branch, expected);
        prop_assert!(!solution.forced_by_travel);
        for (got, want) in solution.axes.to_array().iter().zip(q.to_array()) {
            prop_assert!((got - want).abs() < 1e-9, "{:?} vs {:?}", solution.axes, q);
        }
    }

    /// The module documentation's formulas, typed in independently with the URDF's numbers,
    /// give the same machine coordinates as the kinematics built from the chain.
    #[test]
    fn matches_the_written_out_formulas(
        theta in 0.01..2.0f64, phi in -PI..PI,
        px in -0.1..0.1f64, py in -0.1..0.1f64, pz in -0.1..0.1f64,
    ) {
        let k = kinematics(&ac_mill());
        let o = unit_from_angles(theta, phi);
        let (i, j, kk) = (o.x, o.y, o.z);
        let a = (i.hypot(j)).atan2(kk);
        let c = i.atan2(j);
        let (u1, u2, u3) = (px + 0.1, py + 0.1, pz + 0.1);
        let (z_ac, t_z) = (-0.15, 0.45 - 0.06);
        let turned = u1 * c.sin() + u2 * c.cos();
        let expected = [
            u1 * c.cos() - u2 * c.sin(),
            turned * a.cos() - (u3 + z_ac) * a.sin(),
            turned * a.sin() + (u3 + z_ac) * a.cos() - t_z,
            a,
            c,
        ];
        let RotarySolutions::Regular([first, second]) = k.rotary_solutions(&o) else {
            panic!("not singular");
        };
        prop_assert!((first.0 - a).abs() < 1e-12 && (first.1 - c).abs() < 1e-12);
        prop_assert!((second.0 + a).abs() < 1e-12);
        prop_assert!(((second.1 - c).rem_euclid(TAU) - PI).abs() < 1e-12);
        let linear = k.linear_axes(&Point3::new(px, py, pz), a, c);
        for (got, want) in linear.iter().zip(&expected[..3]) {
            prop_assert!((got - want).abs() < 1e-12, "{:?} vs {:?}", linear, expected);
        }
    }
}

/// The largest round-trip error over many reachable cutter locations (figures for the
/// report; run with `--nocapture`).
#[test]
fn round_trip_error_budget() {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut uniform = |lo: f64, hi: f64| {
        // SplitMix64: deterministic, no dependency.
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        lo + (hi - lo) * (z >> 11) as f64 / (1u64 << 53) as f64
    };
    for (label, machine) in [("ac_mill", ac_mill()), ("general", general_variant())] {
        let k = kinematics(&machine);
        let (mut worst_cl, mut worst_q) = (0.0f64, 0.0f64);
        for _ in 0..100_000 {
            let q = AcAxes {
                x: uniform(-0.3, 0.3),
                y: uniform(-0.3, 0.3),
                z: uniform(-0.35, 0.1),
                a: uniform(-2.09, 2.09),
                c: uniform(-PI, PI),
            };
            let target = k.forward(&q);
            let solution = k.inverse(&target, &q).unwrap();
            worst_cl = worst_cl.max(cl_error(&k.forward(&solution.axes), &target));
            let dq = solution.axes.to_array();
            let q = q.to_array();
            worst_q = worst_q.max((0..5).map(|i| (dq[i] - q[i]).abs()).fold(0.0, f64::max));
        }
        println!("{label}: max |forward(inverse(R)) - R| = {worst_cl:.3e}, max |inverse(forward(q)) - q| = {worst_q:.3e}");
        assert!(worst_cl < 1e-12, "{label}: {worst_cl}");
        // q is recovered to the conditioning of atan2 near A = 0 (1/sin A); well inside 1e-9.
        assert!(worst_q < 1e-9, "{label}: {worst_q}");
    }
}

#[test]
fn tool_axis_along_c_keeps_c() {
    let k = kinematics(&ac_mill());
    // 0.15 m above the part origin: with the tool vertical, Z travel ends 0.09 m above it.
    let p = Point3::new(0.01, -0.02, 0.15);
    for previous_c in [0.0, 1.234, -2.5, 1.234 + 4.0 * PI] {
        let previous = AcAxes {
            a: 0.3,
            c: previous_c,
            ..AcAxes::default()
        };
        let target = CutterLocation {
            point: p,
            axis: Vector3::z(),
        };
        let solution = k.inverse(&target, &previous).unwrap();
        assert_eq!(solution.branch, Branch::Singular);
        assert_eq!(solution.axes.a, 0.0);
        assert_eq!(solution.axes.c, previous_c, "C must stay where it was");
        assert!(cl_error(&k.forward(&solution.axes), &target) < 1e-15);
    }
    // Rounding-level tilt is still the singularity; a real tilt of 1e-8 rad is not.
    let almost = Vector3::new(1e-13, -1e-13, 1.0).normalize();
    assert_eq!(
        k.rotary_solutions(&almost),
        RotarySolutions::Singular { a: 0.0 }
    );
    assert!(matches!(
        k.rotary_solutions(&Vector3::new(1e-8, 0.0, 1.0).normalize()),
        RotarySolutions::Regular(_)
    ));
    // A tool axis pointing down the C axis needs A = 180°, beyond the cradle's travel.
    assert_eq!(
        k.rotary_solutions(&-Vector3::z()),
        RotarySolutions::Singular { a: PI }
    );
}

#[test]
fn a_path_through_the_singularity_keeps_c_and_passes_a_through_zero() {
    let k = kinematics(&ac_mill());
    let phi = 0.7;
    let mut previous = AcAxes {
        c: 0.2,
        ..AcAxes::default()
    };
    // The tool axis swings in a vertical plane through the C axis: θ from −0.5 to 0.5 rad.
    for i in -100..=100 {
        let theta = 0.005 * f64::from(i);
        let target = CutterLocation {
            point: Point3::new(0.02, 0.01, 0.25),
            axis: unit_from_angles(theta, phi),
        };
        let solution = k.inverse(&target, &previous).unwrap();
        // In this plane C = π/2 − φ on the A < 0 side and the A > 0 side alike: the table
        // does not turn at all, the cradle tilts through zero.
        assert!(
            (solution.axes.a - theta).abs() < 1e-12,
            "step {i}: {solution:?}"
        );
        assert!(
            (solution.axes.c - (PI / 2.0 - phi)).abs() < 1e-12,
            "step {i}: {solution:?}"
        );
        let expected = match i {
            ..0 => Branch::Second,
            0 => Branch::Singular,
            _ => Branch::First,
        };
        assert_eq!(solution.branch, expected, "step {i}");
        assert!(cl_error(&k.forward(&solution.axes), &target) < 1e-12);
        previous = solution.axes;
    }
}

#[test]
fn a_path_grazing_the_singularity_turns_c_without_jumps() {
    let k = kinematics(&ac_mill());
    let mut previous = AcAxes::default();
    let mut first_c = None;
    let epsilon = 0.001;
    for i in -30..=30 {
        let t = 0.01 * f64::from(i);
        let target = CutterLocation {
            point: Point3::new(0.0, 0.0, 0.15),
            axis: Vector3::new(t, epsilon, 1.0).normalize(),
        };
        let solution = k.inverse(&target, &previous).unwrap();
        let q = solution.axes;
        if i > -30 {
            // Near the pole C has to sweep fast, but never by a turn or a branch-flip's π.
            assert!(
                (q.c - previous.c).abs() < PI / 2.0,
                "step {i}: {q:?} after {previous:?}"
            );
            assert!(
                (q.a - previous.a).abs() < 0.02,
                "step {i}: {q:?} after {previous:?}"
            );
        }
        first_c.get_or_insert(q.c);
        previous = q;
    }
    // C turned by atan2(0.3, ε) − atan2(−0.3, ε), just under half a turn.
    let swept = previous.c - first_c.unwrap();
    let expected = (0.3f64).atan2(epsilon) - (-0.3f64).atan2(epsilon);
    assert!((swept.abs() - expected).abs() < 1e-12, "swept {swept}");
}

#[test]
fn the_branch_nearest_the_previous_position_wins() {
    let k = kinematics(&ac_mill());
    let q = AcAxes {
        x: 0.01,
        y: -0.02,
        z: -0.1,
        a: 0.5,
        c: 0.3,
    };
    let target = k.forward(&q);
    let mirrored = AcAxes {
        a: -0.5,
        c: 0.3 + PI,
        ..q
    };
    // Same tool axis on the other branch …
    assert!((k.forward(&mirrored).axis - target.axis).norm() < 1e-15);
    // … chosen according to where the machine comes from.
    let near_first = k.inverse(&target, &AcAxes::default()).unwrap();
    assert_eq!(near_first.branch, Branch::First);
    assert!((near_first.axes.a - 0.5).abs() < 1e-12 && (near_first.axes.c - 0.3).abs() < 1e-12);
    let from_second = AcAxes {
        a: -0.4,
        c: 3.3,
        ..AcAxes::default()
    };
    let near_second = k.inverse(&target, &from_second).unwrap();
    assert_eq!(near_second.branch, Branch::Second);
    assert!((near_second.axes.a + 0.5).abs() < 1e-12);
    assert!((near_second.axes.c - (0.3 + PI)).abs() < 1e-12);
    // Both reach the same cutter location with different linear axes.
    assert!(cl_error(&k.forward(&near_second.axes), &target) < 1e-12);
    assert!((near_second.axes.y - near_first.axes.y).abs() > 1e-3);
    // The turn of C follows the previous position: 5 turns up, C stays 5 turns up.
    let wound = AcAxes {
        c: 0.35 + 5.0 * TAU,
        a: 0.45,
        ..AcAxes::default()
    };
    let solution = k.inverse(&target, &wound).unwrap();
    assert!((solution.axes.c - (0.3 + 5.0 * TAU)).abs() < 1e-9);
    // Exactly half-way between the two branches: branch 1, deterministically.
    let tie = AcAxes {
        a: 0.0,
        c: 0.3 + PI / 2.0,
        ..AcAxes::default()
    };
    assert_eq!(k.inverse(&target, &tie).unwrap().branch, Branch::First);
}

#[test]
fn a_branch_outside_the_travel_is_skipped_with_notice() {
    let mut machine = ac_mill();
    let a = joint(&machine, "a");
    machine.joints[a].limits = Some([-0.2, 2.0]);
    let k = kinematics(&machine);
    let q = AcAxes {
        a: 1.0,
        c: 0.4,
        ..AcAxes::default()
    };
    let target = k.forward(&q);
    // The machine sits on the A < 0 side, where the mirrored solution (A = −1) would be
    // nearest; the cradle cannot go there, so branch 1 is taken and flagged.
    let previous = AcAxes {
        a: -0.1,
        c: 0.4 + PI,
        ..AcAxes::default()
    };
    let solution = k.inverse(&target, &previous).unwrap();
    assert_eq!(solution.branch, Branch::First);
    assert!(solution.forced_by_travel);
    assert!((solution.axes.a - 1.0).abs() < 1e-12);
}

#[test]
fn unreachable_cutter_locations_name_the_axis_and_value() {
    let k = kinematics(&ac_mill());
    // Tool axis pointing down at 45°: the cradle would have to tilt 135° either way.
    let down = CutterLocation {
        point: Point3::origin(),
        axis: Vector3::new(-1.0, 0.0, -1.0).normalize(),
    };
    let error = k.inverse(&down, &AcAxes::default()).unwrap_err();
    let AcInverseError::OutOfTravel { violations } = &error else {
        panic!("{error}");
    };
    // A on both branches (and Z, for a point this low).
    let on_a: Vec<_> = violations.iter().filter(|v| v.axis == AcAxis::A).collect();
    assert_eq!(on_a.len(), 2, "{error}");
    assert_ne!(on_a[0].branch, on_a[1].branch);
    for v in on_a {
        assert!((v.value.abs() - 0.75 * PI).abs() < 1e-12);
    }
    let text = error.to_string();
    assert!(
        text.contains("axis 'a' would be at 135.000°, outside its travel [-120.000°, 120.000°]"),
        "{text}"
    );
    assert!(text.contains("axis 'a' would be at -135.000°"), "{text}");

    // A point far out along X, tool vertical: only X is out, at the requested value.
    let far = CutterLocation {
        point: Point3::new(0.5, 0.0, 0.15),
        axis: Vector3::z(),
    };
    let error = k.inverse(&far, &AcAxes::default()).unwrap_err();
    let AcInverseError::OutOfTravel { violations } = &error else {
        panic!("{error}");
    };
    assert_eq!(violations.len(), 1);
    assert_eq!(violations[0].axis, AcAxis::X);
    assert!((violations[0].value - 0.6).abs() < 1e-12);
    assert!(
        error.to_string().contains(
            "axis 'x' would be at 600.000 mm, outside its travel [-300.000 mm, 300.000 mm]"
        ),
        "{error}"
    );

    // Too deep: Z.
    let deep = CutterLocation {
        point: Point3::new(0.0, 0.0, 1.0),
        axis: Vector3::z(),
    };
    let error = k
        .inverse(&deep, &AcAxes::default())
        .unwrap_err()
        .to_string();
    assert!(error.contains("axis 'z' would be at 560.000 mm"), "{error}");
}

#[test]
fn bad_tool_axes_are_refused() {
    let k = kinematics(&ac_mill());
    let cl = |axis: Vector3<f64>| CutterLocation {
        point: Point3::new(0.0, 0.0, 0.15),
        axis,
    };
    let error = k
        .inverse(&cl(Vector3::new(0.12, 0.3, 0.3)), &AcAxes::default())
        .unwrap_err();
    assert!(matches!(error, AcInverseError::NotUnit { .. }), "{error}");
    assert!(
        error.to_string().contains("expected a unit vector"),
        "{error}"
    );
    let error = k
        .inverse(&cl(Vector3::new(f64::NAN, 0.0, 1.0)), &AcAxes::default())
        .unwrap_err();
    assert!(matches!(error, AcInverseError::NotFinite { .. }), "{error}");
    // A normalised vector with rounding is fine.
    let rounded = Vector3::new(0.6, 0.0, 0.8) * (1.0 + 1e-12);
    assert!(k.inverse(&cl(rounded), &AcAxes::default()).is_ok());
}

fn topology_error(machine: &Machine) -> String {
    match AcTableKinematics::new(machine) {
        Ok(_) => panic!("expected a topology error"),
        Err(e) => e.to_string(),
    }
}

fn assert_contains(text: &str, needle: &str) {
    assert!(text.contains(needle), "expected '{needle}' in: {text}");
}

#[test]
fn machines_of_another_topology_are_refused_with_the_reason() {
    // The XYZ table: no rotary axes at all.
    let xyz = Machine::load(&crate_path("models/xyz_table.urdf")).unwrap();
    assert_contains(
        &topology_error(&xyz),
        "machine 'xyz_table' is not a table-tilting A-C mill: 0 revolute joint(s) carry the \
         workpiece (link 'base'); expected two",
    );

    let mutate = |f: &dyn Fn(&mut Machine)| {
        let mut m = ac_mill();
        f(&mut m);
        topology_error(&m)
    };
    assert_contains(
        &mutate(&|m| {
            let a = joint(m, "a");
            m.joints[a].axis = Vector3::y();
        }),
        "the first rotary joint from the base to the workpiece, 'a', turns about (0.000000, \
         1.000000, 0.000000) in the base frame; expected the base X axis",
    );
    assert_contains(
        &mutate(&|m| {
            let c = joint(m, "c");
            m.joints[c].axis = Vector3::x();
        }),
        "the second rotary joint, 'c' (carried by 'a'), turns about (1.000000, 0.000000, \
         0.000000) in the base frame at A = 0; expected the base Z axis",
    );
    // C tilted on the cradle by a rotated origin is caught in the base frame too.
    assert_contains(
        &mutate(&|m| {
            let c = joint(m, "c");
            m.joints[c].origin.rotation = UnitQuaternion::from_euler_angles(0.1, 0.0, 0.0);
        }),
        "'c' (carried by 'a'), turns about (0.000000, -0.099833, 0.995004)",
    );
    assert_contains(
        &mutate(&|m| {
            let z = joint(m, "z");
            m.joints[z].kind = JointKind::Revolute;
        }),
        "revolute joint 'z' is on the tool's branch",
    );
    assert_contains(
        &mutate(&|m| {
            let c = joint(m, "c");
            m.joints[c].kind = JointKind::Prismatic;
        }),
        "prismatic joint 'c' is on the workpiece's branch",
    );
    assert_contains(
        &mutate(&|m| {
            let y = joint(m, "y");
            m.joints[y].axis = Vector3::new(1.0, 1.0, 0.0).normalize();
        }),
        "prismatic joint 'y' moves along (0.707107, 0.707107, 0.000000) in the base frame",
    );
    assert_contains(
        &mutate(&|m| {
            let y = joint(m, "y");
            m.joints[y].axis = Vector3::x();
        }),
        "joints 'x' and 'y' both move the tool along base X",
    );
    assert_contains(
        &mutate(&|m| {
            let mount = joint(m, "tool_mount");
            m.joints[mount].origin.rotation = UnitQuaternion::from_euler_angles(PI / 2.0, 0.0, 0.0);
        }),
        "the spindle direction (the tool link's +Z, from the tool tip towards the spindle) is \
         (0.000000, -1.000000, 0.000000) in the base frame; expected base +Z",
    );
    assert_contains(
        &mutate(&|m| {
            let (x, y) = (m.axis_index("x").unwrap(), m.axis_index("y").unwrap());
            m.axes[x].name = "y".into();
            m.axes[y].name = "x".into();
        }),
        "axis 'y' drives joint 'x', which is the machine's X axis; expected it to be named 'x'",
    );
    assert_contains(
        &mutate(&|m| {
            // The cradle hung from the X carriage: X would move the tool and the part alike.
            let a = joint(m, "a");
            m.joints[a].parent = m.link_index("x_carriage").unwrap();
        }),
        "joint 'x' moves both the tool and the workpiece",
    );
    assert_contains(
        &mutate(&|m| {
            // C first, then A: a rotary table carrying a tilting cradle is another machine.
            let (a, c) = (joint(m, "a"), joint(m, "c"));
            m.joints[a].axis = Vector3::z();
            m.joints[c].axis = Vector3::x();
        }),
        "'a', turns about (0.000000, 0.000000, 1.000000) in the base frame; expected the base \
         X axis",
    );
    assert_contains(
        &mutate(&|m| {
            // A tool changer arm on the base: moves neither the tool nor the part.
            let base = m.root;
            let changer = Link {
                name: "changer".into(),
                ..m.links[m.tool_link].clone()
            };
            m.links.push(changer);
            m.joints.push(Joint {
                name: "changer_arm".into(),
                kind: JointKind::Revolute,
                parent: base,
                child: m.links.len() - 1,
                origin: Isometry3::identity(),
                axis: Vector3::z(),
                limits: None,
                damping: 0.0,
                friction: 0.0,
                mimic: None,
                place: None,
            });
        }),
        "joint 'changer_arm' moves neither the tool (link 'tool') nor the workpiece (link \
         'workpiece')",
    );
    assert_contains(
        &mutate(&|m| {
            // The table clamped: only one rotary carries the part.
            let c = joint(m, "c");
            m.joints[c].kind = JointKind::Fixed;
        }),
        "1 revolute joint(s) carry the workpiece (link 'workpiece'): 'a'; expected two",
    );
}

fn d_table1() -> Program {
    read_program(
        &crate_path("scenarios/programs/d_table1.apt"),
        &ReadOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_studys_cl_program_starts_outside_the_cradle_travel() {
    let k = kinematics(&ac_mill());
    let program = d_table1();
    let errors = k
        .program_to_machine(&program, &AcAxes::default())
        .unwrap_err();
    // Only the first point: its tool axis (−0.5, 0, −0.5) points 45° below the horizon.
    assert_eq!(errors.errors.len(), 1, "{errors}");
    let error = &errors.errors[0];
    assert_eq!(error.span.unwrap().line, 6);
    let text = error.to_string();
    println!("{text}");
    assert!(
        text.contains("d_table1.apt:6:1: outside the machine's travel"),
        "{text}"
    );
    assert!(text.contains("axis 'a' would be at -135.000°"), "{text}");
    assert!(text.contains("axis 'a' would be at 135.000°"), "{text}");
}

#[test]
fn the_studys_cl_program_in_machine_coordinates() {
    let k = kinematics(&ac_mill());
    let mut program = d_table1();
    program.moves.remove(0);
    let machine = k
        .program_to_machine(&program, &AcAxes::default())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(machine.start, AcAxes::default().to_position());
    assert_eq!(machine.moves.len(), 3);
    // All three share the tool axis (0.12, 0.3, 0.3)/|·|: A = atan2(√(i²+j²), k), C = atan2(i, j).
    let (i, j, kk) = (0.12f64, 0.3f64, 0.3f64);
    let a = i.hypot(j).atan2(kk);
    let c = i.atan2(j);
    println!("d_table1.apt (without its first point) in machine coordinates:");
    for (cl, m) in program.moves.iter().zip(&machine.moves) {
        let q = AcAxes::from_position(&m.end);
        println!(
            "  line {}: X {:9.4} mm  Y {:9.4} mm  Z {:9.4} mm  A {:8.4}°  C {:8.4}°",
            m.span.line,
            q.x * 1e3,
            q.y * 1e3,
            q.z * 1e3,
            q.a.to_degrees(),
            q.c.to_degrees()
        );
        assert!((q.a - a).abs() < 1e-12 && (q.c - c).abs() < 1e-12);
        // Independently: the written-out linear formulas.
        let [px, py, pz] = cl.end.linear;
        let (u1, u2, u3) = (px + 0.1, py + 0.1, pz + 0.1);
        let turned = u1 * c.sin() + u2 * c.cos();
        assert!((q.x - (u1 * c.cos() - u2 * c.sin())).abs() < 1e-12);
        assert!((q.y - (turned * a.cos() - (u3 - 0.15) * a.sin())).abs() < 1e-12);
        assert!((q.z - (turned * a.sin() + (u3 - 0.15) * a.cos() - 0.39)).abs() < 1e-12);
        // What the program keeps.
        assert_eq!(m.span, cl.span);
        assert_eq!(m.feed, cl.feed);
        assert!(matches!(m.feed, Feed::PathSpeed(_)));
        assert_eq!(m.feed_rule, cl.feed_rule);
        assert_eq!(m.blend, Blend::ExactStop);
        assert_eq!(m.tool_axis, None);
        assert_eq!(m.end.rotary[1], 0.0);
    }
    assert_eq!(machine.warnings, program.warnings);
    // Regression values (mm, degrees), checked above against the formulas.
    let q = AcAxes::from_position(&machine.moves[2].end);
    let expected = [64.9934, 145.9339, -196.0821, 47.1240, 21.8014];
    let got = [
        q.x * 1e3,
        q.y * 1e3,
        q.z * 1e3,
        q.a.to_degrees(),
        q.c.to_degrees(),
    ];
    for (g, e) in got.iter().zip(expected) {
        assert!((g - e).abs() < 1e-4, "{got:?} vs {expected:?}");
    }
}

fn cl_move(line: u32, end: [f64; 3], tool_axis: Option<[f64; 3]>, motion: Motion) -> Move {
    Move {
        motion,
        end: Position {
            linear: end,
            rotary: [0.0; 3],
        },
        tool_axis,
        feed: Feed::PathSpeed(0.01),
        feed_rule: Default::default(),
        blend: Blend::Continuous {
            tolerance: Some(1e-5),
            naive_cam: None,
        },
        tool_down: None,
        spindle: Default::default(),
        span: Span {
            line,
            column: 1,
            byte_offset: 0,
        },
    }
}

#[test]
fn program_conversion_reports_every_bad_move_at_its_line() {
    let k = kinematics(&ac_mill());
    let up = Some([0.0, 0.0, 1.0]);
    let tilted = Some([0.0, 0.6, 0.8]);
    let program = Program {
        source: "part.apt".into(),
        moves: vec![
            cl_move(3, [0.0, 0.0, 0.15], tilted, Motion::Linear),
            cl_move(4, [0.01, 0.0, 0.15], None, Motion::Linear),
            cl_move(5, [0.5, 0.0, 0.15], up, Motion::Linear),
            cl_move(6, [0.0, 0.0, 0.15], up, Motion::Dwell { seconds: 1.0 }),
            cl_move(
                7,
                [0.01, 0.0, 0.15],
                up,
                Motion::Arc {
                    center: [0.0; 3],
                    plane: crate::program::Plane::XY,
                    clockwise: false,
                    turns: 0,
                },
            ),
            cl_move(8, [0.0, 0.01, 0.15], up, Motion::Linear),
        ],
        ..Program::default()
    };
    let errors = k
        .program_to_machine(&program, &AcAxes::default())
        .unwrap_err();
    let lines: Vec<u32> = errors.errors.iter().map(|e| e.span.unwrap().line).collect();
    assert_eq!(lines, [4, 5, 7], "{errors}");
    let text = errors.to_string();
    assert_contains(&text, "part.apt:4:1: expected a tool-axis vector");
    assert_contains(
        &text,
        "part.apt:5:1: outside the machine's travel: axis 'x' would be at 600.000 mm",
    );
    assert_contains(&text, "part.apt:7:1: an arc in workpiece coordinates");

    // Without the bad moves: the dwell stays put, the last move comes from the tilted one
    // through the singular (vertical) axis with C kept, and blends, feeds, spans survive.
    let good = Program {
        moves: [0, 3, 5].map(|i| program.moves[i].clone()).to_vec(),
        ..program.clone()
    };
    let start = AcAxes {
        c: 0.25,
        ..AcAxes::default()
    };
    let machine = k.program_to_machine(&good, &start).unwrap();
    let q: Vec<AcAxes> = machine
        .moves
        .iter()
        .map(|m| AcAxes::from_position(&m.end))
        .collect();
    assert!((q[0].a - 0.6f64.atan2(0.8)).abs() < 1e-12 && q[0].c.abs() < 1e-12);
    assert_eq!(q[1], q[0], "a dwell does not move");
    assert_eq!(machine.moves[1].motion, Motion::Dwell { seconds: 1.0 });
    assert_eq!(q[2].a, 0.0);
    assert_eq!(q[2].c, q[0].c, "C kept through the vertical tool axis");
    for (m, original) in machine.moves.iter().zip(&good.moves) {
        assert_eq!(m.span, original.span);
        assert_eq!(m.feed, original.feed);
        assert_eq!(m.blend, original.blend);
    }
    assert_eq!(machine.start, start.to_position());
    // Each converted end is the cutter location asked for.
    for (m, original) in machine.moves.iter().zip(&good.moves) {
        let cl = k.forward(&AcAxes::from_position(&m.end));
        assert!((cl.point - Point3::from(original.end.linear)).norm() < 1e-12);
    }
}
