//! Parse time of generated 1-million-line G-code programs: a plain CAM-style one (lines, arcs,
//! comments, modes) and one with parameters, expressions and O-word loops.
//!     cargo bench --bench program_parse

use std::time::Duration;

use cncsim::program::{parse_gcode, parse_gcode_reader, ReadOptions};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

/// A program of `lines` lines in the style of a CAM post: mostly G1 moves with feeds,
/// some arcs, comments and mode changes.
fn generate_program(lines: usize) -> Vec<u8> {
    let mut text = String::with_capacity(lines * 32);
    text.push_str(
        "%\n(generated benchmark program)\nG21 G90 G17 G94 G64 P0.01\nS12000 M3\nG0 X0 Y0 Z5\n",
    );
    let mut line = 5;
    let mut step = 0u64;
    while line < lines - 2 {
        let x = (step % 1000) as f64 * 0.1;
        let y = ((step / 1000) % 1000) as f64 * 0.1;
        match step % 20 {
            0 => text.push_str(&format!(
                "N{step} G1 X{x:.4} Y{y:.4} Z-1.0000 F1200 (pass {step})\n"
            )),
            // Half circle of radius 0.1 from the previous point (0.1 back) to 0.1 ahead.
            7 => text.push_str(&format!("G2 X{:.4} Y{y:.4} I0.1000 J0\n", x + 0.1)),
            13 => text.push_str(&format!(
                "G1 X{x:.4} Y{y:.4} A{:.3} ; with rotary\n",
                (step % 360) as f64
            )),
            _ => text.push_str(&format!("G1 X{x:.4} Y{y:.4}\n")),
        }
        step += 1;
        line += 1;
    }
    text.push_str("M5\nM2\n");
    text.into_bytes()
}

/// A program of `lines` lines that computes its coordinates with parameters and expressions
/// and, every tenth group, runs a three-line body four times in an O-word loop.
fn generate_parametric_program(lines: usize) -> Vec<u8> {
    let mut text = String::with_capacity(lines * 40);
    text.push_str("G21 G90 G17 G94 G64 P0.01\nS12000 M3\nG0 X0 Y0 Z5\n#<pitch> = 0.1\n#<depth> = -1\nG1 Z#<depth> F1200\n");
    let mut line = 6;
    let mut step = 0u64;
    while line < lines - 6 {
        if step % 10 == 9 {
            text.push_str(&format!(
                "o{step} repeat [4]\n  #1 = [#1 + #<pitch>]\n  G1 X[#1 MOD 100] Y[#2 + #<pitch> * 2]\n  G1 Z[#<depth> - 0.5]\no{step} endrepeat\n"
            ));
            line += 5;
        } else {
            text.push_str(&format!(
                "#1 = [{} * #<pitch>] #2 = [{} * #<pitch>]\nG1 X#1 Y[#2 + SIN[#1 * 3.6]]\n",
                step % 1000,
                (step / 1000) % 1000
            ));
            line += 2;
        }
        step += 1;
    }
    text.push_str("M2\n");
    text.into_bytes()
}

fn bench(c: &mut Criterion) {
    let options = ReadOptions::default();
    let programs = [
        ("plain", generate_program(1_000_000)),
        (
            "parameters_and_loops",
            generate_parametric_program(1_000_000),
        ),
    ];
    let mut group = c.benchmark_group("gcode");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    for (name, program) in &programs {
        // Sanity: the generated program parses.
        let parsed = parse_gcode(program, "bench.ngc", &options).expect("generated program parses");
        assert!(parsed.moves.len() > 700_000);
        group.throughput(Throughput::Bytes(program.len() as u64));
        group.bench_function(format!("parse_1M_lines_{name}_in_memory"), |b| {
            b.iter(|| {
                parse_gcode(program, "bench.ngc", &options)
                    .unwrap()
                    .moves
                    .len()
            })
        });
        // From a file on disk, streamed line by line as read_program does.
        let directory = tempfile::tempdir().unwrap();
        let path = directory.path().join("bench.ngc");
        std::fs::write(&path, program).unwrap();
        group.bench_function(format!("parse_1M_lines_{name}_from_file"), |b| {
            b.iter(|| {
                let file = std::io::BufReader::new(std::fs::File::open(&path).unwrap());
                parse_gcode_reader(file, &path, &options)
                    .unwrap()
                    .moves
                    .len()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
