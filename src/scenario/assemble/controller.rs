//! The scenario's controller resolved on its machine: the chosen type's settings for every axis
//! in the machine's axis order, the model of the machine it needs, and the compensation around
//! it. Everything that can fail is checked here, once, when the scenario is assembled; a run
//! then builds fresh instances from it without another check.

use super::GRAVITY;
use crate::control::{
    ActuatorKind, AxisCompensation, Cascade, CascadeAxis, Compensated, ComputedTorque, Controller,
    Pid, PidBank, PidForm, PidSettings, TaskSpace,
};
use crate::diagnostics::FileError;
use crate::dynamics::AxisDynamics;
use crate::fmi::{AxesSpec, FmuController, FmuModel};
use crate::kinematics::AcTableKinematics;
use crate::machine::{Drive, Machine};
use crate::scenario::{ControlSpace, ControllerType, InverseDynamicsSettings, Scenario};
use std::sync::Arc;

/// The control law with its settings per axis.
#[derive(Debug, Clone)]
enum Law {
    Pid {
        form: PidForm,
        axes: Vec<PidSettings>,
    },
    Cascade {
        axes: Vec<CascadeAxis>,
        velocity_filter_hz: f64,
        model: AxisDynamics,
    },
    ComputedTorque {
        settings: InverseDynamicsSettings,
        model: AxisDynamics,
        /// Task space: the tool-tip kinematics of the A-C table (boxed: the other laws are
        /// much smaller).
        task: Option<Box<AcTableKinematics>>,
    },
    /// A controller FMU, loaded and checked once; each controller is an instance of it.
    Fmu(Arc<FmuModel>),
}

/// Everything needed to build the scenario's controller for its machine.
#[derive(Debug, Clone)]
pub struct ControllerRecipe {
    law: Law,
    /// Reversal compensation per axis, where the scenario asks for any.
    compensation: Option<Vec<AxisCompensation>>,
    drives: Vec<Drive>,
    actuator: ActuatorKind,
    period: f64,
}

impl ControllerRecipe {
    /// Resolves the scenario's `[controller]` and `[compensation]` on `machine`: every axis
    /// must have settings of the chosen type (axis names were checked before).
    pub(super) fn new(
        s: &Scenario,
        machine: &Machine,
        actuator: ActuatorKind,
    ) -> Result<Self, FileError> {
        let Some(c) = &s.controller else {
            return Err(FileError::new(
                &s.path,
                None,
                "running a scenario needs a [controller] section",
            ));
        };
        let period = s.timing.servo_period;
        let missing = |what: &str, at, axis: &str| {
            FileError::new(
                &s.path,
                at,
                format!("{what} for axis '{axis}' of machine '{}'", machine.name),
            )
        };
        let law = match c.kind {
            ControllerType::Pid => Law::Pid {
                form: c.pid.form,
                axes: machine
                    .axes
                    .iter()
                    .map(|a| {
                        c.pid.axes.get(&a.name).map(|g| g.settings).ok_or_else(|| {
                            missing("[controller.axes] has no gains", c.pid.at.or(c.at), &a.name)
                        })
                    })
                    .collect::<Result<_, _>>()?,
            },
            ControllerType::Cascade => Law::Cascade {
                axes: machine
                    .axes
                    .iter()
                    .map(|a| {
                        c.cascade
                            .axes
                            .get(&a.name)
                            .map(|g| g.settings)
                            .ok_or_else(|| {
                                missing(
                                    "[controller.cascade] has no loop settings",
                                    c.cascade.at.or(c.at),
                                    &a.name,
                                )
                            })
                    })
                    .collect::<Result<_, _>>()?,
                velocity_filter_hz: c.cascade.velocity_filter_hz,
                model: dynamics_model(s, machine, 1.0)?,
            },
            ControllerType::InverseDynamics => {
                let settings = c.inverse_dynamics.ok_or_else(|| {
                    FileError::new(
                        &s.path,
                        c.at,
                        "type = \"inverse-dynamics\" needs natural_frequency_hz",
                    )
                })?;
                let task = match settings.space {
                    ControlSpace::Joint => None,
                    ControlSpace::Task => Some(Box::new(AcTableKinematics::new(machine).map_err(|e| {
                        FileError::new(
                            &s.path,
                            c.at,
                            format!("controller.space = \"task\" resolves the tool tip on a table-tilting A-C machine: {e}"),
                        )
                    })?)),
                };
                Law::ComputedTorque {
                    settings,
                    model: dynamics_model(s, machine, settings.model_mass_scale)?,
                    task,
                }
            }
            ControllerType::Fmu => {
                let fmu = c.fmu.as_ref().ok_or_else(|| {
                    FileError::new(&s.path, c.at, "type = \"fmu\" needs fmu = \"PATH.fmu\"")
                })?;
                let axes = AxesSpec {
                    names: machine.axes.iter().map(|a| a.name.clone()).collect(),
                    rotary: machine.axes.iter().map(|a| a.is_rotary(machine)).collect(),
                    actuator,
                    servo_period: period,
                };
                let fail = |e: String| {
                    FileError::new(
                        &s.path,
                        fmu.at.or(c.at),
                        format!("controller FMU {}: {e}", fmu.request.path.display()),
                    )
                };
                let model = Arc::new(FmuModel::load(&fmu.request, &axes).map_err(fail)?);
                // One instance now, so an FMU that cannot start is refused before any run.
                model.instantiate().map_err(fail)?;
                Law::Fmu(model)
            }
        };
        let compensation = (!s.compensation.is_empty()).then(|| {
            machine
                .axes
                .iter()
                .map(|a| {
                    s.compensation
                        .get(&a.name)
                        .map(|c| c.compensation)
                        .unwrap_or_default()
                })
                .collect()
        });
        Ok(ControllerRecipe {
            law,
            compensation,
            drives: machine.axes.iter().map(|a| a.drive.clone()).collect(),
            actuator,
            period,
        })
    }

    /// The recipe with axis `axis` of a cascade switched to velocity mode, as a drive is for
    /// measuring its velocity loop: the position loop opened (K_pp = K_ip = 0), the setpoint
    /// velocity passed through whole (kvff = 1) as the velocity command, no acceleration
    /// feed-forward. `None` for any other law.
    pub fn velocity_mode(&self, axis: usize) -> Option<ControllerRecipe> {
        let mut recipe = self.clone();
        let Law::Cascade { axes, .. } = &mut recipe.law else {
            return None;
        };
        let a = axes.get_mut(axis)?;
        a.position_kp = 0.0;
        a.position_ki = 0.0;
        a.velocity_ff = 1.0;
        a.acceleration_ff = 0.0;
        Some(recipe)
    }

    /// A fresh controller (with its compensation), in the machine's axis order.
    pub fn build(&self) -> Box<dyn Controller> {
        let (drives, actuator, period) = (&self.drives, self.actuator, self.period);
        let inner: Box<dyn Controller> = match &self.law {
            Law::Pid { form, axes } => Box::new(PidBank::new(
                axes.iter().map(|g| Pid::new(*g, *form, period)).collect(),
            )),
            Law::Cascade {
                axes,
                velocity_filter_hz,
                model,
            } => Box::new(Cascade::new(
                axes.clone(),
                *velocity_filter_hz,
                model.clone(),
                drives,
                actuator,
                period,
            )),
            Law::ComputedTorque {
                settings,
                model,
                task,
            } => {
                let controller = ComputedTorque::new(
                    model.clone(),
                    drives,
                    actuator,
                    period,
                    settings.omega_n,
                    settings.damping_ratio,
                );
                match task {
                    None => Box::new(controller),
                    Some(kinematics) => Box::new(controller.in_task_space(TaskSpace::new(
                        (**kinematics).clone(),
                        settings.task_damping,
                    ))),
                }
            }
            Law::Fmu(model) => match model.instantiate() {
                Ok(controller) => Box::new(controller),
                Err(e) => Box::new(FmuController::broken(model, e)),
            },
        };
        match &self.compensation {
            None => inner,
            Some(per_axis) => Box::new(Compensated::new(inner, per_axis.clone(), period)),
        }
    }
}

/// The controller's model of the machine: the drives' reflected damping on the joints, the
/// rotor inertia as armature, every link's mass scaled by `mass_scale` (robustness studies).
fn dynamics_model(
    s: &Scenario,
    machine: &Machine,
    mass_scale: f64,
) -> Result<AxisDynamics, FileError> {
    let mut model_machine = machine.clone();
    for axis in &machine.axes {
        model_machine.joints[axis.joint].damping += axis.drive.reflected_damping();
    }
    for link in &mut model_machine.links {
        link.mass *= mass_scale;
        link.inertia *= mass_scale;
    }
    AxisDynamics::of_machine(&model_machine, nalgebra::Vector3::from(GRAVITY)).map_err(|e| {
        FileError::new(
            &s.machine,
            None,
            format!("the controller's model of the machine: {e}"),
        )
    })
}
