//! cncsim's jerk-limited cycle time against the time-optimal, acceleration-limited bound of the
//! same geometry computed by TOPP-RA (`tools/toppra_bound.py`; `pip install toppra`).
//!
//! ```sh
//! # G-code files on the XYZ table with the same limits on every axis:
//! cargo run --example plan_vs_toppra -- --limits 200,2000 --jerk 5e4,1e6,1e8 \
//!     --tolerance 0.05 [--q 0.03] FILE.ngc...
//! # Bundled scenarios with their own limits (jerk as in the scenario):
//! cargo run --example plan_vs_toppra -- --scenario scenarios/plan_table2_jerk_g64.toml
//! ```
//!
//! Prints one Markdown table row per program and jerk limit. `--python` names the interpreter
//! with toppra (default `CNCSIM_PYTHON`, else `python3`).

#[path = "../tests/common/mod.rs"]
mod common;
#[path = "../tests/common/toppra.rs"]
mod toppra;

use std::path::{Path, PathBuf};

use cncsim::kinematics::AxisMap;
use cncsim::machine::Machine;
use cncsim::plan::{
    jerk_limited_plans, tool_lever_arms, AxisLimits, BlendChoice, PlanSettings, Planner,
};
use cncsim::program::{read_program, Program, ReadOptions};
use cncsim::scenario::{load_checked_program, machine_for, plan_settings, Scenario};

struct Options {
    files: Vec<PathBuf>,
    scenarios: Vec<PathBuf>,
    limits: (f64, f64),
    jerks: Vec<f64>,
    tolerance: f64,
    q: Option<f64>,
    machine: PathBuf,
    python: Option<String>,
}

fn parse() -> Result<Options, String> {
    let mut o = Options {
        files: Vec::new(),
        scenarios: Vec::new(),
        limits: (200.0, 2000.0),
        jerks: vec![5e4],
        tolerance: 0.05,
        q: None,
        machine: PathBuf::from("models/xyz_table.urdf"),
        python: None,
    };
    let mut args = std::env::args().skip(1);
    let number = |s: Option<String>| -> Result<f64, String> {
        s.ok_or("missing value")?
            .parse::<f64>()
            .map_err(|e| e.to_string())
    };
    let list = |s: Option<String>| -> Result<Vec<f64>, String> {
        s.ok_or("missing value")?
            .split(',')
            .map(|x| x.parse::<f64>().map_err(|e| e.to_string()))
            .collect()
    };
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--scenario" => o
                .scenarios
                .push(args.next().ok_or("--scenario FILE")?.into()),
            "--limits" => {
                let l = list(args.next())?;
                o.limits = (l[0], l[1]);
            }
            "--jerk" => o.jerks = list(args.next())?,
            "--tolerance" => o.tolerance = number(args.next())?,
            "--q" => o.q = Some(number(args.next())?),
            "--machine" => o.machine = args.next().ok_or("--machine URDF")?.into(),
            "--python" => o.python = args.next(),
            _ => o.files.push(arg.into()),
        }
    }
    Ok(o)
}

/// Plans `program` and compares with the bound; prints a table row.
fn compare(
    label: &str,
    program: &Program,
    axes: &AxisMap,
    settings: &PlanSettings,
    limits: &[AxisLimits],
    python: &str,
    jerk_label: &str,
) -> Result<(), String> {
    let plans = jerk_limited_plans(program, axes, settings)
        .map_err(|e| e.to_string())?
        .ok_or("not a jerk-limited planner")?;
    let planned: f64 = plans.iter().map(|(_, p)| p.duration()).sum();
    let length: f64 = plans
        .iter()
        .flat_map(|(path, plan)| plan.chain_geometry(path, 1e-4))
        .map(|chain| {
            chain
                .points
                .windows(2)
                .map(|w| {
                    (0..3.min(w[0].len()))
                        .map(|i| (w[1][i] - w[0][i]).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .sum::<f64>()
        })
        .sum();
    let problem = toppra::problem_json(&plans, limits, 1e-4);
    if let Some(path) = std::env::var_os("PLAN_VS_TOPPRA_DUMP") {
        std::fs::write(path, &problem).map_err(|e| e.to_string())?;
    }
    let bound = toppra::toppra_bound(python, &problem)?;
    println!(
        "| {label} | {:.0} mm | {jerk_label} | {planned:.2} s | {bound:.2} s | {:.2} |",
        length * 1e3,
        planned / bound
    );
    Ok(())
}

fn main() -> Result<(), String> {
    let o = parse()?;
    let python = match o.python.clone().or_else(toppra::toppra_python) {
        Some(p) => p,
        None => return Err("no Python with toppra (pip install toppra; or --python PY)".into()),
    };
    println!("| program | path (xyz) | jerk | cncsim | TOPP-RA bound | ratio |");
    println!("|---|---|---|---|---|---|");
    if !o.files.is_empty() {
        let machine = Machine::load(&o.machine).map_err(|e| e.to_string())?;
        let axes = AxisMap::new(&machine).map_err(|e| e.to_string())?;
        for file in &o.files {
            let program = read_program(file, &ReadOptions::default())
                .map_err(|e| format!("{}: {e}", file.display()))?;
            let name = file.file_name().unwrap_or_default().to_string_lossy();
            for &jerk in &o.jerks {
                let limits: Vec<AxisLimits> =
                    common::uniform_axes(&machine, o.limits.0, o.limits.1, jerk)
                        .iter()
                        .map(|a| a.limits)
                        .collect();
                let settings = PlanSettings {
                    planner: Planner::JerkLimited {
                        limits: limits.clone(),
                    },
                    period: 1e-3,
                    rapid_speed: 0.05,
                    blend: BlendChoice::Continuous {
                        tolerance: Some(o.tolerance * 1e-3),
                    },
                    axis_names: machine.axes.iter().map(|a| a.name.clone()).collect(),
                    naive_cam_tolerance: o.q.map(|q| q * 1e-3),
                    tool_lever_arms: tool_lever_arms(&machine, &program, &axes),
                };
                compare(
                    &name,
                    &program,
                    &axes,
                    &settings,
                    &limits,
                    &python,
                    &format!("{jerk:.0e}"),
                )?;
            }
        }
    }
    for path in &o.scenarios {
        let s = Scenario::load(Path::new(path)).map_err(|e| e.to_string())?;
        let machine = machine_for(&s).map_err(|e| e.to_string())?;
        let axes = AxisMap::new(&machine).map_err(|e| e.to_string())?;
        let program = load_checked_program(&s, &machine).map_err(|e| e.to_string())?;
        let mut settings =
            plan_settings(&s, &machine, s.planner.profile).map_err(|e| e.to_string())?;
        settings.tool_lever_arms = tool_lever_arms(&machine, &program, &axes);
        let Planner::JerkLimited { limits } = settings.planner.clone() else {
            return Err(format!("{}: not a jerk-limited scenario", path.display()));
        };
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        compare(
            &name, &program, &axes, &settings, &limits, &python, "scenario",
        )?;
    }
    Ok(())
}
