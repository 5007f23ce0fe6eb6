//! Development check of the preparation stage against generated truth: for each case folder
//! written by `diag-bench gen --clean`, the derived q̇/q̈ against the noise-free signals.
//!   cargo run --release -p joint-analysis --example prep_check -- DIR...
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use joint_analysis::log::JointLog;
use joint_analysis::prep;

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0);
    for x in v {
        s += x * x;
        n += 1;
    }
    (s / n.max(1) as f64).sqrt()
}

fn main() {
    for dir in std::env::args().skip(1) {
        let log = JointLog::read_file(std::path::Path::new(&format!("{dir}/log.csv"))).unwrap();
        let clean = JointLog::read_file(std::path::Path::new(&format!("{dir}/clean.csv"))).unwrap();
        let p = match prep::prepare(&log) {
            Ok(p) => p,
            Err(e) => {
                println!("{dir}: refused: {e}");
                continue;
            }
        };
        if std::env::var_os("PREP_DUMP").is_some() {
            let mut out = String::from("t,qd,qdd,rest,amb,dir,qd_err,excl,qdd_err\n");
            for i in 0..p.log.len() {
                out.push_str(&format!(
                    "{},{},{},{},{},{},{},{},{}\n",
                    p.log.t[i],
                    p.qd()[i],
                    p.qdd()[i],
                    u8::from(p.rest[i]),
                    u8::from(p.ambiguous[i]),
                    p.direction[i],
                    p.qd_err[i],
                    u8::from(p.ambiguous[i] || p.sign_unknown[i] || p.rest_edge[i]),
                    p.qdd_err[i]
                ));
            }
            std::fs::write(format!("{dir}/prep.csv"), out).unwrap();
        }
        // match prepared samples to clean ones by time
        let mut j = 0;
        let (mut e1, mut e2, mut v1, mut v2) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (i, &t) in p.log.t.iter().enumerate() {
            while j < clean.t.len() && clean.t[j] < t - 1e-9 {
                j += 1;
            }
            if j >= clean.t.len() {
                break;
            }
            let cqd = clean.qd.as_ref().unwrap()[j];
            let cqdd = clean.qdd.as_ref().unwrap()[j];
            e1.push(p.qd()[i] - cqd);
            e2.push(p.qdd()[i] - cqdd);
            v1.push(cqd);
            v2.push(cqdd);
        }
        let r = &p.report;
        println!(
            "{dir}: n {} rate {:.0} Hz q_noise {:.2e} bw {:.1} Hz | qd {} h {:.1} ms: err {:.3e} (est {:.3e}) of rms {:.3e} | qdd {} h {:.1} ms: err {:.3e} (est {:.3e}) of rms {:.3e}",
            r.samples,
            r.median_rate_hz,
            r.q_noise_sd,
            r.motion_bandwidth_hz,
            r.qd.source,
            r.qd.half_window_s * 1e3,
            rms(e1.iter().copied()),
            r.qd.error_sd,
            rms(v1.iter().copied()),
            r.qdd.source,
            r.qdd.half_window_s * 1e3,
            rms(e2.iter().copied()),
            r.qdd.error_sd,
            rms(v2.iter().copied()),
        );
    }
}
