//! The plant as the servo loop sees it: a block with one input port (the commands held over a
//! servo period) and one output port (the sensors sampled at the start of a period). The
//! Rapier machine ([`super::PhysicsPlant`]) and the analytic axis models
//! ([`super::AnalyticPlant`]) are its two implementations, so everything the loop does
//! (encoder, trip, controller, compensation, recording) applies to both alike.

/// What the plant's sensors show at the start of a servo period, per machine axis in joint
/// units (m or rad) unless the name says otherwise.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Sensors {
    /// Carriage (load-side) position: what the tool does.
    pub position: Vec<f64>,
    /// Carriage (load-side) velocity (m/s or rad/s).
    pub velocity: Vec<f64>,
    /// Drive-side position (motor angle over the ratio); equals `position` without backlash.
    pub drive_position: Vec<f64>,
    /// What the feedback device sees, before encoder rounding: the drive side for a motor
    /// encoder, the carriage for a linear scale.
    pub feedback_position: Vec<f64>,
    /// Armature current (A).
    pub current: Vec<f64>,
    /// Tool point and its velocity in the machine base frame (m, m/s).
    pub tool_point: [f64; 3],
    /// Velocity of the tool point in the machine base frame (m/s).
    pub tool_velocity: [f64; 3],
}

impl Sensors {
    /// Zeroed sensors for `axes` axes.
    pub fn new(axes: usize) -> Sensors {
        let z = || vec![0.0; axes];
        Sensors {
            position: z(),
            velocity: z(),
            drive_position: z(),
            feedback_position: z(),
            current: z(),
            tool_point: [0.0; 3],
            tool_velocity: [0.0; 3],
        }
    }
}

/// What the actuators did over one servo period, per axis.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Hold {
    /// Mean motor torque over the period (N·m).
    pub mean_torque: Vec<f64>,
    /// Armature voltage (V); zero for the ideal torque actuator.
    pub voltage: Vec<f64>,
    /// What the cutting process did over the period (zeros for a plant that does not cut).
    pub cut: CutRecord,
}

/// What the cutting process did over one servo period.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CutRecord {
    /// Force of the tool on the part, mean over the period (N), in the stock's frame (the
    /// program frame at the program's start, carried by the part).
    pub force: [f64; 3],
    /// Largest |force| within the period (N).
    pub peak_force: f64,
    /// Spindle power, mean over the period (W).
    pub spindle_power: f64,
    /// Spindle torque, mean over the period (N·m).
    pub spindle_torque: f64,
    /// Most flutes engaged at once within the period.
    pub engaged_flutes: u32,
}

impl Hold {
    /// A zeroed hold record for `axes` axes.
    pub fn new(axes: usize) -> Hold {
        Hold {
            mean_torque: vec![0.0; axes],
            voltage: vec![0.0; axes],
            cut: CutRecord::default(),
        }
    }
}

/// A simulated machine driven by the servo loop.
pub trait Plant {
    /// Machine axes (the length of every per-axis vector in and out).
    fn axes(&self) -> usize;
    /// Samples the sensors (called at the start of every servo period).
    fn sample(&mut self, out: &mut Sensors);
    /// Advances one servo period with `command` (one value per axis: amplifier input in V, or
    /// motor torque in N·m for the ideal actuator) held, and says what the actuators did.
    fn hold(&mut self, command: &[f64], out: &mut Hold);
    /// Integration steps taken so far (physics steps, or steps of the analytic model).
    fn steps(&self) -> u64;
    /// The spindle speed the program commands over the coming period (rad/s: > 0 turning as
    /// M3, < 0 as M4, 0 stopped), set before every [`Plant::hold`]. A plant that does not cut
    /// ignores it.
    fn set_spindle(&mut self, _speed: f64) {}
    /// Why the plant cannot go on after the last period (e.g. its tool engaged the stock with
    /// the spindle stopped); `None` while it can.
    fn fault(&self) -> Option<String> {
        None
    }
    /// The stock as this plant has cut it so far (`None` for a plant that does not cut).
    fn stock(&self) -> Option<&crate::cutting::Stock> {
        None
    }
    /// The stock as this plant cut it, handed over once at the end of a run (`None` for a
    /// plant that does not cut).
    fn take_cut(&mut self) -> Option<crate::cutting::Cut> {
        None
    }
}
