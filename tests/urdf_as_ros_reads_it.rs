//! URDF as ROS reads it: what urdfdom (the parser behind ROS, RViz, MoveIt and Gazebo) accepts,
//! cncsim reads too, with the same links, and with a located warning where it must choose
//! (the first of repeated elements wins, as in urdfdom; comments with `--`; unknown elements
//! and attributes). Refused are only values no physical machine has, each with its file, line
//! and column.
//!
//! The oracle is `check_urdf` (Debian's `liburdfdom-tools`, installed by `.ci/run`); the files
//! are the probes in `tests/fixtures/urdf_probes` (one construct each, written for these tests;
//! `INDEX.tsv` says which), the machines of the shared corpus and the robots of
//! `example-robot-data` (`CNCSIM_URDF_CORPUS`).

mod common;

use cncsim::machine::{load_urdf, Machine};
use std::path::{Path, PathBuf};
use std::process::Command;

fn probes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/urdf_probes")
}

/// What urdfdom made of a file.
enum Urdfdom {
    /// Parsed without an error in its log: the links of its tree.
    Accepts(Vec<String>),
    /// Parsed, but with errors in its log (a broken element dropped).
    AcceptsWithErrors,
    Refuses,
}

/// `check_urdf FILE`, or `None` where it is not installed.
fn urdfdom(path: &Path) -> Option<Urdfdom> {
    let out = Command::new("check_urdf").arg(path).output().ok()?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() || !stdout.contains("Successfully Parsed") {
        return Some(Urdfdom::Refuses);
    }
    if stderr.contains("Error") || stdout.contains("Error") {
        return Some(Urdfdom::AcceptsWithErrors);
    }
    // "root Link: base has 1 child(ren)" then "    child(1):  x_carriage", one per line.
    let mut links: Vec<String> = stdout
        .lines()
        .filter_map(|l| {
            let l = l.trim();
            l.strip_prefix("root Link: ")
                .and_then(|r| r.split(" has ").next())
                .or_else(|| l.split_once("):  ").map(|(_, name)| name))
                .map(|n| n.trim().to_string())
        })
        .collect();
    links.sort();
    Some(Urdfdom::Accepts(links))
}

/// The refusals cncsim makes where urdfdom reads a value no physical machine has, or a joint
/// a machine tool has no use for; each must name its line and column.
const PHYSICAL_REFUSALS: &[&str] = &[
    "triangle inequality",
    "has inertia but zero mass",
    "expected finite lower < upper",
    "expected a positive size",
    "is not a direction",
    "expected a finite mass ≥ 0",
    "joint type Floating is not supported",
    "joint type Planar is not supported",
    "expected a positive size up to",
];

#[test]
fn cncsim_reads_what_urdfdom_reads_with_the_same_links() {
    if Command::new("check_urdf").arg("--help").output().is_err() {
        assert!(
            !common::required_in_ci(),
            "check_urdf (Debian liburdfdom-tools) is required in CI"
        );
        eprintln!("skipped: check_urdf not installed (apt install liburdfdom-tools)");
        return;
    }
    let mut files = Vec::new();
    common::urdfs(&probes(), &mut files);
    for corpus in ["own-machines/machines", "own-machines/probes"] {
        if let Some(dir) = common::shared_corpus(corpus) {
            common::urdfs(&dir, &mut files);
        }
    }
    if let Some(dir) = std::env::var_os("CNCSIM_URDF_CORPUS") {
        common::urdfs(Path::new(&dir), &mut files);
    }
    let (mut same, mut deliberate, mut both_refuse, mut lenient) = (0, Vec::new(), 0, Vec::new());
    let mut disagreements = Vec::new();
    for f in &files {
        let ours = load_urdf(f);
        match (urdfdom(f).expect("check_urdf runs"), ours) {
            (Urdfdom::Accepts(links), Ok(tree)) => {
                let mut mine: Vec<String> = tree.links.iter().map(|l| l.name.clone()).collect();
                mine.sort();
                if mine == links {
                    same += 1;
                } else {
                    disagreements.push(format!(
                        "{}: links {mine:?} vs urdfdom's {links:?}",
                        f.display()
                    ));
                }
            }
            (Urdfdom::Accepts(_) | Urdfdom::AcceptsWithErrors, Err(e)) => {
                let message = e.to_string();
                let located = e.at.is_some();
                if located && PHYSICAL_REFUSALS.iter().any(|r| message.contains(r)) {
                    deliberate.push(message);
                } else if matches!(urdfdom(f), Some(Urdfdom::AcceptsWithErrors)) && located {
                    // urdfdom logged an error and dropped the element; a located refusal is fair.
                    deliberate.push(message);
                } else {
                    disagreements.push(format!("urdfdom reads it, cncsim refuses: {message}"));
                }
            }
            (Urdfdom::AcceptsWithErrors, Ok(_)) => same += 1,
            (Urdfdom::Refuses, Err(_)) => both_refuse += 1,
            (Urdfdom::Refuses, Ok(_)) => lenient.push(f.display().to_string()),
        }
    }
    eprintln!(
        "{} files: {same} read alike, {} refused as physically impossible (located), {both_refuse} refused by both, {} read by cncsim only",
        files.len(),
        deliberate.len(),
        lenient.len()
    );
    for m in &deliberate {
        eprintln!("  refused: {m}");
    }
    for f in &lenient {
        eprintln!("  cncsim only: {f}");
    }
    assert!(disagreements.is_empty(), "{disagreements:#?}");
    assert!(files.len() >= 100, "{} files", files.len());
}

fn probe(name: &str) -> PathBuf {
    probes().join(format!("{name}.urdf"))
}

/// The warnings of loading `name`, as text.
fn warnings(name: &str) -> Vec<String> {
    let tree = load_urdf(&probe(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    tree.warnings.iter().map(|w| w.to_string()).collect()
}

#[test]
fn where_cncsim_must_choose_it_says_so_at_the_place() {
    // (probe, what the warning says, its place)
    let cases = [
        (
            "material_named_then_empty",
            "a second <material> in <visual>",
            ":6:145:",
        ),
        ("origin_twice_joint", "a second <origin> in <joint>", ":"),
        ("parent_twice", "a second <parent> in <joint>", ":"),
        (
            "geometry_extra_child",
            "a second <material> in <geometry>",
            ":",
        ),
        (
            "geometry_unknown_plane",
            "holds <plane>, which is not a URDF shape",
            ":3:42:",
        ),
        ("comment_double_dash", "a comment holds `--`", ":"),
        (
            "visual_no_geometry",
            "<visual> without <geometry>: ignored",
            ":",
        ),
        ("custom_in_link", "is not a URDF element: ignored", ":"),
        ("unknown_attributes", "not a URDF attribute: ignored", ":"),
        (
            "element_after_robot",
            "beside the <robot> element: ignored",
            ":",
        ),
        ("mimic_unknown_joint", "the mimic is ignored", ":"),
    ];
    for (name, says, at) in cases {
        let found = warnings(name);
        assert!(
            found
                .iter()
                .any(|w| w.contains(says) && w.contains(&format!("{name}.urdf{at}"))),
            "{name}: expected a warning with {says:?} at {at:?} in {found:#?}"
        );
    }
    // The first of repeated elements is read, as urdfdom reads it.
    let tree = load_urdf(&probe("origin_twice_joint")).unwrap();
    let text = std::fs::read_to_string(probe("origin_twice_joint")).unwrap();
    let first = text.find("<origin").unwrap();
    let second = first + 1 + text[first + 1..].find("<origin").unwrap();
    assert_ne!(text[first..first + 40], text[second..second + 40]);
    let x = tree.joints.iter().find(|j| j.name == "x").unwrap();
    let xyz = |at: usize| -> Vec<f64> {
        let v = &text[at..];
        let v = &v[v.find("xyz=\"").unwrap() + 5..];
        v[..v.find('"').unwrap()]
            .split_whitespace()
            .map(|n| n.parse().unwrap())
            .collect()
    };
    assert_eq!(
        x.origin.translation.vector.as_slice(),
        &xyz(first)[..],
        "the first <origin> is read"
    );
    // What is standard ROS (gazebo, transmission, ros2_control) is read without a word.
    for quiet in [
        "gazebo_element",
        "transmission_element",
        "ros2_control_element",
        "00_control",
    ] {
        assert!(warnings(quiet).is_empty(), "{quiet}: {:?}", warnings(quiet));
    }
}

#[test]
fn a_massless_frame_between_two_slides_runs_and_only_a_singular_chain_is_refused() {
    // x_carriage has no <inertial>; the y carriage beyond it has 1 kg: every joint moves
    // mass, the multibody's mass matrix is positive definite.
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("m.urdf");
    std::fs::copy(probe("massless_between_slides"), &urdf).unwrap();
    let drives = cncsim::scenario::drive_file_template(&urdf).unwrap();
    let machine = Machine::parse(&urdf, &std::fs::read_to_string(&urdf).unwrap(), &drives)
        .unwrap_or_else(|e| panic!("{e}"));
    let options = cncsim::model::PlantOptions {
        step: 2.5e-4,
        gravity: [0.0, 0.0, -9.81],
        initial_positions: vec![0.0; machine.axes.len()],
        include_drive_dynamics: true,
        solver_iterations: 4,
    };
    let mut plant = cncsim::model::Plant::new(&machine, &options).unwrap_or_else(|e| panic!("{e}"));
    // A constant force on each axis for 50 ms: the carriage, and the frame with it, moves as
    // 1 kg does (x = F t² / 2m with F = 1 N: 1.25 mm), nothing turns NaN.
    let mut q = vec![0.0; machine.axes.len()];
    for _ in 0..200 {
        plant.set_joint_forces(&vec![1.0; machine.axes.len()]);
        plant.step();
    }
    plant.positions(&mut q);
    assert!(q.iter().all(|v| v.is_finite()), "{q:?}");
    // A link with no mass and nothing beyond it is still refused, at its line.
    let e = load_urdf(&probe("massless_tip"))
        .and_then(|_| {
            let drives = cncsim::scenario::drive_file_template(&probe("massless_tip"))?;
            Machine::parse(
                &probe("massless_tip"),
                &std::fs::read_to_string(probe("massless_tip")).unwrap(),
                &drives,
            )
        })
        .unwrap_err();
    assert!(e.to_string().contains("massless_tip.urdf:8:3"), "{e}");
}

#[test]
fn an_open_mesh_is_weighed_by_its_convex_hull_with_a_warning() {
    let dir = probes().join("stl_open_inertia_from_geometry");
    let urdf = dir.join("stl_open_inertia_from_geometry.urdf");
    let text = std::fs::read_to_string(&urdf).unwrap();
    let drives = cncsim::scenario::drive_file_template(&urdf)
        .unwrap()
        .replace("# inertia_from_geometry = ", "inertia_from_geometry = ");
    let machine = Machine::parse(&urdf, &text, &drives).unwrap_or_else(|e| panic!("{e}"));
    // A 0.1 m box without its top face: its hull is the whole box, 2.7 kg of aluminium.
    let carriage = &machine.links[machine.link_index("x_carriage").unwrap()];
    assert!((carriage.mass - 2.7).abs() < 1e-6, "{}", carriage.mass);
    let warned: Vec<String> = machine.warnings.iter().map(|w| w.to_string()).collect();
    assert!(
        warned
            .iter()
            .any(|w| w.contains("box.stl is not closed") && w.contains("convex hull")),
        "{warned:#?}"
    );
    // The closed box weighs the same, without a word.
    let dir = probes().join("stl_closed_inertia_from_geometry");
    let urdf = dir.join("stl_closed_inertia_from_geometry.urdf");
    let machine = Machine::parse(&urdf, &std::fs::read_to_string(&urdf).unwrap(), &drives)
        .unwrap_or_else(|e| panic!("{e}"));
    let carriage = &machine.links[machine.link_index("x_carriage").unwrap()];
    assert!((carriage.mass - 2.7).abs() < 1e-6, "{}", carriage.mass);
    assert!(machine
        .warnings
        .iter()
        .all(|w| !w.to_string().contains("convex hull")));
}

/// Whether the Python cncsim runs xacro with has it (required in CI).
fn xacro_available() -> bool {
    let python = std::env::var("CNCSIM_PYTHON").unwrap_or_else(|_| "python3".into());
    let found = Command::new(python)
        .args(["-c", "import xacro"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        assert!(
            !common::required_in_ci(),
            "the xacro Python package is required in CI (CNCSIM_PYTHON)"
        );
        eprintln!("skipped: no xacro Python package (pip install xacro)");
    }
    found
}

#[test]
fn a_xacro_file_with_find_and_includes_is_expanded_without_ros() {
    if !xacro_available() {
        return;
    }
    // A ROS package as published: package.xml, a xacro that includes another through
    // `$(find mill_description)`, a macro, properties and a mesh by package:// URL.
    let dir = tempfile::tempdir().unwrap();
    let package = dir.path().join("src/mill_description");
    std::fs::create_dir_all(package.join("urdf")).unwrap();
    std::fs::create_dir_all(package.join("meshes")).unwrap();
    std::fs::write(
        package.join("package.xml"),
        "<?xml version=\"1.0\"?>\n<package format=\"3\"><name>mill_description</name><version>1.0.0</version></package>\n",
    )
    .unwrap();
    std::fs::copy(
        probes().join("stl_closed_inertia_from_geometry/box.stl"),
        package.join("meshes/box.stl"),
    )
    .unwrap();
    std::fs::write(
        package.join("urdf/parts.xacro"),
        r#"<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:property name="t" value="0.02"/>
  <xacro:macro name="slide" params="name mass">
    <link name="${name}">
      <inertial><mass value="${mass}"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
      <visual><geometry><mesh filename="package://mill_description/meshes/box.stl"/></geometry></visual>
    </link>
  </xacro:macro>
</robot>
"#,
    )
    .unwrap();
    let xacro = package.join("urdf/mill.urdf.xacro");
    std::fs::write(
        &xacro,
        r#"<?xml version="1.0"?>
<robot name="mill" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="$(find mill_description)/urdf/parts.xacro"/>
  <link name="base"><visual><origin xyz="0 0 ${-t/2}"/><geometry><box size="${t} ${t} ${t}"/></geometry></visual></link>
  <xacro:slide name="x_carriage" mass="${2*t*100}"/>
  <joint name="x" type="prismatic">
    <parent link="base"/><child link="x_carriage"/><axis xyz="1 0 0"/>
    <limit lower="-0.1" upper="0.1" effort="100" velocity="1"/>
  </joint>
</robot>
"#,
    )
    .unwrap();
    let tree = load_urdf(&xacro).unwrap_or_else(|e| panic!("{e}"));
    let carriage = tree.links.iter().find(|l| l.name == "x_carriage").unwrap();
    assert!((carriage.mass - 4.0).abs() < 1e-12, "{}", carriage.mass);
    assert!(matches!(
        carriage.visuals[0].shape,
        cncsim::machine::Shape::Mesh(_)
    ));
    let base = tree.links.iter().find(|l| l.name == "base").unwrap();
    assert!((base.visuals[0].pose.translation.z + 0.01).abs() < 1e-12);
    // `machine expand` prints the same URDF; the drive file sits beside the xacro.
    let out = Command::new(env!("CARGO_BIN_EXE_cncsim"))
        .args(["machine", "expand"])
        .arg(&xacro)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("<link name=\"x_carriage\">"));
    // The files a sweep ships for it: the xacro, what it includes, the mesh and the package.
    let drives = cncsim::scenario::drive_file_template(&xacro).unwrap();
    std::fs::write(xacro.with_extension("drives.toml"), drives).unwrap();
    let files = Machine::files(&xacro, &[]).unwrap_or_else(|e| panic!("{e}"));
    for needed in [
        "urdf/mill.urdf.xacro",
        "urdf/parts.xacro",
        "meshes/box.stl",
        "package.xml",
    ] {
        assert!(
            files.iter().any(|f| f.ends_with(needed)),
            "{needed} not in {files:#?}"
        );
    }
    // A package nobody can find: said, with what to do.
    std::fs::write(
        &xacro,
        std::fs::read_to_string(&xacro)
            .unwrap()
            .replace("$(find mill_description)", "$(find lathe_description)"),
    )
    .unwrap();
    let e = load_urdf(&xacro).unwrap_err().to_string();
    assert!(
        e.contains("lathe_description") && e.contains("--package-path"),
        "{e}"
    );
}

#[test]
fn a_frame_whose_geometry_gives_no_mass_is_said_even_where_it_may_stay_massless() {
    // inertia_from_geometry asked for, the frame's mesh not found: with the carriage's mass
    // beyond it the frame may stay massless, but not silently.
    let text = std::fs::read_to_string(probe("massless_between_slides"))
        .unwrap()
        .replace(
            "<link name=\"x_carriage\"/>",
            "<link name=\"x_carriage\"><collision><geometry><mesh filename=\"package://nowhere_pkg/box.stl\"/></geometry></collision></link>",
        );
    assert!(text.contains("nowhere_pkg"));
    let urdf = probe("massless_between_slides");
    let drives = cncsim::scenario::drive_file_template(&urdf)
        .unwrap()
        .replace("# inertia_from_geometry = ", "inertia_from_geometry = ");
    let machine = Machine::parse(&urdf, &text, &drives).unwrap_or_else(|e| panic!("{e}"));
    let warned: Vec<String> = machine.warnings.iter().map(|w| w.to_string()).collect();
    assert!(
        warned
            .iter()
            .any(|w| w.contains("massless_between_slides.urdf:4:3")
                && w.contains("inertia_from_geometry gives it no mass")
                && w.contains("nowhere_pkg")),
        "{warned:#?}"
    );
}
