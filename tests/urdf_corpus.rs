//! Real URDFs written by others, as published: the robots of the `example-robot-data` package
//! (BSD-3-Clause; PyPI, installed by `.ci/run`; 69 URDFs from CAD exports, xacro output and
//! hand-written files, with STL, COLLADA and OBJ meshes behind `package://` paths). None of
//! them is a machine tool; all of them are machines someone else described, which is what
//! cncsim must read as they are or refuse by name.
//!
//! For each: cncsim reads it or refuses it with the file and a located reason, never a panic;
//! `machine init` writes a drive file for those it reads, which loads; the machine it gives is
//! built in the physics and held at rest, and stays finite. The corpus is found through
//! `CNCSIM_URDF_CORPUS` (the package's `robots` folder); without it the test is skipped, unless
//! `CNCSIM_REQUIRE_ORACLES` is set.

mod common;

use cncsim::kinematics::ProgramFrame;
use cncsim::machine::Machine;
use cncsim::model::{Plant, PlantOptions};
use std::path::{Path, PathBuf};

fn corpus() -> Option<PathBuf> {
    match std::env::var_os("CNCSIM_URDF_CORPUS") {
        Some(dir) => Some(PathBuf::from(dir)),
        None if std::env::var_os("CNCSIM_REQUIRE_ORACLES").is_some() => {
            panic!("CNCSIM_URDF_CORPUS is not set: .ci/run installs example-robot-data and sets it")
        }
        None => {
            eprintln!("skipped: CNCSIM_URDF_CORPUS is not set");
            None
        }
    }
}

/// What became of one file.
enum Outcome {
    /// Loaded, initialised, built and held at rest: (axes, meshes drawn, mesh warnings).
    Runs(usize, usize, Vec<String>),
    Refused(String),
}

fn try_one(urdf: &Path) -> Outcome {
    let text = std::fs::read_to_string(urdf).unwrap();
    if let Err(e) = cncsim::machine::load_urdf(urdf) {
        return Outcome::Refused(e.to_string());
    }
    let drives = match cncsim::scenario::drive_file_template(urdf) {
        Ok(d) => d,
        Err(e) => return Outcome::Refused(e.to_string()),
    };
    // What `init` wrote loads as it stands.
    let machine = Machine::parse(urdf, &text, &drives).unwrap_or_else(|e| {
        panic!(
            "{}: the drive file init wrote does not load: {e}\n{drives}",
            urdf.display()
        )
    });
    ProgramFrame::new(&machine)
        .unwrap_or_else(|e| panic!("{}: init's axes are refused: {e}", urdf.display()));
    let home: Vec<f64> = machine.axes.iter().map(|a| a.drive.home).collect();
    let options = PlantOptions {
        step: 2.5e-4,
        gravity: [0.0, 0.0, -9.81],
        initial_positions: home,
        include_drive_dynamics: true,
        solver_iterations: 4,
    };
    let mut plant = match Plant::new(&machine, &options) {
        Ok(p) => p,
        Err(e) => return Outcome::Refused(format!("{}: the physics model: {e}", urdf.display())),
    };
    // Drives off, gravity on, 50 ms: whatever falls falls, nothing turns NaN.
    let zeros = vec![0.0; machine.axes.len()];
    let mut q = vec![0.0; machine.axes.len()];
    for _ in 0..200 {
        plant.set_joint_forces(&zeros);
        plant.step();
    }
    plant.positions(&mut q);
    assert!(
        q.iter().all(|v| v.is_finite()) && plant.tool_point().iter().all(|v| v.is_finite()),
        "{}: not finite after 50 ms at rest: {q:?}",
        urdf.display()
    );
    let meshes = machine
        .links
        .iter()
        .flat_map(|l| &l.visuals)
        .filter(|v| matches!(v.shape, cncsim::machine::Shape::Mesh(_)))
        .count();
    let mesh_warnings = machine
        .warnings
        .iter()
        .map(|w| w.to_string())
        .filter(|w| w.contains("mesh"))
        .collect();
    Outcome::Runs(machine.axes.len(), meshes, mesh_warnings)
}

#[test]
fn real_urdfs_load_and_run_or_are_refused_by_name() {
    let Some(dir) = corpus() else { return };
    let mut files = Vec::new();
    common::urdfs(&dir, &mut files);
    assert!(
        files.len() >= 60,
        "{} URDFs under {}",
        files.len(),
        dir.display()
    );
    let (mut runs, mut refused) = (Vec::new(), Vec::new());
    for f in &files {
        match std::panic::catch_unwind(|| try_one(f)) {
            Ok(Outcome::Runs(axes, meshes, warnings)) => runs.push((f, axes, meshes, warnings)),
            Ok(Outcome::Refused(message)) => {
                // Refused by name: the file, a place or the element, and why.
                let name = f.file_name().unwrap().to_string_lossy().into_owned();
                assert!(message.contains(&name), "{message}");
                refused.push(message)
            }
            Err(_) => panic!("{}: panicked", f.display()),
        }
    }
    eprintln!(
        "{} of {} URDFs load, initialise and run; refused:",
        runs.len(),
        files.len()
    );
    for m in &refused {
        eprintln!("  {m}");
    }
    // Measured on example-robot-data 6.0.0: 56 of 69 run. The 13 refusals: inertias no rigid
    // body has on moving links (6; MuJoCo refuses them too), a zero mass with an inertia, a
    // mimic of a joint that does not exist, a massless moving link, a file with no link, two
    // drones without a moving joint, a quadruped on which init takes a sensor for the tool.
    assert!(
        runs.len() >= 56,
        "only {} of {} run",
        runs.len(),
        files.len()
    );
    // Their meshes (STL, COLLADA, OBJ behind package:// paths) are found and read.
    let drawn: usize = runs.iter().map(|r| r.2).sum();
    let missing: Vec<&String> = runs.iter().flat_map(|r| &r.3).collect();
    eprintln!("{drawn} meshes drawn, {} mesh warnings", missing.len());
    for w in &missing {
        eprintln!("  {w}");
    }
    assert!(missing.is_empty(), "{} mesh warnings", missing.len());
    assert!(drawn >= 500, "{drawn} meshes drawn");
}
