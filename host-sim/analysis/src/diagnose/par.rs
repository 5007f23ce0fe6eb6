//! The diagnosis's one way of spreading candidate fits over threads.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Runs `work` on every job on up to `threads` threads and returns the results in the jobs'
/// order, so the outcome does not depend on the schedule. Jobs differ a lot in cost (a grid
/// search against one fit), so the threads take the next job from a shared counter instead of
/// fixed halves, lowest `rank` first (rank the costliest 0). A panicking worker is a bug: it
/// is re-raised here rather than its jobs dropped.
pub(crate) fn costliest_first<J, T, W>(jobs: &[J], threads: usize, rank: impl Fn(&J) -> u8, work: W) -> Vec<T>
where
    J: Sync,
    T: Send,
    W: Fn(&J) -> T + Sync,
{
    if threads <= 1 || jobs.len() < 2 {
        return jobs.iter().map(&work).collect();
    }
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by_key(|&i| rank(&jobs[i]));
    let next = AtomicUsize::new(0);
    let mut out: Vec<(usize, T)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads.min(jobs.len()))
            .map(|_| {
                let (work, next, order) = (&work, &next, &order);
                s.spawn(move || {
                    let mut done = Vec::new();
                    while let Some(&pos) = order.get(next.fetch_add(1, Ordering::Relaxed)) {
                        done.push((pos, work(&jobs[pos])));
                    }
                    done
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e))).collect()
    });
    out.sort_by_key(|(pos, _)| *pos);
    out.into_iter().map(|(_, t)| t).collect()
}

/// The threads to spread work over: the available cores, at most `max`.
pub(crate) fn cores(max: usize) -> usize {
    std::thread::available_parallelism().map(|t| t.get()).unwrap_or(1).clamp(1, max)
}

/// `f` over `0..n` in contiguous chunks on the available cores, the per-sample results in
/// sample order: the same numbers as one loop (each sample is computed alone).
pub(crate) fn per_sample<T, F>(n: usize, f: F) -> Vec<T>
where
    T: Send,
    F: Fn(usize) -> T + Sync,
{
    let threads = cores(8);
    if threads == 1 || n < 50_000 {
        return (0..n).map(&f).collect();
    }
    let chunk = n.div_ceil(4 * threads);
    let ranges: Vec<std::ops::Range<usize>> = (0..n).step_by(chunk).map(|a| a..(a + chunk).min(n)).collect();
    costliest_first(&ranges, threads, |_| 0, |r| r.clone().map(&f).collect::<Vec<T>>()).into_iter().flatten().collect()
}

/// `f` on a zeroed row buffer of `p` values (on the stack up to 32, the usual design width),
/// for per-sample passes that cannot share one buffer across threads.
pub(crate) fn with_row<R>(p: usize, f: impl FnOnce(&mut [f64]) -> R) -> R {
    let mut buf = [0.0; 32];
    match buf.get_mut(..p) {
        Some(x) => f(x),
        None => f(&mut vec![0.0; p]),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn results_keep_the_jobs_order_whatever_the_schedule() {
        let jobs: Vec<u32> = (0..50).collect();
        let out = costliest_first(&jobs, 2, |&j| (j % 3) as u8, |&j| j * j);
        assert_eq!(out, jobs.iter().map(|j| j * j).collect::<Vec<_>>());
        assert_eq!(costliest_first(&jobs, 1, |_| 0, |&j| j + 1)[49], 50);
    }

    #[test]
    fn per_sample_keeps_the_order() {
        let v = per_sample(200_001, |i| i as u64 * 3);
        assert_eq!(v.len(), 200_001);
        assert!(v.iter().enumerate().all(|(i, &x)| x == i as u64 * 3));
    }
}
