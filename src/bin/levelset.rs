//! The `levelset` command.

use clap::{Args, Parser, Subcommand, ValueEnum};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::info::{info_from_dense, info_from_shape, InfoReport};
use sparse_levelset::shapes::Shape;
use std::path::PathBuf;
use std::process::ExitCode;

/// `print!` that ignores a closed standard output (`levelset run … | head` must not
/// panic on a broken pipe).
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// `println!` that ignores a closed standard output.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

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
    /// The speed-up report: the papers' scenarios on the DT-Grid and on tiles (scalar,
    /// SIMD on one thread, SIMD on every thread), with the kernel-only throughput (the
    /// default command). `--storage`: the storage benchmark; `--kernels`: kernels only.
    Bench(BenchArgs),
    /// Evolve one of the papers' scenarios and write DIR/summary.json.
    Run(RunArgs),
    /// Signed distance to the zero level set of a dense float32 .npy field by fast
    /// marching (like scikit-fmm's `distance`), within a band of half-width W.
    Distance(DistanceArgs),
    /// Ray-trace the zero level set of a shape or a dense .npy field into a PNG.
    Render(RenderArgs),
    /// Mesh the zero set of a shape or a dense .npy field (simplicial isosurfacing on the
    /// Kuhn triangulation) into a PLY or OBJ file and report its size and checks.
    Mesh(MeshArgs),
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ScenarioArg {
    /// Sphere under mean curvature flow (tile paper Sec. 5.1).
    Sphere,
    /// Extruded spiral under volume-conserving mean curvature flow (Sec. 5.2, Table 2).
    Spiral,
    /// Enright's periodic deformation test (Sec. 5.4).
    Enright,
    /// A sphere growing at constant speed far beyond its initial box.
    Expand,
    /// A sphere morphing into a torus (H-RLE paper eq. (1)).
    Morph,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum GridArg {
    Tiles,
    Dtgrid,
    /// The dense reference (small sizes only).
    Dense,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum LanesArg {
    Scalar,
    Simd,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum SchemeArg {
    Upwind1,
    Weno5,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum IntegratorArg {
    Euler,
    Rk3,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ReinitArg {
    /// First-order fast marching.
    Fmm,
    /// High-accuracy (second-order) fast marching.
    Fmm2,
}

#[derive(Args)]
struct RunArgs {
    /// The scenario.
    #[arg(value_enum)]
    scenario: ScenarioArg,
    /// Effective resolution N (an N³ box) [default: sphere 256, spiral and enright 128,
    /// expand and morph 64].
    #[arg(long)]
    size: Option<u32>,
    /// Steps to take [default: spiral 1000, morph 300, others 100 unless --time is given;
    /// enright: one period, expand: until the sphere spans twice its box].
    #[arg(long, conflicts_with = "time")]
    steps: Option<u64>,
    /// Simulated time to reach (the last step lands on it).
    #[arg(long)]
    time: Option<f64>,
    /// Representation.
    #[arg(long, value_enum, default_value_t = GridArg::Tiles)]
    grid: GridArg,
    /// Lanes of the tile engine.
    #[arg(long, value_enum, default_value_t = LanesArg::Simd)]
    lanes: LanesArg,
    /// Worker threads of the tile engine [default: all cores].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Shape radius [default: sphere 100·N/256, spiral 50·N/128, enright 0.15, expand N/4,
    /// morph 0.3·N].
    #[arg(long)]
    radius: Option<f64>,
    /// Curvature weight ε [default: 1 for sphere and spiral, 0 otherwise].
    #[arg(long)]
    epsilon: Option<f32>,
    /// Normal speed F of expand [default: 1 voxel per unit time].
    #[arg(long)]
    speed: Option<f32>,
    /// Enright's period T [default: 3].
    #[arg(long)]
    period: Option<f64>,
    /// Spiral: volume-conserving flow (true) or plain mean curvature flow (false).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    volume_conserving: bool,
    /// Spiral depth [default: 40·N/128].
    #[arg(long)]
    depth: Option<f64>,
    /// Band half-width γ in voxels.
    #[arg(long, default_value_t = 3.0)]
    half_width: f32,
    /// Weight of the rescaling term of eq. (3) [default: 1].
    #[arg(long)]
    rescale: Option<f32>,
    /// Spatial scheme [default: upwind1 for sphere and morph, weno5 otherwise].
    #[arg(long, value_enum)]
    scheme: Option<SchemeArg>,
    /// Time integrator [default: euler for sphere and morph, rk3 otherwise].
    #[arg(long, value_enum)]
    integrator: Option<IntegratorArg>,
    /// CFL number in (0, 1].
    #[arg(long, default_value_t = 0.5)]
    cfl: f32,
    /// Keep a record every K steps.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..))]
    record_every: u64,
    /// Start from a dense float32 .npy field (shape (nz, ny, nx), φ < 0 inside, world
    /// units) instead of the scenario's shape.
    #[arg(long, value_name = "FIELD.npy")]
    init: Option<PathBuf>,
    /// Voxel size of the --init field [default: the scenario's].
    #[arg(long, requires = "init")]
    voxel_size: Option<f32>,
    /// Reinitialise the band to a signed distance by fast marching (sparse grids).
    #[arg(long, value_enum)]
    reinit: Option<ReinitArg>,
    /// Reinitialise after every K steps.
    #[arg(long, value_name = "K", default_value_t = 10, requires = "reinit",
          value_parser = clap::value_parser!(u64).range(1..))]
    every: u64,
    /// Write a ray-traced image DIR/render-NNNNNN.png of step 0 and every K-th step (a
    /// fixed camera framing the initial surface with a margin; sparse grids).
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u64).range(1..))]
    render_every: Option<u64>,
    /// Write the zero level set as a binary PLY mesh DIR/mesh-NNNNNN.ply of step 0 and
    /// every K-th step (sparse grids).
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u64).range(1..))]
    mesh_every: Option<u64>,
    /// Output directory (created if needed).
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Also write the final state as a dense field DIR/final.npy (band box + 4 voxels).
    #[arg(long)]
    export_npy: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct DistanceArgs {
    /// A dense float32 .npy field (shape (nz, ny, nx)); its zero level set is the
    /// interface, φ < 0 inside.
    field: PathBuf,
    /// Output .npy file (written atomically): the signed distance, ±W·voxel beyond the band.
    #[arg(short, long, value_name = "OUT.npy")]
    output: PathBuf,
    /// Order of the update: 1 (first-order FMM) or 2 (high-accuracy FMM).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    order: u8,
    /// Band half-width W in voxels (> 1): distances are marched up to W voxels.
    #[arg(long, default_value_t = 3.0)]
    half_width: f32,
    /// Voxel edge length in world units (distances are written in world units).
    #[arg(long, default_value_t = 1.0)]
    voxel_size: f32,
}

#[derive(Args, Default)]
struct BenchArgs {
    /// Smaller shapes and fewer repetitions (a quick look, not a measurement).
    #[arg(long)]
    quick: bool,
    /// The storage benchmark instead: the same stencil arithmetic, random access and band
    /// maintenance on both grids.
    #[arg(long, conflicts_with = "kernels")]
    storage: bool,
    /// Worker threads of the "all threads" runs [default: every core].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Pin worker threads to cores.
    #[arg(long)]
    pin: bool,
    /// The spiral's 1000 iterations (the tile paper's Table 2) instead of 150.
    #[arg(long)]
    full: bool,
    /// Storage benchmark: repetitions per operation; the best time is reported.
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

/// An analytic shape and its parameters (shared by `info`, `render` and `mesh`).
#[derive(Args)]
struct ShapeArgs {
    /// Analytic shape (default: sphere, when no field is given).
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
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true,
          default_values_t = [100.0, 70.0, 50.0])]
    radii: Vec<f64>,
    /// Box half extents "a,b,c".
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true,
          default_values_t = [60.0, 45.0, 30.0])]
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
    /// Shape centre "x,y,z" in world units (negative values are fine: --center -5,2,-3).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true,
          default_values_t = [0.0, 0.0, 0.0])]
    center: Vec<f64>,
}

impl ShapeArgs {
    /// The kind asked for (sphere by default).
    fn kind(&self) -> ShapeKind {
        self.shape.unwrap_or(ShapeKind::Sphere)
    }

    /// The shape, validated; vectors must have three components.
    fn build(&self) -> Result<Shape, String> {
        let a = self;
        let v3 = |name: &str, v: &[f64]| -> Result<[f64; 3], String> {
            <[f64; 3]>::try_from(v)
                .map_err(|_| format!("--{name} takes three comma-separated numbers \"x,y,z\""))
        };
        let center = v3("center", &a.center)?;
        let shape = match a.kind() {
            ShapeKind::Sphere => Shape::Sphere { center, radius: a.radius.unwrap_or(100.0) },
            ShapeKind::Torus => {
                Shape::Torus { center, major_radius: a.major_radius, minor_radius: a.minor_radius }
            }
            ShapeKind::Box => {
                Shape::Box { center, half_extents: v3("half-extents", &a.half_extents)? }
            }
            ShapeKind::Ellipsoid => Shape::Ellipsoid { center, radii: v3("radii", &a.radii)? },
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
        };
        shape.validate().map_err(|e| e.to_string())?;
        Ok(shape)
    }
}

#[derive(Args)]
struct InfoArgs {
    /// A dense float32 .npy level set (shape (nz, ny, nx), φ < 0 inside, world units).
    #[arg(conflicts_with = "shape")]
    field: Option<PathBuf>,
    #[command(flatten)]
    shape: ShapeArgs,
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

#[derive(Args)]
struct RenderArgs {
    /// The level set: FIELD (a dense .npy) or a shape, with the arguments of `levelset info`
    /// (`--json` prints the render summary as JSON).
    #[command(flatten)]
    source: InfoArgs,
    /// A dense float32 .npy level set (shape (nz, ny, nx), φ < 0 inside, world units);
    /// the same as the positional FIELD.
    #[arg(long, value_name = "FIELD.npy", conflicts_with_all = ["shape", "field"])]
    input: Option<PathBuf>,
    /// The PNG to write.
    #[arg(short, long, value_name = "FILE.png")]
    output: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Camera azimuth in degrees (counter-clockwise from +x, seen from the object).
    #[arg(long, default_value_t = -60.0, allow_negative_numbers = true)]
    azimuth: f64,
    /// Camera elevation in degrees, in (-90, 90).
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    elevation: f64,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 35.0)]
    fov: f64,
    /// Rays per pixel along each axis (samples² per pixel), 1..=8.
    #[arg(long, default_value_t = 2)]
    samples: u32,
    /// Grid to trace (tiles or dtgrid; both give the same image).
    #[arg(long, value_enum, default_value_t = GridArg::Tiles)]
    grid: GridArg,
    /// No ground plane.
    #[arg(long)]
    no_ground: bool,
    /// No shadow rays.
    #[arg(long)]
    no_shadows: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct MeshArgs {
    /// A dense float32 .npy level set (shape (nz, ny, nx), φ < 0 inside, world units).
    #[arg(long, value_name = "FIELD.npy", conflicts_with = "shape")]
    input: Option<PathBuf>,
    #[command(flatten)]
    shape: ShapeArgs,
    /// Voxel edge length in world units (also of the --input field).
    #[arg(long, default_value_t = 1.0)]
    voxel_size: f32,
    /// Band half-width γ in voxels.
    #[arg(long, default_value_t = 3.0)]
    half_width: f32,
    /// The isovalue to mesh, in world units (inside the band, |iso| < γ, for shapes).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    iso: f64,
    /// Output mesh: FILE.ply (binary unless --ascii) or FILE.obj.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Write ASCII PLY instead of binary.
    #[arg(long)]
    ascii: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

fn run_info(a: &InfoArgs) -> Result<InfoReport, String> {
    let spec = GridSpec::new(a.voxel_size, [0.0; 3], a.half_width).map_err(|e| e.to_string())?;
    if let Some(path) = &a.field {
        let field = sparse_levelset::npy::read_npy(path).map_err(|e| e.to_string())?;
        return info_from_dense(&path.display().to_string(), &field, spec)
            .map_err(|e| format!("{}: {e}", path.display()));
    }
    let kind = a.shape.kind();
    let shape = a.shape.build()?;
    sparse_levelset::build::check_band_fits(&shape, &spec, 1.0).map_err(|e| e.to_string())?;
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
    outln!("wrote {}", path.display());
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
        outln!("target features: {}", report.target_features.join(","));
        out!("{}", kernels_text(&report.kernels));
        if let Some(path) = &a.json {
            write_json(path, &report)?;
        }
        return Ok(());
    }
    if !a.storage {
        return run_speedup(a);
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
        profile: sparse_levelset::bench::build_profile(),
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

fn run_speedup(a: &BenchArgs) -> Result<(), String> {
    use indicatif::{ProgressBar, ProgressStyle};
    use sparse_levelset::speedup::{run_speedup, SpeedupConfig};
    let mut cfg = SpeedupConfig { pin: a.pin, full: a.full, quick: a.quick, ..Default::default() };
    if let Some(t) = a.threads {
        cfg.threads = t as usize;
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
            .expect("valid template"),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar.set_message("kernels");
    let kernels = kernel_bench(a.quick)?;
    let report = run_speedup(&cfg, &kernels, |m| bar.set_message(m.to_string()))?;
    bar.finish_and_clear();
    out!("{}", report.to_text());
    out!("{}", sparse_levelset::bench::kernels_text(&kernels));
    if let Some(path) = &a.json {
        write_json(path, &report)?;
    }
    Ok(())
}

/// The frames `levelset run` writes while it steps (`--render-every`, `--mesh-every`).
struct Frames {
    dir: PathBuf,
    render_every: Option<u64>,
    mesh_every: Option<u64>,
    /// The camera's frame box, fixed at the first frame.
    frame: Option<sparse_levelset::render::FrameBox>,
    written: usize,
}

impl Frames {
    fn new(a: &RunArgs) -> Result<Frames, String> {
        if (a.render_every.is_some() || a.mesh_every.is_some()) && matches!(a.grid, GridArg::Dense)
        {
            return Err(
                "--render-every and --mesh-every need a sparse grid (--grid tiles or dtgrid)"
                    .into(),
            );
        }
        Ok(Frames {
            dir: a.out.clone(),
            render_every: a.render_every,
            mesh_every: a.mesh_every,
            frame: None,
            written: 0,
        })
    }

    /// Writes the frames due at the simulation's current step.
    fn write(
        &mut self,
        sim: &sparse_levelset::evolve::Simulation,
    ) -> Result<(), sparse_levelset::evolve::EvolveError> {
        use sparse_levelset::evolve::EvolveError;
        use sparse_levelset::mesh::{isosurface_dtgrid, isosurface_tiles, MeshFormat};
        use sparse_levelset::render::{render, FrameBox, RenderOptions};
        let step = sim.steps();
        let due = |every: Option<u64>| every.is_some_and(|k| step.is_multiple_of(k));
        let (mesh_due, render_due) = (due(self.mesh_every), due(self.render_every));
        // A collapsed interface has no surface to mesh or show.
        if (!mesh_due && !render_due) || sim.collapsed() {
            return Ok(());
        }
        let output = |e: &dyn std::fmt::Display| EvolveError::Output(format!("step {step}: {e}"));
        let (tiles, dt) = (sim.tiles(), sim.dtgrid());
        if tiles.is_none() && dt.is_none() {
            return Err(output(&"frames need a sparse grid"));
        }
        if mesh_due {
            let mesh = match tiles {
                Some(t) => isosurface_tiles(t, 0.0),
                None => isosurface_dtgrid(dt.expect("checked above"), 0.0),
            }
            .map_err(|e| output(&e))?;
            let path = self.dir.join(format!("mesh-{step:06}.ply"));
            mesh.write(&path, Some(MeshFormat::PlyBinary)).map_err(|e| output(&e))?;
            self.written += 1;
        }
        if render_due {
            if self.frame.is_none() {
                // The initial surface's box with a margin of half its extent on every
                // side: the camera stays put while the interface moves within it.
                let (lo, hi) = sim.band_bounding_box().ok_or_else(|| output(&"empty level set"))?;
                let spec = sim.spec();
                let (l, h) = (spec.world(lo), spec.world(hi));
                let m: [f64; 3] = std::array::from_fn(|i| 0.5 * (h[i] - l[i]));
                self.frame = Some(FrameBox {
                    lo: std::array::from_fn(|i| l[i] - m[i]),
                    hi: std::array::from_fn(|i| h[i] + m[i]),
                });
            }
            let opts = RenderOptions { frame: self.frame, ..RenderOptions::default() };
            let image = render(sim, &opts).map_err(|e| output(&e))?;
            let path = self.dir.join(format!("render-{step:06}.png"));
            image.write_png(&path).map_err(|e| output(&e))?;
            self.written += 1;
        }
        Ok(())
    }
}

fn run_scenario(a: &RunArgs) -> Result<(), String> {
    use indicatif::{ProgressBar, ProgressStyle};
    use sparse_levelset::evolve::{GridKind, Integrator, Lanes, SpatialScheme};
    use sparse_levelset::scenario::{Scenario, ScenarioKind, ScenarioOptions};
    let kind = match a.scenario {
        ScenarioArg::Sphere => ScenarioKind::Sphere,
        ScenarioArg::Spiral => ScenarioKind::Spiral,
        ScenarioArg::Enright => ScenarioKind::Enright,
        ScenarioArg::Expand => ScenarioKind::Expand,
        ScenarioArg::Morph => ScenarioKind::Morph,
    };
    let lanes = match a.lanes {
        LanesArg::Scalar => Lanes::Scalar,
        LanesArg::Simd => Lanes::Simd,
    };
    let mut o = ScenarioOptions::new(kind);
    o.size = a.size;
    o.steps = a.steps;
    o.time = a.time;
    o.grid = match a.grid {
        GridArg::Tiles => GridKind::Tiles(lanes),
        GridArg::Dtgrid => GridKind::DtGrid,
        GridArg::Dense => GridKind::Dense,
    };
    o.threads = a.threads.map(|t| t as usize);
    o.radius = a.radius;
    o.epsilon = a.epsilon;
    o.speed = a.speed;
    o.period = a.period;
    o.depth = a.depth;
    o.half_width = a.half_width;
    o.rescale = a.rescale;
    o.volume_conserving = Some(a.volume_conserving);
    o.scheme = a.scheme.map(|s| match s {
        SchemeArg::Upwind1 => SpatialScheme::Upwind1,
        SchemeArg::Weno5 => SpatialScheme::Weno5,
    });
    o.integrator = a.integrator.map(|i| match i {
        IntegratorArg::Euler => Integrator::Euler,
        IntegratorArg::Rk3 => Integrator::Rk3,
    });
    o.cfl = a.cfl;
    o.record_every = a.record_every;
    o.voxel_size = a.voxel_size;
    o.reinit = a.reinit.map(|r| sparse_levelset::evolve::Reinit {
        order: match r {
            ReinitArg::Fmm => sparse_levelset::fmm::Order::First,
            ReinitArg::Fmm2 => sparse_levelset::fmm::Order::Second,
        },
        every: a.every,
    });
    if let Some(path) = &a.init {
        let field = sparse_levelset::npy::read_npy(path).map_err(|e| e.to_string())?;
        o.init = Some((path.display().to_string(), field));
    }
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    let scenario = Scenario::resolve(o).map_err(|e| e.to_string())?;
    let bar = if a.quiet { ProgressBar::hidden() } else { ProgressBar::new(1000) };
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {percent}% {msg}")
            .expect("valid template"),
    );
    bar.set_message(format!("{} on {}", kind.name(), scenario.params.grid));
    let mut frames = Frames::new(a)?;
    let (summary, sim) = scenario
        .run_with(|f| bar.set_position((f * 1000.0) as u64), |sim| frames.write(sim))
        .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    let last = summary.records.last().expect("records");
    outln!(
        "{}: {} steps to t = {:.6}{} on {} in {:.2} s ({:.1} Mvoxel-updates/s); band voxels {}, \
         volume V/V0 = {:.6}, area {:.6e}, {} bytes; checksum {}",
        kind.name(),
        summary.steps_taken,
        summary.time,
        if summary.collapsed { " (collapsed)" } else { "" },
        summary.params.grid,
        summary.seconds,
        summary.voxel_updates_per_s / 1e6,
        last.band_voxels,
        summary.volume_ratio,
        last.area,
        last.bytes,
        summary.checksum
    );
    if let (Some(h), Some(p)) = (summary.volume_ratio_half_period, summary.volume_ratio_period) {
        outln!("enright: V(T/2)/V(0) = {h:.6}, V(T)/V(0) = {p:.6}");
    }
    if frames.written > 0 {
        outln!("wrote {} frame file(s) to {}", frames.written, a.out.display());
    }
    write_json(&a.out.join("summary.json"), &summary)?;
    if a.export_npy {
        let path = a.out.join("final.npy");
        let (lo, hi) = sim
            .band_bounding_box()
            .ok_or("the final level set has no band voxels: nothing to export")?;
        let m = 4;
        let origin = sparse_levelset::Coord::new(lo.x - m, lo.y - m, lo.z - m);
        let dims = [
            (hi.x - lo.x + 1 + 2 * m) as usize,
            (hi.y - lo.y + 1 + 2 * m) as usize,
            (hi.z - lo.z + 1 + 2 * m) as usize,
        ];
        let field = sim.to_dense(origin, dims).map_err(|e| e.to_string())?;
        sparse_levelset::npy::write_npy(&path, &field).map_err(|e| e.to_string())?;
        outln!("wrote {} (origin voxel {origin}, dims {dims:?})", path.display());
    }
    Ok(())
}

fn run_distance(a: &DistanceArgs) -> Result<(), String> {
    use indicatif::{ProgressBar, ProgressStyle};
    use sparse_levelset::fmm::{distance_dense, FmmOptions, Order};
    let order = if a.order == 1 { Order::First } else { Order::Second };
    let opts = FmmOptions { order, half_width: Some(a.half_width), ..Default::default() };
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
            .expect("valid template"),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar.set_message(format!("reading {}", a.field.display()));
    let field = sparse_levelset::npy::read_npy(&a.field).map_err(|e| e.to_string())?;
    bar.set_message(format!("fast marching, order {}", a.order));
    let start = std::time::Instant::now();
    let out = distance_dense(&field, a.voxel_size, &opts)
        .map_err(|e| format!("{}: {e}", a.field.display()))?;
    let seconds = start.elapsed().as_secs_f64();
    bar.set_message(format!("writing {}", a.output.display()));
    sparse_levelset::npy::write_npy(&a.output, &out).map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    let g = a.half_width * a.voxel_size;
    let band = out.data().iter().filter(|v| v.abs() < g).count();
    outln!(
        "wrote {}: {band} band voxels (|φ| < {g}) of {}, order {}, {seconds:.3} s",
        a.output.display(),
        out.data().len(),
        a.order
    );
    Ok(())
}

fn run_render(a: &RenderArgs) -> Result<(), String> {
    use indicatif::{ProgressBar, ProgressStyle};
    use sparse_levelset::{build, render};
    use std::time::Instant;
    let i = &a.source;
    let opts = render::RenderOptions {
        width: a.width,
        height: a.height,
        azimuth_deg: a.azimuth,
        elevation_deg: a.elevation,
        fov_deg: a.fov,
        samples: a.samples,
        ground: !a.no_ground,
        shadows: !a.no_shadows,
        ..Default::default()
    };
    opts.validate().map_err(|e| e.to_string())?;
    let spec = GridSpec::new(i.voxel_size, [0.0; 3], i.half_width).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let (name, tiles) = if let Some(path) = a.input.as_ref().or(i.field.as_ref()) {
        let field = sparse_levelset::npy::read_npy(path).map_err(|e| e.to_string())?;
        let tiles = build::tiles_from_dense(&field, spec)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        (path.display().to_string(), tiles)
    } else {
        let kind = i.shape.kind();
        let shape = i.shape.build()?;
        build::check_band_fits(&shape, &spec, 1.0).map_err(|e| e.to_string())?;
        let tiles = build::tiles_from_shape(&shape, spec).map_err(|e| e.to_string())?;
        (format!("{kind:?}").to_lowercase(), tiles)
    };
    let build_seconds = start.elapsed().as_secs_f64();
    let bar = if a.quiet { ProgressBar::hidden() } else { ProgressBar::new(a.height as u64) };
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} rows")
            .expect("valid template"),
    );
    let b = bar.clone();
    let opts = render::RenderOptions {
        progress: sparse_levelset::progress::Progress::new(move |rows, _| {
            b.set_position(rows);
            true
        }),
        ..opts
    };
    let start = Instant::now();
    let (grid, image) = match a.grid {
        GridArg::Tiles => ("tiles", render::render(&tiles, &opts)),
        GridArg::Dtgrid => {
            let dt = build::dtgrid_from(&tiles);
            ("dtgrid", render::render(&dt, &opts))
        }
        GridArg::Dense => return Err("render traces tiles or dtgrid, not dense".into()),
    };
    let image = image.map_err(|e| format!("{name}: {e}"))?;
    let render_seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    image.write_png(&a.output).map_err(|e| e.to_string())?;
    let hit_pixels = (0..image.height())
        .flat_map(|y| (0..image.width()).map(move |x| (x, y)))
        .filter(|&(x, y)| image.depth(x, y).is_some())
        .count();
    if i.json {
        let summary = serde_json::json!({
            "source": name, "grid": grid, "width": a.width, "height": a.height,
            "samples": a.samples, "build_seconds": build_seconds,
            "render_seconds": render_seconds, "hit_pixels": hit_pixels,
            "output": a.output.display().to_string(),
        });
        outln!("{}", serde_json::to_string_pretty(&summary).expect("summary serialises"));
    } else {
        outln!(
            "{name}: {}x{} pixels, {}² rays per pixel, on {grid} in {render_seconds:.2} s \
             (grid built in {build_seconds:.2} s); {hit_pixels} pixels hit the surface; wrote {}",
            a.width,
            a.height,
            a.samples,
            a.output.display()
        );
    }
    Ok(())
}

fn run_mesh(a: &MeshArgs) -> Result<(), String> {
    use indicatif::{ProgressBar, ProgressStyle};
    use sparse_levelset::mesh::{self, MeshFormat};
    let format = MeshFormat::from_path(&a.output, a.ascii).map_err(|e| e.to_string())?;
    let spec = GridSpec::new(a.voxel_size, [0.0; 3], a.half_width).map_err(|e| e.to_string())?;
    if !a.iso.is_finite() {
        return Err(format!("--iso must be finite, got {}", a.iso));
    }
    let bar = if a.quiet { ProgressBar::hidden() } else { ProgressBar::new_spinner() };
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let start = std::time::Instant::now();
    let (source, m) = if let Some(path) = &a.input {
        bar.set_message(format!("reading {}", path.display()));
        let field = sparse_levelset::npy::read_npy(path).map_err(|e| e.to_string())?;
        bar.set_message("meshing");
        let m = mesh::isosurface_dense(&field, &spec, a.iso)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        (path.display().to_string(), m)
    } else {
        let kind = a.shape.kind();
        let shape = a.shape.build()?;
        sparse_levelset::build::check_band_fits(&shape, &spec, 1.0).map_err(|e| e.to_string())?;
        bar.set_message("building tiles");
        let tiles =
            sparse_levelset::build::tiles_from_shape(&shape, spec).map_err(|e| e.to_string())?;
        bar.set_length(tiles.len() as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} tiles",
            )
            .expect("valid template"),
        );
        let m = mesh::isosurface_tiles_with_progress(&tiles, a.iso, &|k| bar.inc(k as u64))
            .map_err(|e| e.to_string())?;
        (format!("{kind:?}").to_lowercase(), m)
    };
    bar.finish_and_clear();
    if m.is_empty() {
        return Err(format!("{source}: the level set has no surface at iso = {}", a.iso));
    }
    let seconds = start.elapsed().as_secs_f64();
    m.write(&a.output, Some(format)).map_err(|e| e.to_string())?;
    let closed = m.is_closed_manifold();
    outln!(
        "{source}: {} vertices, {} triangles, area {:.6e}, enclosed volume {:.6e}, closed \
         manifold: {}, Euler characteristic {} ({seconds:.3} s from input to mesh)",
        m.num_vertices(),
        m.num_triangles(),
        m.area(),
        m.enclosed_volume(),
        if closed { "yes" } else { "no" },
        m.euler_characteristic()
    );
    outln!("wrote {} ({format:?})", a.output.display());
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Info(a)) => run_info(&a).map(|r| {
            if a.json {
                outln!("{}", serde_json::to_string_pretty(&r).expect("report serialises"));
            } else {
                out!("{}", r.to_text());
            }
        }),
        Some(Command::Bench(a)) => run_bench(&a),
        Some(Command::Run(a)) => run_scenario(&a),
        Some(Command::Distance(a)) => run_distance(&a),
        Some(Command::Render(a)) => run_render(&a),
        Some(Command::Mesh(a)) => run_mesh(&a),
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
