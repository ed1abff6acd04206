//! The assembly step: a scenario and its machine in, the wired servo loop and its setpoints
//! out. `run`, `check`, `tune`, `ab`, `sweep` and `calibrate` all build their runs here, so a
//! loop feature or a controller exists for every one of them at once (as Drake's
//! DiagramBuilder wires systems, and ripgrep turns arguments into the workers it runs).

mod against_machine;
mod controller;
mod cutting;

pub use controller::ControllerRecipe;
pub use cutting::CutSetup;

use super::{AnalyticSettings, ProgramKinematics, ProgramSource, Scenario};
use crate::control::{Actuator, ActuatorKind, Controller};
use crate::diagnostics::{FileError, LineColumn};
use crate::kinematics::five_axis::{FiveAxisKinematics, PartFrame};
use crate::kinematics::tool_tip::{cl_to_machine, tcp_to_machine};
use crate::kinematics::{AcAxes, AcTableKinematics, AxisMap, ProgramFrame};
use crate::machine::Machine;
use crate::model::{ModelError, PlantOptions};
use crate::plan::{
    plan_program, AxisKind, AxisLimits, PlanError, PlanSettings, PlannedProgram, Planner,
    SetpointStream, Setpoints,
};
use crate::program::{circle, polyline, read_program, Program, ProgramErrors};
use crate::report::{AxisLabel, ThinnedPath};
use crate::sim::{
    self, AnalyticPlant, Encoder, FollowingErrorTrip, Lane, LaneKind, LoopSettings, Observer,
    Outcome, PhysicsPlant, MAX_PHYSICS_STEPS, MAX_SERVO_TICKS,
};
use std::path::PathBuf;
use std::sync::OnceLock;

/// Points of the programmed path drawn in a recording (evenly thinned over the program).
const PROGRAMMED_PATH_POINTS: usize = 50_000;

/// Builds a plant of one's own for a lane, at rest at the given start (joint units).
pub type MakePlant<'a> = dyn Fn(LaneKind, &[f64]) -> Box<dyn sim::Plant> + 'a;

/// Builds a fresh controller of one's own.
pub type MakeController<'a> = dyn Fn() -> Box<dyn Controller> + 'a;

/// Gravity in the machine base frame: URDF convention, z up.
pub const GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// Why a scenario could not be assembled or run.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A file (scenario, machine, drive file, program) is missing, unreadable or wrong, or the
    /// scenario does not fit its machine.
    #[error("{0}")]
    File(#[from] FileError),
    /// The physics model could not be built from the machine.
    #[error("{path}: {source}")]
    Model {
        /// The scenario file.
        path: PathBuf,
        /// What the model builder refused.
        source: ModelError,
    },
    /// The program (or the approach) could not be planned.
    #[error("{path}: {source}")]
    Plan {
        /// The file whose plan failed: the program's source, or the scenario for its approach.
        path: PathBuf,
        /// What the planner refused.
        source: PlanError,
    },
    /// Writing the report or the recording failed.
    #[error(transparent)]
    Report(#[from] crate::report::ReportError),
    /// The program file has errors.
    #[error("{0}")]
    Program(ProgramErrors),
}

/// A scenario wired for running: the machine with the scenario's choices applied, the planned
/// program and the loop's settings. Plants and controllers are built fresh for each run, and
/// so is the setpoint stream: no sample is kept, so memory does not grow with the program's
/// duration.
pub struct Assembly {
    /// The scenario as loaded.
    pub scenario: Scenario,
    /// The machine with the scenario's `[mechanics]`, `[feedback]` and `[actuator]` choices
    /// applied (and the program frame's warnings added).
    pub machine: Machine,
    /// How each machine axis is shown, in the machine's axis order.
    pub labels: Vec<AxisLabel>,
    /// How program coordinates map onto the machine's axes (sign and home per axis).
    pub axis_map: AxisMap,
    /// The program frame: where contour error, path speed and the tool path are measured.
    pub frame: ProgramFrame,
    /// The planned program, from which the setpoints are streamed.
    pub plan: PlannedProgram,
    /// The actuator model of every axis (the scenario's `[actuator]`).
    pub actuator: ActuatorKind,
    /// The controller, resolved on the machine (a fresh instance for every lane and run).
    pub controller: ControllerRecipe,
    /// The servo loop's period, approach, settle time, encoder, following-error trip and
    /// spindle speeds.
    pub loop_settings: LoopSettings,
    /// The cut every lane makes, with `[cutting]`.
    pub cut: Option<CutSetup>,
    /// What the reports need of the whole program, from one pass over its setpoints when first
    /// asked for.
    overview: OnceLock<ProgramOverview>,
}

/// What a run's reports need to know of the whole program before it runs.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgramOverview {
    /// Largest |commanded velocity| of each axis (joint units per s).
    pub peak_velocity: Vec<f64>,
    /// The programmed tool path on the workpiece (forward kinematics of the setpoints, evenly
    /// thinned to a bounded number of points, the last one kept), m.
    pub programmed_path: Vec<[f64; 3]>,
}

impl Assembly {
    /// Loads the scenario's machine and wires the scenario.
    pub fn new(s: &Scenario) -> Result<Assembly, RunError> {
        Self::with_machine(s, machine_for(s)?)
    }

    /// Wires the scenario on a machine given in memory (e.g. one a calibration varies), taken
    /// as it is: [`machine_for`] is the scenario's machine with its `[mechanics]`,
    /// `[feedback]` and `[actuator]` choices applied.
    pub fn with_machine(s: &Scenario, machine: Machine) -> Result<Assembly, RunError> {
        let plan = plan_for(s, &machine)?;
        Self::from_plan(s, machine, plan)
    }

    /// Wires the scenario on `machine` with a plan made before (e.g. shared by the variants
    /// of a sweep that all run the same setpoints).
    pub fn from_plan(
        s: &Scenario,
        mut machine: Machine,
        plan: PlannedProgram,
    ) -> Result<Assembly, RunError> {
        let Some(actuator) = s.actuator.map(|a| a.kind) else {
            let message = "running a scenario needs [actuator] and [controller] sections (planning with `cncsim plan` does not)";
            return Err(FileError::new(&s.path, None, message).into());
        };
        let labels = labels(&machine);
        against_machine::check_against_machine(s, &machine, &labels)?;
        let controller = ControllerRecipe::new(s, &machine, actuator)?;
        let axis_map = plan.axis_map().clone();
        let (frame, frame_warnings) = ProgramFrame::new(&machine)?;
        machine.warnings.extend(frame_warnings);
        let approach = approach_for(s, &machine, &axis_map, plan.program())?;
        if let Some(message) = cutting::missing_spindle(s, plan.program()) {
            return Err(FileError::new(&s.path, None, message).into());
        }
        let program_start = plan
            .first_position()
            .map_or_else(|| vec![0.0; machine.axes.len()], <[f64]>::to_vec);
        let cut = cutting::cut_setup(s, &machine, &frame, plan.program(), &program_start)?;
        let spindle = cutting::spindles(s, plan.program());
        check_run_length(s, approach.len() + plan.len())?;
        let encoder = Encoder {
            resolution: machine
                .axes
                .iter()
                .map(|a| {
                    let mut drive = a.drive.clone();
                    if let Some((counts, _)) = s.feedback.encoder_counts_per_rev.get(&a.name) {
                        drive.encoder_counts_per_rev = Some(*counts);
                    }
                    drive.encoder_resolution()
                })
                .collect(),
        };
        let trip = FollowingErrorTrip {
            limit: labels
                .iter()
                .map(|l| {
                    if l.rotary {
                        s.feedback.following_error_limit_rotary
                    } else {
                        s.feedback.following_error_limit_linear
                    }
                })
                .collect(),
            axis_names: labels.iter().map(|l| l.name.clone()).collect(),
        };
        Ok(Assembly {
            scenario: s.clone(),
            machine,
            labels,
            axis_map,
            frame,
            plan,
            actuator,
            controller,
            loop_settings: LoopSettings {
                servo_period: s.timing.servo_period,
                approach,
                settle_time: s.timing.settle_time,
                encoder,
                trip,
                spindle,
            },
            cut,
            overview: OnceLock::new(),
        })
    }

    /// The program's peak velocities and tool path, from one pass over its setpoints (made
    /// once, then kept).
    pub fn overview(&self) -> &ProgramOverview {
        self.overview.get_or_init(|| {
            let mut peak = vec![0.0f64; self.machine.axes.len()];
            let mut path = ThinnedPath::new(PROGRAMMED_PATH_POINTS);
            let mut stream = self.setpoints();
            let mut sample = crate::plan::SetpointSample::zeros(stream.axes());
            while stream.next_sample(&mut sample) {
                for (p, v) in peak.iter_mut().zip(&sample.velocity) {
                    *p = p.max(v.abs());
                }
                let q = crate::kinematics::tool_in_workpiece(&self.machine, &sample.position);
                path.push([q.x, q.y, q.z]);
            }
            ProgramOverview {
                peak_velocity: peak,
                programmed_path: path.into_points(),
            }
        })
    }

    /// The program as planned (in machine coordinates, work offset applied).
    pub fn program(&self) -> &Program {
        self.plan.program()
    }

    /// The setpoint stream of the program, from its first sample, computed as it is read.
    pub fn setpoints(&self) -> Box<dyn SetpointStream + Send + '_> {
        self.plan.stream()
    }

    /// Where every axis starts: at rest at the start of the approach, or else at the first
    /// setpoint.
    pub fn start(&self) -> Vec<f64> {
        let approach = &self.loop_settings.approach;
        if !approach.is_empty() {
            approach.position(0).to_vec()
        } else if let Some(first) = self.plan.first_position() {
            first.to_vec()
        } else {
            vec![0.0; self.machine.axes.len()]
        }
    }

    /// The Rapier machine at rest at `initial` (joint units per axis), with its actuators.
    pub fn physics_plant(&self, initial: &[f64]) -> Result<PhysicsPlant, RunError> {
        let s = &self.scenario;
        let options = PlantOptions {
            step: s.timing.physics_step(),
            gravity: GRAVITY,
            initial_positions: initial.to_vec(),
            include_drive_dynamics: true,
            solver_iterations: s.timing.solver_iterations,
        };
        let plant = crate::model::Plant::new(&self.machine, &options).map_err(|source| {
            RunError::Model {
                path: s.path.clone(),
                source,
            }
        })?;
        let axes = &self.machine.axes;
        Ok(PhysicsPlant::new(
            plant,
            axes.iter()
                .map(|a| Actuator::new(self.actuator, &a.drive))
                .collect(),
            axes.iter().map(|a| a.drive.ratio()).collect(),
            s.timing.substeps,
        ))
    }

    /// The analytic reference model at rest at `initial`, integrated with the scenario's RK4
    /// steps per period (16 without an `[analytic]` table).
    pub fn analytic_plant(&self, initial: &[f64]) -> Result<AnalyticPlant, RunError> {
        let s = &self.scenario;
        AnalyticPlant::new(
            &self.machine,
            GRAVITY,
            self.actuator == ActuatorKind::IdealTorque,
            s.timing.servo_period,
            s.analytic
                .map_or(AnalyticSettings::DEFAULT_STEPS, |a| a.steps_per_period),
            initial,
        )
        .map_err(|e| FileError::new(&s.path, None, format!("the analytic model: {e}")).into())
    }

    /// A plant of either kind at rest at `initial`.
    pub fn plant(&self, kind: LaneKind, initial: &[f64]) -> Result<Box<dyn sim::Plant>, RunError> {
        Ok(match kind {
            LaneKind::Physics => Box::new(self.physics_plant(initial)?),
            LaneKind::Analytic => Box::new(self.analytic_plant(initial)?),
        })
    }

    /// A plant of either kind at rest at `initial`, cutting the scenario's stock where it has
    /// `[cutting]`.
    pub fn cutting_plant(
        &self,
        kind: LaneKind,
        initial: &[f64],
    ) -> Result<Box<dyn sim::Plant>, RunError> {
        let Some(cut) = &self.cut else {
            return self.plant(kind, initial);
        };
        Ok(match kind {
            LaneKind::Physics => Box::new(
                self.physics_plant(initial)?
                    .with_cut(cut.plant_cut(), cut.placement.tool_axis),
            ),
            LaneKind::Analytic => {
                // These chains never turn the tool: its axis on the part is the one at home.
                let home: Vec<f64> = self.machine.axes.iter().map(|a| a.drive.home).collect();
                let (_, axis) = cut.placement.tool_at(&self.machine, &home);
                let axis = cut.placement.stock_in_part * axis;
                Box::new(self.analytic_plant(initial)?.with_cut(
                    cut.plant_cut(),
                    axis,
                    self.scenario.timing.substeps,
                ))
            }
        })
    }

    /// A fresh instance of the scenario's controller (with its compensation), in the machine's
    /// axis order.
    pub fn controller(&self) -> Box<dyn Controller> {
        self.controller.build()
    }

    /// What the scenario runs: the physics and, with `[analytic]`, the reference model beside
    /// it.
    pub fn lane_kinds(&self) -> Vec<LaneKind> {
        let mut kinds = vec![LaneKind::Physics];
        if self.scenario.analytic.is_some() {
            kinds.push(LaneKind::Analytic);
        }
        kinds
    }

    /// The lanes of a run with the scenario's plants and controller, each at rest where the
    /// machine starts.
    pub fn lanes(&self) -> Result<Vec<Lane<'static>>, RunError> {
        self.lanes_with(None, None)
    }

    /// The lanes of a run, each at rest where the machine starts: the scenario's plant and
    /// controller in each, or those `plant(lane, start)` and `controller()` make.
    pub fn lanes_with(
        &self,
        plant: Option<&MakePlant<'_>>,
        controller: Option<&MakeController<'_>>,
    ) -> Result<Vec<Lane<'static>>, RunError> {
        let start = self.start();
        self.lane_kinds()
            .into_iter()
            .map(|kind| {
                Ok(Lane {
                    kind,
                    plant: match plant {
                        Some(make) => make(kind, &start),
                        None => self.cutting_plant(kind, &start)?,
                    },
                    controller: controller.map_or_else(|| self.controller(), |make| make()),
                })
            })
            .collect()
    }

    /// Runs `lanes` on the scenario's setpoints through the servo loop.
    pub(crate) fn simulate(
        &self,
        lanes: &mut [Lane<'_>],
        observer: &mut dyn Observer,
        progress: &mut dyn FnMut(usize, usize) -> bool,
    ) -> Outcome {
        sim::run(
            &self.loop_settings,
            lanes,
            &mut self.setpoints(),
            observer,
            progress,
        )
    }

    /// Whether `other` runs the same setpoints (sample for sample): the condition of an A/B
    /// comparison.
    pub fn same_setpoints(&self, other: &Assembly) -> bool {
        let (mut a, mut b) = (self.setpoints(), other.setpoints());
        if a.len() != b.len() || a.axes() != b.axes() || a.period() != b.period() {
            return false;
        }
        let (mut x, mut y) = (
            crate::plan::SetpointSample::zeros(a.axes()),
            crate::plan::SetpointSample::zeros(b.axes()),
        );
        while a.next_sample(&mut x) && b.next_sample(&mut y) {
            if x != y {
                return false;
            }
        }
        true
    }
}

fn labels(machine: &Machine) -> Vec<AxisLabel> {
    machine
        .axes
        .iter()
        .map(|a| AxisLabel {
            name: a.name.clone(),
            rotary: a.is_rotary(machine),
        })
        .collect()
}

/// The setpoints of the scenario's approach (none without one): a straight move from its start
/// to the program's first point at its speed, planned by the scenario's own planner.
fn approach_for(
    s: &Scenario,
    machine: &Machine,
    axis_map: &AxisMap,
    program: &Program,
) -> Result<Setpoints, RunError> {
    let Some(a) = s.approach() else {
        return Ok(Setpoints::default());
    };
    let start = crate::program::Position {
        linear: a.from,
        rotary: program.start.rotary,
    };
    let first = program.moves.first().map(|m| m.span).unwrap_or_default();
    let way = Program {
        source: program.source.clone(),
        start,
        moves: vec![crate::program::Move {
            motion: crate::program::Motion::Linear,
            end: program.start,
            tool_axis: None,
            feed: crate::program::Feed::PathSpeed(a.speed),
            feed_rule: crate::program::FeedRule::LinuxCnc,
            blend: crate::program::Blend::ExactStop,
            tool_down: None,
            spindle: crate::program::Spindle::Off,
            span: first,
        }],
        warnings: Vec::new(),
        tools: Vec::new(),
        reading: None,
    };
    let settings = plan_settings(s, machine, s.planner.profile)?;
    plan_program(&way, axis_map, &settings).map_err(|source| RunError::Plan {
        path: s.path.clone(),
        source,
    })
}

/// The scenario's program on `machine`, planned.
pub fn plan_for(s: &Scenario, machine: &Machine) -> Result<PlannedProgram, RunError> {
    let axis_map = axis_map_for(s, machine)?;
    let program = load_checked_program(s, machine)?;
    let mut settings = plan_settings(s, machine, s.planner.profile)?;
    // Corner tolerances at the tool tip, as the program's author reads them.
    settings.tool_lever_arms = crate::plan::tool_lever_arms(machine, &program, &axis_map);
    let source = program.source.clone();
    PlannedProgram::new(program, axis_map, settings).map_err(|source_error| RunError::Plan {
        path: source,
        source: source_error,
    })
}

/// How machine coordinates map onto `machine`'s axes: each axis's sign and home from the
/// drive file.
pub fn axis_map_for(s: &Scenario, machine: &Machine) -> Result<AxisMap, FileError> {
    AxisMap::new(machine).map_err(|e| FileError::new(&s.machine, None, e.to_string()))
}

/// What the plan of a scenario on a machine depends on: runs with equal keys run the same
/// setpoints (the program and its reading, the work offset, the planner and the servo period,
/// the machine's kinematic description and axes).
#[derive(Debug, Clone, PartialEq)]
pub struct PlanKey {
    source: ProgramSource,
    work_offset: [f64; 3],
    /// The planner's settings on this machine, or why there are none.
    settings: Result<PlanSettings, String>,
    urdf: PathBuf,
    /// Each axis: name, joint, sign, home.
    axes: Vec<(String, usize, i8, f64)>,
}

impl PlanKey {
    /// The key of `s`'s plan on `machine`.
    pub fn new(s: &Scenario, machine: &Machine) -> Self {
        PlanKey {
            source: s.program.source.clone(),
            work_offset: s.program.work_offset,
            settings: plan_settings(s, machine, s.planner.profile).map_err(|e| e.to_string()),
            urdf: machine.urdf_path.clone(),
            axes: machine
                .axes
                .iter()
                .map(|a| (a.name.clone(), a.joint, a.drive.sign, a.drive.home))
                .collect(),
        }
    }
}

/// The scenario's machine with its `[mechanics]`, `[feedback]` and `[actuator]` choices
/// applied.
pub fn machine_for(s: &Scenario) -> Result<Machine, RunError> {
    Ok(with_choices(s, Machine::load(&s.machine)?))
}

/// `machine` with the scenario's `[mechanics]`, `[feedback]` and `[actuator]` choices applied.
pub fn with_choices(s: &Scenario, mut machine: Machine) -> Machine {
    apply_choices(s, &mut machine);
    machine
}

fn apply_choices(s: &Scenario, machine: &mut Machine) {
    for axis in &mut machine.axes {
        if let Some(t) = s.mechanics.transmission.get(&axis.name) {
            axis.drive.set_compliance(Some(t.compliance));
        }
        if !s.mechanics.compliance {
            axis.drive.set_compliance(None);
        }
    }
    keep_mechanics(machine, s.mechanics.friction, s.mechanics.backlash);
    for axis in &mut machine.axes {
        if let Some(feedback) = s.feedback.position {
            axis.drive.feedback = feedback;
        }
        if let Some(mode) = s.actuator.and_then(|a| a.amplifier_mode) {
            axis.drive.amplifier_mode = mode;
        }
    }
}

/// Removes the guides' friction (`friction = false`) and the transmissions' backlash
/// (`backlash = false`) from every axis of `machine`; with both false, its linear part.
pub fn keep_mechanics(machine: &mut Machine, friction: bool, backlash: bool) {
    for axis in &mut machine.axes {
        if !friction {
            axis.drive.guide = None;
        }
        if !backlash {
            axis.drive.backlash = 0.0;
        }
    }
}

/// Refuses a run longer than the loop's bounds, before it starts, with the number it needs.
pub(crate) fn check_run_length(s: &Scenario, samples: usize) -> Result<(), FileError> {
    let settle = (s.timing.settle_time / s.timing.servo_period).round() as u64;
    let ticks = settle + samples as u64;
    let steps = ticks.saturating_mul(s.timing.substeps as u64);
    let what = format!(
        "settle {:?} s + program {:.6} s at a servo period of {:?} ms",
        s.timing.settle_time,
        samples.saturating_sub(1) as f64 * s.timing.servo_period,
        s.timing.servo_period * 1e3
    );
    if ticks > MAX_SERVO_TICKS {
        return Err(FileError::new(
            &s.path,
            None,
            format!("the run needs {ticks} servo ticks ({what}): the limit is {MAX_SERVO_TICKS}"),
        ));
    }
    if steps > MAX_PHYSICS_STEPS {
        return Err(FileError::new(
            &s.path,
            None,
            format!(
                "the run needs {steps} physics steps ({ticks} ticks of {} steps; {what}): the limit is {MAX_PHYSICS_STEPS}",
                s.timing.substeps
            ),
        ));
    }
    Ok(())
}

/// The planner settings of a scenario for its machine, with `profile` (the scenario's own or
/// a command-line override); limits are converted to SI per axis kind.
pub fn plan_settings(
    s: &Scenario,
    machine: &Machine,
    profile: super::ProfileName,
) -> Result<PlanSettings, FileError> {
    use super::ProfileName;
    let p = &s.planner;
    let planner = match profile {
        ProfileName::ConstantVelocity => Planner::ConstantVelocity,
        ProfileName::Trapezoid => Planner::Trapezoid {
            acceleration: p.acceleration.ok_or_else(|| {
                FileError::new(
                    &s.path,
                    p.at,
                    "the trapezoid profile needs [planner] acceleration_mm_s2",
                )
            })?,
        },
        ProfileName::JerkLimited => {
            for (axis, (_, place)) in &p.limits {
                if machine.axis_index(axis).is_none() {
                    return Err(FileError::new(
                        &s.path,
                        *place,
                        format!(
                            "planner.limits.{axis}: the machine '{}' has no axis '{axis}'",
                            machine.name
                        ),
                    ));
                }
            }
            let limits = machine
                .axes
                .iter()
                .map(|a| {
                    let ([v, acc, j], _) = p.limits.get(&a.name).ok_or_else(|| {
                        FileError::new(&s.path, p.at, format!("the jerk-limited profile needs planner.limits.{} (velocity, acceleration, jerk in mm or deg units)", a.name))
                    })?;
                    let kind = if a.is_rotary(machine) { AxisKind::Rotary } else { AxisKind::Linear };
                    Ok(AxisLimits::from_program_units(kind, *v, *acc, *j))
                })
                .collect::<Result<_, FileError>>()?;
            Planner::JerkLimited { limits }
        }
    };
    Ok(PlanSettings {
        planner,
        period: s.timing.servo_period,
        rapid_speed: s.planner.rapid_speed,
        blend: s.planner.blend,
        axis_names: machine.axes.iter().map(|a| a.name.clone()).collect(),
        naive_cam_tolerance: s.planner.naive_cam_tolerance,
        tool_lever_arms: Vec::new(),
    })
}

/// Reads the scenario's program (built-in path or file) and checks it against the machine.
pub fn load_checked_program(s: &Scenario, machine: &Machine) -> Result<Program, RunError> {
    // Program coordinates become machine coordinates under the work offset: G-code starts
    // with it as its G54 origin, every other program is moved by it.
    let mut program = match &s.program.source {
        ProgramSource::Circle(c) => circle(c, &s.path),
        ProgramSource::Polyline(p) => polyline(p, &s.path),
        // Built in machine coordinates: its centre is placed (and the work offset applied)
        // where the test is fitted into the travel.
        ProgramSource::Ballbar(b) => {
            let centre = super::ballbar::ballbar_centre(s, machine, b.radius, b.plane, b.centre)?;
            super::ballbar::ballbar_program(centre, b.radius, b.feed, b.plane, b.overshoot, &s.path)
        }
        ProgramSource::File { path, options } => {
            let options = crate::program::ReadOptions {
                work_offset: s.program.work_offset,
                ..(**options).clone()
            };
            read_program(path, &options).map_err(RunError::Program)?
        }
    };
    if !matches!(
        s.program.source,
        ProgramSource::File { .. } | ProgramSource::Ballbar(_)
    ) {
        program.shift(s.program.work_offset);
    }
    if program.moves.is_empty() {
        return Err(FileError::new(
            &program.source,
            None,
            "the program has no moves: there is nothing to plan or run",
        )
        .into());
    }
    let cl_data = program.moves.iter().any(|m| m.tool_axis.is_some());
    if cl_data {
        program = cl_on_the_axes(s, machine, program)?;
    } else if let ProgramKinematics::ToolTip { tolerance } = s.program.kinematics {
        let kinematics = five_axis(
            s,
            machine,
            PartFrame::Program,
            "kinematics = \"tcp\" reads X Y Z as the tool tip on the part",
        )?;
        program = tcp_to_machine(&kinematics, &program, tolerance).map_err(RunError::Program)?;
    }
    check_program_axes(&program, machine)?;
    Ok(program)
}

/// Cutter-location data (tool tip and axis on the workpiece link) on the machine's axes,
/// from every axis at home: by the A-C table's closed form where the machine is one (in joint
/// coordinates: no sign or home on top), else by the kinematics of its chain.
fn cl_on_the_axes(s: &Scenario, machine: &Machine, program: Program) -> Result<Program, RunError> {
    if s.program.work_offset != [0.0; 3] {
        return Err(FileError::new(
            &program.source,
            None,
            "the program gives tool-axis vectors (CL data), whose coordinates are the workpiece link's, but the scenario sets [program] work_offset_mm: remove it for this program",
        )
        .into());
    }
    let plain = machine
        .axes
        .iter()
        .all(|a| a.drive.sign == 1 && a.drive.home == 0.0);
    if let (true, Ok(closed)) = (plain, AcTableKinematics::new(machine)) {
        return closed
            .program_to_machine(&program, &AcAxes::default())
            .map_err(RunError::Program);
    }
    let kinematics = five_axis(
        s,
        machine,
        PartFrame::WorkpieceLink,
        "the program gives tool-axis vectors (CL data)",
    )?;
    cl_to_machine(&kinematics, &program).map_err(RunError::Program)
}

/// The five-axis kinematics of `machine`; where it has none, the error says what asked for it.
fn five_axis(
    s: &Scenario,
    machine: &Machine,
    part: PartFrame,
    asker: &str,
) -> Result<FiveAxisKinematics, RunError> {
    let (frame, _) = ProgramFrame::new(machine)?;
    let map = AxisMap::new(machine)
        .map_err(|e| FileError::new(&machine.urdf_path, None, e.to_string()))?;
    FiveAxisKinematics::new(machine, &frame, &map, part).map_err(|e| {
        let (file, at) = match part {
            PartFrame::Program => (&s.path, s.program.kinematics_at),
            PartFrame::WorkpieceLink => (&s.path, s.program.at),
        };
        FileError::new(file, at, format!("{asker}: {e}")).into()
    })
}

/// A program may only move axes the machine has.
fn check_program_axes(program: &Program, machine: &Machine) -> Result<(), FileError> {
    let mut at = program.start;
    for m in &program.moves {
        for (name, linear, i) in crate::kinematics::PROGRAM_LETTERS {
            let (from, to) = if linear {
                (at.linear[i], m.end.linear[i])
            } else {
                (at.rotary[i], m.end.rotary[i])
            };
            if from != to && machine.axis_index(name).is_none() {
                let place = Some(LineColumn {
                    line: m.span.line as usize,
                    column: m.span.column as usize,
                });
                return Err(FileError::new(
                    &program.source,
                    place,
                    format!(
                        "this move drives axis {}, which the machine '{}' does not have",
                        name.to_uppercase(),
                        machine.name
                    ),
                ));
            }
        }
        at = m.end;
    }
    Ok(())
}
