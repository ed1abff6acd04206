//! The rigid-body model in the machine's axis coordinates, as controllers see the machine:
//! one coordinate per driven axis, in the machine's axis order. The tree model
//! ([`DynamicsModel`]) has one coordinate per moving joint; a `<mimic>` follower's coordinate
//! is its leader's times the multiplier plus the offset, q_tree = G·q_axes + o with G
//! constant, so the axis-space dynamics are exactly τ_axes = Gᵀ·τ_tree(G·q + o, G·q̇, G·q̈)
//! and M_axes = Gᵀ·M_tree·G (the follower's inertia, weight and damping load its leader
//! through the multiplier, as a chain or gear train passes them on). A passive joint has no
//! axis to follow: a model in axis coordinates cannot hold it, and is refused by name.

use super::{DynamicsError, DynamicsModel, DynamicsWorkspace};
use crate::machine::Machine;
use nalgebra::{DMatrix, Vector3};

/// How a tree coordinate follows the axes: q_tree = multiplier · q_axis + offset.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Source {
    axis: usize,
    multiplier: f64,
    offset: f64,
}

/// [`DynamicsModel`] in axis coordinates (drive armature included); see the module text.
#[derive(Debug, Clone)]
pub struct AxisDynamics {
    tree: DynamicsModel,
    /// Per tree coordinate, the axis it follows.
    sources: Vec<Source>,
    axes: usize,
    /// Whether the tree coordinates are the axes themselves (no follower): no mapping needed.
    identity: bool,
    /// Scratch in tree coordinates.
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
    mass: DMatrix<f64>,
}

impl AxisDynamics {
    /// The model of `machine` (its links and joints as they are, drive armature added) in
    /// the coordinates of its axes. Refuses a machine with a passive joint.
    pub fn of_machine(machine: &Machine, gravity: Vector3<f64>) -> Result<Self, DynamicsError> {
        if let Some(&j) = machine.passive_joints().first() {
            return Err(DynamicsError::BadJoint {
                joint: machine.joints[j].name.clone(),
                problem: "it is passive (moves freely): a model in the axes' coordinates has no coordinate for it; lock it or drive it".into(),
            });
        }
        let tree = DynamicsModel::from_machine(machine, gravity)?.with_drive_armature(machine)?;
        let couplings = machine.couplings();
        let mut sources = vec![None; tree.dof()];
        for (a, axis) in machine.axes.iter().enumerate() {
            if let Some(c) = tree.coordinate_of_joint(axis.joint) {
                sources[c] = Some(Source {
                    axis: a,
                    multiplier: 1.0,
                    offset: 0.0,
                });
            }
        }
        for coupling in &couplings {
            let axis = machine.axes.iter().position(|a| a.joint == coupling.leader);
            if let (Some(c), Some(axis)) = (tree.coordinate_of_joint(coupling.follower), axis) {
                sources[c] = Some(Source {
                    axis,
                    multiplier: coupling.multiplier,
                    offset: coupling.offset,
                });
            }
        }
        let sources = sources
            .into_iter()
            .enumerate()
            .map(|(c, source)| {
                source.ok_or_else(|| DynamicsError::BadJoint {
                    joint: tree.joint_names()[c].clone(),
                    problem: "no axis drives it and it follows none: a model in the axes' coordinates has no coordinate for it".into(),
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let axes = machine.axes.len();
        let identity = sources.len() == axes
            && sources
                .iter()
                .enumerate()
                .all(|(c, s)| s.axis == c && s.multiplier == 1.0 && s.offset == 0.0);
        let n = tree.dof();
        Ok(AxisDynamics {
            tree,
            sources,
            axes,
            identity,
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
            tau: vec![0.0; n],
            mass: DMatrix::zeros(n, n),
        })
    }

    /// Number of axes (coordinates).
    pub fn dof(&self) -> usize {
        self.axes
    }

    /// Scratch for the evaluations.
    pub fn workspace(&self) -> DynamicsWorkspace {
        self.tree.workspace()
    }

    /// `τ = M(q)q̈ + C(q,q̇)q̇ + F q̇ + g(q)` in the axes' coordinates (one value per axis).
    pub fn inverse_dynamics(
        &mut self,
        ws: &mut DynamicsWorkspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) {
        if self.identity {
            self.tree.inverse_dynamics(ws, q, qd, qdd, tau);
            return;
        }
        self.expand(q, qd, qdd);
        self.tree
            .inverse_dynamics(ws, &self.q, &self.qd, &self.qdd, &mut self.tau);
        tau.fill(0.0);
        for (s, t) in self.sources.iter().zip(&self.tau) {
            tau[s.axis] += s.multiplier * t;
        }
    }

    /// `M(q)` in the axes' coordinates (`dof × dof`), armature included.
    pub fn mass_matrix(&mut self, ws: &mut DynamicsWorkspace, q: &[f64], mass: &mut DMatrix<f64>) {
        if self.identity {
            self.tree.mass_matrix(ws, q, mass);
            return;
        }
        assert_eq!(q.len(), self.axes, "one value per axis");
        for (c, s) in self.sources.iter().enumerate() {
            self.q[c] = s.multiplier * q[s.axis] + s.offset;
        }
        self.tree.mass_matrix(ws, &self.q, &mut self.mass);
        mass.fill(0.0);
        for (i, si) in self.sources.iter().enumerate() {
            for (j, sj) in self.sources.iter().enumerate() {
                mass[(si.axis, sj.axis)] += si.multiplier * sj.multiplier * self.mass[(i, j)];
            }
        }
    }

    /// The tree's coordinates, rates and accelerations for the axes'.
    fn expand(&mut self, q: &[f64], qd: &[f64], qdd: &[f64]) {
        assert!(
            q.len() == self.axes && qd.len() == self.axes && qdd.len() == self.axes,
            "one value per axis"
        );
        for (c, s) in self.sources.iter().enumerate() {
            self.q[c] = s.multiplier * q[s.axis] + s.offset;
            self.qd[c] = s.multiplier * qd[s.axis];
            self.qdd[c] = s.multiplier * qdd[s.axis];
        }
    }
}
