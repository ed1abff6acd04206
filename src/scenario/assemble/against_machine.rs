//! What a scenario says about its machine, checked against the machine it runs on: axis
//! names, axis kinds of the compensation keys, and the metric names its bounds use.

use crate::control::ActuatorKind;
use crate::diagnostics::FileError;
use crate::machine::Machine;
use crate::report::{self, AxisLabel};
use crate::scenario::Scenario;

/// Axis names in the scenario must be the machine's; the chosen controller needs settings for
/// every axis; compensation units must fit the axis kind; every bound must name a real metric.
pub(super) fn check_against_machine(
    s: &Scenario,
    machine: &Machine,
    labels: &[AxisLabel],
) -> Result<(), FileError> {
    let names: Vec<&str> = machine.axes.iter().map(|a| a.name.as_str()).collect();
    // Settings of every controller type given, whichever runs: an override may switch types.
    let controller_axes = s.controller.iter().flat_map(|c| {
        let pid = c.pid.axes.iter().map(|(axis, g)| ("axes", axis, g.at));
        let cascade = c
            .cascade
            .axes
            .iter()
            .map(|(axis, g)| ("cascade", axis, g.at));
        pid.chain(cascade)
    });
    for (table, axis, at) in controller_axes {
        if !names.contains(&axis.as_str()) {
            return Err(FileError::new(
                &s.path,
                at,
                format!(
                    "controller.{table}.{axis}: the machine '{}' has no axis '{axis}' (its axes: {})",
                    machine.name,
                    names.join(", ")
                ),
            ));
        }
    }
    for (axis, c) in &s.compensation {
        let Some(i) = machine.axis_index(axis) else {
            return Err(FileError::new(
                &s.path,
                c.at,
                format!(
                    "compensation.{axis}: the machine '{}' has no axis '{axis}' (its axes: {})",
                    machine.name,
                    names.join(", ")
                ),
            ));
        };
        if let Some(rotary) = c.rotary_units {
            if rotary != labels[i].rotary {
                let (kind, keys) = if labels[i].rotary {
                    ("rotary", "backlash_deg and backlash_rate_deg_s")
                } else {
                    ("linear", "backlash_mm and backlash_rate_mm_s")
                };
                return Err(FileError::new(
                    &s.path,
                    c.at,
                    format!("compensation.{axis}: axis '{axis}' is {kind}: expected {keys}"),
                ));
            }
        }
    }
    for (axis, t) in &s.mechanics.transmission {
        let Some(i) = machine.axis_index(axis) else {
            return Err(FileError::new(
                &s.path,
                t.at,
                format!(
                    "mechanics.transmission.{axis}: the machine '{}' has no axis '{axis}' (its axes: {})",
                    machine.name,
                    names.join(", ")
                ),
            ));
        };
        if t.rotary_units != labels[i].rotary {
            let (kind, keys) = if labels[i].rotary {
                ("rotary", "stiffness_nm_per_rad and damping_nm_s_per_rad")
            } else {
                ("linear", "stiffness_n_per_m and damping_n_s_per_m")
            };
            return Err(FileError::new(
                &s.path,
                t.at,
                format!("mechanics.transmission.{axis}: axis '{axis}' is {kind}: expected {keys}"),
            ));
        }
    }
    for (axis, (_, at)) in &s.feedback.encoder_counts_per_rev {
        if !names.contains(&axis.as_str()) {
            return Err(FileError::new(
                &s.path,
                *at,
                format!("feedback.encoder_counts_per_rev.{axis}: the machine has no axis '{axis}'"),
            ));
        }
    }
    check_metric_names(s, labels)
}

/// Every bound must name a metric a run of this scenario on this machine produces; every
/// frequency response must name an axis and a loop it has.
fn check_metric_names(s: &Scenario, labels: &[AxisLabel]) -> Result<(), FileError> {
    // The metric names a run of this machine produces.
    let accumulator = report::MetricsAccumulator::new(
        labels,
        s.actuator.map(|a| a.kind) == Some(ActuatorKind::DcMotor),
        s.timing.servo_period,
        &vec![0.0; labels.len()],
        s.analytic.is_some(),
    );
    let accumulator = if s.cutting.is_some() {
        accumulator.with_cutting()
    } else {
        accumulator
    };
    let mut metrics = accumulator.finish(&s.name, &crate::sim::Outcome::default());
    if s.cutting.is_some() {
        metrics.part = Some(report::PartMetrics::default());
    }
    let template = metrics.to_json();
    let mut known = Vec::new();
    collect_numeric_paths(&template, "", &mut known);
    if let crate::scenario::ProgramSource::Ballbar(b) = &s.program.source {
        let ([a1, a2], _) = crate::scenario::plane_axes(b.plane);
        let letters = ["x", "y", "z"];
        known.extend(crate::report::BallbarRun::metric_names([
            letters[a1],
            letters[a2],
        ]));
    }
    for f in &s.frequency_response {
        if !labels.iter().any(|l| l.name == f.axis) {
            return Err(FileError::new(
                &s.path,
                f.at,
                format!(
                    "frequency_response.{}: the machine has no axis '{}'",
                    f.axis, f.axis
                ),
            ));
        }
        let cascade = s.controller_type() == Some(crate::scenario::ControllerType::Cascade);
        if f.lp == crate::frequency::Loop::Velocity && !cascade {
            return Err(FileError::new(
                &s.path,
                f.at,
                format!("frequency_response.{}: loop = \"velocity\" measures the velocity loop of a cascade controller; this scenario's controller has none (use \"plant\" or \"position\")", f.axis),
            ));
        }
        known.extend(
            crate::report::Figures::METRICS
                .iter()
                .map(|m| format!("frequency_response.{}.{m}", f.axis)),
        );
    }
    for e in &s.expect {
        if !known.contains(&e.metric) {
            return Err(FileError::new(
                &s.path,
                e.at,
                format!(
                    "expect.{}: no such metric; a run of this scenario reports: {}",
                    e.metric,
                    known.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

fn collect_numeric_paths(v: &serde_json::Value, prefix: &str, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                collect_numeric_paths(v, &p, out);
            }
        }
        serde_json::Value::Number(_) | serde_json::Value::Null => out.push(prefix.to_string()),
        _ => {}
    }
}
