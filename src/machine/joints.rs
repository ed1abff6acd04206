//! Moving joints that no axis drives: what the drive file says of them (`[joints.<name>]`),
//! what the URDF says (`<mimic>`), and the default for the rest (locked, with one warning).
//!
//! A locked joint becomes a fixed one at its held position, so every later stage sees a
//! plain fixed joint. A `<mimic>` follower of a driven axis moves with its leader's link when
//! that motion is the same rigid motion (same parent, same axis line, multiplier 1, as the
//! second rail of a gantry): it is then fixed to the leader's link at the mimic offset,
//! which is exact. A follower of a locked joint is locked where the mimic puts it. Other
//! couplings are refused by name rather than simulated wrongly.

use super::drives::{list, JointMode, JointSetting};
use super::{Joint, JointKind, KinematicTree};
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
        /// Name of the leader joint.
        leader: String,
        /// The coordinate the mimic puts it at (m or rad).
        position: f64,
    },
    /// A `<mimic>` follower fixed to its driven leader's link.
    RidesOn {
        /// Name of the leader joint.
        leader: String,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Role {
    Driven,
    Passive,
    /// Held at this coordinate.
    Locked(f64),
    /// Fixed to its leader's link (joint index of the leader).
    RidesOn(usize),
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
        let Some(m) = &joint.mimic else { continue };
        if joint.kind == JointKind::Fixed {
            continue;
        }
        let fail =
            |m: String| FileError::new(&urdf, joint.place, format!("joint '{}': {m}", joint.name));
        let l = index(&m.joint).expect("the URDF reader checked the mimic's leader");
        let leader = &joints[l];
        roles[j] = Some(match roles[l] {
            None if leader.kind == JointKind::Fixed => {
                return Err(fail(format!(
                    "its <mimic> follows '{}', a fixed joint",
                    leader.name
                )))
            }
            None | Some(Role::RidesOn(_)) => {
                return Err(fail(format!(
                    "its <mimic> follows '{}', which itself follows another joint: chains of mimic joints are not supported; let it follow the first joint of the chain",
                    leader.name
                )))
            }
            Some(Role::Locked(q)) => {
                let held = m.multiplier * q + m.offset;
                check_in_travel(joint, held).map_err(|e| {
                    fail(format!(
                        "its <mimic> holds it at {} × {q:?} + {} = {held:?} (its leader '{}' is locked): {e}",
                        m.multiplier, m.offset, leader.name
                    ))
                })?;
                Role::Locked(held)
            }
            Some(Role::Passive) => {
                return Err(fail(format!(
                    "its <mimic> follows the passive joint '{}': a follower of a free joint is not supported; lock '{}' or drive it",
                    leader.name, leader.name
                )))
            }
            Some(Role::Driven) => {
                rigid_follower(joint, leader, m.multiplier).map_err(|why| {
                    fail(format!(
                        "its <mimic> (multiplier {}) couples it to the driven joint '{}', and {why}: cncsim couples a follower that moves rigidly with its leader's link (same parent link, same axis line, multiplier 1). Drive it as an axis of its own, or lock it in the drive file with [joints.{}] mode = \"locked\"",
                        m.multiplier, leader.name, joint.name
                    ))
                })?;
                Role::RidesOn(l)
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
            let leader = || {
                joint
                    .mimic
                    .as_ref()
                    .map_or_else(String::new, |m| m.joint.clone())
            };
            let what = match *role {
                Some(Role::Locked(position)) if joint.mimic.is_some() => Undriven::HeldByMimic {
                    leader: leader(),
                    position,
                },
                Some(Role::Locked(position)) => Undriven::Locked {
                    position,
                    named: settings.iter().any(|(n, ..)| *n == joint.name),
                },
                Some(Role::Passive) => Undriven::Passive,
                Some(Role::RidesOn(_)) => Undriven::RidesOn { leader: leader() },
                Some(Role::Driven) | None => return None,
            };
            Some((joint.name.clone(), what))
        })
        .collect();

    // Apply: locked joints and rigid followers become fixed joints.
    let originals = tree.joints.clone();
    for (joint, role) in tree.joints.iter_mut().zip(&roles) {
        match *role {
            Some(Role::Locked(q)) => {
                joint.origin *= joint.motion(q);
                make_fixed(joint);
            }
            Some(Role::RidesOn(l)) => {
                let leader = &originals[l];
                let offset = joint.mimic.as_ref().map_or(0.0, |m| m.offset);
                // The follower's pose in its leader's child frame: constant, because both move
                // along (or about) the same line by the same amount.
                joint.origin = leader.origin.inverse() * joint.origin * joint.motion(offset);
                joint.parent = leader.child;
                make_fixed(joint);
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

/// Whether `follower` moves exactly as `leader`'s child link does: then it can ride on it.
fn rigid_follower(follower: &Joint, leader: &Joint, multiplier: f64) -> Result<(), String> {
    if follower.kind != leader.kind {
        return Err(format!(
            "the two are of different kinds ({:?} and {:?})",
            follower.kind, leader.kind
        ));
    }
    if multiplier != 1.0 {
        return Err("the multiplier is not 1".into());
    }
    if follower.parent != leader.parent {
        return Err("the two hang on different parent links".into());
    }
    let direction = |j: &Joint| j.origin.rotation * j.axis;
    let (a, b) = (direction(follower), direction(leader));
    if (a - b).norm() > RIGID_MIMIC_TOLERANCE {
        return Err(format!(
            "their axes point different ways in the parent frame ({:?} and {:?})",
            a.as_slice(),
            b.as_slice()
        ));
    }
    if follower.kind == JointKind::Revolute {
        let apart = follower.origin.translation.vector - leader.origin.translation.vector;
        if apart.cross(&b).norm() > RIGID_MIMIC_TOLERANCE {
            return Err("their axes are parallel but not on one line".into());
        }
    }
    Ok(())
}

fn place_text(place: Option<LineColumn>) -> String {
    place.map_or_else(
        || "in the file".into(),
        |p| format!("line {}:{}", p.line, p.column),
    )
}
