//! The three representations the evolution runs on — Sorted Tile List, DT-Grid, dense
//! reference — behind one set of operations, and the dispatch that turns the run-time
//! choices (scheme, stage, advection on/off) into one kernel type per sweep.
//!
//! Every representation stores its values as one flat array (tiles: list position × 64 +
//! local index; DT-Grid: point order; dense: x-fastest box order). Per-voxel inputs (F,
//! u, φⁿ, the band mask) are flat arrays in the same order, so a kernel reads them with
//! the index of its voxel.

use super::exact::ExactSum;
use super::field::{ScalarFn, VectorFn};
use super::{EvolveError, Lanes, SpatialScheme};
use crate::coord::Coord;
use crate::dense::DenseField;
use crate::dtgrid::{DtGrid, Stencil, StencilIter};
use crate::grid::GridSpec;
use crate::tiles::{
    compute_activity, voxel_of, NeighbourTable, PaddedBlock, Tile, TileGrid, ACTIVE_MASK,
};
use levelset_kernels::speed::kappa_bar_integrands;
use levelset_kernels::{
    AdvectionRate, BandMasked, BoxFarWindow, BoxMinAbs, BoxWindow, DefaultLane, DenseBlock,
    Eq3Rate, Lane, Rk3, ScaledVelocity, Sum, TileBlock, Upwind1, VoxelKernel, Weno5, Window,
    BOX27_OFFSETS, BOX_FAR39_OFFSETS,
};
use rayon::prelude::*;
use std::ops::Range;

/// Tiles per parallel task. Results do not depend on it: every tile is computed on its
/// own and reductions are exact (see [`ExactSum`]).
const TILE_CHUNK: usize = 64;

/// Inputs of one Runge–Kutta stage (or one Euler step, which is stage 1 alone).
#[derive(Clone, Copy)]
pub(crate) struct StageParams<'a> {
    /// 1, 2 or 3 (TVD-RK3 stage; forward Euler is stage 1).
    pub stage: u8,
    pub dt: f32,
    pub gamma: f32,
    pub h: f32,
    /// ε, the curvature weight.
    pub eps: f32,
    /// Weight of the rescaling term of eq. (3).
    pub rescale: f32,
    /// F, the same everywhere (then `speed` is unused)...
    pub uniform_speed: Option<f32>,
    /// ... or per voxel (flat order).
    pub speed: &'a [f32],
    /// u per voxel (flat order), if the flow advects.
    pub velocity: Option<[&'a [f32]; 3]>,
    /// Factor of the velocity in this stage (a time-separable field; 1 otherwise).
    pub velocity_scale: f32,
    /// φⁿ per voxel (flat order), read in stages 2 and 3 (empty in stage 1); set by the
    /// representation, which keeps φⁿ.
    pub phi_n: &'a [f32],
}

impl<'a> StageParams<'a> {
    /// φⁿ of the voxels `r` (empty in stage 1).
    #[inline]
    fn phi_n(&self, r: Range<usize>) -> &'a [f32] {
        if self.phi_n.is_empty() {
            &[]
        } else {
            &self.phi_n[r]
        }
    }
}

/// A sweep that runs kernels of any type over a representation: the visitor the dispatch
/// hands the chosen kernel to. `make(range)` builds the kernel for the voxels `range` of
/// the flat order (their per-voxel inputs sliced to start at the block's first voxel).
/// `R` is the halo the kernel needs.
pub(crate) trait Sweep {
    fn run<K, M, const R: usize>(self, make: M) -> Result<(), EvolveError>
    where
        K: VoxelKernel,
        M: Fn(Range<usize>) -> K + Sync,
        Halo<R>: PointWindow;
}

/// A stencil reach `R` (1: the 3×3×3 box; 3: the box and ±3 along the axes) as a type, so
/// that the DT-Grid's sweep picks its point window at compile time.
pub(crate) struct Halo<const R: usize>;

/// How the DT-Grid's stencil iterator serves a kernel of reach `R`: the stencil it walks
/// and the point window over its values.
pub(crate) trait PointWindow {
    fn stencil(rep: &DtRep) -> &Stencil;
    fn eval<K: VoxelKernel>(k: &K, values: &[f32], i: usize) -> f32;
}

impl PointWindow for Halo<1> {
    fn stencil(rep: &DtRep) -> &Stencil {
        &rep.box27
    }
    #[inline(always)]
    fn eval<K: VoxelKernel>(k: &K, values: &[f32], i: usize) -> f32 {
        k.eval::<f32, _>(&BoxWindow::new(values.try_into().expect("27 values")), i)
    }
}

impl PointWindow for Halo<3> {
    fn stencil(rep: &DtRep) -> &Stencil {
        &rep.box_far39
    }
    #[inline(always)]
    fn eval<K: VoxelKernel>(k: &K, values: &[f32], i: usize) -> f32 {
        k.eval::<f32, _>(&BoxFarWindow::new(values.try_into().expect("39 values")), i)
    }
}

/// The kernel of one stage over the voxels `r` of the flat order: the rate (F uniform
/// or per voxel; with or without advection) in a TVD-RK3 stage (stage 1 is Euler).
macro_rules! stage_kernel {
    ($p:expr, $S:ty, $stage:literal, $spd:ident, $adv:ident) => {
        move |r: Range<usize>| Rk3::<_, $stage> {
            rate: stage_kernel!(@rate $p, $S, r, $spd, $adv),
            dt: $p.dt,
            gamma: $p.gamma,
            phi_n: $p.phi_n(r),
        }
    };
    (@speed $p:expr, $r:ident, uniform) => {
        $p.uniform_speed.unwrap_or(0.0)
    };
    (@speed $p:expr, $r:ident, per_voxel) => {
        &$p.speed[$r.clone()]
    };
    (@rate $p:expr, $S:ty, $r:ident, $spd:ident, none) => {
        Eq3Rate::<$S, _>::new($p.h, stage_kernel!(@speed $p, $r, $spd), $p.eps, $p.rescale)
    };
    (@rate $p:expr, $S:ty, $r:ident, $spd:ident, adv) => {
        Sum(
            Eq3Rate::<$S, _>::new($p.h, stage_kernel!(@speed $p, $r, $spd), $p.eps, $p.rescale),
            AdvectionRate::<$S, ScaledVelocity>::new(
                $p.h,
                ScaledVelocity {
                    components: $p
                        .velocity
                        .map(|v| [&v[0][$r.clone()], &v[1][$r.clone()], &v[2][$r.clone()]])
                        .unwrap_or([&[], &[], &[]]),
                    scale: $p.velocity_scale,
                },
            ),
        )
    };
}

/// Decides scheme, stage, uniform or per-voxel F and advection once and runs the sweep
/// with that kernel type (STYLE: decide once, outside the loop).
pub(crate) fn dispatch<V: Sweep>(
    p: &StageParams,
    scheme: SpatialScheme,
    sweep: V,
) -> Result<(), EvolveError> {
    macro_rules! go {
        ($S:ty, $R:literal, $spd:ident, $adv:ident) => {
            match p.stage {
                1 => sweep.run::<_, _, $R>(stage_kernel!(p, $S, 1, $spd, $adv)),
                2 => sweep.run::<_, _, $R>(stage_kernel!(p, $S, 2, $spd, $adv)),
                _ => sweep.run::<_, _, $R>(stage_kernel!(p, $S, 3, $spd, $adv)),
            }
        };
        ($S:ty, $R:literal) => {
            match (p.uniform_speed.is_some(), p.velocity.is_some()) {
                (true, false) => go!($S, $R, uniform, none),
                (true, true) => go!($S, $R, uniform, adv),
                (false, false) => go!($S, $R, per_voxel, none),
                (false, true) => go!($S, $R, per_voxel, adv),
            }
        };
    }
    match scheme {
        SpatialScheme::Upwind1 => go!(Upwind1, 1),
        SpatialScheme::Weno5 => go!(Weno5, 3),
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
fn kappa_terms<L: Lane, W: Window<L>>(w: &W, inv_h: f32, width: f32) -> (L, L) {
    let inv_h = L::splat(inv_h);
    let (num, den) = kappa_bar_integrands(w, inv_h, L::splat(width));
    let h = L::splat(1.0) / inv_h;
    (num * (h * h), den * h)
}

/// What every representation does for the evolution.
pub(crate) trait Representation: Send + Sync {
    fn spec(&self) -> GridSpec;
    /// The current values in flat order.
    fn flat(&self) -> &[f32];
    /// Samples a scalar field at every stored voxel (flat order).
    fn fill_scalar(&self, f: &dyn ScalarFn, t: f64, out: &mut [f32]);
    /// Samples a vector field at every stored voxel (flat order).
    fn fill_vector(&self, f: &dyn VectorFn, t: f64, out: [&mut [f32]; 3]);
    /// Runs one stage: the current values become the stage's result; in stages 2 and 3
    /// the kernel reads φⁿ, kept from stage 1. `last` marks the step's final stage.
    fn stage(
        &mut self,
        p: &StageParams,
        scheme: SpatialScheme,
        last: bool,
    ) -> Result<(), EvolveError>;
    /// Puts φⁿ back after stage 1 of an RK3 step (a later stage failed): the step is
    /// undone.
    fn rollback(&mut self) -> Result<(), EvolveError>;
    /// (Σ κδ|∇φ|, Σ δ|∇φ|) over the current values (eq. (6) without the h³ that cancels).
    fn kappa_bar_sums(&self, width: f32) -> Result<(ExactSum, ExactSum), EvolveError>;
    /// Band maintenance after a step: tile management, DT-Grid rebuild, dense bounds.
    fn finish_step(&mut self) -> Result<(), EvolveError>;
    /// Interior voxels the representation does not store (each counts fully inside).
    fn unstored_inside(&self) -> u64;
    /// Visits the band voxels (|φ| < γ) in [`Coord`] order.
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32));
    /// Value at any voxel (±γ where nothing is stored).
    fn value(&self, c: Coord) -> f32;
    /// Tiles (tiles), points (DT-Grid) or voxels (dense) stored.
    fn units(&self) -> usize;
    /// Bytes of the representation's data (values, indices, flags; unused capacity of
    /// its arrays excluded).
    fn bytes(&self) -> usize;
    /// Bytes of the evolution's buffers (double buffer, φⁿ, band mask, rebuild scratch)
    /// and the representation's unused capacity.
    fn work_bytes(&self) -> usize;
}

/// Bytes a vector holds, used or not.
fn vec_bytes<T>(v: &Vec<T>) -> usize {
    let (used, slack) = crate::grid::vec_bytes(v);
    used + slack
}

// ---------------------------------------------------------------------------------------
// Sorted Tile List.

/// The tile engine: the grid holds the current values; `out` is the double buffer the
/// sweep writes in list order (Sec. 4.7), swapped into the grid after each stage.
#[derive(Clone)]
///
/// # Invariants
/// `table` holds the neighbours of `grid`'s current list (rebuilt after every tile
/// management; checked in debug builds where it is read).
pub(crate) struct TilesRep {
    pub grid: TileGrid,
    pub lanes: Lanes,
    table: NeighbourTable,
    phi_n: Vec<Tile>,
    out: Vec<Tile>,
    box_min: Vec<f32>,
    activity: Vec<u32>,
}

impl TilesRep {
    /// The engine over `grid`; builds the neighbour table in the current rayon pool.
    pub fn new(grid: TileGrid, lanes: Lanes) -> Self {
        let mut table = NeighbourTable::default();
        table.rebuild(grid.tile_coords());
        TilesRep {
            grid,
            lanes,
            table,
            phi_n: Vec::new(),
            out: Vec::new(),
            box_min: Vec::new(),
            activity: Vec::new(),
        }
    }

    /// The neighbour table, checked against the list in debug builds.
    fn table(&self) -> &NeighbourTable {
        debug_assert_eq!(self.table.len(), self.grid.len(), "stale neighbour table");
        &self.table
    }
}

struct TileSweep<'a> {
    grid: &'a TileGrid,
    table: &'a NeighbourTable,
    lanes: Lanes,
    out: &'a mut [Tile],
    box_min: &'a mut [f32],
    /// Compute the band mask from the input (stage 1) or read it (stages 2, 3).
    compute_mask: bool,
    activity: &'a mut [u32],
}

impl Sweep for TileSweep<'_> {
    fn run<K, M, const R: usize>(self, make: M) -> Result<(), EvolveError>
    where
        K: VoxelKernel,
        M: Fn(Range<usize>) -> K + Sync,
        Halo<R>: PointWindow,
    {
        match self.lanes {
            Lanes::Scalar => self.run_lanes::<f32, K, M, R>(make),
            Lanes::Simd => self.run_lanes::<DefaultLane, K, M, R>(make),
        }
    }
}

impl TileSweep<'_> {
    fn run_lanes<L: Lane, K, M, const R: usize>(self, make: M) -> Result<(), EvolveError>
    where
        K: VoxelKernel,
        M: Fn(Range<usize>) -> K + Sync,
    {
        let TileSweep { grid, table, out, box_min, compute_mask, activity, .. } = self;
        let gamma = grid.gamma();
        out.par_chunks_mut(TILE_CHUNK)
            .zip(box_min.par_chunks_mut(TILE_CHUNK * 64))
            .zip(activity.par_chunks_mut(TILE_CHUNK))
            .enumerate()
            .try_for_each(|(c, ((out, mask), act))| {
                let start = c * TILE_CHUNK;
                let mut block = PaddedBlock::<R>::new();
                for i in 0..out.len() {
                    let pos = start + i;
                    block.gather_row(grid, pos, table.row(pos));
                    let tb = TileBlock::<R>::new(block.data())?;
                    let m: &mut [f32; 64] = (&mut mask[64 * i..64 * i + 64])
                        .try_into()
                        .expect("64 mask values per tile");
                    if compute_mask {
                        tb.apply::<L, _>(&BoxMinAbs, m)?;
                    }
                    let k =
                        BandMasked { step: make(64 * pos..64 * pos + 64), box_min: &m[..], gamma };
                    tb.apply::<L, _>(&k, &mut out[i].0)?;
                    act[i] = compute_activity(&out[i], gamma);
                }
                Ok::<(), EvolveError>(())
            })
    }
}

/// The κ̄ integrands of one tile (both in one pass over the block).
#[inline(always)]
fn kappa_tile<L: Lane>(
    tb: &TileBlock<1>,
    inv_h: f32,
    width: f32,
    num: &mut [f32; 64],
    den: &mut [f32; 64],
) {
    tb.for_each::<L>(|first, w| {
        let (a, b) = kappa_terms(w, inv_h, width);
        a.store(&mut num[first..]);
        b.store(&mut den[first..]);
    });
}

fn tile_flat(t: &[Tile]) -> &[f32] {
    bytemuck::cast_slice(t)
}

impl Representation for TilesRep {
    fn spec(&self) -> GridSpec {
        *self.grid.spec()
    }

    fn flat(&self) -> &[f32] {
        tile_flat(self.grid.values())
    }

    fn fill_scalar(&self, f: &dyn ScalarFn, t: f64, out: &mut [f32]) {
        let spec = self.spec();
        let coords = self.grid.tile_coords();
        out.par_chunks_mut(64).zip(coords.par_iter()).for_each(|(o, &tc)| {
            for (row, o) in o.chunks_mut(4).enumerate() {
                let start = voxel_of(tc, 4 * row);
                f.fill_run(&spec, start, t, o);
            }
        });
    }

    fn fill_vector(&self, f: &dyn VectorFn, t: f64, out: [&mut [f32]; 3]) {
        let spec = self.spec();
        let coords = self.grid.tile_coords();
        let [u, v, w] = out;
        u.par_chunks_mut(64)
            .zip(v.par_chunks_mut(64))
            .zip(w.par_chunks_mut(64))
            .zip(coords.par_iter())
            .for_each(|(((u, v), w), &tc)| f.fill_tile(&spec, voxel_of(tc, 0), t, [u, v, w]));
    }

    fn stage(
        &mut self,
        p: &StageParams,
        scheme: SpatialScheme,
        last: bool,
    ) -> Result<(), EvolveError> {
        let n = self.grid.len();
        self.out.resize(n, Tile::splat(0.0));
        self.box_min.resize(64 * n, 0.0);
        self.activity.resize(n, 0);
        let p =
            StageParams { phi_n: if p.stage == 1 { &[] } else { tile_flat(&self.phi_n) }, ..*p };
        debug_assert_eq!(self.table.len(), n, "stale neighbour table");
        let sweep = TileSweep {
            grid: &self.grid,
            table: &self.table,
            lanes: self.lanes,
            out: &mut self.out,
            box_min: &mut self.box_min,
            compute_mask: p.stage == 1,
            activity: &mut self.activity,
        };
        dispatch(&p, scheme, sweep)?;
        self.grid.swap_values(&mut self.out, &self.activity)?;
        if p.stage == 1 && !last {
            // `out` now holds φⁿ: keep it for stages 2 and 3.
            std::mem::swap(&mut self.phi_n, &mut self.out);
        }
        Ok(())
    }

    fn rollback(&mut self) -> Result<(), EvolveError> {
        let g = self.grid.gamma();
        self.activity.clear();
        self.activity.extend(self.phi_n.iter().map(|t| compute_activity(t, g)));
        self.grid.swap_values(&mut self.phi_n, &self.activity)?;
        Ok(())
    }

    fn kappa_bar_sums(&self, width: f32) -> Result<(ExactSum, ExactSum), EvolveError> {
        let inv_h = 1.0 / self.grid.spec().voxel_size;
        let table = self.table();
        let n = self.grid.len();
        let lanes = self.lanes;
        let grid = &self.grid;
        let skip_inactive = width <= grid.gamma();
        let sums = (0..n.div_ceil(TILE_CHUNK))
            .into_par_iter()
            .map(|c| {
                let start = c * TILE_CHUNK;
                let end = (start + TILE_CHUNK).min(n);
                let mut block = PaddedBlock::<1>::new();
                let (mut num, mut den) = (ExactSum::default(), ExactSum::default());
                let (mut a, mut b) = ([0.0f32; 64], [0.0f32; 64]);
                for pos in start..end {
                    // A tile without band voxels holds only ±γ, where δ vanishes when
                    // its width does not exceed γ: its terms are exactly zero.
                    if skip_inactive && grid.activity_flags(pos) & ACTIVE_MASK == 0 {
                        continue;
                    }
                    block.gather_row(grid, pos, table.row(pos));
                    let tb = TileBlock::<1>::new(block.data())?;
                    match lanes {
                        Lanes::Scalar => kappa_tile::<f32>(&tb, inv_h, width, &mut a, &mut b),
                        Lanes::Simd => kappa_tile::<DefaultLane>(&tb, inv_h, width, &mut a, &mut b),
                    }
                    num.add_all(&a);
                    den.add_all(&b);
                }
                Ok::<_, EvolveError>((num, den))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(sums.into_iter().fold((ExactSum::default(), ExactSum::default()), |(a, b), (c, d)| {
            (a.merge(c), b.merge(d))
        }))
    }

    fn finish_step(&mut self) -> Result<(), EvolveError> {
        self.grid.manage_tiles()?;
        self.table.rebuild(self.grid.tile_coords());
        Ok(())
    }

    fn unstored_inside(&self) -> u64 {
        const PLUS_X: usize = crate::coord::direction_index(1, 0, 0);
        let coords = self.grid.tile_coords();
        let mut n = 0u64;
        for p in 1..coords.len() {
            let (a, b) = (coords[p - 1], coords[p]);
            if a.z == b.z
                && a.y == b.y
                && b.x > a.x + 1
                && self.grid.border_flags(p - 1) & (1 << PLUS_X) != 0
            {
                n += 64 * (b.x - a.x - 1) as u64;
            }
        }
        n
    }

    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        let g = self.grid.gamma();
        self.grid.for_each_voxel_sorted(|c, v| {
            if v.abs() < g {
                f(c, v)
            }
        });
    }

    fn value(&self, c: Coord) -> f32 {
        self.grid.value(c)
    }

    fn units(&self) -> usize {
        self.grid.len()
    }

    fn bytes(&self) -> usize {
        self.grid.memory().used()
    }

    fn work_bytes(&self) -> usize {
        self.grid.memory().slack
            + vec_bytes(&self.phi_n)
            + vec_bytes(&self.out)
            + vec_bytes(&self.box_min)
            + vec_bytes(&self.activity)
            + self.table.bytes()
    }
}

// ---------------------------------------------------------------------------------------
// DT-Grid.

/// The DT-Grid engine: the stencil iterator (DT-Grid paper Sec. 3.3) feeds the kernels
/// point by point, scalar and on one thread; after each step the grid is rebuilt
/// (Sec. 3.6.2) to the voxels within one voxel of the band, so it needs no band mask.
#[derive(Clone)]
pub(crate) struct DtRep {
    pub grid: DtGrid,
    phi_n: Vec<f32>,
    out: Vec<f32>,
    kept: DtGrid,
    next: DtGrid,
    box27: Stencil,
    box_far39: Stencil,
}

fn stencil_of(offsets: &[[i32; 3]]) -> Stencil {
    Stencil::new(offsets.iter().map(|o| Coord::new(o[0], o[1], o[2])).collect())
        .expect("non-empty stencil")
}

impl DtRep {
    pub fn new(grid: DtGrid) -> Self {
        let spec = grid.spec();
        DtRep {
            grid,
            phi_n: Vec::new(),
            out: Vec::new(),
            kept: DtGrid::new(spec),
            next: DtGrid::new(spec),
            box27: stencil_of(&BOX27_OFFSETS),
            box_far39: stencil_of(&BOX_FAR39_OFFSETS),
        }
    }
}

struct DtSweep<'a> {
    rep: &'a DtRep,
    out: &'a mut Vec<f32>,
}

impl Sweep for DtSweep<'_> {
    fn run<K, M, const R: usize>(self, make: M) -> Result<(), EvolveError>
    where
        K: VoxelKernel,
        M: Fn(Range<usize>) -> K + Sync,
        Halo<R>: PointWindow,
    {
        let n = self.rep.grid.len();
        let k = make(0..n);
        k.check(n)?;
        self.out.clear();
        self.out.resize(n, 0.0);
        let out = &mut self.out[..];
        let mut it = StencilIter::new(&self.rep.grid, <Halo<R>>::stencil(self.rep));
        while it.advance() {
            let i = it.center_index();
            out[i] = <Halo<R>>::eval(&k, it.values(), i);
        }
        Ok(())
    }
}

impl Representation for DtRep {
    fn spec(&self) -> GridSpec {
        self.grid.spec()
    }

    fn flat(&self) -> &[f32] {
        self.grid.values()
    }

    fn fill_scalar(&self, f: &dyn ScalarFn, t: f64, out: &mut [f32]) {
        let spec = self.spec();
        for_each_run(&self.grid, |i, start, len| f.fill_run(&spec, start, t, &mut out[i..i + len]));
    }

    fn fill_vector(&self, f: &dyn VectorFn, t: f64, out: [&mut [f32]; 3]) {
        let spec = self.spec();
        let [u, v, w] = out;
        for_each_run(&self.grid, |i, start, len| {
            let r = i..i + len;
            f.fill_run(&spec, start, t, [&mut u[r.clone()], &mut v[r.clone()], &mut w[r]]);
        });
    }

    fn stage(
        &mut self,
        p: &StageParams,
        scheme: SpatialScheme,
        last: bool,
    ) -> Result<(), EvolveError> {
        let mut out = std::mem::take(&mut self.out);
        let phi_n = std::mem::take(&mut self.phi_n);
        let stage = p.stage;
        let p = StageParams { phi_n: if stage == 1 { &[] } else { &phi_n }, ..*p };
        let r = dispatch(&p, scheme, DtSweep { rep: self, out: &mut out });
        self.phi_n = phi_n;
        r?;
        self.grid.swap_values(&mut out)?;
        if stage == 1 && !last {
            std::mem::swap(&mut self.phi_n, &mut out);
        }
        self.out = out;
        Ok(())
    }

    fn rollback(&mut self) -> Result<(), EvolveError> {
        self.grid.swap_values(&mut self.phi_n)?;
        Ok(())
    }

    fn kappa_bar_sums(&self, width: f32) -> Result<(ExactSum, ExactSum), EvolveError> {
        let inv_h = 1.0 / self.grid.spec().voxel_size;
        let (mut num, mut den) = (ExactSum::default(), ExactSum::default());
        let mut it = StencilIter::new(&self.grid, &self.box27);
        while it.advance() {
            let v: &[f32; 27] = it.values().try_into().expect("27 values");
            let (a, b) = kappa_terms::<f32, _>(&BoxWindow::new(v), inv_h, width);
            num.add(a);
            den.add(b);
        }
        Ok((num, den))
    }

    fn finish_step(&mut self) -> Result<(), EvolveError> {
        // Sec. 3.6.2: keep the band (|φ| < γ), dilate it by one voxel; new points read ±γ.
        self.grid.rebuild_into(self.grid.gamma(), 1, &mut self.kept, &mut self.next)?;
        std::mem::swap(&mut self.grid, &mut self.next);
        Ok(())
    }

    fn unstored_inside(&self) -> u64 {
        let mut n = 0u64;
        let mut prev: Option<(Coord, f32)> = None;
        for (c, v) in self.grid.iter() {
            if let Some((p, pv)) = prev {
                if p.z == c.z && p.y == c.y && c.x > p.x + 1 && pv < 0.0 {
                    n += (c.x as i64 - p.x as i64 - 1) as u64;
                }
            }
            prev = Some((c, v));
        }
        n
    }

    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        let g = self.grid.gamma();
        for (c, v) in self.grid.iter() {
            if v.abs() < g {
                f(c, v);
            }
        }
    }

    fn value(&self, c: Coord) -> f32 {
        self.grid.value(c)
    }

    fn units(&self) -> usize {
        self.grid.len()
    }

    fn bytes(&self) -> usize {
        self.grid.memory().used()
    }

    fn work_bytes(&self) -> usize {
        self.grid.memory().slack
            + vec_bytes(&self.phi_n)
            + vec_bytes(&self.out)
            + self.kept.memory().total()
            + self.next.memory().total()
    }
}

/// Calls `f(first point index, first voxel, length)` for every x-run of consecutive
/// points of a DT-Grid (its connected components, Sec. 2.1).
fn for_each_run(g: &DtGrid, mut f: impl FnMut(usize, Coord, usize)) {
    let mut run: Option<(usize, Coord, usize)> = None;
    for (i, (c, _)) in g.iter().enumerate() {
        match &mut run {
            Some((_, s, len))
                if s.z == c.z && s.y == c.y && s.x as i64 + *len as i64 == c.x as i64 =>
            {
                *len += 1
            }
            _ => {
                if let Some((i0, s, len)) = run {
                    f(i0, s, len);
                }
                run = Some((i, c, 1));
            }
        }
    }
    if let Some((i0, s, len)) = run {
        f(i0, s, len);
    }
}

// ---------------------------------------------------------------------------------------
// Dense reference.

/// The dense reference: every voxel of a box, the same kernels over a padded copy, the
/// band mask of [`BandMasked`]. For tests on small grids. The box must keep a margin of
/// four voxels around the band ([`EvolveError::DenseBoxTooSmall`] otherwise).
#[derive(Clone)]
pub(crate) struct DenseRep {
    pub field: DenseField,
    pub spec: GridSpec,
    phi_n: Vec<f32>,
    out: Vec<f32>,
    box_min: Vec<f32>,
    padded: Vec<f32>,
}

/// Band voxels must stay this far from the dense box's faces.
const DENSE_MARGIN: usize = 4;

impl DenseRep {
    pub fn new(field: DenseField, spec: GridSpec) -> Result<Self, EvolveError> {
        let rep = DenseRep {
            field,
            spec,
            phi_n: Vec::new(),
            out: Vec::new(),
            box_min: Vec::new(),
            padded: Vec::new(),
        };
        rep.check_margin()?;
        Ok(rep)
    }

    fn check_margin(&self) -> Result<(), EvolveError> {
        let g = self.spec.gamma();
        let [nx, ny, nz] = self.field.dims();
        let o = self.field.origin();
        let near = |v: usize, n: usize| v < DENSE_MARGIN || v + DENSE_MARGIN >= n;
        for (i, &v) in self.field.data().iter().enumerate() {
            if v.abs() < g {
                let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
                if near(x, nx) || near(y, ny) || near(z, nz) {
                    return Err(EvolveError::DenseBoxTooSmall {
                        voxel: Coord::new(o.x + x as i32, o.y + y as i32, o.z + z as i32),
                    });
                }
            }
        }
        Ok(())
    }
}

/// Copies `field` into `padded` with an `R`-voxel halo that repeats the faces (the far
/// field beyond the box keeps the sign and value of the box's face).
fn pad_into<const R: usize>(field: &DenseField, padded: &mut Vec<f32>) {
    let [nx, ny, nz] = field.dims();
    let len = DenseBlock::<R>::padded_len([nx, ny, nz]).expect("the dense field fits in memory");
    padded.resize(len, 0.0);
    let d = field.data();
    let r = R as isize;
    let clamp = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
    for z in -r..nz as isize + r {
        for y in -r..ny as isize + r {
            for x in -r..nx as isize + r {
                let src = clamp(x, nx) + nx * (clamp(y, ny) + ny * clamp(z, nz));
                padded[DenseBlock::<R>::index([nx, ny, nz], x, y, z)] = d[src];
            }
        }
    }
}

struct DenseSweep<'a> {
    rep: &'a mut DenseRep,
    compute_mask: bool,
}

impl Sweep for DenseSweep<'_> {
    fn run<K, M, const R: usize>(self, make: M) -> Result<(), EvolveError>
    where
        K: VoxelKernel,
        M: Fn(Range<usize>) -> K + Sync,
        Halo<R>: PointWindow,
    {
        let rep = self.rep;
        let dims = rep.field.dims();
        let n = rep.field.data().len();
        if self.compute_mask {
            pad_into::<1>(&rep.field, &mut rep.padded);
            rep.box_min.resize(n, 0.0);
            DenseBlock::<1>::new(&rep.padded, dims)?
                .apply::<f32, _>(&BoxMinAbs, &mut rep.box_min)?;
        }
        pad_into::<R>(&rep.field, &mut rep.padded);
        let k = BandMasked { step: make(0..n), box_min: &rep.box_min, gamma: rep.spec.gamma() };
        rep.out.resize(n, 0.0);
        DenseBlock::<R>::new(&rep.padded, dims)?.apply::<f32, _>(&k, &mut rep.out)?;
        Ok(())
    }
}

impl Representation for DenseRep {
    fn spec(&self) -> GridSpec {
        self.spec
    }

    fn flat(&self) -> &[f32] {
        self.field.data()
    }

    fn fill_scalar(&self, f: &dyn ScalarFn, t: f64, out: &mut [f32]) {
        let nx = self.field.dims()[0];
        let o = self.field.origin();
        for (row, chunk) in out.chunks_mut(nx).enumerate() {
            let c = self.field.coord_of(row * nx).expect("row inside the box");
            debug_assert_eq!(c.x, o.x);
            f.fill_run(&self.spec, c, t, chunk);
        }
    }

    fn fill_vector(&self, f: &dyn VectorFn, t: f64, out: [&mut [f32]; 3]) {
        let nx = self.field.dims()[0];
        let [u, v, w] = out;
        for (row, ((u, v), w)) in
            u.chunks_mut(nx).zip(v.chunks_mut(nx)).zip(w.chunks_mut(nx)).enumerate()
        {
            let c = self.field.coord_of(row * nx).expect("row inside the box");
            f.fill_run(&self.spec, c, t, [u, v, w]);
        }
    }

    fn stage(
        &mut self,
        p: &StageParams,
        scheme: SpatialScheme,
        last: bool,
    ) -> Result<(), EvolveError> {
        let phi_n = std::mem::take(&mut self.phi_n);
        let stage = p.stage;
        let p = StageParams { phi_n: if stage == 1 { &[] } else { &phi_n }, ..*p };
        let r = dispatch(&p, scheme, DenseSweep { rep: self, compute_mask: stage == 1 });
        self.phi_n = phi_n;
        r?;
        let data = self.field.data_mut();
        if stage == 1 && !last {
            self.phi_n.clear();
            self.phi_n.extend_from_slice(data);
        }
        data.copy_from_slice(&self.out);
        Ok(())
    }

    fn rollback(&mut self) -> Result<(), EvolveError> {
        self.field.data_mut().copy_from_slice(&self.phi_n);
        Ok(())
    }

    fn kappa_bar_sums(&self, width: f32) -> Result<(ExactSum, ExactSum), EvolveError> {
        let inv_h = 1.0 / self.spec.voxel_size;
        let mut padded = Vec::new();
        pad_into::<1>(&self.field, &mut padded);
        let block = DenseBlock::<1>::new(&padded, self.field.dims())?;
        let mut a = vec![0.0; self.field.data().len()];
        let mut b = a.clone();
        block.apply::<f32, _>(&KappaBarTerm::<true> { inv_h, width }, &mut a)?;
        block.apply::<f32, _>(&KappaBarTerm::<false> { inv_h, width }, &mut b)?;
        let (mut num, mut den) = (ExactSum::default(), ExactSum::default());
        num.add_all(&a);
        den.add_all(&b);
        Ok((num, den))
    }

    fn finish_step(&mut self) -> Result<(), EvolveError> {
        self.check_margin()
    }

    fn unstored_inside(&self) -> u64 {
        0
    }

    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        let g = self.spec.gamma();
        self.field.for_each(|c, v| {
            if v.abs() < g {
                f(c, v)
            }
        });
    }

    fn value(&self, c: Coord) -> f32 {
        self.field.get(c).unwrap_or(self.spec.gamma())
    }

    fn units(&self) -> usize {
        self.field.data().len()
    }

    fn bytes(&self) -> usize {
        self.field.data().len() * 4
    }

    fn work_bytes(&self) -> usize {
        vec_bytes(&self.phi_n)
            + vec_bytes(&self.out)
            + vec_bytes(&self.box_min)
            + vec_bytes(&self.padded)
    }
}
