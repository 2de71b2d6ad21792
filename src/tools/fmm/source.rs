//! Reading the input level set and initialising the frozen set at the interface.
//!
//! Two kinds of input offer their candidate voxels with their six neighbours: any
//! narrow-band level set ([`LevelSet`]: its band voxels, neighbours through its cached
//! accessor) and a dense field (every voxel, neighbours by index arithmetic).

use super::march::{Cost, Lattice, Marcher};
use super::FmmError;
use crate::coord::Coord;
use crate::storage::dense::DenseField;
use crate::storage::levelset::{Accessor, LevelSet};

/// Six neighbour values in the order −x, +x, −y, +y, −z, +z; `None` beyond the domain.
pub(crate) type Star = [Option<f32>; 6];

use crate::coord::FACE_OFFSETS as OFFSETS;

/// An input level set (φ < 0 inside, world units).
pub(crate) trait Source {
    /// Values with `|φ| ≥ clamp` are band-edge values (clamped to ±γ) and carry a sign
    /// only; `∞` for a dense field.
    fn clamp(&self) -> f32;
    /// φ at any voxel, `None` beyond the domain.
    fn value(&self, c: Coord) -> Option<f32>;
    /// Inclusive voxel box the march may enter; `None` for the unbounded grids.
    fn domain(&self) -> Option<(Coord, Coord)>;
    /// Visits every voxel that can be next to the interface (the band voxels of a grid,
    /// every voxel of a dense field) with its value and six neighbours.
    fn for_each_candidate(&self, f: &mut dyn FnMut(Coord, f32, &Star));

    /// Per axis, `h₀ / hₐ`: how many march units one voxel step along the axis is (all 1
    /// for the isotropic grids).
    fn ratios(&self) -> [f64; 3] {
        [1.0; 3]
    }

    /// Whether a voxel with φ = 0 exactly lies on the zero level set even without a
    /// neighbour of the other sign (scikit-fmm's rule for dense arrays).
    fn zero_is_interface(&self) -> bool {
        false
    }

    /// Whether `c` is inside (φ < 0); beyond the domain: outside.
    fn inside(&self, c: Coord) -> bool {
        self.value(c).is_some_and(|v| v < 0.0)
    }

    /// The six neighbours of `c` by random access.
    fn star(&self, c: Coord) -> Star {
        OFFSETS.map(|o| c.checked_add(o).and_then(|n| self.value(n)))
    }
}

/// Any narrow-band level set as a source: its band voxels in order, the six neighbours
/// of each through one cached [`Accessor`] (inside a tile they come from the same cached
/// tile). The march is unbounded: beyond the band every voxel reads ±γ.
pub(crate) struct GridSource<'a, G: ?Sized>(pub &'a G);

impl<G: LevelSet + ?Sized> Source for GridSource<'_, G> {
    fn clamp(&self) -> f32 {
        self.0.spec().gamma()
    }
    fn value(&self, c: Coord) -> Option<f32> {
        Some(self.0.value(c))
    }
    fn domain(&self) -> Option<(Coord, Coord)> {
        None
    }
    fn for_each_candidate(&self, f: &mut dyn FnMut(Coord, f32, &Star)) {
        let mut acc = self.0.accessor();
        self.0.for_each_band_voxel(&mut |c, v| {
            // A neighbour beyond the i32 range does not exist.
            let star = OFFSETS.map(|o| c.checked_add(o).map(|n| acc.value(n)));
            f(c, v, &star);
        });
    }
}

/// A dense field as a source: every voxel is a candidate, the march stays in its box.
pub(crate) struct DenseSource<'a> {
    pub field: &'a DenseField,
}

impl Source for DenseSource<'_> {
    fn clamp(&self) -> f32 {
        f32::INFINITY
    }
    fn value(&self, c: Coord) -> Option<f32> {
        self.field.get(c)
    }
    fn domain(&self) -> Option<(Coord, Coord)> {
        Some((self.field.origin(), self.field.max_coord()))
    }
    fn for_each_candidate(&self, f: &mut dyn FnMut(Coord, f32, &Star)) {
        let [nx, ny, nz] = self.field.dims();
        let d = self.field.data();
        let o = self.field.origin();
        let mut i = 0;
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let star = [
                        (x > 0).then(|| d[i - 1]),
                        (x + 1 < nx).then(|| d[i + 1]),
                        (y > 0).then(|| d[i - nx]),
                        (y + 1 < ny).then(|| d[i + nx]),
                        (z > 0).then(|| d[i - nx * ny]),
                        (z + 1 < nz).then(|| d[i + nx * ny]),
                    ];
                    // In range: the field's box is representable (DenseField invariant).
                    let c = Coord::new(o.x + x as i32, o.y + y as i32, o.z + z as i32);
                    f(c, d[i], &star);
                    i += 1;
                }
            }
        }
    }
}

/// A dense array on a [`Lattice`] (periodic axes wrap, obstacles read as absent) as a
/// source: every voxel that is not an obstacle is a candidate.
pub(crate) struct LatticeSource<'a> {
    pub data: &'a [f32],
    pub lattice: &'a Lattice,
}

impl Source for LatticeSource<'_> {
    fn clamp(&self) -> f32 {
        f32::INFINITY
    }
    fn value(&self, c: Coord) -> Option<f32> {
        let l = self.lattice;
        let inside = |v: i32, lo: i32, n: usize| v >= lo && ((v - lo) as usize) < n;
        let ok = inside(c.x, l.lo.x, l.dims[0])
            && inside(c.y, l.lo.y, l.dims[1])
            && inside(c.z, l.lo.z, l.dims[2]);
        let i = l.index(c);
        (ok && !l.blocked.as_ref().is_some_and(|b| b[i])).then(|| self.data[i])
    }
    fn domain(&self) -> Option<(Coord, Coord)> {
        let l = self.lattice;
        let hi = |v: i32, n: usize| v + n as i32 - 1;
        Some((
            l.lo,
            Coord::new(hi(l.lo.x, l.dims[0]), hi(l.lo.y, l.dims[1]), hi(l.lo.z, l.dims[2])),
        ))
    }
    fn ratios(&self) -> [f64; 3] {
        self.lattice.ratios
    }
    fn zero_is_interface(&self) -> bool {
        true
    }
    fn star(&self, c: Coord) -> Star {
        let mut star = [None; 6];
        for (i, s) in star.iter_mut().enumerate() {
            let d = if i % 2 == 0 { -1 } else { 1 };
            *s = self.lattice.step(c, i / 2, d).and_then(|n| self.value(n));
        }
        star
    }
    fn for_each_candidate(&self, f: &mut dyn FnMut(Coord, f32, &Star)) {
        let l = self.lattice;
        let [nx, ny, nz] = l.dims;
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    // In range: the lattice's box is representable.
                    let c = Coord::new(l.lo.x + x as i32, l.lo.y + y as i32, l.lo.z + z as i32);
                    if let Some(v) = self.value(c) {
                        f(c, v, &self.star(c));
                    }
                }
            }
        }
    }
}

/// The distance (in voxels, ≥ 0) from an interface voxel to the zero level set, or
/// `None` when no 6-neighbour differs in sign (Bærentzen Sec. 4: "the voxel has a
/// 6-neighbour on the other side of the surface").
///
/// The paper gives these voxels exact foot-point distances; a sampled field has no
/// surface to project on, so the distance is estimated as `|φ| / |∇φ|` with the gradient
/// from central differences (one-sided where a neighbour is missing or a clamped band-edge
/// value; exact for a linear φ, second order for a smooth one, and blind to a uniform
/// scaling of φ), and capped by the distance to the nearest zero crossing on the voxel's
/// edges, found by linear interpolation `θ = φ_v / (φ_v − φ_n)` — that crossing lies on
/// the interface, so the true distance can be no larger.
///
/// With per-axis spacing, `ratios[a] = h₀ / hₐ` converts axis `a`'s differences and edge
/// fractions to march units of length `h₀` (the gradient component is the difference
/// times `ratios[a]`, the crossing lies `θ / ratios[a]` away); all 1 on an isotropic grid.
pub(crate) fn interface_distance(v: f32, star: &Star, clamp: f32, ratios: [f64; 3]) -> Option<f64> {
    let vi = v < 0.0;
    let v = v as f64;
    let mut theta = f64::INFINITY;
    for (i, n) in star.iter().enumerate() {
        let Some(n) = n else { continue };
        if (*n < 0.0) != vi {
            // ±∞ is a far-away distance: the interpolant's crossing between it and a finite
            // neighbour lies at the neighbour (θ = 1 from an infinite voxel, 0 towards one).
            let t = if v.is_infinite() { 1.0 } else { v / (v - *n as f64) };
            theta = theta.min(t / ratios[i / 2]);
        }
    }
    if theta == f64::INFINITY {
        return None;
    }
    let usable = |n: Option<f32>| n.filter(|n| n.abs() < clamp).map(|n| n as f64);
    let mut g2 = 0.0;
    if (v.abs() as f32) < clamp {
        for a in 0..3 {
            let g = match (usable(star[2 * a]), usable(star[2 * a + 1])) {
                (Some(m), Some(p)) => 0.5 * (p - m),
                (Some(m), None) => v - m,
                (None, Some(p)) => p - v,
                (None, None) => 0.0,
            };
            let g = g * ratios[a];
            g2 += g * g;
        }
    }
    let d = if g2 > 0.0 { v.abs() / g2.sqrt() } else { f64::INFINITY };
    Some(d.min(theta))
}

/// Freezes every interface voxel of `src` with its initial distance (voxel units,
/// signed): the band voxels with a neighbour of the other sign, and those neighbours
/// even when they are band-edge voxels themselves. Non-finite input values are errors.
/// Returns the number of frozen voxels.
pub(crate) fn freeze_interface<S: Source + ?Sized, C: Cost>(
    src: &S,
    marcher: &mut Marcher<C>,
) -> Result<usize, FmmError> {
    let clamp = src.clamp();
    let ratios = src.ratios();
    let zeros = src.zero_is_interface();
    let mut extra: Vec<Coord> = Vec::new();
    let mut err = None;
    src.for_each_candidate(&mut |c, v, star| {
        if err.is_some() {
            return;
        }
        if v.is_nan() {
            err = Some(FmmError::NonFinite { coord: c, value: v });
            return;
        }
        let d = interface_distance(v, star, clamp, ratios);
        let d = if d.is_none() && zeros && v == 0.0 { Some(0.0) } else { d };
        if let Some(d) = d {
            for (i, n) in star.iter().enumerate() {
                if let Some(n) = n
                    && (*n < 0.0) != (v < 0.0)
                    && n.abs() >= clamp
                {
                    extra.push(c.wrapping_add(OFFSETS[i]));
                }
            }
            let inside = v < 0.0;
            if let Err(e) = marcher.freeze_initial(c, if inside { -d } else { d }, inside) {
                err = Some(e);
            }
        }
    });
    if let Some(e) = err {
        return Err(e);
    }
    extra.sort_unstable();
    extra.dedup();
    for c in extra {
        let v = src.value(c).expect("a neighbour that was read exists");
        if let Some(d) = interface_distance(v, &src.star(c), clamp, ratios) {
            let inside = v < 0.0;
            marcher.freeze_initial(c, if inside { -d } else { d }, inside)?;
        }
    }
    Ok(marcher.initial_len())
}
