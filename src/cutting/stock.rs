//! The workpiece as a tri-dexel model.
//!
//! Three families of parallel rays (along X, along Y and along Z) sit on the lines of one
//! regular lattice of spacing `resolution`: the lattice's vertices are
//! `origin + (i, j, k)·resolution`, and every lattice line parallel to an axis is a ray of that
//! axis' family. Each ray stores the sorted, disjoint, half-open intervals `[a, b)` of material
//! along it, as `f32` offsets from the lattice origin's coordinate on that axis (100 mm at `f32`
//! is about 7 nm: the along-ray coordinate is exact to far below 1 µm). Because the three
//! families share the lattice's vertices, marching cubes on the lattice finds each edge's
//! crossing as an exact dexel endpoint (see the `surface` module).
//!
//! The lattice reaches half a cell beyond the stock's box on every side, so that its outermost
//! vertices are always in air and the surface closes.

mod sweep;

use std::fmt;

use nalgebra::{Point3, Vector3};

use super::tool::{Pose, Tool, ToolShape};
use rayon::prelude::*;
use sweep::{GroupTree, Sweep};

/// `more` value of a dexel whose intervals are inline (zero or one interval).
const INLINE: u32 = u32::MAX;

/// Bytes of one ray's inline record.
const DEXEL_BYTES: u64 = std::mem::size_of::<Dexel>() as u64;

/// Most cells the lattice may have along one axis (keeps indices and `f32` offsets sane).
const MAX_CELLS_PER_AXIS: f64 = 1.0e7;

/// One ray: its single interval inline, or an index into the family's overflow pool when it
/// holds two or more (rare: only rays crossing a slot, pocket or boss). 12 bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Dexel {
    /// The inline interval `[iv[0], iv[1])`; empty when `iv[0] >= iv[1]`. Unused when `more`
    /// points into the pool.
    iv: [f32; 2],
    /// [`INLINE`], or the pool slot holding this ray's intervals.
    more: u32,
}

const EMPTY: Dexel = Dexel {
    iv: [0.0, 0.0],
    more: INLINE,
};

/// One family of parallel rays along `axis`.
#[derive(Debug, Clone)]
pub(crate) struct Family {
    /// Rays along the family's first transverse axis `(axis + 1) % 3`.
    pub(crate) nu: usize,
    /// Rays along the family's second transverse axis `(axis + 2) % 3`.
    pub(crate) nv: usize,
    dexels: Vec<Dexel>,
    /// Interval lists of the rays holding two or more intervals.
    pool: Vec<Vec<[f32; 2]>>,
    /// Free pool slots, reused last-freed first (deterministic).
    free: Vec<u32>,
}

impl Family {
    fn new(nu: usize, nv: usize) -> Family {
        Family {
            nu,
            nv,
            dexels: vec![EMPTY; nu * nv],
            pool: Vec::new(),
            free: Vec::new(),
        }
    }

    /// Index of the ray at transverse lattice indices `(iu, iv)`.
    #[inline]
    pub(crate) fn index(&self, iu: usize, iv: usize) -> usize {
        iv * self.nu + iu
    }

    /// The ray's material intervals, sorted and disjoint.
    #[inline]
    pub(crate) fn intervals(&self, idx: usize) -> &[[f32; 2]] {
        let d = &self.dexels[idx];
        if d.more != INLINE {
            &self.pool[d.more as usize]
        } else if d.iv[0] < d.iv[1] {
            std::slice::from_ref(&d.iv)
        } else {
            &[]
        }
    }

    /// Replaces the ray's intervals (sorted, disjoint, non-empty ones).
    fn set(&mut self, idx: usize, ivs: &[[f32; 2]]) {
        let d = self.dexels[idx];
        if ivs.len() <= 1 {
            if d.more != INLINE {
                self.pool[d.more as usize] = Vec::new();
                self.free.push(d.more);
            }
            self.dexels[idx] = Dexel {
                iv: ivs.first().copied().unwrap_or([0.0, 0.0]),
                more: INLINE,
            };
        } else if d.more != INLINE {
            let v = &mut self.pool[d.more as usize];
            v.clear();
            v.extend_from_slice(ivs);
        } else {
            let slot = match self.free.pop() {
                Some(s) => {
                    self.pool[s as usize] = ivs.to_vec();
                    s
                }
                None => {
                    self.pool.push(ivs.to_vec());
                    (self.pool.len() - 1) as u32
                }
            };
            self.dexels[idx] = Dexel {
                iv: [0.0, 0.0],
                more: slot,
            };
        }
    }

    /// Removes `[s0, s1)` from the ray; returns the length removed (m).
    fn subtract(&mut self, idx: usize, s0: f32, s1: f32) -> f64 {
        if s0 >= s1 {
            return 0.0;
        }
        let d = self.dexels[idx];
        if d.more == INLINE {
            // Fast path: most rays hold one interval and stay inline.
            let [a, b] = d.iv;
            if a >= b || s1 <= a || s0 >= b {
                return 0.0;
            }
            let removed = f64::from(s1.min(b)) - f64::from(s0.max(a));
            match (a < s0, s1 < b) {
                (true, true) => self.set(idx, &[[a, s0], [s1, b]]),
                (true, false) => self.dexels[idx].iv = [a, s0],
                (false, true) => self.dexels[idx].iv = [s1, b],
                (false, false) => self.dexels[idx] = EMPTY,
            }
            return removed;
        }
        let old = &self.pool[d.more as usize];
        let mut out: Vec<[f32; 2]> = Vec::with_capacity(old.len() + 1);
        let mut removed = 0.0;
        for &[a, b] in old {
            if s1 <= a || s0 >= b {
                out.push([a, b]);
                continue;
            }
            removed += f64::from(s1.min(b)) - f64::from(s0.max(a));
            if a < s0 {
                out.push([a, s0]);
            }
            if s1 < b {
                out.push([s1, b]);
            }
        }
        if removed > 0.0 {
            self.set(idx, &out);
        }
        removed
    }

    /// Total material length of all rays (m).
    fn total_length(&self) -> f64 {
        (0..self.dexels.len())
            .map(|i| {
                self.intervals(i)
                    .iter()
                    .map(|iv| f64::from(iv[1]) - f64::from(iv[0]))
                    .sum::<f64>()
            })
            .sum()
    }

    fn bytes(&self) -> u64 {
        let pool: u64 = self
            .pool
            .iter()
            .map(|v| (std::mem::size_of::<Vec<[f32; 2]>>() + v.capacity() * 8) as u64)
            .sum();
        self.dexels.capacity() as u64 * DEXEL_BYTES + pool + self.free.capacity() as u64 * 4
    }
}

/// Why a stock could not be made or used.
#[derive(Debug, Clone, PartialEq)]
pub enum StockError {
    /// The box is empty, inverted or not finite.
    EmptyBox {
        /// Its lower corner (m).
        min: Point3<f64>,
        /// Its upper corner (m).
        max: Point3<f64>,
    },
    /// The resolution is not a positive finite length, or too fine for the box.
    Resolution {
        /// The resolution asked for (m).
        resolution: f64,
    },
    /// The stock would need more memory than allowed.
    TooLarge {
        /// Estimated bytes.
        bytes: u64,
        /// The limit (bytes).
        limit: u64,
    },
    /// The triangle mesh is not closed.
    OpenMesh {
        /// Edges not shared by an even number of triangles.
        open_edges: usize,
    },
    /// The triangle mesh has no triangles or a vertex that is not finite.
    BadMesh,
    /// The tool is not a valid cutter (non-positive or non-finite size, corner radius out of
    /// range).
    BadTool,
    /// A pose has a non-finite tip or a zero or non-finite axis.
    BadPose,
    /// Two stocks compared do not share one lattice.
    LatticeMismatch,
}

impl fmt::Display for StockError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StockError::EmptyBox { min, max } => write!(
                f,
                "stock box is empty or not finite: min ({}, {}, {}) m, max ({}, {}, {}) m",
                min.x, min.y, min.z, max.x, max.y, max.z
            ),
            StockError::Resolution { resolution } => write!(
                f,
                "stock resolution {resolution} m is not a positive length fitting the box"
            ),
            StockError::TooLarge { bytes, limit } => write!(
                f,
                "stock would need about {bytes} bytes, more than the limit of {limit} bytes"
            ),
            StockError::OpenMesh { open_edges } => {
                write!(f, "stock mesh is not closed: {open_edges} open edges")
            }
            StockError::BadMesh => write!(f, "stock mesh is empty or has non-finite vertices"),
            StockError::BadTool => write!(f, "tool has an invalid size or corner radius"),
            StockError::BadPose => write!(f, "tool pose has a non-finite tip or a zero axis"),
            StockError::LatticeMismatch => write!(f, "stocks compared do not share one lattice"),
        }
    }
}

impl std::error::Error for StockError {}

/// A workpiece in the part's frame (m), as three families of dexels.
#[derive(Debug, Clone)]
pub struct Stock {
    /// Lattice vertex (0, 0, 0) (m).
    origin: Point3<f64>,
    /// Lattice spacing (m).
    res: f64,
    /// Cells along each axis; vertices are `n + 1`.
    n: [usize; 3],
    /// The X, Y and Z families.
    fam: [Family; 3],
    /// Bounding box of what the cuts since the last [`Stock::take_changed`] may have touched.
    changed: Option<(Point3<f64>, Point3<f64>)>,
    /// Rays cut against a sweep so far (a diagnostic of removal cost).
    rays_cut: u64,
}

/// The lattice covering `[min, max]`: its origin and cells per axis.
fn lattice(
    min: Point3<f64>,
    max: Point3<f64>,
    resolution: f64,
) -> Result<(Point3<f64>, [usize; 3]), StockError> {
    let finite = min.iter().chain(max.iter()).all(|v| v.is_finite());
    if !finite || (0..3).any(|a| min[a] >= max[a]) {
        return Err(StockError::EmptyBox { min, max });
    }
    if !(resolution.is_finite() && resolution > 0.0) {
        return Err(StockError::Resolution { resolution });
    }
    let mut n = [0usize; 3];
    for a in 0..3 {
        // Half a cell of air on each side: the outermost vertices are outside the box.
        let cells = ((max[a] - min[a]) / resolution - 1e-9).ceil() + 1.0;
        if !(cells.is_finite() && cells <= MAX_CELLS_PER_AXIS) {
            return Err(StockError::Resolution { resolution });
        }
        n[a] = cells.max(1.0) as usize;
    }
    let origin = min - Vector3::repeat(0.5 * resolution);
    Ok((origin, n))
}

/// Rays of all three families for cells `n`.
fn ray_count(n: [usize; 3]) -> u64 {
    let v = n.map(|c| c as u64 + 1);
    v[0] * v[1] + v[1] * v[2] + v[2] * v[0]
}

/// Default length of the tool taken as solid above its tip: the flutes, and a shank of the
/// tool's diameter up to at least 4 diameters above the tip.
pub fn default_reach(tool: &Tool) -> f64 {
    tool.flute_length.max(4.0 * tool.diameter)
}

impl Stock {
    /// Estimated bytes of a stock of the box `[min, max]` at `resolution`, before anything is
    /// allocated: 12 bytes per ray with a quarter more for rays that later hold several
    /// intervals. `u64::MAX` for a box or resolution that [`Stock::from_box`] would refuse.
    pub fn estimate_bytes(min: Point3<f64>, max: Point3<f64>, resolution: f64) -> u64 {
        match lattice(min, max, resolution) {
            Ok((_, n)) => {
                let base = ray_count(n).saturating_mul(DEXEL_BYTES);
                base.saturating_add(base / 4)
                    .saturating_add(std::mem::size_of::<Stock>() as u64)
            }
            Err(_) => u64::MAX,
        }
    }

    /// An empty stock on the lattice covering `[min, max]`, once its estimate fits the limit.
    fn empty(
        min: Point3<f64>,
        max: Point3<f64>,
        resolution: f64,
        memory_limit: u64,
    ) -> Result<Stock, StockError> {
        let (origin, n) = lattice(min, max, resolution)?;
        let bytes = Stock::estimate_bytes(min, max, resolution);
        if bytes > memory_limit {
            return Err(StockError::TooLarge {
                bytes,
                limit: memory_limit,
            });
        }
        let fam = [0, 1, 2].map(|a| Family::new(n[(a + 1) % 3] + 1, n[(a + 2) % 3] + 1));
        Ok(Stock {
            origin,
            res: resolution,
            n,
            fam,
            changed: None,
            rays_cut: 0,
        })
    }

    /// A block `[min, max]` (m) at lattice spacing `resolution` (m), refused without
    /// allocating when [`Stock::estimate_bytes`] exceeds `memory_limit` (bytes).
    pub fn from_box(
        min: Point3<f64>,
        max: Point3<f64>,
        resolution: f64,
        memory_limit: u64,
    ) -> Result<Stock, StockError> {
        let mut stock = Stock::empty(min, max, resolution, memory_limit)?;
        for k in 0..3 {
            let (u, v) = ((k + 1) % 3, (k + 2) % 3);
            let iv = [
                (min[k] - stock.origin[k]) as f32,
                (max[k] - stock.origin[k]) as f32,
            ];
            let inside = |a: usize, i: usize| {
                let p = stock.origin[a] + i as f64 * resolution;
                p >= min[a] && p < max[a]
            };
            let (nu, nv) = (stock.fam[k].nu, stock.fam[k].nv);
            for jv in (0..nv).filter(|&j| inside(v, j)) {
                for ju in (0..nu).filter(|&j| inside(u, j)) {
                    let idx = stock.fam[k].index(ju, jv);
                    stock.fam[k].dexels[idx] = Dexel { iv, more: INLINE };
                }
            }
        }
        Ok(stock)
    }

    /// Every `k`-th ray of each family, on the lattice of spacing `k`·resolution from the same
    /// origin: the same solid seen coarser (for display). Its rays are rays of this stock, so
    /// their endpoints are as exact as here; only features narrower than the coarse cells are
    /// lost.
    pub fn subsampled(&self, k: usize) -> Stock {
        let k = k.max(1);
        if k == 1 {
            return self.clone();
        }
        let n = self.n.map(|c| c.div_ceil(k));
        let fam = [0, 1, 2].map(|a| {
            let old = &self.fam[a];
            let mut f = Family::new(n[(a + 1) % 3] + 1, n[(a + 2) % 3] + 1);
            for jv in 0..f.nv {
                for ju in 0..f.nu {
                    let (ou, ov) = (ju * k, jv * k);
                    if ou < old.nu && ov < old.nv {
                        let ivs = old.intervals(old.index(ou, ov)).to_vec();
                        let idx = f.index(ju, jv);
                        f.set(idx, &ivs);
                    }
                }
            }
            f
        });
        Stock {
            origin: self.origin,
            res: self.res * k as f64,
            n,
            fam,
            changed: None,
            rays_cut: 0,
        }
    }

    /// The solid bounded by a closed triangle mesh (m), e.g. a part's STL, at lattice spacing
    /// `resolution`. Each ray's intervals come from its crossings with the triangles by parity.
    /// A ray through an edge or a vertex is decided as if moved by an infinitesimal
    /// `(ε, ε²)` in its transverse plane, computed on each edge in one canonical direction so
    /// that the triangles sharing the edge agree: it crosses exactly one of them (or, at a
    /// silhouette, none or both), never a parity error. Meshes with open edges (edges not
    /// shared by an even number of triangles, matched by exact vertex coordinates) are refused.
    pub fn from_triangles(
        triangles: &[[Point3<f64>; 3]],
        resolution: f64,
        memory_limit: u64,
    ) -> Result<Stock, StockError> {
        if triangles.is_empty()
            || triangles
                .iter()
                .any(|t| t.iter().any(|p| p.iter().any(|c| !c.is_finite())))
        {
            return Err(StockError::BadMesh);
        }
        let open_edges = count_open_edges(triangles);
        if open_edges > 0 {
            return Err(StockError::OpenMesh { open_edges });
        }
        let mut min = triangles[0][0];
        let mut max = min;
        for p in triangles.iter().flatten() {
            min = min.inf(p);
            max = max.sup(p);
        }
        let mut stock = Stock::empty(min, max, resolution, memory_limit)?;
        for k in 0..3 {
            stock.fill_family_from_triangles(k, triangles);
        }
        Ok(stock)
    }

    fn fill_family_from_triangles(&mut self, k: usize, triangles: &[[Point3<f64>; 3]]) {
        let (u, v) = ((k + 1) % 3, (k + 2) % 3);
        let res = self.res;
        let o = self.origin;
        let (nu, nv) = (self.fam[k].nu, self.fam[k].nv);
        // (ray index, along-ray offset) of every crossing; sorted afterwards.
        let mut hits: Vec<(usize, f64)> = Vec::new();
        for t in triangles {
            // Transverse coordinates relative to the lattice origin, and along-ray offsets.
            let q = t.map(|p| [p[u] - o[u], p[v] - o[v], p[k] - o[k]]);
            let area = (q[1][0] - q[0][0]) * (q[2][1] - q[0][1])
                - (q[1][1] - q[0][1]) * (q[2][0] - q[0][0]);
            if area == 0.0 {
                continue; // Parallel to the rays: never crossed.
            }
            let lo_u = q.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
            let hi_u = q.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max);
            let lo_v = q.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
            let hi_v = q.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max);
            let iu0 = ((lo_u / res).floor().max(0.0)) as usize;
            let iu1 = ((hi_u / res).ceil().max(0.0) as usize).min(nu - 1);
            let iv0 = ((lo_v / res).floor().max(0.0)) as usize;
            let iv1 = ((hi_v / res).ceil().max(0.0) as usize).min(nv - 1);
            for jv in iv0..=iv1 {
                let pv = jv as f64 * res;
                for ju in iu0..=iu1 {
                    let pu = ju as f64 * res;
                    // Edge functions opposite each vertex, each with its sign of the
                    // triangle's orientation when the point is inside.
                    let mut w = [0.0; 3];
                    let mut inside = true;
                    for e in 0..3 {
                        let (a, b) = (q[(e + 1) % 3], q[(e + 2) % 3]);
                        let f = edge_function(a, b, pu, pv);
                        if (f > 0.0) != (area > 0.0) {
                            inside = false;
                            break;
                        }
                        w[e] = f.abs();
                    }
                    if !inside {
                        continue;
                    }
                    let sum = w[0] + w[1] + w[2];
                    let s = if sum > 0.0 {
                        (w[0] * q[0][2] + w[1] * q[1][2] + w[2] * q[2][2]) / sum
                    } else {
                        (q[0][2] + q[1][2] + q[2][2]) / 3.0
                    };
                    hits.push((self.fam[k].index(ju, jv), s));
                }
            }
        }
        hits.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let len = self.n[k] as f64 * res;
        let mut ivs: Vec<[f32; 2]> = Vec::new();
        let mut i = 0;
        while i < hits.len() {
            let ray = hits[i].0;
            let mut j = i;
            while j < hits.len() && hits[j].0 == ray {
                j += 1;
            }
            ivs.clear();
            // Pairs of crossings bound the material; an unpaired last one (only from a
            // numerically inconsistent mesh) is dropped.
            for pair in hits[i..j].chunks_exact(2) {
                let a = pair[0].1.clamp(0.0, len) as f32;
                let b = pair[1].1.clamp(0.0, len) as f32;
                if a < b {
                    match ivs.last_mut() {
                        Some(last) if last[1] >= a => last[1] = last[1].max(b),
                        _ => ivs.push([a, b]),
                    }
                }
            }
            self.fam[k].set(ray, &ivs);
            i = j;
        }
    }

    /// Lattice spacing (m).
    pub fn resolution(&self) -> f64 {
        self.res
    }

    /// The lattice's extent (m): the stock's box with half a cell of air on each side.
    pub fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let max =
            Point3::from(self.origin.coords + Vector3::from_fn(|a, _| self.n[a] as f64 * self.res));
        (self.origin, max)
    }

    /// Lattice vertex `(0, 0, 0)` (m).
    pub fn origin(&self) -> Point3<f64> {
        self.origin
    }

    /// Cells along X, Y and Z (the lattice has one more vertex than cells along each axis).
    pub fn cells(&self) -> [usize; 3] {
        self.n
    }

    pub(crate) fn family(&self, axis: usize) -> &Family {
        &self.fam[axis]
    }

    /// Removes what the tool's solid sweeps moving from `from` to `to` (the tip moving on a
    /// straight line, the axis turning uniformly in the plane of both axes), the tool being
    /// solid up to [`default_reach`] above its tip. Returns the removed volume (m³) as the
    /// dexels measure it (the mean of the three families' measures).
    pub fn remove_swept(&mut self, tool: &Tool, from: &Pose, to: &Pose) -> Result<f64, StockError> {
        self.remove_swept_path(tool, &[*from, *to], default_reach(tool))
    }

    /// [`Stock::remove_swept`] with the tool solid up to `reach` (m) above its tip (raised to
    /// at least twice the corner radius).
    pub fn remove_swept_reach(
        &mut self,
        tool: &Tool,
        from: &Pose,
        to: &Pose,
        reach: f64,
    ) -> Result<f64, StockError> {
        self.remove_swept_path(tool, &[*from, *to], reach)
    }

    /// Removes what the tool sweeps along a path of poses, each consecutive two a move as in
    /// [`Stock::remove_swept`] (one pose: the tool standing there), the tool solid up to
    /// `reach` (m) above its tip. The same solid as the moves removed one by one, found in one
    /// pass over the rays: each ray is read once, and a move whose reach on the ray lies
    /// within what the path's other moves already take from it costs no exact geometry (the
    /// path's first and last moves are taken first: along a path that does not turn back they
    /// hold most rays' ends). Refused as a whole, nothing removed, when any pose is invalid.
    ///
    /// A straight move with a fixed axis sweeps a convex solid, cut from each ray exactly
    /// (closed form for flat and ball ends, converged Newton iterations for the bull nose's
    /// corner). When the axis turns by θ, the move is split into `N` sub-moves, and each
    /// sub-move's tool into height bands, each band swept with the sub-move's middle axis
    /// about its own pivot on the axis (the pivot follows its true path; see
    /// [`band_layout`]). A point of a band at distance `E` from its pivot is then off its true
    /// path by at most `E·θ/(2N)`, held to [`ROTATION_TOLERANCE`]: rotation costs in
    /// proportion to the band's half-height (0.5 mm at least), not to the tool's length;
    /// only the flat end's face and a bull nose's disc, which turn with the axis, need their
    /// radius as `E`. At most [`MAX_SUBSTEPS`] sub-moves (then the bound grows accordingly).
    /// Callers that step in small time steps, as the co-simulation does, turn by little in
    /// each call and need few sub-moves. Heights of the tool that cannot be in the stock
    /// (its axis farther than the radius from the stock's box) are not swept.
    pub fn remove_swept_path(
        &mut self,
        tool: &Tool,
        path: &[Pose],
        reach: f64,
    ) -> Result<f64, StockError> {
        let radius = tool.radius();
        let corner = tool.corner_radius();
        let valid = radius.is_finite()
            && radius > 0.0
            && (0.0..=radius).contains(&corner)
            && reach.is_finite()
            && reach > 0.0;
        if !valid {
            return Err(StockError::BadTool);
        }
        let reach = reach.max(2.0 * corner).max(radius);
        // Each move's sweeps, the path's last move first: along a path that does not turn
        // back it holds most rays' ends (the earlier moves' leading sides lie within it, their
        // trailing sides in material the path's start already left), so the other moves are
        // mostly within what it takes.
        let mut sweeps = Vec::new();
        let mut moves = vec![0];
        match path {
            [] => {}
            [only] => self.sweeps_of_move(tool, only, only, reach, &mut sweeps)?,
            _ => {
                for pair in path.windows(2) {
                    self.sweeps_of_move(tool, &pair[0], &pair[1], reach, &mut sweeps)?;
                    moves.push(sweeps.len());
                }
            }
        }
        let last = moves[moves.len().saturating_sub(2)];
        let (others, last) = sweeps.split_at(last);
        Ok(self.remove_sweeps(
            &last.iter().collect::<Vec<_>>(),
            &others.iter().collect::<Vec<_>>(),
        ))
    }

    /// The fixed-axis straight sweeps that make up one move (see
    /// [`Stock::remove_swept_path`]), appended to `out`.
    fn sweeps_of_move(
        &self,
        tool: &Tool,
        from: &Pose,
        to: &Pose,
        reach: f64,
        out: &mut Vec<Sweep>,
    ) -> Result<(), StockError> {
        let radius = tool.radius();
        let corner = tool.corner_radius();
        let mut axes = [Vector3::zeros(); 2];
        for (axis, pose) in axes.iter_mut().zip([from, to]) {
            let a = pose.axis.into_inner();
            let norm = a.norm();
            if !(pose.tip.iter().all(|c| c.is_finite()) && norm.is_finite() && norm > 0.0) {
                return Err(StockError::BadPose);
            }
            *axis = a / norm;
        }
        let angle = axes[0].dot(&axes[1]).clamp(-1.0, 1.0).acos();
        // The tool's far end turns with the axis where it can be in the stock.
        let end_in_stock = [(from.tip, axes[0]), (to.tip, axes[1])]
            .iter()
            .any(|(tip, a)| self.highest_in_stock(&[*tip], a, radius) > reach);
        let (steps, half_band) = if angle > 1e-12 {
            let turning = turning_lever(tool, end_in_stock);
            let steps = (angle * turning / (2.0 * ROTATION_TOLERANCE))
                .ceil()
                .clamp(1.0, MAX_SUBSTEPS);
            (
                steps as usize,
                (2.0 * ROTATION_TOLERANCE * steps / angle).max(MIN_HALF_BAND),
            )
        } else {
            (1, f64::INFINITY)
        };
        for i in 0..steps {
            let t0 = i as f64 / steps as f64;
            let t1 = (i + 1) as f64 / steps as f64;
            let p0 = from.tip + (to.tip - from.tip) * t0;
            let p1 = from.tip + (to.tip - from.tip) * t1;
            let [a0, a1, axis] =
                [t0, t1, 0.5 * (t0 + t1)].map(|t| slerp(&axes[0], &axes[1], angle, t));
            // A band's pivot moves at most half a band's turn off the tip's fixed-axis path.
            let margin = radius + reach * (a1 - a0).norm() + ROTATION_TOLERANCE;
            let top = self.highest_in_stock(&[p0, p1], &axis, margin);
            if top < 0.0 {
                continue;
            }
            let top = top.min(reach).max(radius).max(2.0 * corner);
            for band in band_layout(tool, top, half_band, top >= reach && end_in_stock) {
                let shift = |a: &Vector3<f64>| (a - axis) * band.pivot;
                let sweep = Sweep::new(
                    tool,
                    band.lo,
                    band.hi,
                    p0 + shift(&a0),
                    p1 + shift(&a1),
                    axis,
                );
                out.push(sweep);
            }
        }
        Ok(())
    }

    /// The highest a point of the axis `a` above any of the tips can be while within
    /// `margin` of the stock's box in every coordinate (m; negative where the axis never
    /// comes that near). An upper bound: each coordinate bounds the height on its own.
    fn highest_in_stock(&self, tips: &[Point3<f64>], a: &Vector3<f64>, margin: f64) -> f64 {
        let (lo, hi) = self.bounds();
        let mut top = f64::INFINITY;
        for k in 0..3 {
            if a[k].abs() < 1e-12 {
                continue;
            }
            let bound = if a[k] > 0.0 {
                hi[k] + margin
            } else {
                lo[k] - margin
            };
            let most = tips
                .iter()
                .map(|tip| (bound - tip[k]) / a[k])
                .fold(f64::NEG_INFINITY, f64::max);
            top = top.min(most);
        }
        top
    }

    /// Cuts fixed-axis straight sweeps from every ray in their bounding boxes, in one pass over
    /// the rays: on each ray the `ends` first (a path's last move), then the `others`, asked
    /// as the groups of a [`GroupTree`] and skipped a group at a time where its bound reaches
    /// no material the sweeps so far leave.
    fn remove_sweeps(&mut self, ends: &[&Sweep], others: &[&Sweep]) -> f64 {
        let (lo, hi) = self.bounds();
        let meets_stock = |sweep: &&&Sweep| {
            let (bmin, bmax) = sweep.bounds();
            (0..3).all(|a| bmax[a] >= lo[a] && bmin[a] <= hi[a])
        };
        let ends: Vec<&Sweep> = ends.iter().filter(meets_stock).copied().collect();
        let middle: Vec<&Sweep> = others.iter().filter(meets_stock).copied().collect();
        let Some((bmin, bmax)) = ends
            .iter()
            .chain(&middle)
            .map(|s| s.bounds())
            .reduce(|(a, b), (c, d)| (a.inf(&c), b.sup(&d)))
        else {
            return 0.0;
        };
        self.changed = Some(match self.changed {
            Some((a, b)) => (a.inf(&bmin), b.sup(&bmax)),
            None => (bmin, bmax),
        });
        let tree = GroupTree::new(&middle);
        let mut total = 0.0;
        for k in 0..3 {
            let end_lanes: Vec<Lane> = ends.iter().filter_map(|s| self.lane(s, k)).collect();
            let middle_lanes: Vec<Option<Lane>> = middle.iter().map(|s| self.lane(s, k)).collect();
            let all = || end_lanes.iter().chain(middle_lanes.iter().flatten());
            let Some(iu0) = all().map(|l| l.iu.0).min() else {
                continue;
            };
            let iu1 = all().map(|l| l.iu.1).max().unwrap_or(iu0);
            let iv0 = all().map(|l| l.iv.0).min().unwrap_or(0);
            let iv1 = all().map(|l| l.iv.1).max().unwrap_or(iv0);
            let lanes = end_lanes.len() + middle_lanes.iter().flatten().count();
            let (u, v) = ((k + 1) % 3, (k + 2) % 3);
            let (res, o) = (self.res, self.origin);
            let family = &self.fam[k];
            // One row of rays: the intervals to remove, found from the stock as it is (rows
            // are independent, so they may be found in parallel and applied in order), and
            // how many (ray, sweep) pairs took the sweep's geometry.
            let row = |jv: usize| -> RowCuts {
                let mut cuts = Vec::new();
                let mut looked = 0;
                let pv = o[v] + jv as f64 * res;
                // Each lane's rays of the row its bound can meet.
                let span = |lane: &Lane| -> Option<(usize, usize)> {
                    if !(lane.iv.0..=lane.iv.1).contains(&jv) {
                        return None;
                    }
                    let (u0, u1) = lane.ray.row_span(pv)?;
                    let first = ((u0 - o[u]) / res).ceil().max(lane.iu.0 as f64);
                    let last = ((u1 - o[u]) / res).floor().min(lane.iu.1 as f64);
                    (first <= last).then_some((first as usize, last as usize))
                };
                let end_here: Vec<(usize, usize, usize)> = end_lanes
                    .iter()
                    .enumerate()
                    .filter_map(|(i, lane)| span(lane).map(|(a, b)| (i, a, b)))
                    .collect();
                let middle_here: Vec<Option<(usize, usize)>> = middle_lanes
                    .iter()
                    .map(|lane| lane.as_ref().and_then(span))
                    .collect();
                let spans = || {
                    end_here
                        .iter()
                        .map(|h| (h.1, h.2))
                        .chain(middle_here.iter().flatten().copied())
                };
                let Some(ju0) = spans().map(|h| h.0).min() else {
                    return (cuts, looked);
                };
                let ju1 = spans().map(|h| h.1).max().unwrap_or(ju0);
                let middle_span = (
                    middle_here
                        .iter()
                        .flatten()
                        .map(|h| h.0)
                        .min()
                        .unwrap_or(usize::MAX),
                    middle_here.iter().flatten().map(|h| h.1).max().unwrap_or(0),
                );
                for ju in ju0..=ju1 {
                    let idx = family.index(ju, jv);
                    let ivs = family.intervals(idx);
                    let (Some(lowest), Some(highest)) = (ivs.first(), ivs.last()) else {
                        continue;
                    };
                    let material = (f64::from(lowest[0]), f64::from(highest[1]));
                    let mut p = o;
                    p[u] += ju as f64 * res;
                    p[v] = pv;
                    let mut taken = Taken::default();
                    // Whether the ray has material within `[a, b]` the sweeps so far leave
                    // (by more than a nanometre: a wall the same tool left, touched again,
                    // is not worth the exact geometry).
                    let more = |taken: &Taken, a: f64, b: f64| {
                        ivs.iter().any(|iv| {
                            let (x, y) = (f64::from(iv[0]).max(a), f64::from(iv[1]).min(b));
                            y - x > CONTACT_ONLY && !taken.holds(x, y)
                        })
                    };
                    let mut cut = |lane: &Lane, taken: &mut Taken| {
                        let (a, b) = (lane.s.0.max(material.0), lane.s.1.min(material.1));
                        if a >= b {
                            return;
                        }
                        let Some((c0, c1)) = lane.ray.bound(&p) else {
                            return;
                        };
                        let (a, b) = (a.max(c0), b.min(c1));
                        if !more(taken, a, b) {
                            return;
                        }
                        looked += 1;
                        if let Some((s0, s1)) = lane.ray.interval(&p, a, b) {
                            taken.add(s0, s1);
                            cuts.push((idx, s0 as f32, s1 as f32));
                        }
                    };
                    for &(i, first, last) in &end_here {
                        if (first..=last).contains(&ju) {
                            cut(&end_lanes[i], &mut taken);
                        }
                    }
                    if !(middle_span.0..=middle_span.1).contains(&ju) {
                        continue;
                    }
                    // The other moves, where they can reach material the ends leave: the
                    // tree's groups, later halves first (nearer the ends, they are likelier
                    // to take what the earlier ones would).
                    let mut stack = [0usize; 64];
                    let mut depth = 1;
                    while depth > 0 {
                        depth -= 1;
                        let node = &tree.nodes[stack[depth]];
                        let reach = node
                            .bound
                            .as_ref()
                            .map_or(Some(material), |g| g.bound(&p, k));
                        match reach {
                            Some((g0, g1))
                                if more(&taken, g0.max(material.0), g1.min(material.1)) => {}
                            _ => continue,
                        }
                        match node.halves {
                            Some((earlier, later)) if depth + 2 <= stack.len() => {
                                stack[depth] = earlier;
                                stack[depth + 1] = later;
                                depth += 2;
                            }
                            _ => {
                                for i in node.sweeps.clone() {
                                    let (Some(lane), Some((first, last))) =
                                        (&middle_lanes[i], middle_here[i])
                                    else {
                                        continue;
                                    };
                                    if (first..=last).contains(&ju) {
                                        cut(lane, &mut taken);
                                    }
                                }
                            }
                        }
                    }
                }
                (cuts, looked)
            };
            // The work: the rays in the box, each asked of a few sweeps (the others are mostly
            // skipped by their groups).
            let rays = (iu1 + 1 - iu0) * (iv1 + 1 - iv0) * lanes.min(4);
            let rows = iv0..=iv1;
            let cuts: Vec<RowCuts> = if rays >= PARALLEL_RAYS {
                rows.into_par_iter().map(row).collect()
            } else {
                rows.map(row).collect()
            };
            let mut removed = 0.0;
            for (row_cuts, looked) in cuts {
                self.rays_cut += looked;
                for (idx, s0, s1) in row_cuts {
                    removed += self.fam[k].subtract(idx, s0, s1);
                }
            }
            total += removed;
        }
        total * self.res * self.res / 3.0
    }

    /// The rays of family `k` a sweep can meet: their index ranges and the span along them.
    fn lane<'a>(&self, sweep: &'a Sweep, k: usize) -> Option<Lane<'a>> {
        let (bmin, bmax) = sweep.bounds();
        let (res, o) = (self.res, self.origin);
        let (u, v) = ((k + 1) % 3, (k + 2) % 3);
        let range = |a: usize| {
            let i0 = ((bmin[a] - o[a]) / res).ceil().max(0.0);
            let i1 = ((bmax[a] - o[a]) / res).floor().min(self.n[a] as f64);
            (i0 <= i1).then_some((i0 as usize, i1 as usize))
        };
        let len = self.n[k] as f64 * res;
        let s = ((bmin[k] - o[k]).max(0.0), (bmax[k] - o[k]).min(len));
        (s.0 <= s.1).then_some(Lane {
            ray: sweep.for_axis(k),
            iu: range(u)?,
            iv: range(v)?,
            s,
        })
    }

    /// Whether material is at `point` (m), read from the family of rays most aligned with
    /// `normal_hint` (the surface normal expected there), on the ray through the lattice
    /// vertex nearest to `point` in that family's transverse plane: the along-ray coordinate,
    /// which is exact, decides, and the transverse one is rounded to the lattice.
    pub fn contains(&self, point: &Point3<f64>, normal_hint: &Vector3<f64>) -> bool {
        let k = most_aligned(normal_hint);
        let (u, v) = ((k + 1) % 3, (k + 2) % 3);
        let rel = point - self.origin;
        if !rel.iter().all(|c| c.is_finite()) {
            return false;
        }
        // The nearest lattice line, rounded by a cast once within the lattice: `f64::round` is
        // a library call, and the force model asks this many times per step.
        let (fu, fv) = (rel[u] / self.res + 0.5, rel[v] / self.res + 0.5);
        if !(fu >= 0.0 && fv >= 0.0 && fu < self.n[u] as f64 + 1.0 && fv < self.n[v] as f64 + 1.0) {
            return false;
        }
        let (iu, iv) = (fu as usize, fv as usize);
        let f = &self.fam[k];
        let s = rel[k];
        f.intervals(f.index(iu, iv))
            .iter()
            .any(|iv| f64::from(iv[0]) <= s && s < f64::from(iv[1]))
    }

    /// Material volume (m³): the mean of the three families' measures (each ray's material
    /// length times the cell area `resolution²`). Each family is exact along its rays and
    /// quantised across them; the mean halves the quantisation bias of walls parallel to
    /// one family.
    pub fn volume(&self) -> f64 {
        let sum: f64 = self.fam.iter().map(Family::total_length).sum();
        sum * self.res * self.res / 3.0
    }

    /// Bytes the stock holds now (rays, overflow intervals and bookkeeping).
    pub fn bytes(&self) -> u64 {
        std::mem::size_of::<Stock>() as u64 + self.fam.iter().map(Family::bytes).sum::<u64>()
    }

    /// How many times removals have intersected a ray with a tool's sweep so far (a ray
    /// without material the sweep can reach, beyond what the path's other moves take, is
    /// skipped and not counted): the measure of removal cost.
    pub fn rays_cut(&self) -> u64 {
        self.rays_cut
    }

    /// Rays that hold more than one interval, over all three families (the overflow pool's
    /// users).
    pub fn multi_interval_rays(&self) -> usize {
        self.fam.iter().map(|f| f.pool.len() - f.free.len()).sum()
    }

    /// The bounding box (m) of everything cut since the last call (or since the stock was
    /// made), and forgets it; `None` when nothing was cut. The surface may have changed only
    /// inside it (grown by one cell), for an incremental display.
    pub fn take_changed(&mut self) -> Option<(Point3<f64>, Point3<f64>)> {
        self.changed.take()
    }
}

/// Index of the largest-magnitude component (0 for a zero or non-finite vector).
pub(crate) fn most_aligned(n: &Vector3<f64>) -> usize {
    let a = n.map(f64::abs);
    if a.y > a.x && a.y >= a.z {
        1
    } else if a.z > a.x && a.z > a.y {
        2
    } else {
        0
    }
}

/// What one row's rays lose: (ray index, interval) pairs, and how many (ray, sweep) pairs
/// took the sweep's geometry.
type RowCuts = (Vec<(usize, f32, f32)>, u64);

/// A sweep prepared for one family's rays: the lattice indices `(iu, iv)` of the rays its box
/// holds (inclusive) and its span `s` along them (m from the lattice origin).
struct Lane<'a> {
    ray: sweep::RaySweep<'a>,
    iu: (usize, usize),
    iv: (usize, usize),
    s: (f64, f64),
}

/// The parts of one ray that sweeps of a path take (a few intervals, merged where they meet).
#[derive(Default, Clone, Copy)]
struct Taken {
    intervals: [(f64, f64); 4],
    count: usize,
}

impl Taken {
    /// Whether `[x, y]` lies within one interval taken (up to [`CONTACT_ONLY`]).
    fn holds(&self, x: f64, y: f64) -> bool {
        self.intervals[..self.count]
            .iter()
            .any(|&(a, b)| a <= x + CONTACT_ONLY && y - CONTACT_ONLY <= b)
    }

    /// Notes `[a, b]` as taken: merged into an interval it meets (or nearly: the bands of a
    /// turning tool meet to rounding), else kept beside while
    /// there is room (beyond that it is forgotten, which only costs later sweeps a look).
    fn add(&mut self, a: f64, b: f64) {
        for iv in &mut self.intervals[..self.count] {
            if a <= iv.1 + CONTACT_ONLY && b >= iv.0 - CONTACT_ONLY {
                *iv = (iv.0.min(a), iv.1.max(b));
                return;
            }
        }
        if self.count < self.intervals.len() {
            self.intervals[self.count] = (a, b);
            self.count += 1;
        }
    }
}

/// How far (m) a turning tool's swept solid may be from the true one, per sub-move.
const ROTATION_TOLERANCE: f64 = 0.5e-6;

/// Overlap (m) of a ray's material with where a sweep can be below which the ray is taken as
/// only touched, not cut.
const CONTACT_ONLY: f64 = 1e-9;

/// Most sub-moves one call splits a turning move into.
const MAX_SUBSTEPS: f64 = 256.0;

/// Half the thinnest height band a turning tool is split into (m): thinner bands would allow
/// fewer sub-moves, at a cost per band that outgrows the saving.
const MIN_HALF_BAND: f64 = 0.5e-3;

/// Rays in a sweep's box from which its rows are found in parallel (below, a thread's start
/// costs more than the rays).
const PARALLEL_RAYS: usize = 4096;

/// The lever arm (m) that sets a turning tool's sub-moves: the thinnest band's half-height,
/// or the radius of a face that turns with the axis (a flat end's, the far end's when it
/// can be in the stock; a bull nose's disc).
fn turning_lever(tool: &Tool, end_in_stock: bool) -> f64 {
    let big = tool.radius();
    let face = match tool.shape {
        ToolShape::Flat => big,
        ToolShape::Ball => 0.0,
        ToolShape::Bull { .. } => big - tool.corner_radius(),
    };
    let end = if end_in_stock { big } else { 0.0 };
    face.max(end).max(MIN_HALF_BAND)
}

/// A height band of the tool swept with one pivot.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Band {
    lo: f64,
    hi: f64,
    /// The height (m) whose point follows its true path.
    pivot: f64,
}

/// The tool's heights `[0, top]` in bands whose points lie within `half` (m) of their pivot
/// along the axis, or whose turning face lies within it: the bottom band pivots at the ball's
/// or disc's centre (a ball is the same ball turned about its centre) or at a flat end's
/// face; a far end inside the stock (`end_cap`) pivots at the end's face; the bands between
/// at their middles. `half` infinite: one band.
fn band_layout(tool: &Tool, top: f64, half: f64, end_cap: bool) -> Vec<Band> {
    let bottom = match tool.shape {
        ToolShape::Flat => 0.0,
        ToolShape::Ball => tool.radius(),
        ToolShape::Bull { .. } => tool.corner_radius(),
    };
    if !half.is_finite() || bottom + half >= top {
        return vec![Band {
            lo: 0.0,
            hi: top,
            pivot: bottom.min(top),
        }];
    }
    let mut bands = vec![Band {
        lo: 0.0,
        hi: bottom + half,
        pivot: bottom,
    }];
    let mut lo = bottom + half;
    // The far end's band pivots at the end; its height is `half`, not twice that.
    let last = if end_cap { top - half } else { top };
    while lo < last {
        let hi = (lo + 2.0 * half).min(last);
        bands.push(Band {
            lo,
            hi,
            pivot: 0.5 * (lo + hi),
        });
        lo = hi;
    }
    if end_cap {
        bands.push(Band {
            lo: lo.min(top),
            hi: top,
            pivot: top,
        });
    }
    bands
}

/// Unit vector a fraction `t` of the way from unit `a` to unit `b`, `angle` apart.
fn slerp(a: &Vector3<f64>, b: &Vector3<f64>, angle: f64, t: f64) -> Vector3<f64> {
    if angle < 1e-9 {
        return *a;
    }
    let s = angle.sin();
    if s.abs() < 1e-12 {
        // Opposite axes: no unique plane; a tool never does this within one move.
        return if t < 0.5 { *a } else { *b };
    }
    let v = a * (((1.0 - t) * angle).sin() / s) + b * ((t * angle).sin() / s);
    v.normalize()
}

/// Edge function of point `(pu, pv)` against the edge `a → b`, computed along the edge's
/// canonical direction (lexicographically smaller end first) and negated back, so that the
/// two triangles sharing an edge get exactly opposite values. Zero is broken by moving the
/// point by `(ε, ε²)`, which gives a consistent non-zero sign.
fn edge_function(a: [f64; 3], b: [f64; 3], pu: f64, pv: f64) -> f64 {
    let swap = (b[0], b[1]) < (a[0], a[1]);
    let (p, q) = if swap { (b, a) } else { (a, b) };
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    let mut f = dx * (pv - p[1]) - dy * (pu - p[0]);
    if f == 0.0 {
        // d/dε of dx·ε² − dy·ε: −dy first, then dx.
        f = if dy != 0.0 {
            -dy.signum() * f64::MIN_POSITIVE
        } else {
            dx.signum() * f64::MIN_POSITIVE
        };
    }
    if swap {
        -f
    } else {
        f
    }
}

/// Edges of the mesh used by an odd number of triangles, matching vertices exactly.
fn count_open_edges(triangles: &[[Point3<f64>; 3]]) -> usize {
    let key = |p: &Point3<f64>| p.coords.map(|c| (c + 0.0).to_bits());
    let mut edges: Vec<([u64; 3], [u64; 3])> = Vec::with_capacity(triangles.len() * 3);
    for t in triangles {
        for e in 0..3 {
            let a = key(&t[e]);
            let b = key(&t[(e + 1) % 3]);
            let (a, b) = ([a.x, a.y, a.z], [b.x, b.y, b.z]);
            edges.push(if a <= b { (a, b) } else { (b, a) });
        }
    }
    edges.sort_unstable();
    let mut open = 0;
    let mut i = 0;
    while i < edges.len() {
        let mut j = i;
        while j < edges.len() && edges[j] == edges[i] {
            j += 1;
        }
        if (j - i) % 2 == 1 {
            open += 1;
        }
        i = j;
    }
    open
}

#[cfg(test)]
mod tests;
