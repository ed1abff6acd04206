//! The machine as a Rapier world: links become rigid bodies of one reduced-coordinate
//! multibody (exact joints, no constraint drift), each drive's rotor and transmission inertia
//! is the joint's armature and its motor-side viscous damping the joint's damping, both
//! reflected through the transmission ratio. Drives push with a generalised force on their
//! joint (reaction on the parent link, where the motor is mounted).
//!
//! A compliant transmission (a drive with a stiffness) splits the axis in two bodies: the drive
//! side (rotor, coupling, gearbox, pulley or screw, its inertia the armature of its own DOF)
//! and the carriage, on a free DOF relative to it. The spring and damper between them, with the
//! backlash as a dead zone inside (no force within the gap), push the two apart every physics
//! step (`TransmissionSpring`). Without a stiffness the backlash is a rigid stop instead: a
//! joint limit of the dead-band DOF.
//!
//! This is the only module that knows about Rapier. Its inputs and outputs are plain numbers
//! per machine axis, in joint units (m or rad) at the joint side of the transmission.

use crate::convert::{self, from_pose, from_vec, to_pose, to_vec};
use crate::machine::{Feedback, Guide, JointKind, Machine, StribeckCurve};
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
    /// The number of initial positions differs from the machine's number of axes.
    #[error("the machine has {machine} axes but {given} initial positions were given")]
    InitialPositions {
        /// Axes the machine has.
        machine: usize,
        /// Initial positions given.
        given: usize,
    },
    /// An initial position lies outside its axis's joint limits.
    #[error("initial position {value} of axis '{axis}' is outside its travel [{lo}, {hi}]")]
    OutsideTravel {
        /// Name of the axis.
        axis: String,
        /// The initial position given (m, or rad on a rotary axis).
        value: f64,
        /// Lower joint limit (m or rad).
        lo: f64,
        /// Upper joint limit (m or rad).
        hi: f64,
    },
    /// The physics step (s) is not a positive finite number.
    #[error("the physics step must be a positive finite number of seconds, got {0}")]
    Step(f64),
    /// `solver_iterations` is zero.
    #[error("solver_iterations must be at least 1")]
    SolverIterations,
    /// A driven joint with `<dynamics friction>` behind backlash or a compliant transmission.
    #[error("joint '{0}': its <dynamics friction> cannot act behind backlash or a compliant transmission (the carriage hangs on the drive side): give the friction as the axis guide's (guide = {{ friction_coefficient = … }}) and set the URDF's to 0")]
    FrictionBehindDriveTrain(String),
    /// A massless moving body on a chain whose mass matrix is singular (the dynamics model's
    /// reason).
    #[error("{0}; give the massless links an <inertial> with a positive mass")]
    SingularMass(String),
    /// Rapier would not add the named joint to the multibody (it would close a kinematic loop).
    #[error("Rapier refused joint '{0}' (it would close a loop)")]
    Joint(String),
    /// A compliant transmission whose drive side has no inertia (no rotor inertia, or the
    /// drives' dynamics left out), so its spring has nothing to push against.
    #[error("axis '{axis}': a compliant transmission needs inertia on its drive side (rotor_inertia_kg_m2 > 0, and the drives' dynamics included)")]
    CompliantWithoutDriveInertia {
        /// Name of the axis.
        axis: String,
    },
    /// A compliant transmission whose joint moves nothing with mass.
    #[error("axis '{axis}': a compliant transmission needs a moving carriage with mass")]
    CompliantWithoutLoad {
        /// Name of the axis.
        axis: String,
    },
    /// A `<mimic>` follower on a joint of its own coupled to an axis whose drive train is split
    /// in two bodies (backlash or a compliant transmission): its leader's coordinate (the
    /// carriage's) is then the sum of two DOFs, which an equality constraint between two DOFs
    /// cannot follow.
    #[error("joint '{follower}' follows axis '{axis}' through its <mimic>, and the axis has backlash or a compliant transmission: a follower on a joint of its own needs a rigid drive train on its leader (remove the backlash and the transmission stiffness of '{axis}', or let the follower ride on its leader's link: same parent, same axis line, multiplier ±1)")]
    FollowerOfSplitDrive {
        /// Name of the follower joint.
        follower: String,
        /// Name of the axis it follows.
        axis: String,
    },
    /// The physics step is too long for the engine's explicit step to integrate a compliant
    /// transmission's two-mass mode faithfully (ω·h above 0.5).
    #[error("axis '{axis}': the transmission's mode at {frequency_hz:.1} Hz (stiffness {stiffness:e}, damping {damping:e}) needs a physics step of at most {max_step:.3e} s to be integrated faithfully; the step is {step:.3e} s (lower [timing] physics_step_ms)")]
    StepTooLongForMode {
        /// Name of the axis.
        axis: String,
        /// Undamped frequency of the two-mass mode (Hz).
        frequency_hz: f64,
        /// Transmission stiffness (N/m, or N·m/rad on a rotary axis).
        stiffness: f64,
        /// Transmission damping (N·s/m, or N·m·s/rad on a rotary axis).
        damping: f64,
        /// Longest physics step that integrates the mode (s).
        max_step: f64,
        /// The physics step asked for (s).
        step: f64,
    },
}

/// The spring and damper of a compliant transmission between the drive side and the carriage,
/// in joint units, with the backlash as a dead zone: the drive passes
/// λ = k·(δ − clamp(δ, ±b/2)) + c·δ̇ to the carriage while the gap is closed (|δ| > b/2),
/// nothing while it is open; δ = drive − carriage.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TransmissionSpring {
    stiffness: f64,
    damping: f64,
    half_gap: f64,
}

impl TransmissionSpring {
    /// Stretch of the spring beyond the gap for gap δ (zero within it).
    fn stretch(&self, gap: f64) -> f64 {
        gap - gap.clamp(-self.half_gap, self.half_gap)
    }

    /// Force on the carriage (N or N·m) over a step of length `h` that starts at gap δ moving
    /// at δ̇. Within the gap or beyond it for the whole step (δ moving on at δ̇): the force at
    /// the start of the step, the engine's symplectic Euler step. A step in which the gap
    /// closes or opens gets the mean force over the part of the step the spring is engaged,
    /// δ taken as moving linearly: the engagement then starts where the gap ends, not at the
    /// step boundary, as the analytic model's located events have it (the rebound off the
    /// spring converges to the analytic one as the step shrinks, `tests/compliant_drives.rs`).
    fn force(&self, gap: f64, gap_rate: f64, h: f64) -> f64 {
        let start = self.stretch(gap);
        let end = self.stretch(gap + gap_rate * h);
        let engaged = |stretch: f64| stretch != 0.0;
        if !engaged(start) && !engaged(end) {
            return 0.0;
        }
        if engaged(start) && engaged(end) && end.signum() == start.signum() {
            return self.stiffness * start + self.damping * gap_rate;
        }
        if gap_rate == 0.0 {
            return self.stiffness * start;
        }
        // Engaged over [0, h·a) with stretch start → 0 (leaving) and over (h·(1 − e), h] with
        // stretch 0 → end (entering); a step can leave one side and enter the other.
        let mut impulse_per_h = 0.0;
        if engaged(start) {
            let leaving = (start / gap_rate).abs() / h;
            impulse_per_h += leaving * (self.stiffness * start / 2.0 + self.damping * gap_rate);
        }
        if engaged(end) {
            let entering = (end / gap_rate).abs() / h;
            impulse_per_h += entering * (self.stiffness * end / 2.0 + self.damping * gap_rate);
        }
        impulse_per_h
    }
}

/// Largest ω·h (mode angular frequency × physics step) at which a compliant transmission is
/// integrated: the engine's symplectic Euler step is stable below 2 and shifts the mode by
/// (ω·h)²/24, 1 % here. The same bound holds the damper's explicit step, c·h/m.
const MAX_MODE_PHASE_PER_STEP: f64 = 0.5;

/// One degree of freedom of the multibody that moves the tool.
struct ChainDof {
    /// Body whose joint owns the DOF.
    body: RigidBodyHandle,
    /// Direction of the DOF in that body's frame.
    local_axis: Vector3<f64>,
    kind: JointKind,
    dof: usize,
}

/// A `<mimic>` follower on its own DOF: the coupling to its leader and where it starts.
struct FollowerDof {
    coupling: MultibodyDofCoupling,
    /// Initial coordinate (m or rad): multiplier × the leader's initial coordinate + offset.
    start: f64,
}

/// Where a machine axis lives in the multibody.
struct AxisBinding {
    /// The body the drive pushes: the drive side of the transmission when the axis has
    /// backlash, the carriage itself otherwise.
    driven: RigidBodyHandle,
    /// Where the motor is mounted (the reaction goes there).
    parent: RigidBodyHandle,
    /// Joint axis in the driven body's frame.
    local_axis: Vector3<f64>,
    kind: JointKind,
    /// Multibody link and DOF of the drive joint.
    drive_link: usize,
    drive_dof: usize,
    /// Multibody link and DOF of the dead band between drive and carriage, if any.
    slack: Option<(usize, usize)>,
    /// The carriage's body and the spring of a compliant transmission (on the `slack` DOF).
    spring: Option<(RigidBodyHandle, TransmissionSpring)>,
    /// Index into a joint's coordinate array (0 = translation along the joint x, 3 = rotation).
    coordinate: usize,
    /// Multibody link and DOF of the carriage's pitch on two runners, if it has them.
    pitch: Option<(usize, usize)>,
    feedback: Feedback,
}

/// The colliders of one guide contact (the carriage's runners on the parent's guide).
struct GuidePair {
    guide: ColliderHandle,
    /// One runner under the joint origin, or the back and the front runner (in that order
    /// along the travel) of a carriage that pitches.
    runners: Vec<ColliderHandle>,
    /// Guide normal in the world frame (constant: guides sit on linear chains).
    normal: Vector3<f64>,
    /// Friction coefficient against sliding speed; with stiction it is set on the colliders
    /// before every step from the carriage's speed at the start of the step.
    coefficient: StribeckCurve,
}

/// The simulated machine.
pub struct Plant {
    world: PhysicsWorld,
    /// Per link: the body that carries it and the link's pose in that body's frame. Links on
    /// fixed joints ride on their parent's body (see [`RigidGroups`]).
    link_bodies: Vec<RigidBodyHandle>,
    link_offsets: Vec<Isometry3<f64>>,
    axes: Vec<AxisBinding>,
    /// The dynamic bodies the drives push or react on: the only ones whose forces change.
    forced_bodies: Vec<RigidBodyHandle>,
    tool_dofs: Vec<ChainDof>,
    /// The DOFs that move the program frame's carrier link (a moving table or bed).
    carrier_dofs: Vec<ChainDof>,
    /// The carrier link, where it moves (`None`: it rides on the fixed base, whose frame is
    /// the world's).
    carrier: Option<usize>,
    /// The link carrying the workpiece (the stock a cut removes rides on it), and the DOFs
    /// that move it.
    part_link: usize,
    part_dofs: Vec<ChainDof>,
    /// The cutting process's load, held until changed: on the tool, and reversed on the part.
    cutting: Option<CuttingLoad>,
    guides: Vec<Option<GuidePair>>,
    multibody: Option<MultibodyJointHandle>,
    tool_link: usize,
    tool_offset: Point3<f64>,
    /// The drives' generalised forces, held between calls of [`Plant::set_joint_forces`].
    joint_forces: Vec<f64>,
    /// Whether an axis has a compliant transmission: then every step reapplies the forces.
    compliant: bool,
    steps: u64,
}

/// Creep speed (m/s or rad/s) at which a passive joint's friction motor reaches its
/// Coulomb force: its stand-in for stiction.
const PASSIVE_CREEP_SPEED: f64 = 1e-6;

/// Natural frequency of the guide contacts' softness (Hz).
const GUIDE_CONTACT_HZ: f64 = 1000.0;

/// Radius of a guide runner: a ball under the carriage, so the runner touches its rail at one
/// point. A carriage without `runner_spacing_m` cannot tilt (the joint holds its rotation), so
/// where the load sits does not matter and one contact point carries it as well as four:
/// friction is μ·N either way, and the solver has three rows per guide instead of twelve (a
/// pad's four corners). With `runner_spacing_m` the carriage pitches on a back and a front
/// runner, whose contacts share the load as its moment demands (weight transfer); it still
/// cannot roll, so two points along the travel suffice.
const RUNNER_RADIUS: f64 = 0.005;

/// Half-width and half-thickness of a guide rail (m).
const RAIL_HALF: [f64; 2] = [0.02, 0.0025];

impl Plant {
    /// Builds the Rapier world for `machine`: one body per rigid group of links, joined into a
    /// multibody at the initial joint positions, with the drives' armature and damping, guide
    /// contacts and compliant transmissions.
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
        if let Some((follower, axis)) = machine.follower_of_split_drive() {
            return Err(ModelError::FollowerOfSplitDrive { follower, axis });
        }
        let couplings = machine.couplings();
        let mut world = PhysicsWorld::new();
        let parameters = &mut world.integration_parameters;
        parameters.num_solver_iterations = options.solver_iterations;
        parameters.dt = options.step;
        // One Coulomb cone per contact point (the default groups four points per constraint).
        parameters.friction_model = FrictionModel::Coulomb;
        // Nothing here flies fast enough to tunnel through a guide (continuous collision
        // detection): measured, turning it off saves 1.6 % of a step and changes no result.
        parameters.max_ccd_substeps = 0;
        // Guide contacts as stiff as the step allows: the default (30-60 Hz, tuned for game
        // piles) lets a 20 kg carriage sag ~0.1 mm into its guide; at GUIDE_CONTACT_HZ the
        // static sag is g/ω² ≈ 1 µm.
        let stiff = SpringCoefficients::new(GUIDE_CONTACT_HZ, 1.0);
        parameters.contact_softness = stiff;
        parameters.static_contact_softness = stiff;
        world.gravity = to_vec(&Vector3::from(options.gravity));
        // A contact pair that moved less than a few centimetres since its last full update is
        // recycled, not rebuilt. Stiction sets the guides' friction coefficient every step;
        // the patched Rapier carries it into recycled pairs (docs/rapier-patch.md, patch 9).
        world.integration_parameters.contact_recycling = true;
        // Rapier's statistics (contact and constraint counts) cost a pass over the contact
        // graph every step; nothing reads them.
        world.physics_pipeline.counters.disable();

        // One body per rigid group (a link and the links fixed to it), at its home pose (all
        // joints at zero); the multibody places them.
        let home = home_poses(machine);
        let groups = RigidGroups::of(machine);
        let masses = groups.mass_properties(machine);
        // A massless body is fine in the multibody's reduced coordinates (a frame between two
        // slides), as long as the mass matrix is not singular: the dynamics model checks it.
        let massless = masses
            .iter()
            .enumerate()
            .any(|(i, m)| i != machine.root && m.is_some_and(|m| m.mass() <= 0.0));
        if massless {
            crate::dynamics::DynamicsModel::from_machine(machine, Vector3::zeros())
                .map_err(|e| ModelError::SingularMass(e.to_string()))?;
        }
        let mut group_bodies = vec![None; machine.links.len()];
        for (i, mass) in masses.into_iter().enumerate() {
            let Some(mass) = mass else { continue };
            let body = if i == machine.root {
                RigidBodyBuilder::fixed()
            } else {
                // Machine axes creep at micrometres per second; they must never sleep.
                RigidBodyBuilder::dynamic()
                    .additional_mass_properties(mass)
                    .can_sleep(false)
            };
            group_bodies[i] = Some(world.insert_body(body.pose(to_pose(&home[i]))));
        }
        let link_bodies: Vec<RigidBodyHandle> = groups
            .carrier
            .iter()
            .map(|&c| group_bodies[c].expect("every carrier has a body"))
            .collect();

        let mut multibody = None;
        // Per URDF joint: the multibody handles of the joint that moves its child link
        // (the dead band when there is one) and of the drive joint.
        let mut child_joint = Vec::with_capacity(machine.joints.len());
        let mut drive_joint = Vec::with_capacity(machine.joints.len());
        let mut drive_body = Vec::with_capacity(machine.joints.len());
        let mut guides: Vec<Option<GuidePair>> = (0..machine.axes.len()).map(|_| None).collect();
        for (j, joint) in machine.joints.iter().enumerate() {
            if joint.kind == JointKind::Fixed {
                // Part of its parent's rigid group: no joint, no body of its own.
                child_joint.push(None);
                drive_joint.push(None);
                drive_body.push(link_bodies[joint.child]);
                continue;
            }
            // The joint's origin in the frame of the body carrying its parent link.
            let origin = groups.offset[joint.parent] * joint.origin;
            let axis = machine.axes.iter().position(|a| a.joint == j);
            let drive = axis.map(|a| &machine.axes[a].drive);
            let backlash = drive.map_or(0.0, |d| d.backlash);
            let compliance = drive.and_then(|d| d.compliance());
            let guide = drive.and_then(|d| d.guide);
            let parent = link_bodies[joint.parent];
            let child = link_bodies[joint.child];
            // Joint frames: x along the joint axis and, for a guided carriage, z along the
            // guide normal, so the free coordinates are x (travel) and z (lift-off).
            let frame = joint_frame(&joint.axis, guide.map(|g| Vector3::from(g.normal)));
            // Guided: lift-off along z; on two runners also pitch about y (normal × travel).
            let free_normal = match guide {
                Some(g) if g.runner_spacing_m.is_some() => {
                    JointAxesMask::LIN_Z | JointAxesMask::ANG_Y
                }
                Some(_) => JointAxesMask::LIN_Z,
                None => JointAxesMask::empty(),
            };
            let locked = match joint.kind {
                JointKind::Revolute => JointAxesMask::LOCKED_REVOLUTE_AXES,
                _ => JointAxesMask::LOCKED_PRISMATIC_AXES,
            };
            let mut insert = |world: &mut PhysicsWorld, a, b, data| {
                let handle = world
                    .insert_multibody_joint(a, b, data)
                    .ok_or_else(|| ModelError::Joint(joint.name.clone()))?;
                multibody.get_or_insert(handle);
                Ok::<_, ModelError>(handle)
            };
            if (backlash > 0.0 || compliance.is_some()) && joint.friction > 0.0 {
                // The multibody has no joint between the carriage and its carrier there.
                return Err(ModelError::FrictionBehindDriveTrain(joint.name.clone()));
            }
            if backlash > 0.0 || compliance.is_some() {
                // The drive side (motor, gearbox, pulley or screw nut) as its own body: no mass
                // of its own, its inertia is the drive's armature on its DOF. The carriage
                // follows it through a short-travel joint with rigid limits ±b/2, or, through
                // a compliant transmission, a free one (the spring acts every step).
                let d = world.insert_body(
                    RigidBodyBuilder::dynamic()
                        .can_sleep(false)
                        .pose(to_pose(&home[joint.child])),
                );
                let drive_data = GenericJointBuilder::new(locked)
                    .local_frame1(to_pose(&(origin * frame)))
                    .local_frame2(to_pose(&frame))
                    .contacts_enabled(false)
                    .build();
                let (slack_axis, slack_locked) = match joint.kind {
                    JointKind::Revolute => (JointAxis::AngX, JointAxesMask::LOCKED_REVOLUTE_AXES),
                    _ => (JointAxis::LinX, JointAxesMask::LOCKED_PRISMATIC_AXES),
                };
                let mut slack_builder = GenericJointBuilder::new(slack_locked & !free_normal)
                    .local_frame1(to_pose(&frame))
                    .local_frame2(to_pose(&frame))
                    .contacts_enabled(false);
                if compliance.is_none() {
                    slack_builder =
                        slack_builder.limits(slack_axis, [-backlash / 2.0, backlash / 2.0]);
                }
                let slack_data = slack_builder.build();
                drive_joint.push(Some(insert(&mut world, parent, d, drive_data)?));
                child_joint.push(Some(insert(&mut world, d, child, slack_data)?));
                drive_body.push(d);
            } else {
                let mut builder = GenericJointBuilder::new(locked & !free_normal)
                    .local_frame1(to_pose(&(origin * frame)))
                    .local_frame2(to_pose(&frame))
                    .contacts_enabled(guide.is_some());
                if joint.friction > 0.0 {
                    // The joint's own Coulomb friction (a passive joint's, or a driven one's
                    // `<dynamics friction>`): a motor holding zero speed with at most the
                    // friction force, stiff enough to hold below a µm/s of creep.
                    let travel = match joint.kind {
                        JointKind::Revolute => JointAxis::AngX,
                        _ => JointAxis::LinX,
                    };
                    builder = builder
                        .motor_model(travel, MotorModel::ForceBased)
                        .motor_velocity(travel, 0.0, joint.friction / PASSIVE_CREEP_SPEED)
                        .motor_max_force(travel, joint.friction);
                }
                let data = builder.build();
                let handle = insert(&mut world, parent, child, data)?;
                drive_joint.push(axis.map(|_| handle));
                child_joint.push(Some(handle));
                drive_body.push(child);
            }
            if let (Some(a), Some(g)) = (axis, guide) {
                // Each guide touches only its own runners: one collision group per axis.
                let group = Group::from_bits_truncate(1 << (a % 32));
                guides[a] = Some(insert_guide(
                    &mut world,
                    (parent, child),
                    joint,
                    (&groups.offset[joint.parent], &frame),
                    g,
                    &home[joint.parent],
                    InteractionGroups::new(group, group, InteractionTestMode::And),
                ));
            }
        }

        let link_of = |world: &PhysicsWorld, handle| {
            world
                .multibody_joints
                .get(handle)
                .expect("joint just inserted")
                .1
        };
        let coordinate = |kind| if kind == JointKind::Revolute { 3 } else { 0 };
        let mut axes = Vec::with_capacity(machine.axes.len());
        for axis in &machine.axes {
            let j = axis.joint;
            let joint = &machine.joints[j];
            let drive = drive_joint[j].expect("every axis has a drive joint");
            let carriage = child_joint[j].expect("axes move their links");
            let slack = (drive != carriage).then(|| link_of(&world, carriage));
            let pitches = axis
                .drive
                .guide
                .is_some_and(|g| g.runner_spacing_m.is_some());
            let spring = match axis.drive.compliance() {
                Some(c) => Some((
                    link_bodies[joint.child],
                    transmission_spring(machine, axis, c, options)?,
                )),
                None => None,
            };
            axes.push(AxisBinding {
                driven: drive_body[j],
                parent: link_bodies[joint.parent],
                local_axis: joint.axis,
                kind: joint.kind,
                drive_link: link_of(&world, drive),
                drive_dof: usize::MAX, // known once the fixed root is resolved (configure_dofs)
                slack: slack.map(|link| (link, usize::MAX)),
                spring,
                coordinate: coordinate(joint.kind),
                pitch: pitches.then(|| (link_of(&world, carriage), usize::MAX)),
                feedback: axis.drive.feedback,
            });
        }

        // Every DOF between the root and the tool link, and between the root and the program
        // frame's carrier (a moving table), for the tool's velocity relative to the part.
        let chain_dofs = |start: usize| {
            let mut dofs = Vec::new();
            let mut link = start;
            while let Some(j) = machine.parent_joint(link) {
                let joint = &machine.joints[j];
                link = joint.parent;
                let Some(carriage) = child_joint[j] else {
                    continue; // fixed
                };
                let child = link_bodies[joint.child];
                let mut push = |body, local_axis, kind, at: (usize, usize)| {
                    dofs.push((
                        ChainDof {
                            body,
                            local_axis,
                            kind,
                            dof: usize::MAX,
                        },
                        at,
                    ))
                };
                // A passive joint has no drive side: its one joint moves the link.
                let drive = drive_joint[j].unwrap_or(carriage);
                let guide = machine
                    .axes
                    .iter()
                    .find(|a| a.joint == j)
                    .and_then(|a| a.drive.guide);
                push(
                    drive_body[j],
                    joint.axis,
                    joint.kind,
                    (link_of(&world, drive), 0),
                );
                if drive != carriage {
                    push(
                        child,
                        joint.axis,
                        joint.kind,
                        (link_of(&world, carriage), 0),
                    );
                }
                if let Some(g) = guide {
                    // The lift-off DOF follows the travel DOF in the carriage's joint, the
                    // pitch (about normal × travel, through the joint origin) the lift-off.
                    let normal = Vector3::from(g.normal).normalize();
                    push(
                        child,
                        normal,
                        JointKind::Prismatic,
                        (link_of(&world, carriage), 1),
                    );
                    if g.runner_spacing_m.is_some() {
                        push(
                            child,
                            normal.cross(&joint.axis.normalize()),
                            JointKind::Revolute,
                            (link_of(&world, carriage), 2),
                        );
                    }
                }
            }
            dofs
        };
        let carrier = crate::kinematics::carrier_link(machine);
        let tool_dofs = chain_dofs(machine.tool_link);
        let carrier_dofs = chain_dofs(carrier);
        let part_dofs = chain_dofs(machine.workpiece_link);

        let mut forced_bodies: Vec<RigidBodyHandle> = axes
            .iter()
            .flat_map(|a| {
                [a.driven, a.parent]
                    .into_iter()
                    .chain(a.spring.map(|(c, _)| c))
            })
            .filter(|&body| world.bodies[body].is_dynamic())
            .collect();
        let compliant = axes.iter().any(|a| a.spring.is_some());
        forced_bodies.sort_unstable_by_key(|body| body.into_raw_parts());
        forced_bodies.dedup();
        let mut plant = Plant {
            world,
            link_bodies,
            link_offsets: groups.offset,
            axes,
            forced_bodies,
            tool_dofs: Vec::new(),
            carrier_dofs: Vec::new(),
            // The base's frame is the world's; any other carrier (a fixture fixed to the base
            // at an offset, a moving bed) has its own pose.
            carrier: (carrier != machine.root).then_some(carrier),
            part_link: machine.workpiece_link,
            part_dofs: Vec::new(),
            cutting: None,
            guides,
            multibody,
            tool_link: machine.tool_link,
            tool_offset: Point3::from(machine.tool.offset_m),
            joint_forces: vec![0.0; machine.axes.len()],
            compliant,
            steps: 0,
        };
        // The joints no axis drives that move: passive ones and <mimic> followers, each on
        // its own DOF with the URDF's damping.
        let passive_dofs = machine
            .passive_joints()
            .into_iter()
            .chain(couplings.iter().map(|c| c.follower))
            .filter_map(|j| {
                let handle = child_joint[j]?;
                Some((link_of(&plant.world, handle), machine.joints[j].damping))
            })
            .collect();
        let followers = couplings
            .iter()
            .map(|c| {
                let link = |j: usize| {
                    link_of(
                        &plant.world,
                        child_joint[j].expect("followers and leaders move"),
                    )
                };
                let leader_start = machine
                    .axes
                    .iter()
                    .zip(&options.initial_positions)
                    .find_map(|(a, &q)| (a.joint == c.leader).then_some(q))
                    .unwrap_or(0.0);
                FollowerDof {
                    coupling: MultibodyDofCoupling {
                        link1: link(c.leader),
                        dof1: 0,
                        axis1: coordinate(machine.joints[c.leader].kind),
                        link2: link(c.follower),
                        dof2: 0,
                        axis2: coordinate(machine.joints[c.follower].kind),
                        coeff: c.multiplier,
                        offset: c.offset,
                    },
                    start: c.multiplier * leader_start + c.offset,
                }
            })
            .collect();
        plant.configure_dofs(
            machine,
            options,
            [tool_dofs, carrier_dofs, part_dofs],
            passive_dofs,
            followers,
        );
        Ok(plant)
    }

    /// Armature, damping and initial coordinates of the driven DOFs, and the final DOF indices.
    /// The chains to the tool, the carrier and the part carry (multibody link, DOF offset
    /// within the link's joint); `passive_dofs` (multibody link, URDF damping) are the joints no axis drives that
    /// move (passive ones and `<mimic>` followers); `followers` couple the latter to leaders.
    fn configure_dofs(
        &mut self,
        machine: &Machine,
        options: &PlantOptions,
        [tool_dofs, carrier_dofs, part_dofs]: [Vec<(ChainDof, (usize, usize))>; 3],
        passive_dofs: Vec<(usize, f64)>,
        followers: Vec<FollowerDof>,
    ) {
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
            binding.drive_dof = mb
                .link(binding.drive_link)
                .expect("axis link")
                .assembly_id();
            if let Some((link, dof)) = &mut binding.slack {
                *dof = mb.link(*link).expect("slack link").assembly_id();
            }
            if let Some((link, dof)) = &mut binding.pitch {
                // Travel (or dead band), lift-off, pitch: the carriage joint's third DOF. Its
                // only stiffness and damping are the runners' contacts (critically damped);
                // Rapier's default damping of angular DOFs is not part of the machine.
                *dof = mb.link(*link).expect("carriage link").assembly_id() + 2;
                mb.damping_mut()[*dof] = 0.0;
            }
            let joint = &machine.joints[axis.joint];
            let (armature, drive_damping) = if options.include_drive_dynamics {
                (
                    axis.drive.reflected_inertia(),
                    axis.drive.reflected_damping(),
                )
            } else {
                (0.0, 0.0)
            };
            mb.armature_mut()[binding.drive_dof] = armature;
            mb.damping_mut()[binding.drive_dof] = drive_damping + joint.damping;
            displacement[binding.drive_dof] = q0;
        }
        for (link, damping) in passive_dofs {
            let dof = mb.link(link).expect("passive joint link").assembly_id();
            mb.damping_mut()[dof] = damping;
        }
        for follower in followers {
            // Rapier holds q_follower = coeff·q_leader + offset as a bilateral velocity
            // constraint with position correction (both DOFs in this one multibody).
            let dof = mb
                .link(follower.coupling.link2)
                .expect("follower link")
                .assembly_id();
            displacement[dof] = follower.start;
            mb.add_dof_coupling(follower.coupling);
        }
        let resolve = |dofs: Vec<(ChainDof, (usize, usize))>| -> Vec<ChainDof> {
            dofs.into_iter()
                .map(|(mut d, (link, offset))| {
                    d.dof = mb.link(link).expect("chain link").assembly_id() + offset;
                    d
                })
                .collect()
        };
        self.tool_dofs = resolve(tool_dofs);
        self.carrier_dofs = resolve(carrier_dofs);
        self.part_dofs = resolve(part_dofs);
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

    /// Number of machine axes (drives).
    pub fn axis_count(&self) -> usize {
        self.axes.len()
    }

    /// Sets the generalised force each drive applies at its joint (N or N·m), held until the
    /// next call. It acts on the drive side of the transmission, the reaction on the link the
    /// motor is mounted on. A linear drive pushes along the joint axis through the joint origin
    /// (the URDF's axis line), not through the carriage's centre of mass: on a carriage that
    /// pitches, the drive's line decides the moment that shifts the load between the runners.
    pub fn set_joint_forces(&mut self, forces: &[f64]) {
        for (held, &f) in self.joint_forces.iter_mut().zip(forces) {
            *held = f;
        }
        if !self.compliant {
            self.apply_forces();
        }
    }

    /// Applies the held drive forces and, on compliant axes, the transmission springs at the
    /// present state.
    fn apply_forces(&mut self) {
        // Only these bodies: touching a body marks it modified, which Rapier then processes.
        for &body in &self.forced_bodies {
            let rb = &mut self.world.bodies[body];
            rb.reset_forces(false);
            rb.reset_torques(false);
        }
        for (binding, &f) in self.axes.iter().zip(&self.joint_forces) {
            // The driven body's origin is the joint origin (the drive side of a backlash sits
            // at its carriage's pose).
            let (direction, origin) = {
                let driven = from_pose(self.world.bodies[binding.driven].position());
                (
                    driven.rotation * binding.local_axis,
                    driven.translation.vector,
                )
            };
            let load = to_vec(&(direction * f));
            let parent_moves = self.world.bodies[binding.parent].is_dynamic();
            match binding.kind {
                JointKind::Prismatic => {
                    let at = to_vec(&origin);
                    self.world.bodies[binding.driven].add_force_at_point(load, at, false);
                    if parent_moves {
                        self.world.bodies[binding.parent].add_force_at_point(-load, at, false);
                    }
                }
                JointKind::Revolute => {
                    self.world.bodies[binding.driven].add_torque(load, false);
                    if parent_moves {
                        self.world.bodies[binding.parent].add_torque(-load, false);
                    }
                }
                JointKind::Fixed => {}
            }
        }
        if self.compliant {
            self.apply_transmission_springs();
        }
        self.apply_cutting_load();
    }

    /// Pushes drive side and carriage of each compliant axis apart by the spring's force at
    /// the state at the start of the step (explicit, see [`MAX_MODE_PHASE_PER_STEP`]).
    fn apply_transmission_springs(&mut self) {
        let Some(handle) = self.multibody else { return };
        let Some((mb, _)) = self.world.multibody_joints.get(handle) else {
            return;
        };
        let v = mb.generalized_velocity();
        let step = self.world.integration_parameters.dt;
        for b in &self.axes {
            let (Some((carriage, spring)), Some((link, dof))) = (b.spring, b.slack) else {
                continue;
            };
            // The slack coordinate is carriage − drive, δ its negative.
            let slack = Self::coordinate(mb, link, b.coordinate);
            let lambda = spring.force(-slack, -v[dof], step);
            if lambda == 0.0 {
                continue;
            }
            let driven = from_pose(self.world.bodies[b.driven].position());
            let direction = driven.rotation * b.local_axis;
            let load = to_vec(&(direction * lambda));
            match b.kind {
                JointKind::Prismatic => {
                    let at = to_vec(&driven.translation.vector);
                    self.world.bodies[carriage].add_force_at_point(load, at, false);
                    self.world.bodies[b.driven].add_force_at_point(-load, at, false);
                }
                JointKind::Revolute => {
                    self.world.bodies[carriage].add_torque(load, false);
                    self.world.bodies[b.driven].add_torque(-load, false);
                }
                JointKind::Fixed => {}
            }
        }
    }

    /// Advances the physics by one step.
    pub fn step(&mut self) {
        if self.compliant || self.cutting.is_some() {
            self.apply_forces();
        }
        self.update_guide_friction();
        self.world.step();
        self.steps += 1;
    }

    /// Rapier's contacts know one coefficient (static = kinetic). Stiction is the coefficient
    /// following the Stribeck curve of the carriage's sliding speed, one step behind; a
    /// carriage at rest creeps at most micrometres per second, so it is held at μ_s.
    fn update_guide_friction(&mut self) {
        for a in 0..self.axes.len() {
            let Some(guide) = &self.guides[a] else {
                continue;
            };
            if !guide.coefficient.has_stiction() {
                continue;
            }
            let Some(mb) = self.multibody() else { return };
            let mu = guide
                .coefficient
                .sliding(Self::carriage_velocity(mb, &self.axes[a]));
            let GuidePair { guide, runners, .. } = guide;
            for &collider in runners.iter().chain([guide]) {
                if let Some(c) = self.world.colliders.get_mut(collider) {
                    c.set_friction(mu);
                }
            }
        }
    }

    /// The machine's multibody (none for a machine without joints).
    fn multibody(&self) -> Option<&Multibody> {
        let handle = self.multibody?;
        self.world.multibody_joints.get(handle).map(|(mb, _)| mb)
    }

    fn coordinate(mb: &Multibody, link: usize, index: usize) -> f64 {
        mb.link(link)
            .map_or(f64::NAN, |l| l.joint().coords()[index])
    }

    /// Carriage (load-side) coordinate of each axis (m or rad): the drive's coordinate plus
    /// where the carriage sits in the dead band.
    pub fn positions(&self, out: &mut [f64]) {
        let Some(mb) = self.multibody() else { return };
        for (o, b) in out.iter_mut().zip(&self.axes) {
            *o = Self::coordinate(mb, b.drive_link, b.coordinate)
                + b.slack
                    .map_or(0.0, |(link, _)| Self::coordinate(mb, link, b.coordinate));
        }
    }

    /// Drive-side coordinate of each axis (m or rad): motor angle over the transmission ratio.
    pub fn drive_positions(&self, out: &mut [f64]) {
        let Some(mb) = self.multibody() else { return };
        for (o, b) in out.iter_mut().zip(&self.axes) {
            *o = Self::coordinate(mb, b.drive_link, b.coordinate);
        }
    }

    /// The position each axis's feedback device measures: the drive side for a motor encoder,
    /// the carriage for a linear scale.
    pub fn feedback_positions(&self, out: &mut [f64]) {
        let Some(mb) = self.multibody() else { return };
        for (o, b) in out.iter_mut().zip(&self.axes) {
            let drive = Self::coordinate(mb, b.drive_link, b.coordinate);
            *o = match (b.feedback, b.slack) {
                (Feedback::Carriage, Some((link, _))) => {
                    drive + Self::coordinate(mb, link, b.coordinate)
                }
                _ => drive,
            };
        }
    }

    /// Carriage velocity of each axis (m/s or rad/s).
    pub fn velocities(&self, out: &mut [f64]) {
        let Some(mb) = self.multibody() else { return };
        for (o, b) in out.iter_mut().zip(&self.axes) {
            *o = Self::carriage_velocity(mb, b);
        }
    }

    /// The drive's velocity plus the carriage's within the dead band.
    fn carriage_velocity(mb: &Multibody, b: &AxisBinding) -> f64 {
        let v = mb.generalized_velocity();
        v[b.drive_dof] + b.slack.map_or(0.0, |(_, dof)| v[dof])
    }

    /// Drive-side velocity of each axis (m/s or rad/s): the motor speed over the ratio.
    pub fn drive_velocities(&self, out: &mut [f64]) {
        let Some(mb) = self.multibody() else { return };
        let v = mb.generalized_velocity();
        for (o, b) in out.iter_mut().zip(&self.axes) {
            *o = v[b.drive_dof];
        }
    }

    /// Normal force each axis's guide carries (N), over all its runners, from the contact
    /// impulses of the last step; `None` for an axis without a guide.
    pub fn guide_normal_forces(&self) -> Vec<Option<f64>> {
        (0..self.guides.len())
            .map(|a| Some(self.runner_normal_forces(a)?.iter().sum()))
            .collect()
    }

    /// Normal force on each runner of axis `axis`'s guide (N), from the contact impulses of
    /// the last step: one runner, or the back and the front runner (along the travel).
    pub fn runner_normal_forces(&self, axis: usize) -> Option<Vec<f64>> {
        let g = self.guides.get(axis)?.as_ref()?;
        let dt = self.step_size();
        let forces = g
            .runners
            .iter()
            .map(|&runner| {
                let pair = self.world.narrow_phase.contact_pair(g.guide, runner);
                let impulse = pair.map_or(Vector3::zeros(), |p| from_vec(&p.total_impulse()));
                // The impulse is the one the pair applies to its first collider; either way
                // its component along the guide normal is the load, up to sign.
                impulse.dot(&g.normal).abs() / dt
            })
            .collect();
        Some(forces)
    }

    /// Pitch of each axis's carriage on its two runners (rad, about guide normal × travel;
    /// positive dips the front: the top leans forward); `None` for a carriage that cannot pitch.
    pub fn carriage_pitches(&self) -> Vec<Option<f64>> {
        let mb = self.multibody();
        self.axes
            .iter()
            .map(|b| {
                let (link, _) = b.pitch?;
                // Joint coordinates: three translations, then the rotations about x, y, z.
                mb.map(|mb| Self::coordinate(mb, link, 4))
            })
            .collect()
    }

    /// World pose of every link, in the machine's link order.
    pub fn link_poses(&self) -> Vec<Isometry3<f64>> {
        (0..self.link_bodies.len())
            .map(|link| self.link_pose(link))
            .collect()
    }

    /// Tool point in the world (the machine base's frame), m.
    fn tool_in_world(&self) -> Point3<f64> {
        let body = &self.world.bodies[self.link_bodies[self.tool_link]];
        from_pose(body.position()) * self.link_offsets[self.tool_link] * self.tool_offset
    }

    fn link_pose(&self, link: usize) -> Isometry3<f64> {
        from_pose(self.world.bodies[self.link_bodies[link]].position()) * self.link_offsets[link]
    }

    /// Tool point relative to the program frame's carrier link (the workpiece, or the link the
    /// rotary axes carrying it stand on), in that link's frame (m).
    pub fn tool_point(&self) -> Point3<f64> {
        let tool = self.tool_in_world();
        match self.carrier {
            None => tool,
            Some(link) => self.link_pose(link).inverse_transform_point(&tool),
        }
    }

    /// Velocity of the tool point relative to the carrier link, in its frame (m/s), from the
    /// joints' generalised velocities along the chains to the tool and to the carrier (a
    /// Jacobian product). Rapier's per-link body velocities of a multibody are one step older
    /// than its joint velocities and positions, so they are not used.
    pub fn tool_velocity(&self) -> Vector3<f64> {
        let Some(mb) = self.multibody() else {
            return Vector3::zeros();
        };
        let tool = self.tool_in_world();
        let velocity = self.point_velocity(mb, &self.tool_dofs, &tool);
        match self.carrier {
            None => velocity,
            Some(link) => {
                // Less the velocity of the carrier's material point under the tool.
                let relative = velocity - self.point_velocity(mb, &self.carrier_dofs, &tool);
                self.link_pose(link)
                    .rotation
                    .inverse_transform_vector(&relative)
            }
        }
    }

    /// Velocity (world frame) of the world point `point` carried by the last link of the chain
    /// `dofs`, from the joints' generalised velocities (a Jacobian product).
    fn point_velocity(
        &self,
        mb: &Multibody,
        dofs: &[ChainDof],
        point: &Point3<f64>,
    ) -> Vector3<f64> {
        let v = mb.generalized_velocity();
        let mut velocity = Vector3::zeros();
        for d in dofs {
            let frame = from_pose(self.world.bodies[d.body].position());
            let axis = frame.rotation * d.local_axis;
            velocity += match d.kind {
                JointKind::Prismatic => axis * v[d.dof],
                JointKind::Revolute => {
                    axis.cross(&(point - Point3::from(frame.translation.vector))) * v[d.dof]
                }
                JointKind::Fixed => Vector3::zeros(),
            };
        }
        velocity
    }

    /// The tool on the part, in the frame of the link carrying the workpiece: the tool point,
    /// the tool's axis (`axis` given in the tool link's frame) and the tool point's velocity
    /// relative to the part's material point under it (m, unit vector, m/s).
    pub fn tool_on_part(&self, axis: &Vector3<f64>) -> ToolOnPart {
        let part = self.link_pose(self.part_link);
        let tool = self.tool_in_world();
        let world_axis = self.link_pose(self.tool_link).rotation * axis;
        let velocity = self.multibody().map_or(Vector3::zeros(), |mb| {
            self.point_velocity(mb, &self.tool_dofs, &tool)
                - self.point_velocity(mb, &self.part_dofs, &tool)
        });
        ToolOnPart {
            point: part.inverse_transform_point(&tool),
            axis: part.rotation.inverse_transform_vector(&world_axis),
            velocity: part.rotation.inverse_transform_vector(&velocity),
        }
    }

    /// Sets the cutting process's load (in the part link's frame), held until changed;
    /// `None` takes it off. It is applied every physics step.
    pub fn set_cutting_load(&mut self, load: Option<CuttingLoad>) {
        if load.is_some() && self.cutting.is_none() {
            // From now on the tool's and the part's bodies are pushed, so their forces are
            // reset every step (a run that never cuts leaves them untouched).
            let bodies = [self.tool_link, self.part_link].map(|link| self.link_bodies[link]);
            for body in bodies {
                if self.world.bodies[body].is_dynamic() && !self.forced_bodies.contains(&body) {
                    self.forced_bodies.push(body);
                }
            }
        }
        self.cutting = load;
    }

    /// Applies the held cutting load: the force on the tool's body at its point, the reverse
    /// and the torque the part takes on the part's body.
    fn apply_cutting_load(&mut self) {
        let Some(load) = self.cutting else { return };
        let part = self.link_pose(self.part_link);
        let force = to_vec(&(part.rotation * load.on_tool));
        let at = to_vec(&(part * load.at).coords);
        let torque = to_vec(&(part.rotation * load.torque_on_part));
        let tool_body = self.link_bodies[self.tool_link];
        let part_body = self.link_bodies[self.part_link];
        if self.world.bodies[tool_body].is_dynamic() {
            self.world.bodies[tool_body].add_force_at_point(force, at, false);
        }
        if self.world.bodies[part_body].is_dynamic() {
            let rb = &mut self.world.bodies[part_body];
            rb.add_force_at_point(-force, at, false);
            rb.add_torque(torque, false);
        }
    }
}

/// The tool on the part, in the frame of the link carrying the workpiece.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolOnPart {
    /// The tool point (m).
    pub point: Point3<f64>,
    /// Unit vector along the tool's axis, from the tip toward the spindle.
    pub axis: Vector3<f64>,
    /// Velocity of the tool point relative to the part's material point under it (m/s).
    pub velocity: Vector3<f64>,
}

/// What the cutting process loads the machine with, in the frame of the link carrying the
/// workpiece.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CuttingLoad {
    /// Force of the part on the tool (N).
    pub on_tool: Vector3<f64>,
    /// Where it acts (m).
    pub at: Point3<f64>,
    /// Torque the part takes besides the reversed force at `at` (N·m): the moment of the
    /// tangential forces about the tool's axis, which on the tool side the spindle motor
    /// takes.
    pub torque_on_part: Vector3<f64>,
}

/// Inserts the guide (on the parent link) and the runners (under the carriage) of a guided
/// joint. At the home pose the runner balls touch the guide's top face, one at the joint
/// origin or two at ∓spacing/2 along the travel; the guide runs the whole travel so no
/// contact ever ends.
fn insert_guide(
    world: &mut PhysicsWorld,
    (parent, child): (RigidBodyHandle, RigidBodyHandle),
    joint: &crate::machine::Joint,
    (parent_offset, frame): (&Isometry3<f64>, &Isometry3<f64>),
    guide: Guide,
    parent_home: &Isometry3<f64>,
    groups: InteractionGroups,
) -> GuidePair {
    // URDF prismatic joints carry limits; a limitless one gets a metre of rail each way.
    let [lo, hi] = joint.limits.unwrap_or([-1.0, 1.0]);
    let [hb, ht] = RAIL_HALF;
    // In the joint frame `frame`: x along the travel, z along the guide normal.
    // Back and front runner at ∓spacing/2 along the travel, or one under the joint origin.
    let spacing = guide.runner_spacing_m;
    let offsets = match spacing {
        Some(l) => vec![-l / 2.0, l / 2.0],
        None => vec![0.0],
    };
    let guide_half_length = (hi - lo) / 2.0 + spacing.unwrap_or(0.0) / 2.0 + RUNNER_RADIUS;
    let guide_shape = ColliderBuilder::cuboid(guide_half_length, hb, ht);
    let coefficient = guide.coefficient();
    // At rest: a carriage starts stuck, held by the static coefficient.
    let mu = coefficient.breakaway;
    let finish = |b: ColliderBuilder, pose: Isometry3<f64>| {
        b.position(to_pose(&pose))
            .density(0.0)
            .friction(mu)
            .friction_combine_rule(CoefficientCombineRule::Min)
            .restitution(0.0)
            .collision_groups(groups)
            .build()
    };
    let guide_pose =
        parent_offset * joint.origin * frame * Translation3::new((lo + hi) / 2.0, 0.0, -ht);
    let runners = offsets
        .into_iter()
        .map(|x| {
            let pose = frame * Translation3::new(x, 0.0, RUNNER_RADIUS);
            let ball = ColliderBuilder::ball(RUNNER_RADIUS);
            world.insert_collider(finish(ball, pose), Some(child))
        })
        .collect();
    let guide_collider = world.insert_collider(finish(guide_shape, guide_pose), Some(parent));
    let normal = (parent_home * joint.origin * frame).rotation * Vector3::z();
    GuidePair {
        guide: guide_collider,
        runners,
        normal,
        coefficient,
    }
}

/// A joint frame whose x is `axis` and, if given, whose z is `normal` (perpendicular to it).
fn joint_frame(axis: &Vector3<f64>, normal: Option<Vector3<f64>>) -> Isometry3<f64> {
    let Some(normal) = normal else {
        return x_to_axis(axis);
    };
    let x = axis.normalize();
    let z = normal.normalize();
    let y = z.cross(&x);
    let rotation = UnitQuaternion::from_rotation_matrix(
        &nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_columns(&[x, y, z])),
    );
    Isometry3::from_parts(Translation3::identity(), rotation)
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

/// Links joined by fixed joints move as one rigid body: each group is carried by the body of
/// its topmost link. A fixed joint costs the multibody a link (kinematics, a block of the mass
/// matrix) and moves nothing, so its child rides on its parent's body instead, with its mass.
struct RigidGroups {
    /// Per link: the link whose body carries it (itself, unless it hangs on a fixed joint).
    carrier: Vec<usize>,
    /// Per link: its pose in the carrier's frame.
    offset: Vec<Isometry3<f64>>,
}

impl RigidGroups {
    fn of(machine: &Machine) -> RigidGroups {
        let n = machine.links.len();
        let mut groups = RigidGroups {
            carrier: (0..n).collect(),
            offset: vec![Isometry3::identity(); n],
        };
        // Joints are ordered parents first, so a parent's carrier is final before its child's.
        for joint in machine.joints.iter().filter(|j| j.kind == JointKind::Fixed) {
            groups.carrier[joint.child] = groups.carrier[joint.parent];
            groups.offset[joint.child] = groups.offset[joint.parent] * joint.origin;
        }
        groups
    }

    /// The combined mass properties of each group, in its carrier's frame (`None` for links
    /// that are carried by another).
    fn mass_properties(&self, machine: &Machine) -> Vec<Option<MassProperties>> {
        let mut sums: Vec<Option<MassProperties>> = vec![None; machine.links.len()];
        for (i, link) in machine.links.iter().enumerate() {
            let own = MassProperties::with_inertia_matrix(
                to_vec(&link.center_of_mass.coords),
                link.mass,
                convert::to_mat(&link.inertia),
            )
            .transform_by(&to_pose(&self.offset[i]));
            let sum = sums[self.carrier[i]].get_or_insert(MassProperties::default());
            *sum += own;
        }
        sums
    }
}

/// The spring of axis `axis`'s compliant transmission, refused where the engine's explicit step
/// could not integrate its mode faithfully.
fn transmission_spring(
    machine: &Machine,
    axis: &crate::machine::Axis,
    compliance: crate::machine::Compliance,
    options: &PlantOptions,
) -> Result<TransmissionSpring, ModelError> {
    let drive_mass = if options.include_drive_dynamics {
        axis.drive.reflected_inertia()
    } else {
        0.0
    };
    if drive_mass.is_nan() || drive_mass <= 0.0 {
        return Err(ModelError::CompliantWithoutDriveInertia {
            axis: axis.name.clone(),
        });
    }
    let load = moved_inertia(machine, axis.joint);
    if load.is_nan() || load <= 0.0 {
        return Err(ModelError::CompliantWithoutLoad {
            axis: axis.name.clone(),
        });
    }
    // The two-mass mode: ω² = k·(1/m_d + 1/m_c); the damper's rate c·(1/m_d + 1/m_c).
    let flexibility = 1.0 / drive_mass + 1.0 / load;
    let omega = (compliance.stiffness * flexibility).sqrt();
    let rate = compliance.damping * flexibility;
    let max_step = MAX_MODE_PHASE_PER_STEP / omega.max(rate);
    if options.step > max_step {
        return Err(ModelError::StepTooLongForMode {
            axis: axis.name.clone(),
            frequency_hz: omega / std::f64::consts::TAU,
            stiffness: compliance.stiffness,
            damping: compliance.damping,
            max_step,
            step: options.step,
        });
    }
    Ok(TransmissionSpring {
        stiffness: compliance.stiffness,
        damping: compliance.damping,
        half_gap: axis.drive.backlash / 2.0,
    })
}

/// What joint `j` moves, at the home pose: the mass of everything downstream of a prismatic
/// joint (kg), the moment of inertia of it about a revolute joint's axis (kg·m²).
pub fn moved_inertia(machine: &Machine, j: usize) -> f64 {
    let joint = &machine.joints[j];
    let home = home_poses(machine);
    let moved = machine.subtree(joint.child);
    let frame = home[joint.parent] * joint.origin;
    let axis = (frame.rotation * joint.axis).normalize();
    let pivot = Point3::from(frame.translation.vector);
    machine
        .links
        .iter()
        .enumerate()
        .filter(|(i, _)| moved[*i])
        .map(|(i, link)| match joint.kind {
            JointKind::Revolute => {
                let rotation = home[i].rotation.to_rotation_matrix();
                let inertia = rotation.matrix() * link.inertia * rotation.matrix().transpose();
                let arm = (home[i] * link.center_of_mass - pivot).cross(&axis);
                axis.dot(&(inertia * axis)) + link.mass * arm.norm_squared()
            }
            _ => link.mass,
        })
        .sum()
}

/// Pose of every link with all joint coordinates at zero.
pub fn home_poses(machine: &Machine) -> Vec<Isometry3<f64>> {
    let mut poses = vec![Isometry3::identity(); machine.links.len()];
    for joint in &machine.joints {
        poses[joint.child] = poses[joint.parent] * joint.origin;
    }
    poses
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// The bundled table with its X and Y carriages on runners `spacing` apart.
    fn table(spacing: Option<f64>) -> Machine {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/xyz_table.urdf");
        let mut machine = Machine::load(&path).expect("bundled model loads");
        for axis in machine.axes.iter_mut().take(2) {
            if let Some(g) = axis.drive.guide.as_mut() {
                g.runner_spacing_m = spacing;
            }
        }
        machine
    }

    fn plant(machine: &Machine) -> Plant {
        let options = PlantOptions {
            step: 2.5e-4,
            gravity: [0.0, 0.0, -9.81],
            initial_positions: vec![0.1, 0.1, 0.0],
            include_drive_dynamics: true,
            solver_iterations: 1,
        };
        Plant::new(machine, &options).expect("plant builds")
    }

    #[test]
    fn two_runners_add_one_pitch_dof_per_carriage() {
        let dofs = |spacing| {
            let p = plant(&table(spacing));
            let runners: Vec<usize> = (0..3)
                .filter_map(|a| p.runner_normal_forces(a).map(|r| r.len()))
                .collect();
            (p.multibody().expect("machine").ndofs(), runners)
        };
        let (one, one_runners) = dofs(None);
        let (two, two_runners) = dofs(Some(0.12));
        assert_eq!(one_runners, [1, 1]);
        assert_eq!(two_runners, [2, 2]);
        assert_eq!(two, one + 2, "a pitch DOF on X and on Y");
    }

    /// At rest the runners share the weight by the lever rule: the Z slide hangs 60 mm ahead
    /// of X's joint origin (the URDF), so X's front runner carries m·g·0.06/L more than half
    /// and its back runner as much less; Y's centre of gravity is over its joint origin.
    #[test]
    fn at_rest_the_runners_share_the_load_by_the_lever_rule() {
        let spacing = 0.12;
        let machine = table(Some(spacing));
        let mut plant = plant(&machine);
        let slide = machine.link_index("z_slide").expect("z slide");
        let hold = machine.links[slide].mass * 9.81;
        for _ in 0..2000 {
            plant.set_joint_forces(&[0.0, 0.0, hold]);
            plant.step();
        }
        let x = plant.runner_normal_forces(0).expect("X has a guide");
        let lever = machine.links[slide].mass * 9.81 * 0.06 / spacing;
        let half = x.iter().sum::<f64>() / 2.0;
        assert!((x[0] - (half - lever)).abs() < 1e-3 * half, "X back {x:?}");
        assert!((x[1] - (half + lever)).abs() < 1e-3 * half, "X front {x:?}");
        let y = plant.runner_normal_forces(1).expect("Y has a guide");
        assert!((y[0] - y[1]).abs() < 1e-3 * y[0], "Y {y:?}");
        // The static tilt is the contacts' sag, far below a micro-radian.
        for pitch in plant.carriage_pitches().into_iter().take(2) {
            assert!(pitch.expect("pitches").abs() < 1e-6);
        }
    }
}
