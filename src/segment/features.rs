//! Feature images: the speed and stopping terms of the segmentation flows.
//!
//! Every function here is dense and works on a whole [`Image`]: Gaussian smoothing
//! ([`gaussian`]), the gradient magnitude ([`gradient_magnitude`]), the edge-stopping
//! function g = 1/(1 + |∇I|/K) ([`edge_potential`]) with a default K from the gradient
//! statistics ([`edge_scale`]), ITK's sigmoid ([`sigmoid`]), and the statistics the flows
//! take their defaults from ([`percentile`], [`mean_std`]).
//!
//! # Determinism
//! The filters run in parallel over x-rows with rayon. Each output value is computed by a
//! fixed sequence of floating-point operations that does not depend on how the rows are
//! split among threads, and the reductions ([`mean_std`]) add per-row partial sums in row
//! order; so every result is bitwise identical for any thread count.
//!
//! # Errors
//! The functions check what they are given (the image's dimensions against its data, its
//! spacing, every parameter's domain) and return [`GridError::InvalidParameter`] with the
//! offending value, or [`GridError::OutOfMemory`] before a buffer the machine cannot hold
//! is allocated. Intensities are not scanned: a non-finite intensity (which the
//! [`Image`] invariants exclude) propagates as NaN or ∞ and never panics.
//!
//! ```
//! use sparse_levelset::io::image::{Image, IDENTITY};
//! use sparse_levelset::segment::features;
//!
//! // A step along x: 0 for x < 64, 100 from x = 64 on.
//! let dims = [128, 2, 2];
//! let data = (0..128 * 2 * 2).map(|i| if i % 128 < 64 { 0.0 } else { 100.0 }).collect();
//! let image = Image { dims, spacing: [1.0; 3], data, to_world: IDENTITY };
//! let smooth = features::gaussian(&image, [1.0, 0.0, 0.0]).unwrap();
//! let grad = features::gradient_magnitude(&smooth).unwrap();
//! let k = features::edge_scale(&grad).unwrap();
//! let g = features::edge_potential(&grad, k).unwrap();
//! // Flat far from the step (g = 1), small on it.
//! assert_eq!(g.data[0], 1.0);
//! assert!(g.data[64] < 0.2);
//! ```

use crate::grid::GridError;
use crate::io::image::Image;
use rayon::prelude::*;

/// A Gaussian kernel reaches `TRUNCATE` standard deviations: its radius is
/// `⌊TRUNCATE · σ + 0.5⌋` voxels, SciPy's rule (`scipy.ndimage.gaussian_filter`,
/// `truncate = 4.0`). At 4σ the sampled Gaussian leaves out 6 · 10⁻⁵ of its mass and,
/// renormalised, has a variance 0.1 % below σ² (at 3σ, ITK-like kernels, it would be 2.7 %
/// below).
pub const TRUNCATE: f64 = 4.0;

/// The widest Gaussian kernel accepted: radius 2¹⁶ voxels (σ up to 16384 voxels).
pub const MAX_RADIUS: usize = 1 << 16;

/// Output rows per parallel task: about this many voxels each.
const TASK_VOXELS: usize = 1 << 14;

/// Checks the [`Image`] invariants that indexing relies on (dimensions ≥ 1 whose product
/// is `data.len()`, finite spacing > 0); `what` names the caller in the message.
pub(crate) fn check_image(image: &Image, what: &str) -> Result<(), GridError> {
    let dims = image.dims;
    if dims.contains(&0) {
        return Err(GridError::InvalidParameter(format!(
            "{what}: image dimensions must all be >= 1, got {dims:?} (nx, ny, nz)"
        )));
    }
    let len = dims[0].checked_mul(dims[1]).and_then(|n| n.checked_mul(dims[2]));
    if len != Some(image.data.len()) {
        return Err(GridError::InvalidParameter(format!(
            "{what}: image dimensions {dims:?} (nx, ny, nz) need {} intensities, the image holds {}",
            len.map_or("more than usize::MAX".to_string(), |n| n.to_string()),
            image.data.len()
        )));
    }
    if let Some(axis) = (0..3).find(|&a| !(image.spacing[a].is_finite() && image.spacing[a] > 0.0))
    {
        return Err(GridError::InvalidParameter(format!(
            "{what}: the spacing along {} must be finite and > 0, got {}",
            AXES[axis], image.spacing[axis]
        )));
    }
    Ok(())
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// An image of the same geometry as `like` holding `data`.
fn with_data(like: &Image, data: Vec<f32>) -> Image {
    Image { dims: like.dims, spacing: like.spacing, data, to_world: like.to_world }
}

/// Refuses `count` values of `elem` bytes the machine cannot hold.
fn check_alloc(count: u128, elem: usize, what: &str) -> Result<(), GridError> {
    crate::memory::check(crate::memory::bytes_of(count, elem), what)
}

/// Rows per parallel task for rows of `nx` voxels.
fn rows_per_task(nx: usize) -> usize {
    (TASK_VOXELS / nx).max(1)
}

/// The sampled Gaussian of standard deviation `sigma` voxels: `2r + 1` weights
/// `w[r + k] ∝ exp(−k² / 2σ²)`, `|k| ≤ r = ⌊4σ + 0.5⌋` ([`TRUNCATE`]), normalised in
/// f64 to sum 1 (the sum is taken from the tails inwards). `sigma = 0`, or any σ below
/// 1/8 voxel, gives the identity `[1.0]`.
///
/// Fails with [`GridError::InvalidParameter`] when `sigma` is negative or not finite, or
/// the radius exceeds [`MAX_RADIUS`].
pub fn gaussian_kernel(sigma: f64) -> Result<Vec<f64>, GridError> {
    sampled_gaussian(sigma).map_err(GridError::InvalidParameter)
}

/// [`gaussian_kernel`], its error a message.
fn sampled_gaussian(sigma: f64) -> Result<Vec<f64>, String> {
    if !(sigma.is_finite() && sigma >= 0.0) {
        return Err(format!(
            "a Gaussian's standard deviation must be finite and >= 0, got {sigma} voxels"
        ));
    }
    let radius = (TRUNCATE * sigma + 0.5).floor();
    if radius > MAX_RADIUS as f64 {
        return Err(format!(
            "a Gaussian of standard deviation {sigma} voxels needs a kernel of radius {radius} \
             voxels; at most {MAX_RADIUS} (σ ≤ {} voxels) is supported",
            MAX_RADIUS as f64 / TRUNCATE
        ));
    }
    let r = radius as usize;
    if r == 0 {
        return Ok(vec![1.0]);
    }
    let inv = -0.5 / (sigma * sigma);
    let mut w: Vec<f64> =
        (0..=2 * r).map(|t| (inv * (t as f64 - r as f64).powi(2)).exp()).collect();
    let mut sum = 0.0;
    for t in (1..=r).rev() {
        sum += w[r - t] + w[r + t];
    }
    sum += w[r];
    w.iter_mut().for_each(|v| *v /= sum);
    Ok(w)
}

/// The weights one 1D pass applies: output position `i` of an axis of `n` voxels is
/// `Σ_j weight · input[j]` over `j = start[i], start[i] + 1, …`, the weights
/// `weights[offset[i]..offset[i + 1]]`. This is the kernel with clamp-to-edge boundaries
/// where the taps that fall outside the axis are folded onto the first or last voxel
/// (their weights summed), so a position costs at most `min(2r + 1, n)` taps whatever r.
struct Taps {
    start: Vec<usize>,
    offset: Vec<usize>,
    weights: Vec<f64>,
}

impl Taps {
    fn new(kernel: &[f64], n: usize) -> Result<Taps, GridError> {
        let r = kernel.len() / 2;
        let per = (2 * r + 1).min(n);
        check_alloc(n as u128 * per as u128, 8, "the weights of a Gaussian pass")?;
        // prefix[t] = Σ_{s < t} w[s], suffix[t] = Σ_{s ≥ t} w[s], each summed from its tail.
        let mut prefix = vec![0.0; kernel.len() + 1];
        for t in 0..kernel.len() {
            prefix[t + 1] = prefix[t] + kernel[t];
        }
        let mut suffix = vec![0.0; kernel.len() + 1];
        for t in (0..kernel.len()).rev() {
            suffix[t] = suffix[t + 1] + kernel[t];
        }
        let mut taps = Taps {
            start: Vec::with_capacity(n),
            offset: Vec::with_capacity(n + 1),
            weights: Vec::with_capacity(n * per),
        };
        taps.offset.push(0);
        for i in 0..n {
            // Input j is kernel tap t = j − i + r.
            let lo = i.saturating_sub(r);
            let hi = (i + r).min(n - 1);
            taps.start.push(lo);
            for j in lo..=hi {
                let t = j + r - i;
                let w = if j == lo && i < r && j == hi && i + r > n - 1 {
                    suffix[0] // n = 1: every tap reads the one voxel
                } else if j == lo && i < r {
                    prefix[t + 1] // taps t' ≤ t read voxel 0
                } else if j == hi && i + r > n - 1 {
                    suffix[t] // taps t' ≥ t read voxel n − 1
                } else {
                    kernel[t]
                };
                taps.weights.push(w);
            }
            taps.offset.push(taps.weights.len());
        }
        Ok(taps)
    }

    #[inline]
    fn of(&self, i: usize) -> (usize, &[f64]) {
        (self.start[i], &self.weights[self.offset[i]..self.offset[i + 1]])
    }
}

/// `acc[i] = w[r] · centre[i] + Σ_{k=1..r} w[r + k] · (plus(k)[i] + minus(k)[i])`: the
/// symmetric kernel `w` applied with its mirrored taps paired (half the multiplications),
/// in `f64`, vectorised over `i`. `plus(k)` and `minus(k)` are the inputs `k` voxels
/// ahead and behind.
#[inline]
fn symmetric<'a>(
    acc: &mut [f64],
    kernel: &[f64],
    centre: &[f32],
    plus: impl Fn(usize) -> &'a [f32],
    minus: impl Fn(usize) -> &'a [f32],
) {
    let r = kernel.len() / 2;
    let wc = kernel[r];
    for (a, &x) in acc.iter_mut().zip(centre) {
        *a = wc * x as f64;
    }
    for k in 1..=r {
        let w = kernel[r + k];
        for ((a, &u), &v) in acc.iter_mut().zip(plus(k)).zip(minus(k)) {
            *a += w * (u as f64 + v as f64);
        }
    }
}

/// One pass along x: `dst` and `src` hold whole rows of `nx` voxels.
fn pass_x(src: &[f32], dst: &mut [f32], nx: usize, kernel: &[f64], taps: &Taps) {
    let r = kernel.len() / 2;
    // Interior outputs [lo, hi) read no clamped voxel: the plain kernel, vectorised over x.
    let (lo, hi) = if nx > 2 * r { (r, nx - r) } else { (nx, nx) };
    let rows = rows_per_task(nx);
    dst.par_chunks_mut(nx * rows).zip(src.par_chunks(nx * rows)).for_each(|(dst, src)| {
        let mut acc = vec![0.0f64; hi - lo];
        for (out, row) in dst.chunks_exact_mut(nx).zip(src.chunks_exact(nx)) {
            if hi > lo {
                // Outputs lo..hi read inputs lo ± k .. hi ± k.
                let plus = |k: usize| &row[lo + k..hi + k];
                let minus = |k: usize| &row[lo - k..hi - k];
                symmetric(&mut acc, kernel, &row[lo..hi], plus, minus);
                for (o, &a) in out[lo..hi].iter_mut().zip(&acc) {
                    *o = a as f32;
                }
            }
            for i in (0..lo).chain(hi..nx) {
                let (start, weights) = taps.of(i);
                let mut a = 0.0f64;
                for (&w, &x) in weights.iter().zip(&row[start..]) {
                    a += w * x as f64;
                }
                out[i] = a as f32;
            }
        }
    });
}

/// One pass along y (`axis = 1`) or z (`axis = 2`): each output row is a weighted sum of
/// whole input rows, vectorised over x.
fn pass_rows(
    src: &[f32],
    dst: &mut [f32],
    dims: [usize; 3],
    axis: usize,
    kernel: &[f64],
    taps: &Taps,
) {
    let [nx, ny, _] = dims;
    let (n, r) = (dims[axis], kernel.len() / 2);
    let rows = rows_per_task(nx);
    dst.par_chunks_mut(nx * rows).enumerate().for_each(|(c, dst)| {
        let mut acc = vec![0.0f64; nx];
        for (q, out) in dst.chunks_exact_mut(nx).enumerate() {
            let row = c * rows + q;
            let (y, z) = (row % ny, row / ny);
            // Input row at position j along the axis: first_row + j · stride.
            let (i, first_row, stride) = if axis == 1 { (y, ny * z, 1) } else { (z, y, ny) };
            let line = |j: usize| {
                let base = (first_row + j * stride) * nx;
                &src[base..base + nx]
            };
            if i >= r && i + r < n {
                symmetric(&mut acc, kernel, line(i), |k| line(i + k), |k| line(i - k));
            } else {
                let (start, weights) = taps.of(i);
                acc.fill(0.0);
                for (s, &w) in weights.iter().enumerate() {
                    for (a, &x) in acc.iter_mut().zip(line(start + s)) {
                        *a += w * x as f64;
                    }
                }
            }
            for (o, &a) in out.iter_mut().zip(&acc) {
                *o = a as f32;
            }
        }
    });
}

/// Gaussian smoothing with standard deviation `sigma[axis]` in **world units** per axis
/// (`sigma / spacing` voxels), as separable 1D passes x, then y, then z.
///
/// * Kernel: the sampled Gaussian of [`gaussian_kernel`], truncated at 4σ ([`TRUNCATE`])
///   and normalised to sum 1; SciPy's `gaussian_filter(…, mode="nearest", truncate=4)`.
/// * Boundary: clamp-to-edge (the edge voxel replicated), the zero-flux Neumann condition
///   of ITK's `DiscreteGaussianImageFilter` and `SmoothingRecursiveGaussianImageFilter`;
///   a constant image is returned unchanged.
/// * Accuracy: each pass accumulates the `f32` intensities in `f64` and rounds once per
///   voxel to `f32`.
/// * An axis is skipped when its σ is 0, rounds to a radius of 0 voxels (σ < 1/8 voxel)
///   or the image has a single voxel along it (clamp-to-edge makes that pass the
///   identity; a 2D image is smoothed in-plane only).
///
/// Fails with [`GridError::InvalidParameter`] on a malformed image, a σ that is negative
/// or not finite, or a kernel wider than [`MAX_RADIUS`]; with [`GridError::OutOfMemory`]
/// when the two working buffers do not fit.
pub fn gaussian(image: &Image, sigma: [f64; 3]) -> Result<Image, GridError> {
    check_image(image, "Gaussian smoothing")?;
    let mut passes = Vec::new();
    for axis in 0..3 {
        let s = sigma[axis];
        if !(s.is_finite() && s >= 0.0) {
            return Err(GridError::InvalidParameter(format!(
                "Gaussian smoothing: sigma along {} must be finite and >= 0 (world units), got {s}",
                AXES[axis]
            )));
        }
        let kernel = sampled_gaussian(s / image.spacing[axis]).map_err(|e| {
            GridError::InvalidParameter(format!(
                "Gaussian smoothing along {} (sigma {s}, spacing {}): {e}",
                AXES[axis], image.spacing[axis]
            ))
        })?;
        let n = image.dims[axis];
        if kernel.len() > 1 && n > 1 {
            let taps = Taps::new(&kernel, n)?;
            passes.push((axis, kernel, taps));
        }
    }
    if passes.is_empty() {
        return Ok(image.clone());
    }
    let len = image.len();
    let buffers = if passes.len() > 1 { 2 } else { 1 };
    check_alloc(buffers * len as u128, 4, "the buffers of a Gaussian smoothing")?;
    // Fusing the x and y passes slice by slice (the slice in cache between them) measured
    // no faster (x and y on 128³, one thread: 4.8 ms both ways): the passes are bound by
    // the f64 arithmetic, not by memory traffic.
    // The third pass writes into the first one's buffer (every value is written): its
    // pages are touched already, where a fresh buffer's first touch costs about as much
    // as the pass and scales worse over threads.
    let (mut result, mut spare): (Option<Vec<f32>>, Option<Vec<f32>>) = (None, None);
    for (axis, kernel, taps) in &passes {
        let mut out = spare.take().unwrap_or_else(|| vec![0.0f32; len]);
        let src = result.as_deref().unwrap_or(&image.data);
        match axis {
            0 => pass_x(src, &mut out, image.dims[0], kernel, taps),
            _ => pass_rows(src, &mut out, image.dims, *axis, kernel, taps),
        }
        spare = result.replace(out);
    }
    Ok(with_data(image, result.unwrap_or_else(|| image.data.clone())))
}

/// Where a derivative along an axis of `n` voxels at position `i` reads: `(plus, minus,
/// factor)` with `∂ ≈ (I[plus] − I[minus]) · factor`, `None` when `n = 1`.
#[inline]
fn stencil(i: usize, n: usize, h: f64) -> Option<(usize, usize, f64)> {
    match n {
        1 => None,
        _ if i == 0 => Some((1, 0, 1.0 / h)),
        _ if i == n - 1 => Some((n - 1, n - 2, 1.0 / h)),
        _ => Some((i + 1, i - 1, 0.5 / h)),
    }
}

/// ∇I, one image per axis, with the differences of [`gradient_magnitude`] (central inside,
/// one-sided on the faces, divided by the axis's spacing; 0 along an axis of one voxel).
/// GAC's advection velocity is −∇g of its edge potential.
///
/// The rows (`y + ny z`) whose difference times the factor is the derivative along `axis`
/// (1: y, 2: z) at the voxels of row (`y`, `z`), as [`stencil`] gives it along the axis.
fn row_stencil(
    axis: usize,
    y: usize,
    z: usize,
    dims: [usize; 3],
    h: f64,
) -> Option<(usize, usize, f64)> {
    let [_, ny, nz] = dims;
    match axis {
        1 => stencil(y, ny, h).map(|(p, m, f)| (p + ny * z, m + ny * z, f)),
        _ => stencil(z, nz, h).map(|(p, m, f)| (y + ny * p, y + ny * m, f)),
    }
}

/// Fails with [`GridError::InvalidParameter`] on a malformed image.
pub fn gradient(image: &Image) -> Result<[Image; 3], GridError> {
    check_image(image, "gradient")?;
    let [nx, ny, _] = image.dims;
    let src = &image.data;
    let rows = rows_per_task(nx);
    // Row by row, as `gradient_magnitude`: along y and z a row of differences of two rows.
    let axis = |a: usize| {
        let h = image.spacing[a];
        let mut out = vec![0.0f32; src.len()];
        out.par_chunks_mut(nx * rows).enumerate().for_each(|(c, dst)| {
            for (q, line) in dst.chunks_exact_mut(nx).enumerate() {
                let row = c * rows + q;
                let (y, z) = (row % ny, row / ny);
                let here = &src[row * nx..(row + 1) * nx];
                if a == 0 {
                    for (x, o) in line.iter_mut().enumerate() {
                        *o = stencil(x, nx, h).map_or(0.0, |(p, m, f)| {
                            ((here[p] as f64 - here[m] as f64) * f) as f32
                        });
                    }
                    continue;
                }
                match row_stencil(a, y, z, image.dims, h) {
                    None => line.fill(0.0),
                    Some((p, m, f)) => {
                        let (plus, minus) =
                            (&src[p * nx..(p + 1) * nx], &src[m * nx..(m + 1) * nx]);
                        for ((o, &u), &v) in line.iter_mut().zip(plus).zip(minus) {
                            *o = ((u as f64 - v as f64) * f) as f32;
                        }
                    }
                }
            }
        });
        with_data(image, out)
    };
    Ok([axis(0), axis(1), axis(2)])
}

/// |∇I| in intensity per world unit: central differences `(I[i+1] − I[i−1]) / 2h` inside,
/// one-sided `(I[1] − I[0]) / h` and `(I[n−1] − I[n−2]) / h` on the faces, with `h` the
/// spacing of the axis. An axis with one voxel contributes 0 (a 2D image has no z
/// derivative). Computed in `f64`, rounded once.
///
/// Fails with [`GridError::InvalidParameter`] on a malformed image.
pub fn gradient_magnitude(image: &Image) -> Result<Image, GridError> {
    check_image(image, "gradient magnitude")?;
    Ok(with_data(image, gradient_magnitude_data(image, image.spacing)))
}

/// [`gradient_magnitude`] per voxel step: the differences taken over unit spacing, the
/// result carrying spacing 1 (what the gradient magnitude of a copy of the image with
/// spacing 1 gives, without that copy: a serial pass over the image's memory).
///
/// Fails with [`GridError::InvalidParameter`] on a malformed image.
pub(crate) fn voxel_gradient_magnitude(image: &Image) -> Result<Image, GridError> {
    check_image(image, "gradient magnitude")?;
    let data = gradient_magnitude_data(image, [1.0; 3]);
    Ok(Image { dims: image.dims, spacing: [1.0; 3], data, to_world: image.to_world })
}

/// The values of [`gradient_magnitude`], with the differences over `spacing` (the image
/// checked by the caller).
fn gradient_magnitude_data(image: &Image, spacing: [f64; 3]) -> Vec<f32> {
    let [nx, ny, _] = image.dims;
    let [sx, sy, sz] = spacing;
    let src = &image.data;
    let mut out = vec![0.0f32; image.len()];
    let rows = rows_per_task(nx);
    out.par_chunks_mut(nx * rows).enumerate().for_each(|(c, dst)| {
        let mut acc = vec![0.0f64; nx];
        for (q, out) in dst.chunks_exact_mut(nx).enumerate() {
            let row = c * rows + q;
            let (y, z) = (row % ny, row / ny);
            let here = &src[row * nx..(row + 1) * nx];
            for (x, a) in acc.iter_mut().enumerate() {
                *a = match stencil(x, nx, sx) {
                    Some((p, m, f)) => {
                        let d = (here[p] as f64 - here[m] as f64) * f;
                        d * d
                    }
                    None => 0.0,
                };
            }
            let neighbours =
                [row_stencil(1, y, z, image.dims, sy), row_stencil(2, y, z, image.dims, sz)];
            for (p, m, f) in neighbours.into_iter().flatten() {
                let plus = &src[p * nx..(p + 1) * nx];
                let minus = &src[m * nx..(m + 1) * nx];
                for ((a, &u), &v) in acc.iter_mut().zip(plus).zip(minus) {
                    let d = (u as f64 - v as f64) * f;
                    *a += d * d;
                }
            }
            for (o, &a) in out.iter_mut().zip(&acc) {
                *o = a.sqrt() as f32;
            }
        }
    });
    out
}

/// Applies `f` to every intensity in `f64`, in parallel, rounding once.
fn map(image: &Image, f: impl Fn(f64) -> f64 + Sync) -> Image {
    let mut out = vec![0.0f32; image.len()];
    out.par_chunks_mut(TASK_VOXELS).zip(image.data.par_chunks(TASK_VOXELS)).for_each(|(o, i)| {
        for (o, &v) in o.iter_mut().zip(i) {
            *o = f(v as f64) as f32;
        }
    });
    with_data(image, out)
}

/// The edge-stopping function of issue 14, `g = 1 / (1 + |∇I| / K)`: 1 where the image is
/// flat, decreasing towards 0 on strong edges, `g = 1/2` where `|∇I| = K`. `grad_mag` is
/// a gradient magnitude ([`gradient_magnitude`], usually of a smoothed image); its absolute
/// value is used, so `g ∈ (0, 1]`. `k` is in the units of `grad_mag` (see [`edge_scale`]
/// for a default).
///
/// This is the stopping function `1/(1 + |∇I|^p)` of Caselles, Kimmel and Sapiro
/// ("Geodesic active contours", 1997) with `p = 1` and the gradient measured in units of
/// K. It is not ITK's `EdgePotentialImageFilter` (`exp(−|∇I|)`), nor the sigmoid of ITK's
/// geodesic-active-contour examples ([`sigmoid`]), nor the common `p = 2`: it decays like
/// `K/|∇I|`, more slowly than those, so that weak edges still slow a front but strong
/// edges do not stop it completely (see [`edge_scale`] for the values it reaches).
///
/// Fails with [`GridError::InvalidParameter`] on a malformed image or a `k` that is not
/// finite and > 0.
pub fn edge_potential(grad_mag: &Image, k: f64) -> Result<Image, GridError> {
    check_image(grad_mag, "edge potential")?;
    if !(k.is_finite() && k > 0.0) {
        return Err(GridError::InvalidParameter(format!(
            "edge potential: the edge scale K must be finite and > 0, got {k}"
        )));
    }
    let inv = 1.0 / k;
    Ok(map(grad_mag, |v| 1.0 / (1.0 + v.abs() * inv)))
}

/// ITK's `SigmoidImageFilter`: `(max − min) / (1 + exp(−(I − β) / α)) + min`. With α > 0
/// the output rises from `min` to `max` around `I = β` over a width of about 4|α|; α < 0
/// reverses it (the usual choice for a speed that is high in flat regions when `I` is a
/// gradient magnitude).
///
/// Fails with [`GridError::InvalidParameter`] on a malformed image, an α that is 0 or not
/// finite, or a β, min or max that is not finite.
pub fn sigmoid(
    image: &Image,
    alpha: f64,
    beta: f64,
    min: f64,
    max: f64,
) -> Result<Image, GridError> {
    check_image(image, "sigmoid")?;
    if !(alpha.is_finite() && alpha != 0.0) {
        return Err(GridError::InvalidParameter(format!(
            "sigmoid: alpha must be finite and nonzero, got {alpha}"
        )));
    }
    for (name, v) in [("beta", beta), ("min", min), ("max", max)] {
        if !v.is_finite() {
            return Err(GridError::InvalidParameter(format!(
                "sigmoid: {name} must be finite, got {v}"
            )));
        }
    }
    let (scale, inv) = (max - min, 1.0 / alpha);
    // exp overflows to ∞ far on the low side, giving exactly `min`, never NaN.
    Ok(map(image, |v| scale / (1.0 + (-(v - beta) * inv).exp()) + min))
}

/// The `q`-quantile (`q ∈ [0, 1]`) of `values` by NumPy's default (`linear`) rule: with
/// the values sorted ascending as `x₀ ≤ … ≤ x_{n−1}` and `h = q (n − 1)`, the result is
/// `x_⌊h⌋ + (h − ⌊h⌋)(x_⌊h⌋+1 − x_⌊h⌋)`, computed in `f64` and rounded. So `q = 0` is the
/// minimum, `q = 1` the maximum, `q = 0.5` the median (the mean of the middle two for an
/// even count). Exact order statistics from two parallel counting passes (linear time, no
/// copy): the result depends on the multiset of values only.
///
/// Fails with [`GridError::InvalidParameter`] when `values` is empty or holds a value that
/// is not finite, or `q` is outside `[0, 1]`.
pub fn percentile(values: &[f32], q: f64) -> Result<f32, GridError> {
    let parts: Vec<&[f32]> = values.chunks(part_len(values.len())).collect();
    percentile_of_parts(&parts, q)
}

/// Values per part of `len` values for the counting passes: one part per thread (each
/// part costs a histogram of 512 kB per pass), of at least 2¹⁶ values.
pub(crate) fn part_len(len: usize) -> usize {
    (1usize << 16).max(len.div_ceil(rayon::current_num_threads()))
}

/// [`percentile`] of the values of all `parts` together (in order: an error names the
/// first value that is not finite by its index in the concatenation).
pub(crate) fn percentile_of_parts(parts: &[&[f32]], q: f64) -> Result<f32, GridError> {
    if !(0.0..=1.0).contains(&q) {
        return Err(GridError::InvalidParameter(format!(
            "percentile: the quantile must be in [0, 1], got {q}"
        )));
    }
    let len: usize = parts.iter().map(|p| p.len()).sum();
    if len == 0 {
        return Err(GridError::InvalidParameter("percentile of no values".to_string()));
    }
    let bad: Vec<Option<usize>> =
        parts.par_iter().map(|p| p.iter().position(|v| !v.is_finite())).collect();
    let mut before = 0;
    for (p, bad) in parts.iter().zip(bad) {
        if let Some(i) = bad {
            return Err(GridError::InvalidParameter(format!(
                "percentile: value {} is {}, not a finite number",
                before + i,
                p[i]
            )));
        }
        before += p.len();
    }
    let h = q * (len - 1) as f64;
    let k = (h.floor() as usize).min(len - 1);
    let frac = h - k as f64;
    let [lo, hi] = super::stats::order_statistics_of_parts(parts, [k, k + 1]);
    if frac == 0.0 {
        return Ok(lo);
    }
    Ok((lo as f64 + frac * (hi as f64 - lo as f64)) as f32)
}

/// [`edge_scale`] returns this many times the median gradient magnitude.
pub const EDGE_SCALE_FACTOR: f64 = 2.0;

/// A default K for [`edge_potential`]: twice the median of the gradient magnitude
/// ([`EDGE_SCALE_FACTOR`]). Pass the gradient of the *smoothed* image, the one the edge
/// potential is computed from.
///
/// The median is a robust estimate of the noise gradient as long as edges cover less than
/// half of the voxels. In a homogeneous region with white noise, each component of
/// `∇(G ∗ I)` is Gaussian with one deviation `s`, so `|∇(G ∗ I)|` follows a χ
/// distribution with 3 degrees of freedom in 3D (median 1.54 s) or 2 in 2D (Rayleigh,
/// median 1.18 s): K = 2 · median puts `g = 1/2` at the 97th percentile of the noise
/// gradient in 3D (94th in 2D) and `g = 2/3` at its median. A smoothed edge of contrast
/// `C` is `C / (σ √(2π))` steep whatever the noise, so its `g` falls as the
/// signal-to-noise ratio grows.
///
/// Measured on the [`crate::segment::phantom`] ball (n = 64, smoothed with σ = 1 voxel;
/// mean g more than 6 voxels inside the surface, and on the voxels within half a voxel of
/// it): SNR 2, inside 0.69, edge 0.29; SNR 4, inside 0.69, edge 0.17; SNR 8, inside 0.70,
/// edge 0.09; with σ = 1.5 voxels at SNR 4, 0.72 and 0.11. A high percentile instead
/// (Canny's 90 %, used by Perona and Malik 1990 for their K) lands in the edges once they
/// cover about a tenth of the voxels (σ = 2 at SNR 4 gave K 7.3, inside 0.92, edge 0.28,
/// no better than at SNR 2); the median does not.
///
/// Where half the gradient or more is exactly 0 (a noise-free image), the rule falls back
/// to a tenth of the largest gradient (edges then get `g ≈ 0.1`), and to 1 for a constant
/// image (where any K gives `g ≡ 1`).
///
/// Fails as [`percentile`] does.
pub fn edge_scale(grad_mag: &Image) -> Result<f64, GridError> {
    check_image(grad_mag, "edge scale")?;
    let median = percentile(&grad_mag.data, 0.5)?.abs() as f64;
    if median > 0.0 {
        return Ok(EDGE_SCALE_FACTOR * median);
    }
    let max = grad_mag.data.par_iter().map(|v| v.abs()).reduce(|| 0.0, f32::max) as f64;
    Ok(if max > 0.0 { 0.1 * max } else { 1.0 })
}

/// Mean and standard deviation of the intensities (the population deviation, divided by
/// the voxel count), in `f64`, by two passes (the mean first, then the squared deviations
/// from it). Deterministic: each x-row is summed in order in `f64` (in parallel), then the
/// row sums are added in row order.
///
/// Fails with [`GridError::InvalidParameter`] on a malformed image.
pub fn mean_std(image: &Image) -> Result<(f64, f64), GridError> {
    check_image(image, "mean and standard deviation")?;
    let nx = image.dims[0];
    let sum_rows = |f: &(dyn Fn(f64) -> f64 + Sync)| -> f64 {
        let partial: Vec<f64> =
            image.data.par_chunks(nx).map(|row| row.iter().map(|&v| f(v as f64)).sum()).collect();
        partial.iter().sum()
    };
    let n = image.len() as f64;
    let mean = sum_rows(&|v| v) / n;
    let var = sum_rows(&|v| (v - mean) * (v - mean)) / n;
    Ok((mean, var.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_radius_and_sum() {
        assert_eq!(gaussian_kernel(0.0).unwrap(), vec![1.0]);
        assert_eq!(gaussian_kernel(0.12).unwrap(), vec![1.0]);
        assert_eq!(gaussian_kernel(0.125).unwrap().len(), 3);
        // ⌊4 · 1 + 0.5⌋ = 4; ⌊4 · 1.2 + 0.5⌋ = 5.
        assert_eq!(gaussian_kernel(1.0).unwrap().len(), 9);
        assert_eq!(gaussian_kernel(1.2).unwrap().len(), 11);
        for s in [0.3, 1.0, 2.7, 10.0] {
            let w = gaussian_kernel(s).unwrap();
            let sum: f64 = w.iter().sum();
            assert!((sum - 1.0).abs() < 1e-14, "σ = {s}: sum {sum}");
            let r = w.len() / 2;
            assert!((0..r).all(|t| w[t] == w[2 * r - t] && w[t] < w[t + 1]), "symmetric, peaked");
        }
        for s in [-1.0, f64::NAN, f64::INFINITY, 1e5] {
            assert!(gaussian_kernel(s).is_err(), "{s}");
        }
    }

    #[test]
    fn folded_taps_sum_to_one_and_match_clamping() {
        let kernel = gaussian_kernel(1.7).unwrap();
        let r = kernel.len() / 2;
        for n in [1, 2, 3, 5, 7, 14, 40] {
            let taps = Taps::new(&kernel, n).unwrap();
            for i in 0..n {
                // The folded weights equal the kernel's weights summed per clamped input.
                let mut want = vec![0.0; n];
                for (t, &w) in kernel.iter().enumerate() {
                    let j = (i as i64 + t as i64 - r as i64).clamp(0, n as i64 - 1) as usize;
                    want[j] += w;
                }
                let (start, weights) = taps.of(i);
                for j in 0..n {
                    let got = if (start..start + weights.len()).contains(&j) {
                        weights[j - start]
                    } else {
                        0.0
                    };
                    assert!((got - want[j]).abs() < 1e-15, "n {n} i {i} j {j}");
                }
            }
        }
    }

    #[test]
    fn percentile_follows_numpy_linear() {
        let v = [3.0f32, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0, 6.0];
        // numpy.percentile(v, [0, 50, 90, 100]) = 1, 3.5, 6.9, 9.
        assert_eq!(percentile(&v, 0.0).unwrap(), 1.0);
        assert_eq!(percentile(&v, 0.5).unwrap(), 3.5);
        assert!((percentile(&v, 0.9).unwrap() - 6.9).abs() < 1e-6);
        assert_eq!(percentile(&v, 1.0).unwrap(), 9.0);
        assert_eq!(percentile(&[7.0], 0.3).unwrap(), 7.0);
        assert!(percentile(&[], 0.5).is_err());
        assert!(percentile(&v, 1.5).is_err());
        assert!(percentile(&v, f64::NAN).is_err());
        assert!(percentile(&[1.0, f32::NAN], 0.5).is_err());
    }

    /// ∇I row by row is the textbook difference at every voxel: central inside,
    /// one-sided on the faces, over the axis's spacing, 0 along an axis of one voxel; on
    /// sizes with thin axes and a 2D image.
    #[test]
    fn gradient_is_the_difference_at_every_voxel() {
        for dims in [[7, 5, 4], [2, 9, 3], [6, 1, 5], [5, 6, 1], [1, 3, 2]] {
            let len = dims.iter().product::<usize>();
            let data: Vec<f32> = (0..len).map(|i| ((i * 7919) % 97) as f32 * 0.37 - 11.0).collect();
            let spacing = [0.7, 1.3, 2.1];
            let image = Image { dims, spacing, data, to_world: crate::io::image::IDENTITY };
            let got = gradient(&image).unwrap();
            let [nx, ny, _] = dims;
            for (a, g) in got.iter().enumerate() {
                let (n, stride) = (dims[a], [1, nx, nx * ny][a]);
                for (i, &v) in g.data.iter().enumerate() {
                    let j = (i / stride) % n;
                    let at = |k: usize| image.data[i - j * stride + k * stride] as f64;
                    let want = match n {
                        1 => 0.0,
                        _ if j == 0 => ((at(1) - at(0)) * (1.0 / spacing[a])) as f32,
                        _ if j == n - 1 => ((at(n - 1) - at(n - 2)) * (1.0 / spacing[a])) as f32,
                        _ => ((at(j + 1) - at(j - 1)) * (0.5 / spacing[a])) as f32,
                    };
                    assert_eq!(v.to_bits(), want.to_bits(), "{dims:?} axis {a} voxel {i}");
                }
            }
        }
    }
}
