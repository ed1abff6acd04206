//! URDF → [`KinematicTree`], with the checks a physics model needs (positive masses,
//! physical inertias, one root, supported joint types) reported against the file.
//!
//! Plausibility limits (a machine tool, not a planet or a dust grain); values outside are
//! refused, values in the suspect band load with a warning:
//!
//! | quantity | refused | warned |
//! |---|---|---|
//! | link mass | < 1e-12 kg or > 100 t (a moving body: < 1 mg) | > 5 t |
//! | radius of gyration √(I_max/m) | > 10 m | |
//! | joint origin, prismatic travel limits | beyond 100 m | |

use super::mesh_path::{package_search_roots, MeshFiles};
use super::visual::visuals_from_urdf;
use super::xml_outline::outline;
use super::{Joint, JointKind, KinematicTree, Link, Mimic, Solid, SolidShape};
use crate::diagnostics::{FileError, LineColumn};
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use std::path::{Path, PathBuf};

/// Lightest mass a link may have (kg), unless it is a massless frame (mass 0). CAD exporters
/// give frame links placeholder masses down to 1e-9 kg; harmless where the link rides on a
/// body with mass, which [`MIN_BODY_MASS_KG`] is about.
pub const MIN_LINK_MASS_KG: f64 = 1e-12;
/// Lightest body a joint may move (kg): a link and the links fixed to it.
pub const MIN_BODY_MASS_KG: f64 = 1e-6;
/// Heaviest mass a link may have (kg).
pub const MAX_LINK_MASS_KG: f64 = 1e5;
/// Above this a link loads with a warning (kg).
pub const SUSPECT_LINK_MASS_KG: f64 = 5e3;
/// Largest radius of gyration of a link (m): inertia and mass must describe a body of machine
/// size.
pub const MAX_RADIUS_OF_GYRATION_M: f64 = 10.0;
/// Inertia below any machine part's (a gram at 30 µm): moments this small are a point mass's,
/// whatever their sign and proportions after an exporter's round-off.
const NEGLIGIBLE_INERTIA_KG_M2: f64 = 1e-12;
/// Largest distance a joint origin or a prismatic limit may give (m).
pub const MAX_MACHINE_SIZE_M: f64 = 100.0;

/// Reads and validates a URDF file.
pub fn load_urdf(path: &Path) -> Result<KinematicTree, FileError> {
    load_urdf_with_package_paths(path, &[])
}

/// [`load_urdf`], looking for `package://` meshes also under `package_paths` (searched before
/// `ROS_PACKAGE_PATH`). A mesh that cannot be found or read is a warning, not an error.
pub fn load_urdf_with_package_paths(
    path: &Path,
    package_paths: &[PathBuf],
) -> Result<KinematicTree, FileError> {
    if super::xacro::is_xacro(path) {
        // Expanded first; its places are those of the expansion (`machine expand` prints it).
        let expanded = super::xacro::expand(path, &package_search_roots(package_paths))?;
        return parse_urdf_with_package_paths(path, &expanded, package_paths).map_err(|mut e| {
            if e.path == path && e.at.is_some() {
                e.message += &format!(
                    " (the place is in the xacro's expansion: `cncsim machine expand {}` prints it)",
                    path.display()
                );
            }
            e
        });
    }
    let text = crate::diagnostics::read_xml_text(path, "machine model (URDF)")?;
    parse_urdf_with_package_paths(path, &text, package_paths)
}

pub(crate) fn parse_urdf(path: &Path, text: &str) -> Result<KinematicTree, FileError> {
    parse_urdf_with_package_paths(path, text, &[])
}

pub(crate) fn parse_urdf_with_package_paths(
    path: &Path,
    text: &str,
    package_paths: &[PathBuf],
) -> Result<KinematicTree, FileError> {
    if !super::xacro::is_xacro(path) {
        refuse_xacro(path, text)?;
    }
    // Bounded, located checks first: the recursive reader behind urdf-rs must never see an
    // unbounded nesting, and its messages carry no position.
    let places = outline(path, text)?;
    // What urdfdom reads past (comments, repeated elements, unknown shapes, empty textures)
    // is read as blank space of the same length, so places stay where they were.
    let blanked = blank(text, &places.ignored);
    let text_for_reader = blanked.as_str();
    let robot = urdf_rs::read_from_string(text_for_reader).map_err(|e| {
        FileError::new(
            path,
            None,
            format!("not a valid URDF document: {}", one_line(&e.to_string())),
        )
    })?;
    let element = |kind: &str, name: &str| -> Option<LineColumn> {
        match kind {
            "link" => places.links.get(name).copied(),
            _ => places.joints.get(name).copied(),
        }
    };
    let err = |kind: &str, name: &str, msg: String| FileError::new(path, element(kind, name), msg);
    let mut warnings = places.warnings.clone();

    if robot.links.is_empty() {
        return Err(FileError::new(path, None, "the URDF has no <link>"));
    }
    let mut links = Vec::with_capacity(robot.links.len());
    let mut mesh_files = MeshFiles::new(path, package_search_roots(package_paths));
    for l in &robot.links {
        let (mut link, visual_warnings) = link_from_urdf(l, &robot.materials, &mut mesh_files)
            .map_err(|m| err("link", &l.name, format!("link '{}': {m}", l.name)))?;
        link.place = element("link", &l.name);
        warnings.extend(
            visual_warnings
                .into_iter()
                .map(|m| err("link", &l.name, format!("link '{}': {m}", l.name))),
        );
        if link.mass > SUSPECT_LINK_MASS_KG {
            warnings.push(err(
                "link",
                &l.name,
                format!(
                    "link '{}': mass {:?} kg is more than {SUSPECT_LINK_MASS_KG:?} kg: is it in kg?",
                    l.name, link.mass
                ),
            ));
        }
        links.push(link);
    }
    for (i, l) in links.iter().enumerate() {
        if links[..i].iter().any(|o| o.name == l.name) {
            return Err(err(
                "link",
                &l.name,
                format!("link name '{}' is used twice", l.name),
            ));
        }
    }

    let find_link = |name: &str| links.iter().position(|l| l.name == name);
    let mut joints = Vec::with_capacity(robot.joints.len());
    for j in &robot.joints {
        let e = |m: String| err("joint", &j.name, format!("joint '{}': {m}", j.name));
        let parent = find_link(&j.parent.link)
            .ok_or_else(|| e(format!("parent link '{}' does not exist", j.parent.link)))?;
        let child = find_link(&j.child.link)
            .ok_or_else(|| e(format!("child link '{}' does not exist", j.child.link)))?;
        let kind = match j.joint_type {
            urdf_rs::JointType::Fixed => JointKind::Fixed,
            urdf_rs::JointType::Prismatic => JointKind::Prismatic,
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => JointKind::Revolute,
            ref other => {
                return Err(e(format!(
                    "joint type {other:?} is not supported (expected fixed, prismatic, revolute or continuous)"
                )))
            }
        };
        let axis = Vector3::from(j.axis.xyz.0);
        if kind != JointKind::Fixed && !(axis.norm() > 1e-9 && axis.iter().all(|v| v.is_finite())) {
            return Err(e(format!("axis {:?} is not a direction", j.axis.xyz.0)));
        }
        let limits = match (kind, &j.joint_type) {
            (JointKind::Fixed, _) | (_, urdf_rs::JointType::Continuous) => None,
            _ => {
                let (lo, hi) = (j.limit.lower, j.limit.upper);
                if lo == 0.0 && hi == 0.0 {
                    // No <limit lower upper> (urdf-rs reads them as 0, 0) is unlimited, as
                    // Drake and MuJoCo read it; so is 0, 0 written out, which the SolidWorks
                    // exporter writes for a joint without limits.
                    let what = if places.bounded.contains(&j.name) {
                        "<limit lower=\"0\" upper=\"0\"> (as CAD exporters write for a joint without limits)"
                    } else {
                        "no <limit lower=\"…\" upper=\"…\"/>"
                    };
                    warnings.push(e(format!(
                        "has {what}: read as a joint without travel limits"
                    )));
                    None
                } else if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                    return Err(e(format!(
                        "limits lower={lo:?} upper={hi:?}: expected finite lower < upper"
                    )));
                } else if kind == JointKind::Prismatic
                    && lo.abs().max(hi.abs()) > MAX_MACHINE_SIZE_M
                {
                    return Err(e(format!(
                        "limits lower={lo:?} upper={hi:?} m: expected a travel within ±{MAX_MACHINE_SIZE_M:?} m"
                    )));
                } else {
                    Some([lo, hi])
                }
            }
        };
        let damping = j.dynamics.as_ref().map_or(0.0, |d| d.damping);
        let friction = j.dynamics.as_ref().map_or(0.0, |d| d.friction);
        for (name, value) in [("damping", damping), ("friction", friction)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(e(format!(
                    "<dynamics {name}=\"{value:?}\">: expected a finite value ≥ 0"
                )));
            }
        }
        let mimic = match &j.mimic {
            None => None,
            Some(m) => {
                let multiplier = m.multiplier.unwrap_or(1.0);
                let offset = m.offset.unwrap_or(0.0);
                if !(multiplier.is_finite() && offset.is_finite()) {
                    return Err(e(format!(
                        "<mimic multiplier=\"{multiplier:?}\" offset=\"{offset:?}\">: expected finite numbers"
                    )));
                }
                if robot.joints.iter().all(|o| o.name != m.joint) {
                    // urdfdom loads it and nothing follows; here too, said once.
                    let names: Vec<&str> = robot.joints.iter().map(|o| o.name.as_str()).collect();
                    warnings.push(e(format!(
                        "<mimic joint=\"{}\">: no joint of that name (the joints: {}): the mimic is ignored, and joint '{}' is a joint of its own",
                        m.joint,
                        names.join(", "),
                        j.name
                    )));
                    None
                } else {
                    Some(Mimic {
                        joint: m.joint.clone(),
                        multiplier,
                        offset,
                    })
                }
            }
        };
        joints.push(Joint {
            name: j.name.clone(),
            kind,
            parent,
            child,
            origin: pose(&j.origin).map_err(e)?,
            axis: if kind == JointKind::Fixed {
                Vector3::z()
            } else {
                axis.normalize()
            },
            limits,
            damping,
            friction,
            mimic,
            place: element("joint", &j.name),
        });
    }

    // A tree: every link but one has exactly one parent joint, and no cycles.
    let mut parent_count = vec![0usize; links.len()];
    for j in &joints {
        parent_count[j.child] += 1;
        if parent_count[j.child] > 1 {
            let name = &links[j.child].name;
            return Err(err(
                "joint",
                &j.name,
                format!(
                    "link '{name}' has more than one parent joint (closed loops are not supported)"
                ),
            ));
        }
    }
    let roots: Vec<usize> = (0..links.len()).filter(|&i| parent_count[i] == 0).collect();
    if roots.len() != 1 {
        let names: Vec<&str> = roots.iter().map(|&i| links[i].name.as_str()).collect();
        return Err(FileError::new(
            path,
            None,
            format!("expected exactly one root link, found {}: {:?} (every other link needs a parent joint)", roots.len(), names),
        ));
    }
    let root = roots[0];
    let ordered = order_parents_first(&joints, root, links.len()).map_err(|cycle| {
        let names: Vec<String> = cycle.iter().map(|&i| format!("'{}'", joints[i].name)).collect();
        let first = &joints[cycle[0]].name;
        err(
            "joint",
            first,
            format!(
                "the joints {} form a cycle (each link's parent joint leads back to the first): a machine must be a tree of links",
                names.join(" → ")
            ),
        )
    })?;
    let joints: Vec<Joint> = ordered.into_iter().map(|i| joints[i].clone()).collect();

    // Inertias that no rigid body has are refused where they move; on the base and the links
    // fixed to it (which never move here) they are not used, and only warned of.
    let mut on_base = vec![false; links.len()];
    on_base[root] = true;
    for j in joints.iter().filter(|j| j.kind == JointKind::Fixed) {
        on_base[j.child] = on_base[j.parent];
    }
    for ((l, link), fixed) in robot.links.iter().zip(&links).zip(&on_base) {
        let Err(problem) = physical_inertia(l) else {
            continue;
        };
        let problem = err(
            "link",
            &link.name,
            format!("link '{}': {problem}", link.name),
        );
        if *fixed {
            warnings.push(FileError::new(
                path,
                problem.at,
                format!(
                    "{}; the link is fixed to the base, which does not move, so it is not used",
                    problem.message
                ),
            ));
        } else {
            return Err(problem);
        }
    }

    // `<robot name>` is required by the URDF schema, but readers (MuJoCo's among them) take a
    // file without it; the file's stem stands in.
    let name = if robot.name.is_empty() {
        path.file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
    } else {
        robot.name
    };
    Ok(KinematicTree {
        name,
        path: path.to_path_buf(),
        text: text.to_string(),
        links,
        joints,
        root,
        warnings,
    })
}

/// Joint indices with every parent link placed before its children, keeping the file's order
/// wherever it already is (so axes come out in the order the URDF lists them). With one root
/// and one parent joint per link, a link the root cannot reach lies on a cycle: the error is
/// that cycle's joints.
pub(super) fn order_parents_first(
    joints: &[Joint],
    root: usize,
    n_links: usize,
) -> Result<Vec<usize>, Vec<usize>> {
    let mut placed = vec![false; n_links];
    placed[root] = true;
    let mut taken = vec![false; joints.len()];
    let mut order = Vec::with_capacity(joints.len());
    while order.len() < joints.len() {
        let before = order.len();
        for (i, j) in joints.iter().enumerate() {
            if !taken[i] && placed[j.parent] {
                taken[i] = true;
                placed[j.child] = true;
                order.push(i);
            }
        }
        if order.len() == before {
            let stuck = (0..joints.len())
                .find(|&i| !taken[i])
                .expect("some joint is left");
            return Err(cycle_through(joints, stuck));
        }
    }
    Ok(order)
}

/// The cycle reached by walking up parent joints from joint `start` (every link has at most one
/// parent joint, so the walk ends on a cycle or at the root; here the root is out of reach).
fn cycle_through(joints: &[Joint], start: usize) -> Vec<usize> {
    let parent_joint = |link: usize| joints.iter().position(|j| j.child == link);
    let mut path = vec![start];
    let mut current = start;
    // At most one step per joint before a joint repeats.
    for _ in 0..joints.len() {
        let Some(up) = parent_joint(joints[current].parent) else {
            break;
        };
        if let Some(at) = path.iter().position(|&j| j == up) {
            let mut cycle = path.split_off(at);
            cycle.reverse();
            return cycle;
        }
        path.push(up);
        current = up;
    }
    path
}

/// The link, and warnings about visuals left out (mesh files missing or unreadable).
fn link_from_urdf(
    l: &urdf_rs::Link,
    materials: &[urdf_rs::Material],
    mesh_files: &mut MeshFiles,
) -> Result<(Link, Vec<String>), String> {
    let m = l.inertial.mass.value;
    let i = &l.inertial.inertia;
    let frame = pose(&l.inertial.origin)?;
    let local = Matrix3::new(
        i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
    );
    if !(m.is_finite() && m >= 0.0) {
        return Err(format!("mass {m:?} kg: expected a finite mass ≥ 0"));
    }
    if m > 0.0 && !(MIN_LINK_MASS_KG..=MAX_LINK_MASS_KG).contains(&m) {
        return Err(format!(
            "mass {m:?} kg: expected 0 (a massless frame) or a mass from {MIN_LINK_MASS_KG:?} to {MAX_LINK_MASS_KG:?} kg"
        ));
    }
    if !local.iter().all(|v| v.is_finite()) {
        return Err("inertia has a non-finite entry".into());
    }
    if m > 0.0 {
        let largest = local.symmetric_eigenvalues().max();
        let gyration = (largest / m).sqrt();
        if gyration > MAX_RADIUS_OF_GYRATION_M {
            return Err(format!(
                "inertia {largest:.4e} kg·m² on a mass of {m:?} kg is a radius of gyration of {gyration:.3e} m: expected at most {MAX_RADIUS_OF_GYRATION_M:?} m (are mass and inertia in kg and kg·m²?)"
            ));
        }
    }
    // Inertia expressed in the link frame (the inertial frame may be rotated).
    let r = frame.rotation.to_rotation_matrix();
    let inertia = r.matrix() * local * r.matrix().transpose();
    let (visuals, warnings) = visuals_from_urdf(&l.visual, materials, mesh_files, pose)?;
    let link = Link {
        name: l.name.clone(),
        mass: m,
        center_of_mass: Point3::from(frame.translation.vector),
        inertia,
        visuals,
        solids: solids_of(l)?,
        place: None,
    };
    Ok((link, warnings))
}

/// The link's collision geometry, else its visual geometry, as solids.
fn solids_of(l: &urdf_rs::Link) -> Result<Vec<Solid>, String> {
    let collision = l.collision.iter().map(|c| (&c.origin, &c.geometry));
    let visual = l.visual.iter().map(|v| (&v.origin, &v.geometry));
    let shapes: Vec<_> = if l.collision.is_empty() {
        visual.collect()
    } else {
        collision.collect()
    };
    let positive = |what: &str, v: f64| {
        if v.is_finite() && v > 0.0 && v <= MAX_MACHINE_SIZE_M {
            Ok(v)
        } else {
            Err(format!(
                "{what} {v:?} m: expected a positive size up to {MAX_MACHINE_SIZE_M:?} m"
            ))
        }
    };
    shapes
        .into_iter()
        .map(|(origin, geometry)| {
            let shape = match geometry {
                urdf_rs::Geometry::Box { size } => {
                    for v in size.0 {
                        positive("box size", v)?;
                    }
                    SolidShape::Box {
                        half_extents: Vector3::from(size.0) / 2.0,
                    }
                }
                urdf_rs::Geometry::Cylinder { radius, length }
                | urdf_rs::Geometry::Capsule { radius, length } => SolidShape::Cylinder {
                    radius: positive("cylinder radius", *radius)?,
                    length: positive("cylinder length", *length)?,
                },
                urdf_rs::Geometry::Sphere { radius } => SolidShape::Sphere {
                    radius: positive("sphere radius", *radius)?,
                },
                urdf_rs::Geometry::Mesh { filename, scale } => SolidShape::Mesh {
                    filename: filename.clone(),
                    scale: scale.as_ref().map_or([1.0; 3], |s| s.0),
                },
            };
            Ok(Solid {
                pose: pose(origin)?,
                shape,
            })
        })
        .collect()
}

/// A link's `<inertial>` as a rigid body can have it.
fn physical_inertia(l: &urdf_rs::Link) -> Result<(), String> {
    let m = l.inertial.mass.value;
    let i = &l.inertial.inertia;
    let local = Matrix3::new(
        i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
    );
    if m > 0.0 {
        check_physical_inertia(&local)
    } else if local.norm() > 0.0 {
        Err("has inertia but zero mass".into())
    } else {
        Ok(())
    }
}

/// Principal moments positive and obeying the triangle inequality (a real body's inertia).
fn check_physical_inertia(i: &Matrix3<f64>) -> Result<(), String> {
    let eig = i.symmetric_eigenvalues();
    let (a, b, c) = (eig[0], eig[1], eig[2]);
    let largest = a.abs().max(b.abs()).max(c.abs());
    // A point mass or a thin rod has zero moments (Drake reads them); round-off of a CAD
    // export leaves a trace below zero or past the triangle's edge.
    if a.min(b).min(c) < -1e-9 * largest - NEGLIGIBLE_INERTIA_KG_M2 {
        return Err(format!(
            "inertia is not positive semi-definite (principal moments {a:.4e}, {b:.4e}, {c:.4e} kg·m²): no rigid body has it"
        ));
    }
    let tol = 1e-6 * (a.abs() + b.abs() + c.abs()) + NEGLIGIBLE_INERTIA_KG_M2;
    if a + b < c - tol || a + c < b - tol || b + c < a - tol {
        return Err(format!(
            "inertia violates the triangle inequality (principal moments {a:.4e}, {b:.4e}, {c:.4e} kg·m²): no rigid body has it"
        ));
    }
    Ok(())
}

fn pose(p: &urdf_rs::Pose) -> Result<Isometry3<f64>, String> {
    let [x, y, z] = p.xyz.0;
    let [r, pi, ya] = p.rpy.0;
    if ![x, y, z, r, pi, ya].iter().all(|v| v.is_finite()) {
        return Err(format!(
            "origin xyz={:?} rpy={:?} has a non-finite value",
            p.xyz.0, p.rpy.0
        ));
    }
    if [x, y, z].iter().any(|v| v.abs() > MAX_MACHINE_SIZE_M) {
        return Err(format!(
            "origin xyz={:?} m: expected offsets within ±{MAX_MACHINE_SIZE_M:?} m",
            p.xyz.0
        ));
    }
    // URDF: R = Rz(yaw)·Ry(pitch)·Rx(roll), which is nalgebra's Euler convention.
    Ok(Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, pi, ya),
    ))
}

/// A xacro file (ROS's XML macro language) is not URDF until it is expanded: its `${…}`
/// expressions and `xacro:` elements would otherwise be read as malformed numbers and unknown
/// elements. Refused with the command that expands it. Many URDFs that xacro wrote keep its
/// namespace declaration and commented-out macros: those are URDF, and read as such.
fn refuse_xacro(path: &Path, text: &str) -> Result<(), FileError> {
    let comments = comment_ranges(text);
    let in_comment = |at: usize| comments.iter().any(|r| r.contains(&at));
    // `${` counts inside a tag (an attribute), where xacro substitutes; in element text it is
    // some plugin's own syntax (a `<gazebo>` block's `${namespace}`).
    let in_tag = |at: usize| text[..at].rfind('<') > text[..at].rfind('>');
    // A leftover `<xacro:property>` or `<xacro:arg>` changes nothing where no `${` uses it
    // (urdfdom reads past it); a macro, an include or a condition would.
    let xacro_element = |at: usize| {
        let name = &text[at + "<xacro:".len()..];
        !["property", "arg"].iter().any(|kept| {
            name.starts_with(kept) && !name[kept.len()..].starts_with(char::is_alphanumeric)
        })
    };
    let marker = ["<xacro:", "${"]
        .iter()
        .filter_map(|m| {
            text.match_indices(m)
                .map(|(at, _)| at)
                .find(|&at| {
                    !in_comment(at)
                        && if *m == "${" {
                            in_tag(at)
                        } else {
                            xacro_element(at)
                        }
                })
                .map(|at| (at, *m))
        })
        .min();
    let Some((offset, found)) = marker else {
        return Ok(());
    };
    let name = path.file_name().map_or_else(
        || "FILE.xacro".to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let stem = name
        .strip_suffix(".xacro")
        .unwrap_or(&name)
        .trim_end_matches(".urdf");
    Err(FileError::at_offset(
        path,
        text,
        offset,
        format!(
            "this is a xacro file (found `{found}`), not URDF: name it {stem}.urdf.xacro and \
             cncsim expands it (with the xacro Python package: `pip install xacro`, no ROS \
             needed), or expand it yourself with `xacro {name} > {stem}_expanded.urdf` and \
             give cncsim that file"
        ),
    ))
}

/// `text` with the bytes of `ranges` as spaces (line ends kept, so places stay the same).
fn blank(text: &str, ranges: &[std::ops::Range<usize>]) -> String {
    let mut bytes = text.as_bytes().to_vec();
    for range in ranges {
        for b in &mut bytes[range.clone()] {
            if *b != b'\n' && *b != b'\r' {
                *b = b' ';
            }
        }
    }
    // Ranges start at a `<` and end after a `>`: whole characters become spaces.
    String::from_utf8(bytes).expect("whole characters were replaced")
}

/// Byte ranges of the XML comments in `text`.
fn comment_ranges(text: &str) -> Vec<std::ops::Range<usize>> {
    let mut ranges = Vec::new();
    let mut from = 0;
    while let Some(start) = text[from..].find("<!--").map(|i| from + i) {
        let end = text[start + 4..]
            .find("-->")
            .map_or(text.len(), |i| start + 4 + i + 3);
        ranges.push(start..end);
        from = end;
    }
    ranges
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}
