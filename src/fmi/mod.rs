//! FMI co-simulation: controller FMUs (FMI 3.0 and 2.0) stepped by the servo loop as one more
//! controller type (`[controller] type = "fmu"`), and the scenario's plant exported as an
//! FMI 3.0 co-simulation FMU (`cncsim export-fmu`, [`export`]; the shared library is the
//! `cncsim-fmu` crate in `fmu/`, stepping [`plant::PlantModel`]). docs/fmi.md has the
//! variable-naming convention and what is supported.

mod binding;
pub mod description;
pub mod export;
mod import;
pub mod plant;

pub use description::{FmiVersion, ModelDescription};
pub use import::{measured_velocity, unpack, AxesSpec, FmuController, FmuModel, FmuRequest};
