//! HJ-WENO5 one-sided derivatives (Jiang & Peng 2000), the fifth-order spatial scheme of
//! Nielsen & Museth 2006 (Sec. 4.1) and of van der Laan et al. 2011 (Sec. 5.2) for the
//! hyperbolic terms.
//!
//! For the left-biased derivative φₓ⁻ at voxel i the five inputs are the backward
//! differences vₖ = D⁻φ at i−2, i−1, i, i+1, i+2; for the right-biased φₓ⁺ they are the
//! forward differences D⁺φ at i+2, i+1, i, i−1, i−2 (mirrored). Three third-order
//! candidates are blended with the Jiang–Peng smoothness indicators and the ideal weights
//! 0.1, 0.6, 0.3.
//!
//! # ε and scaling
//!
//! The indicators are regularised with ε = 10⁻⁶ · max(vₖ²) (+ a tiny constant for flat
//! data), the scale-invariant choice of Osher & Fedkiw (Sec. 3.4 of their book): the
//! weights do not depend on the units of φ, so the derivative is computed from undivided
//! differences and scaled by 1/h once. With the weights written as
//! ωₖ ∝ γₖ Π_{j≠k}(Sⱼ/m + 10⁻⁶)² (m = max vₖ² + tiny), one reciprocal and one division per
//! derivative replace the four divisions of the textbook form; the result is the same
//! formula. Valid for |φ₊₁ − φ₀| < 10¹⁸ (the squares stay finite); NaN in, NaN out.

use crate::diff::{upwind_norms, Axis, X, Y, Z};
use crate::lane::Lane;
use crate::window::Window;

/// Added to max(vₖ²) so that all-flat data (every vₖ = 0) gives weights, not 0/0.
const TINY: f32 = 1e-30;
/// Relative regularisation of the smoothness indicators (Jiang & Peng's ε = 10⁻⁶).
const EPS_REL: f32 = 1e-6;

/// The HJ-WENO5 approximation from five consecutive (undivided or divided) differences,
/// ordered upwind first: `v[0] = v₁ … v[4] = v₅` in Jiang & Peng's notation. Homogeneous
/// of degree one: scaling all inputs by c scales the result by c.
#[inline(always)]
pub fn hj_weno5<L: Lane>(v: [L; 5]) -> L {
    let [v1, v2, v3, v4, v5] = v;
    let c = |x: f32| L::splat(x);

    // The three third-order candidates (ENO stencils).
    let p1 = c(1.0 / 3.0).mul_add(v1, c(-7.0 / 6.0).mul_add(v2, c(11.0 / 6.0) * v3));
    let p2 = c(-1.0 / 6.0).mul_add(v2, c(5.0 / 6.0).mul_add(v3, c(1.0 / 3.0) * v4));
    let p3 = c(1.0 / 3.0).mul_add(v3, c(5.0 / 6.0).mul_add(v4, c(-1.0 / 6.0) * v5));

    // Smoothness indicators S₁..S₃.
    let q13 = c(13.0 / 12.0);
    let q14 = c(0.25);
    let a1 = (v1 - v2) - (v2 - v3);
    let b1 = (v1 - c(4.0) * v2) + c(3.0) * v3;
    let a2 = (v2 - v3) - (v3 - v4);
    let b2 = v2 - v4;
    let a3 = (v3 - v4) - (v4 - v5);
    let b3 = (c(3.0) * v3 - c(4.0) * v4) + v5;
    let s1 = q13.mul_add(a1 * a1, q14 * (b1 * b1));
    let s2 = q13.mul_add(a2 * a2, q14 * (b2 * b2));
    let s3 = q13.mul_add(a3 * a3, q14 * (b3 * b3));

    // Scale-invariant regularisation: work with S/m + 1e-6, m = max v² + tiny.
    let m = (v1 * v1).max(v2 * v2).max(v3 * v3).max(v4 * v4).max(v5 * v5) + c(TINY);
    let r = c(1.0) / m;
    let e = c(EPS_REL);
    let t1 = s1.mul_add(r, e);
    let t2 = s2.mul_add(r, e);
    let t3 = s3.mul_add(r, e);
    let (d1, d2, d3) = (t1 * t1, t2 * t2, t3 * t3);
    // αₖ = γₖ / dₖ  ⇒  ωₖ ∝ γₖ Π_{j≠k} dⱼ.
    let w1 = c(0.1) * (d2 * d3);
    let w2 = c(0.6) * (d1 * d3);
    let w3 = c(0.3) * (d1 * d2);
    w1.mul_add(p1, w2.mul_add(p2, w3 * p3)) / ((w1 + w2) + w3)
}

/// The HJ-WENO5 pair `(φₐ⁻, φₐ⁺)` along axis `A`: left- and right-biased fifth-order
/// derivatives from the 7 values φ₋₃..φ₊₃ (Jiang & Peng 2000; Nielsen & Museth
/// 2006, Sec. 4.1).
/// `inv_h` = 1 / voxel size.
#[inline(always)]
pub fn weno5_one_sided<L: Lane, W: Window<L>, A: Axis>(w: &W, inv_h: L) -> (L, L) {
    let p = [
        A::at::<L, W, -3>(w),
        A::at::<L, W, -2>(w),
        A::at::<L, W, -1>(w),
        w.centre(),
        A::at::<L, W, 1>(w),
        A::at::<L, W, 2>(w),
        A::at::<L, W, 3>(w),
    ];
    // d[k] = φ_{k-2} − φ_{k-3}: the backward difference at offset k−2, k = 0..5.
    let d = [p[1] - p[0], p[2] - p[1], p[3] - p[2], p[4] - p[3], p[5] - p[4], p[6] - p[5]];
    let minus = hj_weno5([d[0], d[1], d[2], d[3], d[4]]);
    let plus = hj_weno5([d[5], d[4], d[3], d[2], d[1]]);
    (minus * inv_h, plus * inv_h)
}

/// The upwind gradient norms `(∇⁺, ∇⁻)` of Sec. 4.7 built from HJ-WENO5 derivatives
/// (see [`upwind_norms`]). Reads the 19-point star.
#[inline(always)]
pub fn weno5_norms<L: Lane, W: Window<L>>(w: &W, inv_h: L) -> (L, L) {
    let (xm, xp) = weno5_one_sided::<L, W, X>(w, inv_h);
    let (ym, yp) = weno5_one_sided::<L, W, Y>(w, inv_h);
    let (zm, zp) = weno5_one_sided::<L, W, Z>(w, inv_h);
    upwind_norms([xm, ym, zm], [xp, yp, zp])
}
