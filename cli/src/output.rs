//! Output of the binaries: standard output that survives a closed pipe, and JSON files
//! written atomically.

use std::path::Path;

/// `print!` that ignores a closed standard output (`levelset run … | head` must not panic
/// on a broken pipe).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// `println!` that ignores a closed standard output.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// Writes `value` as pretty JSON to `path` (atomically: temporary file, then rename) and
/// says so on standard output.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), String> {
    stage_json(path, value)?;
    outln!("wrote {}", path.display());
    Ok(())
}

/// Writes `value` as pretty JSON to `path` (atomically) without a word: for a staged
/// output ([`sparse_levelset::io::fsutil::Outputs`]), whose temporary name is no name to
/// tell a user; the command reports the outputs once they are in place.
pub fn stage_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), String> {
    let text = serde_json::to_string_pretty(value).map_err(|e| e.to_string())?;
    sparse_levelset::io::fsutil::write_atomic(path, |w| {
        use std::io::Write;
        w.write_all(text.as_bytes())
    })
    .map_err(|e| format!("{}: {e}", path.display()))
}

/// Checks, before any work, that the file `path` can be written
/// ([`sparse_levelset::io::fsutil::check_writable`]); the error names the path.
pub fn check_output(path: &Path) -> Result<(), String> {
    sparse_levelset::io::fsutil::check_writable(path)
        .map_err(|e| format!("{}: cannot write the output here: {e}", path.display()))
}

/// Checks, before any work, that the output directory `dir` can be created and written
/// ([`sparse_levelset::io::fsutil::check_writable_dir`]); nothing is created.
pub fn check_output_dir(dir: &Path) -> Result<(), String> {
    sparse_levelset::io::fsutil::check_writable_dir(dir)
        .map_err(|e| format!("{}: cannot write the output here: {e}", dir.display()))
}
