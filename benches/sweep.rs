//! Sweep throughput: a 100-run sweep of short scenarios (a 2 mm move on the XYZ table, 0.1 s
//! settle, 1 ms servo period, metrics only) with one worker thread and with one per core, so
//! docs/sweeps.md can state runs per second and the parallel speed-up measured in one session.
//!
//!     cargo bench --bench sweep
//!
//! Criterion reports the time per sweep and, as throughput, runs per second.

use cncsim::sweep::{execute, run_sweep, Progress, Sweep};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

const RUNS: usize = 100;

/// Writes the short scenario and a sweep of `RUNS` X gains over it into `dir`.
fn sweep_file(dir: &Path) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenario = std::fs::read_to_string(root.join("scenarios/xyz_circle_5mms.toml"))
        .expect("the bundled scenario")
        .replace("../models/", &format!("{}/models/", root.display()))
        .replace(
            "circle = { center_mm = [100.0, 100.0], radius_mm = 30.0, start_angle_deg = 0.0, direction = \"ccw\", z_mm = 0.0 }",
            "polyline = { points_mm = [[100.0, 100.0, 0.0], [102.0, 100.0, 0.0]] }",
        )
        .replace("settle_s = 0.5", "settle_s = 0.1")
        .split("[expect]")
        .next()
        .expect("text before [expect]")
        .to_string();
    std::fs::write(dir.join("short.toml"), scenario).expect("writable temp dir");
    let gains: Vec<String> = (0..RUNS)
        .map(|i| format!("{:.1}", 10000.0 + 200.0 * i as f64))
        .collect();
    let sweep = format!(
        "name = \"bench\"\nscenarios = [\"short.toml\"]\n[grid]\n\"controller.axes.x.kp\" = [{}]\n",
        gains.join(", ")
    );
    let path = dir.join("bench_sweep.toml");
    std::fs::write(&path, sweep).expect("writable temp dir");
    path
}

fn sweeps(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("a temp dir");
    let sweep = Sweep::load(&sweep_file(dir.path())).expect("the bench sweep loads");
    let (runs, jobs) = run_sweep(&sweep, &dir.path().join("out"), None);
    assert_eq!(runs.len(), RUNS);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut group = c.benchmark_group(format!("sweep of {RUNS} short runs"));
    group.sample_size(10);
    group.throughput(Throughput::Elements(RUNS as u64));
    for threads in [1, cores] {
        group.bench_function(format!("--jobs {threads}"), |b| {
            b.iter(|| {
                let (results, _) = execute(
                    &jobs,
                    threads,
                    &AtomicBool::new(false),
                    &Progress::default(),
                    &|_| {},
                );
                assert!(results
                    .iter()
                    .all(|r| r.error.is_none() && r.stopped.is_none()));
                results
            })
        });
    }
    group.finish();
}

criterion_group!(sweep, sweeps);
criterion_main!(sweep);
