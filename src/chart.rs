//! One chart code for every target: the study's and fig. 2's charts are described once
//! ([`Chart`]: lines, shaded bands, axes) by [`study_charts`] and [`fig2_charts`], and drawn
//! by one function, [`draw`], on any plotters backend — natively into the SVG files of
//! `nmci track`, `nmci merge` and `nmci fig2`, in the browser onto a `<canvas>` through
//! web-sys (`crate::wasm::draw_chart`, the backend in `src/wasm/canvas.rs`). The page's charts
//! and the files in `docs/figures` are therefore the same drawing of the same numbers.
//!
//! Layout (in the backend's pixels): the title and the legend, each wrapped to the width, then
//! the plot with its axes. Non-finite values break a line (and are left out of a band); on a
//! log axis values `≤ 0` are left out too. A point left alone between two gaps is drawn as a
//! dot, so every visible value shows.

use plotters::coord::Shift;
use plotters::prelude::*;
use serde::{Deserialize, Serialize};

use crate::sim::{Estimator, Rule, StudyConfig, StudySummary};
#[cfg(not(target_arch = "wasm32"))]
use crate::DrawError;
use crate::Fig2Row;

/// An axis: linear or logarithmic; its range fixed, or covering the data (padded).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Axis {
    /// The axis' label.
    pub label: String,
    /// Logarithmic scale (only positive values are drawn).
    #[serde(default)]
    pub log: bool,
    /// `(lo, hi)`; absent: the data's range, padded by 5 % (linear) or a factor 1.25 (log).
    #[serde(default)]
    pub range: Option<(f64, f64)>,
}

/// A polyline, optionally with a dot at each point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Line {
    /// Legend entry (none: not in the legend).
    pub label: Option<String>,
    /// `#rrggbb`.
    pub colour: String,
    /// Stroke width in pixels.
    pub width: u32,
    /// Dashed instead of solid.
    #[serde(default)]
    pub dashed: bool,
    /// A dot at each point.
    #[serde(default)]
    pub dots: bool,
    /// `(x, y)` points in order.
    pub points: Vec<(f64, f64)>,
}

/// A shaded region between `lower` and `upper` over `x`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Band {
    /// Legend entry (none: not in the legend).
    pub label: Option<String>,
    /// `#rrggbb`.
    pub colour: String,
    /// Fill opacity in `[0, 1]`.
    pub opacity: f64,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Lower edge at each abscissa.
    pub lower: Vec<f64>,
    /// Upper edge at each abscissa.
    pub upper: Vec<f64>,
}

/// A chart: bands drawn first, then lines in order (later lines on top).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Chart {
    /// Title above the legend.
    pub title: String,
    /// Horizontal axis.
    pub x: Axis,
    /// Vertical axis.
    pub y: Axis,
    /// Shaded bands.
    #[serde(default)]
    pub bands: Vec<Band>,
    /// Lines.
    #[serde(default)]
    pub lines: Vec<Line>,
}

/// A `#rrggbb` colour (black for anything else; the registry's colours are checked by a test).
fn rgb(hex: &str) -> RGBColor {
    let byte = |i: usize| {
        hex.get(i..i + 2)
            .and_then(|h| u8::from_str_radix(h, 16).ok())
            .unwrap_or(0)
    };
    RGBColor(byte(1), byte(3), byte(5))
}

/// `#rrggbb` of `(r, g, b)`.
fn hex((r, g, b): (u8, u8, u8)) -> String {
    format!("#{r:02x}{g:02x}{b:02x}")
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

    /// The points drawn of every line (finite, and positive on a log axis; see the module
    /// docs): what a test of a drawing checks.
    pub fn drawn_points(&self) -> Vec<usize> {
        self.lines
            .iter()
            .map(|l| l.points.iter().filter(|p| self.visible(**p)).count())
            .collect()
    }

    fn visible(&self, (x, y): (f64, f64)) -> bool {
        x.is_finite() && y.is_finite() && (!self.x.log || x > 0.0) && (!self.y.log || y > 0.0)
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

/// The study's charts, by name (`nees`, `rmse`, `omega`, and [`coin_chart`] when the summary
/// has COIN series), from a study's configuration and (possibly partial) summary. The time axis
/// covers the configured steps, so a study in progress fills it from the left.
pub fn study_charts(
    config: &StudyConfig,
    summary: &StudySummary,
    runs: usize,
) -> Vec<(&'static str, Chart)> {
    let dt = config.scenario.dt;
    let t_max = config.steps as f64 * dt;
    let time = || Axis {
        label: "time [s]".into(),
        log: false,
        range: Some((0.0, t_max)),
    };
    let at_steps = |values: &[f64]| at_steps(dt, values);
    // The estimators drawn ([`Estimator::charted`]).
    let shown: Vec<(usize, Estimator)> = crate::sim::estimators()
        .enumerate()
        .filter(|(_, e)| e.charted())
        .collect();
    let (lo, hi) = summary.nees_bounds;
    let mut charts = vec![
        (
            "nees",
            Chart {
                title: format!(
                    "NEES of agent {} ({runs} run{}, {} dof; naive fusion is off the scale)",
                    config.agent,
                    if runs == 1 { "" } else { "s" },
                    config.scenario.dim()
                ),
                x: time(),
                y: Axis {
                    label: "mean NEES".into(),
                    log: false,
                    range: Some((0.0, (2.0 * hi).max(10.0))),
                },
                bands: vec![Band {
                    label: Some("95 % χ² band".into()),
                    colour: "#2a9d3f".into(),
                    opacity: 0.15,
                    x: vec![0.0, t_max],
                    lower: vec![lo, lo],
                    upper: vec![hi, hi],
                }],
                lines: estimator_lines(dt, &summary.nees_series),
            },
        ),
        (
            "rmse",
            Chart {
                title: format!(
                    "position RMSE (solid) and 2σ (dashed) of agent {}, mean over runs",
                    config.agent
                ),
                x: time(),
                y: Axis {
                    label: "metres".into(),
                    ..Axis::default()
                },
                bands: Vec::new(),
                lines: shown
                    .iter()
                    .filter(|&&(s, _)| s < summary.rmse_series.len())
                    .flat_map(|&(s, e)| {
                        let line = |label: String, dashed, values: &[f64]| Line {
                            label: Some(label),
                            colour: e.colour().into(),
                            width: 2,
                            dashed,
                            dots: false,
                            points: at_steps(values),
                        };
                        [
                            line(
                                format!("{} RMSE", e.short_label()),
                                false,
                                &summary.rmse_series[s],
                            ),
                            line("2σ".into(), true, &summary.two_sigma_series[s]),
                        ]
                    })
                    .collect(),
            },
        ),
    ];
    // ω: CI's one weight, nmCI's per block (red to orange, y blocks dashed), ICI's.
    let blocks = summary.omega_nmci_series.len();
    let (ci, ici) = (Rule::Ci.method(), Rule::Ici.method());
    let mut omega = vec![Line {
        label: Some(ci.label().into()),
        colour: ci.info().colour.into(),
        width: 2,
        dashed: false,
        dots: false,
        points: at_steps(&summary.omega_ci_series),
    }];
    for (b, series) in summary.omega_nmci_series.iter().enumerate() {
        let shade = (200 * b / blocks.saturating_sub(1).max(1)) as u8;
        omega.push(Line {
            label: Some(format!(
                "G{}{}",
                b / 2 + 1,
                if b % 2 == 0 { "x" } else { "y" }
            )),
            colour: hex((214, shade, shade / 2)),
            width: 2,
            dashed: b % 2 == 1,
            dots: false,
            points: at_steps(series),
        });
    }
    omega.push(Line {
        label: Some(ici.label().into()),
        colour: ici.info().colour.into(),
        width: 2,
        dashed: false,
        dots: false,
        points: at_steps(&summary.omega_ici_series),
    });
    charts.push((
        "omega",
        Chart {
            title: format!(
                "ω when agent {} fuses agent {}: CI's, nmCI's per block (G1x … G{}y), ICI's",
                config.agent,
                config.watched,
                blocks.div_ceil(2)
            ),
            x: time(),
            y: Axis {
                label: "ω".into(),
                log: false,
                range: Some((-0.05, 1.05)),
            },
            bands: Vec::new(),
            lines: omega,
        },
    ));
    if !summary.coin_series.is_empty() {
        charts.push(("coin", coin_chart(config, &summary.coin_series)));
    }
    charts
}

/// The study's COIN chart (`coin.svg`) from every estimator's exact COIN series (in
/// [`crate::sim::estimators`] order; naive fusion is left off, as on the other charts).
pub fn coin_chart(config: &StudyConfig, coin_series: &[Vec<f64>]) -> Chart {
    let dt = config.scenario.dt;
    let t_max = config.steps as f64 * dt;
    Chart {
        title: format!(
            "exact COIN of agent {} (≤ 1: conservative; naive fusion is off the scale)",
            config.agent
        ),
        x: Axis {
            label: "time [s]".into(),
            log: false,
            range: Some((0.0, t_max)),
        },
        y: Axis {
            label: "COIN".into(),
            log: false,
            range: Some((0.0, 1.1)),
        },
        bands: vec![Band {
            label: Some("conservative".into()),
            colour: "#2a9d3f".into(),
            opacity: 0.1,
            x: vec![0.0, t_max],
            lower: vec![0.0, 0.0],
            upper: vec![1.0, 1.0],
        }],
        lines: estimator_lines(dt, coin_series),
    }
}

/// One line per charted estimator ([`Estimator::charted`]: naive fusion's NEES and COIN grow
/// by orders of magnitude, so it is left off; the CSV files and the table have it), its
/// `series` at the steps' times.
fn estimator_lines(dt: f64, series: &[Vec<f64>]) -> Vec<Line> {
    crate::sim::estimators()
        .zip(series)
        .filter(|(e, _)| e.charted())
        .map(|(e, values)| Line {
            label: Some(e.label()),
            colour: e.colour().into(),
            width: 2,
            dashed: false,
            dots: false,
            points: at_steps(dt, values),
        })
        .collect()
}

/// `values[k]` at time `(k + 1)·dt`.
fn at_steps(dt: f64, values: &[f64]) -> Vec<(f64, f64)> {
    values
        .iter()
        .enumerate()
        .map(|(k, &v)| ((k + 1) as f64 * dt, v))
        .collect()
}

/// Fig. 2's two charts from its summary rows over `runs` runs: `‖P_nmCI − P_opt‖₂` against
/// the sample-set size (log–log: median line with dots, min–max band), and
/// `λ_min(P − K P_true Kᵀ)` of nmCI and of the sampled SDP (the zero line dashed: below it,
/// not conservative for the true `P_ab`).
pub fn fig2_charts(rows: &[Fig2Row], runs: usize) -> [Chart; 2] {
    let sizes: Vec<f64> = rows.iter().map(|r| r.samples as f64).collect();
    let (x_lo, x_hi) = sizes
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    // Both charts on the same sample-size axis (the sizes, widened by a factor 1.25).
    let x_range = x_lo.is_finite().then_some((x_lo / 1.25, x_hi * 1.25));
    let x = || Axis {
        label: "samples N".into(),
        log: true,
        range: x_range,
    };
    let median_band = |label: &str, colour: &str, pick: &dyn Fn(&Fig2Row) -> [f64; 3]| {
        let col = |k: usize| rows.iter().map(|r| pick(r)[k]).collect::<Vec<f64>>();
        (
            Band {
                label: None,
                colour: colour.into(),
                opacity: 0.18,
                x: sizes.clone(),
                lower: col(1),
                upper: col(2),
            },
            Line {
                label: Some(label.into()),
                colour: colour.into(),
                width: 2,
                dashed: false,
                dots: true,
                points: sizes.iter().copied().zip(col(0)).collect(),
            },
        )
    };
    let (sdp, nmci) = (crate::Method::Sdp.info(), crate::Method::Nmci.info());
    let (dev_band, dev_line) = median_band("sampled SDP vs nmCI", sdp.colour, &|r| r.dev);
    let (opt_band, opt_line) = median_band(sdp.label, sdp.colour, &|r| r.eig_opt);
    let (nm_band, nm_line) = median_band(nmci.label, nmci.colour, &|r| r.eig_nmci);
    let zero = Line {
        label: None,
        colour: "#000000".into(),
        width: 1,
        dashed: true,
        dots: false,
        points: x_range.map_or(Vec::new(), |(lo, hi)| vec![(lo, 0.0), (hi, 0.0)]),
    };
    [
        Chart {
            title: format!("‖P_nmCI − P_opt‖₂ over {runs} runs (median; band: min to max)"),
            x: x(),
            y: Axis {
                label: "deviation".into(),
                log: true,
                range: None,
            },
            bands: vec![dev_band],
            lines: vec![dev_line],
        },
        Chart {
            title: "λ_min(P − K P_true Kᵀ): below 0 = not conservative for the true P_ab".into(),
            x: x(),
            y: Axis {
                label: "λ_min".into(),
                log: false,
                range: None,
            },
            bands: vec![opt_band, nm_band],
            lines: vec![zero, opt_line, nm_line],
        },
    ]
}

/// `charts` stacked vertically as one SVG document of width `width`, each `height` high —
/// what the CLI writes (`nees.svg`, `fig2.svg`, …).
///
/// ```
/// use nmci::{Axis, Chart, Line};
/// let chart = Chart {
///     title: "a line".into(),
///     x: Axis { label: "x".into(), ..Axis::default() },
///     y: Axis { label: "y".into(), ..Axis::default() },
///     bands: vec![],
///     lines: vec![Line { label: Some("y = x²".into()), colour: "#d62728".into(), width: 2,
///         dashed: false, dots: false, points: (0..5).map(|k| (k as f64, (k * k) as f64)).collect() }],
/// };
/// let svg = nmci::charts_svg(&[&chart], (560, 300)).unwrap();
/// assert!(svg.starts_with("<svg") && svg.contains("y = x²"));
/// ```
#[cfg(not(target_arch = "wasm32"))]
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
