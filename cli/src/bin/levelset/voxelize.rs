//! `levelset voxelize`: a triangle mesh (OBJ, PLY or STL) to a narrow-band signed distance
//! field ([`sparse_levelset::tools::voxelize`]), written as a dense `.npy` around the band (or a
//! sparse `.sls`); a folder of meshes into a folder of `.npy` fields with one summary.

use clap::{Args, ValueEnum};
use levelset_cli::output::check_output;
use levelset_cli::{batch, outln, progress};
use serde::{Deserialize, Serialize};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::io::mesh::MeshFormat;
use sparse_levelset::io::{save_level_set, LevelSetFormat, SaveOptions};
use sparse_levelset::storage::sample::band_voxel_box;
use sparse_levelset::tools::voxelize::{default_voxel_size, voxelize, SignMethod, VoxelizeOptions};
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum SignArg {
    /// Votes of axis rays along x, y and z (robust to holes and self-intersections).
    Rays,
    /// The winding count along one x ray (closed, clean meshes only).
    SingleRay,
}

#[derive(Args)]
pub struct VoxelizeArgs {
    /// The mesh: .obj, .ply or .stl (ASCII or binary), any case. A directory: folder
    /// mode, every mesh in it (see --output); under `mpirun -n N` (a build with
    /// `--features mpi`) the meshes are spread over the ranks.
    #[arg(value_name = "MESH|DIR")]
    pub mesh: PathBuf,
    /// Output: OUT.sls, the sparse band (docs/sls-format.md), OUT.vdb (OpenVDB), or OUT.npy,
    /// a dense float32 field (shape (nz, ny, nx), φ < 0 inside, world units) covering the band plus one
    /// voxel, ±γ beyond the band; written atomically. In folder mode a directory:
    /// OUTDIR/NAME.npy per mesh NAME.EXT (in name order) and OUTDIR/summary.json. Meshes
    /// run in parallel (one thread each) when there are at least as many as threads, one
    /// after another with all threads otherwise; a mesh that fails is reported and skipped,
    /// and the exit code is nonzero. Under `mpirun -n N`, rank r takes the meshes i with
    /// i % N = r, each rank with --threads threads, and rank 0 writes summary.json.
    #[arg(short, long, value_name = "OUT.sls|OUT.npy|OUTDIR")]
    pub output: PathBuf,
    /// Voxel edge length in world units [default: the mesh's median edge length, clamped
    /// to 64..1024 voxels along the longest side of its bounding box].
    #[arg(long, allow_hyphen_values = true)]
    pub voxel_size: Option<f32>,
    /// Band half-width γ in voxels (> 1).
    #[arg(long, default_value_t = 3.0, allow_hyphen_values = true)]
    pub half_width: f32,
    /// How inside is told from outside.
    #[arg(long, value_enum, default_value_t = SignArg::Rays)]
    pub sign: SignArg,
    /// Worker threads [default: all cores].
    #[arg(long, allow_hyphen_values = true,
          value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Voxels of margin around the band in a dense output.
const MARGIN: u32 = 1;

/// The output's format: a level-set file (`.sls`, `.vdb`, dense `.npy`).
fn output_kind(path: &Path) -> Result<LevelSetFormat, String> {
    LevelSetFormat::from_path(path).ok_or_else(|| {
        format!("{}: unknown output format (use {})", path.display(), LevelSetFormat::EXTENSIONS)
    })
}

/// What voxelising one mesh gave: its line of the output and its record in a folder's
/// summary.
#[derive(Debug, Serialize, Deserialize)]
struct Voxelized {
    triangles: usize,
    voxel_size: f32,
    /// Whether the voxel size was chosen from the mesh (no --voxel-size).
    voxel_size_chosen: bool,
    half_width: f32,
    sign: String,
    band_voxels: u64,
    tiles: usize,
    /// The dense output's voxels along x, y, z and the voxel of its element `[0, 0, 0]`
    /// (`.npy` only).
    dims: Option<[usize; 3]>,
    origin: Option<[i32; 3]>,
    /// Seconds of the voxelisation (reading and writing excluded).
    seconds: f64,
    threads: usize,
}

pub fn run(a: &VoxelizeArgs) -> Result<(), String> {
    let threads = a.threads.map_or_else(rayon::current_num_threads, |t| t as usize);
    if a.mesh.is_dir() {
        return folder(a, threads);
    }
    levelset_cli::batch::refuse_one_input_on_ranks(&a.mesh, "mesh")?;
    let bar = progress::spinner(a.quiet);
    let v = voxelize_one(a, &a.mesh, &a.output, threads, &bar)?;
    bar.finish_and_clear();
    let name = a.mesh.display();
    outln!(
        "{name}: {} triangles, voxel size {} ({}), half-width {}, sign {}: {} band voxels \
         in {} tiles, {:.3} s on {threads} thread{}",
        v.triangles,
        v.voxel_size,
        if v.voxel_size_chosen { "chosen from the mesh" } else { "given" },
        v.half_width,
        v.sign,
        v.band_voxels,
        v.tiles,
        v.seconds,
        if threads == 1 { "" } else { "s" }
    );
    let written = match v.origin {
        None => format!("({} band voxels, sparse)", v.band_voxels),
        Some([x, y, z]) => format!(
            "(element [0, 0, 0] is voxel ({x}, {y}, {z}), voxel (0, 0, 0) at the world origin)"
        ),
    };
    outln!("wrote {} {written}", a.output.display());
    Ok(())
}

/// Voxelises the mesh at `path` into `output` on `threads` threads; every check comes
/// before the work. The single-file mode and each mesh of a folder.
fn voxelize_one(
    a: &VoxelizeArgs,
    path: &Path,
    output: &Path,
    threads: usize,
    bar: &indicatif::ProgressBar,
) -> Result<Voxelized, String> {
    let kind = output_kind(output)?;
    check_output(output)?;
    let name = path.display().to_string();
    bar.set_message(format!("reading {name}"));
    let mesh = sparse_levelset::io::mesh::load_mesh(path).map_err(|e| e.to_string())?;
    let chosen = a.voxel_size.is_none();
    let h = match a.voxel_size {
        Some(h) => h,
        None => default_voxel_size(&mesh).map_err(|e| format!("{name}: {e}"))?,
    };
    // The grid (every voxel of the band in the i32 range) and the dense output's box (the
    // mesh's box and the band) are checked before the work.
    let (lo, hi) =
        mesh.positions.iter().fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(lo, hi), p| {
            (std::array::from_fn(|i| lo[i].min(p[i])), std::array::from_fn(|i| hi[i].max(p[i])))
        });
    let spec = GridSpec::new(h, [0.0; 3], a.half_width).map_err(|e| e.to_string())?;
    band_voxel_box(lo, hi, &spec).map_err(|e| format!("{name}: {e}"))?;
    match kind {
        LevelSetFormat::Sls | LevelSetFormat::Vdb => {}
        LevelSetFormat::Npy => {
            let extra = 2.0 * (a.half_width.max(0.0) as f64 + MARGIN as f64 + 1.0);
            let voxels: f64 =
                (0..3).map(|i| ((hi[i] - lo[i]) / h as f64).max(0.0) + extra).product();
            sparse_levelset::memory::check(voxels * 4.0, "the dense .npy output")
                .map_err(|e| format!("{name}: {e} (choose a larger --voxel-size)"))?;
        }
    }
    let b = bar.clone();
    let opts = VoxelizeOptions {
        voxel_size: Some(h),
        half_width: a.half_width,
        sign: match a.sign {
            SignArg::Rays => SignMethod::Rays,
            SignArg::SingleRay => SignMethod::SingleRay,
        },
        progress: sparse_levelset::progress::Progress::new(move |done, total| {
            b.set_length(total);
            b.set_position(done);
            true
        }),
        ..Default::default()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} tiles",
        )
        .expect("valid template"),
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    let start = std::time::Instant::now();
    let grid = pool.install(|| voxelize(&mesh, &opts)).map_err(|e| format!("{name}: {e}"))?;
    let seconds = start.elapsed().as_secs_f64();
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
            .expect("valid template"),
    );
    bar.set_message(format!("writing {}", output.display()));
    let opts = SaveOptions { margin: MARGIN, ..Default::default() };
    let origin = save_level_set(output, &grid, &opts).map_err(|e| e.to_string())?;
    let dims = origin
        .and_then(|_| sparse_levelset::storage::convert::dense_box(&grid, MARGIN).map(|(_, d)| d));
    let origin = origin.map(|o| [o.x, o.y, o.z]);
    Ok(Voxelized {
        triangles: mesh.triangles.len(),
        voxel_size: h,
        voxel_size_chosen: chosen,
        half_width: a.half_width,
        sign: a.sign.to_possible_value().map_or_else(String::new, |v| v.get_name().to_string()),
        band_voxels: grid.band_voxels() as u64,
        tiles: grid.len(),
        dims,
        origin,
        seconds,
        threads,
    })
}

/// The meshes of a folder: `.obj`, `.ply`, `.stl` files (any case), by name.
fn folder_meshes(dir: &Path) -> Result<Vec<PathBuf>, String> {
    batch::list_files(dir, |p| MeshFormat::from_path(p).is_some())
}

/// The output of `mesh` in the folder mode: `OUTDIR/<stem>.npy`.
fn folder_output(a: &VoxelizeArgs, mesh: &Path) -> PathBuf {
    let stem = mesh.file_stem().map_or_else(|| "mesh".into(), |s| s.to_string_lossy());
    a.output.join(format!("{stem}.npy"))
}

/// Folder mode: every mesh of the directory `a.mesh` into `a.output/<stem>.npy`, spread
/// over the MPI ranks when `mpirun` started the process (rank 0 writes the summary).
fn folder(a: &VoxelizeArgs, threads: usize) -> Result<(), String> {
    // Dropped last: MPI is finalised when the last clone goes.
    let transport = levelset_cli::ranks::transport()?;
    let t = transport.as_deref();
    // Every rank checks the same things before any work and fails together.
    let checked = (|| {
        levelset_cli::output::check_output_dir(&a.output)?;
        let meshes = folder_meshes(&a.mesh)?;
        if meshes.is_empty() {
            return Err(format!("{}: no mesh (.obj, .ply, .stl) in it", a.mesh.display()));
        }
        // a.obj and a.ply would both write a.npy.
        let mut outputs: Vec<PathBuf> = meshes.iter().map(|m| folder_output(a, m)).collect();
        outputs.sort();
        if let Some(w) = outputs.windows(2).find(|w| w[0] == w[1]) {
            return Err(format!(
                "{}: two meshes of {} have this output (rename one)",
                w[0].display(),
                a.mesh.display()
            ));
        }
        std::fs::create_dir_all(&a.output).map_err(|e| format!("{}: {e}", a.output.display()))?;
        Ok(meshes)
    })();
    let meshes = batch::agree(t, checked)?;
    let start = std::time::Instant::now();
    let prefix = batch::line_prefix(t);
    // Each rank reports its meshes as they finish, so a long batch shows its progress.
    let results = batch::spread(t, &meshes, threads, |m, threads| {
        let out = folder_output(a, m);
        let r = voxelize_one(a, m, &out, threads, &indicatif::ProgressBar::hidden());
        match &r {
            Ok(v) => outln!(
                "{prefix}{}: {} triangles, {} band voxels, {:.3} s; wrote {}",
                m.display(),
                v.triangles,
                v.band_voxels,
                v.seconds,
                out.display()
            ),
            Err(e) => outln!("{prefix}{}: FAILED, skipped: {e}", m.display()),
        }
        r
    })?;
    let Some(results) = results else { return Ok(()) };
    let failed = results.iter().filter(|r| r.is_err()).count();
    let band_voxels: u64 = results.iter().flatten().map(|v| v.band_voxels).sum();
    let voxelize_seconds: f64 = results.iter().flatten().map(|v| v.seconds).sum();
    let records = meshes
        .iter()
        .zip(results)
        .map(|(m, r)| {
            let mut v = match r {
                Ok(v) => serde_json::to_value(v).map_err(|e| e.to_string())?,
                Err(e) => serde_json::json!({ "error": e }),
            };
            v["mesh"] = serde_json::json!(m.display().to_string());
            v["output"] = serde_json::json!(folder_output(a, m).display().to_string());
            Ok(v)
        })
        .collect::<Result<Vec<_>, String>>()?;
    let fields = vec![
        ("meshes", meshes.len().into()),
        ("failed", failed.into()),
        ("band_voxels", band_voxels.into()),
        ("voxelize_seconds", voxelize_seconds.into()),
    ];
    batch::write_summary(&a.output, fields, records, t, threads, start).map(|(_, how)| {
        outln!("{} meshes, {failed} failed, {band_voxels} band voxels, {how}", meshes.len())
    })?;
    if failed > 0 {
        return Err(format!("{failed} of {} meshes failed (see above)", meshes.len()));
    }
    Ok(())
}
