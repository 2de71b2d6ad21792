//! Fast marching on the sparse grids: signed distances, band reinitialisation and
//! widening, and arrival times — after Bærentzen, *On the Implementation of Fast Marching
//! Methods for 3D Lattices* (Bærentzen 2001).
//!
//! * **The method** (Sec. 2.1, Fig. 3): voxels are *far*, *narrow band* (trial) or
//!   *frozen*; the trial voxel with the smallest arrival time is frozen next and its
//!   neighbours are recomputed. The trial set lives in a binary min-heap with a position
//!   index, so a key can change without searching (Sec. 2.1.1).
//! * **The update**: first order (Sec. 3, eq. (3)–(5)) or the second-order "high
//!   accuracy" variant (Sec. 4, eq. (7)–(10), Appendix A), which falls back to first
//!   order per direction where the voxel two steps away is not frozen or not smaller.
//!   Only frozen values enter an update (Sec. 3). The quadratic is solved robustly (see
//!   `solve_terms`): a direction is dropped when the discriminant is negative.
//! * **Sparse storage**: the march reads any [`LevelSet`] through the one read
//!   interface — its band voxels in [`Coord`] order and the six neighbours of each
//!   through one cached [`crate::storage::levelset::Accessor`] — and a dense field by index
//!   arithmetic, and writes into a hash of 4³ blocks that holds only the
//!   voxels it touches (the band and one layer of trial voxels): nothing spans the
//!   bounding box. Distances march in voxel units and are scaled by the voxel size at
//!   the end.
//! * **Interface initialisation**: the frozen set is every voxel with a 6-neighbour of
//!   the other sign (Sec. 4, the ellipsoid experiment), on both sides. The paper gives
//!   these voxels exact foot-point distances; from a sampled field they get `|φ|/|∇φ|`
//!   (central differences; one-sided next to a clamped ±γ value), capped by the linearly
//!   interpolated zero crossings on the voxel's edges. Inside and outside march
//!   separately (arrival time `−φ` inside, `φ` outside), so signs are preserved.
//! * **Dense arrays** ([`dense_distance`], [`dense_travel_time`],
//!   [`dense_extension_velocities`]): the same march on a bounded box with per-axis
//!   spacing, periodic axes, obstacles, a speed per voxel and an extended field — the
//!   functions of scikit-fmm.
//! * **Determinism**: the march is sequential and heap ties are broken by coordinate,
//!   so the result does not depend on the thread count, on insertion order or on the
//!   input grid type: tiles and DT-Grid give the same values bit for bit.
//!
//! ```
//! use sparse_levelset::{storage::convert, tools::fmm, grid::GridSpec, storage::shapes::Shape, Coord};
//!
//! // A sphere whose band holds 3·φ (not a distance), then reinitialised.
//! let spec = GridSpec::default();
//! let sphere = Shape::Sphere { center: [0.5; 3], radius: 12.0 };
//! let tiles = convert::tiles_from_sdf(
//!     |p| 3.0 * sphere.sdf(p), 3.0, Coord::new(-20, -20, -20), Coord::new(20, 20, 20), spec,
//! )
//! .unwrap();
//! let opts = fmm::FmmOptions { order: fmm::Order::Second, half_width: Some(4.0), ..Default::default() };
//! let out = fmm::reinitialize(&tiles, &opts).unwrap();
//! let c = Coord::new(15, 0, 0); // 2.5 voxels from the surface
//! assert!((out.value(c) - sphere.sdf(spec.world(c)) as f32).abs() < 0.02);
//! assert_eq!(out.spec().half_width, 4.0);
//! ```

mod dense;
mod flat;
mod heap;
mod march;
mod source;
mod store;

#[cfg(test)]
mod tests;

pub use dense::{
    dense_band, dense_distance, dense_extension_velocities, dense_travel_time, DenseExtension,
    DenseGrid, DenseOptions, MIN_SPEED,
};
pub use flat::DenseMarch;

use crate::coord::Coord;
use crate::grid::{GridError, GridSpec};
use crate::progress::{Cancelled, Progress};
use crate::storage::dense::DenseField;
use crate::storage::levelset::LevelSet;
use crate::storage::tiles::{voxel_of, Tile, TileGrid, TILE_LEN};
use march::{Cost, Marcher, UnitCost};
use source::{freeze_interface, DenseSource, GridSource, Source};
use store::{FROZEN, INSIDE, TRIAL};

/// Accuracy of the update.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Order {
    /// First-order one-sided differences (Sec. 3).
    First,
    /// Second-order one-sided differences where the voxel two steps away is frozen,
    /// first order elsewhere (Sec. 4, the "high accuracy" FMM). The default.
    #[default]
    Second,
}

/// Options of the distance computations.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct FmmOptions {
    /// First- or second-order update.
    pub order: Order,
    /// Band half-width W of the result in voxels (finite, > 1): voxels up to distance W
    /// are marched, values beyond read ±W·voxel. `None` keeps the input grid's
    /// half-width (3 for a dense field).
    pub half_width: Option<f32>,
    /// Progress (the marched distance as a share of the half-width) and cancellation.
    pub progress: Progress,
}

/// Errors of the fast-marching functions.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FmmError {
    /// A NaN input value (±∞ is a far-away distance), or a non-finite seed distance.
    #[error("value at voxel {coord} is {value}: a level set needs a number there")]
    NonFinite { coord: Coord, value: f32 },
    /// The input has no voxel with a 6-neighbour of the other sign: nothing to measure
    /// distances from.
    #[error(
        "the level set is empty: no voxel has a neighbour of the other sign (no zero crossing)"
    )]
    NoInterface,
    /// A seed set without seeds.
    #[error("no seed voxels were given")]
    NoSeeds,
    /// The speed closure returned F ≤ 0 or a non-finite value.
    #[error("speed F = {speed} at voxel {coord}: the speed must be finite and > 0")]
    BadSpeed { coord: Coord, speed: f64 },
    /// A parameter outside its domain.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// Grid construction failed (coordinates beyond the tile range, memory).
    #[error(transparent)]
    Grid(#[from] GridError),
    /// Cancelled through [`FmmOptions::progress`]; nothing was changed.
    #[error("fast marching was cancelled")]
    Cancelled(#[from] Cancelled),
}

impl crate::error::Error for FmmError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            FmmError::NonFinite { .. } | FmmError::NoInterface => InvalidData,
            FmmError::NoSeeds | FmmError::BadSpeed { .. } | FmmError::InvalidParameter(_) => {
                InvalidInput
            }
            FmmError::Grid(e) => e.kind(),
            FmmError::Cancelled(_) => Cancelled,
        }
    }
}

/// The output spec: the input's with the requested half-width.
fn output_spec(spec: GridSpec, opts: &FmmOptions) -> Result<GridSpec, FmmError> {
    let w = opts.half_width.unwrap_or(spec.half_width);
    Ok(GridSpec::new(spec.voxel_size, spec.origin, w)?)
}

/// Marches the distance band of `src` to half-width `w` voxels.
fn march_distance<S: Source + ?Sized>(
    src: &S,
    opts: &FmmOptions,
    w: f32,
) -> Result<Marcher<UnitCost>, FmmError> {
    let mut m = Marcher::new(opts.order == Order::Second, src.domain(), UnitCost);
    if freeze_interface(src, &mut m)? == 0 {
        return Err(FmmError::NoInterface);
    }
    m.run(w as f64, &opts.progress)?;
    Ok(m)
}

/// The tiles of the marched band, sorted by coordinate: frozen voxels carry their
/// distance (scaled by the voxel size, clamped to ±γ), trial voxels ±γ by their side,
/// unvisited voxels ±γ by `inside`. Only tiles holding a band voxel (|φ| < γ) are kept.
fn band_tiles<C: Cost>(
    m: &Marcher<C>,
    spec: &GridSpec,
    inside: impl Fn(Coord) -> bool,
) -> Vec<(Coord, Tile)> {
    let g = spec.gamma();
    let h = spec.voxel_size as f64;
    let mut out = Vec::new();
    for (t, b) in m.store.sorted_blocks() {
        let mut tile = Tile::splat(0.0);
        let mut band = false;
        for (l, v) in tile.0.iter_mut().enumerate() {
            let id = b * TILE_LEN as u32 + l as u32;
            let s = m.store.vox[id as usize].state;
            *v = match s & 3 {
                FROZEN => ((m.store.vox[id as usize].value * h) as f32).clamp(-g, g),
                TRIAL => spec.background(s & INSIDE != 0),
                _ => spec.background(inside(voxel_of(t, l))),
            };
            band |= v.abs() < g;
        }
        if band {
            out.push((t, tile));
        }
    }
    out
}

fn to_tiles(
    tiles: Vec<(Coord, Tile)>,
    spec: GridSpec,
    inside: impl Fn(Coord) -> bool,
) -> Result<TileGrid, FmmError> {
    Ok(TileGrid::from_sorted_tiles(spec, tiles, |t| inside(voxel_of(t, 0)))?)
}

/// Reinitialises the band of any level set to a signed distance, or widens/narrows it:
/// the interface voxels are frozen with their estimated distances, then inside and
/// outside are marched up to the half-width of `opts` (default: the input's), and a fresh
/// tile grid is built from the marched band (border and activity flags computed as in
/// [`crate::storage::convert`]). Unvisited voxels take the input's sign. Every storage holding the
/// same band gives the same values bit for bit; [`crate::storage::convert::dtgrid_from`] turns the
/// result into a DT-Grid.
///
/// Errors: [`FmmError::NoInterface`] for a level set without a sign change; an invalid
/// half-width; [`GridError::OutOfRange`] when the band would leave the tile range;
/// [`FmmError::Cancelled`].
pub fn reinitialize<G: LevelSet + ?Sized>(
    grid: &G,
    opts: &FmmOptions,
) -> Result<TileGrid, FmmError> {
    let spec = output_spec(grid.spec(), opts)?;
    let src = GridSource(grid);
    let m = march_distance(&src, opts, spec.half_width)?;
    let inside = |c: Coord| src.inside(c);
    to_tiles(band_tiles(&m, &spec, inside), spec, inside)
}

/// The signed distance to the zero level set of a dense field, like scikit-fmm's
/// `distance`, within a band: φ < 0 inside, world units (`voxel_size` per voxel), exact
/// marched values up to `W·voxel_size` from the interface and `±W·voxel_size` beyond
/// (W = `opts.half_width`, default 3). The march stays inside the array. Works through
/// the same sparse march as the grids (memory proportional to the band, plus the
/// output array).
///
/// ±∞ is a far-away distance (the rule of [`crate::io::input`]): its sign counts, and a
/// crossing next to it lies at its finite neighbour.
///
/// Errors: NaN in the input, no zero crossing, a voxel size or half-width that is not
/// finite and positive (half-width > 1).
pub fn distance_dense(
    field: &DenseField,
    voxel_size: f32,
    opts: &FmmOptions,
) -> Result<DenseField, FmmError> {
    let spec = GridSpec::new(voxel_size, [0.0; 3], opts.half_width.unwrap_or(3.0))?;
    if let Some(i) = crate::storage::dense::first_position(field.data(), |v| v.is_nan()) {
        let coord = field.coord_of(i).expect("index in range");
        return Err(FmmError::NonFinite { coord, value: field.data()[i] });
    }
    let src = DenseSource { field };
    let m = march_distance(&src, opts, spec.half_width)?;
    let g = spec.gamma();
    let h = voxel_size as f64;
    let mut out = field.clone();
    for v in out.data_mut() {
        *v = spec.background(*v < 0.0);
    }
    for (t, b) in m.store.sorted_blocks() {
        for l in 0..TILE_LEN {
            let id = (b * TILE_LEN as u32 + l as u32) as usize;
            if m.store.vox[id].state & 3 == FROZEN {
                let c = voxel_of(t, l);
                let v = ((m.store.vox[id].value * h) as f32).clamp(-g, g);
                out.set(c, v)?;
            }
        }
    }
    Ok(out)
}

/// A band built by marching from given interface values: `frozen` holds the voxels
/// next to the interface with their signed distances (world units; φ < 0 inside), e.g.
/// exact foot-point distances as in the paper's ellipsoid experiment (Sec. 4, Table 1).
/// The march fills the band of `spec` (half-width W) on both sides; `inside` gives the
/// sign of voxels the march does not reach. The frozen set must hold both voxels of
/// every edge along which the sign changes.
pub fn tiles_from_interface(
    spec: GridSpec,
    frozen: &[(Coord, f32)],
    order: Order,
    inside: impl Fn(Coord) -> bool,
) -> Result<TileGrid, FmmError> {
    let mut m = Marcher::new(order == Order::Second, None, UnitCost);
    let h = spec.voxel_size as f64;
    for &(c, v) in frozen {
        if !v.is_finite() {
            return Err(FmmError::NonFinite { coord: c, value: v });
        }
        m.freeze_initial(c, v as f64 / h, v < 0.0)?;
    }
    if m.initial_len() == 0 {
        return Err(FmmError::NoInterface);
    }
    m.run(spec.half_width as f64, &Progress::none())?;
    to_tiles(band_tiles(&m, &spec, &inside), spec, &inside)
}

/// Arrival times of a front that starts at `seeds` (voxel, start time) and moves with
/// speed `F(x) > 0` (world units per time unit; `x` the voxel centre in world space),
/// up to `max_time`: the solution of `|∇T| F = 1` (eq. (1)). Returned sparse, sorted by
/// coordinate: the voxels reached by `max_time`.
pub struct ArrivalTimes {
    coords: Vec<Coord>,
    times: Vec<f64>,
}

impl ArrivalTimes {
    /// Voxels reached.
    pub fn len(&self) -> usize {
        self.coords.len()
    }

    pub fn is_empty(&self) -> bool {
        self.coords.is_empty()
    }

    /// Arrival time at `c`, `None` when the front does not reach it by `max_time`.
    pub fn time(&self, c: Coord) -> Option<f64> {
        self.coords.binary_search(&c).ok().map(|i| self.times[i])
    }

    /// `(voxel, time)` in [`Coord`] order.
    pub fn iter(&self) -> impl Iterator<Item = (Coord, f64)> + '_ {
        self.coords.iter().copied().zip(self.times.iter().copied())
    }
}

struct SpeedCost<F> {
    speed: F,
    spec: GridSpec,
}

impl<F: Fn([f64; 3]) -> f64> Cost for SpeedCost<F> {
    #[inline]
    fn cost(&self, c: Coord) -> Result<f64, FmmError> {
        let f = (self.speed)(self.spec.world(c));
        if !(f.is_finite() && f > 0.0) {
            return Err(FmmError::BadSpeed { coord: c, speed: f });
        }
        Ok(self.spec.voxel_size as f64 / f)
    }
}

/// Computes [`ArrivalTimes`] from `seeds` with speed `speed(x)` until `max_time`
/// (`spec` places the voxels in world space; its half-width is not used). A voxel that
/// appears more than once in `seeds` starts at the smallest of its times.
///
/// Errors: no seeds, a non-finite seed time, `max_time` not finite, F ≤ 0 or not finite
/// at a voxel the march reaches ([`FmmError::BadSpeed`]), a march that would exceed the
/// available memory.
pub fn arrival_times<F: Fn([f64; 3]) -> f64>(
    spec: &GridSpec,
    seeds: &[(Coord, f64)],
    speed: F,
    max_time: f64,
    order: Order,
) -> Result<ArrivalTimes, FmmError> {
    if seeds.is_empty() {
        return Err(FmmError::NoSeeds);
    }
    if !max_time.is_finite() {
        return Err(FmmError::InvalidParameter(format!("max_time must be finite, got {max_time}")));
    }
    let cost = SpeedCost { speed, spec: *spec };
    for &(c, t) in seeds {
        if !t.is_finite() {
            return Err(FmmError::InvalidParameter(format!("seed {c} has time {t}")));
        }
        cost.cost(c)?;
    }
    // A voxel seeded twice keeps its smallest time, whatever the order of `seeds`.
    let mut sorted = seeds.to_vec();
    sorted.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    sorted.dedup_by_key(|s| s.0);
    let mut m = Marcher::new(order == Order::Second, None, cost);
    for &(c, t) in &sorted {
        m.freeze_initial(c, t, false)?;
    }
    m.run(max_time, &Progress::none())?;
    let mut coords = Vec::new();
    let mut times = Vec::new();
    for (t, b) in m.store.sorted_blocks() {
        for l in 0..TILE_LEN {
            let id = (b * TILE_LEN as u32 + l as u32) as usize;
            if m.store.vox[id].state & 3 == FROZEN && m.store.vox[id].value <= max_time {
                coords.push(voxel_of(t, l));
                times.push(m.store.vox[id].value);
            }
        }
    }
    // Blocks are sorted, voxels within a block are not in global order.
    let mut idx: Vec<usize> = (0..coords.len()).collect();
    idx.sort_unstable_by_key(|&i| coords[i]);
    Ok(ArrivalTimes {
        coords: idx.iter().map(|&i| coords[i]).collect(),
        times: idx.iter().map(|&i| times[i]).collect(),
    })
}
