//! Sequential traversal of a sorted coordinate list with neighbour tracking
//! (van der Laan et al. 2011, Algorithm 1) and the streaming dilation of a sorted list
//! (Algorithm 2).

use crate::coord::{reverse, Coord, MID, NEIGHBOURHOOD};

/// The neighbours of one list entry: bit `d` of `matched` is set when the tile at offset
/// [`NEIGHBOURHOOD`]`[d]` exists, and then `ptr[d]` is its list position.
#[derive(Clone, Copy, Debug)]
pub struct Neighbours {
    /// List position of the current tile.
    pub pos: usize,
    /// Coordinate of the current tile.
    pub coord: Coord,
    /// Bit field of the neighbours that exist (bit [`MID`] is the tile itself).
    pub matched: u32,
    /// List positions of the neighbours; valid where `matched` has the bit.
    pub ptr: [usize; 27],
}

impl Neighbours {
    /// List position of the neighbour in direction `d`, if it exists.
    #[inline(always)]
    pub fn get(&self, d: usize) -> Option<usize> {
        if self.matched & (1 << d) != 0 {
            Some(self.ptr[d])
        } else {
            None
        }
    }
}

/// Walks entries `start..end` of a sorted coordinate list, tracking the list position of
/// all 26 neighbours of each entry (Algorithm 1). [`NeighbourCursor::new`] seeds the
/// pointers of a walk that starts mid-list by binary search (Sec. 5.8), so chunks of the
/// list can be walked independently.
///
/// Algorithm 1 keeps one forward-moving pointer per neighbour. The three neighbours of a
/// tile row `(dy, dz)` at `dx = -1, 0, +1` are consecutive in the sorted list when present,
/// so this cursor keeps one pointer per row (9 instead of 27) and matches the three
/// entries from there: the same output, a third of the pointer chasing. Every pointer
/// only moves forward, so a full walk costs O(9 N + 27 N).
pub struct NeighbourCursor<'a> {
    coords: &'a [Coord],
    /// Per row `r = 3 (dz+1) + (dy+1)`: the first list position not below
    /// `cur + (-1, dy, dz)`.
    row: [usize; 9],
    pos: usize,
    end: usize,
}

/// Offset of the first (dx = -1) neighbour of row `r`.
#[inline(always)]
fn row_offset(r: usize) -> Coord {
    NEIGHBOURHOOD[3 * r]
}

impl<'a> NeighbourCursor<'a> {
    /// A cursor over entries `start..end` of `coords`, which must be strictly increasing
    /// tile coordinates within [`super::TILE_MIN`]..=[`super::TILE_MAX`] (as every
    /// [`super::TileGrid`] list is), so that ±1 never wraps (checked in debug builds).
    ///
    /// # Panics
    /// If `start > end` or `end > coords.len()`.
    pub fn new(coords: &'a [Coord], start: usize, end: usize) -> Self {
        debug_assert!(
            coords.iter().all(|&c| super::tile_in_range(c)),
            "tile coordinates out of range"
        );
        Self::over(coords, start, end)
    }

    /// [`NeighbourCursor::new`] without the debug builds' check of every coordinate (for
    /// a caller that made them, or checked them once for many cursors).
    fn over(coords: &'a [Coord], start: usize, end: usize) -> Self {
        assert!(start <= end && end <= coords.len(), "cursor range {start}..{end} out of bounds");
        let mut row = [start; 9];
        if start < end {
            let cur = coords[start];
            for (r, p) in row.iter_mut().enumerate() {
                // Tile coordinates stay within ±2^29, so ±1 never overflows.
                *p = super::lower_bound(coords, cur.wrapping_add(row_offset(r)));
            }
        }
        NeighbourCursor { coords, row, pos: start, end }
    }

    /// The next entry and its neighbours, or `None` past `end`.
    #[inline]
    #[allow(clippy::should_implement_trait)] // returns a value that is not tied to a borrow; Iterator would need the same
    pub fn next(&mut self) -> Option<Neighbours> {
        if self.pos >= self.end {
            return None;
        }
        let coords = self.coords;
        let n = coords.len();
        let cur = coords[self.pos];
        let mut matched = 0u32;
        let mut ptr = [usize::MAX; 27];
        for (r, p) in self.row.iter_mut().enumerate() {
            let first = cur.wrapping_add(row_offset(r));
            let mut q = *p;
            while q < n && coords[q] < first {
                q += 1;
            }
            *p = q;
            // The row's neighbours at dx = -1, 0, +1 follow each other in the list.
            let mut c = first;
            for k in 0..3 {
                if q < n && coords[q] == c {
                    matched |= 1 << (3 * r + k);
                    ptr[3 * r + k] = q;
                    q += 1;
                }
                c.x += 1;
            }
        }
        let out = Neighbours { pos: self.pos, coord: cur, matched, ptr };
        debug_assert!(out.matched & (1 << MID) != 0 && out.ptr[MID] == self.pos);
        self.pos += 1;
        Some(out)
    }
}

impl Iterator for NeighbourCursor<'_> {
    type Item = Neighbours;
    fn next(&mut self) -> Option<Neighbours> {
        NeighbourCursor::next(self)
    }
}

/// The neighbours of one tile in compact form (40 bytes): a row of a [`NeighbourTable`].
///
/// The three neighbours of a tile at `dx = -1, 0, +1` in one neighbour line `(dy, dz)`
/// follow each other in the list where present, so a row keeps, per line, the list
/// position of the first one present, and the others are the next positions: 9 positions
/// and the bit field instead of 27 positions (112 bytes), which is less to read in every
/// sweep, to write in every rebuild and to hold next to the tiles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NeighbourRow {
    /// Bit field of the neighbours that exist, as [`Neighbours::matched`].
    pub matched: u32,
    /// Per neighbour line `r = (dy + 1) + 3 (dz + 1)`: the list position of the first of
    /// its neighbours present (directions `3r`, `3r + 1`, `3r + 2` in that order), 0 when
    /// none is.
    first: [u32; 9],
}

impl NeighbourRow {
    /// A row without neighbours.
    pub const EMPTY: NeighbourRow = NeighbourRow { matched: 0, first: [0; 9] };

    /// The row of neighbours at list positions `ptr[d]` where `matched` has bit `d`; the
    /// present neighbours of each line must follow each other in the list (as they do in
    /// a sorted tile list; checked in debug builds).
    ///
    /// # Panics
    /// If a present neighbour's position does not fit in `u32` (a tile list has fewer
    /// than 2³² entries).
    pub fn new(matched: u32, ptr: &[usize; 27]) -> NeighbourRow {
        let mut row = NeighbourRow::EMPTY;
        for (d, &p) in ptr.iter().enumerate().filter(|&(d, _)| matched & (1 << d) != 0) {
            row.insert(d, u32::try_from(p).expect("list positions fit in u32"));
            debug_assert_eq!(row.position(d), p, "line {} not consecutive", d / 3);
        }
        row
    }

    /// The row as the [`Neighbours`] of list entry `pos` at `coord` (positions of absent
    /// neighbours are 0).
    #[inline]
    pub fn neighbours(&self, pos: usize, coord: Coord) -> Neighbours {
        let ptr = std::array::from_fn(|d| self.get(d).unwrap_or(0));
        Neighbours { pos, coord, matched: self.matched, ptr }
    }

    /// List position of the neighbour in direction `d`, if it exists.
    #[inline(always)]
    pub fn get(&self, d: usize) -> Option<usize> {
        if self.matched & (1 << d) != 0 {
            Some(self.position(d))
        } else {
            None
        }
    }

    /// The row after its neighbour `d` (absent before) was entered at list position `q`:
    /// the first of its line if none before it in the line is present.
    #[inline]
    fn insert(&mut self, d: usize, q: u32) {
        if self.before(d) == 0 {
            self.first[d / 3] = q;
        }
        self.matched |= 1 << d;
    }

    /// The present neighbours of `d`'s line before it, as bits.
    #[inline(always)]
    fn before(&self, d: usize) -> u32 {
        let (r, k) = (d / 3, d % 3);
        (self.matched >> (3 * r)) & ((1 << k) - 1)
    }

    /// The row with every present neighbour at `to[p]` instead of `p`, and without those
    /// whose `to` is [`NONE`] (removed). Line by line: a line's present neighbours are
    /// consecutive positions from its first, and so are those it keeps in the new list
    /// (nothing can come between neighbours at `dx = -1, 0, +1`), so the new first is the
    /// first kept one's new position.
    #[inline]
    fn moved(&self, to: &[u32]) -> NeighbourRow {
        let mut out = NeighbourRow::EMPTY;
        for r in 0..9 {
            let bits = (self.matched >> (3 * r)) & 7;
            if bits == 0 {
                continue;
            }
            let mut p = self.first[r] as usize;
            let mut kept = 0u32;
            for k in 0..3 {
                if (bits >> k) & 1 != 0 {
                    let q = to[p];
                    p += 1;
                    if q != NONE {
                        if kept == 0 {
                            out.first[r] = q;
                        }
                        kept |= 1 << k;
                    }
                }
            }
            out.matched |= kept << (3 * r);
        }
        out
    }

    /// The list position of the first present neighbour of line `r` (0 when none is).
    #[inline(always)]
    pub(crate) fn first(&self, r: usize) -> usize {
        self.first[r] as usize
    }

    /// The least and the greatest list position among the present neighbours of the tile
    /// at `pos` and `pos` itself: the tiles whose gathers read it. The lines follow each
    /// other in list order (z, then y), so the least is the first of the first line with a
    /// neighbour, the greatest the last of the last one.
    #[inline]
    pub fn extent(&self, pos: usize) -> (usize, usize) {
        let (mut lo, mut hi) = (pos, pos);
        for r in 0..9 {
            let bits = (self.matched >> (3 * r)) & 7;
            if bits != 0 {
                let first = self.first[r] as usize;
                lo = lo.min(first);
                hi = hi.max(first + bits.count_ones() as usize - 1);
            }
        }
        (lo, hi)
    }

    /// List position the neighbour in direction `d` has if it exists: the first present
    /// neighbour of its line plus those present before it in that line.
    #[inline(always)]
    pub(crate) fn position(&self, d: usize) -> usize {
        self.first[d / 3] as usize + self.before(d).count_ones() as usize
    }
}

/// The 26-neighbour positions of every tile of a sorted list, computed once by
/// [`NeighbourCursor`] walks over chunks of the list (each seeded by binary search,
/// Sec. 5.8) and then read by every sweep over the same list: a Runge–Kutta step with
/// volume conservation walks the list six times, and reading 40 bytes per tile is
/// cheaper than advancing the nine row pointers again.
///
/// # Invariants
/// Row `p` holds the neighbours of entry `p` of the list the table was built from; a
/// table is only valid as long as that list is unchanged (its owner rebuilds it after
/// tile management).
#[derive(Clone, Debug, Default)]
pub struct NeighbourTable {
    rows: Vec<NeighbourRow>,
}

impl NeighbourTable {
    /// Tiles per parallel walk.
    const CHUNK: usize = 256;

    /// Rebuilds the table for `coords` (a valid tile list, see [`NeighbourCursor::new`])
    /// in the current rayon pool; the result does not depend on the number of threads.
    ///
    /// # Panics
    /// If the list has `u32::MAX` entries or more.
    pub fn rebuild(&mut self, coords: &[Coord]) {
        use rayon::prelude::*;
        assert!(coords.len() < u32::MAX as usize, "tile list too long for a neighbour table");
        let empty = NeighbourRow::EMPTY;
        // The rows needed and a band's headroom (`grown_capacity`), not a doubling.
        if coords.len() > self.rows.capacity() {
            let want = crate::memory::grown_capacity(coords.len());
            self.rows.reserve_exact(want.saturating_sub(self.rows.len()));
        }
        // `fill_rows` writes every row: the old rows need no clearing, only new ones a
        // value (clearing all of them was a pass over the table on one thread).
        self.rows.resize(coords.len(), empty);
        self.rows.par_chunks_mut(Self::CHUNK).enumerate().for_each(|(c, rows)| {
            fill_rows(coords, c * Self::CHUNK, rows);
        });
    }

    /// Makes the table, built for a list that tile management has since changed into
    /// `coords`, that of `coords`: the same rows as [`NeighbourTable::rebuild`] gives.
    /// `moves` says where each tile of the old list went. A kept tile's row is its old row
    /// renumbered (removed neighbours dropped); a created tile's row is searched in
    /// `coords` (Sec. 5.8's binary searches), and each created tile is then entered into
    /// the rows of its kept neighbours. A step changes a few tiles of a band, so this
    /// reads each row once instead of walking the list's lines again.
    ///
    /// # Panics
    /// If `moves` does not fit the table and `coords` (checked in debug builds).
    pub(crate) fn follow(&mut self, coords: &[Coord], moves: &ListMoves) {
        use rayon::prelude::*;
        let ListMoves { to, from } = moves;
        debug_assert!(to.len() == self.rows.len() && from.len() == coords.len());
        // The rows move within the table (as the values within the arena), then are
        // renumbered: no second table next to the first.
        let rows = &mut self.rows;
        let len = coords.len().max(rows.len());
        crate::memory::resize_exact(rows, len, NeighbourRow::EMPTY);
        move_kept(rows, from);
        rows.truncate(coords.len());
        rows.par_iter_mut().zip(from).enumerate().with_min_len(Self::CHUNK).for_each(
            |(q, (row, &p))| {
                *row = if p != NONE {
                    row.moved(to)
                } else {
                    let nb = NeighbourCursor::over(coords, q, q + 1)
                        .next()
                        .expect("a cursor over one entry yields it");
                    NeighbourRow::new(nb.matched, &nb.ptr)
                };
            },
        );
        // The created tiles in their kept neighbours' rows (those of created neighbours
        // found them already); one tile per neighbour and direction, so the order of the
        // writes does not matter. The created tiles are found on the pool: a step creates
        // a few, and a scan of the whole list on one thread would grow with the band.
        let created: Vec<usize> = from
            .par_iter()
            .enumerate()
            .with_min_len(Self::CHUNK)
            .filter_map(|(q, &p)| (p == NONE).then_some(q))
            .collect();
        for q in created {
            let row = rows[q];
            let mut m = row.matched & !(1 << MID);
            while m != 0 {
                let d = m.trailing_zeros() as usize;
                m &= m - 1;
                let e = row.position(d);
                if from[e] != NONE {
                    rows[e].insert(reverse(d), q as u32);
                }
            }
        }
    }

    /// Rows the table holds without growing.
    pub(crate) fn capacity(&self) -> usize {
        self.rows.capacity()
    }

    /// The neighbours of list entry `pos`.
    #[inline(always)]
    pub fn row(&self, pos: usize) -> &NeighbourRow {
        &self.rows[pos]
    }

    /// Number of rows (the length of the list it was built from).
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether the table has no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// Bytes held, used or not.
    pub fn bytes(&self) -> usize {
        self.rows.capacity() * std::mem::size_of::<NeighbourRow>()
    }

    /// Bytes a rebuild for a list of `len` tiles has to allocate.
    pub fn growth_bytes(&self, len: usize) -> usize {
        if len <= self.rows.capacity() {
            return 0;
        }
        (crate::memory::grown_capacity(len) - self.rows.capacity())
            * std::mem::size_of::<NeighbourRow>()
    }
}

/// A list position that does not exist ([`ListMoves`]).
pub(crate) const NONE: u32 = u32::MAX;

/// Where the tiles of a list went when tile management changed it.
pub(crate) struct ListMoves {
    /// Per entry of the old list: its position in the new list, [`NONE`] if removed.
    pub to: Vec<u32>,
    /// Per entry of the new list: its position in the old list, [`NONE`] if created.
    pub from: Vec<u32>,
}

/// Moves every kept entry of `values` (an array of the old list, at least as long as the
/// new list) to its position in the new list, `o` from `from[o]` ([`ListMoves::from`]),
/// in place. A tile's target can only be the source of another tile that moves the same way
/// (towards the front or the back) further along that direction, so the tiles that move
/// towards the front go first in ascending order, then those that move towards the back
/// in descending order; each run of consecutive tiles with one shift is one `memmove`.
/// The created tiles' places keep stale entries (the caller fills them).
pub(crate) fn move_kept<T: Copy>(values: &mut [T], from: &[u32]) {
    let n = from.len();
    let src = |o: usize| (from[o] != NONE).then_some(from[o] as usize);
    // Towards the front, in ascending order.
    let mut o = 0;
    while o < n {
        match src(o) {
            Some(p) if p > o => {
                let mut k = 1;
                while o + k < n && src(o + k) == Some(p + k) {
                    k += 1;
                }
                values.copy_within(p..p + k, o);
                o += k;
            }
            _ => o += 1,
        }
    }
    // Towards the back, in descending order (`end`: one past the next tile to look at).
    let mut end = n;
    while end > 0 {
        let o = end - 1;
        match src(o) {
            Some(p) if p < o => {
                let mut k = 1;
                while k <= p && src(o - k) == Some(p - k) {
                    k += 1;
                }
                values.copy_within(p + 1 - k..p + 1, o + 1 - k);
                end -= k;
            }
            _ => end -= 1,
        }
    }
}

/// The line of a tile coordinate, `(z, y)`, as one key ordered as the list orders lines.
#[inline(always)]
fn line_key(c: Coord) -> i64 {
    ((c.z as i64) << 32) | (c.y as i64 - i32::MIN as i64)
}

/// Fills `rows` with the neighbours of list entries `start..start + rows.len()`: the rows
/// [`NeighbourCursor`] gives, found line by line. The
/// tiles of one x-line `(y, z)` follow each other in the list, and so do those of each of
/// its nine neighbour lines `(y + dy, z + dz)`; the cursor compares whole coordinates
/// for every tile and every row pointer, this finds each neighbour line once per line
/// (forward-moving pointers, seeded by binary search) and then matches the tiles along
/// x with integer compares. Measured with `cargo bench --bench grids -- engine`
/// (one thread, 2-core AMD EPYC, 2026-11-24): a sphere's band of 7,374 tiles 751 → 674 µs,
/// a spiral's of 4,851 tiles 374 → 269 µs.
fn fill_rows(coords: &[Coord], start: usize, rows: &mut [NeighbourRow]) {
    let n = coords.len();
    let end = start + rows.len();
    if start >= end {
        return;
    }
    // Per neighbour line `r = (dy + 1) + 3 (dz + 1)`: the first list position whose line
    // is not below it.
    let mut line = [0usize; 9];
    let first = coords[start];
    for (r, p) in line.iter_mut().enumerate() {
        let (dy, dz) = ((r % 3) as i32 - 1, (r / 3) as i32 - 1);
        // Tile coordinates stay within ±2^29, so ±1 never overflows.
        *p = super::lower_bound(coords, Coord::new(i32::MIN, first.y + dy, first.z + dz));
    }
    let mut pos = start;
    while pos < end {
        let cur = coords[pos];
        let key = line_key(cur);
        let mut line_end = pos + 1;
        while line_end < end && line_key(coords[line_end]) == key {
            line_end += 1;
        }
        // The neighbour lines' extents `lo[r]..hi[r]`.
        let mut lo = [0usize; 9];
        let mut hi = [0usize; 9];
        for r in 0..9 {
            let (dy, dz) = ((r % 3) as i32 - 1, (r / 3) as i32 - 1);
            let target = line_key(Coord::new(0, cur.y + dy, cur.z + dz));
            let mut p = line[r];
            while p < n && line_key(coords[p]) < target {
                p += 1;
            }
            line[r] = p;
            let mut q = p;
            while q < n && line_key(coords[q]) == target {
                q += 1;
            }
            (lo[r], hi[r]) = (p, q);
        }
        // Along x: per neighbour line, the first entry not left of x - 1.
        let mut at = lo;
        for i in pos..line_end {
            let x = coords[i].x;
            let mut row = NeighbourRow::EMPTY;
            for r in 0..9 {
                let mut q = at[r];
                while q < hi[r] && coords[q].x < x - 1 {
                    q += 1;
                }
                at[r] = q;
                // Tiles x - 1, x, x + 1 of the line follow each other where present.
                for k in 0..3 {
                    if q < hi[r] && coords[q].x == x - 1 + k as i32 {
                        row.insert(3 * r + k, q as u32);
                        q += 1;
                    }
                }
            }
            rows[i - start] = row;
        }
        pos = line_end;
    }
}

/// Streams the morphological dilation of a sorted coordinate list by the 3×3×3
/// structuring element, in sorted order (Algorithm 2, Fig. 3). Every coordinate of the
/// dilated set is produced exactly once, with the bit field of the original entries
/// around it and their list positions. O(27 N) for N entries.
pub struct DilationStream<'a> {
    coords: &'a [Coord],
    ptr: [usize; 27],
}

impl<'a> DilationStream<'a> {
    /// A stream over the dilation of `coords`: strictly increasing tile coordinates within
    /// [`super::TILE_MIN`]..=[`super::TILE_MAX`] (checked in debug builds), so that the
    /// element's ±1 offsets never wrap.
    pub fn new(coords: &'a [Coord]) -> Self {
        debug_assert!(
            coords.iter().all(|&c| super::tile_in_range(c)),
            "tile coordinates out of range"
        );
        DilationStream { coords, ptr: [0; 27] }
    }

    /// The next coordinate of the dilated set. `matched` bit `d` says that the original
    /// list holds `coord + NEIGHBOURHOOD[d]`, at position `ptr[d]`; bit [`MID`] says
    /// that `coord` itself was in the list.
    #[inline]
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Option<Neighbours> {
        let coords = self.coords;
        let n = coords.len();
        // Line 5-11: the first coordinate, in order, that the element touches. Coordinates
        // of a valid list are within ±2^29, so subtracting an offset cannot overflow.
        let mut cur: Option<Coord> = None;
        for (&p, off) in self.ptr.iter().zip(&NEIGHBOURHOOD) {
            if p < n {
                let c = coords[p].wrapping_sub(*off);
                cur = Some(match cur {
                    Some(m) if m <= c => m,
                    _ => c,
                });
            }
        }
        let cur = cur?;
        // Line 15-20: which neighbours exist.
        let mut matched = 0u32;
        for (d, (&p, off)) in self.ptr.iter().zip(&NEIGHBOURHOOD).enumerate() {
            if p < n && coords[p] == cur.wrapping_add(*off) {
                matched |= 1 << d;
            }
        }
        // `pos` is the position of `cur` itself when it was in the list.
        let pos = if matched & (1 << MID) != 0 { self.ptr[MID] } else { usize::MAX };
        let out = Neighbours { pos, coord: cur, matched, ptr: self.ptr };
        // Line 22-26: advance the element past the matched entries.
        for d in 0..27 {
            self.ptr[d] += ((matched >> d) & 1) as usize;
        }
        Some(out)
    }
}

impl Iterator for DilationStream<'_> {
    type Item = Neighbours;
    fn next(&mut self) -> Option<Neighbours> {
        DilationStream::next(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::tiles::Tile;

    /// Moving in place gives what a copy into a new arena gives, for lists that lose and
    /// gain tiles anywhere (both directions of movement, runs of every length).
    #[test]
    fn moving_in_place_equals_copying() {
        let mut rng = fastrand::Rng::with_seed(11);
        for _ in 0..300 {
            let n = rng.usize(0..60);
            let old: Vec<Tile> = (0..n).map(|i| Tile::splat(i as f32)).collect();
            // The new list: each old tile kept or not, with created tiles between them.
            let mut from = Vec::new();
            for p in 0..n {
                from.extend(std::iter::repeat_n(NONE, rng.usize(0..3) * usize::from(rng.bool())));
                if rng.u8(0..4) != 0 {
                    from.push(p as u32);
                }
            }
            let want: Vec<Option<Tile>> =
                from.iter().map(|&p| (p != NONE).then(|| old[p as usize])).collect();
            let mut values = old.clone();
            values.resize(n.max(from.len()), Tile::splat(f32::NAN));
            move_kept(&mut values, &from);
            for (o, w) in want.iter().enumerate() {
                if let Some(w) = w {
                    assert_eq!(&values[o], w, "tile {o} of {from:?}");
                }
            }
        }
    }
}
