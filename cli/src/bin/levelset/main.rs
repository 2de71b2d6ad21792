//! The `levelset` command: one module per subcommand. Every input goes through the
//! library's one loader ([`sparse_levelset::io::input`]) and every output path is checked
//! before the work starts. The speed-up report is its own binary, `levelset-speedup`.

mod convert;
mod csg;
mod distance;
mod evolve;
mod filter;
mod info;
mod mesh;
mod phantom;
mod render;
mod run;
mod segment;
mod source;
mod voxelize;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Large buffers in huge pages ([`sparse_levelset::alloc::LargePages`]).
#[global_allocator]
static ALLOC: sparse_levelset::alloc::LargePages = sparse_levelset::alloc::LargePages;

#[derive(Parser)]
#[command(
    name = "levelset",
    version,
    about = "Level sets on sparse grids: the Sorted Tile List engine and its DT-Grid reference",
    arg_required_else_help = true,
    after_help = "The speed-up report (tiles against the DT-Grid) is its own binary: \
                  `levelset-speedup --help`, or `cargo run --release` in the repository."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Build the grids (DT-Grid, tiles, H-RLE) from a shape or a level set (.npy, .sls,
    /// .vdb) and report voxels and bytes, and the size of the .sls file.
    Info(info::InfoArgs),
    /// Evolve one of the papers' scenarios and write DIR/summary.json.
    Run(run::RunArgs),
    /// Signed distance to the zero level set of a level set (.npy, .sls, .vdb) by fast
    /// marching (like scikit-fmm's `distance`), within a band of half-width W.
    Distance(distance::DistanceArgs),
    /// Ray-trace the zero level set of a shape or a level set (.npy, .sls, .vdb) into a PNG.
    Render(render::RenderArgs),
    /// Mesh the zero set of a shape or a level set (.npy, .sls, .vdb) (simplicial
    /// isosurfacing on the Kuhn triangulation) into a PLY, OBJ or STL file and report its
    /// size and checks.
    Mesh(mesh::MeshArgs),
    /// Convert between dense .npy fields, sparse .sls files, OpenVDB .vdb level sets and
    /// meshes (in: .obj, .ply, .stl, voxelised; out: .ply, .obj, meshed), by the files'
    /// extensions.
    Convert(convert::ConvertArgs),
    /// Union, intersection or difference of two level sets (.npy, .sls, .vdb, in any
    /// pair), computed on their sparse bands, into the format the output names.
    Csg(csg::CsgArgs),
    /// Filter a level set (.npy, .sls, .vdb) as OpenVDB's LevelSetFilter does: offset,
    /// dilate, erode, open, close, mean-curvature motion, Gaussian, mean and median of the
    /// band, renormalisation; several in one call, in the order given.
    Filter(filter::FilterArgs),
    /// Evolve a level set (.npy, .sls, .vdb) under a normal speed, mean-curvature motion
    /// and advection by a velocity field (.npy, .vdb) for a time or a number of steps; the
    /// result in any format.
    Evolve(evolve::EvolveArgs),
    /// Signed distance to a triangle mesh (.obj, .ply, .stl) on a narrow band: exact
    /// distances, inside/outside by ray votes robust to holes, into a .npy field; a
    /// directory of meshes into a directory of fields (spread over the ranks under mpirun).
    Voxelize(voxelize::VoxelizeArgs),
    /// Segment a scan (NIfTI, MetaImage, NRRD, .npy, PNG) from seeds or a mask by threshold propagation,
    /// geodesic active contours or Chan–Vese; the mask in the input's format; a directory
    /// of scans in one batch (spread over the ranks under mpirun).
    Segment(segment::SegmentArgs),
    /// Write a seeded noisy phantom (image, truth mask, seeds) for the segmentation.
    Phantom(phantom::PhantomArgs),
}

fn main() -> ExitCode {
    // Ctrl-C or a termination signal: no temporary file of a write in progress is left
    // beside its output (the output itself is replaced only by a completed rename).
    let _ = ctrlc::set_handler(|| {
        sparse_levelset::io::fsutil::abandon_writes();
        std::process::exit(130);
    });
    // Ok(Some(code)): finished with a distinct exit code (3: a segmentation leaked, vanished
    // or told nothing apart).
    let plain = |r: Result<(), String>| r.map(|()| None::<u8>);
    // Every refusal exits with 1 (README), a bad flag included; --help and --version are
    // answers (0).
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { ExitCode::FAILURE } else { ExitCode::SUCCESS };
        }
    };
    // A level forced by LEVELSET_SIMD that this CPU cannot run is refused, not replaced.
    if let Err(e) = levelset_kernels::check_env() {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    // Under an MPI launcher, only the commands that spread their work over the ranks run;
    // any other would run whole on every rank and write the same files.
    let spreads = matches!(
        cli.command,
        Command::Run(_) | Command::Evolve(_) | Command::Segment(_) | Command::Voxelize(_)
    );
    if let Some(n) = levelset_cli::ranks::launched_ranks().filter(|&n| n > 1 && !spreads) {
        eprintln!(
            "error: started on {n} MPI ranks, but this command runs in one process (every rank \
             would do the whole job and write the same files): run it without mpirun; run, \
             evolve, segment and voxelize spread their work over the ranks"
        );
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Info(a) => plain(info::run(&a)),
        Command::Run(a) => plain(run::run(&a)),
        Command::Distance(a) => plain(distance::run(&a)),
        Command::Render(a) => plain(render::run(&a)),
        Command::Mesh(a) => plain(mesh::run(&a)),
        Command::Csg(a) => plain(csg::run(&a)),
        Command::Filter(a) => plain(filter::run(&a)),
        Command::Evolve(a) => plain(evolve::run(&a)),
        Command::Convert(a) => plain(convert::run(&a)),
        Command::Voxelize(a) => plain(voxelize::run(&a)),
        Command::Segment(a) => {
            segment::run(&a).map(|leaked| leaked.then_some(segment::EXIT_LEAKED))
        }
        Command::Phantom(a) => plain(phantom::run(&a)),
    };
    match result {
        Ok(None) => ExitCode::SUCCESS,
        Ok(Some(code)) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
