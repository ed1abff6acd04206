//! One lane's cut: its own stock, the force model stepping with the spindle, and the removal
//! of what the tool sweeps. The plant calls [`Cut::step`] every physics step with the tool's
//! pose and velocity on the part; the cut answers with the force and removes material.

use super::{CutProcess, ForceModel, Material, Pose, StepForces, Stock, Tool};
use nalgebra::{Point3, Unit, Vector3};

/// How far the tool's path may stray from the straight chord removal sweeps it along (m): the
/// stock is cut by the tool swept in straight chords, each as long as the path stays within
/// this of it (at the tip, and at the far end of the fluted part for a turning axis). On a
/// 25 mm radius that is a chord of 0.2 mm; on a straight line the chord grows to
/// [`MAX_CHORD_RESOLUTIONS`].
const CHORD_TOLERANCE: f64 = 0.2e-6;

/// Longest chord (in stock resolutions). Removal lagging behind the tool does not change what
/// the force model reads (it asks in front of the moving tool, where nothing was removed
/// yet; behind it the chip thickness is negative), but a tool turning back into its own track
/// would meet material up to a chord's length too late.
const MAX_CHORD_RESOLUTIONS: f64 = 4.0;

/// Poses kept between removals, to test the chord against.
const MAX_PENDING: usize = 256;

/// Most chords removed in one pass over the rays.
const MAX_PATH: usize = 64;

/// One lane's cut.
pub struct Cut {
    stock: Stock,
    process: CutProcess,
    tool: Tool,
    /// The chords decided and not yet removed, as the poses joining them: the first is where
    /// the stock has been cut to, the last where the next chord starts. Removed together in
    /// one pass over the rays once they reach a chord's length from the first (so the removal
    /// lags the tool by no more than one chord, as if each were removed at once).
    path: Vec<Pose>,
    /// The poses since the path's last, in order (the tool's path the next chord must follow).
    pending: Vec<Pose>,
    /// Peak values over the cut so far.
    totals: CutTotals,
    /// Why the cut could not go on (a removal refused, e.g. a pose not finite).
    fault: Option<String>,
    /// Where a tool that cannot cut at its centre first plunged into the stock.
    plunged_at: Option<Point3<f64>>,
    /// Where the descent into material under way began (tip), if one is.
    descent_from: Option<Point3<f64>>,
}

/// How deep into material a tool that cannot cut at its centre must descend along its axis
/// before the descent is called a plunge (m): more than the micrometres a loaded Z axis
/// vibrates by, less than any plunge a program means.
const PLUNGE_DEPTH: f64 = 0.1e-3;

/// Peak values of a cut.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CutTotals {
    /// Largest |force| of any step (N).
    pub max_force: f64,
    /// Largest spindle power of any step (W).
    pub max_power: f64,
    /// Largest spindle torque of any step (N·m).
    pub max_torque: f64,
    /// Physics steps in which the tool engaged the stock.
    pub engaged_steps: u64,
    /// Volume removed so far, as the stock measures it (m³).
    pub removed_volume: f64,
}

impl Cut {
    /// A cut of `stock` by `tool` with the force model's coefficients.
    pub fn new(stock: Stock, model: ForceModel, tool: Tool) -> Cut {
        Cut {
            stock,
            process: CutProcess::new(model),
            tool,
            path: Vec::new(),
            pending: Vec::new(),
            totals: CutTotals::default(),
            fault: None,
            plunged_at: None,
            descent_from: None,
        }
    }

    /// One physics step of length `dt`: the tool at `pose` moving at `velocity` (tool relative
    /// to part, stock frame) with the spindle at `omega` (rad/s, > 0 for M3). Returns the
    /// step's forces (averaged over the step) and removes what the tool swept up to `pose`.
    pub fn step(
        &mut self,
        pose: &Pose,
        velocity: &Vector3<f64>,
        omega: f64,
        dt: f64,
    ) -> StepForces {
        let ahead = Pose {
            tip: pose.tip + velocity * dt,
            axis: pose.axis,
        };
        let forces = if self.near_stock(pose, &ahead) {
            self.process
                .step(&self.stock as &dyn Material, pose, &ahead, omega, dt)
        } else {
            // Nowhere near the stock: nothing to cut; the spindle turns on.
            self.process.set_angle(self.process.angle() + omega * dt);
            StepForces::default()
        };
        let t = &mut self.totals;
        t.max_force = t.max_force.max(forces.peak_force);
        t.max_power = t.max_power.max(forces.mean_power);
        t.max_torque = t.max_torque.max(forces.mean_torque);
        if forces.engaged_flutes > 0 {
            t.engaged_steps += 1;
        }
        if forces.plunging_without_centre_cutting {
            let from = *self.descent_from.get_or_insert(pose.tip);
            let depth = (from - pose.tip).dot(&pose.axis);
            if depth > PLUNGE_DEPTH && self.plunged_at.is_none() {
                self.plunged_at = Some(pose.tip);
            }
        } else {
            self.descent_from = None;
        }
        self.remove_to(pose, false);
        forces
    }

    /// Whether the tool's fluted part, anywhere between poses `a` and `b`, comes within a cell
    /// of the stock's box (else no edge can meet material: the force model is not asked).
    fn near_stock(&self, a: &Pose, b: &Pose) -> bool {
        let (lo, hi) = self.stock.bounds();
        let margin = self.tool.radius() + 2.0 * self.stock.resolution();
        let reach = self.tool.flute_length;
        let ends = [a, b].map(|p| [p.tip, p.tip + p.axis.into_inner() * reach]);
        (0..3).all(|k| {
            let (min, max) = ends
                .iter()
                .flatten()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(m, n), p| {
                    (m.min(p[k]), n.max(p[k]))
                });
            min - margin <= hi[k] && max + margin >= lo[k]
        })
    }

    /// Moves the tool on to `pose`: the stock loses what the tool sweeps, in straight chords
    /// that follow the path within [`CHORD_TOLERANCE`], removed a chord's length of path at a
    /// time (or, with `always`, up to `pose` now).
    fn remove_to(&mut self, pose: &Pose, always: bool) {
        let (Some(&start), Some(&from)) = (self.path.first(), self.path.last()) else {
            // The first pose: the tool stands where it stands (a tool started inside the
            // stock removes its own volume).
            self.sweep(&[*pose]);
            self.path.push(*pose);
            return;
        };
        let longest = MAX_CHORD_RESOLUTIONS * self.stock.resolution();
        let within = (pose.tip - start.tip).norm() <= longest;
        let follows = within
            && self.pending.len() < MAX_PENDING
            && self
                .pending
                .iter()
                .all(|p| self.off_chord(&from, pose, p) <= CHORD_TOLERANCE);
        if follows && !always {
            self.pending.push(*pose);
            return;
        }
        // The chord to the last pose that still followed, then on from there.
        if let Some(&last) = self.pending.last().filter(|_| !follows) {
            self.pending.clear();
            self.path.push(last);
            if !within || self.path.len() > MAX_PATH {
                self.remove_path();
            }
            return self.remove_to(pose, always);
        }
        self.pending.clear();
        self.path.push(*pose);
        if always || !within || self.path.len() > MAX_PATH {
            self.remove_path();
        }
    }

    /// Removes the chords of the path decided so far.
    fn remove_path(&mut self) {
        if self.path.len() > 1 {
            let path = std::mem::take(&mut self.path);
            self.sweep(&path);
            self.path.push(path[path.len() - 1]);
        }
    }

    /// How far pose `p` lies from the chord `a`–`b` (m): its tip's distance from the segment,
    /// plus how far its axis turns the fluted part's far end from the chord's interpolation.
    fn off_chord(&self, a: &Pose, b: &Pose, p: &Pose) -> f64 {
        let ab = b.tip - a.tip;
        let length2 = ab.norm_squared();
        let t = if length2 > 0.0 {
            ((p.tip - a.tip).dot(&ab) / length2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let on_chord = a.tip + ab * t;
        let axis = a.axis.into_inner() * (1.0 - t) + b.axis.into_inner() * t;
        let turn = (p.axis.into_inner() - axis).norm() * self.tool.flute_length;
        (p.tip - on_chord).norm() + turn
    }

    /// Removes what the tool sweeps along `path`.
    fn sweep(&mut self, path: &[Pose]) {
        let reach = super::stock::default_reach(&self.tool);
        match self.stock.remove_swept_path(&self.tool, path, reach) {
            Ok(volume) => self.totals.removed_volume += volume,
            Err(e) => {
                if self.fault.is_none() {
                    self.fault = Some(format!("the stock could not be cut: {e}"));
                }
            }
        }
    }

    /// Why the cut cannot go on, if it cannot.
    pub fn fault(&self) -> Option<&str> {
        self.fault.as_deref()
    }

    /// Where (stock frame, m) a tool that cannot cut at its centre first plunged into the
    /// stock, if it did.
    pub fn plunged_at(&self) -> Option<Point3<f64>> {
        self.plunged_at
    }

    /// Moves the tool to `pose` without forces: removes what it sweeps (the nominal part's
    /// cut, from the programmed path).
    pub fn sweep_to(&mut self, pose: &Pose) {
        self.remove_to(pose, false);
    }

    /// Removes what the last steps swept and not yet removed (at the end of a run).
    pub fn finish(&mut self) {
        // The last pose the tool reached: the newest one not yet swept to, if any.
        match self.pending.last() {
            Some(&last) => self.remove_to(&last, true),
            None => self.remove_path(),
        }
    }

    /// The stock as cut so far.
    pub fn stock(&self) -> &Stock {
        &self.stock
    }

    /// The stock as cut (after [`Cut::finish`]).
    pub fn into_stock(self) -> Stock {
        self.stock
    }

    /// Peak values so far.
    pub fn totals(&self) -> CutTotals {
        self.totals
    }

    /// The tool.
    pub fn tool(&self) -> &Tool {
        &self.tool
    }
}

/// How far outside the tool's envelope, along its normal, the stock is asked for material at a
/// cutting edge (in stock resolutions). The material a tool meets in one step is a sliver a few
/// micrometres thick (the feed over a step, less the removal's lag), thinner than the lattice
/// resolves across the ray the query reads: read at the edge itself, a ray half a cell aside
/// could answer for the sliver's other side. Half a cell out along the normal clears that
/// (the lateral rounding moves the answer by at most res/2·sin 45° along it), and stays in
/// material wherever the edge meets any: in front of the moving tool everything outside its
/// envelope is outside every earlier envelope too, and behind it the chip thickness is
/// negative, so nothing there is engaged. Where the stock's own boundary crosses the flutes
/// (a wall left by another pass) the engagement angle shifts by about δ·cos φ/(R·sin φ):
/// 0.01 rad for a 10 mm tool at 0.1 mm resolution and a quarter immersion.
const ENGAGEMENT_PROBE_RESOLUTIONS: f64 = 0.5;

impl Material for Stock {
    fn contains(&self, point: &Point3<f64>, normal_hint: &Vector3<f64>) -> bool {
        let probe = point + normal_hint * (ENGAGEMENT_PROBE_RESOLUTIONS * self.resolution());
        Stock::contains(self, &probe, normal_hint)
    }

    /// The lattice's box, grown by the probe's reach: an edge farther out reads no material.
    fn bounds(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        let (lo, hi) = Stock::bounds(self);
        let grow = Vector3::repeat(ENGAGEMENT_PROBE_RESOLUTIONS * self.resolution());
        Some((lo - grow, hi + grow))
    }
}

/// A tool pose from a point and an axis (normalised; a zero axis falls back to +Z).
pub fn pose(tip: Point3<f64>, axis: Vector3<f64>) -> Pose {
    Pose {
        tip,
        axis: Unit::try_new(axis, 1e-12).unwrap_or(Vector3::z_axis()),
    }
}
