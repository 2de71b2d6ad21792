//! First differences, the upwind gradient norms ∇⁺ and ∇⁻ (van der Laan et al. 2011,
//! Sec. 4.7) and the Godunov norms G⁺ and G⁻ of the renormalisation sweeps ([`godunov_norms`]).
//!
//! All differences are divided differences: `inv_h` is `1 / voxel size`, so for a
//! signed-distance φ in world units the results are dimensionless (|∇φ| ≈ 1).

use crate::lane::Lane;
use crate::window::Window;

mod sealed {
    pub trait Sealed {}
}

/// A coordinate axis as a type, so that kernels loop over axes at compile time.
/// Sealed: [`X`], [`Y`], [`Z`].
pub trait Axis: sealed::Sealed + Copy + Default + Send + Sync + 'static {
    /// 0, 1, 2 for x, y, z.
    const INDEX: usize;
    /// The window's value `S` voxels along this axis.
    fn at<L: Lane, W: Window<L>, const S: i32>(w: &W) -> L;
}

/// The x axis (fastest in every layout).
#[derive(Clone, Copy, Debug, Default)]
pub struct X;
/// The y axis.
#[derive(Clone, Copy, Debug, Default)]
pub struct Y;
/// The z axis.
#[derive(Clone, Copy, Debug, Default)]
pub struct Z;

impl sealed::Sealed for X {}
impl sealed::Sealed for Y {}
impl sealed::Sealed for Z {}

impl Axis for X {
    const INDEX: usize = 0;
    #[inline(always)]
    fn at<L: Lane, W: Window<L>, const S: i32>(w: &W) -> L {
        w.at::<S, 0, 0>()
    }
}
impl Axis for Y {
    const INDEX: usize = 1;
    #[inline(always)]
    fn at<L: Lane, W: Window<L>, const S: i32>(w: &W) -> L {
        w.at::<0, S, 0>()
    }
}
impl Axis for Z {
    const INDEX: usize = 2;
    #[inline(always)]
    fn at<L: Lane, W: Window<L>, const S: i32>(w: &W) -> L {
        w.at::<0, 0, S>()
    }
}

/// Backward difference `D⁻ᵃφ = (φ₀ − φ₋₁) / h` along axis `A` (van der Laan et al. 2011, Sec. 4.7).
#[inline(always)]
pub fn diff_minus<L: Lane, W: Window<L>, A: Axis>(w: &W, inv_h: L) -> L {
    (w.centre() - A::at::<L, W, -1>(w)) * inv_h
}

/// Forward difference `D⁺ᵃφ = (φ₊₁ − φ₀) / h` along axis `A` (van der Laan et al. 2011, Sec. 4.7).
#[inline(always)]
pub fn diff_plus<L: Lane, W: Window<L>, A: Axis>(w: &W, inv_h: L) -> L {
    (A::at::<L, W, 1>(w) - w.centre()) * inv_h
}

/// Central difference `D⁰ᵃφ = (φ₊₁ − φ₋₁) / 2h` along axis `A` (van der Laan et al.
/// 2011, Sec. 4.7).
#[inline(always)]
pub fn diff_central<L: Lane, W: Window<L>, A: Axis>(w: &W, inv_h: L) -> L {
    (A::at::<L, W, 1>(w) - A::at::<L, W, -1>(w)) * (inv_h * L::splat(0.5))
}

/// The central-difference gradient `(D⁰ˣφ, D⁰ʸφ, D⁰ᶻφ)` (van der Laan et al. 2011, Sec. 4.7).
#[inline(always)]
pub fn central_gradient<L: Lane, W: Window<L>>(w: &W, inv_h: L) -> [L; 3] {
    [
        diff_central::<L, W, X>(w, inv_h),
        diff_central::<L, W, Y>(w, inv_h),
        diff_central::<L, W, Z>(w, inv_h),
    ]
}

/// ∇⁰ = |central gradient| (van der Laan et al. 2011, Sec. 4.7).
#[inline(always)]
pub fn central_norm<L: Lane, W: Window<L>>(w: &W, inv_h: L) -> L {
    let [gx, gy, gz] = central_gradient(w, inv_h);
    gx.mul_add(gx, gy.mul_add(gy, gz * gz)).sqrt()
}

/// The upwind gradient norms `(∇⁺, ∇⁻)` of van der Laan et al. 2011, Sec. 4.7, from one-sided
/// derivatives `dm[a]` (backward, left-biased) and `dp[a]` (forward, right-biased) per
/// axis:
///
/// * ∇⁺ = ( Σₐ max(dmₐ, 0)² + min(dpₐ, 0)² )^½ — for motion with positive speed,
/// * ∇⁻ = ( Σₐ max(dpₐ, 0)² + min(dmₐ, 0)² )^½ — for negative speed.
///
/// This is the Osher–Sethian/Rouy–Tourin upwind form the paper prints (both one-sided
/// terms of an axis are summed). It agrees with the per-axis `max` of the exact Godunov
/// flux except where the two one-sided derivatives of an axis point away from each other
/// (a local extremum of φ along that axis), where it is larger. The same function serves
/// first-order differences and HJ-WENO5 derivatives, so the two schemes differ only in
/// the derivatives.
///
/// NaN derivatives count as 0 (see [`Lane::max`]: NaN in the first operand yields `rhs`).
#[inline(always)]
pub fn upwind_norms<L: Lane>(dm: [L; 3], dp: [L; 3]) -> (L, L) {
    let z = L::splat(0.0);
    let mut plus = z;
    let mut minus = z;
    for a in 0..3 {
        let [mp, pm, pp, mm] = upwind_parts(dm[a], dp[a]);
        plus = mp.mul_add(mp, plus);
        plus = pm.mul_add(pm, plus);
        minus = pp.mul_add(pp, minus);
        minus = mm.mul_add(mm, minus);
    }
    (plus.sqrt(), minus.sqrt())
}

/// The one-sided derivatives of an axis split by sign: `[max(dm, 0), min(dp, 0),
/// max(dp, 0), min(dm, 0)]` (the upwind parts for a positive, then a negative sign).
#[inline(always)]
fn upwind_parts<L: Lane>(dm: L, dp: L) -> [L; 4] {
    let z = L::splat(0.0);
    [dm.max(z), dp.min(z), dp.max(z), dm.min(z)]
}

/// The Godunov upwind gradient norms `(G⁺, G⁻)` for a positive and a negative sign (or
/// speed), from one-sided derivatives `dm[a]` (backward, left-biased) and `dp[a]` (forward,
/// right-biased) per axis, as for [`upwind_norms`]:
///
/// * G⁺ = ( Σₐ max( max(dmₐ, 0)², min(dpₐ, 0)² ) )^½,
/// * G⁻ = ( Σₐ max( min(dmₐ, 0)², max(dpₐ, 0)² ) )^½.
///
/// This is Godunov's numerical Hamiltonian for H(∇φ) = |∇φ| (Rouy & Tourin, "A viscosity
/// solutions approach to shape-from-shading", SIAM J. Numer. Anal. 29 (1992) 867–884;
/// Osher & Fedkiw, *Level Set Methods and Dynamic Implicit Surfaces*, ch. 6–7, the
/// Godunov scheme for motion in the normal direction and for reinitialisation; the
/// discretisation of |∇φ| in Russo & Smereka, J. Comput. Phys. 163 (2000) 51–67), the
/// flux of the renormalisation sweeps of [`crate::renorm`]. G⁺ is the norm where the sign
/// (of φ⁰, or of the speed) is positive and information flows outward from the interface,
/// G⁻ where it is negative.
///
/// **Difference from [`upwind_norms`]:** per axis it takes the *larger* of the two upwind
/// squares, where [`upwind_norms`] *sums* them. They agree unless both one-sided terms of
/// an axis are non-zero: for G⁺ that is dmₐ > 0 > dpₐ, a local maximum of φ along the
/// axis; for G⁻ it is dmₐ < 0 < dpₐ, a local minimum. There the sum overestimates the
/// gradient (by √2 on a symmetric kink); the Godunov max is the entropy-consistent flux.
///
/// NaN derivatives count as 0 (see [`Lane::max`]: NaN in the first operand yields `rhs`),
/// as in [`upwind_norms`]. Summation order x, y, z with separate roundings (no fused
/// multiply-add), the same in every lane type.
#[inline(always)]
pub fn godunov_norms<L: Lane>(dm: [L; 3], dp: [L; 3]) -> (L, L) {
    let z = L::splat(0.0);
    let mut plus = z;
    let mut minus = z;
    for a in 0..3 {
        let [mp, pm, pp, mm] = upwind_parts(dm[a], dp[a]);
        plus = plus + (mp * mp).max(pm * pm);
        minus = minus + (mm * mm).max(pp * pp);
    }
    (plus.sqrt(), minus.sqrt())
}
