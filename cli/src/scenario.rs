//! The papers' evolution scenarios as command-line presets (behind `levelset run` and the
//! speed-up report):
//!
//! | scenario | what | papers' setup |
//! |---|---|---|
//! | `sphere` | sphere under mean curvature flow | van der Laan et al. 2011, Sec. 5.1: 256³, r₀ = 100, first-order upwind + Euler (Sec. 4.7), 100 steps |
//! | `spiral` | extruded spiral under volume-conserving mean curvature flow | Sec. 5.2 / Table 2: 128³, radius 50, depth 40, HJ-WENO5 + TVD-RK3, 1000 steps |
//! | `enright` | Enright's deformation test | Sec. 5.4: sphere r = 0.15 at (0.35, 0.35, 0.35) in the unit box, period T = 3, 128³ |
//! | `expand` | a sphere growing at constant speed far beyond its box | Nielsen & Museth 2006, Sec. 4.3 (out-of-the-box) |
//! | `morph` | a sphere morphing into a torus | Houston et al. 2006, Sec. 6.4.1, eq. (1) |
//!
//! Two sets of numerical settings: [`ScenarioOptions::new`] takes the defaults that give
//! the right answer soonest (renormalisation by Russo–Smereka sweeps outside the step,
//! steps at the physical terms' stability limit; see [`Defaults`]); [`ScenarioOptions::paper`]
//! the papers' route (the rescaling term of eq. (3) inside the PDE, CFL 0.5, the papers'
//! step counts), which the speed-up report reproduces.
//!
//! Lengths of `sphere`, `spiral`, `expand` and `morph` are in voxels (voxel size 1, the
//! box `[0, size]³`); `enright` lives in the unit box with voxel size 1/size.

use serde::Serialize;
use sparse_levelset::distributed::{HaloStats, Transport};
use sparse_levelset::evolve::{
    tile_step_copies, EnrightVelocity, EvolveError, Flow, GridKind, Integrator, Lanes, Measures,
    Reinit, Renormalization, Settings, Simulation, SpatialScheme, Speed, StaticSdf, TimeStep,
    Velocity,
};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::io::input::{self, Expect, InputError};
use sparse_levelset::storage::convert::band_bytes;
use sparse_levelset::storage::shapes::Shape;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// The scenarios.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ScenarioKind {
    Sphere,
    Spiral,
    Enright,
    Expand,
    Morph,
}

impl ScenarioKind {
    pub const ALL: [ScenarioKind; 5] = [
        ScenarioKind::Sphere,
        ScenarioKind::Spiral,
        ScenarioKind::Enright,
        ScenarioKind::Expand,
        ScenarioKind::Morph,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ScenarioKind::Sphere => "sphere",
            ScenarioKind::Spiral => "spiral",
            ScenarioKind::Enright => "enright",
            ScenarioKind::Expand => "expand",
            ScenarioKind::Morph => "morph",
        }
    }

    /// The papers' effective resolution.
    pub fn default_size(self) -> u32 {
        match self {
            ScenarioKind::Sphere => 256,
            ScenarioKind::Spiral | ScenarioKind::Enright => 128,
            ScenarioKind::Expand | ScenarioKind::Morph => 64,
        }
    }
}

/// Every choice of a scenario run; `None` takes the scenario's default (see
/// [`Scenario::resolve`]).
#[derive(Clone, Debug)]
pub struct ScenarioOptions {
    pub kind: ScenarioKind,
    pub size: Option<u32>,
    pub steps: Option<u64>,
    pub time: Option<f64>,
    pub grid: GridKind,
    /// Worker threads of the tile engine (all cores when `None`).
    pub threads: Option<usize>,
    /// Pin worker thread i to core i (core_affinity).
    pub pin: bool,
    pub radius: Option<f64>,
    pub epsilon: Option<f32>,
    pub speed: Option<f32>,
    pub period: Option<f64>,
    pub depth: Option<f64>,
    pub half_width: f32,
    /// How φ is kept a distance [default: [`Defaults`]].
    pub renormalization: Option<Renormalization>,
    /// Spiral: volume-conserving flow (default) or plain mean curvature flow.
    pub volume_conserving: Option<bool>,
    pub scheme: Option<SpatialScheme>,
    pub integrator: Option<Integrator>,
    /// CFL number in (0, 1] [default: [`Defaults`]].
    pub cfl: Option<f32>,
    /// The papers' step counts where no steps or time are given (sphere 100, spiral
    /// 1000) instead of the physical end times.
    pub paper_steps: bool,
    /// Keep a record every this many steps (and of the first and last step).
    pub record_every: u64,
    /// Start from this dense `.npy` field instead of the scenario's shape (loaded and
    /// checked by [`sparse_levelset::io::input::load_npy`]).
    pub init: Option<PathBuf>,
    /// Voxel size of an `init` field (default: the scenario's).
    pub voxel_size: Option<f32>,
    /// Reinitialise by fast marching every so many steps.
    pub reinit: Option<Reinit>,
    /// Run distributed over the ranks of this transport (the tile engine only; see
    /// [`sparse_levelset::distributed`]).
    pub transport: Option<Arc<dyn Transport>>,
    /// Distributed: move the cuts when the largest rank holds more than (1 + this) × the
    /// smallest rank's tiles (`None`: never).
    pub rebalance: Option<f64>,
}

impl ScenarioOptions {
    /// All defaults for `kind` on the tile engine with SIMD lanes.
    pub fn new(kind: ScenarioKind) -> ScenarioOptions {
        ScenarioOptions {
            kind,
            size: None,
            steps: None,
            time: None,
            grid: GridKind::Tiles(Lanes::Simd),
            threads: None,
            pin: false,
            radius: None,
            epsilon: None,
            speed: None,
            period: None,
            depth: None,
            half_width: 3.0,
            renormalization: None,
            volume_conserving: None,
            scheme: None,
            integrator: None,
            cfl: None,
            paper_steps: false,
            record_every: 10,
            init: None,
            voxel_size: None,
            reinit: None,
            transport: None,
            rebalance: Some(0.1),
        }
    }

    /// The papers' route for `kind` (what the speed-up report runs): the scheme and
    /// integrator of [`Defaults`], the coupled rescaling term of eq. (3) with weight 1,
    /// CFL 0.5 and the papers' step counts.
    pub fn paper(kind: ScenarioKind) -> ScenarioOptions {
        ScenarioOptions {
            renormalization: Some(Renormalization::paper()),
            cfl: Some(0.5),
            paper_steps: true,
            ..ScenarioOptions::new(kind)
        }
    }
}

/// The default numerical settings of each scenario, chosen by measurement (see
/// `docs/benchmarks.md`, "Time to solution"): the physical step at CFL `cfl` of the
/// stability limit of its own terms, then the renormalisation sweeps.
#[derive(Clone, Copy, Debug)]
pub struct Defaults {
    pub scheme: SpatialScheme,
    pub integrator: Integrator,
    pub cfl: f32,
    pub renormalization: Renormalization,
}

impl Defaults {
    pub fn of(kind: ScenarioKind) -> Defaults {
        let s = match kind {
            // Mean curvature flow has no hyperbolic term: the scheme only matters for the
            // renormalisation, and forward Euler at the parabolic limit is as accurate as
            // TVD-RK3 at a third of the cost.
            ScenarioKind::Sphere | ScenarioKind::Morph => Settings::upwind1_euler(),
            ScenarioKind::Spiral | ScenarioKind::Enright | ScenarioKind::Expand => {
                Settings::default()
            }
        };
        // Both routes step at a CFL number (a fixed Δt would carry no CFL number to show).
        let cfl = match s.time_step {
            TimeStep::Cfl(c) => c,
            TimeStep::Fixed(_) => 1.0,
        };
        Defaults {
            scheme: s.scheme,
            integrator: s.integrator,
            cfl,
            renormalization: s.renormalization,
        }
    }
}

/// Every parameter of a run, resolved (what `summary.json` calls `params`).
#[derive(Clone, Debug, Serialize)]
pub struct ScenarioParams {
    pub scenario: ScenarioKind,
    pub size: u32,
    pub grid: &'static str,
    pub lanes: Option<Lanes>,
    pub threads: usize,
    pub scheme: SpatialScheme,
    pub integrator: Integrator,
    pub cfl: f32,
    pub voxel_size: f32,
    pub half_width: f32,
    /// Shape radius (world units): sphere, spiral, Enright sphere, expand, morph source.
    pub radius: f64,
    /// ε, the curvature weight.
    pub epsilon: f32,
    /// F, the normal speed (expand).
    pub speed: f32,
    /// Enright's period T.
    pub period: Option<f64>,
    /// Spiral depth.
    pub depth: Option<f64>,
    pub volume_conserving: bool,
    /// How φ is kept a distance ([`Renormalization::describe`]).
    pub renormalization: String,
    pub steps: Option<u64>,
    pub time: Option<f64>,
    pub record_every: u64,
    /// Fast-marching reinitialisation: `"fmm every K"` or `"fmm2 every K"`.
    pub reinit: Option<String>,
    /// The `--init` field, if any.
    pub init: Option<String>,
    /// The initial shape (its `Debug` form).
    pub shape: String,
    /// The morph target (its `Debug` form).
    pub target: Option<String>,
}

/// One recorded step.
#[derive(Clone, Debug, Serialize)]
pub struct Record {
    pub step: u64,
    pub time: f64,
    pub dt: f32,
    pub band_voxels: usize,
    /// Tiles (tile engine), points (DT-Grid) or voxels (dense) stored.
    pub tiles: usize,
    pub volume: f64,
    pub area: f64,
    pub bytes: usize,
    pub work_bytes: usize,
    /// Wall-clock seconds of stepping since the start (measurements excluded).
    pub seconds: f64,
}

/// The outcome of a run (`summary.json`).
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub params: ScenarioParams,
    pub records: Vec<Record>,
    pub steps_taken: u64,
    pub time: f64,
    pub collapsed: bool,
    /// FNV-1a of the final band (coordinates and value bits, [`Simulation::checksum`]).
    pub checksum: String,
    /// Seconds of stepping in all.
    pub seconds: f64,
    /// Σ over steps of voxels computed × stages / seconds.
    pub voxel_updates_per_s: f64,
    /// Σ over steps of band voxels (|φ| < γ) × stages / seconds.
    pub band_voxel_updates_per_s: f64,
    /// V(t)/V(0) at Enright's maximum deformation t = T/2 (if reached).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_ratio_half_period: Option<f64>,
    /// V(t)/V(0) after one period t = T (if reached).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_ratio_period: Option<f64>,
    /// V(end)/V(0).
    pub volume_ratio: f64,
    /// The ranks of a distributed run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distributed: Option<DistributedSummary>,
    /// The memory the run took.
    pub memory: MemorySummary,
}

/// The memory of a run: the estimate it was admitted with, what the simulation held and
/// what the process held resident, at their peaks.
#[derive(Clone, Debug, Serialize)]
pub struct MemorySummary {
    /// The peak the memory check assumed ([`Scenario::estimated_bytes`]).
    pub estimated_bytes: Option<f64>,
    /// The most bytes the simulation held at a recorded step (grid, buffers and inputs:
    /// [`Measures::bytes`] + [`Measures::work_bytes`]), this rank's.
    pub held_bytes: u64,
    /// The process's peak resident memory ([`sparse_levelset::memory::peak_resident`]).
    pub peak_resident_bytes: Option<u64>,
    /// `peak_resident_bytes` per band voxel at the end.
    pub peak_resident_per_band_voxel: Option<f64>,
    /// `peak_resident_bytes` over the grid's own bytes at the end.
    pub peak_resident_over_grid: Option<f64>,
}

impl MemorySummary {
    /// The process's peak so far against a run that ends with `band_voxels` voxels in a
    /// grid of `grid_bytes`, admitted with `estimated_bytes` and holding at most `held_bytes`.
    pub fn now(
        estimated_bytes: Option<f64>,
        held_bytes: u64,
        band_voxels: usize,
        grid_bytes: usize,
    ) -> MemorySummary {
        let peak = sparse_levelset::memory::peak_resident();
        MemorySummary {
            estimated_bytes,
            held_bytes,
            peak_resident_bytes: peak,
            peak_resident_per_band_voxel: peak
                .filter(|_| band_voxels > 0)
                .map(|p| p as f64 / band_voxels as f64),
            peak_resident_over_grid: peak
                .filter(|_| grid_bytes > 0)
                .map(|p| p as f64 / grid_bytes as f64),
        }
    }

    /// The line the tools print: `memory: peak resident … GB (… bytes per band voxel, … ×
    /// the grid's bytes); estimated before the run … GB`, or `None` where the peak is
    /// unknown (no `/proc`).
    pub fn line(&self) -> Option<String> {
        let peak = self.peak_resident_bytes?;
        let gb = |b: f64| b / 1e9;
        Some(format!(
            "memory: peak resident {:.2} GB ({:.1} bytes per band voxel, {:.2} × the grid's \
             bytes){}",
            gb(peak as f64),
            self.peak_resident_per_band_voxel.unwrap_or(f64::NAN),
            self.peak_resident_over_grid.unwrap_or(f64::NAN),
            self.estimated_bytes
                .map(|e| format!("; estimated before the run {:.2} GB", gb(e)))
                .unwrap_or_default()
        ))
    }
}

/// How a distributed run was spread over its ranks.
#[derive(Clone, Debug, Serialize)]
pub struct DistributedSummary {
    pub ranks: usize,
    /// The final cuts: rank r owns the tile z-slabs `cuts[r] ≤ tz < cuts[r + 1]` (the
    /// outer two are the i32 limits).
    pub cuts: Vec<i32>,
    /// Tiles each rank owns at the end.
    pub tiles_per_rank: Vec<u64>,
    /// The z-slabs of tiles that hold tiles at the end: the most ranks the
    /// decomposition can use.
    pub slabs: usize,
    /// Each rank's exchanges over the run.
    pub halo: Vec<HaloStats>,
}

/// A resolved scenario: the simulation and what to run.
pub struct Scenario {
    pub params: ScenarioParams,
    pub sim: Simulation,
    /// Times to land on exactly and record (Enright's T/2 and T).
    pub milestones: Vec<f64>,
    /// The peak the memory check assumed before the band was built (a shape on tiles:
    /// its band's estimated bytes times [`tile_step_copies`]).
    pub estimated_bytes: Option<f64>,
}

/// Errors of [`Scenario::resolve`]: a parameter, or the `init` field.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error(transparent)]
    Evolve(#[from] EvolveError),
    #[error(transparent)]
    Input(#[from] InputError),
}

impl From<sparse_levelset::GridError> for ScenarioError {
    fn from(e: sparse_levelset::GridError) -> Self {
        ScenarioError::Evolve(e.into())
    }
}

/// Field-sized arrays the dense reference holds (φ, φⁿ, the output, the box minima, the
/// padded copy, and the field it starts from).
const DENSE_COPIES: f64 = 6.0;

fn spec(voxel_size: f32, half_width: f32) -> Result<GridSpec, EvolveError> {
    Ok(GridSpec::new(voxel_size, [0.0; 3], half_width)?)
}

fn positive(what: &str, v: f64) -> Result<f64, EvolveError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(EvolveError::InvalidParameter(format!("{what} must be finite and > 0, got {v}")))
    }
}

/// Refuses a dense reference run whose box (the shape's band box grown by
/// [`sparse_levelset::evolve::DENSE_MARGIN`] voxels) the machine cannot hold.
fn check_dense_box(shape: &Shape, spec: &GridSpec) -> Result<(), ScenarioError> {
    let (lo, hi) = shape.bounds();
    let (vlo, vhi) = sparse_levelset::storage::sample::band_voxel_box(lo, hi, spec)?;
    let m = 2.0 * sparse_levelset::evolve::DENSE_MARGIN as f64;
    let n = |a: i32, b: i32| b as f64 - a as f64 + 1.0 + m;
    let voxels = n(vlo.x, vhi.x) * n(vlo.y, vhi.y) * n(vlo.z, vhi.z);
    sparse_levelset::memory::check(voxels * 4.0 * DENSE_COPIES, "the dense reference's box")?;
    Ok(())
}

/// Runs `run` `reps` times (at least once) and keeps the fastest (stepping seconds): on
/// a shared machine the fastest of a few runs is the one least disturbed by other work,
/// as the kernels' benchmark takes the best of its samples. Every repetition must end
/// with the same band (checksum); one that does not is an error naming `what`.
pub fn fastest_of(
    reps: usize,
    what: &str,
    mut run: impl FnMut() -> Result<(Summary, Simulation), String>,
) -> Result<(Summary, Simulation), String> {
    let mut best = fastest_interleaved(reps, &[what], |_| run())?;
    Ok(best.pop().expect("one configuration"))
}

/// A run [`fastest_interleaved`] compares: the band it ended with and its seconds.
pub trait Repetition {
    fn checksum(&self) -> &str;
    fn seconds(&self) -> f64;
}

impl Repetition for (Summary, Simulation) {
    fn checksum(&self) -> &str {
        &self.0.checksum
    }
    fn seconds(&self) -> f64 {
        self.0.seconds
    }
}

/// [`fastest_of`] for several configurations compared with one another (`what`, one name
/// each; `run(k)` runs configuration `k`): their repetitions take turns (all of them once,
/// then again), so that a stretch of disturbance on the shared machine reaches at most one
/// repetition of each instead of all the repetitions of one, as an A/B comparison
/// alternates its commands. The fastest run of each configuration, in order.
pub fn fastest_interleaved<R: Repetition>(
    reps: usize,
    what: &[&str],
    mut run: impl FnMut(usize) -> Result<R, String>,
) -> Result<Vec<R>, String> {
    let mut best: Vec<Option<R>> = what.iter().map(|_| None).collect();
    for _ in 0..reps.max(1) {
        for (k, slot) in best.iter_mut().enumerate() {
            let next = run(k)?;
            match slot {
                Some(b) if next.checksum() != b.checksum() => {
                    return Err(format!(
                        "{}: repeated runs ended with different bands (checksums {} and {})",
                        what[k],
                        b.checksum(),
                        next.checksum()
                    ));
                }
                Some(b) if next.seconds() >= b.seconds() => {}
                _ => *slot = Some(next),
            }
        }
    }
    Ok(best.into_iter().map(|b| b.expect("at least one repetition")).collect())
}

impl Scenario {
    /// Resolves the options: defaults, shape, flow, settings, the simulation. Everything is
    /// checked before the grid is built: the parameters, the `init` field (the library's
    /// loader, [`sparse_levelset::io::input`]) and the memory of the run.
    pub fn resolve(o: ScenarioOptions) -> Result<Scenario, ScenarioError> {
        let invalid = |m: String| ScenarioError::from(EvolveError::InvalidParameter(m));
        let kind = o.kind;
        let size = o.size.unwrap_or(kind.default_size());
        if !(8..=1 << 16).contains(&size) {
            return Err(invalid(format!("size must be in 8..=65536, got {size}")));
        }
        let n = size as f64;
        let c = [n / 2.0; 3];
        let threads = o.threads.unwrap_or_else(rayon::current_num_threads);
        if threads == 0 {
            return Err(invalid("threads must be >= 1".into()));
        }
        if let Some(t) = o.time {
            positive("time", t)?;
        }
        if o.steps == Some(0) {
            return Err(invalid("steps must be >= 1".into()));
        }
        if o.record_every == 0 {
            return Err(invalid("record-every must be >= 1".into()));
        }
        let mut voxel = 1.0f32;
        let mut steps = o.steps;
        let mut time = o.time;
        let mut period = None;
        let mut depth = None;
        let mut target_desc = None;
        let eps = o.epsilon;
        let defaults = Defaults::of(kind);
        let (shape, flow, radius) = match kind {
            ScenarioKind::Sphere => {
                let r = positive("radius", o.radius.unwrap_or(n * 100.0 / 256.0))?;
                let e = eps.unwrap_or(1.0);
                let shape = Shape::Sphere { center: c, radius: r };
                if steps.is_none() && time.is_none() {
                    if o.paper_steps {
                        steps = Some(100);
                    } else {
                        // Where the paper's 100 steps of Δt = h²/6 end.
                        time = Some(100.0 / 6.0 * (voxel as f64).powi(2) / e as f64);
                    }
                }
                (shape, Flow::mean_curvature(e), r)
            }
            ScenarioKind::Spiral => {
                let r = positive("radius", o.radius.unwrap_or(n * 50.0 / 128.0))?;
                let d = positive("depth", o.depth.unwrap_or(n * 40.0 / 128.0))?;
                depth = Some(d);
                let e = eps.unwrap_or(1.0);
                let shape = Shape::spiral_default(c, r, d);
                if steps.is_none() && time.is_none() {
                    if o.paper_steps {
                        steps = Some(1000);
                    } else {
                        // About where the paper's 1000 steps end (t = 104 at 128³).
                        time = Some(100.0);
                    }
                }
                let vc = o.volume_conserving.unwrap_or(true);
                let flow = if vc { Flow::volume_conserving(e) } else { Flow::mean_curvature(e) };
                (shape, flow, r)
            }
            ScenarioKind::Enright => {
                voxel = 1.0 / size as f32;
                let r = positive("radius", o.radius.unwrap_or(0.15))?;
                let t = positive("period", o.period.unwrap_or(3.0))?;
                period = Some(t);
                if steps.is_none() && time.is_none() {
                    time = Some(t);
                }
                let shape = Shape::Sphere { center: [0.35; 3], radius: r };
                let flow =
                    Flow::advection(Velocity::Field(Arc::new(EnrightVelocity { period: t })))
                        .with_curvature(eps.unwrap_or(0.0));
                (shape, flow, r)
            }
            ScenarioKind::Expand => {
                let r = positive("radius", o.radius.unwrap_or(n / 4.0))?;
                let f = o.speed.unwrap_or(1.0);
                positive("speed", f as f64)?;
                if steps.is_none() && time.is_none() {
                    // Until the sphere spans twice the box: radius = size.
                    time = Some((n - r).max(r) / f as f64);
                }
                let shape = Shape::Sphere { center: c, radius: r };
                let flow =
                    Flow::normal_speed(Speed::Constant(f)).with_curvature(eps.unwrap_or(0.0));
                (shape, flow, r)
            }
            ScenarioKind::Morph => {
                let r = positive("radius", o.radius.unwrap_or(n * 0.3))?;
                let shape = Shape::Sphere { center: c, radius: r };
                let target =
                    Shape::Torus { center: c, major_radius: n * 0.3, minor_radius: n * 0.12 };
                target_desc = Some(format!("{target:?}"));
                let g = o.half_width * voxel;
                let flow =
                    Flow::morph(Arc::new(StaticSdf { sdf: move |p| target.sdf(p), clamp: g }))
                        .with_curvature(eps.unwrap_or(0.0));
                if steps.is_none() && time.is_none() {
                    steps = Some(300);
                }
                (shape, flow, r)
            }
        };
        if steps.is_none() && time.is_none() {
            steps = Some(100);
        }
        let renormalization = o.renormalization.unwrap_or(defaults.renormalization);
        let integrator = o.integrator.unwrap_or(defaults.integrator);
        let cfl = o.cfl.unwrap_or(defaults.cfl);
        let voxel = o.voxel_size.filter(|_| o.init.is_some()).unwrap_or(voxel);
        if !(o.half_width > 1.0 && o.half_width <= 64.0) {
            return Err(invalid(format!(
                "half-width must be in (1, 64] voxels, got {}",
                o.half_width
            )));
        }
        let spec = spec(voxel, o.half_width)?;
        let dense = matches!(o.grid, GridKind::Dense);
        let mut estimated_bytes = None;
        let init = match &o.init {
            Some(path) => {
                let copies = if dense { DENSE_COPIES } else { 1.0 };
                Some(input::load_npy(path, &Expect { copies, ..Expect::new(spec) })?)
            }
            None => {
                // What the evolution holds while it steps, in tile grids of the band (the
                // DT-Grid's arrays and buffers are smaller per band voxel; the dense
                // reference's box is checked below).
                let settings = Settings { integrator, renormalization, ..Settings::default() };
                let band = band_bytes(&shape, &spec);
                let copies = tile_step_copies(&flow, &settings, band);
                input::check_shape(kind.name(), &shape, &Expect { copies, ..Expect::new(spec) })?;
                if matches!(o.grid, GridKind::Tiles(_)) {
                    estimated_bytes = Some(band * copies);
                }
                if dense {
                    check_dense_box(&shape, &spec)?;
                }
                None
            }
        };
        let pool = Arc::new(
            crate::pin::pool(threads, o.pin)
                .map_err(|e| EvolveError::InvalidParameter(format!("thread pool: {e}")))?,
        );
        let settings = Settings {
            scheme: o.scheme.unwrap_or(defaults.scheme),
            integrator,
            time_step: TimeStep::Cfl(cfl),
            renormalization,
            pool: Some(pool),
            reinit: o.reinit,
            ..Settings::default()
        };
        let params = ScenarioParams {
            scenario: kind,
            size,
            grid: o.grid.name(),
            lanes: match o.grid {
                GridKind::Tiles(l) => Some(l),
                _ => None,
            },
            threads: if matches!(o.grid, GridKind::Tiles(_)) { threads } else { 1 },
            scheme: settings.scheme,
            integrator: settings.integrator,
            cfl,
            voxel_size: voxel,
            half_width: o.half_width,
            radius,
            epsilon: flow.curvature,
            speed: match flow.speed {
                Speed::Constant(f) => f,
                _ => 0.0,
            },
            period,
            depth,
            volume_conserving: flow.volume_conserving,
            renormalization: renormalization.describe(),
            steps,
            time,
            record_every: o.record_every,
            reinit: o.reinit.map(|r| {
                let name = match r.order {
                    sparse_levelset::tools::fmm::Order::First => "fmm",
                    sparse_levelset::tools::fmm::Order::Second => "fmm2",
                };
                format!("{name} every {}", r.every)
            }),
            init: o.init.as_ref().map(|p| p.display().to_string()),
            shape: format!("{shape:?}"),
            target: target_desc,
        };
        let sim = match (&o.transport, &init) {
            (Some(t), init) => {
                let GridKind::Tiles(lanes) = o.grid else {
                    return Err(EvolveError::InvalidParameter(
                        "only the tile engine runs distributed (--grid tiles)".into(),
                    )
                    .into());
                };
                let tiles = match init {
                    Some(field) => {
                        sparse_levelset::storage::convert::tiles_from_dense(field, spec)?
                    }
                    None => sparse_levelset::storage::convert::tiles_from_shape(&shape, spec)?,
                };
                Simulation::distributed(t.clone(), tiles, lanes, flow, settings, o.rebalance)?
            }
            (None, Some(field)) => Simulation::from_dense(o.grid, field, spec, flow, settings)?,
            (None, None) => Simulation::from_shape(o.grid, &shape, spec, flow, settings)?,
        };
        let milestones = match (kind, period) {
            (ScenarioKind::Enright, Some(t)) => vec![t / 2.0, t],
            _ => Vec::new(),
        };
        Ok(Scenario { params, sim, milestones, estimated_bytes })
    }

    /// Runs to the requested steps or time (or collapse), recording every
    /// `record_every` steps; `progress(fraction done)` after every step.
    pub fn run(self, progress: impl FnMut(f64)) -> Result<(Summary, Simulation), EvolveError> {
        self.run_with(progress, |_| Ok(()))
    }

    /// [`Scenario::run`] that also calls `after(simulation)` before the first step and
    /// after every step (outside the timed part): the place to write frames (meshes,
    /// images). An error from it ends the run.
    pub fn run_with(
        mut self,
        mut progress: impl FnMut(f64),
        mut after: impl FnMut(&Simulation) -> Result<(), EvolveError>,
    ) -> Result<(Summary, Simulation), EvolveError> {
        after(&self.sim)?;
        let p = &self.params;
        let stages = p.integrator.stages();
        let m0 = self.sim.measure()?;
        let mut records = vec![record(0, 0.0, 0.0, &m0, 0.0)];
        let mut seconds = 0.0;
        let mut updates = 0f64;
        let mut band_updates = 0f64;
        let max_steps = p.steps.unwrap_or(u64::MAX);
        let end_time = p.time.unwrap_or(f64::INFINITY);
        let mut milestones = self.milestones.clone();
        let mut ratios = Vec::new();
        while self.sim.steps() < max_steps && self.sim.time() < end_time && !self.sim.collapsed() {
            let until = milestones.first().copied().unwrap_or(end_time).min(end_time);
            let computed = self.sim.stored_voxels();
            let band = self.sim.band_voxels();
            let t = Instant::now();
            let r = self.sim.step_until(until)?;
            seconds += t.elapsed().as_secs_f64();
            updates += (computed * stages) as f64;
            band_updates += (band * stages) as f64;
            let hit = milestones.first().is_some_and(|&m| self.sim.time() >= m);
            let last = self.sim.steps() >= max_steps || self.sim.time() >= end_time || r.collapsed;
            if hit || last || r.step % p.record_every == 0 {
                let m = self.sim.measure()?;
                if hit {
                    ratios.push(m.volume / m0.volume);
                    milestones.remove(0);
                }
                records.push(record(r.step, r.time, r.dt, &m, seconds));
            }
            after(&self.sim)?;
            let frac = match p.steps {
                Some(s) => self.sim.steps() as f64 / s as f64,
                None => self.sim.time() / end_time,
            };
            progress(frac.min(1.0));
        }
        let last = records.last().expect("the initial record");
        // Collective: every rank of a distributed run gets here.
        let distributed = self.sim.distribution().map(|d| {
            let cuts = d.cuts().map(|(_, cuts)| cuts).unwrap_or_default();
            DistributedSummary {
                ranks: cuts.len().saturating_sub(1),
                cuts,
                tiles_per_rank: d.tiles_per_rank(),
                slabs: d.slabs().unwrap_or(0),
                halo: d.halo_stats_per_rank(),
            }
        });
        let summary = Summary {
            params: self.params,
            steps_taken: self.sim.steps(),
            time: self.sim.time(),
            collapsed: self.sim.collapsed(),
            checksum: format!("{:016x}", self.sim.checksum()),
            seconds,
            voxel_updates_per_s: if seconds > 0.0 { updates / seconds } else { 0.0 },
            band_voxel_updates_per_s: if seconds > 0.0 { band_updates / seconds } else { 0.0 },
            volume_ratio_half_period: ratios.first().copied(),
            volume_ratio_period: ratios.get(1).copied(),
            volume_ratio: last.volume / m0.volume,
            memory: memory_summary(&records, self.estimated_bytes),
            records,
            distributed,
        };
        Ok((summary, self.sim))
    }
}

fn memory_summary(records: &[Record], estimated_bytes: Option<f64>) -> MemorySummary {
    let last = records.last().expect("the initial record");
    let held = records.iter().map(|r| (r.bytes + r.work_bytes) as u64).max().unwrap_or(0);
    MemorySummary::now(estimated_bytes, held, last.band_voxels, last.bytes)
}

fn record(step: u64, time: f64, dt: f32, m: &Measures, seconds: f64) -> Record {
    Record {
        step,
        time,
        dt,
        band_voxels: m.band_voxels,
        tiles: m.stored,
        volume: m.volume,
        area: m.area,
        bytes: m.bytes,
        work_bytes: m.work_bytes,
        seconds,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    impl Repetition for (String, f64) {
        fn checksum(&self) -> &str {
            &self.0
        }
        fn seconds(&self) -> f64 {
            self.1
        }
    }

    #[test]
    fn configurations_take_turns_and_keep_their_fastest_run() {
        let seconds = [[3.0, 2.0, 5.0], [1.0, 4.0, 0.5]];
        let mut calls = Vec::new();
        let mut rep = [0usize; 2];
        let best = fastest_interleaved(3, &["a", "b"], |k| {
            calls.push(k);
            let s = seconds[k][rep[k]];
            rep[k] += 1;
            Ok((format!("band {k}"), s))
        })
        .unwrap();
        assert_eq!(calls, [0, 1, 0, 1, 0, 1]);
        assert_eq!(best, [("band 0".to_string(), 2.0), ("band 1".to_string(), 0.5)]);
        // A repetition that ends with another band is an error naming its configuration.
        let mut n = 0;
        let e = fastest_interleaved(2, &["a", "b"], |k| {
            n += 1;
            Ok((if n == 4 { "other".into() } else { format!("band {k}") }, 1.0))
        })
        .unwrap_err();
        assert!(e.starts_with("b: repeated runs ended with different bands"), "{e}");
        // At least one run each, whatever `reps`.
        let once = fastest_interleaved(0, &["a"], |_| Ok(("x".to_string(), 1.0))).unwrap();
        assert_eq!(once.len(), 1);
    }
}
