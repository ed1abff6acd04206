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

/// The program's warnings, as text.
fn warnings(program: &Program) -> Vec<&str> {
    program
        .warnings
        .iter()
        .map(|w| w.message.as_str())
        .collect()
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

fn strict() -> ReadOptions {
    let mut options = ReadOptions::default();
    options.hpgl.strict = true;
    options
}

#[test]
fn a_comma_before_the_terminator_is_allowed() {
    let program = hpgl(b"IN;PA100,100;PD200,100,200,200,;PU;");
    assert_eq!(drawn(&program).len(), 2);
    // Empty parameters are passed over as plotters and hp2xx pass over them …
    let program = hpgl(b"IN;PA,PU100,100;PD,200,100,,200,200,;PU;");
    let segments = drawn(&program);
    assert_eq!(segments.len(), 2);
    assert!(close(segments[1][1], [200.0, 200.0]));
    // … and refused with --strict, as before.
    assert_eq!(
        first_error(b"PD1,2,,;", &strict()),
        "bad.plt:1:7: expected a number after ',' in the parameters of PD, found ','"
    );
}

#[test]
fn commands_that_do_not_draw_warn_once_per_kind_and_strict_refuses_them() {
    let text =
        b"IN;PS1000,1000;CO\"made by hand\";PW0.35;PT0.3;NP8;PU0,0;PD100,0;PU;EC;PG1;EC1;NP4;";
    let program = hpgl(text);
    let messages = warnings(&program);
    assert_eq!(
        messages,
        [
            "CO (comment) is not a pen move and was skipped (once in the file)",
            "NP (number of pens) is not a pen move and was skipped (2 times in the file)",
            "EC (enable cutter) is not a pen move and was skipped (2 times in the file)",
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
    // Pages are drawn one over another, as hp2xx draws them, with one warning; `page`
    // chooses one (counted as hp2xx -P counts them); --strict refuses a second page.
    let pages = b"IN;PU0,0;PD10,0;PG;PU0,5;PD20,5;PG;PU;PG;";
    let program = hpgl(pages);
    assert_eq!(drawn(&program).len(), 2);
    let messages = warnings(&program);
    assert_eq!(
        messages,
        ["the file draws on 2 pages (1, 2; the first page advance, PG, is here): they are drawn one over another, as hp2xx draws them; page = N in [program] (inspect --page N) plots one"]
    );
    let mut second = ReadOptions::default();
    second.hpgl.page = Some(2);
    let program = parse_hpgl(pages, "t.plt", &second).unwrap();
    assert_eq!(drawn(&program), vec![[[0.0, 5.0], [20.0, 5.0]]]);
    assert!(program.warnings.is_empty(), "{:?}", program.warnings);
    second.hpgl.page = Some(3);
    assert_eq!(
        first_error(pages, &second),
        "bad.plt:1:42: expected page 3 to draw something; the file draws on pages 1, 2, found end of file; hint: choose one of those (page = N in [program], inspect --page N)"
    );
    assert_eq!(
        first_error(b"IN;PU0,0;PD10,0;PG;PD20,0;", &strict()),
        "bad.plt:1:17: expected a command that draws; PG (advance page) is not a pen move (refused with --strict), found 'PG;'"
    );
    assert!(parse_hpgl(
        b"IN;IW0,0,100,100;PU10,10;PD90,90;",
        "t.plt",
        &ReadOptions::default()
    )
    .is_ok());
    // With --strict, drawing outside the window is refused as before (IW clips otherwise:
    // `iw_clips_lines_and_arcs_at_the_window`).
    assert_eq!(
        first_error(b"IN;IW0,0,100,100;PU10,10;PD90,90,150,90;", &strict()),
        "bad.plt:1:26: expected drawing inside the input window (IW 0,0,100,100 plotter units); clipping at the window is not supported, found 'PD90,90,150,90'; hint: re-plot without an input window, or keep the drawing inside it"
    );
    // An arc bulging out of the window is caught too, though its ends are inside.
    assert!(parse_hpgl(
        b"IN;IW0,0,100,100;PU95,75;PD;AA50,50,-58;",
        "t.plt",
        &strict()
    )
    .is_err());
}

/// Pen-down polylines in plotter units, arcs sampled every degree.
fn polylines(program: &Program) -> Vec<Vec<[f64; 2]>> {
    let mut lines: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut from = program.start.linear;
    let mut current: Option<Vec<[f64; 2]>> = None;
    let unit = |p: [f64; 3]| [p[0] * UNITS_PER_METRE, p[1] * UNITS_PER_METRE];
    for mv in &program.moves {
        let to = mv.end.linear;
        let drawing = mv.tool_down == Some(true) && from[2] == to[2];
        if !drawing {
            if let Some(line) = current.take() {
                lines.push(line);
            }
            from = to;
            continue;
        }
        let line = current.get_or_insert_with(|| vec![unit(from)]);
        match mv.motion {
            Motion::Arc {
                center,
                clockwise,
                turns,
                ..
            } => {
                let sweep = cncsim::program::arc_sweep(
                    &from,
                    &to,
                    &center,
                    cncsim::program::Plane::XY,
                    clockwise,
                    turns,
                );
                let radius = (from[0] - center[0]).hypot(from[1] - center[1]);
                let start = (from[1] - center[1]).atan2(from[0] - center[0]);
                let steps = sweep.to_degrees().ceil().max(1.0) as usize;
                for k in 1..=steps {
                    let a =
                        start + if clockwise { -sweep } else { sweep } * k as f64 / steps as f64;
                    line.push(unit([
                        center[0] + radius * a.cos(),
                        center[1] + radius * a.sin(),
                        0.0,
                    ]));
                }
            }
            _ => line.push(unit(to)),
        }
        from = to;
    }
    lines.extend(current);
    lines
}

fn distance_to_polylines(p: [f64; 2], lines: &[Vec<[f64; 2]>]) -> f64 {
    let mut best = f64::INFINITY;
    for line in lines {
        for w in line.windows(2) {
            let d = [w[1][0] - w[0][0], w[1][1] - w[0][1]];
            let n = d[0] * d[0] + d[1] * d[1];
            let t = if n == 0.0 {
                0.0
            } else {
                (((p[0] - w[0][0]) * d[0] + (p[1] - w[0][1]) * d[1]) / n).clamp(0.0, 1.0)
            };
            best = best.min((p[0] - w[0][0] - d[0] * t).hypot(p[1] - w[0][1] - d[1] * t));
        }
    }
    best
}

#[test]
fn iw_clips_lines_and_arcs_at_the_window() {
    // A circle of radius 350 about the window's centre crosses each side of the window
    // (200..800): four arcs are inside it. Computed here from the circle itself.
    let program = hpgl(b"IN;SP1;IW200,200,800,800;PU500,500;CI350;PU0,500;PD1000,500;PU;");
    let lines = polylines(&program);
    let (low, high) = (200.0, 800.0);
    let inside = |p: [f64; 2]| (0..2).all(|i| p[i] >= low - 1e-6 && p[i] <= high + 1e-6);
    // Nothing drawn outside the window.
    for line in &lines {
        for &p in line {
            assert!(inside(p), "{p:?} is outside the window");
        }
    }
    // Every point of the circle inside the window is drawn (to the 0.4-unit chords).
    let mut checked = 0;
    for k in 0..3600 {
        let a = f64::from(k).to_radians() / 10.0;
        let p = [500.0 + 350.0 * a.cos(), 500.0 + 350.0 * a.sin()];
        if inside(p) {
            checked += 1;
            let d = distance_to_polylines(p, &lines);
            assert!(
                d <= 0.4 + 1e-6,
                "circle point {p:?} is {d} units from the drawing"
            );
        }
    }
    assert!(checked > 1000);
    // The line is cut at the window's edges.
    assert!(lines
        .iter()
        .any(|l| l.len() == 2 && close(l[0], [200.0, 500.0]) && close(l[1], [800.0, 500.0])));
    assert!(program.warnings.iter().any(|w| w
        .message
        .starts_with("drawing outside the input window (IW) is not drawn and was clipped")));
    // A dot (pen down without a move) outside the window is not drawn either.
    let program = hpgl(b"IN;IW200,200,800,800;PU100,100;PD;PU;PU300,300;PD;PU;");
    let plunges = program
        .moves
        .iter()
        .filter(|m| m.tool_down == Some(true))
        .count();
    assert_eq!(plunges, 1);
}

#[test]
fn unknown_mnemonics_are_passed_over_unless_they_draw() {
    let program = hpgl(b"IN;SP1;ZZ1,2;QQ\"x\";PU0,0;ZZ;PD100,0;PU;");
    assert_eq!(drawn(&program).len(), 1);
    let messages = warnings(&program);
    assert_eq!(
        messages,
        [
            "ZZ is not an HP-GL command cncsim knows; a plotter passes over it (error 1) and so was it (2 times in the file)",
            "QQ is not an HP-GL command cncsim knows; a plotter passes over it (error 1) and so was it (once in the file)",
        ]
    );
    // Commands that draw are refused by name, not passed over.
    assert_eq!(
        first_error(b"IN;PU0,0;UC99,1,1;", &ReadOptions::default()),
        "bad.plt:1:10: expected a command cncsim draws; user-defined characters (UC) are not supported, found 'UC99,1,1'; hint: plot text as vectors"
    );
    assert_eq!(
        first_error(b"IN;RP1;", &ReadOptions::default()),
        "bad.plt:1:4: expected an HPGL command; RP is not one cncsim knows, found 'RP1'; hint: HP-GL/1 and HP-GL/2 commands are read; check the file is a plot file"
    );
    // --strict refuses unknown mnemonics as before.
    assert_eq!(
        first_error(b"IN;ZZ1,2;", &strict()),
        "bad.plt:1:4: expected an HPGL command; ZZ is not one cncsim knows, found 'ZZ1,2'; hint: HP-GL/1 and HP-GL/2 commands are read; check the file is a plot file"
    );
}

#[test]
fn comments_quoted_and_unquoted_control_characters_pt0_and_raster_fills() {
    let text = b"\x03\x1a IN;CO\"quoted; with a semicolon\";CO unquoted note;\nSP1;PT0;PU0,0;PD100,0;PU;\x04";
    let program = hpgl(text);
    assert_eq!(drawn(&program).len(), 1);
    let messages = warnings(&program);
    assert_eq!(
        messages,
        [
            "a character between commands that is not part of one (a control character or stray punctuation) is not a pen move and was passed over, as plotters do (3 times in the file)",
            "CO (comment) is not a pen move and was skipped (2 times in the file)",
            "PT 0 (pen thickness) is out of the range 0.1 to 5 mm and was ignored, as plotters ignore it (once in the file)",
        ]
    );
    for bad in [&text[..], b"IN;FT21;"] {
        assert!(parse_hpgl(bad, "bad.plt", &strict()).is_err());
    }
    // FT 21 (a PCL raster pattern) is filled as solid fill is: the same drawing as FT 1.
    let solid = hpgl(b"IN;SP1;FT1;PU0,0;RA400,400;");
    let raster = hpgl(b"IN;SP1;FT21,3;PU0,0;RA400,400;");
    assert_eq!(drawn(&solid), drawn(&raster));
    assert!(drawn(&solid).len() > 10);
    assert!(raster.warnings.iter().any(|w| w.message.starts_with("FT 21 (a raster fill pattern) cannot be drawn with a pen and its fills are drawn solid instead")));
}

#[test]
fn an_unfinished_pe_number_is_dropped_as_plotters_drop_it() {
    // As a driver wrote it: the PE data run into "PUSP0" without their ';'.
    let mut text = b"IN;SP1;PE<=m".to_vec();
    text.extend([0xCD, b'm', 0xCD, b'=', b'C', 0xCA, b'C', 0xCA]);
    text.extend(b"PUSP0;");
    let program = hpgl(&text);
    // m + 0xCD: 46 + 14 × 64 = 942 → 471; C + 0xCA: 4 + 11 × 64 = 708 → 354.
    let segments = drawn(&program);
    assert_eq!(segments.len(), 1);
    assert!(close(segments[0][0], [471.0, 471.0]) && close(segments[0][1], [354.0, 354.0]));
    assert!(program.warnings.iter().any(|w| w
        .message
        .starts_with("PE data that end in an unfinished number")));
    assert!(parse_hpgl(&text, "bad.plt", &strict()).is_err());
    // The same file after a text tool re-encoded it as UTF-8 (0xCD → C3 8D, 0xCA → C3 8A):
    // decoded back exactly, and said.
    let mangled: Vec<u8> = String::from_utf8(
        text.iter()
            .map(|&b| b as char)
            .collect::<String>()
            .into_bytes(),
    )
    .unwrap()
    .into_bytes();
    assert_ne!(mangled, text);
    let program = hpgl(&mangled);
    assert_eq!(drawn(&program), segments);
    assert!(program
        .warnings
        .iter()
        .any(|w| w.message.starts_with("PE data re-encoded as UTF-8")));
    assert!(parse_hpgl(&mangled, "bad.plt", &strict()).is_err());
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
    // Raster patterns are filled solid (see below), refused with --strict as before.
    assert!(first_error(b"FT11;", &strict()).contains("raster fill patterns"));
    assert!(first_error(b"FT12;", &ReadOptions::default()).contains("expected fill type 1, 2"));
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

#[test]
fn hatch_lines_are_laid_from_the_anchor_corner() {
    // Horizontal hatching 100 units apart in a 1000-unit square: halfway between multiples of
    // the spacing from the anchor corner, (0, 0) by default, (0, 30) after AC0,30; DF restores.
    let levels = |text: &[u8]| {
        let mut ys: Vec<f64> = drawn(&hpgl(text))
            .into_iter()
            // Hatch lines, not the square's own top and bottom edges.
            .filter(|[a, b]| (a[1] - b[1]).abs() < 1e-6 && a[1] > 1e-6 && a[1] < 1000.0 - 1e-6)
            .map(|[a, _]| (a[1] * 1e6).round() / 1e6)
            .collect();
        ys.sort_by(f64::total_cmp);
        ys.dedup();
        ys
    };
    let square = b"PU0,0;RA1000,1000;PU;";
    let plain = levels(&[b"IN;FT3,100,0;".as_slice(), square].concat());
    assert_eq!(plain.first(), Some(&50.0));
    assert_eq!(plain.len(), 10);
    let anchored = levels(&[b"IN;FT3,100,0;AC0,30;".as_slice(), square].concat());
    assert_eq!(anchored.first(), Some(&80.0), "{anchored:?}");
    assert_eq!(anchored.len(), 10);
    let reset = levels(&[b"IN;FT3,100,0;AC0,30;DF;FT3,100,0;".as_slice(), square].concat());
    assert_eq!(reset, plain);
}

#[test]
fn dv_stacks_label_characters_along_the_text_path() {
    // SI 0.2 × 0.4 cm: a character cell 1.5 × 80 = 120 units wide, a line 2 × 160 = 320 high.
    // After the label the pen stands where the next character would go; a line drawn from
    // there shows where that is.
    let pen_after = |setup: &str| {
        let text = format!("IN;SI0.2,0.4;{setup}PA1000,1000;LBAB\x03PD5000,5000;PU;");
        let program = hpgl(text.as_bytes());
        drawn(&program).last().unwrap()[0]
    };
    let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6;
    assert!(close(pen_after(""), [1240.0, 1000.0]));
    // DV1: each character below the one before, a line apart; DV2 to the left; DV3 up.
    assert!(
        close(pen_after("DV1;"), [1000.0, 360.0]),
        "{:?}",
        pen_after("DV1;")
    );
    assert!(close(pen_after("DV2;"), [760.0, 1000.0]));
    assert!(close(pen_after("DV3;"), [1000.0, 1640.0]));
    // A line feed goes 90° clockwise of the path (DV1: a column to the left), anticlockwise
    // with DV1,1; the carriage return goes back to the top of the column.
    let lf = |setup: &str| {
        let text = format!("IN;SI0.2,0.4;{setup}PA1000,1000;LBA\r\nB\x03PD5000,5000;PU;");
        drawn(&hpgl(text.as_bytes())).last().unwrap()[0]
    };
    assert!(close(lf("DV1;"), [880.0, 680.0]), "{:?}", lf("DV1;"));
    assert!(close(lf("DV1,1;"), [1120.0, 680.0]), "{:?}", lf("DV1,1;"));
    // DF goes back to the right.
    assert!(close(pen_after("DV1;DF;SI0.2,0.4;"), [1240.0, 1000.0]));
}

#[test]
fn polygon_mode_entered_with_the_pen_down_draws_its_edges() {
    // KiCad's filled pads: `PA x,y;PD;PM 0;PA …;PM 2; FP; EP;`. The pen stays down in
    // polygon mode (HP-GL/2), so the edges are pen-down moves, drawn by EP and FP.
    let mut options = ReadOptions::default();
    options.hpgl.hatch_fills = false;
    let program = hpgl_with(
        b"IN;VS40;PU;PA;SP1;\nPA 640,500;PD;PM 0;\nPA 640,700;PA 760,700;PA 760,500;PA 640,500;PM 2; FP; EP;\nPU;PA;SP0;\n",
        &options,
    );
    let segments = drawn(&program);
    for corner in [[640.0, 700.0], [760.0, 700.0], [760.0, 500.0]] {
        assert!(
            segments.iter().any(|s| close(s[1], corner)),
            "{corner:?} not drawn: {segments:?}"
        );
    }
    // Entered with the pen up (KiCad's round pads: `PU;PM 0; PA cx,cy;CI r;PM 2;`), the
    // pen-up move only places the circle.
    let program = hpgl_with(
        b"IN;PA 1070,500;PU;PM 0; PA 1000,500;CI 70;PM 2; FP; EP;\nPU;\n",
        &options,
    );
    let lines = polylines(&program);
    assert!(!lines.is_empty());
    assert!(
        lines
            .iter()
            .flatten()
            .all(|p| ((p[0] - 1000.0).hypot(p[1] - 500.0) - 70.0).abs() < 1e-6),
        "{lines:?}"
    );
}

#[test]
fn a_stray_letter_after_the_last_command_is_passed_over_with_one_warning() {
    let program = hpgl(b"IN;SP1;PA0,0;PD100,0;PUx;\n");
    assert_eq!(drawn(&program).len(), 1);
    let said = warnings(&program);
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(
        said[0].contains("`x;` after the plot's last command is not a command"),
        "{}",
        said[0]
    );
    // Refused with --strict, and anywhere but at the end.
    assert!(first_error(b"IN;PA0,0;PD100,0;PUx;\n", &strict()).contains("bad.plt:1:"));
    assert!(first_error(b"IN;PUx;PD100,0;PU;\n", &ReadOptions::default()).contains("bad.plt:1:"));
}

#[test]
fn drawing_off_the_page_and_pen_down_records_that_draw_nothing_are_said() {
    // PS sets a 100 × 50 mm page; one line leaves it.
    let program = hpgl(b"IN;PS4000,2000;SP1;PA0,0;PD1000,1000;PD5000,1000;PD6000,1500;PU;\n");
    let said = warnings(&program);
    let off: Vec<&&str> = said.iter().filter(|m| m.contains("off the page")).collect();
    assert_eq!(off.len(), 1, "{said:?}");
    assert!(
        off[0].contains("100.0 × 50.0 mm")
            && off[0].contains("first to (125.00, 25.00) mm")
            && off[0].contains("2 times"),
        "{}",
        off[0]
    );
    // On the page: not a word.
    assert!(warnings(&hpgl(b"IN;PS4000,2000;SP1;PA0,0;PD1000,1000;PU;\n")).is_empty());
    // Twelve PD records in polygon mode that no EP or FP draws.
    let mut text = b"IN;SP1;PA0,0;PM0;".to_vec();
    for k in 0..12 {
        text.extend_from_slice(format!("PD{},{};", 100 * k, 50 * (k % 2)).as_bytes());
    }
    text.extend_from_slice(b"PM2;PU;\n");
    let program = hpgl(&text);
    assert!(drawn(&program).is_empty());
    let said = warnings(&program);
    assert!(
        said.iter()
            .any(|m| m.contains("12 pen-down records (PD), the first here, and nothing drawn")),
        "{said:?}"
    );
}

#[test]
fn ps_with_a_paper_number_selects_the_paper_of_an_hpgl1_plotter() {
    // vpype's HP 7475A output: `PS4` (A/A4) or `PS0` (B/A3), then plotter units. The page and
    // P1/P2 stay: SC still maps onto the HP 7475A's P1–P2, and nothing is off any page.
    for paper in ["PS4", "PS0"] {
        let text = format!("IN;{paper};SC0,100,0,100;SP1;PA0,0;PD100,100;PU;SP0;");
        let program = hpgl(text.as_bytes());
        let segments = drawn(&program);
        assert_eq!(segments.len(), 1, "{paper}: {segments:?}");
        let [from, to] = segments[0];
        // The HP 7475A's default P1 (250, 596) and P2 (10250, 7796).
        assert!(
            close(from, [250.0, 596.0]) && close(to, [10250.0, 7796.0]),
            "{paper}: {segments:?}"
        );
        let said = warnings(&program);
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(
            said[0].contains("selects the paper of an HP-GL/1 plotter"),
            "{}",
            said[0]
        );
    }
    // A plot size in plotter units is still one.
    let program = hpgl(b"IN;PS4000,2000;SP1;PA0,0;PD1000,1000;PU;");
    assert!(warnings(&program).is_empty());
}

#[test]
fn a_roman8_dash_in_a_label_is_drawn_as_a_minus_and_other_8_bit_characters_as_blanks() {
    // plotutils' PCL output labels its axes with Roman-8's dash (0xF6) for a minus sign.
    let minus = hpgl(b"IN;SP1;PA0,0;LB\xf61.0\x03;PU;");
    let ascii = hpgl(b"IN;SP1;PA0,0;LB-1.0\x03;PU;");
    assert_eq!(drawn(&minus), drawn(&ascii));
    let said = warnings(&minus);
    assert!(
        said.iter().any(|m| m.contains("the first `0xF6`")),
        "{said:?}"
    );
    // Another 8-bit character: a blank cell, the pen moving on as for a character.
    let blank = hpgl(b"IN;SP1;PA0,0;LB\xb31\x03;PU;");
    let spaced = hpgl(b"IN;SP1;PA0,0;LB 1\x03;PU;");
    assert_eq!(drawn(&blank), drawn(&spaced));
    // UTF-8 text a character a cell: an en dash is a minus, an accented letter a blank.
    let utf8 = hpgl("IN;SP1;PA0,0;LB\u{2013}1 CAF\u{e9}\x03;PU;".as_bytes());
    let ascii = hpgl(b"IN;SP1;PA0,0;LB-1 CAF \x03;PU;");
    assert_eq!(drawn(&utf8), drawn(&ascii));
    // Refused with --strict.
    assert!(first_error(b"IN;SP1;PA0,0;LB\xf61.0\x03;", &strict()).contains("ASCII 32"));
}
