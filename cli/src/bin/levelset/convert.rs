//! `levelset convert IN OUT`: between dense `.npy` fields, sparse `.sls` files, OpenVDB
//! `.vdb` level sets and meshes (`.obj`, `.ply`, `.stl`),
//! chosen by the extensions. Every input goes through the library's one loader; the
//! output path is checked before any work and written atomically.

use clap::{Args, ValueEnum};
use levelset_cli::output::check_output;
use levelset_cli::{outln, progress};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::io::input::Expect;
use sparse_levelset::io::mesh::{load_mesh, save_mesh, MeshFormat};
use sparse_levelset::io::vdb::{VdbCompression, VdbOptions};
use sparse_levelset::io::{self, AnyLevelSet, LevelSetFormat, SaveOptions};
use sparse_levelset::tools::mesh;
use sparse_levelset::tools::voxelize::{voxelize, VoxelizeOptions};
use sparse_levelset::LevelSet;
use std::path::PathBuf;

#[derive(Args)]
pub struct ConvertArgs {
    /// Input: a dense float32 .npy signed distance field, a sparse .sls file, an OpenVDB
    /// .vdb file (its first float grid of class "level set"), or a mesh (.obj, .ply,
    /// .stl), voxelised as `levelset voxelize` does.
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// Output: .sls (sparse, H-RLE encoded), .vdb (an OpenVDB level set for Blender,
    /// Houdini and OpenVDB's tools), .npy (dense, the band's box grown by --margin, ±γ
    /// beyond the band), or a mesh of the zero set (.ply binary, .obj, binary .stl).
    #[arg(value_name = "OUT")]
    pub output: PathBuf,
    /// Voxel edge length in world units of a .npy input [default: 1] or of a voxelised mesh
    /// [default: chosen from the mesh, as `levelset voxelize`]; a .sls file carries its own.
    #[arg(long, allow_hyphen_values = true)]
    pub voxel_size: Option<f32>,
    /// Band half-width γ in voxels of a .npy or mesh input.
    #[arg(long, default_value_t = 3.0, allow_hyphen_values = true)]
    pub half_width: f32,
    /// Voxels of ±γ around the band in a .npy output.
    #[arg(long, default_value_t = 2)]
    pub margin: u32,
    /// Compression of a .vdb output's values besides leaving out the inactive ones: none
    /// (fastest to write and read) or zip (zlib: a few percent smaller, slower).
    #[arg(long, value_enum, default_value_t = VdbCodec::None)]
    pub vdb_compression: VdbCodec,
    /// Name of the grid in a .vdb output.
    #[arg(long, default_value = "level_set")]
    pub vdb_grid_name: String,
    /// No progress spinner.
    #[arg(long)]
    pub quiet: bool,
    /// Worker threads [default: all cores].
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum VdbCodec {
    None,
    Zip,
}

/// The output: a level-set file or a mesh of the zero set.
enum Out {
    LevelSet,
    Mesh(MeshFormat),
}

pub fn run(a: &ConvertArgs) -> Result<(), String> {
    let (pool, _) = crate::source::worker_pool(a.threads)?;
    pool.install(|| convert(a))
}

fn convert(a: &ConvertArgs) -> Result<(), String> {
    let out = if LevelSetFormat::from_path(&a.output).is_some() {
        Out::LevelSet
    } else if let Some(format) = MeshFormat::from_path(&a.output) {
        Out::Mesh(format)
    } else {
        return Err(format!(
            "{}: unknown output type; use {} or {}",
            a.output.display(),
            LevelSetFormat::EXTENSIONS,
            MeshFormat::EXTENSIONS
        ));
    };
    let is_mesh = MeshFormat::from_path(&a.input).is_some();
    if !(is_mesh || LevelSetFormat::from_path(&a.input).is_some()) {
        return Err(format!(
            "{}: unknown input type; use {} or {}",
            a.input.display(),
            LevelSetFormat::EXTENSIONS,
            MeshFormat::EXTENSIONS
        ));
    }
    let vdb_opts = VdbOptions {
        grid_name: a.vdb_grid_name.clone(),
        compression: match a.vdb_compression {
            VdbCodec::None => VdbCompression::None,
            VdbCodec::Zip => VdbCompression::Zip,
        },
    };
    if a.vdb_grid_name.is_empty() || a.vdb_grid_name.contains('\u{1e}') {
        return Err("--vdb-grid-name: a .vdb grid needs a name (without U+001E)".into());
    }
    let spec = GridSpec::new(a.voxel_size.unwrap_or(1.0), [0.0; 3], a.half_width)
        .map_err(|e| e.to_string())?;
    check_output(&a.output)?;
    let name = a.input.display().to_string();
    let bar = progress::spinner(a.quiet);
    let start = std::time::Instant::now();
    bar.set_message(format!("reading {name}"));
    // The input and the grid made from it are held at once.
    let expect = Expect { copies: 2.0, ..Expect::new(spec) };
    let grid: AnyLevelSet = if is_mesh {
        let mesh = load_mesh(&a.input).map_err(|e| e.to_string())?;
        bar.set_message(format!("voxelising {name}"));
        let opts = VoxelizeOptions {
            voxel_size: a.voxel_size,
            half_width: a.half_width,
            ..Default::default()
        };
        AnyLevelSet::Tiles(voxelize(&mesh, &opts).map_err(|e| format!("{name}: {e}"))?)
    } else {
        io::load_level_set(&a.input, &expect).map_err(|e| e.to_string())?.level_set
    };
    bar.set_message(format!("writing {}", a.output.display()));
    let what = match out {
        Out::LevelSet => {
            let opts = SaveOptions { margin: a.margin, vdb: vdb_opts };
            match io::save_level_set(&a.output, &grid, &opts).map_err(|e| e.to_string())? {
                Some(origin) => {
                    format!("{} band voxels, array origin voxel {origin}", grid.band_voxels())
                }
                None => format!("{} band voxels", grid.band_voxels()),
            }
        }
        Out::Mesh(format) => {
            let m =
                mesh::isosurface(&grid, &Default::default()).map_err(|e| format!("{name}: {e}"))?;
            if m.is_empty() {
                return Err(format!("{name}: the level set has no surface to mesh"));
            }
            save_mesh(&a.output, &m, Some(format)).map_err(|e| e.to_string())?;
            format!("{} triangles", m.num_triangles())
        }
    };
    bar.finish_and_clear();
    outln!("{name} -> {}: {what} ({:.3} s)", a.output.display(), start.elapsed().as_secs_f64());
    Ok(())
}
