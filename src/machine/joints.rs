//! Moving joints that no axis drives: what the drive file says of them (`[joints.<name>]`),
//! what the URDF says (`<mimic>`), and the default for the rest (locked, with one warning).
//!
//! A locked joint becomes a fixed one at its held position, so every later stage sees a
//! plain fixed joint. A `<mimic>` follower (q = multiplier × leader + offset; a chain of them
//! composed down to the first leader) of a driven or passive joint whose motion is the same
//! rigid motion as its leader's (same parent, same axis line, multiplier ±1 with the axis
//! turned to match: the second rail of a gantry) is fixed to the leader's link at the mimic
//! offset, which is exact and costs nothing. Any other follower keeps its own joint, coupled
//! to its leader's ([`Undriven::Coupled`]): the physics holds the coupling as an equality
//! constraint, the kinematics and the reference model substitute it. A follower of a locked
//! joint is locked where the mimic puts it.

use super::drives::{list, JointMode, JointSetting};
use super::{Joint, JointKind, KinematicTree, Mimic};
use crate::diagnostics::{FileError, LineColumn};
use nalgebra::Vector3;
use std::path::Path;

/// Tolerance on the axis direction (unit vectors) and axis line (m) of a rigid mimic follower:
/// above the rounding of CAD-exported frames, far below any real misalignment.
const RIGID_MIMIC_TOLERANCE: f64 = 1e-6;

/// The kinematic tree with every undriven joint resolved.
pub(super) struct Resolved {
    pub tree: KinematicTree,
    /// What became of each moving joint no axis drives, in the URDF's order.
    pub undriven: Vec<(String, Undriven)>,
    pub warnings: Vec<FileError>,
}

/// What became of a moving URDF joint that no axis drives.
#[derive(Debug, Clone, PartialEq)]
pub enum Undriven {
    /// Held at this coordinate (m or rad): named so in the drive file, or by default.
    Locked {
        /// The coordinate it is held at (m or rad).
        position: f64,
        /// Whether the drive file names the joint (`[joints.<name>]`); false: locked by default.
        named: bool,
    },
    /// Free (`mode = "passive"`).
    Passive,
    /// A `<mimic>` follower held where its locked leader puts it.
    HeldByMimic {
        /// Name of the leader joint (the first of a chain of mimics).
        leader: String,
        /// The coordinate the mimic puts it at (m or rad).
        position: f64,
    },
    /// A `<mimic>` follower fixed to its leader's link (it moves rigidly with it).
    RidesOn {
        /// Name of the leader joint (the first of a chain of mimics).
        leader: String,
    },
    /// A `<mimic>` follower on its own joint, coupled to its leader's coordinate:
    /// q = multiplier × q_leader + offset.
    Coupled {
        /// Name of the leader joint (the first of a chain of mimics).
        leader: String,
        /// Factor on the leader's coordinate.
        multiplier: f64,
        /// Added to the scaled coordinate (m or rad).
        offset: f64,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Role {
    Driven,
    Passive,
    /// Held at this coordinate.
    Locked(f64),
    /// A follower held at this coordinate by its locked first leader (joint index).
    HeldByMimic(usize, f64),
    /// Fixed to its leader's link (joint index of the leader, and the composed offset).
    RidesOn(usize, f64),
    /// Its own joint, coupled to a driven or passive leader (joint index, multiplier, offset).
    Coupled(usize, f64, f64),
}

/// `driven`: the joints the drive file's axes name, with their places in the drive file;
/// `settings`: its `[joints.<name>]` entries.
pub(super) fn resolve(
    mut tree: KinematicTree,
    driven: &[(&str, Option<LineColumn>)],
    settings: &[(&str, JointSetting, Option<LineColumn>)],
    drives_path: &Path,
) -> Result<Resolved, FileError> {
    let urdf = tree.path.clone();
    let joints = &tree.joints;
    let index = |name: &str| joints.iter().position(|j| j.name == name);
    let moving_names = || {
        list(
            joints
                .iter()
                .filter(|j| j.kind != JointKind::Fixed)
                .map(|j| j.name.as_str()),
        )
    };
    let mut roles: Vec<Option<Role>> = vec![None; joints.len()];
    for &(name, place) in driven {
        let fail = |m: String| FileError::new(drives_path, place, m);
        let Some(j) = index(name) else {
            return Err(fail(format!(
                "joint '{name}' is not a joint of the URDF (its moving joints: {})",
                moving_names()
            )));
        };
        if let Some(m) = &joints[j].mimic {
            return Err(fail(format!(
                "joint '{name}' follows joint '{}' through its <mimic> (URDF {}): it moves with its leader and cannot have a drive of its own; drive '{}' instead",
                m.joint,
                place_text(joints[j].place),
                m.joint
            )));
        }
        roles[j] = Some(Role::Driven);
    }
    for &(name, setting, place) in settings {
        let fail = |m: String| FileError::new(drives_path, place, format!("[joints.{name}]: {m}"));
        let Some(j) = index(name) else {
            return Err(fail(format!(
                "no joint of that name in the URDF (its moving joints: {})",
                moving_names()
            )));
        };
        let joint = &joints[j];
        if joint.kind == JointKind::Fixed {
            return Err(fail(
                "the joint is fixed in the URDF: it needs no entry".into(),
            ));
        }
        if roles[j] == Some(Role::Driven) {
            return Err(fail(
                "an axis drives this joint: give it either an [axes.<letter>] or a [joints] entry"
                    .into(),
            ));
        }
        if let Some(m) = &joint.mimic {
            return Err(fail(format!(
                "the joint follows '{}' through its <mimic>: it needs no entry",
                m.joint
            )));
        }
        roles[j] = Some(match (setting.mode, setting.position) {
            (JointMode::Passive, Some(_)) => {
                return Err(fail(
                    "position applies to mode = \"locked\"; a passive joint moves freely".into(),
                ))
            }
            (JointMode::Passive, None) => Role::Passive,
            (JointMode::Locked, Some(q)) => {
                check_in_travel(joint, q).map_err(|m| fail(format!("position = {q:?}: {m}")))?;
                Role::Locked(q)
            }
            (JointMode::Locked, None) => Role::Locked(rest_position(joint)),
        });
    }
    let mut unnamed = Vec::new();
    for (j, joint) in joints.iter().enumerate() {
        if joint.kind != JointKind::Fixed && joint.mimic.is_none() && roles[j].is_none() {
            roles[j] = Some(Role::Locked(rest_position(joint)));
            unnamed.push(j);
        }
    }
    // Followers last: their leaders' roles are known.
    for (j, joint) in joints.iter().enumerate() {
        if joint.mimic.is_none() || joint.kind == JointKind::Fixed {
            continue;
        }
        let fail =
            |m: String| FileError::new(&urdf, joint.place, format!("joint '{}': {m}", joint.name));
        let (l, multiplier, offset) = first_leader(joints, j).map_err(fail)?;
        let leader = &joints[l];
        roles[j] = Some(match roles[l] {
            Some(Role::Locked(q)) => {
                let held = multiplier * q + offset;
                check_in_travel(joint, held).map_err(|e| {
                    fail(format!(
                        "its <mimic> holds it at {multiplier} × {q:?} + {offset} = {held:?} (its leader '{}' is locked): {e}",
                        leader.name
                    ))
                })?;
                Role::HeldByMimic(l, held)
            }
            Some(Role::Driven | Role::Passive) if rigid_follower(joint, leader, multiplier) => {
                Role::RidesOn(l, offset)
            }
            Some(Role::Driven | Role::Passive) => Role::Coupled(l, multiplier, offset),
            Some(Role::RidesOn(..) | Role::Coupled(..) | Role::HeldByMimic(..)) | None => {
                unreachable!("a first leader is a moving joint without a mimic, so it has a role")
            }
        });
    }

    let mut warnings = Vec::new();
    if let Some(&first) = unnamed.first() {
        let names: Vec<String> = unnamed
            .iter()
            .map(|&j| match joints[j].place {
                Some(p) => format!("'{}' (line {})", joints[j].name, p.line),
                None => format!("'{}'", joints[j].name),
            })
            .collect();
        warnings.push(FileError::new(
            &urdf,
            joints[first].place,
            format!(
                "{} moving joint{} no axis drives {} locked at {} zero position (or nearest limit): {}. To silence this, name {} in {} with [joints.<name>] mode = \"locked\" (or \"passive\" to let {} move freely)",
                unnamed.len(),
                if unnamed.len() == 1 { "" } else { "s" },
                if unnamed.len() == 1 { "is" } else { "are" },
                if unnamed.len() == 1 { "its" } else { "their" },
                names.join(", "),
                if unnamed.len() == 1 { "it" } else { "them" },
                drives_path.display(),
                if unnamed.len() == 1 { "it" } else { "them" },
            ),
        ));
    }

    let undriven = joints
        .iter()
        .zip(&roles)
        .filter_map(|(joint, role)| {
            let what = match *role {
                Some(Role::HeldByMimic(l, position)) => Undriven::HeldByMimic {
                    leader: joints[l].name.clone(),
                    position,
                },
                Some(Role::Locked(position)) => Undriven::Locked {
                    position,
                    named: settings.iter().any(|(n, ..)| *n == joint.name),
                },
                Some(Role::Passive) => Undriven::Passive,
                Some(Role::RidesOn(l, _)) => Undriven::RidesOn {
                    leader: joints[l].name.clone(),
                },
                Some(Role::Coupled(l, multiplier, offset)) => Undriven::Coupled {
                    leader: joints[l].name.clone(),
                    multiplier,
                    offset,
                },
                Some(Role::Driven) | None => return None,
            };
            Some((joint.name.clone(), what))
        })
        .collect();

    // Apply: locked joints and rigid followers become fixed joints.
    let originals = tree.joints.clone();
    for (joint, role) in tree.joints.iter_mut().zip(&roles) {
        match *role {
            Some(Role::Locked(q) | Role::HeldByMimic(_, q)) => {
                joint.origin *= joint.motion(q);
                make_fixed(joint);
            }
            Some(Role::RidesOn(l, offset)) => {
                let leader = &originals[l];
                // The follower's pose in its leader's child frame: constant, because both move
                // along (or about) the same line by the same amount.
                joint.origin = leader.origin.inverse() * joint.origin * joint.motion(offset);
                joint.parent = leader.child;
                make_fixed(joint);
            }
            Some(Role::Coupled(l, multiplier, offset)) => {
                // Coupled to the first leader of its chain, by the composed coefficients.
                joint.mimic = Some(Mimic {
                    joint: originals[l].name.clone(),
                    multiplier,
                    offset,
                });
            }
            Some(Role::Passive | Role::Driven) | None => {}
        }
    }
    let order = super::urdf::order_parents_first(&tree.joints, tree.root, tree.links.len())
        .map_err(|_| FileError::new(&urdf, None, "a mimic follower closes a loop of joints"))?;
    tree.joints = order.into_iter().map(|i| tree.joints[i].clone()).collect();
    Ok(Resolved {
        tree,
        undriven,
        warnings,
    })
}

fn make_fixed(joint: &mut Joint) {
    joint.kind = JointKind::Fixed;
    joint.axis = Vector3::z();
    joint.limits = None;
    joint.mimic = None;
}

/// Where an undriven joint rests by default: 0, or the nearer limit if 0 is outside its travel.
fn rest_position(joint: &Joint) -> f64 {
    match joint.limits {
        Some([lo, hi]) => 0.0f64.clamp(lo, hi),
        None => 0.0,
    }
}

fn check_in_travel(joint: &Joint, q: f64) -> Result<(), String> {
    if !q.is_finite() {
        return Err("expected a finite joint coordinate".into());
    }
    match joint.limits {
        Some([lo, hi]) if !(lo..=hi).contains(&q) => Err(format!(
            "outside the travel [{lo:?}, {hi:?}] of joint '{}'",
            joint.name
        )),
        _ => Ok(()),
    }
}

/// The first leader of `follower`'s chain of mimics (a joint without one) and the composed
/// multiplier and offset: q = multiplier × q_leader + offset.
fn first_leader(joints: &[Joint], follower: usize) -> Result<(usize, f64, f64), String> {
    let (mut multiplier, mut offset) = (1.0, 0.0);
    let mut at = follower;
    // A chain longer than the joints has a loop in it.
    for _ in 0..=joints.len() {
        let Some(m) = &joints[at].mimic else {
            return Ok((at, multiplier, offset));
        };
        let l = joints
            .iter()
            .position(|j| j.name == m.joint)
            .expect("the URDF reader checked the mimic's leader");
        if joints[l].kind == JointKind::Fixed {
            return Err(format!("its <mimic> follows '{}', a fixed joint", m.joint));
        }
        // q_at = m·q_l + o, and q_follower = multiplier·q_at + offset.
        offset += multiplier * m.offset;
        multiplier *= m.multiplier;
        at = l;
    }
    Err(format!(
        "its <mimic> chain (through '{}') comes back to itself",
        joints[follower]
            .mimic
            .as_ref()
            .map_or("", |m| m.joint.as_str())
    ))
}

/// Whether `follower` moves exactly as `leader`'s child link does (same kind, same parent,
/// same axis line, and the multiplier ±1 with the axis turned to match): then it can ride on
/// its leader's link.
fn rigid_follower(follower: &Joint, leader: &Joint, multiplier: f64) -> bool {
    if follower.kind != leader.kind || multiplier.abs() != 1.0 || follower.parent != leader.parent {
        return false;
    }
    let direction = |j: &Joint| j.origin.rotation * j.axis.normalize();
    let (a, b) = (direction(follower) * multiplier, direction(leader));
    if (a - b).norm() > RIGID_MIMIC_TOLERANCE {
        return false;
    }
    let apart = follower.origin.translation.vector - leader.origin.translation.vector;
    follower.kind != JointKind::Revolute || apart.cross(&b).norm() <= RIGID_MIMIC_TOLERANCE
}

fn place_text(place: Option<LineColumn>) -> String {
    place.map_or_else(
        || "in the file".into(),
        |p| format!("line {}:{}", p.line, p.column),
    )
}
