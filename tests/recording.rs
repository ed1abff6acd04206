//! The recordings read back as a reviewer's viewer would: a blueprint store with the views and
//! what each overlays, series named with their units, the event log with the backlash
//! crossings of a run that has them, the summary, an A/B recording overlaying both variants.

mod common;

use cncsim::scenario::{run_ab, Assembly, Override, RunOptions, Scenario};
use common::{rrd_rows, rrd_strings};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn bundled(name: &str) -> Scenario {
    Scenario::load(&root().join("scenarios").join(name)).unwrap()
}

/// The strings of `component` (e.g. `ViewBlueprint:display_name`) of every entity.
fn strings(
    all: &std::collections::BTreeMap<String, Vec<(String, String)>>,
    component: &str,
) -> Vec<(String, String)> {
    all.iter()
        .flat_map(|(e, v)| {
            v.iter()
                .filter(|(c, _)| c == component)
                .map(move |(_, s)| (e.clone(), s.clone()))
        })
        .collect()
}

/// (view name, its contents) of the blueprint.
fn views(path: &Path) -> Vec<(String, Vec<String>)> {
    let all = rrd_strings(path);
    strings(&all, "ViewBlueprint:display_name")
        .into_iter()
        .map(|(entity, name)| {
            let contents = all
                .get(&format!("{entity}/ViewContents"))
                .map(|v| v.iter().map(|(_, q)| q.clone()).collect())
                .unwrap_or_default();
            (name, contents)
        })
        .collect()
}

#[test]
fn the_default_run_carries_a_review_blueprint_named_series_and_a_summary() {
    let scenario = bundled("xyz_circle_5mms.toml");
    let out = tempfile::tempdir().unwrap();
    let mut short = scenario.clone();
    short.program.source =
        cncsim::scenario::ProgramSource::Polyline(cncsim::program::PolylineSpec {
            points: vec![[0.1, 0.1, 0.0], [0.102, 0.1, 0.0]],
            speed: 0.005,
        });
    Assembly::new(&short)
        .unwrap()
        .run(RunOptions::write_to(out.path()).traced())
        .unwrap();
    let rrd = out.path().join("run.rrd");
    let views = views(&rrd);
    let find = |name: &str| {
        views
            .iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("no view '{name}' in {views:?}"))
            .1
            .clone()
    };
    // One plot per comparison, each overlaying what it compares.
    assert_eq!(find("x position (mm)"), ["axes/x/position/**"]);
    assert_eq!(
        find("y following error (µm)"),
        ["axes/y/following_error/**"]
    );
    assert_eq!(
        find("x physics − analytic (µm)"),
        ["axes/x/physics_minus_analytic"]
    );
    assert_eq!(find("z torque (N·m)"), ["axes/z/torque/**"]);
    assert_eq!(find("contour error (µm)"), ["path/contour_error/**"]);
    assert_eq!(find("path speed (mm/s)"), ["path/speed/**"]);
    assert_eq!(find("tool path on the workpiece"), ["$origin/paths/**"]);
    assert_eq!(find("path error, magnified"), ["$origin/**"]);
    assert_eq!(find("events"), ["events"]);
    assert_eq!(find("summary"), ["summary"]);
    // Series names say what and in which unit; physics and analytic are both there.
    let all = rrd_strings(&rrd);
    let names: Vec<String> = strings(&all, "SeriesLines:names")
        .into_iter()
        .map(|(_, n)| n)
        .collect();
    for name in [
        "x commanded (mm)",
        "x physics (mm)",
        "x analytic (mm)",
        "y following error, physics (µm)",
        "y following error, analytic (µm)",
        "x physics − analytic (µm)",
        "z torque, physics (N·m)",
        "x voltage, analytic (V)",
        "contour error, physics (µm)",
        "commanded (mm/s)",
    ] {
        assert!(
            names.iter().any(|n| n == name),
            "no series '{name}' in {names:?}"
        );
    }
    let summary = &strings(&all, "TextDocument:text")[0].1;
    assert!(summary.starts_with("# xyz_circle_5mms"), "{summary}");
    assert!(
        summary.contains("controller: **pid**") && summary.contains("| max contour error |"),
        "{summary}"
    );
    assert!(summary.contains("magnified"), "{summary}");
    let events: Vec<String> = strings(&all, "TextLog:text")
        .into_iter()
        .map(|(_, t)| t)
        .collect();
    assert!(
        events.iter().any(|e| e.starts_with("program start")),
        "{events:?}"
    );
    assert!(
        events.iter().any(|e| e.contains("largest following error")),
        "{events:?}"
    );
}

#[test]
fn backlash_crossings_and_a_stop_are_in_the_event_log() {
    let mut scenario = bundled("paper_corner_90.toml");
    // Out and back on X: one reversal, whose backlash the drive crosses; then a fault.
    scenario.program.source =
        cncsim::scenario::ProgramSource::Polyline(cncsim::program::PolylineSpec {
            points: vec![[0.1, 0.1, 0.0], [0.102, 0.1, 0.0], [0.1, 0.1, 0.0]],
            speed: 0.005,
        });
    scenario.timing.settle_time = 0.5;
    scenario.recording.csv = false;
    let out = tempfile::tempdir().unwrap();
    let run = Assembly::new(&scenario)
        .unwrap()
        .run(RunOptions::write_to(out.path()).traced())
        .unwrap();
    assert!(run.stop().is_none());
    let all = rrd_strings(&out.path().join("run.rrd"));
    let events: Vec<String> = strings(&all, "TextLog:text")
        .into_iter()
        .map(|(_, t)| t)
        .collect();
    let crossings: Vec<&String> = events
        .iter()
        .filter(|e| e.starts_with("x: backlash crossed"))
        .collect();
    assert_eq!(crossings.len(), 1, "{events:?}");
    assert!(crossings[0].ends_with("pushes backward"), "{events:?}");
    assert!(
        events.iter().any(|e| e.contains("exact stop")),
        "{events:?}"
    );

    // The same run with a following-error limit it breaches: the stop is logged at its time.
    scenario.feedback.following_error_limit_linear = 0.2e-3;
    let out = tempfile::tempdir().unwrap();
    let run = Assembly::new(&scenario)
        .unwrap()
        .run(RunOptions::write_to(out.path()).traced())
        .unwrap();
    let stop = run.stop().cloned().expect("the fault");
    let all = rrd_strings(&out.path().join("run.rrd"));
    let events: Vec<String> = strings(&all, "TextLog:text")
        .into_iter()
        .map(|(_, t)| t)
        .collect();
    assert!(
        events
            .iter()
            .any(|e| e.starts_with("physics stopped: following-error fault")),
        "{stop}: {events:?}"
    );
}

#[test]
fn an_ab_recording_overlays_both_variants() {
    let path = root().join("scenarios/mill_table2_fast.toml");
    let load = |o: &str| {
        Scenario::load_with_overrides(&path, &[Override::parse(o).unwrap()], "--a").unwrap()
    };
    let (mut a, mut b) = (load("controller=pid"), load("controller=cascade"));
    for s in [&mut a, &mut b] {
        s.recording.rrd = false;
        s.recording.csv = false;
    }
    let out = tempfile::tempdir().unwrap();
    let report = run_ab(&a, &b, out.path(), &mut |_, _| true).unwrap().report;
    assert!(report.rows.iter().any(|r| r.metric == "max contour error"));
    let rrd = out.path().join("ab.rrd");
    let views = views(&rrd);
    let x = views
        .iter()
        .find(|(n, _)| n == "x following error (µm)")
        .expect("x error plot");
    assert_eq!(
        x.1,
        [
            "a/axes/x/following_error/physics",
            "b/axes/x/following_error/physics"
        ]
    );
    assert!(views
        .iter()
        .any(|(n, c)| n == "contour error (µm)" && c.len() == 2));
    let all = rrd_strings(&rrd);
    let names: Vec<String> = strings(&all, "SeriesLines:names")
        .into_iter()
        .map(|(_, n)| n)
        .collect();
    assert!(
        names
            .iter()
            .any(|n| n == "A: mill_table2_fast controller=pid: x following error, physics (µm)"),
        "{names:?}"
    );
    assert!(names
        .iter()
        .any(|n| n == "B: mill_table2_fast controller=cascade: x following error, physics (µm)"));
    let rows = rrd_rows(&rrd);
    assert!(rows
        .get("/a/axes/c/following_error/physics")
        .is_some_and(|n| *n > 0));
    assert_eq!(
        rows.get("/a/axes/c/following_error/physics"),
        rows.get("/b/axes/c/following_error/physics")
    );
    assert!(strings(&all, "TextDocument:text")
        .iter()
        .any(|(e, t)| e == "/ab_summary" && t.contains("| max contour error |")));
}

#[test]
fn a_run_with_a_chain_longer_than_the_look_ahead_says_so_in_its_summary() {
    // 5 000 lines of 0.2 mm on a curve (CAM raster rows, every line planned): one chain, a
    // handoff between two windows of the look-ahead.
    let dir = tempfile::tempdir().unwrap();
    let program = format!(
        "G21 G90 G17 G64 P0.05 Q0\nG0 X0 Y0 Z1\nF3000\n{}M2\n",
        common::raster_gcode(5000)
    );
    std::fs::write(dir.path().join("raster.ngc"), program).unwrap();
    let mut text = std::fs::read_to_string(root().join("scenarios/xyz_circle_5mms.toml")).unwrap();
    text = text
        .replace("../models/", &format!("{}/models/", root().display()))
        .replace(
            "circle = { center_mm = [100.0, 100.0], radius_mm = 30.0, start_angle_deg = 0.0, \
             direction = \"ccw\", z_mm = 0.0 }\nfeed_mm_s = 5.0",
            "file = \"raster.ngc\"",
        )
        .replace(
            "profile = \"constant-velocity\"",
            "profile = \"jerk-limited\"\n\
             limits.x = { velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }\n\
             limits.y = { velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }\n\
             limits.z = { velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }",
        );
    let file = dir.path().join("raster.toml");
    std::fs::write(&file, text).unwrap();
    let scenario = Scenario::load(&file).unwrap();
    let out = dir.path().join("out");
    let run = Assembly::new(&scenario)
        .unwrap()
        .run(RunOptions::write_to(&out).traced())
        .unwrap();
    assert!(run.stop().is_none(), "{:?}", run.stop());
    assert!(run.warnings.is_empty(), "{:?}", run.warnings);
    let all = rrd_strings(&out.join("run.rrd"));
    let summary = &strings(&all, "TextDocument:text")[0].1;
    assert!(summary.contains("(5001 moves)"), "{summary}");
    assert!(
        summary.contains(
            "- look-ahead 4096 blocks: 1 handoff inside longer chains, 0 stops added where no \
             handoff could be made\n"
        ),
        "{summary}"
    );
}

#[test]
fn a_tool_tip_program_reads_as_its_moves_and_its_path_grows_on_a_short_run() {
    // The head-head machine's tool-tip circle: each programmed move is held on its path by
    // hundreds of joint-space pieces, which the event log counts as the one move they are; the
    // 8 s run's actual path is drawn in pieces as the time cursor moves, not at its end.
    let path = root().join("tests/fixtures/machines/head_bc/head_bc_tcp.toml");
    let mut scenario = Scenario::load(&path).unwrap();
    scenario.recording.rrd = true;
    let out = tempfile::tempdir().unwrap();
    let run = Assembly::new(&scenario)
        .unwrap()
        .run(RunOptions::write_to(out.path()))
        .unwrap();
    assert!(run.stop().is_none());
    let rrd = out.path().join("run.rrd");
    let all = rrd_strings(&rrd);
    let moves: Vec<String> = strings(&all, "TextLog:text")
        .into_iter()
        .map(|(_, t)| t)
        .filter(|t| t.contains("move ") && t.contains("(line "))
        .collect();
    // Lines 5 to 10 of tcp_circle.ngc: G0, G1 Z0, G1 B-15, G3 … C360, G1 B0, G0 Z5.
    let lines: Vec<&str> = moves
        .iter()
        .map(|t| t.rsplit("(line ").next().unwrap().trim_end_matches(')'))
        .collect();
    assert_eq!(lines, ["5", "6", "7", "8", "9", "10"], "{moves:?}");
    let pieces = rrd_rows(&rrd)
        .keys()
        .filter(|e| e.contains("/paths/actual/"))
        .count();
    assert!(pieces >= 50, "{pieces} pieces of the actual path");
}
