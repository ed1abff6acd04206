//! A cut over time: the spindle angle carried from step to step and the edge forces averaged
//! over each physics step, sampled finely enough to resolve every tooth pass.

use std::f64::consts::TAU;

use nalgebra::{Point3, Unit, Vector3};

use super::force::{plunges_without_centre_cutting, EdgeForces, ForceModel, Material};
use super::tool::Pose;

/// Samples per tooth period: the spindle turns at most 2π/(N·36) between samples (10° of
/// tooth pitch), which puts the tooth-passing frequency and its first harmonics well inside
/// the sampling and keeps the mean over a step within a fraction of a percent of the exact
/// integral for the piecewise-smooth edge forces.
pub const SAMPLES_PER_TOOTH: u32 = 36;
/// Cap on the samples of one step, so that a huge `dt·ω` cannot stall the caller; beyond it
/// the samples are coarser than [`SAMPLES_PER_TOOTH`] (the mean then aliases).
pub const MAX_SAMPLES_PER_STEP: u32 = 1 << 16;

/// The forces of one physics step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepForces {
    /// Force on the tool averaged over the step (N, part frame): the step's impulse / dt.
    pub mean_on_tool: Vector3<f64>,
    /// Largest force magnitude among the samples (N).
    pub peak_force: f64,
    /// Spindle torque averaged over the step (N·m), ≥ 0.
    pub mean_torque: f64,
    /// Cutting power averaged over the step, mean torque × |ω| (W).
    pub mean_power: f64,
    /// Most flutes engaged at once among the samples.
    pub engaged_flutes: u32,
    /// Whether any sample cut.
    pub any_engaged: bool,
    /// The spindle is stopped (`omega == 0`) while the tool runs into material.
    pub spindle_stopped_while_engaged: bool,
    /// A flat or bull-nose tool plunges into material (see
    /// [`super::force::plunges_without_centre_cutting`]).
    pub plunging_without_centre_cutting: bool,
    /// Spindle angle advanced over the step, ω·dt (rad, signed).
    pub angle_advanced: f64,
    /// Samples taken.
    pub samples: u32,
}

/// A cut in progress: the force model and the spindle angle it has reached.
#[derive(Debug, Clone, PartialEq)]
pub struct CutProcess {
    model: ForceModel,
    /// Spindle angle of flute 0 at the tip (rad), kept in [0, 2π).
    angle: f64,
}

impl CutProcess {
    /// A cut with the spindle at angle 0.
    pub fn new(model: ForceModel) -> Self {
        CutProcess { model, angle: 0.0 }
    }

    /// The force model.
    pub fn model(&self) -> &ForceModel {
        &self.model
    }

    /// Current spindle angle (rad, in [0, 2π)).
    pub fn angle(&self) -> f64 {
        self.angle
    }

    /// Sets the spindle angle (rad); a non-finite angle is ignored.
    pub fn set_angle(&mut self, angle: f64) {
        if angle.is_finite() {
            self.angle = angle.rem_euclid(TAU);
        }
    }

    /// One physics step of length `dt` (s), the tool moving linearly from `from` to `to`
    /// (its velocity their difference / dt), spindle speed `omega` (rad/s, signed, > 0 for
    /// M3). See [`CutProcess::step_with_velocity`].
    pub fn step(
        &mut self,
        material: &dyn Material,
        from: &Pose,
        to: &Pose,
        omega: f64,
        dt: f64,
    ) -> StepForces {
        let velocity = if dt > 0.0 {
            (to.tip - from.tip) / dt
        } else {
            Vector3::zeros()
        };
        self.step_with_velocity(material, from, to, &velocity, omega, dt)
    }

    /// One physics step with the tool's velocity given (tool relative to part, part frame,
    /// m/s), e.g. the rigid body's own rather than the poses' difference.
    ///
    /// The step is cut into `n = ⌈|ω|·dt / (2π/(N·36))⌉` equal parts ([`SAMPLES_PER_TOOTH`],
    /// at most [`MAX_SAMPLES_PER_STEP`]); the forces are taken at each part's middle (pose
    /// interpolated: tip linearly, axis normalised-linearly; spindle angle advanced at ω)
    /// and averaged, a midpoint rule for the step's impulse. The spindle angle then advances
    /// by ω·dt. A `dt` that is not positive and finite, or a non-finite ω, gives zero forces
    /// and leaves the angle alone.
    pub fn step_with_velocity(
        &mut self,
        material: &dyn Material,
        from: &Pose,
        to: &Pose,
        velocity: &Vector3<f64>,
        omega: f64,
        dt: f64,
    ) -> StepForces {
        if !(dt > 0.0 && dt.is_finite() && omega.is_finite()) {
            return StepForces::default();
        }
        let mid = interpolate(from, to, 0.5);
        let plunging = plunges_without_centre_cutting(self.model.tool(), material, &mid, velocity);
        if omega == 0.0 {
            return StepForces {
                spindle_stopped_while_engaged: self
                    .model
                    .blocked_by_material(material, &mid, velocity),
                plunging_without_centre_cutting: plunging,
                ..StepForces::default()
            };
        }

        let flutes = f64::from(self.model.tool().flutes);
        let max_turn = TAU / (flutes * f64::from(SAMPLES_PER_TOOTH));
        let turn = omega * dt;
        let wanted = (turn.abs() / max_turn).ceil();
        let n = if wanted >= f64::from(MAX_SAMPLES_PER_STEP) {
            MAX_SAMPLES_PER_STEP
        } else {
            (wanted as u32).max(1)
        };

        let mut sum = EdgeForces::default();
        let mut peak: f64 = 0.0;
        let mut engaged_flutes = 0;
        let mut engaged_samples = 0u32;
        for k in 0..n {
            let t = (f64::from(k) + 0.5) / f64::from(n);
            let pose = interpolate(from, to, t);
            let f = self
                .model
                .at(material, &pose, velocity, self.angle + turn * t, omega);
            sum.on_tool += f.on_tool;
            sum.spindle_torque += f.spindle_torque;
            engaged_samples += u32::from(f.engaged_slices > 0);
            peak = peak.max(f.on_tool.norm());
            engaged_flutes = engaged_flutes.max(f.engaged_flutes);
        }
        self.angle = (self.angle + turn).rem_euclid(TAU);
        let inv = 1.0 / f64::from(n);
        let mean_torque = sum.spindle_torque * inv;
        StepForces {
            mean_on_tool: sum.on_tool * inv,
            peak_force: peak,
            mean_torque,
            mean_power: mean_torque * omega.abs(),
            engaged_flutes,
            any_engaged: engaged_samples > 0,
            spindle_stopped_while_engaged: false,
            plunging_without_centre_cutting: plunging,
            angle_advanced: turn,
            samples: n,
        }
    }
}

/// The pose a fraction `t` of the way from `a` to `b`: tip linear, axis normalised-linear
/// (`a`'s axis if the two are opposite).
fn interpolate(a: &Pose, b: &Pose, t: f64) -> Pose {
    let tip = Point3::from(a.tip.coords.lerp(&b.tip.coords, t));
    let axis = if a.axis == b.axis {
        a.axis
    } else {
        Unit::try_new(a.axis.lerp(&b.axis, t), 1e-12).unwrap_or(a.axis)
    };
    Pose { tip, axis }
}

#[cfg(test)]
mod tests {
    use super::super::force::solids::SteadyCut;
    use super::super::material::material;
    use super::super::tool::{Tool, ToolShape};
    use super::*;

    fn tool() -> Tool {
        Tool {
            diameter: 16e-3,
            flutes: 4,
            helix: 30f64.to_radians(),
            flute_length: 20e-3,
            shape: ToolShape::Flat,
        }
    }

    fn process(tool: Tool) -> CutProcess {
        let k = match material("al7075") {
            Some(m) => m.coefficients,
            None => panic!("al7075 missing"),
        };
        match ForceModel::new(tool, k) {
            Ok(m) => CutProcess::new(m),
            Err(e) => panic!("{e}"),
        }
    }

    fn at_x(x: f64) -> Pose {
        Pose {
            tip: Point3::new(x, 0.0, 0.0),
            axis: Vector3::z_axis(),
        }
    }

    /// Runs `steps` physics steps of a straight +X cut; returns the steps' results.
    fn run(
        p: &mut CutProcess,
        stock: &mut SteadyCut,
        feed: f64,
        omega: f64,
        dt: f64,
        steps: usize,
    ) -> Vec<StepForces> {
        let mut x = 0.0;
        (0..steps)
            .map(|_| {
                // The stock as before this step's removal: swept up to where the step starts.
                stock.x_c = x;
                let next = x + feed * dt;
                let f = p.step(stock, &at_x(x), &at_x(next), omega, dt);
                x = next;
                f
            })
            .collect()
    }

    /// |DFT| of `signal` at bin `k` (plain sum: the test needs no FFT crate).
    fn dft_magnitude(signal: &[f64], k: usize) -> f64 {
        let n = signal.len() as f64;
        let (mut re, mut im) = (0.0, 0.0);
        for (i, s) in signal.iter().enumerate() {
            let a = TAU * (k as f64) * (i as f64) / n;
            re += s * a.cos();
            im -= s * a.sin();
        }
        (re * re + im * im).sqrt()
    }

    #[test]
    fn spectrum_peaks_at_tooth_passing_frequency() {
        let t = tool();
        let mut p = process(t);
        let rpm = 6000.0;
        let omega = rpm * TAU / 60.0;
        let c = 0.1e-3;
        let feed = c * 4.0 * rpm / 60.0;
        let mut stock = SteadyCut::down_half(t.radius(), 3e-3);
        let dt = 1.0 / 5000.0; // 5 kHz physics; tooth passing at 400 Hz
        let steps = 2000; // 0.4 s = 40 revolutions; 2.5 Hz bins
        let out = run(&mut p, &mut stock, feed, omega, dt, steps);
        assert!(out.iter().all(|f| f.any_engaged && f.samples >= 1));
        let fx: Vec<f64> = out.iter().map(|f| f.mean_on_tool.x).collect();
        let mean = fx.iter().sum::<f64>() / fx.len() as f64;
        let centred: Vec<f64> = fx.iter().map(|v| v - mean).collect();
        let (best, _) = (1..steps / 2)
            .map(|k| (k, dft_magnitude(&centred, k)))
            .fold((0, 0.0), |acc, x| if x.1 > acc.1 { x } else { acc });
        let bin = 1.0 / (dt * steps as f64);
        let peak_hz = best as f64 * bin;
        let tooth_hz = 4.0 * rpm / 60.0;
        println!("spectrum: peak at {peak_hz} Hz, tooth passing {tooth_hz} Hz (bin {bin} Hz)");
        assert!((peak_hz - tooth_hz).abs() <= bin, "peak {peak_hz} Hz");
    }

    #[test]
    fn step_means_match_closed_form_over_whole_revolutions() {
        // A slot over exactly 10 revolutions in 1 ms steps: the mean of the step means equals
        // Altintas' average force (F̄x = (Nac/8π)·(−2π·K_rc)... evaluated 0→π).
        let t = tool();
        let mut p = process(t);
        let rpm = 3000.0;
        let omega = rpm * TAU / 60.0;
        let c = 0.1e-3;
        let feed = c * 4.0 * rpm / 60.0;
        let a = 5e-3;
        let mut stock = SteadyCut::slot(t.radius(), a);
        let out = run(&mut p, &mut stock, feed, omega, 1e-3, 200);
        let n = out.len() as f64;
        let mean = out.iter().fold(Vector3::zeros(), |s, f| s + f.mean_on_tool) / n;
        let k = p.model().coefficients();
        use std::f64::consts::PI;
        let fx =
            -(4.0 * a * c / (8.0 * PI)) * k.krc * 2.0 * PI - 4.0 * a / (2.0 * PI) * 2.0 * k.kre;
        let fy = (4.0 * a * c / (8.0 * PI)) * k.ktc * 2.0 * PI + 4.0 * a / (2.0 * PI) * 2.0 * k.kte;
        let fz = 4.0 * a / (2.0 * PI) * (2.0 * k.kac * c + k.kae * PI);
        let want = Vector3::new(fx, fy, fz);
        let dev = (mean - want).norm() / want.norm();
        println!(
            "process slot mean: {mean:?} vs {want:?}, deviation {:.4} %",
            100.0 * dev
        );
        assert!(dev < 0.01, "{mean:?} vs {want:?}");
        // Power = torque·ω; torque ≈ (N a R/2π)(2 K_tc c + π K_te) for a slot.
        let torque = out.iter().map(|f| f.mean_torque).sum::<f64>() / n;
        let want_t = 4.0 * a * t.radius() / (2.0 * PI) * (2.0 * k.ktc * c + PI * k.kte);
        assert!(
            (torque - want_t).abs() < 0.01 * want_t,
            "{torque} vs {want_t}"
        );
        assert!((out[0].mean_power - out[0].mean_torque * omega).abs() < 1e-9 * out[0].mean_power);
        assert!(out.iter().all(|f| f.peak_force >= f.mean_on_tool.norm()));
        // Sampling rule: 36 samples per tooth period.
        let per_step = omega * 1e-3 / (TAU / (4.0 * 36.0));
        assert_eq!(out[0].samples, per_step.ceil() as u32);
        // The angle advanced: 200 steps of ω·1 ms = 10 revolutions.
        assert!(
            (p.angle() - 0.0).abs() < 1e-6 || (p.angle() - TAU).abs() < 1e-6,
            "{}",
            p.angle()
        );
    }

    #[test]
    fn stopped_spindle_in_material_is_flagged() {
        let t = tool();
        let mut p = process(t);
        let stock = SteadyCut::slot(t.radius(), 5e-3);
        let f = p.step(&stock, &at_x(0.0), &at_x(1e-5), 0.0, 1e-3);
        assert!(f.spindle_stopped_while_engaged && !f.any_engaged);
        assert_eq!(f.mean_on_tool, Vector3::zeros());
        // Backing out: nothing ahead.
        let f = p.step(&stock, &at_x(0.0), &at_x(-1e-5), 0.0, 1e-3);
        assert!(!f.spindle_stopped_while_engaged);
        // Turning spindle: a cut, not a crash.
        let f = p.step(&stock, &at_x(0.0), &at_x(1e-5), 600.0, 1e-3);
        assert!(!f.spindle_stopped_while_engaged && f.any_engaged);
    }

    #[test]
    fn plunge_and_bad_steps() {
        let t = tool();
        let mut p = process(t);
        let stock = SteadyCut::slot(t.radius(), 5e-3);
        let down = Pose {
            tip: Point3::new(0.0, 0.0, -1e-5),
            axis: Vector3::z_axis(),
        };
        let f = p.step(&stock, &at_x(0.0), &down, 600.0, 1e-3);
        assert!(f.plunging_without_centre_cutting);
        let before = p.angle();
        for (omega, dt) in [
            (600.0, 0.0),
            (600.0, -1.0),
            (600.0, f64::NAN),
            (f64::NAN, 1e-3),
        ] {
            assert_eq!(
                p.step(&stock, &at_x(0.0), &at_x(1e-5), omega, dt),
                StepForces::default()
            );
        }
        assert_eq!(p.angle(), before);
        // A huge step is capped, not stalled.
        let f = p.step(&stock, &at_x(0.0), &at_x(1e-5), 1e6, 10.0);
        assert_eq!(f.samples, MAX_SAMPLES_PER_STEP);
        assert!(f.mean_on_tool.iter().all(|v| v.is_finite()));
    }
}
