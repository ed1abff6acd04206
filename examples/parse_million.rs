//! Writes a 1-million-line G-code program to a temporary file, reads it with
//! `read_program` (streamed) and prints the time and the peak resident memory.
//!     cargo run --release --example parse_million
use std::io::Write;
use std::time::Instant;

use cncsim::program::{read_program, ReadOptions};

fn main() {
    let directory = tempfile::tempdir().expect("temporary directory");
    let path = directory.path().join("million.ngc");
    let mut file = std::io::BufWriter::new(std::fs::File::create(&path).expect("create"));
    writeln!(
        file,
        "G21 G90 G17 G94 G64 P0.01\nS12000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F1200"
    )
    .unwrap();
    let lines = 1_000_000u64;
    for step in 4..lines - 1 {
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
    drop(file);
    let size = std::fs::metadata(&path).unwrap().len();
    let rss_before = peak_rss_kib();
    let started = Instant::now();
    let program = read_program(&path, &ReadOptions::default()).expect("parses");
    let elapsed = started.elapsed();
    println!(
        "{lines} lines, {:.1} MB: {} moves in {:.3} s; peak RSS {} MiB (before reading {} MiB); Move is {} bytes",
        size as f64 / 1e6,
        program.moves.len(),
        elapsed.as_secs_f64(),
        peak_rss_kib() / 1024,
        rss_before / 1024,
        std::mem::size_of::<cncsim::program::Move>()
    );
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
