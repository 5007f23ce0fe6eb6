//! Long series reduced to what a screen can show without losing what matters on it.
//!
//! - [`m4`]: a line of many samples becomes, per pixel column, its first, smallest, largest and
//!   last sample in time order (M4, Jugel et al. 2014). Drawn as a line this is the same picture
//!   at that width as the whole series — every spike and the full band of the noise — from at
//!   most four points a column instead of a blur of 120 000.
//! - [`pixel_dedupe`]: a scatter keeps one point per occupied pixel cell.
//! - [`pyramid`]: min/max levels of a series, coarser by a factor of four each, that the
//!   interactive view picks from as it zooms.

/// (sample index, x, y) of one of a column's first, min, max and last samples.
type Pick = (usize, f64, f64);

/// Samples `(x, y)` of one column of pixels: first, min, max, last in the order they came.
pub fn m4(x: &[f64], y: &[f64], x0: f64, x1: f64, columns: usize) -> Vec<(f64, f64)> {
    let columns = columns.max(1);
    let w = x1 - x0;
    if !(w.is_finite() && w > 0.0) {
        return x.iter().zip(y).map(|(a, b)| (*a, *b)).filter(|(a, b)| a.is_finite() && b.is_finite()).collect();
    }
    let mut out = Vec::with_capacity(4 * columns);
    // (column, first, min, max, last) of the column being filled; samples are taken in order,
    // so a series that goes back in x starts a new run of the same column (still exact)
    let mut cur: Option<(i64, [Pick; 4])> = None;
    let flush = |out: &mut Vec<(f64, f64)>, c: &[Pick; 4]| {
        let mut pts = *c;
        pts.sort_by_key(|p| p.0);
        let mut last = usize::MAX;
        for (i, a, b) in pts {
            if i != last {
                out.push((a, b));
                last = i;
            }
        }
    };
    for (i, (&a, &b)) in x.iter().zip(y).enumerate() {
        if !(a.is_finite() && b.is_finite()) {
            continue;
        }
        let col = (((a - x0) / w) * columns as f64).floor().clamp(-1.0, columns as f64) as i64;
        let p = (i, a, b);
        match &mut cur {
            Some((c, [_, mn, mx, last])) if *c == col => {
                if b < mn.2 {
                    *mn = p;
                }
                if b > mx.2 {
                    *mx = p;
                }
                *last = p;
            }
            _ => {
                if let Some((_, c)) = &cur {
                    flush(&mut out, c);
                }
                cur = Some((col, [p; 4]));
            }
        }
    }
    if let Some((_, c)) = &cur {
        flush(&mut out, c);
    }
    out
}

/// One point per occupied cell of `cell` pixels, the first that falls in it; `to_px` maps a
/// point to pixels.
pub fn pixel_dedupe(pts: &[(f64, f64)], cell: f64, to_px: impl Fn(f64, f64) -> (f64, f64)) -> Vec<(f64, f64)> {
    let mut seen = std::collections::HashSet::new();
    let cell = cell.max(0.5);
    pts.iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .filter(|&(x, y)| {
            let (px, py) = to_px(x, y);
            seen.insert(((px / cell).floor() as i64, (py / cell).floor() as i64))
        })
        .collect()
}

/// One level of a min/max pyramid: buckets of `bucket` consecutive samples, each with the x of
/// its first sample and the y range of all of them.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    pub bucket: usize,
    pub x: Vec<f64>,
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
}

/// Level 0 is the series itself (lo = hi = y); each further level merges four buckets of the
/// one before, until fewer than `min_buckets` would remain. Non-finite samples are left out.
pub fn pyramid(x: &[f64], y: &[f64], min_buckets: usize) -> Vec<Level> {
    let (xs, ys): (Vec<f64>, Vec<f64>) =
        x.iter().zip(y).filter(|(a, b)| a.is_finite() && b.is_finite()).map(|(a, b)| (*a, *b)).unzip();
    let mut levels = vec![Level { bucket: 1, x: xs, lo: ys.clone(), hi: ys }];
    while let Some(prev) = levels.last() {
        if prev.x.len() / 4 < min_buckets.max(1) {
            break;
        }
        let next = Level {
            bucket: prev.bucket * 4,
            x: prev.x.chunks(4).filter_map(|c| c.first().copied()).collect(),
            lo: prev.lo.chunks(4).map(|c| c.iter().copied().fold(f64::INFINITY, f64::min)).collect(),
            hi: prev.hi.chunks(4).map(|c| c.iter().copied().fold(f64::NEG_INFINITY, f64::max)).collect(),
        };
        levels.push(next);
    }
    levels
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    fn series(n: usize) -> (Vec<f64>, Vec<f64>) {
        let x: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        // a slow sine with a pseudo-random noise and a few single-sample spikes
        let mut s = 12345u64;
        let y = x
            .iter()
            .enumerate()
            .map(|(i, t)| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let noise = ((s >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 0.2;
                let spike = if i % 30_011 == 7 { 5.0 } else { 0.0 };
                (t * 0.3).sin() + noise + spike
            })
            .collect();
        (x, y)
    }

    #[test]
    fn m4_keeps_every_columns_min_and_max_and_the_ends() {
        let (x, y) = series(120_000);
        let (x0, x1, cols) = (0.0, 120.0, 600);
        let r = m4(&x, &y, x0, x1, cols);
        assert!(r.len() <= 4 * cols && r.len() >= 2 * cols, "{} points", r.len());
        // per column, the reduced series has the same min and max as the full one
        let col = |v: f64| ((v - x0) / (x1 - x0) * cols as f64).floor() as usize;
        let (mut lo, mut hi) = (vec![f64::INFINITY; cols + 1], vec![f64::NEG_INFINITY; cols + 1]);
        for (a, b) in x.iter().zip(&y) {
            lo[col(*a)] = lo[col(*a)].min(*b);
            hi[col(*a)] = hi[col(*a)].max(*b);
        }
        let (mut rlo, mut rhi) = (vec![f64::INFINITY; cols + 1], vec![f64::NEG_INFINITY; cols + 1]);
        for (a, b) in &r {
            rlo[col(*a)] = rlo[col(*a)].min(*b);
            rhi[col(*a)] = rhi[col(*a)].max(*b);
        }
        assert_eq!(lo, rlo);
        assert_eq!(hi, rhi);
        // the spikes survive, the points stay in time order, and the ends are the series' ends
        assert_eq!(r.iter().filter(|p| p.1 > 4.0).count(), y.iter().filter(|v| **v > 4.0).count());
        assert!(r.windows(2).all(|w| w[0].0 <= w[1].0));
        assert_eq!(r.first().unwrap(), &(x[0], y[0]));
        assert_eq!(r.last().unwrap(), &(*x.last().unwrap(), *y.last().unwrap()));
    }

    #[test]
    fn m4_of_a_short_series_is_the_series() {
        let x = [0.0, 1.0, 2.0, f64::NAN, 4.0];
        let y = [1.0, 3.0, 2.0, 0.0, 5.0];
        assert_eq!(m4(&x, &y, 0.0, 4.0, 100), vec![(0.0, 1.0), (1.0, 3.0), (2.0, 2.0), (4.0, 5.0)]);
    }

    #[test]
    fn pyramid_levels_keep_the_range_of_their_buckets() {
        let (x, y) = series(10_000);
        let p = pyramid(&x, &y, 100);
        assert_eq!(p[0].lo, y);
        assert!(p.len() >= 3 && p.last().unwrap().x.len() >= 100);
        for w in p.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            assert_eq!(b.bucket, 4 * a.bucket);
            for (k, (lo, hi)) in b.lo.iter().zip(&b.hi).enumerate() {
                let part = k * 4..(k * 4 + 4).min(a.lo.len());
                assert_eq!(*lo, a.lo[part.clone()].iter().copied().fold(f64::INFINITY, f64::min));
                assert_eq!(*hi, a.hi[part].iter().copied().fold(f64::NEG_INFINITY, f64::max));
            }
        }
        let top = p.last().unwrap();
        assert_eq!(
            top.lo.iter().copied().fold(f64::INFINITY, f64::min),
            y.iter().copied().fold(f64::INFINITY, f64::min)
        );
        assert_eq!(
            top.hi.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            y.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        );
    }

    #[test]
    fn a_scatter_keeps_one_point_per_pixel_cell() {
        let pts: Vec<(f64, f64)> = (0..10_000).map(|i| ((i % 100) as f64, (i / 100) as f64 * 0.01)).collect();
        // 100 distinct x and y all within one 2-pixel row band: 50 cells
        let r = pixel_dedupe(&pts, 2.0, |x, y| (x, y));
        assert_eq!(r.len(), 50);
    }
}
