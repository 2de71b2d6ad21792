//! The lane types of the x86 levels ([`crate::level`]): [`S1`] (one voxel), [`X4`], [`X8`],
//! [`X16`] (one register each) and [`Pair`] (`f32x16` as two AVX registers), on
//! `core::arch` intrinsics, with `mul_add` always fused.
//!
//! Each operation is the one instruction of [`Lane`]'s documented semantics (the module
//! documentation of [`crate::lane`]): `minps`/`maxps` return the second operand on NaN,
//! comparisons are ordered (false on NaN), `abs` clears and `-` flips the sign bit.
//!
//! # Invariant (what makes the `unsafe` blocks sound)
//! The types are public in this private module: no code outside the crate can name them.
//! They reach code only as the type parameter of [`crate::LaneFn::call`], which
//! [`crate::dispatch`], [`crate::dispatch_one`] and [`crate::dispatch_at`] instantiate only
//! after [`crate::Level::available`] returned true in this process for a level whose
//! features they use: AVX2 and FMA for every type here, AVX-512 F/DQ for [`X16`]. Code
//! built with such a type may outlive the call (a function pointer, a boxed closure), but
//! it runs in the same process on the same CPU. So whenever one of their methods runs, the
//! CPU has the instructions it uses. (Inside `dispatch`'s
//! `#[target_feature]` functions the intrinsics inline; a method called outside them still
//! runs correctly, as a call.)

use crate::lane::{sealed, Lane};
use core::arch::x86_64::*;
use core::ops::{Add, Div, Mul, Neg, Sub};

/// One voxel, `mul_add` fused (`vfmadd` inside the levels' functions).
#[derive(Clone, Copy, Debug)]
pub struct S1(f32);

impl sealed::Sealed for S1 {
    #[inline(always)]
    unsafe fn load_ptr(p: *const f32) -> Self {
        // SAFETY: the caller guarantees `p` is readable.
        S1(unsafe { p.read() })
    }
    #[inline(always)]
    unsafe fn load_rows4(p: *const f32, _stride: usize) -> Self {
        // SAFETY: one row of one value, readable by the caller's guarantee.
        S1(unsafe { p.read() })
    }
}

macro_rules! scalar_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for S1 {
            type Output = S1;
            #[inline(always)]
            fn $f(self, rhs: S1) -> S1 {
                S1(self.0 $op rhs.0)
            }
        }
    };
}
scalar_op!(Add, add, +);
scalar_op!(Sub, sub, -);
scalar_op!(Mul, mul, *);
scalar_op!(Div, div, /);

impl Neg for S1 {
    type Output = S1;
    #[inline(always)]
    fn neg(self) -> S1 {
        S1(-self.0)
    }
}

impl Lane for S1 {
    const LANES: usize = 1;
    const NAME: &'static str = "f32";
    type Scalar = S1;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        S1(x)
    }
    #[inline(always)]
    fn load(src: &[f32]) -> Self {
        S1(src[0])
    }
    #[inline(always)]
    fn store(self, dst: &mut [f32]) {
        dst[0] = self.0;
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        S1(f32::mul_add(self.0, a.0, b.0))
    }
    #[inline(always)]
    fn min(self, rhs: Self) -> Self {
        if self.0 < rhs.0 {
            self
        } else {
            rhs
        }
    }
    #[inline(always)]
    fn max(self, rhs: Self) -> Self {
        if self.0 > rhs.0 {
            self
        } else {
            rhs
        }
    }
    #[inline(always)]
    fn abs(self) -> Self {
        S1(self.0.abs())
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        S1(self.0.sqrt())
    }
    #[inline(always)]
    fn select_gt(self, rhs: Self, if_true: Self, if_false: Self) -> Self {
        if self.0 > rhs.0 {
            if_true
        } else {
            if_false
        }
    }
    #[inline(always)]
    fn any_gt(self, rhs: Self) -> bool {
        self.0 > rhs.0
    }
}

/// One register of `$n` values: the arithmetic traits, `Neg`, and `Lane` from the
/// register's intrinsics. `$sel` is `select_gt`'s body and `$any` `any_gt`'s, over
/// `(a, b, t, f)` and `(a, b)`; `$rows` is `load_rows4`'s over `(p, stride)`.
macro_rules! register_lane {
    (
        $t:ident, $reg:ty, $n:literal, $name:literal,
        add $add:ident, sub $sub:ident, mul $mul:ident, div $div:ident,
        fma $fma:ident, min $min:ident, max $max:ident, sqrt $sqrt:ident,
        xor $xor:ident, andnot $andnot:ident, set1 $set1:ident,
        loadu $loadu:ident, storeu $storeu:ident,
        select |$a:ident, $b:ident, $tt:ident, $ff:ident| $sel:block,
        any |$a2:ident, $b2:ident| $any:block,
        rows |$p:ident, $stride:ident| $rows:block
    ) => {
        #[doc = concat!("`", $name, "` in one register, `mul_add` fused.")]
        #[derive(Clone, Copy, Debug)]
        pub struct $t($reg);

        impl sealed::Sealed for $t {
            #[inline(always)]
            unsafe fn load_ptr(p: *const f32) -> Self {
                // SAFETY: the caller guarantees `p .. p + N` is readable; the module's
                // invariant, that the CPU has the instructions.
                $t(unsafe { $loadu(p) })
            }
            #[inline(always)]
            unsafe fn load_rows4($p: *const f32, $stride: usize) -> Self {
                // SAFETY: the caller guarantees the rows are readable; the module's
                // invariant.
                $t(unsafe { $rows })
            }
        }

        register_lane!(@op $t, Add, add, $add);
        register_lane!(@op $t, Sub, sub, $sub);
        register_lane!(@op $t, Mul, mul, $mul);
        register_lane!(@op $t, Div, div, $div);

        impl Neg for $t {
            type Output = $t;
            #[inline(always)]
            fn neg(self) -> $t {
                // SAFETY: the module's invariant.
                $t(unsafe { $xor(self.0, $set1(-0.0)) })
            }
        }

        impl Lane for $t {
            const LANES: usize = $n;
            const NAME: &'static str = $name;
            type Scalar = S1;
            #[inline(always)]
            fn splat(x: f32) -> Self {
                // SAFETY: the module's invariant.
                $t(unsafe { $set1(x) })
            }
            #[inline(always)]
            fn load(src: &[f32]) -> Self {
                assert!(src.len() >= $n, "a lane group needs {} values", $n);
                // SAFETY: `src` holds at least N values (asserted); the module's invariant.
                $t(unsafe { $loadu(src.as_ptr()) })
            }
            #[inline(always)]
            fn store(self, dst: &mut [f32]) {
                assert!(dst.len() >= $n, "a lane group needs {} values", $n);
                // SAFETY: `dst` holds at least N values (asserted); the module's invariant.
                unsafe { $storeu(dst.as_mut_ptr(), self.0) }
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                // SAFETY: the module's invariant.
                $t(unsafe { $fma(self.0, a.0, b.0) })
            }
            #[inline(always)]
            fn min(self, rhs: Self) -> Self {
                // `min(a, b)` is `a < b ? a : b` (NaN: `b`), the documented rule.
                // SAFETY: the module's invariant.
                $t(unsafe { $min(self.0, rhs.0) })
            }
            #[inline(always)]
            fn max(self, rhs: Self) -> Self {
                // SAFETY: the module's invariant.
                $t(unsafe { $max(self.0, rhs.0) })
            }
            #[inline(always)]
            fn abs(self) -> Self {
                // SAFETY: the module's invariant.
                $t(unsafe { $andnot($set1(-0.0), self.0) })
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                // SAFETY: the module's invariant.
                $t(unsafe { $sqrt(self.0) })
            }
            #[inline(always)]
            fn select_gt(self, rhs: Self, if_true: Self, if_false: Self) -> Self {
                let ($a, $b, $tt, $ff) = (self.0, rhs.0, if_true.0, if_false.0);
                // SAFETY: the module's invariant.
                $t(unsafe { $sel })
            }
            #[inline(always)]
            fn any_gt(self, rhs: Self) -> bool {
                let ($a2, $b2) = (self.0, rhs.0);
                // SAFETY: the module's invariant.
                unsafe { $any }
            }
        }
    };
    (@op $t:ident, $tr:ident, $f:ident, $intr:ident) => {
        impl $tr for $t {
            type Output = $t;
            #[inline(always)]
            fn $f(self, rhs: $t) -> $t {
                // SAFETY: the module's invariant (see the module documentation).
                $t(unsafe { $intr(self.0, rhs.0) })
            }
        }
    };
}

register_lane!(
    X4, __m128, 4, "f32x4",
    add _mm_add_ps, sub _mm_sub_ps, mul _mm_mul_ps, div _mm_div_ps,
    fma _mm_fmadd_ps, min _mm_min_ps, max _mm_max_ps, sqrt _mm_sqrt_ps,
    xor _mm_xor_ps, andnot _mm_andnot_ps, set1 _mm_set1_ps,
    loadu _mm_loadu_ps, storeu _mm_storeu_ps,
    select |a, b, t, f| { _mm_blendv_ps(f, t, _mm_cmp_ps::<_CMP_GT_OQ>(a, b)) },
    any |a, b| { _mm_movemask_ps(_mm_cmp_ps::<_CMP_GT_OQ>(a, b)) != 0 },
    rows |p, _stride| { _mm_loadu_ps(p) }
);

register_lane!(
    X8, __m256, 8, "f32x8",
    add _mm256_add_ps, sub _mm256_sub_ps, mul _mm256_mul_ps, div _mm256_div_ps,
    fma _mm256_fmadd_ps, min _mm256_min_ps, max _mm256_max_ps, sqrt _mm256_sqrt_ps,
    xor _mm256_xor_ps, andnot _mm256_andnot_ps, set1 _mm256_set1_ps,
    loadu _mm256_loadu_ps, storeu _mm256_storeu_ps,
    select |a, b, t, f| { _mm256_blendv_ps(f, t, _mm256_cmp_ps::<_CMP_GT_OQ>(a, b)) },
    any |a, b| { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(a, b)) != 0 },
    rows |p, stride| { _mm256_loadu2_m128(p.add(stride), p) }
);

register_lane!(
    X16, __m512, 16, "f32x16",
    add _mm512_add_ps, sub _mm512_sub_ps, mul _mm512_mul_ps, div _mm512_div_ps,
    fma _mm512_fmadd_ps, min _mm512_min_ps, max _mm512_max_ps, sqrt _mm512_sqrt_ps,
    xor _mm512_xor_ps, andnot _mm512_andnot_ps, set1 _mm512_set1_ps,
    loadu _mm512_loadu_ps, storeu _mm512_storeu_ps,
    select |a, b, t, f| { _mm512_mask_blend_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(a, b), f, t) },
    any |a, b| { _mm512_cmp_ps_mask::<_CMP_GT_OQ>(a, b) != 0 },
    rows |p, stride| {
        let lo = _mm256_loadu2_m128(p.add(stride), p);
        let hi = _mm256_loadu2_m128(p.add(3 * stride), p.add(2 * stride));
        _mm512_castpd_ps(_mm512_insertf64x4::<1>(
            _mm512_castpd256_pd512(_mm256_castps_pd(lo)),
            _mm256_castps_pd(hi),
        ))
    }
);

/// `2N` values as two lane groups of `N` (`f32x16` as two [`X8`] at the AVX2 level): the
/// low half first, every operation half by half.
#[derive(Clone, Copy, Debug)]
pub struct Pair<T>(T, T);

impl<T: Lane> sealed::Sealed for Pair<T> {
    #[inline(always)]
    unsafe fn load_ptr(p: *const f32) -> Self {
        // SAFETY: the caller guarantees `p .. p + 2N` is readable.
        unsafe { Pair(T::load_ptr(p), T::load_ptr(p.add(T::LANES))) }
    }
    #[inline(always)]
    unsafe fn load_rows4(p: *const f32, stride: usize) -> Self {
        // The low half holds the first `N / 4` rows, the high half the rest.
        const { assert!(T::LANES % 4 == 0, "a pair of lane groups of whole rows") };
        let rows = T::LANES / 4;
        // SAFETY: the caller guarantees all `2N / 4` rows are readable.
        unsafe { Pair(T::load_rows4(p, stride), T::load_rows4(p.add(rows * stride), stride)) }
    }
}

macro_rules! pair_op {
    ($tr:ident, $f:ident) => {
        impl<T: Lane> $tr for Pair<T> {
            type Output = Pair<T>;
            #[inline(always)]
            fn $f(self, rhs: Self) -> Self {
                Pair(self.0.$f(rhs.0), self.1.$f(rhs.1))
            }
        }
    };
}
pair_op!(Add, add);
pair_op!(Sub, sub);
pair_op!(Mul, mul);
pair_op!(Div, div);

impl<T: Lane> Neg for Pair<T> {
    type Output = Pair<T>;
    #[inline(always)]
    fn neg(self) -> Self {
        Pair(-self.0, -self.1)
    }
}

impl<T: Lane> Lane for Pair<T> {
    const LANES: usize = 2 * T::LANES;
    const NAME: &'static str = match T::LANES {
        4 => "f32x8",
        8 => "f32x16",
        _ => "pair",
    };
    type Scalar = T::Scalar;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Pair(T::splat(x), T::splat(x))
    }
    #[inline(always)]
    fn load(src: &[f32]) -> Self {
        Pair(T::load(src), T::load(&src[T::LANES..]))
    }
    #[inline(always)]
    fn store(self, dst: &mut [f32]) {
        self.0.store(dst);
        self.1.store(&mut dst[T::LANES..]);
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        Pair(self.0.mul_add(a.0, b.0), self.1.mul_add(a.1, b.1))
    }
    #[inline(always)]
    fn min(self, rhs: Self) -> Self {
        Pair(Lane::min(self.0, rhs.0), Lane::min(self.1, rhs.1))
    }
    #[inline(always)]
    fn max(self, rhs: Self) -> Self {
        Pair(Lane::max(self.0, rhs.0), Lane::max(self.1, rhs.1))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Pair(Lane::abs(self.0), Lane::abs(self.1))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Pair(Lane::sqrt(self.0), Lane::sqrt(self.1))
    }
    #[inline(always)]
    fn select_gt(self, rhs: Self, if_true: Self, if_false: Self) -> Self {
        Pair(
            self.0.select_gt(rhs.0, if_true.0, if_false.0),
            self.1.select_gt(rhs.1, if_true.1, if_false.1),
        )
    }
    #[inline(always)]
    fn any_gt(self, rhs: Self) -> bool {
        self.0.any_gt(rhs.0) || self.1.any_gt(rhs.1)
    }
}
