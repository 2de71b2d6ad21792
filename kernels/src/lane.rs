//! The sealed [`Lane`] trait: the one arithmetic interface every kernel is written against.
//!
//! Implemented for scalar `f32` and `wide::{f32x4, f32x8, f32x16}` (the baseline level),
//! and for the x86 levels' lane types, which no code outside the crate can name
//! ([`crate::level`]); nothing else (the trait is sealed by a private supertrait). A kernel is written once, generic over `L: Lane`;
//! its `f32` instantiation is the reference the vector instantiations are tested against,
//! lane by lane.
//!
//! # Semantics shared by every implementation
//!
//! Each operation below gives the same bits in every lane type at a given level, so a
//! kernel's SIMD result equals its scalar result bit for bit (the tests check exactly
//! this):
//!
//! * `+ - * /` and [`Lane::sqrt`]: IEEE 754 single precision, round to nearest (`addss`,
//!   `addps`, `sqrtps`, ... on x86).
//! * [`Lane::mul_add`]: `self * a + b`, **fused** (one rounding) at the AVX2 and AVX-512
//!   levels, and at the baseline level if and only if [`FUSED_MUL_ADD`] is true, i.e. the
//!   build enables `fma` on x86 or targets aarch64 with NEON; otherwise two roundings.
//!   The baseline's scalar `f32` follows the same rule (it does *not* call `f32::mul_add`
//!   in builds without FMA, which would be fused in software), so fusing never differs
//!   between lane types at a level.
//! * [`Lane::min`] / [`Lane::max`]: `if self < rhs { self } else { rhs }` and
//!   `if self > rhs { self } else { rhs }`, lane-wise. That is the x86 `minps` / `maxps`
//!   rule: **if either operand is NaN, `rhs` is returned**, and for `+0.0` vs `-0.0`
//!   (which compare equal) `rhs` is returned too. So `x.max(L::splat(0.0))` maps NaN to
//!   `+0.0`. On x86 these compile to single `minps`/`maxps` (wide's `fast_min`/`fast_max`,
//!   safe here because the NaN rule above is the documented contract, not an accident);
//!   on other targets the same rule is spelled out with a compare and a select.
//! * [`Lane::select_gt`]: `if self > rhs { t } else { f }`, lane-wise; a NaN comparison is
//!   false.
//! * [`Lane::abs`] clears and `-x` flips the sign bit (also of NaN).
//! * NaN payloads are not specified (wide does not preserve them); kernels never inspect
//!   them.
//!
//! [`FUSED_MUL_ADD`]: crate::FUSED_MUL_ADD

use core::fmt::Debug;
use core::ops::{Add, Div, Mul, Neg, Sub};
use wide::{f32x16, f32x4, f32x8};

/// Whether [`Lane::mul_add`] is fused (one rounding) for the baseline level's lane types
/// (`f32` and `wide`'s) in this build. The x86 levels always fuse ([`crate::Level::fused`]).
pub const FUSED_MUL_ADD: bool =
    cfg!(any(target_feature = "fma", all(target_arch = "aarch64", target_feature = "neon")));

pub(crate) mod sealed {
    /// The private supertrait of [`super::Lane`]: seals it and carries the raw loads the
    /// stencil windows use after checking bounds once per block.
    pub trait Sealed: Copy {
        /// Reads `LANES` consecutive values starting at `p`.
        ///
        /// # Safety
        /// `p .. p + LANES` must be readable `f32`s.
        unsafe fn load_ptr(p: *const f32) -> Self;

        /// Reads the lane group of a 4³ tile: `LANES / ROW` rows of `ROW = min(LANES, 4)`
        /// consecutive values, row `k` starting at `p + k * stride`.
        ///
        /// # Safety
        /// Every `p + k * stride + j` (`k < LANES / ROW`, `j < ROW`) must be a readable
        /// `f32`.
        unsafe fn load_rows4(p: *const f32, stride: usize) -> Self;
    }
}

/// A group of `LANES` `f32` values processed together: one voxel or a vector.
///
/// Sealed: implemented for `f32`, [`f32x4`], [`f32x8`] and [`f32x16`], and for the x86
/// levels' own types (reached only through [`crate::dispatch`]). See the [module
/// documentation](self) for the exact semantics of every operation (NaN, signed zero,
/// fused multiply-add); they are identical for all types at a level.
///
/// Constants inside kernels are written `L::splat(x)`.
///
/// In generic code (`L: Lane`) `a.min(b)` is this trait's method. On a *concrete* type the
/// type's inherent method of the same name wins (`f32::max` ignores NaN, `f32x8::min`
/// handles NaN differently): write `Lane::min(a, b)` there.
pub trait Lane:
    sealed::Sealed
    + Copy
    + Send
    + Sync
    + Debug
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Number of `f32` values in the group.
    const LANES: usize;
    /// Name used in benchmark output: `"f32"`, `"f32x4"`, `"f32x8"`, `"f32x16"`.
    const NAME: &'static str;
    /// The one-voxel lane type with the same arithmetic (`f32` for `f32` and `wide`'s
    /// types; the fused scalar type for the x86 levels' types): what a sweep runs for the
    /// voxels left over at the end of a row.
    type Scalar: Lane;

    /// Every lane set to `x`.
    fn splat(x: f32) -> Self;

    /// The first `LANES` values of `src`.
    ///
    /// # Panics
    /// If `src.len() < LANES`.
    fn load(src: &[f32]) -> Self;

    /// Writes the lanes to `dst[..LANES]`.
    ///
    /// # Panics
    /// If `dst.len() < LANES`.
    fn store(self, dst: &mut [f32]);

    /// `self * a + b`; fused at the x86 levels, and at the baseline iff [`FUSED_MUL_ADD`].
    fn mul_add(self, a: Self, b: Self) -> Self;

    /// `if self < rhs { self } else { rhs }` per lane (NaN in either: `rhs`).
    fn min(self, rhs: Self) -> Self;

    /// `if self > rhs { self } else { rhs }` per lane (NaN in either: `rhs`).
    fn max(self, rhs: Self) -> Self;

    /// Absolute value (clears the sign bit).
    fn abs(self) -> Self;

    /// Correctly rounded square root (NaN for negative inputs).
    fn sqrt(self) -> Self;

    /// `if self > rhs { if_true } else { if_false }` per lane (false if NaN is involved).
    fn select_gt(self, rhs: Self, if_true: Self, if_false: Self) -> Self;

    /// Whether `self > rhs` in at least one lane (false where NaN is involved): the
    /// condition under which [`Lane::select_gt`] picks `if_true` anywhere.
    fn any_gt(self, rhs: Self) -> bool;
}

impl sealed::Sealed for f32 {
    #[inline(always)]
    unsafe fn load_ptr(p: *const f32) -> Self {
        // SAFETY: the caller guarantees `p` is readable.
        unsafe { p.read() }
    }
    #[inline(always)]
    unsafe fn load_rows4(p: *const f32, _stride: usize) -> Self {
        // SAFETY: one row of one value, readable by the caller's guarantee.
        unsafe { p.read() }
    }
}

impl Lane for f32 {
    const LANES: usize = 1;
    const NAME: &'static str = "f32";
    type Scalar = f32;

    #[inline(always)]
    fn splat(x: f32) -> Self {
        x
    }
    #[inline(always)]
    fn load(src: &[f32]) -> Self {
        src[0]
    }
    #[inline(always)]
    fn store(self, dst: &mut [f32]) {
        dst[0] = self;
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        if FUSED_MUL_ADD {
            f32::mul_add(self, a, b)
        } else {
            self * a + b
        }
    }
    #[inline(always)]
    fn min(self, rhs: Self) -> Self {
        if self < rhs {
            self
        } else {
            rhs
        }
    }
    #[inline(always)]
    fn max(self, rhs: Self) -> Self {
        if self > rhs {
            self
        } else {
            rhs
        }
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn select_gt(self, rhs: Self, if_true: Self, if_false: Self) -> Self {
        if self > rhs {
            if_true
        } else {
            if_false
        }
    }
    #[inline(always)]
    fn any_gt(self, rhs: Self) -> bool {
        self > rhs
    }
}

/// `load_rows4` of the wide types: `N / 4` rows of 4 values, row `k` at `p + k * stride`.
///
/// The portable version assembles the rows in an array and loads it as a vector; on x86
/// with AVX the rows are combined in registers instead (128-bit loads and inserts). The
/// values are the same either way. Measured with the kernels' criterion benchmark on a
/// tile (`cargo bench -p levelset-kernels --bench kernels -- tile`, f32x16, 2-core AMD
/// EPYC, 2026-11-24): upwind + curvature 113 → 100 ns per tile, HJ-WENO5 + TVD-RK3
/// 511 → 459 ns.
mod rows4 {
    use wide::{f32x16, f32x4, f32x8};

    /// Portable: through an array.
    ///
    /// # Safety
    /// As [`super::sealed::Sealed::load_rows4`].
    #[inline(always)]
    unsafe fn portable<const N: usize>(p: *const f32, stride: usize) -> [f32; N] {
        let mut a = [0.0f32; N];
        for k in 0..N / 4 {
            // SAFETY: the caller guarantees row `k` (4 values at `p + k * stride`) is
            // readable.
            let row = unsafe { p.add(k * stride).cast::<[f32; 4]>().read_unaligned() };
            a[4 * k..4 * k + 4].copy_from_slice(&row);
        }
        a
    }

    /// # Safety
    /// As [`super::sealed::Sealed::load_rows4`].
    #[inline(always)]
    pub unsafe fn f32x4(p: *const f32, stride: usize) -> f32x4 {
        // SAFETY: the caller's guarantee (one row).
        f32x4::from(unsafe { portable::<4>(p, stride) })
    }

    /// # Safety
    /// As [`super::sealed::Sealed::load_rows4`].
    #[inline(always)]
    pub unsafe fn f32x8(p: *const f32, stride: usize) -> f32x8 {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
        {
            use core::arch::x86_64::{_mm256_loadu2_m128, _mm256_storeu_ps};
            let mut out = [0.0f32; 8];
            // SAFETY: the caller guarantees both rows are readable; `avx` is enabled
            // in this build; `out` holds 8 values.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), _mm256_loadu2_m128(p.add(stride), p)) };
            f32x8::from(out)
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
        // SAFETY: the caller's guarantee.
        f32x8::from(unsafe { portable::<8>(p, stride) })
    }

    /// # Safety
    /// As [`super::sealed::Sealed::load_rows4`].
    #[inline(always)]
    pub unsafe fn f32x16(p: *const f32, stride: usize) -> f32x16 {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
        {
            use core::arch::x86_64::*;
            // SAFETY: the caller guarantees the four rows are readable; `avx512f` (and
            // with it `avx`) is enabled in this build.
            let v = unsafe {
                let lo = _mm256_loadu2_m128(p.add(stride), p);
                let hi = _mm256_loadu2_m128(p.add(3 * stride), p.add(2 * stride));
                _mm512_insertf64x4::<1>(
                    _mm512_castpd256_pd512(_mm256_castps_pd(lo)),
                    _mm256_castps_pd(hi),
                )
            };
            let mut out = [0.0f32; 16];
            // SAFETY: `out` holds 16 values; `avx512f` is enabled.
            unsafe { _mm512_storeu_ps(out.as_mut_ptr(), _mm512_castpd_ps(v)) };
            f32x16::from(out)
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
        // SAFETY: the caller's guarantee.
        f32x16::from(unsafe { portable::<16>(p, stride) })
    }
}

macro_rules! impl_wide_lane {
    ($t:ident, $n:literal, $name:literal) => {
        impl sealed::Sealed for $t {
            #[inline(always)]
            unsafe fn load_ptr(p: *const f32) -> Self {
                // SAFETY: the caller guarantees `p .. p + N` is readable; `[f32; N]` has
                // alignment 4, and the read is unaligned anyway.
                $t::from(unsafe { p.cast::<[f32; $n]>().read_unaligned() })
            }
            #[inline(always)]
            unsafe fn load_rows4(p: *const f32, stride: usize) -> Self {
                // SAFETY: the caller's guarantee, passed on.
                unsafe { rows4::$t(p, stride) }
            }
        }

        impl Lane for $t {
            const LANES: usize = $n;
            const NAME: &'static str = $name;
            type Scalar = f32;

            #[inline(always)]
            fn splat(x: f32) -> Self {
                $t::splat(x)
            }
            #[inline(always)]
            fn load(src: &[f32]) -> Self {
                let a: [f32; $n] = src[..$n].try_into().unwrap();
                $t::from(a)
            }
            #[inline(always)]
            fn store(self, dst: &mut [f32]) {
                dst[..$n].copy_from_slice(&self.to_array());
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                // wide fuses exactly when FUSED_MUL_ADD is true (x86: `fma`; aarch64: NEON).
                $t::mul_add(self, a, b)
            }
            #[inline(always)]
            fn min(self, rhs: Self) -> Self {
                #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
                {
                    // `minps(self, rhs)` is `self < rhs ? self : rhs`: the documented rule.
                    self.fast_min(rhs)
                }
                #[cfg(not(any(target_arch = "x86", target_arch = "x86_64")))]
                {
                    self.simd_lt(rhs).select(self, rhs)
                }
            }
            #[inline(always)]
            fn max(self, rhs: Self) -> Self {
                #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
                {
                    // `maxps(self, rhs)` is `self > rhs ? self : rhs`: the documented rule.
                    self.fast_max(rhs)
                }
                #[cfg(not(any(target_arch = "x86", target_arch = "x86_64")))]
                {
                    self.simd_gt(rhs).select(self, rhs)
                }
            }
            #[inline(always)]
            fn abs(self) -> Self {
                $t::abs(self)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                $t::sqrt(self)
            }
            #[inline(always)]
            fn select_gt(self, rhs: Self, if_true: Self, if_false: Self) -> Self {
                wide::Select::select(self.simd_gt(rhs), if_true, if_false)
            }
            #[inline(always)]
            fn any_gt(self, rhs: Self) -> bool {
                self.simd_gt(rhs).any()
            }
        }
    };
}

impl_wide_lane!(f32x4, 4, "f32x4");
impl_wide_lane!(f32x8, 8, "f32x8");
impl_wide_lane!(f32x16, 16, "f32x16");

/// A lane type chosen at run time (command line, configuration), turned into a type
/// parameter once with [`with_lane!`](crate::with_lane) — never per voxel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LaneKind {
    F32,
    F32x4,
    F32x8,
    F32x16,
}

impl LaneKind {
    /// All lane types, narrowest first.
    pub const ALL: [LaneKind; 4] =
        [LaneKind::F32, LaneKind::F32x4, LaneKind::F32x8, LaneKind::F32x16];

    /// The kind of [`DefaultLane`](crate::DefaultLane) (the baseline level's; the library
    /// runs [`Level::default_lanes`](crate::Level::default_lanes)).
    pub const DEFAULT: LaneKind = match <crate::DefaultLane as Lane>::LANES {
        1 => LaneKind::F32,
        4 => LaneKind::F32x4,
        8 => LaneKind::F32x8,
        _ => LaneKind::F32x16,
    };

    /// `"f32"`, `"f32x4"`, `"f32x8"`, `"f32x16"` (the [`Lane::NAME`]s).
    pub const fn name(self) -> &'static str {
        match self {
            LaneKind::F32 => "f32",
            LaneKind::F32x4 => "f32x4",
            LaneKind::F32x8 => "f32x8",
            LaneKind::F32x16 => "f32x16",
        }
    }

    /// The inverse of [`LaneKind::name`].
    pub fn from_name(name: &str) -> Option<LaneKind> {
        LaneKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Values per lane group.
    pub const fn lanes(self) -> usize {
        match self {
            LaneKind::F32 => 1,
            LaneKind::F32x4 => 4,
            LaneKind::F32x8 => 8,
            LaneKind::F32x16 => 16,
        }
    }
}

/// Evaluates `$body` with the type alias `$L` set to the lane type of the
/// [`LaneKind`](crate::LaneKind) `$kind`: the run-time choice is made once, the body is
/// compiled for every lane type.
///
/// ```
/// use levelset_kernels::{with_lane, Lane, LaneKind};
/// let kind = LaneKind::from_name("f32x8").unwrap();
/// let n = with_lane!(kind, |L| <L as Lane>::LANES);
/// assert_eq!(n, 8);
/// ```
#[macro_export]
macro_rules! with_lane {
    ($kind:expr, |$L:ident| $body:expr) => {
        match $kind {
            $crate::LaneKind::F32 => {
                type $L = f32;
                $body
            }
            $crate::LaneKind::F32x4 => {
                type $L = $crate::wide::f32x4;
                $body
            }
            $crate::LaneKind::F32x8 => {
                type $L = $crate::wide::f32x8;
                $body
            }
            $crate::LaneKind::F32x16 => {
                type $L = $crate::wide::f32x16;
                $body
            }
        }
    };
}
