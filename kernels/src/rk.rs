//! Time integration: forward Euler (van der Laan et al. 2011, Sec. 4.7), the third-order TVD
//! Runge–Kutta scheme of Shu & Osher 1988 (van der Laan et al. 2011, Sec. 5.2; Nielsen &
//! Museth 2006, Sec. 4.1), and CFL time-step limits.
//!
//! TVD-RK3 for φ_t = 𝓛(φ), written as three Euler steps and convex combinations:
//!
//! ```text
//! φ⁽¹⁾  = φⁿ + Δt 𝓛(φⁿ)                                   stage 1
//! φ⁽²⁾  = ¾ φⁿ + ¼ (φ⁽¹⁾ + Δt 𝓛(φ⁽¹⁾))                    stage 2
//! φⁿ⁺¹ = ⅓ φⁿ + ⅔ (φ⁽²⁾ + Δt 𝓛(φ⁽²⁾))                    stage 3
//! ```
//!
//! A stage is a const generic (`STAGE` in 1..=3, [`crate::Rk3`]) decided once per sweep, or,
//! for stages 2 and 3, a pair of weights decided once per sweep ([`crate::Rk3Blend`]: one
//! compiled kernel for both, the same bits).

use crate::lane::Lane;

/// The weights `(a, b)` of TVD-RK3 stage `stage` (Shu & Osher 1988):
/// `φ = a φⁿ + b (φᵏ + Δt 𝓛(φᵏ))`, `(0, 1)`, `(¾, ¼)`, `(⅓, ⅔)` for stages 1, 2, 3 (each the
/// nearest `f32`); `None` for any other stage.
pub const fn rk3_weights(stage: u8) -> Option<(f32, f32)> {
    match stage {
        1 => Some((0.0, 1.0)),
        2 => Some((0.75, 0.25)),
        3 => Some((1.0 / 3.0, 2.0 / 3.0)),
        _ => None,
    }
}

/// The TVD-RK3 stage combination (Shu & Osher 1988) for one lane group:
/// `a φⁿ + b (φᵏ + Δt 𝓛(φᵏ))` with `(a, b)` from [`rk3_weights`]. `phi_n` is ignored in
/// stage 1 (that stage is the Euler step of Sec. 4.7). `STAGE` outside 1..=3 does not
/// compile.
#[inline(always)]
pub fn rk3_combine<L: Lane, const STAGE: u8>(phi_n: L, phi_k: L, dt: L, rate: L) -> L {
    let euler = dt.mul_add(rate, phi_k);
    let (a, b) = const {
        match rk3_weights(STAGE) {
            Some(w) => w,
            None => panic!("TVD-RK3 has stages 1, 2, 3"),
        }
    };
    if STAGE == 1 {
        euler
    } else {
        rk3_blend(phi_n, euler, L::splat(a), L::splat(b))
    }
}

/// `a φⁿ + b e` with `e` the Euler step `φᵏ + Δt 𝓛(φᵏ)`, in the order of operations every
/// later TVD-RK3 stage uses ([`rk3_combine`] at stages 2 and 3, [`crate::Rk3Blend`]):
/// `b · e + (a · φⁿ)`, fused.
#[inline(always)]
pub fn rk3_blend<L: Lane>(phi_n: L, euler: L, a: L, b: L) -> L {
    b.mul_add(euler, a * phi_n)
}

/// Forward Euler `φ + Δt 𝓛` (van der Laan et al. 2011, Sec. 4.7: φⁿ⁺¹ = φⁿ + Δt S). Same
/// bits as [`rk3_combine`] at stage 1.
#[inline(always)]
pub fn euler<L: Lane>(phi: L, dt: L, rate: L) -> L {
    dt.mul_add(rate, phi)
}

/// Clamps to the band `[−γ, γ]` (van der Laan et al. 2011, Sec. 3.1: band values live in
/// (−γ, γ)). NaN maps to −γ (see [`Lane::max`]); `gamma = +∞` disables the clamp (NaN then
/// maps to −∞).
#[inline(always)]
pub fn clamp_band<L: Lane>(phi: L, gamma: L) -> L {
    phi.max(-gamma).min(gamma)
}

// ---------------------------------------------------------------------------------------
// CFL limits. Scalar functions: computed once per time step, outside every loop. Each
// returns the largest stable Δt times `cfl` (use cfl ≤ 1; 0.5 is customary), or +∞ when
// the term imposes no limit.

/// Advection by a velocity field u (φ_t + u·∇φ = 0, upwind): Δt · max(|u|+|v|+|w|) / h ≤
/// cfl, the CFL condition of upwind advection (Osher & Fedkiw ch. 3) with Δx = Δy = Δz = h.
/// `max_abs_sum` is the maximum over the band of `|u| + |v| + |w|`.
pub fn cfl_dt_advection(max_abs_sum: f32, h: f32, cfl: f32) -> f32 {
    limit(cfl * h, max_abs_sum.abs())
}

/// Motion in the normal direction with speed F (the F|∇φ| and rescaling terms of
/// eq. (3)): the Hamiltonian's partial derivatives are F·nₐ with Σ|nₐ| ≤ √3, so
/// Δt · √3 max|F| / h ≤ cfl.
pub fn cfl_dt_normal(max_abs_speed: f32, h: f32, cfl: f32) -> f32 {
    limit(cfl * h, 3f32.sqrt() * max_abs_speed.abs())
}

/// The pseudo-time step Δτ = cfl · h / √3 of the renormalisation sweeps
/// φ_τ = S(φ⁰)(1 − |∇φ|) ([`crate::renorm::RenormRate`]). The Godunov scheme for
/// H = |∇φ| is monotone for Δτ Σₐ |∂H/∂pₐ| / h ≤ 1, and ∂H/∂pₐ = nₐ with Σₐ |nₐ| ≤ √3
/// (Osher & Fedkiw ch. 6–7; the same bound as [`cfl_dt_normal`] with |F| = 1, whose bits
/// this returns). The Russo–Smereka subcell term at interface voxels, φ_τ = (D − φ)/h,
/// relaxes φ towards the anchor D and is stable (no overshoot) for Δτ ≤ h; as
/// h/√3 < h, the Godunov limit is the binding one.
pub fn cfl_dt_renorm(h: f32, cfl: f32) -> f32 {
    limit(cfl * h, 3f32.sqrt())
}

/// The parabolic limit of the curvature term εκ|∇φ| of eq. (3) with κ = ½∇·n (so the
/// diffusion coefficient is b = ε/2): Δt · 2b (1/h² + 1/h² + 1/h²) ≤ cfl, i.e.
/// Δt ≤ cfl · h² / (3|ε|) (the explicit parabolic limit for φ_t = bκ|∇φ| with κ = ∇·n in
/// Osher & Fedkiw ch. 4).
pub fn cfl_dt_curvature(eps: f32, h: f32, cfl: f32) -> f32 {
    limit(cfl * h * h, 3.0 * eps.abs())
}

/// All of eq. (3) at once: Δt (√3 (max|F| + |w_r|) / h + 3|ε| / h²) ≤ cfl, where `w_r` is
/// the weight of the rescaling term (|sgn| ≤ 1). Smaller than each single limit.
pub fn cfl_dt_eq3(max_abs_speed: f32, eps: f32, rescale_weight: f32, h: f32, cfl: f32) -> f32 {
    limit(cfl, cfl_rate_eq3(max_abs_speed, eps, rescale_weight, h))
}

/// The rate of [`cfl_dt_eq3`]: √3 (max|F| + |w_r|) / h + 3|ε| / h², so that Δt · rate ≤
/// cfl. Rates of terms that act together add up (with [`cfl_rate_advection`]).
pub fn cfl_rate_eq3(max_abs_speed: f32, eps: f32, rescale_weight: f32, h: f32) -> f32 {
    3f32.sqrt() * (max_abs_speed.abs() + rescale_weight.abs()) / h + 3.0 * eps.abs() / (h * h)
}

/// The rate of [`cfl_dt_advection`]: max(|u|+|v|+|w|) / h.
pub fn cfl_rate_advection(max_abs_sum: f32, h: f32) -> f32 {
    max_abs_sum.abs() / h
}

/// The rate of [`crate::ImageRate`] on a lattice with spacing sₐ (`inv_spacing[a]` =
/// 1/sₐ, 0 for an axis without derivatives): with n = √(Σ 1/sₐ²) (√3/h when isotropic),
/// (max|F| + |w|) n + max|E| Σ 1/sₐ² + max(|u|+|v|+|w|) max(1/sₐ). The isotropic
/// rates of [`cfl_rate_eq3`] and [`cfl_rate_advection`] with each h replaced by the
/// spacings (the advection bound is the conservative one with the smallest spacing).
pub fn cfl_rate_image(
    max_abs_speed: f32,
    max_abs_curvature: f32,
    rescale_weight: f32,
    max_abs_sum: f32,
    inv_spacing: [f32; 3],
) -> f32 {
    let sum2: f32 = inv_spacing.iter().map(|i| i * i).sum();
    let max_inv = inv_spacing.iter().fold(0.0f32, |m, i| m.max(i.abs()));
    (max_abs_speed.abs() + rescale_weight.abs()) * sum2.sqrt()
        + max_abs_curvature.abs() * sum2
        + max_abs_sum.abs() * max_inv
}

fn limit(numerator: f32, rate: f32) -> f32 {
    if rate > 0.0 {
        numerator / rate
    } else {
        f32::INFINITY
    }
}
