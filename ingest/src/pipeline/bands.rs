//! Rows in bands: the one loop that computes a map's rows in parallel and hands them on in
//! order, used by the in-memory build, the PNG writer (coverage and structure images) and the
//! GeoTIFF writer (structure page and coverage). A few bands per core are in flight at a time,
//! so a 6500×5500 map never holds more than those in memory.

use rayon::prelude::*;

/// Rows in one band.
const BAND_ROWS: usize = 32;

/// Rows `0..height` in bands of [`BAND_ROWS`].
pub(super) fn bands(height: usize) -> Vec<(usize, usize)> {
    (0..height.div_ceil(BAND_ROWS))
        .map(|b| (b * BAND_ROWS, ((b + 1) * BAND_ROWS).min(height)))
        .collect()
}

/// Stream rows `0..height` band by band: `compute(j0, j1)` makes each band's part, a few bands
/// per core at a time in parallel; `take` receives the parts in row order; after each group,
/// `group_done` is told how many rows have been taken. The first error of `take` stops it.
pub(super) fn stream_bands<T: Send, E>(
    height: usize,
    compute: impl Fn(usize, usize) -> T + Sync,
    mut take: impl FnMut(T) -> Result<(), E>,
    mut group_done: impl FnMut(usize),
) -> Result<(), E> {
    let bands = bands(height);
    let mut done = 0;
    // A few bands per core at a time bounds memory; order is kept by `collect`.
    for group in bands.chunks(rayon::current_num_threads().max(1) * 2) {
        let parts: Vec<T> = group.par_iter().map(|&(a, b)| compute(a, b)).collect();
        for (part, &(a, b)) in parts.into_iter().zip(group) {
            take(part)?;
            done += b - a;
        }
        group_done(done);
    }
    Ok(())
}
