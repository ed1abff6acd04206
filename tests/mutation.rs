//! Mutation tests of the three description files a user writes: scenarios, URDF machines and
//! their drive sidecars. Each case takes a bundled file, mutates it (delete, duplicate, swap or
//! truncate lines; replace a number by an extreme, NaN or a wrong type; nest deeply; blow a
//! value up) and runs it in-process through every stage that reads it: parse, load the
//! machine, plan, build the physics model and run a short stretch of the servo loop. Whatever
//! the input, the outcome must be a run or an error that names the file (and the line where
//! there is one) — never a panic, a hang or unbounded work. Every case has a time budget.
//!
//! `cargo test --test mutation` tries `MUTATION_CASES` cases per kind (default 1500);
//! `cargo test --release --test mutation -- --ignored` tries `MUTATION_LONG_CASES` (default
//! 100 000) per kind. Failing inputs are written to `target/mutation-failures/`.

use cncsim::machine::Machine;
use cncsim::scenario::{Assembly, Scenario};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Duration;

/// Longest a case may take (parse, plan, build and a short run, in the test profile).
const BUDGET: Duration = Duration::from_secs(20);
/// Servo ticks of the short run, and the settle time it keeps at most.
const RUN_TICKS: usize = 40;
const RUN_SETTLE_S: f64 = 0.02;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn cases(variable: &str, default: u32) -> u32 {
    std::env::var(variable)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Which file of a run is mutated.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Scenario,
    Urdf,
    Drives,
}

/// A text edit; indices are taken modulo what the text has, so one strategy fits every file.
#[derive(Debug, Clone)]
enum Mutation {
    DeleteLine(usize),
    DuplicateLine { line: usize, times: usize },
    SwapLines(usize, usize),
    Truncate(usize),
    ReplaceNumber { which: usize, with: &'static str },
    DeleteChar(usize),
    InsertChar { at: usize, c: char },
    Nest { line: usize, depth: usize },
    HugeValue { which: usize, bytes: usize },
}

/// Numbers and wrong types a user (or a broken tool) might write where a number was.
const EXTREMES: &[&str] = &[
    "0",
    "-0.0",
    "-1",
    "1",
    "2",
    "1e300",
    "-1e300",
    "1e-300",
    "-1e-300",
    "nan",
    "inf",
    "-inf",
    "1e20",
    "-1e20",
    "1e-9",
    "99999999999999999999",
    "4294967296",
    "-9223372036854775809",
    "0.5",
    "1e6",
    "\"text\"",
    "true",
    "[]",
    "{}",
    "\"\"",
    "1e",
    "--1",
    "0x10",
];

fn mutation() -> impl Strategy<Value = Mutation> {
    let index = 0usize..100_000;
    prop_oneof![
        index.clone().prop_map(Mutation::DeleteLine),
        (index.clone(), 1usize..2000)
            .prop_map(|(line, times)| Mutation::DuplicateLine { line, times }),
        (index.clone(), index.clone()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
        index.clone().prop_map(Mutation::Truncate),
        (index.clone(), prop::sample::select(EXTREMES))
            .prop_map(|(which, with)| Mutation::ReplaceNumber { which, with }),
        (index.clone(), prop::sample::select(EXTREMES))
            .prop_map(|(which, with)| Mutation::ReplaceNumber { which, with }),
        index.clone().prop_map(Mutation::DeleteChar),
        (
            index.clone(),
            prop::sample::select(vec![
                '"', '[', ']', '{', '}', '=', '<', '>', '/', '\n', '#', ',', '.', 'é', '\0'
            ])
        )
            .prop_map(|(at, c)| Mutation::InsertChar { at, c }),
        (
            index.clone(),
            prop::sample::select(vec![2usize, 100, 1_000, 50_000, 300_000])
        )
            .prop_map(|(line, depth)| Mutation::Nest { line, depth }),
        (index, prop::sample::select(vec![1_000usize, 1_000_000]))
            .prop_map(|(which, bytes)| Mutation::HugeValue { which, bytes }),
    ]
}

/// Byte ranges of the number-like tokens of `text`.
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts =
            b[i].is_ascii_digit() || (b[i] == b'-' && b.get(i + 1).is_some_and(u8::is_ascii_digit));
        let inside_word = i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_');
        if starts && !inside_word {
            let start = i;
            i += 1;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b"._+-".contains(&b[i])) {
                i += 1;
            }
            out.push((start, i));
        } else {
            i += 1;
        }
    }
    out
}

fn floor_boundary(text: &str, mut i: usize) -> usize {
    i = i.min(text.len());
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

fn apply(text: &str, m: &Mutation, kind: Kind) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let n = lines.len().max(1);
    let joined = |lines: Vec<String>| lines.join("\n") + "\n";
    match *m {
        Mutation::DeleteLine(l) => {
            if !lines.is_empty() {
                lines.remove(l % n);
            }
            joined(lines)
        }
        Mutation::DuplicateLine { line, times } => {
            if let Some(copy) = lines.get(line % n).cloned() {
                for _ in 0..times {
                    lines.insert(line % n, copy.clone());
                }
            }
            joined(lines)
        }
        Mutation::SwapLines(a, b) => {
            if !lines.is_empty() {
                lines.swap(a % n, b % n);
            }
            joined(lines)
        }
        Mutation::Truncate(at) => text[..floor_boundary(text, at % (text.len() + 1))].to_string(),
        Mutation::ReplaceNumber { which, with } => {
            let tokens = numbers(text);
            if tokens.is_empty() {
                return text.to_string();
            }
            let (a, b) = tokens[which % tokens.len()];
            format!("{}{with}{}", &text[..a], &text[b..])
        }
        Mutation::DeleteChar(at) => {
            let at = floor_boundary(text, at % (text.len() + 1));
            let mut s = text.to_string();
            if at < s.len() {
                s.remove(at);
            }
            s
        }
        Mutation::InsertChar { at, c } => {
            let mut s = text.to_string();
            s.insert(floor_boundary(text, at % (text.len() + 1)), c);
            s
        }
        Mutation::Nest { line, depth } => {
            let at = line % n;
            let nested = match kind {
                Kind::Urdf => format!("{}{}", "<n>".repeat(depth), "</n>".repeat(depth)),
                _ => format!("nest = {}1{}", "[".repeat(depth), "]".repeat(depth)),
            };
            lines.insert(at, nested);
            joined(lines)
        }
        Mutation::HugeValue { which, bytes } => {
            let tokens = numbers(text);
            if tokens.is_empty() {
                return text.to_string();
            }
            let (a, b) = tokens[which % tokens.len()];
            format!("{}{}{}", &text[..a], "9".repeat(bytes), &text[b..])
        }
    }
}

/// The bundled files a kind's cases start from: (scenario, its machine's URDF path).
fn sources(kind: Kind) -> Vec<PathBuf> {
    let r = root();
    match kind {
        Kind::Scenario => [
            "xyz_circle_5mms",
            "paper_circle_05mms",
            "paper_corner_90",
            "mill_table2_fast",
            "mill_table2_id",
            "xyz_square_arc_gcode",
            "plan_table2_jerk",
            "plan_table1_cl",
        ]
        .iter()
        .map(|n| r.join(format!("scenarios/{n}.toml")))
        .collect(),
        // A run of each machine: the paper circle (friction, backlash, stiction) and the mill.
        Kind::Urdf | Kind::Drives => ["paper_circle_05mms", "mill_table2_fast"]
            .iter()
            .map(|n| r.join(format!("scenarios/{n}.toml")))
            .collect(),
    }
}

/// The paths an error may name: the scenario, its machine files, and its program.
fn known_paths(scenario: &Path, machine: &Path) -> Vec<String> {
    let mut paths = vec![
        scenario.display().to_string(),
        machine.display().to_string(),
        machine.with_extension("drives.toml").display().to_string(),
    ];
    if let Ok(s) = Scenario::load(scenario) {
        if let cncsim::scenario::ProgramSource::File { path, .. } = &s.program.source {
            paths.push(path.display().to_string());
        }
    }
    paths
}

/// How far the cases got: refused by the scenario reader, by the machine reader, by planning
/// or model building, or run; printed at the end so that a generator that only makes
/// unreadable files shows.
static REACHED: [AtomicUsize; 4] = [const { AtomicUsize::new(0) }; 4];

fn reached(stage: usize) {
    REACHED[stage].fetch_add(1, Ordering::Relaxed);
}

/// Runs one case through every stage; `Err` describes what went wrong (a panic, an error
/// without its file).
/// Keeps the first `keep` samples of a setpoint list.
fn truncate(setpoints: &mut cncsim::plan::Setpoints, keep: usize) {
    let keep = setpoints.len().min(keep);
    let n = setpoints.axes;
    setpoints.position.truncate(keep * n);
    setpoints.velocity.truncate(keep * n);
    setpoints.acceleration.truncate(keep * n);
    setpoints.segment.truncate(keep);
}

fn run_case(kind: Kind, scenario_path: &Path, mutated: &str) -> Result<(), String> {
    let original = Scenario::load(scenario_path).map_err(|e| format!("bundled scenario: {e}"))?;
    let machine_path = original.machine.clone();
    let paths = known_paths(scenario_path, &machine_path);
    let urdf = std::fs::read_to_string(&machine_path).unwrap();
    let drives = std::fs::read_to_string(machine_path.with_extension("drives.toml")).unwrap();
    let (scenario_text, urdf, drives) = match kind {
        Kind::Scenario => (mutated.to_string(), urdf, drives),
        Kind::Urdf => (
            std::fs::read_to_string(scenario_path).unwrap(),
            mutated.to_string(),
            drives,
        ),
        Kind::Drives => (
            std::fs::read_to_string(scenario_path).unwrap(),
            urdf,
            mutated.to_string(),
        ),
    };
    let check_error = |e: &dyn std::fmt::Display| -> Result<(), String> {
        let message = e.to_string();
        if paths.iter().any(|p| message.starts_with(p.as_str())) {
            Ok(())
        } else {
            Err(format!("error without its file: {message}"))
        }
    };
    let mut scenario = match Scenario::parse(scenario_path, &scenario_text) {
        Ok(s) => s,
        Err(e) => {
            reached(0);
            return check_error(&e);
        }
    };
    // A mutated scenario may name another machine file: load it the way `run` would.
    let machine = if kind == Kind::Scenario {
        Machine::load(&scenario.machine)
    } else {
        Machine::parse(&machine_path, &urdf, &drives)
    };
    let machine = match machine {
        Ok(m) => m,
        Err(e) => {
            reached(1);
            return check_error(&e);
        }
    };
    if scenario.actuator.is_none() {
        // A planning scenario: plan it.
        return match cncsim::scenario::plan_scenario(&scenario, None) {
            Ok(_) => {
                reached(3);
                Ok(())
            }
            Err(e) => {
                reached(2);
                check_error(&e)
            }
        };
    }
    scenario.timing.settle_time = scenario.timing.settle_time.min(RUN_SETTLE_S);
    let (assembly, mut lanes) = match Assembly::with_machine(&scenario, machine)
        .and_then(|a| a.lanes().map(|lanes| (a, lanes)))
    {
        Ok(wired) => wired,
        Err(e) => {
            reached(2);
            return check_error(&e);
        }
    };
    let mut setpoints = cncsim::plan::FirstSamples::new(assembly.setpoints(), RUN_TICKS);
    let keep = cncsim::plan::SetpointStream::len(&setpoints);
    let n = assembly.labels.len();
    // The untraced approach to the program's start is cut short alike.
    let mut loop_settings = assembly.loop_settings.clone();
    truncate(&mut loop_settings.approach, RUN_TICKS);
    let mut recorder =
        cncsim::sim::TraceRecorder::new(scenario.timing.servo_period, n, lanes.len());
    let outcome = cncsim::sim::run(
        &loop_settings,
        &mut lanes,
        &mut setpoints,
        &mut recorder,
        &mut |_, _| true,
    );
    if outcome.ticks > keep {
        return Err(format!("ran {} ticks of {keep}", outcome.ticks));
    }
    reached(3);
    Ok(())
}

/// Runs `run_case` on a worker thread within the budget, catching panics.
fn guarded(kind: Kind, scenario: PathBuf, mutated: String) -> Result<(), String> {
    let (tx, rx) = mpsc::channel();
    let text = mutated.clone();
    std::thread::Builder::new()
        .stack_size(8 << 20)
        .spawn(move || {
            let result = std::panic::catch_unwind(|| run_case(kind, &scenario, &text));
            let _ = tx.send(result.unwrap_or_else(|p| {
                let what = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                Err(format!("panicked: {what}"))
            }));
        })
        .unwrap();
    match rx.recv_timeout(BUDGET) {
        Ok(result) => result,
        Err(_) => Err(format!("took longer than {BUDGET:?}")),
    }
}

fn save_failure(kind: Kind, mutated: &str) -> PathBuf {
    let dir = root().join("target/mutation-failures");
    std::fs::create_dir_all(&dir).unwrap();
    let extension = match kind {
        Kind::Scenario => "toml",
        Kind::Urdf => "urdf",
        Kind::Drives => "drives.toml",
    };
    let path = dir.join(format!("{kind:?}-{:016x}.{extension}", fxhash(mutated)));
    std::fs::write(&path, mutated).unwrap();
    path
}

fn fxhash(s: &str) -> u64 {
    s.bytes().fold(0xcbf29ce484222325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100000001b3)
    })
}

fn mutate_and_run(kind: Kind, cases: u32, seed: u8) {
    let sources = sources(kind);
    let config = Config {
        cases,
        failure_persistence: None,
        max_shrink_iters: 200,
        ..Config::default()
    };
    let mut runner = TestRunner::new_with_rng(
        config,
        TestRng::from_seed(RngAlgorithm::ChaCha, &[seed; 32]),
    );
    let strategy = (0..sources.len(), mutation());
    let result = runner.run(&strategy, |(source, m)| {
        let scenario = &sources[source];
        let original = match kind {
            Kind::Scenario => std::fs::read_to_string(scenario).unwrap(),
            Kind::Urdf | Kind::Drives => {
                let machine = Scenario::load(scenario).unwrap().machine;
                let file = if kind == Kind::Urdf {
                    machine
                } else {
                    machine.with_extension("drives.toml")
                };
                std::fs::read_to_string(file).unwrap()
            }
        };
        let mutated = apply(&original, &m, kind);
        guarded(kind, scenario.clone(), mutated.clone()).map_err(|why| {
            let saved = save_failure(kind, &mutated);
            TestCaseError::fail(format!(
                "{kind:?} from {} with {m:?}: {why} (input saved as {})",
                scenario.display(),
                saved.display()
            ))
        })
    });
    let counts: Vec<usize> = REACHED
        .iter()
        .map(|c| c.swap(0, Ordering::Relaxed))
        .collect();
    eprintln!(
        "{kind:?}: {cases} cases (tallies may mix with tests running beside): refused reading the scenario {}, the machine {}, planning/building {}; ran {}",
        counts[0], counts[1], counts[2], counts[3]
    );
    if let Err(e) = result {
        panic!("{e}");
    }
}

#[test]
fn mutated_scenarios_never_crash() {
    mutate_and_run(Kind::Scenario, cases("MUTATION_CASES", 1500), 1);
}

#[test]
fn mutated_urdf_machines_never_crash() {
    mutate_and_run(Kind::Urdf, cases("MUTATION_CASES", 1500), 2);
}

#[test]
fn mutated_drive_files_never_crash() {
    mutate_and_run(Kind::Drives, cases("MUTATION_CASES", 1500), 3);
}

#[test]
#[ignore = "long: MUTATION_LONG_CASES per kind"]
fn mutated_inputs_long() {
    let n = cases("MUTATION_LONG_CASES", 100_000);
    for (kind, seed) in [(Kind::Scenario, 11), (Kind::Urdf, 12), (Kind::Drives, 13)] {
        mutate_and_run(kind, n, seed);
    }
}

#[test]
fn the_mutations_do_what_they_say() {
    let text = "a = 1.5\nb = [2, -3]\n";
    assert_eq!(numbers(text).len(), 3);
    assert_eq!(
        apply(
            text,
            &Mutation::ReplaceNumber {
                which: 1,
                with: "nan"
            },
            Kind::Scenario
        ),
        "a = 1.5\nb = [nan, -3]\n"
    );
    assert_eq!(
        apply(text, &Mutation::DeleteLine(0), Kind::Scenario),
        "b = [2, -3]\n"
    );
    assert_eq!(apply(text, &Mutation::Truncate(3), Kind::Scenario), "a =");
    assert!(
        apply(text, &Mutation::Nest { line: 0, depth: 3 }, Kind::Urdf)
            .starts_with("<n><n><n></n></n></n>\n")
    );
}
