//! Mean curvature by central differences: van der Laan et al. 2011, eq. (2)
//! discretised as eq. (4).
//!
//! # Convention
//!
//! κ = ½ ∇·(∇φ/|∇φ|), the paper's eq. (2) *with* its factor ½: the mean of the two
//! principal curvatures. A sphere of radius r has κ = 1/r (its level sets at distance ρ
//! from the centre have κ = 1/ρ); a cylinder of radius r has κ = 1/(2r). The same κ enters
//! the speed of eq. (3) and the volume-conserving flow of eq. (5).
//!
//! # Vanishing gradients
//!
//! Where the central gradient vanishes, κ is undefined. [`curvature_speed`] (κ∇⁰, the
//! form eq. (3) needs) divides by `max(|∇⁰φ|², GRAD2_MIN)`; its numerator is bounded by
//! `|∇⁰φ|²` times the second derivatives, so it stays bounded and is exactly 0 for a zero
//! gradient. [`mean_curvature`] returns 0 where `|∇⁰φ|² ≤ GRAD2_MIN`.

use crate::lane::Lane;
use crate::window::Window;

/// Below this squared central-gradient norm (dimensionless, φ in world units divided by
/// world units) the gradient counts as vanishing. φ is distance-like in this project
/// (|∇φ| ≈ 1), so this is far below any meaningful gradient.
pub const GRAD2_MIN: f32 = 1e-12;

/// Central differences of φ up to second order at the centre, *undivided* (multiply by
/// the factors given to get derivatives): first `g[a] = φ₊₁ − φ₋₁` (= 2h D⁰ᵃ), second
/// `d2[a] = φ₊₁ − 2φ₀ + φ₋₁` (= h² D⁰ᵃᵃ), mixed `m = [xy, xz, yz]` with
/// `φ₊₊ − φ₊₋ − φ₋₊ + φ₋₋` (= 4h² D⁰ᵃᵇ). Reads the 3×3×3 box without its 8 corners.
#[derive(Clone, Copy, Debug)]
pub struct CentralDiffs<L> {
    pub g: [L; 3],
    pub d2: [L; 3],
    pub m: [L; 3],
}

/// The undivided central differences of the 3×3×3 box (van der Laan et al. 2011,
/// Sec. 4.7: D⁰ᵃ, D⁰ᵃᵇ).
#[inline(always)]
pub fn central_diffs<L: Lane, W: Window<L>>(w: &W) -> CentralDiffs<L> {
    let c = w.centre();
    let two_c = c + c;
    let (xm, xp) = (w.at::<-1, 0, 0>(), w.at::<1, 0, 0>());
    let (ym, yp) = (w.at::<0, -1, 0>(), w.at::<0, 1, 0>());
    let (zm, zp) = (w.at::<0, 0, -1>(), w.at::<0, 0, 1>());
    let mixed = |pp: L, pm: L, mp: L, mm: L| (pp - pm) - (mp - mm);
    CentralDiffs {
        g: [xp - xm, yp - ym, zp - zm],
        d2: [(xp + xm) - two_c, (yp + ym) - two_c, (zp + zm) - two_c],
        m: [
            mixed(w.at::<1, 1, 0>(), w.at::<1, -1, 0>(), w.at::<-1, 1, 0>(), w.at::<-1, -1, 0>()),
            mixed(w.at::<1, 0, 1>(), w.at::<1, 0, -1>(), w.at::<-1, 0, 1>(), w.at::<-1, 0, -1>()),
            mixed(w.at::<0, 1, 1>(), w.at::<0, 1, -1>(), w.at::<0, -1, 1>(), w.at::<0, -1, -1>()),
        ],
    }
}

/// `(N, G)` with κ∇⁰ = N / (2h² G) and G = Σ gₐ² = 4h² |∇⁰φ|²: eq. (4) multiplied by ∇⁰
/// and rewritten in undivided differences,
/// N = Σₐ d2ₐ (G − gₐ²) − ½ (g_x g_y m_xy + g_x g_z m_xz + g_y g_z m_yz).
#[inline(always)]
fn numerator<L: Lane>(d: &CentralDiffs<L>) -> (L, L) {
    let [gx, gy, gz] = d.g;
    let (sx, sy, sz) = (gx * gx, gy * gy, gz * gz);
    let big_g = sx + sy + sz;
    let [dxx, dyy, dzz] = d.d2;
    let [mxy, mxz, myz] = d.m;
    let diag = dxx.mul_add(sy + sz, dyy.mul_add(sx + sz, dzz * (sx + sy)));
    let cross = (gx * gy).mul_add(mxy, (gx * gz).mul_add(mxz, (gy * gz) * myz));
    (cross.mul_add(L::splat(-0.5), diag), big_g)
}

/// κ∇⁰: the mean curvature times the central gradient norm, the curvature term of eq. (3)
/// without its weight ε (van der Laan et al. 2011, Sec. 4.7, eq. (4) times ∇⁰). No square root: κ∇⁰
/// = ½ (Δφ |∇φ|² − ∇φᵀ H ∇φ) / |∇φ|². Bounded where the gradient vanishes (0 at a zero
/// gradient). Reads the 3×3×3 box without corners; `inv_h` = 1 / voxel size.
#[inline(always)]
pub fn curvature_speed<L: Lane, W: Window<L>>(w: &W, inv_h: L) -> L {
    let (n, big_g) = numerator(&central_diffs(w));
    let g_min = L::splat(4.0 * GRAD2_MIN) / (inv_h * inv_h);
    (L::splat(0.5) * inv_h * inv_h) * n / big_g.max(g_min)
}

/// Mean curvature κ (van der Laan et al. 2011, eq. (4), with the ½ of eq. (2): 1/r on a
/// sphere); 0 where `|∇⁰φ|² ≤ GRAD2_MIN`. `inv_h` = 1 / voxel size.
#[inline(always)]
pub fn mean_curvature<L: Lane, W: Window<L>>(w: &W, inv_h: L) -> L {
    let (n, big_g) = numerator(&central_diffs(w));
    let g_min = L::splat(4.0 * GRAD2_MIN) / (inv_h * inv_h);
    let safe_g = big_g.max(g_min);
    let kappa = inv_h * n / (safe_g * safe_g.sqrt());
    big_g.select_gt(g_min, kappa, L::splat(0.0))
}

/// `(κ∇⁰, ∇⁰)` from one pass over the box: the curvature term of eq. (3) and the central
/// gradient norm, sharing the differences (used for the κ̄ integrals of eq. (6)).
#[inline(always)]
pub fn curvature_speed_and_norm<L: Lane, W: Window<L>>(w: &W, inv_h: L) -> (L, L) {
    let (n, big_g) = numerator(&central_diffs(w));
    let g_min = L::splat(4.0 * GRAD2_MIN) / (inv_h * inv_h);
    let ks = (L::splat(0.5) * inv_h * inv_h) * n / big_g.max(g_min);
    (ks, big_g.sqrt() * (L::splat(0.5) * inv_h))
}

/// κ∇ on a lattice with spacing `sₐ` per axis (`inv_spacing[a]` = 1/sₐ): the divided
/// differences of each axis, gₐ/sₐ, d2ₐ/sₐ² and mixed m_ab/(sₐ s_b), put into eq. (4)
/// as rewritten for [`curvature_speed`] with h = 1 (the formula is the same in divided
/// differences). An axis with `inv_spacing` 0 drops out: on a 2D image (one slice) this is
/// ½ the curvature of the curve in the slice (κ = ½∇·n counts the missing principal
/// curvature as 0), so a caller that wants the curve's curvature doubles the weight.
/// With `inv_spacing` all `1/h` it equals [`curvature_speed`] up to rounding.
#[inline(always)]
pub fn curvature_speed_aniso<L: Lane, W: Window<L>>(w: &W, inv_spacing: [L; 3]) -> L {
    let d = central_diffs(w);
    let [ix, iy, iz] = inv_spacing;
    let scaled = CentralDiffs {
        g: [d.g[0] * ix, d.g[1] * iy, d.g[2] * iz],
        d2: [d.d2[0] * (ix * ix), d.d2[1] * (iy * iy), d.d2[2] * (iz * iz)],
        m: [d.m[0] * (ix * iy), d.m[1] * (ix * iz), d.m[2] * (iy * iz)],
    };
    let (n, big_g) = numerator(&scaled);
    L::splat(0.5) * n / big_g.max(L::splat(4.0 * GRAD2_MIN))
}

/// [`curvature_speed_aniso`] with the z-axis dropped (`inv_spacing` 0 along z: a planar
/// lattice, one slice of a 2-D image), from the 3×3 square of the slice alone: the z-terms
/// of eq. (4) are finite differences times 0, so they add nothing, and the value is that
/// of [`curvature_speed_aniso`] (up to the sign of an exact zero) without reading a voxel
/// off the slice.
#[inline(always)]
pub fn curvature_speed_planar<L: Lane, W: Window<L>>(w: &W, inv_spacing: [L; 2]) -> L {
    let c = w.centre();
    let two_c = c + c;
    let (xm, xp) = (w.at::<-1, 0, 0>(), w.at::<1, 0, 0>());
    let (ym, yp) = (w.at::<0, -1, 0>(), w.at::<0, 1, 0>());
    let mxy = (w.at::<1, 1, 0>() - w.at::<1, -1, 0>()) - (w.at::<-1, 1, 0>() - w.at::<-1, -1, 0>());
    let [ix, iy] = inv_spacing;
    let (gx, gy) = ((xp - xm) * ix, (yp - ym) * iy);
    let (dxx, dyy) = (((xp + xm) - two_c) * (ix * ix), ((yp + ym) - two_c) * (iy * iy));
    let mxy = mxy * (ix * iy);
    let (sx, sy) = (gx * gx, gy * gy);
    // `numerator` with g_z, d2_z and the mixed z-terms 0.
    let diag = dxx.mul_add(sy, dyy * sx);
    let n = ((gx * gy) * mxy).mul_add(L::splat(-0.5), diag);
    L::splat(0.5) * n / (sx + sy).max(L::splat(4.0 * GRAD2_MIN))
}
