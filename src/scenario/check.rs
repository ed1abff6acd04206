//! `[expect]` bounds against a run's metrics.

use super::{Expectation, Scenario};
use std::fmt;

/// One bound that a run did not meet.
#[derive(Debug, Clone, PartialEq)]
pub struct Breach {
    pub expectation: Expectation,
    /// The metric's value; `None` if the run did not produce it.
    pub value: Option<f64>,
}

/// The outcome of checking one scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    pub checked: usize,
    pub breaches: Vec<Breach>,
}

impl Verdict {
    pub fn passed(&self) -> bool {
        self.breaches.is_empty()
    }
}

/// Compares every expectation of `scenario` with `metrics` (the `metrics.json` value).
pub fn check(scenario: &Scenario, metrics: &serde_json::Value) -> Verdict {
    let mut breaches = Vec::new();
    for e in &scenario.expect {
        let value = crate::report::Metrics::lookup(metrics, &e.metric);
        let ok = match value {
            Some(v) => {
                !v.is_nan() && e.min.is_none_or(|lo| v >= lo) && e.max.is_none_or(|hi| v <= hi)
            }
            None => false,
        };
        if !ok {
            breaches.push(Breach {
                expectation: e.clone(),
                value,
            });
        }
    }
    Verdict {
        checked: scenario.expect.len(),
        breaches,
    }
}

impl fmt::Display for Breach {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let e = &self.expectation;
        let bound = match (e.min, e.max) {
            (Some(lo), Some(hi)) => format!("within [{lo}, {hi}]"),
            (Some(lo), None) => format!("≥ {lo}"),
            (None, Some(hi)) => format!("≤ {hi}"),
            (None, None) => "bounded".into(),
        };
        match self.value {
            Some(v) => write!(f, "{} = {v} breaches its bound: expected {bound}", e.metric),
            None => write!(
                f,
                "{} was not produced by the run: expected {bound}",
                e.metric
            ),
        }
    }
}
