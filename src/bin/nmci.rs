//! `nmci` command-line interface.
//!
//! `nmci fuse [FILE]` reads a JSON fusion request from FILE (or standard input) and prints
//! the JSON response; invalid input exits non-zero with a one-line message on stderr.
//! `nmci track` runs the tracking study (see `configs/paper.toml`).

#[cfg(not(target_arch = "wasm32"))]
mod cli {
    use std::io::Read;
    use std::path::PathBuf;
    use std::process::ExitCode;

    use clap::{Parser, Subcommand};

    #[derive(Parser)]
    #[command(
        name = "nmci",
        version,
        about = "Conservative fusion with partially known cross-covariance: CI, nmCI and the sampled-SDP optimal bound"
    )]
    struct Cli {
        #[command(subcommand)]
        command: Command,
    }

    #[derive(Subcommand)]
    enum Command {
        /// Fuse two estimates: read a JSON request from FILE (or stdin), print the JSON response.
        Fuse {
            /// Request file; standard input when absent or `-`.
            file: Option<PathBuf>,
        },
        /// Run the paper's 16-agent tracking study (parallel over runs) and write its outputs.
        Track {
            /// Study configuration (TOML, the form of configs/paper.toml); defaults when absent.
            #[arg(long)]
            config: Option<PathBuf>,
            /// Monte Carlo runs (overrides the configuration).
            #[arg(long)]
            runs: Option<usize>,
            /// Time steps per run (overrides the configuration).
            #[arg(long)]
            steps: Option<usize>,
            /// Seed (overrides the configuration).
            #[arg(long)]
            seed: Option<u64>,
            /// Skip the exact COIN (overrides `coin = true` of the configuration).
            #[arg(long)]
            no_coin: bool,
            /// Output folder: summary.json, nees/rmse/two_sigma/omega/coin CSVs, nees/rmse/omega/coin SVGs.
            #[arg(long, default_value = "out/track")]
            out: PathBuf,
        },
        /// Search the networks the paper's text allows for the one its numbers fit (ω of 7←11
        /// for CI and nmCI and the 2σ covariance-only for every network; the Monte Carlo RMSE
        /// for the short list), ranked by distance to the paper's numbers.
        Sweep {
            /// Study values to run with (TOML, the form of configs/paper.toml); its network is
            /// replaced by each candidate's. Defaults when absent.
            #[arg(long)]
            config: Option<PathBuf>,
            /// Keep the bridges 4–7, 7–11, 12–13 and add up to N more links between groups.
            #[arg(long, default_value_t = 2, conflicts_with = "links")]
            extra: usize,
            /// Instead: 7–11 plus any others, N links between groups in all.
            #[arg(long)]
            links: Option<usize>,
            /// Networks that get the Monte Carlo RMSE (the best by covariance-only distance).
            #[arg(long, default_value_t = 5)]
            short_list: usize,
            /// Monte Carlo runs per short-listed network (overrides the configuration).
            #[arg(long)]
            runs: Option<usize>,
            /// Time steps (overrides the configuration).
            #[arg(long)]
            steps: Option<usize>,
            /// Output folder: sweep.csv (every network), sweep.json, best.toml, network.svg.
            #[arg(long, default_value = "out/sweep")]
            out: PathBuf,
        },
        /// The paper's fig. 2: sampled SDP against nmCI on the 2-D example, by sample-set size.
        Fig2 {
            /// Monte Carlo runs.
            #[arg(long, default_value_t = 1000)]
            runs: usize,
            /// Sample-set sizes, comma-separated.
            #[arg(
                long,
                value_delimiter = ',',
                default_value = "1,2,5,10,20,50,100,200,500,1000"
            )]
            sizes: Vec<usize>,
            /// Seed.
            #[arg(long, default_value_t = 0)]
            seed: u64,
            /// Output folder: fig2.csv and fig2.svg.
            #[arg(long, default_value = "out/fig2")]
            out: PathBuf,
        },
    }

    /// `nmci fig2`: runs in parallel, `fig2.csv` and the two-panel `fig2.svg`.
    fn fig2(runs: usize, sizes: Vec<usize>, seed: u64, out: PathBuf) -> Result<String, String> {
        use indicatif::{ProgressBar, ProgressStyle};
        use nmci::{fig2_csv, fig2_run, fig2_summary, Fig2Config};
        use rayon::prelude::*;

        let config = Fig2Config { runs, sizes, seed };
        config.validate().map_err(|e| e.to_string())?;
        let bar = ProgressBar::new(runs as u64).with_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} runs, {elapsed} (eta {eta})")
                .map_err(|e| e.to_string())?,
        );
        let started = std::time::Instant::now();
        let records = (0..runs)
            .into_par_iter()
            .map(|r| {
                let rec = fig2_run(&config, r);
                bar.inc(1);
                rec
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| e.to_string())?;
        bar.finish_and_clear();
        let rows = fig2_summary(&config, &records);
        std::fs::create_dir_all(&out)
            .map_err(|e| format!("cannot create {}: {e}", out.display()))?;
        let csv_path = out.join("fig2.csv");
        std::fs::write(&csv_path, fig2_csv(&rows))
            .map_err(|e| format!("cannot write {}: {e}", csv_path.display()))?;
        fig2_chart(&out.join("fig2.svg"), &rows, runs)?;
        let failures: usize = rows.iter().map(|r| r.failures).sum();
        Ok(format!(
            "{runs} runs × {} sizes in {:.1} s; {failures} SDP failures (counted in fig2.csv); wrote {} and fig2.svg",
            rows.len(),
            started.elapsed().as_secs_f64(),
            csv_path.display()
        ))
    }

    /// The paper's fig. 2 layout: top, `‖P_nmCI − P_opt‖₂` against the sample-set size (log–log,
    /// median with min and max); bottom, `λ_min(P − K P_true Kᵀ)` of nmCI and of the SDP.
    fn fig2_chart(
        path: &std::path::Path,
        rows: &[nmci::Fig2Row],
        runs: usize,
    ) -> Result<(), String> {
        use plotters::prelude::*;
        let err = |e: &dyn std::fmt::Display| format!("cannot draw {}: {e}", path.display());
        let root = SVGBackend::new(path, (900, 760)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let (top, bottom) = root.split_vertically(380);
        let n_max = rows.iter().map(|r| r.samples).max().unwrap_or(1).max(2) as f64;
        let x_range = (0.8_f64..n_max * 1.25).log_scale();
        let positive: Vec<f64> = rows
            .iter()
            .flat_map(|r| r.dev)
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        let (lo, hi) = positive
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let (lo, hi) = if lo.is_finite() {
            (lo / 2.0, hi * 2.0)
        } else {
            (1e-12, 1.0)
        };
        let mut chart = ChartBuilder::on(&top)
            .caption(
                format!("‖P_nmCI − P_opt‖₂ over {runs} runs (median, min, max)"),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(70)
            .build_cartesian_2d(x_range.clone(), (lo..hi).log_scale())
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("samples N")
            .y_desc("deviation")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(|e| err(&e))?;
        let series =
            |pick: &dyn Fn(&nmci::Fig2Row) -> f64, positive_only: bool| -> Vec<(f64, f64)> {
                rows.iter()
                    .map(|r| (r.samples as f64, pick(r)))
                    .filter(|(_, v)| v.is_finite() && (!positive_only || *v > 0.0))
                    .collect()
            };
        let blue = RGBColor(31, 119, 180);
        let red = RGBColor(214, 39, 40);
        let green = RGBColor(42, 157, 63);
        for (k, width) in [(0, 3), (1, 1), (2, 1)] {
            chart
                .draw_series(LineSeries::new(
                    series(&|r| r.dev[k], true),
                    blue.stroke_width(width),
                ))
                .map_err(|e| err(&e))?;
        }
        let values: Vec<f64> = rows
            .iter()
            .flat_map(|r| r.eig_nmci.iter().chain(&r.eig_opt).copied())
            .filter(|v| v.is_finite())
            .collect();
        let (lo, hi) = values
            .iter()
            .fold((0.0_f64, 0.0_f64), |(a, b), &v| (a.min(v), b.max(v)));
        let pad = 0.05 * (hi - lo).max(1e-9);
        let mut chart = ChartBuilder::on(&bottom)
            .caption(
                "λ_min(P − K P_true Kᵀ): below 0 = not conservative for the true P_ab",
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(70)
            .build_cartesian_2d(x_range, (lo - pad)..(hi + pad))
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("samples N")
            .y_desc("λ_min")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(|e| err(&e))?;
        chart
            .draw_series(LineSeries::new(
                vec![(0.8, 0.0), (n_max * 1.25, 0.0)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| err(&e))?;
        for (label, colour, pick) in [
            (
                "nmCI",
                red,
                &(|r: &nmci::Fig2Row| r.eig_nmci) as &dyn Fn(&nmci::Fig2Row) -> [f64; 3],
            ),
            ("optimal (sampled SDP)", green, &|r: &nmci::Fig2Row| {
                r.eig_opt
            }),
        ] {
            for (k, width) in [(0, 3), (1, 1), (2, 1)] {
                let s = chart
                    .draw_series(LineSeries::new(
                        series(&|r| pick(r)[k], false),
                        colour.stroke_width(width),
                    ))
                    .map_err(|e| err(&e))?;
                if k == 0 {
                    s.label(label).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(3))
                    });
                }
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))?;
        Ok(())
    }

    /// One SVG line chart: `series` of `(label, colour, values)` against time, optional
    /// horizontal bounds.
    fn line_chart(
        path: &std::path::Path,
        title: &str,
        y_label: &str,
        dt: f64,
        series: &[(&str, plotters::style::RGBColor, &[f64])],
        bounds: Option<(f64, f64)>,
        log_y: bool,
    ) -> Result<(), String> {
        use plotters::prelude::*;
        let err = |e: &dyn std::fmt::Display| format!("cannot draw {}: {e}", path.display());
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
                            .legend(|(x, y)| {
                                PathElement::new([(x, y), (x + 18, y)], BLACK.mix(0.6))
                            });
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

    /// A study configuration from a TOML file, or the defaults.
    fn load_config(path: Option<PathBuf>) -> Result<nmci::sim::StudyConfig, String> {
        match path {
            Some(path) => {
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
                toml::from_str(&text).map_err(|e| {
                    format!("invalid configuration {}: {}", path.display(), e.message())
                })
            }
            None => Ok(nmci::sim::StudyConfig::default()),
        }
    }

    /// `nmci sweep`: the ranked networks as CSV and JSON, the best as a configuration and a
    /// drawing, and the top of the ranking on standard output.
    fn sweep(
        config: Option<PathBuf>,
        family: nmci::sim::Family,
        short_list: usize,
        runs: Option<usize>,
        steps: Option<usize>,
        out: PathBuf,
    ) -> Result<String, String> {
        use indicatif::{ProgressBar, ProgressStyle};
        use nmci::sim::*;

        let mut study = load_config(config)?;
        study.runs = runs.unwrap_or(study.runs);
        study.steps = steps.unwrap_or(study.steps);
        let config = SweepConfig {
            study,
            family,
            short_list,
            ..SweepConfig::default()
        };
        config.validate().map_err(|e| e.to_string())?;
        let bar = ProgressBar::new(0).with_style(
            ProgressStyle::with_template(
                "{bar:40} {pos}/{len} pieces (networks × rules, then Monte Carlo runs × rules), {elapsed} (eta {eta})",
            )
            .map_err(|e| e.to_string())?,
        );
        let started = std::time::Instant::now();
        let report = nmci::sim::sweep(&config, |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
        .map_err(|e| e.to_string())?;
        bar.finish_and_clear();
        let best = report
            .ranked
            .first()
            .ok_or("no network of this family fits the paper's text")?;
        std::fs::create_dir_all(&out)
            .map_err(|e| format!("cannot create {}: {e}", out.display()))?;
        let write = |name: &str, text: String| {
            std::fs::write(out.join(name), text)
                .map_err(|e| format!("cannot write {}: {e}", out.join(name).display()))
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
            serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?,
        )?;
        let best_config = config.network(&best.links);
        write(
            "best.toml",
            toml::to_string(&StudyConfig {
                coin: StudyConfig::default().coin,
                ..best_config.clone()
            })
            .map_err(|e| e.to_string())?,
        )?;
        write(
            "network.svg",
            network_svg(
                &best_config.scenario,
                best_config.agent,
                best_config.watched,
            ),
        )?;
        Ok(format!(
            "{} networks fit the text; {} with Monte Carlo RMSE ({} runs × {} steps); {:.1} s\n{table}wrote {}/sweep.csv, sweep.json, best.toml, network.svg",
            report.fitting,
            config.short_list.min(report.fitting),
            config.study.runs,
            config.study.steps,
            started.elapsed().as_secs_f64(),
            out.display()
        ))
    }

    fn track(
        config: Option<PathBuf>,
        runs: Option<usize>,
        steps: Option<usize>,
        seed: Option<u64>,
        no_coin: bool,
        out: PathBuf,
    ) -> Result<String, String> {
        use indicatif::{ProgressBar, ProgressStyle};
        use nmci::sim::*;

        let mut cfg = load_config(config)?;
        cfg.runs = runs.unwrap_or(cfg.runs);
        cfg.steps = steps.unwrap_or(cfg.steps);
        cfg.seed = seed.unwrap_or(cfg.seed);
        cfg.coin &= !no_coin;
        cfg.validate().map_err(|e| e.to_string())?;
        let coin_pieces = if cfg.coin { estimators().count() } else { 0 };
        let bar = ProgressBar::new((cfg.runs * RULES.len() + coin_pieces) as u64).with_style(
            ProgressStyle::with_template(
                "{bar:40} {pos}/{len} runs × rules (+ exact COIN per estimator), {elapsed} (eta {eta})",
            )
            .map_err(|e| e.to_string())?,
        );
        let started = std::time::Instant::now();
        let model = Model::new(&cfg.scenario).map_err(|e| e.to_string())?;
        let (traces, summary) =
            study_parallel(&cfg, &model, || bar.inc(1)).map_err(|e| e.to_string())?;
        bar.finish_and_clear();
        let report = StudyReport::new(&cfg, &summary);
        std::fs::create_dir_all(&out)
            .map_err(|e| format!("cannot create {}: {e}", out.display()))?;
        let write = |name: &str, text: String| {
            std::fs::write(out.join(name), text)
                .map_err(|e| format!("cannot write {}: {e}", out.join(name).display()))
        };
        write(
            "summary.json",
            serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?,
        )?;
        write(
            "network.svg",
            network_svg(&cfg.scenario, cfg.agent, cfg.watched),
        )?;
        let names: Vec<&str> = estimators().map(estimator_name).collect();
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
        let colours = [
            RGBColor(0, 0, 0),
            RGBColor(31, 119, 180),
            RGBColor(214, 39, 40),
            RGBColor(150, 150, 150),
            RGBColor(44, 160, 44),
        ];
        // The estimators drawn on the NEES, RMSE and COIN charts: all but naive fusion.
        let shown = [0, 1, 2, 4];
        let dt = cfg.scenario.dt;
        // Naive fusion's NEES grows by orders of magnitude (see nees.csv): left off the chart
        // so the consistent estimators stay readable against the band.
        let nees: Vec<_> = shown
            .iter()
            .map(|&s| (names[s], colours[s], summary.nees_series[s].as_slice()))
            .collect();
        line_chart(
            &out.join("nees.svg"),
            &format!(
                "NEES of agent {} ({} runs, {} dof; naive fusion is far above, see nees.csv)",
                cfg.agent,
                cfg.runs,
                model.dim()
            ),
            "mean NEES",
            dt,
            &nees,
            Some(summary.nees_bounds),
            false,
        )?;
        let labels: Vec<String> = (0..names.len())
            .flat_map(|s| [format!("{} RMSE", names[s]), format!("{} 2σ", names[s])])
            .collect();
        let mut rmse = Vec::new();
        for s in shown {
            rmse.push((
                labels[2 * s].as_str(),
                colours[s],
                summary.rmse_series[s].as_slice(),
            ));
            rmse.push((
                labels[2 * s + 1].as_str(),
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
        let mut omega = vec![("CI", RGBColor(31, 119, 180), omega_ci.as_slice())];
        for b in 0..blocks {
            let shade = (40 * b) as u8;
            omega.push((
                block_labels[b].as_str(),
                RGBColor(200, shade, shade / 2),
                omega_blocks[b].as_slice(),
            ));
        }
        omega.push(("ICI", colours[4], summary.omega_ici_series.as_slice()));
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
            let coin: Vec<_> = shown
                .iter()
                .map(|&s| (names[s], colours[s], summary.coin_series[s].as_slice()))
                .collect();
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
        Ok(format!(
            "{} runs × {} steps in {:.1} s; wrote {}/summary.json, per-step CSVs and SVG figures\n{}",
            cfg.runs,
            cfg.steps,
            started.elapsed().as_secs_f64(),
            out.display(),
            serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?
        ))
    }

    fn read_input(file: Option<PathBuf>) -> Result<String, String> {
        match file {
            Some(path) if path.as_os_str() != "-" => std::fs::read_to_string(&path)
                .map_err(|e| format!("cannot read {}: {e}", path.display())),
            _ => {
                let mut s = String::new();
                std::io::stdin()
                    .read_to_string(&mut s)
                    .map_err(|e| format!("cannot read standard input: {e}"))?;
                Ok(s)
            }
        }
    }

    /// Runs a request; a solve that takes more than a second gets a progress line on stderr
    /// (elapsed time, and the request's `time_limit` when it has one).
    fn fuse_with_progress(text: &str) -> Result<String, String> {
        use indicatif::{ProgressBar, ProgressStyle};
        use std::sync::mpsc;
        use std::time::Duration;
        let (tx, rx) = mpsc::channel();
        let request = text.to_string();
        let worker = std::thread::spawn(move || {
            let out = nmci::fuse_json(&request).map_err(|e| e.to_string());
            let _ = tx.send(());
            out
        });
        if rx.recv_timeout(Duration::from_secs(1)).is_err() {
            let method = serde_json::from_str::<serde_json::Value>(text)
                .ok()
                .and_then(|v| {
                    let m = v.get("method")?.as_str()?.to_string();
                    let limit = v.get("time_limit").and_then(|t| t.as_f64());
                    Some(match limit {
                        Some(t) => format!("{m} (time limit {t} s)"),
                        None => m,
                    })
                })
                .unwrap_or_else(|| "the request".into());
            let bar = ProgressBar::new_spinner().with_style(
                ProgressStyle::with_template("{spinner} solving {msg}: {elapsed}")
                    .expect("a valid template"),
            );
            bar.set_message(method);
            bar.enable_steady_tick(Duration::from_millis(200));
            let _ = rx.recv();
            bar.finish_and_clear();
        }
        worker
            .join()
            .unwrap_or_else(|_| Err("the solve panicked (a bug: please report it)".into()))
    }

    pub fn main() -> ExitCode {
        let cli = Cli::parse();
        let result = match cli.command {
            Command::Fuse { file } => read_input(file).and_then(|text| fuse_with_progress(&text)),
            Command::Track {
                config,
                runs,
                steps,
                seed,
                no_coin,
                out,
            } => track(config, runs, steps, seed, no_coin, out),
            Command::Sweep {
                config,
                extra,
                links,
                short_list,
                runs,
                steps,
                out,
            } => sweep(
                config,
                match links {
                    Some(count) => nmci::sim::Family::Links { count },
                    None => nmci::sim::Family::Bridges { extra },
                },
                short_list,
                runs,
                steps,
                out,
            ),
            Command::Fig2 {
                runs,
                sizes,
                seed,
                out,
            } => fig2(runs, sizes, seed, out),
        };
        match result {
            Ok(out) => {
                println!("{out}");
                ExitCode::SUCCESS
            }
            Err(message) => {
                eprintln!("nmci: {message}");
                ExitCode::FAILURE
            }
        }
    }
}

#[cfg(not(target_arch = "wasm32"))]
fn main() -> std::process::ExitCode {
    cli::main()
}

/// The CLI is native only; the wasm build of this crate is the library.
#[cfg(target_arch = "wasm32")]
fn main() {}
