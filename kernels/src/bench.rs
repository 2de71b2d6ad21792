//! Pure-kernel throughput: voxel updates per second on a dense, in-cache block, for every
//! lane type. This is the arithmetic limit the grid engines are measured against: a grid
//! can approach it, never beat it.
//!
//! Two kernels, the two discretisations of van der Laan et al. 2011:
//!
//! * `upwind_curvature`: one Euler update of eq. (3) with first-order upwind ∇⁺/∇⁻,
//!   central curvature (eq. (4)) and the rescaling term (Sec. 4.7), clamped to ±γ;
//! * `weno5_rk3`: one TVD-RK3 stage (stage 2, which reads φⁿ and blends) of eq. (3) with
//!   HJ-WENO5 ∇⁺/∇⁻ and central curvature (Sec. 5.2), clamped to ±γ.
//!
//! The block holds a sphere's signed distance (no clamped flat regions, though the
//! arithmetic is branch-free and does not depend on the values). One thread.
//!
//! Measured on the project machine (2-core AMD EPYC, AVX-512) on 2026-11-27 with
//! `levelset-speedup --kernels` from a build for the x86-64 baseline, running at the
//! detected AVX-512 level; 32³ block, best of 5 samples, Mvoxel-updates/s (speed-up over
//! `f32`):
//!
//! | kernel             | f32  | f32x4       | f32x8        | f32x16        |
//! |--------------------|------|-------------|--------------|---------------|
//! | `upwind_curvature` | 143  | 556 (3.9×)  | 1155 (8.1×)  | 1805 (12.6×)  |
//! | `weno5_rk3`        | 26.1 | 86.5 (3.3×) | 172 (6.6×)   | 348 (13.3×)   |
//!
//! `cargo run --release -p levelset-kernels --example kernel_bench -- 32 32 32 1.0`
//! prints this table and the JSON; `cargo bench -p levelset-kernels --bench kernels`
//! adds the tile and point-window (DT-Grid) access patterns.

use crate::block::DenseBlock;
use crate::error::KernelError;
use crate::kernel::{Eq3Rate, Euler, Rk3Blend, Rk3Weights, Upwind1, Weno5};
use crate::lane::{Lane, LaneKind};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// The kernels measured, in output order.
pub const KERNELS: [&str; 2] = ["upwind_curvature", "weno5_rk3"];
/// The lane types measured, in output order.
pub const LANES: [&str; 4] = ["f32", "f32x4", "f32x8", "f32x16"];

/// What to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelBenchConfig {
    /// Interior size of the dense block (default 32³: with the 3-voxel halo 38³ values,
    /// 220 KiB, plus 128 KiB each for φⁿ and the output; all inside a 1 MiB L2).
    pub dims: [usize; 3],
    /// Measuring time per (kernel, lanes) pair, split into `samples` samples; the best
    /// sample counts (default 0.3 s).
    pub seconds: f64,
    /// Samples per pair (default 5).
    pub samples: usize,
}

impl Default for KernelBenchConfig {
    fn default() -> Self {
        KernelBenchConfig { dims: [32, 32, 32], seconds: 0.3, samples: 5 }
    }
}

/// One measurement. JSON: `{"kernel": .., "lanes": .., "voxel_updates_per_s": ..}`.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct KernelResult {
    /// `"upwind_curvature"` or `"weno5_rk3"`.
    pub kernel: &'static str,
    /// `"f32"`, `"f32x4"`, `"f32x8"` or `"f32x16"`.
    pub lanes: &'static str,
    /// Interior voxels updated per second (best sample).
    pub voxel_updates_per_s: f64,
}

/// The kernel section of the speed-up report (`levelset-speedup`; alone with
/// `levelset-speedup --kernels`, whose `--json FILE` writes this). JSON:
/// `{"kernels": [KernelResult, ..], "target_features": ["sse2", ..], "level": "avx512"}`.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct KernelBenchReport {
    pub kernels: Vec<KernelResult>,
    pub target_features: Vec<&'static str>,
    /// The instruction-set level the kernels ran at ([`crate::Level::active`]).
    pub level: &'static str,
}

impl KernelBenchReport {
    /// The report as one line of JSON (no serde needed).
    pub fn to_json(&self) -> String {
        let rows: Vec<String> = self
            .kernels
            .iter()
            .map(|r| {
                format!(
                    "{{\"kernel\":\"{}\",\"lanes\":\"{}\",\"voxel_updates_per_s\":{:.1}}}",
                    r.kernel, r.lanes, r.voxel_updates_per_s
                )
            })
            .collect();
        let feats: Vec<String> = self.target_features.iter().map(|f| format!("\"{f}\"")).collect();
        format!(
            "{{\"kernels\":[{}],\"target_features\":[{}],\"level\":\"{}\"}}",
            rows.join(","),
            feats.join(","),
            self.level
        )
    }

    /// Throughput of `(kernel, lanes)`, if measured.
    pub fn get(&self, kernel: &str, lanes: &str) -> Option<f64> {
        self.kernels
            .iter()
            .find(|r| r.kernel == kernel && r.lanes == lanes)
            .map(|r| r.voxel_updates_per_s)
    }
}

/// The data of the benchmark: a sphere's distance field in a dense block with a 3-voxel
/// halo (served to the first-order kernel through a 1-voxel-halo copy), and φⁿ for the
/// RK3 stage. Public so that the criterion bench measures exactly the same thing.
pub struct Fixture {
    dims: [usize; 3],
    halo1: Vec<f32>,
    halo3: Vec<f32>,
    phi_n: Vec<f32>,
}

/// Parameters of both benchmark kernels: voxel size 1, F = 0.5, ε = 0.2, rescaling on,
/// Δt = 0.1, γ = 3.
const H: f32 = 1.0;
const SPEED: f32 = 0.5;
const EPS: f32 = 0.2;
const DT: f32 = 0.1;
const GAMMA: f32 = 3.0;
const STAGE_2: Rk3Weights = match Rk3Weights::of_stage(2) {
    Some(w) => w,
    None => panic!("TVD-RK3 stage 2 is a blend"),
};

impl Fixture {
    /// Builds the block (interior `dims`, each at least 1).
    pub fn new(dims: [usize; 3]) -> Result<Fixture, KernelError> {
        if dims.contains(&0) {
            return Err(KernelError::EmptyBlock);
        }
        let centre = dims.map(|n| n as f32 * 0.5 - 0.3);
        let radius = 0.35 * dims.iter().copied().min().unwrap_or(1) as f32 + 0.5;
        let phi = |x: isize, y: isize, z: isize| {
            let p = [x as f32 - centre[0], y as f32 - centre[1], z as f32 - centre[2]];
            (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - radius
        };
        let fill = |r: usize| -> Result<Vec<f32>, KernelError> {
            let len = match r {
                1 => DenseBlock::<1>::padded_len(dims),
                _ => DenseBlock::<3>::padded_len(dims),
            }
            .ok_or(KernelError::BlockTooLarge)?;
            let mut v = vec![0.0f32; len];
            let ri = r as isize;
            for z in -ri..dims[2] as isize + ri {
                for y in -ri..dims[1] as isize + ri {
                    for x in -ri..dims[0] as isize + ri {
                        let i = match r {
                            1 => DenseBlock::<1>::index(dims, x, y, z),
                            _ => DenseBlock::<3>::index(dims, x, y, z),
                        };
                        v[i] = phi(x, y, z);
                    }
                }
            }
            Ok(v)
        };
        let halo1 = fill(1)?;
        let halo3 = fill(3)?;
        let mut phi_n = Vec::with_capacity(dims.iter().product());
        for z in 0..dims[2] as isize {
            for y in 0..dims[1] as isize {
                for x in 0..dims[0] as isize {
                    phi_n.push(phi(x, y, z) * 0.99);
                }
            }
        }
        Ok(Fixture { dims, halo1, halo3, phi_n })
    }

    /// Interior voxels.
    pub fn voxels(&self) -> usize {
        self.dims.iter().product()
    }

    /// A zeroed output buffer of the right length.
    pub fn output(&self) -> Vec<f32> {
        vec![0.0; self.voxels()]
    }

    /// Kernel (a): one Euler step of eq. (3), first-order upwind + curvature + rescaling.
    #[inline(always)]
    pub fn upwind_curvature<L: Lane>(&self, out: &mut [f32]) -> Result<(), KernelError> {
        let block = DenseBlock::<1>::new(&self.halo1, self.dims)?;
        let step =
            Euler { rate: Eq3Rate::<Upwind1, f32>::new(H, SPEED, EPS, 1.0), dt: DT, gamma: GAMMA };
        block.apply::<L, _>(&step, out)
    }

    /// Kernel (b): TVD-RK3 stage 2 of eq. (3) with HJ-WENO5 + curvature + rescaling, as
    /// the engine runs it ([`Rk3Blend`]: the stage's weights as values).
    #[inline(always)]
    pub fn weno5_rk3<L: Lane>(&self, out: &mut [f32]) -> Result<(), KernelError> {
        let block = DenseBlock::<3>::new(&self.halo3, self.dims)?;
        let stage = Rk3Blend {
            rate: Eq3Rate::<Weno5, f32>::new(H, SPEED, EPS, 1.0),
            dt: DT,
            gamma: GAMMA,
            phi_n: &self.phi_n,
            weights: STAGE_2,
        };
        block.apply::<L, _>(&stage, out)
    }

    /// Runs kernel `kernel` (one of [`KERNELS`]) with lanes `lanes` (one of [`LANES`]).
    /// Returns `false` for unknown names.
    pub fn run(&self, kernel: &str, lanes: &str, out: &mut [f32]) -> Result<bool, KernelError> {
        let Some(kind) = LaneKind::from_name(lanes) else {
            return Ok(false);
        };
        let which = match kernel {
            "upwind_curvature" => Which::UpwindCurvature,
            "weno5_rk3" => Which::Weno5Rk3,
            _ => return Ok(false),
        };
        crate::dispatch(kind, Run { fx: self, which, out })?;
        Ok(true)
    }
}

#[derive(Clone, Copy)]
enum Which {
    UpwindCurvature,
    Weno5Rk3,
}

/// One run of a kernel over the fixture, at the CPU's level ([`crate::dispatch`]).
struct Run<'a> {
    fx: &'a Fixture,
    which: Which,
    out: &'a mut [f32],
}

impl crate::LaneFn for Run<'_> {
    type Output = Result<(), KernelError>;
    #[inline(always)]
    fn call<L: Lane>(self) -> Self::Output {
        match self.which {
            Which::UpwindCurvature => self.fx.upwind_curvature::<L>(self.out),
            Which::Weno5Rk3 => self.fx.weno5_rk3::<L>(self.out),
        }
    }
}

/// Measures every kernel of [`KERNELS`] with every lane type of [`LANES`] (single thread)
/// and returns them with [`crate::target_features()`]. Takes about
/// `2 × 4 × cfg.seconds` plus warm-up.
pub fn run_kernel_bench(cfg: &KernelBenchConfig) -> Result<KernelBenchReport, KernelError> {
    let fx = Fixture::new(cfg.dims)?;
    let mut out = fx.output();
    let samples = cfg.samples.max(1);
    let per_sample = Duration::from_secs_f64((cfg.seconds / samples as f64).max(1e-3));
    let mut kernels = Vec::new();
    for kernel in KERNELS {
        for lanes in LANES {
            // Warm-up and calibration: repetitions per sample.
            let t0 = Instant::now();
            fx.run(kernel, lanes, &mut out)?;
            black_box(&mut out);
            let once = t0.elapsed().max(Duration::from_nanos(100));
            let reps = (per_sample.as_secs_f64() / once.as_secs_f64()).ceil().max(1.0) as usize;
            let mut best = f64::INFINITY;
            for _ in 0..samples {
                let t = Instant::now();
                for _ in 0..reps {
                    fx.run(kernel, lanes, black_box(&mut out))?;
                }
                black_box(&out);
                best = best.min(t.elapsed().as_secs_f64() / reps as f64);
            }
            kernels.push(KernelResult {
                kernel,
                lanes,
                voxel_updates_per_s: fx.voxels() as f64 / best,
            });
        }
    }
    Ok(KernelBenchReport {
        kernels,
        target_features: crate::target_features(),
        level: crate::Level::active().name(),
    })
}
