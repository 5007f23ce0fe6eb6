//! Where the gap lies: every sample is tagged with the regimes it belongs to (a bit mask), so the
//! residual of any model can be split by regime in one pass. Regimes come in families that each
//! partition the samples (speed: static / low / high; position: four bands; time or temperature:
//! early / late) plus two overlapping windows (around velocity reversals, high acceleration);
//! a regime's `share` is its part of the summed squared residual, so the shares of one family
//! add up to 1.
//!
//! Thresholds come from the data (percentiles of |q̇| and |q̈|), and each regime states them in
//! its `where` text so a reader can check them against the log.

use serde::Serialize;

/// One regime's definition.
#[derive(Clone, Debug, Serialize)]
pub struct RegimeDef {
    pub name: String,
    pub family: &'static str,
    #[serde(rename = "where")]
    pub where_: String,
}

/// The regimes of one log and each sample's membership bits.
#[derive(Clone, Debug)]
pub struct Regimes {
    pub defs: Vec<RegimeDef>,
    pub bits: Vec<u32>,
}

fn percentile(v: &[f64], p: f64) -> f64 {
    crate::prep::quantile::at_rounded(&mut v.to_vec(), p).unwrap_or(0.0)
}

/// Every stride-th value, for percentiles of long logs.
fn thin(v: &[f64]) -> Vec<f64> {
    let stride = (v.len() / 50_000).max(1);
    v.iter().step_by(stride).copied().collect()
}

impl Regimes {
    /// Tags the samples. `window` = half-width in samples of a reversal window.
    pub fn build(t: &[f64], q: &[f64], qd: &[f64], qdd: &[f64], temp: Option<&[f64]>, dt: f64) -> Regimes {
        let n = q.len();
        let mut defs: Vec<RegimeDef> = Vec::new();
        let mut bits = vec![0u32; n];
        let mut add = |name: &str, family: &'static str, where_: String| {
            defs.push(RegimeDef { name: name.to_string(), family, where_ });
            defs.len() - 1
        };
        let aqd: Vec<f64> = thin(&qd.iter().map(|v| v.abs()).collect::<Vec<_>>());
        let v95 = percentile(&aqd, 0.95).max(1e-6);
        let v_static = (0.02 * v95).max(1e-4);
        let v_low = 0.2 * v95;
        let r_static = add("static", "speed", format!("|qd| < {v_static:.4} rad/s"));
        let r_low = add("low_speed", "speed", format!("{v_static:.4} ≤ |qd| < {v_low:.4} rad/s"));
        let r_high = add("high_speed", "speed", format!("|qd| ≥ {v_low:.4} rad/s"));
        // Reversals: sign changes of q̇ between excursions beyond the low-speed limit, so noise
        // around a standstill does not count as a reversal.
        let half = ((0.05 / dt.max(1e-6)).round() as usize).clamp(2, 500);
        let r_rev = add(
            "reversal",
            "reversal",
            format!("±{:.3} s around a change of the direction of motion", half as f64 * dt),
        );
        let aqdd: Vec<f64> = thin(&qdd.iter().map(|v| v.abs()).collect::<Vec<_>>());
        let a90 = percentile(&aqdd, 0.9);
        let r_acc = add("high_accel", "acceleration", format!("|qdd| > {a90:.4} rad/s² (top 10 %)"));
        let qs = thin(q);
        let qb: Vec<f64> = [0.25, 0.5, 0.75].iter().map(|&p| percentile(&qs, p)).collect();
        let mut r_pos = [0usize; 4];
        for (k, r) in r_pos.iter_mut().enumerate() {
            let lo = if k == 0 { "min".to_string() } else { format!("{:.4}", qb[k - 1]) };
            let hi = if k == 3 { "max".to_string() } else { format!("{:.4}", qb[k]) };
            *r = add(
                &format!("position_band_{}", k + 1),
                "position",
                format!("q in [{lo}, {hi}) rad (quartile {})", k + 1),
            );
        }
        let (r_early, r_late, split_val, by_temp) = match temp {
            Some(tp) if percentile(&thin(tp), 0.9) - percentile(&thin(tp), 0.1) > 0.5 => {
                let m = percentile(&thin(tp), 0.5);
                (
                    add("cool", "temperature", format!("temp < {m:.2} °C")),
                    add("warm", "temperature", format!("temp ≥ {m:.2} °C")),
                    m,
                    true,
                )
            }
            _ => {
                let m = 0.5 * (t[0] + t[n - 1]);
                (add("early", "time", format!("t < {m:.3} s")), add("late", "time", format!("t ≥ {m:.3} s")), m, false)
            }
        };
        let mut reversals: Vec<usize> = Vec::new();
        let mut last_dir = 0i8;
        let mut last_idx = 0usize;
        for i in 0..n {
            let v = qd[i].abs();
            let mut b = 0u32;
            b |= 1
                << if v < v_static {
                    r_static
                } else if v < v_low {
                    r_low
                } else {
                    r_high
                };
            if qdd[i].abs() > a90 {
                b |= 1 << r_acc;
            }
            let band = qb.iter().filter(|&&x| q[i] >= x).count();
            b |= 1 << r_pos[band.min(3)];
            let late = if by_temp { temp.map(|tp| tp[i] >= split_val).unwrap_or(false) } else { t[i] >= split_val };
            b |= 1 << if late { r_late } else { r_early };
            bits[i] = b;
            if v >= v_low {
                let dir = if qd[i] > 0.0 { 1 } else { -1 };
                if last_dir != 0 && dir != last_dir {
                    // The reversal sits where q̇ crossed zero between the two excursions.
                    let mut z = last_idx;
                    for k in last_idx..=i {
                        if qd[k] * f64::from(dir) > 0.0 {
                            z = k;
                            break;
                        }
                    }
                    reversals.push(z);
                }
                last_dir = dir;
                last_idx = i;
            }
        }
        for z in reversals {
            let lo = z.saturating_sub(half);
            let hi = (z + half).min(n - 1);
            for bk in bits.iter_mut().take(hi + 1).skip(lo) {
                *bk |= 1 << r_rev;
            }
        }
        Regimes { defs, bits }
    }
}
