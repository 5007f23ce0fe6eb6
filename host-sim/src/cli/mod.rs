//! The `jointctl` command line: one clap struct and one module per subcommand. Human-readable
//! output goes to stdout, progress and diagnostics to stderr, `--json` prints one JSON object
//! for scripts instead of the human summary.

use clap::{Parser, Subcommand};

pub mod diagnose;
pub mod diagnose_bench;
pub mod identify;
pub mod import;
pub mod simulate;

#[derive(Debug, Parser)]
#[command(
    name = "jointctl",
    version,
    about = "Host tool for the exoskeleton/robot-arm joint boards",
    long_about = "Host tool for the exoskeleton/robot-arm joint boards.\n\n\
        Files: a joint log is a CSV (t, q, qd, qdd, u, tau, temp, q_<joint> columns, SI units); \
        a model is a TOML with [friction], [weight], [inertia], [offset], [spring], \
        [gravity_table], [compensation] sections; a plant is a model plus the unmodelled \
        effects and sensor noise of a simulated joint. See shared/spec/formats.md.",
    propagate_version = true
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    Simulate(simulate::SimulateArgs),
    Diagnose(diagnose::DiagnoseArgs),
    DiagnoseBench(diagnose_bench::DiagnoseBenchArgs),
    Identify(identify::IdentifyArgs),
    Import(import::ImportArgs),
}

/// Runs the parsed command; errors carry the file/key/row/column they concern.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Simulate(args) => simulate::run(&args),
        Command::Diagnose(args) => diagnose::run(&args),
        Command::DiagnoseBench(args) => diagnose_bench::run(&args),
        Command::Identify(args) => identify::run(&args),
        Command::Import(args) => import::run(&args),
    }
}
