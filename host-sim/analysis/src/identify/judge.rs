//! The statuses of the papers' procedures and the elastic joint's: what the plateaus, the
//! poses, the motion fit and the free oscillation determine (see [`super::status`]). The
//! regression's are in [`super::joint_ls`].

use super::status::{self, ParamStatus, Status};
use super::{friction, inertia, robust, spring, weight, Data, Identified, Term};

/// Friction and weight known for eq. 5: found when asked for (a friction fit with at least one
/// coefficient, a weight curve).
pub(super) fn friction_weight_known(out: &Identified, terms: &[Term]) -> bool {
    let f = out.friction.as_ref().is_some_and(|f| f.free.iter().any(|x| *x));
    (!terms.contains(&Term::Friction) || f) && (!terms.contains(&Term::Weight) || out.weight.is_some())
}

/// RMS of the filtered q̈ on the inertia fit's samples against its noise in the fit's band.
pub(super) fn acc_excitation(
    data: &Data,
    dat: &inertia::InertiaData,
    cutoff: f64,
    keep: &dyn Fn(usize, f64) -> bool,
) -> (f64, f64) {
    let (mut s2, mut n2, mut n) = (0.0, 0.0, 0usize);
    for (li, (acc, mask)) in dat.acc.iter().zip(&dat.mask).enumerate() {
        let p = &data.prepared[li];
        let noise = inertia::acc_noise_in_band(p, cutoff);
        for i in 0..acc.len() {
            if mask[i] && keep(li, p.t[i]) {
                s2 += acc[i] * acc[i];
                n2 += noise * noise;
                n += 1;
            }
        }
    }
    let m = n.max(1) as f64;
    ((s2 / m).sqrt(), (n2 / m).sqrt())
}

pub(super) const FRICTION_KEYS: [&str; 3] = ["a", "b", "c"];

/// The friction coefficients' statuses from the plateau fit: the curve as a whole is judged
/// by its 95 % CI at the slowest, the median and the fastest point's speed (a, b and c of one
/// curve trade off while the curve is pinned); a coefficient left out for a negative value or
/// too few distinct speeds says so.
pub(super) fn friction_status(fit: Option<&friction::FrictionFit>, n_points: usize) -> Vec<ParamStatus> {
    let test = status::TEST_FRICTION;
    let Some(f) = fit else {
        let why = format!("{n_points} friction points from matched ± constant-velocity plateaus; at least 4 needed");
        return FRICTION_KEYS.iter().map(|k| ParamStatus::not_excited("friction", k, why.clone(), test)).collect();
    };
    let speeds = friction::distinct_speeds(&f.points);
    let mut v: Vec<f64> = f.points.iter().map(|p| p.v).collect();
    v.sort_by(f64::total_cmp);
    let at = [
        v.first().copied().unwrap_or(0.0),
        v.get(v.len() / 2).copied().unwrap_or(0.0),
        v.last().copied().unwrap_or(0.0),
    ];
    let tq = robust::t_quantile_975((f.points.len() as f64 - f.free.iter().filter(|x| **x).count() as f64).max(1.0));
    let (term, why) = if !f.free.iter().any(|x| *x) {
        (
            Status::WeaklyDetermined,
            "every coefficient came out negative: the ± plateau pairs do not cancel the other torques (another \
             joint's motion, a load, a plateau still accelerating)"
                .to_string(),
        )
    } else {
        let mut res = (Status::Determined, String::new());
        let mut parts = Vec::new();
        for &x in &at {
            let (val, half) = f.curve_ci(x, tq);
            parts.push(format!("{val:.4} ± {half:.4} N·m at {x:.3} rad/s"));
            if 2.0 * half > val.abs() {
                res = (
                    Status::WeaklyDetermined,
                    format!(
                        "the curve's 95 % CI at {x:.3} rad/s (±{half:.4} N·m) is wider than its value {val:.4} N·m"
                    ),
                );
                break;
            }
        }
        if res.0 == Status::Determined {
            res.1 = format!("the curve from {} points at {speeds} speed(s): {}", f.points.len(), parts.join(", "));
        }
        res
    };
    let vals = [f.a, f.b, f.c];
    let mut first = true;
    (0..3)
        .map(|k| {
            let key = FRICTION_KEYS[k];
            if f.negative[k] && f.free.iter().any(|x| *x) {
                ParamStatus::negative("friction", key, "friction cannot feed energy in", test)
            } else if !f.free[k] && !f.negative[k] {
                ParamStatus::not_excited(
                    "friction",
                    key,
                    format!("the friction points lie at {speeds} distinct speed(s); {} needed for it", 3 - k.min(2)),
                    test,
                )
            } else {
                let why = if first || term != Status::Determined { why.clone() } else { "with the curve".to_string() };
                first = false;
                let t = (term != Status::Determined).then_some(test);
                ParamStatus {
                    term: "friction",
                    param: key,
                    value: Some(vals[k]),
                    ci95: Some(f.ci95[k]),
                    status: term,
                    why,
                    test: t,
                }
            }
        })
        .collect()
}

/// The weight as a whole (amplitude, s, φ), from the static poses: determined when the fitted
/// curve's swing over the poses stands well above their scatter.
pub(super) fn weight_status(fit: Option<&weight::WeightFit>, poses: &[weight::Pose], need: usize) -> Vec<ParamStatus> {
    let Some(w) = fit else {
        let why = format!("{} static poses; at least {need} needed", poses.len());
        return ["amplitude", "phi", "s"]
            .iter()
            .map(|k| ParamStatus::not_excited("weight", k, why.clone(), status::TEST_WEIGHT))
            .collect();
    };
    let (lo, hi) = poses.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.q), b.max(p.q)));
    let (cmin, cmax) =
        poses.iter().map(|p| w.weight(p.q)).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    let swing = cmax - cmin;
    let tq = robust::t_quantile_975(poses.len().saturating_sub(w.se.len()).max(1) as f64);
    let ci = |k: usize, v: f64| {
        let se = w.se.get(k).copied().unwrap_or(f64::NAN);
        (v - tq * se, v + tq * se)
    };
    let (status, why) = if hi - lo < 0.1 {
        (Status::NotExcited, format!("the poses cover only {:.3} rad", hi - lo))
    } else if swing > 4.0 * w.rms {
        let mut why = format!(
            "the static curve from {} poses over q ∈ [{lo:.3}, {hi:.3}] rad swings {swing:.4} N·m, residual RMS {:.4} N·m",
            poses.len(),
            w.rms
        );
        let (alo, ahi) = ci(0, w.amplitude);
        if ahi - alo > w.amplitude {
            why.push_str(
                "; amplitude, s, φ and the offset trade off over this arc (wide CIs): the curve, not each of them, is \
                 determined, and only over the covered angles",
            );
        }
        (Status::Determined, why)
    } else {
        (
            Status::WeaklyDetermined,
            format!(
                "the poses' torque varies by {swing:.4} N·m over q ∈ [{lo:.3}, {hi:.3}] rad, not well above their scatter \
                 (RMS {:.4} N·m)",
                w.rms
            ),
        )
    };
    let test = (status != Status::Determined).then_some(status::TEST_WEIGHT);
    let mut v = vec![
        ParamStatus {
            term: "weight",
            param: "amplitude",
            value: Some(w.amplitude),
            ci95: Some(ci(0, w.amplitude)),
            status,
            why: why.clone(),
            test,
        },
        ParamStatus {
            term: "weight",
            param: "phi",
            value: Some(w.phi),
            ci95: Some(ci(2, w.phi)),
            status,
            why: "with the amplitude".into(),
            test,
        },
    ];
    let s_why = if w.s_fixed {
        "fixed at 1 (the arc is too short to determine it)".to_string()
    } else {
        "with the amplitude".into()
    };
    v.push(ParamStatus {
        term: "weight",
        param: "s",
        value: Some(w.s),
        ci95: (!w.s_fixed).then(|| ci(1, w.s)),
        status,
        why: s_why,
        test,
    });
    v
}

pub(super) fn inertia_status(fit: Option<&inertia::InertiaFit>, known: bool, exc: Option<(f64, f64)>) -> ParamStatus {
    let test = status::TEST_INERTIA;
    if !known {
        return ParamStatus::not_excited(
            "inertia",
            "j",
            "eq. 5 needs friction and weight known first, and the log does not give them (see above)",
            test,
        );
    }
    let Some(f) = fit else {
        return ParamStatus::not_excited(
            "inertia",
            "j",
            "too few moving samples (|q̇| above 0.05 rad/s, not static)",
            test,
        );
    };
    if let Some((rms, noise)) = exc {
        if rms < status::ACC_EXCITATION * noise {
            return ParamStatus {
                value: Some(f.j),
                ci95: Some(f.ci95[0]),
                ..ParamStatus::not_excited(
                    "inertia",
                    "j",
                    format!("the filtered q̈ (RMS {rms:.3} rad/s²) does not stand above its noise ({noise:.3} rad/s²)"),
                    test,
                )
            };
        }
    }
    if !(f.j > 0.0) {
        return ParamStatus {
            value: Some(f.j),
            ci95: Some(f.ci95[0]),
            status: Status::WeaklyDetermined,
            why: format!("the fit gives J = {:.4} kg·m², not positive: the log's torque holds no J·q̈ it can see", f.j),
            test: Some(test),
            term: "inertia",
            param: "j",
        };
    }
    ParamStatus::from_ci("inertia", "j", f.j, f.ci95[0], None, test)
}

/// C_0 of the papers: the static curve's constant plus the motion fit's ΔC_0 (or the mean of
/// the poses when there is no inertia fit), with its CI.
pub(super) fn offset_papers(out: &Identified, with_inertia: bool) -> (Option<f64>, ParamStatus) {
    let w = out.weight.as_ref().filter(|w| w.fitted_offset);
    let stat = w.map(|w| w.c0).or(out.c0.filter(|_| !with_inertia || out.weight.is_none()));
    let tq_w = robust::t_quantile_975(out.poses.len().saturating_sub(4).max(1) as f64);
    let stat_half = match w {
        Some(w) => w.se.get(3).map_or(f64::NAN, |se| tq_w * se),
        None if !out.poses.is_empty() => {
            let n = out.poses.len() as f64;
            let m = out.poses.iter().map(|p| p.d).sum::<f64>() / n;
            let sd = (out.poses.iter().map(|p| (p.d - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
            robust::t_quantile_975((n - 1.0).max(1.0)) * sd / n.sqrt()
        }
        None => f64::NAN,
    };
    let dynamic = out.inertia.as_ref().filter(|i| i.j > 0.0).map(|i| (i.dc0, 0.5 * (i.ci95[1].1 - i.ci95[1].0)));
    let (c0, half) = match (stat, dynamic) {
        (Some(s), Some((d, h))) => (s + d, stat_half.hypot(h)),
        (Some(s), None) => (s, stat_half),
        (None, Some((d, h))) => (d, h),
        (None, None) => {
            return (
                None,
                ParamStatus::not_excited(
                    "offset",
                    "c0",
                    "no static poses and no usable motion fit",
                    status::TEST_OFFSET,
                ),
            )
        }
    };
    let ci = (c0 - half, c0 + half);
    // With the weight fitted together with a constant, the poses determine their sum (the static
    // curve), not how it splits: the constant is judged with the curve, not on its own CI.
    let curve = out.status.iter().find(|p| p.term == "weight" && p.param == "amplitude");
    if let (Some(_), Some(cs)) = (w, curve) {
        let mut st = ParamStatus::from_ci("offset", "c0", c0, ci, None, status::TEST_OFFSET);
        st.status = cs.status;
        st.test = (cs.status != Status::Determined).then_some(status::TEST_OFFSET);
        st.why = format!(
            "the static curve's constant{}, judged with the weight: the poses determine weight + offset together \
             (95 % CI of the constant alone [{:.4}, {:.4}])",
            if dynamic.is_some() { " plus ΔC_0 from motion" } else { "" },
            ci.0,
            ci.1
        );
        return (Some(c0), st);
    }
    (Some(c0), ParamStatus::from_ci("offset", "c0", c0, ci, None, status::TEST_OFFSET))
}

pub(super) fn spring_status(
    stat: Option<&spring::StaticSpring>,
    free: Option<&spring::FreeFit>,
    n_poses: usize,
    j: Option<f64>,
    b: Option<f64>,
) -> Vec<ParamStatus> {
    let mut v = Vec::new();
    match stat {
        Some(s) => {
            let why = format!(
                "static torque–angle slope of {} + {} poses (paper: mean of the two branches)",
                s.poses_pos, s.poses_neg
            );
            let two = s.poses_pos >= 2 && s.poses_neg >= 2;
            let status = if two { Status::Determined } else { Status::WeaklyDetermined };
            let why = if two { why } else { format!("{why}; one torque branch only") };
            let test = (!two).then_some(status::TEST_SPRING_K);
            for (param, value) in [("k", s.k), ("q0", s.q0)] {
                v.push(ParamStatus {
                    term: "spring",
                    param,
                    value: Some(value),
                    ci95: None,
                    status,
                    why: why.clone(),
                    test,
                });
            }
        }
        None => {
            let why = format!("{n_poses} static poses with torque, no torque–angle branch of 2 poses");
            for p in ["k", "q0"] {
                v.push(ParamStatus::not_excited("spring", p, why.clone(), status::TEST_SPRING_K));
            }
        }
    }
    let k_ok = v.first().is_some_and(|p| p.determined());
    for (term, param, value) in [("spring", "b", b), ("inertia", "j", j)] {
        v.push(match (free, value) {
            (Some(f), Some(x)) if k_ok => ParamStatus {
                term,
                param,
                value: Some(x),
                ci95: None,
                status: Status::Determined,
                why: format!("free oscillation ω_n = {:.4} rad/s, ζ = {:.4} with K", f.omega_n, f.zeta),
                test: None,
            },
            (Some(f), _) => ParamStatus::not_excited(
                term,
                param,
                format!(
                    "the free oscillation gives ω_n = {:.4} rad/s and ζ = {:.4} only; J = K/ω_n² and B = 2ζω_n·J need K",
                    f.omega_n, f.zeta
                ),
                status::TEST_SPRING_K,
            ),
            (None, _) => ParamStatus::not_excited(
                term,
                param,
                "no free oscillation (a trajectory-mode log, or --window START:END:free)",
                status::TEST_SPRING_JB,
            ),
        });
    }
    v
}
