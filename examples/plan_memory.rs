//! Peak resident memory and time of planning a long program with the jerk-limited planner as
//! a stream (`plan_program_stream`, then every sample read): a raster of 1 mm lines on a
//! smooth curve (CAM finishing output), G64 P0.05, a row every `ROW` lines.
//!     cargo run --release --example plan_memory -- 1000000 [stop|blend|dwell]
//! `stop` (default): each row ends in an exact stop (G61 on the step to the next row), so the
//! program is many chains; `blend`: the step is blended too, the whole program one chain;
//! `dwell`: each row ends in a dwell of 10 ms, so the program is many motions.
//! Prints the memory after reading the program and at the end (`ru_maxrss`).
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use cncsim::kinematics::AxisMap;
use cncsim::machine::Machine;
use cncsim::plan::{
    plan_program_stream, AxisKind, AxisLimits, BlendChoice, PlanSettings, Planner, SetpointSample,
};
use cncsim::program::{read_program, ReadOptions};

/// Lines per raster row.
const ROW: usize = 1000;

fn peak_rss_mib() -> f64 {
    // SAFETY: getrusage only writes the struct it is given.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) };
    usage.ru_maxrss as f64 / 1024.0
}

/// How each row of the raster ends.
#[derive(Clone, Copy, PartialEq)]
enum RowEnd {
    Stop,
    Blend,
    Dwell,
}

fn write_program(path: &Path, blocks: usize, row_end: RowEnd) {
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).expect("create"));
    writeln!(file, "G21 G90 G17 G64 P0.05\nG0 X0 Y0 Z1\nF6000").unwrap();
    for k in 0..blocks {
        let (row, step) = (k / ROW, k % ROW);
        let x = if row % 2 == 0 { step } else { ROW - 1 - step } as f64;
        let z = 2.0 * (x * 0.02).sin() + (x * 0.0031).cos();
        let mode = match (step, row_end) {
            (0, RowEnd::Stop) => "G61 ",
            (1, RowEnd::Stop) => "G64 P0.05 ",
            (0, RowEnd::Dwell) if k > 0 => "G4 P0.01\n",
            _ => "",
        };
        writeln!(file, "{mode}G1 X{x:.3} Y{:.3} Z{z:.4}", row as f64 * 0.5).unwrap();
    }
    writeln!(file, "M2").unwrap();
}

fn main() {
    let blocks: usize = std::env::args()
        .nth(1)
        .map_or(1_000_000, |s| s.parse().expect("a number of blocks"));
    let row_end = match std::env::args().nth(2).as_deref() {
        None | Some("stop") => RowEnd::Stop,
        Some("blend") => RowEnd::Blend,
        Some("dwell") => RowEnd::Dwell,
        Some(other) => panic!("expected stop, blend or dwell, not {other}"),
    };
    let file = std::env::temp_dir().join(format!("cncsim_plan_memory_{}.ngc", std::process::id()));
    write_program(&file, blocks, row_end);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine = Machine::load(&root.join("models/xyz_table.urdf")).expect("machine");
    let axes = AxisMap::new(&machine).expect("axes");
    let program = read_program(&file, &ReadOptions::default()).expect("program");
    let _ = std::fs::remove_file(&file);
    println!(
        "{} moves read, peak resident {:.1} MiB",
        program.moves.len(),
        peak_rss_mib()
    );
    let limits = vec![
        AxisLimits::from_program_units(AxisKind::Linear, 200.0, 2000.0, 5e4);
        machine.axes.len()
    ];
    let settings = PlanSettings {
        planner: Planner::JerkLimited { limits },
        period: 1e-3,
        rapid_speed: 0.05,
        blend: BlendChoice::Program,
        axis_names: machine.axes.iter().map(|a| a.name.clone()).collect(),
        // Every line planned as written (G64 P alone would join lines within P, as LinuxCNC's
        // naive-CAM detector does, and leave far fewer segments to plan).
        naive_cam_tolerance: Some(0.0),
        tool_lever_arms: Vec::new(),
    };
    let start = Instant::now();
    let mut stream = plan_program_stream(&program, &axes, &settings).expect("plan");
    let planned = start.elapsed().as_secs_f64();
    let after_planning = peak_rss_mib();
    let len = stream.len();
    let mut sample = SetpointSample::zeros(stream.axes());
    let mut read = 0usize;
    while stream.next_sample(&mut sample) {
        read += 1;
    }
    let total = start.elapsed().as_secs_f64();
    println!(
        "{len} samples ({read} read); planned in {planned:.2} s, all read after {total:.2} s; \
         peak resident {after_planning:.1} MiB after planning, {:.1} MiB at the end",
        peak_rss_mib()
    );
}
