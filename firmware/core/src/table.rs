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
pub const CELLS_MAX: usize = 128;
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
    /// The table holds the residual of the analytic model (weight + gravity series): its data
    /// estimate is `τ_m + table`, fused with `τ_m` (arm paper §3.2.3 with the data side
    /// learned on the model's error). `false` (the default, and every older set): the table is
    /// a gravity torque of its own.
    pub residual: bool,
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
        residual: false,
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
    AxisCount {
        n_axes: u8,
    },
    /// axis reads from a slot that does not exist
    AxisSource {
        axis: u8,
        source: u8,
    },
    /// fewer than 2 or more than [`AXIS_POINTS_MAX`] points
    Points {
        axis: u8,
        points: u8,
    },
    /// product of the points exceeds [`CELLS_MAX`]
    TooManyCells {
        cells: u32,
    },
    GridNotFinite {
        axis: u8,
        index: u8,
    },
    /// `grid[axis][index] <= grid[axis][index − 1]`
    GridNotIncreasing {
        axis: u8,
        index: u8,
    },
    TorqueNotFinite {
        index: u16,
    },
    /// σ must be finite and > 0 where fusion uses it
    SigmaNotPositive {
        index: u16,
    },
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
            TableError::Points { axis, points } => {
                write!(f, "gravity_table axis {axis} has {points} grid points, needs 2..={AXIS_POINTS_MAX}")
            }
            TableError::TooManyCells { cells } => {
                write!(f, "gravity_table has {cells} values, at most {CELLS_MAX} fit")
            }
            TableError::GridNotFinite { axis, index } => {
                write!(f, "gravity_table grid[{axis}][{index}] is not a finite number")
            }
            TableError::GridNotIncreasing { axis, index } => {
                write!(f, "gravity_table grid[{axis}] is not strictly increasing at index {index}")
            }
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

/// Binary search for the cell `[i, i+1]` of a grid with last index `last` that holds `x`
/// (already clamped to the grid); ≤ 4 steps for 16 points.
#[inline(always)]
fn search_cell(grid: &[f32; AXIS_POINTS_MAX], last: usize, x: f32) -> usize {
    let gl = grid.get(last).copied().unwrap_or(0.0);
    let (mut lo, mut hi) = (0usize, last);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if grid.get(mid).copied().unwrap_or(gl) <= x {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Cell index and fraction of `x` along one axis, clamped to the grid.
#[inline]
fn locate(grid: &[f32; AXIS_POINTS_MAX], points: usize, x: f32) -> (usize, f32) {
    let last = points.saturating_sub(1).max(1);
    let g0 = grid.first().copied().unwrap_or(0.0);
    let gl = grid.get(last).copied().unwrap_or(g0);
    let x = math::clamp(x, g0, gl);
    let lo = search_cell(grid, last, x);
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

/// Per-table values precomputed at parameter check time so the control step's interpolation
/// needs no search on uniform grids, no division, and one pass for torque and σ together.
#[derive(Clone, Debug, PartialEq)]
// 8-aligned (see `model::Terms`): a parameter appended to the table does not move it.
#[repr(align(8))]
pub struct Lut {
    n: u8,
    /// copied from the table: its data is the residual of the analytic model
    residual: bool,
    /// where each axis reads its angle (copied from the table)
    source: [u8; AXES_MAX],
    points: [u8; AXES_MAX],
    stride: [u16; AXES_MAX],
    /// 1/(grid[i+1] − grid[i]) per cell and axis
    inv_span: [[f32; AXIS_POINTS_MAX]; AXES_MAX],
    /// 1/step for a uniform grid (the cell index is then computed, not searched), else 0
    inv_step: [f32; AXES_MAX],
}

impl Default for Lut {
    fn default() -> Self {
        Lut {
            n: 0,
            residual: false,
            source: [0; AXES_MAX],
            points: [0; AXES_MAX],
            stride: [0; AXES_MAX],
            inv_span: [[0.0; AXIS_POINTS_MAX]; AXES_MAX],
            inv_step: [0.0; AXES_MAX],
        }
    }
}

impl Lut {
    /// Precompute for a table that passed [`validate`]; an invalid table gives an empty Lut.
    pub fn new(t: &RawTable) -> Lut {
        let mut lut = Lut::default();
        if validate(t).is_err() || t.n_axes == 0 {
            return lut;
        }
        let n = (t.n_axes as usize).min(AXES_MAX);
        lut.n = n as u8;
        lut.residual = t.residual;
        lut.source = t.axis_source;
        let mut s = 1usize;
        for axis in (0..n).rev() {
            let points = t.points.get(axis).copied().unwrap_or(2) as usize;
            let grid = t.grid.get(axis).copied().unwrap_or([0.0; AXIS_POINTS_MAX]);
            if let Some(p) = lut.points.get_mut(axis) {
                *p = points as u8;
            }
            if let Some(st) = lut.stride.get_mut(axis) {
                *st = s as u16;
            }
            s = s.saturating_mul(points);
            let first = grid.first().copied().unwrap_or(0.0);
            let last = grid.get(points - 1).copied().unwrap_or(first);
            let step = (last - first) / (points - 1) as f32;
            let mut uniform = true;
            for i in 0..points - 1 {
                let a = grid.get(i).copied().unwrap_or(0.0);
                let b = grid.get(i + 1).copied().unwrap_or(a);
                if let Some(inv) = lut.inv_span.get_mut(axis).and_then(|r| r.get_mut(i)) {
                    *inv = 1.0 / (b - a);
                }
                if math::abs((b - a) - step) > 1.0e-4 * math::abs(step) {
                    uniform = false;
                }
            }
            if let Some(inv) = lut.inv_step.get_mut(axis) {
                *inv = if uniform { 1.0 / step } else { 0.0 };
            }
        }
        lut
    }

    /// Cell and fraction along one axis, clamped to the grid.
    #[inline(always)]
    fn locate(&self, t: &RawTable, axis: usize, x: f32) -> (usize, f32) {
        let points = self.points.get(axis).copied().unwrap_or(2) as usize;
        let last = points.saturating_sub(1).max(1);
        let empty = [0.0; AXIS_POINTS_MAX];
        let grid = t.grid.get(axis).unwrap_or(&empty);
        let inv_span = self.inv_span.get(axis).unwrap_or(&empty);
        let g0 = grid.first().copied().unwrap_or(0.0);
        let gl = grid.get(last).copied().unwrap_or(g0);
        let x = math::clamp(x, g0, gl);
        let inv_step = self.inv_step.get(axis).copied().unwrap_or(0.0);
        let i = if inv_step > 0.0 {
            // `as usize` saturates at 0 for negatives; the min keeps the last cell.
            (((x - g0) * inv_step) as usize).min(last - 1)
        } else {
            search_cell(grid, last, x)
        };
        let a = grid.get(i).copied().unwrap_or(g0);
        let inv = inv_span.get(i).copied().unwrap_or(0.0);
        // No clamp: x is inside the grid, so the fraction leaves [0, 1] only by the rounding of
        // the uniform-grid index, a few ulps, which moves the result by as little.
        (i, (x - a) * inv)
    }

    /// Where axis `a` reads its angle (0: own q, 1..=3: the other joints' slots).
    #[inline]
    pub fn source(&self, a: usize) -> usize {
        self.source.get(a).copied().unwrap_or(0) as usize
    }

    /// Grid points of axis `a` and the stride of its index in the value arrays.
    #[inline]
    pub fn shape(&self, a: usize) -> (usize, usize) {
        (self.points.get(a).copied().unwrap_or(2) as usize, self.stride.get(a).copied().unwrap_or(0) as usize)
    }

    /// Axes of the table (0: no table).
    #[inline]
    pub fn n_axes(&self) -> u8 {
        self.n
    }

    /// The table holds the analytic model's residual ([`RawTable::residual`]).
    #[inline]
    pub fn residual(&self) -> bool {
        self.residual
    }

    /// Torque and (when `with_sigma`) σ with axis `a` at angle `x[a]`.
    #[inline]
    pub fn eval(&self, t: &RawTable, x: &[f32; AXES_MAX], with_sigma: bool) -> (f32, f32) {
        self.eval_with(t, |a| x.get(a).copied().unwrap_or(0.0), with_sigma)
    }

    /// Torque and (when `with_sigma`) σ where each axis reads its angle from its source:
    /// `angles = [q, others[0], others[1], others[2]]`.
    #[inline]
    pub fn eval_sources(&self, t: &RawTable, angles: &[f32; 4], with_sigma: bool) -> (f32, f32) {
        self.eval_with(
            t,
            |a| {
                let src = self.source.get(a).copied().unwrap_or(0) as usize;
                angles.get(src).copied().unwrap_or(0.0)
            },
            with_sigma,
        )
    }

    /// Torque and (when `with_sigma`) σ with axis `a` at angle `x(a)`, in one pass over the
    /// cell's corners. Same multilinear interpolation as [`interpolate`], specialised for 1 and
    /// 2 axes.
    #[inline(always)]
    fn eval_with<X: Fn(usize) -> f32>(&self, t: &RawTable, x: X, with_sigma: bool) -> (f32, f32) {
        let v = |i: usize| t.torque.get(i).copied().unwrap_or(0.0);
        let s = |i: usize| if with_sigma { t.sigma.get(i).copied().unwrap_or(0.0) } else { 0.0 };
        match self.n {
            0 => (0.0, 0.0),
            1 => {
                let (i, f) = self.locate(t, 0, x(0));
                let lerp = |a: f32, b: f32| a + f * (b - a);
                (lerp(v(i), v(i + 1)), lerp(s(i), s(i + 1)))
            }
            2 => {
                let (i, f) = self.locate(t, 0, x(0));
                let (j, g) = self.locate(t, 1, x(1));
                let s0 = self.stride.first().copied().unwrap_or(0) as usize;
                let o = i * s0 + j;
                // Two rows of two values each: one bounds check per row, none per value.
                let corners = |a: &[f32; CELLS_MAX]| -> f32 {
                    match (a.get(o..o + 2), a.get(o + s0..o + s0 + 2)) {
                        (Some(&[a00, a01]), Some(&[a10, a11])) => {
                            let lo = a00 + g * (a01 - a00);
                            let hi = a10 + g * (a11 - a10);
                            lo + f * (hi - lo)
                        }
                        _ => 0.0,
                    }
                };
                let tau = corners(&t.torque);
                let sigma = if with_sigma { corners(&t.sigma) } else { 0.0 };
                (tau, sigma)
            }
            n => {
                let n = (n as usize).min(AXES_MAX);
                let mut frac = [0.0f32; AXES_MAX];
                let mut origin = 0usize;
                for axis in 0..n {
                    let (i, f) = self.locate(t, axis, x(axis));
                    origin += i * self.stride.get(axis).copied().unwrap_or(0) as usize;
                    if let Some(fr) = frac.get_mut(axis) {
                        *fr = f;
                    }
                }
                let (mut acc_v, mut acc_s) = (0.0f32, 0.0f32);
                for corner in 0..(1usize << n) {
                    let mut w = 1.0f32;
                    let mut idx = origin;
                    for axis in 0..n {
                        let f = frac.get(axis).copied().unwrap_or(0.0);
                        if corner & (1 << axis) != 0 {
                            w *= f;
                            idx += self.stride.get(axis).copied().unwrap_or(0) as usize;
                        } else {
                            w *= 1.0 - f;
                        }
                    }
                    acc_v += w * v(idx);
                    acc_s += w * s(idx);
                }
                (acc_v, acc_s)
            }
        }
    }
}
