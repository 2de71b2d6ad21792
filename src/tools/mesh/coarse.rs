//! Coarser meshes ([`super::MeshOptions::coarsen`]): the isosurface of φ sampled at every
//! k-th voxel, meshed on the Kuhn triangulation of that coarser lattice (Sec. 2.1 with
//! cells of k voxels).
//!
//! A level set is a signed distance, so its samples on the lattice kZ³ are the signed
//! distance on that lattice: the zero set of their simplicial interpolant is the same
//! surface, resolved with cells of k voxels (about k² fewer triangles), and everything
//! that holds for the full-resolution mesh holds for it, because it *is* the full mesh
//! of another level set: one welded vertex per Kuhn edge, the ε rule and the δ offset,
//! a closed manifold, the same bits for any thread count. A decimation of the fine mesh
//! (edge collapses under a quadric error bound) was the alternative; it would need a
//! second, global pass over the fine mesh (slower than meshing it) and its own checks
//! that no collapse pinches or folds the surface, which the coarse lattice gets from
//! the construction.
//!
//! # Which samples
//! The coarse grid is a tile grid of voxel size k·h at the same origin: coarse voxel c
//! holds the fine value at voxel k·c ([`TileGrid::value`], so absent fine tiles read
//! ±γ). It stores every coarse tile that holds the lower corner of a coarse cell meeting
//! a stored fine tile. A coarse cell whose corners change sign has a fine voxel pair
//! with a sign change inside it, hence a stored fine tile (a valid band stores every
//! voxel next to a sign change), so the cell's lower corner is stored and the cell is
//! meshed: no holes. Absent coarse tiles read ±kγ (the coarse grid keeps the half-width
//! in voxels) with the sign of the fine value at their first voxel.
//!
//! # What it costs in accuracy
//! The interpolant's error is O((kh)² κ) for curvature κ. A coarse Kuhn edge is k·|d|
//! voxels long (k, k√2 or k√3); where φ changes sign along it both ends lie within that
//! distance of the surface, so both are band samples (|φ| < γ = w voxels) when k·|d| < w.
//! With the default half-width w = 3 that is every edge for k = 1 and all but the main
//! diagonals for k = 2 (2√3 > 3); a crossing with an end clamped at ±γ is placed as if
//! the far sample were at γ, so the error grows past k = 2 (sphere r = 60: area
//! −2.8·10⁻⁴, +1.3·10⁻³, +1.1·10⁻² for k = 2, 3, 4; `docs/mesh.md`). Features thinner
//! than about k voxels can vanish or merge, as in any coarser sampling.

use super::MeshError;
use crate::grid::GridSpec;
use crate::storage::tiles::{Tile, TileGrid};
use crate::Coord;
use rayon::prelude::*;

/// The tile grid of `grid`'s values at every `k`-th voxel (see the module docs).
pub(super) fn sample(grid: &TileGrid, k: u32) -> Result<TileGrid, MeshError> {
    let spec = grid.spec();
    let coarse_spec = GridSpec::new(spec.voxel_size * k as f32, spec.origin, spec.half_width)
        .map_err(|e| MeshError::InvalidParameter(format!("coarsen {k}: {e}")))?;
    let k = k as i64;
    // The coarse cells c (lower corners) whose box [k c, k (c + 1)] meets the fine tile
    // with first voxel f along one axis, as the coarse tiles that hold them.
    let tiles_of = |f: i64| -> (i64, i64) {
        let lo = (f + k - 1).div_euclid(k) - 1;
        let hi = (f + 3).div_euclid(k);
        (lo.div_euclid(4), hi.div_euclid(4))
    };
    let mut coords: Vec<Coord> = grid
        .tile_coords()
        .par_iter()
        .flat_map_iter(|t| {
            let r = [t.x, t.y, t.z].map(|c| tiles_of(4 * c as i64));
            (r[2].0..=r[2].1).flat_map(move |z| {
                (r[1].0..=r[1].1).flat_map(move |y| {
                    (r[0].0..=r[0].1).map(move |x| Coord::new(x as i32, y as i32, z as i32))
                })
            })
        })
        .collect();
    coords.par_sort_unstable();
    coords.dedup();
    // Fine voxels beyond the i32 range are outside, as beyond the grid's tiles.
    let fine = |v: [i64; 3]| -> f32 {
        let ok = |c: i64| (i32::MIN as i64..=i32::MAX as i64).contains(&c);
        if v.iter().all(|&c| ok(c)) {
            grid.value(Coord::new(v[0] as i32, v[1] as i32, v[2] as i32))
        } else {
            grid.gamma()
        }
    };
    let tiles: Vec<Tile> = coords
        .par_iter()
        .map(|t| {
            // Per axis: the fine voxel of each of the tile's four coarse coordinates, the
            // distinct fine tiles they fall in (at most four), and which one each uses.
            let axis = [t.x, t.y, t.z].map(|c| {
                let f = [0, 1, 2, 3].map(|i| k * (4 * c as i64 + i));
                let mut tiles = [0i64; 4];
                let mut which = [0usize; 4];
                let mut n = 0;
                for (i, &v) in f.iter().enumerate() {
                    let ft = v.div_euclid(4);
                    if n == 0 || tiles[n - 1] != ft {
                        tiles[n] = ft;
                        n += 1;
                    }
                    which[i] = n - 1;
                }
                (f, tiles, which, n)
            });
            // One lookup per fine tile: its list position, or the value it reads as
            // absent (or beyond the representable range).
            let in_range = |c: i64| (i32::MIN as i64 >> 2..=i32::MAX as i64 >> 2).contains(&c);
            let mut fine_tiles = [[[Err(0f32); 4]; 4]; 4];
            for (iz, &tz) in axis[2].1[..axis[2].3].iter().enumerate() {
                for (iy, &ty) in axis[1].1[..axis[1].3].iter().enumerate() {
                    for (ix, &tx) in axis[0].1[..axis[0].3].iter().enumerate() {
                        let ft = [tx, ty, tz];
                        fine_tiles[iz][iy][ix] = if ft.iter().all(|&c| in_range(c)) {
                            let c = Coord::new(tx as i32, ty as i32, tz as i32);
                            grid.find_tile(c).map_err(|_| fine(ft.map(|c| 4 * c)))
                        } else {
                            Err(grid.gamma())
                        };
                    }
                }
            }
            let mut tile = Tile::splat(0.0);
            for (l, v) in tile.0.iter_mut().enumerate() {
                let (ix, iy, iz) = (l & 3, (l >> 2) & 3, l >> 4);
                let f = [axis[0].0[ix], axis[1].0[iy], axis[2].0[iz]];
                *v = match fine_tiles[axis[2].2[iz]][axis[1].2[iy]][axis[0].2[ix]] {
                    Ok(p) => {
                        let fl = f.map(|c| c.rem_euclid(4) as usize);
                        grid.tile(p).0[fl[0] + 4 * fl[1] + 16 * fl[2]]
                    }
                    Err(background) => background,
                };
            }
            tile
        })
        .collect();
    let inside = |t: Coord| fine([t.x, t.y, t.z].map(|c| 4 * k * c as i64)) < 0.0;
    TileGrid::from_sorted_tiles(coarse_spec, coords.into_iter().zip(tiles), inside)
        .map_err(|e| MeshError::InvalidParameter(format!("coarsen {k}: {e}")))
}
