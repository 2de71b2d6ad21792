//! The [`TileGrid`] type: list, arena, flags, random access and tile management.

use super::directory::RowDirectory;
use super::flags::{compute_activity, ACTIVE_MASK, BORDER_MASK, INSIDE, NEIGHBOUR_TRIGGER};
use super::stream::{DilationStream, NeighbourCursor};
use super::{tile_in_range, tile_of, voxel_of, Tile, TILE_LEN};
use crate::coord::{direction_index, reverse, Coord, MID, NEIGHBOURHOOD};
use crate::grid::{vec_bytes, GridError, GridSpec, MemoryReport};

/// A narrow band stored as 4³ tiles behind a sorted tile list (van der Laan et al.
/// 2011, Sec. 4.1).
///
/// # Invariants
/// * `coords` is strictly increasing in [`Coord`] order (sorted, no duplicates) and every
///   coordinate is within [`super::TILE_MIN`]..=[`super::TILE_MAX`];
/// * the arena is in list order: `arena.len() == coords.len()` and list entry `pos` owns
///   arena tile `pos` (nothing orphaned, no indirection), which [`TileGrid::values`] and
///   [`TileGrid::swap_values`] rely on. Construction appends in list order and tile
///   management compacts the arena in list order, so a tile's list position is its
///   identity (the index to the tile data the paper's list holds, Sec. 4.1 and
///   Algorithm 3's `index[]`, would be the identity map and is not stored);
/// * `border`, `activity` have one entry per list entry, in list order; border flags use
///   only [`BORDER_MASK`] bits and activity flags only [`ACTIVE_MASK`] | [`INSIDE`], never
///   [`INSIDE`] together with a region bit;
/// * every value is finite and within `[-γ, γ]`.
///
/// [`TileGrid::check_invariants`] checks all of the above and runs after every mutation in
/// debug builds.
#[derive(Clone, Debug)]
pub struct TileGrid {
    spec: GridSpec,
    pub(super) coords: Vec<Coord>,
    pub(super) arena: Vec<Tile>,
    pub(super) border: Vec<u32>,
    pub(super) activity: Vec<u32>,
    /// Row directory for random access; rebuilt with the list, dropped by `append`.
    dir: Option<RowDirectory>,
}

/// What one tile-management step did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ManageStats {
    pub kept: usize,
    pub removed: usize,
    pub created: usize,
}

const PLUS_X: usize = direction_index(1, 0, 0);

/// Refuses a list of `n` tiles when it has 2³² or more (the neighbour table addresses
/// tiles with u32).
pub(super) fn check_list_len(n: usize) -> Result<(), GridError> {
    if u32::try_from(n).is_err() {
        return Err(GridError::InvalidParameter("more than 2^32 tiles".into()));
    }
    Ok(())
}
const MINUS_X: usize = direction_index(-1, 0, 0);

/// Activity flags as the grid keeps them: bits within [`ACTIVE_MASK`] | [`INSIDE`], and
/// [`INSIDE`] only without a region bit.
fn normalise_activity(activity: &mut [u32]) {
    for a in activity.iter_mut() {
        let f = *a & (ACTIVE_MASK | INSIDE);
        *a = if f & ACTIVE_MASK != 0 { f & ACTIVE_MASK } else { f };
    }
}

impl TileGrid {
    /// An empty grid.
    pub fn new(spec: GridSpec) -> TileGrid {
        TileGrid {
            spec,
            coords: Vec::new(),
            arena: Vec::new(),
            border: Vec::new(),
            activity: Vec::new(),
            dir: None,
        }
    }

    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// γ in world units.
    pub fn gamma(&self) -> f32 {
        self.spec.gamma()
    }

    /// Number of tiles in the list.
    pub fn len(&self) -> usize {
        self.coords.len()
    }

    pub fn is_empty(&self) -> bool {
        self.coords.is_empty()
    }

    /// The sorted tile coordinates.
    pub fn tile_coords(&self) -> &[Coord] {
        &self.coords
    }

    /// Values of the tile at list position `pos`.
    #[inline]
    pub fn tile(&self, pos: usize) -> &Tile {
        &self.arena[pos]
    }

    /// Mutable values of the tile at list position `pos`. Values must stay finite and
    /// within `[-γ, γ]`; call [`TileGrid::refresh_activity`] after changing them.
    #[inline]
    pub fn tile_mut(&mut self, pos: usize) -> &mut Tile {
        &mut self.arena[pos]
    }

    /// The values of every tile in list order: entry `pos` belongs to list position `pos`
    /// (every operation keeps the arena in list order).
    #[inline]
    pub fn values(&self) -> &[Tile] {
        &self.arena
    }

    /// Replaces the values and activity flags of every tile at once (the double-buffered
    /// time step of Sec. 4.7): `values` (one tile per list position, in list order) is
    /// swapped with the arena and `activity` (the new flags, as computed while the step
    /// wrote the tiles; bits outside [`ACTIVE_MASK`] | [`INSIDE`] are dropped) with the
    /// activity flags, so afterwards both hold the previous state, and swapping them back
    /// restores it exactly. Values are clamped to `[-γ, γ]` and finite by the caller (the
    /// time-step kernels clamp; checked in debug builds); a length mismatch is an error
    /// and leaves the grid as it was.
    pub fn swap_values(
        &mut self,
        values: &mut Vec<Tile>,
        activity: &mut Vec<u32>,
    ) -> Result<(), GridError> {
        let n = self.coords.len();
        if values.len() != n || activity.len() != n {
            return Err(GridError::InvalidParameter(format!(
                "{} tiles and {} activity flags for a list of {n}",
                values.len(),
                activity.len()
            )));
        }
        normalise_activity(activity);
        std::mem::swap(&mut self.arena, values);
        std::mem::swap(&mut self.activity, activity);
        self.debug_check();
        Ok(())
    }

    /// The tiles as a sweep reads them while it writes its results back into the arena
    /// ([`super::InPlaceTiles`]); the sweep's activity flags follow with
    /// [`TileGrid::swap_activity`].
    pub(crate) fn in_place(&mut self) -> super::InPlaceTiles<'_> {
        let gamma = self.gamma();
        super::InPlaceTiles::new(&mut self.arena, &self.border, &self.activity, gamma)
    }

    /// [`TileGrid::swap_values`] for the activity flags alone, after a sweep wrote its
    /// values into the arena ([`TileGrid::in_place`]): `activity` then holds the previous
    /// flags. A length mismatch is an error and leaves the grid as it was.
    pub(crate) fn swap_activity(&mut self, activity: &mut Vec<u32>) -> Result<(), GridError> {
        let n = self.coords.len();
        if activity.len() != n {
            return Err(GridError::InvalidParameter(format!(
                "{} activity flags for a list of {n}",
                activity.len()
            )));
        }
        normalise_activity(activity);
        std::mem::swap(&mut self.activity, activity);
        self.debug_check();
        Ok(())
    }

    /// Border flags of the tile at list position `pos` (see [`super::flags`]).
    #[inline]
    pub fn border_flags(&self, pos: usize) -> u32 {
        self.border[pos]
    }

    /// The activity flags of every tile, in list order.
    pub(crate) fn activity(&self) -> &[u32] {
        &self.activity
    }

    /// Takes the values out of the grid, which then holds none until
    /// [`TileGrid::swap_values`] gives it a value array for its list (an undo that
    /// rebuilds φⁿ in the memory of the values it replaces).
    pub(crate) fn take_values(&mut self) -> Vec<Tile> {
        std::mem::take(&mut self.arena)
    }

    /// Activity flags of the tile at list position `pos` (see [`super::flags`]).
    #[inline]
    pub fn activity_flags(&self, pos: usize) -> u32 {
        self.activity[pos]
    }

    /// Sets the activity flags of the tile at `pos` (as the time step does while it
    /// computes, Sec. 4.7). Bits outside [`ACTIVE_MASK`] | [`INSIDE`] are dropped.
    #[inline]
    pub fn set_activity_flags(&mut self, pos: usize, flags: u32) {
        let f = flags & (ACTIVE_MASK | INSIDE);
        let f = if f & ACTIVE_MASK != 0 { f & ACTIVE_MASK } else { f };
        self.activity[pos] = f;
    }

    /// Recomputes every tile's activity flags from its values.
    pub fn refresh_activity(&mut self) {
        let g = self.gamma();
        for (a, t) in self.activity.iter_mut().zip(&self.arena) {
            *a = compute_activity(t, g);
        }
    }

    /// Appends a tile after the last one (Sec. 4.3), O(1). `tile_coord` must be greater
    /// than the last coordinate in [`Coord`] order and within the tile range; values are
    /// clamped to `[-γ, γ]` (NaN is an error); `border` holds the border flags (bits
    /// outside [`BORDER_MASK`] are ignored). Activity flags are computed from the values.
    /// Returns the list position.
    pub fn append(
        &mut self,
        tile_coord: Coord,
        values: &Tile,
        border: u32,
    ) -> Result<usize, GridError> {
        if let Some(&last) = self.coords.last()
            && tile_coord <= last
        {
            return Err(GridError::NotSorted { last, coord: tile_coord });
        }
        if !tile_in_range(tile_coord) {
            return Err(GridError::OutOfRange { coord: tile_coord });
        }
        check_list_len(self.coords.len() + 1)?;
        let g = self.gamma();
        let mut t = *values;
        for (i, v) in t.0.iter_mut().enumerate() {
            if v.is_nan() {
                return Err(GridError::NaN { coord: voxel_of(tile_coord, i) });
            }
            *v = v.clamp(-g, g);
        }
        self.activity.push(compute_activity(&t, g));
        self.arena.push(t);
        self.border.push(border & BORDER_MASK);
        self.coords.push(tile_coord);
        // The directory no longer covers the list; lookups fall back to the plain search
        // until the next rebuild (`from_sorted_tiles`, `manage_tiles`, `build_directory`).
        self.dir = None;
        Ok(self.coords.len() - 1)
    }

    /// Builds a grid from tiles sorted by coordinate, computing the border flags with
    /// Algorithm 1: for every absent neighbour, `inside(tile coordinate)` tells whether
    /// that (uniformly signed) tile is inside. `inside` is called only with in-range
    /// coordinates; tiles beyond the range count as outside.
    pub fn from_sorted_tiles<F: Fn(Coord) -> bool>(
        spec: GridSpec,
        tiles: impl IntoIterator<Item = (Coord, Tile)>,
        inside: F,
    ) -> Result<TileGrid, GridError> {
        let mut g = TileGrid::new(spec);
        let it = tiles.into_iter();
        let (lo, _) = it.size_hint();
        g.reserve(lo);
        for (c, t) in it {
            g.append(c, &t, 0)?;
        }
        let mut cur = NeighbourCursor::new(&g.coords, 0, g.coords.len());
        while let Some(nb) = cur.next() {
            let mut flags = 0u32;
            let mut absent = !nb.matched & BORDER_MASK;
            while absent != 0 {
                let d = absent.trailing_zeros() as usize;
                absent &= absent - 1;
                let t = nb.coord.wrapping_add(NEIGHBOURHOOD[d]);
                if tile_in_range(t) && inside(t) {
                    flags |= 1 << d;
                }
            }
            g.border[nb.pos] = flags;
        }
        g.build_directory();
        g.debug_check();
        Ok(g)
    }

    /// A grid from its four lists in list order (coordinates sorted, one tile, border
    /// and activity flag word per coordinate), as another grid held them: the
    /// coordinates must be strictly increasing and in range, the lengths equal, values
    /// finite and within [-γ, γ]; flags are taken as they are (bits outside their masks
    /// dropped).
    pub(crate) fn from_parts(
        spec: GridSpec,
        coords: Vec<Coord>,
        arena: Vec<Tile>,
        border: Vec<u32>,
        activity: Vec<u32>,
    ) -> Result<TileGrid, GridError> {
        let n = coords.len();
        if arena.len() != n || border.len() != n || activity.len() != n {
            return Err(GridError::InvalidParameter(format!(
                "{n} tile coordinates with {} tiles, {} border and {} activity flags",
                arena.len(),
                border.len(),
                activity.len()
            )));
        }
        check_list_len(n)?;
        for w in coords.windows(2) {
            if w[1] <= w[0] {
                return Err(GridError::NotSorted { last: w[0], coord: w[1] });
            }
        }
        if let Some(&c) = coords.iter().find(|&&c| !tile_in_range(c)) {
            return Err(GridError::OutOfRange { coord: c });
        }
        let g = spec.gamma();
        for (t, &c) in arena.iter().zip(&coords) {
            if let Some(i) = t.0.iter().position(|v| v.is_nan() || v.abs() > g) {
                let coord = voxel_of(c, i);
                return Err(match t.0[i] {
                    v if v.is_nan() => GridError::NaN { coord },
                    v => GridError::InvalidParameter(format!(
                        "value {v} at voxel {coord} is beyond the band's ±{g}"
                    )),
                });
            }
        }
        let mut grid = TileGrid { spec, coords, arena, border, activity, dir: None };
        for b in grid.border.iter_mut() {
            *b &= BORDER_MASK;
        }
        for p in 0..n {
            let a = grid.activity[p];
            grid.set_activity_flags(p, a);
        }
        grid.build_directory();
        grid.debug_check();
        Ok(grid)
    }

    /// The tiles at list positions `range` as a grid of their own, with their flags.
    pub(crate) fn sub_list(&self, range: std::ops::Range<usize>) -> Result<TileGrid, GridError> {
        TileGrid::from_parts(
            self.spec,
            self.coords[range.clone()].to_vec(),
            self.arena[range.clone()].to_vec(),
            self.border[range.clone()].to_vec(),
            self.activity[range].to_vec(),
        )
    }

    /// The values and activity flags of every tile, for a caller that overwrites tiles
    /// with another grid's (a rank's ghost tiles): values must stay finite and within
    /// [-γ, γ], flags within their masks.
    pub(crate) fn values_activity_mut(&mut self) -> (&mut [Tile], &mut [u32]) {
        (&mut self.arena, &mut self.activity)
    }

    /// Reserves room for `additional` more tiles.
    pub fn reserve(&mut self, additional: usize) {
        self.coords.reserve(additional);
        self.arena.reserve(additional);
        self.border.reserve(additional);
        self.activity.reserve(additional);
    }

    /// (Re)builds the row directory that speeds up random access (kept only when it is
    /// small against the list). Done by every operation that rebuilds the list; call it
    /// after a series of [`TileGrid::append`]s.
    pub fn build_directory(&mut self) {
        self.dir = RowDirectory::build(&self.coords);
    }

    /// Where a tile is: its list position, or that it is absent and whether it is inside.
    /// With the row directory the search covers one tile row (O(1) to find the row, then
    /// the few tiles of the row); without it, the whole list by binary search (Sec. 4.5).
    #[inline]
    fn locate(&self, t: Coord) -> Result<usize, bool> {
        if let Some(dir) = &self.dir {
            return match dir.row(t) {
                Some((s, e)) => {
                    let row = &self.coords[s..e];
                    let p = s + row.partition_point(|c| c.x < t.x);
                    if p < e && self.coords[p].x == t.x {
                        Ok(p)
                    } else {
                        Err(self.absent_tile_inside(t, p))
                    }
                }
                // No tile in this row: outside (see `absent_tile_inside`).
                None => Err(false),
            };
        }
        self.find_tile(t).map_err(|p| self.absent_tile_inside(t, p))
    }

    /// List position of a tile coordinate (`Err` = insertion position), by binary
    /// search (Sec. 4.5), O(log N).
    #[inline]
    pub fn find_tile(&self, tile_coord: Coord) -> Result<usize, usize> {
        let p = super::lower_bound(&self.coords, tile_coord);
        if self.coords.get(p) == Some(&tile_coord) {
            Ok(p)
        } else {
            Err(p)
        }
    }

    /// Whether the absent tile `t`, whose insertion position in the list is `p`, is
    /// inside. All tiles of a tile row between two present tiles are absent and share
    /// one sign (a sign change needs band voxels), which the present tile before them
    /// records in its +x border flag and the one after them in its −x flag. A tile row
    /// without tiles is outside: a row through the interior of a bounded region crosses
    /// the band.
    #[inline]
    fn absent_tile_inside(&self, t: Coord, p: usize) -> bool {
        let same_row = |c: Coord| c.z == t.z && c.y == t.y;
        if p > 0 && same_row(self.coords[p - 1]) {
            self.border[p - 1] & (1 << PLUS_X) != 0
        } else if p < self.coords.len() && same_row(self.coords[p]) {
            self.border[p] & (1 << MINUS_X) != 0
        } else {
            false
        }
    }

    /// Value at a voxel by random access (Sec. 4.5): the stored value, or ±γ outside the
    /// tiles with the sign from the border flags.
    #[inline]
    pub fn value(&self, voxel: Coord) -> f32 {
        let (t, l) = tile_of(voxel);
        match self.locate(t) {
            Ok(p) => self.arena[p].0[l],
            Err(inside) => self.spec.background(inside),
        }
    }

    /// Whether tile coordinate `t` is inside, present or not: for a present tile, whether
    /// its first voxel is negative.
    pub fn tile_inside(&self, t: Coord) -> bool {
        match self.locate(t) {
            Ok(p) => self.tile(p).0[0] < 0.0,
            Err(inside) => inside,
        }
    }

    /// Number of stored voxels with `|φ| < γ`.
    pub fn band_voxels(&self) -> usize {
        let g = self.gamma();
        self.arena.iter().map(|t| t.0.iter().filter(|v| v.abs() < g).count()).sum()
    }

    /// Number of stored voxels, tile padding included.
    pub fn stored_voxels(&self) -> usize {
        self.coords.len() * TILE_LEN
    }

    /// Inclusive voxel bounding box of the stored tiles.
    pub fn bounding_box(&self) -> Option<(Coord, Coord)> {
        let first = *self.coords.first()?;
        let (mut lo, mut hi) = (first, first);
        for c in &self.coords {
            lo = Coord::new(lo.x.min(c.x), lo.y.min(c.y), lo.z.min(c.z));
            hi = Coord::new(hi.x.max(c.x), hi.y.max(c.y), hi.z.max(c.z));
        }
        Some((voxel_of(lo, 0), voxel_of(hi, TILE_LEN - 1)))
    }

    /// Visits every stored voxel in [`Coord`] order (not tile order): slab by slab of
    /// tiles with the same z, voxel row by voxel row. O(stored voxels).
    pub fn for_each_voxel_sorted(&self, mut f: impl FnMut(Coord, f32)) {
        let n = self.coords.len();
        let mut slab = 0;
        while slab < n {
            let tz = self.coords[slab].z;
            let mut slab_end = slab;
            while slab_end < n && self.coords[slab_end].z == tz {
                slab_end += 1;
            }
            for lz in 0..4 {
                let mut row = slab;
                while row < slab_end {
                    let ty = self.coords[row].y;
                    let mut row_end = row;
                    while row_end < slab_end && self.coords[row_end].y == ty {
                        row_end += 1;
                    }
                    for ly in 0..4 {
                        for p in row..row_end {
                            let t = self.tile(p);
                            let base = 16 * lz + 4 * ly;
                            for lx in 0..4 {
                                f(voxel_of(self.coords[p], base + lx), t.0[base + lx]);
                            }
                        }
                    }
                    row = row_end;
                }
            }
            slab = slab_end;
        }
    }

    /// Bytes by part: values (the arena), indices (coordinate list and row directory),
    /// flags (border and activity), slack (unused capacity).
    pub fn memory(&self) -> MemoryReport {
        let (v, vs) = vec_bytes(&self.arena);
        let (c, cs) = vec_bytes(&self.coords);
        let (b, bs) = vec_bytes(&self.border);
        let (a, as_) = vec_bytes(&self.activity);
        let (d, ds) = self.dir.as_ref().map_or((0, 0), RowDirectory::bytes);
        MemoryReport { values: v, indices: c + d, flags: b + a, slack: vs + cs + bs + as_ + ds }
    }

    /// Releases unused capacity.
    pub fn shrink_to_fit(&mut self) {
        self.coords.shrink_to_fit();
        self.arena.shrink_to_fit();
        self.border.shrink_to_fit();
        self.activity.shrink_to_fit();
    }

    /// Tile management (Sec. 4.6) exactly as the paper streams it, on one thread: streams
    /// the dilation of the list (Algorithm 2) and, for every position, keeps, removes or
    /// creates a tile from the activity flags of the tile and its neighbours (Algorithm
    /// 3). A removed tile writes its classification into the border flags of its
    /// neighbours that face it; a created tile is filled with ±γ from the border flags its
    /// neighbours hold towards it, and all its own border flags take that sign. The result
    /// is sorted, and the tile data is compacted in list order. Linear in the number of
    /// tiles. [`TileGrid::manage_tiles`] computes the same result in parallel; this is its
    /// reference.
    ///
    /// A tile that would be created outside the representable range gives
    /// [`GridError::OutOfRange`] and leaves the grid unchanged.
    pub fn manage_tiles_streamed(&mut self) -> Result<ManageStats, GridError> {
        self.restructure(|nb, activity| {
            let mut m = nb.matched;
            while m != 0 {
                let d = m.trailing_zeros() as usize;
                m &= m - 1;
                if activity[nb.ptr[d]] & NEIGHBOUR_TRIGGER[d] != 0 {
                    return true;
                }
            }
            false
        })
    }

    /// Dilates the tile set by one tile in all 26 directions (the 3×3×3 structuring
    /// element of Sec. 4.6): every tile is kept and every absent neighbour is created,
    /// filled with ±γ from the border flags. Sorted output, data compacted in list order.
    pub fn dilate(&mut self) -> Result<ManageStats, GridError> {
        self.restructure(|_, _| true)
    }

    /// Algorithms 2 and 3 with `trigger` deciding which positions must hold a tile, then
    /// compaction of the arena into list order. A tile's list position is its index into
    /// the arena (Algorithm 3's `index[]` is the identity, see the type's invariants).
    fn restructure<T>(&mut self, trigger: T) -> Result<ManageStats, GridError>
    where
        T: Fn(&super::Neighbours, &[u32]) -> bool,
    {
        /// Where an entry of the new list comes from.
        enum Entry {
            /// The tile at this position of the old list.
            Kept(usize),
            /// A new tile, inside or not.
            Created(bool),
        }
        let mut new_coords = Vec::with_capacity(self.coords.len() + self.coords.len() / 4 + 16);
        let mut entries: Vec<Entry> = Vec::with_capacity(new_coords.capacity());
        // Border flags change for removals; work on a copy so an error leaves `self` as is.
        let mut border = self.border.clone();
        let mut stats = ManageStats::default();

        let mut stream = DilationStream::new(&self.coords);
        while let Some(nb) = stream.next() {
            let triggered = trigger(&nb, &self.activity);
            if nb.matched & (1 << MID) != 0 {
                let pos = nb.ptr[MID];
                if triggered {
                    new_coords.push(nb.coord);
                    entries.push(Entry::Kept(pos));
                    stats.kept += 1;
                } else {
                    // Algorithm 3 lines 11-18: tell the neighbours what the tile was.
                    let inside = self.activity[pos] & INSIDE != 0;
                    let mut m = nb.matched & !(1 << MID);
                    while m != 0 {
                        let d = m.trailing_zeros() as usize;
                        m &= m - 1;
                        let b = &mut border[nb.ptr[d]];
                        let bit = 1 << reverse(d);
                        *b = if inside { *b | bit } else { *b & !bit };
                    }
                    stats.removed += 1;
                }
            } else if triggered {
                if !tile_in_range(nb.coord) {
                    return Err(GridError::OutOfRange { coord: nb.coord });
                }
                // Lines 22-27: the sign of the new tile from the neighbours' border flags.
                let mut inside = false;
                let mut m = nb.matched;
                while m != 0 {
                    let d = m.trailing_zeros() as usize;
                    m &= m - 1;
                    inside |= border[nb.ptr[d]] & (1 << reverse(d)) != 0;
                }
                new_coords.push(nb.coord);
                entries.push(Entry::Created(inside));
                stats.created += 1;
            }
        }

        if stats.removed == 0 && stats.created == 0 {
            // Nothing changed: the list, the arena and the flags stay as they are.
            self.debug_check();
            return Ok(stats);
        }
        check_list_len(new_coords.len())?;

        // Compaction: gather the tiles in list order into a fresh arena.
        let n = new_coords.len();
        let mut arena = Vec::with_capacity(n);
        let mut new_border = Vec::with_capacity(n);
        let mut activity = Vec::with_capacity(n);
        for e in &entries {
            match *e {
                Entry::Kept(pos) => {
                    arena.push(self.arena[pos]);
                    new_border.push(border[pos]);
                    activity.push(self.activity[pos]);
                }
                Entry::Created(inside) => {
                    let (t, b, a) = self.created_tile(inside);
                    arena.push(t);
                    new_border.push(b);
                    activity.push(a);
                }
            }
        }
        self.replace_list(new_coords, arena, new_border, activity);
        Ok(stats)
    }

    /// Values, border flags and activity flags of a tile that management creates with the
    /// given sign (Algorithm 3 lines 22–31): ±γ everywhere, every border flag that sign.
    #[inline]
    pub(super) fn created_tile(&self, inside: bool) -> (Tile, u32, u32) {
        let g = self.gamma();
        if inside {
            (Tile::splat(-g), BORDER_MASK, INSIDE)
        } else {
            (Tile::splat(g), 0, 0)
        }
    }

    /// Tiles the value arena holds without growing.
    pub(crate) fn value_capacity(&self) -> usize {
        self.arena.capacity()
    }

    /// Gives the value arena the headroom of a growing band
    /// ([`crate::memory::grown_capacity`]), so that tile management, which moves the values
    /// within the arena when it has no spare buffer, rarely has to copy them into a larger
    /// one. No value changes.
    pub(crate) fn reserve_value_headroom(&mut self) {
        let (n, want) = (self.arena.len(), crate::memory::grown_capacity(self.arena.len()));
        if self.arena.capacity() < want {
            self.arena.reserve_exact(want - n);
        }
    }

    /// Installs a new list whose arrays are in list order and rebuilds the row directory;
    /// returns the previous grid.
    pub(super) fn replace_list(
        &mut self,
        coords: Vec<Coord>,
        arena: Vec<Tile>,
        border: Vec<u32>,
        activity: Vec<u32>,
    ) -> TileGrid {
        let mut next = TileGrid { spec: self.spec, coords, arena, border, activity, dir: None };
        next.build_directory();
        next.debug_check();
        std::mem::replace(self, next)
    }

    #[inline]
    pub(super) fn debug_check(&self) {
        #[cfg(debug_assertions)]
        if let Err(e) = self.check_invariants() {
            panic!("TileGrid invariant violated: {e}");
        }
    }

    /// Checks every invariant listed on the type; O(N) plus O(64 N) for the values.
    pub fn check_invariants(&self) -> Result<(), String> {
        let n = self.coords.len();
        let t = self.arena.len();
        if self.border.len() != t || self.activity.len() != t {
            return Err("flag arrays and arena differ in length".into());
        }
        if t != n {
            return Err(format!("{t} arena tiles for {n} list entries (orphans)"));
        }
        for w in self.coords.windows(2) {
            if w[0] >= w[1] {
                return Err(format!("list not strictly increasing at {:?} -> {:?}", w[0], w[1]));
            }
        }
        if let Some(c) = self.coords.iter().find(|&&c| !tile_in_range(c)) {
            return Err(format!("tile {c:?} out of range"));
        }
        if self.border.iter().any(|b| b & !BORDER_MASK != 0) {
            return Err("border flag outside BORDER_MASK".into());
        }
        if self
            .activity
            .iter()
            .any(|&a| a & !(ACTIVE_MASK | INSIDE) != 0 || (a & INSIDE != 0 && a & ACTIVE_MASK != 0))
        {
            return Err("malformed activity flags".into());
        }
        if let Some(dir) = &self.dir {
            for (p, &c) in self.coords.iter().enumerate() {
                match dir.row(c) {
                    Some((s, e))
                        if s <= p
                            && p < e
                            && self.coords[s..e].iter().all(|r| r.z == c.z && r.y == c.y) => {}
                    other => {
                        return Err(format!("row directory gives {other:?} for tile {p} at {c:?}"))
                    }
                }
            }
        }
        let g = self.gamma();
        if self.arena.iter().any(|tile| tile.0.iter().any(|v| !v.is_finite() || v.abs() > g)) {
            return Err("value not finite or outside [-γ, γ]".into());
        }
        Ok(())
    }
}
