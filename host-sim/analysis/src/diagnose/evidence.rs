//! The verdict's evidence (issue 13.7): on the held-out samples, the residual the file's model
//! leaves, binned in the coordinate the named effect lives in, with what the verdict's fit takes
//! out of it binned the same way. Where the effect is real the fitted curve runs through the
//! binned residual; where it is not, the bins scatter around zero and the curve with them.
//!
//! The fitted curve is the change in prediction the whole verdict makes (the residual before
//! less the residual after), so a refit of the model's own terms that comes with the effect is
//! in it too: the plot shows what the verdict explains, not one term in isolation.

use joint_formats::vocab::Effect as Vocab;
use serde::Serialize;

/// One evidence plot: binned held-out residual and binned fitted correction over a coordinate.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Evidence {
    /// the verdict entry this is the evidence for
    pub effect: String,
    /// the coordinate's name and unit, e.g. `q̇ (rad/s)`
    pub coordinate: String,
    pub bins: Vec<Bin>,
    /// the verdict's fitted correction as a curve over the coordinate: its mean in each of up
    /// to [`CURVE_POINTS`] equal-width slices of the coordinate (where a slice has samples), so
    /// a ripple or a Stribeck dip shows its shape rather than 30 bin means
    pub curve: Vec<(f64, f64)>,
}

/// Slices of the coordinate the fitted curve is drawn from.
pub const CURVE_POINTS: usize = 160;

/// One bin of the coordinate.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Bin {
    /// mean of the coordinate in the bin
    pub x: f64,
    /// mean residual of the file's model
    pub residual: f64,
    /// standard error of that mean
    pub sem: f64,
    /// mean of the verdict's fitted correction (residual before − after)
    pub fitted: f64,
    pub samples: usize,
}

/// Bins (at most `nbins`, equally populated, ≥ 20 samples each) of `x` over the samples `idx`.
/// Samples with a non-finite coordinate are skipped. `None` when fewer than 60 remain.
pub fn binned(
    effect: &str,
    coordinate: &str,
    x: &[f64],
    before: &[f64],
    after: &[f64],
    idx: &[usize],
    nbins: usize,
) -> Option<Evidence> {
    let mut pts: Vec<(f64, f64, f64)> = idx
        .iter()
        .filter_map(|&i| {
            let (xi, b, a) = (*x.get(i)?, *before.get(i)?, *after.get(i)?);
            (xi.is_finite() && b.is_finite() && a.is_finite()).then_some((xi, b, b - a))
        })
        .collect();
    if pts.len() < 60 {
        return None;
    }
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let k = nbins.clamp(3, pts.len() / 20);
    let mut bins = Vec::with_capacity(k);
    for b in 0..k {
        let part = &pts[b * pts.len() / k..(b + 1) * pts.len() / k];
        let m = part.len() as f64;
        let mean = |f: &dyn Fn(&(f64, f64, f64)) -> f64| part.iter().map(f).sum::<f64>() / m;
        let (xm, rm, fm) = (mean(&|p| p.0), mean(&|p| p.1), mean(&|p| p.2));
        let var = part.iter().map(|p| (p.1 - rm) * (p.1 - rm)).sum::<f64>() / (m - 1.0).max(1.0);
        bins.push(Bin { x: xm, residual: rm, sem: (var / m).sqrt(), fitted: fm, samples: part.len() });
    }
    let curve = curve(&pts);
    Some(Evidence { effect: effect.to_string(), coordinate: coordinate.to_string(), bins, curve })
}

/// The fitted correction (`.2`) averaged in equal-width slices of the coordinate (`.0`); `pts`
/// sorted by the coordinate.
fn curve(pts: &[(f64, f64, f64)]) -> Vec<(f64, f64)> {
    let (Some(first), Some(last)) = (pts.first(), pts.last()) else { return Vec::new() };
    let (lo, w) = (first.0, last.0 - first.0);
    if !(w > 0.0) {
        return Vec::new();
    }
    let mut sums = vec![(0.0, 0.0, 0usize); CURVE_POINTS];
    for p in pts {
        let k = (((p.0 - lo) / w) * CURVE_POINTS as f64).floor().clamp(0.0, (CURVE_POINTS - 1) as f64) as usize;
        if let Some(s) = sums.get_mut(k) {
            *s = (s.0 + p.0, s.1 + p.2, s.2 + 1);
        }
    }
    sums.iter().filter(|s| s.2 > 0).map(|s| (s.0 / s.2 as f64, s.1 / s.2 as f64)).collect()
}

/// The coordinate an effect of the vocabulary lives in (spec §3): its name for the plot, and
/// which of the log's signals it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coord {
    Velocity,
    Position,
    Time,
    Temperature,
    Load,
    /// the rate of change of the commanded torque (a delay shows against it)
    TorqueRate,
}

impl Coord {
    /// The coordinate for a vocabulary name (`parameters` and friction effects: velocity).
    pub fn of(effect: Vocab, has_temp: bool) -> Coord {
        match effect {
            Vocab::PositionRipple | Vocab::CableSpring | Vocab::Backlash | Vocab::InitialState => Coord::Position,
            Vocab::ThermalDrift if has_temp => Coord::Temperature,
            Vocab::ThermalDrift => Coord::Time,
            Vocab::LoadDependentFriction => Coord::Load,
            Vocab::Delay => Coord::TorqueRate,
            _ => Coord::Velocity,
        }
    }

    pub fn label(self, torque_unit: &str) -> String {
        match self {
            Coord::Velocity => "q̇ (rad/s)".into(),
            Coord::Position => "q (rad)".into(),
            Coord::Time => "t (s)".into(),
            Coord::Temperature => "temperature (°C)".into(),
            Coord::Load => format!("|τ load| ({torque_unit})"),
            Coord::TorqueRate => format!("du/dt ({torque_unit}/s)"),
        }
    }
}

/// Central-difference rate of `u` over time `t` (one-sided at the ends).
pub fn rate(u: &[f64], t: &[f64]) -> Vec<f64> {
    let n = u.len().min(t.len());
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n.saturating_sub(1)));
            let dt = t[b] - t[a];
            if dt > 0.0 {
                (u[b] - u[a]) / dt
            } else {
                0.0
            }
        })
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn a_real_effect_shows_as_the_curve_through_the_bins() {
        // residual = 0.5·x², the fit takes exactly that out: every bin's fitted mean equals
        // its residual mean, and the bins are ordered in x
        let n = 1000;
        let x: Vec<f64> = (0..n).map(|i| i as f64 / n as f64 * 2.0 - 1.0).collect();
        let before: Vec<f64> = x.iter().map(|v| 0.5 * v * v).collect();
        let after = vec![0.0; n];
        let idx: Vec<usize> = (0..n).collect();
        let e = binned("stribeck", "q̇ (rad/s)", &x, &before, &after, &idx, 25).unwrap();
        assert_eq!(e.bins.len(), 25);
        assert_eq!(e.bins.iter().map(|b| b.samples).sum::<usize>(), n);
        for w in e.bins.windows(2) {
            assert!(w[0].x < w[1].x);
        }
        // the curve follows the fitted correction finely: 0.5·x² at the slices' mean x
        assert_eq!(e.curve.len(), CURVE_POINTS);
        for (x, y) in &e.curve {
            assert!((y - 0.5 * x * x).abs() < 2e-4, "curve at {x}: {y}");
        }
        for b in &e.bins {
            assert!((b.residual - b.fitted).abs() < 1e-12);
            assert!((b.residual - 0.5 * b.x * b.x).abs() < 0.01, "bin at {}: {}", b.x, b.residual);
        }
    }

    #[test]
    fn too_few_samples_give_no_plot_and_bins_keep_twenty_each() {
        let x: Vec<f64> = (0..59).map(f64::from).collect();
        let z = vec![0.0; 59];
        let idx: Vec<usize> = (0..59).collect();
        assert!(binned("delay", "t", &x, &z, &z, &idx, 30).is_none());
        let x: Vec<f64> = (0..100).map(f64::from).collect();
        let z = vec![0.0; 100];
        let idx: Vec<usize> = (0..100).collect();
        let e = binned("delay", "t", &x, &z, &z, &idx, 30).unwrap();
        assert_eq!(e.bins.len(), 5);
    }

    #[test]
    fn coordinates_follow_the_vocabulary() {
        assert_eq!(Coord::of(Vocab::PositionRipple, false), Coord::Position);
        assert_eq!(Coord::of(Vocab::ThermalDrift, true), Coord::Temperature);
        assert_eq!(Coord::of(Vocab::ThermalDrift, false), Coord::Time);
        assert_eq!(Coord::of(Vocab::Stribeck, false), Coord::Velocity);
        assert_eq!(Coord::of(Vocab::LoadDependentFriction, false), Coord::Load);
        let r = rate(&[0.0, 1.0, 4.0], &[0.0, 1.0, 2.0]);
        assert_eq!(r, vec![1.0, 2.0, 3.0]);
    }
}
