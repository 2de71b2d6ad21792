//! Pure-kernel throughput (criterion): the arithmetic limit the grid engines are measured
//! against. Run with `cargo bench -p levelset-kernels --bench kernels`.
//!
//! Cases, best to worst access pattern, each id carrying its voxel count so times convert
//! to voxel updates per second (criterion prints elements/s = voxel updates/s):
//!
//! * `dense/<kernel>/<lanes>`: a 32³ block (the `levelset-speedup --kernels` fixture),
//!   lanes = consecutive x voxels, contiguous unaligned loads — the best case;
//! * `tile/<kernel>/<lanes>`: 512 padded 4³ tiles covering the same 32³ block, each
//!   gathered once beforehand (what the Sorted Tile List sweeps, without the gather);
//!   `f32x8`/`f32x16` assemble their lanes from 2/4 tile rows per stencil point. Run at
//!   the CPU's instruction-set level as the engines run (`levelset_kernels::dispatch`),
//!   like `dense`;
//! * `points/<kernel>/f32`: per-voxel stencil arrays through the DT-Grid point windows,
//!   pre-gathered (so only the arithmetic and the window reads count) — scalar only, as
//!   a point-by-point grid runs.
//!
//! Kernels: `upwind_curvature` (Euler step of eq. (3), first-order upwind + curvature +
//! rescaling) and `weno5_rk3` (TVD-RK3 stage 2 of eq. (3) with HJ-WENO5).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use levelset_kernels::bench::{Fixture, KERNELS};
use levelset_kernels::{
    box27_index, star19_index, BoxStarWindow, BoxWindow, Eq3Rate, Euler, Lane, Rk3Blend,
    Rk3Weights, TileBlock, Upwind1, VoxelKernel, Weno5,
};
use std::hint::black_box;
use std::time::Duration;

const DIMS: [usize; 3] = [32, 32, 32];

fn phi(x: i32, y: i32, z: i32) -> f32 {
    let p = [x as f32 - 1.7, y as f32 + 2.2, z as f32 - 9.1];
    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 8.3
}

/// The 512 padded tiles (halo `R`) of the 32³ block of [`phi`], each a whole padded block.
fn tiles_of<const R: usize>() -> Vec<Vec<f32>> {
    let r = R as i32;
    let mut out = Vec::new();
    for tz in 0..8 {
        for ty in 0..8 {
            for tx in 0..8 {
                let mut t = vec![0.0; TileBlock::<R>::LEN];
                for z in -r..4 + r {
                    for y in -r..4 + r {
                        for x in -4..8 {
                            t[TileBlock::<R>::index(x, y, z)] =
                                phi(4 * tx + x, 4 * ty + y, 4 * tz + z);
                        }
                    }
                }
                out.push(t);
            }
        }
    }
    out
}

/// One sweep of a kernel over tiles of halo `R`, at the CPU's level.
struct TileSweep<'a, K, const R: usize> {
    tiles: &'a [Vec<f32>],
    kernel: &'a K,
    out: &'a mut [f32],
}

impl<K: VoxelKernel, const R: usize> levelset_kernels::LaneFn for TileSweep<'_, K, R> {
    type Output = ();
    #[inline(always)]
    fn call<L: Lane>(self) {
        for (t, o) in self.tiles.iter().zip(self.out.chunks_exact_mut(64)) {
            let o: &mut [f32; 64] = o.try_into().expect("64 voxels");
            TileBlock::<R>::new(t).unwrap().apply::<L, _>(self.kernel, o).unwrap();
        }
    }
}

fn upwind() -> Euler<Eq3Rate<Upwind1, f32>> {
    Euler { rate: Eq3Rate::new(1.0, 0.5, 0.2, 1.0), dt: 0.1, gamma: 3.0 }
}

/// TVD-RK3 stage 2 as the engine runs it (the stage's weights as values).
fn weno(phi_n: &[f32]) -> Rk3Blend<'_, Eq3Rate<Weno5, f32>> {
    let weights = Rk3Weights::of_stage(2).expect("TVD-RK3 stage 2 is a blend");
    Rk3Blend { rate: Eq3Rate::new(1.0, 0.5, 0.2, 1.0), dt: 0.1, gamma: 3.0, phi_n, weights }
}

fn dense(c: &mut Criterion) {
    let fx = Fixture::new(DIMS).unwrap();
    let n = fx.voxels();
    let mut g = c.benchmark_group(format!("dense_{}x{}x{}={n}voxels", DIMS[0], DIMS[1], DIMS[2]));
    g.throughput(Throughput::Elements(n as u64));
    g.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(2));
    let mut out = fx.output();
    for kernel in KERNELS {
        for lanes in levelset_kernels::bench::LANES {
            g.bench_function(BenchmarkId::new(kernel, lanes), |b| {
                b.iter(|| fx.run(kernel, lanes, black_box(&mut out)).unwrap())
            });
        }
    }
    g.finish();
}

fn tiles(c: &mut Criterion) {
    let (t1, t3) = (tiles_of::<1>(), tiles_of::<3>());
    let phi_n: Vec<f32> = (0..64).map(|i| phi(i % 4, (i / 4) % 4, i / 16) * 0.99).collect();
    let mut out = vec![0.0f32; 64 * t1.len()];
    let (ku, kw) = (upwind(), weno(&phi_n));
    let mut g = c.benchmark_group(format!("tile_512x4x4x4={}voxels", out.len()));
    g.throughput(Throughput::Elements(out.len() as u64));
    g.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(2));
    for lanes in levelset_kernels::bench::LANES {
        let kind = levelset_kernels::LaneKind::from_name(lanes).expect("a lane type");
        g.bench_function(BenchmarkId::new("upwind_curvature", lanes), |b| {
            b.iter(|| {
                let sweep = TileSweep::<_, 1> { tiles: &t1, kernel: &ku, out: black_box(&mut out) };
                levelset_kernels::dispatch(kind, sweep)
            })
        });
        g.bench_function(BenchmarkId::new("weno5_rk3", lanes), |b| {
            b.iter(|| {
                let sweep = TileSweep::<_, 3> { tiles: &t3, kernel: &kw, out: black_box(&mut out) };
                levelset_kernels::dispatch(kind, sweep)
            })
        });
    }
    g.finish();
}

fn points(c: &mut Criterion) {
    // 4096 voxels of the sphere field, each with its box and star stencil.
    let n = 4096;
    let mut boxes = vec![[0.0f32; 27]; n];
    let mut stars = vec![[0.0f32; 19]; n];
    for (i, (b, s)) in boxes.iter_mut().zip(stars.iter_mut()).enumerate() {
        let (x, y, z) = ((i % 16) as i32, ((i / 16) % 16) as i32, (i / 256) as i32);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    b[box27_index(dx, dy, dz)] = phi(x + dx, y + dy, z + dz);
                }
            }
        }
        s[0] = phi(x, y, z);
        for a in 0..3 {
            for st in [-3, -2, -1, 1, 2, 3] {
                let mut o = [0; 3];
                o[a] = st;
                s[star19_index(o[0], o[1], o[2])] = phi(x + o[0], y + o[1], z + o[2]);
            }
        }
    }
    let phi_n: Vec<f32> = boxes.iter().map(|b| b[13] * 0.99).collect();
    let mut out = vec![0.0f32; n];
    let mut g = c.benchmark_group(format!("points_{n}voxels"));
    g.throughput(Throughput::Elements(n as u64));
    g.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(2));
    let ku = upwind();
    g.bench_function(BenchmarkId::new("upwind_curvature", "f32"), |b| {
        b.iter(|| {
            for (i, bx) in boxes.iter().enumerate() {
                out[i] = ku.eval::<f32, _>(&BoxWindow::new(black_box(bx)), i);
            }
        })
    });
    let kw = weno(&phi_n);
    g.bench_function(BenchmarkId::new("weno5_rk3", "f32"), |b| {
        b.iter(|| {
            for i in 0..n {
                out[i] = kw.eval::<f32, _>(&BoxStarWindow::new(black_box(&boxes[i]), &stars[i]), i);
            }
        })
    });
    g.finish();
    black_box(out);
}

criterion_group!(benches, dense, tiles, points);
criterion_main!(benches);
