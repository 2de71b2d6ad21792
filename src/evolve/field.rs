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
    /// Whether the field changes with `t`. If not, its values must depend on the position
    /// alone: a simulation samples it at most once per step, and keeps the samples while
    /// its layout (the tile list) stays.
    fn time_dependent(&self) -> bool {
        true
    }
}

/// A vector field u(x, t) in world units per unit time, sampled along x-runs of voxels.
pub trait VectorFn: Send + Sync {
    /// Writes the components at voxels `start + (i, 0, 0)` into `out[0][i]`, `out[1][i]`,
    /// `out[2][i]`, at time `t`.
    fn fill_run(&self, spec: &GridSpec, start: Coord, t: f64, out: [&mut [f32]; 3]);
    /// The components at the 4×4×4 voxels of the tile whose first voxel is `origin`, in
    /// tile order (x fastest), at time `t`. Must give the values of
    /// [`VectorFn::fill_run`]; the default runs it row by row, a field may share work
    /// across the block.
    fn fill_tile(&self, spec: &GridSpec, origin: Coord, t: f64, out: [&mut [f32]; 3]) {
        let [u, v, w] = out;
        for row in 0..16 {
            let start =
                Coord::new(origin.x, origin.y + (row & 3) as i32, origin.z + (row >> 2) as i32);
            let r = 4 * row..4 * row + 4;
            self.fill_run(spec, start, t, [&mut u[r.clone()], &mut v[r.clone()], &mut w[r]]);
        }
    }
    /// Whether the field changes with `t` (if not, it is sampled once per step).
    fn time_dependent(&self) -> bool {
        true
    }
    /// For a field u(x, t) = s(t) u(x, 0): s(t). Then the field is sampled at t = 0 (at
    /// most once per step, and on tiles only where the tile list changed: the samples
    /// u(x, 0) must depend on the position alone) and scaled by s in each stage (in f32,
    /// the same on every representation).
    fn time_scale(&self, t: f64) -> Option<f32> {
        let _ = t;
        None
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

/// Enright's deformation test field (LeVeque's 3D flow; van der Laan et al. 2011, Sec. 5.4;
/// Nielsen & Museth 2006, Sec. 4.2) in the unit box, periodic in time with period `T`:
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

impl EnrightVelocity {
    /// sin(πa), sin(2πa) of a world coordinate.
    #[inline]
    fn factors(a: f64) -> (f64, f64) {
        ((PI * a).sin(), (2.0 * PI * a).sin())
    }

    /// u, v, w from the per-axis factors and the time factor `c`.
    #[inline]
    fn velocity(x: (f64, f64), y: (f64, f64), z: (f64, f64), c: f64) -> [f32; 3] {
        let ((sx, s2x), (sy, s2y), (sz, s2z)) = (x, y, z);
        [
            (2.0 * sx * sx * s2y * s2z * c) as f32,
            (-(s2x * sy * sy * s2z) * c) as f32,
            (-(s2x * s2y * sz * sz) * c) as f32,
        ]
    }
}

impl VectorFn for EnrightVelocity {
    fn fill_run(&self, spec: &GridSpec, start: Coord, t: f64, out: [&mut [f32]; 3]) {
        let p = spec.world(start);
        let c = (PI * t / self.period).cos();
        let (fy, fz) = (Self::factors(p[1]), Self::factors(p[2]));
        let [u, v, w] = out;
        for i in 0..u.len() {
            // The x position exactly as `GridSpec::world` computes it for this voxel, so a
            // run gives the same numbers as single voxels.
            let x = spec.world(Coord::new(start.x + i as i32, start.y, start.z))[0];
            [u[i], v[i], w[i]] = Self::velocity(Self::factors(x), fy, fz, c);
        }
    }

    /// The factors of the tile's 4 x, 4 y and 4 z positions, shared by its 64 voxels.
    fn fill_tile(&self, spec: &GridSpec, origin: Coord, t: f64, out: [&mut [f32]; 3]) {
        let c = (PI * t / self.period).cos();
        let axis = |k: usize| -> [(f64, f64); 4] {
            std::array::from_fn(|i| {
                let mut q = [origin.x, origin.y, origin.z];
                q[k] += i as i32;
                Self::factors(spec.world(Coord::new(q[0], q[1], q[2]))[k])
            })
        };
        let (fx, fy, fz) = (axis(0), axis(1), axis(2));
        let [u, v, w] = out;
        for i in 0..64 {
            [u[i], v[i], w[i]] = Self::velocity(fx[i & 3], fy[(i >> 2) & 3], fz[i >> 4], c);
        }
    }

    fn time_scale(&self, t: f64) -> Option<f32> {
        Some((PI * t / self.period).cos() as f32)
    }
}

/// The normal speed F of eq. (3) (φ_t = −F|∇φ|; F > 0 moves the interface outward).
#[derive(Clone)]
pub enum Speed {
    /// The same F everywhere.
    Constant(f32),
    /// F(x, t) from a field.
    Field(Arc<dyn ScalarFn>),
    /// Morphing toward a target level set ψ (Houston et al. 2006, Sec. 6.4.1, eq. (1)): F = φ − ψ,
    /// i.e. φ_t = (ψ − φ)|∇φ|. Eq. (1) as printed, φ_t = (φ − ψ)|∇φ|, makes the difference
    /// e = φ − ψ grow (e_t = e|∇φ|) under either sign convention, so its sign is reversed
    /// here: this form's steady state is φ = ψ. The target is clamped to ±γ like a sparse
    /// level set (the "speed limit" the paper mentions).
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

/// A field given on its own dense grid (an image, a simulated velocity component),
/// sampled at world positions by trilinear interpolation (van der Laan et al. 2011, Sec. 5.4:
/// fields that are not analytic, or live on a grid of another resolution, are interpolated);
/// positions beyond the grid take the value of its nearest face.
#[derive(Clone, Debug)]
pub struct SampledField {
    field: crate::storage::dense::DenseField,
    spec: GridSpec,
}

impl SampledField {
    /// `field` placed in the world by `spec` (voxel size and origin; the half-width is
    /// not used). Non-finite values are an error.
    pub fn new(
        field: crate::storage::dense::DenseField,
        spec: GridSpec,
    ) -> Result<SampledField, crate::grid::GridError> {
        if let Some(i) = crate::storage::dense::first_position(field.data(), |v| !v.is_finite()) {
            return Err(crate::grid::GridError::InvalidParameter(format!(
                "field value {} at voxel {} is not finite",
                field.data()[i],
                field.coord_of(i).unwrap_or_default()
            )));
        }
        Ok(SampledField { field, spec })
    }

    /// The interpolated value at world position `p`.
    pub fn sample(&self, p: [f64; 3]) -> f32 {
        let h = self.spec.voxel_size as f64;
        let o = self.field.origin();
        let dims = self.field.dims();
        let mut i0 = [0usize; 3];
        let mut w = [0.0f64; 3];
        for a in 0..3 {
            let origin = [o.x, o.y, o.z][a] as f64;
            let u = ((p[a] - self.spec.origin[a]) / h - origin).clamp(0.0, (dims[a] - 1) as f64);
            let f = u.floor().min((dims[a].max(2) - 2) as f64).max(0.0);
            i0[a] = f as usize;
            w[a] = if dims[a] > 1 { u - f } else { 0.0 };
        }
        let d = self.field.data();
        let corners = std::array::from_fn(|k| {
            let x = (i0[0] + (k & 1)).min(dims[0] - 1);
            let y = (i0[1] + (k >> 1 & 1)).min(dims[1] - 1);
            let z = (i0[2] + (k >> 2)).min(dims[2] - 1);
            d[x + dims[0] * (y + dims[1] * z)] as f64
        });
        crate::storage::interpolate::trilinear(&corners, w) as f32
    }
}

impl ScalarFn for SampledField {
    fn fill_run(&self, spec: &GridSpec, start: Coord, _t: f64, out: &mut [f32]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.sample(spec.world(Coord::new(start.x + i as i32, start.y, start.z)));
        }
    }
    fn time_dependent(&self) -> bool {
        false
    }
}

/// A velocity given as three [`SampledField`] components.
#[derive(Clone, Debug)]
pub struct SampledVelocity(pub [SampledField; 3]);

impl SampledVelocity {
    /// The components `[u_x, u_y, u_z]` on their dense grids (each placed by its origin on
    /// the lattice of `spec`, e.g. as read by [`crate::io::npy::read_npy_vector`]).
    /// Non-finite values are an error.
    pub fn new(
        fields: [crate::storage::dense::DenseField; 3],
        spec: GridSpec,
    ) -> Result<SampledVelocity, crate::grid::GridError> {
        let [x, y, z] = fields;
        Ok(SampledVelocity([
            SampledField::new(x, spec)?,
            SampledField::new(y, spec)?,
            SampledField::new(z, spec)?,
        ]))
    }
}

impl VectorFn for SampledVelocity {
    fn fill_run(&self, spec: &GridSpec, start: Coord, _t: f64, out: [&mut [f32]; 3]) {
        for (c, o) in self.0.iter().zip(out) {
            c.fill_run(spec, start, 0.0, o);
        }
    }
    fn time_dependent(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::dense::DenseField;

    #[test]
    fn enright_tiles_runs_and_time_scale_agree() {
        let spec = GridSpec::new(1.0 / 37.0, [0.01, -0.02, 0.03], 3.0).unwrap();
        let f = EnrightVelocity { period: 3.0 };
        let origin = Coord::new(8, -4, 12);
        let t = 0.7;
        let mut tile = [[0.0f32; 64]; 3];
        let [a, b, c] = &mut tile;
        f.fill_tile(&spec, origin, t, [a, b, c]);
        let mut base = [[0.0f32; 64]; 3];
        let [a, b, c] = &mut base;
        f.fill_tile(&spec, origin, 0.0, [a, b, c]);
        let s = f.time_scale(t).unwrap();
        for row in 0..16 {
            let start = Coord::new(origin.x, origin.y + (row & 3), origin.z + (row >> 2));
            let mut run = [[0.0f32; 4]; 3];
            let [a, b, c] = &mut run;
            f.fill_run(&spec, start, t, [a, b, c]);
            for k in 0..3 {
                for (i, r) in run[k].iter().enumerate() {
                    let j = 4 * row as usize + i;
                    assert_eq!(r.to_bits(), tile[k][j].to_bits());
                    assert!((base[k][j] * s - tile[k][j]).abs() <= 1e-6);
                }
            }
        }
    }

    #[test]
    fn trilinear_sampling_is_exact_on_linear_fields() {
        let spec = GridSpec::new(0.5, [1.0, -2.0, 0.25], 3.0).unwrap();
        let lin = |c: Coord| {
            let p = spec.world(c);
            (0.5 * p[0] - 2.0 * p[1] + 0.25 * p[2] + 1.0) as f32
        };
        let field = DenseField::from_fn(Coord::new(-3, 2, 5), [7, 5, 6], lin).unwrap();
        let s = SampledField::new(field, spec).unwrap();
        // At voxel centres and between them, inside the grid.
        for p in [[0.0, -0.5, 2.75], [1.3, 0.1, 3.2], [-0.2, 0.3, 3.9]] {
            let exact = 0.5 * p[0] - 2.0 * p[1] + 0.25 * p[2] + 1.0;
            assert!((s.sample(p) as f64 - exact).abs() < 1e-5, "{p:?}");
        }
        // Beyond the grid: the nearest face's value.
        let face = s.sample([-100.0, 0.1, 3.2]);
        let edge = s.sample([spec.world(Coord::new(-3, 0, 0))[0], 0.1, 3.2]);
        assert_eq!(face, edge);
        let mut bad = DenseField::new(Coord::new(0, 0, 0), [2, 2, 2], 0.0).unwrap();
        bad.data_mut()[3] = f32::NAN;
        assert!(SampledField::new(bad, spec).is_err());
    }
}
