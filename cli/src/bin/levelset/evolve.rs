//! `levelset evolve IN -o OUT`: a user's level set (any format) under a flow — motion in
//! the normal direction, by mean curvature, volume-conserving, advection by a velocity
//! field read from a file, or their sum — for a time or a number of steps, with the
//! engine's defaults (first-order upwind, forward Euler at CFL 1, the coupled
//! renormalisation). Under `mpirun` the band is split into z-slabs over the ranks, as
//! `levelset run` does, and gathered for the output.

use crate::source::{level_set_output, FileGridArgs};
use clap::Args;
use levelset_cli::output::{check_output, stage_json};
use levelset_cli::scenario::MemorySummary;
use levelset_cli::{outln, progress};
use sparse_levelset::evolve::Velocity;
use sparse_levelset::evolve::{
    tile_step_copies, Flow, GridKind, Lanes, SampledVelocity, Settings, Simulation, Speed,
};
use sparse_levelset::io::fsutil::Outputs;
use sparse_levelset::io::input::Expect;
use sparse_levelset::io::{self, AnyLevelSet};
use sparse_levelset::storage::convert::{evolving_bytes, tiles_from};
use sparse_levelset::Coord;
use std::path::PathBuf;
use std::sync::Arc;

fn parse_voxel(s: &str) -> Result<Coord, String> {
    let v: Vec<i32> = s
        .split(',')
        .map(|t| t.trim().parse::<i32>().map_err(|e| format!("{t:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] => Ok(Coord::new(x, y, z)),
        _ => Err(format!("expected X,Y,Z (three integers), got {s:?}")),
    }
}

#[derive(Args)]
pub struct EvolveArgs {
    /// The level set: .npy (dense, on --voxel-size and --half-width), .sls or .vdb.
    pub input: PathBuf,
    /// Output, written atomically in the format its extension names (.sls, .vdb or .npy).
    #[arg(short, long, value_name = "OUT.sls|OUT.vdb|OUT.npy")]
    pub output: PathBuf,
    /// Speed F in the normal direction, world units per unit time (> 0 moves outwards).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub speed: f32,
    /// Weight ε ≥ 0 of motion by mean curvature (speed −ε H; a sphere's r² shrinks by 2εt).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub curvature: f32,
    /// Conserve the enclosed volume (the curvature flow's mean removed).
    #[arg(long)]
    pub volume_conserving: bool,
    /// Advect by a velocity field u (φ_t + u·∇φ = 0, world units per unit time): a float32
    /// .npy of shape (nz, ny, nx, 3) on the level set's lattice, element [0, 0, 0] at voxel
    /// --velocity-origin, or an OpenVDB .vdb's first vector grid (Vec3s) placed by its own
    /// transform; trilinear between voxels, the nearest face's value beyond.
    #[arg(long, value_name = "FILE.npy|FILE.vdb")]
    pub velocity: Option<PathBuf>,
    /// The voxel (x, y, z) of the level set's lattice where a .npy velocity field's element
    /// [0, 0, 0] lies.
    #[arg(long, value_name = "X,Y,Z", default_value = "0,0,0", value_parser = parse_voxel)]
    pub velocity_origin: Coord,
    /// Evolve until this time.
    #[arg(long, conflicts_with = "steps", allow_hyphen_values = true)]
    pub time: Option<f64>,
    /// Evolve this many steps.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub steps: Option<u64>,
    /// Also write a JSON summary (steps, time, band voxels, checksum, seconds) here,
    /// together with the output.
    #[arg(long, value_name = "FILE.json")]
    pub summary: Option<PathBuf>,
    #[command(flatten)]
    pub grid: FileGridArgs,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: &EvolveArgs) -> Result<(), String> {
    if !(a.speed.is_finite() && a.curvature.is_finite() && a.curvature >= 0.0) {
        return Err("--speed must be finite and --curvature finite and ≥ 0".into());
    }
    let (time, steps) = match (a.time, a.steps) {
        (Some(t), None) if t.is_finite() && t > 0.0 => (t, u64::MAX),
        (None, Some(n)) => (f64::INFINITY, n),
        _ => return Err("give --time T (finite, > 0) or --steps N".into()),
    };
    let spec = a.grid.spec()?;
    level_set_output(&a.output)?;
    if let Some(s) = &a.summary {
        check_output(s)?;
    }
    let (pool, threads) = a.grid.pool()?;
    let pool = std::sync::Arc::new(pool);
    let name = a.input.display().to_string();
    // The input alone here; the evolution's working copies are checked below, once the
    // flow is known and before the first step.
    let loaded = pool
        .install(|| io::load_level_set(&a.input, &Expect::new(spec)))
        .map_err(|e| e.to_string())?;
    let tiles = match loaded.level_set {
        AnyLevelSet::Tiles(t) => t,
        AnyLevelSet::Hrle(h) => tiles_from(&h),
    };
    // The velocity field: on the level set's lattice (a .npy) or its own (a .vdb).
    let velocity = match &a.velocity {
        Some(p) => {
            let f = io::load_vector_field(p, tiles.spec(), a.velocity_origin)
                .map_err(|e| e.to_string())?;
            let u = SampledVelocity::new(f.components, f.spec)
                .map_err(|e| format!("{}: {e}", p.display()))?;
            Some(Velocity::Field(Arc::new(u)))
        }
        None => None,
    };
    let flow = Flow {
        speed: Speed::Constant(a.speed),
        curvature: a.curvature,
        volume_conserving: a.volume_conserving,
        velocity,
        ..Flow::rest()
    };
    let settings = Settings { pool: Some(pool.clone()), ..Settings::default() };
    // What the steps will hold: the evolving band's grid times the working copies (the
    // rule of `levelset run`'s estimate), checked against the machine's and the process's
    // limits before any step; the loaded grid is held already.
    let evolving = evolving_bytes(&tiles);
    let estimated = tile_step_copies(&flow, &settings, evolving) * evolving;
    sparse_levelset::memory::check(
        estimated - tiles.memory().used() as f64,
        "the evolution's working copies of the level set",
    )
    .map_err(|e| format!("{name}: {e}"))?;
    // Under mpirun (a build with the mpi feature): every rank evolves its z-slabs of the
    // band; rank 0 gathers the band, reports and writes.
    let transport = levelset_cli::ranks::transport()?;
    let ranks = transport.as_ref().map_or(1, |t| t.size());
    let lead = transport.as_ref().is_none_or(|t| t.rank() == 0);
    let mut sim = match &transport {
        Some(t) => {
            Simulation::distributed(t.clone(), tiles, Lanes::Simd, flow, settings, Some(0.1))
        }
        None => Simulation::from_tile_grid(GridKind::Tiles(Lanes::Simd), tiles, flow, settings),
    }
    .map_err(|e| format!("{name}: {e}"))?;
    let len = if steps == u64::MAX { 1000 } else { steps };
    let bar = progress::bar(
        a.quiet || !lead,
        len,
        "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}%",
    );
    let start = std::time::Instant::now();
    sim.run_until(time, steps, |s, _| {
        bar.set_position(if steps == u64::MAX {
            (1000.0 * s.time() / time) as u64
        } else {
            s.steps()
        });
    })
    .map_err(|e| format!("{name}: {e}"))?;
    let seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    // One pass each over the band (collective when distributed), the bytes held, and the
    // whole band.
    let (band_voxels, checksum) = (sim.band_voxels(), sim.checksum());
    let [grid_bytes, work_bytes] = sim.held_bytes();
    let memory = MemorySummary::now(
        Some(estimated),
        (grid_bytes + work_bytes) as u64,
        band_voxels,
        grid_bytes,
    );
    let gathered = match transport {
        Some(_) => sim.gathered_tiles().map_err(|e| format!("{name}: {e}"))?,
        None => None,
    };
    if !lead {
        return Ok(());
    }
    let summary = serde_json::json!({
        "input": name,
        "steps": sim.steps(),
        "time": sim.time(),
        "collapsed": sim.collapsed(),
        "band_voxels": band_voxels,
        "checksum": format!("{checksum:016x}"),
        "seconds": seconds,
        "threads": threads,
        "ranks": ranks,
        "memory": memory,
    });
    // The level set and the summary appear together.
    let mut outputs = Outputs::new();
    let staged = outputs.stage(&a.output);
    let opts = io::SaveOptions::default();
    match &gathered {
        Some(whole) => pool.install(|| io::save_level_set(&staged, whole, &opts)),
        None => pool.install(|| io::save_level_set(&staged, &sim, &opts)),
    }
    .map_err(|e| outputs.named(e))?;
    if let Some(s) = &a.summary {
        let staged = outputs.stage(s);
        stage_json(&staged, &summary).map_err(|e| outputs.named(e))?;
    }
    outputs.commit().map_err(|e| format!("{}: {e}", a.output.display()))?;
    outln!(
        "{name} -> {}: {} steps to t = {:.4e}, {} band voxels, checksum {:016x}, {seconds:.3} s",
        a.output.display(),
        sim.steps(),
        sim.time(),
        band_voxels,
        checksum
    );
    if let Some(line) = memory.line() {
        outln!("{line}");
    }
    Ok(())
}
