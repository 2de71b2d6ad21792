//! A tile with a halo of `R` voxels gathered from its 26 neighbours: the stencil window
//! the kernels read for a whole tile at once (tile paper Sec. 4.7: values at the tile's
//! borders come from the neighbour tiles, or from a "dummy tile" of ±γ chosen by the
//! border flag where the neighbour is absent).

use super::{NeighbourRow, Neighbours, TileGrid, TILE_DIM};

/// The values of a tile and an `R`-voxel halo around it, x fastest:
/// `data[(x + R) + W (y + R) + W² (z + R)]` for local coordinates `x, y, z` in `-R..4+R`,
/// `W = 4 + 2R`. Reused across tiles: [`PaddedBlock::gather`] overwrites every entry.
///
/// `R` must be in 1..=4 (a halo wider than a tile would need more than 26 neighbours).
#[derive(Clone)]
pub struct PaddedBlock<const R: usize> {
    data: Vec<f32>,
}

impl<const R: usize> Default for PaddedBlock<R> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const R: usize> PaddedBlock<R> {
    /// Edge length of the padded block.
    pub const W: usize = 4 + 2 * R;
    const CHECK: () = assert!(R >= 1 && R <= TILE_DIM as usize, "halo must be 1..=4 voxels");

    pub fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        PaddedBlock { data: vec![0.0; Self::W * Self::W * Self::W] }
    }

    /// The padded values, x fastest.
    #[inline(always)]
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// Value at local coordinates (each in `-R..4+R`).
    #[inline(always)]
    pub fn get(&self, x: i32, y: i32, z: i32) -> f32 {
        let r = R as i32;
        let w = Self::W as i32;
        self.data[((x + r) + w * (y + r) + w * w * (z + r)) as usize]
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
        // Each of the 27 parts comes from a neighbour tile or is a "dummy tile" of ±γ.
        let part: [Result<&[f32; 64], f32>; 27] = std::array::from_fn(|d| match get(d) {
            Some(p) => Ok(&values[p].0),
            None => Err(if border & (1 << d) != 0 { -gamma } else { gamma }),
        });
        let w = Self::W;
        let r = R as i32;
        // Block coordinate → (neighbour offset + 1, local coordinate in that tile).
        let split = |v: i32| -> (usize, usize) {
            if v < 0 {
                (0, (v + 4) as usize)
            } else if v < 4 {
                (1, v as usize)
            } else {
                (2, (v - 4) as usize)
            }
        };
        // Row by row along x: the left neighbour's last R voxels, the tile's 4, the right
        // neighbour's first R — three copies of compile-time length per padded row.
        for (row, out) in self.data.chunks_exact_mut(w).enumerate() {
            let (y, z) = ((row % w) as i32 - r, (row / w) as i32 - r);
            let ((oy, ly), (oz, lz)) = (split(y), split(z));
            let base = 3 * oy + 9 * oz;
            let at = 4 * ly + 16 * lz;
            let (left, rest) = out.split_at_mut(R);
            let (mid, right) = rest.split_at_mut(4);
            copy_or_fill(left, part[base], at + 4 - R);
            copy_or_fill(mid, part[base + 1], at);
            copy_or_fill(right, part[base + 2], at);
        }
    }
}

/// Copies `dst.len()` values of a tile from local index `from`, or fills with ±γ.
#[inline(always)]
fn copy_or_fill(dst: &mut [f32], src: Result<&[f32; 64], f32>, from: usize) {
    match src {
        Ok(t) => dst.copy_from_slice(&t[from..from + dst.len()]),
        Err(fill) => dst.fill(fill),
    }
}
