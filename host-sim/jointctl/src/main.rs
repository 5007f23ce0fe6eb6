//! `jointctl`: see `jointctl --help`. The binary only parses arguments and reports errors;
//! every subcommand lives in `host_sim::cli`.

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = host_sim::cli::Cli::parse();
    match host_sim::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
