//! Identification from static poses, as the arm paper's data set (§3.2.2, §4.3): every pose of
//! the 10° grid over `S_j = {90°, 80°, 90°, 120°}` from each joint's zero (10·9·10·13 = 11 700
//! poses; the paper kept 11 200), measured as the averaged torque of N cycles; σ_m per joint
//! from the CAD residual (eq. 6); and per joint a gravity table of that residual over the 1–3
//! joint angles that explain most of its variance within the core's table capacity.
//!
//! A table is fitted by least squares on its multilinear interpolation (for grid nodes that
//! carry poses this is the mean residual of the poses on the node; coarser grids, needed for
//! three axes in 128 values, fit between nodes). Each value's σ is the interpolation-weighted
//! RMS of what the table leaves unexplained around it (the scatter over the joint angles the
//! table does not see, plus the measurement noise).

#![allow(clippy::indexing_slicing)] // numerical kernels: indices bounded by grid and cell counts built just before

use super::cad::{others_of, CadModel};
use super::plant::ArmPlant;
use joint_core::params::RawTable;
use joint_core::table::{AXIS_POINTS_MAX, CELLS_MAX};
use rand_chacha::ChaCha8Rng;

pub const DEG: f64 = std::f64::consts::PI / 180.0;
/// S_j of the paper, degrees.
pub const RANGE_DEG: [f64; 4] = [90.0, 80.0, 90.0, 120.0];
/// Grid step of the paper's data set.
pub const STEP_DEG: f64 = 10.0;
/// Smallest per-value σ of a table, N·m (the core needs σ > 0).
pub const SIGMA_FLOOR: f64 = 1.0e-3;

/// The static data set: motor angles and averaged torques.
#[derive(Clone, Debug)]
pub struct Dataset {
    pub poses: Vec<[f64; 4]>,
    pub torque: Vec<[f64; 4]>,
    pub cycles: usize,
}

/// Every pose of the 10° grid (joint 1 slowest).
pub fn grid_poses() -> Vec<[f64; 4]> {
    let n: [usize; 4] = RANGE_DEG.map(|s| (s / STEP_DEG).round() as usize + 1);
    let mut v = Vec::with_capacity(n.iter().product());
    for a in 0..n[0] {
        for b in 0..n[1] {
            for c in 0..n[2] {
                for d in 0..n[3] {
                    v.push([a, b, c, d].map(|i| i as f64 * STEP_DEG * DEG));
                }
            }
        }
    }
    v
}

pub fn collect(plant: &ArmPlant, cycles: usize, rng: &mut ChaCha8Rng) -> Dataset {
    let poses = grid_poses();
    let torque = poses.iter().map(|q| plant.measure(q, cycles, rng)).collect();
    Dataset { poses, torque, cycles }
}

/// σ_m (eq. 6: standard deviation of the residual), its RMSE (eq. 10) and mean, per joint.
pub fn model_sigma(cad: &CadModel, d: &Dataset) -> [(f64, f64, f64); 4] {
    std::array::from_fn(|j| {
        let e: Vec<f64> = d.poses.iter().zip(&d.torque).map(|(q, t)| t[j] - cad.torques(q)[j]).collect();
        let n = e.len().max(1) as f64;
        let mean = e.iter().sum::<f64>() / n;
        let sd = (e.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n).sqrt();
        let rmse = (e.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
        (sd, rmse, mean)
    })
}

/// A fitted residual table over some joints' angles (0-based joint indices).
#[derive(Clone, Debug)]
pub struct ResidualTable {
    pub joints: Vec<usize>,
    pub grid: Vec<Vec<f64>>,
    pub torque: Vec<f64>,
    pub sigma: Vec<f64>,
    /// share of the residual's variance over the data set the table explains
    pub explained: f64,
}

/// Uniform grid of `points` over joint `j`'s range.
fn axis_grid(j: usize, points: usize) -> Vec<f64> {
    let hi = RANGE_DEG.get(j).copied().unwrap_or(90.0) * DEG;
    (0..points).map(|i| hi * i as f64 / (points - 1).max(1) as f64).collect()
}

/// Points per axis: the 10° grid where it fits, else the longest axis thinned until the
/// product fits the core's table.
pub fn axis_points(joints: &[usize]) -> Vec<usize> {
    let mut p: Vec<usize> = joints
        .iter()
        .map(|&j| ((RANGE_DEG.get(j).copied().unwrap_or(90.0) / STEP_DEG).round() as usize + 1).min(AXIS_POINTS_MAX))
        .collect();
    while p.iter().product::<usize>() > CELLS_MAX {
        if let Some(m) = p.iter_mut().max() {
            *m -= 1;
        }
    }
    p
}

/// Multilinear weights of `x` (one coordinate per axis) on a row-major grid: (cell, weight).
fn weights(grid: &[Vec<f64>], x: &[f64]) -> Vec<(usize, f64)> {
    let n = grid.len();
    let mut base = vec![0usize; n];
    let mut frac = vec![0.0f64; n];
    let mut stride = vec![0usize; n];
    let mut s = 1usize;
    for a in (0..n).rev() {
        let g = &grid[a];
        let xi = x[a].clamp(g[0], g[g.len() - 1]);
        let mut i = 0;
        while i + 2 < g.len() && xi >= g[i + 1] {
            i += 1;
        }
        base[a] = i;
        frac[a] = ((xi - g[i]) / (g[i + 1] - g[i])).clamp(0.0, 1.0);
        stride[a] = s;
        s *= g.len();
    }
    let origin: usize = (0..n).map(|a| base[a] * stride[a]).sum();
    (0..1usize << n)
        .map(|corner| {
            let mut w = 1.0;
            let mut idx = origin;
            for a in 0..n {
                if corner & (1 << a) != 0 {
                    w *= frac[a];
                    idx += stride[a];
                } else {
                    w *= 1.0 - frac[a];
                }
            }
            (idx, w)
        })
        .collect()
}

/// Solve the symmetric positive definite system `a·x = b` (Cholesky); `a` row-major n×n.
fn cholesky_solve(mut a: Vec<f64>, mut b: Vec<f64>, n: usize) -> Option<Vec<f64>> {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d <= 0.0 {
            return None;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    Some(b)
}

/// Fit a residual table over `joints` to `(pose, residual)` pairs.
pub fn fit_table(joints: &[usize], poses: &[[f64; 4]], resid: &[f64]) -> Option<ResidualTable> {
    let pts = axis_points(joints);
    let grid: Vec<Vec<f64>> = joints.iter().zip(&pts).map(|(&j, &p)| axis_grid(j, p)).collect();
    let cells: usize = pts.iter().product();
    let mut ata = vec![0.0f64; cells * cells];
    let mut atb = vec![0.0f64; cells];
    let ws: Vec<Vec<(usize, f64)>> = poses
        .iter()
        .map(|q| {
            let x: Vec<f64> = joints.iter().map(|&j| q[j]).collect();
            weights(&grid, &x)
        })
        .collect();
    for (w, &r) in ws.iter().zip(resid) {
        for &(i, wi) in w {
            atb[i] += wi * r;
            for &(k, wk) in w {
                ata[i * cells + k] += wi * wk;
            }
        }
    }
    // A whisper of ridge keeps nodes without data (none on the paper's grid) solvable.
    let scale = (0..cells).map(|i| ata[i * cells + i]).fold(0.0, f64::max).max(1.0);
    for i in 0..cells {
        ata[i * cells + i] += 1e-9 * scale;
    }
    let torque = cholesky_solve(ata, atb, cells)?;
    let mut num = vec![0.0f64; cells];
    let mut den = vec![0.0f64; cells];
    let mean = resid.iter().sum::<f64>() / resid.len().max(1) as f64;
    let (mut sse, mut sst) = (0.0, 0.0);
    for (w, &r) in ws.iter().zip(resid) {
        let pred: f64 = w.iter().map(|&(i, wi)| wi * torque[i]).sum();
        let e2 = (r - pred) * (r - pred);
        sse += e2;
        sst += (r - mean) * (r - mean);
        for &(i, wi) in w {
            num[i] += wi * e2;
            den[i] += wi;
        }
    }
    let sigma =
        num.iter().zip(&den).map(|(n, d)| if *d > 0.0 { (n / d).sqrt().max(SIGMA_FLOOR) } else { 1.0 }).collect();
    Some(ResidualTable {
        joints: joints.to_vec(),
        grid,
        torque,
        sigma,
        explained: if sst > 0.0 { 1.0 - sse / sst } else { 0.0 },
    })
}

/// Every subset of 1..=3 of the four joints.
pub fn candidate_axes() -> Vec<Vec<usize>> {
    let mut v = Vec::new();
    for mask in 1u32..16 {
        let s: Vec<usize> = (0..4).filter(|i| mask & (1 << i) != 0).collect();
        if s.len() <= 3 {
            v.push(s);
        }
    }
    v
}

/// Candidate axis sets (0-based joints) with the residual variance each explains.
pub type Candidates = Vec<(Vec<usize>, f64)>;

/// Per joint: all candidates' explained variance, and the best table.
pub fn best_table(j: usize, cad: &CadModel, d: &Dataset) -> anyhow::Result<(ResidualTable, Candidates)> {
    let resid: Vec<f64> = d.poses.iter().zip(&d.torque).map(|(q, t)| t[j] - cad.torques(q)[j]).collect();
    let mut scores = Vec::new();
    let mut best: Option<ResidualTable> = None;
    for axes in candidate_axes() {
        let Some(t) = fit_table(&axes, &d.poses, &resid) else { continue };
        scores.push((axes, t.explained));
        if best.as_ref().is_none_or(|b| t.explained > b.explained) {
            best = Some(t);
        }
    }
    let best = best.ok_or_else(|| anyhow::anyhow!("joint {}: no table could be fitted", j + 1))?;
    Ok((best, scores))
}

impl ResidualTable {
    /// The core's table for joint `j`: axis sources 0 (own angle) or 1..=3 (`others_of(j)`).
    pub fn raw(&self, j: usize) -> RawTable {
        let mut t = RawTable::EMPTY;
        let others = others_of(j);
        t.n_axes = self.joints.len() as u8;
        for (a, (&jj, g)) in self.joints.iter().zip(&self.grid).enumerate() {
            let src = if jj == j { 0 } else { 1 + others.iter().position(|&o| o == jj).unwrap_or(0) };
            if let (Some(s), Some(p), Some(row)) = (t.axis_source.get_mut(a), t.points.get_mut(a), t.grid.get_mut(a)) {
                *s = src as u8;
                *p = g.len() as u8;
                for (d, x) in row.iter_mut().zip(g) {
                    *d = *x as f32;
                }
            }
        }
        for (d, x) in t.torque.iter_mut().zip(&self.torque) {
            *d = *x as f32;
        }
        for (d, x) in t.sigma.iter_mut().zip(&self.sigma) {
            *d = *x as f32;
        }
        t.has_sigma = true;
        t.residual = true;
        t
    }

    /// The table's value at motor angles `q` (f64, for reports).
    pub fn eval(&self, q: &[f64; 4]) -> f64 {
        let x: Vec<f64> = self.joints.iter().map(|&j| q[j]).collect();
        weights(&self.grid, &x).iter().map(|&(i, w)| w * self.torque[i]).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_grid_and_capacity() {
        assert_eq!(grid_poses().len(), 10 * 9 * 10 * 13);
        for axes in candidate_axes() {
            let p = axis_points(&axes);
            assert!(p.iter().product::<usize>() <= CELLS_MAX, "{axes:?} {p:?}");
        }
        assert_eq!(axis_points(&[0, 2]), vec![10, 10], "the 10° grid where it fits");
    }

    #[test]
    fn a_residual_on_the_table_axes_is_recovered() {
        let poses = grid_poses();
        let f = |q: &[f64; 4]| 0.3 * q[0] * q[0] - 0.2 * q[3];
        let r: Vec<f64> = poses.iter().map(f).collect();
        let t = fit_table(&[0, 3], &poses, &r).unwrap_or_else(|| unreachable!());
        assert!(t.explained > 0.999, "{}", t.explained);
        let q = [0.35, 0.2, 0.4, 1.1];
        assert!((t.eval(&q) - f(&q)).abs() < 0.01);
    }
}
