//! The frequency response report of `cncsim bode`: the measured points and the linear model's
//! curve, the figures a drive engineer reads off them (resonances, antiresonances, bandwidth,
//! margins), the terminal table, the Bode plot (PNG), CSV and the Rerun recording.

use super::plot::{render, DrawResult, FAMILY};
use super::{ReportError, PLOT_SIZE};
use crate::frequency::{bandwidth, extrema, margins, Crossover, C64};
use serde::Serialize;
use std::path::Path;

/// Coherence below which a measured point is not used for resonances and shown hollow.
pub const MIN_COHERENCE: f64 = 0.8;
/// How far (dB) a peak or dip must stand out to count as a resonance or antiresonance.
pub const PROMINENCE_DB: f64 = 3.0;

/// One curve as arrays over frequency (Hz, dB, degrees).
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct Curve {
    /// Frequencies of the points (Hz), rising.
    pub frequencies_hz: Vec<f64>,
    /// Magnitude at each frequency (dB).
    pub magnitude_db: Vec<f64>,
    /// Phase at each frequency (degrees), unwrapped.
    pub phase_deg: Vec<f64>,
}

impl Curve {
    /// The curve of complex values `h` at `frequency` (Hz), magnitudes scaled by `scale`
    /// (e.g. mm per m), phase unwrapped from the branch of `reference` (rad) at the first point.
    pub fn new(frequency: &[f64], h: &[C64], scale: f64, reference: f64) -> Curve {
        let phase = crate::frequency::estimate::unwrap(
            &h.iter().map(|c| c.arg()).collect::<Vec<_>>(),
            reference,
        );
        Curve {
            frequencies_hz: frequency.to_vec(),
            magnitude_db: h
                .iter()
                .map(|c| crate::frequency::estimate::db(c.norm() * scale))
                .collect(),
            phase_deg: phase.iter().map(|p| p.to_degrees()).collect(),
        }
    }
}

impl Curve {
    /// Like [`Curve::new`], each phase put on the branch nearest the matching phase of
    /// `reference` (degrees, one per point): measured points read against the model, and a
    /// point spoilt by noise does not shift the branch of those after it.
    pub fn near(frequency: &[f64], h: &[C64], scale: f64, reference: &[f64]) -> Curve {
        let mut c = Curve::new(frequency, h, scale, 0.0);
        for (p, r) in c.phase_deg.iter_mut().zip(reference) {
            *p -= ((*p - r) / 360.0).round() * 360.0;
        }
        c
    }
}

/// The figures of one response: resonances and antiresonances (Hz), −3 dB bandwidth of the
/// closed loop, gain and phase margins of the open loop with their crossovers.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct Figures {
    /// Resonances: peaks of the feature response that stand out by [`PROMINENCE_DB`] (Hz,
    /// lowest first).
    pub resonances_hz: Vec<f64>,
    /// Antiresonances: dips of the feature response that stand out alike (Hz, lowest first).
    pub antiresonances_hz: Vec<f64>,
    /// −3 dB bandwidth of the closed loop (Hz).
    pub bandwidth_hz: Option<f64>,
    /// Gain margin of the open loop (dB), read at the phase crossover.
    pub gain_margin_db: Option<f64>,
    /// Where the phase crosses −180° (Hz).
    pub phase_crossover_hz: Option<f64>,
    /// Phase margin of the open loop (degrees), read at the gain crossover.
    pub phase_margin_deg: Option<f64>,
    /// Where |L| = 1 (Hz).
    pub gain_crossover_hz: Option<f64>,
}

impl Figures {
    /// The figures' metric keys under `frequency_response.<axis>` (what `[expect]` bounds):
    /// the first (lowest) resonance and antiresonance, bandwidth, margins and crossovers.
    pub const METRICS: [&'static str; 7] = [
        "resonance_hz",
        "antiresonance_hz",
        "bandwidth_hz",
        "gain_margin_db",
        "phase_margin_deg",
        "gain_crossover_hz",
        "phase_crossover_hz",
    ];

    /// The figures as metrics (keys of [`Self::METRICS`]; a figure not found is left out, so
    /// a bound on it fails as not produced).
    pub fn metrics_json(&self) -> serde_json::Value {
        let values = [
            self.resonances_hz.first().copied(),
            self.antiresonances_hz.first().copied(),
            self.bandwidth_hz,
            self.gain_margin_db,
            self.phase_margin_deg,
            self.gain_crossover_hz,
            self.phase_crossover_hz,
        ];
        let mut map = serde_json::Map::new();
        for (key, value) in Self::METRICS.iter().zip(values) {
            if let Some(v) = value.filter(|v| v.is_finite()) {
                map.insert(key.to_string(), serde_json::json!(v));
            }
        }
        serde_json::Value::Object(map)
    }

    /// The figures from a feature response (whose peaks and dips are the resonances), a closed
    /// loop and an open loop, each at its own frequencies (Hz) with the coherence of each
    /// point (a search refines each sweep where its own curve needs it); points below
    /// [`MIN_COHERENCE`] are left out of every figure.
    pub fn of(feature: Points<'_>, closed: Points<'_>, open: Points<'_>) -> Figures {
        let mag: Vec<f64> = feature
            .values
            .iter()
            .map(|h| crate::frequency::estimate::db(h.norm()))
            .collect();
        // Margins and bandwidth from the coherent points only: an incoherent point is not a
        // transfer function value.
        let (f_open, open) = open.coherent();
        let (f_closed, closed) = closed.coherent();
        let (gm, pm) = margins(&f_open, &open);
        Figures {
            resonances_hz: extrema(
                feature.frequency,
                &mag,
                feature.coherence,
                true,
                PROMINENCE_DB,
                MIN_COHERENCE,
            ),
            antiresonances_hz: extrema(
                feature.frequency,
                &mag,
                feature.coherence,
                false,
                PROMINENCE_DB,
                MIN_COHERENCE,
            ),
            bandwidth_hz: bandwidth(&f_closed, &closed),
            gain_margin_db: gm.map(|c: Crossover| c.margin),
            phase_crossover_hz: gm.map(|c| c.frequency_hz),
            phase_margin_deg: pm.map(|c| c.margin),
            gain_crossover_hz: pm.map(|c| c.frequency_hz),
        }
    }
}

/// One response at its frequencies (Hz), with the coherence of each point.
#[derive(Debug, Clone, Copy)]
pub struct Points<'a> {
    /// Frequencies (Hz), increasing.
    pub frequency: &'a [f64],
    /// The response at each.
    pub values: &'a [C64],
    /// Coherence of each point (1 for a model).
    pub coherence: &'a [f64],
}

impl Points<'_> {
    /// The points whose coherence is at least [`MIN_COHERENCE`].
    fn coherent(&self) -> (Vec<f64>, Vec<C64>) {
        (0..self.frequency.len())
            .filter(|&i| self.coherence[i] >= MIN_COHERENCE)
            .map(|i| (self.frequency[i], self.values[i]))
            .unzip()
    }
}

/// A `cncsim bode` result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BodeRun {
    /// The scenario's name.
    pub scenario: String,
    /// Name of the axis measured.
    pub axis: String,
    /// "plant", "velocity" or "position".
    #[serde(rename = "loop")]
    pub loop_name: String,
    /// "physics" or "analytic": what was measured.
    pub plant: String,
    /// What the main response is, e.g. "plant: feedback position / command".
    pub response: String,
    /// Unit of the magnitude, e.g. "dB re 1 mm/V".
    pub magnitude_unit: String,
    /// Servo period of the loop (s).
    pub servo_period_s: f64,
    /// Excitation: where it enters, its amplitude and unit.
    pub excitation: String,
    /// Amplitude of the excitation, in `amplitude_unit`.
    pub amplitude: f64,
    /// Unit of `amplitude`: the command unit at the controller output, mm or deg (per
    /// second on the velocity command) on a setpoint.
    pub amplitude_unit: String,
    /// Measured points.
    pub frequencies_hz: Vec<f64>,
    /// Measured magnitude at each frequency (dB, see `magnitude_unit`).
    pub magnitude_db: Vec<f64>,
    /// Measured phase at each frequency (degrees).
    pub phase_deg: Vec<f64>,
    /// Coherence of each measured point (0 to 1): the share of the response the excitation
    /// explains.
    pub coherence: Vec<f64>,
    /// The open loop at the plant input (measured by injection at the controller output).
    pub open_loop: Curve,
    /// The figures of the measurement (at the top level of the JSON, beside the curves).
    #[serde(flatten)]
    pub figures: Figures,
    /// The linearised model on a dense grid: main response and open loop.
    pub model: Curve,
    /// The model's open loop on the same grid.
    pub model_open_loop: Curve,
    /// The model's figures on that grid.
    pub model_figures: Figures,
    /// The model at the measured frequencies (for comparing point by point).
    pub model_at_points: Curve,
    /// Largest |command| in any measured block, and the command limit.
    pub peak_command: f64,
    /// The command limit: the lower of the controller's output limit and the actuator's own.
    pub command_limit: f64,
    /// Simulated time of all the measurements, lead-ins included (s).
    pub simulated_time_s: f64,
    /// Wall-clock time of the measurement (s).
    pub wall_time_s: f64,
    /// Notes on what the measurement could not do (saturation, low coherence, nonlinear
    /// mechanics the model leaves out).
    pub notes: Vec<String>,
    /// Settling of each frequency before it is measured (s): at least five of the loop's
    /// slowest ringing time constants by the model.
    pub settle_s: f64,
    /// The relative frequency resolution to which the search on the physics located the peaks
    /// and dips (the widest final gap between measured points, e.g. 0.001); `None` where there
    /// were none.
    pub search_resolution: Option<f64>,
}

fn opt(v: Option<f64>, digits: usize, unit: &str) -> String {
    v.map_or("—".into(), |v| format!("{v:.digits$} {unit}"))
}

fn list(v: &[f64]) -> String {
    if v.is_empty() {
        "none".into()
    } else {
        v.iter()
            .map(|f| format!("{f:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
            + " Hz"
    }
}

/// The range a plot axis shows for `vals`, `pad` beyond both ends.
fn span(vals: Vec<f64>, pad: f64) -> std::ops::Range<f64> {
    let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if lo.is_finite() && hi > lo {
        (lo - pad)..(hi + pad)
    } else {
        -1.0..1.0
    }
}

/// A curve's finite magnitudes (`mag`) or phases against frequency.
fn line(c: &Curve, mag: bool) -> Vec<(f64, f64)> {
    c.frequencies_hz
        .iter()
        .zip(if mag { &c.magnitude_db } else { &c.phase_deg })
        .filter(|(_, v)| v.is_finite())
        .map(|(f, v)| (*f, *v))
        .collect()
}

impl BodeRun {
    /// The terminal report: the figures measured beside the model's, then the response at
    /// about three frequencies per decade.
    pub fn text(&self) -> String {
        let m = &self.model_figures;
        let mut out = format!(
            "Frequency response: {} axis {}, {} loop, measured on {} (stepped sine, {} frequencies, servo period {} ms)\n",
            self.scenario,
            self.axis,
            self.loop_name,
            self.plant,
            self.frequencies_hz.len(),
            self.servo_period_s * 1e3
        );
        out += &format!(
            "  excitation    {}, amplitude {:.4e} {}; peak command {:.3} of limit {:.3}\n",
            self.excitation,
            self.amplitude,
            self.amplitude_unit,
            self.peak_command,
            self.command_limit
        );
        out += &format!(
            "  response      {} ({})\n",
            self.response, self.magnitude_unit
        );
        out += "                 measured                     linear model\n";
        let row = |name: &str, a: String, b: String| format!("  {name:<13} {a:<28} {b}\n");
        out += &row(
            "resonance",
            list(&self.figures.resonances_hz),
            list(&m.resonances_hz),
        );
        out += &row(
            "antiresonance",
            list(&self.figures.antiresonances_hz),
            list(&m.antiresonances_hz),
        );
        if let Some(r) = self.search_resolution {
            out += &format!(
                "  located       by a search on the {} to ±{:.2} % (each frequency settled {:.2} s)\n",
                self.plant,
                50.0 * r,
                self.settle_s
            );
        }
        out += &row(
            "bandwidth",
            opt(self.figures.bandwidth_hz, 1, "Hz (−3 dB)"),
            opt(m.bandwidth_hz, 1, "Hz"),
        );
        let at = |v: Option<f64>, f: Option<f64>, unit: &str| match (v, f) {
            (Some(v), Some(f)) => format!("{v:.1} {unit} at {f:.1} Hz"),
            _ => "—".into(),
        };
        out += &row(
            "gain margin",
            at(
                self.figures.gain_margin_db,
                self.figures.phase_crossover_hz,
                "dB",
            ),
            at(m.gain_margin_db, m.phase_crossover_hz, "dB"),
        );
        out += &row(
            "phase margin",
            at(
                self.figures.phase_margin_deg,
                self.figures.gain_crossover_hz,
                "°",
            ),
            at(m.phase_margin_deg, m.gain_crossover_hz, "°"),
        );
        out += "  f (Hz)   gain (dB)  phase (°)  coherence   model gain  model phase   open loop |L| (dB), ∠L (°)\n";
        let n = self.frequencies_hz.len();
        let mut last = f64::NEG_INFINITY;
        for i in 0..n {
            let f = self.frequencies_hz[i];
            if f.log10() - last < 0.3 && i + 1 != n {
                continue;
            }
            last = f.log10();
            let p = &self.model_at_points;
            let ol = &self.open_loop;
            let open = if ol.frequencies_hz.len() == n {
                format!("{:8.2} {:8.1}", ol.magnitude_db[i], ol.phase_deg[i])
            } else {
                String::new()
            };
            out += &format!(
                "  {:7.2} {:9.2} {:10.1} {:10.4} {:12.2} {:12.1}   {open}\n",
                f,
                self.magnitude_db[i],
                self.phase_deg[i],
                self.coherence[i],
                p.magnitude_db[i],
                p.phase_deg[i],
            );
        }
        for note in &self.notes {
            out += &format!("  note: {note}\n");
        }
        out += &format!(
            "  {:.1} s simulated in {:.2} s\n",
            self.simulated_time_s, self.wall_time_s
        );
        out
    }

    /// The points as CSV: frequency, measured and model magnitude and phase, coherence, open
    /// loop.
    pub fn csv(&self) -> String {
        let mut out = String::from("frequency_hz,magnitude_db,phase_deg,coherence,model_magnitude_db,model_phase_deg,open_loop_magnitude_db,open_loop_phase_deg\n");
        for i in 0..self.frequencies_hz.len() {
            let ol = |v: &Vec<f64>| v.get(i).map_or(String::new(), |x| format!("{x}"));
            out += &format!(
                "{},{},{},{},{},{},{},{}\n",
                self.frequencies_hz[i],
                self.magnitude_db[i],
                self.phase_deg[i],
                self.coherence[i],
                self.model_at_points.magnitude_db[i],
                self.model_at_points.phase_deg[i],
                ol(&self.open_loop.magnitude_db),
                ol(&self.open_loop.phase_deg),
            );
        }
        out
    }

    /// The response as series in a Rerun recording, on a `frequency_mhz` timeline (the
    /// frequency in millihertz, so the viewer's time axis is the frequency axis): measured
    /// magnitude, phase and coherence, the model's magnitude and phase, the open loop; the
    /// figures as a text document.
    pub fn write_recording(&self, path: &Path) -> Result<(), ReportError> {
        let fail = |e: &dyn std::fmt::Display| ReportError::Recording {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let rec = rerun::RecordingStreamBuilder::new("cncsim")
            .recording_name(format!(
                "bode: {} {} {}",
                self.scenario, self.axis, self.loop_name
            ))
            .save(path)
            .map_err(|e| fail(&e))?;
        let base = format!("bode/{}/{}", self.axis, self.loop_name);
        let names = [
            ("magnitude_db/measured", "measured |H| (dB)"),
            ("magnitude_db/model", "model |H| (dB)"),
            ("phase_deg/measured", "measured ∠H (°)"),
            ("phase_deg/model", "model ∠H (°)"),
            ("coherence", "coherence γ²"),
            ("open_loop_db/measured", "measured |L| (dB)"),
            ("open_loop_deg/measured", "measured ∠L (°)"),
            ("open_loop_db/model", "model |L| (dB)"),
            ("open_loop_deg/model", "model ∠L (°)"),
        ];
        for (entity, name) in names {
            let style = if entity.ends_with("model") {
                rec.log_static(
                    format!("{base}/{entity}"),
                    &rerun::SeriesLines::new().with_names([name]),
                )
            } else {
                rec.log_static(
                    format!("{base}/{entity}"),
                    &rerun::SeriesPoints::new().with_names([name]),
                )
            };
            style.map_err(|e| fail(&e))?;
        }
        let log = |f: f64, entity: &str, v: f64| -> Result<(), ReportError> {
            if !v.is_finite() {
                return Ok(());
            }
            rec.set_time_sequence("frequency_mhz", (f * 1e3).round() as i64);
            rec.log(format!("{base}/{entity}"), &rerun::Scalars::new([v]))
                .map_err(|e| fail(&e))
        };
        for i in 0..self.frequencies_hz.len() {
            let f = self.frequencies_hz[i];
            log(f, "magnitude_db/measured", self.magnitude_db[i])?;
            log(f, "phase_deg/measured", self.phase_deg[i])?;
            log(f, "coherence", self.coherence[i])?;
            if let (Some(m), Some(p)) = (
                self.open_loop.magnitude_db.get(i),
                self.open_loop.phase_deg.get(i),
            ) {
                log(f, "open_loop_db/measured", *m)?;
                log(f, "open_loop_deg/measured", *p)?;
            }
        }
        for (i, &f) in self.model.frequencies_hz.iter().enumerate() {
            log(f, "magnitude_db/model", self.model.magnitude_db[i])?;
            log(f, "phase_deg/model", self.model.phase_deg[i])?;
        }
        for (i, &f) in self.model_open_loop.frequencies_hz.iter().enumerate() {
            log(
                f,
                "open_loop_db/model",
                self.model_open_loop.magnitude_db[i],
            )?;
            log(f, "open_loop_deg/model", self.model_open_loop.phase_deg[i])?;
        }
        rec.log_static(
            format!("{base}/figures"),
            &rerun::TextDocument::new(format!("```\n{}\n```", self.text()))
                .with_media_type(rerun::MediaType::markdown()),
        )
        .map_err(|e| fail(&e))?;
        rec.flush_blocking().map_err(|e| fail(&e))?;
        Ok(())
    }

    /// Writes the Bode plot: magnitude above, phase below, on a log frequency axis; the
    /// measured points as dots (filled where the coherence is at least [`MIN_COHERENCE`],
    /// hollow below it), the linear model as a line; the open loop beside the main response
    /// when it was measured; resonances, bandwidth and margins marked and listed.
    pub fn write_plot(&self, path: &Path) -> Result<(), ReportError> {
        render(path, |pixels| self.draw(pixels))
    }

    fn draw(&self, pixels: &mut [u8]) -> DrawResult<()> {
        use plotters::prelude::*;
        let root = BitMapBackend::with_buffer(pixels, PLOT_SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, bottom) = root.split_vertically(PLOT_SIZE.1 / 2 + 20);
        let ((fmin, fmax), mags, phases) = self.extents();
        let fr = (fmin * 0.9)..(fmax * 1.1);
        let main = RGBColor(31, 119, 180);
        let open = RGBColor(214, 39, 40);
        let grey = RGBColor(150, 150, 150);
        let caption = format!(
            "Bode: {} axis {}, {} loop, measured on {} ({})",
            self.scenario, self.axis, self.loop_name, self.plant, self.excitation
        );
        let mut mag_chart = ChartBuilder::on(&top)
            .caption(caption, (FAMILY, 22))
            .margin(12)
            .x_label_area_size(10)
            .y_label_area_size(70)
            .build_cartesian_2d(fr.clone().log_scale(), span(mags, 5.0))?;
        mag_chart
            .configure_mesh()
            .y_desc(format!("magnitude ({})", self.magnitude_unit))
            .x_label_formatter(&|_| String::new())
            .y_label_formatter(&|v| format!("{v:.0}"))
            .label_style((FAMILY, 15))
            .axis_desc_style((FAMILY, 16))
            .draw()?;
        let mut phase_chart = ChartBuilder::on(&bottom)
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(fr.log_scale(), span(phases, 15.0))?;
        phase_chart
            .configure_mesh()
            .x_desc("frequency (Hz)")
            .y_desc("phase (°)")
            .x_label_formatter(&|v| format!("{v}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .label_style((FAMILY, 15))
            .axis_desc_style((FAMILY, 16))
            .draw()?;
        // Model lines.
        mag_chart
            .draw_series(LineSeries::new(
                line(&self.model, true),
                main.stroke_width(2),
            ))?
            .label(format!("{} — linear model", self.response))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 24, y)], main.stroke_width(2)));
        phase_chart.draw_series(LineSeries::new(
            line(&self.model, false),
            main.stroke_width(2),
        ))?;
        {
            mag_chart
                .draw_series(LineSeries::new(
                    line(&self.model_open_loop, true),
                    open.stroke_width(2),
                ))?
                .label("open loop L at the plant input — linear model")
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 24, y)], open.stroke_width(2))
                });
            phase_chart.draw_series(LineSeries::new(
                line(&self.model_open_loop, false),
                open.stroke_width(2),
            ))?;
        }
        // Measured points: filled where coherent.
        for (curve, colour, label) in [
            (None, main, format!("{} — measured", self.response)),
            (
                Some(&self.open_loop),
                open,
                "open loop L — measured".to_string(),
            ),
        ] {
            if curve.is_some_and(|c| c.frequencies_hz.is_empty()) {
                continue;
            }
            let style = |filled: bool| {
                if filled {
                    colour.filled()
                } else {
                    colour.stroke_width(1)
                }
            };
            mag_chart
                .draw_series(
                    self.points(true, curve)
                        .into_iter()
                        .map(|(f, v, c)| Circle::new((f, v), 4, style(c))),
                )?
                .label(label)
                .legend(move |(x, y)| Circle::new((x + 12, y), 4, colour.filled()));
            phase_chart.draw_series(
                self.points(false, curve)
                    .into_iter()
                    .map(|(f, v, c)| Circle::new((f, v), 4, style(c))),
            )?;
        }
        // Reference lines: 0 dB, −3 dB, −180°; resonances and crossovers.
        let (f0, f1) = (fmin * 0.9, fmax * 1.1);
        for (level, style) in [(0.0, grey.stroke_width(1)), (-3.0, grey.stroke_width(1))] {
            mag_chart.draw_series(LineSeries::new([(f0, level), (f1, level)], style))?;
        }
        phase_chart.draw_series(LineSeries::new(
            [(f0, -180.0), (f1, -180.0)],
            grey.stroke_width(1),
        ))?;
        let vertical = |f: f64| [(f, -1e6), (f, 1e6)];
        for &f in &self.figures.resonances_hz {
            mag_chart.draw_series(LineSeries::new(vertical(f), BLACK.mix(0.5).stroke_width(1)))?;
        }
        for &f in &self.figures.antiresonances_hz {
            mag_chart.draw_series(LineSeries::new(vertical(f), grey.mix(0.8).stroke_width(1)))?;
        }
        mag_chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .label_font((FAMILY, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        // The figures, top right.
        let lines = self.figure_lines();
        let mut y = 42;
        for text in lines {
            top.draw(&Text::new(
                text,
                (PLOT_SIZE.0 as i32 - 560, y),
                (FAMILY, 14).into_font().color(&BLACK),
            ))?;
            y += 19;
        }
        root.present()?;
        Ok(())
    }

    /// The figures as the plot lists them, top right.
    fn figure_lines(&self) -> [String; 6] {
        let m = &self.model_figures;
        [
            format!(
                "resonance {}   (model {})",
                list(&self.figures.resonances_hz),
                list(&m.resonances_hz)
            ),
            format!(
                "antiresonance {}   (model {})",
                list(&self.figures.antiresonances_hz),
                list(&m.antiresonances_hz)
            ),
            format!(
                "bandwidth −3 dB {}   (model {})",
                opt(self.figures.bandwidth_hz, 1, "Hz"),
                opt(m.bandwidth_hz, 1, "Hz")
            ),
            format!(
                "gain margin {} at {}   (model {})",
                opt(self.figures.gain_margin_db, 1, "dB"),
                opt(self.figures.phase_crossover_hz, 1, "Hz"),
                opt(m.gain_margin_db, 1, "dB")
            ),
            format!(
                "phase margin {} at {}   (model {})",
                opt(self.figures.phase_margin_deg, 1, "°"),
                opt(self.figures.gain_crossover_hz, 1, "Hz"),
                opt(m.phase_margin_deg, 1, "°")
            ),
            "dots: measured (hollow: coherence < 0.8); lines: linear model".to_string(),
        ]
    }

    /// The measured points of the main response (`curve` None) or of a curve, magnitude or
    /// phase: (frequency, value, coherent).
    fn points(&self, mag: bool, curve: Option<&Curve>) -> Vec<(f64, f64, bool)> {
        let (f, v) = match curve {
            None => (
                &self.frequencies_hz,
                if mag {
                    &self.magnitude_db
                } else {
                    &self.phase_deg
                },
            ),
            Some(c) => (
                &c.frequencies_hz,
                if mag { &c.magnitude_db } else { &c.phase_deg },
            ),
        };
        f.iter()
            .zip(v)
            .zip(&self.coherence)
            .filter(|((_, v), _)| v.is_finite())
            .map(|((f, v), c)| (*f, *v, *c >= MIN_COHERENCE))
            .collect()
    }

    /// The plot's frequency range and the finite magnitudes and phases it shows.
    fn extents(&self) -> ((f64, f64), Vec<f64>, Vec<f64>) {
        let f_all = self
            .frequencies_hz
            .iter()
            .chain(&self.model.frequencies_hz)
            .copied();
        let range = f_all.fold((f64::INFINITY, 0.0f64), |(a, b), f| (a.min(f), b.max(f)));
        let finite = |v: &[f64]| {
            v.iter()
                .copied()
                .filter(|x| x.is_finite())
                .collect::<Vec<_>>()
        };
        let mut mags = finite(&self.magnitude_db);
        mags.extend(finite(&self.model.magnitude_db));
        mags.extend(finite(&self.open_loop.magnitude_db));
        mags.extend(finite(&self.model_open_loop.magnitude_db));
        let mut phases = finite(&self.phase_deg);
        phases.extend(finite(&self.model.phase_deg));
        phases.extend(finite(&self.open_loop.phase_deg));
        phases.extend(finite(&self.model_open_loop.phase_deg));
        (range, mags, phases)
    }
}
