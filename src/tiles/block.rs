//! A tile with a halo of `R` voxels gathered from its 26 neighbours: the stencil window
//! the kernels read for a whole tile at once (tile paper Sec. 4.7: values at the tile's
//! borders come from the neighbour tiles, or from a "dummy tile" of ±γ chosen by the
//! border flag where the neighbour is absent).

use super::{Neighbours, TileGrid, TILE_DIM};

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
        let values = grid.values();
        let border = grid.border_flags(nb.pos);
        let gamma = grid.gamma();
        for d in 0..27usize {
            let src = nb.get(d).map(|p| &values[p].0);
            let fill = if border & (1 << d) != 0 { -gamma } else { gamma };
            // Dispatch on the x extent so every row copy has a compile-time length (a
            // run-time `copy_from_slice` of 1..4 floats costs a call per row).
            match d % 3 {
                0 => self.copy_part::<R>(d, src, fill),
                1 => self.copy_part::<4>(d, src, fill),
                _ => self.copy_part::<R>(d, src, fill),
            }
        }
    }

    /// Copies the part of the halo (or the tile itself) that neighbour `d` covers: `NX`
    /// voxels per row. Absent neighbours (`src == None`) fill it with `fill`.
    #[inline(always)]
    fn copy_part<const NX: usize>(&mut self, d: usize, src: Option<&[f32; 64]>, fill: f32) {
        let w = Self::W;
        // Per axis: (first source voxel in the neighbour, first destination, length).
        let span = |o: usize| -> (usize, usize, usize) {
            match o {
                0 => (4 - R, 0, R),
                1 => (0, R, 4),
                _ => (0, R + 4, R),
            }
        };
        let (sx, dx, _) = span(d % 3);
        let (sy, dy, ny) = span((d / 3) % 3);
        let (sz, dz, nz) = span(d / 9);
        for z in 0..nz {
            for y in 0..ny {
                let o = dx + w * (dy + y) + w * w * (dz + z);
                let dst: &mut [f32; NX] =
                    (&mut self.data[o..o + NX]).try_into().expect("row inside the block");
                match src {
                    Some(t) => {
                        let s = sx + 4 * (sy + y) + 16 * (sz + z);
                        *dst = t[s..s + NX].try_into().expect("row inside the tile");
                    }
                    None => *dst = [fill; NX],
                }
            }
        }
    }
}
