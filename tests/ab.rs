//! `cncsim ab`: PID against inverse dynamics on the A-C mill, same setpoints.

use std::process::Command;

fn ab(a: &str, b: &str, out: &std::path::Path) -> (std::process::Output, serde_json::Value) {
    let output = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(["ab", a, b, "--out", out.to_str().unwrap()])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let json = std::fs::read_to_string(out.join("ab.json"))
        .map(|t| serde_json::from_str(&t).unwrap())
        .unwrap_or_default();
    (output, json)
}

fn row(json: &serde_json::Value, metric: &str) -> (f64, f64) {
    let r = json["rows"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["metric"] == metric)
        .unwrap_or_else(|| panic!("no row {metric}"));
    (r["a"].as_f64().unwrap(), r["b"].as_f64().unwrap())
}

#[test]
fn inverse_dynamics_beats_pid_with_an_exact_model_and_not_with_a_wrong_one() {
    let dir = tempfile::tempdir().unwrap();
    let (out, json) = ab(
        "scenarios/mill_table2_pid.toml",
        "scenarios/mill_table2_id.toml",
        &dir.path().join("exact"),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (pid, id) = row(&json, "max contour error");
    assert!(id * 10.0 < pid, "contour error: PID {pid} µm, ID {id} µm");
    for axis in ["x", "y", "z"] {
        let (pid, id) = row(&json, &format!("{axis}: max following error"));
        assert!(id * 10.0 < pid, "{axis}: PID {pid} µm, ID {id} µm");
    }
    assert!(std::fs::read_to_string(dir.path().join("exact/ab.md"))
        .unwrap()
        .contains("| max contour error | µm |"));
    assert!(
        dir.path().join("exact/a_mill_table2_pid/run.rrd").is_file()
            && dir.path().join("exact/b_mill_table2_id/run.rrd").is_file()
    );

    // The controller's model 20 % heavy: without integral action the gravity over-compensation
    // leaves Z off by about 0.2·m_z·g/(m_eff·ωn²) ≈ 35 µm, far worse than PID.
    let (out, json) = ab(
        "scenarios/mill_table2_pid.toml",
        "scenarios/mill_table2_id_mass120.toml",
        &dir.path().join("heavy"),
    );
    assert!(out.status.success());
    let (pid, id) = row(&json, "z: max following error");
    assert!(
        id > 5.0 * pid && (25.0..50.0).contains(&id),
        "z: PID {pid} µm, heavy-model ID {id} µm"
    );
}

#[test]
fn variants_with_different_setpoints_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (out, _) = ab(
        "scenarios/mill_table2_pid.toml",
        "scenarios/xyz_circle_5mms.toml",
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("do not run the same setpoints"));
}
