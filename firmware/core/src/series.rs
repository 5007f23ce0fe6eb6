//! Analytic multi-angle gravity: a short trigonometric series over the joint's own angle and
//! the three other-joint angle slots.
//!
//! `τ_s = Σ_k a_k · sin(n_k · [q, o0, o1, o2] + φ_k)`, with `n_k` small integer vectors. This is
//! the form every rigid-body gravity model of a serial arm takes once its products of sines and
//! cosines are expanded by the product-to-sum identities (arm paper §3.2.1, Appendix A: at most
//! 16 terms per joint for the shoulder/elbow chain), so a CAD model can run on the joint MCU as
//! data, not as code. The host does the expansion; the core only evaluates and validates.
//!
//! Storage is fixed ([`TERMS_MAX`] terms) and a series is a plain value like the gravity table.
//! [`validate`] refuses anything [`eval`] could not evaluate meaningfully (non-finite or huge
//! amplitudes and phases, multipliers beyond ±[`MULT_MAX`], more than [`TERMS_MAX`] terms),
//! naming the term; [`eval`] itself never panics and returns 0 for an empty series.

use crate::math;

/// Most terms a series may have.
pub const TERMS_MAX: usize = 16;
/// Largest |multiplier| of an angle in one term's argument.
pub const MULT_MAX: i8 = 4;
/// Largest |amplitude|, N·m (a gravity term of a joint board never needs more).
pub const AMPLITUDE_MAX: f32 = 1.0e4;
/// Largest |phase|, rad.
pub const PHASE_MAX: f32 = 100.0;
/// Bytes of one term on the wire and in the store: amplitude f32, phase f32, 4 × i8.
pub const TERM_BYTES: usize = 12;

/// A gravity series as received (TOML, SDO, flash); unchecked.
#[derive(Clone, Debug, PartialEq)]
pub struct RawSeries {
    /// number of terms in use (0 = no series)
    pub n_terms: u8,
    /// a_k, N·m
    pub amplitude: [f32; TERMS_MAX],
    /// φ_k, rad
    pub phase: [f32; TERMS_MAX],
    /// n_k: multipliers of [q, others[0], others[1], others[2]]
    pub mult: [[i8; 4]; TERMS_MAX],
}

impl RawSeries {
    pub const EMPTY: RawSeries =
        RawSeries { n_terms: 0, amplitude: [0.0; TERMS_MAX], phase: [0.0; TERMS_MAX], mult: [[0; 4]; TERMS_MAX] };

    /// Term `k` in its wire layout (little-endian amplitude, phase, then the 4 multipliers).
    pub fn term_bytes(&self, k: usize) -> [u8; TERM_BYTES] {
        let mut b = [0u8; TERM_BYTES];
        let a = self.amplitude.get(k).copied().unwrap_or(0.0).to_le_bytes();
        let p = self.phase.get(k).copied().unwrap_or(0.0).to_le_bytes();
        let m = self.mult.get(k).copied().unwrap_or([0; 4]);
        for (i, x) in b.iter_mut().enumerate() {
            *x = match i {
                0..=3 => a.get(i).copied().unwrap_or(0),
                4..=7 => p.get(i - 4).copied().unwrap_or(0),
                _ => m.get(i - 8).copied().unwrap_or(0) as u8,
            };
        }
        b
    }

    /// Set term `k` from its wire layout; out-of-range `k` or short input changes nothing.
    pub fn set_term_bytes(&mut self, k: usize, b: &[u8]) {
        let (Some(a), Some(p), Some(m)) = (b.get(0..4), b.get(4..8), b.get(8..12)) else {
            return;
        };
        let f = |s: &[u8]| {
            let mut w = [0u8; 4];
            for (d, x) in w.iter_mut().zip(s) {
                *d = *x;
            }
            f32::from_le_bytes(w)
        };
        if let (Some(da), Some(dp), Some(dm)) = (self.amplitude.get_mut(k), self.phase.get_mut(k), self.mult.get_mut(k))
        {
            *da = f(a);
            *dp = f(p);
            for (d, x) in dm.iter_mut().zip(m) {
                *d = *x as i8;
            }
        }
    }
}

impl Default for RawSeries {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// Why a series was refused. Term indices are 0-based.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SeriesError {
    /// more than [`TERMS_MAX`] terms
    TooManyTerms { n_terms: u8 },
    /// amplitude NaN/∞ or beyond ±[`AMPLITUDE_MAX`]
    Amplitude { term: u8 },
    /// phase NaN/∞ or beyond ±[`PHASE_MAX`]
    Phase { term: u8 },
    /// a multiplier beyond ±[`MULT_MAX`]
    Multiplier { term: u8, slot: u8 },
}

impl core::fmt::Display for SeriesError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            // Brief: every byte of text is flash on the board; the limits are in this module.
            SeriesError::TooManyTerms { n_terms } => {
                write!(f, "gravity_series has {n_terms} terms, at most {TERMS_MAX} fit")
            }
            SeriesError::Amplitude { term } => write!(f, "gravity_series term {term}: bad amplitude"),
            SeriesError::Phase { term } => write!(f, "gravity_series term {term}: bad phase"),
            SeriesError::Multiplier { term, slot } => {
                write!(f, "gravity_series term {term}: multiplier {slot} beyond ±{MULT_MAX}")
            }
        }
    }
}

/// Checks what [`eval`] relies on. Terms beyond `n_terms` are ignored.
pub fn validate(s: &RawSeries) -> Result<(), SeriesError> {
    let n = s.n_terms as usize;
    if n > TERMS_MAX {
        return Err(SeriesError::TooManyTerms { n_terms: s.n_terms });
    }
    for k in 0..n {
        let term = k as u8;
        let a = s.amplitude.get(k).copied().unwrap_or(f32::NAN);
        // `!(x <= max)` is also true for NaN.
        if !(math::is_finite(a) && math::abs(a) <= AMPLITUDE_MAX) {
            return Err(SeriesError::Amplitude { term });
        }
        let p = s.phase.get(k).copied().unwrap_or(f32::NAN);
        if !(math::is_finite(p) && math::abs(p) <= PHASE_MAX) {
            return Err(SeriesError::Phase { term });
        }
        let m = s.mult.get(k).copied().unwrap_or([i8::MAX; 4]);
        for (slot, &x) in m.iter().enumerate() {
            if !(-MULT_MAX..=MULT_MAX).contains(&x) {
                return Err(SeriesError::Multiplier { term, slot: slot as u8 });
            }
        }
    }
    Ok(())
}

/// `Σ a_k·sin(n_k·angles + φ_k)` over the first `n_terms` terms, `angles = [q, o0, o1, o2]`.
/// The argument is summed in a fixed order (q, o0, o1, o2, then φ) so every target computes
/// the same bits. Inputs are the control step's clamped angles, so the argument stays far
/// inside the range where [`math::sin`] is exact to its polynomial.
/// Kept out of line on purpose: inlined into the control step, its loop's register use costs
/// every step ~12 instructions even with an empty series (`scripts/fw-bench.sh`).
#[inline(never)]
pub fn eval(s: &RawSeries, angles: &[f32; 4]) -> f32 {
    let n = (s.n_terms as usize).min(TERMS_MAX);
    let mut acc = 0.0f32;
    for ((a, p), m) in s.amplitude.iter().zip(s.phase.iter()).zip(s.mult.iter()).take(n) {
        let mut arg = 0.0f32;
        for (&k, &x) in m.iter().zip(angles.iter()) {
            if k != 0 {
                arg += f32::from(k) * x;
            }
        }
        acc += *a * math::sin(arg + *p);
    }
    acc
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing, clippy::unwrap_used)]
    use super::*;

    fn sample() -> RawSeries {
        let mut s = RawSeries::EMPTY;
        let terms: [(f32, f32, [i8; 4]); 5] = [
            (2.5, 0.3, [1, 0, 0, 0]),
            (-1.25, 1.5707964, [1, -1, 0, 0]),
            (0.75, -0.2, [1, 1, 1, 1]),
            (3.0, 0.0, [0, 0, 2, -1]),
            (-0.5, 2.0, [-4, 4, 0, 3]),
        ];
        for (k, (a, p, m)) in terms.iter().enumerate() {
            s.amplitude[k] = *a;
            s.phase[k] = *p;
            s.mult[k] = *m;
        }
        s.n_terms = terms.len() as u8;
        s
    }

    #[test]
    fn eval_matches_an_f64_reference() {
        let s = sample();
        let mut worst = 0.0f64;
        for i in 0..200 {
            let t = i as f32 * 0.037;
            let angles = [t - 1.0, 0.5 * t, 1.2 - t, 0.3 * t - 0.7];
            let mut want = 0.0f64;
            for k in 0..s.n_terms as usize {
                let mut arg = f64::from(s.phase[k]);
                for (m, x) in s.mult[k].iter().zip(angles.iter()) {
                    arg += f64::from(*m) * f64::from(*x);
                }
                want += f64::from(s.amplitude[k]) * libm::sin(arg);
            }
            let got = f64::from(eval(&s, &angles));
            worst = worst.max(libm::fabs(got - want));
        }
        // f32 arithmetic on |args| < 20 rad and |a| ≤ 3: a few ulps of the largest term.
        assert!(worst < 2.0e-5, "worst |f32 − f64| = {worst}");
    }

    #[test]
    fn empty_series_is_zero_and_terms_beyond_the_count_are_ignored() {
        let mut s = sample();
        s.n_terms = 0;
        assert_eq!(eval(&s, &[0.3, 0.2, 0.1, 0.0]).to_bits(), 0.0f32.to_bits());
        let full = sample();
        let mut longer = sample();
        longer.amplitude[7] = f32::NAN;
        assert_eq!(eval(&full, &[0.3, 0.2, 0.1, 0.0]), eval(&longer, &[0.3, 0.2, 0.1, 0.0]));
        assert_eq!(validate(&longer), Ok(()));
    }

    #[test]
    fn validation_names_the_term() {
        let mut s = sample();
        s.amplitude[2] = f32::NAN;
        assert_eq!(validate(&s), Err(SeriesError::Amplitude { term: 2 }));
        let mut s = sample();
        s.amplitude[1] = 2.0e4;
        assert_eq!(validate(&s), Err(SeriesError::Amplitude { term: 1 }));
        let mut s = sample();
        s.phase[4] = f32::INFINITY;
        assert_eq!(validate(&s), Err(SeriesError::Phase { term: 4 }));
        let mut s = sample();
        s.mult[3][2] = 5;
        assert_eq!(validate(&s), Err(SeriesError::Multiplier { term: 3, slot: 2 }));
        let mut s = sample();
        s.n_terms = TERMS_MAX as u8 + 1;
        assert_eq!(validate(&s), Err(SeriesError::TooManyTerms { n_terms: 17 }));
        // eval on a refused series still returns without panicking
        let _ = eval(&s, &[1.0, 2.0, 3.0, 4.0]);
    }

    #[test]
    fn wire_layout_round_trips() {
        let s = sample();
        let mut t = RawSeries::EMPTY;
        for k in 0..s.n_terms as usize {
            t.set_term_bytes(k, &s.term_bytes(k));
        }
        t.n_terms = s.n_terms;
        assert_eq!(s, t);
    }
}
