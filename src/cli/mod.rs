//! The command line: its arguments ([`args`]), the commands that turn them into reports
//! ([`commands`]), and how a report reaches the terminal ([`show`]).

mod args;
mod commands;
mod show;

pub use args::Cli;
pub use commands::{dispatch, Refused};
pub use show::show;

/// Puts the `--package-path` directories in front of `ROS_PACKAGE_PATH`, where the URDF loader
/// looks for `package://` meshes: called at start-up, before any thread exists (the variable
/// is read, never written, afterwards).
pub fn add_package_paths(dirs: &[std::path::PathBuf]) -> Result<(), String> {
    use cncsim::machine::ROS_PACKAGE_PATH;
    if dirs.is_empty() {
        return Ok(());
    }
    if let Some(missing) = dirs.iter().find(|d| !d.is_dir()) {
        return Err(format!(
            "--package-path {}: no such directory",
            missing.display()
        ));
    }
    let existing = std::env::var_os(ROS_PACKAGE_PATH).unwrap_or_default();
    let roots = dirs
        .iter()
        .cloned()
        .chain(std::env::split_paths(&existing).filter(|p| !p.as_os_str().is_empty()));
    let joined = std::env::join_paths(roots)
        .map_err(|e| format!("--package-path: {e} (a directory name holds the path separator)"))?;
    std::env::set_var(ROS_PACKAGE_PATH, joined);
    Ok(())
}
