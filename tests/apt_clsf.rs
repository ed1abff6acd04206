//! APT / CLSF as CAM systems write it: CIRCLE arcs checked against the CIRCLE records' own
//! centre, axis and radius and against an arc sampled here from the record alone; NX CLSF
//! structure; records that would change the path but cannot be followed are errors.

use std::path::Path;

use cncsim::program::{
    arc_sweep, parse_apt, plane_axes, read_program, CircleSense, Motion, Program, ReadOptions,
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
    // Each kind of skipped record warned about once.
    let kinds: Vec<&str> = program
        .warnings
        .iter()
        .map(|w| w.message.split_whitespace().next().unwrap())
        .collect();
    assert_eq!(
        kinds,
        [
            "TOOL",
            "TLDATA",
            "MSYS:",
            "PAINT",
            "LOAD",
            "COOLNT",
            "CUTCOM",
            "END-OF-PATH"
        ]
    );
}

#[test]
fn a_large_circle_is_an_arc_not_a_chord() {
    // The case: a radius-473 mm arc (90°), once silently a chord up to 139 mm off.
    let program =
        apt("UNITS/MM\nFEDRAT/1000\nGOTO/473,0,0\nCIRCLE/0,0,0,0,0,-1,473,0.01\nGOTO/0,473,0\n");
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
    let program = apt(&text);
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
    // Clockwise about the axis, the end is three quarters round; the other sense takes
    // the quarter turn.
    let mut options = ReadOptions::default();
    options.apt.circle_sense = CircleSense::CounterClockwiseAboutAxis;
    let other = parse_apt(&text, "t.cls", &options).unwrap();
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
        ("CIRCLE/0,0,0,0,0,1", "bad.cls:1:1: expected at least 7 numbers after CIRCLE/ (centre, axis, radius), not 6, found 'CIRCLE/0,0,0,0,0,1'"),
        ("CIRCLE/0,0,0,0,0,0,5", "bad.cls:1:1: expected a non-zero axis vector and a positive radius in CIRCLE, found 'CIRCLE/0,0,0,0,0,0,5'"),
        ("CYCLE/DRILL,RAPTO,2,FEDTO,-10,MMPM,100", "bad.cls:1:1: expected records cncsim can follow; CYCLE changes the tool path and canned cycles are not supported, found 'CYCLE/DRILL,RAPTO,2,FEDTO,-10,MMPM,100'; hint: post the CL data with the path written out as GOTO (and CIRCLE) records"),
        ("ORIGIN/10,0,0", "bad.cls:1:1: expected records cncsim can follow; ORIGIN changes the tool path and origin shifts are not supported, found 'ORIGIN/10,0,0'; hint: post the CL data with the path written out as GOTO (and CIRCLE) records"),
        ("WIBBLE/3", "bad.cls:1:1: expected an APT record cncsim knows; WIBBLE is not one, found 'WIBBLE'; hint: a record that may change the tool path is not skipped; remove it if it does not"),
        ("MSYS/0,0,0,1,0,0,1,0,0", "bad.cls:1:12: expected unit, perpendicular X and Y axis vectors in MSYS/x,y,z,xi,xj,xk,yi,yj,yk, found '1,0,0,1,0,0'"),
        ("GOHOME", "bad.cls:1:1: expected a FROM point before GOHOME (it returns there), found 'GOHOME'"),
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
