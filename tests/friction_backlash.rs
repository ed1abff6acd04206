//! Friction from guide contacts and backlash from a dead-band joint, measured on the Rapier
//! model of the XYZ table (issue 5). Nothing here applies a friction or backlash formula: the
//! test pushes the drives and reads what the engine does.

use cncsim::machine::{Feedback, Guide, Machine};
use cncsim::model::{Plant, PlantOptions};
use std::path::Path;

const G: f64 = 9.81;
const DT: f64 = 2.5e-4;
/// Runner spacing of the two-runner carriages checked here (m): that of the bundled table.
const SPACING: f64 = 0.12;

/// Each check runs on both carriage layouts: one runner without pitch, and a back and a front
/// runner with a pitch degree of freedom (weight transfer).
fn layouts(guide: Guide) -> [Guide; 2] {
    [
        Guide {
            runner_spacing_m: None,
            ..guide
        },
        Guide {
            runner_spacing_m: Some(SPACING),
            ..guide
        },
    ]
}

/// μ_k 0.05, μ_s 0.1, falling over v_s = 2 mm/s.
fn sticky_guide() -> Guide {
    Guide {
        static_friction_coefficient: Some(0.1),
        stribeck_velocity_m_s: Some(2e-3),
        ..Guide::coulomb(0.05)
    }
}

fn table_with(guide: Guide, backlash: [f64; 2]) -> Machine {
    let mut machine =
        Machine::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/xyz_table.urdf"))
            .expect("bundled model loads");
    for (i, axis) in machine.axes.iter_mut().enumerate() {
        if i < 2 {
            axis.drive.guide = Some(guide);
            axis.drive.backlash = backlash[i];
            axis.drive.feedback = Feedback::Motor;
        }
    }
    machine
}

/// Mass carried by the guide of axis `axis` (its carriage and everything on it), from the URDF.
fn carried_mass(machine: &Machine, axis: usize) -> f64 {
    let names: &[&str] = if axis == 0 {
        &["x_carriage", "y_carriage", "z_column", "z_slide"]
    } else {
        &["y_carriage", "z_column", "z_slide"]
    };
    names
        .iter()
        .map(|l| machine.links[machine.link_index(l).unwrap()].mass)
        .sum()
}

/// A plant at x = y = 0.1 m, z = 0, with drive inertia and damping left out (so the drive
/// force is friction and nothing else at constant speed), gravity down.
fn plant(machine: &Machine, drive_dynamics: bool) -> Plant {
    let options = PlantOptions {
        step: DT,
        gravity: [0.0, 0.0, -G],
        initial_positions: vec![0.1, 0.1, 0.0],
        include_drive_dynamics: drive_dynamics,
        solver_iterations: 1,
    };
    Plant::new(machine, &options).expect("plant builds")
}

/// Runs `seconds` of physics with the forces `force(plant)` recomputed every step.
fn run(plant: &mut Plant, seconds: f64, mut force: impl FnMut(&Plant) -> [f64; 3]) {
    for _ in 0..(seconds / DT).round() as usize {
        let f = force(plant);
        plant.set_joint_forces(&f);
        plant.step();
    }
}

/// Holds the Z slide against gravity (no guide on Z) and pushes nothing else.
fn z_hold(machine: &Machine) -> f64 {
    machine.links[machine.link_index("z_slide").unwrap()].mass * G
}

#[test]
fn guides_carry_the_weight_above_them() {
    for guide in layouts(Guide::coulomb(0.1)) {
        guides_carry_the_weight(guide);
    }
}

fn guides_carry_the_weight(guide: Guide) {
    let machine = table_with(guide, [0.0, 0.0]);
    let mut plant = plant(&machine, true);
    let hold = z_hold(&machine);
    run(&mut plant, 0.5, |_| [0.0, 0.0, hold]);
    let normal = plant.guide_normal_forces();
    for (axis, measured) in normal.iter().take(2).enumerate() {
        let expected = carried_mass(&machine, axis) * G;
        let measured = measured.expect("axis has a guide");
        let error = (measured - expected).abs() / expected;
        eprintln!(
            "axis {axis} ({:?} runners): normal {measured:.6} N vs weight {expected:.6} N",
            plant.runner_normal_forces(axis).map(|r| r.len())
        );
        assert!(
            error < 0.01,
            "axis {axis}: normal force {measured:.4} N, weight {expected:.4} N ({:.3} %)",
            error * 100.0
        );
    }
    assert_eq!(normal[2], None, "Z has no guide");
    // The carriages sit on their guides: the tool is where the joint coordinates put it, up
    // to the contact's static sag.
    let mut q = [0.0; 3];
    plant.positions(&mut q);
    let sag = (plant.tool_point() - cncsim::kinematics::tool_point(&machine, &q)).norm();
    eprintln!("sag {sag:e} m");
    assert!(sag < 2e-6, "tool sags {:.3} µm into the guides", sag * 1e6);
}

/// A velocity loop (PI on the drive force) holds the carriage at constant speed; the mean
/// drive force over the last half second is the friction the engine produces. Returns it and
/// the expected N·μ(|v|).
fn force_at_constant_speed(guide: Guide, axis: usize, speed: f64) -> (f64, f64) {
    let machine = table_with(guide, [0.0, 0.0]);
    let mut plant = plant(&machine, false);
    let hold = z_hold(&machine);
    let mut v = [0.0; 3];
    let mut integral = 0.0;
    let (kp, ki) = (2.0e4, 4.0e5);
    let mut sum = 0.0;
    let mut samples = 0;
    let steps = (1.5 / DT) as usize;
    for step in 0..steps {
        plant.velocities(&mut v);
        let error = speed - v[axis];
        integral += error * DT;
        let f = kp * error + ki * integral;
        let mut forces = [0.0, 0.0, hold];
        forces[axis] = f;
        plant.set_joint_forces(&forces);
        plant.step();
        if step >= steps / 3 * 2 {
            sum += f;
            samples += 1;
        }
    }
    plant.velocities(&mut v);
    assert!(
        (v[axis] - speed).abs() < 1e-3 * speed.abs(),
        "axis {axis} did not settle at {speed} m/s: {}",
        v[axis]
    );
    let mu = guide.coefficient().sliding(speed);
    (sum / samples as f64, mu * carried_mass(&machine, axis) * G)
}

/// At each (axis, speed) the drive force equals N·μ(|v|) within 2 % and opposes the motion.
fn assert_sliding_friction(guide: Guide, cases: &[(usize, f64)]) {
    for (guide, &(axis, speed)) in layouts(guide)
        .into_iter()
        .flat_map(|g| cases.iter().map(move |c| (g, c)))
    {
        let (force, expected) = force_at_constant_speed(guide, axis, speed);
        let error = (force.abs() - expected).abs() / expected;
        eprintln!(
            "axis {axis} at {speed} m/s, spacing {:?}: force {force:.6} N vs μ(v)·N {expected:.6} N",
            guide.runner_spacing_m
        );
        assert!(
            error < 0.02,
            "axis {axis} at {speed} m/s: drive force {force:.4} N, μ(v)·N = {expected:.4} N ({:.3} %)",
            error * 100.0
        );
        assert_eq!(
            force.signum(),
            speed.signum(),
            "friction opposes the motion"
        );
    }
}

#[test]
fn sliding_friction_is_mu_times_the_load() {
    assert_sliding_friction(
        Guide::coulomb(0.1),
        &[(0, 0.005), (0, -0.02), (1, 0.005), (1, -0.01)],
    );
}

#[test]
fn no_creep_below_breakaway() {
    let mu = 0.1;
    for (guide, axis) in layouts(Guide::coulomb(mu))
        .into_iter()
        .flat_map(|g| (0..2).map(move |a| (g, a)))
    {
        let machine = table_with(guide, [0.0, 0.0]);
        let mut plant = plant(&machine, true);
        let hold = z_hold(&machine);
        let push = 0.9 * mu * carried_mass(&machine, axis) * G;
        let creep = creep_in_one_second(&mut plant, hold, axis, push);
        eprintln!(
            "axis {axis}, spacing {:?}: creep {creep:e} m in 1 s",
            guide.runner_spacing_m
        );
        assert!(
            creep < 1e-6,
            "axis {axis}: pushed at 90 % of breakaway, crept {:.3} µm in 1 s",
            creep * 1e6
        );
        // And just above breakaway it does move.
        let mut start = [0.0; 3];
        plant.positions(&mut start);
        let mut forces = [0.0, 0.0, hold];
        forces[axis] = 1.1 * mu * carried_mass(&machine, axis) * G;
        run(&mut plant, 0.2, |_| forces);
        let mut end = [0.0; 3];
        plant.positions(&mut end);
        assert!(
            end[axis] - start[axis] > 1e-5,
            "axis {axis} should slide at 110 % of breakaway"
        );
    }
}

/// Lets the plant settle for 0.2 s, then pushes axis `axis` with `push` (N) for 1 s and
/// returns how far it moved (m).
fn creep_in_one_second(plant: &mut Plant, hold: f64, axis: usize, push: f64) -> f64 {
    run(plant, 0.2, |_| [0.0, 0.0, hold]);
    let mut start = [0.0; 3];
    plant.positions(&mut start);
    let mut forces = [0.0, 0.0, hold];
    forces[axis] = push;
    run(plant, 1.0, |_| forces);
    let mut end = [0.0; 3];
    plant.positions(&mut end);
    (end[axis] - start[axis]).abs()
}

#[test]
fn sliding_friction_follows_the_stribeck_curve() {
    // From near breakaway (0.5 mm/s: μ 0.097) through v_s to nearly kinetic (8 mm/s: μ 0.05).
    assert_sliding_friction(
        sticky_guide(),
        &[(0, 0.5e-3), (0, -1e-3), (1, 2e-3), (0, 4e-3), (1, -8e-3)],
    );
}

#[test]
fn stiction_holds_up_to_the_static_coefficient() {
    for (guide, axis) in layouts(sticky_guide())
        .into_iter()
        .flat_map(|g| (0..2).map(move |a| (g, a)))
    {
        let machine = table_with(guide, [0.0, 0.0]);
        let mu_s = guide.static_friction_coefficient.unwrap();
        // Without drive inertia, so that the carriage's acceleration is the net force over its
        // own mass.
        let mut plant = plant(&machine, false);
        let hold = z_hold(&machine);
        // Twice the kinetic friction, 90 % of breakaway: held.
        let breakaway = mu_s * carried_mass(&machine, axis) * G;
        let creep = creep_in_one_second(&mut plant, hold, axis, 0.9 * breakaway);
        eprintln!("axis {axis}: creep {creep:e} m in 1 s at 90 % of μ_s·N");
        assert!(
            creep < 1e-6,
            "axis {axis}: pushed at 90 % of static breakaway, crept {:.3} µm in 1 s",
            creep * 1e6
        );
        // Above breakaway it slides, and once moving the friction falls towards μ_k·N: the
        // push accelerates it at (1.1·μ_s − μ(v))·N / m, between 0.1·μ_s·g (friction stuck at
        // μ_s) and (1.1·μ_s − μ_k)·g, the rate it approaches once the speed passes v_s. More
        // than half the upper bound (three times the lower) after 0.2 s shows that it fell.
        let mut forces = [0.0, 0.0, hold];
        forces[axis] = 1.1 * breakaway;
        run(&mut plant, 0.2, |_| forces);
        let mut v = [0.0; 3];
        plant.velocities(&mut v);
        let upper = (1.1 * mu_s - guide.friction_coefficient) * G * 0.2;
        eprintln!(
            "axis {axis}: {:.4} m/s after 0.2 s above breakaway (≤ {upper:.4})",
            v[axis]
        );
        assert!(
            v[axis] > 0.5 * upper && v[axis] <= upper,
            "axis {axis}: {} m/s",
            v[axis]
        );
    }
}

/// Drives the drive side of X with a stiff position loop along a triangle wave (out 1 mm and
/// back) and returns (drive, carriage) positions at every step.
fn triangle(guide: Guide, backlash: f64) -> Vec<(f64, f64)> {
    let machine = table_with(guide, [backlash, 0.0]);
    let mut plant = plant(&machine, true);
    let hold = z_hold(&machine);
    let (amplitude, speed): (f64, f64) = (1.0e-3, 2.0e-3);
    let half = amplitude / speed;
    let mut out = Vec::new();
    let mut t = 0.0;
    let (mut q, mut qd, mut v) = ([0.0; 3], [0.0; 3], [0.0; 3]);
    run(&mut plant, 0.1, |_| [0.0, 0.0, hold]);
    while t < 2.0 * half + 0.2 {
        let target = 0.1
            + if t < half {
                speed * t
            } else {
                (amplitude - speed * (t - half)).max(0.0)
            };
        plant.drive_positions(&mut qd);
        plant.drive_velocities(&mut v);
        let f = 2.0e6 * (target - qd[0]) - 4.0e4 * v[0];
        plant.set_joint_forces(&[f, 0.0, hold]);
        plant.step();
        plant.positions(&mut q);
        plant.drive_positions(&mut qd);
        out.push((qd[0], q[0]));
        t += DT;
    }
    out
}

#[test]
fn backlash_is_lost_motion_at_reversal() {
    for guide in layouts(Guide::coulomb(0.1)) {
        lost_motion_is_backlash(guide);
    }
}

fn lost_motion_is_backlash(guide: Guide) {
    let b = 0.32e-3;
    let path = triangle(guide, b);
    // While pushing forward the drive leads by b/2; after the reversal it trails by b/2.
    let turn = path
        .iter()
        .enumerate()
        .max_by(|x, y| x.1 .0.total_cmp(&y.1 .0))
        .unwrap()
        .0;
    let (drive_top, carriage_top) = path[turn];
    let lead = drive_top - carriage_top;
    assert!(
        (lead - b / 2.0).abs() < 0.02 * b,
        "drive leads by {:.2} µm, expected b/2",
        lead * 1e6
    );
    // The carriage stays put while the drive crosses the slack: find where it starts back.
    let moved = path[turn..]
        .iter()
        .position(|&(_, c)| carriage_top - c > 0.5e-6)
        .expect("carriage comes back")
        + turn;
    let lost = drive_top - path[moved].0;
    eprintln!(
        "spacing {:?}: lead {lead:e}, lost {lost:e}, end {:e}",
        guide.runner_spacing_m,
        path.last().unwrap().1 - path.last().unwrap().0
    );
    assert!(
        (lost - b).abs() < 0.02 * b,
        "lost motion {:.2} µm, backlash {:.2} µm",
        lost * 1e6,
        b * 1e6
    );
    for &(_, c) in &path[turn..moved] {
        assert!((c - carriage_top).abs() <= 0.5e-6, "carriage stood still");
    }
    let (drive_end, carriage_end) = *path.last().unwrap();
    assert!(
        (carriage_end - drive_end - b / 2.0).abs() < 0.02 * b,
        "after the return the drive trails by b/2: {:.2} µm",
        (carriage_end - drive_end) * 1e6
    );
}

#[test]
fn without_backlash_the_axis_is_stiff() {
    for guide in layouts(Guide::coulomb(0.1)) {
        let path = triangle(guide, 0.0);
        let worst = path.iter().map(|(d, c)| (d - c).abs()).fold(0.0, f64::max);
        assert_eq!(worst, 0.0, "no dead band: carriage is the drive");
    }
}

/// Weight transfer on two runners: a carriage accelerating at a shifts load from its front to
/// its back runner by ΔN = Σ m_i·a·h_i / L (everything it carries, each centre of gravity h_i
/// above the guide plane, runners L apart; the drive pushes along the guide plane, friction acts
/// in it), and the total stays the weight. Measured against that hand calculation from the
/// URDF's masses and inertial origins, on X and on Y, sliding with Coulomb friction.
#[test]
fn acceleration_shifts_the_load_between_the_runners() {
    let guide = Guide {
        runner_spacing_m: Some(SPACING),
        ..Guide::coulomb(0.05)
    };
    let machine = table_with(guide, [0.0, 0.0]);
    let home = cncsim::model::home_poses(&machine);
    let carried: [&[&str]; 2] = [
        &["x_carriage", "y_carriage", "z_column", "z_slide"],
        &["y_carriage", "z_column", "z_slide"],
    ];
    for (axis, joint_name) in ["x", "y"].into_iter().enumerate() {
        let joint = &machine.joints[machine
            .joints
            .iter()
            .position(|j| j.name == joint_name)
            .unwrap()];
        // The guide plane is the joint origin's height (the runners touch the rail there).
        let plane = (home[joint.parent] * joint.origin).translation.vector.z;
        let moment_per_acceleration: f64 = carried[axis]
            .iter()
            .map(|name| {
                let i = machine.link_index(name).unwrap();
                let link = &machine.links[i];
                let height = (home[i] * link.center_of_mass).z - plane;
                link.mass * height
            })
            .sum();
        let mass = carried_mass(&machine, axis);

        let mut plant = plant(&machine, false);
        let hold = z_hold(&machine);
        run(&mut plant, 0.3, |_| [0.0, 0.0, hold]);
        let at_rest = plant.runner_normal_forces(axis).unwrap();
        // Push at three times the friction: a = 2·μ·g once sliding.
        let mut forces = [0.0, 0.0, hold];
        forces[axis] = 3.0 * 0.05 * mass * G;
        run(&mut plant, 0.05, |_| forces);
        let (mut v0, mut v1) = ([0.0; 3], [0.0; 3]);
        plant.velocities(&mut v0);
        let window = 0.05;
        let (mut back, mut front, mut steps) = (0.0, 0.0, 0);
        run(&mut plant, window, |p| {
            let n = p.runner_normal_forces(axis).unwrap();
            back += n[0];
            front += n[1];
            steps += 1;
            forces
        });
        plant.velocities(&mut v1);
        let (back, front) = (back / steps as f64, front / steps as f64);
        let a = (v1[axis] - v0[axis]) / window;
        let expected = mass_shift(moment_per_acceleration, a);
        let shift = [back - at_rest[0], at_rest[1] - front];
        eprintln!(
            "axis {axis}: a = {a:.4} m/s², Σm·h = {moment_per_acceleration:.4} kg·m, at rest \
             back/front {:.4}/{:.4} N, accelerating {back:.4}/{front:.4} N: ΔN {:.4}/{:.4} N \
             against {expected:.4} N",
            at_rest[0], at_rest[1], shift[0], shift[1]
        );
        assert!(
            (a - 2.0 * 0.05 * G).abs() < 0.01 * a,
            "axis {axis}: a = {a}"
        );
        for s in shift {
            assert!(
                (s - expected).abs() < 0.01 * expected,
                "axis {axis}: load shift {s:.4} N, m·a·h/L = {expected:.4} N"
            );
        }
        let total = back + front;
        assert!(
            (total - mass * G).abs() < 1e-3 * mass * G,
            "axis {axis}: the runners carry {total:.4} N in all, the weight is {:.4} N",
            mass * G
        );
        let pitch = plant.carriage_pitches()[axis].expect("two runners pitch");
        eprintln!("axis {axis}: pitch {pitch:e} rad");
    }
}

/// ΔN = Σ m_i·h_i · a / L.
fn mass_shift(moment_per_acceleration: f64, a: f64) -> f64 {
    moment_per_acceleration * a / SPACING
}

/// Why the bundled twin stays on one runner (docs/modelling.md, "Weight transfer: measured, not in the
/// twin"): the backlash's end stops are rigid, so taking up the gap at 5 mm/s changes the
/// carriage's speed within one physics step, an acceleration of some 20 m/s². Under the Y
/// carriage's centre of gravity that lifts a runner of a 120 mm pair off its rail (above
/// g·L/(2·h) ≈ 5 m/s²) and rocks the carriage, which a real transmission's compliance would
/// not; on runners 4 m apart the load only swings. One runner carries the weight throughout.
#[test]
fn a_rigid_backlash_take_up_lifts_a_runner_off() {
    let static_load = |m: &Machine| carried_mass(m, 1) * G;
    for (spacing, lifts_off) in [(None, false), (Some(SPACING), true), (Some(4.0), false)] {
        let mut machine =
            Machine::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/xyz_table.urdf"))
                .expect("bundled model loads");
        let y = &mut machine.axes[1].drive;
        assert!(y.backlash > 0.0, "the bundled Y axis has backlash");
        y.guide
            .as_mut()
            .expect("the bundled Y axis has a guide")
            .runner_spacing_m = spacing;
        let runners = spacing.map_or(1.0, |_| 2.0);
        let share = static_load(&machine) / runners;
        let mut plant = plant(&machine, true);
        let hold = z_hold(&machine);
        run(&mut plant, 0.1, |_| [0.0, 0.0, hold]);
        // The drive side out 1 mm and back at 5 mm/s: two take-ups of the gap.
        let (speed, amplitude) = (5e-3, 1e-3);
        let half = amplitude / speed;
        let (mut qd, mut v) = ([0.0; 3], [0.0; 3]);
        let (mut least, mut most) = (f64::INFINITY, 0.0_f64);
        let steps = ((2.0 * half + 0.2) / DT) as usize;
        for step in 0..steps {
            let t = step as f64 * DT;
            let (target, feed) = if t < half {
                (speed * t, speed)
            } else if t < 2.0 * half {
                (amplitude - speed * (t - half), -speed)
            } else {
                (0.0, 0.0)
            };
            plant.drive_positions(&mut qd);
            plant.drive_velocities(&mut v);
            let f = 2.0e5 * (0.1 + target - qd[1]) - 2.0e4 * (v[1] - feed);
            plant.set_joint_forces(&[0.0, f, hold]);
            plant.step();
            for n in plant.runner_normal_forces(1).expect("Y has a guide") {
                least = least.min(n);
                most = most.max(n);
            }
        }
        eprintln!(
            "spacing {spacing:?}: runner load {least:.3} … {most:.3} N (at rest {share:.3} N), \
             pitch now {:?}",
            plant.carriage_pitches()[1]
        );
        if lifts_off {
            assert!(
                least < 1e-6 * share,
                "a runner lifts off: least load {least} N"
            );
        } else if spacing.is_some() {
            assert!(least > 0.5 * share, "runners stay loaded: least {least} N");
        } else {
            assert!(
                (least - share).abs() < 1e-6 * share && (most - share).abs() < 1e-6 * share,
                "one runner carries the weight: {least} … {most} N"
            );
        }
    }
}
