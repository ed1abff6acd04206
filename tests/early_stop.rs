//! A run that stops early keeps everything it computed: `metrics.json` with `completed =
//! false` and the stop, the CSV and a readable recording up to the stop with the stop in its
//! event log — for every kind of stop (following-error fault, interruption, divergence), with
//! and without the analytic model, at any recording decimation.

mod common;

use cncsim::report::{ReportSetup, RunReport};
use cncsim::scenario::{recording_setup, report_setup, Assembly, RunOptions, Scenario};
use cncsim::sim::{self, Hold, Lane, Plant, Sensors};
use common::{rrd_rows, rrd_strings};
use std::path::{Path, PathBuf};

fn scenario(analytic: bool, decimation: usize) -> Scenario {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut s = Scenario::load(&root.join("scenarios/paper_corner_90.toml")).unwrap();
    s.timing.settle_time = 0.2;
    s.recording.decimation = decimation;
    // Its bounds are for the full run.
    s.expect.clear();
    if !analytic {
        s.analytic = None;
    }
    s
}

fn events(rrd: &Path) -> Vec<String> {
    rrd_strings(rrd)
        .get("/events")
        .map(|v| {
            v.iter()
                .filter(|(c, _)| c == "TextLog:text")
                .map(|(_, t)| t.clone())
                .collect()
        })
        .unwrap_or_default()
}

/// What every early stop must leave: metrics saying so, CSV and recording rows up to the stop.
fn assert_kept(out: &Path, ticks: usize, decimation: usize, stop_words: &str) {
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(json["completed"], false);
    assert!(
        json["stopped"].as_str().unwrap().contains(stop_words),
        "{json}"
    );
    assert_eq!(json["servo_ticks"].as_u64(), Some(ticks as u64));
    let recorded = ticks.div_ceil(decimation);
    if out.join("trace.csv").exists() {
        let csv = std::fs::read_to_string(out.join("trace.csv")).unwrap();
        assert_eq!(csv.lines().count(), recorded + 1);
    }
    let rrd = out.join("run.rrd");
    let rows = rrd_rows(&rrd);
    assert_eq!(
        rows.get("/axes/x/position/physics").copied(),
        Some(recorded),
        "{rows:?}"
    );
    let events = events(&rrd);
    assert!(
        events
            .iter()
            .any(|e| e.starts_with("physics stopped:") && e.contains(stop_words)),
        "{events:?}"
    );
}

#[test]
fn a_following_error_fault_keeps_everything() {
    for (analytic, decimation) in [(false, 1), (true, 1), (true, 7), (false, 7)] {
        let mut s = scenario(analytic, decimation);
        s.feedback.following_error_limit_linear = 0.3e-3;
        let out = tempfile::tempdir().unwrap();
        let run = Assembly::new(&s)
            .unwrap()
            .run(RunOptions::write_to(out.path()))
            .unwrap();
        let stop = run.stop().cloned().expect("the fault");
        assert!(stop.to_string().contains("following-error fault"), "{stop}");
        assert_kept(
            out.path(),
            run.metrics.servo_ticks,
            decimation,
            "following-error fault",
        );
    }
}

#[test]
fn an_interruption_keeps_everything() {
    for (analytic, decimation) in [(true, 3), (false, 1)] {
        let s = scenario(analytic, decimation);
        let out = tempfile::tempdir().unwrap();
        let mut reports = 0;
        let mut progress = |_: usize, _: usize| {
            reports += 1;
            reports < 2
        };
        let run = Assembly::new(&s)
            .unwrap()
            .run(RunOptions::write_to(out.path()).progress(&mut progress))
            .unwrap();
        assert!(run.stop().unwrap().to_string().starts_with("interrupted"));
        assert_kept(
            out.path(),
            run.metrics.servo_ticks,
            decimation,
            "interrupted",
        );
    }
}

/// A plant whose state stops being finite after some ticks: what a numerical blow-up looks
/// like to the loop.
struct Blows {
    inner: Box<dyn Plant>,
    after: usize,
    ticks: usize,
}

impl Plant for Blows {
    fn axes(&self) -> usize {
        self.inner.axes()
    }
    fn sample(&mut self, out: &mut Sensors) {
        self.inner.sample(out);
        if self.ticks >= self.after {
            out.position[1] = f64::NAN;
        }
    }
    fn hold(&mut self, command: &[f64], out: &mut Hold) {
        self.ticks += 1;
        self.inner.hold(command, out);
    }
    fn steps(&self) -> u64 {
        self.inner.steps()
    }
}

#[test]
fn a_divergence_keeps_everything_and_names_time_and_axis() {
    for (analytic, decimation) in [(true, 1), (false, 5)] {
        let s = scenario(analytic, decimation);
        let assembly = Assembly::new(&s).unwrap();
        let mut lanes = assembly.lanes().unwrap();
        // Untraced before the program: the settle at rest, then the approach to its start.
        let settle = (s.timing.settle_time / s.timing.servo_period).round() as usize
            + assembly.loop_settings.approach.len();
        let inner = std::mem::replace(
            &mut lanes[0].plant,
            Box::new(sim::AnalyticPlant::from_models(
                Vec::new(),
                &assembly.machine,
                s.timing.servo_period,
                1,
            )),
        );
        lanes[0].plant = Box::new(Blows {
            inner,
            after: settle + 400,
            ticks: 0,
        });
        let out = tempfile::tempdir().unwrap();
        let setup: ReportSetup = report_setup(&assembly);
        let lane_names = setup.lanes.clone();
        let csv = out.path().join("trace.csv");
        let rrd = out.path().join("run.rrd");
        let mut report = RunReport::new(
            setup,
            Some(&csv),
            Some((&rrd, recording_setup(&assembly, &lane_names))),
            decimation,
        )
        .unwrap();
        let outcome = sim::run(
            &assembly.loop_settings,
            &mut lanes,
            &mut assembly.setpoints(),
            &mut report,
            &mut |_, _| true,
        );
        let stop = outcome.stop().expect("diverged").to_string();
        let at = format!(
            "simulation diverged at t = {:.6} s on axis 'y'",
            400.0 * s.timing.servo_period
        );
        assert!(stop.starts_with(&at), "{stop}");
        let metrics = report.metrics(&outcome);
        std::fs::write(
            out.path().join("metrics.json"),
            serde_json::to_string(&metrics.to_json()).unwrap(),
        )
        .unwrap();
        report.finish(&outcome, &[], "summary").unwrap();
        // The diverged tick itself is not observed: 400 ticks were.
        assert_eq!(metrics.servo_ticks, 400);
        assert_kept(out.path(), 400, decimation, "diverged");
        let _ = Lane {
            kind: sim::LaneKind::Analytic,
            plant: Box::new(sim::AnalyticPlant::from_models(
                Vec::new(),
                &assembly.machine,
                1e-3,
                1,
            )),
            controller: assembly.controller(),
        };
    }
}

/// A plant of one's own through `RunOptions::plant`: with the analytic model as the plant of
/// both lanes, the "physics" lane runs the very same model as the analytic one, so the two
/// agree exactly, where with the scenario's own plants they differ.
#[test]
fn an_own_plant_runs_in_the_scenario_lanes() {
    use cncsim::sim::{LaneKind, Plant};
    let s = scenario(true, 1);
    let assembly = Assembly::new(&s).unwrap();
    let built = std::cell::RefCell::new(Vec::new());
    let make = |kind: LaneKind, start: &[f64]| -> Box<dyn Plant> {
        built.borrow_mut().push(kind);
        assembly.plant(LaneKind::Analytic, start).unwrap()
    };
    let own = assembly.run(RunOptions::new().plant(&make)).unwrap();
    assert_eq!(*built.borrow(), [LaneKind::Physics, LaneKind::Analytic]);
    let theirs = assembly.run(RunOptions::new()).unwrap();
    assert!(own.stop().is_none() && theirs.stop().is_none());
    for (axis, a) in &own.metrics.axes {
        let apart = |m: &cncsim::report::Metrics| m.axes[axis].max_physics_vs_analytic_mm.unwrap();
        assert_eq!(apart(&own.metrics), 0.0, "{axis}");
        assert!(apart(&theirs.metrics) > 0.0, "{axis}");
        assert!(a.max_following_error_mm.is_some());
    }
}
