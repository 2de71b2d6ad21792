//! Writing files safely: to a temporary file in the target's directory, flushed to disk,
//! then renamed into place, so the target never holds a partial file; and checking, before
//! any work, that an output can be written at all ([`check_writable`],
//! [`check_writable_dir`]), so that a long computation never ends in a failed write.

use std::fs::{self, File};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// The temporary files being written now, and whether the process is closing (after
/// [`abandon_writes`], no new one is created).
static PENDING: Mutex<(Vec<PathBuf>, bool)> = Mutex::new((Vec::new(), false));

/// Removes every temporary file a write in progress holds and refuses new writes: what a
/// program does on SIGINT or SIGTERM before it exits, so that an interrupted write leaves
/// nothing beside its output (the output itself is untouched: it is replaced only by a
/// completed rename). Returns how many files were removed.
pub fn abandon_writes() -> usize {
    let mut pending = PENDING.lock().unwrap_or_else(|e| e.into_inner());
    pending.1 = true;
    let removed = pending.0.iter().filter(|p| fs::remove_file(p).is_ok()).count();
    pending.0.clear();
    removed
}

/// Creates the temporary file `tmp`, registered so that [`abandon_writes`] can remove it.
fn create_registered(tmp: &Path) -> io::Result<File> {
    let mut pending = PENDING.lock().unwrap_or_else(|e| e.into_inner());
    if pending.1 {
        return Err(io::Error::new(io::ErrorKind::Interrupted, "the program is closing"));
    }
    let file = fs::OpenOptions::new().write(true).create_new(true).open(tmp)?;
    pending.0.push(tmp.to_path_buf());
    Ok(file)
}

/// Forgets the temporary file `tmp` (renamed into place or removed).
fn unregister(tmp: &Path) {
    let mut pending = PENDING.lock().unwrap_or_else(|e| e.into_inner());
    pending.0.retain(|p| p != tmp);
}

/// Writes a file through `write` into a temporary file next to `path`, `fsync`s it and
/// renames it over `path`. On any error the temporary file is removed and `path` is left
/// as it was.
pub fn write_atomic<F>(path: &Path, write: F) -> io::Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> io::Result<()>,
{
    let name = path.file_name().ok_or_else(|| {
        io::Error::new(io::ErrorKind::InvalidInput, "the path does not name a file")
    })?;
    let dir = parent_dir(path);
    let tmp = temp_path(&dir, name);
    let result = (|| -> io::Result<()> {
        let file = create_registered(&tmp)?;
        let mut w = BufWriter::with_capacity(1 << 20, file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        fs::rename(&tmp, path)?;
        // Make the rename durable (best effort: not every platform can sync a directory).
        #[cfg(unix)]
        if let Ok(d) = File::open(&dir) {
            let _ = d.sync_all();
        }
        Ok(())
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    unregister(&tmp);
    result
}

/// The outputs of one command, written together: each is written (by any writer, through
/// [`write_atomic`] or not) to a staged path beside its target, a hidden name that keeps the
/// target's whole file name at its end (so that a format chosen by the extension is the
/// same), and [`Outputs::commit`] renames them all into place once every one is written.
/// Dropped without a commit (a write failed), the staged files are removed and every target
/// is left as it was. SIGINT and SIGTERM remove them too ([`abandon_writes`]).
///
/// A detached header (`.mhd`, `.nhdr`) names its data file, so it cannot be renamed: such a
/// target is written in place ([`Outputs::stage`] returns the target itself).
#[derive(Debug, Default)]
pub struct Outputs {
    staged: Vec<(PathBuf, PathBuf)>,
}

impl Outputs {
    /// No output staged yet.
    pub fn new() -> Outputs {
        Outputs::default()
    }

    /// The path to write `target`'s content to.
    pub fn stage(&mut self, target: &Path) -> PathBuf {
        let name = target.file_name().map(|n| n.to_string_lossy().to_ascii_lowercase());
        if name.as_deref().is_none_or(|n| n.ends_with(".mhd") || n.ends_with(".nhdr")) {
            return target.to_path_buf();
        }
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let mut staged = std::ffi::OsString::from(format!(
            ".{}-{}-",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        staged.push(target.file_name().unwrap_or_default());
        let staged = parent_dir(target).join(staged);
        let mut pending = PENDING.lock().unwrap_or_else(|e| e.into_inner());
        pending.0.push(staged.clone());
        drop(pending);
        self.staged.push((staged.clone(), target.to_path_buf()));
        staged
    }

    /// A writer's message with every staged path replaced by its target, so that an error
    /// names the output the user asked for.
    pub fn named(&self, message: impl std::fmt::Display) -> String {
        let mut m = message.to_string();
        for (staged, target) in &self.staged {
            m = m.replace(&*staged.to_string_lossy(), &target.to_string_lossy());
        }
        m
    }

    /// Renames every staged file into place.
    pub fn commit(mut self) -> io::Result<()> {
        let staged = std::mem::take(&mut self.staged);
        let mut result = Ok(());
        for (i, (from, to)) in staged.iter().enumerate() {
            if let Err(e) = fs::rename(from, to) {
                for (rest, _) in &staged[i..] {
                    let _ = fs::remove_file(rest);
                }
                result = Err(e);
                break;
            }
        }
        for (from, _) in &staged {
            unregister(from);
        }
        result
    }
}

impl Drop for Outputs {
    fn drop(&mut self) {
        for (from, _) in &self.staged {
            let _ = fs::remove_file(from);
            unregister(from);
        }
    }
}

/// The directory a file `path` lives in (`.` for a bare file name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A fresh hidden name next to `name` in `dir`: `.NAME.PID.N.tmp`.
fn temp_path(dir: &Path, name: &std::ffi::OsStr) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(
        ".{}.{}.tmp",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    dir.join(tmp_name)
}

/// Creates and removes a temporary file in `dir`: what [`write_atomic`] will do there.
fn probe_dir(dir: &Path, name: &std::ffi::OsStr) -> io::Result<()> {
    let tmp = temp_path(dir, name);
    fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
    fs::remove_file(&tmp)
}

/// Checks, before any work, that [`write_atomic`] can write the file `path`: it names a
/// file, not a directory, and a file can be created in its directory (a temporary file is
/// created there and removed again; nothing else is written). Disk space is not checked.
///
/// ```
/// use sparse_levelset::io::fsutil::check_writable;
/// let dir = std::env::temp_dir();
/// assert!(check_writable(&dir.join("result.npy")).is_ok());
/// assert!(check_writable(&dir.join("no-such-dir/result.npy")).is_err());
/// ```
pub fn check_writable(path: &Path) -> io::Result<()> {
    let name = path.file_name().ok_or_else(|| {
        io::Error::new(io::ErrorKind::InvalidInput, "the path does not name a file")
    })?;
    if path.is_dir() {
        return Err(io::Error::new(io::ErrorKind::IsADirectory, "it is a directory"));
    }
    let dir = parent_dir(path);
    if !dir.is_dir() {
        let what = if dir.exists() { "is not a directory" } else { "does not exist" };
        return Err(io::Error::new(
            io::ErrorKind::NotFound,
            format!("the directory {} {what}", dir.display()),
        ));
    }
    probe_dir(&dir, name)
}

/// Checks, before any work, that files can be written in the directory `dir`, creating
/// nothing: an existing `dir` must be a directory in which a file can be created (probed
/// with a temporary file, removed again); a missing one must be creatable, i.e. its nearest
/// existing ancestor is a directory in which an entry can be created. Create it with
/// [`fs::create_dir_all`] when the work starts.
pub fn check_writable_dir(dir: &Path) -> io::Result<()> {
    let not_dir = |p: &Path| {
        io::Error::new(
            io::ErrorKind::NotADirectory,
            format!("{} exists and is not a directory", p.display()),
        )
    };
    if dir.exists() {
        if !dir.is_dir() {
            return Err(not_dir(dir));
        }
        return probe_dir(dir, std::ffi::OsStr::new("write-check"));
    }
    let mut ancestor = dir;
    loop {
        ancestor = match ancestor.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        if ancestor.exists() {
            if !ancestor.is_dir() {
                return Err(not_dir(ancestor));
            }
            return probe_dir(ancestor, std::ffi::OsStr::new("mkdir-check"));
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn outputs_appear_together_or_not_at_all() {
        let dir = std::env::temp_dir().join(format!("fsutil-outputs-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let (a, b) = (dir.join("a.nii.gz"), dir.join("b.json"));
        fs::write(&a, b"old a").unwrap();
        // The second write fails: the first target keeps its old content, nothing is left.
        {
            let mut outputs = Outputs::new();
            let sa = outputs.stage(&a);
            assert!(sa.to_string_lossy().ends_with("a.nii.gz") && sa != a);
            write_atomic(&sa, |w| std::io::Write::write_all(w, b"new a")).unwrap();
            let sb = outputs.stage(&b);
            let failed: io::Result<()> = Err(io::Error::other("the second output failed"));
            assert!(failed.is_err() && !sb.exists());
        }
        assert_eq!(fs::read(&a).unwrap(), b"old a");
        assert!(!b.exists());
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1, "a staged file was left");
        // Both written: both appear at the commit.
        let mut outputs = Outputs::new();
        let (sa, sb) = (outputs.stage(&a), outputs.stage(&b));
        // A writer's message names the target, not the staged file.
        let m = outputs.named(format!("{}: No space left on device", sa.display()));
        assert_eq!(m, format!("{}: No space left on device", a.display()));
        write_atomic(&sa, |w| std::io::Write::write_all(w, b"new a")).unwrap();
        write_atomic(&sb, |w| std::io::Write::write_all(w, b"{}")).unwrap();
        assert_eq!(fs::read(&a).unwrap(), b"old a");
        outputs.commit().unwrap();
        assert_eq!(fs::read(&a).unwrap(), b"new a");
        assert_eq!(fs::read(&b).unwrap(), b"{}");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 2);
        // A detached header is written in place.
        let mhd = dir.join("m.mhd");
        assert_eq!(Outputs::new().stage(&mhd), mhd);
        fs::remove_dir_all(&dir).unwrap();
    }

    use super::*;
    use std::io::Write;

    #[test]
    fn writes_whole_file_or_nothing() {
        let dir = std::env::temp_dir().join(format!("levelset-fsutil-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let p = dir.join("out.txt");
        write_atomic(&p, |w| w.write_all(b"first")).unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"first");
        let err = write_atomic(&p, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("fails half-way"))
        });
        assert!(err.is_err());
        assert_eq!(fs::read(&p).unwrap(), b"first", "target untouched");
        let left: Vec<_> = fs::read_dir(&dir).unwrap().collect();
        assert_eq!(left.len(), 1, "no temporary file left behind");
        assert!(write_atomic(&dir.join("no/such/dir/x"), |_| Ok(())).is_err());
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn outputs_are_checked_without_writing_anything() {
        let dir = std::env::temp_dir().join(format!("levelset-fsutil-w-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let file = dir.join("a-file");
        fs::write(&file, b"x").unwrap();
        assert!(check_writable(&dir.join("out.npy")).is_ok());
        assert!(check_writable(&file).is_ok(), "an existing file is replaced");
        for bad in [dir.clone(), dir.join("missing/out.npy"), file.join("out.npy")] {
            let e = check_writable(&bad).unwrap_err();
            assert!(!e.to_string().is_empty(), "{}", bad.display());
        }
        assert!(check_writable_dir(&dir).is_ok());
        assert!(check_writable_dir(&dir.join("new/sub")).is_ok(), "creatable");
        assert!(check_writable_dir(&file).is_err());
        assert!(check_writable_dir(&file.join("sub/deeper")).is_err());
        // Nothing was created or left behind.
        let left: Vec<_> = fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left, ["a-file"]);
        fs::remove_dir_all(&dir).unwrap();
    }
}
