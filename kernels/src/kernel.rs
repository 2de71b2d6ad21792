//! Whole-voxel kernels: the objects the grid engines sweep over their blocks.
//!
//! A [`VoxelKernel`] turns a stencil [`Window`] into one value per lane. Settings that are
//! fixed for a sweep are fields (the same for every voxel) or type parameters (scheme,
//! RK stage, uniform vs. per-voxel speed), so nothing is decided per voxel. Rates
//! ([`Eq3Rate`], [`AdvectionRate`]) compute 𝓛(φ); [`Euler`] and [`Rk3`] wrap a rate into
//! a time step.

use crate::curvature::{curvature_speed, curvature_speed_aniso, curvature_speed_planar};
use crate::diff::{diff_minus, diff_plus, upwind_norms, Axis, X, Y, Z};
use crate::error::KernelError;
use crate::lane::Lane;
use crate::rk::{clamp_band, euler, rk3_blend, rk3_combine, rk3_weights};
use crate::speed::{advection_rate, eq3_speed, smoothed_sign};
use crate::weno::weno5_one_sided;
use crate::window::Window;
use core::marker::PhantomData;

/// A per-voxel computation over a stencil window.
///
/// `first` is the index of the lane group's first voxel in the voxel order of the block
/// being swept (tile order for [`crate::TileBlock`], x-fastest interior order for
/// [`crate::DenseBlock`], whatever the caller uses for point windows); per-voxel inputs
/// (speed, velocity, φⁿ) are read at `first .. first + LANES` in that order.
pub trait VoxelKernel: Sync {
    /// Largest axis offset read (1: first order / curvature, 3: HJ-WENO5).
    const AXIS_REACH: i32;
    /// Largest max-norm of diagonal offsets read (1 with curvature, 0 without).
    const BOX_REACH: i32;

    /// Checks per-voxel inputs against a block of `voxels` voxels. Drivers call it once
    /// per block, before the loop.
    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        let _ = voxels;
        Ok(())
    }

    /// The kernel's value for the lane group at the window's centre.
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L;
}

// ---------------------------------------------------------------------------------------
// Spatial schemes for the hyperbolic terms.

mod sealed {
    pub trait Sealed {}
}

/// How one-sided derivatives are approximated: [`Upwind1`] or [`Weno5`]. Sealed; chosen
/// once per sweep as a type parameter.
pub trait Scheme: sealed::Sealed + Copy + Default + Send + Sync + 'static {
    /// Axis offsets read.
    const AXIS_REACH: i32;
    /// Name for output (`"upwind1"`, `"weno5"`).
    const NAME: &'static str;
    /// `(φₐ⁻, φₐ⁺)`: the left- and right-biased derivatives along `A`.
    fn one_sided<L: Lane, W: Window<L>, A: Axis>(w: &W, inv_h: L) -> (L, L);

    /// Left-biased and right-biased derivatives of all three axes.
    #[inline(always)]
    fn derivatives<L: Lane, W: Window<L>>(w: &W, inv_h: L) -> ([L; 3], [L; 3]) {
        let (xm, xp) = Self::one_sided::<L, W, X>(w, inv_h);
        let (ym, yp) = Self::one_sided::<L, W, Y>(w, inv_h);
        let (zm, zp) = Self::one_sided::<L, W, Z>(w, inv_h);
        ([xm, ym, zm], [xp, yp, zp])
    }

    /// The upwind norms `(∇⁺, ∇⁻)` of van der Laan et al. 2011, Sec. 4.7, with this scheme's
    /// derivatives ([`upwind_norms`]).
    #[inline(always)]
    fn norms<L: Lane, W: Window<L>>(w: &W, inv_h: L) -> (L, L) {
        let (dm, dp) = Self::derivatives(w, inv_h);
        upwind_norms(dm, dp)
    }
}

/// First-order one-sided differences D⁻, D⁺ (van der Laan et al. 2011, Sec. 4.7). Reads ±1.
#[derive(Clone, Copy, Debug, Default)]
pub struct Upwind1;

/// HJ-WENO5 (Jiang & Peng 2000; Nielsen & Museth 2006, Sec. 4.1; van der Laan et al. 2011,
/// Sec. 5.2). Reads ±3.
#[derive(Clone, Copy, Debug, Default)]
pub struct Weno5;

impl sealed::Sealed for Upwind1 {}
impl sealed::Sealed for Weno5 {}

impl Scheme for Upwind1 {
    const AXIS_REACH: i32 = 1;
    const NAME: &'static str = "upwind1";
    #[inline(always)]
    fn one_sided<L: Lane, W: Window<L>, A: Axis>(w: &W, inv_h: L) -> (L, L) {
        (diff_minus::<L, W, A>(w, inv_h), diff_plus::<L, W, A>(w, inv_h))
    }
}

impl Scheme for Weno5 {
    const AXIS_REACH: i32 = 3;
    const NAME: &'static str = "weno5";
    #[inline(always)]
    fn one_sided<L: Lane, W: Window<L>, A: Axis>(w: &W, inv_h: L) -> (L, L) {
        weno5_one_sided::<L, W, A>(w, inv_h)
    }
}

// ---------------------------------------------------------------------------------------
// Inputs that are either uniform or per voxel (decided by type, not per voxel).

/// A scalar input: `f32` (the same everywhere) or `&[f32]` (one value per voxel, in the
/// block's voxel order).
pub trait ScalarField: Sync {
    /// The field has values for `voxels` voxels.
    fn check(&self, voxels: usize) -> Result<(), KernelError>;
    /// Values for the lane group starting at `first`.
    fn lanes<L: Lane>(&self, first: usize) -> L;
}

impl ScalarField for f32 {
    #[inline(always)]
    fn check(&self, _voxels: usize) -> Result<(), KernelError> {
        Ok(())
    }
    #[inline(always)]
    fn lanes<L: Lane>(&self, _first: usize) -> L {
        L::splat(*self)
    }
}

impl ScalarField for &[f32] {
    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        if self.len() >= voxels {
            Ok(())
        } else {
            Err(KernelError::FieldLength { expected: voxels, got: self.len() })
        }
    }
    #[inline(always)]
    fn lanes<L: Lane>(&self, first: usize) -> L {
        L::load(&self[first..])
    }
}

/// A vector input: `[f32; 3]` (uniform) or `[&[f32]; 3]` (three per-voxel components).
pub trait VectorField: Sync {
    /// Every component has values for `voxels` voxels.
    fn check(&self, voxels: usize) -> Result<(), KernelError>;
    /// Components for the lane group starting at `first`.
    fn lanes<L: Lane>(&self, first: usize) -> [L; 3];
}

impl VectorField for [f32; 3] {
    #[inline(always)]
    fn check(&self, _voxels: usize) -> Result<(), KernelError> {
        Ok(())
    }
    #[inline(always)]
    fn lanes<L: Lane>(&self, _first: usize) -> [L; 3] {
        // Spelled out, not `map`: array maps take a closure the compiler may keep out of
        // line, outside the instruction-set level's function (see `crate::level`).
        [L::splat(self[0]), L::splat(self[1]), L::splat(self[2])]
    }
}

impl VectorField for [&[f32]; 3] {
    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.iter().try_for_each(|c| c.check(voxels))
    }
    #[inline(always)]
    fn lanes<L: Lane>(&self, first: usize) -> [L; 3] {
        [self[0].lanes(first), self[1].lanes(first), self[2].lanes(first)]
    }
}

/// Three per-voxel components times a uniform factor: a velocity u(x, t) = s(t) u(x, 0)
/// sampled once and scaled in each stage without another pass over memory. The product is
/// the f32 `u · s` of each lane, the same bits as scaling the arrays first.
#[derive(Clone, Copy, Debug)]
pub struct ScaledVelocity<'a> {
    pub components: [&'a [f32]; 3],
    pub scale: f32,
}

impl VectorField for ScaledVelocity<'_> {
    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.components.check(voxels)
    }
    #[inline(always)]
    fn lanes<L: Lane>(&self, first: usize) -> [L; 3] {
        let s = L::splat(self.scale);
        let [x, y, z] = self.components.lanes::<L>(first);
        [x * s, y * s, z * s]
    }
}

// ---------------------------------------------------------------------------------------
// Rates 𝓛(φ).

/// The rate S of eq. (3) of van der Laan et al. 2011 (Sec. 4.7 discretisation, see
/// [`eq3_speed`]): data speed F, curvature weight ε, rescaling term with the smoothed sign
/// φ/√(φ²+h²). The hyperbolic terms use the scheme `S` ([`Upwind1`]: Sec. 4.7;
/// [`Weno5`]: Sec. 5.2), the curvature term always central differences (eq. (4)).
/// Reads the 3×3×3 box and, with [`Weno5`], the ±3 star.
#[derive(Clone, Copy, Debug)]
pub struct Eq3Rate<S, F> {
    /// F: `f32` (uniform) or `&[f32]` (per voxel).
    pub speed: F,
    /// ε, the weight of the curvature term.
    pub curvature: f32,
    /// Weight of the rescaling term sgn(φ)(1 − |∇φ|): 1 for eq. (3), 0 to drop it.
    pub rescale: f32,
    /// h, the voxel size in world units (φ is in world units).
    pub voxel_size: f32,
    scheme: PhantomData<S>,
}

impl<S: Scheme, F: ScalarField> Eq3Rate<S, F> {
    /// Voxel size h, data speed F, curvature weight ε, rescaling weight (1 = eq. (3)).
    pub fn new(voxel_size: f32, speed: F, curvature: f32, rescale: f32) -> Self {
        Eq3Rate { speed, curvature, rescale, voxel_size, scheme: PhantomData }
    }
}

impl<S: Scheme, F: ScalarField> VoxelKernel for Eq3Rate<S, F> {
    const AXIS_REACH: i32 = if S::AXIS_REACH > 1 { S::AXIS_REACH } else { 1 };
    const BOX_REACH: i32 = 1;

    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.speed.check(voxels)
    }

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        let h = L::splat(self.voxel_size);
        let inv_h = L::splat(1.0) / h;
        let (grad_plus, grad_minus) = S::norms(w, inv_h);
        let kappa_grad = curvature_speed(w, inv_h);
        let sign = smoothed_sign(w.centre(), h);
        eq3_speed(
            self.speed.lanes::<L>(first),
            L::splat(self.curvature),
            L::splat(self.rescale),
            sign,
            grad_plus,
            grad_minus,
            kappa_grad,
        )
    }
}

/// The rate −u·∇φ of advection by an external velocity, upwinded per axis
/// ([`advection_rate`]) with the scheme `S`. Reads the ±1 or ±3 star.
#[derive(Clone, Copy, Debug)]
pub struct AdvectionRate<S, V> {
    /// u: `[f32; 3]` (uniform) or `[&[f32]; 3]` (per voxel), world units per time.
    pub velocity: V,
    /// h, the voxel size.
    pub voxel_size: f32,
    scheme: PhantomData<S>,
}

impl<S: Scheme, V: VectorField> AdvectionRate<S, V> {
    /// Voxel size h and velocity u.
    pub fn new(voxel_size: f32, velocity: V) -> Self {
        AdvectionRate { velocity, voxel_size, scheme: PhantomData }
    }
}

impl<S: Scheme, V: VectorField> VoxelKernel for AdvectionRate<S, V> {
    const AXIS_REACH: i32 = S::AXIS_REACH;
    const BOX_REACH: i32 = 0;

    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.velocity.check(voxels)
    }

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        let inv_h = L::splat(1.0) / L::splat(self.voxel_size);
        let (dm, dp) = S::derivatives(w, inv_h);
        advection_rate(self.velocity.lanes::<L>(first), dm, dp)
    }
}

/// The rate of eq. (3) plus advection on a lattice with a spacing of its own per axis and
/// a curvature weight that varies from voxel to voxel: the terms of ITK's segmentation
/// level sets (propagation, curvature, advection), with φ < 0 inside,
///
/// ```text
/// 𝓛(φ) = −F|∇φ| + E κ|∇φ| + w sgn(φ)(1 − |∇φ|) − u·∇φ
/// ```
///
/// discretised as [`Eq3Rate`] (upwind norms of the scheme `S`, curvature by central
/// differences, smoothed sign) and [`AdvectionRate`] (upwinded per axis), every difference
/// along axis a divided by its spacing sₐ (`inv_spacing[a]` = 1/sₐ;
/// [`crate::curvature::curvature_speed_aniso`]). An axis with `inv_spacing` 0 has no
/// derivative: a one-slice image evolves as a 2D level set. The one-sided derivatives are
/// shared by the normal-speed and advection terms.
#[derive(Clone, Copy, Debug)]
pub struct ImageRate<S, F, E, V> {
    /// F, the outward normal speed: `f32` (uniform) or `&[f32]` (per voxel).
    pub speed: F,
    /// E = ε Z(x), the curvature weight: `f32` or `&[f32]`.
    pub curvature: E,
    /// u, the advection velocity (none: no advection term).
    pub velocity: Option<V>,
    /// w, the weight of the rescaling term.
    pub rescale: f32,
    /// 1/sₐ per axis (0 drops the axis).
    pub inv_spacing: [f32; 3],
    /// h of the smoothed sign φ/√(φ² + h²) (the smallest spacing).
    pub sign_width: f32,
    scheme: PhantomData<S>,
}

impl<S: Scheme, F: ScalarField, E: ScalarField, V: VectorField> ImageRate<S, F, E, V> {
    /// The rate with its inputs; see the fields.
    pub fn new(
        speed: F,
        curvature: E,
        velocity: Option<V>,
        rescale: f32,
        inv_spacing: [f32; 3],
        sign_width: f32,
    ) -> Self {
        ImageRate {
            speed,
            curvature,
            velocity,
            rescale,
            inv_spacing,
            sign_width,
            scheme: PhantomData,
        }
    }
}

impl<S: Scheme, F: ScalarField, E: ScalarField, V: VectorField> VoxelKernel
    for ImageRate<S, F, E, V>
{
    const AXIS_REACH: i32 = if S::AXIS_REACH > 1 { S::AXIS_REACH } else { 1 };
    const BOX_REACH: i32 = 1;

    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.speed.check(voxels)?;
        self.curvature.check(voxels)?;
        self.velocity.as_ref().map_or(Ok(()), |v| v.check(voxels))
    }

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        let [ix, iy, iz] = self.inv_spacing;
        let inv = [L::splat(ix), L::splat(iy), L::splat(iz)];
        let (xm, xp) = S::one_sided::<L, W, X>(w, inv[0]);
        let (ym, yp) = S::one_sided::<L, W, Y>(w, inv[1]);
        // A dropped z-axis (a planar lattice) is not read at all: its derivatives would be
        // finite values times 0, which add nothing to the norms, the curvature or the
        // advection (the same values; see `curvature_speed_planar`). The test is the same
        // for every voxel of a sweep, so the branch costs nothing.
        let planar = iz == 0.0;
        let (zm, zp) = if planar {
            (L::splat(0.0), L::splat(0.0))
        } else {
            S::one_sided::<L, W, Z>(w, inv[2])
        };
        let (dm, dp) = ([xm, ym, zm], [xp, yp, zp]);
        let (grad_plus, grad_minus) = upwind_norms(dm, dp);
        let kappa_grad = if planar {
            curvature_speed_planar(w, [inv[0], inv[1]])
        } else {
            curvature_speed_aniso(w, inv)
        };
        let sign = smoothed_sign(w.centre(), L::splat(self.sign_width));
        let rate = eq3_speed(
            self.speed.lanes::<L>(first),
            self.curvature.lanes::<L>(first),
            L::splat(self.rescale),
            sign,
            grad_plus,
            grad_minus,
            kappa_grad,
        );
        match &self.velocity {
            Some(u) => rate + advection_rate(u.lanes::<L>(first), dm, dp),
            None => rate,
        }
    }
}

// ---------------------------------------------------------------------------------------
// Time steps.

/// One forward-Euler step φ + Δt 𝓛(φ) of a rate `K`, clamped to [−γ, γ] (van der Laan
/// et al. 2011, Sec. 4.7 and Sec. 3.1). `gamma = f32::INFINITY` disables the clamp.
#[derive(Clone, Copy, Debug)]
pub struct Euler<K> {
    pub rate: K,
    pub dt: f32,
    pub gamma: f32,
}

impl<K: VoxelKernel> VoxelKernel for Euler<K> {
    const AXIS_REACH: i32 = K::AXIS_REACH;
    const BOX_REACH: i32 = K::BOX_REACH;

    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.rate.check(voxels)
    }

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        let rate = self.rate.eval(w, first);
        clamp_band(euler(w.centre(), L::splat(self.dt), rate), L::splat(self.gamma))
    }
}

/// One TVD-RK3 stage (Shu & Osher 1988; van der Laan et al. 2011, Sec. 5.2; Nielsen &
/// Museth 2006, Sec. 4.1) of a rate `K`: the window holds φᵏ (φⁿ, φ⁽¹⁾ or φ⁽²⁾), `phi_n` holds φⁿ
/// per voxel (read in stages 2 and 3; may be empty for stage 1), the result is clamped to [−γ, γ].
/// See [`rk3_combine`].
#[derive(Clone, Copy, Debug)]
pub struct Rk3<'a, K, const STAGE: u8> {
    pub rate: K,
    pub dt: f32,
    pub gamma: f32,
    pub phi_n: &'a [f32],
}

impl<K: VoxelKernel, const STAGE: u8> VoxelKernel for Rk3<'_, K, STAGE> {
    const AXIS_REACH: i32 = K::AXIS_REACH;
    const BOX_REACH: i32 = K::BOX_REACH;

    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.rate.check(voxels)?;
        if STAGE > 1 {
            self.phi_n.check(voxels)?;
        }
        Ok(())
    }

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        let rate = self.rate.eval(w, first);
        let phi_n = if STAGE > 1 { self.phi_n.lanes::<L>(first) } else { w.centre() };
        let next = rk3_combine::<L, STAGE>(phi_n, w.centre(), L::splat(self.dt), rate);
        clamp_band(next, L::splat(self.gamma))
    }
}

/// TVD-RK3 stage 2 or 3 with the stage chosen at run time: the arithmetic and bits of
/// [`Rk3`] at that stage ([`rk3_blend`] with the stage's [`rk3_weights`]), one type for both
/// stages, so that an engine compiles one kernel where [`Rk3`] needs two. The fields are those
/// of [`Rk3`] and the stage's weights; `phi_n` holds φⁿ per voxel and is always read.
#[derive(Clone, Copy, Debug)]
pub struct Rk3Blend<'a, K> {
    pub rate: K,
    pub dt: f32,
    pub gamma: f32,
    pub phi_n: &'a [f32],
    pub weights: Rk3Weights,
}

/// The weights of TVD-RK3 stage 2 or 3 ([`rk3_weights`]), for [`Rk3Blend`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rk3Weights {
    a: f32,
    b: f32,
}

impl Rk3Weights {
    /// The weights of stage `stage` when it is 2 or 3 (`None` otherwise: stage 1 is not a
    /// blend).
    pub const fn of_stage(stage: u8) -> Option<Rk3Weights> {
        match (stage, rk3_weights(stage)) {
            (2 | 3, Some((a, b))) => Some(Rk3Weights { a, b }),
            _ => None,
        }
    }
}

impl<K: VoxelKernel> VoxelKernel for Rk3Blend<'_, K> {
    const AXIS_REACH: i32 = K::AXIS_REACH;
    const BOX_REACH: i32 = K::BOX_REACH;

    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.rate.check(voxels)?;
        self.phi_n.check(voxels)
    }

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        let rate = self.rate.eval(w, first);
        let step = euler(w.centre(), L::splat(self.dt), rate);
        let phi_n = self.phi_n.lanes::<L>(first);
        let Rk3Weights { a, b } = self.weights;
        let next = rk3_blend(phi_n, step, L::splat(a), L::splat(b));
        clamp_band(next, L::splat(self.gamma))
    }
}

// ---------------------------------------------------------------------------------------
// Composition and the band mask.

/// The sum of two rates, 𝓛 = 𝓛ₐ + 𝓛ᵦ: how weighted terms combine into one flow (for
/// example the normal-speed, curvature and rescaling terms of [`Eq3Rate`] plus the
/// advection of [`AdvectionRate`], the combination ITK's level-set filters offer).
#[derive(Clone, Copy, Debug)]
pub struct Sum<A, B>(pub A, pub B);

const fn max_i32(a: i32, b: i32) -> i32 {
    if a > b {
        a
    } else {
        b
    }
}

impl<A: VoxelKernel, B: VoxelKernel> VoxelKernel for Sum<A, B> {
    const AXIS_REACH: i32 = max_i32(A::AXIS_REACH, B::AXIS_REACH);
    const BOX_REACH: i32 = max_i32(A::BOX_REACH, B::BOX_REACH);

    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.0.check(voxels)?;
        self.1.check(voxels)
    }

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        self.0.eval(w, first) + self.1.eval(w, first)
    }
}

/// min |φ| over the 3×3×3 box around each voxel: a voxel whose box holds a band voxel
/// (|φ| < γ) has a box minimum below γ. The band mask of [`BandMasked`] is this value
/// of φⁿ.
#[derive(Clone, Copy, Debug, Default)]
pub struct BoxMinAbs;

impl VoxelKernel for BoxMinAbs {
    const AXIS_REACH: i32 = 1;
    const BOX_REACH: i32 = 1;

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, _first: usize) -> L {
        macro_rules! row {
            ($dy:literal, $dz:literal) => {
                w.at::<-1, $dy, $dz>()
                    .abs()
                    .min(w.at::<0, $dy, $dz>().abs())
                    .min(w.at::<1, $dy, $dz>().abs())
            };
        }
        let a = row!(-1, -1).min(row!(0, -1)).min(row!(1, -1));
        let b = row!(-1, 0).min(row!(0, 0)).min(row!(1, 0));
        let c = row!(-1, 1).min(row!(0, 1)).min(row!(1, 1));
        a.min(b).min(c)
    }
}

/// A time step restricted to the computational band of φⁿ: the step `K` where the 3×3×3
/// box of φⁿ around the voxel holds a band voxel (`box_min[i] < γ`, see [`BoxMinAbs`]),
/// the window's centre (φᵏ, which is ±γ there) elsewhere.
///
/// This is the one band rule every representation follows: a step computes exactly the
/// voxels within one voxel (26-neighbourhood) of a band voxel of φⁿ, and every other
/// voxel keeps ±γ. A grid that stores exactly that set (the DT-Grid after its rebuild)
/// needs no mask; grids that store more (tiles, dense arrays) apply it.
#[derive(Clone, Copy, Debug)]
pub struct BandMasked<'a, K> {
    pub step: K,
    /// min |φⁿ| over each voxel's box, per voxel in the block's order.
    pub box_min: &'a [f32],
    pub gamma: f32,
}

impl<K: VoxelKernel> VoxelKernel for BandMasked<'_, K> {
    const AXIS_REACH: i32 = K::AXIS_REACH;
    const BOX_REACH: i32 = K::BOX_REACH;

    fn check(&self, voxels: usize) -> Result<(), KernelError> {
        self.step.check(voxels)?;
        self.box_min.check(voxels)
    }

    #[inline(always)]
    fn eval<L: Lane, W: Window<L>>(&self, w: &W, first: usize) -> L {
        let m = self.box_min.lanes::<L>(first);
        let gamma = L::splat(self.gamma);
        // A lane group whose voxels are all outside the computational band keeps its
        // values: the step is not evaluated (the same bits as evaluating it and selecting
        // the centre). Groups of up to 8 voxels (one voxel, one or two tile rows) only: a
        // third of a tile's voxels lie outside, but only about a tenth of its 16-voxel
        // slices, too few to pay for the branch. Measured with `levelset run
        // sphere|spiral|enright` (decision 0038).
        if L::LANES <= 8 && !gamma.any_gt(m) {
            return w.centre();
        }
        gamma.select_gt(m, self.step.eval(w, first), w.centre())
    }
}
