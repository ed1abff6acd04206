//! The generic five-axis kinematics against oracles written independently of it: the A-C
//! table's closed form (reproduced to 1e-9), the URDF tree's forward kinematics, and
//! FK(IK(p)) = p on a head-head, a table-table and a head-table machine.

use super::*;
use crate::kinematics::ac_table::tests::{ac_mill, general_variant, in_travel_q};
use crate::kinematics::ac_table::{AcAxes, AcTableKinematics, CutterLocation};
use crate::kinematics::tool_in_workpiece;
use crate::kinematics::tool_tip::tcp_to_machine;
use crate::program::{parse_gcode, ReadOptions};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

fn fixture(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

fn head_bc() -> Machine {
    Machine::load(&fixture("tests/fixtures/machines/head_bc/head_bc.urdf")).unwrap()
}

fn head_table_bc() -> Machine {
    Machine::load(&fixture(
        "tests/fixtures/machines/head_table_bc/head_table_bc.urdf",
    ))
    .unwrap()
}

fn solver(machine: &Machine, part: PartFrame) -> Result<FiveAxisKinematics, ChainError> {
    let (frame, _) = ProgramFrame::new(machine).unwrap();
    let map = AxisMap::new(machine).unwrap();
    FiveAxisKinematics::new(machine, &frame, &map, part)
}

/// A program position with the named axes set.
fn at(values: &[(&str, f64)]) -> Position {
    let mut p = Position::default();
    for &(name, v) in values {
        let &(_, linear, i) = PROGRAM_LETTERS.iter().find(|(l, _, _)| *l == name).unwrap();
        if linear {
            p.linear[i] = v;
        } else {
            p.rotary[i] = v;
        }
    }
    p
}

fn pose_error(a: &ToolPose, b: &ToolPose) -> f64 {
    (a.point - b.point).norm().max((a.axis - b.axis).norm())
}

#[test]
fn finds_the_rotary_pair_on_every_chain() {
    let cases: [(Machine, [&str; 2]); 4] = [
        (ac_mill(), ["C", "A"]),
        (general_variant(), ["C", "A"]),
        (head_bc(), ["C", "B"]),
        (head_table_bc(), ["C", "B"]),
    ];
    for (machine, letters) in cases {
        let k = solver(&machine, PartFrame::Program).unwrap();
        assert_eq!(
            k.rotary_letters(),
            letters.map(String::from),
            "{}",
            machine.name
        );
    }
    let xyz = Machine::load(&fixture("models/xyz_table.urdf")).unwrap();
    let e = solver(&xyz, PartFrame::Program).unwrap_err().to_string();
    assert!(
        e.contains("expected two rotary axes turning the tool relative to the part, found 0"),
        "{e}"
    );
}

#[test]
fn at_home_tool_tip_coordinates_are_joint_coordinates() {
    // The program frame carried by the part: with the rotary axes at home, the tip's part
    // coordinates are the slides' program coordinates.
    for machine in [ac_mill(), head_bc(), head_table_bc()] {
        let k = solver(&machine, PartFrame::Program).unwrap();
        let p = at(&[("x", 0.012), ("y", -0.034), ("z", 0.056)]);
        let pose = k.forward(&p);
        assert!(
            (pose.point - Point3::from(p.linear)).norm() < 1e-15,
            "{}: {}",
            machine.name,
            pose.point
        );
        assert!((pose.axis - Vector3::z()).norm() < 1e-15);
    }
}

#[test]
fn a_swivel_head_tilts_the_tip_about_its_pivot() {
    // head_bc: the tip hangs 150 mm below B; B = 90° swings it up to B's height, 150 mm
    // along −X, and C = 90° turns that onto −Y; the spindle then lies along +Y from the tip.
    let k = solver(&head_bc(), PartFrame::Program).unwrap();
    let b = 90f64.to_radians();
    let pose = k.forward(&at(&[("b", b), ("c", 90f64.to_radians())]));
    assert!(
        (pose.point - Point3::new(0.0, -0.15, 0.15)).norm() < 1e-12,
        "{}",
        pose.point
    );
    assert!(
        (pose.axis - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-12,
        "{}",
        pose.axis
    );
}

fn head_in_travel() -> impl Strategy<Value = Position> {
    (
        -0.2..0.2f64,
        -0.2..0.2f64,
        -0.2..0.1f64,
        -1.55..1.55f64,
        -10.0..10.0f64,
    )
        .prop_map(|(x, y, z, b, c)| at(&[("x", x), ("y", y), ("z", z), ("b", b), ("c", c)]))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The A-C table's closed form, reproduced by the generic solver to 1e-9: the same
    /// solution chosen from any previous position, or the same refusal.
    #[test]
    fn reproduces_the_ac_tables_closed_form(
        q in in_travel_q(), previous in (-2.0..2.0f64, -20.0..20.0f64)
    ) {
        let previous = AcAxes { a: previous.0, c: previous.1, ..AcAxes::default() };
        for machine in [ac_mill(), general_variant()] {
            let closed = AcTableKinematics::new(&machine).unwrap();
            let generic = solver(&machine, PartFrame::WorkpieceLink).unwrap();
            let cl: CutterLocation = closed.forward(&q);
            let pose = ToolPose { point: cl.point, axis: cl.axis };
            prop_assert!(pose_error(&generic.forward(&q.to_position()), &pose) < 1e-12);
            // Ties between the solutions may fall either way in the last bits: skip them.
            if let crate::kinematics::RotarySolutions::Regular([s1, s2]) = closed.rotary_solutions(&cl.axis) {
                let turned = |(a, c): (f64, f64)| {
                    let c = c + std::f64::consts::TAU * ((previous.c - c) / std::f64::consts::TAU).round();
                    (a - previous.a).powi(2) + (c - previous.c).powi(2)
                };
                prop_assume!((turned(s1) - turned(s2)).abs() > 1e-6);
            }
            match (closed.inverse(&cl, &previous), generic.inverse(&pose, &previous.to_position())) {
                (Ok(c), Ok(g)) => {
                    let expected = c.axes.to_position();
                    for i in 0..3 {
                        prop_assert!((g.position.linear[i] - expected.linear[i]).abs() < 1e-9, "{:?} vs {:?}", g.position, expected);
                        prop_assert!((g.position.rotary[i] - expected.rotary[i]).abs() < 1e-9, "{:?} vs {:?}", g.position, expected);
                    }
                    prop_assert_eq!(c.forced_by_travel, g.forced_by_travel);
                }
                (Err(_), Err(_)) => {}
                (c, g) => prop_assert!(false, "closed form {:?}, generic {:?}", c, g),
            }
        }
    }

    /// The generic forward kinematics is the URDF tree's.
    #[test]
    fn forward_is_the_trees(q in in_travel_q()) {
        let machine = general_variant();
        let k = solver(&machine, PartFrame::WorkpieceLink).unwrap();
        let closed = AcTableKinematics::new(&machine).unwrap();
        let tree = tool_in_workpiece(&machine, &closed.machine_q(&q));
        prop_assert!((k.forward(&q.to_position()).point - tree).norm() < 1e-12);
    }

    /// FK(IK(p)) = p to 1e-9 on a head-head, a table-table and a head-table machine, and the
    /// solution nearest the pose's own axes is those axes.
    #[test]
    fn forward_of_inverse_is_the_pose(q in head_in_travel(), ac in in_travel_q(), nudge in -0.01..0.01f64) {
        let cases = [
            (head_bc(), q),
            (head_table_bc(), q),
            (general_variant(), ac.to_position()),
        ];
        for (machine, q) in cases {
            let k = solver(&machine, PartFrame::Program).unwrap();
            let pose = k.forward(&q);
            let mut previous = q;
            for r in &mut previous.rotary {
                *r += nudge;
            }
            let solved = k.inverse(&pose, &previous).map_err(|e| TestCaseError::fail(format!("{}: {e} for {q:?}", machine.name)))?;
            let back = k.forward(&solved.position);
            prop_assert!(pose_error(&back, &pose) < 1e-9, "{}: {:?} vs {:?}", machine.name, back, pose);
            let [i, j] = k.rotary_indices();
            // Away from the pole the nearest solution is the pose's own.
            if pose.axis.z.abs() < 1.0 - 1e-6 {
                prop_assert!((solved.position.rotary[i] - q.rotary[i]).abs() < 1e-9, "{}: {:?} vs {:?}", machine.name, solved.position, q);
                prop_assert!((solved.position.rotary[j] - q.rotary[j]).abs() < 1e-9);
                for l in 0..3 {
                    prop_assert!((solved.position.linear[l] - q.linear[l]).abs() < 1e-9);
                }
            }
        }
    }
}

#[test]
fn both_solutions_of_the_rotary_pair_are_found() {
    // B = 0.5, C = 0.3 and B = −0.5, C = 0.3 + π lean the spindle alike.
    let k = solver(&head_bc(), PartFrame::Program).unwrap();
    let q = at(&[("x", 0.01), ("b", 0.5), ("c", 0.3)]);
    let pose = k.forward(&q);
    let near_first = k.inverse(&pose, &at(&[("b", 0.4), ("c", 0.2)])).unwrap();
    assert_eq!(near_first.solution, Solution::First);
    let near_second = k.inverse(&pose, &at(&[("b", -0.4), ("c", 3.3)])).unwrap();
    assert_eq!(near_second.solution, Solution::Second);
    assert!((near_second.position.rotary[1] + 0.5).abs() < 1e-12);
    assert!((near_second.position.rotary[2] - (0.3 + PI)).abs() < 1e-12);
    assert!(pose_error(&k.forward(&near_second.position), &pose) < 1e-12);
    assert!(!near_second.forced_by_travel);
}

#[test]
fn at_the_pole_the_primary_axis_stays_where_it_was() {
    let k = solver(&head_bc(), PartFrame::Program).unwrap();
    let pose = ToolPose {
        point: Point3::new(0.02, 0.01, -0.03),
        axis: Vector3::z(),
    };
    let solved = k.inverse(&pose, &at(&[("b", 0.2), ("c", 1.234)])).unwrap();
    assert_eq!(solved.solution, Solution::Pole);
    assert_eq!(solved.position.rotary[2], 1.234);
    assert!(solved.position.rotary[1].abs() < 1e-15);
    assert!(pose_error(&k.forward(&solved.position), &pose) < 1e-12);
}

#[test]
fn travel_decides_between_the_solutions() {
    let mut machine = head_bc();
    let b = machine.joints.iter().position(|j| j.name == "b").unwrap();
    machine.joints[b].limits = Some([0.0, 1.6]);
    let k = solver(&machine, PartFrame::Program).unwrap();
    let pose = k.forward(&at(&[("b", 1.0), ("c", 0.0)]));
    // Nearest is B = −1 (outside), so B = +1 is taken, and said to be forced.
    let solved = k.inverse(&pose, &at(&[("b", -0.9), ("c", 3.0)])).unwrap();
    assert!(solved.forced_by_travel);
    assert!((solved.position.rotary[1] - 1.0).abs() < 1e-12);
    machine.joints[b].limits = Some([0.2, 0.3]);
    let k = solver(&machine, PartFrame::Program).unwrap();
    let e = k
        .inverse(&pose, &Position::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(
            "axis 'b' would be at 57.296°, outside its travel [11.459°, 17.189°] (solution 1)"
        ),
        "{e}"
    );
    assert!(e.contains("axis 'b' would be at -57.296°"), "{e}");
}

#[test]
fn a_nutating_head_says_how_far_out_of_reach_an_axis_is() {
    // B tilted 45° towards Z: the spindle reaches at most 90° from the C axis.
    let mut machine = head_bc();
    let b = machine.joints.iter().position(|j| j.name == "b").unwrap();
    machine.joints[b].axis = Vector3::new(0.0, 1.0, 1.0).normalize();
    let k = solver(&machine, PartFrame::Program).unwrap();
    let down = ToolPose {
        point: Point3::origin(),
        axis: -Vector3::z(),
    };
    let e = k
        .inverse(&down, &Position::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("no angles of C and B turn the tool to (0.000000, 0.000000, -1.000000): it is 90.000° outside their reach"), "{e}");
    // Within the cone it reaches, and lands there.
    let side = k.forward(&at(&[("b", 1.0), ("c", 0.5)]));
    let solved = k.inverse(&side, &Position::default()).unwrap();
    assert!(pose_error(&k.forward(&solved.position), &side) < 1e-12);
}

#[test]
fn a_tool_tip_move_keeps_the_tip_on_the_programmed_line_while_the_head_tilts() {
    let machine = head_bc();
    let k = solver(&machine, PartFrame::Program).unwrap();
    let program = parse_gcode(
        "G21 G90 G94 G61\nG1 F600 X0 Y0 Z0 B0 C0\nG1 X20 B30 C45\nG1 X20 Y10\nM2\n",
        "tcp.ngc",
        &ReadOptions::default(),
    )
    .unwrap();
    let tolerance = 1e-6;
    let converted = tcp_to_machine(&k, &program, tolerance).unwrap();
    // The tilting move became pieces; the straight one at fixed angles stayed one move.
    let lines: Vec<u32> = converted.moves.iter().map(|m| m.span.line).collect();
    let tilting = lines.iter().filter(|&&l| l == 3).count();
    assert!(tilting > 10, "{tilting} pieces");
    assert_eq!(lines.iter().filter(|&&l| l == 4).count(), 1);
    // Each piece's tip path stays on the programmed line (y = z = 0, 0 ≤ x ≤ 20 mm).
    let mut from = converted.start;
    let mut seconds = 0.0;
    for m in converted.moves.iter().filter(|m| m.span.line == 3) {
        for t in 0..=20 {
            let t = t as f64 / 20.0;
            let mut p = from;
            for i in 0..3 {
                p.linear[i] += t * (m.end.linear[i] - from.linear[i]);
                p.rotary[i] += t * (m.end.rotary[i] - from.rotary[i]);
            }
            let tip = k.forward(&p).point;
            let off = tip.y.hypot(tip.z);
            assert!(off <= tolerance * 1.000_001, "{off}");
            assert!(tip.x > -1e-9 && tip.x < 0.02 + 1e-9);
        }
        if let crate::program::Feed::InverseTime(t) = m.feed {
            seconds += t;
        } else {
            panic!("pieces are timed");
        }
        from = m.end;
    }
    // 20 mm at 600 mm/min: the tip takes 2 s, whatever the slides do.
    assert!((seconds - 2.0).abs() < 1e-12, "{seconds}");
    let end = k.forward(&from);
    assert!((end.point - Point3::new(0.02, 0.0, 0.0)).norm() < 1e-12);
    let lean = end.axis.z.acos().to_degrees();
    assert!((lean - 30.0).abs() < 1e-9, "{lean}");
}

#[test]
fn cl_data_runs_on_a_head_head_machine() {
    // GOTO points with tool axes, on the swivel head: each end point's tip and axis are
    // reached; vertical axes are at the pole (C kept, one warning); a far lean takes B < 0
    // only where nearer.
    use crate::kinematics::tool_tip::cl_to_machine;
    use crate::program::parse_apt;
    let machine = head_bc();
    let k = solver(&machine, PartFrame::WorkpieceLink).unwrap();
    let text = "FEDRAT/600\nGOTO/0,0,100,0,0,1\nGOTO/10,0,100,0,0,1\nGOTO/10,5,100,0.5,0,0.8660254037844386\nGOTO/10,10,100,0,0.5,0.8660254037844386\nGOTO/0,10,100,0,0,1\nFINI\n";
    let program = parse_apt(text, "head.apt", &ReadOptions::default()).unwrap();
    let converted = cl_to_machine(&k, &program).unwrap();
    assert_eq!(converted.moves.len(), 5);
    for (m, cl) in converted.moves.iter().zip(&program.moves) {
        let pose = k.forward(&m.end);
        assert!((pose.point - Point3::from(cl.end.linear)).norm() < 1e-12);
        let axis = Vector3::from(cl.tool_axis.unwrap()).normalize();
        assert!(
            (pose.axis - axis).norm() < 1e-12,
            "{} vs {}",
            pose.axis,
            axis
        );
    }
    // Leaning along +X then +Y: B = 30° both times, C turning a quarter (not B = −30°,
    // C + 180°).
    let (b, c) = (
        converted.moves[2].end.rotary[1],
        converted.moves[2].end.rotary[2],
    );
    assert!(
        (b - 30f64.to_radians()).abs() < 1e-12 && c.abs() < 1e-12,
        "{b} {c}"
    );
    let (b, c) = (
        converted.moves[3].end.rotary[1],
        converted.moves[3].end.rotary[2],
    );
    assert!(
        (b - 30f64.to_radians()).abs() < 1e-12 && (c - PI / 2.0).abs() < 1e-12,
        "{b} {c}"
    );
    // Back to vertical: C stays at 90°.
    assert!((converted.moves[4].end.rotary[2] - PI / 2.0).abs() < 1e-12);
    let poles: Vec<&str> = converted
        .warnings
        .iter()
        .map(|w| w.message.as_str())
        .filter(|m| m.contains("the pole"))
        .collect();
    assert_eq!(
        poles,
        ["line 2: the tool axis lies along the C axis (the pole) here and in 2 later moves: C is free there and kept where it was"]
    );
}
