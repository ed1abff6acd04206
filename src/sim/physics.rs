//! The Rapier machine as a [`Plant`]: each held command drives the actuator models (ideal
//! torque, or amplifier + DC motor) at the physics rate, their torque pushes the joints
//! through the transmission, and the engine steps `substeps` times per servo period.

use super::cut::PlantCut;
use super::{Hold, Plant, Sensors};
use crate::control::Actuator;
use crate::model;

/// The Rapier machine with its drives' actuator models, stepped by the servo loop.
pub struct PhysicsPlant {
    plant: model::Plant,
    actuators: Vec<Actuator>,
    /// Motor radians per joint unit, per axis (torque → joint force, joint → motor speed).
    ratios: Vec<f64>,
    substeps: usize,
    /// The cut the tool makes, with the tool's axis in the tool link's frame.
    cut: Option<(PlantCut, nalgebra::Vector3<f64>)>,
    /// Scratch, reused every period (the loop allocates nothing).
    drive_velocity: Vec<f64>,
    force: Vec<f64>,
    current: Vec<f64>,
}

impl PhysicsPlant {
    /// `plant` steps at the physics step; one servo period is `substeps` of them.
    pub fn new(
        plant: model::Plant,
        actuators: Vec<Actuator>,
        ratios: Vec<f64>,
        substeps: usize,
    ) -> PhysicsPlant {
        let n = ratios.len();
        PhysicsPlant {
            plant,
            actuators,
            ratios,
            substeps,
            cut: None,
            drive_velocity: vec![0.0; n],
            force: vec![0.0; n],
            current: vec![0.0; n],
        }
    }

    /// The plant cutting `cut`, the tool's axis `tool_axis` in the tool link's frame.
    pub fn with_cut(mut self, cut: PlantCut, tool_axis: nalgebra::Vector3<f64>) -> PhysicsPlant {
        self.cut = Some((cut, tool_axis));
        self
    }

    /// The Rapier model (for checks that look inside it, e.g. the guide contact forces).
    pub fn model(&self) -> &model::Plant {
        &self.plant
    }
}

impl Plant for PhysicsPlant {
    fn axes(&self) -> usize {
        self.ratios.len()
    }

    fn sample(&mut self, out: &mut Sensors) {
        let p = &self.plant;
        p.positions(&mut out.position);
        p.velocities(&mut out.velocity);
        p.drive_positions(&mut out.drive_position);
        p.feedback_positions(&mut out.feedback_position);
        out.current.copy_from_slice(&self.current);
        out.tool_point = p.tool_point().into();
        out.tool_velocity = p.tool_velocity().into();
    }

    // Five per-axis slices: one index reads clearer than zipped iterators.
    #[allow(clippy::needless_range_loop)]
    fn hold(&mut self, command: &[f64], out: &mut Hold) {
        let dt = self.plant.step_size();
        let substeps = self.substeps as f64;
        out.mean_torque.iter_mut().for_each(|t| *t = 0.0);
        for _ in 0..self.substeps {
            // The motor turns with the drive side of the transmission (back-EMF).
            self.plant.drive_velocities(&mut self.drive_velocity);
            for i in 0..self.ratios.len() {
                let k = self.ratios[i];
                let a = self.actuators[i].step(command[i], k * self.drive_velocity[i], dt);
                self.force[i] = a.torque * k;
                out.mean_torque[i] += a.torque / substeps;
                out.voltage[i] = a.voltage;
                self.current[i] = a.current;
            }
            self.plant.set_joint_forces(&self.force);
            if let Some((cut, tool_axis)) = &mut self.cut {
                let tool = self.plant.tool_on_part(tool_axis);
                let load = cut.step(&tool.point, &tool.axis, &tool.velocity, dt);
                self.plant.set_cutting_load(Some(load));
            }
            self.plant.step();
        }
        if let Some((cut, _)) = &mut self.cut {
            cut.end_period(&mut out.cut);
        }
    }

    fn set_spindle(&mut self, speed: f64) {
        if let Some((cut, _)) = &mut self.cut {
            cut.set_spindle(speed);
        }
    }

    fn fault(&self) -> Option<String> {
        self.cut.as_ref().and_then(|(cut, _)| cut.fault())
    }

    fn stock(&self) -> Option<&crate::cutting::Stock> {
        self.cut.as_ref().map(|(cut, _)| cut.stock())
    }

    fn take_cut(&mut self) -> Option<crate::cutting::Cut> {
        self.cut.take().map(|(cut, _)| cut.into_cut())
    }

    fn steps(&self) -> u64 {
        self.plant.steps()
    }
}
