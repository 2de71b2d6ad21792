//! `levelset run`: one of the papers' scenarios, evolved, with `DIR/summary.json` and
//! optional frames (PNG images, PLY meshes) and the final field.

use clap::{Args, ValueEnum};
use levelset_cli::output::{check_output, check_output_dir, stage_json};
use levelset_cli::scenario::{Defaults, Scenario, ScenarioKind, ScenarioOptions};
use levelset_cli::{outln, progress};
use sparse_levelset::evolve::{
    GridKind, Integrator, Lanes, Renormalization, SpatialScheme, Sweeps,
};
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ScenarioArg {
    /// Sphere under mean curvature flow (van der Laan et al. 2011, Sec. 5.1).
    Sphere,
    /// Extruded spiral under volume-conserving mean curvature flow (Sec. 5.2, Table 2).
    Spiral,
    /// Enright's periodic deformation test (Sec. 5.4).
    Enright,
    /// A sphere growing at constant speed far beyond its initial box.
    Expand,
    /// A sphere morphing into a torus (Houston et al. 2006, eq. (1)).
    Morph,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum GridArg {
    Tiles,
    Dtgrid,
    /// The dense reference (small sizes only).
    Dense,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum LanesArg {
    Scalar,
    Simd,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum SchemeArg {
    Upwind1,
    Weno5,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum IntegratorArg {
    Euler,
    Rk3,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum RenormArg {
    /// Russo–Smereka pseudo-time sweeps after the physical step.
    Sweeps,
    /// The rescaling term of eq. (3) inside the PDE (the papers' route).
    Coupled,
    /// None.
    Off,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ReinitArg {
    /// First-order fast marching.
    Fmm,
    /// High-accuracy (second-order) fast marching.
    Fmm2,
}

#[derive(Args)]
pub struct RunArgs {
    /// The scenario.
    #[arg(value_enum)]
    pub scenario: ScenarioArg,
    /// Effective resolution N (an N³ box) [default: sphere 256, spiral and enright 128,
    /// expand and morph 64].
    #[arg(allow_hyphen_values = true, long)]
    pub size: Option<u32>,
    /// Steps to take [default: spiral 1000, morph 300, others 100 unless --time is given;
    /// enright: one period, expand: until the sphere spans twice its box].
    #[arg(allow_hyphen_values = true, long, conflicts_with = "time")]
    pub steps: Option<u64>,
    /// Simulated time to reach (the last step lands on it).
    #[arg(allow_hyphen_values = true, long)]
    pub time: Option<f64>,
    /// Representation.
    #[arg(long, value_enum, default_value_t = GridArg::Tiles)]
    pub grid: GridArg,
    /// Lanes of the tile engine.
    #[arg(long, value_enum, default_value_t = LanesArg::Simd)]
    pub lanes: LanesArg,
    /// Worker threads of the tile engine [default: all cores].
    #[arg(allow_hyphen_values = true, long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// Shape radius [default: sphere 100·N/256, spiral 50·N/128, enright 0.15, expand N/4,
    /// morph 0.3·N].
    #[arg(allow_hyphen_values = true, long)]
    pub radius: Option<f64>,
    /// Curvature weight ε [default: 1 for sphere and spiral, 0 otherwise].
    #[arg(allow_hyphen_values = true, long)]
    pub epsilon: Option<f32>,
    /// Normal speed F of expand [default: 1 voxel per unit time].
    #[arg(allow_hyphen_values = true, long)]
    pub speed: Option<f32>,
    /// Enright's period T [default: 3].
    #[arg(allow_hyphen_values = true, long)]
    pub period: Option<f64>,
    /// Spiral: volume-conserving flow (true) or plain mean curvature flow (false).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub volume_conserving: bool,
    /// Spiral depth [default: 40·N/128].
    #[arg(allow_hyphen_values = true, long)]
    pub depth: Option<f64>,
    /// Band half-width γ in voxels.
    #[arg(allow_hyphen_values = true, long, default_value_t = 3.0)]
    pub half_width: f32,
    /// How φ is kept a signed distance: `sweeps` (Russo–Smereka renormalisation after
    /// the step), `coupled` (the rescaling term of eq. (3) of van der Laan et al. 2011
    /// inside the PDE, the papers' route) or `off`.
    #[arg(long, value_enum, default_value_t = RenormArg::Sweeps)]
    pub renormalize: RenormArg,
    /// Weight w of the coupled rescaling term (with --renormalize coupled) [default: 1].
    #[arg(allow_hyphen_values = true, long)]
    pub rescale: Option<f32>,
    /// Renormalisation sweeps each time (with --renormalize sweeps) [default: 2 for sphere
    /// and morph, 1 otherwise].
    #[arg(allow_hyphen_values = true, long, value_parser = clap::value_parser!(u32).range(1..))]
    pub renorm_sweeps: Option<u32>,
    /// Renormalise after every K steps (with --renormalize sweeps) [default: 1].
    #[arg(allow_hyphen_values = true, long, value_name = "K",
          value_parser = clap::value_parser!(u64).range(1..))]
    pub renorm_every: Option<u64>,
    /// Derivatives of the renormalisation sweeps (with --renormalize sweeps)
    /// [default: weno5].
    #[arg(long, value_enum)]
    pub renorm_scheme: Option<SchemeArg>,
    /// CFL number in (0, 1] of the renormalisation's pseudo-time step Δτ = C·h/√3 (with
    /// --renormalize sweeps) [default: 0.9].
    #[arg(allow_hyphen_values = true, long, value_name = "C")]
    pub renorm_cfl: Option<f32>,
    /// Spatial scheme of the physical step [default: upwind1 for sphere and morph, weno5
    /// otherwise].
    #[arg(long, value_enum)]
    pub scheme: Option<SchemeArg>,
    /// Time integrator [default: euler for sphere and morph, rk3 otherwise].
    #[arg(long, value_enum)]
    pub integrator: Option<IntegratorArg>,
    /// CFL number in (0, 1] of the physical terms' stability limit [default: 1].
    #[arg(allow_hyphen_values = true, long)]
    pub cfl: Option<f32>,
    /// Keep a record every K steps.
    #[arg(allow_hyphen_values = true, long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..))]
    pub record_every: u64,
    /// Start from a dense float32 .npy field (shape (nz, ny, nx), φ < 0 inside, world
    /// units) instead of the scenario's shape.
    #[arg(long, value_name = "FIELD.npy")]
    pub init: Option<PathBuf>,
    /// Voxel size of the --init field [default: the scenario's].
    #[arg(allow_hyphen_values = true, long, requires = "init")]
    pub voxel_size: Option<f32>,
    /// Reinitialise the band to a signed distance by fast marching (sparse grids).
    #[arg(long, value_enum)]
    pub reinit: Option<ReinitArg>,
    /// Reinitialise after every K steps.
    #[arg(allow_hyphen_values = true, long, value_name = "K", default_value_t = 10, requires = "reinit",
          value_parser = clap::value_parser!(u64).range(1..))]
    pub every: u64,
    /// Write a ray-traced image DIR/render-NNNNNN.png of step 0 and every K-th step (a
    /// fixed camera framing the initial surface with a margin; sparse grids).
    #[arg(allow_hyphen_values = true, long, value_name = "K", value_parser = clap::value_parser!(u64).range(1..))]
    pub render_every: Option<u64>,
    /// Write the zero level set as a binary PLY mesh DIR/mesh-NNNNNN.ply of step 0 and
    /// every K-th step (sparse grids).
    #[arg(allow_hyphen_values = true, long, value_name = "K", value_parser = clap::value_parser!(u64).range(1..))]
    pub mesh_every: Option<u64>,
    /// Output directory (created if needed).
    #[arg(long, value_name = "DIR", default_value = "out")]
    pub out: PathBuf,
    /// Also write the final state as a dense field DIR/final.npy (band box + 4 voxels).
    #[arg(long)]
    pub export_npy: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Under `mpirun` (a build with `--features mpi`): move the cuts between the ranks
    /// when the largest rank holds more than (1 + R) × the smallest rank's tiles.
    #[arg(allow_hyphen_values = true, long, value_name = "R", default_value_t = 0.1)]
    pub rebalance: f64,
    /// Under `mpirun`: never move the cuts.
    #[arg(long, conflicts_with = "rebalance")]
    pub no_rebalance: bool,
}

/// The frames `levelset run` writes while it steps (`--render-every`, `--mesh-every`).
struct Frames {
    dir: PathBuf,
    render_every: Option<u64>,
    mesh_every: Option<u64>,
    /// The camera's frame box, fixed at the first frame.
    frame: Option<sparse_levelset::tools::render::FrameBox>,
    written: usize,
}

impl Frames {
    fn new(a: &RunArgs) -> Result<Frames, String> {
        if (a.render_every.is_some() || a.mesh_every.is_some()) && matches!(a.grid, GridArg::Dense)
        {
            return Err(
                "--render-every and --mesh-every need a sparse grid (--grid tiles or dtgrid)"
                    .into(),
            );
        }
        Ok(Frames {
            dir: a.out.clone(),
            render_every: a.render_every,
            mesh_every: a.mesh_every,
            frame: None,
            written: 0,
        })
    }

    /// Writes the frames due at the simulation's current step.
    fn write(
        &mut self,
        sim: &sparse_levelset::evolve::Simulation,
    ) -> Result<(), sparse_levelset::evolve::EvolveError> {
        use sparse_levelset::evolve::EvolveError;
        use sparse_levelset::io::mesh::{save_mesh, MeshFormat};
        use sparse_levelset::tools::mesh::isosurface;
        use sparse_levelset::tools::render::{render, FrameBox, RenderOptions};
        let step = sim.steps();
        let due = |every: Option<u64>| every.is_some_and(|k| step.is_multiple_of(k));
        let (mesh_due, render_due) = (due(self.mesh_every), due(self.render_every));
        // A collapsed interface has no surface to mesh or show.
        if (!mesh_due && !render_due) || sim.collapsed() {
            return Ok(());
        }
        let output = |e: &dyn std::fmt::Display| EvolveError::Output(format!("step {step}: {e}"));
        if mesh_due {
            let mesh = isosurface(sim, &Default::default()).map_err(|e| output(&e))?;
            let path = self.dir.join(format!("mesh-{step:06}.ply"));
            save_mesh(&path, &mesh, Some(MeshFormat::Ply { ascii: false }))
                .map_err(|e| output(&e))?;
            self.written += 1;
        }
        if render_due {
            if self.frame.is_none() {
                // The initial surface's box with a margin of half its extent on every
                // side: the camera stays put while the interface moves within it.
                let (lo, hi) = sim.band_bounding_box().ok_or_else(|| output(&"empty level set"))?;
                let spec = sim.spec();
                let (l, h) = (spec.world(lo), spec.world(hi));
                let m: [f64; 3] = std::array::from_fn(|i| 0.5 * (h[i] - l[i]));
                self.frame = Some(FrameBox {
                    lo: std::array::from_fn(|i| l[i] - m[i]),
                    hi: std::array::from_fn(|i| h[i] + m[i]),
                });
            }
            let opts = RenderOptions { frame: self.frame, ..RenderOptions::default() };
            let image = render(sim, &opts).map_err(|e| output(&e))?;
            let path = self.dir.join(format!("render-{step:06}.png"));
            image.write_png(&path).map_err(|e| output(&e))?;
            self.written += 1;
        }
        Ok(())
    }
}

pub fn run(a: &RunArgs) -> Result<(), String> {
    let kind = match a.scenario {
        ScenarioArg::Sphere => ScenarioKind::Sphere,
        ScenarioArg::Spiral => ScenarioKind::Spiral,
        ScenarioArg::Enright => ScenarioKind::Enright,
        ScenarioArg::Expand => ScenarioKind::Expand,
        ScenarioArg::Morph => ScenarioKind::Morph,
    };
    let lanes = match a.lanes {
        LanesArg::Scalar => Lanes::Scalar,
        LanesArg::Simd => Lanes::Simd,
    };
    let mut o = ScenarioOptions::new(kind);
    o.size = a.size;
    o.steps = a.steps;
    o.time = a.time;
    o.grid = match a.grid {
        GridArg::Tiles => GridKind::Tiles(lanes),
        GridArg::Dtgrid => GridKind::DtGrid,
        GridArg::Dense => GridKind::Dense,
    };
    o.threads = a.threads.map(|t| t as usize);
    o.radius = a.radius;
    o.epsilon = a.epsilon;
    o.speed = a.speed;
    o.period = a.period;
    o.depth = a.depth;
    o.half_width = a.half_width;
    let scheme = |s: SchemeArg| match s {
        SchemeArg::Upwind1 => SpatialScheme::Upwind1,
        SchemeArg::Weno5 => SpatialScheme::Weno5,
    };
    o.renormalization = renormalization(a, kind, scheme)?;
    o.volume_conserving = Some(a.volume_conserving);
    o.scheme = a.scheme.map(scheme);
    o.integrator = a.integrator.map(|i| match i {
        IntegratorArg::Euler => Integrator::Euler,
        IntegratorArg::Rk3 => Integrator::Rk3,
    });
    o.cfl = a.cfl;
    o.record_every = a.record_every;
    o.voxel_size = a.voxel_size;
    o.reinit = a.reinit.map(|r| sparse_levelset::evolve::Reinit {
        order: match r {
            ReinitArg::Fmm => sparse_levelset::tools::fmm::Order::First,
            ReinitArg::Fmm2 => sparse_levelset::tools::fmm::Order::Second,
        },
        every: a.every,
    });
    o.init = a.init.clone();
    o.rebalance = (!a.no_rebalance).then_some(a.rebalance);
    // Distributed (started by mpirun): every rank runs the same code; rank 0 reports and
    // writes, the others only compute.
    let transport = levelset_cli::ranks::transport()?;
    let lead = transport.as_ref().is_none_or(|t| t.rank() == 0);
    if transport.is_some() && (a.render_every.is_some() || a.mesh_every.is_some() || a.export_npy) {
        return Err("--render-every, --mesh-every and --export-npy need the whole band in one \
                    process: run them without mpirun"
            .into());
    }
    o.transport = transport.clone();
    let mut frames = Frames::new(a)?;
    // Before any work: the output directory, every parameter, the --init field, memory.
    check_output_dir(&a.out)?;
    if a.out.is_dir() {
        check_output(&a.out.join("summary.json"))?;
        if a.export_npy {
            check_output(&a.out.join("final.npy"))?;
        }
    }
    let scenario = Scenario::resolve(o).map_err(|e| e.to_string())?;
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    let bar = progress::bar(
        a.quiet || !lead,
        1000,
        "{spinner} [{elapsed_precise}] {bar:30} {percent}% {msg}",
    );
    bar.set_message(format!("{} on {}", kind.name(), scenario.params.grid));
    let (summary, sim) = scenario
        .run_with(|f| bar.set_position((f * 1000.0) as u64), |sim| frames.write(sim))
        .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    if !lead {
        return Ok(());
    }
    let last = summary.records.last().expect("records");
    if let Some(d) = &summary.distributed {
        let halo: u64 = d.halo.iter().map(|h| h.bytes).sum();
        outln!(
            "{} ranks, tiles per rank {:?}, {} rebalancing move(s), halo {:.1} kB per step \
             over all ranks",
            d.ranks,
            d.tiles_per_rank,
            d.halo.first().map_or(0, |h| h.rebalances),
            halo as f64 / 1e3 / summary.steps_taken.max(1) as f64
        );
    }
    outln!(
        "{}: {} steps to t = {:.6}{} on {} in {:.2} s ({:.1} Mvoxel-updates/s); band voxels {}, \
         volume V/V0 = {:.6}, area {:.6e}, {} bytes; checksum {}",
        kind.name(),
        summary.steps_taken,
        summary.time,
        if summary.collapsed { " (collapsed)" } else { "" },
        summary.params.grid,
        summary.seconds,
        summary.voxel_updates_per_s / 1e6,
        last.band_voxels,
        summary.volume_ratio,
        last.area,
        last.bytes,
        summary.checksum
    );
    if let Some(line) = summary.memory.line() {
        outln!("{line}");
    }
    if let (Some(h), Some(p)) = (summary.volume_ratio_half_period, summary.volume_ratio_period) {
        outln!("enright: V(T/2)/V(0) = {h:.6}, V(T)/V(0) = {p:.6}");
    }
    if frames.written > 0 {
        outln!("wrote {} frame file(s) to {}", frames.written, a.out.display());
    }
    // The summary and the final field appear together or not at all.
    let mut outputs = sparse_levelset::io::fsutil::Outputs::new();
    let summary_path = a.out.join("summary.json");
    let staged = outputs.stage(&summary_path);
    stage_json(&staged, &summary).map_err(|e| outputs.named(e))?;
    let origin = match a.export_npy {
        true => {
            let path = a.out.join("final.npy");
            let staged = outputs.stage(&path);
            Some(export_final(&sim, &staged).map_err(|e| outputs.named(e))?)
        }
        false => None,
    };
    outputs.commit().map_err(|e| format!("{}: {e}", summary_path.display()))?;
    outln!("wrote {}", summary_path.display());
    if let Some(origin) = origin {
        outln!("wrote {} (origin voxel {origin})", a.out.join("final.npy").display());
    }
    Ok(())
}

/// Writes the final band as a dense field with a margin of 4 voxels
/// ([`sparse_levelset::storage::convert::export_npy`]), through a DT-Grid of the band voxels so that
/// every representation writes the same file.
/// The renormalisation the flags ask for (`None`: the scenario's default); a flag of
/// another mode is an error.
fn renormalization(
    a: &RunArgs,
    kind: ScenarioKind,
    scheme: impl Fn(SchemeArg) -> SpatialScheme,
) -> Result<Option<Renormalization>, String> {
    let sweep_flags = a.renorm_sweeps.is_some()
        || a.renorm_every.is_some()
        || a.renorm_scheme.is_some()
        || a.renorm_cfl.is_some();
    if a.rescale.is_some() && a.renormalize != RenormArg::Coupled {
        return Err("--rescale is the weight of the coupled term: use it with --renormalize \
                    coupled"
            .into());
    }
    if sweep_flags && a.renormalize != RenormArg::Sweeps {
        return Err("--renorm-sweeps, --renorm-every, --renorm-scheme and --renorm-cfl set \
                    the sweeps of --renormalize sweeps"
            .into());
    }
    Ok(Some(match a.renormalize {
        RenormArg::Off => Renormalization::Off,
        RenormArg::Coupled => Renormalization::Coupled { weight: a.rescale.unwrap_or(1.0) },
        RenormArg::Sweeps if !sweep_flags => return Ok(None),
        RenormArg::Sweeps => {
            let d = match Defaults::of(kind).renormalization {
                Renormalization::Sweeps(d) => d,
                _ => Sweeps::default(),
            };
            Renormalization::Sweeps(Sweeps {
                every: a.renorm_every.unwrap_or(d.every),
                sweeps: a.renorm_sweeps.unwrap_or(d.sweeps),
                scheme: a.renorm_scheme.map_or(d.scheme, scheme),
                cfl: a.renorm_cfl.unwrap_or(d.cfl),
            })
        }
    }))
}

fn export_final(
    sim: &sparse_levelset::evolve::Simulation,
    path: &std::path::Path,
) -> Result<sparse_levelset::Coord, String> {
    let mut dt = sparse_levelset::storage::dtgrid::DtGrid::new(sim.spec());
    let mut pushed = Ok(());
    sim.for_each_band_voxel(|c, v| {
        if pushed.is_ok() {
            pushed = dt.push(c, v);
        }
    });
    pushed.map_err(|e| e.to_string())?;
    sparse_levelset::storage::convert::export_npy(&dt, path, 4).map_err(|e| match e {
        sparse_levelset::storage::convert::ExportError::Empty => {
            "the final level set has no band voxels: nothing to export".to_string()
        }
        e => format!("{}: {e}", path.display()),
    })
}
