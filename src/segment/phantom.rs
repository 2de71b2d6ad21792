//! Seeded noisy phantoms: the synthetic volumes the segmentation is tested and
//! benchmarked on (`levelset phantom` writes them as NIfTI files).
//!
//! A phantom is a piecewise-constant image — background 100, objects 100 + contrast with
//! contrast 100 — plus Gaussian noise of σ = contrast / SNR, its truth mask (a voxel is
//! inside when its centre is inside the analytic shape) and one seed per object, well
//! inside it. The noise comes from SplitMix64 (Steele, Lea & Flood, OOPSLA 2014) through
//! the Box–Muller transform, seeded per z-slice from the phantom's seed: the same seed
//! gives the same bytes forever, on any thread count.

use super::Seed;
use crate::image::{Image, IDENTITY};
use rayon::prelude::*;
use serde::Serialize;

/// Intensity of the background.
pub const BACKGROUND: f32 = 100.0;
/// Intensity step from the background to an object.
pub const CONTRAST: f32 = 100.0;

/// The shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PhantomKind {
    /// A ball of radius 0.3 n at the centre.
    Ball,
    /// A torus (major radius 0.28 n, tube radius 0.1 n) about the z axis.
    Torus,
    /// Five separate balls of radii 0.08 n – 0.16 n, one seed each.
    Blobs,
    /// A ball of radius 0.3 n (world units) on a lattice with 2.5× the spacing along z
    /// (n × n × ⌈n / 2.5⌉ voxels).
    Anisotropic,
}

impl PhantomKind {
    pub const ALL: [PhantomKind; 4] =
        [PhantomKind::Ball, PhantomKind::Torus, PhantomKind::Blobs, PhantomKind::Anisotropic];

    /// `"ball"`, `"torus"`, `"blobs"`, `"anisotropic"`.
    pub fn name(self) -> &'static str {
        match self {
            PhantomKind::Ball => "ball",
            PhantomKind::Torus => "torus",
            PhantomKind::Blobs => "blobs",
            PhantomKind::Anisotropic => "anisotropic",
        }
    }
}

/// A noisy image, its truth and its seeds.
#[derive(Clone, Debug)]
pub struct Phantom {
    pub image: Image,
    /// 1 inside the objects, x fastest.
    pub truth: Vec<u8>,
    /// One per object, in voxel indices.
    pub seeds: Vec<Seed>,
}

/// SplitMix64: one 64-bit state, a fixed sequence.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1).
    fn uniform(&mut self) -> f64 {
        ((self.next() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Standard normal (Box–Muller, one of the pair).
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The phantom `kind` of size `n` (≥ 16) at signal-to-noise ratio `snr` (contrast over
/// the noise's σ; > 0) from `seed`.
pub fn phantom(kind: PhantomKind, n: usize, snr: f64, seed: u64) -> Phantom {
    assert!(n >= 16 && snr > 0.0, "phantom size must be >= 16 and SNR > 0");
    let sz = if kind == PhantomKind::Anisotropic { 2.5 } else { 1.0 };
    let nz = if kind == PhantomKind::Anisotropic { (n as f64 / 2.5).ceil() as usize } else { n };
    let nf = n as f64;
    let centre = [0.5 * nf, 0.5 * nf, 0.5 * nz as f64 * sz];
    // World-unit shapes: (inside test, seeds).
    let blobs: Vec<([f64; 3], f64)> = [
        ([0.25, 0.25, 0.3], 0.14),
        ([0.72, 0.28, 0.3], 0.12),
        ([0.3, 0.72, 0.7], 0.16),
        ([0.72, 0.72, 0.72], 0.1),
        ([0.5, 0.5, 0.52], 0.08),
    ]
    .iter()
    .map(|&(c, r)| (c.map(|v| v * nf), r * nf))
    .collect();
    let (big, tube) = (0.28 * nf, 0.1 * nf);
    let inside = |p: [f64; 3]| -> bool {
        let d = |c: [f64; 3]| {
            ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt()
        };
        match kind {
            PhantomKind::Ball | PhantomKind::Anisotropic => d(centre) < 0.3 * nf,
            PhantomKind::Torus => {
                let q = ((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2)).sqrt() - big;
                (q * q + (p[2] - centre[2]).powi(2)).sqrt() < tube
            }
            PhantomKind::Blobs => blobs.iter().any(|&(c, r)| d(c) < r),
        }
    };
    let seed_radius = 3.0;
    let seeds: Vec<Seed> = match kind {
        PhantomKind::Ball | PhantomKind::Anisotropic => {
            vec![Seed { center: [centre[0], centre[1], centre[2] / sz], radius: seed_radius }]
        }
        PhantomKind::Torus => {
            vec![Seed { center: [centre[0] + big, centre[1], centre[2]], radius: seed_radius }]
        }
        PhantomKind::Blobs => blobs
            .iter()
            .map(|&(c, r)| Seed { center: c, radius: seed_radius.min(0.5 * r) })
            .collect(),
    };
    let slice = n * n;
    let sigma = CONTRAST as f64 / snr;
    let mut data = vec![0f32; slice * nz];
    let mut truth = vec![0u8; slice * nz];
    data.par_chunks_mut(slice).zip(truth.par_chunks_mut(slice)).enumerate().for_each(
        |(z, (d, t))| {
            let mut rng = SplitMix64(seed ^ (z as u64).wrapping_mul(0xd6e8_feb8_6659_fd93));
            for y in 0..n {
                for x in 0..n {
                    let i = x + n * y;
                    t[i] = inside([x as f64, y as f64, z as f64 * sz]) as u8;
                    let clean = BACKGROUND as f64 + CONTRAST as f64 * t[i] as f64;
                    d[i] = (clean + sigma * rng.normal()) as f32;
                }
            }
        },
    );
    let image = Image { dims: [n, n, nz], spacing: [1.0, 1.0, sz], data, to_world: IDENTITY };
    Phantom { image, truth, seeds }
}
