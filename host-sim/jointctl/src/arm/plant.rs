//! The arm as built ("truth"): the CAD potential with the CAD data off, plus what the CAD
//! model does not know — the unmodelled torques the arm paper names (§1, §4.3: assembly
//! tolerances, mass estimates, internal compliance, cables) — and the static measurement.
//!
//! Encoders read motor angles `θ_m`. Each joint is a spring `K_c` between motor and link, so
//! at rest the link sags: `θ_l = θ_m − τ(θ_l)/K_c`, solved by fixed-point iteration (the map
//! contracts: |∂τ/∂θ|/K_c < 0.1 here). The motor holds `τ = G_true(θ_l + offset) + cable(θ_m)`,
//! and a static pose is measured like the paper's data set (§3.2.2): the drive current's
//! torque sampled over N cycles (1000 in the paper) with per-sample noise, then averaged.

#![allow(clippy::indexing_slicing)] // fixed 4-joint arrays

use super::cad::CadModel;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The unmodelled effects; [`ArmPlant::default`] holds the sizes the experiment uses.
#[derive(Clone, Debug)]
pub struct ArmPlant {
    /// the arm's true potential: the CAD one with the forearm moment and the cross term off
    /// (mass and centroid error of the CAD data)
    pub truth: CadModel,
    /// the forearm moment factor and cross-term offset used for `truth` (for reports)
    pub forearm_scale: f64,
    pub cross_offset: f64,
    /// assembly offset: the true angle of each joint is the encoder's plus this, rad
    pub offset: [f64; 4],
    /// joint stiffness between motor and link, N·m/rad
    pub k_c: [f64; 4],
    /// cable torque `k·(θ − θ0) + k2·max(θ − θe, 0)²` per joint: (k, θ0, k2, θe)
    pub cable: [(f64, f64, f64, f64); 4],
    /// per-sample torque noise (current ripple and sensor noise), N·m
    pub noise_sd: [f64; 4],
}

impl Default for ArmPlant {
    fn default() -> Self {
        let deg = std::f64::consts::PI / 180.0;
        let forearm_scale = 1.03;
        let cross_offset = 0.3;
        ArmPlant {
            truth: CadModel::with(super::cad::C_FOREARM * forearm_scale, super::cad::C_CROSS + cross_offset),
            forearm_scale,
            cross_offset,
            offset: [0.0, 1.5 * deg, 0.0, 0.0],
            k_c: [500.0, 500.0, 400.0, 300.0],
            // shoulder abduction and flexion carry the harness: a linear pull and a stiffening
            // one towards the end of the range
            cable: [
                (0.5, 0.0, 0.6, 60.0 * deg),
                (0.0, 0.0, 0.0, 0.0),
                (0.4, 0.5, 0.3, 70.0 * deg),
                (0.0, 0.0, 0.0, 0.0),
            ],
            noise_sd: [0.15, 0.15, 0.1, 0.1],
        }
    }
}

impl ArmPlant {
    /// Link angles at rest for motor angles `qm` (fixed point of the compliance).
    pub fn link_angles(&self, qm: &[f64; 4]) -> [f64; 4] {
        let mut ql = *qm;
        for _ in 0..60 {
            let th: [f64; 4] = std::array::from_fn(|j| ql[j] + self.offset[j]);
            let g = self.truth.torques(&th);
            let next: [f64; 4] = std::array::from_fn(|j| qm[j] - g[j] / self.k_c[j]);
            let step = next.iter().zip(&ql).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            ql = next;
            if step < 1e-13 {
                break;
            }
        }
        ql
    }

    pub fn cable_torque(&self, qm: &[f64; 4]) -> [f64; 4] {
        std::array::from_fn(|j| {
            let (k, q0, k2, qe) = self.cable[j];
            let x = (qm[j] - qe).max(0.0);
            k * (qm[j] - q0) + k2 * x * x
        })
    }

    /// The torque the motors hold at rest at motor angles `qm`, noise-free.
    pub fn static_torque(&self, qm: &[f64; 4]) -> [f64; 4] {
        let ql = self.link_angles(qm);
        let th: [f64; 4] = std::array::from_fn(|j| ql[j] + self.offset[j]);
        let g = self.truth.torques(&th);
        let c = self.cable_torque(qm);
        std::array::from_fn(|j| g[j] + c[j])
    }

    /// A static measurement: `cycles` noisy samples of the held torque, averaged.
    pub fn measure(&self, qm: &[f64; 4], cycles: usize, rng: &mut ChaCha8Rng) -> [f64; 4] {
        let tau = self.static_torque(qm);
        std::array::from_fn(|j| {
            let n = Normal::new(0.0, self.noise_sd[j]).ok();
            let mut acc = 0.0;
            for _ in 0..cycles.max(1) {
                acc += tau[j] + n.map_or(0.0, |d| d.sample(rng));
            }
            acc / cycles.max(1) as f64
        })
    }
}

/// A uniformly random configuration inside `lo..hi` per joint.
pub fn random_config(lo: &[f64; 4], hi: &[f64; 4], rng: &mut ChaCha8Rng) -> [f64; 4] {
    std::array::from_fn(|j| rng.random_range(lo[j]..=hi[j]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compliance_fixed_point_holds() {
        let p = ArmPlant::default();
        let qm = [0.7, 0.4, 1.1, 0.9];
        let ql = p.link_angles(&qm);
        let th: [f64; 4] = std::array::from_fn(|j| ql[j] + p.offset[j]);
        let g = p.truth.torques(&th);
        for j in 0..4 {
            assert!((ql[j] - (qm[j] - g[j] / p.k_c[j])).abs() < 1e-12);
        }
    }
}
