//! Sweeps: N variants × a grid or seeded samples × a suite of scenarios, every run independent,
//! run on all cores (and, as shards, on any engine that can start a process: see
//! `tools/ray_sweep.py`), collected into one table with a summary and plots.
//!
//! - [`file`]: the sweep file and the runs it stands for.
//! - [`runner`]: the runs in parallel (rayon), deterministic, planning once per distinct
//!   setpoint stream; a failed run is a row with its error.
//! - [`results`]: rows → `results.csv`, `results.json`, `summary.md`, plots; and `merge` of
//!   shard outputs into the same files.

pub mod file;
pub mod results;
pub mod runner;

pub use file::{parse_shard, Change, Distribution, RandomSpec, RunSpec, Sweep, MAX_RUNS};
pub use results::{merge, write_results, Row, SweepResults};
pub use runner::{execute, run_sweep, Job, JobResult, Progress};

use crate::diagnostics::FileError;
use crate::machine::Machine;
use crate::scenario::{edit_toml, Override};
use std::path::Path;

/// A change of the machine a run simulates: `drives.<key>=<value>` edits the drives file
/// (any key of it, e.g. `drives.axes.x.guide.friction_coefficient=0.02`), `links.<link>.mass=<kg>`
/// sets a URDF link's mass and scales its inertia alike (the same body, heavier).
#[derive(Debug, Clone)]
pub struct MachineOverride {
    pub text: String,
    kind: MachineChange,
}

#[derive(Debug, Clone)]
enum MachineChange {
    Drives(Override),
    LinkMass { link: String, mass: f64 },
}

impl MachineOverride {
    pub fn parse(text: &str) -> Result<MachineOverride, String> {
        let kind = if let Some(rest) = text.strip_prefix("drives.") {
            MachineChange::Drives(Override::parse(rest).map_err(|e| format!("drives.{e}"))?)
        } else {
            let parsed = text.strip_prefix("links.").and_then(|rest| {
                let (key, value) = rest.split_once('=')?;
                let link = key.trim().strip_suffix(".mass")?;
                Some((link.to_string(), value.trim().parse::<f64>().ok()?))
            });
            match parsed {
                Some((link, mass)) if mass.is_finite() && mass > 0.0 => {
                    MachineChange::LinkMass { link, mass }
                }
                _ => {
                    return Err(format!(
                        "{text}: expected drives.<key>=<value> or links.<link>.mass=<kg> (a positive number)"
                    ))
                }
            }
        };
        Ok(MachineOverride {
            text: text.to_string(),
            kind,
        })
    }
}

/// The machine of `urdf` with `changes` applied (the drives file edited before it is read,
/// then the link masses), every check of loading a machine applied to the result.
pub fn machine_with(urdf: &Path, changes: &[&MachineOverride]) -> Result<Machine, FileError> {
    if changes.is_empty() {
        return Machine::load(urdf);
    }
    let drives_path = crate::machine::DrivesFile::path_for(urdf);
    let urdf_text = crate::diagnostics::read_text(urdf, "machine model (URDF)")?;
    let drives_text = crate::diagnostics::read_text(&drives_path, "drive data")?;
    let drives: Vec<Override> = changes
        .iter()
        .filter_map(|c| match &c.kind {
            MachineChange::Drives(o) => Some(o.clone()),
            _ => None,
        })
        .collect();
    let edited = edit_toml(&drives_text, &drives)
        .map_err(|e| FileError::new(&drives_path, None, format!("drives.{e}")))?;
    let mut machine = Machine::parse(urdf, &urdf_text, &edited)?;
    for c in changes {
        if let MachineChange::LinkMass { link, mass } = &c.kind {
            let Some(i) = machine.link_index(link) else {
                return Err(FileError::new(
                    urdf,
                    None,
                    format!("{}: the machine has no link '{link}'", c.text),
                ));
            };
            let l = &mut machine.links[i];
            if l.mass <= 0.0 {
                return Err(FileError::new(
                    urdf,
                    None,
                    format!(
                        "{}: link '{link}' is massless; its mass cannot be scaled",
                        c.text
                    ),
                ));
            }
            let (lo, hi) = (
                crate::machine::MIN_LINK_MASS_KG,
                crate::machine::MAX_LINK_MASS_KG,
            );
            crate::diagnostics::check_range(&c.text, *mass, "kg", lo, hi)
                .map_err(|m| FileError::new(urdf, None, m))?;
            l.inertia *= mass / l.mass;
            l.mass = *mass;
        }
    }
    Ok(machine)
}
