//! The scenario file format (TOML). Unknown keys are rejected; every value that can be wrong
//! is checked here and reported with the file, line and column it came from.

use crate::control::{ActuatorKind, PidForm, PidGains};
use crate::diagnostics::{read_text, toml_error, FileError, LineColumn};
use crate::machine::{AmplifierMode, Feedback};
use crate::plan::BlendChoice;
use crate::program::{
    parse_tool_table, CircleSpec, FeedRule, LengthUnit, PolylineSpec, ReadOptions,
};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use toml::Spanned;

type Num = Spanned<f64>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    #[serde(default)]
    description: String,
    machine: Spanned<String>,
    program: RawProgram,
    #[serde(default)]
    planner: RawPlanner,
    timing: RawTiming,
    /// Needed to run; a scenario used only for `cncsim plan` may leave these out.
    actuator: Option<RawActuator>,
    controller: Option<RawController>,
    #[serde(default)]
    feedback: RawFeedback,
    #[serde(default)]
    mechanics: RawMechanics,
    #[serde(default)]
    recording: RawRecording,
    /// Run the analytic reference model beside the physics.
    analytic: Option<RawAnalytic>,
    #[serde(default)]
    expect: BTreeMap<String, Spanned<toml::Value>>,
    /// The variants `cncsim ab FILE` runs when no --a/--b overrides are given.
    ab: Option<Spanned<RawAb>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAb {
    #[serde(default)]
    a: Vec<Spanned<String>>,
    #[serde(default)]
    b: Vec<Spanned<String>>,
}

/// Variants declared in a scenario's `[ab]` table: the overrides of A and of B, as written.
#[derive(Debug, Clone, PartialEq)]
pub struct DeclaredVariants {
    pub a: Vec<String>,
    pub b: Vec<String>,
    pub at: Option<LineColumn>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProgram {
    file: Option<Spanned<String>>,
    circle: Option<Spanned<RawCircle>>,
    polyline: Option<Spanned<RawPolyline>>,
    /// Path speed of the built-in paths (mm/s).
    feed_mm_s: Option<Num>,
    /// How a program file's feed applies to moves with rotary axes.
    #[serde(default)]
    feed_rule: RawFeedRule,
    /// HPGL: pen heights (mm), lenient decoding of damaged files, pen-up travel optimisation.
    pen_up_z_mm: Option<f64>,
    pen_down_z_mm: Option<f64>,
    #[serde(default)]
    lenient: bool,
    #[serde(default)]
    optimise_pen_up: bool,
    /// G-code: a LinuxCNC tool table file (lengths in mm) and the G28/G30 positions (mm).
    tool_table: Option<Spanned<String>>,
    g28_home_mm: Option<[f64; 3]>,
    g30_home_mm: Option<[f64; 3]>,
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "kebab-case")]
enum RawFeedRule {
    #[default]
    Linuxcnc,
    EuclideanAllAxes,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCircle {
    center_mm: [f64; 2],
    radius_mm: f64,
    #[serde(default)]
    start_angle_deg: f64,
    #[serde(default)]
    direction: Direction,
    #[serde(default)]
    z_mm: f64,
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum Direction {
    #[default]
    Ccw,
    Cw,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPolyline {
    points_mm: Vec<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlanner {
    #[serde(default)]
    profile: ProfileName,
    #[serde(default = "default_rapid")]
    rapid_mm_s: Num,
    /// Trapezoid profile: path acceleration (mm/s²).
    acceleration_mm_s2: Option<Num>,
    /// Corner behaviour: as programmed, or forced.
    #[serde(default)]
    blend: RawBlend,
    /// Tolerance of `blend = "continuous"` (mm); absent = as far as the segments allow.
    tolerance_mm: Option<Num>,
    /// Jerk-limited planner: limits per machine axis in mm or deg per s, s², s³.
    #[serde(default)]
    limits: BTreeMap<String, Spanned<RawLimits>>,
}

fn default_rapid() -> Num {
    Spanned::new(0..0, 50.0)
}

impl Default for RawPlanner {
    fn default() -> Self {
        RawPlanner {
            profile: ProfileName::default(),
            rapid_mm_s: default_rapid(),
            acceleration_mm_s2: None,
            blend: RawBlend::default(),
            tolerance_mm: None,
            limits: BTreeMap::new(),
        }
    }
}

/// Which planner turns the program into setpoints.
#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ProfileName {
    /// Seed constant-velocity interpolators (equal steps V·T, equal chords).
    #[default]
    #[value(name = "constant")]
    ConstantVelocity,
    /// Seed trapezoidal profile on straight moves (needs acceleration_mm_s2).
    Trapezoid,
    /// Jerk-limited look-ahead planner on the machine axes (needs limits per axis).
    #[value(name = "jerk")]
    JerkLimited,
}

#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[serde(rename_all = "kebab-case")]
enum RawBlend {
    #[default]
    Program,
    ExactStop,
    Continuous,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLimits {
    velocity: f64,
    acceleration: f64,
    jerk: f64,
}

/// The planner part of a scenario: the profile it names and the parameters of every profile
/// it gives (limits stay in program units: the axis kinds come from the machine).
#[derive(Debug, Clone, PartialEq)]
pub struct PlannerSettings {
    pub profile: ProfileName,
    /// Trapezoid path acceleration (m/s²).
    pub acceleration: Option<f64>,
    /// Jerk-limited planner, per axis: [velocity, acceleration, jerk] in mm or deg units.
    pub limits: BTreeMap<String, ([f64; 3], Option<LineColumn>)>,
    /// Where the `[planner]` table is.
    pub at: Option<LineColumn>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTiming {
    servo_period_ms: Num,
    physics_step_ms: Num,
    #[serde(default = "default_settle")]
    settle_s: Num,
    /// Rapier solver iterations per physics step (each is an integration substep).
    #[serde(default = "one")]
    solver_iterations: Spanned<i64>,
}

fn default_settle() -> Num {
    Spanned::new(0..0, 0.5)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawActuator {
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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawController {
    #[serde(rename = "type")]
    kind: ControllerType,
    #[serde(default)]
    form: RawPidForm,
    /// PID gains per axis (`type = "pid"`).
    axes: Option<Spanned<BTreeMap<String, Spanned<RawGains>>>>,
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
}

/// Default least-squares damping of the task-space controller: about the smallest singular
/// value of the mill's task Jacobian a few degrees from A = 0.
pub const DEFAULT_TASK_DAMPING: f64 = 0.05;

/// The computed-torque controller's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseDynamicsSettings {
    /// Closed-loop natural frequency (rad/s).
    pub omega_n: f64,
    pub damping_ratio: f64,
    pub model_mass_scale: f64,
    pub space: ControlSpace,
    /// Task space: the least-squares damping λ (0 in joint space).
    pub task_damping: f64,
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

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "kebab-case")]
enum ControllerType {
    Pid,
    InverseDynamics,
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "kebab-case")]
enum RawPidForm {
    #[default]
    Positional,
    Incremental,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGains {
    kp: f64,
    #[serde(default)]
    ki: f64,
    #[serde(default)]
    kd: f64,
    /// |output| limit (N·m or V); default: none beyond the actuator's own saturation.
    output_limit: Option<f64>,
}

/// Which of the machine's nonlinear mechanics the run keeps (both on by default): turning one
/// off removes it from the physics and the analytic model alike.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMechanics {
    #[serde(default = "yes")]
    friction: bool,
    #[serde(default = "yes")]
    backlash: bool,
}

impl Default for RawMechanics {
    fn default() -> Self {
        RawMechanics {
            friction: true,
            backlash: true,
        }
    }
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawFeedback {
    /// Where every axis's loop is closed, instead of the drive file's choice.
    position: Option<Feedback>,
    #[serde(default)]
    encoder_counts_per_rev: BTreeMap<String, Spanned<i64>>,
    following_error_limit_mm: Option<Num>,
    following_error_limit_deg: Option<Num>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAnalytic {
    #[serde(default = "yes")]
    enabled: bool,
    /// RK4 steps per servo period.
    #[serde(default = "sixteen")]
    steps_per_period: Spanned<i64>,
}

fn sixteen() -> Spanned<i64> {
    Spanned::new(0..0, 16)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRecording {
    #[serde(default = "yes")]
    rrd: bool,
    #[serde(default = "yes")]
    csv: bool,
    #[serde(default = "one")]
    decimation: Spanned<i64>,
}

fn yes() -> bool {
    true
}

fn one() -> Spanned<i64> {
    Spanned::new(0..0, 1)
}

impl Default for RawRecording {
    fn default() -> Self {
        RawRecording {
            rrd: true,
            csv: true,
            decimation: one(),
        }
    }
}

/// Where the program comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ProgramSource {
    Circle(CircleSpec),
    Polyline(PolylineSpec),
    File { path: PathBuf, options: ReadOptions },
}

/// PID settings of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisGains {
    pub gains: PidGains,
    pub output_limit: f64,
    pub at: Option<LineColumn>,
}

/// A bound on one metric.
#[derive(Debug, Clone, PartialEq)]
pub struct Expectation {
    /// Dotted path into `metrics.json`, e.g. `axes.x.max_following_error_mm`.
    pub metric: String,
    pub min: Option<f64>,
    pub max: Option<f64>,
    pub at: Option<LineColumn>,
}

/// A validated scenario: plain data, SI units, paths resolved against the scenario's folder.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub name: String,
    pub path: PathBuf,
    pub description: String,
    pub machine: PathBuf,
    pub machine_at: Option<LineColumn>,
    pub program: ProgramSource,
    pub planner: PlannerSettings,
    pub blend: BlendChoice,
    pub rapid_speed: f64,
    pub servo_period: f64,
    pub substeps: usize,
    pub solver_iterations: usize,
    pub settle_time: f64,
    /// `None`: the scenario has no `[actuator]` (it can be planned, not run).
    pub actuator: Option<ActuatorKind>,
    pub pid_form: PidForm,
    pub gains: BTreeMap<String, AxisGains>,
    pub controller_at: Option<LineColumn>,
    /// `Some` when the controller is the computed-torque one (then `gains` is empty).
    pub inverse_dynamics: Option<InverseDynamicsSettings>,
    pub encoder_counts_per_rev: BTreeMap<String, (u32, Option<LineColumn>)>,
    /// Feedback position for every axis, overriding the drive file; `None` = the drive's.
    pub feedback_position: Option<Feedback>,
    /// Amplifier mode of every drive, overriding the drive file; `None` = the drive's.
    pub amplifier_mode: Option<AmplifierMode>,
    /// Keep the guides' contact friction / the transmissions' backlash of the machine.
    pub friction: bool,
    pub backlash: bool,
    /// Following-error fault limits: m for linear axes, rad for rotary axes.
    pub following_error_limit_linear: f64,
    pub following_error_limit_rotary: f64,
    pub record_rrd: bool,
    pub record_csv: bool,
    pub decimation: usize,
    /// RK4 steps per servo period of the analytic reference model; `None` = not run.
    pub analytic_steps: Option<usize>,
    pub expect: Vec<Expectation>,
    /// `[ab]`: the variants `cncsim ab` runs on this file alone.
    pub ab: Option<DeclaredVariants>,
}

impl Scenario {
    pub fn load(path: &Path) -> Result<Scenario, FileError> {
        let text = read_text(path, "scenario")?;
        Self::parse(path, &text)
    }

    pub fn parse(path: &Path, text: &str) -> Result<Scenario, FileError> {
        let raw: RawScenario = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        let at = |start: usize| Some(LineColumn::of_offset(text, start));
        let err = |span: std::ops::Range<usize>, msg: String| {
            FileError::new(
                path,
                if span == (0..0) { None } else { at(span.start) },
                msg,
            )
        };
        let finite = |v: &Num, what: &str| -> Result<f64, FileError> {
            let x = *v.get_ref();
            if x.is_finite() {
                Ok(x)
            } else {
                Err(err(
                    v.span(),
                    format!("{what} = {x}: expected a finite number"),
                ))
            }
        };
        let positive = |v: &Num, what: &str| -> Result<f64, FileError> {
            let x = finite(v, what)?;
            if x > 0.0 {
                Ok(x)
            } else {
                Err(err(
                    v.span(),
                    format!("{what} = {x}: expected a number > 0"),
                ))
            }
        };
        let dir = path.parent().unwrap_or(Path::new("."));
        let resolve = |p: &str| dir.join(p);

        // Machine: must exist (its contents are checked when it is loaded).
        let machine = resolve(raw.machine.get_ref());
        if !machine.is_file() {
            return Err(err(
                raw.machine.span(),
                format!(
                    "machine model '{}' not found (looked for {})",
                    raw.machine.get_ref(),
                    machine.display()
                ),
            ));
        }

        if let Some(a) = &raw.actuator {
            if let (ActuatorModel::IdealTorque, Some(mode)) = (a.model, &a.amplifier_mode) {
                return Err(err(
                    mode.span(),
                    "[actuator] amplifier_mode applies to model = \"dc-motor\"; the ideal-torque actuator has no amplifier".into(),
                ));
            }
        }

        // Program: exactly one source.
        let p = &raw.program;
        let count = p.file.is_some() as u8 + p.circle.is_some() as u8 + p.polyline.is_some() as u8;
        let program_at = LineColumn::of_first(text, "[program]");
        if count != 1 {
            return Err(FileError::new(
                path,
                program_at,
                format!(
                    "[program] needs exactly one of `file`, `circle` or `polyline`, found {count}"
                ),
            ));
        }
        let feed = || -> Result<f64, FileError> {
            match &p.feed_mm_s {
                Some(v) => Ok(positive(v, "feed_mm_s")? * 1e-3),
                None => Err(FileError::new(
                    path,
                    program_at,
                    "[program] feed_mm_s is required for a built-in path",
                )),
            }
        };
        let program = if let Some(f) = &p.file {
            if let Some(feed) = &p.feed_mm_s {
                return Err(err(
                    feed.span(),
                    "feed_mm_s applies to built-in paths; a program file programs its own feed"
                        .into(),
                ));
            }
            let file = resolve(f.get_ref());
            if !file.is_file() {
                return Err(err(
                    f.span(),
                    format!(
                        "program file '{}' not found (looked for {})",
                        f.get_ref(),
                        file.display()
                    ),
                ));
            }
            let mut options = ReadOptions {
                feed_rule: match p.feed_rule {
                    RawFeedRule::Linuxcnc => FeedRule::LinuxCnc,
                    RawFeedRule::EuclideanAllAxes => FeedRule::EuclideanAllAxes,
                },
                ..ReadOptions::default()
            };
            for (value, target) in [
                (p.pen_up_z_mm, &mut options.hpgl.pen_up_z),
                (p.pen_down_z_mm, &mut options.hpgl.pen_down_z),
            ] {
                if let Some(v) = value {
                    if !v.is_finite() {
                        return Err(FileError::new(
                            path,
                            program_at,
                            format!("pen height {v} mm: expected a finite number"),
                        ));
                    }
                    *target = v * 1e-3;
                }
            }
            options.hpgl.lenient = p.lenient;
            options.hpgl.optimise_pen_up = p.optimise_pen_up;
            if let Some(table) = &p.tool_table {
                let table_path = resolve(table.get_ref());
                let text = std::fs::read_to_string(&table_path).map_err(|error| {
                    err(
                        table.span(),
                        format!("tool table '{}': {error}", table_path.display()),
                    )
                })?;
                options.gcode.tools = parse_tool_table(&text, &table_path, LengthUnit::Millimetre)
                    .map_err(|errors| err(table.span(), errors.to_string()))?;
            }
            for (value, target, key) in [
                (p.g28_home_mm, &mut options.gcode.g28_home, "g28_home_mm"),
                (p.g30_home_mm, &mut options.gcode.g30_home, "g30_home_mm"),
            ] {
                if let Some(home) = value {
                    if !home.iter().all(|v| v.is_finite()) {
                        return Err(FileError::new(
                            path,
                            program_at,
                            format!("{key}: expected finite numbers"),
                        ));
                    }
                    target.linear = home.map(|v| v * 1e-3);
                }
            }
            ProgramSource::File {
                path: file,
                options,
            }
        } else if let Some(c) = &p.circle {
            let v = c.get_ref();
            let nums = [
                v.center_mm[0],
                v.center_mm[1],
                v.radius_mm,
                v.start_angle_deg,
                v.z_mm,
            ];
            if !nums.iter().all(|x| x.is_finite()) || v.radius_mm <= 0.0 {
                return Err(err(
                    c.span(),
                    "circle: expected finite numbers and radius_mm > 0".into(),
                ));
            }
            ProgramSource::Circle(CircleSpec {
                center: [v.center_mm[0] * 1e-3, v.center_mm[1] * 1e-3],
                radius: v.radius_mm * 1e-3,
                start_angle: v.start_angle_deg.to_radians(),
                clockwise: matches!(v.direction, Direction::Cw),
                z: v.z_mm * 1e-3,
                speed: feed()?,
            })
        } else {
            let pl = p.polyline.as_ref().expect("counted above");
            let pts = &pl.get_ref().points_mm;
            if pts.len() < 2 || !pts.iter().flatten().all(|x| x.is_finite()) {
                return Err(err(
                    pl.span(),
                    format!(
                        "polyline: expected at least 2 points of finite numbers, found {}",
                        pts.len()
                    ),
                ));
            }
            ProgramSource::Polyline(PolylineSpec {
                points: pts.iter().map(|p| p.map(|v| v * 1e-3)).collect(),
                speed: feed()?,
            })
        };

        // Timing: physics step ≤ servo period, and a whole number of steps per period.
        let servo_period = positive(&raw.timing.servo_period_ms, "servo_period_ms")? * 1e-3;
        let physics_step = positive(&raw.timing.physics_step_ms, "physics_step_ms")? * 1e-3;
        if physics_step > servo_period * (1.0 + 1e-12) {
            return Err(err(
                raw.timing.physics_step_ms.span(),
                format!("physics_step_ms = {} is longer than servo_period_ms = {}: the physics must step at least once per servo period", physics_step * 1e3, servo_period * 1e3),
            ));
        }
        let ratio = servo_period / physics_step;
        let substeps = ratio.round();
        if (ratio - substeps).abs() > 1e-9 * ratio {
            return Err(err(
                raw.timing.physics_step_ms.span(),
                format!("physics_step_ms = {} does not divide servo_period_ms = {} into whole steps (ratio {ratio:.6})", physics_step * 1e3, servo_period * 1e3),
            ));
        }
        let settle_time = finite(&raw.timing.settle_s, "settle_s")?;
        if settle_time < 0.0 {
            return Err(err(
                raw.timing.settle_s.span(),
                format!("settle_s = {settle_time}: expected a number ≥ 0"),
            ));
        }

        let solver_iterations = *raw.timing.solver_iterations.get_ref();
        if !(1..=64).contains(&solver_iterations) {
            return Err(err(
                raw.timing.solver_iterations.span(),
                format!(
                    "solver_iterations = {solver_iterations}: expected a whole number from 1 to 64"
                ),
            ));
        }

        // The `[controller]` table may carry PID gains and inverse-dynamics parameters side by
        // side (so `ab --a controller=pid --b controller=inverse-dynamics` compares them on one
        // file); `type` chooses, and whatever is given is checked either way.
        let controller_table = LineColumn::of_first(text, "[controller]");
        let inverse_dynamics = match &raw.controller {
            Some(c) => {
                let is_id = matches!(c.kind, ControllerType::InverseDynamics);
                let omega_n = match &c.natural_frequency_hz {
                    Some(f) => Some(positive(f, "natural_frequency_hz")? * std::f64::consts::TAU),
                    None => None,
                };
                let damping_ratio = match &c.damping_ratio {
                    Some(z) => positive(z, "damping_ratio")?,
                    None => 1.0,
                };
                let model_mass_scale = match &c.model_mass_scale {
                    Some(m) => positive(m, "model_mass_scale")?,
                    None => 1.0,
                };
                let task_damping = match &c.task_damping {
                    Some(l) => positive(l, "task_damping")?,
                    None => DEFAULT_TASK_DAMPING,
                };
                match (is_id, omega_n) {
                    (true, Some(omega_n)) => Some(InverseDynamicsSettings {
                        omega_n,
                        damping_ratio,
                        model_mass_scale,
                        space: c.space,
                        task_damping,
                    }),
                    (true, None) => {
                        return Err(FileError::new(
                            path,
                            controller_table,
                            "type = \"inverse-dynamics\" needs natural_frequency_hz",
                        ))
                    }
                    (false, _) if c.axes.is_none() => {
                        return Err(FileError::new(path, controller_table, "type = \"pid\" needs gains per axis: axes.<name> = { kp = …, ki = …, kd = … }"));
                    }
                    (false, _) => None,
                }
            }
            None => None,
        };

        let mut gains = BTreeMap::new();
        let no_axes = BTreeMap::new();
        let controller_axes = raw
            .controller
            .as_ref()
            .and_then(|c| c.axes.as_ref())
            .map_or(&no_axes, |a| a.get_ref());
        for (axis, g) in controller_axes {
            let v = g.get_ref();
            let limit = v.output_limit.unwrap_or(f64::INFINITY);
            let ok = [v.kp, v.ki, v.kd]
                .iter()
                .all(|x| x.is_finite() && *x >= 0.0)
                && limit > 0.0
                && !limit.is_nan();
            if !ok {
                return Err(err(g.span(), format!("controller.axes.{axis}: gains must be finite and ≥ 0, output_limit > 0 (kp={}, ki={}, kd={}, output_limit={limit})", v.kp, v.ki, v.kd)));
            }
            gains.insert(
                axis.clone(),
                AxisGains {
                    gains: PidGains {
                        kp: v.kp,
                        ki: v.ki,
                        kd: v.kd,
                    },
                    output_limit: limit,
                    at: at(g.span().start),
                },
            );
        }

        let mut encoder_counts_per_rev = BTreeMap::new();
        for (axis, c) in &raw.feedback.encoder_counts_per_rev {
            let n = *c.get_ref();
            if !(1..=u32::MAX as i64).contains(&n) {
                return Err(err(
                    c.span(),
                    format!("encoder_counts_per_rev.{axis} = {n}: expected a whole number ≥ 1"),
                ));
            }
            encoder_counts_per_rev.insert(axis.clone(), (n as u32, at(c.span().start)));
        }
        // Defaults trip well beyond any sane tracking error but long before a runaway.
        let following_error_limit_linear = match &raw.feedback.following_error_limit_mm {
            Some(v) => positive(v, "following_error_limit_mm")? * 1e-3,
            None => 10e-3,
        };
        let following_error_limit_rotary = match &raw.feedback.following_error_limit_deg {
            Some(v) => positive(v, "following_error_limit_deg")?.to_radians(),
            None => 10f64.to_radians(),
        };
        let decimation = *raw.recording.decimation.get_ref();
        if decimation < 1 {
            return Err(err(raw.recording.decimation.span(), format!("decimation = {decimation}: expected a whole number ≥ 1 (record every k-th tick)")));
        }

        let rp = &raw.planner;
        let acceleration = match &rp.acceleration_mm_s2 {
            Some(a) => Some(positive(a, "acceleration_mm_s2")? * 1e-3),
            None => None,
        };
        let mut limits = BTreeMap::new();
        for (axis, l) in &rp.limits {
            let v = l.get_ref();
            let values = [v.velocity, v.acceleration, v.jerk];
            if !values.iter().all(|x| x.is_finite() && *x > 0.0) {
                return Err(err(l.span(), format!("planner.limits.{axis}: velocity, acceleration and jerk must be finite and > 0, found {values:?}")));
            }
            limits.insert(axis.clone(), (values, at(l.span().start)));
        }
        let planner = PlannerSettings {
            profile: rp.profile,
            acceleration,
            limits,
            at: LineColumn::of_first(text, "[planner]"),
        };
        let tolerance = match &rp.tolerance_mm {
            Some(t) => Some(positive(t, "tolerance_mm")? * 1e-3),
            None => None,
        };
        let blend = match rp.blend {
            RawBlend::Program => BlendChoice::Program,
            RawBlend::ExactStop => BlendChoice::ExactStop,
            RawBlend::Continuous => BlendChoice::Continuous { tolerance },
        };
        if tolerance.is_some() && rp.blend != RawBlend::Continuous {
            return Err(err(
                rp.tolerance_mm.as_ref().unwrap().span(),
                "tolerance_mm applies to blend = \"continuous\"".into(),
            ));
        }

        let analytic_steps = match &raw.analytic {
            Some(a) if a.enabled => {
                let steps = *a.steps_per_period.get_ref();
                if !(1..=10_000).contains(&steps) {
                    return Err(err(
                        a.steps_per_period.span(),
                        format!(
                            "steps_per_period = {steps}: expected a whole number from 1 to 10000"
                        ),
                    ));
                }
                Some(steps as usize)
            }
            _ => None,
        };

        let ab = match &raw.ab {
            Some(table) => {
                let v = table.get_ref();
                for (side, list) in [("a", &v.a), ("b", &v.b)] {
                    for o in list {
                        if let Err(e) = super::Override::parse(o.get_ref()) {
                            return Err(err(o.span(), format!("ab.{side}: {e}")));
                        }
                    }
                }
                if v.a.is_empty() && v.b.is_empty() {
                    return Err(err(
                        table.span(),
                        "[ab] declares no overrides: expected a = [\"KEY=VALUE\", …] and/or b = […]".into(),
                    ));
                }
                let texts =
                    |list: &[Spanned<String>]| list.iter().map(|o| o.get_ref().clone()).collect();
                Some(DeclaredVariants {
                    a: texts(&v.a),
                    b: texts(&v.b),
                    at: at(table.span().start),
                })
            }
            None => None,
        };

        let mut expect = Vec::new();
        for (key, value) in &raw.expect {
            flatten_expectations(
                key,
                value.get_ref(),
                at(value.span().start),
                path,
                &mut expect,
            )?;
        }

        Ok(Scenario {
            name: raw.name.unwrap_or_else(|| {
                path.file_stem()
                    .map_or("scenario".into(), |s| s.to_string_lossy().into_owned())
            }),
            path: path.to_path_buf(),
            description: raw.description,
            machine,
            machine_at: at(raw.machine.span().start),
            program,
            planner,
            blend,
            rapid_speed: positive(&raw.planner.rapid_mm_s, "rapid_mm_s")? * 1e-3,
            servo_period,
            substeps: substeps as usize,
            solver_iterations: solver_iterations as usize,
            settle_time,
            actuator: raw.actuator.as_ref().map(|a| match a.model {
                ActuatorModel::IdealTorque => ActuatorKind::IdealTorque,
                ActuatorModel::DcMotor => ActuatorKind::DcMotor,
            }),
            // Only PID so far: the `type` enum rejects other names.
            pid_form: match raw.controller.as_ref().map(|c| (c.kind, c.form)) {
                Some((ControllerType::Pid, RawPidForm::Incremental)) => PidForm::Incremental,
                _ => PidForm::Positional,
            },
            gains,
            controller_at: raw
                .controller
                .as_ref()
                .and_then(|c| c.axes.as_ref())
                .and_then(|a| at(a.span().start)),
            inverse_dynamics,
            encoder_counts_per_rev,
            feedback_position: raw.feedback.position,
            amplifier_mode: raw
                .actuator
                .as_ref()
                .and_then(|a| a.amplifier_mode.as_ref().map(|m| *m.get_ref())),
            friction: raw.mechanics.friction,
            backlash: raw.mechanics.backlash,
            following_error_limit_linear,
            following_error_limit_rotary,
            record_rrd: raw.recording.rrd,
            record_csv: raw.recording.csv,
            decimation: decimation as usize,
            analytic_steps,
            expect,
            ab,
        })
    }
}

impl Scenario {
    /// Moves every recorded file position through `f` (`None`: the place no longer exists in
    /// the file, e.g. a line an override wrote).
    pub(crate) fn map_positions(&mut self, f: &dyn Fn(LineColumn) -> Option<LineColumn>) {
        let map = |at: &mut Option<LineColumn>| *at = at.and_then(f);
        map(&mut self.machine_at);
        map(&mut self.planner.at);
        map(&mut self.controller_at);
        for (_, at) in self.planner.limits.values_mut() {
            map(at);
        }
        for g in self.gains.values_mut() {
            map(&mut g.at);
        }
        for (_, at) in self.encoder_counts_per_rev.values_mut() {
            map(at);
        }
        for e in &mut self.expect {
            map(&mut e.at);
        }
        if let Some(ab) = &mut self.ab {
            map(&mut ab.at);
        }
    }
}

/// `[expect]` entries: `metric = { max = … }` / `{ min = … }` / both, possibly nested
/// (`[expect.axes.x]`), flattened to dotted metric paths.
fn flatten_expectations(
    prefix: &str,
    value: &toml::Value,
    at: Option<LineColumn>,
    path: &Path,
    out: &mut Vec<Expectation>,
) -> Result<(), FileError> {
    let fail = |m: String| FileError::new(path, at, m);
    let table = value.as_table().ok_or_else(|| {
        fail(format!(
            "expect.{prefix}: expected a bound such as {{ max = 0.01 }}, found {}",
            value.type_str()
        ))
    })?;
    let is_bound = !table.is_empty() && table.keys().all(|k| k == "min" || k == "max");
    if !is_bound {
        for (k, v) in table {
            if k == "min" || k == "max" {
                return Err(fail(format!(
                    "expect.{prefix}: mixes a bound ({k}) with nested metrics"
                )));
            }
            flatten_expectations(&format!("{prefix}.{k}"), v, at, path, out)?;
        }
        return Ok(());
    }
    let num = |k: &str| -> Result<Option<f64>, FileError> {
        match table.get(k) {
            None => Ok(None),
            Some(v) => {
                let x = v
                    .as_float()
                    .or_else(|| v.as_integer().map(|i| i as f64))
                    .ok_or_else(|| {
                        fail(format!(
                            "expect.{prefix}.{k}: expected a number, found {}",
                            v.type_str()
                        ))
                    })?;
                if x.is_nan() {
                    return Err(fail(format!(
                        "expect.{prefix}.{k} = nan: expected a number"
                    )));
                }
                Ok(Some(x))
            }
        }
    };
    let (min, max) = (num("min")?, num("max")?);
    if let (Some(lo), Some(hi)) = (min, max) {
        if lo > hi {
            return Err(fail(format!("expect.{prefix}: min {lo} > max {hi}")));
        }
    }
    out.push(Expectation {
        metric: prefix.to_string(),
        min,
        max,
        at,
    });
    Ok(())
}
