//! `levelset distance`: the signed distance to the zero level set of any level set by fast
//! marching, like scikit-fmm's `distance` (a dense field of any scale), or the
//! reinitialisation of a sparse `.sls` / `.vdb` level set to a band of a given width.

use clap::Args;
use levelset_cli::output::check_output;
use levelset_cli::{outln, progress};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::io::input::{self, Expect};
use sparse_levelset::io::{self, LevelSetFormat};
use sparse_levelset::storage::convert::tiles_from_dense;
use sparse_levelset::tools::fmm::{distance_dense, reinitialize, FmmOptions, Order};
use std::path::PathBuf;

#[derive(Args)]
pub struct DistanceArgs {
    /// The level set: a dense float32 .npy (shape (nz, ny, nx)) whose zero level set is the
    /// interface, φ < 0 inside, of any scale (it need not be a distance field); or a sparse
    /// .sls / OpenVDB .vdb level set (their own grid).
    pub field: PathBuf,
    /// Output, written atomically in the format its extension names: .npy (dense: the
    /// input's array for a .npy input, the band's box for a sparse one; ±W·voxel beyond the
    /// band), .sls or .vdb (the band of half-width W).
    #[arg(short, long, value_name = "OUT.npy|OUT.sls|OUT.vdb")]
    pub output: PathBuf,
    /// Order of the update: 1 (first-order FMM) or 2 (high-accuracy FMM).
    #[arg(long, default_value_t = 2, allow_hyphen_values = true,
          value_parser = clap::value_parser!(u8).range(1..=2))]
    pub order: u8,
    /// Band half-width W in voxels (> 1): distances are marched up to W voxels.
    #[arg(long, default_value_t = 3.0, allow_hyphen_values = true)]
    pub half_width: f32,
    /// Voxel edge length in world units of a .npy input (distances are written in world
    /// units).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub voxel_size: f32,
    /// Worker threads [default: all cores].
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// No progress spinner.
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: &DistanceArgs) -> Result<(), String> {
    let spec = GridSpec::new(a.voxel_size, [0.0; 3], a.half_width).map_err(|e| e.to_string())?;
    check_output(&a.output)?;
    let unknown = |p: &std::path::Path| {
        format!("{}: unknown level-set file type; use {}", p.display(), LevelSetFormat::EXTENSIONS)
    };
    let out_format = LevelSetFormat::from_path(&a.output).ok_or_else(|| unknown(&a.output))?;
    let in_format = LevelSetFormat::from_path(&a.field).ok_or_else(|| unknown(&a.field))?;
    let order = if a.order == 1 { Order::First } else { Order::Second };
    let opts = FmmOptions { order, half_width: Some(a.half_width), ..Default::default() };
    let (pool, _) = crate::source::worker_pool(a.threads)?;
    let bar = progress::spinner(a.quiet);
    bar.set_message(format!("reading {}", a.field.display()));
    // Any level set with an interface (this command makes distance fields); the input and
    // the output are held at once.
    let expect = Expect { distance_field: false, copies: 2.0, ..Expect::new(spec) };
    let (band, of, seconds) = pool.install(|| -> Result<(usize, usize, f64), String> {
        if in_format == LevelSetFormat::Npy {
            let field = input::load_npy(&a.field, &expect).map_err(|e| e.to_string())?;
            bar.set_message(format!("fast marching, order {}", a.order));
            let start = std::time::Instant::now();
            let out = distance_dense(&field, a.voxel_size, &opts)
                .map_err(|e| format!("{}: {e}", a.field.display()))?;
            let seconds = start.elapsed().as_secs_f64();
            drop(field);
            bar.set_message(format!("writing {}", a.output.display()));
            let g = spec.gamma();
            let band = out.data().iter().filter(|v| v.abs() < g).count();
            if out_format == LevelSetFormat::Npy {
                sparse_levelset::io::npy::write_npy(&a.output, &out).map_err(|e| e.to_string())?;
            } else {
                let tiles = tiles_from_dense(&out, spec).map_err(|e| e.to_string())?;
                io::save_level_set(&a.output, &tiles, &io::SaveOptions::default())
                    .map_err(|e| e.to_string())?;
            }
            Ok((band, out.data().len(), seconds))
        } else {
            let loaded = io::load_level_set(&a.field, &expect).map_err(|e| e.to_string())?;
            bar.set_message(format!("fast marching, order {}", a.order));
            let start = std::time::Instant::now();
            let out = reinitialize(&loaded.level_set, &opts)
                .map_err(|e| format!("{}: {e}", a.field.display()))?;
            let seconds = start.elapsed().as_secs_f64();
            drop(loaded);
            bar.set_message(format!("writing {}", a.output.display()));
            io::save_level_set(&a.output, &out, &io::SaveOptions::default())
                .map_err(|e| e.to_string())?;
            Ok((out.band_voxels(), out.band_voxels(), seconds))
        }
    })?;
    bar.finish_and_clear();
    outln!(
        "wrote {}: {band} band voxels (|φ| < {}) of {of}, order {}, {seconds:.3} s",
        a.output.display(),
        spec.gamma(),
        a.order
    );
    Ok(())
}
