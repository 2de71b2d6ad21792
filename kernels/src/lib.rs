//! # levelset-kernels
//!
//! The stencil arithmetic of sparse-levelset: upwind differences, curvature, HJ-WENO5,
//! the speed of eq. (3) of van der Laan et al. 2011, advection, TVD-RK3 and CFL limits. Every
//! kernel is written once over the sealed [`Lane`] trait and instantiated for scalar `f32` and
//! `wide`'s `f32x4`, `f32x8`, `f32x16` (and for the lane types of the x86 [`level`]s); it reads φ through a [`Window`] and knows no grid
//! type, so the Sorted Tile List ([`TileBlock`]) and the DT-Grid (point windows
//! [`BoxWindow`], [`StarWindow`], [`BoxStarWindow`], [`BoxFarWindow`]) run literally the
//! same arithmetic — bit for bit, which the tests check.
//!
//! ```
//! use levelset_kernels::{
//!     box27_index, wide::f32x8, BoxWindow, DenseBlock, Eq3Rate, Euler, Upwind1, VoxelKernel,
//! };
//!
//! // A sphere of radius 6 (φ < 0 inside) sampled on a 16³ block with a 1-voxel halo.
//! const R: usize = 1;
//! let dims = [16, 16, 16];
//! let mut data = vec![0.0f32; DenseBlock::<R>::padded_len(dims).unwrap()];
//! for z in -1..17 {
//!     for y in -1..17 {
//!         for x in -1..17 {
//!             let p = [x as f32 - 7.5, y as f32 - 7.5, z as f32 - 7.5];
//!             let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
//!             data[DenseBlock::<R>::index(dims, x, y, z)] = r - 6.0;
//!         }
//!     }
//! }
//! let block = DenseBlock::<R>::new(&data, dims)?;
//!
//! // One Euler step of eq. (3): speed F = 1 (outward), curvature weight ε = 0.1,
//! // rescaling on, first-order upwind; voxel size 1, Δt = 0.1, band half-width γ = 3.
//! let step = Euler { rate: Eq3Rate::<Upwind1, f32>::new(1.0, 1.0, 0.1, 1.0), dt: 0.1, gamma: 3.0 };
//! let mut simd = vec![0.0; block.voxels()];
//! let mut scalar = vec![0.0; block.voxels()];
//! block.apply::<f32x8, _>(&step, &mut simd)?;
//! block.apply::<f32, _>(&step, &mut scalar)?;
//! assert_eq!(simd, scalar); // bit for bit: one kernel source, same arithmetic per lane
//!
//! // The DT-Grid path: the same kernel on one voxel's 3×3×3 stencil values.
//! let (x, y, z) = (3, 9, 4);
//! let mut stencil = [0.0f32; 27];
//! for dz in -1..=1 {
//!     for dy in -1..=1 {
//!         for dx in -1..=1 {
//!             stencil[box27_index(dx, dy, dz)] =
//!                 data[DenseBlock::<R>::index(dims, (x + dx) as isize, (y + dy) as isize, (z + dz) as isize)];
//!         }
//!     }
//! }
//! let i = (x + 16 * (y + 16 * z)) as usize;
//! assert_eq!(step.eval::<f32, _>(&BoxWindow::new(&stencil), i), scalar[i]);
//! # Ok::<(), levelset_kernels::KernelError>(())
//! ```
//!
//! # Layers
//!
//! * [`Lane`] (module [`lane`]): the arithmetic, with documented NaN, signed-zero and
//!   fused-multiply-add semantics identical for every lane type; [`LaneKind`] and
//!   [`with_lane!`] turn a run-time lane choice into a type once.
//! * [`Window`] (module [`window`]): stencil access by const offsets; block windows for
//!   tiles and dense blocks, point windows for the DT-Grid.
//! * Stencil functions: [`diff`] (D⁻, D⁺, D⁰, ∇⁺/∇⁻), [`curvature`] (eq. (4)), [`weno`]
//!   (HJ-WENO5), [`speed`] (eq. (3), advection, eq. (6)–(7)), [`rk`] (TVD-RK3, CFL).
//! * Renormalisation ([`renorm`]): [`InterfaceAnchor`] (Russo–Smereka distance estimates
//!   next to the interface, once from φ⁰) and [`RenormRate`] (pseudo-time rate of
//!   φ_τ = S(φ⁰)(1 − |∇φ|) with Godunov norms [`diff::godunov_norms`] and the subcell
//!   fix), stepped with [`Euler`] at [`rk::cfl_dt_renorm`]; [`AnchoredRenormRate`] is
//!   the two in one pass (the first sweep over φ⁰).
//! * Voxel kernels ([`VoxelKernel`]: [`Eq3Rate`], [`AdvectionRate`], their [`Sum`],
//!   [`Euler`], [`Rk3`], the band mask [`BandMasked`] with [`BoxMinAbs`]) and the sweeps
//!   that apply them ([`TileBlock::apply`], [`DenseBlock::apply`]).
//! * [`bench`](mod@bench): the pure-kernel throughput benchmark behind
//!   `levelset-speedup --kernels` (and the kernel section of the speed-up report,
//!   `cargo run --release`).
//!
//! # Instruction-set levels and the `simd` feature
//!
//! A build for the x86-64 baseline runs at the CPU's best [`Level`], chosen once per
//! process ([`level`]): AVX-512 (`f32x16` one register), AVX2 + FMA, or the baseline the
//! build was compiled for (`wide`'s types, which fix their instructions at compile time).
//! [`dispatch`] turns a [`LaneKind`] into the level's lane type and runs a [`LaneFn`]
//! inside a function compiled for the level, so no `RUSTFLAGS` are needed for full speed.
//! Every level with FMA gives the same bits; the environment variable `LEVELSET_SIMD`
//! forces a level. [`target_features()`] lists what a binary was compiled with,
//! [`Level::active`] what it runs.
//!
//! The cargo feature `simd` (default on) only selects the lane kind the library uses
//! unless told otherwise ([`Level::default_lanes`]: `f32x16` at AVX-512, `f32x8` below;
//! `f32` without `simd`) and, for code that names a type at compile time, [`DefaultLane`].
//! Every lane type is compiled and tested either way.
//!
//! # Decisions
//!
//! * **Bitwise agreement, not a tolerance.** Every [`Lane`] operation is the same IEEE
//!   operation in every lane type, `mul_add` is fused in all of them or in none at a
//!   level ([`Level::fused`]), `min`/`max` follow the x86 `minps`/`maxps` rule (NaN →
//!   second operand) everywhere, and the delta function uses a polynomial cosine instead of
//!   libm/wide `cos` (which differ). So SIMD equals scalar bit for bit.
//! * **Offsets are const generics.** An offset a window cannot serve does not compile;
//!   block bounds are checked once per block, then windows load unchecked.
//! * **κ convention:** κ = ½∇·(∇φ/|∇φ|) as in van der Laan et al. 2011, eq. (2)/(4): 1/r on a
//!   sphere. The curvature term of eq. (3) is computed as κ∇⁰ without a square root.
//! * **Upwind norms:** ∇⁺/∇⁻ exactly as printed in van der Laan et al. 2011, Sec. 4.7 (both
//!   one-sided squares of an axis summed), for first-order and for HJ-WENO5 derivatives
//!   alike. This differs from the per-axis-max Godunov flux only at local extrema of φ
//!   along an axis.
//! * **HJ-WENO5 ε** = 10⁻⁶ max vₖ² (scale invariant); weights are formed with one
//!   reciprocal and one division per derivative instead of four divisions.
//! * **Smoothed sign** φ/√(φ² + h²) in the rescaling term (van der Laan et al. 2011, Sec. 3.2).
//! * **Band clamp** to [−γ, γ] is part of the time-step kernels ([`Euler`], [`Rk3`],
//!   [`Rk3Blend`]), so both grids clamp identically.
//! * **A scalar baseline that is scalar.** The `f32` sweeps hide each voxel's index from
//!   LLVM's loop vectoriser (see [`block`]), so `f32` measures one-voxel-at-a-time
//!   arithmetic, as a point-by-point grid runs it, not auto-vectorised code.

pub mod bench;
pub mod block;
pub mod curvature;
pub mod diff;
pub mod error;
pub mod kernel;
pub mod lane;
pub mod level;
pub mod renorm;
pub mod rk;
pub mod speed;
pub mod weno;
pub mod window;
#[cfg(target_arch = "x86_64")]
mod x86;

pub use block::{DenseBlock, TileBlock};
pub use diff::{Axis, X, Y, Z};
pub use error::KernelError;
pub use kernel::{
    AdvectionRate, BandMasked, BoxMinAbs, Eq3Rate, Euler, ImageRate, Rk3, Rk3Blend, Rk3Weights,
    ScalarField, ScaledVelocity, Scheme, Sum, Upwind1, VectorField, VoxelKernel, Weno5,
};
pub use lane::{Lane, LaneKind, FUSED_MUL_ADD};
pub use level::{check_env, dispatch, dispatch_at, dispatch_default, dispatch_one, LaneFn, Level};
pub use renorm::{AnchoredRenormRate, InterfaceAnchor, RenormRate};
pub use window::{
    box27_index, box_far39_index, star19_index, BoxFarWindow, BoxStarWindow, BoxWindow,
    DenseWindow, StarWindow, TileWindow, Window, BOX27_OFFSETS, BOX_FAR39_OFFSETS, STAR19_OFFSETS,
};

/// The `wide` crate the lane types come from (re-exported so users name the same types).
pub use wide;

/// The lane type of the baseline level's default, for code that names a type at compile
/// time: `f32x16` when AVX-512F is compiled in, else `f32x8` (feature `simd`, on by
/// default). The library itself runs [`Level::default_lanes`] at [`Level::active`].
#[cfg(all(feature = "simd", target_feature = "avx512f"))]
pub type DefaultLane = wide::f32x16;
/// The lane type of the baseline level's default, for code that names a type at compile
/// time: `f32x16` when AVX-512F is compiled in, else `f32x8` (feature `simd`, on by
/// default). The library itself runs [`Level::default_lanes`] at [`Level::active`].
#[cfg(all(feature = "simd", not(target_feature = "avx512f")))]
pub type DefaultLane = wide::f32x8;
/// The lane type of the baseline level's default: scalar `f32` (feature `simd` is off).
#[cfg(not(feature = "simd"))]
pub type DefaultLane = f32;

/// The vector-related target features this binary was compiled with (for benchmark
/// output), e.g. `["sse2", ..., "avx2", "fma", "avx512f", ...]`.
pub fn target_features() -> Vec<&'static str> {
    let mut v = Vec::new();
    macro_rules! probe {
        ($($f:literal),*) => {
            $(if cfg!(target_feature = $f) { v.push($f); })*
        };
    }
    probe!(
        "sse2", "sse3", "ssse3", "sse4.1", "sse4.2", "avx", "avx2", "fma", "avx512f", "avx512dq",
        "avx512bw", "avx512vl", "neon", "simd128"
    );
    v
}
