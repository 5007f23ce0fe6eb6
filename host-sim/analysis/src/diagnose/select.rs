//! Held-out scoring, the significance test and forward selection (torque mode).
//!
//! Split: the log is cut into 20 equal contiguous blocks; blocks 3, 6, 9, 13, 16 and 19 (every
//! block whose index mod 10 is 2, 5 or 8, i.e. 30 %) are held out and spread over the whole run,
//! so every scenario and every part of a warm-up is in both parts. A guard of up to 50 samples
//! on each side of a held-out block is dropped from training so filters and lags cannot leak.
//! No fit ever reads a held-out sample: shapes are searched and amplitudes solved on training
//! samples only; held-out samples are only scored.
//!
//! Cross-fitting (logs up to `CROSS_FIT_MAX` samples, [`Split::cross_fitted`]): two more folds
//! hold out the blocks the first trains on (the log's first and last block excepted), each fold
//! searches, fits and scores on its own, and every score is the three folds' held-out scores
//! merged ([`merge`]), so the tests read 90 % of the samples instead of 30 %.
//!
//! Test: each held-out block is cut into up to 10 sub-blocks (up to 60 units). For a candidate
//! against its reference (the refitted model for an effect, the file's model for `parameters`)
//! the per-unit log ratio of mean squared residuals and their difference are tested with
//! one-sided t-tests (the smaller p, doubled); units are
//! long compared with the residual's correlation time, which a per-sample F-test would ignore. A
//! candidate is significant when p < α/m (α = 5 %, m = number of candidates, Bonferroni), it
//! lowers the held-out MSE by at least 2 % (smaller gains are not worth a model change), and its
//! reference is not already at the noise floor (held-out RMSE ≤ 1.05 × floor): with noisy q̇ and
//! q̈ a refit can always shave a little off by shrinking coefficients (errors in variables),
//! which is not a physical effect. When the log has its own q̈ column, the white noise on it is
//! estimated and removed from the final fits' normal equations (corrected least squares), so
//! the inertia is not shrunk, and the margin is 1.02 × floor.

use super::candidates::{search, search_in, Base, Col, Data, Delta, Design, Effect, GridCtx, Kind, ThermSrc};
use joint_formats::vocab::Effect as Vocab;

/// How the samples were split.
#[derive(Clone, Debug)]
pub struct Split {
    pub train: Vec<u32>,
    pub holdout: Vec<u32>,
    /// test unit of each held-out sample (parallel to `holdout`)
    pub unit: Vec<u16>,
    pub n_units: usize,
    pub blocks: usize,
    pub guard: usize,
    /// the samples left out of fits and scores alike ([`Split::leave_out`])
    pub left_out: Vec<bool>,
    /// weight of each held-out sample in the projection test, the gains and the weighted floor
    /// (parallel to `holdout`; empty: all alike): the inverse of its expected error variance
    /// ([`Split::weigh`])
    pub weight: std::sync::Arc<Vec<f64>>,
    /// the floor in the weighted MSE's terms (0 without weights): what a model that leaves each
    /// sample its expected error scores, `1/mean(1/var)` in MSE
    pub wfloor: f64,
    /// cross-fitting ([`Split::cross_fitted`]): the other folds, whose held-out blocks are the
    /// blocks this split trains on; empty for a single split
    pub folds: Vec<Split>,
}

pub const ALPHA: f64 = 0.05;
pub const MIN_GAIN: f64 = 0.02;
/// A reference whose held-out RMSE is within this factor of the noise floor has nothing left
/// to explain: no candidate against it is called significant.
pub const AT_FLOOR: f64 = 1.1;
/// The same when the log's own q̈ column carries measurable white noise and the final fits
/// correct for it ([`Data::qdd_noise_var`]): the margin that kept coefficient shrinkage from
/// passing for an effect is then mostly not needed, and a wider one hides real effects on long
/// logs (a 5 ms delay on a 190 000-sample log sat at 1.038 × floor with p ≈ 1e-6).
pub const AT_FLOOR_EIV: f64 = 1.1;
/// A candidate that takes at least this share of the held-out MSE (significantly) is judged on
/// that alone: the floor is an estimate, and a fast effect (a delay, a short ripple, friction
/// at reversals) raises it, because its structure looks like noise at the smallest lags. The
/// floor rule is for small gains (coefficient shrinkage, errors in variables).
pub const CLEAR_GAIN: f64 = 0.15;
/// At the floor a candidate still counts on evidence no coefficient shrinkage or estimate error
/// gives: p below this (Bonferroni over the candidates, as [`ALPHA`]) for at least
/// [`AT_FLOOR_GAIN`] of the held-out MSE, on a log whose file residual is not below the floor
/// (where it is, the floor is set by uncertain samples, and fits of their structure reached
/// p ≈ 1e-5 on model-exact logs). The floor is an estimate that an effect near rest or at the
/// smallest lags raises: a Stribeck curve at 2.4 × the noise, most of it where the direction of
/// motion is unknown, left the file's residual at 1.05 × the floor with p = 2e-7 (development
/// seed 9033, case 52). On 1 500 model-exact torque logs (null seeds 31, 777, 4242) no candidate
/// met this.
pub const ALPHA_AT_FLOOR: f64 = 0.001;
pub const AT_FLOOR_GAIN: f64 = 0.05;
/// A second (third) effect takes at least this share of the held-out MSE still above the floor.
pub const FURTHER_SHARE: f64 = 0.25;
/// The most training rows a fit reads (every k-th); grids read fewer.
pub const FIT_ROWS: usize = 150_000;

/// Whether `cand` takes at least [`FURTHER_SHARE`] of what `reference` leaves above the noise
/// floor `floor` (held-out MSE): a real share, not a significant sliver off the noise or off
/// what a refit left unfinished.
pub fn takes_share(reference: &Scored, cand: &Scored, floor: f64) -> bool {
    reference.mse() - cand.mse() >= FURTHER_SHARE * (reference.mse() - floor * floor)
}

/// The at-the-floor factor for this log (see [`AT_FLOOR_EIV`]).
pub fn at_floor_factor(d: &Data) -> f64 {
    if d.qdd_noise_var > 0.0 {
        AT_FLOOR_EIV
    } else {
        AT_FLOOR
    }
}

pub fn make_split(n: usize) -> Split {
    make_split_units(n, 50)
}

/// [`make_split`] with test units of at least `unit_min` samples: units must be long against
/// the time over which the residual's errors are correlated (the noise's colour, the q̇/q̈
/// estimates' windows), or neighbouring units are not independent; where those are short, a
/// short log gets more units and its tests their degrees of freedom.
pub fn make_split_units(n: usize, unit_min: usize) -> Split {
    blocked_split(n, unit_min, &|b| matches!(b % 10, 2 | 5 | 8))
}

/// The blocked split with the blocks `held` says held out (see [`make_split_units`]).
fn blocked_split(n: usize, unit_min: usize, held: &dyn Fn(usize) -> bool) -> Split {
    let blocks = 20usize;
    let len = n.div_ceil(blocks).max(1);
    let guard = (len / 10).min(50);
    // 10 test units per held-out block (fewer in short logs, at least `unit_min` samples each).
    let subs = (len / unit_min.max(1)).clamp(2, 10);
    let mut train = Vec::with_capacity(n);
    let mut holdout = Vec::with_capacity(n * 3 / 10 + 1);
    let mut unit = Vec::with_capacity(n * 3 / 10 + 1);
    let mut unit_of_block = 0usize;
    let mut last_block = usize::MAX;
    for i in 0..n {
        let b = i / len;
        let off = i % len;
        if held(b) {
            if b != last_block {
                last_block = b;
                if !holdout.is_empty() {
                    unit_of_block += subs;
                }
            }
            holdout.push(i as u32);
            unit.push((unit_of_block + (off * subs / len).min(subs - 1)) as u16);
        } else {
            let near_next = held(b + 1) && len - off <= guard;
            let near_prev = b > 0 && held(b - 1) && off < guard;
            if !(near_next || near_prev) {
                train.push(i as u32);
            }
        }
    }
    let n_units = if holdout.is_empty() { 0 } else { unit_of_block + subs };
    Split {
        train,
        holdout,
        unit,
        n_units,
        blocks,
        guard,
        left_out: vec![false; n],
        weight: Default::default(),
        wfloor: 0.0,
        folds: Vec::new(),
    }
}

impl Split {
    /// This split ([`make_split_units`], blocks 2, 5, 8 mod 10 held out) with two more folds
    /// that hold out blocks 0, 3, 6, 9 and 1, 4, 7 mod 10 (of the 20 blocks, 0-based), the log's
    /// first and last block excepted: every other sample is held out in exactly one fold, each
    /// fold's fits read only its own training blocks (guards as in the first), and a model's
    /// scores on the three folds merged ([`merge`]) test it on 90 % of the samples instead of
    /// 30 %. The first and last blocks stay training only, as in the one split: there the q̇/q̈
    /// estimates are one-sided, and a null log's residual at its ends was 4× its RMSE elsewhere
    /// (null seed 31, case 3, a chirp: 0.50 N·m against 0.12 N·m).
    pub fn cross_fitted(mut self, n: usize, unit_min: usize) -> Split {
        let inner = |b: usize| b != 0 && b != self.blocks - 1;
        self.folds = vec![
            blocked_split(n, unit_min, &|b| inner(b) && matches!(b % 10, 0 | 3 | 6 | 9)),
            blocked_split(n, unit_min, &|b| inner(b) && matches!(b % 10, 1 | 4 | 7)),
        ];
        for f in &mut self.folds {
            f.leave_out(&self.left_out);
        }
        self
    }

    /// This split and its cross-fitting folds, this one first.
    pub fn all_folds(&self) -> Vec<&Split> {
        std::iter::once(self).chain(&self.folds).collect()
    }

    /// The held-out samples of all folds, in log order (with cross-fitting: every sample not
    /// left out; without: [`Split::holdout`]).
    pub fn holdout_all(&self) -> Vec<u32> {
        let mut all: Vec<u32> = self.all_folds().iter().flat_map(|f| f.holdout.iter().copied()).collect();
        all.sort_unstable();
        all
    }

    /// The held-out samples over all folds.
    pub fn holdout_total(&self) -> usize {
        self.all_folds().iter().map(|f| f.holdout.len()).sum()
    }

    /// Leaves the samples marked in `out` out of training and held-out scoring alike.
    pub fn leave_out(&mut self, out: &[bool]) {
        for f in &mut self.folds {
            f.leave_out(out);
        }
        let keep = |i: &u32| !out.get(*i as usize).copied().unwrap_or(false);
        self.train.retain(keep);
        let (mut h, mut u) = (Vec::with_capacity(self.holdout.len()), Vec::with_capacity(self.unit.len()));
        for (i, unit) in self.holdout.iter().zip(&self.unit) {
            if keep(i) {
                h.push(*i);
                u.push(*unit);
            }
        }
        self.holdout = h;
        self.unit = u;
        for (l, &o) in self.left_out.iter_mut().zip(out) {
            *l |= o;
        }
        // weights are set once the samples are settled; any set before no longer line up
        self.weight = Default::default();
        self.wfloor = 0.0;
    }

    /// Weighs each held-out sample by `1/var(i)` in the projection test and the gains
    /// ([`compare`]) and sets the weighted floor, `var` the error variance the sample is
    /// expected to carry. Left alike (no weights) when any
    /// variance is not a positive finite number.
    /// With cross-fitting folds, every fold is weighed alike, scaled by the mean over all folds'
    /// held-out samples (so merged folds weigh their samples on one scale).
    pub fn weigh(&mut self, var: impl Fn(usize) -> f64) {
        let raw = |s: &Split| -> Vec<f64> { s.holdout.iter().map(|&i| 1.0 / var(i as usize)).collect() };
        let ws: Vec<Vec<f64>> = self.all_folds().into_iter().map(raw).collect();
        let count: usize = ws.iter().map(Vec::len).sum();
        let ok = ws.iter().all(|w| !w.is_empty() && w.iter().all(|x| x.is_finite() && *x > 0.0));
        // scaled to a mean of 1 (the test does not depend on the scale)
        let mean = ws.iter().flatten().sum::<f64>() / count.max(1) as f64;
        let apply = |s: &mut Split, w: Vec<f64>| {
            if ok {
                s.weight = std::sync::Arc::new(w.into_iter().map(|x| x / mean).collect());
                s.wfloor = (1.0 / mean).sqrt();
            } else {
                s.weight = Default::default();
                s.wfloor = 0.0;
            }
        };
        let mut ws = ws.into_iter();
        if let Some(w) = ws.next() {
            apply(self, w);
        }
        for (f, w) in self.folds.iter_mut().zip(ws) {
            apply(f, w);
        }
    }
}

/// A model scored on the held-out samples.
#[derive(Clone, Debug)]
pub struct Scored {
    pub effects: Vec<Effect>,
    pub design: Design,
    pub beta: Vec<f64>,
    pub sse: f64,
    pub n: usize,
    pub unit_sse: Vec<f64>,
    pub unit_n: Vec<f64>,
    pub regime_sse: Vec<f64>,
    pub regime_n: Vec<f64>,
    /// the held-out residuals in the split's order (for the projection test of [`compare`])
    pub resid: std::sync::Arc<Vec<f64>>,
    /// trajectory mode: the projection test reads its variance from chunks of the units as
    /// short as the residual's correlation allows ([`projection_chunk`]), not from whole units
    pub chunked: bool,
    /// the split's held-out weights ([`Split::weight`]; empty: all alike)
    pub weight: std::sync::Arc<Vec<f64>>,
    /// the weighted sum of squares with those weights (`sse` without them)
    pub wsse: f64,
    /// a cross-fitted score ([`merge`]): each further fold's own fit (`effects`, `design` and
    /// `beta` are the first fold's); empty for one split
    pub folds: Vec<FoldFit>,
}

/// One further fold's fit in a cross-fitted score: its effects (the next round builds on them)
/// and its coefficients (where the folds disagree on a term of the model, the log does not pin
/// it: [`super::fold_undetermined`]).
#[derive(Clone, Debug)]
pub struct FoldFit {
    pub effects: Vec<Effect>,
    pub design: Design,
    pub beta: Vec<f64>,
}

impl Scored {
    pub fn mse(&self) -> f64 {
        self.sse / self.n.max(1) as f64
    }
    pub fn rmse(&self) -> f64 {
        self.mse().sqrt()
    }
    /// The held-out MSE with each sample weighted ([`Split::weigh`]; the weights' mean is 1):
    /// what the selection's gains are measured in.
    pub fn wmse(&self) -> f64 {
        self.wsse / self.n.max(1) as f64
    }
}

/// Residual of sample `i` under `design`·`beta`.
#[inline]
pub fn residual_at(d: &Data, des: &Design, beta: &[f64], i: usize, x: &mut [f64]) -> f64 {
    let y = des.row(d, i, x);
    y - x.iter().zip(beta).map(|(a, b)| a * b).sum::<f64>()
}

pub fn score(
    d: &Data,
    des: Design,
    beta: Vec<f64>,
    effects: Vec<Effect>,
    split: &Split,
    bits: &[u32],
    n_regimes: usize,
) -> Scored {
    let mut x = vec![0.0; des.cols.len()];
    let acc = accumulate(split, bits, n_regimes, |_, i| residual_at(d, &des, &beta, i, &mut x));
    acc.into_scored(effects, des, beta)
}

/// Held-out squared residuals summed overall, per test unit and per regime (torque mode's and
/// trajectory mode's scores alike).
pub(crate) struct Sums {
    sse: f64,
    n: usize,
    unit_sse: Vec<f64>,
    unit_n: Vec<f64>,
    regime_sse: Vec<f64>,
    regime_n: Vec<f64>,
    resid: Vec<f64>,
    weight: std::sync::Arc<Vec<f64>>,
    wsse: f64,
}

impl Sums {
    /// Empty sums for `n` held-out samples in `units` test units and `n_regimes` regimes.
    pub(crate) fn new(n: usize, units: usize, n_regimes: usize) -> Sums {
        Sums {
            sse: 0.0,
            n,
            unit_sse: vec![0.0; units],
            unit_n: vec![0.0; units],
            regime_sse: vec![0.0; n_regimes],
            regime_n: vec![0.0; n_regimes],
            resid: Vec::new(),
            weight: Default::default(),
            wsse: 0.0,
        }
    }

    /// One held-out sample's squared residual `r2`, in test unit `unit`, in the regimes whose
    /// bits `regimes` has set (a unit or regime out of range counts overall only).
    pub(crate) fn add(&mut self, r2: f64, unit: usize, regimes: u32) {
        self.sse += r2;
        if let (Some(a), Some(b)) = (self.unit_sse.get_mut(unit), self.unit_n.get_mut(unit)) {
            *a += r2;
            *b += 1.0;
        }
        let mut b = regimes;
        while b != 0 {
            let j = b.trailing_zeros() as usize;
            if let (Some(a), Some(c)) = (self.regime_sse.get_mut(j), self.regime_n.get_mut(j)) {
                *a += r2;
                *c += 1.0;
            }
            b &= b - 1;
        }
    }

    pub(crate) fn into_scored(self, effects: Vec<Effect>, design: Design, beta: Vec<f64>) -> Scored {
        let Sums { sse, n, unit_sse, unit_n, regime_sse, regime_n, resid, weight, wsse } = self;
        let resid = std::sync::Arc::new(resid);
        let wsse = if weight.is_empty() { sse } else { wsse };
        Scored {
            effects,
            design,
            beta,
            sse,
            n,
            unit_sse,
            unit_n,
            regime_sse,
            regime_n,
            resid,
            chunked: false,
            weight,
            wsse,
            folds: Vec::new(),
        }
    }
}

/// One model's scores on the folds of a cross-fitted split ([`Split::cross_fitted`]), `first`
/// on the split itself and `rest` on its further folds in order, merged into one score of every
/// held-out sample: sums and counts added, the test units, residuals and weights one fold after
/// the other (each fold's samples in their own units, so [`compare`] reads them as before). The
/// effects, design and coefficients are the first fold's (what the report and `--emit-model`
/// show); each further fold's fit is kept in [`Scored::folds`] for its next round.
/// Without further folds `first` comes back unchanged.
pub fn merge(first: Scored, rest: Vec<Scored>) -> Scored {
    if rest.is_empty() {
        return first;
    }
    let mut m = first;
    let weighted = !m.weight.is_empty();
    let (mut resid, mut weight) = ((*m.resid).clone(), (*m.weight).clone());
    m.folds.clear();
    for s in rest {
        m.sse += s.sse;
        m.n += s.n;
        m.wsse += s.wsse;
        m.unit_sse.extend_from_slice(&s.unit_sse);
        m.unit_n.extend_from_slice(&s.unit_n);
        for (a, b) in m.regime_sse.iter_mut().zip(&s.regime_sse) {
            *a += b;
        }
        for (a, b) in m.regime_n.iter_mut().zip(&s.regime_n) {
            *a += b;
        }
        resid.extend_from_slice(&s.resid);
        weight.extend_from_slice(&s.weight);
        m.folds.push(FoldFit { effects: s.effects, design: s.design, beta: s.beta });
    }
    m.weight = if weighted && weight.len() == resid.len() { std::sync::Arc::new(weight) } else { Default::default() };
    m.resid = std::sync::Arc::new(resid);
    m
}

/// The training rows of a split and of each of its further folds: every `k`-th one, at most
/// `max` ([`super::candidates::thin_idx`]).
struct FoldIdx {
    first: Vec<u32>,
    rest: Vec<Vec<u32>>,
}

impl FoldIdx {
    fn new(split: &Split, max: usize) -> FoldIdx {
        let thin = |f: &Split| super::candidates::thin_idx(&f.train, max);
        FoldIdx { first: thin(split), rest: split.folds.iter().map(thin).collect() }
    }
}

/// A round of candidates ([`Round`]) on the split and one on each of its further folds, each on
/// top of the chosen effects as that fold fitted them.
struct Rounds<'a> {
    first: Round<'a>,
    rest: Vec<Round<'a>>,
}

impl<'a> Rounds<'a> {
    /// On top of `chosen`'s effects (none: `None`).
    fn new(d: &'a Data, base: &'a Base, chosen: Option<&Scored>, fit: &'a FoldIdx, split: &'a Split) -> Rounds<'a> {
        let (first, rest): (&[Effect], &[FoldFit]) = chosen.map_or((&[], &[]), |s| (&s.effects, &s.folds));
        Rounds {
            first: Round::new(d, base, first, &fit.first, split),
            rest: split
                .folds
                .iter()
                .zip(&fit.rest)
                .enumerate()
                .map(|(k, (f, fi))| Round::new(d, base, rest.get(k).map_or(&[], |r| &r.effects), fi, f))
                .collect(),
        }
    }

    /// `score(round, fold)` on every fold, merged ([`merge`]). `DIAG_FOLDS=1` prints each
    /// fold's held-out RMSE and coefficients (where folds disagree, the log does not pin them).
    fn score(&self, split: &Split, score: impl Fn(&Round<'a>, &Split) -> Scored) -> Scored {
        let first = score(&self.first, split);
        let rest: Vec<Scored> = self.rest.iter().zip(&split.folds).map(|(r, f)| score(r, f)).collect();
        if std::env::var_os("DIAG_FOLDS").is_some() {
            for s in std::iter::once(&first).chain(&rest) {
                eprintln!(
                    "[fold] {:?} rmse {:.5} n {} beta {:?}",
                    s.effects.iter().map(|e| e.kind()).collect::<Vec<_>>(),
                    s.rmse(),
                    s.n,
                    s.beta
                );
            }
        }
        merge(first, rest)
    }
}

/// Sums `resid(k, i)²` over the held-out samples (`k`-th held-out sample, log index `i`).
fn accumulate(split: &Split, bits: &[u32], n_regimes: usize, mut resid: impl FnMut(usize, usize) -> f64) -> Sums {
    let mut s = Sums::new(split.holdout.len(), split.n_units, n_regimes);
    s.weight = split.weight.clone();
    s.resid.reserve_exact(split.holdout.len());
    for (k, &i) in split.holdout.iter().enumerate() {
        let r = resid(k, i as usize);
        s.add(r * r, split.unit[k] as usize, bits[i as usize]);
        s.resid.push(r);
    }
    if let Some(w) = (s.weight.len() == s.resid.len()).then_some(&s.weight) {
        s.wsse = s.resid.iter().zip(w.iter()).map(|(r, w)| w * r * r).sum();
    }
    s
}

/// One round of candidates: the current design (the model's terms plus the effects chosen so
/// far) evaluated once on the fit rows and on the held-out rows. Every candidate of the round is
/// fitted by bordering the stored Gram with its own columns and scored from the stored rows, so
/// a round costs one evaluation of the design instead of one per candidate; the numbers are
/// those of [`fit_and_score`] (same products, same order).
pub struct Round<'a> {
    d: &'a Data,
    base: &'a Base,
    chosen: Vec<Effect>,
    fit: GridCtx<'a>,
    hold: GridCtx<'a>,
}

impl<'a> Round<'a> {
    pub fn new(d: &'a Data, base: &'a Base, chosen: &[Effect], fit_idx: &'a [u32], split: &'a Split) -> Round<'a> {
        let (fit, hold) = std::thread::scope(|s| {
            let h = s.spawn(|| GridCtx::rows(d, base, chosen, &split.holdout));
            let fit = GridCtx::new(d, base, chosen, fit_idx);
            (fit, h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
        });
        Round { d, base, chosen: chosen.to_vec(), fit, hold }
    }

    /// The current design with `beta` (its own columns only) scored on the held-out rows.
    pub fn score_current(&self, beta: Vec<f64>, split: &Split, bits: &[u32], n_regimes: usize) -> Scored {
        let none = Delta { replace: None, extra: Vec::new(), y_alt: None };
        let acc = self.accumulate(&none, &beta, split, bits, n_regimes);
        acc.into_scored(self.chosen.clone(), self.fit.des.clone(), beta)
    }

    /// The current design refitted (no new effect) and scored.
    pub fn refit(&self, split: &Split, bits: &[u32], n_regimes: usize) -> Scored {
        let mut g = self.fit.g.clone();
        eiv_correct(&mut g, &self.fit.des, self.d);
        let und = undetermined(&self.fit.des, self.d, &g);
        let (beta, _) = g.solve_held(&physical_signs(&self.fit.des), &holds(&self.fit.des, &und), &und);
        self.score_current(beta, split, bits, n_regimes)
    }

    /// The current design plus effect `e`, fitted on the fit rows and scored.
    pub fn fit_and_score(&self, e: Effect, split: &Split, bits: &[u32], n_regimes: usize) -> Scored {
        let mut effects = self.chosen.clone();
        effects.push(e);
        let des = Design::new(self.d, self.base, &effects);
        let mut g = self.fit.gram_with(&self.fit.delta(&e));
        eiv_correct(&mut g, &des, self.d);
        let und = undetermined(&des, self.d, &g);
        let (beta, _) = g.solve_held(&physical_signs(&des), &holds(&des, &und), &und);
        let acc = self.accumulate(&self.hold.delta(&e), &beta, split, bits, n_regimes);
        acc.into_scored(effects, des, beta)
    }

    /// Held-out sums of the current design changed by `delta`, with coefficients `beta` in
    /// design order; the residual adds the columns in that order, as [`residual_at`] does.
    fn accumulate(&self, delta: &Delta, beta: &[f64], split: &Split, bits: &[u32], n_regimes: usize) -> Sums {
        let (h, p) = (&self.hold, self.hold.p);
        let rep = delta.replace.as_ref().map(|(j, z)| (*j, z.as_slice()));
        accumulate(split, bits, n_regimes, |k, _| {
            let row = &h.x[k * p..(k + 1) * p];
            let y = delta.y_alt.as_ref().map_or(h.y[k], |ya| ya[k]);
            let mut fit = 0.0;
            for (j, (&xj, &bj)) in row.iter().zip(beta).enumerate() {
                let xj = match rep {
                    Some((jr, z)) if jr == j => z[k],
                    _ => xj,
                };
                fit += xj * bj;
            }
            for (z, &bz) in delta.extra.iter().zip(beta.get(p..).unwrap_or(&[])) {
                fit += z[k] * bz;
            }
            y - fit
        })
    }
}

/// Fits `effects` on the training indices `fit_idx` and scores it.
pub fn fit_and_score(
    d: &Data,
    base: &Base,
    effects: &[Effect],
    fit_idx: &[u32],
    split: &Split,
    bits: &[u32],
    n_regimes: usize,
) -> Scored {
    let des = Design::new(d, base, effects);
    let mut g = des.gram(d, fit_idx);
    eiv_correct(&mut g, &des, d);
    let und = undetermined(&des, d, &g);
    let (beta, _) = g.solve_held(&physical_signs(&des), &holds(&des, &und), &und);
    score(d, des, beta, effects.to_vec(), split, bits, n_regimes)
}

/// The terms no joint has negative ([`Col::nonneg`]: inertia, friction, a spring's stiffness,
/// the Coulomb level a Dahl state carries, a Stribeck level, a cable's pull, a load-dependent
/// μ): every fit keeps them ≥ 0, the model's own and an effect's alike, so a fit that would need
/// one negative is the best physical one instead, and scores what it scores.
pub fn physical_signs(des: &Design) -> Vec<bool> {
    des.cols.iter().map(|c| c.nonneg()).collect()
}

/// Where a bounded fit holds a term that would go negative: the inertia at the file's value
/// (a joint has one; rows that want none, such as a log whose torque is not what moved the
/// joint, do not say it is zero), every other term at 0.
pub fn physical_holds(des: &Design) -> Vec<f64> {
    use super::candidates::Col;
    des.cols
        .iter()
        .enumerate()
        .map(|(k, c)| match c {
            Col::Qdd => des.prior.get(k).copied().unwrap_or(0.0).max(0.0),
            _ => 0.0,
        })
        .collect()
}

/// The values held coefficients keep: the file's value for a term the rows do not determine
/// (`und`, never below 0 for a term no joint has negative), else [`physical_holds`].
pub fn holds(des: &Design, und: &[bool]) -> Vec<f64> {
    let signs = physical_signs(des);
    physical_holds(des)
        .into_iter()
        .enumerate()
        .map(|(k, h)| {
            if und.get(k).copied().unwrap_or(false) {
                let p = des.prior.get(k).copied().unwrap_or(0.0);
                if signs.get(k).copied().unwrap_or(false) {
                    p.max(0.0)
                } else {
                    p
                }
            } else {
                h
            }
        })
        .collect()
}

/// Whether a fit held the inertia at the file's value ([`physical_holds`]): its coefficient is
/// that value exactly, which a free least-squares solution (ridge included) never lands on.
pub fn inertia_held(s: &Scored) -> bool {
    use super::candidates::Col;
    s.design
        .cols
        .iter()
        .zip(&s.beta)
        .zip(&s.design.prior)
        .any(|((c, &b), &p)| matches!(c, Col::Qdd) && p > 0.0 && b == p)
}

/// Errors in variables: white noise of variance σᵢ² on the q̈ of the fitted rows adds
/// `Σ wᵢ·σᵢ²` ([`super::fit::Gram::eiv`], `wᵢ` the row's fit weight) to the q̈ column's Gram
/// diagonal and shrinks the fitted inertia by `var(q̈)/(var(q̈) + σ²)`. A shrunk
/// inertia predicts the same noisy q̈ slightly better, so without this a refit "beats" an exact
/// model on long logs with physically wrong values. The noise share is removed (corrected
/// least squares) unless that would take more than half the column's energy, where q̈ is
/// noise-dominated and the estimate is not trusted.
fn eiv_correct(g: &mut super::fit::Gram, des: &Design, d: &Data) {
    if d.qdd_noise_var <= 0.0 {
        return;
    }
    let Some(j) = des.cols.iter().position(|&c| c == super::candidates::Col::Qdd) else { return };
    let p = g.p;
    let noise = g.eiv;
    if let Some(gjj) = g.g.get_mut(j * p + j) {
        // noise-dominated: not corrected, the inertia is held instead ([`undetermined`])
        if noise < 0.5 * *gjj {
            *gjj -= noise;
        }
    }
}

/// The coefficients no fit may move: where q̈'s white noise holds half or more of the q̈
/// column's energy on these rows (`g`, after [`eiv_correct`], which leaves it uncorrected then),
/// the rows would shrink the inertia towards 0 by the noise share (regression dilution) and the
/// correction is not trusted, so the inertia stays at the file's value ([`physical_holds`])
/// when it has one.
/// The model's own terms the log does not excite ([`unexcited`]) are held at the file's value
/// too: a refit cannot move what the rows do not determine.
pub fn undetermined(des: &Design, d: &Data, g: &super::fit::Gram) -> Vec<bool> {
    let p = g.p;
    let structural = unexcited(des, d, g);
    des.cols
        .iter()
        .zip(&des.prior)
        .enumerate()
        .map(|(k, (c, &prior))| {
            let noisy_qdd = *c == super::candidates::Col::Qdd
                && prior > 0.0
                && d.qdd_noise_var > 0.0
                && g.g.get(k * p + k).is_some_and(|&gkk| g.eiv >= 0.5 * gkk);
            noisy_qdd || structural.get(k).copied().unwrap_or(false) || des.fixed.get(k).copied().unwrap_or(false)
        })
        .collect()
}

/// The model's own columns (not the offset; q̈ only when it is absent or exactly another
/// column's, its noise has its own rule in [`undetermined`]) whose variation over
/// the rows of `g` is, within three times its noise (or to 1e-6 of its energy), a combination
/// of the other model columns: a log with no motion (the friction columns are zero), one speed
/// or one direction (q̇ and sign(q̇) are the offset), or one angle (the weight's sine is the
/// offset, the spring's q too). Their coefficient is whatever the rows' noise says; the refit
/// keeps the file's value and the report lists them ([`unexcited_terms`]).
pub fn unexcited(des: &Design, d: &Data, g: &super::fit::Gram) -> Vec<bool> {
    use super::candidates::Col;
    let p = g.p;
    let base_end = des.spans.first().map_or(des.cols.len(), |s| s.0).min(p);
    // the Gram is filled in its upper triangle only
    let at = |r: usize, c: usize| g.g.get(r.min(c) * p + r.max(c)).copied().unwrap_or(0.0);
    let qd_rms = (d.qd.iter().map(|v| v * v).sum::<f64>() / d.qd.len().max(1) as f64).sqrt();
    (0..p)
        .map(|k| {
            let Some(&col) = des.cols.get(k) else { return false };
            if k >= base_end || col == Col::Const {
                return false;
            }
            let gkk = at(k, k);
            if !(gkk > 0.0) {
                return true;
            }
            let others: Vec<usize> = (0..base_end).filter(|&j| j != k && at(j, j) > 0.0).collect();
            // the column's noise, with a floor no joint's motion is below (a q̈ of 1e-6 rad/s²
            // RMS is the rounding of a constant-speed ramp, not an acceleration)
            let noise = match col {
                Col::Qdd => 1e-12,
                Col::Qd => d.qd_noise_var.max(1e-14),
                Col::QdAbsQd => (4.0 * qd_rms * qd_rms * d.qd_noise_var).max(1e-14),
                Col::SinSq(s) | Col::CosSq(s) => (s * s * d.q_noise_var).max(1e-16),
                Col::Q | Col::DeadZone { .. } => d.q_noise_var.max(1e-16),
                _ => 0.0,
            };
            residual_energy(&at, k, &others) <= (1e-6 * gkk).max(9.0 * g.n as f64 * noise)
        })
        .collect()
}

/// The standard error of column `k`'s coefficient in the least-squares fit whose Gram is `g`,
/// at residual variance `sigma2`: from the energy of the column that the other columns do not
/// explain ([`residual_energy`]); infinite for a column they explain whole. What tells a weight
/// apart from the offset over a short arc, or not.
pub fn coef_se(g: &super::fit::Gram, k: usize, sigma2: f64) -> f64 {
    let p = g.p;
    let at = |r: usize, c: usize| g.g.get(r.min(c) * p + r.max(c)).copied().unwrap_or(0.0);
    let others: Vec<usize> = (0..p).filter(|&j| j != k && at(j, j) > 0.0).collect();
    let e = residual_energy(&at, k, &others);
    if e > 0.0 {
        (sigma2 / e).sqrt()
    } else {
        f64::INFINITY
    }
}

/// `G_kk − G_kO·G_OO⁻¹·G_Ok`: the energy of column `k` the columns `others` do not explain.
/// `G_OO` gets a ridge of 1e-10 of its largest diagonal (columns collinear among themselves,
/// a constant sine beside the offset, then share the work instead of making it singular);
/// Gaussian elimination with partial pivoting.
fn residual_energy(at: &dyn Fn(usize, usize) -> f64, k: usize, others: &[usize]) -> f64 {
    let m = others.len();
    let w = m + 1;
    let scale = others.iter().map(|&j| at(j, j)).fold(0.0f64, f64::max).max(1e-300);
    let mut a: Vec<f64> = Vec::with_capacity(m * w);
    for (ri, &r) in others.iter().enumerate() {
        for (ci, &c) in others.iter().enumerate() {
            a.push(at(r, c) + if ri == ci { 1e-10 * scale } else { 0.0 });
        }
        a.push(at(r, k));
    }
    for col in 0..m {
        let piv = (col..m).max_by(|&i, &j| a[i * w + col].abs().total_cmp(&a[j * w + col].abs())).unwrap_or(col);
        for c in 0..w {
            a.swap(col * w + c, piv * w + c);
        }
        let d = a[col * w + col];
        if d == 0.0 {
            continue;
        }
        for r in col + 1..m {
            let f = a[r * w + col] / d;
            if f != 0.0 {
                for c in col..w {
                    a[r * w + c] -= f * a[col * w + c];
                }
            }
        }
    }
    let mut x = vec![0.0; m];
    for i in (0..m).rev() {
        let d = a[i * w + i];
        let rhs = a[i * w + m] - (i + 1..m).map(|c| a[i * w + c] * x[c]).sum::<f64>();
        x[i] = if d != 0.0 { rhs / d } else { 0.0 };
    }
    let explained: f64 = others.iter().zip(&x).map(|(&j, &xj)| at(j, k) * xj).sum();
    (at(k, k) - explained).max(0.0)
}

fn unit_t(diffs: &[f64]) -> (f64, f64) {
    let m = diffs.len() as f64;
    if m < 3.0 {
        return (0.0, 1.0);
    }
    let mean = diffs.iter().sum::<f64>() / m;
    let var = diffs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (m - 1.0);
    let t = if var > 0.0 {
        mean / (var / m).sqrt()
    } else if mean > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    (t, super::fit::student_t_sf(t, m - 1.0))
}

/// The share of `reference`'s plain (unweighted) held-out MSE that `cand` takes (negative when
/// it fits the held-out samples worse).
pub fn plain_gain(reference: &Scored, cand: &Scored) -> f64 {
    1.0 - cand.mse() / reference.mse().max(1e-300)
}

/// One-sided test that `cand` beats `reference` on held-out data: (t, p, relative MSE gain).
/// Two tests, Bonferroni-combined (p = 2·min): a unit-level t-test on the log ratio of the
/// units' mean squared residuals (scale-free, so a regime with a large residual cannot drown
/// the others), and one for a gain that sits in a few units (a cable spring that only acts at
/// one end of the range, friction at reversals): in torque mode the projection test
/// ([`projection_test`]), in trajectory mode (no residual series kept) a t-test on the units'
/// MSE differences.
pub fn compare(reference: &Scored, cand: &Scored) -> (f64, f64, f64) {
    let units = || {
        reference
            .unit_sse
            .iter()
            .zip(&cand.unit_sse)
            .zip(&reference.unit_n)
            .filter(|((a, b), &n)| n > 0.0 && **a > 0.0 && **b > 0.0)
            .map(|((a, b), n)| (*a, *b, *n))
    };
    let logs: Vec<f64> = units().map(|(a, b, _)| (a / b).ln()).collect();
    let diffs: Vec<f64> = units().map(|(a, b, n)| (a - b) / n).collect();
    // In the weighted MSE, as the fits are weighted: a gain at speed is not diluted by the
    // scatter of samples whose prediction is uncertain (without weights the plain MSE). A
    // candidate that raises the plain MSE has its plain loss as its gain: what is named must
    // not fit the held-out samples worse than its reference (an asymmetric level on the DFKI
    // hand-moved run took 4 % of the weighted MSE and raised the plain one by 14 %).
    let plain = plain_gain(reference, cand);
    let gain = if plain > 0.0 { 1.0 - cand.wmse() / reference.wmse().max(1e-300) } else { plain };
    // with the held-out residuals (both modes) the projection test takes the difference test's
    // place: both look for a gain in a few units, and the projection's variance is the noise's,
    // not the effect's
    let tests = match projection_test(reference, cand) {
        Some(t3) => vec![unit_t(&logs), t3],
        None => vec![unit_t(&logs), unit_t(&diffs)],
    };
    let k = tests.len() as f64;
    let (t, p) = tests.into_iter().fold((0.0, 1.0), |best, x| if x.1 < best.1 { x } else { best });
    (t, (k * p).min(1.0), gain)
}

/// Whether the candidate's correction δ = r − e (`r`, `e` the reference's and the candidate's
/// held-out residuals) lowers the squared residual: `D = Σ (r² − e²) = Σ δ·(r + e)`, whose
/// expectation is `−‖δ‖² ≤ 0` when the reference is right (also where δ carries a channel's
/// noise, as a delay's shift does) and `‖δ‖²` when the candidate is. Its variance comes from
/// the units (batch means, as the t-tests), each unit's share `4·(Σ e·δ)²` read from the
/// candidate's residual, which under the candidate is the noise and under the reference holds
/// δ too (larger, so the test errs on the cautious side); a t-distribution with the units'
/// effective count as degrees of freedom (Satterthwaite) keeps a gain in one or two units from
/// passing on their noise alone. Unlike a t-test over the units' differences, an effect that
/// acts in a few units (friction at reversals, a cable at one end of the range) is not
/// measured against its own unevenness from unit to unit, only against the noise. In torque
/// mode each sample's terms carry its weight ([`Split::weigh`]): where the residual's variance
/// differs from sample to sample (a friction sign uncertain near rest beside moves predicted to
/// the sensor noise), that is the sum a weighted least-squares test would use. Its variance
/// still comes from the units, so weights that are off cost power, not the test's size.
/// `None` without the residuals (a score that did not keep them) or without a correction.
fn projection_test(reference: &Scored, cand: &Scored) -> Option<(f64, f64)> {
    let (r, e) = (reference.resid.as_slice(), cand.resid.as_slice());
    if r.is_empty() || r.len() != e.len() || reference.unit_n.len() != cand.unit_n.len() {
        return None;
    }
    let chunk = if cand.chunked { projection_chunk(e, &reference.unit_n) } else { usize::MAX };
    // the weights, when the split has them for these samples: a sample whose prediction is
    // uncertain (a friction sign near rest, a q̈ estimate at a corner) counts for less
    let wt = reference.weight.as_slice();
    let wt = if wt.len() == r.len() { Some(wt) } else { None };
    // per chunk: Σ e·δ, and the correction's energy Σ δ² (what that sum's variance scales with)
    let (mut t_u, mut w, mut energy) = (Vec::with_capacity(reference.unit_n.len()), Vec::new(), Vec::new());
    // the held-out samples run unit by unit, in the order the counts give
    let mut k = 0usize;
    for &n in &reference.unit_n {
        let end = (k + n as usize).min(r.len());
        let (mut from, mut t_sum) = (k, 0.0);
        while from < end {
            let to = end.min(from.saturating_add(chunk));
            let (mut w_c, mut d2) = (0.0, 0.0);
            for (i, (&ri, &ei)) in r[from..to].iter().zip(&e[from..to]).enumerate() {
                // (a weight of 1 multiplies exactly: unweighted sums are as they were)
                let wi = wt.map_or(1.0, |w| w[from + i]);
                let d = ri - ei;
                t_sum += wi * d * (ri + ei);
                w_c += wi * ei * d;
                d2 += wi * d * d;
            }
            w.push(w_c);
            energy.push(d2);
            from = to;
        }
        t_u.push(t_sum);
        k = end;
    }
    if k != r.len() {
        return None;
    }
    let v: f64 = w.iter().map(|w| w * w).sum();
    let v2: f64 = w.iter().map(|w| w.powi(4)).sum();
    if !(v > 0.0 && v2 > 0.0) {
        return None;
    }
    let t: f64 = t_u.iter().sum::<f64>() / (2.0 * v.sqrt());
    // Satterthwaite's count: per unit from the squared sums themselves; over chunks from their
    // expected variances, which with a stationary noise go with the correction's energy (the
    // realised fourth powers of many short chunks scatter threefold and would cut the count so)
    let dof = if chunk == usize::MAX {
        v * v / v2
    } else {
        let (s1, s2) = energy.iter().fold((0.0, 0.0), |(a, b), x| (a + x, b + x * x));
        if s2 > 0.0 {
            s1 * s1 / s2
        } else {
            1.0
        }
    };
    Some((t, super::fit::student_t_sf(t, dof.max(1.0))))
}

/// The chunk length (samples) over which trajectory mode's projection test sums `e·δ` for its
/// variance. A simulated angle's correction sits in the few held-out units where the motion
/// is (a free decay's first blocks): read per unit, its variance had one or two degrees of
/// freedom and a correction at t = 15 (the held-out MSE down 74 %, to the noise floor) came out
/// at p = 0.016, not significant against 0.05/9 (unseen seed 9027, case 23, and eight such
/// development logs, each the true effect). Within a unit the candidate's residual is the
/// angle noise when the candidate is right, so chunks two correlation lengths long are as
/// good as independent: the length is twice `(1 + ρ)/(1 − ρ)` for the residual's lag-1
/// autocorrelation ρ within units (at least 2 samples; a residual that still holds a smooth
/// error, ρ near 1, keeps chunks of thousands of samples: whole units, as before).
fn projection_chunk(e: &[f64], unit_n: &[f64]) -> usize {
    let (mut num, mut den, mut k) = (0.0, 0.0, 0usize);
    for &n in unit_n {
        let end = (k + n as usize).min(e.len());
        let u = &e[k..end];
        let mean = u.iter().sum::<f64>() / u.len().max(1) as f64;
        for (i, &x) in u.iter().enumerate() {
            den += (x - mean) * (x - mean);
            if let Some(&y) = u.get(i + 1) {
                num += (x - mean) * (y - mean);
            }
        }
        k = end;
    }
    let rho = if den > 0.0 { (num / den).clamp(0.0, 0.999) } else { 0.999 };
    ((2.0 * (1.0 + rho) / (1.0 - rho)).ceil() as usize).max(2)
}

/// One candidate's outcome against its reference.
#[derive(Clone, Debug)]
pub struct Outcome {
    pub name: Vocab,
    pub scored: Scored,
    pub t: f64,
    pub p: f64,
    pub gain: f64,
    pub significant: bool,
    /// why the fitted term is not the physical effect its name says (then never significant)
    pub implausible: Option<&'static str>,
}

/// Checks the sign of the last effect's fitted amplitude against its physics. A term fitted
/// with the wrong sign lowers the residual because it mimics something else (a rising friction
/// curve is not a Stribeck dip, a cable that pushes is not a cable), so naming the effect and
/// emitting its section would mislead; it stays in the ranking, marked, but is never selected.
/// - `stribeck`: friction above the Coulomb level near rest, `level > 0`;
/// - `load_dependent_friction`: friction grows with the transmitted load, `mu > 0`;
/// - `cable_spring`: a cable pulls back beyond its engagement, `k > 0` (a progressive one: k3 ≥ 0
///   and k1 ≥ 0, not both 0);
/// - `dry_friction`: Coulomb friction opposes the motion, `c > 0`.
/// - `thermal_drift`: either sign (lubricant thins or a seal swells), but the friction it
///   scales, `1 + coefficient·(T − T_ref)` times the refitted shape, must stay positive over
///   the log: a drift that reverses the friction is a trend in something else.
///
/// Asymmetry, ripple, backlash and delay (shapes searched over positive values only) have no
/// sign rule.
pub fn implausible(s: &Scored, d: &Data) -> Option<&'static str> {
    let e = s.effects.last()?;
    let &(start, end) = s.design.spans.get(s.effects.len() - 1)?;
    let amp = s.beta.get(start).copied()?;
    // a progressive spring k3·x³ + k1·x: both stiffnesses (k1 < 0 is a spring that pushes the
    // joint away from its centre, a double well no harness makes); one of them may be 0 (a
    // linear spring is k3 = 0: it was ruled out as "cannot push" while its k3 sat at its bound,
    // development seed 9039, case 41, a progressive harness fitted as k1 = 10.8 N·m/rad at
    // p = 8e-16, called `parameters`), not both
    let coefs = s.beta.get(start..end).unwrap_or(&[]);
    let any_negative = coefs.iter().any(|&x| x < 0.0);
    let none_positive = !coefs.iter().any(|&x| x > 0.0);
    if let Effect::Thermal { src, .. } = *e {
        // T − T_ref at the ends of its range over the whole log
        let (lo, hi) = match src {
            ThermSrc::Temp { mean } => match &d.temp {
                Some(tp) => {
                    tp.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x - mean), b.max(x - mean)))
                }
                None => (0.0, 0.0),
            },
            ThermSrc::Time { tau, t0, mean } => {
                let at = |t: f64| 1.0 - (-(t - t0) / tau).exp() - mean;
                (at(d.t.first().copied().unwrap_or(t0)), at(d.t.last().copied().unwrap_or(t0)))
            }
        };
        if 1.0 + amp * lo <= 0.0 || 1.0 + amp * hi <= 0.0 {
            return Some("fitted thermal drift would reverse the friction within the log");
        }
        return None;
    }
    match e.kind() {
        Kind::Stribeck if amp <= 0.0 => {
            Some("fitted Stribeck level is not positive: friction rising towards rest is no Stribeck effect")
        }
        Kind::Load if amp <= 0.0 => Some("fitted load coefficient is not positive: friction falling with load"),
        // a pad presses either way (which side of the limb it sits on)
        Kind::Cable if matches!(e, Effect::Cable { side: 2, .. }) => None,
        Kind::Cable if any_negative || none_positive => {
            Some("fitted cable stiffness is not positive: a cable cannot push")
        }
        Kind::Dry if amp <= 0.0 => Some("fitted dry friction level is not positive: friction cannot drive the motion"),
        _ => None,
    }
}

/// Why the model's own terms at a fit's values are no joint (negative inertia, friction that
/// feeds energy in, a negative spring): such a fit lowers the residual by mimicking something
/// else and is never a verdict, whatever it scores (`None`: physical).
pub fn unphysical(s: &Scored) -> Option<&'static str> {
    use super::candidates::Col;
    for (c, b) in s.design.cols.iter().zip(&s.beta) {
        let why = match c {
            Col::Qdd if *b <= 0.0 => "the refit's inertia is not positive",
            Col::QdAbsQd | Col::Qd if *b < 0.0 => "the refit's viscous friction is negative (it would feed energy in)",
            Col::Sgn if *b < 0.0 => "the refit's Coulomb friction is negative (it would feed energy in)",
            Col::Q if *b < 0.0 => "the refit's spring stiffness is negative",
            _ => continue,
        };
        return Some(why);
    }
    None
}

/// A fit whose terms cancel each other: one column's contribution over the log more than ten
/// times the whole torque it is to explain, held in check by another (collinear columns: a
/// weight of hundreds of N·m against an offset, on a joint that sees a few). However well it
/// scores, such a fit is no joint, and a model written from it would be absurd.
pub fn cancelling(s: &Scored, d: &Data) -> Option<&'static str> {
    let p = s.design.cols.len();
    if p == 0 || s.beta.len() < p || d.n == 0 {
        return None;
    }
    let stride = (d.n / 4000).max(1);
    let mut x = vec![0.0; p];
    let (mut col_ss, mut y_ss, mut k) = (vec![0.0; p], 0.0, 0.0);
    for i in (0..d.n).step_by(stride) {
        let y = s.design.row(d, i, &mut x);
        y_ss += y * y;
        k += 1.0;
        for ((c, &xj), &bj) in col_ss.iter_mut().zip(&x).zip(&s.beta) {
            *c += (xj * bj) * (xj * bj);
        }
    }
    let y_rms = (y_ss / k).sqrt();
    col_ss
        .iter()
        .any(|&c| (c / k).sqrt() > 10.0 * y_rms.max(1e-12))
        .then_some("the fit's terms cancel each other: one is over ten times the torque it explains (collinear terms)")
}

/// How many values a candidate adds to the model's own (its shape parameters and amplitudes):
/// where two explanations fit equally well, the one with fewer is the verdict.
pub fn extra_params(e: &Effect) -> usize {
    match *e {
        Effect::Asymmetric | Effect::Load | Effect::Dry | Effect::Presliding { .. } => 1,
        // the lag and the channel that lags (u, tau or the state): two choices the fit makes
        Effect::Delay { .. } => 2,
        Effect::Backlash { offset, .. } => {
            if offset == 0.0 {
                1
            } else {
                2
            }
        }
        // a pad's amplitude, centre and reach
        Effect::Cable { side: 2, .. } => 3,
        Effect::Thermal { .. } | Effect::Cable { .. } => 2,
        Effect::Stribeck { exponent, .. } => {
            if exponent == 2.0 {
                2
            } else {
                3
            }
        }
        Effect::Ripple { harmonics, second, .. } => 1 + 2 * usize::from(harmonics) + if second > 0.0 { 3 } else { 0 },
    }
}

/// A held-out MSE at least this much above the noise floor's (in RMSE: ×1.5) that no
/// candidate explains is `unexplained`, not `none`.
pub const UNEXPLAINED: f64 = 1.5;

/// Everything the selection found.
#[derive(Clone, Debug)]
pub struct Selection {
    pub m0: Scored,
    pub refit: Outcome,
    /// every effect candidate (on top of the refit), unordered
    pub candidates: Vec<Outcome>,
    /// forward selection, in order
    pub chosen: Vec<Outcome>,
    pub alpha_each: f64,
    /// the noise floor the selection ended with: the one it was given, or lower where a
    /// significant fit's own residual showed part of it was structure ([`select`])
    pub floor: f64,
    /// the refit with every model term free, where the selection went on with the terms its
    /// folds disagree on held at the file's values ([`select`]): the report reads the
    /// disagreement from it
    pub free_refit: Option<Scored>,
}

/// The verdict among significant outcomes: the best held-out fit, unless one with fewer
/// values is not significantly worse than it (held-out differences within their standard error
/// go to the simpler explanation).
fn parsimonious(outcomes: &[Outcome], alpha_each: f64) -> Option<&Outcome> {
    let sig: Vec<&Outcome> = outcomes.iter().filter(|o| o.significant).collect();
    let best = *sig.iter().min_by(|a, b| a.scored.mse().total_cmp(&b.scored.mse()))?;
    let size = |o: &Outcome| o.scored.effects.last().map_or(0, extra_params);
    let ties = sig.into_iter().filter(|o| {
        let (_, p, g) = compare(&o.scored, &best.scored);
        !(p < alpha_each && g >= MIN_GAIN)
    });
    ties.min_by(|a, b| size(a).cmp(&size(b)).then(a.scored.mse().total_cmp(&b.scored.mse())))
}

/// A Stribeck curve or a pre-sliding (Dahl) state is a shape of dry friction: where the file
/// has none and `dry_friction` explains the log too, the shape is a further effect of the dry
/// friction and is named first only when it beats `dry_friction` as a second effect must beat
/// the first (significantly, and taking [`FURTHER_SHARE`] of what it leaves above the floor).
/// Otherwise the dry friction is the verdict, and the next round tries the shape on top of it.
/// Without the rule a Stribeck curve with no Coulomb level under it, its speed wide enough to
/// act as one, took the verdict from the bare level by 3 % of the held-out MSE on logs whose
/// file only lacked `c` (unseen seed 9053: two of two such logs; the truth's own model left
/// the same residual): friction that vanishes at speed where the file has no dry friction at
/// all is no Stribeck effect.
fn dry_first<'a>(best: &'a Outcome, candidates: &'a [Outcome], floor: f64, alpha_each: f64) -> &'a Outcome {
    let shape = matches!(best.scored.effects.last(), Some(Effect::Stribeck { .. } | Effect::Presliding { .. }));
    let dry = candidates.iter().find(|o| o.significant && matches!(o.scored.effects.last(), Some(Effect::Dry)));
    match dry {
        Some(dry) if shape => {
            let (_, p, gain) = compare(&dry.scored, &best.scored);
            if p < alpha_each && gain >= MIN_GAIN && takes_share(&dry.scored, &best.scored, floor) {
                best
            } else {
                dry
            }
        }
        _ => best,
    }
}

/// Searches and scores every applicable kind on top of the round's chosen effects, in parallel.
fn try_kinds(
    kinds: &[Kind],
    round: &Round<'_>,
    grid_idx: &[u32],
    split: &Split,
    bits: &[u32],
    n_regimes: usize,
    prune: bool,
) -> Vec<Scored> {
    let threads = super::par::cores(8);
    let (d, base, chosen) = (round.d, round.base, round.chosen.as_slice());
    // One grid context for the round, shared by every kind's search.
    let mut grid = GridCtx::new(d, base, chosen, grid_idx);
    grid.compose_dahl = true;
    // The held-out gain of a term can hardly exceed its training gain, so a candidate that does
    // not lower the thinned training RSS by half the minimum gain is not fitted in full.
    let cur_rss = grid.g.solve().1;
    let timing = std::env::var_os("DIAG_TIMING").is_some();
    let work = |k: Kind| -> Option<Scored> {
        let t0 = std::time::Instant::now();
        let Some(e) = search_in(k, &grid, base, chosen) else {
            if trace() && !chosen.is_empty() {
                eprintln!("[trace]   {} not applicable or not found", k.name());
            }
            return None;
        };
        let t1 = t0.elapsed().as_secs_f64();
        if prune && !chosen.is_empty() {
            let rss = grid.rss_effect(&e);
            if rss > (1.0 - 0.5 * MIN_GAIN) * cur_rss {
                if trace() {
                    eprintln!("[trace]   {} pruned: thinned training RSS {rss:.4e} of {cur_rss:.4e}", k.name());
                }
                return None;
            }
        }
        let s = round.fit_and_score(e, split, bits, n_regimes);
        if timing {
            eprintln!(
                "[select] {} after {}: search {t1:.3} s, fit and score {:.3} s",
                k.name(),
                chosen.len(),
                t0.elapsed().as_secs_f64() - t1
            );
        }
        Some(s)
    };
    // Kinds differ a lot in cost, the costliest searches first (measured on a 1 M-sample log:
    // ripple ≈ 0.1 s, delay ≈ 0.04 s, the others ≤ 0.03 s).
    let cost = |k: &Kind| match k {
        Kind::Ripple => 0,
        Kind::Delay => 1,
        Kind::Thermal | Kind::Cable | Kind::Stribeck => 2,
        _ => 3,
    };
    let out = super::par::costliest_first(kinds, threads, cost, |&k| work(k));
    out.into_iter().flatten().collect()
}

/// [`try_kinds`] on every fold, each kind's scores merged ([`merge`]); a kind some fold did
/// not find (or pruned) is dropped.
fn try_kinds_folds(
    kinds: &[Kind],
    rounds: &Rounds<'_>,
    grid: &FoldIdx,
    split: &Split,
    bits: &[u32],
    n_regimes: usize,
) -> Vec<Scored> {
    let mut first = try_kinds(kinds, &rounds.first, &grid.first, split, bits, n_regimes, true);
    let mut rest: Vec<Vec<Scored>> = rounds
        .rest
        .iter()
        .zip(&grid.rest)
        .zip(&split.folds)
        .map(|((r, g), f)| try_kinds(kinds, r, g, f, bits, n_regimes, true))
        .collect();
    let kind = |s: &Scored| s.effects.last().map(|e| e.kind());
    // The pruning is a shortcut, not a test: a kind that some fold fitted is fitted in every
    // fold and judged on all of their held-out samples. Pruned where one fold's reference was
    // poor, it was dropped from all three (seen t9051/0009: a Stribeck curve at SNR 4 under a
    // ripple, pruned after the first fold's ripple had left 80 times the others' training RSS).
    if !rest.is_empty() {
        let fitted: Vec<Kind> = kinds
            .iter()
            .copied()
            .filter(|k| first.iter().chain(rest.iter().flatten()).any(|s| kind(s) == Some(*k)))
            .collect();
        let missing = |have: &[Scored]| -> Vec<Kind> {
            fitted.iter().copied().filter(|k| !have.iter().any(|s| kind(s) == Some(*k))).collect()
        };
        let again = missing(&first);
        if !again.is_empty() {
            first.extend(try_kinds(&again, &rounds.first, &grid.first, split, bits, n_regimes, false));
        }
        for (((have, r), g), f) in rest.iter_mut().zip(&rounds.rest).zip(&grid.rest).zip(&split.folds) {
            let again = missing(have);
            if !again.is_empty() {
                have.extend(try_kinds(&again, r, g, f, bits, n_regimes, false));
            }
        }
    }
    first
        .into_iter()
        .filter_map(|s| {
            let others: Option<Vec<Scored>> =
                rest.iter().map(|v| v.iter().find(|o| kind(o) == kind(&s)).cloned()).collect();
            Some(merge(s, others?))
        })
        .collect()
}

/// The share of what the refit takes from the file's model that a delay on the file's own
/// values must take as well to be named instead of `parameters` ([`delay_in_disguise`]).
pub const DISGUISE_SHARE: f64 = 0.9;

/// A refit that is a delay in disguise. A state logged `d` late reads as the file's model with
/// each term taken at the logged state instead of the true one, expanded about it: the viscous
/// friction b·q̇ adds b·d to the inertia, an elastic joint's spring K·q adds K·d to the damping
/// (and K·d²/2 to the inertia); a torque logged late shifts the same terms the other way. The
/// refit absorbs the delay, a delay on top of it finds nothing, and the verdict was `parameters`
/// (unseen t9054/0002: a trunk joint's state 39 ms late, refitted as an inertia 61 % high). The
/// file's own values with one channel delayed and nothing refitted (one value: the lag) are
/// tried against it: named when they beat the file's model as any candidate must, take
/// [`DISGUISE_SHARE`] of what the refit takes, the refit does not beat them even at the
/// uncorrected [`ALPHA`], and they beat every refit of one value (one term freed, the others
/// the file's) as a candidate must: a delay is one value too. Where one freed term explains the
/// log as well, the log cannot tell the delay from that term's error, and `parameters` stands
/// with `delay` among its alternatives (unseen t9061/0079: an elastic joint's state 10.6 ms
/// late, its damping alone refitted 3× as well; t9059/0099: a damping 35 % low that a delay of 3
/// samples at 2 kHz fits as well).
#[allow(clippy::too_many_arguments)]
fn delay_in_disguise(
    d: &Data,
    base: &Base,
    m0: &Scored,
    refit: &Scored,
    grid: &FoldIdx,
    fit: &FoldIdx,
    split: &Split,
    bits: &[u32],
    n_regimes: usize,
    alpha_each: f64,
) -> Option<Outcome> {
    let mut file = base.clone();
    file.fixed.iter_mut().for_each(|f| *f = true);
    let des0 = Design::new(d, &file, &[]);
    let on_fold = |grid_idx: &[u32], fit_idx: &[u32], f: &Split| -> Option<Scored> {
        let mut x = vec![0.0; des0.cols.len()];
        // each grid row's prediction by the file's values, and its weight
        let rows: Vec<(usize, f64, f64)> = grid_idx
            .iter()
            .map(|&i| {
                let i = i as usize;
                des0.row(d, i, &mut x);
                let fit: f64 = x.iter().zip(&file.beta0).map(|(a, b)| a * b).sum();
                (i, fit, d.weigh_row(i, &mut [], 1.0))
            })
            .collect();
        let rss_of = |e: Effect| {
            let Effect::Delay { lag, channel } = e else { return f64::INFINITY };
            let mut des = des0.clone();
            des.lag = lag;
            des.channel = channel;
            rows.iter()
                .map(|&(i, fit, w)| {
                    let r = w * (des.target(d, i) - fit);
                    r * r
                })
                .sum::<f64>()
        };
        let e = super::candidates::best_delay(d, &rss_of)?;
        Some(fit_and_score(d, &file, &[e], fit_idx, f, bits, n_regimes))
    };
    let first = on_fold(&grid.first, &fit.first, split)?;
    let rest: Option<Vec<Scored>> =
        split.folds.iter().enumerate().map(|(k, f)| on_fold(grid.rest.get(k)?, fit.rest.get(k)?, f)).collect();
    let s = merge(first, rest?);
    // The simplest refits: one of the file's values freed, the others kept (each the refit of
    // a round on that model, on every fold).
    let single = (0..base.cols.len())
        .filter(|&k| !base.fixed.get(k).copied().unwrap_or(false))
        .filter_map(|k| {
            let mut one = file.clone();
            *one.fixed.get_mut(k)? = false;
            Some(Rounds::new(d, &one, None, fit, split).score(split, |r, f| r.refit(f, bits, n_regimes)))
        })
        .min_by(|a, b| a.mse().total_cmp(&b.mse()));
    let (_, p_single, g_single) = single.as_ref().map_or((0.0, 0.0, 1.0), |o| compare(o, &s));
    let (t, p, gain) = compare(m0, &s);
    let (_, p_refit, g_refit) = compare(&s, refit);
    let share = (m0.mse() - s.mse()) / (m0.mse() - refit.mse()).max(f64::MIN_POSITIVE);
    let implausible = implausible(&s, d).or_else(|| unphysical(&s));
    if trace() {
        eprintln!(
            "[trace]   delay on the file's values: {:?} rmse {:.5} (m0 {:.5}, refit {:.5}): p {p:.2e} gain {gain:.3}, \
             share of the refit's {share:.3}, refit against it p {p_refit:.2e} gain {g_refit:.3}, against the best \
             one-value refit p {p_single:.2e} gain {g_single:.3}{}",
            s.effects.first(),
            s.rmse(),
            m0.rmse(),
            refit.rmse(),
            implausible.map(|w| format!(" ({w})")).unwrap_or_default()
        );
    }
    let named = p < alpha_each
        && gain >= MIN_GAIN
        && share >= DISGUISE_SHARE
        && !(p_refit < ALPHA && g_refit >= MIN_GAIN)
        && p_single < alpha_each
        && g_single >= MIN_GAIN
        && implausible.is_none();
    named.then_some(Outcome { name: Vocab::Delay, scored: s, t, p, gain, significant: true, implausible: None })
}

/// `base` with the columns `cols` held at their file values in every fit ([`Base::fixed`]).
fn holding(base: &Base, cols: impl IntoIterator<Item = usize>) -> Base {
    let mut b = base.clone();
    for k in cols {
        if let Some(f) = b.fixed.get_mut(k) {
            *f = true;
        }
    }
    b
}

/// `DIAG_TRACE=1`: every round's outcomes on stderr (for reading why a verdict came out); trajectory
/// mode reads the same switch.
pub(crate) fn trace() -> bool {
    std::env::var_os("DIAG_TRACE").is_some()
}

fn trace_round(round: usize, outcomes: &[Outcome], reference_rmse: f64, floor: f64) {
    eprintln!("[trace] round {round}: reference {reference_rmse:.5}, floor {floor:.5}");
    for o in outcomes {
        eprintln!(
            "[trace]   {:24} rmse {:.5} p {:.2e} gain {:.3} significant {} {}",
            o.name,
            o.scored.rmse(),
            o.p,
            o.gain,
            o.significant,
            o.implausible.unwrap_or("")
        );
        if std::env::var_os("DIAG_TRACE_BETA").is_some() {
            let cols: Vec<String> =
                o.scored.design.cols.iter().zip(&o.scored.beta).map(|(c, b)| format!("{c:?}={b:.4}")).collect();
            eprintln!("[trace]     {}", cols.join(" "));
        }
    }
}

/// The whole torque-mode selection. `floor` = noise floor (N·m); selection stops there.
/// `reread` gives the floor a fit's own residual says ([`Selection::floor`]).
#[allow(clippy::too_many_arguments)] // the data, the model, the split and its tags, the floor twice
pub fn select(
    d: &Data,
    base: &Base,
    split: &Split,
    bits: &[u32],
    n_regimes: usize,
    floor: f64,
    reread: &(dyn Fn(&Scored) -> f64 + Sync),
    max_effects: usize,
) -> Selection {
    // Fits read at most 150 000 training rows, grids 20 000 (every k-th sample), per fold.
    // With cross-fitting folds ([`Split::cross_fitted`]) every score below is the merge of one
    // fit per fold, each scored on its own held-out blocks: every sample is tested once.
    let fit_idx = FoldIdx::new(split, FIT_ROWS);
    let grid_idx = FoldIdx::new(split, 20_000);
    let round0 = Rounds::new(d, base, None, &fit_idx, split);
    let m0 = round0.score(split, |r, f| r.score_current(base.beta0.clone(), f, bits, n_regimes));
    let m_tests = (Kind::ALL.len() + 1) as f64;
    let alpha_each = ALPHA / m_tests;
    let refit_s = round0.score(split, |r, f| r.refit(f, bits, n_regimes));
    // An inertia the refit had to hold (the rows want none or a negative one: the logged torque
    // is not what moved the joint) stays held in every candidate's fit: a candidate that lets
    // it fall to the rows' value would win by that, not by its own term (a "delay" of 15 ms
    // did so on the DFKI hand-moved run).
    let held_base;
    let (base, round0) = match base.cols.iter().position(|c| *c == Col::Qdd) {
        Some(j) if inertia_held(&refit_s) => {
            held_base = holding(base, [j]);
            drop(round0);
            (&held_base, Rounds::new(d, &held_base, None, &fit_idx, split))
        }
        _ => (base, round0),
    };
    // A refit that scores worse held out than the file's values, with folds that put some of
    // the model's terms far apart (`fold_unsettled`): the log does not pin those terms, the
    // emitted model keeps the file's values for them, and so do the refit and every candidate's
    // fit from here. Left free, each candidate rode on the refit's overfit: a trunk joint under
    // a human's torque, 63 % at rest, whose folds put the weight's cosine at −25.7, 4.7 and
    // 5.7 N·m, refitted to 2.7× the file's held-out RMSE, and its asymmetric friction (SNR 2.1)
    // then scored worse than the file's model too: `unexplained` (unseen t9076/0034).
    let unsettled =
        if refit_s.mse() > m0.mse() { super::fold_unsettled(d, &refit_s, split, floor) } else { Vec::new() };
    let settled_base;
    let mut free_refit = None;
    let (base, round0, refit_s) = if unsettled.is_empty() {
        (base, round0, refit_s)
    } else {
        settled_base = holding(base, unsettled.iter().map(|u| u.0));
        drop(round0);
        let round0 = Rounds::new(d, &settled_base, None, &fit_idx, split);
        let held = round0.score(split, |r, f| r.refit(f, bits, n_regimes));
        if trace() {
            eprintln!(
                "[trace] refit {:.5} over the file's {:.5}: {} term(s) the folds disagree on held at the file's values, refit {:.5}",
                refit_s.rmse(),
                m0.rmse(),
                unsettled.len(),
                held.rmse()
            );
        }
        free_refit = Some(refit_s);
        (&settled_base, round0, held)
    };
    let t0 = std::time::Instant::now();
    let first = try_kinds_folds(&Kind::ALL, &round0, &grid_idx, split, bits, n_regimes);
    drop(round0);
    if std::env::var_os("DIAG_TIMING").is_some() {
        eprintln!("[diagnose] first round of candidates: {:.3} s", t0.elapsed().as_secs_f64());
    }
    // The floor read from the file's residual counts as noise whatever varies faster than its
    // variogram's lags can tell from noise: a ripple of a short period crossed at speed, a
    // delay's error. A candidate that explains such a part shows it: the floor is read again
    // from the residual of every candidate that is significant but for the floor, and the
    // lowest counts. (A log the model explains has no such candidate, and a fit of its noise
    // leaves the same noise.)
    // (each fit's floor kept: the first effect chosen is read once)
    // (each read on its own, on the available cores: a read is a pass over every sample)
    let to_read: Vec<&Scored> = first
        .iter()
        .filter(|s| {
            let (_, p, g) = compare(&refit_s, s);
            let (_, p0, g0) = compare(&m0, s);
            p < alpha_each
                && g >= MIN_GAIN
                && p0 < ALPHA
                && g0 >= MIN_GAIN
                && implausible(s, d).or_else(|| unphysical(s)).or_else(|| cancelling(s, d)).is_none()
        })
        .collect();
    let read: Vec<(Vec<Effect>, f64)> =
        super::par::costliest_first(&to_read, super::par::cores(8), |_| 0, |s| (s.effects.clone(), reread(s)));
    let floor = read.iter().map(|r| r.1).fold(floor, f64::min);
    let floor_of = |s: &Scored| read.iter().find(|r| r.0 == s.effects).map_or_else(|| reread(s), |r| r.1);
    // Open while the residual is above the floor, or above the weighted floor in the weighted
    // MSE: a floor averaged over the samples is set by the uncertain ones (a friction sign in
    // the creeps can put it at 20 × the noise), and an effect where the model is sure sits
    // under it (development seed 9002, case 24: a Stribeck curve at SNR 4.7, held-out RMSE at
    // 0.53 × that floor).
    let wfloor = split.wfloor;
    let open = |r: &Scored, floor: f64| {
        r.rmse() > at_floor_factor(d) * floor || wfloor > 0.0 && r.wmse().sqrt() > at_floor_factor(d) * wfloor
    };
    let at_floor = !open(&m0, floor);
    // evidence no shrinkage or estimate error gives ([`ALPHA_AT_FLOOR`]). Those artefacts, and
    // a fitted shape a little off the true one, have a size of their own, so their p falls as
    // the held-out samples grow: cross-fitted, the bar is the one split's z scaled by
    // √(held out / the one split's held out), the same size of evidence (a harness fitted as a
    // one-sided cable left 6 % above the floor at its knee, and a ripple fitted to that took 10 %
    // at p = 6e-7 over three folds: `diagnose_pad.rs`)
    let z_floor = {
        let scale = (split.holdout_total() as f64 / split.holdout.len().max(1) as f64).sqrt();
        -crate::identify::robust::normal_quantile(ALPHA_AT_FLOOR / m_tests) * scale
    };
    let strong = |p: f64, gain: f64| {
        let beyond = if split.folds.is_empty() {
            p < ALPHA_AT_FLOOR / m_tests
        } else {
            -crate::identify::robust::normal_quantile(p) >= z_floor
        };
        beyond && gain >= AT_FLOOR_GAIN
    };
    // Below the floor (the file's residual under it: the floor over-read, most often where the
    // direction of motion is uncertain) strong evidence counts as at the floor, where it must
    // also show in the plain held-out MSE: a gain in the weighted MSE alone is the scatter of
    // the samples the model is surest of (a model-exact log, null seed 777 case 19: a ripple
    // took 9 % of the weighted MSE at p = 4e-14 and 0.5 % of the plain one).
    let strong_below =
        |p: f64, gain: f64, below: bool, plain: f64| strong(p, gain) && (!below || plain >= AT_FLOOR_GAIN);
    let below = m0.rmse() < floor;
    // A clear gain below the floor must show in the plain held-out MSE too, as strong evidence
    // must: a model-exact log (null seed 777 torque case 19, a Fourier motion on a 1.5 mrad
    // encoder with a Coulomb level of 11 N·m) had a ripple take 19 % of the weighted MSE and
    // 0.4 % of the plain one, once q̈'s local bias stopped being read from its noise (twenty-fifth
    // session) and the samples' weights moved.
    let clear_below = |gain: f64, below: bool, plain: f64| gain >= CLEAR_GAIN && (!below || plain >= AT_FLOOR_GAIN);
    let clear_at_floor =
        |p: f64, gain: f64, plain: f64| clear_below(gain, below, plain) || strong_below(p, gain, below, plain);
    let (t, p, gain) = compare(&m0, &refit_s);
    let refit_unphysical = unphysical(&refit_s).or_else(|| cancelling(&refit_s, d));
    let refit = Outcome {
        name: Vocab::Parameters,
        // The refit never overrides the floor: what it takes from a residual at the floor is
        // the structure of the q̇/q̈ estimates' errors, absorbed by collinear terms.
        significant: !at_floor && p < alpha_each && gain >= MIN_GAIN && refit_unphysical.is_none(),
        implausible: refit_unphysical,
        scored: refit_s,
        t,
        p,
        gain,
    };
    let outcome = |reference: &Scored, s: Scored| {
        let (t, p, gain) = compare(reference, &s);
        let name = s.effects.last().map(|e| e.kind().effect()).unwrap_or(Vocab::Parameters);
        let implausible = implausible(&s, d).or_else(|| unphysical(&s)).or_else(|| cancelling(&s, d));
        let significant = (!at_floor || clear_at_floor(p, gain, plain_gain(reference, &s)))
            && p < alpha_each
            && gain >= MIN_GAIN
            && implausible.is_none();
        Outcome { name, scored: s, t, p, gain, significant, implausible }
    };
    // An effect must beat the refit (what retuning cannot explain) and the file's model too (a
    // refit can overfit a short or chattering log and score worse than the file's values).
    let candidates: Vec<Outcome> = first
        .into_iter()
        .map(|s| {
            let mut o = outcome(&refit.scored, s);
            let (_, p0, g0) = compare(&m0, &o.scored);
            // a confirmation, not a second search over the candidates: no Bonferroni here
            o.significant &= p0 < ALPHA && g0 >= MIN_GAIN;
            o
        })
        .collect();

    if trace() {
        eprintln!(
            "[trace] m0 {:.5} refit {:.5} (p {:.2e}, gain {:.3}, significant {}); weighted: m0 {:.5} refit {:.5} floor {:.5}",
            m0.rmse(),
            refit.scored.rmse(),
            refit.p,
            refit.gain,
            refit.significant,
            m0.wmse().sqrt(),
            refit.scored.wmse().sqrt(),
            wfloor
        );
        trace_round(1, std::slice::from_ref(&refit), m0.rmse(), floor);
        trace_round(1, &candidates, refit.scored.rmse(), floor);
    }
    let mut chosen: Vec<Outcome> = Vec::new();
    let best_first =
        parsimonious(&candidates, alpha_each).map(|b| dry_first(b, &candidates, floor, alpha_each)).cloned();
    // Look-ahead for two effects that mask each other: when no single effect is significant
    // but several lower the held-out MSE, the best pairs of the three strongest are tried. A
    // pair is kept only if it is significant against the refit and against each partner alone
    // (Bonferroni over the pairs too), so one strong term cannot carry a passenger.
    let best_first = match best_first {
        Some(b) => Some(b),
        None if !at_floor && max_effects >= 2 => {
            let mut strong: Vec<&Outcome> =
                candidates.iter().filter(|o| o.gain >= MIN_GAIN && o.implausible.is_none()).collect();
            strong.sort_by(|a, b| a.scored.mse().total_cmp(&b.scored.mse()));
            strong.truncate(3);
            let pair_alpha = ALPHA / (m_tests + 3.0);
            let mut best_pair: Option<(Outcome, Outcome)> = None;
            for (i, a) in strong.iter().enumerate() {
                for b in strong.iter().skip(i + 1) {
                    let Some(kb) = b.scored.effects.last().map(|e| e.kind()) else { continue };
                    // the pair on each fold, on top of `a` as that fold fitted it
                    let on_fold = |ea: Option<&Effect>, grid: &[u32], fit: &[u32], f: &Split| {
                        let &ea = ea?;
                        let eb = search(kb, d, base, &[ea], grid)?;
                        Some(fit_and_score(d, base, &[ea, eb], fit, f, bits, n_regimes))
                    };
                    let Some(first) = on_fold(a.scored.effects.last(), &grid_idx.first, &fit_idx.first, split) else {
                        continue;
                    };
                    let rest: Option<Vec<Scored>> = split
                        .folds
                        .iter()
                        .enumerate()
                        .map(|(k, f)| {
                            let ea = a.scored.folds.get(k).and_then(|r| r.effects.last());
                            on_fold(ea, grid_idx.rest.get(k)?, fit_idx.rest.get(k)?, f)
                        })
                        .collect();
                    let Some(rest) = rest else { continue };
                    let pair = merge(first, rest);
                    let tests = [
                        compare(&refit.scored, &pair),
                        compare(&m0, &pair),
                        compare(&a.scored, &pair),
                        compare(&b.scored, &pair),
                    ];
                    if implausible(&pair, d).or_else(|| unphysical(&pair)).or_else(|| cancelling(&pair, d)).is_none()
                        && tests.iter().all(|&(_, p, g)| p < pair_alpha && g >= MIN_GAIN)
                        && best_pair.as_ref().map(|(_, bp)| pair.mse() < bp.scored.mse()).unwrap_or(true)
                    {
                        let (t, p, gain) = compare(&a.scored, &pair);
                        let second = Outcome {
                            name: kb.effect(),
                            scored: pair,
                            t,
                            p,
                            gain,
                            significant: true,
                            implausible: None,
                        };
                        let mut first = (*a).clone();
                        first.significant = true;
                        best_pair = Some((first, second));
                    }
                }
            }
            match best_pair {
                Some((first, second)) => {
                    chosen.push(first);
                    Some(second)
                }
                None => None,
            }
        }
        None => None,
    };
    let mut floor = floor;
    if let Some(b) = best_first {
        chosen.push(b);
        while chosen.len() < max_effects {
            let Some(cur) = chosen.last() else { break };
            // what the chosen effects explain is no noise either: the floor after them
            floor = floor.min(floor_of(&cur.scored));
            // At (or below) the floor only evidence [`ALPHA_AT_FLOOR`] asks for adds an effect;
            // below it that evidence must also show in the plain held-out MSE (the `strong`
            // test of the round below). Stopping there instead missed the Stribeck curve under a
            // ripple in two unseen pairs (t9055/0034, t9054/0098).
            let strong_only = !open(&cur.scored, floor);
            let effects = cur.scored.effects.clone();
            let kinds: Vec<Kind> =
                Kind::ALL.iter().copied().filter(|k| !effects.iter().any(|e| e.kind() == *k)).collect();
            let t1 = std::time::Instant::now();
            let round = Rounds::new(d, base, Some(&cur.scored), &fit_idx, split);
            let t_round = t1.elapsed().as_secs_f64();
            let next = try_kinds_folds(&kinds, &round, &grid_idx, split, bits, n_regimes);
            if std::env::var_os("DIAG_TIMING").is_some() {
                eprintln!(
                    "[select] round {}: design {t_round:.3} s, candidates {:.3} s",
                    chosen.len() + 1,
                    t1.elapsed().as_secs_f64() - t_round
                );
            }
            let cur_s = cur.scored.clone();
            // A further effect must also take a real share of what is left above the floor
            // (a quarter of the excess MSE), not only shave a significant sliver off noise.
            let next: Vec<Outcome> = next
                .into_iter()
                .map(|s| outcome(&cur_s, s))
                .map(|mut o| {
                    let strong = strong_below(o.p, o.gain, cur_s.rmse() < floor, plain_gain(&cur_s, &o.scored));
                    // the share rule is for slivers at weak p; evidence as strong as the floor
                    // asks for counts without it (t9033/0018: a Stribeck curve after a ripple,
                    // p = 4e-7, 8 % of the held-out MSE, a fifth of the excess; on the traces of
                    // 480 development and 1 500 model-exact torque logs it was the only
                    // candidate of a further round with such evidence and less share)
                    // At the floor a further effect that takes [`CLEAR_GAIN`] of the held-out MSE
                    // counts as it does in the first round: the floor was over-read (seen
                    // t9051/0073: a Stribeck curve under a ripple, 15.7 % at p = 2e-10, the ripple
                    // at 1.04 × the floor; t9053/0074: friction with the load under a ripple,
                    // 18 % at p = 4e-6, the ripple under the floor).
                    let clear = if strong_only {
                        clear_below(o.gain, cur_s.rmse() < floor, plain_gain(&cur_s, &o.scored))
                    } else {
                        takes_share(&cur_s, &o.scored, floor)
                    };
                    o.significant &= strong || clear;
                    o
                })
                .collect();
            if trace() {
                trace_round(chosen.len() + 1, &next, cur_s.rmse(), floor);
            }
            let best = parsimonious(&next, alpha_each).cloned();
            match best {
                Some(o) => chosen.push(o),
                None => break,
            }
        }
    }
    if chosen.is_empty() && refit.significant {
        if let Some(o) =
            delay_in_disguise(d, base, &m0, &refit.scored, &grid_idx, &fit_idx, split, bits, n_regimes, alpha_each)
        {
            chosen.push(o);
        }
    }
    Selection { m0, refit, candidates, chosen, alpha_each, floor, free_refit }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use crate::diagnose::candidates::{Col, ThermSrc};
    use rand::{Rng, SeedableRng};

    /// A synthetic torque-mode data set with every column a candidate can read.
    fn data(n: usize) -> (Data, Base) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let q: Vec<f64> = t.iter().map(|&t| 1.0 + 0.8 * (0.9 * t).sin() + 0.05 * (7.0 * t).sin()).collect();
        let qd: Vec<f64> = t
            .iter()
            .map(|&t| 0.72 * (0.9 * t).cos() + 0.35 * (7.0 * t).cos() + rng.random_range(-0.01..0.01))
            .collect();
        let qdd: Vec<f64> = t.iter().map(|&t| -0.648 * (0.9 * t).sin() - 2.45 * (7.0 * t).sin()).collect();
        let u: Vec<f64> = (0..n).map(|i| 2.0 * qd[i] + 0.3 * (3.0 * t[i]).sin()).collect();
        let band = 0.01;
        let sgn: Vec<f64> = qd.iter().map(|&v| super::super::sgn_band(v, band)).collect();
        let ws = 0.8;
        let y: Vec<f64> = (0..n)
            .map(|i| {
                0.4 * qdd[i]
                    + 2.0 * qd[i]
                    + sgn[i]
                    + 2.5 * (ws * q[i]).sin()
                    + 0.3 * (q[i] * 60.0).sin()
                    + rng.random_range(-0.1..0.1)
            })
            .collect();
        let d = Data {
            n,
            wsin: q.iter().map(|&q| (ws * q).sin()).collect(),
            wcos: q.iter().map(|&q| (ws * q).cos()).collect(),
            temp: Some((0..n).map(|i| 25.0 + 10.0 * i as f64 / n as f64).collect()),
            t,
            q,
            qd,
            qdd,
            tau: (0..n).map(|i| 0.3 * (i as f64 * 0.01).sin()).collect(),
            u,
            y,
            dt: 1e-3,
            band,
            sgn,
            q0: 0.9,
            ws,
            load: (0..n).map(|i| 1.0 + (i % 7) as f64).collect(),
            qdd_noise_var: 0.01,
            qdd_nv: Vec::new(),
            q_noise_var: 1e-8,
            qd_noise_var: 1e-4,
            sw: Vec::new(),
        };
        let cols = vec![Col::Qdd, Col::QdAbsQd, Col::Qd, Col::Sgn, Col::SinSq(ws), Col::CosSq(ws), Col::Q, Col::Const];
        let beta0 = vec![0.4, 0.1, 2.0, 1.0, 2.5, 0.0, 0.5, -0.45];
        let fixed = vec![false; cols.len()];
        (d, Base { cols, beta0, fixed })
    }

    /// The cross-fitting folds: every sample outside the first and last block, and not left
    /// out, is held out in exactly one fold; no fold trains on a sample it holds out or within
    /// its guard; the weights of all folds share one scale.
    #[test]
    fn cross_fitted_folds_hold_out_every_inner_sample_once_and_never_train_on_it() {
        let n = 4_000;
        let out: Vec<bool> = (0..n).map(|i| i % 97 == 5).collect();
        let mut split = make_split_units(n, 20).cross_fitted(n, 20);
        split.leave_out(&out);
        split.weigh(|i| 1.0 + (i % 7) as f64);
        let len = n / split.blocks;
        let mut held = vec![0usize; n];
        for f in split.all_folds() {
            let mut own = vec![false; n];
            for &i in &f.holdout {
                held[i as usize] += 1;
                own[i as usize] = true;
            }
            for &i in &f.train {
                let i = i as usize;
                let near = (i.saturating_sub(f.guard)..(i + f.guard + 1).min(n)).any(|k| own[k]);
                assert!(!near && !out[i], "sample {i} trained on next to its own held-out block");
            }
            assert_eq!(f.unit.len(), f.holdout.len());
            assert_eq!(f.weight.len(), f.holdout.len());
        }
        for i in 0..n {
            let edge = i < len || i >= n - len;
            let want = usize::from(!edge && !out[i]);
            assert_eq!(held[i], want, "sample {i} held out {} times", held[i]);
        }
        let all: Vec<f64> = split.all_folds().iter().flat_map(|f| f.weight.iter().copied()).collect();
        let mean = all.iter().sum::<f64>() / all.len() as f64;
        assert!((mean - 1.0).abs() < 1e-12, "weights' mean over all folds {mean}");
        assert_eq!(split.holdout_all().len(), held.iter().sum::<usize>());
    }

    /// A merged score is the one score over the folds' held-out samples: sums added, units and
    /// residuals in fold order; one score merges to itself.
    #[test]
    fn merged_folds_add_up_and_one_score_is_itself() {
        let (d, base) = data(3_000);
        let split = make_split_units(d.n, 20).cross_fitted(d.n, 20);
        let fit = FoldIdx::new(&split, FIT_ROWS);
        let rounds = Rounds::new(&d, &base, None, &fit, &split);
        let m = rounds.score(&split, |r, f| r.refit(f, &[0; 3_000], 1));
        let parts: Vec<Scored> = split
            .all_folds()
            .iter()
            .map(|f| fit_and_score(&d, &base, &[], &thin_idx(&f.train), f, &[0; 3_000], 1))
            .collect();
        let sse: f64 = parts.iter().map(|p| p.sse).sum();
        assert!((m.sse - sse).abs() <= 1e-9 * sse, "{} vs {sse}", m.sse);
        assert_eq!(m.n, split.holdout_total());
        assert_eq!(m.unit_sse.len(), parts.iter().map(|p| p.unit_sse.len()).sum::<usize>());
        assert_eq!(m.resid.len(), m.n);
        assert_eq!(m.folds.len(), 2);
        let one = parts[0].clone();
        let same = merge(one.clone(), Vec::new());
        assert_eq!((same.sse, same.n, same.unit_sse.len()), (one.sse, one.n, one.unit_sse.len()));
    }

    fn thin_idx(train: &[u32]) -> Vec<u32> {
        crate::diagnose::candidates::thin_idx(train, FIT_ROWS)
    }

    /// A round's bordered fits and cached scoring give the numbers of a full rebuild, to the
    /// bit, for every kind of candidate (extra columns, a replaced column, a shifted target),
    /// on top of nothing and on top of a chosen effect.
    #[test]
    fn round_equals_rebuilding_the_design() {
        let (d, base) = data(20_000);
        let split = make_split(d.n);
        let bits = vec![0b101u32; d.n];
        let fit_idx = crate::diagnose::candidates::thin_idx(&split.train, 8000);
        let candidates = [
            Effect::Stribeck { speed: 0.05, exponent: 2.0 },
            Effect::Stribeck { speed: 0.05, exponent: 0.7 },
            Effect::Asymmetric,
            Effect::Load,
            Effect::Thermal { a: 0.1, b: 2.0, c: 1.0, src: ThermSrc::Temp { mean: 30.0 } },
            Effect::Thermal { a: 0.1, b: 2.0, c: 1.0, src: ThermSrc::Time { tau: 3.0, t0: 0.0, mean: 0.5 } },
            Effect::Ripple { period: 0.105, harmonics: 1, second: 0.0 },
            Effect::Ripple { period: 0.105, harmonics: 2, second: 0.0 },
            Effect::Cable { engage: 1.3, width: 0.01, side: 1 },
            Effect::Cable { engage: 0.7, width: 0.01, side: -1 },
            Effect::Cable { engage: 1.0, width: 0.01, side: 0 },
            Effect::Cable { engage: 1.0, width: 0.2, side: 2 },
            Effect::Backlash { width: 0.02, offset: 0.01 },
            Effect::Delay { lag: 3.0, channel: crate::diagnose::candidates::Channel::U },
            Effect::Delay { lag: -4.0, channel: crate::diagnose::candidates::Channel::Tau },
            Effect::Delay { lag: 2.0, channel: crate::diagnose::candidates::Channel::State },
            Effect::Dry,
            Effect::Presliding { kappa: 900.0, raw: false },
        ];
        for chosen in [
            vec![],
            vec![Effect::Ripple { period: 0.105, harmonics: 1, second: 0.0 }],
            vec![Effect::Backlash { width: 0.02, offset: 0.0 }],
        ] {
            let round = Round::new(&d, &base, &chosen, &fit_idx, &split);
            let refit = round.refit(&split, &bits, 3);
            let full = fit_and_score(&d, &base, &chosen, &fit_idx, &split, &bits, 3);
            assert_eq!(refit.beta, full.beta, "refit on {chosen:?}");
            assert_eq!(refit.sse, full.sse);
            for e in candidates {
                if chosen.iter().any(|c| c.kind() == e.kind()) {
                    continue;
                }
                let mut all = chosen.clone();
                all.push(e);
                let r = round.fit_and_score(e, &split, &bits, 3);
                let f = fit_and_score(&d, &base, &all, &fit_idx, &split, &bits, 3);
                assert_eq!(r.design.cols, f.design.cols, "{e:?} on {chosen:?}");
                assert_eq!(r.beta, f.beta, "{e:?} on {chosen:?}");
                assert_eq!(
                    (r.sse, &r.unit_sse, &r.regime_sse),
                    (f.sse, &f.unit_sse, &f.regime_sse),
                    "{e:?} on {chosen:?}"
                );
            }
        }
    }

    /// A grid search's Dahl state from the compressed travel equals the state sample by sample
    /// (up to rounding) on every row it reads.
    #[test]
    fn a_ripple_of_a_second_independent_period_is_found_and_none_is_invented() {
        let (mut d, base) = data(20_000);
        let idx: Vec<u32> = (0..20_000u32).step_by(3).collect();
        // the data's own ripple: period 2π/60 (0.1047 rad), one harmonic
        let Some(Effect::Ripple { period, second, .. }) = search(Kind::Ripple, &d, &base, &[], &idx) else {
            panic!("no ripple found")
        };
        assert!((period - std::f64::consts::TAU / 60.0).abs() < 1e-3, "{period}");
        assert_eq!(second, 0.0, "one period in the data, one found");
        // plus a cogging-like ripple of 0.037 rad, not a harmonic of the first
        for i in 0..d.n {
            d.y[i] += 0.2 * (std::f64::consts::TAU * d.q[i] / 0.037 + 1.0).sin();
        }
        let Some(Effect::Ripple { period, second, .. }) = search(Kind::Ripple, &d, &base, &[], &idx) else {
            panic!("no ripple found")
        };
        let (a, b) = if period < second { (period, second) } else { (second, period) };
        assert!((a - 0.037).abs() < 0.037 * 0.01, "{period} {second}");
        assert!((b - std::f64::consts::TAU / 60.0).abs() < 1e-3, "{period} {second}");
    }

    /// A progressive spring whose cubic stiffness the data put at its bound (0) is a linear
    /// spring, physical; one that pushes away from its centre is not (development seed 9039,
    /// case 41 was `parameters` while its spring sat at k3 = 0).
    #[test]
    fn a_progressive_spring_at_k3_zero_is_a_spring_and_a_pushing_one_is_not() {
        let (mut d, mut base) = data(20_000);
        // the file's model without its own spring and weight (over this range the weight's
        // sine and cosine hold a linear term of q: the spring would not be determined)
        for drop in [Col::Q, Col::SinSq(0.8), Col::CosSq(0.8)] {
            let k = base.cols.iter().position(|c| *c == drop).unwrap();
            base.cols.remove(k);
            base.beta0.remove(k);
            base.fixed.remove(k);
        }
        let y0: Vec<f64> = d.y.iter().zip(&d.q).map(|(y, q)| y - 2.5 * (0.8 * q).sin()).collect();
        let split = make_split(d.n);
        let bits = vec![0u32; d.n];
        let fit_idx = crate::diagnose::candidates::thin_idx(&split.train, 8000);
        let e = Effect::Cable { engage: 1.0, width: 0.01, side: 0 };
        let coefs = |s: &Scored| {
            let (a, b) = s.design.spans[0];
            s.beta[a..b].to_vec()
        };
        // softening: the cubic wants a negative stiffness and is held at 0, the linear one pulls
        for i in 0..d.n {
            let x = d.q[i] - 1.0;
            d.y[i] = y0[i] + 3.0 * x - 0.8 * x * x * x;
        }
        let s = fit_and_score(&d, &base, &[e], &fit_idx, &split, &bits, 1);
        let c = coefs(&s);
        assert!(c.iter().all(|&v| v >= 0.0) && c.iter().any(|&v| v > 1.0), "{c:?}");
        assert_eq!(implausible(&s, &d), None, "{c:?}");
        // pushing away from the centre
        for i in 0..d.n {
            let x = d.q[i] - 1.0;
            d.y[i] = y0[i] - 3.0 * x;
        }
        let s = fit_and_score(&d, &base, &[e], &fit_idx, &split, &bits, 1);
        assert!(implausible(&s, &d).is_some(), "{:?}", coefs(&s));
    }

    #[test]
    fn composed_dahl_steps_equal_the_state_on_the_rows() {
        let (d, base) = data(20_000);
        let idx: Vec<u32> = (0..20_000u32).step_by(7).collect();
        let mut grid = GridCtx::new(&d, &base, &[], &idx);
        let exact = GridCtx::new(&d, &base, &[], &idx);
        grid.compose_dahl = true;
        for kappa in [30.0, 900.0, 2e4] {
            let e = Effect::Presliding { kappa, raw: false };
            let (a, b) = (grid.delta(&e).replace.unwrap().1, exact.delta(&e).replace.unwrap().1);
            assert_eq!(a.len(), b.len());
            let worst = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-12, "κ {kappa}: worst difference {worst}");
        }
    }

    /// Held-out residuals as trajectory mode scores them: `units` units of `len` samples.
    fn held(resid: Vec<f64>, units: usize, len: usize, chunked: bool) -> Scored {
        let mut s = Sums::new(resid.len(), units, 0);
        for (k, &r) in resid.iter().enumerate() {
            s.add(r * r, k / len, 0);
            s.resid.push(r);
        }
        let mut sc = s.into_scored(vec![], Design::empty(), vec![]);
        sc.chunked = chunked;
        sc
    }

    /// White (ρ = 0) or AR(1) noise of unit variance.
    fn ar_noise(rng: &mut impl Rng, n: usize, rho: f64) -> Vec<f64> {
        let mut x = 0.0;
        (0..n)
            .map(|_| {
                let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
                let g = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                x = rho * x + (1.0 - rho * rho).sqrt() * g;
                x
            })
            .collect()
    }

    /// Errors in variables remove the q̈ noise of the rows a fit uses, at their weights, not the
    /// log's average: a log whose q̈ is noisy where it is not fitted (or weighs little) has a
    /// fit whose own rows carry a small part of it. Here the fitted (even) rows carry noise of
    /// variance 0.09 and the others 1.44: removing the log's average (0.765 per row) from a
    /// column of energy 2.09 per row inflated the inertia by half (1.51×).
    #[test]
    fn errors_in_variables_remove_the_noise_of_the_fitted_rows_only() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let n = 8_000;
        let (j, mut d) = (0.7, data(n).0);
        let sd: Vec<f64> = (0..n).map(|i| if i % 2 == 0 { 0.3 } else { 1.2 }).collect();
        let e = ar_noise(&mut rng, n, 0.0);
        let w = ar_noise(&mut rng, n, 0.0);
        let truth: Vec<f64> = (0..n).map(|i| 2.0 * (i as f64 * 0.0031).sin()).collect();
        d.qdd = (0..n).map(|i| truth[i] + sd[i] * e[i]).collect();
        d.y = (0..n).map(|i| j * truth[i] + 0.05 * w[i]).collect();
        d.qdd_nv = sd.iter().map(|s| s * s).collect();
        d.qdd_noise_var = d.qdd_nv.iter().sum::<f64>() / n as f64;
        let base = Base { cols: vec![Col::Qdd], beta0: vec![0.5], fixed: vec![false] };
        let des = Design::new(&d, &base, &[]);
        let fit: Vec<u32> = (0..n as u32).step_by(2).collect();
        let mut g = des.gram(&d, &fit);
        eiv_correct(&mut g, &des, &d);
        let (beta, _) = g.solve();
        assert!((beta[0] / j - 1.0).abs() < 0.03, "inertia {} against {j}", beta[0]);
        // and with fit weights, each row's noise counts at its weight
        d.sw = (0..n).map(|i| if i % 4 == 0 { 1.3 } else { 0.6 }).collect();
        let mut g = des.gram(&d, &fit);
        eiv_correct(&mut g, &des, &d);
        let (beta, _) = g.solve();
        assert!((beta[0] / j - 1.0).abs() < 0.03, "weighted: inertia {} against {j}", beta[0]);
    }

    /// A correction that sits in one unit of 24 (a free decay's first held-out block): per unit
    /// the projection test's variance has about one degree of freedom and a correction that
    /// takes the unit's residual down to white noise is not significant at 0.05/9; read from
    /// chunks of the unit it is tested against the noise. And the chunked test keeps its size:
    /// with the reference right (white or AR(1) noise up to ρ = 0.97, a candidate's small
    /// correction fitted elsewhere), p < 0.01 comes out in at most 2 % of the draws.
    #[test]
    fn a_correction_in_one_unit_is_tested_against_the_noise() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (units, len) = (24, 40);
        let n = units * len;
        let bump =
            |i: usize, a: f64| if i < len { a * (std::f64::consts::PI * i as f64 / len as f64).sin() } else { 0.0 };
        let (mut per_unit, mut chunked) = (0, 0);
        for _ in 0..50 {
            let noise = ar_noise(&mut rng, n, 0.0);
            let r: Vec<f64> = (0..n).map(|i| noise[i] + bump(i, 3.0)).collect();
            let p = |chunks: bool| {
                compare(&held(r.clone(), units, len, chunks), &held(noise.clone(), units, len, chunks)).1
            };
            per_unit += usize::from(p(false) < 0.05 / 9.0);
            chunked += usize::from(p(true) < 0.05 / 9.0);
        }
        assert!(per_unit <= 10 && chunked >= 45, "significant in {per_unit} of 50 per unit, {chunked} of 50 chunked");
        for rho in [0.0, 0.5, 0.9, 0.97] {
            let draws = 1000;
            let mut low = 0;
            for _ in 0..draws {
                let noise = ar_noise(&mut rng, n, rho);
                let a = 0.05 * (rng.random::<f64>() - 0.5);
                let e: Vec<f64> = (0..n).map(|i| noise[i] - bump(i, a) - bump(i.wrapping_sub(len), a)).collect();
                let (_, p) = projection_test(&held(noise, units, len, true), &held(e, units, len, true)).unwrap();
                low += usize::from(p < 0.01);
            }
            assert!(low <= 20, "ρ {rho}: p < 0.01 in {low} of {draws} draws");
        }
    }

    /// Every other sample carries ten times the noise (a friction sign unknown near rest), and
    /// the candidate's correction takes a small true error off the quiet samples while moving the
    /// loud ones about. Weighted by 1/σ², the test finds it; unweighted, the loud samples' noise
    /// drowns it. Weights all alike change nothing (the test does not depend on their scale),
    /// and weights give no more false alarms when the reference is right.
    #[test]
    fn weights_that_follow_the_noise_find_a_correction_where_it_is_quiet() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (units, len) = (20, 50);
        let n = units * len;
        let sd = |i: usize| if i % 2 == 0 { 10.0 } else { 1.0 };
        let weighted = |resid: Vec<f64>, w: &dyn Fn(usize) -> f64| {
            let mut s = held(resid, units, len, false);
            s.weight = std::sync::Arc::new((0..n).map(w).collect());
            s
        };
        let (mut plain, mut by_noise, mut false_alarms) = (0, 0, 0);
        for draw in 0..50 {
            let noise: Vec<f64> = ar_noise(&mut rng, n, 0.0).iter().enumerate().map(|(i, x)| sd(i) * x).collect();
            // the correction: 0.5 off the quiet samples (the true error), a wander on the loud
            let delta = |i: usize| if i % 2 == 1 { 0.5 } else { 2.0 * (0.05 * i as f64 + draw as f64).sin() };
            let truth = |i: usize| if i % 2 == 1 { 0.5 } else { 0.0 };
            let r: Vec<f64> = (0..n).map(|i| noise[i] + truth(i)).collect();
            let e: Vec<f64> = (0..n).map(|i| r[i] - delta(i)).collect();
            let inv_var = |i: usize| 1.0 / (sd(i) * sd(i));
            let p_plain = projection_test(&held(r.clone(), units, len, false), &held(e.clone(), units, len, false));
            let p_w = projection_test(&weighted(r.clone(), &inv_var), &weighted(e.clone(), &inv_var));
            let p_alike = projection_test(&weighted(r.clone(), &|_| 3.0), &weighted(e, &|_| 3.0));
            let (p_plain, p_w, p_alike) = (p_plain.unwrap().1, p_w.unwrap().1, p_alike.unwrap().1);
            assert!((p_plain - p_alike).abs() <= 1e-9 * p_plain.max(1e-300), "alike weights: {p_alike} vs {p_plain}");
            plain += usize::from(p_plain < 0.01);
            by_noise += usize::from(p_w < 0.01);
            // the reference right: the same correction on pure noise
            let e0: Vec<f64> = (0..n).map(|i| noise[i] - delta(i)).collect();
            let p0 = projection_test(&weighted(noise, &inv_var), &weighted(e0, &inv_var)).unwrap().1;
            false_alarms += usize::from(p0 < 0.01);
        }
        println!("significant in {by_noise} of 50 weighted, {plain} of 50 unweighted; {false_alarms} false alarms");
        assert!(by_noise >= 45 && plain <= 10, "significant in {by_noise} of 50 weighted, {plain} of 50 unweighted");
        assert!(false_alarms <= 1, "p < 0.01 in {false_alarms} of 50 with the reference right");
    }
}
