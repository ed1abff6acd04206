//! Planning throughput on a 100k-block program, whole (`plan`) and as the setpoint stream a
//! run reads (`plan_path_stream`: every window timed before the first sample), and the cost of
//! one profile computation.
//!
//! Run: `cargo bench --bench planner`

use std::hint::black_box;

use cncsim::plan::{
    plan, plan_path_stream, AxisKind, AxisLimits, AxisPath, AxisSpec, Blend, Geometry, Limits,
    PathSegment, Profile, SetpointSample,
};
use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};

/// A 5-axis program of `blocks` short lines (0.2–2 mm, with direction changes from a few
/// degrees to sharp corners and some collinear runs), like CAM output for a freeform surface.
fn program(blocks: usize, blend: Blend) -> AxisPath {
    let axes: Vec<AxisSpec> = [
        ("x", AxisKind::Linear, 150.0, 1000.0, 10_000.0),
        ("y", AxisKind::Linear, 150.0, 1000.0, 10_000.0),
        ("z", AxisKind::Linear, 100.0, 800.0, 8_000.0),
        ("a", AxisKind::Rotary, 90.0, 500.0, 5_000.0),
        ("c", AxisKind::Rotary, 180.0, 1000.0, 10_000.0),
    ]
    .iter()
    .map(|&(name, kind, v, a, j)| AxisSpec {
        name: name.into(),
        kind,
        limits: AxisLimits::from_program_units(kind, v, a, j),
    })
    .collect();
    // Deterministic pseudo-random walk (64-bit LCG).
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut random = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut position = vec![0.0; 5];
    let mut heading: f64 = 0.0;
    let mut segments = Vec::with_capacity(blocks);
    for k in 0..blocks {
        let r = random();
        // 20 % collinear, 60 % gentle turns, 20 % sharp corners.
        if r > 0.2 {
            heading += if r < 0.8 {
                (random() - 0.5) * 0.3
            } else {
                (random() - 0.5) * 3.0
            };
        }
        let step = 0.2e-3 + 1.8e-3 * random();
        position[0] += step * heading.cos();
        position[1] += step * heading.sin();
        position[2] += 0.1 * step * (random() - 0.5);
        position[3] += 0.002 * (random() - 0.5);
        position[4] += 0.004 * (random() - 0.5);
        segments.push(PathSegment {
            geometry: Geometry::Line {
                end: position.clone(),
            },
            feed: Some(0.1),
            feed_metric: vec![1.0, 1.0, 1.0, 0.0, 0.0],
            blend,
            source_index: k as u32,
        });
    }
    AxisPath {
        axes,
        start: vec![0.0; 5],
        segments,
        tool_lever_arms: Vec::new(),
    }
}

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
        let path = program(BLOCKS, blend);
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
        let path = program(BLOCKS, blend);
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
