//! The scenario file format (TOML). Unknown keys are rejected; every value that can be wrong
//! is checked here and reported with the file, line and column it came from. Numbers must lie
//! in the ranges of [`limits`], which keep a run physically meaningful and its work bounded.

use crate::control::{ActuatorKind, AxisCompensation, CascadeAxis, PidForm, PidGains, PidSettings};
use crate::diagnostics::{check_range, read_text, toml_error, FileError, LineColumn};
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

/// Ranges of a scenario's numbers, in the units of their keys (inclusive). Outside them a value
/// is refused with its place in the file; a run's length is bounded besides by
/// [`crate::sim::MAX_SERVO_TICKS`] and [`crate::sim::MAX_PHYSICS_STEPS`].
pub mod limits {
    /// Servo period (ms): from 100 kHz drives to the slowest seed document (20 ms) with margin.
    pub const SERVO_PERIOD_MS: (f64, f64) = (0.01, 100.0);
    /// Physics step (ms); it must also divide the servo period.
    pub const PHYSICS_STEP_MS: (f64, f64) = (0.001, 100.0);
    /// Most physics steps per servo period.
    pub const MAX_SUBSTEPS: usize = 10_000;
    /// Settle time before the program (s).
    pub const SETTLE_S: (f64, f64) = (0.0, 3600.0);
    /// Path speeds: built-in path feed, rapid speed (mm/s). No machine tool moves 20 m/s.
    pub const SPEED_MM_S: (f64, f64) = (1e-3, 2e4);
    /// Above this a feed loads with a warning (mm/s).
    pub const SUSPECT_SPEED_MM_S: f64 = 5e3;
    /// Trapezoid path acceleration (mm/s²).
    pub const ACCELERATION_MM_S2: (f64, f64) = (1e-3, 1e7);
    /// Jerk-limited planner limits per axis, mm or deg per s, s², s³.
    pub const LIMIT_VELOCITY: (f64, f64) = (1e-3, 1e5);
    pub const LIMIT_ACCELERATION: (f64, f64) = (1e-3, 1e8);
    pub const LIMIT_JERK: (f64, f64) = (1e-3, 1e11);
    /// Corner tolerance (mm).
    pub const TOLERANCE_MM: (f64, f64) = (1e-6, 100.0);
    /// Coordinates and radii of built-in paths and pen heights (|value| ≤, mm): 100 m.
    pub const COORDINATE_MM: f64 = 1e5;
    /// Following-error fault limits.
    pub const FOLLOWING_ERROR_LIMIT_MM: (f64, f64) = (1e-6, 1e3);
    pub const FOLLOWING_ERROR_LIMIT_DEG: (f64, f64) = (1e-6, 360.0);
    /// PID gains (≥ 0) and output limits.
    pub const MAX_GAIN: f64 = 1e12;
    /// Inverse dynamics: closed-loop natural frequency (Hz), damping ratio, model mass scale,
    /// task-space least-squares damping.
    pub const NATURAL_FREQUENCY_HZ: (f64, f64) = (1e-3, 1e4);
    pub const DAMPING_RATIO: (f64, f64) = (1e-3, 100.0);
    pub const MODEL_MASS_SCALE: (f64, f64) = (1e-3, 100.0);
    pub const TASK_DAMPING: (f64, f64) = (1e-9, 10.0);
    /// Recording decimation (record every k-th tick).
    pub const MAX_DECIMATION: i64 = 1_000_000;
    /// PID error limits and deadband (m or rad).
    pub const MAX_ERROR: f64 = 1.0;
    /// Cascade feed-forward shares (1 = the whole setpoint velocity or inertia torque).
    pub const MAX_FEED_FORWARD_SHARE: f64 = 2.0;
    /// Cut-off of the cascade's velocity estimate (Hz).
    pub const VELOCITY_FILTER_HZ: (f64, f64) = (0.0, 1e6);
    /// Compensated backlash.
    pub const MAX_BACKLASH_MM: f64 = 100.0;
    pub const MAX_BACKLASH_DEG: f64 = 90.0;
}

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
    /// Backlash and friction compensation per axis.
    #[serde(default)]
    compensation: BTreeMap<String, Spanned<RawCompensation>>,
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
    /// The ISO 230-4 circular test as the program (src/scenario/ballbar.rs).
    ballbar: Option<Spanned<RawBallbar>>,
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
    /// Where the machine is before the program: it reaches the program's first point by an
    /// untraced straight move from here (mm), as a real machine comes from home.
    approach_from_mm: Option<Spanned<[f64; 3]>>,
    /// Speed of that move (mm/s); default: the planner's rapid speed.
    approach_feed_mm_s: Option<Num>,
    /// Program zero, as G54 sets it: its machine coordinates along X, Y, Z (mm); default:
    /// where the tool is with every axis at its home.
    work_offset_mm: Option<Spanned<[f64; 3]>>,
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
struct RawBallbar {
    radius_mm: f64,
    feed_mm_min: f64,
    #[serde(default)]
    plane: super::ballbar::BallbarPlane,
    center_mm: Option<[f64; 3]>,
    #[serde(default = "default_overshoot")]
    overshoot_deg: f64,
}

fn default_overshoot() -> f64 {
    45.0
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
    /// Naive-CAM collinearity tolerance (LinuxCNC's G64 Q, mm): runs of short straight moves
    /// within it of one line are joined, with continuous blending.
    naive_cam_tolerance_mm: Option<Num>,
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
            naive_cam_tolerance_mm: None,
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
}

impl ControllerType {
    pub fn name(self) -> &'static str {
        match self {
            ControllerType::Pid => "pid",
            ControllerType::Cascade => "cascade",
            ControllerType::InverseDynamics => "inverse-dynamics",
        }
    }
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
}

/// One axis's compensation at reversals, in the units of the keys.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCompensation {
    backlash_mm: Option<f64>,
    backlash_deg: Option<f64>,
    backlash_rate_mm_s: Option<f64>,
    backlash_rate_deg_s: Option<f64>,
    friction_pulse: Option<f64>,
    friction_decay_ms: Option<f64>,
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
    /// Steps per servo period (exact or RK4, see `sim::analytic`).
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
    /// The ISO 230-4 circular test (`cncsim ballbar`'s program): its figures join the metrics
    /// under `ballbar`.
    Ballbar(super::ballbar::BallbarSpec),
    /// The reader settings are boxed: with the G-code tool table they outweigh the others.
    File {
        path: PathBuf,
        options: Box<ReadOptions>,
    },
}

/// The machine's way to the program: a straight move from `from` at `speed`, run before the
/// settle and not traced, identically in the physics and the analytic model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach {
    /// Start point in program coordinates (m).
    pub from: [f64; 3],
    /// Path speed (m/s).
    pub speed: f64,
}

/// PID settings of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisGains {
    pub settings: PidSettings,
    pub at: Option<LineColumn>,
}

impl AxisGains {
    pub fn gains(&self) -> PidGains {
        self.settings.gains()
    }

    pub fn output_limit(&self) -> f64 {
        self.settings.output_limit
    }
}

/// Cascade settings of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisCascade {
    pub settings: CascadeAxis,
    pub at: Option<LineColumn>,
}

/// Compensation of one axis, SI; `rotary_units` says which unit family the backlash keys used
/// (`None` when none was given), checked against the axis kind when the machine is known.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensationEntry {
    pub compensation: AxisCompensation,
    pub rotary_units: Option<bool>,
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
    /// The untraced approach to the program's first point: from where (m), at what speed (m/s).
    pub approach: Option<Approach>,
    /// Machine coordinates of program zero along X, Y, Z (m): the work offset (G54).
    pub work_offset: [f64; 3],
    pub planner: PlannerSettings,
    pub blend: BlendChoice,
    /// LinuxCNC's G64 Q (m): runs of straight moves within it of one line are joined.
    pub naive_cam_tolerance: Option<f64>,
    pub rapid_speed: f64,
    pub servo_period: f64,
    pub substeps: usize,
    pub solver_iterations: usize,
    pub settle_time: f64,
    /// `None`: the scenario has no `[actuator]` (it can be planned, not run).
    pub actuator: Option<ActuatorKind>,
    /// The controller that runs; `None` without a `[controller]` (plan only). The settings of
    /// every type given stand side by side below (each checked), so an override of `type`
    /// switches between them.
    pub controller: Option<ControllerType>,
    pub pid_form: PidForm,
    pub gains: BTreeMap<String, AxisGains>,
    pub cascade: BTreeMap<String, AxisCascade>,
    /// Cut-off of the cascade's velocity estimate (Hz; 0 = unfiltered).
    pub velocity_filter_hz: f64,
    pub controller_at: Option<LineColumn>,
    /// The computed-torque settings, where given (natural_frequency_hz).
    pub inverse_dynamics: Option<InverseDynamicsSettings>,
    /// Backlash and friction compensation per axis.
    pub compensation: BTreeMap<String, CompensationEntry>,
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
    /// Steps per servo period of the analytic reference model; `None` = not run.
    pub analytic_steps: Option<usize>,
    pub expect: Vec<Expectation>,
    /// `[ab]`: the variants `cncsim ab` runs on this file alone.
    pub ab: Option<DeclaredVariants>,
    /// Values that are legal but look wrong, located in the file.
    pub warnings: Vec<FileError>,
}

impl Scenario {
    pub fn load(path: &Path) -> Result<Scenario, FileError> {
        let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        if ["urdf", "xacro"].contains(&extension.to_ascii_lowercase().as_str()) {
            return Err(FileError::new(
                path,
                None,
                format!(
                    "this is a machine model, not a scenario: a run needs a scenario file (.toml) naming the machine, the program and the controller (see scenarios/). For a machine of your own, `cncsim machine check {}` shows how cncsim reads it and `cncsim machine init {}` writes its drive file",
                    path.display(),
                    path.display()
                ),
            ));
        }
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
        // A number within its range (limits), or an error at its place.
        let ranged = |v: &Num, what: &str, unit: &str, (lo, hi): (f64, f64)| {
            let x = *v.get_ref();
            check_range(what, x, unit, lo, hi)
                .map(|()| x)
                .map_err(|m| err(v.span(), m))
        };
        let mut warnings = Vec::new();
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
        let count = p.file.is_some() as u8
            + p.circle.is_some() as u8
            + p.polyline.is_some() as u8
            + p.ballbar.is_some() as u8;
        let program_at = LineColumn::of_first(text, "[program]");
        if count != 1 {
            return Err(FileError::new(
                path,
                program_at,
                format!(
                    "[program] needs exactly one of `file`, `circle`, `polyline` or `ballbar`, found {count}"
                ),
            ));
        }
        let feed = || -> Result<f64, FileError> {
            match &p.feed_mm_s {
                Some(v) => Ok(ranged(v, "feed_mm_s", "mm/s", limits::SPEED_MM_S)? * 1e-3),
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
                    let c = limits::COORDINATE_MM;
                    check_range("pen height", v, "mm", -c, c)
                        .map_err(|m| FileError::new(path, program_at, m))?;
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
                options: Box::new(options),
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
            let c_mm = limits::COORDINATE_MM;
            let in_reach = nums.iter().all(|x| x.is_finite() && x.abs() <= c_mm);
            if !in_reach || v.radius_mm <= 0.0 {
                return Err(err(
                    c.span(),
                    format!("circle: expected numbers within ±{c_mm:?} mm and radius_mm > 0, found center_mm = {:?}, radius_mm = {:?}, start_angle_deg = {:?}, z_mm = {:?}", v.center_mm, v.radius_mm, v.start_angle_deg, v.z_mm),
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
        } else if let Some(b) = &p.ballbar {
            if let Some(feed) = &p.feed_mm_s {
                return Err(err(
                    feed.span(),
                    "feed_mm_s applies to circle and polyline; the ballbar test takes feed_mm_min"
                        .into(),
                ));
            }
            let v = b.get_ref();
            let c_mm = limits::COORDINATE_MM;
            let (lo, hi) = limits::SPEED_MM_S;
            let centre_ok = v
                .center_mm
                .is_none_or(|c| c.iter().all(|x| x.is_finite() && x.abs() <= c_mm));
            if !(v.radius_mm > 0.0 && v.radius_mm <= c_mm)
                || !(v.feed_mm_min >= lo * 60.0 && v.feed_mm_min <= hi * 60.0)
                || !(v.overshoot_deg > 0.0 && v.overshoot_deg <= 180.0)
                || !centre_ok
            {
                return Err(err(
                    b.span(),
                    format!("ballbar: expected 0 < radius_mm ≤ {c_mm:?}, feed_mm_min within [{}, {}], 0 < overshoot_deg ≤ 180 and center_mm within ±{c_mm:?} mm, found radius_mm = {:?}, feed_mm_min = {:?}, overshoot_deg = {:?}, center_mm = {:?}", lo * 60.0, hi * 60.0, v.radius_mm, v.feed_mm_min, v.overshoot_deg, v.center_mm),
                ));
            }
            ProgramSource::Ballbar(super::ballbar::BallbarSpec {
                radius: v.radius_mm * 1e-3,
                feed: v.feed_mm_min / 60e3,
                plane: v.plane.into(),
                centre: v.center_mm.map(|c| c.map(|x| x * 1e-3)),
                overshoot: v.overshoot_deg.to_radians(),
            })
        } else {
            let pl = p.polyline.as_ref().expect("counted above");
            let pts = &pl.get_ref().points_mm;
            let c_mm = limits::COORDINATE_MM;
            if pts.len() < 2
                || !pts
                    .iter()
                    .flatten()
                    .all(|x| x.is_finite() && x.abs() <= c_mm)
            {
                return Err(err(
                    pl.span(),
                    format!(
                        "polyline: expected at least 2 points with coordinates within ±{c_mm:?} mm, found {} points",
                        pts.len()
                    ),
                ));
            }
            ProgramSource::Polyline(PolylineSpec {
                points: pts.iter().map(|p| p.map(|v| v * 1e-3)).collect(),
                speed: feed()?,
            })
        };

        // A point of the program in mm, within the coordinate limit, to metres.
        let point_mm = |v: &Spanned<[f64; 3]>, key: &str| {
            let c = limits::COORDINATE_MM;
            let p = v.get_ref();
            if p.iter().all(|x| x.is_finite() && x.abs() <= c) {
                Ok(p.map(|x| x * 1e-3))
            } else {
                Err(err(
                    v.span(),
                    format!("{key} = {p:?}: expected coordinates within ±{c:?} mm"),
                ))
            }
        };
        let approach = match &p.approach_from_mm {
            None => {
                if let Some(f) = &p.approach_feed_mm_s {
                    return Err(err(
                        f.span(),
                        "approach_feed_mm_s applies with approach_from_mm".into(),
                    ));
                }
                None
            }
            Some(from) => {
                let from = point_mm(from, "approach_from_mm")?;
                let speed = match &p.approach_feed_mm_s {
                    Some(f) => ranged(f, "approach_feed_mm_s", "mm/s", limits::SPEED_MM_S)?,
                    None => *raw.planner.rapid_mm_s.get_ref(),
                };
                Some(Approach {
                    from,
                    speed: speed * 1e-3,
                })
            }
        };
        let work_offset = match &p.work_offset_mm {
            None => [0.0; 3],
            Some(offset) => point_mm(offset, "work_offset_mm")?,
        };
        for (key, value) in [
            ("feed_mm_s", p.feed_mm_s.as_ref()),
            ("rapid_mm_s", Some(&raw.planner.rapid_mm_s)),
        ] {
            if let Some(v) = value.filter(|v| *v.get_ref() > limits::SUSPECT_SPEED_MM_S) {
                warnings.push(err(
                    v.span(),
                    format!(
                        "{key} = {:?} mm/s is more than {:?} mm/s: few machines move that fast",
                        v.get_ref(),
                        limits::SUSPECT_SPEED_MM_S
                    ),
                ));
            }
        }

        // Timing: physics step ≤ servo period, and a whole number of steps per period.
        let t = &raw.timing;
        let servo_period_ms = ranged(
            &t.servo_period_ms,
            "servo_period_ms",
            "ms",
            limits::SERVO_PERIOD_MS,
        )?;
        let physics_step_ms = ranged(
            &t.physics_step_ms,
            "physics_step_ms",
            "ms",
            limits::PHYSICS_STEP_MS,
        )?;
        let (servo_period, physics_step) = (servo_period_ms * 1e-3, physics_step_ms * 1e-3);
        if physics_step > servo_period * (1.0 + 1e-12) {
            return Err(err(
                t.physics_step_ms.span(),
                format!("physics_step_ms = {physics_step_ms:?} is longer than servo_period_ms = {servo_period_ms:?}: the physics must step at least once per servo period"),
            ));
        }
        let ratio = servo_period / physics_step;
        let substeps = ratio.round();
        if (ratio - substeps).abs() > 1e-9 * ratio {
            return Err(err(
                t.physics_step_ms.span(),
                format!("physics_step_ms = {physics_step_ms:?} does not divide servo_period_ms = {servo_period_ms:?} into whole steps (ratio {ratio:.6})"),
            ));
        }
        if substeps as usize > limits::MAX_SUBSTEPS {
            return Err(err(
                t.physics_step_ms.span(),
                format!("physics_step_ms = {physics_step_ms:?} makes {substeps} physics steps per servo period: expected at most {}", limits::MAX_SUBSTEPS),
            ));
        }
        let settle_time = ranged(&t.settle_s, "settle_s", "s", limits::SETTLE_S)?;

        let solver_iterations = *raw.timing.solver_iterations.get_ref();
        if !(1..=64).contains(&solver_iterations) {
            return Err(err(
                raw.timing.solver_iterations.span(),
                format!(
                    "solver_iterations = {solver_iterations}: expected a whole number from 1 to 64"
                ),
            ));
        }

        // The `[controller]` table may carry the settings of every controller type side by
        // side (so `ab --a controller=pid --b controller=cascade` compares them on one file);
        // `type` chooses, and whatever is given is checked either way.
        let controller_table = LineColumn::of_first(text, "[controller]");
        let inverse_dynamics = match &raw.controller {
            Some(c) => {
                let omega_n = match &c.natural_frequency_hz {
                    Some(f) => Some(
                        ranged(
                            f,
                            "natural_frequency_hz",
                            "Hz",
                            limits::NATURAL_FREQUENCY_HZ,
                        )? * std::f64::consts::TAU,
                    ),
                    None => None,
                };
                let damping_ratio = match &c.damping_ratio {
                    Some(z) => ranged(z, "damping_ratio", "", limits::DAMPING_RATIO)?,
                    None => 1.0,
                };
                let model_mass_scale = match &c.model_mass_scale {
                    Some(m) => ranged(m, "model_mass_scale", "", limits::MODEL_MASS_SCALE)?,
                    None => 1.0,
                };
                let task_damping = match &c.task_damping {
                    Some(l) => ranged(l, "task_damping", "", limits::TASK_DAMPING)?,
                    None => DEFAULT_TASK_DAMPING,
                };
                omega_n.map(|omega_n| InverseDynamicsSettings {
                    omega_n,
                    damping_ratio,
                    model_mass_scale,
                    space: c.space,
                    task_damping,
                })
            }
            None => None,
        };
        if let Some(c) = &raw.controller {
            let needs = match c.kind {
                ControllerType::InverseDynamics if inverse_dynamics.is_none() => {
                    Some("type = \"inverse-dynamics\" needs natural_frequency_hz")
                }
                ControllerType::Pid if c.axes.is_none() => Some(
                    "type = \"pid\" needs gains per axis: axes.<name> = { kp = …, ki = …, kd = … }",
                ),
                ControllerType::Cascade if c.cascade.is_none() => Some(
                    "type = \"cascade\" needs loop settings per axis: cascade.<name> = { position_kp = …, velocity_kp = …, velocity_ki = … }",
                ),
                _ => None,
            };
            if let Some(message) = needs {
                return Err(FileError::new(path, controller_table, message));
            }
        }
        let pid_form = match raw.controller.as_ref().map(|c| c.form) {
            Some(RawPidForm::Incremental) => PidForm::Incremental,
            _ => PidForm::Positional,
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
            let fail = |m: String| err(g.span(), format!("controller.axes.{axis}: {m}"));
            let limit = v.output_limit.unwrap_or(f64::INFINITY);
            let ok = [v.kp, v.ki, v.kd]
                .iter()
                .all(|x| (0.0..=limits::MAX_GAIN).contains(x))
                && limit > 0.0
                && !limit.is_nan();
            if !ok {
                return Err(fail(format!("gains must be from 0 to {:?}, output_limit > 0 (kp = {:?}, ki = {:?}, kd = {:?}, output_limit = {limit:?})", limits::MAX_GAIN, v.kp, v.ki, v.kd)));
            }
            let g_max = limits::MAX_GAIN;
            for (name, value, lo, hi) in [
                ("ff0", v.ff0, -g_max, g_max),
                ("ff1", v.ff1, -g_max, g_max),
                ("ff2", v.ff2, -g_max, g_max),
                ("bias", v.bias, -g_max, g_max),
                ("deadband", v.deadband, 0.0, limits::MAX_ERROR),
            ] {
                check_range(name, value, "", lo, hi).map_err(&fail)?;
            }
            for (name, value) in [
                ("max_error", v.max_error),
                ("max_error_i", v.max_error_i),
                ("max_error_d", v.max_error_d),
            ] {
                if let Some(x) = value {
                    check_range(name, x, "", f64::MIN_POSITIVE, g_max).map_err(&fail)?;
                }
            }
            if let (PidForm::Incremental, Some(_)) = (pid_form, v.max_error_i) {
                return Err(fail("max_error_i limits the integral of the positional form; the incremental form has none (its accumulated output stays within output_limit)".into()));
            }
            gains.insert(
                axis.clone(),
                AxisGains {
                    settings: PidSettings {
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
                    },
                    at: at(g.span().start),
                },
            );
        }

        let mut cascade = BTreeMap::new();
        let no_cascade = BTreeMap::new();
        let cascade_axes = raw
            .controller
            .as_ref()
            .and_then(|c| c.cascade.as_ref())
            .map_or(&no_cascade, |a| a.get_ref());
        for (axis, entry) in cascade_axes {
            let v = entry.get_ref();
            let fail = |m: String| err(entry.span(), format!("controller.cascade.{axis}: {m}"));
            let g_max = limits::MAX_GAIN;
            for (name, value, lo, hi) in [
                ("position_kp", v.position_kp, 0.0, g_max),
                ("position_ki", v.position_ki, 0.0, g_max),
                ("velocity_kp", v.velocity_kp, 0.0, g_max),
                ("velocity_ki", v.velocity_ki, 0.0, g_max),
                (
                    "velocity_ff",
                    v.velocity_ff,
                    0.0,
                    limits::MAX_FEED_FORWARD_SHARE,
                ),
                (
                    "acceleration_ff",
                    v.acceleration_ff,
                    0.0,
                    limits::MAX_FEED_FORWARD_SHARE,
                ),
            ] {
                check_range(name, value, "", lo, hi).map_err(&fail)?;
            }
            for (name, value) in [
                ("velocity_limit", v.velocity_limit),
                ("output_limit", v.output_limit),
            ] {
                if let Some(x) = value {
                    check_range(name, x, "", f64::MIN_POSITIVE, g_max).map_err(&fail)?;
                }
            }
            cascade.insert(
                axis.clone(),
                AxisCascade {
                    settings: CascadeAxis {
                        position_kp: v.position_kp,
                        position_ki: v.position_ki,
                        velocity_kp: v.velocity_kp,
                        velocity_ki: v.velocity_ki,
                        velocity_ff: v.velocity_ff,
                        acceleration_ff: v.acceleration_ff,
                        velocity_limit: v.velocity_limit.unwrap_or(f64::INFINITY),
                        output_limit: v.output_limit.unwrap_or(f64::INFINITY),
                    },
                    at: at(entry.span().start),
                },
            );
        }
        let velocity_filter_hz = match raw
            .controller
            .as_ref()
            .and_then(|c| c.velocity_filter_hz.as_ref())
        {
            Some(f) => ranged(f, "velocity_filter_hz", "Hz", limits::VELOCITY_FILTER_HZ)?,
            None => 0.0,
        };

        let mut compensation = BTreeMap::new();
        for (axis, entry) in &raw.compensation {
            let v = entry.get_ref();
            let fail = |m: String| err(entry.span(), format!("compensation.{axis}: {m}"));
            let (backlash, rate, rotary_units) = match (
                v.backlash_mm,
                v.backlash_deg,
                v.backlash_rate_mm_s,
                v.backlash_rate_deg_s,
            ) {
                (None, None, None, None) => (0.0, 0.0, None),
                (Some(b), None, Some(r), None) => {
                    check_range("backlash_mm", b, "mm", 0.0, limits::MAX_BACKLASH_MM).map_err(&fail)?;
                    check_range("backlash_rate_mm_s", r, "mm/s", 1e-6, limits::SPEED_MM_S.1).map_err(&fail)?;
                    (b * 1e-3, r * 1e-3, Some(false))
                }
                (None, Some(b), None, Some(r)) => {
                    check_range("backlash_deg", b, "deg", 0.0, limits::MAX_BACKLASH_DEG).map_err(&fail)?;
                    check_range("backlash_rate_deg_s", r, "deg/s", 1e-6, limits::LIMIT_VELOCITY.1).map_err(&fail)?;
                    (b.to_radians(), r.to_radians(), Some(true))
                }
                _ => return Err(fail("backlash compensation takes backlash_mm with backlash_rate_mm_s (linear axes) or backlash_deg with backlash_rate_deg_s (rotary axes)".into())),
            };
            let (pulse, decay) = match (v.friction_pulse, v.friction_decay_ms) {
                (None, None) => (0.0, 1.0),
                (Some(a), Some(d)) => {
                    check_range("friction_pulse", a, "", -limits::MAX_GAIN, limits::MAX_GAIN).map_err(&fail)?;
                    check_range("friction_decay_ms", d, "ms", 1e-3, 1e5).map_err(&fail)?;
                    (a, d * 1e-3)
                }
                _ => return Err(fail("friction compensation takes friction_pulse (in controller output units: V or N·m) with friction_decay_ms".into())),
            };
            compensation.insert(
                axis.clone(),
                CompensationEntry {
                    compensation: AxisCompensation {
                        backlash,
                        backlash_rate: rate,
                        friction_pulse: pulse,
                        friction_decay: decay,
                    },
                    rotary_units,
                    at: at(entry.span().start),
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
            Some(v) => {
                ranged(
                    v,
                    "following_error_limit_mm",
                    "mm",
                    limits::FOLLOWING_ERROR_LIMIT_MM,
                )? * 1e-3
            }
            None => 10e-3,
        };
        let following_error_limit_rotary = match &raw.feedback.following_error_limit_deg {
            Some(v) => ranged(
                v,
                "following_error_limit_deg",
                "deg",
                limits::FOLLOWING_ERROR_LIMIT_DEG,
            )?
            .to_radians(),
            None => 10f64.to_radians(),
        };
        let decimation = *raw.recording.decimation.get_ref();
        if !(1..=limits::MAX_DECIMATION).contains(&decimation) {
            return Err(err(raw.recording.decimation.span(), format!("decimation = {decimation}: expected a whole number from 1 to {} (record every k-th tick)", limits::MAX_DECIMATION)));
        }

        let rp = &raw.planner;
        let acceleration = match &rp.acceleration_mm_s2 {
            Some(a) => {
                Some(ranged(a, "acceleration_mm_s2", "mm/s²", limits::ACCELERATION_MM_S2)? * 1e-3)
            }
            None => None,
        };
        let mut axis_limits = BTreeMap::new();
        for (axis, l) in &rp.limits {
            let v = l.get_ref();
            let values = [v.velocity, v.acceleration, v.jerk];
            let ranges = [
                ("velocity", "mm/s or deg/s", limits::LIMIT_VELOCITY),
                (
                    "acceleration",
                    "mm/s² or deg/s²",
                    limits::LIMIT_ACCELERATION,
                ),
                ("jerk", "mm/s³ or deg/s³", limits::LIMIT_JERK),
            ];
            for (value, (name, unit, (lo, hi))) in values.iter().zip(ranges) {
                check_range(
                    &format!("planner.limits.{axis}.{name}"),
                    *value,
                    unit,
                    lo,
                    hi,
                )
                .map_err(|m| err(l.span(), m))?;
            }
            axis_limits.insert(axis.clone(), (values, at(l.span().start)));
        }
        let planner = PlannerSettings {
            profile: rp.profile,
            acceleration,
            limits: axis_limits,
            at: LineColumn::of_first(text, "[planner]"),
        };
        let tolerance = match &rp.tolerance_mm {
            Some(t) => Some(ranged(t, "tolerance_mm", "mm", limits::TOLERANCE_MM)? * 1e-3),
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
        let naive_cam_tolerance = match &rp.naive_cam_tolerance_mm {
            Some(q) if rp.blend == RawBlend::ExactStop => {
                return Err(err(
                    q.span(),
                    "naive_cam_tolerance_mm joins moves: it needs blend = \"continuous\" or \"program\"".into(),
                ))
            }
            Some(q) => Some(
                ranged(q, "naive_cam_tolerance_mm", "mm", limits::TOLERANCE_MM)? * 1e-3,
            ),
            None => None,
        };

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
            approach,
            work_offset,
            planner,
            blend,
            naive_cam_tolerance,
            rapid_speed: ranged(
                &raw.planner.rapid_mm_s,
                "rapid_mm_s",
                "mm/s",
                limits::SPEED_MM_S,
            )? * 1e-3,
            servo_period,
            substeps: substeps as usize,
            solver_iterations: solver_iterations as usize,
            settle_time,
            actuator: raw.actuator.as_ref().map(|a| match a.model {
                ActuatorModel::IdealTorque => ActuatorKind::IdealTorque,
                ActuatorModel::DcMotor => ActuatorKind::DcMotor,
            }),
            controller: raw.controller.as_ref().map(|c| c.kind),
            pid_form,
            gains,
            cascade,
            velocity_filter_hz,
            controller_at: raw
                .controller
                .as_ref()
                .and_then(|c| c.axes.as_ref())
                .and_then(|a| at(a.span().start)),
            inverse_dynamics,
            compensation,
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
            warnings,
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
        for w in &mut self.warnings {
            map(&mut w.at);
        }
        for (_, at) in self.planner.limits.values_mut() {
            map(at);
        }
        for g in self.gains.values_mut() {
            map(&mut g.at);
        }
        for c in self.cascade.values_mut() {
            map(&mut c.at);
        }
        for c in self.compensation.values_mut() {
            map(&mut c.at);
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
                if !x.is_finite() {
                    return Err(fail(format!(
                        "expect.{prefix}.{k} = {x:?}: expected a finite number"
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
