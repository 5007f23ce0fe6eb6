//! The `jointctl` command line: one clap struct and one module per subcommand. Human-readable
//! output goes to stdout, progress and diagnostics to stderr, `--json` prints one JSON object
//! for scripts instead of the human summary.

use clap::{Parser, Subcommand};

/// `println!` to a chosen stream: stdout, or stderr when an output (`--out -`) took stdout (see
/// `joint_formats::output::Outputs::human`). A closed terminal is not worth failing a finished
/// run for, so write errors are dropped (where `println!` would have panicked).
macro_rules! say {
    ($o:expr) => {{
        let _ = writeln!($o);
    }};
    ($o:expr, $($a:tt)*) => {{
        let _ = writeln!($o, $($a)*);
    }};
}

/// `print!` to a chosen stream, as [`say!`].
macro_rules! say_raw {
    ($o:expr, $($a:tt)*) => {{
        let _ = write!($o, $($a)*);
    }};
}

pub mod arm;
pub mod bus_args;
pub mod bus_budget;
pub mod choice;
pub mod closed_loop;
pub mod diagnose;
pub mod diagnose_bench;
pub mod eds;
pub mod identify;
pub mod import;
pub mod log_can;
pub mod num;
pub mod pull;
pub mod push;
pub mod save;
pub mod scan;
pub mod sim_bus;
pub mod simulate;
pub mod status;
pub mod watch;

#[derive(Debug, Parser)]
#[command(
    name = "jointctl",
    version,
    about = "Host tool for the exoskeleton/robot-arm joint boards",
    long_about = "Host tool for the exoskeleton/robot-arm joint boards.\n\n\
        Files: a joint log is a CSV (t, q, qd, qdd, u, tau, temp, q_<joint> columns, SI units); \
        a model is a TOML with [friction], [weight], [inertia], [offset], [spring], \
        [gravity_table], [compensation] sections, optionally [controller], [gravity_series] \
        (a multi-angle sine series, docs/arm-gravity.md), [presliding] (sigma: the Coulomb \
        friction as a Dahl pre-sliding state that builds up over c/sigma after each reversal \
        instead of c·sign(qd); its level is [friction] c plus [dry_friction] c) and the effect \
        terms the joint can compensate ([stribeck], [asymmetric_friction], [position_ripple], \
        [cable_spring], [dry_friction]); a plant is a model plus the unmodelled \
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
    // CAN (issue 4)
    Push(push::PushArgs),
    Pull(pull::PullArgs),
    Save(save::SaveArgs),
    Status(status::StatusArgs),
    Discard(status::DiscardArgs),
    Scan(scan::ScanArgs),
    Watch(watch::WatchArgs),
    Log(log_can::LogArgs),
    Sim(sim_bus::SimArgs),
    Eds(eds::EdsArgs),
    BusBudget(bus_budget::BusBudgetArgs),
    // closed loop (issue 7)
    ClosedLoop(closed_loop::ClosedLoopArgs),
    // arm gravity fusion (issue 7)
    ArmGravity(arm::ArmArgs),
}

/// Runs the parsed command; errors carry the file/key/row/column they concern.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Simulate(args) => simulate::run(&args),
        Command::Diagnose(args) => diagnose::run(&args),
        Command::DiagnoseBench(args) => diagnose_bench::run(&args),
        Command::Identify(args) => identify::run(&args),
        Command::Import(args) => import::run(&args),
        Command::Push(args) => push::run(&args),
        Command::Pull(args) => pull::run(&args),
        Command::Save(args) => save::run(&args),
        Command::Status(args) => status::run_status(&args),
        Command::Discard(args) => status::run_discard(&args),
        Command::Scan(args) => scan::run(&args),
        Command::Watch(args) => watch::run(&args),
        Command::Log(args) => log_can::run(&args),
        Command::Sim(args) => sim_bus::run(&args),
        Command::Eds(args) => eds::run(&args),
        Command::BusBudget(args) => bus_budget::run(&args),
        Command::ClosedLoop(args) => closed_loop::run(&args),
        Command::ArmGravity(args) => arm::run(&args),
    }
}
