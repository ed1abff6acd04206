//! APT / CLSF as CAM systems write it: CIRCLE arcs checked against the CIRCLE records' own
//! centre, axis and radius and against an arc sampled here from the record alone; NX CLSF
//! structure; records that would change the path but cannot be followed are errors.

mod common;

use std::path::Path;

use cncsim::program::{
    arc_sweep, parse_apt, plane_axes, read_program, ClWriter, Motion, Program, ReadOptions,
};
use nalgebra::{Rotation3, Unit, Vector3};

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/apt")
        .join(name)
}

fn apt(text: &str) -> Program {
    parse_apt(text, "t.cls", &ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

fn first_error(text: &str, options: &ReadOptions) -> String {
    match parse_apt(text, "bad.cls", options) {
        Ok(_) => format!("<no error for {text:?}>"),
        Err(errors) => errors.errors[0].to_string(),
    }
}

/// A CIRCLE record as this test reads it: centre and radius (mm), axis.
struct Record {
    centre: Vector3<f64>,
    axis: Unit<Vector3<f64>>,
    radius: f64,
}

fn circle_records(text: &str, frame_origin: Vector3<f64>) -> Vec<Record> {
    text.lines()
        .filter_map(|line| line.strip_prefix("CIRCLE/"))
        .map(|rest| {
            let v: Vec<f64> = rest
                .split(',')
                .filter_map(|f| f.trim().parse().ok())
                .collect();
            Record {
                centre: Vector3::new(v[0], v[1], v[2]) + frame_origin,
                axis: Unit::new_normalize(Vector3::new(v[3], v[4], v[5])),
                radius: v[6],
            }
        })
        .collect()
}

/// Points (mm) along a decoded arc move from `from`, every degree.
fn decoded_arc(from: &[f64; 3], mv: &cncsim::program::Move) -> Vec<Vector3<f64>> {
    let Motion::Arc {
        center,
        plane,
        clockwise,
        turns,
    } = mv.motion
    else {
        panic!("expected an arc, found {:?}", mv.motion);
    };
    let (first, second, normal) = plane_axes(plane);
    let sweep = arc_sweep(from, &mv.end.linear, &center, plane, clockwise, turns);
    let radius = (from[first] - center[first]).hypot(from[second] - center[second]);
    let start = (from[second] - center[second]).atan2(from[first] - center[first]);
    let steps = (sweep.to_degrees().ceil() as usize).max(1);
    (0..=steps)
        .map(|k| {
            let t = k as f64 / steps as f64;
            let angle = start + if clockwise { -sweep } else { sweep } * t;
            let mut p = [0.0; 3];
            p[first] = center[first] + radius * angle.cos();
            p[second] = center[second] + radius * angle.sin();
            p[normal] = from[normal] + (mv.end.linear[normal] - from[normal]) * t;
            Vector3::new(p[0], p[1], p[2]) * 1000.0
        })
        .collect()
}

/// The arc a CIRCLE record describes from `start` to `end` (mm), sampled every degree:
/// clockwise about the record's axis (NX), with `extra_turns`, helical along the axis.
fn reference_arc(
    record: &Record,
    start: Vector3<f64>,
    end: Vector3<f64>,
    extra_turns: u32,
) -> Vec<Vector3<f64>> {
    let axis = record.axis.into_inner();
    let radial = |p: Vector3<f64>| {
        let d = p - record.centre;
        d - axis * d.dot(&axis)
    };
    let (r0, r1) = (radial(start), radial(end));
    // Clockwise about the axis = a negative rotation about it.
    let mut sweep = (r0.cross(&r1).dot(&axis)).atan2(r0.dot(&r1));
    if sweep >= 0.0 {
        sweep -= std::f64::consts::TAU;
    }
    if (r1 - r0).norm() < 1e-9 {
        sweep = -std::f64::consts::TAU;
    }
    sweep -= std::f64::consts::TAU * f64::from(extra_turns);
    let (h0, h1) = (
        (start - record.centre).dot(&axis),
        (end - record.centre).dot(&axis),
    );
    let steps = (sweep.abs().to_degrees().ceil() as usize).max(1);
    (0..=steps)
        .map(|k| {
            let t = k as f64 / steps as f64;
            let rotation = Rotation3::from_axis_angle(&record.axis, sweep * t);
            record.centre + rotation * r0 + axis * (h0 + (h1 - h0) * t)
        })
        .collect()
}

/// Largest distance (mm) from a point of `a` to the polyline `b`.
fn distance_to_polyline(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter()
        .map(|p| {
            b.windows(2)
                .map(|w| {
                    let d = w[1] - w[0];
                    let t = ((p - w[0]).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
                    (p - (w[0] + d * t)).norm()
                })
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

#[test]
fn nx_clsf_arcs_follow_their_circle_records() {
    let path = fixture("nx_clsf_profile.cls");
    let text = std::fs::read_to_string(&path).unwrap();
    let program = read_program(&path, &ReadOptions::default()).unwrap();
    // MSYS puts the MCS origin at (100, 50, 0) mm.
    let records = circle_records(&text, Vector3::new(100.0, 50.0, 0.0));
    assert_eq!(records.len(), 5);
    let mut position = program.start.linear;
    let mut arcs = 0;
    for mv in &program.moves {
        if let Motion::Arc { turns, .. } = mv.motion {
            let record = &records[arcs];
            let decoded = decoded_arc(&position, mv);
            // Every decoded point on the record's circle (the cylinder about its axis).
            for p in &decoded {
                let d = p - record.centre;
                let off_axis = (d - record.axis.into_inner() * d.dot(&record.axis)).norm();
                assert!(
                    (off_axis - record.radius).abs() < 1e-9,
                    "{off_axis} vs {}",
                    record.radius
                );
            }
            // And along the arc the record describes, in its direction.
            let start = Vector3::from(position) * 1000.0;
            let end = Vector3::from(mv.end.linear) * 1000.0;
            let reference = reference_arc(record, start, end, turns);
            let apart = distance_to_polyline(&decoded, &reference)
                .max(distance_to_polyline(&reference, &decoded));
            // One-degree chords of a radius-10 arc: 0.0015 mm apart at most.
            assert!(
                apart < 0.002,
                "arc {arcs}: {apart} mm from the record's arc"
            );
            arcs += 1;
        }
        position = mv.end.linear;
    }
    assert_eq!(arcs, 5);
    // The helical entry: two turns (TIMES,2), 4 mm down.
    let helix = program
        .moves
        .iter()
        .find(|m| matches!(m.motion, Motion::Arc { turns: 1, .. }));
    assert!(helix.is_some());
    // Each kind of skipped record warned about once; TLDATA is read into the tool and
    // CUTCOM is read (and said), not skipped.
    let kinds: Vec<&str> = program
        .warnings
        .iter()
        .map(|w| w.message.split_whitespace().next().unwrap())
        .collect();
    assert_eq!(
        kinds,
        [
            "TOOL",
            "MSYS:",
            "PAINT",
            "LOAD",
            "COOLNT",
            "CUTCOM:",
            "END-OF-PATH"
        ]
    );
    assert_eq!(program.tools.len(), 1);
    assert_eq!(
        program.tools[0].operation.as_deref(),
        Some("PLANAR_PROFILE")
    );
    assert_eq!(program.tools[0].diameter, 0.01);
}

#[test]
fn a_large_circle_is_an_arc_not_a_chord() {
    // The case: a radius-473 mm arc (90°), once silently a chord up to 139 mm off.
    let program = apt(
        "TOOL PATH/CONTOUR,TOOL,MILL\nUNITS/MM\nFEDRAT/1000\nGOTO/473,0,0\nCIRCLE/0,0,0,0,0,-1,473,0.01\nGOTO/0,473,0\n",
    );
    let mv = &program.moves[1];
    let decoded = decoded_arc(&program.moves[0].end.linear, mv);
    let record = Record {
        centre: Vector3::zeros(),
        axis: Unit::new_normalize(Vector3::new(0.0, 0.0, -1.0)),
        radius: 473.0,
    };
    let reference = reference_arc(&record, decoded[0], *decoded.last().unwrap(), 0);
    // The quarter arc through (334.5, 334.5), not the three-quarter one nor the chord.
    let middle = decoded[decoded.len() / 2];
    assert!(
        (middle - Vector3::new(334.46, 334.46, 0.0)).norm() < 0.01,
        "{middle}"
    );
    assert!(distance_to_polyline(&decoded, &reference) < 0.08);
}

#[test]
fn arcs_about_tilted_axes_are_chords_within_a_micrometre() {
    // A 45° tilted plane: radius 20 mm about (0, 1, 1)/√2, a quarter turn.
    let s = 20.0 / 2f64.sqrt();
    let text = format!(
        "UNITS/MM\nFEDRAT/600\nGOTO/20,0,0\nCIRCLE/0,0,0,0,0.7071068,0.7071068,20,0.01\nGOTO/0,{s},{}\n",
        -s
    );
    // Read as NX writes arcs (clockwise about the axis).
    let mut nx = ReadOptions::default();
    nx.apt.writer = Some(ClWriter::Nx);
    let program = parse_apt(&text, "t.cls", &nx).unwrap();
    let points: Vec<Vector3<f64>> = std::iter::once(Vector3::new(20.0, 0.0, 0.0))
        .chain(
            program.moves[1..]
                .iter()
                .map(|m| Vector3::from(m.end.linear) * 1000.0),
        )
        .collect();
    assert!(program.moves[1..]
        .iter()
        .all(|m| m.motion == Motion::Linear));
    let record = Record {
        centre: Vector3::zeros(),
        axis: Unit::new_normalize(Vector3::new(0.0, 1.0, 1.0)),
        radius: 20.0,
    };
    let reference = reference_arc(&record, points[0], *points.last().unwrap(), 0);
    // Every chord end on the arc, every chord within 1 µm of it (midpoint sagitta).
    assert!(distance_to_polyline(&points, &reference) < 1e-3);
    for w in points.windows(2) {
        let middle = (w[0] + w[1]) / 2.0;
        assert!(20.0 - middle.norm() <= 1e-3 + 1e-9);
    }
    assert!(program
        .warnings
        .iter()
        .any(|w| w.message.contains("chords within 0.0010 mm")));
    // Clockwise about the axis, the end is three quarters round; APT's sense takes the
    // quarter turn.
    let other = apt(&text);
    let ratio = (program.moves.len() - 1) as f64 / (other.moves.len() - 1) as f64;
    assert!((ratio - 3.0).abs() < 0.05, "{ratio}");
}

#[test]
fn delay_gohome_tlaxis_and_godlta() {
    let program = apt(
        "FROM/0,0,50\nSPINDL/RPM,6000,CLW\nFEDRAT/MMPM,600\nGOTO/10,0,5\nDELAY/1.5\nDELAY/REV,30\nTLAXIS/0,0,2\nGODLTA/0,0,-5\nGOHOME\nFINI\n",
    );
    let kinds: Vec<String> = program
        .moves
        .iter()
        .map(|m| format!("{:?}", m.motion))
        .collect();
    assert_eq!(
        kinds,
        [
            "Linear",
            "Dwell { seconds: 1.5 }",
            "Dwell { seconds: 0.3 }",
            "Linear",
            "Linear"
        ]
    );
    assert_eq!(program.moves[3].end.linear, [0.01, 0.0, 0.0]);
    assert_eq!(program.moves[3].tool_axis, Some([0.0, 0.0, 1.0]));
    assert_eq!(program.moves[4].end.linear, [0.0, 0.0, 0.05]);
}

#[test]
fn records_that_cannot_be_followed_are_errors() {
    let options = ReadOptions::default();
    let table: &[(&str, &str)] = &[
        ("FEDRAT/100\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10,0.01\nGOTO/0,10.5,0", "bad.cls:4:1: expected the arc's end (the GOTO) on the CIRCLE (radius 10.0000 mm), but it is 0.5000 mm off it; expected at most 0.0100 mm, found 'GOTO/0,10.5,0'; hint: check the CIRCLE record before this GOTO"),
        ("FEDRAT/100\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10", "bad.cls:3:1: expected a GOTO ending the arc of this CIRCLE, found the end of the program"),
        ("FEDRAT/100\nCIRCLE/0,0,0,0,0,1,10\nGODLTA/1,0,0", "bad.cls:3:1: expected a GOTO to end the arc of the CIRCLE before, not GODLTA, found 'GODLTA/1,0,0'"),
        ("CIRCLE/0,0,0,0,1", "bad.cls:1:1: expected at least 6 numbers after CIRCLE/ (centre, axis[, radius]), not 5, found 'CIRCLE/0,0,0,0,1'"),
        ("CIRCLE/0,0,0,0,0,1", "bad.cls:1:1: expected the tool off the axis of a CIRCLE without a radius (the radius is the tool's distance from the axis), but it is on it, found 'CIRCLE/0,0,0,0,0,1'"),
        ("CIRCLE/0,0,0,0,0,0,5", "bad.cls:1:1: expected a non-zero axis vector and a positive radius in CIRCLE, found 'CIRCLE/0,0,0,0,0,0,5'"),
        ("CYCLE/MILL,RAPTO,2,FEDTO,-10,MMPM,100", "bad.cls:1:7: expected a cycle cncsim can expand; MILL in CYCLE is not one, found 'MILL'; hint: CYCLE/DRILL (plain, DEEP, BRKCHP), CSINK, BORE, REAM and TAP are expanded; post other cycles as GOTO records"),
        ("ORIGIN/10,0,0", "bad.cls:1:1: expected records cncsim can follow; ORIGIN changes the tool path and origin shifts are not supported, found 'ORIGIN/10,0,0'; hint: post the CL data with the path written out as GOTO (and CIRCLE) records"),
        ("DEFSUB / 6", "bad.cls:1:1: expected records cncsim can follow; DEFSUB changes the tool path and subroutines (DEFSUB … ENDSUB, CALSUB) are not supported, found 'DEFSUB / 6'; hint: post the CL data with the path written out as GOTO (and CIRCLE) records"),
        ("WIBBLE/3", "bad.cls:1:1: expected an APT record cncsim knows; WIBBLE is not one, found 'WIBBLE'; hint: a record that may change the tool path is not skipped; remove it if it does not"),
        ("MSYS/0,0,0,1,0,0,1,0,0", "bad.cls:1:12: expected unit, perpendicular X and Y axis vectors in MSYS/x,y,z,xi,xj,xk,yi,yj,yk, found '1,0,0,1,0,0'"),
        ("DELAY/REV,3", "bad.cls:1:11: expected a turning spindle for a delay in revolutions, found '3'; hint: program DELAY in seconds or start the spindle (SPINDL) first"),
    ];
    let mut failures = Vec::new();
    for (input, expected) in table {
        let actual = first_error(input, &options);
        if actual != *expected {
            failures.push(format!(
                "input {input:?}\n  expected: {expected}\n  actual:   {actual}"
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn gohome_without_from_is_left_out_with_a_warning() {
    // Pro/ENGINEER ends programs with GOHOME and no FROM: the machine's home, not in the data.
    let program = apt("FEDRAT/100\nGOTO/1,2,3\nRAPID\nGOHOME\nFINI\n");
    assert_eq!(program.moves.len(), 1);
    assert!(program
        .warnings
        .iter()
        .any(|w| w.message.starts_with("GOHOME without a FROM point")));
    let mut strict = ReadOptions::default();
    strict.apt.strict = true;
    assert_eq!(
        first_error("FEDRAT/100\nGOHOME", &strict),
        "bad.cls:2:1: expected a FROM point before GOHOME (it returns there), found 'GOHOME'"
    );
}

#[test]
fn strict_refuses_what_would_be_skipped() {
    let mut options = ReadOptions::default();
    options.apt.strict = true;
    assert_eq!(
        first_error("PAINT/COLOR,186", &options),
        "bad.cls:1:1: expected a motion record; PAINT (display colour and speed) does not move the tool (refused with --strict), found 'PAINT/COLOR,186'"
    );
    // Comments and free text stay allowed.
    assert!(parse_apt("PARTNO TEST\n$$ comment\nFINI", "t.cls", &options).is_ok());
}

#[test]
fn msys_rotates_points_and_tool_axes() {
    // MCS turned 90° about Z and moved to (10, 0, 0).
    let program = apt("MSYS/10,0,0,0,1,0,-1,0,0\nFEDRAT/100\nGOTO/5,0,0,1,0,0\n");
    let mv = &program.moves[0];
    assert!((Vector3::from(mv.end.linear) - Vector3::new(0.010, 0.005, 0.0)).norm() < 1e-15);
    let axis = mv.tool_axis.unwrap();
    assert!((Vector3::from(axis) - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-15);
}

// ---------------------------------------------------------------------------------------
// NX CLSF as NX writes it: names, tools, cycles, splines, cutter compensation
// ---------------------------------------------------------------------------------------

#[test]
fn nx_names_with_digits_underscores_and_dashes_and_tldata_read_into_the_tools() {
    let program = apt(
        "TOOL PATH/2_TORETC_250_BOK,TOOL,FACE_MILL_2\nTLDATA/MILL,250.0000,1.0000,50.0000,0.0000,0.0000\n\
         RAPID\nGOTO/1,2,3\nEND-OF-PATH\n\
         TOOL PATH/BOK_7,TOOL,R390-25A25L-17L\nTLDATA/DRILL,MILL,63.0000,0.0000,239.0000,178.0000,35.0000\n\
         RAPID\nGOTO/4,5,6\nEND-OF-PATH\n",
    );
    assert_eq!(program.moves.len(), 2);
    type Described<'a> = (
        Option<&'a str>,
        Option<&'a str>,
        &'a str,
        f64,
        f64,
        f64,
        f64,
    );
    let tools: Vec<Described> = program
        .tools
        .iter()
        .map(|t| {
            (
                t.operation.as_deref(),
                t.name.as_deref(),
                t.kind.as_str(),
                t.diameter,
                t.corner_radius,
                t.length,
                t.tip_angle.to_degrees(),
            )
        })
        .collect();
    assert_eq!(
        tools,
        [
            (
                Some("2_TORETC_250_BOK"),
                Some("FACE_MILL_2"),
                "MILL",
                0.25,
                0.001,
                0.05,
                0.0
            ),
            (
                Some("BOK_7"),
                Some("R390-25A25L-17L"),
                "DRILL,MILL",
                0.063,
                0.0,
                0.239,
                35.0
            ),
        ]
    );
    // The inspect report names them.
    let report = cncsim::program::inspect_report(&program, None, &Default::default());
    assert!(
        report.contains("tool: 7:1: DRILL,MILL diameter 63.0000 mm, corner radius 0.0000 mm, length 239.0000 mm, taper 178.000 deg, tip 35.000 deg (operation BOK_7, tool R390-25A25L-17L)"),
        "{report}"
    );
    // Skipped records are counted in one warning per kind.
    let messages: Vec<&str> = program
        .warnings
        .iter()
        .map(|w| w.message.as_str())
        .collect();
    assert_eq!(
        messages,
        [
            "TOOL PATH (start of an NX tool path) does not move the tool and was skipped (2 records in the file)",
            "END-OF-PATH (end of an NX tool path) does not move the tool and was skipped (2 records in the file)",
        ]
    );
}

/// A hole as the cycle's definition makes it, written out here from the definition
/// (NX's posts: rapid-to, feed-to, retract-to = the GOTO point + the distance × tool axis):
/// (rapid?, point mm) and dwells as `None` points.
fn moves_mm(program: &Program, from: usize) -> Vec<(String, [f64; 3])> {
    program.moves[from..]
        .iter()
        .map(|m| {
            let kind = match (m.motion, m.feed) {
                (Motion::Dwell { seconds }, _) => format!("dwell {seconds}"),
                (_, cncsim::program::Feed::Rapid) => "rapid".to_string(),
                (_, cncsim::program::Feed::PathSpeed(v)) => format!("feed {:.3}", v * 60_000.0),
                (_, other) => format!("{other:?}"),
            };
            let p = m.end.linear;
            (kind, [p[0] * 1e3, p[1] * 1e3, p[2] * 1e3])
        })
        .collect()
}

fn assert_moves(actual: &[(String, [f64; 3])], expected: &[(&str, [f64; 3])]) {
    let same = actual.len() == expected.len()
        && actual
            .iter()
            .zip(expected)
            .all(|((ka, pa), (ke, pe))| ka == ke && (0..3).all(|i| (pa[i] - pe[i]).abs() < 1e-9));
    assert!(same, "expected\n{expected:?}\nfound\n{actual:?}");
}

#[test]
fn drill_cycles_make_each_goto_a_hole_as_the_cycle_defines_it() {
    let rapid_to = 3.0;
    let feed_to = -10.0;
    let step = 4.0;
    let clearance = 0.254; // the peck clearance cncsim states (LinuxCNC's 0.010 in)
    let text = format!(
        "FROM/0,0,50\nFEDRAT/MMPM,1000\n\
         CYCLE/DRILL,RAPTO,{rapid_to},FEDTO,{feed_to},MMPM,250\nGOTO/10,20,0\nGOTO/30,20,0\n\
         CYCLE/DRILL,DEEP,FEDTO,{feed_to},STEP,{step},RAPTO,{rapid_to},RTRCTO,AUTO,MMPM,200\nGOTO/50,0,0\n\
         CYCLE/DRILL,BRKCHP,RAPTO,{rapid_to},FEDTO,{feed_to},STEP,{step},DWELL,0.5,RTRCTO,10\nGOTO/70,0,0\n\
         CYCLE/OFF\nGOTO/70,0,40\n"
    );
    let program = apt(&text);
    let (r, f) = (rapid_to, feed_to);
    // First hole: from above, across at the FROM height, down to RAPTO, feed, back to RAPTO.
    let mut expected: Vec<(&str, [f64; 3])> = vec![
        ("rapid", [10.0, 20.0, 50.0]),
        ("rapid", [10.0, 20.0, r]),
        ("feed 250.000", [10.0, 20.0, f]),
        ("rapid", [10.0, 20.0, r]),
        // Next hole: at RAPTO height already, across.
        ("rapid", [30.0, 20.0, r]),
        ("feed 250.000", [30.0, 20.0, f]),
        ("rapid", [30.0, 20.0, r]),
        ("rapid", [50.0, 0.0, r]),
    ];
    // DEEP: pecks of STEP from RAPTO, back to RAPTO after each, down to the last depth
    // less the clearance.
    let mut depth = r;
    let mut pecks = Vec::new();
    while depth > f {
        let next = (depth - step).max(f);
        pecks.push((depth, next));
        depth = next;
    }
    let deep: Vec<(&str, [f64; 3])> = pecks
        .iter()
        .enumerate()
        .flat_map(|(k, &(top, bottom))| {
            let mut v = Vec::new();
            if k > 0 {
                v.push(("rapid", [50.0, 0.0, r]));
                v.push(("rapid", [50.0, 0.0, top + clearance]));
            }
            v.push(("feed 200.000", [50.0, 0.0, bottom]));
            v
        })
        .collect();
    expected.extend(deep);
    expected.push(("rapid", [50.0, 0.0, r]));
    // BRKCHP: the same pecks backing off by the clearance only; dwell; out to RTRCTO; the
    // feed is the last FEDRAT (the cycle gives none).
    expected.push(("rapid", [70.0, 0.0, r]));
    for (k, &(top, bottom)) in pecks.iter().enumerate() {
        if k > 0 {
            expected.push(("rapid", [70.0, 0.0, top + clearance]));
        }
        expected.push(("feed 1000.000", [70.0, 0.0, bottom]));
    }
    expected.push(("dwell 0.5", [70.0, 0.0, f]));
    expected.push(("rapid", [70.0, 0.0, 10.0]));
    // CYCLE/OFF: a GOTO is a move again.
    expected.push(("feed 1000.000", [70.0, 0.0, 40.0]));
    assert_moves(&moves_mm(&program, 0), &expected);
    assert!(program.warnings.iter().any(|w| w
        .message
        .starts_with("CYCLE/DRILL,DEEP: each GOTO is a hole")));
}

#[test]
fn a_hole_follows_the_tool_axis_and_the_msys_frame() {
    // MCS turned 90° about Z: the GOTO's tool axis (1,0,0) is +Y on the table.
    let program = apt(
        "MSYS/100,0,0,0,1,0,-1,0,0\nFROM/0,0,0\nCYCLE/DRILL,RAPTO,2,FEDTO,-5,MMPM,100\nGOTO/10,0,0,1,0,0\n",
    );
    // The hole's point: (100,0,0) + R(10,0,0) = (100,10,0); the axis +Y.
    let moves = moves_mm(&program, 0);
    let (last_kind, last) = moves.last().unwrap();
    assert_eq!(last_kind, "rapid");
    assert!((last[0] - 100.0).abs() < 1e-9 && (last[1] - 12.0).abs() < 1e-9);
    let bottom = moves.iter().find(|(k, _)| k.starts_with("feed")).unwrap().1;
    assert!(
        (bottom[0] - 100.0).abs() < 1e-9
            && (bottom[1] - 5.0).abs() < 1e-9
            && bottom[2].abs() < 1e-9
    );
}

#[test]
fn cycles_that_cannot_be_expanded_are_refused_by_name() {
    let options = ReadOptions::default();
    for (input, expected) in [
        ("CYCLE/THREAD,FEDTO,-5", "bad.cls:1:7: expected a cycle cncsim can expand; THREAD in CYCLE is not one, found 'THREAD'; hint: CYCLE/DRILL (plain, DEEP, BRKCHP), CSINK, BORE, REAM and TAP are expanded; post other cycles as GOTO records"),
        ("CYCLE/DRILL,RAPTO,3", "bad.cls:1:1: expected FEDTO (the depth) in CYCLE/DRILL, found 'CYCLE/DRILL,RAPTO,3'"),
        ("CYCLE/DRILL,RAPTO,-10,FEDTO,-5", "bad.cls:1:1: expected FEDTO (-5.0000 mm) below RAPTO (-10.0000 mm) along the tool axis in CYCLE/DRILL, found 'CYCLE/DRILL,RAPTO,-10,FEDTO,-5'"),
        ("CYCLE/ON", "bad.cls:1:1: expected a CYCLE record that defines the cycle before CYCLE/ON, found 'CYCLE/ON'"),
        ("CYCLE/DRILL,FEDTO,-5\nGOTO/0,0,0", "bad.cls:2:1: expected a feed (in the CYCLE or a FEDRAT before it) for the holes of CYCLE/DRILL, found 'GOTO/0,0,0'"),
        ("FEDRAT/100\nCUTCOM/LEFT,PLUS", "bad.cls:2:13: expected a compensation setting cncsim can follow in CUTCOM; PLUS is not one, found 'PLUS'; hint: CUTCOM/LEFT|RIGHT|ON|OFF[,XYPLAN][,n] and TLCOMP/ON|OFF[,n] are read"),
        ("KNOT/0.5,1", "bad.cls:1:1: expected NURBS/ before KNOT/, found 'KNOT/0.5,1'"),
        ("FEDRAT/100\nGOTO/0,0,0\nNURBS/\nKNOT/0.5,1\nCNTRL/1,0,0\nFINI", "bad.cls:3:1: expected a NURBS of degree 1 to 9 (CNTRL points − KNOT values + 1), found degree 0 (2 knots, 1 control points), found 'NURBS/\\nKNOT/0.5,1\\nCNTRL/1,0,0'"),
    ] {
        assert_eq!(first_error(input, &options), expected, "{input:?}");
    }
}

#[test]
fn a_peck_step_that_would_need_too_many_pecks_is_an_error() {
    let error = first_error(
        "CYCLE/DRILL,DEEP,RAPTO,0,FEDTO,-1000,STEP,0.001,MMPM,100\nGOTO/0,0,0",
        &ReadOptions::default(),
    );
    assert!(
        error.starts_with("bad.cls:2:1: expected at most 100000 pecks per hole; CYCLE/DRILL,DEEP with its STEP needs 10000"),
        "{error}"
    );
}

#[test]
fn cutter_compensation_is_read_and_said_once() {
    let program = apt(
        "FEDRAT/100\nGOTO/0,0,0\nCUTCOM/LEFT,XYPLAN\nGOTO/10,0,0\nCUTCOM/OFF\nCUTCOM/RIGHT,1\nGOTO/20,0,0\nCUTCOM/OFF\nTLCOMP/ON,3\n",
    );
    assert_eq!(program.moves.len(), 3);
    assert_eq!(program.moves[2].end.linear, [0.02, 0.0, 0.0]);
    let messages: Vec<&str> = program
        .warnings
        .iter()
        .map(|w| w.message.as_str())
        .collect();
    assert_eq!(
        messages,
        [
            "CUTCOM: the CL points are the tool centre's; the controller's compensation offsets them by the register's wear only, taken as 0 mm: the points are followed as written",
            "TLCOMP: tool length compensation does not move the tool tip the CL points give: they are followed as written",
        ]
    );
}

/// The NURBS of `nx_nurbs.cls` as cncsim follows it: the GOTO before it, then its chords (mm).
fn decoded_spline() -> (Program, Vec<Vector3<f64>>) {
    let program = read_program(&fixture("nx_nurbs.cls"), &ReadOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    let nurbs_line = 18;
    let mut points = Vec::new();
    for (index, mv) in program.moves.iter().enumerate() {
        if mv.span.line == nurbs_line {
            if points.is_empty() {
                points.push(Vector3::from(program.moves[index - 1].end.linear) * 1e3);
            }
            assert_eq!(mv.motion, Motion::Linear);
            points.push(Vector3::from(mv.end.linear) * 1e3);
        }
    }
    (program, points)
}

fn oracle_points(text: &str) -> Vec<Vector3<f64>> {
    text.lines()
        .map(|line| {
            let v: Vec<f64> = line
                .split_whitespace()
                .map(|f| f.parse().unwrap())
                .collect();
            Vector3::new(v[0], v[1], v[2])
        })
        .collect()
}

/// cncsim's chords against geomdl's evaluation of the same curve: every point geomdl gives
/// within the chord tolerance (1 µm) of the chords, every chord point on geomdl's curve.
fn compare_spline(oracle: &[Vector3<f64>]) {
    let (program, ours) = decoded_spline();
    assert!(ours.len() > 10, "{} chords", ours.len());
    assert!((ours[0] - oracle[0]).norm() < 1e-9);
    assert!((ours.last().unwrap() - oracle.last().unwrap()).norm() < 1e-9);
    let tolerance_mm = ReadOptions::default().apt.chord_tolerance * 1e3;
    let oracle_to_ours = distance_to_polyline(oracle, &ours);
    assert!(
        oracle_to_ours <= tolerance_mm + 1e-6,
        "geomdl's curve is {oracle_to_ours} mm from the chords"
    );
    // geomdl's points are 1000 steps apart: its polyline is within 1e-4 mm of its curve.
    let ours_to_oracle = distance_to_polyline(&ours, oracle);
    assert!(
        ours_to_oracle <= 1e-4,
        "a chord point is {ours_to_oracle} mm off geomdl's curve"
    );
    // The spline is said, once; the tool description comes with it.
    assert!(program
        .warnings
        .iter()
        .any(|w| w.message == "NURBS: the B-spline is followed by chords within 0.0010 mm of it"));
    assert_eq!(program.tools[0].name.as_deref(), Some("BALL_MILL-D6"));
}

#[test]
fn nurbs_follow_the_committed_geomdl_evaluation() {
    let text = std::fs::read_to_string(fixture("nx_nurbs.cls.geomdl.txt")).unwrap();
    compare_spline(&oracle_points(&text));
}

#[test]
fn live_geomdl_agrees() {
    let python = std::env::var("CNCSIM_PYTHON").unwrap_or_else(|_| "python3".into());
    let available = std::process::Command::new(&python)
        .args(["-c", "import geomdl"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !available {
        let required = std::env::var("CNCSIM_REQUIRE_ORACLES").is_ok_and(|v| v == "1");
        assert!(
            !required,
            "geomdl is not installed and CNCSIM_REQUIRE_ORACLES=1"
        );
        eprintln!("skipped: geomdl is not installed");
        return;
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/oracles/nurbs_oracle.py");
    let output = std::process::Command::new(&python)
        .arg(script)
        .arg(fixture("nx_nurbs.cls"))
        .arg("1000")
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    compare_spline(&oracle_points(&String::from_utf8_lossy(&output.stdout)));
}

/// CL data as SolidWorks CAM (and CAMWorks, Creo) write it, in a file written here from the
/// records those systems put out: `UNIT/MM`, `RAPID/`, `TRNTYP/WORLD,0,0,0`, `CSYS/` matrices
/// (a part turned over for its second side), `CIRCLE` without a radius, `CYCLE/INIT`, drill
/// depths as positive `FEDTO`, `DEEP2` with `1STPECK`/`SUBPECK`, tool data records and a
/// cycle left on across a tool change.
#[test]
fn solidworks_cam_cl_data_is_read_as_its_records_define_it() {
    let text = "PARTNO/PLATE\nUNIT/MM\nMULTAX/OFF\nCSI_SET_FLUTE_LENGTH/22.\n\
        TRNTYP/WORLD,0,0,0\nCSYS/1.,0,0,0,0,1.,0,0,0,0,1.,0\nRAPID/\nGOTO/40.,20.,5.\n\
        FEDRAT/300.,MMPM\nGOTO/40.,20.,-2.\nCIRCLE/30.,20.,-2.,0,0,1.\nGOTO/30.,30.,-2.\n\
        RAPID/\nGOTO/60.,20.,25.\nCYCLE/INIT\n\
        CYCLE/DRILL,FEDTO,8.,MMPM,120.,RAPTO,3.,RTRCTO,25.,DWELL,0\nGOTO/60.,20.,0.\n\
        CYCLE/DEEP2,FEDTO,9.,1STPECK,5.,SUBPECK,2.,MMPM,100.,RAPTO,3.,RTRCTO,25.\nGOTO/80.,20.,0.\n\
        LOAD/TOOL,2\nTRNTYP/WORLD,0,0,0\nCSYS/-1.,0,0,0,0,1.,0,0,0,0,-1.,0\nRAPID/\n\
        GOTO/90.,10.,-40.,0,0,-1.\nCYCLE/INIT\nCYCLE/DRILL,FEDTO,4.,MMPM,60.,RAPTO,2.,RTRCTO,40.,DWELL,0\n\
        GOTO/90.,10.,-30.,0,0,-1.\nCYCLE/OFF\nFINI\n";
    let program = apt(text);
    let moves = moves_mm(&program, 0);
    // The arc: from (40, 20) about (30, 20) counter-clockwise about +Z (APT's sense, the
    // radius the tool's 10 mm from the axis) to (30, 30): a quarter turn, every point 10 mm
    // from the centre, turning left.
    let arc = &program.moves[2];
    let points = decoded_arc(&[40e-3, 20e-3, -2e-3], arc);
    for p in &points {
        let r = ((p.x - 30.0).powi(2) + (p.y - 20.0).powi(2)).sqrt();
        assert!((r - 10.0).abs() < 1e-6, "{r} mm from the centre");
    }
    let (a, b) = (points[1] - points[0], points[2] - points[1]);
    assert!(
        a.cross(&b).z > 0.0,
        "the arc turns counter-clockwise seen from +Z"
    );
    assert!((arc.end.linear[0] - 0.030).abs() < 1e-12 && (arc.end.linear[1] - 0.030).abs() < 1e-12);
    // The holes: FEDTO 8 is 8 mm below the GOTO point, not 8 mm above RAPTO; RTRCTO 25 above.
    let after_arc: Vec<(&str, [f64; 3])> = vec![
        ("rapid", [60.0, 20.0, 25.0]),
        ("rapid", [60.0, 20.0, 3.0]),
        ("feed 120.000", [60.0, 20.0, -8.0]),
        ("rapid", [60.0, 20.0, 25.0]),
        // DEEP2: a first peck of 5, the next ones of 2, back to RAPTO between them.
        ("rapid", [80.0, 20.0, 25.0]),
        ("rapid", [80.0, 20.0, 3.0]),
        ("feed 100.000", [80.0, 20.0, -2.0]),
        ("rapid", [80.0, 20.0, 3.0]),
        ("rapid", [80.0, 20.0, -2.0 + 0.254]),
        ("feed 100.000", [80.0, 20.0, -4.0]),
        ("rapid", [80.0, 20.0, 3.0]),
        ("rapid", [80.0, 20.0, -4.0 + 0.254]),
        ("feed 100.000", [80.0, 20.0, -6.0]),
        ("rapid", [80.0, 20.0, 3.0]),
        ("rapid", [80.0, 20.0, -6.0 + 0.254]),
        ("feed 100.000", [80.0, 20.0, -8.0]),
        ("rapid", [80.0, 20.0, 3.0]),
        ("rapid", [80.0, 20.0, -8.0 + 0.254]),
        ("feed 100.000", [80.0, 20.0, -9.0]),
        ("rapid", [80.0, 20.0, 25.0]),
    ];
    assert_moves(&moves[3..3 + after_arc.len()], &after_arc);
    // Second side: the part turned over (CSYS rotates 180° about Y). The tool comes from below
    // in the part's frame, (0, 0, -1); in the set-up's frame x' = A·x + d it is +Z again, and
    // the hole is drilled down from the turned GOTO point.
    let a = nalgebra::Matrix3::new(-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
    let start = a * Vector3::new(90.0, 10.0, -40.0);
    let hole = a * Vector3::new(90.0, 10.0, -30.0);
    let turned: Vec<(&str, [f64; 3])> = vec![
        ("rapid", start.into()),
        ("rapid", [hole.x, hole.y, hole.z + 2.0]),
        ("feed 60.000", [hole.x, hole.y, hole.z - 4.0]),
        ("rapid", [hole.x, hole.y, hole.z + 40.0]),
    ];
    let tail = &moves[moves.len() - turned.len()..];
    assert_moves(tail, &turned);
    let axis = program.moves.last().unwrap().tool_axis;
    assert!(
        axis.is_some_and(|a| (Vector3::from(a) - Vector3::z()).norm() < 1e-12),
        "{axis:?}"
    );
    // What was read in a way the records do not spell out is said once each.
    let said = |needle: &str| program.warnings.iter().any(|w| w.message.contains(needle));
    assert!(said("read as a depth below the hole's GOTO point"));
    assert!(said(
        "CSYS: the points and tool axes that follow are carried into this set-up's frame"
    ));
    assert!(said(
        "CSI_SET_FLUTE_LENGTH (SolidWorks CAM tool data) does not move the tool"
    ));
    assert!(said(
        "CYCLE/INIT (cycle initialisation) does not move the tool"
    ));
    // --strict refuses what it skips.
    let mut strict = ReadOptions::default();
    strict.apt.strict = true;
    assert!(parse_apt(text, "t.cls", &strict).is_err());
}

#[test]
fn creo_comments_go_on_over_continued_lines_and_camworks_names_the_arc_direction() {
    // Creo: a `$$->` comment whose line ends in `$` takes the next line with it; DEPTH and
    // CLEAR in its cycles.
    let creo = "$$-> MFGNO / PLATE\nUNITS / MM\n$$-> CSYS / 1.0000000000, 0.0000000000, 0.0000000000, 0.0000000000,  $\n            0.0000000000, 1.0000000000, 0.0000000000, 0.0000000000,  $\n            0.0000000000, 0.0000000000, 1.0000000000, 0.0000000000\nFEDRAT / 100.000000,  MMPM\nRAPID\nGOTO / 10.0, 10.0, 5.0\nCYCLE / DEEP, DEPTH, 3.500000, STEP, 1.000000, MMPM, 50.000000, CLEAR,$\n 1.000000\nGOTO / 10.0, 10.0, 0.0\nCYCLE / OFF\n";
    let program = apt(creo);
    let last_feed = program
        .moves
        .iter()
        .filter(|m| matches!(m.feed, cncsim::program::Feed::PathSpeed(_)))
        .map(|m| m.end.linear[2] * 1e3)
        .fold(f64::INFINITY, f64::min);
    assert!(
        (last_feed - -3.5).abs() < 1e-9,
        "the hole ends {last_feed} mm"
    );
    // A comment decorated with `$$` at both ends does not continue: the GOTO after it stands.
    let decorated =
        apt("FEDRAT/100\n$$ ---------- $$\nGOTO/1,2,3\n$$ note $\n  continued\nGOTO/4,5,6\n");
    assert_eq!(decorated.moves.len(), 2);
    // CAMWorks: the direction as a word after the radius; CLOCKWISE turns the other way.
    let arc = |word: &str| {
        let text = format!(
            "UNITS/MM\nFEDRAT/100\nGOTO/ 10.000000,0.000000,-1.000000\nCIRCLE/ 0.000000,0.000000,-1.000000,0.000000,0.000000,1.000000,10.000000,{word}\nGOTO/ 0.000000,10.000000,-1.000000\n"
        );
        let program = apt(&text);
        let points = decoded_arc(&[0.010, 0.0, -0.001], &program.moves[1]);
        let (a, b) = (points[1] - points[0], points[2] - points[1]);
        a.cross(&b).z
    };
    assert!(arc("COUNTERCLOCKWISE") > 0.0);
    assert!(arc("CLOCKWISE") < 0.0);
}

/// The GOTO points of a CL file (mm), read here line by line: `GOTO / x, y, z[, i, j, k]`.
fn goto_points(text: &str) -> Vec<[f64; 3]> {
    text.lines()
        .filter_map(|line| line.trim_start().strip_prefix("GOTO"))
        .map(|rest| {
            let values: Vec<f64> = rest
                .trim_start()
                .trim_start_matches('/')
                .split(',')
                .map(|v| v.trim().parse().unwrap())
                .collect();
            [values[0], values[1], values[2]]
        })
        .collect()
}

#[test]
fn creo_files_decode_and_reach_every_goto() {
    // Real files written by PTC Creo, from another project: not in this repository, read from
    // the shared corpus (skipped without it, a failure in CI).
    let Some(creo) = common::shared_corpus("programs/creo") else {
        return;
    };
    let read = |name: &str| {
        let path = creo.join(name);
        let text = std::fs::read_to_string(&path).unwrap();
        let program = parse_apt(&text, &path, &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        (text, program)
    };
    for name in ["profilfraesen_2.ncl.1", "schruppen_1.ncl.1"] {
        let (text, program) = read(name);
        let gotos = goto_points(&text);
        assert!(gotos.len() >= 52, "{name}: {} GOTOs", gotos.len());
        let ends: Vec<[f64; 3]> = program
            .moves
            .iter()
            .map(|m| m.end.linear.map(|v| v * 1e3))
            .collect();
        let mut next = 0;
        for (k, goto) in gotos.iter().enumerate() {
            // Each GOTO is reached by a move, in order.
            let found = ends[next..]
                .iter()
                .position(|e| (0..3).all(|i| (e[i] - goto[i]).abs() < 1e-6));
            let Some(offset) = found else {
                panic!("{name}: GOTO {k} {goto:?} is not reached after move {next}");
            };
            next += offset + 1;
        }
    }
    // Drilling: CYCLE / DEEP, DEPTH 3.5, STEP 1, CLEAR 1 at GOTO points 0.5 mm high: each hole
    // fed in pecks of 1 mm from 1.5 mm down to 0.5 − 3.5 = −3 mm, ⌈4.5⌉ = 5 feeds.
    let (_, program) = read("bohren_1.ncl.8");
    let feeds: Vec<[f64; 3]> = program
        .moves
        .iter()
        .filter(|m| matches!(m.feed, cncsim::program::Feed::PathSpeed(_)))
        .map(|m| m.end.linear.map(|v| v * 1e3))
        .collect();
    assert_eq!(feeds.len(), 10, "{feeds:?}");
    for hole in feeds.chunks(5) {
        let bottom = hole.last().unwrap()[2];
        assert!((bottom - -3.0).abs() < 1e-9, "{hole:?}");
        assert!(hole.windows(2).all(|w| w[1][2] < w[0][2]));
    }
}

#[test]
fn a_goto_list_without_feed_runs_at_the_feed_given_or_is_refused() {
    // Tool paths published as bare GOTO lists (a study's 5-axis path, blank-separated): no
    // FEDRAT anywhere. Refused by default; with a feed given they run at it, said once.
    let text = "GOTO/-10.0 5.0 0.0 0.0 0.0 1.0\nGOTO/-10.0 15.0 0.0 0.0 0.0 1.0\nFEDRAT/600\nGOTO/0.0 15.0 0.0\n";
    assert!(first_error(text, &ReadOptions::default())
        .contains("expected a FEDRAT (or RAPID) before the first GOTO"));
    let mut options = ReadOptions::default();
    options.apt.default_feed = Some(0.020);
    let program = parse_apt(text, "t.cls", &options).unwrap();
    let feeds: Vec<f64> = program
        .moves
        .iter()
        .map(|m| match m.feed {
            cncsim::program::Feed::PathSpeed(v) => v * 1e3,
            _ => f64::NAN,
        })
        .collect();
    assert_eq!(feeds, [20.0, 20.0, 10.0]);
    assert_eq!(
        program
            .warnings
            .iter()
            .filter(|w| w.message.contains("no FEDRAT before this GOTO"))
            .count(),
        1
    );
    // A feed for CL data given with a plot file is refused: HPGL programs its own speed.
    let dir = tempfile::tempdir().unwrap();
    let plot = dir.path().join("p.plt");
    std::fs::write(&plot, "IN;PU0,0;PD100,0;").unwrap();
    let e = cncsim::program::read_program(&plot, &options)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("this file is HPGL, which programs its own feed"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------
// The writer's conventions, and the tangents that catch a wrong reading
// ---------------------------------------------------------------------------------------

/// The records of CL text read by hand: `$$` comments dropped, `$` continuations joined;
/// each as (major word, parameters).
fn own_records(text: &str) -> Vec<(String, Vec<String>)> {
    let mut records = Vec::new();
    let mut pending = String::new();
    for line in text.lines() {
        let line = line.trim();
        if line.starts_with("$$") {
            continue;
        }
        match line.strip_suffix('$') {
            Some(head) => pending.push_str(head),
            None => {
                pending.push_str(line);
                let record = std::mem::take(&mut pending);
                let (major, rest) = record.split_once('/').unwrap_or((&record, ""));
                let parameters = rest
                    .split(',')
                    .map(|p| p.trim().to_string())
                    .filter(|p| !p.is_empty())
                    .collect();
                records.push((major.trim().to_uppercase(), parameters));
            }
        }
    }
    records
}

/// Cut length (mm) of CL text read by hand: GOTO moves at feed (not the one after RAPID),
/// each CIRCLE's arc from the tool to the next GOTO turned counter-clockwise about its axis
/// vector (APT's definition) when `counter_clockwise`, else the other way, helical where the
/// GOTO moves along the axis.
fn own_cut_length(text: &str, counter_clockwise: bool) -> f64 {
    let mut at: Option<Vector3<f64>> = None;
    let mut rapid = false;
    let mut circle: Option<(Vector3<f64>, Vector3<f64>)> = None;
    let mut length = 0.0;
    for (major, parameters) in own_records(text) {
        let numbers: Vec<f64> = parameters.iter().filter_map(|p| p.parse().ok()).collect();
        match major.as_str() {
            "RAPID" => rapid = true,
            "CIRCLE" => {
                circle = Some((
                    Vector3::new(numbers[0], numbers[1], numbers[2]),
                    Vector3::new(numbers[3], numbers[4], numbers[5]).normalize(),
                ))
            }
            "GOTO" => {
                let to = Vector3::new(numbers[0], numbers[1], numbers[2]);
                if let (Some(from), false) = (at, rapid) {
                    length += match circle.take() {
                        None => (to - from).norm(),
                        Some((centre, axis)) => {
                            let across = |p: Vector3<f64>| {
                                let r = p - centre;
                                r - axis * r.dot(&axis)
                            };
                            let (a, b) = (across(from), across(to));
                            let turned = axis.dot(&a.cross(&b)).atan2(a.dot(&b));
                            let mut sweep = if counter_clockwise {
                                turned.rem_euclid(std::f64::consts::TAU)
                            } else {
                                (-turned).rem_euclid(std::f64::consts::TAU)
                            };
                            if sweep < 1e-9 {
                                sweep = std::f64::consts::TAU;
                            }
                            let rise = (to - from).dot(&axis);
                            (sweep * a.norm()).hypot(rise)
                        }
                    };
                }
                circle = None;
                rapid = false;
                at = Some(to);
            }
            _ => {}
        }
    }
    length
}

fn cut_length_mm(program: &Program) -> f64 {
    cncsim::program::summarize(program).cut_length * 1e3
}

#[test]
fn creo_arcs_turn_counter_clockwise_and_cut_what_the_file_means() {
    // PTC's CL files: `$$* Pro/CLfile` in the header; CIRCLE counter-clockwise about its
    // axis vector, as APT defines it. Read the NX way, the pocket's corner arcs become
    // three-quarter loops.
    let Some(creo) = common::shared_corpus("programs/creo") else {
        return;
    };
    for name in ["profilfraesen_2.ncl.1", "schruppen_1.ncl.1"] {
        let path = creo.join(name);
        let text = std::fs::read_to_string(&path).unwrap();
        let program = read_program(&path, &ReadOptions::default()).unwrap();
        let reading = program.reading.clone().unwrap();
        assert!(
            reading.contains("PTC Creo") && reading.contains("line 1: `$$*"),
            "{name}: {reading}"
        );
        let expected = own_cut_length(&text, true);
        let loops = own_cut_length(&text, false);
        let got = cut_length_mm(&program);
        assert!(
            (got - expected).abs() <= 1e-6 * expected,
            "{name}: cut length {got:.4} mm, the counter-clockwise reading {expected:.4} mm"
        );
        // The other way round, every corner is a three-quarter loop.
        assert!(loops > 1.1 * expected, "{name}: {loops} vs {expected}");
        assert!(
            !program
                .warnings
                .iter()
                .any(|w| w.message.contains("against")),
            "{name}: {:?}",
            program.warnings
        );
        // Read as NX writes arcs, the arcs whose entry or exit runs along them still turn the
        // way those moves say, and the file says it is not NX's. The profile's arcs all have
        // a tangent lead; of the roughing's 419, the 161 that do are read right (the others
        // are entered and left across the circle or along the tool axis: nothing tells).
        let mut options = ReadOptions::default();
        options.apt.writer = Some(ClWriter::Nx);
        let forced = read_program(&path, &options).unwrap();
        let got = cut_length_mm(&forced);
        if name.starts_with("profil") {
            assert!(
                (got - expected).abs() <= 1e-6 * expected,
                "{name} read as NX: cut length {got:.4} mm, the tangent reading {expected:.4} mm"
            );
        }
        let told = if name.starts_with("profil") { 20 } else { 161 };
        assert!(
            forced.warnings.iter().any(|w| w.message.contains(&format!(
                "({told} of the {told} arcs whose entry or exit move runs along them"
            ))),
            "{name}: {:?}",
            forced.warnings
        );
        let said: Vec<&str> = forced
            .warnings
            .iter()
            .map(|w| w.message.as_str())
            .filter(|m| m.contains("likely written by another CAM system"))
            .collect();
        assert_eq!(said.len(), 1, "{name}: {:?}", forced.warnings);
        assert!(said[0].contains("Siemens NX"), "{}", said[0]);
    }
}

#[test]
fn nx_corpus_files_are_read_as_nx_and_their_tangents_agree() {
    let Some(directory) = common::shared_corpus("programs/apt") else {
        return;
    };
    let mut arcs = 0;
    for entry in std::fs::read_dir(&directory).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        if !name.starts_with("CLSFProcessor") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let program = read_program(&path, &ReadOptions::default()).unwrap();
        let reading = program.reading.clone().unwrap();
        assert!(
            reading.contains("Siemens NX") && reading.contains("`TOOL PATH/"),
            "{name}: {reading}"
        );
        assert!(
            !program
                .warnings
                .iter()
                .any(|w| w.message.contains("against")),
            "{name}: {:?}",
            program.warnings
        );
        arcs += text.matches("CIRCLE/").count();
    }
    assert!(arcs > 100, "{arcs} arcs");
}

/// The one arc of `program` (a Motion::Arc): whether it turns clockwise seen from +Z.
fn the_arc_is_clockwise(program: &Program) -> bool {
    let arcs: Vec<bool> = program
        .moves
        .iter()
        .filter_map(|m| match m.motion {
            Motion::Arc { clockwise, .. } => Some(clockwise),
            _ => None,
        })
        .collect();
    assert_eq!(arcs.len(), 1, "{:?}", program.moves);
    arcs[0]
}

#[test]
fn an_arc_turns_the_way_its_entry_or_exit_runs_along_it() {
    // No writer named: APT's convention, counter-clockwise about (0,0,1).
    let quarter = "FEDRAT/600\nGOTO/0,10,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/10,0,0\n";
    // From the left heading +X at (0,10): clockwise seen from +Z, against the convention.
    let entering = format!("FEDRAT/600\nRAPID\nGOTO/-10,10,0\n{}", &quarter[11..]);
    let program = apt(&entering);
    assert!(the_arc_is_clockwise(&program));
    assert!((cut_length_mm(&program) - (10.0 + 5.0 * std::f64::consts::PI)).abs() < 1e-9);
    let against: Vec<&str> = program
        .warnings
        .iter()
        .map(|w| w.message.as_str())
        .filter(|m| m.contains("against the convention of standard APT"))
        .collect();
    assert_eq!(against.len(), 2, "{:?}", program.warnings);
    assert!(
        against[0].contains("as its entry move runs along it")
            && against[0].contains("(1 of the 1 arcs")
    );
    // Entered radially (says nothing), left heading -Y at (10,0): clockwise again.
    let leaving = format!(
        "FEDRAT/600\nRAPID\nGOTO/0,20,0\n{}GOTO/10,-10,0\n",
        &quarter[11..]
    );
    let program = apt(&leaving);
    assert!(the_arc_is_clockwise(&program));
    assert!(program.warnings[0]
        .message
        .contains("as its exit move runs along it"));
    // Entered and left radially: the convention, without a word.
    let radial = format!("FEDRAT/600\nGOTO/0,20,0\n{}GOTO/20,0,0\n", &quarter[11..]);
    let program = apt(&radial);
    assert!(!the_arc_is_clockwise(&program));
    assert!(program.warnings.is_empty(), "{:?}", program.warnings);
    // The tangent reading agrees with the convention: no word either.
    let along = format!("FEDRAT/600\nGOTO/10,10,0\n{}", &quarter[11..]);
    let program = apt(&along);
    assert!(!the_arc_is_clockwise(&program));
    assert!(program.warnings.is_empty(), "{:?}", program.warnings);
}

#[test]
fn the_writer_is_named_by_the_header_or_the_user() {
    let read = |text: &str, name: &str, writer: Option<ClWriter>| {
        let mut options = ReadOptions::default();
        options.apt.writer = writer;
        parse_apt(text, name, &options).unwrap().reading.unwrap()
    };
    let plain = "FEDRAT/600\nGOTO/1,2,3\n";
    assert!(read(plain, "a.apt", None)
        .contains("standard APT (no writer recognised) (no writer's mark"));
    assert!(read(plain, "part.ncl", None).contains("PTC Creo / Pro/ENGINEER (the file name's .ncl"));
    assert!(read(&format!("$$*CATIA0\n{plain}"), "a.aptsource", None)
        .contains("CATIA (line 1: `$$*CATIA0`)"));
    assert!(read(&format!("$$Machine Group-1\n{plain}"), "a.apt", None).contains("Mastercam"));
    let named = read(
        &format!("TOOL PATH/A,TOOL,B\n{plain}"),
        "a.cls",
        Some(ClWriter::Creo),
    );
    assert!(
        named.contains("PTC Creo") && named.contains("named by the user"),
        "{named}"
    );
    assert!(
        named.contains("turn counter-clockwise about their axis vector"),
        "{named}"
    );
}

#[test]
fn apt_is_recognised_with_blanks_around_the_slash_and_partno_without_one() {
    use cncsim::program::ProgramFormat;
    for head in [
        "PARTNO CORE_WORK\nUNITS / MM\n",
        "$$* header\nPARTNO PART TO BE MACHINED\n",
        "$$ comment\nGOTO / 1.0, 2.0, 3.0\n",
        "MULTAX\nGOTO  / 1, 2, 3\n",
    ] {
        assert_eq!(
            ProgramFormat::from_content(head.as_bytes()),
            Some(ProgramFormat::Apt),
            "{head:?}"
        );
    }
    for name in ["x.ncl", "bohren_1.ncl.8"] {
        assert_eq!(
            ProgramFormat::from_path(Path::new(name)),
            Some(ProgramFormat::Apt),
            "{name}"
        );
    }
    // G-code is not taken for CL data.
    assert_ne!(
        ProgramFormat::from_content(b"G0 X1 Y2\nG1 Z-1 F100\n"),
        Some(ProgramFormat::Apt)
    );
}

#[test]
fn a_tap_feeds_one_pitch_per_revolution() {
    // 20 threads per inch at 600 rpm: 1.27 mm × 600 = 762 mm/min, whatever feed is written.
    for (pitch, written) in [("TPI, 20", ", MMPM, 700"), ("PITCH, 1.27", "")] {
        let text = format!(
            "UNITS / MM\nSPINDL / RPM, 600, CLW\nFEDRAT / 300, MMPM\nRAPID\nGOTO / 0, 0, 5\nCYCLE / TAP, DEPTH, 10, {pitch}{written}, CLEAR, 2\nGOTO / 0, 0, 0\nCYCLE / OFF\n"
        );
        let program = apt(&text);
        let feeds: Vec<f64> = program
            .moves
            .iter()
            .filter_map(|m| match m.feed {
                cncsim::program::Feed::PathSpeed(speed) => Some(speed * 60e3),
                _ => None,
            })
            .collect();
        assert!(!feeds.is_empty());
        for feed in feeds {
            assert!((feed - 762.0).abs() < 1e-9, "{pitch}: {feed} mm/min");
        }
        let warned = program
            .warnings
            .iter()
            .any(|w| w.message.contains("not pitch × spindle speed"));
        assert_eq!(warned, !written.is_empty(), "{:?}", program.warnings);
    }
    // Without a turning spindle a tap cannot be fed.
    let error = first_error(
        "UNITS/MM\nFEDRAT/300\nCYCLE/TAP,DEPTH,10,TPI,20,CLEAR,2\n",
        &ReadOptions::default(),
    );
    assert!(
        error.contains("expected a turning spindle for CYCLE/TAP"),
        "{error}"
    );
}

#[test]
fn lathe_programs_are_refused_as_lathe_programs_by_name() {
    for (record, what) in [
        ("HEAD / 1", "HEAD selects a lathe's turret head"),
        (
            "CYCLE / TURN, 2.0, MMPR, 0.2",
            "CYCLE/TURN is a turning cycle",
        ),
        (
            "OP / THREAD, 1.5",
            "OP/THREAD is a threading pass on a lathe",
        ),
    ] {
        let text =
            format!("PARTNO / SHAFT\nUNITS / MM\n{record}\nFEDRAT / 0.2, MMPR\nGOTO / 10, 0, 0\n");
        let errors = parse_apt(&text, "shaft.ncl", &ReadOptions::default()).unwrap_err();
        assert_eq!(errors.errors.len(), 1, "{record}: {errors}");
        let message = errors.errors[0].to_string();
        assert!(
            message.starts_with("shaft.ncl:3:1: expected a milling program; ")
                && message.contains(what)
                && message.contains("this is a lathe (turning) program"),
            "{message}"
        );
    }
}

#[test]
fn movarc_is_an_arc_through_its_angle() {
    // Autodesk's APT post: MOVARC/centre, normal, radius, ANGLE, sweep; counter-clockwise
    // about the normal.
    let text = "PARTNO/'BOSS'\nPPRINT/'Autodesk Fusion'\nUNITS/MM\nFEDRAT/600,MMPM\nRAPID\nGOTO/10,0,0\nMOVARC/0,0,0,0,0,1,10,ANGLE,450\nGOTO/0,10,0\n";
    let program = apt(text);
    assert!(program
        .reading
        .as_ref()
        .unwrap()
        .contains("Autodesk Fusion"));
    assert!(!the_arc_is_clockwise(&program));
    let expected = 10.0 * std::f64::consts::PI * 2.5;
    assert!(
        (cut_length_mm(&program) - expected).abs() < 1e-9,
        "{}",
        cut_length_mm(&program)
    );
}

#[test]
fn catia_lines_wrapped_inside_a_number_are_joined_as_written() {
    // CATIA wraps its records at a fixed column, inside a number if need be.
    let text = "$$*CATIA0\nPARTNO PART TO BE MACHINED\nFEDRAT/ 2000.0000,MMPM\nGOTO  / 10.00000, 20.00000,   0$\n.752602\nGOTO  / 10.00000, 21.00000, $\n  1.5\n";
    let program = apt(text);
    let ends: Vec<[f64; 3]> = program
        .moves
        .iter()
        .map(|m| m.end.linear.map(|v| v * 1e3))
        .collect();
    assert_eq!(ends.len(), 2, "{ends:?}");
    assert!((ends[0][2] - 0.752602).abs() < 1e-9, "{ends:?}");
    assert!((ends[1][2] - 1.5).abs() < 1e-9, "{ends:?}");
    assert!(program.reading.unwrap().contains("CATIA"));
}

#[test]
fn points_after_a_goto_are_more_points_of_it_and_of_its_arc() {
    // Pro/ENGINEER: a CIRCLE, a GOTO, then the arc's further points on lines of their own;
    // here a full circle of radius 0.025 in through 300°, 60° and back to 180°.
    let text = "$$*  Pro/CLfile  Vers 1.0\nUNITS / INCHES\nFEDRAT / 10.000000,  IPM\nGOTO / 7.4300, 5.8500, 1.8000\nCIRCLE / 7.4550, 5.8500, 1.8000,  $\n0.0000, 0.0000, 1.0000,  0.0250\nGOTO / 7.4675, 5.8283, 1.8000\n       7.4675, 5.8717, 1.8000\n       7.4300, 5.8500, 1.8000\nFEDRAT / 5.000000,  IPM\nGOTO / 7.4300, 5.8500, 1.3000\n";
    let program = apt(text);
    let arcs: Vec<&cncsim::program::Move> = program
        .moves
        .iter()
        .filter(|m| {
            matches!(
                m.motion,
                Motion::Arc {
                    clockwise: false,
                    ..
                }
            )
        })
        .collect();
    assert_eq!(arcs.len(), 3, "{:?}", program.moves);
    // 4 in from the origin (not cut: no RAPID, so it counts), one full turn of 0.025 in.
    let circumference = std::f64::consts::TAU * 0.025 * 25.4;
    let first: f64 = Vector3::new(7.43, 5.85, 1.8).norm() * 25.4;
    let last = 0.5 * 25.4;
    let expected = first + circumference + last;
    // The points are written to 0.0001 in: the arcs through them are as long within 0.01 mm.
    assert!(
        (cut_length_mm(&program) - expected).abs() < 0.01,
        "{} vs {expected}",
        cut_length_mm(&program)
    );
    // Bare numbers anywhere else are still an error.
    assert!(first_error("FEDRAT/10\n1,2,3\n", &ReadOptions::default())
        .contains("expected an APT statement word"));
}
