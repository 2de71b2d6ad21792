//! Overlap of two segmentations: Dice, Jaccard and the relative volume difference.
//!
//! A mask is a slice of bytes, one per voxel in the layout of its image; any nonzero byte
//! is inside. Both masks must have the same length; the functions return
//! [`GridError::InvalidParameter`] when they do not, and never panic. Counting is exact
//! (integers), so the results do not depend on the thread count.
//!
//! ```
//! use sparse_levelset::segment::metrics::{dice, jaccard};
//!
//! let a = [1, 1, 1, 0, 0];
//! let b = [0, 1, 1, 1, 0];
//! assert_eq!(dice(&a, &b).unwrap(), 2.0 * 2.0 / 6.0);
//! assert_eq!(jaccard(&a, &b).unwrap(), 0.5);
//! assert!(dice(&a, &b[..4]).is_err());
//! ```

use crate::grid::GridError;
use rayon::prelude::*;

/// Voxel counts of two masks `a` and `b`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Overlap {
    /// |A|: voxels inside `a`.
    pub a: u64,
    /// |B|: voxels inside `b`.
    pub b: u64,
    /// |A ∩ B|: voxels inside both.
    pub both: u64,
}

impl Overlap {
    /// Dice's coefficient `2 |A ∩ B| / (|A| + |B|)` (Dice 1945), 1 when both are empty.
    pub fn dice(&self) -> f64 {
        match self.a + self.b {
            0 => 1.0,
            sum => 2.0 * self.both as f64 / sum as f64,
        }
    }

    /// The Jaccard index `|A ∩ B| / |A ∪ B|` (Jaccard 1912), 1 when both are empty.
    /// Equals `D / (2 − D)` with `D` the Dice coefficient.
    pub fn jaccard(&self) -> f64 {
        match self.a + self.b - self.both {
            0 => 1.0,
            union => self.both as f64 / union as f64,
        }
    }

    /// The relative volume difference `(|A| − |B|) / |B|` of a segmentation `a` against a
    /// reference `b`: signed, 0 for equal volumes (whatever the overlap), −1 for an empty
    /// segmentation. 0 when both are empty, `+∞` when only the reference is.
    pub fn volume_difference(&self) -> f64 {
        match (self.a, self.b) {
            (0, 0) => 0.0,
            (_, 0) => f64::INFINITY,
            (a, b) => (a as f64 - b as f64) / b as f64,
        }
    }
}

/// Voxels per parallel task.
const CHUNK: usize = 1 << 16;

/// Counts `a`, `b` and their intersection.
///
/// Fails with [`GridError::InvalidParameter`] when the lengths differ.
pub fn overlap(a: &[u8], b: &[u8]) -> Result<Overlap, GridError> {
    if a.len() != b.len() {
        return Err(GridError::InvalidParameter(format!(
            "overlap of masks of different sizes: {} and {} voxels",
            a.len(),
            b.len()
        )));
    }
    Ok(a.par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(a, b)| {
            let mut o = Overlap::default();
            for (&u, &v) in a.iter().zip(b) {
                let (u, v) = ((u != 0) as u64, (v != 0) as u64);
                o.a += u;
                o.b += v;
                o.both += u & v;
            }
            o
        })
        .reduce(Overlap::default, |x, y| Overlap {
            a: x.a + y.a,
            b: x.b + y.b,
            both: x.both + y.both,
        }))
}

/// Dice's coefficient of two masks ([`Overlap::dice`]).
///
/// Fails with [`GridError::InvalidParameter`] when the lengths differ.
pub fn dice(a: &[u8], b: &[u8]) -> Result<f64, GridError> {
    overlap(a, b).map(|o| o.dice())
}

/// The Jaccard index of two masks ([`Overlap::jaccard`]).
///
/// Fails with [`GridError::InvalidParameter`] when the lengths differ.
pub fn jaccard(a: &[u8], b: &[u8]) -> Result<f64, GridError> {
    overlap(a, b).map(|o| o.jaccard())
}

/// The relative volume difference of `segmentation` against `reference`
/// ([`Overlap::volume_difference`]).
///
/// Fails with [`GridError::InvalidParameter`] when the lengths differ.
pub fn volume_difference(segmentation: &[u8], reference: &[u8]) -> Result<f64, GridError> {
    overlap(segmentation, reference).map(|o| o.volume_difference())
}
