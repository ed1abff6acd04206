//! Helpers shared by the verification tests. Everything here works from sampled positions
//! only, independently of the planner's bookkeeping.
#![allow(dead_code)]

use cncsim::machine::Machine;
use cncsim::plan::{
    AxisKind, AxisLimits, AxisPath, AxisSpec, Blend, BlendChoice, Geometry, PathSegment, Plan,
    PlanSettings, Planner, SetpointSample, SetpointStream, Setpoints,
};

pub fn axis(name: &str, kind: AxisKind, v: f64, a: f64, j: f64) -> AxisSpec {
    AxisSpec {
        name: name.to_string(),
        kind,
        limits: AxisLimits {
            velocity: v,
            acceleration: a,
            jerk: j,
        },
    }
}

pub fn linear_axes(limits: &[(f64, f64, f64)]) -> Vec<AxisSpec> {
    limits
        .iter()
        .enumerate()
        .map(|(i, &(v, a, j))| axis(&format!("q{i}"), AxisKind::Linear, v, a, j))
        .collect()
}

pub fn line(end: &[f64], feed: Option<f64>, blend: Blend, index: u32) -> PathSegment {
    PathSegment {
        geometry: Geometry::Line { end: end.to_vec() },
        feed,
        feed_metric: vec![1.0; end.len()],
        blend,
        source_index: index,
    }
}

/// Positions of axis `i` over the samples.
pub fn column(sp: &Setpoints, i: usize) -> Vec<f64> {
    (0..sp.len()).map(|k| sp.position(k)[i]).collect()
}

/// Largest |k-th difference| / T^k of a sequence.
pub fn max_difference(q: &[f64], order: usize, period: f64) -> f64 {
    let mut d = q.to_vec();
    for _ in 0..order {
        d = d.windows(2).map(|w| w[1] - w[0]).collect();
    }
    d.iter().fold(0.0_f64, |m, x| m.max(x.abs())) / period.powi(order as i32)
}

/// Asserts that finite differences of the sampled positions respect every axis limit, allowing a
/// small relative excess plus the rounding floor of a k-th difference: each position carries a
/// few ulps of its magnitude, and the sample time k·T carries ε·t, which moves the position by
/// up to ε·t·v; a k-th difference adds 2^k of these.
pub fn assert_within_limits(sp: &Setpoints, axes: &[AxisSpec], rel: f64) {
    assert!(
        sp.position.iter().all(|x| x.is_finite()),
        "non-finite position"
    );
    let duration = sp.duration();
    for (i, axis) in axes.iter().enumerate() {
        let q = column(sp, i);
        let l = axis.limits;
        let magnitude = q.iter().fold(1e-3_f64, |m, x| m.max(x.abs()));
        let ulps = 4.0 * f64::EPSILON * (magnitude + duration * l.velocity);
        for (order, limit, what) in [
            (1, l.velocity, "velocity"),
            (2, l.acceleration, "acceleration"),
            (3, l.jerk, "jerk"),
        ] {
            let floor = 2f64.powi(order) * ulps / sp.period.powi(order);
            let found = max_difference(&q, order as usize, sp.period);
            assert!(
                found <= limit * (1.0 + rel) + floor,
                "axis {} {what}: {found} > limit {limit} (+ rounding {floor})",
                axis.name
            );
        }
    }
}

pub fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Smallest distance from any sample to `point`.
pub fn closest_approach(sp: &Setpoints, point: &[f64]) -> f64 {
    (0..sp.len())
        .map(|k| distance(sp.position(k), point))
        .fold(f64::INFINITY, f64::min)
}

/// Distance from `p` to the segment `a`–`b`.
pub fn distance_to_segment(p: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let ab: Vec<f64> = a.iter().zip(b).map(|(x, y)| y - x).collect();
    let len2: f64 = ab.iter().map(|x| x * x).sum();
    let t = if len2 > 0.0 {
        (p.iter()
            .zip(a)
            .zip(&ab)
            .map(|((p, a), d)| (p - a) * d)
            .sum::<f64>()
            / len2)
            .clamp(0.0, 1.0)
    } else {
        0.0
    };
    let closest: Vec<f64> = a.iter().zip(&ab).map(|(a, d)| a + t * d).collect();
    distance(p, &closest)
}

/// Largest distance from any sample to the polyline through `points`.
pub fn max_deviation_from_polyline(sp: &Setpoints, points: &[Vec<f64>]) -> f64 {
    (0..sp.len())
        .map(|k| {
            points
                .windows(2)
                .map(|w| distance_to_segment(sp.position(k), &w[0], &w[1]))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

/// The plan sampled finely for checking limits: fine enough to resolve every phase, coarse
/// enough that rounding stays far below the jerk limits in third differences.
pub fn fine(plan: &Plan) -> Setpoints {
    let period = (plan.duration() / 5_000.0).clamp(2e-4, 1e-3);
    plan.sample(period)
}

/// The plan sampled very finely for checking distances to programmed points: between samples
/// the path moves at most v·T, so the closest sample is within (v·T/2)²/(2·d) of the true
/// closest approach d on a smooth curve.
pub fn dense(plan: &Plan) -> Setpoints {
    plan.sample(1e-5)
}

/// Closed-form time-optimal rest-to-rest duration (Biagiotti & Melchiorri, "Trajectory
/// Planning for Automatic Machines and Robots", §3.4, with zero boundary velocities), written
/// independently of the planner: try each regime and keep the one whose assumptions hold.
pub fn closed_form_duration(length: f64, v: f64, a: f64, j: f64) -> f64 {
    let l = length.abs();
    if l == 0.0 {
        return 0.0;
    }
    // Velocity-limited: reaching V takes V/A + A/J if A is reached (V·J ≥ A²), else 2·sqrt(V/J).
    let t_reach = if v * j >= a * a {
        v / a + a / j
    } else {
        2.0 * (v / j).sqrt()
    };
    if l >= v * t_reach {
        return l / v + t_reach;
    }
    // Acceleration-limited (A reached, V not): T = A/J + sqrt((A/J)² + 4L/A).
    let t = a / j + ((a / j).powi(2) + 4.0 * l / a).sqrt();
    let peak = a * (t / 2.0 - a / j);
    if peak * j >= a * a && peak <= v {
        return t;
    }
    // Jerk-limited: T = 4·(L / 2J)^(1/3).
    4.0 * (l / (2.0 * j)).cbrt()
}

/// Rows per entity path in an .rrd file, decoded with the rerun crate.
pub fn rrd_rows(path: &std::path::Path) -> std::collections::BTreeMap<String, usize> {
    use rerun::external::re_log_encoding::DecoderApp;
    use rerun::log::{Chunk, LogMsg};
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut rows = std::collections::BTreeMap::new();
    for msg in DecoderApp::decode_lazy(file) {
        if let LogMsg::ArrowMsg(_, arrow) = msg.unwrap() {
            let chunk = Chunk::from_arrow_msg(&arrow).unwrap();
            // Rows on the run's timeline (static rows, e.g. series names, are not ticks); a
            // static-only entity still shows, with its rows.
            let timed = chunk.timelines().keys().any(|t| t.as_str() == "sim_time");
            let entry = rows.entry(chunk.entity_path().to_string()).or_insert(0);
            if timed || chunk.is_static() {
                *entry += if timed { chunk.num_rows() } else { 0 };
            }
        }
    }
    rows
}

/// Every data chunk of a recording, over all its stores (the blueprint's included), in the
/// order written.
pub fn rrd_chunks(path: &std::path::Path) -> Vec<rerun::log::Chunk> {
    use rerun::external::re_log_encoding::DecoderApp;
    use rerun::log::{Chunk, LogMsg};
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    DecoderApp::decode_lazy(file)
        .filter_map(|msg| match msg.unwrap() {
            LogMsg::ArrowMsg(_, arrow) => Some(Chunk::from_arrow_msg(&arrow).unwrap()),
            _ => None,
        })
        .collect()
}

/// Every string a recording holds, by entity path and component (e.g. `/events` →
/// `TextLog:text`), over all its stores (the blueprint's included), in the order written.
pub fn rrd_strings(
    path: &std::path::Path,
) -> std::collections::BTreeMap<String, Vec<(String, String)>> {
    let mut out: std::collections::BTreeMap<String, Vec<(String, String)>> = Default::default();
    for chunk in rrd_chunks(path) {
        let entity = chunk.entity_path().to_string();
        let components: Vec<_> = chunk.component_descriptors().map(|d| d.component).collect();
        for component in components {
            let is_text = chunk.components().get_array(component).is_some_and(|a| {
                matches!(
                    a.values().data_type(),
                    rerun::external::arrow::datatypes::DataType::Utf8
                        | rerun::external::arrow::datatypes::DataType::LargeUtf8
                )
            });
            if !is_text {
                continue;
            }
            for slice in chunk.iter_slices::<String>(component) {
                for s in slice {
                    out.entry(entity.clone())
                        .or_default()
                        .push((component.to_string(), s.to_string()));
                }
            }
        }
    }
    out
}

/// For each entity: (component, number of values) of every component a recording logs.
pub fn rrd_components(
    path: &std::path::Path,
) -> std::collections::BTreeMap<String, Vec<(String, usize)>> {
    let mut out: std::collections::BTreeMap<String, Vec<(String, usize)>> = Default::default();
    for chunk in rrd_chunks(path) {
        let entity = chunk.entity_path().to_string();
        let components: Vec<_> = chunk.component_descriptors().map(|d| d.component).collect();
        for component in components {
            if let Some(list) = chunk.components().get_array(component) {
                out.entry(entity.clone())
                    .or_default()
                    .push((component.to_string(), list.values().len()));
            }
        }
    }
    out
}

/// The machine's axes, each with velocity `v`, acceleration `a` and jerk `j` in program units
/// (mm or deg).
pub fn uniform_axes(machine: &Machine, v: f64, a: f64, j: f64) -> Vec<AxisSpec> {
    machine
        .axes
        .iter()
        .map(|axis| {
            let kind = if axis.is_rotary(machine) {
                AxisKind::Rotary
            } else {
                AxisKind::Linear
            };
            AxisSpec {
                name: axis.name.clone(),
                kind,
                limits: AxisLimits::from_program_units(kind, v, a, j),
            }
        })
        .collect()
}

pub fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Reads `stream` to its end, checking its length, and each sample from `from` on against
/// `expected` bit for bit.
pub fn assert_stream_equals(
    stream: &mut dyn SetpointStream,
    expected: &Setpoints,
    from: usize,
    what: &str,
) {
    assert_eq!(
        stream.len(),
        expected.len(),
        "{what}: length known up front"
    );
    assert_eq!(stream.axes(), expected.axes);
    assert_eq!(stream.period(), expected.period);
    let mut sample = SetpointSample::zeros(stream.axes());
    let mut k = 0;
    while stream.next_sample(&mut sample) {
        assert!(k < expected.len(), "{what}: more samples than announced");
        if k < from {
            k += 1;
            continue;
        }
        assert_eq!(
            bits(&sample.position),
            bits(expected.position(k)),
            "{what}: {k}"
        );
        assert_eq!(
            bits(&sample.velocity),
            bits(expected.velocity(k)),
            "{what}: {k}"
        );
        assert_eq!(
            bits(&sample.acceleration),
            bits(expected.acceleration(k)),
            "{what}: {k}"
        );
        assert_eq!(sample.segment, expected.segment[k], "{what}: {k}");
        k += 1;
    }
    assert_eq!(k, expected.len(), "{what}: fewer samples than announced");
    // An exhausted stream stays exhausted.
    assert!(!stream.next_sample(&mut sample));
}

/// A 5-axis program of `blocks` short lines (0.2–2 mm, with direction changes of a few degrees
/// and some collinear runs), like CAM output for a freeform surface, every junction `blend`:
/// the planner benchmark's path. With `sharp_corners`, a fifth of the turns are sharp (up to
/// 86°) and the rotary axes wander at random (corners that stop: chains of a few blocks);
/// without, the rotary axes turn steadily (one long chain).
pub fn random_walk(blocks: usize, blend: Blend, sharp_corners: bool) -> AxisPath {
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
            heading += if r < 0.8 || !sharp_corners {
                (random() - 0.5) * 0.3
            } else {
                (random() - 0.5) * 3.0
            };
        }
        let step = 0.2e-3 + 1.8e-3 * random();
        position[0] += step * heading.cos();
        position[1] += step * heading.sin();
        position[2] += 0.1 * step * (random() - 0.5);
        if sharp_corners {
            position[3] += 0.002 * (random() - 0.5);
            position[4] += 0.004 * (random() - 0.5);
        } else {
            position[3] += 0.2 * step;
            position[4] += 0.3 * step;
        }
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

/// The jerk-limited planner for [`raster_gcode`] programs on `machine`: v = 200 mm/s,
/// a = 2000 mm/s², j = 5·10⁴ mm/s³ on every axis, 1 ms, corners as programmed, every line planned
/// as written (naive-CAM joining off).
pub fn raster_settings(machine: &Machine) -> PlanSettings {
    PlanSettings {
        planner: Planner::JerkLimited {
            limits: vec![
                AxisLimits::from_program_units(AxisKind::Linear, 200.0, 2000.0, 5e4);
                machine.axes.len()
            ],
        },
        period: 1e-3,
        rapid_speed: 0.05,
        blend: BlendChoice::Program,
        axis_names: machine.axes.iter().map(|a| a.name.clone()).collect(),
        naive_cam_tolerance: Some(0.0),
        tool_lever_arms: Vec::new(),
    }
}

/// CAM raster output in G-code: `lines` moves of 1 mm along X on a smooth curve in Z, in rows
/// of 1000 alternating in direction, 0.5 mm apart in Y (no header, no end).
pub fn raster_gcode(lines: usize) -> String {
    use std::fmt::Write;
    let mut text = String::new();
    for k in 0..lines {
        let (row, step) = (k / 1000, k % 1000);
        let x = if row % 2 == 0 { step } else { 999 - step } as f64;
        let z = 2.0 * (x * 0.02).sin() + (x * 0.0031).cos();
        writeln!(text, "G1 X{x:.3} Y{:.3} Z{z:.4}", row as f64 * 0.5).unwrap();
    }
    text
}

/// Runs the `cncsim` binary with `args` from the repository's root.
pub fn cncsim(args: &[&str]) -> std::process::Output {
    // `option_env!`: examples include this module too (never calling this), and only tests
    // have the binary.
    #[allow(clippy::option_env_unwrap)]
    let binary = option_env!("CARGO_BIN_EXE_cncsim").expect("run from an integration test");
    std::process::Command::new(binary)
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap()
}

pub fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `cncsim COMMAND ARGS --json --out OUT`, expects success and returns the report.
pub fn cncsim_json(command: &str, args: &[&str], out: &std::path::Path) -> serde_json::Value {
    let mut all: Vec<&str> = vec![command];
    all.extend_from_slice(args);
    let out_s = out.display().to_string();
    all.extend_from_slice(&["--json", "--out", &out_s]);
    let o = cncsim(&all);
    assert!(o.status.success(), "cncsim {all:?} failed: {}", stderr(&o));
    serde_json::from_slice(&o.stdout).expect("--json prints JSON")
}

/// The Python interpreter of the oracles (`CNCSIM_PYTHON`, else `python3`) if it runs
/// `import_line`; without it the test is skipped, or fails under `CNCSIM_REQUIRE_ORACLES=1`.
/// `what` names the missing package in the message.
pub fn oracle_python(import_line: &str, what: &str) -> Option<String> {
    let python = std::env::var("CNCSIM_PYTHON").unwrap_or_else(|_| "python3".into());
    let ok = std::process::Command::new(&python)
        .args(["-c", import_line])
        .output()
        .is_ok_and(|o| o.status.success());
    if ok {
        return Some(python);
    }
    assert!(
        !std::env::var("CNCSIM_REQUIRE_ORACLES").is_ok_and(|v| v == "1"),
        "CNCSIM_REQUIRE_ORACLES=1 but {python} cannot import {what} (CNCSIM_PYTHON names the interpreter)"
    );
    eprintln!("skipped: {python} cannot import {what}");
    None
}

/// Whether the tests run in CI, where a missing oracle or corpus is a failure, not a skip:
/// `CNCSIM_REQUIRE_ORACLES=1` (set by `.ci/run`) or `CI=true`.
pub fn required_in_ci() -> bool {
    std::env::var("CNCSIM_REQUIRE_ORACLES").is_ok_and(|v| v == "1")
        || std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// `relative` in the shared corpus: files written by other projects (machines, part programs)
/// that this repository does not hold, kept in `../shared/corpus/` beside the checkout. `None`
/// (the test skips, saying in one line where they are expected) when it is missing, a failure
/// in CI ([`required_in_ci`]).
pub fn shared_corpus(relative: &str) -> Option<std::path::PathBuf> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    let path = root.join(relative);
    if path.exists() {
        return Some(path);
    }
    assert!(
        !required_in_ci(),
        "{} is missing: the shared corpus must sit beside the checkout in CI",
        path.display()
    );
    eprintln!(
        "skipped: {relative} not found in the shared corpus (expected at {})",
        path.display()
    );
    None
}

/// Every `*.urdf` under `dir`, depth first, in name order.
pub fn urdfs(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
    let mut entries: Vec<std::path::PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            urdfs(&p, out);
        } else if p.extension().is_some_and(|e| e == "urdf") {
            out.push(p);
        }
    }
}
