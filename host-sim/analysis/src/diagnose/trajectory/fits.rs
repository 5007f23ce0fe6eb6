//! Fits through the simulation: which values are free, the start's prior, the training
//! residual, multi-start, and the held-out score of the result.
//!
//! Every fit reads the training part only (the first 70 % of the window, thinned to ≤ 2000
//! samples). The start is a nuisance every model needs: fits other than `initial_state` keep
//! it near the estimate from the log (the first angle and the prepared q̇) through two prior
//! rows weighted by that estimate's uncertainty against the angle noise, so on a short log the
//! start cannot trade places with the damping; `initial_state` frees it (no prior), and the
//! judgement then asks whether it went further than the estimate's uncertainty.

use super::lm;
use super::sim;
use super::split::Split;
use super::terms::{Kind, Layout};
use crate::diagnose::select::Scored;

/// The start as estimated from the log, with its uncertainty (1σ).
#[derive(Clone, Copy, Debug)]
pub struct Prior {
    pub q: f64,
    pub v: f64,
    pub sd_q: f64,
    pub sd_v: f64,
}

/// One window of the log and what every fit of it shares.
pub struct Problem<'a> {
    pub t: &'a [f64],
    pub q: &'a [f64],
    pub u: Option<&'a [f64]>,
    pub lay: &'a Layout,
    pub n: usize,
    pub split: &'a Split,
    /// training samples the residual reads (thinned)
    pub train_idx: Vec<usize>,
    pub prior: Prior,
    /// the angle noise the prior rows are weighed against, rad
    pub noise: f64,
    /// regime bits (for [`Scored`])
    pub bits: &'a [u32],
    pub nreg: usize,
}

/// Which values a fit frees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Free {
    /// the start only, without its prior (`initial_state`)
    Start,
    /// the start (with its prior) and the model's terms (`parameters`)
    Terms,
    /// the start and the effects' values, the model's terms at the file's values
    Own,
    /// the start, the terms and the effects' values
    All,
}

/// A finished fit, simulated over the whole window and scored on the held-out part.
#[derive(Clone, Debug)]
pub struct Fitted {
    pub effects: Vec<Kind>,
    pub free: Free,
    pub theta: Vec<f64>,
    pub sim: Vec<f64>,
    pub scored: Scored,
    /// training sum of squares (data rows only)
    pub train_sse: f64,
    pub lm: Option<lm::Fit>,
}

impl Fitted {
    /// The values of effect number `k` in θ.
    pub fn effect_values(&self, lay: &Layout, k: usize) -> &[f64] {
        let mut off = 2 + lay.nb();
        for (i, &e) in self.effects.iter().enumerate() {
            let len = lay.len(e);
            if i == k {
                return self.theta.get(off..off + len).unwrap_or(&[]);
            }
            off += len;
        }
        &[]
    }

    pub fn base(&self, lay: &Layout) -> &[f64] {
        self.theta.get(2..2 + lay.nb()).unwrap_or(&[])
    }

    /// How many values the fit adds to the file's model (what parsimony counts): its effects'
    /// and, when it refits them, the model's terms.
    pub fn size(&self, lay: &Layout) -> usize {
        let own: usize = self.effects.iter().map(|k| k.size(lay)).sum();
        own + if matches!(self.free, Free::All | Free::Terms) { lay.nb() } else { 0 }
    }
}

impl Problem<'_> {
    /// The input as the joint felt it: the logged `u` at `t − lag` (held at its ends).
    fn input(&self, lag: f64) -> Option<std::borrow::Cow<'_, [f64]>> {
        let u = self.u?;
        if lag == 0.0 {
            return Some(std::borrow::Cow::Borrowed(u));
        }
        let t = self.t;
        let mut k = 0usize;
        let shifted = t
            .iter()
            .map(|&ti| {
                let at = ti - lag;
                while k + 1 < t.len() && t[k + 1] <= at {
                    k += 1;
                }
                if at <= t[0] {
                    return u[0];
                }
                let (t0, t1) = (t[k], t.get(k + 1).copied().unwrap_or(t[k]));
                let f = if t1 > t0 { ((at - t0) / (t1 - t0)).clamp(0.0, 1.0) } else { 0.0 };
                u[k] + f * (u.get(k + 1).copied().unwrap_or(u[k]) - u[k])
            })
            .collect();
        Some(std::borrow::Cow::Owned(shifted))
    }

    /// The simulated angle over the first `n` samples (with the sub-step plan when given).
    pub fn simulate(&self, th: &[f64], effects: &[Kind], n: usize, plan: Option<&[u8]>) -> Option<Vec<f64>> {
        let law = self.lay.law(th, effects);
        let u = self.input(self.lay.delay(th, effects));
        let start = (th[0], th[1]);
        match plan {
            Some(p) => sim::run_planned(&law, self.t, u.as_deref(), start, n, p),
            None => sim::run(&law, self.t, u.as_deref(), start, n),
        }
    }

    fn plan(&self, th: &[f64], effects: &[Kind], n: usize) -> Option<Vec<u8>> {
        let law = self.lay.law(th, effects);
        let u = self.input(self.lay.delay(th, effects));
        sim::plan(&law, self.t, u.as_deref(), (th[0], th[1]), n)
    }

    /// The prior rows' weights: the data residuals stand for `stride` samples each.
    fn prior_weights(&self) -> (f64, f64) {
        let stride = (self.split.n_train() as f64 / self.train_idx.len().max(1) as f64).max(1.0);
        let w = |sd: f64| self.noise / (sd.max(1e-300) * stride.sqrt());
        (w(self.prior.sd_q), w(self.prior.sd_v))
    }

    fn free_idx(&self, effects: &[Kind], free: Free) -> Vec<usize> {
        let nb = self.lay.nb();
        let ne: usize = effects.iter().map(|&k| self.lay.len(k)).sum();
        match free {
            Free::Start => vec![0, 1],
            Free::Terms => (0..2 + nb).collect(),
            Free::Own => [0, 1].into_iter().chain(2 + nb..2 + nb + ne).collect(),
            Free::All => (0..2 + nb + ne).collect(),
        }
    }

    fn bounds(&self, effects: &[Kind]) -> (Vec<f64>, Vec<f64>) {
        let (mut lo, mut hi) = self.lay.base_bounds();
        for &k in effects {
            let (l, h) = self.lay.effect_bounds(k);
            lo.extend(l);
            hi.extend(h);
        }
        (lo, hi)
    }

    /// LM from `theta0` over the `free` values, on the samples `idx` (the training part when
    /// `None`); `prior`: whether the start's prior rows are added.
    fn lm(
        &self,
        effects: &[Kind],
        free: &[usize],
        theta0: &[f64],
        iters: usize,
        idx: Option<&[usize]>,
        prior: bool,
    ) -> Option<(Vec<f64>, lm::Fit)> {
        let idx = idx.unwrap_or(&self.train_idx);
        let upto = idx.last().map_or(0, |i| i + 1);
        let plan = self.plan(theta0, effects, upto)?;
        let (lo, hi) = self.bounds(effects);
        let pick = |v: &[f64]| free.iter().map(|&k| v[k]).collect::<Vec<f64>>();
        let (lo_f, hi_f, x0) = (pick(&lo), pick(&hi), pick(theta0));
        let scale = |k: usize| match k {
            0 => self.lay.span(),
            1 => self.lay.v_typ,
            _ => 1e-3,
        };
        let steps: Vec<f64> = free.iter().zip(&x0).map(|(&k, v)| 1e-6 * v.abs().max(scale(k))).collect();
        let (wq, wv) = self.prior_weights();
        let full = |x: &[f64]| {
            let mut th = theta0.to_vec();
            for (&k, &v) in free.iter().zip(x) {
                th[k] = v;
            }
            th
        };
        let resid = |x: &[f64]| {
            let th = full(x);
            let s = self.simulate(&th, effects, upto, Some(&plan))?;
            let mut r: Vec<f64> = idx.iter().map(|&i| s[i] - self.q[i]).collect();
            if prior {
                r.push(wq * (th[0] - self.prior.q));
                r.push(wv * (th[1] - self.prior.v));
            }
            Some(r)
        };
        let f = lm::fit(&x0, &lo_f, &hi_f, &steps, iters, resid)?;
        Some((full(&f.theta), f))
    }

    /// The best fit of `effects` over `starts` (full θ vectors, [`Problem::prefilter`]ed),
    /// scored.
    pub fn fit(&self, effects: &[Kind], free: Free, starts: Vec<Vec<f64>>) -> Option<Fitted> {
        let starts = self.prefilter(effects, free, starts);
        self.fit_each(effects, free, starts)
    }

    /// The best fit of `effects` from each of `starts` as they are (already chosen).
    pub fn fit_each(&self, effects: &[Kind], free: Free, starts: Vec<Vec<f64>>) -> Option<Fitted> {
        let idx = self.free_idx(effects, free);
        let prior = free != Free::Start;
        let iters = if effects.is_empty() { 30 } else { 15 };
        let mut best: Option<(Vec<f64>, lm::Fit)> = None;
        for (t, f) in on_threads(&starts, |th| self.lm(effects, &idx, th, iters, None, prior)).into_iter().flatten() {
            if best.as_ref().is_none_or(|b| f.cost < b.1.cost) {
                best = Some((t, f));
            }
        }
        let (theta, f) = best?;
        self.finish(effects.to_vec(), free, theta, Some(f))
    }

    /// One descent of `effects` from `theta` (a fit of the same values on another fold's
    /// training part: it starts at that fit's optimum), at most `iters` finite-difference
    /// Jacobians, scored.
    pub fn refit_from(&self, effects: &[Kind], free: Free, theta: &[f64], iters: usize) -> Option<Fitted> {
        let idx = self.free_idx(effects, free);
        let (th, f) = self.lm(effects, &idx, theta, iters, None, free != Free::Start)?;
        self.finish(effects.to_vec(), free, th, Some(f))
    }

    /// The starts worth a full fit: with more than two, each first gets a few iterations on the
    /// last effect's own values (the model's terms held) on the first 40 % of the training
    /// samples, and the best two (three of a dense grid, after four iterations) are kept.
    pub fn prefilter(&self, effects: &[Kind], free: Free, starts: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        self.prefilter_on(effects, free, starts, 2, 5, 4)
    }

    /// [`Problem::prefilter`] on the first `num/den` of the training samples, a dense grid
    /// (more than 8 starts) descended `dense_iters` steps.
    pub fn prefilter_on(
        &self,
        effects: &[Kind],
        free: Free,
        starts: Vec<Vec<f64>>,
        num: usize,
        den: usize,
        dense_iters: usize,
    ) -> Vec<Vec<f64>> {
        let idx = self.free_idx(effects, free);
        let prior = free != Free::Start;
        match effects.last() {
            // A friction level is scanned, not descended (see [`Layout::level_grid`]).
            Some(&last) if starts.len() > 2 && self.lay.level_grid(last) => self.scan(effects, starts, 3),
            Some(&last) if starts.len() > 2 => {
                let len = self.lay.len(last);
                let own: Vec<usize> =
                    (idx.len().saturating_sub(len)..idx.len()).filter_map(|k| idx.get(k).copied()).collect();
                // a dense grid of starts (the ripple's periods) keeps three; the shapes are told
                // apart on the first num/den of the training samples (at least 30)
                let (iters, keep) = if starts.len() > 8 { (dense_iters, 3) } else { (3, 2) };
                let cut = self.train_idx.len() * num / den.max(1);
                let early: Vec<usize> = self.train_idx.iter().copied().take(cut.max(30)).collect();
                let mut pre: Vec<(Vec<f64>, f64)> = on_threads(&starts, |th| {
                    self.lm(effects, &own, th, iters, Some(&early), prior).map(|(t, f)| (t, f.cost))
                })
                .into_iter()
                .flatten()
                .collect();
                pre.sort_by(|a, b| a.1.total_cmp(&b.1));
                pre.into_iter().take(keep).map(|(t, _)| t).collect()
            }
            _ => starts,
        }
    }

    /// The `keep` starts whose simulation fits the whole training part best, each simulated once
    /// as it is.
    pub fn scan(&self, effects: &[Kind], starts: Vec<Vec<f64>>, keep: usize) -> Vec<Vec<f64>> {
        let upto = self.train_idx.last().map_or(0, |i| i + 1);
        let costs = on_threads(&starts, |th| {
            let s = self.simulate(th, effects, upto, None)?;
            Some(self.train_idx.iter().map(|&i| (s[i] - self.q[i]).powi(2)).sum::<f64>())
        });
        let mut pre: Vec<(Vec<f64>, f64)> =
            starts.into_iter().zip(costs).filter_map(|(th, c)| c.map(|c| (th, c))).collect();
        pre.sort_by(|a, b| a.1.total_cmp(&b.1));
        pre.into_iter().take(keep).map(|(t, _)| t).collect()
    }

    /// Simulates `theta` over the whole window and scores it.
    pub fn finish(&self, effects: Vec<Kind>, free: Free, theta: Vec<f64>, f: Option<lm::Fit>) -> Option<Fitted> {
        let sim = self.simulate(&theta, &effects, self.n, None)?;
        let train_sse = self.train_idx.iter().map(|&i| (sim[i] - self.q[i]).powi(2)).sum();
        let scored = score(&sim, self.q, self.split, self.bits, self.nreg, theta.clone());
        Some(Fitted { effects, free, theta, sim, scored, train_sse, lm: f })
    }

    /// The start that makes the file's model (at `theta0`'s terms) follow the first `k` samples:
    /// over so short a stretch a model error has not yet built up, so this is a model-based
    /// estimate of the start, free of the boundary bias a local polynomial can have.
    pub fn local_start(&self, theta0: &[f64], k: usize) -> Option<(f64, f64)> {
        let idx: Vec<usize> = (0..k.min(self.n)).collect();
        let (th, _) = self.lm(&[], &[0, 1], theta0, 30, Some(&idx), false)?;
        Some((th[0], th[1]))
    }
}

/// The held-out score of a simulated angle: squared residuals over the held-out samples, per
/// test unit and per regime, and the residuals themselves in time order (the units run in that
/// order), so [`crate::diagnose::select::compare`] can weigh a candidate's correction against
/// the noise (its projection test) and not only against how unevenly the gain falls over the
/// units: a free decay puts nearly all of a model error into the first held-out blocks, and the
/// units after the joint has settled hold noise alone, whose scatter drowned a refit that took
/// a spring constant from 5.4 back to the true 9.7 (3.5× → 1.06× the floor held out, p = 0.013
/// over the units, not significant at 0.05/9; seed 7 case 73).
pub fn score(sim: &[f64], q: &[f64], split: &Split, bits: &[u32], nreg: usize, theta: Vec<f64>) -> Scored {
    let mut s = crate::diagnose::select::Sums::new(split.n_held(), split.units, nreg);
    let mut resid = Vec::with_capacity(split.n_held());
    for (i, (&qi, &si)) in q.iter().zip(sim).enumerate() {
        if split.held[i] {
            let r = qi - si;
            s.add(r * r, split.unit[i], bits.get(i).copied().unwrap_or(0));
            resid.push(r);
        }
    }
    let mut scored = s.into_scored(vec![], crate::diagnose::candidates::Design::empty(), theta);
    scored.resid = std::sync::Arc::new(resid);
    scored.chunked = true;
    scored
}

/// `work` on every start, on two threads where there are two cores, the results in the starts'
/// order (each start's fit is the same computation on either path, so the best one is too).
fn on_threads<T: Send>(starts: &[Vec<f64>], work: impl Fn(&Vec<f64>) -> T + Sync) -> Vec<T> {
    let threads = crate::diagnose::par::cores(2);
    crate::diagnose::par::costliest_first(starts, threads, |_| 0, work)
}
