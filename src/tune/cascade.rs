//! Tuning the cascade the way servo drives are commissioned: the velocity loop first, by the
//! bandwidth its margins allow, then the position loop at a quarter of it.
//!
//! The velocity loop is the axis's one linear model ([`AxisPlant`], `crate::frequency::linear`):
//! the plant from the command to the motor encoder sampled with the servo loop's zero-order
//! hold (the DC motor's current and back-EMF, the compliant drive train's two masses and the
//! hold's lag all exact in it), the velocity estimate as the differenced encoder behind its
//! low-pass, the PI law Kpv + Kiv·T·z/(z − 1) and the command filters, all evaluated at
//! z = e^{jωT}. The PI's integral zero sits at a quarter of the crossover ω_v (Kiv = Kpv·ω_v/4)
//! and Kpv puts the crossover at ω_v (|L(e^{jω_vT})| = 1). The largest ω_v is the one whose
//! open loop, evaluated on a dense grid, crosses 0 dB once with [`PHASE_MARGIN_DEG`] of phase
//! margin and [`GAIN_MARGIN_DB`] of gain margin, and on a compliant drive train without a notch
//! lies below the antiresonance (so below its first resonance). The position loop is P with
//! Kpp = ω_v/4 (its bandwidth a quarter of the velocity loop's, so the two do not fight), with
//! full velocity and acceleration feed-forward.

use crate::control::{velocity_smoothing, CascadeAxis, TorqueFilters};
use crate::frequency::{AxisPlant, LinearController, Loop, SampledPlant, C64};
use serde::Serialize;
use std::f64::consts::{PI, TAU};

/// Phase margin the velocity loop is designed for (degrees).
pub const PHASE_MARGIN_DEG: f64 = 50.0;
/// Gain margin the velocity loop keeps (dB).
pub const GAIN_MARGIN_DB: f64 = 6.0;

/// What lies in the velocity loop besides the plant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LoopShape {
    /// The velocity estimate's first-order low-pass (Hz; 0: none).
    pub velocity_filter_hz: f64,
    /// Low-pass and notch on the command.
    pub torque_filters: TorqueFilters,
}

/// A cascade design for one axis, with the figures it was derived from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CascadeDesign {
    /// Velocity-loop crossover (Hz).
    pub velocity_bandwidth_hz: f64,
    /// Phase margin at the velocity-loop crossover (degrees).
    pub phase_margin_deg: f64,
    /// Position-loop bandwidth (Hz): Kpp/2π.
    pub position_bandwidth_hz: f64,
    /// Gain margin of the velocity loop (dB; infinite when the phase never reaches −180°).
    pub gain_margin_db: f64,
    /// The drive train's resonance (Hz), when it is compliant.
    pub resonance_hz: Option<f64>,
    /// The drive train's antiresonance seen from the motor (Hz), when it is compliant.
    pub antiresonance_hz: Option<f64>,
    /// Joint force per command unit at standstill.
    pub force_per_command: f64,
    /// Inertia the motor moves at low frequency, drive side and carriage (kg or kg·m²).
    pub mass: f64,
    /// Viscous damping at low frequency (N·s/m or N·m·s/rad; back-EMF included in voltage
    /// mode).
    pub damping: f64,
    /// The gains as the cascade controller takes them: PI velocity loop, P position loop, full
    /// feed-forward, no limits, the shape's command filters.
    #[serde(skip)]
    pub axis: CascadeAxis,
}

/// The cascade of `plant` at servo period `period` with what `shape` puts in the velocity loop.
/// `bandwidth_hz` imposes the velocity-loop crossover; by default it is the largest that keeps
/// the margins.
pub fn design_cascade(
    plant: &AxisPlant,
    period: f64,
    shape: &LoopShape,
    bandwidth_hz: Option<f64>,
) -> Result<CascadeDesign, String> {
    if !(plant.force_per_command() > 0.0 && plant.total_mass() > 0.0 && period > 0.0) {
        return Err(
            "the axis has no drive gain or no inertia to design a velocity loop for".into(),
        );
    }
    let velocity_loop = VelocityLoop::new(plant, period, shape);
    let omega = match bandwidth_hz {
        Some(f) => {
            if !(f > 0.0 && f < 0.5 / period) {
                return Err(format!(
                    "velocity bandwidth {f} Hz: expected a value above 0 and below the Nyquist frequency {} Hz",
                    0.5 / period
                ));
            }
            TAU * f
        }
        None => velocity_loop.largest_crossover()?,
    };
    let (velocity_kp, velocity_ki) = velocity_loop.gains_for_crossover(omega);
    let margins = velocity_loop.margins(velocity_kp, velocity_ki);
    let position_kp = omega / 4.0;
    let modes = plant.modes_hz();
    Ok(CascadeDesign {
        velocity_bandwidth_hz: omega / TAU,
        phase_margin_deg: velocity_loop.phase_margin_at(velocity_kp, velocity_ki, omega),
        gain_margin_db: margins.gain_margin_db,
        resonance_hz: modes.map(|m| m.0),
        antiresonance_hz: modes.map(|m| m.1),
        position_bandwidth_hz: position_kp / TAU,
        force_per_command: plant.force_per_command(),
        mass: plant.total_mass(),
        damping: plant.low_frequency_damping(),
        axis: CascadeAxis {
            position_kp,
            position_ki: 0.0,
            velocity_kp,
            velocity_ki,
            velocity_ff: 1.0,
            acceleration_ff: 1.0,
            velocity_limit: f64::INFINITY,
            output_limit: f64::INFINITY,
            filters: shape.torque_filters,
        },
    })
}

/// Phase and gain margin of an open loop, and how often it crosses 0 dB.
struct Margins {
    gain_margin_db: f64,
    crossovers: usize,
}

/// Points per decade of the grid the margins are read on.
const GRID_PER_DECADE: f64 = 400.0;

/// The velocity loop of one axis, broken at the plant input: L = C_v·F·V̂·P_m with the PI law
/// C_v, the command filters F, the velocity estimate V̂ and the plant to the motor encoder P_m.
/// On the grid L is kept as its two parts, L = Kpv·L_p + Kiv·L_i, so that trying gains costs
/// no plant evaluation.
struct VelocityLoop<'a> {
    plant: &'a AxisPlant,
    sampled: SampledPlant,
    shape: LoopShape,
    period: f64,
    /// Frequencies of the grid (Hz), from 0.01 Hz to the Nyquist frequency.
    grid: Vec<f64>,
    /// L at Kpv = 1, Kiv = 0 on the grid.
    proportional: Vec<C64>,
    /// L at Kpv = 0, Kiv = 1 on the grid.
    integral: Vec<C64>,
}

impl<'a> VelocityLoop<'a> {
    fn new(plant: &'a AxisPlant, period: f64, shape: &LoopShape) -> VelocityLoop<'a> {
        let sampled = plant.sampled(period);
        let (lo, hi) = (0.01, 0.5 / period);
        let n = ((hi / lo).log10() * GRID_PER_DECADE).ceil() as usize;
        let grid: Vec<f64> = (0..=n)
            .map(|i| lo * (hi / lo).powf(i as f64 / n as f64))
            .collect();
        let mut l = VelocityLoop {
            plant,
            sampled,
            shape: *shape,
            period,
            grid: Vec::new(),
            proportional: Vec::new(),
            integral: Vec::new(),
        };
        l.proportional = grid.iter().map(|&f| l.open(1.0, 0.0, f)).collect();
        l.integral = grid.iter().map(|&f| l.open(0.0, 1.0, f)).collect();
        l.grid = grid;
        l
    }

    /// L(e^{jωT}) at `frequency` (Hz) with the velocity gains `kp`, `ki`: the controller's own
    /// law on the sampled plant.
    fn open(&self, kp: f64, ki: f64, frequency: f64) -> C64 {
        let law = LinearController::Cascade {
            position_kp: 0.0,
            position_ki: 0.0,
            velocity_kp: kp,
            velocity_ki: ki,
            velocity_ff: 0.0,
            acceleration_ff: 0.0,
            smoothing: velocity_smoothing(self.shape.velocity_filter_hz, self.period),
            filters: self.shape.torque_filters,
        };
        law.response(Loop::Velocity, self.plant, &self.sampled, frequency)
            .open
    }

    /// Kpv and Kiv that put the crossover at ω (rad/s) with the PI zero at ω/4.
    fn gains_for_crossover(&self, omega: f64) -> (f64, f64) {
        let unit = self.open(1.0, omega / 4.0, omega / TAU);
        let kp = 1.0 / unit.norm();
        (kp, kp * omega / 4.0)
    }

    /// Phase margin at a crossover ω (rad/s): the distance of L's phase there from −180°
    /// (modulo 360°), negative past it.
    fn phase_margin_at(&self, kp: f64, ki: f64, omega: f64) -> f64 {
        let margin = (self.open(kp, ki, omega / TAU).arg().to_degrees() + 180.0).rem_euclid(360.0);
        if margin > 180.0 {
            margin - 360.0
        } else {
            margin
        }
    }

    /// The crossovers and the gain margin of L on the grid.
    fn margins(&self, kp: f64, ki: f64) -> Margins {
        let values: Vec<C64> = self
            .proportional
            .iter()
            .zip(&self.integral)
            .map(|(p, i)| kp * p + ki * i)
            .collect();
        // Unwrapped phase along the grid, in degrees.
        let mut phase = Vec::with_capacity(values.len());
        let mut previous: f64 = values[0].arg().to_degrees();
        for v in &values {
            let mut p = v.arg().to_degrees();
            p -= 360.0 * ((p - previous) / 360.0).round();
            phase.push(p);
            previous = p;
        }
        let mut crossovers = 0;
        let mut gain_margin_db = f64::INFINITY;
        for i in 1..values.len() {
            let (g0, g1) = (values[i - 1].norm().log10(), values[i].norm().log10());
            if (g0 >= 0.0) != (g1 >= 0.0) {
                crossovers += 1;
            }
            // Phase crossings of −180° (mod 360°).
            let (k0, k1) = (
                ((phase[i - 1] + 180.0) / 360.0).floor(),
                ((phase[i] + 180.0) / 360.0).floor(),
            );
            if k0 != k1 {
                let edge = k0.max(k1) * 360.0 - 180.0;
                let f = (edge - phase[i - 1]) / (phase[i] - phase[i - 1]);
                let g = g0 + f * (g1 - g0);
                gain_margin_db = gain_margin_db.min(-20.0 * g);
            }
        }
        Margins {
            gain_margin_db,
            crossovers,
        }
    }

    /// Whether the loop with its crossover at ω meets both margins with one crossover.
    fn meets_margins(&self, omega: f64) -> bool {
        let (kp, ki) = self.gains_for_crossover(omega);
        let m = self.margins(kp, ki);
        m.crossovers == 1
            && self.phase_margin_at(kp, ki, omega) >= PHASE_MARGIN_DEG
            && m.gain_margin_db >= GAIN_MARGIN_DB
    }

    /// The largest crossover that meets the margins: scanned down a grid, then bisected.
    fn largest_crossover(&self) -> Result<f64, String> {
        // Without a notch the loop stays below the antiresonance: above it the motor moves
        // while the load rings on the spring, a mode the motor-side loop can neither see nor
        // damp (its pole and zero nearly cancel where the drive side is the heavier).
        let mut hi = 0.9 * PI / self.period;
        if let (Some((_, antiresonance)), None) =
            (self.plant.modes_hz(), self.shape.torque_filters.notch)
        {
            hi = hi.min(TAU * antiresonance);
        }
        let lo = TAU * 0.1;
        let n = 200;
        let candidates: Vec<f64> = (0..=n)
            .map(|i| lo * (hi / lo).powf(i as f64 / n as f64))
            .collect();
        let Some(best) = candidates.iter().rposition(|&w| self.meets_margins(w)) else {
            let modes = match self.plant.modes_hz() {
                Some((resonance, _)) => format!(
                    " (the drive train resonates at {resonance:.1} Hz: a notch there, or a low-pass below it, lets the loop through)"
                ),
                None => String::new(),
            };
            return Err(format!(
                "no velocity-loop crossover above 0.1 Hz keeps {PHASE_MARGIN_DEG}° of phase margin and {GAIN_MARGIN_DB} dB of gain margin{modes}"
            ));
        };
        let (mut good, mut bad) = (candidates[best], *candidates.get(best + 1).unwrap_or(&hi));
        if best == n {
            return Ok(good);
        }
        for _ in 0..40 {
            let mid = (good * bad).sqrt();
            if self.meets_margins(mid) {
                good = mid;
            } else {
                bad = mid;
            }
        }
        Ok(good)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tune::linear::xyz_table_x_axis;

    #[test]
    fn the_design_meets_its_phase_margin_and_crossover() {
        let axis = xyz_table_x_axis();
        let d = design_cascade(&axis, 1e-3, &LoopShape::default(), None).unwrap();
        assert!(
            (d.phase_margin_deg - PHASE_MARGIN_DEG).abs() < 1e-6,
            "{d:?}"
        );
        // |L| = 1 at the crossover, the PI zero at a quarter of it.
        let w = TAU * d.velocity_bandwidth_hz;
        let l = VelocityLoop::new(&axis, 1e-3, &LoopShape::default());
        assert!(
            (l.open(d.axis.velocity_kp, d.axis.velocity_ki, w / TAU)
                .norm()
                - 1.0)
                .abs()
                < 1e-12
        );
        assert!((d.axis.velocity_ki / d.axis.velocity_kp - w / 4.0).abs() < 1e-9 * w);
        // Well below the rigid plant-only estimate |b·Kpv/(j·m·ω + c')| = 1 would not hold:
        // the hold, the current and the PI zero are in the loop.
        assert!(
            d.velocity_bandwidth_hz > 20.0 && d.velocity_bandwidth_hz < 500.0,
            "{d:?}"
        );
        // A slower servo period allows less bandwidth (the current's L/R = 2.1 ms lags too).
        let slow = design_cascade(&axis, 4e-3, &LoopShape::default(), None).unwrap();
        assert!(
            slow.velocity_bandwidth_hz < 0.7 * d.velocity_bandwidth_hz,
            "{} vs {} Hz",
            slow.velocity_bandwidth_hz,
            d.velocity_bandwidth_hz
        );
        assert!(design_cascade(&axis, 1e-3, &LoopShape::default(), Some(600.0)).is_err());
        // The rigid loop's margins, read off its frequency response: the design's phase
        // margin, and a gain margin from the delays.
        assert!(d.gain_margin_db > GAIN_MARGIN_DB, "{d:?}");
    }

    /// The X axis with its drive side joined to its 20 kg carriage by a spring of stiffness k.
    fn compliant(k: f64) -> (AxisPlant, LoopShape) {
        let axis = AxisPlant {
            transmission: crate::frequency::Transmission {
                stiffness: k,
                damping: 20.0,
            },
            ..xyz_table_x_axis()
        };
        (axis, LoopShape::default())
    }

    #[test]
    fn on_a_compliant_drive_train_the_crossover_stays_below_the_resonance() {
        // A belt of 2·10⁵ N/m: a 16 Hz mode, lightly damped (ζ ≈ 0.5 %).
        let (axis, shape) = compliant(2.0e5);
        let rigid = design_cascade(&xyz_table_x_axis(), 1e-3, &shape, None).unwrap();
        let d = design_cascade(&axis, 1e-3, &shape, None).unwrap();
        let resonance = d.resonance_hz.unwrap();
        assert!((resonance - 16.5).abs() < 0.5, "{resonance}");
        assert!(d.velocity_bandwidth_hz < resonance, "{d:?}");
        assert!(
            d.velocity_bandwidth_hz < rigid.velocity_bandwidth_hz,
            "{d:?}"
        );
        assert!(d.phase_margin_deg >= PHASE_MARGIN_DEG - 1e-6, "{d:?}");
        assert!(d.gain_margin_db >= GAIN_MARGIN_DB - 1e-6, "{d:?}");
        // A notch on the resonance lets the loop through to a higher crossover.
        let notched = LoopShape {
            torque_filters: TorqueFilters {
                lowpass_hz: None,
                notch: Some(crate::control::Notch {
                    hz: resonance,
                    width_hz: 0.5 * resonance,
                    depth: 0.0,
                }),
            },
            ..shape
        };
        let n = design_cascade(&axis, 1e-3, &notched, None).unwrap();
        assert!(
            n.velocity_bandwidth_hz > d.velocity_bandwidth_hz,
            "{n:?} vs {d:?}"
        );
        // A stiff screw, its mode far above the loop: the rigid design's crossover.
        let (axis, stiff) = compliant(1.0e10);
        let s = design_cascade(&axis, 1e-3, &stiff, None).unwrap();
        assert!(
            (s.velocity_bandwidth_hz / rigid.velocity_bandwidth_hz - 1.0).abs() < 0.05,
            "{s:?} vs {rigid:?}"
        );
    }
}
