//! Which samples the fits read and which only score them.
//!
//! A free decay shows its low-speed effects (a Stribeck rise, pre-sliding, where the joint
//! sticks) only in its last part, where the swing has died down: with the last 30 % held out,
//! a fit never sees them and an effect that is plainly there (the held-out residual twice the
//! noise) cannot be fitted. So the window is cut like torque mode's: 20 equal blocks in time,
//! blocks 3, 6, 9, 13, 16 and 19 (30 %) held out. The simulation still runs through a held-out
//! block without reading it, so its score is a prediction: the model must carry the state
//! through the block to meet the next training block, and the block's angles are never fitted.
//! Each held-out block is cut into up to four test units (one per sample in a short log: a
//! 20-sample log has six units of one sample, a 60-sample log twelve of one sample).
//! Cross-fitting ([`Split::folds`]) adds two more splits whose held-out blocks are the other
//! inner ones.

/// The split of one window.
#[derive(Clone, Debug)]
pub struct Split {
    /// per sample: held out
    pub held: Vec<bool>,
    /// per sample: its test unit (held-out samples only)
    pub unit: Vec<usize>,
    pub units: usize,
    /// every training sample, in order
    pub train: Vec<usize>,
    pub blocks: usize,
    /// held-out blocks, 1-based as torque mode reports them
    pub held_blocks: Vec<usize>,
}

pub const BLOCKS: usize = 20;

/// Held-out blocks (0-based): every block whose index mod 10 is 2, 5 or 8.
fn is_held(b: usize) -> bool {
    matches!(b % 10, 2 | 5 | 8)
}

/// The cross-fitting folds' held-out blocks (0-based), as torque mode's
/// ([`crate::diagnose::select::Split::cross_fitted`]): mod 10 in {0, 3, 6, 9} and in {1, 4, 7},
/// never the first block (where the start is read) nor the last. With [`is_held`]'s blocks
/// every other block is held out once.
fn fold_held(fold: usize, b: usize) -> bool {
    let inner = b != 0 && b + 1 != BLOCKS;
    inner
        && match fold {
            0 => matches!(b % 10, 0 | 3 | 6 | 9),
            _ => matches!(b % 10, 1 | 4 | 7),
        }
}

impl Split {
    pub fn new(n: usize) -> Split {
        Split::over(n, None)
    }

    /// The split of a window of `n` samples whose samples from `from` on are scored at every
    /// `m`-th one only (`thin = Some((from, m))`): the blocks are laid over the samples that can
    /// be scored, so a long noisy rest after a short motion leaves the motion its share of the
    /// held-out samples; every sample not held out is fitted, the whole rest included (its
    /// angle is evidence: a spring's or a friction's rest).
    pub fn over(n: usize, thin: Option<(usize, usize)>) -> Split {
        Split::over_blocks(n, thin, &is_held)
    }

    /// The two further folds of [`Split::over`]'s window for cross-fitting (see [`fold_held`]):
    /// with it, each inner block is held out by exactly one of the three.
    pub fn folds(n: usize, thin: Option<(usize, usize)>) -> [Split; 2] {
        [Split::over_blocks(n, thin, &|b| fold_held(0, b)), Split::over_blocks(n, thin, &|b| fold_held(1, b))]
    }

    fn over_blocks(n: usize, thin: Option<(usize, usize)>, is_held: &dyn Fn(usize) -> bool) -> Split {
        let used: Vec<usize> =
            (0..n).filter(|&i| thin.is_none_or(|(from, m)| i < from || (i - from) % m.max(1) == 0)).collect();
        let nu = used.len();
        let edge = |b: usize| (b * nu + BLOCKS / 2) / BLOCKS;
        let mut held = vec![false; n];
        let mut unit = vec![usize::MAX; n];
        let mut units = 0;
        let mut held_blocks = Vec::new();
        for b in 0..BLOCKS {
            let (lo, hi) = (edge(b), edge(b + 1).min(nu));
            if !is_held(b) || hi <= lo {
                continue;
            }
            held_blocks.push(b + 1);
            let len = hi - lo;
            let subs = len.min(4);
            for (k, &i) in used[lo..hi].iter().enumerate() {
                held[i] = true;
                unit[i] = units + (k * subs / len).min(subs - 1);
            }
            units += subs;
        }
        let train = (0..n).filter(|&i| !held[i]).collect();
        Split { held, unit, units, train, blocks: BLOCKS, held_blocks }
    }

    pub fn n_train(&self) -> usize {
        self.train.len()
    }

    /// The training samples a fit's residual reads: every one, thinned to at most 2 000 (every
    /// k-th).
    pub fn fit_rows(&self) -> Vec<usize> {
        self.train.iter().copied().step_by(self.n_train().div_ceil(2000).max(1)).collect()
    }

    pub fn n_held(&self) -> usize {
        self.held.iter().filter(|h| **h).count()
    }
}

/// The fewest training and held-out samples a window of `n` gives.
pub fn sizes(n: usize) -> (usize, usize) {
    let s = Split::new(n);
    (s.n_train(), s.n_held())
}

#[cfg(test)]
#[allow(clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn thirty_percent_held_in_six_blocks_and_short_logs_get_one_unit_per_sample() {
        let s = Split::new(1000);
        assert_eq!(s.n_held(), 300);
        assert_eq!(s.held_blocks, vec![3, 6, 9, 13, 16, 19]);
        assert_eq!(s.units, 24);
        assert!(!s.held[0] && !s.held[999]);
        let s = Split::new(20);
        assert_eq!((s.n_train(), s.n_held(), s.units), (14, 6, 6));
        let s = Split::new(35);
        assert_eq!(s.n_held(), s.units);
        assert!(s.n_held() >= 10);
    }

    #[test]
    fn a_thinned_tail_leaves_the_motion_its_held_out_blocks() {
        // 200 samples of motion and 1800 of rest scored at every 9th: 400 samples laid out in
        // blocks, half of them the motion, so about three of the six held-out blocks lie in it
        let s = Split::over(2000, Some((200, 9)));
        assert_eq!(s.held_blocks, vec![3, 6, 9, 13, 16, 19]);
        assert_eq!(s.n_held(), 120);
        let moving_held = (0..200).filter(|&i| s.held[i]).count();
        assert!((50..=70).contains(&moving_held), "{moving_held}");
        // only every 9th rest sample can be held out; every other sample is fitted
        assert!((200..2000).filter(|&i| s.held[i]).all(|i| (i - 200) % 9 == 0));
        assert_eq!(s.n_train() + s.n_held(), 2000);
        // no thinning: the plain split
        let (a, b) = (Split::over(1000, None), Split::new(1000));
        assert_eq!((a.held, a.unit, a.train), (b.held, b.unit, b.train));
    }

    #[test]
    fn the_three_folds_hold_out_every_inner_block_once() {
        for (n, thin) in [(1000, None), (57, None), (2000, Some((200, 9)))] {
            let main = Split::over(n, thin);
            let folds = Split::folds(n, thin);
            let mut times = vec![0usize; n];
            for s in std::iter::once(&main).chain(&folds) {
                assert_eq!(s.n_train() + s.n_held(), n);
                for i in 0..n {
                    times[i] += usize::from(s.held[i]);
                }
            }
            // never a sample held out twice; the first and the last block never
            assert!(times.iter().all(|&k| k <= 1));
            let all: Vec<usize> = std::iter::once(&main).chain(&folds).flat_map(|s| s.held_blocks.clone()).collect();
            let mut sorted = all.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (2..=19).collect::<Vec<_>>(), "{n}");
        }
    }
}
