//! `levelset segment`: a scan (NIfTI, `.npy`, PNG) segmented from seeds or a mask by
//! threshold propagation, geodesic active contours or Chan–Vese
//! ([`sparse_levelset::segment`]); the mask in the input's format, the level set as a
//! float volume, the run's figures as JSON.

use clap::{Args, ValueEnum};
use levelset_cli::output::check_output;
use levelset_cli::{outln, progress};
use sparse_levelset::image::{self, LoadedImage, Output};
use sparse_levelset::segment::{metrics::dice, segment, Init, Method, Params, Seed};
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum MethodArg {
    /// Propagation where the smoothed intensity lies in [--lower, --upper] (ITK's
    /// ThresholdSegmentationLevelSet).
    Threshold,
    /// Geodesic active contours (ITK's GeodesicActiveContourLevelSet).
    Gac,
    /// Chan–Vese region competition, grown from the seeds.
    ChanVese,
}

#[derive(Args)]
pub struct SegmentArgs {
    /// The image: .nii, .nii.gz, .npy (shape (nz, ny, nx) or (ny, nx)) or .png (grey).
    #[arg(value_name = "IMAGE")]
    pub image: PathBuf,
    /// The method.
    #[arg(long, value_enum)]
    pub method: MethodArg,
    /// A seed ball `x,y,z[:r]`: voxel indices along the image's x, y, z axes (fractional
    /// allowed; z may be left out for a 2D image), radius in voxels [default 3];
    /// repeatable. World coordinates and radius with --world.
    #[arg(long = "seed", value_name = "x,y,z[:r]", allow_hyphen_values = true)]
    pub seeds: Vec<String>,
    /// Seeds are in the image's world coordinates (NIfTI: scanner millimetres).
    #[arg(long)]
    pub world: bool,
    /// Start from this mask (same size and format family as the image) instead of seeds.
    #[arg(long, value_name = "MASK")]
    pub init_mask: Option<PathBuf>,
    /// Lower threshold (threshold method).
    #[arg(long, allow_hyphen_values = true)]
    pub lower: Option<f32>,
    /// Upper threshold (threshold method).
    #[arg(long, allow_hyphen_values = true)]
    pub upper: Option<f32>,
    /// σ of the Gaussian smoothing in world units (0: none) [default: one voxel per axis].
    #[arg(long, allow_hyphen_values = true)]
    pub sigma: Option<f64>,
    /// Propagation weight β (ITK's PropagationScaling) [default 1].
    #[arg(long, allow_hyphen_values = true)]
    pub propagation: Option<f32>,
    /// Curvature weight ε (ITK's CurvatureScaling; Chan–Vese's μ) in world units.
    #[arg(long, allow_hyphen_values = true)]
    pub curvature: Option<f32>,
    /// Advection weight α (ITK's AdvectionScaling; GAC) [default 1].
    #[arg(long, allow_hyphen_values = true)]
    pub advection: Option<f32>,
    /// K of the rational edge potential 1/(1 + |∇Ĩ|/K) (GAC) [default: the sigmoid edge
    /// potential with α, β from the gradient statistics].
    #[arg(long, allow_hyphen_values = true)]
    pub edge_scale: Option<f64>,
    /// Chan–Vese λ₁ (inside data weight).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub lambda1: f32,
    /// Chan–Vese λ₂ (outside data weight).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub lambda2: f32,
    /// Chan–Vese ν (area term).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub nu: f32,
    /// Stop when the RMS change of φ per unit time near the interface is below this.
    #[arg(long, allow_hyphen_values = true)]
    pub rms: Option<f64>,
    /// Stop when the volume changed by less than this fraction over 10 steps.
    #[arg(long, allow_hyphen_values = true)]
    pub volume_change: Option<f64>,
    /// At most this many steps.
    #[arg(long, allow_hyphen_values = true)]
    pub max_iterations: Option<u64>,
    /// Voxel spacing `sx,sy,sz` in world units (for .npy and PNG; replaces a NIfTI's).
    #[arg(long, value_name = "sx,sy,sz", allow_hyphen_values = true)]
    pub spacing: Option<String>,
    /// The mask out (0/1), in the input's format family by extension: .nii(.gz) (with the
    /// input's header when it is NIfTI), .npy (uint8), .png (2D images).
    #[arg(short, long, value_name = "MASK")]
    pub output: PathBuf,
    /// The final level set (φ < 0 inside, world units) as a float32 volume (.nii(.gz) or
    /// .npy), ±γ beyond the band.
    #[arg(long, value_name = "OUT")]
    pub level_set: Option<PathBuf>,
    /// A truth mask: its Dice coefficient goes into the figures.
    #[arg(long, value_name = "MASK")]
    pub truth: Option<PathBuf>,
    /// Print the run's figures as JSON on standard output.
    #[arg(long)]
    pub json: bool,
    /// Worker threads [default: all cores].
    #[arg(long, allow_hyphen_values = true,
          value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// `x,y,z[:r]` (or `x,y[:r]` for a 2D image).
fn parse_seed(s: &str, planar: bool) -> Result<Seed, String> {
    let bad = || format!("--seed {s:?}: expected x,y,z[:r] with finite numbers (r > 0)");
    let (c, r) = match s.split_once(':') {
        Some((c, r)) => (c, r.trim().parse::<f64>().map_err(|_| bad())?),
        None => (s, 3.0),
    };
    let v: Vec<f64> = c
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    let center = match (v.len(), planar) {
        (3, _) => [v[0], v[1], v[2]],
        (2, true) => [v[0], v[1], 0.0],
        _ => return Err(bad()),
    };
    if !(center.iter().all(|x| x.is_finite()) && r.is_finite() && r > 0.0) {
        return Err(bad());
    }
    Ok(Seed { center, radius: r })
}

fn parse_spacing(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("--spacing {s:?}: expected sx,sy,sz"))?;
    match v[..] {
        [x, y, z] => Ok([x, y, z]),
        _ => Err(format!("--spacing {s:?}: expected three numbers sx,sy,sz")),
    }
}

fn load(path: &Path, spacing: Option<[f64; 3]>) -> Result<LoadedImage, String> {
    image::load(path, spacing).map_err(|e| e.to_string())
}

pub fn run(a: &SegmentArgs) -> Result<(), String> {
    // Everything is checked before the work starts.
    let spacing = a.spacing.as_deref().map(parse_spacing).transpose()?;
    let loaded = load(&a.image, spacing)?;
    let img = &loaded.image;
    let method = match a.method {
        MethodArg::Threshold => match (a.lower, a.upper) {
            (Some(lower), Some(upper)) => Method::Threshold { lower, upper },
            _ => return Err("the threshold method needs --lower and --upper".into()),
        },
        MethodArg::Gac => Method::Gac,
        MethodArg::ChanVese => {
            Method::ChanVese { lambda1: a.lambda1, lambda2: a.lambda2, nu: a.nu }
        }
    };
    let init = match (&a.init_mask, a.seeds.is_empty()) {
        (Some(_), false) => return Err("give seeds or --init-mask, not both".into()),
        (None, true) => return Err("give at least one --seed x,y,z[:r] or --init-mask".into()),
        (Some(m), true) => {
            let mask = load(m, spacing)?;
            if mask.image.dims != img.dims {
                return Err(format!(
                    "{}: {:?} voxels, the image has {:?}",
                    m.display(),
                    mask.image.dims,
                    img.dims
                ));
            }
            Init::Mask(mask.image.data.iter().map(|&v| (v != 0.0) as u8).collect())
        }
        (None, false) => Init::Seeds {
            seeds: a.seeds.iter().map(|s| parse_seed(s, img.is_2d())).collect::<Result<_, _>>()?,
            world: a.world,
        },
    };
    let truth = match &a.truth {
        Some(t) => {
            let t = load(t, spacing)?;
            if t.image.dims != img.dims {
                return Err(format!(
                    "the truth mask has {:?} voxels, the image {:?}",
                    t.image.dims, img.dims
                ));
            }
            Some(t.image.data.iter().map(|&v| (v != 0.0) as u8).collect::<Vec<u8>>())
        }
        None => None,
    };
    image::check_output(&a.output, &loaded, Output::Mask).map_err(|e| e.to_string())?;
    check_output(&a.output)?;
    if let Some(ls) = &a.level_set {
        image::check_output(ls, &loaded, Output::Float).map_err(|e| e.to_string())?;
        check_output(ls)?;
    }
    let threads = a.threads.map_or_else(rayon::current_num_threads, |t| t as usize);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    let mut params = Params::new(method);
    params.sigma = a.sigma;
    params.propagation = a.propagation;
    params.curvature = a.curvature;
    params.advection = a.advection;
    params.edge_scale = a.edge_scale;
    if let Some(v) = a.rms {
        params.rms = v;
    }
    if let Some(v) = a.volume_change {
        params.volume_change = v;
    }
    if let Some(v) = a.max_iterations {
        params.max_iterations = v;
    }
    params.pool = Some(Arc::new(pool));
    let bar = progress::bar(
        a.quiet || a.json,
        params.max_iterations,
        "{spinner} [{elapsed_precise}] {pos} steps  {msg}",
    );
    let mut monitor = |s: &sparse_levelset::segment::StepInfo| {
        bar.set_position(s.iteration);
        bar.set_message(format!("RMS {:.4}  band {}  inside {}", s.rms, s.band_voxels, s.voxels));
        true
    };
    let name = a.image.display().to_string();
    let result = segment(img, &init, &params, &mut monitor).map_err(|e| format!("{name}: {e}"))?;
    bar.finish_and_clear();
    image::save_mask(&a.output, &result.mask, &loaded).map_err(|e| e.to_string())?;
    if let Some(ls) = &a.level_set {
        let [nx, ny, nz] = img.dims;
        let phi = result
            .simulation
            .to_dense(sparse_levelset::Coord::new(0, 0, 0), [nx, ny, nz])
            .map_err(|e| e.to_string())?;
        image::save_f32(ls, phi.data(), &loaded).map_err(|e| e.to_string())?;
    }
    let r = &result.report;
    let dice = truth.as_ref().and_then(|t| dice(&result.mask, t).ok());
    if a.json {
        let mut v = serde_json::to_value(r).map_err(|e| e.to_string())?;
        v["image"] = serde_json::json!(name);
        v["dims"] = serde_json::json!(img.dims);
        v["threads"] = serde_json::json!(threads);
        v["dice"] = serde_json::json!(dice);
        v["voxel_updates_per_s"] =
            serde_json::json!(r.voxel_updates / r.seconds_evolution.max(1e-12));
        outln!("{}", serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?);
    } else {
        outln!(
            "{name}: {} voxels ({:.6} world units³) after {} steps ({:?}), {:.2} s{}; wrote {}",
            r.voxels,
            r.volume,
            r.iterations,
            r.stop,
            r.seconds,
            dice.map_or(String::new(), |d| format!(", Dice {d:.4}")),
            a.output.display()
        );
    }
    Ok(())
}
