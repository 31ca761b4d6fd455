//! Running a CPU twin's independent rows (or bands of rows) on several
//! threads when the image is large, and on the calling thread otherwise.
//!
//! Every twin writes each output row from its inputs alone, so the order in
//! which rows run does not change a single bit of the result: the threaded
//! and the single-threaded runs are bit-identical. Small images stay on the
//! calling thread because handing rows to rayon's pool costs more than it
//! saves below [`PARALLEL_PIXELS`].

use rayon::iter::{IndexedParallelIterator, ParallelIterator};

/// Images with at least this many pixels have their rows processed on
/// several threads.
pub(crate) const PARALLEL_PIXELS: usize = 1 << 16;

/// Whether an image of `pixels` pixels has its rows spread over threads:
/// at least [`PARALLEL_PIXELS`] of them, and a pool of more than one thread
/// (a pool of one would only add a hand-over to it and a wake-up of the
/// caller per call).
pub(crate) fn parallel(pixels: usize) -> bool {
    pixels >= PARALLEL_PIXELS && rayon::current_num_threads() > 1
}

/// Run `body` on every item of `rows` (one item per row or band of rows,
/// e.g. zipped `par_chunks_mut(width)` of the output planes), spread over
/// rayon's pool when [`parallel`] says so for `pixels`, in order on the
/// calling thread otherwise.
pub(crate) fn for_each_row<I>(pixels: usize, rows: I, body: impl Fn(I::Item) + Sync + Send)
where
    I: IndexedParallelIterator,
{
    if parallel(pixels) {
        rows.for_each(body);
    } else {
        // A minimum piece length above the item count keeps rayon from
        // splitting: the whole iterator runs as one sequential piece on
        // this thread.
        rows.with_min_len(usize::MAX).for_each(body);
    }
}

/// Where the row pass's output rows of a `height`-row image sit in a buffer
/// of `width`-wide rows: row `v` (clamped to the image) in slot `v % slots`.
/// `slots = height` is the whole image; fewer slots make a ring of the rows
/// the vertical pass still needs.
#[derive(Clone, Copy)]
pub(crate) struct RowStore {
    /// Row length.
    pub(crate) width: usize,
    /// Rows of the image.
    pub(crate) height: usize,
    /// Rows the buffer holds.
    pub(crate) slots: usize,
}

impl RowStore {
    /// Row `v` (clamped to the image) of `buf`.
    #[inline(always)]
    pub(crate) fn row(self, buf: &[f32], v: isize) -> &[f32] {
        let s = v.clamp(0, self.height as isize - 1) as usize % self.slots;
        &buf[s * self.width..(s + 1) * self.width]
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use rayon::prelude::*;

    use super::*;

    /// Below the threshold every row runs on the calling thread, in order;
    /// at the threshold every row runs exactly once, and the results agree.
    #[test]
    fn small_images_stay_on_this_thread_and_both_paths_agree() {
        let width = 256;
        let rows = PARALLEL_PIXELS / width;
        let src: Vec<f32> = (0..width * rows).map(|i| (i as f32 * 0.37).sin()).collect();
        let row_body = |(y, (s, d)): (usize, (&[f32], &mut [f32]))| {
            for (o, &v) in d.iter_mut().zip(s) {
                *o = v * v + y as f32;
            }
        };

        let order = Mutex::new(Vec::new());
        let mut small = vec![0.0; src.len()];
        for_each_row(PARALLEL_PIXELS - 1, src.par_chunks(width).zip(small.par_chunks_mut(width)).enumerate(), |r| {
            assert!(rayon::current_thread_index().is_none(), "row {} ran on a pool thread", r.0);
            order.lock().unwrap().push(r.0);
            row_body(r);
        });
        assert_eq!(order.into_inner().unwrap(), (0..rows).collect::<Vec<_>>());

        let mut large = vec![0.0; src.len()];
        for_each_row(PARALLEL_PIXELS, src.par_chunks(width).zip(large.par_chunks_mut(width)).enumerate(), row_body);
        assert_eq!(
            small.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            large.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
    }
}
