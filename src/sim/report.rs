//! The files of a study (native only): `summary.json`, per-step CSVs, SVG charts and the
//! network's drawing — what `nmci track` and `nmci merge` write, and Python's
//! `Study.write`.

use std::path::{Path, PathBuf};

use crate::error::ReportError;

use super::{network_svg, Candidate, Study, StudyConfig, SweepConfig, SweepReport};

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
    for (file, series) in [
        ("nees.csv", &summary.nees_series),
        ("rmse.csv", &summary.rmse_series),
        ("two_sigma.csv", &summary.two_sigma_series),
        ("coin.csv", &summary.coin_series),
    ] {
        if series.is_empty() {
            continue;
        }
        write(file, super::series_csv(series, cfg.scenario.dt))?;
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

    // Figures (SVG): the charts the page draws (src/chart/).
    for (name, chart) in super::study_charts(cfg, summary, cfg.runs) {
        let path = out.join(format!("{name}.svg"));
        crate::chart::write_svg(&path, &[&chart], super::STUDY_SVG_SIZE)?;
        written.borrow_mut().push(path);
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
