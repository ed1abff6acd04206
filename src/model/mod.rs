//! The machine as a Rapier world: links become rigid bodies of one reduced-coordinate
//! multibody (exact joints, no constraint drift), each drive's rotor and transmission inertia
//! is the joint's armature and its motor-side viscous damping the joint's damping, both
//! reflected through the transmission ratio. Drives push with a generalised force on their
//! joint (reaction on the parent link, where the motor is mounted).
//!
//! This is the only module that knows about Rapier. Its inputs and outputs are plain numbers
//! per machine axis, in joint units (m or rad) at the joint side of the transmission.

mod convert;

use crate::machine::{JointKind, Machine};
use convert::{from_pose, to_pose, to_vec};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rapier3d_f64::prelude::*;

/// How the model is to be built.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantOptions {
    /// Physics step (s).
    pub step: f64,
    /// Gravity in the machine base frame (m/s²).
    pub gravity: [f64; 3],
    /// Initial joint coordinate per machine axis (m or rad), in the machine's axis order.
    pub initial_positions: Vec<f64>,
    /// Include the drives' reflected inertia and damping (off only for engine checks).
    pub include_drive_dynamics: bool,
    /// Rapier's solver iterations per step. Rapier integrates each iteration as a substep of
    /// `step / solver_iterations`, so 1 makes `step` the integrator's true step.
    pub solver_iterations: usize,
}

/// Errors building the physics model from a machine description.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ModelError {
    #[error("the machine has {machine} axes but {given} initial positions were given")]
    InitialPositions { machine: usize, given: usize },
    #[error("initial position {value} of axis '{axis}' is outside its travel [{lo}, {hi}]")]
    OutsideTravel {
        axis: String,
        value: f64,
        lo: f64,
        hi: f64,
    },
    #[error("the physics step must be a positive finite number of seconds, got {0}")]
    Step(f64),
    #[error("solver_iterations must be at least 1")]
    SolverIterations,
    #[error("link '{0}' moves but has no mass; give it an <inertial> with a positive mass")]
    MasslessMovingLink(String),
    #[error("Rapier refused joint '{0}' (it would close a loop)")]
    Joint(String),
}

struct AxisBinding {
    child: RigidBodyHandle,
    parent: RigidBodyHandle,
    /// Joint axis in the child link frame.
    local_axis: Vector3<f64>,
    kind: JointKind,
    /// Index of the joint's DOF in the multibody's generalised coordinates.
    dof: usize,
    /// The multibody link of the child, for reading its joint coordinate.
    link_id: usize,
    /// Index into the joint coordinate array (0 = translation along the joint axis, 3 = rotation).
    coordinate: usize,
    /// Whether this joint lies between the root and the tool (moves the tool point).
    carries_tool: bool,
}

/// The simulated machine.
pub struct Plant {
    world: PhysicsWorld,
    link_bodies: Vec<RigidBodyHandle>,
    axes: Vec<AxisBinding>,
    multibody: Option<MultibodyJointHandle>,
    tool_link: usize,
    tool_offset: Point3<f64>,
    steps: u64,
}

impl Plant {
    pub fn new(machine: &Machine, options: &PlantOptions) -> Result<Plant, ModelError> {
        if !(options.step.is_finite() && options.step > 0.0) {
            return Err(ModelError::Step(options.step));
        }
        if options.initial_positions.len() != machine.axes.len() {
            return Err(ModelError::InitialPositions {
                machine: machine.axes.len(),
                given: options.initial_positions.len(),
            });
        }
        for (axis, &q) in machine.axes.iter().zip(&options.initial_positions) {
            if let Some([lo, hi]) = machine.joints[axis.joint].limits {
                if !(q >= lo && q <= hi) {
                    return Err(ModelError::OutsideTravel {
                        axis: axis.name.clone(),
                        value: q,
                        lo,
                        hi,
                    });
                }
            }
        }

        if options.solver_iterations == 0 {
            return Err(ModelError::SolverIterations);
        }
        let mut world = PhysicsWorld::new();
        world.integration_parameters.num_solver_iterations = options.solver_iterations;
        world.gravity = to_vec(&Vector3::from(options.gravity));
        world.integration_parameters.dt = options.step;

        // Bodies at their home poses (all joints at zero); the multibody places them.
        let home = home_poses(machine);
        let mut link_bodies = Vec::with_capacity(machine.links.len());
        for (i, link) in machine.links.iter().enumerate() {
            let body = if i == machine.root {
                RigidBodyBuilder::fixed()
            } else {
                if link.mass <= 0.0 {
                    return Err(ModelError::MasslessMovingLink(link.name.clone()));
                }
                let props = MassProperties::with_inertia_matrix(
                    to_vec(&link.center_of_mass.coords),
                    link.mass,
                    convert::to_mat(&link.inertia),
                );
                // Machine axes creep at micrometres per second; they must never sleep.
                RigidBodyBuilder::dynamic()
                    .additional_mass_properties(props)
                    .can_sleep(false)
            };
            link_bodies.push(world.insert_body(body.pose(to_pose(&home[i]))));
        }

        let mut multibody = None;
        let mut joint_handles = Vec::with_capacity(machine.joints.len());
        for joint in &machine.joints {
            // Joint frames whose local x is the joint axis, so the free coordinate is x / angle-x.
            let align = x_to_axis(&joint.axis);
            let locked = match joint.kind {
                JointKind::Fixed => JointAxesMask::LOCKED_FIXED_AXES,
                JointKind::Prismatic => JointAxesMask::LOCKED_PRISMATIC_AXES,
                JointKind::Revolute => JointAxesMask::LOCKED_REVOLUTE_AXES,
            };
            let data = GenericJointBuilder::new(locked)
                .local_frame1(to_pose(&(joint.origin * align)))
                .local_frame2(to_pose(&align))
                .build();
            let handle = world
                .insert_multibody_joint(link_bodies[joint.parent], link_bodies[joint.child], data)
                .ok_or_else(|| ModelError::Joint(joint.name.clone()))?;
            multibody.get_or_insert(handle);
            joint_handles.push(handle);
        }

        // The joints on the path from the root to the tool link.
        let mut joints_to_tool = Vec::new();
        let mut link = machine.tool_link;
        while let Some(j) = machine.parent_joint(link) {
            joints_to_tool.push(j);
            link = machine.joints[j].parent;
        }
        let mut axes = Vec::with_capacity(machine.axes.len());
        for axis in &machine.axes {
            let joint = &machine.joints[axis.joint];
            let (_, link_id) = world
                .multibody_joints
                .get(joint_handles[axis.joint])
                .expect("joint just inserted");
            axes.push(AxisBinding {
                child: link_bodies[joint.child],
                parent: link_bodies[joint.parent],
                local_axis: joint.axis,
                kind: joint.kind,
                dof: usize::MAX, // known once the fixed root is resolved (configure_dofs)
                link_id,
                coordinate: if joint.kind == JointKind::Revolute {
                    3
                } else {
                    0
                },
                carries_tool: joints_to_tool.contains(&axis.joint),
            });
        }

        let mut plant = Plant {
            world,
            link_bodies,
            axes,
            multibody,
            tool_link: machine.tool_link,
            tool_offset: Point3::from(machine.tool.offset_m),
            steps: 0,
        };
        plant.configure_dofs(machine, options);
        Ok(plant)
    }

    /// Armature, damping and initial coordinates of the driven DOFs.
    fn configure_dofs(&mut self, machine: &Machine, options: &PlantOptions) {
        let Some(handle) = self.multibody else { return };
        let PhysicsWorld {
            multibody_joints,
            bodies,
            ..
        } = &mut self.world;
        let (mb, _) = multibody_joints.get_mut(handle).expect("machine multibody");
        // Rapier treats a new multibody's root as free (6 DOFs) until forward kinematics sees
        // that the root body is fixed; resolve that first so the DOF indices are final.
        mb.forward_kinematics(bodies, false);
        let mut displacement = vec![0.0; mb.ndofs()];
        for (binding, (axis, &q0)) in self
            .axes
            .iter_mut()
            .zip(machine.axes.iter().zip(&options.initial_positions))
        {
            binding.dof = mb.link(binding.link_id).expect("axis link").assembly_id();
            let joint = &machine.joints[axis.joint];
            let (armature, drive_damping) = if options.include_drive_dynamics {
                (
                    axis.drive.reflected_inertia(),
                    axis.drive.reflected_damping(),
                )
            } else {
                (0.0, 0.0)
            };
            mb.armature_mut()[binding.dof] = armature;
            mb.damping_mut()[binding.dof] = drive_damping + joint.damping;
            displacement[binding.dof] = q0;
        }
        mb.apply_displacements(&displacement);
        mb.forward_kinematics(bodies, false);
        mb.update_rigid_bodies(bodies, true);
    }

    /// Physics step (s).
    pub fn step_size(&self) -> f64 {
        self.world.integration_parameters.dt
    }

    /// Number of physics steps taken so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    pub fn axis_count(&self) -> usize {
        self.axes.len()
    }

    /// Sets the generalised force each drive applies at its joint (N or N·m), held until the
    /// next call.
    pub fn set_joint_forces(&mut self, forces: &[f64]) {
        for body in &self.link_bodies {
            if let Some(rb) = self.world.bodies.get_mut(*body) {
                rb.reset_forces(false);
                rb.reset_torques(false);
            }
        }
        for (binding, &f) in self.axes.iter().zip(forces) {
            let direction = {
                let child = &self.world.bodies[binding.child];
                from_pose(child.position()).rotation * binding.local_axis
            };
            let load = to_vec(&(direction * f));
            let parent_moves = self.world.bodies[binding.parent].is_dynamic();
            match binding.kind {
                JointKind::Prismatic => {
                    self.world.bodies[binding.child].add_force(load, false);
                    if parent_moves {
                        self.world.bodies[binding.parent].add_force(-load, false);
                    }
                }
                JointKind::Revolute => {
                    self.world.bodies[binding.child].add_torque(load, false);
                    if parent_moves {
                        self.world.bodies[binding.parent].add_torque(-load, false);
                    }
                }
                JointKind::Fixed => {}
            }
        }
    }

    /// Advances the physics by one step.
    pub fn step(&mut self) {
        self.world.step();
        self.steps += 1;
    }

    /// The machine's multibody (none for a machine without joints).
    fn multibody(&self) -> Option<&Multibody> {
        let handle = self.multibody?;
        self.world.multibody_joints.get(handle).map(|(mb, _)| mb)
    }

    /// Joint coordinate of each axis (m or rad).
    pub fn positions(&self, out: &mut [f64]) {
        let Some(mb) = self.multibody() else { return };
        for (o, b) in out.iter_mut().zip(&self.axes) {
            *o = mb
                .link(b.link_id)
                .map_or(f64::NAN, |l| l.joint().coords()[b.coordinate]);
        }
    }

    /// Joint velocity of each axis (m/s or rad/s).
    pub fn velocities(&self, out: &mut [f64]) {
        let Some(mb) = self.multibody() else { return };
        let v = mb.generalized_velocity();
        for (o, b) in out.iter_mut().zip(&self.axes) {
            *o = v[b.dof];
        }
    }

    /// World pose of every link, in the machine's link order.
    pub fn link_poses(&self) -> Vec<Isometry3<f64>> {
        self.link_bodies
            .iter()
            .map(|h| from_pose(self.world.bodies[*h].position()))
            .collect()
    }

    /// Tool point in the machine base frame (m).
    pub fn tool_point(&self) -> Point3<f64> {
        let body = &self.world.bodies[self.link_bodies[self.tool_link]];
        from_pose(body.position()) * self.tool_offset
    }

    /// Velocity of the tool point (m/s), from the joints' generalised velocities along the
    /// chain to the tool (a Jacobian product). Rapier's per-link body velocities of a multibody
    /// are one step older than its joint velocities and positions, so they are not used.
    pub fn tool_velocity(&self) -> Vector3<f64> {
        let Some(mb) = self.multibody() else {
            return Vector3::zeros();
        };
        let v = mb.generalized_velocity();
        let tool = self.tool_point();
        let mut velocity = Vector3::zeros();
        for b in self.axes.iter().filter(|b| b.carries_tool) {
            let frame = from_pose(self.world.bodies[b.child].position());
            let axis = frame.rotation * b.local_axis;
            velocity += match b.kind {
                JointKind::Prismatic => axis * v[b.dof],
                JointKind::Revolute => {
                    axis.cross(&(tool - Point3::from(frame.translation.vector))) * v[b.dof]
                }
                JointKind::Fixed => Vector3::zeros(),
            };
        }
        velocity
    }
}

/// A rotation taking the x axis onto `axis` (unit).
fn x_to_axis(axis: &Vector3<f64>) -> Isometry3<f64> {
    let rotation = UnitQuaternion::rotation_between(&Vector3::x(), axis)
        // Only `axis = -x` has no unique shortest rotation; any half-turn about a normal will do.
        .unwrap_or_else(|| {
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI)
        });
    Isometry3::from_parts(Translation3::identity(), rotation)
}

/// Pose of every link with all joint coordinates at zero.
pub fn home_poses(machine: &Machine) -> Vec<Isometry3<f64>> {
    let mut poses = vec![Isometry3::identity(); machine.links.len()];
    for joint in &machine.joints {
        poses[joint.child] = poses[joint.parent] * joint.origin;
    }
    poses
}
