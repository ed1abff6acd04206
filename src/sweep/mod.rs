//! Sweeps: N variants × a grid or seeded samples × a suite of scenarios, every run independent,
//! run on all cores (and, as shards, on any engine that can start a process: see
//! `tools/ray_sweep.py`), collected into one table with a summary and plots.
//!
//! - [`mod@file`]: the sweep file and the runs it stands for.
//! - [`runner`]: the runs in parallel (rayon), deterministic, planning once per distinct
//!   setpoint stream; a failed run is a row with its error.
//! - [`results`]: rows → `results.csv`, `results.json`, `summary.md`, plots; and `merge` of
//!   shard outputs into the same files.
//! - [`calibrate`]: CMA-ES over machine and scenario keys against measured figures or traces,
//!   each generation's candidates run by the runner.

pub mod calibrate;
pub mod file;
pub mod results;
pub mod runner;

pub use file::{
    check_run_timeout, parse_shard, Change, Distribution, RandomSpec, RunSpec, Sweep, MAX_RUNS,
    RUN_TIMEOUT_S,
};
pub use results::{merge, write_results, MergeOutput, Row, SweepOutput, SweepResults};
pub use runner::{
    execute, input_files, read_record, run_list_digest, run_sweep, Job, JobResult, Progress, RECORD,
};

use crate::diagnostics::FileError;
use crate::machine::Machine;
use crate::scenario::{edit_toml, Override};
use std::path::{Path, PathBuf};

/// A change of the machine a run simulates: `drives.<key>=<value>` edits the drives file
/// (any key of it, e.g. `drives.axes.x.guide.friction_coefficient=0.02`), `links.<link>.mass=<kg>`
/// sets a URDF link's mass and scales its inertia alike (the same body, heavier).
#[derive(Debug, Clone)]
pub struct MachineOverride {
    /// The override as written, e.g. `links.carriage.mass=12`.
    pub text: String,
    kind: MachineChange,
}

#[derive(Debug, Clone)]
enum MachineChange {
    Drives(Override),
    LinkMass { link: String, mass: f64 },
}

impl MachineOverride {
    /// Reads `drives.<key>=<value>` or `links.<link>.mass=<kg>` (a positive number); the error
    /// says which form was expected.
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
    // The text as the loader reads it (a xacro file expanded).
    let urdf_text = crate::machine::load_urdf(urdf)?.text;
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

/// The files of the machine `urdf` with `changes` written into them, comments and layout kept:
/// drives keys edited in the drives file, link masses (and their inertia, scaled alike) in the
/// URDF. The edited machine is loaded and checked first, so a refused value edits nothing.
pub fn machine_edits(
    urdf: &Path,
    changes: &[&MachineOverride],
) -> Result<Vec<(PathBuf, String)>, FileError> {
    if changes.is_empty() {
        return Ok(Vec::new());
    }
    machine_with(urdf, changes)?;
    let mut edits = Vec::new();
    let drives: Vec<Override> = changes
        .iter()
        .filter_map(|c| match &c.kind {
            MachineChange::Drives(o) => Some(o.clone()),
            _ => None,
        })
        .collect();
    if !drives.is_empty() {
        let path = crate::machine::DrivesFile::path_for(urdf);
        let text = crate::diagnostics::read_text(&path, "drive data")?;
        let edited = edit_toml(&text, &drives)
            .map_err(|e| FileError::new(&path, None, format!("drives.{e}")))?;
        edits.push((path, edited));
    }
    let masses: Vec<(&str, f64)> = changes
        .iter()
        .filter_map(|c| match &c.kind {
            MachineChange::LinkMass { link, mass } => Some((link.as_str(), *mass)),
            _ => None,
        })
        .collect();
    if !masses.is_empty() {
        if crate::machine::xacro::is_xacro(urdf) {
            return Err(FileError::new(
                urdf,
                None,
                "link masses are written into a URDF, not into a xacro file (its masses may be macro arguments or expressions): write them into the xacro by hand",
            ));
        }
        let mut text = crate::diagnostics::read_text(urdf, "machine model (URDF)")?;
        for (link, mass) in masses {
            text = set_link_mass(&text, link, mass).map_err(|m| FileError::new(urdf, None, m))?;
        }
        edits.push((urdf.to_path_buf(), text));
    }
    Ok(edits)
}

/// `text` (a URDF) with link `link`'s `<mass value>` set to `mass` and its `<inertia>` moments
/// scaled by the same factor (the same body, heavier), to six significant digits; every other
/// byte as it was.
fn set_link_mass(text: &str, link: &str, mass: f64) -> Result<String, String> {
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_str(text);
    let (mut inside, mut depth) = (false, 0usize);
    let mut tags: Vec<(&str, std::ops::Range<usize>)> = Vec::new();
    loop {
        let start = reader.buffer_position() as usize;
        let event = reader.read_event().map_err(|e| e.to_string())?;
        let end = reader.buffer_position() as usize;
        match event {
            Event::Start(_) if inside => depth += 1,
            Event::Start(e) if e.name().as_ref() == b"link" => {
                inside = e
                    .try_get_attribute("name")
                    .ok()
                    .flatten()
                    .is_some_and(|a| a.value.as_ref() == link.as_bytes());
                depth = 0;
            }
            Event::Empty(e) if inside => match e.name().as_ref() {
                b"mass" => tags.push(("mass", start..end)),
                b"inertia" => tags.push(("inertia", start..end)),
                _ => {}
            },
            Event::End(_) if inside => {
                if depth == 0 {
                    break;
                }
                depth -= 1;
            }
            Event::Eof => break,
            _ => {}
        }
    }
    let mass_tag = tags
        .iter()
        .find(|(k, _)| *k == "mass")
        .ok_or_else(|| format!("link '{link}' has no <mass value=\"…\"/>"))?;
    let old = attribute(&text[mass_tag.1.clone()], "value")
        .and_then(|(_, v)| v.parse::<f64>().ok())
        .filter(|m| *m > 0.0)
        .ok_or_else(|| format!("link '{link}': its <mass> has no positive value"))?;
    let scale = mass / old;
    let six = |v: f64| {
        format!("{:.5e}", v)
            .parse::<f64>()
            .map_or(v, |r| r)
            .to_string()
    };
    let mut out = text.to_string();
    // Right to left, so earlier offsets stay valid.
    let mut spans = tags;
    spans.sort_by_key(|(_, r)| std::cmp::Reverse(r.start));
    for (kind, range) in spans {
        let mut tag = out[range.clone()].to_string();
        let names: &[&str] = if kind == "mass" {
            &["value"]
        } else {
            &["ixx", "iyy", "izz", "ixy", "ixz", "iyz"]
        };
        for name in names {
            if let Some((span, v)) = attribute(&tag, name) {
                let v: f64 = v.parse().map_err(|_| {
                    format!("link '{link}': <{kind} {name}=\"{v}\"> is not a number")
                })?;
                tag.replace_range(span, &six(v * scale));
            }
        }
        out.replace_range(range, &tag);
    }
    Ok(out)
}

/// The byte range and text of attribute `name`'s value in one XML tag.
fn attribute<'a>(tag: &'a str, name: &str) -> Option<(std::ops::Range<usize>, &'a str)> {
    let bytes = tag.as_bytes();
    let mut from = 0;
    while let Some(i) = tag[from..].find(name).map(|i| i + from) {
        from = i + name.len();
        if i == 0 || !bytes[i - 1].is_ascii_whitespace() {
            continue;
        }
        let rest = tag[from..].trim_start();
        let Some(after_eq) = rest.strip_prefix('=') else {
            continue;
        };
        let value = after_eq.trim_start();
        let quote = value.chars().next().filter(|q| *q == '"' || *q == '\'')?;
        let start = tag.len() - value.len() + 1;
        let end = start + tag[start..].find(quote)?;
        return Some((start..end, &tag[start..end]));
    }
    None
}
