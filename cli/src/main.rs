//! `nmci` command-line interface.
//!
//! `nmci fuse [FILE]` reads a JSON fusion request from FILE (or standard input) and prints
//! the JSON response; invalid input exits non-zero with a one-line message on stderr.
//! `nmci track` runs the tracking study (see `configs/paper.toml`), or with `--first-run` a
//! shard of its runs; `nmci merge` puts shards together.

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
        #[command(after_help = fuse_help())]
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
            /// Run a shard: runs FIRST_RUN..FIRST_RUN + runs of the study, written to
            /// OUT/shard-FIRST-END.json for `nmci merge` (the exact COIN goes with the shard
            /// holding run 0).
            #[arg(long)]
            first_run: Option<usize>,
            /// Output folder: summary.json, nees/rmse/two_sigma/omega/coin CSVs, nees/rmse/omega/coin SVGs
            /// (or the shard file with --first-run).
            #[arg(long, default_value = "out/track")]
            out: PathBuf,
            /// Also print the summary (summary.json's content) on stdout.
            #[arg(long)]
            json: bool,
        },
        /// Merge shards of a study (`nmci track --first-run`) into the study itself, bit for bit
        /// what one `nmci track` of all the runs gives, and write its files.
        Merge {
            /// Shard files, or folders whose shard-*.json files are all read.
            #[arg(required = true)]
            inputs: Vec<PathBuf>,
            /// Output folder, as for `nmci track`.
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

    /// `nmci fuse --help`'s epilogue: the methods (from the rule registry), the request's
    /// fields (from the contract) and an example.
    fn fuse_help() -> String {
        let methods: Vec<String> = nmci::rules::rules()
            .iter()
            .map(|r| format!("  {:<10} {} ({})", r.name, r.label, r.guarantee.phrase()))
            .collect();
        format!(
            "Methods (\"method\"):\n{}\n\nRequest fields: {}.\nEvery field, default and error: docs/contract.md.\n\nExample:\n  echo '{{\"pa\":[[3,0],[0,1]],\"pb\":[[1,0],[0,4]],\"pab_unknown\":[[true,false],[false,true]],\"method\":\"nmci\"}}' | nmci fuse",
            methods.join("\n"),
            nmci::contract::request_fields().join(", ")
        )
    }

    /// `nmci fig2`: runs in parallel, `fig2.csv` and the two-panel `fig2.svg`.
    fn fig2(runs: usize, sizes: Vec<usize>, seed: u64, out: PathBuf) -> Result<String, String> {
        use indicatif::{ProgressBar, ProgressStyle};
        use nmci::fig2::{fig2_run, fig2_summary, Fig2Config};
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
        nmci::fig2::write_fig2(&rows, runs, &out).map_err(|e| e.to_string())?;
        let csv_path = out.join("fig2.csv");
        let failures: usize = rows.iter().map(|r| r.failures).sum();
        Ok(format!(
            "{runs} runs × {} sizes in {:.1} s; {failures} SDP failures (counted in fig2.csv); wrote {} and fig2.svg",
            rows.len(),
            started.elapsed().as_secs_f64(),
            csv_path.display()
        ))
    }

    /// A study configuration from a TOML file, or the defaults.
    fn load_config(path: Option<PathBuf>) -> Result<nmci::study::StudyConfig, String> {
        match path {
            Some(path) => {
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
                nmci::study::StudyConfig::from_toml(&text).map_err(|e| match e {
                    nmci::study::SimError::InvalidConfig(m) => {
                        format!("invalid configuration {}: {m}", path.display())
                    }
                    e => e.to_string(),
                })
            }
            None => Ok(nmci::study::StudyConfig::default()),
        }
    }

    /// `nmci sweep`: the ranked networks as CSV and JSON, the best as a configuration and a
    /// drawing, and the top of the ranking on standard output.
    fn sweep(
        config: Option<PathBuf>,
        family: nmci::study::NetworkFamily,
        short_list: usize,
        runs: Option<usize>,
        steps: Option<usize>,
        out: PathBuf,
    ) -> Result<String, String> {
        use indicatif::{ProgressBar, ProgressStyle};
        use nmci::study::*;

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
                "{bar:40} {pos}/{len} pieces (networks × rules, then the short list's Monte Carlo runs, networks × rules), {elapsed} (eta {eta})",
            )
            .map_err(|e| e.to_string())?,
        );
        let started = std::time::Instant::now();
        let report = nmci::study::sweep(&config, |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
        .map_err(|e| e.to_string())?;
        bar.finish_and_clear();
        if report.ranked.is_empty() {
            return Err("no network of this family fits the paper's text".into());
        }
        let (_, table) = write_sweep(&config, &report, &out).map_err(|e| e.to_string())?;
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

    #[allow(clippy::too_many_arguments)]
    fn track(
        config: Option<PathBuf>,
        runs: Option<usize>,
        steps: Option<usize>,
        seed: Option<u64>,
        no_coin: bool,
        first_run: Option<usize>,
        out: PathBuf,
        json: bool,
    ) -> Result<String, String> {
        use indicatif::{ProgressBar, ProgressStyle};
        use nmci::study::*;

        let mut cfg = load_config(config)?;
        cfg.runs = runs.unwrap_or(cfg.runs);
        cfg.steps = steps.unwrap_or(cfg.steps);
        cfg.seed = seed.unwrap_or(cfg.seed);
        cfg.coin &= !no_coin;
        cfg.validate().map_err(|e| e.to_string())?;
        let coin_pieces = if carries_coin(&cfg, first_run.unwrap_or(0)) {
            estimators().count()
        } else {
            0
        };
        let bar = ProgressBar::new((run_pieces(cfg.runs, STUDY_RULES.len()) + coin_pieces) as u64).with_style(
            ProgressStyle::with_template(
                "{bar:40} {pos}/{len} parts done (each rule's share of the runs, then the exact COIN of each estimator), {elapsed} (eta {eta})",
            )
            .map_err(|e| e.to_string())?,
        );
        let started = std::time::Instant::now();
        let model = Model::new(&cfg.scenario).map_err(|e| e.to_string())?;
        if let Some(first_run) = first_run {
            let shard =
                run_shard(&cfg, &model, first_run, || bar.inc(1)).map_err(|e| e.to_string())?;
            bar.finish_and_clear();
            std::fs::create_dir_all(&out)
                .map_err(|e| format!("cannot create {}: {e}", out.display()))?;
            let path = out.join(shard.file_name());
            let text = serde_json::to_string(&shard).map_err(|e| e.to_string())?;
            std::fs::write(&path, text)
                .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            return Ok(format!(
                "runs {first_run}..{} × {} steps in {:.1} s; wrote the shard {} (merge shards with `nmci merge`)",
                first_run + cfg.runs,
                cfg.steps,
                started.elapsed().as_secs_f64(),
                path.display()
            ));
        }
        let study = study_parallel(&cfg, &model, || bar.inc(1)).map_err(|e| e.to_string())?;
        bar.finish_and_clear();
        write_study(&study, &out).map_err(|e| e.to_string())?;
        let mut done = format!(
            "{} runs × {} steps in {:.1} s; wrote {}/summary.json, per-step CSVs and SVG figures",
            cfg.runs,
            cfg.steps,
            started.elapsed().as_secs_f64(),
            out.display(),
        );
        if json {
            done.push('\n');
            done += &serde_json::to_string_pretty(&study.report()).map_err(|e| e.to_string())?;
        }
        Ok(done)
    }

    /// `nmci merge`: reads shards (files, or every `shard-*.json` in folders), merges them
    /// into one study and writes what `nmci track` writes.
    fn merge(inputs: Vec<PathBuf>, out: PathBuf) -> Result<String, String> {
        use nmci::study::*;
        let mut files = Vec::new();
        for input in inputs {
            if input.is_dir() {
                let found = shard_files(&input)
                    .map_err(|e| format!("cannot read {}: {e}", input.display()))?;
                if found.is_empty() {
                    return Err(format!("{} holds no shard-*.json file", input.display()));
                }
                files.extend(found);
            } else {
                files.push(input);
            }
        }
        let shards = files
            .iter()
            .map(|path| {
                let text = std::fs::read_to_string(path)
                    .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
                serde_json::from_str::<StudyShard>(&text)
                    .map_err(|e| format!("{} is not a study shard: {e}", path.display()))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let count = shards.len();
        let study = merge_shards(shards).map_err(|e| e.to_string())?;
        write_study(&study, &out).map_err(|e| e.to_string())?;
        Ok(format!(
            "merged {count} shards: {} runs × {} steps; wrote {}/summary.json, per-step CSVs and SVG figures\n{}",
            study.config.runs,
            study.config.steps,
            out.display(),
            serde_json::to_string_pretty(&study.report()).map_err(|e| e.to_string())?
        ))
    }

    /// The request text, read up to one byte past [`nmci::contract::MAX_REQUEST_BYTES`]: a longer input
    /// is refused without being read whole.
    fn read_input(file: Option<PathBuf>) -> Result<String, String> {
        let limit = nmci::contract::MAX_REQUEST_BYTES;
        let mut bytes = Vec::new();
        match file {
            Some(path) if path.as_os_str() != "-" => std::fs::File::open(&path)
                .and_then(|f| f.take(limit as u64 + 1).read_to_end(&mut bytes))
                .map_err(|e| format!("cannot read {}: {e}", path.display()))?,
            _ => std::io::stdin()
                .take(limit as u64 + 1)
                .read_to_end(&mut bytes)
                .map_err(|e| format!("cannot read standard input: {e}"))?,
        };
        if bytes.len() > limit {
            return Err(nmci::RequestError::TooLarge {
                bytes: bytes.len(),
                limit,
            }
            .to_string());
        }
        String::from_utf8(bytes).map_err(|e| format!("the request is not UTF-8 text: {e}"))
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
            let out = nmci::contract::fuse_json(&request).map_err(|e| e.to_string());
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
        let out = worker
            .join()
            .unwrap_or_else(|_| Err("the solve panicked (a bug: please report it)".into()))?;
        // How the blocks were found, when the response says (`structure.note`): on stderr, so
        // the JSON on stdout stays the response alone. A list's notes name their request.
        let note =
            |v: &serde_json::Value| Some(v.get("structure")?.get("note")?.as_str()?.to_owned());
        match serde_json::from_str::<serde_json::Value>(&out) {
            Ok(serde_json::Value::Array(responses)) => {
                for (i, r) in responses.iter().enumerate() {
                    if let Some(note) = note(r) {
                        eprintln!("nmci: structure: request {i}: {note}");
                    }
                }
            }
            Ok(response) => {
                if let Some(note) = note(&response) {
                    eprintln!("nmci: structure: {note}");
                }
            }
            Err(_) => {}
        }
        Ok(out)
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
                first_run,
                out,
                json,
            } => track(config, runs, steps, seed, no_coin, first_run, out, json),
            Command::Merge { inputs, out } => merge(inputs, out),
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
                    Some(count) => nmci::study::NetworkFamily::Links { count },
                    None => nmci::study::NetworkFamily::Bridges { extra },
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

fn main() -> std::process::ExitCode {
    cli::main()
}
