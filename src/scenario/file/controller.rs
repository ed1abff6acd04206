//! `[controller]`: which controller runs, and the settings of every controller type given.
//!
//! The table may carry the settings of several types side by side (so `ab --a
//! controller.type=pid --b controller.type=cascade` compares them on one file); `type` chooses,
//! and whatever is given is checked either way.

use super::limits;
use super::source::{InFile, Num, Source};
use crate::control::{CascadeAxis, Notch, PidForm, PidSettings, TorqueFilters};
use crate::diagnostics::{check_range, FileError, LineColumn};
use serde::Deserialize;
use std::collections::BTreeMap;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawController {
    #[serde(rename = "type")]
    kind: ControllerType,
    #[serde(default)]
    form: RawPidForm,
    /// PID settings per axis (`type = "pid"`).
    axes: Option<Spanned<BTreeMap<String, Spanned<RawGains>>>>,
    /// Cascade loop settings per axis (`type = "cascade"`).
    cascade: Option<Spanned<BTreeMap<String, Spanned<RawCascade>>>>,
    /// Cascade: cut-off of the velocity estimate's low-pass (Hz; 0 = none).
    velocity_filter_hz: Option<Num>,
    /// Inverse dynamics: closed-loop natural frequency (Hz) and damping ratio of every axis.
    natural_frequency_hz: Option<Num>,
    damping_ratio: Option<Num>,
    /// Inverse dynamics: scale on every link mass and inertia of the controller's model (1 =
    /// the true machine), to study robustness to model error.
    model_mass_scale: Option<Num>,
    /// Inverse dynamics: where the error dynamics are imposed, joint space or at the tool tip.
    #[serde(default)]
    space: ControlSpace,
    /// Task space: damping λ of the least-squares inverse of the task Jacobian near its
    /// singularity (units of its singular values).
    task_damping: Option<Num>,
    /// FMU: the co-simulation FMU file, relative to the scenario (`type = "fmu"`).
    fmu: Option<Spanned<String>>,
    /// FMU: start values of its parameters, by variable name.
    parameters: Option<Spanned<BTreeMap<String, Spanned<f64>>>>,
    /// FMU: cncsim's signal name → the FMU's variable name, where they differ.
    variables: Option<Spanned<BTreeMap<String, Spanned<String>>>>,
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "kebab-case")]
enum RawPidForm {
    #[default]
    Positional,
    Incremental,
}

/// One axis's PID, LinuxCNC's terms; joint units (m or rad), output in V or N·m.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGains {
    kp: f64,
    #[serde(default)]
    ki: f64,
    #[serde(default)]
    kd: f64,
    #[serde(default)]
    ff0: f64,
    #[serde(default)]
    ff1: f64,
    #[serde(default)]
    ff2: f64,
    #[serde(default)]
    bias: f64,
    #[serde(default)]
    deadband: f64,
    max_error: Option<f64>,
    max_error_i: Option<f64>,
    max_error_d: Option<f64>,
    /// |output| limit (N·m or V; LinuxCNC's maxoutput); default: none beyond the actuator's
    /// own saturation.
    output_limit: Option<f64>,
}

/// One axis's cascade, joint units (m or rad): Kpp 1/s, Kip 1/s², Kpv and Kiv output per
/// m/s and per m, the velocity limit in m/s.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCascade {
    position_kp: f64,
    #[serde(default)]
    position_ki: f64,
    velocity_kp: f64,
    #[serde(default)]
    velocity_ki: f64,
    #[serde(default)]
    velocity_ff: f64,
    #[serde(default)]
    acceleration_ff: f64,
    velocity_limit: Option<f64>,
    output_limit: Option<f64>,
    /// Second-order low-pass on the command (Hz).
    torque_lowpass_hz: Option<f64>,
    /// Notch on the command: centre (Hz), −3 dB width (Hz), gain at the centre.
    notch_hz: Option<f64>,
    notch_width_hz: Option<f64>,
    notch_depth: Option<f64>,
}

/// Default least-squares damping of the task-space controller: about the smallest singular
/// value of the mill's task Jacobian a few degrees from A = 0.
pub const DEFAULT_TASK_DAMPING: f64 = 0.05;

/// Which controller runs.
#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum ControllerType {
    /// PID per axis with LinuxCNC's feed-forward terms.
    Pid,
    /// Position loop over velocity loop per axis, with velocity and acceleration feed-forward.
    Cascade,
    /// Computed torque from the machine's rigid-body model.
    InverseDynamics,
    /// A co-simulation FMU (FMI 3.0 or 2.0), stepped once per servo period.
    Fmu,
}

impl ControllerType {
    /// The type as the scenario's `type` key spells it (`"pid"`, `"inverse-dynamics"`, …).
    pub fn name(self) -> &'static str {
        match self {
            ControllerType::Pid => "pid",
            ControllerType::Cascade => "cascade",
            ControllerType::InverseDynamics => "inverse-dynamics",
            ControllerType::Fmu => "fmu",
        }
    }
}

/// Where the inverse-dynamics controller imposes ë + K_D·ė + K_P·e = 0.
#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[serde(rename_all = "kebab-case")]
pub enum ControlSpace {
    /// On every joint (machine axis).
    #[default]
    Joint,
    /// On the tool tip and tool axis in workpiece coordinates (resolved acceleration).
    Task,
}

/// PID settings of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisGains {
    /// Every PID term of the axis, checked.
    pub settings: PidSettings,
    /// Where the axis's entry is in the file.
    pub at: Option<LineColumn>,
}

impl AxisGains {
    /// The axis's Kp, Ki and Kd.
    pub fn gains(&self) -> crate::control::PidGains {
        self.settings.gains()
    }

    /// The axis's |output| limit (N·m or V; infinite for none).
    pub fn output_limit(&self) -> f64 {
        self.settings.output_limit
    }
}

/// Cascade settings of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisCascade {
    /// The axis's position and velocity loops, feed-forward, limits and command filters,
    /// checked.
    pub settings: CascadeAxis,
    /// Where the axis's entry is in the file.
    pub at: Option<LineColumn>,
}

/// The PID controller's settings: its form and each axis's terms.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PidTable {
    /// Positional or incremental (the `form` key; positional by default).
    pub form: PidForm,
    /// Each axis's terms, by axis name.
    pub axes: BTreeMap<String, AxisGains>,
    /// Where the `axes` table is.
    pub at: Option<LineColumn>,
}

/// The cascade controller's settings: each axis's loops and the velocity estimate's filter.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CascadeTable {
    /// Each axis's loops, by axis name.
    pub axes: BTreeMap<String, AxisCascade>,
    /// Cut-off of the velocity estimate (Hz; 0 = unfiltered).
    pub velocity_filter_hz: f64,
    /// Where the `cascade` table is.
    pub at: Option<LineColumn>,
}

/// The computed-torque controller's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseDynamicsSettings {
    /// Closed-loop natural frequency (rad/s).
    pub omega_n: f64,
    /// Closed-loop damping ratio (1 by default).
    pub damping_ratio: f64,
    /// Scale on every link mass and inertia of the controller's model (1 = the true machine),
    /// to study robustness to model error.
    pub model_mass_scale: f64,
    /// Where the error dynamics are imposed: joint space or at the tool tip.
    pub space: ControlSpace,
    /// Task space: the least-squares damping λ (0 in joint space).
    pub task_damping: f64,
}

/// A controller FMU as the scenario asks for it (loaded and checked against the machine when
/// the scenario is assembled).
#[derive(Debug, Clone, PartialEq)]
pub struct FmuSettings {
    /// The FMU file (resolved against the scenario's folder), its parameters and the variable
    /// names that differ from cncsim's.
    pub request: crate::fmi::FmuRequest,
    /// Where `fmu = …` is written.
    pub at: Option<LineColumn>,
}

/// The `[controller]` section: the type that runs and the settings of every type given.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerSettings {
    /// The type that runs (the `type` key).
    pub kind: ControllerType,
    /// The PID settings (empty when no `axes` table is given).
    pub pid: PidTable,
    /// The cascade settings (empty when no `cascade` table is given).
    pub cascade: CascadeTable,
    /// Given with natural_frequency_hz.
    pub inverse_dynamics: Option<InverseDynamicsSettings>,
    /// Given with `fmu = "PATH"`.
    pub fmu: Option<FmuSettings>,
    /// Where the `[controller]` table is.
    pub at: Option<LineColumn>,
}

impl TryFrom<InFile<'_, &RawController>> for ControllerSettings {
    type Error = FileError;

    fn try_from(InFile { raw: c, file }: InFile<'_, &RawController>) -> Result<Self, FileError> {
        let at = file.table("[controller]");
        let inverse_dynamics = inverse_dynamics(c, file)?;
        let needs = match c.kind {
            ControllerType::InverseDynamics if inverse_dynamics.is_none() => {
                Some("type = \"inverse-dynamics\" needs natural_frequency_hz")
            }
            ControllerType::Pid if c.axes.is_none() => Some(
                "type = \"pid\" needs gains per axis: axes.<name> = { kp = …, ki = …, kd = … }",
            ),
            ControllerType::Fmu if c.fmu.is_none() => Some(
                "type = \"fmu\" needs the FMU file: fmu = \"PATH.fmu\" (relative to the scenario)",
            ),
            ControllerType::Cascade if c.cascade.is_none() => Some(
                "type = \"cascade\" needs loop settings per axis: cascade.<name> = { position_kp = …, velocity_kp = …, velocity_ki = … }",
            ),
            _ => None,
        };
        if let Some(message) = needs {
            return Err(file.error_at(at, message));
        }
        let form = match c.form {
            RawPidForm::Incremental => PidForm::Incremental,
            RawPidForm::Positional => PidForm::Positional,
        };
        let mut pid = PidTable {
            form,
            axes: BTreeMap::new(),
            at: c.axes.as_ref().and_then(|a| file.at(a.span().start)),
        };
        for (axis, g) in c.axes.iter().flat_map(|a| a.get_ref()) {
            let settings = pid_settings(g.get_ref(), form)
                .map_err(|m| file.error(g.span(), format!("controller.axes.{axis}: {m}")))?;
            let at = file.at(g.span().start);
            pid.axes.insert(axis.clone(), AxisGains { settings, at });
        }
        let mut cascade = CascadeTable {
            at: c.cascade.as_ref().and_then(|a| file.at(a.span().start)),
            ..CascadeTable::default()
        };
        for (axis, entry) in c.cascade.iter().flat_map(|a| a.get_ref()) {
            let settings = cascade_axis(entry.get_ref())
                .map_err(|m| file.error(entry.span(), format!("controller.cascade.{axis}: {m}")))?;
            let at = file.at(entry.span().start);
            cascade
                .axes
                .insert(axis.clone(), AxisCascade { settings, at });
        }
        cascade.velocity_filter_hz = file
            .ranged_opt(
                c.velocity_filter_hz.as_ref(),
                "velocity_filter_hz",
                "Hz",
                limits::VELOCITY_FILTER_HZ,
            )?
            .unwrap_or(0.0);
        let fmu = fmu_settings(c, file)?;
        Ok(ControllerSettings {
            kind: c.kind,
            pid,
            cascade,
            inverse_dynamics,
            fmu,
            at,
        })
    }
}

/// The FMU settings, where `fmu` is given: the file must exist; parameters must be finite.
fn fmu_settings(c: &RawController, file: &Source<'_>) -> Result<Option<FmuSettings>, FileError> {
    let Some(written) = &c.fmu else {
        if let Some(p) = &c.parameters {
            return Err(file.error(
                p.span(),
                "controller.parameters are an FMU's: they need fmu = \"PATH.fmu\"",
            ));
        }
        if let Some(v) = &c.variables {
            return Err(file.error(
                v.span(),
                "controller.variables map an FMU's variables: they need fmu = \"PATH.fmu\"",
            ));
        }
        return Ok(None);
    };
    let path = file.resolve(written.get_ref());
    if !path.is_file() {
        return Err(file.error(
            written.span(),
            format!(
                "controller FMU '{}' not found (looked for {})",
                written.get_ref(),
                path.display()
            ),
        ));
    }
    let mut request = crate::fmi::FmuRequest {
        path,
        ..Default::default()
    };
    for (name, value) in c.parameters.iter().flat_map(|p| p.get_ref()) {
        if !value.get_ref().is_finite() {
            return Err(file.error(
                value.span(),
                format!("controller.parameters.{name} must be a finite number"),
            ));
        }
        request.parameters.insert(name.clone(), *value.get_ref());
    }
    for (ours, theirs) in c.variables.iter().flat_map(|v| v.get_ref()) {
        request
            .variables
            .insert(ours.clone(), theirs.get_ref().clone());
    }
    Ok(Some(FmuSettings {
        request,
        at: file.at(written.span().start),
    }))
}

/// The computed-torque settings, where natural_frequency_hz is given.
fn inverse_dynamics(
    c: &RawController,
    file: &Source<'_>,
) -> Result<Option<InverseDynamicsSettings>, FileError> {
    let omega_n = file
        .ranged_opt(
            c.natural_frequency_hz.as_ref(),
            "natural_frequency_hz",
            "Hz",
            limits::NATURAL_FREQUENCY_HZ,
        )?
        .map(|f| f * std::f64::consts::TAU);
    let damping_ratio = file
        .ranged_opt(
            c.damping_ratio.as_ref(),
            "damping_ratio",
            "",
            limits::DAMPING_RATIO,
        )?
        .unwrap_or(1.0);
    let model_mass_scale = file
        .ranged_opt(
            c.model_mass_scale.as_ref(),
            "model_mass_scale",
            "",
            limits::MODEL_MASS_SCALE,
        )?
        .unwrap_or(1.0);
    let task_damping = file
        .ranged_opt(
            c.task_damping.as_ref(),
            "task_damping",
            "",
            limits::TASK_DAMPING,
        )?
        .unwrap_or(DEFAULT_TASK_DAMPING);
    Ok(omega_n.map(|omega_n| InverseDynamicsSettings {
        omega_n,
        damping_ratio,
        model_mass_scale,
        space: c.space,
        task_damping,
    }))
}

/// One axis's PID terms, checked.
fn pid_settings(v: &RawGains, form: PidForm) -> Result<PidSettings, String> {
    let limit = v.output_limit.unwrap_or(f64::INFINITY);
    let g_max = limits::MAX_GAIN;
    let ok = [v.kp, v.ki, v.kd].iter().all(|x| (0.0..=g_max).contains(x))
        && limit > 0.0
        && !limit.is_nan();
    if !ok {
        return Err(format!("gains must be from 0 to {g_max:?}, output_limit > 0 (kp = {:?}, ki = {:?}, kd = {:?}, output_limit = {limit:?})", v.kp, v.ki, v.kd));
    }
    for (name, value, lo, hi) in [
        ("ff0", v.ff0, -g_max, g_max),
        ("ff1", v.ff1, -g_max, g_max),
        ("ff2", v.ff2, -g_max, g_max),
        ("bias", v.bias, -g_max, g_max),
        ("deadband", v.deadband, 0.0, limits::MAX_ERROR),
    ] {
        check_range(name, value, "", lo, hi)?;
    }
    for (name, value) in [
        ("max_error", v.max_error),
        ("max_error_i", v.max_error_i),
        ("max_error_d", v.max_error_d),
    ] {
        if let Some(x) = value {
            check_range(name, x, "", f64::MIN_POSITIVE, g_max)?;
        }
    }
    if let (PidForm::Incremental, Some(_)) = (form, v.max_error_i) {
        return Err("max_error_i limits the integral of the positional form; the incremental form has none (its accumulated output stays within output_limit)".into());
    }
    Ok(PidSettings {
        kp: v.kp,
        ki: v.ki,
        kd: v.kd,
        ff0: v.ff0,
        ff1: v.ff1,
        ff2: v.ff2,
        bias: v.bias,
        deadband: v.deadband,
        max_error: v.max_error,
        max_error_i: v.max_error_i,
        max_error_d: v.max_error_d,
        output_limit: limit,
    })
}

/// One axis's cascade loops, checked.
fn cascade_axis(v: &RawCascade) -> Result<CascadeAxis, String> {
    let g_max = limits::MAX_GAIN;
    let share = limits::MAX_FEED_FORWARD_SHARE;
    for (name, value, lo, hi) in [
        ("position_kp", v.position_kp, 0.0, g_max),
        ("position_ki", v.position_ki, 0.0, g_max),
        ("velocity_kp", v.velocity_kp, 0.0, g_max),
        ("velocity_ki", v.velocity_ki, 0.0, g_max),
        ("velocity_ff", v.velocity_ff, 0.0, share),
        ("acceleration_ff", v.acceleration_ff, 0.0, share),
    ] {
        check_range(name, value, "", lo, hi)?;
    }
    for (name, value) in [
        ("velocity_limit", v.velocity_limit),
        ("output_limit", v.output_limit),
    ] {
        if let Some(x) = value {
            check_range(name, x, "", f64::MIN_POSITIVE, g_max)?;
        }
    }
    let notch = match (v.notch_hz, v.notch_width_hz, v.notch_depth) {
        (None, None, None) => None,
        (Some(hz), Some(width_hz), depth) => {
            check_range("notch_hz", hz, "Hz", 1e-3, 1e6)?;
            check_range("notch_width_hz", width_hz, "Hz", 1e-3, 2.0 * hz)?;
            let depth = depth.unwrap_or(0.0);
            check_range("notch_depth", depth, "", 0.0, 1.0)?;
            Some(Notch {
                hz,
                width_hz,
                depth,
            })
        }
        _ => {
            return Err(
                "a notch takes notch_hz and notch_width_hz (and optionally notch_depth, its gain at the centre: 0 by default)"
                    .into(),
            )
        }
    };
    if let Some(hz) = v.torque_lowpass_hz {
        check_range("torque_lowpass_hz", hz, "Hz", 1e-3, 1e6)?;
    }
    Ok(CascadeAxis {
        position_kp: v.position_kp,
        position_ki: v.position_ki,
        velocity_kp: v.velocity_kp,
        velocity_ki: v.velocity_ki,
        velocity_ff: v.velocity_ff,
        acceleration_ff: v.acceleration_ff,
        velocity_limit: v.velocity_limit.unwrap_or(f64::INFINITY),
        output_limit: v.output_limit.unwrap_or(f64::INFINITY),
        filters: TorqueFilters {
            lowpass_hz: v.torque_lowpass_hz,
            notch,
        },
    })
}
