//! `cncsim export-fmu`: the scenario's plant as an FMI 3.0 co-simulation FMU. The archive holds
//! the model description written here for the scenario, the `cncsim-fmu` shared library (built
//! from fmu/) as the platform binary, and in `resources/` the scenario with the machine's
//! URDF, its drive file and the program file, which the library loads and plans again at
//! instantiation (planning is deterministic: the setpoints are the ones `cncsim run` uses).

use super::plant::{self, PlantModel, PlantVariable, SCENARIO_FILE};
use crate::control::ActuatorKind;
use crate::scenario::{Assembly, Scenario};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The FMU's model identifier: the name of its shared library in `binaries/`.
pub const MODEL_IDENTIFIER: &str = "cncsim_plant";

/// The file in `resources/` holding the instantiation token (the library checks it).
pub const TOKEN_FILE: &str = "token";

/// The file name of the shared library cargo builds from fmu/ (`cncsim-fmu`) on this platform.
pub fn library_file() -> String {
    format!(
        "{}cncsim_fmu{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    )
}

/// The FMI 3.0 platform folder of this build.
pub fn platform_folder() -> Option<&'static str> {
    use std::env::consts::{ARCH, OS};
    Some(match (ARCH, OS) {
        ("x86_64", "linux") => "x86_64-linux",
        ("aarch64", "linux") => "aarch64-linux",
        ("x86_64", "macos") => "x86_64-darwin",
        ("aarch64", "macos") => "aarch64-darwin",
        ("x86_64", "windows") => "x86_64-windows",
        _ => return None,
    })
}

/// Where the plant library is looked for: `$CNCSIM_FMU_LIBRARY`, else in the running
/// executable's target folder: its `deps/` first (where `cargo test` leaves the library, built
/// there for fmu/'s integration test: cargo copies a shared library up beside `cncsim` only
/// when it was asked for by name, and `deps/` always holds the latest build), then beside the
/// executable (`cargo build -p cncsim-fmu`), then its parent (test and bench executables live
/// in `deps/` below it).
pub fn find_library() -> Result<PathBuf, String> {
    if let Some(p) = std::env::var_os("CNCSIM_FMU_LIBRARY") {
        let p = PathBuf::from(p);
        return if p.is_file() {
            Ok(p)
        } else {
            Err(format!(
                "CNCSIM_FMU_LIBRARY = {}: no such file",
                p.display()
            ))
        };
    }
    let exe = std::env::current_exe().map_err(|e| format!("where is cncsim running from? {e}"))?;
    let mut looked = Vec::new();
    let exe_dir = exe.parent().unwrap_or(Path::new("."));
    let dirs = [exe_dir.join("deps"), exe_dir.to_path_buf()]
        .into_iter()
        .chain(exe_dir.parent().map(Path::to_path_buf));
    for dir in dirs {
        let candidate = dir.join(library_file());
        if candidate.is_file() {
            return Ok(candidate);
        }
        looked.push(candidate.display().to_string());
    }
    Err(format!(
        "the plant FMU's library {} is not built (looked for {}): build it with `cargo build -p cncsim-fmu` (with --release for a release cncsim), or set CNCSIM_FMU_LIBRARY to it",
        library_file(),
        looked.join(", ")
    ))
}

/// What `export-fmu` wrote.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Exported {
    /// The FMU file written.
    pub fmu: PathBuf,
    /// The plant library packed into it.
    pub library: PathBuf,
    /// The model's name: the scenario's.
    pub model_name: String,
    /// Servo period (s): the FMU's step size.
    pub servo_period: f64,
    /// Servo ticks of the whole run (settle, approach, program) and the first one's time.
    pub ticks: usize,
    /// Program time of the first tick (s; negative with a settle or an approach).
    pub start_time: f64,
    /// Names of the input variables (the axes' commands).
    pub inputs: Vec<String>,
    /// Names of the output variables, `program_time` last.
    pub outputs: Vec<String>,
    /// Files in `resources/`.
    pub resources: Vec<String>,
}

/// Writes the plant FMU of `scenario` (assembled as `assembly`) to `out`, with the library at
/// `library`. `text` is the scenario's text (overrides applied).
pub fn export(
    scenario: &Scenario,
    text: &str,
    assembly: &Assembly,
    library: &Path,
    out: &Path,
) -> Result<Exported, String> {
    let folder = platform_folder().ok_or("FMI 3.0 has no platform folder for this platform")?;
    let axis_names: Vec<String> = assembly
        .machine
        .axes
        .iter()
        .map(|a| a.name.clone())
        .collect();
    let (scenario_text, files) = resources(scenario, text, &axis_names)?;
    // The plant the FMU will run, built here first: what does not load here would fail in
    // the FMU (and its tick count goes into the model description).
    let model = PlantModel::new(assembly)?;
    let axes: Vec<(String, bool)> = model.axes().to_vec();
    let variables = plant::variables(&axes, assembly.actuator);
    let token = token(&scenario_text, &files);
    let xml = model_description(
        &scenario.name,
        &token,
        &variables,
        model.period(),
        model.start_time(),
        model.ticks(),
        assembly.actuator,
    );
    let binary = std::fs::read(library)
        .map_err(|e| format!("cannot read the plant library {}: {e}", library.display()))?;

    let file =
        std::fs::File::create(out).map_err(|e| format!("cannot write {}: {e}", out.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .unix_permissions(0o644);
    let mut put = |name: &str, bytes: &[u8]| -> Result<(), String> {
        zip.start_file(name, options)
            .and_then(|()| zip.write_all(bytes).map_err(Into::into))
            .map_err(|e| format!("writing {name} into {}: {e}", out.display()))
    };
    put("modelDescription.xml", xml.as_bytes())?;
    put(
        &format!(
            "binaries/{folder}/{MODEL_IDENTIFIER}{}",
            std::env::consts::DLL_SUFFIX
        ),
        &binary,
    )?;
    put(
        &format!("resources/{SCENARIO_FILE}"),
        scenario_text.as_bytes(),
    )?;
    // The library checks the master's instantiationToken against this.
    put(&format!("resources/{TOKEN_FILE}"), token.as_bytes())?;
    let mut names = vec![SCENARIO_FILE.to_string()];
    for (name, bytes) in &files {
        put(&format!("resources/{name}"), bytes)?;
        names.push(name.clone());
    }
    zip.finish()
        .map_err(|e| format!("finishing {}: {e}", out.display()))?;
    Ok(Exported {
        fmu: out.to_path_buf(),
        library: library.to_path_buf(),
        model_name: scenario.name.clone(),
        servo_period: model.period(),
        ticks: model.ticks(),
        start_time: model.start_time(),
        inputs: variables
            .iter()
            .filter(|v| v.is_input())
            .map(|v| v.name.clone())
            .collect(),
        outputs: variables
            .iter()
            .filter(|v| !v.is_input())
            .map(|v| v.name.clone())
            .collect(),
        resources: names,
    })
}

/// The scenario as the FMU reads it, with the files it names: the machine (URDF and drive
/// file) under `machine/`, the program file and tool table under `program/`. Its controller
/// is replaced by a zero-gain PID on every axis, never run: the plant FMU has no controller
/// (the master connects one), and a controller FMU of the scenario is not shipped.
fn resources(s: &Scenario, text: &str, axes: &[String]) -> Result<(String, Files), String> {
    let mut doc: toml_edit::DocumentMut = text
        .parse()
        .map_err(|e| format!("{}: {e}", s.path.display()))?;
    let mut files = Vec::new();
    let mut add = |dir: &str, path: &Path| -> Result<String, String> {
        let name = path
            .file_name()
            .ok_or_else(|| format!("{}: not a file", path.display()))?
            .to_string_lossy()
            .into_owned();
        let bytes =
            std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let entry = format!("{dir}/{name}");
        files.push((entry.clone(), bytes));
        Ok(entry)
    };
    let urdf = add("machine", &s.machine)?;
    let drives = crate::machine::DrivesFile::path_for(&s.machine);
    add("machine", &drives)?;
    doc["machine"] = toml_edit::value(urdf);
    let base = s.path.parent().unwrap_or(Path::new("."));
    for key in ["file", "tool_table"] {
        let written = doc
            .get("program")
            .and_then(|p| p.get(key))
            .and_then(|v| v.as_str())
            .map(str::to_string);
        if let Some(written) = written {
            let entry = add("program", &base.join(written))?;
            doc["program"][key] = toml_edit::value(entry);
        }
    }
    let mut controller = toml_edit::Table::new();
    controller["type"] = toml_edit::value("pid");
    let mut gains = toml_edit::Table::new();
    gains.set_dotted(true);
    for axis in axes {
        let mut zero = toml_edit::InlineTable::new();
        zero.insert("kp", 0.0.into());
        gains[axis.as_str()] = toml_edit::Item::Value(zero.into());
    }
    controller["axes"] = toml_edit::Item::Table(gains);
    doc["controller"] = toml_edit::Item::Table(controller);
    // Neither the plant's files nor its comparisons travel: they are the master's business.
    for section in ["compensation", "expect", "ab", "recording"] {
        doc.remove(section);
    }
    Ok((doc.to_string(), files))
}

/// Files for `resources/`: path inside it, contents.
type Files = Vec<(String, Vec<u8>)>;

/// A deterministic instantiation token: the FMU's contents decide it.
fn token(scenario: &str, files: &[(String, Vec<u8>)]) -> String {
    // FNV-1a over everything the FMU's behaviour depends on.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for b in bytes {
            h ^= u64::from(*b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    eat(scenario.as_bytes());
    for (name, bytes) in files {
        eat(name.as_bytes());
        eat(bytes);
    }
    eat(env!("CARGO_PKG_VERSION").as_bytes());
    format!("{{cncsim-plant-{h:016x}}}")
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The FMI 3.0 model description of the plant FMU.
fn model_description(
    name: &str,
    token: &str,
    variables: &[PlantVariable],
    period: f64,
    start_time: f64,
    ticks: usize,
    actuator: ActuatorKind,
) -> String {
    let mut x = String::new();
    let stop = start_time + ticks as f64 * period;
    x += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
    x += &format!(
        "<fmiModelDescription fmiVersion=\"3.0\" modelName=\"{}\" instantiationToken=\"{}\" description=\"cncsim plant of scenario {}: machine, drives, friction, backlash and physics, stepped one servo period per doStep\" generationTool=\"cncsim {}\" variableNamingConvention=\"flat\">\n",
        escape(name),
        escape(token),
        escape(name),
        env!("CARGO_PKG_VERSION")
    );
    // The step is the servo period and nothing else: the plant is what the servo loop steps.
    x += &format!(
        "  <CoSimulation modelIdentifier=\"{MODEL_IDENTIFIER}\" canHandleVariableCommunicationStepSize=\"false\" fixedInternalStepSize=\"{period:?}\" canBeInstantiatedOnlyOncePerProcess=\"false\" canGetAndSetFMUState=\"false\" canSerializeFMUState=\"false\" providesIntermediateUpdate=\"false\" canReturnEarlyAfterIntermediateUpdate=\"false\" hasEventMode=\"false\"/>\n"
    );
    x += "  <UnitDefinitions>\n";
    let units: [(&str, &str); 8] = [
        ("m", "m=\"1\""),
        ("m/s", "m=\"1\" s=\"-1\""),
        ("m/s2", "m=\"1\" s=\"-2\""),
        ("rad", "rad=\"1\""),
        ("rad/s", "rad=\"1\" s=\"-1\""),
        ("rad/s2", "rad=\"1\" s=\"-2\""),
        ("s", "s=\"1\""),
        (
            if actuator == ActuatorKind::IdealTorque {
                "N.m"
            } else {
                "V"
            },
            if actuator == ActuatorKind::IdealTorque {
                "kg=\"1\" m=\"2\" s=\"-2\""
            } else {
                "kg=\"1\" m=\"2\" s=\"-3\" A=\"-1\""
            },
        ),
    ];
    for (unit, base) in units {
        x += &format!("    <Unit name=\"{unit}\"><BaseUnit {base}/></Unit>\n");
    }
    x += "  </UnitDefinitions>\n";
    x += &format!(
        "  <DefaultExperiment startTime=\"{start_time:?}\" stopTime=\"{stop:?}\" stepSize=\"{period:?}\"/>\n"
    );
    x += "  <ModelVariables>\n";
    x += &format!(
        "    <Float64 name=\"time\" valueReference=\"{}\" causality=\"independent\" variability=\"continuous\" unit=\"s\" description=\"program time\"/>\n",
        plant::TIME_REFERENCE
    );
    for v in variables {
        let (causality, extra) = if v.is_input() {
            ("input", " start=\"0\"")
        } else {
            ("output", "")
        };
        // Outputs change at communication points only (the plant is sampled once a period).
        x += &format!(
            "    <Float64 name=\"{}\" valueReference=\"{}\" causality=\"{causality}\" variability=\"discrete\" unit=\"{}\" description=\"{}\"{extra}/>\n",
            escape(&v.name),
            v.value_reference,
            v.unit,
            escape(&v.description)
        );
    }
    x += "  </ModelVariables>\n  <ModelStructure>\n";
    // No output depends directly on an input: a command acts over the next period.
    for v in variables.iter().filter(|v| !v.is_input()) {
        x += &format!(
            "    <Output valueReference=\"{}\" dependencies=\"\"/>\n",
            v.value_reference
        );
    }
    for v in variables.iter().filter(|v| !v.is_input()) {
        x += &format!(
            "    <InitialUnknown valueReference=\"{}\" dependencies=\"\"/>\n",
            v.value_reference
        );
    }
    x += "  </ModelStructure>\n</fmiModelDescription>\n";
    x
}
