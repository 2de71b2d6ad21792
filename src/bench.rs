//! Reference stencil passes over both storages with identical scalar arithmetic
//! (`smooth7`, `star19`): what the storage benchmark (`levelset-speedup --storage`) and the
//! criterion benches (`benches/grids.rs`) time, so a ratio measures the data structures —
//! tile traversal with a padded block (van der Laan et al. 2011, Sec. 4.4, 4.7) against the DT-Grid
//! stencil iterator (Nielsen & Museth 2006, Sec. 3.3) — and not different arithmetic.

use crate::storage::dtgrid::{DtGrid, Stencil, StencilIter};
use crate::storage::tiles::{tile_of, NeighbourCursor, PaddedBlock, Tile, TileGrid};

/// One explicit diffusion step of the 7-point Laplacian, clamped to the band.
/// `v` is the 7-point star `[centre, -x, +x, -y, +y, -z, +z]`.
#[inline(always)]
fn smooth7(v: [f32; 7], g: f32) -> f32 {
    let [c, xm, xp, ym, yp, zm, zp] = v;
    (c + 0.1 * ((xm + xp) + (ym + yp) + (zm + zp) - 6.0 * c)).clamp(-g, g)
}

/// Weights of the 19-point star (centre, then ±1..±3 per axis): a read pattern like
/// HJ-WENO5's.
const STAR_W: [f32; 4] = [0.4, 0.06, 0.03, 0.01];

#[inline(always)]
fn star19(c: f32, axis: [[f32; 6]; 3]) -> f32 {
    let mut s = STAR_W[0] * c;
    for a in axis {
        s += STAR_W[1] * (a[2] + a[3]) + STAR_W[2] * (a[1] + a[4]) + STAR_W[3] * (a[0] + a[5]);
    }
    s
}

/// `smooth7` over every tile: gather a 1-voxel halo, update 64 voxels. Output in list order.
pub fn tiles_smooth7(grid: &TileGrid, out: &mut Vec<Tile>) {
    // The PaddedBlock<1> layout: rows of 12 (x from -4), 6 rows per slice.
    const SY: usize = 12;
    const SZ: usize = 12 * 6;
    out.clear();
    out.reserve(grid.len());
    let g = grid.gamma();
    let mut block = PaddedBlock::<1>::new();
    let mut cur = NeighbourCursor::new(grid.tile_coords(), 0, grid.len());
    while let Some(nb) = cur.next() {
        block.gather(grid, &nb);
        let d = block.data();
        let mut t = Tile::splat(0.0);
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4 {
                    let i = (x + 4) + SY * (y + 1) + SZ * (z + 1);
                    let star =
                        [d[i], d[i - 1], d[i + 1], d[i - SY], d[i + SY], d[i - SZ], d[i + SZ]];
                    t.0[x + 4 * y + 16 * z] = smooth7(star, g);
                }
            }
        }
        out.push(t);
    }
}

/// `smooth7` over every DT-Grid point with the 7-point stencil iterator.
pub fn dtgrid_smooth7(grid: &DtGrid, out: &mut Vec<f32>) {
    out.clear();
    out.resize(grid.len(), 0.0);
    let g = grid.gamma();
    let mut it = StencilIter::new(grid, &Stencil::star7());
    while it.advance() {
        let v = it.values();
        out[it.center_index()] = smooth7(v.try_into().expect("7-point star"), g);
    }
}

/// The same 7-point smoothing over an H-RLE level set, read with its stencil iterator
/// ([`crate::storage::hrle::HrleGrid::for_each_star`]); the output is indexed like the DT-Grid's.
pub fn hrle_smooth7(grid: &crate::storage::hrle::HrleGrid, out: &mut Vec<f32>) {
    out.clear();
    out.resize(grid.len(), 0.0);
    let g = grid.spec().gamma();
    grid.for_each_star(|_, i, v| out[i] = smooth7(v, g));
}

/// `star19` over every tile with a 3-voxel halo.
pub fn tiles_star19(grid: &TileGrid, out: &mut Vec<Tile>) {
    // The PaddedBlock<3> layout: rows of 12 (x from -4), 10 rows per slice, 10 slices.
    const SY: usize = 12;
    const SZ: usize = 12 * 10;
    out.clear();
    out.reserve(grid.len());
    let mut block = PaddedBlock::<3>::new();
    let mut cur = NeighbourCursor::new(grid.tile_coords(), 0, grid.len());
    while let Some(nb) = cur.next() {
        block.gather(grid, &nb);
        let d: &[f32; SZ * 10] = block.data().try_into().expect("12×10×10 block");
        let mut t = Tile::splat(0.0);
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4 {
                    let i = (x + 4) + SY * (y + 3) + SZ * (z + 3);
                    let ax = |s: usize| {
                        [d[i - 3 * s], d[i - 2 * s], d[i - s], d[i + s], d[i + 2 * s], d[i + 3 * s]]
                    };
                    t.0[x + 4 * y + 16 * z] = star19(d[i], [ax(1), ax(SY), ax(SZ)]);
                }
            }
        }
        out.push(t);
    }
}

/// `star19` over every DT-Grid point with the WENO5 stencil iterator.
pub fn dtgrid_star19(grid: &DtGrid, out: &mut Vec<f32>) {
    out.clear();
    out.resize(grid.len(), 0.0);
    let mut it = StencilIter::new(grid, &Stencil::weno5());
    while it.advance() {
        let v = it.values();
        let mut axis = [[0.0f32; 6]; 3];
        for (a, ax) in axis.iter_mut().enumerate() {
            ax.copy_from_slice(&v[1 + 6 * a..7 + 6 * a]);
        }
        out[it.center_index()] = star19(v[0], axis);
    }
}

/// Largest |difference| between a tile result and a DT-Grid result over the DT-Grid's
/// points (the band voxels both grids store).
pub fn max_abs_diff(tiles: &TileGrid, tile_out: &[Tile], dt: &DtGrid, dt_out: &[f32]) -> f32 {
    let mut m = 0.0f32;
    let mut pos = 0usize;
    for (i, (c, _)) in dt.iter().enumerate() {
        let (t, l) = tile_of(c);
        // DT-Grid points come in lexicographic order, tiles are not visited in that order:
        // find the tile (near the last one) by binary search.
        if tiles.tile_coords().get(pos) != Some(&t) {
            pos = tiles.find_tile(t).expect("every band voxel lies in a tile");
        }
        m = m.max((tile_out[pos].0[l] - dt_out[i]).abs());
    }
    m
}
