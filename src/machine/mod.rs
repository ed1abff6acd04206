//! Machine description: the URDF kinematic tree plus the drive data URDF has no element for.
//!
//! Everything here is plain data in SI units, read once at start-up and shared by the later
//! stages (kinematics, the physics model, the controllers). Nothing here knows about Rapier.

mod collada;
mod drives;
mod inertia;
mod joints;
mod mesh;
mod mesh_path;
mod urdf;
mod visual;
pub mod xacro;
mod xml_outline;

pub use drives::{
    AmplifierMode, Compliance, DcMotor, Drive, DrivesFile, Feedback, Guide, InertiaFromGeometry,
    JointMode, JointSetting, StribeckCurve, Tool, Transmission, Workpiece, AXIS_LETTERS,
    COMPLIANCE_RANGES, DENSITY_RANGE_KG_M3,
};
pub use joints::Undriven;
pub use mesh::{read_mesh, MAX_MESH_FILE_BYTES, MAX_MESH_TRIANGLES};
pub use mesh_path::{package_search_roots, ROS_PACKAGE_PATH};
pub use urdf::{
    load_urdf, load_urdf_with_package_paths, MAX_LINK_MASS_KG, MAX_MACHINE_SIZE_M,
    MAX_RADIUS_OF_GYRATION_M, MIN_BODY_MASS_KG, MIN_LINK_MASS_KG, SUSPECT_LINK_MASS_KG,
};
pub use visual::{Shape, TriangleMesh, Visual};
pub use xml_outline::{MAX_XML_DEPTH, MAX_XML_ELEMENTS};

use crate::diagnostics::{FileError, LineColumn};
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use std::path::{Path, PathBuf};

/// A solid of a link's geometry (its collision geometry, else its visual one), kept for
/// computing masses that the URDF leaves out (`inertia_from_geometry`).
#[derive(Debug, Clone, PartialEq)]
pub struct Solid {
    /// Pose of the shape's frame in the link frame.
    pub pose: Isometry3<f64>,
    /// The shape, in the shape's frame.
    pub shape: SolidShape,
}

/// The shape of a [`Solid`], as a URDF `<geometry>` gives it.
#[derive(Debug, Clone, PartialEq)]
pub enum SolidShape {
    /// A box centred on the shape frame's origin, aligned with its axes.
    Box {
        /// Half the box's size along x, y, z (m).
        half_extents: Vector3<f64>,
    },
    /// Along the shape frame's z axis, centred on its origin (URDF).
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Length along z (m).
        length: f64,
    },
    /// A sphere centred on the shape frame's origin.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// A mesh file, as the URDF names it, with its scale: read only when its volume is asked
    /// for (`inertia_from_geometry`).
    Mesh {
        /// The mesh file as the URDF writes it (a path or a `package://` URL).
        filename: String,
        /// Scale along x, y, z applied to the mesh's coordinates.
        scale: [f64; 3],
    },
}

/// A rigid link.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    /// The URDF link name.
    pub name: String,
    /// Mass (kg); zero only for massless frames such as the fixed base.
    pub mass: f64,
    /// Centre of mass in the link frame (m).
    pub center_of_mass: Point3<f64>,
    /// Inertia tensor about the centre of mass, in the link frame (kg·m²).
    pub inertia: Matrix3<f64>,
    /// What the link looks like (URDF `<visual>`s), in the file's order.
    pub visuals: Vec<Visual>,
    /// Its collision geometry, else its visual geometry.
    pub solids: Vec<Solid>,
    /// Where the link is declared in the URDF.
    pub place: Option<LineColumn>,
}

/// How a joint moves its child link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Does not move.
    Fixed,
    /// Slides along its axis (coordinate in m).
    Prismatic,
    /// Turns about its axis (coordinate in rad).
    Revolute,
}

/// A joint between two links, URDF semantics: the child frame sits at `origin` in the parent
/// frame when the joint coordinate is zero and moves along / about `axis` (child frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// The URDF joint name.
    pub name: String,
    /// How the joint moves.
    pub kind: JointKind,
    /// Index of the parent link.
    pub parent: usize,
    /// Index of the child link.
    pub child: usize,
    /// Pose of the child frame in the parent frame at joint coordinate zero.
    pub origin: Isometry3<f64>,
    /// Unit axis in the joint (child) frame.
    pub axis: Vector3<f64>,
    /// Travel limits (m or rad), if any.
    pub limits: Option<[f64; 2]>,
    /// Viscous damping of the guide or bearing itself (N·s/m or N·m·s/rad).
    pub damping: f64,
    /// Coulomb friction of the guide or bearing itself (N or N·m), URDF `<dynamics friction>`:
    /// acts only on a passive joint (a driven axis gets its friction from its guide contact).
    pub friction: f64,
    /// URDF `<mimic>`: this joint follows another one.
    pub mimic: Option<Mimic>,
    /// Where the joint is declared in the URDF.
    pub place: Option<LineColumn>,
}

/// A `<mimic>` follower: position = multiplier × leader position + offset.
#[derive(Debug, Clone, PartialEq)]
pub struct Mimic {
    /// Name of the joint followed.
    pub joint: String,
    /// Factor on the leader's position (1 when the URDF gives none).
    pub multiplier: f64,
    /// Added to the scaled leader position (m or rad; 0 when the URDF gives none).
    pub offset: f64,
}

/// A `<mimic>` follower on its own joint: q_follower = multiplier × q_leader + offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coupling {
    /// Index of the follower joint.
    pub follower: usize,
    /// Index of the leader joint (a driven or passive joint, never itself a follower).
    pub leader: usize,
    /// Factor on the leader's coordinate.
    pub multiplier: f64,
    /// Added to the scaled coordinate (m or rad).
    pub offset: f64,
}

/// A driven machine axis: a non-fixed joint with its drive.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Program letter of the axis (`x`, `y`, `z`, `a`, `b`, `c`).
    pub name: String,
    /// Index of the joint the axis drives.
    pub joint: usize,
    /// The axis's motor, amplifier and transmission.
    pub drive: Drive,
}

impl Joint {
    /// The child frame's motion relative to its zero pose at joint coordinate `q` (m or rad).
    pub fn motion(&self, q: f64) -> Isometry3<f64> {
        use nalgebra::{Translation3, Unit, UnitQuaternion};
        match self.kind {
            JointKind::Fixed => Isometry3::identity(),
            JointKind::Prismatic => Isometry3::from_parts(
                Translation3::from(self.axis * q),
                UnitQuaternion::identity(),
            ),
            JointKind::Revolute => Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Unit::new_normalize(self.axis), q),
            ),
        }
    }
}

impl Axis {
    /// Whether the axis drives a revolute joint (joint units rad, not m).
    pub fn is_rotary(&self, machine: &Machine) -> bool {
        machine.joints[self.joint].kind == JointKind::Revolute
    }
}

/// A machine: links, joints (parents before children), its driven axes and its tool.
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    /// The URDF `<robot name>`, or the URDF's file name without the extension.
    pub name: String,
    /// The URDF file it was loaded from.
    pub urdf_path: PathBuf,
    /// The links, indexed by the joints' `parent` and `child`.
    pub links: Vec<Link>,
    /// Joints ordered so that a joint's parent link is placed before its child.
    pub joints: Vec<Joint>,
    /// Index of the root link (the machine base).
    pub root: usize,
    /// The driven axes, in the machine's axis order.
    pub axes: Vec<Axis>,
    /// What became of each moving URDF joint no axis drives (locked ones are fixed joints
    /// now, followers of a driven axis ride on its link).
    pub undriven: Vec<(String, Undriven)>,
    /// Links whose mass and inertia were computed from their geometry
    /// (`inertia_from_geometry`), not read from the URDF.
    pub masses_from_geometry: Vec<String>,
    /// The tool point, as the drive file gives it.
    pub tool: Tool,
    /// Index of the tool link.
    pub tool_link: usize,
    /// Index of the link carrying the workpiece (the root unless the sidecar names one).
    pub workpiece_link: usize,
    /// Values of the URDF and drives file that load but look wrong, located in their file.
    pub warnings: Vec<FileError>,
}

impl Machine {
    /// Loads `path` (URDF) and its drive sidecar `<stem>.drives.toml` next to it.
    pub fn load(path: &Path) -> Result<Machine, FileError> {
        Self::load_with_package_paths(path, &[])
    }

    /// [`Machine::load`], looking for `package://` meshes also under `package_paths` (before
    /// `ROS_PACKAGE_PATH`).
    pub fn load_with_package_paths(
        path: &Path,
        package_paths: &[PathBuf],
    ) -> Result<Machine, FileError> {
        let tree = load_urdf_with_package_paths(path, package_paths)?;
        let drives_path = DrivesFile::path_for(path);
        if !drives_path.exists() {
            return Err(FileError::new(
                &drives_path,
                None,
                format!(
                    "no drive file: a machine's drive data (motors, transmissions, tool) lives in a file next to its URDF, named after it with .drives.toml for the URDF's extension; `cncsim machine init {}` writes one to fill in",
                    path.display()
                ),
            ));
        }
        let drives = DrivesFile::load(&drives_path)?;
        drives.attach(tree, &drives_path)
    }

    /// Every file [`Machine::load_with_package_paths`] reads for the machine at `path`: the
    /// URDF (a xacro file with every file it includes), its drive file, the meshes of its
    /// visuals and solids, and the `package.xml` of the package each mesh lies in (what
    /// `package://` is resolved through). What a run needs
    /// copied to a machine that has none of them (a Ray worker).
    pub fn files(path: &Path, package_paths: &[PathBuf]) -> Result<Vec<PathBuf>, FileError> {
        let tree = load_urdf_with_package_paths(path, package_paths)?;
        let mut meshes = mesh_path::MeshFiles::new(path, package_search_roots(package_paths));
        let mut files = vec![path.to_path_buf(), DrivesFile::path_for(path)];
        let included = if xacro::is_xacro(path) {
            xacro::dependencies(path, &package_search_roots(package_paths))?
        } else {
            Vec::new()
        };
        for link in &tree.links {
            for visual in &link.visuals {
                if let Shape::Mesh(mesh) = &visual.shape {
                    files.push(mesh.source.clone());
                }
            }
            for solid in &link.solids {
                if let SolidShape::Mesh { filename, .. } = &solid.shape {
                    // A solid whose mesh is missing is an error only where its mass is needed.
                    files.extend(meshes.resolve(filename).ok());
                }
            }
        }
        files.extend(included);
        // The package each file lies in: what `package://` and `$(find …)` are resolved by.
        let manifests: Vec<PathBuf> = files
            .iter()
            .filter_map(|file| {
                file.ancestors()
                    .skip(1)
                    .map(|dir| dir.join("package.xml"))
                    .find(|manifest| manifest.is_file())
            })
            .collect();
        files.extend(manifests);
        // A drive file not written yet is not read.
        files.retain(|f| f.is_file());
        files.sort();
        files.dedup();
        Ok(files)
    }

    /// [`Machine::load`] on texts in memory, reported as if read from `path` and its sidecar.
    pub fn parse(path: &Path, urdf: &str, drives: &str) -> Result<Machine, FileError> {
        let tree = urdf::parse_urdf(path, urdf)?;
        let drives_path = DrivesFile::path_for(path);
        DrivesFile::parse(&drives_path, drives)?.attach(tree, &drives_path)
    }

    /// Indices of the joints no axis drives that move freely (`mode = "passive"`).
    pub fn passive_joints(&self) -> Vec<usize> {
        self.undriven
            .iter()
            .filter(|(_, what)| *what == Undriven::Passive)
            .filter_map(|(name, _)| self.joints.iter().position(|j| &j.name == name))
            .collect()
    }

    /// The `<mimic>` followers on joints of their own ([`Undriven::Coupled`]), in the URDF's
    /// order: each follows the first leader of its chain, a driven or passive joint.
    pub fn couplings(&self) -> Vec<Coupling> {
        let index = |name: &str| self.joints.iter().position(|j| j.name == name);
        self.undriven
            .iter()
            .filter_map(|(name, what)| match what {
                Undriven::Coupled {
                    leader,
                    multiplier,
                    offset,
                } => Some(Coupling {
                    follower: index(name)?,
                    leader: index(leader)?,
                    multiplier: *multiplier,
                    offset: *offset,
                }),
                _ => None,
            })
            .collect()
    }

    /// The first `<mimic>` follower on a joint of its own whose leader is an axis with backlash
    /// or a compliant transmission, as (follower joint, axis): the leader's coordinate (the
    /// carriage's) is then the sum of two bodies' motions, which neither the physics' equality
    /// constraint nor the reference model follows.
    pub fn follower_of_split_drive(&self) -> Option<(String, String)> {
        self.couplings().into_iter().find_map(|c| {
            let axis = self.axes.iter().find(|a| a.joint == c.leader)?;
            (axis.drive.backlash > 0.0 || axis.drive.compliance().is_some())
                .then(|| (self.joints[c.follower].name.clone(), axis.name.clone()))
        })
    }

    /// Every joint's coordinate (m or rad, in `joints` order) for the axes at `q` (axis order):
    /// the axes' joints at their coordinate, `<mimic>` followers where their leader puts them,
    /// every other joint (fixed, passive) at zero.
    pub fn joint_coordinates(&self, q: &[f64]) -> Vec<f64> {
        let mut value = vec![0.0; self.joints.len()];
        for (axis, &v) in self.axes.iter().zip(q) {
            value[axis.joint] = v;
        }
        for c in self.couplings() {
            value[c.follower] = c.multiplier * value[c.leader] + c.offset;
        }
        value
    }

    /// Index of the axis with program letter `name`, if the machine has it.
    pub fn axis_index(&self, name: &str) -> Option<usize> {
        self.axes.iter().position(|a| a.name == name)
    }

    /// Index of the link named `name`, if any.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.links.iter().position(|l| l.name == name)
    }

    /// Whether each link is `link` or below it (joints are ordered parents first, so one
    /// pass finds the subtree).
    pub fn subtree(&self, link: usize) -> Vec<bool> {
        let mut below = vec![false; self.links.len()];
        below[link] = true;
        for joint in &self.joints {
            if below[joint.parent] {
                below[joint.child] = true;
            }
        }
        below
    }

    /// Joint index whose child is `link`, if any (none for the root).
    pub fn parent_joint(&self, link: usize) -> Option<usize> {
        self.joints.iter().position(|j| j.child == link)
    }
}

/// The URDF part of a machine, before drives are attached.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicTree {
    /// The URDF `<robot name>`, or the file name without the extension.
    pub name: String,
    /// The URDF file.
    pub path: PathBuf,
    /// The URDF's text as read.
    pub text: String,
    /// The links, in the file's order.
    pub links: Vec<Link>,
    /// The joints, parents before children.
    pub joints: Vec<Joint>,
    /// Index of the root link.
    pub root: usize,
    /// Values that load but look wrong (e.g. a 10 t carriage), located in the file.
    pub warnings: Vec<FileError>,
}
