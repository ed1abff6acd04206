//! Writes two 1-million-line G-code programs to temporary files, reads each with
//! `read_program` (streamed) and prints the time, the moves kept and the peak resident memory:
//! a plain CAM-style program, and one that computes its coordinates with parameters and
//! expressions and repeats blocks in O-word loops.
//!     cargo run --release --example parse_million
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use cncsim::program::{read_program, ReadOptions};

const LINES: u64 = 1_000_000;

/// Mostly G1 moves with line numbers, arcs, a rotary axis and comments.
fn write_plain(path: &Path) {
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).expect("create"));
    writeln!(
        file,
        "G21 G90 G17 G94 G64 P0.01\nS12000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F1200"
    )
    .unwrap();
    for step in 4..LINES - 1 {
        let x = (step % 1000) as f64 * 0.1;
        let y = ((step / 1000) % 1000) as f64 * 0.1;
        match step % 20 {
            7 => writeln!(file, "G2 X{:.4} Y{y:.4} I0.1000 J0", x + 0.1).unwrap(),
            13 => writeln!(
                file,
                "G1 X{x:.4} Y{y:.4} A{:.3} (rotary)",
                (step % 360) as f64
            )
            .unwrap(),
            _ => writeln!(file, "N{step} G1 X{x:.4} Y{y:.4}").unwrap(),
        }
    }
    writeln!(file, "M2").unwrap();
}

/// The same kind of path with its coordinates in parameters and expressions, and every
/// tenth group of lines an O-word loop that runs its three-line body four times.
fn write_parametric(path: &Path) {
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).expect("create"));
    writeln!(
        file,
        "G21 G90 G17 G94 G64 P0.01\nS12000 M3\nG0 X0 Y0 Z5\n#<pitch> = 0.1\n#<depth> = -1\nG1 Z#<depth> F1200"
    )
    .unwrap();
    let mut line = 6;
    let mut step = 0u64;
    while line < LINES - 6 {
        if step % 10 == 9 {
            writeln!(
                file,
                "o{step} repeat [4]\n  #1 = [#1 + #<pitch>]\n  G1 X[#1 MOD 100] Y[#2 + #<pitch> * 2]\n  G1 Z[#<depth> - 0.5]\no{step} endrepeat"
            )
            .unwrap();
            line += 5;
        } else {
            writeln!(
                file,
                "#1 = [{} * #<pitch>] #2 = [{} * #<pitch>]\nG1 X#1 Y[#2 + SIN[#1 * 3.6]]",
                step % 1000,
                (step / 1000) % 1000
            )
            .unwrap();
            line += 2;
        }
        step += 1;
    }
    writeln!(file, "M2").unwrap();
}

fn main() {
    let directory = tempfile::tempdir().expect("temporary directory");
    for (name, write) in [
        ("plain", write_plain as fn(&Path)),
        ("parameters and O-word loops", write_parametric),
    ] {
        let path = directory.path().join("million.ngc");
        write(&path);
        let size = std::fs::metadata(&path).unwrap().len();
        let lines = std::io::BufRead::split(
            std::io::BufReader::new(std::fs::File::open(&path).unwrap()),
            b'\n',
        )
        .count();
        let rss_before = peak_rss_kib();
        let started = Instant::now();
        let program = read_program(&path, &ReadOptions::default()).expect("parses");
        let elapsed = started.elapsed();
        println!(
            "{name}: {lines} lines, {:.1} MB: {} moves in {:.3} s; peak RSS {} MiB (before reading {} MiB); Move is {} bytes",
            size as f64 / 1e6,
            program.moves.len(),
            elapsed.as_secs_f64(),
            peak_rss_kib() / 1024,
            rss_before / 1024,
            std::mem::size_of::<cncsim::program::Move>()
        );
        drop(program);
    }
}

/// VmHWM from /proc (Linux); 0 elsewhere.
fn peak_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            status
                .lines()
                .find(|line| line.starts_with("VmHWM:"))
                .and_then(|line| line.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}
