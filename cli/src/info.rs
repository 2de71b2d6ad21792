//! The `levelset info` report: the three grids (DT-Grid, tiles, H-RLE) built from one
//! input, with their voxel counts and bytes by part, and the size of its `.sls` file.

use serde::Serialize;
use sparse_levelset::grid::{GridError, GridSpec, MemoryReport};
use sparse_levelset::storage::convert::{
    dtgrid_from, dtgrid_from_dense, tiles_from, tiles_from_dense, tiles_from_shape,
};
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::dtgrid::DtGrid;
use sparse_levelset::storage::hrle::HrleGrid;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::TileGrid;
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
    /// `"dtgrid"`, `"tiles"` or `"hrle"`.
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
    /// Total bytes / value bytes (the measure of Nielsen & Museth 2006, Fig. 7).
    pub total_over_values: f64,
    /// Wall time to build the grid from the input.
    pub build_seconds: f64,
}

/// The header of a `.sls` input.
#[derive(Clone, Debug, Serialize)]
pub struct SlsFileInfo {
    pub version: u32,
    /// The grid it was written from.
    pub written_from: String,
    /// Runs of the z, y and x blocks.
    pub runs: [u64; 3],
    pub origin: [f64; 3],
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
    /// Tile bytes / DT-Grid bytes (van der Laan et al. 2011, Sec. 5.3: about 2.5 at 4³).
    pub tiles_over_dtgrid_bytes: f64,
    /// H-RLE bytes / DT-Grid bytes (Houston et al. 2006, Table II: 1.05–1.07).
    pub hrle_over_dtgrid_bytes: f64,
    /// Bytes of the level set as a `.sls` file.
    pub sls_bytes: usize,
    /// The domain of an unenclosed (clipped) level set, `[lo, hi]` as `[x, y, z]`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub domain: Option<[[i32; 3]; 2]>,
    /// What the `.sls` file's header says (`.sls` input).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sls_file: Option<SlsFileInfo>,
    /// Augmented fields (`.sls` input).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub fields: Vec<String>,
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

/// The H-RLE line and the `.sls` size of a level set.
fn hrle_info<G: LevelSet>(g: &G) -> Result<(HrleGrid, GridInfo, usize), GridError> {
    let t0 = Instant::now();
    let mut h = match sparse_levelset::storage::hrle::HrleGrid::of(g) {
        Some(h) => h.clone(),
        None => HrleGrid::from_level_set(g)?,
    };
    h.shrink_to_fit();
    let info = grid_info("hrle", &h, 0, t0.elapsed().as_secs_f64());
    let bytes = sparse_levelset::io::sls::encode(&h, sparse_levelset::io::sls::Source::Hrle).len();
    Ok((h, info, bytes))
}

struct Parts<'a> {
    source: String,
    shape: Option<Shape>,
    dense_dims: Option<[usize; 3]>,
    spec: GridSpec,
    grids: [GridInfo; 3],
    hrle: HrleGrid,
    sls_bytes: usize,
    header: Option<&'a sparse_levelset::io::sls::Header>,
    warnings: Vec<String>,
}

fn assemble(p: Parts) -> InfoReport {
    let [dt, tiles, h] = p.grids;
    let over = |a: &GridInfo| {
        if dt.bytes.total > 0 {
            a.bytes.total as f64 / dt.bytes.total as f64
        } else {
            0.0
        }
    };
    InfoReport {
        source: p.source,
        shape: p.shape,
        dense_dims: p.dense_dims,
        voxel_size: p.spec.voxel_size,
        half_width: p.spec.half_width,
        gamma: p.spec.gamma(),
        tiles_over_dtgrid_bytes: over(&tiles),
        hrle_over_dtgrid_bytes: over(&h),
        sls_bytes: p.sls_bytes,
        domain: p.hrle.domain().map(|(lo, hi)| [[lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]]),
        fields: p.hrle.fields().iter().map(|f| f.name.clone()).collect(),
        sls_file: p.header.map(|h| SlsFileInfo {
            version: h.version,
            written_from: format!("{:?}", h.source).to_lowercase(),
            runs: h.runs,
            origin: h.spec.origin,
        }),
        grids: vec![dt, tiles, h],
        warnings: p.warnings,
    }
}

/// Reports a sparse level set read from a `.sls` file (with its `header`) or a `.vdb` file
/// (`None`): its H-RLE encoding and the tile list and DT-Grid it converts into.
pub fn info_from_sparse(
    name: &str,
    grid: &HrleGrid,
    header: Option<&sparse_levelset::io::sls::Header>,
) -> Result<InfoReport, GridError> {
    let t0 = Instant::now();
    let mut tiles = tiles_from(grid);
    tiles.shrink_to_fit();
    let t_tiles = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let mut dt = dtgrid_from(grid);
    dt.shrink_to_fit();
    let t_dt = t1.elapsed().as_secs_f64();
    let (hrle, h, sls_bytes) = hrle_info(grid)?;
    let mut warnings = Vec::new();
    if grid.domain().is_some() {
        warnings.push(
            "the level set is unenclosed (clipped to its domain): the tiles and the DT-Grid \
             hold its band but read their own signs beyond it"
                .into(),
        );
    }
    Ok(assemble(Parts {
        source: name.to_string(),
        shape: None,
        dense_dims: None,
        spec: grid.spec(),
        grids: [
            grid_info("dtgrid", &dt, 0, t_dt),
            grid_info("tiles", &tiles, tiles.len(), t_tiles),
            h,
        ],
        hrle,
        sls_bytes,
        header,
        warnings,
    }))
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
    let built = Built { tiles: &tiles, t_tiles, dt: &dt, t_dt };
    built.report(name, Some(shape.clone()), None, spec, warnings)
}

/// The tiles and DT-Grid built from a shape or a dense field, with their build times.
struct Built<'a> {
    tiles: &'a TileGrid,
    t_tiles: f64,
    dt: &'a DtGrid,
    t_dt: f64,
}

impl Built<'_> {
    /// The report of both grids and of the H-RLE converted from the tiles.
    fn report(
        &self,
        source: &str,
        shape: Option<Shape>,
        dense_dims: Option<[usize; 3]>,
        spec: GridSpec,
        warnings: Vec<String>,
    ) -> Result<InfoReport, GridError> {
        let (hrle, h, sls_bytes) = hrle_info(self.tiles)?;
        Ok(assemble(Parts {
            source: source.to_string(),
            shape,
            dense_dims,
            spec,
            grids: [
                grid_info("dtgrid", self.dt, 0, self.t_dt),
                grid_info("tiles", self.tiles, self.tiles.len(), self.t_tiles),
                h,
            ],
            hrle,
            sls_bytes,
            header: None,
            warnings,
        }))
    }
}

/// Builds both grids of a dense field and reports them. The field is expected to have
/// passed the library's checks ([`sparse_levelset::io::input::check_field`]: an interface, a
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
    let built = Built { tiles: &tiles, t_tiles, dt: &dt, t_dt };
    built.report(source, None, Some(field.dims()), spec, warnings)
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
        let _ = writeln!(
            s,
            "tiles / dtgrid bytes = {:.2}   hrle / dtgrid bytes = {:.3}   .sls file: {}",
            self.tiles_over_dtgrid_bytes,
            self.hrle_over_dtgrid_bytes,
            human_bytes(self.sls_bytes)
        );
        if let Some(f) = &self.sls_file {
            let _ = writeln!(
                s,
                ".sls version {}, written from {}, origin {:?}, runs (z, y, x) {:?}, checksum verified",
                f.version, f.written_from, f.origin, f.runs
            );
        }
        if let Some([lo, hi]) = self.domain {
            let _ = writeln!(s, "domain (unenclosed level set): {lo:?} .. {hi:?}");
        }
        if !self.fields.is_empty() {
            let _ = writeln!(s, "fields: {}", self.fields.join(", "));
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        s
    }
}
