//! The command line: its arguments ([`args`]), the commands that turn them into reports
//! ([`commands`]), and how a report reaches the terminal ([`show`]).

mod args;
mod commands;
mod show;

pub use args::Cli;
pub use commands::{dispatch, Refused};
pub use show::show;
