//! HPGL as real plot files are: what is drawn, what is skipped with a warning, what is an
//! error. (Geometry against independent readers: `hpgl_oracles.rs`.)

use cncsim::program::{parse_hpgl, Motion, Program, ReadOptions};

const UNITS_PER_METRE: f64 = 40_000.0;

fn hpgl_with(text: &[u8], options: &ReadOptions) -> Program {
    parse_hpgl(text, "t.plt", options).unwrap_or_else(|e| panic!("{e}"))
}

fn hpgl(text: &[u8]) -> Program {
    hpgl_with(text, &ReadOptions::default())
}

fn first_error(text: &[u8], options: &ReadOptions) -> String {
    match parse_hpgl(text, "bad.plt", options) {
        Ok(_) => format!("<no error for {:?}>", String::from_utf8_lossy(text)),
        Err(errors) => errors.errors[0].to_string(),
    }
}

/// Pen-down segments in plotter units (arcs as their end points).
fn drawn(program: &Program) -> Vec<[[f64; 2]; 2]> {
    let mut segments = Vec::new();
    let mut from = program.start.linear;
    for mv in &program.moves {
        let to = mv.end.linear;
        if mv.tool_down == Some(true) && from[2] == to[2] && (from[0], from[1]) != (to[0], to[1]) {
            segments.push([
                [from[0] * UNITS_PER_METRE, from[1] * UNITS_PER_METRE],
                [to[0] * UNITS_PER_METRE, to[1] * UNITS_PER_METRE],
            ]);
        }
        from = to;
    }
    segments
}

fn close(a: [f64; 2], b: [f64; 2]) -> bool {
    (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6
}

#[test]
fn a_comma_before_the_terminator_is_allowed() {
    let program = hpgl(b"IN;PA100,100;PD200,100,200,200,;PU;");
    assert_eq!(drawn(&program).len(), 2);
    assert_eq!(
        first_error(b"PD1,2,,;", &ReadOptions::default()),
        "bad.plt:1:7: expected a number after ',' in the parameters of PD, found ','"
    );
}

#[test]
fn commands_that_do_not_draw_warn_once_per_kind_and_strict_refuses_them() {
    let text =
        b"IN;PS1000,1000;CO\"made by hand\";PW0.35;PT0.3;NP8;PU0,0;PD100,0;PU;EC;PG1;EC1;NP4;";
    let program = hpgl(text);
    let messages: Vec<&str> = program
        .warnings
        .iter()
        .map(|w| w.message.as_str())
        .collect();
    assert_eq!(
        messages,
        [
            "CO (comment) is not a pen move and was skipped; further ones without a warning",
            "NP (number of pens) is not a pen move and was skipped; further ones without a warning",
            "EC (enable cutter) is not a pen move and was skipped; further ones without a warning",
            "PG (advance page) is not a pen move and was skipped; further ones without a warning",
        ]
    );
    assert_eq!(drawn(&program).len(), 1);
    let mut strict = ReadOptions::default();
    strict.hpgl.strict = true;
    assert_eq!(
        first_error(text, &strict),
        "bad.plt:1:16: expected a command that draws; CO (comment) is not a pen move (refused with --strict), found 'CO\"made by hand\";'"
    );
}

#[test]
fn pcl_and_pjl_around_an_hpgl2_plot() {
    let mut job = Vec::new();
    job.extend_from_slice(
        b"\x1b%-12345X@PJL JOB\r\n@PJL ENTER LANGUAGE=PCL\r\n\x1bE\x1b&l1O\x1b*v6W",
    );
    job.extend_from_slice(&[0, 3, 0, 8, 8, 8]); // binary colour set-up data
    job.extend_from_slice(
        b"\x1b%-1BBPIN;SP1;PU0,0;PD400,0;PU;\x1b%0A\x1bE\x1b%-12345X@PJL EOJ\r\n\x1b%-12345X",
    );
    let program = hpgl(&job);
    assert_eq!(drawn(&program), vec![[[0.0, 0.0], [400.0, 0.0]]]);
    assert_eq!(program.warnings.len(), 2, "{:?}", program.warnings);
    // A raster image cannot be drawn with a pen.
    assert_eq!(
        first_error(b"\x1bE\x1b*b3WAAA\x1b%1BIN;", &ReadOptions::default()),
        "bad.plt:1:3: expected PCL control or HP-GL/2 vectors; PCL raster graphics are an image, not pen moves, found '\\x1b*b3WAAA'; hint: re-plot the drawing as vectors (HP-GL/2) without raster images"
    );
    assert_eq!(
        first_error(b"\x1bEHello\x1b%1BIN;", &ReadOptions::default()),
        "bad.plt:1:3: expected PCL commands or an HP-GL/2 plot (ESC%1B) in the PCL part of the file; PCL text is printed, not plotted, found 'H'; hint: cncsim draws the HP-GL/2 vectors of a plot file; re-plot without text pages"
    );
    assert_eq!(
        first_error(b"\x1b*b99W12", &ReadOptions::default()),
        "bad.plt:1:1: expected as many data bytes as the PCL command announces, found the end of the file, found '\\x1b*b99W12'"
    );
}

#[test]
fn drawing_after_a_page_advance_or_outside_the_window_is_refused() {
    assert_eq!(
        first_error(b"IN;PU0,0;PD10,0;PG;PD20,0;", &ReadOptions::default()),
        "bad.plt:1:20: expected one page; this draws after the page advance (PG) at line 1 column 17, found 'PD20,0'; hint: plot each page to its own file"
    );
    assert!(parse_hpgl(
        b"IN;IW0,0,100,100;PU10,10;PD90,90;",
        "t.plt",
        &ReadOptions::default()
    )
    .is_ok());
    assert_eq!(
        first_error(b"IN;IW0,0,100,100;PU10,10;PD90,90,150,90;", &ReadOptions::default()),
        "bad.plt:1:26: expected drawing inside the input window (IW 0,0,100,100 plotter units); clipping at the window is not supported, found 'PD90,90,150,90'; hint: re-plot without an input window, or keep the drawing inside it"
    );
    // An arc bulging out of the window is caught too, though its ends are inside.
    assert!(parse_hpgl(
        b"IN;IW0,0,100,100;PU95,75;PD;AA50,50,-58;",
        "t.plt",
        &ReadOptions::default()
    )
    .is_err());
}

#[test]
fn circles_stay_circles_under_equal_units_and_become_ellipses_under_unequal_ones() {
    // Equal user units: one arc move.
    let program = hpgl(b"IN;IP0,0,1000,1000;SC0,10,0,10;PA5,5;CI2;");
    assert_eq!(
        program
            .moves
            .iter()
            .filter(|m| matches!(m.motion, Motion::Arc { .. }))
            .count(),
        1
    );
    // X units twice Y units: chords at 5° on an ellipse with semi-axes 200 and 100.
    let program = hpgl(b"IN;IP0,0,1000,500;SC0,10,0,10;PA5,5;CI2;");
    let segments = drawn(&program);
    assert_eq!(segments.len(), 72);
    for [point, _] in segments {
        let (x, y) = ((point[0] - 500.0) / 200.0, (point[1] - 250.0) / 100.0);
        assert!((x.hypot(y) - 1.0).abs() < 1e-9, "{point:?}");
    }
    // A chord angle of 10° halves the chords; CT1 reads it as a deviation instead.
    let program = hpgl(b"IN;IP0,0,1000,500;SC0,10,0,10;PA5,5;CI2,10;");
    assert_eq!(drawn(&program).len(), 36);
    let program = hpgl(b"IN;IP0,0,1000,500;SC0,10,0,10;PA5,5;CT1;CI2,0.1;");
    assert_eq!(drawn(&program).len(), 10); // 2·acos(1 − 0.1/2) = 36.4° per chord
}

#[test]
fn a_mirrored_scale_turns_arcs_the_other_way() {
    // User Y runs down (IP with P2 below P1): a counter-clockwise user arc is clockwise on
    // the table.
    let program = hpgl(b"IN;IP0,1000,1000,0;SC0,10,0,10;PA5,5;PD;AR1,0,90;");
    let arc = program
        .moves
        .iter()
        .find(|m| matches!(m.motion, Motion::Arc { .. }))
        .unwrap();
    assert!(matches!(
        arc.motion,
        Motion::Arc {
            clockwise: true,
            ..
        }
    ));
    assert!(close(
        [
            arc.end.linear[0] * UNITS_PER_METRE,
            arc.end.linear[1] * UNITS_PER_METRE
        ],
        [600.0, 600.0]
    ));
}

#[test]
fn fills_are_outlines_plus_the_hatch_the_fill_type_asks_for() {
    // RA with solid fill at pen thickness 0.5 mm (20 plotter units): outline plus lines
    // 20 units apart inside the rectangle.
    let program = hpgl(b"IN;PT0.5;PU0,0;RA200,100;");
    let segments = drawn(&program);
    let outline = 4;
    assert_eq!(segments.len(), outline + 5); // y = 10, 30, 50, 70, 90
    for [a, b] in &segments[outline..] {
        assert_eq!(a[1], b[1]);
        assert!((0.0..=200.0).contains(&a[0]) && (0.0..=200.0).contains(&b[0]));
    }
    // Bidirectional: alternate lines run back.
    assert!(segments[outline][0][0] < segments[outline][1][0]);
    assert!(segments[outline + 1][0][0] > segments[outline + 1][1][0]);
    // Without hatching, the outline alone.
    let mut options = ReadOptions::default();
    options.hpgl.hatch_fills = false;
    assert_eq!(
        drawn(&hpgl_with(b"IN;PT0.5;PU0,0;RA200,100;", &options)).len(),
        4
    );
    // Cross-hatch at 45° and 135°, 30 units apart, inside a wedge.
    let program = hpgl(b"IN;PU500,500;FT4,30,45;WG100,0,90;");
    for [a, b] in drawn(&program) {
        for p in [a, b] {
            let (x, y) = (p[0] - 500.0, p[1] - 500.0);
            assert!(
                x >= -1e-9 && y >= -1e-9 && x.hypot(y) <= 100.0 + 1e-6,
                "{p:?}"
            );
        }
    }
    // The pen ends where it started.
    let last = program.moves.last().unwrap();
    assert!(close(
        [
            last.end.linear[0] * UNITS_PER_METRE,
            last.end.linear[1] * UNITS_PER_METRE
        ],
        [500.0, 500.0]
    ));
    // A fill that would take more lines than allowed is refused.
    let mut options = ReadOptions::default();
    options.hpgl.max_fill_lines = 3;
    assert_eq!(
        first_error(b"IN;PT0.5;PU0,0;RA200,100;", &options),
        "bad.plt:1:16: expected at most 3 fill lines in a plot; this fill needs 5 more, found 'RA200,100'; hint: draw fills as outlines (--no-hatch), or widen the fill spacing (FT, PT, PW)"
    );
    assert!(first_error(b"FT11;", &ReadOptions::default()).contains("raster fill patterns"));
}

#[test]
fn polygon_mode_keeps_holes_and_edges_only_what_the_pen_drew() {
    let text = b"IN;PU0,0;PM0;PD100,0,100,100,0,100,0,0;PM1;PU30,30;PD70,30,70,70,30,70,30,30;PM2;FT3,10;FP;";
    let program = hpgl(text);
    let segments = drawn(&program);
    // Outline: 8 edges; hatch lines at y = 5 … 95 with the hole cut out between 30 and 70.
    let hatch = &segments[8..];
    let through_hole = hatch.iter().filter(|s| s[0][1] == 55.0).count();
    assert_eq!(through_hole, 2);
    assert_eq!(hatch.iter().filter(|s| s[0][1] == 15.0).count(), 1);
    // EP draws the pen-down edges and the closing edge, not the pen-up move.
    let program = hpgl(b"IN;PU0,0;PM0;PD100,0,100,100;PU0,100;PM2;EP;");
    let segments = drawn(&program);
    assert_eq!(segments.len(), 3);
    assert!(!segments
        .iter()
        .any(|s| s[0][1] == 100.0 && s[1][1] == 100.0));
    assert_eq!(
        first_error(b"PM1;", &ReadOptions::default()),
        "bad.plt:1:1: expected PM0 (polygon mode) before PM1, found 'PM1'"
    );
}

#[test]
fn encoded_polylines_rotation_and_relative_input_points() {
    // PE: pen-up absolute move to (1000, 500), then a relative line of (+200, −100).
    let pe: &[u8] = &[
        b'P',
        b'E',
        b'<',
        b'=',
        63 + 16,
        191 + 31,
        63 + 40,
        191 + 15,
        63 + 16,
        191 + 6,
        63 + 9,
        191 + 3,
        b';',
    ];
    let program = hpgl(pe);
    assert_eq!(drawn(&program), vec![[[1000.0, 500.0], [1200.0, 400.0]]]);
    // RO 90 on a 1000 × 600 page: the rotated x axis runs up the page from its
    // lower-right corner.
    let program = hpgl(b"IN;PS1000,600;RO90;PU0,0;PD100,0;");
    assert_eq!(drawn(&program), vec![[[1000.0, 0.0], [1000.0, 100.0]]]);
    // IR: P1 and P2 in percent of the page.
    let program = hpgl(b"IN;PS1000,600;IR10,10,90,90;SC0,1,0,1;PU0,0;PD1,1;");
    assert_eq!(drawn(&program), vec![[[100.0, 60.0], [900.0, 540.0]]]);
}

#[test]
fn labels_are_drawn_through_the_stroke_font() {
    let program = hpgl(b"IN;SI0.2,0.3;PU1000,1000;LBHI\x03PD;PR10,0;");
    let segments = drawn(&program);
    // H: three strokes, I: one; then the mark from where the label left the pen.
    assert_eq!(segments.len(), 5);
    assert_eq!(segments[4], [[1240.0, 1000.0], [1250.0, 1000.0]]);
    // Every glyph stroke inside its character box (80 × 120 units from the origin).
    for [a, b] in &segments[..4] {
        for p in [a, b] {
            assert!((1000.0..=1000.0 + 2.0 * 120.0).contains(&p[0]), "{p:?}");
            assert!((1000.0..=1120.0 + 1e-9).contains(&p[1]), "{p:?}");
        }
    }
}
