//! Robust statistics of the image that the segmentation's defaults are taken from, so that
//! they hold on any intensity scale, offset and noise level:
//!
//! * [`Normalization`]: the image is mapped to `(I − c) / s` before anything else, with c
//!   the (lower) median and s the distance between the 1st and 99th percentiles, all
//!   order statistics. For `a·I + b` with `a > 0` every one of them transforms exactly
//!   (where `a·I + b` is itself exact in `f32`, the normalised images are bit for bit the
//!   same), so every later default, and the mask, is the same.
//! * [`noise_sigma`]: the noise level, from the median absolute second difference along
//!   the axes (a high-pass whose variance is 6σ² for white noise), flat runs excluded.
//! * [`smoothing_voxels`]: the Gaussian σ (in voxels) that brings the noise of the smoothed
//!   image, or of its gradient, far enough below the contrast the seeds see.
//! * [`probe_edges`]: rays cast from the seeds outward, which measure the contrast of the
//!   first edge they cross and the gradient magnitude on it.

use crate::grid::GridError;
use crate::io::image::Image;
use rayon::prelude::*;

/// An affine map of intensities onto a scale of their own: `v ↦ (v − center) / scale`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Normalization {
    pub center: f64,
    pub scale: f64,
}

/// `x`'s place in [`f32::total_cmp`]'s order as an unsigned integer.
fn order_key(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | 1 << 31
    }
}

/// The inverse of [`order_key`].
fn from_order_key(k: u32) -> f32 {
    f32::from_bits(if k >> 31 == 1 { k & !(1 << 31) } else { !k })
}

/// Values per parallel task of [`order_statistics`].
const ORDER_CHUNK: usize = 1 << 16;

/// The bucket of `counts` (counts per bucket, in order) that holds rank `k` (0-based),
/// and `k`'s rank within it.
fn bucket_of(counts: &[u64], mut k: u64) -> (usize, u64) {
    let mut b = 0;
    while k >= counts[b] {
        k -= counts[b];
        b += 1;
    }
    (b, k)
}

/// The `k`-th smallest values (0-based, each `k` clamped to the last) of `v` (not empty)
/// in [`f32::total_cmp`]'s order: [`order_statistics_of_parts`] over one part per thread
/// (at least [`ORDER_CHUNK`] values each), with no copy of `v`.
pub(crate) fn order_statistics<const N: usize>(v: &[f32], ks: [usize; N]) -> [f32; N] {
    let chunk = ORDER_CHUNK.max(v.len().div_ceil(rayon::current_num_threads()));
    let parts: Vec<&[f32]> = v.chunks(chunk).collect();
    order_statistics_of_parts(&parts, ks)
}

/// Values visited part by part, in parallel: what [`order_statistics_of`] selects from,
/// without the values having to be stored.
pub(crate) trait ValueParts: Sync {
    /// How many parts.
    fn parts(&self) -> usize;
    /// Calls `f` with every value of part `part` (the same values on every call).
    fn visit(&self, part: usize, f: impl FnMut(f32));
}

impl ValueParts for [&[f32]] {
    fn parts(&self) -> usize {
        self.len()
    }
    fn visit(&self, part: usize, f: impl FnMut(f32)) {
        self[part].iter().copied().for_each(f);
    }
}

/// Up to this many values, [`order_statistics_of_parts`] selects from a copy of them
/// instead of counting: the counting passes zero a histogram of 512 kB per part and pass,
/// which costs more than selecting among that many values. The middle ranks of 1,430
/// values in two parts (as many as the seeds' voxels of the 128³ blobs phantom): 0.93 and
/// 1.6 ms on one thread, 0.34–0.44 and 0.12 ms on two by counting, 0.004–0.006 ms from a
/// copy; of 2¹⁴ values, 0.11–0.13 ms by counting and 0.04 ms from a copy (minima of 50
/// calls in a test build, two runs, 2-core AMD EPYC, 2026-12-03).
const SELECT_FROM_COPY: usize = 1 << 14;

/// [`order_statistics_of`] the values of all `parts` together (not all empty); the same
/// values whichever way they are found.
pub(crate) fn order_statistics_of_parts<const N: usize>(
    parts: &[&[f32]],
    ks: [usize; N],
) -> [f32; N] {
    let len: usize = parts.iter().map(|p| p.len()).sum();
    if (1..=SELECT_FROM_COPY).contains(&len) {
        let mut v = parts.concat();
        return ks.map(|k| *v.select_nth_unstable_by(k.min(len - 1), f32::total_cmp).1);
    }
    order_statistics_of(parts, |_| ks).expect("values to select from")
}

/// The `k`-th smallest values (0-based, each `k` clamped to the last; the ranks `ks` gives
/// for the number of values) of the values of all `parts` together, in [`f32::total_cmp`]'s
/// order; `None` when there are none. Exact, from two parallel counting passes over the
/// values' order keys (the high 16 bits, then the low 16 bits within each high part a
/// wanted rank falls in, counted once however many ranks fall in it), a histogram per
/// part. Counts are integers, so the result depends neither on the parts nor on the thread
/// count. Callers give about one part per thread: each part zeroes a histogram of 512 kB
/// per pass and wanted high part (and one more in the second pass, of which a page is
/// used), whatever its length. The parts' histograms are added into the first one's (not
/// reduced from fresh zeroed ones, whose first touch cost more than the counting on two
/// threads).
pub(crate) fn order_statistics_of<V: ValueParts + ?Sized, const N: usize>(
    parts: &V,
    ks: impl FnOnce(usize) -> [usize; N],
) -> Option<[f32; N]> {
    type Counts = Vec<u64>;
    let add = |a: &mut [u64], b: &[u64]| a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
    let zero = || vec![0u64; 1 << 16];
    let mut high: Vec<Counts> = (0..parts.parts())
        .into_par_iter()
        .map(|p| {
            let mut h = zero();
            parts.visit(p, |x| h[(order_key(x) >> 16) as usize] += 1);
            h
        })
        .collect::<Vec<Counts>>();
    // The parts' counts added into the first part's (integers: in any order).
    let (high, rest) = high.split_first_mut()?;
    rest.iter().for_each(|h| add(high, h));
    let len = high.iter().sum::<u64>();
    if len == 0 {
        return None;
    }
    // (high part, rank within it) of every wanted rank, and the distinct high parts.
    let places = ks(len as usize).map(|k| bucket_of(high, (k as u64).min(len - 1)));
    let mut wanted: Vec<u32> = places.iter().map(|&(b, _)| b as u32).collect();
    wanted.sort_unstable();
    wanted.dedup();
    // One histogram of the low 16 bits per wanted high part, after a block that takes the
    // values of the other high parts (spread over 16 counters by their low bits, so that
    // consecutive ones seldom wait on the same counter): every value is counted, in the
    // block a table gives its high part, without a branch. A test of the high part per
    // value, whose outcome follows the data, was mispredicted so often that the three
    // order statistics of a 128³ image took 6.0 ms on one thread and 3.7–5.5 ms on two;
    // 4.5 and 2.4 ms this way (minima of 150 calls, a copy of this function built alone,
    // 2-core AMD EPYC, 2026-11-28).
    let blocks = wanted.len() + 1;
    let mut block_of = vec![0u8; 1 << 16];
    for (j, &b) in wanted.iter().enumerate() {
        block_of[b as usize] = u8::try_from(j + 1).expect("at most 255 ranks at once");
    }
    let mut low: Vec<Counts> = (0..parts.parts())
        .into_par_iter()
        .map(|p| {
            let mut h = vec![0u64; blocks << 16];
            parts.visit(p, |x| {
                let key = order_key(x);
                let block = block_of[(key >> 16) as usize] as usize;
                let l = (key & 0xffff) as usize;
                h[if block == 0 { l & 15 } else { block << 16 | l }] += 1;
            });
            h
        })
        .collect();
    // The wanted parts' counts added into the first part's (the other values' block aside).
    let (low, rest) = low.split_first_mut().expect("at least one part");
    rest.iter().for_each(|h| add(&mut low[1 << 16..], &h[1 << 16..]));
    Some(places.map(|(b, k)| {
        let j = wanted.iter().position(|&p| p == b as u32).expect("a wanted part");
        let (l, _) = bucket_of(&low[(j + 1) << 16..(j + 2) << 16], k);
        from_order_key((b as u32) << 16 | l as u32)
    }))
}

impl Normalization {
    /// The normalization of `data` (not empty, finite): center the lower median, scale the
    /// 99th minus the 1st percentile (order statistics ⌊q (n − 1)⌋), else the range, else 1
    /// (a constant image).
    pub fn of(data: &[f32]) -> Result<Normalization, GridError> {
        let n = data.len();
        let at = |q: f64| ((q * (n - 1) as f64).floor() as usize).min(n - 1);
        let [center, p99, p01] = order_statistics(data, [at(0.5), at(0.99), at(0.01)]);
        let (center, p99, p01) = (center as f64, p99 as f64, p01 as f64);
        let mut scale = p99 - p01;
        if scale.is_nan() || scale <= 0.0 {
            let (lo, hi) = data
                .par_iter()
                .fold(|| (f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)))
                .reduce(
                    || (f32::INFINITY, f32::NEG_INFINITY),
                    |(a, b), (c, d)| (a.min(c), b.max(d)),
                );
            scale = hi as f64 - lo as f64;
        }
        if !(scale > 0.0 && scale.is_finite()) {
            scale = 1.0;
        }
        Ok(Normalization { center, scale })
    }

    /// `(v − center) / scale`.
    #[inline]
    pub fn apply(&self, v: f64) -> f64 {
        (v - self.center) / self.scale
    }

    /// The inverse of [`Normalization::apply`].
    #[inline]
    pub fn back(&self, v: f64) -> f64 {
        v * self.scale + self.center
    }

    /// A threshold in normalised units; ±∞ stay infinite.
    pub fn threshold(&self, v: f32) -> f32 {
        if v.is_infinite() {
            v
        } else {
            self.apply(v as f64) as f32
        }
    }

    /// The image normalised (computed in `f64`, rounded once).
    pub fn image(&self, image: &Image) -> Image {
        let mut data = vec![0.0f32; image.len()];
        data.par_chunks_mut(1 << 14).zip(image.data.par_chunks(1 << 14)).for_each(|(o, i)| {
            for (o, &v) in o.iter_mut().zip(i) {
                *o = self.apply(v as f64) as f32;
            }
        });
        // Not `..image.clone()`: that copied the intensities on one thread only to drop
        // them. With it this took 9.1 ms on one thread and 7.8 ms on two for a 128³ image,
        // without it 4.8 and 2.5 ms (`levelset segment` of the snr2 blobs phantom,
        // threshold method; phase timers, minima of three runs; 2-core AMD EPYC,
        // 2026-11-28).
        let (dims, spacing, to_world) = (image.dims, image.spacing, image.to_world);
        Image { dims, spacing, data, to_world }
    }
}

/// The noise σ of `image` (white noise assumed): the median of |I[i−1] − 2I[i] + I[i+1]|
/// along every axis of at least 3 voxels, over the triplets that are not all equal (flat
/// padding and constant backgrounds say nothing of the noise), divided by 0.6745 √6
/// (the second difference of white noise has variance 6σ²; 0.6745 is the median of |N(0, 1)|).
/// 0 when no triplet varies.
pub(crate) fn noise_sigma(image: &Image) -> Result<f64, GridError> {
    let rows = image.dims[1] * image.dims[2];
    let per = rows.div_ceil(rayon::current_num_threads()).max(1);
    let samples = SecondDifferences { image, per };
    let median = order_statistics_of(&samples, |n| [(n - 1) / 2]);
    Ok(median.map_or(0.0, |[m]| m as f64 / (0.674_489_75 * 6f64.sqrt())))
}

/// The samples of [`noise_sigma`], computed where they are counted (two passes of the
/// order statistics) instead of stored: every second voxel along x, all rows (enough
/// samples, half the work), `per` rows a part. Stored (a 12 MB array for a 128³ image, in
/// vectors that grew per part) they took 23.8 ms on one thread and 15.0 ms on two; computed
/// twice, axis by axis along each row, 12.3 and 6.4 ms (timer around the call, minima of 5
/// runs of `levelset segment` of the second generator's blobs 128³, threshold; 2-core AMD
/// EPYC, 2026-11-30).
struct SecondDifferences<'a> {
    image: &'a Image,
    per: usize,
}

impl ValueParts for SecondDifferences<'_> {
    fn parts(&self) -> usize {
        (self.image.dims[1] * self.image.dims[2]).div_ceil(self.per)
    }
    fn visit(&self, part: usize, mut f: impl FnMut(f32)) {
        let [nx, ny, nz] = self.image.dims;
        let d = &self.image.data;
        let mut triplet = |a: f32, b: f32, c: f32| {
            if !(a == b && b == c) {
                f((a as f64 - 2.0 * b as f64 + c as f64).abs() as f32);
            }
        };
        // Axis by axis within a row (the order of the samples does not matter to their
        // order statistics): whether y and z have neighbours on both sides is the row's.
        for row in part * self.per..((part + 1) * self.per).min(ny * nz) {
            let (y, z) = (row % ny, row / ny);
            let line = &d[nx * row..nx * (row + 1)];
            if nx >= 3 {
                for x in (2..nx - 1).step_by(2) {
                    triplet(line[x - 1], line[x], line[x + 1]);
                }
            }
            for (n, at, stride) in [(ny, y, nx), (nz, z, nx * ny)] {
                if n >= 3 && at > 0 && at + 1 < n {
                    let (before, after) = (&d[nx * row - stride..], &d[nx * row + stride..]);
                    for x in (0..nx).step_by(2) {
                        triplet(before[x], line[x], after[x]);
                    }
                }
            }
        }
    }
}

/// The factor by which a Gaussian of `v` voxels along every smoothed axis (`axes` of
/// them) divides white noise's standard deviation: `(2√π v)^(−axes/2)` (∫G² over the
/// axes).
pub(crate) fn noise_factor(v: f64, axes: usize) -> f64 {
    (2.0 * std::f64::consts::PI.sqrt() * v).powf(-(axes as f64) / 2.0)
}

/// Candidate smoothing widths, voxels.
pub(crate) const SIGMA_STEPS: [f64; 9] = [0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0];

/// The smallest σ (voxels) of [`SIGMA_STEPS`] within `[lo, hi]` for which `ok(σ)` holds,
/// else `hi`.
pub(crate) fn smoothing_voxels(lo: f64, hi: f64, ok: impl Fn(f64) -> bool) -> f64 {
    SIGMA_STEPS.iter().copied().filter(|&v| v >= lo && v <= hi).find(|&v| ok(v)).unwrap_or(hi)
}

/// What rays from the seeds saw of the first edge they crossed.
#[derive(Clone, Debug, Default)]
pub(crate) struct EdgeProbe {
    /// Rays cast (that could meet an edge), and those that crossed one.
    pub rays: usize,
    /// The edge counts as found when at least 1/`share` of the rays crossed it: 4 from
    /// seeds inside the object ([`probe_edges`]).
    pub share: usize,
    /// Per edge-crossing ray: the contrast `2 (Ĩ(s*) − m)` at the gradient peak s* of the
    /// edge (the intensity halfway across a symmetric edge), and the peak gradient.
    pub contrasts: Vec<f64>,
    pub peaks: Vec<f64>,
}

impl EdgeProbe {
    /// At least 1/`share` of the rays crossed an edge (and one did).
    pub fn crossed(&self) -> bool {
        !self.peaks.is_empty() && self.peaks.len() * self.share >= self.rays
    }

    /// The edge's contrast, the median of |contrast| over the rays that crossed it, when
    /// enough did ([`Self::crossed`]).
    pub fn contrast(&self) -> Option<f64> {
        let abs: Vec<f64> = self.contrasts.iter().map(|c| c.abs()).collect();
        quantile(&abs, 0.5).filter(|_| self.crossed())
    }
}

/// Directions on the unit sphere (Fibonacci lattice), or in the xy plane for 2D.
fn directions(planar: bool) -> Vec<[f64; 3]> {
    if planar {
        let n = 48;
        return (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                [a.cos(), a.sin(), 0.0]
            })
            .collect();
    }
    let n = 128;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|k| {
            let z = 1.0 - (2.0 * k as f64 + 1.0) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * k as f64;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}

/// Trilinear interpolation of `image` at voxel coordinates `p` (inside the image).
fn trilinear(image: &Image, p: [f64; 3]) -> f64 {
    let mut i0 = [0usize; 3];
    let mut f = [0.0f64; 3];
    for a in 0..3 {
        let n = image.dims[a];
        let x = p[a].clamp(0.0, (n - 1) as f64);
        let b = (x.floor() as usize).min(n.saturating_sub(2));
        i0[a] = b;
        f[a] = if n > 1 { x - b as f64 } else { 0.0 };
    }
    let mut acc = 0.0;
    for corner in 0..8 {
        let mut w = 1.0;
        let mut idx = [0usize; 3];
        for a in 0..3 {
            let bit = (corner >> a) & 1;
            if bit == 1 && image.dims[a] == 1 {
                w = 0.0;
            }
            idx[a] = i0[a] + bit;
            w *= if bit == 1 { f[a] } else { 1.0 - f[a] };
        }
        if w != 0.0 {
            acc += w * image.data[image.index(idx[0], idx[1], idx[2])] as f64;
        }
    }
    acc
}

/// Casts rays from every origin (voxel coordinates) outward, half a voxel of the smallest
/// spacing a step, through `smoothed` (Ĩ) and `grad` (|∇Ĩ|), and records, per ray, the
/// first edge: the first point where |Ĩ − m| exceeds `tau` (m the median intensity of the
/// initial region), then the largest gradient within `reach` (world units) on either side
/// of it, and the contrast 2 (Ĩ − m) at that peak. Rays that leave the image first record
/// nothing.
pub(crate) fn probe_edges(
    smoothed: &Image,
    grad: &Image,
    origins: &[[f64; 3]],
    m: f64,
    tau: f64,
    reach: f64,
) -> EdgeProbe {
    let planar = smoothed.is_2d();
    let dirs = directions(planar);
    let s = smoothed.spacing;
    let h = s.iter().copied().fold(f64::INFINITY, f64::min);
    let step = 0.5 * h;
    let inside = |p: [f64; 3]| (0..3).all(|a| p[a] >= 0.0 && p[a] <= (smoothed.dims[a] - 1) as f64);
    let results: Vec<Option<(f64, f64)>> = origins
        .par_iter()
        .flat_map_iter(|o| dirs.iter().map(move |d| (*o, *d)))
        .map(|(o, d)| {
            // p(t) = o + t d / s (voxel coordinates), t in world units.
            let at = |t: f64| -> [f64; 3] { std::array::from_fn(|a| o[a] + t * d[a] / s[a]) };
            let mut t = 0.0;
            let cross = loop {
                let p = at(t);
                if !inside(p) {
                    return None;
                }
                if (trilinear(smoothed, p) - m).abs() > tau {
                    break t;
                }
                t += step;
            };
            let (mut best, mut best_t) = (f64::NEG_INFINITY, cross);
            let mut u = (cross - reach).max(0.0);
            while u <= cross + reach {
                let p = at(u);
                if inside(p) {
                    let g = trilinear(grad, p);
                    if g > best {
                        (best, best_t) = (g, u);
                    }
                }
                u += step;
            }
            let c = 2.0 * (trilinear(smoothed, at(best_t)) - m);
            Some((c, best))
        })
        .collect();
    let mut probe = EdgeProbe { rays: results.len(), share: 4, ..Default::default() };
    for (c, g) in results.into_iter().flatten() {
        probe.contrasts.push(c);
        probe.peaks.push(g);
    }
    probe
}

/// The `q`-quantile (lower order statistic) of `v`, `None` when empty.
pub(crate) fn quantile(v: &[f64], q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut w = v.to_vec();
    w.sort_by(f64::total_cmp);
    Some(w[((q * (w.len() - 1) as f64).floor() as usize).min(w.len() - 1)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::image::IDENTITY;

    /// The counting selection against a sort, over values with both signs, signed zeros,
    /// infinities, many repeats (a constant background) and subnormals, at every rank of a
    /// small set and at chosen ranks of a large one (several parallel parts).
    #[test]
    fn order_statistics_equal_a_sort() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut v: Vec<f32> = (0..300_000)
            .map(|i| match i % 7 {
                0 => 0.0,
                1 => -0.0,
                2 => f32::from_bits(next() as u32 & 0x007f_ffff),
                3 => 250.0,
                _ => (next() % 2_000_000) as f32 / 997.0 - 1000.0,
            })
            .collect();
        v.extend([f32::INFINITY, f32::NEG_INFINITY, f32::MIN_POSITIVE, -f32::MAX]);
        let mut sorted = v.clone();
        sorted.sort_by(f32::total_cmp);
        let n = v.len();
        let ks = [0, 1, n / 100, n / 7, n / 2, (n - 1) / 2, n - 2, n - 1, n + 5];
        let got = order_statistics(&v, ks);
        for (k, g) in ks.iter().zip(got) {
            let want = sorted[(*k).min(n - 1)];
            assert_eq!(g.to_bits(), want.to_bits(), "rank {k}");
        }
        // Uneven parts, empty ones among them, in any split: the same values.
        let (a, rest) = v.split_at(7);
        let (b, c) = rest.split_at(200_000);
        for parts in [vec![a, &[], b, c], vec![&v[..]], vec![c, &[], a, b, &[]]] {
            let got = order_statistics_of_parts(&parts, ks);
            for (k, g) in ks.iter().zip(got) {
                assert_eq!(g.to_bits(), sorted[(*k).min(n - 1)].to_bits(), "rank {k}");
            }
        }
        // Below the copy's bound, a copy's selection and the counting agree with a sort
        // (every 37th rank and the last).
        let few = &v[..SELECT_FROM_COPY];
        let mut s = few.to_vec();
        s.sort_by(f32::total_cmp);
        for k in (0..few.len()).step_by(37).chain([few.len() - 1]) {
            let copied = order_statistics_of_parts(&[few], [k])[0];
            let counted = order_statistics_of(&[few][..], |_| [k]).unwrap()[0];
            assert_eq!((copied.to_bits(), counted.to_bits()), (s[k].to_bits(), s[k].to_bits()));
        }
        let small = &v[..40];
        let mut s = small.to_vec();
        s.sort_by(f32::total_cmp);
        for (k, want) in s.iter().enumerate() {
            assert_eq!(order_statistics(small, [k])[0].to_bits(), want.to_bits(), "rank {k}");
        }
    }

    #[test]
    fn normalization_is_exact_under_exact_affine_maps() {
        // Values k/1024: 1000 v − 500 is exact in f32.
        let data: Vec<f32> = (0..5000).map(|i| ((i * 7919) % 4096) as f32 / 1024.0).collect();
        let scaled: Vec<f32> = data.iter().map(|&v| 1000.0 * v - 500.0).collect();
        let a = Normalization::of(&data).unwrap();
        let b = Normalization::of(&scaled).unwrap();
        for (&x, &y) in data.iter().zip(&scaled) {
            assert_eq!((a.apply(x as f64) as f32).to_bits(), (b.apply(y as f64) as f32).to_bits());
        }
        assert_eq!(Normalization::of(&[3.0; 10]).unwrap().scale, 1.0);
    }

    #[test]
    fn noise_sigma_of_white_noise() {
        let dims = [64, 64, 16];
        let mut rng = crate::segment::phantom::SplitMix64::new(5);
        let mut data = Vec::with_capacity(64 * 64 * 16);
        while data.len() < 64 * 64 * 16 {
            let (a, b) = rng.normal_pair();
            data.push(10.0 + 2.0 * a as f32);
            data.push(10.0 + 2.0 * b as f32);
        }
        let im = Image { dims, spacing: [1.0; 3], data, to_world: IDENTITY };
        let s = noise_sigma(&im).unwrap();
        assert!((s - 2.0).abs() < 0.1, "{s}");
        let flat = Image { data: vec![1.0; 64 * 64 * 16], ..im };
        assert_eq!(noise_sigma(&flat).unwrap(), 0.0);
    }

    /// The samples counted where they are made are the textbook ones: the median over a
    /// sort of every second difference (every second voxel along x, each axis of at least
    /// three voxels with a neighbour on both sides, varying triplets only), on odd and
    /// even sizes, thin axes, a 2D image and flat patches, in one and several parts.
    #[test]
    fn noise_sigma_is_the_median_of_every_sample() {
        let mut rng = crate::segment::phantom::SplitMix64::new(11);
        for dims in [[7, 5, 4], [8, 3, 9], [2, 6, 5], [9, 9, 1], [1, 1, 40], [33, 17, 2]] {
            let data: Vec<f32> = (0..dims.iter().product::<usize>())
                .map(|i| if i % 11 < 4 { 3.0 } else { rng.normal_pair().0 as f32 })
                .collect();
            let im = Image { dims, spacing: [1.0; 3], data, to_world: IDENTITY };
            let [nx, ny, nz] = dims;
            let mut all = Vec::new();
            for z in 0..nz {
                for y in 0..ny {
                    for x in (0..nx).step_by(2) {
                        let i = x + nx * (y + ny * z);
                        for (axis, stride) in [(0, 1), (1, nx), (2, nx * ny)] {
                            let at = [x, y, z][axis];
                            if dims[axis] < 3 || at == 0 || at + 1 >= dims[axis] {
                                continue;
                            }
                            let (a, b, c) = (im.data[i - stride], im.data[i], im.data[i + stride]);
                            if !(a == b && b == c) {
                                all.push((a as f64 - 2.0 * b as f64 + c as f64).abs() as f32);
                            }
                        }
                    }
                }
            }
            all.sort_by(f32::total_cmp);
            let want = all
                .get(all.len().saturating_sub(1) / 2)
                .map_or(0.0, |&m| m as f64 / (0.674_489_75 * 6f64.sqrt()));
            for per in [1, 2, 5, ny * nz] {
                let samples = SecondDifferences { image: &im, per };
                let got = order_statistics_of(&samples, |n| [(n - 1) / 2])
                    .map_or(0.0, |[m]| m as f64 / (0.674_489_75 * 6f64.sqrt()));
                assert_eq!(got.to_bits(), want.to_bits(), "{dims:?}, {per} rows a part");
            }
            assert_eq!(noise_sigma(&im).unwrap().to_bits(), want.to_bits(), "{dims:?}");
        }
    }
}
