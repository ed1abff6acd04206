//! A machine written by someone else: frames turned as CAD exporters turn them, a moving bed,
//! a `<mimic>` rail, undriven clamp joints, massless links, xacro. Its figures must be those of
//! the tool on the part (ISO 841 program axes), never an artefact of the URDF's frames.

mod common;

use cncsim::kinematics::{AxisMap, ProgramFrame};
use cncsim::machine::Machine;
use cncsim::scenario::{report_setup, Assembly, RunOptions, Scenario};
use cncsim::sim::Trace;
use nalgebra::{Matrix3, Point3, Vector3};
use std::path::{Path, PathBuf};

/// The bundled gantry's files: `models/` for the machine, `scenarios/` for its circle.
fn fixture(name: &str) -> PathBuf {
    let folder = if name.ends_with(".toml") && !name.contains("drives") {
        "scenarios"
    } else {
        "models"
    };
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(folder)
        .join(name)
}

fn gantry_text() -> (String, String) {
    (
        std::fs::read_to_string(fixture("cad_gantry.urdf")).unwrap(),
        std::fs::read_to_string(fixture("cad_gantry.drives.toml")).unwrap(),
    )
}

/// The gantry with its drive file edited by `edit` (applied to the text).
fn gantry_with(edit: impl Fn(String) -> String) -> Result<Machine, cncsim::diagnostics::FileError> {
    let (urdf, drives) = gantry_text();
    Machine::parse(&fixture("cad_gantry.urdf"), &urdf, &edit(drives))
}

#[test]
fn program_axes_are_where_each_axis_moves_the_tool_on_the_part() {
    let machine = Machine::load(&fixture("cad_gantry.urdf")).unwrap();
    let (frame, warnings) = ProgramFrame::new(&machine).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(machine.links[frame.carrier].name, "workpiece");
    // The workpiece frame is the bed's, turned -90° about world x: world +x is its +x, world
    // +y its +z, world +z its -y. X moves the tool along world +x; the bed's joint moves the
    // part along world +y, so the tool along world -y, and sign = -1 makes that program -Y;
    // Z moves the tool up.
    let expected = Matrix3::from_columns(&[
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.0, -1.0, 0.0),
    ]);
    assert!(
        (frame.directions - expected).norm() < 1e-12,
        "{}",
        frame.directions
    );
    assert!(frame.directions.determinant() > 0.0);
    // Program zero is the tool over the part with every joint at zero: a program point maps
    // back onto the part where the joints put the tool.
    let map = AxisMap::new(&machine).unwrap();
    let p = cncsim::program::Position {
        linear: [0.012, -0.034, 0.005],
        rotary: [0.0; 3],
    };
    let mut q = vec![0.0; 3];
    map.machine_axes(&p, &mut q);
    let [x, y, z] = ["x", "y", "z"].map(|l| machine.axis_index(l).unwrap());
    assert_eq!(
        [q[x], q[y], q[z]],
        [0.012, 0.034, 0.005],
        "Y runs backwards (sign = -1)"
    );
    let on_part = cncsim::kinematics::tool_in_link(&machine, frame.carrier, &q);
    let back = frame.program_point(&on_part);
    assert!((back - Point3::from(p.linear)).norm() < 1e-12, "{back}");
}

#[test]
fn a_left_handed_set_of_axes_loads_with_a_warning_naming_the_axis_to_flip() {
    let machine = gantry_with(|d| d.replace("sign = -1\n", "")).unwrap();
    let (frame, warnings) = ProgramFrame::new(&machine).unwrap();
    assert!(frame.directions.determinant() < 0.0);
    let text: Vec<String> = warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(text.len(), 1, "{text:?}");
    assert!(
        text[0].contains("left-handed: parts come out mirrored"),
        "{}",
        text[0]
    );
    assert!(text[0].contains("`sign = -1` in [axes.y]"), "{}", text[0]);
}

#[test]
fn work_offset_home_and_sign_place_program_zero_as_g54_does() {
    // Y homed 10 mm along its joint; program zero at machine (5, 20, -3) mm. A G-code program
    // goes to program zero, then to machine Z 0 with G53, then home with G28.
    let dir = gantry_folder(
        |u| u,
        |d| {
            d.replace(
                "peak_torque_nm = 7.0\nsign = -1",
                "peak_torque_nm = 7.0\nsign = -1\nhome = 0.010",
            )
        },
    );
    std::fs::write(
        dir.path().join("g54.ngc"),
        "G21 G90\nG0 X0 Y0 Z0\nG1 X4 F600\nG53 G0 Z0\nG28\nM2\n",
    )
    .unwrap();
    let path = dir.path().join("cad_gantry_circle.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text
        .replace(
            "circle = { center_mm = [10.0, -5.0], radius_mm = 20.0, start_angle_deg = 0.0, direction = \"ccw\", z_mm = 0.0 }\nfeed_mm_s = 20.0",
            "file = \"g54.ngc\"\nwork_offset_mm = [5.0, 20.0, -3.0]",
        )
        .replace("profile = \"constant-velocity\"", "profile = \"constant-velocity\"\nrapid_mm_s = 50.0");
    let scenario = Scenario::parse(&path, &text).unwrap();
    let assembly = Assembly::new(&scenario).unwrap();
    let machine = &assembly.machine;
    let [x, y, z] = ["x", "y", "z"].map(|l| machine.axis_index(l).unwrap());
    let setpoints = assembly.plan.collect();
    // The end of each move: joint = home + sign·machine coordinate.
    let at_move_end = |index: u32| {
        let k = (0..setpoints.len())
            .rev()
            .find(|&k| setpoints.segment[k] == index)
            .unwrap();
        setpoints.position(k).to_vec()
    };
    let joints = |q: Vec<f64>| [q[x], q[y], q[z]];
    let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-12);
    // G0 X0 Y0 Z0: program zero, machine (5, 20, -3) mm.
    let zero = joints(at_move_end(0));
    assert!(close(zero, [0.005, 0.010 - 0.020, -0.003]), "{zero:?}");
    // G53 G0 Z0: machine Z 0 whatever the offset.
    let g53 = joints(at_move_end(2));
    assert!(close(g53, [0.009, 0.010 - 0.020, 0.0]), "{g53:?}");
    // G28: machine zero (its stored position), where every joint is at its home.
    let g28 = joints(at_move_end(setpoints.segment[setpoints.len() - 1]));
    assert!(close(g28, [0.0, 0.010, 0.0]), "{g28:?}");
    // In the program frame the tool at program zero is at the offset.
    let (frame, _) = ProgramFrame::new(machine).unwrap();
    let mut q = vec![0.0; 3];
    q[x] = zero[0];
    q[y] = zero[1];
    q[z] = zero[2];
    let on_part = cncsim::kinematics::tool_in_link(machine, frame.carrier, &q);
    let p = frame.program_point(&on_part);
    assert!(
        (p - Point3::new(0.005, 0.020, -0.003)).norm() < 1e-12,
        "{p}"
    );
}

#[test]
fn axes_not_at_right_angles_are_refused_naming_both_joints() {
    let (urdf, drives) = gantry_text();
    // The carriage's axis tilted by 5° towards the gantry's travel.
    let tilted = urdf.replace(
        "<axis xyz=\"-1 0 0\"/>",
        "<axis xyz=\"-0.9961947 0 0.0871557\"/>",
    );
    let machine = Machine::parse(&fixture("cad_gantry.urdf"), &tilted, &drives).unwrap();
    let e = ProgramFrame::new(&machine).unwrap_err().to_string();
    assert!(e.contains("cad_gantry.urdf:"), "{e}");
    assert!(
        e.contains("joint 'rail_left'") && e.contains("joint 'carriage_joint'"),
        "{e}"
    );
    assert!(e.contains("85.000° apart"), "{e}");
}

#[test]
fn undriven_joints_are_locked_with_one_warning_and_mimic_followers_ride_along() {
    let machine =
        gantry_with(|d| d.replace("[joints.clamp_joint]\nmode = \"locked\"\n", "")).unwrap();
    let warnings: Vec<String> = machine.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("1 moving joint no axis drives is locked")
            && warnings[0].contains("'clamp_joint' (line"),
        "{}",
        warnings[0]
    );
    // Named in the drive file: no warning.
    let named = Machine::load(&fixture("cad_gantry.urdf")).unwrap();
    assert!(named.warnings.is_empty(), "{:?}", named.warnings);
    // The clamp's jaw (a mimic of the locked lever) and the right rail (a mimic of X) are
    // fixed joints now; three axes remain, the mass of the right rail rides on X; the Z
    // counterweight keeps its joint (coupled to Z).
    let moving: Vec<&str> = named
        .joints
        .iter()
        .filter(|j| j.kind != cncsim::machine::JointKind::Fixed)
        .map(|j| j.name.as_str())
        .collect();
    assert_eq!(
        moving,
        [
            "bed_joint",
            "rail_left",
            "carriage_joint",
            "counterweight_joint"
        ]
    );
    let rail = named
        .joints
        .iter()
        .find(|j| j.name == "rail_right")
        .unwrap();
    assert_eq!(named.links[rail.parent].name, "gantry_left");
    // Riding on the left rail, the right one stays 0.5 m from it wherever X goes.
    for x in [-0.1, 0.0, 0.07] {
        let poses = cncsim::kinematics::link_poses(&named, &[0.0, x, 0.0]);
        let l = named.link_index("gantry_left").unwrap();
        let r = named.link_index("gantry_right").unwrap();
        let apart = poses[r].translation.vector - poses[l].translation.vector;
        assert!(
            (apart - Vector3::new(0.0, 0.5, 0.0)).norm() < 1e-12,
            "{apart}"
        );
    }
}

/// The gantry with its Z counterweight (a `<mimic>` of Z on a joint of its own, as a chain over
/// a pulley couples it) made `mass` kg and moving `multiplier` times as far as Z, from 10 mm.
fn with_counterweight(mass: f64, multiplier: f64) -> impl Fn(String) -> String {
    move |urdf: String| {
        let edited = urdf
            .replace(
                "<mass value=\"2\"/><inertia ixx=\"2e-3\"",
                &format!("<mass value=\"{mass}\"/><inertia ixx=\"2e-3\""),
            )
            .replace(
                "<mimic joint=\"carriage_joint\" multiplier=\"-1\" offset=\"0\"/>",
                &format!(
                    "<mimic joint=\"carriage_joint\" multiplier=\"{multiplier}\" offset=\"0.01\"/>"
                ),
            );
        assert_eq!(
            edited.matches("0.01\"/>").count(),
            1,
            "the counterweight was edited"
        );
        edited
    }
}

/// The bundled gantry with its counterweight made `mass` kg at `multiplier`.
fn counterweighted_gantry(mass: f64, multiplier: f64) -> Machine {
    let (urdf, drives) = gantry_text();
    Machine::parse(
        &fixture("cad_gantry.urdf"),
        &with_counterweight(mass, multiplier)(urdf),
        &drives,
    )
    .unwrap()
}

#[test]
fn a_mimic_follower_on_its_own_joint_is_coupled_exactly_as_an_atwood_machine() {
    use cncsim::machine::Undriven;
    use cncsim::model::{Plant, PlantOptions};
    // The carriage (2 kg) and a 3 kg counterweight moving half as fast the other way: with no
    // drive force and no armature the pair falls as an Atwood machine does,
    // a = -g·(m_z + μ·m_w)/(m_z + μ²·m_w) along Z (μ = -0.5: -g·0.5/2.75).
    let (m_z, m_w, mu) = (2.0, 3.0, -0.5);
    let machine = counterweighted_gantry(m_w, mu);
    let coupled = machine
        .undriven
        .iter()
        .find(|(name, _)| name == "counterweight_joint")
        .map(|(_, what)| what.clone());
    assert_eq!(
        coupled,
        Some(Undriven::Coupled {
            leader: "carriage_joint".into(),
            multiplier: mu,
            offset: 0.01
        })
    );
    let g = 9.81;
    let step = 2.5e-4;
    let mut plant = Plant::new(
        &machine,
        &PlantOptions {
            step,
            gravity: [0.0, 0.0, -g],
            initial_positions: vec![0.0; 3],
            include_drive_dynamics: false,
            solver_iterations: 1,
        },
    )
    .unwrap();
    plant.set_joint_forces(&[0.0; 3]);
    let start = plant.link_poses();
    let steps = 400;
    for _ in 0..steps {
        plant.step();
    }
    let z = machine.axis_index("z").unwrap();
    let (mut q, mut v) = (vec![0.0; 3], vec![0.0; 3]);
    plant.positions(&mut q);
    plant.velocities(&mut v);
    let t = steps as f64 * step;
    let a = -g * (m_z + mu * m_w) / (m_z + mu * mu * m_w);
    assert!(
        (v[z] - a * t).abs() < 1e-9 * g,
        "Z speed {} m/s after {t} s, the Atwood machine's {} m/s",
        v[z],
        a * t
    );
    // The counterweight is where its mimic puts it, in the physics and in the kinematics.
    let w = machine.link_index("counterweight").unwrap();
    let physics = plant.link_poses()[w].translation.vector;
    let kinematics = cncsim::kinematics::link_poses(&machine, &q)[w]
        .translation
        .vector;
    assert!(
        (physics - kinematics).norm() < 1e-9,
        "{physics} against {kinematics}"
    );
    // Measured in the world: the counterweight rose by μ times the carriage's fall.
    let carriage = machine.link_index("carriage").unwrap();
    let rise = |l: usize| plant.link_poses()[l].translation.z - start[l].translation.z;
    assert!(
        (rise(w) - mu * rise(carriage)).abs() < 1e-12,
        "counterweight {} m, carriage {} m",
        rise(w),
        rise(carriage)
    );
    assert!(
        rise(carriage) < -1e-3,
        "the carriage falls: {}",
        rise(carriage)
    );
}

#[test]
fn the_counterweight_carries_the_z_carriage_in_the_physics_and_the_reference_model() {
    // The bundled gantry's counterweight is as heavy as the carriage: Z holds its height on
    // the circle with no torque, in both models; without it, the carriage's weight through the
    // screw, m·g·lead/2π.
    let run = |urdf_edit: &dyn Fn(String) -> String| {
        let dir = gantry_folder(urdf_edit, |d| d);
        let scenario = Scenario::load(&dir.path().join("cad_gantry_circle.toml")).unwrap();
        let run = Assembly::new(&scenario)
            .unwrap()
            .run(RunOptions::write_to(dir.path().join("out")))
            .unwrap();
        assert!(run.stop().is_none(), "{:?}", run.stop());
        assert!(run.verdict.passed(), "{:?}", run.verdict.breaches);
        let z = &run.metrics_json["axes"]["z"];
        (
            z["peak_torque_nm"].as_f64().unwrap(),
            z["max_physics_vs_analytic_mm"].as_f64().unwrap(),
        )
    };
    let (balanced, balanced_vs) = run(&|u| u);
    assert!(balanced.abs() < 1e-12, "Z torque {balanced} N·m");
    assert!(
        balanced_vs < 1e-9,
        "Z physics against the reference model {balanced_vs} mm"
    );
    let without = |u: String| {
        let start = u.find("  <!-- The Z counterweight").unwrap();
        let end = u.find("  <link name=\"tool_tip\"/>").unwrap();
        format!("{}{}", &u[..start], &u[end..])
    };
    let (held, held_vs) = run(&without);
    let weight = 2.0 * 9.81 * 0.005 / (2.0 * std::f64::consts::PI);
    assert!(
        (held.abs() - weight).abs() < 1e-3 * weight,
        "Z torque {held} N·m, the carriage's weight {weight} N·m"
    );
    assert!(
        held_vs < 1e-6,
        "Z physics against the reference model {held_vs} mm"
    );

    // A follower of an axis whose drive train is split (backlash) is refused by name.
    let (urdf, drives) = gantry_text();
    let machine = Machine::parse(
        &fixture("cad_gantry.urdf"),
        &urdf,
        &drives.replace("[axes.z]\n", "[axes.z]\nbacklash = 2e-5\n"),
    )
    .unwrap();
    assert_eq!(
        machine.follower_of_split_drive(),
        Some(("counterweight_joint".into(), "z".into()))
    );
}

#[test]
fn a_mirrored_rail_and_a_chain_of_mimics_ride_on_their_leader() {
    // The right rail's axis turned round with multiplier -1 is the same rigid motion; a jaw
    // following the rail through another mimic composes down to the left rail.
    let (urdf, drives) = gantry_text();
    let turned = urdf.replace(
        "<axis xyz=\"0 0 1\"/>\n    <limit lower=\"-0.15\" upper=\"0.15\" effort=\"500\" velocity=\"0.5\"/>\n    <mimic joint=\"rail_left\" multiplier=\"1\" offset=\"0\"/>",
        "<axis xyz=\"0 0 -1\"/>\n    <limit lower=\"-0.15\" upper=\"0.15\" effort=\"500\" velocity=\"0.5\"/>\n    <mimic joint=\"rail_left\" multiplier=\"-1\" offset=\"0\"/>",
    );
    assert_ne!(turned, urdf);
    let machine = Machine::parse(&fixture("cad_gantry.urdf"), &turned, &drives).unwrap();
    assert!(machine.undriven.contains(&(
        "rail_right".into(),
        cncsim::machine::Undriven::RidesOn {
            leader: "rail_left".into()
        }
    )));
    let l = machine.link_index("gantry_left").unwrap();
    let r = machine.link_index("gantry_right").unwrap();
    for x in [-0.1, 0.07] {
        let poses = cncsim::kinematics::link_poses(&machine, &[0.0, x, 0.0]);
        let apart = poses[r].translation.vector - poses[l].translation.vector;
        assert!(
            (apart - Vector3::new(0.0, 0.5, 0.0)).norm() < 1e-12,
            "{apart}"
        );
    }
    // A chain: a pin following the jaw, which follows the lever, composes down to the lever
    // (q_pin = 2·(−q_lever) + 0.1): held where the locked lever puts it, coupled to a free one.
    let jaw = "<mimic joint=\"clamp_joint\" multiplier=\"-1\" offset=\"0\"/>\n  </joint>";
    let chained = urdf.replace(
        jaw,
        &format!("{jaw}\n  <link name=\"clamp_pin\"><inertial><mass value=\"0.05\"/><inertia ixx=\"1e-6\" ixy=\"0\" ixz=\"0\" iyy=\"1e-6\" iyz=\"0\" izz=\"1e-6\"/></inertial></link>\n  <joint name=\"clamp_pin_joint\" type=\"prismatic\">\n    <parent link=\"bed\"/><child link=\"clamp_pin\"/><axis xyz=\"1 0 0\"/>\n    <limit lower=\"-0.2\" upper=\"0.2\" effort=\"1\" velocity=\"1\"/>\n    <mimic joint=\"clamp_jaw_joint\" multiplier=\"2\" offset=\"0.1\"/>\n  </joint>"),
    );
    assert_ne!(chained, urdf);
    let pin = |drives: &str| {
        let machine = Machine::parse(&fixture("cad_gantry.urdf"), &chained, drives).unwrap();
        let (_, what) = machine
            .undriven
            .into_iter()
            .find(|(name, _)| name == "clamp_pin_joint")
            .unwrap();
        what
    };
    assert_eq!(
        pin(&drives),
        cncsim::machine::Undriven::HeldByMimic {
            leader: "clamp_joint".into(),
            position: 0.1
        }
    );
    assert_eq!(
        pin(&drives.replace("mode = \"locked\"", "mode = \"passive\"")),
        cncsim::machine::Undriven::Coupled {
            leader: "clamp_joint".into(),
            multiplier: -2.0,
            offset: 0.1
        }
    );
    // A loop of mimics is refused naming the joint.
    let looped = urdf.replace(
        "<axis xyz=\"0 1 0\"/>\n    <limit lower=\"-0.5\" upper=\"0.5\" effort=\"10\" velocity=\"1\"/>\n  </joint>",
        "<axis xyz=\"0 1 0\"/>\n    <limit lower=\"-0.5\" upper=\"0.5\" effort=\"10\" velocity=\"1\"/>\n    <mimic joint=\"clamp_jaw_joint\" multiplier=\"1\" offset=\"0\"/>\n  </joint>",
    );
    assert_ne!(looped, urdf);
    let e = Machine::parse(
        &fixture("cad_gantry.urdf"),
        &looped,
        &drives.replace("[joints.clamp_joint]\nmode = \"locked\"\n", ""),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("comes back to itself"), "{e}");
}

#[test]
fn every_massless_moving_link_is_listed_in_one_error_and_geometry_can_fill_them() {
    let (urdf, drives) = gantry_text();
    let massless = urdf
        .replace(
            "<inertial><mass value=\"2\"/><inertia ixx=\"0.005\" ixy=\"0\" ixz=\"0\" iyy=\"0.005\" iyz=\"0\" izz=\"0.005\"/></inertial>",
            "",
        )
        .replace(
            "<inertial><origin xyz=\"0 0.25 0\"/><mass value=\"8\"/>\n      <inertia ixx=\"0.2\" ixy=\"0\" ixz=\"0\" iyy=\"0.02\" iyz=\"0\" izz=\"0.2\"/></inertial>",
            "",
        );
    assert_ne!(massless, urdf);
    let e = Machine::parse(&fixture("cad_gantry.urdf"), &massless, &drives)
        .unwrap_err()
        .to_string();
    // The carriage has nothing with mass beyond it: refused, at its line. The gantry's rails
    // lost their mass too, but carry mass beyond them (the Z slide, the counterweight): in
    // reduced coordinates a massless frame with mass beyond is fine.
    assert!(e.contains("1 moving link has no mass"), "{e}");
    assert!(
        e.contains("'carriage' (line") && !e.contains("'gantry_left'"),
        "{e}"
    );
    assert!(e.contains("inertia_from_geometry"), "{e}");
    // With a density, they come from their geometry: the carriage a 60 mm cube of steel and
    // its tool, a cylinder of 6 mm radius and 170 mm. Every link without mass that moves and
    // has geometry gets its mass so, as MuJoCo's inertiafromgeom does: the right rail from its
    // upright, the workpiece link (on the moving bed) from its block of stock.
    let with_density = format!("inertia_from_geometry = {{ density_kg_m3 = 7850.0 }}\n{drives}");
    let m = Machine::parse(&fixture("cad_gantry.urdf"), &massless, &with_density).unwrap();
    let carriage = &m.links[m.link_index("carriage").unwrap()];
    let mass = 7850.0 * (0.06f64.powi(3) + std::f64::consts::PI * 0.006f64.powi(2) * 0.17);
    assert!(
        (carriage.mass - mass).abs() < 1e-9 * mass,
        "{}",
        carriage.mass
    );
    assert_eq!(
        m.masses_from_geometry,
        ["workpiece", "gantry_left", "gantry_right", "carriage"]
    );
}

#[test]
fn xacro_written_as_urdf_is_refused_with_what_to_do() {
    // A `.urdf` holding xacro: cncsim reads a `.urdf` as URDF, so it says to name it
    // `.urdf.xacro` (which it expands) or to expand it.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mill.urdf");
    std::fs::write(
        &path,
        "<?xml version=\"1.0\"?>\n<robot name=\"mill\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n  <xacro:property name=\"t\" value=\"0.02\"/>\n  <link name=\"base\"><visual><origin xyz=\"0 0 ${-t/2}\"/></visual></link>\n</robot>\n",
    )
    .unwrap();
    let e = cncsim::machine::load_urdf(&path).unwrap_err().to_string();
    // At the `${…}` the property is used in (a `<xacro:property>` alone changes nothing).
    assert!(e.contains("mill.urdf:4:46"), "{e}");
    assert!(e.contains("xacro file"), "{e}");
    assert!(e.contains("name it mill.urdf.xacro"), "{e}");
    assert!(e.contains("`xacro mill.urdf > mill_expanded.urdf`"), "{e}");
    assert!(e.contains("pip install xacro"), "{e}");
}

/// The contour error (distance of the tool from the programmed path, on the part) can never
/// exceed the distance of the tool from its setpoint, which lies on the path: the following
/// error vector, in program axes. On a machine whose URDF frames are turned and whose bed
/// moves, a figure computed in the wrong frame breaks this by the travel.
fn contour_within_following_error(
    trace: &Trace,
    setup: &cncsim::report::ReportSetup,
    axes: &[usize; 3],
) -> f64 {
    let n = trace.axes;
    let mut worst: f64 = 0.0;
    for k in 0..trace.len() {
        let mut setpoint = cncsim::plan::SetpointSample::zeros(n);
        setpoint
            .position
            .copy_from_slice(&trace.commanded[k * n..(k + 1) * n]);
        setpoint
            .velocity
            .copy_from_slice(&trace.commanded_velocity[k * n..(k + 1) * n]);
        setpoint.segment = trace.segment[k];
        let sample = setup.path.sample(
            trace.tool_point[k],
            trace.tool_velocity[k],
            &setpoint,
            &trace.actual[k * n..(k + 1) * n],
        );
        let following: f64 = axes
            .iter()
            .map(|&i| {
                (Trace::at(&trace.commanded, n, k, i) - Trace::at(&trace.actual, n, k, i)).powi(2)
            })
            .sum::<f64>()
            .sqrt();
        assert!(
            sample.contour_error <= following + 1e-9,
            "tick {k}: contour error {} m against a following error of {following} m",
            sample.contour_error
        );
        worst = worst.max(sample.contour_error);
    }
    worst
}

/// The gantry's circle with its files edited, in a folder of its own.
fn gantry_folder(
    urdf_edit: impl Fn(String) -> String,
    drives_edit: impl Fn(String) -> String,
) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let scenario = std::fs::read_to_string(fixture("cad_gantry_circle.toml")).unwrap();
    std::fs::write(
        dir.path().join("cad_gantry_circle.toml"),
        scenario.replace("../models/cad_gantry.urdf", "cad_gantry.urdf"),
    )
    .unwrap();
    let (urdf, drives) = gantry_text();
    std::fs::write(dir.path().join("cad_gantry.urdf"), urdf_edit(urdf)).unwrap();
    std::fs::write(
        dir.path().join("cad_gantry.drives.toml"),
        drives_edit(drives),
    )
    .unwrap();
    dir
}

fn run_gantry(
    scenario_edit: impl Fn(String) -> String,
    drives_edit: impl Fn(String) -> String,
) -> (f64, f64, Vec<String>) {
    run_gantry_with(|u| u, scenario_edit, drives_edit)
}

fn run_gantry_with(
    urdf_edit: impl Fn(String) -> String,
    scenario_edit: impl Fn(String) -> String,
    drives_edit: impl Fn(String) -> String,
) -> (f64, f64, Vec<String>) {
    let dir = gantry_folder(urdf_edit, drives_edit);
    let path = dir.path().join("cad_gantry_circle.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let scenario = Scenario::parse(&path, &scenario_edit(text)).unwrap();
    let assembly = Assembly::new(&scenario).unwrap();
    let setup = report_setup(&assembly);
    let out = dir.path().join("out");
    let run = Assembly::new(&scenario)
        .unwrap()
        .run(RunOptions::write_to(&out).traced())
        .unwrap();
    assert!(run.stop().is_none(), "{:?}", run.stop());
    let trace = run.trace.expect("traced");
    let axes = [0, 1, 2].map(|c| assembly.machine.axis_index(["x", "y", "z"][c]).unwrap());
    let worst = contour_within_following_error(&trace, &setup, &axes);
    if let Some(analytic) = run.analytic {
        contour_within_following_error(&analytic, &setup, &axes);
    }
    let warnings = run.warnings.iter().map(|w| w.to_string()).collect();
    (worst, run.metrics.max_contour_error_mm, warnings)
}

#[test]
fn on_a_turned_moving_bed_gantry_the_contour_error_stays_within_the_following_error() {
    let (worst, reported_mm, warnings) = run_gantry(|s| s, |d| d);
    assert!(warnings.is_empty(), "{warnings:?}");
    // The whole circle at 20 mm/s under a 20 Hz loop: micrometres, not the 20 mm of travel a
    // world-frame figure would show.
    assert!(worst < 20e-6, "contour error {worst} m");
    assert!(
        (reported_mm - worst * 1e3).abs() < 1e-9,
        "{reported_mm} mm reported, {worst} m recomputed"
    );
}

#[test]
fn mirrored_axes_and_a_work_offset_keep_the_contour_error_honest() {
    let (worst, _, warnings) = run_gantry(
        |s| {
            s.replace(
                "[planner]",
                "work_offset_mm = [-20.0, 15.0, 2.0]\n\n[planner]",
            )
        },
        |d| d.replace("sign = -1\n", ""),
    );
    assert!(
        warnings.iter().any(|w| w.contains("left-handed")),
        "{warnings:?}"
    );
    assert!(worst < 20e-6, "contour error {worst} m");
}

#[test]
fn a_passive_joint_moves_freely_in_the_physics_and_the_analytic_model_says_it_has_none() {
    // Both clamp joints free: the jaw no longer a mimic of the lever.
    let unmimicked = |u: String| {
        u.replace(
            "<mimic joint=\"clamp_joint\" multiplier=\"-1\" offset=\"0\"/>",
            "",
        )
    };
    let passive = |d: String| {
        d.replace("mode = \"locked\"", "mode = \"passive\"")
            + "\n[joints.clamp_jaw_joint]\nmode = \"passive\"\n"
    };
    let (urdf, drives) = gantry_text();
    let machine = Machine::parse(
        &fixture("cad_gantry.urdf"),
        &unmimicked(urdf),
        &passive(drives),
    )
    .unwrap();
    let names: Vec<&str> = machine
        .passive_joints()
        .into_iter()
        .map(|j| machine.joints[j].name.as_str())
        .collect();
    assert_eq!(names, ["clamp_joint", "clamp_jaw_joint"]);
    // The physics runs it (the contour property holds); the reference model refuses by name.
    let (worst, _, _) = run_gantry_with(
        unmimicked,
        |s| {
            s.replace("[analytic]\nenabled = true\n", "")
                .split("[expect]")
                .next()
                .unwrap()
                .to_string()
        },
        passive,
    );
    assert!(worst < 20e-6, "contour error {worst} m");
    let dir = gantry_folder(unmimicked, passive);
    let scenario = Scenario::load(&dir.path().join("cad_gantry_circle.toml")).unwrap();
    let e = Assembly::new(&scenario)
        .unwrap()
        .lanes()
        .err()
        .expect("the analytic lane is refused")
        .to_string();
    assert!(e.contains("joint 'clamp_joint' is passive"), "{e}");
    // A follower of a free joint is coupled to it: the jaw mirrors the free lever, and the
    // physics runs it.
    let (urdf, drives) = gantry_text();
    let free_lever = |d: String| d.replace("mode = \"locked\"", "mode = \"passive\"");
    let machine = Machine::parse(&fixture("cad_gantry.urdf"), &urdf, &free_lever(drives)).unwrap();
    assert!(machine.undriven.contains(&(
        "clamp_jaw_joint".into(),
        cncsim::machine::Undriven::Coupled {
            leader: "clamp_joint".into(),
            multiplier: -1.0,
            offset: 0.0
        }
    )));
    let (worst, _, _) = run_gantry_with(
        |u| u,
        |s| {
            s.replace("[analytic]\nenabled = true\n", "")
                .split("[expect]")
                .next()
                .unwrap()
                .to_string()
        },
        free_lever,
    );
    assert!(worst < 20e-6, "contour error {worst} m");
}

#[test]
fn a_urdf_that_xacro_wrote_is_read_as_urdf() {
    // xacro keeps its namespace and the macros its author commented out.
    let (urdf, drives) = gantry_text();
    let written = urdf
        .replace("<robot name=\"cad_gantry\">", "<robot name=\"cad_gantry\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n  <!-- <xacro:include filename=\"${extras}\"/> -->")
        .replace("<texture", "");
    Machine::parse(&fixture("cad_gantry.urdf"), &written, &drives).unwrap();
}

#[test]
fn machine_init_guesses_the_letters_from_the_kinematics_and_its_file_loads() {
    let urdf = fixture("cad_gantry.urdf");
    let drives = cncsim::scenario::drive_file_template(&urdf).unwrap();
    let machine = Machine::parse(&urdf, &gantry_text().0, &drives).unwrap();
    let letters: Vec<(String, String, i8)> = machine
        .axes
        .iter()
        .map(|a| {
            (
                a.name.clone(),
                machine.joints[a.joint].name.clone(),
                a.drive.sign,
            )
        })
        .collect();
    assert_eq!(
        letters,
        [
            ("y".to_string(), "bed_joint".to_string(), -1),
            ("x".to_string(), "rail_left".to_string(), 1),
            ("z".to_string(), "carriage_joint".to_string(), 1),
        ],
        "{drives}"
    );
    assert!(
        drives.contains("[joints.clamp_joint]\nmode = \"locked\""),
        "{drives}"
    );
    assert!(
        drives.contains("[workpiece]\nlink = \"workpiece\""),
        "{drives}"
    );
    assert!(drives.contains("[tool]\nlink = \"tool_tip\""), "{drives}");
    let (frame, warnings) = ProgramFrame::new(&machine).unwrap();
    assert!(warnings.is_empty() && frame.directions.determinant() > 0.0);
}

#[test]
fn machine_check_prints_the_mapping_and_run_on_a_urdf_points_to_it() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(["machine", "check"])
        .arg(fixture("cad_gantry.urdf"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for line in [
        "X     rail_left            linear   tool   [ 1.0000,  0.0000,  0.0000]      +1",
        "Y     bed_joint            linear   part   [ 0.0000,  0.0000,  1.0000]      -1",
        "X, Y, Z are right-handed with +Z up, from the part towards the tool (ISO 841)",
        "rail_right: follows 'rail_left' (<mimic>), riding on its link",
        "clamp_joint: locked at 0 ([joints] in the drive file)",
        "clamp_jaw_joint: held at 0 by its <mimic> of 'clamp_joint'",
    ] {
        assert!(text.contains(line), "{line}\n{text}");
    }
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .arg("run")
        .arg(fixture("cad_gantry.urdf"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("this is a machine model, not a scenario") && e.contains("cncsim machine init"),
        "{e}"
    );
}

#[test]
fn a_workpiece_on_a_fixture_fixed_to_the_base_is_measured_in_its_own_frame() {
    // The paper's table with the part on a fixture bolted to the base 200 mm off and turned
    // 90° about z: the program axes turn with it, the figures do not move.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let urdf = std::fs::read_to_string(root.join("models/xyz_table.urdf"))
        .unwrap()
        .replace(
            "</robot>",
            "  <link name=\"fixture\"/>\n  <joint name=\"fixture_mount\" type=\"fixed\">\n    <parent link=\"base\"/><child link=\"fixture\"/>\n    <origin xyz=\"0.2 0.1 0.01\" rpy=\"0 0 1.5707963267948966\"/>\n  </joint>\n</robot>",
        );
    let drives = std::fs::read_to_string(root.join("models/xyz_table.drives.toml"))
        .unwrap()
        .replace("[tool]", "[workpiece]\nlink = \"fixture\"\n\n[tool]");
    std::fs::write(dir.path().join("xyz_table.urdf"), urdf).unwrap();
    std::fs::write(dir.path().join("xyz_table.drives.toml"), drives).unwrap();
    let path = dir.path().join("circle.toml");
    let text = std::fs::read_to_string(root.join("scenarios/xyz_circle_5mms.toml"))
        .unwrap()
        .replace("../models/xyz_table.urdf", "xyz_table.urdf")
        .replace("feed_mm_s = 5.0", "feed_mm_s = 40.0");
    let scenario = Scenario::parse(&path, text.split("[expect]").next().unwrap()).unwrap();
    let assembly = Assembly::new(&scenario).unwrap();
    let (frame, _) = ProgramFrame::new(&assembly.machine).unwrap();
    assert_eq!(assembly.machine.links[frame.carrier].name, "fixture");
    // World +x is the fixture's -y, world +y its +x.
    assert!((frame.directions.column(0) - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
    let setup = report_setup(&assembly);
    let run = Assembly::new(&scenario)
        .unwrap()
        .run(RunOptions::write_to(dir.path().join("out")).traced())
        .unwrap();
    let axes = [0, 1, 2].map(|c| assembly.machine.axis_index(["x", "y", "z"][c]).unwrap());
    let worst = contour_within_following_error(run.trace.as_ref().unwrap(), &setup, &axes);
    contour_within_following_error(run.analytic.as_ref().unwrap(), &setup, &axes);
    // The same circle as on the base: micrometres, not the fixture's 224 mm offset.
    assert!(worst < 5e-6, "contour error {worst} m");
}

/// Copies a folder (a third-party package) into `to`.
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap().flatten() {
        let target = to.join(entry.file_name());
        if entry.path().is_dir() {
            copy_tree(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

/// Runs `scenario` traced and checks the contour error against the following error on every
/// tick of the physics and the reference model; returns the run.
fn run_honest(scenario: &Scenario) -> cncsim::scenario::RunOutput {
    let assembly = Assembly::new(scenario).unwrap();
    let setup = report_setup(&assembly);
    let out = tempfile::tempdir().unwrap();
    let run = Assembly::new(scenario)
        .unwrap()
        .run(RunOptions::write_to(out.path()).traced())
        .unwrap();
    assert!(run.stop().is_none(), "{:?}", run.stop());
    let axes = [0, 1, 2].map(|c| assembly.machine.axis_index(["x", "y", "z"][c]).unwrap());
    contour_within_following_error(run.trace.as_ref().unwrap(), &setup, &axes);
    if let Some(analytic) = &run.analytic {
        contour_within_following_error(analytic, &setup, &axes);
    }
    run
}

/// A circle of 40 mm at 25 mm/s on the SolidWorks-exported gantry of CMU-BORG's Li et al. (ICRA
/// 2023), as published: its frames turned as the exporter turns them (the uprights 90° about x),
/// its bed moving (Y), two grasper fingers on the X carriage that no drive moves. PID on ideal
/// torque, by pole placement on each axis's joint-side inertia with the reflected rotor and pulley
/// or screw (X 1.069 kg, Y 2.925 kg, Z 5.782 kg): Kp = m·ωn²/k, Kd = 2ζ·m·ωn/k, Ki = Kp·ωn/5,
/// ωn = 2π·20 Hz, ζ = 0.8 (k: motor rad per m). Program zero 235 mm below the Z bar's top: the
/// fingertips 5 mm above the bed plate. Measured: contour 1.23 µm; following error X 0.84 µm,
/// Y 34.2 µm (the circle leaves along Y), Z 0.020 µm; path-speed error 2.06 mm/s, caught up in
/// 40 ms; physics against the analytic model X 0.005 µm, Y 0.34 µm, Z 0.001 µm. Bounds about
/// 1.5× above.
const SW_GANTRY_CIRCLE: &str = r#"
name = "sw_gantry_circle"
machine = "urdf/GantryAssembly_URDF.SLDASM.urdf"
[program]
circle = { center_mm = [0.0, 0.0], radius_mm = 40.0, start_angle_deg = 0.0, direction = "ccw", z_mm = 0.0 }
feed_mm_s = 25.0
work_offset_mm = [0.0, 0.0, -235.0]
[planner]
profile = "jerk-limited"
limits.x = { velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }
limits.y = { velocity = 200.0, acceleration = 2000.0, jerk = 50000.0 }
limits.z = { velocity = 100.0, acceleration = 1000.0, jerk = 20000.0 }
[timing]
servo_period_ms = 1.0
physics_step_ms = 0.25
settle_s = 0.2
[actuator]
model = "ideal-torque"
[controller]
type = "pid"
axes.x = { kp = 107.5, ki = 2702.0, kd = 1.369, output_limit = 0.5 }
axes.y = { kp = 294.2, ki = 7394.0, kd = 3.746, output_limit = 0.5 }
axes.z = { kp = 116.2, ki = 2922.0, kd = 1.48, output_limit = 0.5 }
[analytic]
enabled = true
[recording]
rrd = false
# The Y joint's own <dynamics friction="3"> (N) acts, in the physics and the analytic model
# alike: the PID's integral has to break it away at every reversal of Y (measured: contour
# 72.3 µm, Y 86.3 µm, path speed 3.195 mm/s; the bounds before the friction was applied were
# 2 µm, 52 µm and 3.1 mm/s). Physics and analytic model still agree within 0.5 µm on Y.
[expect]
max_contour_error_mm = { max = 0.075 }
max_path_speed_error_mm_s = { max = 3.25 }
path_speed_catch_up_s = { max = 0.06 }
axes.x.max_following_error_mm = { max = 0.0013 }
axes.y.max_following_error_mm = { max = 0.088 }
axes.z.max_following_error_mm = { max = 0.00003 }
axes.x.max_physics_vs_analytic_mm = { max = 0.00001 }
axes.y.max_physics_vs_analytic_mm = { max = 0.0005 }
axes.z.max_physics_vs_analytic_mm = { max = 0.000003 }
"#;

#[test]
fn gantries_written_by_others_run_as_published_and_their_figures_are_the_tool_on_the_part() {
    // Machines written by other projects are not in this repository: their URDFs and meshes are
    // read from the shared corpus (skipped without it, a failure in CI).
    let (Some(sw_gantry), Some(ntnu_gantry)) = (
        common::shared_corpus("own-machines/machines/sw_gantry_cmu"),
        common::shared_corpus("own-machines/machines/ntnu_gantry"),
    ) else {
        return;
    };
    // The SolidWorks export (MIT), as published, with cncsim's drive file beside its URDF: the
    // scenario's bounds hold, its meshes are all drawn, nothing is warned of.
    let dir = tempfile::tempdir().unwrap();
    copy_tree(&sw_gantry, dir.path());
    let urdf = dir.path().join("urdf/GantryAssembly_URDF.SLDASM.urdf");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures/machines/sw_gantry_cmu.drives.toml"),
        urdf.with_extension("drives.toml"),
    )
    .unwrap();
    let scenario = Scenario::parse(&dir.path().join("circle.toml"), SW_GANTRY_CIRCLE).unwrap();
    let run = run_honest(&scenario);
    assert!(run.verdict.passed(), "{:?}", run.verdict.breaches);
    assert!(run.warnings.is_empty(), "{:?}", run.warnings);
    let machine = Machine::load(&urdf).unwrap();
    let meshes = machine.links.iter().flat_map(|l| &l.visuals).count();
    assert_eq!(meshes, 9);
    // `machine check` says that the Y joint's own friction acts.
    let check = cncsim::scenario::check_machine(&urdf).unwrap().text();
    assert!(
        check.contains(
            "Y also has the URDF's <dynamics> at joint 'BasePlateJoint': damping 0 N·s/m, Coulomb friction 3 N"
        ),
        "{check}"
    );

    // The Blender/Phobos export (Apache-2.0): a 6.6 m overhead gantry of 1.3 t, as published,
    // with the drive file `machine init` writes and a model-based controller (no gains to
    // tune): a 100 mm circle at 50 mm/s, 200 mm below the arm's top.
    let dir = tempfile::tempdir().unwrap();
    copy_tree(&ntnu_gantry, dir.path());
    let urdf = dir.path().join("gantry_support/urdf/gantry.urdf");
    std::fs::write(
        urdf.with_extension("drives.toml"),
        cncsim::scenario::drive_file_template(&urdf).unwrap(),
    )
    .unwrap();
    let path = dir.path().join("circle.toml");
    let scenario = Scenario::parse(
        &path,
        "machine = \"gantry_support/urdf/gantry.urdf\"\n\
         [program]\n\
         circle = { center_mm = [300.0, 300.0], radius_mm = 100.0, start_angle_deg = 0.0, direction = \"ccw\", z_mm = -200.0 }\n\
         feed_mm_s = 50.0\n\
         [planner]\nprofile = \"jerk-limited\"\n\
         limits.x = { velocity = 200.0, acceleration = 500.0, jerk = 5000.0 }\n\
         limits.y = { velocity = 200.0, acceleration = 500.0, jerk = 5000.0 }\n\
         limits.z = { velocity = 200.0, acceleration = 500.0, jerk = 5000.0 }\n\
         [timing]\nservo_period_ms = 1.0\nphysics_step_ms = 0.25\nsettle_s = 0.2\n\
         [actuator]\nmodel = \"ideal-torque\"\n\
         [controller]\ntype = \"inverse-dynamics\"\nnatural_frequency_hz = 10.0\n\
         [analytic]\nenabled = true\n\
         [recording]\nrrd = false\n",
    )
    .unwrap();
    let run = run_honest(&scenario);
    // Computed torque on an exact model of the rigid machine: measured 0.026 µm.
    let contour_mm = run.metrics.max_contour_error_mm;
    assert!(
        contour_mm > 0.0 && contour_mm < 1e-4,
        "contour error {contour_mm} mm on a 100 mm circle"
    );
}

#[test]
fn the_controllers_model_in_axis_coordinates_carries_the_followers() {
    use cncsim::dynamics::AxisDynamics;
    // The gantry with a 3 kg counterweight at μ = −0.5 on Z: in the axes' coordinates Z moves
    // m_z + μ²·m_w plus its drive's armature J·k², and holds m_z + μ·m_w against gravity.
    let (m_z, m_w, mu) = (2.0, 3.0, -0.5);
    let machine = counterweighted_gantry(m_w, mu);
    let g = 9.81;
    let mut model = AxisDynamics::of_machine(&machine, Vector3::new(0.0, 0.0, -g)).unwrap();
    assert_eq!(model.dof(), 3);
    let mut ws = model.workspace();
    let z = machine.axis_index("z").unwrap();
    let armature = machine.axes[z].drive.reflected_inertia();
    let (q, qd) = ([0.0; 3], [0.0; 3]);
    let mut qdd = [0.0; 3];
    qdd[z] = 1.5;
    let mut tau = [0.0; 3];
    model.inverse_dynamics(&mut ws, &q, &qd, &qdd, &mut tau);
    let expected = (m_z + mu * mu * m_w + armature) * qdd[z] + g * (m_z + mu * m_w);
    assert!(
        (tau[z] - expected).abs() < 1e-9 * expected.abs(),
        "{} N against {expected} N",
        tau[z]
    );
    let mut mass = nalgebra::DMatrix::zeros(3, 3);
    model.mass_matrix(&mut ws, &q, &mut mass);
    assert!((mass[(z, z)] - (m_z + mu * mu * m_w + armature)).abs() < 1e-9);
    // A passive joint has no coordinate among the axes: refused by name, not a panic.
    let (urdf, drives) = gantry_text();
    let free = Machine::parse(
        &fixture("cad_gantry.urdf"),
        &urdf,
        &drives.replace("mode = \"locked\"", "mode = \"passive\""),
    )
    .unwrap();
    let e = AxisDynamics::of_machine(&free, Vector3::new(0.0, 0.0, -g))
        .unwrap_err()
        .to_string();
    assert!(e.contains("joint 'clamp_joint': it is passive"), "{e}");
}

/// The README's walkthrough machine, `models/desk_router/`: in the shape a CAD exporter writes
/// one, read as its drive file (init's, corrected by hand) says.
#[test]
fn the_walkthrough_router_reads_as_an_exporters_package() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let urdf = root.join("models/desk_router/urdf/desk_router.urdf");
    let machine = Machine::load(&urdf).unwrap();
    // Every mesh behind its package:// path is found and drawn.
    let text = std::fs::read_to_string(&urdf).unwrap();
    assert_eq!(text.matches("package://desk_router/meshes/").count(), 16);
    assert_eq!(machine.links.iter().flat_map(|l| &l.visuals).count(), 8);
    // Turned frames, a moving bed: the program axes are still right-handed, on the stock.
    let (frame, warnings) = ProgramFrame::new(&machine).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(machine.links[frame.carrier].name, "Stock");
    assert!(frame.directions.determinant() > 0.0);
    assert!(text.contains("<mimic") && text.contains("rpy=\"1.5707963267949 0 1.5707963267949\""));
    // The committed URDF and meshes are what the generator writes.
    let python = std::env::var("CNCSIM_PYTHON").unwrap_or_else(|_| "python3".into());
    let out = tempfile::tempdir().unwrap();
    let Ok(status) = std::process::Command::new(&python)
        .arg(root.join("tools/desk_router.py"))
        .arg(out.path())
        .status()
    else {
        eprintln!("skipped: {python} does not run (the generator's output is not compared)");
        return;
    };
    assert!(status.success());
    for file in [
        "urdf/desk_router.urdf",
        "package.xml",
        "meshes/ZRam.STL",
        "meshes/Bed.STL",
    ] {
        assert!(
            std::fs::read(out.path().join(file)).unwrap()
                == std::fs::read(root.join("models/desk_router").join(file)).unwrap(),
            "models/desk_router/{file} is not what tools/desk_router.py writes"
        );
    }
}

#[test]
fn a_driven_joints_urdf_friction_acts_and_behind_backlash_is_refused_by_name() {
    // `<dynamics friction>` on the bed's driven joint: the physics holds the bed against up to
    // that force (a stiff zero-speed motor at the joint), and the reference model adds it to
    // the axis's Coulomb friction.
    let (urdf, drives) = gantry_text();
    let with_friction = urdf.replace(
        "<limit lower=\"-0.15\" upper=\"0.15\" effort=\"500\" velocity=\"0.5\"/>\n  </joint>",
        "<limit lower=\"-0.15\" upper=\"0.15\" effort=\"500\" velocity=\"0.5\"/>\n    <dynamics friction=\"40\"/>\n  </joint>",
    );
    assert_ne!(with_friction, urdf);
    let machine = Machine::parse(&fixture("cad_gantry.urdf"), &with_friction, &drives).unwrap();
    let y = machine.axis_index("y").unwrap();
    let options = cncsim::model::PlantOptions {
        step: 2.5e-4,
        gravity: [0.0, 0.0, -9.81],
        initial_positions: vec![0.0; machine.axes.len()],
        include_drive_dynamics: false,
        solver_iterations: 4,
    };
    let travel = |force: f64| {
        let mut plant = cncsim::model::Plant::new(&machine, &options).unwrap();
        let mut forces = vec![0.0; machine.axes.len()];
        forces[y] = force;
        for _ in 0..400 {
            plant.set_joint_forces(&forces);
            plant.step();
        }
        let mut q = vec![0.0; machine.axes.len()];
        plant.positions(&mut q);
        q[y].abs()
    };
    // 30 N against 40 N of friction: held (below a µm in 0.1 s); 80 N: the bed moves.
    assert!(travel(30.0) < 1e-6, "{}", travel(30.0));
    assert!(travel(80.0) > 1e-4, "{}", travel(80.0));
    // Behind backlash the carriage hangs on the drive side: no joint for it to act at.
    let backlash = drives.replace(
        "joint = \"bed_joint\"",
        "joint = \"bed_joint\"\nbacklash = 0.00002",
    );
    let e = Machine::parse(&fixture("cad_gantry.urdf"), &with_friction, &backlash)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cad_gantry.urdf:23:3") && e.contains("<dynamics friction=\"40\">"),
        "{e}"
    );
}

/// A URDF of the given joints (name, type, parent, child, axis), every link 1 kg, the tool
/// and part links named by the joints' children; written into `dir` as `name.urdf`.
fn machine_of(dir: &Path, name: &str, joints: &[(&str, &str, &str, &str, [f64; 3])]) -> PathBuf {
    let mut links: Vec<&str> = vec!["base"];
    for j in joints {
        links.push(j.3);
    }
    let mut text = format!("<robot name=\"{name}\">\n");
    for l in &links {
        text += &format!(
            "  <link name=\"{l}\"><inertial><mass value=\"1\"/><inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/></inertial></link>\n"
        );
    }
    for (j, kind, parent, child, axis) in joints {
        let limit = if *kind == "continuous" {
            String::new()
        } else {
            "<limit lower=\"-0.5\" upper=\"0.5\" effort=\"100\" velocity=\"1\"/>".to_string()
        };
        text += &format!(
            "  <joint name=\"{j}\" type=\"{kind}\"><parent link=\"{parent}\"/><child link=\"{child}\"/><origin xyz=\"0 0 0.1\"/><axis xyz=\"{} {} {}\"/>{limit}</joint>\n",
            axis[0], axis[1], axis[2]
        );
    }
    text += "</robot>\n";
    let path = dir.join(format!("{name}.urdf"));
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn machine_init_names_second_parallel_motions_as_iso_841_does_and_check_says_why() {
    // A boring mill: a W quill in the Z ram, a C head turning about Z and a C table under
    // the part. The second Z slide is W and the second Z rotation D, never another axis's
    // letter; programs hold them at home.
    let dir = tempfile::tempdir().unwrap();
    let urdf = machine_of(
        dir.path(),
        "boring_mill",
        &[
            (
                "table_turn",
                "continuous",
                "base",
                "part_table",
                [0.0, 0.0, 1.0],
            ),
            ("x", "prismatic", "base", "column", [1.0, 0.0, 0.0]),
            ("y", "prismatic", "column", "saddle", [0.0, 1.0, 0.0]),
            ("z", "prismatic", "saddle", "ram", [0.0, 0.0, 1.0]),
            ("quill", "prismatic", "ram", "quill_body", [0.0, 0.0, 1.0]),
            (
                "head_turn",
                "continuous",
                "quill_body",
                "tool",
                [0.0, 0.0, 1.0],
            ),
        ],
    );
    let drives = cncsim::scenario::drive_file_template(&urdf).unwrap();
    std::fs::write(dir.path().join("boring_mill.drives.toml"), &drives).unwrap();
    let machine = Machine::load(&urdf).unwrap();
    let letters: Vec<(String, String)> = machine
        .axes
        .iter()
        .map(|a| (machine.joints[a.joint].name.clone(), a.name.clone()))
        .collect();
    for (joint, letter) in [
        ("table_turn", "c"),
        ("x", "x"),
        ("y", "y"),
        ("z", "z"),
        ("quill", "w"),
        ("head_turn", "d"),
    ] {
        assert!(
            letters.contains(&(joint.to_string(), letter.to_string())),
            "{joint} → {letter}: {letters:?}\n{drives}"
        );
    }
    assert!(
        drives.contains("# W: URDF joint 'quill', which moves the tool along Z in the base's frame like Z (joint 'z'): W, ISO 841's secondary linear motion; programs hold it at home."),
        "{drives}"
    );
    assert!(
        drives.contains("# D: URDF joint 'head_turn', which turns about Z in the base's frame like C (joint 'table_turn'): D, ISO 841's secondary rotary motion; programs hold it at home."),
        "{drives}"
    );
    // Programs can run on it: the secondary axes hold their home.
    AxisMap::new(&machine).unwrap();
    let report = cncsim::scenario::check_machine(&urdf).unwrap();
    let text = report.text();
    for line in [
        "  C: turns about Z: C (ISO 841: A, B, C turn about X, Y, Z)",
        "  W: a second motion along Z: W, ISO 841's secondary linear motion; programs hold it at home",
        "  D: a second rotation (about Z): D, ISO 841's secondary rotary motion; programs hold it at home",
    ] {
        assert!(text.contains(line), "{line}\n{text}");
    }
    // A letter against its axis is explained, with the letter it should have.
    let wrong = drives.replace("[axes.c]", "[axes.a]");
    std::fs::write(dir.path().join("boring_mill.drives.toml"), wrong).unwrap();
    let text = cncsim::scenario::check_machine(&urdf).unwrap().text();
    assert!(
        text.contains("  A: turns about Z, but A turns about X in ISO 841: name it C (or D, E where C is taken)"),
        "{text}"
    );
}

#[test]
fn machine_init_never_writes_a_left_handed_or_z_down_frame() {
    // Every sign of every slide's joint axis, each slide on the tool's or the part's side: the
    // drive file init writes reads right-handed with +Z up, and check says so.
    let dir = tempfile::tempdir().unwrap();
    let mut cases = 0;
    for signs in 0..8u32 {
        for sides in 0..8u32 {
            let s = |k: u32| if signs & (1 << k) == 0 { 1.0 } else { -1.0 };
            let on_part = |k: u32| sides & (1 << k) != 0;
            // Part-side slides stack under the part, tool-side ones under the tool.
            let mut joints = Vec::new();
            let (mut part_parent, mut tool_parent) = ("base", "base");
            let names = [("x", "sx"), ("y", "sy"), ("z", "sz")];
            for (k, (joint, link)) in names.iter().enumerate() {
                let axis = [0.0, 0.0, 0.0];
                let mut axis = axis;
                axis[k] = s(k as u32);
                let parent = if on_part(k as u32) {
                    part_parent
                } else {
                    tool_parent
                };
                joints.push((*joint, "prismatic", parent, *link, axis));
                if on_part(k as u32) {
                    part_parent = link;
                } else {
                    tool_parent = link;
                }
            }
            joints.push(("part_mount", "fixed", part_parent, "part", [1.0, 0.0, 0.0]));
            joints.push(("tool_mount", "fixed", tool_parent, "tool", [1.0, 0.0, 0.0]));
            let name = format!("m{signs}_{sides}");
            let urdf = machine_of(dir.path(), &name, &joints);
            let drives = cncsim::scenario::drive_file_template(&urdf).unwrap();
            std::fs::write(dir.path().join(format!("{name}.drives.toml")), &drives).unwrap();
            let report = cncsim::scenario::check_machine(&urdf)
                .unwrap_or_else(|e| panic!("{name}: {e}\n{drives}"));
            assert!(
                report.right_handed && report.z_up == Some(true),
                "{name}: right-handed {}, z up {:?}\n{drives}",
                report.right_handed,
                report.z_up
            );
            assert!(
                report.text().contains(
                    "X, Y, Z are right-handed with +Z up, from the part towards the tool (ISO 841)"
                ),
                "{name}"
            );
            let machine = Machine::load(&urdf).unwrap();
            let (_, warnings) = ProgramFrame::new(&machine).unwrap();
            assert!(warnings.is_empty(), "{name}: {warnings:?}");
            cases += 1;
        }
    }
    assert_eq!(cases, 64);
}

#[test]
fn a_z_axis_pointing_into_the_part_is_warned_of_and_check_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = machine_of(
        dir.path(),
        "z_down",
        &[
            ("x", "prismatic", "base", "sx", [1.0, 0.0, 0.0]),
            ("y", "prismatic", "sx", "sy", [0.0, -1.0, 0.0]),
            ("z", "prismatic", "sy", "tool", [0.0, 0.0, -1.0]),
        ],
    );
    std::fs::write(
        dir.path().join("z_down.drives.toml"),
        three_slide_drives("z_down"),
    )
    .unwrap();
    let machine = Machine::load(&urdf).unwrap();
    let (_, warnings) = ProgramFrame::new(&machine).unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.to_string().contains("program +Z points down")),
        "{warnings:?}"
    );
    let report = cncsim::scenario::check_machine(&urdf).unwrap();
    assert_eq!(report.z_up, Some(false));
    assert!(report.right_handed, "X, −Y, −Z is right-handed");
    assert!(
        report
            .text()
            .contains("+Z points DOWN, from the tool into the part"),
        "{}",
        report.text()
    );
}

/// A drive file for a three-slide machine written by `machine_of`: the same small servo on
/// each of its joints x, y, z.
fn three_slide_drives(machine: &str) -> String {
    let mut text = format!("machine = \"{machine}\"\n[tool]\nlink = \"tool\"\n");
    for axis in ["x", "y", "z"] {
        text += &format!(
            "[axes.{axis}]\njoint = \"{axis}\"\ntransmission = {{ kind = \"screw\", lead_m = 0.01 }}\nrotor_inertia_kg_m2 = 1e-4\nviscous_damping_nm_s_per_rad = 1e-4\nmotor = {{ torque_constant_nm_per_a = 0.6, back_emf_v_s_per_rad = 0.6, resistance_ohm = 1.5, inductance_h = 4e-3 }}\namplifier_gain = 10.0\nsupply_voltage_v = 300.0\npeak_torque_nm = 7.0\n"
        );
    }
    text
}

#[test]
fn the_tool_link_init_guesses_is_said_to_be_a_guess_until_checked() {
    // A link named like a tool wins over a deeper one that is not ("multiple" holds "tip"
    // only as letters, not as a word).
    let dir = tempfile::tempdir().unwrap();
    let urdf = machine_of(
        dir.path(),
        "printer",
        &[
            ("x", "prismatic", "base", "sx", [1.0, 0.0, 0.0]),
            ("y", "prismatic", "sx", "sy", [0.0, 1.0, 0.0]),
            ("z", "prismatic", "sy", "carriage", [0.0, 0.0, 1.0]),
            (
                "tip_mount",
                "fixed",
                "carriage",
                "nozzle_tip",
                [1.0, 0.0, 0.0],
            ),
            (
                "fan",
                "continuous",
                "carriage",
                "multiple_fan_blades",
                [0.0, 0.0, 1.0],
            ),
        ],
    );
    let drives = cncsim::scenario::drive_file_template(&urdf).unwrap();
    assert!(
        drives
            .contains("[tool]\nlink = \"nozzle_tip\"\noffset_m = [0.0, 0.0, 0.0]\nguessed = true"),
        "{drives}"
    );
    std::fs::write(dir.path().join("printer.drives.toml"), &drives).unwrap();
    let machine = Machine::load(&urdf).unwrap();
    assert!(
        machine.warnings.iter().any(|w| w
            .to_string()
            .contains("[tool] link = 'nozzle_tip' is `machine init`'s guess")),
        "{:?}",
        machine.warnings
    );
    let text = cncsim::scenario::check_machine(&urdf).unwrap().text();
    assert!(
        text.contains("tool point: link 'nozzle_tip' + [0.000, 0.000, 0.000] mm, at [0.000, 0.000, 400.000] mm in 'base' with every axis at home — machine init's GUESS"),
        "{text}"
    );
    // Checked by the user: the line deleted, nothing more said.
    std::fs::write(
        dir.path().join("printer.drives.toml"),
        drives.replace("guessed = true\n", ""),
    )
    .unwrap();
    let machine = Machine::load(&urdf).unwrap();
    assert!(
        !machine
            .warnings
            .iter()
            .any(|w| w.to_string().contains("guess")),
        "{:?}",
        machine.warnings
    );
    let text = cncsim::scenario::check_machine(&urdf).unwrap().text();
    assert!(!text.contains("GUESS"), "{text}");
}
