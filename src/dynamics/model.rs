//! The dynamics model: a [`KinematicTree`] reduced, once, to what the recursive algorithms
//! need per evaluation.
//!
//! Reduction: every link hangs rigidly from the nearest moving joint above it (or from the
//! base). Links joined by fixed joints are merged into one *body* per moving joint, with their
//! inertias summed in that joint's child frame, so the algorithms only ever loop over the
//! `n` moving joints. Links rigidly attached to the base never move and are dropped.
//!
//! Coordinates: body `i` is the `i`-th non-fixed joint of `tree.joints`. The loader orders
//! joints parents first, so a body's parent always has a smaller index — the property every
//! recursive pass below relies on.

use super::error::DynamicsError;
use super::spatial::{Force, Motion, SpatialInertia, Transform};
use crate::machine::{Joint, JointKind, KinematicTree, Link, Machine};
use nalgebra::{DMatrix, Isometry3, Vector3};

/// The motion a joint allows, in its own (child) frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointMotion {
    /// Rotation about the joint axis (coordinate in rad).
    Revolute,
    /// Translation along the joint axis (coordinate in m).
    Prismatic,
}

/// One moving joint and everything rigidly attached below it (up to the next moving joints).
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Name of the joint (the coordinate's name).
    pub joint_name: String,
    /// Index of the joint in the tree's `joints`.
    pub joint_index: usize,
    /// Whether the joint rotates or translates.
    pub motion: JointMotion,
    /// Unit axis in the joint (child) frame.
    pub axis: Vector3<f64>,
    /// Motion subspace `S`: the spatial velocity of the body per unit joint rate.
    pub subspace: Motion,
    /// Parent body, `None` for a body hanging from the (fixed) base.
    pub parent: Option<usize>,
    /// From the parent body frame to this joint's frame at q = 0 (URDF joint origin, composed
    /// with any fixed joints in between).
    pub tree_transform: Transform,
    /// Spatial inertia of the body in its joint frame: the joint's child link plus every link
    /// fixed to it.
    pub inertia: SpatialInertia,
    /// Viscous damping of the joint (N·s/m or N·m·s/rad).
    pub damping: f64,
    /// Reflected rotor inertia of the drive (kg or kg·m²), added to M's diagonal.
    pub armature: f64,
}

impl Body {
    /// From this body's frame at q = 0 to its frame at `q` (URDF: child = origin · motion(q)).
    #[inline]
    pub fn joint_transform(&self, q: f64) -> Transform {
        match self.motion {
            JointMotion::Revolute => Transform::rotation_about(&self.axis, q),
            JointMotion::Prismatic => Transform::translation_along(&self.axis, q),
        }
    }

    /// `ⁱX_λ(i)(q)`: from the parent body frame to this body's frame.
    #[inline]
    pub fn parent_to_body(&self, q: f64) -> Transform {
        self.joint_transform(q) * self.tree_transform
    }
}

/// Rigid-body dynamics of a machine's kinematic tree, built once and evaluated many times.
///
/// Joint coordinates `q` are ordered as the non-fixed joints appear in `tree.joints` (parents
/// first; for a URDF listing a serial chain root to tip that is URDF order). The names in that
/// order are [`DynamicsModel::joint_names`]. Revolute coordinates are in rad, prismatic in m;
/// generalised forces in N·m and N.
///
/// The evaluation methods (see `rnea.rs`, `crba.rs`, `forward.rs`) take a
/// [`DynamicsWorkspace`] made by [`DynamicsModel::workspace`] and never allocate.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicsModel {
    pub(super) bodies: Vec<Body>,
    /// Gravitational acceleration in the base (root link) frame, m/s².
    pub(super) gravity: Vector3<f64>,
    joint_names: Vec<String>,
}

impl DynamicsModel {
    /// Builds the model of `tree` under gravity `gravity` (m/s², root link frame; e.g.
    /// `(0, 0, -9.81)` for a z-up machine). Damping is taken from the joints, armature is zero
    /// (see [`DynamicsModel::with_armature`]).
    pub fn new(tree: &KinematicTree, gravity: Vector3<f64>) -> Result<Self, DynamicsError> {
        Self::from_parts(&tree.links, &tree.joints, tree.root, gravity)
    }

    /// As [`DynamicsModel::new`], from a machine's URDF part. Drive armature is not included;
    /// add it with [`DynamicsModel::with_drive_armature`].
    pub fn from_machine(machine: &Machine, gravity: Vector3<f64>) -> Result<Self, DynamicsError> {
        Self::from_parts(&machine.links, &machine.joints, machine.root, gravity)
    }

    fn from_parts(
        links: &[Link],
        joints: &[Joint],
        root: usize,
        gravity: Vector3<f64>,
    ) -> Result<Self, DynamicsError> {
        check_tree(links, joints, root)?;
        for link in links {
            check_link(link)?;
        }

        // Where each link hangs: (body, pose of the link frame in the body frame).
        // Body `None` is the base.
        let mut attachment: Vec<Option<(Option<usize>, Isometry3<f64>)>> = vec![None; links.len()];
        attachment[root] = Some((None, Isometry3::identity()));
        let mut bodies: Vec<Body> = Vec::new();
        for (index, joint) in joints.iter().enumerate() {
            check_joint(joint)?;
            let (parent_body, parent_pose) =
                attachment[joint.parent].expect("check_tree guarantees parents-first order");
            let joint_in_parent_body = parent_pose * joint.origin;
            let motion = match joint.kind {
                JointKind::Fixed => {
                    attachment[joint.child] = Some((parent_body, joint_in_parent_body));
                    continue;
                }
                JointKind::Revolute => JointMotion::Revolute,
                JointKind::Prismatic => JointMotion::Prismatic,
            };
            let axis = joint.axis.normalize();
            let subspace = match motion {
                JointMotion::Revolute => Motion::new(axis, Vector3::zeros()),
                JointMotion::Prismatic => Motion::new(Vector3::zeros(), axis),
            };
            attachment[joint.child] = Some((Some(bodies.len()), Isometry3::identity()));
            bodies.push(Body {
                joint_name: joint.name.clone(),
                joint_index: index,
                motion,
                axis,
                subspace,
                parent: parent_body,
                tree_transform: Transform::from_pose(&joint_in_parent_body),
                inertia: SpatialInertia::ZERO,
                damping: joint.damping,
                armature: 0.0,
            });
        }
        if bodies.is_empty() {
            return Err(DynamicsError::NoMovingJoint);
        }

        // Merge each moving link's inertia into its body, in the body frame.
        for (link, place) in links.iter().zip(&attachment) {
            let (Some(body), link_in_body) = place.expect("check_tree: every link is reached")
            else {
                continue; // fixed to the base
            };
            if link.mass > 0.0 {
                let own = SpatialInertia::from_center_of_mass(
                    link.mass,
                    &link.center_of_mass.coords,
                    &link.inertia,
                );
                bodies[body].inertia +=
                    Transform::from_pose(&link_in_body).inverse_transform_inertia(&own);
            }
        }
        let massless: Vec<usize> = (0..bodies.len())
            .filter(|&b| bodies[b].inertia.mass <= 0.0)
            .collect();
        let mut model = DynamicsModel {
            joint_names: bodies.iter().map(|b| b.joint_name.clone()).collect(),
            bodies,
            gravity: Vector3::zeros(),
        };
        // In reduced coordinates a massless body is fine where every joint still moves mass
        // (a frame between two slides with the carriage beyond): the mass matrix is then
        // positive definite. Only a chain whose mass matrix is singular is refused, at the
        // first massless body.
        if let Some(&b) = massless.first() {
            let n = model.dof();
            let mut mass = nalgebra::DMatrix::zeros(n, n);
            model.mass_matrix(&mut model.workspace(), &vec![0.0; n], &mut mass);
            // Singular to round-off: the smallest eigenvalue against the largest diagonal term
            // (masses and inertias mixed; a real machine's spread is far within 1e12).
            let largest = mass.diagonal().iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let smallest = mass.symmetric_eigenvalues().min();
            if smallest.is_nan() || smallest <= 1e-12 * largest {
                let names = links
                    .iter()
                    .zip(&attachment)
                    .filter(|(_, place)| place.is_some_and(|(owner, _)| owner == Some(b)))
                    .map(|(l, _)| l.name.clone())
                    .collect();
                return Err(DynamicsError::MasslessBody {
                    joint: model.bodies[b].joint_name.clone(),
                    links: names,
                });
            }
        }
        model.set_gravity(gravity)?;
        Ok(model)
    }

    /// Adds per-joint armature (reflected rotor inertia, kg·m² or kg), one per coordinate.
    pub fn with_armature(mut self, armature: &[f64]) -> Result<Self, DynamicsError> {
        self.set_armature(armature)?;
        Ok(self)
    }

    /// Sets each driven joint's armature to its drive's reflected rotor and transmission
    /// inertia (`J·k²`, see [`crate::machine::Drive::reflected_inertia`]); joints without a
    /// drive get none. `machine` must be the one this model was built from.
    pub fn with_drive_armature(self, machine: &Machine) -> Result<Self, DynamicsError> {
        let mut armature = vec![0.0; self.dof()];
        for axis in &machine.axes {
            let coordinate =
                self.coordinate_of_joint(axis.joint)
                    .ok_or_else(|| DynamicsError::BadJoint {
                        joint: machine
                            .joints
                            .get(axis.joint)
                            .map_or_else(|| format!("#{}", axis.joint), |j| j.name.clone()),
                        problem: format!(
                            "axis '{}' drives a joint the model does not move",
                            axis.name
                        ),
                    })?;
            armature[coordinate] = axis.drive.reflected_inertia();
        }
        self.with_armature(&armature)
    }

    /// Sets per-joint armature in place (kg·m² or kg), one finite value ≥ 0 per coordinate;
    /// on an error the model is unchanged.
    pub fn set_armature(&mut self, armature: &[f64]) -> Result<(), DynamicsError> {
        self.check_len("armature", armature.len())?;
        for (i, &a) in armature.iter().enumerate() {
            if !(a.is_finite() && a >= 0.0) {
                return Err(DynamicsError::Negative {
                    what: "armature".into(),
                    index: i,
                    joint: self.joint_names[i].clone(),
                    value: a,
                });
            }
        }
        for (body, &a) in self.bodies.iter_mut().zip(armature) {
            body.armature = a;
        }
        Ok(())
    }

    /// Sets the gravitational acceleration (m/s², root link frame); refused unless finite.
    pub fn set_gravity(&mut self, gravity: Vector3<f64>) -> Result<(), DynamicsError> {
        if !gravity.iter().all(|g| g.is_finite()) {
            return Err(DynamicsError::BadGravity(gravity.into()));
        }
        self.gravity = gravity;
        Ok(())
    }

    /// Number of joint coordinates (moving joints).
    pub fn dof(&self) -> usize {
        self.bodies.len()
    }

    /// Joint names in coordinate order.
    pub fn joint_names(&self) -> &[String] {
        &self.joint_names
    }

    /// The bodies (one per coordinate), parents before children.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// The coordinate of the tree joint with index `joint_index`, `None` for a fixed joint.
    pub fn coordinate_of_joint(&self, joint_index: usize) -> Option<usize> {
        self.bodies
            .iter()
            .position(|b| b.joint_index == joint_index)
    }

    /// The coordinate of the joint named `name`, `None` if there is no such moving joint.
    pub fn coordinate_of(&self, name: &str) -> Option<usize> {
        self.joint_names.iter().position(|n| n == name)
    }

    /// Gravitational acceleration in the root link frame (m/s²).
    pub fn gravity(&self) -> Vector3<f64> {
        self.gravity
    }

    /// Scratch space for the evaluation methods, sized for this model.
    pub fn workspace(&self) -> DynamicsWorkspace {
        DynamicsWorkspace::new(self.dof())
    }

    /// Checks that a vector meant for this model has one value per coordinate.
    pub(super) fn check_len(&self, what: &str, got: usize) -> Result<(), DynamicsError> {
        if got == self.dof() {
            return Ok(());
        }
        Err(DynamicsError::WrongLength {
            what: what.into(),
            expected: self.dof(),
            got,
            joints: self.joint_names.join(", "),
        })
    }

    /// Panics with a clear message when a hot-path argument has the wrong length: that is a
    /// programming error, validated inputs (see `report.rs`) never get here.
    #[inline]
    pub(super) fn assert_len(&self, what: &str, got: usize) {
        assert_eq!(
            got,
            self.dof(),
            "{what} has {got} entries, the model has {} coordinates",
            self.dof()
        );
    }
}

/// Per-evaluation scratch: body transforms, velocities, accelerations, forces, composite
/// inertias and the mass-matrix factor. Allocated once, reused every servo period.
#[derive(Debug, Clone)]
pub struct DynamicsWorkspace {
    /// `ⁱX_λ(i)`: parent body frame → body frame, at the current q.
    pub(super) parent_to_body: Vec<Transform>,
    pub(super) velocity: Vec<Motion>,
    pub(super) acceleration: Vec<Motion>,
    pub(super) force: Vec<Force>,
    pub(super) composite_inertia: Vec<SpatialInertia>,
    /// Mass matrix, overwritten in place by its factor in forward dynamics.
    pub(super) mass_factor: DMatrix<f64>,
}

impl DynamicsWorkspace {
    /// Scratch space for a model with `dof` coordinates (see [`DynamicsModel::workspace`]).
    pub fn new(dof: usize) -> Self {
        DynamicsWorkspace {
            parent_to_body: vec![Transform::identity(); dof],
            velocity: vec![Motion::ZERO; dof],
            acceleration: vec![Motion::ZERO; dof],
            force: vec![Force::ZERO; dof],
            composite_inertia: vec![SpatialInertia::ZERO; dof],
            mass_factor: DMatrix::zeros(dof, dof),
        }
    }

    pub(super) fn assert_fits(&self, model: &DynamicsModel) {
        assert_eq!(
            self.velocity.len(),
            model.dof(),
            "workspace made for another model"
        );
    }
}

/// Indices in range, one root, each joint's parent placed before it and each link placed once.
/// `KinematicTree`'s fields are public, so a hand-built tree gets the loader's guarantees here.
fn check_tree(links: &[Link], joints: &[Joint], root: usize) -> Result<(), DynamicsError> {
    let bad = |m: String| Err(DynamicsError::MalformedTree(m));
    if root >= links.len() {
        return bad(format!("root link {root} out of {} links", links.len()));
    }
    let mut placed = vec![false; links.len()];
    placed[root] = true;
    for j in joints {
        if j.parent >= links.len() || j.child >= links.len() {
            return bad(format!("joint '{}' refers to a missing link", j.name));
        }
        if !placed[j.parent] {
            return bad(format!(
                "joint '{}' comes before a joint placing its parent link '{}' \
                 (joints must be ordered parents first)",
                j.name, links[j.parent].name
            ));
        }
        if placed[j.child] {
            return bad(format!(
                "link '{}' is placed twice (joint '{}'): closed loops are not supported",
                links[j.child].name, j.name
            ));
        }
        placed[j.child] = true;
    }
    if let Some(i) = placed.iter().position(|p| !p) {
        return bad(format!(
            "link '{}' is not connected to the root",
            links[i].name
        ));
    }
    Ok(())
}

fn check_link(link: &Link) -> Result<(), DynamicsError> {
    let bad = |p: String| {
        Err(DynamicsError::BadLink {
            link: link.name.clone(),
            problem: p,
        })
    };
    let i = &link.inertia;
    if !(link.mass.is_finite() && link.mass >= 0.0) {
        return bad(format!("mass {} kg: expected a finite mass ≥ 0", link.mass));
    }
    if !link.center_of_mass.iter().all(|c| c.is_finite()) || !i.iter().all(|v| v.is_finite()) {
        return bad("non-finite centre of mass or inertia".into());
    }
    if (i - i.transpose()).amax() > 1e-12 * i.amax().max(1.0) {
        return bad("inertia tensor is not symmetric".into());
    }
    if link.mass > 0.0 && i.cholesky().is_none() {
        return bad("inertia tensor is not positive definite".into());
    }
    if link.mass == 0.0 && i.amax() > 0.0 {
        return bad("has rotational inertia but zero mass".into());
    }
    Ok(())
}

fn check_joint(joint: &Joint) -> Result<(), DynamicsError> {
    let bad = |p: String| {
        Err(DynamicsError::BadJoint {
            joint: joint.name.clone(),
            problem: p,
        })
    };
    let o = &joint.origin;
    if !(o.translation.vector.iter().all(|v| v.is_finite())
        && o.rotation.coords.iter().all(|v| v.is_finite()))
    {
        return bad("non-finite origin".into());
    }
    if joint.kind == JointKind::Fixed {
        return Ok(());
    }
    let n = joint.axis.norm();
    if !(n.is_finite() && (n - 1.0).abs() < 1e-6) {
        return bad(format!(
            "axis {:?} is not a unit vector",
            joint.axis.as_slice()
        ));
    }
    if !(joint.damping.is_finite() && joint.damping >= 0.0) {
        return bad(format!(
            "damping {}: expected a finite value ≥ 0",
            joint.damping
        ));
    }
    Ok(())
}
