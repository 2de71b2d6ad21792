//! `levelset csg`: the union, intersection or difference of two dense level sets,
//! computed on their sparse bands ([`sparse_levelset::tools::csg`]).

use clap::{Args, ValueEnum};
use levelset_cli::output::check_output;
use levelset_cli::{outln, progress};
use sparse_levelset::coord::Coord;
use sparse_levelset::grid::GridSpec;
use sparse_levelset::io::input::{self, Expect};
use sparse_levelset::storage::convert::{tiles_from_dense, to_dense};
use sparse_levelset::tools::csg::{csg, CsgOp};
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum OpArg {
    /// A ∪ B: min(φ_A, φ_B).
    Union,
    /// A ∩ B: max(φ_A, φ_B).
    Intersection,
    /// A − B: max(φ_A, −φ_B).
    Difference,
}

#[derive(Args)]
pub struct CsgArgs {
    /// First operand: a dense float32 .npy signed distance field (shape (nz, ny, nx),
    /// φ < 0 inside, world units).
    #[arg(value_name = "A.npy")]
    pub a: PathBuf,
    /// Second operand, on the same voxels (the first element of each array is the same voxel).
    #[arg(value_name = "B.npy")]
    pub b: PathBuf,
    /// The operation.
    #[arg(long, value_enum)]
    pub op: OpArg,
    /// Output .npy file (written atomically), covering both operands' arrays; ±γ beyond
    /// the result's band.
    #[arg(short, long, value_name = "OUT.npy")]
    pub output: PathBuf,
    /// Voxel edge length in world units (of both operands).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub voxel_size: f32,
    /// Band half-width γ in voxels.
    #[arg(long, default_value_t = 3.0, allow_hyphen_values = true)]
    pub half_width: f32,
}

pub fn run(a: &CsgArgs) -> Result<(), String> {
    let spec = GridSpec::new(a.voxel_size, [0.0; 3], a.half_width).map_err(|e| e.to_string())?;
    check_output(&a.output)?;
    let op = match a.op {
        OpArg::Union => CsgOp::Union,
        OpArg::Intersection => CsgOp::Intersection,
        OpArg::Difference => CsgOp::Difference,
    };
    let bar = progress::spinner(false);
    // Both operands are loaded and checked before any work; the output array is held
    // with one of them.
    let expect = Expect { copies: 2.0, ..Expect::new(spec) };
    let mut grids = Vec::new();
    let mut dims = [0usize; 3];
    for path in [&a.a, &a.b] {
        bar.set_message(format!("reading {}", path.display()));
        let field = input::load_npy(path, &expect).map_err(|e| e.to_string())?;
        for (d, n) in dims.iter_mut().zip(field.dims()) {
            *d = (*d).max(n);
        }
        grids.push(tiles_from_dense(&field, spec).map_err(|e| e.to_string())?);
    }
    bar.set_message(op.name());
    let start = std::time::Instant::now();
    let result = csg(&grids[0], &grids[1], op).map_err(|e| e.to_string())?;
    let seconds = start.elapsed().as_secs_f64();
    drop(grids);
    bar.set_message(format!("writing {}", a.output.display()));
    let out = to_dense(&result, Coord::new(0, 0, 0), dims).map_err(|e| e.to_string())?;
    sparse_levelset::io::npy::write_npy(&a.output, &out).map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    outln!(
        "wrote {}: {} of {} and {}, {} band voxels, {seconds:.3} s",
        a.output.display(),
        op.name(),
        a.a.display(),
        a.b.display(),
        result.band_voxels()
    );
    Ok(())
}
