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
    /// The legend entry (the variant's name).
    pub label: &'a str,
    /// Sample times (s).
    pub time: &'a [f64],
    /// Contour error at each time (m).
    pub contour_error: &'a [f64],
}

const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
pub(super) const FAMILY: &str = "sans-serif";

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
    render(path, |pixels| draw(pixels, series))
}

pub(super) type DrawResult<T> = Result<T, Box<dyn std::error::Error>>;

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

/// One bar group's values per series: (low, value, high); low/high draw a whisker where they
/// differ from the value (e.g. the spread over a grid).
pub struct BarSeries {
    /// The legend entry.
    pub label: String,
    /// Per group, in the groups' order: (low, value, high); `None` draws no bar.
    pub values: Vec<Option<(f64, f64, f64)>>,
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// Writes `pixels` (RGB, [`PLOT_SIZE`]) as a PNG.
/// Draws a plot of `PLOT_SIZE` on white with `draw` and writes it to `path` as PNG.
pub(super) fn render(
    path: &Path,
    draw: impl FnOnce(&mut [u8]) -> DrawResult<()>,
) -> Result<(), ReportError> {
    register_font();
    let (w, h) = PLOT_SIZE;
    let mut pixels = vec![255u8; (w * h * 3) as usize];
    draw(&mut pixels).map_err(|e| drawing_error(path, e))?;
    write_png(path, &pixels)
}

fn write_png(path: &Path, pixels: &[u8]) -> Result<(), ReportError> {
    let (w, h) = PLOT_SIZE;
    let io = |source| ReportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::create(path).map_err(io)?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder
        .write_header()
        .and_then(|mut writer| writer.write_image_data(pixels))
        .map_err(|e| io(std::io::Error::other(e)))
}

fn drawing_error(path: &Path, e: Box<dyn std::error::Error>) -> ReportError {
    ReportError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(format!("drawing the plot: {e}")),
    }
}

/// Grouped bars: one group per entry of `groups` (e.g. scenarios), one bar per series (e.g.
/// variants), on a logarithmic axis when the values span more than two decades.
pub fn write_bar_plot(
    path: &Path,
    title: &str,
    y_label: &str,
    groups: &[String],
    series: &[BarSeries],
) -> Result<(), ReportError> {
    render(path, |pixels| {
        draw_bars(pixels, title, y_label, groups, series)
    })
}

fn draw_bars(
    pixels: &mut [u8],
    title: &str,
    y_label: &str,
    groups: &[String],
    series: &[BarSeries],
) -> DrawResult<()> {
    let root = BitMapBackend::with_buffer(pixels, PLOT_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let values: Vec<f64> = series
        .iter()
        .flat_map(|s| s.values.iter().flatten().flat_map(|v| [v.0, v.1, v.2]))
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    let top = values.iter().copied().fold(0.0, f64::max);
    let bottom = values.iter().copied().fold(f64::INFINITY, f64::min);
    let log = bottom > 0.0 && top / bottom > 100.0;
    let n = series.len().max(1) as f64;
    let width = 0.8 / n;
    let x_range = -0.5..groups.len() as f64 - 0.5;
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(title, (FAMILY, 28))
        .margin(20)
        .x_label_area_size(60)
        .y_label_area_size(100);
    let bar = |g: usize, i: usize| {
        let x0 = g as f64 - 0.4 + i as f64 * width;
        (x0, x0 + width * 0.9)
    };
    let label_groups = |x: &f64| {
        let g = x.round();
        if (x - g).abs() < 1e-6 && g >= 0.0 && (g as usize) < groups.len() {
            groups[g as usize].clone()
        } else {
            String::new()
        }
    };
    macro_rules! bars {
        ($chart:expr, $floor:expr) => {{
            let chart = $chart;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_labels(groups.len().max(1))
                .x_label_formatter(&label_groups)
                .y_desc(y_label)
                .label_style((FAMILY, 18))
                .draw()?;
            for (i, s) in series.iter().enumerate() {
                let color = PALETTE[i % PALETTE.len()];
                let rects = s.values.iter().enumerate().filter_map(|(g, v)| {
                    let (_, mid, _) = (*v)?;
                    let (x0, x1) = bar(g, i);
                    Some(Rectangle::new(
                        [(x0, $floor), (x1, mid.max($floor))],
                        color.filled(),
                    ))
                });
                chart
                    .draw_series(rects)?
                    .label(s.label.clone())
                    .legend(move |(x, y)| {
                        Rectangle::new([(x, y - 6), (x + 18, y + 6)], color.filled())
                    });
                let whiskers = s.values.iter().enumerate().filter_map(|(g, v)| {
                    let (lo, _, hi) = (*v)?;
                    let (x0, x1) = bar(g, i);
                    let xm = 0.5 * (x0 + x1);
                    (hi > lo).then(|| {
                        PathElement::new(
                            [(xm, lo.max($floor)), (xm, hi.max($floor))],
                            BLACK.stroke_width(2),
                        )
                    })
                });
                chart.draw_series(whiskers)?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .label_font((FAMILY, 18))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()?;
        }};
    }
    if log {
        let floor = bottom / 2.0;
        let mut chart = builder.build_cartesian_2d(x_range, (floor..top * 2.0).log_scale())?;
        bars!(&mut chart, floor);
    } else {
        let top = if top > 0.0 { top * 1.1 } else { 1.0 };
        let mut chart = builder.build_cartesian_2d(x_range, 0.0..top)?;
        bars!(&mut chart, 0.0);
    }
    root.present()?;
    Ok(())
}

/// Lines of y against x, one per series (e.g. a metric against a swept value).
pub fn write_line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<(), ReportError> {
    render(path, |pixels| {
        draw_lines(pixels, title, x_label, y_label, series)
    })
}

fn draw_lines(
    pixels: &mut [u8],
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> DrawResult<()> {
    let root = BitMapBackend::with_buffer(pixels, PLOT_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let points: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.1.iter().copied())
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    let (x0, x1) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.0), b.max(p.0))
        });
    let y1 = points.iter().fold(0.0f64, |m, p| m.max(p.1));
    let y0 = points
        .iter()
        .map(|p| p.1)
        .filter(|y| *y > 0.0)
        .fold(f64::INFINITY, f64::min);
    let x_range = if x1 > x0 { x0..x1 } else { x0 - 1.0..x0 + 1.0 };
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(title, (FAMILY, 28))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(100);
    macro_rules! lines {
        ($chart:expr, $floor:expr, $y_desc:expr) => {{
            let chart = $chart;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc($y_desc)
                .label_style((FAMILY, 18))
                .draw()?;
            for (i, (label, pts)) in series.iter().enumerate() {
                let color = PALETTE[i % PALETTE.len()];
                let pts: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (x, y.max($floor))).collect();
                chart
                    .draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))?
                    .label(label.clone())
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 24, y)], color.stroke_width(3))
                    });
                chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .label_font((FAMILY, 18))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()?;
        }};
    }
    // Values spanning more than two decades: a logarithmic y axis, so the small ones show.
    if y0 > 0.0 && y1 / y0 > 100.0 {
        let floor = y0 / 2.0;
        let mut chart = builder.build_cartesian_2d(x_range, (floor..y1 * 2.0).log_scale())?;
        lines!(&mut chart, floor, format!("{y_label} (log scale)"));
    } else {
        let top = if y1 > 0.0 { y1 * 1.1 } else { 1.0 };
        let mut chart = builder.build_cartesian_2d(x_range, 0.0..top)?;
        lines!(&mut chart, 0.0, y_label.to_string());
    }
    root.present()?;
    Ok(())
}
