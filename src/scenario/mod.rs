//! Scenario files: what to run (machine, program, planner, controller, timing, recording)
//! and the bounds the result must meet. Running one is the whole data flow end to end.

mod ab;
mod assemble;
mod ballbar;
mod bode;
mod check;
mod file;
mod machine_setup;
mod overrides;
mod plan;
mod run;
mod tune;

pub use ab::{run_ab, AbOutput, AbReport, AbRow};
pub use assemble::{
    axis_map_for, keep_mechanics, load_checked_program, machine_for, plan_for, plan_settings,
    with_choices, Assembly, ControllerRecipe, MakeController, MakePlant, PlanKey, ProgramOverview,
    RunError, GRAVITY,
};
pub use ballbar::{
    ballbar_centre, ballbar_passes, ballbar_program, default_plane_centre_overshoot,
    default_radius_and_feed, plane_axes, run_ballbar, BallbarOptions, BallbarOutput, BallbarPlane,
    BallbarSpec,
};
pub use bode::{
    axis_linear_model, check_range, loop_name, run_bode, AxisLinearModel, BodeError, BodeOptions,
    BodeOutput, DEFAULT_FROM_HZ, DEFAULT_TO_SHARE,
};
pub use check::{check, check_scenarios, scenario_files, Breach, CheckReport, Verdict};
pub use file::{
    limits, ActuatorSettings, AnalyticSettings, Approach, AxisCascade, AxisGains, CascadeTable,
    CompensationEntry, ControlSpace, ControllerSettings, ControllerType, DeclaredVariants,
    Expectation, FeedbackSettings, FmuSettings, FrequencyResponse, InverseDynamicsSettings,
    Mechanics, PidTable, PlannerSettings, ProfileName, ProgramKinematics, ProgramSettings,
    ProgramSource, RecordingSettings, Scenario, Timing, TransmissionEntry,
};
pub use machine_setup::{
    check_machine, drive_file_template, AxisRow, DriveFileDraft, MachineReport, ToolPointRow,
};
pub use overrides::{edit_toml, Override};
pub use plan::{plan_scenario, PlanOutput, PlanReport};
pub use run::{
    recording_setup, report_setup, summary_markdown, RunOptions, RunOutput, ScenarioRun,
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
