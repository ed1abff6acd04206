//! Planning memory is bounded by the look-ahead, not the program: the most heap the planner's
//! stream holds beyond the decoded program (every allocation counted by this binary's global
//! allocator, so live heap, not resident memory) is the same for a program four times as long,
//! whether it is one chain planned window by window or many chains. (One test: the counters are
//! shared by the whole binary.)

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use cncsim::kinematics::AxisMap;
use cncsim::machine::Machine;
use cncsim::plan::{plan_program_stream, SetpointSample};
use cncsim::program::{parse_gcode, ReadOptions};

/// The system allocator, counting the bytes live and their peak.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn allocated(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Relaxed) + bytes;
    PEAK.fetch_max(live, Relaxed);
}

// SAFETY: every call is passed on to the system allocator unchanged; only counters are kept.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            allocated(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            allocated(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        unsafe { System.dealloc(p, layout) };
        LIVE.fetch_sub(layout.size(), Relaxed);
    }

    unsafe fn realloc(&self, p: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, layout, size) };
        if !q.is_null() {
            LIVE.fetch_sub(layout.size(), Relaxed);
            allocated(size);
        }
        q
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Heap held by the decoded program of `lines` raster lines (1 mm on a curve, rows of 1000,
/// G64 P0.05 with every line planned), and the most the planner's stream holds beyond it while
/// every sample is read. `stops`: each row ends in an exact stop (many chains); else the whole
/// program is one chain.
fn planning_peak(lines: usize, stops: bool) -> (usize, usize) {
    let body = common::raster_gcode(lines);
    let body = if stops {
        // G61 on the step to each next row, G64 again on its first line.
        body.lines()
            .enumerate()
            .map(|(k, line)| match k % 1000 {
                0 => format!("G61 {line}\n"),
                1 => format!("G64 P0.05 {line}\n"),
                _ => format!("{line}\n"),
            })
            .collect()
    } else {
        body
    };
    let text = format!("G21 G90 G17 G64 P0.05\nG0 X0 Y0 Z1\nF6000\n{body}M2\n");
    drop(body);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine = Machine::load(&root.join("models/xyz_table.urdf")).unwrap();
    let axes = AxisMap::new(&machine).unwrap();
    let settings = common::raster_settings(&machine);
    let before = LIVE.load(Relaxed);
    let program = parse_gcode(&text, "raster.ngc", &ReadOptions::default()).unwrap();
    drop(text);
    let base = LIVE.load(Relaxed);
    PEAK.store(base, Relaxed);
    let samples = {
        let mut stream = plan_program_stream(&program, &axes, &settings).unwrap();
        let mut sample = SetpointSample::zeros(stream.axes());
        let mut read = 0usize;
        while stream.next_sample(&mut sample) {
            read += 1;
        }
        assert_eq!(read, stream.len());
        read
    };
    let peak = PEAK.load(Relaxed) - base;
    println!(
        "{lines} lines, {}: program {:.1} MiB, planning {:.2} MiB more at most ({samples} samples)",
        if stops {
            "a stop every row"
        } else {
            "one chain"
        },
        (base - before) as f64 / 1048576.0,
        peak as f64 / 1048576.0
    );
    (base - before, peak)
}

#[test]
fn planning_memory_does_not_grow_with_the_program() {
    for stops in [false, true] {
        let (short_program, short) = planning_peak(20_000, stops);
        let (long_program, long) = planning_peak(80_000, stops);
        assert!(long_program > 3 * short_program);
        // The same look-ahead, and the same first windows kept for the evaluation: less than
        // 2 bytes more per line (anything kept per segment takes more). Measured: 63 kB more in
        // one chain (where the windows fall; 160 000 lines need no more than 80 000), none with
        // the stops.
        assert!(
            long.saturating_sub(short) < 2 * 60_000,
            "{long} bytes for 80 000 lines, {short} for 20 000"
        );
    }
}
