//! The charts (src/chart/): they describe exactly the numbers of the study and of fig. 2,
//! they are drawn point for point (a non-finite value breaks a line), and the CLI's SVG files
//! are this code's drawing — the page draws the same `Chart` objects on a canvas (checked by
//! the page's end-to-end test).

use nmci::study::{estimators, run_study, StudyConfig};
use nmci::{
    chart::{charts_svg, Axis, Chart, Line},
    fig2::{fig2_charts, fig2_run, fig2_summary, Fig2Config},
    study::study_charts,
};

/// The point counts of the SVG's polylines stroked in `colour` (plotters draws each line
/// segment, and each legend sample, as one), sorted.
fn polylines(svg: &str, colour: &str) -> Vec<usize> {
    let mut counts: Vec<usize> = svg
        .split("<polyline")
        .skip(1)
        .filter(|p| p.contains(&format!("stroke=\"{colour}\"")))
        .map(|p| {
            let start = p.find("points=\"").expect("a polyline has points") + 8;
            let end = start + p[start..].find('"').unwrap();
            p[start..end].split_whitespace().count()
        })
        .collect();
    counts.sort_unstable();
    counts
}

fn small_study() -> StudyConfig {
    StudyConfig {
        runs: 2,
        steps: 12,
        seed: 5,
        coin: true,
        ..StudyConfig::default()
    }
}

#[test]
fn study_charts_carry_the_summary_series_at_their_times() {
    let config = small_study();
    let (summary, _) = run_study(&config).unwrap();
    let charts = study_charts(&config, &summary, config.runs);
    let names: Vec<&str> = charts.iter().map(|c| c.0).collect();
    assert_eq!(names, ["nees", "rmse", "omega", "coin"]);
    let dt = config.scenario.dt;
    let all: Vec<_> = estimators().collect();
    let charted: Vec<usize> = (0..all.len()).filter(|&s| all[s].charted()).collect();
    assert_eq!(charted.len(), all.len() - 1, "naive fusion is left off");
    let at = |series: &[f64]| -> Vec<(f64, f64)> {
        series
            .iter()
            .enumerate()
            .map(|(k, &v)| ((k + 1) as f64 * dt, v))
            .collect()
    };
    for (name, chart) in &charts {
        assert_eq!(
            chart.x.range,
            Some((0.0, config.steps as f64 * dt)),
            "{name}"
        );
        match *name {
            "nees" | "coin" => {
                let series = if *name == "nees" {
                    &summary.nees_series
                } else {
                    &summary.coin_series
                };
                assert_eq!(chart.lines.len(), charted.len(), "{name}");
                for (line, &s) in chart.lines.iter().zip(&charted) {
                    assert_eq!(line.label.as_deref(), Some(all[s].label().as_str()));
                    assert_eq!(line.colour, all[s].colour());
                    assert_eq!(line.points, at(&series[s]), "{name} of {}", all[s].name());
                }
            }
            "rmse" => {
                assert_eq!(chart.lines.len(), 2 * charted.len());
                for (pair, &s) in chart.lines.chunks(2).zip(&charted) {
                    assert_eq!(pair[0].points, at(&summary.rmse_series[s]));
                    assert_eq!(pair[1].points, at(&summary.two_sigma_series[s]));
                    assert!(!pair[0].dashed && pair[1].dashed);
                }
            }
            _ => {
                let blocks = summary.omega_nmci_series.len();
                assert_eq!(blocks, 8);
                assert_eq!(chart.lines.len(), blocks + 2);
                assert_eq!(chart.lines[0].points, at(&summary.omega_ci_series));
                for b in 0..blocks {
                    assert_eq!(chart.lines[b + 1].points, at(&summary.omega_nmci_series[b]));
                }
                assert_eq!(
                    chart.lines[blocks + 1].points,
                    at(&summary.omega_ici_series)
                );
            }
        }
    }
    // The NEES chart's band is the χ² interval.
    let nees = &charts[0].1;
    let (lo, hi) = summary.nees_bounds;
    assert_eq!(
        (nees.bands[0].lower.clone(), nees.bands[0].upper.clone()),
        (vec![lo, lo], vec![hi, hi])
    );
    // Without COIN there is no COIN chart.
    let (plain, _) = run_study(&StudyConfig {
        coin: false,
        ..config.clone()
    })
    .unwrap();
    assert_eq!(study_charts(&config, &plain, 2).len(), 3);
}

#[test]
fn every_line_is_drawn_point_for_point_and_a_nan_breaks_it() {
    let line = |label: &str, points: Vec<(f64, f64)>| Line {
        label: Some(label.into()),
        colour: "#d62728".into(),
        width: 2,
        dashed: false,
        dots: false,
        points,
    };
    let chart = Chart {
        title: "t".into(),
        x: Axis::default(),
        y: Axis::default(),
        bands: vec![],
        lines: vec![
            line(
                "whole",
                (0..7).map(|k| (k as f64, (k * k) as f64)).collect(),
            ),
            line(
                "broken",
                vec![
                    (0.0, 1.0),
                    (1.0, f64::NAN),
                    (2.0, 3.0),
                    (3.0, 4.0),
                    (4.0, f64::INFINITY),
                ],
            ),
        ],
    };
    assert_eq!(chart.drawn_points(), [7, 3]);
    let svg = charts_svg(&[&chart], (560, 300)).unwrap();
    // Two legend samples (2 points each), the whole line (7), the broken line's runs (1 and
    // 2); the run of one point is drawn as a dot too.
    assert_eq!(polylines(&svg, "#D62728"), [1, 2, 2, 2, 7], "{svg}");
    assert_eq!(svg.matches("<circle").count(), 1, "{svg}");
    assert!(svg.contains("whole") && svg.contains("broken"));
    // On a log axis values ≤ 0 are left out.
    let log = Chart {
        y: Axis {
            log: true,
            ..Axis::default()
        },
        lines: vec![line(
            "log",
            vec![(0.0, 1.0), (1.0, 0.0), (2.0, 10.0), (3.0, 100.0)],
        )],
        ..chart
    };
    assert_eq!(log.drawn_points(), [3]);
    assert_eq!(
        polylines(&charts_svg(&[&log], (560, 300)).unwrap(), "#D62728"),
        [1, 2, 2]
    );
}

#[test]
fn fig2_charts_carry_the_rows_median_min_and_max() {
    let config = Fig2Config {
        runs: 3,
        sizes: vec![1, 10, 50],
        seed: 2,
    };
    let runs: Vec<_> = (0..config.runs)
        .map(|r| fig2_run(&config, r).unwrap())
        .collect();
    let rows = fig2_summary(&config, &runs);
    let [dev, eig] = fig2_charts(&rows, config.runs);
    assert!(dev.x.log && dev.y.log && eig.x.log && !eig.y.log);
    let x: Vec<f64> = rows.iter().map(|r| r.samples as f64).collect();
    let col = |pick: &dyn Fn(&nmci::fig2::Fig2Row) -> [f64; 3], k: usize| -> Vec<f64> {
        rows.iter().map(|r| pick(r)[k]).collect()
    };
    let median = |pick: &dyn Fn(&nmci::fig2::Fig2Row) -> [f64; 3]| -> Vec<(f64, f64)> {
        x.iter().copied().zip(col(pick, 0)).collect()
    };
    assert_eq!(dev.lines[0].points, median(&|r| r.dev));
    assert_eq!(
        (dev.bands[0].lower.clone(), dev.bands[0].upper.clone()),
        (col(&|r| r.dev, 1), col(&|r| r.dev, 2))
    );
    // The zero line, then the SDP's and nmCI's medians (with dots), bands min to max.
    assert!(eig.lines[0].points.iter().all(|p| p.1 == 0.0) && eig.lines[0].label.is_none());
    assert_eq!(eig.lines[1].points, median(&|r| r.eig_opt));
    assert_eq!(eig.lines[2].points, median(&|r| r.eig_nmci));
    assert!(eig.lines[1].dots && eig.lines[2].dots);
    assert_eq!(eig.bands[1].lower, col(&|r| r.eig_nmci, 1));
    assert_eq!(eig.bands[0].upper, col(&|r| r.eig_opt, 2));
    assert!(dev.title.contains("over 3 runs"));
}
