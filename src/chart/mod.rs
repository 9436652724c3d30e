//! Charts as data, drawn one way on every target: a [`Chart`] (lines, shaded bands, axes) is
//! built by whoever owns the numbers (the study: `sim::study_charts`, `sim::coin_chart`;
//! fig. 2: `fig2_charts`) and drawn by one function, [`draw`] (feature `charts`), on any
//! plotters backend — natively into the SVG files of `nmci track`, `nmci merge` and
//! `nmci fig2`, in the browser onto a `<canvas>` through web-sys (`crate::wasm::draw_chart`,
//! the backend in `src/wasm/canvas.rs`). The page's charts and the files in `docs/figures` are
//! therefore the same drawing of the same numbers. This module knows no study and no figure.
//!
//! Layout (in the backend's pixels): the title and the legend, each wrapped to the width, then
//! the plot with its axes. Non-finite values break a line (and are left out of a band); on a
//! log axis values `≤ 0` are left out too. A point left alone between two gaps is drawn as a
//! dot, so every visible value shows.

use serde::{Deserialize, Serialize};

#[cfg(feature = "charts")]
mod draw;
#[cfg(feature = "charts")]
pub use draw::charts_svg;
#[cfg(feature = "charts")]
pub use draw::draw;
#[cfg(all(feature = "charts", not(target_arch = "wasm32")))]
pub(crate) use draw::write_svg;

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

impl Chart {
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
}
