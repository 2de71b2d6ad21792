//! The three representations the evolution runs on — Sorted Tile List ([`tiles`]),
//! DT-Grid ([`dtgrid`]), dense reference ([`dense`]) — behind one internal trait,
//! [`Representation`].
//!
//! Every representation stores its values as one flat array (tiles: list position × 64 +
//! local index; DT-Grid: point order; dense: x-fastest box order). Per-voxel inputs (F,
//! u, φⁿ, the band mask) are flat arrays in the same order, so a kernel reads them with
//! the index of its voxel.
//!
//! # Atomic steps
//! A step is *begun* by its first stage and ends with [`Representation::commit_step`] or
//! [`Representation::undo_step`]. Until then the representation keeps what it needs to
//! put the state before the step back: φⁿ (on the DT-Grid and the dense reference the
//! double buffer the first stage swapped out, or the φⁿ buffer of TVD-RK3, so no copy is
//! made; on tiles forward Euler's φⁿ packed, see [`tiles`]) and, when the band maintenance of
//! [`Representation::finish_step`] replaced the tile list or the DT-Grid, the previous one
//! (which the replacement would otherwise drop; the tile list's without values of its own
//! when the new list's were built in a step buffer, see
//! [`crate::storage::tiles::TileGrid::manage_tiles`]: φⁿ is put back into it).

pub(crate) mod dense;
pub(crate) mod dtgrid;
pub(crate) mod packed;
pub(crate) mod tiles;

pub(crate) use crate::memory::resize_exact;
pub(crate) use dense::DenseRep;
pub(crate) use dtgrid::DtRep;
pub(crate) use tiles::{step_bytes_per_tile, TilesRep, TILE_GRID_BYTES};

use super::dispatch::{RenormParams, StageParams};
use super::field::{ScalarFn, VectorFn};
use super::{EvolveError, Settings, SpatialScheme, StepKeeps};
use crate::coord::Coord;
use crate::exact::ExactSum;
use crate::grid::{GridError, GridSpec};
use crate::memory::grown_capacity;
use levelset_kernels::speed::kappa_bar_integrands;
use levelset_kernels::{Lane, VoxelKernel, Window};
use rayon::prelude::*;

/// What every representation does for the evolution.
pub(crate) trait Representation: Send + Sync {
    fn spec(&self) -> GridSpec;
    /// The current values in flat order.
    fn flat(&self) -> &[f32];
    /// Samples a scalar field at every stored voxel (flat order). With `planar` (a planar
    /// lattice's level set, extruded over z) a representation may sample only the voxels
    /// its sweeps compute: the tiles their first z-slice (see `TileBlock::apply_slices`),
    /// the other voxels then hold 0.
    fn fill_scalar(&self, f: &dyn ScalarFn, t: f64, planar: bool, out: &mut [f32]);
    /// Per-voxel arrays in flat order of which, with `planar`, the sweeps read only each
    /// unit's first z-slice: `Some((unit, read))`, the first `read` voxels of every `unit`
    /// (tiles: 16 of 64; the other slices hold copies of φ's first slice, and the inputs'
    /// passes may skip them). `None`: every voxel is read.
    fn read_slices(&self, planar: bool) -> Option<(usize, usize)> {
        let _ = planar;
        None
    }
    /// The units of the flat order (tiles: their coordinates, 64 voxels each), when the
    /// representation keeps such keys; empty otherwise. Per-voxel samples of a field that
    /// does not change with time stay valid while the units and the spec stay.
    fn unit_keys(&self) -> &[Coord] {
        &[]
    }
    /// Samples a vector field at every stored voxel (flat order).
    fn fill_vector(&self, f: &dyn VectorFn, t: f64, out: [&mut [f32]; 3]);
    /// Samples a field that depends on the position only (u(x, 0) of a time-separable
    /// field, [`VectorFn::time_scale`]) at t = 0 like [`Representation::fill_vector`],
    /// reusing earlier samples: `prev` holds, unit by unit (a representation's run of
    /// voxels in flat order, 64 per tile), the samples of the units `keys` names, and
    /// `keys` becomes the units of `out`, or empty when the representation keeps no keys.
    /// The samples are the field's, so reused and fresh ones have the same bits (on a
    /// planar lattice only the reused units' voxels that the sweeps read are kept,
    /// [`Representation::read_slices`]). Returns
    /// whether every sample written anew is finite (the reused ones were checked when
    /// they were sampled). The default samples everything anew.
    fn fill_static_vector(
        &self,
        f: &dyn VectorFn,
        keys: &mut Vec<Coord>,
        prev: [&[f32]; 3],
        out: [&mut [f32]; 3],
    ) -> bool {
        let _ = prev;
        keys.clear();
        let [u, v, w] = out;
        self.fill_vector(f, 0.0, [&mut *u, &mut *v, &mut *w]);
        [u, v, w].iter().all(|c| c.iter().all(|x| x.is_finite()))
    }
    /// [`Representation::fill_static_vector`] for a scalar field of the position alone,
    /// sampled at the voxels the sweeps read (`planar`: see
    /// [`Representation::fill_scalar`]). `finish` is applied to the samples of every unit
    /// taken anew (the voxels the sweeps read; it may scale them) and says whether they are
    /// acceptable; reused samples are those `finish` left. Returns whether all new ones
    /// were. The default samples everything anew.
    fn fill_static_scalar(
        &self,
        f: &dyn ScalarFn,
        planar: bool,
        keys: &mut Vec<Coord>,
        prev: &[f32],
        out: &mut [f32],
        finish: &(dyn Fn(&mut [f32]) -> bool + Sync),
    ) -> bool {
        let _ = prev;
        keys.clear();
        self.fill_scalar(f, 0.0, planar, out);
        let (unit, read) = self.read_slices(planar).unwrap_or((4096, 4096));
        out.par_chunks_mut(unit)
            .map(|u| {
                let n = read.min(u.len());
                finish(&mut u[..n])
            })
            .reduce(|| true, |a, b| a && b)
    }
    /// Runs one stage: the current values become the stage's result; in stages 2 and 3
    /// the kernel reads φⁿ, kept from stage 1. `last` marks the step's final stage. On
    /// an error the values are those before the stage.
    fn stage(
        &mut self,
        p: &StageParams,
        scheme: SpatialScheme,
        last: bool,
    ) -> Result<(), EvolveError>;
    /// Renormalisation ([`super::Renormalization::Sweeps`]): the Russo–Smereka anchors of
    /// the current values φ⁰, then `p.sweeps` forward-Euler sweeps in pseudo time, each
    /// swapped into the values (the first sweep may evaluate the anchors in place,
    /// [`levelset_kernels::AnchoredRenormRate`]: no anchor pass when it is the only one;
    /// the tile engine's first sweep also stores them for the others). The voxels computed
    /// are those of the band mask of the step in progress (after its stages, before its
    /// band maintenance: the stored set every representation holds is still that of φⁿ)
    /// or, with `fresh`, the mask of φ⁰ (at rest, where the band maintenance has stored
    /// it; the pass then begins an undoable change like a step's first stage). The stored
    /// set does not change. On an error the caller undoes the step.
    fn renormalize(&mut self, p: &RenormParams, fresh: bool) -> Result<(), EvolveError>;
    /// Band maintenance after a step or a reinitialisation: tile management, DT-Grid
    /// rebuild, dense bounds. New storage is admitted by `budget` before it is allocated
    /// (the DT-Grid: before its rebuilt grid replaces the current one). On an error the
    /// representation is as before the call.
    fn finish_step(&mut self, budget: &MemoryBudget) -> Result<(), EvolveError>;
    /// Visits φⁿ of the step in progress on the units this rank owned before the step, in
    /// slices of values (nothing when no stage has run). Values of exactly ±γ (outside the
    /// band) may be left out.
    fn for_each_owned_step_start(&self, f: &mut dyn FnMut(&[f32]));
    /// Puts back the state before the step in progress: values, stored set, flags.
    fn undo_step(&mut self);
    /// The step in progress stands: drops what [`Representation::undo_step`] needed.
    fn commit_step(&mut self);
    /// (Σ κδ|∇φ|, Σ δ|∇φ|) over the current values (eq. (6) without the h³ that cancels).
    fn kappa_bar_sums(&self, width: f32) -> Result<(ExactSum, ExactSum), EvolveError>;
    /// Visits the interior voxels the representation does not store as x-runs
    /// `(first voxel, length)`, in [`Coord`] order.
    fn for_each_unstored_inside_run(&self, f: &mut dyn FnMut(Coord, u32));
    /// Interior voxels the representation does not store (each counts fully inside).
    fn unstored_inside(&self) -> u64 {
        let mut n = 0u64;
        self.for_each_unstored_inside_run(&mut |_, len| n += len as u64);
        n
    }
    /// Visits the band voxels (|φ| < γ) in [`Coord`] order.
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32));
    /// Whether `f` holds for some stored voxel, visited in flat order until it does.
    fn any_voxel(&self, f: &mut dyn FnMut(Coord, f32) -> bool) -> bool;
    /// Value at any voxel (±γ where nothing is stored).
    fn value(&self, c: Coord) -> f32;
    /// The rank's transport when the representation is one rank's part of a
    /// distributed band ([`crate::distributed`]); `None` otherwise.
    fn comm(&self) -> Option<&crate::distributed::Comm> {
        None
    }
    /// The values of the units this rank owns, in flat order (all of them unless
    /// distributed).
    fn owned_flat(&self) -> &[f32] {
        self.flat()
    }
    /// Tiles (tiles, those this rank owns when distributed), points (DT-Grid) or voxels
    /// (dense) stored.
    fn units(&self) -> usize;
    /// Bytes of the representation's data (values, indices, flags; unused capacity of
    /// its arrays excluded).
    fn bytes(&self) -> usize;
    /// Bytes of the evolution's buffers (double buffer, φⁿ, band mask, rebuild scratch)
    /// and the representation's unused capacity.
    fn work_bytes(&self) -> usize;
    /// Bytes of the representation and its buffers (as [`Representation::bytes`] +
    /// [`Representation::work_bytes`]) once a step's buffers hold the current band
    /// (`keeps`: with a φⁿ buffer of its own, TVD-RK3 or a renormalisation;
    /// `anchors`: with the stored anchors of a renormalisation): what its first stage may
    /// allocate.
    fn step_bytes(&self, keeps: StepKeeps) -> u64;
}

/// The representation a simulation runs on.
#[derive(Clone)]
pub(crate) enum Rep {
    Tiles(TilesRep),
    // Boxed: the DT-Grid engine holds three grids (current, rebuild scratch, result).
    DtGrid(Box<DtRep>),
    Dense(DenseRep),
}

impl Rep {
    /// Takes what the representation reads of the simulation's settings: the tile
    /// engine's [`Settings::double_buffer_bytes`] and whether its lattice is planar.
    /// Called wherever a representation joins a simulation (its start, a
    /// reinitialisation).
    pub fn take_settings(&mut self, settings: &Settings) {
        if let Rep::Tiles(t) = self {
            t.double_buffer_bytes = settings.double_buffer_bytes;
            t.planar = settings.lattice.is_some_and(|l| l.planar);
        }
    }

    pub fn get(&self) -> &dyn Representation {
        match self {
            Rep::Tiles(r) => r,
            Rep::DtGrid(r) => r.as_ref(),
            Rep::Dense(r) => r,
        }
    }

    pub fn get_mut(&mut self) -> &mut dyn Representation {
        match self {
            Rep::Tiles(r) => r,
            Rep::DtGrid(r) => r.as_mut(),
            Rep::Dense(r) => r,
        }
    }
}

/// The memory a run may use ([`super::Settings::memory_limit`]): new storage is admitted
/// before it is allocated.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MemoryBudget {
    /// The most bytes the simulation may take; `None`: what the machine can give
    /// ([`crate::memory::limit`]) bounds each growth instead.
    pub limit: Option<u64>,
    /// What steps keep besides the double buffer, for the estimates.
    pub keeps: StepKeeps,
    /// Bytes the simulation holds besides the representation (the per-voxel inputs),
    /// counted against the limit.
    pub held: u64,
}

impl MemoryBudget {
    /// Admits a representation of `needed` bytes (data and buffers, estimated) that
    /// replaces one of `current` bytes; `what` names it in the error
    /// ([`GridError::OutOfMemory`]).
    pub fn admit(&self, needed: u64, current: u64, what: &str) -> Result<(), GridError> {
        let needed = needed.saturating_add(self.held);
        match self.limit {
            Some(limit) if needed > limit => {
                Err(GridError::OutOfMemory { what: what.to_string(), needed, limit })
            }
            Some(_) => Ok(()),
            // The growth is what is allocated while the current state still exists.
            None => {
                let current = current.saturating_add(self.held);
                if needed > current {
                    crate::memory::check((needed - current) as f64, what)
                } else {
                    Ok(())
                }
            }
        }
    }
}

/// The integrands of κ̄ (eq. (6)) with the smoothed delta of eq. (7), made
/// dimensionless so that their fixed-point sums neither overflow nor lose precision at any
/// voxel size: `NUM` selects κ δ(φ)|∇φ| · h² (numerator) or δ(φ)|∇φ| · h (denominator,
/// which summed times h² is the interface area); κ̄ = Σ num / (h Σ den).
#[derive(Clone, Copy)]
pub(crate) struct KappaBarTerm<const NUM: bool> {
    pub inv_h: f32,
    pub width: f32,
}

impl<const NUM: bool> VoxelKernel for KappaBarTerm<NUM> {
    const AXIS_REACH: i32 = 1;
    const BOX_REACH: i32 = 1;
    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, _first: usize) -> L {
        let (num, den) = kappa_terms(w, self.inv_h, self.width);
        if NUM {
            num
        } else {
            den
        }
    }
}

/// Both integrands of [`KappaBarTerm`] from one evaluation of the stencil.
#[inline(always)]
pub(crate) fn kappa_terms<L: Lane, W: Window<L>>(w: &W, inv_h: f32, width: f32) -> (L, L) {
    let inv_h = L::splat(inv_h);
    let (num, den) = kappa_bar_integrands(w, inv_h, L::splat(width));
    let h = L::splat(1.0) / inv_h;
    (num * (h * h), den * h)
}

/// Bytes a vector holds, used or not.
pub(crate) fn vec_bytes<T>(v: &Vec<T>) -> usize {
    let (used, slack) = crate::grid::vec_bytes(v);
    used + slack
}

/// Bytes a vector has to allocate to hold `n` elements ([`resize_exact`]'s growth).
pub(crate) fn growth_bytes<T>(v: &Vec<T>, n: usize) -> u64 {
    if n <= v.capacity() {
        return 0;
    }
    ((grown_capacity(n) - v.capacity()) * std::mem::size_of::<T>()) as u64
}

/// Which buffer of the DT-Grid or the dense reference holds φⁿ while a step is in progress
/// (no copy is made: the first stage's double buffer, swapped out of the grid, is kept).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Undo {
    /// No step in progress, or its first stage failed before changing anything.
    #[default]
    Nothing,
    /// Forward Euler: the output buffer `out` holds φⁿ.
    Out,
    /// TVD-RK3: the φⁿ buffer holds it.
    PhiN,
}

impl Undo {
    /// φⁿ of the step in progress: the buffer this names (`out` or `phi_n`), empty when
    /// no step is in progress.
    pub(crate) fn held<'a, T>(self, phi_n: &'a [T], out: &'a [T]) -> &'a [T] {
        match self {
            Undo::Nothing => &[],
            Undo::Out => out,
            Undo::PhiN => phi_n,
        }
    }

    /// Frees `out` for further sweeps within a step: φⁿ held there moves to `phi_n` (a
    /// swap). Returns whether it moved (the caller moves companion buffers alike).
    pub(crate) fn vacate_out<T>(&mut self, phi_n: &mut Vec<T>, out: &mut Vec<T>) -> bool {
        if *self == Undo::Out {
            std::mem::swap(phi_n, out);
            *self = Undo::PhiN;
            true
        } else {
            false
        }
    }

    /// Where φⁿ is kept after a stage-1 sweep that swapped its result in and left the
    /// previous values in `out`: there for a one-stage step; moved into `phi_n` (which
    /// the later stages read) for TVD-RK3.
    pub(crate) fn after_stage1<T>(last: bool, phi_n: &mut Vec<T>, out: &mut Vec<T>) -> Undo {
        if last {
            Undo::Out
        } else {
            std::mem::swap(phi_n, out);
            Undo::PhiN
        }
    }
}
