//! Measures of any level set: band voxels, enclosed volume and interface area, the same
//! numbers for every storage of the same band.
//!
//! * **Volume** (world units): h³ Σ clamp(½ − φ/h, 0, 1) over the band voxels, plus h³ per
//!   interior voxel outside the band. The interior outside the band is counted row by
//!   row from the band voxels in [`Coord`] order: on an x-row, the voxels before the first
//!   band voxel and after the last are outside (the interior is bounded), and each gap
//!   between two band voxels has one sign (a sign change needs band voxels), read once.
//! * **Area** (world units): h³ Σ δ(φ)|∇φ| over the band voxels with the smoothed delta of
//!   eq. (7) of van der Laan et al. 2011 and |∇φ| from the 27-point box of eq. (4), the integrand
//!   the evolution's κ̄ (eq. (6)) uses.
//!
//! Terms are added as exact fixed-point sums ([`crate::exact::ExactSum`]), so the
//! results do not depend on the order of the voxels: the tile grid, the DT-Grid and a
//! simulation's state give the same bits, and the volume equals
//! [`crate::evolve::Simulation::measure`]'s.
//!
//! ```
//! use sparse_levelset::{storage::convert, grid::GridSpec, tools::measure, storage::shapes::Shape};
//!
//! let r = 20.0;
//! let sphere = Shape::Sphere { center: [0.5; 3], radius: r };
//! let tiles = convert::tiles_from_shape(&sphere, GridSpec::default()).unwrap();
//! let m = measure::measure(&tiles, &Default::default()).unwrap();
//! let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
//! assert!((m.volume - exact).abs() < 1e-3 * exact);
//! assert_eq!(m, measure::measure(&convert::dtgrid_from(&tiles), &Default::default()).unwrap());
//! ```

use crate::coord::Coord;
use crate::exact::ExactSum;
use crate::progress::{Cancelled, Progress};
use crate::storage::levelset::{Accessor, LevelSet};
use levelset_kernels::speed::kappa_bar_integrands;
use levelset_kernels::{BoxWindow, Lane, LaneFn, BOX27_OFFSETS};
use serde::Serialize;

/// Options of [`measure`].
#[derive(Clone, Debug, PartialEq)]
pub struct MeasureOptions {
    /// Width ε of the smoothed delta of eq. (7), in voxels (finite, > 0, at most the
    /// half-width, so that only band voxels carry the interface).
    pub delta_width: f32,
    /// Progress (band voxels done) and cancellation.
    pub progress: Progress,
}

impl Default for MeasureOptions {
    /// ε = 1.5 voxels, the evolution's default.
    fn default() -> Self {
        MeasureOptions { delta_width: 1.5, progress: Progress::none() }
    }
}

/// What [`measure`] finds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Measures {
    /// Voxels with |φ| < γ.
    pub band_voxels: usize,
    /// Enclosed volume, world units.
    pub volume: f64,
    /// Interface area, world units.
    pub area: f64,
}

/// Errors of [`measure`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeasureError {
    #[error("invalid measure option: {0}")]
    InvalidOption(String),
    /// A band value is NaN: no measure of it means anything.
    #[error("the value at voxel {coord} is NaN")]
    NaN { coord: Coord },
    #[error("measuring was cancelled")]
    Cancelled(#[from] Cancelled),
}

impl crate::error::Error for MeasureError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            MeasureError::InvalidOption(_) => InvalidInput,
            MeasureError::NaN { .. } => InvalidData,
            MeasureError::Cancelled(_) => Cancelled,
        }
    }
}

/// Band voxels, volume and area of any level set (see the [module docs](self)).
pub fn measure<G: LevelSet + ?Sized>(
    grid: &G,
    opts: &MeasureOptions,
) -> Result<Measures, MeasureError> {
    let spec = grid.spec();
    let w = opts.delta_width;
    if !(w.is_finite() && w > 0.0 && w <= spec.half_width) {
        return Err(MeasureError::InvalidOption(format!(
            "delta width must be finite, > 0 and at most the half-width {}, got {w}",
            spec.half_width
        )));
    }
    let h = spec.voxel_size;
    let (inv_h, width) = (1.0 / h, w * h);
    // The total costs a pass over the band: counted only for a listener.
    let total = if opts.progress.is_active() { grid.band_voxels() as u64 } else { 0 };
    let ticker = opts.progress.start(total);
    let mut acc = grid.accessor();
    let mut inside_terms = ExactSum::default();
    let mut area_terms = ExactSum::default();
    let mut gaps_inside: u64 = 0;
    let mut band = 0usize;
    let mut prev: Option<Coord> = None;
    let mut err = None;
    let mut box27 = [0f32; 27];
    grid.for_each_band_voxel(&mut |c, v| {
        if err.is_some() {
            return;
        }
        if v.is_nan() {
            err = Some(MeasureError::NaN { coord: c });
            return;
        }
        band += 1;
        if band.is_multiple_of(4096)
            && let Err(e) = ticker.advance(4096)
        {
            err = Some(e.into());
            return;
        }
        inside_terms.add((0.5 - v / h).clamp(0.0, 1.0));
        // A gap since the previous band voxel of this row: one sign, read at its start.
        if let Some(p) = prev.filter(|p| p.z == c.z && p.y == c.y && c.x - p.x > 1)
            && acc.value(Coord::new(p.x + 1, p.y, p.z)) < 0.0
        {
            gaps_inside += (c.x - p.x - 1) as u64;
        }
        prev = Some(c);
        if v.abs() < width {
            for (o, slot) in BOX27_OFFSETS.iter().zip(box27.iter_mut()) {
                *slot = match c.checked_add(Coord::new(o[0], o[1], o[2])) {
                    Some(n) => acc.value(n),
                    // Beyond the i32 range nothing is stored: outside.
                    None => spec.gamma(),
                };
            }
            let den = levelset_kernels::dispatch_one(AreaTerm { box27: &box27, inv_h, width });
            area_terms.add(den * (1.0 / inv_h));
        }
    });
    if let Some(e) = err {
        return Err(e);
    }
    ticker.set(band as u64)?;
    let h = h as f64;
    let h3 = h * h * h;
    Ok(Measures {
        band_voxels: band,
        volume: h3 * (inside_terms.value() + gaps_inside as f64),
        // The terms hold δ|∇φ|·h: area = h³ Σ δ|∇φ| = h² Σ terms.
        area: h * h * area_terms.value(),
    })
}

/// The area integrand δ|∇φ| of one voxel's 3×3×3 box, at the CPU's level (so that it has
/// the bits of the engine's κ̄ terms).
struct AreaTerm<'a> {
    box27: &'a [f32; 27],
    inv_h: f32,
    width: f32,
}

impl LaneFn for AreaTerm<'_> {
    type Output = f32;
    #[inline(always)]
    fn call<L: Lane>(self) -> f32 {
        let w = BoxWindow::new(self.box27);
        let (_, den) = kappa_bar_integrands::<L, _>(&w, L::splat(self.inv_h), L::splat(self.width));
        crate::evolve::one_value(den)
    }
}
