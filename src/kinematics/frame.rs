//! The program coordinate system of a machine, as a CNC defines it (ISO 841): program +X is
//! where the X axis moves the tool relative to the workpiece, whatever the orientation of the
//! URDF's frames and whichever of tool and table the axis moves; machine zero is where the tool
//! is on the part with every axis at its home (a work offset, G54, is the program reader's).
//!
//! Every figure that compares the tool with the programmed path (contour error, path speed,
//! the tool path, the planner's tool-tip figures) is taken in this frame, from the tool point
//! relative to the frame's carrier link: an offset, a rotated CAD frame or a moving table can
//! then never show up as error.

use super::link_poses;
use crate::diagnostics::FileError;
use crate::machine::{DrivesFile, JointKind, Machine};
use nalgebra::{Matrix3, Point3, Vector3};

/// Largest |cos| between two program axes (about 0.06° from a right angle): above the rounding
/// of CAD-exported frames, below any real machine's squareness error worth simulating.
pub const ORTHOGONALITY_TOLERANCE: f64 = 1e-3;

/// How far the tool's travel per unit of a linear axis may be from 1 (a `<mimic>` follower on
/// the tool's or the part's chain adds its own travel): round-off of CAD frames, nothing more.
const RATIO_TOLERANCE: f64 = 1e-6;

/// The program frame of a machine: where program coordinates are, in the carrier link's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgramFrame {
    /// The link the frame is fixed in: the workpiece link, or, where rotary axes carry the
    /// workpiece (a tilting table), the link those axes stand on.
    pub carrier: usize,
    /// Columns: program +X, +Y, +Z in the carrier's frame (unit vectors at right angles,
    /// within [`ORTHOGONALITY_TOLERANCE`]).
    pub directions: Matrix3<f64>,
    /// Program coordinates of a carrier-frame vector: the inverse of `directions`, exact for
    /// frames that are not quite square. `None` where `directions` is the identity, so a
    /// machine whose frames are aligned has its figures untouched by round-off.
    to_program: Option<Matrix3<f64>>,
    /// The tool point at machine zero (every axis at its home), in the carrier's frame (m).
    pub origin: Point3<f64>,
}

impl ProgramFrame {
    /// The frame of `machine`, and its warnings (a left-handed set of axes). Refuses axes that
    /// are not at right angles, or that do not move the tool against the part.
    pub fn new(machine: &Machine) -> Result<(ProgramFrame, Vec<FileError>), FileError> {
        let carrier = carrier_link(machine);
        let home: Vec<f64> = machine.axes.iter().map(|a| a.drive.home).collect();
        let poses = link_poses(machine, &home);
        let on_chain = |link: usize| chain_joints(machine, link);
        let tool_chain = on_chain(machine.tool_link);
        let carrier_chain = on_chain(carrier);
        let carrier_rotation = poses[carrier].rotation;
        let couplings = machine.couplings();
        let urdf = &machine.urdf_path;
        let mut found: [Option<(usize, Vector3<f64>)>; 3] = [None; 3];
        for (i, axis) in machine.axes.iter().enumerate() {
            let Some(letter) = ["x", "y", "z"].iter().position(|l| *l == axis.name) else {
                continue;
            };
            let joint = &machine.joints[axis.joint];
            let place = joint.place;
            if joint.kind != JointKind::Prismatic {
                return Err(FileError::new(
                    urdf,
                    place,
                    format!(
                        "axis {} drives joint '{}', which turns: the letters x, y, z name linear axes, a, b, c rotary ones",
                        axis.name.to_uppercase(),
                        joint.name
                    ),
                ));
            }
            // Where one unit of the axis moves the tool relative to the part (world frame):
            // its own joint, and the <mimic> followers coupled to it that sit on either chain.
            let mut motion = Vector3::zeros();
            let mut moves_both = false;
            let followers = couplings
                .iter()
                .filter(|c| c.leader == axis.joint)
                .map(|c| (c.follower, c.multiplier));
            for (j, multiplier) in std::iter::once((axis.joint, 1.0)).chain(followers) {
                let moved = &machine.joints[j];
                let side = match (tool_chain.contains(&j), carrier_chain.contains(&j)) {
                    (true, false) => 1.0,
                    (false, true) => -1.0,
                    (both, _) => {
                        moves_both |= both;
                        continue;
                    }
                };
                if moved.kind != JointKind::Prismatic {
                    return Err(FileError::new(
                        urdf,
                        moved.place,
                        format!(
                            "joint '{}' follows axis {} (joint '{}') through its <mimic> and turns the {}: cncsim's linear axes move the tool on the part along straight lines",
                            moved.name,
                            axis.name.to_uppercase(),
                            joint.name,
                            if side > 0.0 { "tool" } else { "workpiece" }
                        ),
                    ));
                }
                let world = (poses[moved.parent] * moved.origin).rotation * moved.axis;
                motion += world * (side * multiplier);
            }
            if motion.norm() < 1e-9 {
                let what = if moves_both {
                    "moves the tool and the workpiece together"
                } else {
                    "moves neither the tool nor the workpiece"
                };
                return Err(FileError::new(
                    urdf,
                    place,
                    format!(
                        "axis {} (joint '{}') {what} (tool link '{}', workpiece link '{}'): it cannot move the tool on the part",
                        axis.name.to_uppercase(),
                        joint.name,
                        machine.links[machine.tool_link].name,
                        machine.links[machine.workpiece_link].name
                    ),
                ));
            }
            if (motion.norm() - 1.0).abs() > RATIO_TOLERANCE {
                return Err(FileError::new(
                    urdf,
                    place,
                    format!(
                        "axis {} (joint '{}') moves the tool {:.6} mm on the part per mm of its joint, its <mimic> followers included: program coordinates are joint coordinates, so cncsim needs 1",
                        axis.name.to_uppercase(),
                        joint.name,
                        motion.norm()
                    ),
                ));
            }
            let direction = carrier_rotation.inverse() * motion * f64::from(axis.drive.sign);
            found[letter] = Some((i, direction.normalize()));
        }
        let letters = ["X", "Y", "Z"];
        for a in 0..3 {
            for b in a + 1..3 {
                let (Some((i, u)), Some((j, v))) = (found[a], found[b]) else {
                    continue;
                };
                let cos = u.dot(&v);
                if cos.abs() > ORTHOGONALITY_TOLERANCE {
                    let (ja, jb) = (
                        &machine.joints[machine.axes[i].joint],
                        &machine.joints[machine.axes[j].joint],
                    );
                    return Err(FileError::new(
                        urdf,
                        ja.place,
                        format!(
                            "axes {} (joint '{}', direction {}) and {} (joint '{}', direction {}) are {:.3}° apart: program axes X, Y, Z must be at right angles (ISO 841). Directions are where each axis moves the tool relative to the workpiece (link '{}'), in that link's frame",
                            letters[a],
                            ja.name,
                            show(&u),
                            letters[b],
                            jb.name,
                            show(&v),
                            cos.clamp(-1.0, 1.0).acos().to_degrees(),
                            machine.links[carrier].name
                        ),
                    ));
                }
            }
        }
        let directions = complete(found.map(|f| f.map(|(_, d)| d)));
        let mut warnings = Vec::new();
        if directions.determinant() < 0.0 {
            // Suggest the axis that points most against its namesake of the carrier's frame.
            let flip = (0..3)
                .filter(|&c| found[c].is_some())
                .min_by(|&a, &b| directions[(a, a)].total_cmp(&directions[(b, b)]))
                .unwrap_or(1);
            warnings.push(FileError::new(
                &DrivesFile::path_for(urdf),
                None,
                format!(
                    "the axes X {}, Y {}, Z {} (in the frame of link '{}') are left-handed: parts come out mirrored. Flip one axis: `sign = -1` in [axes.{}]",
                    show(&directions.column(0).into()),
                    show(&directions.column(1).into()),
                    show(&directions.column(2).into()),
                    machine.links[carrier].name,
                    letters[flip].to_lowercase()
                ),
            ));
        }
        // ISO 841: +Z points from the part towards the tool, up on a machine whose Z is
        // vertical (the URDF's +z is up, REP 103).
        let up = (carrier_rotation * directions.column(2)).normalize().z;
        if found[2].is_some() && up < -0.5 {
            warnings.push(FileError::new(
                &DrivesFile::path_for(urdf),
                None,
                format!(
                    "program +Z points down (its direction {} in link '{}' is {:.1}° from the URDF's +z): ISO 841's +Z points from the part towards the tool, so a program's Z moves come out upside down. Flip it: `sign = -1` in [axes.z], and in one of [axes.x], [axes.y] to stay right-handed",
                    show(&directions.column(2).into()),
                    machine.links[carrier].name,
                    up.clamp(-1.0, 1.0).acos().to_degrees()
                ),
            ));
        }
        let to_program = (directions != Matrix3::identity()).then(|| {
            directions
                .try_inverse()
                .expect("axes at right angles within tolerance are independent")
        });
        let origin = super::tool_in_link(machine, carrier, &home);
        Ok((
            ProgramFrame {
                carrier,
                directions,
                to_program,
                origin,
            },
            warnings,
        ))
    }

    /// Machine coordinates along the program axes (m) of a point given in the carrier's frame.
    pub fn program_point(&self, carrier_point: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.program_vector(&(carrier_point - self.origin)))
    }

    /// Program-frame components of a vector given in the carrier's frame.
    pub fn program_vector(&self, v: &Vector3<f64>) -> Vector3<f64> {
        match &self.to_program {
            None => *v,
            Some(m) => m * v,
        }
    }

    /// The carrier-frame point of program coordinates `p` (m).
    pub fn carrier_point(&self, p: &Point3<f64>) -> Point3<f64> {
        self.origin + self.directions * p.coords
    }
}

/// The link a machine's program frame is fixed in: the workpiece link, unless a rotary joint
/// lies between it and the base; then the last link before the first such joint (the link the
/// rotary axes stand on). Between that link and the base only linear and fixed joints lie, so
/// the carrier never turns.
pub fn carrier_link(machine: &Machine) -> usize {
    let mut chain = chain_joints(machine, machine.workpiece_link);
    chain.reverse(); // from the base down
    let mut carrier = machine.root;
    for j in chain {
        let joint = &machine.joints[j];
        if joint.kind == JointKind::Revolute {
            break;
        }
        carrier = joint.child;
    }
    carrier
}

/// The joints from the base to `link` (from `link` up).
pub fn chain_joints(machine: &Machine, mut link: usize) -> Vec<usize> {
    let mut chain = Vec::new();
    while let Some(j) = machine.parent_joint(link) {
        chain.push(j);
        link = machine.joints[j].parent;
    }
    chain
}

/// The program axes from the directions the machine has: a missing one completes a
/// right-handed set (two missing: the carrier's own axis least aligned with the one given).
fn complete(found: [Option<Vector3<f64>>; 3]) -> Matrix3<f64> {
    let own = [Vector3::x(), Vector3::y(), Vector3::z()];
    let mut d: [Option<Vector3<f64>>; 3] = found;
    let given: Vec<usize> = (0..3).filter(|&i| d[i].is_some()).collect();
    if given.len() == 1 {
        let g = d[given[0]].expect("given");
        // The next axis after the given one: the carrier frame's own axis of that name, unless
        // it is nearly along the given one (then the carrier's axis least along it).
        let next = (given[0] + 1) % 3;
        let helper = if own[next].dot(&g).abs() < 0.9 {
            &own[next]
        } else {
            own.iter()
                .min_by(|a, b| a.dot(&g).abs().total_cmp(&b.dot(&g).abs()))
                .expect("three axes")
        };
        d[next] = Some((helper - g * helper.dot(&g)).normalize());
    }
    if d.iter().all(Option::is_none) {
        return Matrix3::identity();
    }
    for i in 0..3 {
        if d[i].is_none() {
            let (a, b) = (
                d[(i + 1) % 3].expect("two given"),
                d[(i + 2) % 3].expect("two given"),
            );
            d[i] = Some(a.cross(&b).normalize());
        }
    }
    Matrix3::from_columns(&d.map(|v| v.expect("completed")))
}

fn show(v: &Vector3<f64>) -> String {
    format!("[{:.4}, {:.4}, {:.4}]", v.x, v.y, v.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_axes_complete_a_right_handed_set() {
        let x = Vector3::x();
        let y = Vector3::y();
        assert_eq!(complete([Some(x), Some(y), None]), Matrix3::identity());
        assert_eq!(complete([Some(x), None, None]), Matrix3::identity());
        assert_eq!(complete([None, None, None]), Matrix3::identity());
        assert_eq!(complete([None, Some(y), None]), Matrix3::identity());
        assert_eq!(
            complete([None, None, Some(Vector3::z())]),
            Matrix3::identity()
        );
        let m = complete([None, Some(-Vector3::z()), None]);
        assert!((m.determinant() - 1.0).abs() < 1e-12);
        assert_eq!(m.column(1).into_owned(), -Vector3::z());
    }
}
