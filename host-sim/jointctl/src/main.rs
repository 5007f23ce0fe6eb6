//! `jointctl`: see `jointctl --help`. The binary only parses arguments and reports errors;
//! every subcommand lives in `jointctl::cli`.

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = jointctl::cli::Cli::parse();
    match jointctl::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
