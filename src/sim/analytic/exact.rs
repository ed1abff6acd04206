//! Exact solution of the modes whose equations are linear.
//!
//! With a voltage-mode amplifier (or the ideal torque actuator) and friction that does not
//! depend on the speed (none, or Coulomb without a Stribeck drop), every mode of an axis is a
//! linear ODE with a constant input over the hold interval:
//!
//! ```text
//!   ẏ = A·y + B·[w, 1]ᵀ,   y = [x_d, v_d, x_c, v_c, i, q],   w = armature voltage or motor torque
//! ```
//!
//! so y(t) = Φ(t)·y(0) + Γ(t)·[w, 1]ᵀ with [[Φ, Γ], [0, I]] = exp([[A, B], [0, 0]]·t). There is
//! then no integration error to speak of (the matrix exponential is accurate to round-off),
//! and a step costs one small matrix product instead of four evaluations of the equations.
//! A current-mode amplifier (its voltage clamps on the back-EMF it adds) and the Stribeck curve
//! are not linear; their modes stay with RK4.

use super::{Actuator, ActuatorInput, AxisModel, AxisState, Contact, Guide, Mode};
use crate::machine::AmplifierMode;
use nalgebra::{SMatrix, SVector};

const XD: usize = 0;
const VD: usize = 1;
const XC: usize = 2;
const VC: usize = 3;
const I: usize = 4;
const Q: usize = 5;

type State = SVector<f64, 6>;

/// The exact flow of one linear mode over one duration.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct LinearFlow {
    pub(super) mode: Mode,
    pub(super) duration: f64,
    transition: SMatrix<f64, 6, 6>,
    /// Response to the input and to the constant forces (gravity, Coulomb friction).
    forced: SMatrix<f64, 6, 2>,
}

impl LinearFlow {
    /// The state `duration` after `y` under input `w` ([`AxisModel::linear_input`]).
    pub(super) fn apply(&self, y: &AxisState, w: f64) -> AxisState {
        let next = self.transition * to_vector(y) + self.forced * SVector::<f64, 2>::new(w, 1.0);
        from_vector(&next)
    }
}

/// Flows computed for the standard step, kept because every tick reuses them. A cache of
/// derived values: two models are equal whatever their caches hold.
#[derive(Debug, Clone, Default)]
pub(super) struct FlowCache {
    flows: Vec<LinearFlow>,
}

impl PartialEq for FlowCache {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// Modes × step lengths worth keeping: 4 contact states × 4 guide states, one step length.
const CACHE_CAPACITY: usize = 16;

impl FlowCache {
    pub(super) fn get(&self, mode: Mode, duration: f64) -> Option<&LinearFlow> {
        self.flows
            .iter()
            .find(|f| f.mode == mode && f.duration == duration)
    }

    pub(super) fn insert(&mut self, flow: LinearFlow) {
        if self.flows.len() < CACHE_CAPACITY {
            self.flows.push(flow);
        }
    }
}

impl AxisModel {
    /// Whether the equations of `mode` are linear (see the module documentation).
    pub(super) fn is_linear(&self, mode: Mode) -> bool {
        let amplifier_linear = !matches!(
            self.actuator,
            Actuator::DcMotor {
                amplifier_mode: AmplifierMode::Current,
                ..
            }
        );
        let friction_linear = match mode.guide {
            Guide::Sliding { direction } => direction == 0.0 || !self.friction.has_stiction(),
            Guide::Stuck => true,
        };
        amplifier_linear && friction_linear
    }

    /// A, B of `mode` when its equations are linear, with w the armature voltage (voltage
    /// mode) or the motor torque (ideal actuator); `None` when they are not.
    pub(super) fn linear_system(
        &self,
        mode: Mode,
    ) -> Option<(SMatrix<f64, 6, 6>, SMatrix<f64, 6, 2>)> {
        if !self.is_linear(mode) {
            return None;
        }
        let mut a = SMatrix::<f64, 6, 6>::zeros();
        let mut b = SMatrix::<f64, 6, 2>::zeros();
        // Motor force at the joint: from the current, or from the input (ideal actuator).
        let (force_per_current, force_per_input) = match self.actuator {
            Actuator::DcMotor {
                torque_constant,
                back_emf_constant,
                resistance,
                inductance,
                ..
            } => {
                a[(I, I)] = -resistance / inductance;
                a[(I, VD)] = -back_emf_constant * self.ratio / inductance;
                b[(I, 0)] = 1.0 / inductance;
                (self.ratio * torque_constant, 0.0)
            }
            Actuator::IdealTorque { .. } => (0.0, self.ratio),
        };
        a[(Q, I)] = 1.0;
        // Friction against the direction of sliding: a constant here (is_linear; direction 0
        // means no Coulomb friction at all).
        let friction = match mode.guide {
            Guide::Stuck => 0.0,
            Guide::Sliding { direction } => self.friction.kinetic * direction,
        };
        let sliding = matches!(mode.guide, Guide::Sliding { .. });
        match mode.contact {
            Contact::Rigid | Contact::Closed { .. } => {
                a[(XD, VC)] = 1.0;
                a[(XC, VC)] = 1.0;
                if sliding {
                    let m = self.effective_mass();
                    for row in [VD, VC] {
                        a[(row, I)] = force_per_current / m;
                        a[(row, VC)] = -self.effective_damping() / m;
                        b[(row, 0)] = force_per_input / m;
                        b[(row, 1)] = (self.carriage_force() - friction) / m;
                    }
                }
            }
            Contact::Compliant { side } => {
                // λ = k·(x_d − x_c) + c·(v_d − v_c) − k·side·b/2 on the carriage, −λ on the drive.
                let (k, c) = self
                    .compliance
                    .map_or((0.0, 0.0), |c| (c.stiffness, c.damping));
                let preload = k * side * self.backlash / 2.0;
                let (md, mc) = (self.drive_mass, self.carriage_mass);
                a[(XD, VD)] = 1.0;
                a[(VD, I)] = force_per_current / md;
                a[(VD, XD)] = -k / md;
                a[(VD, XC)] = k / md;
                a[(VD, VD)] = -(self.drive_damping + c) / md;
                a[(VD, VC)] = c / md;
                b[(VD, 0)] = force_per_input / md;
                b[(VD, 1)] = preload / md;
                a[(XC, VC)] = 1.0;
                if sliding {
                    a[(VC, XD)] = k / mc;
                    a[(VC, XC)] = -k / mc;
                    a[(VC, VD)] = c / mc;
                    a[(VC, VC)] = -(self.carriage_damping + c) / mc;
                    b[(VC, 1)] = (self.carriage_force() - friction - preload) / mc;
                }
            }
            Contact::Open => {
                a[(XD, VD)] = 1.0;
                a[(VD, I)] = force_per_current / self.drive_mass;
                a[(VD, VD)] = -self.drive_damping / self.drive_mass;
                b[(VD, 0)] = force_per_input / self.drive_mass;
                a[(XC, VC)] = 1.0;
                if sliding {
                    a[(VC, VC)] = -self.carriage_damping / self.carriage_mass;
                    b[(VC, 1)] = (self.carriage_force() - friction) / self.carriage_mass;
                }
            }
        }
        Some((a, b))
    }

    /// The w of [`Self::linear_system`] for an input: the armature voltage of a voltage-mode
    /// amplifier does not depend on the state.
    pub(super) fn linear_input(&self, input: ActuatorInput) -> f64 {
        match input {
            ActuatorInput::Voltage(amplifier) => {
                self.armature_voltage(&AxisState::default(), amplifier)
            }
            ActuatorInput::Torque(torque) => torque,
        }
    }

    /// The exact flow of `mode` over `duration`, when the mode is linear.
    pub(super) fn linear_flow(&self, mode: Mode, duration: f64) -> Option<LinearFlow> {
        let (a, b) = self.linear_system(mode)?;
        let mut augmented = SMatrix::<f64, 8, 8>::zeros();
        augmented.fixed_view_mut::<6, 6>(0, 0).copy_from(&a);
        augmented.fixed_view_mut::<6, 2>(0, 6).copy_from(&b);
        let exponential = (augmented * duration).exp();
        Some(LinearFlow {
            mode,
            duration,
            transition: exponential.fixed_view::<6, 6>(0, 0).into_owned(),
            forced: exponential.fixed_view::<6, 2>(0, 6).into_owned(),
        })
    }
}

fn to_vector(y: &AxisState) -> State {
    State::from([
        y.drive_position,
        y.drive_velocity,
        y.carriage_position,
        y.carriage_velocity,
        y.current,
        y.charge,
    ])
}

fn from_vector(v: &State) -> AxisState {
    AxisState {
        drive_position: v[XD],
        drive_velocity: v[VD],
        carriage_position: v[XC],
        carriage_velocity: v[VC],
        current: v[I],
        charge: v[Q],
    }
}

#[cfg(test)]
pub(super) fn rate_from_system(
    model: &AxisModel,
    mode: Mode,
    y: &AxisState,
    input: ActuatorInput,
) -> Option<AxisState> {
    let (a, b) = model.linear_system(mode)?;
    let w = model.linear_input(input);
    Some(from_vector(
        &(a * to_vector(y) + b * SVector::<f64, 2>::new(w, 1.0)),
    ))
}
