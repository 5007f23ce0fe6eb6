//! Finding the test segments in a log from the data: constant-velocity plateaus (friction),
//! static poses (weight, spring slope, gravity table), moving samples (inertia and offset) and
//! a free release (elastic oscillation); `--window START:END:KIND` replaces the automatic
//! search for that kind.
//!
//! Everything works on a prepared log ([`Prepared`]), built on the shared preparation stage
//! ([`crate::prep::prepare`]): stale rows dropped, the log split at gaps and jumps, unit and
//! rate refusals, and q̇, q̈ from the data-driven local cubic fits (or the logged columns where
//! those are the better estimate). On top of that, a zero-phase low-passed velocity `qd_f` and
//! acceleration `qdd_f` (per gap-free stretch) are used only to *classify* samples. A plateau is a stretch of at least `min_plateau` s where the joint moves
//! (|q̇| ≥ `v_move`) with a velocity that changes slowly (|q̈| ≤ `a_flat` + `a_flat_rel`·|q̇|);
//! a static pose is a stretch of at least `min_static` s with |q̇| ≤ `v_static`, of which the
//! first `settle_share` is dropped (the joint is still settling there).

use super::filter;
use crate::prep::{self, PrepError, PrepReport};
use joint_formats::log::JointLog;

/// What a segment is used for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SegKind {
    Plateau,
    Static,
    Motion,
    Free,
}

impl SegKind {
    pub fn parse(s: &str) -> Result<SegKind, String> {
        match s {
            "plateau" => Ok(SegKind::Plateau),
            "static" => Ok(SegKind::Static),
            "motion" => Ok(SegKind::Motion),
            "free" => Ok(SegKind::Free),
            o => Err(format!("unknown window kind `{o}` (known: plateau, static, motion, free)")),
        }
    }
}

/// A user-given window: times in seconds of the log's own clock, applied to every log.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    pub start: f64,
    pub end: f64,
    pub kind: SegKind,
}

impl std::str::FromStr for Window {
    type Err = String;
    fn from_str(s: &str) -> Result<Window, String> {
        let parts: Vec<&str> = s.split(':').collect();
        let [a, b, k] = parts.as_slice() else {
            return Err(format!("`{s}`: expected START:END:KIND (seconds, kind plateau|static|motion|free)"));
        };
        let num = |x: &str| x.trim().parse::<f64>().map_err(|_| format!("`{s}`: `{x}` is not a number of seconds"));
        let (start, end) = (num(a)?, num(b)?);
        if !(start.is_finite() && end.is_finite() && end > start) {
            return Err(format!("`{s}`: need START < END"));
        }
        Ok(Window { start, end, kind: SegKind::parse(k.trim())? })
    }
}

/// A half-open sample range `[start, end)` of one log.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Segment {
    pub kind: SegKind,
    pub start: usize,
    pub end: usize,
}

impl Segment {
    pub fn len(&self) -> usize {
        self.end.saturating_sub(self.start)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Thresholds of the automatic search.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentCfg {
    /// rad/s: moving above this
    pub v_move: f64,
    /// rad/s: static below this
    pub v_static: f64,
    /// rad/s²: a plateau's velocity changes by less than this (plus `a_flat_rel`·|q̇|); loose,
    /// because the second friction pass takes `J·q̈` off
    pub a_flat: f64,
    pub a_flat_rel: f64,
    /// rad/s² (plus `a_strict_rel`·|q̇|): the samples the first friction pass uses, before J is known
    pub a_strict: f64,
    pub a_strict_rel: f64,
    /// s
    pub min_plateau: f64,
    /// s
    pub min_static: f64,
    /// share of a static stretch dropped at its start
    pub settle_share: f64,
    /// Hz, low-pass used for classification
    pub classify_cutoff: f64,
}

impl Default for SegmentCfg {
    fn default() -> Self {
        SegmentCfg {
            v_move: 0.03,
            v_static: 0.02,
            a_flat: 0.3,
            a_flat_rel: 0.5,
            a_strict: 0.1,
            a_strict_rel: 0.1,
            min_plateau: 0.25,
            min_static: 0.5,
            settle_share: 0.4,
            classify_cutoff: 5.0,
        }
    }
}

/// A log with the derived columns identification needs, all of the prepared log's length (stale
/// rows already dropped).
#[derive(Clone, Debug)]
pub struct Prepared {
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    /// q̇ of the preparation stage (logged, or the local cubic fit's), 0 at rest
    pub qd: Vec<f64>,
    /// zero-phase low-passed velocity (classification, friction argument)
    pub qd_f: Vec<f64>,
    /// zero-phase low-passed acceleration (classification)
    pub qdd_f: Vec<f64>,
    /// q̈ of the preparation stage (logged, from the logged q̇, or from q), 0 at rest
    pub qdd: Vec<f64>,
    /// disturbance d = u − tau (torque mode only)
    pub d: Option<Vec<f64>>,
    /// other joints' angles (`q_<name>`)
    pub others: Vec<(String, Vec<f64>)>,
    /// median sample rate, Hz
    pub fs: f64,
    /// gap-free stretches (half-open index ranges): filters and derivatives never cross them
    pub pieces: Vec<std::ops::Range<usize>>,
    /// samples found at rest by the preparation stage
    pub rest: Vec<bool>,
    /// samples whose motion is undecided (a move leaving or reaching a rest): fits leave them out
    pub ambiguous: Vec<bool>,
    /// noise (1σ) of the q̈ used, per sample
    pub qdd_noise: Vec<f64>,
    /// what the preparation did (smoother, windows, stale rows, gaps)
    pub prep: PrepReport,
}

impl Prepared {
    /// Prepares a log: the shared stage's refusals (units, rate) are this one's.
    pub fn new(log: &JointLog, cfg: &SegmentCfg) -> Result<Prepared, PrepError> {
        let pp = prep::prepare(log)?;
        let l = &pp.log;
        let fs = 1.0 / prep::median_step(&l.t);
        let qd = whole_stretch(&pp, &pp.report.qd, pp.qd(), false);
        let qdd = whole_stretch(&pp, &pp.report.qdd, pp.qdd(), true);
        let qd_f = filter::filtfilt_pieces(&qd, cfg.classify_cutoff, fs, &pp.segments);
        let qdd_f = filter::filtfilt_pieces(&qdd, cfg.classify_cutoff, fs, &pp.segments);
        let d = match (&l.u, &l.tau) {
            (Some(u), Some(tau)) => Some(u.iter().zip(tau).map(|(u, t)| u - t).collect()),
            _ => None,
        };
        Ok(Prepared {
            t: l.t.clone(),
            q: l.q.clone(),
            qd,
            qd_f,
            qdd_f,
            qdd,
            d,
            others: l.others.clone(),
            fs,
            pieces: pp.segments.clone(),
            rest: pp.rest.clone(),
            ambiguous: pp.ambiguous.clone(),
            qdd_noise: pp.qdd_noise.clone(),
            prep: pp.report,
        })
    }

    /// Zero-phase low-pass of a per-sample series of this log, stretch by stretch.
    pub fn lowpass(&self, x: &[f64], fc: f64) -> Vec<f64> {
        filter::filtfilt_pieces(x, fc, self.fs, &self.pieces)
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Sample range of a time window.
    pub fn range_of(&self, w: &Window) -> (usize, usize) {
        let s = self.t.partition_point(|&t| t < w.start);
        let e = self.t.partition_point(|&t| t < w.end);
        (s, e)
    }
}

/// A derivative as the preparation stage chose it (its source and its data-driven window), but
/// evaluated over each gap-free stretch as a whole, without the stage's rest handling (q̇ = q̈ = 0
/// at rest, one-sided windows next to a rest). At a true rest the local cubic gives ≈ 0 anyway;
/// but the stage's rest test (|q̇| and |q̈| within 4σ of their noise) also takes the turning points
/// of a swing for rests when q̈ is noisy (DFKI sys-id run: 12 of them, 22 % of the samples), and
/// q̈ set to 0 exactly where a pendulum's is largest, with one-sided estimates spiking at each
/// such "rest"'s ends, takes J from 0.15 to 0.02 kg·m² there. A logged column the stage chose
/// is kept as it is (at a turning point its q̇ is ≈ 0 anyway).
fn whole_stretch(pp: &prep::Prepared, info: &prep::DerivInfo, used: &[f64], second: bool) -> Vec<f64> {
    let mut out = used.to_vec();
    if !pp.rest.iter().any(|r| *r) || info.source == "logged" {
        return out;
    }
    let dt = prep::median_step(&pp.log.t);
    let h = ((info.half_window_s / dt).round() as usize).max(2);
    let from_qd = info.source == "derived from the logged qd";
    let src: &[f64] = if from_qd { pp.log.qd.as_deref().unwrap_or(&pp.log.q) } else { &pp.log.q };
    for r in &pp.segments {
        let e = prep::lpr::estimate(&pp.log.t[r.clone()], &src[r.clone()], h);
        let v = if second && !from_qd { &e.d2 } else { &e.d1 };
        out[r.clone()].copy_from_slice(v);
    }
    out
}

/// Runs of `true` in a mask of at least `min_len` samples, as half-open ranges.
fn runs(mask: impl Iterator<Item = bool>, min_len: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start: Option<usize> = None;
    let mut n = 0;
    for (i, m) in mask.enumerate() {
        n = i + 1;
        match (m, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                if i - s >= min_len {
                    out.push((s, i));
                }
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        if n - s >= min_len {
            out.push((s, n));
        }
    }
    out
}

/// The automatic segments of one prepared log, or the windows of a kind where given.
pub fn find(p: &Prepared, cfg: &SegmentCfg, windows: &[Window]) -> Vec<Segment> {
    let mut segs = Vec::new();
    let given = |k: SegKind| windows.iter().any(|w| w.kind == k);
    for w in windows {
        let (s, e) = p.range_of(w);
        if e > s {
            segs.push(Segment { kind: w.kind, start: s, end: e });
        }
    }
    let n_plateau = (cfg.min_plateau * p.fs).ceil() as usize;
    let n_static = (cfg.min_static * p.fs).ceil() as usize;
    if !given(SegKind::Plateau) {
        // Split by direction so a plateau never spans a reversal.
        for dir in [1.0f64, -1.0] {
            let mask = p
                .qd_f
                .iter()
                .zip(&p.qdd_f)
                .map(|(v, a)| dir * v >= cfg.v_move && a.abs() <= cfg.a_flat + cfg.a_flat_rel * v.abs());
            for (s, e) in runs(mask, n_plateau.max(2)) {
                segs.push(Segment { kind: SegKind::Plateau, start: s, end: e });
            }
        }
    }
    if !given(SegKind::Static) {
        let mask = p.qd_f.iter().map(|v| v.abs() <= cfg.v_static);
        for (s, e) in runs(mask, n_static.max(2)) {
            let skip = ((e - s) as f64 * cfg.settle_share) as usize;
            segs.push(Segment { kind: SegKind::Static, start: s + skip, end: e });
        }
    }
    segs.sort_by_key(|s| s.start);
    segs
}

/// The free-oscillation segment of a log: the given `free` window, else from the first
/// sample where the speed exceeds 20 % of the log's largest speed (certainly after the
/// release; the fit's initial state is free, so starting a little late costs nothing) to the
/// end of the log.
pub fn free_segment(p: &Prepared, windows: &[Window]) -> Option<Segment> {
    if let Some(w) = windows.iter().find(|w| w.kind == SegKind::Free) {
        let (s, e) = p.range_of(w);
        return (e > s + 10).then_some(Segment { kind: SegKind::Free, start: s, end: e });
    }
    let vmax = p.qd_f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if vmax <= 0.0 {
        return None;
    }
    let s = p.qd_f.iter().position(|v| v.abs() > 0.2 * vmax)?;
    (p.len() > s + 10).then_some(Segment { kind: SegKind::Free, start: s, end: p.len() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_parses_and_refuses() {
        let w: Window = "1.5:3:static".parse().unwrap();
        assert_eq!(w, Window { start: 1.5, end: 3.0, kind: SegKind::Static });
        assert!("3:1:static".parse::<Window>().is_err());
        assert!("1:3:wobble".parse::<Window>().unwrap_err().contains("wobble"));
        assert!("1:3".parse::<Window>().is_err());
    }

    #[test]
    fn runs_respect_min_length() {
        let m = [true, true, false, true, true, true, false, true];
        assert_eq!(runs(m.iter().copied(), 2), vec![(0, 2), (3, 6)]);
        assert_eq!(runs(m.iter().copied(), 1), vec![(0, 2), (3, 6), (7, 8)]);
    }
}
