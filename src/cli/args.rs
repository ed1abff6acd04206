//! Command-line interface.

use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(name = "cncsim", version, about = "Physics co-simulation testbed for CNC machines", long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    /// A directory to look for the ROS packages of `package://` mesh files in (it may be a
    /// package, or hold packages below it), searched before `ROS_PACKAGE_PATH`; may be given
    /// more than once.
    #[arg(long = "package-path", value_name = "DIR", global = true, action = clap::ArgAction::Append)]
    pub package_path: Vec<PathBuf>,
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
    /// A/B: run two variants on the same setpoints (e.g. PID against inverse dynamics) and
    /// compare contour error, following error, torque and time side by side; writes OUT/ab.md,
    /// OUT/ab.json, OUT/contour_error.png and each variant's outputs. The variants are two
    /// scenario files, or one file run twice with overrides:
    /// `cncsim ab S.toml --a controller=pid --b controller=inverse-dynamics`; without --a/--b
    /// one file runs the variants its `[ab]` table declares.
    Ab {
        /// Scenario of variant A (and of B when no second file is given).
        #[arg(value_name = "A.toml")]
        scenario: PathBuf,
        /// Scenario of variant B (default: the same file as A).
        #[arg(value_name = "B.toml")]
        other: Option<PathBuf>,
        /// Overrides for variant A: dotted scenario keys and TOML values, e.g.
        /// `controller=pid` (short for controller.type), `controller.natural_frequency_hz=30`,
        /// `timing.physics_step_ms=0.125`; bare words are strings.
        #[arg(long = "a", value_name = "KEY=VALUE", num_args = 1.., action = clap::ArgAction::Append)]
        a_overrides: Vec<String>,
        /// Overrides for variant B, as for --a.
        #[arg(long = "b", value_name = "KEY=VALUE", num_args = 1.., action = clap::ArgAction::Append)]
        b_overrides: Vec<String>,
        /// Output folder (default: out/ab_<A>_vs_<B>).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// ISO 230-4 circular (ballbar) test on the scenario's machine and controller: feed-in,
    /// a full circle counter-clockwise and one clockwise with 45° overshoot arcs, for every
    /// feed at every radius; prints G, H, F and the diagnosis; writes OUT/ballbar.json,
    /// OUT/ballbar.rrd and per run OUT/F<feed>_R<radius>/ (polar.png, polar.csv, metrics.json
    /// with the figures under `ballbar`, and the run's own trace and recording).
    Ballbar {
        scenario: PathBuf,
        /// Radius or radii (mm), comma-separated (default: the scenario's circle, else 100).
        #[arg(long = "radius-mm", value_delimiter = ',', num_args = 1.., allow_negative_numbers = true)]
        radius_mm: Vec<f64>,
        /// Feed or feeds (mm/min), comma-separated (default: the scenario's circle feed,
        /// else 1000).
        #[arg(long = "feed-mm-min", value_delimiter = ',', num_args = 1.., allow_negative_numbers = true)]
        feed_mm_min: Vec<f64>,
        /// Plane of the circle (default: the scenario's ballbar program's, else xy).
        #[arg(long, value_enum)]
        plane: Option<cncsim::scenario::BallbarPlane>,
        /// Centre in program coordinates, mm (x,y,z); default: the scenario's circle centre
        /// or program start, else the middle of the travel.
        #[arg(
            long = "center-mm",
            value_delimiter = ',',
            allow_negative_numbers = true
        )]
        center_mm: Option<Vec<f64>>,
        /// Overshoot arc before and after the 360° of data (degrees, 0 < o ≤ 180; default
        /// 45): long enough for the planner's speed-up and slow-down to stay out of the data.
        #[arg(long = "overshoot-deg", allow_negative_numbers = true)]
        overshoot_deg: Option<f64>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// Output folder (default: out/ballbar_<scenario name>).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Plan a scenario's program only: cycle time, per-move durations, and max |v|, |a|, |j|
    /// per machine axis and at the tool tip on the workpiece.
    Plan {
        scenario: PathBuf,
        /// Planner to use instead of the scenario's own.
        #[arg(long, value_enum)]
        profile: Option<cncsim::scenario::ProfileName>,
        /// Write the setpoint positions at the servo period: `t_s`, then one column per axis
        /// in mm or deg, at full precision.
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Write a Rerun recording of the setpoints and the tool path on the workpiece.
        #[arg(long)]
        rrd: Option<PathBuf>,
    },
    /// Export the scenario's plant (machine, drives, friction, backlash, physics step) as an
    /// FMI 3.0 co-simulation FMU: input command_<axis>, outputs measured_position_<axis>,
    /// measured_velocity_<axis>, motor_position_<axis>, the planned setpoint_*_<axis>, …
    /// (docs/fmi.md). Needs the plant library built (`cargo build -p cncsim-fmu`).
    ExportFmu {
        scenario: PathBuf,
        /// The FMU file to write.
        #[arg(long, value_name = "FILE.fmu")]
        out: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Your own machine: `check` shows how cncsim reads a URDF and its drive file (letter →
    /// joint, direction, sign, travel, masses, meshes, what is missing); `init` writes a
    /// commented drive file for a URDF, its letters guessed from the kinematics.
    Machine {
        #[command(subcommand)]
        action: MachineCommand,
    },
    /// Rigid-body inverse dynamics of a URDF at one state: joint torques τ, M(q), C(q,q̇)q̇ and
    /// g(q) (SI units, joints in URDF order).
    Dynamics {
        urdf: PathBuf,
        /// Joint positions, comma-separated (m or rad).
        #[arg(
            long,
            value_delimiter = ',',
            allow_negative_numbers = true,
            required = true
        )]
        q: Vec<f64>,
        /// Joint velocities (m/s or rad/s).
        #[arg(
            long,
            value_delimiter = ',',
            allow_negative_numbers = true,
            required = true
        )]
        qd: Vec<f64>,
        /// Joint accelerations (m/s² or rad/s²).
        #[arg(
            long,
            value_delimiter = ',',
            allow_negative_numbers = true,
            required = true
        )]
        qdd: Vec<f64>,
        /// Gravity in the base frame (m/s²).
        #[arg(
            long,
            value_delimiter = ',',
            allow_negative_numbers = true,
            default_value = "0,0,-9.81"
        )]
        gravity: Vec<f64>,
        /// Print {"tau": [...], "mass_matrix": [[...]], "coriolis": [...], "gravity": [...]}.
        #[arg(long)]
        json: bool,
    },
    /// Decode a part program (G-code, HPGL, APT CL data) and print its moves or a summary,
    /// cut and rapid / pen-up lengths and the program time at programmed feed.
    Inspect {
        program: PathBuf,
        /// Feed over the Euclidean norm of all axis deltas (mm and degrees), as in the 5-axis
        /// study, instead of LinuxCNC's rule.
        #[arg(long)]
        euclidean_feed: bool,
        /// HPGL: drop a dangling coordinate with a warning instead of rejecting the file.
        #[arg(long)]
        lenient: bool,
        /// HPGL: reorder and reverse strokes to shorten pen-up travel; report before/after.
        #[arg(long)]
        optimise_pen_up: bool,
        /// HPGL and APT: refuse commands and records that do not move the pen or tool
        /// (instead of skipping them with one warning per kind).
        #[arg(long)]
        strict: bool,
        /// HPGL: draw fills (RA RR WG FP) as outlines only, without hatch lines.
        #[arg(long)]
        no_hatch: bool,
        /// HPGL: plot only page N (from 1; pages are counted at each PG, FR, AF, AH, as
        /// hp2xx -P counts them). Default: every page, one over another, as hp2xx draws them.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
        page: Option<u32>,
        /// APT CL data: the feed (mm/s) of moves before any FEDRAT, for a file that programs
        /// none (a list of GOTO records).
        #[arg(long, value_name = "MM_S")]
        feed: Option<f64>,
        /// APT CL data: read it as this CAM system writes it (nx, creo, catia, solidworks,
        /// camworks, mastercam, fusion, apt) instead of the one its header names.
        #[arg(long, value_name = "NAME", value_parser = parse_cl_writer)]
        cl_writer: Option<cncsim::program::ClWriter>,
        /// List every move, however long the program.
        #[arg(long)]
        all: bool,
        /// G-code: a LinuxCNC tool table file (`T1 P1 Z50 D6`, lengths in mm) for T, M6,
        /// G43 and cutter compensation.
        #[arg(long)]
        tool_table: Option<PathBuf>,
    },
    /// Frequency response of one axis measured on the physics through the scenario's loop
    /// (stepped sine), with the linear model from the drive data laid over it: resonances,
    /// antiresonances, −3 dB bandwidth, gain and phase margins; writes OUT/bode.png, bode.csv,
    /// bode.json and bode.rrd (docs/frequency-response.md).
    Bode {
        scenario: PathBuf,
        /// Machine axis to measure (e.g. x).
        #[arg(long)]
        axis: String,
        /// What to measure: the plant (excitation added to the controller output, the loop
        /// holding the axis), the closed velocity loop of a cascade, or the closed position
        /// loop; the open loop at the plant input is measured with each.
        #[arg(long = "loop", value_enum, default_value_t = BodeLoop::Plant)]
        lp: BodeLoop,
        /// Lowest frequency (Hz; default 2).
        #[arg(long, allow_negative_numbers = true)]
        from: Option<f64>,
        /// Highest frequency (Hz; default 0.4 of the servo rate; below the Nyquist frequency).
        #[arg(long, allow_negative_numbers = true)]
        to: Option<f64>,
        /// Frequencies per decade.
        #[arg(long, default_value_t = 12)]
        per_decade: usize,
        /// Measure the analytic reference model instead of the physics.
        #[arg(long)]
        analytic: bool,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// Output folder (default: out/bode_<scenario>_<axis>_<loop>).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Ziegler–Nichols gains for one axis: find the ultimate gain K_cr and period P_cr of the
    /// scenario's simulated axis (P only, raised until sustained oscillation), print Kp, Ki, Kd
    /// and a ready-to-paste `axes.<axis> = { ... }` line.
    Tune {
        scenario: PathBuf,
        /// Machine axis to tune (e.g. x).
        #[arg(long)]
        axis: String,
        /// Setpoint step that excites a linear axis (mm).
        #[arg(long, default_value_t = 0.05)]
        step_mm: f64,
        /// Setpoint step that excites a rotary axis (deg).
        #[arg(long, default_value_t = 0.05)]
        step_deg: f64,
        /// Relative width of the final gain bracket, K_hi/K_lo − 1.
        #[arg(long, default_value_t = 0.005)]
        tolerance: f64,
        /// Simulated time per trial (s) to start from; doubled (up to 60 s) until the
        /// oscillating bound shows four periods.
        #[arg(long, default_value_t = 1.0)]
        trial_s: f64,
        /// First gain tried (default: the scenario's kp for the axis).
        #[arg(long)]
        start_gain: Option<f64>,
        /// Give up after this many simulations.
        #[arg(long, default_value_t = 60)]
        max_simulations: usize,
        /// Run the trials on the analytic reference model instead of the physics.
        #[arg(long)]
        analytic: bool,
        /// Tune the linear part of the axis: the scenario with friction and backlash off
        /// (as a gain design on a linear model does).
        #[arg(long)]
        linear: bool,
        /// Print the report as JSON (progress still goes to stderr).
        #[arg(long)]
        json: bool,
        /// Design the cascade (position loop over velocity loop) of the axis instead, on the
        /// axis's linear model (the one `bode` draws): the velocity loop at the largest
        /// crossover with 50° of phase and 6 dB of gain margin, the position loop at a quarter
        /// of it, checked by a velocity step on the simulated axis.
        #[arg(long)]
        cascade: bool,
        /// With --cascade: impose the velocity-loop crossover (Hz) instead of the largest that
        /// keeps the margins.
        #[arg(long, requires = "cascade")]
        velocity_bandwidth_hz: Option<f64>,
    },
    /// Sweep: every variant × grid point × sample of a sweep file over its scenarios, on all
    /// cores; writes OUT/results.csv, results.json, summary.md, plots and per-run outputs.
    Sweep {
        sweep: PathBuf,
        /// Runs at once (default: the number of cores).
        #[arg(long)]
        jobs: Option<usize>,
        /// Run only shard K of N (every N-th run from the K-th), e.g. 2/4; `cncsim merge`
        /// combines the shards' output folders.
        #[arg(long)]
        shard: Option<String>,
        /// Output folder (default: out/sweep_<name>, or …_shard_K_of_N).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Wall-clock seconds a run may take (instead of the sweep file's run_timeout_s); a
        /// run past it is ended, its row says `timeout after N s`, and the sweep exits 1.
        #[arg(long, value_name = "S", value_parser = parse_run_timeout)]
        run_timeout_s: Option<f64>,
        /// Go on with the sweep that --out holds: run only the runs without a finished record
        /// there; refused when the folder holds another sweep's runs.
        #[arg(long)]
        resume: bool,
        /// Run nothing: list every file the sweep's runs read (the sweep file, scenarios,
        /// machines, drive files, meshes, programs, tool tables, FMUs, stock shapes), one
        /// absolute path per line: what a worker without this filesystem needs.
        #[arg(long, conflicts_with_all = ["resume", "out", "run_timeout_s", "jobs"])]
        inputs: bool,
    },
    /// Calibrate: fit machine and scenario keys to measured figures or traces (CMA-ES, seeded,
    /// candidates in parallel); writes OUT/report.md, evaluations.csv/json, convergence.png,
    /// and runs the target and [predict] scenarios with the best values into OUT/predictions/.
    Calibrate {
        spec: PathBuf,
        /// Runs at once (default: the number of cores).
        #[arg(long)]
        jobs: Option<usize>,
        /// Output folder (default: out/calibration_<name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write the best values into the drives files, URDFs and scenarios they came from
        /// (comments kept).
        #[arg(long)]
        write: bool,
        /// Go on with the calibration whose log (evaluation_log.jsonl) --out holds: its
        /// candidates are answered from the log, the search goes on from there to the result
        /// an uninterrupted calibration gives; refused when the log is another calibration's.
        #[arg(long)]
        resume: bool,
    },
    /// Merge the output folders of a sweep's shards into one (results, summary, plots).
    Merge {
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
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

#[derive(Subcommand, Debug)]
pub enum MachineCommand {
    /// Load a URDF with its drive file and print the mapping from program letters to joints.
    Check {
        urdf: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Write a drive file for a URDF (default: next to it, `<name>.drives.toml`).
    Init {
        urdf: PathBuf,
        /// Where to write it (`-` for standard output).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace an existing file.
        #[arg(long)]
        force: bool,
    },
    /// Print the URDF a xacro file expands to, as cncsim reads it: the `xacro` Python package
    /// with `$(find PKG)` resolved by cncsim's package search (no ROS needed).
    Expand { xacro: PathBuf },
}

/// The loop `cncsim bode` measures.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum BodeLoop {
    Plant,
    Velocity,
    Position,
}

/// `--cl-writer NAME`: a CAM system cncsim knows the CL conventions of.
fn parse_cl_writer(name: &str) -> Result<cncsim::program::ClWriter, String> {
    cncsim::program::ClWriter::from_name(name).ok_or_else(|| {
        format!(
            "expected one of {}, found '{name}'",
            cncsim::program::ClWriter::names()
        )
    })
}

/// `--run-timeout-s S`: seconds within the allowed range.
fn parse_run_timeout(text: &str) -> Result<f64, String> {
    let seconds: f64 = text
        .parse()
        .map_err(|_| format!("expected seconds, found '{text}'"))?;
    cncsim::sweep::check_run_timeout(seconds)
}
