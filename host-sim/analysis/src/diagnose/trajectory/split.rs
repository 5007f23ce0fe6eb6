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

impl Split {
    pub fn new(n: usize) -> Split {
        let edge = |b: usize| (b * n + BLOCKS / 2) / BLOCKS;
        let mut held = vec![false; n];
        let mut unit = vec![usize::MAX; n];
        let mut units = 0;
        let mut held_blocks = Vec::new();
        for b in 0..BLOCKS {
            let (lo, hi) = (edge(b), edge(b + 1).min(n));
            if !is_held(b) || hi <= lo {
                continue;
            }
            held_blocks.push(b + 1);
            let len = hi - lo;
            let subs = len.min(4);
            for i in lo..hi {
                held[i] = true;
                unit[i] = units + ((i - lo) * subs / len).min(subs - 1);
            }
            units += subs;
        }
        let train = (0..n).filter(|&i| !held[i]).collect();
        Split { held, unit, units, train, blocks: BLOCKS, held_blocks }
    }

    pub fn n_train(&self) -> usize {
        self.train.len()
    }

    pub fn n_held(&self) -> usize {
        self.held.len() - self.train.len()
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
}
