//! `cncsim dynamics` reproduces the reference inverse-dynamics fixture to 1e-6.

use std::process::Command;

fn dynamics(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .arg("dynamics")
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap()
}

#[test]
fn fixture_values_are_reproduced() {
    let out = dynamics(&[
        "tests/fixtures/ac_table_eccentric.urdf",
        "--q",
        "0.3,1.0",
        "--qd",
        "0.5,-1.0",
        "--qdd",
        "2.0,3.0",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let vector = |key: &str| -> Vec<f64> {
        json[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    // Reference values: tests/fixtures/ac_table_eccentric.md.
    let close = |a: &[f64], b: &[f64]| {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-6)
    };
    assert!(close(&vector("tau"), &[2.497425, 0.798267]), "{json}");
    assert!(close(&vector("coriolis"), &[0.028827, -0.000682]), "{json}");
    assert!(close(&vector("gravity"), &[1.278697, 0.469910]), "{json}");
    let m: Vec<f64> = json["mass_matrix"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| r.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()))
        .collect();
    assert!(
        close(&m, &[0.62534219, -0.02026134, -0.02026134, 0.12318750]),
        "{json}"
    );
}

#[test]
fn bad_dynamics_input_is_an_error_not_a_panic() {
    for (args, words) in [
        (
            vec![
                "tests/fixtures/ac_table_eccentric.urdf",
                "--q",
                "0.3",
                "--qd",
                "0,0",
                "--qdd",
                "0,0",
            ],
            "q has 1 values, expected 2",
        ),
        (
            vec![
                "tests/fixtures/ac_table_eccentric.urdf",
                "--q",
                "nan,0",
                "--qd",
                "0,0",
                "--qdd",
                "0,0",
            ],
            "q[0] (joint 'A') is NaN: expected a finite number",
        ),
        (
            vec!["no/such.urdf", "--q", "0", "--qd", "0", "--qdd", "0"],
            "cannot read machine model",
        ),
    ] {
        let out = dynamics(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(
            err.contains(words) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    }
}
