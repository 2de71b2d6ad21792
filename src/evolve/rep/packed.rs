//! Tiles stored by what they hold: per tile, which voxels hold ±a background value and the
//! other values alone, packed per group of tiles.
//!
//! Two arrays of the tile engine take this form:
//! * **The renormalisation's anchors.** Russo & Smereka's subcell fix ("A remark on
//!   computing distance functions", J. Comput. Phys. 163 (2000) 51–67, Sec. 3) gives a
//!   voxel next to the interface of φ⁰ a distance estimate and every other voxel ±∞, the
//!   sign of φ⁰ ([`levelset_kernels::InterfaceAnchor`]). Only the voxels of a thin shell
//!   around the interface hold a number. A sweep reads only the anchors of the voxels its
//!   band mask selects (`BandMasked` keeps the value elsewhere), so only those are kept.
//! * **φⁿ kept to undo a step or a renormalisation.** Outside the band a tile's voxels hold
//!   ±γ exactly (the clamp of van der Laan, Jalba & Roerdink, "A memory and computation
//!   efficient sparse level-set method", J. Sci. Comput. 46 (2011) 243–264, Sec. 3), so
//!   only the band voxels are stored; every value, whatever it is, comes back bit for bit.

use crate::evolve::dispatch::Anchors;
use crate::storage::tiles::Tile;
use levelset_kernels::{KernelError, Lane, ScalarField};
use std::ops::Range;

/// Tiles per group of stored values (at most 64, so that a group's values are indexed by
/// `u16`): the tile sweeps' chunks, so that each chunk fills one group.
pub(crate) const GROUP: usize = 64;

/// A tile list stored by content: per tile the bits of its stored voxels and of those
/// that hold −background (the rest hold +background), and per group of [`GROUP`]
/// consecutive tiles the stored values in list order. The background is the caller's
/// (∞ for anchors, γ for φⁿ) and is not kept.
///
/// # Invariants
/// `stored`, `negative` and `start` have one entry per tile; `values` one vector per group;
/// tile `p`'s stored values are `values[p / GROUP][start[p]..]`, as many as `stored[p]`
/// has bits; no voxel is both stored and negative.
#[derive(Clone, Debug, Default)]
pub(crate) struct PackedTiles {
    stored: Vec<u64>,
    negative: Vec<u64>,
    start: Vec<u16>,
    values: Vec<Vec<f32>>,
}

/// The per-tile arrays of one group, as [`PackedTiles::groups_mut`] hands them out.
pub(crate) struct PackedGroup<'a> {
    pub stored: &'a mut [u64],
    pub negative: &'a mut [u64],
    pub start: &'a mut [u16],
    pub values: &'a mut Vec<f32>,
}

impl PackedGroup<'_> {
    /// Stores the group's `tiles` (in order from its first) at the voxels of their words
    /// `masks` (the others are never read: they come back as +background), in a vector of
    /// exactly their number: every such voxel that is not ±`background`.
    pub fn fill(&mut self, tiles: &[Tile], masks: impl Iterator<Item = u64>, background: f32) {
        let (neg_bits, pos_bits) = ((-background).to_bits(), background.to_bits());
        let mut total = 0;
        for (i, (t, mask)) in tiles.iter().zip(masks).enumerate() {
            let (neg, pos) = equal_bits(t, neg_bits, pos_bits);
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

/// Which voxels of `t` hold exactly the bits `a` and which `b`: bit `v` of each word for
/// voxel `v`, eight voxels per comparison.
#[inline(always)]
fn equal_bits(t: &Tile, a: u32, b: u32) -> (u64, u64) {
    use wide::u32x8;
    let (a, b) = (u32x8::splat(a), u32x8::splat(b));
    let rows: &[[u32; 8]; 8] = bytemuck::cast_ref(&t.0);
    rows.iter().enumerate().fold((0, 0), |(x, y), (c, r)| {
        let r = u32x8::new(*r);
        let bits = |m: u32x8| u64::from(m.to_bitmask()) << (8 * c);
        (x | bits(r.simd_eq(a)), y | bits(r.simd_eq(b)))
    })
}

impl PackedTiles {
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
    ) -> impl rayon::iter::IndexedParallelIterator<Item = PackedGroup<'_>> {
        use rayon::prelude::*;
        self.stored
            .par_chunks_mut(GROUP)
            .zip(self.negative.par_chunks_mut(GROUP))
            .zip(self.start.par_chunks_mut(GROUP))
            .zip(self.values.par_iter_mut())
            .map(|(((stored, negative), start), values)| PackedGroup {
                stored,
                negative,
                start,
                values,
            })
    }

    /// Every voxel of `tiles`, stored where it is not ±`background` (in parallel); the
    /// previous content is replaced.
    pub fn pack(&mut self, tiles: &[Tile], background: f32) {
        use rayon::prelude::*;
        self.resize(tiles.len());
        self.groups_mut().zip(tiles.par_chunks(GROUP)).for_each(|(mut g, t)| {
            g.fill(t, std::iter::repeat(u64::MAX), background);
        });
    }

    /// Writes what [`PackedTiles::pack`] stored back into `tiles` (one per packed tile),
    /// bit for bit, in parallel.
    pub fn unpack(&self, tiles: &mut [Tile], background: f32) {
        use rayon::prelude::*;
        debug_assert_eq!(tiles.len(), self.stored.len(), "one tile per packed tile");
        tiles.par_chunks_mut(GROUP).enumerate().for_each(|(c, group)| {
            for (i, t) in group.iter_mut().enumerate() {
                *t = Tile(self.tile(c * GROUP + i, background));
            }
        });
    }

    /// The values of tile `p`: ±`background` where none is stored.
    #[inline(always)]
    fn tile(&self, p: usize, background: f32) -> [f32; 64] {
        // ±background by the sign bit, branch-free.
        let (b, negative) = (background.to_bits(), self.negative[p]);
        let mut v = [0.0f32; 64];
        for (i, x) in v.iter_mut().enumerate() {
            *x = f32::from_bits(b | (((negative >> i) & 1) as u32) << 31);
        }
        let mut m = self.stored[p];
        for &a in self.stored_values(p) {
            v[m.trailing_zeros() as usize] = a;
            m &= m - 1;
        }
        v
    }

    /// The values stored for tile `p` (its voxels that do not hold ±background), in voxel
    /// order.
    #[inline(always)]
    pub fn stored_values(&self, p: usize) -> &[f32] {
        let first = usize::from(self.start[p]);
        &self.values[p / GROUP][first..first + self.stored[p].count_ones() as usize]
    }

    /// Tiles packed.
    pub fn len(&self) -> usize {
        self.stored.len()
    }

    /// Bytes held, used or not.
    pub fn bytes(&self) -> usize {
        let v = |n: usize, size: usize| n * size;
        v(self.stored.capacity() + self.negative.capacity(), 8)
            + v(self.start.capacity(), 2)
            + v(self.values.capacity(), std::mem::size_of::<Vec<f32>>())
            + self.values.iter().map(|g| 4 * g.capacity()).sum::<usize>()
    }
}

/// The anchors of one tile, unpacked for a sweep's kernel ([`levelset_kernels::RenormRate`]):
/// built once per tile, read per lane group as a plain load.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileAnchorField {
    values: [f32; 64],
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

/// Anchors are packed with the background ∞ ([`PackedTiles`]). A sweep's blocks are whole
/// tiles: the voxels `r` are tile `r.start / 64`'s.
impl<'a> Anchors<'a> for &'a PackedTiles {
    type Field = TileAnchorField;

    #[inline(always)]
    fn field(self, r: Range<usize>) -> TileAnchorField {
        debug_assert!(r.start.is_multiple_of(64) && r.len() == 64, "a tile's voxels");
        TileAnchorField { values: self.tile(r.start / 64, f32::INFINITY) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Packing keeps every value bit for bit, whatever it is: ±background, −0, values
    /// next to the background, infinities and a NaN.
    #[test]
    fn unpacking_returns_what_was_packed() {
        let gamma = 3.0f32;
        let special = [gamma, -gamma, 0.0, -0.0, f32::INFINITY, f32::NAN, gamma.next_up(), -2.5];
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        // More than one group, the last one partial.
        let tiles: Vec<Tile> = (0..2 * GROUP + 5)
            .map(|_| {
                let mut t = Tile::splat(0.0);
                for v in t.0.iter_mut() {
                    let r = next();
                    *v = match r % 4 {
                        0 | 1 => {
                            if r & 4 == 0 {
                                gamma
                            } else {
                                -gamma
                            }
                        }
                        2 => special[(r >> 8) as usize % special.len()],
                        _ => ((r >> 16) as u32 as f32 / u32::MAX as f32 - 0.5) * 2.0 * gamma,
                    };
                }
                t
            })
            .collect();
        let mut packed = PackedTiles::default();
        packed.pack(&tiles, gamma);
        let mut back = vec![Tile::splat(1.0); tiles.len()];
        packed.unpack(&mut back, gamma);
        for (a, b) in tiles.iter().zip(&back) {
            assert!(a.0.iter().zip(&b.0).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
        // Only the voxels that are not ±γ are stored.
        let stored: usize = (0..tiles.len()).map(|p| packed.stored_values(p).len()).sum();
        let expected = tiles
            .iter()
            .flat_map(|t| t.0)
            .filter(|v| v.to_bits() != gamma.to_bits() && v.to_bits() != (-gamma).to_bits())
            .count();
        assert_eq!(stored, expected);
    }
}
