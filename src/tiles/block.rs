//! A tile with a halo of `R` voxels gathered from its 26 neighbours: the stencil window
//! the kernels read for a whole tile at once (tile paper Sec. 4.7: values at the tile's
//! borders come from the neighbour tiles, or from a "dummy tile" of ±γ chosen by the
//! border flag where the neighbour is absent).

use super::{NeighbourRow, Neighbours, Tile, TileGrid, TILE_DIM};

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
        self.gather_with(grid, nb.pos, |d| nb.get(d));
    }

    /// Fills the block for the tile at list position `pos`, whose neighbours are `row`
    /// (from a [`super::NeighbourTable`] of `grid`'s list).
    #[inline]
    pub fn gather_row(&mut self, grid: &TileGrid, pos: usize, row: &NeighbourRow) {
        self.gather_with(grid, pos, |d| row.get(d));
    }

    /// Fills the rows of the block that the kernels' [`levelset_kernels::TileWindow`]
    /// reads (the 3×3×3 box and the axis offsets up to `R`, see
    /// [`levelset_kernels::TileBlock`]) for the tile at list position `pos`, whose
    /// neighbours are `row`. For `R = 1` that is the whole block; for `R = 3` 140 of the
    /// 300 row copies of [`PaddedBlock::gather_row`]. Other entries keep what they held.
    #[inline]
    pub fn gather_star_row(&mut self, grid: &TileGrid, pos: usize, row: &NeighbourRow) {
        let plan = &Self::STAR;
        self.gather_plan(grid, pos, |d| row.get(d), &plan.rows[..plan.len]);
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
    pub fn prefetch(grid: &TileGrid, row: &NeighbourRow) {
        // Directions with offset +1 along x (d = (ox + 1) + 3 (oy + 1) + 9 (oz + 1)).
        for d in [2, 5, 8, 11, 14, 17, 20, 23, 26] {
            if let Some(p) = row.get(d) {
                prefetch_tile(grid.tile(p));
            }
        }
    }

    #[inline(always)]
    fn gather_with(&mut self, grid: &TileGrid, pos: usize, get: impl Fn(usize) -> Option<usize>) {
        let plan = &Self::FULL;
        self.gather_plan(grid, pos, get, &plan.rows[..plan.len]);
    }

    /// min |φ| over the 3×3×3 box of every voxel of the tile, in tile order: the band
    /// mask of the evolution (`levelset_kernels::BoxMinAbs` over this block, the same
    /// bits: the minimum of finite values does not depend on the order, and `abs` makes
    /// every zero +0), computed separably (along x, then y, then z; 9 instead of 27
    /// loads per voxel) from the box rows, which every gather fills. Returns whether any
    /// voxel's box holds a band voxel (a minimum below `gamma`).
    #[inline]
    pub fn box_min_abs(&self, gamma: f32, out: &mut [f32; 64]) -> bool {
        use levelset_kernels::{wide::f32x4, Lane};
        let (sx, w, r) = (Self::SX, Self::W, R);
        let d = &self.data[..];
        let row = |i: usize| <f32x4 as Lane>::load(&d[i..i + 4]).abs();
        // Along x: rows y, z in -1..5 (index y + 6 z).
        let mut mx = [f32x4::splat(0.0); 36];
        for z in 0..6 {
            let slice = 3 + sx * (r - 1) + sx * w * (z + r - 1);
            for y in 0..6 {
                let base = slice + sx * y;
                mx[y + 6 * z] = Lane::min(Lane::min(row(base), row(base + 1)), row(base + 2));
            }
        }
        // Along y: rows y in 0..4, z in -1..5 (index y + 4 z).
        let mut my = [f32x4::splat(0.0); 24];
        for z in 0..6 {
            for y in 0..4 {
                let j = y + 6 * z;
                my[y + 4 * z] = Lane::min(Lane::min(mx[j], mx[j + 1]), mx[j + 2]);
            }
        }
        // Along z.
        let g = f32x4::splat(gamma);
        let mut any = false;
        for (i, o) in out.chunks_exact_mut(4).enumerate() {
            let v = Lane::min(Lane::min(my[i], my[i + 4]), my[i + 8]);
            Lane::store(v, o);
            any |= g.any_gt(v);
        }
        any
    }

    /// The whole block, part by part.
    const FULL: Plan = plan(R, false);
    /// The box rows and the star's centre rows, part by part.
    const STAR: Plan = plan(R, true);

    #[inline(always)]
    fn gather_plan(
        &mut self,
        grid: &TileGrid,
        pos: usize,
        get: impl Fn(usize) -> Option<usize>,
        plan: &[RowCopy],
    ) {
        let values = grid.values();
        let border = grid.border_flags(pos);
        let gamma = grid.gamma();
        if gamma.to_bits() != self.dummy_gamma.to_bits() {
            self.dummy = [Tile::splat(gamma), Tile::splat(-gamma)];
            self.dummy_gamma = gamma;
        }
        let dummy = &self.dummy;
        // Each of the 27 parts is a neighbour tile or a "dummy tile" of ±γ chosen by the
        // border flag (set: the absent neighbour is inside).
        let part: [&[f32; 64]; 27] = std::array::from_fn(|d| match get(d) {
            Some(p) => &values[p].0,
            None => &dummy[((border >> d) & 1) as usize].0,
        });
        let data: &mut [f32] = &mut self.data;
        for c in plan {
            let (src, dst) = (c.src as usize, c.dst as usize);
            data[dst..dst + 4].copy_from_slice(&part[c.part as usize][src..src + 4]);
        }
    }
}

/// Prefetches the four cache lines of `tile` into every cache level.
#[inline(always)]
fn prefetch_tile(tile: &Tile) {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = tile.0.as_ptr().cast::<i8>();
        for line in 0..4 {
            // SAFETY: a prefetch is a hint that never faults, whatever the address (this
            // one is inside `tile`); SSE is part of every x86_64 target.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = tile;
}

/// Whether block coordinate `v` (along y or z: `-r..0` the − neighbour, `0..4` the tile,
/// `4..` the + neighbour) lies in the part at offset `o`.
const fn in_part(v: i32, o: i32) -> bool {
    (o == -1 && v < 0) || (o == 0 && v >= 0 && v < 4) || (o == 1 && v >= 4)
}

const fn inner(v: i32) -> bool {
    v >= 0 && v < 4
}

const fn boxed(v: i32) -> bool {
    v >= -1 && v < 5
}

/// One 4-value row copy of a gather: from `src` (local index of a row start) of part
/// `part` (the neighbour direction, [`crate::coord::NEIGHBOURHOOD`] order) to `dst`
/// (padded index).
#[derive(Clone, Copy)]
struct RowCopy {
    part: u8,
    src: u8,
    dst: u16,
}

/// The row copies of a gather, in part order (`len` of `rows` used).
struct Plan {
    len: usize,
    rows: [RowCopy; MAX_COPIES],
}

/// Row copies of the largest block (`R = 4`: 12 × 12 padded rows of three pieces).
const MAX_COPIES: usize = 3 * 12 * 12;

/// The row copies that fill a block with halo `r` (`star`: only the rows a
/// [`levelset_kernels::TileWindow`] reads), grouped by part so that the loads of one
/// neighbour tile follow each other. Evaluated at compile time.
const fn plan(r: usize, star: bool) -> Plan {
    let ri = r as i32;
    let w = 4 + 2 * ri;
    let mut out = Plan { len: 0, rows: [RowCopy { part: 0, src: 0, dst: 0 }; MAX_COPIES] };
    let mut d = 0usize;
    while d < 27 {
        let (ox, oy, oz) = ((d % 3) as i32 - 1, ((d / 3) % 3) as i32 - 1, (d / 9) as i32 - 1);
        let mut z = -ri;
        while z < 4 + ri {
            let mut y = -ri;
            while y < 4 + ri {
                // The star: box rows (all three pieces), and the tile's piece of the rows
                // along y and z through the tile.
                let wanted = !star || (boxed(y) && boxed(z)) || (ox == 0 && (inner(y) || inner(z)));
                if in_part(y, oy) && in_part(z, oz) && wanted {
                    let (ly, lz) = ((y + 4) % 4, (z + 4) % 4);
                    let dst = 4 * (ox + 1) + 12 * (y + ri) + 12 * w * (z + ri);
                    assert!(dst + 4 <= 12 * w * w);
                    out.rows[out.len] =
                        RowCopy { part: d as u8, src: (4 * ly + 16 * lz) as u8, dst: dst as u16 };
                    out.len += 1;
                }
                y += 1;
            }
            z += 1;
        }
        d += 1;
    }
    out
}
