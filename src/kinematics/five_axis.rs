//! Inverse kinematics of any five-axis machine from its URDF chain: three linear axes and two
//! rotary axes that turn the tool relative to the part, wherever they sit (a swivel head
//! carrying both, a tilting table carrying both, or one on each side).
//!
//! # The chain, as two exponentials
//!
//! Going from the workpiece link up to the link the tool's and the part's branches share and
//! down to the tool link, the rotary joints meet in an order: the one met first is the
//! **primary** axis (the C table of an A-C table mill, the C of a B-C head), the other the
//! **secondary**. With every axis at its home (program coordinates zero), let `u₁`, `u₂` be
//! their axis directions in the world frame, `p` the tool axis and `R_w0` the workpiece link's
//! orientation. Prismatic joints never turn anything, so (product of exponentials)
//!
//! ```text
//! R_w0 · O = Rot(u₁, ψ₁) · Rot(u₂, ψ₂) · p,    ψₖ = side_k · sign_k · r_k
//! ```
//!
//! where `O` is the tool axis in the workpiece link's frame, `r_k` the program's rotary
//! coordinate, `sign_k` the drive's sign and `side_k` = +1 for a joint on the tool's branch,
//! −1 on the part's (turning the table one way turns the tool the other way on the part).
//! [`FiveAxisKinematics::new`] checks this form against the URDF's forward kinematics (a
//! `<mimic>` follower or a third turning joint would break it).
//!
//! # Orientation: both solutions
//!
//! `Rot(u₁, ψ₁)·Rot(u₂, ψ₂)·p = q` is Paden and Kahan's second subproblem (Murray, Li and
//! Sastry, *A Mathematical Introduction to Robotic Manipulation*, §3.2): the intermediate
//! vector `z = Rot(u₂, ψ₂)·p = Rot(u₁, −ψ₁)·q` satisfies `u₂·z = u₂·p`, `u₁·z = u₁·q`,
//! `|z| = 1`, so with `c = u₁·u₂`
//!
//! ```text
//! z = α·u₁ + β·u₂ ± γ·(u₁ × u₂),
//! α = (u₁·q − c·u₂·p) / (1 − c²),   β = (u₂·p − c·u₁·q) / (1 − c²),
//! γ² = (1 − α² − β² − 2αβc) / |u₁ × u₂|²
//! ```
//!
//! and each angle is the rotation about its axis taking one vector to the other. `γ² < 0`:
//! the orientation is out of the head's reach (a nutating head's cone). The two signs of γ are
//! the two solutions (A and −A, C and C + π on an A-C table). **The pole**: where `z` lies
//! along `u₁` the tool axis is along the primary axis and ψ₁ is free; it is kept where it was.
//!
//! # Position
//!
//! With the rotary axes set, the tool point on the part is affine in the three linear
//! coordinates (`P = P₀ + M·s`, exact: prismatic joints add straight moves), so the linear
//! axes solve a 3 × 3 system; `M` is taken from the forward kinematics itself.
//!
//! # Choosing
//!
//! Each angle is taken at the 2π multiple nearest the previous position within the joint's
//! travel; of the two solutions the one nearest the previous rotary coordinates wins (ties to
//! the one whose secondary angle lies in [0, π]); a solution with any axis outside its travel
//! is dropped, and if both are, every violation of both is the error.

use super::ac_table::nearest_turn;
use super::{chain_joints, link_poses, AxisMap, ProgramFrame, PROGRAM_LETTERS};
use crate::machine::{JointKind, Machine};
use crate::program::Position;
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Unit, Vector3};
use std::f64::consts::PI;
use std::fmt;

/// Tool axis within this angle (rad) of the primary rotary axis is at the pole: the primary
/// angle is kept (0.1 nrad, as the A-C table's closed form).
pub const POLE_ANGLE: f64 = 1e-10;
/// Travel slack (m or rad) for rounding at a travel limit.
const TRAVEL_SLACK: f64 = 1e-9;
/// How far the chain's two-exponential form may be from its forward kinematics (unit vectors).
const FORM_TOLERANCE: f64 = 1e-9;

/// Where cutter locations are given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PartFrame {
    /// The workpiece link's own frame (CL data: CAM's part datum is the workpiece link).
    WorkpieceLink,
    /// The program frame carried by the workpiece link: with every rotary axis at its home it
    /// is the program frame, so tool-tip coordinates then equal joint coordinates (as
    /// LinuxCNC's TCP kinematics, G43.4, TRAORI and TCPM read a program).
    Program,
}

/// A tool point and tool axis on the part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolPose {
    /// Tool point (m).
    pub point: Point3<f64>,
    /// Tool axis, unit, from the tip towards the spindle.
    pub axis: Vector3<f64>,
}

/// Which solution of the rotary pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Solution {
    /// The secondary angle's principal value lies in [0, π].
    First,
    /// The other.
    Second,
    /// The tool axis lies along the primary axis: its angle is kept.
    Pole,
}

impl fmt::Display for Solution {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Solution::First => "solution 1",
            Solution::Second => "solution 2",
            Solution::Pole => "the pole",
        })
    }
}

/// Machine coordinates found for a tool pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solved {
    /// Program (joint-mode) coordinates: every axis the machine has.
    pub position: Position,
    /// Which solution.
    pub solution: Solution,
    /// The solution nearest the previous position was outside the travel.
    pub forced_by_travel: bool,
}

/// Why a tool pose has no machine coordinates.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InverseError {
    /// A NaN or infinite value.
    #[error("the tool point or axis has a non-finite value")]
    NotFinite,
    /// The tool axis is the zero vector.
    #[error("the tool-axis vector is zero")]
    ZeroAxis,
    /// No pair of rotary angles turns the tool to the axis asked for.
    #[error("no angles of {primary} and {secondary} turn the tool to ({:.6}, {:.6}, {:.6}): it is {:.3}° outside their reach", axis[0], axis[1], axis[2], short_by.to_degrees())]
    OutOfReach {
        /// The primary axis letter.
        primary: String,
        /// The secondary axis letter.
        secondary: String,
        /// The axis asked for.
        axis: [f64; 3],
        /// Angle (rad) between it and the nearest axis the head reaches.
        short_by: f64,
    },
    /// The linear axes do not span space at these angles.
    #[error("at these rotary angles the linear axes do not move the tool in three independent directions")]
    LinearSingular,
    /// Every solution puts some axis outside its travel.
    #[error("outside the machine's travel: {}", violations.join("; "))]
    OutOfTravel {
        /// Every violation of every solution tried, as shown to the user.
        violations: Vec<String>,
    },
}

/// Why a machine has no five-axis kinematics.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("machine '{machine}' has no tool-tip kinematics: {problem}")]
pub struct ChainError {
    /// The machine's name.
    pub machine: String,
    /// What is missing or wrong.
    pub problem: String,
}

/// One rotary axis of the pair.
#[derive(Debug, Clone, PartialEq)]
struct Rotary {
    /// Index into `Machine::axes`.
    axis: usize,
    /// Index into `Position::rotary`.
    letter: usize,
    /// Its direction in the world frame at home.
    direction: Unit<Vector3<f64>>,
    /// ψ = scale · r: side × drive sign.
    scale: f64,
    /// Drive sign and home (joint = home + sign · r).
    sign: f64,
    home: f64,
    limits: Option<[f64; 2]>,
}

/// Inverse and forward kinematics of a five-axis machine (module documentation).
#[derive(Debug, Clone)]
pub struct FiveAxisKinematics {
    machine: Machine,
    map: AxisMap,
    /// [primary, secondary].
    rotary: [Rotary; 2],
    /// The tool axis in the world frame at home (`p`).
    tool_axis_home: Vector3<f64>,
    /// The tool axis in the tool link's frame.
    tool_axis_in_tool: Vector3<f64>,
    /// The workpiece link's orientation at home (`R_w0`).
    workpiece_home: Rotation3<f64>,
    /// Part frame → workpiece link frame: `point_w = part_to_work · p + part_origin`.
    part_to_work: Matrix3<f64>,
    work_to_part: Matrix3<f64>,
    part_origin: Vector3<f64>,
}

impl FiveAxisKinematics {
    /// The kinematics of `machine` with cutter locations in `part` coordinates. Refuses a
    /// machine whose tool is not turned relative to the part by exactly two rotary axes and
    /// moved by three linear ones, or whose chain is not of the two-exponential form.
    pub fn new(
        machine: &Machine,
        frame: &ProgramFrame,
        map: &AxisMap,
        part: PartFrame,
    ) -> Result<FiveAxisKinematics, ChainError> {
        let fail = |problem: String| ChainError {
            machine: machine.name.clone(),
            problem,
        };
        let tool_chain = chain_joints(machine, machine.tool_link);
        let work_chain = chain_joints(machine, machine.workpiece_link);
        // The relative chain, from the part to the tool: the part's branch upwards, then the
        // tool's downwards; `side` +1 on the tool's branch.
        let mut relative: Vec<(usize, f64)> = work_chain
            .iter()
            .filter(|j| !tool_chain.contains(j))
            .map(|&j| (j, -1.0))
            .collect();
        let tool_only: Vec<usize> = tool_chain
            .iter()
            .filter(|j| !work_chain.contains(j))
            .copied()
            .collect();
        relative.extend(tool_only.iter().rev().map(|&j| (j, 1.0)));
        let mut q_home = vec![0.0; map.axes()];
        map.machine_axes(&Position::default(), &mut q_home);
        let poses = link_poses(machine, &q_home);
        let mut rotary = Vec::new();
        let mut linear = Vec::new();
        for &(j, side) in &relative {
            let joint = &machine.joints[j];
            if joint.kind == JointKind::Fixed {
                continue;
            }
            let Some(axis) = machine.axes.iter().position(|a| a.joint == j) else {
                if joint.mimic.is_some() {
                    continue; // checked below through the two-exponential form
                }
                return Err(fail(format!(
                    "joint '{}' moves the tool relative to the part but no axis drives it",
                    joint.name
                )));
            };
            let name = &machine.axes[axis].name;
            let Some(&(_, _, letter)) = PROGRAM_LETTERS.iter().find(|(l, _, _)| l == name) else {
                return Err(fail(format!(
                    "axis '{name}' has no program letter (x, y, z, a, b, c)"
                )));
            };
            let drive = &machine.axes[axis].drive;
            if joint.kind == JointKind::Prismatic {
                linear.push((axis, letter, joint.name.clone()));
                continue;
            }
            let world = (poses[joint.parent] * joint.origin).rotation * joint.axis;
            rotary.push(Rotary {
                axis,
                letter,
                direction: Unit::new_normalize(world),
                scale: side * f64::from(drive.sign),
                sign: f64::from(drive.sign),
                home: drive.home,
                limits: joint.limits,
            });
        }
        let names = |axes: &[usize]| {
            axes.iter()
                .map(|&a| machine.axes[a].name.to_uppercase())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let [primary, secondary]: [Rotary; 2] = rotary.clone().try_into().map_err(|_| {
            fail(format!(
                "expected two rotary axes turning the tool relative to the part, found {}{}",
                rotary.len(),
                if rotary.is_empty() {
                    String::new()
                } else {
                    format!(
                        " ({})",
                        names(&rotary.iter().map(|r| r.axis).collect::<Vec<_>>())
                    )
                }
            ))
        })?;
        let linear_letters: Vec<usize> = linear.iter().map(|l| l.1).collect();
        let mut sorted = linear_letters.clone();
        sorted.sort();
        if sorted != [0, 1, 2] {
            return Err(fail(format!(
                "expected the linear axes X, Y and Z to move the tool relative to the part, found {}",
                if linear.is_empty() {
                    "none".to_string()
                } else {
                    names(&linear.iter().map(|l| l.0).collect::<Vec<_>>())
                }
            )));
        }
        let letter_of = |axis: &Rotary| machine.axes[axis.axis].name.to_uppercase();
        let (u1, u2) = (primary.direction, secondary.direction);
        if u1.cross(&u2).norm() < 1e-6 {
            return Err(fail(format!(
                "the rotary axes {} and {} are parallel: together they turn the tool about one direction only",
                letter_of(&primary),
                letter_of(&secondary)
            )));
        }
        // The tool axis: program +Z at home (ISO 841: +Z along the spindle, from the part
        // towards the tool), in the tool link's frame.
        let carrier = poses[frame.carrier];
        let z_world = (carrier.rotation * frame.directions.column(2)).normalize();
        let tool_axis_in_tool = poses[machine.tool_link].rotation.inverse() * z_world;
        if z_world.cross(&u2).norm() < 1e-6 {
            return Err(fail(format!(
                "the tool's axis lies along the secondary rotary axis {}: it turns the tool about its own axis",
                letter_of(&secondary)
            )));
        }
        let work_home = poses[machine.workpiece_link];
        let (part_to_work, part_origin) = match part {
            PartFrame::WorkpieceLink => (Matrix3::identity(), Vector3::zeros()),
            PartFrame::Program => {
                let carrier_in_work: Isometry3<f64> = work_home.inverse() * carrier;
                let rotation = carrier_in_work.rotation.to_rotation_matrix().into_inner();
                (
                    rotation * frame.directions,
                    (carrier_in_work * frame.origin).coords,
                )
            }
        };
        let work_to_part = part_to_work
            .try_inverse()
            .ok_or_else(|| fail("the program frame's axes do not span space".into()))?;
        let kinematics = FiveAxisKinematics {
            machine: machine.clone(),
            map: map.clone(),
            rotary: [primary, secondary],
            tool_axis_home: z_world,
            tool_axis_in_tool,
            workpiece_home: work_home.rotation.to_rotation_matrix(),
            part_to_work,
            work_to_part,
            part_origin,
        };
        kinematics.check_form().map_err(fail)?;
        Ok(kinematics)
    }

    /// The program letters (upper case) of the primary and the secondary rotary axis.
    pub fn rotary_letters(&self) -> [String; 2] {
        self.rotary
            .each_ref()
            .map(|r| self.machine.axes[r.axis].name.to_uppercase())
    }

    /// Program-position index (into `Position::rotary`) of the primary and secondary axes.
    pub fn rotary_indices(&self) -> [usize; 2] {
        [self.rotary[0].letter, self.rotary[1].letter]
    }

    /// The chain must turn the tool as the two exponentials say, at angles all over the circle.
    fn check_form(&self) -> Result<(), String> {
        for k in 0..12 {
            let angles = [0.7 + 1.9 * k as f64, -0.4 + 2.3 * k as f64];
            let mut position = Position::default();
            for (r, angle) in self.rotary.iter().zip(angles) {
                position.rotary[r.letter] = angle;
            }
            let axis = self.forward(&position).axis;
            let predicted = self.turned(
                angles[0] * self.rotary[0].scale,
                angles[1] * self.rotary[1].scale,
            );
            if (self.part_vector(&(self.workpiece_home.inverse() * predicted)) - axis).norm()
                > FORM_TOLERANCE
            {
                return Err(format!(
                    "the rotary axes {} and {} do not turn the tool as two joints of one chain do (a <mimic> follower or another turning joint between the tool and the part?)",
                    self.rotary_letters()[0],
                    self.rotary_letters()[1]
                ));
            }
        }
        Ok(())
    }

    /// `Rot(u₁, ψ₁)·Rot(u₂, ψ₂)·p` in the world frame.
    fn turned(&self, psi1: f64, psi2: f64) -> Vector3<f64> {
        Rotation3::from_axis_angle(&self.rotary[0].direction, psi1)
            * Rotation3::from_axis_angle(&self.rotary[1].direction, psi2)
            * self.tool_axis_home
    }

    fn part_point(&self, work: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.work_to_part * (work.coords - self.part_origin))
    }

    fn part_vector(&self, work: &Vector3<f64>) -> Vector3<f64> {
        (self.work_to_part * work).normalize()
    }

    /// Forward kinematics: the tool point and axis on the part at program coordinates `p`.
    pub fn forward(&self, p: &Position) -> ToolPose {
        let mut q = vec![0.0; self.map.axes()];
        self.map.machine_axes(p, &mut q);
        let poses = link_poses(&self.machine, &q);
        let work = poses[self.machine.workpiece_link];
        let tool = poses[self.machine.tool_link];
        let point = tool * Point3::from(self.machine.tool.offset_m);
        let axis = tool.rotation * self.tool_axis_in_tool;
        ToolPose {
            point: self.part_point(&work.inverse_transform_point(&point)),
            axis: self.part_vector(&work.inverse_transform_vector(&axis)),
        }
    }

    /// The rotary angles (ψ₁, ψ₂) of both solutions for a unit tool axis on the part, or the
    /// pole's one (ψ₁ = `None`: free).
    fn orientations(&self, axis: &Vector3<f64>) -> Result<Vec<(Option<f64>, f64)>, InverseError> {
        let q = self.workpiece_home * (self.part_to_work * axis).normalize();
        let (u1, u2, p) = (
            self.rotary[0].direction.into_inner(),
            self.rotary[1].direction.into_inner(),
            self.tool_axis_home,
        );
        let c = u1.dot(&u2);
        let (u1q, u2p) = (u1.dot(&q), u2.dot(&p));
        let alpha = (u1q - c * u2p) / (1.0 - c * c);
        let beta = (u2p - c * u1q) / (1.0 - c * c);
        let cross = u1.cross(&u2);
        let gamma2 =
            (1.0 - alpha * alpha - beta * beta - 2.0 * alpha * beta * c) / cross.norm_squared();
        if gamma2 < -1e-12 {
            // The head reaches the axes whose angle to u₁ lies within the angle between u₁
            // and u₂ of the angle between p and u₂.
            let angle = |a: &Vector3<f64>, b: &Vector3<f64>| a.dot(b).clamp(-1.0, 1.0).acos();
            let (to_u2, between) = (angle(&p, &u2), angle(&u1, &u2));
            let asked = angle(&u1, &q);
            let short_by = ((to_u2 - between).abs() - asked)
                .max(asked - (to_u2 + between))
                .max(0.0);
            let [primary, secondary] = self.rotary_letters();
            return Err(InverseError::OutOfReach {
                primary,
                secondary,
                // + 0.0: no "-0.000000" in the message.
                axis: [axis.x + 0.0, axis.y + 0.0, axis.z + 0.0],
                short_by,
            });
        }
        let gamma = gamma2.max(0.0).sqrt();
        let mut out = Vec::new();
        for g in [gamma, -gamma] {
            let z = alpha * u1 + beta * u2 + g * cross;
            let psi2 = rotation_taking(&u2, &p, &z);
            let perpendicular = z - u1 * u1.dot(&z);
            let psi1 = (perpendicular.norm() >= POLE_ANGLE).then(|| rotation_taking(&u1, &z, &q));
            out.push((psi1, psi2));
            if gamma == 0.0 || psi1.is_none() {
                break; // one solution (a double root, or the pole)
            }
        }
        Ok(out)
    }

    /// Program coordinates of the linear axes that put the tool point on `point` (part
    /// coordinates) with the rotary and every other axis as in `at`.
    pub fn linear_axes(
        &self,
        point: &Point3<f64>,
        at: &Position,
    ) -> Result<[f64; 3], InverseError> {
        let mut p = *at;
        p.linear = [0.0; 3];
        let origin = self.forward(&p).point;
        let mut m = Matrix3::zeros();
        for k in 0..3 {
            let mut unit = p;
            unit.linear[k] = 1.0;
            m.set_column(k, &(self.forward(&unit).point - origin));
        }
        let lu = m.lu();
        if m.determinant().abs() < 1e-9 {
            return Err(InverseError::LinearSingular);
        }
        let s = lu
            .solve(&(point - origin))
            .ok_or(InverseError::LinearSingular)?;
        Ok([s[0], s[1], s[2]])
    }

    /// The axes outside their travel at program coordinates `p`, as shown to the user.
    pub fn travel_violations(&self, p: &Position, solution: Option<Solution>) -> Vec<String> {
        let mut q = vec![0.0; self.map.axes()];
        self.map.machine_axes(p, &mut q);
        let mut out = Vec::new();
        for (i, axis) in self.machine.axes.iter().enumerate() {
            let Some([lower, upper]) = self.machine.joints[axis.joint].limits else {
                continue;
            };
            let value = q[i];
            if value < lower - TRAVEL_SLACK || value > upper + TRAVEL_SLACK {
                let (scale, unit) = if axis.is_rotary(&self.machine) {
                    (180.0 / PI, "°")
                } else {
                    (1000.0, " mm")
                };
                out.push(format!(
                    "axis '{}' would be at {:.3}{unit}, outside its travel [{:.3}{unit}, {:.3}{unit}]{}",
                    axis.name,
                    value * scale,
                    lower * scale,
                    upper * scale,
                    solution.map_or(String::new(), |s| format!(" ({s})"))
                ));
            }
        }
        out
    }

    /// Inverse kinematics with the continuity rule (module documentation): machine
    /// coordinates putting the tool on `target`, nearest `previous` (program coordinates;
    /// axes that do not move the tool on the part keep their values).
    pub fn inverse(&self, target: &ToolPose, previous: &Position) -> Result<Solved, InverseError> {
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !finite(target.point.coords.as_slice()) || !finite(target.axis.as_slice()) {
            return Err(InverseError::NotFinite);
        }
        if target.axis.norm() == 0.0 {
            return Err(InverseError::ZeroAxis);
        }
        let axis = target.axis.normalize();
        let orientations = self.orientations(&axis)?;
        let mut candidates: Vec<(Solution, Position, Vec<String>)> = Vec::new();
        for (psi1, psi2) in orientations {
            let solution = match psi1 {
                None => Solution::Pole,
                Some(_) => {
                    let r2 = psi2 / self.rotary[1].scale;
                    // The secondary angle's principal value in [0, π]: solution 1.
                    if r2.sin() >= 0.0 {
                        Solution::First
                    } else {
                        Solution::Second
                    }
                }
            };
            let mut p = *previous;
            let mut violations = Vec::new();
            for (r, psi) in self.rotary.iter().zip([psi1, Some(psi2)]) {
                let prev_joint = r.home + r.sign * previous.rotary[r.letter];
                let joint = match psi {
                    None => prev_joint,
                    Some(psi) => {
                        let joint = r.home + r.sign * psi / r.scale;
                        nearest_turn(joint, prev_joint, r.limits).unwrap_or(joint)
                    }
                };
                p.rotary[r.letter] = (joint - r.home) / r.sign;
            }
            match self.linear_axes(&target.point, &p) {
                Ok(s) => {
                    p.linear = s;
                    violations.extend(self.travel_violations(&p, Some(solution)));
                }
                Err(e) => violations.push(format!("{e} ({solution})")),
            }
            candidates.push((solution, p, violations));
        }
        let distance = |p: &Position| {
            self.rotary
                .iter()
                .map(|r| (p.rotary[r.letter] - previous.rotary[r.letter]).powi(2))
                .sum::<f64>()
        };
        // The second goes first only if nearer by more than rounding: an exact tie goes to
        // solution 1 whatever the last bits say.
        if candidates.len() == 2 {
            let first = candidates
                .iter()
                .position(|c| c.0 == Solution::First)
                .unwrap_or(0);
            candidates.swap(0, first);
            if distance(&candidates[1].1) < distance(&candidates[0].1) - 1e-12 {
                candidates.swap(0, 1);
            }
        }
        match candidates.iter().position(|(_, _, v)| v.is_empty()) {
            Some(i) => Ok(Solved {
                position: candidates[i].1,
                solution: candidates[i].0,
                forced_by_travel: i > 0,
            }),
            None => Err(InverseError::OutOfTravel {
                violations: candidates.into_iter().flat_map(|(_, _, v)| v).collect(),
            }),
        }
    }
}

/// The angle of the rotation about unit `axis` taking `from` to `to` (their components
/// across `axis`; Paden and Kahan's first subproblem).
fn rotation_taking(axis: &Vector3<f64>, from: &Vector3<f64>, to: &Vector3<f64>) -> f64 {
    let a = from - axis * axis.dot(from);
    let b = to - axis * axis.dot(to);
    axis.dot(&a.cross(&b)).atan2(a.dot(&b))
}

#[cfg(test)]
mod tests;
