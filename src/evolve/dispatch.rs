//! The dispatch: the run-time choices of a stage — spatial scheme, F uniform or per
//! voxel, advection on or off, Runge–Kutta stage — become one kernel type, decided once
//! per stage and outside every loop (the way OpenVDB's
//! `LevelSetTracker` nests `normalize1<S>` → `normalize2<S, T>`). Three plain generic
//! functions, one per choice:
//!
//! 1. [`dispatch`]: the scheme ([`Upwind1`] with the 27-point reach 1, [`Weno5`] with
//!    reach 3);
//! 2. `inputs::<S, R>`: the rate from the stage's inputs — eq. (3) with a uniform or a
//!    per-voxel F, alone or plus advection (`Sum<Eq3Rate, AdvectionRate>`);
//! 3. `stage::<R>`: the TVD-RK3 stage around the rate (`Rk3<_, 1>`; `Rk3Blend` for stages
//!    2 and 3, one kernel with the stage's weights as values; forward Euler is stage 1
//!    alone),
//!
//! and the result goes to the representation's [`Sweep`], which runs it over its voxels
//! (the tile sweep then picks the lane type, the DT-Grid sweep its point window).

use super::{EvolveError, Lattice, SpatialScheme};
use levelset_kernels::{
    AdvectionRate, AnchoredRenormRate, BoxFarWindow, BoxWindow, Eq3Rate, Euler, ImageRate,
    InterfaceAnchor, Lane, RenormRate, Rk3, Rk3Blend, Rk3Weights, ScalarField, ScaledVelocity,
    Scheme, Sum, Upwind1, VoxelKernel, Weno5,
};
use std::ops::Range;

/// Inputs of one Runge–Kutta stage (or one Euler step, which is stage 1 alone).
#[derive(Clone, Copy)]
pub(crate) struct StageParams<'a> {
    /// 1, 2 or 3 (TVD-RK3 stage; forward Euler is stage 1).
    pub stage: u8,
    pub dt: f32,
    pub gamma: f32,
    pub h: f32,
    /// ε, the curvature weight.
    pub eps: f32,
    /// Weight of the coupled rescaling term of eq. (3) ([`super::Renormalization::Coupled`];
    /// 0 otherwise).
    pub rescale: f32,
    /// F, the same everywhere (then `speed` is unused)...
    pub uniform_speed: Option<f32>,
    /// ... or per voxel (flat order).
    pub speed: &'a [f32],
    /// u per voxel (flat order), if the flow advects.
    pub velocity: Option<[&'a [f32]; 3]>,
    /// Factor of the velocity in this stage (a time-separable field; 1 otherwise).
    pub velocity_scale: f32,
    /// φⁿ per voxel (flat order), read in stages 2 and 3 (empty in stage 1); set by the
    /// representation, which keeps φⁿ.
    pub phi_n: &'a [f32],
    /// ε Z(x) per voxel (flat order), if the flow has a curvature field (then `eps` is
    /// unused).
    pub curvature: Option<&'a [f32]>,
    /// The anisotropic lattice, if any ([`super::Settings::lattice`]).
    pub lattice: Option<Lattice>,
}

/// A sweep that runs kernels of any type over a representation: the visitor the dispatch
/// hands the chosen kernel to. `make(range)` builds the kernel for the voxels `range` of
/// the flat order (their per-voxel inputs sliced to start at the block's first voxel).
/// `R` is the halo the kernel needs.
pub(crate) trait Sweep {
    fn run<K, M, const R: usize>(self, make: M) -> Result<(), EvolveError>
    where
        K: VoxelKernel,
        M: Fn(Range<usize>) -> K + Sync,
        Halo<R>: Reach;
}

/// A stencil reach `R` (1: the 3×3×3 box; 3: the box and ±3 along the axes) as a type, so
/// that a sweep that gathers each voxel's values (the DT-Grid's) picks its point window at
/// compile time.
pub(crate) struct Halo<const R: usize>;

/// The point windows over one voxel's gathered values.
pub(crate) enum PointWindow {
    /// The 3×3×3 box (27 values, [`levelset_kernels::BOX27_OFFSETS`]).
    Box27,
    /// The box and ±2, ±3 along the axes (39 values, [`levelset_kernels::BOX_FAR39_OFFSETS`]).
    BoxFar39,
}

/// What a kernel of a reach reads per voxel when its values are gathered point by point.
pub(crate) trait Reach {
    /// The window of the gathered values.
    const WINDOW: PointWindow;
    /// The kernel's value at voxel `i` from its window's `values`, with the one-voxel lane
    /// type `L` (`f32`, or the fused scalar of the CPU's level).
    fn eval<L: Lane, K: VoxelKernel>(k: &K, values: &[f32], i: usize) -> f32;
}

impl Reach for Halo<1> {
    const WINDOW: PointWindow = PointWindow::Box27;
    #[inline(always)]
    fn eval<L: Lane, K: VoxelKernel>(k: &K, values: &[f32], i: usize) -> f32 {
        let w = BoxWindow::new(values.try_into().expect("27 values"));
        one_value(k.eval::<L, _>(&w, i))
    }
}

impl Reach for Halo<3> {
    const WINDOW: PointWindow = PointWindow::BoxFar39;
    #[inline(always)]
    fn eval<L: Lane, K: VoxelKernel>(k: &K, values: &[f32], i: usize) -> f32 {
        let w = BoxFarWindow::new(values.try_into().expect("39 values"));
        one_value(k.eval::<L, _>(&w, i))
    }
}

/// The value of a one-voxel lane group.
#[inline(always)]
pub(crate) fn one_value<L: Lane>(v: L) -> f32 {
    let mut out = [0.0f32; 1];
    v.store(&mut out);
    out[0]
}

/// Level 1: the scheme, with its reach.
pub(crate) fn dispatch<V: Sweep>(
    p: &StageParams<'_>,
    scheme: SpatialScheme,
    sweep: V,
) -> Result<(), EvolveError> {
    match scheme {
        SpatialScheme::Upwind1 => inputs::<Upwind1, 1, V>(p, sweep),
        SpatialScheme::Weno5 => inputs::<Weno5, 3, V>(p, sweep),
    }
}

/// Level 2: the rate from the inputs — F uniform (`f32`) or per voxel (`&[f32]`), with or
/// without advection.
fn inputs<'a, S: Scheme, const R: usize, V: Sweep>(
    p: &StageParams<'a>,
    sweep: V,
) -> Result<(), EvolveError>
where
    Halo<R>: Reach,
{
    if p.lattice.is_some() || p.curvature.is_some() {
        return image::<S, R, V>(p, sweep);
    }
    let (h, eps, w) = (p.h, p.eps, p.rescale);
    let speed: &'a [f32] = p.speed;
    let scale = p.velocity_scale;
    let advection = move |u: [&'a [f32]; 3], r: Range<usize>| {
        let components = [&u[0][r.clone()], &u[1][r.clone()], &u[2][r]];
        AdvectionRate::<S, ScaledVelocity<'a>>::new(h, ScaledVelocity { components, scale })
    };
    match (p.uniform_speed, p.velocity) {
        (Some(f), None) => {
            stage::<R, _, _, V>(p, sweep, move |_| Eq3Rate::<S, f32>::new(h, f, eps, w))
        }
        (Some(f), Some(u)) => stage::<R, _, _, V>(p, sweep, move |r| {
            Sum(Eq3Rate::<S, f32>::new(h, f, eps, w), advection(u, r))
        }),
        (None, None) => stage::<R, _, _, V>(p, sweep, move |r| {
            Eq3Rate::<S, &'a [f32]>::new(h, &speed[r], eps, w)
        }),
        (None, Some(u)) => stage::<R, _, _, V>(p, sweep, move |r: Range<usize>| {
            Sum(Eq3Rate::<S, &'a [f32]>::new(h, &speed[r.clone()], eps, w), advection(u, r))
        }),
    }
}

/// Level 2 on a lattice or with a curvature field: [`ImageRate`] with F and ε Z each
/// uniform or per voxel, with or without advection.
fn image<'a, S: Scheme, const R: usize, V: Sweep>(
    p: &StageParams<'a>,
    sweep: V,
) -> Result<(), EvolveError>
where
    Halo<R>: Reach,
{
    let (inv, sign_width, factor) = match p.lattice {
        Some(l) => (l.inv_spacing(), l.min_spacing(), l.curvature_factor()),
        None => ([1.0 / p.h; 3], p.h, 1.0),
    };
    // A per-voxel ε Z carries the factor already (see `Inputs::fill_curvature`).
    let eps = p.eps * factor;
    let speed = p.speed;
    match (p.uniform_speed, p.curvature) {
        (Some(f), None) => {
            image_rate::<S, R, _, _, V>(p, sweep, inv, sign_width, move |_| (f, eps))
        }
        (Some(f), Some(e)) => {
            image_rate::<S, R, _, _, V>(p, sweep, inv, sign_width, move |r| (f, &e[r]))
        }
        (None, None) => {
            image_rate::<S, R, _, _, V>(p, sweep, inv, sign_width, move |r| (&speed[r], eps))
        }
        (None, Some(e)) => image_rate::<S, R, _, _, V>(p, sweep, inv, sign_width, move |r| {
            (&speed[r.clone()], &e[r])
        }),
    }
}

/// [`ImageRate`] with the (F, ε Z) that `fe` gives for a block's voxels, into the stage.
fn image_rate<'a, S, const R: usize, F, E, V>(
    p: &StageParams<'a>,
    sweep: V,
    inv: [f32; 3],
    sign_width: f32,
    fe: impl Fn(Range<usize>) -> (F, E) + Sync + 'a,
) -> Result<(), EvolveError>
where
    S: Scheme,
    F: ScalarField + 'a,
    E: ScalarField + 'a,
    V: Sweep,
    Halo<R>: Reach,
{
    let w = p.rescale;
    let scale = p.velocity_scale;
    let velocity = p.velocity;
    stage::<R, _, _, V>(p, sweep, move |r: Range<usize>| {
        let u = velocity.map(|u| ScaledVelocity {
            components: [&u[0][r.clone()], &u[1][r.clone()], &u[2][r.clone()]],
            scale,
        });
        let (f, e) = fe(r);
        ImageRate::<S, F, E, ScaledVelocity<'a>>::new(f, e, u, w, inv, sign_width)
    })
}

/// Level 3: the TVD-RK3 stage around the rate (stage 1 is forward Euler), handed to the
/// sweep.
fn stage<'a, const R: usize, K, F, V>(
    p: &StageParams<'a>,
    sweep: V,
    rate: F,
) -> Result<(), EvolveError>
where
    K: VoxelKernel,
    F: Fn(Range<usize>) -> K + Sync,
    V: Sweep,
    Halo<R>: Reach,
{
    let (dt, gamma) = (p.dt, p.gamma);
    let phi_n: &'a [f32] = p.phi_n;
    // φⁿ of the voxels `r` (empty in stage 1).
    let phi_n = move |r: Range<usize>| if phi_n.is_empty() { &[][..] } else { &phi_n[r] };
    match p.stage {
        1 => sweep.run::<_, _, R>(move |r: Range<usize>| Rk3::<K, 1> {
            rate: rate(r.clone()),
            dt,
            gamma,
            phi_n: phi_n(r),
        }),
        // Stages 2 and 3 are one kernel with the stage's weights as values (the bits of
        // `Rk3<K, 2 | 3>`): each kernel of the step is compiled once for them, not twice.
        stage => {
            let Some(weights) = Rk3Weights::of_stage(stage) else {
                unreachable!("TVD-RK3 has stages 1, 2 and 3, not {stage}")
            };
            sweep.run::<_, _, R>(move |r: Range<usize>| Rk3Blend {
                rate: rate(r.clone()),
                dt,
                gamma,
                phi_n: phi_n(r),
                weights,
            })
        }
    }
}

/// One pseudo-time sweep of the renormalisation ([`super::Renormalization::Sweeps`]).
#[derive(Clone, Copy)]
pub(crate) struct RenormParams {
    pub scheme: SpatialScheme,
    /// Δτ.
    pub dtau: f32,
    pub gamma: f32,
    pub h: f32,
    /// Sweeps of one renormalisation.
    pub sweeps: u32,
}

impl RenormParams {
    /// Whether the anchors get a pass and a buffer of their own: only when more than one
    /// sweep reads them; a single sweep evaluates them in place ([`AnchoredRenormRate`]).
    pub fn anchored(&self) -> bool {
        anchors_stored(self.sweeps)
    }
}

/// Whether a renormalisation of `sweeps` sweeps stores its anchors (see
/// [`RenormParams::anchored`]); the memory estimates use the same rule.
pub(crate) fn anchors_stored(sweeps: u32) -> bool {
    sweeps > 1
}

/// The anchor pass of a renormalisation: [`InterfaceAnchor`] over φ⁰ (reach 1).
pub(crate) fn dispatch_anchor<V: Sweep>(h: f32, sweep: V) -> Result<(), EvolveError> {
    sweep.run::<_, _, 1>(move |_| InterfaceAnchor { voxel_size: h })
}

/// Stored anchors of a renormalisation ([`InterfaceAnchor`] over φ⁰): what the sweeps'
/// kernels read for the voxels `r` of the flat order.
pub(crate) trait Anchors<'a>: Copy + Send + Sync + 'a {
    /// The anchors of one block's voxels.
    type Field: ScalarField + 'a;
    /// The anchors of the voxels `r`.
    fn field(self, r: Range<usize>) -> Self::Field;
}

/// One anchor per voxel, in the flat order.
impl<'a> Anchors<'a> for &'a [f32] {
    type Field = &'a [f32];
    #[inline(always)]
    fn field(self, r: Range<usize>) -> &'a [f32] {
        &self[r]
    }
}

/// One forward-Euler sweep in pseudo time of the renormalisation rate, with the scheme's
/// reach. `anchor` holds the Russo–Smereka anchors of φ⁰ per voxel (flat order): the
/// distance estimate at voxels next to the interface, ±∞ elsewhere ([`InterfaceAnchor`]);
/// `None` evaluates them in place from the values swept, which must be φ⁰ (the first
/// sweep; [`AnchoredRenormRate`], the same bits as an anchor pass before it).
pub(crate) fn dispatch_renorm<'a, A: Anchors<'a>, V: Sweep>(
    p: &RenormParams,
    anchor: Option<A>,
    sweep: V,
) -> Result<(), EvolveError> {
    match p.scheme {
        SpatialScheme::Upwind1 => renorm::<Upwind1, 1, A, V>(p, anchor, sweep),
        SpatialScheme::Weno5 => renorm::<Weno5, 3, A, V>(p, anchor, sweep),
    }
}

/// The first sweep of [`dispatch_renorm`] with the anchors evaluated in place
/// ([`AnchoredRenormRate`]) alone: for a sweep that stores them as well, whose type then
/// compiles no other kernel.
pub(crate) fn dispatch_renorm_first<V: Sweep>(
    p: &RenormParams,
    sweep: V,
) -> Result<(), EvolveError> {
    match p.scheme {
        SpatialScheme::Upwind1 => renorm_in_place::<Upwind1, 1, V>(p, sweep),
        SpatialScheme::Weno5 => renorm_in_place::<Weno5, 3, V>(p, sweep),
    }
}

/// A sweep of [`AnchoredRenormRate`]: the anchors evaluated from the values swept (φ⁰).
fn renorm_in_place<S: Scheme, const R: usize, V: Sweep>(
    p: &RenormParams,
    sweep: V,
) -> Result<(), EvolveError>
where
    Halo<R>: Reach,
{
    let (h, dt, gamma) = (p.h, p.dtau, p.gamma);
    sweep.run::<_, _, R>(move |_| Euler { rate: AnchoredRenormRate::<S>::new(h), dt, gamma })
}

fn renorm<'a, S: Scheme, const R: usize, A: Anchors<'a>, V: Sweep>(
    p: &RenormParams,
    anchor: Option<A>,
    sweep: V,
) -> Result<(), EvolveError>
where
    Halo<R>: Reach,
{
    let (h, dt, gamma) = (p.h, p.dtau, p.gamma);
    match anchor {
        Some(anchor) => sweep.run::<_, _, R>(move |r: Range<usize>| Euler {
            rate: RenormRate::<S, A::Field>::new(h, anchor.field(r)),
            dt,
            gamma,
        }),
        None => renorm_in_place::<S, R, V>(p, sweep),
    }
}
