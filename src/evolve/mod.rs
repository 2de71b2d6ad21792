//! Evolution of a level set under a PDE, with one API over the Sorted Tile List (scalar
//! or SIMD lanes), the DT-Grid and a dense reference.
//!
//! The PDE is eq. (3) of van der Laan et al. 2011 with an advection term added,
//!
//! ```text
//! φ_t = −F(x, t)|∇φ| + ε κ |∇φ| − u(x, t)·∇φ  [+ w sgn(φ)(1 − |∇φ|)]
//! ```
//!
//! discretised as in its Sec. 4.7 (first-order upwind, [`SpatialScheme::Upwind1`]) or with
//! HJ-WENO5 for the hyperbolic terms (Sec. 5.2, [`SpatialScheme::Weno5`]), the curvature
//! term always with central differences (eq. (4)), integrated with forward Euler or
//! TVD-RK3 ([`Integrator`]). A [`Flow`] chooses the physical terms:
//!
//! * mean curvature flow: ε > 0 ([`Flow::mean_curvature`]; van der Laan et al. 2011, Sec. 5.1);
//! * volume-conserving mean curvature flow, eq. (5): F = ε κ̄ with κ̄ from eq. (6)–(7),
//!   recomputed from the current φ in every stage ([`Flow::volume_conserving`]; Sec. 5.2);
//! * normal speed F(x, t), constant or a field ([`Speed`]);
//! * advection by u(x, t) ([`Velocity`]; Enright's test, Sec. 5.4);
//! * morphing toward a target ([`Speed::MorphTo`], Houston et al. 2006, eq. (1)).
//!
//! # Keeping φ a distance
//! [`Settings::renormalization`] chooses how φ stays close to a signed distance:
//!
//! * [`Renormalization::Sweeps`] (the default): a level-set tracker's renormalisation as
//!   an operator of its own — after the physical step, pseudo-time sweeps of
//!   φ_τ = sgn(φ⁰)(1 − |∇φ|) with Godunov upwinding and the subcell fix of Russo &
//!   Smereka (J. Comput. Phys. 163 (2000), Sec. 3) at the voxels next to the interface,
//!   which keeps the zero crossings where they are ([`Simulation::renormalize`]). The
//!   step's CFL limit covers only the physical terms.
//! * [`Renormalization::Coupled`]: the rescaling term w sgn(φ)(1 − |∇φ|) of eq. (3)
//!   (Sec. 3.2) inside the PDE, the route of van der Laan et al. 2011 (and of the speed-up report).
//!   Its rate √3 w/h enters the CFL limit, and with first-order upwinding it moves a curved
//!   interface: the one-sided gradient norm is off by O(h/r) there, and the term turns
//!   that into motion (a sphere of r₀ = 20 under mean curvature flow reaches r = 13.37
//!   instead of 14.14 at half its collapse time).
//! * [`Renormalization::Off`].
//!
//! # Steps at the stability limit
//! [`TimeStep::Cfl`] scales the largest stable explicit step of the physical terms: the
//! upwind CFL limits of advection (Δt Σ|uₐ|/h ≤ 1) and normal speed (Δt √3|F|/h ≤ 1) and
//! the parabolic limit of the curvature term (Δt ≤ h²/(3ε)), whose rates add up
//! ([`levelset_kernels::rk`]); the coupled rescaling term adds √3 w/h.

//! # The band rule (the same for every representation)
//! Values live in `[−γ, γ]`; a voxel with |φ| < γ is a band voxel; a voxel nobody stores
//! reads −γ inside and +γ outside. A step computes exactly the voxels whose 3×3×3 box
//! holds a band voxel of φⁿ (the band dilated by one voxel), in every stage; every other
//! voxel keeps ±γ. The DT-Grid stores exactly that set (rebuilt after every step, Nielsen
//! & Museth 2006, Sec. 3.6.2: keep |φ| < γ, dilate by one, new points at ±γ); tiles (tile
//! management of Alg. 2–3 from the guard-band activity flags of Fig. 5 keeps every voxel
//! within one voxel of the band in a tile) and the dense reference store more and mask
//! with [`levelset_kernels::BandMasked`]. Reductions (κ̄, volume, area) are exact sums
//! ([`crate::exact`]) and the time step comes from maxima over the band voxels. So all three
//! representations, every lane type and every thread count compute the same numbers,
//! bit for bit; the tests check it.
//!
//! # Steps are atomic
//! A step either completes — stages, a due renormalisation, band maintenance, collapse
//! test, a due reinitialisation — or fails and leaves the simulation exactly as it was (see
//! [`Simulation`]); growth is admitted against [`Settings::memory_limit`] before it is
//! allocated. Collapse means that no interface is left as seen from the band
//! ([`Simulation::step_until`], "Collapse").
//!
//! # Layout
//! `dispatch` turns the run-time choices of a stage into one kernel type (scheme →
//! inputs → stage, plain generic functions); `rep` holds one file per representation
//! behind the internal `Representation` trait; `inputs` samples F and u; `simulation`
//! runs the steps.
//!
//! ```
//! use sparse_levelset::{storage::convert, evolve::{Flow, Settings, Simulation, GridKind, Lanes}, grid::GridSpec, storage::shapes::Shape};
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
//! let r = (3.0 * tiles.measure()?.volume / (4.0 * std::f64::consts::PI)).cbrt();
//! let exact = (12.0f64 * 12.0 - 2.0 * tiles.time()).sqrt(); // r² = r₀² − 2εt
//! assert!((r - exact).abs() < 0.1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod dispatch;
pub(crate) use dispatch::one_value;
pub mod field;
mod inputs;
mod rep;
mod simulation;

pub use field::{
    EnrightVelocity, SampledField, SampledVelocity, ScalarClosure, ScalarFn, Speed, StaticSdf,
    VectorClosure, VectorFn, Velocity,
};
pub use simulation::{Distribution, Simulation};

use crate::coord::Coord;
use crate::grid::GridError;
use levelset_kernels::KernelError;
use serde::Serialize;
use std::sync::Arc;

/// Spatial discretisation of the hyperbolic terms (normal speed, rescaling, advection).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SpatialScheme {
    /// First-order one-sided differences (van der Laan et al. 2011, Sec. 4.7).
    Upwind1,
    /// Fifth-order HJ-WENO (van der Laan et al. 2011, Sec. 5.2; Nielsen & Museth 2006, Sec. 4.1).
    Weno5,
}

/// Time integration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Forward Euler (van der Laan et al. 2011, Sec. 4.7).
    Euler,
    /// Third-order TVD Runge–Kutta of Shu & Osher 1988 (van der Laan et al. 2011, Sec. 5.2).
    Rk3,
}

impl Integrator {
    /// Sweeps of the physical terms per time step.
    pub fn stages(self) -> usize {
        match self {
            Integrator::Euler => 1,
            Integrator::Rk3 => 3,
        }
    }
}

/// Lane type of the tile engine's kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Lanes {
    /// One voxel at a time (`f32`): the same code path as the DT-Grid's arithmetic.
    Scalar,
    /// The widest vector of the CPU's instruction-set level
    /// ([`levelset_kernels::Level::default_lanes`]: `f32x16` with AVX-512, `f32x8` below).
    Simd,
}

impl Lanes {
    /// The lane kind the kernels run with, at [`levelset_kernels::Level::active`].
    pub fn kind(self) -> levelset_kernels::LaneKind {
        match self {
            Lanes::Scalar => levelset_kernels::LaneKind::F32,
            Lanes::Simd => levelset_kernels::Level::active().default_lanes(),
        }
    }
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
#[derive(Clone)]
pub struct Flow {
    /// F of eq. (3): φ_t = −F|∇φ| (F > 0 moves the interface outward).
    pub speed: Speed,
    /// ε ≥ 0, the weight of the curvature term εκ|∇φ| (κ = ½∇·(∇φ/|∇φ|), 1/r on a sphere).
    pub curvature: f32,
    /// Adds F = ε κ̄ (eq. (5)–(7)): the curvature flow conserves the enclosed volume.
    pub volume_conserving: bool,
    /// u of the advection term −u·∇φ.
    pub velocity: Option<Velocity>,
    /// Z(x), a factor of the curvature weight that varies in space: the curvature term is
    /// then ε Z(x) κ|∇φ| (ITK's curvature term; a geodesic active contour's Z is the
    /// edge potential g). `None`: Z = 1. Sampled like F; must be finite and ≥ 0.
    pub curvature_field: Option<Arc<dyn ScalarFn>>,
}

impl std::fmt::Debug for Flow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Flow")
            .field("speed", &self.speed)
            .field("curvature", &self.curvature)
            .field("volume_conserving", &self.volume_conserving)
            .field("velocity", &self.velocity)
            .field("curvature_field", &self.curvature_field.as_ref().map(|_| ".."))
            .finish()
    }
}

impl Flow {
    /// Nothing moves: F = 0, ε = 0, no advection.
    pub fn rest() -> Flow {
        Flow {
            speed: Speed::Constant(0.0),
            curvature: 0.0,
            volume_conserving: false,
            velocity: None,
            curvature_field: None,
        }
    }

    /// Motion by mean curvature with weight ε (eq. (3) with F = 0; van der Laan et al.
    /// 2011, Sec. 5.1).
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

    /// Morphing toward the level set `target` (Houston et al. 2006, eq. (1)).
    pub fn morph(target: Arc<dyn ScalarFn>) -> Flow {
        Flow::normal_speed(Speed::MorphTo(target))
    }

    /// The same flow with curvature weight ε.
    pub fn with_curvature(mut self, eps: f32) -> Flow {
        self.curvature = eps;
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

    /// The same flow with a curvature weight ε Z(x) that varies in space.
    pub fn with_curvature_field(mut self, eps: f32, z: Arc<dyn ScalarFn>) -> Flow {
        self.curvature = eps;
        self.curvature_field = Some(z);
        self
    }

    fn validate(&self) -> Result<(), EvolveError> {
        let bad = |what: &str, v: f32| {
            Err(EvolveError::InvalidParameter(format!("{what} must be finite and >= 0, got {v}")))
        };
        if !(self.curvature.is_finite() && self.curvature >= 0.0) {
            return bad("curvature weight ε", self.curvature);
        }
        if let Speed::Constant(f) = self.speed
            && !f.is_finite()
        {
            return Err(EvolveError::InvalidParameter(format!("speed F must be finite, got {f}")));
        }
        if let Some(Velocity::Constant(u)) = self.velocity
            && u.iter().any(|c| !c.is_finite())
        {
            return Err(EvolveError::InvalidParameter(format!(
                "velocity must be finite, got {u:?}"
            )));
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
    /// Spatial scheme of the physical step's hyperbolic terms (normal speed, advection).
    pub scheme: SpatialScheme,
    pub integrator: Integrator,
    pub time_step: TimeStep,
    /// How φ is kept close to a signed distance while it moves.
    pub renormalization: Renormalization,
    /// Width of the smoothed delta function of eq. (7), in voxels (κ̄ and area).
    pub delta_width: f32,
    /// The thread pool for the tile engine (the global rayon pool when `None`). The
    /// DT-Grid and dense references run on the calling thread.
    pub pool: Option<Arc<rayon::ThreadPool>>,
    /// Reinitialise the band to a signed distance by fast marching every so many steps
    /// (sparse grids only; see [`Simulation::reinitialize`]).
    pub reinit: Option<Reinit>,
    /// The most bytes the simulation's data and buffers ([`Measures::bytes`] +
    /// [`Measures::work_bytes`]) may take during a step, a reinitialisation included: a
    /// step whose band would outgrow it fails with [`GridError::OutOfMemory`] and the
    /// simulation keeps its last state. Growth is admitted before it is allocated — the
    /// step's buffers before its first stage, a new tile list before tile management
    /// builds it, a reinitialisation's second band (estimated at twice the grid) before
    /// the march — except the DT-Grid's rebuild, which is checked once built in its
    /// scratch grids and freed when refused. The dense box never grows. `None`: every
    /// growth must fit in what the machine can give ([`crate::memory::limit`]).
    pub memory_limit: Option<u64>,
    /// A lattice with a spacing of its own per axis (an image's voxels, segmentation):
    /// every derivative along axis a is divided by its spacing sₐ instead of the grid's
    /// voxel size ([`levelset_kernels::ImageRate`]), which then only sets the band's
    /// half-width γ (give it the largest spacing) and the δ width. `None`: the grid's
    /// voxel size along every axis. See [`Lattice`] for what it allows.
    pub lattice: Option<Lattice>,
    /// The largest band, in bytes of its tiles' values, on which the tile engine's forward
    /// Euler keeps φⁿ whole and writes its stage into a second value array, as TVD-RK3
    /// always does; above it, φⁿ is packed and the stage written in place. The same values
    /// either way, bit for bit: a choice of memory against time. Double-buffered, a step
    /// holds two more value arrays (a sphere of 20,500 tiles peaked at 36 MiB instead of
    /// 25) and took 0.8 × the time of the step in place (`docs/decisions/0043`); in place,
    /// the peak stays within 2.5 × the grid's bytes on large bands. Default
    /// [`Settings::DOUBLE_BUFFER_BYTES`]; 0 packs always.
    pub double_buffer_bytes: u64,
}

/// An anisotropic lattice ([`Settings::lattice`]): voxel spacing per axis, or a 2D image.
///
/// On a lattice, φ is kept a distance by the coupled rescaling term
/// ([`Renormalization::Coupled`] or [`Renormalization::Off`]; the renormalisation sweeps
/// and fast-marching reinitialisation are isotropic and refused), the flow may not be
/// volume-conserving, and [`Measures::area`] is not computed (NaN).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Lattice {
    /// World units per voxel along x, y, z (finite, > 0).
    pub spacing: [f32; 3],
    /// A 2D image laid in the slice z = const: no derivative along z, and the curvature
    /// term uses the curvature of the curve in the slice (κ = ∇·n in 2D, twice the ½∇·n
    /// of a cylinder's surface).
    pub planar: bool,
}

impl Lattice {
    /// 1/sₐ per axis, 0 along z for a planar lattice.
    pub fn inv_spacing(&self) -> [f32; 3] {
        let [x, y, z] = self.spacing.map(|s| 1.0 / s);
        [x, y, if self.planar { 0.0 } else { z }]
    }

    /// The factor of the curvature weight: 2 on a planar lattice (see [`Lattice::planar`]).
    pub fn curvature_factor(&self) -> f32 {
        if self.planar {
            2.0
        } else {
            1.0
        }
    }

    /// The smallest spacing of the axes with derivatives (the smoothed sign's width).
    pub fn min_spacing(&self) -> f32 {
        let axes = if self.planar { 2 } else { 3 };
        self.spacing[..axes].iter().fold(f32::INFINITY, |m, &s| m.min(s))
    }

    /// World volume of one voxel (area of a pixel times the z spacing when planar).
    pub fn voxel_volume(&self) -> f64 {
        self.spacing.iter().map(|&s| s as f64).product()
    }

    fn validate(&self, settings: &Settings, flow: &Flow) -> Result<(), EvolveError> {
        let invalid = |m: String| Err(EvolveError::InvalidParameter(m));
        if let Some(s) = self.spacing.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            return invalid(format!("lattice spacing must be finite and > 0, got {s}"));
        }
        if matches!(settings.renormalization, Renormalization::Sweeps(_)) {
            return invalid(
                "renormalisation sweeps are isotropic: on a lattice use the coupled rescaling \
                 term (Renormalization::Coupled) or none"
                    .into(),
            );
        }
        if settings.reinit.is_some() {
            return invalid("fast-marching reinitialisation is isotropic: not on a lattice".into());
        }
        if flow.volume_conserving {
            return invalid("volume-conserving flow is not available on a lattice".into());
        }
        Ok(())
    }
}

/// Periodic reinitialisation by fast marching.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reinit {
    /// First-order or high-accuracy fast marching.
    pub order: crate::tools::fmm::Order,
    /// After every this many steps (≥ 1).
    pub every: u64,
}

pub(crate) use rep::TILE_GRID_BYTES;

/// How many times the bytes of its tile grid (values and the list's other arrays) a
/// simulation on tiles holds while it steps with this flow and these settings, for a
/// band whose grid takes `grid_bytes`: the engine's buffers ([`Integrator::Rk3`], and
/// forward Euler on a band within [`Settings::double_buffer_bytes`], keep φⁿ whole beside
/// a double buffer; [`Renormalization::Sweeps`] keeps φⁿ; more than one sweep keeps the
/// anchors) and the flow's per-voxel inputs (a velocity field: its samples and the
/// previous ones, six values per voxel; a speed field or a morph target: two; a curvature
/// field: one). The peak a run's memory check assumes, against a band's estimated bytes
/// ([`crate::storage::convert::band_bytes`]).
pub fn tile_step_copies(flow: &Flow, settings: &Settings, grid_bytes: f64) -> f64 {
    let keeps = step_keeps(settings.integrator, settings.renormalization);
    let mut fields = 0u64;
    if matches!(flow.velocity, Some(Velocity::Field(_))) {
        fields += 6;
    }
    if !matches!(flow.speed, Speed::Constant(_)) {
        fields += 2;
    }
    if flow.curvature_field.is_some() {
        fields += 1;
    }
    let tile_values = std::mem::size_of::<crate::storage::tiles::Tile>() as u64;
    let tiles = (grid_bytes / TILE_GRID_BYTES as f64).ceil() as usize;
    let whole = keeps.whole_phi_n(tiles, settings.double_buffer_bytes);
    let bytes = rep::step_bytes_per_tile(keeps, whole) + fields * tile_values;
    bytes as f64 / TILE_GRID_BYTES as f64
}

/// What a step keeps besides the double buffer, for the memory estimates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct StepKeeps {
    /// φⁿ beside the double buffer (TVD-RK3, or a renormalisation in the step).
    pub phi_n: bool,
    /// The renormalisation's anchors (more than one sweep:
    /// [`dispatch::anchors_stored`]).
    pub anchors: bool,
    /// TVD-RK3 (whose later stages need the double buffer and φⁿ at once).
    pub rk3: bool,
    /// A forward-Euler stage (false for a renormalisation at rest).
    pub euler: bool,
}

impl StepKeeps {
    /// Whether the tile engine keeps φⁿ whole beside a double buffer on a band of `tiles`
    /// tiles, with `double_buffer_bytes` of [`Settings::double_buffer_bytes`]: always
    /// with TVD-RK3, with forward Euler where [`euler_double_buffered`]; otherwise φⁿ is
    /// packed and the sweeps write in place.
    pub fn whole_phi_n(self, tiles: usize, double_buffer_bytes: u64) -> bool {
        self.rk3 || (self.euler && euler_double_buffered(tiles, double_buffer_bytes))
    }
}

/// Whether forward Euler's stage on a band of `tiles` tiles is double-buffered: its tiles'
/// values take at most `double_buffer_bytes` ([`Settings::double_buffer_bytes`]).
pub(crate) fn euler_double_buffered(tiles: usize, double_buffer_bytes: u64) -> bool {
    tiles as u64 * std::mem::size_of::<crate::storage::tiles::Tile>() as u64 <= double_buffer_bytes
}

/// What a step with `integrator` and `renorm` keeps: the one rule of the memory budget and
/// of [`tile_step_copies`].
pub(crate) fn step_keeps(integrator: Integrator, renorm: Renormalization) -> StepKeeps {
    let rk3 = integrator == Integrator::Rk3;
    let euler = !rk3;
    match renorm {
        Renormalization::Sweeps(s) => {
            StepKeeps { phi_n: true, anchors: dispatch::anchors_stored(s.sweeps), rk3, euler }
        }
        _ => StepKeeps { phi_n: rk3, anchors: false, rk3, euler },
    }
}

/// How φ is kept close to a signed distance (|∇φ| = 1) while the flow moves it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "lowercase", tag = "kind")]
pub enum Renormalization {
    /// Nothing: |∇φ| follows the flow (a shear steepens or flattens φ and the band
    /// widens or thins).
    Off,
    /// The rescaling term w sgn(φ)(1 − |∇φ|) of eq. (3) of van der Laan et al. 2011
    /// (Sec. 3.2) as a term of the PDE, in every stage, with the smoothed sign φ/√(φ² + h²). Its
    /// rate √3 w/h counts in the step's CFL limit, so it shortens the step of slow flows
    /// (mean curvature flow takes about three times as many steps). The papers' route:
    /// the speed-up report's benchmarks run it with w = 1.
    Coupled {
        /// w ≥ 0.
        weight: f32,
    },
    /// Renormalisation as an operator of its own, outside the physical step: after every
    /// `every`-th step, `sweeps` pseudo-time sweeps of φ_τ = sgn(φ⁰)(1 − |∇φ|) with
    /// Godunov upwinding and the subcell fix of Russo & Smereka (J. Comput. Phys. 163
    /// (2000)) at the voxels next to the interface, which keeps the zero crossings in
    /// place (see [`Simulation::renormalize`]). The physical step's CFL limit then covers
    /// only the physical terms.
    Sweeps(Sweeps),
}

/// The pseudo-time sweeps of [`Renormalization::Sweeps`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Sweeps {
    /// After every this many steps (≥ 1).
    pub every: u64,
    /// Sweeps each time (≥ 1).
    pub sweeps: u32,
    /// Derivatives of the Godunov Hamiltonian: first-order one-sided differences or
    /// HJ-WENO5.
    pub scheme: SpatialScheme,
    /// Pseudo-time step Δτ = cfl · h/√3, the CFL limit of the Godunov scheme
    /// ([`levelset_kernels::rk::cfl_dt_renorm`]); in (0, 1].
    pub cfl: f32,
}

impl Default for Sweeps {
    /// One HJ-WENO5 sweep after every step at CFL 0.9. (First-order sweeps leave the
    /// distance off by O(h/r) near a curved interface, which the curvature term reads:
    /// a sphere of r₀ = 20 under mean curvature flow ends 3.5 % too large at half its
    /// collapse time with one, 0.62 % with one HJ-WENO5 sweep, 0.04 % with two.)
    fn default() -> Self {
        Sweeps { every: 1, sweeps: 1, scheme: SpatialScheme::Weno5, cfl: 0.9 }
    }
}

impl Renormalization {
    /// The weight of the coupled rescaling term (0 unless [`Renormalization::Coupled`]).
    pub fn coupled_weight(&self) -> f32 {
        match self {
            Renormalization::Coupled { weight } => *weight,
            _ => 0.0,
        }
    }

    /// Eq. (3) of van der Laan et al. 2011: the coupled rescaling term with weight 1.
    pub fn paper() -> Renormalization {
        Renormalization::Coupled { weight: 1.0 }
    }

    /// A short description: `"off"`, `"coupled w=1"`, `"sweeps 1 upwind1 every 1, cfl 0.9"`.
    pub fn describe(&self) -> String {
        match self {
            Renormalization::Off => "off".into(),
            Renormalization::Coupled { weight } => format!("coupled w={weight}"),
            Renormalization::Sweeps(s) => {
                let scheme = match s.scheme {
                    SpatialScheme::Upwind1 => "upwind1",
                    SpatialScheme::Weno5 => "weno5",
                };
                format!("sweeps {} {scheme} every {}, cfl {}", s.sweeps, s.every, s.cfl)
            }
        }
    }

    fn validate(&self) -> Result<(), EvolveError> {
        let invalid = |m: String| Err(EvolveError::InvalidParameter(m));
        match *self {
            Renormalization::Off => Ok(()),
            Renormalization::Coupled { weight } if !(weight.is_finite() && weight >= 0.0) => {
                invalid(format!("rescaling weight must be finite and >= 0, got {weight}"))
            }
            Renormalization::Coupled { .. } => Ok(()),
            Renormalization::Sweeps(s) => {
                if s.every == 0 {
                    invalid("renormalisation interval must be at least 1 step".into())
                } else if s.sweeps == 0 {
                    invalid("renormalisation needs at least 1 sweep".into())
                } else if !(s.cfl > 0.0 && s.cfl <= 1.0) {
                    invalid(format!("renormalisation CFL number must be in (0, 1], got {}", s.cfl))
                } else {
                    Ok(())
                }
            }
        }
    }
}

impl Default for Settings {
    /// HJ-WENO5 and TVD-RK3 at the physical terms' stability limit (CFL 1: TVD-RK3 is a
    /// convex combination of forward-Euler steps, so it keeps the monotone upwind step's
    /// limit; Shu & Osher, J. Comput. Phys. 77 (1988), Sec. 2), renormalisation by
    /// [`Sweeps::default`] after every step, δ width 1.5 voxels, no fast-marching
    /// reinitialisation, memory bounded by what the machine can give.
    fn default() -> Self {
        Settings {
            scheme: SpatialScheme::Weno5,
            integrator: Integrator::Rk3,
            time_step: TimeStep::Cfl(1.0),
            renormalization: Renormalization::Sweeps(Sweeps::default()),
            delta_width: 1.5,
            pool: None,
            reinit: None,
            memory_limit: None,
            lattice: None,
            double_buffer_bytes: Settings::DOUBLE_BUFFER_BYTES,
        }
    }
}

impl Settings {
    /// The default of [`Settings::double_buffer_bytes`], 64 MiB: bands of up to 262,144
    /// tiles (a sphere of radius 300 built at γ = 3 has 185,289; its evolving band about
    /// 1.3 times as many) step double-buffered, where the second
    /// value array costs little next to the machine's memory and the pack of φⁿ and the
    /// in-place sweeps cost the most against the step.
    pub const DOUBLE_BUFFER_BYTES: u64 = 64 << 20;

    /// First-order upwind and forward Euler at the stability limit (CFL 1), two HJ-WENO5
    /// renormalisation sweeps after every step: the cheapest accurate route for mean
    /// curvature flow, whose physical step has only the central curvature term (a sphere of
    /// r₀ = 100 ends within 0.0015 voxel of √(r₀² − 2t) at t = 16.67 in 50 steps).
    pub fn upwind1_euler() -> Settings {
        Settings {
            scheme: SpatialScheme::Upwind1,
            integrator: Integrator::Euler,
            renormalization: Renormalization::Sweeps(Sweeps { sweeps: 2, ..Sweeps::default() }),
            ..Settings::default()
        }
    }

    /// The first-order route of van der Laan et al. 2011 (Sec. 4.7): first-order upwind, forward
    /// Euler, the coupled rescaling term of eq. (3), CFL 0.5 — what its sphere benchmark runs.
    pub fn paper_upwind1() -> Settings {
        Settings {
            scheme: SpatialScheme::Upwind1,
            integrator: Integrator::Euler,
            time_step: TimeStep::Cfl(0.5),
            renormalization: Renormalization::paper(),
            ..Settings::default()
        }
    }

    /// The route of van der Laan et al. 2011, Sec. 5.2: HJ-WENO5, TVD-RK3, the coupled rescaling
    /// term of eq. (3), CFL 0.5.
    pub fn paper_weno5_rk3() -> Settings {
        Settings {
            scheme: SpatialScheme::Weno5,
            integrator: Integrator::Rk3,
            ..Settings::paper_upwind1()
        }
    }

    fn validate(&self, flow: &Flow) -> Result<(), EvolveError> {
        self.renormalization.validate()?;
        if let Some(l) = &self.lattice {
            l.validate(self, flow)?;
        }
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
    /// No interface is left as seen from the band (for example a shape collapsed under
    /// curvature flow; see [`Simulation::step_until`], "Collapse").
    #[error(
        "the interface collapsed at step {step}, t = {time}: the band holds no interior it \
         resolves"
    )]
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
    Reinit(#[from] crate::tools::fmm::FmmError),
    /// The periodic reinitialisation due after step `step` failed; it is part of the step,
    /// so the step was undone: the simulation is as before it (time, step count and band
    /// unchanged).
    #[error("step {step} was undone: the reinitialisation after it failed: {reason}")]
    ReinitFailed { step: u64, reason: String },
    /// Another rank of a distributed simulation failed ([`crate::distributed`]): every
    /// rank keeps its state.
    #[error("rank {rank} failed: {message}")]
    OtherRank { rank: usize, message: String },
    /// Writing an output of the run (a mesh or image frame) failed.
    #[error("output: {0}")]
    Output(String),
}

impl crate::error::Error for EvolveError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            EvolveError::Grid(e) => e.kind(),
            EvolveError::Kernel(e) => e.kind(),
            EvolveError::InvalidParameter(_)
            | EvolveError::CflViolated { .. }
            | EvolveError::DenseBoxTooSmall { .. } => InvalidInput,
            EvolveError::EmptyLevelSet => InvalidData,
            EvolveError::Collapsed { .. }
            | EvolveError::NonFiniteField { .. }
            | EvolveError::ReinitFailed { .. }
            | EvolveError::OtherRank { .. } => Failed,
            EvolveError::Reinit(e) => e.kind(),
            EvolveError::Output(_) => Io,
        }
    }
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
    /// No interface is left as seen from the band ([`Simulation::collapsed`]).
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
    /// per interior voxel that is not stored (on a [`Lattice`], its voxel volume instead
    /// of h³ and its smallest spacing as h).
    pub volume: f64,
    /// Interface area, world units: h³ Σ δ(φ)|∇φ| with the δ of eq. (7) (NaN on a
    /// [`Lattice`]).
    pub area: f64,
    /// Bytes of the representation's data (unused array capacity excluded).
    pub bytes: usize,
    /// Bytes of the evolution's buffers (double buffer, φⁿ, band mask, per-voxel speed and
    /// velocity, rebuild scratch, the previous tile list or DT-Grid kept by a step) and the
    /// representation's unused capacity.
    pub work_bytes: usize,
}

/// Runs `f` on a thread of `pool` (of the global rayon pool when `None`), so that the
/// parallel passes inside it start from a worker (a caller outside the pool is parked
/// until `f` returns).
fn in_worker<T: Send>(pool: &Option<Arc<rayon::ThreadPool>>, f: impl FnOnce() -> T + Send) -> T {
    match pool {
        Some(pool) => pool.install(f),
        None => rayon::scope(|_| f()),
    }
}

/// Runs `f` in `pool` (the global rayon pool when `None`).
fn in_pool<T: Send>(pool: &Option<Arc<rayon::ThreadPool>>, f: impl FnOnce() -> T + Send) -> T {
    match pool {
        Some(pool) => pool.install(f),
        None => f(),
    }
}
