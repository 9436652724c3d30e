//! `nmci` command-line interface.
//!
//! `nmci fuse [FILE]` reads a JSON fusion request from FILE (or standard input) and prints
//! the JSON response; invalid input exits non-zero with a one-line message on stderr.

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
