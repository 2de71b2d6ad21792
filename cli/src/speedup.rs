//! The speed-up report of `levelset-speedup` (what `cargo run --release` runs): the papers
//! evolution scenarios on the DT-Grid, on tiles with scalar lanes, with SIMD lanes on one
//! thread and with SIMD lanes on every thread — the same flows, kernels and band rule, so
//! the ratios measure the data structures and the lanes (van der Laan et al. 2011, Sec. 5: the same
//! level-set code on both structures).
//!
//! Every run of a scenario ends with the same band, bit for bit (see [`sparse_levelset::evolve`]):
//! the report shows the checksums and the largest difference of the final φ between the
//! DT-Grid and each tile run.
//!
//! Its last section, time to solution ([`crate::solution`]), runs each scenario to its
//! physical end with its own settings and reports the seconds beside the error against
//! the analytic answer.

use crate::scenario::{Scenario, ScenarioKind, ScenarioOptions};
use crate::solution::SolutionRun;
use serde::Serialize;
use sparse_levelset::evolve::{GridKind, Lanes, Simulation};
use sparse_levelset::Coord;

/// What to run.
#[derive(Clone, Debug)]
pub struct SpeedupConfig {
    /// Worker threads of the "all threads" run (default: every core).
    pub threads: usize,
    /// Pin the worker threads to cores (core_affinity).
    pub pin: bool,
    /// The spiral's 1000 iterations (van der Laan et al. 2011, Table 2) instead of the short
    /// run.
    pub full: bool,
    /// A quick look: small sizes and few steps (not a measurement).
    pub quick: bool,
    /// Runs of every configuration; the fastest is reported ([`crate::scenario::fastest_of`]).
    pub reps: usize,
}

impl Default for SpeedupConfig {
    fn default() -> Self {
        SpeedupConfig {
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            pin: false,
            full: false,
            quick: false,
            reps: 3,
        }
    }
}

/// One run of one scenario.
#[derive(Clone, Debug, Serialize)]
pub struct RunResult {
    /// "DT-Grid", "tiles scalar" or "tiles SIMD" (for the text table).
    #[serde(skip)]
    pub label: &'static str,
    /// `"dtgrid"` or `"tiles"`.
    pub grid: &'static str,
    /// `"scalar"` or `"simd"` (`"scalar"` for the DT-Grid, whose arithmetic is scalar).
    pub lanes: &'static str,
    pub threads: usize,
    /// Seconds of stepping (set-up and measurements excluded).
    pub seconds: f64,
    /// Stored voxels (DT-Grid points, tiles × 64) × RK stages per second.
    pub voxel_updates_per_s: f64,
    /// Band voxels (|φ| < γ) × stages per second: the same numerator for every run.
    pub band_voxel_updates_per_s: f64,
    /// Bytes of the representation's data at the end.
    pub bytes: usize,
    pub bytes_vs_dtgrid: f64,
    pub speedup_vs_dtgrid: f64,
    /// The most bytes the simulation held while it stepped (the representation, its step
    /// buffers and the flow's per-voxel inputs), per band voxel at the end.
    pub held_bytes_per_band_voxel: f64,
    /// Checksum of the final band (equal for equal bands).
    pub checksum: String,
}

/// One scenario: its runs and how they compare.
#[derive(Clone, Debug, Serialize)]
pub struct ScenarioBench {
    pub name: &'static str,
    pub size: u32,
    pub steps: u64,
    /// The kernels benchmark's kernel of the same arithmetic (`upwind_curvature` for
    /// first-order runs, `weno5_rk3` for HJ-WENO5 + TVD-RK3) ...
    pub kernel: &'static str,
    /// ... at the lane type of the tile engine's SIMD runs.
    pub kernel_lanes: &'static str,
    pub kernel_voxel_updates_per_s: f64,
    /// Tiles, SIMD, one thread: voxel-updates/s over the kernel-only throughput.
    pub engine_fraction_of_kernel: f64,
    /// Largest |φ_tiles − φ_dtgrid| over the band voxels of either, over all tile runs.
    pub max_abs_diff: f32,
    pub runs: Vec<RunResult>,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct SpeedupReport {
    pub cpu: String,
    pub target_features: Vec<&'static str>,
    /// The instruction-set level the kernels ran at ([`levelset_kernels::Level::active`]).
    pub level: &'static str,
    pub profile: &'static str,
    pub threads: usize,
    pub pinned: bool,
    /// Runs of every configuration (scenarios and time to solution); the fastest is shown.
    pub reps: usize,
    pub scenarios: Vec<ScenarioBench>,
    /// The operators around the evolution (fast marching, isosurfacing) on the sphere
    /// benchmark's initial band.
    pub tools: Vec<ToolBench>,
    /// Each scenario run to its end with its own settings: seconds and error
    /// ([`crate::solution::run_time_to_solution`]).
    pub time_to_solution: Vec<SolutionRun>,
    /// Segmentation of a noisy phantom ([`crate::segbench::run_segmentation`]).
    pub segmentation: Vec<crate::segbench::SegmentBench>,
}

impl SpeedupReport {
    /// The report's heading (machine, build, threads) without any section.
    pub fn new(cfg: &SpeedupConfig) -> SpeedupReport {
        SpeedupReport {
            cpu: crate::storage::cpu_name(),
            target_features: levelset_kernels::target_features(),
            level: levelset_kernels::Level::active().name(),
            profile: crate::storage::build_profile(),
            threads: cfg.threads,
            pinned: cfg.pin,
            reps: cfg.reps,
            scenarios: Vec::new(),
            tools: Vec::new(),
            time_to_solution: Vec::new(),
            segmentation: Vec::new(),
        }
    }
}

/// One operator's throughput.
#[derive(Clone, Debug, Serialize)]
pub struct ToolBench {
    /// What ran, e.g. `"fmm reinitialise, first order"`.
    pub name: &'static str,
    /// `"tiles"` or `"dtgrid"`.
    pub grid: &'static str,
    /// Band voxels (|φ| < γ) of the input.
    pub band_voxels: usize,
    /// Best of three runs, seconds.
    pub seconds: f64,
    pub band_voxels_per_s: f64,
    /// What the result holds (band voxels, triangles), for the text table.
    pub output: String,
}

/// Best-of-`reps` seconds of `f`, with the result of the last run.
fn best_of<T>(reps: usize, mut f: impl FnMut() -> Result<T, String>) -> Result<(f64, T), String> {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..reps {
        let t = std::time::Instant::now();
        let r = f()?;
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    Ok((best, out.expect("at least one run")))
}

/// Fast marching (both orders, both grids; sequential by nature) and isosurfacing (tiles,
/// every thread) of the sphere scenario's initial band (radius 100·N/256 voxels, γ = 3):
/// the report's operators section, also alone (`levelset-speedup --tools`).
pub fn run_tools(
    cfg: &SpeedupConfig,
    mut progress: impl FnMut(&str),
) -> Result<Vec<ToolBench>, String> {
    use sparse_levelset::tools::fmm::{FmmOptions, Order};
    let n = if cfg.quick { 64.0 } else { 256.0 };
    let c = n / 2.0;
    let shape = sparse_levelset::storage::shapes::Shape::Sphere {
        center: [c, c, c],
        radius: 100.0 * n / 256.0,
    };
    let spec = sparse_levelset::grid::GridSpec::default();
    let tiles = sparse_levelset::storage::convert::tiles_from_shape(&shape, spec)
        .map_err(|e| e.to_string())?;
    let dt = sparse_levelset::storage::convert::dtgrid_from(&tiles);
    let band = tiles.band_voxels();
    let mut out = Vec::new();
    let reps = if cfg.quick { 1 } else { 3 };
    let mut push = |name, grid, seconds: f64, output: String| {
        out.push(ToolBench {
            name,
            grid,
            band_voxels: band,
            seconds,
            band_voxels_per_s: band as f64 / seconds,
            output,
        })
    };
    for (order, name) in [
        (Order::First, "fmm reinitialise, first order"),
        (Order::Second, "fmm reinitialise, second order"),
    ] {
        let opts = FmmOptions { order, ..Default::default() };
        progress(&format!("{name} (tiles)"));
        let (s, g) = best_of(reps, || {
            sparse_levelset::tools::fmm::reinitialize(&tiles, &opts).map_err(|e| e.to_string())
        })?;
        push(name, "tiles", s, format!("{} band voxels", g.band_voxels()));
        progress(&format!("{name} (DT-Grid)"));
        let (s, g) = best_of(reps, || {
            sparse_levelset::tools::fmm::reinitialize(&dt, &opts).map_err(|e| e.to_string())
        })?;
        push(name, "dtgrid", s, format!("{} band voxels", g.band_voxels()));
    }
    let name = "isosurface (simplicial, welded)";
    progress(&format!("{name} (tiles)"));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cfg.threads)
        .build()
        .map_err(|e| format!("thread pool: {e}"))?;
    let (s, m) = best_of(reps, || {
        pool.install(|| sparse_levelset::tools::mesh::isosurface(&tiles, &Default::default()))
            .map_err(|e| e.to_string())
    })?;
    push(name, "tiles", s, format!("{} triangles, {} thread(s)", m.triangles.len(), cfg.threads));
    Ok(out)
}

/// The scenarios with their sizes and fixed step counts.
fn plan(cfg: &SpeedupConfig) -> Vec<(ScenarioKind, u32, u64)> {
    if cfg.quick {
        return vec![
            (ScenarioKind::Sphere, 64, 4),
            (ScenarioKind::Spiral, 48, 4),
            (ScenarioKind::Enright, 48, 4),
        ];
    }
    vec![
        (ScenarioKind::Sphere, 256, 100),
        (ScenarioKind::Spiral, 128, if cfg.full { 1000 } else { 150 }),
        (ScenarioKind::Enright, 256, 60),
    ]
}

fn band(sim: &Simulation) -> Vec<(Coord, f32)> {
    let mut v = Vec::new();
    sim.for_each_band_voxel(|c, x| v.push((c, x)));
    v
}

/// Largest |a − b| over the band voxels of either band (a voxel missing on one side
/// reads ±γ there, through the simulation's random access).
fn max_abs_diff(a: &[(Coord, f32)], sa: &Simulation, b: &[(Coord, f32)], sb: &Simulation) -> f32 {
    let (mut i, mut j, mut m) = (0, 0, 0.0f32);
    while i < a.len() || j < b.len() {
        let d = match (a.get(i), b.get(j)) {
            (Some(&(ca, va)), Some(&(cb, vb))) if ca == cb => {
                i += 1;
                j += 1;
                (va - vb).abs()
            }
            (Some(&(ca, va)), Some(&(cb, _))) if ca < cb => {
                i += 1;
                (va - sb.value(ca)).abs()
            }
            (Some(&(ca, va)), None) => {
                i += 1;
                (va - sb.value(ca)).abs()
            }
            (_, Some(&(cb, vb))) => {
                j += 1;
                (sa.value(cb) - vb).abs()
            }
            (None, None) => unreachable!("the loop condition"),
        };
        m = m.max(d);
    }
    m
}

/// Runs the report's speed-up sections (the scenarios and the operators; the time to
/// solution is [`crate::solution::run_time_to_solution`]); `progress(message)` before
/// every run.
pub fn run_speedup(
    cfg: &SpeedupConfig,
    kernels: &[levelset_kernels::bench::KernelResult],
    mut progress: impl FnMut(&str),
) -> Result<SpeedupReport, String> {
    // The lane type the tile engine's SIMD runs use.
    let engine_lanes = Lanes::Simd.kind().name();
    let mut scenarios = Vec::new();
    for (kind, size, steps) in plan(cfg) {
        let runs_plan: [(GridKind, usize); 4] = [
            (GridKind::DtGrid, 1),
            (GridKind::Tiles(Lanes::Scalar), 1),
            (GridKind::Tiles(Lanes::Simd), 1),
            (GridKind::Tiles(Lanes::Simd), cfg.threads),
        ];
        let mut runs = Vec::new();
        let mut reference: Option<(Vec<(Coord, f32)>, Simulation)> = None;
        let mut max_diff = 0.0f32;
        let mut kernel = "";
        let whats: Vec<String> = runs_plan
            .iter()
            .map(|&(grid, threads)| {
                format!("{} {size}³: {} {threads} thread(s)", kind.name(), grid_label(grid))
            })
            .collect();
        let names: Vec<&str> = whats.iter().map(String::as_str).collect();
        // The configurations take turns, repetition by repetition (see
        // `fastest_interleaved`): the ratios between them compare runs of the same moments.
        let bests = crate::scenario::fastest_interleaved(cfg.reps, &names, |k| {
            let ((grid, threads), what) = (runs_plan[k], names[k]);
            progress(what);
            let mut o = ScenarioOptions::paper(kind);
            o.size = Some(size);
            o.steps = Some(steps);
            o.grid = grid;
            o.threads = Some(threads);
            o.pin = cfg.pin;
            o.record_every = u64::MAX;
            let sc = Scenario::resolve(o).map_err(|e| format!("{what}: {e}"))?;
            kernel = match sc.params.scheme {
                sparse_levelset::evolve::SpatialScheme::Upwind1 => "upwind_curvature",
                sparse_levelset::evolve::SpatialScheme::Weno5 => "weno5_rk3",
            };
            sc.run(|_| {}).map_err(|e| format!("{what}: {e}"))
        })?;
        for ((grid, threads), (summary, sim)) in runs_plan.into_iter().zip(bests) {
            let last = summary.records.last().expect("records");
            let b = band(&sim);
            if let Some((rb, rs)) = &reference {
                max_diff = max_diff.max(max_abs_diff(&b, &sim, rb, rs));
            }
            runs.push(RunResult {
                label: grid_label(grid),
                grid: grid.name(),
                lanes: match grid {
                    GridKind::Tiles(Lanes::Simd) => "simd",
                    _ => "scalar",
                },
                threads,
                seconds: summary.seconds,
                voxel_updates_per_s: summary.voxel_updates_per_s,
                band_voxel_updates_per_s: summary.band_voxel_updates_per_s,
                bytes: last.bytes,
                bytes_vs_dtgrid: 0.0,
                speedup_vs_dtgrid: 0.0,
                held_bytes_per_band_voxel: summary.memory.held_bytes as f64
                    / last.band_voxels.max(1) as f64,
                checksum: summary.checksum.clone(),
            });
            if reference.is_none() {
                reference = Some((b, sim));
            }
        }
        let (dt_s, dt_b) = (runs[0].seconds, runs[0].bytes as f64);
        for r in &mut runs {
            r.speedup_vs_dtgrid = dt_s / r.seconds;
            r.bytes_vs_dtgrid = r.bytes as f64 / dt_b;
        }
        let k = kernels
            .iter()
            .find(|r| r.kernel == kernel && r.lanes == engine_lanes)
            .map_or(0.0, |r| r.voxel_updates_per_s);
        scenarios.push(ScenarioBench {
            name: kind.name(),
            size,
            steps,
            kernel,
            kernel_lanes: engine_lanes,
            kernel_voxel_updates_per_s: k,
            engine_fraction_of_kernel: if k > 0.0 { runs[2].voxel_updates_per_s / k } else { 0.0 },
            max_abs_diff: max_diff,
            runs,
        });
    }
    let tools = run_tools(cfg, progress)?;
    Ok(SpeedupReport { scenarios, tools, ..SpeedupReport::new(cfg) })
}

fn grid_label(g: GridKind) -> &'static str {
    match g {
        GridKind::DtGrid => "DT-Grid",
        GridKind::Tiles(Lanes::Scalar) => "tiles scalar",
        GridKind::Tiles(Lanes::Simd) => "tiles SIMD",
        GridKind::Dense => "dense",
    }
}

impl SpeedupReport {
    /// The report as a text table.
    pub fn to_text(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "CPU: {}; level: {}; target features compiled in: {}; {} build; up to {} \
             thread(s){}; stepping seconds: the fastest of {} run(s) of each configuration",
            self.cpu,
            levelset_kernels::Level::from_name(self.level)
                .map_or(self.level.to_string(), |l| l.describe()),
            self.target_features.join(","),
            self.profile,
            self.threads,
            if self.pinned { ", pinned" } else { "" },
            self.reps
        );
        for sc in &self.scenarios {
            let _ = writeln!(
                s,
                "\n{} {}³, {} steps: kernel-only {} ({}) {:.1} Mvox/s; tiles SIMD 1 thread \
                 reaches {:.0} % of it; max |φ_tiles − φ_dtgrid| = {}",
                sc.name,
                sc.size,
                sc.steps,
                sc.kernel,
                sc.kernel_lanes,
                sc.kernel_voxel_updates_per_s / 1e6,
                100.0 * sc.engine_fraction_of_kernel,
                sc.max_abs_diff
            );
            let _ = writeln!(
                s,
                "  {:<13} {:>7} {:>9} {:>10} {:>13} {:>9} {:>11} {:>8} {:>9}  checksum",
                "grid",
                "threads",
                "seconds",
                "Mvox/s",
                "band Mvox/s",
                "speed-up",
                "bytes",
                "bytes/DT",
                "held B/bv"
            );
            for r in &sc.runs {
                let _ = writeln!(
                    s,
                    "  {:<13} {:>7} {:>9.3} {:>10.1} {:>13.1} {:>8.2}x {:>11} {:>8.2} {:>9.1}  {}",
                    r.label,
                    r.threads,
                    r.seconds,
                    r.voxel_updates_per_s / 1e6,
                    r.band_voxel_updates_per_s / 1e6,
                    r.speedup_vs_dtgrid,
                    r.bytes,
                    r.bytes_vs_dtgrid,
                    r.held_bytes_per_band_voxel,
                    r.checksum
                );
            }
        }
        if !self.tools.is_empty() {
            let _ = writeln!(s, "\nOperators on the sphere benchmark's initial band:");
            let _ = writeln!(
                s,
                "  {:<34} {:<7} {:>11} {:>9} {:>14}  result",
                "operator", "grid", "band voxels", "seconds", "band Mvox/s"
            );
            for t in &self.tools {
                let _ = writeln!(
                    s,
                    "  {:<34} {:<7} {:>11} {:>9.3} {:>14.2}  {}",
                    t.name,
                    t.grid,
                    t.band_voxels,
                    t.seconds,
                    t.band_voxels_per_s / 1e6,
                    t.output
                );
            }
        }
        if !self.scenarios.is_empty() {
            s.push_str(
                "\nMvox/s: stored voxels (DT-Grid points, tiles x 64) x RK stages per second of \
                 stepping; band Mvox/s: voxels with |phi| < gamma x stages per second (the same \
                 work for every run).\n",
            );
        }
        s.push_str(&crate::segbench::to_text(&self.segmentation));
        s.push_str(&crate::solution::to_text(&self.time_to_solution));
        s
    }
}
