//! The TOPP-RA oracle: the time-optimal, acceleration-limited traversal of the geometry a plan
//! follows, computed by `tools/toppra_bound.py` with the `toppra` Python package.
#![allow(dead_code)]

use std::path::Path;
use std::process::Command;

use cncsim::plan::{AxisLimits, AxisPath, Plan};

/// Whether `CNCSIM_REQUIRE_ORACLES=1` asks for every oracle to be present.
pub fn oracles_required() -> bool {
    std::env::var("CNCSIM_REQUIRE_ORACLES").is_ok_and(|v| v == "1")
}

/// The Python interpreter with `toppra` importable (`CNCSIM_PYTHON`, else `python3`), if any.
pub fn toppra_python() -> Option<String> {
    let python = std::env::var("CNCSIM_PYTHON").unwrap_or_else(|_| "python3".to_string());
    let ok = Command::new(&python)
        .args(["-c", "import toppra"])
        .output()
        .is_ok_and(|o| o.status.success());
    ok.then_some(python)
}

/// The oracle's input: every chain of every plan (with the path it was planned from) as points
/// at most `max_step` apart with the programmed feed at each, and the axis velocity and
/// acceleration limits.
pub fn problem_json(plans: &[(AxisPath, Plan)], limits: &[AxisLimits], max_step: f64) -> String {
    let chains: Vec<serde_json::Value> = plans
        .iter()
        .flat_map(|(path, plan)| plan.chain_geometry(path, max_step))
        .map(|chain| {
            let feeds: Vec<serde_json::Value> = chain
                .feeds
                .iter()
                .map(|f| match f {
                    Some(f) => serde_json::json!({"speed": f.speed, "weights": f.weights}),
                    None => serde_json::Value::Null,
                })
                .collect();
            serde_json::json!({"points": chain.points, "feeds": feeds})
        })
        .collect();
    serde_json::json!({
        "velocity": limits.iter().map(|l| l.velocity).collect::<Vec<_>>(),
        "acceleration": limits.iter().map(|l| l.acceleration).collect::<Vec<_>>(),
        "chains": chains,
    })
    .to_string()
}

/// Runs the oracle on `problem` (JSON); the total time-optimal duration (s).
pub fn toppra_bound(python: &str, problem: &str) -> Result<f64, String> {
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    let input = dir.path().join("problem.json");
    std::fs::write(&input, problem).map_err(|e| e.to_string())?;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/toppra_bound.py");
    let out = Command::new(python)
        .arg(script)
        .arg(&input)
        .output()
        .map_err(|e| e.to_string())?;
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    let answer: serde_json::Value =
        serde_json::from_slice(&out.stdout).map_err(|e| e.to_string())?;
    answer["total"]
        .as_f64()
        .ok_or_else(|| format!("no total in {answer}"))
}
