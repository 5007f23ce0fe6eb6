//! `jointctl arm-gravity`: the arm paper's gravity fusion end to end on four simulated joint
//! nodes (docs/arm-gravity.md).

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use crate::arm::{self, cad::others_of, ArmConfig, Method};
use joint_formats::log::write_atomic;
use joint_formats::model_file::ModelFile;

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
    /// Random configurations inside the identified range to score
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub configs: usize,
    /// Configurations beyond the range (the clamp demonstration)
    #[arg(long, value_name = "N", default_value_t = 6)]
    pub out_configs: usize,
    /// Clamp coefficient k of τ_m ± k·σ_m (0 < k ≤ 100)
    #[arg(long, value_name = "K", default_value_t = 1.0)]
    pub clamp_k: f64,
    /// Samples averaged per identification pose (the paper: 1000)
    #[arg(long, value_name = "N", default_value_t = 1000)]
    pub cycles: usize,
    /// Write the JSON result here
    #[arg(long, value_name = "OUT.json")]
    pub json: PathBuf,
    /// Write each joint's fused model TOML (series, residual table, σ_m, k) into this directory
    #[arg(long, value_name = "DIR")]
    pub tables: Option<PathBuf>,
}

pub fn run(a: &ArmArgs) -> anyhow::Result<()> {
    let cfg = ArmConfig {
        seed: a.seed,
        configs: a.configs,
        out_configs: a.out_configs,
        clamp_k: a.clamp_k,
        id_cycles: a.cycles,
        ..ArmConfig::default()
    };
    let (report, id) = arm::run(&cfg, &mut |s| eprintln!("arm-gravity: {s}"))?;
    print!("{}", arm::format_report(&report));
    let text = serde_json::to_string_pretty(&report)?;
    write_atomic(&a.json, |w| w.write_all(text.as_bytes())).with_context(|| format!("writing {}", a.json.display()))?;
    if let Some(dir) = &a.tables {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for j in 0..4 {
            let raw = arm::joint_params(&id, j, Method::Fused(a.clamp_k));
            let cols: Vec<String> = others_of(j).iter().map(|o| format!("q_j{}", o + 1)).collect();
            let mf = ModelFile::from_raw(&raw, Some(&format!("arm joint {}", j + 1)), &cols);
            let path = dir.join(format!("arm-joint{}.toml", j + 1));
            write_atomic(&path, |w| w.write_all(mf.to_toml_string().as_bytes()))
                .with_context(|| format!("writing {}", path.display()))?;
            // what was written must read back to the same parameters
            let back = ModelFile::read_file(&path)?.raw_params()?;
            if back != raw {
                anyhow::bail!("{}: does not read back to the pushed parameters", path.display());
            }
        }
        eprintln!("arm-gravity: models in {}", dir.display());
    }
    Ok(())
}
