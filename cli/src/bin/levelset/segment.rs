//! `levelset segment`: a scan (NIfTI, MetaImage, NRRD, `.npy`, PNG) segmented from seeds or a mask by
//! threshold propagation, geodesic active contours or Chan–Vese
//! ([`sparse_levelset::segment`]); the mask in the input's format, the level set as a
//! float volume, the run's figures as JSON.

use clap::{Args, ValueEnum};
use levelset_cli::output::check_output;
use levelset_cli::{batch, outln, progress};
use sparse_levelset::io::fsutil::Outputs;
use sparse_levelset::io::image::{self, LoadedImage, Output};
use sparse_levelset::segment::{metrics::dice, segment, Init, Method, Params, Seed, Stop};
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
    /// The image: .nii, .nii.gz, .mha, .mhd, .nrrd, .nhdr, .npy (shape (nz, ny, nx) or
    /// (ny, nx)) or .png (grey).
    /// A directory: batch mode, every image in it (see --output); under
    /// `mpirun -n N` (a build with `--features mpi`) the images are spread over the ranks.
    #[arg(value_name = "IMAGE|DIR")]
    pub image: PathBuf,
    /// The method.
    #[arg(long, value_enum)]
    pub method: MethodArg,
    /// Add another method's terms with a weight, `METHOD:W` (threshold, gac, chan-vese;
    /// repeatable): the flow is the weighted sum, --method with weight 1.
    #[arg(long = "add", value_name = "METHOD:W")]
    pub add: Vec<String>,
    /// A seed ball `x,y,z[:r]`: voxel indices along the image's x, y, z axes (fractional
    /// allowed; z may be left out for a 2D image), radius in voxels [default 3];
    /// repeatable. World coordinates and radius with --world.
    #[arg(long = "seed", value_name = "x,y,z[:r]", allow_hyphen_values = true)]
    pub seeds: Vec<String>,
    /// Seeds are in the image's world coordinates (the file's own frame: NIfTI's RAS,
    /// MetaImage's LPS, NRRD's `space`).
    #[arg(long)]
    pub world: bool,
    /// Start from this mask (same size as the image, nonzero inside) instead of seeds.
    #[arg(long, value_name = "MASK")]
    pub init_mask: Option<PathBuf>,
    /// Start from the zero level of this level set (a float volume of the image's size,
    /// φ < 0 inside: .nii(.gz) or .npy) instead of seeds; only the zero level is read (its
    /// signed distance starts the run), so its units and steepness do not matter.
    #[arg(long, value_name = "LEVELSET")]
    pub init_level_set: Option<PathBuf>,
    /// Lower threshold (threshold method); without --upper the window is open above
    /// (everything brighter); `-inf` for an open lower end.
    #[arg(long, allow_hyphen_values = true)]
    pub lower: Option<f32>,
    /// Upper threshold (threshold method); without --lower the window is open below;
    /// `inf` for an open upper end.
    #[arg(long, allow_hyphen_values = true)]
    pub upper: Option<f32>,
    /// A feature image of the image's size (any image format), as ITK's filters take one:
    /// for --method gac the edge potential itself (1 in flat regions, near 0 on edges; no
    /// smoothing, no sigmoid); for threshold and chan-vese the intensities compared in
    /// place of the image (smoothed only with --sigma).
    #[arg(long, value_name = "IMAGE")]
    pub feature: Option<PathBuf>,
    /// Do not stop a run that leaks (one whose region spreads over an image face the seeds
    /// did not touch, or grows past half the image; a start shrinking onto the objects,
    /// past itself): for objects that fill the image.
    #[arg(long)]
    pub no_leak_guard: bool,
    /// ITK's plain GAC balloon (outward wherever the edge potential lets it) and the
    /// textbook Chan–Vese. By default the first edge that rays from the seeds cross shapes
    /// both: GAC's balloon turns inward beyond the intensity midway across it (the report's
    /// `edge_level`), so that a weak stretch of edge does not let the front run on, and
    /// Chan–Vese's outside mean is no farther from the inside's than the intensity beyond
    /// it (the neighbouring tissue, not the whole outside). GAC shrinking a start
    /// (--propagation < 0) likewise turns outward beyond the first edge that rays from the
    /// start's boundary cross inward, so that it does not eat an object the start cuts
    #[arg(long)]
    pub no_first_edge: bool,
    /// Start the level set from the seeds' balls (or the --init-mask). By default it starts
    /// from the part of the image the front from the seeds is sure to cover (a flood fill
    /// through the voxels where the method's speed is clearly outward; the report's
    /// `start_voxels`), or for GAC shrinking an --init-mask (--propagation < 0) without the
    /// part the front from outside is sure to sweep: the same answer in fewer steps
    #[arg(long)]
    pub no_fast_start: bool,
    /// σ of the Gaussian smoothing in world units (0: none) [default: from the image's noise].
    #[arg(long, allow_hyphen_values = true)]
    pub sigma: Option<f64>,
    /// Propagation weight β (ITK's PropagationScaling) [default 1]; negative shrinks a
    /// larger initial region (--init-mask) onto the object (threshold, gac).
    #[arg(long, allow_hyphen_values = true)]
    pub propagation: Option<f32>,
    /// Curvature weight ε (ITK's CurvatureScaling; Chan–Vese's μ) in world units
    /// [default: 1.5 × the smallest spacing for gac, 0.2 × for the others].
    #[arg(long, allow_hyphen_values = true)]
    pub curvature: Option<f32>,
    /// Advection weight α (ITK's AdvectionScaling; GAC) [default 3].
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
    /// Voxel spacing `sx,sy,sz` in world units (for .npy and PNG; replaces a file's).
    #[arg(long, value_name = "sx,sy,sz", allow_hyphen_values = true)]
    pub spacing: Option<String>,
    /// The mask out (0/1), in the input's format family by extension: .nii(.gz), .mha,
    /// .mhd, .nrrd, .nhdr (with the input's geometry), .npy (uint8), .png (2D images).
    /// In batch mode a
    /// directory: NAME-mask.EXT per image NAME.EXT and summary.json. Batch mode takes
    /// every image of DIR except NAME-truth.* (a truth: its Dice is reported); without
    /// --seed, each image's seeds (and thresholds, unless --lower/--upper) come from
    /// NAME-seeds.json ({"seeds": [{"center": [x, y, z], "radius": r}], "lower", "upper"},
    /// as `levelset phantom` writes). Images run in parallel (one thread each) when there
    /// are at least as many as threads, one after another with all threads otherwise; an
    /// image that fails is reported and skipped. Under `mpirun -n N`, rank r takes the
    /// images i (in name order) with i % N = r, each rank with --threads threads, and rank
    /// 0 writes summary.json with every image's record.
    #[arg(short, long, value_name = "MASK|OUTDIR")]
    pub output: PathBuf,
    /// The final level set (φ < 0 inside, world units) as a float32 volume (.nii(.gz) or
    /// .npy), ±γ beyond the band.
    #[arg(long, value_name = "OUT")]
    pub level_set: Option<PathBuf>,
    /// The surface (φ = 0) as a triangle mesh in the image's world coordinates (NIfTI:
    /// scanner millimetres): .ply, .obj or .stl.
    #[arg(long, value_name = "OUT.ply|OUT.obj|OUT.stl")]
    pub mesh: Option<PathBuf>,
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

/// One image's segmentation: its files and inputs, checked before any work.
struct Job {
    name: String,
    loaded: LoadedImage,
    output: PathBuf,
    level_set: Option<PathBuf>,
    mesh: Option<PathBuf>,
    truth: Option<Vec<u8>>,
    init: Init,
    method: Method,
    /// Methods added with their weights.
    terms: Vec<(Method, f32)>,
    /// The user's feature image.
    feature: Option<Arc<sparse_levelset::io::image::Image>>,
}

/// The method from the flags, the thresholds from `window` when the flags give none.
fn method_of(
    a: &SegmentArgs,
    arg: MethodArg,
    window: Option<(f32, f32)>,
) -> Result<Method, String> {
    Ok(match arg {
        MethodArg::Threshold => match open_window(a.lower, a.upper).or(window) {
            Some((lower, upper)) => Method::Threshold { lower, upper },
            None => return Err("the threshold method needs --lower or --upper (or both)".into()),
        },
        MethodArg::Gac => Method::Gac,
        MethodArg::ChanVese => {
            Method::ChanVese { lambda1: a.lambda1, lambda2: a.lambda2, nu: a.nu }
        }
    })
}

/// An image that must have `like`'s size (a mask, a level set, a feature image).
fn load_like(
    path: &Path,
    spacing: Option<[f64; 3]>,
    like: &LoadedImage,
) -> Result<LoadedImage, String> {
    let m = load(path, spacing)?;
    if m.image.dims != like.image.dims {
        return Err(format!(
            "{}: {:?} voxels, the image has {:?}",
            path.display(),
            m.image.dims,
            like.image.dims
        ));
    }
    Ok(m)
}

/// A 0/1 mask of `like`'s size from a file.
fn load_mask(
    path: &Path,
    spacing: Option<[f64; 3]>,
    like: &LoadedImage,
) -> Result<Vec<u8>, String> {
    let m = load_like(path, spacing, like)?;
    Ok(m.image.data.iter().map(|&v| (v != 0.0) as u8).collect())
}

/// A threshold window from its two ends, either left open (None: ∓∞); None when both are.
fn open_window(lower: Option<f32>, upper: Option<f32>) -> Option<(f32, f32)> {
    match (lower, upper) {
        (None, None) => None,
        (l, u) => Some((l.unwrap_or(f32::NEG_INFINITY), u.unwrap_or(f32::INFINITY))),
    }
}

/// Seeds and the (lower, upper) thresholds if given.
type SeedsFile = (Vec<Seed>, Option<(f32, f32)>);

/// Seeds and thresholds of a `NAME-seeds.json` file.
fn seeds_file(path: &Path) -> Result<SeedsFile, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let list = v.get("seeds").unwrap_or(&v);
    let bad = || {
        format!(
            "{}: expected {{\"seeds\": [{{\"center\": [x, y, z], \"radius\": r}}]}}",
            path.display()
        )
    };
    let seeds = list
        .as_array()
        .ok_or_else(bad)?
        .iter()
        .map(|s| {
            let c = s.get("center").and_then(|c| c.as_array()).ok_or_else(bad)?;
            let c: Vec<f64> =
                c.iter().map(|x| x.as_f64().ok_or_else(bad)).collect::<Result<_, _>>()?;
            let radius = s.get("radius").and_then(|r| r.as_f64()).unwrap_or(3.0);
            match c[..] {
                [x, y, z] => Ok(Seed { center: [x, y, z], radius }),
                _ => Err(bad()),
            }
        })
        .collect::<Result<Vec<_>, String>>()?;
    // A window open at one end: that end null or left out.
    let f = |k: &str| v.get(k).and_then(|x| x.as_f64()).map(|x| x as f32);
    Ok((seeds, open_window(f("lower"), f("upper"))))
}

/// Loads and checks one image's inputs and outputs.
fn job(
    a: &SegmentArgs,
    image_path: &Path,
    output: PathBuf,
    level_set: Option<PathBuf>,
    truth: Option<&Path>,
    seeds_json: Option<&Path>,
) -> Result<Job, String> {
    let spacing = a.spacing.as_deref().map(parse_spacing).transpose()?;
    let loaded = load(image_path, spacing)?;
    let planar = loaded.image.is_2d();
    let starts =
        a.init_mask.is_some() as u8 + a.init_level_set.is_some() as u8 + !a.seeds.is_empty() as u8;
    if starts > 1 {
        return Err("give one of --seed, --init-mask and --init-level-set".into());
    }
    let (init, window) = if let Some(m) = &a.init_mask {
        (Init::Mask(load_mask(m, spacing, &loaded)?), None)
    } else if let Some(l) = &a.init_level_set {
        (Init::LevelSet(load_like(l, spacing, &loaded)?.image.data), None)
    } else if !a.seeds.is_empty() {
        let seeds = a.seeds.iter().map(|s| parse_seed(s, planar)).collect::<Result<_, _>>()?;
        (Init::Seeds { seeds, world: a.world }, None)
    } else if let Some(file) = seeds_json {
        let (seeds, window) = seeds_file(file)?;
        (Init::Seeds { seeds, world: a.world }, window)
    } else {
        return Err("give at least one --seed x,y,z[:r], --init-mask or --init-level-set".into());
    };
    let method = method_of(a, a.method, window)?;
    let terms = added(a, window)?;
    let feature = match &a.feature {
        Some(f) => Some(Arc::new(load_like(f, spacing, &loaded)?.image)),
        None => None,
    };
    let truth = truth.map(|t| load_mask(t, spacing, &loaded)).transpose()?;
    image::check_output(&output, &loaded, Output::Mask).map_err(|e| e.to_string())?;
    check_output(&output)?;
    if let Some(ls) = &level_set {
        image::check_output(ls, &loaded, Output::Float).map_err(|e| e.to_string())?;
        check_output(ls)?;
    }
    let mesh = a.mesh.clone();
    if let Some(m) = &mesh {
        if loaded.image.is_2d() {
            return Err("--mesh: a 2D image's segmentation has no surface".into());
        }
        if sparse_levelset::io::mesh::MeshFormat::from_path(m).is_none() {
            return Err(format!(
                "{}: unknown mesh format (use {})",
                m.display(),
                sparse_levelset::io::mesh::MeshFormat::EXTENSIONS
            ));
        }
        check_output(m)?;
    }
    let name = image_path.display().to_string();
    Ok(Job { name, loaded, output, level_set, mesh, truth, init, method, terms, feature })
}

/// The methods added with `--add METHOD:W`.
fn added(a: &SegmentArgs, window: Option<(f32, f32)>) -> Result<Vec<(Method, f32)>, String> {
    a.add
        .iter()
        .map(|t| {
            let bad = || format!("--add {t:?}: expected METHOD:W with METHOD threshold, gac or chan-vese and W >= 0");
            let (m, w) = t.split_once(':').ok_or_else(bad)?;
            let w: f32 = w.trim().parse().map_err(|_| bad())?;
            let arg = match m.trim() {
                "threshold" => MethodArg::Threshold,
                "gac" => MethodArg::Gac,
                "chan-vese" => MethodArg::ChanVese,
                _ => return Err(bad()),
            };
            Ok((method_of(a, arg, window)?, w))
        })
        .collect()
}

/// The parameters from the flags.
fn params_of(a: &SegmentArgs, method: Method, threads: usize) -> Result<Params, String> {
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
    params.leak_guard = !a.no_leak_guard;
    params.first_edge = !a.no_first_edge;
    params.fast_start = !a.no_fast_start;
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
    Ok(params)
}

/// Runs a job on `threads` threads, writes its outputs, returns its figures.
fn execute(
    a: &SegmentArgs,
    j: &Job,
    threads: usize,
    bar: &indicatif::ProgressBar,
) -> Result<serde_json::Value, String> {
    let params = Params {
        terms: j.terms.clone(),
        feature: j.feature.clone(),
        ..params_of(a, j.method, threads)?
    };
    bar.set_length(params.max_iterations);
    let mut monitor = |s: &sparse_levelset::segment::StepInfo| {
        bar.set_position(s.iteration);
        bar.set_message(format!("RMS {:.4}  band {}  inside {}", s.rms, s.band_voxels, s.voxels));
        true
    };
    let img = &j.loaded.image;
    let result =
        segment(img, &j.init, &params, &mut monitor).map_err(|e| format!("{}: {e}", j.name))?;
    // The mask, the level set and the mesh appear together or not at all.
    let mut outputs = Outputs::new();
    let staged = outputs.stage(&j.output);
    image::save_mask(&staged, &result.mask, &j.loaded).map_err(|e| outputs.named(e))?;
    if let Some(ls) = &j.level_set {
        let phi = result
            .simulation
            .to_dense(sparse_levelset::Coord::new(0, 0, 0), img.dims)
            .map_err(|e| e.to_string())?;
        let staged = outputs.stage(ls);
        image::save_f32(&staged, phi.data(), &j.loaded).map_err(|e| outputs.named(e))?;
    }
    if let Some(path) = &j.mesh {
        let mesh = result.mesh(img).map_err(|e| e.to_string())?;
        let staged = outputs.stage(path);
        sparse_levelset::io::mesh::save_mesh(&staged, &mesh, None).map_err(|e| outputs.named(e))?;
    }
    outputs.commit().map_err(|e| format!("{}: {e}", j.output.display()))?;
    let r = &result.report;
    let mut v = serde_json::to_value(r).map_err(|e| e.to_string())?;
    v["image"] = serde_json::json!(j.name);
    v["output"] = serde_json::json!(j.output.display().to_string());
    v["dims"] = serde_json::json!(img.dims);
    v["threads"] = serde_json::json!(threads);
    v["dice"] = serde_json::json!(j.truth.as_ref().and_then(|t| dice(&result.mask, t).ok()));
    v["voxel_updates_per_s"] = serde_json::json!(r.voxel_updates / r.seconds_evolution.max(1e-12));
    v["leaked"] = serde_json::json!(r.stop == Stop::Leaked);
    v["vanished"] = serde_json::json!(r.stop == Stop::Vanished);
    Ok(v)
}

/// One summary line of a finished image.
fn summary_line(v: &serde_json::Value) -> String {
    let dice = v["dice"].as_f64().map_or(String::new(), |d| format!(", Dice {d:.4}"));
    format!(
        "{}: {} voxels after {} steps ({}), {:.2} s{dice}; wrote {}",
        v["image"].as_str().unwrap_or("?"),
        v["voxels"],
        v["iterations"],
        v["stop"].as_str().unwrap_or("?"),
        v["seconds"].as_f64().unwrap_or(0.0),
        v["output"].as_str().unwrap_or("?"),
    )
}

/// The exit code of a run (or batch) whose mask is not a segmentation of the seeded
/// object: it leaked ([`Stop::Leaked`]), it vanished (nothing is left inside:
/// [`Stop::Vanished`]), or Chan–Vese's region was not told apart from its surroundings
/// (`weak_contrast`). Its outputs are written, and a warning says why.
pub const EXIT_LEAKED: u8 = 3;

/// The warning for a record whose mask is not the seeded object, if it is not.
fn warning_of(v: &serde_json::Value) -> Option<String> {
    let image = v["image"].as_str().unwrap_or("?");
    if v["leaked"].as_bool() == Some(true) {
        return Some(format!(
            "warning: {image}: the segmentation leaked and was stopped: {} (the mask is not the \
             seeded object; check the seeds and window, or give --no-leak-guard if the object \
             does fill the image)",
            v["leak"].as_str().unwrap_or("?")
        ));
    }
    if v["vanished"].as_bool() == Some(true) {
        return Some(format!(
            "warning: {image}: the segmentation vanished: nothing is left inside and the mask is \
             empty (the method found no object where the front started; check the seeds or the \
             initial mask, the window, and the sign of --propagation)"
        ));
    }
    v["weak_contrast"].as_str().map(|why| format!("warning: {image}: {why}"))
}

/// Runs `levelset segment`; `Ok(true)` when a mask is not the seeded object (a leak, an
/// empty mask or weak contrast: [`EXIT_LEAKED`]).
pub fn run(a: &SegmentArgs) -> Result<bool, String> {
    let threads = a.threads.map_or_else(rayon::current_num_threads, |t| t as usize);
    if a.image.is_dir() {
        return batch(a, threads);
    }
    levelset_cli::batch::refuse_one_input_on_ranks(&a.image, "image")?;
    // Everything is checked before the work starts.
    let j = job(a, &a.image, a.output.clone(), a.level_set.clone(), a.truth.as_deref(), None)?;
    let bar =
        progress::bar(a.quiet || a.json, 1, "{spinner} [{elapsed_precise}] {pos} steps  {msg}");
    let v = execute(a, &j, threads, &bar)?;
    bar.finish_and_clear();
    if a.json {
        outln!("{}", serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?);
    } else {
        outln!("{}", summary_line(&v));
    }
    let warning = warning_of(&v);
    if let Some(w) = &warning {
        eprintln!("{w}");
    }
    Ok(warning.is_some())
}

/// The images of a batch directory: supported extensions, not `*-truth.*`, by name.
fn batch_images(dir: &Path) -> Result<Vec<PathBuf>, String> {
    batch::list_files(dir, |p| {
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("").to_ascii_lowercase();
        image::split_file_name(&name).is_some_and(|(stem, _)| !stem.ends_with("-truth"))
    })
}

/// Batch mode: every image of `a.image` into the directory `a.output`, spread over the
/// MPI ranks when `mpirun` started the process (rank 0 writes the summary).
fn batch(a: &SegmentArgs, threads: usize) -> Result<bool, String> {
    // Dropped last: MPI is finalised when the last clone goes.
    let transport = levelset_cli::ranks::transport()?;
    let t = transport.as_deref();
    // Every rank checks the same things before any work and fails together.
    let checked = (|| {
        if a.level_set.is_some() || a.truth.is_some() {
            return Err("batch mode takes no --level-set or --truth (truths are found as \
                        NAME-truth.*)"
                .to_string());
        }
        levelset_cli::output::check_output_dir(&a.output)?;
        let images = batch_images(&a.image)?;
        if images.is_empty() {
            return Err(format!(
                "{}: no image ({}) in it",
                a.image.display(),
                image::SUPPORTED_EXTENSIONS
            ));
        }
        std::fs::create_dir_all(&a.output).map_err(|e| format!("{}: {e}", a.output.display()))?;
        Ok(images)
    })();
    let images = batch::agree(t, checked)?;
    let start = std::time::Instant::now();
    let prefix = batch::line_prefix(t);
    let one = |p: &PathBuf, threads: usize| -> Result<serde_json::Value, String> {
        let file = p.file_name().and_then(|n| n.to_str()).unwrap_or("image").to_string();
        let (stem, ext) = image::split_file_name(&file).unwrap_or((&file, ""));
        let sibling = |suffix: &str| a.image.join(format!("{stem}{suffix}"));
        let truth = Some(sibling(&format!("-truth{ext}"))).filter(|t| t.is_file());
        let seeds = Some(sibling("-seeds.json")).filter(|s| s.is_file());
        let out = a.output.join(format!("{stem}-mask{ext}"));
        let j = job(a, p, out, None, truth.as_deref(), seeds.as_deref())?;
        execute(a, &j, threads, &indicatif::ProgressBar::hidden())
    };
    // Each rank reports its images as they finish, so a long batch shows its progress.
    let results = batch::spread(t, &images, threads, |p, threads| {
        let r = one(p, threads);
        match &r {
            Ok(v) => {
                outln!("{prefix}{}", summary_line(v));
                if let Some(w) = warning_of(v) {
                    eprintln!("{prefix}{w}");
                }
            }
            Err(e) => outln!("{prefix}{}: FAILED, skipped: {e}", p.display()),
        }
        r
    })?;
    let Some(results) = results else { return Ok(false) };
    let failed = results.iter().filter(|r| r.is_err()).count();
    let count = |flagged: fn(&serde_json::Value) -> bool| {
        results.iter().filter(|r| r.as_ref().is_ok_and(flagged)).count()
    };
    let leaked = count(|v| v["leaked"].as_bool() == Some(true));
    let weak = count(|v| v["weak_contrast"].is_string());
    let vanished = count(|v| v["vanished"].as_bool() == Some(true));
    let records: Vec<serde_json::Value> = images
        .iter()
        .zip(results)
        .map(|(p, r)| match r {
            Ok(v) => v,
            Err(e) => serde_json::json!({"image": p.display().to_string(), "error": e}),
        })
        .collect();
    let fields = vec![
        ("images", images.len().into()),
        ("failed", failed.into()),
        ("leaked", leaked.into()),
        ("weak_contrast", weak.into()),
        ("vanished", vanished.into()),
    ];
    let (summary, how) = batch::write_summary(&a.output, fields, records, t, threads, start)?;
    let note = |n: usize, what: &str| if n > 0 { format!(", {n} {what}") } else { String::new() };
    let (weak_note, vanished_note) = (note(weak, "with weak contrast"), note(vanished, "vanished"));
    outln!(
        "{} images, {failed} failed, {leaked} leaked{weak_note}{vanished_note}, {how}",
        images.len()
    );
    if a.json {
        outln!("{}", serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?);
    }
    if failed > 0 {
        return Err(format!("{failed} of {} images failed (see above)", images.len()));
    }
    Ok(leaked + weak + vanished > 0)
}
