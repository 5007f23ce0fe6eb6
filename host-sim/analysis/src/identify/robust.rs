//! Small dense least squares: ordinary, weighted and robust (Tukey bisquare IRLS), with
//! standard errors and 95 % confidence intervals.
//!
//! The trunk paper fitted its friction curve with MATLAB's "Bisquare" robust option; this is the
//! same estimator (iteratively reweighted least squares, tuning constant 4.685, residuals scaled
//! by MAD/0.6745 and adjusted for leverage), so a few bad plateaus do not pull the curve. The
//! problems here have at most a handful of unknowns and up to millions of rows, so the design is
//! held column by column and reduced to normal equations once per iteration (columns are scaled
//! to unit norm first, which keeps the normal equations well conditioned for p ≤ 6).

/// Result of a (robust) linear fit `y ≈ X·beta`.
#[derive(Clone, Debug, PartialEq)]
pub struct LinFit {
    pub beta: Vec<f64>,
    /// standard error of each coefficient
    pub se: Vec<f64>,
    /// 95 % confidence interval of each coefficient (t distribution, n − p dof)
    pub ci95: Vec<(f64, f64)>,
    /// residual scale (robust fits: the final robust σ)
    pub sigma: f64,
    /// final weight of each row (1 for ordinary least squares)
    pub weights: Vec<f64>,
    pub iterations: usize,
    /// (XᵀWX)⁻¹ (row-major p×p, unscaled by σ²): the coefficients' covariance is σ² times it
    pub xtx_inv: Vec<f64>,
}

/// Solves the symmetric positive definite system `a·x = b` (a row-major n×n) by Cholesky;
/// `None` if `a` is not positive definite.
pub fn solve_spd(a: &[f64], b: &[f64], n: usize) -> Option<Vec<f64>> {
    let l = cholesky(a, n)?;
    let mut y = vec![0.0; n];
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * n + k] * y[k];
        }
        y[i] = s / l[i * n + i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let mut s = y[i];
        for k in i + 1..n {
            s -= l[k * n + i] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
    Some(x)
}

fn cholesky(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                if !(s > 0.0 && s.is_finite()) {
                    return None;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    Some(l)
}

/// Inverse of a symmetric positive definite matrix (row-major n×n).
pub fn invert_spd(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut inv = vec![0.0; n * n];
    for c in 0..n {
        let mut e = vec![0.0; n];
        e[c] = 1.0;
        let x = solve_spd(a, &e, n)?;
        for r in 0..n {
            inv[r * n + c] = x[r];
        }
    }
    Some(inv)
}

/// Weighted least squares on columns `x` (each of length m); returns beta and (XᵀWX)⁻¹ in the
/// original (unscaled) coordinates.
fn wls(x: &[&[f64]], y: &[f64], w: Option<&[f64]>) -> Option<(Vec<f64>, Vec<f64>)> {
    let p = x.len();
    let m = y.len();
    // Column scales: the weighted norm of each column.
    let wt = |i: usize| w.map_or(1.0, |w| w[i]);
    let mut scale = vec![0.0; p];
    for (j, col) in x.iter().enumerate() {
        let s: f64 = (0..m).map(|i| wt(i) * col[i] * col[i]).sum();
        scale[j] = if s > 0.0 { 1.0 / s.sqrt() } else { 1.0 };
    }
    let mut ata = vec![0.0; p * p];
    let mut aty = vec![0.0; p];
    for i in 0..m {
        let wi = wt(i);
        if wi == 0.0 {
            continue;
        }
        for a in 0..p {
            let xa = x[a][i] * scale[a] * wi;
            aty[a] += xa * y[i];
            for b in 0..=a {
                ata[a * p + b] += xa * x[b][i] * scale[b];
            }
        }
    }
    for a in 0..p {
        for b in 0..a {
            ata[b * p + a] = ata[a * p + b];
        }
    }
    let z = solve_spd(&ata, &aty, p)?;
    let inv = invert_spd(&ata, p)?;
    let beta = (0..p).map(|j| z[j] * scale[j]).collect();
    let mut cov = vec![0.0; p * p];
    for a in 0..p {
        for b in 0..p {
            cov[a * p + b] = inv[a * p + b] * scale[a] * scale[b];
        }
    }
    Some((beta, cov))
}

fn residuals(x: &[&[f64]], y: &[f64], beta: &[f64], r: &mut Vec<f64>) {
    r.clear();
    r.extend_from_slice(y);
    for (col, b) in x.iter().zip(beta) {
        for (ri, xi) in r.iter_mut().zip(col.iter()) {
            *ri -= b * xi;
        }
    }
}

/// Ordinary least squares with standard errors and 95 % CIs; `None` if the columns are
/// linearly dependent or there are not more rows than unknowns.
pub fn ols(x: &[&[f64]], y: &[f64]) -> Option<LinFit> {
    let (p, m) = (x.len(), y.len());
    if m <= p || x.iter().any(|c| c.len() != m) {
        return None;
    }
    let (beta, cov) = wls(x, y, None)?;
    let mut r = Vec::with_capacity(m);
    residuals(x, y, &beta, &mut r);
    let dof = (m - p) as f64;
    let s2 = r.iter().map(|v| v * v).sum::<f64>() / dof;
    Some(finish(beta, &cov, s2.sqrt(), dof, vec![1.0; m], 1))
}

fn finish(beta: Vec<f64>, cov: &[f64], sigma: f64, dof: f64, weights: Vec<f64>, iterations: usize) -> LinFit {
    let p = beta.len();
    let tq = t_quantile_975(dof);
    let se: Vec<f64> = (0..p).map(|j| sigma * cov[j * p + j].max(0.0).sqrt()).collect();
    let ci95 = beta.iter().zip(&se).map(|(b, s)| (b - tq * s, b + tq * s)).collect();
    LinFit { beta, se, ci95, sigma, weights, iterations, xtx_inv: cov.to_vec() }
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Robust fit with Tukey's bisquare weights (tuning constant 4.685, as MATLAB's `fit(...,
/// 'Robust','Bisquare')`), by iteratively reweighted least squares from the OLS start.
/// The covariance is σ_robust²·(XᵀWX)⁻¹ with σ_robust² = Σwr²/(Σw − p).
pub fn bisquare(x: &[&[f64]], y: &[f64]) -> Option<LinFit> {
    const TUNE: f64 = 4.685;
    let (p, m) = (x.len(), y.len());
    if m <= p || x.iter().any(|c| c.len() != m) {
        return None;
    }
    let (mut beta, mut cov) = wls(x, y, None)?;
    // Leverages h_i of the unweighted design (MATLAB adjusts residuals by 1/sqrt(1 − h)).
    let lev: Vec<f64> = (0..m)
        .map(|i| {
            let mut h = 0.0;
            for a in 0..p {
                for b in 0..p {
                    h += x[a][i] * cov[a * p + b] * x[b][i];
                }
            }
            (1.0 - h).max(1e-6).sqrt().recip()
        })
        .collect();
    let mut w = vec![1.0; m];
    let mut r = Vec::with_capacity(m);
    let mut abs_r = Vec::with_capacity(m);
    let mut iterations = 0;
    for it in 0..100 {
        iterations = it + 1;
        residuals(x, y, &beta, &mut r);
        abs_r.clear();
        abs_r.extend(r.iter().zip(&lev).map(|(ri, l)| (ri * l).abs()));
        // MAD of the p-largest-excluded residuals is MATLAB's choice; the plain MAD is close
        // enough for the row counts here and never zero unless the fit is exact.
        let mut s = median(&mut abs_r) / 0.6745;
        if s <= 1e-12 * (1.0 + y.iter().map(|v| v.abs()).fold(0.0, f64::max)) {
            s = 1e-12;
        }
        for i in 0..m {
            let u = r[i] * lev[i] / (TUNE * s);
            w[i] = if u.abs() < 1.0 { (1.0 - u * u).powi(2) } else { 0.0 };
        }
        let (nb, nc) = wls(x, y, Some(&w))?;
        let change = nb.iter().zip(&beta).map(|(a, b)| (a - b).abs() / (b.abs() + 1e-9)).fold(0.0, f64::max);
        beta = nb;
        cov = nc;
        if change < 1e-8 {
            break;
        }
    }
    residuals(x, y, &beta, &mut r);
    let sw: f64 = w.iter().sum();
    let dof = (sw - p as f64).max(1.0);
    let s2 = r.iter().zip(&w).map(|(r, w)| w * r * r).sum::<f64>() / dof;
    Some(finish(beta, &cov, s2.sqrt(), dof, w, iterations))
}

#[allow(clippy::excessive_precision)] // the published coefficients, kept as printed
/// Standard normal quantile (Acklam's rational approximation, |error| < 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383577518672690e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] =
        [-5.447609879822406e1, 1.615858368580409e2, -1.556989798598866e2, 6.680131188771972e1, -1.328068155288572e1];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [7.784695709041462e-3, 3.224671290700398e-1, 2.445134137142996, 3.754408661907416];
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    let pl = 0.02425;
    if p < pl {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else if p <= 1.0 - pl {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -normal_quantile(1.0 - p)
    }
}

/// z of p = 0.001, one-sided: the upper 0.1 % point of the standard normal.
pub const Z_P001: f64 = 3.090_232;

/// `χ²_k/k` at the upper-tail normal deviate `z` (Wilson–Hilferty; `z = 0` is the median):
/// times `k`, the χ²_k quantile.
pub fn chi2_ratio(k: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    (1.0 - a + z * a.sqrt()).powi(3)
}

/// 97.5 % quantile of Student's t with `dof` degrees of freedom (exact for 1 and 2, a
/// Cornish–Fisher expansion above, within 0.2 % for dof ≥ 3).
pub fn t_quantile_975(dof: f64) -> f64 {
    if dof < 1.5 {
        return 12.706_204_736;
    }
    if dof < 2.5 {
        return 4.302_652_730;
    }
    let z = normal_quantile(0.975);
    let (z2, v) = (z * z, dof);
    let g1 = (z2 + 1.0) * z / 4.0;
    let g2 = ((5.0 * z2 + 16.0) * z2 + 3.0) * z / 96.0;
    let g3 = (((3.0 * z2 + 19.0) * z2 + 17.0) * z2 - 15.0) * z / 384.0;
    let g4 = ((((79.0 * z2 + 776.0) * z2 + 1482.0) * z2 - 1920.0) * z2 - 945.0) * z / 92160.0;
    z + g1 / v + g2 / (v * v) + g3 / (v * v * v) + g4 / (v * v * v * v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_match_tables() {
        for (dof, t) in [(3.0, 3.182), (5.0, 2.571), (10.0, 2.228), (30.0, 2.042), (1e6, 1.960)] {
            assert!((t_quantile_975(dof) - t).abs() < 0.006, "dof {dof}: {}", t_quantile_975(dof));
        }
    }

    #[test]
    fn bisquare_ignores_outliers_that_pull_ols() {
        let v: Vec<f64> = (1..=30).map(|i| i as f64 * 0.05).collect();
        let v2: Vec<f64> = v.iter().map(|v| v * v).collect();
        let one = vec![1.0; v.len()];
        let mut y: Vec<f64> = v.iter().map(|v| 1.5 * v * v + 8.0 * v + 2.0 + 0.01 * (v * 37.0).sin()).collect();
        y[4] += 5.0;
        y[20] -= 4.0;
        let x: [&[f64]; 3] = [&v2, &v, &one];
        let rob = bisquare(&x, &y).unwrap();
        let o = ols(&x, &y).unwrap();
        assert!((rob.beta[1] - 8.0).abs() < 0.1, "{:?}", rob.beta);
        assert!((o.beta[1] - 8.0).abs() > (rob.beta[1] - 8.0).abs());
        assert!(rob.weights[4] == 0.0 && rob.weights[20] == 0.0);
        assert!(rob.ci95[1].0 < 8.0 && rob.ci95[1].1 > 8.0);
    }
}
