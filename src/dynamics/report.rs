//! The data of `cncsim dynamics URDF --q … --qd … --qdd … [--json]`: every term of the
//! equation of motion at one state, from user input that is validated, never trusted.

use super::error::DynamicsError;
use super::model::{DynamicsModel, JointMotion};
use crate::machine::KinematicTree;
use nalgebra::{DMatrix, Vector3};
use std::fmt;

/// All terms of `τ = M(q)q̈ + C(q,q̇)q̇ + F q̇ + g(q)` at one state, joints in coordinate order.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicsReport {
    /// Name of the machine (the kinematic tree's name).
    pub machine: String,
    /// Gravitational acceleration in the root link frame (m/s²).
    pub gravity_vector: [f64; 3],
    /// Names of the moving joints, in coordinate order.
    pub joints: Vec<String>,
    /// Per joint: true for revolute (rad, N·m), false for prismatic (m, N).
    pub revolute: Vec<bool>,
    /// Joint positions `q` (rad or m).
    pub q: Vec<f64>,
    /// Joint velocities `q̇` (rad/s or m/s).
    pub qd: Vec<f64>,
    /// Joint accelerations `q̈` (rad/s² or m/s²).
    pub qdd: Vec<f64>,
    /// `τ`, including damping and armature.
    pub tau: Vec<f64>,
    /// `M(q)`, row-major, including armature.
    pub mass_matrix: Vec<Vec<f64>>,
    /// `M(q) q̈`.
    pub inertial: Vec<f64>,
    /// `C(q,q̇) q̇`.
    pub coriolis: Vec<f64>,
    /// `F q̇` (joint damping from the URDF).
    pub damping: Vec<f64>,
    /// `g(q)`.
    pub gravity: Vec<f64>,
}

impl DynamicsReport {
    /// Evaluates `tree` at (`q`, `qd`, `qdd`) under `gravity` (m/s², root frame). Lengths and
    /// finiteness are checked against the model; any problem is an error, never a panic.
    pub fn evaluate(
        tree: &KinematicTree,
        gravity: Vector3<f64>,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
    ) -> Result<Self, DynamicsError> {
        let model = DynamicsModel::new(tree, gravity)?;
        Self::evaluate_model(&model, &tree.name, q, qd, qdd)
    }

    /// As [`DynamicsReport::evaluate`], with an existing model (e.g. one with armature).
    pub fn evaluate_model(
        model: &DynamicsModel,
        machine: &str,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
    ) -> Result<Self, DynamicsError> {
        for (what, values) in [("q", q), ("qd", qd), ("qdd", qdd)] {
            model.check_len(what, values.len())?;
            if let Some(index) = values.iter().position(|v| !v.is_finite()) {
                return Err(DynamicsError::NotFinite {
                    what: what.into(),
                    index,
                    joint: model.joint_names()[index].clone(),
                    value: values[index],
                });
            }
        }
        let n = model.dof();
        let mut ws = model.workspace();
        let mut tau = vec![0.0; n];
        let mut coriolis = vec![0.0; n];
        let mut gravity = vec![0.0; n];
        let mut damping = vec![0.0; n];
        let mut mass = DMatrix::zeros(n, n);
        model.inverse_dynamics(&mut ws, q, qd, qdd, &mut tau);
        model.coriolis_forces(&mut ws, q, qd, &mut coriolis);
        model.gravity_forces(&mut ws, q, &mut gravity);
        model.damping_forces(qd, &mut damping);
        model.mass_matrix(&mut ws, q, &mut mass);
        let inertial: Vec<f64> = (&mass * nalgebra::DVector::from_column_slice(qdd))
            .iter()
            .copied()
            .collect();
        let all_finite = [&tau, &coriolis, &gravity, &damping, &inertial]
            .iter()
            .all(|v| v.iter().all(|x| x.is_finite()))
            && mass.iter().all(|x| x.is_finite());
        if !all_finite {
            return Err(DynamicsError::NonFiniteResult);
        }
        Ok(DynamicsReport {
            machine: machine.to_string(),
            gravity_vector: model.gravity().into(),
            joints: model.joint_names().to_vec(),
            revolute: model
                .bodies()
                .iter()
                .map(|b| b.motion == JointMotion::Revolute)
                .collect(),
            q: q.to_vec(),
            qd: qd.to_vec(),
            qdd: qdd.to_vec(),
            tau,
            mass_matrix: mass
                .row_iter()
                .map(|r| r.iter().copied().collect())
                .collect(),
            inertial,
            coriolis,
            damping,
            gravity,
        })
    }

    /// `{"joints": [...], "tau": [...], "mass_matrix": [[...]], "coriolis": [...],
    /// "gravity": [...]}`, SI units, joints in coordinate order.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "joints": self.joints,
            "tau": self.tau,
            "mass_matrix": self.mass_matrix,
            "coriolis": self.coriolis,
            "gravity": self.gravity,
        })
    }

    /// Human-readable tables: state and force terms per joint, then the mass matrix.
    pub fn to_text(&self) -> String {
        self.to_string()
    }
}

impl fmt::Display for DynamicsReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [gx, gy, gz] = self.gravity_vector;
        writeln!(
            f,
            "Inverse dynamics of '{}' ({} moving joints), gravity ({gx}, {gy}, {gz}) m/s²",
            self.machine,
            self.joints.len()
        )?;
        writeln!(f, "τ = M(q)·q̈ + C(q,q̇)·q̇ + F·q̇ + g(q)")?;
        writeln!(f)?;
        let name_width = self
            .joints
            .iter()
            .map(|j| j.chars().count())
            .max()
            .unwrap_or(0);
        let name_width = name_width.max("joint".len());
        let columns = ["q", "q̇", "q̈", "τ", "M·q̈", "C·q̇", "F·q̇", "g(q)"];
        write!(f, "{:<name_width$}  {:<9}", "joint", "type")?;
        for c in columns {
            write!(f, " {}", right_aligned(c, 13))?;
        }
        writeln!(f)?;
        for (i, joint) in self.joints.iter().enumerate() {
            let kind = if self.revolute[i] {
                "revolute"
            } else {
                "prismatic"
            };
            write!(f, "{}  {kind:<9}", left_aligned(joint, name_width))?;
            let values = [
                self.q[i],
                self.qd[i],
                self.qdd[i],
                self.tau[i],
                self.inertial[i],
                self.coriolis[i],
                self.damping[i],
                self.gravity[i],
            ];
            for v in values {
                // `+ 0.0` prints an exact −0 (e.g. zero damping times a negative rate) as 0.
                write!(f, " {:>13}", format!("{:.6}", v + 0.0))?;
            }
            writeln!(f)?;
        }
        writeln!(f)?;
        writeln!(
            f,
            "Units: revolute q rad, q̇ rad/s, q̈ rad/s², forces N·m; \
             prismatic q m, q̇ m/s, q̈ m/s², forces N."
        )?;
        writeln!(f)?;
        writeln!(
            f,
            "Mass matrix M(q) (kg·m² rotary–rotary, kg linear–linear, kg·m mixed):"
        )?;
        write!(f, "{:<name_width$}", "")?;
        for j in &self.joints {
            write!(f, " {}", right_aligned(j, 13))?;
        }
        writeln!(f)?;
        for (joint, row) in self.joints.iter().zip(&self.mass_matrix) {
            write!(f, "{}", left_aligned(joint, name_width))?;
            for v in row {
                write!(f, " {:>13}", format!("{v:.8}"))?;
            }
            writeln!(f)?;
        }
        Ok(())
    }
}

/// Columns on a terminal: combining marks (the dots of q̇, q̈) take no width of their own.
fn display_width(s: &str) -> usize {
    s.chars()
        .filter(|c| !('\u{0300}'..='\u{036F}').contains(c))
        .count()
}

fn right_aligned(s: &str, width: usize) -> String {
    format!("{}{s}", " ".repeat(width.saturating_sub(display_width(s))))
}

fn left_aligned(s: &str, width: usize) -> String {
    format!("{s}{}", " ".repeat(width.saturating_sub(display_width(s))))
}

impl crate::command::Report for DynamicsReport {
    fn text(&self) -> String {
        self.to_text()
    }

    fn json(&self) -> Option<serde_json::Value> {
        Some(self.to_json())
    }
}
