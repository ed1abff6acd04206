//! Checks of the reference model against closed forms, its own convergence order, and the
//! linear servo theory. Figures in the assertions are derived in the comments next to them.

use super::*;
use crate::control::{Controller, ControllerInput, Pid, PidBank, PidForm, PidGains, PidSettings};
use crate::machine::{AmplifierMode, Machine, StribeckCurve};
use crate::plan::Setpoints;
use crate::sim::{Encoder, FollowingErrorTrip, Lane, LoopSettings, Stop, Trace, TraceRecorder};
use nalgebra::{SMatrix, SVector};
use std::path::Path;

/// The XYZ table with voltage-mode amplifiers, the plant these tests' closed forms describe.
fn machine() -> Machine {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/xyz_table.urdf");
    let mut m = Machine::load(&path).expect("the XYZ table loads");
    for a in &mut m.axes {
        a.drive.amplifier_mode = AmplifierMode::Voltage;
    }
    m
}

fn x_drive() -> Drive {
    let m = machine();
    m.axes[m.axis_index("x").unwrap()].drive.clone()
}

/// The X axis alone: 20 kg moved, no gravity along it, no guide damping.
fn x_axis(options: AxisModelOptions) -> AxisModel {
    AxisModel::from_drive(&x_drive(), 20.0, 0.0, 0.0, options).unwrap()
}

/// The same axis with a current-mode amplifier: its modes are not linear (the armature voltage
/// clamps on the back-EMF it adds), so RK4 integrates all of them.
fn x_axis_current_mode(options: AxisModelOptions) -> AxisModel {
    let mut drive = x_drive();
    drive.amplifier_mode = AmplifierMode::Current;
    AxisModel::from_drive(&drive, 20.0, 0.0, 0.0, options).unwrap()
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// Position and velocity of a mass m with damping c under a constant force F from rest.
fn damped_mass_under_force(f: f64, m: f64, c: f64, t: f64) -> (f64, f64) {
    let tau = m / c;
    let decay = (-t / tau).exp();
    (f / c * (t - tau * (1.0 - decay)), f / c * (1.0 - decay))
}

#[test]
fn model_takes_its_masses_from_the_machine() {
    let machine = machine();
    let models = AxisModel::for_machine(&machine, [0.0, 0.0, -9.81], false).unwrap();
    // X moves 8 + 3.5 + m_zc + 0.5 kg, Y 3.5 + m_zc + 0.5 kg, Z 0.5 kg (URDF; the z_column's
    // mass m_zc is calibrated); J·k² on top.
    let column = machine.links[machine.link_index("z_column").unwrap()].mass;
    let expected_moved = [12.0 + column, 4.0 + column, 0.5];
    for (model, moved) in models.iter().zip(expected_moved) {
        let reflected = model.drive_mass;
        assert!(relative(model.effective_mass(), moved + reflected) < 1e-12);
        assert!(relative(model.carriage_mass, moved) < 1e-12);
    }
    assert_eq!(models[0].gravity_force, 0.0);
    assert_eq!(models[1].gravity_force, 0.0);
    assert!(relative(models[2].gravity_force, -0.5 * 9.81) < 1e-12);
    // X: J_m·(N/r)² = 3.89e-5 · 4000² = 622.4 kg.
    assert!(relative(models[0].drive_mass, 622.4) < 1e-12);
}

#[test]
fn free_axis_under_constant_torque_follows_the_closed_form() {
    let mut axis = x_axis(AxisModelOptions {
        ideal_actuator: true,
        ..Default::default()
    });
    let torque = 0.5;
    let (m, c, f) = (
        axis.effective_mass(),
        axis.effective_damping(),
        torque * axis.ratio(),
    );
    let (period, steps) = (1e-3, 10);
    let duration = 2.0;
    // Errors relative to the end values: early on x ~ t² is computed by the closed form with
    // cancellation, so a pointwise relative error would measure the reference, not the model.
    let (x_end, v_end) = damped_mass_under_force(f, m, c, duration);
    let mut worst: f64 = 0.0;
    for k in 1..=(duration / period).round() as usize {
        let hold = axis.advance(torque, period, steps);
        assert_eq!(hold.mean_torque, torque);
        let (x, v) = damped_mass_under_force(f, m, c, k as f64 * period);
        worst = worst
            .max((axis.position() - x).abs() / x_end)
            .max((axis.velocity() - v).abs() / v_end);
    }
    assert!(worst < 1e-10, "relative error {worst:e}");
}

/// z = [x, v, i, ∫i, 1]: the armature and the mechanics under constant voltage are linear, so
/// z(t) = e^(A·t)·z(0) exactly.
fn dc_motor_exact(axis: &AxisModel, drive: &Drive, voltage: f64, t: f64) -> SVector<f64, 5> {
    let (m, c, k) = (
        axis.effective_mass(),
        axis.effective_damping(),
        axis.ratio(),
    );
    let mo = &drive.motor;
    let (km, kb, r, l) = (
        mo.torque_constant_nm_per_a,
        drive.effective_back_emf(),
        mo.resistance_ohm,
        mo.inductance_h,
    );
    #[rustfmt::skip]
    let a = SMatrix::<f64, 5, 5>::from_row_slice(&[
        0.0, 1.0,           0.0,        0.0, 0.0,
        0.0, -c / m,        k * km / m, 0.0, 0.0,
        0.0, -kb * k / l,   -r / l,     0.0, voltage / l,
        0.0, 0.0,           1.0,        0.0, 0.0,
        0.0, 0.0,           0.0,        0.0, 0.0,
    ]);
    (a * t).exp() * SVector::<f64, 5>::new(0.0, 0.0, 0.0, 0.0, 1.0)
}

/// Largest relative deviation of the X axis's step response to `command` (V) from the exact
/// solution.
fn step_response_error(drive: &Drive, command: f64) -> f64 {
    let mut axis = AxisModel::from_drive(drive, 20.0, 0.0, 0.0, Default::default()).unwrap();
    let (period, steps) = (1e-3, 20);
    let voltage = drive.amplifier_gain * command;
    let current_mode = drive.amplifier_mode == AmplifierMode::Current;
    let mut worst: f64 = 0.0;
    let mut previous_charge = 0.0;
    for k in 1..=200 {
        let hold = axis.advance(command, period, steps);
        if !current_mode {
            assert_eq!(hold.voltage, voltage);
        }
        let exact = dc_motor_exact(&axis, drive, voltage, k as f64 * period);
        let mean_torque =
            drive.motor.torque_constant_nm_per_a * (exact[3] - previous_charge) / period;
        previous_charge = exact[3];
        // Scales: the values at the end of the run (the response is monotone or nearly).
        let end = dc_motor_exact(&axis, drive, voltage, 0.2);
        worst = worst
            .max((axis.position() - exact[0]).abs() / end[0])
            .max((axis.velocity() - exact[1]).abs() / end[1])
            .max((axis.current() - exact[2]).abs() / (voltage / drive.motor.resistance_ohm))
            .max((hold.mean_torque - mean_torque).abs() / (0.055 * voltage / 1.1));
    }
    worst
}

#[test]
fn dc_motor_step_response_matches_the_linear_ode() {
    // RK4 at h = 50 µs against the fastest pole (−395 /s): h·λ = 0.02, global error ~1e-10.
    let worst = step_response_error(&x_drive(), 1.0);
    assert!(worst < 1e-8, "relative error {worst:e}");
}

/// Current mode: the amplifier cancels the back-EMF, so a step accelerates the axis past the
/// voltage-mode speed limit K_a·u/K_b (the exact solution has K_b = 0), for as long as the
/// armature voltage K_a·u + K_b·ω stays within the supply (0.01 V: 0.6 V after 0.2 s).
#[test]
fn current_mode_step_response_matches_the_linear_ode() {
    let mut drive = x_drive();
    drive.amplifier_mode = AmplifierMode::Current;
    let worst = step_response_error(&drive, 0.01);
    assert!(worst < 1e-8, "relative error {worst:e}");
    let mut axis = AxisModel::from_drive(&drive, 20.0, 0.0, 0.0, Default::default()).unwrap();
    for _ in 0..200 {
        axis.advance(0.01, 1e-3, 20);
    }
    let omega = axis.ratio() * axis.drive_velocity();
    assert!(
        omega > 10.0 * 0.04 / drive.motor.back_emf_v_s_per_rad,
        "ω = {omega}"
    );
    assert!(0.04 + drive.motor.back_emf_v_s_per_rad * omega < 0.1 * drive.supply_voltage_v);
}

#[test]
fn coulomb_friction_holds_an_axis_below_breakaway() {
    let friction = 50.0;
    for ideal_actuator in [true, false] {
        let mut axis = x_axis(AxisModelOptions {
            friction: StribeckCurve::coulomb(friction),
            ideal_actuator,
            ..Default::default()
        });
        // 80 % of breakaway at the joint: torque 40 N / k, or the voltage whose stall current
        // gives 40 N: V = 40·R/(k·K_m) = 0.2 V, u = V/K_a.
        let command = if ideal_actuator {
            40.0 / axis.ratio()
        } else {
            40.0 * 1.1 / (axis.ratio() * 0.055) / 4.0
        };
        for _ in 0..1000 {
            axis.advance(command, 1e-3, 10);
        }
        assert_eq!(axis.position(), 0.0, "ideal actuator: {ideal_actuator}");
        assert_eq!(axis.velocity(), 0.0);
        assert!(relative(axis.ratio() * 0.055 * axis.current(), 40.0) < 1e-9);
    }
}

#[test]
fn coulomb_friction_above_breakaway_subtracts_from_the_drive_force() {
    let friction = 50.0;
    let mut axis = x_axis(AxisModelOptions {
        friction: StribeckCurve::coulomb(friction),
        ideal_actuator: true,
        ..Default::default()
    });
    let f = 80.0;
    let (m, c) = (axis.effective_mass(), axis.effective_damping());
    for _ in 0..500 {
        axis.advance(f / axis.ratio(), 1e-3, 10);
    }
    let (x, v) = damped_mass_under_force(f - friction, m, c, 0.5);
    assert!(relative(axis.position(), x) < 1e-10);
    assert!(relative(axis.velocity(), v) < 1e-10);
}

#[test]
fn breakaway_happens_when_the_rising_current_reaches_the_friction_force() {
    // Stalled, the current rises as i(t) = I∞·(1 − e^(−t/τ)); the axis must start moving at
    // the instant k·K_m·i = F_c, located inside the step, not at the next step boundary.
    let friction = 100.0;
    let mut axis = x_axis(AxisModelOptions {
        friction: StribeckCurve::coulomb(friction),
        ..Default::default()
    });
    let (command, k, km, r, l) = (0.5, axis.ratio(), 0.055, 1.1, 2.3e-3);
    let force_at_stall = k * km * 4.0 * command / r;
    let breakaway = -(l / r) * (1.0 - friction / force_at_stall).ln();
    let chunk = 1e-6;
    let mut t = 0.0;
    while axis.velocity() == 0.0 {
        axis.advance(command, chunk, 1);
        t += chunk;
    }
    assert!(
        (t - chunk..=t).contains(&breakaway),
        "moved in ({:.7}, {t:.7}], breakaway at {breakaway:.7}",
        t - chunk
    );
}

#[test]
fn at_constant_speed_the_drive_force_is_damping_plus_friction() {
    let friction = 50.0;
    let drive = x_drive();
    let mut axis = x_axis(AxisModelOptions {
        friction: StribeckCurve::coulomb(friction),
        ..Default::default()
    });
    let command = 2.0;
    let (k, km, kb, r) = (axis.ratio(), 0.055, 0.0554, 1.1);
    let voltage = drive.amplifier_gain * command;
    let mut hold = axis.advance(command, 1e-3, 10);
    for _ in 0..1000 {
        hold = axis.advance(command, 1e-3, 10);
    }
    let c = axis.effective_damping();
    let v = axis.velocity();
    // Steady state: k·K_m·(V − K_b·k·v)/R = c·v + F_c.
    let speed = (k * km * voltage / r - friction) / (c + k * k * km * kb / r);
    assert!(relative(v, speed) < 1e-9, "{v} vs {speed}");
    assert!(relative(k * hold.mean_torque, c * v + friction) < 1e-9);
}

/// Kinetic 50 N, breakaway 100 N, falling over 1 mm/s.
fn sticky() -> StribeckCurve {
    StribeckCurve {
        kinetic: 50.0,
        breakaway: 100.0,
        stribeck_velocity: 1e-3,
    }
}

#[test]
fn stiction_holds_between_kinetic_and_breakaway_force() {
    let mut axis = x_axis(AxisModelOptions {
        friction: sticky(),
        ideal_actuator: true,
        ..Default::default()
    });
    // 95 N: almost twice the kinetic friction, still below breakaway.
    for _ in 0..1000 {
        axis.advance(95.0 / axis.ratio(), 1e-3, 10);
    }
    assert_eq!(axis.position(), 0.0);
    assert_eq!(axis.velocity(), 0.0);
    // 105 N breaks it away, and the falling friction lets it run away from the 5 N that a
    // constant breakaway friction would leave: past v_s the net force nears 55 N.
    for _ in 0..200 {
        axis.advance(105.0 / axis.ratio(), 1e-3, 10);
    }
    let (m, c) = (axis.effective_mass(), axis.effective_damping());
    let (_, v_stuck_friction) = damped_mass_under_force(5.0, m, c, 0.2);
    let (_, v_kinetic) = damped_mass_under_force(55.0, m, c, 0.2);
    let v = axis.velocity();
    assert!(v > 5.0 * v_stuck_friction && v < v_kinetic, "{v} m/s");
}

#[test]
fn at_constant_speed_the_drive_force_is_damping_plus_stribeck_friction() {
    let drive = x_drive();
    let friction = sticky();
    let mut axis = x_axis(AxisModelOptions {
        friction,
        ..Default::default()
    });
    // A slow steady speed, around v_s, where the curve is steep.
    let command = 0.3;
    let mut hold = axis.advance(command, 1e-3, 10);
    for _ in 0..3000 {
        hold = axis.advance(command, 1e-3, 10);
    }
    let (k, km, kb, r) = (axis.ratio(), 0.055, 0.0554, 1.1);
    let voltage = drive.amplifier_gain * command;
    let c = axis.effective_damping();
    let v = axis.velocity();
    assert!(v > 0.2e-3 && v < 5e-3, "{v} m/s");
    // Steady state: k·K_m·(V − K_b·k·v)/R = c·v + F(v), and the torque carries it.
    let drive_force = k * km * (voltage - kb * k * v) / r;
    let resisting = c * v + friction.sliding(v);
    assert!(
        relative(drive_force, resisting) < 1e-9,
        "{drive_force} vs {resisting}"
    );
    assert!(relative(k * hold.mean_torque, resisting) < 1e-9);
}

fn pid(kp: f64, ki: f64, kd: f64, limit: f64) -> Pid {
    Pid::new(
        PidSettings::plain(PidGains { kp, ki, kd }, limit),
        PidForm::Positional,
        1e-3,
    )
}

/// The scenario's X loop: positional PID, 1 ms servo period, ±6 V.
fn x_pid() -> PidBank {
    PidBank::new(vec![pid(19800.0, 6.1e5, 146.0, 6.0)])
}

/// The loop's settings for `axes` axes: 1 ms, 0.1 s settle, no trip within reach.
fn loop_settings(axes: usize, encoder: Vec<Option<f64>>) -> LoopSettings {
    LoopSettings {
        servo_period: 1e-3,
        approach: Setpoints::default(),
        settle_time: 0.1,
        encoder: Encoder {
            resolution: encoder,
        },
        trip: FollowingErrorTrip {
            limit: vec![1.0; axes],
            axis_names: (0..axes).map(|i| format!("q{i}")).collect(),
        },
        spindle: Default::default(),
    }
}

/// The servo loop on the analytic models alone: the reference run.
struct ReferenceRun {
    trace: Trace,
    stop: Option<Stop>,
}

fn run_reference(
    models: Vec<AxisModel>,
    controller: &mut dyn Controller,
    s: &Setpoints,
    steps_per_period: usize,
    settings: &LoopSettings,
) -> ReferenceRun {
    let n = models.len();
    let mut models = models;
    for (m, &p) in models.iter_mut().zip(s.position(0)) {
        m.rest_at(p);
    }
    let plant = AnalyticPlant::from_models(models, &machine(), 1e-3, steps_per_period);
    let mut lanes = [Lane {
        kind: crate::sim::LaneKind::Analytic,
        plant: Box::new(plant),
        controller: Box::new(Borrowed(controller)),
    }];
    let mut recorder = TraceRecorder::new(1e-3, n, 1);
    let outcome = crate::sim::run(
        settings,
        &mut lanes,
        &mut s.stream(),
        &mut recorder,
        &mut |_, _| true,
    );
    ReferenceRun {
        trace: recorder.lane(0).clone(),
        stop: outcome.stop().cloned(),
    }
}

/// A controller lent to the loop (the tests look at it afterwards).
struct Borrowed<'a>(&'a mut dyn Controller);

impl Controller for Borrowed<'_> {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        self.0.update(input, command)
    }
    fn reset(&mut self) {
        self.0.reset()
    }
}

/// One axis: position(t) sampled every `period` for `duration` seconds.
fn setpoints(period: f64, duration: f64, position: impl Fn(f64) -> (f64, f64, f64)) -> Setpoints {
    let mut s = Setpoints::new(period, 1);
    let ticks = (duration / period).round() as usize;
    for k in 0..=ticks {
        let (p, v, a) = position(k as f64 * period);
        s.push(&[p], &[v], &[a], 0);
    }
    s
}

fn run(axis: AxisModel, s: &Setpoints, steps_per_period: usize) -> ReferenceRun {
    let run = run_reference(
        vec![axis],
        &mut x_pid(),
        s,
        steps_per_period,
        &loop_settings(1, vec![None]),
    );
    assert!(run.stop.is_none());
    run
}

/// Forward at `speed` for `leg` seconds, back for as long, then hold; from 10 mm.
fn out_and_back(speed: f64, leg: f64) -> Setpoints {
    setpoints(1e-3, 2.0 * leg + 0.5, |t| {
        let start = 0.01;
        if t <= leg {
            (start + speed * t, speed, 0.0)
        } else if t <= 2.0 * leg {
            (start + speed * (2.0 * leg - t), -speed, 0.0)
        } else {
            (start, 0.0, 0.0)
        }
    })
}

#[test]
fn backlash_is_lost_motion_at_a_reversal() {
    let backlash = 0.32e-3;
    let speed = 2e-3;
    let axis = x_axis(AxisModelOptions {
        friction: StribeckCurve::coulomb(20.0),
        backlash,
        ..Default::default()
    });
    let r = run(axis, &out_and_back(speed, 1.0), 10);
    let trace = &r.trace;
    // The drive turns at the top; the carriage, pushed no more, coasts a few nm and stops,
    // held by friction with the gap open, until the drive has crossed the gap and picks it up from the other side.
    let top = (0..trace.len())
        .max_by(|&a, &b| r.trace.drive[a].total_cmp(&r.trace.drive[b]))
        .unwrap();
    let standstill: Vec<usize> = (top..trace.len())
        .skip_while(|&k| trace.actual_velocity[k] != 0.0)
        .take_while(|&k| trace.actual_velocity[k] == 0.0)
        .collect();
    let (first, last) = (standstill[0], *standstill.last().unwrap());
    let carriage_moved = trace.actual[last] - trace.actual[first];
    assert_eq!(carriage_moved, 0.0);
    // Ticks sample the drive every 1 ms; at ≤ 2 mm/s that is ≤ 2 µm of 320 µm.
    let lost = r.trace.drive[first] - r.trace.drive[last + 1];
    assert!(
        relative(lost, backlash) < 0.02,
        "lost motion {lost:e} vs backlash {backlash:e}"
    );
    // With the motor encoder in the loop (type 2: drive error → 0) the carriage trails the
    // setpoint by b/2 on each leg, so the contour error jumps by b at the reversal.
    let error_at = |t: f64| {
        let k = (t / 1e-3).round() as usize;
        trace.commanded[k] - trace.actual[k]
    };
    assert!(
        relative(error_at(0.9), backlash / 2.0) < 1e-3,
        "{}",
        error_at(0.9)
    );
    assert!(
        relative(error_at(1.9), -backlash / 2.0) < 1e-3,
        "{}",
        error_at(1.9)
    );
}

#[test]
fn without_backlash_there_is_no_dead_band() {
    let axis = x_axis(AxisModelOptions {
        friction: StribeckCurve::coulomb(20.0),
        ..Default::default()
    });
    let r = run(axis, &out_and_back(2e-3, 1.0), 10);
    let trace = &r.trace;
    assert_eq!(r.trace.drive, trace.actual);
    let error_at = |t: f64| {
        let k = (t / 1e-3).round() as usize;
        trace.commanded[k] - trace.actual[k]
    };
    assert!(error_at(0.9).abs() < 1e-9 && error_at(1.9).abs() < 1e-9);
}

/// Max |a − b| of the carriage positions of two traces of the same run.
fn max_difference(a: &crate::sim::Trace, b: &crate::sim::Trace) -> f64 {
    a.actual
        .iter()
        .zip(&b.actual)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Ratio of successive differences at 2, 4, 8 steps per period, the finest difference, and
/// the finest trace.
fn convergence_ratio(axis: impl Fn() -> AxisModel, s: &Setpoints) -> (f64, f64, ReferenceRun) {
    let [coarse, medium, fine] = [2, 4, 8].map(|steps| run(axis(), s, steps));
    let (d1, d2) = (
        max_difference(&coarse.trace, &medium.trace),
        max_difference(&medium.trace, &fine.trace),
    );
    (d1 / d2, d2, fine)
}

/// The run switches: the carriage sticks, and the gap both closes and opens.
fn assert_switches(r: &ReferenceRun) {
    let trace = &r.trace;
    assert!(trace.actual_velocity.contains(&0.0));
    let gaps = || {
        trace
            .drive
            .iter()
            .zip(&trace.actual)
            .map(|(d, c)| (d - c).abs())
    };
    assert!(gaps().any(|gap| gap < 1e-5));
    assert!(gaps().any(|gap| gap > 1e-4));
}

fn friction_and_backlash() -> AxisModelOptions {
    AxisModelOptions {
        friction: StribeckCurve::coulomb(20.0),
        backlash: 0.32e-3,
        ..Default::default()
    }
}

#[test]
fn linear_modes_are_solved_exactly_whatever_the_step() {
    // Voltage mode without friction and backlash: one linear mode, solved by the matrix
    // exponential over each whole hold, so the steps per period do not enter at all.
    let s = out_and_back(10e-3, 0.3);
    let runs = [1, 4, 16].map(|steps| run(x_axis(Default::default()), &s, steps));
    for other in &runs[1..] {
        assert_eq!(max_difference(&runs[0].trace, &other.trace), 0.0);
    }
    // With Coulomb friction and backlash every mode is still linear; the steps set where the
    // guards are checked and the events are located (to 2⁻⁴⁴ of a step), so the traces agree
    // to round-off (measured 7e-17 m between 4 and 8 steps).
    let (_, finest, r) = convergence_ratio(|| x_axis(friction_and_backlash()), &s);
    assert_switches(&r);
    println!("friction + backlash, exact modes: finest difference {finest:.2e} m");
    assert!(finest < 1e-12, "difference {finest:e} m");
}

#[test]
fn halving_the_step_shrinks_the_difference_sixteenfold() {
    // Closed loop, so the test covers the runner; current mode, so RK4 integrates. Steps of
    // 0.5, 0.25, 0.125 ms against the fastest pole keep the differences far above round-off;
    // measured ratio 17.4 (voltage mode, before it was solved exactly: 19.0, 17.4, 16.7,
    // 16.3 over 1, 2, 4, 8, 16 steps per period: fourth order).
    let s = out_and_back(10e-3, 0.3);
    let (ratio, finest, _) = convergence_ratio(|| x_axis_current_mode(Default::default()), &s);
    println!("no friction, no backlash: ratio {ratio:.2}, finest difference {finest:.2e} m");
    assert!((14.5..18.5).contains(&ratio), "ratio {ratio}");
}

#[test]
fn closed_loop_with_friction_and_backlash_converges_at_fourth_order() {
    // Most switches here come with a new command, at tick boundaries common to all step sizes;
    // the test that switches inside steps is `located_events_keep_fourth_order_...`. Measured
    // (voltage mode, when it still ran RK4) over 1, 2, 4, 8, 16 steps per period: 13.6, 17.4,
    // 16.4, 14.8.
    let s = out_and_back(10e-3, 0.3);
    let (ratio, finest, r) = convergence_ratio(|| x_axis_current_mode(friction_and_backlash()), &s);
    assert_switches(&r);
    println!("friction + backlash: ratio {ratio:.2}, finest difference {finest:.2e} m");
    assert!(ratio > 12.0, "ratio {ratio}");
}

#[test]
fn closed_loop_with_stiction_converges_at_fourth_order() {
    // The Stribeck drop is smooth within a sliding mode, so it keeps the order; breakaway now
    // waits for twice the kinetic force. Its sliding modes are not linear: RK4 even in voltage
    // mode.
    let s = out_and_back(10e-3, 0.3);
    let options = AxisModelOptions {
        friction: StribeckCurve {
            kinetic: 20.0,
            breakaway: 40.0,
            stribeck_velocity: 1e-3,
        },
        backlash: 0.32e-3,
        ..Default::default()
    };
    let (ratio, finest, r) = convergence_ratio(|| x_axis(options), &s);
    assert!(r.trace.actual_velocity.contains(&0.0));
    println!("stiction + backlash: ratio {ratio:.2}, finest difference {finest:.2e} m");
    assert!(ratio > 12.0, "ratio {ratio}");
}

#[test]
fn located_events_keep_fourth_order_within_one_long_hold() {
    // One hold of 50 ms, so every switch falls inside a step: stalled, the current rises until
    // breakaway (no backlash), or the drive crosses the gap and strikes the stuck carriage
    // (backlash). Switching at step ends instead would leave an O(h) error: ratio ≈ 2. In
    // current mode RK4 integrates (fourth order); in voltage mode the modes are solved exactly
    // and only the located instants differ, by round-off.
    for backlash in [0.0, 0.32e-3] {
        let options = AxisModelOptions {
            friction: StribeckCurve::coulomb(100.0),
            backlash,
            ..Default::default()
        };
        let end = |axis: fn(AxisModelOptions) -> AxisModel, steps: usize| {
            let mut axis = axis(options);
            axis.advance(0.5, 0.05, steps);
            assert!(axis.velocity() > 0.0);
            axis.position()
        };
        // Steps of 250, 125, 62.5 µs: in the asymptotic range (at 1 ms, h·R/L ≈ 0.5 is not).
        let [coarse, medium, fine] = [200, 400, 800].map(|n| end(x_axis_current_mode, n));
        let ratio = (coarse - medium).abs() / (medium - fine).abs();
        println!("one hold, backlash {backlash:e}: ratio {ratio:.2}");
        assert!((12.0..20.0).contains(&ratio), "ratio {ratio}");
        // Measured 4e-18 and 2.2e-16 m; RK4's differences above are of order 1e-10 m.
        let [coarse, fine] = [200, 800].map(|n| end(x_axis, n));
        let difference = (coarse - fine).abs();
        println!("exact modes: difference {difference:.2e} m");
        assert!(difference < 1e-14, "difference {difference:e} m");
    }
}

#[test]
fn linear_system_is_the_rate_of_every_linear_mode() {
    // The exact solution's matrices against the equations RK4 integrates, in every mode and
    // for both linear actuators, at an arbitrary state.
    let y = AxisState {
        drive_position: 0.0123,
        drive_velocity: 0.0456,
        carriage_position: 0.0121,
        carriage_velocity: -0.0071,
        current: 1.7,
        charge: 0.0023,
    };
    let options = friction_and_backlash();
    let mut checked = 0;
    // Gravity along the axis and guide damping (every term of A and B non-zero somewhere), and
    // one command inside the supply and one far beyond it (the clamp).
    for (ideal_actuator, command) in [(false, 0.8), (false, 40.0), (true, 0.8)] {
        let axis = AxisModel::from_drive(
            &x_drive(),
            20.0,
            -9.81,
            35.0,
            AxisModelOptions {
                ideal_actuator,
                ..options
            },
        )
        .unwrap();
        let input = axis.input(command);
        let compliant = AxisModel::from_drive(
            &x_drive(),
            20.0,
            -9.81,
            35.0,
            AxisModelOptions {
                ideal_actuator,
                compliance: Some(Compliance {
                    stiffness: 3.0e5,
                    damping: 410.0,
                }),
                ..options
            },
        )
        .unwrap();
        let contacts = [
            (Contact::Rigid, &axis),
            (Contact::Open, &axis),
            (Contact::Closed { side: 1.0 }, &axis),
            (Contact::Closed { side: -1.0 }, &axis),
            (Contact::Compliant { side: 1.0 }, &compliant),
            (Contact::Compliant { side: -1.0 }, &compliant),
            (Contact::Compliant { side: 0.0 }, &compliant),
        ];
        let guides = [-1.0, 0.0, 1.0]
            .map(|direction| Guide::Sliding { direction })
            .into_iter()
            .chain([Guide::Stuck]);
        for (contact, axis) in contacts {
            for guide in guides.clone() {
                let mode = Mode { contact, guide };
                let exact = exact::rate_from_system(axis, mode, &y, input).unwrap();
                let rate = axis.rate(&y, mode, input);
                for (a, b) in [
                    (exact.drive_position, rate.drive_position),
                    (exact.drive_velocity, rate.drive_velocity),
                    (exact.carriage_position, rate.carriage_position),
                    (exact.carriage_velocity, rate.carriage_velocity),
                    (exact.current, rate.current),
                    (exact.charge, rate.charge),
                ] {
                    assert!(
                        (a - b).abs() <= 1e-12 * b.abs().max(1.0),
                        "{mode:?}: {a} vs {b}"
                    );
                }
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 84);
    // Not linear: the current-mode amplifier, and a Stribeck curve while sliding.
    let current = x_axis_current_mode(options);
    let rigid = |guide| Mode {
        contact: Contact::Rigid,
        guide,
    };
    assert!(!current.is_linear(rigid(Guide::Stuck)));
    let sticky = x_axis(AxisModelOptions {
        friction: sticky(),
        ..options
    });
    assert!(sticky.is_linear(rigid(Guide::Stuck)));
    assert!(!sticky.is_linear(rigid(Guide::Sliding { direction: 1.0 })));
}

/// Steady velocity per volt at the amplifier input, dx/dt / u at s → 0 (m/(V·s)).
fn velocity_gain(axis: &AxisModel, drive: &Drive) -> f64 {
    let (k, m) = (axis.ratio(), &drive.motor);
    let (km, kb, r) = (
        m.torque_constant_nm_per_a,
        m.back_emf_v_s_per_rad,
        m.resistance_ohm,
    );
    drive.amplifier_gain * k * km / (r * axis.effective_damping() + kb * km * k * k)
}

#[test]
fn type_two_loop_tracks_a_ramp_without_error() {
    // Plant integrator + PID integrator: the ramp error decays to zero, also against friction
    // (the integral supplies damping + friction force).
    let (speed, friction) = (5e-3, 30.0);
    let options = AxisModelOptions {
        friction: StribeckCurve::coulomb(friction),
        ..Default::default()
    };
    let s = setpoints(1e-3, 2.0, |t| (0.01 + speed * t, speed, 0.0));
    let r = run(x_axis(options), &s, 10);
    let trace = &r.trace;
    let error: Vec<f64> = (0..trace.len())
        .map(|k| trace.commanded[k] - trace.actual[k])
        .collect();
    let peak = error.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let end = error[error.len() - 1].abs();
    println!("ramp {speed} m/s: peak following error {peak:.3e} m, after 2 s {end:.3e} m");
    assert!(peak > 1e-6, "the velocity step must excite a transient");
    assert!(end < 1e-12, "steady ramp error {end:e}");
    // And the drive force at constant speed is damping + friction.
    let axis = x_axis(options);
    let last = trace.len() - 2;
    let force = axis.ratio() * trace.torque[last];
    assert!(relative(force, axis.effective_damping() * speed + friction) < 1e-6);
}

#[test]
fn type_two_loop_lags_a_parabola_by_acceleration_over_ka() {
    // Constant acceleration A: the integrator must ramp u at A/G₀ (G₀ = steady m/s per V), so
    // it needs a constant error e with Ki·e = A/G₀: e = A/(Ki·G₀), the 1/K_a of linear theory.
    let acceleration = 0.01;
    let s = setpoints(1e-3, 2.0, |t| {
        (
            0.01 + acceleration * t * t / 2.0,
            acceleration * t,
            acceleration,
        )
    });
    let axis = x_axis(Default::default());
    let expected = acceleration / (6.1e5 * velocity_gain(&axis, &x_drive()));
    let r = run(axis, &s, 10);
    let trace = &r.trace;
    let e = trace.commanded[trace.len() - 1] - trace.actual[trace.len() - 1];
    println!("parabola: steady error {e:.4e} m, theory {expected:.4e} m");
    assert!(relative(e, expected) < 1e-4, "{e:e} vs {expected:e}");
    let command = trace.command[trace.len() - 1];
    assert!(
        command.abs() < 6.0,
        "the loop must stay linear (u = {command} V)"
    );
}

#[test]
fn z_axis_holds_its_weight() {
    let models = AxisModel::for_machine(&machine(), [0.0, 0.0, -9.81], false).unwrap();
    let z = models[2].clone();
    let ratio = z.ratio();
    let mut pid = PidBank::new(vec![pid(9700.0, 3.0e5, 85.0, 3.125)]);
    let s = setpoints(1e-3, 2.0, |_| (-0.02, 0.0, 0.0));
    let run = run_reference(vec![z], &mut pid, &s, 10, &loop_settings(1, vec![None]));
    let trace = run.trace;
    let last = trace.len() - 1;
    // Holding torque m·g/k = 0.5·9.81/(2π/5 mm) = 3.90e-3 N·m, and no position error.
    let holding = 0.5 * 9.81 / ratio;
    assert!(relative(trace.torque[last], holding) < 1e-6);
    assert!((trace.actual[last] + 0.02).abs() < 1e-12);
}

/// Passes everything to a PID bank and keeps what the controller was shown.
struct Recording {
    inner: PidBank,
    measured: Vec<f64>,
}

impl Controller for Recording {
    fn update(&mut self, input: &ControllerInput<'_>, command: &mut [f64]) {
        self.measured.extend_from_slice(input.measured_position);
        self.inner.update(input, command);
    }
    fn reset(&mut self) {
        self.inner.reset();
    }
}

#[test]
fn the_controller_sees_encoder_counts() {
    let resolution = 1e-6;
    let s = setpoints(1e-3, 0.3, |t| (0.01 + 5e-3 * t, 5e-3, 0.0));
    let mut controller = Recording {
        inner: x_pid(),
        measured: Vec::new(),
    };
    let settings = loop_settings(1, vec![Some(resolution)]);
    let trace = run_reference(
        vec![x_axis(Default::default())],
        &mut controller,
        &s,
        10,
        &settings,
    )
    .trace;
    let settle = controller.measured.len() - trace.len();
    for (k, &seen) in controller.measured[settle..].iter().enumerate() {
        let counts = seen / resolution;
        assert!((counts - counts.round()).abs() < 1e-6, "tick {k}: {seen:e}");
        assert!((seen - trace.actual[k]).abs() <= resolution / 2.0 + 1e-15);
    }
}

/// The X drive without viscous damping and a 20 kg carriage on a spring of stiffness `k`
/// (and damper `c`), with `backlash`: a conservative two-mass system when c = 0.
fn two_mass(k: f64, c: f64, backlash: f64) -> AxisModel {
    let mut drive = x_drive();
    drive.viscous_damping_nm_s_per_rad = 0.0;
    AxisModel::from_drive(
        &drive,
        20.0,
        0.0,
        0.0,
        AxisModelOptions {
            ideal_actuator: true,
            backlash,
            compliance: Some(Compliance {
                stiffness: k,
                damping: c,
            }),
            ..Default::default()
        },
    )
    .unwrap()
}

/// Kinetic plus spring energy of a two-mass axis (J).
fn energy(axis: &AxisModel) -> f64 {
    let y = &axis.state;
    let k = axis.compliance.unwrap().stiffness;
    let gap = y.drive_position - y.carriage_position;
    let stretch = gap - gap.clamp(-axis.backlash / 2.0, axis.backlash / 2.0);
    0.5 * axis.drive_mass * y.drive_velocity.powi(2)
        + 0.5 * axis.carriage_mass * y.carriage_velocity.powi(2)
        + 0.5 * k * stretch * stretch
}

#[test]
fn a_compliant_axis_rings_at_the_two_mass_frequency() {
    // Drive side 622.4 kg (J·k²), carriage 20 kg, k = 2·10⁵ N/m: the gap, released from
    // δ₀ = 10 µm with both at rest and no torque, swings as δ₀·cos(ωt) with
    // ω² = k·(1/m_d + 1/m_c), while the centre of mass stays where it was.
    let k = 2.0e5;
    let mut axis = two_mass(k, 0.0, 0.0);
    let (md, mc) = (axis.drive_mass, axis.carriage_mass);
    let omega = (k * (1.0 / md + 1.0 / mc)).sqrt();
    let delta0 = 1e-5;
    axis.state.drive_position = delta0;
    let centre = md * delta0 / (md + mc);
    let mut worst: f64 = 0.0;
    for tick in 1..=500 {
        axis.advance(0.0, 1e-3, 4);
        let t = tick as f64 * 1e-3;
        let y = axis.state;
        let gap = y.drive_position - y.carriage_position;
        worst = worst.max((gap - delta0 * (omega * t).cos()).abs() / delta0);
        let moved = (md * y.drive_position + mc * y.carriage_position) / (md + mc);
        assert!((moved - centre).abs() < 1e-15, "centre of mass moved");
    }
    assert!(worst < 1e-9, "relative error {worst:e}");
}

#[test]
fn the_backlash_is_a_dead_zone_inside_the_compliant_chain() {
    // The carriage, pushed at 10 mm/s with the drive at rest in the middle of a 0.2 mm gap,
    // coasts free (no force within the gap) until δ = −b/2 at t = 0.1 mm / 10 mm/s = 10 ms,
    // then the spring takes it; without damping no energy is lost over many crossings.
    let mut axis = two_mass(2.0e5, 0.0, 0.2e-3);
    axis.state.carriage_velocity = 0.01;
    let start = energy(&axis);
    for _ in 0..9 {
        axis.advance(0.0, 1e-3, 4);
        assert_eq!(
            axis.drive_velocity(),
            0.0,
            "the drive is pushed within the gap"
        );
    }
    axis.advance(0.0, 1e-3, 4);
    axis.advance(0.0, 1e-3, 4);
    assert!(
        axis.drive_velocity() > 0.0,
        "engaged at 10 ms: the spring pulls the drive along"
    );
    let mut crossings = 0;
    let mut open = false;
    for _ in 0..3000 {
        axis.advance(0.0, 1e-3, 4);
        let gap = axis.drive_position() - axis.position();
        let now_open = gap.abs() <= 0.1e-3;
        crossings += usize::from(now_open != open);
        open = now_open;
        let e = energy(&axis);
        assert!((e - start).abs() < 1e-9 * start, "energy {e} vs {start}");
    }
    assert!(crossings > 10, "only {crossings} gap crossings");
}

#[test]
fn the_transmission_damper_dissipates_at_the_two_mass_damping_ratio() {
    // Damping c across the spring: the gap's swing decays as exp(−ζωt) with
    // ζ = c/(2·√(k·m_eff)), m_eff = m_d·m_c/(m_d + m_c).
    let (k, c) = (2.0e5, 150.0);
    let mut axis = two_mass(k, c, 0.0);
    let (md, mc) = (axis.drive_mass, axis.carriage_mass);
    let m_eff = md * mc / (md + mc);
    let omega_n = (k / m_eff).sqrt();
    let zeta = c / (2.0 * (k * m_eff).sqrt());
    let omega_d = omega_n * (1.0 - zeta * zeta).sqrt();
    let delta0 = 1e-5;
    axis.state.drive_position = delta0;
    for tick in 1..=300 {
        axis.advance(0.0, 1e-3, 4);
        let t = tick as f64 * 1e-3;
        let y = axis.state;
        let gap = y.drive_position - y.carriage_position;
        // δ(t) = δ₀·e^(−ζω_n t)·(cos ω_d t + ζω_n/ω_d·sin ω_d t) from rest.
        let expected = delta0
            * (-zeta * omega_n * t).exp()
            * ((omega_d * t).cos() + zeta * omega_n / omega_d * (omega_d * t).sin());
        assert!(
            (gap - expected).abs() < 1e-9 * delta0,
            "t = {t}: {gap} vs {expected}"
        );
    }
}
