//! `levelset render`: a ray-traced PNG of the zero level set of a shape or a dense field.

use crate::run::GridArg;
use crate::source::{Input, SourceArgs};
use clap::Args;
use levelset_cli::output::check_output;
use levelset_cli::{outln, progress};
use sparse_levelset::io::input::Expect;
use sparse_levelset::{storage::convert, tools::render};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct RenderArgs {
    /// The level set: FIELD (a dense .npy) or a shape, with the arguments of `levelset info`.
    #[command(flatten)]
    pub source: SourceArgs,
    /// The PNG to write.
    #[arg(short, long, value_name = "FILE.png")]
    pub output: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 640, allow_hyphen_values = true)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 480, allow_hyphen_values = true)]
    pub height: u32,
    /// Camera azimuth in degrees (counter-clockwise from +x, seen from the object).
    #[arg(long, default_value_t = -60.0, allow_hyphen_values = true)]
    pub azimuth: f64,
    /// Camera elevation in degrees, in (-90, 90).
    #[arg(long, default_value_t = 30.0, allow_hyphen_values = true)]
    pub elevation: f64,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 35.0, allow_hyphen_values = true)]
    pub fov: f64,
    /// Rays per pixel along each axis (samples² per pixel), 1..=8.
    #[arg(long, default_value_t = 2, allow_hyphen_values = true)]
    pub samples: u32,
    /// Grid to trace (tiles or dtgrid; both give the same image).
    #[arg(long, value_enum, default_value_t = GridArg::Tiles)]
    pub grid: GridArg,
    /// No ground plane.
    #[arg(long)]
    pub no_ground: bool,
    /// No shadow rays.
    #[arg(long)]
    pub no_shadows: bool,
    /// Print the render summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Worker threads [default: all cores].
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
}

pub fn run(a: &RenderArgs) -> Result<(), String> {
    let (pool, _) = crate::source::worker_pool(a.threads)?;
    pool.install(|| render_file(a))
}

fn render_file(a: &RenderArgs) -> Result<(), String> {
    let opts = render::RenderOptions {
        width: a.width,
        height: a.height,
        azimuth_deg: a.azimuth,
        elevation_deg: a.elevation,
        fov_deg: a.fov,
        samples: a.samples,
        ground: !a.no_ground,
        shadows: !a.no_shadows,
        ..Default::default()
    };
    opts.validate().map_err(|e| e.to_string())?;
    if matches!(a.grid, GridArg::Dense) {
        return Err("render traces tiles or dtgrid, not dense".into());
    }
    let spec = a.source.spec()?;
    check_output(&a.output)?;
    let start = Instant::now();
    // The tiles, and the DT-Grid made from them, are held at once.
    let copies = if matches!(a.grid, GridArg::Dtgrid) { 2.0 } else { 1.0 };
    let input = a.source.load(&Expect { copies, ..Expect::new(spec) })?;
    let name = input.name().to_string();
    let tiles = match &input {
        Input::Field { field, .. } => {
            convert::tiles_from_dense(field, spec).map_err(|e| format!("{name}: {e}"))?
        }
        Input::Shape { shape, .. } => {
            convert::tiles_from_shape(shape, spec).map_err(|e| e.to_string())?
        }
        Input::Sparse { grid, .. } => convert::tiles_from(grid.as_ref()),
    };
    drop(input);
    let build_seconds = start.elapsed().as_secs_f64();
    let bar = progress::bar(
        a.quiet,
        a.height as u64,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} rows",
    );
    let b = bar.clone();
    let progress = sparse_levelset::progress::Progress::new(move |rows, _| {
        b.set_position(rows);
        true
    });
    let opts = render::RenderOptions { progress, ..opts };
    let start = Instant::now();
    let (grid, image) = match a.grid {
        GridArg::Dtgrid => ("dtgrid", render::render(&convert::dtgrid_from(&tiles), &opts)),
        _ => ("tiles", render::render(&tiles, &opts)),
    };
    let image = image.map_err(|e| format!("{name}: {e}"))?;
    let render_seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    image.write_png(&a.output).map_err(|e| e.to_string())?;
    let hit_pixels = (0..image.height())
        .flat_map(|y| (0..image.width()).map(move |x| (x, y)))
        .filter(|&(x, y)| image.depth(x, y).is_some())
        .count();
    if a.json {
        let summary = serde_json::json!({
            "source": name, "grid": grid, "width": a.width, "height": a.height,
            "samples": a.samples, "build_seconds": build_seconds,
            "render_seconds": render_seconds, "hit_pixels": hit_pixels,
            "output": a.output.display().to_string(),
        });
        outln!("{}", serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?);
    } else {
        outln!(
            "{name}: {}x{} pixels, {}² rays per pixel, on {grid} in {render_seconds:.2} s \
             (grid built in {build_seconds:.2} s); {hit_pixels} pixels hit the surface; wrote {}",
            a.width,
            a.height,
            a.samples,
            a.output.display()
        );
    }
    Ok(())
}
