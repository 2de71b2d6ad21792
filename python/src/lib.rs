//! The native part of the `sparse_levelset` Python package (`sparse_levelset._native`).
//!
//! The Python layer (`python/sparse_levelset/__init__.py`) takes NumPy arrays in any float
//! dtype and memory order, checks shapes and names, and calls these functions with
//! float32 arrays that are C- or Fortran-contiguous; everything here works on the
//! library's types. Long calls run on a worker thread with the GIL released while the
//! calling thread watches for Ctrl-C and forwards progress (the `watch` module).

use pyo3::exceptions::{
    PyKeyboardInterrupt, PyMemoryError, PyOSError, PyRuntimeError, PyValueError,
};
use pyo3::prelude::*;
use sparse_levelset::{Error, ErrorKind};
use std::fmt::Display;

mod arrays;
mod functions;
mod levelset;
mod segment;
mod simulation;
mod watch;

/// A `ValueError` with the library's message (bad arrays and parameters).
pub(crate) fn value_error(e: impl Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// The exception of a library error, chosen by its kind (never by its message):
/// `MemoryError` when the process cannot hold the result, `KeyboardInterrupt` when a
/// progress callback or Ctrl-C stopped the call, `OSError` for files that cannot be read or
/// written (missing, unreadable, corrupt, in a variant of their format that is not read),
/// `RuntimeError` for a computation that failed (an interface that collapsed), and
/// `ValueError` for arguments, data and file names (extensions) the library does not take.
pub(crate) fn lib_error(e: impl Error) -> PyErr {
    let msg = e.to_string();
    match e.kind() {
        ErrorKind::OutOfMemory => PyMemoryError::new_err(msg),
        ErrorKind::Cancelled => PyKeyboardInterrupt::new_err(msg),
        ErrorKind::Io | ErrorKind::CorruptFile | ErrorKind::Unsupported => PyOSError::new_err(msg),
        ErrorKind::Failed => PyRuntimeError::new_err(msg),
        _ => PyValueError::new_err(msg),
    }
}

/// A thread pool of `threads` threads (`None`: the global pool).
pub(crate) fn pool(threads: Option<usize>) -> PyResult<Option<std::sync::Arc<rayon::ThreadPool>>> {
    match threads {
        None => Ok(None),
        Some(0) => Err(value_error("threads must be at least 1")),
        Some(n) => Ok(Some(std::sync::Arc::new(
            rayon::ThreadPoolBuilder::new().num_threads(n).build().map_err(value_error)?,
        ))),
    }
}

/// A bug: the library panicked (caught on the worker thread, never an abort).
pub(crate) fn panic_error(what: &str) -> PyErr {
    PyRuntimeError::new_err(format!(
        "internal error in sparse_levelset ({what}); please report it with the input"
    ))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("SIMD_LANES", if cfg!(feature = "simd") { "simd" } else { "scalar" })?;
    // A level forced by LEVELSET_SIMD that this CPU cannot run is refused, not replaced.
    sparse_levelset::level::check_env().map_err(pyo3::exceptions::PyImportError::new_err)?;
    m.add("SIMD_LEVEL", sparse_levelset::level::Level::active().name())?;
    functions::register(m)?;
    levelset::register(m)?;
    simulation::register(m)?;
    segment::register(m)?;
    Ok(())
}
