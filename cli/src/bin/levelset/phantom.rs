//! `levelset phantom`: the seeded noisy phantoms of the segmentation tests and benchmark
//! ([`sparse_levelset::segment::phantom`]) as NIfTI files with their truth and seeds.

use clap::{Args, ValueEnum};
use levelset_cli::outln;
use levelset_cli::output::{check_output_dir, write_json};
use sparse_levelset::io::image::{self, LoadedImage};
use sparse_levelset::segment::phantom::{phantom, PhantomKind, BACKGROUND, CONTRAST};
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum KindArg {
    Ball,
    Torus,
    Blobs,
    Anisotropic,
}

#[derive(Args)]
pub struct PhantomArgs {
    /// The shape.
    #[arg(value_enum)]
    pub kind: KindArg,
    /// Voxels along x and y (z too, except for the anisotropic phantom: size/2.5).
    #[arg(long, default_value_t = 128,
          value_parser = clap::value_parser!(u64).range(16..=1024))]
    pub size: u64,
    /// Contrast over the noise's σ.
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    pub snr: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory: NAME.nii.gz, NAME-truth.nii.gz, NAME-seeds.json.
    #[arg(short, long)]
    pub output: PathBuf,
    /// File name stem [default: the kind].
    #[arg(long)]
    pub name: Option<String>,
}

pub fn run(a: &PhantomArgs) -> Result<(), String> {
    check_output_dir(&a.output)?;
    let kind = match a.kind {
        KindArg::Ball => PhantomKind::Ball,
        KindArg::Torus => PhantomKind::Torus,
        KindArg::Blobs => PhantomKind::Blobs,
        KindArg::Anisotropic => PhantomKind::Anisotropic,
    };
    let p = phantom(kind, a.size as usize, a.snr, a.seed).map_err(|e| e.to_string())?;
    std::fs::create_dir_all(&a.output).map_err(|e| format!("{}: {e}", a.output.display()))?;
    let name = a.name.as_deref().unwrap_or(kind.name());
    if name.is_empty() || name.contains(['/', '\\']) {
        return Err(format!("--name {name:?}: a file name stem, without a directory"));
    }
    let like = LoadedImage::from_image(p.image.clone());
    let img = a.output.join(format!("{name}.nii.gz"));
    image::save_f32(&img, &p.image.data, &like).map_err(|e| e.to_string())?;
    let truth = a.output.join(format!("{name}-truth.nii.gz"));
    image::save_mask(&truth, &p.truth, &like).map_err(|e| e.to_string())?;
    outln!("wrote {} and {}", img.display(), truth.display());
    let seeds = serde_json::json!({
        "seeds": p.seeds,
        "lower": BACKGROUND + 0.5 * CONTRAST,
        "upper": BACKGROUND + 3.0 * CONTRAST,
        "dims": p.image.dims,
        "spacing": p.image.spacing,
        "snr": a.snr,
    });
    write_json(&a.output.join(format!("{name}-seeds.json")), &seeds)
}
