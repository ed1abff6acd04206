//! A machine drawn with meshes and primitives: the bundled XYZ table with an STL part, a sphere
//! and a mesh that is not there added to its base, loaded and recorded; the recording read back
//! holds each shape at its `visual_<i>` entity.

mod common;

use cncsim::machine::{Machine, Shape};
use cncsim::report::{AxisLabel, RecordingSetup, RrdWriter};
use common::{cncsim, rrd_components, stderr};
use std::path::PathBuf;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A binary STL of a tetrahedron with 1000-unit edges (millimetres): 4 triangles, 12 corners.
fn tetrahedron_stl() -> Vec<u8> {
    let corners = [
        [0.0f32, 0.0, 0.0],
        [1000.0, 0.0, 0.0],
        [0.0, 1000.0, 0.0],
        [0.0, 0.0, 1000.0],
    ];
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut out = vec![0u8; 80];
    out.extend_from_slice(&(faces.len() as u32).to_le_bytes());
    for f in faces {
        out.extend_from_slice(&[0u8; 12]);
        for k in f {
            for x in corners[k] {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
        out.extend_from_slice(&[0, 0]);
    }
    out
}

#[test]
fn a_machine_with_mesh_and_primitive_visuals_is_recorded_with_each_shape() {
    let dir = tempfile::tempdir().unwrap();
    let models = root().join("models");
    let urdf = std::fs::read_to_string(models.join("xyz_table.urdf")).unwrap();
    let added = "    <visual>\n      <origin xyz=\"0 0 0.1\"/>\n      <geometry><mesh filename=\"meshes/part.stl\" scale=\"0.001 0.001 0.001\"/></geometry>\n      <material name=\"frame\"/>\n    </visual>\n\
                 \x20   <visual><geometry><sphere radius=\"0.05\"/></geometry></visual>\n\
                 \x20   <visual><geometry><mesh filename=\"meshes/not_there.stl\"/></geometry></visual>\n  </link>\n\n  <!-- X carriage";
    let urdf = urdf.replacen("  </link>\n\n  <!-- X carriage", added, 1);
    assert!(
        urdf.contains("part.stl"),
        "the base link's end was not found"
    );
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    std::fs::write(dir.path().join("meshes/part.stl"), tetrahedron_stl()).unwrap();
    let path = dir.path().join("xyz_table.urdf");
    std::fs::write(&path, urdf).unwrap();
    std::fs::copy(
        models.join("xyz_table.drives.toml"),
        dir.path().join("xyz_table.drives.toml"),
    )
    .unwrap();

    let machine = Machine::load(&path).unwrap();
    let warnings: Vec<String> = machine.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("link 'base': visual 3: mesh \"meshes/not_there.stl\": no file")
            && warnings[0].contains("not_there.stl"),
        "{warnings:?}"
    );
    let base = &machine.links[machine.link_index("base").unwrap()];
    assert_eq!(base.visuals.len(), 3);
    let Shape::Mesh(mesh) = &base.visuals[1].shape else {
        panic!("{:?}", base.visuals)
    };
    assert_eq!(mesh.vertices.len(), 12);

    let labels: Vec<AxisLabel> = machine
        .axes
        .iter()
        .map(|a| AxisLabel {
            name: a.name.clone(),
            rotary: a.is_rotary(&machine),
        })
        .collect();
    let setup = RecordingSetup {
        name: "meshes",
        machine: &machine,
        labels: &labels,
        dc_motor: false,
        decimation: 1,
        lanes: &[cncsim::sim::LaneKind::Physics],
        programmed_path: vec![[0.0; 3], [0.01, 0.0, 0.0]],
        variant: None,
        stock_frame: None,
        duration: 0.0,
    };
    let rrd = dir.path().join("run.rrd");
    RrdWriter::create(&rrd, &setup)
        .unwrap()
        .finish("# meshes")
        .unwrap();
    let all = rrd_components(&rrd);
    let at = |entity: &str, component: &str| {
        all.get(entity)
            .and_then(|c| c.iter().find(|(n, _)| n == component))
            .map(|(_, count)| *count)
            .unwrap_or_else(|| panic!("no {component} at {entity}: {:?}", all.get(entity)))
    };
    // The box stays where it was; the mesh, the sphere follow in the file's order.
    assert_eq!(at("/world/machine/base/visual_0", "Boxes3D:half_sizes"), 1);
    assert_eq!(
        at("/world/machine/base/visual_1", "Mesh3D:vertex_positions"),
        12
    );
    assert_eq!(
        at("/world/machine/base/visual_1", "Mesh3D:triangle_indices"),
        4
    );
    assert_eq!(
        at("/world/machine/base/visual_1", "Mesh3D:albedo_factor"),
        1
    );
    assert_eq!(
        at("/world/machine/base/visual_2", "Ellipsoids3D:half_sizes"),
        1
    );
    assert!(!all.contains_key("/world/machine/base/visual_3"));
    assert_eq!(
        at("/world/machine/base/visual_1", "Transform3D:translation"),
        1
    );
}

/// `package://` meshes of a package that lies neither above the URDF nor on
/// `ROS_PACKAGE_PATH` are found through `--package-path`, and named in a warning without it.
#[test]
fn package_meshes_are_found_through_the_package_path_option() {
    let dir = tempfile::tempdir().unwrap();
    let models = root().join("models");
    let (machine_dir, workspace) = (dir.path().join("machine"), dir.path().join("ws"));
    let package = workspace.join("src/tetra_parts");
    std::fs::create_dir_all(&machine_dir).unwrap();
    std::fs::create_dir_all(package.join("meshes")).unwrap();
    std::fs::write(
        package.join("package.xml"),
        "<?xml version=\"1.0\"?>\n<package format=\"2\"><name>tetra_parts</name><version>1.0.0</version></package>\n",
    )
    .unwrap();
    std::fs::write(package.join("meshes/part.stl"), tetrahedron_stl()).unwrap();
    let urdf = std::fs::read_to_string(models.join("xyz_table.urdf")).unwrap();
    let added = "    <visual><geometry><mesh filename=\"package://tetra_parts/meshes/part.stl\" scale=\"0.001 0.001 0.001\"/></geometry></visual>\n  </link>\n\n  <!-- X carriage";
    let urdf = urdf.replacen("  </link>\n\n  <!-- X carriage", added, 1);
    assert!(
        urdf.contains("tetra_parts"),
        "the base link's end was not found"
    );
    let path = machine_dir.join("xyz_table.urdf");
    std::fs::write(&path, urdf).unwrap();
    std::fs::copy(
        models.join("xyz_table.drives.toml"),
        machine_dir.join("xyz_table.drives.toml"),
    )
    .unwrap();
    let path = path.to_str().unwrap();

    let check = |extra: &[&str]| {
        let mut args = vec!["machine", "check", path];
        args.extend_from_slice(extra);
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_cncsim"))
            .args(&args)
            .env_remove("ROS_PACKAGE_PATH")
            .output()
            .unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            stderr(&out),
        )
    };
    // The report's warnings (on either stream) that name the package.
    let warned = |out: &str| {
        out.lines()
            .any(|l| l.starts_with("warning:") && l.contains("tetra_parts"))
    };
    let (status, text, errors) = check(&[]);
    assert_eq!(status, Some(0), "{errors}");
    assert!(
        (warned(&text) || warned(&errors)) && !text.contains("(4 triangles)"),
        "without the option the package is not found: {text}\n{errors}"
    );
    let ws = workspace.to_str().unwrap();
    let (status, text, errors) = check(&["--package-path", ws]);
    assert_eq!(status, Some(0), "{errors}");
    assert!(
        text.contains("part.stl (4 triangles)") && !warned(&text) && !warned(&errors),
        "with --package-path the mesh is drawn: {text}\n{errors}"
    );
    // A directory that is not there is bad input, named.
    let o = cncsim(&["machine", "check", path, "--package-path", "/no/such/dir"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--package-path /no/such/dir: no such directory"),
        "{}",
        stderr(&o)
    );
}
