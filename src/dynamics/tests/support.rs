//! Hand-built trees and plain (non-spatial) kinematics for the tests.

use crate::machine::{Joint, JointKind, KinematicTree, Link};
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use std::path::PathBuf;

pub const GRAVITY: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

pub fn fixture_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

pub fn base_link() -> Link {
    Link {
        name: "base".into(),
        mass: 0.0,
        center_of_mass: Point3::origin(),
        inertia: Matrix3::zeros(),
        visuals: Vec::new(),
        solids: Vec::new(),
        place: None,
    }
}

pub fn link(name: &str, mass: f64, com: [f64; 3], inertia_about_com: Matrix3<f64>) -> Link {
    Link {
        name: name.into(),
        mass,
        center_of_mass: Point3::from(com),
        inertia: inertia_about_com,
        visuals: Vec::new(),
        solids: Vec::new(),
        place: None,
    }
}

pub fn joint(
    name: &str,
    kind: JointKind,
    parent: usize,
    child: usize,
    origin: Isometry3<f64>,
    axis: Vector3<f64>,
) -> Joint {
    Joint {
        name: name.into(),
        kind,
        parent,
        child,
        origin,
        axis: axis.normalize(),
        limits: None,
        damping: 0.0,
        friction: 0.0,
        mimic: None,
        place: None,
    }
}

pub fn pose(xyz: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    )
}

pub fn tree(links: Vec<Link>, joints: Vec<Joint>) -> KinematicTree {
    KinematicTree {
        name: "test".into(),
        path: PathBuf::from("test.urdf"),
        text: String::new(),
        links,
        joints,
        root: 0,
        warnings: Vec::new(),
    }
}

/// World (root) pose of every link at `q`, by composing URDF transforms directly:
/// child = parent · origin · motion(q). Shares no code with the spatial algebra.
pub fn link_poses(tree: &KinematicTree, q: &[f64]) -> Vec<Isometry3<f64>> {
    let mut poses = vec![Isometry3::identity(); tree.links.len()];
    let mut coordinate = 0;
    for j in &tree.joints {
        let motion = match j.kind {
            JointKind::Fixed => Isometry3::identity(),
            JointKind::Revolute => Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Unit::new_normalize(j.axis), q[coordinate]),
            ),
            JointKind::Prismatic => Isometry3::translation(
                j.axis.x * q[coordinate],
                j.axis.y * q[coordinate],
                j.axis.z * q[coordinate],
            ),
        };
        if j.kind != JointKind::Fixed {
            coordinate += 1;
        }
        poses[j.child] = poses[j.parent] * j.origin * motion;
    }
    poses
}

/// Potential energy `V(q) = −Σ mₖ gᵀ cₖ(q)` (J).
pub fn potential_energy(tree: &KinematicTree, gravity: &Vector3<f64>, q: &[f64]) -> f64 {
    let poses = link_poses(tree, q);
    tree.links
        .iter()
        .zip(&poses)
        .map(|(l, p)| -l.mass * gravity.dot(&(p * l.center_of_mass).coords))
        .sum()
}

/// Kinetic energy `Σ ½ m |v_c|² + ½ ωᵀ I ω` at (`q`, `qd`), with each link's velocity taken
/// from central differences of its pose along `qd` (J). Accurate to O(h²).
pub fn kinetic_energy(tree: &KinematicTree, q: &[f64], qd: &[f64]) -> f64 {
    let h = 1e-5;
    let shifted = |s: f64| -> Vec<f64> { q.iter().zip(qd).map(|(q, v)| q + s * v).collect() };
    let (plus, now, minus) = (
        link_poses(tree, &shifted(h)),
        link_poses(tree, q),
        link_poses(tree, &shifted(-h)),
    );
    let mut energy = 0.0;
    for (k, l) in tree.links.iter().enumerate() {
        if l.mass == 0.0 {
            continue;
        }
        let v = ((plus[k] * l.center_of_mass) - (minus[k] * l.center_of_mass)) / (2.0 * h);
        // Quaternion log: robust near identity (a rotation matrix's acos of the trace is not).
        let omega = (plus[k].rotation * minus[k].rotation.inverse()).scaled_axis() / (2.0 * h);
        let r = now[k].rotation.to_rotation_matrix();
        let inertia_world = r.matrix() * l.inertia * r.matrix().transpose();
        energy += 0.5 * l.mass * v.norm_squared() + 0.5 * omega.dot(&(inertia_world * omega));
    }
    energy
}

pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

pub fn max_abs(a: &[f64]) -> f64 {
    a.iter().map(|x| x.abs()).fold(0.0, f64::max)
}
