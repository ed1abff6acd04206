use std::f64::consts::PI;
use std::time::Instant;

use nalgebra::{Point3, Unit, Vector3};

use super::super::compare::compare;
use super::super::surface::mesh_volume;
use super::super::tool::ToolShape;
use super::*;

const MM: f64 = 1e-3;
const RES: f64 = 0.1 * MM;
const LIMIT: u64 = 1 << 30;

fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
    Point3::new(x * MM, y * MM, z * MM)
}

fn tool(diameter_mm: f64, shape: ToolShape) -> Tool {
    Tool {
        diameter: diameter_mm * MM,
        flutes: 3,
        helix: 0.5,
        flute_length: 20.0 * MM,
        shape,
    }
}

fn pose(tip: Point3<f64>, axis: Vector3<f64>) -> Pose {
    Pose {
        tip,
        axis: Unit::new_normalize(axis),
    }
}

fn z_up(tip: Point3<f64>) -> Pose {
    pose(tip, Vector3::z())
}

/// Every (position, leaving?) endpoint of `stock` that differs from `original`, all families.
fn changed_points(stock: &Stock, original: &Stock) -> Vec<(Point3<f64>, usize)> {
    let mut out = Vec::new();
    let res = stock.resolution();
    let o = stock.origin();
    for k in 0..3 {
        let (u, v) = ((k + 1) % 3, (k + 2) % 3);
        let f = stock.family(k);
        let fo = original.family(k);
        for jv in 0..f.nv {
            for ju in 0..f.nu {
                let idx = f.index(ju, jv);
                let orig: Vec<f32> = fo.intervals(idx).iter().flatten().copied().collect();
                for &x in f.intervals(idx).iter().flatten() {
                    if !orig.contains(&x) {
                        let mut q = o;
                        q[u] += ju as f64 * res;
                        q[v] += jv as f64 * res;
                        q[k] += f64::from(x);
                        out.push((q, k));
                    }
                }
            }
        }
    }
    out
}

#[test]
fn straight_slot_volume() {
    let original = Stock::from_box(p(0.0, -10.0, 0.0), p(40.0, 10.0, 10.0), RES, LIMIT).unwrap();
    let mut stock = original.clone();
    let t = tool(10.0, ToolShape::Flat);
    let yc = 0.0123;
    let removed = stock
        .remove_swept(&t, &z_up(p(-10.0, yc, 7.0)), &z_up(p(50.0, yc, 7.0)))
        .unwrap();
    let expected = 10.0 * 3.0 * 40.0 * MM * MM * MM;
    let rel = (removed - expected).abs() / expected;
    assert!(
        rel < 0.005,
        "removed {removed} expected {expected} rel {rel}"
    );
    let by_volume = original.volume() - stock.volume();
    assert!((by_volume - removed).abs() < 1e-6 * expected);
    // The floor is exact on every Z ray in the slot.
    for (q, k) in changed_points(&stock, &original) {
        if k == 2 && (q.y - yc * MM).abs() < 4.9 * MM {
            assert!((q.z - 7.0 * MM).abs() < 1e-8, "floor at {q}");
        }
    }
}

#[test]
fn ball_groove_section_and_circle() {
    let original = Stock::from_box(p(0.0, -10.0, 0.0), p(40.0, 10.0, 10.0), RES, LIMIT).unwrap();
    let mut stock = original.clone();
    let t = tool(10.0, ToolShape::Ball);
    let (r, d, yc) = (5.0 * MM, 2.0 * MM, 0.0371 * MM);
    let tip_z = 10.0 * MM - d;
    let from = z_up(Point3::new(-10.0 * MM, yc, tip_z));
    let to = z_up(Point3::new(50.0 * MM, yc, tip_z));
    let removed = stock.remove_swept(&t, &from, &to).unwrap();
    let area = r * r * ((r - d) / r).acos() - (r - d) * (2.0 * r * d - d * d).sqrt();
    let measured = removed / (40.0 * MM);
    let rel = (measured - area).abs() / area;
    assert!(rel < 0.005, "area {measured} expected {area} rel {rel}");
    // Groove points on the ball's circle (Y and Z families: exact along their rays).
    let centre_z = tip_z + r;
    let mut n = 0;
    for (q, k) in changed_points(&stock, &original) {
        if k == 0 {
            continue;
        }
        let dist = ((q.y - yc).powi(2) + (q.z - centre_z).powi(2)).sqrt();
        assert!(
            (dist - r).abs() < 1e-6,
            "point {q} at {dist} from the axis (family {k})"
        );
        n += 1;
    }
    assert!(n > 1000);
}

/// Signed distance of `q` from the plane through `a` with unit normal `n`.
fn plane_distance(q: &Point3<f64>, a: &Point3<f64>, n: &Vector3<f64>) -> f64 {
    (q - a).dot(n)
}

#[test]
fn tilted_flat_tool_cuts_exact_planes() {
    for tilt_deg in [30.0f64, 45.0] {
        let tilt = tilt_deg.to_radians();
        let original =
            Stock::from_box(p(-15.0, 0.0, 0.0), p(15.0, 20.0, 10.0), RES, LIMIT).unwrap();
        let t = tool(10.0, ToolShape::Flat);
        let axis = Vector3::new(tilt.sin(), 0.0, tilt.cos());
        // Bottom face: the tip moves along Y (in the bottom's plane), cutting the plane
        // through the tip with normal `axis`.
        let mut stock = original.clone();
        let tip = p(0.0, -10.0, 8.0);
        let end = p(0.0, 30.0, 8.0);
        stock
            .remove_swept(&t, &pose(tip, axis), &pose(end, axis))
            .unwrap();
        let u = Vector3::new(tilt.cos(), 0.0, -tilt.sin()); // In the bottom plane, ⊥ Y.
        let mut n = 0;
        for (q, _) in changed_points(&stock, &original) {
            let along = (q - tip).dot(&u);
            if along.abs() < 4.5 * MM && q.y > 0.5 * MM && q.y < 19.5 * MM {
                let e = plane_distance(&q, &tip, &axis);
                assert!(
                    e.abs() < 1e-6,
                    "tilt {tilt_deg}: bottom point {q} off by {e}"
                );
                n += 1;
            }
        }
        assert!(n > 500, "tilt {tilt_deg}: only {n} bottom points");

        // Flank: the side of the tilted tool moving along Y cuts the plane at distance R
        // from the axis line, normal to both the axis and Y.
        let mut stock = original.clone();
        let tip = p(-8.0, -10.0, 3.0);
        let end = p(-8.0, 30.0, 3.0);
        stock
            .remove_swept(&t, &pose(tip, axis), &pose(end, axis))
            .unwrap();
        let side = u; // Pointing from the axis toward +X (into the remaining material).
        let on_wall = tip + side * (5.0 * MM);
        let mut n = 0;
        for (q, _) in changed_points(&stock, &original) {
            let h = (q - tip).dot(&axis);
            let e = plane_distance(&q, &on_wall, &side);
            if h > 0.5 * MM && q.y > 0.5 * MM && q.y < 19.5 * MM && e.abs() < 0.5 * MM {
                assert!(
                    e.abs() < 1e-6,
                    "tilt {tilt_deg}: flank point {q} off by {e}"
                );
                n += 1;
            }
        }
        assert!(n > 500, "tilt {tilt_deg}: only {n} flank points");
    }
}

#[test]
fn side_milling_with_deviation() {
    let original = Stock::from_box(p(0.0, 0.0, 0.0), p(40.0, 20.0, 10.0), RES, LIMIT).unwrap();
    let t = tool(10.0, ToolShape::Flat);
    let amp = 5e-6;
    let delta = |x: f64| amp * (2.0 * PI * x / (20.0 * MM)).sin();
    let (y_wall, z_tip) = (2.0 * MM, 2.0 * MM);
    let centre_y = y_wall - 5.0 * MM;
    let mut nominal = original.clone();
    nominal
        .remove_swept(
            &t,
            &z_up(Point3::new(-10.0 * MM, centre_y, z_tip)),
            &z_up(Point3::new(50.0 * MM, centre_y, z_tip)),
        )
        .unwrap();
    let mut machined = original.clone();
    let steps = 300;
    let at = |i: usize| {
        let x = -10.0 * MM + 60.0 * MM * i as f64 / steps as f64;
        z_up(Point3::new(x, centre_y + delta(x), z_tip))
    };
    for i in 0..steps {
        machined.remove_swept(&t, &at(i), &at(i + 1)).unwrap();
    }
    let cmp = compare(&machined, &nominal, &original).unwrap();
    let mut wall = 0;
    let mut sum2 = 0.0;
    for pt in &cmp.points {
        let expected = if pt.normal.y.abs() > 0.9 {
            wall += 1;
            sum2 += pt.error * pt.error;
            -delta(pt.position.x)
        } else {
            0.0
        };
        assert!(
            (pt.error - expected).abs() < 1e-6,
            "at {} error {} expected {expected}",
            pt.position,
            pt.error
        );
    }
    assert!(wall > 1000, "{wall} wall points");
    assert!(
        (cmp.max_error - amp).abs() < 0.2e-6,
        "max {}",
        cmp.max_error
    );
    let wall_rms = (sum2 / wall as f64).sqrt();
    assert!(
        (wall_rms - amp / 2f64.sqrt()).abs() < 0.2e-6,
        "rms {wall_rms}"
    );
    assert!(cmp.rms_error <= wall_rms && cmp.rms_error > 0.0);
    assert!(cmp.removed_volume > 0.0);
}

#[test]
fn circular_boss_with_deviation() {
    let original = Stock::from_box(p(-15.0, -15.0, 0.0), p(15.0, 15.0, 10.0), RES, LIMIT).unwrap();
    let t = tool(6.0, ToolShape::Flat);
    let (boss, r) = (10.0 * MM, 3.0 * MM);
    let amp = 5e-6;
    let delta = |a: f64| amp * (3.0 * a).sin();
    let steps = 720;
    let path = |i: usize, dev: bool| {
        let a = 2.0 * PI * i as f64 / steps as f64;
        let rad = boss + r + if dev { delta(a) } else { 0.0 };
        z_up(Point3::new(rad * a.cos(), rad * a.sin(), 5.0 * MM))
    };
    let mut nominal = original.clone();
    let mut machined = original.clone();
    for i in 0..steps {
        nominal
            .remove_swept(&t, &path(i, false), &path(i + 1, false))
            .unwrap();
        machined
            .remove_swept(&t, &path(i, true), &path(i + 1, true))
            .unwrap();
    }
    let cmp = compare(&machined, &nominal, &original).unwrap();
    let mut wall = 0;
    for pt in &cmp.points {
        let q = pt.position;
        let rad = (q.x * q.x + q.y * q.y).sqrt();
        if q.z > 5.05 * MM && (rad - boss).abs() < 0.05 * MM {
            // The boss wall: tool centre further out leaves material (undercut, +).
            let expected = delta(q.y.atan2(q.x));
            assert!(
                (pt.error - expected).abs() < 1e-6,
                "at {q} (angle {}) error {} expected {expected}",
                q.y.atan2(q.x),
                pt.error
            );
            wall += 1;
        }
    }
    assert!(wall > 1000, "{wall} wall points");
    assert!(
        (cmp.max_error - amp).abs() < 0.5e-6,
        "max {}",
        cmp.max_error
    );
}

fn box_mesh(min: Point3<f64>, max: Point3<f64>) -> Vec<[Point3<f64>; 3]> {
    let c = |i: usize| {
        Point3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    };
    // Outward quads as corner indices, counter-clockwise seen from outside.
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    quads
        .iter()
        .flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]])
        .collect()
}

#[test]
fn mesh_stock_equals_box_stock() {
    let (min, max) = (p(0.0, 0.0, 0.0), p(20.03, 10.0, 7.51));
    let mesh = box_mesh(min, max);
    assert!(mesh_volume(&mesh) > 0.0);
    let from_mesh = Stock::from_triangles(&mesh, RES, LIMIT).unwrap();
    let from_box = Stock::from_box(min, max, RES, LIMIT).unwrap();
    let (a, b) = (from_mesh.volume(), from_box.volume());
    assert!((a - b).abs() < 1e-3 * b, "mesh {a} box {b}");
    let exact = 20.03 * 10.0 * 7.51 * MM * MM * MM;
    assert!((b - exact).abs() < 5e-3 * exact, "box {b} exact {exact}");
    // A mesh whose edges pass exactly through lattice lines: the tie rule keeps parity.
    let aligned = box_mesh(p(0.05, 0.05, 0.05), p(4.05, 3.05, 2.05));
    let s = Stock::from_triangles(&aligned, RES, LIMIT).unwrap();
    let v = 4.0 * 3.0 * 2.0 * MM * MM * MM;
    assert!(
        (s.volume() - v).abs() < 0.03 * v,
        "aligned {} vs {v}",
        s.volume()
    );
    let mut open = mesh.clone();
    open.pop();
    match Stock::from_triangles(&open, RES, LIMIT) {
        Err(StockError::OpenMesh { open_edges }) => assert_eq!(open_edges, 3),
        other => panic!("open mesh accepted: {other:?}"),
    }
    assert!(matches!(
        Stock::from_triangles(&[], RES, LIMIT),
        Err(StockError::BadMesh)
    ));
}

#[test]
fn memory_estimate_and_refusal() {
    let (min, max) = (p(0.0, 0.0, 0.0), p(100.0, 100.0, 50.0));
    let est = Stock::estimate_bytes(min, max, RES);
    assert!(est < 150_000_000, "estimate {est}");
    let stock = Stock::from_box(min, max, RES, 150_000_000).unwrap();
    let actual = stock.bytes();
    assert!(
        actual <= est && actual * 5 / 4 >= est - 1000,
        "actual {actual} estimate {est}"
    );
    let rays = 1002u64 * 1002 + 2 * 1002 * 502;
    eprintln!(
        "100x100x50 mm at 0.1 mm: estimate {est} B, actual {actual} B, {} B/ray",
        actual as f64 / rays as f64
    );
    match Stock::from_box(min, max, RES, 1_000_000) {
        Err(StockError::TooLarge { bytes, limit }) => {
            assert_eq!(bytes, est);
            assert_eq!(limit, 1_000_000);
        }
        other => panic!("not refused: {other:?}"),
    }
    // A request far past any memory is refused by the estimate, before allocating.
    let huge = Stock::from_box(min, p(10_000.0, 10_000.0, 10_000.0), 1e-6, u64::MAX / 2);
    assert!(huge.is_err());
    assert!(matches!(
        Stock::from_box(min, max, 0.0, LIMIT),
        Err(StockError::Resolution { .. })
    ));
    assert!(matches!(
        Stock::from_box(max, min, RES, LIMIT),
        Err(StockError::EmptyBox { .. })
    ));
}

fn cut_sample() -> Stock {
    let mut stock = Stock::from_box(p(0.0, 0.0, 0.0), p(20.0, 15.0, 8.0), RES, LIMIT).unwrap();
    let ball = tool(6.0, ToolShape::Ball);
    let flat = tool(4.0, ToolShape::Flat);
    let bull = tool(
        8.0,
        ToolShape::Bull {
            corner_radius: 1.0 * MM,
        },
    );
    stock
        .remove_swept(&ball, &z_up(p(-5.0, 4.0, 5.0)), &z_up(p(25.0, 9.0, 6.0)))
        .unwrap();
    stock
        .remove_swept(&flat, &z_up(p(3.0, -5.0, 2.5)), &z_up(p(12.0, 20.0, 2.5)))
        .unwrap();
    stock
        .remove_swept(
            &bull,
            &pose(p(15.0, 12.0, 6.0), Vector3::new(0.3, 0.1, 1.0)),
            &pose(p(18.0, 2.0, 5.5), Vector3::new(0.28, 0.05, 1.0)),
        )
        .unwrap();
    stock
}

#[test]
fn same_cuts_same_surface() {
    let a = cut_sample().surface();
    let b = cut_sample().surface();
    assert!(!a.is_empty());
    let bits = |m: &Vec<[Point3<f64>; 3]>| -> Vec<u64> {
        m.iter()
            .flatten()
            .flat_map(|q| q.iter().map(|c| c.to_bits()).collect::<Vec<_>>())
            .collect()
    };
    assert_eq!(bits(&a), bits(&b));
}

#[test]
fn the_streamed_surface_is_the_mesh_and_writes_the_same_stl() {
    let stock = cut_sample();
    let mesh = stock.surface_mesh();
    let streamed = stock.surface_triangles();
    assert_eq!(streamed.len(), mesh.triangles.len());
    assert_eq!(stock.surface_triangle_count(), mesh.triangles.len());
    let soup = mesh.triangle_soup();
    let mut n = 0;
    for (a, b) in streamed.zip(&soup) {
        assert_eq!(a, *b, "triangle {n}");
        n += 1;
    }
    assert_eq!(n, soup.len());
    let dir = tempfile::tempdir().unwrap();
    let (from_mesh, streamed) = (dir.path().join("mesh.stl"), dir.path().join("streamed.stl"));
    crate::cutting::write_binary_stl(&from_mesh, &mesh, true).unwrap();
    crate::cutting::write_binary_stl_triangles(&streamed, stock.surface_triangles(), true).unwrap();
    let bytes = std::fs::read(&streamed).unwrap();
    assert_eq!(std::fs::read(&from_mesh).unwrap(), bytes);
    assert_eq!(bytes.len(), 84 + 50 * soup.len());
}

#[test]
fn surface_is_watertight_and_encloses_the_volume() {
    let stock = cut_sample();
    let mesh = stock.surface_mesh();
    // Every undirected edge in exactly two triangles, once in each direction.
    let mut directed: Vec<(u32, u32)> = mesh
        .triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .collect();
    directed.sort_unstable();
    for w in directed.windows(2) {
        assert_ne!(w[0], w[1], "directed edge used twice");
    }
    for &(a, b) in &directed {
        assert!(directed.binary_search(&(b, a)).is_ok(), "edge {a}-{b} open");
    }
    let v_mesh = mesh_volume(&mesh.triangle_soup());
    let v = stock.volume();
    assert!((v_mesh - v).abs() < 0.005 * v, "mesh {v_mesh} dexels {v}");
}

#[test]
fn contains_reads_the_aligned_family() {
    let mut stock = Stock::from_box(p(0.0, 0.0, 0.0), p(10.0, 10.0, 10.0), RES, LIMIT).unwrap();
    let t = tool(4.0, ToolShape::Flat);
    stock
        .remove_swept(&t, &z_up(p(-5.0, 5.0, 6.0)), &z_up(p(15.0, 5.0, 6.0)))
        .unwrap();
    let up = Vector3::z();
    assert!(stock.contains(&p(5.0, 5.0, 5.9995), &up));
    assert!(!stock.contains(&p(5.0, 5.0, 6.0005), &up));
    assert!(!stock.contains(&p(50.0, 5.0, 5.0), &up));
    assert!(stock.take_changed().is_some());
    assert!(stock.take_changed().is_none());
}

#[test]
fn bad_inputs_are_errors() {
    let mut stock = Stock::from_box(p(0.0, 0.0, 0.0), p(5.0, 5.0, 5.0), RES, LIMIT).unwrap();
    let mut t = tool(4.0, ToolShape::Flat);
    t.diameter = f64::NAN;
    let a = z_up(p(0.0, 0.0, 0.0));
    assert_eq!(stock.remove_swept(&t, &a, &a), Err(StockError::BadTool));
    let t = tool(4.0, ToolShape::Flat);
    let bad = z_up(Point3::new(f64::INFINITY, 0.0, 0.0));
    assert_eq!(stock.remove_swept(&t, &a, &bad), Err(StockError::BadPose));
}

#[test]
fn turning_axis_is_subdivided() {
    // A ball tool turning about its ball centre cuts the same as a still one.
    let original = Stock::from_box(p(0.0, 0.0, 0.0), p(20.0, 20.0, 10.0), RES, LIMIT).unwrap();
    let t = tool(6.0, ToolShape::Ball);
    let mut still = original.clone();
    still
        .remove_swept(&t, &z_up(p(10.0, 10.0, 8.0)), &z_up(p(10.0, 10.0, 8.0)))
        .unwrap();
    let mut turning = original.clone();
    let c = p(10.0, 10.0, 11.0);
    let axis = Vector3::new(0.05f64.sin(), 0.0, 0.05f64.cos());
    let tip1 = c - axis * (3.0 * MM);
    let tip0 = p(10.0, 10.0, 8.0);
    turning
        .remove_swept(&t, &pose(tip0, Vector3::z()), &pose(tip1, axis))
        .unwrap();
    // The shank, which does move, stays above the block: the dent must match the still tool's.
    let r = 3.0 * MM;
    for (q, k) in changed_points(&turning, &original) {
        if k == 2 && (q - c).xy().norm() < 1.5 * MM {
            let dz = c.z - (r * r - (q - c).xy().norm_squared()).sqrt();
            assert!((q.z - dz).abs() < 1e-6, "{q}: {} vs {dz}", q.z);
        }
    }
    // A ball turned about its centre is the same ball: the same volume goes.
    let (v0, v1) = (original.volume(), still.volume());
    assert!(((v0 - turning.volume()) / (v0 - v1) - 1.0).abs() < 1e-4);
}

#[test]
fn a_turning_tool_in_one_call_cuts_as_in_two_thousand() {
    // Each shape tilts by 3° while moving 2 mm through a block, 12 mm deep: once, split into
    // sub-moves and height bands, and as 2000 calls of 0.0015° each (each then one sweep
    // of the whole tool, its far end at most 0.16 µm off). The surfaces agree within the
    // micrometre.
    let original = Stock::from_box(p(0.0, 0.0, 0.0), p(16.0, 14.0, 12.0), RES, LIMIT).unwrap();
    let turn = 3f64.to_radians();
    for shape in [
        ToolShape::Flat,
        ToolShape::Ball,
        ToolShape::Bull {
            corner_radius: 1.0 * MM,
        },
    ] {
        let t = tool(6.0, shape);
        let at = |f: f64| {
            let a = turn * f;
            pose(
                p(6.0 + 2.0 * f, 7.0, 1.0 + 0.5 * f),
                Vector3::new(a.sin(), 0.0, a.cos()),
            )
        };
        let mut once = original.clone();
        once.remove_swept(&t, &at(0.0), &at(1.0)).unwrap();
        let mut fine = original.clone();
        let n = 2000;
        for i in 0..n {
            let (f0, f1) = (i as f64 / n as f64, (i + 1) as f64 / n as f64);
            fine.remove_swept(&t, &at(f0), &at(f1)).unwrap();
        }
        let cmp = compare(&once, &fine, &original).unwrap();
        // Where the cut meets the block's untouched top face, and at a flat end's corner,
        // the comparison's normal (from neighbouring rays) mixes two faces: a ray grazing
        // the 3° wall there turns 0.3 µm across it into 6 µm along it. Those edge points are
        // counted, not bounded: fewer than 1 in 2000.
        let mut errors: Vec<f64> = cmp
            .points
            .iter()
            .filter(|q| q.position.z < 11.8 * MM)
            .map(|q| q.error.abs())
            .collect();
        errors.sort_by(f64::total_cmp);
        let n = errors.len();
        assert!(n > 20_000, "{shape:?}: {n} points");
        let beyond = errors.iter().filter(|e| **e > 1e-6).count();
        assert!(
            beyond * 2000 < n,
            "{shape:?}: {beyond} of {n} points beyond 1 µm"
        );
        let p999 = errors[n * 999 / 1000];
        assert!(
            p999 < 0.6e-6,
            "{shape:?}: 99.9 % within {:.3} µm",
            p999 * 1e6
        );
        let rel = (cmp.removed_volume - (original.volume() - fine.volume())).abs()
            / (original.volume() - fine.volume());
        assert!(rel < 1e-3, "{shape:?}: volume off by {rel}");
    }
}

/// The material of every ray of `stock`, slivers under 10 nm dropped and gaps under 10 nm
/// closed (what a nanometre-level contact decision may change).
fn rays(stock: &Stock) -> Vec<Vec<[f64; 2]>> {
    let mut out = Vec::new();
    for k in 0..3 {
        let f = stock.family(k);
        for idx in 0..f.nu * f.nv {
            let mut ivs: Vec<[f64; 2]> = Vec::new();
            for iv in f.intervals(idx) {
                let (a, b) = (f64::from(iv[0]), f64::from(iv[1]));
                match ivs.last_mut() {
                    Some(last) if a - last[1] < 1e-8 => last[1] = b,
                    _ => ivs.push([a, b]),
                }
            }
            ivs.retain(|iv| iv[1] - iv[0] >= 1e-8);
            out.push(ivs);
        }
    }
    out
}

#[test]
fn a_path_removed_at_once_is_its_moves_removed_one_by_one() {
    // Paths of 1 to 60 moves of 5 to 40 µm, each pose off its line by up to 1.5 µm (a tool
    // vibrating under load), the axis turning, one path turning back on itself: removed in
    // one pass and move by move, every ray keeps the same material to the nanometre.
    let original = Stock::from_box(p(0.0, 0.0, 0.0), p(14.0, 12.0, 8.0), RES, LIMIT).unwrap();
    let mut looked = (0, 0);
    for (case, shape) in [
        ToolShape::Flat,
        ToolShape::Ball,
        ToolShape::Bull {
            corner_radius: 1.0 * MM,
        },
    ]
    .into_iter()
    .enumerate()
    {
        let t = tool(6.0, shape);
        for (moves, step_um, turn, back) in [
            (1, 40.0, 0.0, false),
            (12, 30.0, 0.002, false),
            (60, 5.0, 0.0003, false),
            (40, 20.0, 0.0, true),
        ] {
            let pose_at = |i: usize| {
                let j = (i + 7 * case) as f64;
                let along = if back && i > moves / 2 { moves - i } else { i } as f64;
                let wobble = Vector3::new((j * 1.7).sin(), (j * 2.3).cos(), (j * 0.9).sin());
                let a = turn * i as f64;
                pose(
                    p(5.0, 4.0, 6.5)
                        + Vector3::new(1.0, 0.4, -0.2).normalize() * (along * step_um * 1e-6)
                        + wobble * 1.5e-6,
                    Vector3::new(a.sin(), 0.3 * a.sin(), a.cos()),
                )
            };
            let path: Vec<Pose> = (0..=moves).map(pose_at).collect();
            // The same start: the tool standing at the first pose.
            let mut start = original.clone();
            start.remove_swept(&t, &path[0], &path[0]).unwrap();
            let mut once = start.clone();
            once.remove_swept_path(&t, &path, default_reach(&t))
                .unwrap();
            let mut each = start.clone();
            for pair in path.windows(2) {
                each.remove_swept(&t, &pair[0], &pair[1]).unwrap();
            }
            looked.0 += once.rays_cut() - start.rays_cut();
            looked.1 += each.rays_cut() - start.rays_cut();
            let (a, b) = (rays(&once), rays(&each));
            let mut differ = 0;
            for (x, y) in a.iter().zip(&b) {
                let same = x.len() == y.len()
                    && x.iter()
                        .zip(y)
                        .all(|(i, j)| (i[0] - j[0]).abs() < 1e-8 && (i[1] - j[1]).abs() < 1e-8);
                differ += usize::from(!same);
            }
            assert_eq!(
                differ, 0,
                "{shape:?}, {moves} moves of {step_um} µm: {differ} rays differ"
            );
            assert!(once.volume() < start.volume() || moves == 1);
        }
    }
    // One pass looks at far fewer rays than the moves one by one.
    assert!(
        looked.0 * 2 < looked.1,
        "rays looked at: {} at once, {} one by one",
        looked.0,
        looked.1
    );
}

/// Timings for the report: `cargo test --release -- --ignored --nocapture timings`.
#[test]
#[ignore]
fn timings() {
    let mut stock = Stock::from_box(p(0.0, 0.0, 0.0), p(100.0, 100.0, 50.0), RES, 1 << 31).unwrap();
    for (name, t) in [
        ("flat", tool(10.0, ToolShape::Flat)),
        ("ball", tool(10.0, ToolShape::Ball)),
        (
            "bull",
            tool(
                10.0,
                ToolShape::Bull {
                    corner_radius: 2.0 * MM,
                },
            ),
        ),
    ] {
        for (label, axis) in [
            ("vertical", Vector3::z()),
            ("tilted", Vector3::new(0.3, 0.2, 1.0)),
        ] {
            let mut y = 5.0 * MM + 10.0 * MM * (name.len() as f64);
            let n = 50;
            let rays0 = stock.rays_cut();
            let start = Instant::now();
            for i in 0..n {
                let x0 = 10.0 * MM + i as f64 * 1.0 * MM;
                y += 0.01 * MM;
                stock
                    .remove_swept(
                        &t,
                        &pose(Point3::new(x0, y, 47.0 * MM), axis),
                        &pose(Point3::new(x0 + 1.0 * MM, y, 47.0 * MM), axis),
                    )
                    .unwrap();
            }
            let per = start.elapsed().as_secs_f64() / n as f64;
            let rays = (stock.rays_cut() - rays0) as f64 / n as f64;
            eprintln!(
                "{name} {label}: {:.3} ms per 1 mm move, {rays:.0} rays, {:.0} ns/ray",
                per * 1e3,
                per * 1e9 / rays
            );
        }
    }
    let small = cut_sample();
    let cells: usize = small.cells().iter().product();
    let start = Instant::now();
    let mesh = small.surface_mesh();
    eprintln!(
        "surface: {cells} cells, {} triangles in {:.1} ms",
        mesh.triangles.len(),
        start.elapsed().as_secs_f64() * 1e3
    );
    let start = Instant::now();
    let mesh = stock.surface_mesh();
    eprintln!(
        "surface of 100x100x50 mm at 0.1 mm: {} triangles in {:.1} ms",
        mesh.triangles.len(),
        start.elapsed().as_secs_f64() * 1e3
    );
}
