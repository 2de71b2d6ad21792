//! Memory the machine can give: every large allocation (a dense array, a grid built from a
//! shape, the growth of a band during a run, a file's data) is estimated and checked here
//! before it is made, so that a request the machine cannot hold is an error instead of an
//! abort in the allocator.

use crate::grid::GridError;

/// Fraction of the memory this process may still take that one request may take.
const SHARE: f64 = 0.7;
/// Assumed available memory where the operating system does not say (`/proc/meminfo`).
const FALLBACK: u64 = 8 << 30;

/// Bytes of memory this process may still take now, `None` where the operating system
/// tells nothing: the smallest of
/// * the machine's available memory (`MemAvailable` of `/proc/meminfo`);
/// * the address-space limit (`RLIMIT_AS`, `ulimit -v`) less the address space in use
///   (`VmSize` of `/proc/self/status`);
/// * the data-segment limit (`RLIMIT_DATA`, `ulimit -d`) less the data in use (`VmData`);
/// * the memory cgroup's limit less its use, at every level of the process's cgroup
///   (v2: `memory.max` and `memory.current`; v1: `memory.limit_in_bytes` and
///   `memory.usage_in_bytes`).
pub fn available() -> Option<u64> {
    [meminfo(), rlimit_room(), cgroup_room()].into_iter().flatten().min()
}

fn meminfo() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/meminfo").ok()?;
    kib_field(&s, "MemAvailable:")
}

/// The most memory this process has held resident so far (`VmHWM` of
/// `/proc/self/status`), `None` where the operating system does not say.
pub fn peak_resident() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    kib_field(&s, "VmHWM:")
}

/// A `Name:   1234 kB` field of a `/proc` file, in bytes.
fn kib_field(s: &str, name: &str) -> Option<u64> {
    let line = s.lines().find(|l| l.starts_with(name))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kb.checked_mul(1024)
}

/// The room the address-space and data-segment limits leave.
#[cfg(target_os = "linux")]
fn rlimit_room() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let limit = |resource| {
        let mut r = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
        // SAFETY: `getrlimit` writes one `rlimit` through the valid pointer it is given.
        let ok = unsafe { libc::getrlimit(resource, &mut r) } == 0;
        #[allow(clippy::unnecessary_cast)] // `rlim_t` is not 64 bits on every target
        (ok && r.rlim_cur != libc::RLIM_INFINITY).then_some(r.rlim_cur as u64)
    };
    let room = |resource, used: &str| {
        let limit = limit(resource)?;
        Some(limit.saturating_sub(kib_field(&status, used).unwrap_or(0)))
    };
    [room(libc::RLIMIT_AS, "VmSize:"), room(libc::RLIMIT_DATA, "VmData:")]
        .into_iter()
        .flatten()
        .min()
}

#[cfg(not(target_os = "linux"))]
fn rlimit_room() -> Option<u64> {
    None
}

/// The room the memory cgroup leaves, the tightest over the process's cgroup and its
/// ancestors (a container may see its own cgroup as the hierarchy's root).
fn cgroup_room() -> Option<u64> {
    let cgroups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let read = |p: &std::path::Path| -> Option<u64> {
        std::fs::read_to_string(p).ok()?.trim().parse().ok()
    };
    let mut rooms = Vec::new();
    for line in cgroups.lines() {
        let mut parts = line.splitn(3, ':');
        let (_, controllers, path) = (parts.next(), parts.next()?, parts.next()?);
        let (base, limit, usage) = match controllers {
            "" => ("/sys/fs/cgroup", "memory.max", "memory.current"),
            c if c.split(',').any(|c| c == "memory") => {
                ("/sys/fs/cgroup/memory", "memory.limit_in_bytes", "memory.usage_in_bytes")
            }
            _ => continue,
        };
        let mut dir = std::path::PathBuf::from(base).join(path.trim_start_matches('/'));
        loop {
            if let (Some(l), Some(u)) = (read(&dir.join(limit)), read(&dir.join(usage))) {
                rooms.push(l.saturating_sub(u));
            }
            if dir.as_os_str() == base || !dir.pop() {
                break;
            }
        }
    }
    rooms.into_iter().min()
}

/// The most one request may allocate: 70 % of [`available`] (of 8 GiB where unknown).
pub fn limit() -> u64 {
    (available().unwrap_or(FALLBACK) as f64 * SHARE) as u64
}

/// The last [`limit`] that [`check`] read, when, and the bytes it admitted since.
struct Reading {
    limit: u64,
    at: std::time::Instant,
    admitted: f64,
}

static LAST: std::sync::Mutex<Option<Reading>> = std::sync::Mutex::new(None);

/// How long a reading serves small requests ([`check`]).
const READING_LIFE: std::time::Duration = std::time::Duration::from_secs(1);
/// The part of a reading that the small requests admitted without a new reading may add up
/// to ([`check`]).
const READING_SHARE: f64 = 0.25;

/// Refuses a request of `bytes` (an estimate; NaN and ∞ are refused) that exceeds
/// [`limit`]; `what` names it in the error.
///
/// Reading the limit means reading up to five files of `/proc` and `/sys`. A request that,
/// with those admitted since, stays within a quarter of a reading less than a second old
/// is admitted on that reading; any other request reads the limit again. (An evolving
/// band admits its new tile list at every step that changes it; see
/// docs/decisions/0036.)
pub fn check(bytes: f64, what: &str) -> Result<(), GridError> {
    let valid = bytes.is_finite() && bytes >= 0.0;
    // A poisoned lock only means another thread panicked while holding it: the reading
    // is plain data, and a stale one is read again below.
    let mut last = LAST.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(r) = last.as_mut()
        && valid
        && r.at.elapsed() < READING_LIFE
        && r.admitted + bytes <= READING_SHARE * r.limit as f64
    {
        r.admitted += bytes;
        return Ok(());
    }
    let limit = limit();
    if valid && bytes <= limit as f64 {
        *last = Some(Reading { limit, at: std::time::Instant::now(), admitted: bytes });
        return Ok(());
    }
    *last = None;
    Err(GridError::OutOfMemory {
        what: what.to_string(),
        needed: if bytes.is_finite() { bytes.max(0.0) as u64 } else { u64::MAX },
        limit,
    })
}

/// `n` elements of `elem` bytes each, as an estimate for [`check`] (∞ when it overflows).
pub fn bytes_of(n: u128, elem: usize) -> f64 {
    n as f64 * elem as f64
}

/// The capacity a buffer of a band takes when it has to grow to `n` elements: `n` plus a
/// sixteenth. A band changes by a few tiles per step; allocating exactly would reallocate
/// (copying the buffer and faulting in fresh pages) at every step in which it grows by one
/// tile past its largest size so far, and doubling as `Vec` does would let the memory
/// budget's estimates lag behind. Measured on `levelset run sphere --renormalize coupled
/// --rescale 1 --cfl 0.5 --steps 100 --threads 1` (2-core AMD EPYC, 2026-11-24): with
/// exact sizes `perf record` put 3.6 % of the run in the copies of reallocated buffers;
/// with the headroom the run took 1.00 → 0.94 s (medians of four alternated runs).
pub(crate) const fn grown_capacity(n: usize) -> usize {
    n.saturating_add(n / 16)
}

/// Resizes a buffer to `n` elements; when it has to grow, to the capacity
/// [`grown_capacity`] gives (a sixteenth of headroom instead of the doubling of a growing
/// `Vec`), so that its capacity is what the memory budget admitted.
pub(crate) fn resize_exact<T: Clone>(v: &mut Vec<T>, n: usize, fill: T) {
    if n > v.capacity() {
        v.reserve_exact(grown_capacity(n) - v.len());
    }
    v.resize(n, fill);
}

/// Asks Linux to back the 2 MiB-aligned interior of a fresh output buffer with
/// transparent huge pages (`madvise(MADV_HUGEPAGE)`, honoured when THP is `madvise` or
/// `always`), before anything touches it: the first write then faults once per 2 MiB
/// instead of once per 4 KiB. The mesh of the r = 100 sphere writes 34 MB; where the
/// allocator hands out fresh pages (glibc's mmap threshold fixed at 128 KiB) one thread
/// spent 49 ms of CPU with 4 KiB pages and 38.5 ms with this (three alternated runs of
/// 15, minima; 2-core AMD EPYC); where it reuses pages, nothing changes. A hint only:
/// the contents and the result are the same either way, and elsewhere it is a no-op.
pub(crate) fn advise_huge_pages<T>(v: &mut Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let bytes = v.capacity() * std::mem::size_of::<T>();
        let p = v.as_mut_ptr() as usize;
        let (start, end) = (p.next_multiple_of(HUGE), (p + bytes) & !(HUGE - 1));
        if end > start {
            // SAFETY: the range lies inside the buffer's own allocation; MADV_HUGEPAGE
            // changes how pages are backed, never their contents, and a failure (THP
            // off, old kernel) only leaves the default.
            unsafe { libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE) };
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

/// Asks the CPU to bring the cache line holding `p` into every cache level. A hint only:
/// it never faults, whatever the address, and changes no value; a no-op off x86-64.
#[inline(always)]
pub(crate) fn prefetch_line<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: a prefetch is a hint that never faults, whatever the address; SSE is
        // part of every x86_64 target.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p.cast::<i8>()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recent_reading_admits_only_small_requests() {
        // A small request leaves a reading behind; a request beyond a quarter of it is read
        // again, so what a fresh reading refuses is still refused.
        assert!(check(1024.0, "a small array").is_ok());
        let over = limit() as f64 * 1.5;
        assert!(check(over, "a large array").is_err());
        assert!(check(1024.0, "a small array").is_ok());
        assert!(check(over, "a large array").is_err());
        assert!(check(f64::NAN, "a NaN").is_err());
    }

    #[test]
    fn refuses_what_the_machine_cannot_hold() {
        assert!(check(1024.0, "a small array").is_ok());
        for bad in [f64::NAN, f64::INFINITY, 1e30, -1.0] {
            let e = check(bad, "the test array").unwrap_err();
            let msg = e.to_string();
            assert!(msg.contains("the test array"), "{msg}");
            assert!(msg.contains("GiB") || msg.contains("address space"), "{msg}");
        }
    }
}
