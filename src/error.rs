//! One classification for every error of the library: each error type answers
//! [`Error::kind`], so that a front end (the command line, Python) chooses its response —
//! an exit code, an exception class — from the kind and never from the message's text.
//!
//! ```
//! use sparse_levelset::{Error, ErrorKind, GridSpec};
//!
//! let err = GridSpec::new(-1.0, [0.0; 3], 3.0).unwrap_err();
//! assert_eq!(err.kind(), ErrorKind::InvalidInput);
//! ```

/// What kind of failure an error reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ErrorKind {
    /// A parameter, option or argument the caller gave is outside its domain.
    InvalidInput,
    /// The data the caller gave cannot be taken: NaN values, a field without an interface,
    /// an empty mesh.
    InvalidData,
    /// A file is not what its name or header says: truncated, corrupt, a wrong signature.
    CorruptFile,
    /// A file name whose extension names no format this library reads or writes.
    UnknownFormat,
    /// A file in a variant of its format this library does not handle: a format version, a
    /// voxel type, a 4-D image.
    Unsupported,
    /// The operating system refused: a missing file, a permission, a full disk.
    Io,
    /// The operation needs more memory than the process may use; nothing was allocated.
    OutOfMemory,
    /// A progress callback (or an interrupt) stopped the operation.
    Cancelled,
    /// The computation itself failed: an interface that collapsed, a non-finite speed, a
    /// rank of a distributed run that failed.
    Failed,
}

impl ErrorKind {
    /// A short name of the kind (`"invalid input"`, `"out of memory"`, …).
    pub fn as_str(self) -> &'static str {
        match self {
            ErrorKind::InvalidInput => "invalid input",
            ErrorKind::InvalidData => "invalid data",
            ErrorKind::CorruptFile => "corrupt file",
            ErrorKind::UnknownFormat => "unknown format",
            ErrorKind::Unsupported => "unsupported",
            ErrorKind::Io => "i/o",
            ErrorKind::OutOfMemory => "out of memory",
            ErrorKind::Cancelled => "cancelled",
            ErrorKind::Failed => "failed",
        }
    }
}

impl std::fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// An error of this library: a message (its `Display`) and a [`ErrorKind`].
pub trait Error: std::error::Error + Send + Sync + 'static {
    /// The kind of failure.
    fn kind(&self) -> ErrorKind;
}

impl Error for crate::progress::Cancelled {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Cancelled
    }
}

/// The kernels' errors are lengths and sizes the caller got wrong.
impl Error for levelset_kernels::KernelError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::InvalidInput
    }
}

/// An I/O error's kind: out of memory where the system says so, otherwise I/O.
pub(crate) fn io_kind(e: &std::io::Error) -> ErrorKind {
    match e.kind() {
        std::io::ErrorKind::OutOfMemory => ErrorKind::OutOfMemory,
        _ => ErrorKind::Io,
    }
}
