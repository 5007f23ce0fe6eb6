//! Order statistics without sorting: the k-th smallest by selection (O(n)), the same element a
//! sort would put at k, so a result does not change when a sort is replaced by this.

/// The element at index `k` (clamped) of `v` in ascending `total_cmp` order; `v` is reordered.
/// `None` when `v` is empty.
pub fn kth(v: &mut [f64], k: usize) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let k = k.min(v.len() - 1);
    let (_, x, _) = v.select_nth_unstable_by(k, f64::total_cmp);
    Some(*x)
}

/// The `p`-quantile as the element at `round((n − 1)·p)` in ascending order; `v` is reordered.
pub fn at_rounded(v: &mut [f64], p: f64) -> Option<f64> {
    let k = ((v.len().max(1) - 1) as f64 * p).round() as usize;
    kth(v, k)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn selection_gives_the_sorted_element() {
        let mut x: u64 = 7;
        let v: Vec<f64> = (0..1001)
            .map(|_| {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let mut sorted = v.clone();
        sorted.sort_by(f64::total_cmp);
        for p in [0.0, 0.01, 0.5, 0.95, 0.99, 1.0] {
            let k = ((v.len() - 1) as f64 * p).round() as usize;
            assert_eq!(at_rounded(&mut v.clone(), p), Some(sorted[k]), "p = {p}");
        }
        assert_eq!(kth(&mut [], 0), None);
        assert_eq!(kth(&mut v.clone(), 5000), Some(sorted[1000]), "clamped");
    }
}
