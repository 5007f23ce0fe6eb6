//! `cargo bench -p host-sim --bench diagnose`: a 1 M-sample torque-mode log (1000 s at 1 kHz,
//! Stribeck withheld from the model) diagnosed end to end — CSV read plus the full diagnosis —
//! with wall time and peak memory (VmHWM from /proc/self/status) printed. The log is generated
//! in this process, written to a temporary CSV, and the measurement runs in a fresh child
//! process so the simulator's memory does not count. Targets: ≤ 2 s and ≤ 500 MB.
//! `DIAG_BENCH_SAMPLES` changes the size; `DIAG_BENCH_KEEP=DIR` keeps the CSV and model there
//! (the NumPy reference tests/python/bench_numpy_diagnose.py reads the same files).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::process::Command;

/// jointctl's allocator (host-sim/jointctl/src/main.rs), so this measures what jointctl does.
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;
use std::time::Instant;

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{simulate, SimConfig};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

const MODEL: &str = "[friction]\na = 0.5\nb = 2.0\nc = 1.0\nv_band = 0.01\n[weight]\namplitude = 2.5\ns = 0.802\nphi = 0.0\n[inertia]\nj = 0.4\n[offset]\nc0 = -0.3\n";

fn vm_hwm_mb() -> f64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|k| k.parse::<f64>().ok())
        .map(|kb| kb / 1024.0)
        .unwrap_or(f64::NAN)
}

fn child(log: &str, model: &str) {
    let t0 = Instant::now();
    let l = JointLog::read_file(std::path::Path::new(log)).unwrap();
    let t_read = t0.elapsed().as_secs_f64();
    let m = ModelFile::read_file(std::path::Path::new(model)).unwrap();
    let t1 = Instant::now();
    let samples = l.len();
    // as `jointctl diagnose` without --emit-model: the log handed over, not copied
    let d = joint_analysis::diagnose::diagnose_owned(l, &m, &joint_analysis::diagnose::Options::default()).unwrap();
    let t_diag = t1.elapsed().as_secs_f64();
    let json = serde_json::to_string(&d.report).unwrap();
    let total = t0.elapsed().as_secs_f64();
    println!(
        "diagnose {} samples: read {t_read:.3} s + diagnose {t_diag:.3} s = {total:.3} s wall; peak RSS (VmHWM) {:.0} MB; verdict {} (shrink {:.1} %); {} B of JSON",
        samples,
        vm_hwm_mb(),
        d.report.verdict.effect,
        100.0 * d.report.verdict.shrink,
        json.len()
    );
    println!("DIAG_BENCH total_s={total:.4} diagnose_s={t_diag:.4} read_s={t_read:.4} vmhwm_mb={:.1}", vm_hwm_mb());
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let (Ok(log), Ok(model)) = (std::env::var("DIAG_BENCH_LOG"), std::env::var("DIAG_BENCH_MODEL")) {
        child(&log, &model);
        return;
    }
    let samples: usize = std::env::var("DIAG_BENCH_SAMPLES").ok().and_then(|s| s.parse().ok()).unwrap_or(1_000_000);
    let keep = std::env::var("DIAG_BENCH_KEEP").ok();
    let tmp = tempfile::tempdir().unwrap();
    let dir = keep.as_ref().map(std::path::PathBuf::from).unwrap_or_else(|| tmp.path().to_path_buf());
    std::fs::create_dir_all(&dir).unwrap();
    let (log_path, model_path) = (dir.join("bench-1m.csv"), dir.join("bench-model.toml"));
    if !log_path.exists() {
        let plant = PlantFile::parse(
            &format!("{MODEL}[stribeck]\nlevel = 0.8\nspeed = 0.05\n[sensors]\nq_noise = 0.0001\nqd_noise = 0.002\nqdd_noise = 0.3\ntau_noise = 0.08\n[joint_range]\nmin = 0.0\nmax = 2.0\n"),
            "bench-plant",
        )
        .unwrap();
        let model = ModelFile::parse(MODEL, "bench-model").unwrap();
        let secs = samples as f64 / 1000.0 / 3.0;
        let cfg = SimConfig {
            scenarios: vec![ScenarioKind::Sweep, ScenarioKind::Poses, ScenarioKind::Hand],
            seconds: secs,
            rate: Some(1000.0),
            range: Some((0.0, 2.0)),
            ..SimConfig::default()
        };
        let t = Instant::now();
        let (log, _) = simulate(&plant, &model.param_set().unwrap(), &cfg).unwrap();
        log.write_file(&log_path).unwrap();
        std::fs::write(&model_path, MODEL).unwrap();
        eprintln!("generated {} samples in {:.1} s → {}", log.len(), t.elapsed().as_secs_f64(), log_path.display());
    }
    let _ = args;
    let exe = std::env::current_exe().unwrap();
    let out = Command::new(exe).env("DIAG_BENCH_LOG", &log_path).env("DIAG_BENCH_MODEL", &model_path).output().unwrap();
    print!("{}", String::from_utf8_lossy(&out.stdout));
    eprint!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success());
}
