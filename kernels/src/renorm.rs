//! Renormalisation: pseudo-time sweeps of φ_τ = sgn(φ⁰)(1 − |∇φ|) (Sussman, Smereka &
//! Osher 1994) with Godunov upwinding and the subcell fix of Russo & Smereka, "A remark
//! on computing distance functions", J. Comput. Phys. 163 (2000) 51–67, Sec. 3, which
//! keeps the zero crossings of φ⁰ in place.
//!
//! Two kernels: [`InterfaceAnchor`] runs once over φ⁰ (the values before the first sweep)
//! and gives every voxel its *anchor* — Russo & Smereka's distance estimate D at the voxels
//! next to the interface, ±∞ (the sign of φ⁰) elsewhere; [`RenormRate`] is the rate of
//! one sweep, read with those anchors; [`AnchoredRenormRate`] is the first sweep's rate
//! with the anchors evaluated in place (no anchor pass when one sweep is all). Forward
//! Euler in pseudo time with the step of [`crate::rk::cfl_dt_renorm`] wraps them
//! ([`crate::Euler`]).

use crate::diff::godunov_norms;
use crate::diff::{Axis, X, Y, Z};
use crate::error::KernelError;
use crate::kernel::{ScalarField, Scheme, VoxelKernel};
use crate::lane::Lane;
use crate::window::Window;
use core::marker::PhantomData;

/// Added to each axis' difference bound so that a flat neighbourhood gives D = 0·φ⁰/tiny
/// instead of 0/0 (undivided differences, world units: far below any resolvable slope).
const TINY: f32 = 1e-30;

/// 1 where `v < 0` (inside), else 0 (NaN counts as outside).
#[inline(always)]
fn inside<L: Lane>(v: L) -> L {
    L::splat(0.0).select_gt(v, L::splat(1.0), L::splat(0.0))
}

/// Where the slope of φ⁰ changes by this fraction or more across a voxel, the distance
/// estimate takes Russo & Smereka's bound outright (see [`slope`]).
const UNRESOLVED: f32 = 0.25;

/// The undivided slope of φ⁰ along `A` for the distance estimate, never below `TINY`.
///
/// Russo & Smereka take the bound B = max(|φ₊ − φ₋|/2, |φ₊ − φ₀|, |φ₀ − φ₋|). B exceeds the
/// slope of a smooth distance function by O(h/r) and so moves a resolved curved interface
/// by O(h²/r) per renormalisation, which accumulates over a run. Where φ⁰ is resolved
/// along the axis, the central difference C = |φ₊ − φ₋|/2 is a second-order estimate
/// instead. With the one-sided differences d₊ = φ₊ − φ₀, d₋ = φ₀ − φ₋ and the relative
/// change of slope q = |d₊ − d₋| / (|d₊| + |d₋|) (0 on a straight profile, 1 where one
/// side is flat), the slope is C + w (B − C) with w = min(1, (q / 0.25)²) where φ⁰ is
/// monotone along the axis (d₊ d₋ > 0) and w = 1 where it is not (at an extremum, where C
/// vanishes). Resolved profiles (q ≈ h/r) get C up to O(q²); thin, under-resolved
/// features (a sheet a voxel thick, where the advected profile is rounded) get B, which
/// keeps them from inflating. The blend is continuous in φ⁰, so no voxel switches rule
/// abruptly between sweeps.
#[inline(always)]
fn slope<L: Lane, W: Window<L>, A: Axis>(w: &W) -> L {
    let (m, c, p) = (A::at::<L, W, -1>(w), w.centre(), A::at::<L, W, 1>(w));
    let (dp, dm) = (p - c, c - m);
    let (z, one) = (L::splat(0.0), L::splat(1.0));
    let central = (p - m).abs() * L::splat(0.5);
    let bound = central.max(dp.abs()).max(dm.abs());
    let q = (dp - dm).abs() / (dp.abs() + dm.abs() + L::splat(TINY));
    let q = q * L::splat(1.0 / UNRESOLVED);
    // dp·dm > 0: monotone along the axis.
    let weight = (dp * dm).select_gt(z, (q * q).min(one), one);
    weight.mul_add(bound - central, central).max(L::splat(TINY))
}

/// The anchor of each voxel, evaluated over φ⁰: at a voxel next to the interface —
/// inside (φ⁰ < 0) while a face neighbour is not, or the other way round — Russo &
/// Smereka's distance estimate D = h φ⁰ / Δφ⁰ with Δφ⁰ = (Σₐ sₐ²)^½ over the axis slopes
/// sₐ (their Sec. 3, the three-dimensional form; sₐ blends their bound with the central
/// difference where φ⁰ is resolved, see `slope`);
/// elsewhere +∞ where φ⁰ ≥ 0 and −∞ where φ⁰ < 0. Reads the six face neighbours.
///
/// φ = 0 counts as outside (the crate's convention φ < 0 inside), so a voxel with φ⁰ = 0
/// next to an inside voxel is anchored at 0. NaN in φ⁰ yields a NaN or infinite anchor
/// (the band clamp of the sweep then maps the voxel to −γ); nothing panics.
#[derive(Clone, Copy, Debug)]
pub struct InterfaceAnchor {
    /// h, the voxel size (φ in world units).
    pub voxel_size: f32,
}

impl VoxelKernel for InterfaceAnchor {
    const AXIS_REACH: i32 = 1;
    const BOX_REACH: i32 = 0;

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, _first: usize) -> L {
        let c = w.centre();
        let n = [
            w.at::<-1, 0, 0>(),
            w.at::<1, 0, 0>(),
            w.at::<0, -1, 0>(),
            w.at::<0, 1, 0>(),
            w.at::<0, 0, -1>(),
            w.at::<0, 0, 1>(),
        ];
        // Neighbours inside: at least one (min) and all (max) — as 0/1 lanes.
        let nmin = n[0].min(n[1]).min(n[2]).min(n[3]).min(n[4]).min(n[5]);
        let nmax = n[0].max(n[1]).max(n[2]).max(n[3]).max(n[4]).max(n[5]);
        let (ic, some_in, all_in) = (inside(c), inside(nmin), inside(nmax));
        let one = L::splat(1.0);
        // Inside with an outside neighbour, or outside with an inside one.
        let mixed = ic * (one - all_in) + (one - ic) * some_in;
        let (sx, sy, sz) = (slope::<L, W, X>(w), slope::<L, W, Y>(w), slope::<L, W, Z>(w));
        let grad = sx.mul_add(sx, sy.mul_add(sy, sz * sz)).sqrt();
        let d = L::splat(self.voxel_size) * c / grad;
        let far = ic.select_gt(L::splat(0.5), L::splat(f32::NEG_INFINITY), L::splat(f32::INFINITY));
        mixed.select_gt(L::splat(0.5), d, far)
    }
}

/// The rate of one renormalisation sweep with the anchors `a` of [`InterfaceAnchor`]:
///
/// * next to the interface (|a| < ∞): (a − sgn(a)|φ|)/h, Russo & Smereka's subcell fix
///   (their eq. (14)), which relaxes φ to the anchor and so keeps the crossing of φ⁰;
/// * elsewhere: s (1 − G) with s = sgn(φ⁰) = sgn(a) and the Godunov norm G = G⁺ for
///   s > 0, G⁻ for s < 0 ([`godunov_norms`]) of the scheme's one-sided derivatives.
///
/// Both are computed in every lane and one is selected, so every lane type gives the same
/// bits. Reads the star of the scheme (±1 or ±3 along the axes).
#[derive(Clone, Copy, Debug)]
pub struct RenormRate<S, A> {
    /// The anchors: `&[f32]` per voxel in the block's order.
    pub anchor: A,
    /// h, the voxel size.
    pub voxel_size: f32,
    scheme: PhantomData<S>,
}

impl<S: Scheme, A: ScalarField> RenormRate<S, A> {
    /// Voxel size h and the anchors of φ⁰.
    pub fn new(voxel_size: f32, anchor: A) -> Self {
        RenormRate { anchor, voxel_size, scheme: PhantomData }
    }
}

impl<S: Scheme, A: ScalarField> VoxelKernel for RenormRate<S, A> {
    const AXIS_REACH: i32 = S::AXIS_REACH;
    const BOX_REACH: i32 = 0;

    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.anchor.check(voxels)
    }

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        renorm_rate::<S, L, W>(self.anchor.lanes::<L>(first), w, self.voxel_size)
    }
}

/// The rate of [`RenormRate`] at the lanes of `w` with anchors `a`.
#[inline(always)]
fn renorm_rate<S: Scheme, L: Lane, W: Window<L>>(a: L, w: &W, voxel_size: f32) -> L {
    let phi = w.centre();
    let (z, one) = (L::splat(0.0), L::splat(1.0));
    let h = L::splat(voxel_size);
    let inv_h = one / h;
    // sgn(a): +1, −1 or 0.
    let s = a.select_gt(z, one, z.select_gt(a, -one, z));
    let (dm, dp) = S::derivatives(w, inv_h);
    let (gp, gm) = godunov_norms(dm, dp);
    let g = s.select_gt(z, gp, gm);
    let eikonal = s * (one - g);
    let subcell = (a - s * phi.abs()) * inv_h;
    L::splat(f32::INFINITY).select_gt(a.abs(), subcell, eikonal)
}

/// The first renormalisation sweep's rate with the anchors evaluated in place: over φ⁰,
/// [`InterfaceAnchor`] followed by [`RenormRate`] with its result, the same operations in
/// the same order, so the same bits as the anchor pass and a sweep that reads its
/// anchors back. The sweep's star window (±1 or ±3 along the axes) holds the six face
/// neighbours the anchor reads, so a renormalisation of one sweep needs no anchor pass
/// and no anchor buffer.
#[derive(Clone, Copy, Debug)]
pub struct AnchoredRenormRate<S> {
    /// h, the voxel size.
    pub voxel_size: f32,
    scheme: PhantomData<S>,
}

impl<S: Scheme> AnchoredRenormRate<S> {
    /// Voxel size h; the window holds φ⁰.
    pub fn new(voxel_size: f32) -> Self {
        AnchoredRenormRate { voxel_size, scheme: PhantomData }
    }
}

impl<S: Scheme> VoxelKernel for AnchoredRenormRate<S> {
    const AXIS_REACH: i32 = if S::AXIS_REACH > 1 { S::AXIS_REACH } else { 1 };
    const BOX_REACH: i32 = 0;

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        let a = InterfaceAnchor { voxel_size: self.voxel_size }.eval(w, first);
        renorm_rate::<S, L, W>(a, w, self.voxel_size)
    }
}
