//! Calibration: fitting a machine's unknowns (keys of its drives file, link masses, scenario
//! keys) to what was measured on the real machine (figures of a run, or measured traces), by
//! CMA-ES, every generation's candidates run in parallel through the sweep runner.
//!
//! Why CMA-ES: the cost is a handful of simulated figures, discontinuous where friction makes
//! an axis stick, and not differentiable; CMA-ES is the standard derivative-free method for
//! such rugged, ill-conditioned problems of a few dimensions, invariant to how the parameters
//! are scaled, and it evaluates a whole population per generation (λ runs in parallel, where
//! Nelder–Mead evaluates one point at a time). It is seeded, so a calibration gives the same
//! answer every time. (The `cmaes` crate.)
//!
//! The spec (TOML; unknown keys are errors, paths relative to the file):
//!
//! ```toml
//! name = "paper_twin"
//! scenario = "../scenarios/paper_circle_05mms.toml"   # of the targets that name none
//! [parameters]                    # key = { min, max, scale = "linear" | "log", start, step }
//! "drives.axes.x.guide.friction_coefficient" = { min = 0.002, max = 0.1, scale = "log", also = ["drives.axes.y.guide.friction_coefficient"] }
//! "links.z_column.mass" = { min = 2.0, max = 30.0 }
//! "timing.servo_period_ms" = { min = 1.0, max = 20.0, step = 1.0 }
//! [[target]]                      # a figure of metrics.json, measured, with its tolerance
//! metric = "axes.x.max_following_error_mm"
//! measured = 0.61
//! tolerance = 0.1                 # relative: the cost is Σ ((run − measured)/(tolerance·measured))²
//! [[target]]                      # or a measured trace: RMS difference after time alignment
//! trace = "measured.csv"          # a time column (s) and those named in `columns`
//! time_column = "t_s"             # the default
//! columns = { x_actual_mm = "x_mm" }   # the run's trace.csv column = the measured column
//! tolerance_mm = 0.05             # the cost is (RMS / tolerance_mm)²
//! max_shift_s = 0.2               # time alignment searched within ± this
//! [optimizer]
//! seed = 1
//! population = 8
//! max_evaluations = 96
//! sigma = 0.3                     # initial step, in units of each parameter's range
//! [predict]                       # run with the best parameters afterwards, reported
//! scenarios = ["../scenarios/paper_circle_10mms.toml"]
//! ```
//!
//! A parameter may set further keys to the same value (`also`) or be a factor of another
//! parameter (`times = "<key>"`: the value applied is this × that one's, e.g. a static friction
//! coefficient as a multiple of the kinetic one, so the search never proposes μ_s < μ).

use super::file::Change;
use super::runner::{execute, Job, JobResult, Progress};
use super::MachineOverride;
use crate::diagnostics::{read_text, toml_error, FileError, LineColumn};
use crate::report::Metrics;
use crate::scenario::{edit_toml, Override, Scenario};
use crate::sim::Stop;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;
use toml::Spanned;

mod log;
pub use log::{EvaluationLog, LOG_FILE};

/// Most runs a calibration may ask for (evaluations × scenarios).
pub const MAX_CALIBRATION_RUNS: usize = 100_000;
/// Most rows of a measured trace.
pub const MAX_TRACE_ROWS: usize = 10_000_000;
/// The cost of a candidate whose run failed or stopped early: worse than any that ran.
const FAILED: f64 = 1e9;

/// A free parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Parameter {
    /// The key the parameter sets: `drives.<key>`, `links.<link>.mass` or a scenario key.
    pub key: String,
    /// Lower bound of the search, in the key's own unit.
    pub min: f64,
    /// Upper bound of the search, in the key's own unit.
    pub max: f64,
    /// Searched on a log scale (`scale = "log"`; then `min` > 0).
    pub log: bool,
    /// Quantum of the value (e.g. a servo period in whole milliseconds); `None`: continuous.
    pub step: Option<f64>,
    /// Where the search starts; `None`: the middle of the range (geometric on a log scale).
    pub start: Option<f64>,
    /// Further keys set to the same value.
    pub also: Vec<String>,
    /// The value applied is this parameter × that one's (e.g. μ_s as a multiple of μ).
    pub times: Option<String>,
}

/// A measured trace: times and the measured columns, in the order of the target's `columns`.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredTrace {
    /// Sample times (s), rising.
    pub t_s: Vec<f64>,
    /// Each measured column's samples, one per time, in the units of the file.
    pub columns: Vec<Vec<f64>>,
}

/// What a run must reproduce.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// A figure of the run's `metrics.json` against its measured value; the cost term is
    /// ((run − measured)/(tolerance·measured))².
    Metric {
        /// The scenario the run simulates.
        scenario: PathBuf,
        /// The `metrics.json` key, dotted (e.g. `axes.x.max_following_error_mm`).
        metric: String,
        /// The measured value, in the metric's unit (not zero).
        measured: f64,
        /// Relative tolerance.
        tolerance: f64,
    },
    /// A measured trace the run's `trace.csv` must follow; the cost term is
    /// (RMS difference / `tolerance_mm`)².
    Trace {
        /// The scenario the run simulates (with its `trace.csv` written).
        scenario: PathBuf,
        /// The measured CSV file.
        trace: PathBuf,
        /// (run trace.csv column, measured column).
        columns: Vec<(String, String)>,
        /// The measured trace as read.
        measured: MeasuredTrace,
        /// The RMS difference that costs 1 (mm).
        tolerance_mm: f64,
        /// Time shifts between run and measurement searched within ± this (s, 0 to 60).
        max_shift_s: f64,
    },
}

impl Target {
    fn scenario(&self) -> &Path {
        match self {
            Target::Metric { scenario, .. } | Target::Trace { scenario, .. } => scenario,
        }
    }

    /// The target's name in reports: its metric key, or `RMS to <file> (mm)` for a trace.
    pub fn name(&self) -> String {
        match self {
            Target::Metric { metric, .. } => metric.clone(),
            Target::Trace { trace, .. } => format!(
                "RMS to {} (mm)",
                trace
                    .file_name()
                    .map_or(String::new(), |f| f.to_string_lossy().into_owned())
            ),
        }
    }
}

/// A validated calibration spec.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The calibration's name: the spec's `name`, or else the file's stem.
    pub name: String,
    /// The spec file.
    pub path: PathBuf,
    /// The free parameters, ordered by key.
    pub parameters: Vec<Parameter>,
    /// What the runs must reproduce; the cost is the sum of their terms.
    pub targets: Vec<Target>,
    /// Seed of CMA-ES (`optimizer.seed`, default 0).
    pub seed: u64,
    /// Candidates per generation, λ (default 4 + ⌊3 ln n⌋ for n parameters).
    pub population: usize,
    /// Most candidates CMA-ES evaluates (default 100); each runs every target scenario.
    pub max_evaluations: usize,
    /// Initial CMA-ES step, as a fraction of each parameter's range (default 0.3).
    pub sigma: f64,
    /// Further scenarios run with the best values afterwards (`[predict] scenarios`).
    pub predict: Vec<PathBuf>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SpecFile {
    name: Option<String>,
    scenario: Option<Spanned<String>>,
    parameters: Spanned<BTreeMap<Spanned<String>, Spanned<ParameterSpec>>>,
    #[serde(rename = "target")]
    targets: Spanned<Vec<Spanned<TargetSpec>>>,
    #[serde(default)]
    optimizer: OptimizerSpec,
    #[serde(default)]
    predict: PredictSpec,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ParameterSpec {
    min: f64,
    max: f64,
    #[serde(default)]
    scale: Scale,
    step: Option<f64>,
    start: Option<f64>,
    #[serde(default)]
    also: Vec<String>,
    times: Option<String>,
}

#[derive(Deserialize, Default, PartialEq)]
#[serde(rename_all = "lowercase")]
enum Scale {
    #[default]
    Linear,
    Log,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TargetSpec {
    scenario: Option<Spanned<String>>,
    metric: Option<String>,
    measured: Option<f64>,
    tolerance: Option<f64>,
    trace: Option<Spanned<String>>,
    time_column: Option<String>,
    columns: Option<BTreeMap<String, String>>,
    tolerance_mm: Option<f64>,
    max_shift_s: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct OptimizerSpec {
    seed: Option<u64>,
    population: Option<usize>,
    max_evaluations: Option<usize>,
    sigma: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct PredictSpec {
    #[serde(default)]
    scenarios: Vec<Spanned<String>>,
}

impl Calibration {
    /// Reads and validates the calibration spec at `path` (see [`Calibration::parse`]).
    pub fn load(path: &Path) -> Result<Calibration, FileError> {
        let text = read_text(path, "calibration spec")?;
        Self::parse(path, &text)
    }

    /// Validates spec `text` read from `path`: paths relative to its directory and required to
    /// exist, every parameter key one a run can apply, measured traces read. Errors name the place.
    pub fn parse(path: &Path, text: &str) -> Result<Calibration, FileError> {
        let spec: SpecFile = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        let at = |span: std::ops::Range<usize>, m: String| {
            FileError::at_offset(path, text, span.start, m)
        };
        let dir = path.parent().unwrap_or(Path::new("."));
        let file = |p: &Spanned<String>, what: &str| -> Result<PathBuf, FileError> {
            let full = dir.join(p.get_ref());
            if full.is_file() {
                Ok(full)
            } else {
                Err(at(
                    p.span(),
                    format!(
                        "{what} '{}' not found (looked for {})",
                        p.get_ref(),
                        full.display()
                    ),
                ))
            }
        };
        let name = spec.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map_or("calibration".into(), |s| s.to_string_lossy().into_owned())
        });
        let default_scenario = spec
            .scenario
            .as_ref()
            .map(|s| file(s, "scenario"))
            .transpose()?;

        let mut parameters = Vec::new();
        for (key, p) in spec.parameters.get_ref() {
            let fail = |m: String| at(key.span(), format!("parameters.\"{}\": {m}", key.get_ref()));
            let q = p.get_ref();
            let log = q.scale == Scale::Log;
            if !(q.min.is_finite() && q.max.is_finite() && q.min < q.max && (!log || q.min > 0.0)) {
                return Err(fail(format!("expected finite min < max (min > 0 on a log scale), found min = {:?}, max = {:?}", q.min, q.max)));
            }
            if let Some(s) = q
                .step
                .filter(|s| !(s.is_finite() && *s > 0.0 && *s <= q.max - q.min))
            {
                return Err(fail(format!(
                    "step = {s:?}: expected a number > 0, at most max − min"
                )));
            }
            if let Some(s) = q.start.filter(|s| !(q.min..=q.max).contains(s)) {
                return Err(fail(format!(
                    "start = {s:?}: expected a value from min to max"
                )));
            }
            // Every key must be one a run can apply (`drives.…`, `links.….mass` or a scenario key).
            for k in std::iter::once(key.get_ref()).chain(&q.also) {
                Change::parse(&format!("{k}=1.0")).map_err(&fail)?;
            }
            parameters.push(Parameter {
                key: key.get_ref().clone(),
                min: q.min,
                max: q.max,
                log,
                step: q.step,
                start: q.start,
                also: q.also.clone(),
                times: q.times.clone(),
            });
        }
        if parameters.is_empty() {
            return Err(at(
                spec.parameters.span(),
                "[parameters] names no parameter: expected \"<key>\" = { min = …, max = … }".into(),
            ));
        }
        for key in spec.parameters.get_ref().keys() {
            let p = parameters
                .iter()
                .find(|p| &p.key == key.get_ref())
                .expect("just added");
            if let Some(t) = &p.times {
                if !parameters.iter().any(|q| &q.key == t && q.times.is_none()) {
                    return Err(at(key.span(), format!("parameters.\"{}\": times = \"{t}\": expected the key of another parameter (one that is not itself a factor)", p.key)));
                }
            }
        }

        let mut targets = Vec::new();
        for t in spec.targets.get_ref() {
            let fail = |m: String| at(t.span(), format!("[[target]]: {m}"));
            let q = t.get_ref();
            let scenario = match &q.scenario {
                Some(s) => file(s, "scenario")?,
                None => default_scenario.clone().ok_or_else(|| {
                    fail("names no scenario and there is no top-level scenario = …".into())
                })?,
            };
            match (&q.metric, &q.trace) {
                (Some(metric), None) => {
                    if q.columns.is_some()
                        || q.time_column.is_some()
                        || q.tolerance_mm.is_some()
                        || q.max_shift_s.is_some()
                    {
                        return Err(fail(format!("{metric}: columns, time_column, tolerance_mm and max_shift_s belong to trace targets")));
                    }
                    let (Some(measured), Some(tolerance)) = (q.measured, q.tolerance) else {
                        return Err(fail(format!("{metric}: expected measured = <number> and tolerance = <relative, e.g. 0.1>")));
                    };
                    if !(measured.is_finite()
                        && measured != 0.0
                        && tolerance.is_finite()
                        && tolerance > 0.0)
                    {
                        return Err(fail(format!("{metric}: expected measured ≠ 0 and a tolerance > 0 (relative), found measured = {measured:?}, tolerance = {tolerance:?}")));
                    }
                    targets.push(Target::Metric {
                        scenario,
                        metric: metric.clone(),
                        measured,
                        tolerance,
                    });
                }
                (None, Some(trace)) => {
                    if q.measured.is_some() || q.tolerance.is_some() {
                        return Err(fail("measured and tolerance belong to metric targets (a trace target has tolerance_mm)".into()));
                    }
                    let trace_path = file(trace, "measured trace")?;
                    let columns: Vec<(String, String)> =
                        q.columns.clone().unwrap_or_default().into_iter().collect();
                    if columns.is_empty() {
                        return Err(fail("expected columns = { <run trace.csv column> = \"<measured column>\", … }".into()));
                    }
                    let tolerance_mm = q
                        .tolerance_mm
                        .filter(|v| v.is_finite() && *v > 0.0)
                        .ok_or_else(|| fail("expected tolerance_mm = <number > 0>".into()))?;
                    let max_shift_s = q.max_shift_s.unwrap_or(0.0);
                    if !(0.0..=60.0).contains(&max_shift_s) {
                        return Err(fail(format!(
                            "max_shift_s = {max_shift_s:?}: expected 0 to 60 s"
                        )));
                    }
                    let time_column = q.time_column.as_deref().unwrap_or("t_s");
                    let measured = MeasuredTrace::load(&trace_path, time_column, &columns)?;
                    targets.push(Target::Trace {
                        scenario,
                        trace: trace_path,
                        columns,
                        measured,
                        tolerance_mm,
                        max_shift_s,
                    });
                }
                _ => {
                    return Err(fail(
                        "expected either metric = \"<metric key>\" or trace = \"<measured CSV>\""
                            .into(),
                    ))
                }
            }
        }
        if targets.is_empty() {
            return Err(at(
                spec.targets.span(),
                "expected at least one [[target]]".into(),
            ));
        }

        let opt = &spec.optimizer;
        let in_text = |k: &str| LineColumn::of_first(text, k);
        let opt_fail =
            |k: &str, m: String| FileError::new(path, in_text(k), format!("optimizer.{k}: {m}"));
        // CMA-ES's own default population, 4 + ⌊3 ln n⌋.
        let population = opt
            .population
            .unwrap_or(4 + (3.0 * (parameters.len() as f64).ln()) as usize);
        if !(2..=1000).contains(&population) {
            return Err(opt_fail(
                "population",
                format!("{population}: expected 2 to 1000"),
            ));
        }
        let mut distinct: Vec<&Path> = targets.iter().map(Target::scenario).collect();
        distinct.sort();
        distinct.dedup();
        let max_evaluations = opt.max_evaluations.unwrap_or(100);
        if max_evaluations == 0
            || max_evaluations.saturating_mul(distinct.len()) > MAX_CALIBRATION_RUNS
        {
            return Err(opt_fail("max_evaluations", format!("{max_evaluations} × {} scenarios: expected 1 to {MAX_CALIBRATION_RUNS} runs in all", distinct.len())));
        }
        let sigma = opt.sigma.unwrap_or(0.3);
        if !(sigma > 0.0 && sigma <= 1.0) {
            return Err(opt_fail(
                "sigma",
                format!("{sigma:?}: expected a number from 0 to 1 (of each parameter's range)"),
            ));
        }
        let predict = spec
            .predict
            .scenarios
            .iter()
            .map(|s| file(s, "prediction scenario"))
            .collect::<Result<_, _>>()?;
        Ok(Calibration {
            name,
            path: path.to_path_buf(),
            parameters,
            targets,
            seed: opt.seed.unwrap_or(0),
            population,
            max_evaluations,
            sigma,
            predict,
        })
    }

    /// Parameter values of a point of the unit box (each coordinate clamped to [0, 1]).
    pub fn values(&self, unit: &[f64]) -> Vec<f64> {
        self.parameters
            .iter()
            .zip(unit)
            .map(|(p, &u)| {
                let u = u.clamp(0.0, 1.0);
                let v = if p.log {
                    (p.min.ln() + u * (p.max.ln() - p.min.ln())).exp()
                } else {
                    p.min + u * (p.max - p.min)
                };
                match p.step {
                    Some(s) => (p.min + ((v - p.min) / s).round() * s).clamp(p.min, p.max),
                    None => v,
                }
            })
            .collect()
    }

    fn unit_of(p: &Parameter, v: f64) -> f64 {
        if p.log {
            (v.ln() - p.min.ln()) / (p.max.ln() - p.min.ln())
        } else {
            (v - p.min) / (p.max - p.min)
        }
    }

    /// The changes that apply parameter values to a run.
    pub fn changes(&self, values: &[f64]) -> Vec<Change> {
        let by_key: BTreeMap<&str, f64> = self
            .parameters
            .iter()
            .zip(values)
            .map(|(p, v)| (p.key.as_str(), *v))
            .collect();
        let mut out = Vec::new();
        for (p, &v) in self.parameters.iter().zip(values) {
            let applied = match &p.times {
                Some(t) => v * by_key[t.as_str()],
                None => v,
            };
            for key in std::iter::once(&p.key).chain(&p.also) {
                out.push(
                    Change::parse(&format!("{key}={applied:?}"))
                        .expect("checked when the spec was read"),
                );
            }
        }
        out
    }

    /// The distinct scenarios of the targets.
    fn target_scenarios(&self) -> Vec<PathBuf> {
        let mut s: Vec<PathBuf> = self
            .targets
            .iter()
            .map(|t| t.scenario().to_path_buf())
            .collect();
        s.sort();
        s.dedup();
        s
    }
}

impl MeasuredTrace {
    /// Reads a measured trace: a header with the time column (seconds) and the measured
    /// columns, then rows of numbers with rising times. Errors name the file, line and column.
    pub fn load(
        path: &Path,
        time_column: &str,
        columns: &[(String, String)],
    ) -> Result<MeasuredTrace, FileError> {
        // Streamed row by row (a run's own trace can be large); bounded by MAX_TRACE_ROWS.
        let mut reader = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_path(path)
            .map_err(|e| {
                FileError::new(path, None, format!("cannot read the measured trace: {e}"))
            })?;
        let located = |pos: Option<&csv::Position>| {
            pos.map(|p| LineColumn {
                line: p.line() as usize,
                column: 1,
            })
        };
        let header = reader
            .headers()
            .map_err(|e| FileError::new(path, None, format!("cannot read the header: {e}")))?
            .clone();
        let index = |name: &str| {
            header.iter().position(|h| h == name).ok_or_else(|| {
                FileError::new(
                    path,
                    Some(LineColumn { line: 1, column: 1 }),
                    format!(
                        "expected a column '{name}' in the header, found {}",
                        header.iter().collect::<Vec<_>>().join(", ")
                    ),
                )
            })
        };
        let t_col = index(time_column)?;
        let wanted: Vec<usize> = columns
            .iter()
            .map(|(_, m)| index(m))
            .collect::<Result<_, _>>()?;
        let mut trace = MeasuredTrace {
            t_s: Vec::new(),
            columns: vec![Vec::new(); wanted.len()],
        };
        for record in reader.records() {
            let record =
                record.map_err(|e| FileError::new(path, located(e.position()), format!("{e}")))?;
            if trace.t_s.len() >= MAX_TRACE_ROWS {
                return Err(FileError::new(
                    path,
                    located(record.position()),
                    format!("more than {MAX_TRACE_ROWS} rows"),
                ));
            }
            let number = |c: usize| -> Result<f64, FileError> {
                let cell = record.get(c).unwrap_or("");
                cell.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        FileError::new(
                            path,
                            located(record.position()),
                            format!(
                                "column '{}': expected a finite number, found '{cell}'",
                                &header[c]
                            ),
                        )
                    })
            };
            let t = number(t_col)?;
            if trace.t_s.last().is_some_and(|&last| t <= last) {
                return Err(FileError::new(
                    path,
                    located(record.position()),
                    format!("{time_column} = {t}: expected times rising from row to row"),
                ));
            }
            trace.t_s.push(t);
            for (k, &c) in wanted.iter().enumerate() {
                trace.columns[k].push(number(c)?);
            }
        }
        if trace.t_s.len() < 2 {
            return Err(FileError::new(
                path,
                None,
                "expected at least two rows of measurements",
            ));
        }
        Ok(trace)
    }
}

/// RMS difference between a run's `trace.csv` (in `run_dir`) and a measured trace, at the best
/// time shift within ±`max_shift_s` (in whole servo periods), over the measured samples the run
/// covers.
fn trace_rms(
    run_dir: &Path,
    columns: &[(String, String)],
    measured: &MeasuredTrace,
    max_shift_s: f64,
) -> Result<f64, String> {
    let path = run_dir.join("trace.csv");
    let runs: Vec<(String, String)> = columns
        .iter()
        .map(|(run, _)| (run.clone(), run.clone()))
        .collect();
    let sim = MeasuredTrace::load(&path, "t_s", &runs).map_err(|e| e.to_string())?;
    let at = |t: f64, c: usize| -> Option<f64> {
        let k = sim.t_s.partition_point(|&s| s <= t);
        if k == 0 || k >= sim.t_s.len() {
            return None;
        }
        let (ta, tb) = (sim.t_s[k - 1], sim.t_s[k]);
        let (a, b) = (sim.columns[c][k - 1], sim.columns[c][k]);
        Some(a + (t - ta) / (tb - ta) * (b - a))
    };
    let dt = sim.t_s[1] - sim.t_s[0];
    let shifts = (max_shift_s / dt).floor() as i64;
    let mut best: Option<f64> = None;
    for s in -shifts..=shifts {
        let shift = s as f64 * dt;
        let (mut sum, mut n) = (0.0, 0usize);
        for (i, &t) in measured.t_s.iter().enumerate() {
            for c in 0..columns.len() {
                if let Some(v) = at(t + shift, c) {
                    sum += (v - measured.columns[c][i]).powi(2);
                    n += 1;
                }
            }
        }
        // At least half the measured samples must overlap the run, or a shift that leaves
        // only the quiet end of a trace would look like a perfect fit.
        if 2 * n >= measured.t_s.len() * columns.len() {
            let rms = (sum / n as f64).sqrt();
            best = Some(best.map_or(rms, |b: f64| b.min(rms)));
        }
    }
    best.ok_or_else(|| {
        "the run's trace covers less than half of the measured trace at every shift".into()
    })
}

/// One evaluated candidate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Evaluation {
    /// In evaluation order; within a generation by parameter values, so every run numbers
    /// the candidates alike however its threads interleave.
    pub index: usize,
    /// Generation of the candidate: 0 the start point, then CMA-ES's, then one per polish move.
    pub generation: usize,
    /// Parameter values (in the order of the spec).
    pub values: Vec<f64>,
    /// Each target's value in the run (NaN when the run failed).
    pub results: Vec<f64>,
    /// Sum of the targets' squared misses in their tolerances (plus a wall growing outside the
    /// parameter box); 1e9 for each target without a value.
    pub cost: f64,
    /// Why the candidate has no cost of its own, when it has none.
    #[serde(serialize_with = "failure_text")]
    pub failure: Option<Failure>,
}

/// Why a candidate has no cost of its own (it is given the cost of a failure).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Failure {
    /// A run could not start: a value it refuses, a key the scenario lacks (the message names
    /// the place).
    CannotStart(String),
    /// A run stopped early: divergence, following-error fault, or interruption.
    Stopped(Stop),
    /// A run never started: the calibration was interrupted first.
    NotRun,
    /// A run lacks a metric a target names.
    MissingMetric(String),
    /// A run's trace could not be compared with the measured one.
    Trace(String),
}

impl Failure {
    /// Whether an interruption, not the candidate, is to blame.
    pub fn interrupted(&self) -> bool {
        matches!(
            self,
            Failure::NotRun | Failure::Stopped(Stop::Interrupted { .. })
        )
    }
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Failure::CannotStart(why) | Failure::Trace(why) => f.write_str(why),
            Failure::Stopped(stop) => write!(f, "{stop}"),
            Failure::NotRun => f.write_str("interrupted"),
            Failure::MissingMetric(metric) => write!(f, "the run has no metric `{metric}`"),
        }
    }
}

fn failure_text<S: serde::Serializer>(failure: &Option<Failure>, s: S) -> Result<S::Ok, S::Error> {
    match failure {
        Some(f) => s.collect_str(f),
        None => s.serialize_none(),
    }
}

/// How the cost changes around the best candidate along one parameter: the best moved down
/// and up by a small step (2 % of the range, or one `step`) with the others held.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sensitivity {
    /// (value, cost) below and above the best (None at a bound or when the run failed).
    pub below: Option<(f64, f64)>,
    /// (value, cost) above the best (None at a bound or when the run failed).
    pub above: Option<(f64, f64)>,
    /// Half-width of Δcost ≤ 1 from the parabola through the three points, when it opens
    /// upwards: the one-sigma uncertainty with the tolerances as standard deviations.
    pub sigma: Option<f64>,
}

impl Sensitivity {
    fn of(best: (f64, f64), below: Option<(f64, f64)>, above: Option<(f64, f64)>) -> Sensitivity {
        let (p0, c0) = best;
        let sigma = match (below, above) {
            // Only at a minimum: a neighbour with a lower cost means the search stopped short.
            (Some((pl, cl)), Some((ph, ch))) if ph > pl && cl > c0 && ch > c0 => {
                let curvature = 2.0 * ((ch - c0) / (ph - p0) - (c0 - cl) / (p0 - pl)) / (ph - pl);
                (curvature > 0.0).then(|| (2.0 / curvature).sqrt())
            }
            _ => None,
        };
        Sensitivity {
            below,
            above,
            sigma,
        }
    }
}

/// Unit-box step of the sensitivity profile and the polish.
const PROFILE_STEP: f64 = 0.02;
/// Most moves of the polish after CMA-ES.
const MAX_POLISH_ROUNDS: usize = 8;

/// The running state of a calibration, for a progress display.
#[derive(Debug, Default)]
pub struct CalibrationProgress {
    /// Candidates evaluated so far.
    pub evaluations: AtomicUsize,
    /// Lowest cost so far (`None` before the first candidate).
    pub best: Mutex<Option<f64>>,
}

/// Everything a calibration found.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationResult {
    /// The calibration's name.
    pub name: String,
    /// The free parameters, as in the spec.
    pub parameters: Vec<Parameter>,
    /// Each target's name ([`Target::name`]), in the order of the spec.
    pub targets: Vec<String>,
    /// Every candidate evaluated, numbered by `index`: the start point, the CMA-ES
    /// generations, then the polish.
    pub evaluations: Vec<Evaluation>,
    /// The candidate of lowest cost among those whose runs succeeded (`None`: none did).
    pub best: Option<Evaluation>,
    /// Per parameter: the range of values among the candidates within a cost of 1 of the best
    /// (with the tolerances as standard deviations, the one-sigma range of a χ² fit, as far as
    /// the candidates sampled it).
    pub ranges: Vec<Option<(f64, f64)>>,
    /// Per parameter: the best candidate moved one small step each way with the others held.
    pub sensitivity: Vec<Sensitivity>,
    /// Moves of the compass search after CMA-ES (each to a better neighbour).
    pub polish_rounds: usize,
    /// Candidates answered from the log of an earlier run of the calibration (`--resume`)
    /// instead of being run again.
    pub recalled: usize,
    /// Whether the calibration was interrupted (the best is the best so far).
    pub interrupted: bool,
    /// Why CMA-ES stopped (e.g. MaxFunctionEvaluations, TolFun).
    pub stop_reason: String,
    /// Wall-clock time of the whole calibration (s).
    pub wall_time_s: f64,
}

/// Runs one candidate: every target scenario with `values` applied, in `scratch/`, which is
/// removed afterwards (the figures are kept in the evaluation).
fn evaluate(
    cal: &Calibration,
    scenarios: &[PathBuf],
    values: Vec<f64>,
    scratch: &Path,
    interrupted: &AtomicBool,
    log: &EvaluationLog,
) -> Evaluation {
    if let Some(earlier) = log.recall(&values) {
        return earlier;
    }
    let (evaluation, cut_short) = run_candidate(cal, scenarios, values, scratch, interrupted);
    // A candidate an interruption cut short anywhere, or whose runs could not start (a cause
    // outside the log's digest may go away), is run again by a resume.
    let cannot_start = matches!(evaluation.failure, Some(Failure::CannotStart(_)));
    if !cut_short && !cannot_start {
        log.keep(&evaluation);
    }
    evaluation
}

/// Runs one candidate (see [`evaluate`]); says whether an interruption cut any of its runs
/// short.
fn run_candidate(
    cal: &Calibration,
    scenarios: &[PathBuf],
    values: Vec<f64>,
    scratch: &Path,
    interrupted: &AtomicBool,
) -> (Evaluation, bool) {
    let changes = cal.changes(&values);
    let jobs: Vec<Job> = scenarios
        .iter()
        .enumerate()
        .map(|(i, s)| Job {
            index: i,
            scenario: s.clone(),
            changes: changes.clone(),
            out_dir: scratch.join(i.to_string()),
            recordings: false,
            csv: cal
                .targets
                .iter()
                .any(|t| matches!(t, Target::Trace { scenario, .. } if scenario == s)),
            timeout: None,
            record: false,
        })
        .collect();
    let (results, _) = execute(&jobs, 1, interrupted, &Progress::default(), &|_| {});
    let cut_short = results.len() < jobs.len()
        || results
            .iter()
            .any(|r| matches!(r.stopped, Some(Stop::Interrupted { .. })));
    // A run that cannot start is the spec's fault: it is named before any other failure.
    let mut failure = results
        .iter()
        .find_map(|r| r.error.clone())
        .map(Failure::CannotStart);
    let mut cost = 0.0;
    let mut out = Vec::new();
    for t in &cal.targets {
        let i = scenarios
            .iter()
            .position(|s| s == t.scenario())
            .expect("a target's scenario is run");
        let r: Option<&JobResult> = results.iter().find(|r| r.index == i);
        let failed = match r {
            None => Some(Failure::NotRun),
            Some(r) => (r.error.clone().map(Failure::CannotStart))
                .or(r.stopped.clone().map(Failure::Stopped)),
        };
        let value = match (t, r, failed) {
            (_, _, Some(f)) => {
                failure.get_or_insert(f);
                f64::NAN
            }
            (Target::Metric { metric, .. }, Some(r), None) => r
                .metrics
                .as_ref()
                .and_then(|m| Metrics::lookup(m, metric))
                .unwrap_or_else(|| {
                    failure.get_or_insert(Failure::MissingMetric(metric.clone()));
                    f64::NAN
                }),
            (
                Target::Trace {
                    columns,
                    measured,
                    max_shift_s,
                    ..
                },
                Some(_),
                None,
            ) => trace_rms(&jobs[i].out_dir, columns, measured, *max_shift_s).unwrap_or_else(|e| {
                failure.get_or_insert(Failure::Trace(e));
                f64::NAN
            }),
            (_, None, None) => unreachable!("a missing run is a failure"),
        };
        let term = match t {
            Target::Metric {
                measured,
                tolerance,
                ..
            } => ((value - measured) / (tolerance * measured)).powi(2),
            Target::Trace { tolerance_mm, .. } => (value / tolerance_mm).powi(2),
        };
        cost += if term.is_finite() { term } else { FAILED };
        out.push(value);
    }
    let _ = std::fs::remove_dir_all(scratch);
    let evaluation = Evaluation {
        index: 0,
        generation: 0,
        values,
        results: out,
        cost,
        failure,
    };
    (evaluation, cut_short)
}

/// Runs the calibration: generations of `population` candidates until `max_evaluations` (or an
/// interruption, or CMA-ES converging), `threads` runs at once, scratch runs under `out`.
/// Before the search, the start point is run once: a metric no run has is a spec error.
/// Every candidate is looked up in `log` first (an earlier run of the calibration that
/// stopped) and logged there when run.
pub fn calibrate(
    cal: &Calibration,
    out: &Path,
    log: &EvaluationLog,
    threads: usize,
    interrupted: &AtomicBool,
    progress: &CalibrationProgress,
    on_change: &(dyn Fn(&CalibrationProgress) + Sync),
) -> Result<CalibrationResult, FileError> {
    let started = std::time::Instant::now();
    let scenarios = cal.target_scenarios();
    let scratch = out.join("scratch");
    let start_unit: Vec<f64> = cal
        .parameters
        .iter()
        .map(|p| p.start.map_or(0.5, |s| Calibration::unit_of(p, s)))
        .collect();
    let first = evaluate(
        cal,
        &scenarios,
        cal.values(&start_unit),
        &scratch.join("start"),
        interrupted,
        log,
    );
    // The start point must run: a run that cannot start (a key the scenario does not have, a
    // value it refuses) or lacks a metric is a fault of the spec, reported before the search.
    match &first.failure {
        Some(f @ Failure::MissingMetric(metric)) => {
            let spec_text = std::fs::read_to_string(&cal.path).unwrap_or_default();
            return Err(FileError::new(
                &cal.path,
                LineColumn::of_first(&spec_text, metric),
                format!("{f}: see a run's metrics.json for the keys"),
            ));
        }
        Some(f @ Failure::CannotStart(_)) => {
            return Err(FileError::new(
                &cal.path,
                None,
                format!("at the start point the run cannot start: {f}"),
            ));
        }
        _ => {}
    }

    // Generation 0 is the start point.
    let generation = AtomicUsize::new(1);
    let counter = AtomicUsize::new(0);
    let pending: Mutex<Vec<Evaluation>> = Mutex::new(Vec::new());
    let objective = |unit: &cmaes::DVector<f64>| -> f64 {
        let u: Vec<f64> = unit.iter().copied().collect();
        // CMA-ES samples all of space: outside the box the point is clamped to its edge and
        // pays a wall growing with the distance, so the search turns back.
        let outside: f64 = u.iter().map(|x| (x - x.clamp(0.0, 1.0)).powi(2)).sum();
        let n = counter.fetch_add(1, Ordering::Relaxed);
        let mut e = evaluate(
            cal,
            &scenarios,
            cal.values(&u),
            &scratch.join(n.to_string()),
            interrupted,
            log,
        );
        e.generation = generation.load(Ordering::Relaxed);
        e.cost += 1e3 * outside;
        let cost = e.cost;
        pending.lock().expect("no panics while held").push(e);
        progress.evaluations.fetch_add(1, Ordering::Relaxed);
        {
            let mut best = progress.best.lock().expect("no panics while held");
            if best.is_none_or(|b| cost < b) {
                *best = Some(cost);
            }
        }
        on_change(progress);
        cost
    };
    let mut evaluations = vec![first];
    let mut stop_reason = String::from("interrupted");
    let mut search = || {
        let state = cmaes::CMAESOptions::new(start_unit.clone(), cal.sigma)
            .population_size(cal.population)
            .seed(cal.seed)
            .max_function_evals(cal.max_evaluations)
            .build(&objective);
        let mut state = match state {
            Ok(s) => s,
            Err(e) => {
                stop_reason = format!("CMA-ES refused its options: {e:?}");
                return;
            }
        };
        while !interrupted.load(Ordering::Relaxed) {
            let done = state.next_parallel();
            let mut generation_runs =
                std::mem::take(&mut *pending.lock().expect("no panics while held"));
            if interrupted.load(Ordering::Relaxed) {
                // A generation cut short is not a fair sample: keep only its finished runs.
                generation_runs.retain(|e| !e.failure.as_ref().is_some_and(Failure::interrupted));
            }
            generation_runs.sort_by(|a, b| {
                a.values
                    .partial_cmp(&b.values)
                    .unwrap_or(std::cmp::Ordering::Equal)
            });
            evaluations.extend(generation_runs);
            generation.fetch_add(1, Ordering::Relaxed);
            if let Some(d) = done {
                stop_reason = d
                    .reasons
                    .iter()
                    .map(|r| format!("{r:?}"))
                    .collect::<Vec<_>>()
                    .join(", ");
                break;
            }
        }
    };
    match rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
    {
        Ok(pool) => pool.install(search),
        Err(_) => search(),
    }
    let best_of = |evaluations: &[Evaluation]| {
        evaluations
            .iter()
            .filter(|e| e.failure.is_none())
            .min_by(|a, b| a.cost.total_cmp(&b.cost))
            .cloned()
    };
    let mut best = best_of(&evaluations);
    // Polish: CMA-ES stops on its budget, not at a minimum. A compass search around the best
    // (each parameter a small step each way) moves to a better neighbour while there is one;
    // its last round is the sensitivity profile.
    let mut sensitivity = Vec::new();
    let mut polish_rounds = 0;
    while let Some(b) = best
        .clone()
        .filter(|_| !interrupted.load(Ordering::Relaxed))
    {
        let (profile, mut runs) =
            profile(cal, &scenarios, &b, &scratch, (threads, interrupted), log);
        let round = generation.load(Ordering::Relaxed) + polish_rounds;
        for e in &mut runs {
            e.generation = round;
        }
        evaluations.extend(runs);
        sensitivity = profile;
        let better = best_of(&evaluations).filter(|n| n.cost < b.cost);
        if better.is_none() || polish_rounds == MAX_POLISH_ROUNDS {
            break;
        }
        best = better;
        polish_rounds += 1;
    }
    for (i, e) in evaluations.iter_mut().enumerate() {
        e.index = i;
    }
    // The best again, now numbered.
    let best = best.and_then(|b| {
        evaluations
            .iter()
            .find(|e| e.values == b.values && e.failure.is_none())
            .cloned()
    });
    let ranges = (0..cal.parameters.len())
        .map(|i| {
            let b = best.as_ref()?;
            evaluations
                .iter()
                .filter(|e| e.failure.is_none() && e.cost <= b.cost + 1.0)
                .map(|e| e.values[i])
                .fold(None, |r: Option<(f64, f64)>, v| {
                    Some(r.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))))
                })
        })
        .collect();
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(CalibrationResult {
        name: cal.name.clone(),
        parameters: cal.parameters.clone(),
        targets: cal.targets.iter().map(Target::name).collect(),
        evaluations,
        best,
        ranges,
        sensitivity,
        polish_rounds,
        recalled: log.recalled(),
        interrupted: interrupted.load(Ordering::Relaxed),
        stop_reason,
        wall_time_s: started.elapsed().as_secs_f64(),
    })
}

/// The sensitivity profile around `best`: 2 runs per parameter (fewer at the bounds), in
/// parallel.
fn profile(
    cal: &Calibration,
    scenarios: &[PathBuf],
    best: &Evaluation,
    scratch: &Path,
    (threads, interrupted): (usize, &AtomicBool),
    log: &EvaluationLog,
) -> (Vec<Sensitivity>, Vec<Evaluation>) {
    let unit: Vec<f64> = cal
        .parameters
        .iter()
        .zip(&best.values)
        .map(|(p, &v)| Calibration::unit_of(p, v))
        .collect();
    // Each neighbour as (parameter, values); stepped parameters move by one step.
    let mut points: Vec<(usize, Vec<f64>)> = Vec::new();
    for (i, p) in cal.parameters.iter().enumerate() {
        for sign in [-1.0, 1.0] {
            let mut values = best.values.clone();
            values[i] = match p.step {
                Some(step) => best.values[i] + sign * step,
                None => {
                    let mut u = unit.clone();
                    u[i] += sign * PROFILE_STEP;
                    cal.values(&u)[i]
                }
            };
            if (p.min..=p.max).contains(&values[i]) && values[i] != best.values[i] {
                points.push((i, values));
            }
        }
    }
    let run = |(k, (_, values)): (usize, &(usize, Vec<f64>))| {
        evaluate(
            cal,
            scenarios,
            values.clone(),
            &scratch.join(format!("profile{k}")),
            interrupted,
            log,
        )
    };
    let runs: Vec<Evaluation> = match rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
    {
        Ok(pool) => pool.install(|| {
            use rayon::prelude::*;
            points.par_iter().enumerate().map(run).collect()
        }),
        Err(_) => points.iter().enumerate().map(run).collect(),
    };
    let sensitivity = (0..cal.parameters.len())
        .map(|i| {
            let side = |below: bool| {
                points.iter().zip(&runs).find_map(|((j, values), e)| {
                    (*j == i && (values[i] < best.values[i]) == below && e.failure.is_none())
                        .then_some((values[i], e.cost))
                })
            };
            Sensitivity::of((best.values[i], best.cost), side(true), side(false))
        })
        .collect();
    (sensitivity, runs)
}

/// The runs of the target and prediction scenarios with the best values, each with its
/// recording, in `out/<scenario stem>/`. Returns (scenario, result) in spec order.
pub fn predict(
    cal: &Calibration,
    values: &[f64],
    out: &Path,
    threads: usize,
    interrupted: &AtomicBool,
) -> Vec<(PathBuf, JobResult)> {
    let mut scenarios = cal.target_scenarios();
    for p in &cal.predict {
        if !scenarios.contains(p) {
            scenarios.push(p.clone());
        }
    }
    let changes = cal.changes(values);
    let jobs: Vec<Job> = scenarios
        .iter()
        .enumerate()
        .map(|(i, s)| Job {
            index: i,
            scenario: s.clone(),
            changes: changes.clone(),
            out_dir: out.join(
                s.file_stem()
                    .map_or("scenario".into(), |s| s.to_string_lossy().into_owned()),
            ),
            recordings: true,
            csv: true,
            timeout: None,
            record: false,
        })
        .collect();
    let (results, _) = execute(&jobs, threads, interrupted, &Progress::default(), &|_| {});
    results
        .into_iter()
        .map(|r| (scenarios[r.index].clone(), r))
        .collect()
}

/// The predictions table: per scenario, each axis's largest error with when and where in the
/// motion it occurred, the path-speed error and each axis's stick-slip stalls.
pub fn predictions_markdown(cal: &Calibration, runs: &[(PathBuf, JobResult)]) -> String {
    let targets = cal.target_scenarios();
    let axes: Vec<String> = runs
        .iter()
        .find_map(|(_, r)| {
            r.metrics.as_ref()?["axes"]
                .as_object()
                .map(|a| a.keys().cloned().collect())
        })
        .unwrap_or_default();
    let mut t = String::from("| scenario |");
    for a in &axes {
        t += &format!(" {} max error |", a.to_uppercase());
    }
    t += &format!(
        " path-speed error | stalls {} | role |\n|---|",
        axes.iter()
            .map(|a| a.to_uppercase())
            .collect::<Vec<_>>()
            .join(" / ")
    );
    t += &"---|".repeat(axes.len());
    t += "---:|---:|---|\n";
    for (s, r) in runs {
        let stem = s
            .file_stem()
            .map_or(String::new(), |s| s.to_string_lossy().into_owned());
        let role = if targets.contains(s) {
            "calibration"
        } else {
            "prediction"
        };
        let Some(m) = &r.metrics else {
            t += &format!(
                "| {stem} | failed: {} |{}| | {role} |\n",
                r.error.as_deref().unwrap_or("?"),
                " |".repeat(axes.len())
            );
            continue;
        };
        let axis = |a: &str| {
            let v = |k: &str| Metrics::lookup(m, &format!("axes.{a}.{k}"));
            let at = m["axes"][a]["max_following_error_at"]
                .as_str()
                .unwrap_or("?");
            let (value, unit) = match (v("max_following_error_mm"), v("max_following_error_deg")) {
                (Some(e), _) => (Some(e), "mm"),
                (None, Some(e)) => (Some(e), "°"),
                _ => (None, ""),
            };
            match (value, v("max_following_error_time_s")) {
                (Some(e), Some(time)) => format!("{e:.3} {unit} ({at}, {time:.2} s)"),
                _ => "—".into(),
            }
        };
        let stalls = |a: &str| {
            Metrics::lookup(m, &format!("axes.{a}.stick_slip_stalls"))
                .map_or("—".into(), |v| format!("{v}"))
        };
        t += &format!(
            "| {stem}{} |",
            if r.stopped.is_some() {
                " (stopped early)"
            } else {
                ""
            }
        );
        for a in &axes {
            t += &format!(" {} |", axis(a));
        }
        t += &format!(
            " {:.2} mm/s | {} | {role} |\n",
            Metrics::lookup(m, "max_path_speed_error_mm_s").unwrap_or(f64::NAN),
            axes.iter()
                .map(|a| stalls(a))
                .collect::<Vec<_>>()
                .join(" / "),
        );
    }
    t
}

impl CalibrationResult {
    /// The report: the fitted parameters with their ranges, each target, the best candidates.
    pub fn markdown(&self, cal: &Calibration) -> String {
        let mut t = format!(
            "# Calibration {}\n\n{} candidates evaluated in {:.1} s (CMA-ES, seed {}, population {}; stopped: {}; then a compass search around the best, {} move{} to a better neighbour, and its last round as the sensitivity profile){}.\n\n",
            self.name,
            self.evaluations.len(),
            self.wall_time_s,
            cal.seed,
            cal.population,
            self.stop_reason,
            self.polish_rounds,
            if self.polish_rounds == 1 { "" } else { "s" },
            if self.interrupted { "; interrupted: the best so far" } else { "" }
        );
        if self.recalled > 0 {
            t += &format!(
                "Resumed: {} of the candidates were answered from the log of the earlier, stopped run ({LOG_FILE}), the others run now; the wall time is this run's.\n\n",
                self.recalled
            );
        }
        let Some(best) = &self.best else {
            return t + "No candidate ran to the end.\n";
        };
        t += "## Fitted parameters\n\nOne-sigma from the local curvature of the cost (the best moved a small step each way, the other parameters held; \"not convex\" where the cost does not rise both ways), and the range of all candidates within Δcost ≤ 1 of the best.\n\n| parameter | value | ± one sigma | cost below / best / above | candidates within Δcost ≤ 1 | bounds |\n|---|---:|---:|---|---|---|\n";
        let within = self
            .evaluations
            .iter()
            .filter(|e| e.failure.is_none() && e.cost <= best.cost + 1.0)
            .count();
        for (i, p) in self.parameters.iter().enumerate() {
            let range = match self.ranges[i] {
                Some(_) if within < 2 => "only the best".into(),
                Some((lo, hi)) => format!("{lo:.5} … {hi:.5} ({within})"),
                None => "—".into(),
            };
            let factor = p
                .times
                .as_deref()
                .map_or(String::new(), |k| format!(" (× {k})"));
            let (sigma, costs) = match self.sensitivity.get(i) {
                Some(s) => {
                    let c = |side: Option<(f64, f64)>| {
                        side.map_or("—".into(), |(_, c)| format!("{c:.3}"))
                    };
                    let lower = [s.below, s.above]
                        .into_iter()
                        .flatten()
                        .any(|(_, c)| c < best.cost);
                    let sigma = match s.sigma {
                        Some(v) => format!("{v:.5}"),
                        None if lower => "not a minimum: search stopped short".into(),
                        None => "not convex".into(),
                    };
                    (
                        sigma,
                        format!("{} / {:.3} / {}", c(s.below), best.cost, c(s.above)),
                    )
                }
                None => ("—".into(), "—".into()),
            };
            t += &format!(
                "| {}{factor} | {:.5} | {sigma} | {costs} | {range} | {} … {}{} |\n",
                p.key,
                best.values[i],
                p.min,
                p.max,
                if p.log { ", log" } else { "" }
            );
        }
        t +=
            "\n## Targets\n\n| target | measured | best candidate | miss |\n|---|---:|---:|---:|\n";
        for (i, target) in cal.targets.iter().enumerate() {
            let v = best.results[i];
            match target {
                Target::Metric {
                    metric,
                    measured,
                    tolerance,
                    ..
                } => {
                    t += &format!(
                        "| {metric} | {measured} | {v:.4} | {:+.1} % (tolerance {:.0} %) |\n",
                        (v / measured - 1.0) * 100.0,
                        tolerance * 100.0
                    );
                }
                Target::Trace { tolerance_mm, .. } => {
                    t += &format!(
                        "| {} | — | {v:.4} | tolerance {tolerance_mm} mm |\n",
                        target.name()
                    );
                }
            }
        }
        t += &format!("\nCost of the best candidate (Σ of squared misses in tolerances): {:.4}\n\n## Best candidates\n\n| # | cost |", best.cost);
        for p in &self.parameters {
            t += &format!(" {} |", p.key);
        }
        for name in &self.targets {
            t += &format!(" {name} |");
        }
        t += "\n|---|---:|";
        t += &"---:|".repeat(self.parameters.len() + self.targets.len());
        t += "\n";
        let mut ranked: Vec<&Evaluation> = self
            .evaluations
            .iter()
            .filter(|e| e.failure.is_none())
            .collect();
        ranked.sort_by(|a, b| a.cost.total_cmp(&b.cost).then(a.index.cmp(&b.index)));
        for e in ranked.iter().take(10) {
            t += &format!("| {} | {:.4} |", e.index, e.cost);
            for v in e.values.iter().chain(&e.results) {
                t += &format!(" {v:.5} |");
            }
            t += "\n";
        }
        let failed: Vec<&Evaluation> = self
            .evaluations
            .iter()
            .filter(|e| e.failure.is_some())
            .collect();
        if let Some(first) = failed.first() {
            t += &format!(
                "\n{} candidates failed or stopped early (cost {FAILED:e}), e.g. #{}: {}\n",
                failed.len(),
                first.index,
                first
                    .failure
                    .as_ref()
                    .map_or(String::new(), |f| f.to_string())
            );
        }
        t
    }

    /// The convergence plot: every candidate's cost, and the best so far, against evaluations
    /// (log scale; failed candidates left out).
    pub fn plot(&self, path: &Path) -> Result<(), crate::report::ReportError> {
        let mut best = f64::INFINITY;
        let (mut all, mut running) = (Vec::new(), Vec::new());
        for e in self.evaluations.iter().filter(|e| e.failure.is_none()) {
            best = best.min(e.cost);
            all.push((e.index as f64, e.cost.max(1e-6)));
            running.push((e.index as f64, best.max(1e-6)));
        }
        crate::report::write_line_plot(
            path,
            &format!("calibration {}: cost against evaluations", self.name),
            "evaluation",
            "cost (Σ squared misses in tolerances)",
            &[
                ("every candidate".into(), all),
                ("best so far".into(), running),
            ],
        )
    }

    /// Every evaluation as CSV: index, generation, parameters, target values, cost, failure.
    pub fn csv(&self) -> String {
        let mut w = csv::Writer::from_writer(Vec::new());
        let mut header = vec!["index".to_string(), "generation".into()];
        header.extend(self.parameters.iter().map(|p| p.key.clone()));
        header.extend(self.targets.iter().cloned());
        header.extend(["cost".into(), "failure".into()]);
        let _ = w.write_record(&header);
        for e in &self.evaluations {
            let mut row = vec![e.index.to_string(), e.generation.to_string()];
            row.extend(e.values.iter().chain(&e.results).map(|v| format!("{v:?}")));
            row.push(format!("{:?}", e.cost));
            row.push(e.failure.as_ref().map_or(String::new(), |f| f.to_string()));
            let _ = w.write_record(&row);
        }
        String::from_utf8(w.into_inner().unwrap_or_default()).unwrap_or_default()
    }
}

/// Writes the best values into the files they came from, comments kept: drives keys into the
/// machines' drives files, link masses into the URDFs (inertia scaled alike), scenario keys
/// into every scenario of the calibration (targets and predictions). Returns the files written.
pub fn write_back(cal: &Calibration, values: &[f64]) -> Result<Vec<PathBuf>, FileError> {
    let changes = cal.changes(values);
    let mut scenarios = cal.target_scenarios();
    scenarios.extend(cal.predict.iter().cloned());
    scenarios.sort();
    scenarios.dedup();
    let mut machines: Vec<PathBuf> = Vec::new();
    for s in &scenarios {
        let scenario = Scenario::load(s)?;
        if !machines.contains(&scenario.machine) {
            machines.push(scenario.machine);
        }
    }
    let scenario_overrides: Vec<Override> = changes
        .iter()
        .filter_map(|c| match c {
            Change::Scenario(o) => Some(o.clone()),
            Change::Machine(_) => None,
        })
        .collect();
    let machine_changes: Vec<&MachineOverride> = changes
        .iter()
        .filter_map(|c| match c {
            Change::Machine(m) => Some(m),
            Change::Scenario(_) => None,
        })
        .collect();
    // Everything is edited and checked in memory first, so a refused value writes nothing.
    let mut edits: Vec<(PathBuf, String)> = Vec::new();
    if !scenario_overrides.is_empty() {
        for s in &scenarios {
            let text = read_text(s, "scenario")?;
            let edited =
                edit_toml(&text, &scenario_overrides).map_err(|e| FileError::new(s, None, e))?;
            Scenario::parse(s, &edited)?;
            edits.push((s.clone(), edited));
        }
    }
    for urdf in &machines {
        edits.extend(super::machine_edits(urdf, &machine_changes)?);
    }
    let mut written = Vec::new();
    for (path, text) in edits {
        std::fs::write(&path, text)
            .map_err(|e| FileError::new(&path, None, format!("cannot write: {e}")))?;
        written.push(path);
    }
    Ok(written)
}

/// `cncsim calibrate`: the search, the scenarios run again with the best values, and what was
/// written back.
#[derive(Debug, Clone)]
pub struct CalibrationOutput {
    /// What the search found.
    pub result: CalibrationResult,
    /// The report (`report.md`): the search, and the predictions where they ran.
    pub report: String,
    /// The output directory.
    pub out: PathBuf,
    /// Files the best values were written into (`--write`).
    pub updated: Vec<PathBuf>,
    /// Why the best values could not be written back.
    pub not_written: Option<String>,
    /// Whether the calibration was interrupted.
    pub interrupted: bool,
}

impl CalibrationOutput {
    /// The search's result with the predictions at its best values (`runs`, when they ran), and
    /// with `write` the best values written into the scenario and machine files.
    pub fn new(
        cal: &Calibration,
        result: CalibrationResult,
        runs: Option<Vec<(PathBuf, JobResult)>>,
        out: &Path,
        write: bool,
        interrupted: bool,
    ) -> Self {
        let mut report = result.markdown(cal);
        let (mut updated, mut not_written) = (Vec::new(), None);
        if let (Some(runs), Some(best)) = (&runs, &result.best) {
            report += &format!(
                "\n## With the best values\n\nRecordings in `predictions/<scenario>/`. Where the largest error occurs: start (before the axis first caught up with its command), reversal (after the command slowed and turned), stop, or moving.\n\n{}",
                predictions_markdown(cal, runs)
            );
            if write {
                match write_back(cal, &best.values) {
                    Ok(paths) => updated = paths,
                    Err(e) => {
                        report += &format!("\n**Not written back:** {e}\n");
                        not_written = Some(e.to_string());
                    }
                }
            }
        }
        CalibrationOutput {
            result,
            report,
            out: out.to_path_buf(),
            updated,
            not_written,
            interrupted,
        }
    }
}

impl crate::command::Report for CalibrationOutput {
    /// `report.md`, every evaluation (`evaluations.json`, `.csv`) and the cost over the
    /// search (`convergence.png`, where there is a successful candidate to plot).
    fn write(&self) -> Result<Vec<PathBuf>, crate::command::WriteError> {
        use crate::command::{cannot_write, write_file};
        std::fs::create_dir_all(&self.out).map_err(|e| cannot_write(&self.out, e))?;
        let json = serde_json::to_string_pretty(&self.result).expect("plain values");
        let mut files = vec![
            write_file(self.out.join("report.md"), &self.report)?,
            write_file(self.out.join("evaluations.json"), json)?,
            write_file(self.out.join("evaluations.csv"), self.result.csv())?,
        ];
        let plot = self.out.join("convergence.png");
        if self.result.plot(&plot).is_ok() {
            files.push(plot);
        }
        Ok(files)
    }

    fn text(&self) -> String {
        self.report.clone()
    }

    fn json(&self) -> Option<serde_json::Value> {
        serde_json::to_value(&self.result).ok()
    }

    fn messages(&self) -> Vec<String> {
        let mut lines: Vec<String> = (self.updated.iter())
            .map(|p| format!("  updated {}", p.display()))
            .collect();
        lines.extend(self.not_written.iter().map(|e| format!("error: {e}")));
        lines
    }

    fn ending(&self) -> crate::command::Ending {
        use crate::command::Ending;
        if self.not_written.is_some() {
            Ending::BadInput(None)
        } else if self.result.best.is_none() {
            Ending::Failed(None)
        } else if self.interrupted {
            Ending::Interrupted(None)
        } else {
            Ending::Done
        }
    }
}
