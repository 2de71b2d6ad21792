//! `levelset mesh`: the zero set (or any level inside the band) of a shape or a dense field
//! as a welded triangle mesh, by simplicial isosurfacing.

use crate::source::{Input, SourceArgs};
use clap::Args;
use levelset_cli::output::check_output;
use levelset_cli::{outln, progress};
use sparse_levelset::io::input::Expect;
use sparse_levelset::io::mesh::{save_mesh, MeshFormat};
use sparse_levelset::tools::mesh;
use std::path::PathBuf;

#[derive(Args)]
pub struct MeshArgs {
    #[command(flatten)]
    pub source: SourceArgs,
    /// The isovalue to mesh, in world units, inside the band (|iso| < γ).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub iso: f64,
    /// Output mesh: FILE.ply (binary unless --ascii), FILE.obj or FILE.stl (binary).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Mesh every K-th voxel: the same surface from cells of K voxels, about K² times
    /// fewer triangles, still a closed manifold (1: full resolution).
    #[arg(long, value_name = "K", default_value_t = 1,
          value_parser = clap::value_parser!(u32).range(1..=64))]
    pub coarsen: u32,
    /// Write ASCII PLY instead of binary.
    #[arg(long)]
    pub ascii: bool,
    /// Worker threads [default: all cores].
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: &MeshArgs) -> Result<(), String> {
    let format = match MeshFormat::from_path(&a.output) {
        Some(MeshFormat::Ply { .. }) => MeshFormat::Ply { ascii: a.ascii },
        Some(f) => f,
        None => {
            return Err(format!(
                "{}: unknown mesh format (use {})",
                a.output.display(),
                MeshFormat::EXTENSIONS
            ))
        }
    };
    let spec = a.source.spec()?;
    check_output(&a.output)?;
    // Positions far from the origin are written as f64 (see `sparse_levelset::tools::mesh`), so
    // no position limit applies.
    let expect = Expect { iso: a.iso, ..Expect::new(spec) };
    let bar = progress::spinner(a.quiet);
    let start = std::time::Instant::now();
    if let Some(path) = &a.source.field {
        bar.set_message(format!("reading {}", path.display()));
    }
    let (pool, _) = crate::source::worker_pool(a.threads)?;
    let input = pool.install(|| a.source.load(&expect))?;
    let m = pool.install(|| -> Result<_, String> {
        Ok(match &input {
            Input::Field { name, field } if a.coarsen == 1 => {
                bar.set_message("meshing");
                mesh::isosurface_dense(field, &spec, a.iso).map_err(|e| format!("{name}: {e}"))?
            }
            Input::Sparse { grid, .. } => {
                bar.set_message("meshing");
                let opts =
                    mesh::MeshOptions { iso: a.iso, coarsen: a.coarsen, ..Default::default() };
                mesh::isosurface(grid.as_ref(), &opts)
                    .map_err(|e| format!("{}: {e}", input.name()))?
            }
            Input::Field { name, field } => {
                // Coarsening samples a level set: the field's band as tiles (the loader has
                // checked that it is a distance at the half-width).
                bar.set_message("building tiles");
                let tiles = sparse_levelset::storage::convert::tiles_from_dense(field, spec)
                    .map_err(|e| format!("{name}: {e}"))?;
                bar.set_message("meshing");
                let opts =
                    mesh::MeshOptions { iso: a.iso, coarsen: a.coarsen, ..Default::default() };
                mesh::isosurface(&tiles, &opts).map_err(|e| format!("{name}: {e}"))?
            }
            Input::Shape { shape, .. } => {
                bar.set_message("building tiles");
                let tiles = sparse_levelset::storage::convert::tiles_from_shape(shape, spec)
                    .map_err(|e| e.to_string())?;
                bar.set_length(tiles.len() as u64);
                bar.set_style(
                    indicatif::ProgressStyle::with_template(
                        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} tiles",
                    )
                    .expect("valid template"),
                );
                let b = bar.clone();
                let progress = sparse_levelset::progress::Progress::new(move |done, _| {
                    b.set_position(done);
                    true
                });
                let opts = mesh::MeshOptions { iso: a.iso, progress, coarsen: a.coarsen };
                mesh::isosurface(&tiles, &opts).map_err(|e| e.to_string())?
            }
        })
    })?;
    bar.finish_and_clear();
    let source = input.name();
    if m.is_empty() {
        return Err(format!("{source}: the level set has no surface at iso = {}", a.iso));
    }
    let seconds = start.elapsed().as_secs_f64();
    save_mesh(&a.output, &m, Some(format)).map_err(|e| e.to_string())?;
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
    outln!("wrote {} ({})", a.output.display(), format.name());
    Ok(())
}
