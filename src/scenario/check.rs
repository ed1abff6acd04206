//! `[expect]` bounds against a run's metrics, and `cncsim check`: scenarios run as checks.

use super::{folder_name, Expectation, RunError, RunOutput, Scenario};
use crate::command::{Ending, Report, Stream};
use crate::diagnostics::FileError;
use std::fmt;
use std::path::{Path, PathBuf};

/// One bound that a run did not meet.
#[derive(Debug, Clone, PartialEq)]
pub struct Breach {
    /// The bound not met (metric, limits and where the file declares it).
    pub expectation: Expectation,
    /// The metric's value; `None` if the run did not produce it.
    pub value: Option<f64>,
}

/// The outcome of checking one scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// Number of bounds checked.
    pub checked: usize,
    /// The bounds the run did not meet.
    pub breaches: Vec<Breach>,
}

impl Verdict {
    /// Whether every bound was met.
    pub fn passed(&self) -> bool {
        self.breaches.is_empty()
    }
}

/// Compares every expectation of `scenario` with `metrics` (the `metrics.json` value).
pub fn check(scenario: &Scenario, metrics: &serde_json::Value) -> Verdict {
    let mut breaches = Vec::new();
    for e in &scenario.expect {
        let value = crate::report::Metrics::lookup(metrics, &e.metric);
        let ok = match value {
            Some(v) => {
                !v.is_nan() && e.min.is_none_or(|lo| v >= lo) && e.max.is_none_or(|hi| v <= hi)
            }
            None => false,
        };
        if !ok {
            breaches.push(Breach {
                expectation: e.clone(),
                value,
            });
        }
    }
    Verdict {
        checked: scenario.expect.len(),
        breaches,
    }
}

impl fmt::Display for Breach {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let e = &self.expectation;
        let bound = match (e.min, e.max) {
            (Some(lo), Some(hi)) => format!("within [{lo}, {hi}]"),
            (Some(lo), None) => format!("≥ {lo}"),
            (None, Some(hi)) => format!("≤ {hi}"),
            (None, None) => "bounded".into(),
        };
        match self.value {
            Some(v) => write!(f, "{} = {v} breaches its bound: expected {bound}", e.metric),
            None => write!(
                f,
                "{} was not produced by the run: expected {bound}",
                e.metric
            ),
        }
    }
}

/// `cncsim check`: how many scenarios met their bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CheckReport {
    /// Scenarios that ran to the end within all their bounds.
    pub passed: usize,
    /// Scenarios that breached a bound, stopped early, or could not be read or run.
    pub failed: usize,
    /// Planning scenarios without bounds, not run.
    pub skipped: usize,
    /// A scenario could not be read or run (bad input).
    pub bad_input: bool,
}

impl Report for CheckReport {
    fn text(&self) -> String {
        format!(
            "{} passed, {} failed, {} skipped\n",
            self.passed, self.failed, self.skipped
        )
    }

    /// Bad input anywhere makes it bad input (as for every command), whatever else ran.
    fn ending(&self) -> Ending {
        if self.bad_input {
            Ending::BadInput(None)
        } else if self.failed > 0 {
            Ending::Failed(None)
        } else {
            Ending::Done
        }
    }
}

/// The scenario files of `paths`: files as given, folders' `*.toml` in name order.
pub fn scenario_files(paths: &[PathBuf]) -> Result<Vec<PathBuf>, FileError> {
    let mut files = Vec::new();
    for p in paths {
        if !p.is_dir() {
            files.push(p.clone());
            continue;
        }
        let entries = std::fs::read_dir(p)
            .map_err(|e| FileError::new(p, None, format!("cannot read folder: {e}")))?;
        let mut found: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|f| f.extension().is_some_and(|x| x == "toml"))
            .collect();
        found.sort();
        if found.is_empty() {
            return Err(FileError::new(
                p,
                None,
                "no scenario files (*.toml) in this folder",
            ));
        }
        files.extend(found);
    }
    Ok(files)
}

/// Runs every scenario of `files` with `run` (outputs under `root/<name>`) and checks its
/// bounds, showing a line per scenario through `show` as it goes. A planning scenario without
/// bounds is skipped.
pub fn check_scenarios(
    files: &[PathBuf],
    root: &Path,
    run: &mut dyn FnMut(&Scenario, &Path) -> Result<RunOutput, RunError>,
    show: &mut dyn FnMut(Stream, String),
) -> CheckReport {
    let mut report = CheckReport::default();
    let warn = |show: &mut dyn FnMut(Stream, String), warnings: &[FileError]| {
        for w in warnings {
            show(Stream::Err, format!("warning: {w}"));
        }
    };
    for f in files {
        let scenario = match Scenario::load(f) {
            Ok(s) => s,
            Err(e) => {
                show(Stream::Err, format!("error: {e}"));
                report.failed += 1;
                report.bad_input = true;
                continue;
            }
        };
        warn(show, &scenario.warnings);
        if scenario.actuator.is_none() && scenario.expect.is_empty() {
            show(
                Stream::Out,
                format!(
                    "SKIP {} (planning scenario: no [actuator] or [controller] to run)",
                    f.display()
                ),
            );
            report.skipped += 1;
            continue;
        }
        let output = match run(&scenario, &root.join(folder_name(&scenario.name))) {
            Ok(output) => output,
            Err(e) => {
                show(Stream::Err, format!("error: {e}"));
                report.failed += 1;
                report.bad_input = true;
                continue;
            }
        };
        warn(show, &output.warnings);
        let verdict = &output.verdict;
        if verdict.passed() && output.stop().is_none() {
            show(
                Stream::Out,
                format!("PASS {} ({} bounds)", f.display(), verdict.checked),
            );
            report.passed += 1;
            continue;
        }
        show(Stream::Out, format!("FAIL {}", f.display()));
        if let Some(stop) = output.stop() {
            show(Stream::Out, format!("  {stop}"));
        }
        for b in &verdict.breaches {
            show(
                Stream::Out,
                match b.expectation.at {
                    Some(at) => format!("  {}:{}:{}: {b}", f.display(), at.line, at.column),
                    None => format!("  {}: {b}", f.display()),
                },
            );
        }
        report.failed += 1;
    }
    report
}
