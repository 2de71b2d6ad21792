//! Feature images: Gaussian smoothing, gradient magnitude and the edge potentials of
//! geodesic active contours, dense over the image and parallel (each output voxel is
//! computed on its own, so the bits do not depend on the thread count).
use crate::image::Image;
use rayon::prelude::*;

/// G_σ ∗ I with σ per axis in world units (σ/spacing voxels; 0 skips an axis, and so
/// does an axis of one voxel): separable passes with the kernel truncated at ⌈3σ⌉ voxels
/// and normalised to sum 1 in f64, edges replicated (zero-flux, as ITK's Gaussian
/// filters).
pub fn gaussian(image: &Image, sigma: [f64; 3]) -> Image {
    let mut out = image.clone();
    for a in 0..3 {
        let sv = sigma[a] / image.spacing[a];
        if sv <= 0.0 || image.dims[a] == 1 {
            continue;
        }
        let r = (3.0 * sv).ceil() as i64;
        let mut w: Vec<f64> = (-r..=r).map(|k| (-(k * k) as f64 / (2.0 * sv * sv)).exp()).collect();
        let s: f64 = w.iter().sum();
        w.iter_mut().for_each(|v| *v /= s);
        let [nx, ny, _] = image.dims;
        let stride = [1, nx, nx * ny][a];
        let n = image.dims[a] as i64;
        let src = out.data.clone();
        out.data.par_iter_mut().enumerate().for_each(|(i, o)| {
            let k = ((i / stride) as i64) % n;
            let base = i as i64 - k * stride as i64;
            let mut acc = 0.0;
            for (j, wj) in w.iter().enumerate() {
                let kk = (k + j as i64 - r).clamp(0, n - 1);
                acc += wj * src[(base + kk * stride as i64) as usize] as f64;
            }
            *o = acc as f32;
        });
    }
    out
}

/// |∇I| in world units: central differences divided by twice the spacing, one-sided at
/// the faces; an axis of one voxel (a 2D image's z) has no derivative.
pub fn gradient_magnitude(image: &Image) -> Image {
    let [nx, ny, _] = image.dims;
    let d = &image.data;
    let mut out = image.clone();
    out.data.par_iter_mut().enumerate().for_each(|(i, o)| {
        let mut g2 = 0.0f64;
        for a in 0..3 {
            let n = image.dims[a];
            if n == 1 {
                continue;
            }
            let stride = [1, nx, nx * ny][a];
            let k = (i / stride) % n;
            let lo = if k > 0 { i - stride } else { i };
            let hi = if k + 1 < n { i + stride } else { i };
            let g =
                (d[hi] as f64 - d[lo] as f64) / (((hi - lo) / stride) as f64 * image.spacing[a]);
            g2 += g * g;
        }
        *o = g2.sqrt() as f32;
    });
    out
}

/// The rational edge potential g = 1/(1 + |∇I|/K) of a gradient-magnitude image.
pub fn edge_potential(grad: &Image, k: f64) -> Image {
    let mut out = grad.clone();
    out.data.par_iter_mut().for_each(|v| *v = (1.0 / (1.0 + *v as f64 / k)) as f32);
    out
}

/// K for [`edge_potential`]: the median of |∇I| (a flat region's gradient).
pub fn edge_scale(grad: &Image) -> f64 {
    let mut v = grad.data.clone();
    let m = v.len() / 2;
    v.select_nth_unstable_by(m, |a, b| a.total_cmp(b));
    (v[m] as f64).max(1e-12)
}
/// ITK's `SigmoidImageFilter`: (max − min)/(1 + exp(−(I − β)/α)) + min.
pub fn sigmoid(image: &Image, alpha: f64, beta: f64, min: f64, max: f64) -> Image {
    let mut out = image.clone();
    out.data.par_iter_mut().for_each(|v| {
        *v = ((max - min) / (1.0 + (-(*v as f64 - beta) / alpha).exp()) + min) as f32
    });
    out
}
/// The order statistic at fraction `q` ∈ [0, 1] of `values` (rounded to the nearest
/// rank); NaN-free input assumed.
pub fn percentile(values: &[f32], q: f64) -> f32 {
    let mut v = values.to_vec();
    let m = ((v.len() - 1) as f64 * q).round() as usize;
    v.select_nth_unstable_by(m, |a, b| a.total_cmp(b));
    v[m]
}
