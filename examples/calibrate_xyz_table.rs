//! Calibrates the unknowns of the XYZ-table twin on the paper's 5 mm/s circle only (seed digest
//! §2.3): the guide friction coefficient μ, the mass of the Z assembly (the `z_column` link) and
//! the servo settings, with gains that are not free but follow from Ziegler–Nichols on the
//! simulated axes (`cncsim tune --linear`) for every candidate.
//!
//! The servo settings the paper does not give are part of the search:
//! - the amplifier mode (default: current only; `--amplifier voltage,current` searches both).
//!   The paper's printed plant is the current-mode one: `cncsim tune --linear` reproduces its
//!   K_cr = 64.5 V/m and P_cr = 0.70 s in continuous time, and so its gain table, only with
//!   `amplifier_mode = "current"`;
//! - the servo period (the digest's 4 ms comes from another source document, which also uses
//!   20 ms);
//! - where the Ziegler–Nichols cycle is taken (`--design`): on the loop sampled at the
//!   candidate's period (`sampled`), or on the continuous-time linear model (`continuous`), as
//!   the paper did on its G_p(s): that design is the paper's own table (on X with m_z = 8 kg
//!   Kp 38.72, Ki 110.5, Kd 3.39; printed: 38.72, 110.63, 3.39), run at the candidate's period.
//!
//! The guide friction is searched as kinetic μ plus stiction: a static coefficient μ_s = ratio·μ
//! falling to μ over the Stribeck velocity v_s (ratio 1 = plain Coulomb friction).
//!
//! The gains are designed on the linear part of the axis (friction and backlash removed). For
//! each (amplifier mode, servo period, design, m_z) tune X, Y and Z; for each friction run
//! `scenarios/paper_circle_05mms.toml` with those gains on the full machine, and compare the
//! paper's three figures (max position error X 0.61 mm, Y 0.92 mm, max path-speed error
//! 7.38 mm/s). The search minimises the root sum of squares of the three relative misses and
//! reports the worst one, which the issue wants within 10 %. A candidate whose X or Y hunts by
//! stick-slip between reversals (`stick_slip_stalls` > 0) ranks after all that do not: the
//! paper's errors peak only at the start and at reversals. Nothing else is looked at: the
//! other paper experiments are predictions.
//!
//! ```text
//! cargo run --release --example calibrate_xyz_table            # search and report
//! cargo run --release --example calibrate_xyz_table -- --write # also write the best values
//! ```
//! Any grid dimension can be replaced from the command line, e.g. `--mu 0.03,0.05
//! --static-ratio 1,2 --stribeck-mm-s 1 --z-kg 8 --period-ms 4 --amplifier current
//! --design continuous`. `--write` puts the friction (μ, μ_s, v_s) and the amplifier mode into
//! `models/xyz_table.drives.toml`, m_z into `models/xyz_table.urdf` and the servo period and
//! gains into every `scenarios/paper_*.toml`.

use cncsim::machine::{AmplifierMode, Machine};
use cncsim::scenario::{
    keep_mechanics, machine_for, run_scenario_with, tune_scenario_with, PlantKind as TunePlant,
    Scenario, TuneOptions,
};
use cncsim::tune::ZieglerNichols;
use std::path::{Path, PathBuf};

/// The paper's measurements on the 5 mm/s circle: X and Y max position error (mm), max
/// path-speed error (mm/s).
const TARGET: [f64; 3] = [0.61, 0.92, 7.38];
/// Guide friction coefficients. Not zero: the issue's machine has friction from the Z
/// assembly's weight, and a frictionless twin only matches by hunting through its backlash.
const FRICTION: [f64; 4] = [0.01, 0.02, 0.03, 0.05];
/// Static over kinetic friction coefficient (1 = plain Coulomb, no stiction).
const STATIC_RATIO: [f64; 3] = [1.0, 2.0, 3.0];
/// Stribeck velocity (mm/s): how fast the coefficient falls from static to kinetic.
const STRIBECK_MM_S: [f64; 2] = [0.2, 1.0];
const Z_ASSEMBLY_KG: [f64; 3] = [4.0, 8.0, 15.0];
/// Servo period (ms); the physics step stays the scenario's. 20 ms (the other source's) is
/// left out of the default grid: in the sampled design every candidate there had Y ≥ 1.26 mm
/// (`--period-ms 20`).
const SERVO_PERIOD_MS: [f64; 2] = [4.0, 8.0];
/// Setpoint step of the Ziegler–Nichols experiment (the linear loop does not depend on it).
const TUNE_STEP_M: f64 = 0.05e-3;
/// Trial length the tune starts from; it doubles the trials itself when the loop is slower.
const TRIAL_S: f64 = 2.0;

/// The Ziegler–Nichols result of one axis: its TOML line (to print) and the gains (to write).
struct AxisGains {
    axis: &'static str,
    line: String,
    kp: f64,
    ki: f64,
    kd: f64,
}

/// The guide friction of a candidate: kinetic μ, μ_s/μ_k and the Stribeck velocity.
#[derive(Clone, Copy)]
struct Friction {
    mu: f64,
    static_ratio: f64,
    stribeck_mm_s: f64,
}

impl Friction {
    /// μ_s and v_s (m/s) of a guide with stiction; `None` for plain Coulomb (ratio 1).
    fn stiction(&self) -> Option<(f64, f64)> {
        (self.static_ratio > 1.0)
            .then_some((self.mu * self.static_ratio, self.stribeck_mm_s * 1e-3))
    }
}

struct Candidate {
    mode: AmplifierMode,
    period_ms: f64,
    design: Design,
    friction: Friction,
    z_mass: f64,
    figures: [f64; 3],
    /// Largest relative miss of the three figures.
    worst: f64,
    /// Root sum of squares of the relative misses: what the search minimises.
    score: f64,
    /// Stick-slip stalls of X and Y between reversals.
    stalls: [usize; 2],
}

impl Candidate {
    /// Candidates that hunt by stick-slip rank after every one that does not, then by score.
    fn rank(&self) -> (bool, f64) {
        (self.stalls != [0, 0], self.score)
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn with_parameters(
    base: &Machine,
    mode: AmplifierMode,
    friction: Friction,
    z_mass: f64,
) -> Machine {
    let mut m = base.clone();
    for axis in &mut m.axes {
        axis.drive.amplifier_mode = mode;
        if let Some(g) = &mut axis.drive.guide {
            g.friction_coefficient = friction.mu;
            let stiction = friction.stiction();
            g.static_friction_coefficient = stiction.map(|(mu_s, _)| mu_s);
            g.stribeck_velocity_m_s = stiction.map(|(_, v_s)| v_s);
        }
    }
    let z = m
        .link_index("z_column")
        .expect("the table has a z_column link");
    let link = &mut m.links[z];
    // Same box, other mass: the inertia scales with it.
    link.inertia *= z_mass / link.mass;
    link.mass = z_mass;
    m
}

/// The scenario at another servo period (same physics step).
fn at_period(s: &Scenario, period_ms: f64) -> Scenario {
    let mut s = s.clone();
    let physics_step = s.servo_period / s.substeps as f64;
    s.servo_period = period_ms * 1e-3;
    s.substeps = (s.servo_period / physics_step).round() as usize;
    s
}

/// Where the Ziegler–Nichols ultimate cycle is taken.
#[derive(Clone, Copy, PartialEq)]
enum Design {
    /// The sampled loop at the candidate's servo period, found by simulation.
    Sampled,
    /// The continuous-time linear model (T → 0), as the paper designed on its G_p(s): its
    /// printed table is this design (`cncsim tune --linear` prints it beside the sampled one).
    Continuous,
}

impl Design {
    fn name(self) -> &'static str {
        match self {
            Design::Sampled => "sampled",
            Design::Continuous => "continuous",
        }
    }
}

/// Ziegler–Nichols on the linear part of every axis (friction and backlash removed), as
/// `cncsim tune --linear` does.
fn tune(s: &Scenario, machine: &Machine, design: Design) -> Result<Vec<AxisGains>, String> {
    let mut machine = machine.clone();
    keep_mechanics(&mut machine, false, false);
    let mut gains = Vec::new();
    for axis in ["x", "y", "z"] {
        let mut options = TuneOptions::new(axis, TUNE_STEP_M);
        options.trial_time = TRIAL_S;
        let report = tune_scenario_with(
            s,
            machine.clone(),
            &options,
            TunePlant::Physics,
            &mut |_| {},
        )
        .map_err(|e| format!("tune {axis}: {e}"))?;
        // The sampled search runs for both designs: its report also carries the linear
        // model's continuous-time cycle.
        let zn = match design {
            Design::Sampled => report.gains,
            Design::Continuous => {
                let linear = report.linear.as_ref();
                match linear.and_then(|l| l.continuous_gain.zip(l.continuous_period)) {
                    Some((k, p)) => ZieglerNichols::from_ultimate(k, p),
                    None => return Err(format!("tune {axis}: no continuous-time ultimate cycle")),
                }
            }
        };
        gains.push(AxisGains {
            axis,
            line: format!(
                "axes.{axis} = {{ kp = {:.4}, ki = {:.4}, kd = {:.4} }}  ({} design)",
                zn.kp,
                zn.ki,
                zn.kd,
                design.name()
            ),
            kp: zn.kp,
            ki: zn.ki,
            kd: zn.kd,
        });
    }
    Ok(gains)
}

/// What one candidate did on the circle.
struct Figures {
    /// X, Y max position error (mm), max path-speed error (mm/s): the paper's three.
    paper: [f64; 3],
    /// Stick-slip stalls of X and Y (`axes.<x|y>.stick_slip_stalls` in `metrics.json`). The
    /// paper's errors peak only at the start and at reversals (seed digest §2.3); a candidate
    /// that stalls in between is not the paper's machine, however its maxima compare.
    stalls: [usize; 2],
}

/// Runs the circle on `machine` with `gains`.
fn run(s: &Scenario, machine: Machine, gains: &[AxisGains]) -> Result<Figures, String> {
    let mut s = s.clone();
    for g in gains {
        let axis = s
            .gains
            .get_mut(g.axis)
            .expect("paper scenarios have PID gains");
        axis.settings.kp = g.kp;
        axis.settings.ki = g.ki;
        axis.settings.kd = g.kd;
    }
    let out = std::env::temp_dir().join("cncsim_calibration");
    s.record_rrd = false;
    s.record_csv = false;
    s.analytic_steps = None;
    // The scenario's bounds are for `cncsim check`; a candidate is judged by its figures.
    s.expect.clear();
    let run = run_scenario_with(&s, machine, &out, &mut |_, _| true).map_err(|e| e.to_string())?;
    if let Some(stop) = run.stop {
        return Err(format!("run stopped: {stop}"));
    }
    let m = &run.metrics;
    Ok(Figures {
        paper: [
            m.axes["x"].max_following_error_mm.unwrap_or(f64::NAN),
            m.axes["y"].max_following_error_mm.unwrap_or(f64::NAN),
            m.max_path_speed_error_mm_s,
        ],
        stalls: ["x", "y"].map(|a| m.axes[a].stick_slip_stalls),
    })
}

/// `--NAME a,b,c` from the command line, or the default grid.
fn grid_arg<T: std::str::FromStr + Clone>(name: &str, default: &[T]) -> Vec<T> {
    let args: Vec<String> = std::env::args().collect();
    match args.iter().position(|a| a == name) {
        Some(i) => args
            .get(i + 1)
            .unwrap_or_else(|| panic!("{name} needs a comma-separated list"))
            .split(',')
            .map(|v| {
                v.trim()
                    .parse()
                    .unwrap_or_else(|_| panic!("{name}: cannot read {v}"))
            })
            .collect(),
        None => default.to_vec(),
    }
}

/// `--NAME a,b` from the command line, or `default`, each a name in `choices`.
fn grid_choice<T: Copy>(name: &str, default: &[&str], choices: &[(&str, T)]) -> Vec<T> {
    let default: Vec<String> = default.iter().map(|d| d.to_string()).collect();
    grid_arg::<String>(name, &default)
        .iter()
        .map(|v| match choices.iter().find(|(n, _)| n == v) {
            Some(&(_, choice)) => choice,
            None => {
                let names: Vec<&str> = choices.iter().map(|(n, _)| *n).collect();
                panic!("{name}: expected one of {}, found {v}", names.join(", "))
            }
        })
        .collect()
}

fn main() {
    let write = std::env::args().any(|a| a == "--write");
    let modes = grid_choice(
        "--amplifier",
        &["current"],
        &[
            ("voltage", AmplifierMode::Voltage),
            ("current", AmplifierMode::Current),
        ],
    );
    let periods = grid_arg("--period-ms", &SERVO_PERIOD_MS);
    let designs = grid_choice(
        "--design",
        &["sampled", "continuous"],
        &[
            ("sampled", Design::Sampled),
            ("continuous", Design::Continuous),
        ],
    );
    let static_ratios = grid_arg("--static-ratio", &STATIC_RATIO);
    let stribeck = grid_arg("--stribeck-mm-s", &STRIBECK_MM_S);
    let mut frictions = Vec::new();
    for mu in grid_arg("--mu", &FRICTION) {
        for &static_ratio in &static_ratios {
            // Without stiction the Stribeck velocity means nothing: one candidate.
            let speeds = if static_ratio > 1.0 {
                &stribeck[..]
            } else {
                &stribeck[..1]
            };
            for &stribeck_mm_s in speeds {
                frictions.push(Friction {
                    mu,
                    static_ratio,
                    stribeck_mm_s,
                });
            }
        }
    }
    let z_masses = grid_arg("--z-kg", &Z_ASSEMBLY_KG);

    let path = root().join("scenarios/paper_circle_05mms.toml");
    let s = Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let base = machine_for(&s).unwrap_or_else(|e| panic!("{e}"));
    println!(
        "calibrating on {} (targets: X {} mm, Y {} mm, path speed {} mm/s)",
        path.display(),
        TARGET[0],
        TARGET[1],
        TARGET[2]
    );
    println!("amplifier     design  T ms       μ  μs/μ  vs mm/s  m_z kg    X mm     Y mm   v mm/s   worst miss   RSS miss  stalls X/Y");
    let mut best: Option<(Candidate, Vec<AxisGains>)> = None;
    for &mode in &modes {
        for &period_ms in &periods {
            let s = at_period(&s, period_ms);
            for (&design, &z_mass) in designs
                .iter()
                .flat_map(|d| z_masses.iter().map(move |m| (d, m)))
            {
                // The linear loop does not see μ: one tune per (mode, period, design, m_z).
                let linear = Friction {
                    mu: 0.0,
                    static_ratio: 1.0,
                    stribeck_mm_s: 0.0,
                };
                let gains = match tune(&s, &with_parameters(&base, mode, linear, z_mass), design) {
                    Ok(g) => g,
                    Err(e) => {
                        println!(
                            "{:>9} {:>10} {period_ms:5.1} {z_mass:16.1}  tune failed: {e}",
                            mode.name(),
                            design.name()
                        );
                        continue;
                    }
                };
                for &friction in &frictions {
                    let (mu, ratio, vs) =
                        (friction.mu, friction.static_ratio, friction.stribeck_mm_s);
                    let machine = with_parameters(&base, mode, friction, z_mass);
                    let figures = match run(&s, machine, &gains) {
                        Ok(f) => f,
                        Err(e) => {
                            println!(
                                "{:>9} {:>10} {period_ms:5.1} {mu:7.4} {ratio:5.2} {vs:8.3} {z_mass:8.1}  failed: {e}",
                                mode.name(),
                                design.name()
                            );
                            continue;
                        }
                    };
                    let misses: Vec<f64> = figures
                        .paper
                        .iter()
                        .zip(TARGET)
                        .map(|(f, t)| f / t - 1.0)
                        .collect();
                    let worst = misses.iter().fold(0.0, |w: f64, m| w.max(m.abs()));
                    let score = misses.iter().map(|m| m * m).sum::<f64>().sqrt();
                    let c = Candidate {
                        mode,
                        period_ms,
                        design,
                        friction,
                        z_mass,
                        figures: figures.paper,
                        stalls: figures.stalls,
                        worst,
                        score,
                    };
                    println!(
                        "{:>9} {:>10} {:5.1} {mu:7.4} {ratio:5.2} {vs:8.3} {:8.1} {:8.4} {:8.4} {:8.3} {:10.1} % {:8.1} % {:>7}",
                        c.mode.name(),
                        c.design.name(),
                        c.period_ms,
                        c.z_mass,
                        c.figures[0],
                        c.figures[1],
                        c.figures[2],
                        c.worst * 100.0,
                        c.score * 100.0,
                        format!("{}/{}", c.stalls[0], c.stalls[1]),
                    );
                    if best.as_ref().is_none_or(|(b, _)| c.rank() < b.rank()) {
                        let copy = gains
                            .iter()
                            .map(|g| AxisGains {
                                axis: g.axis,
                                line: g.line.clone(),
                                ..*g
                            })
                            .collect();
                        best = Some((c, copy));
                    }
                }
            }
        }
    }
    let Some((best, gains)) = best else {
        eprintln!("no candidate ran");
        std::process::exit(1);
    };
    if best.stalls != [0, 0] {
        println!("every candidate hunts by stick-slip between reversals; the least bad:");
    }
    println!(
        "best: {} amplifiers, {} gain design, servo period {} ms, μ = {}, μ_s/μ_k = {}, v_s = {} mm/s, m_z = {} kg: X {:.4} mm, Y {:.4} mm, path speed {:.3} mm/s (worst miss {:.1} %, RSS {:.1} %)",
        best.mode.name(),
        best.design.name(),
        best.period_ms,
        best.friction.mu,
        best.friction.static_ratio,
        best.friction.stribeck_mm_s,
        best.z_mass,
        best.figures[0],
        best.figures[1],
        best.figures[2],
        best.worst * 100.0,
        best.score * 100.0
    );
    for g in &gains {
        println!("  {}", g.line);
    }
    if write {
        write_back(&best, &gains);
    }
}

/// Sets a TOML value, keeping the comment and spacing around the old one.
fn set(item: &mut toml_edit::Item, value: f64) {
    let decor = item.as_value().map(|v| v.decor().clone());
    *item = toml_edit::value(value);
    if let (Some(decor), Some(v)) = (decor, item.as_value_mut()) {
        *v.decor_mut() = decor;
    }
}

/// Six significant digits, for the URDF's mass and inertia.
fn six_digits(x: f64) -> f64 {
    format!("{x:.5e}")
        .parse()
        .expect("a formatted float parses")
}

/// Four significant digits, as `cncsim tune` prints gains.
fn four_digits(x: f64) -> f64 {
    format!("{x:.3e}")
        .parse()
        .expect("a formatted float parses")
}

/// Edits a TOML file in place, keeping its comments and layout.
fn edit_toml(file: &Path, edit: impl FnOnce(&mut toml_edit::DocumentMut)) {
    let text = std::fs::read_to_string(file).unwrap();
    let mut doc: toml_edit::DocumentMut = text
        .parse()
        .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    edit(&mut doc);
    std::fs::write(file, doc.to_string()).unwrap();
}

fn write_back(best: &Candidate, gains: &[AxisGains]) {
    edit_toml(&root().join("models/xyz_table.drives.toml"), |doc| {
        let axes = doc["axes"].as_table_like_mut().expect("[axes]");
        for (_, drive) in axes.iter_mut() {
            if drive.get("guide").is_some() {
                set(
                    &mut drive["guide"]["friction_coefficient"],
                    best.friction.mu,
                );
                let guide = drive["guide"].as_table_like_mut().expect("guide table");
                if let Some((mu_s, v_s)) = best.friction.stiction() {
                    let mu_s = four_digits(mu_s);
                    guide.insert("static_friction_coefficient", toml_edit::value(mu_s));
                    guide.insert("stribeck_velocity_m_s", toml_edit::value(v_s));
                } else {
                    guide.remove("static_friction_coefficient");
                    guide.remove("stribeck_velocity_m_s");
                }
                // Keys added to an inline table: let it lay itself out again.
                guide.fmt();
            }
            drive["amplifier_mode"] = toml_edit::value(best.mode.name());
        }
    });
    // The z_column's <mass> and <inertia> in the URDF, scaled as `with_parameters` scales
    // them (same box, other mass).
    let urdf = root().join("models/xyz_table.urdf");
    let text = std::fs::read_to_string(&urdf).unwrap();
    let start = text
        .find("<link name=\"z_column\">")
        .expect("z_column link");
    let end = start + text[start..].find("</link>").unwrap();
    let mut link = text[start..end].to_string();
    let attribute = |link: &str, element: &str, name: &str| -> (usize, usize, f64) {
        let at = link.find(element).unwrap();
        let key = format!("{name}=\"");
        let from = at + link[at..].find(&key).unwrap() + key.len();
        let to = from + link[from..].find('"').unwrap();
        (from, to, link[from..to].parse().unwrap())
    };
    let (_, _, old_mass) = attribute(&link, "<mass ", "value");
    let scale = best.z_mass / old_mass;
    // Right to left, so earlier offsets stay valid.
    for (element, name) in [
        ("<inertia ", "izz"),
        ("<inertia ", "iyy"),
        ("<inertia ", "ixx"),
        ("<mass ", "value"),
    ] {
        let (from, to, v) = attribute(&link, element, name);
        link.replace_range(from..to, &format!("{}", six_digits(v * scale)));
    }
    std::fs::write(&urdf, format!("{}{}{}", &text[..start], link, &text[end..])).unwrap();
    for entry in std::fs::read_dir(root().join("scenarios")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if name.starts_with("paper_") && name.ends_with(".toml") {
            edit_toml(&path, |doc| {
                set(&mut doc["timing"]["servo_period_ms"], best.period_ms);
                for g in gains {
                    let axis = &mut doc["controller"]["axes"][g.axis];
                    set(&mut axis["kp"], four_digits(g.kp));
                    set(&mut axis["ki"], four_digits(g.ki));
                    set(&mut axis["kd"], four_digits(g.kd));
                }
            });
        }
    }
    println!(
        "wrote μ, the amplifier mode, m_z, the servo period and the gains into the model and scenarios/paper_*.toml"
    );
}
