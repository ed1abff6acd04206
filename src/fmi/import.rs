//! A co-simulation FMU as cncsim's controller: unpacked and loaded once per scenario
//! ([`FmuModel`]), one instance per lane and run ([`FmuController`]), stepped once per servo
//! period.

use super::binding::{Api, FmuInstance};
use super::description::{Causality, ModelDescription, Quantity};
use crate::control::{ActuatorKind, Controller, ControllerInput};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The folder of this platform's binaries in an FMU, per FMI version.
fn platform_folder(fmi3: bool) -> Option<&'static str> {
    use std::env::consts::{ARCH, OS};
    Some(match (OS, ARCH, fmi3) {
        ("linux", "x86_64", true) => "x86_64-linux",
        ("linux", "aarch64", true) => "aarch64-linux",
        ("linux", "x86_64", false) => "linux64",
        ("macos", "x86_64", true) => "x86_64-darwin",
        ("macos", "aarch64", true) => "aarch64-darwin",
        ("macos", _, false) => "darwin64",
        ("windows", "x86_64", true) => "x86_64-windows",
        ("windows", "x86_64", false) => "win64",
        _ => return None,
    })
}

/// Unpacks the zip archive `fmu` into `into`.
pub fn unpack(fmu: &Path, into: &Path) -> Result<(), String> {
    let file = std::fs::File::open(fmu).map_err(|e| format!("cannot open it: {e}"))?;
    let mut archive =
        zip::ZipArchive::new(file).map_err(|e| format!("not an FMU (not a zip archive: {e})"))?;
    archive
        .extract(into)
        .map_err(|e| format!("cannot unpack it: {e}"))
}

/// What the controller exchanges with the FMU for one machine axis: value references.
#[derive(Debug, Clone, Default)]
struct AxisPorts {
    setpoint_position: u32,
    measured_position: u32,
    setpoint_velocity: Option<u32>,
    setpoint_acceleration: Option<u32>,
    measured_velocity: Option<u32>,
    motor_position: Option<u32>,
    command: u32,
}

/// The signals cncsim offers a controller FMU, per axis (`<a>` the axis name in lower case),
/// with whether the FMU must have them.
const INPUTS: [(&str, bool); 6] = [
    ("setpoint_position", true),
    ("measured_position", true),
    ("setpoint_velocity", false),
    ("setpoint_acceleration", false),
    ("measured_velocity", false),
    ("motor_position", false),
];

/// How a scenario asks for a controller FMU.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FmuRequest {
    /// The FMU file.
    pub path: PathBuf,
    /// Start values of the FMU's parameters, by variable name.
    pub parameters: BTreeMap<String, f64>,
    /// cncsim's name of a signal → the FMU's variable name, where they differ.
    pub variables: BTreeMap<String, String>,
}

/// The machine a controller FMU is connected to.
#[derive(Debug, Clone)]
pub struct AxesSpec {
    /// Axis names as the scenario writes them.
    pub names: Vec<String>,
    /// Per axis, whether it is rotary (its signals in rad, else in m).
    pub rotary: Vec<bool>,
    /// What the commands are (V at the amplifier input, or N·m).
    pub actuator: ActuatorKind,
    /// Servo period (s): the FMU's communication step.
    pub servo_period: f64,
}

/// A controller FMU unpacked, loaded and checked against the machine: every lane's
/// controller is an instance of it.
pub struct FmuModel {
    /// The FMU file (for messages).
    pub path: PathBuf,
    /// The FMU's model description.
    pub description: ModelDescription,
    api: Arc<Api>,
    /// The unpacked FMU (removed when the model is dropped).
    dir: tempfile::TempDir,
    ports: Vec<AxisPorts>,
    parameters: Vec<(u32, f64)>,
    period: f64,
}

impl std::fmt::Debug for FmuModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FmuModel")
            .field("path", &self.path)
            .field("model", &self.description.model_name)
            .finish()
    }
}

impl FmuModel {
    /// Unpacks `request.path`, reads its model description, maps its variables onto the
    /// machine's axes and loads its binary. Errors name the variable at fault; the caller
    /// names the FMU.
    pub fn load(request: &FmuRequest, axes: &AxesSpec) -> Result<FmuModel, String> {
        let dir = tempfile::Builder::new()
            .prefix("cncsim-fmu-")
            .tempdir()
            .map_err(|e| format!("cannot make a folder to unpack it: {e}"))?;
        unpack(&request.path, dir.path())?;
        let xml_path = dir.path().join("modelDescription.xml");
        let xml = std::fs::read_to_string(&xml_path)
            .map_err(|_| "not an FMU: it has no modelDescription.xml".to_string())?;
        let description = ModelDescription::parse(&xml)?;
        let (ports, parameters) = map_variables(&description, request, axes)?;
        let fmi3 = description.version == super::FmiVersion::Fmi3;
        let folder = platform_folder(fmi3).ok_or_else(|| {
            format!(
                "cncsim cannot load FMU binaries on this platform ({}-{})",
                std::env::consts::ARCH,
                std::env::consts::OS
            )
        })?;
        let library = dir.path().join("binaries").join(folder).join(format!(
            "{}{}",
            description.model_identifier,
            std::env::consts::DLL_SUFFIX
        ));
        if !library.is_file() {
            let present: Vec<String> = std::fs::read_dir(dir.path().join("binaries"))
                .into_iter()
                .flatten()
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect();
            return Err(format!(
                "it has no binary for this platform: binaries/{folder}/{}{} is missing{}",
                description.model_identifier,
                std::env::consts::DLL_SUFFIX,
                if present.is_empty() {
                    " (it has no binaries at all; a source-only FMU must be compiled first)"
                        .to_string()
                } else {
                    format!(" (it has binaries for {})", present.join(", "))
                }
            ));
        }
        let api = Arc::new(Api::load(&library, description.version)?);
        Ok(FmuModel {
            path: request.path.clone(),
            description,
            api,
            dir,
            ports,
            parameters,
            period: axes.servo_period,
        })
    }

    /// A fresh instance, parameters set, initialised at its first step.
    pub fn instantiate(self: &Arc<Self>) -> Result<FmuController, String> {
        let instance = self.new_instance()?;
        let n = self.ports.len();
        let mut inputs = Vec::new();
        for p in &self.ports {
            inputs.push(p.setpoint_position);
            inputs.push(p.measured_position);
            inputs.extend(p.setpoint_velocity);
            inputs.extend(p.setpoint_acceleration);
            inputs.extend(p.measured_velocity);
            inputs.extend(p.motor_position);
        }
        let values = vec![0.0; inputs.len()];
        Ok(FmuController {
            model: Arc::clone(self),
            instance: Some(instance),
            initialized: false,
            input_references: inputs,
            input_values: values,
            output_references: self.ports.iter().map(|p| p.command).collect(),
            previous_measured: vec![f64::NAN; n],
            fault: None,
        })
    }

    fn new_instance(&self) -> Result<FmuInstance, String> {
        let mut instance = FmuInstance::new(
            Arc::clone(&self.api),
            &self.description.model_name,
            &self.description.token,
            &self.dir.path().join("resources"),
        )?;
        self.set_parameters(&mut instance)?;
        Ok(instance)
    }

    fn set_parameters(&self, instance: &mut FmuInstance) -> Result<(), String> {
        for (reference, value) in &self.parameters {
            instance.set(&[*reference], &[*value]).map_err(|e| {
                let name = self
                    .description
                    .variables
                    .iter()
                    .find(|v| v.value_reference == *reference)
                    .map_or("?", |v| v.name.as_str());
                format!("setting parameter '{name}' = {value:?}: {e}")
            })?;
        }
        Ok(())
    }
}

/// Parameter start values: value reference, value.
type Parameters = Vec<(u32, f64)>;

/// Checks the FMU's variables against what cncsim exchanges for `axes` and resolves their
/// value references.
fn map_variables(
    d: &ModelDescription,
    request: &FmuRequest,
    axes: &AxesSpec,
) -> Result<(Vec<AxisPorts>, Parameters), String> {
    // cncsim names of every signal it can exchange.
    let mut known: Vec<String> = Vec::new();
    for axis in &axes.names {
        let a = axis.to_lowercase();
        for (signal, _) in INPUTS {
            known.push(format!("{signal}_{a}"));
        }
        known.push(format!("command_{a}"));
    }
    for key in request.variables.keys() {
        if !known.contains(key) {
            return Err(format!(
                "controller.variables.{key}: cncsim has no signal '{key}' for this machine (it has {})",
                known.join(", ")
            ));
        }
    }
    let fmu_name = |ours: &str| -> String {
        request
            .variables
            .get(ours)
            .cloned()
            .unwrap_or_else(|| ours.to_string())
    };
    let mut used_inputs: Vec<String> = Vec::new();
    let lookup = |ours: &str,
                  required: bool,
                  causality: Causality,
                  quantity: Quantity|
     -> Result<Option<u32>, String> {
        let name = fmu_name(ours);
        let Some(v) = d.variable(&name) else {
            return if required {
                Err(format!(
                    "it has no variable '{name}'{} (cncsim's {} {ours})",
                    if name != ours {
                        format!(", which controller.variables maps {ours} to")
                    } else {
                        String::new()
                    },
                    causality.name(),
                ))
            } else {
                Ok(None)
            };
        };
        if v.causality != causality {
            return Err(format!(
                "variable '{name}' has causality \"{}\"; as cncsim's {ours} it must be an {}",
                v.causality.name(),
                causality.name()
            ));
        }
        if !v.is_float64() {
            return Err(format!(
                "variable '{name}' is {}; cncsim exchanges 64-bit floats (Float64 / Real)",
                v.type_name
            ));
        }
        quantity
            .check(v.unit.as_deref(), d)
            .map_err(|e| format!("variable '{name}': {e}"))?;
        Ok(Some(v.value_reference))
    };
    let command_quantity = match axes.actuator {
        ActuatorKind::IdealTorque => Quantity::Torque,
        _ => Quantity::Voltage,
    };
    let mut ports = Vec::new();
    for (axis, rotary) in axes.names.iter().zip(&axes.rotary) {
        let a = axis.to_lowercase();
        let (pos, vel, acc) = if *rotary {
            (
                Quantity::Angle,
                Quantity::AngularVelocity,
                Quantity::AngularAcceleration,
            )
        } else {
            (Quantity::Length, Quantity::Velocity, Quantity::Acceleration)
        };
        let quantity = |signal: &str| match signal {
            "setpoint_velocity" | "measured_velocity" => vel,
            "setpoint_acceleration" => acc,
            _ => pos,
        };
        let mut refs = BTreeMap::new();
        for (signal, required) in INPUTS {
            let ours = format!("{signal}_{a}");
            let r = lookup(&ours, required, Causality::Input, quantity(signal))?;
            if r.is_some() {
                used_inputs.push(fmu_name(&ours));
            }
            refs.insert(signal, r);
        }
        let command = lookup(
            &format!("command_{a}"),
            true,
            Causality::Output,
            command_quantity,
        )?
        .expect("required");
        ports.push(AxisPorts {
            setpoint_position: refs["setpoint_position"].expect("required"),
            measured_position: refs["measured_position"].expect("required"),
            setpoint_velocity: refs["setpoint_velocity"],
            setpoint_acceleration: refs["setpoint_acceleration"],
            measured_velocity: refs["measured_velocity"],
            motor_position: refs["motor_position"],
            command,
        });
    }
    // Every input must be fed: an input cncsim does not know would stay at its start value.
    if let Some(v) = d
        .variables
        .iter()
        .find(|v| v.causality == Causality::Input && !used_inputs.contains(&v.name))
    {
        return Err(format!(
            "input '{}' is not a signal cncsim provides (per axis: {}; or map it with [controller.variables])",
            v.name,
            INPUTS
                .iter()
                .map(|(s, _)| format!("{s}_<axis>"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    let mut parameters = Vec::new();
    for (name, value) in &request.parameters {
        let v = d.variable(name).ok_or_else(|| {
            let names: Vec<&str> = d
                .variables
                .iter()
                .filter(|v| v.causality == Causality::Parameter)
                .map(|v| v.name.as_str())
                .collect();
            format!(
                "controller.parameters.{name}: the FMU has no variable '{name}' (its parameters: {})",
                if names.is_empty() {
                    "none".to_string()
                } else {
                    names.join(", ")
                }
            )
        })?;
        if v.causality != Causality::Parameter {
            return Err(format!(
                "controller.parameters.{name}: variable '{name}' has causality \"{}\", not a parameter",
                v.causality.name()
            ));
        }
        if !v.is_float64() {
            return Err(format!(
                "controller.parameters.{name}: variable '{name}' is {}; cncsim sets 64-bit float parameters",
                v.type_name
            ));
        }
        parameters.push((v.value_reference, *value));
    }
    Ok((ports, parameters))
}

/// One instance of a controller FMU as a [`Controller`]. A failing FMU call is kept as the
/// controller's [`fault`](Controller::fault); the loop stops the lane there.
pub struct FmuController {
    model: Arc<FmuModel>,
    instance: Option<FmuInstance>,
    initialized: bool,
    input_references: Vec<u32>,
    input_values: Vec<f64>,
    output_references: Vec<u32>,
    /// The measured positions of the previous tick (NaN before the first).
    previous_measured: Vec<f64>,
    fault: Option<String>,
}

impl FmuController {
    /// A controller whose instance could not be made: it fails at its first tick with `why`.
    pub fn broken(model: &Arc<FmuModel>, why: String) -> FmuController {
        FmuController {
            model: Arc::clone(model),
            instance: None,
            initialized: false,
            input_references: Vec::new(),
            input_values: Vec::new(),
            output_references: Vec::new(),
            previous_measured: Vec::new(),
            fault: Some(format!("controller FMU {}: {why}", model.path.display())),
        }
    }

    fn step(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) -> Result<(), String> {
        let instance = self
            .instance
            .as_mut()
            .ok_or("the FMU instance is gone after a failed reset")?;
        if !self.initialized {
            instance.initialize(input.time)?;
            self.initialized = true;
        }
        let period = self.model.period;
        let mut k = 0;
        for (i, p) in self.model.ports.iter().enumerate() {
            let mut put = |v: f64| {
                self.input_values[k] = v;
                k += 1;
            };
            put(input.setpoint_position[i]);
            put(input.measured_position[i]);
            if p.setpoint_velocity.is_some() {
                put(input.setpoint_velocity[i]);
            }
            if p.setpoint_acceleration.is_some() {
                put(input.setpoint_acceleration[i]);
            }
            if p.measured_velocity.is_some() {
                put(measured_velocity(
                    input.measured_position[i],
                    self.previous_measured[i],
                    period,
                ));
            }
            if p.motor_position.is_some() {
                put(input.motor_position[i]);
            }
        }
        self.previous_measured
            .copy_from_slice(input.measured_position);
        instance.set(&self.input_references, &self.input_values)?;
        instance.do_step(input.time, period)?;
        instance.get(&self.output_references, command)
    }
}

/// The measured velocity a controller FMU receives: the backward difference of the measured
/// position over the servo period, as a drive differentiates its encoder (zero at the first
/// tick, where the machine is at rest). The exported plant FMU computes the same.
pub fn measured_velocity(measured: f64, previous: f64, period: f64) -> f64 {
    if previous.is_nan() {
        0.0
    } else {
        (measured - previous) / period
    }
}

impl Controller for FmuController {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        if self.fault.is_some() {
            command.iter_mut().for_each(|c| *c = 0.0);
            return;
        }
        if let Err(e) = self.step(input, command) {
            command.iter_mut().for_each(|c| *c = 0.0);
            self.fault = Some(format!("controller FMU {}: {e}", self.model.path.display()));
        }
    }

    fn reset(&mut self) {
        self.previous_measured
            .iter_mut()
            .for_each(|p| *p = f64::NAN);
        self.initialized = false;
        self.fault = None;
        let Some(instance) = self.instance.as_mut() else {
            return;
        };
        let reset = instance
            .reset()
            .and_then(|()| self.model.set_parameters(instance));
        if let Err(e) = reset {
            self.fault = Some(format!(
                "controller FMU {}: reset: {e}",
                self.model.path.display()
            ));
        }
    }

    fn fault(&self) -> Option<&str> {
        self.fault.as_deref()
    }
}
