//! Closed-form kinematics of the table-tilting A-C mill (docs/sources.md §3.1): cutter-location
//! data in workpiece coordinates ⇄ machine axes X, Y, Z, A, C.
//!
//! # The machine, as read from the URDF
//!
//! Two branches leave the machine base. The spindle rides three prismatic joints along base
//! X, Y, Z; the workpiece rides a revolute joint A about base X (the cradle) and, on the
//! cradle, a revolute joint C about the cradle's Z (the rotary table). [`AcTableKinematics::new`]
//! finds both chains in the URDF tree and keeps every offset and axis direction it finds
//! there; nothing below is specific to the numbers of `models/ac_mill.urdf`.
//!
//! # Conventions
//!
//! * Lengths in metres, angles in radians, all frames right-handed; "base" is the URDF root.
//! * The tool point is the drive file's tool offset in the tool link (for the A-C mill: the
//!   tool tip, at the tool link's origin).
//! * **Tool axis** `O`: the APT / ISO 3592 convention, a unit vector along the tool pointing
//!   **from the tool tip towards the spindle**. On this machine that is the tool link's +Z
//!   (the spindle head sits above the tip), expressed in the workpiece frame. A tool axis of
//!   (0, 0, 1) therefore means "spindle vertical above the part" (A = 0).
//! * Machine coordinates are the URDF joint coordinates: positive A turns the cradle
//!   right-handed about its URDF axis, positive C the table about its URDF axis.
//!
//! # Derivation (forward)
//!
//! With every transform composed along the URDF chain (origins `T_*`, joint motions `Rot`):
//!
//! ```text
//! T_w(A, C) = T_A0 · Rot(a_A, A) · T_AC · Rot(a_C, C) · T_Cw        (base ← workpiece)
//! p_t(x, y, z) = p_t0 + x·u_x + y·u_y + z·u_z                      (tool point in base)
//! P = T_w⁻¹ · p_t,   O = R_w⁻¹ · d                                  (workpiece coordinates)
//! ```
//!
//! `T_A0` takes the base to the A joint frame (fixed joints and A's origin), `T_AC` the cradle
//! to the C joint frame, `T_Cw` the table to the workpiece; `u_x, u_y, u_z` are the prismatic
//! directions in the base frame and `p_t0` the tool point at X = Y = Z = 0 (both constant:
//! prismatic joints never rotate what they carry); `d` is the spindle direction (tool link +Z)
//! in the base frame, which must be base +Z.
//!
//! # Derivation (inverse)
//!
//! Rotations only. Moving each joint rotation to the front of the product,
//! `R_A0·Rot(a_A, A) = Rot(R_A0·a_A, A)·R_A0`, gives
//!
//! ```text
//! R_w(A, C) = Rot(u_A, A) · Rot(u_C, C) · R_w0,
//! ```
//!
//! where `u_A` is A's axis in the base frame, `u_C` C's axis in the base frame at A = 0 and
//! `R_w0` the workpiece orientation at A = C = 0. The topology check demands
//! `u_A = s_A·e_x`, `u_C = s_C·e_z` (s = ±1), so with α = s_A·A, γ = s_C·C and `v = R_w0·O`
//! (the tool axis in table axes at zero; `v = O` on the A-C mill), `R_w·O = d = e_z` reads
//! `Rot_z(γ)·v = Rot_x(−α)·e_z = (0, sin α, cos α)`:
//!
//! ```text
//! v_x cos γ − v_y sin γ = 0,   v_x sin γ + v_y cos γ = sin α,   v_z = cos α.
//! ```
//!
//! Hence |sin α| = ρ = √(v_x² + v_y²), and the two solutions are
//!
//! ```text
//! branch 1:  α = atan2(ρ, v_z) ∈ [0, π],   γ = atan2(v_x, v_y)
//! branch 2:  α = −atan2(ρ, v_z),           γ = atan2(v_x, v_y) + π
//! ```
//!
//! i.e. on the A-C mill, with O = (i, j, k): **A = ±atan2(√(i² + j²), k), C = atan2(i, j)
//! (+π on the A < 0 branch)**. The study's printed A = atan(i/j), C = atan(√(i²+j²)/k) have
//! the two formulas swapped between the axes and lose the quadrant. At ρ = 0 (O along the C
//! axis) the first equation holds for every γ: C is undefined and is kept where it was.
//!
//! Translations: with A, C known, the tool point must coincide with the workpiece point:
//! `p_t0 + U·(x, y, z) = T_w(A, C)·P`, so `(x, y, z) = U⁻¹·(T_w(A, C)·P − p_t0)` with
//! `U = [u_x u_y u_z]`. Written out for the A-C mill (U = I, A axis through the base origin,
//! C axis at (0, y_AC, z_AC) on the cradle, workpiece origin w on the table, tool tip at
//! p_t0 = (0, 0, t_z) at machine zero), with (u₁, u₂, u₃) = P + w:
//!
//! ```text
//! x = u₁ cos C − u₂ sin C
//! y = (u₁ sin C + u₂ cos C + y_AC) cos A − (u₃ + z_AC) sin A
//! z = (u₁ sin C + u₂ cos C + y_AC) sin A + (u₃ + z_AC) cos A − t_z
//! ```
//!
//! with w = (0.1, 0.1, 0.1) m, y_AC = 0, z_AC = −0.15 m, t_z = 0.45 − 0.06 = 0.39 m from the
//! URDF. This is the study's eq. 9 up to its z constant: the study adds −z0203 + z0405 − z7,
//! i.e. measures z from a different machine zero; ours is the URDF's.
//!
//! # Choosing among the solutions
//!
//! Each branch's A and C are taken at the 2π multiple nearest the previous solution (within
//! the joint's travel, if it has one); the branch nearest the previous (A, C) in the
//! Euclidean sense wins, ties going to branch 1 (A ≥ 0). A branch with any axis outside its
//! travel is dropped; if both are, the error lists every violation of both.

use crate::machine::{JointKind, Machine};
use crate::program::{Position, Program, ProgramError, ProgramErrors, Warning};
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use std::f64::consts::{PI, TAU};
use std::fmt;

/// Largest deviation of a joint direction from the base axis it must follow (unit vectors):
/// far above the rounding of URDF `rpy` origins (~1e-16), far below any real misalignment
/// a URDF would describe on purpose.
const DIRECTION_TOLERANCE: f64 = 1e-9;

/// |sin A| below which the tool axis counts as along the C axis and C is kept. The tool axis
/// then reached is off the requested one by at most this angle (0.1 nrad), below every
/// tolerance a caller could state, yet well above rounding (~1e-16) so that a vector that is
/// "vertical" up to rounding does not pick a random C.
pub const SINGULAR_SIN_A: f64 = 1e-10;

/// How far a tool-axis vector's length may be from 1 and still be accepted (and normalised):
/// rounding of a normalised vector, not a vector that was never normalised.
pub const UNIT_TOLERANCE: f64 = 1e-9;

/// Travel slack (m or rad): a point computed exactly at a travel limit must not fail on the
/// last bit of rounding.
const TRAVEL_SLACK: f64 = 1e-9;

/// The five axes of the A-C mill.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AcAxis {
    /// Spindle along base X (linear).
    X,
    /// Spindle along base Y (linear).
    Y,
    /// Spindle along base Z (linear).
    Z,
    /// Cradle tilt about base X (rotary).
    A,
    /// Rotary table about the cradle's Z (rotary).
    C,
}

impl AcAxis {
    /// All five axes in order X, Y, Z, A, C (the order of [`AcAxes::to_array`]).
    pub const ALL: [AcAxis; 5] = [AcAxis::X, AcAxis::Y, AcAxis::Z, AcAxis::A, AcAxis::C];

    /// The program letter (also the machine axis name, which the topology check enforces).
    pub fn letter(self) -> &'static str {
        match self {
            AcAxis::X => "x",
            AcAxis::Y => "y",
            AcAxis::Z => "z",
            AcAxis::A => "a",
            AcAxis::C => "c",
        }
    }

    /// Whether the axis is A or C.
    pub fn is_rotary(self) -> bool {
        matches!(self, AcAxis::A | AcAxis::C)
    }

    fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for AcAxis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.letter())
    }
}

/// Machine coordinates of the A-C mill: X, Y, Z (m) and A, C (rad), URDF joint values.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AcAxes {
    /// X axis (m).
    pub x: f64,
    /// Y axis (m).
    pub y: f64,
    /// Z axis (m).
    pub z: f64,
    /// A axis, the cradle tilt (rad).
    pub a: f64,
    /// C axis, the rotary table (rad).
    pub c: f64,
}

impl AcAxes {
    /// The coordinate of one axis (m or rad).
    pub fn get(&self, axis: AcAxis) -> f64 {
        self.to_array()[axis.index()]
    }

    /// [x, y, z, a, c].
    pub fn to_array(&self) -> [f64; 5] {
        [self.x, self.y, self.z, self.a, self.c]
    }

    /// From [x, y, z, a, c].
    pub fn from_array([x, y, z, a, c]: [f64; 5]) -> AcAxes {
        AcAxes { x, y, z, a, c }
    }

    /// As a program position: linear = (x, y, z), rotary = (A, B = 0, C).
    pub fn to_position(&self) -> Position {
        Position {
            linear: [self.x, self.y, self.z],
            rotary: [self.a, 0.0, self.c],
        }
    }

    /// From a program position holding machine coordinates (B is ignored).
    pub fn from_position(p: &Position) -> AcAxes {
        AcAxes {
            x: p.linear[0],
            y: p.linear[1],
            z: p.linear[2],
            a: p.rotary[0],
            c: p.rotary[2],
        }
    }
}

/// Cutter location in workpiece coordinates: tool point `point` (m) and tool axis `axis`
/// (unit, from the tip towards the spindle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutterLocation {
    /// Tool point in workpiece coordinates (m).
    pub point: Point3<f64>,
    /// Tool axis in workpiece coordinates: unit vector from the tip towards the spindle.
    pub axis: Vector3<f64>,
}

/// Which of the two inverse solutions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Branch {
    /// Branch 1 of the derivation: s_A·A ∈ [0, π] (A ≥ 0 on the A-C mill).
    First,
    /// Branch 2: the tilt mirrored, A → −A, C → C + π.
    Second,
    /// The tool axis lies along the C axis (|sin A| < [`SINGULAR_SIN_A`]): one A, C kept.
    Singular,
}

impl fmt::Display for Branch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Branch::First => "branch 1",
            Branch::Second => "branch 2",
            Branch::Singular => "singular (A = 0)",
        })
    }
}

/// The rotary solutions of a tool axis, principal values (A as computed, C in (−π, π]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RotarySolutions {
    /// Two solutions, `[(A, C) of branch 1, (A, C) of branch 2]`.
    Regular([(f64, f64); 2]),
    /// The tool axis is along the C axis: A is this value, C is free.
    Singular {
        /// The one A (rad).
        a: f64,
    },
}

/// An inverse-kinematics solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AcSolution {
    /// The machine coordinates.
    pub axes: AcAxes,
    /// The branch they belong to.
    pub branch: Branch,
    /// The solution nearest the previous one was outside the travel, so this one (possibly
    /// far from the previous one) was taken.
    pub forced_by_travel: bool,
}

/// One axis outside its travel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TravelViolation {
    /// The branch whose solution needs the value.
    pub branch: Branch,
    /// The axis outside its travel.
    pub axis: AcAxis,
    /// The value the axis would need (m or rad).
    pub value: f64,
    /// Lower end of the axis travel (m or rad).
    pub lower: f64,
    /// Upper end of the axis travel (m or rad).
    pub upper: f64,
}

impl fmt::Display for TravelViolation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (scale, unit) = if self.axis.is_rotary() {
            (180.0 / PI, "°")
        } else {
            (1000.0, " mm")
        };
        write!(
            f,
            "axis '{}' would be at {:.3}{unit}, outside its travel [{:.3}{unit}, {:.3}{unit}] ({})",
            self.axis,
            self.value * scale,
            self.lower * scale,
            self.upper * scale,
            self.branch
        )
    }
}

/// Why a cutter location has no machine coordinates.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AcInverseError {
    /// The tool point or the tool axis has a NaN or infinite component.
    #[error("cutter location ({p:?}, tool axis {o:?}) has a non-finite value", p = point, o = axis)]
    NotFinite {
        /// The tool point as given (m).
        point: [f64; 3],
        /// The tool axis as given.
        axis: [f64; 3],
    },
    /// The tool axis is not a unit vector (its length is off 1 by more than
    /// [`UNIT_TOLERANCE`]).
    #[error(
        "tool-axis vector ({:.6}, {:.6}, {:.6}) has length {length:.9}; expected a unit vector (normalise it first)",
        axis[0], axis[1], axis[2]
    )]
    NotUnit {
        /// The tool axis as given.
        axis: [f64; 3],
        /// Its Euclidean length.
        length: f64,
    },
    /// Every solution puts some axis outside its travel.
    #[error("outside the machine's travel: {}", list(violations))]
    OutOfTravel {
        /// Every violation of every solution tried.
        violations: Vec<TravelViolation>,
    },
}

fn list(violations: &[TravelViolation]) -> String {
    violations
        .iter()
        .map(|v| v.to_string())
        .collect::<Vec<_>>()
        .join("; ")
}

/// The machine is not a table-tilting A-C mill; `problem` says what is missing or wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("machine '{machine}' is not a table-tilting A-C mill: {problem}")]
pub struct AcTopologyError {
    /// Name of the machine.
    pub machine: String,
    /// What is missing or wrong.
    pub problem: String,
}

/// One machine axis as this kinematics uses it.
#[derive(Debug, Clone, PartialEq)]
struct AxisData {
    /// Index into `Machine::axes`.
    machine_axis: usize,
    limits: Option<[f64; 2]>,
}

/// Closed-form forward and inverse kinematics of a table-tilting A-C mill, built from the
/// machine's URDF chain (see the module documentation for the derivation).
#[derive(Debug, Clone, PartialEq)]
pub struct AcTableKinematics {
    /// In [`AcAxis`] order.
    axes: [AxisData; 5],
    /// Number of machine axes (for [`AcTableKinematics::machine_q`]).
    machine_axes: usize,
    /// Tool point in the base frame at X = Y = Z = 0.
    tool_zero: Point3<f64>,
    /// U⁻¹, U = [u_x u_y u_z] (base-frame directions of the linear axes).
    linear_inverse: Matrix3<f64>,
    linear_directions: Matrix3<f64>,
    /// Spindle direction (tool link +Z) in the base frame; validated to be +Z.
    spindle: Vector3<f64>,
    /// Base ← A joint frame at A = 0.
    base_to_a: Isometry3<f64>,
    a_axis: Unit<Vector3<f64>>,
    /// Cradle ← C joint frame at C = 0.
    a_to_c: Isometry3<f64>,
    c_axis: Unit<Vector3<f64>>,
    /// Table ← workpiece.
    c_to_workpiece: Isometry3<f64>,
    /// R_w0: workpiece orientation in the base frame at A = C = 0.
    workpiece_zero_rotation: Matrix3<f64>,
    /// A's axis is s_A·e_x, C's axis at A = 0 is s_C·e_z.
    a_sign: f64,
    c_sign: f64,
}

/// Joints from the root down to `link`, root first.
fn joints_from_root(machine: &Machine, link: usize) -> Vec<usize> {
    let mut path = Vec::new();
    let mut current = link;
    while let Some(j) = machine.parent_joint(current) {
        path.push(j);
        current = machine.joints[j].parent;
        if path.len() > machine.joints.len() {
            break; // a cycle; the URDF loader rejects those, this only guards the loop
        }
    }
    path.reverse();
    path
}

/// The pose the joints compose to with every joint coordinate at zero.
fn compose_at_zero(machine: &Machine, joints: &[usize]) -> Isometry3<f64> {
    joints.iter().fold(Isometry3::identity(), |pose, &j| {
        pose * machine.joints[j].origin
    })
}

/// ±1 if `v` is ±`e` (unit vectors) within [`DIRECTION_TOLERANCE`].
fn sign_along(v: &Vector3<f64>, e: &Vector3<f64>) -> Option<f64> {
    if (v - e).norm() < DIRECTION_TOLERANCE {
        Some(1.0)
    } else if (v + e).norm() < DIRECTION_TOLERANCE {
        Some(-1.0)
    } else {
        None
    }
}

fn show(v: &Vector3<f64>) -> String {
    let clean = |x: f64| if x.abs() < 5e-7 { 0.0 } else { x };
    format!("({:.6}, {:.6}, {:.6})", clean(v.x), clean(v.y), clean(v.z))
}

fn rotation(axis: &Unit<Vector3<f64>>, angle: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_axis_angle(axis, angle),
    )
}

/// `value + 2πk` for the k that brings it nearest `previous`, restricted to `limits`;
/// `None` if no multiple lies within the limits.
pub(super) fn nearest_turn(value: f64, previous: f64, limits: Option<[f64; 2]>) -> Option<f64> {
    let mut k = ((previous - value) / TAU).round();
    if let Some([lower, upper]) = limits {
        let k_min = ((lower - TRAVEL_SLACK - value) / TAU).ceil();
        let k_max = ((upper + TRAVEL_SLACK - value) / TAU).floor();
        if k_min > k_max {
            return None;
        }
        k = k.clamp(k_min, k_max);
    }
    Some(value + TAU * k)
}

impl AcTableKinematics {
    /// Extracts the A-C chain from `machine`, checking its topology: the tool rides exactly
    /// three prismatic joints along base X, Y, Z (driven by axes `x`, `y`, `z`); the workpiece
    /// rides exactly two revolute joints, the first about base X (axis `a`), the second about
    /// base Z at A = 0 (axis `c`); the spindle (tool link +Z) points along base +Z; no other
    /// joint moves.
    pub fn new(machine: &Machine) -> Result<AcTableKinematics, AcTopologyError> {
        let fail = |problem: String| AcTopologyError {
            machine: machine.name.clone(),
            problem,
        };
        let joint_name = |j: usize| machine.joints[j].name.as_str();
        let link_name = |l: usize| machine.links[l].name.as_str();
        let moving = |j: &usize| machine.joints[*j].kind != JointKind::Fixed;

        let tool_path = joints_from_root(machine, machine.tool_link);
        let work_path = joints_from_root(machine, machine.workpiece_link);
        let common = tool_path
            .iter()
            .zip(&work_path)
            .take_while(|(a, b)| a == b)
            .count();
        if let Some(&j) = tool_path[..common].iter().find(|j| moving(j)) {
            return Err(fail(format!(
                "joint '{}' moves both the tool and the workpiece; expected the linear axes on \
                 the tool's branch and the rotary axes on the workpiece's, meeting at the base",
                joint_name(j)
            )));
        }
        let tool_branch = &tool_path[common..];
        let work_branch = &work_path[common..];
        for (j, joint) in machine.joints.iter().enumerate() {
            if joint.kind != JointKind::Fixed
                && !tool_branch.contains(&j)
                && !work_branch.contains(&j)
            {
                return Err(fail(format!(
                    "joint '{}' moves neither the tool (link '{}') nor the workpiece (link '{}')",
                    joint.name,
                    link_name(machine.tool_link),
                    link_name(machine.workpiece_link)
                )));
            }
        }

        // The machine axis driving joint j; `attach` guarantees every moving joint has one.
        let axis_of = |j: usize, expected: AcAxis| -> Result<AxisData, AcTopologyError> {
            let index = machine
                .axes
                .iter()
                .position(|a| a.joint == j)
                .ok_or_else(|| fail(format!("joint '{}' has no drive", joint_name(j))))?;
            let name = &machine.axes[index].name;
            if name != expected.letter() {
                return Err(fail(format!(
                    "axis '{name}' drives joint '{}', which is the machine's {} axis; expected \
                     it to be named '{expected}'",
                    joint_name(j),
                    expected.letter().to_uppercase()
                )));
            }
            Ok(AxisData {
                machine_axis: index,
                limits: machine.joints[j].limits,
            })
        };

        // Tool branch: three prismatic joints along base X, Y, Z.
        let mut linear: [Option<(usize, Vector3<f64>)>; 3] = [None; 3];
        let mut pose = Isometry3::identity();
        for &j in tool_branch {
            let joint = &machine.joints[j];
            pose *= joint.origin;
            match joint.kind {
                JointKind::Fixed => {}
                JointKind::Revolute => {
                    return Err(fail(format!(
                        "revolute joint '{}' is on the tool's branch; a table-tilting A-C mill \
                         carries no rotary axis on the spindle side",
                        joint.name
                    )))
                }
                JointKind::Prismatic => {
                    let direction = pose.rotation * joint.axis;
                    let Some(k) =
                        (0..3).find(|&k| sign_along(&direction, &Vector3::ith(k, 1.0)).is_some())
                    else {
                        return Err(fail(format!(
                            "prismatic joint '{}' moves along {} in the base frame; expected \
                             the base X, Y or Z axis",
                            joint.name,
                            show(&direction)
                        )));
                    };
                    if let Some((other, _)) = linear[k] {
                        return Err(fail(format!(
                            "joints '{}' and '{}' both move the tool along base {}; expected one \
                             linear axis each along X, Y and Z",
                            joint_name(other),
                            joint.name,
                            ["X", "Y", "Z"][k]
                        )));
                    }
                    linear[k] = Some((j, direction));
                }
            }
        }
        let mut linear_joints = [(0, Vector3::zeros()); 3];
        for (k, slot) in linear.iter().enumerate() {
            linear_joints[k] = slot.ok_or_else(|| {
                fail(format!(
                    "no prismatic joint moves the tool (link '{}') along base {}",
                    link_name(machine.tool_link),
                    ["X", "Y", "Z"][k]
                ))
            })?;
        }
        let tool_pose = pose;
        let spindle = tool_pose.rotation * Vector3::z();
        if sign_along(&spindle, &Vector3::z()) != Some(1.0) {
            return Err(fail(format!(
                "the spindle direction (the tool link's +Z, from the tool tip towards the \
                 spindle) is {} in the base frame; expected base +Z (a vertical spindle above \
                 the table)",
                show(&spindle)
            )));
        }

        // Workpiece branch: revolute A about base X, then revolute C about base Z at A = 0.
        let mut rotary = Vec::new();
        for (i, &j) in work_branch.iter().enumerate() {
            match machine.joints[j].kind {
                JointKind::Fixed => {}
                JointKind::Prismatic => {
                    return Err(fail(format!(
                        "prismatic joint '{}' is on the workpiece's branch; a table-tilting A-C \
                         mill moves the workpiece only by the A and C rotary axes",
                        joint_name(j)
                    )))
                }
                JointKind::Revolute => rotary.push(i),
            }
        }
        let &[ia, ic] = rotary.as_slice() else {
            let names: Vec<String> = rotary
                .iter()
                .map(|&i| format!("'{}'", joint_name(work_branch[i])))
                .collect();
            return Err(fail(format!(
                "{} revolute joint(s) carry the workpiece (link '{}'){}; expected two: A \
                 about base X, carrying C about the table's Z",
                rotary.len(),
                link_name(machine.workpiece_link),
                if names.is_empty() {
                    String::new()
                } else {
                    format!(": {}", names.join(", "))
                }
            )));
        };
        let (ja, jc) = (work_branch[ia], work_branch[ic]);
        let base_to_a = compose_at_zero(machine, &work_branch[..=ia]);
        let a_to_c = compose_at_zero(machine, &work_branch[ia + 1..=ic]);
        let c_to_workpiece = compose_at_zero(machine, &work_branch[ic + 1..]);
        let a_axis = Unit::new_normalize(machine.joints[ja].axis);
        let c_axis = Unit::new_normalize(machine.joints[jc].axis);
        let u_a = base_to_a.rotation * a_axis.into_inner();
        let u_c = (base_to_a * a_to_c).rotation * c_axis.into_inner();
        let a_sign = sign_along(&u_a, &Vector3::x()).ok_or_else(|| {
            fail(format!(
                "the first rotary joint from the base to the workpiece, '{}', turns about {} in \
                 the base frame; expected the base X axis (the A axis tilting the cradle)",
                joint_name(ja),
                show(&u_a)
            ))
        })?;
        let c_sign = sign_along(&u_c, &Vector3::z()).ok_or_else(|| {
            fail(format!(
                "the second rotary joint, '{}' (carried by '{}'), turns about {} in the base \
                 frame at A = 0; expected the base Z axis (the C table)",
                joint_name(jc),
                joint_name(ja),
                show(&u_c)
            ))
        })?;

        let axes = [
            axis_of(linear_joints[0].0, AcAxis::X)?,
            axis_of(linear_joints[1].0, AcAxis::Y)?,
            axis_of(linear_joints[2].0, AcAxis::Z)?,
            axis_of(ja, AcAxis::A)?,
            axis_of(jc, AcAxis::C)?,
        ];
        let linear_directions =
            Matrix3::from_columns(&[linear_joints[0].1, linear_joints[1].1, linear_joints[2].1]);
        // Signed unit columns along X, Y, Z: a signed permutation, invertible by construction.
        let linear_inverse = linear_directions
            .try_inverse()
            .ok_or_else(|| fail("the linear axes do not span space".into()))?;
        let workpiece_zero_rotation = (base_to_a * a_to_c * c_to_workpiece)
            .rotation
            .to_rotation_matrix()
            .into_inner();
        Ok(AcTableKinematics {
            axes,
            machine_axes: machine.axes.len(),
            tool_zero: tool_pose * Point3::from(machine.tool.offset_m),
            linear_inverse,
            linear_directions,
            spindle,
            base_to_a,
            a_axis,
            a_to_c,
            c_axis,
            c_to_workpiece,
            workpiece_zero_rotation,
            a_sign,
            c_sign,
        })
    }

    /// Travel of an axis (m or rad), `None` for an unlimited (continuous) joint.
    pub fn limits(&self, axis: AcAxis) -> Option<[f64; 2]> {
        self.axes[axis.index()].limits
    }

    /// Index into `Machine::axes` of an axis.
    pub fn machine_axis(&self, axis: AcAxis) -> usize {
        self.axes[axis.index()].machine_axis
    }

    /// Joint coordinates in machine-axis order (for `kinematics::link_poses`).
    pub fn machine_q(&self, q: &AcAxes) -> Vec<f64> {
        let mut out = vec![0.0; self.machine_axes];
        for axis in AcAxis::ALL {
            out[self.machine_axis(axis)] = q.get(axis);
        }
        out
    }

    /// Machine coordinates from joint coordinates in machine-axis order.
    pub fn axes_from_machine_q(&self, q: &[f64]) -> AcAxes {
        let v = |axis: AcAxis| q[self.machine_axis(axis)];
        AcAxes {
            x: v(AcAxis::X),
            y: v(AcAxis::Y),
            z: v(AcAxis::Z),
            a: v(AcAxis::A),
            c: v(AcAxis::C),
        }
    }

    /// Pose of the workpiece frame in the base frame: T_w(A, C) = T_A0·Rot(A)·T_AC·Rot(C)·T_Cw.
    pub fn workpiece_pose(&self, a: f64, c: f64) -> Isometry3<f64> {
        self.base_to_a
            * rotation(&self.a_axis, a)
            * self.a_to_c
            * rotation(&self.c_axis, c)
            * self.c_to_workpiece
    }

    /// Tool point in the base frame.
    pub fn tool_point(&self, q: &AcAxes) -> Point3<f64> {
        self.tool_zero + self.linear_directions * Vector3::new(q.x, q.y, q.z)
    }

    /// Forward kinematics: machine coordinates → cutter location in workpiece coordinates.
    pub fn forward(&self, q: &AcAxes) -> CutterLocation {
        let workpiece = self.workpiece_pose(q.a, q.c);
        CutterLocation {
            point: workpiece.inverse_transform_point(&self.tool_point(q)),
            axis: workpiece.inverse_transform_vector(&self.spindle),
        }
    }

    /// Checks a tool-axis vector and returns it exactly normalised.
    fn unit_axis(&self, cl: &CutterLocation) -> Result<Vector3<f64>, AcInverseError> {
        let (p, o) = (cl.point, cl.axis);
        if !(p.iter().all(|v| v.is_finite()) && o.iter().all(|v| v.is_finite())) {
            return Err(AcInverseError::NotFinite {
                point: [p.x, p.y, p.z],
                axis: [o.x, o.y, o.z],
            });
        }
        let length = o.norm();
        if (length - 1.0).abs() > UNIT_TOLERANCE {
            return Err(AcInverseError::NotUnit {
                axis: [o.x, o.y, o.z],
                length,
            });
        }
        Ok(o / length)
    }

    /// Rotary solutions of a unit tool axis `o` (workpiece coordinates), principal values.
    pub fn rotary_solutions(&self, o: &Vector3<f64>) -> RotarySolutions {
        // v = R_w0·O: the tool axis in the table's axes at A = C = 0 (see the module docs).
        let v = self.workpiece_zero_rotation * o;
        let rho = v.x.hypot(v.y);
        let alpha = rho.atan2(v.z);
        if rho < SINGULAR_SIN_A {
            // α = 0 (or π for a tool axis pointing down the C axis); γ is free.
            return RotarySolutions::Singular {
                a: self.a_sign * 0.0f64.atan2(v.z),
            };
        }
        let gamma = v.x.atan2(v.y);
        let gamma_mirror = if gamma > 0.0 { gamma - PI } else { gamma + PI };
        RotarySolutions::Regular([
            (self.a_sign * alpha, self.c_sign * gamma),
            (-self.a_sign * alpha, self.c_sign * gamma_mirror),
        ])
    }

    /// Linear axes that put the tool point on workpiece point `p` at rotary angles `a`, `c`:
    /// (x, y, z) = U⁻¹·(T_w(A, C)·P − p_t0).
    pub fn linear_axes(&self, p: &Point3<f64>, a: f64, c: f64) -> Vector3<f64> {
        self.linear_inverse * (self.workpiece_pose(a, c) * p - self.tool_zero)
    }

    fn violation(&self, branch: Branch, axis: AcAxis, value: f64) -> Option<TravelViolation> {
        let [lower, upper] = self.limits(axis)?;
        (value < lower - TRAVEL_SLACK || value > upper + TRAVEL_SLACK).then_some(TravelViolation {
            branch,
            axis,
            value,
            lower,
            upper,
        })
    }

    /// One branch's candidate: rotary angles at the turn nearest `previous`, linear axes, and
    /// whatever lies outside the travel.
    fn candidate(
        &self,
        branch: Branch,
        point: &Point3<f64>,
        (a, c): (f64, f64),
        previous: &AcAxes,
    ) -> (AcAxes, Vec<TravelViolation>) {
        let mut violations = Vec::new();
        let mut turned = |axis: AcAxis, value: f64, previous: f64| {
            nearest_turn(value, previous, self.limits(axis)).unwrap_or_else(|| {
                violations.extend(self.violation(branch, axis, value));
                value
            })
        };
        let a = turned(AcAxis::A, a, previous.a);
        let c = turned(AcAxis::C, c, previous.c);
        let linear = self.linear_axes(point, a, c);
        let q = AcAxes {
            x: linear.x,
            y: linear.y,
            z: linear.z,
            a,
            c,
        };
        for axis in [AcAxis::X, AcAxis::Y, AcAxis::Z] {
            violations.extend(self.violation(branch, axis, q.get(axis)));
        }
        (q, violations)
    }

    /// Inverse kinematics with the continuity rule: of the solutions within the travel, the
    /// one whose (A, C) is nearest `previous` (each angle at its nearest 2π multiple); along
    /// the C axis (A = 0) C stays at `previous.c`.
    pub fn inverse(
        &self,
        cl: &CutterLocation,
        previous: &AcAxes,
    ) -> Result<AcSolution, AcInverseError> {
        let o = self.unit_axis(cl)?;
        let mut candidates: Vec<(Branch, AcAxes, Vec<TravelViolation>)> = match self
            .rotary_solutions(&o)
        {
            RotarySolutions::Singular { a } => {
                let (q, v) = self.candidate(Branch::Singular, &cl.point, (a, previous.c), previous);
                vec![(Branch::Singular, q, v)]
            }
            RotarySolutions::Regular([first, second]) => {
                let (q1, v1) = self.candidate(Branch::First, &cl.point, first, previous);
                let (q2, v2) = self.candidate(Branch::Second, &cl.point, second, previous);
                vec![(Branch::First, q1, v1), (Branch::Second, q2, v2)]
            }
        };
        let distance = |q: &AcAxes| (q.a - previous.a).powi(2) + (q.c - previous.c).powi(2);
        // Branch 2 goes first only if it is nearer by more than rounding: an exact tie (the
        // previous position half-way between the branches) goes to branch 1 whatever the
        // last bits of atan2 say.
        if candidates.len() == 2 && distance(&candidates[1].1) < distance(&candidates[0].1) - 1e-12
        {
            candidates.swap(0, 1);
        }
        match candidates.iter().position(|(_, _, v)| v.is_empty()) {
            Some(i) => Ok(AcSolution {
                axes: candidates[i].1,
                branch: candidates[i].0,
                forced_by_travel: i > 0,
            }),
            None => Err(AcInverseError::OutOfTravel {
                violations: candidates.into_iter().flat_map(|(_, _, v)| v).collect(),
            }),
        }
    }

    /// Converts APT CL moves (workpiece coordinates, `tool_axis: Some(..)`) into machine-axis
    /// moves: `end.linear` = (x, y, z), `end.rotary` = (A, 0, C), solved in program order with
    /// the continuity rule from `start` (the machine's position before the program, which
    /// also becomes the new program's `start`). Spans, feeds, feed rules, blends, spindle and
    /// tool state are kept; `tool_axis` becomes `None` because the orientation now lives in
    /// A and C (and a converted program must not be converted again). Dwells stay where the
    /// machine is. Every move that cannot be converted is reported, each at its line; after
    /// a failed move the next one continues from the last good position. A move that had to
    /// take the far branch because the near one is outside the travel adds a warning.
    pub fn program_to_machine(
        &self,
        program: &Program,
        start: &AcAxes,
    ) -> Result<Program, ProgramErrors> {
        let mut errors = Vec::new();
        let mut warnings = program.warnings.clone();
        let mut moves = Vec::with_capacity(program.moves.len());
        let mut previous = *start;
        for m in &program.moves {
            // ProgramError's display leads with `file:line:column`, naming the line.
            let error = |problem: String, hint: &str| {
                ProgramError::new(program.source.clone(), Some(m.span), problem).hint(hint)
            };
            let mut converted = m.clone();
            converted.tool_axis = None;
            match super::tool_tip::cl_target(program, m) {
                Err(e) => {
                    errors.push(e);
                    continue;
                }
                Ok(None) => {}
                Ok(Some(target)) => {
                    let cl = CutterLocation {
                        point: target.point,
                        axis: target.axis,
                    };
                    match self.inverse(&cl, &previous) {
                        Ok(solution) => {
                            if solution.forced_by_travel {
                                warnings.push(Warning {
                                    span: m.span,
                                    message: format!(
                                        "line {}: the solution nearest the previous position is \
                                         outside the travel; took {} (A = {:.3}°, C = {:.3}°), a \
                                         large rotary move",
                                        m.span.line,
                                        solution.branch,
                                        solution.axes.a.to_degrees(),
                                        solution.axes.c.to_degrees()
                                    ),
                                });
                            }
                            previous = solution.axes;
                        }
                        Err(e) => {
                            let hint = match e {
                                AcInverseError::OutOfTravel { .. } => {
                                    "the cutter location is unreachable on this machine: change \
                                     the tool axis or the workpiece set-up"
                                }
                                _ => "program a finite point and a unit tool-axis vector",
                            };
                            errors.push(error(e.to_string(), hint));
                            continue;
                        }
                    }
                }
            }
            converted.end = previous.to_position();
            moves.push(converted);
        }
        if !errors.is_empty() {
            return Err(ProgramErrors {
                errors,
                suppressed: 0,
            });
        }
        Ok(Program {
            source: program.source.clone(),
            start: start.to_position(),
            moves,
            warnings,
            tools: program.tools.clone(),
            reading: program.reading.clone(),
        })
    }
}

#[cfg(test)]
pub(crate) mod tests;
