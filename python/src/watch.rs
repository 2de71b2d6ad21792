//! Long calls: the work runs on a scoped worker thread while the calling thread, with the
//! GIL released between looks, checks for Ctrl-C (`PyErr_CheckSignals` acts only on the
//! main thread, so it cannot be called from inside the work) and hands the latest
//! progress to the user's callback. A signal or an exception in the callback cancels the
//! work through the library's [`Progress`] (or a monitor's `false`), and the exception is
//! raised once the worker has stopped: nothing keeps running behind the caller's back.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use sparse_levelset::progress::Progress;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::Duration;

/// How often the waiting thread looks for signals and progress.
const TICK: Duration = Duration::from_millis(50);

/// What the work and the waiting thread share: the latest progress report and the cancel
/// flag. A library [`Progress`] (called for every finished part, from every worker) writes
/// two atomics; a monitor (once per step) a list of named numbers.
#[derive(Default)]
pub struct Watch {
    latest: Mutex<Option<Vec<(&'static str, f64)>>>,
    done: AtomicU64,
    total: AtomicU64,
    counted: AtomicBool,
    cancel: AtomicBool,
}

impl Watch {
    /// Records a report for the callback; false once the call is cancelled (a monitor's
    /// answer).
    pub fn report(&self, values: Vec<(&'static str, f64)>) -> bool {
        if let Ok(mut l) = self.latest.lock() {
            *l = Some(values);
        }
        !self.cancelled()
    }

    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// A library [`Progress`] reporting `done` and `total` here and stopping on cancel.
    pub fn progress(self: &Arc<Self>) -> Progress {
        let w = Arc::clone(self);
        Progress::new(move |done, total| {
            w.done.fetch_max(done, Ordering::Relaxed);
            w.total.store(total, Ordering::Relaxed);
            w.counted.store(true, Ordering::Relaxed);
            !w.cancelled()
        })
    }

    /// The report not yet handed to the callback, if any.
    fn pending(&self) -> Option<Vec<(&'static str, f64)>> {
        if self.counted.swap(false, Ordering::Relaxed) {
            let done = self.done.load(Ordering::Relaxed) as f64;
            return Some(vec![
                ("done", done),
                ("total", self.total.load(Ordering::Relaxed) as f64),
            ]);
        }
        self.latest.lock().ok().and_then(|mut l| l.take())
    }
}

/// Runs `work` on a worker thread and waits for it, forwarding progress to `callback`
/// (called with a dict of the latest report) and turning Ctrl-C into `KeyboardInterrupt`.
pub fn run<R: Send>(
    py: Python<'_>,
    callback: Option<&Bound<'_, PyAny>>,
    what: &str,
    work: impl FnOnce(&Arc<Watch>) -> R + Send,
) -> PyResult<R> {
    let watch = Arc::new(Watch::default());
    let (tx, rx) = mpsc::channel();
    let rx = Mutex::new(rx);
    std::thread::scope(|scope| {
        let w = Arc::clone(&watch);
        scope.spawn(move || {
            let _ = tx.send(catch_unwind(AssertUnwindSafe(|| work(&w))));
        });
        let mut error: Option<PyErr> = None;
        loop {
            match py.detach(|| match rx.lock() {
                Ok(rx) => rx.recv_timeout(TICK),
                Err(_) => Err(mpsc::RecvTimeoutError::Disconnected),
            }) {
                Ok(Ok(r)) => {
                    // The last report (a short call may end before the first look): the
                    // callback sees the work's final progress.
                    if let (None, Some(cb), Some(values)) = (&error, callback, watch.pending()) {
                        forward(py, cb, values)?;
                    }
                    return error.map_or(Ok(r), Err);
                }
                Ok(Err(_)) => return Err(crate::panic_error(what)),
                Err(mpsc::RecvTimeoutError::Disconnected) => return Err(crate::panic_error(what)),
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
            if error.is_some() {
                continue;
            }
            if let Err(e) = py.check_signals() {
                error = Some(e);
            } else if let Some(cb) = callback {
                if let Some(values) = watch.pending() {
                    if let Err(e) = forward(py, cb, values) {
                        error = Some(e);
                    }
                }
            }
            if error.is_some() {
                watch.cancel.store(true, Ordering::Relaxed);
            }
        }
    })
}

/// Calls the user's callback with a report as a dict (whole numbers as ints).
fn forward(
    py: Python<'_>,
    cb: &Bound<'_, PyAny>,
    values: Vec<(&'static str, f64)>,
) -> PyResult<()> {
    let d = PyDict::new(py);
    for (k, v) in values {
        if v.fract() == 0.0 && v.abs() < 9.0e15 {
            d.set_item(k, v as i64)?;
        } else {
            d.set_item(k, v)?;
        }
    }
    cb.call1((d,))?;
    Ok(())
}
