//! The scenario's plant as an FMU sees it: the Rapier machine with its drives, stepped one
//! servo period per `doStep` exactly as the servo loop steps it ([`sim::sense`] at the start of
//! every period, [`sim::Plant::hold`] over it), with the scenario's planned setpoints as
//! outputs. The `cncsim-fmu` crate (fmu/) wraps it in FMI 3.0's C interface; `cncsim
//! export-fmu` writes its model description from [`variables`].

use crate::control::ActuatorKind;
use crate::plan::SetpointSample;
use crate::scenario::{Assembly, Scenario};
use crate::sim::{self, Hold, LoopSettings, Plant, Sensors};
use std::path::Path;

/// The scenario file inside the FMU's `resources/`.
pub const SCENARIO_FILE: &str = "scenario.toml";

/// The value reference of the independent variable `time`.
pub const TIME_REFERENCE: u32 = 0;

/// One signal of the plant FMU, per axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Signal {
    /// Input: the controller's command (V at the amplifier input, or N·m).
    Command,
    /// Output: the planned position setpoint of the tick (m or rad).
    SetpointPosition,
    /// Output: the planned velocity setpoint of the tick (m/s or rad/s).
    SetpointVelocity,
    /// Output: the planned acceleration setpoint of the tick (m/s² or rad/s²).
    SetpointAcceleration,
    /// The position the loop closes on, after the encoder.
    MeasuredPosition,
    /// Backward difference of the measured position over the servo period.
    MeasuredVelocity,
    /// The motor encoder (drive side of any backlash), after the encoder.
    MotorPosition,
    /// The carriage (load side), exact.
    CarriagePosition,
    /// The carriage's velocity (load side), exact.
    CarriageVelocity,
}

impl Signal {
    /// Every signal, in value-reference order within an axis.
    pub const ALL: [Signal; 9] = [
        Signal::Command,
        Signal::SetpointPosition,
        Signal::SetpointVelocity,
        Signal::SetpointAcceleration,
        Signal::MeasuredPosition,
        Signal::MeasuredVelocity,
        Signal::MotorPosition,
        Signal::CarriagePosition,
        Signal::CarriageVelocity,
    ];

    /// The variable name's stem (`<stem>_<axis>`).
    pub fn stem(self) -> &'static str {
        match self {
            Signal::Command => "command",
            Signal::SetpointPosition => "setpoint_position",
            Signal::SetpointVelocity => "setpoint_velocity",
            Signal::SetpointAcceleration => "setpoint_acceleration",
            Signal::MeasuredPosition => "measured_position",
            Signal::MeasuredVelocity => "measured_velocity",
            Signal::MotorPosition => "motor_position",
            Signal::CarriagePosition => "carriage_position",
            Signal::CarriageVelocity => "carriage_velocity",
        }
    }

    /// Its SI unit on a linear or rotary axis, with `actuator` deciding the command's.
    pub fn unit(self, rotary: bool, actuator: ActuatorKind) -> &'static str {
        use Signal::*;
        match (self, rotary) {
            (Command, _) if actuator == ActuatorKind::IdealTorque => "N.m",
            (Command, _) => "V",
            (SetpointVelocity | MeasuredVelocity | CarriageVelocity, false) => "m/s",
            (SetpointVelocity | MeasuredVelocity | CarriageVelocity, true) => "rad/s",
            (SetpointAcceleration, false) => "m/s2",
            (SetpointAcceleration, true) => "rad/s2",
            (_, false) => "m",
            (_, true) => "rad",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Signal::Command => "controller command, held over the servo period",
            Signal::SetpointPosition => "planned position setpoint of the tick",
            Signal::SetpointVelocity => "planned velocity setpoint of the tick",
            Signal::SetpointAcceleration => "planned acceleration setpoint of the tick",
            Signal::MeasuredPosition => "position the position loop closes on, after the encoder",
            Signal::MeasuredVelocity => {
                "backward difference of the measured position over the servo period"
            }
            Signal::MotorPosition => "motor encoder position (drive side), joint units",
            Signal::CarriagePosition => "carriage (load side) position, exact",
            Signal::CarriageVelocity => "carriage (load side) velocity, exact",
        }
    }
}

/// One variable of the plant FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantVariable {
    /// The variable's name: `<stem>_<axis>` in lower case, or `program_time`.
    pub name: String,
    /// Its FMI value reference (counted from 1, after `time`).
    pub value_reference: u32,
    /// `None`: `program_time`.
    pub signal: Option<(usize, Signal)>,
    /// The SI unit as FMI writes unit names (`m`, `m/s2`, `N.m`, `s`, …).
    pub unit: &'static str,
    /// The human-readable description written into the model description.
    pub description: String,
}

impl PlantVariable {
    /// Whether the master sets this variable: only the axes' commands are inputs.
    pub fn is_input(&self) -> bool {
        matches!(self.signal, Some((_, Signal::Command)))
    }
}

/// The plant FMU's variables after `time` (value reference 0): every signal of every axis,
/// then `program_time`. Names use the axis names in lower case.
pub fn variables(axes: &[(String, bool)], actuator: ActuatorKind) -> Vec<PlantVariable> {
    let mut out = Vec::new();
    let mut reference = TIME_REFERENCE + 1;
    for (i, (name, rotary)) in axes.iter().enumerate() {
        for signal in Signal::ALL {
            out.push(PlantVariable {
                name: format!("{}_{}", signal.stem(), name.to_lowercase()),
                value_reference: reference,
                signal: Some((i, signal)),
                unit: signal.unit(*rotary, actuator),
                description: format!("axis {name}: {}", signal.description()),
            });
            reference += 1;
        }
    }
    out.push(PlantVariable {
        name: "program_time".into(),
        value_reference: reference,
        signal: None,
        unit: "s",
        description: "time from the program's first setpoint (negative while the machine settles and approaches)".into(),
    });
    out
}

/// The setpoint of every servo tick of the scenario's run (settle, approach, program), with
/// its time, as the servo loop visits them ([`sim::for_each_tick`]).
pub fn tick_setpoints(assembly: &Assembly) -> (Vec<f64>, Vec<SetpointSample>) {
    let (mut times, mut samples) = (Vec::new(), Vec::new());
    sim::for_each_tick(
        &assembly.loop_settings,
        &mut *assembly.setpoints(),
        &mut |time, sample, _| {
            times.push(time);
            samples.push(sample.clone());
            true
        },
    );
    (times, samples)
}

/// The plant of a scenario, stepped one servo period at a time.
pub struct PlantModel {
    settings: LoopSettings,
    plant: sim::PhysicsPlant,
    /// Axis names and whether rotary.
    axes: Vec<(String, bool)>,
    actuator: ActuatorKind,
    period: f64,
    times: Vec<f64>,
    setpoints: Vec<SetpointSample>,
    /// The tick the outputs are of (the last one held after the setpoints end).
    tick: usize,
    /// Program time of the outputs.
    time: f64,
    sensors: Sensors,
    measured: Vec<f64>,
    motor: Vec<f64>,
    measured_velocity: Vec<f64>,
    /// The measured positions of the tick before (scratch: nothing is allocated per step).
    previous_measured: Vec<f64>,
    command: Vec<f64>,
    hold: Hold,
}

impl PlantModel {
    /// Loads the scenario in `resources/` and puts the machine at rest where it starts.
    pub fn load(resources: &Path) -> Result<PlantModel, String> {
        let scenario = Scenario::load(&resources.join(SCENARIO_FILE)).map_err(|e| e.to_string())?;
        let assembly = Assembly::new(&scenario).map_err(|e| e.to_string())?;
        Self::new(&assembly)
    }

    /// The plant of an assembled scenario, at rest where the machine starts, sampled at its
    /// first tick.
    pub fn new(assembly: &Assembly) -> Result<PlantModel, String> {
        let plant = assembly
            .physics_plant(&assembly.start())
            .map_err(|e| e.to_string())?;
        let (times, setpoints) = tick_setpoints(assembly);
        if setpoints.is_empty() {
            return Err("the scenario's program has no setpoints".into());
        }
        let n = plant.axes();
        let axes = assembly
            .labels
            .iter()
            .map(|l| (l.name.clone(), l.rotary))
            .collect();
        let mut model = PlantModel {
            settings: assembly.loop_settings.clone(),
            plant,
            axes,
            actuator: assembly.actuator,
            period: assembly.scenario.timing.servo_period,
            time: times[0],
            times,
            setpoints,
            tick: 0,
            sensors: Sensors::new(n),
            measured: vec![0.0; n],
            motor: vec![0.0; n],
            measured_velocity: vec![0.0; n],
            previous_measured: vec![0.0; n],
            command: vec![0.0; n],
            hold: Hold::new(n),
        };
        model.sense().map_err(|e| e.to_string())?;
        Ok(model)
    }

    /// Axis names and whether each is rotary.
    pub fn axes(&self) -> &[(String, bool)] {
        &self.axes
    }

    /// What the commands are.
    pub fn actuator(&self) -> ActuatorKind {
        self.actuator
    }

    /// The servo period (s): every step is one.
    pub fn period(&self) -> f64 {
        self.period
    }

    /// Servo ticks of the whole run (settle, approach, program).
    pub fn ticks(&self) -> usize {
        self.setpoints.len()
    }

    /// Program time of the first tick (s; negative with a settle or an approach).
    pub fn start_time(&self) -> f64 {
        self.times[0]
    }

    fn sense(&mut self) -> Result<(), sim::Stop> {
        self.previous_measured.copy_from_slice(&self.measured);
        let sp = &self.setpoints[self.tick.min(self.setpoints.len() - 1)];
        sim::sense(
            &self.settings,
            &mut self.plant,
            self.time,
            &sp.position,
            &mut self.sensors,
            &mut self.measured,
            &mut self.motor,
        )?;
        let first = self.tick == 0;
        for ((v, m), p) in self
            .measured_velocity
            .iter_mut()
            .zip(&self.measured)
            .zip(&self.previous_measured)
        {
            *v = super::measured_velocity(*m, if first { f64::NAN } else { *p }, self.period);
        }
        Ok(())
    }

    /// Holds the commands over one servo period and samples the next tick. A divergence or a
    /// following-error trip is an error saying where; the plant cannot go on after it.
    pub fn step(&mut self) -> Result<(), String> {
        self.plant.hold(&self.command, &mut self.hold);
        self.tick += 1;
        self.time = match self.times.get(self.tick) {
            Some(t) => *t,
            // After the program: the last setpoint held, time going on.
            None => self.time + self.period,
        };
        self.sense().map_err(|e| e.to_string())
    }

    /// The value of variable `reference` (see [`variables`]), or `None` if there is none.
    pub fn get(&self, reference: u32) -> Option<f64> {
        if reference == TIME_REFERENCE {
            return Some(self.time);
        }
        let per_axis = Signal::ALL.len();
        let index = (reference - 1) as usize;
        if index == per_axis * self.axes.len() {
            return Some(self.time);
        }
        if index > per_axis * self.axes.len() {
            return None;
        }
        let (axis, signal) = (index / per_axis, Signal::ALL[index % per_axis]);
        let sp = &self.setpoints[self.tick.min(self.setpoints.len() - 1)];
        Some(match signal {
            Signal::Command => self.command[axis],
            Signal::SetpointPosition => sp.position[axis],
            Signal::SetpointVelocity => sp.velocity[axis],
            Signal::SetpointAcceleration => sp.acceleration[axis],
            Signal::MeasuredPosition => self.measured[axis],
            Signal::MeasuredVelocity => self.measured_velocity[axis],
            Signal::MotorPosition => self.motor[axis],
            Signal::CarriagePosition => self.sensors.position[axis],
            Signal::CarriageVelocity => self.sensors.velocity[axis],
        })
    }

    /// Sets input `reference` (a command); `false` if it is not an input.
    pub fn set(&mut self, reference: u32, value: f64) -> bool {
        let per_axis = Signal::ALL.len() as u32;
        if reference == TIME_REFERENCE || reference > per_axis * self.axes.len() as u32 {
            return false;
        }
        let index = reference - 1;
        if !index.is_multiple_of(per_axis) {
            return false;
        }
        self.command[(index / per_axis) as usize] = value;
        true
    }
}
