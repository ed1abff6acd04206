//! What a run writes and runs beside the physics: `[recording]` and `[analytic]`.

use super::limits;
use super::source::InFile;
use crate::diagnostics::FileError;
use serde::Deserialize;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRecording {
    #[serde(default = "yes")]
    rrd: bool,
    #[serde(default = "yes")]
    csv: bool,
    #[serde(default = "one")]
    decimation: Spanned<i64>,
}

fn yes() -> bool {
    true
}

fn one() -> Spanned<i64> {
    Spanned::new(0..0, 1)
}

impl Default for RawRecording {
    fn default() -> Self {
        RawRecording {
            rrd: true,
            csv: true,
            decimation: one(),
        }
    }
}

/// The `[recording]` section: which files a run writes, and every how many ticks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordingSettings {
    /// The Rerun recording `run.rrd`.
    pub rrd: bool,
    /// The time series `trace.csv`.
    pub csv: bool,
    /// Record every k-th servo tick.
    pub decimation: usize,
}

impl TryFrom<InFile<'_, &RawRecording>> for RecordingSettings {
    type Error = FileError;

    fn try_from(InFile { raw, file }: InFile<'_, &RawRecording>) -> Result<Self, FileError> {
        let decimation = *raw.decimation.get_ref();
        if !(1..=limits::MAX_DECIMATION).contains(&decimation) {
            return Err(file.error(raw.decimation.span(), format!("decimation = {decimation}: expected a whole number from 1 to {} (record every k-th tick)", limits::MAX_DECIMATION)));
        }
        Ok(RecordingSettings {
            rrd: raw.rrd,
            csv: raw.csv,
            decimation: decimation as usize,
        })
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawAnalytic {
    #[serde(default = "yes")]
    enabled: bool,
    /// Steps per servo period (exact or RK4, see `sim::analytic`).
    #[serde(default = "sixteen")]
    steps_per_period: Spanned<i64>,
}

fn sixteen() -> Spanned<i64> {
    Spanned::new(0..0, 16)
}

/// The `[analytic]` section: the reference model runs beside the physics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnalyticSettings {
    /// Integration steps per servo period.
    pub steps_per_period: usize,
}

impl AnalyticSettings {
    /// The model's steps when it runs without an `[analytic]` table (e.g. for `tune`).
    pub const DEFAULT_STEPS: usize = 16;

    /// The section as written: `None` when it turns the model off.
    pub(super) fn from_raw(
        InFile { raw, file }: InFile<'_, &RawAnalytic>,
    ) -> Result<Option<Self>, FileError> {
        if !raw.enabled {
            return Ok(None);
        }
        let steps = *raw.steps_per_period.get_ref();
        if !(1..=10_000).contains(&steps) {
            return Err(file.error(
                raw.steps_per_period.span(),
                format!("steps_per_period = {steps}: expected a whole number from 1 to 10000"),
            ));
        }
        Ok(Some(AnalyticSettings {
            steps_per_period: steps as usize,
        }))
    }
}
