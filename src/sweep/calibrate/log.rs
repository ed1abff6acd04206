//! The log of a calibration's evaluations, written as each candidate finishes, so that a
//! calibration stopped by anything (Ctrl-C, SIGKILL, a lost node) goes on where it stopped.
//!
//! Why replay and not a saved optimizer state: CMA-ES here is seeded and its next candidates
//! depend only on the costs of the earlier ones, so a resumed calibration runs the same search
//! again from the start, answering every candidate the log holds from the log (no run) and
//! running only the others. The result is the one an uninterrupted calibration gives, bit for
//! bit, and nothing of the `cmaes` crate's internals is stored.
//!
//! The file is JSON lines: a header with the digest of the calibration's inputs (the spec, its
//! target scenarios and measured traces), then one line per evaluated candidate with its
//! parameter values, target results and cost as the bits of their f64s (exact, NaN included).
//! Each line is written whole, in one write; a last line cut short by a kill is dropped on
//! resume. Candidates a Ctrl-C cut short are not logged: a resume runs them.

use super::{Calibration, Evaluation, Failure};
use crate::diagnostics::{FileError, LineColumn};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// The log's file name in a calibration's output folder.
pub const LOG_FILE: &str = "evaluation_log.jsonl";

#[derive(Serialize, Deserialize)]
struct Header {
    calibration: String,
    /// SHA-256 of the spec, its target scenarios and measured traces.
    inputs_sha256: String,
}

/// One evaluated candidate, exactly.
#[derive(Serialize, Deserialize)]
struct Line {
    /// The f64 bits of the parameter values.
    values: Vec<u64>,
    /// The f64 bits of each target's result.
    results: Vec<u64>,
    /// The f64 bits of the cost (before any out-of-box wall the search adds).
    cost: u64,
    failure: Option<Failure>,
}

fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

fn floats(bits: &[u64]) -> Vec<f64> {
    bits.iter().map(|&b| f64::from_bits(b)).collect()
}

/// Where a calibration keeps its evaluations, and what an earlier one of it left there.
pub struct EvaluationLog {
    path: PathBuf,
    file: Mutex<std::fs::File>,
    /// The earlier calibration's evaluations, by the bits of their parameter values.
    earlier: HashMap<Vec<u64>, Line>,
    /// Candidates answered from `earlier` so far.
    recalled: AtomicUsize,
    /// A write failed: nothing more is appended (a half line would make the log unreadable).
    broken: std::sync::atomic::AtomicBool,
}

impl EvaluationLog {
    /// A new log in `out` (an earlier one there is replaced).
    pub fn start(cal: &Calibration, out: &Path) -> Result<EvaluationLog, FileError> {
        let path = out.join(LOG_FILE);
        let header = header_line(cal)?;
        let cannot = |e: std::io::Error| FileError::new(&path, None, format!("cannot write: {e}"));
        std::fs::create_dir_all(out).map_err(cannot)?;
        std::fs::write(&path, header).map_err(cannot)?;
        Self::append_to(path, HashMap::new())
    }

    /// The log in `out` of an earlier run of this calibration, to go on from. `Ok(None)` when
    /// `out` holds none; refused when it holds another calibration's (other spec, scenarios or
    /// measurements), or a line that is not a log line before the last.
    pub fn resume(cal: &Calibration, out: &Path) -> Result<Option<EvaluationLog>, FileError> {
        let path = out.join(LOG_FILE);
        let text = match std::fs::read_to_string(&path) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(FileError::new(&path, None, format!("cannot read: {e}"))),
        };
        let header = header_line(cal)?;
        let mut lines = text.split_inclusive('\n');
        let found = lines.next().unwrap_or_default();
        if found != header {
            let theirs = serde_json::from_str::<Header>(found)
                .map_or_else(|_| "no header".to_string(), |h| h.inputs_sha256);
            let ours = serde_json::from_str::<Header>(&header).map(|h| h.inputs_sha256);
            return Err(FileError::new(
                &path,
                Some(LineColumn { line: 1, column: 1 }),
                format!(
                    "--resume: this log is another calibration's (or this one's with another spec, target scenario or measured trace): its inputs' digest is {theirs}, this calibration's {}; resume with the inputs that wrote it, or give another --out",
                    ours.unwrap_or_default()
                ),
            ));
        }
        let mut kept = header;
        let mut earlier = HashMap::new();
        for (i, line) in lines.enumerate() {
            // A line without its newline is the one a kill cut short: dropped, run again.
            if !line.ends_with('\n') {
                break;
            }
            let logged: Line = serde_json::from_str(line).map_err(|e| {
                FileError::new(
                    &path,
                    Some(LineColumn {
                        line: i + 2,
                        column: e.column(),
                    }),
                    format!("--resume: expected a logged evaluation: {e}"),
                )
            })?;
            kept.push_str(line);
            earlier.insert(logged.values.clone(), logged);
        }
        // The whole lines only, replaced at once: appends go after a complete line.
        let partial = path.with_extension("jsonl.partial");
        std::fs::write(&partial, &kept)
            .and_then(|()| std::fs::rename(&partial, &path))
            .map_err(|e| FileError::new(&path, None, format!("cannot rewrite: {e}")))?;
        Self::append_to(path, earlier).map(Some)
    }

    fn append_to(
        path: PathBuf,
        earlier: HashMap<Vec<u64>, Line>,
    ) -> Result<EvaluationLog, FileError> {
        let file = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| FileError::new(&path, None, format!("cannot append: {e}")))?;
        Ok(EvaluationLog {
            path,
            file: Mutex::new(file),
            earlier,
            recalled: AtomicUsize::new(0),
            broken: std::sync::atomic::AtomicBool::new(false),
        })
    }

    /// Evaluations the earlier calibration left in the log.
    pub fn earlier(&self) -> usize {
        self.earlier.len()
    }

    /// Candidates answered from the log so far.
    pub fn recalled(&self) -> usize {
        self.recalled.load(Ordering::Relaxed)
    }

    /// The earlier calibration's evaluation of `values`, if it made one.
    pub(super) fn recall(&self, values: &[f64]) -> Option<Evaluation> {
        let line = self.earlier.get(&bits(values))?;
        self.recalled.fetch_add(1, Ordering::Relaxed);
        Some(Evaluation {
            index: 0,
            generation: 0,
            values: floats(&line.values),
            results: floats(&line.results),
            cost: f64::from_bits(line.cost),
            failure: line.failure.clone(),
        })
    }

    /// Logs an evaluation as one whole line. A failed write is warned once and ends the log
    /// there (a resume runs the later candidates again); the search goes on.
    pub(super) fn keep(&self, e: &Evaluation) {
        if e.failure.as_ref().is_some_and(Failure::interrupted)
            || self.broken.load(Ordering::Relaxed)
        {
            return;
        }
        let line = Line {
            values: bits(&e.values),
            results: bits(&e.results),
            cost: e.cost.to_bits(),
            failure: e.failure.clone(),
        };
        let mut text = serde_json::to_string(&line).expect("plain data serializes");
        text.push('\n');
        let mut file = self.file.lock().expect("no panics while held");
        if let Err(error) = file.write_all(text.as_bytes()) {
            if !self.broken.swap(true, Ordering::Relaxed) {
                eprintln!(
                    "warning: {}: cannot log an evaluation ({error}); the log ends here, and a resumed calibration runs the later candidates again",
                    self.path.display()
                );
            }
        }
    }
}

/// The log's first line: the calibration's name and the digest of its inputs: the spec, its
/// measured traces, every file its target scenarios' runs read (scenarios, machines, programs
/// …), and cncsim's version.
fn header_line(cal: &Calibration) -> Result<String, FileError> {
    use sha2::{Digest, Sha256};
    let mut files = vec![cal.path.clone()];
    for t in &cal.targets {
        if let super::Target::Trace { trace, .. } = t {
            files.push(trace.clone());
        }
    }
    let runs: Vec<super::Job> = cal
        .target_scenarios()
        .into_iter()
        .enumerate()
        .map(|(index, scenario)| super::Job {
            index,
            scenario,
            changes: Vec::new(),
            out_dir: PathBuf::new(),
            recordings: false,
            csv: false,
            timeout: None,
            record: false,
        })
        .collect();
    files.extend(crate::sweep::input_files(&runs)?);
    let mut hash = Sha256::new();
    hash.update(env!("CARGO_PKG_VERSION").as_bytes());
    for file in &files {
        let bytes = std::fs::read(file)
            .map_err(|e| FileError::new(file, None, format!("cannot read: {e}")))?;
        hash.update((bytes.len() as u64).to_le_bytes());
        hash.update(&bytes);
    }
    let header = Header {
        calibration: cal.name.clone(),
        inputs_sha256: hash.finalize().iter().map(|b| format!("{b:02x}")).collect(),
    };
    Ok(serde_json::to_string(&header).expect("plain data serializes") + "\n")
}
