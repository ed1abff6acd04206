//! Cost of one servo period of the XYZ table: PID + DC-motor actuators + 4 physics steps of
//! 0.25 ms (T = 1 ms), and of one bare physics step; each with rigid joints, with the table's
//! guide contacts (friction) and backlash joints, and with stiction on the guides.

use cncsim::control::{Actuator, ActuatorKind, Pid, PidBank, PidForm, PidGains, PidSettings};
use cncsim::machine::Machine;
use cncsim::model::{Plant, PlantOptions};
use cncsim::plan::Setpoints;
use cncsim::sim::{
    self, Encoder, FollowingErrorTrip, Lane, LoopSettings, PhysicsPlant, Unobserved,
};
use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use std::path::Path;

/// The XYZ table with voltage-mode amplifiers, which the bench's stiff gains are for.
fn table() -> Machine {
    let mut m = Machine::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/xyz_table.urdf"))
        .unwrap();
    for a in &mut m.axes {
        a.drive.amplifier_mode = cncsim::machine::AmplifierMode::Voltage;
    }
    m
}

fn plant(machine: &Machine, step: f64) -> Plant {
    let options = PlantOptions {
        step,
        gravity: [0.0, 0.0, -9.81],
        initial_positions: vec![0.1, 0.1, 0.0],
        include_drive_dynamics: true,
        solver_iterations: 1,
    };
    Plant::new(machine, &options).unwrap()
}

/// The table with both taken out, with plain Coulomb guides and backlash, and with stiction
/// (μ_s = 2·μ over v_s = 1 mm/s: its contact pairs are rebuilt every step, not recycled).
fn variants() -> [(&'static str, Machine); 3] {
    let mut rigid = table();
    for axis in &mut rigid.axes {
        axis.drive.guide = None;
        axis.drive.backlash = 0.0;
    }
    let with_guides = |stiction: bool| {
        let mut m = table();
        for g in m.axes.iter_mut().filter_map(|a| a.drive.guide.as_mut()) {
            (g.static_friction_coefficient, g.stribeck_velocity_m_s) = if stiction {
                (Some(2.0 * g.friction_coefficient), Some(1e-3))
            } else {
                (None, None)
            };
        }
        m
    };
    [
        ("rigid joints", rigid),
        ("guide contacts + backlash", with_guides(false)),
        ("guide contacts with stiction + backlash", with_guides(true)),
    ]
}

fn benches(c: &mut Criterion) {
    for (label, machine) in variants() {
        let mut p = plant(&machine, 2.5e-4);
        c.bench_function(
            &format!("physics step (0.25 ms), XYZ table, {label}"),
            |b| {
                b.iter(|| {
                    p.set_joint_forces(&[1.0, -1.0, 5.0]);
                    p.step();
                })
            },
        );
    }

    // One servo period through the full loop: 1000 ticks per iteration, reported per tick.
    let ticks = 1000;
    let mut setpoints = Setpoints::new(1e-3, 3);
    for k in 0..ticks {
        let x = 0.1 + 5e-6 * k as f64;
        setpoints.push(&[x, 0.1, 0.0], &[0.005, 0.0, 0.0], &[0.0; 3], 0);
    }
    let mut group = c.benchmark_group("servo period (1 ms = PID + DC motor + 4 physics steps)");
    group.throughput(criterion::Throughput::Elements(ticks as u64));
    for (label, machine) in variants() {
        group.bench_function(format!("xyz table, {label}, per 1000 ticks"), |b| {
            let settings = LoopSettings {
                servo_period: 1e-3,
                approach: Setpoints::default(),
                settle_time: 0.0,
                encoder: Encoder {
                    resolution: vec![None; 3],
                },
                trip: FollowingErrorTrip {
                    limit: vec![1.0; 3],
                    axis_names: vec!["x".into(), "y".into(), "z".into()],
                },
                spindle: Default::default(),
            };
            b.iter_batched(
                || {
                    let gains = PidGains {
                        kp: 19800.0,
                        ki: 6.1e5,
                        kd: 146.0,
                    };
                    let pid = Pid::new(PidSettings::plain(gains, 6.0), PidForm::Positional, 1e-3);
                    let plant = PhysicsPlant::new(
                        plant(&machine, 2.5e-4),
                        machine
                            .axes
                            .iter()
                            .map(|a| Actuator::new(ActuatorKind::DcMotor, &a.drive))
                            .collect(),
                        machine.axes.iter().map(|a| a.drive.ratio()).collect(),
                        4,
                    );
                    [Lane {
                        kind: sim::LaneKind::Physics,
                        plant: Box::new(plant),
                        controller: Box::new(PidBank::new(vec![pid; 3])),
                    }]
                },
                |mut lanes| {
                    sim::run(
                        &settings,
                        &mut lanes,
                        &mut setpoints.stream(),
                        &mut Unobserved,
                        &mut |_, _| true,
                    )
                },
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

/// One servo period of the A-C mill (5 axes, 4 physics steps of 0.25 ms) with each controller,
/// on the first 1000 ticks of the study's program: per-axis PID against computed torque (RNEA
/// on the URDF model every period), in joint space and resolved at the tool tip.
fn mill(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut group = c.benchmark_group("servo period, A-C mill");
    group.throughput(criterion::Throughput::Elements(1000));
    for (name, overrides) in [
        ("mill_table2_pid", ""),
        ("mill_table2_id", ""),
        ("mill_table2_id", "controller.space=task"),
    ] {
        let overrides: Vec<_> = overrides
            .split_whitespace()
            .map(|o| cncsim::scenario::Override::parse(o).unwrap())
            .collect();
        let scenario = cncsim::scenario::Scenario::load_with_overrides(
            &root.join(format!("scenarios/{name}.toml")),
            &overrides,
            "--a",
        )
        .unwrap();
        group.bench_function(format!("{}, per 1000 ticks", scenario.name), |b| {
            let assembly = cncsim::scenario::Assembly::new(&scenario).unwrap();
            // In memory, so that the loop is timed and not the planner.
            let first = cncsim::plan::collect(&mut cncsim::plan::FirstSamples::new(
                assembly.setpoints(),
                1000,
            ));
            let settings = LoopSettings {
                settle_time: 0.0,
                approach: Setpoints::default(),
                ..assembly.loop_settings.clone()
            };
            b.iter_batched(
                || assembly.lanes().unwrap(),
                |mut lanes| {
                    sim::run(
                        &settings,
                        &mut lanes,
                        &mut first.stream(),
                        &mut Unobserved,
                        &mut |_, _| true,
                    )
                },
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(servo, benches, mill);
criterion_main!(servo);
