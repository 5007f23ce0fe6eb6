//! Nonlinear least squares: Levenberg–Marquardt with a forward-difference Jacobian, and a
//! multi-start wrapper that keeps the best local solution.
//!
//! The fits here (a sine of the angle, a damped oscillation) have few unknowns and cost
//! functions with several local minima (phase and frequency wrap), so each is started from a
//! handful of physically spread guesses rather than trusted to one start.

use super::robust::{invert_spd, solve_spd};

/// Result of a nonlinear fit.
#[derive(Clone, Debug, PartialEq)]
pub struct NlsFit {
    pub params: Vec<f64>,
    /// sum of squared residuals at `params`
    pub cost: f64,
    /// residual standard deviation, √(cost/(m − p))
    pub sigma: f64,
    /// standard errors from σ²·(JᵀJ)⁻¹ (NaN where singular)
    pub se: Vec<f64>,
    pub iterations: usize,
}

/// Minimises Σ r_i(p)² from `p0`. `f(p, r)` fills the `m` residuals.
pub fn levenberg_marquardt<F>(mut f: F, p0: &[f64], m: usize, max_iter: usize) -> NlsFit
where
    F: FnMut(&[f64], &mut [f64]),
{
    let n = p0.len();
    let mut p = p0.to_vec();
    let mut r = vec![0.0; m];
    let mut r_try = vec![0.0; m];
    let mut jac = vec![0.0; m * n]; // column-major: column j at j*m
    let cost_of = |r: &[f64]| -> f64 {
        let c: f64 = r.iter().map(|v| v * v).sum();
        if c.is_finite() {
            c
        } else {
            f64::INFINITY
        }
    };
    f(&p, &mut r);
    let mut cost = cost_of(&r);
    let mut lambda = 1e-3;
    let mut jtj = vec![0.0; n * n];
    let mut jtr = vec![0.0; n];
    let mut iterations = 0;
    let mut p_try = p.clone();
    for it in 0..max_iter {
        iterations = it + 1;
        // Jacobian by forward differences.
        for j in 0..n {
            let h = 1e-7 * p[j].abs().max(1e-4);
            p_try.copy_from_slice(&p);
            p_try[j] += h;
            f(&p_try, &mut r_try);
            let col = &mut jac[j * m..(j + 1) * m];
            for ((c, a), b) in col.iter_mut().zip(&r_try).zip(&r) {
                *c = (a - b) / h;
            }
        }
        for a in 0..n {
            let ca = &jac[a * m..(a + 1) * m];
            jtr[a] = ca.iter().zip(&r).map(|(x, y)| x * y).sum();
            for b in 0..=a {
                let cb = &jac[b * m..(b + 1) * m];
                let v: f64 = ca.iter().zip(cb).map(|(x, y)| x * y).sum();
                jtj[a * n + b] = v;
                jtj[b * n + a] = v;
            }
        }
        let mut improved = false;
        for _ in 0..12 {
            let mut a = jtj.clone();
            for d in 0..n {
                a[d * n + d] += lambda * jtj[d * n + d].max(1e-12);
            }
            let neg: Vec<f64> = jtr.iter().map(|v| -v).collect();
            let Some(step) = solve_spd(&a, &neg, n) else {
                lambda *= 10.0;
                continue;
            };
            for j in 0..n {
                p_try[j] = p[j] + step[j];
            }
            f(&p_try, &mut r_try);
            let c_try = cost_of(&r_try);
            if c_try < cost {
                let rel = (cost - c_try) / cost.max(1e-300);
                p.copy_from_slice(&p_try);
                std::mem::swap(&mut r, &mut r_try);
                cost = c_try;
                lambda = (lambda * 0.3).max(1e-12);
                improved = true;
                if rel < 1e-12 {
                    return finish(p, cost, m, &jtj, iterations);
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    finish(p, cost, m, &jtj, iterations)
}

fn finish(p: Vec<f64>, cost: f64, m: usize, jtj: &[f64], iterations: usize) -> NlsFit {
    let n = p.len();
    let dof = (m as f64 - n as f64).max(1.0);
    let sigma = (cost / dof).sqrt();
    let se = match invert_spd(jtj, n) {
        Some(inv) => (0..n).map(|j| sigma * inv[j * n + j].max(0.0).sqrt()).collect(),
        None => vec![f64::NAN; n],
    };
    NlsFit { params: p, cost, sigma, se, iterations }
}

/// Runs [`levenberg_marquardt`] from every start and returns the lowest-cost fit (`None` when
/// there is no start or no fit reaches a finite cost).
pub fn multi_start<F>(mut f: F, starts: &[Vec<f64>], m: usize, max_iter: usize) -> Option<NlsFit>
where
    F: FnMut(&[f64], &mut [f64]),
{
    let mut best: Option<NlsFit> = None;
    for s in starts {
        let fit = levenberg_marquardt(&mut f, s, m, max_iter);
        if fit.cost.is_finite() && best.as_ref().is_none_or(|b| fit.cost < b.cost) {
            best = Some(fit);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_sine_from_several_starts() {
        let q: Vec<f64> = (0..40).map(|i| i as f64 * 0.05).collect();
        let y: Vec<f64> = q.iter().map(|q| 2.79 * (0.8 * q - 0.027).sin() - 0.59).collect();
        let f = |p: &[f64], r: &mut [f64]| {
            for ((ri, q), y) in r.iter_mut().zip(&q).zip(&y) {
                *ri = p[0] * (p[1] * q + p[2]).sin() + p[3] - y;
            }
        };
        let starts = vec![vec![1.0, 0.5, 0.0, 0.0], vec![-1.0, 1.5, 1.0, 0.0], vec![3.0, 1.0, -1.0, 0.0]];
        let fit = multi_start(f, &starts, q.len(), 200).unwrap();
        assert!(fit.cost < 1e-12, "{fit:?}");
    }
}
