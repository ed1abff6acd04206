//! Cost of a controller FMU per servo tick against the built-in controller of the same law: the
//! XYZ table's three-axis positional PID with feed-forward, built in (`type = "pid"`) and as
//! the FMU the FMI tests build (FMPy's FMI 3.0 template with the law filled in, compiled by
//! gcc: tests/oracles/fmi_controller.py). One `update` = what the servo loop calls once per
//! tick: for the FMU, fmi3SetFloat64 of the 12 inputs, fmi3DoStep, fmi3GetFloat64 of the 3
//! commands.
//!
//! Needs Python with FMPy (`CNCSIM_PYTHON`, else python3) and gcc to build the FMU; without
//! them only the built-in controller is measured.

use cncsim::control::{Controller, ControllerInput};
use cncsim::scenario::{Assembly, Scenario};
use criterion::{criterion_group, criterion_main, Criterion};
use std::path::Path;
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

const SCENARIO: &str = r#"name = "bench"
machine = "MACHINE"
[program]
circle = { center_mm = [100.0, 100.0], radius_mm = 5.0, start_angle_deg = 0.0, direction = "ccw", z_mm = 0.0 }
feed_mm_s = 20.0
[timing]
servo_period_ms = 1.0
physics_step_ms = 0.25
[actuator]
model = "dc-motor"
amplifier_mode = "voltage"
[controller]
CONTROLLER
"#;

const PID: &str = r#"type = "pid"
axes.x = { kp = 19800.0, ki = 6.1e5, kd = 146.0, ff1 = 55.6, ff2 = 0.8, output_limit = 6.0 }
axes.y = { kp = 19800.0, ki = 6.1e5, kd = 146.0, ff1 = 55.6, ff2 = 0.8, output_limit = 6.0 }
axes.z = { kp = 9700.0, ki = 3.0e5, kd = 85.0, ff1 = 13.7, ff2 = 0.39, output_limit = 3.125 }"#;

const FMU: &str = r#"type = "fmu"
fmu = "FMU"
parameters = { period = 0.001, kp_x = 19800.0, ki_x = 6.1e5, kd_x = 146.0, ff1_x = 55.6, ff2_x = 0.8, output_limit_x = 6.0, kp_y = 19800.0, ki_y = 6.1e5, kd_y = 146.0, ff1_y = 55.6, ff2_y = 0.8, output_limit_y = 6.0, kp_z = 9700.0, ki_z = 3.0e5, kd_z = 85.0, ff1_z = 13.7, ff2_z = 0.39, output_limit_z = 3.125 }"#;

fn controller(dir: &Path, name: &str, table: &str) -> Box<dyn Controller> {
    let text = SCENARIO
        .replace("MACHINE", &format!("{ROOT}/models/xyz_table.urdf"))
        .replace("CONTROLLER", table);
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    Assembly::new(&Scenario::load(&path).unwrap())
        .unwrap()
        .controller()
}

/// Builds the controller FMU; `None` (with why) without FMPy or gcc.
fn build_fmu(dir: &Path) -> Option<std::path::PathBuf> {
    let python = std::env::var("CNCSIM_PYTHON").unwrap_or_else(|_| "python3".into());
    let fmu = dir.join("pid_controller.fmu");
    let built = Command::new(&python)
        .arg(Path::new(ROOT).join("tests/oracles/fmi_controller.py"))
        .arg(&fmu)
        .arg("xyz")
        .output();
    match built {
        Ok(o) if o.status.success() => Some(fmu),
        _ => {
            eprintln!("controller FMU not built ({python} with fmpy and gcc needed): measuring the built-in PID only");
            None
        }
    }
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let mut controllers = vec![("built-in PID", controller(dir.path(), "pid", PID))];
    if let Some(fmu) = build_fmu(dir.path()) {
        let table = FMU.replace("FMU", &fmu.display().to_string());
        controllers.push(("FMU PID (FMI 3.0)", controller(dir.path(), "fmu", &table)));
    }
    let mut group = c.benchmark_group("controller update per servo tick (3 axes)");
    for (name, mut controller) in controllers {
        let mut command = [0.0; 3];
        let mut k = 0u64;
        group.bench_function(name, |b| {
            b.iter(|| {
                // A moving setpoint and a lagging measurement: every term of the law works.
                k += 1;
                let t = k as f64 * 1e-3;
                let s = [0.1 + 0.005 * t.cos(), 0.1 + 0.005 * t.sin(), 0.0];
                let v = [-0.005 * t.sin(), 0.005 * t.cos(), 0.0];
                let a = [-0.005 * t.cos(), -0.005 * t.sin(), 0.0];
                let m = [s[0] - 1e-6, s[1] + 1e-6, 0.0];
                let input = ControllerInput {
                    time: t,
                    setpoint_position: &s,
                    setpoint_velocity: &v,
                    setpoint_acceleration: &a,
                    measured_position: &m,
                    motor_position: &m,
                };
                controller.update(&input, &mut command);
                assert!(controller.fault().is_none());
                command[0]
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
