//! Frequency response of a servo axis: measured on a plant through the servo loop by stepped
//! sine ([`measure`], [`estimate`]), and derived from the drive data as the linearised,
//! sampled loop ([`linear`]) to be laid over it: the one linear model of an axis, which
//! `tune` designs on as well. `cncsim bode` (`scenario::bode`) wires both
//! to a scenario; docs/frequency-response.md says how to read the result.

pub mod estimate;
pub mod linear;
pub mod measure;

pub use estimate::{
    bandwidth, extrema, h1, log_grid, margins, phasor, segments, Crossover, Segment, SweepTiming,
};
pub use linear::{
    AxisPlant, LinearActuator, LinearController, Loop, LoopResponse, PlantResponse, SampledPlant,
    Transmission, C64,
};
pub use measure::{estimates, run_sweep, Estimate, Excitation, Injected, Injection, Samples};
