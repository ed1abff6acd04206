//! Planning throughput on a 100k-block program, whole (`plan`) and as the setpoint stream a
//! run reads (`plan_path_stream`: every window timed before the first sample), and the cost of
//! one profile computation.
//!
//! Run: `cargo bench --bench planner`

use std::hint::black_box;

use cncsim::plan::{plan, plan_path_stream, Blend, Limits, Profile, SetpointSample};
use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};

#[path = "../tests/common/mod.rs"]
mod common;
use common::random_walk;

/// Blocks per benchmarked program.
const BLOCKS: usize = 100_000;

/// The benchmarked blend modes: 0.01 mm corner tolerance, and a stop at every block.
fn blends() -> [(&'static str, Blend); 2] {
    [
        (
            "continuous_0.01mm",
            Blend::Continuous {
                tolerance: Some(1e-5),
            },
        ),
        ("exact_stop", Blend::ExactStop),
    ]
}

fn planning_throughput(c: &mut Criterion) {
    let mut group = c.benchmark_group("plan_100k_blocks");
    group.sample_size(10);
    group.throughput(Throughput::Elements(BLOCKS as u64));
    for (name, blend) in blends() {
        let path = random_walk(BLOCKS, blend, true);
        group.bench_function(name, |b| b.iter(|| plan(black_box(&path)).unwrap()));
    }
    group.finish();
}

/// The streaming planner's timing pass: building the stream times every window of the path
/// (as a run does before its first tick); the first sample is read, no further one. The path
/// is handed over by value, so its copy is made, and the stream dropped, outside the timing.
fn streaming_throughput(c: &mut Criterion) {
    let period = 1e-3;
    let mut group = c.benchmark_group("stream_100k_blocks");
    group.sample_size(10);
    group.throughput(Throughput::Elements(BLOCKS as u64));
    for (name, blend) in blends() {
        let path = random_walk(BLOCKS, blend, true);
        let mut sample = SetpointSample::zeros(path.axes.len());
        group.bench_function(name, |b| {
            b.iter_batched(
                || path.clone(),
                |path| {
                    let mut stream = plan_path_stream(path, period).unwrap();
                    assert!(stream.next_sample(&mut sample));
                    stream
                },
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();
}

fn profile_cost(c: &mut Criterion) {
    let limits = Limits::new(0.15, 1.0, 10.0);
    let mut group = c.benchmark_group("profile");
    group.bench_function("rest_to_rest_closed_form", |b| {
        b.iter(|| Profile::rest_to_rest(black_box(0.0123), black_box(&limits)))
    });
    group.bench_function("between_speeds", |b| {
        b.iter(|| Profile::plan(black_box(0.0123), black_box(0.05), black_box(0.02), &limits))
    });
    let profile = Profile::rest_to_rest(0.0123, &limits);
    group.bench_function("state_eval", |b| {
        b.iter(|| profile.state(black_box(0.0765)))
    });
    group.finish();
}

criterion_group!(
    benches,
    planning_throughput,
    streaming_throughput,
    profile_cost
);
criterion_main!(benches);
