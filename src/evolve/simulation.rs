//! [`Simulation`]: one level set evolving under a [`Flow`] on one representation, one
//! atomic step at a time.

use super::dispatch::{anchors_stored, RenormParams, StageParams};
use super::inputs::Inputs;
use super::rep::{DenseRep, DtRep, MemoryBudget, Rep, TilesRep};
use super::{
    in_pool, in_worker, EvolveError, Flow, GridKind, Integrator, Measures, Renormalization,
    Settings, StepReport, Sweeps, TimeStep, Velocity, DENSE_MARGIN,
};
use crate::coord::Coord;
use crate::distributed::{Comm, HaloStats, RankPart, Transport};
use crate::exact::ExactSum;
use crate::grid::MemoryReport;
use crate::grid::{GridError, GridSpec};
use crate::storage::dense::DenseField;
use crate::storage::dtgrid::DtGrid;
use crate::storage::levelset::{Accessor, LevelSet};
use crate::storage::shapes::Shape;
use crate::storage::tiles::TileGrid;
use levelset_kernels::rk::{cfl_dt_renorm, cfl_rate_advection, cfl_rate_eq3, cfl_rate_image};
use std::sync::Arc;

/// A level set evolving under a [`Flow`] on one representation.
///
/// # Atomic steps
/// [`Simulation::step`], [`Simulation::step_until`] and [`Simulation::run_until`] either
/// take a whole step — every stage, the band maintenance (tile management, DT-Grid
/// rebuild), the collapse test and a due reinitialisation — or fail and leave the
/// simulation exactly as before the step: values, stored tiles or points, flags, time,
/// step count and the collapsed flag. Nothing is copied for this: the double buffer the
/// first stage swaps out of the grid still holds φⁿ, and the tile list or DT-Grid the
/// band maintenance replaces is kept until the step stands.
#[derive(Clone)]
pub struct Simulation {
    rep: Rep,
    kind: GridKind,
    flow: Flow,
    settings: Settings,
    time: f64,
    steps: u64,
    collapsed: bool,
    /// Per-voxel F and u of the current stage (scratch: every step samples them anew).
    inputs: Inputs,
}

/// Values per parallel task of [`Simulation::measure`]'s sums (64 tiles).
const MEASURE_CHUNK: usize = 4096;

impl Simulation {
    /// A simulation of the band of an analytic shape on representation `kind` (the dense
    /// reference gets the band's bounding box with a margin of [`DENSE_MARGIN`] voxels).
    pub fn from_shape(
        kind: GridKind,
        shape: &Shape,
        spec: GridSpec,
        flow: Flow,
        settings: Settings,
    ) -> Result<Simulation, EvolveError> {
        let tiles = crate::storage::convert::tiles_from_shape(shape, spec)?;
        Simulation::from_tile_grid(kind, tiles, flow, settings)
    }

    /// A simulation starting from a tile grid, converted to representation `kind` (the
    /// dense reference gets the grid's bounding box with a margin of [`DENSE_MARGIN`]
    /// voxels).
    pub fn from_tile_grid(
        kind: GridKind,
        tiles: TileGrid,
        flow: Flow,
        settings: Settings,
    ) -> Result<Simulation, EvolveError> {
        let spec = *tiles.spec();
        let rep = match kind {
            GridKind::Tiles(lanes) => {
                Rep::Tiles(in_pool(&settings.pool, || TilesRep::new(tiles, lanes)))
            }
            GridKind::DtGrid => {
                Rep::DtGrid(Box::new(DtRep::new(crate::storage::convert::dtgrid_from(&tiles))))
            }
            GridKind::Dense => {
                let (lo, hi) = tiles.bounding_box().ok_or(EvolveError::EmptyLevelSet)?;
                let (origin, dims) = crate::storage::convert::margin_box(lo, hi, DENSE_MARGIN);
                let field = crate::storage::convert::to_dense(&tiles, origin, dims)?;
                Rep::Dense(DenseRep::new(field, spec)?)
            }
        };
        Simulation::start(rep, kind, flow, settings)
    }

    /// One rank's part of a simulation distributed over the ranks of `transport`
    /// ([`crate::distributed`]): every rank passes the same whole band `tiles`, keeps the
    /// z-slabs of tiles the balanced cuts give it (and one ghost slab on either side) and
    /// runs the tile engine with `lanes` on them. Every rank must call this and then the
    /// same methods in the same order: steps, [`Simulation::measure`],
    /// [`Simulation::checksum`], [`Simulation::band_voxels`] and
    /// [`Simulation::stored_voxels`] are collective and return the whole band's figures
    /// on every rank, equal to the single-process run's bit for bit. After a step, when
    /// the largest rank holds more than (1 + `rebalance`) × the smallest rank's tiles,
    /// the cuts move (`None`: never). Periodic reinitialisation by fast marching
    /// ([`Settings::reinit`]) is refused: the march is not distributed.
    pub fn distributed(
        transport: Arc<dyn Transport>,
        tiles: TileGrid,
        lanes: super::Lanes,
        flow: Flow,
        settings: Settings,
        rebalance: Option<f64>,
    ) -> Result<Simulation, EvolveError> {
        if settings.reinit.is_some() {
            return Err(EvolveError::InvalidParameter(
                "reinitialisation by fast marching is not distributed: use the \
                 renormalisation sweeps"
                    .into(),
            ));
        }
        if let Some(r) = rebalance.filter(|r| !(r.is_finite() && *r >= 0.0)) {
            return Err(EvolveError::InvalidParameter(format!(
                "the rebalancing threshold must be finite and ≥ 0, got {r}"
            )));
        }
        let comm = Arc::new(Comm::new(transport));
        let (part, local) = in_pool(&settings.pool, || RankPart::split(comm, &tiles, rebalance))?;
        drop(tiles);
        let rep = in_pool(&settings.pool, || TilesRep::distributed(local, lanes, part));
        Simulation::start(Rep::Tiles(rep), GridKind::Tiles(lanes), flow, settings)
    }

    /// The distributed run's side of the simulation (this rank, the cuts, the exchange
    /// statistics); `None` when the simulation is not distributed.
    pub fn distribution(&self) -> Option<Distribution<'_>> {
        match &self.rep {
            Rep::Tiles(t) if t.cuts().is_some() => Some(Distribution { sim: self }),
            _ => None,
        }
    }

    /// A simulation starting from a DT-Grid (kept as a DT-Grid).
    pub fn from_dtgrid(
        grid: DtGrid,
        flow: Flow,
        settings: Settings,
    ) -> Result<Simulation, EvolveError> {
        Simulation::start(Rep::DtGrid(Box::new(DtRep::new(grid))), GridKind::DtGrid, flow, settings)
    }

    /// A simulation starting from a dense field (φ < 0 inside, world units, values
    /// clamped to ±γ), on representation `kind`. ±∞ is a far-away distance (clamped like
    /// any value beyond ±γ, the rule of [`crate::io::input`]); NaN is an error.
    pub fn from_dense(
        kind: GridKind,
        field: &DenseField,
        spec: GridSpec,
        flow: Flow,
        settings: Settings,
    ) -> Result<Simulation, EvolveError> {
        if let Some(i) = crate::storage::dense::first_position(field.data(), |v| v.is_nan()) {
            let coord = field.coord_of(i).unwrap_or_default();
            return Err(EvolveError::Grid(crate::GridError::NaN { coord }));
        }
        match kind {
            GridKind::Dense => {
                let g = spec.gamma();
                let mut f = field.clone();
                f.data_mut().iter_mut().for_each(|v| *v = v.clamp(-g, g));
                Simulation::start(Rep::Dense(DenseRep::new(f, spec)?), kind, flow, settings)
            }
            _ => {
                let tiles = crate::storage::convert::tiles_from_dense(field, spec)?;
                Simulation::from_tile_grid(kind, tiles, flow, settings)
            }
        }
    }

    /// The checks of `flow` and `settings` that every constructor runs before it starts
    /// (parameters in their domains, a lattice the flow supports): for a caller that has
    /// work to do before it builds the grid, so that bad parameters are refused first.
    pub fn check(flow: &Flow, settings: &Settings) -> Result<(), EvolveError> {
        flow.validate()?;
        settings.validate(flow)
    }

    fn start(
        rep: Rep,
        kind: GridKind,
        flow: Flow,
        settings: Settings,
    ) -> Result<Simulation, EvolveError> {
        Simulation::check(&flow, &settings)?;
        if settings.reinit.is_some() && kind == GridKind::Dense {
            return Err(EvolveError::InvalidParameter(
                "reinitialisation by fast marching runs on the sparse grids (tiles, DT-Grid), \
                 not on the dense reference"
                    .into(),
            ));
        }
        let mut rep = rep;
        rep.take_settings(&settings);
        let mut sim = Simulation {
            rep,
            kind,
            flow,
            settings,
            time: 0.0,
            steps: 0,
            collapsed: false,
            inputs: Inputs::default(),
        };
        let g = sim.spec().gamma();
        let rep = sim.rep.get();
        let band = rep.owned_flat().iter().any(|v| v.abs() < g);
        if !rep.comm().map_or(band, |c| c.any(band)) {
            return Err(EvolveError::EmptyLevelSet);
        }
        // Bring the initial band to the band rule: every voxel within one voxel of the
        // band stored (tile management, DT-Grid rebuild).
        let budget = sim.budget();
        let rep = sim.rep.get_mut();
        in_pool(&sim.settings.pool, || rep.finish_step(&budget))?;
        Ok(sim)
    }

    /// The grid's voxel size, origin and band half-width.
    pub fn spec(&self) -> GridSpec {
        self.rep.get().spec()
    }

    /// The representation this simulation runs on.
    pub fn kind(&self) -> GridKind {
        self.kind
    }

    pub fn flow(&self) -> &Flow {
        &self.flow
    }

    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Simulated time.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Whether the interface has collapsed: no interface is left as seen from the band
    /// (see [`Simulation::step`]).
    pub fn collapsed(&self) -> bool {
        self.collapsed
    }

    /// The memory budget of [`Settings::memory_limit`].
    fn budget(&self) -> MemoryBudget {
        MemoryBudget {
            limit: self.settings.memory_limit,
            keeps: super::step_keeps(self.settings.integrator, self.settings.renormalization),
            held: self.inputs.bytes() as u64,
        }
    }

    /// The sweeps of the renormalisation due after step `step` (1-based), if any.
    fn renorm_due(&self, step: u64) -> Option<Sweeps> {
        match self.settings.renormalization {
            Renormalization::Sweeps(s) if step.is_multiple_of(s.every) => Some(s),
            _ => None,
        }
    }

    /// The parameters of a renormalisation by `s`.
    fn renorm_params(&self, s: &Sweeps) -> RenormParams {
        let spec = self.spec();
        RenormParams {
            scheme: s.scheme,
            dtau: cfl_dt_renorm(spec.voxel_size, s.cfl),
            gamma: spec.gamma(),
            h: spec.voxel_size,
            sweeps: s.sweeps,
        }
    }

    /// Renormalises the band now: `sweeps.sweeps` pseudo-time sweeps of
    /// φ_τ = sgn(φ⁰)(1 − |∇φ|) with Godunov upwinding (first order or HJ-WENO5) and the
    /// subcell fix of Russo & Smereka (J. Comput. Phys. 163 (2000)) at the voxels next
    /// to the interface (φ⁰ is the band before the first sweep), forward Euler with
    /// Δτ = cfl · h/√3, over the voxels within one voxel of the band (the band rule),
    /// then the band maintenance. The zero crossings stay where they are (to the
    /// accuracy of the subcell fix's distance estimate); the band moves towards
    /// |∇φ| = 1 by about `sweeps` · Δτ of distance from the interface, so a band far
    /// from a distance needs several calls (each may widen the band by one voxel).
    /// `sweeps.every` is ignored. Atomic: on an error nothing changes.
    pub fn renormalize(&mut self, sweeps: &Sweeps) -> Result<(), EvolveError> {
        super::Renormalization::Sweeps(Sweeps { every: 1, ..*sweeps }).validate()?;
        if self.settings.lattice.is_some() {
            return Err(EvolveError::InvalidParameter(
                "renormalisation sweeps are isotropic: not on a lattice".into(),
            ));
        }
        if self.collapsed {
            return Err(EvolveError::Collapsed { step: self.steps, time: self.time });
        }
        let anchors = anchors_stored(sweeps.sweeps);
        let keeps = super::StepKeeps { phi_n: true, anchors, rk3: false, euler: false };
        let budget = MemoryBudget { keeps, ..self.budget() };
        let rep = self.rep.get();
        let admitted =
            budget.admit(rep.step_bytes(keeps), self.rep_bytes(), "the renormalisation's buffers");
        self.agree(admitted.map_err(EvolveError::from))?;
        let p = self.renorm_params(sweeps);
        let pool = self.settings.pool.clone();
        let rep = self.rep.get_mut();
        let r = in_pool(&pool, || {
            rep.renormalize(&p, true)?;
            rep.finish_step(&budget)
        });
        match r {
            Ok(()) => {
                rep.commit_step();
                Ok(())
            }
            Err(e) => {
                if let Some(c) = rep.comm() {
                    c.abort(&format!("renormalisation: {e}"));
                }
                rep.undo_step();
                Err(e)
            }
        }
    }

    /// Bytes of the representation and its buffers now.
    fn rep_bytes(&self) -> u64 {
        let rep = self.rep.get();
        (rep.bytes() + rep.work_bytes()) as u64
    }

    /// Reinitialises the band to a signed distance by fast marching
    /// ([`crate::tools::fmm::reinitialize`], the same values on both grids), keeping the half-width, then brings the band to the band rule
    /// again. The interface stays where it is (its voxels keep their distance estimates);
    /// the rest of the band becomes an exact marched distance. Sparse grids only. On an
    /// error (including a second band that [`Settings::memory_limit`] does not admit) the
    /// simulation is unchanged.
    pub fn reinitialize(&mut self, order: crate::tools::fmm::Order) -> Result<(), EvolveError> {
        if self.rep.get().comm().is_some() {
            return Err(EvolveError::InvalidParameter(
                "reinitialisation by fast marching is not distributed".into(),
            ));
        }
        self.rep = self.reinitialized(order)?;
        Ok(())
    }

    /// The current band reinitialised (see [`Simulation::reinitialize`]), as a new
    /// representation: the current one is not touched.
    fn reinitialized(&self, order: crate::tools::fmm::Order) -> Result<Rep, EvolveError> {
        let opts = crate::tools::fmm::FmmOptions { order, ..Default::default() };
        let pool = &self.settings.pool;
        let budget = self.budget();
        // The new band is built next to the current one: the marched band and the grid
        // built from it, about twice the current grid's bytes.
        let current = self.rep_bytes();
        let needed = current + 2 * self.rep.get().bytes() as u64;
        budget.admit(needed, current, "the reinitialised band")?;
        let mut rep = match &self.rep {
            Rep::Tiles(t) => {
                let grid = in_pool(pool, || crate::tools::fmm::reinitialize(&t.grid, &opts))?;
                Rep::Tiles(in_pool(pool, || TilesRep::new(grid, t.lanes)))
            }
            Rep::DtGrid(d) => {
                let grid = crate::storage::convert::dtgrid_from(&crate::tools::fmm::reinitialize(
                    &d.grid, &opts,
                )?);
                Rep::DtGrid(Box::new(DtRep::new(grid)))
            }
            Rep::Dense(_) => {
                return Err(EvolveError::InvalidParameter(
                    "reinitialisation by fast marching runs on the sparse grids".into(),
                ))
            }
        };
        rep.take_settings(&self.settings);
        let r = rep.get_mut();
        in_pool(pool, || r.finish_step(&budget))?;
        Ok(rep)
    }

    /// The tile grid, when running on tiles.
    pub fn tiles(&self) -> Option<&TileGrid> {
        match &self.rep {
            Rep::Tiles(t) => Some(&t.grid),
            _ => None,
        }
    }

    /// The whole band as one tile grid, on every rank: when distributed, the ranks' own
    /// tiles gathered (collective: every rank must call it), equal to the single-process
    /// run's grid; a copy of the tile grid otherwise; `None` on a DT-Grid or a dense box.
    pub fn gathered_tiles(&self) -> Result<Option<TileGrid>, EvolveError> {
        let r = match &self.rep {
            Rep::Tiles(t) => t.gather().map(Some).map_err(EvolveError::from),
            _ => Ok(None),
        };
        self.agree(r)
    }

    /// The DT-Grid, when running on a DT-Grid.
    pub fn dtgrid(&self) -> Option<&DtGrid> {
        match &self.rep {
            Rep::DtGrid(t) => Some(&t.grid),
            _ => None,
        }
    }

    /// Value at any voxel.
    pub fn value(&self, c: Coord) -> f32 {
        self.rep.get().value(c)
    }

    /// The current values as a dense field over `origin .. origin + dims`.
    pub fn to_dense(&self, origin: Coord, dims: [usize; 3]) -> Result<DenseField, GridError> {
        match self.tiles() {
            // Row by row on tiles (the same values, one tile search per row).
            Some(grid) => crate::storage::convert::to_dense(grid, origin, dims),
            None => DenseField::from_fn(origin, dims, |c| self.value(c)),
        }
    }

    /// Band voxels (|φ| < γ); the whole band's when distributed (collective).
    pub fn band_voxels(&self) -> usize {
        let g = self.spec().gamma();
        let rep = self.rep.get();
        // At the CPU's instruction-set level: a vectorised count of the whole band.
        let n = levelset_kernels::dispatch_one(BandCount { values: rep.owned_flat(), gamma: g });
        self.sum_counts([n as u64])[0] as usize
    }

    /// Bytes held now (collective when distributed): the representation's
    /// ([`Measures::bytes`]) and its step buffers' with the flow's per-voxel inputs
    /// ([`Measures::work_bytes`]), without the band's sums [`Simulation::measure`] makes.
    pub fn held_bytes(&self) -> [usize; 2] {
        self.sum_counts(self.local_bytes()).map(|b| b as usize)
    }

    /// This rank's part of [`Simulation::held_bytes`].
    fn local_bytes(&self) -> [u64; 2] {
        let rep = self.rep.get();
        [rep.bytes() as u64, (rep.work_bytes() + self.inputs.bytes()) as u64]
    }

    /// Voxels a stage computes: stored voxels (tile padding included; the ranks' own
    /// tiles when distributed, collective).
    pub fn stored_voxels(&self) -> usize {
        self.sum_counts([self.rep.get().owned_flat().len() as u64])[0] as usize
    }

    /// Counts summed over the ranks (as they are when not distributed).
    fn sum_counts<const N: usize>(&self, v: [u64; N]) -> [u64; N] {
        self.rep.get().comm().map_or(v, |c| c.sum_u64(v))
    }

    /// A result agreed on by every rank (as it is when not distributed): when one rank
    /// fails, every rank fails, the others with [`EvolveError::OtherRank`].
    fn agree<T>(&self, r: Result<T, EvolveError>) -> Result<T, EvolveError> {
        match self.rep.get().comm() {
            None => r,
            Some(c) => match c.agree(r) {
                Ok(r) => r,
                Err((rank, message)) => Err(EvolveError::OtherRank { rank, message }),
            },
        }
    }

    /// Inclusive bounding box of the band voxels (`None` when there are none).
    pub fn band_bounding_box(&self) -> Option<(Coord, Coord)> {
        let mut b: Option<(Coord, Coord)> = None;
        self.for_each_band_voxel(|c, _| {
            b = Some(match b {
                None => (c, c),
                Some((lo, hi)) => (
                    Coord::new(lo.x.min(c.x), lo.y.min(c.y), lo.z.min(c.z)),
                    Coord::new(hi.x.max(c.x), hi.y.max(c.y), hi.z.max(c.z)),
                ),
            })
        });
        b
    }

    /// Visits the band voxels (|φ| < γ) in [`Coord`] order (this rank's own when
    /// distributed).
    pub fn for_each_band_voxel(&self, mut f: impl FnMut(Coord, f32)) {
        self.rep.get().for_each_band_voxel(&mut f)
    }

    /// Visits every voxel with φ ≤ 0 — the stored ones one at a time, the interior the
    /// representation does not store as x-runs — as `(first voxel, run length)`, in no
    /// particular order: region integrals over the inside (a segmentation's region means)
    /// in O(stored voxels + interior runs). The unstored interior is the runs between the
    /// stored voxels of a row: an inside that goes on beyond a row's first or last stored
    /// voxel (without end) is not visited; [`Simulation::fold_inside`] counts it within a
    /// given x range.
    pub fn for_each_inside_run(&self, mut f: impl FnMut(Coord, u32)) {
        let rep = self.rep.get();
        rep.any_voxel(&mut |c, v| {
            if v <= 0.0 {
                f(c, 1);
            }
            false
        });
        rep.for_each_unstored_inside_run(&mut f);
    }

    /// The voxels of [`Simulation::for_each_inside_run`] folded over the thread pool
    /// ([`Settings::pool`]). On tiles, each stored tile comes whole, as the mask of its
    /// voxels with φ ≤ 0 (bit `l` for voxel `l` of the tile, x fastest; on a planar
    /// lattice the first z-slice only, the low 16 bits) given to `tile` with the tile's
    /// first voxel, and the unstored interior as x-runs given to `run`: between the tiles
    /// of a row, and, within `span` (voxel x), before a row's first tile and after its
    /// last where the band's border flags say the inside goes on there (where
    /// [`crate::storage::tiles::TileGrid::value`] reads −γ: a region that meets the image's
    /// x faces away from the band). Other representations give every voxel as a run, in
    /// one part (with their own rule for what lies beyond the band). Every part of the band
    /// folds into its own `identity()`, and `combine` joins the parts. Neither the parts,
    /// nor the order of the tiles and runs, nor the grouping of `combine` is fixed (they
    /// follow the thread count), so the result is deterministic when the callbacks and
    /// `combine` commute exactly: counts and integer sums, or [`crate::exact::ExactSum`].
    pub fn fold_inside<T: Send>(
        &self,
        span: std::ops::Range<i32>,
        identity: impl Fn() -> T + Sync + Send,
        tile: impl Fn(&mut T, Coord, u64) + Sync + Send,
        run: impl Fn(&mut T, Coord, u32) + Sync + Send,
        combine: impl Fn(T, T) -> T + Sync + Send,
    ) -> T {
        match &self.rep {
            Rep::Tiles(t) => super::in_pool(&self.settings.pool, || {
                t.fold_inside(span, &identity, &tile, &run, &combine)
            }),
            _ => {
                let mut acc = identity();
                self.for_each_inside_run(|c, len| run(&mut acc, c, len));
                acc
            }
        }
    }

    /// FNV-1a over the band voxels' coordinates and value bits in [`Coord`] order: equal
    /// band contents give equal checksums, whatever the representation. Distributed, the
    /// ranks hash their parts in turn (rank order is [`Coord`] order), so the checksum is
    /// the single-process one (collective).
    pub fn checksum(&self) -> u64 {
        let hash = |mut h: u64| {
            let mut eat = |bytes: [u8; 4]| {
                for b in bytes {
                    h ^= b as u64;
                    h = h.wrapping_mul(0x0000_0100_0000_01b3);
                }
            };
            self.for_each_band_voxel(|c, v| {
                eat(c.x.to_le_bytes());
                eat(c.y.to_le_bytes());
                eat(c.z.to_le_bytes());
                eat(v.to_bits().to_le_bytes());
            });
            h
        };
        const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
        match self.rep.get().comm() {
            None => hash(FNV_OFFSET),
            Some(c) => c.chain(FNV_OFFSET, hash),
        }
    }

    /// Band voxels, storage, volume and area of the current state (of the whole band, on
    /// every rank, when distributed: collective). Fails when the area's sums cannot be
    /// computed (a kernel refused its block).
    pub fn measure(&self) -> Result<Measures, EvolveError> {
        let rep = self.rep.get();
        let spec = self.spec();
        let lattice = self.settings.lattice;
        let h = lattice.map_or(spec.voxel_size, |l| l.min_spacing());
        let g = spec.gamma();
        let width = self.settings.delta_width * h;
        // Exact sums: the same over any split of the band between threads.
        let flat_inside = in_pool(&self.settings.pool, || {
            use rayon::prelude::*;
            rep.owned_flat()
                .par_chunks(MEASURE_CHUNK)
                .map(|c| {
                    let mut inside = ExactSum::default();
                    c.iter().for_each(|&v| inside.add((0.5 - v / h).clamp(0.0, 1.0)));
                    inside
                })
                .reduce(ExactSum::default, ExactSum::merge)
        });
        let band = levelset_kernels::dispatch_one(BandCount { values: rep.owned_flat(), gamma: g });
        let unstored = rep.unstored_inside();
        let flat_inside = rep.comm().map_or(flat_inside, |c| c.sum_exact([flat_inside])[0]);
        let [held, work] = self.local_bytes();
        let [band, unstored, stored, bytes, work_bytes] =
            self.sum_counts([band as u64, unstored, rep.units() as u64, held, work]);
        let h3 = lattice.map_or((h as f64).powi(3), |l| l.voxel_volume());
        let area = match lattice {
            // The δ integral's gradient is isotropic.
            Some(_) => f64::NAN,
            None => {
                let (_, den) = in_pool(&self.settings.pool, || rep.kappa_bar_sums(width))?;
                // The sums hold δ|∇φ|·h (see `KappaBarTerm`): area = h³ Σ δ|∇φ| = h² Σ den.
                h3 / h as f64 * den.value()
            }
        };
        Ok(Measures {
            band_voxels: band as usize,
            stored: stored as usize,
            volume: h3 * (flat_inside.value() + unstored as f64),
            area,
            bytes: bytes as usize,
            work_bytes: work_bytes as usize,
        })
    }

    /// The largest stable Δt for the current state (CFL number 1), given the largest |F|,
    /// |u|₁ and curvature weight over the band voxels: the rates of eq. (3) and of
    /// advection add up (see [`levelset_kernels::rk`]; on a lattice
    /// [`levelset_kernels::rk::cfl_rate_image`]).
    fn stability_limit(&self, max_f: f32, max_u: f32, eps: f32) -> f32 {
        let h = self.spec().voxel_size;
        let w = self.settings.renormalization.coupled_weight();
        let rate = match &self.settings.lattice {
            Some(l) => cfl_rate_image(max_f, eps, w, max_u, l.inv_spacing()),
            None => cfl_rate_eq3(max_f, eps, w, h) + cfl_rate_advection(max_u, h),
        };
        if rate > 0.0 {
            1.0 / rate
        } else {
            f32::INFINITY
        }
    }

    /// One time step; see [`Simulation::step_until`].
    pub fn step(&mut self) -> Result<StepReport, EvolveError> {
        self.step_until(f64::INFINITY)
    }

    /// Steps until `time` is reached (the last step lands on it exactly), the interface
    /// collapses, or `max_steps` steps were taken; calls `each` after every step. On an
    /// error the failed step is undone: the simulation holds the state after the last
    /// step that succeeded.
    pub fn run_until(
        &mut self,
        time: f64,
        max_steps: u64,
        mut each: impl FnMut(&Simulation, &StepReport),
    ) -> Result<(), EvolveError> {
        let mut n = 0;
        while self.time < time && n < max_steps && !self.collapsed {
            let r = self.step_until(time)?;
            each(self, &r);
            n += 1;
        }
        Ok(())
    }

    /// One step that does not pass time `until`: when the step the CFL condition allows
    /// would reach or pass it, Δt is shortened and the simulation lands on `until`
    /// exactly.
    ///
    /// A step is atomic (see [the type docs](Simulation)): it fails without changing
    /// anything when the interface has collapsed, the flow gives a non-finite speed in
    /// any stage, a fixed Δt violates the CFL limit, the band would leave the coordinate
    /// range ([`GridError::OutOfRange`]) or outgrow the memory budget
    /// ([`Settings::memory_limit`], [`GridError::OutOfMemory`]), the dense reference's
    /// box is too small, or the periodic reinitialisation after it fails
    /// ([`EvolveError::ReinitFailed`]).
    ///
    /// # Collapse
    /// After the step the simulation has collapsed when no interface is left as seen from
    /// the band: no inside band voxel (−γ < φ < 0) has an inside face neighbour (φ < 0),
    /// and either nothing is inside any more or what is left did not grow in the step (the
    /// band's inside measure Σ clamp(½ − φ/h, 0, 1) over |φ| < γ, an exact sum, did not
    /// increase). What such a state holds inside are sub-voxel blobs: each crosses the
    /// interface within one voxel along every axis, so no central difference sees its
    /// curvature (at a blob centred on a voxel the central gradient vanishes and the
    /// curvature term of eq. (3) is exactly 0, while the smoothed sign of the rescaling
    /// term only lets φ decay towards 0⁻); under mean curvature flow a sphere of radius h
    /// vanishes in h²/(2ε) anyway. The test uses only band values and their face
    /// neighbours, which every representation stores with the same bits, so all
    /// representations collapse in the same step.
    pub fn step_until(&mut self, until: f64) -> Result<StepReport, EvolveError> {
        // The whole step on a thread of the pool: its parallel passes (seven or more per
        // step) then start from a worker instead of being injected from outside, which
        // would wake a worker and park the caller at every pass.
        let pool = self.settings.pool.clone();
        in_worker(&pool, || self.step_until_in_pool(until))
    }

    /// [`Simulation::step_until`], on a thread of the pool.
    fn step_until_in_pool(&mut self, until: f64) -> Result<StepReport, EvolveError> {
        if self.collapsed {
            return Err(EvolveError::Collapsed { step: self.steps, time: self.time });
        }
        if until.is_nan() || until <= self.time {
            return Err(EvolveError::InvalidParameter(format!(
                "cannot step to t = {until} from t = {}",
                self.time
            )));
        }
        // The buffers' memory, stage 1's inputs and Δt: nothing changes yet (but scratch).
        // Distributed, every rank agrees on each (the inputs' κ̄ and Δt's maxima are
        // collective themselves, so no rank may skip them).
        let rep = self.rep.get();
        let budget = self.budget();
        let needed =
            rep.step_bytes(budget.keeps) + self.inputs.growth_bytes(rep.flat().len(), &self.flow);
        let admitted = budget.admit(needed, self.rep_bytes(), "the step's buffers");
        self.agree(admitted.map_err(EvolveError::from))?;
        let rep = self.rep.get();
        let prepared =
            self.inputs.prepare(rep, &self.flow, &self.settings, self.time, true, self.steps);
        let kappa_bar = self.agree(prepared)?;
        let (dt, lands) = self.time_step(until)?;
        // The step proper: on an error everything is put back.
        match self.advance(dt) {
            Ok(collapsed) => {
                let rep = self.rep.get_mut();
                rep.commit_step();
                self.time = if lands { until } else { self.time + dt as f64 };
                self.steps += 1;
                self.collapsed = collapsed;
                if let Rep::Tiles(t) = &mut self.rep {
                    t.rebalance();
                }
                Ok(StepReport { step: self.steps, time: self.time, dt, kappa_bar, collapsed })
            }
            Err(e) => {
                // A rank cannot undo its part of a step the others took (see
                // `crate::distributed`, "Failures").
                if let Some(c) = self.rep.get().comm() {
                    c.abort(&format!("step {}: {e}", self.steps + 1));
                }
                self.rep.get_mut().undo_step();
                Err(e)
            }
        }
    }

    /// Δt of the step starting now (stage 1's inputs prepared) and whether it is
    /// shortened to land on `until`.
    fn time_step(&self, until: f64) -> Result<(f32, bool), EvolveError> {
        let g = self.spec().gamma();
        let advects = self.flow.velocity.is_some();
        let (inputs, rep) = (&self.inputs, self.rep.get());
        let (flat, slices) = (rep.flat(), super::inputs::read_slices(rep, &self.settings));
        let eps = self.flow.curvature * self.settings.lattice.map_or(1.0, |l| l.curvature_factor());
        let (max_f, max_u, max_u0, max_e) =
            in_pool(&self.settings.pool, || inputs.band_maxima(flat, g, advects, eps, slices));
        // Distributed: every rank's band and ghosts hold values of the whole band, so the
        // maxima over the ranks are the whole band's.
        let [max_f, max_u, max_u0, max_e] = match self.rep.get().comm() {
            Some(c) => c.max_f32([max_f, max_u, max_u0, max_e]),
            None => [max_f, max_u, max_u0, max_e],
        };
        let mut limit = self.stability_limit(max_f, max_u, max_e);
        let rest = (until - self.time) as f32;
        // A time-separable velocity s(t) u(x, 0) is read at the later stages' times too
        // (t + Δt and t + Δt/2 in TVD-RK3): the limit holds there as well. (Where s
        // vanishes — Enright's field at T/2 — the current velocity alone would allow any
        // step.) The limit only shrinks, so the iteration ends at a step that holds at
        // its own stage times when |s| grows monotonically over it.
        if let (Some(Velocity::Field(f)), Integrator::Rk3) =
            (&self.flow.velocity, self.settings.integrator)
        {
            let cfl = match self.settings.time_step {
                TimeStep::Cfl(c) => c,
                TimeStep::Fixed(_) => 1.0,
            };
            if f.time_scale(self.time).is_some() {
                for _ in 0..8 {
                    let dt = (cfl * limit).min(rest) as f64;
                    let later = [self.time + dt, self.time + 0.5 * dt]
                        .map(|t| f.time_scale(t).unwrap_or(0.0).abs() * max_u0)
                        .into_iter()
                        .fold(max_u, f32::max);
                    let l = self.stability_limit(max_f, later, max_e);
                    if l >= limit {
                        break;
                    }
                    limit = l;
                }
            }
        }
        let mut dt = match self.settings.time_step {
            TimeStep::Cfl(cfl) => cfl * limit,
            TimeStep::Fixed(d) if d > limit => {
                return Err(EvolveError::CflViolated { dt: d, limit, step: self.steps })
            }
            TimeStep::Fixed(d) => d,
        };
        let mut lands = false;
        if dt >= rest {
            dt = rest;
            lands = true;
        }
        if !(dt.is_finite() && dt > 0.0) {
            return Err(EvolveError::InvalidParameter(format!(
                "no finite time step (Δt = {dt}): the flow moves nothing"
            )));
        }
        Ok((dt, lands))
    }

    /// The part of a step that changes the representation: the stages, the band
    /// maintenance, the collapse test and a due reinitialisation (which replaces the
    /// representation). Returns whether the interface collapsed. On an error the caller
    /// undoes the step.
    fn advance(&mut self, dt: f32) -> Result<bool, EvolveError> {
        self.run_stages(dt)?;
        if let Some(s) = self.renorm_due(self.steps + 1) {
            let p = self.renorm_params(&s);
            let rep = self.rep.get_mut();
            in_pool(&self.settings.pool, || rep.renormalize(&p, false))?;
        }
        let budget = self.budget();
        let rep = self.rep.get_mut();
        in_pool(&self.settings.pool, || rep.finish_step(&budget))?;
        let collapsed = self.detect_collapse();
        let step = self.steps + 1;
        if let Some(r) = self.settings.reinit
            && !collapsed
            && step.is_multiple_of(r.every)
        {
            let rep = self
                .reinitialized(r.order)
                .map_err(|e| EvolveError::ReinitFailed { step, reason: e.to_string() })?;
            self.rep = rep;
        }
        Ok(collapsed)
    }

    /// The Runge–Kutta stages of a step of `dt` (stage 1's inputs already prepared).
    fn run_stages(&mut self, dt: f32) -> Result<(), EvolveError> {
        let stages: &[(u8, f64)] = match self.settings.integrator {
            Integrator::Euler => &[(1, 0.0)],
            Integrator::Rk3 => &[(1, 0.0), (2, 1.0), (3, 0.5)],
        };
        let spec = self.spec();
        for (si, &(stage, c)) in stages.iter().enumerate() {
            if stage > 1 {
                let t = self.time + c * dt as f64;
                let rep = self.rep.get();
                self.inputs.prepare(rep, &self.flow, &self.settings, t, false, self.steps)?;
            }
            let p = StageParams {
                rescale: self.settings.renormalization.coupled_weight(),
                lattice: self.settings.lattice,
                ..self.inputs.params(stage, dt, &spec, &self.flow)
            };
            let last = si + 1 == stages.len();
            let scheme = self.settings.scheme;
            let rep = self.rep.get_mut();
            in_pool(&self.settings.pool, || rep.stage(&p, scheme, last))?;
        }
        Ok(())
    }

    /// Whether no interface is left after the step in progress (see
    /// [`Simulation::step_until`], "Collapse").
    fn detect_collapse(&self) -> bool {
        let rep = self.rep.get();
        let spec = rep.spec();
        let (g, h) = (spec.gamma(), spec.voxel_size);
        let comm = rep.comm();
        let inside = |c: Coord| rep.value(c) < 0.0;
        let resolved = rep.any_voxel(&mut |c, v| {
            v < 0.0
                && v > -g
                && crate::coord::FACE_OFFSETS.iter().any(|&d| c.checked_add(d).is_some_and(inside))
        });
        if comm.map_or(resolved, |c| c.any(resolved)) {
            return false;
        }
        let empty = rep.unstored_inside() == 0 && !rep.owned_flat().iter().any(|&v| v < 0.0);
        if comm.map_or(empty, |c| !c.any(!empty)) {
            return true;
        }
        // Over the band voxels only: φⁿ may leave out the values of ±γ.
        let inside_measure = |s: &mut ExactSum, values: &[f32]| {
            for &v in values.iter().filter(|v| v.abs() < g) {
                s.add((0.5 - v / h).clamp(0.0, 1.0));
            }
        };
        let (mut now, mut before) = (ExactSum::default(), ExactSum::default());
        inside_measure(&mut now, rep.owned_flat());
        rep.for_each_owned_step_start(&mut |v| inside_measure(&mut before, v));
        let [now, before] = comm.map_or([now, before], |c| c.sum_exact([now, before]));
        now.value() <= before.value()
    }
}

/// The accessor of a simulation's state: the tile or DT-Grid accessor, random access on
/// the dense reference. (One lives on the stack per ray or row: its size does not
/// matter, an indirection per lookup would.)
#[allow(clippy::large_enum_variant)]
enum SimulationAccessor<'a> {
    Tiles(crate::storage::tiles::TileAccessor<'a>),
    DtGrid(crate::storage::dtgrid::DtAccessor<'a>),
    Other(&'a crate::evolve::Simulation),
}

impl Accessor for SimulationAccessor<'_> {
    #[inline]
    fn value(&mut self, voxel: Coord) -> f32 {
        match self {
            SimulationAccessor::Tiles(a) => a.value(voxel),
            SimulationAccessor::DtGrid(a) => a.value(voxel),
            SimulationAccessor::Other(s) => s.value(voxel),
        }
    }
}

/// A simulation's current state (tiles, DT-Grid or the dense reference).
impl LevelSet for crate::evolve::Simulation {
    fn spec(&self) -> GridSpec {
        crate::evolve::Simulation::spec(self)
    }
    fn value(&self, voxel: Coord) -> f32 {
        crate::evolve::Simulation::value(self, voxel)
    }
    fn accessor(&self) -> impl Accessor + '_ {
        match (self.tiles(), self.dtgrid()) {
            (Some(t), _) => SimulationAccessor::Tiles(crate::storage::tiles::TileAccessor::new(t)),
            (_, Some(d)) => SimulationAccessor::DtGrid(crate::storage::dtgrid::DtAccessor::new(d)),
            _ => SimulationAccessor::Other(self),
        }
    }
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        crate::evolve::Simulation::for_each_band_voxel(self, f)
    }
    fn band_voxels(&self) -> usize {
        crate::evolve::Simulation::band_voxels(self)
    }
    fn bounding_box(&self) -> Option<(Coord, Coord)> {
        match (self.tiles(), self.dtgrid()) {
            (Some(t), _) => t.bounding_box(),
            (_, Some(d)) => d.bounding_box(),
            _ => self.band_bounding_box(),
        }
    }
    fn memory(&self) -> MemoryReport {
        match (self.tiles(), self.dtgrid()) {
            (Some(t), _) => t.memory(),
            (_, Some(d)) => d.memory(),
            _ => MemoryReport { values: self.stored_voxels() * 4, ..Default::default() },
        }
    }
    fn storage(&self) -> Option<&dyn std::any::Any> {
        match (self.tiles(), self.dtgrid()) {
            (Some(t), _) => Some(t),
            (_, Some(d)) => Some(d),
            _ => None,
        }
    }
}

/// A distributed simulation's view of its ranks ([`Simulation::distribution`]). The methods
/// marked collective must be called on every rank in the same order.
pub struct Distribution<'a> {
    sim: &'a Simulation,
}

impl Distribution<'_> {
    /// This rank's exchange statistics.
    pub fn halo_stats(&self) -> Option<HaloStats> {
        match &self.sim.rep {
            Rep::Tiles(t) => t.halo_stats(),
            _ => None,
        }
    }

    /// The z-slabs of tiles that hold tiles, over all ranks (collective): the most ranks a
    /// slab decomposition can use.
    pub fn slabs(&self) -> Option<usize> {
        let Rep::Tiles(t) = &self.sim.rep else { return None };
        let n = t.owned_slabs()?;
        Some(self.sim.sum_counts([n as u64])[0] as usize)
    }

    /// Every rank's exchange statistics, in rank order (collective).
    pub fn halo_stats_per_rank(&self) -> Vec<HaloStats> {
        let (Some(c), Some(mine)) = (self.sim.rep.get().comm(), self.halo_stats()) else {
            return Vec::new();
        };
        c.gather(&mine.to_bytes()).iter().filter_map(|b| HaloStats::from_bytes(b)).collect()
    }

    /// This rank and the cuts (tile z coordinates: rank r owns `cuts[r] ≤ tz <
    /// cuts[r + 1]`).
    pub fn cuts(&self) -> Option<(usize, Vec<i32>)> {
        match &self.sim.rep {
            Rep::Tiles(t) => t.cuts().map(|(r, c)| (r, c.to_vec())),
            _ => None,
        }
    }

    /// The tiles every rank owns, in rank order (collective).
    pub fn tiles_per_rank(&self) -> Vec<u64> {
        let rep = self.sim.rep.get();
        let n = rep.units() as u64;
        rep.comm().map_or_else(|| vec![n], |c| c.counts(n))
    }
}

/// The values below γ in magnitude, counted inside the function of the CPU's level
/// (a plain loop, no closure: see `levelset_kernels::level`).
struct BandCount<'a> {
    values: &'a [f32],
    gamma: f32,
}

impl levelset_kernels::LaneFn for BandCount<'_> {
    type Output = usize;
    #[inline(always)]
    fn call<L: levelset_kernels::Lane>(self) -> usize {
        let mut n = 0;
        for &v in self.values {
            n += usize::from(v.abs() < self.gamma);
        }
        n
    }
}
