//! `cncsim bode`, the frequency response of a servo axis, end to end and against what is known
//! independently of it:
//! - measured on the analytic reference model (the axis's ODEs), the response equals cncsim's
//!   linearised sampled model point by point (the measurement's own accuracy);
//! - measured on the physics (Rapier), it agrees with the same loop built by python-control
//!   from the scenario, drive file and URDF (`tests/oracles/bode_oracle.py`), margins from
//!   `control.margin`; skipped without python-control unless `CNCSIM_REQUIRE_ORACLES=1` (then a
//!   failure);
//! - bad options are refused with exit status 2.

mod common;

use common::{cncsim, stderr};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Runs `cncsim bode ARGS --json --out OUT` and returns the report.
fn bode_json(args: &[&str], out: &Path) -> serde_json::Value {
    common::cncsim_json("bode", args, out)
}

fn numbers(v: &serde_json::Value, key: &str) -> Vec<f64> {
    v[key]
        .as_array()
        .unwrap_or_else(|| panic!("no array {key}"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn number(v: &serde_json::Value, key: &str) -> Option<f64> {
    v[key].as_f64()
}

/// The difference of two angles (degrees), wrapped into (−180, 180].
fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    if d > 180.0 {
        d - 360.0
    } else {
        d
    }
}

const SCENARIO: &str = "scenarios/xyz_circle_5mms.toml";

#[test]
fn on_the_analytic_model_the_measurement_is_the_linear_model() {
    let dir = tempfile::tempdir().unwrap();
    // PID on DC motors in voltage mode; a cascade on ideal torque drives.
    let cascade = "scenarios/ballbar_xyz_servo_mismatch.toml";
    for (scenario, axis, lp) in [
        (SCENARIO, "z", "plant"),
        (SCENARIO, "x", "position"),
        (cascade, "x", "velocity"),
        (cascade, "y", "position"),
    ] {
        let r = bode_json(
            &[
                scenario,
                "--axis",
                axis,
                "--loop",
                lp,
                "--analytic",
                "--from",
                "3",
                "--to",
                "300",
                "--per-decade",
                "5",
            ],
            &dir.path().join(format!("{axis}_{lp}")),
        );
        let f = numbers(&r, "frequencies_hz");
        let (mag, phase, coh) = (
            numbers(&r, "magnitude_db"),
            numbers(&r, "phase_deg"),
            numbers(&r, "coherence"),
        );
        let model = &r["model_at_points"];
        let (mm, mp) = (numbers(model, "magnitude_db"), numbers(model, "phase_deg"));
        assert!(f.len() >= 11, "{f:?}");
        for i in 0..f.len() {
            assert!(
                (mag[i] - mm[i]).abs() < 0.05,
                "{axis} {lp} {} Hz: {} dB measured, {} dB model",
                f[i],
                mag[i],
                mm[i]
            );
            assert!(
                angle_diff(phase[i], mp[i]).abs() < 0.3,
                "{axis} {lp} {} Hz: {}° measured, {}° model",
                f[i],
                phase[i],
                mp[i]
            );
            assert!(coh[i] > 0.999, "{} Hz: coherence {}", f[i], coh[i]);
        }
        // The margins of the measured open loop are the model's.
        let m = &r["model_figures"];
        let (gm, pm) = (
            number(&r, "gain_margin_db").unwrap(),
            number(&r, "phase_margin_deg").unwrap(),
        );
        assert!(
            (gm - number(m, "gain_margin_db").unwrap()).abs() < 0.3,
            "{gm}"
        );
        assert!(
            (pm - number(m, "phase_margin_deg").unwrap()).abs() < 1.0,
            "{pm}"
        );
    }
}

/// The Python with python-control, or `None` (a failure under `CNCSIM_REQUIRE_ORACLES=1`).
fn python_with_control() -> Option<String> {
    common::oracle_python("import control, numpy", "control (python-control)")
}

fn oracle(python: &str, scenario: &Path, axis: &str, lp: &str, f: &[f64]) -> serde_json::Value {
    let o = Command::new(python)
        .arg(root().join("tests/oracles/bode_oracle.py"))
        .arg(scenario)
        .args([axis, lp, &serde_json::to_string(f).unwrap()])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "oracle failed on {} {axis} {lp}: {}\n{}",
        scenario.display(),
        stderr(&o),
        std::fs::read_to_string(scenario).unwrap_or_default()
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

/// A copy of the bundled scenario with a finer physics step, written beside the original so
/// that its machine path resolves.
fn scenario_with_step(dir: &Path, step_ms: f64) -> PathBuf {
    let text = std::fs::read_to_string(root().join(SCENARIO)).unwrap();
    let text = text
        .replace(
            "physics_step_ms = 0.25",
            &format!("physics_step_ms = {step_ms}"),
        )
        .replace(
            "machine = \"../models/xyz_table.urdf\"",
            &format!(
                "machine = \"{}\"",
                root().join("models/xyz_table.urdf").display()
            ),
        );
    let path = dir.join(format!("xyz_step_{step_ms}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Asserts that responses `a` (cncsim) and `b` (python-control), magnitudes (dB) and phases
/// (degrees) at frequencies `f`, agree within `db` and `deg` at every frequency.
fn assert_agree(
    label: &str,
    f: &[f64],
    (am, ap): (&[f64], &[f64]),
    (bm, bp): (&[f64], &[f64]),
    (db, deg): (f64, f64),
) {
    for i in 0..f.len() {
        assert!(
            (am[i] - bm[i]).abs() < db,
            "{label} {} Hz: {} dB cncsim, {} dB python-control",
            f[i],
            am[i],
            bm[i]
        );
        assert!(
            angle_diff(ap[i], bp[i]).abs() < deg,
            "{label} {} Hz: {}° cncsim, {}° python-control",
            f[i],
            ap[i],
            bp[i]
        );
    }
}

#[test]
fn on_the_physics_the_response_agrees_with_python_control() {
    let Some(python) = python_with_control() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // Rapier integrates at first order: at the scenario's 0.25 ms step the physics leads the
    // sampled model by about ω·dt/2 (5° at 110 Hz). A quarter of the step keeps that within
    // 3° up to the default top of the sweep, 0.4 of the servo rate (400 Hz).
    let scenario = scenario_with_step(dir.path(), 0.0625);
    for (axis, lp) in [("z", "plant"), ("z", "position"), ("x", "position")] {
        let s = scenario.display().to_string();
        let r = bode_json(
            &[&s, "--axis", axis, "--loop", lp, "--per-decade", "6"],
            &dir.path().join(format!("{axis}_{lp}")),
        );
        assert_eq!(numbers(&r, "frequencies_hz").last(), Some(&400.0));
        let f = numbers(&r, "frequencies_hz");
        let o = oracle(&python, &scenario, axis, lp, &f);
        let (mag, phase) = (numbers(&r, "magnitude_db"), numbers(&r, "phase_deg"));
        let (om, op) = (numbers(&o, "magnitude_db"), numbers(&o, "phase_deg"));
        let label = format!("{axis} {lp} (physics)");
        assert_agree(&label, &f, (&mag, &phase), (&om, &op), (1.0, 5.0));
        // The open loop measured at the plant input against python-control's C·P, and the
        // margins against control.margin.
        let ol = &r["open_loop"];
        let (lm, lp_) = (numbers(ol, "magnitude_db"), numbers(ol, "phase_deg"));
        let (olm, olp) = (
            numbers(&o, "open_loop_magnitude_db"),
            numbers(&o, "open_loop_phase_deg"),
        );
        let label = format!("{axis} open loop (physics)");
        assert_agree(&label, &f, (&lm, &lp_), (&olm, &olp), (1.0, 5.0));
        let close = |key: &str, tol: f64| {
            let (a, b) = (number(&r, key), number(&o, key));
            match (a, b) {
                (Some(a), Some(b)) => assert!((a - b).abs() < tol, "{axis} {key}: {a} vs {b}"),
                _ => panic!("{axis} {key}: cncsim {a:?}, python-control {b:?}"),
            }
        };
        close("phase_margin_deg", 5.0);
        close("gain_margin_db", 1.0);
        close(
            "gain_crossover_hz",
            0.02 * number(&o, "gain_crossover_hz").unwrap(),
        );
        close(
            "phase_crossover_hz",
            0.03 * number(&o, "phase_crossover_hz").unwrap(),
        );
    }
}

#[test]
fn files_table_and_recording() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bode");
    let out_s = out.display().to_string();
    let o = cncsim(&[
        "bode",
        SCENARIO,
        "--axis",
        "y",
        "--analytic",
        "--from",
        "5",
        "--to",
        "100",
        "--per-decade",
        "3",
        "--out",
        &out_s,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    for needle in [
        "resonance",
        "bandwidth",
        "gain margin",
        "phase margin",
        "coherence",
    ] {
        assert!(text.contains(needle), "{needle} not in\n{text}");
    }
    let png = std::fs::read(out.join("bode.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let csv = std::fs::read_to_string(out.join("bode.csv")).unwrap();
    assert!(csv.starts_with("frequency_hz,magnitude_db,phase_deg,coherence,"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("bode.json")).unwrap()).unwrap();
    for key in [
        "resonances_hz",
        "antiresonances_hz",
        "bandwidth_hz",
        "gain_margin_db",
        "phase_margin_deg",
        "frequencies_hz",
        "magnitude_db",
        "phase_deg",
        "coherence",
    ] {
        assert!(json.get(key).is_some(), "{key} missing");
    }
    let entities = common::rrd_rows(&out.join("bode.rrd"));
    for part in [
        "magnitude_db/measured",
        "magnitude_db/model",
        "phase_deg/measured",
        "coherence",
    ] {
        let entity = format!("/bode/y/plant/{part}");
        assert!(
            entities.contains_key(&entity),
            "{entity} not in {:?}",
            entities.keys()
        );
    }
}

#[test]
fn impossible_options_are_refused() {
    for (args, needle) in [
        (vec!["--from", "50", "--to", "20"], "below --to"),
        (vec!["--from", "-1"], "positive"),
        (vec!["--to", "500"], "Nyquist"),
        (vec!["--to", "800"], "Nyquist"),
        (vec!["--per-decade", "0"], "--per-decade"),
        (vec!["--loop", "velocity"], "cascade"),
    ] {
        let mut all = vec!["bode", SCENARIO, "--axis", "x"];
        all.extend(args.iter());
        let o = cncsim(&all);
        assert_eq!(o.status.code(), Some(2), "{all:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{all:?}: {}", stderr(&o));
    }
    let o = cncsim(&["bode", SCENARIO, "--axis", "w"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no such axis"), "{}", stderr(&o));
}

/// The bundled scenario with `extra_expect` appended to its `[expect]` table and `tables`
/// after it, written where its machine path resolves.
fn scenario_with(dir: &Path, name: &str, extra_expect: &str, tables: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join(SCENARIO)).unwrap();
    assert!(
        text.trim_end().ends_with("max = 0.001 }"),
        "[expect] is the last table"
    );
    let text = text.replace(
        "machine = \"../models/xyz_table.urdf\"",
        &format!(
            "machine = \"{}\"",
            root().join("models/xyz_table.urdf").display()
        ),
    ) + extra_expect
        + tables;
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_scenario_bounds_its_frequency_response() {
    let dir = tempfile::tempdir().unwrap();
    let table = "\n[frequency_response.z]\nloop = \"plant\"\nfrom_hz = 5.0\nto_hz = 300.0\nper_decade = 6\n";
    // The Z loop measured on the physics: phase margin 29.0° at 66.5 Hz (`cncsim bode`).
    let within = "frequency_response.z.phase_margin_deg = { min = 25.0, max = 33.0 }\nfrequency_response.z.gain_crossover_hz = { min = 60.0, max = 72.0 }\n";
    let good = scenario_with(dir.path(), "good", within, table);
    let out = dir.path().join("out").display().to_string();
    let o = cncsim(&["check", good.to_str().unwrap(), "--out", &out]);
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        stderr(&o)
    );
    let metrics: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("out/xyz_circle_5mms/metrics.json")).unwrap(),
    )
    .unwrap();
    let pm = metrics["frequency_response"]["z"]["phase_margin_deg"]
        .as_f64()
        .unwrap();
    assert!((25.0..33.0).contains(&pm), "{pm}");
    assert!(dir
        .path()
        .join("out/xyz_circle_5mms/frequency_response_z_plant/bode.png")
        .is_file());

    // A bound the loop breaches fails the check (exit status 1) and names the metric.
    let tight = "frequency_response.z.phase_margin_deg = { min = 45.0 }\n";
    let bad = scenario_with(dir.path(), "tight", tight, table);
    let o = cncsim(&["check", bad.to_str().unwrap(), "--out", &out]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stdout).contains("frequency_response.z.phase_margin_deg"));

    // Bad tables are refused before anything runs, with the place in the file.
    for (name, expect, tables, needle) in [
        (
            "nyquist",
            "",
            "\n[frequency_response.z]\nto_hz = 600.0\n",
            "Nyquist",
        ),
        (
            "order",
            "",
            "\n[frequency_response.z]\nfrom_hz = 50.0\nto_hz = 20.0\n",
            "must be above from_hz",
        ),
        (
            "velocity",
            "",
            "\n[frequency_response.z]\nloop = \"velocity\"\n",
            "cascade",
        ),
        ("axis", "", "\n[frequency_response.w]\n", "no axis 'w'"),
        (
            "key",
            "",
            "\n[frequency_response.z]\nfrom = 5.0\n",
            "unknown field",
        ),
        (
            "metric",
            "frequency_response.x.phase_margin_deg = { min = 1.0 }\n",
            table,
            "no such metric",
        ),
    ] {
        let path = scenario_with(dir.path(), name, expect, tables);
        let o = cncsim(&["check", path.to_str().unwrap(), "--out", &out]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{name}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("{name}.toml:")),
            "{name}: no place: {}",
            stderr(&o)
        );
    }
}

/// The compliant XYZ table (`scenarios/xyz_circle_compliant.toml`: X's belt and gearbox a
/// 7·10⁵ N/m spring) with X's PID lowered to gains its first mode allows (the rigid design
/// the scenario keeps is unstable on it: python-control's gain margin −17.5 dB).
fn compliant_scenario(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenarios/xyz_circle_compliant.toml")).unwrap();
    let rigid_gains = "axes.x = { kp = 19800.0, ki = 6.1e5, kd = 146.0";
    assert!(text.contains(rigid_gains));
    let text = text
        .replace(rigid_gains, "axes.x = { kp = 2000.0, ki = 2.0e4, kd = 0.0")
        // On the carriage's linear scale, where the loop sees the mode.
        .replace("position = \"motor\"", "position = \"carriage\"")
        .replace(
            "machine = \"../models/xyz_table.urdf\"",
            &format!(
                "machine = \"{}\"",
                root().join("models/xyz_table.urdf").display()
            ),
        );
    let path = dir.join("xyz_compliant_soft_x.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_compliant_axis_shows_its_two_mass_resonance() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = compliant_scenario(dir.path());
    let s = scenario.display().to_string();
    // On the analytic model (the lead's two-mass ODEs) the measurement is the linear model.
    let r = bode_json(
        &[&s, "--axis", "x", "--analytic", "--to", "200"],
        &dir.path().join("analytic"),
    );
    let (mag, phase) = (numbers(&r, "magnitude_db"), numbers(&r, "phase_deg"));
    let model = &r["model_at_points"];
    let (mm, mp) = (numbers(model, "magnitude_db"), numbers(model, "phase_deg"));
    for i in 0..mag.len() {
        assert!(
            (mag[i] - mm[i]).abs() < 0.05,
            "analytic point {i}: {} vs {}",
            mag[i],
            mm[i]
        );
        assert!(
            angle_diff(phase[i], mp[i]).abs() < 0.3,
            "analytic point {i}"
        );
    }
    // The undamped two-mass frequencies of the drive data: √(k(1/m_d + 1/m_c)) and √(k/m_c).
    let (k, md, mc) = (7.0e5, 3.89e-5 * 4000.0f64.powi(2), 17.74585);
    let resonance = (k * (1.0 / md + 1.0 / mc)).sqrt() / std::f64::consts::TAU;
    let model_res = numbers(&r["model_figures"], "resonances_hz");
    assert_eq!(model_res.len(), 1, "{model_res:?}");
    assert!(
        (model_res[0] / resonance - 1.0).abs() < 0.02,
        "{model_res:?} vs {resonance}"
    );

    let Some(python) = python_with_control() else {
        return;
    };
    // On the physics, against python-control: the resonance within 2 %, the response within
    // 1 dB and 5° away from it (Rapier's lead stays below 5° up to 80 Hz at its 0.25 ms step).
    let r = bode_json(
        &[&s, "--axis", "x", "--to", "80"],
        &dir.path().join("physics"),
    );
    let f = numbers(&r, "frequencies_hz");
    let o = oracle(&python, &scenario, "x", "plant", &f);
    let measured = numbers(&r, "resonances_hz");
    let expected = numbers(&o, "resonances_hz");
    assert_eq!(expected.len(), 1, "python-control: {expected:?}");
    assert_eq!(measured.len(), 1, "measured: {measured:?}");
    assert!(
        (measured[0] / expected[0] - 1.0).abs() < 0.01,
        "resonance {measured:?} vs python-control {expected:?}"
    );
    let anti = numbers(&r, "antiresonances_hz");
    let anti_expected = numbers(&o, "antiresonances_hz");
    assert_eq!(
        anti.len(),
        anti_expected.len(),
        "{anti:?} vs {anti_expected:?}"
    );
    for (a, b) in anti.iter().zip(&anti_expected) {
        assert!((a / b - 1.0).abs() < 0.01, "antiresonance {a} vs {b}");
    }
    let (mag, phase) = (numbers(&r, "magnitude_db"), numbers(&r, "phase_deg"));
    let (om, op) = (numbers(&o, "magnitude_db"), numbers(&o, "phase_deg"));
    let near = |f: f64| {
        expected
            .iter()
            .chain(&anti_expected)
            .any(|&c| (f / c - 1.0).abs() < 0.1)
    };
    let mut compared = 0;
    for i in 0..f.len() {
        if near(f[i]) {
            continue;
        }
        compared += 1;
        assert!(
            (mag[i] - om[i]).abs() < 1.0,
            "{} Hz: {} vs {} dB",
            f[i],
            mag[i],
            om[i]
        );
        assert!(
            angle_diff(phase[i], op[i]).abs() < 5.0,
            "{} Hz: {}° vs {}°",
            f[i],
            phase[i],
            op[i]
        );
    }
    assert!(compared >= 15, "{compared} points away from the resonance");
    for (key, tol) in [("phase_margin_deg", 5.0), ("gain_margin_db", 1.0)] {
        let (a, b) = (number(&r, key).unwrap(), number(&o, key).unwrap());
        assert!((a - b).abs() < tol, "{key}: {a} vs python-control {b}");
    }
}

#[test]
fn a_lightly_damped_resonance_is_located_by_a_search_with_the_default_options() {
    // The XYZ table's X belt as a 6·10⁵ N/m spring with no damping of its own (ζ ≈ 0.005 from
    // the motor's back-EMF), friction and backlash off: the case a coarse grid and unsettled
    // points measured 3 % low. Default options: the resonance must match the undamped
    // two-mass formula of the drive data, √(k(1/m_d + 1/m_c)), on the physics and on the
    // analytic model.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(compliant_scenario(dir.path()))
        .unwrap()
        .replacen(
            "[mechanics.transmission.y]\nstiffness_n_per_m = 7.0e5\ndamping_n_s_per_m = 368.0\n",
            "",
            1,
        )
        .replacen(
            "stiffness_n_per_m = 7.0e5\ndamping_n_s_per_m = 368.0",
            "stiffness_n_per_m = 6.0e5",
            1,
        );
    assert!(
        text.contains("stiffness_n_per_m = 6.0e5\n")
            && !text.contains("[mechanics.transmission.y]"),
        "{text}"
    );
    let path = dir.path().join("light.toml");
    std::fs::write(&path, text).unwrap();
    let s = path.display().to_string();
    let (k, md, mc) = (6.0e5, 3.89e-5 * 4000.0f64.powi(2), 17.74585);
    let two_mass = (k * (1.0 / md + 1.0 / mc)).sqrt() / std::f64::consts::TAU;
    for (what, extra) in [("physics", None), ("analytic", Some("--analytic"))] {
        let mut args = vec![s.as_str(), "--axis", "x"];
        args.extend(extra);
        let r = bode_json(&args, &dir.path().join(what));
        let measured = numbers(&r, "resonances_hz");
        assert_eq!(measured.len(), 1, "{what}: {measured:?}");
        // Physics: Rapier's 0.25 ms step adds about 0.1 %.
        assert!(
            (measured[0] / two_mass - 1.0).abs() < 0.005,
            "{what}: {measured:?} vs the two-mass {two_mass} Hz"
        );
        let model = numbers(&r["model_figures"], "resonances_hz");
        assert!(
            (model[0] / two_mass - 1.0).abs() < 0.001,
            "model {model:?} vs {two_mass}"
        );
        // The search reached its resolution, and the loop's ringing set the settling.
        assert!(number(&r, "search_resolution").unwrap() <= 1e-3);
        assert!(number(&r, "settle_s").unwrap() > 1.0, "{}", r["settle_s"]);
        eprintln!(
            "{what}: resonance {:.3} Hz, model {:.3} Hz, two-mass {two_mass:.3} Hz, settle {:.2} s",
            measured[0],
            model[0],
            number(&r, "settle_s").unwrap()
        );
    }
}

#[test]
fn the_command_filters_are_in_the_linear_model() {
    // The cascade of the servo-mismatch scenario with a notch at 40 Hz (−20 dB at its centre)
    // and a 150 Hz low-pass on X's command: measured on the analytic model, the response is
    // the linear law with the filters' biquads, point by point.
    let dir = tempfile::tempdir().unwrap();
    let text =
        std::fs::read_to_string(root().join("scenarios/ballbar_xyz_servo_mismatch.toml")).unwrap();
    assert!(text.contains("cascade.x = { "));
    let text = text
        .replace(
            "cascade.x = { ",
            "cascade.x = { notch_hz = 40.0, notch_width_hz = 20.0, notch_depth = 0.1, torque_lowpass_hz = 150.0, ",
        )
        .replace(
            "machine = \"../models/xyz_table.urdf\"",
            &format!(
                "machine = \"{}\"",
                root().join("models/xyz_table.urdf").display()
            ),
        );
    let scenario = dir.path().join("filtered.toml");
    std::fs::write(&scenario, text).unwrap();
    let s = scenario.display().to_string();
    let r = bode_json(
        &[
            &s,
            "--axis",
            "x",
            "--loop",
            "velocity",
            "--analytic",
            "--to",
            "300",
        ],
        &dir.path().join("out"),
    );
    let (mag, phase) = (numbers(&r, "magnitude_db"), numbers(&r, "phase_deg"));
    let model = &r["model_at_points"];
    let (mm, mp) = (numbers(model, "magnitude_db"), numbers(model, "phase_deg"));
    let f = numbers(&r, "frequencies_hz");
    for i in 0..mag.len() {
        assert!(
            (mag[i] - mm[i]).abs() < 0.05,
            "{} Hz: {} vs {} dB",
            f[i],
            mag[i],
            mm[i]
        );
        assert!(angle_diff(phase[i], mp[i]).abs() < 0.3, "{} Hz", f[i]);
    }
}

/// A copy of bundled scenario `src` with the `[controller]` type set to `kind`, the line of
/// `cascade.<axis>` replaced by `cascade_line` (when given) and the machine path made absolute.
fn scenario_copy(
    dir: &Path,
    src: &str,
    kind: &str,
    cascade_line: Option<(&str, &str)>,
    extra: &[(&str, &str)],
) -> PathBuf {
    let mut text = std::fs::read_to_string(root().join(src)).unwrap();
    for (from, to) in extra {
        assert!(text.contains(from), "{src}: no '{from}'");
        text = text.replace(from, to);
    }
    let own_type = text
        .lines()
        .find(|l| l.starts_with("type = \""))
        .expect("a [controller] type")
        .to_string();
    text = text.replacen(
        &format!("\n{own_type}\n"),
        &format!("\ntype = \"{kind}\"\n"),
        1,
    );
    if let Some((axis, line)) = cascade_line {
        let prefix = format!("cascade.{axis} = {{");
        let old = text
            .lines()
            .find(|l| l.starts_with(&prefix))
            .unwrap_or_else(|| panic!("{src}: no {prefix}"))
            .to_string();
        text = text.replacen(&format!("\n{old}\n"), &format!("\n{line}\n"), 1);
    }
    let machine = text
        .lines()
        .find(|l| l.starts_with("machine = \"../"))
        .expect("a bundled machine")
        .to_string();
    let path = machine
        .trim_start_matches("machine = \"../")
        .trim_end_matches('"');
    text = text.replace(
        &machine,
        &format!("machine = \"{}\"", root().join(path).display()),
    );
    let out = dir.join(format!(
        "{}_{kind}.toml",
        Path::new(src).file_stem().unwrap().to_string_lossy()
    ));
    std::fs::write(&out, text).unwrap();
    out
}

#[test]
fn the_one_linear_model_is_python_controls() {
    // The linear model `bode` lays over its measurements (and `tune` designs on), against the
    // same loops built by python-control from the scenario, drive file and URDF alone: the
    // responses at every frequency of the sweep and the open loop's margins. PID on the paper's
    // table (current mode, carriage feedback, 5 ms); a cascade on the compliant table (DC
    // motors in voltage mode, two-mass drive trains); a cascade with a notch and a low-pass on
    // ideal torque drives.
    let Some(python) = python_with_control() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let paper = scenario_copy(
        dir.path(),
        "scenarios/paper_circle_05mms.toml",
        "pid",
        None,
        &[],
    );
    let compliant = scenario_copy(
        dir.path(),
        "scenarios/xyz_circle_compliant.toml",
        "cascade",
        None,
        &[],
    );
    let filtered = scenario_copy(
        dir.path(),
        "scenarios/ballbar_xyz_servo_mismatch.toml",
        "cascade",
        None,
        &[(
            "cascade.x = { ",
            "cascade.x = { notch_hz = 40.0, notch_width_hz = 20.0, notch_depth = 0.1, torque_lowpass_hz = 150.0, ",
        )],
    );
    for (scenario, axis, lp, to) in [
        (&paper, "x", "position", "90"),
        (&paper, "y", "plant", "90"),
        (&compliant, "x", "velocity", "300"),
        (&compliant, "y", "position", "300"),
        (&filtered, "x", "velocity", "300"),
        (&filtered, "x", "position", "300"),
    ] {
        let s = scenario.display().to_string();
        let r = bode_json(
            &[
                &s,
                "--axis",
                axis,
                "--loop",
                lp,
                "--analytic",
                "--from",
                "1",
                "--to",
                to,
                "--per-decade",
                "6",
            ],
            &dir.path().join(format!("{axis}_{lp}_{to}")),
        );
        let f = numbers(&r, "frequencies_hz");
        let model = &r["model_at_points"];
        let (mm, mp) = (numbers(model, "magnitude_db"), numbers(model, "phase_deg"));
        // The oracle also evaluates the open loop at the model's crossovers: cncsim's margins
        // are read where python-control's open loop has its gain at 0 dB and its phase at
        // −180° (control.margin reports the one crossing it deems critical, which on a
        // conditionally stable loop is not the one cncsim reports).
        let figures = &r["model_figures"];
        let gc = number(figures, "gain_crossover_hz");
        let pc = number(figures, "phase_crossover_hz");
        let mut asked = f.clone();
        asked.extend(gc.iter().chain(pc.iter()));
        let o = oracle(&python, scenario, axis, lp, &asked);
        let (om, op) = (numbers(&o, "magnitude_db"), numbers(&o, "phase_deg"));
        let (lm, lpz) = (
            numbers(&o, "open_loop_magnitude_db"),
            numbers(&o, "open_loop_phase_deg"),
        );
        let label = format!("{s} {axis} {lp}");
        assert_agree(&label, &f, (&mm, &mp), (&om, &op), (0.01, 0.1));
        let mut at = f.len();
        if gc.is_some() {
            let pm = number(figures, "phase_margin_deg").unwrap();
            assert!(
                lm[at].abs() < 0.01,
                "{s} {axis} {lp}: |L| = {} dB at cncsim's gain crossover",
                lm[at]
            );
            assert!(
                angle_diff(180.0 + lpz[at], pm).abs() < 0.1,
                "{s} {axis} {lp}: phase margin {pm}° in cncsim, {}° in python-control's L",
                180.0 + lpz[at]
            );
            at += 1;
        }
        if pc.is_some() {
            let gm = number(figures, "gain_margin_db").unwrap();
            assert!(
                angle_diff(lpz[at], 180.0).abs() < 0.1,
                "{s} {axis} {lp}: ∠L = {}° at cncsim's phase crossover",
                lpz[at]
            );
            assert!(
                (gm + lm[at]).abs() < 0.05,
                "{s} {axis} {lp}: gain margin {gm} dB in cncsim, {} dB in python-control's L",
                -lm[at]
            );
        }
    }
}

#[test]
fn the_cascade_design_has_its_margins_in_python_control() {
    // `tune --cascade` designs on the one linear model; python-control, given the gains it
    // prints, finds the velocity loop's crossover and margins where the design says they are:
    // a rigid DC-motor axis at 5 ms, a two-mass one held below its antiresonance, and an
    // ideal torque axis.
    let Some(python) = python_with_control() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for (src, axis) in [
        ("scenarios/paper_circle_05mms.toml", "y"),
        ("scenarios/xyz_circle_compliant.toml", "x"),
        ("scenarios/ballbar_xyz_servo_mismatch.toml", "z"),
    ] {
        let path = root().join(src).display().to_string();
        let o = cncsim(&["tune", &path, "--axis", axis, "--cascade", "--json"]);
        assert!(o.status.success(), "{src}: {}", stderr(&o));
        let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let design = &report["design"];
        let line = report["toml"].as_str().unwrap();
        let scenario = scenario_copy(dir.path(), src, "cascade", Some((axis, line)), &[]);
        let crossover = number(design, "velocity_bandwidth_hz").unwrap();
        let o = oracle(&python, &scenario, axis, "velocity", &[1.0, crossover]);
        let pc = number(&o, "gain_crossover_hz").unwrap();
        assert!(
            (pc / crossover - 1.0).abs() < 0.005,
            "{src} {axis}: crossover {crossover} Hz designed, {pc} Hz in python-control"
        );
        for (key, tol) in [("phase_margin_deg", 0.3), ("gain_margin_db", 0.1)] {
            let (a, b) = (number(design, key).unwrap(), number(&o, key).unwrap());
            assert!(
                (a - b).abs() < tol,
                "{src} {axis} {key}: designed {a}, python-control {b}"
            );
        }
        assert!(number(&o, "phase_margin_deg").unwrap() >= 49.5, "{o}");
        assert!(number(&o, "gain_margin_db").unwrap() >= 5.9, "{o}");
    }
}
