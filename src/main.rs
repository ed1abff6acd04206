//! `cncsim`: parses the command line, runs the command, shows its report, and turns how it
//! ended into the exit status: 0 success; 1 a run stopped early, a bound was breached, a sweep
//! had a failed run or a tune found no boundary; 2 bad input; 130 interrupted (Ctrl-C).

use clap::Parser;
use cncsim::command::Ending;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

mod cli;
use cli::{Cli, Refused};

/// Set by Ctrl-C: a running simulation stops at its next progress report and still writes
/// everything it computed.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so printing into a closed pipe (`cncsim inspect … | head`) would
    // panic; the default action ends the process quietly, as other command-line tools do.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_DFL at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    if let Err(message) = cli::add_package_paths(&cli.package_path) {
        eprintln!("error: {message}");
        return ExitCode::from(2);
    }
    // A second Ctrl-C while the first is being handled ends the process the usual way.
    let _ = ctrlc::set_handler(|| {
        if INTERRUPTED.swap(true, Ordering::Relaxed) {
            std::process::exit(130);
        }
    });
    let ending = match cli::dispatch(cli.command, &INTERRUPTED) {
        Ok((report, json)) => cli::show(report.as_ref(), json),
        Err(Refused::BadInput(message)) => Ending::BadInput(Some(message)),
        Err(Refused::Failed(message)) => Ending::Failed(Some(message)),
    };
    match ending {
        Ending::Done => ExitCode::SUCCESS,
        Ending::Failed(message) => {
            if let Some(m) = message {
                eprintln!("error: {m}");
            }
            ExitCode::from(1)
        }
        Ending::BadInput(message) => {
            if let Some(m) = message {
                eprintln!("error: {m}");
            }
            ExitCode::from(2)
        }
        Ending::Interrupted(message) => {
            if let Some(m) = message {
                eprintln!("{m}");
            }
            ExitCode::from(130)
        }
    }
}
