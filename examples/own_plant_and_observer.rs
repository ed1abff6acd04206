//! Bring your own plant and your own observer: a scenario's program and controller run against
//! a model of the axes written here, in a lane beside the scenario's own physics, while an
//! observer written here watches every tick.
//!
//!     cargo run --example own_plant_and_observer [-- SCENARIO]
//!
//! - A plant is any type that implements [`Plant`]: it samples its sensors at the start of
//!   every servo period and holds the command over the period. Here each axis is what a step
//!   test on a real drive identifies, a first-order velocity response to the command (gain K
//!   in m/s per volt at the amplifier input, for a DC-motor scenario; time constant τ),
//!   integrated exactly over the period. The tool
//!   point comes from the machine's own forward kinematics.
//! - An observer is any type that implements [`Observer`]: it sees each lane's ticks
//!   ([`TickRecord`]: setpoint, sensors, command) and early stops. Here it keeps each lane's
//!   largest following error per axis.
//!
//! `RunOptions::plant(&make)` replaces the plant of every lane; the scenario's physics runs
//! first, then this example runs the same scenario with its own plant and compares.
//! `cargo test --example own_plant_and_observer` runs the check at the end of this file.

use cncsim::kinematics::tool_point;
use cncsim::machine::Machine;
use cncsim::scenario::{Assembly, RunOptions, Scenario};
use cncsim::sim::{Hold, LaneKind, Observer, Plant, Sensors, TickRecord};
use std::path::{Path, PathBuf};

/// Each axis a first-order velocity response to its command: τ·v̇ = K·u − v, ẋ = v.
struct IdentifiedAxes {
    machine: Machine,
    /// Steady velocity per volt at the amplifier input (m/s or rad/s per V), per axis.
    gain: Vec<f64>,
    /// Time constant of the velocity response (s).
    tau: f64,
    period: f64,
    position: Vec<f64>,
    velocity: Vec<f64>,
    periods: u64,
}

impl Plant for IdentifiedAxes {
    fn axes(&self) -> usize {
        self.position.len()
    }

    fn sample(&mut self, out: &mut Sensors) {
        out.position.copy_from_slice(&self.position);
        out.velocity.copy_from_slice(&self.velocity);
        out.drive_position.copy_from_slice(&self.position);
        out.feedback_position.copy_from_slice(&self.position);
        out.current.iter_mut().for_each(|c| *c = 0.0);
        let tool = tool_point(&self.machine, &self.position);
        // The tool's velocity by a finite difference of the forward kinematics along q̇.
        let dt = 1e-6;
        let ahead: Vec<f64> = (self.position.iter().zip(&self.velocity))
            .map(|(q, v)| q + v * dt)
            .collect();
        let tool_ahead = tool_point(&self.machine, &ahead);
        out.tool_point = tool.into();
        out.tool_velocity = ((tool_ahead - tool) / dt).into();
    }

    fn hold(&mut self, command: &[f64], out: &mut Hold) {
        let (t, tau) = (self.period, self.tau);
        let decay = (-t / tau).exp();
        for (i, &u) in command.iter().enumerate() {
            // Exact over the period with u held: v → K·u with time constant τ.
            let target = self.gain[i] * u;
            let v0 = self.velocity[i];
            self.position[i] += target * t + (v0 - target) * tau * (1.0 - decay);
            self.velocity[i] = target + (v0 - target) * decay;
            out.mean_torque[i] = 0.0;
            out.voltage[i] = u;
        }
        self.periods += 1;
    }

    fn steps(&self) -> u64 {
        self.periods
    }
}

/// The largest following error of each lane and axis (m or rad), from the ticks it observes.
#[derive(Default)]
struct LargestFollowingError {
    per_lane: Vec<Vec<f64>>,
    ticks: usize,
}

impl Observer for LargestFollowingError {
    fn tick(&mut self, lane: usize, record: &TickRecord<'_>) {
        if self.per_lane.len() <= lane {
            self.per_lane.resize(lane + 1, Vec::new());
        }
        let largest = &mut self.per_lane[lane];
        largest.resize(record.sensors.position.len(), 0.0);
        for (i, e) in largest.iter_mut().enumerate() {
            let error = (record.setpoint.position[i] - record.sensors.position[i]).abs();
            *e = e.max(error);
        }
        if lane == 0 {
            self.ticks += 1;
        }
    }
}

/// The largest following error per axis (m or rad) of one scenario, three ways.
struct Compared {
    /// The physics lane's, from the run's metrics (`metrics.json`).
    from_metrics: Vec<f64>,
    /// The physics lane's, as the observer saw it.
    physics: Vec<f64>,
    /// The identified plant's, as the observer saw it.
    own: Vec<f64>,
}

/// Runs `path` with the scenario's plants, then with [`IdentifiedAxes`] (K from each drive's
/// steady speed per command, τ = 20 ms), each watched by a [`LargestFollowingError`].
fn compare(path: &Path) -> Result<Compared, Box<dyn std::error::Error>> {
    let scenario = Scenario::load(path)?;
    let assembly = Assembly::new(&scenario)?;
    let mut physics_watch = LargestFollowingError::default();
    let physics = assembly.run(RunOptions::new().observer(&mut physics_watch))?;
    // metrics.json's figures are in mm (deg on rotary axes), by axis name.
    let from_metrics: Vec<f64> = assembly
        .machine
        .axes
        .iter()
        .map(|a| {
            let m = &physics.metrics.axes[&a.name];
            m.max_following_error_mm
                .map(|mm| mm * 1e-3)
                .or(m.max_following_error_deg.map(f64::to_radians))
                .unwrap_or(f64::NAN)
        })
        .collect();

    let machine = assembly.machine.clone();
    let period = scenario.timing.servo_period;
    // Steady speed per volt at the amplifier: what the drive's damping and back-EMF let
    // through (the scenario's actuator is a DC motor).
    let gain: Vec<f64> = machine
        .axes
        .iter()
        .map(|a| 1.0 / a.drive.steady_volts_per_velocity())
        .collect();
    let make = |_lane: LaneKind, start: &[f64]| -> Box<dyn Plant> {
        Box::new(IdentifiedAxes {
            machine: machine.clone(),
            gain: gain.clone(),
            tau: 0.02,
            period,
            position: start.to_vec(),
            velocity: vec![0.0; start.len()],
            periods: 0,
        })
    };
    let mut own_watch = LargestFollowingError::default();
    assembly.run(RunOptions::new().plant(&make).observer(&mut own_watch))?;
    Ok(Compared {
        from_metrics,
        physics: physics_watch.per_lane[0].clone(),
        own: own_watch.per_lane[0].clone(),
    })
}

#[cfg_attr(test, allow(dead_code))] // built as a test too: its check is below
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenarios/xyz_circle_5mms.toml")
        });
    let c = compare(&path)?;
    println!("largest following error per axis (µm or µrad):");
    println!(
        "  physics, from metrics.json    {:?}",
        micro(&c.from_metrics)
    );
    println!("  physics, seen by the observer {:?}", micro(&c.physics));
    println!("  identified first-order axes   {:?}", micro(&c.own));
    Ok(())
}

#[cfg_attr(test, allow(dead_code))]
fn micro(values: &[f64]) -> Vec<String> {
    values.iter().map(|v| format!("{:.3}", v * 1e6)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The observer sees what the metrics report (the same ticks, the same errors), and the
    /// identified plant, run in the physics' place, follows the program.
    #[test]
    fn the_observer_sees_the_metrics_ticks_and_the_own_plant_runs() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/xyz_circle_5mms.toml");
        let Compared {
            from_metrics: metrics,
            physics,
            own,
        } = compare(&path).unwrap();
        assert_eq!(metrics.len(), physics.len());
        for (m, p) in metrics.iter().zip(&physics) {
            assert!(
                (m - p).abs() <= 1e-12 * m.abs().max(1e-9),
                "{metrics:?} vs {physics:?}"
            );
        }
        assert!(own.iter().all(|e| e.is_finite()), "{own:?}");
        assert!(
            own.iter().any(|&e| e > 0.0) && own.iter().all(|&e| e < 1e-2),
            "{own:?}"
        );
        assert_ne!(own, physics, "the own plant ran in the physics' place");
    }
}
