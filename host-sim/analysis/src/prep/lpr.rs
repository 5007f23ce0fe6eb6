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
    let (w1, w2) = weights(h, dt)?;
    let (w, k, dk) = match order {
        Order::First => (w1, 5, d5),
        Order::Second => (w2, 4, d4),
    };
    let var = sigma * sigma * w.iter().map(|x| x * x).sum::<f64>();
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
    let mut best: Option<(usize, f64, f64)> = None;
    let mut h = 2usize;
    while h <= h_max.max(2) {
        if let Some((var, bias)) = error_at(h, dt, order, sigma, d4, d5) {
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
    let uniform = m == 2 * h + 1 && t.windows(2).all(|w| ((w[1] - w[0]) - dt).abs() <= 0.01 * dt);
    let interior = if uniform { weights(h, dt) } else { None }.map(|(w1, w2)| {
        let (g1, g2) = (w1.iter().map(|w| w * w).sum::<f64>(), w2.iter().map(|w| w * w).sum::<f64>());
        (w1, w2, g1, g2)
    });
    let mut a = vec![0.0; p * p];
    let mut b = vec![0.0; p];
    for i in 0..n {
        if let Some((w1, w2, g1, g2)) = interior.as_ref().filter(|_| i >= h && i + h < n) {
            let win = &x[i - h..=i + h];
            out.d1.push(w1.iter().zip(win).map(|(w, v)| w * v).sum());
            out.d2.push(w2.iter().zip(win).map(|(w, v)| w * v).sum());
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

    #[test]
    fn a_noisier_signal_gets_a_wider_window() {
        let quiet = choose_half_width(1e-3, Order::Second, 1e-6, 50.0, 200.0, 400).unwrap().0;
        let noisy = choose_half_width(1e-3, Order::Second, 1e-4, 50.0, 200.0, 400).unwrap().0;
        let fast = choose_half_width(1e-3, Order::Second, 1e-4, 5000.0, 2e4, 400).unwrap().0;
        assert!(noisy > quiet && fast < noisy, "quiet {quiet}, noisy {noisy}, fast {fast}");
    }
}
