//! A rank's part of the decomposition ([`RankPart`]): its cuts, the exchange plan of its
//! tile list, and the tile records of a hand-over.

use super::balanced_cuts;
use super::cuts::{stored_by, stored_z, z_range};
use super::transport::Comm;
use crate::coord::Coord;
use crate::storage::tiles::{Tile, TileGrid};
use std::ops::Range;
use std::sync::Arc;

/// Bytes of one tile in a hand-over: coordinate, border and activity flags, 64 values.
pub(super) const TILE_RECORD: usize = 12 + 4 + 4 + std::mem::size_of::<Tile>();

/// A rank's part of the decomposition: its cuts and the exchange plan of its current
/// tile list.
///
/// # Invariants
/// * `owned`, `send` and `recv` are positions of the current list of the rank's grid
///   (rebuilt with every hand-over);
/// * the ghost positions `recv[s]` of this rank hold, in list order, the tiles that rank
///   `s` sends from its `send[this rank]`.
#[derive(Clone)]
pub(crate) struct RankPart {
    pub comm: Arc<Comm>,
    pub cuts: Vec<i32>,
    /// The list positions of the tiles this rank owns.
    pub owned: Range<usize>,
    /// `send[d]`: the owned positions rank `d` holds as ghosts (empty for this rank).
    send: Vec<Range<usize>>,
    /// `recv[s]`: the ghost positions rank `s` owns (empty for this rank).
    recv: Vec<Range<usize>>,
    /// Rebalance when the largest rank holds more than (1 + this) × the smallest rank's
    /// tiles (`None`: never).
    pub rebalance: Option<f64>,
}

impl RankPart {
    /// The part of `grid` (the whole band, the same on every rank) that rank
    /// `comm.rank()` stores under cuts that balance its tiles.
    pub fn split(
        comm: Arc<Comm>,
        grid: &TileGrid,
        rebalance: Option<f64>,
    ) -> Result<(RankPart, TileGrid), crate::GridError> {
        let cuts = balanced_cuts(&slab_counts(grid.tile_coords(), 0..grid.len()), comm.size());
        let (lo, hi) = stored_z(&cuts, comm.rank());
        let r = z_range(grid.tile_coords(), lo, hi);
        let local = grid.sub_list(r)?;
        let part = RankPart::plan(comm, cuts, &local, rebalance);
        Ok((part, local))
    }

    /// The exchange plan of `grid` (this rank's list) under `cuts`.
    fn plan(comm: Arc<Comm>, cuts: Vec<i32>, grid: &TileGrid, rebalance: Option<f64>) -> Self {
        let (me, n) = (comm.rank(), comm.size());
        let coords = grid.tile_coords();
        let owned = z_range(coords, cuts[me], cuts[me + 1]);
        let mut send = vec![0..0; n];
        let mut recv = vec![0..0; n];
        for r in (0..n).filter(|&r| r != me) {
            send[r] = stored_by(coords, &owned, &cuts, r);
            recv[r] = z_range(coords, cuts[r], cuts[r + 1]);
        }
        RankPart { comm, cuts, owned, send, recv, rebalance }
    }

    /// The tile z range `[lo, hi)` this rank owns.
    pub fn owned_z(&self) -> (i32, i32) {
        let r = self.comm.rank();
        (self.cuts[r], self.cuts[r + 1])
    }

    /// The positions of the tiles this rank owns in a list of its (`coords`, sorted):
    /// `owned` for the current list, or the list before a step.
    pub fn owned_in(&self, coords: &[Coord]) -> Range<usize> {
        let (lo, hi) = self.owned_z();
        z_range(coords, lo, hi)
    }

    /// Gives the ghost tiles of `grid` their owners' current values and activity flags.
    pub fn sync_values(&self, grid: &mut TileGrid) {
        const PER: usize = std::mem::size_of::<Tile>() + 4;
        let send = self
            .send
            .iter()
            .map(|r| {
                let mut m = Vec::with_capacity(r.len() * PER);
                for p in r.clone() {
                    m.extend_from_slice(bytemuck::bytes_of(grid.tile(p)));
                    m.extend_from_slice(&grid.activity_flags(p).to_le_bytes());
                }
                m
            })
            .collect();
        let recv = self.comm.exchange(send);
        let (tiles, flags) = grid.values_activity_mut();
        for (s, (m, r)) in recv.iter().zip(&self.recv).enumerate() {
            if m.len() != r.len() * PER {
                self.comm.abort(&format!(
                    "ghost exchange: rank {s} sent {} bytes for {} ghost tiles",
                    m.len(),
                    r.len()
                ));
            }
            for (p, rec) in r.clone().zip(m.chunks_exact(PER)) {
                let (t, a) = rec.split_at(std::mem::size_of::<Tile>());
                tiles[p] = bytemuck::pod_read_unaligned(t);
                flags[p] = u32::from_le_bytes(a.try_into().expect("4 bytes"));
            }
        }
    }

    /// The list this rank stores under `cuts` (the current ones for the hand-over after
    /// tile management, new ones to rebalance): every rank sends the tiles it owns to the
    /// ranks that store them under `cuts`, whole (coordinates, flags, values). The plan
    /// is rebuilt for the returned list.
    pub fn redistribute(&mut self, grid: &TileGrid, cuts: Vec<i32>) -> TileGrid {
        let (me, n) = (self.comm.rank(), self.comm.size());
        let coords = grid.tile_coords();
        let owned = self.owned_in(coords);
        let ranges: Vec<Range<usize>> =
            (0..n).map(|d| stored_by(coords, &owned, &cuts, d)).collect();
        let moved = self.cuts != cuts;
        let send: Vec<Vec<u8>> = ranges
            .iter()
            .enumerate()
            .map(|(d, r)| if d == me { Vec::new() } else { pack_tiles(grid, r.clone()) })
            .collect();
        if moved {
            let sent: u64 = (0..n).filter(|&d| d != me).map(|d| ranges[d].len() as u64).sum();
            self.comm.record(|st| {
                st.rebalances += 1;
                st.tiles_moved += sent;
            });
        }
        let recv = self.comm.exchange(send);
        let total: usize = (0..n)
            .map(|s| if s == me { ranges[me].len() } else { recv[s].len() / TILE_RECORD })
            .sum();
        let mut parts = TileParts::with_capacity(total);
        for (s, m) in recv.iter().enumerate() {
            if s == me {
                parts.extend_from(grid, ranges[me].clone());
            } else if let Err(e) = parts.unpack(m) {
                self.comm.abort(&format!("tile hand-over from rank {s}: {e}"));
            }
        }
        let local = match parts.into_grid(*grid.spec()) {
            Ok(g) => g,
            Err(e) => self.comm.abort(&format!("tile hand-over: {e}")),
        };
        *self = RankPart::plan(self.comm.clone(), cuts, &local, self.rebalance);
        local
    }
}

/// (tile z, tiles) of every non-empty slab among `coords[range]`, sorted by z.
pub(crate) fn slab_counts(coords: &[Coord], range: Range<usize>) -> Vec<(i32, u64)> {
    let mut out: Vec<(i32, u64)> = Vec::new();
    for c in &coords[range] {
        match out.last_mut() {
            Some((z, n)) if *z == c.z => *n += 1,
            _ => out.push((c.z, 1)),
        }
    }
    out
}

/// The records of the tiles at `range` of `grid` ([`TILE_RECORD`] bytes each).
pub(super) fn pack_tiles(grid: &TileGrid, range: Range<usize>) -> Vec<u8> {
    let mut m = Vec::with_capacity(range.len() * TILE_RECORD);
    let coords = grid.tile_coords();
    for p in range {
        let c = coords[p];
        for v in [c.x, c.y, c.z] {
            m.extend_from_slice(&v.to_le_bytes());
        }
        m.extend_from_slice(&grid.border_flags(p).to_le_bytes());
        m.extend_from_slice(&grid.activity_flags(p).to_le_bytes());
        m.extend_from_slice(bytemuck::bytes_of(grid.tile(p)));
    }
    m
}

/// A tile list assembled in list order from parts.
pub(super) struct TileParts {
    coords: Vec<Coord>,
    tiles: Vec<Tile>,
    border: Vec<u32>,
    activity: Vec<u32>,
}

impl TileParts {
    fn with_capacity(n: usize) -> TileParts {
        TileParts {
            coords: Vec::with_capacity(n),
            tiles: Vec::with_capacity(n),
            border: Vec::with_capacity(n),
            activity: Vec::with_capacity(n),
        }
    }

    fn extend_from(&mut self, grid: &TileGrid, r: Range<usize>) {
        self.coords.extend_from_slice(&grid.tile_coords()[r.clone()]);
        self.tiles.extend_from_slice(&grid.values()[r.clone()]);
        self.border.extend(r.clone().map(|p| grid.border_flags(p)));
        self.activity.extend(r.map(|p| grid.activity_flags(p)));
    }

    fn unpack(&mut self, m: &[u8]) -> Result<(), String> {
        if !m.len().is_multiple_of(TILE_RECORD) {
            return Err(format!("{} bytes is not a whole number of tiles", m.len()));
        }
        let word = |b: &[u8], i: usize| u32::from_le_bytes(b[4 * i..4 * i + 4].try_into().unwrap());
        for rec in m.chunks_exact(TILE_RECORD) {
            let c = Coord::new(word(rec, 0) as i32, word(rec, 1) as i32, word(rec, 2) as i32);
            self.coords.push(c);
            self.border.push(word(rec, 3));
            self.activity.push(word(rec, 4));
            self.tiles.push(bytemuck::pod_read_unaligned(&rec[20..]));
        }
        Ok(())
    }

    fn into_grid(self, spec: crate::GridSpec) -> Result<TileGrid, String> {
        TileGrid::from_parts(spec, self.coords, self.tiles, self.border, self.activity)
            .map_err(|e| e.to_string())
    }
}
