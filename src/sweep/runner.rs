//! Runs many scenario runs on all cores. Each job is independent and deterministic (Rapier runs
//! single-threaded; nothing depends on scheduling), so the results are the same whatever the
//! number of threads, and they come back in the jobs' order, not in the order they finish.
//! Jobs that run the same setpoints share one plan: it is made once, by the first job that
//! needs it, and the others wait for it.

use super::file::{Change, RunSpec, Sweep};
use super::machine_with;
use crate::diagnostics::FileError;
use crate::plan::PlannedProgram;
use crate::scenario::{plan_for, with_choices, Assembly, PlanKey, RunOptions, Scenario};
use crate::sim::Stop;
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// One run: a scenario file with its changes, its outputs in `out_dir`.
#[derive(Debug, Clone)]
pub struct Job {
    /// Position of the run in its sweep (or calibration); the result carries it back.
    pub index: usize,
    /// The scenario file.
    pub scenario: PathBuf,
    /// The overrides applied to the scenario and its machine.
    pub changes: Vec<Change>,
    /// The folder the run writes its outputs into.
    pub out_dir: PathBuf,
    /// Write the run's Rerun recording and CSV as its `[recording]` asks; off: metrics only.
    pub recordings: bool,
    /// Write the run's CSV trace even without recordings (a calibration reads it back).
    pub csv: bool,
    /// Wall-clock time the run may take; past it the run is ended and its result says
    /// `timeout after N s`.
    pub timeout: Option<Duration>,
    /// Write the result into `out_dir/result.json` when the run ends (a sweep's record of the
    /// run, which `--resume` reads back).
    pub record: bool,
}

impl Job {
    /// The job's scenario, its scenario overrides applied (machine ones apply to the machine).
    pub fn scenario(&self) -> Result<Scenario, FileError> {
        let overrides: Vec<_> = self
            .changes
            .iter()
            .filter_map(|c| match c {
                Change::Scenario(o) => Some(o.clone()),
                Change::Machine(_) => None,
            })
            .collect();
        Scenario::load_with_overrides(&self.scenario, &overrides, "override")
    }
}

/// How a job ended.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JobResult {
    /// The job's `index`.
    pub index: usize,
    /// The run's `metrics.json` (`None` when the run could not start).
    pub metrics: Option<serde_json::Value>,
    /// Why it could not start (bad override, bad file: the message names the place).
    pub error: Option<String>,
    /// Why it stopped early (divergence, following-error fault, interruption).
    pub stopped: Option<Stop>,
    /// Wall-clock time of the job (s).
    pub wall_time_s: f64,
}

/// What the runner has done so far, for a progress display.
#[derive(Debug, Default)]
pub struct Progress {
    /// Jobs in all (set by the caller; the runner does not touch it).
    pub total: usize,
    /// Jobs finished, failed ones included.
    pub done: AtomicUsize,
    /// Jobs running now.
    pub running: AtomicUsize,
    /// Jobs that could not start or stopped early.
    pub failed: AtomicUsize,
    /// The `index` of the job that failed last, if any.
    pub last_failed: Mutex<Option<usize>>,
}

type PlanSlot = Arc<OnceLock<Result<PlannedProgram, String>>>;

/// Plans shared between jobs, by [`PlanKey`] (a sweep has few distinct plans: a list will do).
#[derive(Default)]
struct PlanCache {
    slots: Mutex<Vec<(PlanKey, PlanSlot)>>,
    made: AtomicUsize,
}

impl PlanCache {
    fn get(
        &self,
        s: &Scenario,
        machine: &crate::machine::Machine,
    ) -> Result<PlannedProgram, String> {
        let slot = {
            let mut slots = self
                .slots
                .lock()
                .expect("no job panics while holding the lock");
            let key = PlanKey::new(s, machine);
            match slots.iter().find(|(k, _)| *k == key) {
                Some((_, slot)) => slot.clone(),
                None => {
                    let slot = PlanSlot::default();
                    slots.push((key, slot.clone()));
                    slot
                }
            }
        };
        slot.get_or_init(|| {
            self.made.fetch_add(1, Ordering::Relaxed);
            plan_for(s, machine).map_err(|e| e.to_string())
        })
        .clone()
    }
}

fn run_job(job: &Job, cache: &PlanCache, interrupted: &AtomicBool) -> JobResult {
    let started = Instant::now();
    let failed = |error: String| JobResult {
        index: job.index,
        metrics: None,
        error: Some(error),
        stopped: None,
        wall_time_s: started.elapsed().as_secs_f64(),
    };
    let mut s = match job.scenario() {
        Ok(s) => s,
        Err(e) => return failed(e.to_string()),
    };
    if !job.recordings {
        s.recording.rrd = false;
        s.recording.csv = job.csv;
    }
    let machine_changes: Vec<_> = job
        .changes
        .iter()
        .filter_map(|c| match c {
            Change::Machine(m) => Some(m),
            Change::Scenario(_) => None,
        })
        .collect();
    let machine = match machine_with(&s.machine, &machine_changes) {
        Ok(m) => with_choices(&s, m),
        Err(e) => return failed(e.to_string()),
    };
    let plan = match cache.get(&s, &machine) {
        Ok(plan) => plan,
        Err(e) => return failed(e),
    };
    let assembly = match Assembly::from_plan(&s, machine, plan) {
        Ok(a) => a,
        Err(e) => return failed(e.to_string()),
    };
    let mut timed_out = false;
    let mut keep_going = |_: usize, _: usize| {
        if job.timeout.is_some_and(|limit| started.elapsed() > limit) {
            timed_out = true;
        }
        !timed_out && !interrupted.load(Ordering::Relaxed)
    };
    let run = match assembly.run(RunOptions::write_to(&job.out_dir).progress(&mut keep_going)) {
        Ok(run) => run,
        Err(e) => return failed(e.to_string()),
    };
    // Ended at its time limit (not merely finishing after it): the figures so far are kept,
    // the row says why.
    let ended_at = run.stop().filter(|_| timed_out).map(Stop::time);
    let (stopped, error) = match (job.timeout, ended_at) {
        (Some(limit), Some(time)) => (
            None,
            Some(format!(
                "timeout after {} s (stopped at t = {time:.3} s of the program)",
                limit.as_secs_f64()
            )),
        ),
        _ => (run.stop().cloned(), None),
    };
    JobResult {
        index: job.index,
        stopped,
        metrics: Some(run.metrics_json),
        error,
        wall_time_s: started.elapsed().as_secs_f64(),
    }
}

/// Runs `jobs` on `threads` threads (1: in this thread); `on_change` hears after every job.
/// Jobs not started when `interrupted` is set are left out of the result; a running one stops
/// as interrupted and is kept. Also returns how many distinct plans were made.
pub fn execute(
    jobs: &[Job],
    threads: usize,
    interrupted: &AtomicBool,
    progress: &Progress,
    on_change: &(dyn Fn(&Progress) + Sync),
) -> (Vec<JobResult>, usize) {
    let cache = PlanCache::default();
    let one = |job: &Job| -> Option<JobResult> {
        if interrupted.load(Ordering::Relaxed) {
            return None;
        }
        progress.running.fetch_add(1, Ordering::Relaxed);
        on_change(progress);
        let result = run_job(job, &cache, interrupted);
        // A run interrupted (Ctrl-C) is not finished: no record, so a resume runs it again.
        let interrupted_run = matches!(result.stopped, Some(Stop::Interrupted { .. }));
        if job.record && !interrupted_run {
            if let Err(e) = write_record(job, &result) {
                eprintln!("warning: the record of run {} was not written ({e}): a resumed sweep runs it again", job.index);
            }
        }
        progress.running.fetch_sub(1, Ordering::Relaxed);
        progress.done.fetch_add(1, Ordering::Relaxed);
        if result.error.is_some() || result.stopped.is_some() {
            progress.failed.fetch_add(1, Ordering::Relaxed);
            *progress
                .last_failed
                .lock()
                .expect("no job panics while holding the lock") = Some(job.index);
        }
        on_change(progress);
        Some(result)
    };
    let results: Vec<Option<JobResult>> = if threads <= 1 {
        jobs.iter().map(one).collect()
    } else {
        match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
            Ok(pool) => pool.install(|| jobs.par_iter().map(one).collect()),
            Err(_) => jobs.iter().map(one).collect(),
        }
    };
    (
        results.into_iter().flatten().collect(),
        cache.made.load(Ordering::Relaxed),
    )
}

/// The file of a run's record in its folder.
pub const RECORD: &str = "result.json";

/// Writes the job's result as its record, atomically: a whole file or none, whenever the
/// process is killed (written beside, then renamed over).
fn write_record(job: &Job, result: &JobResult) -> std::io::Result<()> {
    std::fs::create_dir_all(&job.out_dir)?;
    let partial = job.out_dir.join(format!("{RECORD}.partial"));
    std::fs::write(
        &partial,
        serde_json::to_vec(result).map_err(std::io::Error::other)?,
    )?;
    std::fs::rename(&partial, job.out_dir.join(RECORD))
}

/// The record a finished run of `job` left in its folder, if a whole one is there.
pub fn read_record(job: &Job) -> Option<JobResult> {
    let text = std::fs::read(job.out_dir.join(RECORD)).ok()?;
    serde_json::from_slice::<JobResult>(&text)
        .ok()
        .filter(|result| result.index == job.index)
}

/// A digest (SHA-256, hex) of the runs `jobs` stand for: each one's index, folder name,
/// scenario file (its name and its bytes) and changes; not where the folder or the files
/// are, which `./o` and `o` name alike. Another sweep, or the same one with a scenario or a
/// change edited, has another.
pub fn run_list_digest(jobs: &[Job]) -> String {
    use sha2::{Digest, Sha256};
    let name = |path: &std::path::Path| {
        path.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    // Each scenario's bytes, read once however many runs share it.
    let mut contents: std::collections::HashMap<&PathBuf, Vec<u8>> = Default::default();
    let mut hash = Sha256::new();
    for job in jobs {
        hash.update(job.index.to_le_bytes());
        hash.update(name(&job.out_dir).as_bytes());
        hash.update([0]);
        hash.update(name(&job.scenario).as_bytes());
        hash.update([0]);
        let bytes = contents
            .entry(&job.scenario)
            .or_insert_with(|| std::fs::read(&job.scenario).unwrap_or_default());
        hash.update(&bytes[..]);
        for change in &job.changes {
            hash.update(change.text().as_bytes());
            hash.update([0]);
        }
        hash.update([1]);
    }
    hash.finalize()
        .iter()
        .map(|byte| format!("{byte:02x}"))
        .collect()
}

/// Every file the runs of `jobs` read: each job's scenario (its overrides applied) with the
/// files it names, and each machine's files ([`crate::machine::Machine::files`]). Absolute,
/// sorted, each once; what a sweep needs on a worker that shares no filesystem with here.
pub fn input_files(jobs: &[Job]) -> Result<Vec<PathBuf>, FileError> {
    let mut files = std::collections::BTreeSet::new();
    let mut machines = std::collections::BTreeSet::new();
    for job in jobs {
        let scenario = job.scenario()?;
        files.insert(job.scenario.clone());
        files.extend(scenario.files.iter().filter(|f| f.is_file()).cloned());
        if machines.insert(scenario.machine.clone()) {
            files.extend(crate::machine::Machine::files(&scenario.machine, &[])?);
        }
    }
    Ok(files
        .into_iter()
        .map(|f| absolute_as_named(&f))
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect())
}

/// `file` made absolute with its folder's links resolved but its own name kept: cncsim opens
/// it by that name, which may be a link (a `colcon --symlink-install` tree).
pub fn absolute_as_named(file: &std::path::Path) -> PathBuf {
    let absolute = std::path::absolute(file).unwrap_or_else(|_| file.to_path_buf());
    match (absolute.parent(), absolute.file_name()) {
        (Some(folder), Some(name)) => std::fs::canonicalize(folder)
            .map_or_else(|_| absolute.clone(), |folder| folder.join(name)),
        _ => absolute,
    }
}

/// The jobs of a sweep's runs (those of shard `shard` = (K, N): every N-th from the K-th),
/// each writing into `out/runs/<index>_<scenario>_<variant>[_p<point>]/` within the sweep's
/// `run_timeout_s`.
pub fn run_sweep(
    sweep: &Sweep,
    out: &std::path::Path,
    shard: Option<(usize, usize)>,
) -> (Vec<RunSpec>, Vec<Job>) {
    let runs: Vec<RunSpec> = sweep
        .runs()
        .into_iter()
        .filter(|r| shard.is_none_or(|(k, n)| r.index % n == k - 1))
        .collect();
    let jobs = runs
        .iter()
        .map(|r| {
            let scenario = &sweep.scenarios[r.scenario];
            let stem = scenario
                .file_stem()
                .map_or("scenario".into(), |s| s.to_string_lossy().into_owned());
            let mut folder = format!("{:05}_{stem}_{}", r.index, sweep.variants[r.variant].0);
            if !r.values.is_empty() {
                folder += &format!("_p{}", r.point);
            }
            Job {
                index: r.index,
                scenario: scenario.clone(),
                changes: sweep.changes(r),
                out_dir: out.join("runs").join(crate::scenario::folder_name(&folder)),
                recordings: sweep.recordings,
                csv: false,
                timeout: sweep.run_timeout_s.map(Duration::from_secs_f64),
                record: true,
            }
        })
        .collect();
    (runs, jobs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// Slurm job arrays and Kubernetes Indexed Jobs run shard K of N for every K from 1 to N
    /// (docs/sweeps.md): every run is in exactly one shard, whatever N, more shards than runs
    /// included, and each keeps its own index and folder.
    #[test]
    fn shards_partition_the_runs() {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("sweeps");
        let text = "scenarios = [\"../scenarios/xyz_circle_5mms.toml\"]\n[variants]\na = []\nb = []\nc = []\n[grid]\n\"timing.servo_period_ms\" = [0.5, 1.0, 2.0, 4.0]\n";
        let sweep = Sweep::parse(&dir.join("t.toml"), text).unwrap();
        let (_, everything) = run_sweep(&sweep, Path::new("o"), None);
        assert_eq!(everything.len(), 12);
        for n in 1..=13 {
            let mut seen = vec![0; everything.len()];
            for k in 1..=n {
                let (runs, jobs) = run_sweep(&sweep, Path::new("o"), Some((k, n)));
                for (run, job) in runs.iter().zip(&jobs) {
                    assert_eq!(run.index % n, k - 1);
                    assert_eq!(job.out_dir, everything[run.index].out_dir);
                    seen[run.index] += 1;
                }
            }
            assert!(seen.iter().all(|&count| count == 1), "{n} shards: {seen:?}");
        }
    }
}
