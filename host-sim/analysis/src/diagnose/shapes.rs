//! The shapes the candidates fit, written here and nowhere else in the analysis.
//!
//! The simulator's plant has its own effect code; the two are kept apart on purpose: a bench
//! whose effects came from the same functions the candidates fit could only ever agree with
//! itself. The parametrisation is the one `--emit-model` writes (so an emitted section means
//! to the plant what it meant to the fit); the code is this module's.

/// Dead zone of total width `w` centred on 0: a backlash gap in an elastic element.
pub fn dead_zone(x: f64, w: f64) -> f64 {
    let h = w / 2.0;
    if x > h {
        x - h
    } else if x < -h {
        x + h
    } else {
        0.0
    }
}

/// A cable or harness that engages at `engage` and goes from slack to stiffness `k` over
/// `width` (a quadratic blend, so the torque and its slope are continuous).
pub fn engaged_spring(k: f64, engage: f64, width: f64, q: f64) -> f64 {
    let x = q - engage;
    if x <= 0.0 {
        0.0
    } else if x < width {
        k * x * x / (2.0 * width)
    } else {
        k * (x - width / 2.0)
    }
}

/// A pad or strap that presses over a range of angles only: 1 at `centre`, falling to 0 at
/// `centre ± half` as a raised cosine (value and slope continuous), 0 beyond.
pub fn pad(centre: f64, half: f64, q: f64) -> f64 {
    let z = (q - centre) / half;
    if z.abs() >= 1.0 {
        0.0
    } else {
        0.5 * (1.0 + (std::f64::consts::PI * z).cos())
    }
}

/// One step of the normalised Dahl state z = F/c over travel `dq`: the exact solution of
/// dz/dq = κ·(1 − z·sign(dq)), an exponential approach to ±1 (so |z| ≤ 1 for any step).
pub fn dahl_step(z: f64, kappa: f64, dq: f64) -> f64 {
    // Once saturated in the direction of travel (exactly ±1) the state stays there: no exp.
    if dq > 0.0 && z < 1.0 {
        1.0 - (1.0 - z) * (-kappa * dq).exp()
    } else if dq < 0.0 && z > -1.0 {
        -1.0 + (1.0 + z) * (kappa * dq).exp()
    } else {
        z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dead_zone_is_zero_inside_and_shifted_outside() {
        assert_eq!(dead_zone(0.004, 0.01), 0.0);
        assert_eq!(dead_zone(-0.005, 0.01), 0.0);
        assert!((dead_zone(0.02, 0.01) - 0.015).abs() < 1e-15);
        assert!((dead_zone(-0.02, 0.01) + 0.015).abs() < 1e-15);
    }

    #[test]
    fn dahl_steps_compose_and_stay_bounded() {
        // rate independence: one step of 2δ equals two of δ
        let (k, z0) = (800.0, -0.3);
        let two = dahl_step(dahl_step(z0, k, 1e-3), k, 1e-3);
        assert!((two - dahl_step(z0, k, 2e-3)).abs() < 1e-12);
        // a long travel saturates at the sign, a reversal starts back from where it was
        assert!((dahl_step(z0, k, 1.0) - 1.0).abs() < 1e-12);
        assert!(dahl_step(1.0, k, -1e-4) < 1.0 && dahl_step(1.0, k, -1e-4) > 0.8);
        for dq in [-10.0, -1e-3, 0.0, 1e-3, 10.0] {
            assert!(dahl_step(0.99, 1e6, dq).abs() <= 1.0);
        }
    }

    #[test]
    fn a_pad_presses_inside_its_range_only() {
        assert_eq!(pad(0.3, 0.1, 0.3), 1.0);
        assert_eq!(pad(0.3, 0.1, 0.45), 0.0);
        assert_eq!(pad(0.3, 0.1, 0.19), 0.0);
        assert!((pad(0.3, 0.1, 0.35) - 0.5).abs() < 1e-12);
        // slope 0 at the edges, continuous with the 0 outside: 1e-4 inside it is ~(π·1e-3)²/4
        assert!(pad(0.3, 0.1, 0.3999) < 3e-6);
    }

    #[test]
    fn engaged_spring_is_continuous_with_its_slope() {
        let (k, e, w) = (3.0, 0.2, 0.01);
        assert_eq!(engaged_spring(k, e, w, 0.19), 0.0);
        let at = |q: f64| engaged_spring(k, e, w, q);
        // value and slope continuous where the blend meets the line
        let q1 = e + w;
        assert!((at(q1 - 1e-9) - at(q1 + 1e-9)).abs() < 1e-7);
        let slope = |q: f64| (at(q + 1e-7) - at(q - 1e-7)) / 2e-7;
        assert!((slope(q1 - 1e-6) - k).abs() < 1e-3 && (slope(q1 + 1e-6) - k).abs() < 1e-6);
        assert!((at(e + 1.0) - k * (1.0 - w / 2.0)).abs() < 1e-12);
    }
}
