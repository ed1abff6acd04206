//! The scenario file format (TOML). Unknown keys are rejected; every value that can be wrong
//! is checked and reported with the file, line and column it came from. Each section is its
//! own type, built and checked from its raw form in its own module (`TryFrom`); [`Scenario::parse`]
//! puts them together. Numbers must lie in the ranges of [`limits`], which keep a run
//! physically meaningful and its work bounded. What depends on the machine (axis names, axis
//! kinds, metric names) is checked when the scenario is assembled on it.

mod actuation;
mod checks;
mod controller;
mod cutting;
mod frequency;
pub mod limits;
mod outputs;
mod planner;
mod program;
mod source;
mod timing;

pub use actuation::{
    ActuatorSettings, CompensationEntry, FeedbackSettings, Mechanics, TransmissionEntry,
};
pub use checks::{DeclaredVariants, Expectation};
pub use controller::{
    AxisCascade, AxisGains, CascadeTable, ControlSpace, ControllerSettings, ControllerType,
    FmuSettings, InverseDynamicsSettings, PidTable,
};
pub use frequency::FrequencyResponse;
pub use outputs::{AnalyticSettings, RecordingSettings};
pub use planner::{PlannerSettings, ProfileName};
pub use program::{Approach, ProgramKinematics, ProgramSettings, ProgramSource};
pub use timing::Timing;

use crate::diagnostics::{read_text, toml_error, FileError, LineColumn};
use serde::Deserialize;
use source::Source;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    #[serde(default)]
    description: String,
    machine: Spanned<String>,
    program: program::RawProgram,
    #[serde(default)]
    planner: planner::RawPlanner,
    timing: timing::RawTiming,
    /// Needed to run; a scenario used only for `cncsim plan` may leave these out.
    actuator: Option<actuation::RawActuator>,
    controller: Option<controller::RawController>,
    #[serde(default)]
    feedback: actuation::RawFeedback,
    #[serde(default)]
    mechanics: actuation::RawMechanics,
    #[serde(default)]
    recording: outputs::RawRecording,
    /// Backlash and friction compensation per axis.
    #[serde(default)]
    compensation: BTreeMap<String, Spanned<actuation::RawCompensation>>,
    /// Run the analytic reference model beside the physics.
    analytic: Option<outputs::RawAnalytic>,
    /// The stock, tool and material of a cut.
    cutting: Option<cutting::RawCutting>,
    /// Frequency-response measurements per axis, whose figures `[expect]` can bound.
    #[serde(default)]
    frequency_response: BTreeMap<String, Spanned<frequency::RawFrequencyResponse>>,
    #[serde(default)]
    expect: BTreeMap<String, Spanned<toml::Value>>,
    /// The variants `cncsim ab FILE` runs when no --a/--b overrides are given.
    ab: Option<Spanned<checks::RawAb>>,
}

/// A validated scenario: plain data, SI units, paths resolved against the scenario's folder.
/// Each field is one section of the file.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// The scenario's `name`, or else its file name without the extension.
    pub name: String,
    /// The scenario file it was read from.
    pub path: PathBuf,
    /// The free-text `description` (empty when not given).
    pub description: String,
    /// The machine's URDF (its drive file beside it).
    pub machine: PathBuf,
    /// Where the `machine` value is in the file.
    pub machine_at: Option<LineColumn>,
    /// `[program]`: what runs, and where (work offset, approach).
    pub program: ProgramSettings,
    /// `[planner]`: the motion profile and its parameters.
    pub planner: PlannerSettings,
    /// `[timing]`: servo period, physics substeps and solver iterations, settle time.
    pub timing: Timing,
    /// `None`: the scenario has no `[actuator]` (it can be planned, not run).
    pub actuator: Option<ActuatorSettings>,
    /// `None`: the scenario has no `[controller]` (it can be planned, not run).
    pub controller: Option<ControllerSettings>,
    /// `[feedback]`: position feedback, encoder resolution, following-error limits.
    pub feedback: FeedbackSettings,
    /// `[mechanics]`: which of the machine's friction, backlash and compliance the run keeps,
    /// and transmissions whose stiffness and damping it replaces.
    pub mechanics: Mechanics,
    /// Backlash and friction compensation per axis.
    pub compensation: BTreeMap<String, CompensationEntry>,
    /// `[recording]`: which files a run writes, and every how many ticks.
    pub recording: RecordingSettings,
    /// The analytic reference model beside the physics; `None` = not run.
    pub analytic: Option<AnalyticSettings>,
    /// `[cutting]`: the stock the tool removes, the tool and the material; `None` = the tool
    /// cuts air.
    pub cutting: Option<crate::cutting::CuttingSpec>,
    /// `[expect]`: the bounds on the run's metrics, each flattened to its dotted metric path.
    pub expect: Vec<Expectation>,
    /// `[frequency_response.<axis>]`: measurements a run makes after its program (by axis
    /// name).
    pub frequency_response: Vec<FrequencyResponse>,
    /// `[ab]`: the variants `cncsim ab` runs on this file alone.
    pub ab: Option<DeclaredVariants>,
    /// Values that are legal but look wrong, located in the file.
    pub warnings: Vec<FileError>,
    /// The files the scenario names (machine, program, tool table, FMU, stock …), resolved
    /// against its folder: with the machine's own files, what a run reads.
    pub files: Vec<PathBuf>,
}

impl Scenario {
    /// Reads and checks the scenario file at `path` (a URDF or xacro is refused with a hint).
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

    /// Checks a scenario's `text`, read from `path` (against whose folder its paths resolve;
    /// the machine named must exist).
    pub fn parse(path: &Path, text: &str) -> Result<Scenario, FileError> {
        let raw: RawScenario = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        let file = Source::new(path, text);
        // The machine must exist (its contents are checked when it is loaded).
        let machine = file.resolve(raw.machine.get_ref());
        if !machine.is_file() {
            return Err(file.error(
                raw.machine.span(),
                format!(
                    "machine model '{}' not found (looked for {})",
                    raw.machine.get_ref(),
                    machine.display()
                ),
            ));
        }
        let actuator = match &raw.actuator {
            Some(a) => Some(ActuatorSettings::try_from(file.section(a))?),
            None => None,
        };
        let program = ProgramSettings::try_from(file.section(&raw.program))?;
        let timing = Timing::try_from(file.section(&raw.timing))?;
        let controller = match &raw.controller {
            Some(c) => Some(ControllerSettings::try_from(file.section(c))?),
            None => None,
        };
        // The command filters of a cascade are discrete at the servo period.
        for (axis, c) in controller.iter().flat_map(|c| &c.cascade.axes) {
            crate::control::filters::check_filters(&c.settings.filters, timing.servo_period)
                .map_err(|m| file.error_at(c.at, format!("controller.cascade.{axis}: {m}")))?;
        }
        let mut compensation = BTreeMap::new();
        for (axis, entry) in &raw.compensation {
            let entry = actuation::AxisEntry { axis, entry };
            compensation.insert(
                axis.clone(),
                CompensationEntry::try_from(file.section(entry))?,
            );
        }
        let feedback = FeedbackSettings::try_from(file.section(&raw.feedback))?;
        let mechanics = Mechanics::try_from(file.section(&raw.mechanics))?;
        let recording = RecordingSettings::try_from(file.section(&raw.recording))?;
        let planner = PlannerSettings::try_from(file.section(&raw.planner))?;
        let analytic = match &raw.analytic {
            Some(a) => AnalyticSettings::from_raw(file.section(a))?,
            None => None,
        };
        let cutting = match &raw.cutting {
            Some(c) => Some(crate::cutting::CuttingSpec::try_from(file.section(c))?),
            None => None,
        };
        let ab = match &raw.ab {
            Some(table) => Some(DeclaredVariants::try_from(file.section(table))?),
            None => None,
        };
        let expect = checks::Expectations::try_from(file.section(&raw.expect))?.0;
        let mut frequency_response = Vec::new();
        for (axis, table) in &raw.frequency_response {
            let entry =
                FrequencyResponse::try_from(file.section(frequency::AxisTable { axis, table }))?;
            let nyquist = 0.5 / timing.servo_period;
            if let Some(to) = entry.to_hz.filter(|&f| f >= nyquist) {
                return Err(file.error(
                    table.span(),
                    format!("frequency_response.{axis}: to_hz = {to} is at or above the Nyquist frequency {nyquist} Hz of the servo period"),
                ));
            }
            frequency_response.push(entry);
        }
        let machine_at = file.at(raw.machine.span().start);
        let (warnings, files) = file.into_warnings_and_files();
        Ok(Scenario {
            name: raw.name.unwrap_or_else(|| {
                path.file_stem()
                    .map_or("scenario".into(), |s| s.to_string_lossy().into_owned())
            }),
            path: path.to_path_buf(),
            description: raw.description,
            machine,
            machine_at,
            program,
            planner,
            timing,
            actuator,
            controller,
            feedback,
            mechanics,
            compensation,
            recording,
            analytic,
            cutting,
            expect,
            frequency_response,
            ab,
            warnings,
            files,
        })
    }

    /// The untraced approach to the program's first point, where one is asked for: from where
    /// (m), at what speed (m/s; the planner's rapid speed unless given).
    pub fn approach(&self) -> Option<Approach> {
        self.program.approach_from.map(|from| Approach {
            from,
            speed: self
                .program
                .approach_speed
                .unwrap_or(self.planner.rapid_speed),
        })
    }

    /// The controller type that runs, if any.
    pub fn controller_type(&self) -> Option<ControllerType> {
        self.controller.as_ref().map(|c| c.kind)
    }
}

impl Scenario {
    /// Moves every recorded file position through `f` (`None`: the place no longer exists in
    /// the file, e.g. a line an override wrote).
    pub(crate) fn map_positions(&mut self, f: &dyn Fn(LineColumn) -> Option<LineColumn>) {
        let map = |at: &mut Option<LineColumn>| *at = at.and_then(f);
        map(&mut self.machine_at);
        map(&mut self.planner.at);
        map(&mut self.program.at);
        for w in &mut self.warnings {
            map(&mut w.at);
        }
        for (_, at) in self.planner.limits.values_mut() {
            map(at);
        }
        if let Some(c) = &mut self.controller {
            map(&mut c.at);
            map(&mut c.pid.at);
            map(&mut c.cascade.at);
            if let Some(f) = &mut c.fmu {
                map(&mut f.at);
            }
            for g in c.pid.axes.values_mut() {
                map(&mut g.at);
            }
            for a in c.cascade.axes.values_mut() {
                map(&mut a.at);
            }
        }
        for c in self.compensation.values_mut() {
            map(&mut c.at);
        }
        for (_, at) in self.feedback.encoder_counts_per_rev.values_mut() {
            map(at);
        }
        for f in &mut self.frequency_response {
            map(&mut f.at);
        }
        for e in &mut self.expect {
            map(&mut e.at);
        }
        if let Some(ab) = &mut self.ab {
            map(&mut ab.at);
        }
    }
}
