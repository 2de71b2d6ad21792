//! Progress and cancellation of long operations, a field of each tool's options (as
//! OpenVDB passes an `InterruptT`), not a second family of functions.
//!
//! ```
//! use sparse_levelset::progress::Progress;
//! use std::sync::atomic::{AtomicU64, Ordering};
//! use std::sync::Arc;
//!
//! let seen = Arc::new(AtomicU64::new(0));
//! let s = seen.clone();
//! // Report how far the work is; return false to cancel it.
//! let progress = Progress::new(move |done, _total| {
//!     s.store(done, Ordering::Relaxed);
//!     true
//! });
//! let ticker = progress.start(10);
//! ticker.advance(4).unwrap();
//! ticker.advance(6).unwrap();
//! assert_eq!(seen.load(Ordering::Relaxed), 10);
//! ```

use std::fmt;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// The callback type: `(units done, units in all)`; `false` asks the work to stop.
type Callback = dyn Fn(u64, u64) -> bool + Send + Sync;

/// An optional progress callback, called from worker threads as parts of the work finish
/// (in any order; the counts only grow). Returning `false` cancels the operation, which
/// then fails with its `Cancelled` error and changes nothing. The default reports nothing.
#[derive(Clone, Default)]
pub struct Progress(Option<Arc<Callback>>);

impl Progress {
    /// Reports to `f(done, total)`; `f` returns `false` to cancel.
    pub fn new(f: impl Fn(u64, u64) -> bool + Send + Sync + 'static) -> Self {
        Progress(Some(Arc::new(f)))
    }

    /// No reports, no cancellation.
    pub fn none() -> Self {
        Progress(None)
    }

    /// Whether a callback listens (an operation may skip counting its work otherwise).
    pub fn is_active(&self) -> bool {
        self.0.is_some()
    }

    /// Starts counting an operation of `total` units.
    pub fn start(&self, total: u64) -> Ticker<'_> {
        Ticker { progress: self, total, done: AtomicU64::new(0), cancelled: AtomicBool::new(false) }
    }
}

impl fmt::Debug for Progress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(if self.0.is_some() { "Progress(callback)" } else { "Progress(none)" })
    }
}

/// Two options are equal whatever their callbacks (a callback has no value to compare).
impl PartialEq for Progress {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// The operation was cancelled through its [`Progress`] callback.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("cancelled")]
pub struct Cancelled;

/// The counter of one running operation, shared by its worker threads.
pub struct Ticker<'a> {
    progress: &'a Progress,
    total: u64,
    done: AtomicU64,
    cancelled: AtomicBool,
}

impl Ticker<'_> {
    /// Adds `units` finished units and reports; `Err(Cancelled)` once the callback has
    /// asked to stop (then also for every later call, from any thread).
    pub fn advance(&self, units: u64) -> Result<(), Cancelled> {
        let Some(f) = &self.progress.0 else { return Ok(()) };
        let done = self.done.fetch_add(units, Ordering::Relaxed) + units;
        if !f(done.min(self.total), self.total) {
            self.cancelled.store(true, Ordering::Relaxed);
        }
        self.check()
    }

    /// Reports that `done` units are finished in all (for work that knows its position
    /// rather than its increments; the count never goes back).
    pub fn set(&self, done: u64) -> Result<(), Cancelled> {
        let Some(f) = &self.progress.0 else { return Ok(()) };
        let done = self.done.fetch_max(done, Ordering::Relaxed).max(done);
        if !f(done.min(self.total), self.total) {
            self.cancelled.store(true, Ordering::Relaxed);
        }
        self.check()
    }

    /// `Err(Cancelled)` once the callback has asked to stop.
    pub fn check(&self) -> Result<(), Cancelled> {
        if self.cancelled.load(Ordering::Relaxed) {
            Err(Cancelled)
        } else {
            Ok(())
        }
    }
}
