//! A drawing of a scenario's network (SVG text), used by the CLI, the docs and the page.
//!
//! Groups sit on a circle (group 1 at the top left, then clockwise), each group's agents on a
//! small circle around its centre in ring order. Links inside a group are grey and straight;
//! links between groups are dark and bowed to one side, so links along one line stay apart
//! and do not run straight through the agents between their ends. The headline
//! agent (red) and the watched neighbour (blue) are filled.

use super::Scenario;
use std::fmt::Write;

/// The SVG of `scenario`'s network; `agent` and `watched` (1-based) are highlighted.
pub fn network_svg(scenario: &Scenario, agent: usize, watched: usize) -> String {
    let (groups, m) = (scenario.groups, scenario.agents_per_group);
    let size: f64 = 420.0;
    let centre = size / 2.0;
    let tau = std::f64::consts::TAU;
    let (big, small) = if groups == 1 {
        (0.0, 0.32 * size)
    } else {
        (
            0.3 * size,
            (0.13 * size).min(0.3 * size * (tau / groups as f64 / 2.0).sin() * 0.8),
        )
    };
    let place = |a: usize| -> (f64, f64) {
        let (g, k) = (a / m, a % m);
        let phase = -0.75 * std::f64::consts::PI;
        let gt = phase + tau * g as f64 / groups as f64;
        let (gx, gy) = (centre + big * gt.cos(), centre + big * gt.sin());
        let kt = phase + tau * k as f64 / m as f64;
        (gx + small * kt.cos(), gy + small * kt.sin())
    };
    let mut svg = String::new();
    let _ = write!(
        svg,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 {size} {size}\" width=\"{size}\" height=\"{size}\" font-family=\"sans-serif\" font-size=\"12\">\
         <rect width=\"{size}\" height=\"{size}\" fill=\"white\"/>"
    );
    for (a, b) in scenario.links() {
        let ((x1, y1), (x2, y2)) = (place(a), place(b));
        let between = a / m != b / m;
        let (colour, width) = if between {
            ("#1f2937", 2.2)
        } else {
            ("#9ca3af", 1.4)
        };
        // Links between groups bow to one side (a quadratic curve whose control point is
        // the midpoint moved by a fifth of the length, perpendicular) instead of running
        // straight through the agents that lie on the segment.
        let (dx, dy) = (x2 - x1, y2 - y1);
        let bow = if between { 0.2 } else { 0.0 };
        let (qx, qy) = ((x1 + x2) / 2.0 - bow * dy, (y1 + y2) / 2.0 + bow * dx);
        let _ = write!(
            svg,
            "<path d=\"M {x1:.1} {y1:.1} Q {qx:.1} {qy:.1} {x2:.1} {y2:.1}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"{width}\"/>"
        );
    }
    for g in 0..groups {
        let (cx, cy) = (0..m)
            .map(|k| place(g * m + k))
            .fold((0.0, 0.0), |(sx, sy), (x, y)| {
                (sx + x / m as f64, sy + y / m as f64)
            });
        let _ = write!(
            svg,
            "<text x=\"{cx:.1}\" y=\"{:.1}\" text-anchor=\"middle\" fill=\"#6b7280\">G{}</text>",
            cy + 4.0,
            g + 1
        );
    }
    for a in 0..scenario.agents() {
        let (x, y) = place(a);
        let id = a + 1;
        let fill = if id == agent {
            "#dc2626"
        } else if id == watched {
            "#2563eb"
        } else {
            "white"
        };
        let text = if id == agent || id == watched {
            "white"
        } else {
            "#111827"
        };
        let _ = write!(
            svg,
            "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"11\" fill=\"{fill}\" stroke=\"#111827\" stroke-width=\"1.2\"/>\
             <text x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\" fill=\"{text}\">{id}</text>",
            y + 4.0
        );
    }
    svg.push_str("</svg>\n");
    svg
}
