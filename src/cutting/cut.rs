//! One lane's cut: its own stock, the force model stepping with the spindle, and the removal
//! of what the tool sweeps. The plant calls [`Cut::step`] every physics step with the tool's
//! pose and velocity on the part; the cut answers with the force and removes material.

use super::{CutProcess, ForceModel, Material, Pose, StepForces, Stock, Tool};
use nalgebra::{Point3, Unit, Vector3};

/// How far the tool's path may stray from the straight chord removal sweeps it along (m): the
/// stock is cut by the tool swept in straight chords, each as long as the path stays within
/// this of it (at the tip, and at the far end of the fluted part for a turning axis). On a
/// 25 mm radius that is a chord of 0.2 mm; on a straight line the chord grows to the stretch
/// removed at once, [`MAX_STRETCH_RESOLUTIONS`].
const CHORD_TOLERANCE: f64 = 0.2e-6;

/// Longest stretch of path removed in one pass over the rays (in stock resolutions), which is
/// also the most the removal lags the tool by. Lagging removal does not change what the force
/// model reads (it asks in front of the moving tool, where nothing was removed yet; behind it
/// the chip thickness is negative; beside it, on a path curving less sharply than the tool's
/// radius, nothing earlier swept either), as long as the tool does not turn back or aside into
/// its own track: a stretch ends where the path leaves its course by [`COURSE_RESOLUTIONS`].
const MAX_STRETCH_RESOLUTIONS: f64 = 8.0;

/// How far (in stock resolutions) the tool may fall behind or aside from the course of the
/// stretch of path not yet removed (from its start through its last chord's end) before that
/// stretch is removed: the force model's probe reads half a cell outside the tool, so a tool
/// turning into its own track meets no material it already cut. Vibration of a micrometre and
/// paths curving gently stay on course.
const COURSE_RESOLUTIONS: f64 = 0.5;

/// Poses kept between removals, to test the chord against.
const MAX_PENDING: usize = 256;

/// Most chords removed in one pass over the rays.
const MAX_PATH: usize = 160;

/// One lane's cut.
pub struct Cut {
    stock: Stock,
    process: CutProcess,
    tool: Tool,
    /// The chords decided and not yet removed, as the poses joining them: the first is where
    /// the stock has been cut to, the last where the next chord starts. Removed together in
    /// one pass over the rays once the tool is a stretch ([`MAX_STRETCH_RESOLUTIONS`]) from the
    /// first, or leaves the stretch's course.
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
    /// that follow the path within [`CHORD_TOLERANCE`], removed a stretch of path at a time
    /// (or, with `always`, up to `pose` now).
    fn remove_to(&mut self, pose: &Pose, always: bool) {
        let (Some(&start), Some(&from)) = (self.path.first(), self.path.last()) else {
            // The first pose: the tool stands where it stands (a tool started inside the
            // stock removes its own volume).
            self.sweep(&[*pose]);
            self.path.push(*pose);
            return;
        };
        let longest = MAX_STRETCH_RESOLUTIONS * self.stock.resolution();
        let within =
            (pose.tip - start.tip).norm() <= longest && self.on_course(&start, &from, pose);
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

    /// Whether `pose` keeps to the course of the stretch from `start` to `from`: not behind
    /// `from` along it, nor aside from it, by more than [`COURSE_RESOLUTIONS`]. A stretch
    /// shorter than that has no course yet.
    fn on_course(&self, start: &Pose, from: &Pose, pose: &Pose) -> bool {
        let slack = COURSE_RESOLUTIONS * self.stock.resolution();
        let course = from.tip - start.tip;
        let length = course.norm();
        if length <= slack {
            return true;
        }
        let r = pose.tip - start.tip;
        let along = r.dot(&course) / length;
        along >= length - slack && (r - course * (along / length)).norm() <= slack
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutting::{material, ToolShape};

    const MM: f64 = 1e-3;

    fn slot_cut() -> Cut {
        let stock = Stock::from_box(
            Point3::new(0.0, -10.0 * MM, -5.0 * MM),
            Point3::new(20.0 * MM, 10.0 * MM, 0.0),
            0.1 * MM,
            1 << 30,
        )
        .unwrap();
        let tool = Tool {
            diameter: 6.0 * MM,
            flutes: 3,
            helix: 0.5,
            flute_length: 10.0 * MM,
            shape: ToolShape::Flat,
        };
        let model = ForceModel::new(tool, material("al7075").unwrap().coefficients).unwrap();
        Cut::new(stock, model, tool)
    }

    /// Whether the stock holds material at `(x, y)` mm, 1 mm below its top.
    fn solid(cut: &Cut, x: f64, y: f64) -> bool {
        cut.stock()
            .contains(&Point3::new(x * MM, y * MM, -MM), &Vector3::x())
    }

    #[test]
    fn removal_lags_the_tool_by_a_stretch_and_catches_up_where_it_turns_back() {
        // A 6 mm tool, 2 mm deep, feeding along X in 5 µm steps from x = 5 mm.
        let mut cut = slot_cut();
        let at = |x: f64| pose(Point3::new(x * MM, 0.0, -2.0 * MM), Vector3::z());
        let dt = 1e-4;
        let v = Vector3::new(0.05, 0.0, 0.0);
        let mut x = 5.0;
        for _ in 0..=200 {
            cut.step(&at(x), &v, 1000.0, dt);
            x += 0.005;
        }
        // At x = 6 mm the removal lags by at most a stretch (0.8 mm here): the tool's trailing
        // edge is cut, its leading edge at 9 mm not yet by more than 0.8 mm.
        assert!(!solid(&cut, 5.0 - 3.0 + 0.05, 0.0), "behind the start");
        assert!(!solid(&cut, 9.0 - 0.85, 0.0), "lagging more than a stretch");
        // Turning back: once the tool is half a cell behind its course, what it swept going
        // forward is gone before it cuts again.
        for _ in 0..20 {
            x -= 0.005;
            cut.step(&at(x), &(-v), 1000.0, dt);
        }
        assert!(
            !solid(&cut, 8.99, 0.0),
            "the forward stretch left behind at the turn"
        );
        // Away from the cut the block is whole.
        assert!(solid(&cut, 9.2, 0.0) && solid(&cut, 6.0, 3.2));
    }
}
