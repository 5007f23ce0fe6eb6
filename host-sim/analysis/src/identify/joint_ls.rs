//! What the whole-log regression ([`inertia::joint_ls`]) determines.
//!
//! One least-squares fit on every sample gives every rigid term a value, whether the log moves
//! it or not. Each term is judged in this order: *not excited* when the log has nothing that
//! drives it (no acceleration above its noise for J, no motion for friction, one direction only
//! for the Coulomb term, a short arc for the weight); *weakly determined* when the other terms'
//! columns explain the torque it contributes over this log (variance inflation factor above
//! [`status::VIF_COLLINEAR`] — a pendulum swinging almost freely has `J·q̈ ≈ −m·g·l·sin q`, so J
//! and the weight are only determined as their ratio), or when its CI is wider than its value
//! (for friction: the curve's CI at the log's speeds, since a, b and c of one curve may trade off
//! while the curve is pinned); *determined* otherwise. A coefficient that came out negative
//! where the physics wants it ≥ 0 is left out and the others refitted without it.
//!
//! The determined terms keep the values of the full regression: refitting without an
//! undetermined term would push its torque into the terms it is collinear with.
//!
//! [`inertia::joint_ls`]: super::inertia::joint_ls

use super::inertia::{JointLsFit, JOINT_LS_TERMS};
use super::robust;
use super::status::{self, ParamStatus, Status};
use super::Term;

/// The t quantile of the fit's 95 % intervals (the degrees of freedom are the independent
/// samples: the filter correlates neighbours).
fn tq(f: &JointLsFit, fs: f64) -> f64 {
    let dof = f.n as f64 * (2.0 * f.cutoff_hz / fs).min(1.0) - 7.0;
    robust::t_quantile_975(dof.max(1.0))
}

/// 95 % CI of column `k` at value `v`.
pub fn ci(f: &JointLsFit, fs: f64, k: usize, v: f64) -> (f64, f64) {
    let t = tq(f, fs);
    (v - t * f.se[k], v + t * f.se[k])
}

/// Amplitude and phase of `α·sin q + β·cos q` with their standard errors (delta method).
pub fn amplitude_phase(f: &JointLsFit) -> (f64, f64, f64, f64) {
    let (a, b) = (f.alpha, f.beta);
    let amp = a.hypot(b);
    let (va, vb, cab) = (f.cov[4][4], f.cov[5][5], f.cov[4][5]);
    if !(amp > 0.0) {
        return (0.0, 0.0, va.max(vb).max(0.0).sqrt(), f64::NAN);
    }
    let se_amp = ((a * a * va + b * b * vb + 2.0 * a * b * cab) / (amp * amp)).max(0.0).sqrt();
    let se_phi = ((b * b * va + a * a * vb - 2.0 * a * b * cab).max(0.0)).sqrt() / (amp * amp);
    (amp, b.atan2(a), se_amp, se_phi)
}

fn collinear(f: &JointLsFit, t: usize) -> Option<String> {
    (f.gvif[t] > status::VIF_COLLINEAR).then(|| {
        let (o, r) = f.partner[t];
        format!(
            "collinear with the {} term over this log (the other terms explain its torque: VIF {:.0}, correlation \
             {:+.2}): only their combination is determined",
            JOINT_LS_TERMS.get(o).map_or("?", |x| x.0),
            f.gvif[t],
            r
        )
    })
}

fn inertia(f: &JointLsFit, fs: f64) -> ParamStatus {
    let test = status::TEST_INERTIA;
    if f.acc_rms < status::ACC_EXCITATION * f.acc_noise {
        return ParamStatus::not_excited(
            "inertia",
            "j",
            format!(
                "the filtered q̈ (RMS {:.3} rad/s²) does not stand above its noise in the fit's band ({:.3} rad/s²)",
                f.acc_rms, f.acc_noise
            ),
            test,
        );
    }
    if f.negative[0] {
        return ParamStatus::negative("inertia", "j", "inertia cannot be negative", test);
    }
    ParamStatus::from_ci("inertia", "j", f.j, ci(f, fs, 0, f.j), collinear(f, 0), test)
}

/// The friction curve as a whole: its 95 % CI at the 10th, 50th and 90th percentile of the
/// log's speeds against its value there.
fn friction(f: &JointLsFit, fs: f64) -> Vec<ParamStatus> {
    let test = status::TEST_FRICTION;
    let keys = ["a", "b", "c"];
    if f.speeds[2] < 0.03 {
        let why = format!("the joint does not move (90 % of |q̇| below {:.4} rad/s)", f.speeds[2]);
        return keys.iter().map(|k| ParamStatus::not_excited("friction", k, why.clone(), test)).collect();
    }
    let free: Vec<usize> = (1..=3).filter(|&k| f.free[k] && (k != 3 || f.both_ways)).collect();
    let t = tq(f, fs);
    let beta = [f.a, f.b, f.c];
    let mut term: (Status, String) = match collinear(f, 1) {
        Some(why) => (Status::WeaklyDetermined, why),
        None if free.is_empty() => (Status::WeaklyDetermined, "no coefficient left".into()),
        None => (Status::Determined, String::new()),
    };
    if term.0 == Status::Determined {
        let mut worst = Vec::new();
        for v in f.speeds {
            let g = [v * v, v, 1.0];
            let val: f64 = free.iter().map(|&k| beta[k - 1] * g[k - 1]).sum();
            let var: f64 = free
                .iter()
                .flat_map(|&i| free.iter().map(move |&j| (i, j)))
                .map(|(i, j)| g[i - 1] * g[j - 1] * f.cov[i][j])
                .sum();
            let half = t * var.max(0.0).sqrt();
            worst.push(format!("{val:.4} ± {half:.4} N·m at {v:.3} rad/s"));
            if 2.0 * half > val.abs() {
                term = (
                    Status::WeaklyDetermined,
                    format!(
                        "the curve's 95 % CI at {v:.3} rad/s (±{half:.4} N·m) is wider than its value {val:.4} N·m"
                    ),
                );
                break;
            }
        }
        if term.0 == Status::Determined {
            term.1 = format!("the curve over the log's speeds: {}", worst.join(", "));
        }
    }
    let mut first = true;
    (1..=3)
        .map(|k| {
            let key = keys[k - 1];
            if k == 3 && !f.both_ways {
                ParamStatus::not_excited(
                    "friction",
                    key,
                    "no reversals: the joint moves one way only, so c·sign(q̇) is a constant the offset takes",
                    test,
                )
            } else if f.negative[k] {
                ParamStatus::negative("friction", key, "friction cannot feed energy in", test)
            } else {
                let why = if first { term.1.clone() } else { "with the curve".to_string() };
                first = false;
                let test = (term.0 != Status::Determined).then_some(test);
                ParamStatus {
                    term: "friction",
                    param: key,
                    value: Some(beta[k - 1]),
                    ci95: Some(ci(f, fs, k, beta[k - 1])),
                    status: term.0,
                    why,
                    test,
                }
            }
        })
        .collect()
}

fn weight(f: &JointLsFit, fs: f64) -> Vec<ParamStatus> {
    let test = status::TEST_WEIGHT;
    if f.q_span < 0.2 {
        let why = format!("q covers only {:.3} rad: sin q and cos q are not told apart from the offset", f.q_span);
        return ["amplitude", "phi", "s"]
            .iter()
            .map(|k| ParamStatus::not_excited("weight", k, why.clone(), test))
            .collect();
    }
    let (amp, phi, se_amp, se_phi) = amplitude_phase(f);
    let t = tq(f, fs);
    let a =
        ParamStatus::from_ci("weight", "amplitude", amp, (amp - t * se_amp, amp + t * se_amp), collinear(f, 2), test);
    let test = (a.status != Status::Determined).then_some(test);
    let p = ParamStatus {
        term: "weight",
        param: "phi",
        value: Some(phi),
        ci95: Some((phi - t * se_phi, phi + t * se_phi)),
        status: a.status,
        why: "with the amplitude".into(),
        test,
    };
    let s = ParamStatus {
        term: "weight",
        param: "s",
        value: Some(1.0),
        ci95: None,
        status: a.status,
        why: "fixed at 1 (the regression's sin q, cos q)".into(),
        test,
    };
    vec![a, p, s]
}

/// The statuses of the terms asked for.
pub fn statuses(f: &JointLsFit, fs: f64, terms: &[Term]) -> Vec<ParamStatus> {
    let mut v = Vec::new();
    if terms.contains(&Term::Inertia) {
        v.push(inertia(f, fs));
    }
    if terms.contains(&Term::Friction) {
        v.extend(friction(f, fs));
    }
    if terms.contains(&Term::Weight) {
        v.extend(weight(f, fs));
    }
    if terms.contains(&Term::Offset) {
        v.push(ParamStatus::from_ci("offset", "c0", f.c0, ci(f, fs, 6, f.c0), None, status::TEST_OFFSET));
    }
    v
}

/// When J and the weight are collinear (a pendulum swinging nearly freely: `J·q̈ ≈ −A·sin q`),
/// the log determines their ratio A/J (= g/l for a point mass at l); a note saying so.
pub fn ratio_note(f: &JointLsFit) -> Option<String> {
    let (amp, _, _, _) = amplitude_phase(f);
    let pair = f.gvif[0] > status::VIF_COLLINEAR && f.partner[0].0 == 2;
    (pair && f.j > 0.0 && amp > 0.0).then(|| {
        let r = amp / f.j;
        format!(
            "J and the weight are collinear over this log: what it determines is their ratio A/J = {r:.2} 1/s² \
             (a pendulum's m·g·l/J = g/l: a point mass at l = {:.3} m)",
            9.81 / r
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn amplitude_and_phase_errors_by_the_delta_method() {
        let mut cov = [[0.0; 7]; 7];
        cov[4][4] = 0.01;
        cov[5][5] = 0.01;
        let f = JointLsFit {
            j: 0.0,
            a: 0.0,
            b: 0.0,
            c: 0.0,
            alpha: 3.0,
            beta: 4.0,
            c0: 0.0,
            se: [0.0, 0.0, 0.0, 0.0, 0.1, 0.1, 0.0],
            cov,
            gvif: [0.0; 3],
            partner: [(0, 0.0); 3],
            free: [true; 7],
            negative: [false; 7],
            acc_rms: 1.0,
            acc_noise: 0.0,
            q_span: 1.0,
            speeds: [0.1, 0.5, 1.0],
            both_ways: true,
            rms: 0.0,
            r2: 1.0,
            n: 1000,
            cutoff_hz: 5.0,
        };
        let (amp, phi, se_amp, se_phi) = amplitude_phase(&f);
        assert!((amp - 5.0).abs() < 1e-12 && (phi - 4f64.atan2(3.0)).abs() < 1e-12);
        // uncorrelated, equal errors: the amplitude's error is theirs, the phase's that over A
        assert!((se_amp - 0.1).abs() < 1e-12 && (se_phi - 0.02).abs() < 1e-12);
    }
}
