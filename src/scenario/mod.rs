//! Scenario files: what to run (machine, program, planner, controller, timing, recording)
//! and the bounds the result must meet. Running one is the whole data flow end to end.

mod ab;
mod check;
mod file;
mod overrides;
mod plan;
mod run;

pub use ab::{run_ab, AbReport, AbRow};
pub use check::{check, Breach, Verdict};
pub use file::{
    AxisGains, ControlSpace, DeclaredVariants, Expectation, InverseDynamicsSettings,
    PlannerSettings, ProfileName, ProgramSource, Scenario,
};
pub use overrides::Override;
pub use plan::{plan_scenario, PlanReport};
pub use run::{
    load_checked_program, plan_settings, prepare, run_scenario, Prepared, RunError, RunOutput,
};

/// A scenario or variant name as a single folder name (no separators, no `..`).
pub fn folder_name(name: &str) -> String {
    let cleaned: String = name
        .chars()
        .map(|c| {
            if c.is_alphanumeric() || "-_.=".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if cleaned.trim_matches('.').is_empty() {
        "scenario".into()
    } else {
        cleaned
    }
}
