//! Scenario files: what to run (machine, program, planner, controller, timing, recording)
//! and the bounds the result must meet. Running one is the whole data flow end to end.

mod check;
mod file;
mod run;

pub use check::{check, Breach, Verdict};
pub use file::{AxisGains, Expectation, Profile, ProgramSource, Scenario};
pub use run::{run_scenario, RunError, RunOutput};
