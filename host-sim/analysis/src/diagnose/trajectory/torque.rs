//! What the model misses as a torque, read sample by sample from the prepared derivatives:
//! `r = u − J·q̈ − D(q, q̇)`. Verdicts never come from it (the simulation fits and the held-out
//! angles do); it finds starts for a shape whose simulated fit is multimodal beyond the reach
//! of a fixed grid of starts. A short-period ripple of a few per cent of the torque scale has a
//! stiffness `2π·A/P` that can exceed the spring's or the weight's many times over (seed 7
//! case 0: 4.9 N·m at 0.032 rad against a 37 N·m pendulum, 960 against 37 N·m/rad): the joint
//! then settles in the ripple's wells, and a fit started at 2 % of the torque scale never
//! reaches that response; its period landed on 0.26 rad, 7× the truth. As a torque the ripple
//! is linear in its amplitudes: a periodogram over q gives period, amplitude and phase.

use super::sim::Law;

/// The torque residual over the usable training samples, with each sample's weight.
pub struct Torque {
    q: Vec<f64>,
    r: Vec<f64>,
    w: Vec<f64>,
}

/// What the residual is read from: per sample of the window.
pub struct Samples<'a> {
    pub q: &'a [f64],
    pub qd: &'a [f64],
    pub qdd: &'a [f64],
    pub u: Option<&'a [f64]>,
    /// the 1σ error of q̈ (its share of the torque error is J times it)
    pub qdd_err: &'a [f64],
    /// whether the sample moves in a known direction (not at rest, not ambiguous)
    pub moving: &'a [bool],
}

impl Torque {
    /// The residual of `law` at the samples `idx` that move; `None` with fewer than 20.
    pub fn new(law: &Law, s: &Samples, idx: &[usize]) -> Option<Torque> {
        let use_: Vec<usize> = idx.iter().copied().filter(|&i| s.moving.get(i).copied().unwrap_or(false)).collect();
        if use_.len() < 20 {
            return None;
        }
        let sd: Vec<f64> = use_.iter().map(|&i| law.j * s.qdd_err[i]).collect();
        // a sample's weight from its q̈ error, floored at the median error so a few samples
        // with a tiny error do not carry the fit
        let mut sorted = sd.clone();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let floor = sorted[sorted.len() / 2].max(1e-300);
        let w = sd.iter().map(|e| 1.0 / e.max(floor).powi(2)).collect();
        let r = use_
            .iter()
            .map(|&i| s.u.map_or(0.0, |u| u[i]) - law.j * s.qdd[i] - law.torque_at(s.q[i], s.qd[i]))
            .collect();
        Some(Torque { q: use_.iter().map(|&i| s.q[i]).collect(), r, w })
    }

    /// Ripple starts `[α, β, ln P]` in the law's convention (`α·sin(2πq/P) + β·cos(2πq/P)`
    /// added to D): periods every 1 % from `lo` to `hi`, each with its weighted least-squares
    /// amplitudes; the `keep` best local maxima of the fitted share, at least 10 % apart.
    pub fn ripple_starts(&self, lo: f64, hi: f64, keep: usize) -> Vec<Vec<f64>> {
        if !(lo > 0.0 && hi > lo) {
            return Vec::new();
        }
        let periods: Vec<f64> = (0..).map(|i| lo * 1.01f64.powi(i)).take_while(|p| *p <= hi).collect();
        let fit = |p: f64| {
            let (mut ss, mut sc, mut cc, mut sr, mut cr) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for ((&q, &r), &w) in self.q.iter().zip(&self.r).zip(&self.w) {
                let (sn, cs) = (std::f64::consts::TAU * q / p).sin_cos();
                ss += w * sn * sn;
                sc += w * sn * cs;
                cc += w * cs * cs;
                sr += w * sn * r;
                cr += w * cs * r;
            }
            let det = ss * cc - sc * sc;
            if !(det > 1e-12 * (ss * cc).max(1e-300)) {
                return (0.0, 0.0, 0.0);
            }
            // r = u − J·q̈ − D is what D lacks: α·sin + β·cos added to it
            let (a, b) = ((sr * cc - cr * sc) / det, (cr * ss - sr * sc) / det);
            (a * sr + b * cr, a, b)
        };
        let fits: Vec<(f64, f64, f64)> = periods.iter().map(|&p| fit(p)).collect();
        let mut peaks: Vec<usize> = (0..fits.len())
            .filter(|&i| {
                let g = fits[i].0;
                g > 0.0 && (i == 0 || fits[i - 1].0 <= g) && (i + 1 == fits.len() || fits[i + 1].0 <= g)
            })
            .collect();
        peaks.sort_by(|&a, &b| fits[b].0.total_cmp(&fits[a].0));
        let mut out: Vec<usize> = Vec::new();
        for i in peaks {
            if out.iter().all(|&k| (periods[i] / periods[k]).ln().abs() > 0.1f64.ln_1p()) {
                out.push(i);
            }
            if out.len() == keep {
                break;
            }
        }
        // each peak refined between its neighbours (golden section on the share): across tens of
        // periods a period 0.5 % off drifts a quarter period out of phase
        out.into_iter()
            .map(|i| {
                let (mut a, mut b) = (periods[i.saturating_sub(1)], periods[(i + 1).min(periods.len() - 1)]);
                let g = 0.5 * (5f64.sqrt() - 1.0);
                for _ in 0..30 {
                    let (x1, x2) = (b - g * (b - a), a + g * (b - a));
                    if fit(x1).0 >= fit(x2).0 {
                        b = x2;
                    } else {
                        a = x1;
                    }
                }
                let p = 0.5 * (a + b);
                let f = fit(p);
                if f.0 >= fits[i].0 {
                    vec![f.1, f.2, p.ln()]
                } else {
                    vec![fits[i].1, fits[i].2, periods[i].ln()]
                }
            })
            .collect()
    }
}
