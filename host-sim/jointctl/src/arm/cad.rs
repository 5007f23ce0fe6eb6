//! The arm's "CAD model": the gravity torques of the arm paper's Appendix A, reconstructed,
//! written as one potential energy and expanded into the core's trigonometric series.
//!
//! # Reconstruction (the text extraction lost minus signs and parentheses)
//! In the extracted Appendix A every `+` survived and every `−` (U+2212) vanished, so two terms
//! with no operator between them were joined by a minus. Read that way,
//! `τ1 = sin θ1·(2.3807 + 15.76045·sin θ34) − cos θ1·(0.5922 + 4.9509·sin θ2
//!       + cos θ2·(0.48671 + 15.76045·cos θ34 − 4.98265·sin θ34))`, θ34 = θ3 + θ4.
//! A static gravity torque is the gradient of one potential, `τ_j = ∂P/∂θ_j`, and τ1 fixes
//! `P = −cos θ1·X − sin θ1·Y` with `X = 2.3807 + 15.76045·sin θ34` and
//! `Y = 0.5922 + 4.9509·sin θ2 + cos θ2·(0.48671 + 15.76045·cos θ34 − 4.98265·sin θ34)` (up to
//! a function of θ2..θ4, which no term of τ2..τ4 calls for). The CAD model here is that P; all
//! four torques are its exact partial derivatives ([`CadModel::torques`]), checked against
//! finite differences of P in the tests.
//!
//! Against the paper's other three expressions read by the same rule
//! ([`appendix_a_literal`]):
//! - τ2: the paper's `sin θ1·(sin θ2·(0.48671 + 15.76045·cos θ3 − 4.98265·sin θ3) −
//!   5.4434·cos θ2)` has ∂P/∂θ2's signs and structure exactly, but `θ3` where P has `θ3 + θ4`
//!   and 5.4434 where ∂P/∂θ2 has 4.9509 (the `sin θ2` coefficient of τ1);
//! - τ3, τ4: with θ34 shifted by 90° (the π/2 offset of joint 3 in the paper's Table 3) the
//!   paper's τ3 is ∂P/∂θ3 except the sign of the 4.98265 term; its τ4 lacks the
//!   `15.76045·cos θ1` term that ∂P/∂θ4 must share with ∂P/∂θ3 (P depends on θ3 and θ4 only
//!   through θ3 + θ4 in every term the paper prints).
//!
//! So the four printed expressions are not the gradient of any single potential; the model
//! keeps τ1 verbatim and derives the rest from it. [`literal_mismatch`] measures the gaps.

use joint_core::series::{RawSeries, TERMS_MAX};
use std::f64::consts::FRAC_PI_2;

/// Appendix A coefficients, N·m.
pub const C_X0: f64 = 2.3807;
pub const C_FOREARM: f64 = 15.76045;
pub const C_Y0: f64 = 0.5922;
pub const C_S2: f64 = 4.9509;
pub const C_C2: f64 = 0.48671;
pub const C_CROSS: f64 = 4.98265;
/// The paper's τ2 `cos θ2` coefficient (differs from C_S2, see the module documentation).
pub const C_TAU2_C2: f64 = 5.4434;

/// sin or cos of a linear combination of the four joint angles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Trig {
    Sin([i8; 4]),
    Cos([i8; 4]),
}

impl Trig {
    fn arg(n: &[i8; 4], th: &[f64; 4]) -> f64 {
        n.iter().zip(th).map(|(&k, &x)| f64::from(k) * x).sum()
    }
    pub fn eval(&self, th: &[f64; 4]) -> f64 {
        match self {
            Trig::Sin(n) => Trig::arg(n, th).sin(),
            Trig::Cos(n) => Trig::arg(n, th).cos(),
        }
    }
    /// (n, φ) with the factor = sin(n·θ + φ).
    fn as_sin(&self) -> ([i8; 4], f64) {
        match *self {
            Trig::Sin(n) => (n, 0.0),
            Trig::Cos(n) => (n, FRAC_PI_2),
        }
    }
}

/// `coef · Π factors`.
#[derive(Clone, Debug, PartialEq)]
pub struct Product {
    pub coef: f64,
    pub factors: Vec<Trig>,
}

fn p(coef: f64, factors: &[Trig]) -> Product {
    Product { coef, factors: factors.to_vec() }
}

pub fn eval_sum(ps: &[Product], th: &[f64; 4]) -> f64 {
    ps.iter().map(|p| p.coef * p.factors.iter().map(|f| f.eval(th)).product::<f64>()).sum()
}

/// ∂/∂θ_j of a sum of products (product rule, d sin(n·θ) = n_j cos(n·θ) dθ_j).
pub fn derivative(ps: &[Product], j: usize) -> Vec<Product> {
    let mut out = Vec::new();
    for pr in ps {
        for (i, f) in pr.factors.iter().enumerate() {
            let (n, d) = match *f {
                Trig::Sin(n) => (n, Trig::Cos(n)),
                Trig::Cos(n) => (n, Trig::Sin(n)),
            };
            let nj = f64::from(n.get(j).copied().unwrap_or(0));
            if nj == 0.0 {
                continue;
            }
            let sign = if matches!(f, Trig::Cos(_)) { -1.0 } else { 1.0 };
            let mut factors = pr.factors.clone();
            if let Some(x) = factors.get_mut(i) {
                *x = d;
            }
            out.push(Product { coef: pr.coef * sign * nj, factors });
        }
    }
    out
}

/// One term `a·sin(n·θ + φ)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SinTerm {
    pub a: f64,
    pub phi: f64,
    pub n: [i8; 4],
}

/// Product-to-sum expansion: `sin x · sin y = ½ sin(x − y + π/2) + ½ sin(x + y − π/2)`,
/// applied factor by factor; terms with the same frequency vector are merged (a vector and its
/// negative are one frequency: `sin(−x + φ) = sin(x − φ + π)`), zero terms dropped.
pub fn expand(ps: &[Product]) -> Vec<SinTerm> {
    let mut raw: Vec<SinTerm> = Vec::new();
    for pr in ps {
        // the empty product is the constant coef = coef·sin(0·θ + π/2)
        let mut acc = vec![SinTerm { a: pr.coef, phi: FRAC_PI_2, n: [0; 4] }];
        for f in &pr.factors {
            let (m, psi) = f.as_sin();
            let mut next = Vec::with_capacity(2 * acc.len());
            for t in &acc {
                let minus: [i8; 4] = std::array::from_fn(|i| t.n[i] - m[i]);
                let plus: [i8; 4] = std::array::from_fn(|i| t.n[i] + m[i]);
                // t.a·sin(x)·sin(y), x = n·θ + φ, y = m·θ + ψ
                next.push(SinTerm { a: 0.5 * t.a, phi: t.phi - psi + FRAC_PI_2, n: minus });
                next.push(SinTerm { a: 0.5 * t.a, phi: t.phi + psi - FRAC_PI_2, n: plus });
            }
            acc = next;
        }
        // acc currently holds coef·sin(·)·Π…: the first factor was the constant sin(π/2) = 1.
        raw.extend(acc);
    }
    // canonical sign: first non-zero multiplier positive
    let mut merged: Vec<([i8; 4], f64, f64)> = Vec::new(); // (n, A of sin, B of cos)
    for mut t in raw {
        if let Some(&first) = t.n.iter().find(|&&k| k != 0) {
            if first < 0 {
                t.n = t.n.map(|k| -k);
                t.phi = -t.phi + std::f64::consts::PI;
            }
        }
        let (sa, ca) = (t.a * t.phi.cos(), t.a * t.phi.sin());
        match merged.iter_mut().find(|(n, _, _)| *n == t.n) {
            Some(e) => {
                e.1 += sa;
                e.2 += ca;
            }
            None => merged.push((t.n, sa, ca)),
        }
    }
    merged
        .into_iter()
        .filter_map(|(n, a_s, b_c)| {
            let r = a_s.hypot(b_c);
            if r < 1e-12 {
                return None;
            }
            if n == [0; 4] {
                // constant: keep it as value·sin(π/2)
                return Some(SinTerm { a: b_c, phi: FRAC_PI_2, n });
            }
            Some(SinTerm { a: r, phi: b_c.atan2(a_s), n })
        })
        .collect()
}

pub fn eval_terms(ts: &[SinTerm], th: &[f64; 4]) -> f64 {
    ts.iter().map(|t| t.a * (Trig::arg(&t.n, th) + t.phi).sin()).sum()
}

/// The other joints of joint `j` (0-based) in the order they fill its angle slots 1..=3.
pub fn others_of(j: usize) -> [usize; 3] {
    let mut o = [0usize; 3];
    let mut k = 0;
    for i in 0..4 {
        if i != j {
            if let Some(x) = o.get_mut(k) {
                *x = i;
            }
            k += 1;
        }
    }
    o
}

/// The series of joint `j` in the core's layout: multipliers over `[θ_j, others_of(j)…]`.
pub fn core_series(terms: &[SinTerm], j: usize) -> anyhow::Result<RawSeries> {
    if terms.len() > TERMS_MAX {
        anyhow::bail!("joint {}: {} series terms, the core holds {TERMS_MAX}", j + 1, terms.len());
    }
    let order = {
        let o = others_of(j);
        [j, o[0], o[1], o[2]]
    };
    let mut s = RawSeries::EMPTY;
    for (k, t) in terms.iter().enumerate() {
        if let (Some(a), Some(ph), Some(m)) = (s.amplitude.get_mut(k), s.phase.get_mut(k), s.mult.get_mut(k)) {
            *a = t.a as f32;
            *ph = t.phi as f32;
            *m = order.map(|i| t.n.get(i).copied().unwrap_or(0));
        }
    }
    s.n_terms = terms.len() as u8;
    Ok(s)
}

/// A gravity model given by its potential energy as products of sines and cosines.
#[derive(Clone, Debug)]
pub struct CadModel {
    pub potential: Vec<Product>,
    /// ∂P/∂θ_j as products, derived once
    grad: Vec<Vec<Product>>,
}

const S1: Trig = Trig::Sin([1, 0, 0, 0]);
const C1: Trig = Trig::Cos([1, 0, 0, 0]);
const S2: Trig = Trig::Sin([0, 1, 0, 0]);
const C2: Trig = Trig::Cos([0, 1, 0, 0]);
const S34: Trig = Trig::Sin([0, 0, 1, 1]);
const C34: Trig = Trig::Cos([0, 0, 1, 1]);

impl CadModel {
    /// P with the given forearm moment (15.76045 in the paper) and cross term (4.98265): the
    /// plant scales these to stand for a mass/centroid error of the CAD data.
    pub fn with(forearm: f64, cross: f64) -> CadModel {
        // P = −cos θ1·X − sin θ1·Y
        let potential = vec![
            p(-C_X0, &[C1]),
            p(-forearm, &[C1, S34]),
            p(-C_Y0, &[S1]),
            p(-C_S2, &[S1, S2]),
            p(-C_C2, &[S1, C2]),
            p(-forearm, &[S1, C2, C34]),
            p(cross, &[S1, C2, S34]),
        ];
        let grad = (0..4).map(|j| derivative(&potential, j)).collect();
        CadModel { potential, grad }
    }

    /// The paper's model (Appendix A, reconstructed).
    pub fn paper() -> CadModel {
        CadModel::with(C_FOREARM, C_CROSS)
    }

    pub fn potential(&self, th: &[f64; 4]) -> f64 {
        eval_sum(&self.potential, th)
    }

    /// τ_j = ∂P/∂θ_j as products.
    pub fn torque_products(&self, j: usize) -> Vec<Product> {
        self.grad.get(j).cloned().unwrap_or_default()
    }

    pub fn torques(&self, th: &[f64; 4]) -> [f64; 4] {
        std::array::from_fn(|j| self.grad.get(j).map_or(0.0, |g| eval_sum(g, th)))
    }

    /// Joint `j`'s torque expanded into sine terms (what the core runs).
    pub fn series_terms(&self, j: usize) -> Vec<SinTerm> {
        expand(&self.torque_products(j))
    }
}

/// The four expressions as printed in Appendix A, minus signs restored by the rule of the
/// module documentation, not made consistent.
pub fn appendix_a_literal(th: &[f64; 4]) -> [f64; 4] {
    let [t1, t2, t3, t4] = *th;
    let (s1, c1, s2, c2) = (t1.sin(), t1.cos(), t2.sin(), t2.cos());
    let (s34, c34) = ((t3 + t4).sin(), (t3 + t4).cos());
    let (s3, c3) = (t3.sin(), t3.cos());
    let tau1 = s1 * (C_X0 + C_FOREARM * s34) - c1 * (C_Y0 + C_S2 * s2 + c2 * (C_C2 + C_FOREARM * c34 - C_CROSS * s34));
    let tau2 = s1 * (s2 * (C_C2 + C_FOREARM * c3 - C_CROSS * s3) - C_TAU2_C2 * c2);
    let tau3 = c1 * C_FOREARM * s34 + s1 * c2 * (C_FOREARM * c34 + C_CROSS * s34);
    let tau4 = s1 * c2 * (C_FOREARM * c34 + C_CROSS * s34);
    [tau1, tau2, tau3, tau4]
}

/// How far the literal expressions are from the CAD model's gradient over `poses`: per joint
/// the largest |literal − ∂P/∂θ_j|, N·m, as printed and (τ3, τ4) with θ34 shifted by +90°.
pub fn literal_mismatch(m: &CadModel, poses: &[[f64; 4]]) -> ([f64; 4], [f64; 4]) {
    let mut plain = [0.0f64; 4];
    let mut shifted = [0.0f64; 4];
    for th in poses {
        let g = m.torques(th);
        let lit = appendix_a_literal(th);
        // literal τ3/τ4 evaluated at θ3 − 90° compare with the model at θ3
        let mut th_s = *th;
        th_s[2] -= FRAC_PI_2;
        let lit_s = appendix_a_literal(&th_s);
        for j in 0..4 {
            plain[j] = plain[j].max((lit[j] - g[j]).abs());
            let l = if j >= 2 { lit_s[j] } else { lit[j] };
            shifted[j] = shifted[j].max((l - g[j]).abs());
        }
    }
    (plain, shifted)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing)]
    use super::*;

    fn poses() -> Vec<[f64; 4]> {
        let mut v = Vec::new();
        for i in 0..7 {
            for k in 0..5 {
                let a = i as f64 * 0.31 - 0.4;
                let b = k as f64 * 0.47 - 0.2;
                v.push([a, b, 0.5 * a + b, 1.3 - b]);
            }
        }
        v
    }

    #[test]
    fn torques_are_the_gradient_of_one_potential() {
        let m = CadModel::paper();
        let h = 1e-6;
        for th in poses() {
            let g = m.torques(&th);
            for j in 0..4 {
                let (mut a, mut b) = (th, th);
                a[j] += h;
                b[j] -= h;
                let fd = (m.potential(&a) - m.potential(&b)) / (2.0 * h);
                assert!((fd - g[j]).abs() < 1e-7, "joint {j}: {fd} vs {}", g[j]);
            }
        }
    }

    #[test]
    fn tau1_is_appendix_a_verbatim() {
        let m = CadModel::paper();
        for th in poses() {
            assert!((m.torques(&th)[0] - appendix_a_literal(&th)[0]).abs() < 1e-12);
        }
    }

    #[test]
    fn expansion_reproduces_the_products_within_capacity() {
        let m = CadModel::paper();
        for j in 0..4 {
            let terms = m.series_terms(j);
            assert!(terms.len() <= TERMS_MAX, "joint {j}: {} terms", terms.len());
            for th in poses() {
                let want = m.torques(&th)[j];
                assert!((eval_terms(&terms, &th) - want).abs() < 1e-12, "joint {j}");
            }
        }
    }

    #[test]
    fn core_series_in_f32_matches_the_f64_model() {
        let m = CadModel::paper();
        for j in 0..4 {
            let s = core_series(&m.series_terms(j), j).unwrap();
            assert_eq!(joint_core::series::validate(&s), Ok(()));
            let o = others_of(j);
            for th in poses() {
                let angles = [th[j] as f32, th[o[0]] as f32, th[o[1]] as f32, th[o[2]] as f32];
                let got = f64::from(joint_core::series::eval(&s, &angles));
                assert!((got - m.torques(&th)[j]).abs() < 1e-4, "joint {j}");
            }
        }
    }
}
