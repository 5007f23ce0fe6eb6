//! Levenberg–Marquardt inside bounds, for fits through the simulation.
//!
//! A trial step is projected onto the bounds (a physical term cannot be fitted negative; a
//! shape parameter stays in its searched range), the Jacobian is a forward difference that
//! turns backward at an upper bound, and the result carries `JᵀJ` at the solution so a
//! parameter's standard error can be read from it (the fitted start's, for `initial_state`).

use crate::diagnose::fit::cholesky_solve;

/// A finished fit.
#[derive(Clone, Debug)]
pub struct Fit {
    pub theta: Vec<f64>,
    pub cost: f64,
    /// `JᵀJ` at `theta` (row-major, p×p), empty when no iteration ran
    pub jtj: Vec<f64>,
}

impl Fit {
    /// The standard error of parameter `k` for residuals of standard deviation `sd`
    /// (`None` when `JᵀJ` is singular there).
    pub fn std_err(&self, k: usize, sd: f64) -> Option<f64> {
        let p = self.theta.len();
        if self.jtj.len() != p * p || k >= p {
            return None;
        }
        let mut m = self.jtj.clone();
        // a tiny ridge relative to each diagonal keeps a flat direction from failing the solve
        for i in 0..p {
            m[i * p + i] += 1e-12 * m[i * p + i].abs().max(1e-300);
        }
        let mut e = vec![0.0; p];
        e[k] = 1.0;
        let x = cholesky_solve(&mut m, p, &e)?;
        let var = x.get(k).copied()?;
        (var > 0.0).then(|| sd * var.sqrt())
    }
}

/// Minimises `Σ r(θ)²` from `theta0` within `[lo, hi]`; `step` is each parameter's difference
/// step. `None` when the residual cannot be evaluated at the start.
pub fn fit(
    theta0: &[f64],
    lo: &[f64],
    hi: &[f64],
    step: &[f64],
    iters: usize,
    mut resid: impl FnMut(&[f64]) -> Option<Vec<f64>>,
) -> Option<Fit> {
    let p = theta0.len();
    let clamp = |th: &mut [f64]| {
        for ((x, l), h) in th.iter_mut().zip(lo).zip(hi) {
            *x = x.clamp(*l, *h);
        }
    };
    let mut theta = theta0.to_vec();
    clamp(&mut theta);
    let mut r = resid(&theta)?;
    let mut cost: f64 = r.iter().map(|x| x * x).sum();
    let mut lambda = 1e-3;
    // Finite differences cost one simulation per value: they are taken afresh every fourth
    // accepted step, and in between the Jacobian follows Broyden's rank-one updates along the
    // steps taken (each step's own residual change), which cost nothing extra.
    let fd = |theta: &[f64], r: &[f64], resid: &mut dyn FnMut(&[f64]) -> Option<Vec<f64>>| -> Vec<Vec<f64>> {
        (0..p)
            .map(|k| {
                let mut th = theta.to_vec();
                let h = if theta[k] + step[k] > hi[k] { -step[k] } else { step[k] };
                th[k] += h;
                match resid(&th) {
                    Some(rk) => rk.iter().zip(r).map(|(a, b)| (a - b) / h).collect(),
                    None => vec![0.0; r.len()],
                }
            })
            .collect()
    };
    let mut jac = fd(&theta, &r, &mut resid);
    let mut fresh = true;
    let mut since_fd = 0;
    let mut fds = 1;
    let mut jtj = Vec::new();
    while fds <= iters {
        let mut a = vec![0.0; p * p];
        let mut g = vec![0.0; p];
        for i in 0..p {
            for j in i..p {
                let s: f64 = jac[i].iter().zip(&jac[j]).map(|(x, y)| x * y).sum();
                a[i * p + j] = s;
                a[j * p + i] = s;
            }
            g[i] = jac[i].iter().zip(&r).map(|(x, y)| x * y).sum();
        }
        if fresh {
            jtj.clone_from(&a);
        }
        let mut accepted: Option<(Vec<f64>, Vec<f64>, f64)> = None;
        for _ in 0..6 {
            let mut m = a.clone();
            for i in 0..p {
                m[i * p + i] += lambda * a[i * p + i].max(1e-12);
            }
            let Some(delta) = cholesky_solve(&mut m, p, &g) else {
                lambda *= 10.0;
                continue;
            };
            let mut cand: Vec<f64> = theta.iter().zip(&delta).map(|(t, d)| t - d).collect();
            clamp(&mut cand);
            if let Some(rc) = resid(&cand) {
                let c: f64 = rc.iter().map(|x| x * x).sum();
                if c.is_finite() && c < cost {
                    lambda = (lambda / 10.0).max(1e-9);
                    accepted = Some((cand, rc, c));
                    break;
                }
            }
            lambda *= 10.0;
        }
        let converged = match accepted {
            Some((cand, rc, c)) => {
                let rel = (cost - c) / cost.max(1e-300);
                let dth: Vec<f64> = cand.iter().zip(&theta).map(|(a, b)| a - b).collect();
                let dd: f64 = dth.iter().map(|x| x * x).sum();
                if dd > 0.0 {
                    // Broyden: J += (Δr − J·Δθ)·Δθᵀ / |Δθ|²
                    let jd: Vec<f64> = (0..r.len()).map(|i| (0..p).map(|k| jac[k][i] * dth[k]).sum()).collect();
                    for (k, col) in jac.iter_mut().enumerate() {
                        let f = dth[k] / dd;
                        for (i, x) in col.iter_mut().enumerate() {
                            *x += (rc[i] - r[i] - jd[i]) * f;
                        }
                    }
                }
                theta = cand;
                r = rc;
                cost = c;
                since_fd += 1;
                fresh = false;
                rel <= 1e-5
            }
            None => true,
        };
        if converged {
            if fresh {
                break;
            }
            // a stall on an updated Jacobian is checked against a fresh one before stopping
        } else if since_fd < 4 {
            continue;
        }
        jac = fd(&theta, &r, &mut resid);
        fresh = true;
        since_fd = 0;
        fds += 1;
    }
    Some(Fit { theta, cost, jtj })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn a_bound_holds_and_the_free_parameter_still_fits() {
        // y = a·e^(−t/τ) with the data's a = −1 but a ≥ 0 imposed: a sits at 0
        let ts: Vec<f64> = (0..40).map(|i| i as f64 * 0.1).collect();
        let r = |th: &[f64]| Some(ts.iter().map(|t| th[0] * (-t / th[1]).exp() + (-t / 1.5).exp()).collect());
        let f = fit(&[1.0, 1.0], &[0.0, 0.1], &[10.0, 10.0], &[1e-6, 1e-6], 50, r).unwrap();
        assert_eq!(f.theta[0], 0.0);
        // unbounded it recovers the truth, with a standard error that shrinks with the noise
        let r = |th: &[f64]| Some(ts.iter().map(|t| th[0] * (-t / th[1]).exp() - 2.0 * (-t / 1.5).exp()).collect());
        let f = fit(&[1.0, 1.0], &[-10.0, 0.1], &[10.0, 10.0], &[1e-6, 1e-6], 100, r).unwrap();
        assert!((f.theta[0] - 2.0).abs() < 1e-5 && (f.theta[1] - 1.5).abs() < 1e-5, "{:?}", f.theta);
        let (s1, s2) = (f.std_err(0, 0.01).unwrap(), f.std_err(0, 0.02).unwrap());
        assert!(s1 > 0.0 && (s2 / s1 - 2.0).abs() < 1e-9);
    }
}
