//! What both sparse grids share: the grid's placement in space, band semantics, the
//! memory report and the error type of grid construction and maintenance.

use crate::coord::Coord;
use serde::Serialize;

/// Placement of a grid in world space and its narrow-band half-width.
///
/// # Band semantics (shared by the tiles, the DT-Grid and the dense reference)
/// φ < 0 inside, φ > 0 outside, in world units. Every stored value lies in `[-γ, γ]`
/// with `γ = half_width · voxel_size` ([`GridSpec::gamma`]). A voxel is a *band voxel*
/// when `|φ| < γ`. A voxel that a grid does not store reads as `-γ` inside and `+γ`
/// outside (Nielsen & Museth 2006, Sec. 3.3; van der Laan et al. 2011, Sec. 4.7,
/// "dummy tile").
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GridSpec {
    /// Edge length of a voxel in world units (> 0, finite).
    pub voxel_size: f32,
    /// World position of voxel (0, 0, 0).
    pub origin: [f64; 3],
    /// Half-width of the band in voxels (> 1, finite); the papers' default is 3.
    pub half_width: f32,
}

impl Default for GridSpec {
    fn default() -> Self {
        GridSpec { voxel_size: 1.0, origin: [0.0; 3], half_width: 3.0 }
    }
}

impl GridSpec {
    /// A checked spec: voxel size finite and > 0, half-width finite and > 1 voxel, origin
    /// finite, and every quantity the computation forms from them representable in `f32`.
    ///
    /// The half-width must exceed one voxel so that a voxel next to the interface (within
    /// one voxel of a zero crossing) is always in the band; then the band separates inside
    /// from outside and every grid can tell the sign of a voxel it does not store. At
    /// exactly one voxel a voxel with φ = 0 could neighbour an unstored voxel at −γ, and
    /// the DT-Grid's sign rule could not tell the interior from a thin shell.
    ///
    /// # Representable
    /// Band values are `f32` in world units and the kernels square them (|∇φ|², WENO5's
    /// smoothness indicators) and divide by h² (curvature), and meshes and images place
    /// voxels at `f32` world positions. So the spec is refused unless, in `f32`:
    /// * γ = half-width × h and γ² are finite (γ ≤ 1.8·10¹⁹ world units);
    /// * 1/h² is finite (h ≥ 2⁻⁶³ ≈ 1.1·10⁻¹⁹);
    /// * the world position of every voxel of the `i32` range, `origin ± 2³¹·h`, is finite.
    pub fn new(voxel_size: f32, origin: [f64; 3], half_width: f32) -> Result<Self, GridError> {
        let bad = |msg: String| Err(GridError::InvalidParameter(msg));
        if !(voxel_size.is_finite() && voxel_size > 0.0) {
            return bad(format!("voxel size must be finite and > 0, got {voxel_size}"));
        }
        if !(half_width.is_finite() && half_width > 1.0) {
            return bad(format!("half-width must be finite and > 1 voxel, got {half_width}"));
        }
        if origin.iter().any(|o| !o.is_finite()) {
            return bad(format!("origin must be finite, got {origin:?}"));
        }
        let h = voxel_size;
        if !(1.0 / (h * h)).is_finite() {
            return bad(format!(
                "voxel size {h} is too small: 1/h² overflows f32 (the smallest voxel size is \
                 2^-63 ≈ 1.1e-19)"
            ));
        }
        let g = half_width * h;
        if !(g * g).is_finite() {
            return bad(format!(
                "the band half-width γ = {half_width} voxels × {h:e} = {g:e} world units is too large: \
                 γ² overflows f32 (γ must be at most about 1.8e19)"
            ));
        }
        let far = (0..3).map(|a| origin[a].abs() + 2f64.powi(31) * h as f64).fold(0.0, f64::max);
        if !(far as f32).is_finite() {
            return bad(format!(
                "voxel size {h} and origin {origin:?} put voxels of the i32 range at world \
                 position {far:e}, beyond f32"
            ));
        }
        Ok(GridSpec { voxel_size, origin, half_width })
    }

    /// γ = half-width × voxel size, in world units.
    #[inline]
    pub fn gamma(&self) -> f32 {
        self.half_width * self.voxel_size
    }

    /// World position of the centre of voxel `c`.
    #[inline]
    pub fn world(&self, c: Coord) -> [f64; 3] {
        let h = self.voxel_size as f64;
        [
            self.origin[0] + c.x as f64 * h,
            self.origin[1] + c.y as f64 * h,
            self.origin[2] + c.z as f64 * h,
        ]
    }

    /// `+γ` when `inside` is false, `-γ` when true.
    #[inline]
    pub fn background(&self, inside: bool) -> f32 {
        if inside {
            -self.gamma()
        } else {
            self.gamma()
        }
    }
}

/// Bytes a grid uses, by part. `slack` is capacity allocated but not in use (vector
/// growth, arena tiles not in the list).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct MemoryReport {
    /// Numerical values (f32), including tile padding.
    pub values: usize,
    /// Coordinates and indices: the DT-Grid's nCoord/acc/proj arrays, the tile list.
    pub indices: usize,
    /// Per-tile border and activity flags.
    pub flags: usize,
    /// Allocated but unused capacity.
    pub slack: usize,
}

impl MemoryReport {
    pub fn total(&self) -> usize {
        self.used() + self.slack
    }

    /// Bytes in use: values, indices and flags, unused capacity excluded.
    pub fn used(&self) -> usize {
        self.values + self.indices + self.flags
    }
}

/// Bytes used and allocated-but-unused of a vector.
pub(crate) fn vec_bytes<T>(v: &Vec<T>) -> (usize, usize) {
    let s = std::mem::size_of::<T>();
    (v.len() * s, (v.capacity() - v.len()) * s)
}

/// Errors of grid construction and maintenance. Grids are left unchanged when one is
/// returned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// A coordinate (voxel, or tile for the tile list) would leave the representable
    /// range; grids never wrap around.
    #[error("coordinate {coord} is outside the representable range of the grid")]
    OutOfRange { coord: Coord },
    /// `push`/`append` must receive strictly increasing coordinates in the order of
    /// [`Coord`].
    #[error("coordinates must be pushed in strictly increasing lexicographic order: {coord} after {last}")]
    NotSorted { last: Coord, coord: Coord },
    /// A NaN value was given where a level-set value is required.
    #[error("value at {coord} is NaN")]
    NaN { coord: Coord },
    /// A parameter outside its documented domain.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// An allocation the machine cannot hold, refused before it was made
    /// ([`crate::memory::check`]).
    #[error(
        "{what} needs about {} but only about {} of memory may be used",
        gib(*needed),
        gib(*limit)
    )]
    OutOfMemory { what: String, needed: u64, limit: u64 },
}

impl crate::error::Error for GridError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            GridError::OutOfRange { .. }
            | GridError::NotSorted { .. }
            | GridError::InvalidParameter(_) => InvalidInput,
            GridError::NaN { .. } => InvalidData,
            GridError::OutOfMemory { .. } => OutOfMemory,
        }
    }
}

/// `bytes` as GiB with one decimal, for the messages of [`GridError::OutOfMemory`] and
/// its kin.
pub(crate) fn gib(bytes: u64) -> String {
    if bytes == u64::MAX {
        "more than the address space".to_string()
    } else {
        format!("{:.1} GiB", bytes as f64 / (1u64 << 30) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spec_refuses_what_f32_cannot_represent() {
        assert!(GridSpec::new(1.0, [0.0; 3], 3.0).is_ok());
        assert!(GridSpec::new(1e-6, [-1e6; 3], 3.0).is_ok());
        assert!(GridSpec::new(1e6, [0.0; 3], 64.0).is_ok());
        let cases: [(f32, [f64; 3], f32, &str); 7] = [
            (1e38, [0.0; 3], 3.0, "γ²"),
            (1e19, [0.0; 3], 3.0, "γ²"),
            (1e-30, [0.0; 3], 3.0, "too small"),
            (f32::MIN_POSITIVE, [0.0; 3], 3.0, "too small"),
            (1.0, [1e39, 0.0, 0.0], 3.0, "beyond f32"),
            (f32::INFINITY, [0.0; 3], 3.0, "finite"),
            (1.0, [0.0; 3], f32::INFINITY, "half-width"),
        ];
        for (h, o, w, needle) in cases {
            let e = GridSpec::new(h, o, w).unwrap_err().to_string();
            assert!(e.contains(needle), "h = {h}, origin {o:?}, w = {w}: {e}");
        }
    }
}
