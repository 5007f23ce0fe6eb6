//! Where a free response begins: a log with no input cannot gain energy, so a log that does
//! starts before the release (a hand still pushing, a release that is not at rest).
//!
//! The energy per unit inertia is `e = ½q̇² + κ·V(q)`, with `V` the file's restoring law per
//! inertia (its weight, spring and constant: `V' = −restoring/J`) and `κ` a scale regressed from
//! the log, `q̈ = κ·r(q) + γ₁·q̇ + γ₂·sign(q̇)`, since the file's J or weight may be a guess (the
//! shape is what the diagnosis tests, not this check). A gain is believed beyond 10 % of the
//! energy, twice the share of q̈ the regression misses beyond q̈'s own error, and the noise of
//! the kinetic term.
//!
//! Only the first swing of an oscillating log is searched (up to its second reversal, at most a
//! quarter of the log), from where the preparation's smoother has both sides of a sample: a
//! release is at the start, and a gain later in a log is a model error as often as a push.

use crate::diagnose::candidates::Col;
use crate::identify::robust::ols;

use super::terms::Layout;

/// A start that gains energy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Release {
    /// the sample (within the window) where the energy peaks: the free response starts there
    pub at: usize,
    /// the energy's gain from the first sample to `at`, as a share of its value at `at`
    pub gain: f64,
    /// the smallest gain that would have been believed, same units
    pub tol: f64,
}

/// The release of a free response over `q, qd, qdd` (the prepared columns of the window) with
/// their errors (`lay` laid out over the same `q`: its `qmin, qmax` are the angles travelled), or `None` when the log does not oscillate or its energy does not rise beyond
/// what the model's error and the noise allow. `moving[i]`: the sample is neither at rest nor of
/// unknown direction; `edge`: samples at the log's start whose derivatives are one-sided.
pub fn find(
    lay: &Layout,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    err: (&[f64], &[f64]),
    moving: &[bool],
    edge: usize,
) -> Option<Release> {
    let (qd_err, qdd_err) = err;
    let n = q.len();
    // the file's restoring torque per inertia, and its potential (V' = −r)
    let cons: Vec<(Col, f64)> = lay
        .cols
        .iter()
        .zip(&lay.beta0)
        .filter(|(c, _)| matches!(c, Col::SinSq(_) | Col::CosSq(_) | Col::Q | Col::Const))
        .map(|(c, b)| (*c, *b / lay.j))
        .collect();
    if n < 50 || !(lay.j > 0.0) || cons.iter().all(|(c, _)| *c == Col::Const) {
        return None;
    }
    let r = |x: f64| -> f64 {
        -cons
            .iter()
            .map(|&(c, b)| {
                b * match c {
                    Col::SinSq(s) => libm::sin(s * x),
                    Col::CosSq(s) => libm::cos(s * x),
                    Col::Q => x,
                    _ => 1.0,
                }
            })
            .sum::<f64>()
    };
    let v = |x: f64| -> f64 {
        cons.iter()
            .map(|&(c, b)| {
                b * match c {
                    Col::SinSq(s) => -libm::cos(s * x) / s,
                    Col::CosSq(s) => libm::sin(s * x) / s,
                    Col::Q => 0.5 * x * x,
                    _ => x,
                }
            })
            .sum::<f64>()
    };
    // the first swing: from the edge to the second reversal, at most a quarter of the log
    let first = (edge..n / 4).find(|&i| moving[i])?;
    let mut reversals = 0;
    let mut end = None;
    let mut last = 0.0f64;
    for i in first..n / 4 {
        if !moving[i] {
            continue;
        }
        let sg = qd[i].signum();
        if last != 0.0 && sg != last {
            reversals += 1;
            if reversals == 2 {
                end = Some(i);
                break;
            }
        }
        last = sg;
    }
    let end = end?;
    let rows: Vec<usize> = (edge..n).filter(|&i| moving[i]).collect();
    if rows.len() < 50 {
        return None;
    }
    let x = [
        rows.iter().map(|&i| r(q[i])).collect::<Vec<f64>>(),
        rows.iter().map(|&i| qd[i]).collect(),
        rows.iter().map(|&i| qd[i].signum()).collect(),
    ];
    let y: Vec<f64> = rows.iter().map(|&i| qdd[i]).collect();
    let fit = ols(&[&x[0], &x[1], &x[2]], &y)?;
    let kappa = fit.beta[0];
    // a restoring law the log does not confirm (reversed, or not resolved) measures no energy
    if !(kappa > 0.0) || fit.se[0] > 0.1 * kappa {
        return None;
    }
    let y_rms = (y.iter().map(|v| v * v).sum::<f64>() / y.len() as f64).sqrt();
    let err2 = rows.iter().map(|&i| qdd_err[i] * qdd_err[i]).sum::<f64>() / rows.len() as f64;
    let misfit = (fit.sigma * fit.sigma - err2).max(0.0).sqrt() / y_rms.max(1e-300);
    let e = |i: usize| 0.5 * qd[i] * qd[i] + kappa * v(q[i]);
    // the energy's zero: the bottom of the potential over the angles travelled (V is defined
    // up to a constant)
    let (lo, hi) = (lay.qmin, lay.qmax);
    let e_min = (0..=400).map(|k| kappa * v(lo + (hi - lo) * k as f64 / 400.0)).fold(f64::INFINITY, f64::min);
    let (at, e_at) =
        (first..end).filter(|&i| moving[i]).map(|i| (i, e(i) - e_min)).max_by(|a, b| a.1.total_cmp(&b.1))?;
    let e0 = e(first) - e_min;
    if !(e_at > 0.0) || at <= first {
        return None;
    }
    let gain = (e_at - e0) / e_at;
    let noise = 3.0 * (qd[first].abs() * qd_err[first]).hypot(qd[at].abs() * qd_err[at]) / e_at;
    let tol = (2.0 * misfit).max(0.1).max(noise);
    (gain > tol).then_some(Release { at, gain, tol })
}
