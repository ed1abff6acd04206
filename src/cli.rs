//! Command-line interface.

use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(name = "cncsim", version, about = "Physics co-simulation testbed for CNC machines", long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run a scenario: write metrics.json, trace.csv and run.rrd, print the metrics.
    Run {
        scenario: PathBuf,
        /// Output folder (default: out/<scenario name>).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Run scenarios (files, or folders of *.toml) and check their [expect] bounds; exits
    /// non-zero if any bound is breached or any run fails.
    Check {
        #[arg(required = true)]
        scenarios: Vec<PathBuf>,
        /// Output root (default: out/); each scenario writes to <root>/<name>.
        #[arg(long)]
        out: Option<PathBuf>,
    },
}
