//! The drive-side choices of a run: `[actuator]`, `[feedback]`, `[mechanics]` and
//! `[compensation.<axis>]`. Each overrides or adds to what the machine's drive file says.

use super::limits;
use super::source::{InFile, Num};
use crate::control::{ActuatorKind, AxisCompensation};
use crate::diagnostics::{check_range, FileError, LineColumn};
use crate::machine::{AmplifierMode, Compliance, Feedback, COMPLIANCE_RANGES};
use serde::Deserialize;
use std::collections::BTreeMap;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawActuator {
    model: ActuatorModel,
    /// Every drive's amplifier mode, overriding the drive file.
    amplifier_mode: Option<Spanned<AmplifierMode>>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "kebab-case")]
enum ActuatorModel {
    IdealTorque,
    DcMotor,
}

/// The `[actuator]` section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActuatorSettings {
    /// The actuator model of every drive (`model`): DC motor behind its amplifier, or ideal
    /// torque.
    pub kind: ActuatorKind,
    /// Amplifier mode of every drive, overriding the drive file; `None` = the drive's.
    pub amplifier_mode: Option<AmplifierMode>,
}

impl TryFrom<InFile<'_, &RawActuator>> for ActuatorSettings {
    type Error = FileError;

    fn try_from(InFile { raw: a, file }: InFile<'_, &RawActuator>) -> Result<Self, FileError> {
        if let (ActuatorModel::IdealTorque, Some(mode)) = (a.model, &a.amplifier_mode) {
            return Err(file.error(
                mode.span(),
                "[actuator] amplifier_mode applies to model = \"dc-motor\"; the ideal-torque actuator has no amplifier",
            ));
        }
        Ok(ActuatorSettings {
            kind: match a.model {
                ActuatorModel::IdealTorque => ActuatorKind::IdealTorque,
                ActuatorModel::DcMotor => ActuatorKind::DcMotor,
            },
            amplifier_mode: a.amplifier_mode.as_ref().map(|m| *m.get_ref()),
        })
    }
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct RawFeedback {
    /// Where every axis's loop is closed, instead of the drive file's choice.
    position: Option<Feedback>,
    #[serde(default)]
    encoder_counts_per_rev: BTreeMap<String, Spanned<i64>>,
    following_error_limit_mm: Option<Num>,
    following_error_limit_deg: Option<Num>,
}

/// The `[feedback]` section, SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct FeedbackSettings {
    /// Feedback position for every axis, overriding the drive file; `None` = the drive's.
    pub position: Option<Feedback>,
    /// Encoder resolution per axis, overriding the drive file.
    pub encoder_counts_per_rev: BTreeMap<String, (u32, Option<LineColumn>)>,
    /// Following-error fault limits: m for linear axes, rad for rotary axes.
    pub following_error_limit_linear: f64,
    /// Following-error fault limit of rotary axes (rad), from `following_error_limit_deg`.
    pub following_error_limit_rotary: f64,
}

impl TryFrom<InFile<'_, &RawFeedback>> for FeedbackSettings {
    type Error = FileError;

    fn try_from(InFile { raw, file }: InFile<'_, &RawFeedback>) -> Result<Self, FileError> {
        let mut encoder_counts_per_rev = BTreeMap::new();
        for (axis, c) in &raw.encoder_counts_per_rev {
            let n = *c.get_ref();
            if !(1..=u32::MAX as i64).contains(&n) {
                return Err(file.error(
                    c.span(),
                    format!("encoder_counts_per_rev.{axis} = {n}: expected a whole number ≥ 1"),
                ));
            }
            encoder_counts_per_rev.insert(axis.clone(), (n as u32, file.at(c.span().start)));
        }
        // Defaults trip well beyond any sane tracking error but long before a runaway.
        let following_error_limit_linear = file
            .ranged_opt(
                raw.following_error_limit_mm.as_ref(),
                "following_error_limit_mm",
                "mm",
                limits::FOLLOWING_ERROR_LIMIT_MM,
            )?
            .map_or(10e-3, |v| v * 1e-3);
        let following_error_limit_rotary = file
            .ranged_opt(
                raw.following_error_limit_deg.as_ref(),
                "following_error_limit_deg",
                "deg",
                limits::FOLLOWING_ERROR_LIMIT_DEG,
            )?
            .unwrap_or(10.0)
            .to_radians();
        Ok(FeedbackSettings {
            position: raw.position,
            encoder_counts_per_rev,
            following_error_limit_linear,
            following_error_limit_rotary,
        })
    }
}

/// Which of the machine's mechanics the run keeps (all on by default), and transmissions made
/// compliant or stiffer than the drive file says: turning one off removes it from the physics
/// and the analytic model alike.
#[derive(Debug, Clone, PartialEq)]
pub struct Mechanics {
    /// The guides' contact friction.
    pub friction: bool,
    /// The transmissions' backlash.
    pub backlash: bool,
    /// The transmissions' compliance (false: every drive train rigid).
    pub compliance: bool,
    /// `[mechanics.transmission.<axis>]`: stiffness and damping replacing the drive file's.
    pub transmission: BTreeMap<String, TransmissionEntry>,
}

impl Default for Mechanics {
    fn default() -> Self {
        Mechanics {
            friction: true,
            backlash: true,
            compliance: true,
            transmission: BTreeMap::new(),
        }
    }
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMechanics {
    friction: Option<bool>,
    backlash: Option<bool>,
    compliance: Option<bool>,
    #[serde(default)]
    transmission: BTreeMap<String, Spanned<RawTransmission>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTransmission {
    stiffness_n_per_m: Option<f64>,
    damping_n_s_per_m: Option<f64>,
    stiffness_nm_per_rad: Option<f64>,
    damping_nm_s_per_rad: Option<f64>,
}

/// One axis's transmission compliance from the scenario, SI; `rotary_units` says which unit
/// family its keys used, checked against the axis kind when the machine is known.
#[derive(Debug, Clone, PartialEq)]
pub struct TransmissionEntry {
    /// Stiffness and damping (N/m and N·s/m, or N·m/rad and N·m·s/rad on a rotary axis).
    pub compliance: Compliance,
    /// Whether the keys were the rotary ones (`stiffness_nm_per_rad`, `damping_nm_s_per_rad`).
    pub rotary_units: bool,
    /// Where the entry starts in the scenario file, for messages.
    pub at: Option<LineColumn>,
}

impl TryFrom<InFile<'_, &RawMechanics>> for Mechanics {
    type Error = FileError;

    fn try_from(InFile { raw, file }: InFile<'_, &RawMechanics>) -> Result<Self, FileError> {
        let mut transmission = BTreeMap::new();
        for (axis, entry) in &raw.transmission {
            let v = entry.get_ref();
            let fail =
                |m: String| file.error(entry.span(), format!("mechanics.transmission.{axis}: {m}"));
            let (stiffness, damping, rotary_units) = match (
                v.stiffness_n_per_m,
                v.damping_n_s_per_m,
                v.stiffness_nm_per_rad,
                v.damping_nm_s_per_rad,
            ) {
                (Some(k), c, None, None) => (k, c, false),
                (None, None, Some(k), c) => (k, c, true),
                _ => return Err(fail("expected stiffness_n_per_m (with an optional damping_n_s_per_m) on a linear axis, or stiffness_nm_per_rad (with damping_nm_s_per_rad) on a rotary one".into())),
            };
            let keys: &[&str] = if rotary_units {
                &[
                    "transmission_stiffness_nm_per_rad",
                    "transmission_damping_nm_s_per_rad",
                ]
            } else {
                &[
                    "transmission_stiffness_n_per_m",
                    "transmission_damping_n_s_per_m",
                ]
            };
            for (key, value) in keys.iter().zip([Some(stiffness), damping]) {
                let Some(value) = value else { continue };
                let &(_, unit, lo, hi) = COMPLIANCE_RANGES
                    .iter()
                    .find(|r| r.0 == *key)
                    .expect("every compliance key has a range");
                let short = key.trim_start_matches("transmission_");
                check_range(short, value, unit, lo, hi).map_err(fail)?;
            }
            transmission.insert(
                axis.clone(),
                TransmissionEntry {
                    compliance: Compliance {
                        stiffness,
                        damping: damping.unwrap_or(0.0),
                    },
                    rotary_units,
                    at: file.at(entry.span().start),
                },
            );
        }
        Ok(Mechanics {
            friction: raw.friction.unwrap_or(true),
            backlash: raw.backlash.unwrap_or(true),
            compliance: raw.compliance.unwrap_or(true),
            transmission,
        })
    }
}

/// One axis's compensation at reversals, in the units of the keys.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCompensation {
    backlash_mm: Option<f64>,
    backlash_deg: Option<f64>,
    backlash_rate_mm_s: Option<f64>,
    backlash_rate_deg_s: Option<f64>,
    friction_pulse: Option<f64>,
    friction_decay_ms: Option<f64>,
}

/// Compensation of one axis, SI; `rotary_units` says which unit family the backlash keys used
/// (`None` when none was given), checked against the axis kind when the machine is known.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensationEntry {
    /// The compensation (joint units: m or rad).
    pub compensation: AxisCompensation,
    /// Whether the backlash keys were the rotary ones (`_deg`); `None` when none was given.
    pub rotary_units: Option<bool>,
    /// Where the entry starts in the scenario file, for messages.
    pub at: Option<LineColumn>,
}

/// `[compensation.<axis>]`: the axis name with its raw entry.
pub(super) struct AxisEntry<'a> {
    pub axis: &'a str,
    pub entry: &'a Spanned<RawCompensation>,
}

impl TryFrom<InFile<'_, AxisEntry<'_>>> for CompensationEntry {
    type Error = FileError;

    fn try_from(InFile { raw, file }: InFile<'_, AxisEntry<'_>>) -> Result<Self, FileError> {
        let (axis, v) = (raw.axis, raw.entry.get_ref());
        let fail = |m: String| file.error(raw.entry.span(), format!("compensation.{axis}: {m}"));
        let (backlash, rate, rotary_units) = match (
            v.backlash_mm,
            v.backlash_deg,
            v.backlash_rate_mm_s,
            v.backlash_rate_deg_s,
        ) {
            (None, None, None, None) => (0.0, 0.0, None),
            (Some(b), None, Some(r), None) => {
                check_range("backlash_mm", b, "mm", 0.0, limits::MAX_BACKLASH_MM).map_err(fail)?;
                check_range("backlash_rate_mm_s", r, "mm/s", 1e-6, limits::SPEED_MM_S.1)
                    .map_err(fail)?;
                (b * 1e-3, r * 1e-3, Some(false))
            }
            (None, Some(b), None, Some(r)) => {
                check_range("backlash_deg", b, "deg", 0.0, limits::MAX_BACKLASH_DEG)
                    .map_err(fail)?;
                check_range("backlash_rate_deg_s", r, "deg/s", 1e-6, limits::LIMIT_VELOCITY.1)
                    .map_err(fail)?;
                (b.to_radians(), r.to_radians(), Some(true))
            }
            _ => return Err(fail("backlash compensation takes backlash_mm with backlash_rate_mm_s (linear axes) or backlash_deg with backlash_rate_deg_s (rotary axes)".into())),
        };
        let (pulse, decay) = match (v.friction_pulse, v.friction_decay_ms) {
            (None, None) => (0.0, 1.0),
            (Some(a), Some(d)) => {
                check_range("friction_pulse", a, "", -limits::MAX_GAIN, limits::MAX_GAIN)
                    .map_err(fail)?;
                check_range("friction_decay_ms", d, "ms", 1e-3, 1e5).map_err(fail)?;
                (a, d * 1e-3)
            }
            _ => return Err(fail("friction compensation takes friction_pulse (in controller output units: V or N·m) with friction_decay_ms".into())),
        };
        Ok(CompensationEntry {
            compensation: AxisCompensation {
                backlash,
                backlash_rate: rate,
                friction_pulse: pulse,
                friction_decay: decay,
            },
            rotary_units,
            at: file.at(raw.entry.span().start),
        })
    }
}
