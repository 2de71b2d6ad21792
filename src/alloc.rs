//! [`LargePages`], a global allocator for programs built on this library: large blocks
//! straight from the kernel in transparent huge pages, everything else from the system
//! allocator.
//!
//! The whole-image passes of segmentation and the dense tools write fresh image-sized
//! buffers (a Gaussian, a gradient, a mask) one after another. From the system allocator
//! each one is faulted in by the pass that fills it, a 4 KiB page at a time; mapped
//! 2 MiB-aligned and advised `MADV_HUGEPAGE` before anything touches them, such blocks
//! fault once per 2 MiB, on whichever thread writes there. Where that pays and where it
//! loses (the same large blocks again and again in one process) is measured in decision
//! 0055 (`docs/decisions/0055-large-blocks-in-huge-pages.md`).

use std::alloc::{GlobalAlloc, Layout, System};

/// A global allocator: blocks of at least [`LargePages::THRESHOLD`] bytes (and an
/// alignment of at most a page) are mapped on their own, 2 MiB-aligned, with
/// `madvise(MADV_HUGEPAGE)` (honoured when the kernel's transparent huge pages are
/// `madvise` or `always`), grown in place or moved by `mremap`, and unmapped when freed;
/// smaller ones, and every block off Linux, come from [`System`].
///
/// ```no_run
/// #[global_allocator]
/// static ALLOC: sparse_levelset::alloc::LargePages = sparse_levelset::alloc::LargePages;
/// ```
#[derive(Clone, Copy, Debug, Default)]
pub struct LargePages;

impl LargePages {
    /// The smallest block mapped on its own: 1 MiB (a 64³ image of `f32`).
    pub const THRESHOLD: usize = 1 << 20;
}

/// The page size the mappings are rounded to, and the largest alignment they serve.
#[cfg(target_os = "linux")]
const PAGE: usize = 4096;

#[cfg(target_os = "linux")]
mod mapped {
    use super::PAGE;

    /// A transparent huge page of x86-64 and most aarch64 kernels.
    const HUGE: usize = 2 << 20;

    /// The bytes mapped for a block of `size` bytes.
    pub fn span(size: usize) -> usize {
        size.next_multiple_of(PAGE)
    }

    /// A fresh zeroed mapping of `span(size)` bytes, 2 MiB-aligned when it holds a huge
    /// page, advised `MADV_HUGEPAGE`; null when the kernel refuses.
    pub fn map(size: usize) -> *mut u8 {
        let len = span(size);
        let extra = if len >= HUGE { HUGE - PAGE } else { 0 };
        let Some(total) = len.checked_add(extra) else { return std::ptr::null_mut() };
        // SAFETY: an anonymous private mapping at an address of the kernel's choosing
        // touches no existing memory.
        let p = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                total,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            )
        };
        if p == libc::MAP_FAILED {
            return std::ptr::null_mut();
        }
        let base = p as usize;
        let start = base.next_multiple_of(if extra > 0 { HUGE } else { PAGE });
        // SAFETY: the head and the tail trimmed lie inside the mapping just made, page
        // aligned, and nothing refers to them; the advice changes how pages are backed,
        // never their contents. It covers the whole mapping, not only its whole huge pages
        // as `memory::advise_huge_pages` does inside a buffer: advice on part of it would
        // split the mapping in two, which `mremap` then refuses to resize.
        unsafe {
            if start > base {
                libc::munmap(p, start - base);
            }
            let tail = base + total - (start + len);
            if tail > 0 {
                libc::munmap((start + len) as *mut libc::c_void, tail);
            }
            libc::madvise(start as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
        }
        start as *mut u8
    }

    /// Unmaps a block of [`map`].
    ///
    /// # Safety
    /// `p` came from [`map`] or [`remap`] for `size` bytes and is not used again.
    pub unsafe fn unmap(p: *mut u8, size: usize) {
        // SAFETY: the caller's contract: the mapping is this block's own.
        unsafe { libc::munmap(p.cast(), span(size)) };
    }

    /// A block of [`map`] resized to `new` bytes (contents kept up to the smaller size),
    /// in place or moved; null, the block untouched, when the kernel refuses.
    ///
    /// # Safety
    /// `p` came from [`map`] or [`remap`] for `old` bytes.
    pub unsafe fn remap(p: *mut u8, old: usize, new: usize) -> *mut u8 {
        // SAFETY: the caller's contract; MREMAP_MAYMOVE keeps the contents and the
        // mapping's advice, and leaves the old mapping as it was on failure.
        let q = unsafe { libc::mremap(p.cast(), span(old), span(new), libc::MREMAP_MAYMOVE) };
        if q == libc::MAP_FAILED {
            std::ptr::null_mut()
        } else {
            q.cast()
        }
    }
}

#[cfg(target_os = "linux")]
fn is_mapped(layout: Layout) -> bool {
    layout.size() >= LargePages::THRESHOLD && layout.align() <= PAGE
}

#[cfg(not(target_os = "linux"))]
fn is_mapped(_: Layout) -> bool {
    false
}

// SAFETY: every block is either from `System` (with its own layout) or a mapping of its
// own sized by the layout's size (page aligned, so any alignment up to a page holds);
// which of the two is decided by the layout alone, the same at allocation, reallocation
// and release.
unsafe impl GlobalAlloc for LargePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        #[cfg(target_os = "linux")]
        if is_mapped(layout) {
            return mapped::map(layout.size());
        }
        // SAFETY: forwarded to the system allocator with the caller's layout.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        #[cfg(target_os = "linux")]
        if is_mapped(layout) {
            // A fresh anonymous mapping reads as zeros.
            return mapped::map(layout.size());
        }
        // SAFETY: forwarded to the system allocator with the caller's layout.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        #[cfg(target_os = "linux")]
        if is_mapped(layout) {
            // SAFETY: a block of this layout is a mapping of its own (above).
            unsafe { mapped::unmap(ptr, layout.size()) };
            return;
        }
        // SAFETY: a block of this layout came from the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: `GlobalAlloc::realloc`'s contract: the new layout is valid.
        let new = unsafe { Layout::from_size_align_unchecked(new_size, layout.align()) };
        match (is_mapped(layout), is_mapped(new)) {
            #[cfg(target_os = "linux")]
            // SAFETY: the block is a mapping of `layout.size()` bytes.
            (true, true) => unsafe { mapped::remap(ptr, layout.size(), new_size) },
            // SAFETY: both layouts are the system allocator's.
            (false, false) => unsafe { System.realloc(ptr, layout, new_size) },
            _ => {
                // From one kind to the other: a new block, the contents copied, the old
                // block released (only when the new one was made).
                // SAFETY: `new` is a valid layout of nonzero size; the copy stays within
                // both blocks; the old block is released with its own layout.
                unsafe {
                    let q = self.alloc(new);
                    if !q.is_null() {
                        std::ptr::copy_nonoverlapping(ptr, q, layout.size().min(new_size));
                        self.dealloc(ptr, layout);
                    }
                    q
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_of_both_kinds_hold_their_contents_through_every_resize() {
        let a = LargePages;
        let sizes = [8, 4096, LargePages::THRESHOLD - 1, LargePages::THRESHOLD, 3 << 20, 5 << 20];
        for &from in &sizes {
            for &to in &sizes {
                for align in [1, 8, 64, 4096] {
                    let layout = Layout::from_size_align(from, align).unwrap();
                    // SAFETY: a valid layout; every access below stays within the block's
                    // size; the block is released with its final layout.
                    unsafe {
                        let p = a.alloc_zeroed(layout);
                        assert!(!p.is_null());
                        assert_eq!(p as usize % align, 0);
                        let zeros = std::slice::from_raw_parts(p, from);
                        assert!(zeros.iter().all(|&b| b == 0), "{from} bytes not zeroed");
                        for i in 0..from {
                            *p.add(i) = (i % 251) as u8;
                        }
                        let q = a.realloc(p, layout, to);
                        assert!(!q.is_null());
                        assert_eq!(q as usize % align, 0);
                        let kept = std::slice::from_raw_parts(q, from.min(to));
                        assert!(kept.iter().enumerate().all(|(i, &b)| b == (i % 251) as u8));
                        a.dealloc(q, Layout::from_size_align(to, align).unwrap());
                    }
                }
            }
        }
    }
}
