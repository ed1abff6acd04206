//! The milling force model: Altintas' linear edge-force mechanistic model (*Manufacturing
//! Automation*, 2nd ed., ch. 2) on a sliced cutting edge, with the chip thickness taken from
//! the actual tool–part motion and the engagement from the stock itself.
//!
//! # Conventions
//!
//! * Tool frame: tip at the origin, unit axis `â` toward the spindle, and an orthonormal pair
//!   `b₀`, `b₁ = b₀ × â` across it. `b₀` is the image of +Y under the smallest rotation taking
//!   +Z onto `â` ([`tool_frame`]); so for `â = +Z` it is `b₀ = +Y`, `b₁ = +X`, Altintas' frame.
//! * Angles: a flute at angle θ points along `r̂(θ) = cos θ·b₀ + sin θ·b₁`, i.e. θ is measured
//!   from `b₀` clockwise seen from the spindle (from +Y toward +X for `â = +Z`). The spindle
//!   angle φ is that of flute 0 at the tip. It grows under M3 (rotation vector `−|ω|·â`,
//!   clockwise seen from the spindle) and shrinks under M4; `omega` is signed, > 0 for M3.
//! * Flute j at height z stands at `θ_j(z) = φ + j·2π/N − s·z·tan β/R` with `s = sign(ω)`:
//!   under M3 the tool is right-hand cut with a right-hand helix (higher points lag behind);
//!   under M4 it is taken as the mirror image, a left-hand cut, left-hand helix tool, as run
//!   with M4. So an M4 cut is exactly the mirror image of the mirrored M3 cut.
//! * Envelope normal at an edge point: `n̂ = sin κ·r̂ − cos κ·â`, κ the axial immersion angle
//!   (π/2 on the cylinder, → 0 at a ball's tip).
//! * Chip thickness `h = (v·n̂)·2π/(N|ω|)`, v the tool's velocity relative to the part.
//! * Forces **on the tool**: tangential `−s·dF_t·(r̂ × â)` (against the edge's cutting
//!   velocity), radial `−dF_r·n̂` (out of the material), axial `+dF_a·(cos κ·r̂ + sin κ·â)`,
//!   which is `+dF_a·â` on the cylinder: Altintas' `dF_z = dF_a`, positive toward the spindle
//!   for a right-hand helix under M3 (and for its mirror under M4).
//!
//! With `â = +Z`, feed +X and M3 these give Altintas' closed forms: `dF_x = −dF_t cos φ −
//! dF_r sin φ`, `dF_y = dF_t sin φ − dF_r cos φ`, `dF_z = dF_a`, `h = c sin φ`.
//!
//! # What is cut
//!
//! The profile sliced is the corner arc (ball, bull nose) and the cylinder up to the flute
//! length. A flat or bull-nose tool's flat bottom is not modelled: plunging with it is
//! drilling, which [`plunges_without_centre_cutting`] lets the caller warn about.

use std::f64::consts::{FRAC_PI_2, TAU};
use std::fmt;

use nalgebra::{Point3, Unit, Vector3};

use super::material::{CoefficientError, Coefficients};
use super::tool::{Pose, Tool};

/// The stock as the force model sees it: whether a point holds material.
///
/// The edge points tested lie on the tool's envelope, so the answer must come from the stock
/// *before* the removal of this instant (of this physics step, for the caller of
/// [`super::process::CutProcess`]): after it, the envelope is empty by construction.
pub trait Material {
    /// Whether `point` (part frame, m) holds material. `normal_hint` is the tool envelope's
    /// outward unit normal there, for implementations that resolve boundary points by
    /// looking slightly ahead along it.
    fn contains(&self, point: &Point3<f64>, normal_hint: &Vector3<f64>) -> bool;

    /// A box outside which no point holds material (part frame, m), where one is known: the
    /// model then leaves out the slices whose edge ring cannot reach it.
    fn bounds(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        None
    }
}

/// Largest slice along the profile (m): 0.25 mm.
pub const MAX_SLICE_LENGTH: f64 = 0.25e-3;
/// Largest angle a slice may span (rad), as corner-arc angle and as helix lag: 5°.
pub const MAX_SLICE_ANGLE: f64 = TAU / 72.0;
/// Cap on the number of slices, so that an absurd flute length cannot make `at` unbounded;
/// beyond it the slices grow longer than [`MAX_SLICE_LENGTH`].
pub const MAX_SLICES: usize = 4096;
/// Bisection steps locating where the stock's boundary crosses a slice: the crossing is
/// taken at the middle of the last interval, within 1/2⁷ = 1/128 of the slice (2 µm).
pub const BOUNDARY_BISECTIONS: u32 = 6;
/// Angles around the tool tested for a stopped spindle (one per 15°).
const STOPPED_ANGLES: u32 = 24;
/// A tool without centre cutting may descend along its axis at up to this fraction of its
/// speed (≈ 5.7° ramp) before [`plunges_without_centre_cutting`] calls it a plunge.
pub const PLUNGE_SLOPE_LIMIT: f64 = 0.1;

/// Forces on the tool at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EdgeForces {
    /// Resultant force on the tool (N, part frame).
    pub on_tool: Vector3<f64>,
    /// Torque resisting the spindle about its axis, `Σ dF_t·r` (N·m), ≥ 0.
    pub spindle_torque: f64,
    /// Flutes with at least one engaged slice.
    pub engaged_flutes: u32,
    /// Engaged (flute, slice) pairs.
    pub engaged_slices: u32,
}

/// A tool refused by [`ForceModel::new`].
#[derive(Debug, Clone, PartialEq)]
pub enum ModelError {
    /// A tool dimension is missing, non-finite or out of range; the text says which.
    Tool(String),
    /// A coefficient is out of range.
    Coefficients(CoefficientError),
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ModelError::Tool(why) => write!(f, "tool refused by the force model: {why}"),
            ModelError::Coefficients(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for ModelError {}

impl From<CoefficientError> for ModelError {
    fn from(e: CoefficientError) -> Self {
        ModelError::Coefficients(e)
    }
}

/// A point of the tool's profile (the half-section of its envelope).
#[derive(Debug, Clone, Copy, PartialEq)]
struct ProfilePoint {
    /// Height above the tip (m).
    z: f64,
    /// Distance from the axis (m).
    rho: f64,
    /// sin κ, cos κ of the axial immersion angle κ.
    sin_k: f64,
    cos_k: f64,
    /// cos, sin of the helix lag ψ = z·tan β/R.
    cos_lag: f64,
    sin_lag: f64,
}

/// The cutting profile parametrised by its arc length `u` from the bottom of the corner arc
/// (or from the tip, for a flat tool): uniform in `u` is uniform in chip width.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Profile {
    radius: f64,
    corner: f64,
    /// Arc length of the cut part of the corner arc (m).
    arc_length: f64,
    /// Total profile length (m).
    length: f64,
    /// tan β / R (rad/m).
    lag_rate: f64,
}

impl Profile {
    fn at(&self, u: f64) -> ProfilePoint {
        let (z, rho, sin_k, cos_k) = if u <= self.arc_length && self.corner > 0.0 {
            let (s, c) = (u / self.corner).sin_cos();
            (
                self.corner * (1.0 - c),
                (self.radius - self.corner) + self.corner * s,
                s,
                c,
            )
        } else {
            (self.corner + (u - self.arc_length), self.radius, 1.0, 0.0)
        };
        let (sin_lag, cos_lag) = (z * self.lag_rate).sin_cos();
        ProfilePoint {
            z,
            rho,
            sin_k,
            cos_k,
            cos_lag,
            sin_lag,
        }
    }
}

/// One axial slice: its mid-point geometry and its profile length (the chip width `db`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Slice {
    mid: ProfilePoint,
    /// Profile parameter at its lower and upper ends (m).
    u0: f64,
    u1: f64,
}

/// The tool frame of a pose: `b₀`, `b₁ = b₀ × â`, `â`.
///
/// `b₀` is +Y carried by the smallest rotation taking +Z onto `â`, which is continuous in
/// the axis (a tilting 5-axis tool keeps its flute phase) everywhere but at `â = −Z`, a tool
/// pointing up from below, where it falls back to +Y.
pub fn tool_frame(axis: &Unit<Vector3<f64>>) -> (Vector3<f64>, Vector3<f64>) {
    let (ax, ay, az) = (axis.x, axis.y, axis.z);
    let b0 = if 1.0 + az > 1e-9 {
        // Rodrigues' formula for the rotation about Z × â, closed form for the image of +Y.
        let k = 1.0 / (1.0 + az);
        Vector3::new(-ax * ay * k, 1.0 - ay * ay * k, -ay)
    } else {
        Vector3::y()
    };
    let b1 = b0.cross(axis);
    (b0, b1)
}

/// The edge-force model of one tool with one set of coefficients.
///
/// The cutting profile is cut into slices of at most [`MAX_SLICE_LENGTH`] along the profile,
/// also spanning at most [`MAX_SLICE_ANGLE`] of corner arc and of helix lag (at most
/// [`MAX_SLICES`] in all). Each slice is evaluated at its mid-point (chip thickness, force
/// direction), an O(Δ²) error; where the stock's boundary crosses a slice (the depth of cut,
/// a helical flute's entry and exit) the engaged part is located by bisection to 1/128 of
/// the slice ([`BOUNDARY_BISECTIONS`]), so the depth of cut is resolved to ≈ 2 µm rather
/// than to a whole slice. Features
/// thinner than a slice lying wholly between its two ends are missed.
#[derive(Debug, Clone, PartialEq)]
pub struct ForceModel {
    tool: Tool,
    coefficients: Coefficients,
    profile: Profile,
    slices: Vec<Slice>,
    /// Profile points at the slices' ends (`slices.len() + 1`).
    nodes: Vec<ProfilePoint>,
}

impl ForceModel {
    /// A model for `tool` cutting with `coefficients`; refuses a tool without a positive
    /// finite diameter and flute length, with no flutes, a helix outside [0, π/2) or a bull
    /// nose whose corner radius is not in (0, R), and coefficients out of range.
    pub fn new(tool: Tool, coefficients: Coefficients) -> Result<ForceModel, ModelError> {
        coefficients.validate()?;
        let radius = tool.radius();
        if !(radius.is_finite() && radius > 0.0) {
            return Err(ModelError::Tool(format!(
                "diameter {} m is not positive",
                tool.diameter
            )));
        }
        if tool.flutes == 0 || tool.flutes > 1024 {
            return Err(ModelError::Tool(format!(
                "{} flutes (1…1024 accepted)",
                tool.flutes
            )));
        }
        if !(tool.helix.is_finite() && (0.0..FRAC_PI_2).contains(&tool.helix)) {
            return Err(ModelError::Tool(format!(
                "helix angle {} rad is outside [0, π/2)",
                tool.helix
            )));
        }
        if !(tool.flute_length.is_finite() && tool.flute_length > 0.0) {
            return Err(ModelError::Tool(format!(
                "flute length {} m is not positive",
                tool.flute_length
            )));
        }
        let corner = tool.corner_radius();
        match tool.shape {
            super::tool::ToolShape::Bull { corner_radius }
                if !(corner_radius.is_finite()
                    && corner_radius > 0.0
                    && corner_radius < radius) =>
            {
                return Err(ModelError::Tool(format!(
                    "corner radius {corner_radius} m is outside (0, R = {radius} m)"
                )));
            }
            _ => {}
        }

        // The corner arc is cut up to the flute length (a flute shorter than the corner
        // ends on the arc, at cos κ = (r − L)/r).
        let arc_angle = if corner > 0.0 {
            if tool.flute_length >= corner {
                FRAC_PI_2
            } else {
                ((corner - tool.flute_length) / corner)
                    .clamp(-1.0, 1.0)
                    .acos()
            }
        } else {
            0.0
        };
        let arc_length = corner * arc_angle;
        let cylinder = (tool.flute_length - corner).max(0.0);
        let lag_rate = tool.helix.tan() / radius;
        let profile = Profile {
            radius,
            corner,
            arc_length,
            length: arc_length + cylinder,
            lag_rate,
        };

        // Slice counts: by length, by arc angle, and by helix lag (so a steep helix on a
        // small tool is still followed finely).
        let max_len_by_lag = if lag_rate > 0.0 {
            MAX_SLICE_ANGLE / lag_rate
        } else {
            f64::INFINITY
        };
        let cyl_step = MAX_SLICE_LENGTH.min(max_len_by_lag);
        let count = |len: f64, step: f64| -> usize {
            if len <= 0.0 {
                0
            } else {
                ((len / step).ceil() as usize).max(1)
            }
        };
        let mut n_arc = count(arc_length, MAX_SLICE_LENGTH)
            .max(count(arc_angle, MAX_SLICE_ANGLE))
            .max(count(corner * (1.0 - arc_angle.cos()), cyl_step));
        let mut n_cyl = count(cylinder, cyl_step);
        let total = n_arc + n_cyl;
        if total > MAX_SLICES {
            // Keep the proportions, at least one slice for each part that exists.
            let scale = MAX_SLICES as f64 / total as f64;
            n_arc = if n_arc > 0 {
                ((n_arc as f64 * scale) as usize).max(1)
            } else {
                0
            };
            n_cyl = if n_cyl > 0 {
                ((n_cyl as f64 * scale) as usize).max(1)
            } else {
                0
            };
        }

        let mut bounds = Vec::with_capacity(n_arc + n_cyl + 1);
        for i in 0..n_arc {
            bounds.push(arc_length * i as f64 / n_arc as f64);
        }
        for i in 0..=n_cyl {
            bounds.push(arc_length + cylinder * i as f64 / n_cyl.max(1) as f64);
        }
        bounds.dedup();
        let nodes: Vec<ProfilePoint> = bounds.iter().map(|&u| profile.at(u)).collect();
        let slices: Vec<Slice> = bounds
            .windows(2)
            .map(|w| Slice {
                mid: profile.at(0.5 * (w[0] + w[1])),
                u0: w[0],
                u1: w[1],
            })
            .collect();

        Ok(ForceModel {
            tool,
            coefficients,
            profile,
            slices,
            nodes,
        })
    }

    /// The tool.
    pub fn tool(&self) -> &Tool {
        &self.tool
    }

    /// The coefficients.
    pub fn coefficients(&self) -> &Coefficients {
        &self.coefficients
    }

    /// Number of axial slices per flute.
    pub fn slice_count(&self) -> usize {
        self.slices.len()
    }

    /// Forces at one instant: tool at `pose`, moving at `velocity` (tool relative to part,
    /// part frame, m/s), spindle angle `angle` (rad, of flute 0 at the tip), spindle speed
    /// `omega` (rad/s, signed: > 0 for M3, < 0 for M4).
    ///
    /// A slice of a flute is engaged where its chip thickness is positive **and** the stock
    /// holds material at its edge point. So a tool at rest relative to the part (zero
    /// velocity: no chip) feels no force, edge forces included, and a stopped spindle
    /// (`omega == 0`, infinite tooth period) none either: that case is the caller's to
    /// flag, with [`ForceModel::blocked_by_material`]. Non-finite inputs give zero forces.
    pub fn at(
        &self,
        material: &dyn Material,
        pose: &Pose,
        velocity: &Vector3<f64>,
        angle: f64,
        omega: f64,
    ) -> EdgeForces {
        let finite = omega.is_finite()
            && angle.is_finite()
            && velocity.iter().all(|v| v.is_finite())
            && pose.tip.iter().all(|v| v.is_finite())
            && pose.axis.iter().all(|v| v.is_finite());
        if !finite || omega == 0.0 {
            return EdgeForces::default();
        }
        let sense = omega.signum();
        let axis = pose.axis.into_inner();
        let (b0, b1) = tool_frame(&pose.axis);
        let (vb0, vb1, va) = (velocity.dot(&b0), velocity.dot(&b1), velocity.dot(&axis));
        let flutes = self.tool.flutes;
        let period = TAU / (f64::from(flutes) * omega.abs());
        let pitch = TAU / f64::from(flutes);
        let k = &self.coefficients;

        // Accumulated in the tool frame: along b₀, b₁ and â.
        let (mut f0, mut f1, mut fa, mut torque) = (0.0, 0.0, 0.0, 0.0);
        let mut engaged_flutes = 0;
        let mut engaged_slices = 0;

        let edge = EdgeFrame {
            tip: &pose.tip,
            axis: &axis,
            b0: &b0,
            b1: &b1,
            sense,
        };
        let (reach_lo, reach_hi) = self.heights_near(material, pose);
        for j in 0..flutes {
            let (sa, ca) = (angle + f64::from(j) * pitch).sin_cos();
            let mut flute_engaged = false;
            // Whether the stock holds the node shared with the previous slice, when known.
            let mut below: Option<bool> = None;
            for (i, slice) in self.slices.iter().enumerate() {
                if slice_z_max(&self.nodes[i], &self.nodes[i + 1]) < reach_lo
                    || slice_z_min(&self.nodes[i], &self.nodes[i + 1]) > reach_hi
                {
                    below = None;
                    continue;
                }
                let m = &slice.mid;
                let (st, ct) = rotate(sa, ca, m, sense);
                let vr = ct * vb0 + st * vb1;
                let h = (m.sin_k * vr - m.cos_k * va) * period;
                if h.is_nan() || h <= 0.0 {
                    below = None;
                    continue;
                }
                let lower = match below {
                    Some(held) => held,
                    None => edge.holds(material, &self.nodes[i], sa, ca),
                };
                let upper = edge.holds(material, &self.nodes[i + 1], sa, ca);
                below = Some(upper);
                // A slice the stock's boundary crosses is evaluated at the middle of its
                // engaged part, not at its own middle: that keeps the error at a helical
                // flute's entry and exit second order in the slice size.
                let (fraction, m, st, ct, h) = match (lower, upper) {
                    (true, true) => (1.0, *m, st, ct, h),
                    (false, false) => continue,
                    _ => {
                        let (fraction, centre) =
                            self.boundary_fraction(material, &edge, slice, lower, sa, ca);
                        let p = self.profile.at(centre);
                        let (st, ct) = rotate(sa, ca, &p, sense);
                        let h = (p.sin_k * (ct * vb0 + st * vb1) - p.cos_k * va) * period;
                        (fraction, p, st, ct, h)
                    }
                };
                if !(fraction > 0.0 && h > 0.0) {
                    continue;
                }
                let db = (slice.u1 - slice.u0) * fraction;
                let dft = (k.ktc * h + k.kte) * db;
                let dfr = (k.krc * h + k.kre) * db;
                let dfa = (k.kac * h + k.kae) * db;
                // On the tool: radial −dF_r·n̂, axial dF_a·(cos κ r̂ + sin κ â),
                // tangential −s·dF_t·t̂ with t̂ = r̂ × â = cos θ b₁ − sin θ b₀.
                let f_r = -dfr * m.sin_k + dfa * m.cos_k;
                let f_t = -sense * dft;
                f0 += f_r * ct - f_t * st;
                f1 += f_r * st + f_t * ct;
                fa += dfr * m.cos_k + dfa * m.sin_k;
                torque += dft * m.rho;
                engaged_slices += 1;
                flute_engaged = true;
            }
            if flute_engaged {
                engaged_flutes += 1;
            }
        }
        EdgeForces {
            on_tool: b0 * f0 + b1 * f1 + axis * fa,
            spindle_torque: torque,
            engaged_flutes,
            engaged_slices,
        }
    }

    /// The heights above the tip (m) between which an edge ring of the tool can reach the
    /// material's box: per axis k the ring at height z spans the axis point ± R·√(1 − â_k²);
    /// all heights where the material has no box.
    fn heights_near(&self, material: &dyn Material, pose: &Pose) -> (f64, f64) {
        let Some((lo, hi)) = material.bounds() else {
            return (f64::NEG_INFINITY, f64::INFINITY);
        };
        let radius = self.tool.radius();
        let (mut z0, mut z1) = (f64::NEG_INFINITY, f64::INFINITY);
        for k in 0..3 {
            let a = pose.axis[k];
            let spread = radius * (1.0 - a * a).max(0.0).sqrt();
            let (below, above) = (lo[k] - spread - pose.tip[k], hi[k] + spread - pose.tip[k]);
            if a.abs() < 1e-12 {
                if below > 0.0 || above < 0.0 {
                    return (f64::INFINITY, f64::NEG_INFINITY);
                }
                continue;
            }
            let (p, q) = (below / a, above / a);
            z0 = z0.max(p.min(q));
            z1 = z1.min(p.max(q));
        }
        (z0, z1)
    }

    /// Whether the tool's envelope runs into material along `velocity` (part frame, m/s):
    /// some point of the cutting profile, at any of 24 angles around the axis, moves into
    /// stock (`v·n̂ > 0` and the stock holds it). For a stopped spindle that is a crash, not
    /// a cut; the caller flags it. Zero velocity never runs into anything.
    pub fn blocked_by_material(
        &self,
        material: &dyn Material,
        pose: &Pose,
        velocity: &Vector3<f64>,
    ) -> bool {
        if !velocity.iter().all(|v| v.is_finite()) || velocity.norm_squared() == 0.0 {
            return false;
        }
        let axis = pose.axis.into_inner();
        let (b0, b1) = tool_frame(&pose.axis);
        let edge = EdgeFrame {
            tip: &pose.tip,
            axis: &axis,
            b0: &b0,
            b1: &b1,
            sense: 1.0,
        };
        (0..STOPPED_ANGLES).any(|k| {
            // Geometry only: the helix lag is irrelevant for a full turn of angles.
            let (s, c) = (TAU * f64::from(k) / f64::from(STOPPED_ANGLES)).sin_cos();
            self.slices.iter().any(|slice| {
                let p = ProfilePoint {
                    cos_lag: 1.0,
                    sin_lag: 0.0,
                    ..slice.mid
                };
                let r = b0 * c + b1 * s;
                let n = r * p.sin_k - axis * p.cos_k;
                n.dot(velocity) > 0.0 && edge.holds(material, &p, s, c)
            })
        })
    }

    /// The engaged fraction of a slice whose two ends disagree (`lower` held, the upper one
    /// not, or the reverse), by bisection on the profile parameter, and the profile
    /// parameter of the engaged part's middle.
    fn boundary_fraction(
        &self,
        material: &dyn Material,
        edge: &EdgeFrame<'_>,
        slice: &Slice,
        lower: bool,
        sa: f64,
        ca: f64,
    ) -> (f64, f64) {
        let (mut lo, mut hi) = (slice.u0, slice.u1);
        for _ in 0..BOUNDARY_BISECTIONS {
            let mid = 0.5 * (lo + hi);
            if edge.holds(material, &self.profile.at(mid), sa, ca) == lower {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let crossing = 0.5 * (lo + hi);
        let width = slice.u1 - slice.u0;
        if width.is_nan() || width <= 0.0 {
            return (0.0, slice.u0);
        }
        let (from, to) = if lower {
            (slice.u0, crossing)
        } else {
            (crossing, slice.u1)
        };
        (((to - from) / width).clamp(0.0, 1.0), 0.5 * (from + to))
    }
}

/// `(sin θ, cos θ)` of a flute at `θ = a − s·ψ` from `(sin a, cos a)` and the point's lag.
#[inline]
fn rotate(sa: f64, ca: f64, p: &ProfilePoint, sense: f64) -> (f64, f64) {
    let sl = sense * p.sin_lag;
    (sa * p.cos_lag - ca * sl, ca * p.cos_lag + sa * sl)
}

/// A pose's frame, for placing edge points.
struct EdgeFrame<'a> {
    tip: &'a Point3<f64>,
    axis: &'a Vector3<f64>,
    b0: &'a Vector3<f64>,
    b1: &'a Vector3<f64>,
    sense: f64,
}

impl EdgeFrame<'_> {
    /// Whether the stock holds the edge point of profile point `p` on the flute whose angle
    /// at the tip has sine `sa`, cosine `ca`.
    #[inline]
    fn holds(&self, material: &dyn Material, p: &ProfilePoint, sa: f64, ca: f64) -> bool {
        let (st, ct) = rotate(sa, ca, p, self.sense);
        let r = self.b0 * ct + self.b1 * st;
        let point = self.tip + self.axis * p.z + r * p.rho;
        let normal = r * p.sin_k - self.axis * p.cos_k;
        material.contains(&point, &normal)
    }
}

fn slice_z_min(a: &ProfilePoint, b: &ProfilePoint) -> f64 {
    a.z.min(b.z)
}

fn slice_z_max(a: &ProfilePoint, b: &ProfilePoint) -> f64 {
    a.z.max(b.z)
}

/// Whether a tool that does not cut at its centre (flat, bull nose) is plunging into
/// material: moving along −`â` faster than [`PLUNGE_SLOPE_LIMIT`] of its speed with stock
/// under its tip. The force model has no bottom edges, so such a plunge feels no axial
/// cutting force; the caller should warn (it is drilling with an end mill).
pub fn plunges_without_centre_cutting(
    tool: &Tool,
    material: &dyn Material,
    pose: &Pose,
    velocity: &Vector3<f64>,
) -> bool {
    if tool.cuts_at_centre() {
        return false;
    }
    let axis = pose.axis.into_inner();
    let descent = -velocity.dot(&axis);
    let speed = velocity.norm();
    // `!(x > y)` keeps NaN out.
    if !(descent > PLUNGE_SLOPE_LIMIT * speed && speed.is_finite()) {
        return false;
    }
    material.contains(&pose.tip, &(-axis))
}

#[cfg(test)]
pub(crate) mod solids {
    //! Analytic stocks for the closed-form tests.
    use super::Material;
    use nalgebra::{Point3, Vector3};

    /// A steady straight cut along +X with the tool axis along +Z, tip at height 0 and the
    /// stock's top at `top`: the part holds `y_min ≤ y ≤ y_max` below `top`, minus what the
    /// tool has swept so far, the points with `x < x_c` and `|y| < R` (the union of its
    /// discs along −X), `x_c` being the tool's current x.
    pub struct SteadyCut {
        pub x_c: f64,
        pub radius: f64,
        pub y_min: f64,
        pub y_max: f64,
        pub top: f64,
    }

    impl SteadyCut {
        /// A full slot of depth `depth`.
        pub fn slot(radius: f64, depth: f64) -> Self {
            SteadyCut {
                x_c: 0.0,
                radius,
                y_min: f64::NEG_INFINITY,
                y_max: f64::INFINITY,
                top: depth,
            }
        }
        /// Half immersion on the +Y side: up-milling under M3 (φ from 0 to π/2).
        pub fn up_half(radius: f64, depth: f64) -> Self {
            SteadyCut {
                y_min: 0.0,
                ..Self::slot(radius, depth)
            }
        }
        /// Half immersion on the −Y side: down-milling under M3 (φ from π/2 to π).
        pub fn down_half(radius: f64, depth: f64) -> Self {
            SteadyCut {
                y_max: 0.0,
                ..Self::slot(radius, depth)
            }
        }
        /// The same stock mirrored across the XZ plane (y → −y).
        pub fn mirrored(&self) -> Self {
            SteadyCut {
                y_min: -self.y_max,
                y_max: -self.y_min,
                ..*self
            }
        }
    }

    impl Material for SteadyCut {
        fn contains(&self, p: &Point3<f64>, _normal_hint: &Vector3<f64>) -> bool {
            let swept = p.x < self.x_c && p.y.abs() < self.radius;
            p.z < self.top && p.y >= self.y_min && p.y <= self.y_max && !swept
        }
    }

    /// Everything below the plane `z = top`.
    pub struct Below {
        pub top: f64,
    }

    impl Material for Below {
        fn contains(&self, p: &Point3<f64>, _normal_hint: &Vector3<f64>) -> bool {
            p.z < self.top
        }
    }

    /// No material at all.
    pub struct Air;

    impl Material for Air {
        fn contains(&self, _p: &Point3<f64>, _normal_hint: &Vector3<f64>) -> bool {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::material::material;
    use super::super::tool::ToolShape;
    use super::solids::{Air, Below, SteadyCut};
    use super::*;
    use std::f64::consts::PI;

    fn al7075() -> Coefficients {
        match material("al7075") {
            Some(m) => m.coefficients,
            None => panic!("al7075 missing from the table"),
        }
    }

    fn flat(diameter: f64, flutes: u32, helix_deg: f64, flute_length: f64) -> Tool {
        Tool {
            diameter,
            flutes,
            helix: helix_deg.to_radians(),
            flute_length,
            shape: ToolShape::Flat,
        }
    }

    fn model(tool: Tool) -> ForceModel {
        match ForceModel::new(tool, al7075()) {
            Ok(m) => m,
            Err(e) => panic!("{e}"),
        }
    }

    fn upright(x: f64) -> Pose {
        Pose {
            tip: Point3::new(x, 0.0, 0.0),
            axis: Vector3::z_axis(),
        }
    }

    /// Altintas' mean forces per revolution (forces on the tool), flat end mill, axial depth
    /// `a`, feed per tooth `c`, immersion `st..ex`. Re-derived by integrating the elemental
    /// forces `(N a/2π) ∫ dF(φ) dφ`; the result agrees with the book's forms term by term.
    fn closed_form_mean(
        k: &Coefficients,
        n: f64,
        a: f64,
        c: f64,
        st: f64,
        ex: f64,
    ) -> Vector3<f64> {
        let fx = |p: f64| {
            n * a * c / (8.0 * PI) * (k.ktc * (2.0 * p).cos() - k.krc * (2.0 * p - (2.0 * p).sin()))
                + n * a / (2.0 * PI) * (-k.kte * p.sin() + k.kre * p.cos())
        };
        let fy = |p: f64| {
            n * a * c / (8.0 * PI) * (k.ktc * (2.0 * p - (2.0 * p).sin()) + k.krc * (2.0 * p).cos())
                - n * a / (2.0 * PI) * (k.kte * p.cos() + k.kre * p.sin())
        };
        let fz = |p: f64| n * a / (2.0 * PI) * (-k.kac * c * p.cos() + k.kae * p);
        Vector3::new(fx(ex) - fx(st), fy(ex) - fy(st), fz(ex) - fz(st))
    }

    /// Feed velocity (m/s) for feed per tooth `c` at spindle speed `omega`.
    fn feed_speed(c: f64, flutes: u32, omega: f64) -> f64 {
        c * f64::from(flutes) * omega.abs() / TAU
    }

    /// Mean over one revolution, `samples` evenly spaced angles (mid-points).
    fn mean_per_rev(
        m: &ForceModel,
        stock: &dyn Material,
        v: &Vector3<f64>,
        omega: f64,
        samples: usize,
    ) -> Vector3<f64> {
        let pose = upright(0.0);
        let mut sum = Vector3::zeros();
        for i in 0..samples {
            let phi = TAU * (i as f64 + 0.5) / samples as f64;
            sum += m.at(stock, &pose, v, phi, omega).on_tool;
        }
        sum / samples as f64
    }

    /// Per-component check: `rel` of the component, or of a tenth of the resultant for
    /// components smaller than that (so near-zero components get an absolute tolerance of
    /// `rel/10` of the resultant, stricter than the brief's 2 % of it). Returns the worst
    /// deviation relative to that base.
    fn compare(label: &str, got: &Vector3<f64>, want: &Vector3<f64>, rel: f64) -> f64 {
        let mut worst: f64 = 0.0;
        for i in 0..3 {
            let base = want[i].abs().max(0.1 * want.norm());
            let dev = (got[i] - want[i]).abs() / base;
            worst = worst.max(dev);
            assert!(
                dev <= rel,
                "{label} component {i}: got {} N, closed form {} N ({:.3} % of {base} N)",
                got[i],
                want[i],
                100.0 * dev
            );
        }
        worst
    }

    #[test]
    fn mean_forces_match_closed_forms() {
        let tool = flat(16e-3, 4, 30.0, 20e-3);
        let m = model(tool);
        let k = al7075();
        let (a, c, omega) = (5e-3, 0.1e-3, 1000.0 * TAU / 60.0); // 1000 rpm
        let v = Vector3::new(feed_speed(c, 4, omega), 0.0, 0.0);
        let r = tool.radius();
        let cases: [(&str, SteadyCut, f64, f64); 3] = [
            ("slot", SteadyCut::slot(r, a), 0.0, PI),
            ("up-milling half", SteadyCut::up_half(r, a), 0.0, FRAC_PI_2),
            (
                "down-milling half",
                SteadyCut::down_half(r, a),
                FRAC_PI_2,
                PI,
            ),
        ];
        let mut worst: f64 = 0.0;
        for (label, stock, st, ex) in cases {
            let got = mean_per_rev(&m, &stock, &v, omega, 7200);
            let want = closed_form_mean(&k, 4.0, a, c, st, ex);
            let dev = compare(label, &got, &want, 0.02);
            println!(
                "mean forces, {label}: {got:?} N vs closed form {want:?} N, worst {:.3} %",
                100.0 * dev
            );
            worst = worst.max(dev);
        }
        println!("mean forces: worst deviation {:.4} %", 100.0 * worst);
    }

    /// Instantaneous closed form for straight flutes: the sum over teeth in the immersion of
    /// Altintas' elemental forces with `h = c sin φ`, times the axial depth.
    fn closed_form_instant(
        k: &Coefficients,
        n: u32,
        a: f64,
        c: f64,
        phi: f64,
        st: f64,
        ex: f64,
    ) -> Vector3<f64> {
        let mut f = Vector3::zeros();
        for j in 0..n {
            let p = (phi + TAU * f64::from(j) / f64::from(n)).rem_euclid(TAU);
            if p < st || p > ex {
                continue;
            }
            let h = c * p.sin();
            let (ft, fr, fa) = (
                (k.ktc * h + k.kte) * a,
                (k.krc * h + k.kre) * a,
                (k.kac * h + k.kae) * a,
            );
            f += Vector3::new(
                -ft * p.cos() - fr * p.sin(),
                ft * p.sin() - fr * p.cos(),
                fa,
            );
        }
        f
    }

    #[test]
    fn straight_flutes_match_instantaneous_closed_form() {
        let tool = flat(10e-3, 3, 0.0, 20e-3);
        let m = model(tool);
        let k = al7075();
        let (a, c, omega) = (5e-3, 0.08e-3, 1047.0);
        let v = Vector3::new(feed_speed(c, 3, omega), 0.0, 0.0);
        let r = tool.radius();
        let pose = upright(0.0);
        let mut worst: f64 = 0.0;
        for (stock, st, ex) in [
            (SteadyCut::slot(r, a), 0.0, PI),
            (SteadyCut::up_half(r, a), 0.0, FRAC_PI_2),
            (SteadyCut::down_half(r, a), FRAC_PI_2, PI),
        ] {
            let samples = 720;
            let peak = (0..samples)
                .map(|i| {
                    closed_form_instant(
                        &k,
                        3,
                        a,
                        c,
                        TAU * (i as f64 + 0.5) / samples as f64,
                        st,
                        ex,
                    )
                    .norm()
                })
                .fold(0.0, f64::max);
            for i in 0..samples {
                let phi = TAU * (i as f64 + 0.5) / samples as f64;
                let got = m.at(&stock, &pose, &v, phi, omega).on_tool;
                let want = closed_form_instant(&k, 3, a, c, phi, st, ex);
                // 1 % of the instantaneous resultant, with a floor of 0.1 % of the peak
                // where no tooth cuts.
                let dev = (got - want).norm() / want.norm().max(0.1 * peak);
                worst = worst.max(dev);
                assert!(dev <= 0.01, "φ = {phi}: got {got:?}, closed form {want:?}");
            }
        }
        println!("straight flutes: worst deviation {:.2e} (relative)", worst);
    }

    #[test]
    fn m4_is_the_mirror_image_of_m3() {
        let tool = flat(16e-3, 4, 30.0, 20e-3);
        let m = model(tool);
        let (a, c, omega) = (5e-3, 0.1e-3, 600.0);
        let v = Vector3::new(feed_speed(c, 4, omega), 0.0, 0.0);
        let stock = SteadyCut::up_half(tool.radius(), a);
        let mirror = stock.mirrored();
        let pose = upright(0.0);
        for i in 0..90 {
            let phi = TAU * (i as f64 + 0.37) / 90.0;
            let m3 = m.at(&stock, &pose, &v, phi, omega);
            // Mirroring y → −y maps a flute at φ to π − φ, and M3 to M4.
            let m4 = m.at(&mirror, &pose, &v, PI - phi, -omega);
            let expect = Vector3::new(m3.on_tool.x, -m3.on_tool.y, m3.on_tool.z);
            assert!(
                (m4.on_tool - expect).norm() <= 1e-9 * (1.0 + expect.norm()),
                "φ = {phi}: {m4:?} vs {m3:?}"
            );
            assert!(
                (m4.spindle_torque - m3.spindle_torque).abs() <= 1e-9 * (1.0 + m3.spindle_torque)
            );
            assert_eq!(m4.engaged_slices, m3.engaged_slices);
        }
        // On the same stock, M4 cuts the other half: the +Y half is down-milling for it,
        // and its tangential force (so F_y's sign in the mean) turns around.
        let m3 = mean_per_rev(&m, &stock, &v, omega, 720);
        let m4 = mean_per_rev(&m, &stock, &v, -omega, 720);
        assert!(m3.y > 0.0 && m4.y < 0.0, "{m3:?} {m4:?}");
    }

    #[test]
    fn no_motion_no_chip_and_stopped_spindle_no_force() {
        let tool = flat(10e-3, 3, 30.0, 20e-3);
        let m = model(tool);
        let stock = SteadyCut::slot(tool.radius(), 5e-3);
        let pose = upright(0.0);
        let still = m.at(&stock, &pose, &Vector3::zeros(), 0.3, 1000.0);
        assert_eq!(still, EdgeForces::default());
        let v = Vector3::new(0.01, 0.0, 0.0);
        let stopped = m.at(&stock, &pose, &v, 0.3, 0.0);
        assert_eq!(stopped, EdgeForces::default());
        assert!(m.blocked_by_material(&stock, &pose, &v));
        // Backing out of the slot moves into the swept region only.
        assert!(!m.blocked_by_material(&stock, &pose, &(-v)));
        assert!(!m.blocked_by_material(&stock, &pose, &Vector3::zeros()));
        // Non-finite inputs: zero, no panic.
        assert_eq!(
            m.at(&stock, &pose, &v, f64::NAN, 1000.0),
            EdgeForces::default()
        );
        assert_eq!(
            m.at(&stock, &pose, &v, 0.0, f64::INFINITY),
            EdgeForces::default()
        );
        // Air: nothing.
        assert_eq!(m.at(&Air, &pose, &v, 0.3, 1000.0).engaged_slices, 0);
    }

    #[test]
    fn torque_and_power_follow_the_tangential_force() {
        // Slot, straight flutes: torque = Σ dF_t·R, and F on the tool opposes the feed.
        let tool = flat(10e-3, 2, 0.0, 20e-3);
        let m = model(tool);
        let k = al7075();
        // A depth between slice ends: the bisection locates it.
        let (a, c, omega) = (2.1e-3, 0.05e-3, 1000.0);
        let v = Vector3::new(feed_speed(c, 2, omega), 0.0, 0.0);
        let stock = SteadyCut::slot(tool.radius(), a);
        let phi = 1.0;
        let f = m.at(&stock, &upright(0.0), &v, phi, omega);
        let ft = (k.ktc * c * phi.sin() + k.kte) * a;
        let resolution = MAX_SLICE_LENGTH / 128.0 / a;
        let dev = (f.spindle_torque - ft * tool.radius()).abs() / (ft * tool.radius());
        println!(
            "torque at a depth between slices: deviation {:.2e} (bound {resolution:.2e})",
            dev
        );
        assert!(dev <= resolution);
        assert_eq!(f.engaged_flutes, 1);
        assert!(f.on_tool.x < 0.0);
    }

    #[test]
    fn ball_tip_and_normals() {
        let r = 5e-3;
        let tool = Tool {
            diameter: 2.0 * r,
            flutes: 2,
            helix: 30f64.to_radians(),
            flute_length: 20e-3,
            shape: ToolShape::Ball,
        };
        let m = model(tool);
        // Tip: radius → 0, geometry finite.
        let first = m.slices[0].mid;
        assert!(first.rho > 0.0 && first.rho < 0.2e-3 && first.rho.is_finite());
        assert!(m.nodes[0].rho.abs() < 1e-15 && m.nodes[0].cos_k == 1.0);
        // 45° lead: z = R(1 − cos 45°), n̂ = (r̂ − â)/√2.
        let p = m.profile.at(r * PI / 4.0);
        let z45 = r * (1.0 - (PI / 4.0).cos());
        assert!((p.z - z45).abs() < 1e-12 && (p.rho - r * (PI / 4.0).sin()).abs() < 1e-12);
        assert!((p.sin_k - 0.5f64.sqrt()).abs() < 1e-12 && (p.cos_k - 0.5f64.sqrt()).abs() < 1e-12);
        // The slice spanning that height has its normal within half a slice of 45°.
        let s = m
            .slices
            .iter()
            .find(|s| s.u0 <= r * PI / 4.0 && r * PI / 4.0 <= s.u1)
            .map(|s| s.mid);
        let s = s.unwrap_or(first);
        let kappa = s.sin_k.atan2(s.cos_k);
        assert!((kappa - PI / 4.0).abs() <= MAX_SLICE_ANGLE / 2.0 + 1e-12);
        // The normal handed to the stock at a 45° edge point.
        struct Probe(std::cell::RefCell<Vec<(Point3<f64>, Vector3<f64>)>>);
        impl Material for Probe {
            fn contains(&self, p: &Point3<f64>, n: &Vector3<f64>) -> bool {
                self.0.borrow_mut().push((*p, *n));
                true
            }
        }
        let probe = Probe(Default::default());
        let pose = upright(0.0);
        let _ = m.at(&probe, &pose, &Vector3::new(0.0, 0.0, -0.01), 0.0, 1000.0);
        for (pt, n) in probe.0.borrow().iter() {
            assert!(n.iter().all(|x| x.is_finite()) && (n.norm() - 1.0).abs() < 1e-12);
            // On a sphere of radius R about (0, 0, R) below the equator: n̂ ∥ point − centre.
            if pt.z < r - 1e-12 {
                let radial = (pt - Point3::new(0.0, 0.0, r)) / r;
                assert!((radial - n).norm() < 1e-9, "{pt:?} {n:?}");
            }
        }
        // Plunging a ball into a plane: no NaN, force pushes the tool up, lateral ≈ 0 in the
        // mean, the tip slices engaged.
        let below = Below { top: 1e-3 };
        let mut mean = Vector3::zeros();
        for i in 0..360 {
            let f = m.at(
                &below,
                &pose,
                &Vector3::new(0.0, 0.0, -0.005),
                TAU * i as f64 / 360.0,
                1000.0,
            );
            assert!(f.on_tool.iter().all(|x| x.is_finite()) && f.spindle_torque.is_finite());
            assert!(f.engaged_slices > 0);
            mean += f.on_tool / 360.0;
        }
        assert!(mean.z > 0.0 && mean.xy().norm() < 1e-6 * mean.z, "{mean:?}");
        assert!(!plunges_without_centre_cutting(
            &tool,
            &below,
            &pose,
            &Vector3::new(0.0, 0.0, -0.005)
        ));
    }

    #[test]
    fn flat_plunge_is_flagged() {
        let tool = flat(10e-3, 3, 30.0, 20e-3);
        let pose = upright(0.0);
        let below = Below { top: 1e-3 };
        let down = Vector3::new(0.0, 0.0, -0.005);
        assert!(plunges_without_centre_cutting(&tool, &below, &pose, &down));
        // A gentle ramp (2°) is not a plunge; neither is plunging in air.
        let ramp = Vector3::new(0.01, 0.0, -0.01 * 2f64.to_radians().tan());
        assert!(!plunges_without_centre_cutting(&tool, &below, &pose, &ramp));
        assert!(!plunges_without_centre_cutting(&tool, &Air, &pose, &down));
        assert!(!plunges_without_centre_cutting(
            &tool,
            &below,
            &pose,
            &Vector3::new(f64::NAN, 0.0, -1.0)
        ));
    }

    #[test]
    fn tools_are_refused_with_a_reason() {
        let good = flat(10e-3, 3, 30.0, 20e-3);
        let bad = [
            Tool {
                diameter: 0.0,
                ..good
            },
            Tool {
                diameter: f64::NAN,
                ..good
            },
            Tool { flutes: 0, ..good },
            Tool {
                helix: FRAC_PI_2,
                ..good
            },
            Tool {
                flute_length: -1.0,
                ..good
            },
            Tool {
                shape: ToolShape::Bull {
                    corner_radius: 6e-3,
                },
                ..good
            },
        ];
        for t in bad {
            assert!(
                matches!(ForceModel::new(t, al7075()), Err(ModelError::Tool(_))),
                "{t:?}"
            );
        }
        let k = Coefficients {
            ktc: -1.0,
            ..al7075()
        };
        assert!(matches!(
            ForceModel::new(good, k),
            Err(ModelError::Coefficients(_))
        ));
        // Absurd but valid sizes stay bounded.
        let long = ForceModel::new(
            Tool {
                flute_length: 1e3,
                ..good
            },
            al7075(),
        )
        .map(|m| m.slice_count());
        assert!(matches!(long, Ok(n) if n <= MAX_SLICES + 1));
        // Bull nose, flute shorter than the corner.
        let bull = Tool {
            shape: ToolShape::Bull {
                corner_radius: 2e-3,
            },
            flute_length: 1e-3,
            ..good
        };
        let bm = model(bull);
        assert!(bm.nodes.last().map(|p| (p.z - 1e-3).abs() < 1e-12) == Some(true));
    }

    #[test]
    fn tilted_axis_frame_is_orthonormal_and_continuous() {
        for axis in [
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(0.3, -0.2, 0.9),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(1e-6, 0.0, -1.0),
        ] {
            let a = Unit::new_normalize(axis);
            let (b0, b1) = tool_frame(&a);
            assert!((b0.norm() - 1.0).abs() < 1e-9 && (b1.norm() - 1.0).abs() < 1e-9);
            assert!(b0.dot(&a).abs() < 1e-9 && b1.dot(&a).abs() < 1e-9);
            assert!((b0.cross(&a) - b1).norm() < 1e-12);
        }
        let (b0, b1) = tool_frame(&Vector3::z_axis());
        assert_eq!((b0, b1), (Vector3::y(), Vector3::x()));
    }

    /// A tilted tool: the same cut expressed in a rotated frame gives the rotated force.
    #[test]
    fn forces_rotate_with_the_frame() {
        let tool = flat(10e-3, 3, 30.0, 20e-3);
        let m = model(tool);
        let stock = SteadyCut::up_half(tool.radius(), 4e-3);
        let v = Vector3::new(0.02, 0.0, 0.0);
        let f = m.at(&stock, &upright(0.0), &v, 0.7, 900.0);
        // The smallest rotation taking Z onto the new axis also carries b₀, so the flute
        // phase is the same and the force rotates with it.
        let rot = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), 0.4);
        struct Rotated<'a>(&'a SteadyCut, nalgebra::Rotation3<f64>);
        impl Material for Rotated<'_> {
            fn contains(&self, p: &Point3<f64>, n: &Vector3<f64>) -> bool {
                self.0
                    .contains(&(self.1.inverse() * p), &(self.1.inverse() * n))
            }
        }
        let pose = Pose {
            tip: Point3::origin(),
            axis: Unit::new_normalize(rot * Vector3::z()),
        };
        let g = m.at(&Rotated(&stock, rot), &pose, &(rot * v), 0.7, 900.0);
        assert!(
            (g.on_tool - rot * f.on_tool).norm() < 1e-9 * f.on_tool.norm(),
            "{g:?} {f:?}"
        );
    }

    /// `cargo test --release -- --ignored --nocapture at_call_cost`
    #[test]
    #[ignore]
    fn at_call_cost() {
        let tool = flat(10e-3, 3, 30.0, 25e-3);
        let m = model(tool);
        let stock = SteadyCut::slot(tool.radius(), 5e-3);
        let v = Vector3::new(0.05, 0.0, 0.0);
        let pose = upright(0.0);
        let calls = 200_000;
        let start = std::time::Instant::now();
        let mut sum = 0.0;
        for i in 0..calls {
            sum += m.at(&stock, &pose, &v, i as f64 * 0.01, 1047.0).on_tool.x;
        }
        let ns = start.elapsed().as_nanos() as f64 / calls as f64;
        println!(
            "at(): {ns:.0} ns per call ({} slices × 3 flutes, 25 mm flutes, 5 mm deep slot; checksum {sum:.3})",
            m.slice_count()
        );
    }
}
