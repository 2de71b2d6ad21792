//! The flows' inputs sampled on the image lattice: a dense volume read at the voxel a
//! level-set voxel sits on (no interpolation: the level set lives on the image's voxels),
//! and the Chan–Vese region force, whose region means change from step to step.

use crate::coord::Coord;
use crate::evolve::{ScalarFn, VectorFn};
use crate::grid::GridSpec;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// Where a lattice voxel falls in the image: its index in the data, or `None` outside.
/// On a 2D image (one slice) every z reads the slice: the level set is extruded along z.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lookup {
    pub dims: [usize; 3],
}

impl Lookup {
    /// The data index of voxel `c`, `None` outside the image.
    #[inline]
    pub fn index(&self, c: Coord) -> Option<usize> {
        let [nx, ny, nz] = self.dims;
        let z = if nz == 1 { 0 } else { c.z };
        if c.x < 0 || c.y < 0 || z < 0 {
            return None;
        }
        let (x, y, z) = (c.x as usize, c.y as usize, z as usize);
        (x < nx && y < ny && z < nz).then(|| x + nx * (y + ny * z))
    }

    /// The data indices of the `len` voxels from `start` along x, when all of them are in
    /// the image (consecutive in the data): the fields' runs read such a slice at once
    /// instead of looking up each voxel.
    #[inline]
    pub fn run(&self, start: Coord, len: usize) -> Option<std::ops::Range<usize>> {
        let first = self.index(start)?;
        (start.x as usize + len <= self.dims[0]).then(|| first..first + len)
    }
}

/// A dense volume on the image lattice as a scalar field of the flow (speed F or the
/// curvature factor Z), `outside` beyond the image.
pub(crate) struct VoxelField {
    pub lookup: Lookup,
    pub data: Arc<Vec<f32>>,
    pub outside: f32,
}

impl ScalarFn for VoxelField {
    fn fill_run(&self, _spec: &GridSpec, start: Coord, _t: f64, out: &mut [f32]) {
        // Element by element, not `copy_from_slice`: the runs are 4 voxels, and a copy of
        // unknown length calls `memmove` (12.6 % of the samples of a 128³ GAC segmentation
        // on one thread, `perf record`, 2-core AMD EPYC, 2026-11-28).
        if let Some(r) = self.lookup.run(start, out.len()) {
            out.iter_mut().zip(&self.data[r]).for_each(|(o, &d)| *o = d);
            return;
        }
        for (i, o) in out.iter_mut().enumerate() {
            let c = Coord::new(start.x + i as i32, start.y, start.z);
            *o = self.lookup.index(c).map_or(self.outside, |k| self.data[k]);
        }
    }
    fn time_dependent(&self) -> bool {
        false
    }
}

/// Three dense volumes as the advection velocity, 0 beyond the image.
pub(crate) struct VoxelVector {
    pub lookup: Lookup,
    pub data: [Arc<Vec<f32>>; 3],
}

impl VectorFn for VoxelVector {
    fn fill_run(&self, _spec: &GridSpec, start: Coord, _t: f64, out: [&mut [f32]; 3]) {
        let [u, v, w] = out;
        if let Some(r) = self.lookup.run(start, u.len()) {
            for (o, d) in [u, v, w].into_iter().zip(&self.data) {
                o.iter_mut().zip(&d[r.clone()]).for_each(|(o, &d)| *o = d);
            }
            return;
        }
        for i in 0..u.len() {
            let c = Coord::new(start.x + i as i32, start.y, start.z);
            (u[i], v[i], w[i]) = match self.lookup.index(c) {
                Some(k) => (self.data[0][k], self.data[1][k], self.data[2][k]),
                None => (0.0, 0.0, 0.0),
            };
        }
    }
    fn time_dependent(&self) -> bool {
        false
    }
    /// The image's samples depend on the position alone: kept from step to step for the
    /// tiles that stay (s = 1 leaves them as they are, bit for bit).
    fn time_scale(&self, _t: f64) -> Option<f32> {
        Some(1.0)
    }
}

/// The Chan–Vese region force with the current region means c₁ (inside) and c₂
/// (outside), set by the driver before each step:
///
/// ```text
/// F = (λ₂ (I − c₂)² − λ₁ (I − c₁)²) / (c₁ − c₂)² − ν,   clamped to [−1, 1]
/// ```
///
/// (Chan & Vese, IEEE TIP 10 (2001), eq. (9), in the level-set form φ_t = −F|∇φ| of Zhao
/// et al. with φ < 0 inside, so that a voxel closer to c₁ pulls the front over it.) The
/// division by (c₁ − c₂)² makes F dimensionless — ±1 at I = c₁ and I = c₂ for λ₁ = λ₂
/// — so the same μ and ν work at any contrast; the clamp keeps outliers from setting the
/// time step. Beyond the image F = −1 (the front stays in the image).
pub(crate) struct RegionForce {
    pub lookup: Lookup,
    /// The intensities the force compares (the smoothed image).
    pub data: Arc<Vec<f32>>,
    pub lambda1: f32,
    pub lambda2: f32,
    pub nu: f32,
    /// Its weight in a sum of methods (1 alone), applied after the clamp.
    pub weight: f32,
    /// c₁ and c₂ as f64 bits.
    means: [AtomicU64; 2],
}

impl RegionForce {
    /// The force on `data` with `[λ₁, λ₂, ν]` and a weight.
    pub fn new(
        lookup: Lookup,
        data: Arc<Vec<f32>>,
        [lambda1, lambda2, nu]: [f32; 3],
        weight: f32,
    ) -> Self {
        RegionForce {
            lookup,
            data,
            lambda1,
            lambda2,
            nu,
            weight,
            means: [AtomicU64::new(0), AtomicU64::new(0)],
        }
    }

    /// Sets c₁ (inside) and c₂ (outside) for the next step.
    pub fn set_means(&self, c1: f64, c2: f64) {
        self.means[0].store(c1.to_bits(), Ordering::Relaxed);
        self.means[1].store(c2.to_bits(), Ordering::Relaxed);
    }

    fn means(&self) -> (f32, f32) {
        let m = |k: usize| f64::from_bits(self.means[k].load(Ordering::Relaxed)) as f32;
        (m(0), m(1))
    }
}

impl ScalarFn for RegionForce {
    fn fill_run(&self, _spec: &GridSpec, start: Coord, _t: f64, out: &mut [f32]) {
        let (c1, c2) = self.means();
        let d = c1 - c2;
        let scale = if d != 0.0 { 1.0 / (d * d) } else { 0.0 };
        let force = |v: f32| {
            let (a, b) = (v - c1, v - c2);
            self.weight
                * ((self.lambda2 * b * b - self.lambda1 * a * a) * scale - self.nu).clamp(-1.0, 1.0)
        };
        if let Some(r) = self.lookup.run(start, out.len()) {
            out.iter_mut().zip(&self.data[r]).for_each(|(o, &v)| *o = force(v));
            return;
        }
        for (i, o) in out.iter_mut().enumerate() {
            let c = Coord::new(start.x + i as i32, start.y, start.z);
            *o = self.lookup.index(c).map_or(-self.weight, |k| force(self.data[k]));
        }
    }
    /// The means change between steps (the driver sets them), so F is sampled in every
    /// stage; they stay fixed within a step.
    fn time_dependent(&self) -> bool {
        true
    }
}

/// The sum of scalar fields (the speeds of a weighted sum of methods, each already
/// weighted).
pub(crate) struct SumField {
    pub terms: Vec<Arc<dyn ScalarFn>>,
}

impl ScalarFn for SumField {
    fn fill_run(&self, spec: &GridSpec, start: Coord, t: f64, out: &mut [f32]) {
        // Terms after the first are added in pieces of a stack buffer (no allocation
        // per run).
        let mut part = [0.0f32; PIECE];
        for (k, f) in self.terms.iter().enumerate() {
            if k == 0 {
                f.fill_run(spec, start, t, out);
                continue;
            }
            for (i, o) in out.chunks_mut(PIECE).enumerate() {
                let at = Coord::new(start.x + (i * PIECE) as i32, start.y, start.z);
                let p = &mut part[..o.len()];
                f.fill_run(spec, at, t, p);
                o.iter_mut().zip(p.iter()).for_each(|(o, p)| *o += p);
            }
        }
    }
    fn time_dependent(&self) -> bool {
        self.terms.iter().any(|f| f.time_dependent())
    }
}

/// Voxels of a sum's stack buffer.
const PIECE: usize = 64;

/// Σ εᵢ Zᵢ(x) of a weighted sum of methods: each term a weight ε and a field Z (1 when
/// none).
pub(crate) struct CurvatureSum {
    pub terms: Vec<(f32, Option<Arc<dyn ScalarFn>>)>,
}

impl ScalarFn for CurvatureSum {
    fn fill_run(&self, spec: &GridSpec, start: Coord, t: f64, out: &mut [f32]) {
        let mut part = [0.0f32; PIECE];
        out.fill(0.0);
        for (eps, z) in &self.terms {
            match z {
                Some(z) => {
                    for (i, o) in out.chunks_mut(PIECE).enumerate() {
                        let at = Coord::new(start.x + (i * PIECE) as i32, start.y, start.z);
                        let p = &mut part[..o.len()];
                        z.fill_run(spec, at, t, p);
                        o.iter_mut().zip(p.iter()).for_each(|(o, p)| *o += eps * p);
                    }
                }
                None => out.iter_mut().for_each(|o| *o += eps),
            }
        }
    }
    fn time_dependent(&self) -> bool {
        self.terms.iter().any(|(_, z)| z.as_ref().is_some_and(|z| z.time_dependent()))
    }
}
