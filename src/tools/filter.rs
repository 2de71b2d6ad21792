//! Filters of a level set, as OpenVDB's `LevelSetFilter` and `vdb_tool` apply them to any
//! narrow band: offsets (dilation and erosion), morphological opening and closing, motion by
//! mean curvature for a time, Gaussian, mean and median filters of the band's values, and
//! renormalisation. Each result is a signed distance on the input's grid (same voxel size,
//! origin and half-width), as a Sorted Tile List.
//!
//! * **Offsets** are exact up to fast marching's error: the level set is reinitialised by
//!   second-order fast marching ([`crate::tools::fmm::reinitialize`]) to a band wider than
//!   the offset, and the new band is sampled from `φ − d` (so a sphere of radius r becomes
//!   one of radius r + d). Opening is an erosion then a dilation by the same distance (it
//!   rounds convex edges by that radius); closing a dilation then an erosion (it fills
//!   concave creases and gaps narrower than twice the radius).
//! * **Mean-curvature motion** runs the tile engine (first-order upwind, the coupled
//!   renormalisation) with speed −H, H = (κ₁ + κ₂)/2 the mean curvature, for the given time:
//!   a sphere's radius follows r² = r₀² − 2t.
//! * **Gaussian, mean and median** replace each voxel's value near the band by the weighted
//!   mean, mean or median of its (2w + 1)³ neighbourhood (the Gaussian with σ = w / 2, the
//!   band's ±γ beyond it), then reinitialise: they smooth the surface, as OpenVDB's do.
//!
//! ```
//! use sparse_levelset::storage::{convert, shapes::Shape};
//! use sparse_levelset::tools::filter::{filter, Filter};
//! use sparse_levelset::{Coord, GridSpec, LevelSet};
//!
//! let sphere = Shape::Sphere { center: [0.0; 3], radius: 10.0 };
//! let tiles = convert::tiles_from_shape(&sphere, GridSpec::default()).unwrap();
//! let grown = filter(&tiles, &[Filter::Offset(2.5)]).unwrap();
//! // The surface moved out by 2.5: the voxel at x = 12 is 0.5 inside.
//! assert!((grown.value(Coord::new(12, 0, 0)) + 0.5).abs() < 0.05);
//! ```

use crate::coord::Coord;
use crate::evolve::{EvolveError, Flow, GridKind, Lanes, Settings, Simulation};
use crate::grid::{GridError, GridSpec};
use crate::storage::levelset::LevelSet;
use crate::storage::sample::sample_band_tiles;
use crate::storage::tiles::{voxel_of, Tile, TileGrid};
use crate::tools::fmm::{self, FmmError, FmmOptions, Order};

/// One filter; [`filter`] applies a list of them in order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    /// Move the surface outwards by a distance in world units (inwards when negative).
    Offset(f64),
    /// Outwards by a distance (world units, ≥ 0): `Offset(d)`.
    Dilate(f64),
    /// Inwards by a distance (world units, ≥ 0): `Offset(−d)`.
    Erode(f64),
    /// Erode, then dilate by the same distance (world units).
    Open(f64),
    /// Dilate, then erode by the same distance (world units).
    Close(f64),
    /// Motion by mean curvature for a time (world units²).
    MeanCurvature(f64),
    /// Gaussian filter of half-width `w` voxels (σ = w / 2).
    Gaussian(u32),
    /// Mean over the (2w + 1)³ neighbourhood.
    Mean(u32),
    /// Median over the (2w + 1)³ neighbourhood.
    Median(u32),
    /// Reinitialisation to a signed distance (second-order fast marching).
    Renormalize,
}

/// A filter as written on a command line, `NAME[:VALUE]` (vdb_tool's names): `offset:D`,
/// `dilate:D`, `erode:D`, `open:R`, `close:R`, `mean-curvature:T`, `gaussian:W`, `mean:W`,
/// `median:W`, `renormalize`.
impl std::str::FromStr for Filter {
    type Err = FilterError;

    fn from_str(s: &str) -> Result<Filter, FilterError> {
        let bad = |why: String| FilterError::InvalidParameter(format!("{s}: {why}"));
        let (name, value) = s.split_once(':').map_or((s, None), |(n, v)| (n, Some(v.trim())));
        let number = || -> Result<f64, FilterError> {
            let v = value.ok_or_else(|| bad(format!("{name} takes a value, {name}:VALUE")))?;
            v.parse::<f64>().map_err(|_| bad(format!("{v:?} is not a number")))
        };
        let width = || -> Result<u32, FilterError> {
            let v = value.ok_or_else(|| bad(format!("{name} takes a width, {name}:W")))?;
            v.parse::<u32>().map_err(|_| bad(format!("{v:?} is not a whole number")))
        };
        Ok(match name.trim() {
            "offset" => Filter::Offset(number()?),
            "dilate" => Filter::Dilate(number()?),
            "erode" => Filter::Erode(number()?),
            "open" => Filter::Open(number()?),
            "close" => Filter::Close(number()?),
            "mean-curvature" => Filter::MeanCurvature(number()?),
            "gaussian" => Filter::Gaussian(width()?),
            "mean" => Filter::Mean(width()?),
            "median" => Filter::Median(width()?),
            "renormalize" if value.is_none() => Filter::Renormalize,
            _ => {
                return Err(bad("unknown filter; use offset, dilate, erode, open, close, \
                                mean-curvature, gaussian, mean, median or renormalize"
                    .into()))
            }
        })
    }
}

/// Why a filter failed.
#[derive(Debug, thiserror::Error)]
pub enum FilterError {
    /// A filter's parameter is out of range.
    #[error("invalid filter: {0}")]
    InvalidParameter(String),
    /// The level set has no interface (or lost it: an erosion or a smoothing removed it).
    #[error("the level set is empty: no interface to filter")]
    Empty,
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error(transparent)]
    Fmm(#[from] FmmError),
    #[error(transparent)]
    Evolve(#[from] EvolveError),
}

impl crate::error::Error for FilterError {
    fn kind(&self) -> crate::error::ErrorKind {
        match self {
            FilterError::InvalidParameter(_) => crate::error::ErrorKind::InvalidInput,
            FilterError::Empty => crate::error::ErrorKind::InvalidData,
            FilterError::Grid(e) => e.kind(),
            FilterError::Fmm(e) => e.kind(),
            FilterError::Evolve(e) => e.kind(),
        }
    }
}

/// Applies `filters` in order to `ls`; the parameters of all of them are checked first.
pub fn filter<L: LevelSet + ?Sized>(ls: &L, filters: &[Filter]) -> Result<TileGrid, FilterError> {
    validate(filters)?;
    if ls.band_voxels() == 0 {
        return Err(FilterError::Empty);
    }
    let mut grid = crate::storage::convert::tiles_from(ls);
    for f in filters {
        grid = match *f {
            Filter::Offset(d) => offset(&grid, d)?,
            Filter::Dilate(d) => offset(&grid, d)?,
            Filter::Erode(d) => offset(&grid, -d)?,
            Filter::Open(d) => offset(&offset(&grid, -d)?, d)?,
            Filter::Close(d) => offset(&offset(&grid, d)?, -d)?,
            Filter::MeanCurvature(t) => mean_curvature(grid, t)?,
            Filter::Gaussian(w) => neighbourhood(&grid, w, Kernel::Gaussian)?,
            Filter::Mean(w) => neighbourhood(&grid, w, Kernel::Mean)?,
            Filter::Median(w) => neighbourhood(&grid, w, Kernel::Median)?,
            Filter::Renormalize => renormalize(&grid, grid.spec().half_width)?,
        };
        if !has_interface(&grid) {
            return Err(FilterError::Empty);
        }
    }
    Ok(grid)
}

/// Whether the band holds both signs (a surface).
fn has_interface(grid: &TileGrid) -> bool {
    let (mut inside, mut outside) = (false, false);
    grid.for_each_band_voxel(&mut |_, v| {
        inside |= v < 0.0;
        outside |= v >= 0.0;
    });
    inside && outside
}

/// Checks every filter's parameters (what [`filter`] does first), so that a caller can
/// refuse a bad list before reading its input.
pub fn validate(filters: &[Filter]) -> Result<(), FilterError> {
    filters.iter().try_for_each(check)
}

fn check(f: &Filter) -> Result<(), FilterError> {
    let bad = |what: String| Err(FilterError::InvalidParameter(what));
    match *f {
        Filter::Offset(d) if !d.is_finite() => bad(format!("offset {d}: a finite distance")),
        Filter::Dilate(d) | Filter::Erode(d) | Filter::Open(d) | Filter::Close(d)
            if !(d.is_finite() && d >= 0.0) =>
        {
            bad(format!("{f:?}: a finite distance ≥ 0"))
        }
        Filter::MeanCurvature(t) if !(t.is_finite() && t >= 0.0) => {
            bad(format!("mean-curvature time {t}: finite and ≥ 0"))
        }
        Filter::Gaussian(w) | Filter::Mean(w) | Filter::Median(w) if !(1..=8).contains(&w) => {
            bad(format!("{f:?}: a half-width of 1 to 8 voxels"))
        }
        _ => Ok(()),
    }
}

/// Reinitialises `grid` to a band of `half_width` voxels.
fn renormalize(grid: &TileGrid, half_width: f32) -> Result<TileGrid, FilterError> {
    let opts =
        FmmOptions { order: Order::Second, half_width: Some(half_width), ..Default::default() };
    Ok(fmm::reinitialize(grid, &opts)?)
}

/// The band of `phi` (world units, Lipschitz ≤ 1, defined at every voxel) on `spec`, over
/// the voxel box `lo..=hi`, which holds it.
fn band_of(
    phi: impl Fn(Coord) -> f32 + Sync,
    lo: Coord,
    hi: Coord,
    spec: GridSpec,
) -> Result<TileGrid, FilterError> {
    let tiles = sample_band_tiles(&phi, 1.0, lo, hi, &spec)?;
    Ok(TileGrid::from_sorted_tiles(spec, tiles.into_iter().map(|(c, v)| (c, Tile(v))), |t| {
        phi(voxel_of(t, 0)) < 0.0
    })?)
}

/// The box of `grid`'s band grown by `by` voxels.
fn grown_box(grid: &TileGrid, by: f64) -> Result<(Coord, Coord), FilterError> {
    let (lo, hi) = grid.band_bounding_box().ok_or(FilterError::Empty)?;
    let by = by.ceil();
    let grow = |v: i32, s: f64| {
        let w = v as f64 + s * by;
        if w < i32::MIN as f64 || w > i32::MAX as f64 {
            Err(FilterError::Grid(GridError::OutOfRange { coord: Coord::new(v, v, v) }))
        } else {
            Ok(w as i32)
        }
    };
    Ok((
        Coord::new(grow(lo.x, -1.0)?, grow(lo.y, -1.0)?, grow(lo.z, -1.0)?),
        Coord::new(grow(hi.x, 1.0)?, grow(hi.y, 1.0)?, grow(hi.z, 1.0)?),
    ))
}

/// The surface moved outwards by `d` world units.
fn offset(grid: &TileGrid, d: f64) -> Result<TileGrid, FilterError> {
    if d == 0.0 {
        return Ok(grid.clone());
    }
    let spec = *grid.spec();
    let h = spec.voxel_size as f64;
    // A band wide enough that every voxel of the new band reads its true distance.
    let wide = renormalize(grid, (d.abs() / h) as f32 + spec.half_width + 2.0)?;
    let (lo, hi) = grown_box(&wide, 0.0)?;
    band_of(|c| (wide.value(c) as f64 - d) as f32, lo, hi, spec)
}

/// Motion by mean curvature (speed −H) for time `t`.
fn mean_curvature(grid: TileGrid, t: f64) -> Result<TileGrid, FilterError> {
    if t == 0.0 {
        return Ok(grid);
    }
    // Flow::mean_curvature(ε) moves with speed −ε H.
    let flow = Flow::mean_curvature(1.0);
    // The lanes give the same bits; SIMD is the faster.
    let kind = GridKind::Tiles(Lanes::Simd);
    let mut sim = Simulation::from_tile_grid(kind, grid, flow, Settings::default())?;
    sim.run_until(t, u64::MAX, |_, _| {})?;
    if sim.collapsed() {
        return Err(FilterError::Empty);
    }
    Ok(sim.tiles().expect("a tile simulation").clone())
}

#[derive(Clone, Copy)]
enum Kernel {
    Gaussian,
    Mean,
    Median,
}

/// Each voxel near the band replaced by a filter of its (2w + 1)³ neighbourhood, then a
/// reinitialisation.
fn neighbourhood(grid: &TileGrid, w: u32, kernel: Kernel) -> Result<TileGrid, FilterError> {
    let spec = *grid.spec();
    let r = w as i32;
    let sigma = w as f64 / 2.0;
    let weights: Vec<f64> = (-r..=r)
        .map(|k| match kernel {
            Kernel::Gaussian => (-(k * k) as f64 / (2.0 * sigma * sigma)).exp(),
            _ => 1.0,
        })
        .collect();
    let filtered = |c: Coord| -> f32 {
        // Only the median keeps the neighbourhood's values.
        let mut values = match kernel {
            Kernel::Median => Vec::with_capacity(((2 * r + 1) as usize).pow(3)),
            _ => Vec::new(),
        };
        let (mut sum, mut wsum) = (0.0f64, 0.0f64);
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    let v = grid.value(Coord::new(c.x + dx, c.y + dy, c.z + dz));
                    match kernel {
                        Kernel::Median => values.push(v),
                        _ => {
                            let wt = weights[(dx + r) as usize]
                                * weights[(dy + r) as usize]
                                * weights[(dz + r) as usize];
                            sum += wt * v as f64;
                            wsum += wt;
                        }
                    }
                }
            }
        }
        match kernel {
            Kernel::Median => {
                let mid = values.len() / 2;
                *values.select_nth_unstable_by(mid, f32::total_cmp).1
            }
            _ => (sum / wsum) as f32,
        }
    };
    let (lo, hi) = grown_box(grid, r as f64 + 1.0)?;
    let smoothed = band_of(filtered, lo, hi, spec)?;
    if !has_interface(&smoothed) {
        return Err(FilterError::Empty);
    }
    renormalize(&smoothed, spec.half_width)
}
