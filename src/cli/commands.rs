//! Each command: its arguments in, its report out. Progress goes to the error stream as the
//! command works; everything it found is in the report.

use super::args::{BodeLoop, Command, MachineCommand};
use super::show::progress_bar;
use cncsim::command::{Report, Stream};
use cncsim::machine::{DrivesFile, Machine};
use cncsim::program::{
    inspect, parse_tool_table, FeedRule, InspectOptions, LengthUnit, ProgramError, ProgramErrors,
    ReadOptions,
};
use cncsim::scenario::{
    check_scenarios, folder_name, outcome_text, scenario_files, tune_scenario, Assembly,
    DriveFileDraft, Override, PlanOutput, ProfileName, RunError, RunOptions, RunOutput, Scenario,
    ScenarioRun, TuneError, TuneOptions,
};
use cncsim::sim::LaneKind;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// The bundled scenario `cncsim` runs without arguments.
const DEFAULT_SCENARIO: &str = "scenarios/xyz_circle_5mms.toml";

/// Why a command gave no report.
pub enum Refused {
    /// Its input is wrong (exit status 2).
    BadInput(String),
    /// It ran and failed without a report (exit status 1).
    Failed(String),
}

impl<E: std::fmt::Display> From<E> for Refused {
    fn from(error: E) -> Self {
        Refused::BadInput(error.to_string())
    }
}

/// A command's report and whether `--json` was asked for.
pub type Shown = (Box<dyn Report>, bool);

/// Runs the command (`None`: the bundled scenario). `interrupted` is set by Ctrl-C: a running
/// simulation stops at its next progress report and still writes everything it computed.
pub fn dispatch(command: Option<Command>, interrupted: &AtomicBool) -> Result<Shown, Refused> {
    let text = |report: Box<dyn Report>| Ok((report, false));
    match command {
        None => {
            let scenario = default_scenario();
            eprintln!(
                "running the bundled scenario {} (see `cncsim --help` for more)",
                scenario.display()
            );
            text(Box::new(run(&scenario, None, interrupted)?))
        }
        Some(Command::Run { scenario, out }) => text(Box::new(run(&scenario, out, interrupted)?)),
        Some(Command::Check { scenarios, out }) => {
            text(Box::new(check(&scenarios, out, interrupted)?))
        }
        Some(Command::Plan {
            scenario,
            profile,
            csv,
            rrd,
        }) => text(Box::new(plan(&scenario, profile, csv, rrd)?)),
        Some(Command::Ballbar {
            scenario,
            radius_mm,
            feed_mm_min,
            plane,
            center_mm,
            overshoot_deg,
            json,
            out,
        }) => {
            let test = BallbarArgs {
                radius_mm,
                feed_mm_min,
                plane,
                center_mm,
                overshoot_deg,
            };
            Ok((Box::new(ballbar(&scenario, test, out, interrupted)?), json))
        }
        Some(Command::Bode {
            scenario,
            axis,
            lp,
            from,
            to,
            per_decade,
            analytic,
            json,
            out,
        }) => {
            let lp = match lp {
                BodeLoop::Plant => cncsim::frequency::Loop::Plant,
                BodeLoop::Velocity => cncsim::frequency::Loop::Velocity,
                BodeLoop::Position => cncsim::frequency::Loop::Position,
            };
            let mut options = cncsim::scenario::BodeOptions::new(&axis, lp);
            options.from = from;
            options.to = to;
            options.per_decade = per_decade;
            options.plant = lane(analytic);
            Ok((Box::new(bode(&scenario, &options, out, interrupted)?), json))
        }
        Some(Command::ExportFmu {
            scenario,
            out,
            json,
        }) => Ok((Box::new(export_fmu(&scenario, &out)?), json)),
        Some(Command::Inspect {
            program,
            euclidean_feed,
            lenient,
            optimise_pen_up,
            strict,
            no_hatch,
            page,
            feed,
            cl_writer,
            all,
            tool_table,
        }) => {
            let mut options = ReadOptions::default();
            options.apt.writer = cl_writer;
            if let Some(table) = tool_table {
                options.gcode.tools = std::fs::read_to_string(&table)
                    .map_err(|error| {
                        ProgramErrors::single(ProgramError::new(
                            &table,
                            None,
                            format!("could not read the tool table: {error}"),
                        ))
                    })
                    .and_then(|text| parse_tool_table(&text, &table, LengthUnit::Millimetre))?;
            }
            if euclidean_feed {
                options.feed_rule = FeedRule::EuclideanAllAxes;
            }
            options.hpgl.lenient = lenient;
            options.hpgl.optimise_pen_up = optimise_pen_up;
            options.hpgl.strict = strict;
            options.apt.strict = strict;
            options.hpgl.hatch_fills = !no_hatch;
            options.hpgl.page = page;
            if let Some(feed) = feed {
                let (lo, hi) = cncsim::scenario::limits::SPEED_MM_S;
                if !(lo..=hi).contains(&feed) {
                    return Err(ProgramErrors::single(ProgramError::new(
                        &program,
                        None,
                        format!("--feed {feed}: expected a feed from {lo} to {hi} mm/s"),
                    ))
                    .into());
                }
                options.apt.default_feed = Some(feed * 1e-3);
            }
            let listing = InspectOptions {
                list_limit: if all {
                    usize::MAX
                } else {
                    InspectOptions::default().list_limit
                },
            };
            text(Box::new(inspect(&program, &options, &listing)?))
        }
        Some(Command::Ab {
            scenario,
            other,
            a_overrides,
            b_overrides,
            out,
        }) => text(Box::new(ab(
            &scenario,
            other.as_deref(),
            &a_overrides,
            &b_overrides,
            out,
            interrupted,
        )?)),
        Some(Command::Tune {
            scenario,
            axis,
            analytic,
            linear,
            json,
            cascade: true,
            velocity_bandwidth_hz,
            ..
        }) => {
            let scenario = scenario_to_tune(&scenario, linear)?;
            let machine = cncsim::scenario::machine_for(&scenario)?;
            let report = cncsim::scenario::tune_cascade(
                &scenario,
                machine,
                &axis,
                velocity_bandwidth_hz,
                lane(analytic),
            )?;
            Ok((Box::new(report), json))
        }
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
            let report = tune(&scenario, options, step_deg.to_radians(), analytic, linear)?;
            Ok((Box::new(report), json))
        }
        Some(Command::Machine {
            action: MachineCommand::Check { urdf, json },
        }) => Ok((Box::new(cncsim::scenario::check_machine(&urdf)?), json)),
        Some(Command::Machine {
            action: MachineCommand::Init { urdf, out, force },
        }) => {
            let text = cncsim::scenario::drive_file_template(&urdf)?;
            let out = out.unwrap_or_else(|| DrivesFile::path_for(&urdf));
            if out != Path::new("-") && out.exists() && !force {
                return Err(Refused::BadInput(format!(
                    "{}: exists already; --force replaces it, --out writes elsewhere",
                    out.display()
                )));
            }
            Ok((Box::new(DriveFileDraft { urdf, text, out }), false))
        }
        Some(Command::Machine {
            action: MachineCommand::Expand { xacro },
        }) => {
            let roots = cncsim::machine::package_search_roots(&[]);
            let urdf = cncsim::machine::xacro::expand(&xacro, &roots)?;
            Ok((Box::new(Expanded(urdf)), false))
        }
        Some(Command::Dynamics {
            urdf,
            q,
            qd,
            qdd,
            gravity,
            json,
        }) => {
            let &[gx, gy, gz] = gravity.as_slice() else {
                return Err(Refused::BadInput(format!(
                    "--gravity takes 3 values (x,y,z in m/s²), got {}",
                    gravity.len()
                )));
            };
            let tree = cncsim::machine::load_urdf(&urdf)?;
            let gravity = nalgebra::Vector3::new(gx, gy, gz);
            let report = cncsim::dynamics::DynamicsReport::evaluate(&tree, gravity, &q, &qd, &qdd)
                .map_err(|e| Refused::BadInput(format!("{}: {e}", urdf.display())))?;
            Ok((Box::new(report), json))
        }
        Some(Command::Sweep {
            sweep,
            shard,
            inputs: true,
            ..
        }) => {
            let sweep = cncsim::sweep::Sweep::load(&sweep)?;
            let shard = shard
                .as_deref()
                .map(cncsim::sweep::parse_shard)
                .transpose()?;
            let (_, jobs) = cncsim::sweep::run_sweep(&sweep, Path::new("."), shard);
            // The sweep file first: a worker is told where it lies among the others.
            let mut files = vec![cncsim::sweep::runner::absolute_as_named(&sweep.path)];
            files.extend(cncsim::sweep::input_files(&jobs)?);
            text(Box::new(InputFiles(files)))
        }
        Some(Command::Sweep {
            sweep,
            jobs,
            shard,
            out,
            run_timeout_s,
            resume,
            inputs: false,
        }) => text(Box::new(self::sweep(
            &sweep,
            jobs,
            shard.as_deref(),
            out,
            run_timeout_s,
            resume,
            interrupted,
        )?)),
        Some(Command::Merge { dirs, out }) => {
            let results = cncsim::sweep::merge(&dirs)?;
            text(Box::new(cncsim::sweep::MergeOutput {
                results,
                folders: dirs.len(),
                out,
            }))
        }
        Some(Command::Calibrate {
            spec,
            jobs,
            out,
            write,
            resume,
        }) => text(Box::new(calibrate(
            &spec,
            jobs,
            out,
            (write, resume),
            interrupted,
        )?)),
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

fn lane(analytic: bool) -> LaneKind {
    if analytic {
        LaneKind::Analytic
    } else {
        LaneKind::Physics
    }
}

/// Values that loaded but look wrong, as compilers print warnings.
fn print_warnings(warnings: &[cncsim::diagnostics::FileError]) {
    for w in warnings {
        eprintln!("warning: {w}");
    }
}

fn run(
    path: &Path,
    out: Option<PathBuf>,
    interrupted: &AtomicBool,
) -> Result<ScenarioRun, Refused> {
    let scenario = Scenario::load(path)?;
    print_warnings(&scenario.warnings);
    let out = out.unwrap_or_else(|| Path::new("out").join(folder_name(&scenario.name)));
    let output = run_with_bar(&scenario, &out, interrupted)?;
    Ok(ScenarioRun {
        path: scenario.path,
        output,
    })
}

/// Runs a scenario, with a progress bar once it takes longer than a moment.
fn run_with_bar(
    scenario: &Scenario,
    out: &Path,
    interrupted: &AtomicBool,
) -> Result<RunOutput, RunError> {
    let bar = progress_bar(None);
    bar.set_message(scenario.name.clone());
    let started = std::time::Instant::now();
    let mut progress = |done: usize, total: usize| {
        if started.elapsed() > Duration::from_millis(300) {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        }
        !interrupted.load(Ordering::Relaxed)
    };
    let result = Assembly::new(scenario)
        .and_then(|assembly| assembly.run(RunOptions::write_to(out).progress(&mut progress)));
    bar.finish_and_clear();
    result
}

fn check(
    paths: &[PathBuf],
    out: Option<PathBuf>,
    interrupted: &AtomicBool,
) -> Result<cncsim::scenario::CheckReport, Refused> {
    let files = scenario_files(paths)?;
    let root = out.unwrap_or_else(|| PathBuf::from("out"));
    Ok(check_scenarios(
        &files,
        &root,
        &mut |scenario, out| run_with_bar(scenario, out, interrupted),
        &mut |stream, line| match stream {
            Stream::Out => println!("{line}"),
            Stream::Err => eprintln!("{line}"),
        },
    ))
}

/// `export-fmu`: the scenario's plant as an FMI 3.0 co-simulation FMU.
fn export_fmu(scenario: &Path, out: &Path) -> Result<ExportFmuReport, Refused> {
    let s = Scenario::load(scenario)?;
    let text = std::fs::read_to_string(scenario)?;
    let assembly = Assembly::new(&s)?;
    let library = cncsim::fmi::export::find_library().map_err(Refused::Failed)?;
    let exported = cncsim::fmi::export::export(&s, &text, &assembly, &library, out)
        .map_err(|e| Refused::BadInput(format!("{}: {e}", scenario.display())))?;
    Ok(ExportFmuReport(exported))
}

/// What `machine expand` wrote: the URDF of a xacro file.
struct Expanded(String);

impl Report for Expanded {
    fn text(&self) -> String {
        self.0.clone()
    }
}

/// What `sweep --inputs` found: the files the sweep reads.
struct InputFiles(Vec<PathBuf>);

impl Report for InputFiles {
    fn text(&self) -> String {
        self.0
            .iter()
            .map(|f| format!("{}\n", f.display()))
            .collect()
    }

    fn json(&self) -> Option<serde_json::Value> {
        Some(serde_json::json!(self.0))
    }
}

/// What `export-fmu` wrote.
struct ExportFmuReport(cncsim::fmi::export::Exported);

impl Report for ExportFmuReport {
    fn write(&self) -> Result<Vec<PathBuf>, cncsim::command::WriteError> {
        Ok(vec![self.0.fmu.clone()])
    }

    fn text(&self) -> String {
        let e = &self.0;
        format!(
            "{}: FMI 3.0 co-simulation FMU of the plant of '{}'\n  step: {} ms (the servo period); {} ticks from t = {:.6} s (settle and approach before the program at t = 0)\n  inputs: {}\n  outputs: {}\n  resources: {}\n  library: {}\n",
            e.fmu.display(),
            e.model_name,
            e.servo_period * 1e3,
            e.ticks,
            e.start_time,
            e.inputs.join(", "),
            e.outputs.join(", "),
            e.resources.join(", "),
            e.library.display()
        )
    }

    fn json(&self) -> Option<serde_json::Value> {
        serde_json::to_value(&self.0).ok()
    }
}

fn plan(
    path: &Path,
    profile: Option<ProfileName>,
    csv: Option<PathBuf>,
    rrd: Option<PathBuf>,
) -> Result<PlanOutput, Refused> {
    let scenario = Scenario::load(path)?;
    Ok(PlanOutput {
        report: cncsim::scenario::plan_scenario(&scenario, profile)?,
        name: scenario.name,
        csv,
        rrd,
    })
}

fn ab(
    a: &Path,
    b: Option<&Path>,
    a_overrides: &[String],
    b_overrides: &[String],
    out: Option<PathBuf>,
    interrupted: &AtomicBool,
) -> Result<cncsim::scenario::AbOutput, Refused> {
    let parse = |flag: &str, texts: &[String]| -> Result<Vec<Override>, String> {
        texts
            .iter()
            .map(|t| Override::parse(t).map_err(|e| format!("{flag} {e}")))
            .collect()
    };
    let (mut oa, mut ob) = (parse("--a", a_overrides)?, parse("--b", b_overrides)?);
    let (mut flag_a, mut flag_b) = ("--a", "--b");
    if b.is_none() && oa.is_empty() && ob.is_empty() {
        // One file and no overrides: the variants the file declares in [ab].
        let Some(declared) = Scenario::load(a)?.ab else {
            return Err(Refused::BadInput(format!("{}: ab with one scenario needs overrides to tell the variants apart: --a KEY=VALUE… and/or --b KEY=VALUE…, an [ab] table in the file, or a second scenario file", a.display())));
        };
        let parsed = |list: &[String]| -> Vec<Override> {
            list.iter()
                .map(|o| Override::parse(o).expect("checked when the scenario was read"))
                .collect()
        };
        (oa, ob) = (parsed(&declared.a), parsed(&declared.b));
        (flag_a, flag_b) = ("[ab] a:", "[ab] b:");
    }
    let sa = Scenario::load_with_overrides(a, &oa, flag_a)?;
    let sb = Scenario::load_with_overrides(b.unwrap_or(a), &ob, flag_b)?;
    let out = out.unwrap_or_else(|| {
        Path::new("out").join(folder_name(&format!("ab_{}_vs_{}", sa.name, sb.name)))
    });
    let mut progress = |_: usize, _: usize| !interrupted.load(Ordering::Relaxed);
    Ok(cncsim::scenario::run_ab(&sa, &sb, &out, &mut progress)?)
}

/// The scenario a tune command designs on; `linear`: without friction and backlash, as the
/// source paper designed its gains.
fn scenario_to_tune(path: &Path, linear: bool) -> Result<Scenario, cncsim::diagnostics::FileError> {
    let mut scenario = Scenario::load(path)?;
    if linear {
        scenario.mechanics.friction = false;
        scenario.mechanics.backlash = false;
    }
    Ok(scenario)
}

fn tune(
    path: &Path,
    mut options: TuneOptions,
    rotary_step: f64,
    analytic: bool,
    linear: bool,
) -> Result<cncsim::scenario::TuneReport, Refused> {
    let scenario = scenario_to_tune(path, linear)?;
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
    tune_scenario(&scenario, &options, lane(analytic), &mut progress).map_err(|e| match e {
        TuneError::Search { .. } => Refused::Failed(e.to_string()),
        e => Refused::BadInput(e.to_string()),
    })
}

/// Worker threads: as asked, or one per core.
fn threads(jobs: Option<usize>) -> Result<usize, Refused> {
    match jobs {
        Some(0) => Err(Refused::BadInput("--jobs 0: expected at least 1".into())),
        Some(n) => Ok(n),
        None => Ok(std::thread::available_parallelism().map_or(1, |n| n.get())),
    }
}

/// Off a terminal, a sweep's progress line comes at most this often.
const PLAIN_LINE_EVERY: std::time::Duration = std::time::Duration::from_secs(10);

fn sweep(
    path: &Path,
    jobs: Option<usize>,
    shard: Option<&str>,
    out: Option<PathBuf>,
    run_timeout_s: Option<f64>,
    resume: bool,
    interrupted: &AtomicBool,
) -> Result<cncsim::sweep::SweepOutput, Refused> {
    use cncsim::sweep::{
        execute, parse_shard, read_record, run_list_digest, run_sweep, Progress, Sweep,
        SweepResults,
    };
    let mut sweep = Sweep::load(path)?;
    sweep.run_timeout_s = run_timeout_s.or(sweep.run_timeout_s);
    let shard = shard.map(parse_shard).transpose()?;
    let threads = threads(jobs)?;
    let out = out.unwrap_or_else(|| {
        let mut name = format!("sweep_{}", folder_name(&sweep.name));
        if let Some((k, n)) = shard {
            name += &format!("_shard_{k}_of_{n}");
        }
        Path::new("out").join(name)
    });
    let (runs, all_jobs) = run_sweep(&sweep, &out, shard);
    // The folder's sweep is known by the digest of its run list: a resume goes on with its own
    // sweep only, and reruns only the runs without a whole record.
    let digest_path = out.join("sweep_digest.txt");
    let digest = run_list_digest(&all_jobs);
    let resuming = match std::fs::read_to_string(&digest_path) {
        Ok(found) if resume && found.trim() != digest => {
            return Err(Refused::BadInput(format!(
                "{}: --resume: the folder holds the runs of another sweep (or of this one with other scenarios, changes or shard): its run list's digest is {}, this sweep's {digest}; resume with the sweep that wrote it, or give another --out",
                out.display(),
                found.trim()
            )))
        }
        Ok(_) => resume,
        Err(_) => false,
    };
    let (mut recorded, mut jobs) = (Vec::new(), Vec::new());
    for job in &all_jobs {
        match resuming.then(|| read_record(job)).flatten() {
            Some(record) => recorded.push(record),
            None => jobs.push(job.clone()),
        }
    }
    std::fs::create_dir_all(&out)
        .and_then(|()| std::fs::write(&digest_path, &digest))
        .map_err(|e| Refused::BadInput(format!("{}: {e}", digest_path.display())))?;
    if resume {
        eprintln!(
            "resuming: {} of {} runs have a record in {}; running the other {}",
            recorded.len(),
            all_jobs.len(),
            out.display(),
            jobs.len()
        );
    }
    eprintln!(
        "sweep {}: {} runs ({} scenarios × {} variants × {} points{}) on {threads} threads",
        sweep.name,
        all_jobs.len(),
        sweep.scenarios.len(),
        sweep.variants.len(),
        sweep.points().len(),
        shard.map_or(String::new(), |(k, n)| format!(", shard {k}/{n}"))
    );
    let progress = Progress {
        total: jobs.len(),
        ..Default::default()
    };
    let bar = progress_bar(Some("runs"));
    bar.set_length(jobs.len() as u64);
    // Off a terminal (CI logs, batch jobs) the bar is hidden: plain lines instead, at most one
    // every PLAIN_LINE_EVERY and one at the end.
    let terminal = std::io::stderr().is_terminal();
    let started = std::time::Instant::now();
    let last_line: std::sync::Mutex<Option<std::time::Instant>> = Default::default();
    let run_name = |index: usize| {
        jobs.iter()
            .find(|job| job.index == index)
            .and_then(|job| job.out_dir.file_name())
            .map_or(index.to_string(), |name| {
                name.to_string_lossy().into_owned()
            })
    };
    let on_change = |p: &Progress| {
        let done = p.done.load(Ordering::Relaxed);
        let failed = p.failed.load(Ordering::Relaxed);
        let last_failed = p
            .last_failed
            .lock()
            .ok()
            .and_then(|last| *last)
            .map(run_name);
        let failed_text = match &last_failed {
            Some(name) => format!("{failed} failed, the last {name}"),
            None => format!("{failed} failed"),
        };
        if terminal {
            bar.set_position(done as u64);
            bar.set_message(format!(
                "({} running, {failed_text})",
                p.running.load(Ordering::Relaxed)
            ));
            return;
        }
        let Ok(mut last) = last_line.lock() else {
            return;
        };
        let now = std::time::Instant::now();
        let finished = done == p.total;
        if !finished && last.is_some_and(|at| now - at < PLAIN_LINE_EVERY) {
            return;
        }
        *last = Some(now);
        let elapsed = started.elapsed().as_secs_f64();
        let left = if done == 0 || finished {
            String::new()
        } else {
            format!(
                ", about {:.0} s left",
                elapsed / done as f64 * (p.total - done) as f64
            )
        };
        eprintln!(
            "sweep: {done} of {} runs done, {failed_text}; {elapsed:.0} s elapsed{left}",
            p.total
        );
    };
    let (results, plans) = execute(&jobs, threads, interrupted, &progress, &on_change);
    bar.finish_and_clear();
    let mut results = results;
    results.extend(recorded);
    results.sort_by_key(|result| result.index);
    Ok(cncsim::sweep::SweepOutput {
        results: SweepResults::new(&sweep, &runs, &results, shard),
        out,
        jobs: all_jobs.len(),
        done: results.len(),
        plans,
        interrupted: interrupted.load(Ordering::Relaxed),
        any_failed: results
            .iter()
            .any(|r| r.error.is_some() || r.stopped.is_some()),
    })
}

fn calibrate(
    path: &Path,
    jobs: Option<usize>,
    out: Option<PathBuf>,
    (write, resume): (bool, bool),
    interrupted: &AtomicBool,
) -> Result<cncsim::sweep::calibrate::CalibrationOutput, Refused> {
    use cncsim::sweep::calibrate::{
        calibrate, predict, Calibration, CalibrationOutput, CalibrationProgress, EvaluationLog,
    };
    let cal = Calibration::load(path)?;
    let threads = threads(jobs)?;
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
    // Every candidate is logged as it finishes; a resume answers those from the log.
    let log = match resume
        .then(|| EvaluationLog::resume(&cal, &out))
        .transpose()?
    {
        Some(Some(log)) => {
            eprintln!(
                "resuming: {} evaluations in {}; the search replays them and goes on",
                log.earlier(),
                out.join(cncsim::sweep::calibrate::LOG_FILE).display()
            );
            log
        }
        Some(None) => {
            eprintln!(
                "resuming: {} holds no evaluation log; starting",
                out.display()
            );
            EvaluationLog::start(&cal, &out)?
        }
        None => EvaluationLog::start(&cal, &out)?,
    };
    let bar = progress_bar(Some("candidates"));
    bar.set_length(cal.max_evaluations as u64 + 1);
    let on_change = |p: &CalibrationProgress| {
        bar.set_position(p.evaluations.load(Ordering::Relaxed) as u64 + 1);
        if let Some(b) = *p.best.lock().expect("no panics while held") {
            bar.set_message(format!("(best cost {b:.4})"));
        }
    };
    let progress = CalibrationProgress::default();
    let result = calibrate(
        &cal,
        &out,
        &log,
        threads,
        interrupted,
        &progress,
        &on_change,
    );
    bar.finish_and_clear();
    let result = result?;
    let stopped = interrupted.load(Ordering::Relaxed);
    let runs = match &result.best {
        Some(best) if !stopped => {
            eprintln!("running the scenarios with the best values …");
            Some(predict(
                &cal,
                &best.values,
                &out.join("predictions"),
                threads,
                interrupted,
            ))
        }
        _ => None,
    };
    Ok(CalibrationOutput::new(
        &cal, result, runs, &out, write, stopped,
    ))
}

/// The test `cncsim ballbar` is asked for, as given on the command line.
struct BallbarArgs {
    radius_mm: Vec<f64>,
    feed_mm_min: Vec<f64>,
    plane: Option<cncsim::scenario::BallbarPlane>,
    center_mm: Option<Vec<f64>>,
    overshoot_deg: Option<f64>,
}

fn ballbar(
    path: &Path,
    test: BallbarArgs,
    out: Option<PathBuf>,
    interrupted: &AtomicBool,
) -> Result<cncsim::scenario::BallbarOutput, Refused> {
    if let Some(o) = test.overshoot_deg.filter(|o| !(*o > 0.0 && *o <= 180.0)) {
        return Err(Refused::BadInput(format!(
            "--overshoot-deg {o}: must be more than 0 and at most 180"
        )));
    }
    let scenario = Scenario::load(path)?;
    let (own_plane, own_centre, own_overshoot) =
        cncsim::scenario::default_plane_centre_overshoot(&scenario);
    print_warnings(&scenario.warnings);
    let (radius, feed) = cncsim::scenario::default_radius_and_feed(&scenario);
    for (flag, values) in [
        ("--radius-mm", &test.radius_mm),
        ("--feed-mm-min", &test.feed_mm_min),
    ] {
        if let Some(v) = values.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(Refused::BadInput(format!(
                "{flag} {v}: must be a positive number"
            )));
        }
    }
    let centre = match test.center_mm.as_deref() {
        None => own_centre,
        Some(&[x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => {
            Some([x * 1e-3, y * 1e-3, z * 1e-3])
        }
        Some(v) => {
            return Err(Refused::BadInput(format!(
                "--center-mm takes 3 finite values (x,y,z in mm), got {v:?}"
            )))
        }
    };
    let given_or = |values: &[f64], to_si: fn(f64) -> f64, default: f64| -> Vec<f64> {
        if values.is_empty() {
            vec![default]
        } else {
            values.iter().map(|&v| to_si(v)).collect()
        }
    };
    let options = cncsim::scenario::BallbarOptions {
        radii: given_or(&test.radius_mm, |r| r * 1e-3, radius),
        feeds: given_or(&test.feed_mm_min, |f| f / 60e3, feed),
        plane: test.plane.map_or(own_plane, Into::into),
        centre,
        overshoot: test.overshoot_deg.map_or(own_overshoot, f64::to_radians),
    };
    let out = out.unwrap_or_else(|| {
        Path::new("out").join(folder_name(&format!("ballbar_{}", scenario.name)))
    });
    let mut progress = |_: usize, _: usize| !interrupted.load(Ordering::Relaxed);
    let report = cncsim::scenario::run_ballbar(&scenario, &options, &out, &mut progress)?;
    Ok(cncsim::scenario::BallbarOutput {
        report,
        path: scenario.path,
        out,
    })
}

fn bode(
    path: &Path,
    options: &cncsim::scenario::BodeOptions,
    out: Option<PathBuf>,
    interrupted: &AtomicBool,
) -> Result<cncsim::scenario::BodeOutput, Refused> {
    let scenario = Scenario::load(path)?;
    print_warnings(&scenario.warnings);
    let out = out.unwrap_or_else(|| {
        Path::new("out").join(folder_name(&format!(
            "bode_{}_{}_{}",
            scenario.name,
            options.axis,
            cncsim::scenario::loop_name(options.lp)
        )))
    });
    let mut progress = |_: usize, _: usize| !interrupted.load(Ordering::Relaxed);
    match cncsim::scenario::run_bode(&scenario, options, &mut progress) {
        Ok(run) => Ok(cncsim::scenario::BodeOutput { run, out }),
        Err(cncsim::scenario::BodeError::Failed(m)) => Err(Refused::Failed(m)),
        Err(e) => Err(Refused::BadInput(e.to_string())),
    }
}
