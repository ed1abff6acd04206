//! The sweep file (TOML; unknown keys are errors, paths relative to the file):
//!
//! ```toml
//! name = "feedforward_vs_pid"
//! scenarios = ["../scenarios/paper_corner_90.toml", "../scenarios"]   # files or folders
//! run_timeout_s = 600                   # optional: a run past it ends, its row says timeout
//! baseline = "pid"                      # optional: ratios and wins against this variant
//! [variants]                            # named override lists (the `ab` override syntax)
//! pid = []
//! slow_servo = ["timing.servo_period_ms=4"]
//! [grid]                                # optional: cartesian product, for every variant
//! "controller.axes.x.kp" = [10000.0, 20000.0]
//! [random]                              # optional: seeded samples (with the grid: product)
//! samples = 16
//! seed = 1
//! "controller.model_mass_scale" = { uniform = [0.8, 1.2] }   # or log_uniform, or choice
//! [report]
//! metrics = ["max_contour_error_mm", "axes.x.max_following_error_mm"]
//! recordings = false                    # per-run CSV and recording (off by default)
//! ```
//!
//! Overrides are scenario keys, or keys of the machine: `drives.<key>` edits the machine's
//! drives file (e.g. `drives.axes.x.guide.friction_coefficient=0.02`) and
//! `links.<link>.mass=<kg>` a URDF link's mass (its inertia scaled alike).

use super::MachineOverride;
use crate::diagnostics::{read_text, toml_error, FileError, LineColumn};
use crate::scenario::Override;
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};

/// Most runs one sweep may have: a bound on the work a file can ask for.
pub const MAX_RUNS: usize = 1_000_000;

/// The time a run may be given (s): from a tenth of a second to 30 days.
pub const RUN_TIMEOUT_S: (f64, f64) = (0.1, 30.0 * 86_400.0);

/// `seconds` as a run's time limit, or what is wrong with it.
pub fn check_run_timeout(seconds: f64) -> Result<f64, String> {
    if (RUN_TIMEOUT_S.0..=RUN_TIMEOUT_S.1).contains(&seconds) {
        Ok(seconds)
    } else {
        Err(format!(
            "expected a run time limit from {} to {} s, found {seconds}",
            RUN_TIMEOUT_S.0, RUN_TIMEOUT_S.1
        ))
    }
}

/// A sampled parameter's distribution.
#[derive(Debug, Clone, PartialEq)]
pub enum Distribution {
    /// Uniform between the bounds (lo, hi).
    Uniform(f64, f64),
    /// Uniform in the logarithm between the bounds (lo, hi; lo > 0).
    LogUniform(f64, f64),
    /// One of the listed values, each equally likely.
    Choice(Vec<toml::Value>),
}

/// One change of a run: a scenario override or a machine override.
#[derive(Debug, Clone)]
pub enum Change {
    /// A scenario key (the `ab` override syntax).
    Scenario(Override),
    /// A key of the machine: `drives.<key>` or `links.<link>.mass`.
    Machine(MachineOverride),
}

impl Change {
    /// `drives.…` and `links.….mass` change the machine, anything else the scenario.
    pub fn parse(text: &str) -> Result<Change, String> {
        if text.starts_with("drives.") || text.starts_with("links.") {
            MachineOverride::parse(text).map(Change::Machine)
        } else {
            Override::parse(text).map(Change::Scenario)
        }
    }

    /// The change as written, `KEY=VALUE`.
    pub fn text(&self) -> &str {
        match self {
            Change::Scenario(o) => &o.text,
            Change::Machine(m) => &m.text,
        }
    }
}

/// A validated sweep: plain data, paths resolved.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// The sweep's name: its `name`, or else the file's stem.
    pub name: String,
    /// The sweep file.
    pub path: PathBuf,
    /// The scenario files, each folder listed replaced by its `*.toml` files (sorted).
    pub scenarios: Vec<PathBuf>,
    /// The variant that ratios and wins are reckoned against, if one is named.
    pub baseline: Option<String>,
    /// Variant names and their changes, in the file's order.
    pub variants: Vec<(String, Vec<Change>)>,
    /// Swept keys and their values (TOML value text), in the file's order.
    pub grid: Vec<(String, Vec<String>)>,
    /// The seeded samples (`[random]`), if any.
    pub random: Option<RandomSpec>,
    /// The metrics the summary and the plots show (`report.metrics`; keys of `metrics.json`,
    /// default `max_contour_error_mm`).
    pub metrics: Vec<String>,
    /// Whether each run writes the recording and CSV its `[recording]` asks for
    /// (`report.recordings`; off: metrics only).
    pub recordings: bool,
    /// Wall-clock time (s) a run may take (`run_timeout_s`); one past it is ended and its row
    /// says `timeout after N s`.
    pub run_timeout_s: Option<f64>,
}

/// The `[random]` table: seeded samples of some keys, for every variant and grid point.
#[derive(Debug, Clone, PartialEq)]
pub struct RandomSpec {
    /// Samples drawn (≥ 1).
    pub samples: usize,
    /// Seed of the ChaCha8 stream the samples are drawn from (default 0).
    pub seed: u64,
    /// Each sampled key with its distribution, in the file's order.
    pub parameters: Vec<(String, Distribution)>,
}

/// One run of a sweep: which scenario, which variant, which point of the grid and samples.
#[derive(Debug, Clone)]
pub struct RunSpec {
    /// Position in the sweep (rows are ordered by it, whatever order runs finish in).
    pub index: usize,
    /// Index into [`Sweep::scenarios`].
    pub scenario: usize,
    /// Index into [`Sweep::variants`].
    pub variant: usize,
    /// Index of the grid/sample point (0 without grid or samples).
    pub point: usize,
    /// The point's values: (key, TOML value text).
    pub values: Vec<(String, String)>,
}

impl Sweep {
    /// Reads and validates the sweep file at `path` (see [`Sweep::parse`]).
    pub fn load(path: &Path) -> Result<Sweep, FileError> {
        let text = read_text(path, "sweep")?;
        Self::parse(path, &text)
    }

    /// Validates sweep `text` read from `path`: paths relative to its directory and required to
    /// exist, every override parsed, at most [`MAX_RUNS`] runs. Errors name the place.
    pub fn parse(path: &Path, text: &str) -> Result<Sweep, FileError> {
        let doc: toml::Table = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        // The order of the variants and grid keys is the file's: toml_edit keeps it.
        let ordered: toml_edit::DocumentMut = text.parse().map_err(|e: toml_edit::TomlError| {
            let at = e.span().map(|s| LineColumn::of_offset(text, s.start));
            FileError::new(path, at, e.message().trim().to_string())
        })?;
        let place = |needle: &str| LineColumn::of_first(text, needle);
        let fail = |needle: &str, message: String| FileError::new(path, place(needle), message);
        for key in doc.keys() {
            if ![
                "name",
                "scenarios",
                "baseline",
                "variants",
                "grid",
                "random",
                "report",
                "run_timeout_s",
            ]
            .contains(&key.as_str())
            {
                return Err(fail(key, format!("unknown key `{key}`, expected one of name, scenarios, baseline, run_timeout_s, [variants], [grid], [random], [report]")));
            }
        }
        let run_timeout_s = match doc.get("run_timeout_s") {
            None => None,
            Some(value) => {
                let seconds = value
                    .as_float()
                    .or_else(|| value.as_integer().map(|i| i as f64));
                Some(
                    seconds
                        .and_then(|s| check_run_timeout(s).ok())
                        .ok_or_else(|| {
                            fail(
                                "run_timeout_s",
                                format!(
                                    "run_timeout_s: expected seconds from {} to {}, found {value}",
                                    RUN_TIMEOUT_S.0, RUN_TIMEOUT_S.1
                                ),
                            )
                        })?,
                )
            }
        };
        let dir = path.parent().unwrap_or(Path::new("."));
        let name = match doc.get("name") {
            None => path
                .file_stem()
                .map_or("sweep".into(), |s| s.to_string_lossy().into_owned()),
            Some(toml::Value::String(s)) => s.clone(),
            Some(v) => {
                return Err(fail(
                    "name",
                    format!("name: expected a string, found {}", v.type_str()),
                ))
            }
        };

        let mut scenarios = Vec::new();
        let list = doc
            .get("scenarios")
            .and_then(|v| v.as_array())
            .ok_or_else(|| {
                fail(
                    "scenarios",
                    "expected scenarios = [\"file.toml\" or \"folder\", …]".into(),
                )
            })?;
        for entry in list {
            let Some(p) = entry.as_str() else {
                return Err(fail(
                    "scenarios",
                    format!(
                        "scenarios: expected paths (strings), found {}",
                        entry.type_str()
                    ),
                ));
            };
            let full = dir.join(p);
            if full.is_dir() {
                let mut found: Vec<PathBuf> = std::fs::read_dir(&full)
                    .map_err(|e| {
                        fail(
                            p,
                            format!("scenarios: cannot read folder {}: {e}", full.display()),
                        )
                    })?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|f| f.extension().is_some_and(|x| x == "toml"))
                    .collect();
                found.sort();
                if found.is_empty() {
                    return Err(fail(
                        p,
                        format!("scenarios: no *.toml in folder {}", full.display()),
                    ));
                }
                scenarios.extend(found);
            } else if full.is_file() {
                scenarios.push(full);
            } else {
                return Err(fail(
                    p,
                    format!("scenarios: '{p}' not found (looked for {})", full.display()),
                ));
            }
        }
        if scenarios.is_empty() {
            return Err(fail(
                "scenarios",
                "scenarios: expected at least one scenario".into(),
            ));
        }

        let mut variants = Vec::new();
        match ordered.get("variants").and_then(|v| v.as_table_like()) {
            Some(table) => {
                for (vname, item) in table.iter() {
                    let Some(array) = item.as_array() else {
                        return Err(fail(
                            vname,
                            format!("variants.{vname}: expected a list of \"KEY=VALUE\" overrides"),
                        ));
                    };
                    let mut changes = Vec::new();
                    for o in array.iter() {
                        let Some(t) = o.as_str() else {
                            return Err(fail(
                                vname,
                                format!("variants.{vname}: expected \"KEY=VALUE\" strings"),
                            ));
                        };
                        changes.push(
                            Change::parse(t)
                                .map_err(|e| fail(t, format!("variants.{vname}: {e}")))?,
                        );
                    }
                    variants.push((vname.to_string(), changes));
                }
            }
            None if doc.contains_key("variants") => {
                return Err(fail(
                    "[variants]",
                    "[variants] must be a table of name = [overrides]".into(),
                ))
            }
            None => variants.push(("as-is".to_string(), Vec::new())),
        }
        if variants.is_empty() {
            return Err(fail("[variants]", "[variants] declares no variant".into()));
        }
        let baseline = match doc.get("baseline") {
            None => None,
            Some(toml::Value::String(b)) => {
                if !variants.iter().any(|(n, _)| n == b) {
                    let names: Vec<&str> = variants.iter().map(|(n, _)| n.as_str()).collect();
                    return Err(fail(
                        "baseline",
                        format!(
                            "baseline = \"{b}\": no such variant (variants: {})",
                            names.join(", ")
                        ),
                    ));
                }
                Some(b.clone())
            }
            Some(v) => {
                return Err(fail(
                    "baseline",
                    format!("baseline: expected a variant name, found {}", v.type_str()),
                ))
            }
        };

        let mut grid = Vec::new();
        if let Some(table) = ordered.get("grid").and_then(|v| v.as_table_like()) {
            for (key, item) in table.iter() {
                let Some(values) = item.as_array().filter(|a| !a.is_empty()) else {
                    return Err(fail(
                        key,
                        format!("grid.\"{key}\": expected a non-empty list of values"),
                    ));
                };
                let texts: Vec<String> = values
                    .iter()
                    .map(|v| v.to_string().trim().to_string())
                    .collect();
                for t in &texts {
                    Change::parse(&format!("{key}={t}"))
                        .map_err(|e| fail(key, format!("grid: {e}")))?;
                }
                grid.push((key.to_string(), texts));
            }
        }

        let random = match doc.get("random") {
            None => None,
            Some(toml::Value::Table(t)) => {
                let samples = match t.get("samples") {
                    Some(toml::Value::Integer(n)) if *n >= 1 => *n as usize,
                    other => {
                        return Err(fail(
                            "samples",
                            format!("random.samples: expected a whole number ≥ 1, found {other:?}"),
                        ))
                    }
                };
                let seed = match t.get("seed") {
                    None => 0,
                    Some(toml::Value::Integer(n)) if *n >= 0 => *n as u64,
                    other => {
                        return Err(fail(
                            "seed",
                            format!("random.seed: expected a whole number ≥ 0, found {other:?}"),
                        ))
                    }
                };
                let mut parameters = Vec::new();
                let table = ordered["random"].as_table_like().expect("a table");
                for (key, _) in table
                    .iter()
                    .filter(|(k, _)| *k != "samples" && *k != "seed")
                {
                    let spec = t[key].as_table().ok_or_else(|| fail(key, format!("random.\"{key}\": expected {{ uniform = [lo, hi] }}, {{ log_uniform = [lo, hi] }} or {{ choice = [values] }}")))?;
                    let pair = |v: &toml::Value| -> Option<(f64, f64)> {
                        let a = v.as_array()?;
                        let n = |x: &toml::Value| {
                            x.as_float().or_else(|| x.as_integer().map(|i| i as f64))
                        };
                        match a.as_slice() {
                            [lo, hi] => Some((n(lo)?, n(hi)?)),
                            _ => None,
                        }
                    };
                    let d = match spec.iter().next() {
                        Some((kind, v)) if spec.len() == 1 => match kind.as_str() {
                            "uniform" => pair(v)
                                .filter(|(a, b)| a.is_finite() && b.is_finite() && a < b)
                                .map(|(a, b)| Distribution::Uniform(a, b)),
                            "log_uniform" => pair(v)
                                .filter(|(a, b)| {
                                    a.is_finite() && b.is_finite() && *a > 0.0 && a < b
                                })
                                .map(|(a, b)| Distribution::LogUniform(a, b)),
                            "choice" => v
                                .as_array()
                                .filter(|a| !a.is_empty())
                                .map(|a| Distribution::Choice(a.clone())),
                            _ => None,
                        },
                        _ => None,
                    };
                    let d = d.ok_or_else(|| fail(key, format!("random.\"{key}\": expected {{ uniform = [lo, hi] }} or {{ log_uniform = [lo, hi] }} with finite lo < hi (lo > 0 for log_uniform), or {{ choice = [values] }}")))?;
                    parameters.push((key.to_string(), d));
                }
                if parameters.is_empty() {
                    return Err(fail("[random]", "[random] samples no parameter".into()));
                }
                Some(RandomSpec {
                    samples,
                    seed,
                    parameters,
                })
            }
            Some(_) => return Err(fail("random", "[random] must be a table".into())),
        };

        let (mut metrics, mut recordings) = (vec!["max_contour_error_mm".to_string()], false);
        if let Some(report) = doc.get("report") {
            let t = report
                .as_table()
                .ok_or_else(|| fail("[report]", "[report] must be a table".into()))?;
            for key in t.keys() {
                if !["metrics", "recordings"].contains(&key.as_str()) {
                    return Err(fail(
                        key,
                        format!("report: unknown key `{key}`, expected metrics or recordings"),
                    ));
                }
            }
            if let Some(m) = t.get("metrics") {
                let list = m.as_array().filter(|a| !a.is_empty()).ok_or_else(|| fail("metrics", "report.metrics: expected a non-empty list of metric names (keys of metrics.json)".into()))?;
                metrics = list
                    .iter()
                    .map(|v| {
                        v.as_str().map(String::from).ok_or_else(|| {
                            fail("metrics", "report.metrics: expected strings".into())
                        })
                    })
                    .collect::<Result<_, _>>()?;
            }
            if let Some(r) = t.get("recordings") {
                recordings = r.as_bool().ok_or_else(|| {
                    fail(
                        "recordings",
                        "report.recordings: expected true or false".into(),
                    )
                })?;
            }
        }

        let sweep = Sweep {
            name,
            path: path.to_path_buf(),
            scenarios,
            baseline,
            variants,
            grid,
            random,
            metrics,
            recordings,
            run_timeout_s,
        };
        let points = sweep.point_count();
        let runs = sweep
            .scenarios
            .len()
            .saturating_mul(sweep.variants.len())
            .saturating_mul(points);
        if runs > MAX_RUNS {
            return Err(FileError::new(path, None, format!("the sweep has {runs} runs ({} scenarios × {} variants × {points} points): the limit is {MAX_RUNS}", sweep.scenarios.len(), sweep.variants.len())));
        }
        Ok(sweep)
    }

    fn point_count(&self) -> usize {
        let grid: usize = self
            .grid
            .iter()
            .map(|(_, v)| v.len())
            .fold(1, usize::saturating_mul);
        let samples = self.random.as_ref().map_or(1, |r| r.samples);
        grid.saturating_mul(samples)
    }

    /// The points of the grid (cartesian product, last key fastest) and, with `[random]`, of
    /// the samples for each: (key, value text) lists. Samples are drawn from a ChaCha8 stream
    /// seeded by `seed`, so the same file gives the same points everywhere.
    pub fn points(&self) -> Vec<Vec<(String, String)>> {
        let mut points: Vec<Vec<(String, String)>> = vec![Vec::new()];
        for (key, values) in &self.grid {
            points = points
                .iter()
                .flat_map(|p| {
                    values.iter().map(move |v| {
                        let mut q = p.clone();
                        q.push((key.clone(), v.clone()));
                        q
                    })
                })
                .collect();
        }
        let Some(random) = &self.random else {
            return points;
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(random.seed);
        let samples: Vec<Vec<(String, String)>> = (0..random.samples)
            .map(|_| {
                random
                    .parameters
                    .iter()
                    .map(|(key, d)| {
                        let value = match d {
                            Distribution::Uniform(lo, hi) => {
                                format!("{:?}", rng.random_range(*lo..*hi))
                            }
                            Distribution::LogUniform(lo, hi) => {
                                format!("{:?}", rng.random_range(lo.ln()..hi.ln()).exp())
                            }
                            Distribution::Choice(values) => {
                                values[rng.random_range(0..values.len())].to_string()
                            }
                        };
                        (key.clone(), value)
                    })
                    .collect()
            })
            .collect();
        points
            .iter()
            .flat_map(|p| {
                samples.iter().map(move |s| {
                    let mut q = p.clone();
                    q.extend(s.iter().cloned());
                    q
                })
            })
            .collect()
    }

    /// Every run, scenario by scenario, variant by variant, point by point.
    pub fn runs(&self) -> Vec<RunSpec> {
        let points = self.points();
        let mut runs = Vec::new();
        for scenario in 0..self.scenarios.len() {
            for variant in 0..self.variants.len() {
                for (point, values) in points.iter().enumerate() {
                    runs.push(RunSpec {
                        index: runs.len(),
                        scenario,
                        variant,
                        point,
                        values: values.clone(),
                    });
                }
            }
        }
        runs
    }

    /// The changes of a run: its variant's, then its point's.
    pub fn changes(&self, run: &RunSpec) -> Vec<Change> {
        let mut changes = self.variants[run.variant].1.clone();
        changes.extend(run.values.iter().map(|(k, v)| {
            Change::parse(&format!("{k}={v}")).expect("checked when the sweep was read")
        }));
        changes
    }
}

/// `K/N`: the K-th of N shards (1-based).
pub fn parse_shard(text: &str) -> Result<(usize, usize), String> {
    let parsed = text.split_once('/').and_then(|(k, n)| {
        Some((
            k.trim().parse::<usize>().ok()?,
            n.trim().parse::<usize>().ok()?,
        ))
    });
    match parsed {
        Some((k, n)) if n >= 1 && (1..=n).contains(&k) => Ok((k, n)),
        _ => Err(format!(
            "--shard {text}: expected K/N with 1 ≤ K ≤ N (e.g. 2/4)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sweep(text: &str) -> Result<Sweep, String> {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("sweeps");
        Sweep::parse(&dir.join("t.toml"), text).map_err(|e| e.to_string())
    }

    #[test]
    fn grid_and_samples_multiply_in_a_fixed_order() {
        let s = sweep(
            "scenarios = [\"../scenarios/paper_corner_90.toml\"]\n[variants]\npid = []\nff = [\"controller.axes.x.ff1=0.1\"]\n[grid]\n\"controller.axes.x.kp\" = [1.0, 2.0]\n\"timing.servo_period_ms\" = [1, 4]\n[random]\nsamples = 3\nseed = 7\n\"controller.axes.y.kp\" = { uniform = [10.0, 20.0] }\n",
        )
        .unwrap();
        let runs = s.runs();
        assert_eq!(runs.len(), 2 * 4 * 3);
        assert_eq!(
            runs[0].values[0],
            ("controller.axes.x.kp".into(), "1.0".into())
        );
        assert_eq!(
            runs[3].values[1],
            ("timing.servo_period_ms".into(), "4".into())
        );
        // The same seed, the same samples.
        let again = s.points();
        assert_eq!(s.points(), again);
        let y: f64 = runs[0].values[2].1.parse().unwrap();
        assert!((10.0..20.0).contains(&y));
        assert_eq!(runs[12].variant, 1);
    }

    #[test]
    fn mistakes_name_their_place() {
        let e = sweep("scenarios = [\"nope.toml\"]\n").unwrap_err();
        assert!(
            e.contains("t.toml:1:") && e.contains("'nope.toml' not found"),
            "{e}"
        );
        let e = sweep("scenarios = [\"../scenarios/paper_corner_90.toml\"]\nbaseline = \"x\"\n[variants]\npid = []\n").unwrap_err();
        assert!(
            e.contains("baseline = \"x\": no such variant (variants: pid)"),
            "{e}"
        );
        let e = sweep("scenarios = [\"../scenarios/paper_corner_90.toml\"]\n[random]\nsamples = 2\n\"a.b\" = { uniform = [2.0, 1.0] }\n").unwrap_err();
        assert!(e.contains("finite lo < hi"), "{e}");
        let e = sweep("scenarios = [\"../scenarios/paper_corner_90.toml\"]\n[grid]\n\"controller.axes.x.kp\" = [1.0]\n\"timing.settle_s\" = [1.0]\n[report]\nplots = true\n").unwrap_err();
        assert!(e.contains("unknown key `plots`"), "{e}");
        assert_eq!(parse_shard("2/4"), Ok((2, 4)));
        assert!(parse_shard("5/4").is_err() && parse_shard("0/1").is_err());
    }
}
