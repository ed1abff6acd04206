use clap::Parser;
use cncsim::machine::Machine;
use cncsim::program::{
    inspect, parse_tool_table, FeedRule, InspectOptions, LengthUnit, ProgramError, ProgramErrors,
    ReadOptions,
};
use cncsim::report::metrics_table;
use cncsim::scenario::{
    check, folder_name, outcome_text, run_scenario, tune_scenario, Override, PlantKind, RunOutput,
    Scenario, TuneError, TuneOptions,
};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

mod cli;
use cli::{Cli, Command, MachineCommand};

/// The bundled scenario `cncsim` runs without arguments.
const DEFAULT_SCENARIO: &str = "scenarios/xyz_circle_5mms.toml";

/// Set by Ctrl-C: a running simulation stops at its next progress report and still writes
/// everything it computed.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Exit codes: 0 success, 1 a check failed, a run stopped early or a tune found no boundary,
/// 2 bad input.
fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so printing into a closed pipe (`cncsim inspect … | head`) would
    // panic; the default action ends the process quietly, as other command-line tools do.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_DFL at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    // A second Ctrl-C while the first is being handled ends the process the usual way.
    let _ = ctrlc::set_handler(|| {
        if INTERRUPTED.swap(true, Ordering::Relaxed) {
            std::process::exit(130);
        }
    });
    match cli.command {
        None => {
            let scenario = default_scenario();
            eprintln!(
                "running the bundled scenario {} (see `cncsim --help` for more)",
                scenario.display()
            );
            run_one(&scenario, None)
        }
        Some(Command::Run { scenario, out }) => run_one(&scenario, out),
        Some(Command::Sweep {
            sweep,
            jobs,
            shard,
            out,
        }) => sweep_cli(&sweep, jobs, shard.as_deref(), out),
        Some(Command::Merge { dirs, out }) => merge_cli(&dirs, &out),
        Some(Command::Calibrate {
            spec,
            jobs,
            out,
            write,
        }) => calibrate_cli(&spec, jobs, out, write),
        Some(Command::Check { scenarios, out }) => check_all(&scenarios, out),
        Some(Command::Ballbar {
            scenario,
            radius_mm,
            feed_mm_min,
            plane,
            center_mm,
            overshoot_deg,
            json,
            out,
        }) => ballbar_cli(
            &scenario,
            radius_mm,
            feed_mm_min,
            plane,
            center_mm,
            overshoot_deg,
            json,
            out,
        ),
        Some(Command::Plan {
            scenario,
            profile,
            csv,
            rrd,
        }) => plan_one(&scenario, profile, csv, rrd),
        Some(Command::Machine { action }) => machine_cli(action),
        Some(Command::Dynamics {
            urdf,
            q,
            qd,
            qdd,
            gravity,
            json,
        }) => dynamics(&urdf, &q, &qd, &qdd, &gravity, json),
        Some(Command::Ab {
            scenario,
            other,
            a_overrides,
            b_overrides,
            out,
        }) => ab(&scenario, other.as_deref(), &a_overrides, &b_overrides, out),
        Some(Command::Tune {
            scenario,
            axis,
            analytic,
            linear,
            json,
            cascade: true,
            velocity_bandwidth_hz,
            ..
        }) => tune_cascade_cli(
            &scenario,
            &axis,
            velocity_bandwidth_hz,
            analytic,
            linear,
            json,
        ),
        Some(Command::Tune {
            scenario,
            axis,
            step_mm,
            step_deg,
            tolerance,
            trial_s,
            start_gain,
            max_simulations,
            analytic,
            linear,
            json,
            cascade: false,
            ..
        }) => {
            let mut options = TuneOptions::new(&axis, step_mm * 1e-3);
            options.tolerance = tolerance;
            options.trial_time = trial_s;
            options.start_gain = start_gain;
            options.max_simulations = max_simulations;
            tune(
                &scenario,
                options,
                step_deg.to_radians(),
                analytic,
                linear,
                json,
            )
        }
        Some(Command::Inspect {
            program,
            euclidean_feed,
            lenient,
            optimise_pen_up,
            strict,
            no_hatch,
            all,
            tool_table,
        }) => {
            let mut options = ReadOptions::default();
            if let Some(table) = tool_table {
                let tools = std::fs::read_to_string(&table)
                    .map_err(|error| {
                        ProgramErrors::single(ProgramError::new(
                            &table,
                            None,
                            format!("could not read the tool table: {error}"),
                        ))
                    })
                    .and_then(|text| parse_tool_table(&text, &table, LengthUnit::Millimetre));
                match tools {
                    Ok(tools) => options.gcode.tools = tools,
                    Err(e) => return fail_input(&e),
                }
            }
            if euclidean_feed {
                options.feed_rule = FeedRule::EuclideanAllAxes;
            }
            options.hpgl.lenient = lenient;
            options.hpgl.optimise_pen_up = optimise_pen_up;
            options.hpgl.strict = strict;
            options.apt.strict = strict;
            options.hpgl.hatch_fills = !no_hatch;
            let listing = InspectOptions {
                list_limit: if all {
                    usize::MAX
                } else {
                    InspectOptions::default().list_limit
                },
            };
            match inspect(&program, &options, &listing) {
                Ok(report) => {
                    print!("{report}");
                    ExitCode::SUCCESS
                }
                Err(e) => fail_input(&e),
            }
        }
    }
}

fn default_scenario() -> PathBuf {
    let here = PathBuf::from(DEFAULT_SCENARIO);
    if here.is_file() {
        here
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_SCENARIO)
    }
}

fn run_one(path: &Path, out: Option<PathBuf>) -> ExitCode {
    let scenario = match Scenario::load(path) {
        Ok(s) => s,
        Err(e) => return fail_input(&e),
    };
    print_warnings(&scenario.warnings);
    let out = out.unwrap_or_else(|| Path::new("out").join(folder_name(&scenario.name)));
    match execute(&scenario, &out) {
        Ok(run) => {
            print_warnings(&run.warnings);
            print!("{}", metrics_table(&run.metrics));
            for f in &run.files {
                println!("  wrote {}", f.display());
            }
            if let Some(stop) = &run.stop {
                eprintln!("error: {}: {stop}", scenario.path.display());
                return ExitCode::from(1);
            }
            ExitCode::SUCCESS
        }
        Err(e) => fail_input(&e),
    }
}

/// `cncsim ballbar`: checks the numbers, runs the tests, prints the report.
#[allow(clippy::too_many_arguments)]
fn ballbar_cli(
    path: &Path,
    radius_mm: Vec<f64>,
    feed_mm_min: Vec<f64>,
    plane: Option<cncsim::scenario::BallbarPlane>,
    center_mm: Option<Vec<f64>>,
    overshoot_deg: Option<f64>,
    json: bool,
    out: Option<PathBuf>,
) -> ExitCode {
    if let Some(o) = overshoot_deg.filter(|o| !(*o > 0.0 && *o <= 180.0)) {
        return fail_input(&format!(
            "--overshoot-deg {o}: must be more than 0 and at most 180"
        ));
    }
    let scenario = match Scenario::load(path) {
        Ok(s) => s,
        Err(e) => return fail_input(&e),
    };
    let (own_plane, own_centre, own_overshoot) =
        cncsim::scenario::default_plane_centre_overshoot(&scenario);
    print_warnings(&scenario.warnings);
    let (radius, feed) = cncsim::scenario::default_radius_and_feed(&scenario);
    let positive =
        |flag: &str, values: &[f64]| match values.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            Some(v) => Err(format!("{flag} {v}: must be a positive number")),
            None => Ok(()),
        };
    if let Err(e) = positive("--radius-mm", &radius_mm).and(positive("--feed-mm-min", &feed_mm_min))
    {
        return fail_input(&e);
    }
    let centre = match center_mm.as_deref() {
        None => own_centre,
        Some(&[x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => {
            Some([x * 1e-3, y * 1e-3, z * 1e-3])
        }
        Some(v) => {
            return fail_input(&format!(
                "--center-mm takes 3 finite values (x,y,z in mm), got {v:?}"
            ))
        }
    };
    let options = cncsim::scenario::BallbarOptions {
        radii: if radius_mm.is_empty() {
            vec![radius]
        } else {
            radius_mm.iter().map(|r| r * 1e-3).collect()
        },
        feeds: if feed_mm_min.is_empty() {
            vec![feed]
        } else {
            feed_mm_min.iter().map(|f| f / 60e3).collect()
        },
        plane: plane.map_or(own_plane, Into::into),
        centre,
        overshoot: overshoot_deg.map_or(own_overshoot, f64::to_radians),
    };
    let out = out.unwrap_or_else(|| {
        Path::new("out").join(folder_name(&format!("ballbar_{}", scenario.name)))
    });
    let mut progress = |_: usize, _: usize| !INTERRUPTED.load(Ordering::Relaxed);
    let report = match cncsim::scenario::run_ballbar(&scenario, &options, &out, &mut progress) {
        Ok(r) => r,
        Err(e) => return fail_input(&e),
    };
    if json {
        print!("{}", report.json());
    } else {
        print!("{}", report.text());
        for run in &report.runs {
            for f in run
                .files
                .iter()
                .filter(|f| f.extension().is_some_and(|e| e == "png"))
            {
                println!("  wrote {}", f.display());
            }
        }
        println!("  wrote {}", out.join("ballbar.json").display());
        println!("  wrote {}", out.join("ballbar.rrd").display());
    }
    if report.runs.iter().any(|r| !r.completed) {
        eprintln!(
            "error: {}: a ballbar run stopped early (its figures are of what ran)",
            path.display()
        );
        return ExitCode::from(1);
    }
    if report.runs.iter().any(|r| !r.breaches.is_empty()) {
        eprintln!(
            "error: {}: a ballbar figure breaches an [expect] bound",
            path.display()
        );
        return ExitCode::from(1);
    }
    ExitCode::SUCCESS
}

fn plan_one(
    path: &Path,
    profile: Option<cncsim::scenario::ProfileName>,
    csv: Option<PathBuf>,
    rrd: Option<PathBuf>,
) -> ExitCode {
    let scenario = match Scenario::load(path) {
        Ok(s) => s,
        Err(e) => return fail_input(&e),
    };
    let report = match cncsim::scenario::plan_scenario(&scenario, profile) {
        Ok(r) => r,
        Err(e) => return fail_input(&e),
    };
    print!("{}", report.text());
    if let Some(csv) = csv {
        let written = std::fs::File::create(&csv).and_then(|f| {
            let mut w = std::io::BufWriter::new(f);
            cncsim::plan::write_setpoint_stream_csv(
                &mut w,
                report.plan.stream().as_mut(),
                &report.axes,
            )?;
            std::io::Write::flush(&mut w)
        });
        if let Err(e) = written {
            return fail_input(&format!("{}: cannot write: {e}", csv.display()));
        }
        println!("  wrote {}", csv.display());
    }
    if let Some(rrd) = rrd {
        let labels: Vec<cncsim::report::AxisLabel> = report
            .axes
            .iter()
            .map(|a| cncsim::report::AxisLabel {
                name: a.name.clone(),
                rotary: a.kind == cncsim::plan::AxisKind::Rotary,
            })
            .collect();
        if let Err(e) = cncsim::report::write_setpoints_recording(
            &rrd,
            &scenario.name,
            report.plan.stream().as_mut(),
            &labels,
            &report.tool_path,
        ) {
            return fail_input(&e);
        }
        println!("  wrote {}", rrd.display());
    }
    ExitCode::SUCCESS
}

fn dynamics(
    urdf: &Path,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &[f64],
    json: bool,
) -> ExitCode {
    let &[gx, gy, gz] = gravity else {
        return fail_input(&format!(
            "--gravity takes 3 values (x,y,z in m/s²), got {}",
            gravity.len()
        ));
    };
    let tree = match cncsim::machine::load_urdf(urdf) {
        Ok(t) => t,
        Err(e) => return fail_input(&e),
    };
    match cncsim::dynamics::DynamicsReport::evaluate(
        &tree,
        nalgebra::Vector3::new(gx, gy, gz),
        q,
        qd,
        qdd,
    ) {
        Ok(report) if json => {
            println!(
                "{}",
                serde_json::to_string_pretty(&report.to_json()).expect("JSON of numbers")
            );
            ExitCode::SUCCESS
        }
        Ok(report) => {
            print!("{}", report.to_text());
            ExitCode::SUCCESS
        }
        Err(e) => fail_input(&format!("{}: {e}", urdf.display())),
    }
}

fn ab(
    a: &Path,
    b: Option<&Path>,
    a_overrides: &[String],
    b_overrides: &[String],
    out: Option<PathBuf>,
) -> ExitCode {
    let parse = |flag: &str, texts: &[String]| -> Result<Vec<Override>, String> {
        texts
            .iter()
            .map(|t| Override::parse(t).map_err(|e| format!("{flag} {e}")))
            .collect()
    };
    let (mut oa, mut ob) = match (parse("--a", a_overrides), parse("--b", b_overrides)) {
        (Ok(oa), Ok(ob)) => (oa, ob),
        (Err(e), _) | (_, Err(e)) => return fail_input(&e),
    };
    let (mut flag_a, mut flag_b) = ("--a", "--b");
    if b.is_none() && oa.is_empty() && ob.is_empty() {
        // One file and no overrides: the variants the file declares in [ab].
        let declared = match Scenario::load(a) {
            Ok(s) => s.ab,
            Err(e) => return fail_input(&e),
        };
        let Some(declared) = declared else {
            return fail_input(&format!("{}: ab with one scenario needs overrides to tell the variants apart: --a KEY=VALUE… and/or --b KEY=VALUE…, an [ab] table in the file, or a second scenario file", a.display()));
        };
        let parsed = |list: &[String]| -> Vec<Override> {
            list.iter()
                .map(|o| Override::parse(o).expect("checked when the scenario was read"))
                .collect()
        };
        (oa, ob) = (parsed(&declared.a), parsed(&declared.b));
        (flag_a, flag_b) = ("[ab] a:", "[ab] b:");
    }
    let (sa, sb) = match (
        Scenario::load_with_overrides(a, &oa, flag_a),
        Scenario::load_with_overrides(b.unwrap_or(a), &ob, flag_b),
    ) {
        (Ok(sa), Ok(sb)) => (sa, sb),
        (Err(e), _) | (_, Err(e)) => return fail_input(&e),
    };
    let out = out.unwrap_or_else(|| {
        Path::new("out").join(folder_name(&format!("ab_{}_vs_{}", sa.name, sb.name)))
    });
    let mut progress = |_: usize, _: usize| !INTERRUPTED.load(Ordering::Relaxed);
    let (report, ra, rb) = match cncsim::scenario::run_ab(&sa, &sb, &out, &mut progress) {
        Ok(r) => r,
        Err(e) => return fail_input(&e),
    };
    let table = report.markdown();
    print!("{table}");
    let json = serde_json::to_string_pretty(&report).expect("plain numbers");
    for (name, text) in [("ab.md", table), ("ab.json", json + "\n")] {
        let path = out.join(name);
        if let Err(e) = std::fs::write(&path, text) {
            return fail_input(&format!("{}: cannot write: {e}", path.display()));
        }
        println!("  wrote {}", path.display());
    }
    println!("  wrote {}", out.join("ab.rrd").display());
    let plot = out.join("contour_error.png");
    let labels = [format!("A: {}", sa.name), format!("B: {}", sb.name)];
    let curves = [&ra, &rb].map(|r| (r.contour_envelope.times(), r.contour_envelope.values()));
    let series = [0, 1].map(|i| cncsim::report::ContourSeries {
        label: &labels[i],
        time: &curves[i].0,
        contour_error: &curves[i].1,
    });
    if let Err(e) = cncsim::report::write_contour_error_plot(&plot, &series) {
        return fail_input(&e);
    }
    println!("  wrote {}", plot.display());
    for (s, r) in [(&sa, &ra), (&sb, &rb)] {
        if let Some(stop) = &r.stop {
            eprintln!("error: {}: {stop}", s.path.display());
            return ExitCode::from(1);
        }
    }
    ExitCode::SUCCESS
}

/// The scenario a tune command designs on; `linear`: without friction and backlash, as the
/// source paper designed its gains.
fn scenario_to_tune(path: &Path, linear: bool) -> Result<Scenario, cncsim::diagnostics::FileError> {
    let mut scenario = Scenario::load(path)?;
    if linear {
        scenario.friction = false;
        scenario.backlash = false;
    }
    Ok(scenario)
}

fn tune(
    path: &Path,
    mut options: TuneOptions,
    rotary_step: f64,
    analytic: bool,
    linear: bool,
    json: bool,
) -> ExitCode {
    let scenario = match scenario_to_tune(path, linear) {
        Ok(s) => s,
        Err(e) => return fail_input(&e),
    };
    // The step is given per axis kind; the tuner learns the kind from the machine.
    let rotary = Machine::load(&scenario.machine)
        .ok()
        .and_then(|m| {
            let i = m.axis_index(&options.axis)?;
            Some(m.axes[i].is_rotary(&m))
        })
        .unwrap_or(false);
    if rotary {
        options.step = rotary_step;
    }
    let plant = if analytic {
        PlantKind::Analytic
    } else {
        PlantKind::Physics
    };
    let mut progress = |t: &cncsim::tune::Trial| {
        eprintln!(
            "  K = {:.5e}: {}{}",
            t.gain,
            outcome_text(t),
            t.oscillation.ratio.map_or(String::new(), |r| format!(
                ", swing ratio per period {r:.4}"
            ))
        );
    };
    match tune_scenario(&scenario, &options, plant, &mut progress) {
        Ok(report) if json => {
            println!(
                "{}",
                serde_json::to_string_pretty(&report.to_json()).expect("plain values")
            );
            ExitCode::SUCCESS
        }
        Ok(report) => {
            print!("{}", report.text());
            ExitCode::SUCCESS
        }
        Err(e @ TuneError::Search { .. }) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
        Err(e) => fail_input(&e),
    }
}

fn sweep_cli(
    path: &Path,
    jobs: Option<usize>,
    shard: Option<&str>,
    out: Option<PathBuf>,
) -> ExitCode {
    use cncsim::sweep::{
        execute, parse_shard, run_sweep, write_results, Progress, Sweep, SweepResults,
    };
    let sweep = match Sweep::load(path) {
        Ok(s) => s,
        Err(e) => return fail_input(&e),
    };
    let shard = match shard.map(parse_shard).transpose() {
        Ok(s) => s,
        Err(e) => return fail_input(&e),
    };
    let threads =
        jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return fail_input(&"--jobs 0: expected at least 1");
    }
    let out = out.unwrap_or_else(|| {
        let mut name = format!("sweep_{}", folder_name(&sweep.name));
        if let Some((k, n)) = shard {
            name += &format!("_shard_{k}_of_{n}");
        }
        Path::new("out").join(name)
    });
    let (runs, jobs) = run_sweep(&sweep, &out, shard);
    eprintln!(
        "sweep {}: {} runs ({} scenarios × {} variants × {} points{}) on {threads} threads",
        sweep.name,
        jobs.len(),
        sweep.scenarios.len(),
        sweep.variants.len(),
        sweep.points().len(),
        shard.map_or(String::new(), |(k, n)| format!(", shard {k}/{n}"))
    );
    let progress = Progress {
        total: jobs.len(),
        ..Default::default()
    };
    let bar = ProgressBar::new(jobs.len() as u64).with_style(
        ProgressStyle::with_template(
            "{spinner} [{bar:30}] {pos}/{len} runs {msg} {elapsed_precise} eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let on_change = |p: &Progress| {
        bar.set_position(p.done.load(Ordering::Relaxed) as u64);
        bar.set_message(format!(
            "({} running, {} failed)",
            p.running.load(Ordering::Relaxed),
            p.failed.load(Ordering::Relaxed)
        ));
    };
    let (results, plans) = execute(&jobs, threads, &INTERRUPTED, &progress, &on_change);
    bar.finish_and_clear();
    let table = SweepResults::new(&sweep, &runs, &results, shard);
    match write_results(&table, &out) {
        Ok(files) => {
            print!("{}", table.summary());
            eprintln!("{} plans made for {} runs", plans, results.len());
            for f in files {
                println!("  wrote {}", f.display());
            }
        }
        Err(e) => return fail_input(&e),
    }
    if INTERRUPTED.load(Ordering::Relaxed) {
        eprintln!(
            "interrupted: {} of {} runs done; the files hold them",
            results.len(),
            jobs.len()
        );
        return ExitCode::from(130);
    }
    if results
        .iter()
        .any(|r| r.error.is_some() || r.stopped.is_some())
    {
        return ExitCode::from(1);
    }
    ExitCode::SUCCESS
}

fn calibrate_cli(path: &Path, jobs: Option<usize>, out: Option<PathBuf>, write: bool) -> ExitCode {
    use cncsim::sweep::calibrate::{
        calibrate, predict, predictions_markdown, write_back, Calibration, CalibrationProgress,
    };
    let cal = match Calibration::load(path) {
        Ok(c) => c,
        Err(e) => return fail_input(&e),
    };
    let threads =
        jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return fail_input(&"--jobs 0: expected at least 1");
    }
    let out = out.unwrap_or_else(|| {
        Path::new("out").join(format!("calibration_{}", folder_name(&cal.name)))
    });
    eprintln!(
        "calibration {}: {} parameters, {} targets, CMA-ES population {}, up to {} candidates on {threads} threads",
        cal.name,
        cal.parameters.len(),
        cal.targets.len(),
        cal.population,
        cal.max_evaluations
    );
    let bar = ProgressBar::new(cal.max_evaluations as u64 + 1).with_style(
        ProgressStyle::with_template(
            "{spinner} [{bar:30}] {pos}/{len} candidates {msg} {elapsed_precise} eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let on_change = |p: &CalibrationProgress| {
        bar.set_position(p.evaluations.load(Ordering::Relaxed) as u64 + 1);
        if let Some(b) = *p.best.lock().expect("no panics while held") {
            bar.set_message(format!("(best cost {b:.4})"));
        }
    };
    let progress = CalibrationProgress::default();
    let result = match calibrate(&cal, &out, threads, &INTERRUPTED, &progress, &on_change) {
        Ok(r) => r,
        Err(e) => {
            bar.finish_and_clear();
            return fail_input(&e);
        }
    };
    bar.finish_and_clear();
    let mut report = result.markdown(&cal);
    let mut files = Vec::new();
    let written = (|| -> std::io::Result<()> {
        std::fs::create_dir_all(&out)?;
        let json = serde_json::to_string_pretty(&result).map_err(std::io::Error::other)?;
        for (name, text) in [
            ("evaluations.json", json),
            ("evaluations.csv", result.csv()),
        ] {
            std::fs::write(out.join(name), text)?;
            files.push(out.join(name));
        }
        Ok(())
    })();
    if let Err(e) = written {
        return fail_input(&format!("{}: {e}", out.display()));
    }
    if result.plot(&out.join("convergence.png")).is_ok() {
        files.push(out.join("convergence.png"));
    }
    let mut status = ExitCode::SUCCESS;
    match &result.best {
        Some(best) if !INTERRUPTED.load(Ordering::Relaxed) => {
            eprintln!("running the scenarios with the best values …");
            let runs = predict(
                &cal,
                &best.values,
                &out.join("predictions"),
                threads,
                &INTERRUPTED,
            );
            report += &format!(
                "\n## With the best values\n\nRecordings in `predictions/<scenario>/`. Where the largest error occurs: start (before the axis first caught up with its command), reversal (after the command slowed and turned), stop, or moving.\n\n{}",
                predictions_markdown(&cal, &runs)
            );
            if write {
                match write_back(&cal, &best.values) {
                    Ok(paths) => {
                        for p in paths {
                            eprintln!("  updated {}", p.display());
                        }
                    }
                    Err(e) => {
                        report += &format!("\n**Not written back:** {e}\n");
                        status = ExitCode::from(2);
                        eprintln!("error: {e}");
                    }
                }
            }
        }
        Some(_) => status = ExitCode::from(130),
        None => status = ExitCode::from(1),
    }
    if std::fs::write(out.join("report.md"), &report).is_ok() {
        files.insert(0, out.join("report.md"));
    }
    print!("{report}");
    for f in files {
        println!("  wrote {}", f.display());
    }
    status
}

fn merge_cli(dirs: &[PathBuf], out: &Path) -> ExitCode {
    let merged = match cncsim::sweep::merge(dirs) {
        Ok(m) => m,
        Err(e) => return fail_input(&e),
    };
    match cncsim::sweep::write_results(&merged, out) {
        Ok(files) => {
            println!(
                "merged {} folders: {} of {} runs",
                dirs.len(),
                merged.rows.len(),
                merged.total_runs
            );
            for f in files {
                println!("  wrote {}", f.display());
            }
            ExitCode::SUCCESS
        }
        Err(e) => fail_input(&e),
    }
}

fn tune_cascade_cli(
    path: &Path,
    axis: &str,
    bandwidth_hz: Option<f64>,
    analytic: bool,
    linear: bool,
    json: bool,
) -> ExitCode {
    let scenario = match scenario_to_tune(path, linear) {
        Ok(s) => s,
        Err(e) => return fail_input(&e),
    };
    let machine = match cncsim::scenario::machine_for(&scenario) {
        Ok(m) => m,
        Err(e) => return fail_input(&e),
    };
    let plant = if analytic {
        PlantKind::Analytic
    } else {
        PlantKind::Physics
    };
    match cncsim::scenario::tune_cascade(&scenario, machine, axis, bandwidth_hz, plant) {
        Ok(report) if json => {
            println!(
                "{}",
                serde_json::to_string_pretty(&report).expect("plain values")
            );
            ExitCode::SUCCESS
        }
        Ok(report) => {
            print!("{}", report.text());
            ExitCode::SUCCESS
        }
        Err(e) => fail_input(&e),
    }
}

fn check_all(paths: &[PathBuf], out: Option<PathBuf>) -> ExitCode {
    let mut files = Vec::new();
    for p in paths {
        if p.is_dir() {
            match std::fs::read_dir(p) {
                Ok(entries) => {
                    let mut found: Vec<PathBuf> = entries
                        .filter_map(|e| e.ok().map(|e| e.path()))
                        .filter(|f| f.extension().is_some_and(|x| x == "toml"))
                        .collect();
                    found.sort();
                    if found.is_empty() {
                        return fail_input(&format!(
                            "{}: no scenario files (*.toml) in this folder",
                            p.display()
                        ));
                    }
                    files.extend(found);
                }
                Err(e) => return fail_input(&format!("{}: cannot read folder: {e}", p.display())),
            }
        } else {
            files.push(p.clone());
        }
    }
    let root = out.unwrap_or_else(|| PathBuf::from("out"));
    let (mut passed, mut failed, mut skipped) = (0, 0, 0);
    // Bad input anywhere makes the exit status 2 (as for every command), whatever else ran.
    let mut bad_input = false;
    for f in &files {
        let scenario = match Scenario::load(f) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("error: {e}");
                failed += 1;
                bad_input = true;
                continue;
            }
        };
        print_warnings(&scenario.warnings);
        if scenario.actuator.is_none() && scenario.expect.is_empty() {
            println!(
                "SKIP {} (planning scenario: no [actuator] or [controller] to run)",
                f.display()
            );
            skipped += 1;
            continue;
        }
        match execute(&scenario, &root.join(folder_name(&scenario.name))) {
            Ok(run) => {
                print_warnings(&run.warnings);
                let verdict = check(&scenario, &run.metrics_json);
                let stopped = run.stop.is_some();
                if verdict.passed() && !stopped {
                    println!("PASS {} ({} bounds)", f.display(), verdict.checked);
                    passed += 1;
                } else {
                    println!("FAIL {}", f.display());
                    if let Some(stop) = &run.stop {
                        println!("  {stop}");
                    }
                    for b in &verdict.breaches {
                        match b.expectation.at {
                            Some(at) => {
                                println!("  {}:{}:{}: {b}", f.display(), at.line, at.column)
                            }
                            None => println!("  {}: {b}", f.display()),
                        }
                    }
                    failed += 1;
                }
            }
            Err(e) => {
                eprintln!("error: {e}");
                failed += 1;
                bad_input = true;
            }
        }
    }
    println!("{passed} passed, {failed} failed, {skipped} skipped");
    if bad_input {
        ExitCode::from(2)
    } else if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}

/// Values that loaded but look wrong, as compilers print warnings.
fn print_warnings(warnings: &[cncsim::diagnostics::FileError]) {
    for w in warnings {
        eprintln!("warning: {w}");
    }
}

fn execute(scenario: &Scenario, out: &Path) -> Result<RunOutput, cncsim::scenario::RunError> {
    let bar = ProgressBar::new(1).with_style(
        ProgressStyle::with_template(
            "{spinner} {msg} [{bar:30}] {percent:>3}% {elapsed_precise} eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(scenario.name.clone());
    // Only runs longer than a moment show a bar.
    let started = std::time::Instant::now();
    let mut progress = |done: usize, total: usize| {
        if started.elapsed() > Duration::from_millis(300) {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        }
        !INTERRUPTED.load(Ordering::Relaxed)
    };
    let result = run_scenario(scenario, out, &mut progress);
    bar.finish_and_clear();
    result
}

/// `cncsim machine check|init`.
fn machine_cli(action: MachineCommand) -> ExitCode {
    match action {
        MachineCommand::Check { urdf, json } => match cncsim::scenario::check_machine(&urdf) {
            Ok(report) if json => {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&report.json()).expect("JSON of plain values")
                );
                ExitCode::SUCCESS
            }
            Ok(report) => {
                print!("{}", report.text());
                ExitCode::SUCCESS
            }
            Err(e) => fail_input(&e),
        },
        MachineCommand::Init { urdf, out, force } => {
            let text = match cncsim::scenario::drive_file_template(&urdf) {
                Ok(t) => t,
                Err(e) => return fail_input(&e),
            };
            let out = out.unwrap_or_else(|| cncsim::machine::DrivesFile::path_for(&urdf));
            if out == Path::new("-") {
                print!("{text}");
                return ExitCode::SUCCESS;
            }
            if out.exists() && !force {
                return fail_input(&format!(
                    "{}: exists already; --force replaces it, --out writes elsewhere",
                    out.display()
                ));
            }
            if let Err(e) = std::fs::write(&out, text) {
                return fail_input(&format!("{}: cannot write: {e}", out.display()));
            }
            eprintln!(
                "wrote {}: fill in the values marked ASSUMED, then `cncsim machine check {}`",
                out.display(),
                urdf.display()
            );
            ExitCode::SUCCESS
        }
    }
}

fn fail_input(e: &dyn std::fmt::Display) -> ExitCode {
    eprintln!("error: {e}");
    ExitCode::from(2)
}
