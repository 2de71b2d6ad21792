//! Feature images, phantoms and overlap metrics of the segmentation module (issue 14).
//!
//! Tolerances are stated as absolute + relative where the result is rounded from `f64`.

use sparse_levelset::io::image::{Image, IDENTITY};
use sparse_levelset::segment::features::{
    edge_potential, edge_scale, gaussian, gaussian_kernel, gradient_magnitude, mean_std,
    percentile, sigmoid,
};
use sparse_levelset::segment::metrics::{dice, jaccard, overlap, volume_difference};
use sparse_levelset::segment::phantom::{
    analytic_volume, noise_sigma, phantom, Phantom, PhantomKind, SplitMix64, BACKGROUND, CONTRAST,
};

fn image(
    dims: [usize; 3],
    spacing: [f64; 3],
    mut f: impl FnMut(usize, usize, usize) -> f32,
) -> Image {
    let [nx, ny, nz] = dims;
    let mut data = Vec::with_capacity(nx * ny * nz);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                data.push(f(x, y, z));
            }
        }
    }
    Image { dims, spacing, data, to_world: IDENTITY }
}

/// Uniform noise in [0, 100).
fn noise_image(dims: [usize; 3], spacing: [f64; 3], seed: u64) -> Image {
    let mut rng = SplitMix64::new(seed);
    image(dims, spacing, |_, _, _| (100.0 * rng.next_f64()) as f32)
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

fn bits(data: &[f32]) -> Vec<u32> {
    data.iter().map(|v| v.to_bits()).collect()
}

/// The definition, tap by tap: each axis in turn, every tap reading the clamped voxel,
/// summed in f64 and rounded to f32 after each pass.
fn reference_gaussian(img: &Image, sigma: [f64; 3]) -> Vec<f32> {
    let [nx, ny, nz] = img.dims;
    let mut cur = img.data.clone();
    for axis in 0..3 {
        let w = gaussian_kernel(sigma[axis] / img.spacing[axis]).unwrap();
        let r = w.len() as i64 / 2;
        let n = img.dims[axis] as i64;
        let mut next = cur.clone();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let mut p = [x as i64, y as i64, z as i64];
                    let i = p[axis];
                    let mut a = 0.0f64;
                    for (t, &wt) in w.iter().enumerate() {
                        p[axis] = (i + t as i64 - r).clamp(0, n - 1);
                        a +=
                            wt * cur[img.index(p[0] as usize, p[1] as usize, p[2] as usize)] as f64;
                    }
                    next[img.index(x, y, z)] = a as f32;
                }
            }
        }
        cur = next;
    }
    cur
}

#[test]
fn gaussian_kernel_sums_to_one() {
    for sigma in [0.2, 0.5, 1.0, 1.7, 3.3, 12.0] {
        let w = gaussian_kernel(sigma).unwrap();
        let sum: f64 = w.iter().sum();
        assert!((sum - 1.0).abs() <= 1e-14, "σ {sigma}: {sum}");
        assert_eq!(w.len(), 2 * (4.0 * sigma + 0.5).floor() as usize + 1, "σ {sigma}");
    }
}

#[test]
fn gaussian_keeps_a_constant_image_exactly() {
    let spacing = [0.7, 1.3, 2.1];
    let img = image([13, 7, 5], spacing, |_, _, _| 123.456);
    // Ordinary kernels, then kernels far wider than the image (every tap folded).
    for sigma in [[1.5, 2.0, 3.0], [40.0, 40.0, 40.0], [0.0, 0.5, 0.0]] {
        let out = gaussian(&img, sigma).unwrap();
        assert_eq!(out.dims, img.dims);
        assert_eq!(out.spacing, img.spacing);
        assert!(out.data.iter().all(|&v| v == 123.456f32), "σ {sigma:?}");
    }
}

#[test]
fn gaussian_matches_the_tap_by_tap_definition() {
    // Sizes that are not multiples of a vector width; one axis shorter than the kernel.
    let img = noise_image([37, 19, 6], [0.8, 1.0, 0.5], 5);
    for sigma in [[1.3, 2.2, 4.0], [0.9, 0.0, 0.3], [30.0, 1.0, 0.0]] {
        let got = gaussian(&img, sigma).unwrap();
        let want = reference_gaussian(&img, sigma);
        for (i, (&g, &w)) in got.data.iter().zip(&want).enumerate() {
            // Summation order differs (mirrored taps paired, folded boundaries): a few ulp.
            assert!((g - w).abs() <= 1e-5 + 1e-6 * w.abs(), "σ {sigma:?} voxel {i}: {g} vs {w}");
        }
    }
}

#[test]
fn gaussian_delta_has_variance_sigma_squared_in_world_units() {
    let dims = [41, 45, 29];
    let spacing = [1.0, 0.8, 1.5];
    let c = [20usize, 22, 14];
    let img = image(dims, spacing, |x, y, z| if [x, y, z] == c { 1000.0 } else { 0.0 });
    let sigma = [2.0, 2.5, 3.0]; // world units: 2, 3.125 and 2 voxels
    let out = gaussian(&img, sigma).unwrap();
    let mass: f64 = out.data.iter().map(|&v| v as f64).sum();
    assert!((mass - 1000.0).abs() < 1e-3, "mass {mass}");
    for axis in 0..3 {
        let (mut m1, mut m2) = (0.0, 0.0);
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let d = ([x, y, z][axis] as f64 - c[axis] as f64) * spacing[axis];
                    let v = out.data[out.index(x, y, z)] as f64 / mass;
                    m1 += d * v;
                    m2 += d * d * v;
                }
            }
        }
        let s2 = sigma[axis] * sigma[axis];
        assert!(m1.abs() < 1e-6, "axis {axis}: mean {m1}");
        // Truncation at 4σ lowers the variance by 0.1 %; sampling adds < 10⁻⁶ at σ ≥ 2 voxels.
        assert!((m2 - s2).abs() <= 0.005 * s2, "axis {axis}: variance {m2}, σ² {s2}");
    }
}

#[test]
fn gaussian_is_separable_and_skips_single_voxel_axes() {
    // Varies along y only: smoothing along x or z leaves it unchanged, bit for bit.
    let img = image([9, 23, 6], [1.0, 0.5, 2.0], |_, y, _| (0.3 * y as f32).sin() * 50.0);
    let out = gaussian(&img, [3.0, 0.0, 5.0]).unwrap();
    assert_eq!(bits(&out.data), bits(&img.data));
    // Smoothing along y does change it.
    let out = gaussian(&img, [0.0, 1.0, 0.0]).unwrap();
    assert_ne!(bits(&out.data), bits(&img.data));
    // A 2D image: σ along z is ignored.
    let flat = noise_image([17, 11, 1], [1.0; 3], 9);
    let a = gaussian(&flat, [1.0, 1.0, 0.0]).unwrap();
    let b = gaussian(&flat, [1.0, 1.0, 7.0]).unwrap();
    assert_eq!(bits(&a.data), bits(&b.data));
}

#[test]
fn gaussian_refuses_bad_parameters() {
    let img = noise_image([4, 4, 4], [1.0; 3], 1);
    for (sigma, what) in [
        ([-1.0, 0.0, 0.0], "sigma along x must be finite and >= 0"),
        ([0.0, f64::NAN, 0.0], "sigma along y"),
        ([0.0, 0.0, f64::INFINITY], "sigma along z"),
        ([0.0, 0.0, 1e6], "at most 65536"),
    ] {
        let e = gaussian(&img, sigma).unwrap_err().to_string();
        assert!(e.contains(what), "{sigma:?}: {e}");
    }
    let mut bad = img.clone();
    bad.data.pop();
    let e = gaussian(&bad, [1.0; 3]).unwrap_err().to_string();
    assert!(e.contains("[4, 4, 4]") && e.contains("need 64") && e.contains("holds 63"), "{e}");
    let mut bad = img.clone();
    bad.spacing[1] = 0.0;
    let e = gradient_magnitude(&bad).unwrap_err().to_string();
    assert!(e.contains("spacing along y"), "{e}");
    let mut bad = img;
    bad.dims = [0, 4, 4];
    assert!(mean_std(&bad).is_err());
}

#[test]
fn features_are_bitwise_identical_on_one_and_two_threads() {
    // Enough rows (61 · 29) for several parallel tasks.
    let img = noise_image([37, 61, 29], [0.9, 1.1, 2.5], 3);
    let run = || {
        let smooth = gaussian(&img, [1.3, 2.2, 4.0]).unwrap();
        let grad = gradient_magnitude(&smooth).unwrap();
        let k = edge_scale(&grad).unwrap();
        let g = edge_potential(&grad, k).unwrap();
        let s = sigmoid(&grad, -2.0, 5.0, 0.0, 1.0).unwrap();
        let stats = mean_std(&img).unwrap();
        let p = phantom(PhantomKind::Blobs, 24, 3.0, 11).unwrap();
        (bits(&smooth.data), bits(&g.data), bits(&s.data), k.to_bits(), stats, bits(&p.image.data))
    };
    let one = pool(1).install(run);
    let two = pool(2).install(run);
    assert!(one == two);
}

#[test]
fn gradient_magnitude_of_a_ramp_is_its_slope() {
    let spacing = [0.5, 1.5, 2.0];
    let slope = [2.0, 3.0, -0.5];
    let f = |x: usize, y: usize, z: usize| {
        (slope[0] * x as f64 * spacing[0]
            + slope[1] * y as f64 * spacing[1]
            + slope[2] * z as f64 * spacing[2]) as f32
    };
    let img = image([11, 7, 6], spacing, f);
    let g = gradient_magnitude(&img).unwrap();
    let want = (slope.iter().map(|s| s * s).sum::<f64>()).sqrt();
    // Central inside, one-sided on the faces: both exact on a linear function.
    for &v in &g.data {
        assert!((v as f64 - want).abs() <= 1e-5 * want, "{v} vs {want}");
    }
    // A 2D image has no z derivative.
    let flat = image([11, 7, 1], spacing, f);
    let g = gradient_magnitude(&flat).unwrap();
    let want = slope[0].hypot(slope[1]);
    assert!(g.data.iter().all(|&v| (v as f64 - want).abs() <= 1e-5 * want));
}

#[test]
fn gradient_magnitude_stencils() {
    // I = x² (world), h = 0.5: central differences give 2x inside, one-sided h at x = 0
    // and 2x − h at the last voxel.
    let h = 0.5;
    let img = image([6, 1, 1], [h, 1.0, 1.0], |x, _, _| ((x as f64 * h).powi(2)) as f32);
    let g = gradient_magnitude(&img).unwrap();
    let want = [0.5, 1.0, 2.0, 3.0, 4.0, 4.5];
    for (x, (&v, &w)) in g.data.iter().zip(&want).enumerate() {
        assert!((v as f64 - w).abs() < 1e-6, "x {x}: {v} vs {w}");
    }
}

#[test]
fn edge_potential_and_sigmoid_formulas() {
    let img = image([5, 1, 1], [1.0; 3], |x, _, _| [0.0, 1.0, 3.0, -3.0, 9.0][x]);
    let g = edge_potential(&img, 3.0).unwrap();
    assert_eq!(g.data, vec![1.0, 0.75, 0.5, 0.5, 0.25]);
    for k in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = edge_potential(&img, k).unwrap_err().to_string();
        assert!(e.contains("edge scale K must be finite and > 0"), "{e}");
    }
    // (max − min) / (1 + exp(−(I − β)/α)) + min with α = 2, β = 10, min = −1, max = 3.
    let values = [10.0, 10.0 + 2.0 * 3f64.ln(), -1e6, 1e6, 10.0 - 2.0 * 3f64.ln()];
    let img = image([5, 1, 1], [1.0; 3], |x, _, _| values[x] as f32);
    let s = sigmoid(&img, 2.0, 10.0, -1.0, 3.0).unwrap();
    let want = [1.0, 2.0, -1.0, 3.0, 0.0];
    for (&v, &w) in s.data.iter().zip(&want) {
        assert!((v - w).abs() < 1e-6, "{v} vs {w}");
    }
    // α < 0 reverses it.
    let r = sigmoid(&img, -2.0, 10.0, -1.0, 3.0).unwrap();
    assert!((r.data[1] - 0.0).abs() < 1e-6 && r.data[2] == 3.0);
    assert!(sigmoid(&img, 0.0, 1.0, 0.0, 1.0).unwrap_err().to_string().contains("alpha"));
    assert!(sigmoid(&img, 1.0, 1.0, f64::NAN, 1.0).unwrap_err().to_string().contains("min"));
}

#[test]
fn statistics() {
    let img = image([4, 1, 1], [1.0; 3], |x, _, _| [1.0, 2.0, 3.0, 4.0][x]);
    let (m, s) = mean_std(&img).unwrap();
    assert_eq!(m, 2.5);
    assert!((s - 1.25f64.sqrt()).abs() < 1e-15);
    let v = [5.0f32, -1.0, 2.0, 2.0, 8.0];
    assert_eq!(percentile(&v, 0.5).unwrap(), 2.0);
    assert_eq!(percentile(&v, 0.0).unwrap(), -1.0);
    assert_eq!(percentile(&v, 1.0).unwrap(), 8.0);
    assert_eq!(percentile(&v, 0.875).unwrap(), 6.5); // h = 3.5: between 5 and 8
                                                     // The edge scale of a constant gradient, of one with mostly zeros, of zeros.
    let c = image([3, 3, 1], [1.0; 3], |_, _, _| 4.0);
    assert_eq!(edge_scale(&c).unwrap(), 8.0);
    let sparse = image([10, 1, 1], [1.0; 3], |x, _, _| if x == 3 { 20.0 } else { 0.0 });
    assert_eq!(edge_scale(&sparse).unwrap(), 2.0);
    let zero = image([3, 1, 1], [1.0; 3], |_, _, _| 0.0);
    assert_eq!(edge_scale(&zero).unwrap(), 1.0);
}

/// Mean of `values` where `select` holds.
fn mean_of(values: &[f32], select: impl Fn(usize) -> bool) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (i, &v) in values.iter().enumerate() {
        if select(i) {
            s += v as f64;
            n += 1;
        }
    }
    assert!(n > 0);
    s / n as f64
}

#[test]
fn edge_potential_separates_the_ball_phantom() {
    // Ball n = 64 (centre 31.5, radius 19.2) at SNR 4, smoothed with σ = 1 voxel.
    let p = phantom(PhantomKind::Ball, 64, 4.0, 1).unwrap();
    let grad = gradient_magnitude(&gaussian(&p.image, [1.0; 3]).unwrap()).unwrap();
    let g = edge_potential(&grad, edge_scale(&grad).unwrap()).unwrap();
    let dist = |i: usize| {
        let (x, y, z) = (i % 64, i / 64 % 64, i / 4096);
        let d2: f64 = [x, y, z].iter().map(|&c| (c as f64 - 31.5).powi(2)).sum();
        d2.sqrt() - 19.2
    };
    let inside = mean_of(&g.data, |i| dist(i) < -6.0);
    let edge = mean_of(&g.data, |i| dist(i).abs() <= 0.5);
    // Measured 0.69 and 0.17.
    assert!(inside > 0.6 && edge < 0.25 && inside > 3.0 * edge, "inside {inside}, edge {edge}");
}

fn all_phantoms(n: usize, snr: f64, seed: u64) -> Vec<Phantom> {
    PhantomKind::ALL.iter().map(|&k| phantom(k, n, snr, seed).unwrap()).collect()
}

#[test]
fn phantoms_are_reproducible() {
    let a = all_phantoms(24, 2.0, 7);
    let b = pool(2).install(|| all_phantoms(24, 2.0, 7));
    let c = pool(1).install(|| all_phantoms(24, 2.0, 8));
    for ((a, b), c) in a.iter().zip(&b).zip(&c) {
        assert_eq!(bits(&a.image.data), bits(&b.image.data));
        assert_eq!(a.truth, b.truth);
        assert_eq!(a.seeds, b.seeds);
        // Another seed: other noise, same shapes.
        assert_eq!(a.truth, c.truth);
        let same = a.image.data.iter().zip(&c.image.data).filter(|(u, v)| u == v).count();
        assert!(same < a.image.len() / 100, "{same} equal voxels");
    }
}

#[test]
fn phantom_noise_has_the_stated_sigma() {
    for (kind, snr) in
        [(PhantomKind::Ball, 4.0), (PhantomKind::Anisotropic, 2.0), (PhantomKind::Torus, 1.0)]
    {
        let p = phantom(kind, 64, snr, 2).unwrap();
        let sigma = noise_sigma(snr);
        assert_eq!(sigma, CONTRAST as f64 / snr);
        for (label, clean) in [(0u8, BACKGROUND), (1, BACKGROUND + CONTRAST)] {
            let (mut s1, mut s2, mut n) = (0.0, 0.0, 0.0);
            for (&v, &t) in p.image.data.iter().zip(&p.truth) {
                if t == label {
                    let d = v as f64 - clean as f64;
                    s1 += d;
                    s2 += d * d;
                    n += 1.0;
                }
            }
            let mean = s1 / n;
            let std = (s2 / n - mean * mean).sqrt();
            assert!(mean.abs() < 0.05 * sigma, "{kind} label {label}: mean offset {mean}");
            assert!((std - sigma).abs() < 0.05 * sigma, "{kind} label {label}: σ {std} vs {sigma}");
        }
    }
    // No noise at SNR = ∞: two intensities.
    let p = phantom(PhantomKind::Torus, 16, f64::INFINITY, 0).unwrap();
    for (&v, &t) in p.image.data.iter().zip(&p.truth) {
        assert_eq!(v, BACKGROUND + CONTRAST * t as f32);
    }
}

#[test]
fn phantom_truth_volumes_and_seeds() {
    for kind in PhantomKind::ALL {
        let p = phantom(kind, 64, 3.0, 1).unwrap();
        let voxel: f64 = p.image.spacing.iter().product();
        let count = p.truth.iter().filter(|&&t| t == 1).count() as f64;
        assert!(p.truth.iter().all(|&t| t <= 1));
        let want = analytic_volume(kind, 64).unwrap();
        assert!((count * voxel - want).abs() < 0.03 * want, "{kind}: {} vs {want}", count * voxel);
        assert_eq!(p.seeds.len(), if kind == PhantomKind::Blobs { 5 } else { 1 });
        if kind == PhantomKind::Anisotropic {
            assert_eq!(p.image.dims, [64, 64, 26]);
            assert_eq!(p.image.spacing, [1.0, 1.0, 2.5]);
        } else {
            assert_eq!(p.image.dims, [64; 3]);
        }
        // Every voxel of every seed ball is inside, and seeds are 2 to 3 voxels wide.
        for s in &p.seeds {
            assert!((2.0..=3.0).contains(&s.radius), "{kind}: seed radius {}", s.radius);
            let r = s.radius.ceil() as i64;
            let c = s.center.map(|v| v.round() as i64);
            let mut voxels = 0;
            for dz in -r..=r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        let q = [c[0] + dx, c[1] + dy, c[2] + dz];
                        let d2: f64 = (0..3).map(|a| (q[a] as f64 - s.center[a]).powi(2)).sum();
                        if d2 <= s.radius * s.radius {
                            let i = p.image.index(q[0] as usize, q[1] as usize, q[2] as usize);
                            assert_eq!(p.truth[i], 1, "{kind}: seed {s:?} voxel {q:?}");
                            voxels += 1;
                        }
                    }
                }
            }
            assert!(voxels >= 7, "{kind}: seed {s:?} covers {voxels} voxels");
        }
    }
}

/// 6-connected components of a mask: the component of each voxel (0 outside).
fn components(mask: &[u8], dims: [usize; 3]) -> (usize, Vec<usize>) {
    let [nx, ny, nz] = dims;
    let mut label = vec![0usize; mask.len()];
    let mut count = 0;
    for start in 0..mask.len() {
        if mask[start] == 0 || label[start] != 0 {
            continue;
        }
        count += 1;
        label[start] = count;
        let mut stack = vec![start];
        while let Some(i) = stack.pop() {
            let (x, y, z) = (i % nx, i / nx % ny, i / (nx * ny));
            let mut push = |j: usize| {
                if mask[j] != 0 && label[j] == 0 {
                    label[j] = count;
                    stack.push(j);
                }
            };
            if x > 0 {
                push(i - 1);
            }
            if x + 1 < nx {
                push(i + 1);
            }
            if y > 0 {
                push(i - nx);
            }
            if y + 1 < ny {
                push(i + nx);
            }
            if z > 0 {
                push(i - nx * ny);
            }
            if z + 1 < nz {
                push(i + nx * ny);
            }
        }
    }
    (count, label)
}

#[test]
fn blobs_are_separate_with_a_seed_each() {
    for n in [16, 64] {
        let p = phantom(PhantomKind::Blobs, n, 2.0, 0).unwrap();
        let (count, label) = components(&p.truth, p.image.dims);
        assert_eq!(count, 5, "n {n}");
        let mut seen: Vec<usize> = p
            .seeds
            .iter()
            .map(|s| {
                let [x, y, z] = s.center.map(|v| v.round() as usize);
                label[p.image.index(x, y, z)]
            })
            .collect();
        seen.sort_unstable();
        assert_eq!(seen, vec![1, 2, 3, 4, 5], "n {n}: one seed per blob");
        // Radii differ: the blob sizes are all different.
        let mut sizes: Vec<usize> =
            (1..=5).map(|l| label.iter().filter(|&&v| v == l).count()).collect();
        sizes.sort_unstable();
        sizes.dedup();
        assert_eq!(sizes.len(), 5);
    }
}

#[test]
fn phantom_refuses_bad_parameters() {
    let e = phantom(PhantomKind::Ball, 15, 2.0, 0).unwrap_err().to_string();
    assert!(e.contains("n >= 16") && e.contains("got 15"), "{e}");
    for snr in [0.0, -1.0, f64::NAN] {
        let e = phantom(PhantomKind::Ball, 16, snr, 0).unwrap_err().to_string();
        assert!(e.contains("signal-to-noise ratio must be > 0"), "{snr}: {e}");
    }
    let e = phantom(PhantomKind::Ball, 1 << 21, 2.0, 0).unwrap_err().to_string();
    assert!(e.contains("2097152×2097152×2097152"), "{e}");
}

#[test]
fn overlap_metrics_on_small_cases() {
    let a = [1u8, 1, 0, 0];
    let b = [1u8, 0, 1, 0];
    assert_eq!(dice(&a, &b).unwrap(), 0.5);
    assert_eq!(jaccard(&a, &b).unwrap(), 1.0 / 3.0);
    assert_eq!(volume_difference(&a, &b).unwrap(), 0.0);
    // Any nonzero byte is inside.
    assert_eq!(dice(&[255, 7, 0], &[1, 1, 0]).unwrap(), 1.0);
    assert_eq!(dice(&[0, 0], &[0, 0]).unwrap(), 1.0);
    assert_eq!(jaccard(&[0, 0], &[0, 0]).unwrap(), 1.0);
    assert_eq!(dice(&[1, 0], &[0, 0]).unwrap(), 0.0);
    assert_eq!(dice(&[], &[]).unwrap(), 1.0);
    assert_eq!(volume_difference(&[1, 1, 1, 0], &[1, 1, 0, 0]).unwrap(), 0.5);
    assert_eq!(volume_difference(&[0, 0], &[1, 1]).unwrap(), -1.0);
    assert_eq!(volume_difference(&[1, 0], &[0, 0]).unwrap(), f64::INFINITY);
    let o = overlap(&[1, 1, 1, 0, 1], &[0, 1, 1, 1, 1]).unwrap();
    assert_eq!((o.a, o.b, o.both), (4, 4, 3));
    let d = o.dice();
    assert!((o.jaccard() - d / (2.0 - d)).abs() < 1e-15);
    let e = dice(&a, &b[..3]).unwrap_err().to_string();
    assert!(e.contains("4 and 3 voxels"), "{e}");
    // Large masks (several parallel chunks) count exactly.
    let n = 300_001;
    let big_a: Vec<u8> = (0..n).map(|i| (i % 3 == 0) as u8).collect();
    let big_b: Vec<u8> = (0..n).map(|i| (i % 2 == 0) as u8).collect();
    let o = overlap(&big_a, &big_b).unwrap();
    assert_eq!((o.a, o.b, o.both), (100_001, 150_001, 50_001));
}
