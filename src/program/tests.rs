//! Tests of the three readers against the reference programs, the features each language
//! needs, and the exact error messages of bad inputs.

use std::path::PathBuf;

use super::types::{Blend, Feed, FeedRule, Motion, Plane, Position, Program, Spindle};
use super::*;

/// The sample programs of the source documents (copies of the sample programs described in docs/sources.md).
fn samples_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenarios/programs")
}

fn sample(name: &str) -> PathBuf {
    samples_dir().join(name)
}

fn gcode(text: &str) -> Program {
    gcode_with(text, &ReadOptions::default())
}

fn gcode_with(text: &str, options: &ReadOptions) -> Program {
    match parse_gcode(text, "t.ngc", options) {
        Ok(program) => program,
        Err(errors) => panic!("unexpected errors:\n{errors}"),
    }
}

fn errors_of(result: Result<Program, ProgramErrors>) -> Vec<String> {
    match result {
        Ok(program) => panic!("expected errors, got {} moves", program.moves.len()),
        Err(errors) => errors.errors.iter().map(|e| e.to_string()).collect(),
    }
}

fn mm(metres: f64) -> f64 {
    metres * 1000.0
}

fn assert_close(actual: f64, expected: f64, tolerance: f64) {
    assert!(
        (actual - expected).abs() <= tolerance,
        "expected {expected} ± {tolerance}, got {actual}"
    );
}

/// Durations of all moves, in order.
fn durations(program: &Program) -> Vec<Option<f64>> {
    let mut position = program.start;
    program
        .moves
        .iter()
        .map(|mv| {
            let duration = move_duration(&position, mv);
            position = mv.end;
            duration
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// G-code
// ---------------------------------------------------------------------------------------

#[test]
fn d_table2_segment_times_under_the_euclidean_rule() {
    let options = ReadOptions {
        feed_rule: FeedRule::EuclideanAllAxes,
        ..ReadOptions::default()
    };
    let program = read_program(&sample("d_table2.ngc"), &options).unwrap();
    assert_eq!(program.moves.len(), 6);
    assert_eq!(program.moves[0].feed, Feed::Rapid);
    let times: Vec<f64> = durations(&program)[1..]
        .iter()
        .map(|t| t.unwrap())
        .collect();
    let expected = [0.422, 0.471, 0.422, 0.365, 0.258];
    for (time, expected) in times.iter().zip(expected) {
        assert_close(*time, expected, 0.0005);
    }
    assert_close(times.iter().sum::<f64>(), 1.938, 0.0015);
    // F9000 mm/min is the study's 150 mm/s; exact stops throughout.
    assert_eq!(program.moves[1].feed, Feed::PathSpeed(0.15));
    assert!(program.moves.iter().all(|m| m.blend == Blend::ExactStop));
    let last = &program.moves[5].end;
    assert_eq!(last.linear, [0.06, 0.05, 0.03]);
    assert_close(last.rotary[0], 20f64.to_radians(), 1e-15);
    assert_close(last.rotary[2], (-30f64).to_radians(), 1e-15);
}

#[test]
fn d_table2_under_linuxcnc_rule_feeds_only_the_linear_axes() {
    let program = read_program(&sample("d_table2.ngc"), &ReadOptions::default()).unwrap();
    let first = durations(&program)[1].unwrap();
    // sqrt(20² + 10² + 30²) / 150
    assert_close(first, 1400f64.sqrt() / 150.0, 1e-12);
}

#[test]
fn purely_rotary_move_under_linuxcnc_rule_uses_degrees_per_minute() {
    for units in ["G21", "G20"] {
        let program = gcode(&format!("{units} G1 A90 F45"));
        // 90 degrees at 45 deg/min = 2 minutes, whatever the length units.
        assert_close(durations(&program)[0].unwrap(), 120.0, 1e-9);
    }
}

#[test]
fn units_distance_modes_and_rotary_degrees() {
    let program = gcode("G20 G0 X1 Y2\nG91 X1 A90\nG21 G90 Z-3 C-45");
    assert_eq!(program.moves[0].end.linear, [0.0254, 0.0508, 0.0]);
    assert_close(program.moves[1].end.linear[0], 0.0508, 1e-15);
    assert_eq!(program.moves[1].end.rotary[0], std::f64::consts::FRAC_PI_2);
    assert_eq!(program.moves[2].end.linear[2], -0.003);
    assert_eq!(program.moves[2].end.rotary[2], -std::f64::consts::FRAC_PI_4);
}

#[test]
fn words_comments_line_numbers_and_block_delete() {
    let text = "N10 g1 x 1 . 5 y-2 f600 (comment) ; rest\n/G0 X100\n  (only a comment)\nN20G0X0.5";
    let program = gcode(text);
    assert_eq!(program.moves.len(), 2);
    assert_eq!(program.moves[0].end.linear, [0.0015, -0.002, 0.0]);
    assert_eq!(program.moves[0].feed, Feed::PathSpeed(0.01));
    assert_eq!(program.moves[1].span.line, 4);
    assert_eq!(program.moves[1].end.linear[0], 0.0005);
    // With the block-delete switch off the '/' block runs.
    let mut options = ReadOptions::default();
    options.gcode.block_delete = false;
    let program = gcode_with(text, &options);
    assert_eq!(program.moves.len(), 3);
    assert_eq!(program.moves[1].end.linear[0], 0.1);
}

#[test]
fn arcs_in_centre_form() {
    // Half circle, clockwise, centre 5 mm along X (G91.1 offsets are from the start).
    let program = gcode("G17 G2 X10 Y0 I5 J0 F100");
    let mv = &program.moves[0];
    assert_eq!(
        mv.motion,
        Motion::Arc {
            center: [0.005, 0.0, 0.0],
            plane: Plane::XY,
            clockwise: true,
            turns: 0
        }
    );
    assert_close(
        move_length(&program.start, mv),
        0.005 * std::f64::consts::PI,
        1e-15,
    );
    // G90.1: I J are absolute.
    let program = gcode("G0 X10\nG90.1 G3 X20 Y0 I15 J0 F100");
    assert_eq!(
        program.moves[1].motion,
        Motion::Arc {
            center: [0.015, 0.0, 0.0],
            plane: Plane::XY,
            clockwise: false,
            turns: 0
        }
    );
}

#[test]
fn full_circle_and_helix_with_turns() {
    let program = gcode("G2 X0 Y0 I5 F100");
    assert_close(
        move_length(&program.start, &program.moves[0]),
        0.01 * std::f64::consts::PI,
        1e-15,
    );
    // Two turns (P2) down 1 mm.
    let program = gcode("G3 X0 Y0 Z-1 I5 P2 F100");
    let mv = &program.moves[0];
    assert!(matches!(
        mv.motion,
        Motion::Arc {
            turns: 1,
            clockwise: false,
            ..
        }
    ));
    let expected = (2.0 * 0.01 * std::f64::consts::PI).hypot(0.001);
    assert_close(move_length(&program.start, mv), expected, 1e-15);
}

#[test]
fn arcs_in_radius_form() {
    // Quarter circle clockwise from (0,0) to (5,5): short way round (5,0).
    let program = gcode("G2 X5 Y5 R5 F100");
    let Motion::Arc { center, .. } = program.moves[0].motion else {
        panic!()
    };
    assert_close(center[0], 0.005, 1e-15);
    assert_close(center[1], 0.0, 1e-15);
    // Negative R: the long way round, centre (0,5), 270 degrees.
    let program = gcode("G2 X5 Y5 R-5 F100");
    let Motion::Arc { center, .. } = program.moves[0].motion else {
        panic!()
    };
    assert_close(center[0], 0.0, 1e-15);
    assert_close(center[1], 0.005, 1e-15);
    assert_close(
        move_length(&program.start, &program.moves[0]),
        0.005 * 1.5 * std::f64::consts::PI,
        1e-15,
    );
}

#[test]
fn arcs_in_other_planes() {
    // G18: Z is the first axis, X the second; centre offsets K and I; helical along Y.
    let program = gcode("G18 G2 Z10 X0 K5 Y3 F100");
    assert_eq!(
        program.moves[0].motion,
        Motion::Arc {
            center: [0.0, 0.0, 0.005],
            plane: Plane::ZX,
            clockwise: true,
            turns: 0
        }
    );
    let program = gcode("G19 G3 Y10 Z0 J5 F100");
    assert_eq!(
        program.moves[0].motion,
        Motion::Arc {
            center: [0.0, 0.005, 0.0],
            plane: Plane::YZ,
            clockwise: false,
            turns: 0
        }
    );
}

#[test]
fn arc_end_point_tolerance_follows_linuxcnc() {
    // 0.02 mm off: inside the absolute tolerance (0.0283 mm).
    assert!(parse_gcode("G2 X10.02 Y0 I5 F100", "t.ngc", &ReadOptions::default()).is_ok());
    // 0.1 mm off a 5 mm radius: 2 % and 0.1 mm, refused.
    assert!(parse_gcode("G2 X10.1 Y0 I5 F100", "t.ngc", &ReadOptions::default()).is_err());
    // 0.05 mm off a 100 mm radius: more than the absolute tolerance but within 0.1 %.
    assert!(parse_gcode("G2 X200.05 Y0 I100 F100", "t.ngc", &ReadOptions::default()).is_ok());
    // 3 mm off a 10 m radius: within 0.1 % but beyond 100 × the absolute tolerance.
    assert!(parse_gcode("G2 X20003 Y0 I10000 F100", "t.ngc", &ReadOptions::default()).is_err());
    // In inches the tolerance is 0.002828 in: 0.002 in passes, 0.004 in on r=1 in fails.
    assert!(parse_gcode("G20 G2 X2.002 Y0 I1 F10", "t.ngc", &ReadOptions::default()).is_ok());
    assert!(parse_gcode("G20 G2 X2.004 Y0 I1 F10", "t.ngc", &ReadOptions::default()).is_err());
}

#[test]
fn path_control_dwell_spindle_and_feed_modes() {
    let program = gcode(
        "G61 G1 X1 F60\nG64 P0.02 X2\nG64 X3\nG4 P1.5\nS1200 M3\nG1 X4\nM4\nG93 G1 X5 F2\nM5 G94 G1 X6 F60",
    );
    let moves = &program.moves;
    assert_eq!(moves[0].blend, Blend::ExactStop);
    assert_eq!(moves[0].feed, Feed::PathSpeed(0.001));
    assert_eq!(
        moves[1].blend,
        Blend::Continuous {
            tolerance: Some(0.00002),
            naive_cam: Some(0.00002),
        }
    );
    assert_eq!(
        moves[2].blend,
        Blend::Continuous {
            tolerance: None,
            naive_cam: None,
        }
    );
    assert_eq!(moves[3].motion, Motion::Dwell { seconds: 1.5 });
    assert_eq!(moves[3].end.linear[0], 0.003);
    assert_eq!(moves[4].spindle, Spindle::Clockwise { rpm: 1200.0 });
    assert_eq!(moves[5].spindle, Spindle::CounterClockwise { rpm: 1200.0 });
    // G93 F2: the move takes half a minute.
    assert_eq!(moves[5].feed, Feed::InverseTime(30.0));
    assert_eq!(moves[6].spindle, Spindle::Off);
    assert_eq!(moves[6].feed, Feed::PathSpeed(0.001));
    assert_eq!(durations(&program)[3], Some(1.5));
    // LinuxCNC clears the feed rate on every G94: a G1 after it needs a new F.
    let errors = errors_of(parse_gcode(
        "G1 X1 F60\nG94\nG1 X2",
        "t.ngc",
        &ReadOptions::default(),
    ));
    assert_eq!(errors, vec!["t.ngc:3:1: expected a non-zero feed rate (F word) before a G1/G2/G3 move, found 'G1 X2'; hint: add e.g. F300 (mm per minute in G94)"]);
}

#[test]
fn program_end_and_percent_delimiters() {
    // Anything after M2 is not read, not even garbage.
    let program = gcode("G0 X1\nM2\nG0 X2 @@@");
    assert_eq!(program.moves.len(), 1);
    let program = gcode("%\nG0 X1\n%\nthis is not read");
    assert_eq!(program.moves.len(), 1);
}

#[test]
fn a_block_with_an_error_is_skipped_and_reading_goes_on() {
    let result = parse_gcode(
        "G0 X1\nG0 XQ\nG1 X2\nG0 G1 X3\nG0 X4",
        "part.ngc",
        &ReadOptions::default(),
    );
    let errors = errors_of(result);
    assert_eq!(
        errors,
        vec![
            "part.ngc:2:5: expected a number after 'X', found 'Q'",
            "part.ngc:3:1: expected a non-zero feed rate (F word) before a G1/G2/G3 move, found 'G1 X2'; hint: add e.g. F300 (mm per minute in G94)",
            "part.ngc:4:4: expected one G code of the motion group per block, but G0 and G1 are both in it, found 'G1'; hint: LinuxCNC refuses two codes of one modal group in a block; split the block",
        ]
    );
}

#[test]
fn error_count_is_capped_and_the_rest_counted() {
    let text = "G0 XQ\n".repeat(150);
    let options = ReadOptions {
        max_errors: 100,
        ..ReadOptions::default()
    };
    let errors = parse_gcode(&text, "t.ngc", &options).unwrap_err();
    assert_eq!(errors.errors.len(), 100);
    assert_eq!(errors.suppressed, 50);
    assert!(errors.to_string().ends_with("… and 50 more errors"));
}

// ---------------------------------------------------------------------------------------
// HPGL
// ---------------------------------------------------------------------------------------

/// (x, y, z) in mm and tool-down flag of each move.
fn hpgl_points(program: &Program) -> Vec<([f64; 3], Option<bool>)> {
    program
        .moves
        .iter()
        .map(|m| {
            (
                [
                    mm(m.end.linear[0]),
                    mm(m.end.linear[1]),
                    mm(m.end.linear[2]),
                ],
                m.tool_down,
            )
        })
        .collect()
}

#[test]
fn b_line_5mm_decodes_exactly() {
    let program = read_program(&sample("b_line_5mm.plt"), &ReadOptions::default()).unwrap();
    let moves = &program.moves;
    assert_eq!(program.start.linear, [0.0, 0.0, 0.005]);
    assert_eq!(moves.len(), 4);
    // Pen down at the origin, line to (5, 0) mm, pen up, back to the origin.
    assert_eq!(
        (moves[0].end.linear, moves[0].tool_down),
        ([0.0, 0.0, 0.0], Some(true))
    );
    assert_eq!(
        (moves[1].end.linear, moves[1].tool_down),
        ([0.005, 0.0, 0.0], Some(true))
    );
    assert_eq!(moves[1].feed, Feed::PathSpeed(0.2)); // VS20: 20 cm/s
    assert_eq!(moves[1].motion, Motion::Linear);
    assert_eq!(
        (moves[2].end.linear, moves[2].tool_down),
        ([0.005, 0.0, 0.005], Some(false))
    );
    assert_eq!(
        (moves[3].end.linear, moves[3].tool_down),
        ([0.0, 0.0, 0.005], Some(false))
    );
    assert_eq!(moves[3].feed, Feed::Rapid);
    assert_eq!(program.warnings, vec![]);
}

#[test]
fn b_square_and_triangle_decode_exactly() {
    let square = read_program(&sample("b_square_5mm.plt"), &ReadOptions::default()).unwrap();
    let corners: Vec<[f64; 3]> = square
        .moves
        .iter()
        .filter(|m| !is_rapid(m))
        .map(|m| m.end.linear)
        .collect();
    assert_eq!(
        corners,
        vec![
            [0.005, 0.0, 0.0],
            [0.005, 0.005, 0.0],
            [0.0, 0.005, 0.0],
            [0.0, 0.0, 0.0]
        ]
    );
    let triangle = read_program(&sample("b_triangle_5mm.plt"), &ReadOptions::default()).unwrap();
    let corners: Vec<[f64; 3]> = triangle
        .moves
        .iter()
        .filter(|m| !is_rapid(m))
        .map(|m| m.end.linear)
        .collect();
    // PA100,173: 2.5 mm, 4.325 mm.
    assert_eq!(
        corners,
        vec![[0.005, 0.0, 0.0], [0.0025, 0.004325, 0.0], [0.0, 0.0, 0.0]]
    );
    assert_close(
        summarize(&triangle).cut_length,
        0.005 + 2.0 * 0.0025f64.hypot(0.004325),
        1e-15,
    );
}

#[test]
fn b_circle_r3mm_decodes_exactly() {
    let program = read_program(&sample("b_circle_r3mm.plt"), &ReadOptions::default()).unwrap();
    let points = hpgl_points(&program);
    // Rapid to (6, 3), pen down, 36 chords round the circle, pen up, home.
    assert_eq!(points[0], ([6.0, 3.0, 5.0], Some(false)));
    assert_eq!(points[1], ([6.0, 3.0, 0.0], Some(true)));
    let chords: Vec<&Move> = program.moves.iter().filter(|m| !is_rapid(m)).collect();
    assert_eq!(chords.len(), 36);
    assert_eq!(chords[0].end.linear, [0.005975, 0.003525, 0.0]); // PA239,141
    assert_eq!(chords[8].end.linear, [0.003, 0.006, 0.0]); // PA120,240
    assert_eq!(chords[26].end.linear, [0.003, 0.0, 0.0]); // PA120,0
    assert_eq!(chords[35].end.linear, [0.006, 0.003, 0.0]); // PA240,120 closes it
                                                            // Every chord end lies within 1.6 plotter units (0.04 mm) of the 3 mm circle about
                                                            // (3, 3); AutoCAD's worst point, PA26,197, is 1.5 units out.
    for chord in &chords {
        let radius = (chord.end.linear[0] - 0.003).hypot(chord.end.linear[1] - 0.003);
        assert_close(radius, 0.003, 0.000040);
    }
    assert_eq!(points.last().unwrap().0, [0.0, 0.0, 5.0]);
}

#[test]
fn damaged_circle_is_refused_by_default_and_lenient_reading_drops_the_coordinate() {
    let path = sample("b_circle_r3mm_as_printed.plt");
    let errors = read_program(&path, &ReadOptions::default()).unwrap_err();
    assert_eq!(errors.errors.len(), 1);
    assert_eq!(
        errors.errors[0].to_string(),
        format!(
            "{}:1:287: expected x,y pairs after PA: an even number of coordinates, not 1 (byte offset 286), found 'PA120'; hint: the file may be damaged; the lenient option drops the dangling coordinate",
            path.display()
        )
    );
    let mut options = ReadOptions::default();
    options.hpgl.lenient = true;
    let program = read_program(&path, &options).unwrap();
    assert_eq!(program.warnings.len(), 1);
    assert_eq!(program.warnings[0].span.column, 287);
    assert_eq!(
        program.warnings[0].message,
        "PA has 1 coordinate: the dangling coordinate 120 is dropped"
    );
    let chords: Vec<&Move> = program.moves.iter().filter(|m| !is_rapid(m)).collect();
    assert_eq!(chords.len(), 35);
    // The printed start point is PA240,123.
    assert_eq!(program.moves[0].end.linear, [0.006, 0.003075, 0.005]);
    assert_eq!(chords[25].end.linear, [0.002475, 0.000025, 0.0]); // PA99,1
    assert_eq!(chords[26].end.linear, [0.003525, 0.000025, 0.0]); // PA141,1
}

fn hpgl(text: &str, options: &ReadOptions) -> HpglOutput {
    match parse_hpgl_detailed(text, "t.plt", options) {
        Ok(output) => output,
        Err(errors) => panic!("unexpected errors:\n{errors}"),
    }
}

/// The drawn segments as unordered pairs of end points (plotter units, rounded), sorted.
fn drawn_segments(program: &Program) -> Vec<[[i64; 2]; 2]> {
    let mut position = program.start;
    let mut segments = Vec::new();
    for mv in &program.moves {
        if !is_rapid(mv) {
            let a = [
                (position.linear[0] * 40_000.0).round() as i64,
                (position.linear[1] * 40_000.0).round() as i64,
            ];
            let b = [
                (mv.end.linear[0] * 40_000.0).round() as i64,
                (mv.end.linear[1] * 40_000.0).round() as i64,
            ];
            segments.push(if a <= b { [a, b] } else { [b, a] });
        }
        position = mv.end;
    }
    segments.sort();
    segments
}

#[test]
fn four_separate_strokes_of_a_square_become_one_chained_drawing() {
    // AutoCAD without optimisation: four LINE entities, pen lifted between them, drawn in an
    // order that needs pen-up returns.
    let text = "IN;SP1;PU0,0;PD2000,0;PU;PU2000,2000;PD0,2000;PU;PU2000,0;PD2000,2000;PU;PU0,2000;PD0,0;PU;PU0,0;SP;";
    let plain = hpgl(text, &ReadOptions::default());
    let mut options = ReadOptions::default();
    options.hpgl.optimise_pen_up = true;
    let optimised = hpgl(text, &options);
    // Same lines drawn.
    assert_eq!(
        drawn_segments(&plain.program),
        drawn_segments(&optimised.program)
    );
    assert_eq!(drawn_segments(&optimised.program).len(), 4);
    // As drawn: 4 lifts and 50 + 50√2 + 50 mm of pen-up travel; after: one stroke.
    assert_eq!(plain.pen_up.lifts_before, 4);
    assert_close(plain.pen_up.before, 0.05 + 0.05 * 2f64.sqrt() + 0.05, 1e-12);
    assert_eq!(
        plain.pen_up,
        PenUpTravel {
            after: plain.pen_up.before,
            lifts_after: 4,
            ..plain.pen_up
        }
    );
    assert_eq!(optimised.pen_up.lifts_after, 1);
    assert_eq!(optimised.pen_up.after, 0.0);
    assert_eq!(optimised.pen_up.before, plain.pen_up.before);
    let plunges = optimised
        .program
        .moves
        .iter()
        .filter(|m| m.tool_down == Some(true) && m.feed == Feed::Rapid)
        .count();
    assert_eq!(plunges, 1);
    // One pen-down stroke of four sides, then the pen goes up where it ended (the origin).
    let cuts: Vec<[f64; 3]> = optimised
        .program
        .moves
        .iter()
        .filter(|m| !is_rapid(m))
        .map(|m| m.end.linear)
        .collect();
    assert_eq!(
        cuts,
        vec![
            [0.05, 0.0, 0.0],
            [0.05, 0.05, 0.0],
            [0.0, 0.05, 0.0],
            [0.0, 0.0, 0.0]
        ]
    );
}

#[test]
fn optimisation_reverses_strokes_and_keeps_pen_changes_in_order() {
    // Two parallel strokes both drawn left to right: the second is better drawn backwards.
    let text = "PU0,0;PD400,0;PU;PU0,40;PD400,40;PU;PU0,0;";
    let mut options = ReadOptions::default();
    options.hpgl.optimise_pen_up = true;
    let output = hpgl(text, &options);
    // As drawn: diagonal pen-up returns, (10, 0) → (0, 1) and (10, 1) → (0, 0) mm.
    assert_close(output.pen_up.before, 2.0 * 0.000101f64.sqrt(), 1e-12);
    // Reordered: 1 mm up to the second stroke's end, draw it backwards, 1 mm home.
    assert_close(output.pen_up.after, 0.002, 1e-12);
    let cuts: Vec<[f64; 3]> = output
        .program
        .moves
        .iter()
        .filter(|m| !is_rapid(m))
        .map(|m| m.end.linear)
        .collect();
    assert_eq!(cuts, vec![[0.01, 0.0, 0.0], [0.0, 0.001, 0.0]]);
    let plain = hpgl(text, &ReadOptions::default());
    assert_eq!(
        drawn_segments(&plain.program),
        drawn_segments(&output.program)
    );
    // A pen change is a barrier: the far stroke drawn with pen 1 stays first, although
    // without SP2 the near stroke would be drawn first.
    let cuts_of = |text: &str| -> Vec<[f64; 3]> {
        let output = hpgl(text, &options);
        output
            .program
            .moves
            .iter()
            .filter(|m| !is_rapid(m))
            .map(|m| m.end.linear)
            .collect()
    };
    assert_eq!(
        cuts_of("SP1;PU4000,0;PD4400,0;PU;SP2;PU0,40;PD400,40;PU;"),
        vec![[0.11, 0.0, 0.0], [0.0, 0.001, 0.0]]
    );
    assert_eq!(
        cuts_of("SP1;PU4000,0;PD4400,0;PU;PU0,40;PD400,40;PU;"),
        vec![[0.01, 0.001, 0.0], [0.11, 0.0, 0.0]]
    );
}

#[test]
fn separators_terminators_scaling_and_relative_moves() {
    // Spaces as separators, no terminators, lower case, relative plotting.
    let program = hpgl(
        "in sp1 pu 0 0 pd 400 0 pr 0,400 -400,0pu",
        &ReadOptions::default(),
    )
    .program;
    let cuts: Vec<[f64; 3]> = program
        .moves
        .iter()
        .filter(|m| !is_rapid(m))
        .map(|m| m.end.linear)
        .collect();
    assert_eq!(
        cuts,
        vec![[0.01, 0.0, 0.0], [0.01, 0.01, 0.0], [0.0, 0.01, 0.0]]
    );
    // SC maps user units onto P1..P2: with IP0,0,4000,4000 and SC0,100,0,100 a user unit
    // is 40 plotter units, i.e. 1 mm.
    let program = hpgl(
        "IP0,0,4000,4000;SC0,100,0,100;PU10,20;PD30,20;",
        &ReadOptions::default(),
    )
    .program;
    let cuts: Vec<[f64; 3]> = program
        .moves
        .iter()
        .filter(|m| !is_rapid(m))
        .map(|m| m.end.linear)
        .collect();
    assert_eq!(cuts, vec![[0.03, 0.02, 0.0]]);
}

#[test]
fn circles_and_arcs() {
    let output = hpgl(
        "PU400,400;CI200;PA800,400;PD;AA400,400,90;",
        &ReadOptions::default(),
    );
    let moves = &output.program.moves;
    // CI: pen up to (15 mm, 10 mm), down, full circle, up, back to the centre.
    let circle = moves
        .iter()
        .find(|m| matches!(m.motion, Motion::Arc { .. }))
        .unwrap();
    assert_eq!(circle.end.linear, [0.015, 0.01, 0.0]);
    assert_eq!(
        circle.motion,
        Motion::Arc {
            center: [0.01, 0.01, 0.0],
            plane: Plane::XY,
            clockwise: false,
            turns: 0
        }
    );
    let arcs: Vec<&Move> = moves
        .iter()
        .filter(|m| matches!(m.motion, Motion::Arc { .. }))
        .collect();
    assert_eq!(arcs.len(), 2);
    // AA about (10, 10) mm by +90° from (20, 10) mm ends at (10, 20) mm.
    assert_close(arcs[1].end.linear[0], 0.01, 1e-15);
    assert_close(arcs[1].end.linear[1], 0.02, 1e-15);
    assert_close(
        summarize(&output.program).cut_length,
        2.0 * std::f64::consts::PI * 0.005 + 0.5 * std::f64::consts::PI * 0.01,
        1e-12,
    );
}

// ---------------------------------------------------------------------------------------
// APT
// ---------------------------------------------------------------------------------------

#[test]
fn d_table1_decodes_with_normalised_tool_axes() {
    let program = read_program(&sample("d_table1.apt"), &ReadOptions::default()).unwrap();
    assert_eq!(program.moves.len(), 4);
    let ends: Vec<[f64; 3]> = program.moves.iter().map(|m| m.end.linear).collect();
    assert_eq!(
        ends,
        vec![
            [-0.01, -0.01, -0.01],
            [0.03, 0.06, 0.045],
            [0.04, 0.08, 0.06],
            [0.05, 0.1, 0.075]
        ]
    );
    let first = program.moves[0].tool_axis.unwrap();
    let half_root_two = std::f64::consts::FRAC_1_SQRT_2;
    assert_close(first[0], -half_root_two, 1e-15);
    assert_eq!(first[1], 0.0);
    assert_close(first[2], -half_root_two, 1e-15);
    for mv in &program.moves {
        let axis = mv.tool_axis.unwrap();
        assert_close(axis.iter().map(|c| c * c).sum::<f64>(), 1.0, 1e-15);
    }
    // (0.12, 0.3, 0.3) and its multiples all point the same way.
    let second = program.moves[1].tool_axis.unwrap();
    assert_close(second[0], 0.12 / 0.194_4f64.sqrt(), 1e-12);
    // One warning per vector, naming its line.
    let lines: Vec<u32> = program.warnings.iter().map(|w| w.span.line).collect();
    assert_eq!(lines, vec![6, 7, 8, 9]);
    assert_eq!(
        program.warnings[0].message,
        "line 6: tool-axis vector (-0.5, 0, -0.5) has length 0.707107, normalised to (-0.707107, 0.000000, -0.707107)"
    );
    // FEDRAT/100 is 100 mm/min by APT's convention, or 100 mm/s if told so.
    assert_eq!(program.moves[1].feed, Feed::PathSpeed(0.1 / 60.0));
    let mut options = ReadOptions::default();
    options.apt.feed_time_base = FeedTimeBase::PerSecond;
    let program = read_program(&sample("d_table1.apt"), &options).unwrap();
    assert_eq!(program.moves[1].feed, Feed::PathSpeed(0.1));
}

#[test]
fn apt_continuation_comments_rapid_units_and_fini() {
    let text = "PARTNO / any text, even / and ,\nUNITS/INCHES $$ inches from here\nFEDRAT/10,IPM\nRAPID\nGOTO/1,2,$\n  3\nGOTO/2, 2, 3 $$ feed again\nGODLTA/0,0,-1\nFINI\nGOTO/9,9,9\n";
    let program = parse_apt(text, "t.apt", &ReadOptions::default()).unwrap();
    assert_eq!(program.moves.len(), 3);
    let first = program.moves[0].end.linear;
    assert_eq!([first[0], first[1]], [0.0254, 0.0508]);
    assert_close(first[2], 0.0762, 1e-15);
    assert_eq!(program.moves[0].feed, Feed::Rapid);
    assert_eq!(program.moves[0].span.line, 5);
    assert_eq!(program.moves[1].feed, Feed::PathSpeed(0.254 / 60.0));
    assert_close(program.moves[2].end.linear[2], 0.0508, 1e-15);
    assert_eq!(program.moves[0].tool_axis, None);
}

// ---------------------------------------------------------------------------------------
// Files, dispatch and the inspect report
// ---------------------------------------------------------------------------------------

#[test]
fn read_program_dispatches_on_extension() {
    let directory = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let path = directory.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let gcode_path = write("a.NGC", "G0 X1");
    assert_eq!(
        read_program_detailed(&gcode_path, &ReadOptions::default())
            .unwrap()
            .format,
        ProgramFormat::Gcode
    );
    let hpgl_path = write("a.hpgl", "PU;PD40,0;PU;");
    let outcome = read_program_detailed(&hpgl_path, &ReadOptions::default()).unwrap();
    assert_eq!(outcome.format, ProgramFormat::Hpgl);
    assert!(outcome.pen_up.is_none());
    let mut optimising = ReadOptions::default();
    optimising.hpgl.optimise_pen_up = true;
    let outcome = read_program_detailed(&hpgl_path, &optimising).unwrap();
    assert_eq!(outcome.pen_up.unwrap().lifts_after, 1);
    let apt_path = write("a.cls", "RAPID\nGOTO/1,1,1");
    assert_eq!(
        read_program(&apt_path, &ReadOptions::default())
            .unwrap()
            .moves
            .len(),
        1
    );
    // Recognised by content whatever the extension.
    let gcode_txt = write("a.txt", "G0 X1");
    let outcome = read_program_detailed(&gcode_txt, &ReadOptions::default()).unwrap();
    assert_eq!(outcome.format, ProgramFormat::Gcode);
    let plot_prn = write("a.prn", "\x03IN;SP1;PU0,0;PD40,0;");
    let outcome = read_program_detailed(&plot_prn, &ReadOptions::default()).unwrap();
    assert_eq!(outcome.format, ProgramFormat::Hpgl);
    let cl_txt = write(
        "cl.txt",
        "$$ header\nTOOL PATH/2_OP-1,TOOL,EM_10\nRAPID\nGOTO/1,1,1",
    );
    let outcome = read_program_detailed(&cl_txt, &ReadOptions::default()).unwrap();
    assert_eq!(outcome.format, ProgramFormat::Apt);
    // CL data in a file named as a plot file is still CL data.
    let cl_plt = write("cl.plt", "UNITS/MM\nRAPID\nGOTO/1,1,1");
    assert_eq!(
        read_program_detailed(&cl_plt, &ReadOptions::default())
            .unwrap()
            .format,
        ProgramFormat::Apt
    );
    let unknown = write("a.txt", "hello world");
    assert_eq!(
        read_program(&unknown, &ReadOptions::default()).unwrap_err().to_string(),
        format!(
            "{}: expected a part program (G-code, HPGL or APT CL data); the content is none of them and '.txt' names none; hint: use .ngc .nc .gcode .tap (G-code), .plt .hpgl .hpg .hgl .hp .prn (HPGL) or .apt .cl .cls .clsf .ncl (APT CL data)",
            unknown.display()
        )
    );
    let missing = directory.path().join("missing.ngc");
    let message = read_program(&missing, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        message.starts_with(&format!(
            "{}: could not read the program: ",
            missing.display()
        )),
        "{message}"
    );
}

#[test]
fn inspect_report_lists_moves_and_totals() {
    let options = ReadOptions {
        feed_rule: FeedRule::EuclideanAllAxes,
        ..ReadOptions::default()
    };
    let report = inspect(
        &sample("d_table2.ngc"),
        &options,
        &InspectOptions::default(),
    )
    .unwrap()
    .0;
    assert!(
        report.contains("moves: 6 (5 cutting, 1 rapid/pen-up, 0 dwell)"),
        "{report}"
    );
    assert!(
        report.contains("program time at programmed feed: 1.938 s"),
        "{report}"
    );
    assert!(report.contains("      2         6:1  line      20.0000    10.0000    30.0000   10.0000    0.0000   50.0000     150.000      0.422"), "{report}");
    // Long programs are summarised.
    let text: String = (0..1000).map(|i| format!("G1 X{i} F100\n")).collect();
    let program = gcode(&text);
    let report = inspect_report(&program, None, &InspectOptions { list_limit: 10 });
    assert!(report.contains("… 990 moves not listed"), "{report}");
    assert!(report.contains("cut length: 999.000 mm"), "{report}");
    assert!(
        report.contains("program time at programmed feed: 599.400 s"),
        "{report}"
    );
    // HPGL shows pen-up travel.
    let mut options = ReadOptions::default();
    options.hpgl.optimise_pen_up = true;
    let report = inspect(
        &sample("b_line_5mm.plt"),
        &options,
        &InspectOptions::default(),
    )
    .unwrap()
    .0;
    assert!(
        report.contains(
            "pen-up travel: 5.000 mm with 1 lifts as drawn, 5.000 mm with 1 lifts after reordering"
        ),
        "{report}"
    );
}

// ---------------------------------------------------------------------------------------
// Bad inputs and their exact messages
// ---------------------------------------------------------------------------------------

#[derive(Clone, Copy)]
enum Language {
    Gcode,
    Hpgl,
    Apt,
}

fn first_error(language: Language, text: &str, options: &ReadOptions) -> String {
    let result = match language {
        Language::Gcode => parse_gcode(text, "bad.ngc", options),
        Language::Hpgl => parse_hpgl(text, "bad.plt", options),
        Language::Apt => parse_apt(text, "bad.apt", options),
    };
    match result {
        Ok(_) => format!("<no error for {text:?}>"),
        Err(errors) => errors.errors[0].to_string(),
    }
}

#[test]
fn bad_inputs_give_exact_messages() {
    use Language::{Apt, Gcode, Hpgl};
    let table: &[(Language, &str, &str)] = &[
        (Gcode, "G1 XQ F100", "bad.ngc:1:5: expected a number after 'X', found 'Q'"),
        (Gcode, "G1 X", "bad.ngc:1:5: expected a number after 'X', found end of line"),
        (Gcode, "G0 G1 X1", "bad.ngc:1:4: expected one G code of the motion group per block, but G0 and G1 are both in it, found 'G1'; hint: LinuxCNC refuses two codes of one modal group in a block; split the block"),
        (Gcode, "G20 G21", "bad.ngc:1:5: expected one G code of the units group per block, but G20 and G21 are both in it, found 'G21'; hint: LinuxCNC refuses two codes of one modal group in a block; split the block"),
        (Gcode, "M3 M5", "bad.ngc:1:4: expected one M code of the spindle group per block, but M3 and M5 are both in it, found 'M5'; hint: LinuxCNC refuses two codes of one modal group in a block; split the block"),
        (Gcode, "G0 X1 X2", "bad.ngc:1:7: expected one X word per block, but X2 is the second, found 'X2'; hint: the first is 'X1'"),
        (Gcode, "G12 X1", "bad.ngc:1:1: expected a G code LinuxCNC knows; G12 is not one, found 'G12'"),
        (Gcode, "F100 G81 X1 Y1 Z-1", "bad.ngc:1:6: expected an R word (retract plane) with G81, found 'G81'"),
        (Gcode, "M99", "bad.ngc:1:1: expected a supported M code; M99 is not supported, found 'M99'; hint: Fanuc-style subprograms (M98/M99) are not supported; use o<name> sub / call"),
        (Gcode, "M97", "bad.ngc:1:1: expected an M code LinuxCNC knows; M97 is not one, found 'M97'"),
        (Gcode, "X1", "bad.ngc:1:1: expected a motion mode (G0, G1, G2, G3 or a canned cycle) for the axis words, found 'X1'; hint: no motion mode is active (at program start or after G80); add G0 or G1"),
        (Gcode, "G1 X1", "bad.ngc:1:1: expected a non-zero feed rate (F word) before a G1/G2/G3 move, found 'G1 X1'; hint: add e.g. F300 (mm per minute in G94)"),
        (Gcode, "G93 G1 X1", "bad.ngc:1:1: expected an F word on every G1/G2/G3 block in inverse-time mode (G93), found 'G93 G1 X1'; hint: in G93 the F word is 1 / (move time in minutes) and is not modal"),
        (Gcode, "G0 X1 (unclosed", "bad.ngc:1:7: expected ')' to close the comment, found end of line; hint: comments in parentheses end on the line they start"),
        (Gcode, "G0 X1 (a (b) c)", "bad.ngc:1:10: expected ')' before another '(' (comments do not nest), found '('"),
        (Gcode, "G0 X#<depth>", "bad.ngc:1:5: expected a defined parameter; #<depth> is not defined, found '#<depth>'; hint: assign it first, e.g. #<name> = 0 (names without '_' are local to their subroutine)"),
        (Gcode, "G0 U1", "bad.ngc:1:4: expected an axis of X Y Z A B C; U V W axes are not supported, found 'U'"),
        (Gcode, "G0 X1 N5", "bad.ngc:1:7: expected the line number (N word) at the start of the block, found 'N'"),
        (Gcode, "G0 X1 E5", "bad.ngc:1:7: expected a word letter cncsim supports; E words (G76 threading, M66 inputs) are not supported, found 'E'"),
        (Gcode, "G0 X1 \u{e9}", "bad.ngc:1:7: expected a G-code word, comment or blank, found '\u{e9}'"),
        (Gcode, "G1 X1 I2 F100", "bad.ngc:1:7: expected I to come with an arc (G2/G3), G87 or G10, found 'I2'; hint: no code in this block uses the I word"),
        (Gcode, "G4", "bad.ngc:1:1: expected a P word (dwell time in seconds) with G4, found 'G4'; hint: write e.g. G4 P0.5 for half a second"),
        (Gcode, "G2 X10 Y0 F100", "bad.ngc:1:1: expected an R word or centre offsets I J on an arc, found 'G2 X10 Y0 F100'"),
        (Gcode, "G2 X10 Y0 I5 R5 F100", "bad.ngc:1:14: expected either R or centre offsets on an arc, not both, found 'G2 X10 Y0 I5 R5 F100'"),
        (Gcode, "G2 X10 Y0 K5 F100", "bad.ngc:1:11: expected centre offsets I and J for an arc in the XY (G17) plane, found 'K5'"),
        (Gcode, "G2 X0 Y0 R5 F100", "bad.ngc:1:1: expected an R-form arc to end somewhere other than its start, found 'G2 X0 Y0 R5 F100'; hint: a full circle needs the centre form (I J K)"),
        (Gcode, "G2 X10 Y0 R4 F100", "bad.ngc:1:11: expected an arc radius of at least 5.0000 mm (half the distance from start (X0.0000,Y0.0000) to end (X10.0000,Y0.0000)), found 'R4'"),
        (Gcode, "G2 X10.5 Y0 I5 J0 F100", "bad.ngc:1:1: arc end point is off the circle by 0.5000 mm: radius to end differs from radius to start (start=(X0.0000,Y0.0000) center=(X5.0000,Y0.0000) end=(X10.5000,Y0.0000) r1=5.0000 r2=5.5000, rel_err=9.0909%); expected at most 0.0283 mm (or 2.8284 mm within 0.1% of the radius), found 'G2 X10.5 Y0 I5 J0 F100'; hint: check the end point and the centre offsets (G91.1: I J K are relative to the start point)"),
        (Gcode, "G2 X0 Y0 I0 J0 F100", "bad.ngc:1:1: expected an arc centre away from its start and end points (zero-radius arc: start=(X0.0000,Y0.0000) center=(X0.0000,Y0.0000) end=(X0.0000,Y0.0000) r1=0.0000 r2=0.0000), found 'G2 X0 Y0 I0 J0 F100'"),
        (Gcode, "G2 X1 Y1 I1 P1.5 F100", "bad.ngc:1:13: expected a whole number of turns of 1 or more after P on an arc, found 'P1.5'"),
        (Gcode, "G1 X1 F-5", "bad.ngc:1:7: expected a feed rate of zero or more, found 'F-5'"),
        (Gcode, "%\nG0 X1", "bad.ngc:3:1: expected a closing '%' line (the program opened with '%'), found end of file; hint: end the program with M2/M30 or a '%' line"),
        (Gcode, "O100 sub", "bad.ngc:1:1: expected 'o100 endsub' to end the subroutine defined here, found end of file"),
        (Gcode, "G0 X[1 + ]", "bad.ngc:1:10: expected a number, parameter or expression, found ']'"),
        (Gcode, "#1 = [1 / 0]", "bad.ngc:1:9: expected a non-zero divisor, found '1 / 0'"),
        (Gcode, "G0 X[SQRT[-1]]", "bad.ngc:1:6: expected a SQRT argument of zero or more, found 'SQRT[-1]'"),
        (Gcode, "G0 X[[0 - 2] ** 0.5]", "bad.ngc:1:14: expected a whole-number power of a negative number, found '-2 ** 0.5'"),
        (Gcode, "G0 X[1 FOO 2]", "bad.ngc:1:8: expected ']' or an operator (+ - * / ** MOD AND OR XOR EQ NE GT GE LT LE), found 'F'"),
        (Gcode, "G0 X#6000", "bad.ngc:1:5: expected a parameter number from 1 to 5601, not 6000, found '#6000'"),
        (Gcode, "#<a = 1", "bad.ngc:1:2: expected '>' to close the parameter name, found '<a = 1'"),
        (Gcode, "o1 endwhile", "bad.ngc:1:1: expected an open 'o1 while' before this 'endwhile', found 'o1 endwhile'"),
        (Gcode, "o<missing> call", "bad.ngc:1:1: expected a definition of subroutine o<missing> (o<missing> sub … o<missing> endsub) in this file, found 'o<missing> call'; hint: cncsim reads one file; LinuxCNC would also look for a file of that name in its subroutine path"),
        (Gcode, "o1 if", "bad.ngc:1:1: expected one bracketed condition after 'if', e.g. o1 if [#1 LT 3], found 'o1 if'"),
        (Gcode, "o1 sub\no2 sub\no2 endsub\no1 endsub", "bad.ngc:1:1: expected 'o1 endsub' before another subroutine definition (line 2); definitions do not nest, found 'o2 sub'"),
        (Gcode, "G43 H5", "bad.ngc:1:5: expected a tool of the tool table; tool 5 is not in it, found 'H5'; hint: the tool table is empty: name a LinuxCNC tool table with the scenario's [program] tool_table (or inspect --tool-table)"),
        (Gcode, "T3 M6", "bad.ngc:1:1: expected a tool of the tool table; tool 3 is not in it, found 'T3'; hint: the tool table is empty: name a LinuxCNC tool table with the scenario's [program] tool_table (or inspect --tool-table)"),
        (Gcode, "G80 X1", "bad.ngc:1:5: expected no axis words with G80, found 'X1'; hint: G80 cancels the motion mode; put the move in its own block"),
        (Gcode, "G10 L2 P10 X1", "bad.ngc:1:8: expected P0 to P9 with G10 L2/L20 (0 = the active system, 1 = G54 … 9 = G59.3), found 'P10'"),
        (Gcode, "F100 G83 X1 Y1 Z-5 R1", "bad.ngc:1:6: expected a Q word (peck depth) with G83, found 'G83'"),
        (Gcode, "G92", "bad.ngc:1:1: expected axis words with G92, found 'G92'"),
        (Gcode, "G53 G91 G0 X1", "bad.ngc:1:1: expected absolute distance mode (G90) with G53, found 'G53'"),
        (Gcode, "G41.1 D2 G1 X0.5 F100", "bad.ngc:1:1: expected a cutter compensation entry move longer than the tool radius (1.0000); it is 0.5000, found 'G41.1 D2 G1 X0.5 F100'"),
        (Gcode, "(ABORT, tool broken)", "bad.ngc:1:8: expected no (ABORT,…) comment: the program aborts here (tool broken), found ' tool broken'"),
        (Gcode, "G0 X1\n%", "bad.ngc:2:1: expected '%' only on the first line, or to close a program that opened with '%', found '%'"),
        (Hpgl, "IN;PA10;", "bad.plt:1:4: expected x,y pairs after PA: an even number of coordinates, not 1 (byte offset 3), found 'PA10'; hint: the file may be damaged; the lenient option drops the dangling coordinate"),
        (Hpgl, "IN;PA10,20,30;", "bad.plt:1:4: expected x,y pairs after PA: an even number of coordinates, not 3 (byte offset 3), found 'PA10,20,30'; hint: the file may be damaged; the lenient option drops the dangling coordinate"),
        (Hpgl, "IN;PA10,x;", "bad.plt:1:9: expected a number after ',' in the parameters of PA, found 'x'"),
        // Empty parameters and unknown mnemonics are passed over as plotters do; their
        // refusals under --strict are in tests/hpgl_plot_files.rs.
        (Hpgl, "IN;PA10*20;", "bad.plt:1:8: expected ',', ';' or a number in the parameters of PA, found '*'"),
        (Hpgl, "IN;\n  5;", "bad.plt:2:3: expected an HPGL command (two letters) or ';', found '5'"),
        (Hpgl, "P", "bad.plt:1:1: expected a two-letter HPGL command, found 'P'"),
        (Hpgl, "\x1b.(;\x1b\x01IN;", "bad.plt:1:5: expected '.' (HP device control), '%' (PCL language switch) or a PCL command after ESC, found '\\x1b\\x01'"),
        (Hpgl, "\x1b.!", "bad.plt:1:1: expected a known HP device-control sequence (ESC . followed by ( ) @ A B E H I J K L M N O P Q R S T U Y Z), found '\\x1b.!'"),
        (Hpgl, "SC0,0,0,10;", "bad.plt:1:1: expected SC limits with xmin ≠ xmax and ymin ≠ ymax, not 0,0,0,10, found 'SC0,0,0,10'"),
        (Hpgl, "VS0;", "bad.plt:1:1: expected a positive pen speed (cm/s) after VS, not 0, found 'VS0'"),
        (Hpgl, "CI;", "bad.plt:1:1: expected 1 or 2 parameters after CI, not 0, found 'CI'"),
        (Apt, "GOTO/1,2", "bad.apt:1:1: expected 3 or 6 numbers after GOTO/, not 2, found 'GOTO/1,2'"),
        (Apt, "FEDRAT/100\nGOTO/1,2,x", "bad.apt:2:10: expected a number in GOTO, found 'x'"),
        (Apt, "GOTO/1,2,3", "bad.apt:1:1: expected a FEDRAT (or RAPID) before the first GOTO, found 'GOTO/1,2,3'; hint: add e.g. FEDRAT/100 before the motion records, or give the feed (feed_mm_s in [program], inspect --feed)"),
        (Apt, "FEDRAT/100\nGOTO/1,2,3,0,0,0", "bad.apt:2:12: expected a non-zero tool-axis vector, found '0,0,0'; hint: the tool-axis vector (i,j,k) must point along the tool"),
        (Apt, "UNITS/FURLONGS", "bad.apt:1:7: expected MM or INCHES after UNITS/, found 'FURLONGS'"),
        (Apt, "FEDRAT/100,IPR", "bad.apt:1:12: expected a feed per minute; feed per revolution is not supported, found 'IPR'; hint: post the feed per minute"),
        (Apt, "GOTO 1,2,3", "bad.apt:1:6: expected '/' or the end of the record after GOTO, found '1'"),
        (Apt, "GOTO/1,,3", "bad.apt:1:8: expected a number or word in the parameters of GOTO, found ','"),
        (Apt, "GOTO/1,,3", "bad.apt:1:8: expected a number or word in the parameters of GOTO, found ','"),
        (Apt, "FEDRAT/1 A", "bad.apt:1:10: expected ',' between the parameters of FEDRAT, found 'A'"),
        (Apt, "123/4", "bad.apt:1:1: expected an APT statement word (GOTO, FEDRAT, …), found '123'"),
    ];
    let options = ReadOptions::default();
    let mut failures = Vec::new();
    for (language, input, expected) in table {
        let actual = first_error(*language, input, &options);
        if actual != *expected {
            failures.push(format!(
                "input {input:?}\n  expected: {expected}\n  actual:   {actual}"
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} messages differ:\n{}",
        failures.len(),
        table.len(),
        failures.join("\n")
    );
}

#[test]
fn several_errors_of_one_file_are_reported_together_in_every_language() {
    let hpgl_errors =
        parse_hpgl("PA1;PA1,2;UC;PA3;", "x.plt", &ReadOptions::default()).unwrap_err();
    assert_eq!(hpgl_errors.errors.len(), 3);
    let apt_errors = parse_apt(
        "GOTO/1\nRAPID\nGOTO/1,2,3\nGOTO/x",
        "x.apt",
        &ReadOptions::default(),
    )
    .unwrap_err();
    let lines: Vec<u32> = apt_errors
        .errors
        .iter()
        .map(|e| e.span.unwrap().line)
        .collect();
    assert_eq!(lines, vec![1, 4]);
}

#[test]
fn regression_inputs_found_by_fuzzing_do_not_panic() {
    // Inputs that once crashed or hung a reader (kept as regression tests).
    let inputs: &[&[u8]] = &[
        b"",
        b"\xff\xfe",
        b"G2 X1e400 I1",
        b"G0 X99999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999999",
        b"G2 X0.0000000001 Y0 R0.00000000005 F1",
        b"G3 X0 Y0 I1 P4294967296 F1",
        b"\x1b.",
        b"\x1b",
        b"PA-",
        b"AA0,0,1e308",
        b"AA0,0,99999999999999999999999999999999999999999;",
        b"PU1,1;AR0,0,360;PD;AR1,1,720;",
        b"GOTO/1,2,3,$",
        b"$$",
        b"$",
    ];
    let options = ReadOptions::default();
    for input in inputs {
        let _ = parse_gcode(input, "f.ngc", &options);
        let _ = parse_hpgl(input, "f.plt", &options);
        let _ = parse_apt(input, "f.apt", &options);
    }
}

#[test]
fn optimising_a_large_plot_is_fast_and_never_worse() {
    // 20 000 short strokes scattered by a simple generator, far from the origin.
    let mut text = String::from("IN;SP1;");
    let mut seed = 12345u64;
    let mut next = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 33) % 100_000
    };
    for _ in 0..20_000 {
        let (x, y) = (next() + 1_000_000, next());
        text.push_str(&format!(
            "PU{x},{y};PD{},{};",
            x + next() % 400,
            y + next() % 400
        ));
    }
    text.push_str("PU;PA0,0;");
    let mut options = ReadOptions::default();
    options.hpgl.optimise_pen_up = true;
    let started = std::time::Instant::now();
    let output = hpgl(&text, &options);
    assert!(
        started.elapsed().as_secs_f64() < 5.0,
        "took {:?}",
        started.elapsed()
    );
    assert!(
        output.pen_up.after < 0.5 * output.pen_up.before,
        "{:?}",
        output.pen_up
    );
    let plain = hpgl(&text, &ReadOptions::default());
    assert_eq!(
        drawn_segments(&plain.program),
        drawn_segments(&output.program)
    );
}

#[test]
fn reversed_arc_strokes_draw_the_same_arcs() {
    // Two arc strokes; the second is nearer when drawn backwards.
    let text = "PU0,0;PD;AA0,400,90;PU;PU4000,0;PD;AR-400,0,-90;PU;";
    let mut options = ReadOptions::default();
    options.hpgl.optimise_pen_up = true;
    let optimised = hpgl(text, &options);
    let plain = hpgl(text, &ReadOptions::default());
    assert!(optimised.pen_up.after < optimised.pen_up.before);
    let arcs = |program: &Program| -> Vec<(Motion, [f64; 3])> {
        program
            .moves
            .iter()
            .filter(|m| matches!(m.motion, Motion::Arc { .. }))
            .map(|m| (m.motion, m.end.linear))
            .collect()
    };
    let (plain_arcs, optimised_arcs) = (arcs(&plain.program), arcs(&optimised.program));
    assert_eq!(plain_arcs.len(), 2);
    assert_close(
        summarize(&optimised.program).cut_length,
        summarize(&plain.program).cut_length,
        1e-15,
    );
    // Some arc was reversed: same centre, opposite direction.
    let reversed = optimised_arcs.iter().any(|(motion, _)| {
        plain_arcs.iter().any(|(plain, _)| match (motion, plain) {
            (
                Motion::Arc {
                    center: a,
                    clockwise: ca,
                    ..
                },
                Motion::Arc {
                    center: b,
                    clockwise: cb,
                    ..
                },
            ) => a == b && ca != cb,
            _ => false,
        })
    });
    assert!(reversed, "{optimised_arcs:?}");
}

#[test]
fn line_index_columns_count_characters_and_stay_right_when_looked_up_out_of_order() {
    let text = "ab\u{e9}c\nxyz".as_bytes();
    let index = super::source::LineIndex::new(text);
    // 'c' is byte 4 but the fourth character.
    assert_eq!((index.span(4).line, index.span(4).column), (1, 4));
    assert_eq!(index.span(1).column, 2);
    assert_eq!(index.span(4).column, 4);
    let y = index.span(7);
    assert_eq!((y.line, y.column, y.byte_offset), (2, 2, 7));
    assert_eq!(index.span(100).byte_offset, text.len() as u32);
}

#[test]
fn endless_loops_stop_at_the_block_and_move_limits() {
    let mut options = ReadOptions::default();
    options.gcode.max_blocks = 10_000;
    let errors = errors_of(parse_gcode(
        "G0 X0\no1 while [1]\no1 endwhile",
        "t.ngc",
        &options,
    ));
    assert_eq!(errors, vec!["t.ngc:3:1: expected the program to end within 10000 executed blocks; it runs on (an endless loop?), found 'o1 endwhile'; hint: check the loop conditions; the limit is GcodeOptions::max_blocks"]);
    options.gcode.max_moves = 1000;
    let errors = errors_of(parse_gcode(
        "o1 while [1]\nG0 X1\nG0 X0\no1 endwhile",
        "t.ngc",
        &options,
    ));
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(
        errors[0].starts_with("t.ngc:2:1: expected at most 1000 moves from one program"),
        "{errors:?}"
    );
}

#[test]
fn full_circle_from_centre_offsets_alone_and_g80_with_g0_as_linuxcnc() {
    // `G2 I20 J0`: no axis words, a full circle about (20, 0) back to the start.
    let program = gcode("G0 X0 Y0\nG2 I20 J0 F100\nG80 G0 X5\nG0 G80 Y5");
    assert_eq!(program.moves.len(), 4);
    match program.moves[1].motion {
        Motion::Arc {
            center,
            clockwise: true,
            turns: 0,
            ..
        } => assert_eq!(center[..2], [0.02, 0.0]),
        other => panic!("{other:?}"),
    }
    assert_eq!(program.moves[1].end.linear, [0.0, 0.0, 0.0]);
    assert_close(
        summarize(&program).cut_length,
        std::f64::consts::TAU * 0.02,
        1e-15,
    );
    // G80 gives way to a motion code in the same block, in either order.
    assert_eq!(program.moves[2].end.linear[0], 0.005);
    assert_eq!(program.moves[3].end.linear[1], 0.005);
}

#[test]
fn offsets_tools_and_subroutines_reach_the_machine_position() {
    let mut options = ReadOptions::default();
    options.gcode.tools = vec![ToolSpec {
        number: 1,
        offset: Position {
            linear: [0.0, 0.0, 0.05],
            rotary: [0.0; 3],
        },
        diameter: 0.006,
    }];
    let program = gcode_with(
        "o<hole> sub\nG0 X#1 Y#2\no<hole> endsub\nG10 L2 P1 X100 Y50\nT1 M6 G43 H1\nG0 Z10\no<hole> call [1] [2]",
        &options,
    );
    // Machine position = program position + G54 origin + tool length; a new origin does not
    // move the tool, so X and Y stay where they were until programmed.
    assert_eq!(program.moves[0].end.linear, [0.0, 0.0, 0.06]);
    assert_eq!(program.moves[1].end.linear, [0.101, 0.052, 0.06]);
}

/// LinuxCNC's G64 P- Q-: the blend tolerance and the naive-CAM tolerance of the moves that
/// follow, until the next G61/G64. As in LinuxCNC, a G64 with P and no Q takes Q = P, and Q0
/// gives none.
#[test]
fn a_programs_g64_q_is_carried_with_each_move() {
    let program = gcode(
        "G64 P0.05 Q0.03\nG1 X1 F60\nX2\nG64 P0.05\nG1 X3\nG20 G64 Q0.001\nX4\nG21 G64 P0.05 Q0 X5\nG61 X6",
    );
    // (P, Q) of each move, in m; None for an exact stop.
    let blends: Vec<Option<(Option<f64>, Option<f64>)>> = program
        .moves
        .iter()
        .map(|m| match m.blend {
            Blend::Continuous {
                tolerance,
                naive_cam,
            } => Some((tolerance, naive_cam)),
            Blend::ExactStop => None,
        })
        .collect();
    let close = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) => (a - b).abs() < 1e-15,
        (a, b) => a == b,
    };
    let expected = [
        Some((Some(5e-5), Some(3e-5))),
        Some((Some(5e-5), Some(3e-5))),
        Some((Some(5e-5), Some(5e-5))),
        Some((None, Some(0.001 * 0.0254))),
        Some((Some(5e-5), None)),
        None,
    ];
    assert_eq!(blends.len(), expected.len(), "{blends:?}");
    for (found, wanted) in blends.iter().zip(&expected) {
        let same = match (found, wanted) {
            (Some((p, q)), Some((wp, wq))) => close(*p, *wp) && close(*q, *wq),
            (found, wanted) => found == wanted,
        };
        assert!(same, "{blends:?}");
    }
    assert!(!program.warnings.iter().any(|w| w.message.contains("G64")));
    let err = crate::program::parse_gcode(
        "G64 P0.05 Q-1",
        "bad.ngc",
        &crate::program::ReadOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("G64 Q tolerance"), "{err}");
}
