//! What cutting costs: the full slot on the bundled mill run through the servo loop with the
//! cutting process on and, as the anchor measured in the same session, the same run in air
//! (no `[cutting]`); and the 5-axis study's program cutting a block on the A-C table, whose
//! simulated time over the measured time is its real-time factor. Metrics only (no files):
//! the nominal part and its comparison are part of a cutting run, as `cncsim run` does them.
//!
//!     cargo bench --bench cutting
//!
//! The README's figures are ratios of these, from one session.

use cncsim::scenario::{Assembly, RunOptions, Scenario};
use criterion::{criterion_group, criterion_main, Criterion};
use std::path::Path;

fn scenario(name: &str) -> Scenario {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut s = Scenario::load(&root.join("scenarios").join(name)).expect("bundled scenario");
    s.recording.rrd = false;
    s.recording.csv = false;
    s
}

fn cutting(c: &mut Criterion) {
    let mut group = c.benchmark_group("cutting");
    group.sample_size(10);
    let slot = scenario("mill_slot.toml");
    let mut air = slot.clone();
    air.cutting = None;
    // Its bounds are on the cut's figures, which a run in air has not.
    air.expect.clear();
    for (name, s) in [("mill_slot in air", &air), ("mill_slot cutting", &slot)] {
        let assembly = Assembly::new(s).expect("the slot assembles");
        group.bench_function(name, |b| {
            b.iter(|| {
                let run = assembly.run(RunOptions::new()).expect("the slot runs");
                assert!(run.stop().is_none());
                run.metrics.sim_time_s
            })
        });
    }
    let five_axis = scenario("mill_table2_cut.toml");
    let assembly = Assembly::new(&five_axis).expect("the 5-axis cut assembles");
    group.bench_function("mill_table2_cut (5-axis, 0.1 mm stock)", |b| {
        b.iter(|| {
            let run = assembly
                .run(RunOptions::new())
                .expect("the 5-axis cut runs");
            assert!(run.stop().is_none());
            run.metrics.sim_time_s
        })
    });
    group.finish();
}

criterion_group!(benches, cutting);
criterion_main!(benches);
