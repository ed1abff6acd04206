//! A sweep's results: one row per run, in the sweep's order, written as `results.csv` and
//! `results.json` (which also carries what `merge` needs to rebuild everything from shards),
//! `summary.md` (per scenario: the chosen metrics of every variant and point, the ratio to the
//! baseline, the best marked; the wins of each variant overall) and PNG plots.

use super::file::{RunSpec, Sweep};
use super::runner::JobResult;
use crate::diagnostics::FileError;
use crate::report::{write_bar_plot, write_line_plot, BarSeries, ReportError};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// One run's row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// Position of the run in the sweep.
    pub index: usize,
    /// The scenario file's stem.
    pub scenario: String,
    /// The variant's name.
    pub variant: String,
    /// Index of the grid/sample point (0 without grid or samples).
    pub point: usize,
    /// The grid/sample values of the run (key, value as written).
    pub values: Vec<(String, String)>,
    /// Whether the run started and reached its end.
    pub completed: bool,
    /// Why the run stopped early, if it did.
    pub stopped: Option<String>,
    /// Why the run could not start, or that it was ended at its time limit.
    pub error: Option<String>,
    /// Wall-clock time of the run (s).
    pub wall_time_s: f64,
    /// Every numeric figure of the run's `metrics.json`, by dotted key.
    pub metrics: BTreeMap<String, f64>,
}

/// Everything `results.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepResults {
    /// The sweep's name.
    pub name: String,
    /// The variant ratios and wins are reckoned against, if any.
    pub baseline: Option<String>,
    /// The metrics the summary and the plots show.
    pub report_metrics: Vec<String>,
    /// Variant names in the sweep's order.
    pub variants: Vec<String>,
    /// Swept keys (grid, then sampled).
    pub keys: Vec<String>,
    /// Runs in the whole sweep; the shards that are here.
    pub total_runs: usize,
    /// The shards whose rows are here, as (K, N); empty when the sweep ran whole.
    pub shards: Vec<(usize, usize)>,
    /// One row per run that has a result, in the sweep's order.
    pub rows: Vec<Row>,
}

/// Numeric leaves of a JSON value by dotted key.
pub fn flatten(v: &serde_json::Value, prefix: &str, out: &mut BTreeMap<String, f64>) {
    match v {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                flatten(v, &key, out);
            }
        }
        serde_json::Value::Number(n) => {
            if let Some(x) = n.as_f64() {
                out.insert(prefix.to_string(), x);
            }
        }
        _ => {}
    }
}

impl SweepResults {
    /// The rows of `runs` from their results (runs without a result, e.g. not started after
    /// an interruption, are left out).
    pub fn new(
        sweep: &Sweep,
        runs: &[RunSpec],
        results: &[JobResult],
        shard: Option<(usize, usize)>,
    ) -> SweepResults {
        let by_index: BTreeMap<usize, &JobResult> = results.iter().map(|r| (r.index, r)).collect();
        let rows = runs
            .iter()
            .filter_map(|run| {
                let r = by_index.get(&run.index)?;
                let mut metrics = BTreeMap::new();
                if let Some(m) = &r.metrics {
                    flatten(m, "", &mut metrics);
                }
                let scenario = sweep.scenarios[run.scenario]
                    .file_stem()
                    .map_or("scenario".into(), |s| s.to_string_lossy().into_owned());
                Some(Row {
                    index: run.index,
                    scenario,
                    variant: sweep.variants[run.variant].0.clone(),
                    point: run.point,
                    values: run.values.clone(),
                    completed: r.error.is_none() && r.stopped.is_none(),
                    stopped: r.stopped.as_ref().map(|s| s.to_string()),
                    error: r.error.clone(),
                    wall_time_s: r.wall_time_s,
                    metrics,
                })
            })
            .collect();
        let mut keys: Vec<String> = sweep.grid.iter().map(|(k, _)| k.clone()).collect();
        if let Some(r) = &sweep.random {
            keys.extend(r.parameters.iter().map(|(k, _)| k.clone()));
        }
        SweepResults {
            name: sweep.name.clone(),
            baseline: sweep.baseline.clone(),
            report_metrics: sweep.metrics.clone(),
            variants: sweep.variants.iter().map(|(n, _)| n.clone()).collect(),
            keys,
            total_runs: sweep.runs().len(),
            shards: shard.into_iter().collect(),
            rows,
        }
    }

    fn scenarios(&self) -> Vec<String> {
        let mut seen = Vec::new();
        for r in &self.rows {
            if !seen.contains(&r.scenario) {
                seen.push(r.scenario.clone());
            }
        }
        seen
    }

    /// `results.csv`: index, scenario, variant, point, the swept values, the run's state, then
    /// every metric (the union over runs; empty where a run has none).
    pub fn csv(&self) -> String {
        let metric_keys: BTreeSet<&String> =
            self.rows.iter().flat_map(|r| r.metrics.keys()).collect();
        let quote = |s: &str| {
            if s.contains([',', '"', '\n']) {
                format!("\"{}\"", s.replace('"', "\"\""))
            } else {
                s.to_string()
            }
        };
        let mut header: Vec<String> = ["index", "scenario", "variant", "point"]
            .map(String::from)
            .to_vec();
        header.extend(self.keys.iter().cloned());
        header.extend(["completed", "stopped", "error", "wall_time_s"].map(String::from));
        header.extend(metric_keys.iter().map(|k| k.to_string()));
        let mut out = header
            .iter()
            .map(|h| quote(h))
            .collect::<Vec<_>>()
            .join(",")
            + "\n";
        for r in &self.rows {
            let mut cells = vec![
                r.index.to_string(),
                quote(&r.scenario),
                quote(&r.variant),
                r.point.to_string(),
            ];
            for k in &self.keys {
                cells.push(quote(
                    r.values
                        .iter()
                        .find(|(key, _)| key == k)
                        .map_or("", |(_, v)| v),
                ));
            }
            cells.push(r.completed.to_string());
            cells.push(quote(
                &r.stopped.as_ref().map_or(String::new(), |s| s.to_string()),
            ));
            cells.push(quote(r.error.as_deref().unwrap_or("")));
            cells.push(format!("{:.6}", r.wall_time_s));
            for k in &metric_keys {
                cells.push(
                    r.metrics
                        .get(*k)
                        .map_or(String::new(), |v| format!("{v:?}")),
                );
            }
            out += &(cells.join(",") + "\n");
        }
        out
    }

    /// `summary.md`.
    pub fn summary(&self) -> String {
        let mut t = format!("# Sweep {}\n\n", self.name);
        let done = self.rows.len();
        t += &format!("{done} of {} runs", self.total_runs);
        if !self.shards.is_empty() {
            let shards: Vec<String> = self
                .shards
                .iter()
                .map(|(k, n)| format!("{k}/{n}"))
                .collect();
            t += &format!(" (shards {})", shards.join(", "));
        }
        let failed = self.rows.iter().filter(|r| !r.completed).count();
        t += &format!("; {failed} failed or stopped early. Smaller is better for every figure; the best of each scenario and point is **bold**");
        if let Some(b) = &self.baseline {
            t += &format!("; (×r) is the ratio to the baseline variant `{b}`");
        }
        t += ".\n\n";
        let mut wins: BTreeMap<&str, usize> =
            self.variants.iter().map(|v| (v.as_str(), 0)).collect();
        for scenario in self.scenarios() {
            t += &format!("## {scenario}\n\n| variant |");
            for k in &self.keys {
                t += &format!(" {k} |");
            }
            for m in &self.report_metrics {
                t += &format!(" {m} |");
            }
            t += "\n|---|";
            t += &"---|".repeat(self.keys.len());
            t += &"---:|".repeat(self.report_metrics.len());
            t += "\n";
            let rows: Vec<&Row> = self
                .rows
                .iter()
                .filter(|r| r.scenario == scenario)
                .collect();
            let points: BTreeSet<usize> = rows.iter().map(|r| r.point).collect();
            for point in points {
                let at: Vec<&&Row> = rows.iter().filter(|r| r.point == point).collect();
                let best: Vec<Option<f64>> = self
                    .report_metrics
                    .iter()
                    .map(|m| {
                        at.iter()
                            .filter(|r| r.completed)
                            .filter_map(|r| r.metrics.get(m))
                            .copied()
                            .filter(|v| v.is_finite())
                            .reduce(f64::min)
                    })
                    .collect();
                let base = self
                    .baseline
                    .as_ref()
                    .and_then(|b| at.iter().find(|r| &r.variant == b));
                for r in &at {
                    t += &format!("| {} |", r.variant);
                    for k in &self.keys {
                        t += &format!(
                            " {} |",
                            r.values
                                .iter()
                                .find(|(key, _)| key == k)
                                .map_or("", |(_, v)| v)
                        );
                    }
                    for (m, best) in self.report_metrics.iter().zip(&best) {
                        match (r.metrics.get(m), &r.error) {
                            (_, Some(_)) => t += " error |",
                            (None, _) => t += " — |",
                            (Some(v), _) => {
                                let mut cell = format!("{v:.4}");
                                if let Some(b) =
                                    base.and_then(|b| b.metrics.get(m)).filter(|b| **b != 0.0)
                                {
                                    cell += &format!(" (×{:.3})", v / b);
                                }
                                if Some(*v) == *best && r.completed {
                                    cell = format!("**{cell}**");
                                    *wins.entry(r.variant.as_str()).or_insert(0) += 1;
                                }
                                if !r.completed {
                                    cell += " (stopped)";
                                }
                                t += &format!(" {cell} |");
                            }
                        }
                    }
                    t += "\n";
                }
            }
            t += "\n";
        }
        t += "## Wins\n\nHow often each variant has the smallest value of a metric (per scenario, point and metric):\n\n| variant | wins |\n|---|---:|\n";
        for v in &self.variants {
            t += &format!("| {v} | {} |\n", wins.get(v.as_str()).copied().unwrap_or(0));
        }
        let errors: Vec<&Row> = self
            .rows
            .iter()
            .filter(|r| r.error.is_some() || r.stopped.is_some())
            .collect();
        if !errors.is_empty() {
            t += "\n## Runs that failed or stopped\n\n";
            for r in errors {
                t += &format!(
                    "- run {} ({}, {}): {}\n",
                    r.index,
                    r.scenario,
                    r.variant,
                    r.error
                        .clone()
                        .or(r.stopped.as_ref().map(|s| s.to_string()))
                        .unwrap_or_default()
                );
            }
        }
        t
    }

    /// The plots: per metric, variants side by side per scenario (the median over points, the
    /// whisker from the smallest to the largest); with a one-key grid and no samples, also the
    /// metric against the swept value, one line per scenario and variant.
    pub fn plots(&self, out: &Path) -> Result<Vec<PathBuf>, ReportError> {
        let scenarios = self.scenarios();
        let mut files = Vec::new();
        for m in &self.report_metrics {
            let series: Vec<BarSeries> = self
                .variants
                .iter()
                .map(|v| BarSeries {
                    label: v.clone(),
                    values: scenarios
                        .iter()
                        .map(|s| {
                            let mut xs: Vec<f64> = self
                                .rows
                                .iter()
                                .filter(|r| &r.scenario == s && &r.variant == v && r.completed)
                                .filter_map(|r| r.metrics.get(m).copied())
                                .filter(|x| x.is_finite())
                                .collect();
                            xs.sort_by(f64::total_cmp);
                            (!xs.is_empty()).then(|| (xs[0], xs[xs.len() / 2], xs[xs.len() - 1]))
                        })
                        .collect(),
                })
                .collect();
            let path = out.join(format!("plot_{}.png", crate::scenario::folder_name(m)));
            write_bar_plot(
                &path,
                &format!("{}: {m}", self.name),
                m,
                &scenarios,
                &series,
            )?;
            files.push(path);
            let swept_one = self.keys.len() == 1
                && self
                    .rows
                    .iter()
                    .all(|r| r.values.len() == 1 && r.values[0].1.parse::<f64>().is_ok());
            if swept_one {
                let key = &self.keys[0];
                let mut lines = Vec::new();
                for s in &scenarios {
                    for v in &self.variants {
                        let mut pts: Vec<(f64, f64)> = self
                            .rows
                            .iter()
                            .filter(|r| &r.scenario == s && &r.variant == v && r.completed)
                            .filter_map(|r| {
                                Some((r.values[0].1.parse::<f64>().ok()?, *r.metrics.get(m)?))
                            })
                            .collect();
                        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                        if !pts.is_empty() {
                            lines.push((format!("{s}, {v}"), pts));
                        }
                    }
                }
                let path = out.join(format!(
                    "plot_{}_vs_{}.png",
                    crate::scenario::folder_name(m),
                    crate::scenario::folder_name(key)
                ));
                write_line_plot(
                    &path,
                    &format!("{}: {m} against {key}", self.name),
                    key,
                    m,
                    &lines,
                )?;
                files.push(path);
            }
        }
        Ok(files)
    }
}

/// Writes `results.json`, `results.csv`, `summary.md` and the plots into `out`; returns the
/// files written.
pub fn write_results(results: &SweepResults, out: &Path) -> Result<Vec<PathBuf>, ReportError> {
    std::fs::create_dir_all(out).map_err(|source| ReportError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let mut files = Vec::new();
    let json = serde_json::to_string_pretty(results).expect("plain values") + "\n";
    for (name, text) in [
        ("results.json", json),
        ("results.csv", results.csv()),
        ("summary.md", results.summary()),
    ] {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|source| ReportError::Io {
            path: path.clone(),
            source,
        })?;
        files.push(path);
    }
    files.extend(results.plots(out)?);
    Ok(files)
}

/// Combines the `results.json` of shard folders into one set of results (rows in the sweep's
/// order); they must come from the same sweep and not overlap.
pub fn merge(dirs: &[PathBuf]) -> Result<SweepResults, FileError> {
    let mut merged: Option<SweepResults> = None;
    for dir in dirs {
        let path = dir.join("results.json");
        let text = crate::diagnostics::read_text(&path, "sweep results")?;
        let part: SweepResults = serde_json::from_str(&text).map_err(|e| {
            FileError::new(&path, None, format!("not the results.json of a sweep: {e}"))
        })?;
        merged = Some(match merged {
            None => part,
            Some(mut m) => {
                if (m.name.as_str(), m.total_runs, &m.variants, &m.keys)
                    != (
                        part.name.as_str(),
                        part.total_runs,
                        &part.variants,
                        &part.keys,
                    )
                {
                    return Err(FileError::new(
                        &path,
                        None,
                        format!(
                            "from another sweep: '{}' with {} runs, not '{}' with {}",
                            part.name, part.total_runs, m.name, m.total_runs
                        ),
                    ));
                }
                for row in part.rows {
                    if m.rows.iter().any(|r| r.index == row.index) {
                        return Err(FileError::new(
                            &path,
                            None,
                            format!(
                                "run {} is in two of the folders (overlapping shards)",
                                row.index
                            ),
                        ));
                    }
                    m.rows.push(row);
                }
                m.shards.extend(part.shards);
                m
            }
        });
    }
    let mut m = merged
        .ok_or_else(|| FileError::new(Path::new("."), None, "merge needs at least one folder"))?;
    m.rows.sort_by_key(|r| r.index);
    m.shards.sort();
    Ok(m)
}

/// `cncsim sweep`: the results table of the runs done, and how the sweep ended.
#[derive(Debug, Clone)]
pub struct SweepOutput {
    /// The results of the runs done.
    pub results: SweepResults,
    /// The output folder.
    pub out: PathBuf,
    /// Runs asked for (this shard's), runs done, plans made for them.
    pub jobs: usize,
    /// Runs done.
    pub done: usize,
    /// Distinct plans made for them.
    pub plans: usize,
    /// Whether the sweep was interrupted.
    pub interrupted: bool,
    /// A run could not start or stopped early.
    pub any_failed: bool,
}

impl crate::command::Report for SweepOutput {
    fn write(&self) -> Result<Vec<PathBuf>, crate::command::WriteError> {
        Ok(write_results(&self.results, &self.out)?)
    }

    fn text(&self) -> String {
        self.results.summary()
    }

    fn messages(&self) -> Vec<String> {
        vec![format!("{} plans made for {} runs", self.plans, self.done)]
    }

    fn ending(&self) -> crate::command::Ending {
        use crate::command::Ending;
        if self.interrupted {
            Ending::Interrupted(Some(format!(
                "interrupted: {} of {} runs done; the files hold them",
                self.done, self.jobs
            )))
        } else if self.any_failed {
            Ending::Failed(None)
        } else {
            Ending::Done
        }
    }
}

/// `cncsim merge`: the shards' results as one table.
#[derive(Debug, Clone)]
pub struct MergeOutput {
    /// The merged results.
    pub results: SweepResults,
    /// How many folders were merged.
    pub folders: usize,
    /// The folder the merged files go to.
    pub out: PathBuf,
}

impl crate::command::Report for MergeOutput {
    fn write(&self) -> Result<Vec<PathBuf>, crate::command::WriteError> {
        Ok(write_results(&self.results, &self.out)?)
    }

    fn text(&self) -> String {
        format!(
            "merged {} folders: {} of {} runs\n",
            self.folders,
            self.results.rows.len(),
            self.results.total_runs
        )
    }
}
