//! A row directory over the sorted tile list, for random access.
//!
//! Van der Laan et al. 2011 find a tile by binary search over the whole list (Sec. 4.5). That is
//! O(log N) dependent loads per lookup, against the DT-Grid's short searches inside one
//! p-column. The directory narrows the search to one tile row `(tz, ty)` in O(1): a dense
//! table over the slabs `tz`, each with a dense table over its rows `ty` holding the list
//! position where the row starts. The search inside the row is then over a handful of
//! tiles. It is built in O(N) whenever the list is rebuilt, and it is only kept when its
//! tables stay small against the list (sparse layouts fall back to the plain search).

use crate::coord::Coord;

#[derive(Clone, Debug)]
struct Slab {
    /// First row `ty` of the slab.
    ty0: i32,
    /// Index in `starts` of row `ty0`.
    off: u32,
    /// Rows `ty0 .. ty0 + count`.
    count: u32,
    /// List position one past the slab's last tile.
    end: u32,
}

/// Row directory of a sorted list of tile coordinates (see the module docs).
///
/// # Invariants
/// Built from the list it serves: `row(t)` returns the exact list range of the tiles of
/// row `(t.z, t.y)`. Any change of the list must rebuild or drop it.
#[derive(Clone, Debug)]
pub(crate) struct RowDirectory {
    tz0: i32,
    slabs: Vec<Slab>,
    /// Per row of every slab: the list position of its first tile (or where it would be).
    starts: Vec<u32>,
}

impl RowDirectory {
    /// Builds the directory of `coords` (strictly increasing), or `None` when its tables
    /// would be large compared with the list (more than 4 slots per tile) or the list is
    /// empty or too long for u32 positions.
    pub(crate) fn build(coords: &[Coord]) -> Option<RowDirectory> {
        let n = coords.len();
        if n == 0 || n > u32::MAX as usize {
            return None;
        }
        let budget = 4 * n as u64 + 64;
        let (tz0, tz1) = (coords[0].z, coords[n - 1].z);
        if (tz1 as i64 - tz0 as i64 + 1) as u64 > budget {
            return None;
        }
        // First pass: the ty range of every slab, to check the budget before allocating.
        let mut slots = 0u64;
        let mut i = 0;
        while i < n {
            let z = coords[i].z;
            let ty0 = coords[i].y;
            let mut j = i;
            while j < n && coords[j].z == z {
                j += 1;
            }
            slots += (coords[j - 1].y as i64 - ty0 as i64 + 1) as u64;
            if slots > budget {
                return None;
            }
            i = j;
        }
        let nslabs = (tz1 as i64 - tz0 as i64 + 1) as usize;
        let mut slabs = Vec::with_capacity(nslabs);
        let mut starts = Vec::with_capacity(slots as usize);
        let mut i = 0;
        for tz in tz0..=tz1 {
            if i >= n || coords[i].z != tz {
                // An empty slab: no rows; lookups in it find nothing.
                slabs.push(Slab { ty0: 0, off: starts.len() as u32, count: 0, end: i as u32 });
                continue;
            }
            let ty0 = coords[i].y;
            let off = starts.len() as u32;
            let mut ty = ty0;
            while i < n && coords[i].z == tz {
                let y = coords[i].y;
                while ty <= y {
                    starts.push(i as u32);
                    ty += 1;
                }
                while i < n && coords[i].z == tz && coords[i].y == y {
                    i += 1;
                }
            }
            slabs.push(Slab { ty0, off, count: starts.len() as u32 - off, end: i as u32 });
        }
        Some(RowDirectory { tz0, slabs, starts })
    }

    /// The list range `start..end` of the tiles of row `(t.z, t.y)`, or `None` when the row
    /// lies outside the directory's tables (then the row holds no tile).
    #[inline]
    pub(crate) fn row(&self, t: Coord) -> Option<(usize, usize)> {
        let iz = (t.z as i64 - self.tz0 as i64) as u64;
        let slab = self.slabs.get(usize::try_from(iz).ok()?)?;
        let iy = (t.y as i64 - slab.ty0 as i64) as u64;
        if iy >= slab.count as u64 {
            return None;
        }
        let k = (slab.off as u64 + iy) as usize;
        let start = self.starts[k] as usize;
        let end = if iy + 1 < slab.count as u64 { self.starts[k + 1] } else { slab.end } as usize;
        Some((start, end))
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> (usize, usize) {
        let s = std::mem::size_of::<Slab>();
        (
            self.slabs.len() * s + self.starts.len() * 4,
            (self.slabs.capacity() - self.slabs.len()) * s
                + (self.starts.capacity() - self.starts.len()) * 4,
        )
    }
}
