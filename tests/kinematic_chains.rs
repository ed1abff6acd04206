//! Figures like with like on every kinematic chain: where rotary axes carry the tool (a
//! head-head B-C machine written for these tests), a joint-mode program's tool path is the
//! forward kinematics of its joint path, checked here against the closed form; the contour
//! error and path speed compare the tool with it; and a run whose figures contradict each
//! other says so.

use cncsim::kinematics::tool_path::{
    programmed_tool_path, rotary_axes_carry_tool, tool_in_program_frame, TOOL_PATH_TOLERANCE,
};
use cncsim::program::PathGeometry;
use cncsim::scenario::{report_setup, Assembly, RunOptions, Scenario};
use nalgebra::{Point3, Rotation3, Vector3};
use std::path::{Path, PathBuf};

fn head_bc() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/machines/head_bc")
}

fn scenario() -> Scenario {
    Scenario::load(&head_bc().join("head_bc_joint.toml")).unwrap()
}

/// The tool tip of the head-head machine in its program frame (origin at the tip with every
/// axis at zero) at joint coordinates X Y Z (m), B, C (rad): the tip hangs 150 mm below the
/// B axis, B tilts it about Y, C turns the head about Z.
fn closed_form(x: f64, y: f64, z: f64, b: f64, c: f64) -> Point3<f64> {
    let pivot = Vector3::new(0.0, 0.0, -0.15);
    let swung = Rotation3::from_axis_angle(&Vector3::z_axis(), c)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), b)
        * pivot;
    Point3::new(x, y, z) + swung - pivot
}

#[test]
fn the_programmed_tool_path_of_a_swivel_head_is_its_forward_kinematics() {
    let assembly = Assembly::new(&scenario()).unwrap();
    let (machine, frame, map) = (&assembly.machine, &assembly.frame, &assembly.axis_map);
    assert!(rotary_axes_carry_tool(machine, frame));
    let program = assembly.program();
    let path = programmed_tool_path(machine, frame, map, program);
    let slides = PathGeometry::of(program);
    let (ib, ic) = (
        machine.axis_index("b").unwrap(),
        machine.axis_index("c").unwrap(),
    );
    let mut at = program.start;
    let mut worst: f64 = 0.0;
    for (m, mv) in program.moves.iter().enumerate() {
        let segment = slides.segments[slides.segment_of_move[m]];
        for k in 0..=200 {
            let s = k as f64 / 200.0;
            let p = segment.point_at(s);
            let rotary = |i: usize| at.rotary[i] + s * (mv.end.rotary[i] - at.rotary[i]);
            let expected = closed_form(p.x, p.y, p.z, rotary(1), rotary(2));
            // The kinematics used by the figures agree with the closed form …
            let mut q = vec![0.0; machine.axes.len()];
            q[machine.axis_index("x").unwrap()] = p.x;
            q[machine.axis_index("y").unwrap()] = p.y;
            q[machine.axis_index("z").unwrap()] = p.z;
            q[ib] = rotary(1);
            q[ic] = rotary(2);
            let fk = tool_in_program_frame(machine, frame, &q);
            assert!(
                (fk - expected).norm() < 1e-12,
                "move {m} at {s}: {fk} vs {expected}"
            );
            // … and the path's straight pieces stay within the tolerance of it.
            let d = path
                .closest_to_move(&expected, m, 0)
                .map(|q| (q - expected).norm())
                .unwrap();
            worst = worst.max(d);
        }
        // Move ends are on the path exactly.
        let end = closed_form(
            mv.end.linear[0],
            mv.end.linear[1],
            mv.end.linear[2],
            mv.end.rotary[1],
            mv.end.rotary[2],
        );
        let last = path.segments[path.segment_of_move[m]];
        let cncsim::program::Segment::Line { end: piece_end, .. } = last else {
            panic!("pieces are lines")
        };
        assert!(
            (piece_end - end).norm() < 1e-12,
            "move {m} ends at {piece_end}, not {end}"
        );
        at = mv.end;
    }
    assert!(
        worst <= TOOL_PATH_TOLERANCE * 1.000_001,
        "the pieces stray {worst} m from the kinematics' curve"
    );
    // Not the program's X Y Z: the head's swing moves the tip tens of millimetres off them.
    let off = (0..=100)
        .map(|k| {
            let p = closed_form(
                0.02,
                0.0,
                0.0,
                30f64.to_radians(),
                (0.9 * k as f64).to_radians(),
            );
            slides
                .closest_to_move(&p, 2, 0)
                .map_or(0.0, |q| (q - p).norm())
        })
        .fold(0.0, f64::max);
    assert!(off > 0.05, "{off}");
}

#[test]
fn on_a_swivel_head_the_figures_are_the_tools_and_agree_with_each_other() {
    let s = scenario();
    let run = Assembly::new(&s)
        .unwrap()
        .run(RunOptions::default().traced())
        .unwrap();
    assert!(run.stop().is_none(), "{:?}", run.stop());
    let m = &run.metrics;
    // Micrometres (the head's swing counted as error would be tens of millimetres): within
    // the rounding of the G64 P0.01 corners and the tool's following error.
    assert!(m.max_contour_error_mm < 0.012, "{}", m.max_contour_error_mm);
    assert!(m.max_commanded_contour_error_mm <= 0.01 + 1e-6);
    assert!(
        m.inconsistent_figures.is_none(),
        "{:?}",
        m.inconsistent_figures
    );
    // The commanded path speed is the commanded tool point's: the tip sweeps while X Y Z
    // stand still, and the actual speed follows it.
    assert!(
        m.max_path_speed_error_mm_s < 1.0,
        "{}",
        m.max_path_speed_error_mm_s
    );
}

#[test]
fn setpoints_far_from_the_programmed_path_show_when_the_path_is_not_the_tools() {
    // The signal the run's consistency check reads: with the programmed X Y Z taken for the
    // tool's path (what a figure that ignores the head would do), the commanded tool point
    // leaves it by far more than the G64 P0.01 corners allow; with the kinematics' path it
    // stays within them.
    let assembly = Assembly::new(&scenario()).unwrap();
    let setup = report_setup(&assembly);
    let mut wrong = setup.path.clone();
    wrong.geometry = PathGeometry::of(assembly.program());
    let mut stream = assembly.setpoints();
    let mut sample = cncsim::plan::SetpointSample::zeros(stream.axes());
    let (mut right_worst, mut wrong_worst): (f64, f64) = (0.0, 0.0);
    while stream.next_sample(&mut sample) {
        let tool = tool_in_program_frame(&assembly.machine, &assembly.frame, &sample.position);
        let carrier_point = assembly.frame.carrier_point(&tool);
        for (tracker, worst) in [(&setup.path, &mut right_worst), (&wrong, &mut wrong_worst)] {
            let p = tracker.sample(carrier_point.into(), [0.0; 3], &sample, &sample.position);
            assert_eq!(p.tool_following_error, 0.0);
            // G64 P0.01 without Q: Q = P (LinuxCNC), so joined lines may add another 10 µm.
            assert_eq!(p.corner_tolerance, Some(2e-5));
            *worst = worst.max(p.commanded_deviation);
        }
    }
    assert!(right_worst <= 1e-5 + 1e-9, "{right_worst}");
    assert!(wrong_worst > 0.05, "{wrong_worst}");
}

#[test]
fn a_tool_swinging_on_a_joint_no_axis_drives_is_reported_as_inconsistent() {
    // B left free (passive) and never programmed: the head swings as X accelerates, the tool
    // with it, and no following error explains the contour error.
    let dir = tempfile::tempdir().unwrap();
    for file in ["head_bc.urdf", "swivel.ngc"] {
        std::fs::copy(head_bc().join(file), dir.path().join(file)).unwrap();
    }
    let drives = std::fs::read_to_string(head_bc().join("head_bc.drives.toml")).unwrap();
    let b_table = drives.find("[axes.b]").unwrap();
    let b_end = drives[b_table..]
        .find("\n\n")
        .map_or(drives.len(), |e| b_table + e);
    let drives = format!(
        "{}{}\n[joints.b]\nmode = \"passive\"\n",
        &drives[..b_table],
        &drives[b_end..]
    );
    std::fs::write(dir.path().join("head_bc.drives.toml"), drives).unwrap();
    std::fs::write(
        dir.path().join("swivel.ngc"),
        "G21 G90 G94 G61\nG0 X0 Y0 Z0 C0\nG1 F3000 X60\nG1 Y40 C90\nG1 X0 Y0 C0\nM2\n",
    )
    .unwrap();
    let text = std::fs::read_to_string(head_bc().join("head_bc_joint.toml"))
        .unwrap()
        .replace("limits.b = { velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }\n", "")
        // Computed torque needs every moving joint driven or locked: PID instead (pole
        // placement at 20 Hz on each axis's moved inertia with the reflected rotor).
        .replace(
            "type = \"inverse-dynamics\"\nnatural_frequency_hz = 20.0\ndamping_ratio = 1.0\n",
            "type = \"pid\"\naxes.x = { kp = 3420.0, ki = 8.6e4, kd = 43.5, output_limit = 7.0 }\naxes.y = { kp = 1911.0, ki = 4.8e4, kd = 24.3, output_limit = 7.0 }\naxes.z = { kp = 905.0, ki = 2.27e4, kd = 11.5, output_limit = 7.0 }\naxes.c = { kp = 123.0, ki = 3075.0, kd = 1.56, output_limit = 5.0 }\n",
        );
    assert!(text.contains("type = \"pid\""));
    let path = dir.path().join("head_bc_joint.toml");
    std::fs::write(&path, &text).unwrap();
    let s = Scenario::parse(&path, &text).unwrap();
    let run = Assembly::new(&s)
        .unwrap()
        .run(RunOptions::write_to(dir.path().join("out")))
        .unwrap();
    let found = run
        .metrics
        .inconsistent_figures
        .as_ref()
        .expect("the swinging head is reported");
    assert!(found.measured_mm > 2.0 * found.explained_mm, "{found:?}");
    assert!(found.likely_cause.contains("a joint the axes do not drive"));
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("out/metrics.json")).unwrap(),
    )
    .unwrap();
    assert!(json["inconsistent_figures"]["likely_cause"].is_string());
    assert!(
        run.warnings
            .iter()
            .any(|w| w.to_string().contains("cannot all be true")),
        "{:?}",
        run.warnings
    );
}

#[test]
fn a_tool_tip_circle_on_a_swivel_head_stays_on_the_circle_with_the_spindle_leaning() {
    // kinematics = "tcp": X Y Z are the tip on the part, B and C the head's angles. The tip
    // must stay on the programmed 30 mm circle (z = 0) while C turns the 15° lean round with
    // it, checked through the closed form above (not cncsim's kinematics).
    let s = Scenario::load(&head_bc().join("head_bc_tcp.toml")).unwrap();
    let assembly = Assembly::new(&s).unwrap();
    let run = assembly.run(RunOptions::default().traced()).unwrap();
    assert!(run.stop().is_none(), "{:?}", run.stop());
    let m = &run.metrics;
    assert!(
        m.inconsistent_figures.is_none(),
        "{:?}",
        m.inconsistent_figures
    );
    let t = run.trace.as_ref().unwrap();
    let machine = &assembly.machine;
    let index = |name: &str| machine.axis_index(name).unwrap();
    let (ix, iy, iz, ib, ic) = (index("x"), index("y"), index("z"), index("b"), index("c"));
    let tip_and_lean = |q: &[f64]| {
        let tip = closed_form(q[ix], q[iy], q[iz], q[ib], q[ic]);
        let axis = Rotation3::from_axis_angle(&Vector3::z_axis(), q[ic])
            * Rotation3::from_axis_angle(&Vector3::y_axis(), q[ib])
            * Vector3::z();
        (tip, axis)
    };
    let (mut worst_off, mut worst_lean, mut worst_toward): (f64, f64, f64) = (0.0, 0.0, 0.0);
    let mut azimuths = Vec::new();
    for k in 0..t.len() {
        let row = |v: &[f64]| v[k * t.axes..(k + 1) * t.axes].to_vec();
        let (commanded, _) = tip_and_lean(&row(&t.commanded));
        let lean_commanded = tip_and_lean(&row(&t.commanded)).1.z.acos().to_degrees();
        // On the circle: the commanded tip 15 mm from the centre at z = 0, leaning 15°.
        let on_circle = (commanded.x.hypot(commanded.y) - 0.015).abs() < 2e-6
            && commanded.z.abs() < 2e-6
            && (lean_commanded - 15.0).abs() < 1e-3;
        if !on_circle {
            continue;
        }
        let (tip, axis) = tip_and_lean(&row(&t.actual));
        let off = (tip.x.hypot(tip.y) - 0.015).hypot(tip.z);
        worst_off = worst_off.max(off);
        worst_lean = worst_lean.max((axis.z.acos().to_degrees() - 15.0).abs());
        // The spindle leans towards the centre: its tilt is along −(tip direction).
        let inward = -Vector3::new(tip.x, tip.y, 0.0).normalize();
        let across = Vector3::new(axis.x, axis.y, 0.0).normalize();
        worst_toward = worst_toward.max(inward.angle(&across).to_degrees());
        azimuths.push(tip.y.atan2(tip.x).to_degrees());
    }
    // The whole circle was run leaning.
    let covered = (0..36)
        .filter(|&d| {
            let lo = -180.0 + 10.0 * d as f64;
            azimuths.iter().any(|&a| a >= lo && a < lo + 10.0)
        })
        .count();
    assert_eq!(covered, 36, "{} samples on the circle", azimuths.len());
    // The tip stays on the programmed circle within the reported contour error (the
    // joint-space pieces are within the 1 µm tolerance of it), …
    assert!(
        worst_off <= m.max_contour_error_mm * 1e-3 + 1e-6,
        "tip {:.3} µm off the circle, contour error {:.3} µm",
        worst_off * 1e6,
        m.max_contour_error_mm * 1e3
    );
    assert!(m.max_contour_error_mm < 0.005, "{}", m.max_contour_error_mm);
    // … and the spindle leans as programmed: 15° towards the centre, to the head's
    // following error (millidegrees).
    assert!(worst_lean < 0.01, "lean off by {worst_lean}°");
    assert!(worst_toward < 0.01, "lean direction off by {worst_toward}°");
    eprintln!(
        "tcp circle: tip ≤ {:.3} µm off the circle, lean ≤ {:.4}° off, direction ≤ {:.4}°; contour error {:.3} µm",
        worst_off * 1e6,
        worst_lean,
        worst_toward,
        m.max_contour_error_mm * 1e3
    );
}
