//! The A/B contour-error plot: contour error over time of every variant, as a PNG.
//!
//! Text is rasterised by plotters' pure-Rust `ab_glyph` backend from a bundled font (DejaVu
//! Sans, `assets/fonts/`), so no system font library is needed; the pixels are encoded by the
//! `png` crate.

use super::ReportError;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// Size of the written image (pixels).
pub const PLOT_SIZE: (u32, u32) = (1280, 720);

/// One curve: a label, sample times (s) and contour error (m) at those times.
pub struct ContourSeries<'a> {
    pub label: &'a str,
    pub time: &'a [f64],
    pub contour_error: &'a [f64],
}

const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is compiled in and known good; a failure here is a build defect.
        if plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_err() {
            panic!("the bundled font assets/fonts/DejaVuSans.ttf is not a valid font");
        }
    });
}

/// Writes contour error (µm) against time (s) of every series to `path`. When the largest
/// errors of the series differ more than tenfold the y axis is logarithmic, so that the better
/// variant is not a flat line at zero.
pub fn write_contour_error_plot(
    path: &Path,
    series: &[ContourSeries<'_>],
) -> Result<(), ReportError> {
    register_font();
    let (w, h) = PLOT_SIZE;
    let mut pixels = vec![255u8; (w * h * 3) as usize];
    draw(&mut pixels, series).map_err(|e| ReportError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(format!("drawing the plot: {e}")),
    })?;
    let io = |source| ReportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::create(path).map_err(io)?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let encoded = encoder
        .write_header()
        .and_then(|mut writer| writer.write_image_data(&pixels));
    encoded.map_err(|e| io(std::io::Error::other(e)))
}

type DrawResult<T> = Result<T, Box<dyn std::error::Error>>;

fn draw(pixels: &mut [u8], series: &[ContourSeries<'_>]) -> DrawResult<()> {
    let root = BitMapBackend::with_buffer(pixels, PLOT_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let um = |m: f64| m * 1e6;
    let t_end = series
        .iter()
        .filter_map(|s| s.time.last().copied())
        .fold(0.0, f64::max);
    let t_start = series
        .iter()
        .filter_map(|s| s.time.first().copied())
        .fold(t_end, f64::min);
    let t_range = if t_end > t_start {
        t_start..t_end
    } else {
        t_start..t_start + 1.0
    };
    let peaks: Vec<f64> = series
        .iter()
        .map(|s| s.contour_error.iter().copied().map(um).fold(0.0, f64::max))
        .collect();
    let top = peaks.iter().copied().fold(0.0, f64::max);
    let bottom = peaks.iter().copied().fold(f64::INFINITY, f64::min);
    let log = bottom > 0.0 && top / bottom > 10.0;
    let caption = "Contour error";
    let y_label = if log {
        "contour error (µm, log scale)"
    } else {
        "contour error (µm)"
    };
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(caption, (FAMILY, 28))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(90);
    if log {
        // Floor three decades below the better variant's peak: exact zeros stay on the chart.
        let floor = bottom * 1e-3;
        let mut chart = builder.build_cartesian_2d(t_range, (floor..top * 1.5).log_scale())?;
        curves(&mut chart, series, y_label, floor)?;
    } else {
        let top = if top > 0.0 { top * 1.05 } else { 1.0 };
        let mut chart = builder.build_cartesian_2d(t_range, 0.0..top)?;
        curves(&mut chart, series, y_label, 0.0)?;
    }
    root.present()?;
    Ok(())
}

/// Mesh, one line per series (µm, clamped up to `floor`) and the legend, on either y scale.
fn curves<'a, DB, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<plotters::coord::types::RangedCoordf64, Y>>,
    series: &[ContourSeries<'_>],
    y_label: &str,
    floor: f64,
) -> DrawResult<()>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    Y: Ranged<ValueType = f64> + plotters::coord::ranged1d::ValueFormatter<f64>,
{
    let colors = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
    ];
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc(y_label)
        .label_style((FAMILY, 18))
        .draw()?;
    for (i, s) in series.iter().enumerate() {
        let color = colors[i % colors.len()];
        let points = s
            .time
            .iter()
            .zip(s.contour_error)
            .map(|(&t, &e)| (t, (e * 1e6).max(floor)));
        chart
            .draw_series(LineSeries::new(points, color.stroke_width(2)))?
            .label(s.label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 24, y)], color.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FAMILY, 18))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
