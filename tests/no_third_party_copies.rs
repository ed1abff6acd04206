//! The repository holds only what the project wrote. Machines, scenarios and fixtures copied
//! from another project (with its licence file, a note of where the copy came from, or its
//! copyright notice) are not committed: tests read such files from the shared corpus beside the
//! checkout (`tests/common`'s `shared_corpus`). This test fails on any file under `models/`,
//! `scenarios/` or `tests/fixtures/` that says it is a copy of another project's file.

use std::path::{Path, PathBuf};

/// The folders that must hold only the project's own files.
const OWN_FOLDERS: &[&str] = &["models", "scenarios", "tests/fixtures"];

/// File names (before the first dot, any case) that come with a copy: a licence, a notice, a
/// note of the copy's source.
const COPY_FILE_NAMES: &[&str] = &[
    "license",
    "licence",
    "copying",
    "notice",
    "copyright",
    "authors",
    "source",
];

/// What a copied file or its note says (matched in lower case).
const COPY_MARKS: &[&str] = &[
    "copied from",
    "byte for byte",
    "verbatim copy",
    "unmodified from",
    "taken from the repository",
    "from the public repository",
    "copyright (c)",
    "copyright ©",
    "all rights reserved",
    "spdx-license-identifier",
    "permission is hereby granted",
    "licensed under the apache license",
    "gnu general public license",
    "automatically created by",
];

/// Why `path` (with its contents) looks like a copy of another project's file, if it does.
fn copy_mark(path: &Path, contents: &[u8]) -> Option<String> {
    let name = path.file_name()?.to_string_lossy().to_lowercase();
    // `LICENSE`, `LICENSE-MIT`, `SOURCE.md`, `their_gantry_LICENSE.txt`: the first or last word of
    // the name before its extension.
    let stem = name.split('.').next().unwrap_or("");
    let words: Vec<&str> = stem.split(['-', '_']).collect();
    let first = words.first().copied().unwrap_or("");
    let last = words.last().copied().unwrap_or("");
    if COPY_FILE_NAMES.contains(&first) || (last != "source" && COPY_FILE_NAMES.contains(&last)) {
        return Some(format!(
            "its name ({name}) is that of a licence or a source note"
        ));
    }
    let text = String::from_utf8_lossy(&contents[..contents.len().min(1 << 20)]).to_lowercase();
    COPY_MARKS
        .iter()
        .find(|mark| text.contains(*mark))
        .map(|mark| format!("it says \"{mark}\""))
}

fn files_under(dir: &Path, found: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files_under(&path, found);
        } else {
            found.push(path);
        }
    }
}

/// Every file under `folders` of `root` that looks like a copy, with the reason.
fn copies_under(root: &Path, folders: &[&str]) -> Vec<String> {
    let mut files = Vec::new();
    for folder in folders {
        files_under(&root.join(folder), &mut files);
    }
    files.sort();
    files
        .iter()
        .filter_map(|path| {
            let contents = std::fs::read(path).ok()?;
            copy_mark(path, &contents).map(|why| {
                format!(
                    "{}: {why}",
                    path.strip_prefix(root).unwrap_or(path).display()
                )
            })
        })
        .collect()
}

#[test]
fn models_scenarios_and_fixtures_hold_no_copy_of_another_projects_file() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let copies = copies_under(root, OWN_FOLDERS);
    assert!(
        copies.is_empty(),
        "files copied from other projects (they belong in the shared corpus, not here):\n{}",
        copies.join("\n")
    );
}

#[test]
fn a_licence_file_or_a_note_of_a_copy_is_found() {
    // The check itself, on a tree written here: it must fail where a copy sits.
    let dir = tempfile::tempdir().unwrap();
    let write = |relative: &str, text: &str| {
        let path = dir.path().join(relative);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    };
    write("models/own.urdf", "<robot name=\"own\"/>\n");
    write(
        "scenarios/own.toml",
        "# written here\nmachine = \"../models/own.urdf\"\n",
    );
    assert!(copies_under(dir.path(), OWN_FOLDERS).is_empty());

    write("models/their_gantry/LICENSE", "MIT License\n");
    write("models/their_gantry_LICENSE.txt", "MIT License\n");
    write(
        "tests/fixtures/cl/theirs/SOURCE.md",
        "Where these came from.\n",
    );
    write(
        "tests/fixtures/cl/theirs/part.ncl",
        "$$ copied byte for byte from the public repository someone/cam\nGOTO/0,0,0\n",
    );
    write(
        "scenarios/programs/theirs.ngc",
        "( Copyright (c) 2019 Someone. All rights reserved. )\nG0 X0\n",
    );
    write(
        "models/exported/urdf/exported.urdf",
        "<!-- This URDF was automatically created by SolidWorks to URDF Exporter! -->\n<robot name=\"x\"/>\n",
    );
    let copies = copies_under(dir.path(), OWN_FOLDERS);
    assert_eq!(copies.len(), 6, "{copies:#?}");
    for (path, why) in [
        ("models/their_gantry/LICENSE", "its name (license)"),
        (
            "models/their_gantry_LICENSE.txt",
            "its name (their_gantry_license.txt)",
        ),
        ("tests/fixtures/cl/theirs/SOURCE.md", "its name (source.md)"),
        ("tests/fixtures/cl/theirs/part.ncl", "\"byte for byte\""),
        ("scenarios/programs/theirs.ngc", "\"copyright (c)\""),
        (
            "models/exported/urdf/exported.urdf",
            "\"automatically created by\"",
        ),
    ] {
        assert!(
            copies
                .iter()
                .any(|c| c.starts_with(&format!("{path}: ")) && c.contains(why)),
            "{path} not found for {why}: {copies:#?}"
        );
    }
}
