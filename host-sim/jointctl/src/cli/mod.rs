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
    long_about = long_about(),
    propagate_version = true
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// The top-level help. Its section lists follow from the parameter table and the effect
/// vocabulary: a model's own sections are the table's sections that are no effect term, the
/// effect terms listed are those the joint compensates (their sections have parameters in the
/// table), so a term added to the table is in the help at once.
pub fn long_about() -> String {
    use joint_core::params;
    use joint_formats::vocab::Effect;
    let list = |v: Vec<&str>| v.iter().map(|s| format!("[{s}]")).collect::<Vec<_>>().join(", ");
    let own: Vec<&str> = params::sections().filter(|s| Effect::from_section(s).is_none()).collect();
    let terms: Vec<&str> = Effect::terms().filter(|e| e.compensable()).filter_map(Effect::section).collect();
    let presliding = Effect::PreslidingHysteresis.section().unwrap_or_default();
    let dry = Effect::DryFriction.section().unwrap_or_default();
    format!(
        "Host tool for the exoskeleton/robot-arm joint boards.\n\n\
        Files: a joint log is a CSV (t, q, qd, qdd, u, tau, temp, q_<joint> columns, SI units); \
        a model is a TOML of optional sections: its own terms {}, [gravity_series] (a multi-angle \
        sine series, docs/arm-gravity.md), and the effect terms the joint can compensate: {}. \
        [{presliding}] sigma makes the Coulomb friction a Dahl pre-sliding state that builds up \
        over c/sigma after each reversal instead of c·sign(qd), its level [friction] c plus \
        [{dry}] c. A plant is a model plus the unmodelled effects and sensor noise of a simulated \
        joint. See shared/spec/formats.md.",
        list(own),
        list(terms)
    )
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

#[cfg(test)]
mod tests {
    use super::*;
    use joint_formats::vocab::Effect;

    /// Every section of the parameter table is in the help, every effect term the joint
    /// compensates too, and no effect term it cannot run (a plant's, not a model's).
    #[test]
    fn the_help_names_every_model_section_and_only_the_compensable_terms() {
        let help = long_about();
        for s in joint_core::params::sections() {
            assert!(help.contains(&format!("[{s}]")), "[{s}] missing: {help}");
        }
        for e in Effect::terms() {
            let s = format!("[{}]", e.section().unwrap());
            assert_eq!(help.contains(&s), e.compensable(), "{s}: {help}");
        }
        assert!(help.contains("[gravity_series]"));
    }
}
