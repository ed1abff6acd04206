//! What a link looks like: the URDF `<visual>` shapes as plain data (metres, link frame), mesh
//! files already read, so that the recording stage needs no file access.

use super::mesh::read_mesh;
use super::mesh_path::MeshFiles;
use nalgebra::{Isometry3, Vector3};
use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;

/// One `<visual>` of a link.
#[derive(Debug, Clone, PartialEq)]
pub struct Visual {
    /// Pose of the visual frame in the link frame (the shape's centre for primitives).
    pub pose: Isometry3<f64>,
    /// The geometry, in the visual frame.
    pub shape: Shape,
    /// RGBA colour, 0–1, from the visual's `<material>` (inline or named at robot level).
    pub color: Option<[f32; 4]>,
}

/// The geometry of a visual: a URDF primitive or a mesh (m).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// A box centred on the visual frame's origin, its edges along the frame's axes.
    Box {
        /// Half the box's size along x, y and z (m).
        half_extents: Vector3<f64>,
    },
    /// Axis along the visual frame's z, centred on its origin (URDF).
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Length along z (m).
        length: f64,
    },
    /// A cylinder of `length` along z with hemispherical caps (urdf-rs's `<capsule>` extension).
    Capsule {
        /// Radius of the cylinder and its caps (m).
        radius: f64,
        /// Length of the cylinder along z, without the caps (m).
        length: f64,
    },
    /// A sphere centred on the visual frame's origin.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// Shared: a machine is cloned per run and per recording, its meshes need not be.
    Mesh(Arc<TriangleMesh>),
}

/// A triangle mesh read from a file, in the visual frame (m), the URDF `scale` applied.
#[derive(Clone, PartialEq)]
pub struct TriangleMesh {
    /// The file it was read from.
    pub source: PathBuf,
    /// Vertex positions (m, visual frame).
    pub vertices: Vec<[f32; 3]>,
    /// Counter-clockwise seen from outside (front faces), as STL, OBJ and COLLADA give them.
    pub triangles: Vec<[u32; 3]>,
    /// Unit normal per vertex, where the file gives them for every vertex.
    pub normals: Option<Vec<[f32; 3]>>,
}

impl fmt::Debug for TriangleMesh {
    // A machine prints in test failures: counts, not a million vertices.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("TriangleMesh")
            .field("source", &self.source)
            .field("vertices", &self.vertices.len())
            .field("triangles", &self.triangles.len())
            .field("normals", &self.normals.is_some())
            .finish()
    }
}

/// The visuals of a URDF link. Shapes with impossible sizes are errors (the URDF is wrong);
/// a mesh file that is missing or unreadable is left out with a warning, returned beside the
/// visuals (the machine still loads and runs; only its picture is incomplete).
pub(super) fn visuals_from_urdf(
    visuals: &[urdf_rs::Visual],
    materials: &[urdf_rs::Material],
    files: &mut MeshFiles,
    pose: impl Fn(&urdf_rs::Pose) -> Result<Isometry3<f64>, String>,
) -> Result<(Vec<Visual>, Vec<String>), String> {
    let mut out = Vec::with_capacity(visuals.len());
    let mut warnings = Vec::new();
    for (i, v) in visuals.iter().enumerate() {
        let (pose, color) = (pose(&v.origin)?, color(v, materials)?);
        let which = match &v.name {
            Some(name) => format!("visual {i} ('{name}')"),
            None => format!("visual {i}"),
        };
        let positive = |what: &str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(value)
            } else {
                Err(format!(
                    "{which}: {what} {value:?} m: expected a positive size"
                ))
            }
        };
        let shape = match &v.geometry {
            urdf_rs::Geometry::Box { size } => {
                let s = Vector3::from(size.0);
                if !s.iter().all(|v| v.is_finite() && *v > 0.0) {
                    return Err(format!("box size {:?}: expected positive sizes", size.0));
                }
                Shape::Box {
                    half_extents: s / 2.0,
                }
            }
            urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
                radius: positive("cylinder radius", *radius)?,
                length: positive("cylinder length", *length)?,
            },
            urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
                radius: positive("capsule radius", *radius)?,
                length: positive("capsule length", *length)?,
            },
            urdf_rs::Geometry::Sphere { radius } => Shape::Sphere {
                radius: positive("sphere radius", *radius)?,
            },
            urdf_rs::Geometry::Mesh { filename, scale } => {
                let scale = scale.as_ref().map_or([1.0; 3], |s| s.0);
                if !scale.iter().all(|s| s.is_finite() && *s != 0.0) {
                    return Err(format!(
                        "{which}: mesh scale {scale:?}: expected three finite, non-zero factors"
                    ));
                }
                let found = match files.resolve(filename) {
                    Ok(found) => found,
                    Err(why) => {
                        warnings.push(format!("{which}: {why}; the link is drawn without it"));
                        continue;
                    }
                };
                match read_mesh(&found, scale) {
                    Ok(mesh) => Shape::Mesh(Arc::new(mesh)),
                    Err(why) => {
                        warnings.push(format!(
                            "{which}: mesh file {} (from \"{filename}\"): {why}; the link is drawn without it",
                            found.display()
                        ));
                        continue;
                    }
                }
            }
        };
        out.push(Visual { pose, shape, color });
    }
    Ok((out, warnings))
}

/// A visual's material gives its colour inline or names a robot-level material.
fn color(v: &urdf_rs::Visual, materials: &[urdf_rs::Material]) -> Result<Option<[f32; 4]>, String> {
    let color = v
        .material
        .as_ref()
        .and_then(|m| {
            m.color.as_ref().or_else(|| {
                materials
                    .iter()
                    .find(|d| d.name == m.name)
                    .and_then(|d| d.color.as_ref())
            })
        })
        .map(|c| c.rgba.0.map(|x| x as f32));
    if let Some(c) = color {
        if !c.iter().all(|x| (0.0..=1.0).contains(x)) {
            return Err(format!("colour rgba {c:?}: expected values from 0 to 1"));
        }
    }
    Ok(color)
}

#[cfg(test)]
mod tests {
    use super::super::mesh::tests::binary_stl;
    use super::super::urdf::parse_urdf_with_package_paths;
    use super::*;
    use std::path::Path;

    fn urdf(visuals: &str) -> String {
        format!(
            "<robot name=\"r\">\n  <material name=\"red\"><color rgba=\"1 0 0 1\"/></material>\n  <link name=\"base\">\n{visuals}  </link>\n</robot>\n"
        )
    }

    #[test]
    fn primitives_keep_their_pose_size_and_colour() {
        let text = urdf(
            "    <visual><origin xyz=\"0 0 0.1\"/><geometry><box size=\"0.2 0.4 0.6\"/></geometry><material name=\"red\"/></visual>\n\
             \x20   <visual name=\"shaft\"><origin xyz=\"1 0 0\" rpy=\"1.5707963267948966 0 0\"/><geometry><cylinder radius=\"0.05\" length=\"0.3\"/></geometry>\n\
             \x20     <material name=\"blue\"><color rgba=\"0 0 1 0.5\"/></material></visual>\n\
             \x20   <visual><geometry><sphere radius=\"0.02\"/></geometry></visual>\n",
        );
        let tree = parse_urdf_with_package_paths(Path::new("m.urdf"), &text, &[]).unwrap();
        assert!(tree.warnings.is_empty(), "{:?}", tree.warnings);
        let v = &tree.links[0].visuals;
        assert_eq!(v.len(), 3);
        assert_eq!(
            v[0].shape,
            Shape::Box {
                half_extents: Vector3::new(0.1, 0.2, 0.3)
            }
        );
        assert_eq!(v[0].color, Some([1.0, 0.0, 0.0, 1.0]));
        assert_eq!(v[0].pose.translation.vector, Vector3::new(0.0, 0.0, 0.1));
        assert_eq!(
            v[1].shape,
            Shape::Cylinder {
                radius: 0.05,
                length: 0.3
            }
        );
        assert_eq!(v[1].color, Some([0.0, 0.0, 1.0, 0.5]));
        // The cylinder's axis (visual z) lies along the link's -y after the roll of 90°.
        let axis = v[1].pose.rotation * Vector3::z();
        assert!(
            (axis - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12,
            "{axis}"
        );
        assert_eq!(v[2].shape, Shape::Sphere { radius: 0.02 });
        assert_eq!(v[2].color, None);

        let bad = urdf(
            "    <visual><geometry><cylinder radius=\"0\" length=\"0.3\"/></geometry></visual>\n",
        );
        let e = parse_urdf_with_package_paths(Path::new("m.urdf"), &bad, &[])
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "m.urdf:3:3: link 'base': visual 0: cylinder radius 0.0 m: expected a positive size"
        );
    }

    #[test]
    fn meshes_are_read_scaled_and_missing_or_broken_ones_are_warnings() {
        let ws = tempfile::tempdir().unwrap();
        let pkg = ws.path().join("mill_description");
        std::fs::create_dir_all(pkg.join("meshes")).unwrap();
        std::fs::create_dir_all(pkg.join("urdf")).unwrap();
        std::fs::write(
            pkg.join("package.xml"),
            "<package format=\"3\"><name>mill_description</name></package>",
        )
        .unwrap();
        std::fs::write(pkg.join("meshes/base.stl"), binary_stl()).unwrap();
        std::fs::write(
            pkg.join("meshes/broken.stl"),
            b"solid x\n  facet nonsense\n",
        )
        .unwrap();
        let text = urdf(
            "    <visual><geometry><mesh filename=\"package://mill_description/meshes/base.stl\" scale=\"0.001 0.001 0.001\"/></geometry><material name=\"red\"/></visual>\n\
             \x20   <visual><geometry><mesh filename=\"package://mill_description/meshes/gone.stl\"/></geometry></visual>\n\
             \x20   <visual><geometry><mesh filename=\"../meshes/broken.stl\"/></geometry></visual>\n\
             \x20   <visual><geometry><box size=\"1 1 1\"/></geometry></visual>\n",
        );
        let path = pkg.join("urdf/mill.urdf");
        std::fs::write(&path, &text).unwrap();
        let tree = parse_urdf_with_package_paths(&path, &text, &[]).unwrap();
        let v = &tree.links[0].visuals;
        // The two unusable meshes are left out; the box follows the mesh that loaded.
        assert_eq!(v.len(), 2, "{v:?}");
        let Shape::Mesh(mesh) = &v[0].shape else {
            panic!("{v:?}")
        };
        assert_eq!(mesh.triangles.len(), 4);
        assert_eq!(mesh.vertices.len(), 12);
        let largest = mesh
            .vertices
            .iter()
            .flatten()
            .fold(0.0f32, |a, &b| a.max(b));
        assert_eq!(largest, 0.001);
        assert_eq!(v[0].color, Some([1.0, 0.0, 0.0, 1.0]));
        assert!(matches!(v[1].shape, Shape::Box { .. }));

        let warnings: Vec<String> = tree.warnings.iter().map(|w| w.to_string()).collect();
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        // Located at the link, naming the file looked for and where it was looked for.
        let urdf_at = format!("{}:3:3: link 'base': visual 1: ", path.display());
        assert!(warnings[0].starts_with(&urdf_at), "{}", warnings[0]);
        assert!(
            warnings[0].contains("package 'mill_description' is")
                && warnings[0].contains("meshes/gone.stl")
                && warnings[0].ends_with("the link is drawn without it"),
            "{}",
            warnings[0]
        );
        assert!(
            warnings[1].contains("visual 2: mesh file ")
                && warnings[1].contains("broken.stl")
                && warnings[1].contains("not a valid STL file"),
            "{}",
            warnings[1]
        );
    }
}
