//! What the log must show of a drawn effect, so that its label is something the data can
//! tell apart from a wrong parameter of the file's own terms.
//!
//! An effect is only a label when part of its signature on the drawn trajectory lies outside
//! what the file model's terms (offset, spring k·(q − q0), weight, J, b, c) can absorb:
//! - backlash adds −k·clamp(q − q0, lo, hi): on one side of the zone that is the constant
//!   −k·lo or −k·hi, an offset / q0 error; only a trajectory that crosses the zone shows the
//!   saturation;
//! - a one-sided cable is 0 until q_e and a linear spring past it: never engaged it is
//!   nothing, always engaged it is a spring-and-offset error; it must engage for part of the log;
//! - a position ripple with fewer than ~2 periods over the span is mostly a slope and an offset;
//! - asymmetric friction without motion in both directions is a Coulomb level error (one
//!   direction only) and needs reversals to show c₊ ≠ c₋.
//!
//! `check` measures these on the clean angle and velocity at the sample times and returns
//! what the draw guaranteed (written to truth.json) or why it failed.

use serde_json::{json, Value};

use crate::effects::{CableShape, Effect};

/// Crossings each way of the zone, at least.
pub const MIN_CROSSINGS: usize = 3;
/// Share of samples on each side of a backlash zone, at least.
pub const MIN_SIDE_SHARE: f64 = 0.1;
/// Engaged share of a one-sided cable.
pub const CABLE_SHARE: (f64, f64) = (0.05, 0.95);
/// Ripple periods over the angle span, at least.
pub const MIN_PERIODS: f64 = 2.0;
/// Direction changes of the motion, at least (asymmetric friction).
pub const MIN_REVERSALS: usize = 2;
/// Half-width around q0 that holds any drawn backlash zone (width ≤ 20 mrad, centred or
/// on either side of q0): a trajectory crossing this band crosses every possible zone.
pub const BACKLASH_BAND: f64 = 0.02;

/// Full crossings of [lo, hi]: from below lo to above hi (up) and back (down).
pub fn crossings(q: &[f64], lo: f64, hi: f64) -> (usize, usize) {
    let (mut up, mut down) = (0, 0);
    // −1 below, +1 above, 0 before the first sample outside the zone.
    let mut side = 0i8;
    for &x in q {
        let s = if x > hi {
            1
        } else if x < lo {
            -1
        } else {
            continue;
        };
        if side == -1 && s == 1 {
            up += 1;
        } else if side == 1 && s == -1 {
            down += 1;
        }
        side = s;
    }
    (up, down)
}

/// Share of the values satisfying `pred`.
pub fn share(q: &[f64], pred: impl Fn(f64) -> bool) -> f64 {
    if q.is_empty() {
        return 0.0;
    }
    q.iter().filter(|x| pred(**x)).count() as f64 / q.len() as f64
}

/// Sign changes of the motion (rest samples skipped).
pub fn reversals(qd: &[f64]) -> usize {
    let mut last = 0.0f64;
    let mut n = 0;
    for &v in qd.iter().filter(|v| **v != 0.0) {
        if last != 0.0 && v.signum() != last {
            n += 1;
        }
        last = v.signum();
    }
    n
}

/// The p-quantile (0..1) of the values (nearest rank); 0 for an empty slice.
pub fn quantile(q: &[f64], p: f64) -> f64 {
    let mut s: Vec<f64> = q.iter().copied().filter(|x| x.is_finite()).collect();
    s.sort_by(f64::total_cmp);
    let i = ((s.len().saturating_sub(1)) as f64 * p.clamp(0.0, 1.0)).round() as usize;
    s.get(i).copied().unwrap_or(0.0)
}

/// Whether a trajectory shows every backlash zone that may be drawn around `q0`.
pub fn backlash_band_ok(q: &[f64], q0: f64) -> bool {
    let (lo, hi) = (q0 - BACKLASH_BAND, q0 + BACKLASH_BAND);
    let (up, down) = crossings(q, lo, hi);
    up.min(down) >= MIN_CROSSINGS && share(q, |x| x < lo) >= MIN_SIDE_SHARE && share(q, |x| x > hi) >= MIN_SIDE_SHARE
}

/// What the log shows of `effect` (Null for families without a requirement), or why it
/// shows too little.
pub fn check(effect: &Effect, q: &[f64], qd: &[f64]) -> Result<Value, String> {
    match effect {
        Effect::Backlash { q0, lo, hi, .. } => {
            let (a, b) = (q0 + lo, q0 + hi);
            let (up, down) = crossings(q, a, b);
            let below = share(q, |x| x < a);
            let above = share(q, |x| x > b);
            let g = json!({
                "crossings_up": up, "crossings_down": down,
                "share_below": below, "share_inside": 1.0 - below - above, "share_above": above,
            });
            if up.min(down) < MIN_CROSSINGS || below.min(above) < MIN_SIDE_SHARE {
                return Err(format!("backlash zone shown too little: {g}"));
            }
            Ok(g)
        }
        Effect::CableSpring { cable: CableShape::OneSided { q_e, side, .. } } => {
            let engaged = share(q, |x| side * (x - q_e) > 0.0);
            let g = json!({ "engaged_share": engaged });
            if !(CABLE_SHARE.0..=CABLE_SHARE.1).contains(&engaged) {
                return Err(format!("cable engaged for {:.1} % of the samples", 100.0 * engaged));
            }
            Ok(g)
        }
        Effect::PositionRipple { harmonics } => {
            let span = span(q);
            let longest = harmonics.iter().map(|h| h.period).fold(0.0, f64::max);
            let periods = span / longest.max(1e-12);
            let g = json!({ "periods_in_span": periods });
            if periods < MIN_PERIODS {
                return Err(format!("ripple: {periods:.2} periods over the span"));
            }
            Ok(g)
        }
        Effect::AsymmetricFriction { .. } => {
            let n = reversals(qd);
            let g = json!({
                "reversals": n,
                "share_positive": share(qd, |v| v > 0.0), "share_negative": share(qd, |v| v < 0.0),
            });
            if n < MIN_REVERSALS {
                return Err(format!("asymmetric friction: {n} reversals"));
            }
            Ok(g)
        }
        _ => Ok(Value::Null),
    }
}

/// Peak-to-peak of the values.
pub fn span(q: &[f64]) -> f64 {
    let lo = q.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = q.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (hi - lo).max(0.0)
}

/// The guarantees of all effects (name → what was shown), or the first failure.
pub fn check_all(effects: &[Effect], q: &[f64], qd: &[f64]) -> Result<serde_json::Map<String, Value>, String> {
    let mut m = serde_json::Map::new();
    for e in effects {
        let g = check(e, q, qd)?;
        if !g.is_null() {
            m.insert(e.name().to_string(), g);
        }
    }
    Ok(m)
}
