//! The readers' thread pool: as many threads as rayon's global pool, each with a large stack.
//!
//! Decoders that run on several threads run here rather than on the global pool because the
//! LAZ arithmetic decoder recurses deeply on some damaged files: on a global-pool thread's small
//! stack that overflows, and an overflow aborts the process where a panic becomes an error.

use std::sync::OnceLock;

/// Reserved, not committed: untouched stack costs no memory.
const STACK: usize = 1 << 30;

/// The pool, built on first use with the global pool's thread count (so `RAYON_NUM_THREADS`
/// caps reading too); `None` if its threads could not be started.
fn pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: OnceLock<Option<rayon::ThreadPool>> = OnceLock::new();
    POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(rayon::current_num_threads().max(1))
            .stack_size(STACK)
            .thread_name(|i| format!("asbuilt-read-{i}"))
            .build()
            .ok()
    })
    .as_ref()
}

/// Runs `work` in the readers' pool, so the rayon calls inside it share that pool's threads;
/// on the calling thread when there is no pool.
pub(crate) fn install<T: Send>(work: impl FnOnce() -> T + Send) -> T {
    match pool() {
        Some(p) => p.install(work),
        None => work(),
    }
}

/// Threads the readers' pool runs.
pub(crate) fn threads() -> usize {
    pool().map_or(1, |p| p.current_num_threads())
}

/// Reads `blocks` blocks from `reader` with `fill` (block index, buffer to size and fill) and
/// hands each to `use_block` with the fill's outcome, in order. With `ahead`, the next block is
/// read on a thread of its own while the caller decodes the current one, so reading and
/// decoding overlap. Reading stops after a failed fill; `use_block` should then fail too.
pub(crate) fn read_ahead<R, F, E>(
    reader: &mut R,
    blocks: usize,
    ahead: bool,
    mut fill: impl FnMut(&mut R, usize, &mut Vec<u8>) -> Result<(), F> + Send,
    mut use_block: impl FnMut(usize, &[u8], Result<(), F>) -> Result<(), E>,
) -> Result<(), E>
where
    R: Send,
    F: Send,
{
    if !ahead || blocks < 2 {
        let mut buf = Vec::new();
        for k in 0..blocks {
            let filled = fill(reader, k, &mut buf);
            let failed = filled.is_err();
            use_block(k, &buf, filled)?;
            if failed {
                break;
            }
        }
        return Ok(());
    }
    std::thread::scope(|s| {
        // Two buffers: one being read, one being decoded.
        let (full_tx, full_rx) = std::sync::mpsc::sync_channel::<(Vec<u8>, Result<(), F>)>(1);
        let (empty_tx, empty_rx) = std::sync::mpsc::sync_channel::<Vec<u8>>(2);
        let _ = empty_tx.send(Vec::new());
        let _ = empty_tx.send(Vec::new());
        s.spawn(move || {
            for k in 0..blocks {
                let Ok(mut buf) = empty_rx.recv() else {
                    return;
                };
                let filled = fill(reader, k, &mut buf);
                let failed = filled.is_err();
                if full_tx.send((buf, filled)).is_err() || failed {
                    return;
                }
            }
        });
        for k in 0..blocks {
            // A closed channel means the reading thread panicked: the scope rethrows that.
            let Ok((buf, filled)) = full_rx.recv() else {
                break;
            };
            let failed = filled.is_err();
            use_block(k, &buf, filled)?;
            if failed {
                break;
            }
            let _ = empty_tx.send(buf);
        }
        Ok(())
    })
}
