//! Evolution of a level set under a PDE, with one API over the Sorted Tile List (scalar
//! or SIMD lanes), the DT-Grid and a dense reference.
//!
//! The PDE is eq. (3) of the tile paper with an advection term added,
//!
//! ```text
//! φ_t = −F(x, t)|∇φ| + ε κ |∇φ| + w sgn(φ)(1 − |∇φ|) − u(x, t)·∇φ
//! ```
//!
//! discretised as in its Sec. 4.7 (first-order upwind, [`SpatialScheme::Upwind1`]) or with
//! HJ-WENO5 for the hyperbolic terms (Sec. 5.2, [`SpatialScheme::Weno5`]), the curvature
//! term always with central differences (eq. (4)), integrated with forward Euler or
//! TVD-RK3 ([`Integrator`]). A [`Flow`] chooses the terms:
//!
//! * mean curvature flow: ε > 0 ([`Flow::mean_curvature`]; tile paper Sec. 5.1);
//! * volume-conserving mean curvature flow, eq. (5): F = ε κ̄ with κ̄ from eq. (6)–(7),
//!   recomputed from the current φ in every stage ([`Flow::volume_conserving`]; Sec. 5.2);
//! * normal speed F(x, t), constant or a field ([`Speed`]);
//! * advection by u(x, t) ([`Velocity`]; Enright's test, Sec. 5.4);
//! * morphing toward a target ([`Speed::MorphTo`], H-RLE paper eq. (1));
//! * the rescaling term of eq. (3) with weight w (Sec. 3.2).
//!
//! # The band rule (the same for every representation)
//! Values live in `[−γ, γ]`; a voxel with |φ| < γ is a band voxel; a voxel nobody stores
//! reads −γ inside and +γ outside. A step computes exactly the voxels whose 3×3×3 box
//! holds a band voxel of φⁿ (the band dilated by one voxel), in every stage; every other
//! voxel keeps ±γ. The DT-Grid stores exactly that set (rebuilt after every step, DT-Grid
//! paper Sec. 3.6.2: keep |φ| < γ, dilate by one, new points at ±γ); tiles (tile
//! management of Alg. 2–3 from the guard-band activity flags of Fig. 5 keeps every voxel
//! within one voxel of the band in a tile) and the dense reference store more and mask
//! with [`levelset_kernels::BandMasked`]. Reductions (κ̄, volume, area) are exact sums
//! ([`exact`]) and the time step comes from maxima over the band voxels. So all three
//! representations, every lane type and every thread count compute the same numbers,
//! bit for bit; the tests check it.
//!
//! ```
//! use sparse_levelset::{build, evolve::{Flow, Settings, Simulation, GridKind, Lanes}, grid::GridSpec, shapes::Shape};
//!
//! let spec = GridSpec::default();
//! let shape = Shape::Sphere { center: [0.0; 3], radius: 12.0 };
//! let flow = Flow::mean_curvature(1.0);
//! let mut tiles = Simulation::from_shape(GridKind::Tiles(Lanes::Simd), &shape, spec, flow.clone(), Settings::default())?;
//! let mut dt = Simulation::from_shape(GridKind::DtGrid, &shape, spec, flow, Settings::default())?;
//! for _ in 0..20 {
//!     tiles.step()?;
//!     dt.step()?;
//! }
//! assert_eq!(tiles.checksum(), dt.checksum()); // the same band, bit for bit
//! let r = (3.0 * tiles.measure().volume / (4.0 * std::f64::consts::PI)).cbrt();
//! let exact = (12.0f64 * 12.0 - 2.0 * tiles.time()).sqrt(); // r² = r₀² − 2εt
//! assert!((r - exact).abs() < 0.1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod engine;
pub mod exact;
pub mod field;

pub use field::{
    EnrightVelocity, SampledField, SampledVelocity, ScalarClosure, ScalarFn, Speed, StaticSdf,
    VectorClosure, VectorFn, Velocity,
};

use crate::coord::Coord;
use crate::dense::DenseField;
use crate::dtgrid::DtGrid;
use crate::grid::{GridError, GridSpec};
use crate::shapes::Shape;
use crate::tiles::TileGrid;
use engine::{DenseRep, DtRep, Representation, StageParams, TilesRep};
use exact::ExactSum;
use levelset_kernels::rk::{cfl_rate_advection, cfl_rate_eq3};
use levelset_kernels::KernelError;
use serde::Serialize;
use std::sync::Arc;

/// Spatial discretisation of the hyperbolic terms (normal speed, rescaling, advection).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SpatialScheme {
    /// First-order one-sided differences (tile paper Sec. 4.7).
    Upwind1,
    /// Fifth-order HJ-WENO (tile paper Sec. 5.2, DT-Grid paper Sec. 4.1).
    Weno5,
}

/// Time integration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Forward Euler (tile paper Sec. 4.7).
    Euler,
    /// Third-order TVD Runge–Kutta of Shu & Osher (tile paper Sec. 5.2).
    Rk3,
}

/// Lane type of the tile engine's kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Lanes {
    /// One voxel at a time (`f32`): the same code path as the DT-Grid's arithmetic.
    Scalar,
    /// The widest vector the build supports ([`levelset_kernels::DefaultLane`]).
    Simd,
}

/// Which representation a simulation runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridKind {
    Tiles(Lanes),
    DtGrid,
    /// A dense box: the reference for tests on small grids.
    Dense,
}

impl GridKind {
    /// `"tiles"`, `"dtgrid"` or `"dense"`.
    pub fn name(self) -> &'static str {
        match self {
            GridKind::Tiles(_) => "tiles",
            GridKind::DtGrid => "dtgrid",
            GridKind::Dense => "dense",
        }
    }
}

/// The terms of the PDE (see the [module docs](self)).
#[derive(Clone, Debug)]
pub struct Flow {
    /// F of eq. (3): φ_t = −F|∇φ| (F > 0 moves the interface outward).
    pub speed: Speed,
    /// ε ≥ 0, the weight of the curvature term εκ|∇φ| (κ = ½∇·(∇φ/|∇φ|), 1/r on a sphere).
    pub curvature: f32,
    /// Adds F = ε κ̄ (eq. (5)–(7)): the curvature flow conserves the enclosed volume.
    pub volume_conserving: bool,
    /// u of the advection term −u·∇φ.
    pub velocity: Option<Velocity>,
    /// w ≥ 0, the weight of the rescaling term sgn(φ)(1 − |∇φ|) of eq. (3) (Sec. 3.2);
    /// 1 keeps φ close to a signed distance, 0 drops the term.
    pub rescale: f32,
}

impl Flow {
    /// Nothing moves: F = 0, ε = 0, no advection, rescaling on (w = 1).
    pub fn rest() -> Flow {
        Flow {
            speed: Speed::Constant(0.0),
            curvature: 0.0,
            volume_conserving: false,
            velocity: None,
            rescale: 1.0,
        }
    }

    /// Motion by mean curvature with weight ε (eq. (3) with F = 0; tile paper Sec. 5.1).
    pub fn mean_curvature(eps: f32) -> Flow {
        Flow { curvature: eps, ..Flow::rest() }
    }

    /// Volume-conserving mean curvature flow φ_t = ε(κ − κ̄)|∇φ| (eq. (5)).
    pub fn volume_conserving(eps: f32) -> Flow {
        Flow { curvature: eps, volume_conserving: true, ..Flow::rest() }
    }

    /// Motion in the normal direction with speed F.
    pub fn normal_speed(speed: Speed) -> Flow {
        Flow { speed, ..Flow::rest() }
    }

    /// Advection by a velocity field.
    pub fn advection(velocity: Velocity) -> Flow {
        Flow { velocity: Some(velocity), ..Flow::rest() }
    }

    /// Morphing toward the level set `target` (H-RLE paper eq. (1)).
    pub fn morph(target: Arc<dyn ScalarFn>) -> Flow {
        Flow::normal_speed(Speed::MorphTo(target))
    }

    /// The same flow with curvature weight ε.
    pub fn with_curvature(mut self, eps: f32) -> Flow {
        self.curvature = eps;
        self
    }

    /// The same flow with rescaling weight w.
    pub fn with_rescale(mut self, w: f32) -> Flow {
        self.rescale = w;
        self
    }

    /// The same flow with normal speed F.
    pub fn with_speed(mut self, speed: Speed) -> Flow {
        self.speed = speed;
        self
    }

    /// The same flow with an advection velocity.
    pub fn with_velocity(mut self, velocity: Velocity) -> Flow {
        self.velocity = Some(velocity);
        self
    }

    fn validate(&self) -> Result<(), EvolveError> {
        let bad = |what: &str, v: f32| {
            Err(EvolveError::InvalidParameter(format!("{what} must be finite and >= 0, got {v}")))
        };
        if !(self.curvature.is_finite() && self.curvature >= 0.0) {
            return bad("curvature weight ε", self.curvature);
        }
        if !(self.rescale.is_finite() && self.rescale >= 0.0) {
            return bad("rescaling weight", self.rescale);
        }
        if let Speed::Constant(f) = self.speed {
            if !f.is_finite() {
                return Err(EvolveError::InvalidParameter(format!(
                    "speed F must be finite, got {f}"
                )));
            }
        }
        if let Some(Velocity::Constant(u)) = self.velocity {
            if u.iter().any(|c| !c.is_finite()) {
                return Err(EvolveError::InvalidParameter(format!(
                    "velocity must be finite, got {u:?}"
                )));
            }
        }
        Ok(())
    }
}

/// How the time step is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TimeStep {
    /// The largest stable step times this CFL number (in (0, 1]) in every step.
    Cfl(f32),
    /// This Δt in every step; a step where it exceeds the stability limit (CFL number 1)
    /// is rejected with [`EvolveError::CflViolated`] before anything changes.
    Fixed(f32),
}

/// Numerical settings of a simulation.
#[derive(Clone, Debug)]
pub struct Settings {
    pub scheme: SpatialScheme,
    pub integrator: Integrator,
    pub time_step: TimeStep,
    /// Width of the smoothed delta function of eq. (7), in voxels (κ̄ and area).
    pub delta_width: f32,
    /// The thread pool for the tile engine (the global rayon pool when `None`). The
    /// DT-Grid and dense references run on the calling thread.
    pub pool: Option<Arc<rayon::ThreadPool>>,
    /// Reinitialise the band to a signed distance by fast marching every so many steps
    /// (sparse grids only; see [`Simulation::reinitialize`]).
    pub reinit: Option<Reinit>,
}

/// Periodic reinitialisation by fast marching.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reinit {
    /// First-order or high-accuracy fast marching.
    pub order: crate::fmm::Order,
    /// After every this many steps (≥ 1).
    pub every: u64,
}

impl Default for Settings {
    /// First-order upwind, forward Euler, CFL 0.5, δ width 1.5 voxels, no reinitialisation.
    fn default() -> Self {
        Settings {
            scheme: SpatialScheme::Upwind1,
            integrator: Integrator::Euler,
            time_step: TimeStep::Cfl(0.5),
            delta_width: 1.5,
            pool: None,
            reinit: None,
        }
    }
}

impl Settings {
    /// HJ-WENO5 with TVD-RK3 (the tile paper's Sec. 5.2 scheme), CFL 0.5.
    pub fn weno5_rk3() -> Settings {
        Settings {
            scheme: SpatialScheme::Weno5,
            integrator: Integrator::Rk3,
            ..Settings::default()
        }
    }

    fn validate(&self) -> Result<(), EvolveError> {
        match self.time_step {
            TimeStep::Cfl(c) if !(c > 0.0 && c <= 1.0) => {
                Err(EvolveError::InvalidParameter(format!("CFL number must be in (0, 1], got {c}")))
            }
            TimeStep::Fixed(dt) if !(dt.is_finite() && dt > 0.0) => {
                Err(EvolveError::InvalidParameter(format!(
                    "time step must be finite and > 0, got {dt}"
                )))
            }
            _ if !(self.delta_width.is_finite() && self.delta_width > 0.0) => {
                Err(EvolveError::InvalidParameter(format!(
                    "delta width must be finite and > 0, got {}",
                    self.delta_width
                )))
            }
            _ if self.reinit.is_some_and(|r| r.every == 0) => Err(EvolveError::InvalidParameter(
                "reinitialisation interval must be at least 1 step".into(),
            )),
            _ => Ok(()),
        }
    }
}

/// Why a simulation could not start or step.
#[derive(Debug, thiserror::Error)]
pub enum EvolveError {
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error("kernel: {0}")]
    Kernel(#[from] KernelError),
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// The initial level set has no band voxel: there is no interface to move.
    #[error("the level set is empty: no voxel has |φ| < γ, so there is no interface to evolve")]
    EmptyLevelSet,
    /// The interior vanished (for example a shape collapsed under curvature flow).
    #[error("the interface collapsed at step {step}, t = {time}: no voxel is inside any more")]
    Collapsed { step: u64, time: f64 },
    #[error(
        "time step {dt} exceeds the stability limit {limit} (CFL number 1) at step {step}; \
         use a smaller step or the CFL-limited step"
    )]
    CflViolated { dt: f32, limit: f32, step: u64 },
    #[error("a speed or velocity sample is not finite in step {step} (t = {time})")]
    NonFiniteField { step: u64, time: f64 },
    #[error(
        "the band reached voxel {voxel}, within 4 voxels of the dense reference box's face; \
         use a larger box"
    )]
    DenseBoxTooSmall { voxel: Coord },
    #[error("reinitialisation: {0}")]
    Reinit(#[from] crate::fmm::FmmError),
    /// The periodic reinitialisation after step `step` failed; the step itself was taken
    /// (time and step count advanced) and its band is kept as it was.
    #[error("step {step} was taken, but the reinitialisation after it failed: {reason}")]
    ReinitFailed { step: u64, reason: String },
    /// Writing an output of the run (a mesh or image frame) failed.
    #[error("output: {0}")]
    Output(String),
}

/// Voxels of room around the initial band that the dense reference's box gets: the
/// interface may move this far (less the four-voxel margin the box must keep).
pub const DENSE_MARGIN: u32 = 16;

/// What one step did.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct StepReport {
    pub step: u64,
    /// Time after the step.
    pub time: f64,
    pub dt: f32,
    /// κ̄ of stage 1 (volume-conserving flow only).
    pub kappa_bar: Option<f64>,
    /// No voxel is inside any more.
    pub collapsed: bool,
}

/// Measurements of the current state.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Measures {
    /// Voxels with |φ| < γ.
    pub band_voxels: usize,
    /// Tiles (tile engine), points (DT-Grid) or voxels (dense) stored.
    pub stored: usize,
    /// Enclosed volume, world units: h³ Σ clamp(½ − φ/h, 0, 1) over stored voxels plus h³
    /// per interior voxel that is not stored.
    pub volume: f64,
    /// Interface area, world units: h³ Σ δ(φ)|∇φ| with the δ of eq. (7).
    pub area: f64,
    /// Bytes of the representation's data (unused array capacity excluded).
    pub bytes: usize,
    /// Bytes of the evolution's buffers and the representation's unused capacity.
    pub work_bytes: usize,
}

/// Runs `f` in `pool` (the global rayon pool when `None`).
fn in_pool<T: Send>(pool: &Option<Arc<rayon::ThreadPool>>, f: impl FnOnce() -> T + Send) -> T {
    match pool {
        Some(pool) => pool.install(f),
        None => f(),
    }
}

#[derive(Clone)]
enum Rep {
    Tiles(TilesRep),
    // Boxed: the DT-Grid engine holds three grids (current, rebuild scratch, result).
    DtGrid(Box<DtRep>),
    Dense(DenseRep),
}

impl Rep {
    fn get(&self) -> &dyn Representation {
        match self {
            Rep::Tiles(r) => r,
            Rep::DtGrid(r) => r.as_ref(),
            Rep::Dense(r) => r,
        }
    }

    fn get_mut(&mut self) -> &mut dyn Representation {
        match self {
            Rep::Tiles(r) => r,
            Rep::DtGrid(r) => r.as_mut(),
            Rep::Dense(r) => r,
        }
    }
}

/// A level set evolving under a [`Flow`] on one representation.
#[derive(Clone)]
pub struct Simulation {
    rep: Rep,
    kind: GridKind,
    flow: Flow,
    settings: Settings,
    time: f64,
    steps: u64,
    collapsed: bool,
    /// Per-voxel F (flat order) and u.
    speed: Vec<f32>,
    /// F when it is the same everywhere (a constant, plus ε κ̄); then `speed` is empty.
    uniform_speed: Option<f32>,
    velocity: [Vec<f32>; 3],
    /// The factor of `velocity` in the current stage ([`VectorFn::time_scale`]; else 1).
    velocity_scale: f32,
    /// F without ε κ̄ (a sampled field) or the morph target ψ, per voxel.
    base: Vec<f32>,
}

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
        let tiles = crate::build::tiles_from_shape(shape, spec)?;
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
                Rep::DtGrid(Box::new(DtRep::new(crate::build::dtgrid_from_tiles(&tiles))))
            }
            GridKind::Dense => {
                let (origin, dims) = crate::build::dense_box(&tiles, DENSE_MARGIN)
                    .ok_or(EvolveError::EmptyLevelSet)?;
                let field = crate::build::to_dense(&tiles, origin, dims)?;
                Rep::Dense(DenseRep::new(field, spec)?)
            }
        };
        Simulation::start(rep, kind, flow, settings)
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
    /// clamped to ±γ), on representation `kind`. Non-finite values are an error.
    pub fn from_dense(
        kind: GridKind,
        field: &DenseField,
        spec: GridSpec,
        flow: Flow,
        settings: Settings,
    ) -> Result<Simulation, EvolveError> {
        if let Some(i) = field.data().iter().position(|v| !v.is_finite()) {
            let c = field.coord_of(i).unwrap_or_default();
            return Err(EvolveError::InvalidParameter(format!(
                "the initial field is not finite at voxel {c} (value {})",
                field.data()[i]
            )));
        }
        match kind {
            GridKind::Dense => {
                let g = spec.gamma();
                let mut f = field.clone();
                f.data_mut().iter_mut().for_each(|v| *v = v.clamp(-g, g));
                Simulation::start(Rep::Dense(DenseRep::new(f, spec)?), kind, flow, settings)
            }
            _ => {
                let tiles = crate::build::tiles_from_dense(field, spec)?;
                Simulation::from_tile_grid(kind, tiles, flow, settings)
            }
        }
    }

    fn start(
        rep: Rep,
        kind: GridKind,
        flow: Flow,
        settings: Settings,
    ) -> Result<Simulation, EvolveError> {
        flow.validate()?;
        settings.validate()?;
        if settings.reinit.is_some() && kind == GridKind::Dense {
            return Err(EvolveError::InvalidParameter(
                "reinitialisation by fast marching runs on the sparse grids (tiles, DT-Grid), \
                 not on the dense reference"
                    .into(),
            ));
        }
        let mut sim = Simulation {
            rep,
            kind,
            flow,
            settings,
            time: 0.0,
            steps: 0,
            collapsed: false,
            speed: Vec::new(),
            uniform_speed: None,
            velocity: Default::default(),
            velocity_scale: 1.0,
            base: Vec::new(),
        };
        let g = sim.spec().gamma();
        if !sim.rep.get().flat().iter().any(|v| v.abs() < g) {
            return Err(EvolveError::EmptyLevelSet);
        }
        // Bring the initial band to the band rule: every voxel within one voxel of the
        // band stored (tile management, DT-Grid rebuild).
        let rep = sim.rep.get_mut();
        in_pool(&sim.settings.pool, || rep.finish_step())?;
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

    /// Whether the interior has vanished.
    pub fn collapsed(&self) -> bool {
        self.collapsed
    }

    /// Reinitialises the band to a signed distance by fast marching
    /// ([`crate::fmm::reinitialize_tiles`] / [`crate::fmm::reinitialize_dtgrid`], the same
    /// values on both grids), keeping the half-width, then brings the band to the band rule
    /// again. The interface stays where it is (its voxels keep their distance estimates);
    /// the rest of the band becomes an exact marched distance. Sparse grids only.
    pub fn reinitialize(&mut self, order: crate::fmm::Order) -> Result<(), EvolveError> {
        let opts = crate::fmm::FmmOptions { order, ..Default::default() };
        let pool = &self.settings.pool;
        // The new representation replaces the current one only once it is complete: on an
        // error the simulation is unchanged.
        let mut rep = match &self.rep {
            Rep::Tiles(t) => {
                let grid = in_pool(pool, || crate::fmm::reinitialize_tiles(&t.grid, &opts))?;
                Rep::Tiles(in_pool(pool, || TilesRep::new(grid, t.lanes)))
            }
            Rep::DtGrid(d) => {
                Rep::DtGrid(Box::new(DtRep::new(crate::fmm::reinitialize_dtgrid(&d.grid, &opts)?)))
            }
            Rep::Dense(_) => {
                return Err(EvolveError::InvalidParameter(
                    "reinitialisation by fast marching runs on the sparse grids".into(),
                ))
            }
        };
        let r = rep.get_mut();
        in_pool(pool, || r.finish_step())?;
        self.rep = rep;
        Ok(())
    }

    /// The tile grid, when running on tiles.
    pub fn tiles(&self) -> Option<&TileGrid> {
        match &self.rep {
            Rep::Tiles(t) => Some(&t.grid),
            _ => None,
        }
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
        DenseField::from_fn(origin, dims, |c| self.value(c))
    }

    /// Band voxels (|φ| < γ).
    pub fn band_voxels(&self) -> usize {
        let g = self.spec().gamma();
        self.rep.get().flat().iter().filter(|v| v.abs() < g).count()
    }

    /// Voxels a stage computes: stored voxels (tile padding included).
    pub fn stored_voxels(&self) -> usize {
        self.rep.get().flat().len()
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

    /// Visits the band voxels (|φ| < γ) in [`Coord`] order.
    pub fn for_each_band_voxel(&self, mut f: impl FnMut(Coord, f32)) {
        self.rep.get().for_each_band_voxel(&mut f)
    }

    /// FNV-1a over the band voxels' coordinates and value bits in [`Coord`] order: equal
    /// band contents give equal checksums, whatever the representation.
    pub fn checksum(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
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
    }

    /// Band voxels, storage, volume and area of the current state.
    pub fn measure(&self) -> Measures {
        let spec = self.spec();
        let h = spec.voxel_size;
        let g = spec.gamma();
        let width = self.settings.delta_width * h;
        let mut flat_inside = ExactSum::default();
        let mut band = 0usize;
        for &v in self.rep.get().flat() {
            flat_inside.add((0.5 - v / h).clamp(0.0, 1.0));
            band += (v.abs() < g) as usize;
        }
        let unstored = self.rep.get().unstored_inside();
        let area_sum = in_pool(&self.settings.pool, || self.rep.get().kappa_bar_sums(width));
        let h3 = (h as f64).powi(3);
        Measures {
            band_voxels: band,
            stored: self.rep.get().units(),
            volume: h3 * (flat_inside.value() + unstored as f64),
            // The sums hold δ|∇φ|·h (see `KappaBarTerm`): area = h³ Σ δ|∇φ| = h² Σ den.
            area: area_sum.map_or(f64::NAN, |(_, den)| h3 / h as f64 * den.value()),
            bytes: self.rep.get().bytes(),
            work_bytes: self.rep.get().work_bytes(),
        }
    }

    /// The largest stable Δt for the current state (CFL number 1), given the largest |F|
    /// and |u|₁ over the band voxels: the rates of eq. (3) and of advection add up
    /// (see [`levelset_kernels::rk`]).
    fn stability_limit(&self, max_f: f32, max_u: f32) -> f32 {
        let h = self.spec().voxel_size;
        let rate = cfl_rate_eq3(max_f, self.flow.curvature, self.flow.rescale, h)
            + cfl_rate_advection(max_u, h);
        if rate > 0.0 {
            1.0 / rate
        } else {
            f32::INFINITY
        }
    }

    /// One time step. Fails cleanly (the state unchanged) when the flow gives non-finite
    /// speeds, a fixed Δt violates the CFL limit, or the interface has collapsed.
    pub fn step(&mut self) -> Result<StepReport, EvolveError> {
        self.step_until(f64::INFINITY)
    }

    /// Steps until `time` is reached (the last step lands on it exactly), the interface
    /// collapses, or `max_steps` steps were taken; calls `each` after every step.
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
    pub fn step_until(&mut self, until: f64) -> Result<StepReport, EvolveError> {
        if self.collapsed {
            return Err(EvolveError::Collapsed { step: self.steps, time: self.time });
        }
        if until.is_nan() || until <= self.time {
            return Err(EvolveError::InvalidParameter(format!(
                "cannot step to t = {until} from t = {}",
                self.time
            )));
        }
        let spec = self.spec();
        let (h, g) = (spec.voxel_size, spec.gamma());
        let n = self.rep.get().flat().len();
        let stages: &[(u8, f64)] = match self.settings.integrator {
            Integrator::Euler => &[(1, 0.0)],
            Integrator::Rk3 => &[(1, 0.0), (2, 1.0), (3, 0.5)],
        };
        let t0 = self.time;
        let mut dt = 0.0f32;
        let mut lands = false;
        let mut kappa_bar_1 = None;
        for (si, &(stage, c)) in stages.iter().enumerate() {
            let t = t0 + c * dt as f64;
            let kappa_bar = match self.prepare_fields(n, t, stage == 1) {
                Ok(k) => k,
                Err(e) => {
                    if stage > 1 {
                        // Stage 1 already wrote φ⁽¹⁾: put φⁿ back so the step is undone.
                        self.rep.get_mut().rollback()?;
                    }
                    return Err(e);
                }
            };
            if stage == 1 {
                kappa_bar_1 = kappa_bar;
                let (max_f, max_u) = self.band_maxima(g);
                let limit = self.stability_limit(max_f, max_u);
                dt = match self.settings.time_step {
                    TimeStep::Cfl(cfl) => cfl * limit,
                    TimeStep::Fixed(d) if d > limit => {
                        return Err(EvolveError::CflViolated { dt: d, limit, step: self.steps })
                    }
                    TimeStep::Fixed(d) => d,
                };
                let rest = (until - t0) as f32;
                if dt >= rest {
                    dt = rest;
                    lands = true;
                }
                if !(dt.is_finite() && dt > 0.0) {
                    return Err(EvolveError::InvalidParameter(format!(
                        "no finite time step (Δt = {dt}): the flow moves nothing"
                    )));
                }
            }
            let p =
                StageParams {
                    stage,
                    dt,
                    gamma: g,
                    h,
                    eps: self.flow.curvature,
                    rescale: self.flow.rescale,
                    uniform_speed: self.uniform_speed,
                    speed: &self.speed,
                    velocity: self.flow.velocity.as_ref().map(|_| {
                        [&self.velocity[0][..], &self.velocity[1][..], &self.velocity[2][..]]
                    }),
                    velocity_scale: self.velocity_scale,
                    phi_n: &[],
                };
            let last = si + 1 == stages.len();
            let scheme = self.settings.scheme;
            let rep = self.rep.get_mut();
            in_pool(&self.settings.pool, || rep.stage(&p, scheme, last))?;
        }
        let rep = self.rep.get_mut();
        in_pool(&self.settings.pool, || rep.finish_step())?;
        self.time = if lands { until } else { t0 + dt as f64 };
        self.steps += 1;
        let rep = self.rep.get();
        // Unstored interior (cheap, per tile row) first; the values only when there is none.
        self.collapsed = rep.unstored_inside() == 0 && !rep.flat().iter().any(|&v| v < 0.0);
        if let Some(r) = self.settings.reinit {
            if !self.collapsed && self.steps.is_multiple_of(r.every) {
                // The step stands; a failed reinitialisation leaves its result as it is
                // and is reported.
                self.reinitialize(r.order).map_err(|e| EvolveError::ReinitFailed {
                    step: self.steps,
                    reason: e.to_string(),
                })?;
            }
        }
        Ok(StepReport {
            step: self.steps,
            time: self.time,
            dt,
            kappa_bar: kappa_bar_1,
            collapsed: self.collapsed,
        })
    }

    /// Fills the per-voxel F and u for a stage at time `t`; returns κ̄ when the flow is
    /// volume-conserving. `first` marks stage 1 (the layout may have changed since the
    /// last step, so everything is sampled anew); fields that do not depend on time are
    /// sampled only then, into `base` (F) and `velocity` (u).
    fn prepare_fields(
        &mut self,
        n: usize,
        t: f64,
        first: bool,
    ) -> Result<Option<f64>, EvolveError> {
        let rep: &dyn Representation = self.rep.get();
        let pool = &self.settings.pool;
        // Volume conservation: F += ε κ̄ of the current stage's φ.
        let mut kappa_bar = None;
        let mut add = 0.0f32;
        if self.flow.volume_conserving {
            let width = self.settings.delta_width * rep.spec().voxel_size;
            let (num, den) = in_pool(pool, || rep.kappa_bar_sums(width))?;
            let h = rep.spec().voxel_size as f64;
            // The sums hold κδ|∇φ|·h² and δ|∇φ|·h (see `KappaBarTerm`).
            let kb = if den.value() > 0.0 { num.value() / den.value() / h } else { 0.0 };
            kappa_bar = Some(kb);
            add = (self.flow.curvature as f64 * kb) as f32;
        }
        // Normal speed: F = base + ε κ̄, uniform (no per-voxel array) for a constant F.
        self.uniform_speed = None;
        if !matches!(self.flow.speed, Speed::Constant(_)) {
            self.speed.resize(n, 0.0);
        }
        match &self.flow.speed {
            Speed::Constant(f) => {
                self.uniform_speed = Some(*f + add);
                self.speed.clear();
            }
            Speed::Field(f) => {
                if first || f.time_dependent() {
                    self.base.resize(n, 0.0);
                    let base = &mut self.base;
                    in_pool(pool, || rep.fill_scalar(f.as_ref(), t, base));
                }
                for (s, &b) in self.speed.iter_mut().zip(&self.base) {
                    *s = b + add;
                }
            }
            Speed::MorphTo(target) => {
                if first {
                    self.base.resize(n, 0.0);
                    let base = &mut self.base;
                    in_pool(pool, || rep.fill_scalar(target.as_ref(), t, base));
                    let g = rep.spec().gamma();
                    self.base.iter_mut().for_each(|v| *v = v.clamp(-g, g));
                }
                for ((s, &phi), &psi) in self.speed.iter_mut().zip(rep.flat()).zip(&self.base) {
                    *s = (phi - psi) + add;
                }
            }
        }
        // Advection velocity.
        self.velocity_scale = 1.0;
        let mut check_velocity = self.flow.velocity.is_some();
        if let Some(vel) = &self.flow.velocity {
            for c in &mut self.velocity {
                c.resize(n, 0.0);
            }
            match vel {
                Velocity::Constant(u) => {
                    if first {
                        for (c, &v) in self.velocity.iter_mut().zip(u) {
                            c.fill(v);
                        }
                    } else {
                        check_velocity = false;
                    }
                }
                Velocity::Field(f) => match f.time_scale(t) {
                    // u(x, t) = s(t) u(x, 0): u(x, 0) sampled once per step, the kernels
                    // multiply by s.
                    Some(scale) => {
                        if first {
                            let [a, b, c] = &mut self.velocity;
                            in_pool(pool, || rep.fill_vector(f.as_ref(), 0.0, [a, b, c]));
                        } else {
                            check_velocity = false;
                        }
                        self.velocity_scale = scale;
                    }
                    None => {
                        if first || f.time_dependent() {
                            let [a, b, c] = &mut self.velocity;
                            in_pool(pool, || rep.fill_vector(f.as_ref(), t, [a, b, c]));
                        } else {
                            check_velocity = false;
                        }
                    }
                },
            }
        }
        // Every sample a stage reads must be finite: a NaN would count as 0 in the upwind
        // choice and an infinity would turn into NaN and then −γ.
        let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
        // (Arrays checked when written; a scale is checked in every stage.)
        let velocity_ok = self.velocity_scale.is_finite()
            && (!check_velocity || self.velocity.iter().all(|c| finite(c)));
        let speed_ok = self.uniform_speed.map_or_else(|| finite(&self.speed), f32::is_finite);
        if !speed_ok || !velocity_ok {
            return Err(EvolveError::NonFiniteField { step: self.steps, time: t });
        }
        Ok(kappa_bar)
    }

    /// max |F| and max (|u|+|v|+|w|) over the band voxels of the current values (the set
    /// every representation holds, so every representation takes the same Δt).
    fn band_maxima(&self, g: f32) -> (f32, f32) {
        let flat = self.rep.get().flat();
        let mut max_f = 0.0f32;
        match self.uniform_speed {
            // Every step starts with band voxels (or the interface has collapsed).
            Some(f) => max_f = f.abs(),
            None => {
                for (&v, &f) in flat.iter().zip(&self.speed) {
                    if v.abs() < g {
                        max_f = max_f.max(f.abs());
                    }
                }
            }
        }
        let mut max_u = 0.0f32;
        if self.flow.velocity.is_some() {
            let [a, b, c] = &self.velocity;
            let s = self.velocity_scale;
            for (i, &v) in flat.iter().enumerate() {
                if v.abs() < g {
                    max_u = max_u.max((a[i] * s).abs() + (b[i] * s).abs() + (c[i] * s).abs());
                }
            }
        }
        (max_f, max_u)
    }
}
