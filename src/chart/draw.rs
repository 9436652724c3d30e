//! Drawing a [`Chart`] with plotters (feature `charts`): [`draw`] on any backend, [`charts_svg`]
//! as SVG text (the CLI's files, the page's exports). The layout is in the parent module's docs.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Axis, Chart, Line};
use crate::DrawError;

/// A `#rrggbb` colour (black for anything else; the registry's colours are checked by a test).
fn rgb(hex: &str) -> RGBColor {
    let byte = |i: usize| {
        hex.get(i..i + 2)
            .and_then(|h| u8::from_str_radix(h, 16).ok())
            .unwrap_or(0)
    };
    RGBColor(byte(1), byte(3), byte(5))
}

impl Chart {
    /// The range of one axis: fixed, or the finite (positive on a log axis) data padded.
    fn range(&self, axis: &Axis, values: impl Iterator<Item = f64>) -> (f64, f64) {
        if let Some(r) = axis.range {
            return r;
        }
        let (lo, hi) = values
            .filter(|v| v.is_finite() && (!axis.log || *v > 0.0))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        match (lo.is_finite(), axis.log) {
            (false, false) => (0.0, 1.0),
            (false, true) => (0.1, 10.0),
            (true, true) => (lo / 1.25, hi * 1.25),
            (true, false) => {
                let pad = 0.05 * (hi - lo).max(1e-12 * lo.abs().max(1.0));
                (lo - pad, hi + pad)
            }
        }
    }

    fn x_range(&self) -> (f64, f64) {
        let xs = self.lines.iter().flat_map(|l| l.points.iter().map(|p| p.0));
        let band_xs = self.bands.iter().flat_map(|b| b.x.iter().copied());
        self.range(&self.x, xs.chain(band_xs))
    }

    fn y_range(&self) -> (f64, f64) {
        let ys = self.lines.iter().flat_map(|l| l.points.iter().map(|p| p.1));
        let band_ys = self
            .bands
            .iter()
            .flat_map(|b| b.lower.iter().chain(&b.upper).copied());
        self.range(&self.y, ys.chain(band_ys))
    }

    /// The legend's entries: `(label, colour, dashed, filled)`.
    fn legend(&self) -> Vec<(&str, RGBColor, bool, bool)> {
        let bands = self
            .bands
            .iter()
            .filter_map(|b| Some((b.label.as_deref()?, rgb(&b.colour), false, true)));
        let lines = self
            .lines
            .iter()
            .filter_map(|l| Some((l.label.as_deref()?, rgb(&l.colour), l.dashed, false)));
        bands.chain(lines).collect()
    }

    /// The runs of consecutive visible points of a line (a non-finite value breaks it).
    fn segments<'a>(&'a self, line: &'a Line) -> impl Iterator<Item = Vec<(f64, f64)>> + 'a {
        line.points
            .split(move |p| !self.visible(*p))
            .filter(|s| !s.is_empty())
            .map(<[_]>::to_vec)
    }
}

/// Font sizes (pixels): the title, the axes' labels, the ticks and the legend.
const TITLE: u32 = 15;
const TEXT: u32 = 12;

/// Draws `chart` onto `area` (see the module docs for the layout); the caller presents the
/// root area once every chart on it is drawn.
pub fn draw<DB: DrawingBackend>(
    chart: &Chart,
    area: &DrawingArea<DB, Shift>,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    area.fill(&WHITE)?;
    let (width, _) = area.dim_in_pixel();
    let title_style = ("sans-serif", TITLE).into_font().color(&BLACK);
    let text_style = ("sans-serif", TEXT).into_font().color(&BLACK);
    // The title, wrapped at spaces to the width.
    let mut title_lines: Vec<String> = Vec::new();
    for word in chart.title.split(' ') {
        match title_lines.last_mut() {
            Some(line)
                if area
                    .estimate_text_size(&format!("{line} {word}"), &title_style)?
                    .0
                    <= width.saturating_sub(16) =>
            {
                line.push(' ');
                line.push_str(word);
            }
            _ => title_lines.push(word.to_string()),
        }
    }
    let title_height = TITLE as i32 + 4;
    for (k, line) in title_lines.iter().enumerate() {
        area.draw(&Text::new(
            line.clone(),
            (8, 4 + title_height * k as i32),
            title_style.clone(),
        ))?;
    }
    // The legend: entries laid out left to right, wrapped to the width.
    let legend = chart.legend();
    let row_height = TEXT as i32 + 6;
    let top = title_height * title_lines.len() as i32 + 6;
    let (mut x, mut y) = (8_i32, top);
    let mut placed = Vec::with_capacity(legend.len());
    for &(label, colour, dashed, filled) in &legend {
        let (w, _) = area.estimate_text_size(label, &text_style)?;
        let entry = 22 + w as i32 + 14;
        if x > 8 && x + entry > width as i32 - 4 {
            x = 8;
            y += row_height;
        }
        placed.push((x, y, label, colour, dashed, filled));
        x += entry;
    }
    let legend_bottom = if legend.is_empty() {
        top
    } else {
        y + row_height
    };
    for (x, y, label, colour, dashed, filled) in placed {
        let mid = y + row_height / 2 - 2;
        if filled {
            area.draw(&Rectangle::new(
                [(x, mid - 5), (x + 18, mid + 5)],
                colour.mix(0.3).filled(),
            ))?;
        } else if dashed {
            for k in 0..3 {
                area.draw(&PathElement::new(
                    [(x + 7 * k, mid), (x + 7 * k + 4, mid)],
                    colour.stroke_width(2),
                ))?;
            }
        } else {
            area.draw(&PathElement::new(
                [(x, mid), (x + 18, mid)],
                colour.stroke_width(2),
            ))?;
        }
        area.draw(&Text::new(label, (x + 22, y + 1), text_style.clone()))?;
    }
    let (_, plot) = area.split_vertically(legend_bottom as u32 + 2);
    let mut builder = ChartBuilder::on(&plot);
    builder
        .margin_right(12)
        .margin_bottom(4)
        .x_label_area_size(TEXT * 3)
        .y_label_area_size(TEXT * 5);
    let ((x0, x1), (y0, y1)) = (chart.x_range(), chart.y_range());
    macro_rules! body {
        ($cartesian:expr) => {{
            let mut c = $cartesian;
            c.configure_mesh()
                .x_desc(chart.x.label.as_str())
                .y_desc(chart.y.label.as_str())
                .label_style(("sans-serif", TEXT - 1))
                .axis_desc_style(("sans-serif", TEXT))
                .light_line_style(WHITE)
                .bold_line_style(BLACK.mix(0.08))
                .x_label_formatter(&|v| tick(*v, chart.x.log))
                .y_label_formatter(&|v| tick(*v, chart.y.log))
                .draw()?;
            for band in &chart.bands {
                let edge = |ys: &[f64]| -> Vec<(f64, f64)> {
                    band.x
                        .iter()
                        .zip(ys)
                        .map(|(&x, &y)| (x, y))
                        .filter(|&p| chart.visible(p))
                        .collect()
                };
                let (lower, upper) = (edge(&band.lower), edge(&band.upper));
                if lower.is_empty() || upper.is_empty() {
                    continue;
                }
                let polygon: Vec<(f64, f64)> =
                    upper.into_iter().chain(lower.into_iter().rev()).collect();
                c.draw_series(std::iter::once(Polygon::new(
                    polygon,
                    rgb(&band.colour).mix(band.opacity).filled(),
                )))?;
            }
            for line in &chart.lines {
                let style = rgb(&line.colour).stroke_width(line.width);
                for segment in chart.segments(line) {
                    if line.dashed {
                        c.draw_series(DashedLineSeries::new(segment.clone(), 5, 3, style))?;
                    } else {
                        c.draw_series(LineSeries::new(segment.clone(), style))?;
                    }
                    // A point alone between gaps draws no line: a dot shows it.
                    if line.dots || segment.len() == 1 {
                        c.draw_series(
                            segment
                                .iter()
                                .map(|&p| Circle::new(p, 2.5, rgb(&line.colour).filled())),
                        )?;
                    }
                }
            }
        }};
    }
    match (chart.x.log, chart.y.log) {
        (false, false) => body!(builder.build_cartesian_2d(x0..x1, y0..y1)?),
        (true, false) => body!(builder.build_cartesian_2d((x0..x1).log_scale(), y0..y1)?),
        (false, true) => body!(builder.build_cartesian_2d(x0..x1, (y0..y1).log_scale())?),
        (true, true) => {
            body!(builder.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?)
        }
    }
    Ok(())
}

/// A tick label: up to four decimals without trailing zeros; `1e-6` style on a log axis
/// away from 1.
fn tick(v: f64, log: bool) -> String {
    if log && (v.abs() < 1e-3 || v.abs() >= 1e5) {
        return format!("{v:.0e}");
    }
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// `charts` stacked vertically as one SVG document of width `width`, each `height` high —
/// what the CLI writes (`nees.svg`, `fig2.svg`, …).
///
/// ```
/// use nmci::chart::{Axis, Chart, Line};
/// let chart = Chart {
///     title: "a line".into(),
///     x: Axis { label: "x".into(), ..Axis::default() },
///     y: Axis { label: "y".into(), ..Axis::default() },
///     bands: vec![],
///     lines: vec![Line { label: Some("y = x²".into()), colour: "#d62728".into(), width: 2,
///         dashed: false, dots: false, points: (0..5).map(|k| (k as f64, (k * k) as f64)).collect() }],
/// };
/// let svg = nmci::chart::charts_svg(&[&chart], (560, 300)).unwrap();
/// assert!(svg.starts_with("<svg") && svg.contains("y = x²"));
/// ```
pub fn charts_svg(charts: &[&Chart], (width, height): (u32, u32)) -> Result<String, DrawError> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height * charts.len() as u32))
            .into_drawing_area();
        let areas = root.split_evenly((charts.len(), 1));
        for (chart, area) in charts.iter().zip(&areas) {
            draw(chart, area).map_err(|e| DrawError(e.to_string()))?;
        }
        root.present().map_err(|e| DrawError(e.to_string()))?;
    }
    Ok(svg)
}

/// Writes [`charts_svg`] into the file `path`.
#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn write_svg(
    path: &std::path::Path,
    charts: &[&Chart],
    size: (u32, u32),
) -> Result<(), crate::ReportError> {
    let svg = charts_svg(charts, size).map_err(|e| crate::ReportError::Draw {
        path: path.to_path_buf(),
        message: e.0,
    })?;
    std::fs::write(path, svg).map_err(|e| crate::ReportError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}
