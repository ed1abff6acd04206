//! Bring your own controller: a scenario run through the library with a controller written
//! here, compared with the scenario's own on the same setpoints.
//!
//!     cargo run --example own_controller [-- SCENARIO]
//!
//! The path from a scenario file to metrics, as a library user walks it:
//!
//! 1. [`Scenario::load`] reads and checks the file;
//! 2. [`Assembly::new`] loads the machine, plans the program into setpoints and wires the loop;
//! 3. [`Assembly::run`] runs it with [`RunOptions`]: here with a controller of one's own (any
//!    type that implements [`Controller`]), a fresh one per lane; `RunOptions::write_to(dir)`
//!    would also write `metrics.json`, the CSV trace and the recording, `.observer(..)` add an
//!    observer of every tick, `.traced()` keep the ticks in memory, `.plant(..)` run a plant of
//!    one's own (any type that implements `sim::Plant`) in each lane;
//! 4. `RunOutput::metrics` holds the figures of `metrics.json`.
//!
//! The controller here is a PD on each axis plus exact velocity feed-forward from the linear
//! model of the drive (the command that holds the setpoint speed against the drive's own
//! damping and back-EMF): it tracks a circle with far less lag than the PD alone.

use cncsim::control::{Controller, ControllerInput};
use cncsim::scenario::{Assembly, RunOptions, Scenario};
use std::path::PathBuf;

/// PD plus velocity feed-forward, per axis (error in m, output in V at the amplifier input).
#[derive(Clone)]
struct PdWithFeedForward {
    kp: Vec<f64>,
    kd: Vec<f64>,
    /// Volts per m/s that hold a steady speed.
    velocity_gain: Vec<f64>,
    period: f64,
    previous_error: Vec<f64>,
}

impl Controller for PdWithFeedForward {
    #[allow(clippy::needless_range_loop)] // five per-axis slices, one index
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        for i in 0..command.len() {
            let error = input.setpoint_position[i] - input.measured_position[i];
            let derivative = (error - self.previous_error[i]) / self.period;
            self.previous_error[i] = error;
            command[i] = self.kp[i] * error
                + self.kd[i] * derivative
                + self.velocity_gain[i] * input.setpoint_velocity[i];
        }
    }

    fn reset(&mut self) {
        self.previous_error.iter_mut().for_each(|e| *e = 0.0);
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenarios/xyz_circle_5mms.toml")
        });
    let scenario = Scenario::load(&path)?;
    let assembly = Assembly::new(&scenario)?;
    let n = assembly.machine.axes.len();
    // The drive's steady volts per (m/s): ω = k·v at the motor; the amplifier must supply the
    // back-EMF K_b·ω (voltage mode) and the current for the viscous torque C·ω.
    let velocity_gain = assembly
        .machine
        .axes
        .iter()
        .map(|a| a.drive.steady_volts_per_velocity())
        .collect();
    let mine = PdWithFeedForward {
        kp: vec![5000.0; n],
        kd: vec![60.0; n],
        velocity_gain,
        period: scenario.timing.servo_period,
        previous_error: vec![0.0; n],
    };
    let make_mine = || Box::new(mine.clone()) as Box<dyn Controller>;
    let own = assembly
        .run(RunOptions::new().controller(&make_mine))?
        .metrics;
    let theirs = assembly.run(RunOptions::new())?.metrics;
    println!(
        "{}: {} on {}",
        scenario.name,
        scenario.controller_type().map_or("-", |c| c.name()),
        assembly.machine.name
    );
    println!("{:<34} {:>14} {:>14}", "", "own PD + FF", "scenario's");
    println!(
        "{:<34} {:>14.3} {:>14.3}",
        "max contour error (µm)",
        own.max_contour_error_mm * 1e3,
        theirs.max_contour_error_mm * 1e3
    );
    for (axis, a) in &own.axes {
        let b = &theirs.axes[axis];
        println!(
            "{:<34} {:>14.3} {:>14.3}",
            format!("{axis}: max following error (µm)"),
            a.max_following_error_mm.unwrap_or(f64::NAN) * 1e3,
            b.max_following_error_mm.unwrap_or(f64::NAN) * 1e3
        );
        println!(
            "{:<34} {:>14.4} {:>14.4}",
            format!("{axis}: rms torque (N·m)"),
            a.rms_torque_nm,
            b.rms_torque_nm
        );
    }
    Ok(())
}
