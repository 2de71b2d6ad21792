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
/// the gather overwrites every entry.
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

    #[inline(always)]
    fn gather_with(&mut self, grid: &TileGrid, pos: usize, get: impl Fn(usize) -> Option<usize>) {
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
        let (sx, w, r) = (Self::SX, Self::W, R as i32);
        // Block coordinate along y or z → (neighbour offset + 1, local coordinate).
        let split = |v: i32| -> (usize, usize) {
            if v < 0 {
                (0, (v + 4) as usize)
            } else if v < 4 {
                (1, v as usize)
            } else {
                (2, (v - 4) as usize)
            }
        };
        for (row, out) in self.data.chunks_exact_mut(sx).enumerate() {
            let (y, z) = ((row % w) as i32 - r, (row / w) as i32 - r);
            let ((oy, ly), (oz, lz)) = (split(y), split(z));
            let base = 3 * oy + 9 * oz;
            let at = 4 * ly + 16 * lz;
            for (k, dst) in out.chunks_exact_mut(4).enumerate() {
                dst.copy_from_slice(&part[base + k][at..at + 4]);
            }
        }
    }
}
