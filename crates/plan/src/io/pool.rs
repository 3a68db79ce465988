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
