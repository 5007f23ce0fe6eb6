//! Derivatives by local polynomial regression (a Savitzky–Golay filter that honours the real
//! time stamps), with the window chosen from the data.
//!
//! At every sample a cubic in time is fitted by least squares to the `2h+1` samples around it
//! (the window slides inwards at a segment's ends, so it never reaches across a gap), and its
//! first and second derivatives at the sample are the estimates. For a window of half-width `h`
//! the estimate is a weighted sum `Σ w_j·x_{i+j}`: white noise σ on `x` gives it the variance
//! `σ²·Σ w_j²`, and the motion gives it a bias whose leading term is
//! `Σ w_j·(j·dt)^k/k! · x^(k)` with k = 5 for the first derivative and k = 4 for the second
//! (a symmetric cubic fit is exact for polynomials up to degree 3, and odd/even moments cancel).
//! [`choose_half_width`] takes the `h` that minimises variance + bias² with σ and the RMS of
//! `x^(k)` read from the signal's spectrum ([`super::spectrum`]): a wider window where the
//! signal is noisy and the motion slow, a narrower one where the motion is fast.

/// Polynomial degree of the local fits.
pub const DEGREE: usize = 3;

/// Interior weights of the first and second derivative at the centre of a uniform window of
/// half-width `h` and step `dt` (least-squares cubic).
pub fn weights(h: usize, dt: f64) -> Option<(Vec<f64>, Vec<f64>)> {
    let m = 2 * h + 1;
    if m < DEGREE + 2 {
        return None;
    }
    // Normal equations in scaled time s = j/h; the estimate's weights are rows of (XᵀX)⁻¹Xᵀ.
    let p = DEGREE + 1;
    let mut a = vec![0.0; p * p];
    for j in -(h as i64)..=(h as i64) {
        let s = j as f64 / h as f64;
        for r in 0..p {
            for c in 0..p {
                a[r * p + c] += s.powi((r + c) as i32);
            }
        }
    }
    let inv = invert(&a, p)?;
    let scale = h as f64 * dt;
    let mut w1 = Vec::with_capacity(m);
    let mut w2 = Vec::with_capacity(m);
    for j in -(h as i64)..=(h as i64) {
        let s = j as f64 / h as f64;
        let pw: Vec<f64> = (0..p).map(|k| s.powi(k as i32)).collect();
        let row = |r: usize| (0..p).map(|c| inv[r * p + c] * pw[c]).sum::<f64>();
        w1.push(row(1) / scale);
        w2.push(2.0 * row(2) / (scale * scale));
    }
    Some((w1, w2))
}

/// Which derivative an estimate is of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    First,
    Second,
}

/// The estimate's error at half-width `h`: (noise variance, bias) for a signal with white
/// noise `sigma` whose 4th and 5th derivatives have RMS `d4`, `d5`.
pub fn error_at(h: usize, dt: f64, order: Order, sigma: f64, d4: f64, d5: f64) -> Option<(f64, f64)> {
    error_with(h, dt, order, &|w: &[f64]| sigma * sigma * w.iter().map(|x| x * x).sum::<f64>(), d4, d5)
}

/// As [`error_at`], with the noise variance of the estimator's weights given by `noise_var`
/// (a coloured noise's: see `spectrum::NoiseModel::filtered_variance`).
pub fn error_with(
    h: usize,
    dt: f64,
    order: Order,
    noise_var: &dyn Fn(&[f64]) -> f64,
    d4: f64,
    d5: f64,
) -> Option<(f64, f64)> {
    let (w1, w2) = weights(h, dt)?;
    let (w, k, dk) = match order {
        Order::First => (w1, 5, d5),
        Order::Second => (w2, 4, d4),
    };
    let var = noise_var(&w);
    let fact: f64 = (1..=k).map(|i| i as f64).product();
    let moment: f64 = w.iter().enumerate().map(|(i, wj)| wj * ((i as f64 - h as f64) * dt).powi(k) / fact).sum::<f64>();
    Some((var, (moment * dk).abs()))
}

/// The half-width minimising variance + bias² for `order`, between 2 samples and `h_max`, and
/// the estimate's error (noise variance, bias) there.
pub fn choose_half_width(
    dt: f64,
    order: Order,
    sigma: f64,
    d4: f64,
    d5: f64,
    h_max: usize,
) -> Option<(usize, f64, f64)> {
    choose_half_width_with(dt, order, &|w: &[f64]| sigma * sigma * w.iter().map(|x| x * x).sum::<f64>(), d4, d5, h_max)
}

/// As [`choose_half_width`], with the noise variance of the estimator's weights given by
/// `noise_var`.
pub fn choose_half_width_with(
    dt: f64,
    order: Order,
    noise_var: &dyn Fn(&[f64]) -> f64,
    d4: f64,
    d5: f64,
    h_max: usize,
) -> Option<(usize, f64, f64)> {
    let mut best: Option<(usize, f64, f64)> = None;
    let mut h = 2usize;
    while h <= h_max.max(2) {
        if let Some((var, bias)) = error_with(h, dt, order, noise_var, d4, d5) {
            if best.map(|(_, v, b)| var + bias * bias < v + b * b).unwrap_or(true) {
                best = Some((h, var, bias));
            }
        }
        // every half-width up to 12, then steps of ~6 %
        h = if h < 12 { h + 1 } else { (h as f64 * 1.06).ceil() as usize };
    }
    best
}

/// First and second derivatives of `x` over `t` by local cubic fits of `2h+1` samples. `t` and
/// `x` are one segment (no gap inside). Fewer than `DEGREE + 2` samples: linear slopes.
pub fn derivatives(t: &[f64], x: &[f64], h: usize) -> (Vec<f64>, Vec<f64>) {
    let e = estimate(t, x, h);
    (e.d1, e.d2)
}

/// Local-fit derivatives and, per sample, their noise gain: white noise σ on `x` gives the
/// estimate the variance `σ²·gain` (the diagonal of the fit's inverse normal matrix: larger
/// where the window is one-sided, at a segment's ends).
pub struct Estimate {
    pub d1: Vec<f64>,
    pub d2: Vec<f64>,
    pub gain1: Vec<f64>,
    pub gain2: Vec<f64>,
}

/// Whether every step of `t` is `dt` within 1 %: evenly stamped, as the estimates and the
/// spectrum take a log (its jitter, if any, too small to count).
pub(crate) fn evenly_stamped(t: &[f64], dt: f64) -> bool {
    t.windows(2).all(|w| ((w[1] - w[0]) - dt).abs() <= 0.01 * dt)
}

pub fn estimate(t: &[f64], x: &[f64], h: usize) -> Estimate {
    let n = x.len().min(t.len());
    let m = (2 * h + 1).min(n);
    if m < DEGREE + 2 {
        let (d1, d2) = fallback(t, x);
        // a two-point slope over 2·dt: gain 1/(2·dt²); its slope 4× that again
        let dt = if n > 1 { (t[n - 1] - t[0]) / (n - 1) as f64 } else { 1.0 };
        let g1 = 1.0 / (2.0 * dt * dt);
        return Estimate { d1, d2, gain1: vec![g1; n], gain2: vec![4.0 * g1 / (dt * dt); n] };
    }
    let p = DEGREE + 1;
    let mut out = Estimate {
        d1: Vec::with_capacity(n),
        d2: Vec::with_capacity(n),
        gain1: Vec::with_capacity(n),
        gain2: Vec::with_capacity(n),
    };
    // Evenly stamped (within 1 % of the step): the interior windows all have the same weights,
    // so the interior is a convolution; only the ends need their own fits.
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    let uniform = m == 2 * h + 1 && evenly_stamped(t, dt);
    let interior = if uniform { weights(h, dt) } else { None }.map(|(w1, w2)| {
        let (g1, g2) = (w1.iter().map(|w| w * w).sum::<f64>(), w2.iter().map(|w| w * w).sum::<f64>());
        (w1, w2, g1, g2)
    });
    // Evenly stamped: the interior from sliding index moments (see [`Sliding`]).
    let mut sliding = if interior.is_some() { Sliding::new(x, h, dt) } else { None };
    // Unevenly stamped: the interior fits from running moment sums (see [`Moments`]).
    let mut moments = if interior.is_none() && m == 2 * h + 1 { Some(Moments::new(t, x, h)) } else { None };
    let mut a = vec![0.0; p * p];
    let mut b = vec![0.0; p];
    for i in 0..n {
        if let Some(mo) = moments.as_mut().filter(|_| i >= h && i + h < n) {
            let (d1, d2, g1, g2) = mo.at(i);
            out.d1.push(d1);
            out.d2.push(d2);
            out.gain1.push(g1);
            out.gain2.push(g2);
            continue;
        }
        if let Some((_, _, g1, g2)) = interior.as_ref().filter(|_| i >= h && i + h < n) {
            let (d1, d2) = match sliding.as_mut() {
                Some(sl) => sl.at(i),
                None => (0.0, 0.0),
            };
            out.d1.push(d1);
            out.d2.push(d2);
            out.gain1.push(*g1);
            out.gain2.push(*g2);
            continue;
        }
        let lo = i.saturating_sub(h).min(n - m);
        let hi = lo + m;
        let scale = ((t[hi - 1] - t[lo]) / 2.0).max(1e-12);
        a.iter_mut().for_each(|v| *v = 0.0);
        b.iter_mut().for_each(|v| *v = 0.0);
        for j in lo..hi {
            let s = (t[j] - t[i]) / scale;
            let mut pw = [1.0f64; 2 * DEGREE + 1];
            for k in 1..pw.len() {
                pw[k] = pw[k - 1] * s;
            }
            for r in 0..p {
                for c in 0..p {
                    a[r * p + c] += pw[r + c];
                }
                b[r] += pw[r] * x[j];
            }
        }
        let unit = |k: usize| {
            let mut e = vec![0.0; p];
            e[k] = 1.0;
            solve(&a, &e, p).map_or(0.0, |c| c[k])
        };
        match solve(&a, &b, p) {
            Some(c) => {
                out.d1.push(c[1] / scale);
                out.d2.push(2.0 * c[2] / (scale * scale));
                out.gain1.push(unit(1) / (scale * scale));
                out.gain2.push(4.0 * unit(2) / (scale * scale * scale * scale));
            }
            None => {
                out.d1.push(0.0);
                out.d2.push(0.0);
                out.gain1.push(0.0);
                out.gain2.push(0.0);
            }
        }
    }
    out
}

/// The interior of an evenly stamped segment in O(1) per sample: the index moments
/// `S_k = Σ_{j=−h..h} j^k·x_{i+j}` (k ≤ 3) slide from one sample to the next by the binomial
/// theorem (`(j−1)^k`), and the cubic fit's derivatives are fixed combinations of them (the
/// inverse normal matrix of the uniform window). Recomputed from scratch every 256 samples, and
/// taken about the block's first value, so rounding cannot build up.
struct Sliding<'a> {
    x: &'a [f64],
    h: usize,
    /// rows 1 and 2 of the inverse normal matrix in scaled time s = j/h, with the scaling to
    /// index moments and to derivatives folded in
    r1: [f64; DEGREE + 1],
    r2: [f64; DEGREE + 1],
    s: [f64; DEGREE + 1],
    next: usize,
    since: usize,
    base: f64,
}

impl<'a> Sliding<'a> {
    fn new(x: &'a [f64], h: usize, dt: f64) -> Option<Self> {
        const P: usize = DEGREE + 1;
        let mut a = [0.0f64; P * P];
        for j in -(h as i64)..=(h as i64) {
            let s = j as f64 / h as f64;
            for r in 0..P {
                for c in 0..P {
                    a[r * P + c] += s.powi((r + c) as i32);
                }
            }
        }
        let inv = invert4(&a)?;
        let scale = h as f64 * dt;
        let (mut r1, mut r2) = ([0.0; P], [0.0; P]);
        for k in 0..P {
            let to_index = (h as f64).powi(k as i32); // b_k = S_k / h^k
            r1[k] = inv[P + k] / to_index / scale;
            r2[k] = 2.0 * inv[2 * P + k] / to_index / (scale * scale);
        }
        Some(Sliding { x, h, r1, r2, s: [0.0; P], next: usize::MAX, since: 0, base: 0.0 })
    }

    fn refresh(&mut self, i: usize) {
        self.base = self.x[i];
        self.s = [0.0; DEGREE + 1];
        for j in -(self.h as i64)..=(self.h as i64) {
            let v = self.x[(i as i64 + j) as usize] - self.base;
            let jf = j as f64;
            self.s[0] += v;
            self.s[1] += jf * v;
            self.s[2] += jf * jf * v;
            self.s[3] += jf * jf * jf * v;
        }
        self.since = 0;
    }

    /// (q̇, q̈) at interior sample `i` (called in increasing order).
    fn at(&mut self, i: usize) -> (f64, f64) {
        if i != self.next || self.since >= 256 {
            self.refresh(i);
        } else {
            // window moves from i−1 to i: drop x[i−1−h] (j = −h), add x[i+h] (j = h+1), then
            // re-index j → j − 1
            let h = self.h as f64;
            let (out, inn) = (self.x[i - 1 - self.h] - self.base, self.x[i + self.h] - self.base);
            let [s0, s1, s2, s3] = self.s;
            let t0 = s0 - out + inn;
            let t1 = s1 + h * out + (h + 1.0) * inn;
            let t2 = s2 - h * h * out + (h + 1.0) * (h + 1.0) * inn;
            let t3 = s3 + h * h * h * out + (h + 1.0).powi(3) * inn;
            // Σ(j−1)^k·v = Σ_m C(k,m)(−1)^(k−m)·T_m
            self.s = [t0, t1 - t0, t2 - 2.0 * t1 + t0, t3 - 3.0 * t2 + 3.0 * t1 - t0];
            self.since += 1;
        }
        self.next = i + 1;
        // a constant has zero derivatives: taking `base` off changes nothing but the rounding
        let d = |r: &[f64; DEGREE + 1]| r.iter().zip(&self.s).map(|(a, b)| a * b).sum::<f64>();
        (d(&self.r1), d(&self.r2))
    }
}

/// The interior fits of an unevenly stamped segment without refitting each window: sums of
/// `u^k` (k ≤ 6) and `u^k·x` (k ≤ 3) over the window, `u = (t − anchor)/scale`, slid one sample
/// at a time and re-anchored every `h` samples (so |u| stays ≤ 2 and the sums exact to ~1e-12);
/// each sample's normal equations are those sums shifted to its own time by the binomial
/// theorem. O(1) per sample instead of O(h).
struct Moments<'a> {
    t: &'a [f64],
    x: &'a [f64],
    h: usize,
    scale: f64,
    anchor: f64,
    /// first sample of the window the sums hold (the window is `lo..lo + 2h + 1`)
    lo: usize,
    since: usize,
    pu: [f64; 2 * DEGREE + 1],
    qu: [f64; DEGREE + 1],
}

impl<'a> Moments<'a> {
    fn new(t: &'a [f64], x: &'a [f64], h: usize) -> Self {
        let n = t.len().min(x.len());
        let scale = if n > 1 { (t[n - 1] - t[0]) / (n - 1) as f64 * h as f64 } else { 1.0 }.max(1e-12);
        let mut m =
            Moments { t, x, h, scale, anchor: 0.0, lo: 0, since: 0, pu: [0.0; 2 * DEGREE + 1], qu: [0.0; DEGREE + 1] };
        m.reanchor(0);
        m
    }

    fn add(&mut self, j: usize, sign: f64) {
        let u = (self.t[j] - self.anchor) / self.scale;
        let mut pw = 1.0;
        for k in 0..=2 * DEGREE {
            self.pu[k] += sign * pw;
            if k <= DEGREE {
                self.qu[k] += sign * pw * self.x[j];
            }
            pw *= u;
        }
    }

    fn reanchor(&mut self, lo: usize) {
        self.lo = lo;
        self.anchor = self.t[lo + self.h];
        self.pu = [0.0; 2 * DEGREE + 1];
        self.qu = [0.0; DEGREE + 1];
        for j in lo..=lo + 2 * self.h {
            self.add(j, 1.0);
        }
        self.since = 0;
    }

    /// (q̇, q̈, gain of q̇, gain of q̈) at interior sample `i` (`h ≤ i < n − h`, called in order).
    fn at(&mut self, i: usize) -> (f64, f64, f64, f64) {
        let lo = i - self.h;
        if lo < self.lo || lo > self.lo + self.h || self.since >= self.h {
            self.reanchor(lo);
        }
        while self.lo < lo {
            let (out, inn) = (self.lo, self.lo + 2 * self.h + 1);
            self.add(inn, 1.0);
            self.add(out, -1.0);
            self.lo += 1;
            self.since += 1;
        }
        // shift to u' = u + δ, δ = (anchor − t_i)/scale: Σu'^k = Σ_m C(k,m)·δ^(k−m)·Σu^m
        let delta = (self.anchor - self.t[i]) / self.scale;
        let mut dp = [1.0f64; 2 * DEGREE + 1];
        for k in 1..dp.len() {
            dp[k] = dp[k - 1] * delta;
        }
        let binom = |k: usize, m: usize| -> f64 { (0..m).fold(1.0, |acc, r| acc * (k - r) as f64 / (r + 1) as f64) };
        let mut pp = [0.0f64; 2 * DEGREE + 1];
        for (k, v) in pp.iter_mut().enumerate() {
            *v = (0..=k).map(|m| binom(k, m) * dp[k - m] * self.pu[m]).sum();
        }
        let mut qq = [0.0f64; DEGREE + 1];
        for (k, v) in qq.iter_mut().enumerate() {
            *v = (0..=k).map(|m| binom(k, m) * dp[k - m] * self.qu[m]).sum();
        }
        const P: usize = DEGREE + 1;
        let mut a = [0.0f64; P * P];
        for r in 0..P {
            for c in 0..P {
                a[r * P + c] = pp[r + c];
            }
        }
        let Some(inv) = invert4(&a) else { return (0.0, 0.0, 0.0, 0.0) };
        let coef = |r: usize| (0..P).map(|c| inv[r * P + c] * qq[c]).sum::<f64>();
        let s = self.scale;
        (coef(1) / s, 2.0 * coef(2) / (s * s), inv[P + 1] / (s * s), 4.0 * inv[2 * P + 2] / (s * s * s * s))
    }
}

/// The inverse of a 4×4 matrix (Gauss–Jordan with partial pivoting, no allocation).
fn invert4(a: &[f64; 16]) -> Option<[f64; 16]> {
    let mut m = *a;
    let mut inv = [0.0f64; 16];
    for k in 0..4 {
        inv[k * 4 + k] = 1.0;
    }
    for col in 0..4 {
        let piv = (col..4).max_by(|&i, &j| m[i * 4 + col].abs().total_cmp(&m[j * 4 + col].abs()))?;
        if m[piv * 4 + col].abs() < 1e-300 {
            return None;
        }
        for k in 0..4 {
            m.swap(col * 4 + k, piv * 4 + k);
            inv.swap(col * 4 + k, piv * 4 + k);
        }
        let d = m[col * 4 + col];
        for k in 0..4 {
            m[col * 4 + k] /= d;
            inv[col * 4 + k] /= d;
        }
        for r in 0..4 {
            if r != col {
                let f = m[r * 4 + col];
                if f != 0.0 {
                    for k in 0..4 {
                        m[r * 4 + k] -= f * m[col * 4 + k];
                        inv[r * 4 + k] -= f * inv[col * 4 + k];
                    }
                }
            }
        }
    }
    Some(inv)
}

/// Two-point slopes (and their slopes) for segments too short for a cubic.
fn fallback(t: &[f64], x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let slope = |t: &[f64], x: &[f64]| -> Vec<f64> {
        let n = x.len();
        (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(n.saturating_sub(1)));
                let dt = t[b] - t[a];
                if b > a && dt > 0.0 {
                    (x[b] - x[a]) / dt
                } else {
                    0.0
                }
            })
            .collect()
    };
    let d1 = slope(t, x);
    let d2 = slope(t, &d1);
    (d1, d2)
}

/// Solves the small symmetric system `a·c = b` (Gauss–Jordan with partial pivoting).
fn solve(a: &[f64], b: &[f64], p: usize) -> Option<Vec<f64>> {
    let mut m: Vec<f64> = Vec::with_capacity(p * (p + 1));
    for r in 0..p {
        m.extend_from_slice(&a[r * p..(r + 1) * p]);
        m.push(b[r]);
    }
    let w = p + 1;
    for col in 0..p {
        let piv = (col..p).max_by(|&i, &j| m[i * w + col].abs().total_cmp(&m[j * w + col].abs()))?;
        if m[piv * w + col].abs() < 1e-300 {
            return None;
        }
        for k in 0..w {
            m.swap(col * w + k, piv * w + k);
        }
        let d = m[col * w + col];
        for k in 0..w {
            m[col * w + k] /= d;
        }
        for r in 0..p {
            if r != col {
                let f = m[r * w + col];
                if f != 0.0 {
                    for k in 0..w {
                        m[r * w + k] -= f * m[col * w + k];
                    }
                }
            }
        }
    }
    Some((0..p).map(|r| m[r * w + p]).collect())
}

fn invert(a: &[f64], p: usize) -> Option<Vec<f64>> {
    let mut inv = vec![0.0; p * p];
    for c in 0..p {
        let mut e = vec![0.0; p];
        e[c] = 1.0;
        let col = solve(a, &e, p)?;
        for r in 0..p {
            inv[r * p + c] = col[r];
        }
    }
    Some(inv)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn cubic_fits_are_exact_on_cubics_even_with_uneven_stamps() {
        let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.01 + 0.003 * ((i * 7 % 5) as f64)).collect();
        let f = |t: f64| 0.3 + 1.2 * t - 0.7 * t * t + 0.05 * t * t * t;
        let x: Vec<f64> = t.iter().map(|&t| f(t)).collect();
        let (d1, d2) = derivatives(&t, &x, 6);
        for (i, &ti) in t.iter().enumerate() {
            assert!((d1[i] - (1.2 - 1.4 * ti + 0.15 * ti * ti)).abs() < 1e-8, "d1 at {i}");
            assert!((d2[i] - (-1.4 + 0.3 * ti)).abs() < 1e-7, "d2 at {i}");
        }
    }

    #[test]
    fn interior_weights_match_the_fit() {
        let dt = 0.002;
        let h = 7;
        let (w1, w2) = weights(h, dt).unwrap();
        let t: Vec<f64> = (0..(2 * h + 1)).map(|i| i as f64 * dt).collect();
        let x: Vec<f64> = t.iter().map(|&t| (3.0 * t).sin()).collect();
        let (d1, d2) = derivatives(&t, &x, h);
        let c1: f64 = w1.iter().zip(&x).map(|(w, x)| w * x).sum();
        let c2: f64 = w2.iter().zip(&x).map(|(w, x)| w * x).sum();
        assert!((c1 - d1[h]).abs() < 1e-9 && (c2 - d2[h]).abs() < 1e-6, "{c1} {} {c2} {}", d1[h], d2[h]);
    }

    #[test]
    fn interior_gain_is_the_weights_square_sum_and_the_ends_are_worse() {
        let dt = 1e-3;
        let h = 10;
        let t: Vec<f64> = (0..200).map(|i| i as f64 * dt).collect();
        let e = estimate(&t, &vec![0.0; 200], h);
        let (w1, w2) = weights(h, dt).unwrap();
        let s1: f64 = w1.iter().map(|w| w * w).sum();
        let s2: f64 = w2.iter().map(|w| w * w).sum();
        assert!((e.gain1[100] / s1 - 1.0).abs() < 1e-9 && (e.gain2[100] / s2 - 1.0).abs() < 1e-9);
        assert!(e.gain1[0] > 5.0 * e.gain1[100] && e.gain2[0] > 5.0 * e.gain2[100]);
    }

    /// The running-sum interior of an uneven log against a fit of each window from scratch
    /// (the ends' path), on a non-polynomial signal and a long segment (many re-anchorings).
    #[test]
    fn running_sums_match_window_by_window_fits_on_jittered_stamps() {
        let n = 5000;
        let h = 40;
        let t: Vec<f64> =
            (0..n).map(|i| 10.0 + i as f64 * 1e-3 + 2e-4 * ((i * 7919 % 13) as f64 / 13.0 - 0.5)).collect();
        let x: Vec<f64> = t.iter().map(|&t| (2.3 * t).sin() + 0.2 * (11.0 * t).cos()).collect();
        let e = estimate(&t, &x, h);
        let p = DEGREE + 1;
        for i in (h..n - h).step_by(97) {
            let (lo, hi) = (i - h, i + h + 1);
            let scale = (t[hi - 1] - t[lo]) / 2.0;
            let mut a = vec![0.0; p * p];
            let mut b = vec![0.0; p];
            for j in lo..hi {
                let s = (t[j] - t[i]) / scale;
                for r in 0..p {
                    for c in 0..p {
                        a[r * p + c] += s.powi((r + c) as i32);
                    }
                    b[r] += s.powi(r as i32) * x[j];
                }
            }
            let c = solve(&a, &b, p).unwrap();
            let inv = invert(&a, p).unwrap();
            let (d1, d2) = (c[1] / scale, 2.0 * c[2] / (scale * scale));
            let (g1, g2) = (inv[p + 1] / (scale * scale), 4.0 * inv[2 * p + 2] / scale.powi(4));
            assert!((e.d1[i] - d1).abs() < 1e-9 * (1.0 + d1.abs()), "q̇ at {i}: {} vs {d1}", e.d1[i]);
            assert!((e.d2[i] - d2).abs() < 1e-7 * (1.0 + d2.abs()), "q̈ at {i}: {} vs {d2}", e.d2[i]);
            assert!((e.gain1[i] / g1 - 1.0).abs() < 1e-9 && (e.gain2[i] / g2 - 1.0).abs() < 1e-9, "gains at {i}");
        }
    }

    /// The sliding moments of an even log against the interior weights applied window by
    /// window, over many refreshes, on a signal far from zero (the rounding a slide could build).
    #[test]
    fn sliding_moments_match_the_weights_on_a_long_even_log() {
        let (n, h, dt) = (20_000, 150, 5e-4);
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let x: Vec<f64> = t.iter().map(|&t| 100.0 + (1.7 * t).sin() + 1e-3 * (40.0 * t).cos()).collect();
        let e = estimate(&t, &x, h);
        let (w1, w2) = weights(h, dt).unwrap();
        for i in (h..n - h).step_by(37) {
            let win = &x[i - h..=i + h];
            let c1: f64 = w1.iter().zip(win).map(|(w, v)| w * v).sum();
            let c2: f64 = w2.iter().zip(win).map(|(w, v)| w * v).sum();
            assert!((e.d1[i] - c1).abs() < 1e-9, "q̇ at {i}: {} vs {c1}", e.d1[i]);
            assert!((e.d2[i] - c2).abs() < 1e-6, "q̈ at {i}: {} vs {c2}", e.d2[i]);
        }
    }

    #[test]
    fn a_noisier_signal_gets_a_wider_window() {
        let quiet = choose_half_width(1e-3, Order::Second, 1e-6, 50.0, 200.0, 400).unwrap().0;
        let noisy = choose_half_width(1e-3, Order::Second, 1e-4, 50.0, 200.0, 400).unwrap().0;
        let fast = choose_half_width(1e-3, Order::Second, 1e-4, 5000.0, 2e4, 400).unwrap().0;
        assert!(noisy > quiet && fast < noisy, "quiet {quiet}, noisy {noisy}, fast {fast}");
    }
}
