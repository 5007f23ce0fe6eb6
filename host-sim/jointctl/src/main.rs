//! `jointctl`: see `jointctl --help`. The binary only parses arguments and reports errors;
//! every subcommand lives in `jointctl::cli`.

use clap::Parser;

/// mimalloc instead of glibc's malloc: the diagnosis of a 1 M-sample log allocates and frees
/// dozens of column-sized buffers, which glibc returns to the kernel and faults in again.
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

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
