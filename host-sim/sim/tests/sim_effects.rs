//! The simulated joint: with no effect the residual against the same model is sensor noise,
//! and each effect section changes the log the way its definition (src/effects.rs) says.
//! Effects are checked on noise-free plants so the assertions can be tight.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

mod common;

use common::{mean, rms, sign, trunk};
use host_sim::scenario::ScenarioKind::{Free, Hand, Poses, Sweep};

#[test]
fn no_effect_noise_free_plant_matches_the_model() {
    let r = trunk("", &[Sweep, Poses, Hand], 8.0);
    assert!(rms(&r.resid) < 0.02, "residual {} N·m", rms(&r.resid));
    assert!(rms(r.log.u.as_ref().unwrap()) > 1.0, "the joint was actually driven");
}

#[test]
fn no_effect_residual_is_at_the_noise_floor() {
    let plant = common::example("examples/plants/trunk-right.toml");
    let r = common::run_with(&plant, &common::trunk_model(), &[Sweep, Poses, Hand], 10.0, 3);
    let floor = r.floor.unwrap();
    let res = rms(&r.resid);
    // The floor from the sensor settings alone: load cell 0.15, u 0.1, J·qdd 0.12 N·m, …
    assert!(floor > 0.2 && floor < 0.6, "floor {floor}");
    assert!(res / floor > 0.85 && res / floor < 1.2, "residual {res} vs floor {floor}");
}

#[test]
fn same_seed_same_bytes() {
    let plant = common::example("examples/plants/trunk-right-thermal-drift.toml");
    let bytes = |seed| {
        let r = common::run_with(&plant, &common::trunk_model(), &[Hand, Sweep], 2.0, seed);
        let mut b = Vec::new();
        r.log.write_csv(&mut b).unwrap();
        b
    };
    assert_eq!(bytes(5), bytes(5));
    assert_ne!(bytes(5), bytes(6));
}

#[test]
fn stribeck_raises_friction_at_low_speed_only() {
    let r = trunk("[stribeck]\nlevel = 1.5\nspeed = 0.05\n", &[Sweep], 20.0);
    let qd = r.log.qd.as_ref().unwrap();
    let low =
        mean(qd.iter().zip(&r.resid).filter(|(v, _)| v.abs() > 0.012 && v.abs() < 0.03).map(|(v, e)| e * sign(*v)));
    let high = mean(qd.iter().zip(&r.resid).filter(|(v, _)| v.abs() > 0.3).map(|(v, e)| e * sign(*v)));
    assert!(low > 0.6 * 1.5 * (-0.36f64).exp(), "low-speed excess {low}");
    assert!(high.abs() < 0.02, "high-speed excess {high}");
}

#[test]
fn asymmetric_friction_differs_by_direction() {
    let r = trunk("[asymmetric_friction]\ndelta = 0.8\n", &[Sweep], 10.0);
    let qd = r.log.qd.as_ref().unwrap();
    let fwd = mean(qd.iter().zip(&r.resid).filter(|(v, _)| **v > 0.05).map(|(_, e)| *e));
    let back = mean(qd.iter().zip(&r.resid).filter(|(v, _)| **v < -0.05).map(|(_, e)| *e));
    // friction magnitude c+delta forward, c−delta backward: residual·sign(qd) = ±delta
    assert!((fwd - 0.8).abs() < 0.05, "forward {fwd}");
    assert!((-back - -0.8).abs() < 0.05, "backward {back}");
}

#[test]
fn load_dependent_friction_grows_with_the_external_load() {
    // μ·|τ_ext|·sgn(q̇): the load the joint transmits, which the log has as `tau` (= −τ_ext)
    let r = trunk("[load_dependent_friction]\nmu = 0.1\n", &[Hand], 10.0);
    let (qd, tau) = (r.log.qd.as_ref().unwrap(), r.log.tau.as_ref().unwrap());
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for i in 0..qd.len() {
        if qd[i].abs() > 0.05 {
            sxy += r.resid[i] * sign(qd[i]) * tau[i].abs();
            sxx += tau[i] * tau[i];
        }
    }
    let mu = sxy / sxx;
    assert!((mu - 0.1).abs() < 0.01, "fitted mu {mu}");
}

#[test]
fn thermal_drift_scales_friction_with_temperature() {
    let text =
        "[thermal_drift]\ncoefficient = -0.01\nt_ambient = 25.0\nrise = 30.0\ntime_constant = 5.0\nt_ref = 25.0\n";
    let r = trunk(text, &[Sweep], 20.0);
    let temp = r.log.temp.as_ref().expect("temp column");
    assert!(temp[0] < 25.1 && *temp.last().unwrap() > 54.0, "temperature rises");
    let qd = r.log.qd.as_ref().unwrap();
    // residual = coefficient·(T − t_ref)·friction(qd)
    let fr = |v: f64| 1.8941792639567765 * v * v.abs() + 8.938141604040842 * v + 2.32 * sign(v);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for i in 0..qd.len() {
        if qd[i].abs() > 0.05 {
            let x = (temp[i] - 25.0) * fr(qd[i]);
            sxy += r.resid[i] * x;
            sxx += x * x;
        }
    }
    assert!((sxy / sxx - -0.01).abs() < 0.001, "fitted coefficient {}", sxy / sxx);
    let early = mean((0..2000).filter(|&i| qd[i].abs() > 0.05).map(|i| r.resid[i] * sign(qd[i])));
    let late = mean((18000..20000).filter(|&i| qd[i].abs() > 0.05).map(|i| r.resid[i] * sign(qd[i])));
    assert!(late < early - 0.3, "friction falls as the joint warms: early {early}, late {late}");
}

#[test]
fn position_ripple_has_the_set_period_in_q() {
    let r = trunk("[position_ripple]\namplitude = 0.6\nperiod = 0.0785\nphase = 0.5\n", &[Sweep], 10.0);
    // Least-squares fit e ≈ A·sin(2πq/P) + B·cos(2πq/P); share of the residual's power explained.
    let fit = |period: f64| {
        let (mut ss, mut cc, mut sc, mut es, mut ec, mut ee) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for (q, e) in r.log.q.iter().zip(&r.resid) {
            let a = std::f64::consts::TAU * q / period;
            let (s, c) = (a.sin(), a.cos());
            ss += s * s;
            cc += c * c;
            sc += s * c;
            es += e * s;
            ec += e * c;
            ee += e * e;
        }
        let det = ss * cc - sc * sc;
        let (a, b) = ((es * cc - ec * sc) / det, (ec * ss - es * sc) / det);
        ((a * a + b * b).sqrt(), (a * es + b * ec) / ee)
    };
    let (amp, share) = fit(0.0785);
    assert!((amp - 0.6).abs() < 0.03 && share > 0.95, "at the set period: amplitude {amp}, explained {share}");
    let (_, s1) = fit(0.0785 * 1.37);
    let (_, s2) = fit(0.0785 * 0.61);
    assert!(s1 < 0.2 && s2 < 0.2, "other periods explain {s1}, {s2}");
}

#[test]
fn cable_spring_is_zero_below_engage_and_has_slope_k_above() {
    let r = trunk("[cable_spring]\nk = 6.0\nengage = 1.2\nwidth = 0.01\n", &[Sweep, Poses], 10.0);
    let q = &r.log.q;
    let below: Vec<f64> = q.iter().zip(&r.resid).filter(|(q, _)| **q < 1.19).map(|(_, e)| *e).collect();
    assert!(below.len() > 1000 && rms(&below) < 0.02, "below engage {} ({} samples)", rms(&below), below.len());
    let pts: Vec<(f64, f64)> = q.iter().zip(&r.resid).filter(|(q, _)| **q > 1.22).map(|(q, e)| (*q, *e)).collect();
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let slope =
        pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / pts.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    assert!((slope - 6.0).abs() < 0.3, "slope above engage {slope}");
    let offset = my - slope * (mx - 1.2);
    assert!((offset + 6.0 * 0.005).abs() < 0.01, "k·(q − engage − width/2): {offset}");
}

#[test]
fn dry_friction_adds_a_constant_magnitude() {
    let r = trunk("[dry_friction]\nc = 1.0\n", &[Sweep], 10.0);
    let qd = r.log.qd.as_ref().unwrap();
    let ex: Vec<f64> = qd.iter().zip(&r.resid).filter(|(v, _)| v.abs() > 0.05).map(|(v, e)| e * sign(*v)).collect();
    let m = mean(ex.iter().copied());
    assert!((m - 1.0).abs() < 0.03, "mean {m}");
    let sd = (ex.iter().map(|x| (x - m).powi(2)).sum::<f64>() / ex.len() as f64).sqrt();
    assert!(sd < 0.05, "constant magnitude, spread {sd}");
}

#[test]
fn delay_shifts_the_measured_disturbance_by_the_lag() {
    // What the sensors say the actuator gave: tau + model(q, qd, qdd) = u(t − delay).
    let peak = |extra: &str| {
        let r = trunk(extra, &[Hand], 6.0);
        let u = r.log.u.as_ref().unwrap();
        let seen: Vec<f64> = u.iter().zip(&r.resid).map(|(u, e)| u - e).collect();
        // Differences whiten the smooth torques so the correlation peak is sharp.
        let du: Vec<f64> = u.windows(2).map(|w| w[1] - w[0]).collect();
        let ds: Vec<f64> = seen.windows(2).map(|w| w[1] - w[0]).collect();
        let n = du.len();
        let corr = |lag: usize| (lag..n).map(|i| du[i - lag] * ds[i]).sum::<f64>() / (n - lag) as f64;
        (0..40).max_by(|a, b| corr(*a).total_cmp(&corr(*b))).unwrap()
    };
    let (p0, p1) = (peak(""), peak("[delay]\nseconds = 0.01\n"));
    assert_eq!((p0, p1), (0, 10));
}

#[test]
fn backlash_in_the_spring_is_a_dead_zone() {
    // Elastic joint, hand-moved: the true spring is k·dz(q − q0), the model's k·(q − q0).
    let model = common::example("examples/models/elastic-joint.toml");
    let plant = "[spring]\nk = 7.3035\nb = 0.0416\n[inertia]\nj = 0.0085\n[joint_range]\nmin = -0.5\nmax = 0.5\n[backlash]\nwidth = 0.1\n";
    let r = common::run_with(plant, &model, &[Hand], 8.0, 2);
    let q = &r.log.q;
    let inside = mean(q.iter().zip(&r.resid).filter(|(q, _)| q.abs() < 0.04).map(|(q, e)| e + 7.3035 * q));
    assert!(inside.abs() < 0.02, "inside the gap the spring is absent: {inside}");
    let outside = mean(q.iter().zip(&r.resid).filter(|(q, _)| q.abs() > 0.06).map(|(q, e)| e * sign(*q)));
    assert!((outside + 7.3035 * 0.05).abs() < 0.02, "outside it is shifted by k·width/2: {outside}");
}

#[test]
fn backlash_in_the_transmission_shows_at_reversals() {
    let zone = |extra: &str| {
        let r = trunk(extra, &[Sweep], 10.0);
        let qd = r.log.qd.as_ref().unwrap();
        let mut near = vec![false; qd.len()];
        for i in 1..qd.len() {
            if qd[i - 1].signum() != qd[i].signum() {
                for flag in near.iter_mut().take((i + 150).min(qd.len())).skip(i.saturating_sub(150)) {
                    *flag = true;
                }
            }
        }
        let pick =
            |want: bool| r.resid.iter().zip(&near).filter(|(_, n)| **n == want).map(|(e, _)| *e).collect::<Vec<_>>();
        (rms(&pick(true)), rms(&pick(false)))
    };
    let (rev, steady) = zone("[backlash]\nwidth = 0.02\n");
    let (rev0, _) = zone("");
    assert!(
        rev > 0.2 && rev > 5.0 * steady && rev > 5.0 * rev0,
        "reversal {rev}, steady {steady}, without backlash {rev0}"
    );
}

#[test]
fn free_release_of_the_elastic_joint_oscillates_at_the_models_frequency() {
    let model = common::example("examples/models/elastic-joint.toml");
    let plant = common::example("examples/plants/elastic-joint-ideal.toml");
    let r = common::run_with(&plant, &model, &[Free], 3.0, 1);
    let q = &r.log.q;
    assert!((q[0] - 0.2618).abs() < 0.002, "released at 75 % of ±30°: {}", q[0]);
    // Zero crossings of q give the damped period 2π/(ω_n·√(1−ζ²)).
    let cross: Vec<f64> = (1..1500).filter(|&i| q[i - 1] > 0.0 && q[i] <= 0.0).map(|i| r.log.t[i]).collect();
    let (k, b, j): (f64, f64, f64) = (7.3035, 0.0416, 0.0085);
    let wn = (k / j).sqrt();
    let zeta = b / (2.0 * (k * j).sqrt());
    let period = std::f64::consts::TAU / (wn * (1.0 - zeta * zeta).sqrt());
    let measured = (cross.last().unwrap() - cross[0]) / (cross.len() - 1) as f64;
    assert!((measured / period - 1.0).abs() < 0.01, "period {measured} vs {period}");
}
