//! The drive sidecar `<machine>.drives.toml`: motor, amplifier and transmission data per axis,
//! which URDF has no element for, and the tool point.
//!
//! Every number is checked against the range a machine-tool drive can have ([`DRIVE_RANGES`]
//! and the guide and backlash limits below); values outside are refused with the file, the
//! axis and the range, suspect ones load with a warning.

use super::{Axis, JointKind, KinematicTree, Machine};
use crate::diagnostics::{check_range, read_text, toml_error, FileError, LineColumn};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Plausible range of each drive constant (SI): from a miniature positioning stage to the
/// largest machine-tool axis, with margin. Outside it a value is a typo or a unit mistake
/// (a radius in mm, an inductance in mH), and the simulation would be meaningless.
pub const DRIVE_RANGES: &[(&str, &str, f64, f64)] = &[
    ("gear_ratio", "", 1e-3, 1e4),
    ("ratio", "", 1e-3, 1e5),
    ("pulley_radius_m", "m", 1e-4, 1.0),
    ("lead_m", "m", 1e-5, 0.5),
    ("rotor_inertia_kg_m2", "kg·m²", 1e-10, 10.0),
    ("transmission_inertia_kg_m2", "kg·m²", 0.0, 100.0),
    ("viscous_damping_nm_s_per_rad", "N·m·s/rad", 0.0, 100.0),
    ("motor.torque_constant_nm_per_a", "N·m/A", 1e-4, 100.0),
    ("motor.back_emf_v_s_per_rad", "V·s/rad", 0.0, 100.0),
    ("motor.resistance_ohm", "Ω", 1e-4, 1e3),
    ("motor.inductance_h", "H", 1e-7, 10.0),
    ("amplifier_gain", "V/V", 1e-3, 1e4),
    ("supply_voltage_v", "V", 0.1, 1e4),
    ("peak_torque_nm", "N·m", 1e-4, 1e5),
];

/// Largest friction coefficient of a guide (static or kinetic); dry steel on steel is about 0.8.
pub const MAX_FRICTION_COEFFICIENT: f64 = 2.0;
/// Above this a guide's kinetic coefficient loads with a warning (machine guides: 0.001–0.2).
pub const SUSPECT_FRICTION_COEFFICIENT: f64 = 0.5;
/// Range of the Stribeck velocity (m/s).
pub const STRIBECK_VELOCITY_RANGE_M_S: (f64, f64) = (1e-7, 1.0);
/// Range of a guide's runner spacing (m): from a miniature stage's blocks to a gantry's.
pub const RUNNER_SPACING_RANGE_M: (f64, f64) = (1e-3, 5.0);
/// Backlash above this loads with a warning (m at a linear joint, rad at a rotary one).
pub const SUSPECT_BACKLASH: f64 = 2e-3;

/// How motor rotation becomes joint motion.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Transmission {
    /// Gearbox then a belt pulley (linear joint): x = (r/N)·θ.
    Belt {
        /// Gearbox ratio N: motor turns per pulley turn.
        gear_ratio: f64,
        /// Pulley radius r (m).
        pulley_radius_m: f64,
    },
    /// Optional gearbox then a ball screw of the given lead (linear joint): z = (lead/2πN)·θ.
    Screw {
        /// Gearbox ratio N: motor turns per screw turn (1 without a gearbox).
        #[serde(default = "one")]
        gear_ratio: f64,
        /// Screw lead: travel per screw turn (m).
        lead_m: f64,
    },
    /// Gearbox on a rotary joint: q = θ/N.
    Gear {
        /// Gearbox ratio N: motor turns per joint turn.
        ratio: f64,
    },
}

fn one() -> f64 {
    1.0
}

impl Transmission {
    /// Motor radians per joint unit (rad/m for linear joints, rad/rad for rotary ones).
    pub fn motor_per_joint(&self) -> f64 {
        match *self {
            Transmission::Belt {
                gear_ratio,
                pulley_radius_m,
            } => gear_ratio / pulley_radius_m,
            Transmission::Screw { gear_ratio, lead_m } => {
                gear_ratio * std::f64::consts::TAU / lead_m
            }
            Transmission::Gear { ratio } => ratio,
        }
    }

    fn joint_kind(&self) -> JointKind {
        match self {
            Transmission::Belt { .. } | Transmission::Screw { .. } => JointKind::Prismatic,
            Transmission::Gear { .. } => JointKind::Revolute,
        }
    }

    fn values(&self) -> Vec<(&'static str, f64)> {
        match *self {
            Transmission::Belt {
                gear_ratio,
                pulley_radius_m,
            } => {
                vec![
                    ("gear_ratio", gear_ratio),
                    ("pulley_radius_m", pulley_radius_m),
                ]
            }
            Transmission::Screw { gear_ratio, lead_m } => {
                vec![("gear_ratio", gear_ratio), ("lead_m", lead_m)]
            }
            Transmission::Gear { ratio } => vec![("ratio", ratio)],
        }
    }
}

/// Armature-controlled DC motor: L·di/dt + R·i + K_b·ω = V, T = K_m·i.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DcMotor {
    /// Torque constant K_m (N·m/A).
    pub torque_constant_nm_per_a: f64,
    /// Back-EMF constant K_b (V·s/rad).
    pub back_emf_v_s_per_rad: f64,
    /// Armature resistance R (Ω).
    pub resistance_ohm: f64,
    /// Armature inductance L (H).
    pub inductance_h: f64,
}

/// Which position the servo loop is closed on. The two differ only with backlash.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Feedback {
    /// Motor encoder (semi-closed loop): the drive-side position. Backlash is then outside
    /// the loop and shows as lost motion at reversals.
    #[default]
    Motor,
    /// Linear scale on the carriage (fully closed loop).
    Carriage,
}

/// How the servo amplifier drives the armature. Both take the controller output u (V at the
/// amplifier input) and are limited by the supply voltage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AmplifierMode {
    /// Armature voltage = K_a·u: the back-EMF K_b·ω opposes it, so the motor runs at a speed
    /// roughly proportional to u (a velocity-like plant, heavily damped).
    #[default]
    Voltage,
    /// Current (torque) mode: the amplifier adds the back-EMF to its output, so the current
    /// obeys L·di/dt + R·i = K_a·u (demand K_a/R amperes per volt, the armature's own time
    /// constant L/R) for as long as K_a·u + K_b·ω stays within the supply. The plant is then
    /// a double integrator with only the motor's viscous damping.
    Current,
}

impl AmplifierMode {
    /// Armature voltage for amplifier output `ka_u` = K_a·u (V) against back-EMF
    /// `back_emf` = K_b·ω (V), clamped to the supply.
    pub fn armature_voltage(self, ka_u: f64, back_emf: f64, supply: f64) -> f64 {
        let compensation = match self {
            AmplifierMode::Voltage => 0.0,
            AmplifierMode::Current => back_emf,
        };
        (ka_u + compensation).clamp(-supply, supply)
    }

    /// The name used in drives and scenario files.
    pub fn name(self) -> &'static str {
        match self {
            AmplifierMode::Voltage => "voltage",
            AmplifierMode::Current => "current",
        }
    }
}

/// The guide a linear carriage slides on. The carriage gets a free degree of freedom along
/// the guide normal and rests on the guide under its own weight and everything it carries, so
/// the contact (not the joint) carries the load and Coulomb friction μ·N emerges from it.
///
/// With a static coefficient above the kinetic one the guide has stiction: the carriage breaks
/// away at μ_s·N and the coefficient falls to μ_k along the Stribeck curve
/// μ(v) = μ_k + (μ_s − μ_k)·exp(−(v/v_s)²) as it speeds up ([`StribeckCurve`]).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Guide {
    /// Kinetic (sliding) Coulomb coefficient μ_k of the guide contact.
    pub friction_coefficient: f64,
    /// Static coefficient μ_s ≥ μ_k; absent = μ_k (no stiction).
    #[serde(default)]
    pub static_friction_coefficient: Option<f64>,
    /// Stribeck velocity v_s (m/s): the sliding speed over which μ falls from μ_s towards
    /// μ_k. Required when μ_s > μ_k.
    #[serde(default)]
    pub stribeck_velocity_m_s: Option<f64>,
    /// Outward normal of the guide surface (the direction the carriage is lifted off), in the
    /// joint frame; must be perpendicular to the joint axis.
    #[serde(default = "up")]
    pub normal: [f64; 3],
    /// Distance (m) between a front and a back runner along the travel; with it the carriage
    /// gets a pitch degree of freedom as well, so the load shifts between the runners when
    /// the carriage accelerates under a high centre of gravity (weight transfer). Absent: one
    /// runner under the joint origin and no pitch.
    #[serde(default)]
    pub runner_spacing_m: Option<f64>,
}

impl Guide {
    /// A guide with plain Coulomb friction (static = kinetic) and an upward normal.
    pub fn coulomb(friction_coefficient: f64) -> Guide {
        Guide {
            friction_coefficient,
            static_friction_coefficient: None,
            stribeck_velocity_m_s: None,
            normal: up(),
            runner_spacing_m: None,
        }
    }

    /// The friction coefficient as a function of sliding speed.
    pub fn coefficient(&self) -> StribeckCurve {
        let kinetic = self.friction_coefficient;
        StribeckCurve {
            kinetic,
            breakaway: self.static_friction_coefficient.unwrap_or(kinetic),
            stribeck_velocity: self.stribeck_velocity_m_s.unwrap_or(0.0),
        }
    }

    fn validate(&self) -> Result<(), String> {
        let mu = self.friction_coefficient;
        check_range(
            "guide.friction_coefficient",
            mu,
            "",
            0.0,
            MAX_FRICTION_COEFFICIENT,
        )?;
        if let Some(mu_s) = self.static_friction_coefficient {
            if !(mu_s.is_finite() && mu_s >= mu && mu_s <= MAX_FRICTION_COEFFICIENT) {
                return Err(format!(
                    "guide.static_friction_coefficient = {mu_s:?}: expected a value from \
                     the kinetic friction_coefficient ({mu:?}) to {MAX_FRICTION_COEFFICIENT:?}"
                ));
            }
        }
        let curve = self.coefficient();
        match self.stribeck_velocity_m_s {
            Some(v) => {
                let (lo, hi) = STRIBECK_VELOCITY_RANGE_M_S;
                check_range("guide.stribeck_velocity_m_s", v, "m/s", lo, hi)?;
            }
            None if curve.has_stiction() => {
                return Err(format!(
                    "guide.static_friction_coefficient = {:?} exceeds the kinetic {:?}: expected \
                     stribeck_velocity_m_s, the speed over which the coefficient falls",
                    curve.breakaway, curve.kinetic
                ));
            }
            None => {}
        }
        if let Some(l) = self.runner_spacing_m {
            let (lo, hi) = RUNNER_SPACING_RANGE_M;
            check_range("guide.runner_spacing_m", l, "m", lo, hi)?;
        }
        let n = self.normal;
        if !(n.iter().all(|v| v.is_finite()) && n.iter().any(|v| *v != 0.0)) {
            return Err(format!(
                "guide.normal = {n:?}: expected a finite, non-zero vector"
            ));
        }
        Ok(())
    }
}

/// Coulomb friction with a Stribeck drop: `breakaway` holds a body at rest, and a sliding
/// body feels kinetic + (breakaway − kinetic)·exp(−(v/v_s)²) against its motion. The same
/// curve serves as coefficients (a [`Guide`]) or as forces (scaled by the normal load).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StribeckCurve {
    /// Level while sliding fast (kinetic force or coefficient); the floor of the curve.
    pub kinetic: f64,
    /// Largest force (or coefficient) that holds a body at rest; ≥ `kinetic`.
    pub breakaway: f64,
    /// Speed scale of the drop (m/s or rad/s); irrelevant when breakaway = kinetic.
    pub stribeck_velocity: f64,
}

impl StribeckCurve {
    /// Plain Coulomb friction: static = kinetic = `level`.
    pub fn coulomb(level: f64) -> StribeckCurve {
        StribeckCurve {
            kinetic: level,
            breakaway: level,
            stribeck_velocity: 0.0,
        }
    }

    /// Magnitude while sliding at `speed` (either sign).
    pub fn sliding(&self, speed: f64) -> f64 {
        let excess = self.breakaway - self.kinetic;
        if excess == 0.0 {
            return self.kinetic;
        }
        let ratio = speed / self.stribeck_velocity;
        self.kinetic + excess * (-ratio * ratio).exp()
    }

    /// Whether the breakaway level is above the kinetic one (the curve has a Stribeck drop).
    pub fn has_stiction(&self) -> bool {
        self.breakaway > self.kinetic
    }

    /// The same curve with both levels multiplied by `factor` (coefficients to forces).
    pub fn scaled(&self, factor: f64) -> StribeckCurve {
        StribeckCurve {
            kinetic: self.kinetic * factor,
            breakaway: self.breakaway * factor,
            stribeck_velocity: self.stribeck_velocity,
        }
    }
}

fn up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// One axis's drive, all on the motor side unless the name says otherwise.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Drive {
    /// URDF joint this drive moves.
    pub joint: String,
    /// How motor rotation becomes joint motion.
    pub transmission: Transmission,
    /// Motor rotor inertia (kg·m²).
    pub rotor_inertia_kg_m2: f64,
    /// Gearbox, pulley or screw inertia on the motor side (kg·m²).
    #[serde(default)]
    pub transmission_inertia_kg_m2: f64,
    /// Motor-side viscous damping (N·m·s/rad).
    pub viscous_damping_nm_s_per_rad: f64,
    /// The motor's electrical and torque constants.
    pub motor: DcMotor,
    /// Amplifier gain K_a (V per volt of controller output), see [`AmplifierMode`].
    pub amplifier_gain: f64,
    /// Voltage or current (torque) mode; voltage by default.
    #[serde(default)]
    pub amplifier_mode: AmplifierMode,
    /// Supply voltage (V): the largest armature voltage the amplifier can apply.
    pub supply_voltage_v: f64,
    /// Torque limit of the ideal torque actuator (N·m at the motor).
    pub peak_torque_nm: f64,
    /// Lost motion of the transmission at the joint (m or rad): the physics model puts a
    /// dead band of this width between the drive side and the carriage.
    #[serde(default)]
    pub backlash: f64,
    /// Equivalent stiffness of the transmission at the joint, between the drive side and the
    /// carriage (linear axes, N/m): screw, nut and bearings, or belt, in series with the
    /// coupling and gearbox reflected through the ratio. Absent: a rigid transmission.
    #[serde(default)]
    pub transmission_stiffness_n_per_m: Option<f64>,
    /// Viscous damping across that stiffness (N·s/m); needs the stiffness.
    #[serde(default)]
    pub transmission_damping_n_s_per_m: Option<f64>,
    /// Rotary axes: the transmission's torsional stiffness at the joint (N·m/rad).
    #[serde(default)]
    pub transmission_stiffness_nm_per_rad: Option<f64>,
    /// Rotary axes: damping across it (N·m·s/rad).
    #[serde(default)]
    pub transmission_damping_nm_s_per_rad: Option<f64>,
    /// Guide contact with friction (linear axes); absent = a frictionless rigid joint.
    #[serde(default)]
    pub guide: Option<Guide>,
    /// Where the position feedback is measured.
    #[serde(default)]
    pub feedback: Feedback,
    /// Motor encoder resolution, counts per motor revolution; absent = ideal feedback.
    #[serde(default)]
    pub encoder_counts_per_rev: Option<u32>,
    /// +1: the axis letter's positive direction is where the joint moves the tool relative to
    /// the workpiece as its coordinate grows; -1 reverses it (a negative SCALE in LinuxCNC).
    #[serde(default = "positive")]
    pub sign: i8,
    /// Joint coordinate at machine zero (m or rad), where the axis is homed.
    #[serde(default)]
    pub home: f64,
}

fn positive() -> i8 {
    1
}

impl Drive {
    /// Motor radians per joint unit.
    pub fn ratio(&self) -> f64 {
        self.transmission.motor_per_joint()
    }

    /// Armature voltage the amplifier applies for controller output `u` (V) at motor speed
    /// `omega` (rad/s), clamped to the supply.
    pub fn armature_voltage(&self, u: f64, omega: f64) -> f64 {
        self.amplifier_mode.armature_voltage(
            self.amplifier_gain * u,
            self.motor.back_emf_v_s_per_rad * omega,
            self.supply_voltage_v,
        )
    }

    /// The back-EMF constant the controller-to-current path sees (V·s/rad): zero in current
    /// mode, where the amplifier cancels it.
    pub fn effective_back_emf(&self) -> f64 {
        match self.amplifier_mode {
            AmplifierMode::Voltage => self.motor.back_emf_v_s_per_rad,
            AmplifierMode::Current => 0.0,
        }
    }

    /// Motor-side inertia of rotor and transmission (kg·m²).
    pub fn motor_side_inertia(&self) -> f64 {
        self.rotor_inertia_kg_m2 + self.transmission_inertia_kg_m2
    }

    /// Motor-side inertia seen at the joint (kg or kg·m²): J·k².
    pub fn reflected_inertia(&self) -> f64 {
        self.motor_side_inertia() * self.ratio().powi(2)
    }

    /// Amplifier input (V) that holds a steady joint velocity of one unit (1 m/s, or 1 rad/s)
    /// against the motor's viscous damping and, in voltage mode, its back-EMF:
    /// (K_b'·k + R·C·k/K_m)/K_a, with K_b' zero in current mode. Friction and the load's own
    /// damping are not in it.
    pub fn steady_volts_per_velocity(&self) -> f64 {
        let k = self.ratio();
        let damping_current =
            self.viscous_damping_nm_s_per_rad * k / self.motor.torque_constant_nm_per_a;
        (self.effective_back_emf() * k + self.motor.resistance_ohm * damping_current)
            / self.amplifier_gain
    }

    /// Motor-side viscous damping seen at the joint (N·s/m or N·m·s/rad): C·k².
    pub fn reflected_damping(&self) -> f64 {
        self.viscous_damping_nm_s_per_rad * self.ratio().powi(2)
    }

    /// The transmission's compliance at the joint, if it has one (`None`: rigid).
    pub fn compliance(&self) -> Option<Compliance> {
        let (stiffness, damping) = match self.transmission.joint_kind() {
            JointKind::Revolute => (
                self.transmission_stiffness_nm_per_rad,
                self.transmission_damping_nm_s_per_rad,
            ),
            _ => (
                self.transmission_stiffness_n_per_m,
                self.transmission_damping_n_s_per_m,
            ),
        };
        Some(Compliance {
            stiffness: stiffness?,
            damping: damping.unwrap_or(0.0),
        })
    }

    /// Sets (or with `None` removes) the transmission's compliance, in the keys of this
    /// drive's joint kind.
    pub fn set_compliance(&mut self, compliance: Option<Compliance>) {
        let stiffness = compliance.map(|c| c.stiffness);
        let damping = compliance.map(|c| c.damping);
        match self.transmission.joint_kind() {
            JointKind::Revolute => {
                self.transmission_stiffness_nm_per_rad = stiffness;
                self.transmission_damping_nm_s_per_rad = damping;
            }
            _ => {
                self.transmission_stiffness_n_per_m = stiffness;
                self.transmission_damping_n_s_per_m = damping;
            }
        }
    }

    /// Joint units per encoder count, if the encoder is modelled.
    pub fn encoder_resolution(&self) -> Option<f64> {
        self.encoder_counts_per_rev
            .map(|c| std::f64::consts::TAU / (c as f64 * self.ratio()))
    }

    fn check(&self) -> Result<(), String> {
        let mut named: Vec<(&str, f64)> = self.transmission.values();
        named.extend([
            ("rotor_inertia_kg_m2", self.rotor_inertia_kg_m2),
            (
                "transmission_inertia_kg_m2",
                self.transmission_inertia_kg_m2,
            ),
            (
                "viscous_damping_nm_s_per_rad",
                self.viscous_damping_nm_s_per_rad,
            ),
            (
                "motor.torque_constant_nm_per_a",
                self.motor.torque_constant_nm_per_a,
            ),
            (
                "motor.back_emf_v_s_per_rad",
                self.motor.back_emf_v_s_per_rad,
            ),
            ("motor.resistance_ohm", self.motor.resistance_ohm),
            ("motor.inductance_h", self.motor.inductance_h),
            ("amplifier_gain", self.amplifier_gain),
            ("supply_voltage_v", self.supply_voltage_v),
            ("peak_torque_nm", self.peak_torque_nm),
        ]);
        for (name, v) in named {
            let &(_, unit, lo, hi) = DRIVE_RANGES
                .iter()
                .find(|r| r.0 == name)
                .expect("every drive constant has a range");
            check_range(name, v, unit, lo, hi)?;
        }
        if !(self.backlash.is_finite() && self.backlash >= 0.0) {
            return Err(format!(
                "backlash = {:?}: expected a finite value ≥ 0",
                self.backlash
            ));
        }
        self.check_compliance()?;
        if let Some(guide) = &self.guide {
            guide.validate()?;
            if self.transmission.joint_kind() != JointKind::Prismatic {
                return Err("a guide (friction contact) needs a linear axis".into());
            }
        }
        if !matches!(self.sign, 1 | -1) {
            return Err(format!("sign = {}: expected 1 or -1", self.sign));
        }
        if !self.home.is_finite() {
            return Err(format!(
                "home = {:?}: expected a finite joint coordinate",
                self.home
            ));
        }
        if self.encoder_counts_per_rev == Some(0) {
            return Err(
                "encoder_counts_per_rev = 0: expected at least 1 count per revolution".into(),
            );
        }
        Ok(())
    }
}

impl Drive {
    /// The compliance keys match the transmission's joint kind, and their values their ranges.
    fn check_compliance(&self) -> Result<(), String> {
        let linear = [
            (
                "transmission_stiffness_n_per_m",
                self.transmission_stiffness_n_per_m,
            ),
            (
                "transmission_damping_n_s_per_m",
                self.transmission_damping_n_s_per_m,
            ),
        ];
        let rotary = [
            (
                "transmission_stiffness_nm_per_rad",
                self.transmission_stiffness_nm_per_rad,
            ),
            (
                "transmission_damping_nm_s_per_rad",
                self.transmission_damping_nm_s_per_rad,
            ),
        ];
        let (own, other, kind) = match self.transmission.joint_kind() {
            JointKind::Revolute => (rotary, linear, "a rotary (gear) axis"),
            _ => (linear, rotary, "a linear (belt or screw) axis"),
        };
        if let Some((name, _)) = other.iter().find(|(_, v)| v.is_some()) {
            return Err(format!(
                "{name} does not fit {kind}: expected {} and {}",
                own[0].0, own[1].0
            ));
        }
        match own {
            [(_, None), (damping, Some(_))] => Err(format!(
                "{damping} without {}: damping acts across the transmission's stiffness",
                own[0].0
            )),
            [(stiffness, Some(k)), (damping, c)] => {
                let &(_, unit, lo, hi) = COMPLIANCE_RANGES
                    .iter()
                    .find(|r| r.0 == stiffness)
                    .expect("every compliance key has a range");
                check_range(stiffness, k, unit, lo, hi)?;
                if let Some(c) = c {
                    let &(_, unit, lo, hi) = COMPLIANCE_RANGES
                        .iter()
                        .find(|r| r.0 == damping)
                        .expect("every compliance key has a range");
                    check_range(damping, c, unit, lo, hi)?;
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }
}

/// A transmission's compliance at the joint: the spring and damper between the drive side
/// (rotor, coupling, gearbox, pulley or screw, reflected through the ratio) and the carriage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Compliance {
    /// N/m at a linear joint, N·m/rad at a rotary one.
    pub stiffness: f64,
    /// N·s/m or N·m·s/rad.
    pub damping: f64,
}

/// Ranges of the compliance keys: from a long rubber belt to a preloaded large ball screw (a
/// feed drive's axial stiffness is typically 10–1000 N/µm), and from the softest to the
/// stiffest gearbox and direct drive.
pub const COMPLIANCE_RANGES: &[(&str, &str, f64, f64)] = &[
    ("transmission_stiffness_n_per_m", "N/m", 1e2, 1e11),
    ("transmission_damping_n_s_per_m", "N·s/m", 0.0, 1e8),
    ("transmission_stiffness_nm_per_rad", "N·m/rad", 1e-1, 1e10),
    ("transmission_damping_nm_s_per_rad", "N·m·s/rad", 0.0, 1e7),
];

/// The tool point: a point fixed in one link.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tool {
    /// The URDF link the tool point is fixed in.
    pub link: String,
    /// Tool point in the tool link's frame (m).
    #[serde(default)]
    pub offset_m: [f64; 3],
    /// The link is `machine init`'s guess, not yet checked by the user (said at every load).
    #[serde(default)]
    pub guessed: bool,
}

/// The link that carries the workpiece (tool-tip figures are given in its frame).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Workpiece {
    /// The URDF link that carries the workpiece.
    pub link: String,
    /// The link is `machine init`'s guess, not yet checked by the user (said at every load).
    #[serde(default)]
    pub guessed: bool,
}

/// What happens to a moving URDF joint that no axis drives (`[joints.<name>]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum JointMode {
    /// Held at `position`: the joint becomes a fixed one.
    Locked,
    /// Free, with the URDF's own `<dynamics damping friction>` (physics only).
    Passive,
}

/// A `[joints.<name>]` entry.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSetting {
    /// Locked or passive.
    pub mode: JointMode,
    /// Where a locked joint is held (m or rad); absent: 0, or the nearer limit if 0 is
    /// outside the travel.
    #[serde(default)]
    pub position: Option<f64>,
}

/// `inertia_from_geometry`: masses and inertias of links the URDF leaves massless, from their
/// collision (else visual) geometry at a uniform density, as MuJoCo's `inertiafromgeom` does.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InertiaFromGeometry {
    /// Uniform density of the geometry (kg/m³).
    pub density_kg_m3: f64,
}

/// Range of `inertia_from_geometry.density_kg_m3`: from foam to tungsten, with margin.
pub const DENSITY_RANGE_KG_M3: (f64, f64) = (10.0, 25_000.0);

/// The letters an axis may have (ISO 841): X, Y, Z linear and A, B, C turning about them,
/// which programs move; then the secondary motions U, V, W (linear, parallel to X, Y, Z) and
/// D, E (a second rotation parallel to one already named), which programs hold at home.
pub const AXIS_LETTERS: [&str; 11] = ["x", "y", "z", "a", "b", "c", "u", "v", "w", "d", "e"];

/// Contents of a drive sidecar file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DrivesFile {
    /// The URDF `<robot name>` this file belongs to, or the URDF's file name.
    pub machine: String,
    /// The tool point.
    pub tool: Tool,
    /// Absent: the workpiece sits on the machine base.
    #[serde(default)]
    pub workpiece: Option<Workpiece>,
    /// Drives keyed by the program letter of the axis.
    pub axes: BTreeMap<String, toml::Spanned<Drive>>,
    /// Moving joints no axis drives, keyed by URDF joint name.
    #[serde(default)]
    pub joints: BTreeMap<String, toml::Spanned<JointSetting>>,
    /// Masses and inertias for links the URDF leaves massless; absent: such links are
    /// refused.
    #[serde(default)]
    pub inertia_from_geometry: Option<InertiaFromGeometry>,
    #[serde(skip)]
    text: String,
}

impl DrivesFile {
    /// The sidecar naming rule, stated once: `models/foo.urdf` → `models/foo.drives.toml`, next
    /// to the URDF.
    pub fn path_for(urdf: &Path) -> PathBuf {
        urdf.with_extension("drives.toml")
    }

    /// Reads the drives file at `path`.
    pub fn load(path: &Path) -> Result<DrivesFile, FileError> {
        let text = read_text(path, "drive data (the .drives.toml next to the URDF)")?;
        Self::parse(path, &text)
    }

    /// Reads the contents of a drives file (`path` names it in errors).
    pub fn parse(path: &Path, text: &str) -> Result<DrivesFile, FileError> {
        let mut file: DrivesFile = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        file.text = text.to_string();
        Ok(file)
    }

    /// Checks the drives against the URDF and builds the machine: joints no axis drives are
    /// locked, passive or follow their `<mimic>` leader (`machine::joints`), missing masses are
    /// computed or refused (`machine::inertia`), then every axis is checked against its joint.
    pub fn attach(self, tree: KinematicTree, path: &Path) -> Result<Machine, FileError> {
        let text = &self.text;
        let at = |key: &str| LineColumn::of_first(text, key);
        let urdf_file = tree
            .path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        if self.machine != tree.name && self.machine != urdf_file {
            return Err(FileError::new(
                path,
                at("machine"),
                format!(
                    "machine = {:?}: expected the URDF's robot name {:?} or its file name {:?}",
                    self.machine, tree.name, urdf_file
                ),
            ));
        }
        let link_named = |name: &str, key: &str, what: &str| {
            tree.links
                .iter()
                .position(|l| l.name == name)
                .ok_or_else(|| {
                    FileError::new(
                        path,
                        at(key),
                        format!(
                            "{what} link '{name}' is not a link of the URDF (its links: {})",
                            list(tree.links.iter().map(|l| l.name.as_str()))
                        ),
                    )
                })
        };
        link_named(&self.tool.link, "[tool]", "tool")?;
        if let Some(w) = &self.workpiece {
            link_named(&w.link, "[workpiece]", "workpiece")?;
        }
        if !self
            .tool
            .offset_m
            .iter()
            .all(|v| v.is_finite() && v.abs() <= super::MAX_MACHINE_SIZE_M)
        {
            return Err(FileError::new(
                path,
                at("offset_m"),
                format!(
                    "tool offset_m = {:?}: expected finite offsets within ±{:?} m",
                    self.tool.offset_m,
                    super::MAX_MACHINE_SIZE_M
                ),
            ));
        }
        let place_of = |span: std::ops::Range<usize>| Some(LineColumn::of_offset(text, span.start));
        for (name, spanned) in &self.axes {
            if !AXIS_LETTERS.contains(&name.as_str()) {
                return Err(FileError::new(
                    path,
                    place_of(spanned.span()),
                    format!(
                        "[axes.{name}]: '{name}' is not an axis letter (expected one of {})",
                        AXIS_LETTERS.join(", ")
                    ),
                ));
            }
        }
        let driven: Vec<(&str, Option<LineColumn>)> = self
            .axes
            .values()
            .map(|d| (d.get_ref().joint.as_str(), place_of(d.span())))
            .collect();
        let settings: Vec<(&str, JointSetting, Option<LineColumn>)> = self
            .joints
            .iter()
            .map(|(name, s)| (name.as_str(), *s.get_ref(), place_of(s.span())))
            .collect();
        let super::joints::Resolved {
            mut tree,
            undriven,
            warnings: joint_warnings,
        } = super::joints::resolve(tree, &driven, &settings, path)?;
        let mut warnings = std::mem::take(&mut tree.warnings);
        warnings.extend(joint_warnings);
        let inertia = match self.inertia_from_geometry {
            Some(g) => {
                let (lo, hi) = DENSITY_RANGE_KG_M3;
                check_range(
                    "inertia_from_geometry.density_kg_m3",
                    g.density_kg_m3,
                    "kg/m³",
                    lo,
                    hi,
                )
                .map_err(|m| FileError::new(path, at("inertia_from_geometry"), m))?;
                Some(g.density_kg_m3)
            }
            None => None,
        };
        let computed = super::inertia::complete(&mut tree, inertia, path)?;
        // What weighing the geometry found (open meshes weighed by their hull).
        warnings.append(&mut tree.warnings);

        let tool_link = tree
            .links
            .iter()
            .position(|l| l.name == self.tool.link)
            .expect("checked above");
        let workpiece_link = match &self.workpiece {
            None => tree.root,
            Some(w) => tree
                .links
                .iter()
                .position(|l| l.name == w.link)
                .expect("checked above"),
        };
        let mut axes = Vec::new();
        for (name, spanned) in &self.axes {
            let place = place_of(spanned.span());
            let drive = spanned.get_ref();
            let fail = |m: String| FileError::new(path, place, format!("axis '{name}': {m}"));
            drive.check().map_err(&fail)?;
            let joint = tree
                .joints
                .iter()
                .position(|j| j.name == drive.joint)
                .expect("resolve checked every driven joint");
            let kind = tree.joints[joint].kind;
            if kind != drive.transmission.joint_kind() {
                return Err(fail(format!(
                    "a {:?} transmission cannot drive the {kind:?} joint '{}'",
                    drive.transmission, drive.joint
                )));
            }
            if let Some(guide) = &drive.guide {
                let normal = nalgebra::Vector3::from(guide.normal).normalize();
                if normal.dot(&tree.joints[joint].axis).abs() > 1e-9 {
                    return Err(fail(format!(
                        "guide.normal = {:?} is not perpendicular to the axis of joint '{}'",
                        guide.normal, drive.joint
                    )));
                }
            }
            if axes.iter().any(|a: &Axis| a.joint == joint) {
                return Err(fail(format!("joint '{}' is driven twice", drive.joint)));
            }
            // The URDF's `<dynamics friction>` acts at the joint, between the carriage and what
            // carries it. Behind backlash or a compliant transmission the multibody has no such
            // joint (the carriage hangs on the drive side), so it is refused there by name.
            let urdf_joint = &tree.joints[joint];
            if urdf_joint.friction > 0.0 && (drive.backlash > 0.0 || drive.compliance().is_some()) {
                return Err(FileError::new(
                    &tree.path,
                    urdf_joint.place,
                    format!(
                        "joint '{}': <dynamics friction=\"{}\"> on axis {} with backlash or a compliant transmission: there the friction is the guide's (guide = {{ friction_coefficient = … }} in [axes.{name}] of {}); set the URDF's friction to 0",
                        urdf_joint.name,
                        urdf_joint.friction,
                        name.to_uppercase(),
                        path.display()
                    ),
                ));
            }
            // The dead band must fit in the travel, or the carriage never engages.
            let limits = tree.joints[joint].limits;
            let travel = match (kind, limits) {
                (_, Some([lo, hi])) => hi - lo,
                (JointKind::Revolute, None) => std::f64::consts::TAU,
                _ => f64::INFINITY,
            };
            if drive.backlash >= travel {
                return Err(fail(format!(
                    "backlash = {:?} is not smaller than the travel {travel:?} of joint '{}': the carriage would never engage",
                    drive.backlash, drive.joint
                )));
            }
            if let Some([lo, hi]) = limits {
                if !(lo..=hi).contains(&drive.home) {
                    return Err(fail(format!(
                        "home = {:?} is outside the travel [{lo:?}, {hi:?}] of joint '{}'",
                        drive.home, drive.joint
                    )));
                }
            }
            if drive.backlash > SUSPECT_BACKLASH {
                warnings.push(fail(format!(
                    "backlash = {:?} is more than {SUSPECT_BACKLASH:?} (2 mm or 0.11°): a worn machine, or a unit mistake?",
                    drive.backlash
                )));
            }
            if let Some(g) = &drive.guide {
                if g.friction_coefficient > SUSPECT_FRICTION_COEFFICIENT {
                    warnings.push(fail(format!(
                        "guide.friction_coefficient = {:?} is more than {SUSPECT_FRICTION_COEFFICIENT:?}: machine guides slide at 0.001–0.2",
                        g.friction_coefficient
                    )));
                }
            }
            let rotary_letter = ["a", "b", "c", "d", "e"].contains(&name.as_str());
            if rotary_letter != (kind == JointKind::Revolute) {
                return Err(fail(format!(
                    "joint '{}' is {}: the letters x, y, z (and u, v, w) name linear axes, a, b, c (and d, e) rotary ones",
                    drive.joint,
                    if kind == JointKind::Revolute {
                        "revolute"
                    } else {
                        "linear"
                    }
                )));
            }
            axes.push(Axis {
                name: name.clone(),
                joint,
                drive: drive.clone(),
            });
        }
        // Axes in chain order (parents first), the order the physics model uses.
        axes.sort_by_key(|a| a.joint);
        let guesses = [
            self.tool.guessed.then_some(("tool", &self.tool.link)),
            (self.workpiece.as_ref())
                .filter(|w| w.guessed)
                .map(|w| ("workpiece", &w.link)),
        ];
        for (table, link) in guesses.into_iter().flatten() {
            warnings.push(FileError::new(
                path,
                at(&format!("[{table}]")),
                format!(
                    "[{table}] link = '{link}' is `machine init`'s guess (guessed = true): check it in `cncsim machine check`, then delete the guessed line"
                ),
            ));
        }
        Ok(Machine {
            name: tree.name,
            urdf_path: tree.path,
            links: tree.links,
            joints: tree.joints,
            root: tree.root,
            axes,
            undriven,
            masses_from_geometry: computed,
            tool: self.tool,
            tool_link,
            workpiece_link,
            warnings,
        })
    }
}

/// Names for a message, comma-separated, at most 24 of them.
pub(super) fn list<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let names: Vec<&str> = names.collect();
    let shown: Vec<String> = names.iter().take(24).map(|n| format!("'{n}'")).collect();
    let more = names.len().saturating_sub(24);
    if more > 0 {
        format!("{} and {more} more", shown.join(", "))
    } else {
        shown.join(", ")
    }
}
