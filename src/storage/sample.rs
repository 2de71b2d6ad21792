//! Culled sampling of a signed distance function into the 4³ tiles of its narrow band.
//!
//! The band of a surface is a thin shell, so a dense pass over the bounding box wastes
//! almost all of its evaluations. [`sample_band_tiles`] instead subdivides the box into
//! tile-aligned power-of-two blocks and discards a whole block with one evaluation when
//! the Lipschitz bound proves that no voxel in it can be a band voxel; only the tiles that
//! survive down to single-tile size are evaluated voxel by voxel. The number of
//! evaluations therefore scales with the band, not with the box.
//!
//! # Conventions
//! * φ < 0 inside, in world units; a *band voxel* has `|φ| < γ`,
//!   `γ = half_width · voxel_size` ([`GridSpec::gamma`]); stored values are clamped to
//!   `[−γ, γ]`.
//! * Tile `t` holds voxels `4t ..= 4t + 3` on each axis (tile = voxel `>> 2`, floor
//!   division); inside a tile, voxel `(x, y, z)` sits at
//!   `(x − 4tx) + 4 (y − 4ty) + 16 (z − 4tz)`, x fastest.
//! * Results are sorted in [`Coord`] order (z, then y, then x) and identical for any
//!   number of threads.
//!
//! ```
//! use sparse_levelset::{storage::sample, storage::shapes::Shape, GridSpec, Coord};
//!
//! let spec = GridSpec::default();
//! let sphere = Shape::Sphere { center: [0.0; 3], radius: 10.0 };
//! let tiles = sample::sample_shape_tiles(&sphere, &spec).unwrap();
//! // Every stored value is clamped to ±γ and the voxel (10, 0, 0) is on the surface.
//! let (_, values) = tiles.iter().find(|(t, _)| *t == Coord::new(2, 0, 0)).unwrap();
//! assert_eq!(values[2], 0.0); // x = 10 = 4·2 + 2, y = z = 0
//! assert!(tiles.iter().all(|(_, v)| v.iter().all(|x| x.abs() <= 3.0)));
//! ```

use crate::coord::Coord;
use crate::grid::{GridError, GridSpec};
use crate::storage::shapes::Shape;
use rayon::prelude::*;

/// Voxels per tile edge.
const TILE: i64 = 4;
/// log2 of the edge, in tiles, of the smallest top-level block (16 tiles = 64 voxels).
const MIN_TOP_LOG2: u32 = 4;
/// Upper bound on the number of top-level blocks; bigger boxes get bigger blocks.
const MAX_TOP_BLOCKS: i64 = 4096;
/// Blocks at least this many tiles wide (log2) split their children across threads.
const PAR_LOG2: u32 = 2;
/// Relative safety factor of the culling bound (≈ 8 f32 ulps): covers the rounding of
/// φ to f32 at the block centre and at the voxel, and of the bound itself.
const SAFETY: f64 = 1e-6;

/// Every 4³ tile in the voxel box `[lo, hi]` that contains a voxel with `|φ| < γ`, with
/// its 64 values clamped to `[−γ, γ]`, sorted by tile coordinate in [`Coord`] order,
/// without duplicates.
///
/// * `phi(v)` is the signed distance (φ < 0 inside, world units) at the centre of voxel
///   `v`; it may be called at any voxel of a tile that meets the box, including voxels
///   just outside `[lo, hi]`.
/// * `lipschitz` is `L` in `|φ(a) − φ(b)| ≤ L · voxel_size · |a − b|` (1 for an exact
///   distance, see [`Shape::lipschitz`]); a wrong `L` silently loses band tiles.
/// * `[lo, hi]` is an inclusive voxel box that must contain the whole band (see
///   [`band_voxel_box`]); tiles are examined when they meet the box, and then all of
///   their 64 voxels count.
///
/// Blocks whose centre value satisfies `|φ(c)| − L · r ≥ γ` (with `r` the largest world
/// distance from the centre voxel to a voxel of the block, plus a relative safety margin
/// of 1e-6) are skipped. Work is spread with rayon; the output does not depend on the
/// number of threads.
///
/// # Errors
/// * [`GridError::InvalidParameter`]: `lipschitz` negative or not finite, `lo > hi` on
///   an axis, or an invalid `spec` (see [`GridSpec::new`]);
/// * [`GridError::NaN`]: `phi` returned NaN at an evaluated voxel; the coordinate is
///   the first such voxel in the (deterministic) traversal order. `±∞` is accepted and
///   clamped.
pub fn sample_band_tiles<F: Fn(Coord) -> f32 + Sync>(
    phi: F,
    lipschitz: f32,
    lo: Coord,
    hi: Coord,
    spec: &GridSpec,
) -> Result<Vec<(Coord, [f32; 64])>, GridError> {
    let spec = GridSpec::new(spec.voxel_size, spec.origin, spec.half_width)?;
    if !(lipschitz.is_finite() && lipschitz >= 0.0) {
        return Err(GridError::InvalidParameter(format!(
            "Lipschitz constant must be finite and >= 0, got {lipschitz}"
        )));
    }
    if lo.x > hi.x || lo.y > hi.y || lo.z > hi.z {
        return Err(GridError::InvalidParameter(format!(
            "sampling box is empty: lo {lo} is not <= hi {hi} on every axis"
        )));
    }
    let ctx = Ctx {
        phi: &phi,
        tlo: [(lo.x >> 2) as i64, (lo.y >> 2) as i64, (lo.z >> 2) as i64],
        thi: [(hi.x >> 2) as i64, (hi.y >> 2) as i64, (hi.z >> 2) as i64],
        gamma: spec.gamma(),
        // Lipschitz constant per voxel of distance, with the safety margin folded in.
        l_voxel: lipschitz as f64 * spec.voxel_size as f64 * (1.0 + SAFETY),
        gamma_bound: spec.gamma() as f64 * (1.0 + SAFETY),
    };

    // Top-level blocks: aligned, 2^k tiles wide, as few as needed to stay under
    // MAX_TOP_BLOCKS (a function of the box only, so the traversal is deterministic).
    let mut k = MIN_TOP_LOG2;
    let top = loop {
        let lo_b: [i64; 3] = std::array::from_fn(|a| ctx.tlo[a] >> k);
        let hi_b: [i64; 3] = std::array::from_fn(|a| ctx.thi[a] >> k);
        // Per axis at most 2^30 blocks, so the product fits in i128.
        let count: i128 = (0..3).map(|a| (hi_b[a] - lo_b[a] + 1) as i128).product();
        if count <= MAX_TOP_BLOCKS as i128 {
            let mut blocks = Vec::with_capacity(count as usize);
            for bz in lo_b[2]..=hi_b[2] {
                for by in lo_b[1]..=hi_b[1] {
                    for bx in lo_b[0]..=hi_b[0] {
                        blocks.push(Block { start: [bx << k, by << k, bz << k], log2: k });
                    }
                }
            }
            break blocks;
        }
        k += 1;
    };

    let parts: Vec<Result<Tiles, GridError>> = top
        .par_iter()
        .map(|b| {
            let mut out = Vec::new();
            ctx.visit(*b, &mut out).map(|()| out)
        })
        .collect();
    let mut tiles = Vec::new();
    for p in parts {
        tiles.extend(p?);
    }
    // Blocks are visited depth first (a Morton-like order), so sort into Coord order.
    // Keys are unique (blocks are disjoint), so the result does not depend on the sort.
    tiles.par_sort_unstable_by_key(|(t, _)| t.key());
    debug_assert!(tiles.windows(2).all(|w| w[0].0 < w[1].0));
    Ok(tiles)
}

/// [`sample_band_tiles`] for an analytic shape: validates it, takes the box from
/// [`band_voxel_box`] and evaluates `shape.sdf` at `spec.world(voxel)`.
pub fn sample_shape_tiles(
    shape: &Shape,
    spec: &GridSpec,
) -> Result<Vec<(Coord, [f32; 64])>, GridError> {
    shape.validate()?;
    let (min, max) = shape.bounds();
    let (lo, hi) = band_voxel_box(min, max, spec)?;
    let lipschitz = shape.lipschitz() as f32;
    sample_band_tiles(|c| shape.sdf(spec.world(c)) as f32, lipschitz, lo, hi, spec)
}

/// The inclusive voxel box that contains every band voxel of a shape whose interior lies
/// in the world box `[min, max]`: the voxels within `γ` plus one voxel of the box, for an
/// exact (1-Lipschitz) distance.
///
/// # Errors
/// [`GridError::InvalidParameter`] when the box is not finite, inverted, or leaves the
/// `i32` voxel range, or `spec` is invalid.
pub fn band_voxel_box(
    min: [f64; 3],
    max: [f64; 3],
    spec: &GridSpec,
) -> Result<(Coord, Coord), GridError> {
    let spec = GridSpec::new(spec.voxel_size, spec.origin, spec.half_width)?;
    let h = spec.voxel_size as f64;
    let g = spec.gamma() as f64;
    let mut lo = [0i32; 3];
    let mut hi = [0i32; 3];
    for a in 0..3 {
        if !(min[a].is_finite() && max[a].is_finite() && min[a] <= max[a]) {
            return Err(GridError::InvalidParameter(format!(
                "world box {min:?}..{max:?} must be finite and not inverted"
            )));
        }
        let l = ((min[a] - g - spec.origin[a]) / h).floor() - 1.0;
        let u = ((max[a] + g - spec.origin[a]) / h).ceil() + 1.0;
        let range = i32::MIN as f64..=i32::MAX as f64;
        if !(range.contains(&l) && range.contains(&u)) {
            return Err(GridError::InvalidParameter(format!(
                "world box {min:?}..{max:?} with its band leaves the i32 voxel range \
                 (voxel size {h}, origin {:?})",
                spec.origin
            )));
        }
        lo[a] = l as i32;
        hi[a] = u as i32;
    }
    Ok((Coord::new(lo[0], lo[1], lo[2]), Coord::new(hi[0], hi[1], hi[2])))
}

/// Band tiles with their values, as returned by [`sample_band_tiles`].
type Tiles = Vec<(Coord, [f32; 64])>;

/// An aligned cube of `2^log2` tiles per edge starting at tile `start`.
#[derive(Clone, Copy, Debug)]
struct Block {
    start: [i64; 3],
    log2: u32,
}

struct Ctx<'a, F> {
    phi: &'a F,
    /// Inclusive tile range of the box.
    tlo: [i64; 3],
    thi: [i64; 3],
    gamma: f32,
    l_voxel: f64,
    gamma_bound: f64,
}

impl<F: Fn(Coord) -> f32 + Sync> Ctx<'_, F> {
    /// Evaluates φ, turning NaN into an error.
    #[inline]
    fn eval(&self, c: Coord) -> Result<f32, GridError> {
        let v = (self.phi)(c);
        if v.is_nan() {
            Err(GridError::NaN { coord: c })
        } else {
            Ok(v)
        }
    }

    /// Appends the band tiles of `b ∩ box` to `out` in depth-first order.
    fn visit(&self, b: Block, out: &mut Tiles) -> Result<(), GridError> {
        let size = 1i64 << b.log2;
        // Clip to the box: only tiles in [tlo, thi] are ever output. Non-empty here, all
        // tiles inside the i32 tile range, so every voxel below is a valid Coord.
        let a: [i64; 3] = std::array::from_fn(|i| b.start[i].max(self.tlo[i]));
        let z: [i64; 3] = std::array::from_fn(|i| (b.start[i] + size - 1).min(self.thi[i]));
        debug_assert!((0..3).all(|i| a[i] <= z[i]));

        // Centre voxel of the clipped voxel range [4a, 4z + 3]: 2a + 2z + 1. Its largest
        // offset to a voxel of the range is 2 n, n = z - a + 1 tiles, on each axis.
        let centre = Coord::new(
            (2 * a[0] + 2 * z[0] + 1) as i32,
            (2 * a[1] + 2 * z[1] + 1) as i32,
            (2 * a[2] + 2 * z[2] + 1) as i32,
        );
        let reach: [f64; 3] = std::array::from_fn(|i| (2 * (z[i] - a[i] + 1)) as f64);
        let r = (reach[0] * reach[0] + reach[1] * reach[1] + reach[2] * reach[2]).sqrt();
        let vc = self.eval(centre)?;
        // |φ(v)| ≥ |φ(c)| − L·r ≥ γ for every voxel v of the block: no band voxel.
        if (vc.abs() as f64) - self.l_voxel * r >= self.gamma_bound {
            return Ok(());
        }

        if b.log2 == 0 {
            return self.tile(Coord::new(a[0] as i32, a[1] as i32, a[2] as i32), centre, vc, out);
        }

        let half = size / 2;
        let children = (0..8).filter_map(|n: i64| {
            let start = [
                b.start[0] + (n & 1) * half,
                b.start[1] + ((n >> 1) & 1) * half,
                b.start[2] + ((n >> 2) & 1) * half,
            ];
            // Keep children that meet the box.
            let meets = (0..3).all(|i| start[i] <= self.thi[i] && start[i] + half > self.tlo[i]);
            meets.then_some(Block { start, log2: b.log2 - 1 })
        });
        if b.log2 >= PAR_LOG2 {
            let children: Vec<Block> = children.collect();
            let parts: Vec<_> = children
                .par_iter()
                .map(|&c| {
                    let mut v = Vec::new();
                    self.visit(c, &mut v).map(|()| v)
                })
                .collect();
            // The first error in child order: the same one a sequential visit reports.
            for p in parts {
                out.extend(p?);
            }
        } else {
            for c in children {
                self.visit(c, out)?;
            }
        }
        Ok(())
    }

    /// Evaluates tile `t` (the centre voxel's value `vc` is already known) and keeps it
    /// when one of its voxels is a band voxel.
    fn tile(&self, t: Coord, centre: Coord, vc: f32, out: &mut Tiles) -> Result<(), GridError> {
        let base = [t.x as i64 * TILE, t.y as i64 * TILE, t.z as i64 * TILE];
        let mut values = [0.0f32; 64];
        let mut band = false;
        for (n, v) in values.iter_mut().enumerate() {
            let n = n as i64;
            // Within the tile, so within i32.
            let c = Coord::new(
                (base[0] + (n & 3)) as i32,
                (base[1] + ((n >> 2) & 3)) as i32,
                (base[2] + (n >> 4)) as i32,
            );
            let x = if c == centre { vc } else { self.eval(c)? };
            band |= x.abs() < self.gamma;
            *v = x.clamp(-self.gamma, self.gamma);
        }
        if band {
            out.push((t, values));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Every tile of the box, evaluated densely: the reference.
    fn brute_force<F: Fn(Coord) -> f32>(
        phi: F,
        lo: Coord,
        hi: Coord,
        spec: &GridSpec,
    ) -> Vec<(Coord, [f32; 64])> {
        let g = spec.gamma();
        let mut out = Vec::new();
        for tz in (lo.z >> 2)..=(hi.z >> 2) {
            for ty in (lo.y >> 2)..=(hi.y >> 2) {
                for tx in (lo.x >> 2)..=(hi.x >> 2) {
                    let mut v = [0.0f32; 64];
                    let mut band = false;
                    for (n, x) in v.iter_mut().enumerate() {
                        let c = Coord::new(
                            4 * tx + (n as i32 & 3),
                            4 * ty + ((n as i32 >> 2) & 3),
                            4 * tz + (n as i32 >> 4),
                        );
                        let p = phi(c);
                        band |= p.abs() < g;
                        *x = p.clamp(-g, g);
                    }
                    if band {
                        out.push((Coord::new(tx, ty, tz), v));
                    }
                }
            }
        }
        out
    }

    fn random_shape(rng: &mut fastrand::Rng, c: [f64; 3], size: f64) -> Shape {
        let r = |rng: &mut fastrand::Rng| size * (0.3 + 0.7 * rng.f64());
        let jitter = |rng: &mut fastrand::Rng| {
            [c[0] + rng.f64() * 3.0, c[1] - rng.f64() * 3.0, c[2] + rng.f64()]
        };
        match rng.usize(0..6) {
            0 => Shape::Sphere { center: jitter(rng), radius: r(rng) },
            1 => {
                let major = r(rng);
                Shape::Torus {
                    center: jitter(rng),
                    major_radius: major,
                    minor_radius: major * (0.2 + 0.5 * rng.f64()),
                }
            }
            2 => Shape::Box { center: jitter(rng), half_extents: [r(rng), r(rng), r(rng)] },
            3 => Shape::Ellipsoid { center: jitter(rng), radii: [r(rng), r(rng), r(rng)] },
            4 => Shape::spiral_default(jitter(rng), 2.0 * size, size),
            _ => Shape::Union(vec![
                Shape::Sphere { center: jitter(rng), radius: r(rng) },
                Shape::Box { center: jitter(rng), half_extents: [r(rng), r(rng), r(rng)] },
            ]),
        }
    }

    /// Culled sampling equals the dense evaluation: same tiles, same values.
    #[test]
    fn matches_brute_force_on_random_shapes() {
        let mut rng = fastrand::Rng::with_seed(2024);
        for case in 0..40 {
            let voxel = [1.0f32, 0.5, 0.37, 1.7][case % 4];
            let half_width = [3.0f32, 1.25, 2.5, 4.0][(case / 4) % 4];
            let origin = [rng.f64() * 10.0 - 5.0, rng.f64() * 10.0 - 5.0, rng.f64() * 10.0 - 5.0];
            let spec = GridSpec::new(voxel, origin, half_width).unwrap();
            // Centres at negative and positive coordinates.
            let c = [rng.f64() * 80.0 - 40.0, rng.f64() * 80.0 - 40.0, rng.f64() * 80.0 - 40.0];
            let size = 4.0 + 6.0 * rng.f64();
            let shape = random_shape(&mut rng, c, size);
            shape.validate().unwrap();
            let (min, max) = shape.bounds();
            let (lo, hi) = band_voxel_box(min, max, &spec).unwrap();
            let phi = |v: Coord| shape.sdf(spec.world(v)) as f32;
            let got = sample_band_tiles(phi, 1.0, lo, hi, &spec).unwrap();
            let want = brute_force(phi, lo, hi, &spec);
            assert!(!want.is_empty(), "case {case}");
            assert_eq!(got.len(), want.len(), "case {case}: {shape:?}");
            for (g, w) in got.iter().zip(&want) {
                assert_eq!(g.0, w.0, "case {case}");
                assert_eq!(
                    g.1.map(f32::to_bits),
                    w.1.map(f32::to_bits),
                    "case {case} tile {}",
                    g.0
                );
            }
            assert_eq!(sample_shape_tiles(&shape, &spec).unwrap(), got);
        }
    }

    /// The evaluation count follows the band, not the box.
    #[test]
    fn evaluations_scale_with_the_band() {
        let spec = GridSpec::default();
        let sphere = Shape::Sphere { center: [224.5, 224.5, 224.5], radius: 200.0 };
        let count = AtomicUsize::new(0);
        let phi = |c: Coord| {
            count.fetch_add(1, Ordering::Relaxed);
            sphere.sdf(spec.world(c)) as f32
        };
        let tiles =
            sample_band_tiles(phi, 1.0, Coord::new(0, 0, 0), Coord::new(449, 449, 449), &spec)
                .unwrap();
        let evals = count.load(Ordering::Relaxed);
        let ratio = evals as f64 / (tiles.len() * 64) as f64;
        eprintln!(
            "sphere r=200 in 450³: {} band tiles, {evals} evaluations, ratio {ratio:.3} (box: {} voxels)",
            tiles.len(),
            450usize.pow(3)
        );
        assert!(tiles.len() > 10_000);
        assert!(ratio < 10.0, "ratio {ratio}");
        // Every band voxel of the sphere is in a returned tile: check a sample of them.
        let set: std::collections::HashSet<Coord> = tiles.iter().map(|t| t.0).collect();
        for z in (0..450).step_by(7) {
            for y in (0..450).step_by(5) {
                for x in 0..450 {
                    let c = Coord::new(x, y, z);
                    if (sphere.sdf(spec.world(c)) as f32).abs() < 3.0 {
                        assert!(set.contains(&Coord::new(x >> 2, y >> 2, z >> 2)), "{c}");
                    }
                }
            }
        }
    }

    #[test]
    fn identical_for_any_thread_count() {
        let spec = GridSpec::new(0.5, [-3.0, 1.0, 2.0], 3.0).unwrap();
        let shape = Shape::Union(vec![
            Shape::spiral_default([0.0, 0.0, 0.0], 25.0, 20.0),
            Shape::Torus { center: [10.0, -20.0, 5.0], major_radius: 8.0, minor_radius: 2.0 },
        ]);
        let run = |n| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
            pool.install(|| sample_shape_tiles(&shape, &spec).unwrap())
        };
        let one = run(1);
        assert!(!one.is_empty());
        assert_eq!(one, run(3));
        assert_eq!(one, run(8));
    }

    /// Boxes at the ends of the i32 range: no overflow, still correct.
    #[test]
    fn coordinates_near_i32_limits() {
        let spec = GridSpec::default();
        for (cx, cy, cz) in [
            (i32::MAX as f64 - 6.0, i32::MAX as f64 - 6.0, i32::MAX as f64 - 6.0),
            (i32::MIN as f64 + 5.5, i32::MIN as f64 + 7.0, 0.0),
            (i32::MAX as f64 - 3.0, i32::MIN as f64 + 2.0, i32::MAX as f64),
        ] {
            // φ in voxel units straight from the integer coordinates (world positions this
            // far out would lose the precision the test needs only in f32).
            let r = 5.0;
            let phi = |c: Coord| {
                let d = [c.x as f64 - cx, c.y as f64 - cy, c.z as f64 - cz];
                ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - r) as f32
            };
            let clamp = |v: f64| v.clamp(i32::MIN as f64, i32::MAX as f64) as i32;
            let lo = Coord::new(clamp(cx - 10.0), clamp(cy - 10.0), clamp(cz - 10.0));
            let hi = Coord::new(clamp(cx + 10.0), clamp(cy + 10.0), clamp(cz + 10.0));
            let got = sample_band_tiles(phi, 1.0, lo, hi, &spec).unwrap();
            assert!(!got.is_empty());
            assert_eq!(got, brute_force(phi, lo, hi, &spec));
        }
        // The whole i32 range as a box, with a small sphere in it: culling keeps it cheap.
        let count = AtomicUsize::new(0);
        let phi = |c: Coord| {
            count.fetch_add(1, Ordering::Relaxed);
            let d = [c.x as f64 - 1000.0, c.y as f64 + 3.0, c.z as f64];
            ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - 6.0) as f32
        };
        let min = Coord::new(i32::MIN, i32::MIN, i32::MIN);
        let max = Coord::new(i32::MAX, i32::MAX, i32::MAX);
        let got = sample_band_tiles(phi, 1.0, min, max, &spec).unwrap();
        let lo = Coord::new(980, -23, -20);
        let hi = Coord::new(1020, 17, 20);
        assert_eq!(got, brute_force(phi, lo, hi, &spec));
        assert!(count.load(Ordering::Relaxed) < 2_000_000, "{}", count.load(Ordering::Relaxed));
    }

    #[test]
    fn errors() {
        let spec = GridSpec::default();
        let o = Coord::new(0, 0, 0);
        let h = Coord::new(20, 20, 20);
        let sphere = |c: Coord| ((c.x * c.x + c.y * c.y + c.z * c.z) as f32).sqrt() - 10.0;
        for l in [-1.0, f32::NAN, f32::INFINITY] {
            assert!(matches!(
                sample_band_tiles(sphere, l, o, h, &spec),
                Err(GridError::InvalidParameter(_))
            ));
        }
        assert!(matches!(
            sample_band_tiles(sphere, 1.0, h, o, &spec),
            Err(GridError::InvalidParameter(_))
        ));
        let bad = GridSpec { voxel_size: 0.0, ..spec };
        assert!(matches!(
            sample_band_tiles(sphere, 1.0, o, h, &bad),
            Err(GridError::InvalidParameter(_))
        ));
        // NaN in the band, deterministically reported.
        let nan_at = Coord::new(10, 1, 2);
        let phi = |c: Coord| if c == nan_at { f32::NAN } else { sphere(c) };
        assert_eq!(sample_band_tiles(phi, 1.0, o, h, &spec), Err(GridError::NaN { coord: nan_at }));
        // ±inf is accepted and clamped (a far-away value).
        let phi = |c: Coord| if c == nan_at { f32::INFINITY } else { sphere(c) };
        let tiles = sample_band_tiles(phi, 1.0, o, h, &spec).unwrap();
        let t = tiles.iter().find(|t| t.0 == Coord::new(2, 0, 0)).unwrap();
        assert_eq!(t.1[2 + 4 + 16 * 2], 3.0);
        // Box helpers.
        assert!(band_voxel_box([0.0; 3], [f64::NAN, 0.0, 0.0], &spec).is_err());
        assert!(band_voxel_box([0.0; 3], [3e9, 0.0, 0.0], &spec).is_err());
        assert!(band_voxel_box([1.0; 3], [0.0; 3], &spec).is_err());
        assert_eq!(
            band_voxel_box([-1.5, 0.0, 2.0], [1.5, 0.0, 2.0], &spec).unwrap(),
            (Coord::new(-6, -4, -2), Coord::new(6, 4, 6))
        );
    }

    /// Tile-local layout: x fastest, floor division for negative coordinates.
    #[test]
    fn tile_layout_and_negative_coordinates() {
        let spec = GridSpec::new(1.0, [0.0; 3], 100.0).unwrap();
        // φ encodes the voxel so every value is distinguishable; all |φ| < γ = 100.
        let phi = |c: Coord| (c.x + 10 * c.y + 50 * c.z) as f32 * 0.01;
        let tiles =
            sample_band_tiles(phi, 1.0, Coord::new(-5, -1, -4), Coord::new(-5, -1, -4), &spec)
                .unwrap();
        assert_eq!(tiles.len(), 1);
        let (t, v) = tiles[0];
        assert_eq!(t, Coord::new(-2, -1, -1));
        for n in 0..64i32 {
            let c = Coord::new(-8 + (n & 3), -4 + ((n >> 2) & 3), -4 + (n >> 4));
            assert_eq!(v[n as usize], phi(c));
        }
    }
}
