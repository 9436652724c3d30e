//! `nmci` command-line interface.
//!
//! `nmci fuse [FILE]` reads a JSON fusion request from FILE (or standard input) and prints
//! the JSON response; invalid input exits non-zero with a one-line message on stderr.
//! `nmci track` runs the tracking study (see `configs/study.toml`).

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
            /// Study configuration (TOML, the form of configs/study.toml); defaults when absent.
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
            /// Output folder: summary.json, nees.csv, rmse.csv, two_sigma.csv, omega.csv.
            #[arg(long, default_value = "out/track")]
            out: PathBuf,
        },
    }

    fn track(
        config: Option<PathBuf>,
        runs: Option<usize>,
        steps: Option<usize>,
        seed: Option<u64>,
        out: PathBuf,
    ) -> Result<String, String> {
        use indicatif::{ProgressBar, ProgressStyle};
        use nmci::sim::*;
        use rayon::prelude::*;

        let mut cfg: StudyConfig = match config {
            Some(path) => {
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
                toml::from_str(&text).map_err(|e| {
                    format!("invalid configuration {}: {}", path.display(), e.message())
                })?
            }
            None => StudyConfig::default(),
        };
        cfg.runs = runs.unwrap_or(cfg.runs);
        cfg.steps = steps.unwrap_or(cfg.steps);
        cfg.seed = seed.unwrap_or(cfg.seed);
        cfg.validate().map_err(|e| e.to_string())?;
        let model = Model::new(&cfg.scenario).map_err(|e| e.to_string())?;
        let bar = ProgressBar::new(cfg.runs as u64).with_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} runs, {elapsed} (eta {eta})")
                .map_err(|e| e.to_string())?,
        );
        let started = std::time::Instant::now();
        let traces = (0..cfg.runs as u64)
            .into_par_iter()
            .map(|r| {
                let t = simulate_run(&model, &cfg.run_spec(r, Storage::Blocks));
                bar.inc(1);
                t
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| e.to_string())?;
        bar.finish_and_clear();
        let summary = summarize(&traces, model.dim());
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
        let names = ["central", "ci", "nmci", "naive"];
        for (file, series) in [
            ("nees.csv", &summary.nees_series),
            ("rmse.csv", &summary.rmse_series),
            ("two_sigma.csv", &summary.two_sigma_series),
        ] {
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
        csv += "\n";
        for (r, t) in traces.iter().enumerate() {
            for k in 0..t.omega_ci.len() {
                csv += &format!("{},{},{}", k + 1, r, t.omega_ci[k]);
                for w in &t.omega_nmci[k] {
                    csv += &format!(",{w}");
                }
                csv += "\n";
            }
        }
        write("omega.csv", csv)?;
        Ok(format!(
            "{} runs × {} steps in {:.1} s; wrote {}/summary.json and per-step CSVs\n{}",
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

    pub fn main() -> ExitCode {
        let cli = Cli::parse();
        let result = match cli.command {
            Command::Fuse { file } => {
                read_input(file).and_then(|text| nmci::fuse_json(&text).map_err(|e| e.to_string()))
            }
            Command::Track {
                config,
                runs,
                steps,
                seed,
                out,
            } => track(config, runs, steps, seed, out),
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
