//! Integer grid coordinates and the one lexicographic order every structure uses.

use std::cmp::Ordering;
use std::fmt;

/// A voxel (or, in [`crate::storage::tiles`], a tile) coordinate on the unbounded integer grid.
///
/// # The order
/// Coordinates compare **z first, then y, then x**, so x is the fastest-varying
/// component everywhere in this crate:
/// * along the Sorted Tile List (van der Laan et al. 2011, Sec. 4.1, "lexicographically sorted"),
/// * inside a tile (`index = x + 4 y + 16 z`, see [`crate::storage::tiles::Tile`]),
/// * along a DT-Grid p-column (`x_N` of Nielsen & Museth 2006 is our `x`, its `x_1` our `z`),
/// * in dense arrays and `.npy` files (C order with shape `(nz, ny, nx)`).
///
/// `Ord` is written by hand below (not derived) so that the field order of the struct
/// cannot silently change it.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Coord {
    pub x: i32,
    pub y: i32,
    pub z: i32,
}

impl Coord {
    pub const fn new(x: i32, y: i32, z: i32) -> Self {
        Coord { x, y, z }
    }

    /// The key whose natural tuple order is the crate's lexicographic order.
    #[inline(always)]
    pub const fn key(self) -> (i32, i32, i32) {
        (self.z, self.y, self.x)
    }

    /// Component-wise sum, `None` on i32 overflow.
    #[inline]
    pub fn checked_add(self, o: Coord) -> Option<Coord> {
        Some(Coord {
            x: self.x.checked_add(o.x)?,
            y: self.y.checked_add(o.y)?,
            z: self.z.checked_add(o.z)?,
        })
    }

    /// Component-wise sum that wraps; only for callers that have checked the range.
    #[inline(always)]
    pub fn wrapping_add(self, o: Coord) -> Coord {
        Coord {
            x: self.x.wrapping_add(o.x),
            y: self.y.wrapping_add(o.y),
            z: self.z.wrapping_add(o.z),
        }
    }

    /// Component-wise difference that wraps; only for callers that have checked the range.
    #[inline(always)]
    pub fn wrapping_sub(self, o: Coord) -> Coord {
        Coord {
            x: self.x.wrapping_sub(o.x),
            y: self.y.wrapping_sub(o.y),
            z: self.z.wrapping_sub(o.z),
        }
    }

    /// Chebyshev (max-norm) distance, computed in i64 so it never overflows.
    pub fn chebyshev(self, o: Coord) -> i64 {
        let d = |a: i32, b: i32| (a as i64 - b as i64).abs();
        d(self.x, o.x).max(d(self.y, o.y)).max(d(self.z, o.z))
    }
}

impl Ord for Coord {
    #[inline(always)]
    fn cmp(&self, other: &Self) -> Ordering {
        self.key().cmp(&other.key())
    }
}

impl PartialOrd for Coord {
    #[inline(always)]
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl fmt::Debug for Coord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({}, {}, {})", self.x, self.y, self.z)
    }
}

impl fmt::Display for Coord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

/// The six face neighbours' offsets, in the order −x, +x, −y, +y, −z, +z.
pub const FACE_OFFSETS: [Coord; 6] = [
    Coord::new(-1, 0, 0),
    Coord::new(1, 0, 0),
    Coord::new(0, -1, 0),
    Coord::new(0, 1, 0),
    Coord::new(0, 0, -1),
    Coord::new(0, 0, 1),
];

/// The 27 offsets of the 3×3×3 neighbourhood in lexicographic order; index
/// `d = 9 (dz+1) + 3 (dy+1) + (dx+1)`, so [`MID`] = 13 is the centre and the opposite
/// direction of `d` is `26 - d` (`reverse` of van der Laan et al. 2011, Sec. 4.6.3).
pub const NEIGHBOURHOOD: [Coord; 27] = {
    let mut out = [Coord::new(0, 0, 0); 27];
    let mut d = 0;
    while d < 27 {
        out[d] = Coord::new((d % 3) as i32 - 1, ((d / 3) % 3) as i32 - 1, (d / 9) as i32 - 1);
        d += 1;
    }
    out
};

/// Index of the centre in [`NEIGHBOURHOOD`].
pub const MID: usize = 13;

/// The opposite direction in [`NEIGHBOURHOOD`].
#[inline(always)]
pub const fn reverse(d: usize) -> usize {
    26 - d
}

/// Index in [`NEIGHBOURHOOD`] of an offset with components in -1..=1.
#[inline(always)]
pub const fn direction_index(dx: i32, dy: i32, dz: i32) -> usize {
    (9 * (dz + 1) + 3 * (dy + 1) + (dx + 1)) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_is_z_then_y_then_x() {
        let a = Coord::new(5, 0, 0);
        let b = Coord::new(0, 1, 0);
        let c = Coord::new(0, 0, 1);
        assert!(a < b && b < c);
        assert!(Coord::new(-1, 7, 7) < Coord::new(0, 7, 7));
        assert!(Coord::new(i32::MAX, i32::MAX, i32::MIN) < Coord::new(i32::MIN, i32::MIN, 0));
    }

    #[test]
    fn neighbourhood_is_sorted_and_reversible() {
        for d in 0..27 {
            let o = NEIGHBOURHOOD[d];
            assert_eq!(direction_index(o.x, o.y, o.z), d);
            let r = NEIGHBOURHOOD[reverse(d)];
            assert_eq!((r.x, r.y, r.z), (-o.x, -o.y, -o.z));
            if d > 0 {
                assert!(NEIGHBOURHOOD[d - 1] < o);
            }
        }
        assert_eq!(NEIGHBOURHOOD[MID], Coord::new(0, 0, 0));
    }

    #[test]
    fn checked_add_reports_overflow() {
        assert!(Coord::new(i32::MAX, 0, 0).checked_add(Coord::new(1, 0, 0)).is_none());
        assert_eq!(
            Coord::new(-3, 4, 5).checked_add(Coord::new(1, 1, 1)),
            Some(Coord::new(-2, 5, 6))
        );
    }
}
