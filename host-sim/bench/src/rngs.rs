//! Seeding and the few draws every module uses.
//!
//! Every case gets its own ChaCha stream from (seed, case, stream), so a case's data
//! does not depend on how many cases are generated or in which order.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// The generator's random source.
pub type Rng64 = ChaCha8Rng;

/// SplitMix64 finaliser: spreads nearby seeds (1, 2, 3 …) over the whole 64-bit space.
fn mix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// An independent stream for one (seed, case, purpose).
pub fn stream(seed: u64, case: u64, purpose: u64) -> Rng64 {
    let key = mix(mix(seed) ^ mix(case.wrapping_mul(0x100_0193)) ^ mix(purpose.wrapping_add(77)));
    ChaCha8Rng::seed_from_u64(key)
}

/// Uniform in [lo, hi]; a degenerate interval returns lo instead of panicking.
pub fn uniform(rng: &mut Rng64, lo: f64, hi: f64) -> f64 {
    if hi > lo {
        rng.random_range(lo..hi)
    } else {
        lo
    }
}

/// Log-uniform in [lo, hi] (both > 0): scale factors and noise levels spread over decades.
pub fn log_uniform(rng: &mut Rng64, lo: f64, hi: f64) -> f64 {
    uniform(rng, lo.ln(), hi.ln()).exp()
}

/// True with probability p (p clamped to [0, 1]).
pub fn chance(rng: &mut Rng64, p: f64) -> bool {
    rng.random_bool(p.clamp(0.0, 1.0))
}

/// ±1 with equal odds.
pub fn sign(rng: &mut Rng64) -> f64 {
    if chance(rng, 0.5) {
        1.0
    } else {
        -1.0
    }
}

/// A standard normal draw.
pub fn normal(rng: &mut Rng64) -> f64 {
    rng.sample(StandardNormal)
}

/// Integer in [lo, hi] inclusive.
pub fn int(rng: &mut Rng64, lo: usize, hi: usize) -> usize {
    if hi > lo {
        rng.random_range(lo..=hi)
    } else {
        lo
    }
}

/// One item of a weighted list (weights need not sum to 1); None only for an empty list.
pub fn weighted<T: Copy>(rng: &mut Rng64, items: &[(T, f64)]) -> Option<T> {
    let total: f64 = items.iter().map(|(_, w)| w.max(0.0)).sum();
    let mut x = uniform(rng, 0.0, total);
    for (item, w) in items {
        x -= w.max(0.0);
        if x <= 0.0 {
            return Some(*item);
        }
    }
    items.last().map(|(item, _)| *item)
}

/// One item of a list with equal odds.
pub fn pick<T: Copy>(rng: &mut Rng64, items: &[T]) -> Option<T> {
    let n = items.len();
    if n == 0 {
        return None;
    }
    items.get(int(rng, 0, n - 1)).copied()
}
