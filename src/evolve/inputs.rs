//! The per-voxel inputs of a stage: the normal speed F and the advection velocity u
//! sampled at the representation's voxels (flat order), κ̄ of the volume-conserving flow
//! (eq. (5)–(7)), and the maxima the time step comes from.

use super::dispatch::StageParams;
use super::field::{Speed, VectorFn, Velocity};
use super::rep::{growth_bytes, resize_exact, vec_bytes, Representation};
use super::{in_pool, EvolveError, Flow, Settings};
use crate::coord::Coord;
use crate::grid::GridSpec;
use rayon::prelude::*;
use std::sync::Arc;

/// F and u of the current stage, and what is kept between stages.
#[derive(Clone)]
pub(crate) struct Inputs {
    /// Per-voxel F (flat order); empty when F is uniform.
    speed: Vec<f32>,
    /// F when it is the same everywhere (a constant, plus ε κ̄); then `speed` is empty.
    uniform_speed: Option<f32>,
    /// u per voxel, one array per component.
    velocity: [Vec<f32>; 3],
    /// The factor of `velocity` in the current stage ([`super::VectorFn::time_scale`];
    /// else 1).
    velocity_scale: f32,
    /// F without ε κ̄ (a sampled field) or the morph target ψ, per voxel.
    base: Vec<f32>,
    /// A time-separable velocity's samples u(x, 0) depend on the position only, so they
    /// are kept from step to step: `velocity` holds the samples of the units (tiles) of
    /// this layout (empty: nothing to reuse).
    velocity_layout: Layout,
    /// The previous samples while the new ones are assembled (swapped with `velocity`).
    spare: [Vec<f32>; 3],
    /// ε Z(x) per voxel ([`Flow::curvature_field`]), times the lattice's curvature factor;
    /// empty without one.
    curvature: Vec<f32>,
    /// The layouts `base` and `curvature` were sampled on, when their fields do not
    /// change with time: sampled again only when the layout has changed.
    base_layout: Layout,
    curvature_layout: Layout,
    /// The weight `curvature`'s samples carry (ε times the lattice's factor).
    curvature_weight: f32,
}

/// The layout per-voxel samples were taken on: the representation's units
/// ([`Representation::unit_keys`]) and spec. Empty: unknown (sample again).
#[derive(Clone, Default)]
struct Layout {
    units: Vec<Coord>,
    spec: Option<GridSpec>,
}

impl Layout {
    /// Whether samples taken on this layout are those of `rep`'s voxels now.
    fn holds(&self, rep: &dyn Representation) -> bool {
        !self.units.is_empty() && self.spec == Some(rep.spec()) && self.units == rep.unit_keys()
    }

    fn clear(&mut self) {
        self.units.clear();
    }
}

/// What [`Inputs::fill_velocity`] wrote.
enum Written {
    /// Nothing (no velocity, or nothing to sample in this stage).
    Nothing,
    /// The arrays, to be checked.
    Arrays,
    /// Samples it has checked itself: whether they are finite.
    Checked(bool),
}

/// Whether the flow steps a planar lattice's level set (see [`Representation::fill_scalar`]).
fn planar(settings: &Settings) -> bool {
    settings.lattice.is_some_and(|l| l.planar)
}

impl Default for Inputs {
    fn default() -> Self {
        Inputs {
            speed: Vec::new(),
            uniform_speed: None,
            velocity: Default::default(),
            velocity_scale: 1.0,
            base: Vec::new(),
            velocity_layout: Layout::default(),
            spare: Default::default(),
            curvature: Vec::new(),
            base_layout: Layout::default(),
            curvature_layout: Layout::default(),
            curvature_weight: f32::NAN,
        }
    }
}

/// Values per parallel task of the scans over per-voxel arrays (64 tiles).
const CHUNK: usize = 4096;

/// The slices of `rep`'s per-voxel arrays that the sweeps of a flow with `settings` read
/// ([`Representation::read_slices`] of a planar lattice's level set).
pub(crate) fn read_slices(rep: &dyn Representation, settings: &Settings) -> Option<(usize, usize)> {
    rep.read_slices(planar(settings))
}

/// The voxels the sweeps read of a task's `CHUNK` values, as (unit, read): the first
/// `read` of every `unit` ([`read_slices`]; every voxel when `None`).
fn read_part(slices: Option<(usize, usize)>) -> (usize, usize) {
    let (unit, read) = slices.unwrap_or((CHUNK, CHUNK));
    debug_assert!(CHUNK.is_multiple_of(unit) && read <= unit, "units within a task");
    (unit, read)
}

/// The parts of `c` (a task's values) that the sweeps read (see [`read_part`]).
fn read_parts(c: &[f32], (unit, read): (usize, usize)) -> impl Iterator<Item = &[f32]> {
    c.chunks(unit).map(move |u| &u[..read.min(u.len())])
}

/// [`read_parts`] of a mutable task.
fn read_parts_mut(c: &mut [f32], (unit, read): (usize, usize)) -> impl Iterator<Item = &mut [f32]> {
    c.chunks_mut(unit).map(move |u| {
        let n = read.min(u.len());
        &mut u[..n]
    })
}

/// The larger of two values that are not NaN (`b` when they are equal): a comparison and a
/// select, which vectorise.
#[inline(always)]
fn larger(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// Lanes of the branch-free maxima ([`band_max_into`]).
const MAX_LANES: usize = 16;

/// Takes into `acc` the largest `x` of the voxels of `v` with |v| < `g`: `x` of the
/// voxel's values in `xs` (slices as long as `v` at least), finite and ≥ 0. Branch-free,
/// lane by lane (the voxel at `i` goes to lane `i` mod 16; the caller takes the largest
/// lane). With a test per voxel, [`Inputs::band_maxima`] took 11–12 % of the samples of
/// `levelset segment` of scikit-image's `coins()` by GAC on one thread, and 3–4 % this
/// way (`perf record`, three runs of each build, 2-core AMD EPYC, 2026-11-30; decision
/// 0046). A maximum does not depend on the order it is taken in, so the bits are those of
/// a voxel-by-voxel scan.
#[inline(always)]
fn band_max_into<const N: usize>(
    acc: &mut [f32; MAX_LANES],
    v: &[f32],
    g: f32,
    xs: [&[f32]; N],
    x: impl Fn([f32; N]) -> f32,
) {
    const W: usize = MAX_LANES;
    let n = v.len();
    let xs = xs.map(|s| &s[..n]);
    // `x` of every voxel, then a select: a value computed only where the test holds kept
    // the loop scalar, with a branch per voxel.
    let pick = |v: f32, x: f32| if v.abs() < g { x } else { 0.0 };
    let mut lanes = *acc;
    for c in 0..n / W {
        let vs: &[f32; W] = v[c * W..][..W].try_into().expect("a group of W");
        let group: [&[f32; W]; N] = xs.map(|s| s[c * W..][..W].try_into().expect("a group of W"));
        for (j, a) in lanes.iter_mut().enumerate() {
            *a = larger(pick(vs[j], x(group.map(|s| s[j]))), *a);
        }
    }
    for (i, a) in (n / W * W..n).zip(lanes.iter_mut()) {
        *a = larger(pick(v[i], x(xs.map(|s| s[i]))), *a);
    }
    *acc = lanes;
}

/// The samples `out` of a scalar field of the position alone on `rep`'s voxels, taken on
/// `layout`: those of the units that stay are kept, the others sampled and passed through
/// `finish` ([`Representation::fill_static_scalar`]; `spare` holds the previous samples
/// meanwhile). Returns whether every new sample was acceptable; if not, `layout` is
/// cleared, so that a retry of the step samples everything anew.
#[allow(clippy::too_many_arguments)] // the inputs' parts, borrowed apart
fn resample(
    rep: &dyn Representation,
    f: &dyn super::field::ScalarFn,
    planar: bool,
    pool: &Option<Arc<rayon::ThreadPool>>,
    layout: &mut Layout,
    out: &mut Vec<f32>,
    spare: &mut Vec<f32>,
    finish: &(dyn Fn(&mut [f32]) -> bool + Sync),
) -> bool {
    if layout.spec != Some(rep.spec()) || out.len() != 64 * layout.units.len() {
        layout.clear();
    }
    layout.spec = Some(rep.spec());
    std::mem::swap(out, spare);
    if layout.units.is_empty() {
        // Nothing to reuse: no copy of the old samples either.
        spare.clear();
    }
    resize_exact(out, rep.flat().len(), 0.0);
    let keys = &mut layout.units;
    let ok = in_pool(pool, || rep.fill_static_scalar(f, planar, keys, spare, out, finish));
    if !ok {
        layout.clear();
    }
    ok
}

impl Inputs {
    /// Bytes held, used or not.
    pub fn bytes(&self) -> usize {
        vec_bytes(&self.speed)
            + vec_bytes(&self.base)
            + self.velocity.iter().chain(&self.spare).map(vec_bytes).sum::<usize>()
            + vec_bytes(&self.velocity_layout.units)
            + vec_bytes(&self.curvature)
            + vec_bytes(&self.base_layout.units)
            + vec_bytes(&self.curvature_layout.units)
    }

    /// Bytes the inputs of `flow` have to allocate for `n` voxels.
    pub fn growth_bytes(&self, n: usize, flow: &Flow) -> u64 {
        let mut b = 0;
        if !matches!(flow.speed, Speed::Constant(_)) {
            b += growth_bytes(&self.speed, n)
                + growth_bytes(&self.base, n)
                + growth_bytes(&self.base_layout.units, n / 64);
        }
        if flow.velocity.is_some() {
            b += self.velocity.iter().map(|c| growth_bytes(c, n)).sum::<u64>();
        }
        if flow.curvature_field.is_some() {
            b += growth_bytes(&self.curvature, n)
                + growth_bytes(&self.curvature_layout.units, n / 64);
        }
        // The previous samples while new ones are taken: a time-separable velocity's three
        // components and their keys (a tile's coordinate per 64 voxels), or one array for
        // a static speed or curvature field.
        let mut spares = 0;
        if let Some(Velocity::Field(f)) = &flow.velocity
            && f.time_scale(0.0).is_some()
        {
            spares = 3;
            b += growth_bytes(&self.velocity_layout.units, n / 64);
        }
        let static_speed = matches!(&flow.speed, Speed::Field(f) if !f.time_dependent());
        if static_speed || flow.curvature_field.as_ref().is_some_and(|z| !z.time_dependent()) {
            spares = spares.max(1);
        }
        b + self.spare[..spares].iter().map(|c| growth_bytes(c, n)).sum::<u64>()
    }

    /// Fills the per-voxel F and u of `rep`'s voxels for a stage at time `t` of step
    /// `step`; returns κ̄ when the flow is volume-conserving. `first` marks stage 1 (the
    /// layout may have changed since the last step); fields that do not depend on time are
    /// sampled only then, into `base` (F), `curvature` and `velocity` (u), and only when
    /// the layout has changed since they were last sampled (a tile list that stays keeps
    /// its samples). Every sample the stage reads must be finite
    /// ([`EvolveError::NonFiniteField`] otherwise). Changes only these inputs.
    pub fn prepare(
        &mut self,
        rep: &dyn Representation,
        flow: &Flow,
        settings: &Settings,
        t: f64,
        first: bool,
        step: u64,
    ) -> Result<Option<f64>, EvolveError> {
        let pool = &settings.pool;
        let kappa_bar = kappa_bar(rep, flow, settings)?;
        // Volume conservation: F += ε κ̄ of the current stage's φ.
        let add = kappa_bar.map_or(0.0, |kb| (flow.curvature as f64 * kb) as f32);
        let part = read_part(read_slices(rep, settings));
        self.fill_speed(rep, &flow.speed, settings, t, first, add);
        let written = self.fill_velocity(rep, flow.velocity.as_ref(), pool, t, first);
        let curvature_ok = self.fill_curvature(rep, flow, settings, t, first);
        // Every sample a stage reads must be finite: a NaN would count as 0 in the upwind
        // choice and an infinity would turn into NaN and then −γ. (Arrays are checked
        // when written; a scale in every stage.) Each part tested whole, without an early
        // exit, so that the test vectorises.
        let finite = |v: &[f32]| {
            in_pool(pool, || {
                v.par_chunks(CHUNK).all(|c| {
                    read_parts(c, part).all(|c| c.iter().fold(true, |ok, x| ok & x.is_finite()))
                })
            })
        };
        let velocity_ok = self.velocity_scale.is_finite()
            && match written {
                Written::Nothing => true,
                Written::Arrays => self.velocity.iter().all(|c| finite(c)),
                Written::Checked(ok) => ok,
            };
        let speed_ok = self.uniform_speed.map_or_else(|| finite(&self.speed), f32::is_finite);
        if !speed_ok || !velocity_ok || !curvature_ok {
            return Err(EvolveError::NonFiniteField { step, time: t });
        }
        Ok(kappa_bar)
    }

    /// Normal speed F = base + `add`, uniform (no per-voxel array) for a constant F; at
    /// the voxels the sweeps read ([`Representation::read_slices`]: the others are left as
    /// they are).
    fn fill_speed(
        &mut self,
        rep: &dyn Representation,
        speed: &Speed,
        settings: &Settings,
        t: f64,
        first: bool,
        add: f32,
    ) {
        let (pool, planar) = (&settings.pool, planar(settings));
        let part = read_part(read_slices(rep, settings));
        let n = rep.flat().len();
        self.uniform_speed = None;
        if !matches!(speed, Speed::Constant(_)) {
            resize_exact(&mut self.speed, n, 0.0);
        }
        match speed {
            Speed::Constant(f) => {
                self.uniform_speed = Some(*f + add);
                self.speed.clear();
            }
            Speed::Field(f) => {
                // Every stage when F depends on time; else in stage 1, for the units new
                // to the layout F was sampled on (the speed is checked below, as a whole).
                if f.time_dependent() {
                    self.base_layout.clear();
                    resize_exact(&mut self.base, n, 0.0);
                    let base = &mut self.base;
                    in_pool(pool, || rep.fill_scalar(f.as_ref(), t, planar, base));
                } else if first && !(self.base.len() == n && self.base_layout.holds(rep)) {
                    let (base, spare) = (&mut self.base, &mut self.spare[0]);
                    let layout = &mut self.base_layout;
                    resample(rep, f.as_ref(), planar, pool, layout, base, spare, &|_| true);
                }
                let (speed, base) = (&mut self.speed, &self.base);
                in_pool(pool, || {
                    speed.par_chunks_mut(CHUNK).zip(base.par_chunks(CHUNK)).for_each(|(s, b)| {
                        for (s, b) in read_parts_mut(s, part).zip(read_parts(b, part)) {
                            s.iter_mut().zip(b).for_each(|(s, &b)| *s = b + add);
                        }
                    })
                });
            }
            Speed::MorphTo(target) => {
                self.base_layout.clear();
                if first {
                    resize_exact(&mut self.base, n, 0.0);
                    let base = &mut self.base;
                    in_pool(pool, || rep.fill_scalar(target.as_ref(), t, planar, base));
                    let g = rep.spec().gamma();
                    let base = &mut self.base;
                    in_pool(pool, || base.par_iter_mut().for_each(|v| *v = v.clamp(-g, g)));
                }
                let (speed, base) = (&mut self.speed, &self.base);
                in_pool(pool, || {
                    speed
                        .par_chunks_mut(CHUNK)
                        .zip(rep.flat().par_chunks(CHUNK))
                        .zip(base.par_chunks(CHUNK))
                        .for_each(|((s, phi), psi)| {
                            let parts = read_parts_mut(s, part)
                                .zip(read_parts(phi, part))
                                .zip(read_parts(psi, part));
                            for ((s, phi), psi) in parts {
                                for ((s, &phi), &psi) in s.iter_mut().zip(phi).zip(psi) {
                                    *s = (phi - psi) + add;
                                }
                            }
                        })
                });
            }
        }
    }

    /// ε Z(x) per voxel, times the lattice's curvature factor, when the flow has a
    /// curvature field (sampled in stage 1, and in every stage when it depends on time);
    /// returns whether every sample the sweeps read ([`Representation::read_slices`]) is
    /// finite and ≥ 0.
    fn fill_curvature(
        &mut self,
        rep: &dyn Representation,
        flow: &Flow,
        settings: &Settings,
        t: f64,
        first: bool,
    ) -> bool {
        let pool = &settings.pool;
        let part = read_part(read_slices(rep, settings));
        let factor = settings.lattice.map_or(1.0, |l| l.curvature_factor());
        let Some(z) = &flow.curvature_field else {
            self.curvature.clear();
            return true;
        };
        if !(first || z.time_dependent()) {
            return true;
        }
        // A field that does not change with time, on the layout it was sampled (and
        // checked) on with the same weight: as it is.
        let n = rep.flat().len();
        let eps = flow.curvature * factor;
        if self.curvature_weight.to_bits() != eps.to_bits() {
            self.curvature_layout.clear();
            self.curvature_weight = eps;
        }
        if !z.time_dependent() && self.curvature.len() == n && self.curvature_layout.holds(rep) {
            return true;
        }
        // Each new sample checked, then weighted.
        let weigh = |c: &mut [f32]| {
            let ok = c.iter().fold(true, |ok, &v| ok & (v.is_finite() & (v >= 0.0)));
            c.iter_mut().for_each(|v| *v *= eps);
            ok
        };
        if !z.time_dependent() {
            let (out, spare) = (&mut self.curvature, &mut self.spare[0]);
            let layout = &mut self.curvature_layout;
            return resample(rep, z.as_ref(), planar(settings), pool, layout, out, spare, &weigh);
        }
        self.curvature_layout.clear();
        resize_exact(&mut self.curvature, n, 0.0);
        let out = &mut self.curvature;
        in_pool(pool, || rep.fill_scalar(z.as_ref(), t, planar(settings), out));
        let curvature = &mut self.curvature;
        in_pool(pool, || {
            curvature
                .par_chunks_mut(CHUNK)
                .map(|c| read_parts_mut(c, part).fold(true, |ok, c| weigh(c) & ok))
                .reduce(|| true, |a, b| a && b)
        })
    }

    /// Advection velocity u; returns what was written (and how it is to be checked).
    fn fill_velocity(
        &mut self,
        rep: &dyn Representation,
        velocity: Option<&Velocity>,
        pool: &Option<Arc<rayon::ThreadPool>>,
        t: f64,
        first: bool,
    ) -> Written {
        self.velocity_scale = 1.0;
        let Some(vel) = velocity else { return Written::Nothing };
        let n = rep.flat().len();
        let written = |w: bool| if w { Written::Arrays } else { Written::Nothing };
        // u(x, t) = s(t) u(x, 0): u(x, 0) sampled once per step (where the layout changed),
        // the kernels multiply by s.
        if let Velocity::Field(f) = vel
            && let Some(scale) = f.time_scale(t)
        {
            self.velocity_scale = scale;
            return if first {
                self.fill_static(rep, f.as_ref(), pool, n)
            } else {
                Written::Nothing
            };
        }
        self.velocity_layout.clear();
        for c in &mut self.velocity {
            resize_exact(c, n, 0.0);
        }
        match vel {
            Velocity::Constant(u) => {
                if first {
                    for (c, &v) in self.velocity.iter_mut().zip(u) {
                        c.fill(v);
                    }
                }
                written(first)
            }
            Velocity::Field(f) => {
                let sample = first || f.time_dependent();
                if sample {
                    let [a, b, c] = &mut self.velocity;
                    in_pool(pool, || rep.fill_vector(f.as_ref(), t, [a, b, c]));
                }
                written(sample)
            }
        }
    }

    /// u(x, 0) of a time-separable field at the `n` voxels of `rep`: the samples of
    /// units kept from the last step are reused ([`Representation::fill_static_vector`]),
    /// the others sampled and checked.
    fn fill_static(
        &mut self,
        rep: &dyn Representation,
        f: &dyn VectorFn,
        pool: &Option<Arc<rayon::ThreadPool>>,
        n: usize,
    ) -> Written {
        let layout = &mut self.velocity_layout;
        if layout.holds(rep) && self.velocity.iter().all(|c| c.len() == n) {
            // The same units as the samples' (checked when taken): nothing to do.
            return Written::Checked(true);
        }
        if layout.spec != Some(rep.spec()) {
            layout.clear();
        }
        layout.spec = Some(rep.spec());
        if layout.units.is_empty() {
            // Nothing to reuse: no copy of the old samples either.
            for c in &mut self.velocity {
                c.clear();
            }
        }
        for c in &mut self.spare {
            resize_exact(c, n, 0.0);
        }
        std::mem::swap(&mut self.spare, &mut self.velocity);
        let [a, b, c] = &mut self.velocity;
        let [pa, pb, pc] = &self.spare;
        let keys = &mut self.velocity_layout.units;
        let ok = in_pool(pool, || rep.fill_static_vector(f, keys, [pa, pb, pc], [a, b, c]));
        if !ok {
            // Sample everything anew next time: the step stops here, and its retry must
            // not take a non-finite sample as checked.
            self.velocity_layout.clear();
        }
        Written::Checked(ok)
    }

    /// max |F|, max (|u|+|v|+|w|), the same of the unscaled samples (u(x, 0) of a
    /// time-separable field; equal otherwise) and the largest curvature weight (ε, or
    /// max ε Z(x) with a curvature field) over the band voxels of `flat` (the set
    /// every representation holds, so every representation takes the same Δt) that the
    /// sweeps read (`slices`, [`Representation::read_slices`]: a planar lattice's other
    /// slices are copies). One pass, in parallel chunks (call it in the pool): a maximum of
    /// finite values does not depend on how it is grouped, so neither do the bits.
    pub fn band_maxima(
        &self,
        flat: &[f32],
        g: f32,
        advects: bool,
        eps: f32,
        slices: Option<(usize, usize)>,
    ) -> (f32, f32, f32, f32) {
        let s = self.velocity_scale;
        // Every step starts with band voxels (or the interface has collapsed).
        let uniform = self.uniform_speed.map(f32::abs);
        let curvature = !self.curvature.is_empty();
        if let (Some(f), false, false) = (uniform, advects, curvature) {
            // Nothing per voxel to scan.
            return (f, 0.0, 0.0, eps);
        }
        let part = read_part(slices);
        let (speed, [a, b, c], z) = (&self.speed, &self.velocity, &self.curvature);
        let max4 = |x: [f32; 4], y: [f32; 4]| std::array::from_fn(|i| x[i].max(y[i]));
        let [max_f, max_u, max_u0, max_e] = flat
            .par_chunks(CHUNK)
            .enumerate()
            .map(|(k, v)| {
                let mut acc = [[0.0f32; MAX_LANES]; 4];
                for (j, v) in read_parts(v, part).enumerate() {
                    let at = k * CHUNK + j * part.0;
                    let r = at..at + v.len();
                    if uniform.is_none() {
                        band_max_into(&mut acc[0], v, g, [&speed[r.clone()]], |[f]| f.abs());
                    }
                    if advects {
                        let abc = [&a[r.clone()], &b[r.clone()], &c[r.clone()]];
                        let sum = |[a, b, c]: [f32; 3]| a.abs() + b.abs() + c.abs();
                        band_max_into(&mut acc[2], v, g, abc, sum);
                        if s != 1.0 {
                            let scaled =
                                |[a, b, c]: [f32; 3]| (a * s).abs() + (b * s).abs() + (c * s).abs();
                            band_max_into(&mut acc[1], v, g, abc, scaled);
                        }
                    }
                    if curvature {
                        band_max_into(&mut acc[3], v, g, [&z[r]], |[e]| e);
                    }
                }
                acc.map(|lanes| lanes.into_iter().fold(0.0, larger))
            })
            .reduce(|| [0.0; 4], max4);
        let max_f = uniform.unwrap_or(max_f);
        // Unscaled samples (s = 1) are their own scaled maximum.
        let max_u = if advects && s == 1.0 { max_u0 } else { max_u };
        (max_f, max_u, max_u0, if curvature { max_e } else { eps })
    }

    /// The inputs of stage `stage` with step `dt` (φⁿ is set by the representation).
    pub fn params(&self, stage: u8, dt: f32, spec: &GridSpec, flow: &Flow) -> StageParams<'_> {
        StageParams {
            stage,
            dt,
            gamma: spec.gamma(),
            h: spec.voxel_size,
            eps: flow.curvature,
            rescale: 0.0,
            uniform_speed: self.uniform_speed,
            speed: &self.speed,
            velocity: flow
                .velocity
                .as_ref()
                .map(|_| [&self.velocity[0][..], &self.velocity[1][..], &self.velocity[2][..]]),
            velocity_scale: self.velocity_scale,
            phi_n: &[],
            curvature: (!self.curvature.is_empty()).then_some(&self.curvature[..]),
            lattice: None,
        }
    }
}

/// κ̄ of the current values (eq. (6)), for a volume-conserving flow.
fn kappa_bar(
    rep: &dyn Representation,
    flow: &Flow,
    settings: &Settings,
) -> Result<Option<f64>, EvolveError> {
    if !flow.volume_conserving {
        return Ok(None);
    }
    let width = settings.delta_width * rep.spec().voxel_size;
    let (num, den) = in_pool(&settings.pool, || rep.kappa_bar_sums(width))?;
    let h = rep.spec().voxel_size as f64;
    // The sums hold κδ|∇φ|·h² and δ|∇φ|·h (see `KappaBarTerm`).
    Ok(Some(if den.value() > 0.0 { num.value() / den.value() / h } else { 0.0 }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Inputs with every per-voxel array of `n` voxels set from `f(voxel, array)`.
    fn inputs(n: usize, s: f32, f: impl Fn(usize, usize) -> f32) -> Inputs {
        let column = |k: usize| (0..n).map(|i| f(i, k)).collect::<Vec<f32>>();
        Inputs {
            speed: column(0),
            velocity: [column(1), column(2), column(3)],
            velocity_scale: s,
            curvature: column(4),
            ..Inputs::default()
        }
    }

    /// The maxima as the definition reads, voxel by voxel over `voxels`.
    fn by_definition(i: &Inputs, flat: &[f32], g: f32, voxels: &[usize]) -> [f32; 4] {
        let mut m = [0.0f32; 4];
        for &v in voxels.iter().filter(|&&v| flat[v].abs() < g) {
            let u = |k: usize| i.velocity[k][v];
            let s = i.velocity_scale;
            m[0] = m[0].max(i.speed[v].abs());
            m[1] = m[1].max((u(0) * s).abs() + (u(1) * s).abs() + (u(2) * s).abs());
            m[2] = m[2].max(u(0).abs() + u(1).abs() + u(2).abs());
            m[3] = m[3].max(i.curvature[v]);
        }
        m
    }

    #[test]
    fn lane_maxima_equal_a_scan_at_every_length() {
        // Lengths around the 16 lanes (the remainder taken lane by lane too), values in
        // and out of the band, and a running maximum the scan must keep.
        let wave = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 100.0 - 5.0;
        for n in [0, 1, 5, 15, 16, 17, 31, 40, 64, 100] {
            let v: Vec<f32> = (0..n).map(|i| wave(i, 0)).collect();
            let [a, b, c]: [Vec<f32>; 3] =
                std::array::from_fn(|k| (0..n + 3).map(|i| wave(i, k + 1)).collect());
            let sum = |[a, b, c]: [f32; 3]| a.abs() + b.abs() + c.abs();
            let mut acc = [0.0f32; MAX_LANES];
            acc[3] = 0.5;
            band_max_into(&mut acc, &v, 3.0, [&a, &b, &c], sum);
            let got = acc.into_iter().fold(0.0, larger);
            let want = (0..n)
                .filter(|&i| v[i].abs() < 3.0)
                .map(|i| sum([a[i], b[i], c[i]]))
                .fold(0.5f32, f32::max);
            assert_eq!(got.to_bits(), want.to_bits(), "n = {n}");
        }
    }

    #[test]
    fn band_maxima_read_the_band_voxels_of_the_slices_the_sweeps_read() {
        // 150 tiles (more than one task of CHUNK values, the last one partial); values
        // that differ from voxel to voxel, half of them outside the band (|φ| ≥ g = 3).
        let n = 150 * 64;
        let wave = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 100.0 - 5.0;
        let flat: Vec<f32> = (0..n).map(|i| wave(i, 5)).collect();
        let g = 3.0;
        for s in [1.0, -0.5] {
            let mut inp = inputs(n, s, |i, k| if k == 4 { wave(i, k).abs() } else { wave(i, k) });
            let got = inp.band_maxima(&flat, g, true, 0.25, None);
            let all: Vec<usize> = (0..n).collect();
            assert_eq!(<[f32; 4]>::from(got), by_definition(&inp, &flat, g, &all));
            // A planar lattice's tiles: only each tile's first 16 voxels are read, so a
            // larger value (or a NaN) in the other slices does not count.
            let first: Vec<usize> = (0..n).filter(|i| i % 64 < 16).collect();
            let expect = by_definition(&inp, &flat, g, &first);
            for v in (0..n).filter(|i| i % 64 >= 16) {
                inp.speed[v] = if v % 2 == 0 { 1e9 } else { f32::NAN };
                inp.curvature[v] = 1e9;
            }
            let got = inp.band_maxima(&flat, g, true, 0.25, Some((64, 16)));
            assert_eq!(<[f32; 4]>::from(got), expect);
            assert!(expect.iter().all(|&m| m > 0.0), "a test that reads values");
        }
        // A uniform speed, no velocity and no curvature field: nothing to scan.
        let uniform = Inputs { uniform_speed: Some(-2.0), ..Inputs::default() };
        assert_eq!(uniform.band_maxima(&flat, g, false, 0.25, None), (2.0, 0.0, 0.0, 0.25));
    }
}
