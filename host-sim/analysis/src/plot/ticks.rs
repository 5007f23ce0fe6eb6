//! Axis ticks on "nice" values: a step of 1, 2 or 5 times a power of ten, the axis widened to
//! whole steps so its ends carry ticks, and labels with as many decimals as the step needs
//! (0.5, 1, 1.5 rather than 0.091, 1.025, 1.959).

/// The smallest 1-2-5 step that puts at most `max_ticks` ticks on `[lo, hi]` once the range is
/// widened to whole steps. A degenerate or non-finite span gives 1.
pub fn nice_step(lo: f64, hi: f64, max_ticks: usize) -> f64 {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) {
        return 1.0;
    }
    let max_ticks = max_ticks.max(2) as f64;
    let mut mag = 10f64.powf((span / max_ticks).log10().floor());
    // a bounded search: the first candidate is at most 10× too small, so three decades suffice
    for _ in 0..4 {
        for m in [1.0, 2.0, 5.0] {
            let step = m * mag;
            let n = (hi / step).ceil() - (lo / step).floor() + 1.0;
            if n <= max_ticks {
                return step;
            }
        }
        mag *= 10.0;
    }
    mag
}

/// An axis: its range (whole steps) and its ticks.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    pub lo: f64,
    pub hi: f64,
    pub step: f64,
}

impl Axis {
    /// The axis over the data range `[lo, hi]`, widened to whole 1-2-5 steps, with at most
    /// `max_ticks` ticks. An empty or non-finite range gives [0, 1]; a single value is widened
    /// by a tenth of its size (or by 1 at zero).
    pub fn covering(lo: f64, hi: f64, max_ticks: usize) -> Axis {
        let (mut lo, mut hi) = if lo.is_finite() && hi.is_finite() && lo <= hi { (lo, hi) } else { (0.0, 1.0) };
        if hi - lo <= 1e-12 * lo.abs().max(hi.abs()).max(1e-300) {
            let w = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
            (lo, hi) = (lo - w, hi + w);
        }
        let step = nice_step(lo, hi, max_ticks);
        // the ends are ticks, cleaned of last-bit noise unless that would cut off data
        let (a, b) = ((lo / step).floor() * step, (hi / step).ceil() * step);
        let (ca, cb) = (clean(a), clean(b));
        Axis { lo: if ca <= lo { ca } else { a }, hi: if cb >= hi { cb } else { b }, step }
    }

    /// The ticks: every whole multiple of the step in the range (computed as k·step, so they do
    /// not drift).
    pub fn ticks(&self) -> Vec<f64> {
        let (a, b) = ((self.lo / self.step).round() as i64, (self.hi / self.step).round() as i64);
        (a..=b).map(|k| clean(k as f64 * self.step)).collect()
    }

    /// Minor ticks between the ticks: fifths of a 1 or 5 step, quarters of a 2 step.
    pub fn minor_ticks(&self) -> Vec<f64> {
        let mant = (self.step / 10f64.powf(self.step.log10().floor())).round();
        let sub = if mant == 2.0 { self.step / 4.0 } else { self.step / 5.0 };
        let (a, b) = ((self.lo / sub).round() as i64, (self.hi / sub).round() as i64);
        (a..=b).map(|k| clean(k as f64 * sub)).collect()
    }

    /// A tick's label with the decimals the step needs.
    pub fn label(&self, v: f64) -> String {
        format_tick(v, self.step)
    }
}

/// `v` without the last-bit noise of `k·step` (0.30000000000000004 → 0.3), and never −0.
fn clean(v: f64) -> f64 {
    let r: f64 = format!("{v:.12e}").parse().unwrap_or(v);
    if r == 0.0 {
        0.0
    } else {
        r
    }
}

/// A tick label: as many decimals as `step` has (a 1-2-5 step needs one digit after its
/// leading one), in scientific notation for very large or very small values.
pub fn format_tick(v: f64, step: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v.is_finite() { "0".into() } else { format!("{v}") };
    }
    let step = step.abs().max(f64::MIN_POSITIVE);
    let big = v.abs().max(step);
    if big >= 1e6 || step < 1e-4 {
        // mantissa digits: those of the step relative to the value's magnitude
        let d = (big.log10().floor() - step.log10().floor()).clamp(0.0, 6.0) as usize;
        return format!("{v:.d$e}");
    }
    let d = (-step.log10().floor()).max(0.0) as usize;
    let s = format!("{v:.d$}");
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        "0".into()
    } else {
        s
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    fn is_125(step: f64) -> bool {
        let m = step / 10f64.powf(step.log10().floor());
        [1.0, 2.0, 5.0].iter().any(|c| (m - c).abs() < 1e-9)
    }

    #[test]
    fn ticks_fall_on_1_2_5_multiples_and_cover_the_range() {
        // the ranges the hand-written plots labelled 1.959, 1.025, 0.091, and a spread of others
        let mut cases = vec![(0.091, 1.959), (-0.013, 2.07), (0.0, 120_000.0), (-3.3e-5, 7.7e-5), (17.2, 17.9)];
        let mut x = 0.37_f64;
        for _ in 0..500 {
            // a deterministic walk over scales and offsets
            x = (x * 9301.0 + 49297.0) % 233280.0 / 233280.0;
            let scale = 10f64.powf(x * 12.0 - 6.0);
            let lo = (x - 0.5) * scale * 3.0;
            cases.push((lo, lo + scale * (0.1 + x)));
        }
        for (lo, hi) in cases {
            for max in [4, 6, 8, 11] {
                let a = Axis::covering(lo, hi, max);
                assert!(is_125(a.step), "step {} for [{lo}, {hi}]", a.step);
                assert!(a.lo <= lo && a.hi >= hi, "[{}, {}] does not cover [{lo}, {hi}]", a.lo, a.hi);
                let t = a.ticks();
                assert!(t.len() >= 2 && t.len() <= max, "{} ticks for [{lo}, {hi}] (max {max})", t.len());
                assert_eq!(*t.first().unwrap(), a.lo);
                assert_eq!(*t.last().unwrap(), a.hi);
                for v in &t {
                    let k = v / a.step;
                    assert!((k - k.round()).abs() < 1e-6, "{v} is not a multiple of {}", a.step);
                }
                // the widening is less than a step on each side
                assert!(lo - a.lo < a.step * (1.0 + 1e-9) && a.hi - hi < a.step * (1.0 + 1e-9));
            }
        }
    }

    #[test]
    fn labels_have_the_decimals_the_step_needs() {
        let a = Axis::covering(0.091, 1.959, 6);
        assert_eq!(a.step, 0.5);
        let l: Vec<String> = a.ticks().iter().map(|v| a.label(*v)).collect();
        assert_eq!(l, ["0", "0.5", "1.0", "1.5", "2.0"]);
        let a = Axis::covering(-0.3, 0.3, 8);
        let l: Vec<String> = a.ticks().iter().map(|v| a.label(*v)).collect();
        assert_eq!(l, ["-0.3", "-0.2", "-0.1", "0", "0.1", "0.2", "0.3"]);
        assert_eq!(format_tick(120_000.0, 20_000.0), "120000");
        assert_eq!(format_tick(2.0e-5, 1.0e-5), "2e-5");
        assert_eq!(format_tick(3.0e6, 1.0e6), "3e6");
    }

    #[test]
    fn degenerate_ranges_still_give_an_axis() {
        for (lo, hi) in [(0.0, 0.0), (5.0, 5.0), (f64::NAN, 1.0), (f64::INFINITY, f64::NEG_INFINITY)] {
            let a = Axis::covering(lo, hi, 6);
            assert!(a.hi > a.lo && a.ticks().len() >= 2, "{lo} {hi}: {a:?}");
        }
        let a = Axis::covering(0.0, 1.0, 6);
        assert_eq!((a.step, a.minor_ticks().len()), (0.2, 21));
    }
}
