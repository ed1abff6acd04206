//! Scenario files: what to run (machine, program, planner, controller, timing, recording)
//! and the bounds the result must meet. Running one is the whole data flow end to end.

mod ab;
mod assemble;
mod ballbar;
mod check;
mod file;
mod machine_setup;
mod overrides;
mod plan;
mod run;
mod tune;

pub use ab::{run_ab, AbReport, AbRow};
pub use assemble::{
    axis_map_for, keep_mechanics, load_checked_program, machine_for, plan_for, plan_key,
    plan_settings, with_choices, Assembly, PlantKind, ProgramOverview, RunError, GRAVITY,
};
pub use ballbar::{
    ballbar_centre, ballbar_passes, ballbar_program, default_plane_centre_overshoot,
    default_radius_and_feed, plane_axes, run_ballbar, BallbarOptions, BallbarPlane, BallbarSpec,
};
pub use check::{check, Breach, Verdict};
pub use file::{
    limits, Approach, AxisCascade, AxisGains, CompensationEntry, ControlSpace, ControllerType,
    DeclaredVariants, Expectation, InverseDynamicsSettings, PlannerSettings, ProfileName,
    ProgramSource, Scenario,
};
pub use machine_setup::{check_machine, drive_file_template, AxisRow, MachineReport};
pub use overrides::{edit_toml, Override};
pub use plan::{plan_scenario, PlanReport};
pub use run::{
    recording_setup, report_setup, run_assembly, run_assembly_observed, run_scenario,
    run_scenario_traced, run_scenario_with, summary_markdown, RunOutput,
};
pub use tune::{
    outcome_text, tune_cascade, tune_scenario, tune_scenario_with, CascadeTuneReport,
    LinearPrediction, TuneError, TuneOptions, TuneReport,
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
