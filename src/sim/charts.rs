//! The study's charts ([`Chart`] data): NEES, RMSE, ω and COIN against time, one line per
//! estimator in the colours of the rule registry.

use crate::chart::{Axis, Band, Chart, Line};

use super::{Estimator, StudyConfig, StudyRule, StudySummary};

/// The size of each study chart's SVG file (`nmci track`'s `nees.svg`, …, and the page's
/// exports of the same charts).
pub const STUDY_SVG_SIZE: (u32, u32) = (900, 480);

/// A per-step series file (`nees.csv`, `rmse.csv`, `two_sigma.csv`, `coin.csv`): a row per step
/// (`step`, `time` = step·`dt`), a column per estimator, every value as Rust prints it (so it
/// reads back to the same bits). What `nmci track` writes and the page exports.
pub fn series_csv(series: &[Vec<f64>], dt: f64) -> String {
    let names: Vec<&str> = super::estimators().map(|e| e.name()).collect();
    let mut csv = format!("step,time,{}\n", names.join(","));
    for k in 0..series.first().map_or(0, Vec::len) {
        let row: Vec<String> = series.iter().map(|s| s[k].to_string()).collect();
        csv += &format!("{},{},{}\n", k + 1, (k + 1) as f64 * dt, row.join(","));
    }
    csv
}

/// `#rrggbb` of `(r, g, b)`.
fn hex((r, g, b): (u8, u8, u8)) -> String {
    format!("#{r:02x}{g:02x}{b:02x}")
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
    let (ci, ici) = (StudyRule::Ci.method(), StudyRule::Ici.method());
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
