//! The part as cut against the nominal part, from corresponding dexel endpoints.
//!
//! `machined` and `nominal` are one original stock cut by the actual and by the programmed
//! tool motion, so their rays correspond one to one. On each ray, every machined endpoint that
//! differs from the original's is a machined surface point; it is paired with the nominal's
//! nearest endpoint of the same kind (entering or leaving material), and the along-ray
//! difference becomes a normal distance through the nominal surface's normal there, estimated
//! from the nominal's corresponding endpoints on the four neighbouring rays. A point counts
//! only in the family most aligned with that normal (the surface's slope across the family
//! is at most 1 in both transverse directions, i.e. |cos| ≥ 1/√3), where the along-ray
//! coordinate is exact and well conditioned.
//!
//! Sign: the error is positive where material is left beyond the nominal surface (undercut)
//! and negative where too much was removed (overcut).

use nalgebra::{Point3, Vector3};

use super::stock::{Family, Stock, StockError};

/// One machined surface point and its error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Position on the machined surface (m).
    pub position: Point3<f64>,
    /// Normal distance to the nominal surface (m): positive = material left (undercut),
    /// negative = overcut.
    pub error: f64,
    /// Outward unit normal of the nominal surface there.
    pub normal: Vector3<f64>,
}

/// How the machined part differs from the nominal one.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceComparison {
    /// Largest |error| over the points (m); 0 with no points.
    pub max_error: f64,
    /// Root mean square error over the points (m); 0 with no points.
    pub rms_error: f64,
    /// The machined surface points, family by family, ray by ray.
    pub points: Vec<SurfacePoint>,
    /// Machined endpoints with no nominal endpoint of their kind within two cells on their
    /// ray, or no neighbours to estimate the normal from (left out of the figures).
    pub unmatched: usize,
    /// Volume removed from the original by the machining (m³): original − machined.
    pub removed_volume: f64,
}

/// An endpoint: along-ray offset and whether material ends there (leaving) or starts.
fn endpoints(ivs: &[[f32; 2]]) -> impl Iterator<Item = (f32, bool)> + '_ {
    ivs.iter().flat_map(|iv| [(iv[0], false), (iv[1], true)])
}

/// The endpoint of kind `leaving` nearest `s` within `window` (m).
fn nearest(ivs: &[[f32; 2]], s: f64, leaving: bool, window: f64) -> Option<f64> {
    let mut best: Option<f64> = None;
    for (x, kind) in endpoints(ivs) {
        let x = f64::from(x);
        if kind == leaving
            && (x - s).abs() <= window
            && best.is_none_or(|b| (x - s).abs() < (b - s).abs())
        {
            best = Some(x);
        }
    }
    best
}

/// Compares the `machined` stock with the `nominal` one, both cut from `original`; see the
/// module's documentation. The three must share one lattice.
pub fn compare(
    machined: &Stock,
    nominal: &Stock,
    original: &Stock,
) -> Result<SurfaceComparison, StockError> {
    let same = |a: &Stock, b: &Stock| {
        a.cells() == b.cells() && a.origin() == b.origin() && a.resolution() == b.resolution()
    };
    if !same(machined, nominal) || !same(machined, original) {
        return Err(StockError::LatticeMismatch);
    }
    let res = machined.resolution();
    let o = machined.origin();
    let window = 2.0 * res;
    let mut points = Vec::new();
    let mut unmatched = 0;
    for k in 0..3 {
        let (u, v) = ((k + 1) % 3, (k + 2) % 3);
        let fm = machined.family(k);
        let fnom = nominal.family(k);
        let fo = original.family(k);
        for jv in 0..fm.nv {
            for ju in 0..fm.nu {
                let idx = fm.index(ju, jv);
                let m = fm.intervals(idx);
                let orig = fo.intervals(idx);
                if m == orig {
                    continue;
                }
                let nom = fnom.intervals(idx);
                for (x, leaving) in endpoints(m) {
                    if endpoints(orig).any(|(y, kind)| y == x && kind == leaving) {
                        continue;
                    }
                    let sm = f64::from(x);
                    let Some(sn) = nearest(nom, sm, leaving, window) else {
                        unmatched += 1;
                        continue;
                    };
                    let Some((gu, gv)) = slopes(fnom, ju, jv, sn, leaving, res, window) else {
                        unmatched += 1;
                        continue;
                    };
                    if gu.abs() > 1.0 || gv.abs() > 1.0 {
                        continue; // Another family is better aligned with the normal here.
                    }
                    let along = if leaving { sm - sn } else { sn - sm };
                    let cos = 1.0 / (1.0 + gu * gu + gv * gv).sqrt();
                    // Outward normal ∝ (−∂s/∂u, −∂s/∂v, 1) where material ends, its opposite
                    // where it starts.
                    let sign = if leaving { 1.0 } else { -1.0 };
                    let mut normal = Vector3::zeros();
                    normal[u] = -gu * sign * cos;
                    normal[v] = -gv * sign * cos;
                    normal[k] = sign * cos;
                    let mut position = o;
                    position[u] += ju as f64 * res;
                    position[v] += jv as f64 * res;
                    position[k] += sm;
                    points.push(SurfacePoint {
                        position,
                        error: along * cos,
                        normal,
                    });
                }
            }
        }
    }
    let max_error = points.iter().map(|p| p.error.abs()).fold(0.0, f64::max);
    let rms_error = if points.is_empty() {
        0.0
    } else {
        (points.iter().map(|p| p.error * p.error).sum::<f64>() / points.len() as f64).sqrt()
    };
    Ok(SurfaceComparison {
        max_error,
        rms_error,
        points,
        unmatched,
        removed_volume: original.volume() - machined.volume(),
    })
}

/// Slopes `(∂s/∂u, ∂s/∂v)` of the surface through endpoint `s` (of kind `leaving`) on ray
/// `(ju, jv)`, from the corresponding endpoints on the neighbouring rays: central
/// differences where both neighbours have one, one-sided where one has; `None` when neither
/// has one in some direction.
fn slopes(
    f: &Family,
    ju: usize,
    jv: usize,
    s: f64,
    leaving: bool,
    res: f64,
    window: f64,
) -> Option<(f64, f64)> {
    let at = |iu: Option<usize>, iv: Option<usize>| -> Option<f64> {
        let (iu, iv) = (iu?, iv?);
        if iu >= f.nu || iv >= f.nv {
            return None;
        }
        nearest(f.intervals(f.index(iu, iv)), s, leaving, window)
    };
    let diff = |minus: Option<f64>, plus: Option<f64>| match (minus, plus) {
        (Some(a), Some(b)) => Some((b - a) / (2.0 * res)),
        (Some(a), None) => Some((s - a) / res),
        (None, Some(b)) => Some((b - s) / res),
        (None, None) => None,
    };
    let gu = diff(at(ju.checked_sub(1), Some(jv)), at(Some(ju + 1), Some(jv)))?;
    let gv = diff(at(Some(ju), jv.checked_sub(1)), at(Some(ju), Some(jv + 1)))?;
    Some((gu, gv))
}
