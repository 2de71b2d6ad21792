//! Speed terms: the right-hand side S of eq. (3) of van der Laan et al. 2011
//! (discretised in Sec. 4.7), advection by an external velocity, and the smoothed delta function
//! and curvature integrals of the volume-conserving flow (Sec. 5.2, eq. (5)–(7)).

use crate::curvature::curvature_speed_and_norm;
use crate::lane::Lane;
use crate::window::Window;

/// The smoothed sign φ / √(φ² + h²) that replaces sgn(φ) in the rescaling term (van der
/// Laan et al. 2011, Sec. 3.2: a smooth sign improves stability). `h` is the voxel size; the result
/// is in (−1, 1), 0 at φ = 0, and ±1 far from the interface.
#[inline(always)]
pub fn smoothed_sign<L: Lane>(phi: L, h: L) -> L {
    phi / phi.mul_add(phi, h * h).sqrt()
}

/// S of eq. (3) as discretised in Sec. 4.7 of van der Laan et al. 2011:
///
/// S = −(max(F,0) ∇⁺ + min(F,0) ∇⁻) + ε κ∇⁰ + w (max(s,0)(1 − ∇⁺) + min(s,0)(1 − ∇⁻))
///
/// with data speed `f` (F), curvature weight `eps` (ε), curvature term `kappa_grad`
/// (κ∇⁰ from [`crate::curvature::curvature_speed`]), smoothed sign `sign` (s, from
/// [`smoothed_sign`]) and the upwind norms `(grad_plus, grad_minus)` = (∇⁺, ∇⁻) of either
/// scheme. `rescale` (w) weights the rescaling term: 1 is eq. (3), 0 drops it (eq. (5) is
/// eq. (3) with F = κ̄, ε = 1, w = 0).
///
/// Evaluated as `w s + ε κ∇⁰ − (max(F,0) + w max(s,0)) ∇⁺ − (min(F,0) + w min(s,0)) ∇⁻`,
/// the same sum regrouped. A NaN F or s counts as 0 in the upwind choice (see
/// [`Lane::max`]).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn eq3_speed<L: Lane>(
    f: L,
    eps: L,
    rescale: L,
    sign: L,
    grad_plus: L,
    grad_minus: L,
    kappa_grad: L,
) -> L {
    let z = L::splat(0.0);
    let a = f.max(z) + rescale * sign.max(z);
    let b = f.min(z) + rescale * sign.min(z);
    let base = eps.mul_add(kappa_grad, rescale * sign);
    (-a).mul_add(grad_plus, (-b).mul_add(grad_minus, base))
}

/// The rate −u·∇φ of advection by an external velocity `u` (φ_t + u·∇φ = 0), upwinded per
/// axis: the backward (left-biased) derivative `dm[a]` where uₐ > 0, the forward one
/// `dp[a]` where uₐ < 0 (upwinding as in Osher & Fedkiw ch. 3; with HJ-WENO5 derivatives the scheme of
/// flow test of Nielsen & Museth 2006, Sec. 4.2).
#[inline(always)]
pub fn advection_rate<L: Lane>(u: [L; 3], dm: [L; 3], dp: [L; 3]) -> L {
    let z = L::splat(0.0);
    let mut acc = z;
    for a in 0..3 {
        acc = u[a].max(z).mul_add(dm[a], acc);
        acc = u[a].min(z).mul_add(dp[a], acc);
    }
    -acc
}

/// cos(y) for |y| ≤ π/2 from its Taylor polynomial to y¹² (error < 10⁻⁸), in lane
/// arithmetic so that every lane type gives the same bits (wide's and libm's cos differ).
#[inline(always)]
fn cos_half_range<L: Lane>(y: L) -> L {
    let y2 = y * y;
    let c = |x: f64| L::splat(x as f32);
    let mut p = c(1.0 / 479_001_600.0);
    p = p.mul_add(y2, c(-1.0 / 3_628_800.0));
    p = p.mul_add(y2, c(1.0 / 40_320.0));
    p = p.mul_add(y2, c(-1.0 / 720.0));
    p = p.mul_add(y2, c(1.0 / 24.0));
    p = p.mul_add(y2, c(-0.5));
    p.mul_add(y2, c(1.0))
}

/// The smoothed delta function of eq. (7) of van der Laan et al. 2011,
/// δ(φ) = (1 + cos(πφ/ε)) / 2ε for |φ| < ε and 0 otherwise (the paper's `φ < ε` means
/// |φ| < ε), evaluated as cos²(πφ/2ε)/ε. `width` is ε, a multiple of the voxel size.
#[inline(always)]
pub fn smoothed_delta<L: Lane>(phi: L, width: L) -> L {
    let one = L::splat(1.0);
    let t = (phi / width).max(-one).min(one);
    let c = cos_half_range(t * L::splat(core::f32::consts::FRAC_PI_2));
    width.select_gt(phi.abs(), c * c / width, L::splat(0.0))
}

/// The integrands of the average curvature κ̄ of eq. (6): `(κ δ(φ) |∇φ|, δ(φ) |∇φ|)` at
/// the centre, with |∇φ| = ∇⁰ and κ from eq. (4). Summed over the band (times h³, which
/// cancels) they give κ̄ = Σ first / Σ second. `width` is the ε of eq. (7).
#[inline(always)]
pub fn kappa_bar_integrands<L: Lane, W: Window<L>>(w: &W, inv_h: L, width: L) -> (L, L) {
    let (kappa_grad, grad) = curvature_speed_and_norm(w, inv_h);
    let delta = smoothed_delta(w.centre(), width);
    (delta * kappa_grad, delta * grad)
}
