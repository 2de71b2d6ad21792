//! Parallel tile management (van der Laan et al. 2011, Sec. 4.6, Algorithm 3; its Sec. 5.8 leaves
//! multicore to future work).
//!
//! The paper streams the dilation of the whole list (Algorithm 2) and decides keep /
//! remove / create at every position of it. The same decisions split into independent
//! chunks of the list:
//!
//! 1. **Keep or remove** each tile from its neighbours' activity (pull, as Algorithm 3),
//!    with a [`NeighbourCursor`] per chunk seeded by binary search (Sec. 5.8). A removed
//!    tile writes its classification into the border flags its neighbours hold towards it
//!    (lines 11–18): each such bit belongs to exactly one removed tile, so the writes are
//!    atomic bit operations whose result does not depend on their order.
//! 2. **Create** the absent neighbours a tile's guard regions trigger (push: the same
//!    trigger test, seen from the active tile), collected per chunk, then sorted and
//!    deduplicated; each takes the OR of the border flags its present neighbours hold
//!    towards it (lines 22–27). Those bits point at an absent position, so no removal
//!    changes them and the old flags give the paper's answer.
//! 3. **Compaction**: each chunk merges its kept tiles with the created tiles of its
//!    coordinate range; a prefix sum over the chunks' counts places every chunk's output,
//!    written in parallel in list order.
//!
//! The result does not depend on the number of threads or the chunking, and equals
//! [`TileGrid::manage_tiles_streamed`] (tested).

use super::flags::{ACTIVE_MASK, BORDER_MASK, INSIDE, NEIGHBOUR_TRIGGER};
use super::stream::{move_kept, ListMoves, NeighbourCursor, NeighbourTable, NONE};
use super::{lower_bound, tile_in_range, ManageStats, Tile, TileGrid};
use crate::coord::{reverse, Coord, MID, NEIGHBOURHOOD};
use crate::grid::GridError;
use crate::memory::{grown_capacity, resize_exact};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// The neighbours in a tile's own layer (offsets with dz = 0; bits of [`NEIGHBOURHOOD`],
/// the centre excluded): what a planar band may create.
const IN_PLANE: u32 = {
    let mut mask = 0;
    let mut d = 0;
    while d < 27 {
        if NEIGHBOURHOOD[d].z == 0 && d != MID {
            mask |= 1 << d;
        }
        d += 1;
    }
    mask
};

/// Tiles per parallel task (the result does not depend on it; the unit tests use small
/// chunks so that their grids span many).
const CHUNK: usize = if cfg!(test) { 7 } else { 512 };

/// Splits `v` into consecutive slices of the given lengths.
fn split_by<'a, T>(mut v: &'a mut [T], lens: &[usize]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(lens.len());
    for &l in lens {
        let (a, b) = v.split_at_mut(l);
        out.push(a);
        v = b;
    }
    out
}

/// `total` copies of `v`, with the headroom of a growing band's buffers
/// (`grown_capacity`): the step buffers the arena is swapped with then rarely have to grow.
/// Written on the thread pool (a pass over the new list's arrays at every step that
/// changes it).
fn filled<T: Clone + Send + Sync>(total: usize, v: T) -> Vec<T> {
    let mut out = Vec::with_capacity(grown_capacity(total));
    out.par_extend(rayon::iter::repeat_n(v, total));
    out
}

impl TileGrid {
    /// Tile management (Sec. 4.6, Algorithm 3) in parallel chunks (keep/remove by pull,
    /// creation by push, compaction by a prefix sum; docs/decisions/0004): keeps,
    /// removes or creates tiles from the activity flags of each tile and its neighbours; a
    /// removed tile writes its classification into the border flags of its neighbours that
    /// face it; a created tile is filled with ±γ from the border flags its neighbours hold
    /// towards it, and all its own border flags take that sign.
    /// The result is sorted, the tile data compacted in list order, and identical to
    /// [`TileGrid::manage_tiles_streamed`] for any number of threads. Linear in the number
    /// of tiles.
    ///
    /// A tile that would be created outside the representable range gives
    /// [`GridError::OutOfRange`] and leaves the grid unchanged.
    pub fn manage_tiles(&mut self) -> Result<ManageStats, GridError> {
        self.manage_tiles_checked(None, |_| Ok(()), &mut Vec::new(), true, false)
            .map(|(stats, _)| stats)
    }

    /// [`TileGrid::manage_tiles`] that asks `admit(tiles)` before it allocates the new list
    /// of `tiles` tiles (an error from it is returned and leaves the grid unchanged), and
    /// returns the previous grid when the list changed (`None` when nothing changed), so
    /// that a caller can put it back. `table`, when given, holds the neighbours of the
    /// current list (a caller that keeps one saves the walk that finds them); when the
    /// list changes, it is made to follow it ([`NeighbourTable::follow`]) instead of being
    /// rebuilt.
    ///
    /// `spare` is a buffer of tiles whose contents do not matter (a step's scratch
    /// buffer). When its capacity holds the new list, the new values are written into its
    /// memory instead of a new allocation, and the previous grid returned **lends its
    /// values** to `spare` in exchange: its value array is then empty (its list, border
    /// and activity flags are whole), and [`TileGrid::swap_values`] must give it a full
    /// set (φⁿ, which a caller that undoes a step holds anyway) before it is used. So the
    /// list changes without a second value array next to the first.
    ///
    /// `in_place`: where the spare is too small, the values move within the grid's own
    /// arena instead of into a new one (compaction towards the front, then expansion
    /// towards the back, see [`move_kept`]); the previous grid returned then has no values
    /// either, as above. Otherwise a new arena holds them and the previous grid keeps its
    /// own.
    ///
    /// `planar`: the band is a 2-D level set extruded along z over the tile layers it
    /// holds (a planar lattice, [`crate::evolve::Lattice::planar`]), so no tile is created
    /// above or below a tile of the list: the extrusion's faces would otherwise trigger a
    /// new layer at every step, whose tiles, filled with ±γ by their neighbours' sides,
    /// evolve an interface of their own.
    pub(crate) fn manage_tiles_checked(
        &mut self,
        table: Option<&mut NeighbourTable>,
        admit: impl FnOnce(usize) -> Result<(), GridError>,
        spare: &mut Vec<Tile>,
        in_place: bool,
        planar: bool,
    ) -> Result<(ManageStats, Option<TileGrid>), GridError> {
        let n = self.coords.len();
        if n == 0 {
            return Ok((ManageStats::default(), None));
        }
        let border_new: Vec<AtomicU32> =
            self.border.par_iter().map(|&b| AtomicU32::new(b)).collect();
        let mut keep = vec![false; n];
        let creatable = if planar { IN_PLANE } else { BORDER_MASK };
        let created =
            self.keep_and_find_created(table.as_deref(), &border_new, &mut keep, creatable);
        if let Some(&c) = created.iter().find(|&&c| !tile_in_range(c)) {
            return Err(GridError::OutOfRange { coord: c });
        }
        let kept = keep.iter().filter(|&&k| k).count();
        let stats = ManageStats { kept, removed: n - kept, created: created.len() };
        if stats.removed == 0 && stats.created == 0 {
            // Nothing changed (and without removals no border flag did either).
            self.debug_check();
            return Ok((stats, None));
        }
        let created_inside = self.created_signs(&created);
        let total = stats.kept + stats.created;
        super::grid::check_list_len(total)?;
        admit(total)?;
        let recycle = spare.capacity() >= total;
        let arena = if recycle {
            // The compaction writes every tile: the spare's old values need no clearing,
            // only the tiles beyond its length need a value (a pass over the whole arena
            // here ran on one thread at every step that changed the list).
            let mut a = std::mem::take(spare);
            a.truncate(total);
            a.resize(total, Tile::splat(0.0));
            Some(a)
        } else if in_place {
            None
        } else {
            Some(filled(total, Tile::splat(0.0)))
        };
        let (list, moves) =
            self.compact(&keep, &border_new, &created, &created_inside, total, arena);
        let (coords, arena, border, activity) = list;
        let arena = match arena {
            Some(a) => a,
            None => {
                // Growing with a band's headroom, so that the next steps move within this
                // arena instead of copying it into a larger one.
                let mut values = std::mem::take(&mut self.arena);
                resize_exact(&mut values, total.max(n), Tile::splat(0.0));
                move_kept(&mut values, &moves.from);
                values.truncate(total);
                // The created tiles, by the sign their activity flags took.
                values.par_iter_mut().zip(&moves.from).zip(&activity).for_each(
                    |((v, &from), &a)| {
                        if from == NONE {
                            *v = self.created_tile(a & INSIDE != 0).0;
                        }
                    },
                );
                values
            }
        };
        if let Some(t) = table {
            t.follow(&coords, &moves);
        }
        let mut prev = self.replace_list(coords, arena, border, activity);
        if recycle {
            std::mem::swap(spare, &mut prev.arena);
        }
        Ok((stats, Some(prev)))
    }

    /// Phases 1 and 2, per chunk: marks the tiles to keep in `keep`, writes the removal
    /// notices into `border_new` (Algorithm 3 lines 11–18) and returns the absent
    /// positions the active tiles trigger, sorted and without duplicates. The neighbours
    /// come from `table` (that of the current list) or a cursor walk. Only the neighbours
    /// of `creatable` (bits of [`NEIGHBOURHOOD`]) are created.
    fn keep_and_find_created(
        &self,
        table: Option<&NeighbourTable>,
        border_new: &[AtomicU32],
        keep: &mut [bool],
        creatable: u32,
    ) -> Vec<Coord> {
        let coords = &self.coords[..];
        let activity = &self.activity[..];
        if let Some(t) = table {
            debug_assert_eq!(t.len(), coords.len(), "stale neighbour table");
        }
        let found: Vec<Vec<Coord>> = keep
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, keep)| {
                let start = c * CHUNK;
                let mut created = Vec::new();
                let end = start + keep.len();
                let mut cur = table.is_none().then(|| NeighbourCursor::new(coords, start, end));
                for (i, &coord) in coords[start..end].iter().enumerate() {
                    let p = start + i;
                    let tile = Classify { p, coord, activity, border_new, creatable };
                    keep[i] = match table {
                        // The row's positions, computed for the bits visited only.
                        Some(t) => {
                            let row = t.row(p);
                            tile.run(row.matched, |d| row.position(d), &mut created)
                        }
                        None => {
                            let nb = cur
                                .as_mut()
                                .and_then(NeighbourCursor::next)
                                .expect("a cursor yields every entry of its range");
                            tile.run(nb.matched, |d| nb.ptr[d], &mut created)
                        }
                    };
                }
                created
            })
            .collect();
        let mut created: Vec<Coord> = found.concat();
        created.par_sort_unstable();
        created.dedup();
        created
    }

    /// Lines 22–27: the sign of each new tile from its present neighbours' border flags.
    /// The new tiles are sorted, so per row of neighbours (dy, dz) a pointer into the old
    /// list only moves forward (as in Algorithm 1); chunks seed theirs by binary search.
    fn created_signs(&self, created: &[Coord]) -> Vec<bool> {
        let (coords, old_border) = (&self.coords[..], &self.border[..]);
        let n = coords.len();
        let mut created_inside = vec![false; created.len()];
        created_inside.par_chunks_mut(CHUNK).zip(created.par_chunks(CHUNK)).for_each(
            |(inside, created)| {
                let mut row = [0usize; 9];
                for (r, p) in row.iter_mut().enumerate() {
                    *p = lower_bound(coords, created[0].wrapping_add(NEIGHBOURHOOD[3 * r]));
                }
                for (ins, &c) in inside.iter_mut().zip(created) {
                    for (r, p) in row.iter_mut().enumerate() {
                        let first = c.wrapping_add(NEIGHBOURHOOD[3 * r]);
                        let mut q = *p;
                        while q < n && coords[q] < first {
                            q += 1;
                        }
                        *p = q;
                        let mut x = first;
                        for k in 0..3 {
                            let d = 3 * r + k;
                            if q < n && coords[q] == x {
                                *ins |= old_border[q] & (1 << reverse(d)) != 0;
                                q += 1;
                            }
                            x.x += 1;
                        }
                    }
                }
            },
        );
        created_inside
    }

    /// Phase 3: the new list in list order (coordinates, values, border and activity
    /// flags), `total` entries, its values written into `new_arena` (one tile per entry;
    /// `None`: the values are left to the caller), and where each tile went
    /// ([`ListMoves`]). Each chunk merges its kept tiles with the created tiles of its
    /// coordinate range; a prefix sum over the chunks' counts places every chunk's output,
    /// written in parallel.
    #[allow(clippy::type_complexity)] // the four arrays of a list
    fn compact(
        &self,
        keep: &[bool],
        border_new: &[AtomicU32],
        created: &[Coord],
        created_inside: &[bool],
        total: usize,
        mut new_arena: Option<Vec<Tile>>,
    ) -> ((Vec<Coord>, Option<Vec<Tile>>, Vec<u32>, Vec<u32>), ListMoves) {
        debug_assert!(new_arena.as_ref().is_none_or(|a| a.len() == total));
        let (coords, arena, activity) = (&self.coords[..], &self.arena[..], &self.activity[..]);
        let n = coords.len();
        let chunks = n.div_ceil(CHUNK);
        let cuts: Vec<usize> = (0..=chunks)
            .map(|c| match c {
                0 => 0,
                c if c == chunks => created.len(),
                c => created.partition_point(|&x| x < coords[c * CHUNK]),
            })
            .collect();
        let lens: Vec<usize> = (0..chunks)
            .map(|c| {
                let k = keep[c * CHUNK..((c + 1) * CHUNK).min(n)].iter().filter(|&&k| k).count();
                k + cuts[c + 1] - cuts[c]
            })
            .collect();
        let mut new_coords = filled(total, Coord::default());
        let mut new_border = filled(total, 0u32);
        let mut new_activity = filled(total, 0u32);
        let mut moves = ListMoves { to: filled(n, NONE), from: filled(total, NONE) };
        // Each chunk's first new position.
        let bases: Vec<usize> = lens
            .iter()
            .scan(0, |b, &l| {
                *b += l;
                Some(*b - l)
            })
            .collect();
        let arena_parts: Vec<Option<&mut [Tile]>> = match new_arena.as_mut() {
            Some(a) => split_by(a, &lens).into_iter().map(Some).collect(),
            None => lens.iter().map(|_| None).collect(),
        };
        split_by(&mut new_coords, &lens)
            .into_par_iter()
            .zip(arena_parts)
            .zip(split_by(&mut new_border, &lens))
            .zip(split_by(&mut new_activity, &lens))
            .zip(split_by(&mut moves.from, &lens))
            .zip(moves.to.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(c, (((((oc, mut oa), ob), of), from), to))| {
                let base = bases[c];
                let (mut p, end) = (c * CHUNK, ((c + 1) * CHUNK).min(n));
                let (mut q, qend) = (cuts[c], cuts[c + 1]);
                let mut o = 0;
                loop {
                    while p < end && !keep[p] {
                        p += 1;
                    }
                    let take_old = match (p < end, q < qend) {
                        (true, true) => coords[p] < created[q],
                        (true, false) => true,
                        (false, true) => false,
                        (false, false) => break,
                    };
                    if take_old {
                        oc[o] = coords[p];
                        if let Some(oa) = oa.as_deref_mut() {
                            oa[o] = arena[p];
                        }
                        ob[o] = border_new[p].load(Ordering::Relaxed);
                        of[o] = activity[p];
                        // Positions fit in u32: `check_list_len` refused longer lists.
                        from[o] = p as u32;
                        to[p - c * CHUNK] = (base + o) as u32;
                        p += 1;
                    } else {
                        oc[o] = created[q];
                        let (tile, b, a) = self.created_tile(created_inside[q]);
                        if let Some(oa) = oa.as_deref_mut() {
                            oa[o] = tile;
                        }
                        (ob[o], of[o]) = (b, a);
                        q += 1;
                    }
                    o += 1;
                }
                debug_assert_eq!(o, oc.len());
            });
        ((new_coords, new_arena, new_border, new_activity), moves)
    }
}

/// Tile management's decision for one tile of the list (Algorithm 3).
struct Classify<'a> {
    p: usize,
    coord: Coord,
    activity: &'a [u32],
    border_new: &'a [AtomicU32],
    /// The neighbours that may be created (bits of [`NEIGHBOURHOOD`]).
    creatable: u32,
}

impl Classify<'_> {
    /// Whether the tile stays, from the activity of its neighbours `matched` (at list
    /// positions `ptr(d)`). A tile that goes writes its classification into the border
    /// flags its neighbours hold towards it (lines 11–18); an active tile pushes the absent
    /// neighbours it triggers onto `created`.
    #[inline(always)]
    fn run(&self, matched: u32, ptr: impl Fn(usize) -> usize, created: &mut Vec<Coord>) -> bool {
        let Classify { p, coord, activity, border_new, creatable } = *self;
        let mut triggered = false;
        let mut m = matched;
        while m != 0 {
            let d = m.trailing_zeros() as usize;
            m &= m - 1;
            if activity[ptr(d)] & NEIGHBOUR_TRIGGER[d] != 0 {
                triggered = true;
                break;
            }
        }
        if !triggered {
            let inside = activity[p] & INSIDE != 0;
            let mut m = matched & !(1 << MID);
            while m != 0 {
                let d = m.trailing_zeros() as usize;
                m &= m - 1;
                let bit = 1u32 << reverse(d);
                let b = &border_new[ptr(d)];
                if inside {
                    b.fetch_or(bit, Ordering::Relaxed);
                } else {
                    b.fetch_and(!bit, Ordering::Relaxed);
                }
            }
        }
        let a = activity[p];
        if a & ACTIVE_MASK != 0 {
            let mut absent = !matched & creatable;
            while absent != 0 {
                let e = absent.trailing_zeros() as usize;
                absent &= absent - 1;
                if a & NEIGHBOUR_TRIGGER[reverse(e)] != 0 {
                    created.push(coord.wrapping_add(NEIGHBOURHOOD[e]));
                }
            }
        }
        triggered
    }
}
