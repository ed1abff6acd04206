//! Real part programs written by others. They are not committed: `tests/fixtures/corpus.md`
//! lists each one's repository, commit, path and licence; with `CNCSIM_PROGRAM_CORPUS=DIR`
//! (the files laid out as `owner+name/path`) the listed ones are checked. CI cannot fetch them
//! (its network reaches only the package registries), so there the test passes over them.
//! Every listed file must decode (or be refused with the message listed for it), and for CL
//! data every GOTO point of the file must be a point the tool goes to: no geometry lost.
//!
//! `CNCSIM_CL_CORPUS=DIR` runs the GOTO check on every file of another directory of CL data.

use std::path::{Path, PathBuf};

use cncsim::program::{read_program_detailed, Program, ProgramFormat, ReadOptions};
use nalgebra::{Matrix3, Vector3};

struct Entry {
    repo: String,
    path: String,
    expected: String,
}

/// The `corpus` table of `tests/fixtures/corpus.md`: `| repo | commit | licence | path | expected |`.
fn manifest() -> Vec<Entry> {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/corpus.md"),
    )
    .unwrap();
    text.lines()
        .filter(|line| line.starts_with("| `"))
        .map(|line| {
            let cells: Vec<&str> = line
                .trim_matches('|')
                .split(" | ")
                .map(|c| c.trim().trim_matches('`'))
                .collect();
            Entry {
                repo: cells[0].to_string(),
                path: cells[3].to_string(),
                expected: cells[4].to_string(),
            }
        })
        .collect()
}

fn corpus_directory(variable: &str, required: bool) -> Option<PathBuf> {
    match std::env::var(variable) {
        Ok(directory) => Some(PathBuf::from(directory)),
        Err(_) => {
            let require =
                required && std::env::var("CNCSIM_REQUIRE_ORACLES").is_ok_and(|v| v == "1");
            assert!(
                !require,
                "{variable} is not set and CNCSIM_REQUIRE_ORACLES=1"
            );
            eprintln!("skipped: {variable} is not set");
            None
        }
    }
}

/// The GOTO points of a CL file (m, MSYS applied), each with whether a cycle was on (then
/// the tool axis at it, along which the hole lies).
fn goto_points(text: &str) -> Vec<(Vector3<f64>, Option<Vector3<f64>>)> {
    let mut rotation = Matrix3::identity();
    let mut origin = Vector3::zeros();
    let mut scale = 1e-3;
    let mut cycle = false;
    let mut axis = Vector3::z();
    let mut points = Vec::new();
    let numbers = |rest: &str| -> Vec<f64> {
        rest.split(',')
            .filter_map(|v| v.trim().parse().ok())
            .collect()
    };
    for line in text.lines() {
        let line = line.trim().to_ascii_uppercase();
        if let Some(rest) = line.strip_prefix("UNITS/") {
            scale = if rest.starts_with("INCH") {
                0.0254
            } else {
                1e-3
            };
        } else if let Some(rest) = line.strip_prefix("MSYS/") {
            let v = numbers(rest);
            let x = Vector3::new(v[3], v[4], v[5]).normalize();
            let y = Vector3::new(v[6], v[7], v[8]).normalize();
            rotation = Matrix3::from_columns(&[x, y, x.cross(&y)]);
            origin = Vector3::new(v[0], v[1], v[2]) * scale;
        } else if let Some(rest) = line.strip_prefix("CYCLE/") {
            cycle = !rest.starts_with("OFF");
        } else if let Some(rest) = line.strip_prefix("GOTO/") {
            let v = numbers(rest);
            if v.len() == 6 {
                axis = rotation * Vector3::new(v[3], v[4], v[5]).normalize();
            }
            let point = rotation * Vector3::new(v[0], v[1], v[2]) * scale + origin;
            points.push((point, cycle.then_some(axis)));
        }
    }
    points
}

/// Checks that the moves go through every GOTO point in order (a hole: a move on the line
/// through it along the tool axis). Returns what is missing.
fn every_goto_reached(text: &str, program: &Program) -> Result<(), String> {
    let ends: Vec<Vector3<f64>> = program
        .moves
        .iter()
        .map(|m| Vector3::from(m.end.linear))
        .collect();
    let mut cursor = 0;
    for (index, (point, hole_axis)) in goto_points(text).iter().enumerate() {
        let hit = ends[cursor..].iter().position(|end| match hole_axis {
            None => (end - point).norm() < 1e-9,
            Some(axis) => {
                let d = end - point;
                (d - axis * d.dot(axis)).norm() < 1e-9
            }
        });
        match hit {
            Some(offset) => cursor += offset,
            None => {
                return Err(format!(
                    "GOTO number {} ({:.4}, {:.4}, {:.4} mm) is not reached by the moves after move {cursor}",
                    index + 1,
                    point.x * 1e3,
                    point.y * 1e3,
                    point.z * 1e3
                ))
            }
        }
    }
    Ok(())
}

fn check(path: &Path) -> Result<(ProgramFormat, usize), String> {
    let outcome =
        read_program_detailed(path, &ReadOptions::default()).map_err(|e| e.to_string())?;
    if outcome.format == ProgramFormat::Apt {
        let text = String::from_utf8_lossy(&std::fs::read(path).unwrap()).into_owned();
        every_goto_reached(&text, &outcome.program)?;
    }
    Ok((outcome.format, outcome.program.moves.len()))
}

#[test]
fn the_listed_real_programs_decode_and_keep_their_geometry() {
    let Some(directory) = corpus_directory("CNCSIM_PROGRAM_CORPUS", false) else {
        return;
    };
    let entries = manifest();
    assert!(entries.len() >= 10);
    let mut failures = Vec::new();
    let mut decoded = 0;
    for entry in &entries {
        let path = directory
            .join(entry.repo.replace('/', "+"))
            .join(&entry.path);
        let result = check(&path);
        println!("{}/{}: {result:?}", entry.repo, entry.path);
        match (&result, entry.expected.as_str()) {
            (Ok(_), "decodes") => decoded += 1,
            (Err(message), expected) if expected != "decodes" && message.contains(expected) => {}
            _ => failures.push(format!(
                "{}/{}: expected {}, got {result:?}",
                entry.repo, entry.path, entry.expected
            )),
        }
    }
    println!("{decoded} of {} decoded", entries.len());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn cl_data_of_a_corpus_directory_keep_every_goto() {
    let Some(directory) = corpus_directory("CNCSIM_CL_CORPUS", false) else {
        return;
    };
    let mut paths: Vec<PathBuf> = std::fs::read_dir(directory)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    paths.sort();
    let mut failures = Vec::new();
    for path in &paths {
        let result = check(path);
        println!("{}: {result:?}", path.display());
        if result.is_err() {
            failures.push(format!("{}: {result:?}", path.display()));
        }
    }
    println!(
        "{} of {} decoded with every GOTO reached",
        paths.len() - failures.len(),
        paths.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
