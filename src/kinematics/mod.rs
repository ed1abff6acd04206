//! Machine kinematics: how program coordinates become machine-axis coordinates.
//!
//! A Cartesian machine (the XYZ table) maps each program axis letter to the machine axis of the
//! same name one to one (LinuxCNC's "trivial kinematics"); five-axis machines add inverse
//! kinematics here: the A-C table's closed form ([`ac_table`]) and any chain's
//! ([`five_axis`]), which put cutter-location data and tool-tip programs on the axes
//! ([`tool_tip`]).

pub mod ac_table;
pub mod five_axis;
mod frame;
mod part;
pub mod tool_path;
pub mod tool_tip;

pub use frame::{carrier_link, chain_joints, ProgramFrame, ORTHOGONALITY_TOLERANCE};
pub use part::PartPlacement;

pub use ac_table::{
    AcAxes, AcAxis, AcInverseError, AcSolution, AcTableKinematics, AcTopologyError, Branch,
    CutterLocation, RotarySolutions, TravelViolation,
};

use crate::machine::Machine;
use crate::program::Position;

/// Where each machine axis takes its coordinate from in a program [`Position`] (in machine
/// coordinates: a work offset is the program reader's), and how: joint = home + sign ×
/// coordinate. On a plain machine (sign +1, home 0) the program's numbers are the joints'.
/// ISO 841's secondary axes (U V W, D E) have no program coordinate: programs hold them at
/// their home.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisMap {
    /// For machine axis i: (linear?, index into `Position::linear` or `Position::rotary`), or
    /// `None` for a secondary axis held at home.
    sources: Vec<Option<(bool, usize)>>,
    /// For machine axis i: (sign, home), where not (1, 0).
    affine: Vec<Option<(f64, f64)>>,
    /// For machine axis i: whether it turns.
    rotary: Vec<bool>,
}

/// A machine axis whose name is not an axis letter; holds the name.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("machine axis '{0}' has no program coordinate (expected one of x, y, z, a, b, c, or a secondary axis u, v, w, d, e)")]
pub struct UnknownAxis(pub String);

/// The program letters and where each takes its coordinate from in a [`Position`]: (letter,
/// linear?, index).
pub const PROGRAM_LETTERS: [(&str, bool, usize); 6] = [
    ("x", true, 0),
    ("y", true, 1),
    ("z", true, 2),
    ("a", false, 0),
    ("b", false, 1),
    ("c", false, 2),
];
/// ISO 841's secondary letters, which programs hold at home.
const SECONDARY_LETTERS: [&str; 5] = ["u", "v", "w", "d", "e"];

impl AxisMap {
    /// Trivial kinematics: machine axis `x` takes program X, and so on, each with its drive's
    /// sign and home.
    pub fn new(machine: &Machine) -> Result<AxisMap, UnknownAxis> {
        let mut map = Self::joint_coordinates(machine)?;
        for (i, axis) in machine.axes.iter().enumerate() {
            let (sign, home) = (f64::from(axis.drive.sign), axis.drive.home);
            if sign != 1.0 || home != 0.0 || map.sources[i].is_none() {
                map.affine[i] = Some((sign, home));
            }
        }
        Ok(map)
    }

    /// Program coordinates that are joint coordinates (the A-C table's inverse kinematics
    /// gives joint coordinates).
    pub fn joint_coordinates(machine: &Machine) -> Result<AxisMap, UnknownAxis> {
        let sources: Vec<Option<(bool, usize)>> = machine
            .axes
            .iter()
            .map(
                |a| match PROGRAM_LETTERS.iter().find(|(l, _, _)| *l == a.name) {
                    Some(&(_, linear, i)) => Ok(Some((linear, i))),
                    None if SECONDARY_LETTERS.contains(&a.name.as_str()) => Ok(None),
                    None => Err(UnknownAxis(a.name.clone())),
                },
            )
            .collect::<Result<_, _>>()?;
        let affine = vec![None; sources.len()];
        // A program letter's kind is its letter's (A B C turn); a secondary axis's, its joint's.
        let rotary = (sources.iter().zip(&machine.axes))
            .map(|(source, a)| source.map_or(a.is_rotary(machine), |(linear, _)| !linear))
            .collect();
        Ok(AxisMap {
            sources,
            affine,
            rotary,
        })
    }

    /// A map from explicit sources: (linear?, index) per machine axis.
    #[cfg(test)]
    pub(crate) fn from_sources(sources: Vec<(bool, usize)>) -> AxisMap {
        let affine = vec![None; sources.len()];
        let rotary = sources.iter().map(|&(linear, _)| !linear).collect();
        AxisMap {
            sources: sources.into_iter().map(Some).collect(),
            affine,
            rotary,
        }
    }

    /// The machine axis fed by a program coordinate (linear index 0–2 = X, Y, Z; rotary 0–2 =
    /// A, B, C), if the machine has one.
    pub fn machine_axis(&self, linear: bool, index: usize) -> Option<usize> {
        self.sources
            .iter()
            .position(|&s| s == Some((linear, index)))
    }

    /// Whether machine axis `i` is a rotary one (A, B, C, or a turning secondary axis).
    pub fn is_rotary(&self, i: usize) -> bool {
        self.rotary[i]
    }

    /// Number of machine axes.
    pub fn axes(&self) -> usize {
        self.sources.len()
    }

    /// Machine-axis coordinates of a program position (a secondary axis: its home).
    pub fn machine_axes(&self, p: &Position, out: &mut [f64]) {
        for ((o, &source), affine) in out.iter_mut().zip(&self.sources).zip(&self.affine) {
            let v = match source {
                Some((true, i)) => p.linear[i],
                Some((false, i)) => p.rotary[i],
                None => 0.0,
            };
            *o = match affine {
                None => v,
                Some((sign, zero)) => zero + sign * v,
            };
        }
    }

    /// Machine-axis components of a program-frame vector (a velocity, a direction).
    pub fn machine_vector(&self, v: &Position, out: &mut [f64]) {
        for ((o, &source), affine) in out.iter_mut().zip(&self.sources).zip(&self.affine) {
            let c = match source {
                Some((true, i)) => v.linear[i],
                Some((false, i)) => v.rotary[i],
                None => 0.0,
            };
            *o = match affine {
                Some((sign, _)) if *sign < 0.0 => -c,
                _ => c,
            };
        }
    }

    /// An arc of the program in the plane of machine axes `plane` = (i, j): its centre on
    /// those axes and its sense there (a mirrored axis turns clockwise into anticlockwise).
    pub fn machine_arc(
        &self,
        plane: [usize; 2],
        center: [f64; 2],
        clockwise: bool,
    ) -> ([f64; 2], bool) {
        let mut mirrored = false;
        let mut out = center;
        for (o, &axis) in out.iter_mut().zip(&plane) {
            if let Some((sign, zero)) = self.affine[axis] {
                *o = zero + sign * *o;
                mirrored ^= sign < 0.0;
            }
        }
        (out, clockwise ^ mirrored)
    }

    /// Program position of machine-axis coordinates (axes the machine lacks stay at zero).
    pub fn program_position(&self, q: &[f64]) -> Position {
        let mut p = Position::default();
        for ((&v, &source), affine) in q.iter().zip(&self.sources).zip(&self.affine) {
            let v = match affine {
                None => v,
                Some((sign, zero)) => sign * (v - zero),
            };
            match source {
                Some((true, i)) => p.linear[i] = v,
                Some((false, i)) => p.rotary[i] = v,
                None => {}
            }
        }
        p
    }
}

/// World pose of every link for joint coordinates `q` (one per machine axis, in axis order):
/// the forward kinematics of the URDF tree, `<mimic>` followers where their leaders put them.
pub fn link_poses(machine: &Machine, q: &[f64]) -> Vec<nalgebra::Isometry3<f64>> {
    let joint_value = machine.joint_coordinates(q);
    let mut poses = vec![nalgebra::Isometry3::identity(); machine.links.len()];
    for (j, joint) in machine.joints.iter().enumerate() {
        poses[joint.child] = poses[joint.parent] * joint.origin * joint.motion(joint_value[j]);
    }
    poses
}

/// Tool point in the machine base frame for joint coordinates `q`.
pub fn tool_point(machine: &Machine, q: &[f64]) -> nalgebra::Point3<f64> {
    link_poses(machine, q)[machine.tool_link] * nalgebra::Point3::from(machine.tool.offset_m)
}

/// Tool point in the workpiece link's frame for joint coordinates `q`: where the tool is on
/// the part, whichever of them the axes move.
pub fn tool_in_workpiece(machine: &Machine, q: &[f64]) -> nalgebra::Point3<f64> {
    tool_in_link(machine, machine.workpiece_link, q)
}

/// Tool point in the frame of `link` for joint coordinates `q`.
pub fn tool_in_link(machine: &Machine, link: usize, q: &[f64]) -> nalgebra::Point3<f64> {
    let poses = link_poses(machine, q);
    let tool = poses[machine.tool_link] * nalgebra::Point3::from(machine.tool.offset_m);
    if link == machine.root {
        // The base's frame is the world's.
        return tool;
    }
    poses[link].inverse_transform_point(&tool)
}
