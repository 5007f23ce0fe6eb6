//! The gravity table (arm paper §3.2.2) from static samples over one or several joint angles,
//! with per-cell σ and the analytic model's σ_m (arm paper eq. 6) for the fusion.
//!
//! Data: every sample of the static segments (the joint's own q̇ ≈ 0; the other joints may
//! move slowly, their angles are read per sample), torque `d − friction(q̇) − C_0`: the whole
//! static gravity, because the firmware fuses the table with the weight term as two estimates of
//! the same torque. Axes: `q` and every `q_<name>` column of the logs (at most 3).
//!
//! Grid per axis: when the samples' values fall in 2..=16 tight clusters (poses on a grid, as in
//! the paper), the cluster centres; otherwise evenly spaced points over the covered range (8,
//! fewer with many axes so the table stays within the core's `CELLS_MAX` values). Values: least squares of the
//! multilinear interpolation to the samples, with a small second-difference penalty so cells
//! the data do not reach are filled smoothly instead of left singular.
//!
//! σ per cell: the standard error of the cell's value (the residual variance of the samples,
//! weighted by their interpolation weight on the cell, over that weight), so a well-measured
//! cell is trusted over the analytic model and a thinly measured one less; cells without data
//! get three times the largest σ (the fusion then leans on the analytic model there). σ_m is the mean absolute
//! residual of the analytic model (weight + offset) on the same samples (eq. 6).

use super::robust::solve_spd;
use super::segments::{Prepared, SegKind, Segment};
use joint_formats::model_file::TableSpec;

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TableFit {
    pub axes: Vec<String>,
    pub grid: Vec<Vec<f64>>,
    pub torque: Vec<f64>,
    pub sigma: Vec<f64>,
    /// σ_m of the analytic model on the table's samples (eq. 6), N·m; None without a model
    pub sigma_model: Option<f64>,
    /// RMS residual of the table on its samples, N·m
    pub rms: f64,
    pub samples: usize,
    /// cells that no sample reached
    pub empty_cells: usize,
    /// per cell: reached by at least one sample
    pub reached: Vec<bool>,
}

impl TableFit {
    pub fn spec(&self) -> TableSpec {
        TableSpec {
            axes: self.axes.clone(),
            grid: self.grid.clone(),
            torque: self.torque.clone(),
            sigma: Some(self.sigma.clone()),
        }
    }

    /// Table torque and σ at the point `x` (one value per axis), multilinear, clamped to the grid.
    pub fn eval(&self, x: &[f64]) -> (f64, f64) {
        let mut idx = Vec::new();
        let mut w = Vec::new();
        corners(&self.grid, x, &mut idx, &mut w);
        let t = idx.iter().zip(&w).map(|(i, w)| w * self.torque[*i]).sum();
        let s = idx.iter().zip(&w).map(|(i, w)| w * self.sigma[*i]).sum();
        (t, s)
    }

    /// The gravity the joint computes from the weight torque `w` and this table (the core's
    /// rule: fused with inverse-variance weights and clamped to w ± k·σ_m when σ_m > 0, else
    /// the table added to the weight).
    pub fn gravity(&self, w: f64, x: &[f64], clamp_k: f64) -> f64 {
        let (tt, st) = self.eval(x);
        match self.sigma_model {
            Some(sm) if sm > 0.0 => {
                let (vm, vd) = (sm * sm, st * st);
                let fused = w + (tt - w) * vm / (vm + vd);
                let band = clamp_k * sm;
                fused.clamp(w - band, w + band)
            }
            _ => w + tt,
        }
    }
}

/// Cell corners and weights of `x` on the grid (row-major, last axis fastest).
fn corners(grid: &[Vec<f64>], x: &[f64], idx: &mut Vec<usize>, w: &mut Vec<f64>) {
    idx.clear();
    w.clear();
    for_corners(grid, x, |k, wt| {
        idx.push(k);
        w.push(wt);
    });
}

/// Each corner of `x`'s cell on the grid (clamped to it) with its multilinear weight, row-major
/// index (last axis fastest); no allocation.
fn for_corners(grid: &[Vec<f64>], x: &[f64], mut each: impl FnMut(usize, f64)) {
    let n = grid.len();
    let mut lo = [0usize; 4];
    let mut fr = [0.0f64; 4];
    for a in 0..n {
        let g = &grid[a];
        let last = g.len() - 1;
        let xa = x[a].clamp(g[0], g[last]);
        let i = g.partition_point(|&v| v <= xa).saturating_sub(1).min(last - 1);
        lo[a] = i;
        fr[a] = ((xa - g[i]) / (g[i + 1] - g[i])).clamp(0.0, 1.0);
    }
    for c in 0..(1usize << n) {
        let mut k = 0usize;
        let mut wt = 1.0;
        for a in 0..n {
            let bit = (c >> a) & 1;
            wt *= if bit == 1 { fr[a] } else { 1.0 - fr[a] };
            k = k * grid[a].len() + lo[a] + bit;
        }
        each(k, wt);
    }
}

/// A table's `values` at the point `x` (one value per axis), multilinear, clamped to the grid:
/// the rule the core's table follows, for a table as a model file states it.
pub(crate) fn interpolate(grid: &[Vec<f64>], values: &[f64], x: &[f64]) -> f64 {
    let mut v = 0.0;
    for_corners(grid, x, |k, wt| v += wt * values[k]);
    v
}

/// Grid of one axis: cluster centres when the values are a few tight clusters, else evenly
/// spaced `even` points over the range.
fn axis_grid(values: &mut [f64], even: usize) -> Option<Vec<f64>> {
    values.sort_by(f64::total_cmp);
    let (lo, hi) = (*values.first()?, *values.last()?);
    if !(hi > lo) {
        return None;
    }
    let tol = (0.02 * (hi - lo)).max(1e-3);
    let mut clusters: Vec<(f64, f64, usize)> = Vec::new(); // first, sum, count
    let mut prev = lo;
    for &v in values.iter() {
        match clusters.last_mut() {
            Some(c) if v - prev <= tol && v - c.0 <= 2.0 * tol => {
                c.1 += v;
                c.2 += 1;
            }
            _ => clusters.push((v, v, 1)),
        }
        prev = v;
    }
    if (2..=16).contains(&clusters.len()) {
        let centres: Vec<f64> = clusters.iter().map(|c| c.1 / c.2 as f64).collect();
        if centres.windows(2).all(|w| w[1] > w[0]) {
            return Some(centres);
        }
    }
    Some((0..even).map(|k| lo + (hi - lo) * k as f64 / (even - 1) as f64).collect())
}

/// Fits the table. `static_torque(log, i)` is the static gravity torque of a sample (d less
/// friction and offset); `model(log, i)` the analytic model's prediction of the same torque.
pub fn fit(
    logs: &[(&Prepared, &[Segment])],
    static_torque: &dyn Fn(usize, usize) -> f64,
    model: Option<&dyn Fn(usize, usize) -> f64>,
) -> Result<TableFit, String> {
    let Some((first, _)) = logs.iter().find(|(p, _)| p.d.is_some()) else {
        return Err("needs a torque-mode log".into());
    };
    let mut axes = vec!["q".to_string()];
    axes.extend(first.others.iter().map(|(n, _)| n.clone()).take(3));
    let n_axes = axes.len();
    // Samples: (log, index), at most ~60 000 spread evenly over the static segments.
    let mut pts: Vec<(usize, usize)> = Vec::new();
    let total: usize = logs
        .iter()
        .filter(|(p, _)| p.d.is_some())
        .flat_map(|(_, s)| s.iter().filter(|s| s.kind == SegKind::Static).map(Segment::len))
        .sum();
    let stride = (total / 60_000).max(1);
    for (li, (p, segs)) in logs.iter().enumerate() {
        if p.d.is_none() {
            continue;
        }
        for a in &axes[1..] {
            if !p.others.iter().any(|(n, _)| n == a) {
                return Err(format!("log {} has no column `{a}` (the table's axes come from the first log)", li + 1));
            }
        }
        for s in segs.iter().filter(|s| s.kind == SegKind::Static) {
            pts.extend((s.start..s.end).step_by(stride).map(|i| (li, i)));
        }
    }
    if pts.len() < 20 {
        return Err(format!(
            "{} static samples; hold the joint still at several poses (or give --window START:END:static)",
            pts.len()
        ));
    }
    let coord = |li: usize, i: usize, a: usize| -> f64 {
        let p = logs[li].0;
        if a == 0 {
            p.q[i]
        } else {
            p.others.iter().find(|(n, _)| *n == axes[a]).map_or(0.0, |(_, c)| c[i])
        }
    };
    let even = match n_axes {
        1 => 8,
        2 => 8,
        // within the core's CELLS_MAX (128): 5³ = 125, 3⁴ = 81
        3 => 5,
        _ => 3,
    };
    let mut grid = Vec::with_capacity(n_axes);
    for a in 0..n_axes {
        let mut v: Vec<f64> = pts.iter().map(|&(li, i)| coord(li, i, a)).collect();
        grid.push(
            axis_grid(&mut v, even)
                .ok_or_else(|| format!("axis `{}` does not vary over the static samples", axes[a]))?,
        );
    }
    let cells: usize = grid.iter().map(Vec::len).product();
    if cells > joint_core::table::CELLS_MAX {
        // Clustered axes can have up to 16 points each.
        return Err(format!(
            "{cells} table values needed for the pose grid, at most {} fit on the joint",
            joint_core::table::CELLS_MAX
        ));
    }
    // Normal equations of the interpolation weights.
    let mut ata = vec![0.0; cells * cells];
    let mut aty = vec![0.0; cells];
    let mut wsum = vec![0.0; cells];
    let (mut idx, mut w) = (Vec::new(), Vec::new());
    let mut x = vec![0.0; n_axes];
    let mut ys = Vec::with_capacity(pts.len());
    for &(li, i) in &pts {
        for (a, xa) in x.iter_mut().enumerate() {
            *xa = coord(li, i, a);
        }
        let y = static_torque(li, i);
        ys.push(y);
        corners(&grid, &x, &mut idx, &mut w);
        for (k, (&ci, &wi)) in idx.iter().zip(&w).enumerate() {
            aty[ci] += wi * y;
            wsum[ci] += wi;
            for (&cj, &wj) in idx.iter().zip(&w).take(k + 1) {
                ata[ci * cells + cj] += wi * wj;
                if cj != ci {
                    ata[cj * cells + ci] += wi * wj;
                }
            }
        }
    }
    // Second-difference smoothing along every axis, weak against the data.
    let scale = (0..cells).map(|c| ata[c * cells + c]).fold(0.0f64, f64::max).max(1.0);
    let lambda = 1e-4 * scale;
    let mut strides = vec![1usize; n_axes];
    for a in (0..n_axes.saturating_sub(1)).rev() {
        strides[a] = strides[a + 1] * grid[a + 1].len();
    }
    for a in 0..n_axes {
        let len = grid[a].len();
        for c in 0..cells {
            let pos = (c / strides[a]) % len;
            if pos == 0 || pos + 1 >= len {
                continue;
            }
            let trip = [(c - strides[a], 1.0), (c, -2.0), (c + strides[a], 1.0)];
            for &(i, wi) in &trip {
                for &(j, wj) in &trip {
                    ata[i * cells + j] += lambda * wi * wj;
                }
            }
        }
    }
    // A tiny ridge keeps a cell reached by nothing (and not pinned by smoothing) defined.
    for c in 0..cells {
        ata[c * cells + c] += 1e-9 * scale;
    }
    let torque = solve_spd(&ata, &aty, cells).ok_or("the table's least squares is singular")?;
    // Residuals and per-cell σ.
    let mut r2w = vec![0.0; cells];
    let mut sq = 0.0;
    let mut abs_model = 0.0;
    for (k, &(li, i)) in pts.iter().enumerate() {
        for (a, xa) in x.iter_mut().enumerate() {
            *xa = coord(li, i, a);
        }
        corners(&grid, &x, &mut idx, &mut w);
        let pred: f64 = idx.iter().zip(&w).map(|(c, wi)| wi * torque[*c]).sum();
        let r = ys[k] - pred;
        sq += r * r;
        for (c, wi) in idx.iter().zip(&w) {
            r2w[*c] += wi * r * r;
        }
        if let Some(m) = model {
            abs_model += (m(li, i) - ys[k]).abs();
        }
    }
    let mut sigma: Vec<f64> = (0..cells)
        .map(|c| {
            if wsum[c] > 1e-9 {
                // standard error of the cell's value: residual variance over its weight
                (r2w[c] / wsum[c] / wsum[c].max(1.0)).sqrt()
            } else {
                f64::NAN
            }
        })
        .collect();
    let reached: Vec<f64> = sigma.iter().copied().filter(|s| s.is_finite()).collect();
    let smax = reached.iter().copied().fold(0.0f64, f64::max);
    let mut sorted = reached.clone();
    sorted.sort_by(f64::total_cmp);
    let floor = (0.1 * sorted.get(sorted.len() / 2).copied().unwrap_or(0.0)).max(1e-4);
    let empty_cells = sigma.iter().filter(|s| !s.is_finite()).count();
    let reached = sigma.iter().map(|s| s.is_finite()).collect();
    for s in &mut sigma {
        *s = if s.is_finite() { s.max(floor) } else { (3.0 * smax).max(floor) };
    }
    Ok(TableFit {
        axes,
        grid,
        torque,
        sigma,
        sigma_model: model.map(|_| abs_model / pts.len() as f64),
        rms: (sq / pts.len() as f64).sqrt(),
        samples: pts.len(),
        empty_cells,
        reached,
    })
}
