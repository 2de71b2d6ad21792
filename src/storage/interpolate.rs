//! Trilinear interpolation between voxel centres: one formula ([`trilinear`]) and one
//! cached sampler of any level set ([`Trilinear`]), which the ray tracer, the Python
//! package's `LevelSet.value` and the sampled fields of an evolution
//! ([`crate::evolve::SampledField`]) share.

use crate::coord::Coord;
use crate::grid::GridSpec;
use crate::storage::levelset::Accessor;

/// Trilinear interpolation of a cell's eight corner values at the fractions `f` ∈ [0, 1]³
/// of the cell: corner `k` sits at `(k & 1, k >> 1 & 1, k >> 2)` (x fastest), and the
/// lerps run along x, then y, then z. At a corner (`f` of zeros and ones) it returns that
/// corner's value exactly.
#[inline]
pub fn trilinear(c: &[f64; 8], f: [f64; 3]) -> f64 {
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let x00 = lerp(c[0], c[1], f[0]);
    let x10 = lerp(c[2], c[3], f[0]);
    let x01 = lerp(c[4], c[5], f[0]);
    let x11 = lerp(c[6], c[7], f[0]);
    lerp(lerp(x00, x10, f[1]), lerp(x01, x11, f[1]), f[2])
}

/// The trilinear interpolant of any level set between voxel centres, read through its
/// accessor with the eight corners of the last cell cached (consecutive samples of a ray or
/// of nearby points mostly share a cell). Values are in world units or in voxels ([`Units`]);
/// a corner beyond the `i32` lattice reads `+γ`, as every unstored voxel far out does.
pub struct Trilinear<A> {
    acc: A,
    spec: GridSpec,
    scale: f64,
    gamma: f64,
    base: [i64; 3],
    corners: [f64; 8],
    /// Samples taken since the owner last reset it (the ray tracer's budget).
    pub(crate) samples: u32,
}

/// The units of the values a [`Trilinear`] returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Units {
    /// World units, as the level set stores them.
    World,
    /// Voxels: φ / h (the ray tracer's).
    Voxels,
}

impl<A: Accessor> Trilinear<A> {
    /// The interpolant of a level set with `spec`, read through its accessor `acc`.
    pub fn new(acc: A, spec: &GridSpec, units: Units) -> Self {
        let (scale, gamma) = match units {
            Units::World => (1.0, spec.gamma() as f64),
            Units::Voxels => (1.0 / spec.voxel_size as f64, spec.half_width as f64),
        };
        Trilinear {
            acc,
            spec: *spec,
            scale,
            gamma,
            base: [i64::MIN; 3],
            corners: [0.0; 8],
            samples: 0,
        }
    }

    /// The interpolant at voxel-space point `p` (voxel `c` at `p = c`).
    #[inline]
    pub fn phi(&mut self, p: [f64; 3]) -> f64 {
        self.samples += 1;
        let base = [p[0].floor() as i64, p[1].floor() as i64, p[2].floor() as i64];
        if base != self.base {
            self.fill(base);
        }
        let f = [p[0] - base[0] as f64, p[1] - base[1] as f64, p[2] - base[2] as f64];
        trilinear(&self.corners, f)
    }

    /// The interpolant at world point `p` (voxel `c` at `spec.world(c)`).
    #[inline]
    pub fn at_world(&mut self, p: [f64; 3]) -> f64 {
        let h = self.spec.voxel_size as f64;
        let o = self.spec.origin;
        self.phi([(p[0] - o[0]) / h, (p[1] - o[1]) / h, (p[2] - o[2]) / h])
    }

    /// Reads the corners of the cell at `base` (x fastest). A corner beyond the i32 range
    /// cannot be stored, so it reads +γ (outside), as every unstored voxel far out does.
    #[cold]
    fn fill(&mut self, base: [i64; 3]) {
        self.base = base;
        let range = i32::MIN as i64..i32::MAX as i64;
        if base.iter().all(|b| range.contains(b)) {
            let b = Coord::new(base[0] as i32, base[1] as i32, base[2] as i32);
            for (k, c) in self.corners.iter_mut().enumerate() {
                let v = Coord::new(
                    b.x + (k & 1) as i32,
                    b.y + ((k >> 1) & 1) as i32,
                    b.z + (k >> 2) as i32,
                );
                *c = self.acc.value(v) as f64 * self.scale;
            }
            return;
        }
        for (k, c) in self.corners.iter_mut().enumerate() {
            let v = [
                base[0] + (k & 1) as i64,
                base[1] + ((k >> 1) & 1) as i64,
                base[2] + (k >> 2) as i64,
            ];
            let ok = v.iter().all(|&x| (i32::MIN as i64..=i32::MAX as i64).contains(&x));
            *c = if ok {
                self.acc.value(Coord::new(v[0] as i32, v[1] as i32, v[2] as i32)) as f64
                    * self.scale
            } else {
                self.gamma
            };
        }
    }

    /// Unit gradient of the interpolant at `p` by central differences one voxel apart
    /// (continuous across cell faces, unlike the interpolant's own gradient); `None` where
    /// it vanishes.
    pub fn normal(&mut self, p: [f64; 3]) -> Option<[f64; 3]> {
        let mut g = [0.0; 3];
        for a in 0..3 {
            let (mut q, mut r) = (p, p);
            q[a] += 0.5;
            r[a] -= 0.5;
            g[a] = self.phi(q) - self.phi(r);
        }
        let n = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        (n > 0.0 && n.is_finite()).then(|| [g[0] / n, g[1] / n, g[2] / n])
    }
}
