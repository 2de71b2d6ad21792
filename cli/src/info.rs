//! The `levelset info` report: both grids built from one input, with their voxel counts and
//! bytes by part.

use serde::Serialize;
use sparse_levelset::build::{dtgrid_from, dtgrid_from_dense, tiles_from_dense, tiles_from_shape};
use sparse_levelset::dense::DenseField;
use sparse_levelset::grid::{GridError, GridSpec, MemoryReport};
use sparse_levelset::shapes::Shape;
use sparse_levelset::LevelSet;
use std::fmt::Write as _;
use std::time::Instant;

/// Bytes of one grid by part, with the total.
#[derive(Clone, Debug, Serialize)]
pub struct Bytes {
    pub values: usize,
    pub indices: usize,
    pub flags: usize,
    pub slack: usize,
    pub total: usize,
}

impl From<MemoryReport> for Bytes {
    fn from(m: MemoryReport) -> Self {
        Bytes {
            values: m.values,
            indices: m.indices,
            flags: m.flags,
            slack: m.slack,
            total: m.total(),
        }
    }
}

/// One grid's line of the report.
#[derive(Clone, Debug, Serialize)]
pub struct GridInfo {
    /// `"dtgrid"` or `"tiles"`.
    pub grid: &'static str,
    /// Stored voxels with |φ| < γ.
    pub band_voxels: usize,
    /// Stored voxels, tile padding included.
    pub stored_voxels: usize,
    /// Tiles in the list (0 for the DT-Grid, which has none).
    pub tiles: usize,
    pub bytes: Bytes,
    /// Total bytes / band voxels.
    pub bytes_per_band_voxel: f64,
    /// Total bytes / value bytes (the DT-Grid paper's Fig. 7 measure).
    pub total_over_values: f64,
    /// Wall time to build the grid from the input.
    pub build_seconds: f64,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct InfoReport {
    /// What the grids were built from, e.g. `sphere` or the `.npy` path.
    pub source: String,
    /// The shape and its parameters, when built from a shape.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shape: Option<Shape>,
    /// Dimensions `[nx, ny, nz]` of the dense input, when built from a field.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dense_dims: Option<[usize; 3]>,
    pub voxel_size: f32,
    pub half_width: f32,
    pub gamma: f32,
    pub grids: Vec<GridInfo>,
    /// Tile bytes / DT-Grid bytes (the tile paper measured about 2.5 at 4³, Sec. 5.3).
    pub tiles_over_dtgrid_bytes: f64,
    /// Things the user should know about the input.
    pub warnings: Vec<String>,
}

fn grid_info<G: LevelSet>(name: &'static str, g: &G, tiles: usize, secs: f64) -> GridInfo {
    let m = g.memory();
    let band = g.band_voxels();
    GridInfo {
        grid: name,
        band_voxels: band,
        stored_voxels: g.memory().values / 4,
        tiles,
        bytes: m.into(),
        bytes_per_band_voxel: if band > 0 { m.total() as f64 / band as f64 } else { 0.0 },
        total_over_values: if m.values > 0 { m.total() as f64 / m.values as f64 } else { 0.0 },
        build_seconds: secs,
    }
}

fn assemble(
    source: String,
    shape: Option<Shape>,
    dense_dims: Option<[usize; 3]>,
    spec: GridSpec,
    dt: GridInfo,
    tiles: GridInfo,
    warnings: Vec<String>,
) -> InfoReport {
    let ratio =
        if dt.bytes.total > 0 { tiles.bytes.total as f64 / dt.bytes.total as f64 } else { 0.0 };
    InfoReport {
        source,
        shape,
        dense_dims,
        voxel_size: spec.voxel_size,
        half_width: spec.half_width,
        gamma: spec.gamma(),
        grids: vec![dt, tiles],
        tiles_over_dtgrid_bytes: ratio,
        warnings,
    }
}

/// Builds both grids of a shape and reports them.
pub fn info_from_shape(name: &str, shape: &Shape, spec: GridSpec) -> Result<InfoReport, GridError> {
    let t0 = Instant::now();
    let mut tiles = tiles_from_shape(shape, spec)?;
    tiles.shrink_to_fit();
    let t_tiles = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let mut dt = dtgrid_from(&tiles);
    dt.shrink_to_fit();
    // The DT-Grid is built from the tiles' samples: charge it the sampling time too.
    let t_dt = t1.elapsed().as_secs_f64() + t_tiles;
    let mut warnings = Vec::new();
    if tiles.is_empty() {
        warnings.push("the shape has no voxel within the band: both grids are empty".into());
    }
    Ok(assemble(
        name.to_string(),
        Some(shape.clone()),
        None,
        spec,
        grid_info("dtgrid", &dt, 0, t_dt),
        grid_info("tiles", &tiles, tiles.len(), t_tiles),
        warnings,
    ))
}

/// Builds both grids of a dense field and reports them. The field is expected to have
/// passed the library's checks ([`sparse_levelset::input::check_field`]: an interface, a
/// distance field at this half-width).
pub fn info_from_dense(
    source: &str,
    field: &DenseField,
    spec: GridSpec,
) -> Result<InfoReport, GridError> {
    let g = spec.gamma();
    let t0 = Instant::now();
    let mut tiles = tiles_from_dense(field, spec)?;
    tiles.shrink_to_fit();
    let t_tiles = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let mut dt = dtgrid_from_dense(field, spec)?;
    dt.shrink_to_fit();
    let t_dt = t1.elapsed().as_secs_f64();
    let mut warnings = Vec::new();
    if field.boundary_touches(g) {
        warnings.push(
            "the band or the interior touches the array boundary; voxels beyond the array are \
             read as outside (+γ), which closes the surface there"
                .into(),
        );
    }
    if tiles.is_empty() {
        warnings.push(format!("no voxel has |φ| < γ = {g}: both grids are empty"));
    }
    Ok(assemble(
        source.to_string(),
        None,
        Some(field.dims()),
        spec,
        grid_info("dtgrid", &dt, 0, t_dt),
        grid_info("tiles", &tiles, tiles.len(), t_tiles),
        warnings,
    ))
}

/// Bytes for people: B, KiB, MiB or GiB.
pub fn human_bytes(bytes: usize) -> String {
    let b = bytes as f64;
    if b >= 1024.0 * 1024.0 * 1024.0 {
        format!("{:.2} GiB", b / (1024.0 * 1024.0 * 1024.0))
    } else if b >= 1024.0 * 1024.0 {
        format!("{:.2} MiB", b / (1024.0 * 1024.0))
    } else if b >= 1024.0 {
        format!("{:.1} KiB", b / 1024.0)
    } else {
        format!("{bytes} B")
    }
}

impl InfoReport {
    /// The report as a table for people.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "source: {}   voxel size {}   half-width {} voxels (γ = {})",
            self.source, self.voxel_size, self.half_width, self.gamma
        );
        if let Some(d) = self.dense_dims {
            let _ = writeln!(s, "dense input: {} x {} x {} (nx, ny, nz)", d[0], d[1], d[2]);
        }
        let _ = writeln!(
            s,
            "{:<7} {:>12} {:>12} {:>9} {:>11} {:>11} {:>10} {:>10} {:>11} {:>9} {:>8}",
            "grid",
            "band vox",
            "stored vox",
            "tiles",
            "values",
            "indices",
            "flags",
            "slack",
            "total",
            "B/band",
            "build s"
        );
        for g in &self.grids {
            let _ = writeln!(
                s,
                "{:<7} {:>12} {:>12} {:>9} {:>11} {:>11} {:>10} {:>10} {:>11} {:>9.2} {:>8.3}",
                g.grid,
                g.band_voxels,
                g.stored_voxels,
                g.tiles,
                human_bytes(g.bytes.values),
                human_bytes(g.bytes.indices),
                human_bytes(g.bytes.flags),
                human_bytes(g.bytes.slack),
                human_bytes(g.bytes.total),
                g.bytes_per_band_voxel,
                g.build_seconds
            );
        }
        for g in &self.grids {
            let _ = writeln!(s, "{}: total / values = {:.3}", g.grid, g.total_over_values);
        }
        let _ = writeln!(s, "tiles / dtgrid bytes = {:.2}", self.tiles_over_dtgrid_bytes);
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        s
    }
}
