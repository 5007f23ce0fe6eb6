//! `jointctl arm-gravity`: the arm paper's gravity fusion end to end on four simulated joint
//! nodes (docs/arm-gravity.md).

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use super::num;
use crate::arm::{self, cad::others_of, ArmConfig, Method, CLAMP_K_OFF};
use joint_formats::model_file::ModelFile;
use joint_formats::output::{FolderKind, Plan};

/// What `--tables DIR` writes; an existing folder holding only these is a previous run's and
/// is replaced as a whole, anything else in it makes the run refuse.
pub const TABLES: FolderKind = FolderKind {
    what: "the arm's model tables (arm-joint1.toml … arm-joint4.toml)",
    owns: |name| matches!(name, "arm-joint1.toml" | "arm-joint2.toml" | "arm-joint3.toml" | "arm-joint4.toml"),
};

/// Arm gravity fusion (arm paper): a 4-joint arm whose CAD model is the paper's Appendix A,
/// a plant with the torques the CAD model misses (cable, joint compliance, an assembly offset,
/// mass/centroid error), identification from static poses on the paper's 10° grid (σ_m and a
/// residual table per joint), then four joint nodes running the firmware core on a simulated
/// CAN bus, each receiving its model by SDO push and the other joints' angles by PDO. Prints
/// RRMSE and maximum error of CAD only, table only and fused at random configurations beside
/// the paper's Tables 5 and 6, and what the clamp τ_m ± k·σ_m does beyond the table's range.
///
/// Example:
///   jointctl arm-gravity --seed 1 --configs 10 --clamp-k 1 --json arm.json --tables models/
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct ArmArgs {
    /// Random seed (measurement noise and the scored configurations)
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// Random configurations inside the identified range to score, 1..=1000
    #[arg(long, value_name = "N", default_value_t = 10, value_parser = num::count(1, 1000))]
    pub configs: usize,
    /// Configurations beyond the range (the clamp demonstration), 0..=1000
    #[arg(long, value_name = "N", default_value_t = 6, value_parser = num::count(0, 1000))]
    pub out_configs: usize,
    /// Clamp coefficient k of τ_m ± k·σ_m (0 < k ≤ 100)
    #[arg(long, value_name = "K", default_value_t = 1.0, value_parser = num::positive(CLAMP_K_OFF, ""))]
    pub clamp_k: f64,
    /// Samples averaged per identification pose (the paper: 1000), 1..=100000
    #[arg(long, value_name = "N", default_value_t = 1000, value_parser = num::count(1, 100_000))]
    pub cycles: usize,
    /// Write the JSON result here (- for stdout)
    #[arg(long, value_name = "OUT.json")]
    pub json: PathBuf,
    /// Write each joint's fused model TOML (series, residual table, σ_m, k) into this directory,
    /// built aside and moved into place whole (an existing DIR is replaced only if it holds
    /// a previous run's tables)
    #[arg(long, value_name = "DIR")]
    pub tables: Option<PathBuf>,
}

pub fn run(a: &ArmArgs) -> anyhow::Result<()> {
    let mut plan = Plan::new();
    let json_out = plan.file("--json", &a.json);
    let tables_out = plan.folder_opt("--tables", a.tables.as_deref(), TABLES);
    let outs = plan.check()?;
    let cfg = ArmConfig {
        seed: a.seed,
        configs: a.configs,
        out_configs: a.out_configs,
        clamp_k: a.clamp_k,
        id_cycles: a.cycles,
        ..ArmConfig::default()
    };
    let (report, id) = arm::run(&cfg, &mut |s| eprintln!("arm-gravity: {s}"))?;
    say_raw!(outs.human(), "{}", arm::format_report(&report));
    let text = serde_json::to_string_pretty(&report)?;
    let mut json = outs.open(json_out)?;
    json.write_all(text.as_bytes()).with_context(|| format!("{}: cannot write", json.named()))?;
    if let (Some(slot), Some(shown)) = (tables_out, &a.tables) {
        let st = outs.stage(slot)?;
        let dir = st.path();
        for j in 0..4 {
            let raw = arm::joint_params(&id, j, Method::Fused(a.clamp_k));
            let cols: Vec<String> = others_of(j).iter().map(|o| format!("q_j{}", o + 1)).collect();
            let mf = ModelFile::from_raw(&raw, Some(&format!("arm joint {}", j + 1)), &cols);
            let name = format!("arm-joint{}.toml", j + 1);
            let path = dir.join(&name);
            std::fs::write(&path, mf.to_toml_string())
                .with_context(|| format!("{}: cannot write {name}", st.named()))?;
            // what was written must read back to the same parameters (checked before it is moved
            // into place, so a table that does not survive the file never replaces a good one)
            let back = ModelFile::read_file(&path)?.raw_params()?;
            if back != raw {
                anyhow::bail!("{}: {name} does not read back to the pushed parameters", st.named());
            }
        }
        st.commit()?;
        eprintln!("arm-gravity: models in {}", shown.display());
    }
    json.commit()?;
    Ok(())
}
