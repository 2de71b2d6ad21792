//! `levelset info`: the grids of a shape, a dense field, a `.sls` or a `.vdb` file, their
//! voxels and bytes.

use crate::source::{Input, SourceArgs};
use clap::Args;
use levelset_cli::info::{info_from_dense, info_from_shape, info_from_sparse};
use levelset_cli::{out, outln};
use sparse_levelset::io::input::Expect;

#[derive(Args)]
pub struct InfoArgs {
    #[command(flatten)]
    pub source: SourceArgs,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Worker threads [default: all cores].
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
}

pub fn run(a: &InfoArgs) -> Result<(), String> {
    let (pool, _) = crate::source::worker_pool(a.threads)?;
    pool.install(|| info(a))
}

fn info(a: &InfoArgs) -> Result<(), String> {
    let spec = a.source.spec()?;
    // The three grids are held at once.
    let expect = Expect { copies: 3.0, ..Expect::new(spec) };
    let report = match a.source.load(&expect)? {
        Input::Field { name, field } => {
            info_from_dense(&name, &field, spec).map_err(|e| format!("{name}: {e}"))?
        }
        Input::Shape { name, shape } => {
            info_from_shape(&name, &shape, spec).map_err(|e| e.to_string())?
        }
        Input::Sparse { name, grid, header } => {
            info_from_sparse(&name, &grid, header.as_ref()).map_err(|e| format!("{name}: {e}"))?
        }
    };
    if a.json {
        outln!("{}", serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?);
    } else {
        out!("{}", report.to_text());
    }
    Ok(())
}
