//! Seeded noisy phantoms: test images for segmentation with a known answer.
//!
//! A phantom is a volume of piecewise-constant intensity, [`BACKGROUND`] outside the
//! objects and `BACKGROUND + CONTRAST` inside, plus white Gaussian noise of standard
//! deviation `σ = CONTRAST / snr` ([`noise_sigma`]): **the signal-to-noise ratio is the
//! contrast over the noise σ**. It comes with its truth mask (a voxel is inside when its
//! centre is inside the analytic shape, the same rule that sets its clean intensity, so
//! there is no partial volume) and with one seed per object for the flows to start from.
//!
//! The noise is reproducible forever: it comes from [`SplitMix64`], whose sequence is fixed
//! by this module, one stream per z-slice derived from `(seed, z)`, so a phantom does not
//! depend on the number of threads that made it. Within a slice the voxels, x fastest,
//! take the deviates of [`SplitMix64::normal_pair`] in order (the cosine one, then the
//! sine one).
//!
//! ```
//! use sparse_levelset::segment::phantom::{phantom, PhantomKind, BACKGROUND};
//!
//! let p = phantom(PhantomKind::Ball, 32, 4.0, 7).unwrap();
//! assert_eq!(p.image.dims, [32, 32, 32]);
//! let seed = &p.seeds[0];
//! let [x, y, z] = seed.center.map(|c| c.round() as usize);
//! assert_eq!(p.truth[p.image.index(x, y, z)], 1);
//! assert!(p.image.data[0] > BACKGROUND - 150.0 && p.image.data[0] < BACKGROUND + 150.0);
//! ```

use crate::grid::GridError;
use crate::io::image::{Image, IDENTITY};
use rayon::prelude::*;
use std::fmt;
use std::str::FromStr;

/// Intensity of the background.
pub const BACKGROUND: f32 = 100.0;
/// Intensity of the objects above the background.
pub const CONTRAST: f32 = 100.0;
/// The smallest `n` accepted: below it the thinnest parts (the torus tube, 0.1 n, and the
/// smallest blob, 0.08 n) are under two voxels across.
pub const MIN_SIZE: usize = 16;

/// SplitMix64 (Steele, Lea and Flood, "Fast splittable pseudorandom number generators",
/// OOPSLA 2014; Vigna's reference `splitmix64.c`): a 64-bit state advanced by the golden
/// gamma `0x9E3779B97F4A7C15` and a bijective finaliser.
///
/// **The sequence is fixed forever**: phantoms made with a seed are reproducible across
/// versions, and the module's tests check it against the reference values. (The
/// `f64` deviates of [`SplitMix64::normal_pair`] also go through the platform's `ln`,
/// `sin` and `cos`; these may differ in the last bit between platforms, which is why the
/// guarantee is stated for the integer sequence.)
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

/// The SplitMix64 finaliser (a bijection of `u64`; Stafford's "Mix13" variant).
#[inline]
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl SplitMix64 {
    /// A generator whose state starts at `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix64(self.state)
    }

    /// A uniform deviate in `[0, 1)`: the top 53 bits of [`SplitMix64::next_u64`] times
    /// 2⁻⁵³.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Two independent standard normal deviates by the Box–Muller transform (Box and
    /// Muller 1958): `u₁ ∈ (0, 1]`, `u₂ ∈ [0, 1)`, `ρ = √(−2 ln u₁)`, returning
    /// `(ρ cos 2πu₂, ρ sin 2πu₂)`.
    #[inline]
    pub fn normal_pair(&mut self) -> (f64, f64) {
        let u1 = 1.0 - self.next_f64();
        let u2 = self.next_f64();
        let rho = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        (rho * c, rho * s)
    }
}

/// The generator of z-slice `z` of the phantom of `seed`: state `mix64(seed + mix64(z +
/// 1))`, distinct for every slice, and far apart in the SplitMix64 sequence (a slice
/// draws at most n² numbers out of a period of 2⁶⁴).
fn slice_rng(seed: u64, z: usize) -> SplitMix64 {
    SplitMix64::new(mix64(seed.wrapping_add(mix64(z as u64 + 1))))
}

pub use super::Seed;

/// A phantom: the noisy image, its truth and its seeds.
#[derive(Clone, Debug)]
pub struct Phantom {
    /// The noisy image (placement [`IDENTITY`]).
    pub image: Image,
    /// 1 inside an object, 0 outside, in the layout of the image.
    pub truth: Vec<u8>,
    /// One seed per object, in the order of the objects.
    pub seeds: Vec<Seed>,
}

/// The shapes [`phantom`] makes, sized relative to `n`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PhantomKind {
    /// A centred ball of radius 0.3 n.
    Ball,
    /// A torus about the z axis, major radius 0.28 n and minor (tube) radius 0.1 n, seeded
    /// in its tube.
    Torus,
    /// Five separate balls of radii 0.08 n to 0.17 n, at least 0.1 n apart, one seed
    /// each.
    Blobs,
    /// A ball of radius 0.3 n world units in `n × n × ⌈n / 2.5⌉` voxels of spacing
    /// `(1, 1, 2.5)`: round in world units, flattened in voxels.
    Anisotropic,
}

impl PhantomKind {
    /// Every kind, in declaration order.
    pub const ALL: [PhantomKind; 4] =
        [PhantomKind::Ball, PhantomKind::Torus, PhantomKind::Blobs, PhantomKind::Anisotropic];

    /// The lower-case name, as parsed by [`FromStr`].
    pub fn name(self) -> &'static str {
        match self {
            PhantomKind::Ball => "ball",
            PhantomKind::Torus => "torus",
            PhantomKind::Blobs => "blobs",
            PhantomKind::Anisotropic => "anisotropic",
        }
    }
}

impl fmt::Display for PhantomKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for PhantomKind {
    type Err = GridError;

    fn from_str(s: &str) -> Result<Self, GridError> {
        PhantomKind::ALL.into_iter().find(|k| k.name() == s).ok_or_else(|| {
            let names: Vec<&str> = PhantomKind::ALL.iter().map(|k| k.name()).collect();
            GridError::InvalidParameter(format!(
                "unknown phantom {s:?}; the phantoms are {}",
                names.join(", ")
            ))
        })
    }
}

/// The blobs of [`PhantomKind::Blobs`]: centre and radius as fractions of `n`. The
/// smallest gap between two balls is 0.108 n (the last two), the smallest margin to the
/// volume's faces 0.1 n (checked by a unit test).
const BLOBS: [([f64; 3], f64); 5] = [
    ([0.28, 0.28, 0.30], 0.17),
    ([0.72, 0.28, 0.30], 0.13),
    ([0.28, 0.72, 0.62], 0.12),
    ([0.72, 0.70, 0.66], 0.15),
    ([0.50, 0.50, 0.82], 0.08),
];

/// An analytic solid in world units (lattice position = voxel index × spacing).
#[derive(Clone, Copy, Debug)]
enum Solid {
    Ball {
        center: [f64; 3],
        radius: f64,
    },
    /// About the z axis through `center`.
    Torus {
        center: [f64; 3],
        major: f64,
        minor: f64,
    },
}

impl Solid {
    #[inline]
    fn contains(&self, p: [f64; 3]) -> bool {
        match *self {
            Solid::Ball { center: c, radius } => {
                let d: f64 = (0..3).map(|a| (p[a] - c[a]).powi(2)).sum();
                d < radius * radius
            }
            Solid::Torus { center: c, major, minor } => {
                let rho = (p[0] - c[0]).hypot(p[1] - c[1]);
                (rho - major).powi(2) + (p[2] - c[2]).powi(2) < minor * minor
            }
        }
    }

    /// The volume in world units³.
    fn volume(&self) -> f64 {
        use std::f64::consts::PI;
        match *self {
            Solid::Ball { radius, .. } => 4.0 / 3.0 * PI * radius.powi(3),
            Solid::Torus { major, minor, .. } => 2.0 * PI * PI * major * minor * minor,
        }
    }

    /// The seed: a point well inside and the radius of a ball around it that is inside
    /// (in world units).
    fn seed_world(&self) -> ([f64; 3], f64) {
        match *self {
            Solid::Ball { center, radius } => (center, radius),
            Solid::Torus { center, major, minor } => {
                ([center[0] + major, center[1], center[2]], minor)
            }
        }
    }
}

/// The geometry of a phantom: dimensions, spacing and solids.
fn layout(kind: PhantomKind, n: usize) -> ([usize; 3], [f64; 3], Vec<Solid>) {
    let nf = n as f64;
    let mid = (nf - 1.0) / 2.0;
    match kind {
        PhantomKind::Ball => {
            ([n; 3], [1.0; 3], vec![Solid::Ball { center: [mid; 3], radius: 0.3 * nf }])
        }
        PhantomKind::Torus => (
            [n; 3],
            [1.0; 3],
            vec![Solid::Torus { center: [mid; 3], major: 0.28 * nf, minor: 0.1 * nf }],
        ),
        PhantomKind::Blobs => (
            [n; 3],
            [1.0; 3],
            BLOBS
                .iter()
                .map(|&(c, r)| Solid::Ball { center: c.map(|f| f * nf), radius: r * nf })
                .collect(),
        ),
        PhantomKind::Anisotropic => {
            let nz = (2 * n).div_ceil(5); // ⌈n / 2.5⌉
            let spacing = [1.0, 1.0, 2.5];
            let center = [mid, mid, (nz as f64 - 1.0) / 2.0 * spacing[2]];
            ([n, n, nz], spacing, vec![Solid::Ball { center, radius: 0.3 * nf }])
        }
    }
}

/// The noise standard deviation of a phantom of signal-to-noise ratio `snr`:
/// `CONTRAST / snr` (0 for `snr = ∞`).
pub fn noise_sigma(snr: f64) -> f64 {
    CONTRAST as f64 / snr
}

/// The analytic volume of the objects of a phantom, in world units³ (the truth mask's
/// voxel count times the voxel volume approaches it as `n` grows).
///
/// Fails as [`phantom`] does on `n`.
pub fn analytic_volume(kind: PhantomKind, n: usize) -> Result<f64, GridError> {
    check_size(n)?;
    Ok(layout(kind, n).2.iter().map(Solid::volume).sum())
}

fn check_size(n: usize) -> Result<(), GridError> {
    if n < MIN_SIZE {
        return Err(GridError::InvalidParameter(format!(
            "a phantom needs n >= {MIN_SIZE} voxels per side, got {n}"
        )));
    }
    Ok(())
}

/// A phantom of `kind` in a volume of about `n³` voxels with signal-to-noise ratio `snr`
/// (contrast over noise σ; `f64::INFINITY` gives the clean image) and noise seed `seed`.
///
/// The shapes are centred in voxel index space, sized relative to `n` (see
/// [`PhantomKind`]) and do not depend on `seed`; only the noise does. Each seed is at the
/// centre of its object (on the tube's centre circle for the torus) with a radius of
/// `min(3, r / 2)` voxels, `r` being the object's inscribed radius around that point in
/// voxels along the axis of largest spacing.
///
/// Fails with [`GridError::InvalidParameter`] when `n < MIN_SIZE` or `snr` is not > 0
/// (NaN included), and with [`GridError::OutOfMemory`] when the volume does not fit.
pub fn phantom(kind: PhantomKind, n: usize, snr: f64, seed: u64) -> Result<Phantom, GridError> {
    check_size(n)?;
    if snr.is_nan() || snr <= 0.0 {
        return Err(GridError::InvalidParameter(format!(
            "a phantom's signal-to-noise ratio must be > 0 (infinity for no noise), got {snr}"
        )));
    }
    let (dims, spacing, solids) = layout(kind, n);
    let [nx, ny, nz] = dims;
    let len = (nx as u128) * (ny as u128) * (nz as u128);
    crate::memory::check(
        crate::memory::bytes_of(len, std::mem::size_of::<f32>() + 1),
        &format!("a phantom of {nx}×{ny}×{nz} voxels"),
    )?;
    let len = len as usize; // fits: the check above bounds it by the memory limit
    let sigma = noise_sigma(snr);
    let mut data = vec![0.0f32; len];
    let mut truth = vec![0u8; len];
    let slice = nx * ny;
    data.par_chunks_mut(slice).zip(truth.par_chunks_mut(slice)).enumerate().for_each(
        |(z, (data, truth))| {
            let mut rng = slice_rng(seed, z);
            let mut spare = None;
            for (i, (v, t)) in data.iter_mut().zip(truth.iter_mut()).enumerate() {
                let (x, y) = (i % nx, i / nx);
                let p = [x as f64 * spacing[0], y as f64 * spacing[1], z as f64 * spacing[2]];
                let inside = solids.iter().any(|s| s.contains(p));
                *t = inside as u8;
                let clean = BACKGROUND as f64 + if inside { CONTRAST as f64 } else { 0.0 };
                let noise = if sigma > 0.0 {
                    match spare.take() {
                        Some(b) => b,
                        None => {
                            let (a, b) = rng.normal_pair();
                            spare = Some(b);
                            a
                        }
                    }
                } else {
                    0.0
                };
                *v = (clean + sigma * noise) as f32;
            }
        },
    );
    let max_spacing = spacing.iter().copied().fold(0.0, f64::max);
    let seeds = solids
        .iter()
        .map(|s| {
            let (c, r) = s.seed_world();
            Seed {
                center: std::array::from_fn(|a| c[a] / spacing[a]),
                radius: (0.5 * r / max_spacing).min(3.0),
            }
        })
        .collect();
    Ok(Phantom { image: Image { dims, spacing, data, to_world: IDENTITY }, truth, seeds })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix64_reference_sequence() {
        // Vigna's splitmix64.c from state 1234567.
        let mut g = SplitMix64::new(1234567);
        let want: [u64; 5] = [
            6457827717110365317,
            3203168211198807973,
            9817491932198370423,
            4593380528125082431,
            16408922859458223821,
        ];
        for w in want {
            assert_eq!(g.next_u64(), w);
        }
        assert_eq!(SplitMix64::new(0).next_u64(), 0xE220_A839_7B1D_CDAF);
    }

    #[test]
    fn box_muller_moments() {
        let mut g = SplitMix64::new(42);
        let (mut s1, mut s2, mut s4) = (0.0, 0.0, 0.0);
        let m = 200_000;
        for _ in 0..m / 2 {
            let (a, b) = g.normal_pair();
            for v in [a, b] {
                s1 += v;
                s2 += v * v;
                s4 += v.powi(4);
            }
        }
        let m = m as f64;
        assert!((s1 / m).abs() < 0.01);
        assert!((s2 / m - 1.0).abs() < 0.01);
        assert!((s4 / m - 3.0).abs() < 0.06, "kurtosis {}", s4 / m);
    }

    #[test]
    fn blobs_are_apart_and_inside() {
        for (i, &(c, r)) in BLOBS.iter().enumerate() {
            assert!(r >= 0.08);
            assert!(c.iter().all(|&f| f - r >= 0.1 && f + r <= 0.9), "blob {i}");
            for &(d, s) in &BLOBS[i + 1..] {
                let dist: f64 = (0..3).map(|a| (c[a] - d[a]).powi(2)).sum::<f64>().sqrt();
                assert!(dist - r - s >= 0.1, "blobs {i}: gap {}", dist - r - s);
                assert_ne!(r, s, "radii differ");
            }
        }
    }

    #[test]
    fn names_round_trip() {
        for k in PhantomKind::ALL {
            assert_eq!(k.name().parse::<PhantomKind>().unwrap(), k);
        }
        let e = "sphere".parse::<PhantomKind>().unwrap_err().to_string();
        assert!(e.contains("\"sphere\"") && e.contains("ball, torus, blobs, anisotropic"), "{e}");
    }
}
