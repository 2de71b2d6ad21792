//! The Sorted Tile List engine: every tile gathered with its halo into a padded block,
//! the kernels over its 64 voxels with scalar or SIMD lanes, tiles in parallel chunks
//! (van der Laan et al. 2011, Sec. 4.7), tile management after each step (Sec. 4.6).

use super::packed::{self, PackedGroup, PackedTiles};
use super::{growth_bytes, kappa_terms, resize_exact, vec_bytes, MemoryBudget, Representation};
use crate::coord::Coord;
use crate::distributed::{Comm, RankPart};
use crate::evolve::dispatch::{
    dispatch, dispatch_renorm, dispatch_renorm_first, Halo, RenormParams, StageParams, Sweep,
};
use crate::evolve::field::{ScalarFn, VectorFn};
use crate::evolve::{EvolveError, Lanes, SpatialScheme, StepKeeps};
use crate::exact::ExactSum;
use crate::grid::GridSpec;
use crate::memory::grown_capacity;
use crate::storage::tiles::{
    compute_activity, voxel_of, InPlaceTiles, NeighbourTable, PaddedBlock, Tile, TileGrid,
    TileSource, SLICE_LEN, TILE_LEN,
};
use levelset_kernels::{BandMasked, Lane, LaneFn, TileBlock, VoxelKernel};
use rayon::prelude::*;
use std::ops::Range;

/// Tiles per parallel task. Results do not depend on it: every tile is computed on its
/// own and reductions are exact (see [`ExactSum`]).
const TILE_CHUNK: usize = 64;

/// Runs of `len` voxels from voxel x `x` along the first `rows` rows of voxels (of the
/// sixteen, in z-slice order) of the tile row whose tiles' first voxel is at `first`'s y
/// and z.
fn row_runs(
    first: Coord,
    x: i32,
    len: u32,
    rows: usize,
    f: &mut (impl FnMut(Coord, u32) + ?Sized),
) {
    for row in 0..rows as i32 {
        f(Coord::new(x, first.y + (row & 3), first.z + (row >> 2)), len);
    }
}

/// Bytes per tile of the grid's own arrays (values, coordinate, border and activity; the
/// row directory is small against them).
pub(crate) const TILE_GRID_BYTES: u64 =
    (std::mem::size_of::<Tile>() + std::mem::size_of::<Coord>() + 2 * 4) as u64;

/// Bytes per tile of the arrays tile management builds next to the list: the new list's
/// coordinates, border and activity flags, where each tile went and came from, the flags it
/// keeps while it decides, with a growing band's headroom.
const MANAGE_BYTES_PER_TILE: u64 = 40;

/// Bytes per tile of the stored anchors ([`PackedTiles`]) in the estimates: the two bit
/// words and the start of each tile, and the values of the voxels next to the interface
/// (about 8 a tile on spheres of radius 200 to 800 and in the morph scenario).
const ANCHOR_BYTES_PER_TILE: u64 = 18 + 4 * 16;

/// Bytes per tile of φⁿ packed for the undo ([`PackedTiles`]) in the estimates: the two bit
/// words and the start of each tile, and the band voxels' values, counted as half the
/// tile's (27 a tile on a sphere of radius 800 at γ = 3).
const PACKED_BYTES_PER_TILE: u64 = 18 + 4 * 32;

/// Bytes per tile the engine holds while it steps: the grid's own arrays, the activity
/// flags a sweep computes, the band mask, the neighbour table's row, φⁿ (`whole`, see
/// [`StepKeeps::whole_phi_n`]: the double buffer and φⁿ whole beside it; otherwise φⁿ
/// packed, see [`TileUndo`]) with its activity flags, and the larger of the anchors,
/// which live through a renormalisation, and the arrays of tile management, which follows
/// it. Tile management moves the values within the arena (or writes them into a free step
/// buffer), so it adds no value array.
pub(crate) fn step_bytes_per_tile(keeps: StepKeeps, whole: bool) -> u64 {
    let tile = std::mem::size_of::<Tile>() as u64;
    let row = std::mem::size_of::<crate::storage::tiles::NeighbourRow>() as u64;
    let b = TILE_GRID_BYTES + 4 + 8 + row + 4;
    let b = b + if whole { 2 * tile } else { PACKED_BYTES_PER_TILE };
    b + if keeps.anchors {
        ANCHOR_BYTES_PER_TILE.max(MANAGE_BYTES_PER_TILE)
    } else {
        MANAGE_BYTES_PER_TILE
    }
}

/// Where the tile engine keeps φⁿ of the step (or the renormalisation) in progress, to
/// undo it and for TVD-RK3's later stages.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum TileUndo {
    /// No step in progress, or its first stage failed before changing anything.
    #[default]
    Nothing,
    /// TVD-RK3, and forward Euler on a band within [`TilesRep::double_buffer_bytes`]: the
    /// φⁿ buffer holds it, whole (for the stages that read it), the sweeps writing into
    /// the double buffer.
    PhiN,
    /// Forward Euler on larger bands, and a renormalisation at rest: packed
    /// ([`Buffers::packed`]), the sweeps writing in place. Outside the band a tile holds
    /// ±γ, so the packed φⁿ takes a fraction of a value array (27 of 64 values a tile on a
    /// sphere of radius 800).
    Packed,
}

/// The tile engine: the grid holds the current values. TVD-RK3's stages, forward Euler's
/// on a band within `double_buffer_bytes`, and the renormalisation's sweeps after them,
/// write into the double buffer `out` in list order (Sec. 4.7), swapped into the grid
/// after each sweep; forward Euler's stage on a larger band, and every sweep of a
/// renormalisation whose φⁿ is packed, write into the grid in place ([`TileSweep`]).
///
/// # Invariants
/// * `table` holds the neighbours of `grid`'s current list (rebuilt after every tile
///   management; checked in debug builds where it is read);
/// * while a step is in progress, `undo` names the buffer holding φⁿ (`phi_n` or
///   `packed`; its activity flags are in `phi_n_activity`) in the list order of the state
///   before the step, and `prev` holds that state's grid when tile management has
///   replaced it.
#[derive(Clone)]
pub(crate) struct TilesRep {
    pub grid: TileGrid,
    pub lanes: Lanes,
    table: NeighbourTable,
    buf: Buffers,
    undo: TileUndo,
    /// Boxed: kept only while a step is in progress.
    prev: Option<Box<TileGrid>>,
    /// This rank's part of a distributed band (`None`: the whole band); see
    /// [`crate::distributed`]. Boxed: most grids are not distributed.
    part: Option<Box<RankPart>>,
    /// [`crate::evolve::Settings::double_buffer_bytes`] (set by [`super::Rep::take_settings`]).
    pub double_buffer_bytes: u64,
    /// A planar lattice ([`crate::evolve::Lattice::planar`]; set by
    /// [`super::Rep::take_settings`]): tile management creates no tile above or below
    /// the list's tiles, so the band stays in the tile layers it started in.
    pub planar: bool,
}

/// The buffers of a step, one entry per tile in list order.
#[derive(Clone, Default)]
struct Buffers {
    /// φⁿ (TVD-RK3) and its activity flags (whenever a step is in progress).
    phi_n: Vec<Tile>,
    phi_n_activity: Vec<u32>,
    /// φⁿ packed (forward Euler and renormalisation; boxed: empty with TVD-RK3).
    packed: Box<PackedTiles>,
    /// The double buffer (TVD-RK3) and the activity flags a sweep computes.
    out: Vec<Tile>,
    activity: Vec<u32>,
    /// The band mask, one bit per voxel (bit `i` of a tile's word: voxel `i`'s box of φⁿ
    /// holds a band voxel, min |φⁿ| < γ; see [`band_bits`]): a 32nd of the minima it
    /// stands for.
    band: Vec<u64>,
    /// The renormalisation's anchors of φ⁰, stored where they hold a number (boxed: empty
    /// between renormalisations).
    anchor: Box<PackedTiles>,
}

impl Buffers {
    /// Bytes they have to allocate to serve `tiles` tiles ([`step_bytes_per_tile`]'s
    /// arrays; `whole`: φⁿ kept whole beside the double buffer).
    fn growth(&self, tiles: usize, keeps: StepKeeps, whole: bool) -> u64 {
        let mut b = growth_bytes(&self.band, tiles)
            + growth_bytes(&self.activity, tiles)
            + growth_bytes(&self.phi_n_activity, tiles);
        if whole {
            b += growth_bytes(&self.out, tiles) + growth_bytes(&self.phi_n, tiles);
        } else {
            // Packed anew at every step.
            b += tiles as u64 * PACKED_BYTES_PER_TILE;
        }
        if keeps.anchors {
            // Dropped after every renormalisation.
            b += tiles as u64 * ANCHOR_BYTES_PER_TILE;
        }
        b
    }

    /// Sizes the sweep buffers for `tiles` tiles.
    fn resize(&mut self, tiles: usize) {
        resize_exact(&mut self.out, tiles, Tile::splat(0.0));
        self.resize_flags(tiles);
    }

    /// Sizes the band mask and the activity flags for `tiles` tiles (an in-place sweep
    /// writes no `out`).
    fn resize_flags(&mut self, tiles: usize) {
        resize_exact(&mut self.band, tiles, 0);
        resize_exact(&mut self.activity, tiles, 0);
    }

    /// Bytes held, used or not.
    fn bytes(&self) -> usize {
        vec_bytes(&self.phi_n)
            + vec_bytes(&self.phi_n_activity)
            + self.packed.bytes()
            + vec_bytes(&self.out)
            + vec_bytes(&self.band)
            + vec_bytes(&self.activity)
            + self.anchor.bytes()
    }
}

impl TilesRep {
    /// The engine over `grid`; builds the neighbour table in the current rayon pool.
    pub fn new(mut grid: TileGrid, lanes: Lanes) -> Self {
        grid.reserve_value_headroom();
        let mut table = NeighbourTable::default();
        table.rebuild(grid.tile_coords());
        TilesRep {
            grid,
            lanes,
            table,
            buf: Buffers::default(),
            undo: TileUndo::Nothing,
            prev: None,
            part: None,
            double_buffer_bytes: crate::evolve::Settings::DOUBLE_BUFFER_BYTES,
            planar: false,
        }
    }

    /// The engine over one rank's part of a distributed band (`grid`: its tiles and
    /// ghosts, as `part` plans them).
    pub fn distributed(grid: TileGrid, lanes: Lanes, part: RankPart) -> Self {
        TilesRep { part: Some(Box::new(part)), ..TilesRep::new(grid, lanes) }
    }

    /// The list positions this rank owns (every tile when the band is not distributed).
    fn owned(&self) -> Range<usize> {
        self.part.as_ref().map_or(0..self.grid.len(), |p| p.owned.clone())
    }

    /// Keeps φⁿ, the state before the step (or the renormalisation at rest) begins, packed
    /// with its activity flags, for [`Representation::undo_step`]; the sweeps then write in
    /// place.
    fn keep_step_start(&mut self) {
        let gamma = self.grid.gamma();
        self.buf.packed.pack(self.grid.values(), gamma);
        self.buf.phi_n_activity.clear();
        self.buf.phi_n_activity.extend_from_slice(self.grid.activity());
        self.undo = TileUndo::Packed;
    }

    /// The values changed (a sweep was swapped in): the ghost tiles get their owners'
    /// new values and activity flags, which the next sweep, the κ̄ sums and tile
    /// management read (distributed bands only).
    fn exchange_ghosts(&mut self) {
        exchange_ghosts(&self.part, &mut self.grid)
    }

    /// The step buffers a [`TileSweep`] of the `n` tiles needs: `out` as well when
    /// `double`-buffered, the band mask and flags only in place.
    fn size_for_sweep(&mut self, n: usize, double: bool) {
        if double {
            self.buf.resize(n);
        } else {
            self.buf.resize_flags(n);
        }
    }

    /// Takes a finished [`TileSweep`]'s results into the grid, then exchanges the ghost
    /// tiles: `double`-buffered, its values and flags (`out` and `activity` then hold the
    /// previous ones); in place, its flags.
    fn take_sweep(&mut self, double: bool) -> Result<(), EvolveError> {
        if double {
            self.grid.swap_values(&mut self.buf.out, &mut self.buf.activity)?;
        } else {
            self.grid.swap_activity(&mut self.buf.activity)?;
        }
        self.exchange_ghosts();
        Ok(())
    }

    /// Whether tile z `tz` is this rank's (always, when the band is not distributed).
    fn owns_z(&self, tz: i32) -> bool {
        self.part.as_ref().is_none_or(|p| {
            let (lo, hi) = p.owned_z();
            lo <= tz && tz < hi
        })
    }

    /// Moves the cuts of a distributed band to balance the ranks' tiles when the largest
    /// rank holds more than (1 + threshold) × the smallest one's and new cuts improve
    /// that (collective); see [`crate::distributed`]. Returns whether tiles moved. Call
    /// between steps.
    pub fn rebalance(&mut self) -> bool {
        let Some(part) = self.part.as_mut() else { return false };
        let Some(threshold) = part.rebalance else { return false };
        let counts = part.comm.counts(part.owned.len() as u64);
        let spread = |c: &[u64]| {
            let (lo, hi) = (c.iter().min().copied(), c.iter().max().copied());
            (lo.unwrap_or(0), hi.unwrap_or(0))
        };
        let (lo, hi) = spread(&counts);
        if hi as f64 <= (1.0 + threshold) * lo as f64 {
            return false;
        }
        let mine = crate::distributed::slab_counts(self.grid.tile_coords(), part.owned.clone());
        let bytes: Vec<u8> = mine
            .iter()
            .flat_map(|&(z, n)| z.to_le_bytes().into_iter().chain(n.to_le_bytes()))
            .collect();
        let slabs: Vec<(i32, u64)> = part
            .comm
            .gather(&bytes)
            .iter()
            .flat_map(|m| {
                m.chunks_exact(12).map(|c| {
                    let z = i32::from_le_bytes(c[..4].try_into().expect("4 bytes"));
                    (z, u64::from_le_bytes(c[4..].try_into().expect("8 bytes")))
                })
            })
            .collect();
        let n = part.comm.size();
        let cuts = crate::distributed::balanced_cuts(&slabs, n);
        let mut after = vec![0u64; n];
        for &(z, k) in &slabs {
            after[crate::distributed::owner(&cuts, z)] += k;
        }
        let (new_lo, new_hi) = spread(&after);
        if cuts == part.cuts || new_hi - new_lo >= hi - lo {
            return false;
        }
        let grid = part.redistribute(&self.grid, cuts);
        self.grid = grid;
        self.table.rebuild(self.grid.tile_coords());
        true
    }

    /// The inside voxels the list does not store between tile `p − 1` and tile `p` (`p ≥ 1`)
    /// of one row of tiles, if the tile before the gap is inside towards +x: x-runs of
    /// voxels, one per row of voxels of the tiles strictly between them, for the first
    /// `rows` rows of the sixteen (in z-slice order).
    fn unstored_inside_runs_before(
        &self,
        p: usize,
        rows: usize,
        f: &mut (impl FnMut(Coord, u32) + ?Sized),
    ) {
        const PLUS_X: usize = crate::coord::direction_index(1, 0, 0);
        let coords = self.grid.tile_coords();
        let (a, b) = (coords[p - 1], coords[p]);
        if a.z == b.z
            && a.y == b.y
            && b.x > a.x + 1
            && self.grid.border_flags(p - 1) & (1 << PLUS_X) != 0
        {
            let first = voxel_of(Coord::new(a.x + 1, a.y, a.z), 0);
            row_runs(first, first.x, 4 * (b.x - a.x - 1) as u32, rows, f);
        }
    }

    /// The inside of `for_each_inside_run`, this rank's tiles split over the current thread
    /// pool: each stored tile as the mask of its voxels with φ ≤ 0 (bit `l` for voxel `l`,
    /// x fastest) given to `tile` with the tile's first voxel, and the unstored interior
    /// as x-runs given to `run`: between the tiles of a row, and within `span` (voxel x)
    /// before a row's first tile and after its last where the tile's border flag says
    /// the grid is inside there (as [`TileGrid::value`] reads it). Each part folds into
    /// its own `identity()`, and `combine` joins the parts in an order and grouping that
    /// depend on the thread count. On a planar lattice, each tile's first z-slice only
    /// (the low 16 bits; the other slices are its copies).
    pub(crate) fn fold_inside<T: Send>(
        &self,
        span: std::ops::Range<i32>,
        identity: &(impl Fn() -> T + Sync),
        tile: &(impl Fn(&mut T, Coord, u64) + Sync),
        run: &(impl Fn(&mut T, Coord, u32) + Sync),
        combine: &(impl Fn(T, T) -> T + Sync),
    ) -> T {
        const PLUS_X: usize = crate::coord::direction_index(1, 0, 0);
        const MINUS_X: usize = crate::coord::direction_index(-1, 0, 0);
        let coords = self.grid.tile_coords();
        let values = self.grid.values();
        let read = self.read_slices(self.planar).map_or(TILE_LEN, |(_, read)| read);
        let same_row = |a: Coord, b: Coord| a.z == b.z && a.y == b.y;
        // The run from x0 to x1 (within `span`) along each row of voxels read.
        let open_end = |acc: &mut T, first: Coord, x0: i64, x1: i64| {
            let (x0, x1) = (x0.max(span.start as i64), x1.min(span.end as i64));
            if x0 < x1 {
                row_runs(first, x0 as i32, (x1 - x0) as u32, read / 4, &mut |c, len| {
                    run(acc, c, len)
                });
            }
        };
        self.owned()
            .into_par_iter()
            .with_min_len(TILE_CHUNK)
            .fold(identity, |mut acc, p| {
                // Branch-free: one bit per voxel read.
                let mask = values[p].0[..read]
                    .iter()
                    .enumerate()
                    .fold(0u64, |m, (l, &v)| m | ((v <= 0.0) as u64) << l);
                if mask != 0 {
                    tile(&mut acc, voxel_of(coords[p], 0), mask);
                }
                if p > 0 {
                    let f = &mut |c, len| run(&mut acc, c, len);
                    self.unstored_inside_runs_before(p, read / 4, f);
                }
                let (c, flags) = (coords[p], self.grid.border_flags(p));
                let first = voxel_of(c, 0);
                if (p == 0 || !same_row(coords[p - 1], c)) && flags & (1 << MINUS_X) != 0 {
                    open_end(&mut acc, first, i64::MIN, first.x as i64);
                }
                if coords.get(p + 1).is_none_or(|&n| !same_row(c, n)) && flags & (1 << PLUS_X) != 0
                {
                    open_end(&mut acc, first, first.x as i64 + 4, i64::MAX);
                }
                acc
            })
            .reduce(identity, combine)
    }

    /// The z-slabs of tiles this rank owns that hold tiles (distributed bands only).
    pub fn owned_slabs(&self) -> Option<usize> {
        let p = self.part.as_ref()?;
        Some(crate::distributed::slab_counts(self.grid.tile_coords(), p.owned.clone()).len())
    }

    /// The statistics of this rank's exchanges (distributed bands only).
    pub fn halo_stats(&self) -> Option<crate::distributed::HaloStats> {
        self.part.as_ref().map(|p| p.comm.stats())
    }

    /// The whole band as one grid (collective when distributed): every rank's own tiles
    /// with their border flags, gathered in rank order, which is [`Coord`] order. A tile's
    /// 26 neighbours lie in its rank's own or ghost slabs, so its flags are the whole
    /// band's. A copy of the grid when the band is not distributed.
    /// Per-voxel samples of a field of the position alone, in `N` arrays, on the current
    /// list: a tile that was in the list `keys` keeps its samples from `prev` (the first
    /// `read` of its 64, those the sweeps read: on a planar lattice its first slice; the
    /// others are never read), a tile new to it is sampled by `sample(its coordinate, its
    /// 64 voxels in each array)`, which
    /// returns whether they are acceptable (checked: reused samples were checked when they
    /// were taken). `keys` becomes the current list. Both lists are sorted, so each chunk
    /// of the current list finds its first predecessor by binary search and then merges
    /// forward. Returns whether every new sample was acceptable.
    fn merge_static<const N: usize>(
        &self,
        read: usize,
        keys: &mut Vec<Coord>,
        prev: [&[f32]; N],
        out: [&mut [f32]; N],
        sample: impl Fn(Coord, [&mut [f32]; N]) -> bool + Sync,
    ) -> bool {
        let coords = self.grid.tile_coords();
        let old: &[Coord] = keys;
        debug_assert!(prev.iter().all(|c| c.len() == 64 * old.len()), "samples per key");
        const CHUNK: usize = 64 * TILE_CHUNK;
        let mut outs = out.map(|o| o.chunks_mut(CHUNK));
        let chunks: Vec<[&mut [f32]; N]> = coords
            .chunks(TILE_CHUNK)
            .map(|_| std::array::from_fn(|c| outs[c].next().expect("64 samples per tile")))
            .collect();
        let ok = chunks
            .into_par_iter()
            .zip(coords.par_chunks(TILE_CHUNK))
            .map(|(mut out, tiles)| {
                let mut j = old.partition_point(|k| *k < tiles[0]);
                let mut ok = true;
                for (i, &tc) in tiles.iter().enumerate() {
                    while j < old.len() && old[j] < tc {
                        j += 1;
                    }
                    let r = 64 * i..64 * i + 64;
                    if j < old.len() && old[j] == tc {
                        for (o, p) in out.iter_mut().zip(prev) {
                            o[64 * i..64 * i + read].copy_from_slice(&p[64 * j..64 * j + read]);
                        }
                    } else {
                        let tile = out.each_mut().map(|o| &mut o[r.clone()]);
                        ok &= sample(tc, tile);
                    }
                }
                ok
            })
            .reduce(|| true, |a, b| a && b);
        keys.clear();
        keys.extend_from_slice(coords);
        ok
    }

    pub(crate) fn gather(&self) -> Result<TileGrid, crate::grid::GridError> {
        let Some(p) = &self.part else { return Ok(self.grid.clone()) };
        const RECORD: usize = 16 + 4 * crate::storage::tiles::TILE_LEN;
        let mut bytes = Vec::with_capacity(p.owned.len() * RECORD);
        for pos in p.owned.clone() {
            let c = self.grid.tile_coords()[pos];
            for v in [c.x, c.y, c.z] {
                bytes.extend(v.to_le_bytes());
            }
            bytes.extend(self.grid.border_flags(pos).to_le_bytes());
            for v in self.grid.tile(pos).0 {
                bytes.extend(v.to_le_bytes());
            }
        }
        let word = |b: &[u8], k: usize| -> [u8; 4] { b[4 * k..4 * k + 4].try_into().expect("4") };
        let mut g = TileGrid::new(*self.grid.spec());
        for part in p.comm.gather(&bytes) {
            for r in part.chunks_exact(RECORD) {
                let i = |k| i32::from_le_bytes(word(r, k));
                let mut t = Tile::splat(0.0);
                for (k, v) in t.0.iter_mut().enumerate() {
                    *v = f32::from_le_bytes(word(r, 4 + k));
                }
                g.append(Coord::new(i(0), i(1), i(2)), &t, u32::from_le_bytes(word(r, 3)))?;
            }
        }
        g.build_directory();
        Ok(g)
    }

    /// This rank and the cuts of a distributed band.
    pub fn cuts(&self) -> Option<(usize, &[i32])> {
        self.part.as_ref().map(|p| (p.comm.rank(), &p.cuts[..]))
    }

    /// The neighbour table, checked against the list in debug builds.
    fn table(&self) -> &NeighbourTable {
        debug_assert_eq!(self.table.len(), self.grid.len(), "stale neighbour table");
        &self.table
    }
}

/// What every chunk of a tile sweep reads: the tiles from `grid` (a [`TileGrid`], or the
/// [`InPlaceTiles`] of one that an in-place sweep overwrites).
struct Shared<'a, M, S> {
    grid: &'a S,
    table: &'a NeighbourTable,
    compute_mask: bool,
    /// A planar lattice's step: each tile's first z-slice is computed and copied into the
    /// other three (the level set is extruded along z; see [`crate::evolve::Lattice::planar`]).
    planar: bool,
    owned: &'a Range<usize>,
    make: &'a M,
}

/// The kernel over the tile at list position `pos` into `out`, unless no voxel of it is
/// in the computational band (or it is not this rank's): then `Ok(false)` and `out` is
/// untouched. `mask` is the tile's band-mask word, computed from the block with
/// `compute_mask` (stage 1) and read otherwise. Prefetches for the tile
/// [`PaddedBlock::PREFETCH_AHEAD`] positions on when that is below `prefetch_end`.
#[allow(clippy::too_many_arguments)] // the sweep's state, passed apart so that it inlines
#[inline(always)]
fn sweep_tile<L, K, M, S, const R: usize>(
    shared: &Shared<'_, M, S>,
    block: &mut PaddedBlock<R>,
    m: &mut [f32; 64],
    pos: usize,
    prefetch_end: usize,
    mask: &mut u64,
    out: &mut Tile,
) -> Result<bool, EvolveError>
where
    L: Lane,
    K: VoxelKernel,
    M: Fn(Range<usize>) -> K,
    S: TileSource,
{
    let Shared { grid, table, compute_mask, planar, owned, make } = *shared;
    let gamma = grid.gamma();
    let ahead = pos + PaddedBlock::<R>::PREFETCH_AHEAD;
    if ahead < prefetch_end {
        PaddedBlock::<R>::prefetch(grid, table.row(ahead));
    }
    // The tile's band mask as minima for `BandMasked`: exact in stage 1, stand-ins with
    // the same comparisons with γ (`band_minima`) in later ones.
    let computes = if !owned.contains(&pos) {
        false
    } else if compute_mask {
        // On a planar lattice only the first z-slice is computed, and only its rows are
        // gathered (the same bits: no other row is read).
        if planar {
            block.gather_star_row_planar(grid, pos, table.row(pos));
            block.box_min_abs_planar(gamma, m);
        } else {
            block.gather_star_row(grid, pos, table.row(pos));
            block.box_min_abs(gamma, m);
        }
        *mask = band_bits(m, gamma);
        *mask != 0
    } else {
        let computes = *mask != 0;
        if computes {
            // A kernel without diagonal offsets reads the rows along the axes only.
            match (K::BOX_REACH == 0, planar) {
                (true, false) => block.gather_axes_row(grid, pos, table.row(pos)),
                (false, false) => block.gather_star_row(grid, pos, table.row(pos)),
                (true, true) => block.gather_axes_row_planar(grid, pos, table.row(pos)),
                (false, true) => block.gather_star_row_planar(grid, pos, table.row(pos)),
            }
            band_minima(*mask, gamma, m);
        }
        computes
    };
    if !computes {
        return Ok(false);
    }
    let tb = TileBlock::<R>::new(block.data())?;
    let k = BandMasked { step: make(64 * pos..64 * pos + 64), box_min: &m[..], gamma };
    tb.apply_slices::<L, _>(&k, &mut out.0, planar)?;
    Ok(true)
}

/// Parallel tasks per thread of a [`TileSweep`] in place: a task's first and last z-slabs
/// of tiles are read by its neighbours' tasks and wait for the end of the sweep, so fewer,
/// longer tasks hold fewer tiles aside.
const IN_PLACE_TASKS_PER_THREAD: usize = 4;

/// A sweep of the tile list, by one of two routes. Given `out`, double-buffered (van der
/// Laan et al. 2011, Sec. 4.7): the results go into `out` in chunks of [`TILE_CHUNK`]
/// tiles, and the grid is only read. Otherwise in place, into the grid it reads (Sec. 4.7
/// without the double buffer; the streaming of a band through its stencil,
/// Nielsen & Museth 2006, Sec. 3.3): a tile's new values wait in a queue until every
/// tile that reads it (its neighbours and itself) has been computed, which in list order
/// is about a z-slab of tiles later, and are then written into the arena. The list is
/// cut into a few long tasks; a tile read by another task's tiles (within a tile of the
/// cut) is written after all tasks end. Every tile is computed from the values before the
/// sweep, so the result is bit for bit the double-buffered sweep's, on any number of
/// threads and tasks; a failure part-way leaves the grid part-written, so the route is
/// only for a step that holds φⁿ to undo it. Either route holds the band mask (computed
/// from the input in stage 1, read otherwise) and the activity flags, which are swapped
/// in afterwards ([`TileGrid::swap_activity`], or with `out` by
/// [`TileGrid::swap_values`]). One sweep type for both routes compiles each kernel once.
struct TileSweep<'a, X: Extra<'a> = NoExtra> {
    grid: InPlaceTiles<'a>,
    table: &'a NeighbourTable,
    lanes: Lanes,
    band: &'a mut [u64],
    compute_mask: bool,
    activity: &'a mut [u32],
    /// The list positions to compute (this rank's tiles when distributed): the others
    /// (ghost tiles, which the exchange after the sweep overwrites) keep their values.
    owned: Range<usize>,
    /// A planar lattice's step (see [`Shared`]).
    planar: bool,
    /// The double buffer, one tile per list position; `None`: in place.
    out: Option<&'a mut [Tile]>,
    /// What else each task does with the tiles' blocks: nothing ([`NoExtra`]), or store
    /// the anchors of the swept values ([`AnchorExtra`]).
    extra: X,
}

impl<'a, X: Extra<'a>> Sweep for TileSweep<'a, X> {
    fn run<K, M, const R: usize>(self, make: M) -> Result<(), EvolveError>
    where
        K: VoxelKernel,
        M: Fn(Range<usize>) -> K + Sync,
        Halo<R>: crate::evolve::dispatch::Reach,
    {
        let simd = self.lanes == Lanes::Simd;
        let TileSweep {
            grid, table, band, compute_mask, activity, owned, planar, out, extra, ..
        } = self;
        let (anchors, h) = extra.anchors();
        let shared =
            Shared { grid: &grid, table, compute_mask, planar, owned: &owned, make: &make };
        let run = |start: usize,
                   mask: &mut [u64],
                   act: &mut [u32],
                   out: Option<&mut [Tile]>,
                   groups: &mut [Option<PackedGroup<'_>>]| {
            let extra = X::Use::new(h, groups, act.len());
            let chunk = SweepChunk::<M, X::Use<'_, '_>, R> {
                shared: &shared,
                start,
                mask,
                act,
                out,
                extra,
            };
            levelset_kernels::dispatch_default(simd, chunk)
        };
        run_sweep_tasks(&grid, band, activity, out, anchors, &run)
    }
}

/// What the tasks of a [`TileSweep`] do with each tile's gathered block besides its kernel
/// (a type, so that a sweep without extra work compiles none).
trait Extra<'a> {
    type Use<'c, 'g: 'c>: BlockUse<'c, 'g>;
    /// Where the anchors go and the voxel size they are evaluated with (none, and a size
    /// no task reads, without anchors).
    fn anchors(self) -> (Option<&'a mut PackedTiles>, f32);
}

/// A [`TileSweep`] that runs its kernel only.
struct NoExtra;

impl<'a> Extra<'a> for NoExtra {
    type Use<'c, 'g: 'c> = NoUse;
    fn anchors(self) -> (Option<&'a mut PackedTiles>, f32) {
        (None, 0.0)
    }
}

/// A [`TileSweep`] that also stores the anchors of the values it sweeps (the first sweep of
/// a renormalisation, over φ⁰; see [`StoreAnchors`]).
struct AnchorExtra<'a> {
    anchors: &'a mut PackedTiles,
    /// The voxel size h.
    h: f32,
}

impl<'a> Extra<'a> for AnchorExtra<'a> {
    type Use<'c, 'g: 'c> = StoreAnchors<'c, 'g>;
    fn anchors(self) -> (Option<&'a mut PackedTiles>, f32) {
        (Some(self.anchors), self.h)
    }
}

/// A task's use of each tile's block besides the kernel.
trait BlockUse<'c, 'g: 'c>: Sized {
    /// For a task of `len` tiles whose groups of [`packed::GROUP`] tiles are `groups`
    /// (`None` each unless anchors are stored), anchors evaluated with voxel size `h`.
    fn new(h: f32, groups: &'c mut [Option<PackedGroup<'g>>], len: usize) -> Self;

    /// After a tile of the task (nothing, unless the type does something).
    #[inline(always)]
    fn after<L: Lane, const R: usize>(&mut self, tile: TileDone<'_, R>) -> Result<(), EvolveError> {
        let _ = tile;
        Ok(())
    }
}

/// A tile of a task whose kernel has run, as [`BlockUse::after`] sees it.
struct TileDone<'b, const R: usize> {
    /// Its place in the task.
    i: usize,
    /// Whether the kernel ran on `block` (then `mask` is the tile's band-mask word and `m`
    /// the box minima or their stand-ins).
    computed: bool,
    mask: u64,
    block: &'b PaddedBlock<R>,
    m: &'b [f32; 64],
    gamma: f32,
}

/// Nothing besides the kernel.
struct NoUse;

impl<'c, 'g: 'c> BlockUse<'c, 'g> for NoUse {
    #[inline(always)]
    fn new(_: f32, _: &'c mut [Option<PackedGroup<'g>>], _: usize) -> Self {
        NoUse
    }
}

/// The anchors ([`levelset_kernels::InterfaceAnchor`], under the same band mask) of every
/// computed tile from the block its kernel read, packed group by group as the anchor
/// pass of a renormalisation packs them. The first sweep of a renormalisation reads φ⁰, so
/// it stores what a pass of its own would (the same kernel over the same values), and
/// that pass's gather and traversal are saved. Tiles not computed store none: no sweep
/// reads their anchors.
struct StoreAnchors<'c, 'g> {
    h: f32,
    groups: &'c mut [Option<PackedGroup<'g>>],
    len: usize,
    tiles: Vec<Tile>,
    masks: [u64; packed::GROUP],
}

impl<'c, 'g: 'c> BlockUse<'c, 'g> for StoreAnchors<'c, 'g> {
    fn new(h: f32, groups: &'c mut [Option<PackedGroup<'g>>], len: usize) -> Self {
        let tiles = vec![Tile::splat(f32::INFINITY); packed::GROUP];
        StoreAnchors { h, groups, len, tiles, masks: [0; packed::GROUP] }
    }

    #[inline(always)]
    fn after<L: Lane, const R: usize>(&mut self, tile: TileDone<'_, R>) -> Result<(), EvolveError> {
        let TileDone { i, computed, mask, block, m, gamma } = tile;
        let slot = i % packed::GROUP;
        self.masks[slot] = if computed { mask } else { 0 };
        if computed {
            let tb = TileBlock::<R>::new(block.data())?;
            let step = levelset_kernels::InterfaceAnchor { voxel_size: self.h };
            let k = BandMasked { step, box_min: &m[..], gamma };
            tb.apply_slices::<L, _>(&k, &mut self.tiles[slot].0, false)?;
        }
        if slot == packed::GROUP - 1 || i + 1 == self.len {
            let group = self.groups[i / packed::GROUP].as_mut().expect("a group per 64 tiles");
            group.fill(&self.tiles[..=slot], self.masks[..=slot].iter().copied(), f32::INFINITY);
        }
        Ok(())
    }
}

/// A task of a [`TileSweep`] as [`run_sweep_tasks`] calls it: the tiles from list position
/// `start` (their band-mask words, activity flags and, double-buffered, output tiles).
type SweepTaskFn<'f> = dyn Fn(
        usize,
        &mut [u64],
        &mut [u32],
        Option<&mut [Tile]>,
        &mut [Option<PackedGroup<'_>>],
    ) -> Result<Vec<(usize, Tile)>, EvolveError>
    + Sync
    + 'f;

/// The tasks of a [`TileSweep`] on the current rayon pool: chunks of [`TILE_CHUNK`] tiles
/// double-buffered into `out`; in place, [`IN_PLACE_TASKS_PER_THREAD`] tasks per thread,
/// whose held tiles are written after every task has ended. Apart from the kernel's type
/// (`task` is called through a pointer once per task): rayon's machinery is compiled once,
/// not once for every kernel, lane type and instruction-set level.
fn run_sweep_tasks(
    grid: &InPlaceTiles<'_>,
    band: &mut [u64],
    activity: &mut [u32],
    out: Option<&mut [Tile]>,
    anchors: Option<&mut PackedTiles>,
    task: &SweepTaskFn<'_>,
) -> Result<(), EvolveError> {
    // The anchors' groups of `packed::GROUP` tiles (`None` each without anchors); every
    // task starts at a multiple of the group size, so no group is split between tasks.
    const { assert!(TILE_CHUNK.is_multiple_of(packed::GROUP), "chunks of whole groups") };
    let n = grid.len();
    let mut groups: Vec<Option<PackedGroup<'_>>> = match anchors {
        Some(a) => {
            a.resize(n);
            a.groups_mut().map(Some).collect()
        }
        None => (0..n.div_ceil(packed::GROUP)).map(|_| None).collect(),
    };
    if let Some(out) = out {
        return out
            .par_chunks_mut(TILE_CHUNK)
            .zip(band.par_chunks_mut(TILE_CHUNK))
            .zip(activity.par_chunks_mut(TILE_CHUNK))
            .zip(groups.par_chunks_mut(TILE_CHUNK / packed::GROUP))
            .enumerate()
            .try_for_each(|(c, (((out, mask), act), groups))| {
                task(c * TILE_CHUNK, mask, act, Some(out), groups).map(|_| ())
            });
    }
    let tasks = IN_PLACE_TASKS_PER_THREAD * rayon::current_num_threads();
    let len = n.div_ceil(tasks).max(TILE_CHUNK).next_multiple_of(TILE_CHUNK);
    let held: Vec<Vec<(usize, Tile)>> = band
        .par_chunks_mut(len)
        .zip(activity.par_chunks_mut(len))
        .zip(groups.par_chunks_mut(len / packed::GROUP))
        .enumerate()
        .map(|(c, ((mask, act), groups))| task(c * len, mask, act, None, groups))
        .collect::<Result<_, _>>()?;
    held.par_iter().for_each(|tiles| {
        for (pos, t) in tiles {
            // SAFETY: every task has ended, so no gather reads any tile; each position
            // is held by one task only.
            unsafe { grid.write(*pos, t) };
        }
    });
    Ok(())
}

/// One task of a [`TileSweep`]: the tiles from list position `start`. Returns the
/// new values of its tiles that other tasks read, to be written after every task ends
/// (none when double-buffered into `out`).
struct SweepChunk<'a, 'c, M, E, const R: usize> {
    shared: &'a Shared<'a, M, InPlaceTiles<'a>>,
    start: usize,
    mask: &'c mut [u64],
    act: &'c mut [u32],
    out: Option<&'c mut [Tile]>,
    /// What else is done with each tile's block.
    extra: E,
}

impl<'c, 'g: 'c, K, M, E, const R: usize> LaneFn for SweepChunk<'_, 'c, M, E, R>
where
    K: VoxelKernel,
    M: Fn(Range<usize>) -> K + Sync,
    E: BlockUse<'c, 'g>,
{
    type Output = Result<Vec<(usize, Tile)>, EvolveError>;

    #[inline(always)]
    fn call<L: Lane>(self) -> Self::Output {
        let SweepChunk { shared, start, mask, act, out, mut extra } = self;
        let gamma = shared.grid.gamma();
        let end = start + act.len();
        // Double-buffered: prefetch across the chunk's end (the grid is only read); in
        // place, not beyond the task: another task may be writing there.
        let prefetch_end = if out.is_some() { shared.table.len() } else { end };
        let mut task = Task {
            grid: shared.grid,
            table: shared.table,
            start,
            end,
            out,
            act,
            waiting: Waiting::default(),
            held: Vec::new(),
        };
        let mut block = PaddedBlock::<R>::new();
        let mut m = [0.0f32; 64];
        for (i, pos) in (start..end).enumerate() {
            let t = task.slot(i);
            let computed = sweep_tile::<L, K, M, _, R>(
                shared,
                &mut block,
                &mut m,
                pos,
                prefetch_end,
                &mut mask[i],
                t,
            )?;
            let mask = mask[i];
            extra.after::<L, R>(TileDone { i, computed, mask, block: &block, m: &m, gamma })?;
            task.after(i, pos, computed);
        }
        Ok(task.finish())
    }
}

/// What a task of a [`TileSweep`] does around each tile's kernel, apart from the
/// kernel's type: compiled once for every kernel.
struct Task<'a, 'c> {
    grid: &'a InPlaceTiles<'a>,
    table: &'a NeighbourTable,
    start: usize,
    end: usize,
    out: Option<&'c mut [Tile]>,
    act: &'c mut [u32],
    /// Computed tiles waiting for their last reader.
    waiting: Waiting,
    /// Computed tiles that another task reads.
    held: Vec<(usize, Tile)>,
}

impl Task<'_, '_> {
    /// Where the kernel writes the task's tile `i`: its entry of `out`, or the ring.
    #[inline(never)]
    fn slot(&mut self, i: usize) -> &mut Tile {
        match self.out.as_deref_mut() {
            Some(o) => &mut o[i],
            None => self.waiting.slot(),
        }
    }

    /// After the kernel of the task's tile `i` (list position `pos`), which wrote its
    /// [`Task::slot`] if `computed`: the activity flags; a tile not computed keeps its
    /// values and flags. In place, the tiles whose readers are all done are written.
    #[inline(never)]
    fn after(&mut self, i: usize, pos: usize, computed: bool) {
        let grid = self.grid;
        if let Some(o) = self.out.as_deref_mut() {
            if computed {
                self.act[i] = compute_activity(&o[i], grid.gamma());
            } else {
                self.act[i] = grid.activity(pos);
                o[i] = Tile(*grid.part(pos));
            }
            return;
        }
        if computed {
            let t = self.waiting.slot();
            self.act[i] = compute_activity(t, grid.gamma());
            // The tiles that read this one: its neighbours and itself.
            let (first, last) = self.table.row(pos).extent(pos);
            if first < self.start || last >= self.end {
                self.held.push((pos, *t));
            } else {
                self.waiting.push(pos, last);
            }
        } else {
            self.act[i] = grid.activity(pos);
        }
        while let Some((p, v)) = self.waiting.pop_until(pos) {
            // SAFETY: every tile that reads `p` is in this task (`first >= start`,
            // `last < end`), so no other task reads it, and all of them up to its
            // last reader (`<= pos`) have been gathered; no later gather reads it.
            unsafe { grid.write(p, v) };
        }
    }

    /// Writes the tiles still waiting (every tile of the task has been computed) and
    /// returns the held ones.
    #[inline(never)]
    fn finish(mut self) -> Vec<(usize, Tile)> {
        while let Some((p, v)) = self.waiting.pop_until(usize::MAX) {
            // SAFETY: as in `after`: every tile of the task has been computed.
            unsafe { self.grid.write(p, v) };
        }
        self.held
    }
}

/// The computed tiles of an in-place sweep's task that wait for their last reader, in
/// list order: a ring that the kernel writes into directly ([`Waiting::slot`]).
#[derive(Default)]
struct Waiting {
    tiles: Vec<Tile>,
    /// Per slot: the tile's list position and that of its last reader.
    meta: Vec<(usize, usize)>,
    head: usize,
    len: usize,
}

impl Waiting {
    /// The free slot after the waiting tiles (the ring grows when full), which
    /// [`Waiting::push`] then commits.
    #[inline(always)]
    fn slot(&mut self) -> &mut Tile {
        if self.len == self.tiles.len() {
            self.grow();
        }
        let cap = self.tiles.len();
        &mut self.tiles[(self.head + self.len) & (cap - 1)]
    }

    /// Commits the slot of [`Waiting::slot`]: the tile at `pos`, read last by `last`.
    #[inline(always)]
    fn push(&mut self, pos: usize, last: usize) {
        let cap = self.tiles.len();
        self.meta[(self.head + self.len) & (cap - 1)] = (pos, last);
        self.len += 1;
    }

    /// The first waiting tile when its last reader is at or before `done`.
    #[inline(always)]
    fn pop_until(&mut self, done: usize) -> Option<(usize, &Tile)> {
        if self.len == 0 || self.meta[self.head].1 > done {
            return None;
        }
        let h = self.head;
        self.head = (h + 1) & (self.tiles.len() - 1);
        self.len -= 1;
        Some((self.meta[h].0, &self.tiles[h]))
    }

    /// Doubles the ring (at least 64 slots), keeping the waiting tiles in order.
    #[cold]
    fn grow(&mut self) {
        let cap = (2 * self.tiles.len()).max(64);
        let mut tiles = Vec::with_capacity(cap);
        let mut meta = Vec::with_capacity(cap);
        let old = self.tiles.len();
        for k in 0..self.len {
            let i = (self.head + k) & (old.max(1) - 1);
            tiles.push(self.tiles[i]);
            meta.push(self.meta[i]);
        }
        tiles.resize(cap, Tile::splat(0.0));
        meta.resize(cap, (0, 0));
        (self.tiles, self.meta, self.head) = (tiles, meta, 0);
    }
}

/// Samples `f` at time `t` at the first `sampled` voxels of the tile at `tc` into `o` (its
/// 64 voxels), row by row; the others (a planar lattice's unread slices) are set to 0.
fn sample_tile(
    f: &dyn ScalarFn,
    spec: &GridSpec,
    tc: Coord,
    t: f64,
    sampled: usize,
    o: &mut [f32],
) {
    let (sampled, unread) = o.split_at_mut(sampled);
    unread.fill(0.0);
    for (row, o) in sampled.chunks_mut(4).enumerate() {
        f.fill_run(spec, voxel_of(tc, 4 * row), t, o);
    }
}

/// The band mask of a tile from its voxels' box minima: bit `i` set iff `m[i] < gamma`.
#[inline(always)]
fn band_bits(m: &[f32; 64], gamma: f32) -> u64 {
    let mut bits = 0u64;
    for (i, &v) in m.iter().enumerate() {
        bits |= u64::from(v < gamma) << i;
    }
    bits
}

/// Minima that compare with `gamma` as the ones `bits` came from ([`band_bits`]): 0 for a
/// set bit (0 < γ), γ for a clear one (not < γ), which is all [`BandMasked`] asks of them.
#[inline(always)]
fn band_minima(bits: u64, gamma: f32, m: &mut [f32; 64]) {
    for (i, v) in m.iter_mut().enumerate() {
        *v = if (bits >> i) & 1 != 0 { 0.0 } else { gamma };
    }
}

/// The κ̄ integrands of the tiles of one chunk, run at the CPU's level.
struct KappaChunk<'a> {
    grid: &'a TileGrid,
    table: &'a NeighbourTable,
    tiles: Range<usize>,
    inv_h: f32,
    width: f32,
}

impl LaneFn for KappaChunk<'_> {
    type Output = Result<(ExactSum, ExactSum), EvolveError>;

    #[inline(always)]
    fn call<L: Lane>(self) -> Self::Output {
        let KappaChunk { grid, table, tiles, inv_h, width } = self;
        let mut block = PaddedBlock::<1>::new();
        let (mut num, mut den) = (ExactSum::default(), ExactSum::default());
        let (mut a, mut b) = ([0.0f32; 64], [0.0f32; 64]);
        for pos in tiles {
            // δ(φ) is 0 wherever |φ| < ε fails (NaN included), and a term δ·x is then ±0
            // or NaN, both of which the exact sums count as 0: a tile with no voxel
            // closer to the interface than ε adds nothing, and is not gathered (with
            // γ = 3 and ε = 1.5 voxels, about a quarter of the spiral's band tiles).
            if !grid.tile(pos).0.iter().fold(false, |any, v| any | (width > v.abs())) {
                continue;
            }
            block.gather_star_row(grid, pos, table.row(pos));
            let tb = TileBlock::<1>::new(block.data())?;
            kappa_tile::<L>(&tb, inv_h, width, &mut a, &mut b);
            num.add_all(&a);
            den.add_all(&b);
        }
        Ok((num, den))
    }
}

/// The κ̄ integrands of one tile (both in one pass over the block).
#[inline(always)]
fn kappa_tile<L: Lane>(
    tb: &TileBlock<1>,
    inv_h: f32,
    width: f32,
    num: &mut [f32; 64],
    den: &mut [f32; 64],
) {
    // A plain loop, not `for_each`: it must inline into the level's function.
    for g in 0..64 / L::LANES {
        let (first, w) = tb.group::<L>(g);
        let (a, b) = kappa_terms(&w, inv_h, width);
        a.store(&mut num[first..]);
        b.store(&mut den[first..]);
    }
}

/// See [`TilesRep::exchange_ghosts`] (a function of the two fields it touches, for
/// callers that borrow others).
fn exchange_ghosts(part: &Option<Box<RankPart>>, grid: &mut TileGrid) {
    if let Some(part) = part {
        part.sync_values(grid);
    }
}

fn tile_flat(t: &[Tile]) -> &[f32] {
    bytemuck::cast_slice(t)
}

impl Representation for TilesRep {
    fn spec(&self) -> GridSpec {
        *self.grid.spec()
    }

    fn flat(&self) -> &[f32] {
        tile_flat(self.grid.values())
    }

    fn fill_scalar(&self, f: &dyn ScalarFn, t: f64, planar: bool, out: &mut [f32]) {
        let spec = self.spec();
        let coords = self.grid.tile_coords();
        // A planar lattice's sweeps read the first z-slice only; the other slices are set
        // to 0.
        let sampled = self.read_slices(planar).map_or(TILE_LEN, |(_, read)| read);
        out.par_chunks_mut(TILE_LEN)
            .zip(coords.par_iter())
            .for_each(|(o, &tc)| sample_tile(f, &spec, tc, t, sampled, o));
    }

    fn read_slices(&self, planar: bool) -> Option<(usize, usize)> {
        planar.then_some((TILE_LEN, SLICE_LEN))
    }

    fn unit_keys(&self) -> &[Coord] {
        self.grid.tile_coords()
    }

    fn fill_vector(&self, f: &dyn VectorFn, t: f64, out: [&mut [f32]; 3]) {
        let spec = self.spec();
        let coords = self.grid.tile_coords();
        let [u, v, w] = out;
        u.par_chunks_mut(64)
            .zip(v.par_chunks_mut(64))
            .zip(w.par_chunks_mut(64))
            .zip(coords.par_iter())
            .for_each(|(((u, v), w), &tc)| f.fill_tile(&spec, voxel_of(tc, 0), t, [u, v, w]));
    }

    fn fill_static_vector(
        &self,
        f: &dyn VectorFn,
        keys: &mut Vec<Coord>,
        prev: [&[f32]; 3],
        out: [&mut [f32]; 3],
    ) -> bool {
        let spec = self.spec();
        let read = self.read_slices(self.planar).map_or(TILE_LEN, |(_, read)| read);
        self.merge_static(read, keys, prev, out, |tc, [u, v, w]| {
            f.fill_tile(&spec, voxel_of(tc, 0), 0.0, [&mut *u, &mut *v, &mut *w]);
            [u, v, w].iter().all(|c| c.iter().all(|x| x.is_finite()))
        })
    }

    fn fill_static_scalar(
        &self,
        f: &dyn ScalarFn,
        planar: bool,
        keys: &mut Vec<Coord>,
        prev: &[f32],
        out: &mut [f32],
        finish: &(dyn Fn(&mut [f32]) -> bool + Sync),
    ) -> bool {
        let spec = self.spec();
        let sampled = self.read_slices(planar).map_or(TILE_LEN, |(_, read)| read);
        self.merge_static(sampled, keys, [prev], [out], |tc, [o]| {
            sample_tile(f, &spec, tc, 0.0, sampled, o);
            finish(&mut o[..sampled])
        })
    }

    fn stage(
        &mut self,
        p: &StageParams,
        scheme: SpatialScheme,
        last: bool,
    ) -> Result<(), EvolveError> {
        let n = self.grid.len();
        debug_assert_eq!(self.table.len(), n, "stale neighbour table");
        let owned = self.owned();
        let planar = p.lattice.is_some_and(|l| l.planar);
        // TVD-RK3 (its later stages read φⁿ whole), and forward Euler on a band within
        // `double_buffer_bytes`: double-buffered. Forward Euler on a larger band: φⁿ
        // packed, the stage written in place.
        let first = p.stage == 1;
        let in_place =
            first && last && !crate::evolve::euler_double_buffered(n, self.double_buffer_bytes);
        if in_place {
            self.keep_step_start();
        }
        self.size_for_sweep(n, !in_place);
        let Buffers { phi_n, out, band, activity, .. } = &mut self.buf;
        let p = StageParams { phi_n: if first { &[] } else { tile_flat(phi_n) }, ..*p };
        let sweep = TileSweep {
            owned,
            grid: self.grid.in_place(),
            table: &self.table,
            lanes: self.lanes,
            band,
            compute_mask: first,
            activity,
            planar,
            out: (!in_place).then_some(&mut out[..]),
            extra: NoExtra,
        };
        dispatch(&p, scheme, sweep)?;
        self.take_sweep(!in_place)?;
        if first && !in_place {
            // `out` and `activity` now hold φⁿ and its flags: kept for the later stages and
            // the renormalisation's sweeps (and for undoing the step).
            std::mem::swap(&mut self.buf.phi_n, &mut self.buf.out);
            std::mem::swap(&mut self.buf.phi_n_activity, &mut self.buf.activity);
            self.undo = TileUndo::PhiN;
        }
        Ok(())
    }

    fn renormalize(&mut self, p: &RenormParams, fresh: bool) -> Result<(), EvolveError> {
        let n = self.grid.len();
        let owned = self.owned();
        // More than one sweep reads the anchors of φ⁰: the first sweep, which evaluates
        // them in place, also stores them (no pass of their own); one sweep stores none.
        let anchored = p.anchored();
        if self.undo == TileUndo::Nothing {
            // At rest: φ⁰ packed for undoing the renormalisation.
            self.keep_step_start();
        }
        for s in 0..p.sweeps {
            debug_assert_eq!(self.table.len(), n, "stale neighbour table");
            // At rest, the first sweep computes the band mask of φ⁰ itself.
            let compute_mask = fresh && s == 0;
            // After stages that keep φⁿ apart, `out` is free: double-buffered.
            // When φⁿ is packed, the sweep writes into the grid behind itself instead of
            // into a second value array (docs/decisions/0033, 0043).
            let double = self.undo == TileUndo::PhiN;
            self.size_for_sweep(n, double);
            let Buffers { out, band, activity, anchor, .. } = &mut self.buf;
            macro_rules! sweep {
                ($extra:expr) => {
                    TileSweep {
                        owned: owned.clone(),
                        grid: self.grid.in_place(),
                        table: &self.table,
                        lanes: self.lanes,
                        band,
                        compute_mask,
                        activity,
                        planar: false,
                        out: double.then_some(&mut out[..]),
                        extra: $extra,
                    }
                };
            }
            if s == 0 && anchored {
                let extra = AnchorExtra { anchors: anchor, h: p.h };
                dispatch_renorm_first(p, sweep!(extra))?;
            } else {
                dispatch_renorm(p, (s > 0).then_some(&**anchor), sweep!(NoExtra))?;
            }
            self.take_sweep(double)?;
        }
        // The anchors live only through a renormalisation: tile management, next, has
        // their memory.
        *self.buf.anchor = PackedTiles::default();
        Ok(())
    }

    fn finish_step(&mut self, budget: &MemoryBudget) -> Result<(), EvolveError> {
        let current = (self.bytes() + self.work_bytes()) as u64;
        // The new list's coordinates and flags are allocated next to the current list's
        // (which a step in progress keeps until it stands); the step buffers grow to the
        // new list in the next step, which admits them before its first stage.
        debug_assert_eq!(self.table.len(), self.grid.len(), "stale neighbour table");
        // The new list's values go into the memory of `out`, which never holds φⁿ of the
        // step in progress (it is empty unless TVD-RK3 allocated it), when it is large
        // enough; the list before the step then keeps no values of its own (φⁿ is put back
        // into it on undo). The table follows the list. Where the spare is too small, the
        // values move within the grid's arena, which grows only past its capacity; the
        // table's rows move within the table.
        let spare = &mut self.buf.out;
        let arena_cap = spare.capacity().max(self.grid.value_capacity());
        let rows_cap = self.table.capacity();
        let growth = |cap: usize, n: usize, size: usize| {
            (if n <= cap { 0 } else { grown_capacity(n) - cap } * size) as u64
        };
        let managed = self.grid.manage_tiles_checked(
            Some(&mut self.table),
            |tiles| {
                let needed = current
                    + growth(arena_cap, tiles, std::mem::size_of::<Tile>())
                    + growth(
                        rows_cap,
                        tiles,
                        std::mem::size_of::<crate::storage::tiles::NeighbourRow>(),
                    )
                    + tiles as u64 * MANAGE_BYTES_PER_TILE;
                budget.admit(needed, current, "the band's tiles")
            },
            spare,
            true,
            self.planar,
        );
        let (_, prev) = match (managed, &self.part) {
            (Ok(m), _) => m,
            (Err(e), None) => return Err(e.into()),
            // The other ranks wait in the hand-over below (`crate::distributed`, "Failures").
            (Err(e), Some(p)) => p.comm.abort(&format!("tile management: {e}")),
        };
        if let Some(prev) = prev {
            // A step in progress keeps the list its φⁿ belongs to.
            if self.undo != TileUndo::Nothing && self.prev.is_none() {
                self.prev = Some(Box::new(prev));
            }
        }
        // Distributed: the ghost slabs become the owners' tiles (this rank's decisions
        // about them missed the neighbours beyond them).
        if let Some(part) = self.part.as_mut() {
            let cuts = part.cuts.clone();
            let grid = part.redistribute(&self.grid, cuts);
            let old = std::mem::replace(&mut self.grid, grid);
            if self.undo != TileUndo::Nothing && self.prev.is_none() {
                self.prev = Some(Box::new(old));
            }
            self.table.rebuild(self.grid.tile_coords());
        }
        Ok(())
    }

    fn for_each_owned_step_start(&self, f: &mut dyn FnMut(&[f32])) {
        // φⁿ is in the order of the list before the step.
        let coords = self.prev.as_ref().map_or(self.grid.tile_coords(), |g| g.tile_coords());
        let owned = self.part.as_ref().map_or(0..coords.len(), |p| p.owned_in(coords));
        match self.undo {
            TileUndo::Nothing => {}
            TileUndo::PhiN => f(tile_flat(&self.buf.phi_n[owned])),
            // The voxels not stored hold ±γ.
            TileUndo::Packed => owned.for_each(|p| f(self.buf.packed.stored_values(p))),
        }
    }

    fn undo_step(&mut self) {
        if self.undo == TileUndo::Nothing {
            debug_assert!(self.prev.is_none(), "a list replaced without a step in progress");
            return;
        }
        let mut values = match self.undo {
            TileUndo::PhiN => std::mem::take(&mut self.buf.phi_n),
            // Unpacked into the memory of the grid's values (the current list's, which
            // tile management grew to hold the list before the step, or the list's own).
            _ => self.grid.take_values(),
        };
        // The values of the list tile management built (with φⁿ whole): kept as the φⁿ
        // buffer of the next step, so that the undone step leaves the memory it found
        // (the list before the step then holds no values of its own).
        let mut managed = Vec::new();
        if let Some(prev) = self.prev.take() {
            managed = self.grid.take_values();
            self.grid = *prev;
            self.table.rebuild(self.grid.tile_coords());
        }
        if self.undo == TileUndo::Packed {
            let packed = std::mem::take(&mut *self.buf.packed);
            resize_exact(&mut values, packed.len(), Tile::splat(0.0));
            packed.unpack(&mut values, self.grid.gamma());
        }
        // φⁿ has one tile per entry of the list it was computed on (restored above).
        self.grid
            .swap_values(&mut values, &mut self.buf.phi_n_activity)
            .expect("φⁿ matches the list before the step");
        if self.undo == TileUndo::PhiN {
            // The buffer stays for the next step.
            self.buf.phi_n = if values.capacity() >= managed.capacity() { values } else { managed };
        }
        self.undo = TileUndo::Nothing;
    }

    fn commit_step(&mut self) {
        self.undo = TileUndo::Nothing;
        self.prev = None;
        *self.buf.packed = PackedTiles::default();
    }

    fn kappa_bar_sums(&self, width: f32) -> Result<(ExactSum, ExactSum), EvolveError> {
        let inv_h = 1.0 / self.grid.spec().voxel_size;
        let table = self.table();
        let owned = self.owned();
        let simd = self.lanes == Lanes::Simd;
        let grid = &self.grid;
        let sums = (0..owned.len().div_ceil(TILE_CHUNK))
            .into_par_iter()
            .map(|c| {
                let start = owned.start + c * TILE_CHUNK;
                let end = (start + TILE_CHUNK).min(owned.end);
                let chunk = KappaChunk { grid, table, tiles: start..end, inv_h, width };
                levelset_kernels::dispatch_default(simd, chunk)
            })
            .collect::<Result<Vec<_>, _>>();
        let sums = match (sums, &self.part) {
            (Ok(s), _) => s,
            (Err(e), None) => return Err(e),
            // The other ranks wait in the reduction below.
            (Err(e), Some(p)) => p.comm.abort(&format!("κ̄ sums: {e}")),
        };
        let (num, den) =
            sums.into_iter().fold((ExactSum::default(), ExactSum::default()), |(a, b), (c, d)| {
                (a.merge(c), b.merge(d))
            });
        Ok(match &self.part {
            Some(p) => {
                let [num, den] = p.comm.sum_exact([num, den]);
                (num, den)
            }
            None => (num, den),
        })
    }

    fn for_each_unstored_inside_run(&self, f: &mut dyn FnMut(Coord, u32)) {
        let owned = self.owned();
        for p in owned.start.max(1)..owned.end {
            self.unstored_inside_runs_before(p, 16, &mut *f);
        }
    }

    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        if self.part.is_none() {
            return crate::storage::levelset::LevelSet::for_each_band_voxel(&self.grid, f);
        }
        crate::storage::levelset::LevelSet::for_each_band_voxel(&self.grid, &mut |c, v| {
            if self.owns_z(c.z >> 2) {
                f(c, v)
            }
        })
    }

    fn any_voxel(&self, f: &mut dyn FnMut(Coord, f32) -> bool) -> bool {
        let owned = self.owned();
        let coords = &self.grid.tile_coords()[owned.clone()];
        self.grid.values()[owned]
            .iter()
            .zip(coords)
            .any(|(t, &tc)| t.0.iter().enumerate().any(|(l, &v)| f(voxel_of(tc, l), v)))
    }

    fn comm(&self) -> Option<&Comm> {
        self.part.as_ref().map(|p| &*p.comm)
    }

    fn owned_flat(&self) -> &[f32] {
        let owned = self.owned();
        tile_flat(&self.grid.values()[owned])
    }

    fn value(&self, c: Coord) -> f32 {
        self.grid.value(c)
    }

    fn units(&self) -> usize {
        self.owned().len()
    }

    fn bytes(&self) -> usize {
        self.grid.memory().used()
    }

    fn work_bytes(&self) -> usize {
        self.grid.memory().slack
            + self.buf.bytes()
            + self.table.bytes()
            + self.prev.as_ref().map_or(0, |p| p.memory().total())
    }

    fn step_bytes(&self, keeps: StepKeeps) -> u64 {
        let tiles = self.grid.len();
        let whole = keeps.whole_phi_n(tiles, self.double_buffer_bytes);
        (self.bytes() + self.work_bytes()) as u64
            + self.buf.growth(tiles, keeps, whole)
            + self.table.growth_bytes(tiles) as u64
    }
}
