//! The stock's surface as a closed triangle mesh, and binary STL output.
//!
//! Marching cubes on the stock's lattice, whose grid lines are the dexel rays: a lattice
//! vertex is inside when the Z ray through it holds material there (`a ≤ z < b`), and a
//! crossed edge's mesh vertex is the exact dexel endpoint on the ray along that edge, not an
//! interpolation. The triangulation of each of the 256 cube cases is built once from the
//! cube's faces: on a face with two diagonal inside corners each inside corner is cut off
//! on its own (a rule that depends only on the face, so both cells sharing it agree), the
//! face segments chain into loops around the cube, and each loop is fanned into triangles.
//! Mesh vertices are shared by edge, so the mesh is watertight and consistently oriented,
//! with normals pointing out of the material. Only cells the surface crosses are visited:
//! per column of cells, between the layers where any of its four Z rays changes state.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::path::Path;
use std::sync::OnceLock;

use nalgebra::{Point3, Vector3};

use super::stock::{Family, Stock};

/// A triangle mesh with shared vertices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IndexedMesh {
    /// Vertex positions (m).
    pub vertices: Vec<Point3<f64>>,
    /// Triangles as vertex indices, counter-clockwise seen from outside the material.
    pub triangles: Vec<[u32; 3]>,
}

impl IndexedMesh {
    /// The triangles with their vertex positions.
    pub fn triangle_soup(&self) -> Vec<[Point3<f64>; 3]> {
        self.triangles
            .iter()
            .map(|t| t.map(|i| self.vertices[i as usize]))
            .collect()
    }
}

/// Corner `c` of the unit cube is at `(c & 1, (c >> 1) & 1, (c >> 2) & 1)`.
/// Edge `e` runs along axis `e / 4` from its lower corner `EDGE_LOW[e]`.
const EDGE_LOW: [u8; 12] = [0, 2, 4, 6, 0, 1, 4, 5, 0, 1, 2, 3];

fn edge_between(a: u8, b: u8) -> u8 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    let axis = match hi ^ lo {
        1 => 0,
        2 => 1,
        _ => 2,
    };
    (0..4)
        .map(|i| axis * 4 + i)
        .find(|&e| EDGE_LOW[e as usize] == lo)
        .unwrap_or(0)
}

/// Triangles (as cube edges) of each of the 256 corner-inside cases.
fn case_table() -> &'static [Vec<[u8; 3]>] {
    static TABLE: OnceLock<Vec<Vec<[u8; 3]>>> = OnceLock::new();
    TABLE.get_or_init(|| (0..256u32).map(|m| triangulate_case(m as u8)).collect())
}

fn triangulate_case(mask: u8) -> Vec<[u8; 3]> {
    let inside = |c: u8| mask & (1 << c) != 0;
    // next[e]: the crossed edge that the surface loop goes to from edge e.
    let mut next = [u8::MAX; 12];
    for axis in 0..3u8 {
        for side in 0..2u8 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let corner = |cu: u8, cv: u8| (side << axis) | (cu << u) | (cv << v);
            // Counter-clockwise seen from outside the cube: (u, v, axis) is right-handed, so
            // this order is counter-clockwise seen from +axis; reversed on the − side.
            let mut cs = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
            if side == 0 {
                cs.reverse();
            }
            let edge = |i: usize| edge_between(cs[i % 4], cs[(i + 1) % 4]);
            let ins: Vec<bool> = cs.iter().map(|&c| inside(c)).collect();
            let count = ins.iter().filter(|&&b| b).count();
            if count == 2 && ins[0] == ins[2] {
                // Diagonal: cut off each inside corner i, from its leaving edge i to its
                // arriving edge i − 1 (inside on the left seen from outside).
                for i in (0..4).filter(|&i| ins[i]) {
                    next[edge(i) as usize] = edge(i + 3);
                }
            } else if count > 0 && count < 4 {
                let leave = (0..4).find(|&i| ins[i] && !ins[(i + 1) % 4]);
                let enter = (0..4).find(|&i| !ins[i] && ins[(i + 1) % 4]);
                if let (Some(l), Some(e)) = (leave, enter) {
                    next[edge(l) as usize] = edge(e);
                }
            }
        }
    }
    let mut done = [false; 12];
    let mut tris = Vec::new();
    for start in 0..12 {
        if next[start] == u8::MAX || done[start] {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = start;
        while !done[e] && next[e] != u8::MAX {
            done[e] = true;
            lp.push(e as u8);
            e = next[e] as usize;
        }
        // The loop runs clockwise seen from outside the material: fan it reversed.
        for i in 1..lp.len().saturating_sub(1) {
            tris.push([lp[0], lp[i + 1], lp[i]]);
        }
    }
    tris
}

/// Multiplicative hash for edge keys (they are dense integers; no attacker to resist).
#[derive(Default)]
struct EdgeHasher(u64);

impl Hasher for EdgeHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (i ^ (i >> 29)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// Lattice index range `[k0, k1)` of vertices inside `[a, b)` at spacing `res`, `k ≤ kmax`.
fn vertex_run(a: f32, b: f32, res: f64, kmax: usize) -> (usize, usize) {
    let first = |x: f64| {
        // Smallest k with k·res ≥ x, decided by the same product the queries use.
        let mut k = (x / res).ceil().max(0.0) as usize;
        while k > 0 && (k - 1) as f64 * res >= x {
            k -= 1;
        }
        while k <= kmax && (k as f64 * res) < x {
            k += 1;
        }
        k.min(kmax + 1)
    };
    (first(f64::from(a)), first(f64::from(b)))
}

/// Whether the ray holds material at along-ray offset `s`.
#[inline]
fn ray_inside(ivs: &[[f32; 2]], s: f64) -> bool {
    ivs.iter()
        .any(|iv| f64::from(iv[0]) <= s && s < f64::from(iv[1]))
}

/// The along-ray offset where the edge `[lo, hi]` of the ray crosses the surface, going
/// from inside to outside when `lo_inside`. The exact endpoint when the ray has one of that
/// kind on the edge; otherwise (the families disagree about a vertex the surface passes
/// within rounding of) the ray's endpoint nearest the edge, clamped onto it.
fn crossing(ivs: &[[f32; 2]], lo: f64, hi: f64, lo_inside: bool) -> f64 {
    let kind = if lo_inside { 1 } else { 0 };
    let mut best: Option<f64> = None;
    for iv in ivs {
        let s = f64::from(iv[kind]);
        if s > lo && s <= hi {
            return s;
        }
    }
    let mid = 0.5 * (lo + hi);
    for iv in ivs {
        for &x in iv {
            let s = f64::from(x);
            if best.is_none_or(|b| (s - mid).abs() < (b - mid).abs()) {
                best = Some(s);
            }
        }
    }
    best.unwrap_or(mid).clamp(lo, hi)
}

/// The four Z rays of one column of cells and the scratch its walk needs.
#[derive(Default)]
struct ColumnScratch {
    breaks: Vec<usize>,
    cells: Vec<usize>,
}

impl Stock {
    /// Visits the cells of column `(ix, iy)` the surface crosses, bottom up: `visit(k, mask)`
    /// with the cube's inside-corner mask (corner `c` at `(c & 1, (c >> 1) & 1, (c >> 2) & 1)`).
    /// Only the layers where any of the column's four Z rays changes state are looked at.
    fn surface_cells_of_column(
        &self,
        ix: usize,
        iy: usize,
        scratch: &mut ColumnScratch,
        visit: &mut impl FnMut(usize, u8),
    ) {
        let nz = self.cells()[2];
        let res = self.resolution();
        let fz = self.family(2);
        let rays = [
            fz.intervals(fz.index(ix, iy)),
            fz.intervals(fz.index(ix + 1, iy)),
            fz.intervals(fz.index(ix, iy + 1)),
            fz.intervals(fz.index(ix + 1, iy + 1)),
        ];
        if rays.iter().all(|r| r.is_empty()) {
            return;
        }
        // Layers where any of the four rays changes state.
        let ColumnScratch { breaks, cells } = scratch;
        breaks.clear();
        for r in &rays {
            for iv in r.iter() {
                let (k0, k1) = vertex_run(iv[0], iv[1], res, nz);
                breaks.push(k0);
                breaks.push(k1);
            }
        }
        breaks.push(0);
        breaks.push(nz + 1);
        breaks.sort_unstable();
        breaks.dedup();
        cells.clear();
        for w in breaks.windows(2) {
            let (p, q) = (w[0], w[1]);
            // Within [p, q) every ray keeps its state: the cells there are crossed only if
            // the rays disagree. Cell q − 1 reaches the next run.
            let s = p as f64 * res;
            let st0 = ray_inside(rays[0], s);
            let disagree = rays[1..].iter().any(|r| ray_inside(r, s) != st0);
            let last = q.min(nz);
            if disagree {
                cells.extend(p..last);
            } else if q > p && q - 1 < nz {
                cells.push(q - 1);
            }
        }
        for &k in cells.iter() {
            let mut mask = 0u8;
            for c in 0..8u8 {
                let r = rays[(c & 3) as usize];
                let kk = k + (c >> 2) as usize;
                if ray_inside(r, kk as f64 * res) {
                    mask |= 1 << c;
                }
            }
            if mask != 0 && mask != u8::MAX {
                visit(k, mask);
            }
        }
    }

    /// The lattice vertex at the low end of cube edge `e` of cell `(ix, iy, k)`, and the
    /// edge's axis.
    fn edge_origin(ix: usize, iy: usize, k: usize, e: u8) -> ([usize; 3], usize) {
        let low = EDGE_LOW[e as usize];
        (
            [
                ix + (low & 1) as usize,
                iy + ((low >> 1) & 1) as usize,
                k + ((low >> 2) & 1) as usize,
            ],
            (e / 4) as usize,
        )
    }

    /// The mesh vertex on cube edge `e` of cell `(ix, iy, k)` whose inside mask is `mask`.
    fn cell_edge_point(&self, ix: usize, iy: usize, k: usize, mask: u8, e: u8) -> Point3<f64> {
        let (vi, axis) = Self::edge_origin(ix, iy, k, e);
        let lo_inside = mask & (1 << EDGE_LOW[e as usize]) != 0;
        let fam = [self.family(0), self.family(1), self.family(2)];
        edge_point(self.origin(), self.resolution(), vi, axis, lo_inside, fam)
    }

    /// The material's surface as a closed, consistently oriented triangle mesh with shared
    /// vertices (normals pointing out of the material). Features thinner than one lattice
    /// cell may be lost, as in any marching cubes.
    pub fn surface_mesh(&self) -> IndexedMesh {
        let [nx, ny, _] = self.cells();
        let table = case_table();
        let mut mesh = IndexedMesh::default();
        let mut ids: HashMap<u64, u32, BuildHasherDefault<EdgeHasher>> = HashMap::default();
        let mut scratch = ColumnScratch::default();
        for iy in 0..ny {
            for ix in 0..nx {
                self.surface_cells_of_column(ix, iy, &mut scratch, &mut |k, mask| {
                    for tri in &table[mask as usize] {
                        let t = tri.map(|e| {
                            let (vi, axis) = Self::edge_origin(ix, iy, k, e);
                            let key = ((((vi[2] * (ny + 1) + vi[1]) * (nx + 1) + vi[0]) * 3) + axis)
                                as u64;
                            let next_id = mesh.vertices.len() as u32;
                            let id = *ids.entry(key).or_insert(next_id);
                            if id == next_id {
                                mesh.vertices.push(self.cell_edge_point(ix, iy, k, mask, e));
                            }
                            id
                        });
                        mesh.triangles.push(t);
                    }
                });
            }
        }
        mesh
    }

    /// How many triangles [`Stock::surface_mesh`] has, without making them.
    pub fn surface_triangle_count(&self) -> usize {
        let [nx, ny, _] = self.cells();
        let table = case_table();
        let mut scratch = ColumnScratch::default();
        let mut count = 0;
        for iy in 0..ny {
            for ix in 0..nx {
                self.surface_cells_of_column(ix, iy, &mut scratch, &mut |_, mask| {
                    count += table[mask as usize].len();
                });
            }
        }
        count
    }

    /// The triangles of [`Stock::surface_mesh`] one column of cells at a time, in the same
    /// order and with the same vertex positions (each edge's vertex is the exact dexel
    /// endpoint, found the same way from either cell): the surface streamed, without the
    /// whole mesh in memory.
    pub fn surface_triangles(&self) -> SurfaceTriangles<'_> {
        SurfaceTriangles {
            stock: self,
            column: 0,
            count: self.surface_triangle_count(),
            buffer: Vec::new(),
            next: 0,
            scratch: ColumnScratch::default(),
        }
    }

    /// The material's surface as triangles (m), normals pointing out of the material; see
    /// [`Stock::surface_mesh`].
    pub fn surface(&self) -> Vec<[Point3<f64>; 3]> {
        self.surface_mesh().triangle_soup()
    }

    /// The surface drawn on a lattice coarse enough to have at most about `max_triangles`
    /// triangles (every k-th ray, see [`Stock::subsampled`]); the stock's own lattice where
    /// that is fine enough already.
    pub fn surface_coarse(&self, max_triangles: usize) -> Vec<[Point3<f64>; 3]> {
        // A closed surface crossing the lattice has some 2 triangles per cell face it cuts;
        // the stock's outer faces bound how many cells that is (the cut adds a few times more).
        let [a, b, c] = self.cells().map(|n| n as f64);
        let faces = 2.0 * (a * b + b * c + c * a);
        let k = ((8.0 * faces / max_triangles.max(1) as f64).sqrt().ceil() as usize).max(1);
        self.subsampled(k).surface()
    }
}

/// The stock's surface triangles (m), streamed column by column: see
/// [`Stock::surface_triangles`].
pub struct SurfaceTriangles<'a> {
    stock: &'a Stock,
    /// Next column to walk, `iy·nx + ix`.
    column: usize,
    /// Triangles not yet returned.
    count: usize,
    buffer: Vec<[Point3<f64>; 3]>,
    next: usize,
    scratch: ColumnScratch,
}

impl Iterator for SurfaceTriangles<'_> {
    type Item = [Point3<f64>; 3];

    fn next(&mut self) -> Option<Self::Item> {
        let [nx, ny, _] = self.stock.cells();
        while self.next == self.buffer.len() {
            if self.column >= nx * ny {
                return None;
            }
            let (ix, iy) = (self.column % nx, self.column / nx);
            self.column += 1;
            self.buffer.clear();
            self.next = 0;
            let (stock, buffer, table) = (self.stock, &mut self.buffer, case_table());
            stock.surface_cells_of_column(ix, iy, &mut self.scratch, &mut |k, mask| {
                for tri in &table[mask as usize] {
                    buffer.push(tri.map(|e| stock.cell_edge_point(ix, iy, k, mask, e)));
                }
            });
        }
        self.next += 1;
        self.count -= 1;
        Some(self.buffer[self.next - 1])
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.count, Some(self.count))
    }
}

impl ExactSizeIterator for SurfaceTriangles<'_> {}

/// The mesh vertex on the lattice edge from vertex `vi` along `axis`.
fn edge_point(
    o: Point3<f64>,
    res: f64,
    vi: [usize; 3],
    axis: usize,
    lo_inside: bool,
    fam: [&Family; 3],
) -> Point3<f64> {
    let f = fam[axis];
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let ivs = f.intervals(f.index(vi[u], vi[v]));
    let lo = vi[axis] as f64 * res;
    let s = crossing(ivs, lo, lo + res, lo_inside);
    let mut p = Point3::new(
        o.x + vi[0] as f64 * res,
        o.y + vi[1] as f64 * res,
        o.z + vi[2] as f64 * res,
    );
    p[axis] = o[axis] + s;
    p
}

/// Volume enclosed by a closed, outward-oriented triangle mesh (m³), by the divergence
/// theorem (relative to the first vertex, for precision).
pub fn mesh_volume(triangles: &[[Point3<f64>; 3]]) -> f64 {
    let Some(first) = triangles.first() else {
        return 0.0;
    };
    let c = first[0];
    triangles
        .iter()
        .map(|t| {
            let (a, b, d) = (t[0] - c, t[1] - c, t[2] - c);
            a.dot(&b.cross(&d))
        })
        .sum::<f64>()
        / 6.0
}

/// Writes a mesh (m) as a binary STL, in millimetres when `scale_to_mm` (the usual unit of STL
/// files), else in metres. See [`write_binary_stl_triangles`].
pub fn write_binary_stl(path: &Path, mesh: &IndexedMesh, scale_to_mm: bool) -> std::io::Result<()> {
    let vertex = |i: u32| mesh.vertices[i as usize];
    write_binary_stl_triangles(
        path,
        mesh.triangles.iter().map(|t| t.map(vertex)),
        scale_to_mm,
    )
}

/// Writes triangles (m) as a binary STL, in millimetres when `scale_to_mm`, else in metres.
/// Each facet's normal is its vertices' right-hand normal. Facets are made as they are
/// written: a part of millions of triangles streamed from [`Stock::surface_triangles`] takes
/// no copy in memory.
pub fn write_binary_stl_triangles(
    path: &Path,
    triangles: impl ExactSizeIterator<Item = [Point3<f64>; 3]>,
    scale_to_mm: bool,
) -> std::io::Result<()> {
    let scale = if scale_to_mm { 1000.0 } else { 1.0 };
    let facets = triangles.map(|[a, b, c]| {
        let n: Vector3<f64> = (b - a).cross(&(c - a));
        let n = n.try_normalize(0.0).unwrap_or_else(Vector3::zeros);
        stl_io::Triangle {
            normal: stl_io::Normal::new([n.x as f32, n.y as f32, n.z as f32]),
            vertices: [a, b, c].map(|p| {
                stl_io::Vertex::new([
                    (p.x * scale) as f32,
                    (p.y * scale) as f32,
                    (p.z * scale) as f32,
                ])
            }),
        }
    });
    let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
    stl_io::write_stl(&mut file, facets)?;
    std::io::Write::flush(&mut file)
}
