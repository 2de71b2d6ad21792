//! The `levelset` command.

use clap::{Args, Parser, Subcommand, ValueEnum};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::info::{info_from_dense, info_from_shape, InfoReport};
use sparse_levelset::shapes::Shape;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "levelset",
    version,
    about = "Level sets on sparse grids: the Sorted Tile List engine and its DT-Grid reference"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Build both grids from a shape or a dense .npy field and report voxels and bytes.
    Info(InfoArgs),
    /// Time the same stencil arithmetic, random access and band maintenance on the tiles
    /// and on the DT-Grid (the default command).
    Bench(BenchArgs),
}

#[derive(Args, Default)]
struct BenchArgs {
    /// Smaller shapes and fewer repetitions (a quick look, not a measurement).
    #[arg(long)]
    quick: bool,
    /// Repetitions per operation; the best time is reported.
    #[arg(long, default_value_t = 9, value_parser = clap::value_parser!(u32).range(1..=1000))]
    reps: u32,
    /// Only the pure-kernel section: voxel updates/s of the PDE kernels on a dense in-cache
    /// block for scalar f32 and every SIMD width.
    #[arg(long)]
    kernels: bool,
    /// Also write the results as JSON to this file.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ShapeKind {
    Sphere,
    Torus,
    Box,
    Ellipsoid,
    Spiral,
}

#[derive(Args)]
struct InfoArgs {
    /// A dense float32 .npy level set (shape (nz, ny, nx), φ < 0 inside, world units).
    #[arg(conflicts_with = "shape")]
    field: Option<PathBuf>,
    /// Analytic shape to build (default: sphere, when no field is given).
    #[arg(long, value_enum)]
    shape: Option<ShapeKind>,
    /// Sphere radius, or the spiral's outer radius [default: sphere 100, spiral 50].
    #[arg(long)]
    radius: Option<f64>,
    /// Torus radius of the centre circle.
    #[arg(long, default_value_t = 80.0)]
    major_radius: f64,
    /// Torus tube radius.
    #[arg(long, default_value_t = 20.0)]
    minor_radius: f64,
    /// Ellipsoid radii "a,b,c".
    #[arg(long, value_delimiter = ',', num_args = 3, default_values_t = [100.0, 70.0, 50.0])]
    radii: Vec<f64>,
    /// Box half extents "a,b,c".
    #[arg(long, value_delimiter = ',', num_args = 3, default_values_t = [60.0, 45.0, 30.0])]
    half_extents: Vec<f64>,
    /// Spiral extrusion depth (papers: 40 for radius 50).
    #[arg(long, default_value_t = 40.0)]
    depth: f64,
    /// Spiral turns (a multiple of 0.5).
    #[arg(long, default_value_t = 2.0)]
    turns: f64,
    /// Spiral arm thickness [default: radius / 5].
    #[arg(long)]
    thickness: Option<f64>,
    /// Shape centre "x,y,z" in world units.
    #[arg(long, value_delimiter = ',', num_args = 3, default_values_t = [0.0, 0.0, 0.0])]
    center: Vec<f64>,
    /// Voxel edge length in world units.
    #[arg(long, default_value_t = 1.0)]
    voxel_size: f32,
    /// Band half-width γ in voxels.
    #[arg(long, default_value_t = 3.0)]
    half_width: f32,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

fn arr3(v: &[f64]) -> [f64; 3] {
    [v[0], v[1], v[2]]
}

fn shape_of(a: &InfoArgs, kind: ShapeKind) -> Shape {
    let center = arr3(&a.center);
    match kind {
        ShapeKind::Sphere => Shape::Sphere { center, radius: a.radius.unwrap_or(100.0) },
        ShapeKind::Torus => {
            Shape::Torus { center, major_radius: a.major_radius, minor_radius: a.minor_radius }
        }
        ShapeKind::Box => Shape::Box { center, half_extents: arr3(&a.half_extents) },
        ShapeKind::Ellipsoid => Shape::Ellipsoid { center, radii: arr3(&a.radii) },
        ShapeKind::Spiral => {
            let radius = a.radius.unwrap_or(50.0);
            Shape::Spiral {
                center,
                radius,
                depth: a.depth,
                turns: a.turns,
                thickness: a.thickness.unwrap_or(radius / 5.0),
            }
        }
    }
}

/// Refuses a shape whose band would not fit in memory, before building it. The estimate
/// is the band of the bounding box's surface: an upper bound for convex shapes, within a
/// small factor for the others.
fn check_size(shape: &Shape, spec: &GridSpec) -> Result<(), String> {
    let (lo, hi) = shape.bounds();
    let e: Vec<f64> = (0..3).map(|i| (hi[i] - lo[i]).max(0.0) / spec.voxel_size as f64).collect();
    let area = 2.0 * (e[0] * e[1] + e[1] * e[2] + e[0] * e[2]);
    // Tiles pad the band to whole tiles: about 4 tile layers of 64 voxels per 16 voxels of area.
    let tile_bytes = area * (2.0 * spec.half_width as f64 + 8.0) * 4.0 * 1.5;
    let limit = available_memory().unwrap_or(8 << 30) as f64 * 0.7;
    if tile_bytes > limit {
        return Err(format!(
            "the band of this shape needs about {:.1} GiB but about {:.1} GiB of memory is \
             available: use a smaller shape or a larger --voxel-size",
            tile_bytes / (1u64 << 30) as f64,
            limit / (1u64 << 30) as f64
        ));
    }
    Ok(())
}

fn available_memory() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = s.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn run_info(a: &InfoArgs) -> Result<InfoReport, String> {
    let spec = GridSpec::new(a.voxel_size, [0.0; 3], a.half_width).map_err(|e| e.to_string())?;
    if let Some(path) = &a.field {
        let field = sparse_levelset::npy::read_npy(path).map_err(|e| e.to_string())?;
        return info_from_dense(&path.display().to_string(), &field, spec)
            .map_err(|e| format!("{}: {e}", path.display()));
    }
    let kind = a.shape.unwrap_or(ShapeKind::Sphere);
    let shape = shape_of(a, kind);
    shape.validate().map_err(|e| e.to_string())?;
    check_size(&shape, &spec)?;
    let name = format!("{kind:?}").to_lowercase();
    info_from_shape(&name, &shape, spec).map_err(|e| e.to_string())
}

fn write_json<T: serde::Serialize>(path: &std::path::Path, value: &T) -> Result<(), String> {
    let text = serde_json::to_string_pretty(value).expect("report serialises");
    sparse_levelset::fsutil::write_atomic(path, |w| {
        use std::io::Write;
        w.write_all(text.as_bytes())
    })
    .map_err(|e| format!("{}: {e}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
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

fn run_bench(a: &BenchArgs) -> Result<(), String> {
    use indicatif::{ProgressBar, ProgressStyle};
    use sparse_levelset::bench::{cpu_name, kernels_text, run_scenario, StorageBench};
    if a.kernels {
        let report = levelset_kernels::bench::KernelBenchReport {
            kernels: kernel_bench(a.quick)?,
            target_features: levelset_kernels::target_features(),
        };
        println!("target features: {}", report.target_features.join(","));
        print!("{}", kernels_text(&report.kernels));
        if let Some(path) = &a.json {
            write_json(path, &report)?;
        }
        return Ok(());
    }
    let spec = GridSpec::default();
    let scale = if a.quick { 0.4 } else { 1.0 };
    let reps = if a.quick { 1 } else { a.reps as usize };
    // The tile paper's scenarios: a sphere in a 256³ box (Sec. 5.1) and the extruded
    // spiral of radius 50, depth 40 in a 128³ box (Sec. 5.2).
    let scenarios = [
        ("sphere", Shape::Sphere { center: [0.0; 3], radius: 100.0 * scale }),
        ("spiral", Shape::spiral_default([0.0; 3], 50.0 * scale, 40.0 * scale)),
    ];
    let bar = ProgressBar::new((scenarios.len() * 4 + 1) as u64);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}")
            .expect("valid template"),
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
        profile: if cfg!(debug_assertions) { "debug" } else { "release" },
        threads: 1,
        repetitions: reps,
        scenarios: results,
        kernels,
    };
    print!("{}", report.to_text());
    if let Some(path) = &a.json {
        write_json(path, &report)?;
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Info(a)) => run_info(&a).map(|r| {
            if a.json {
                println!("{}", serde_json::to_string_pretty(&r).expect("report serialises"));
            } else {
                print!("{}", r.to_text());
            }
        }),
        Some(Command::Bench(a)) => run_bench(&a),
        None => run_bench(&BenchArgs { reps: 9, ..Default::default() }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
