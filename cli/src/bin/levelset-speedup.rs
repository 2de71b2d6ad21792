//! `levelset-speedup`: the speed-up report, what `cargo run --release` runs at the
//! repository's root — the papers' scenarios on the DT-Grid and on tiles (scalar, SIMD on
//! one thread, SIMD on every thread) with the kernel-only throughput, then the time to
//! solution (each scenario run to its end, seconds and error); `--solution`: that section
//! alone; `--storage`: the storage benchmark; `--kernels`: the kernels alone.

use clap::Parser;
use levelset_cli::output::{check_output, write_json};
use levelset_cli::storage::{cpu_name, kernels_text, run_scenario, StorageBench};
use levelset_cli::{out, outln, progress};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::shapes::Shape;
use std::path::PathBuf;
use std::process::ExitCode;

/// The speed-up of the Sorted Tile List over the DT-Grid: the papers' scenarios on both
/// (DT-Grid, tiles scalar, tiles SIMD on one thread and on every thread), with the
/// kernel-only throughput, and the time to solution: each scenario run to its end with its
/// own settings on 1 and on every thread, seconds and the error against the analytic
/// answer. `--solution`: that section only; `--storage`: the storage benchmark;
/// `--kernels`: kernels only.
#[derive(Parser)]
#[command(name = "levelset-speedup", version)]
struct BenchArgs {
    /// Smaller shapes and fewer repetitions (a quick look, not a measurement).
    #[arg(long)]
    quick: bool,
    /// The storage benchmark instead: the same stencil arithmetic, random access and band
    /// maintenance on both grids.
    #[arg(long, conflicts_with = "kernels")]
    storage: bool,
    /// Worker threads of the "all threads" runs [default: every core].
    #[arg(long, allow_hyphen_values = true,
          value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Pin worker threads to cores.
    #[arg(long)]
    pin: bool,
    /// The spiral's 1000 iterations (van der Laan et al. 2011, Table 2) instead of 150.
    #[arg(long)]
    full: bool,
    /// Repetitions of every measured run; the fastest is reported (the same band every
    /// time, checked) [default: 3; 9 per operation with --storage; 1 with --quick].
    #[arg(long, allow_hyphen_values = true,
          value_parser = clap::value_parser!(u32).range(1..=1000))]
    reps: Option<u32>,
    /// Only the pure-kernel section: voxel updates/s of the PDE kernels on a dense in-cache
    /// block for scalar f32 and every SIMD width.
    #[arg(long)]
    kernels: bool,
    /// Only the time-to-solution section: each scenario (sphere 256³ and a small sphere,
    /// Enright, spiral) run to its end with its default settings, on 1 thread and on
    /// `--threads`: seconds of stepping and the error against the analytic answer.
    #[arg(long, conflicts_with_all = ["kernels", "storage"])]
    solution: bool,
    /// Only the operators section: fast marching and isosurfacing of the sphere
    /// benchmark's initial band (isosurfacing on `--threads`).
    #[arg(long, conflicts_with_all = ["kernels", "storage", "solution"])]
    tools: bool,
    /// Time to solution: Enright's test at this size [default: the scenario's, 128].
    #[arg(long, value_name = "N", allow_hyphen_values = true,
          conflicts_with_all = ["kernels", "storage"],
          value_parser = clap::value_parser!(u32).range(8..=65536))]
    solution_enright_size: Option<u32>,
    /// Time to solution: every default size times this, in (0, 1] (a quick look, not a
    /// measurement) [default: 1, or 0.25 with --quick].
    #[arg(long, value_name = "F", allow_hyphen_values = true,
          conflicts_with_all = ["kernels", "storage"], value_parser = scale)]
    solution_scale: Option<f64>,
    /// The memory table instead (Houston et al. 2006, Table II): bytes of the H-RLE, the DT-Grid,
    /// the tiles and the .sls file for the spiral, a sphere of radius 1000 (--memory-radius)
    /// and that sphere clipped by a plane (unenclosed).
    #[arg(long, conflicts_with_all = ["kernels", "storage", "solution"])]
    memory: bool,
    /// Memory table: also this mesh (.obj, .ply, .stl; e.g. the Stanford bunny from
    /// `python3 docs/data/fetch_bunny.py`), voxelised at each of --memory-sizes.
    #[arg(long, value_name = "MESH", requires = "memory")]
    memory_mesh: Option<PathBuf>,
    /// Memory table: voxels across the mesh's longest side, one row each.
    #[arg(long, value_delimiter = ',', default_values_t = [256u32, 512, 1024, 2048],
          requires = "memory_mesh",
          value_parser = clap::value_parser!(u32).range(8..=65536))]
    memory_sizes: Vec<u32>,
    /// Memory table: the sphere's radius in voxels.
    #[arg(long, default_value_t = 1000.0, requires = "memory", allow_hyphen_values = true)]
    memory_radius: f64,
    /// Also write the results as JSON to this file (checked before the work starts).
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
}

fn scale(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v <= 1.0 => Ok(v),
        _ => Err(format!("{s} is not in (0, 1]")),
    }
}

fn main() -> ExitCode {
    match run(&BenchArgs::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn kernel_bench(quick: bool) -> Result<Vec<levelset_kernels::bench::KernelResult>, String> {
    use levelset_kernels::bench::{run_kernel_bench, KernelBenchConfig};
    let mut cfg = KernelBenchConfig::default();
    if quick {
        cfg.seconds = 0.05;
        cfg.samples = 2;
    }
    run_kernel_bench(&cfg).map(|r| r.kernels).map_err(|e| e.to_string())
}

fn run(a: &BenchArgs) -> Result<(), String> {
    // A level forced by LEVELSET_SIMD that this CPU cannot run is refused, not replaced.
    levelset_kernels::check_env()?;
    if let Some(path) = &a.json {
        check_output(path)?;
    }
    if a.kernels {
        let report = levelset_kernels::bench::KernelBenchReport {
            kernels: kernel_bench(a.quick)?,
            target_features: levelset_kernels::target_features(),
            level: levelset_kernels::Level::active().name(),
        };
        outln!(
            "level: {}; target features compiled in: {}",
            levelset_kernels::Level::active().describe(),
            report.target_features.join(",")
        );
        out!("{}", kernels_text(&report.kernels));
        if let Some(path) = &a.json {
            write_json(path, &report)?;
        }
        return Ok(());
    }
    if a.storage {
        return storage(a);
    }
    if a.memory {
        return memory(a);
    }
    speedup(a)
}

fn memory(a: &BenchArgs) -> Result<(), String> {
    use levelset_cli::memtable::{analytic_rows, MemoryTable};
    let r = a.memory_radius;
    if !(r.is_finite() && (2.0..=100_000.0).contains(&r)) {
        return Err(format!("--memory-radius must be in [2, 100000] voxels, got {r}"));
    }
    let bar = progress::spinner(false);
    let mut rows = Vec::new();
    if let Some(path) = &a.memory_mesh {
        let mesh = sparse_levelset::io::mesh::load_mesh(path).map_err(|e| e.to_string())?;
        let name = path.file_stem().map_or("mesh".into(), |s| s.to_string_lossy().into_owned());
        rows = levelset_cli::memtable::mesh_rows(&name, &mesh, &a.memory_sizes, |m| {
            bar.set_message(m.to_string())
        })?;
    }
    rows.extend(analytic_rows(r, |m| bar.set_message(m.to_string())).map_err(|e| e.to_string())?);
    bar.finish_and_clear();
    let table = MemoryTable { half_width: GridSpec::default().half_width, rows };
    out!("{}", table.to_text());
    if let Some(path) = &a.json {
        write_json(path, &table)?;
    }
    Ok(())
}

fn storage(a: &BenchArgs) -> Result<(), String> {
    let spec = GridSpec::default();
    let scale = if a.quick { 0.4 } else { 1.0 };
    let reps = a.reps.unwrap_or(if a.quick { 1 } else { 9 }) as usize;
    // The scenarios of van der Laan et al. 2011: a sphere in a 256³ box (Sec. 5.1) and the extruded
    // spiral of radius 50, depth 40 in a 128³ box (Sec. 5.2).
    let scenarios = [
        ("sphere", Shape::Sphere { center: [0.0; 3], radius: 100.0 * scale }),
        ("spiral", Shape::spiral_default([0.0; 3], 50.0 * scale, 40.0 * scale)),
    ];
    let bar = progress::bar(
        false,
        (scenarios.len() * 4 + 1) as u64,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}",
    );
    let mut results = Vec::new();
    for (name, shape) in &scenarios {
        bar.set_message(format!("{name}: building"));
        let r = run_scenario(name, shape, spec, reps, |op| {
            bar.inc(1);
            bar.set_message(format!("{name}: {op} done"));
        })
        .map_err(|e| e.to_string())?;
        results.push(r);
    }
    bar.set_message("kernels");
    let kernels = kernel_bench(a.quick)?;
    bar.finish_and_clear();
    let report = StorageBench {
        cpu: cpu_name(),
        target_features: levelset_kernels::target_features(),
        level: levelset_kernels::Level::active().name(),
        profile: levelset_cli::storage::build_profile(),
        threads: 1,
        repetitions: reps,
        scenarios: results,
        kernels,
    };
    out!("{}", report.to_text());
    if let Some(path) = &a.json {
        write_json(path, &report)?;
    }
    Ok(())
}

fn speedup(a: &BenchArgs) -> Result<(), String> {
    use levelset_cli::solution::{run_time_to_solution, SolutionConfig};
    use levelset_cli::speedup::{run_speedup, SpeedupConfig, SpeedupReport};
    let reps = a.reps.unwrap_or(if a.quick { 1 } else { 3 }) as usize;
    let mut cfg =
        SpeedupConfig { pin: a.pin, full: a.full, quick: a.quick, reps, ..Default::default() };
    if let Some(t) = a.threads {
        cfg.threads = t as usize;
    }
    if a.tools {
        let bar = progress::spinner(false);
        let tools = levelset_cli::speedup::run_tools(&cfg, |m| bar.set_message(m.to_string()))?;
        bar.finish_and_clear();
        let report = SpeedupReport { tools, ..SpeedupReport::new(&cfg) };
        out!("{}", report.to_text());
        if let Some(path) = &a.json {
            write_json(path, &report)?;
        }
        return Ok(());
    }
    let (mut report, kernels) = if a.solution {
        (SpeedupReport::new(&cfg), None)
    } else {
        let bar = progress::spinner(false);
        bar.set_message("kernels");
        let kernels = kernel_bench(a.quick)?;
        let mut report = run_speedup(&cfg, &kernels, |m| bar.set_message(m.to_string()))?;
        let n = if a.quick { 48 } else { 96 };
        report.segmentation =
            levelset_cli::segbench::run_segmentation(n, cfg.threads, reps, |m| {
                bar.set_message(m.to_string())
            })?;
        bar.finish_and_clear();
        (report, Some(kernels))
    };
    let sol = SolutionConfig {
        threads: vec![1, cfg.threads],
        pin: cfg.pin,
        enright_size: a.solution_enright_size,
        scale: a.solution_scale.unwrap_or(if a.quick { 0.25 } else { 1.0 }),
        reps,
    };
    let bar =
        progress::bar(false, 1000, "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% {msg}");
    let mut shown = String::new();
    report.time_to_solution = run_time_to_solution(&sol, |what, done| {
        if what != shown {
            shown = what.to_string();
            bar.set_message(shown.clone());
        }
        bar.set_position((done * 1000.0) as u64);
    })?;
    bar.finish_and_clear();
    out!("{}", report.to_text());
    if let Some(kernels) = &kernels {
        out!("{}", kernels_text(kernels));
    }
    if let Some(path) = &a.json {
        write_json(path, &report)?;
    }
    Ok(())
}
