//! `levelset csg`: the union, intersection or difference of two level sets in any format,
//! computed on their sparse bands ([`sparse_levelset::tools::csg`]) and written sparse or
//! dense as the output's extension says.

use crate::source::{level_set_output, FileGridArgs};
use clap::{Args, ValueEnum};
use levelset_cli::{outln, progress};
use sparse_levelset::coord::Coord;
use sparse_levelset::io::input::Expect;
use sparse_levelset::io::{self, LevelSetFormat};
use sparse_levelset::storage::convert::to_dense;
use sparse_levelset::tools::csg::{csg, CsgOp};
use sparse_levelset::LevelSet;
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
    /// First operand: a level set in any format — a dense float32 .npy signed distance
    /// field (shape (nz, ny, nx), φ < 0 inside, world units, on --voxel-size and
    /// --half-width), a sparse .sls file or an OpenVDB .vdb level set (both carry their own
    /// grid).
    #[arg(value_name = "A")]
    pub a: PathBuf,
    /// Second operand, on the same grid (a .npy's first element is voxel (0, 0, 0)).
    #[arg(value_name = "B")]
    pub b: PathBuf,
    /// The operation.
    #[arg(long, value_enum)]
    pub op: OpArg,
    /// Output, written atomically in the format its extension names: .sls or .vdb (the
    /// sparse result, no dense pass), or .npy (dense: the box of both operands' arrays and
    /// bands, ±γ beyond the result's band).
    #[arg(short, long, value_name = "OUT.sls|OUT.vdb|OUT.npy")]
    pub output: PathBuf,
    #[command(flatten)]
    pub grid: FileGridArgs,
    /// No progress spinner.
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: &CsgArgs) -> Result<(), String> {
    let spec = a.grid.spec()?;
    let format = level_set_output(&a.output)?;
    let op = match a.op {
        OpArg::Union => CsgOp::Union,
        OpArg::Intersection => CsgOp::Intersection,
        OpArg::Difference => CsgOp::Difference,
    };
    let (pool, _) = a.grid.pool()?;
    let bar = progress::spinner(a.quiet);
    // Both operands are loaded and checked before any work.
    let expect = Expect { copies: 2.0, ..Expect::new(spec) };
    let mut operands = Vec::new();
    // The dense output's box: every operand's array (a .npy) or band (a sparse file).
    let mut lo = [i32::MAX; 3];
    let mut hi = [i32::MIN; 3];
    for path in [&a.a, &a.b] {
        bar.set_message(format!("reading {}", path.display()));
        let loaded =
            pool.install(|| io::load_level_set(path, &expect)).map_err(|e| e.to_string())?;
        let (l, h) = match loaded.npy_dims {
            Some(d) => ([0; 3], [d[0] as i32 - 1, d[1] as i32 - 1, d[2] as i32 - 1]),
            None => match loaded.level_set.band_bounding_box() {
                Some((l, h)) => ([l.x, l.y, l.z], [h.x, h.y, h.z]),
                None => ([0; 3], [0; 3]),
            },
        };
        for d in 0..3 {
            lo[d] = lo[d].min(l[d]);
            hi[d] = hi[d].max(h[d]);
        }
        operands.push(loaded.level_set);
    }
    bar.set_message(op.name());
    let start = std::time::Instant::now();
    let result = pool.install(|| csg(&operands[0], &operands[1], op)).map_err(|e| e.to_string())?;
    let seconds = start.elapsed().as_secs_f64();
    drop(operands);
    bar.set_message(format!("writing {}", a.output.display()));
    pool.install(|| -> Result<(), String> {
        if format == LevelSetFormat::Npy {
            let dims = [0, 1, 2].map(|d| (hi[d] as i64 - lo[d] as i64 + 1).max(1) as usize);
            let origin = Coord::new(lo[0], lo[1], lo[2]);
            let out = to_dense(&result, origin, dims).map_err(|e| e.to_string())?;
            sparse_levelset::io::npy::write_npy(&a.output, &out).map_err(|e| e.to_string())
        } else {
            let opts = io::SaveOptions::default();
            io::save_level_set(&a.output, &result, &opts).map(|_| ()).map_err(|e| e.to_string())
        }
    })?;
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
