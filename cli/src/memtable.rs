//! The memory table (`levelset-speedup --memory`), in the style of Houston et al. 2006,
//! Table II: the bytes of one level set held by the H-RLE encoding, the DT-Grid and the
//! Sorted Tile List, and the size of its `.sls` file, at half-width 3 (the paper's band of
//! 6 voxels). Rows: a mesh voxelised at increasing resolution, the spiral of van der Laan
//! et al. 2011, a sphere of radius 1000, and an unenclosed level set (a sphere clipped by a
//! plane, Fig. 9), which the H-RLE stores open while the DT-Grid and the tiles must store the
//! closed hemisphere, band along the cut included.

use crate::info::human_bytes;
use serde::Serialize;
use sparse_levelset::grid::{GridError, GridSpec};
use sparse_levelset::io::sls::{self, Source};
use sparse_levelset::storage::convert::{dtgrid_from, tiles_from_sdf, tiles_from_shape};
use sparse_levelset::storage::hrle::HrleGrid;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::TileGrid;
use sparse_levelset::tools::mesh::TriangleMesh;
use sparse_levelset::tools::voxelize::{voxelize, VoxelizeOptions};
use sparse_levelset::{Coord, LevelSet};
use std::fmt::Write as _;

/// One row: a level set and its bytes in each representation.
#[derive(Clone, Debug, Serialize)]
pub struct MemoryRow {
    /// What was stored.
    pub model: String,
    /// Voxels of the band's bounding box, `[nx, ny, nz]`.
    pub bounding_box: [u64; 3],
    /// Band voxels (|φ| < γ) of the H-RLE (for the unenclosed row: of the open set).
    pub band_voxels: usize,
    pub hrle_bytes: usize,
    pub dtgrid_bytes: usize,
    pub tiles_bytes: usize,
    pub sls_bytes: usize,
    /// H-RLE bytes / DT-Grid bytes (Table II: 1.05 to 1.07).
    pub hrle_over_dtgrid: f64,
}

/// The whole table.
#[derive(Clone, Debug, Serialize)]
pub struct MemoryTable {
    pub half_width: f32,
    pub rows: Vec<MemoryRow>,
}

fn box_of(ls: &impl LevelSet) -> [u64; 3] {
    ls.band_bounding_box()
        .map_or([0; 3], |(lo, hi)| [hi.x - lo.x, hi.y - lo.y, hi.z - lo.z].map(|d| d as u64 + 1))
}

/// The row of a level set given as tiles: its DT-Grid and H-RLE are converted from them.
pub fn row_of_tiles(model: &str, tiles: &TileGrid) -> Result<MemoryRow, GridError> {
    let mut h = HrleGrid::from_level_set(tiles)?;
    h.shrink_to_fit();
    let mut dt = dtgrid_from(tiles);
    dt.shrink_to_fit();
    Ok(row(model, &h, dt.memory().used(), tiles.memory().used()))
}

fn row(model: &str, h: &HrleGrid, dtgrid_bytes: usize, tiles_bytes: usize) -> MemoryRow {
    let hrle_bytes = h.memory().used();
    MemoryRow {
        model: model.to_string(),
        bounding_box: box_of(h),
        band_voxels: h.band_voxels(),
        hrle_bytes,
        dtgrid_bytes,
        tiles_bytes,
        sls_bytes: sls::encode(h, Source::Hrle).len(),
        hrle_over_dtgrid: hrle_bytes as f64 / dtgrid_bytes.max(1) as f64,
    }
}

/// Rows of a mesh voxelised (exact distances, [`sparse_levelset::tools::voxelize`]) so that the
/// longest side of its bounding box spans each of `sizes` voxels. `progress` is told each
/// size.
pub fn mesh_rows(
    name: &str,
    mesh: &TriangleMesh,
    sizes: &[u32],
    mut progress: impl FnMut(&str),
) -> Result<Vec<MemoryRow>, String> {
    let (lo, hi) =
        mesh.positions.iter().fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(lo, hi), p| {
            (std::array::from_fn(|i| lo[i].min(p[i])), std::array::from_fn(|i| hi[i].max(p[i])))
        });
    let side = (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max);
    let mut rows = Vec::new();
    for &n in sizes {
        progress(&format!("{name} at {n}"));
        let opts =
            VoxelizeOptions { voxel_size: Some((side / n as f64) as f32), ..Default::default() };
        let tiles = voxelize(mesh, &opts).map_err(|e| format!("{name}: {e}"))?;
        rows.push(
            row_of_tiles(&format!("{name}, {n} voxels across"), &tiles)
                .map_err(|e| e.to_string())?,
        );
    }
    Ok(rows)
}

/// The analytic rows: the spiral (van der Laan et al. 2011, radius 50, depth 40), a sphere of
/// radius `r` (1000 in the table), and that sphere clipped by the plane x = 0: open in the H-RLE,
/// closed (sphere ∩ {x ≤ 0}) in the DT-Grid and the tiles. `progress` is told each row.
pub fn analytic_rows(r: f64, mut progress: impl FnMut(&str)) -> Result<Vec<MemoryRow>, GridError> {
    let spec = GridSpec::default();
    let mut rows = Vec::new();
    progress("spiral");
    let spiral = Shape::spiral_default([0.0; 3], 50.0, 40.0);
    rows.push(row_of_tiles("spiral (radius 50, depth 40)", &tiles_from_shape(&spiral, spec)?)?);
    progress("sphere");
    let c = [0.25, 0.5, 0.75];
    let sphere = Shape::Sphere { center: c, radius: r };
    let tiles = tiles_from_shape(&sphere, spec)?;
    rows.push(row_of_tiles(&format!("sphere, radius {r}"), &tiles)?);
    progress("clipped sphere");
    let h = HrleGrid::from_level_set(&tiles)?;
    drop(tiles);
    let far = r.ceil() as i32 + 8;
    let mut open = h.clip(Coord::new(-far, -far, -far), Coord::new(0, far, far))?;
    drop(h);
    open.shrink_to_fit();
    // The closed hemisphere: max(sphere, x − 0) sampled on its band.
    let half = tiles_from_sdf(
        move |p| {
            let d =
                ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt() - r;
            d.max(p[0])
        },
        1.0,
        Coord::new(-far, -far, -far),
        Coord::new(far, far, far),
        spec,
    )?;
    let mut dt = dtgrid_from(&half);
    dt.shrink_to_fit();
    rows.push(row(
        &format!("sphere, radius {r}, clipped by x = 0 (unenclosed)"),
        &open,
        dt.memory().used(),
        half.memory().used(),
    ));
    Ok(rows)
}

impl MemoryTable {
    /// The table for people.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "memory at half-width {} (bytes in use; the .sls file as written):",
            self.half_width
        );
        let _ = writeln!(
            s,
            "{:<48} {:>16} {:>12} {:>11} {:>11} {:>11} {:>11} {:>8}",
            "model", "bounding box", "band vox", "H-RLE", "DT-Grid", "tiles", ".sls", "H/DT"
        );
        for r in &self.rows {
            let b = r.bounding_box;
            let _ = writeln!(
                s,
                "{:<48} {:>16} {:>12} {:>11} {:>11} {:>11} {:>11} {:>8.3}",
                r.model,
                format!("{}x{}x{}", b[0], b[1], b[2]),
                r.band_voxels,
                human_bytes(r.hrle_bytes),
                human_bytes(r.dtgrid_bytes),
                human_bytes(r.tiles_bytes),
                human_bytes(r.sls_bytes),
                r.hrle_over_dtgrid
            );
        }
        s
    }
}
