//! `[frequency_response.<axis>]`: frequency-response measurements a run makes after its
//! program (what `cncsim bode` measures), whose figures become metrics that `[expect]` can
//! bound: `frequency_response.<axis>.resonance_hz` and the others of
//! [`crate::report::Figures`].

use super::source::{InFile, Num};
use crate::diagnostics::{FileError, LineColumn};
use crate::frequency::Loop;
use serde::Deserialize;
use toml::Spanned;

/// The loop as written.
#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawLoop {
    Plant,
    Velocity,
    Position,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawFrequencyResponse {
    #[serde(rename = "loop", default)]
    lp: Option<RawLoop>,
    from_hz: Option<Num>,
    to_hz: Option<Num>,
    per_decade: Option<Spanned<i64>>,
}

/// One axis's table with its name, as the file has it.
pub(super) struct AxisTable<'a> {
    pub axis: &'a str,
    pub table: &'a Spanned<RawFrequencyResponse>,
}

/// One measurement a scenario asks for (frequencies in Hz; `None`: `cncsim bode`'s default).
#[derive(Debug, Clone, PartialEq)]
pub struct FrequencyResponse {
    /// Name of the axis measured (the table's key).
    pub axis: String,
    /// Which loop (`loop`; default: the plant).
    pub lp: Loop,
    /// Lowest frequency of the sweep (Hz).
    pub from_hz: Option<f64>,
    /// Highest frequency of the sweep (Hz).
    pub to_hz: Option<f64>,
    /// Frequencies per decade (default 12).
    pub per_decade: usize,
    /// Where the table is.
    pub at: Option<LineColumn>,
}

impl TryFrom<InFile<'_, AxisTable<'_>>> for FrequencyResponse {
    type Error = FileError;

    fn try_from(InFile { raw, file }: InFile<'_, AxisTable<'_>>) -> Result<Self, FileError> {
        let t = raw.table.get_ref();
        let at = file.at(raw.table.span().start);
        let range = (1e-2, 1e6);
        let from = file.ranged_opt(t.from_hz.as_ref(), "from_hz", "Hz", range)?;
        let to = file.ranged_opt(t.to_hz.as_ref(), "to_hz", "Hz", range)?;
        if let (Some(f), Some(to_v), Some(to_raw)) = (from, to, t.to_hz.as_ref()) {
            if f >= to_v {
                return Err(file.error(
                    to_raw.span(),
                    format!("to_hz = {to_v}: must be above from_hz = {f}"),
                ));
            }
        }
        let per_decade = match &t.per_decade {
            None => 12,
            Some(n) => {
                let v = *n.get_ref();
                if !(1..=200).contains(&v) {
                    return Err(file.error(
                        n.span(),
                        format!("per_decade = {v}: expected a whole number from 1 to 200"),
                    ));
                }
                v as usize
            }
        };
        Ok(FrequencyResponse {
            axis: raw.axis.to_string(),
            lp: match t.lp.unwrap_or(RawLoop::Plant) {
                RawLoop::Plant => Loop::Plant,
                RawLoop::Velocity => Loop::Velocity,
                RawLoop::Position => Loop::Position,
            },
            from_hz: from,
            to_hz: to,
            per_decade,
            at,
        })
    }
}
