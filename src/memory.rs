//! Memory the machine can give: every large allocation (a dense array, a grid built from a
//! shape, the growth of a band during a run, a file's data) is estimated and checked here
//! before it is made, so that a request the machine cannot hold is an error instead of an
//! abort in the allocator.

use crate::grid::GridError;

/// Fraction of the currently available memory one request may take.
const SHARE: f64 = 0.7;
/// Assumed available memory where the operating system does not say (`/proc/meminfo`).
const FALLBACK: u64 = 8 << 30;

/// Bytes of memory available now (`MemAvailable` of `/proc/meminfo`), `None` where the
/// operating system does not tell.
pub fn available() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = s.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kb.checked_mul(1024)
}

/// The most one request may allocate: 70 % of [`available`] (of 8 GiB where unknown).
pub fn limit() -> u64 {
    (available().unwrap_or(FALLBACK) as f64 * SHARE) as u64
}

/// Refuses a request of `bytes` (an estimate; NaN and ∞ are refused) that exceeds
/// [`limit`]; `what` names it in the error.
pub fn check(bytes: f64, what: &str) -> Result<(), GridError> {
    let limit = limit();
    if bytes.is_finite() && bytes >= 0.0 && bytes <= limit as f64 {
        return Ok(());
    }
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

#[cfg(test)]
mod tests {
    use super::*;

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
