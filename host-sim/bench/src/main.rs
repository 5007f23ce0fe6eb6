//! `diag-bench`: generate diagnosis test cases (`gen`) and score `jointctl diagnose` on
//! them (`run`). See the library's documentation and README.md for the seeds' rules.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Parser, Subcommand, ValueEnum};

use diag_bench::gen::{run_gen, ModeSel};
use diag_bench::score::{run, RunOpts};

#[derive(Parser)]
#[command(name = "diag-bench", about = "Independent generator and black-box scorer for jointctl diagnose")]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Clone, Copy, ValueEnum)]
enum ModeArg {
    Torque,
    Trajectory,
    Any,
}

#[derive(Subcommand)]
enum Cmd {
    /// Write DIR/case-KKKK/{log.csv, model.toml, truth.json} and DIR/manifest.json.
    Gen {
        #[arg(long)]
        seed: u64,
        #[arg(long)]
        cases: u64,
        #[arg(long)]
        out: PathBuf,
        /// One family (e.g. stribeck, none, compound, or "stribeck+position_ripple");
        /// default: the mix with ≥ 30 % none.
        #[arg(long)]
        family: Option<String>,
        #[arg(long, value_enum, default_value = "any")]
        mode: ModeArg,
        /// Also write clean.csv (noise-free t, q, qd, qdd, u, tau) per case, for checks of
        /// signal preparation; never give it to the tool under test.
        #[arg(long)]
        clean: bool,
    },
    /// Run `JOINTCTL diagnose` on every case and score the verdicts.
    Run {
        /// A folder written by `gen` (repeat for several seeds).
        #[arg(long = "cases-dir", required = true)]
        cases_dir: Vec<PathBuf>,
        #[arg(long)]
        jointctl: PathBuf,
        #[arg(long)]
        json: Option<PathBuf>,
        #[arg(long, default_value_t = 2)]
        jobs: usize,
        /// Seconds before a case's diagnose is killed and counted as refused.
        #[arg(long, default_value_t = 600.0)]
        timeout: f64,
    },
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().cmd {
        Cmd::Gen { seed, cases, out, family, mode, clean } => {
            let sel = match mode {
                ModeArg::Torque => ModeSel::Torque,
                ModeArg::Trajectory => ModeSel::Trajectory,
                ModeArg::Any => ModeSel::Any,
            };
            run_gen(seed, cases, &out, family.as_deref(), sel, clean)
        }
        Cmd::Run { cases_dir, jointctl, json, jobs, timeout } => run(&RunOpts {
            cases_dirs: cases_dir,
            jointctl,
            json_out: json,
            jobs,
            timeout: Duration::from_secs_f64(timeout.max(1.0)),
        }),
    }
}
