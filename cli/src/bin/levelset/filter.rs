//! `levelset filter IN -o OUT --op NAME[:VALUE] ...`: OpenVDB's level-set filters
//! (`vdb_tool`'s `-dilate`, `-erode`, `-open`, `-close`, `-gauss`, `-mean`, `-median`) on a
//! level set in any format, in the order given ([`sparse_levelset::tools::filter`]).

use crate::source::{level_set_output, FileGridArgs};
use clap::Args;
use levelset_cli::{outln, progress};
use sparse_levelset::io;
use sparse_levelset::io::input::Expect;
use sparse_levelset::tools::filter::{filter, validate, Filter};
use std::path::PathBuf;

#[derive(Args)]
pub struct FilterArgs {
    /// The level set: .npy (dense, on --voxel-size and --half-width), .sls or .vdb.
    pub input: PathBuf,
    /// Output, written atomically in the format its extension names (.sls, .vdb or .npy).
    #[arg(short, long, value_name = "OUT.sls|OUT.vdb|OUT.npy")]
    pub output: PathBuf,
    /// A filter, `NAME[:VALUE]`, repeatable, applied in the order given. Distances and
    /// times are in world units, widths in voxels: `offset:D` (outwards, inwards when
    /// negative), `dilate:D`, `erode:D`, `open:R`, `close:R`, `mean-curvature:T` (a sphere's
    /// r² shrinks by 2T), `gaussian:W`, `mean:W`, `median:W` (the (2W + 1)³ neighbourhood,
    /// W = 1 to 8), `renormalize`.
    #[arg(long = "op", value_name = "NAME[:VALUE]", required = true, allow_hyphen_values = true)]
    pub ops: Vec<String>,
    #[command(flatten)]
    pub grid: FileGridArgs,
    /// No progress spinner.
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: &FilterArgs) -> Result<(), String> {
    let filters = a
        .ops
        .iter()
        .map(|s| s.parse::<Filter>().map_err(|e| format!("--op {e}")))
        .collect::<Result<Vec<_>, _>>()?;
    validate(&filters).map_err(|e| e.to_string())?;
    let spec = a.grid.spec()?;
    level_set_output(&a.output)?;
    let (pool, _) = a.grid.pool()?;
    let bar = progress::spinner(a.quiet);
    bar.set_message(format!("reading {}", a.input.display()));
    let expect = Expect { copies: 3.0, ..Expect::new(spec) };
    let name = a.input.display().to_string();
    let result = pool.install(|| -> Result<_, String> {
        let loaded = io::load_level_set(&a.input, &expect).map_err(|e| e.to_string())?;
        bar.set_message(format!("filtering {name}"));
        let start = std::time::Instant::now();
        let out = filter(&loaded.level_set, &filters).map_err(|e| format!("{name}: {e}"))?;
        let seconds = start.elapsed().as_secs_f64();
        bar.set_message(format!("writing {}", a.output.display()));
        io::save_level_set(&a.output, &out, &io::SaveOptions::default())
            .map_err(|e| e.to_string())?;
        Ok((out.band_voxels(), seconds))
    })?;
    bar.finish_and_clear();
    outln!(
        "{name} -> {}: {} filter(s), {} band voxels, {:.3} s",
        a.output.display(),
        filters.len(),
        result.0,
        result.1
    );
    Ok(())
}
