//! URDF → [`KinematicTree`], with the checks a physics model needs (positive masses,
//! physical inertias, one root, supported joint types) reported against the file.

use super::{BoxShape, Joint, JointKind, KinematicTree, Link};
use crate::diagnostics::{read_text, FileError, LineColumn};
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use std::path::Path;

/// Reads and validates a URDF file.
pub fn load_urdf(path: &Path) -> Result<KinematicTree, FileError> {
    let text = read_text(path, "machine model (URDF)")?;
    parse_urdf(path, &text)
}

pub(crate) fn parse_urdf(path: &Path, text: &str) -> Result<KinematicTree, FileError> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| {
        FileError::new(
            path,
            None,
            format!("not a valid URDF document: {}", one_line(&e.to_string())),
        )
    })?;
    let element =
        |kind: &str, name: &str| LineColumn::of_first(text, &format!("<{kind} name=\"{name}\""));
    let err = |kind: &str, name: &str, msg: String| FileError::new(path, element(kind, name), msg);

    if robot.links.is_empty() {
        return Err(FileError::new(path, None, "the URDF has no <link>"));
    }
    let mut links = Vec::with_capacity(robot.links.len());
    for l in &robot.links {
        links.push(
            link_from_urdf(l)
                .map_err(|m| err("link", &l.name, format!("link '{}': {m}", l.name)))?,
        );
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
                if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                    return Err(e(format!(
                        "limits lower={lo} upper={hi}: expected finite lower < upper"
                    )));
                }
                Some([lo, hi])
            }
        };
        let damping = j.dynamics.as_ref().map_or(0.0, |d| d.damping);
        if !(damping.is_finite() && damping >= 0.0) {
            return Err(e(format!("damping {damping}: expected a finite value ≥ 0")));
        }
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
    let ordered = order_parents_first(&joints, root, links.len()).ok_or_else(|| {
        FileError::new(
            path,
            None,
            "the joints form a cycle; a machine must be a tree of links",
        )
    })?;
    let joints = ordered.into_iter().map(|i| joints[i].clone()).collect();

    Ok(KinematicTree {
        name: robot.name,
        path: path.to_path_buf(),
        text: text.to_string(),
        links,
        joints,
        root,
    })
}

/// Joint indices with every parent link placed before its children, keeping the file's order
/// wherever it already is (so axes come out in the order the URDF lists them); `None` if some
/// link cannot be reached from the root.
fn order_parents_first(joints: &[Joint], root: usize, n_links: usize) -> Option<Vec<usize>> {
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
            return None;
        }
    }
    Some(order)
}

fn link_from_urdf(l: &urdf_rs::Link) -> Result<Link, String> {
    let m = l.inertial.mass.value;
    let i = &l.inertial.inertia;
    let frame = pose(&l.inertial.origin)?;
    let local = Matrix3::new(
        i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
    );
    if !(m.is_finite() && m >= 0.0) {
        return Err(format!("mass {m} kg: expected a finite mass ≥ 0"));
    }
    if !local.iter().all(|v| v.is_finite()) {
        return Err("inertia has a non-finite entry".into());
    }
    if m > 0.0 {
        check_physical_inertia(&local)?;
    } else if local.norm() > 0.0 {
        return Err("has inertia but zero mass".into());
    }
    // Inertia expressed in the link frame (the inertial frame may be rotated).
    let r = frame.rotation.to_rotation_matrix();
    let inertia = r.matrix() * local * r.matrix().transpose();
    let mut boxes = Vec::new();
    for v in &l.visual {
        if let urdf_rs::Geometry::Box { size } = &v.geometry {
            let s = Vector3::from(size.0);
            if !s.iter().all(|v| v.is_finite() && *v > 0.0) {
                return Err(format!("box size {:?}: expected positive sizes", size.0));
            }
            let color = v
                .material
                .as_ref()
                .and_then(|m| m.color.as_ref())
                .map(|c| c.rgba.0.map(|x| x as f32));
            boxes.push(BoxShape {
                pose: pose(&v.origin)?,
                half_extents: s / 2.0,
                color,
            });
        }
    }
    Ok(Link {
        name: l.name.clone(),
        mass: m,
        center_of_mass: Point3::from(frame.translation.vector),
        inertia,
        boxes,
    })
}

/// Principal moments positive and obeying the triangle inequality (a real body's inertia).
fn check_physical_inertia(i: &Matrix3<f64>) -> Result<(), String> {
    let eig = i.symmetric_eigenvalues();
    let (a, b, c) = (eig[0], eig[1], eig[2]);
    let tol = 1e-12 * (a.abs() + b.abs() + c.abs());
    if a <= 0.0 || b <= 0.0 || c <= 0.0 {
        return Err(format!(
            "inertia is not positive definite (principal moments {a:.4e}, {b:.4e}, {c:.4e} kg·m²)"
        ));
    }
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
    // URDF: R = Rz(yaw)·Ry(pitch)·Rx(roll), which is nalgebra's Euler convention.
    Ok(Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, pi, ya),
    ))
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}
