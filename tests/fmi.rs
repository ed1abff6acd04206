//! FMI co-simulation (docs/fmi.md): a controller FMU built by another tool (FMPy's FMI 3.0
//! source template with a PID filled in, compiled by gcc: tests/oracles/fmi_controller.py)
//! runs as cncsim's controller and gives the built-in PID's numbers; cncsim's plant exported
//! as an FMU and stepped by an independent master (FMPy: tests/oracles/fmi_master.py) with
//! that controller gives `cncsim run`'s numbers; bad FMUs are refused with the variable named.
//!
//! The oracle is Python with FMPy (`CNCSIM_PYTHON`, else python3) and a C compiler (`CC`,
//! else gcc); without them the tests skip, unless CNCSIM_REQUIRE_ORACLES=1 (CI), where they
//! fail.

mod common;

use cncsim::scenario::{Assembly, RunOptions, Scenario};
use cncsim::sim::Trace;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

const CNCSIM: &str = env!("CARGO_BIN_EXE_cncsim");
const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The PID of every axis: kp, ki, kd, ff1, ff2, output limit (the default scenario's gains,
/// with velocity and acceleration feed-forward from each axis's nominal plant).
const GAINS: [(&str, [f64; 6]); 3] = [
    ("x", [19800.0, 6.1e5, 146.0, 55.6, 0.8, 6.0]),
    ("y", [19800.0, 6.1e5, 146.0, 55.6, 0.8, 6.0]),
    ("z", [9700.0, 3.0e5, 85.0, 13.7, 0.39, 3.125]),
];

/// The oracle's Python, when it has FMPy and a C compiler is there for the controller FMU.
fn python() -> Option<String> {
    let cc = std::env::var("CC").unwrap_or_else(|_| "gcc".into());
    let compiler = Command::new(&cc)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !compiler {
        assert!(
            !std::env::var("CNCSIM_REQUIRE_ORACLES").is_ok_and(|v| v == "1"),
            "CNCSIM_REQUIRE_ORACLES=1 but the C compiler {cc} is missing"
        );
        eprintln!("skipped: the C compiler {cc} is missing");
        return None;
    }
    common::oracle_python("import fmpy, jinja2", "fmpy (pip install fmpy)")
}

/// The controller FMU, built once per test binary.
fn controller_fmu() -> Option<&'static Path> {
    static FMU: OnceLock<Option<(tempfile::TempDir, PathBuf)>> = OnceLock::new();
    FMU.get_or_init(|| {
        let python = python()?;
        let dir = tempfile::tempdir().unwrap();
        let fmu = dir.path().join("pid_controller.fmu");
        let out = Command::new(&python)
            .arg(Path::new(ROOT).join("tests/oracles/fmi_controller.py"))
            .arg(&fmu)
            .arg("xyz")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "building the controller FMU: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Some((dir, fmu))
    })
    .as_ref()
    .map(|(_, p)| p.as_path())
}

/// The controller FMU's parameters for [`GAINS`].
fn parameters() -> Vec<(String, f64)> {
    let mut out = vec![("period".to_string(), 1e-3)];
    for (axis, [kp, ki, kd, ff1, ff2, limit]) in GAINS {
        for (name, value) in [
            ("kp", kp),
            ("ki", ki),
            ("kd", kd),
            ("ff1", ff1),
            ("ff2", ff2),
            ("output_limit", limit),
        ] {
            out.push((format!("{name}_{axis}"), value));
        }
    }
    out
}

/// A short run of the XYZ table with its guide friction and backlash: settle, approach, an
/// r = 5 mm circle at 20 mm/s. `controller` is the `[controller]` table's body.
fn scenario(dir: &Path, name: &str, controller: &str, analytic: bool) -> PathBuf {
    let text = format!(
        r#"name = "{name}"
machine = "{ROOT}/models/xyz_table.urdf"

[program]
circle = {{ center_mm = [100.0, 100.0], radius_mm = 5.0, start_angle_deg = 0.0, direction = "ccw", z_mm = 0.0 }}
feed_mm_s = 20.0
approach_from_mm = [95.0, 100.0, 0.0]
approach_feed_mm_s = 20.0

[planner]
profile = "constant-velocity"

[timing]
servo_period_ms = 1.0
physics_step_ms = 0.25
settle_s = 0.2

[actuator]
model = "dc-motor"
amplifier_mode = "voltage"

[controller]
{controller}
{}
[recording]
rrd = false
csv = true
"#,
        if analytic {
            "[analytic]\nenabled = true\n"
        } else {
            ""
        }
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

fn pid_controller() -> String {
    let mut s = "type = \"pid\"\nform = \"positional\"\n".to_string();
    for (axis, [kp, ki, kd, ff1, ff2, limit]) in GAINS {
        s += &format!(
            "axes.{axis} = {{ kp = {kp:?}, ki = {ki:?}, kd = {kd:?}, ff1 = {ff1:?}, ff2 = {ff2:?}, output_limit = {limit:?} }}\n"
        );
    }
    s
}

fn fmu_controller(fmu: &Path, extra: &[(String, f64)]) -> String {
    let mut params: Vec<String> = parameters()
        .into_iter()
        .chain(extra.iter().cloned())
        .map(|(k, v)| format!("{k} = {v:?}"))
        .collect();
    params.dedup();
    format!(
        "type = \"fmu\"\nfmu = \"{}\"\nparameters = {{ {} }}\n",
        fmu.display(),
        params.join(", ")
    )
}

fn traced(scenario: &Path) -> (Trace, Option<Trace>) {
    let s = Scenario::load(scenario).unwrap();
    let run = Assembly::new(&s)
        .unwrap()
        .run(RunOptions::new().traced())
        .unwrap();
    assert!(run.stop().is_none(), "{:?}", run.stop());
    (run.trace.unwrap(), run.analytic)
}

/// Largest |a − b| over two series of the same length.
fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn a_controller_fmu_gives_the_built_in_pid_numbers() {
    let Some(fmu) = controller_fmu() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let builtin = traced(&scenario(dir.path(), "builtin", &pid_controller(), true));
    let imported = traced(&scenario(
        dir.path(),
        "imported",
        &fmu_controller(fmu, &[]),
        true,
    ));
    let (b, i) = (&builtin.0, &imported.0);
    assert!(b.len() > 1500, "{} ticks", b.len());
    let du = max_difference(&b.command, &i.command);
    let dx = max_difference(&b.actual, &i.actual);
    eprintln!(
        "built-in PID vs FMU PID over {} ticks: command {du:e} V, position {dx:e} m",
        b.len()
    );
    // The same operations in the same order (C without fused multiply-add): round-off at most.
    assert!(du <= 1e-12, "commands differ by {du:e} V");
    assert!(dx <= 1e-15, "positions differ by {dx:e} m");
    // The machine moved (friction and backlash on): the comparison is not of zeros.
    let peak = b.command.iter().fold(0.0f64, |m, u| m.max(u.abs()));
    assert!(peak > 0.1, "peak command {peak} V");
    // The analytic lane ran its own instance of the FMU.
    let (ab, ai) = (builtin.1.unwrap(), imported.1.unwrap());
    assert!(max_difference(&ab.command, &ai.command) <= 1e-12);
}

#[test]
fn fmpy_master_with_the_exported_plant_gives_cncsims_answer() {
    let Some(fmu) = controller_fmu() else {
        return;
    };
    let python = python().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let plant_scenario = scenario(dir.path(), "plant", &pid_controller(), false);
    let plant_fmu = dir.path().join("plant.fmu");
    let out = Command::new(CNCSIM)
        .arg("export-fmu")
        .arg(&plant_scenario)
        .arg("--out")
        .arg(&plant_fmu)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "export-fmu: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // The machine's files travel inside.
    let mut names = Vec::new();
    let mut zip = zip::ZipArchive::new(std::fs::File::open(&plant_fmu).unwrap()).unwrap();
    for i in 0..zip.len() {
        names.push(zip.by_index(i).unwrap().name().unwrap().to_string());
    }
    for want in [
        "modelDescription.xml",
        "binaries/x86_64-linux/cncsim_plant.so",
        "resources/scenario.toml",
        "resources/machine/xyz_table.urdf",
        "resources/machine/xyz_table.drives.toml",
    ] {
        assert!(names.iter().any(|n| n == want), "{want} not in {names:?}");
    }

    let csv = dir.path().join("master.csv");
    let mut master = Command::new(&python);
    master
        .arg(Path::new(ROOT).join("tests/oracles/fmi_master.py"))
        .arg(&plant_fmu)
        .arg(fmu)
        .arg(&csv);
    for (k, v) in parameters() {
        master.arg(format!("{k}={v:?}"));
    }
    let out = master.output().unwrap();
    assert!(
        out.status.success(),
        "FMPy master: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();

    // cncsim's own run of the same controller FMU, and of its built-in PID.
    let imported = traced(&scenario(
        dir.path(),
        "imported",
        &fmu_controller(fmu, &[]),
        false,
    ))
    .0;
    let builtin = traced(&plant_scenario).0;
    let n = imported.len();
    // The master also stepped the settle and the approach; the program is its last n rows.
    let program = &rows[rows.len() - n..];
    assert_eq!(program[0][column("program_time")], 0.0);
    let mut worst: f64 = 0.0;
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        let master_u: Vec<f64> = program
            .iter()
            .map(|r| r[column(&format!("command_{axis}"))])
            .collect();
        let master_x: Vec<f64> = program
            .iter()
            .map(|r| r[column(&format!("carriage_position_{axis}"))])
            .collect();
        let master_sp: Vec<f64> = program
            .iter()
            .map(|r| r[column(&format!("setpoint_position_{axis}"))])
            .collect();
        let of = |t: &Trace, s: &[f64]| -> Vec<f64> {
            (0..t.len()).map(|k| Trace::at(s, t.axes, k, i)).collect()
        };
        for (what, cncsim, tolerance) in [
            (
                "command (FMU in cncsim)",
                of(&imported, &imported.command),
                1e-12,
            ),
            (
                "command (built-in PID)",
                of(&builtin, &builtin.command),
                1e-12,
            ),
        ] {
            let d = max_difference(&master_u, &cncsim);
            eprintln!("axis {axis}: FMPy master vs cncsim {what}: {d:e} V");
            assert!(d <= tolerance, "axis {axis}: {what} differs by {d:e} V");
            worst = worst.max(d);
        }
        let d = max_difference(&master_x, &of(&imported, &imported.actual));
        eprintln!("axis {axis}: FMPy master vs cncsim carriage position: {d:e} m");
        assert!(d <= 1e-15, "axis {axis}: position differs by {d:e} m");
        assert_eq!(master_sp, of(&imported, &imported.commanded));
    }
    eprintln!("worst command difference {worst:e} V over {n} program ticks");
}

/// The controller FMU with its model description edited by `edit`, or `binaries/` left out.
fn edited_fmu(
    fmu: &Path,
    dir: &Path,
    name: &str,
    edit: &dyn Fn(&str) -> String,
    binaries: bool,
) -> PathBuf {
    let mut archive = zip::ZipArchive::new(std::fs::File::open(fmu).unwrap()).unwrap();
    let out = dir.join(format!("{name}.fmu"));
    let mut writer = zip::ZipWriter::new(std::fs::File::create(&out).unwrap());
    for i in 0..archive.len() {
        let mut entry = archive.by_index(i).unwrap();
        let entry_name = entry.name().unwrap().to_string();
        if !binaries && entry_name.starts_with("binaries/") {
            continue;
        }
        let mut bytes = Vec::new();
        entry.read_to_end(&mut bytes).unwrap();
        if entry_name == "modelDescription.xml" {
            bytes = edit(&String::from_utf8(bytes).unwrap()).into_bytes();
        }
        writer
            .start_file(entry_name, zip::write::SimpleFileOptions::default())
            .unwrap();
        writer.write_all(&bytes).unwrap();
    }
    writer.finish().unwrap();
    out
}

fn run_cli(scenario: &Path, out: &Path) -> (i32, String) {
    let o = Command::new(CNCSIM)
        .arg("run")
        .arg(scenario)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ),
    )
}

#[test]
fn bad_controller_fmus_are_refused_naming_the_fmu_and_the_variable() {
    let Some(fmu) = controller_fmu() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let same = |s: &str| s.to_string();
    // Name, FMU, extra parameters, what the message must say.
    type Case<'a> = (&'a str, PathBuf, Vec<(String, f64)>, &'a [&'a str]);
    let cases: Vec<Case> = vec![
        (
            "no_binary",
            edited_fmu(fmu, dir.path(), "no_binary", &same, false),
            vec![],
            &[
                "no binary for this platform",
                "binaries/x86_64-linux/pid_controller.so",
            ],
        ),
        (
            "no_command_y",
            edited_fmu(
                fmu,
                dir.path(),
                "no_command_y",
                &|s| s.replace("name=\"command_y\"", "name=\"u_y\""),
                true,
            ),
            vec![],
            &["no variable 'command_y'"],
        ),
        (
            "millimetres",
            edited_fmu(
                fmu,
                dir.path(),
                "millimetres",
                &|s| {
                    s.replace(
                        "name=\"measured_position_x\"",
                        "name=\"measured_position_x\" unit=\"mm\"",
                    )
                },
                true,
            ),
            vec![],
            &["measured_position_x", "\"mm\"", "m (SI)"],
        ),
        (
            "model_exchange",
            edited_fmu(
                fmu,
                dir.path(),
                "model_exchange",
                &|s| s.replace("<CoSimulation", "<ModelExchange"),
                true,
            ),
            vec![],
            &["not a co-simulation FMU"],
        ),
        (
            "unknown_parameter",
            fmu.to_path_buf(),
            vec![("kq_x".to_string(), 1.0)],
            &["controller.parameters.kq_x", "no variable 'kq_x'"],
        ),
    ];
    for (name, path, extra, expected) in cases {
        let s = scenario(dir.path(), name, &fmu_controller(&path, &extra), false);
        let (code, text) = run_cli(&s, &dir.path().join(name));
        assert_eq!(code, 2, "{name}: exit {code}: {text}");
        assert!(!text.contains("panicked"), "{name}: {text}");
        assert!(
            text.contains(&path.display().to_string()),
            "{name}: the FMU is not named: {text}"
        );
        for e in expected {
            assert!(text.contains(e), "{name}: '{e}' not in: {text}");
        }
    }
}

#[test]
fn a_failing_do_step_stops_the_run_where_it_failed_and_keeps_what_was_computed() {
    let Some(fmu) = controller_fmu() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // Step 1000: after the settle (200 ticks) and the approach (about 500), in the program.
    let s = scenario(
        dir.path(),
        "fails",
        &fmu_controller(fmu, &[("fail_at_step".into(), 1000.0)]),
        false,
    );
    let out = dir.path().join("out");
    let (code, text) = run_cli(&s, &out);
    assert_eq!(code, 1, "{text}");
    let at = text
        .split("the controller failed at t = ")
        .nth(1)
        .unwrap_or_else(|| panic!("no stop in: {text}"));
    let time: f64 = at.split(' ').next().unwrap().parse().unwrap();
    assert!(text.contains("fmi3DoStep returned Error"), "{text}");
    assert!(text.contains("fail_at_step reached"), "{text}");
    assert!(text.contains("pid_controller.fmu"), "{text}");
    // The run stopped at the 1000th tick: program tick k = time / T.
    let k = (time / 1e-3).round() as usize;
    assert!((250..350).contains(&k), "stopped at t = {time}");
    let trace = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    // The header and the k program ticks before the failing one, all written.
    assert_eq!(trace.lines().count(), 1 + k);

    // With reversal compensation around it, the FMU's failure stops the run just the same.
    let compensated = format!(
        "{}[compensation]\nx = {{ backlash_mm = 0.01, backlash_rate_mm_s = 10.0 }}\n",
        fmu_controller(fmu, &[("fail_at_step".into(), 1000.0)])
    );
    let s = scenario(dir.path(), "fails_compensated", &compensated, false);
    let (code, text) = run_cli(&s, &dir.path().join("compensated"));
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains(&format!("the controller failed at t = {time:.6} s")),
        "{text}"
    );
    assert!(out.join("metrics.json").is_file());
}

#[test]
fn controller_parameters_are_overridden_by_ab_variants() {
    let Some(fmu) = controller_fmu() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path(), "ab", &fmu_controller(fmu, &[]), false);
    let out = dir.path().join("ab");
    let o = Command::new(CNCSIM)
        .arg("ab")
        .arg(&s)
        .args(["--a", "controller.parameters.kd_x=146.0"])
        .args(["--b", "controller.parameters.kd_x=14.6"])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{text}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("ab.json")).unwrap()).unwrap();
    let text = report.to_string();
    // The two variants ran different gains: their X following errors differ.
    let metrics: Vec<serde_json::Value> = ["a", "b"]
        .iter()
        .map(|v| {
            let dir = std::fs::read_dir(&out)
                .unwrap()
                .flatten()
                .map(|e| e.path())
                .find(|p| p.is_dir() && p.file_name().unwrap().to_string_lossy().starts_with(v))
                .unwrap_or_else(|| panic!("no variant folder {v} in {text}"));
            serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap())
                .unwrap()
        })
        .collect();
    assert_ne!(
        metrics[0]["axes"]["x"]["max_following_error_mm"],
        metrics[1]["axes"]["x"]["max_following_error_mm"]
    );
}

/// The FMI 2.0 controller of tests/fixtures/fmi (the same law, hand-written against the FMI
/// 2.0 headers FMPy ships), compiled by the C compiler into an FMU.
fn fmi2_controller_fmu(dir: &Path) -> Option<PathBuf> {
    let python = python()?;
    let out = Command::new(&python)
        .args([
            "-c",
            "import fmpy, os; print(os.path.join(os.path.dirname(fmpy.__file__), 'c-code'))",
        ])
        .output()
        .unwrap();
    let headers = String::from_utf8(out.stdout).unwrap().trim().to_string();
    let fixtures = Path::new(ROOT).join("tests/fixtures/fmi");
    let library = dir.join("pid_fmi2.so");
    let cc = std::env::var("CC").unwrap_or_else(|_| "gcc".into());
    let built = Command::new(cc)
        .args([
            "-std=c99",
            "-O2",
            "-ffp-contract=off",
            "-shared",
            "-fPIC",
            "-I",
        ])
        .arg(&headers)
        .arg("-o")
        .arg(&library)
        .arg(fixtures.join("pid_fmi2.c"))
        .arg("-lm")
        .output()
        .unwrap();
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    let fmu = dir.join("pid_fmi2.fmu");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&fmu).unwrap());
    let options = zip::write::SimpleFileOptions::default();
    zip.start_file("modelDescription.xml", options).unwrap();
    zip.write_all(&std::fs::read(fixtures.join("pid_fmi2.xml")).unwrap())
        .unwrap();
    zip.start_file("binaries/linux64/pid_fmi2.so", options)
        .unwrap();
    zip.write_all(&std::fs::read(&library).unwrap()).unwrap();
    zip.finish().unwrap();
    Some(fmu)
}

#[test]
fn an_fmi2_controller_fmu_gives_the_built_in_pid_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let Some(fmu) = fmi2_controller_fmu(dir.path()) else {
        return;
    };
    let builtin = traced(&scenario(dir.path(), "builtin", &pid_controller(), false)).0;
    let imported = traced(&scenario(
        dir.path(),
        "fmi2",
        &fmu_controller(&fmu, &[]),
        false,
    ))
    .0;
    let du = max_difference(&builtin.command, &imported.command);
    let dx = max_difference(&builtin.actual, &imported.actual);
    eprintln!("built-in PID vs FMI 2.0 FMU: command {du:e} V, position {dx:e} m");
    assert!(du <= 1e-12 && dx <= 1e-15, "{du:e} V, {dx:e} m");
}

#[test]
fn the_plant_fmus_model_stepped_with_the_built_in_pid_gives_the_servo_loops_numbers() {
    use cncsim::control::ControllerInput;
    use cncsim::fmi::plant::{variables, PlantModel, Signal};
    let dir = tempfile::tempdir().unwrap();
    let s = Scenario::load(&scenario(dir.path(), "plant", &pid_controller(), false)).unwrap();
    let assembly = Assembly::new(&s).unwrap();
    let run = assembly.run(RunOptions::new().traced()).unwrap();
    let trace = run.trace.unwrap();

    // A master in Rust: the plant as the FMU steps it, the scenario's own controller.
    let mut plant = PlantModel::new(&assembly).unwrap();
    let vars = variables(plant.axes(), plant.actuator());
    let reference = |signal: Signal, axis: usize| {
        vars.iter()
            .find(|v| v.signal == Some((axis, signal)))
            .unwrap()
            .value_reference
    };
    let program_time = vars.last().unwrap().value_reference;
    let mut controller = assembly.controller();
    let n = plant.axes().len();
    let (mut commands, mut positions) = (Vec::new(), Vec::new());
    for _ in 0..plant.ticks() {
        let read = |signal| -> Vec<f64> {
            (0..n)
                .map(|i| plant.get(reference(signal, i)).unwrap())
                .collect()
        };
        let (sp, sv, sa) = (
            read(Signal::SetpointPosition),
            read(Signal::SetpointVelocity),
            read(Signal::SetpointAcceleration),
        );
        let (measured, motor) = (read(Signal::MeasuredPosition), read(Signal::MotorPosition));
        let carriage = read(Signal::CarriagePosition);
        let time = plant.get(program_time).unwrap();
        let mut command = vec![0.0; n];
        controller.update(
            &ControllerInput {
                time,
                setpoint_position: &sp,
                setpoint_velocity: &sv,
                setpoint_acceleration: &sa,
                measured_position: &measured,
                motor_position: &motor,
            },
            &mut command,
        );
        if time >= 0.0 {
            commands.extend_from_slice(&command);
            positions.extend_from_slice(&carriage);
        }
        for (i, u) in command.iter().enumerate() {
            assert!(plant.set(reference(Signal::Command, i), *u));
        }
        plant.step().unwrap();
    }
    assert_eq!(commands.len(), trace.command.len());
    // Bit for bit: the same plant code, stepped the same way.
    assert!(commands == trace.command, "commands differ");
    assert!(positions == trace.actual, "positions differ");
}

#[test]
fn controller_variables_map_other_names() {
    let Some(fmu) = controller_fmu() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let renamed = edited_fmu(
        fmu,
        dir.path(),
        "renamed",
        &|s| {
            s.replace("name=\"command_y\"", "name=\"u_y\"")
                .replace("name=\"measured_position_x\"", "name=\"x_feedback\"")
        },
        true,
    );
    let table = format!(
        "{}[controller.variables]\ncommand_y = \"u_y\"\nmeasured_position_x = \"x_feedback\"\n",
        fmu_controller(&renamed, &[])
    );
    let mapped = traced(&scenario(dir.path(), "mapped", &table, false)).0;
    let builtin = traced(&scenario(dir.path(), "builtin", &pid_controller(), false)).0;
    assert_eq!(mapped.command, builtin.command);
    // A key that is not one of cncsim's signals is refused, naming it.
    let bad = format!(
        "{}[controller.variables]\ncommand_q = \"u_y\"\n",
        fmu_controller(&renamed, &[])
    );
    let (code, text) = run_cli(
        &scenario(dir.path(), "bad_map", &bad, false),
        &dir.path().join("bad_map"),
    );
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("controller.variables.command_q"), "{text}");
}
