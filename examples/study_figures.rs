//! Prints the planning figures of the 5-axis study's program (docs/sources.md §3.3): per-axis limits
//! v = 150, a = 1000, j = 1000 (mm and degree units), F = 150 mm/s on the Euclidean norm of all
//! axis deltas in mm and degrees.
//!
//! Run: `cargo run --example study_figures`

use std::f64::consts::PI;

use cncsim::plan::{
    finite_difference_extremes, plan, AxisKind, AxisLimits, AxisPath, AxisSpec, Blend, Geometry,
    PathSegment,
};

const TABLE: [[f64; 5]; 5] = [
    [20.0, 10.0, 30.0, 10.0, 50.0],
    [-40.0, 20.0, 0.0, 10.0, 30.0],
    [10.0, 30.0, -30.0, 20.0, 10.0],
    [50.0, 40.0, 0.0, 20.0, -10.0],
    [60.0, 50.0, 30.0, 20.0, -30.0],
];

fn main() {
    let kinds = [
        ("x", AxisKind::Linear),
        ("y", AxisKind::Linear),
        ("z", AxisKind::Linear),
        ("a", AxisKind::Rotary),
        ("c", AxisKind::Rotary),
    ];
    let axes: Vec<AxisSpec> = kinds
        .iter()
        .map(|&(name, kind)| AxisSpec {
            name: name.into(),
            kind,
            limits: AxisLimits::from_program_units(kind, 150.0, 1000.0, 1000.0),
        })
        .collect();
    let to_si = |p: &[f64; 5]| -> Vec<f64> {
        p.iter()
            .zip(&axes)
            .map(|(x, a)| x / a.kind.program_units_per_si())
            .collect()
    };
    let rotary_weight = 1e-3 / (PI / 180.0);
    let metric = vec![1.0, 1.0, 1.0, rotary_weight, rotary_weight];
    let modes = [
        ("exact stop (G61)", Blend::ExactStop),
        (
            "G64 P0.05 mm",
            Blend::Continuous {
                tolerance: Some(0.05e-3),
            },
        ),
        (
            "G64 P5 mm",
            Blend::Continuous {
                tolerance: Some(5e-3),
            },
        ),
    ];
    for (label, blend) in modes {
        let segments = TABLE
            .iter()
            .enumerate()
            .map(|(k, p)| PathSegment {
                geometry: Geometry::Line { end: to_si(p) },
                feed: Some(0.15),
                feed_metric: metric.clone(),
                blend,
                source_index: k as u32 + 1,
            })
            .collect();
        let path = AxisPath {
            axes: axes.clone(),
            start: vec![0.0; 5],
            segments,
            tool_lever_arms: Vec::new(),
        };
        let planned = plan(&path).expect("the study's program plans");
        println!("{label}: total {:.6} s", planned.duration());
        for t in planned.segment_timings() {
            println!("  segment {}: {:.6} s", t.source_index, t.duration);
        }
        let speeds: Vec<String> = planned
            .junction_speeds()
            .iter()
            .map(|v| format!("{:.2}", v * 1e3))
            .collect();
        println!("  junction path speeds (mm/s): {}", speeds.join(", "));
        let sampled = planned.sample(1e-3);
        print!("  max |v| |a| |j| at 1 kHz (mm, deg):");
        for (axis, e) in axes.iter().zip(finite_difference_extremes(&sampled)) {
            let k = axis.kind.program_units_per_si();
            print!(
                "  {} {:.1} {:.1} {:.1}",
                axis.name,
                e.velocity * k,
                e.acceleration * k,
                e.jerk * k
            );
        }
        println!();
    }
}
