//! `levelset distance`: the signed distance to the zero level set of a dense field by fast
//! marching, like scikit-fmm's `distance`.

use clap::Args;
use levelset_cli::output::check_output;
use levelset_cli::{outln, progress};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::io::input::{self, Expect};
use sparse_levelset::tools::fmm::{distance_dense, FmmOptions, Order};
use std::path::PathBuf;

#[derive(Args)]
pub struct DistanceArgs {
    /// A dense float32 .npy level set (shape (nz, ny, nx)); its zero level set is the
    /// interface, φ < 0 inside. Any scale: it need not be a distance field.
    pub field: PathBuf,
    /// Output .npy file (written atomically): the signed distance, ±W·voxel beyond the band.
    #[arg(short, long, value_name = "OUT.npy")]
    pub output: PathBuf,
    /// Order of the update: 1 (first-order FMM) or 2 (high-accuracy FMM).
    #[arg(long, default_value_t = 2, allow_hyphen_values = true,
          value_parser = clap::value_parser!(u8).range(1..=2))]
    pub order: u8,
    /// Band half-width W in voxels (> 1): distances are marched up to W voxels.
    #[arg(long, default_value_t = 3.0, allow_hyphen_values = true)]
    pub half_width: f32,
    /// Voxel edge length in world units (distances are written in world units).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub voxel_size: f32,
}

pub fn run(a: &DistanceArgs) -> Result<(), String> {
    let spec = GridSpec::new(a.voxel_size, [0.0; 3], a.half_width).map_err(|e| e.to_string())?;
    check_output(&a.output)?;
    let order = if a.order == 1 { Order::First } else { Order::Second };
    let opts = FmmOptions { order, half_width: Some(a.half_width), ..Default::default() };
    let bar = progress::spinner(false);
    bar.set_message(format!("reading {}", a.field.display()));
    // Any level set with an interface (this command makes distance fields); the input and
    // the output are held at once.
    let expect = Expect { distance_field: false, copies: 2.0, ..Expect::new(spec) };
    let field = input::load_npy(&a.field, &expect).map_err(|e| e.to_string())?;
    bar.set_message(format!("fast marching, order {}", a.order));
    let start = std::time::Instant::now();
    let out = distance_dense(&field, a.voxel_size, &opts)
        .map_err(|e| format!("{}: {e}", a.field.display()))?;
    let seconds = start.elapsed().as_secs_f64();
    bar.set_message(format!("writing {}", a.output.display()));
    sparse_levelset::io::npy::write_npy(&a.output, &out).map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    let g = spec.gamma();
    let band = out.data().iter().filter(|v| v.abs() < g).count();
    outln!(
        "wrote {}: {band} band voxels (|φ| < {g}) of {}, order {}, {seconds:.3} s",
        a.output.display(),
        out.data().len(),
        a.order
    );
    Ok(())
}
