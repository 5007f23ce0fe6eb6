//! Arm gravity fusion end to end (arm paper §3.2, §4.3–4.4): a 4-joint arm whose CAD model is
//! the paper's Appendix A ([`cad`]), a plant that adds what the CAD model misses ([`plant`]),
//! identification from static poses on the paper's grid ([`identify`]), and four joint nodes
//! running the firmware core on one simulated CAN bus ([`bus`]).
//!
//! What runs: the CAD model is expanded into each joint's trigonometric series on the host and
//! pushed to the joint with its residual table, σ_m and clamp k by SDO. Every joint takes the
//! other joints' angles from their TPDOs and computes, in its control step, the model torque
//! τ_m (series), the data estimate τ_m + r(q_subset) (residual table), and the fused torque
//! `τ_f = fuse(τ_m, σ_m, τ_m + r, σ_r, k)` (inverse-variance weights, clamp τ_m ± k·σ_m). The
//! three predictions are three pushes of the same nodes: CAD only (series, no table), table
//! only (series + residual table, σ_m = 0 so the table is added as is) and fused. They are
//! scored at random static configurations against the plant's averaged steady-state torque:
//! RRMSE (eq. 11) and maximum absolute error per joint, beside the paper's Tables 5 and 6.
//! Configurations beyond the identified range show what the clamp does.

#![allow(clippy::indexing_slicing)] // numerical code over fixed 4-joint arrays and equal-length vectors

pub mod bus;
pub mod cad;
pub mod identify;
pub mod plant;

use cad::CadModel;
use identify::{Dataset, ResidualTable, DEG, RANGE_DEG};
use joint_core::params::{ParamId, RawParams};
use plant::ArmPlant;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// Paper Table 5, RRMSE %, joints 1..4.
pub const PAPER_RRMSE_CAD: [f64; 4] = [7.75, 8.25, 5.04, 9.97];
pub const PAPER_RRMSE_BNN: [f64; 4] = [2.80, 3.27, 2.90, 9.45];
pub const PAPER_RRMSE_FUSED: [f64; 4] = [5.32, 5.60, 3.61, 9.45];
/// Paper Table 6, maximum absolute error, N·m.
pub const PAPER_MAX_CAD: [f64; 4] = [1.4883, 0.96760, 0.5250, 0.4368];
pub const PAPER_MAX_BNN: [f64; 4] = [0.3985, 0.3989, 0.3846, 0.3746];
pub const PAPER_MAX_FUSED: [f64; 4] = [0.8891, 0.7165, 0.4346, 0.3746];

/// The largest clamp coefficient the core accepts (`gravity_table_clamp_k` ≤ 100): "no clamp".
pub const CLAMP_K_OFF: f64 = 100.0;

#[derive(Clone, Debug)]
pub struct ArmConfig {
    pub seed: u64,
    /// random in-range configurations scored
    pub configs: usize,
    /// configurations beyond the table's range (clamp demonstration)
    pub out_configs: usize,
    /// how far beyond S_j those go, degrees (each joint drawn in S_j … S_j + this)
    pub out_margin_deg: f64,
    /// the joint (0-based) swept across its range edge, and how far beyond, degrees
    pub sweep_joint: usize,
    pub sweep_margin_deg: f64,
    pub clamp_k: f64,
    /// samples averaged per identification pose (the paper: 1000)
    pub id_cycles: usize,
    /// samples averaged per scored configuration (the paper: 5 s at 1 kHz)
    pub eval_cycles: usize,
}

impl Default for ArmConfig {
    fn default() -> Self {
        ArmConfig {
            seed: 1,
            configs: 10,
            out_configs: 6,
            out_margin_deg: 30.0,
            sweep_joint: 0,
            sweep_margin_deg: 40.0,
            clamp_k: 1.0,
            id_cycles: 1000,
            eval_cycles: 5000,
        }
    }
}

/// RRMSE (%) and maximum absolute error (N·m) per joint of one method.
#[derive(Clone, Debug, Serialize)]
pub struct Score {
    pub rrmse_pct: [f64; 4],
    pub max_abs: [f64; 4],
}

fn score(pred: &[[f64; 4]], meas: &[[f64; 4]]) -> Score {
    let rrmse_pct = std::array::from_fn(|j| {
        let num: f64 = pred.iter().zip(meas).map(|(p, m)| (p[j] - m[j]).powi(2)).sum::<f64>().sqrt();
        let den: f64 = meas.iter().map(|m| m[j] * m[j]).sum::<f64>().sqrt();
        100.0 * num / den
    });
    let max_abs = std::array::from_fn(|j| pred.iter().zip(meas).map(|(p, m)| (p[j] - m[j]).abs()).fold(0.0, f64::max));
    Score { rrmse_pct, max_abs }
}

#[derive(Clone, Debug, Serialize)]
pub struct JointIdent {
    /// σ_m, N·m (eq. 6)
    pub sigma_m: f64,
    /// RMSE of the CAD model over the data set, N·m (eq. 10)
    pub rmse_m: f64,
    pub mean_residual: f64,
    /// the table's axes, as joint numbers 1..=4
    pub table_joints: Vec<usize>,
    pub table_points: Vec<usize>,
    /// share of the residual variance the chosen table explains
    pub explained: f64,
    /// every candidate axis set (joint numbers) and the variance it explains
    pub candidates: Vec<(Vec<usize>, f64)>,
    pub series_terms: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct Configs {
    /// motor angles, degrees
    pub q_deg: Vec<[f64; 4]>,
    pub measured: Vec<[f64; 4]>,
    pub cad: Vec<[f64; 4]>,
    pub table: Vec<[f64; 4]>,
    pub fused: Vec<[f64; 4]>,
}

#[derive(Clone, Debug, Serialize)]
pub struct InRange {
    pub cad: Score,
    pub table: Score,
    pub fused: Score,
    /// share of (configuration, joint) pairs where the clamp held the fused torque at its band
    pub clamp_active_share: f64,
    pub configs: Configs,
}

/// One joint swept from inside its range to beyond it, the others held.
#[derive(Clone, Debug, Serialize)]
pub struct Sweep {
    /// joint number 1..=4
    pub joint: usize,
    /// the other joints' angles, degrees
    pub held_deg: [f64; 4],
    /// the swept joint's angle, degrees
    pub q_deg: Vec<f64>,
    pub measured: Vec<f64>,
    pub cad: Vec<f64>,
    pub table: Vec<f64>,
    pub fused: Vec<f64>,
    pub fused_no_clamp: Vec<f64>,
    /// k·σ_m of the swept joint, N·m
    pub band: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct OutOfRange {
    pub cad: Score,
    pub table: Score,
    pub fused: Score,
    pub fused_no_clamp: Score,
    /// every fused torque within [τ_m − k·σ_m, τ_m + k·σ_m] as the core rounds it (f32)
    pub clamp_bound_holds: bool,
    /// largest |τ_f − τ_m| / (k·σ_m) seen (≤ 1 when the bound holds)
    pub max_deviation_over_band: f64,
    /// share of (configuration, joint) pairs where the clamp was active
    pub clamp_active_share: f64,
    /// largest |τ_f(no clamp) − τ_m| / (k·σ_m): how far the data would have pulled
    pub max_unclamped_over_band: f64,
    pub configs: Configs,
    pub fused_no_clamp_values: Vec<[f64; 4]>,
}

#[derive(Clone, Debug, Serialize)]
pub struct AppendixCheck {
    /// max |literal τ_j − ∂P/∂θ_j| over the identification grid, N·m
    pub literal_vs_gradient: [f64; 4],
    /// the same with θ3 + θ4 shifted by 90° in the literal τ3, τ4
    pub literal_shifted_vs_gradient: [f64; 4],
}

#[derive(Clone, Debug, Serialize)]
pub struct ArmReport {
    pub seed: u64,
    pub clamp_k: f64,
    pub id_cycles: usize,
    pub eval_cycles: usize,
    pub poses: usize,
    pub range_deg: [f64; 4],
    pub appendix_a: AppendixCheck,
    pub joints: Vec<JointIdent>,
    pub in_range: InRange,
    pub out_of_range: OutOfRange,
    pub sweep: Sweep,
    pub paper: serde_json::Value,
    /// SDO frames of the four pushes of the fused model
    pub push_frames: u64,
}

/// The identified model of every joint: series, residual table, σ_m.
pub struct Identified {
    pub series: Vec<joint_core::series::RawSeries>,
    pub tables: Vec<ResidualTable>,
    pub sigma_m: [f64; 4],
    pub joints: Vec<JointIdent>,
    pub poses: usize,
}

pub fn identify(cad_model: &CadModel, data: &Dataset) -> anyhow::Result<Identified> {
    let sig = identify::model_sigma(cad_model, data);
    let mut series = Vec::new();
    let mut tables = Vec::new();
    let mut joints = Vec::new();
    for (j, &(sd, rmse, mean)) in sig.iter().enumerate() {
        let terms = cad_model.series_terms(j);
        series.push(cad::core_series(&terms, j)?);
        let (t, cands) = identify::best_table(j, cad_model, data)?;
        joints.push(JointIdent {
            sigma_m: sd,
            rmse_m: rmse,
            mean_residual: mean,
            table_joints: t.joints.iter().map(|x| x + 1).collect(),
            table_points: t.grid.iter().map(Vec::len).collect(),
            explained: t.explained,
            candidates: cands.into_iter().map(|(a, e)| (a.into_iter().map(|x| x + 1).collect(), e)).collect(),
            series_terms: terms.len(),
        });
        tables.push(t);
    }
    Ok(Identified { series, tables, sigma_m: sig.map(|s| s.0), joints, poses: data.poses.len() })
}

/// Which prediction a push makes the joints compute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    Cad,
    Table,
    Fused(f64),
}

/// Joint `j`'s parameter set for `method`.
pub fn joint_params(id: &Identified, j: usize, method: Method) -> RawParams {
    let mut raw = RawParams::defaults();
    raw.series = id.series.get(j).cloned().unwrap_or_default();
    // The joint commands its gravity torque: all of C_c (no other term is pushed), within a
    // limit above any torque of this arm.
    raw.set(ParamId::Fraction, 1.0);
    raw.set(ParamId::TorqueLimit, 60.0);
    if method != Method::Cad {
        if let Some(t) = id.tables.get(j) {
            raw.table = t.raw(j);
        }
    }
    if let Method::Fused(k) = method {
        raw.set(ParamId::TableSigmaModel, id.sigma_m.get(j).copied().unwrap_or(0.0) as f32);
        raw.set(ParamId::TableClampK, k as f32);
    }
    raw
}

fn predict(bus: &mut bus::ArmBus, id: &Identified, method: Method, qs: &[[f64; 4]]) -> anyhow::Result<Vec<[f32; 4]>> {
    let sets: Vec<RawParams> = (0..4).map(|j| joint_params(id, j, method)).collect();
    bus.push(&sets)?;
    qs.iter().map(|q| bus.hold(q).map(|(g, _)| g)).collect()
}

fn widen(v: &[[f32; 4]]) -> Vec<[f64; 4]> {
    v.iter().map(|r| r.map(f64::from)).collect()
}

/// Run the whole experiment. `progress` gets a line per stage.
pub fn run(cfg: &ArmConfig, progress: &mut dyn FnMut(&str)) -> anyhow::Result<(ArmReport, Identified)> {
    if !(cfg.clamp_k.is_finite() && cfg.clamp_k > 0.0 && cfg.clamp_k <= CLAMP_K_OFF) {
        anyhow::bail!(
            "--clamp-k {}: must be in (0, {CLAMP_K_OFF}] (the core's gravity_table_clamp_k range)",
            cfg.clamp_k
        );
    }
    if cfg.configs == 0 {
        anyhow::bail!("--configs must be at least 1");
    }
    let cad_model = CadModel::paper();
    let plant = ArmPlant::default();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    progress(&format!("measuring {} static poses ({} cycles each)", identify::grid_poses().len(), cfg.id_cycles));
    let data = identify::collect(&plant, cfg.id_cycles, &mut rng);
    let (lit, lit_s) = cad::literal_mismatch(&cad_model, &data.poses);
    progress("fitting σ_m and the residual tables");
    let id = identify(&cad_model, &data)?;

    let lo = [0.0; 4];
    let hi = RANGE_DEG.map(|s| s * DEG);
    let q_in: Vec<[f64; 4]> = (0..cfg.configs).map(|_| plant::random_config(&lo, &hi, &mut rng)).collect();
    let hi_out = RANGE_DEG.map(|s| (s + cfg.out_margin_deg) * DEG);
    let q_out: Vec<[f64; 4]> = (0..cfg.out_configs).map(|_| plant::random_config(&hi, &hi_out, &mut rng)).collect();
    let meas_in: Vec<[f64; 4]> = q_in.iter().map(|q| plant.measure(q, cfg.eval_cycles, &mut rng)).collect();
    let meas_out: Vec<[f64; 4]> = q_out.iter().map(|q| plant.measure(q, cfg.eval_cycles, &mut rng)).collect();
    // the sweep: one joint from 0 to S_j + margin in 5° steps, the others mid-range
    let sj = cfg.sweep_joint.min(3);
    let held: [f64; 4] = RANGE_DEG.map(|s| 0.5 * s * DEG);
    let sweep_deg: Vec<f64> =
        (0..).map(|i| 5.0 * f64::from(i)).take_while(|&d| d <= RANGE_DEG[sj] + cfg.sweep_margin_deg + 1e-9).collect();
    let q_sweep: Vec<[f64; 4]> = sweep_deg
        .iter()
        .map(|&d| {
            let mut q = held;
            q[sj] = d * DEG;
            q
        })
        .collect();
    let meas_sweep: Vec<[f64; 4]> = q_sweep.iter().map(|q| plant.measure(q, cfg.eval_cycles, &mut rng)).collect();

    progress("four joint nodes on the simulated bus: CAD only, table only, fused, fused without clamp");
    let mut b = bus::ArmBus::new()?;
    let all: Vec<[f64; 4]> = q_in.iter().chain(&q_out).chain(&q_sweep).copied().collect();
    let cad_p = predict(&mut b, &id, Method::Cad, &all)?;
    let table_p = predict(&mut b, &id, Method::Table, &all)?;
    let f0 = b.master.sdo_frames;
    let fused_p = predict(&mut b, &id, Method::Fused(cfg.clamp_k), &all)?;
    let push_frames = b.master.sdo_frames - f0;
    let free_p = predict(&mut b, &id, Method::Fused(CLAMP_K_OFF), &all)?;

    let n = q_in.len();
    let n_out = n + q_out.len();
    let split = |v: &[[f32; 4]]| (widen(&v[..n]), widen(&v[n..n_out]));
    let sweep_col = |v: &[[f32; 4]]| v[n_out..].iter().map(|r| f64::from(r[sj])).collect::<Vec<f64>>();
    let (cad_in, cad_out) = split(&cad_p);
    let (tab_in, tab_out) = split(&table_p);
    let (fus_in, fus_out) = split(&fused_p);
    let (_, free_out) = split(&free_p);

    // The clamp, exactly as the core rounds it: fl(τ_m − band) ≤ τ_f ≤ fl(τ_m + band).
    let band_of = |j: usize| (cfg.clamp_k as f32 * id.sigma_m[j] as f32).abs();
    let at_band = |i: usize, j: usize| {
        let (tm, tf) = (cad_p[i][j], fused_p[i][j]);
        tf == tm - band_of(j) || tf == tm + band_of(j)
    };
    let active_in = (0..n).flat_map(|i| (0..4).map(move |j| (i, j))).filter(|&(i, j)| at_band(i, j)).count();
    let mut holds = true;
    let (mut worst, mut worst_free, mut active) = (0.0f64, 0.0f64, 0usize);
    // every configuration beyond the range: the random ones and the sweep's points past S_j
    let beyond: Vec<usize> = (n..n_out)
        .chain((0..q_sweep.len()).filter(|&k| sweep_deg[k] > RANGE_DEG[sj] + 1e-9).map(|k| n_out + k))
        .collect();
    for &i in &beyond {
        let row = &fused_p[i];
        for j in 0..4 {
            let tm = cad_p[i][j];
            let tf = row[j];
            let band = band_of(j);
            if !(tf >= tm - band && tf <= tm + band) {
                holds = false;
            }
            let dev = f64::from((tf - tm).abs()) / f64::from(band);
            worst = worst.max(dev);
            worst_free = worst_free.max(f64::from((free_p[i][j] - tm).abs()) / f64::from(band));
            if at_band(i, j) {
                active += 1;
            }
        }
    }

    let configs = |q: &[[f64; 4]], m: &[[f64; 4]], c: &[[f64; 4]], t: &[[f64; 4]], f: &[[f64; 4]]| Configs {
        q_deg: q.iter().map(|r| r.map(|x| x / DEG)).collect(),
        measured: m.to_vec(),
        cad: c.to_vec(),
        table: t.to_vec(),
        fused: f.to_vec(),
    };
    let report = ArmReport {
        seed: cfg.seed,
        clamp_k: cfg.clamp_k,
        id_cycles: cfg.id_cycles,
        eval_cycles: cfg.eval_cycles,
        poses: id.poses,
        range_deg: RANGE_DEG,
        appendix_a: AppendixCheck { literal_vs_gradient: lit, literal_shifted_vs_gradient: lit_s },
        joints: id.joints.clone(),
        in_range: InRange {
            cad: score(&cad_in, &meas_in),
            table: score(&tab_in, &meas_in),
            fused: score(&fus_in, &meas_in),
            clamp_active_share: active_in as f64 / (4 * n) as f64,
            configs: configs(&q_in, &meas_in, &cad_in, &tab_in, &fus_in),
        },
        out_of_range: OutOfRange {
            cad: score(&cad_out, &meas_out),
            table: score(&tab_out, &meas_out),
            fused: score(&fus_out, &meas_out),
            fused_no_clamp: score(&free_out, &meas_out),
            clamp_bound_holds: holds,
            max_deviation_over_band: worst,
            clamp_active_share: active as f64 / (4 * beyond.len()).max(1) as f64,
            max_unclamped_over_band: worst_free,
            configs: configs(&q_out, &meas_out, &cad_out, &tab_out, &fus_out),
            fused_no_clamp_values: free_out.clone(),
        },
        sweep: Sweep {
            joint: sj + 1,
            held_deg: held.map(|x| x / DEG),
            q_deg: sweep_deg.clone(),
            measured: meas_sweep.iter().map(|r| r[sj]).collect(),
            cad: sweep_col(&cad_p),
            table: sweep_col(&table_p),
            fused: sweep_col(&fused_p),
            fused_no_clamp: sweep_col(&free_p),
            band: f64::from(band_of(sj)),
        },
        paper: serde_json::json!({
            "table5_rrmse_pct": {"cad": PAPER_RRMSE_CAD, "bnn": PAPER_RRMSE_BNN, "fused": PAPER_RRMSE_FUSED},
            "table6_max_abs_nm": {"cad": PAPER_MAX_CAD, "bnn": PAPER_MAX_BNN, "fused": PAPER_MAX_FUSED},
        }),
        push_frames,
    };
    Ok((report, id))
}

/// Human-readable table of a report (what `jointctl arm-gravity` prints).
pub fn format_report(r: &ArmReport) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let row = |s: &mut String, name: &str, v: &[f64; 4], prec: usize| {
        let _ = writeln!(s, "  {name:<22}{}", v.iter().map(|x| format!("{x:>9.prec$}")).collect::<String>());
    };
    let _ = writeln!(s, "identification: {} static poses, {} cycles averaged each", r.poses, r.id_cycles);
    for (j, ji) in r.joints.iter().enumerate() {
        let _ = writeln!(
            s,
            "  joint {}: σ_m {:.3} N·m, {} series terms, residual table over joints {:?} ({:?} points) explains {:.0} %",
            j + 1,
            ji.sigma_m,
            ji.series_terms,
            ji.table_joints,
            ji.table_points,
            100.0 * ji.explained
        );
    }
    let _ = writeln!(
        s,
        "\n{} random configurations in range (seed {}), clamp k = {}",
        r.in_range.configs.q_deg.len(),
        r.seed,
        r.clamp_k
    );
    let _ = writeln!(s, "RRMSE %                     joint 1  joint 2  joint 3  joint 4");
    row(&mut s, "CAD only", &r.in_range.cad.rrmse_pct, 2);
    row(&mut s, "table only (τ_m + r)", &r.in_range.table.rrmse_pct, 2);
    row(&mut s, "fused", &r.in_range.fused.rrmse_pct, 2);
    row(&mut s, "paper CAD", &PAPER_RRMSE_CAD, 2);
    row(&mut s, "paper BNN", &PAPER_RRMSE_BNN, 2);
    row(&mut s, "paper fused", &PAPER_RRMSE_FUSED, 2);
    let _ = writeln!(s, "max |error| N·m");
    row(&mut s, "CAD only", &r.in_range.cad.max_abs, 3);
    row(&mut s, "table only (τ_m + r)", &r.in_range.table.max_abs, 3);
    row(&mut s, "fused", &r.in_range.fused.max_abs, 3);
    row(&mut s, "paper CAD", &PAPER_MAX_CAD, 3);
    row(&mut s, "paper BNN", &PAPER_MAX_BNN, 3);
    row(&mut s, "paper fused", &PAPER_MAX_FUSED, 3);
    let _ = writeln!(
        s,
        "clamp active (fused held at τ_m ± k·σ_m) in {:.0} % of joint-configurations in range",
        100.0 * r.in_range.clamp_active_share
    );
    let o = &r.out_of_range;
    let _ = writeln!(s, "\n{} configurations beyond the table's range (S_j … S_j + margin)", o.configs.q_deg.len());
    let _ = writeln!(s, "max |error| N·m             joint 1  joint 2  joint 3  joint 4");
    row(&mut s, "CAD only", &o.cad.max_abs, 3);
    row(&mut s, "table only", &o.table.max_abs, 3);
    row(&mut s, "fused, clamp k", &o.fused.max_abs, 3);
    row(&mut s, "fused, no clamp", &o.fused_no_clamp.max_abs, 3);
    let _ = writeln!(
        s,
        "clamp |τ_f − τ_m| ≤ k·σ_m: {} (largest {:.3} of the band; clamp active in {:.0} % of joint-configurations; unclamped the data pulls up to {:.2} bands)",
        if o.clamp_bound_holds { "holds" } else { "VIOLATED" },
        o.max_deviation_over_band,
        100.0 * o.clamp_active_share,
        o.max_unclamped_over_band
    );
    let w = &r.sweep;
    let held: Vec<String> =
        (0..4).filter(|&j| j + 1 != w.joint).map(|j| format!("q{} = {:.0}°", j + 1, w.held_deg[j])).collect();
    let _ = writeln!(
        s,
        "\njoint {} swept across its range edge ({}°), {}; error (N·m) = prediction − measured, band k·σ_m = {:.3}",
        w.joint,
        r.range_deg[w.joint - 1],
        held.join(", "),
        w.band
    );
    let _ = writeln!(s, "  q°      measured   CAD err  table err  fused err  no-clamp err  |τ_f−τ_m|");
    for (i, q) in w.q_deg.iter().enumerate() {
        if (q.round() as i64) % 10 != 0 {
            continue;
        }
        let m = w.measured[i];
        let _ = writeln!(
            s,
            "  {:>5.0} {:>10.3} {:>9.3} {:>10.3} {:>10.3} {:>13.3} {:>10.3}{}",
            q,
            m,
            w.cad[i] - m,
            w.table[i] - m,
            w.fused[i] - m,
            w.fused_no_clamp[i] - m,
            (w.fused[i] - w.cad[i]).abs(),
            if *q > r.range_deg[w.joint - 1] { "  beyond" } else { "" }
        );
    }
    s
}
