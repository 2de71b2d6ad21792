//! The Sorted Tile List (van der Laan et al. 2011, Sec. 4): 4³ tiles of f32 in a
//! 64-byte-aligned arena behind a lexicographically sorted list of tile coordinates.
//!
//! * [`TileGrid`] holds the list, the arena and the per-tile flags (Sec. 4.1).
//! * [`NeighbourCursor`] walks the list with the 26-neighbour tracking of Algorithm 1
//!   (Sec. 4.4) and can start at any list position (its pointers are seeded by binary
//!   search, Sec. 5.8), which is what parallel chunks use.
//! * [`PaddedBlock`] gathers a tile and an R-voxel halo from its neighbours: the stencil
//!   window of a whole tile.
//! * [`DilationStream`] is the streaming dilation of the sorted list (Algorithm 2,
//!   Sec. 4.6.1); [`TileGrid::manage_tiles`] runs the tile update of Algorithm 3 on it.
//!
//! Tile coordinates are voxel coordinates divided by 4 with floor (`voxel >> 2`); inside a
//! tile x is fastest: `local = lx + 4 ly + 16 lz`.

mod block;
mod directory;
pub mod flags;
mod grid;
mod manage;
mod stream;

pub use block::{InPlaceTiles, PaddedBlock, TileSource};
pub use flags::{
    compute_activity, region_of_local, ACTIVE_MASK, BORDER_MASK, INSIDE, NEIGHBOUR_TRIGGER,
};
pub use grid::{ManageStats, TileGrid};
pub use stream::{DilationStream, NeighbourCursor, NeighbourRow, NeighbourTable, Neighbours};

use crate::coord::Coord;
use crate::grid::{GridSpec, MemoryReport};
use crate::storage::levelset::{Accessor, LevelSet};

/// Voxels along a tile edge.
pub const TILE_DIM: i32 = 4;
/// Voxels in a tile.
pub const TILE_LEN: usize = 64;
/// Voxels in one z-slice of a tile: what a planar lattice's tile holds (a 2-D level set is
/// extruded over a tile layer's `TILE_DIM` slices; the sweeps compute the first slice
/// and copy it into the others).
pub const SLICE_LEN: usize = TILE_LEN / TILE_DIM as usize;
/// Smallest tile coordinate whose voxels fit in i32.
pub const TILE_MIN: i32 = i32::MIN >> 2;
/// Largest tile coordinate whose voxels fit in i32.
pub const TILE_MAX: i32 = i32::MAX >> 2;

/// The values of one 4³ tile, x fastest (`local = lx + 4 ly + 16 lz`), aligned to a
/// 64-byte cache line so a 4×4 z-slice is one aligned 16-lane load.
#[derive(Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(64))]
pub struct Tile(pub [f32; TILE_LEN]);

impl Tile {
    /// A tile with every voxel set to `v`.
    pub const fn splat(v: f32) -> Tile {
        Tile([v; TILE_LEN])
    }
}

impl std::fmt::Debug for Tile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.0.iter()).finish()
    }
}

/// Local index of voxel (lx, ly, lz) in a tile, each in 0..4.
#[inline(always)]
pub const fn local_index(lx: i32, ly: i32, lz: i32) -> usize {
    (lx + 4 * ly + 16 * lz) as usize
}

/// The tile holding `voxel` and the voxel's local index in it.
#[inline(always)]
pub fn tile_of(voxel: Coord) -> (Coord, usize) {
    let t = Coord::new(voxel.x >> 2, voxel.y >> 2, voxel.z >> 2);
    (t, local_index(voxel.x & 3, voxel.y & 3, voxel.z & 3))
}

/// The voxel coordinate of local index `local` in tile `t` (t must be in
/// [`TILE_MIN`]..=[`TILE_MAX`]).
#[inline(always)]
pub fn voxel_of(t: Coord, local: usize) -> Coord {
    let l = local as i32;
    Coord::new(4 * t.x + (l & 3), 4 * t.y + ((l >> 2) & 3), 4 * t.z + (l >> 4))
}

/// Whether every voxel of tile coordinate `t` is representable in i32.
#[inline(always)]
pub fn tile_in_range(t: Coord) -> bool {
    let ok = |v: i32| (TILE_MIN..=TILE_MAX).contains(&v);
    ok(t.x) && ok(t.y) && ok(t.z)
}

/// A `u128` whose unsigned order is the [`Coord`] order (z, then y, then x): each
/// component biased to unsigned. Comparing two of these is two `u64` compares without
/// branches, which makes the binary search below branch-free.
#[inline(always)]
fn order_key(c: Coord) -> u128 {
    let u = |v: i32| (v as u32 ^ 0x8000_0000) as u128;
    (u(c.z) << 64) | (u(c.y) << 32) | u(c.x)
}

/// First position in the sorted `coords` whose coordinate is not less than `c`
/// (`coords.len()` if none): a branch-free binary search (van der Laan et al. 2011,
/// Sec. 4.5).
#[inline]
pub fn lower_bound(coords: &[Coord], c: Coord) -> usize {
    let k = order_key(c);
    let mut base = 0usize;
    let mut size = coords.len();
    if size == 0 {
        return 0;
    }
    while size > 1 {
        let half = size / 2;
        let mid = base + half;
        let probe = order_key(coords[mid]);
        base = if probe < k { mid } else { base };
        size -= half;
    }
    base + (order_key(coords[base]) < k) as usize
}

/// The tile accessor: a direct-mapped table over the low two bits of each tile
/// coordinate, so the 2×2×2 tiles around any cell, or the 3×3×3 around a tile, take
/// distinct slots. A slot holds the tile's list position, or the ±γ of an absent tile.
/// (For the renderer the random tile searches were two thirds of the time without it.)
pub struct TileAccessor<'a> {
    grid: &'a TileGrid,
    keys: [Coord; 64],
    /// `Ok(list position)` or `Err(value of every voxel of the absent tile)`.
    slots: [Result<usize, f32>; 64],
    filled: u64,
}

impl<'a> TileAccessor<'a> {
    /// An empty cache over `grid`.
    pub fn new(grid: &'a TileGrid) -> Self {
        TileAccessor { grid, keys: [Coord::default(); 64], slots: [Err(0.0); 64], filled: 0 }
    }
}

impl Accessor for TileAccessor<'_> {
    #[inline]
    fn value(&mut self, voxel: Coord) -> f32 {
        let (t, l) = tile_of(voxel);
        let i = ((t.x & 3) | (t.y & 3) << 2 | (t.z & 3) << 4) as usize;
        if self.filled & (1 << i) == 0 || self.keys[i] != t {
            self.keys[i] = t;
            self.filled |= 1 << i;
            self.slots[i] = self.grid.find_tile(t).map_err(|_| self.grid.value(voxel_of(t, 0)));
        }
        match self.slots[i] {
            Ok(pos) => self.grid.tile(pos).0[l],
            Err(v) => v,
        }
    }
}

impl LevelSet for TileGrid {
    fn spec(&self) -> GridSpec {
        *TileGrid::spec(self)
    }
    fn value(&self, voxel: Coord) -> f32 {
        TileGrid::value(self, voxel)
    }
    fn accessor(&self) -> impl Accessor + '_ {
        TileAccessor::new(self)
    }
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        let g = self.gamma();
        self.for_each_voxel_sorted(|c, v| {
            if v.abs() < g {
                f(c, v)
            }
        });
    }
    fn band_voxels(&self) -> usize {
        TileGrid::band_voxels(self)
    }
    fn bounding_box(&self) -> Option<(Coord, Coord)> {
        TileGrid::bounding_box(self)
    }
    fn memory(&self) -> MemoryReport {
        TileGrid::memory(self)
    }
    fn storage(&self) -> Option<&dyn std::any::Any> {
        Some(self)
    }
}

impl TileGrid {
    /// The Sorted Tile List behind `ls`, when it is one ([`LevelSet::storage`]).
    pub fn of<L: LevelSet + ?Sized>(ls: &L) -> Option<&TileGrid> {
        ls.storage()?.downcast_ref()
    }
}

#[cfg(test)]
mod tests;
