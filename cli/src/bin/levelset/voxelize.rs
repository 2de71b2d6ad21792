//! `levelset voxelize`: a triangle mesh (OBJ, PLY or STL) to a narrow-band signed distance
//! field ([`sparse_levelset::voxelize`]), written as a dense `.npy` around the band.

use clap::{Args, ValueEnum};
use levelset_cli::output::check_output;
use levelset_cli::{outln, progress};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::sample::band_voxel_box;
use sparse_levelset::voxelize::{
    default_voxel_size, read_mesh, voxelize, SignMethod, VoxelizeOptions,
};
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
    /// The mesh: .obj, .ply or .stl (ASCII or binary), any case.
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// Output: OUT.sls, the sparse band (docs/sls-format.md), or OUT.npy, a dense float32
    /// field (shape (nz, ny, nx), φ < 0 inside, world units) covering the band plus one
    /// voxel, ±γ beyond the band; written atomically.
    #[arg(short, long, value_name = "OUT.sls|OUT.npy")]
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

/// The output formats, by extension.
#[derive(Clone, Copy, Debug)]
enum Output {
    /// The sparse band as a `.sls` file ([`sparse_levelset::sls::save`]).
    Sls,
    /// A dense `.npy` around the band ([`sparse_levelset::build::export_npy`]).
    Npy,
}

/// Voxels of margin around the band in a dense output.
const MARGIN: u32 = 1;

fn output_kind(path: &Path) -> Result<Output, String> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("npy") => Ok(Output::Npy),
        Some("sls") => Ok(Output::Sls),
        _ => Err(format!("{}: unknown output format (use .sls or .npy)", path.display())),
    }
}

pub fn run(a: &VoxelizeArgs) -> Result<(), String> {
    let kind = output_kind(&a.output)?;
    check_output(&a.output)?;
    let name = a.mesh.display().to_string();
    let bar = progress::spinner(a.quiet);
    bar.set_message(format!("reading {name}"));
    let mesh = read_mesh(&a.mesh).map_err(|e| e.to_string())?;
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
        Output::Sls => {}
        Output::Npy => {
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
    let threads = a.threads.map_or_else(rayon::current_num_threads, |t| t as usize);
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
    bar.set_message(format!("writing {}", a.output.display()));
    let written = match kind {
        Output::Sls => {
            sparse_levelset::sls::save(&a.output, &grid).map_err(|e| e.to_string())?;
            format!("({} band voxels, sparse)", grid.band_voxels())
        }
        Output::Npy => {
            let origin = sparse_levelset::build::export_npy(&grid, &a.output, MARGIN)
                .map_err(|e| format!("{}: {e}", a.output.display()))?;
            format!("(element [0, 0, 0] is voxel {origin}, voxel (0, 0, 0) at the world origin)")
        }
    };
    bar.finish_and_clear();
    outln!(
        "{name}: {} triangles, voxel size {h} ({}), half-width {}, sign {:?}: {} band voxels \
         in {} tiles, {seconds:.3} s on {threads} thread{}",
        mesh.triangles.len(),
        if chosen { "chosen from the mesh" } else { "given" },
        a.half_width,
        a.sign,
        grid.band_voxels(),
        grid.len(),
        if threads == 1 { "" } else { "s" }
    );
    outln!("wrote {} {written}", a.output.display());
    Ok(())
}
