//! Worker pools for the runs, optionally with each worker pinned to a core
//! (`core_affinity`), so a benchmark's threads do not migrate between cores.

use rayon::{ThreadPool, ThreadPoolBuildError, ThreadPoolBuilder};

/// A rayon pool of `threads` workers; with `pin`, worker i is pinned to core i (modulo the
/// cores the operating system reports). Pinning is best effort: a core that cannot be
/// taken leaves the thread unpinned.
pub fn pool(threads: usize, pin: bool) -> Result<ThreadPool, ThreadPoolBuildError> {
    let mut builder = ThreadPoolBuilder::new().num_threads(threads);
    if pin {
        let cores = core_affinity::get_core_ids().unwrap_or_default();
        if !cores.is_empty() {
            builder = builder.start_handler(move |i| {
                let _ = core_affinity::set_for_current(cores[i % cores.len()]);
            });
        }
    }
    builder.build()
}
