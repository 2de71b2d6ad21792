//! Externally given fields of a flow: a scalar F(x, t) (normal speed, morph target) and a
//! vector u(x, t) (advection velocity), sampled at voxel centres.
//!
//! Both grids and the dense reference sample a field run by run: `len` consecutive voxels
//! along x from `start`. A field's value at a voxel must depend only on that voxel and `t`
//! (not on how the grid cuts its voxels into runs), so every representation gets the same
//! numbers; [`EnrightVelocity`] uses runs to share the y and z factors of a row.

use crate::coord::Coord;
use crate::grid::GridSpec;
use std::f64::consts::PI;
use std::sync::Arc;

/// A scalar field F(x, t) in world units, sampled along x-runs of voxels.
pub trait ScalarFn: Send + Sync {
    /// Writes the value at voxels `start + (i, 0, 0)`, `i in 0..out.len()`, at time `t`.
    fn fill_run(&self, spec: &GridSpec, start: Coord, t: f64, out: &mut [f32]);
    /// Whether the field changes with `t` (if not, it is sampled once per step).
    fn time_dependent(&self) -> bool {
        true
    }
}

/// A vector field u(x, t) in world units per unit time, sampled along x-runs of voxels.
pub trait VectorFn: Send + Sync {
    /// Writes the components at voxels `start + (i, 0, 0)` into `out[0][i]`, `out[1][i]`,
    /// `out[2][i]`, at time `t`.
    fn fill_run(&self, spec: &GridSpec, start: Coord, t: f64, out: [&mut [f32]; 3]);
    /// Whether the field changes with `t` (if not, it is sampled once per step).
    fn time_dependent(&self) -> bool {
        true
    }
}

/// A scalar field from a closure of the world position and time.
pub struct ScalarClosure<F>(pub F);

impl<F: Fn([f64; 3], f64) -> f32 + Send + Sync> ScalarFn for ScalarClosure<F> {
    fn fill_run(&self, spec: &GridSpec, start: Coord, t: f64, out: &mut [f32]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = (self.0)(spec.world(Coord::new(start.x + i as i32, start.y, start.z)), t);
        }
    }
}

/// A vector field from a closure of the world position and time.
pub struct VectorClosure<F>(pub F);

impl<F: Fn([f64; 3], f64) -> [f32; 3] + Send + Sync> VectorFn for VectorClosure<F> {
    fn fill_run(&self, spec: &GridSpec, start: Coord, t: f64, out: [&mut [f32]; 3]) {
        let [u, v, w] = out;
        for i in 0..u.len() {
            let c = (self.0)(spec.world(Coord::new(start.x + i as i32, start.y, start.z)), t);
            (u[i], v[i], w[i]) = (c[0], c[1], c[2]);
        }
    }
}

/// A time-independent signed distance (a shape, a target of a morph) as a scalar field,
/// clamped to `[-clamp, clamp]`.
pub struct StaticSdf<F> {
    pub sdf: F,
    pub clamp: f32,
}

impl<F: Fn([f64; 3]) -> f64 + Send + Sync> ScalarFn for StaticSdf<F> {
    fn fill_run(&self, spec: &GridSpec, start: Coord, _t: f64, out: &mut [f32]) {
        for (i, o) in out.iter_mut().enumerate() {
            let d = (self.sdf)(spec.world(Coord::new(start.x + i as i32, start.y, start.z)));
            *o = (d as f32).clamp(-self.clamp, self.clamp);
        }
    }
    fn time_dependent(&self) -> bool {
        false
    }
}

/// Enright's deformation test field (LeVeque's 3D flow, tile paper Sec. 5.4, DT-Grid paper
/// Sec. 4.2) in the unit box, periodic in time with period `T`:
///
/// ```text
/// u =  2 sin²(πx) sin(2πy) sin(2πz) cos(πt/T)
/// v = −  sin(2πx) sin²(πy) sin(2πz) cos(πt/T)
/// w = −  sin(2πx) sin(2πy) sin²(πz) cos(πt/T)
/// ```
///
/// Divergence free; the flow stretches a sphere into thin sheets until t = T/2 and takes it
/// back to the start at t = T.
#[derive(Clone, Copy, Debug)]
pub struct EnrightVelocity {
    pub period: f64,
}

impl VectorFn for EnrightVelocity {
    fn fill_run(&self, spec: &GridSpec, start: Coord, t: f64, out: [&mut [f32]; 3]) {
        let p = spec.world(start);
        let c = (PI * t / self.period).cos();
        let (sy, s2y) = ((PI * p[1]).sin(), (2.0 * PI * p[1]).sin());
        let (sz, s2z) = ((PI * p[2]).sin(), (2.0 * PI * p[2]).sin());
        let [u, v, w] = out;
        for i in 0..u.len() {
            // The x position exactly as `GridSpec::world` computes it for this voxel, so a
            // run gives the same numbers as single voxels.
            let x = spec.world(Coord::new(start.x + i as i32, start.y, start.z))[0];
            let (sx, s2x) = ((PI * x).sin(), (2.0 * PI * x).sin());
            u[i] = (2.0 * sx * sx * s2y * s2z * c) as f32;
            v[i] = (-(s2x * sy * sy * s2z) * c) as f32;
            w[i] = (-(s2x * s2y * sz * sz) * c) as f32;
        }
    }
}

/// The normal speed F of eq. (3) (φ_t = −F|∇φ|; F > 0 moves the interface outward).
#[derive(Clone)]
pub enum Speed {
    /// The same F everywhere.
    Constant(f32),
    /// F(x, t) from a field.
    Field(Arc<dyn ScalarFn>),
    /// Morphing toward a target level set ψ (H-RLE paper Sec. 6.4.1, eq. (1)): F = φ − ψ,
    /// i.e. φ_t = (ψ − φ)|∇φ|. The paper prints (φ − ψ)|∇φ| for its opposite sign
    /// convention (φ > 0 inside); with φ < 0 inside this is the form whose steady state
    /// is φ = ψ. The target is clamped to ±γ like a sparse level set (the "speed limit"
    /// the paper mentions).
    MorphTo(Arc<dyn ScalarFn>),
}

impl Speed {
    /// F(x, t) from a closure of the world position and time.
    pub fn from_fn<F: Fn([f64; 3], f64) -> f32 + Send + Sync + 'static>(f: F) -> Speed {
        Speed::Field(Arc::new(ScalarClosure(f)))
    }
}

impl std::fmt::Debug for Speed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Speed::Constant(v) => write!(f, "Constant({v})"),
            Speed::Field(_) => write!(f, "Field(..)"),
            Speed::MorphTo(_) => write!(f, "MorphTo(..)"),
        }
    }
}

/// An advection velocity u (φ_t + u·∇φ = 0).
#[derive(Clone)]
pub enum Velocity {
    /// The same u everywhere.
    Constant([f32; 3]),
    /// u(x, t) from a field.
    Field(Arc<dyn VectorFn>),
}

impl Velocity {
    /// u(x, t) from a closure of the world position and time.
    pub fn from_fn<F: Fn([f64; 3], f64) -> [f32; 3] + Send + Sync + 'static>(f: F) -> Velocity {
        Velocity::Field(Arc::new(VectorClosure(f)))
    }
}

impl std::fmt::Debug for Velocity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Velocity::Constant(v) => write!(f, "Constant({v:?})"),
            Velocity::Field(_) => write!(f, "Field(..)"),
        }
    }
}
