//! A local worker pool. With one thread everything runs on the calling thread and rayon's
//! global pool is never touched; with more, work runs on a pool owned by the solve. Callers
//! split work into a fixed list of tasks (by the thread count) and combine the results in task
//! order, so results are deterministic for a fixed thread count. Without the `rayon` feature
//! the same tasks run one after the other on the calling thread: the results are the same.

#[cfg(feature = "rayon")]
use rayon::prelude::*;

use crate::error::Result;

/// Runs lists of tasks on one or more threads.
pub(crate) struct Executor {
    #[cfg(feature = "rayon")]
    pool: Option<rayon::ThreadPool>,
    threads: usize,
}

impl Executor {
    /// An executor with `threads` workers (at least 1).
    #[cfg(feature = "rayon")]
    pub(crate) fn new(threads: usize) -> Result<Self> {
        let threads = threads.max(1);
        let pool = if threads > 1 {
            Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .map_err(|e| crate::BundleAdjustError::ThreadPool {
                        threads,
                        reason: e.to_string(),
                    })?,
            )
        } else {
            None
        };
        Ok(Self { pool, threads })
    }

    /// An executor that splits work for `threads` workers (at least 1) and runs it on the
    /// calling thread.
    #[cfg(not(feature = "rayon"))]
    #[allow(clippy::unnecessary_wraps)]
    pub(crate) fn new(threads: usize) -> Result<Self> {
        Ok(Self {
            threads: threads.max(1),
        })
    }

    /// Number of worker threads.
    pub(crate) fn threads(&self) -> usize {
        self.threads
    }

    /// Applies `f` to every task and returns the results in task order.
    pub(crate) fn map<T: Send, R: Send>(
        &self,
        tasks: Vec<T>,
        f: impl Fn(T) -> R + Sync + Send,
    ) -> Vec<R> {
        #[cfg(feature = "rayon")]
        {
            if let Some(pool) = &self.pool
                && tasks.len() > 1
            {
                return pool.install(|| tasks.into_par_iter().map(f).collect());
            }
        }
        tasks.into_iter().map(f).collect()
    }
}

/// Splits `data` into consecutive pieces ending at the offsets in `ends` (ascending, the last
/// one `data.len()` or less).
pub(crate) fn split_at_offsets<'a, T>(mut data: &'a mut [T], ends: &[usize]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(ends.len());
    let mut consumed = 0;
    for &end in ends {
        let (head, tail) = data.split_at_mut(end - consumed);
        out.push(head);
        data = tail;
        consumed = end;
    }
    out
}

/// Splits `0..n` into `parts` consecutive ranges of about equal total `weight`.
pub(crate) fn balanced_ranges(
    n: usize,
    parts: usize,
    weight: impl Fn(usize) -> usize,
) -> Vec<core::ops::Range<usize>> {
    let parts = parts.max(1);
    let total: usize = (0..n).map(&weight).sum();
    let mut ranges = Vec::with_capacity(parts);
    let mut start = 0;
    let mut acc = 0usize;
    let mut i = 0;
    for p in 1..=parts {
        let target = total * p / parts;
        while i < n && (acc < target || p == parts) {
            acc += weight(i);
            i += 1;
        }
        ranges.push(start..i);
        start = i;
    }
    ranges
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balanced_ranges_cover_everything() {
        let w = |i: usize| i % 7 + 1;
        for parts in 1..6 {
            let r = balanced_ranges(100, parts, w);
            assert_eq!(r.len(), parts);
            assert_eq!(r[0].start, 0);
            assert_eq!(r[parts - 1].end, 100);
            for k in 1..parts {
                assert_eq!(r[k].start, r[k - 1].end);
            }
        }
        assert_eq!(balanced_ranges(0, 3, w), vec![0..0, 0..0, 0..0]);
    }

    #[test]
    fn split_at_offsets_splits() {
        let mut v: Vec<usize> = (0..10).collect();
        let parts = split_at_offsets(&mut v, &[3, 3, 7, 10]);
        let lens: Vec<usize> = parts.iter().map(|p| p.len()).collect();
        assert_eq!(lens, vec![3, 0, 4, 3]);
    }
}
