//! A tile with a halo of `R` voxels gathered from its 26 neighbours: the stencil window
//! the kernels read for a whole tile at once (van der Laan et al. 2011, Sec. 4.7:
//! values at the tile's borders come from the neighbour tiles, or from a "dummy tile" of ±γ chosen
//! by the border flag where the neighbour is absent).

use super::{NeighbourRow, Neighbours, Tile, TileGrid, TILE_DIM};
use std::marker::PhantomData;

/// Where a gather reads its tiles: a grid, or a grid that a sweep is overwriting behind
/// itself ([`InPlaceTiles`]).
pub trait TileSource {
    /// The values of the tile at list position `p` (in range).
    fn part(&self, p: usize) -> &[f32; 64];
    /// Border flags of the tile at list position `pos` (see [`super::flags`]).
    fn border(&self, pos: usize) -> u32;
    /// Activity flags of the tile at list position `pos`.
    fn activity(&self, pos: usize) -> u32;
    /// The band's half-width γ (the dummy tiles' value).
    fn gamma(&self) -> f32;
}

impl TileSource for TileGrid {
    #[inline(always)]
    fn part(&self, p: usize) -> &[f32; 64] {
        &self.values()[p].0
    }
    #[inline(always)]
    fn border(&self, pos: usize) -> u32 {
        self.border_flags(pos)
    }
    #[inline(always)]
    fn activity(&self, pos: usize) -> u32 {
        self.activity_flags(pos)
    }
    #[inline(always)]
    fn gamma(&self) -> f32 {
        TileGrid::gamma(self)
    }
}

/// A grid's tiles for a sweep that writes each result back into the arena once no tile
/// left to compute reads the old values (see `TilesRep`'s in-place renormalisation): reads
/// and writes go through a raw pointer, so that tiles can be read on every thread while
/// others are written. Borrows the grid exclusively for its lifetime; the border and
/// activity flags are only read.
///
/// # Invariants
/// `ptr` points to `len` initialised tiles that nothing else accesses while this exists.
pub struct InPlaceTiles<'g> {
    ptr: *mut Tile,
    len: usize,
    border: &'g [u32],
    activity: &'g [u32],
    gamma: f32,
    _arena: PhantomData<&'g mut [Tile]>,
}

// SAFETY: the view only hands out tiles by position; `write`'s contract keeps a tile from
// being read while it is written (on any thread), so sharing it is sharing `&[Tile]`.
unsafe impl Send for InPlaceTiles<'_> {}
// SAFETY: as above.
unsafe impl Sync for InPlaceTiles<'_> {}

impl<'g> InPlaceTiles<'g> {
    /// The view of `arena` with the list's flags and half-width.
    pub(super) fn new(
        arena: &'g mut [Tile],
        border: &'g [u32],
        activity: &'g [u32],
        gamma: f32,
    ) -> Self {
        debug_assert!(border.len() == arena.len() && activity.len() == arena.len());
        InPlaceTiles {
            ptr: arena.as_mut_ptr(),
            len: arena.len(),
            border,
            activity,
            gamma,
            _arena: PhantomData,
        }
    }

    /// Number of tiles.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are no tiles.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Overwrites the tile at list position `pos` with `t` (finite values in [-γ, γ], as
    /// the time-step kernels give).
    ///
    /// # Safety
    /// No reference to tile `pos` that [`TileSource::part`] gave is alive, and none is
    /// taken on any thread until this returns: every gather that reads tile `pos` has
    /// finished, and none starts later.
    #[inline(always)]
    pub unsafe fn write(&self, pos: usize, t: &Tile) {
        assert!(pos < self.len, "tile {pos} of {}", self.len);
        // SAFETY: in bounds (checked); no reader by the caller's guarantee, and the view
        // borrows the arena exclusively, so no one else holds it.
        let dst = unsafe { &mut (*self.ptr.add(pos)).0 };
        // Cache line by cache line: a plain copy of the 256 bytes became a call to
        // `memmove`, whose start-up cost showed in the sweep's profile.
        for (d, s) in dst.chunks_exact_mut(16).zip(t.0.chunks_exact(16)) {
            d.copy_from_slice(s);
        }
    }
}

impl TileSource for InPlaceTiles<'_> {
    #[inline(always)]
    fn part(&self, p: usize) -> &[f32; 64] {
        assert!(p < self.len, "tile {p} of {}", self.len);
        // SAFETY: in bounds (checked) and initialised (the invariant); a tile is only
        // written when no reference to it lives (`write`'s contract).
        unsafe { &(*self.ptr.add(p)).0 }
    }
    #[inline(always)]
    fn border(&self, pos: usize) -> u32 {
        self.border[pos]
    }
    #[inline(always)]
    fn activity(&self, pos: usize) -> u32 {
        self.activity[pos]
    }
    #[inline(always)]
    fn gamma(&self) -> f32 {
        self.gamma
    }
}

/// The values of a tile and its halo, in the layout of the kernels'
/// [`levelset_kernels::TileBlock`]: `R` voxels along y and z, a whole tile row along x,
/// x fastest: `data[(x + 4) + 12 (y + R) + 12 W (z + R)]` for local `x` in `-4..8` and
/// `y, z` in `-R..4+R`, `W = 4 + 2R`. Each padded row is the same x-row of three tiles,
/// so [`PaddedBlock::gather`] copies three aligned 4-value rows per padded row, without
/// branches (absent neighbours read from two dummy tiles of ±γ). Reused across tiles:
/// [`PaddedBlock::gather`] overwrites every entry, [`PaddedBlock::gather_star_row`] the
/// rows a kernel window reads (the 3×3×3 box and the axes, see
/// [`levelset_kernels::TileBlock`]).
///
/// `R` must be in 1..=4 (a halo wider than a tile would need more than 26 neighbours).
#[derive(Clone)]
pub struct PaddedBlock<const R: usize> {
    data: Vec<f32>,
    /// The dummy tiles (Sec. 4.7): `[+γ; 64]` and `[−γ; 64]` for `dummy_gamma`.
    dummy: [Tile; 2],
    dummy_gamma: f32,
}

impl<const R: usize> Default for PaddedBlock<R> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const R: usize> PaddedBlock<R> {
    /// Row length (x extent) of the padded block.
    pub const SX: usize = 12;
    /// Extent of the padded block along y and z.
    pub const W: usize = 4 + 2 * R;
    /// How many tiles ahead of its gather a sweep prefetches ([`PaddedBlock::prefetch`]):
    /// of 2 and 4 on the sphere run of [`PaddedBlock::prefetch`], 4 was faster (prefetching all 26 neighbours
    /// 4 tiles ahead was slower than the +x ones alone).
    pub const PREFETCH_AHEAD: usize = 4;
    const CHECK: () = assert!(R >= 1 && R <= TILE_DIM as usize, "halo must be 1..=4 voxels");

    pub fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        PaddedBlock {
            data: vec![0.0; Self::SX * Self::W * Self::W],
            dummy: [Tile::splat(f32::NAN); 2],
            dummy_gamma: f32::NAN,
        }
    }

    /// The padded values, x fastest.
    #[inline(always)]
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// Value at local coordinates (`x` in `-4..8`, `y, z` in `-R..4+R`).
    #[inline(always)]
    pub fn get(&self, x: i32, y: i32, z: i32) -> f32 {
        let (r, sx, w) = (R as i32, Self::SX as i32, Self::W as i32);
        self.data[((x + 4) + sx * (y + r) + sx * w * (z + r)) as usize]
    }

    /// Fills the block for the tile described by `nb` (from a
    /// [`super::NeighbourCursor`] over `grid`'s list).
    #[inline]
    pub fn gather(&mut self, grid: &TileGrid, nb: &Neighbours) {
        self.gather_parts::<false, true, false, TileGrid>(
            grid,
            nb.pos,
            &NeighbourRow::new(nb.matched, &nb.ptr),
        );
    }

    /// Fills the block for the tile at list position `pos`, whose neighbours are `row`
    /// (from a [`super::NeighbourTable`] of `grid`'s list).
    #[inline]
    pub fn gather_row(&mut self, grid: &TileGrid, pos: usize, row: &NeighbourRow) {
        self.gather_parts::<false, true, false, TileGrid>(grid, pos, row);
    }

    /// Fills the rows of the block that the kernels' [`levelset_kernels::TileWindow`]
    /// reads (the 3×3×3 box and the axis offsets up to `R`, see
    /// [`levelset_kernels::TileBlock`]) for the tile at list position `pos`, whose
    /// neighbours are `row`. For `R = 1` that is the whole block; for `R = 3` 140 of the
    /// 300 row copies of [`PaddedBlock::gather_row`]. Other entries keep what they held.
    /// Always inlined: into the tile sweeps' functions compiled for the CPU's
    /// instruction-set level (wider copies there).
    #[inline(always)]
    pub fn gather_star_row<S: TileSource>(&mut self, grid: &S, pos: usize, row: &NeighbourRow) {
        self.gather_parts::<true, true, false, S>(grid, pos, row);
    }

    /// [`PaddedBlock::gather_star_row`] for a kernel that computes the tile's first
    /// z-slice alone from that slice's values (a planar lattice, see
    /// `levelset_kernels::TileBlock::apply_slices` and `levelset_kernels::ImageRate`, which
    /// reads nothing along z there): the slice's box rows and its rows along y (up to `R`).
    /// For `R = 3` 22 of the 140 row copies. Other entries keep what they held (NaN in
    /// debug builds, so that a kernel reading off the slice fails the tests' comparisons).
    #[inline(always)]
    pub fn gather_star_row_planar<S: TileSource>(
        &mut self,
        grid: &S,
        pos: usize,
        row: &NeighbourRow,
    ) {
        self.gather_parts::<true, true, true, S>(grid, pos, row);
    }

    /// Fills the rows of the block that a kernel without diagonal offsets
    /// (`VoxelKernel::BOX_REACH == 0`) reads: the tile's own rows with both x-neighbours,
    /// and the rows beside it along y and z (up to `R`) with the tile column's piece alone.
    /// For `R = 3` 96 of the 140 row copies of [`PaddedBlock::gather_star_row`]; for `R = 1`
    /// 64 of 108. Other entries keep what they held (in debug builds they are set to NaN,
    /// so that a kernel reading a diagonal offset it did not declare fails the tests'
    /// comparisons instead of reading another tile's values).
    #[inline(always)]
    pub fn gather_axes_row<S: TileSource>(&mut self, grid: &S, pos: usize, row: &NeighbourRow) {
        self.gather_parts::<true, false, false, S>(grid, pos, row);
    }

    /// [`PaddedBlock::gather_axes_row`] for the first z-slice alone (see
    /// [`PaddedBlock::gather_star_row_planar`]).
    #[inline(always)]
    pub fn gather_axes_row_planar<S: TileSource>(
        &mut self,
        grid: &S,
        pos: usize,
        row: &NeighbourRow,
    ) {
        self.gather_parts::<true, false, true, S>(grid, pos, row);
    }

    /// Asks the CPU to bring into cache the neighbour tiles that a gather for the tile at
    /// list position `pos` (neighbours `row`) reads and the gathers of the tiles before it
    /// in the list did not: its +x neighbours (the list is x-fastest, so the others were
    /// the +x neighbours of earlier tiles). A hint only: no value changes. A sweep calls it
    /// [`PaddedBlock::PREFETCH_AHEAD`] tiles ahead of its gather; the loads of a gather from a band
    /// larger than the L2 cache wait on memory otherwise (measured with
    /// `levelset run sphere --renormalize coupled --rescale 1 --cfl 0.5 --steps 100
    /// --threads 1`, 2-core AMD EPYC, 2026-11-24, five alternated runs: 1.47–1.80 s, mean
    /// 1.61, → 1.37–1.51 s, mean 1.45; `levelset run enright --threads 1` 3–4 % faster).
    #[inline(always)]
    pub fn prefetch<S: TileSource>(grid: &S, row: &NeighbourRow) {
        // Directions with offset +1 along x (d = (ox + 1) + 3 (oy + 1) + 9 (oz + 1)).
        for d in [2, 5, 8, 11, 14, 17, 20, 23, 26] {
            if let Some(p) = row.get(d) {
                prefetch_tile(grid.part(p));
            }
        }
    }

    /// min |φ| over the 3×3×3 box of every voxel of the tile, in tile order: the band
    /// mask of the evolution (`levelset_kernels::BoxMinAbs` over this block, the same
    /// bits: the minimum of finite values does not depend on the order, and `abs` makes
    /// every zero +0), computed separably (along x, then y, then z; 9 instead of 27
    /// loads per voxel) from the box rows, which every gather fills. Returns whether any
    /// voxel's box holds a band voxel (a minimum below `gamma`).
    #[inline(always)]
    pub fn box_min_abs(&self, gamma: f32, out: &mut [f32; 64]) -> bool {
        self.box_min_abs_of::<false>(gamma, out)
    }

    /// [`PaddedBlock::box_min_abs`] of the first z-slice over its 3×3 squares, from the
    /// slice's box rows ([`PaddedBlock::gather_star_row_planar`]), copied into the other
    /// three slices. On a planar lattice every slice is a copy of the first, and the tiles
    /// above and below are absent (their ±γ is never below a minimum, which is at most γ)
    /// or copies too: the 3×3×3 box's minimum is the square's, the same bits.
    #[inline(always)]
    pub fn box_min_abs_planar(&self, gamma: f32, out: &mut [f32; 64]) -> bool {
        self.box_min_abs_of::<true>(gamma, out)
    }

    #[inline(always)]
    fn box_min_abs_of<const PLANAR: bool>(&self, gamma: f32, out: &mut [f32; 64]) -> bool {
        use levelset_kernels::{wide::f32x4, Lane};
        let (sx, w, r) = (Self::SX, Self::W, R);
        // z-rows of the box computed (index z + 1): −1..5 (all four slices) or the first
        // slice's alone.
        let zs = if PLANAR { 1..2 } else { 0..6 };
        let d = &self.data[..];
        let row = |i: usize| <f32x4 as Lane>::load(&d[i..i + 4]).abs();
        // Along x: rows y, z in -1..5 (index y + 6 z).
        let mut mx = [f32x4::splat(0.0); 36];
        for z in zs.clone() {
            let slice = 3 + sx * (r - 1) + sx * w * (z + r - 1);
            for y in 0..6 {
                let base = slice + sx * y;
                mx[y + 6 * z] = Lane::min(Lane::min(row(base), row(base + 1)), row(base + 2));
            }
        }
        // Along y: rows y in 0..4, z in -1..5 (index y + 4 z).
        let mut my = [f32x4::splat(0.0); 24];
        for z in zs {
            for y in 0..4 {
                let j = y + 6 * z;
                my[y + 4 * z] = Lane::min(Lane::min(mx[j], mx[j + 1]), mx[j + 2]);
            }
        }
        // Along z.
        let g = f32x4::splat(gamma);
        let mut any = false;
        let computed = if PLANAR { 16 } else { 64 };
        for (i, o) in out[..computed].chunks_exact_mut(4).enumerate() {
            let v =
                if PLANAR { my[i + 4] } else { Lane::min(Lane::min(my[i], my[i + 4]), my[i + 8]) };
            Lane::store(v, o);
            any |= g.any_gt(v);
        }
        if PLANAR {
            let (first, rest) = out.split_at_mut(16);
            rest.chunks_exact_mut(16).for_each(|slice| slice.copy_from_slice(first));
        }
        any
    }

    /// Fills the whole block (`STAR`: only the rows a [`levelset_kernels::TileWindow`]
    /// reads, see [`PaddedBlock::gather_star_row`]; `STAR` without `BOX`: only those along
    /// the axes, see [`PaddedBlock::gather_axes_row`]) from the tile at list position
    /// `pos`, whose neighbours are `row`.
    ///
    /// Padded row by padded row: a box row (`y, z` in `-1..5`) is the same x-row of three
    /// neighbouring parts, three 4-value copies; a star row outside the box is the tile
    /// column's piece alone. Against a loop over a precomputed table of row copies
    /// (`cargo bench --bench grids -- engine/sphere`, a sphere's band of 7,374 tiles, one
    /// thread, 2-core AMD EPYC, 2026-11-24): `R = 1` 721 → 280 µs, `R = 3` 898 → 456 µs;
    /// of that, the unchecked copies (instead of indexing with bounds checks) gave about two
    /// fifths.
    #[inline(always)]
    fn gather_parts<const STAR: bool, const BOX: bool, const PLANAR: bool, S: TileSource>(
        &mut self,
        grid: &S,
        pos: usize,
        row: &NeighbourRow,
    ) {
        let border = grid.border(pos);
        let gamma = grid.gamma();
        if gamma.to_bits() != self.dummy_gamma.to_bits() {
            self.dummy = [Tile::splat(gamma), Tile::splat(-gamma)];
            self.dummy_gamma = gamma;
        }
        // Each of the 27 parts is a neighbour tile or a "dummy tile" of ±γ chosen by the
        // border flag (set: the absent neighbour is inside).
        let part = parts(row, grid, pos, border, &self.dummy);
        let data: &mut [f32] = &mut self.data;
        let (r, w) = (R, Self::W);
        // A padded y or z coordinate `v` (in `0..W`, the local coordinate `v - R`): the
        // offset of its part (0, 1, 2 for −1, 0, +1) and its coordinate inside the part.
        let part_of = |v: usize| (v >= r) as usize + (v >= r + 4) as usize;
        let local = |v: usize| (v + 4 - r) % 4;
        let box_rows = r - 1..r + 5;
        let core = r..r + 4;
        for z in 0..w {
            for y in 0..w {
                // `in_box`: the row needs its three x-pieces; `in_star`: it is read at all.
                let (in_box, in_star) = if PLANAR {
                    // The rows the first z-slice's voxels read, a kernel on a planar
                    // lattice reading nothing off the slice (`inv_spacing` 0 along z, see
                    // `levelset_kernels::ImageRate`): the slice's box rows (or its own
                    // rows, whose x-neighbours the axes read) and its rows along y.
                    let first = z == r;
                    let in_box =
                        first && if BOX { box_rows.contains(&y) } else { core.contains(&y) };
                    (in_box, first)
                } else if !BOX {
                    let (cy, cz) = (core.contains(&y), core.contains(&z));
                    (cy && cz, cy || cz)
                } else if box_rows.contains(&y) && box_rows.contains(&z) {
                    (true, true)
                } else {
                    (false, core.contains(&y) || core.contains(&z))
                };
                if STAR && !in_star {
                    #[cfg(debug_assertions)]
                    data[12 * y + 12 * w * z..][..12].fill(f32::NAN);
                    continue;
                }
                let middle = 1 + 3 * part_of(y) + 9 * part_of(z);
                let src = 4 * local(y) + 16 * local(z);
                let dst = 12 * y + 12 * w * z;
                // The x-pieces: all three, or the tile column's alone (a star row outside
                // the box).
                let pieces = if STAR && !in_box { 1..2 } else { 0..3 };
                #[cfg(debug_assertions)]
                if pieces.len() == 1 {
                    data[dst..][..4].fill(f32::NAN);
                    data[dst + 8..][..4].fill(f32::NAN);
                }
                for k in pieces {
                    // SAFETY: `y, z < W`, so `dst + 4k + 4 <= 12 W² = data.len()`;
                    // `local(·) < 4`, so `src + 4 <= 64`; `middle - 1 + k < 27`.
                    unsafe { copy_row(data, dst + 4 * k, part[middle - 1 + k], src) };
                }
            }
        }
    }
}

/// The 27 parts of the padded block of the tile at list position `pos` among `values`,
/// whose neighbours are `row`: part `d` is the neighbour tile in direction `d`, or where it
/// is absent the dummy tile `dummy[1]` (−γ) if bit `d` of `border` is set (the absent
/// neighbour is inside) and `dummy[0]` (+γ) if not.
///
/// Line by line: a line's present neighbours are consecutive list positions from its first,
/// so each part's position is a running count, and every part is selected without a
/// branch. A plain loop, inlined into the sweep: the `array::from_fn` this replaced kept its
/// closure out of line (6–7 % of `levelset run sphere --renormalize coupled --rescale 1
/// --cfl 0.5 --steps 100 --threads 1` in `perf record`, 2-core AMD EPYC, 2026-11-28).
#[inline(always)]
fn parts<'g, S: TileSource>(
    row: &NeighbourRow,
    values: &'g S,
    pos: usize,
    border: u32,
    dummy: &'g [Tile; 2],
) -> [&'g [f32; 64]; 27] {
    let mut part = [&dummy[0].0; 27];
    for r in 0..9 {
        let mut p = row.first(r);
        for k in 0..3 {
            let d = 3 * r + k;
            let present = (row.matched >> d) & 1 != 0;
            let tile = values.part(if present { p } else { pos });
            let absent = &dummy[((border >> d) & 1) as usize].0;
            part[d] = if present { tile } else { absent };
            p += usize::from(present);
        }
    }
    part
}

/// Copies the 4 values at `src` of `part` to `data[dst..dst + 4]`.
///
/// # Safety
/// `dst + 4 <= data.len()` and `src + 4 <= 64`.
#[inline(always)]
unsafe fn copy_row(data: &mut [f32], dst: usize, part: &[f32; 64], src: usize) {
    debug_assert!(dst + 4 <= data.len() && src + 4 <= 64, "row copy out of range");
    // SAFETY: both ranges are in bounds by the caller's guarantee; `[f32; 4]` reads and
    // writes are unaligned.
    unsafe {
        let row = part.as_ptr().add(src).cast::<[f32; 4]>().read_unaligned();
        data.as_mut_ptr().add(dst).cast::<[f32; 4]>().write_unaligned(row);
    }
}

/// Prefetches the four cache lines of `tile` into every cache level.
#[inline(always)]
fn prefetch_tile(tile: &[f32; 64]) {
    for line in 0..4 {
        crate::memory::prefetch_line(tile.as_ptr().wrapping_add(16 * line));
    }
}
