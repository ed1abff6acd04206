//! What a scenario is checked against and compared with: `[expect]` bounds and `[ab]` variants.

use super::source::InFile;
use crate::diagnostics::{FileError, LineColumn};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;
use toml::Spanned;

/// A bound on one metric.
#[derive(Debug, Clone, PartialEq)]
pub struct Expectation {
    /// Dotted path into `metrics.json`, e.g. `axes.x.max_following_error_mm`.
    pub metric: String,
    /// Lowest value allowed, in the metric's own unit; `None`: no lower bound.
    pub min: Option<f64>,
    /// Highest value allowed, in the metric's own unit; `None`: no upper bound.
    pub max: Option<f64>,
    /// Where the bound's `[expect]` entry starts in the scenario file, for messages.
    pub at: Option<LineColumn>,
}

/// The `[expect]` section: each bound, flattened to its dotted metric path.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Expectations(pub Vec<Expectation>);

impl TryFrom<InFile<'_, &BTreeMap<String, Spanned<toml::Value>>>> for Expectations {
    type Error = FileError;

    fn try_from(
        InFile { raw, file }: InFile<'_, &BTreeMap<String, Spanned<toml::Value>>>,
    ) -> Result<Self, FileError> {
        let mut expect = Vec::new();
        for (key, value) in raw {
            flatten_expectations(
                key,
                value.get_ref(),
                file.at(value.span().start),
                file.path,
                &mut expect,
            )?;
        }
        Ok(Expectations(expect))
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawAb {
    #[serde(default)]
    a: Vec<Spanned<String>>,
    #[serde(default)]
    b: Vec<Spanned<String>>,
}

/// Variants declared in a scenario's `[ab]` table: the overrides of A and of B, as written.
#[derive(Debug, Clone, PartialEq)]
pub struct DeclaredVariants {
    /// Overrides of variant A, each `KEY=VALUE`.
    pub a: Vec<String>,
    /// Overrides of variant B, each `KEY=VALUE`.
    pub b: Vec<String>,
    /// Where the `[ab]` table starts in the scenario file, for messages.
    pub at: Option<LineColumn>,
}

impl TryFrom<InFile<'_, &Spanned<RawAb>>> for DeclaredVariants {
    type Error = FileError;

    fn try_from(
        InFile { raw: table, file }: InFile<'_, &Spanned<RawAb>>,
    ) -> Result<Self, FileError> {
        let v = table.get_ref();
        for (side, list) in [("a", &v.a), ("b", &v.b)] {
            for o in list {
                if let Err(e) = crate::scenario::Override::parse(o.get_ref()) {
                    return Err(file.error(o.span(), format!("ab.{side}: {e}")));
                }
            }
        }
        if v.a.is_empty() && v.b.is_empty() {
            return Err(file.error(
                table.span(),
                "[ab] declares no overrides: expected a = [\"KEY=VALUE\", …] and/or b = […]",
            ));
        }
        let texts = |list: &[Spanned<String>]| list.iter().map(|o| o.get_ref().clone()).collect();
        Ok(DeclaredVariants {
            a: texts(&v.a),
            b: texts(&v.b),
            at: file.at(table.span().start),
        })
    }
}

/// `[expect]` entries: `metric = { max = … }` / `{ min = … }` / both, possibly nested
/// (`[expect.axes.x]`), flattened to dotted metric paths.
fn flatten_expectations(
    prefix: &str,
    value: &toml::Value,
    at: Option<LineColumn>,
    path: &Path,
    out: &mut Vec<Expectation>,
) -> Result<(), FileError> {
    let fail = |m: String| FileError::new(path, at, m);
    let table = value.as_table().ok_or_else(|| {
        fail(format!(
            "expect.{prefix}: expected a bound such as {{ max = 0.01 }}, found {}",
            value.type_str()
        ))
    })?;
    let is_bound = !table.is_empty() && table.keys().all(|k| k == "min" || k == "max");
    if !is_bound {
        for (k, v) in table {
            if k == "min" || k == "max" {
                return Err(fail(format!(
                    "expect.{prefix}: mixes a bound ({k}) with nested metrics"
                )));
            }
            flatten_expectations(&format!("{prefix}.{k}"), v, at, path, out)?;
        }
        return Ok(());
    }
    let num = |k: &str| -> Result<Option<f64>, FileError> {
        match table.get(k) {
            None => Ok(None),
            Some(v) => {
                let x = v
                    .as_float()
                    .or_else(|| v.as_integer().map(|i| i as f64))
                    .ok_or_else(|| {
                        fail(format!(
                            "expect.{prefix}.{k}: expected a number, found {}",
                            v.type_str()
                        ))
                    })?;
                if !x.is_finite() {
                    return Err(fail(format!(
                        "expect.{prefix}.{k} = {x:?}: expected a finite number"
                    )));
                }
                Ok(Some(x))
            }
        }
    };
    let (min, max) = (num("min")?, num("max")?);
    if let (Some(lo), Some(hi)) = (min, max) {
        if lo > hi {
            return Err(fail(format!("expect.{prefix}: min {lo} > max {hi}")));
        }
    }
    out.push(Expectation {
        metric: prefix.to_string(),
        min,
        max,
        at,
    });
    Ok(())
}
