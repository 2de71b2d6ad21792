//! Fast marching on dense arrays with per-axis spacing, periodic axes and obstacles:
//! signed distances, travel times and extension velocities (scikit-fmm's `distance`,
//! `travel_time` and `extension_velocities`).
//!
//! The march is the one of the sparse grids (see [`super`]), on a bounded box:
//!
//! * **Spacing per axis.** The one-sided differences of Bærentzen, *On the Implementation
//!   of Fast Marching Methods for 3D Lattices*, Technical Report IMM-REP-2001-13 (2001),
//!   Sec. 3, eq. (3)–(5), and of the high-accuracy variant, Sec. 4, eq. (7)–(10), are
//!   divided by the spacing `hₐ` of their axis, so each axis's term of the quadratic
//!   carries the factor `1/hₐ²`. Lengths are measured in units of the smallest spacing
//!   `h₀`: the factor is `(h₀/hₐ)²`, exactly 1 on an isotropic grid, whose results are
//!   bit for bit those of [`super::distance_dense`].
//! * **Periodic axes.** The neighbour of the last voxel of a periodic axis is its first
//!   voxel (and the second-order difference reads two voxels across the face).
//! * **Obstacles** (`mask`, and for travel times the voxels of speed 0): never frozen,
//!   never an upwind neighbour, no zero crossing with them; the front goes around them.
//!   Voxels the front cannot reach (cut off by obstacles, or beyond `narrow`) are not
//!   reached: their `reached` flag is false.
//! * **Interface.** Voxels with a 6-neighbour of the other sign (and voxels with φ = 0
//!   exactly, which lie on the zero level set) are frozen first, with the distance
//!   estimate of the sparse grids (`|φ|/|∇φ|`, capped by the edge crossings), computed
//!   with the per-axis spacing.
//!
//! Arrays are `x`-fastest over `dims = [nx, ny, nz]` (a NumPy C-ordered array of shape
//! `(nz, ny, nx)`); a 1-D or 2-D array is a box with `ny = nz = 1` or `nz = 1`.

use super::flat::DenseMarch;
use super::march::{Cost, Extension, Lattice, Marcher, UnitCost};
use super::source::{freeze_interface, LatticeSource};
use super::store::FROZEN;
use super::{FmmError, Order};
use crate::coord::Coord;
use crate::progress::Progress;
use crate::storage::tiles::{voxel_of, TILE_LEN};
use rayon::prelude::*;

/// A dense array's box and spacing.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseGrid {
    /// Voxels along x, y, z (x fastest in the arrays); each ≥ 1.
    pub dims: [usize; 3],
    /// Spacing along x, y, z (world units; finite and > 0).
    pub spacing: [f64; 3],
    /// Axes whose neighbours wrap around.
    pub periodic: [bool; 3],
}

impl DenseGrid {
    /// An isotropic, non-periodic grid.
    pub fn new(dims: [usize; 3], spacing: f64) -> DenseGrid {
        DenseGrid { dims, spacing: [spacing; 3], periodic: [false; 3] }
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.dims.iter().product()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Options of the dense marches.
#[derive(Clone, Debug, Default)]
pub struct DenseOptions {
    /// First- or second-order update.
    pub order: Order,
    /// scikit-fmm's `narrow`: march only while the value (distance in world units, or
    /// travel time) stays ≤ this (finite, > 0); voxels beyond are not reached. `None`:
    /// the whole array.
    pub narrow: Option<f64>,
    /// Progress (share of the narrow band, or of the array's voxels) and cancellation.
    pub progress: Progress,
}

/// [`dense_extension_velocities`]'s result: the signed distance and the extended field
/// (0 where not reached).
#[derive(Clone, Debug, PartialEq)]
pub struct DenseExtension {
    /// The signed distance, as [`dense_distance`] gives it.
    pub distance: DenseMarch,
    /// The extended field per voxel.
    pub extension: Vec<f32>,
}

/// Speeds below this are obstacles (scikit-fmm masks speeds below the double-precision
/// epsilon: the arrival times would overflow).
pub const MIN_SPEED: f64 = f64::EPSILON;

/// Checks the grid, the arrays' lengths, `narrow` and φ; returns the lattice (obstacles
/// from `mask` and `extra`).
pub(super) fn checked_lattice(
    phi: &[f32],
    grid: &DenseGrid,
    mask: Option<&[bool]>,
    narrow: Option<f64>,
    extra: Option<Vec<bool>>,
) -> Result<(Lattice, f64), FmmError> {
    let bad = |m: String| Err(FmmError::InvalidParameter(m));
    if grid.dims.contains(&0) {
        return bad(format!("the grid is empty: dims {:?}", grid.dims));
    }
    if grid.dims.iter().any(|&n| n > i32::MAX as usize) {
        return bad(format!("the grid's dims {:?} exceed the coordinate range", grid.dims));
    }
    let Some(n) = grid.dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d)) else {
        return bad(format!("the grid's dims {:?} hold too many voxels", grid.dims));
    };
    if n != phi.len() {
        return bad(format!("phi has {} values, the grid {:?} has {n}", phi.len(), grid.dims));
    }
    if grid.spacing.iter().any(|h| !(h.is_finite() && *h > 0.0)) {
        return bad(format!("the spacing must be finite and > 0, got {:?}", grid.spacing));
    }
    if let Some(w) = narrow
        && !(w.is_finite() && w > 0.0)
    {
        return bad(format!("narrow must be finite and > 0, got {w}"));
    }
    if let Some(m) = mask
        && m.len() != phi.len()
    {
        return bad(format!("the mask has {} values, phi has {}", m.len(), phi.len()));
    }
    let lo = Coord::new(0, 0, 0);
    let dims = grid.dims;
    let h0 = grid.spacing.iter().copied().fold(f64::INFINITY, f64::min);
    let ratios = grid.spacing.map(|h| h0 / h);
    let blocked = match (mask, extra) {
        (None, None) => None,
        (Some(m), None) => Some(m.to_vec()),
        (None, Some(e)) => Some(e),
        (Some(m), Some(mut e)) => {
            for (e, m) in e.iter_mut().zip(m) {
                *e |= *m;
            }
            Some(e)
        }
    };
    // Values under obstacles are never read.
    let open = |i: usize| !blocked.as_ref().is_some_and(|b| b[i]);
    if let Some((i, v)) = phi.iter().enumerate().find(|&(i, v)| v.is_nan() && open(i)) {
        let coord = coord_of(dims, i);
        return Err(FmmError::NonFinite { coord, value: *v });
    }
    let lattice = Lattice { lo, dims, ratios, periodic: grid.periodic, blocked };
    Ok((lattice, h0))
}

fn coord_of(dims: [usize; 3], i: usize) -> Coord {
    let x = i % dims[0];
    let y = (i / dims[0]) % dims[1];
    let z = i / (dims[0] * dims[1]);
    Coord::new(x as i32, y as i32, z as i32)
}

/// Freezes the interface of `phi`, or fails when it has none.
fn freeze<C: Cost>(phi: &[f32], m: &mut Marcher<C>, lattice: &Lattice) -> Result<(), FmmError> {
    let src = LatticeSource { data: phi, lattice };
    if freeze_interface(&src, m)? == 0 {
        return Err(FmmError::NoInterface);
    }
    Ok(())
}

/// Copies the frozen values `f(value)` out of the march.
fn collect<C: Cost>(m: &Marcher<C>, n: usize, f: impl Fn(f64) -> f32) -> DenseMarch {
    let l = m.lattice().expect("a dense march has a lattice");
    let mut values = vec![0.0f32; n];
    let mut reached = vec![false; n];
    for (t, b) in m.store.sorted_blocks() {
        for k in 0..TILE_LEN {
            let id = (b * TILE_LEN as u32 + k as u32) as usize;
            if m.store.vox[id].state & 3 == FROZEN {
                let i = l.index(voxel_of(t, k));
                values[i] = f(m.store.vox[id].value);
                reached[i] = true;
            }
        }
    }
    DenseMarch { values, reached }
}

/// The signed distance to the zero level set of `phi` (φ < 0 inside, world units) on a
/// dense grid with per-axis spacing, periodic axes and obstacles (`mask`, true =
/// obstacle), like scikit-fmm's `distance`: see the module docs.
///
/// Errors (before any work): an empty grid, `phi` or `mask` of the wrong length, a
/// spacing or `narrow` that is not finite and > 0, NaN in `phi`
/// ([`FmmError::NonFinite`]); no zero crossing outside the obstacles
/// ([`FmmError::NoInterface`]); [`FmmError::Cancelled`].
pub fn dense_distance(
    phi: &[f32],
    grid: &DenseGrid,
    mask: Option<&[bool]>,
    opts: &DenseOptions,
) -> Result<DenseMarch, FmmError> {
    let (lattice, h0) = checked_lattice(phi, grid, mask, opts.narrow, None)?;
    let second = opts.order == Order::Second;
    let limit = opts.narrow.map_or(f64::INFINITY, |w| w / h0);
    if !lattice.periodic.contains(&true) && super::flat::fits(lattice.dims) {
        // The same march on a flat array (same values, bit for bit).
        let scale = |v: f64| (v * h0) as f32;
        return match super::flat::distance(phi, &lattice, second, limit, &opts.progress, scale)? {
            Some(out) => Ok(out),
            None => Err(FmmError::NoInterface),
        };
    }
    sparse_distance(phi, lattice, h0, second, limit, &opts.progress)
}

/// The band a level-set method starts from, taken from the zero level of `phi` alone: the
/// signed distance to it ([`dense_distance`], second order) out to `gamma` and one voxel
/// of the largest spacing more, clamped to ±`gamma`, and ±`gamma` by the sign of `phi`
/// beyond. A mask's ±1, a distance in other units or a steep function give the same band.
/// Errors: those of [`dense_distance`] (NaN, no zero crossing, ...).
pub fn dense_band(
    phi: &[f32],
    grid: &DenseGrid,
    gamma: f32,
    progress: Progress,
) -> Result<Vec<f32>, FmmError> {
    let h_max = grid.spacing.iter().fold(0.0f64, |m, &s| m.max(s));
    let opts = DenseOptions { order: Order::Second, narrow: Some(gamma as f64 + h_max), progress };
    let marched = dense_distance(phi, grid, None, &opts)?;
    let DenseMarch { mut values, reached } = marched;
    values.par_iter_mut().zip(&reached).zip(phi).for_each(|((d, &reached), &v)| {
        *d = if reached { d.clamp(-gamma, gamma) } else { gamma.copysign(v) };
    });
    Ok(values)
}

/// [`dense_distance`] through the sparse march (periodic axes; the tests' reference for
/// the flat one).
pub(super) fn sparse_distance(
    phi: &[f32],
    lattice: Lattice,
    h0: f64,
    second: bool,
    limit: f64,
    progress: &Progress,
) -> Result<DenseMarch, FmmError> {
    let mut m = Marcher::on_lattice(second, lattice.clone(), UnitCost);
    freeze(phi, &mut m, &lattice)?;
    m.run(limit, progress)?;
    Ok(collect(&m, phi.len(), |v| (v * h0) as f32))
}

/// Speeds per voxel: the cost `h₀ / F` of the march.
struct FieldCost<'a> {
    speed: &'a [f32],
    /// Voxels along x and y (the box starts at the origin).
    nx: usize,
    ny: usize,
    h0: f64,
}

impl Cost for FieldCost<'_> {
    #[inline]
    fn cost(&self, c: Coord) -> Result<f64, FmmError> {
        // Obstacles (F < MIN_SPEED) are never updated; the speeds were checked.
        let i = (c.z as usize * self.ny + c.y as usize) * self.nx + c.x as usize;
        Ok(self.h0 / self.speed[i] as f64)
    }
}

/// Checks a speed array outside the obstacles of `mask` (length, finite; ≥ 0 when
/// `positive`).
fn check_speed(
    speed: &[f32],
    n: usize,
    dims: [usize; 3],
    mask: Option<&[bool]>,
    positive: bool,
) -> Result<(), FmmError> {
    if speed.len() != n {
        return Err(FmmError::InvalidParameter(format!(
            "speed has {} values, phi has {n}",
            speed.len()
        )));
    }
    let open = |i: usize| mask.is_none_or(|m| m.get(i) != Some(&true));
    let bad = |v: f32| !v.is_finite() || (positive && v < 0.0);
    if let Some((i, v)) = speed.iter().enumerate().find(|&(i, v)| bad(*v) && open(i)) {
        return Err(FmmError::BadSpeed { coord: coord_of(dims, i), speed: *v as f64 });
    }
    Ok(())
}

/// The travel time of the front that starts at the zero level set of `phi` and moves
/// with speed `speed` (world units per time unit, ≥ 0, same layout as `phi`): the
/// solution of `|∇T| F = 1` (Bærentzen 2001, eq. (1)), ≥ 0 on both sides of the zero
/// level set, like scikit-fmm's `travel_time`. The voxels next to the zero level set
/// start at `|d| / F` (their distance estimate over their own speed, as scikit-fmm).
/// Voxels with `F <` [`MIN_SPEED`] (in particular `F = 0`) are obstacles, as are those
/// of `mask`; `narrow` bounds the time.
///
/// Errors: those of [`dense_distance`]; a speed that is negative or not finite
/// ([`FmmError::BadSpeed`]), or of the wrong length.
pub fn dense_travel_time(
    phi: &[f32],
    speed: &[f32],
    grid: &DenseGrid,
    mask: Option<&[bool]>,
    opts: &DenseOptions,
) -> Result<DenseMarch, FmmError> {
    check_speed(speed, phi.len(), grid.dims, mask, true)?;
    let slow: Vec<bool> = speed.iter().map(|&f| (f as f64) < MIN_SPEED).collect();
    let (lattice, h0) = checked_lattice(phi, grid, mask, opts.narrow, Some(slow))?;
    let [nx, ny, _] = grid.dims;
    let cost = FieldCost { speed, nx, ny, h0 };
    let mut m = Marcher::on_lattice(opts.order == Order::Second, lattice.clone(), cost);
    freeze(phi, &mut m, &lattice)?;
    // Distances (units of h₀) to times: d · h₀ / F at the voxel.
    m.map_initial(|c, d| d * h0 / speed[lattice.index(c)] as f64);
    m.run(opts.narrow.unwrap_or(f64::INFINITY), &opts.progress)?;
    Ok(collect(&m, phi.len(), |v| v.abs() as f32))
}

/// The value of `speed` carried to an interface voxel from the zero level set (as
/// scikit-fmm): along each axis, at the nearest zero crossing on the voxel's edges
/// (fraction `θ` of the edge), `speed` interpolated linearly between the voxel and its
/// neighbour — or the neighbour's value when the voxel is in `ext_mask`, the voxel's when
/// the neighbour is; the axes' values are averaged with weights `1/(θ hₐ)²` (the squared
/// components of the normal for a planar front). A voxel on the level set (φ = 0) keeps
/// its own value.
fn interface_speed(
    c: Coord,
    phi: &[f32],
    speed: &[f32],
    ext_mask: Option<&[bool]>,
    l: &Lattice,
    spacing: [f64; 3],
) -> f64 {
    let i = l.index(c);
    let (v, f) = (phi[i] as f64, speed[i] as f64);
    let masked = |j: usize| ext_mask.is_some_and(|m| m[j]);
    let (mut num, mut den) = (0.0, 0.0);
    for (axis, h) in spacing.iter().enumerate() {
        let mut best: Option<(f64, f64)> = None;
        for d in [-1, 1] {
            let Some(n) = l.step(c, axis, d) else { continue };
            let j = l.index(n);
            let vn = phi[j] as f64;
            if (vn < 0.0) == (v < 0.0) {
                continue;
            }
            let theta = if v.is_infinite() { 1.0 } else { v / (v - vn) };
            if best.is_none_or(|(t, _)| theta < t) {
                let fn_ = speed[j] as f64;
                let fc = if masked(i) {
                    fn_
                } else if masked(j) {
                    f
                } else {
                    f + theta * (fn_ - f)
                };
                best = Some((theta, fc));
            }
        }
        if let Some((theta, fc)) = best {
            let dist = theta * h;
            if dist == 0.0 {
                return f;
            }
            num += fc / (dist * dist);
            den += 1.0 / (dist * dist);
        }
    }
    if den > 0.0 {
        num / den
    } else {
        f
    }
}

/// scikit-fmm's `extension_velocities`: the signed distance of [`dense_distance`] and
/// `speed` extended from the zero level set along the distance's characteristics, so that
/// `∇f · ∇d = 0` (Adalsteinsson & Sethian, *The Fast Construction of Extension Velocities
/// in Level Set Methods*, J. Comput. Phys. 148 (1999) 2–22): interface voxels take the
/// speed at the zero level set (interpolated as scikit-fmm does; `ext_mask` marks voxels
/// whose own speed is not to be used there), every other voxel the average of its upwind
/// neighbours' values, weighted by their share in its distance (each axis's component of
/// ∇d, from the second-order one-sided difference where the voxel two steps upwind is
/// frozen). Only the speed at the interface voxels is read; any finite value is allowed.
/// The distance is that of [`dense_distance`] bit for bit.
///
/// Errors: those of [`dense_distance`]; a non-finite speed, a `speed` or `ext_mask` of the
/// wrong length.
pub fn dense_extension_velocities(
    phi: &[f32],
    speed: &[f32],
    ext_mask: Option<&[bool]>,
    grid: &DenseGrid,
    mask: Option<&[bool]>,
    opts: &DenseOptions,
) -> Result<DenseExtension, FmmError> {
    check_speed(speed, phi.len(), grid.dims, mask, false)?;
    if let Some(e) = ext_mask
        && e.len() != phi.len()
    {
        return Err(FmmError::InvalidParameter(format!(
            "ext_mask has {} values, phi has {}",
            e.len(),
            phi.len()
        )));
    }
    let (lattice, h0) = checked_lattice(phi, grid, mask, opts.narrow, None)?;
    let mut m = Marcher::on_lattice(opts.order == Order::Second, lattice.clone(), UnitCost);
    freeze(phi, &mut m, &lattice)?;
    let mut ext = vec![0.0f64; phi.len()];
    for &c in m.initial() {
        ext[lattice.index(c)] = interface_speed(c, phi, speed, ext_mask, &lattice, grid.spacing);
    }
    m.extension = Some(Extension { values: ext });
    m.run(opts.narrow.map_or(f64::INFINITY, |w| w / h0), &opts.progress)?;
    let distance = collect(&m, phi.len(), |v| (v * h0) as f32);
    let ext = &m.extension.as_ref().expect("set above").values;
    let extension =
        ext.iter().zip(&distance.reached).map(|(&f, &r)| if r { f as f32 } else { 0.0 }).collect();
    Ok(DenseExtension { distance, extension })
}
