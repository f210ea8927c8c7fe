//! Order-preserving maps over slices: in parallel with the `rayon` feature, on the calling
//! thread without it. Each item is computed on its own and results are returned in item order,
//! so the results do not depend on the feature or the thread count.

/// `f(index, item)` for every item of `items`, in item order (in parallel with the `rayon`
/// feature, in chunks of at least `min_len` items).
pub(crate) fn map_indexed<T: Sync, R: Send>(
    items: &[T],
    min_len: usize,
    f: impl Fn(usize, &T) -> R + Sync + Send,
) -> Vec<R> {
    #[cfg(feature = "rayon")]
    {
        use rayon::prelude::*;
        items
            .par_iter()
            .enumerate()
            .with_min_len(min_len.max(1))
            .map(|(i, item)| f(i, item))
            .collect()
    }
    #[cfg(not(feature = "rayon"))]
    {
        let _ = min_len;
        items
            .iter()
            .enumerate()
            .map(|(i, item)| f(i, item))
            .collect()
    }
}

/// The results in order, or the first error in item order (whatever the thread count).
pub(crate) fn first_error<R, E>(results: Vec<Result<R, E>>) -> Result<Vec<R>, E> {
    results.into_iter().collect()
}
