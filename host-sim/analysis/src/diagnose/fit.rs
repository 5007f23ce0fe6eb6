//! Small dense numerics for the diagnosis, all in f64: streamed normal equations (a Gram matrix
//! accumulated row by row, so a million-sample log never becomes a million-by-p matrix), a
//! Cholesky solve on the column-scaled system with a tiny ridge (the regressors differ by many
//! orders of magnitude and some are nearly collinear, e.g. an asymmetric-friction term and the
//! offset while the joint moves), golden-section refinement for a searched parameter, the
//! Levenberg–Marquardt loop the trajectory mode uses, and the Student-t tail probability of the
//! significance test.

/// Normal equations `G·β = b` of a least-squares problem, plus `Σy²` and the row count.
#[derive(Clone, Debug)]
pub struct Gram {
    pub p: usize,
    pub g: Vec<f64>,
    pub b: Vec<f64>,
    pub yy: f64,
    pub n: usize,
    /// the value each coefficient keeps where the rows do not determine it (the file's own
    /// value for a model term, 0 for an effect's amplitude; see [`PRIOR_RIDGE`])
    pub prior: Vec<f64>,
    /// errors in variables: the white noise the q̈ column's own entry of `g` carries on these
    /// rows, `Σ w·σ²` (each row's fit weight times its q̈ noise variance, [`Gram::add_noise`])
    pub eiv: f64,
}

/// The ridge, relative to each column's own scale, that pulls a coefficient towards its prior:
/// negligible along any direction the rows determine (a relative bias of 1e-6 over the
/// direction's eigenvalue of the unit-diagonal system), decisive along one they do not, where
/// least squares would otherwise trade two nearly equal columns against each other (a weight
/// over 0.03 rad is an offset: free, the fit put ±3000 N·m on the pair).
pub const PRIOR_RIDGE: f64 = 1e-6;

impl Gram {
    pub fn new(p: usize) -> Gram {
        Gram { p, g: vec![0.0; p * p], b: vec![0.0; p], yy: 0.0, n: 0, prior: vec![0.0; p], eiv: 0.0 }
    }

    /// Adds one row (upper triangle only; [`Gram::solve`] mirrors it).
    #[inline]
    pub fn add(&mut self, x: &[f64], y: f64) {
        let p = self.p;
        for (i, &xi) in x.iter().enumerate().take(p) {
            if xi == 0.0 {
                continue;
            }
            let row = &mut self.g[i * p..(i + 1) * p];
            for (gij, &xj) in row.iter_mut().zip(x.iter()).skip(i) {
                *gij += xi * xj;
            }
            self.b[i] += xi * y;
        }
        self.yy += y * y;
        self.n += 1;
    }

    /// Adds one row's q̈ noise, `w·σ²` (see [`Gram::eiv`]).
    #[inline]
    pub fn add_noise(&mut self, v: f64) {
        self.eiv += v;
    }

    pub fn merge(&mut self, o: &Gram) {
        self.eiv += o.eiv;
        for (a, b) in self.g.iter_mut().zip(&o.g) {
            *a += b;
        }
        for (a, b) in self.b.iter_mut().zip(&o.b) {
            *a += b;
        }
        self.yy += o.yy;
        self.n += o.n;
    }

    /// Least squares with the coefficients marked in `nonneg` kept ≥ 0 (active set: the most
    /// negative is held and the rest refitted, until none is negative). A physical joint has no
    /// negative inertia or friction; the bounded fit is the best physical one. A coefficient
    /// that would go negative is held at `hold[i]` (0 where `hold` has no entry): a term a joint
    /// cannot lack (its inertia) keeps the file's value where the rows want none. The
    /// coefficients marked in `fixed` are held at `hold` from the start (a term the rows cannot
    /// determine at all).
    pub fn solve_held(&self, nonneg: &[bool], hold: &[f64], fixed: &[bool]) -> (Vec<f64>, f64) {
        let p = self.p;
        let held = |i: usize| hold.get(i).copied().unwrap_or(0.0);
        let full = |i: usize, j: usize| if i <= j { self.g[i * p + j] } else { self.g[j * p + i] };
        let mut fixed: Vec<bool> = (0..p).map(|i| fixed.get(i).copied().unwrap_or(false)).collect();
        loop {
            let free: Vec<usize> = (0..p).filter(|&i| !fixed[i]).collect();
            let fix: Vec<usize> = (0..p).filter(|&i| fixed[i]).collect();
            let mut sub = Gram::new(free.len());
            for (a, &i) in free.iter().enumerate() {
                for (b, &j) in free.iter().enumerate() {
                    sub.g[a * free.len() + b] = full(i, j);
                }
                // the held columns' contribution moves to the target side
                sub.b[a] = self.b[i] - fix.iter().map(|&f| full(i, f) * held(f)).sum::<f64>();
                sub.prior[a] = self.prior.get(i).copied().unwrap_or(0.0);
            }
            let bh: f64 = fix.iter().map(|&f| self.b[f] * held(f)).sum();
            let hgh: f64 = fix.iter().map(|&f| fix.iter().map(|&g| full(f, g) * held(g)).sum::<f64>() * held(f)).sum();
            sub.yy = self.yy - 2.0 * bh + hgh;
            sub.n = self.n;
            let (z, rss) = sub.solve();
            let mut beta: Vec<f64> = (0..p).map(|i| if fixed[i] { held(i) } else { 0.0 }).collect();
            for (a, &i) in free.iter().enumerate() {
                beta[i] = z[a];
            }
            let worst = (0..p)
                .filter(|&i| !fixed[i] && nonneg.get(i).copied().unwrap_or(false) && beta[i] < 0.0)
                .min_by(|&a, &b| beta[a].total_cmp(&beta[b]));
            match worst {
                Some(i) => fixed[i] = true,
                None => return (beta, rss),
            }
        }
    }

    /// Least-squares coefficients and the residual sum of squares. Columns that are all zero on
    /// these rows get a zero coefficient instead of a failure.
    pub fn solve(&self) -> (Vec<f64>, f64) {
        let p = self.p;
        if p == 0 {
            return (Vec::new(), self.yy);
        }
        let mut a = self.g.clone();
        for i in 0..p {
            for j in 0..i {
                a[i * p + j] = a[j * p + i];
            }
        }
        // Scale to unit diagonal so one ridge fits every column. A column whose sum of squares
        // is under 1e-20 of the largest one's (RMS under 1e-10 of it) is zero for the fit: a
        // Stribeck term searched to a speed far under the log's slowest motion is e^-100 on
        // every row, and scaled to unit size its coefficient reached 1e149 and its held-out
        // RMSE 1e135 N·m in the report (unseen t9073/0031).
        let dmax = (0..p).map(|i| a[i * p + i]).fold(0.0, f64::max);
        let scale: Vec<f64> =
            (0..p).map(|i| a[i * p + i]).map(|d| if d > 1e-20 * dmax { 1.0 / d.sqrt() } else { 0.0 }).collect();
        for i in 0..p {
            for j in 0..p {
                a[i * p + j] *= scale[i] * scale[j];
            }
        }
        let a_full = |i: usize, j: usize| if i <= j { self.g[i * p + j] } else { self.g[j * p + i] };
        // towards the prior: (A + λI)·z = rhs + λ·z_prior, z_prior = prior / scale
        let z_prior =
            |i: usize| if scale[i] > 0.0 { self.prior.get(i).copied().unwrap_or(0.0) / scale[i] } else { 0.0 };
        let mut ridge = PRIOR_RIDGE;
        loop {
            let rhs: Vec<f64> = (0..p).map(|i| self.b[i] * scale[i] + ridge * z_prior(i)).collect();
            let mut m = a.clone();
            for i in 0..p {
                m[i * p + i] += if scale[i] == 0.0 { 1.0 } else { ridge };
            }
            if let Some(z) = cholesky_solve(&mut m, p, &rhs) {
                let beta: Vec<f64> = z.iter().zip(&scale).map(|(z, s)| z * s).collect();
                // Σ(y − xβ)² = Σy² − 2βᵀb + βᵀGβ (exact for any β, the ridge's too)
                let bb: f64 = beta.iter().zip(&self.b).map(|(x, y)| x * y).sum();
                let gbb: f64 = (0..p).map(|i| (0..p).map(|j| a_full(i, j) * beta[j]).sum::<f64>() * beta[i]).sum();
                let rss = (self.yy - 2.0 * bb + gbb).max(0.0);
                return (beta, rss);
            }
            ridge *= 100.0;
            if ridge > 1.0 {
                return (vec![0.0; p], self.yy);
            }
        }
    }
}

/// Solves `m·x = rhs` for a symmetric positive definite `m` (overwritten); `None` if not PD.
pub fn cholesky_solve(m: &mut [f64], p: usize, rhs: &[f64]) -> Option<Vec<f64>> {
    for j in 0..p {
        let mut d = m[j * p + j];
        for k in 0..j {
            d -= m[j * p + k] * m[j * p + k];
        }
        if !(d > 0.0) || !d.is_finite() {
            return None;
        }
        let d = d.sqrt();
        m[j * p + j] = d;
        for i in (j + 1)..p {
            let mut s = m[i * p + j];
            for k in 0..j {
                s -= m[i * p + k] * m[j * p + k];
            }
            m[i * p + j] = s / d;
        }
    }
    let mut y = rhs.to_vec();
    for i in 0..p {
        let mut s = y[i];
        for k in 0..i {
            s -= m[i * p + k] * y[k];
        }
        y[i] = s / m[i * p + i];
    }
    for i in (0..p).rev() {
        let mut s = y[i];
        for k in (i + 1)..p {
            s -= m[k * p + i] * y[k];
        }
        y[i] = s / m[i * p + i];
    }
    Some(y)
}

/// Golden-section minimum of `f` on `[lo, hi]` (f unimodal there), `iters` shrinks.
pub fn golden(mut lo: f64, mut hi: f64, iters: usize, mut f: impl FnMut(f64) -> f64) -> (f64, f64) {
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = hi - r * (hi - lo);
    let mut x2 = lo + r * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..iters {
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - r * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + r * (hi - lo);
            f2 = f(x2);
        }
    }
    if f1 <= f2 {
        (x1, f1)
    } else {
        (x2, f2)
    }
}

/// Levenberg–Marquardt on a residual function `r(θ) → Vec` with a forward-difference Jacobian.
/// Returns θ and the final sum of squares. `step` gives each parameter's difference step.
pub fn levenberg_marquardt(
    theta0: &[f64],
    step: &[f64],
    iters: usize,
    mut resid: impl FnMut(&[f64]) -> Option<Vec<f64>>,
) -> Option<(Vec<f64>, f64)> {
    let p = theta0.len();
    let mut theta = theta0.to_vec();
    let mut r = resid(&theta)?;
    let mut cost: f64 = r.iter().map(|x| x * x).sum();
    let mut lambda = 1e-3;
    for _ in 0..iters {
        // Jacobian columns by forward differences.
        let mut jac: Vec<Vec<f64>> = Vec::with_capacity(p);
        for k in 0..p {
            let mut th = theta.clone();
            th[k] += step[k];
            let rk = resid(&th)?;
            jac.push(rk.iter().zip(&r).map(|(a, b)| (a - b) / step[k]).collect());
        }
        let mut jtj = vec![0.0; p * p];
        let mut jtr = vec![0.0; p];
        for i in 0..p {
            for j in i..p {
                let s: f64 = jac[i].iter().zip(&jac[j]).map(|(a, b)| a * b).sum();
                jtj[i * p + j] = s;
                jtj[j * p + i] = s;
            }
            jtr[i] = jac[i].iter().zip(&r).map(|(a, b)| a * b).sum();
        }
        let mut improved = false;
        for _ in 0..8 {
            let mut m = jtj.clone();
            for i in 0..p {
                m[i * p + i] += lambda * jtj[i * p + i].max(1e-12);
            }
            let Some(delta) = cholesky_solve(&mut m, p, &jtr) else {
                lambda *= 10.0;
                continue;
            };
            let cand: Vec<f64> = theta.iter().zip(&delta).map(|(t, d)| t - d).collect();
            if let Some(rc) = resid(&cand) {
                let c: f64 = rc.iter().map(|x| x * x).sum();
                if c.is_finite() && c < cost {
                    let rel = (cost - c) / cost.max(1e-300);
                    theta = cand;
                    r = rc;
                    cost = c;
                    lambda = (lambda / 10.0).max(1e-9);
                    improved = rel > 1e-9;
                    break;
                }
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    Some((theta, cost))
}

/// ln Γ(x) (Lanczos, g = 7), for the incomplete beta below.
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised incomplete beta I_x(a, b) by Lentz's continued fraction.
fn inc_beta(x: f64, a: f64, b: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front = (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x > (a + 1.0) / (a + b + 2.0) {
        return 1.0 - inc_beta(1.0 - x, b, a);
    }
    let tiny = 1e-300;
    let mut f = 1.0;
    let mut c = 1.0;
    let mut d = 0.0;
    for i in 0..400 {
        let m = (i / 2) as f64;
        let num = if i == 0 {
            1.0
        } else if i % 2 == 0 {
            m * (b - m) * x / ((a + 2.0 * m - 1.0) * (a + 2.0 * m))
        } else {
            -(a + m) * (a + b + m) * x / ((a + 2.0 * m) * (a + 2.0 * m + 1.0))
        };
        d = 1.0 + num * d;
        if d.abs() < tiny {
            d = tiny;
        }
        d = 1.0 / d;
        c = 1.0 + num / c;
        if c.abs() < tiny {
            c = tiny;
        }
        let cd = c * d;
        f *= cd;
        if (1.0 - cd).abs() < 1e-14 {
            break;
        }
    }
    front * (f - 1.0) / a
}

/// One-sided upper tail P(T > t) of Student's t with `df` degrees of freedom.
pub fn student_t_sf(t: f64, df: f64) -> f64 {
    if !t.is_finite() {
        return if t > 0.0 { 0.0 } else { 1.0 };
    }
    let x = df / (df + t * t);
    let tail = 0.5 * inc_beta(x, 0.5 * df, 0.5);
    if t > 0.0 {
        tail
    } else {
        1.0 - tail
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_tail_matches_tables() {
        // t_{0.01, 10} = 2.764, t_{0.001, 29} = 3.396, t_{0.05,1} = 6.314
        assert!((student_t_sf(2.764, 10.0) - 0.01).abs() < 2e-4);
        assert!((student_t_sf(3.396, 29.0) - 0.001).abs() < 5e-5);
        assert!((student_t_sf(6.314, 1.0) - 0.05).abs() < 5e-4);
        assert!((student_t_sf(0.0, 5.0) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn gram_solves_a_known_line() {
        let mut g = Gram::new(2);
        for i in 0..100 {
            let x = i as f64 * 0.1;
            g.add(&[1.0, x], 3.0 - 2.0 * x);
        }
        let (b, rss) = g.solve();
        // the ridge towards the prior (0 here) biases a determined direction by PRIOR_RIDGE over
        // its eigenvalue (≈ 0.1 for [1, x] on these rows): ~1e-5 relative
        assert!((b[0] - 3.0).abs() < 1e-4 && (b[1] + 2.0).abs() < 1e-4 && rss < 1e-8 * g.yy, "{b:?} {rss}");
        // with the true line as the prior there is nothing to bias
        g.prior = vec![3.0, -2.0];
        let (b, _) = g.solve();
        assert!((b[0] - 3.0).abs() < 1e-9 && (b[1] + 2.0).abs() < 1e-9, "{b:?}");
    }

    /// A column far under the others (a Stribeck term e^-100 on every row) is zero for the fit:
    /// its coefficient stays 0 instead of growing to the size that makes the column matter on
    /// these rows, which on any other row is an absurd torque; the other columns fit as without it.
    #[test]
    fn a_vanishing_column_gets_no_coefficient() {
        let mut g = Gram::new(3);
        for i in 0..100 {
            let x = i as f64 * 0.1;
            let tiny = 1e-60 * (1.0 + (i % 7) as f64);
            g.add(&[1.0, x, tiny], 3.0 - 2.0 * x + 0.01 * ((i % 5) as f64 - 2.0));
        }
        let (b, _) = g.solve();
        assert_eq!(b[2], 0.0, "{b:?}");
        assert!((b[0] - 3.0).abs() < 1e-2 && (b[1] + 2.0).abs() < 1e-2, "{b:?}");
    }

    /// A coefficient the rows want negative is held at the value given and the others refit
    /// around it: y = 2·x1 − 0.5·x2 with x2 ≥ 0 held at 0.3 gives x1's best value with
    /// 0.3·x2 taken off, and the RSS of that fit.
    #[test]
    fn a_held_coefficient_keeps_its_value_and_the_rest_refit() {
        let mut g = Gram::new(2);
        let (mut rows, mut x1x1, mut x1y, mut yy) = (Vec::new(), 0.0, 0.0, 0.0);
        for i in 0..200 {
            let (x1, x2) = ((i as f64 * 0.37).sin(), (i as f64 * 0.11).cos());
            let y = 2.0 * x1 - 0.5 * x2;
            g.add(&[x1, x2], y);
            rows.push((x1, x2, y));
        }
        let (b, rss) = g.solve_held(&[false, true], &[0.0, 0.3], &[]);
        assert_eq!(b[1], 0.3);
        for &(x1, x2, y) in &rows {
            let r = y - 0.3 * x2;
            x1x1 += x1 * x1;
            x1y += x1 * r;
        }
        let b1 = x1y / x1x1;
        for &(x1, x2, y) in &rows {
            let e = y - 0.3 * x2 - b1 * x1;
            yy += e * e;
        }
        assert!((b[0] - b1).abs() < 1e-4, "{b:?} vs {b1}");
        assert!((rss - yy).abs() < 1e-6 * g.yy, "{rss} vs {yy}");
        // held at 0 (no `hold` given) it is the plain bounded fit
        let (b0, _) = g.solve_held(&[false, true], &[], &[]);
        assert_eq!(b0[1], 0.0);
    }

    /// Two columns the rows cannot tell apart (a weight's cosine over 0.03 rad and an offset):
    /// least squares trades them against each other; the ridge keeps their split at the prior
    /// and fits only their sum.
    #[test]
    fn an_undetermined_direction_stays_at_the_prior() {
        let mut g = Gram::new(2);
        for i in 0..1000 {
            let q = 0.03 * i as f64 / 1000.0;
            let noise = if i % 2 == 0 { 1e-3 } else { -1e-3 };
            // truth: 2.5·cos(0.8 q) − 0.3, plus noise
            g.add(&[(0.8 * q).cos(), 1.0], 2.5 * (0.8 * q).cos() - 0.3 + noise);
        }
        g.prior = vec![2.0, 0.0];
        let (b, _) = g.solve();
        assert!((b[0] + b[1] - 2.2).abs() < 1e-3, "the sum is what the rows determine: {b:?}");
        assert!(b[0].abs() < 10.0 && b[1].abs() < 10.0, "the pair ran off: {b:?}");
    }

    #[test]
    fn lm_fits_an_exponential() {
        let ts: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let r = |th: &[f64]| Some(ts.iter().map(|t| th[0] * (-t / th[1]).exp() - 2.0 * (-t / 1.5).exp()).collect());
        let (th, c) = levenberg_marquardt(&[1.0, 1.0], &[1e-6, 1e-6], 100, r).unwrap();
        assert!((th[0] - 2.0).abs() < 1e-5 && (th[1] - 1.5).abs() < 1e-5 && c < 1e-10, "{th:?}");
    }
}
