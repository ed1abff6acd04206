//! Parse time of a generated 1-million-line G-code program (lines, arcs, comments, modes).
//!     cargo bench --bench gcode_parse

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

fn bench(c: &mut Criterion) {
    let program = generate_program(1_000_000);
    let options = ReadOptions::default();
    // Sanity: the generated program parses.
    let parsed = parse_gcode(&program, "bench.ngc", &options).expect("generated program parses");
    assert!(parsed.moves.len() > 990_000);
    let mut group = c.benchmark_group("gcode");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20))
        .throughput(Throughput::Bytes(program.len() as u64));
    group.bench_function("parse_1M_lines_in_memory", |b| {
        b.iter(|| {
            parse_gcode(&program, "bench.ngc", &options)
                .unwrap()
                .moves
                .len()
        })
    });
    // From a file on disk, streamed line by line as read_program does.
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("bench.ngc");
    std::fs::write(&path, &program).unwrap();
    group.bench_function("parse_1M_lines_from_file", |b| {
        b.iter(|| {
            let file = std::io::BufReader::new(std::fs::File::open(&path).unwrap());
            parse_gcode_reader(file, &path, &options)
                .unwrap()
                .moves
                .len()
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
