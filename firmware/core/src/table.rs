//! Lookup-table gravity over one to four joint angles, and model/data fusion.
//!
//! The table is a regular (not necessarily uniform) grid, stored row-major with the last axis
//! fastest, and interpolated multilinearly; inputs outside the grid are clamped to its edge, so
//! the table never extrapolates. Storage is fixed at compile time ([`CELLS_MAX`] values), which
//! keeps a parameter set a plain `Copy`-free value with no allocation.
//!
//! Fusion follows the arm paper §3.2.3: the analytic model torque `τ_m` (σ_m from its residuals,
//! eq. 6) and the table torque `τ_t` (σ_t per cell, interpolated like the torque) are averaged
//! with inverse-variance weights, and the result is clamped to `τ_m ± k·σ_m` so the data can
//! never pull the command far from physics (eq. 8).

use crate::math;

/// Most axes a table may have.
pub const AXES_MAX: usize = 4;
/// Most grid points along one axis.
pub const AXIS_POINTS_MAX: usize = 16;
/// Most values in one table (product of the points of all axes).
pub const CELLS_MAX: usize = 256;
/// Highest axis source: 0 is the joint's own angle, 1..=3 the other joints' angle slots.
pub const AXIS_SOURCE_MAX: u8 = 3;

/// A gravity table as received (from a TOML file, SDO writes or flash); unchecked.
#[derive(Clone, Debug, PartialEq)]
pub struct RawTable {
    /// 0 = no table.
    pub n_axes: u8,
    /// where each axis reads its angle: 0 = own `q`, 1..=3 = `others[source − 1]`.
    pub axis_source: [u8; AXES_MAX],
    /// grid points per axis.
    pub points: [u8; AXES_MAX],
    /// grid coordinates per axis, rad, strictly increasing in the first `points[a]` entries.
    pub grid: [[f32; AXIS_POINTS_MAX]; AXES_MAX],
    /// table torque, N·m, row-major (last axis fastest).
    pub torque: [f32; CELLS_MAX],
    /// per-value standard deviation, N·m (> 0), used only by fusion.
    pub sigma: [f32; CELLS_MAX],
    pub has_sigma: bool,
}

impl RawTable {
    pub const EMPTY: RawTable = RawTable {
        n_axes: 0,
        axis_source: [0; AXES_MAX],
        points: [0; AXES_MAX],
        grid: [[0.0; AXIS_POINTS_MAX]; AXES_MAX],
        torque: [0.0; CELLS_MAX],
        sigma: [0.0; CELLS_MAX],
        has_sigma: false,
    };

    /// Number of values the grid defines (product of points), 0 for no table.
    pub fn cells(&self) -> usize {
        if self.n_axes == 0 {
            return 0;
        }
        let mut n = 1usize;
        for p in self.points.iter().take(self.n_axes as usize) {
            n = n.saturating_mul(*p as usize);
        }
        n
    }
}

impl Default for RawTable {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// Why a table was refused. Indices are 0-based.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TableError {
    /// more than [`AXES_MAX`] axes
    AxisCount { n_axes: u8 },
    /// axis reads from a slot that does not exist
    AxisSource { axis: u8, source: u8 },
    /// fewer than 2 or more than [`AXIS_POINTS_MAX`] points
    Points { axis: u8, points: u8 },
    /// product of the points exceeds [`CELLS_MAX`]
    TooManyCells { cells: u32 },
    GridNotFinite { axis: u8, index: u8 },
    /// `grid[axis][index] <= grid[axis][index − 1]`
    GridNotIncreasing { axis: u8, index: u8 },
    TorqueNotFinite { index: u16 },
    /// σ must be finite and > 0 where fusion uses it
    SigmaNotPositive { index: u16 },
}

impl core::fmt::Display for TableError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            TableError::AxisCount { n_axes } => {
                write!(f, "gravity_table has {n_axes} axes, at most {AXES_MAX} are supported")
            }
            TableError::AxisSource { axis, source } => {
                write!(f, "gravity_table axis {axis} reads angle slot {source}, slots are 0..={AXIS_SOURCE_MAX}")
            }
            TableError::Points { axis, points } => write!(
                f,
                "gravity_table axis {axis} has {points} grid points, needs 2..={AXIS_POINTS_MAX}"
            ),
            TableError::TooManyCells { cells } => {
                write!(f, "gravity_table has {cells} values, at most {CELLS_MAX} fit")
            }
            TableError::GridNotFinite { axis, index } => {
                write!(f, "gravity_table grid[{axis}][{index}] is not a finite number")
            }
            TableError::GridNotIncreasing { axis, index } => write!(
                f,
                "gravity_table grid[{axis}] is not strictly increasing at index {index}"
            ),
            TableError::TorqueNotFinite { index } => {
                write!(f, "gravity_table torque[{index}] is not a finite number")
            }
            TableError::SigmaNotPositive { index } => {
                write!(f, "gravity_table sigma[{index}] must be finite and > 0")
            }
        }
    }
}

/// Checks everything interpolation relies on, so [`interpolate`] can run without any check.
pub fn validate(t: &RawTable) -> Result<(), TableError> {
    if t.n_axes == 0 {
        return Ok(());
    }
    if t.n_axes as usize > AXES_MAX {
        return Err(TableError::AxisCount { n_axes: t.n_axes });
    }
    let mut cells: u32 = 1;
    for axis in 0..t.n_axes as usize {
        let a = axis as u8;
        let source = t.axis_source.get(axis).copied().unwrap_or(u8::MAX);
        if source > AXIS_SOURCE_MAX {
            return Err(TableError::AxisSource { axis: a, source });
        }
        let points = t.points.get(axis).copied().unwrap_or(0);
        if !(2..=AXIS_POINTS_MAX as u8).contains(&points) {
            return Err(TableError::Points { axis: a, points });
        }
        cells = cells.saturating_mul(points as u32);
        let grid = t.grid.get(axis).ok_or(TableError::AxisCount { n_axes: t.n_axes })?;
        let mut prev = f32::NEG_INFINITY;
        for (i, &g) in grid.iter().take(points as usize).enumerate() {
            if !math::is_finite(g) {
                return Err(TableError::GridNotFinite { axis: a, index: i as u8 });
            }
            if g <= prev {
                return Err(TableError::GridNotIncreasing { axis: a, index: i as u8 });
            }
            prev = g;
        }
    }
    if cells as usize > CELLS_MAX {
        return Err(TableError::TooManyCells { cells });
    }
    for (i, &v) in t.torque.iter().take(cells as usize).enumerate() {
        if !math::is_finite(v) {
            return Err(TableError::TorqueNotFinite { index: i as u16 });
        }
    }
    if t.has_sigma {
        for (i, &s) in t.sigma.iter().take(cells as usize).enumerate() {
            if !(math::is_finite(s) && s > 0.0) {
                return Err(TableError::SigmaNotPositive { index: i as u16 });
            }
        }
    }
    Ok(())
}

/// Cell index and fraction of `x` along one axis, clamped to the grid.
#[inline]
fn locate(grid: &[f32; AXIS_POINTS_MAX], points: usize, x: f32) -> (usize, f32) {
    let last = points.saturating_sub(1).max(1);
    let g0 = grid.first().copied().unwrap_or(0.0);
    let gl = grid.get(last).copied().unwrap_or(g0);
    let x = math::clamp(x, g0, gl);
    // Binary search for the cell [i, i+1] that holds x; ≤ 4 steps for 16 points.
    let mut lo = 0usize;
    let mut hi = last;
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if grid.get(mid).copied().unwrap_or(gl) <= x {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let a = grid.get(lo).copied().unwrap_or(g0);
    let b = grid.get(lo + 1).copied().unwrap_or(gl);
    let span = b - a;
    let frac = if span > 0.0 { math::clamp((x - a) / span, 0.0, 1.0) } else { 0.0 };
    (lo, frac)
}

/// Multilinear interpolation of `values` (torque or σ) at the angles `x` (one per axis, already
/// read from their sources). A table that passed [`validate`] is required for meaningful
/// results; anything else still returns a finite number or 0, never panics.
pub fn interpolate(t: &RawTable, values: &[f32; CELLS_MAX], x: &[f32; AXES_MAX]) -> f32 {
    let n = (t.n_axes as usize).min(AXES_MAX);
    if n == 0 {
        return 0.0;
    }
    let mut base = [0usize; AXES_MAX];
    let mut frac = [0.0f32; AXES_MAX];
    let mut stride = [0usize; AXES_MAX];
    let mut s = 1usize;
    for axis in (0..n).rev() {
        let points = t.points.get(axis).copied().unwrap_or(2) as usize;
        let grid = t.grid.get(axis).unwrap_or(&[0.0; AXIS_POINTS_MAX]);
        let xi = x.get(axis).copied().unwrap_or(0.0);
        let (i, f) = locate(grid, points, xi);
        if let (Some(b), Some(fr), Some(st)) = (base.get_mut(axis), frac.get_mut(axis), stride.get_mut(axis)) {
            *b = i;
            *fr = f;
            *st = s;
        }
        s = s.saturating_mul(points);
    }
    let mut origin = 0usize;
    for axis in 0..n {
        origin += base.get(axis).copied().unwrap_or(0) * stride.get(axis).copied().unwrap_or(0);
    }
    // Sum over the 2^n corners of the cell.
    let mut acc = 0.0f32;
    for corner in 0..(1usize << n) {
        let mut w = 1.0f32;
        let mut idx = origin;
        for axis in 0..n {
            let f = frac.get(axis).copied().unwrap_or(0.0);
            if corner & (1 << axis) != 0 {
                w *= f;
                idx += stride.get(axis).copied().unwrap_or(0);
            } else {
                w *= 1.0 - f;
            }
        }
        acc += w * values.get(idx).copied().unwrap_or(0.0);
    }
    acc
}

/// Inverse-variance fusion of a model torque and a data torque, clamped to
/// `tau_model ± k·sigma_model` (arm paper eq. 7–8). Written as a convex combination
/// `τ_m + (τ_d − τ_m)·σ_m²/(σ_m² + σ_d²)`, which is the same weighted mean without dividing by
/// tiny variances.
#[inline]
pub fn fuse(tau_model: f32, sigma_model: f32, tau_data: f32, sigma_data: f32, k: f32) -> f32 {
    let vm = sigma_model * sigma_model;
    let vd = sigma_data * sigma_data;
    let sum = vm + vd;
    let w_data = if sum > 0.0 { vm / sum } else { 0.5 };
    let fused = tau_model + (tau_data - tau_model) * w_data;
    let band = math::abs(k * sigma_model);
    math::clamp(fused, tau_model - band, tau_model + band)
}
