//! The narrow-band heap of the fast marching method (Bærentzen, Sec. 2.1.1): a binary
//! min-heap over a list of entries that never move, plus a permutation.
//!
//! An entry (key, voxel) is appended to `entries` once and keeps its index (its
//! *handle*) for life; the heap orders handles, and `pos[handle]` is where a handle sits
//! in the heap. A voxel stores its handle, so decreasing (or raising) its key is
//! `update(handle, key)` without the heap ever touching the voxel storage — the
//! separation the paper recommends (after Sedgewick).
//!
//! Ties are broken by the voxel coordinate in [`Coord`] order, so the extraction order —
//! and hence every marched value — does not depend on the order in which voxels were
//! inserted.

use crate::coord::Coord;
use std::cmp::Ordering;

/// Handle of a heap entry (its index in the entry list).
pub(crate) type Handle = u32;

const REMOVED: u32 = u32::MAX;

#[derive(Clone, Copy, Debug)]
struct Entry {
    key: f64,
    coord: Coord,
    voxel: u32,
}

/// A heap slot: the key is kept next to the handle so that sifting reads one array.
#[derive(Clone, Copy, Debug)]
struct Slot {
    key: f64,
    handle: Handle,
}

/// Binary min-heap with a position index (see the module docs).
#[derive(Default, Debug)]
pub(crate) struct IndexedHeap {
    /// Entries by handle (the key here is the authoritative copy).
    entries: Vec<Entry>,
    /// Slots in heap order.
    heap: Vec<Slot>,
    /// Heap position of each handle, [`REMOVED`] once popped.
    pos: Vec<u32>,
}

impl IndexedHeap {
    pub(crate) fn new() -> IndexedHeap {
        IndexedHeap::default()
    }

    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.heap.len()
    }

    #[cfg(test)]
    pub(crate) fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }

    #[inline]
    fn less(&self, a: Slot, b: Slot) -> bool {
        match a.key.total_cmp(&b.key) {
            Ordering::Less => true,
            Ordering::Greater => false,
            Ordering::Equal => {
                self.entries[a.handle as usize].coord < self.entries[b.handle as usize].coord
            }
        }
    }

    /// Inserts `(key, voxel at coord)` and returns its handle.
    pub(crate) fn push(&mut self, key: f64, coord: Coord, voxel: u32) -> Handle {
        let h = self.entries.len() as Handle;
        assert!(h != REMOVED, "more than 2^32 - 1 heap entries");
        self.entries.push(Entry { key, coord, voxel });
        self.pos.push(self.heap.len() as u32);
        self.heap.push(Slot { key, handle: h });
        self.sift_up(self.heap.len() - 1);
        h
    }

    /// Changes the key of an entry still in the heap (decrease or increase).
    pub(crate) fn update(&mut self, h: Handle, key: f64) {
        let p = self.pos[h as usize];
        debug_assert!(p != REMOVED, "update of a popped entry");
        let old = self.entries[h as usize].key;
        self.entries[h as usize].key = key;
        self.heap[p as usize].key = key;
        if key < old {
            self.sift_up(p as usize);
        } else {
            self.sift_down(p as usize);
        }
    }

    /// Key of an entry.
    pub(crate) fn key(&self, h: Handle) -> f64 {
        self.entries[h as usize].key
    }

    /// The smallest key, if any.
    pub(crate) fn peek_key(&self) -> Option<f64> {
        self.heap.first().map(|s| s.key)
    }

    /// Removes the entry with the smallest key: `(key, coord, voxel)`.
    pub(crate) fn pop(&mut self) -> Option<(f64, Coord, u32)> {
        let top = self.heap.first()?.handle;
        let last = self.heap.pop().expect("non-empty");
        if !self.heap.is_empty() {
            self.heap[0] = last;
            self.pos[last.handle as usize] = 0;
            self.sift_down(0);
        }
        self.pos[top as usize] = REMOVED;
        let e = self.entries[top as usize];
        Some((e.key, e.coord, e.voxel))
    }

    fn sift_up(&mut self, mut i: usize) {
        let h = self.heap[i];
        while i > 0 {
            let parent = (i - 1) / 2;
            let ph = self.heap[parent];
            if !self.less(h, ph) {
                break;
            }
            self.heap[i] = ph;
            self.pos[ph.handle as usize] = i as u32;
            i = parent;
        }
        self.heap[i] = h;
        self.pos[h.handle as usize] = i as u32;
    }

    fn sift_down(&mut self, mut i: usize) {
        let n = self.heap.len();
        let h = self.heap[i];
        loop {
            let l = 2 * i + 1;
            if l >= n {
                break;
            }
            let r = l + 1;
            let c = if r < n && self.less(self.heap[r], self.heap[l]) { r } else { l };
            let ch = self.heap[c];
            if !self.less(ch, h) {
                break;
            }
            self.heap[i] = ch;
            self.pos[ch.handle as usize] = i as u32;
            i = c;
        }
        self.heap[i] = h;
        self.pos[h.handle as usize] = i as u32;
    }

    /// Checks the heap property and the position index (tests).
    #[cfg(test)]
    pub(crate) fn check(&self) -> Result<(), String> {
        for (i, &h) in self.heap.iter().enumerate() {
            let p = self.pos[h.handle as usize] as usize;
            if p != i || h.key.to_bits() != self.entries[h.handle as usize].key.to_bits() {
                return Err(format!("slot {i}: handle {} at pos {p}, key {}", h.handle, h.key));
            }
            if i > 0 && self.less(h, self.heap[(i - 1) / 2]) {
                return Err(format!("heap order broken at {i}"));
            }
        }
        Ok(())
    }
}
