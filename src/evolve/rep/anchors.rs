//! The renormalisation's anchors on tiles, stored by what they hold.
//!
//! Russo & Smereka's subcell fix ("A remark on computing distance functions", J. Comput.
//! Phys. 163 (2000) 51–67, Sec. 3) gives a voxel next to the interface of φ⁰ a distance
//! estimate and every other voxel ±∞, the sign of φ⁰ ([`levelset_kernels::InterfaceAnchor`]).
//! Only the voxels of a thin shell around the interface hold a number, so a tile's anchors
//! are two bit words (which are stored, which are −∞) and the stored values alone, packed
//! per group of tiles. A sweep reads only the anchors of the voxels its band mask selects
//! (`BandMasked` keeps the value elsewhere), so only those are kept.

use crate::evolve::dispatch::Anchors;
use crate::storage::tiles::Tile;
use levelset_kernels::{KernelError, Lane, ScalarField};
use std::ops::Range;

/// Tiles per group of stored values (at most 64, so that a group's values are indexed by
/// `u16`): the tile sweeps' chunks, so that each chunk fills one group.
pub(crate) const GROUP: usize = 64;

/// The anchors of a tile list: per tile the bits of its stored and its −∞ voxels (the rest
/// are +∞), and per group of [`GROUP`] consecutive tiles the stored values in list order.
///
/// # Invariants
/// `stored`, `negative` and `start` have one entry per tile; `values` one vector per group;
/// tile `p`'s stored anchors are `values[p / GROUP][start[p]..]`, as many as `stored[p]`
/// has bits; no voxel is both stored and −∞.
#[derive(Clone, Debug, Default)]
pub(crate) struct TileAnchors {
    stored: Vec<u64>,
    negative: Vec<u64>,
    start: Vec<u16>,
    values: Vec<Vec<f32>>,
}

/// The per-tile arrays of one group, as [`TileAnchors::groups_mut`] hands them out.
pub(crate) struct GroupAnchors<'a> {
    pub stored: &'a mut [u64],
    pub negative: &'a mut [u64],
    pub start: &'a mut [u16],
    pub values: &'a mut Vec<f32>,
}

impl GroupAnchors<'_> {
    /// Stores the anchors `tiles` of the group's tiles (in order from its first) at the
    /// voxels of their band-mask words `masks` (the others are never read), in a vector of
    /// exactly their number.
    pub fn fill(&mut self, tiles: &[Tile], masks: &[u64]) {
        let mut total = 0;
        for (i, (t, &mask)) in tiles.iter().zip(masks).enumerate() {
            // Branch-free over the tile: which anchors are −∞ and which +∞.
            let (mut neg, mut pos) = (0u64, 0u64);
            for (v, a) in t.0.iter().enumerate() {
                let b = a.to_bits();
                neg |= u64::from(b == f32::NEG_INFINITY.to_bits()) << v;
                pos |= u64::from(b == f32::INFINITY.to_bits()) << v;
            }
            self.stored[i] = mask & !neg & !pos;
            self.negative[i] = mask & neg;
            // A group holds at most 64 tiles of 64 values.
            self.start[i] = total as u16;
            total += self.stored[i].count_ones() as usize;
        }
        self.values.clear();
        self.values.reserve_exact(total);
        for (t, &stored) in tiles.iter().zip(self.stored.iter()) {
            let mut m = stored;
            while m != 0 {
                self.values.push(t.0[m.trailing_zeros() as usize]);
                m &= m - 1;
            }
        }
    }
}

impl TileAnchors {
    /// Room for `tiles` tiles. The capacity of the values is kept.
    pub fn resize(&mut self, tiles: usize) {
        self.stored.resize(tiles, 0);
        self.negative.resize(tiles, 0);
        self.start.resize(tiles, 0);
        self.values.resize_with(tiles.div_ceil(GROUP), Vec::new);
    }

    /// The groups' arrays, in list order, to be filled in parallel.
    pub fn groups_mut(
        &mut self,
    ) -> impl rayon::iter::IndexedParallelIterator<Item = GroupAnchors<'_>> {
        use rayon::prelude::*;
        self.stored
            .par_chunks_mut(GROUP)
            .zip(self.negative.par_chunks_mut(GROUP))
            .zip(self.start.par_chunks_mut(GROUP))
            .zip(self.values.par_iter_mut())
            .map(|(((stored, negative), start), values)| GroupAnchors {
                stored,
                negative,
                start,
                values,
            })
    }

    /// Bytes held, used or not.
    pub fn bytes(&self) -> usize {
        let v = |n: usize, size: usize| n * size;
        v(self.stored.capacity() + self.negative.capacity(), 8)
            + v(self.start.capacity(), 2)
            + v(self.values.capacity(), std::mem::size_of::<Vec<f32>>())
            + self.values.iter().map(|g| 4 * g.capacity()).sum::<usize>()
    }

    /// Whether nothing is allocated.
    pub fn is_unallocated(&self) -> bool {
        self.stored.capacity() == 0
    }
}

/// The anchors of one tile, unpacked for a sweep's kernel ([`levelset_kernels::RenormRate`]):
/// built once per tile, read per lane group as a plain load.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileAnchorField {
    values: [f32; 64],
}

impl TileAnchorField {
    #[inline(always)]
    fn unpack(stored: u64, negative: u64, values: &[f32]) -> Self {
        // ±∞ by the sign bit, branch-free.
        let mut v = [0.0f32; 64];
        for (i, x) in v.iter_mut().enumerate() {
            *x = f32::from_bits(f32::INFINITY.to_bits() | (((negative >> i) & 1) as u32) << 31);
        }
        let mut m = stored;
        for &a in values.iter().take(stored.count_ones() as usize) {
            v[m.trailing_zeros() as usize] = a;
            m &= m - 1;
        }
        TileAnchorField { values: v }
    }
}

impl ScalarField for TileAnchorField {
    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.values.as_slice().check(voxels)
    }

    #[inline(always)]
    fn lanes<L: Lane>(&self, first: usize) -> L {
        L::load(&self.values[first..])
    }
}

/// A sweep's blocks are whole tiles: the voxels `r` are tile `r.start / 64`'s.
impl<'a> Anchors<'a> for &'a TileAnchors {
    type Field = TileAnchorField;

    #[inline(always)]
    fn field(self, r: Range<usize>) -> TileAnchorField {
        debug_assert!(r.start.is_multiple_of(64) && r.len() == 64, "a tile's voxels");
        let p = r.start / 64;
        let values = &self.values[p / GROUP][usize::from(self.start[p])..];
        TileAnchorField::unpack(self.stored[p], self.negative[p], values)
    }
}
