//! Layer 1 of the test plan: every kernel at every lane width against the scalar `f32`
//! instantiation, lane by lane, on edge values (±0, ±γ, tiny, subnormal, huge, ±∞, NaN,
//! flat regions) and random values; and the three feeds (dense block, padded tile, DT-Grid
//! point windows) against each other.
//!
//! Tolerance: **bitwise** (abs 0 + rel 0; any NaN equals any NaN). `Lane` guarantees the
//! same IEEE operation sequence in every lane type, including whether `mul_add` is fused
//! at a level (`Level::fused`), so no rounding can differ; a tolerance would only hide a
//! bug. The tile tests also run every lane kind at every instruction-set level the CPU has.

// Index loops compare several arrays lane by lane; they read better than zipped iterators.
#![allow(clippy::needless_range_loop)]

use crate::common;

use crate::common::{for_lanes, for_simd_lanes, same_bits, value, Fill, Rng, FILLS, GAMMA};
use levelset_kernels::curvature::{curvature_speed, mean_curvature};
use levelset_kernels::diff::{central_norm, diff_central, diff_minus, diff_plus};
use levelset_kernels::speed::{kappa_bar_integrands, smoothed_delta, smoothed_sign};
use levelset_kernels::weno::weno5_one_sided;
use levelset_kernels::{
    box27_index, box_far39_index, dispatch_at, star19_index, AdvectionRate, Axis, BoxFarWindow,
    BoxStarWindow, BoxWindow, DenseBlock, Eq3Rate, Euler, Lane, LaneFn, LaneKind, Level, Rk3,
    Rk3Blend, Rk3Weights, Scheme, StarWindow, TileBlock, Upwind1, VoxelKernel, Weno5, Window, X, Y,
    Z,
};
use std::marker::PhantomData;

/// Voxel size used by the probes (not 1, so that scaling is exercised).
const H: f32 = 0.7;

// ---------------------------------------------------------------------------------------
// Probes: one VoxelKernel per stencil function, so the block sweeps can run each alone.

macro_rules! probe {
    ($name:ident, $axis:expr, $box:expr, |$w:ident, $inv_h:ident| $e:expr) => {
        struct $name;
        impl VoxelKernel for $name {
            const AXIS_REACH: i32 = $axis;
            const BOX_REACH: i32 = $box;
            #[inline(always)]
            fn eval<L: Lane, W: Window<L>>(&self, $w: &W, _first: usize) -> L {
                let $inv_h = L::splat(1.0 / H);
                $e
            }
        }
    };
}

/// D⁻ (KIND 0), D⁺ (1), D⁰ (2) along axis A.
struct Diff<A, const KIND: u8>(PhantomData<A>);
impl<A: Axis, const KIND: u8> VoxelKernel for Diff<A, KIND> {
    const AXIS_REACH: i32 = 1;
    const BOX_REACH: i32 = 0;
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, _first: usize) -> L {
        let inv_h = L::splat(1.0 / H);
        match KIND {
            0 => diff_minus::<L, W, A>(w, inv_h),
            1 => diff_plus::<L, W, A>(w, inv_h),
            _ => diff_central::<L, W, A>(w, inv_h),
        }
    }
}

/// HJ-WENO5 φ⁻ (SIDE 0) or φ⁺ (1) along axis A.
struct WenoDiff<A, const SIDE: u8>(PhantomData<A>);
impl<A: Axis, const SIDE: u8> VoxelKernel for WenoDiff<A, SIDE> {
    const AXIS_REACH: i32 = 3;
    const BOX_REACH: i32 = 0;
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, _first: usize) -> L {
        let (m, p) = weno5_one_sided::<L, W, A>(w, L::splat(1.0 / H));
        if SIDE == 0 {
            m
        } else {
            p
        }
    }
}

probe!(CentralNorm, 1, 0, |w, inv_h| central_norm(w, inv_h));
probe!(Upwind1Plus, 1, 0, |w, inv_h| Upwind1::norms(w, inv_h).0);
probe!(Upwind1Minus, 1, 0, |w, inv_h| Upwind1::norms(w, inv_h).1);
probe!(Weno5Plus, 3, 0, |w, inv_h| Weno5::norms(w, inv_h).0);
probe!(Weno5Minus, 3, 0, |w, inv_h| Weno5::norms(w, inv_h).1);
probe!(CurvatureSpeed, 1, 1, |w, inv_h| curvature_speed(w, inv_h));
probe!(MeanCurvature, 1, 1, |w, inv_h| mean_curvature(w, inv_h));
probe!(SmoothedSign, 0, 0, |w, _inv_h| smoothed_sign(w.centre(), L::splat(H)));
probe!(SmoothedDelta, 0, 0, |w, _inv_h| smoothed_delta(w.centre(), L::splat(1.5 * H)));
probe!(KappaBarNum, 1, 1, |w, inv_h| kappa_bar_integrands(w, inv_h, L::splat(1.5 * H)).0);
probe!(KappaBarDen, 1, 1, |w, inv_h| kappa_bar_integrands(w, inv_h, L::splat(1.5 * H)).1);

// ---------------------------------------------------------------------------------------
// The three comparisons.

/// `kernel` on a dense block with every lane type equals the `f32` result bit for bit;
/// returns the `f32` result.
fn dense_all_lanes<K: VoxelKernel>(name: &str, k: &K, block: &DenseBlock<3>) -> Vec<f32> {
    let mut reference = vec![0.0; block.voxels()];
    block.apply::<f32, _>(k, &mut reference).unwrap();
    for_simd_lanes!(|L| {
        let mut out = vec![f32::from_bits(0x7fc0_1234); block.voxels()];
        block.apply::<L, _>(k, &mut out).unwrap();
        for (i, (&a, &b)) in out.iter().zip(&reference).enumerate() {
            assert!(same_bits(a, b), "{name} dense {} voxel {i}: {a:e} vs f32 {b:e}", L::NAME);
        }
    });
    reference
}

/// `kernel` on a padded tile with every lane type equals the `f32` result, which equals
/// the dense-block result on the same data; returns it.
fn tile_all_lanes<K: VoxelKernel>(name: &str, k: &K, tile: &[f32]) -> [f32; 64] {
    let padded = tile_layout(tile);
    let block = TileBlock::<3>::new(&padded).unwrap();
    let mut reference = [0.0; 64];
    block.apply::<f32, _>(k, &mut reference).unwrap();
    for_lanes!(|L| {
        let mut out = [f32::from_bits(0x7fc0_1234); 64];
        block.apply::<L, _>(k, &mut out).unwrap();
        for i in 0..64 {
            assert!(same_bits(out[i], reference[i]), "{name} tile {} voxel {i}", L::NAME);
        }
    });
    // The same values as a 4×4×4 dense block with a 3-voxel halo.
    let dense = DenseBlock::<3>::new(tile, [4, 4, 4]).unwrap();
    let d = dense_all_lanes(name, k, &dense);
    for i in 0..64 {
        assert!(same_bits(d[i], reference[i]), "{name} tile vs dense voxel {i}");
    }
    // At every instruction-set level this CPU has, every lane kind against the level's
    // own scalar (the x86 levels' lane types: one register, a pair of AVX registers), on
    // the tile. (The dense block at every level: `levels.rs`.)
    for level in Level::ALL.into_iter().filter(|l| l.available()) {
        let scalar = dispatch_at(level, LaneKind::F32, TileApply { block: &block, k }).unwrap();
        for kind in LaneKind::ALL {
            let out = dispatch_at(level, kind, TileApply { block: &block, k }).unwrap();
            for i in 0..64 {
                let what = format!("{name} at {level}, {} voxel {i}", kind.name());
                assert!(same_bits(out[i], scalar[i]), "{what}");
            }
        }
        if level.fused() == Level::Baseline.fused() {
            // The same rounding as the baseline: the same bits.
            for i in 0..64 {
                assert!(same_bits(scalar[i], reference[i]), "{name} at {level} voxel {i}");
            }
        }
    }
    reference
}

/// [`TileBlock::apply`] as a [`LaneFn`], for [`dispatch_at`].
struct TileApply<'a, K> {
    block: &'a TileBlock<'a, 3>,
    k: &'a K,
}

impl<K: VoxelKernel> LaneFn for TileApply<'_, K> {
    type Output = [f32; 64];
    #[inline(always)]
    fn call<L: Lane>(self) -> [f32; 64] {
        let mut out = [f32::from_bits(0x7fc0_1234); 64];
        self.block.apply::<L, _>(self.k, &mut out).unwrap();
        out
    }
}

/// Index of local coordinates (each in `-3..7`) in a 4×4×4 dense block with a 3-voxel
/// halo: the layout the tile tests fill.
fn dense_index(x: i32, y: i32, z: i32) -> usize {
    DenseBlock::<3>::index([4, 4, 4], x as isize, y as isize, z as isize)
}

/// A tile's values and 3-voxel halo given in the dense layout, copied into the
/// [`TileBlock`] layout (whose x halo is a whole tile row; the 4th voxel on each side is
/// never read with `R = 3` and stays NaN).
fn tile_layout(dense: &[f32]) -> Vec<f32> {
    let mut t = vec![f32::NAN; TileBlock::<3>::LEN];
    for z in -3..7 {
        for y in -3..7 {
            for x in -3..7 {
                t[TileBlock::<3>::index(x, y, z)] = dense[dense_index(x, y, z)];
            }
        }
    }
    t
}

/// The stencils a DT-Grid stencil iterator would hand over for tile voxel `(x, y, z)`.
fn gather(tile: &[f32], x: i32, y: i32, z: i32) -> ([f32; 27], [f32; 19]) {
    let mut b = [0.0; 27];
    for dz in -1..=1 {
        for dy in -1..=1 {
            for dx in -1..=1 {
                b[box27_index(dx, dy, dz)] = tile[dense_index(x + dx, y + dy, z + dz)];
            }
        }
    }
    let mut s = [0.0; 19];
    s[0] = tile[dense_index(x, y, z)];
    for a in 0..3 {
        for st in [-3, -2, -1, 1, 2, 3] {
            let mut o = [0; 3];
            o[a] = st;
            s[star19_index(o[0], o[1], o[2])] = tile[dense_index(x + o[0], y + o[1], z + o[2])];
        }
    }
    (b, s)
}

/// The 39-point box + far-star stencil of tile voxel `(x, y, z)`.
fn gather39(tile: &[f32], x: i32, y: i32, z: i32) -> [f32; 39] {
    let mut v = [0.0; 39];
    let mut seen = [false; 39];
    for dz in -3..=3i32 {
        for dy in -3..=3i32 {
            for dx in -3..=3i32 {
                let nonzero = (dx != 0) as i32 + (dy != 0) as i32 + (dz != 0) as i32;
                let m = dx.abs().max(dy.abs()).max(dz.abs());
                if m <= 1 || nonzero == 1 {
                    let i = box_far39_index(dx, dy, dz);
                    assert!(!seen[i], "index {i} twice");
                    seen[i] = true;
                    v[i] = tile[dense_index(x + dx, y + dy, z + dz)];
                }
            }
        }
    }
    assert!(seen.iter().all(|&s| s));
    v
}

/// Which DT-Grid point windows a kernel fits, as a type (a kernel must never be
/// instantiated with a window it does not fit: that is a compile-time error).
trait Points {
    fn eval<K: VoxelKernel>(k: &K, b: &[f32; 27], s: &[f32; 19], i: usize) -> Vec<f32>;
}
/// Box, star and both (star-1 kernels).
struct All;
/// Box and both (kernels with diagonals, reach 1).
struct Boxes;
/// Star and both (axis-only kernels of reach 3).
struct Stars;
/// Box + star only (diagonals and reach 3).
struct Both;
impl Points for All {
    fn eval<K: VoxelKernel>(k: &K, b: &[f32; 27], s: &[f32; 19], i: usize) -> Vec<f32> {
        vec![
            k.eval::<f32, _>(&BoxWindow::new(b), i),
            k.eval::<f32, _>(&StarWindow::new(s), i),
            k.eval::<f32, _>(&BoxStarWindow::new(b, s), i),
        ]
    }
}
impl Points for Boxes {
    fn eval<K: VoxelKernel>(k: &K, b: &[f32; 27], s: &[f32; 19], i: usize) -> Vec<f32> {
        vec![
            k.eval::<f32, _>(&BoxWindow::new(b), i),
            k.eval::<f32, _>(&BoxStarWindow::new(b, s), i),
        ]
    }
}
impl Points for Stars {
    fn eval<K: VoxelKernel>(k: &K, b: &[f32; 27], s: &[f32; 19], i: usize) -> Vec<f32> {
        vec![
            k.eval::<f32, _>(&StarWindow::new(s), i),
            k.eval::<f32, _>(&BoxStarWindow::new(b, s), i),
        ]
    }
}
impl Points for Both {
    fn eval<K: VoxelKernel>(k: &K, b: &[f32; 27], s: &[f32; 19], i: usize) -> Vec<f32> {
        vec![k.eval::<f32, _>(&BoxStarWindow::new(b, s), i)]
    }
}

/// The point windows (DT-Grid feed) give the tile's `f32` result for every voxel.
fn points_match<K: VoxelKernel, P: Points>(name: &str, k: &K, tile: &[f32], expect: &[f32; 64]) {
    for i in 0..64 {
        let (x, y, z) = ((i % 4) as i32, ((i / 4) % 4) as i32, (i / 16) as i32);
        let (b, s) = gather(tile, x, y, z);
        // The 39-point stencil serves every kernel.
        let f = gather39(tile, x, y, z);
        let mut got = P::eval(k, &b, &s, i);
        got.push(k.eval::<f32, _>(&BoxFarWindow::new(&f), i));
        for v in got {
            assert!(
                same_bits(v, expect[i]),
                "{name} point window voxel {i}: {v:e} vs {:e}",
                expect[i]
            );
        }
    }
}

fn fill_dense(fill: Fill, rng: &mut Rng, dims: [usize; 3]) -> Vec<f32> {
    let mut v = vec![0.0; DenseBlock::<3>::padded_len(dims).unwrap()];
    for z in -3..dims[2] as isize + 3 {
        for y in -3..dims[1] as isize + 3 {
            for x in -3..dims[0] as isize + 3 {
                v[DenseBlock::<3>::index(dims, x, y, z)] =
                    value(fill, rng, [x as f64, y as f64, z as f64]);
            }
        }
    }
    v
}

/// Per-voxel inputs (speed, velocity, φⁿ) drawn from the same fill.
fn field(fill: Fill, rng: &mut Rng, n: usize) -> Vec<f32> {
    (0..n).map(|i| value(fill, rng, [i as f64, 0.5, 0.25])).collect()
}

/// Something to do with one kernel (a closure cannot be generic over the kernel type).
trait Check {
    fn run<K: VoxelKernel, P: Points>(&self, name: &str, k: &K);
}

/// Runs every probe and kernel through `$c.run::<_, P>(name, kernel)`; `P` names the
/// DT-Grid point windows the kernel fits.
macro_rules! all_kernels {
    ($c:expr, $speed:expr, $vel:expr, $phi_n:expr) => {{
        let c = $c;
        let speed: &[f32] = $speed;
        let vel: [&[f32]; 3] = $vel;
        let phi_n: &[f32] = $phi_n;
        macro_rules! axes {
            ($ty:ident, $kind:literal, $pts:ident) => {
                c.run::<_, $pts>(
                    concat!(stringify!($ty), $kind, "x"),
                    &$ty::<X, $kind>(PhantomData),
                );
                c.run::<_, $pts>(
                    concat!(stringify!($ty), $kind, "y"),
                    &$ty::<Y, $kind>(PhantomData),
                );
                c.run::<_, $pts>(
                    concat!(stringify!($ty), $kind, "z"),
                    &$ty::<Z, $kind>(PhantomData),
                );
            };
        }
        axes!(Diff, 0, All);
        axes!(Diff, 1, All);
        axes!(Diff, 2, All);
        axes!(WenoDiff, 0, Stars);
        axes!(WenoDiff, 1, Stars);
        c.run::<_, All>("central_norm", &CentralNorm);
        c.run::<_, All>("upwind1 grad+", &Upwind1Plus);
        c.run::<_, All>("upwind1 grad-", &Upwind1Minus);
        c.run::<_, Stars>("weno5 grad+", &Weno5Plus);
        c.run::<_, Stars>("weno5 grad-", &Weno5Minus);
        c.run::<_, Boxes>("curvature_speed", &CurvatureSpeed);
        c.run::<_, Boxes>("mean_curvature", &MeanCurvature);
        c.run::<_, All>("smoothed_sign", &SmoothedSign);
        c.run::<_, All>("smoothed_delta", &SmoothedDelta);
        c.run::<_, Boxes>("kappa_bar num", &KappaBarNum);
        c.run::<_, Boxes>("kappa_bar den", &KappaBarDen);
        c.run::<_, Boxes>("eq3 upwind1 uniform F", &Eq3Rate::<Upwind1, f32>::new(H, 0.8, 0.3, 1.0));
        c.run::<_, Boxes>(
            "eq3 upwind1 field F",
            &Eq3Rate::<Upwind1, &[f32]>::new(H, speed, 0.3, 1.0),
        );
        c.run::<_, Both>("eq3 weno5 field F", &Eq3Rate::<Weno5, &[f32]>::new(H, speed, -0.2, 0.5));
        c.run::<_, All>(
            "advect upwind1 uniform",
            &AdvectionRate::<Upwind1, [f32; 3]>::new(H, [0.3, -1.2, 0.0]),
        );
        c.run::<_, Stars>("advect weno5 field", &AdvectionRate::<Weno5, [&[f32]; 3]>::new(H, vel));
        let eq3u = Eq3Rate::<Upwind1, f32>::new(H, -0.4, 0.25, 1.0);
        let eq3w = Eq3Rate::<Weno5, &[f32]>::new(H, speed, 0.25, 1.0);
        c.run::<_, Boxes>("euler eq3 upwind1", &Euler { rate: eq3u, dt: 0.11, gamma: GAMMA });
        c.run::<_, Boxes>("euler no clamp", &Euler { rate: eq3u, dt: 0.11, gamma: f32::INFINITY });
        c.run::<_, Both>(
            "rk3 stage 1",
            &Rk3::<_, 1> { rate: eq3w, dt: 0.07, gamma: GAMMA, phi_n: &[] },
        );
        c.run::<_, Both>("rk3 stage 2", &Rk3::<_, 2> { rate: eq3w, dt: 0.07, gamma: GAMMA, phi_n });
        c.run::<_, Both>("rk3 stage 3", &Rk3::<_, 3> { rate: eq3w, dt: 0.07, gamma: GAMMA, phi_n });
    }};
}

struct DenseCheck<'a> {
    block: DenseBlock<'a, 3>,
}
impl Check for &DenseCheck<'_> {
    fn run<K: VoxelKernel, P: Points>(&self, name: &str, k: &K) {
        dense_all_lanes(name, k, &self.block);
    }
}

struct TileCheck<'a> {
    tile: &'a [f32],
}
impl Check for &TileCheck<'_> {
    fn run<K: VoxelKernel, P: Points>(&self, name: &str, k: &K) {
        let expect = tile_all_lanes(name, k, self.tile);
        points_match::<K, P>(name, k, self.tile, &expect);
    }
}

#[test]
fn dense_blocks_every_lane_matches_scalar() {
    let mut rng = Rng(17);
    // Sizes that are not multiples of 4, 8 or 16 (the ends of rows run with f32 lanes).
    for dims in [[19, 5, 3], [16, 2, 2], [7, 3, 4], [33, 1, 1]] {
        for fill in FILLS {
            let data = fill_dense(fill, &mut rng, dims);
            let block = DenseBlock::<3>::new(&data, dims).unwrap();
            let n = block.voxels();
            let mut f = || field(fill, &mut rng, n);
            let (speed, u, v, w, phi_n) = (f(), f(), f(), f(), f());
            all_kernels!(&DenseCheck { block }, &speed, [&u, &v, &w], &phi_n);
        }
    }
}

#[test]
fn tiles_every_lane_matches_scalar_dense_and_point_windows() {
    let mut rng = Rng(4242);
    for round in 0..3 {
        for fill in FILLS {
            let tile = fill_dense(fill, &mut rng, [4, 4, 4]);
            assert_eq!(tile.len(), 1000);
            let mut f = || field(fill, &mut rng, 64);
            let (speed, u, v, w, phi_n) = (f(), f(), f(), f(), f());
            let _ = round;
            all_kernels!(&TileCheck { tile: &tile }, &speed, [&u, &v, &w], &phi_n);
        }
    }
}

/// TVD-RK3 stages 2 and 3 with the stage a run-time value ([`Rk3Blend`]) give the bits of
/// the stage as a type ([`Rk3`]), with every lane type; stage 1 and stages past 3 are not
/// blends.
#[test]
fn rk3_blend_matches_the_stages_bit_for_bit() {
    let mut rng = Rng(303);
    for dims in [[19, 5, 3], [7, 3, 4]] {
        for fill in FILLS {
            let data = fill_dense(fill, &mut rng, dims);
            let block = DenseBlock::<3>::new(&data, dims).unwrap();
            let n = block.voxels();
            let (speed, phi_n) = (field(fill, &mut rng, n), field(fill, &mut rng, n));
            let rate = Eq3Rate::<Weno5, &[f32]>::new(H, &speed, 0.25, 1.0);
            let (dt, gamma) = (0.07, GAMMA);
            let typed2 =
                dense_all_lanes("rk3 2", &Rk3::<_, 2> { rate, dt, gamma, phi_n: &phi_n }, &block);
            let typed3 =
                dense_all_lanes("rk3 3", &Rk3::<_, 3> { rate, dt, gamma, phi_n: &phi_n }, &block);
            for (stage, typed) in [(2, typed2), (3, typed3)] {
                let weights = Rk3Weights::of_stage(stage).unwrap();
                let blend = Rk3Blend { rate, dt, gamma, phi_n: &phi_n, weights };
                let got = dense_all_lanes("rk3 blend", &blend, &block);
                for (i, (&a, &b)) in got.iter().zip(&typed).enumerate() {
                    assert!(same_bits(a, b), "stage {stage} {fill:?} voxel {i}: {a:e} vs {b:e}");
                }
            }
        }
    }
    for stage in [0, 1, 4] {
        assert_eq!(Rk3Weights::of_stage(stage), None, "stage {stage}");
    }
}

/// The 1-voxel-halo tile (what first-order kernels need) gives the same bits as the
/// 3-voxel one.
#[test]
fn tile_halo_one_matches_halo_three() {
    let mut rng = Rng(99);
    for fill in FILLS {
        let t3 = fill_dense(fill, &mut rng, [4, 4, 4]);
        let mut t1 = vec![f32::NAN; TileBlock::<1>::LEN];
        for z in -1..5 {
            for y in -1..5 {
                for x in -1..5 {
                    t1[TileBlock::<1>::index(x, y, z)] = t3[dense_index(x, y, z)];
                }
            }
        }
        let k =
            Euler { rate: Eq3Rate::<Upwind1, f32>::new(H, 0.5, 0.2, 1.0), dt: 0.1, gamma: GAMMA };
        for_lanes!(|L| {
            let (mut a, mut b) = ([0.0; 64], [0.0; 64]);
            TileBlock::<1>::new(&t1).unwrap().apply::<L, _>(&k, &mut a).unwrap();
            TileBlock::<3>::new(&tile_layout(&t3)).unwrap().apply::<L, _>(&k, &mut b).unwrap();
            for i in 0..64 {
                assert!(same_bits(a[i], b[i]), "{} voxel {i}", L::NAME);
            }
        });
    }
}

/// An operation's name, its lane result and the scalar function it must match.
type Op<L> = (&'static str, L, fn(f32, f32, f32) -> f32);

/// The Lane operations themselves, lane by lane, on every pair of edge and random values.
#[test]
fn lane_ops_match_scalar() {
    let mut rng = Rng(7);
    let mut vals: Vec<f32> = common::EDGE.to_vec();
    for _ in 0..200 {
        vals.push(rng.range(-10.0, 10.0) as f32);
    }
    let n = vals.len();
    for_simd_lanes!(|L| {
        let k = L::LANES;
        for start in 0..n {
            // Lane j takes vals[(start + j * 7) % n] and vals[(start * 3 + j) % n].
            let a: Vec<f32> = (0..k).map(|j| vals[(start + j * 7) % n]).collect();
            let b: Vec<f32> = (0..k).map(|j| vals[(start * 3 + j) % n]).collect();
            let c: Vec<f32> = (0..k).map(|j| vals[(start * 5 + 2 * j + 1) % n]).collect();
            let (va, vb, vc) = (L::load(&a), L::load(&b), L::load(&c));
            let ops: [Op<L>; 11] = [
                ("add", va + vb, |a, b, _| a + b),
                ("sub", va - vb, |a, b, _| a - b),
                ("mul", va * vb, |a, b, _| a * b),
                ("div", va / vb, |a, b, _| a / b),
                ("neg", -va, |a, _, _| -a),
                ("mul_add", Lane::mul_add(va, vb, vc), |a, b, c| Lane::mul_add(a, b, c)),
                ("min", Lane::min(va, vb), |a, b, _| Lane::min(a, b)),
                ("max", Lane::max(va, vb), |a, b, _| Lane::max(a, b)),
                ("abs", Lane::abs(va), |a, _, _| Lane::abs(a)),
                ("sqrt", Lane::sqrt(va), |a, _, _| Lane::sqrt(a)),
                ("select_gt", va.select_gt(vb, vc, va), |a, b, c| Lane::select_gt(a, b, c, a)),
            ];
            for (name, v, f) in ops {
                let mut out = vec![0.0; k];
                v.store(&mut out);
                for j in 0..k {
                    let s = f(a[j], b[j], c[j]);
                    assert!(
                        same_bits(out[j], s),
                        "{} {name}({:e}, {:e}, {:e}) = {:e}, f32 gives {:e}",
                        L::NAME,
                        a[j],
                        b[j],
                        c[j],
                        out[j],
                        s
                    );
                }
            }
        }
    });
}

/// The documented NaN / signed-zero rules of min and max. (Called as `Lane::max(a, b)`:
/// on a concrete type, `a.max(b)` would pick the type's inherent method, e.g. `f32::max`.)
#[test]
fn min_max_nan_and_zero_rules() {
    for_lanes!(|L| {
        let nan = L::splat(f32::NAN);
        let one = L::splat(1.0);
        let mut o = vec![0.0; L::LANES];
        Lane::max(one, nan).store(&mut o);
        assert!(o[0].is_nan(), "max(1, NaN) = rhs = NaN");
        Lane::max(nan, one).store(&mut o);
        assert_eq!(o[0], 1.0, "max(NaN, 1) = rhs = 1");
        Lane::min(nan, one).store(&mut o);
        assert_eq!(o[0], 1.0, "min(NaN, 1) = rhs = 1");
        Lane::max(L::splat(0.0), L::splat(-0.0)).store(&mut o);
        assert!(o[0] == 0.0 && o[0].is_sign_negative(), "max(+0, -0) = rhs = -0");
        Lane::min(L::splat(-0.0), L::splat(0.0)).store(&mut o);
        assert!(o[0] == 0.0 && o[0].is_sign_positive(), "min(-0, +0) = rhs = +0");
        nan.select_gt(one, one, L::splat(2.0)).store(&mut o);
        assert_eq!(o[0], 2.0, "NaN > 1 is false");
    });
}
