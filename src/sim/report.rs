//! The files of a study (native only): `summary.json`, per-step CSVs, SVG charts and the
//! network's drawing — what `nmci track` and `nmci merge` write, and Python's
//! `Study.write`.

use std::path::{Path, PathBuf};

use crate::error::ReportError;

use super::{
    estimators, network_svg, Candidate, Estimator, Rule, Study, StudyConfig, SweepConfig,
    SweepReport,
};

/// Writes a study's files into `out` (created if missing): `summary.json` (the
/// [`StudyReport`](super::StudyReport)), `nees.csv`, `rmse.csv`, `two_sigma.csv`, `coin.csv`
/// (per step, one column per estimator), `omega.csv` (per run and step), `nees.svg`,
/// `rmse.svg`, `omega.svg`, `coin.svg` and `network.svg`. Returns the files written.
pub fn write_study(study: &Study, out: &Path) -> Result<Vec<PathBuf>, ReportError> {
    let Study {
        config: cfg,
        traces,
        summary,
    } = study;
    let report = study.report();
    std::fs::create_dir_all(out).map_err(|e| ReportError::Create {
        path: out.to_path_buf(),
        message: e.to_string(),
    })?;
    let written = std::cell::RefCell::new(Vec::new());
    let write = |name: &str, text: String| {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| ReportError::Write {
            path: path.clone(),
            message: e.to_string(),
        })?;
        written.borrow_mut().push(path);
        Ok::<(), ReportError>(())
    };
    write(
        "summary.json",
        serde_json::to_string_pretty(&report).expect("a report serialises"),
    )?;
    write(
        "network.svg",
        network_svg(&cfg.scenario, cfg.agent, cfg.watched),
    )?;
    let all: Vec<Estimator> = estimators().collect();
    let names: Vec<&str> = all.iter().map(|e| e.name()).collect();
    for (file, series) in [
        ("nees.csv", &summary.nees_series),
        ("rmse.csv", &summary.rmse_series),
        ("two_sigma.csv", &summary.two_sigma_series),
        ("coin.csv", &summary.coin_series),
    ] {
        if series.is_empty() {
            continue;
        }
        let mut csv = format!("step,time,{}\n", names.join(","));
        for k in 0..cfg.steps {
            let row: Vec<String> = series.iter().map(|s| s[k].to_string()).collect();
            csv += &format!(
                "{},{},{}\n",
                k + 1,
                (k + 1) as f64 * cfg.scenario.dt,
                row.join(",")
            );
        }
        write(file, csv)?;
    }
    let mut csv = String::from("step,run,omega_ci");
    let blocks = traces
        .first()
        .and_then(|t| t.omega_nmci.first())
        .map_or(0, Vec::len);
    for b in 0..blocks {
        csv += &format!(",omega_nmci_{}", b + 1);
    }
    csv += ",omega_ici\n";
    for (r, t) in traces.iter().enumerate() {
        for k in 0..t.omega_ci.len() {
            csv += &format!("{},{},{}", k + 1, r, t.omega_ci[k]);
            for w in &t.omega_nmci[k] {
                csv += &format!(",{w}");
            }
            csv += &format!(",{}\n", t.omega_ici[k]);
        }
    }
    write("omega.csv", csv)?;

    // Figures (SVG): NEES with the 95 % χ² band, RMSE and 2σ, ω of the watched fusion.
    use plotters::style::RGBColor;
    let colours: Vec<RGBColor> = all.iter().map(|e| rgb(e.colour())).collect();
    let labels: Vec<String> = all.iter().map(|e| e.label()).collect();
    // The estimators drawn on the NEES, RMSE and COIN charts ([`Estimator::charted`]): naive
    // fusion's NEES grows by orders of magnitude (see nees.csv), so it is left off the chart
    // and the consistent estimators stay readable against the band.
    let shown: Vec<usize> = (0..all.len()).filter(|&s| all[s].charted()).collect();
    let dt = cfg.scenario.dt;
    // The charted estimators' series of one kind, with their labels and colours.
    fn charted<'a>(
        shown: &[usize],
        labels: &'a [String],
        colours: &[RGBColor],
        series: &'a [Vec<f64>],
    ) -> Vec<(&'a str, RGBColor, &'a [f64])> {
        shown
            .iter()
            .map(|&s| (labels[s].as_str(), colours[s], series[s].as_slice()))
            .collect()
    }
    let nees = charted(&shown, &labels, &colours, &summary.nees_series);
    line_chart(
        &out.join("nees.svg"),
        &format!(
            "NEES of agent {} ({} runs, {} dof; naive fusion is far above, see nees.csv)",
            cfg.agent,
            cfg.runs,
            cfg.scenario.dim()
        ),
        "mean NEES",
        dt,
        &nees,
        Some(summary.nees_bounds),
        false,
    )?;
    // Short labels here: two series per estimator.
    let rmse_labels: Vec<String> = all
        .iter()
        .flat_map(|e| {
            let l = e.short_label();
            [format!("{l} RMSE"), format!("{l} 2σ")]
        })
        .collect();
    let mut rmse = Vec::new();
    for &s in &shown {
        rmse.push((
            rmse_labels[2 * s].as_str(),
            colours[s],
            summary.rmse_series[s].as_slice(),
        ));
        rmse.push((
            rmse_labels[2 * s + 1].as_str(),
            RGBColor(
                colours[s].0 / 2 + 120,
                colours[s].1 / 2 + 120,
                colours[s].2 / 2 + 120,
            ),
            summary.two_sigma_series[s].as_slice(),
        ));
    }
    line_chart(
        &out.join("rmse.svg"),
        &format!(
            "position RMSE and 2σ of agent {} (mean over runs)",
            cfg.agent
        ),
        "metres",
        dt,
        &rmse,
        None,
        false,
    )?;
    let omega_ci = &summary.omega_ci_series;
    let omega_blocks = &summary.omega_nmci_series;
    let block_labels: Vec<String> = (0..blocks)
        .map(|b| format!("nmCI G{}{}", b / 2 + 1, if b % 2 == 0 { "x" } else { "y" }))
        .collect();
    let (ci, ici) = (Rule::Ci.method(), Rule::Ici.method());
    let mut omega = vec![(ci.label(), rgb(ci.info().colour), omega_ci.as_slice())];
    for b in 0..blocks {
        // Red to orange over the blocks (as the page's chart): 0..=200, never wrapping.
        let shade = (200 * b / blocks.saturating_sub(1).max(1)) as u8;
        omega.push((
            block_labels[b].as_str(),
            RGBColor(214, shade, shade / 2),
            omega_blocks[b].as_slice(),
        ));
    }
    omega.push((
        ici.label(),
        rgb(ici.info().colour),
        summary.omega_ici_series.as_slice(),
    ));
    line_chart(
        &out.join("omega.svg"),
        &format!(
            "ω when agent {} fuses agent {} (mean over runs)",
            cfg.agent, cfg.watched
        ),
        "ω",
        dt,
        &omega,
        None,
        false,
    )?;
    if !summary.coin_series.is_empty() {
        let coin = charted(&shown, &labels, &colours, &summary.coin_series);
        line_chart(
            &out.join("coin.svg"),
            &format!(
                "exact COIN of agent {} (≤ 1 conservative; naive fusion is far above, see coin.csv)",
                cfg.agent
            ),
            "COIN",
            dt,
            &coin,
            None,
            false,
        )?;
    }
    for name in ["nees.svg", "rmse.svg", "omega.svg"]
        .into_iter()
        .chain((!summary.coin_series.is_empty()).then_some("coin.svg"))
    {
        written.borrow_mut().push(out.join(name));
    }
    Ok(written.into_inner())
}

/// Writes a network sweep's files into `out` (created if missing): `sweep.csv` (every network
/// that fits the paper's text, ranked, then the references), `sweep.json` (the
/// [`SweepReport`]) and, when a network fits, `best.toml` (the study configuration on the best
/// one) and `network.svg` (its drawing) — what `nmci sweep` writes. Returns the files written
/// and the ranking's first `config.short_list` rows and the references as text.
pub fn write_sweep(
    config: &SweepConfig,
    report: &SweepReport,
    out: &Path,
) -> Result<(Vec<PathBuf>, String), ReportError> {
    std::fs::create_dir_all(out).map_err(|e| ReportError::Create {
        path: out.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut written = Vec::new();
    let mut write = |name: &str, text: String| {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| ReportError::Write {
            path: path.clone(),
            message: e.to_string(),
        })?;
        written.push(path);
        Ok::<(), ReportError>(())
    };
    let links = |c: &Candidate| {
        c.links
            .iter()
            .map(|(a, b)| format!("{a}-{b}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let pct = |r: Option<f64>| r.map_or(String::new(), |r| format!("{:.1}", -100.0 * r));
    let mut csv = String::from(
        "rank,links,fits_text,distance,omega_ci,omega_nmci,two_sigma_reduction_pct,rmse_reduction_pct\n",
    );
    let rows = report
        .ranked
        .iter()
        .enumerate()
        .map(|(k, c)| ((k + 1).to_string(), c))
        .chain(
            report
                .references
                .iter()
                .map(|c| ("reference".to_string(), c)),
        );
    let mut table = String::new();
    for (i, (rank, c)) in rows.enumerate() {
        let omega = c
            .omega_nmci
            .iter()
            .map(|w| format!("{w:.3}"))
            .collect::<Vec<_>>()
            .join(" ");
        csv += &format!(
            "{rank},{},{},{:.4},{:.4},{omega},{},{}\n",
            links(c),
            c.text_mismatch.is_none(),
            c.distance,
            c.omega_ci,
            pct(Some(c.two_sigma_reduction)),
            pct(c.rmse_reduction)
        );
        if i < config.short_list.max(1) || rank == "reference" {
            table += &format!(
                "{rank:>9}  d = {:.3}  links {:<28} CI ω {:.3}  nmCI ω {omega}  2σ {:>6} %  RMSE {:>6} %\n",
                c.distance,
                links(c),
                c.omega_ci,
                pct(Some(c.two_sigma_reduction)),
                pct(c.rmse_reduction)
            );
        }
    }
    write("sweep.csv", csv)?;
    write(
        "sweep.json",
        serde_json::to_string_pretty(report).expect("a sweep report serialises"),
    )?;
    if let Some(best) = report.ranked.first() {
        let best_config = config.network(&best.links);
        write(
            "best.toml",
            toml::to_string(&StudyConfig {
                coin: StudyConfig::default().coin,
                ..best_config.clone()
            })
            .expect("a study configuration serialises to TOML"),
        )?;
        write(
            "network.svg",
            network_svg(
                &best_config.scenario,
                best_config.agent,
                best_config.watched,
            ),
        )?;
    }
    Ok((written, table))
}

/// One SVG line chart: `series` of `(label, colour, values)` against time, optional
/// horizontal bounds.
pub(crate) fn line_chart(
    path: &std::path::Path,
    title: &str,
    y_label: &str,
    dt: f64,
    series: &[(&str, plotters::style::RGBColor, &[f64])],
    bounds: Option<(f64, f64)>,
    log_y: bool,
) -> Result<(), ReportError> {
    use plotters::prelude::*;
    let err = |e: &dyn std::fmt::Display| ReportError::Draw {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let steps = series.iter().map(|s| s.2.len()).max().unwrap_or(0).max(1);
    let t_max = steps as f64 * dt;
    let finite = series
        .iter()
        .flat_map(|s| s.2.iter().copied())
        .chain(bounds.iter().flat_map(|b| [b.0, b.1]))
        .filter(|v| v.is_finite() && (!log_y || *v > 0.0));
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 1.0) };
    let root = SVGBackend::new(path, (900, 520)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70);
    let x_range = 0.0..t_max;
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc("time [s]")
                .y_desc(y_label)
                .y_label_formatter(&|v| {
                    format!("{:.4}", v)
                        .trim_end_matches('0')
                        .trim_end_matches('.')
                        .to_string()
                })
                .draw()
                .map_err(|e| err(&e))?;
            if let Some((b_lo, b_hi)) = bounds {
                for (b, name) in [(b_lo, "95 % lower"), (b_hi, "95 % upper")] {
                    chart
                        .draw_series(LineSeries::new(
                            [(0.0, b), (t_max, b)],
                            BLACK.mix(0.6).stroke_width(1),
                        ))
                        .map_err(|e| err(&e))?
                        .label(name)
                        .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], BLACK.mix(0.6)));
                }
            }
            for (label, colour, values) in series {
                let colour = *colour;
                chart
                    .draw_series(LineSeries::new(
                        values
                            .iter()
                            .enumerate()
                            .filter(|(_, v)| v.is_finite() && (!log_y || **v > 0.0))
                            .map(|(k, v)| ((k + 1) as f64 * dt, *v)),
                        colour.stroke_width(2),
                    ))
                    .map_err(|e| err(&e))?
                    .label(*label)
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 18, y)], colour.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.3))
                .draw()
                .map_err(|e| err(&e))?;
        }};
    }
    if log_y {
        draw!(builder
            .build_cartesian_2d(x_range, (lo * 0.8..hi * 1.25).log_scale())
            .map_err(|e| err(&e))?);
    } else {
        let pad = 0.05 * (hi - lo).max(1e-12);
        draw!(builder
            .build_cartesian_2d(x_range, (lo - pad)..(hi + pad))
            .map_err(|e| err(&e))?);
    }
    root.present().map_err(|e| err(&e))
}

/// A `#rrggbb` colour of the registry ([`crate::RuleInfo::colour`]) for plotters (black for
/// anything else; the registry's colours are checked by a test).
pub(crate) fn rgb(hex: &str) -> plotters::style::RGBColor {
    let byte = |i: usize| {
        hex.get(i..i + 2)
            .and_then(|h| u8::from_str_radix(h, 16).ok())
            .unwrap_or(0)
    };
    plotters::style::RGBColor(byte(1), byte(3), byte(5))
}
