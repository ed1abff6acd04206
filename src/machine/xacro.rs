//! xacro without ROS. Most ROS robot descriptions ship as xacro (URDF with macros); cncsim
//! expands them through the `xacro` Python package (`pip install xacro`, no ROS needed), with
//! `$(find PKG)` resolved by cncsim's own package search instead of ROS's package index (a
//! stand-in `ament_index_python` module): the folders above the file (the package itself or
//! one beside it), then `--package-path` and `ROS_PACKAGE_PATH` up to three levels down, for a
//! folder whose `package.xml` names PKG. Arguments keep the defaults the file gives them.

use crate::diagnostics::FileError;
use std::path::{Path, PathBuf};

/// The Python that runs xacro: `CNCSIM_PYTHON`, else `python3`.
fn python() -> String {
    std::env::var("CNCSIM_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// `ament_index_python.packages` as xacro's `$(find)` calls it, answered from the folders in
/// `CNCSIM_PACKAGE_ROOTS` (the same search cncsim makes for `package://` meshes).
const FIND_SHIM: &str = r#"
import os, re

class PackageNotFoundError(Exception):
    pass

def _name(manifest):
    try:
        with open(manifest, encoding="utf-8", errors="replace") as f:
            found = re.search(r"<name>\s*([^<\s]+)\s*</name>", f.read())
        return found.group(1) if found else None
    except OSError:
        return None

def _is(folder, name):
    return _name(os.path.join(folder, "package.xml")) == name

def _folders(variable):
    return [r for r in os.environ.get(variable, "").split(os.pathsep) if r]

def get_package_share_directory(package_name):
    # The folders above the file: the package itself, or one beside it.
    above = _folders("CNCSIM_PACKAGES_ABOVE")
    for folder in above:
        for candidate in (folder, os.path.join(folder, package_name)):
            if _is(candidate, package_name):
                return candidate
    # The package path: searched up to three levels down.
    roots = _folders("CNCSIM_PACKAGE_ROOTS")
    for root in roots:
        for top, dirs, files in os.walk(root):
            depth = top[len(root):].count(os.sep)
            dirs[:] = sorted(d for d in dirs if not d.startswith(".")) if depth < 3 else []
            if "package.xml" in files and _is(top, package_name):
                return top
    raise PackageNotFoundError(
        "package '%s' not found: no package.xml naming it above the file (%s) or on the package path (%s); "
        "give the folder holding it with --package-path (or ROS_PACKAGE_PATH)"
        % (package_name, ", ".join(above) or "-", ", ".join(roots) or "none given")
    )
"#;

/// Runs xacro on `path` and returns the URDF it writes. `roots`: where `$(find PKG)` looks.
pub fn expand(path: &Path, roots: &[PathBuf]) -> Result<String, FileError> {
    run_xacro(path, roots, &[])
}

/// The files xacro reads for `path` (the file itself and every file it includes).
pub fn dependencies(path: &Path, roots: &[PathBuf]) -> Result<Vec<PathBuf>, FileError> {
    let listed = run_xacro(path, roots, &["--deps"])?;
    let mut files = vec![path.to_path_buf()];
    files.extend(listed.split_whitespace().map(PathBuf::from));
    Ok(files)
}

/// Runs xacro with `options` on `path`; returns what it writes.
fn run_xacro(path: &Path, roots: &[PathBuf], options: &[&str]) -> Result<String, FileError> {
    let fail = |m: String| FileError::new(path, None, m);
    // A folder of this call's own (runs of a sweep load their machines in parallel), removed
    // when it is dropped.
    let folder = tempfile::Builder::new()
        .prefix("cncsim-xacro-")
        .tempdir()
        .map_err(|e| {
            fail(format!(
                "cannot expand the xacro file: a temporary folder: {e}"
            ))
        })?;
    let shim = folder.path().to_path_buf();
    let package = shim.join("ament_index_python");
    std::fs::create_dir_all(&package)
        .and_then(|()| std::fs::write(package.join("__init__.py"), ""))
        .and_then(|()| std::fs::write(package.join("packages.py"), FIND_SHIM))
        .map_err(|e| {
            fail(format!(
                "cannot expand the xacro file: {}: {e}",
                shim.display()
            ))
        })?;
    let above: Vec<PathBuf> = path
        .canonicalize()
        .unwrap_or_else(|_| path.to_path_buf())
        .ancestors()
        .skip(1)
        .map(Path::to_path_buf)
        .collect();
    let python_path = std::env::join_paths(
        std::iter::once(shim.clone()).chain(std::env::var_os("PYTHONPATH").map(PathBuf::from)),
    )
    .map_err(|e| fail(format!("cannot expand the xacro file: {e}")))?;
    let joined = |folders: &[PathBuf]| {
        std::env::join_paths(folders)
            .map_err(|e| fail(format!("cannot expand the xacro file: {e}")))
    };
    let (above, roots) = (joined(&above)?, joined(roots)?);
    let ran = std::process::Command::new(python())
        .args([
            "-c",
            "import sys, xacro; sys.argv = ['xacro'] + sys.argv[1:]; xacro.main()",
        ])
        .args(options)
        .arg(path)
        .env("PYTHONPATH", python_path)
        .env("CNCSIM_PACKAGES_ABOVE", above)
        .env("CNCSIM_PACKAGE_ROOTS", roots)
        .output();
    drop(folder);
    let by_hand = format!(
        "`pip install xacro` (no ROS needed) and run again; `cncsim machine expand {} > FILE.urdf` then writes the expansion, and `--package-path DIR` finds a package `$(find …)` names elsewhere",
        path.display()
    );
    let ran = ran.map_err(|e| {
        fail(format!(
            "a xacro file: cncsim expands it with the xacro Python package, but {} cannot run ({e}): set CNCSIM_PYTHON to a Python with it, or {by_hand}",
            python()
        ))
    })?;
    let stderr = String::from_utf8_lossy(&ran.stderr);
    if !ran.status.success() {
        // xacro writes its reason, then the file it was in (each include on a line of its own).
        let why: Vec<&str> = stderr
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .map(|l| l.strip_prefix("error: ").unwrap_or(l))
            .map(plain_reason)
            .take(6)
            .collect();
        let why = if why.is_empty() {
            "no message".to_string()
        } else {
            why.join("; ")
        };
        if stderr.contains("No module named 'xacro'") {
            return Err(fail(format!(
                "a xacro file: cncsim expands it with the xacro Python package, which {} lacks: {by_hand}",
                python()
            )));
        }
        return Err(fail(format!("xacro could not expand it: {why}")));
    }
    String::from_utf8(ran.stdout).map_err(|_| fail("xacro wrote text that is not UTF-8".into()))
}

/// Whether `path` names a xacro file (`.xacro`, `.urdf.xacro`).
pub fn is_xacro(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("xacro"))
}

/// A line of xacro's error output without the exception's class, and said once (xacro prints
/// a substitution error's message twice).
fn plain_reason(line: &str) -> &str {
    let line = match line.strip_prefix("<class '") {
        Some(rest) => rest.split_once("'>: ").map_or(line, |(_, message)| message),
        None => line,
    };
    let half = line.len() / 2;
    match (line.get(..half), line.get(half + 1..)) {
        (Some(a), Some(b)) if a == b && line.as_bytes()[half] == b' ' => a,
        _ => line,
    }
}
