//! The tile engine on several ranks: a domain decomposition of the Sorted Tile List.
//!
//! A distributed [`Simulation`](crate::evolve::Simulation) (built by
//! [`Simulation::distributed`](crate::evolve::Simulation::distributed)) runs one part of
//! the band on every rank of a [`Transport`] — MPI processes (`Mpi`, cargo feature
//! `mpi`) or threads of one process ([`LocalRanks`], for tests and experiments). The
//! result is the single-process result bit for bit, for any number of ranks and threads.
//!
//! # Decomposition
//! The tile list is sorted z first ([`Coord`] order), so a range of tile z coordinates (a
//! stack of whole z-slabs of tiles) is a contiguous range of the list. Rank `r` owns the
//! slabs `cuts[r] ≤ tz < cuts[r + 1]`; the cuts are placed where the tile counts balance
//! ([`balanced_cuts`]). Each rank stores its slabs and one ghost slab on either side
//! ([`GHOST`]): a kernel reaches at most 3 voxels, less than a tile, so one slab of tiles
//! is the widest stencil's halo.
//!
//! # One step
//! * **After every sweep** (each RK stage, each renormalisation pass) the ghost tiles
//!   receive their owners' new values and activity flags, which the next sweep, the κ̄
//!   sums and tile management read. The sweep computes only the rank's own tiles; the
//!   ghosts keep their values until the exchange replaces them.
//! * **Tile management** (Algorithm 3) decides for each tile from its own and its 26
//!   neighbours' activity flags, and gives a new tile the sign its neighbours' border
//!   flags hold towards it. With the ghosts' values and activity flags exact, every
//!   decision about an owned tile sees what the single-process run sees: owned tiles are
//!   kept, removed and created as there, including the tiles a neighbour's band creates
//!   across a cut (each rank creates the tiles of its own slabs, triggered by the ghost
//!   slab that holds its neighbour's band). Decisions about ghost tiles miss the
//!   neighbours beyond them and are discarded: every rank then hands the tiles of its
//!   slabs that its neighbours hold as ghosts (coordinates, values, border and activity
//!   flags) to them, which replace their ghost slabs.
//! * **Reductions** combine each rank's exact partial results: maxima for Δt, the
//!   fixed-point sums of κ̄, volume, area and the collapse test
//!   ([`ExactSum`], associative and commutative), counts.
//!   Each rank sums over the tiles it owns only.
//! * **Rebalancing**: after a step, when the largest rank holds more than
//!   (1 + threshold) × the smallest rank's tiles, new cuts are computed from the tile
//!   count of every slab and the tiles move to their new owners (one exchange, the same
//!   as the ghost hand-over with other cuts).
//!
//! Every rank calls the simulation's methods in the same order: steps, measures, the
//! checksum and the band counts are collective. A rank's
//! [`for_each_band_voxel`](crate::evolve::Simulation::for_each_band_voxel) visits its own
//! part of the band.
//!
//! # Example
//! Two ranks as threads of this process; with MPI, every process of `mpirun` makes its
//! transport with `Arc::new(Mpi::init()?)` (feature `mpi`) and runs the closure's body.
//! ```
//! use sparse_levelset::storage::convert::tiles_from_shape;
//! use sparse_levelset::distributed::LocalRanks;
//! use sparse_levelset::evolve::{Flow, GridKind, Lanes, Settings, Simulation};
//! use sparse_levelset::{grid::GridSpec, storage::shapes::Shape};
//! use std::sync::Arc;
//!
//! let shape = Shape::Sphere { center: [0.0; 3], radius: 12.0 };
//! let spec = GridSpec::default();
//! let flow = Flow::mean_curvature(1.0);
//! let checksums = LocalRanks::run(2, |transport| {
//!     let tiles = tiles_from_shape(&shape, spec).unwrap();
//!     // A pool per rank: a rank waiting in an exchange holds its thread.
//!     let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
//!     let settings = Settings { pool: Some(Arc::new(pool)), ..Settings::default() };
//!     let rebalance = Some(0.1);
//!     let mut sim =
//!         Simulation::distributed(transport, tiles, Lanes::Simd, flow.clone(), settings, rebalance)
//!             .unwrap();
//!     for _ in 0..5 {
//!         sim.step().unwrap();
//!     }
//!     sim.checksum() // collective: the whole band's
//! });
//! let kind = GridKind::Tiles(Lanes::Simd);
//! let mut one = Simulation::from_shape(kind, &shape, spec, flow, Settings::default()).unwrap();
//! for _ in 0..5 {
//!     one.step().unwrap();
//! }
//! assert_eq!(checksums, vec![one.checksum(); 2]);
//! ```
//!
//! # Failures
//! What can fail before a step changes anything (the memory budget of the step's
//! buffers, stage 1's speeds, a fixed Δt against the CFL limit) is agreed on by all
//! ranks: every rank returns an error and keeps its state. A failure inside a step on one
//! rank (a later stage's non-finite speed, growth past the coordinate range or the memory
//! budget in tile management) cannot be undone on the other ranks, which are waiting in
//! the step's exchanges: the job is aborted ([`Transport::abort`]) with the message.

#[cfg(feature = "mpi")]
mod mpi;
#[cfg(feature = "mpi")]
pub use self::mpi::Mpi;

use crate::coord::Coord;
use crate::exact::ExactSum;
use crate::storage::tiles::{Tile, TileGrid};
use serde::Serialize;
use std::ops::Range;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Ghost slabs of tiles on either side of a rank's slabs: one tile (4 voxels) covers the
/// widest stencil (HJ-WENO5's 3 voxels).
pub const GHOST: i32 = 1;

/// How ranks talk: the few collective operations the decomposition needs. Every rank
/// calls them in the same order.
///
/// Implementations: `Mpi` (feature `mpi`), [`LocalRanks`] (threads of one process) and
/// [`SingleRank`].
pub trait Transport: Send + Sync {
    /// This rank, `0..size()`.
    fn rank(&self) -> usize;
    /// The number of ranks.
    fn size(&self) -> usize;
    /// Sends `send[d]` to every rank `d` (one entry per rank, empty for nothing) and
    /// returns what every rank sent to this one (`recv[s]` from rank `s`). Collective.
    fn exchange(&self, send: Vec<Vec<u8>>) -> Vec<Vec<u8>>;
    /// Every rank's `data`, in rank order. Collective.
    fn all_gather(&self, data: &[u8]) -> Vec<Vec<u8>>;
    /// Ends the whole job with `message` (a failure that the other ranks cannot undo).
    fn abort(&self, message: &str) -> !;
}

impl std::fmt::Debug for dyn Transport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Transport {{ rank: {}, size: {} }}", self.rank(), self.size())
    }
}

/// One rank: the transport of a process that is not distributed.
#[derive(Clone, Copy, Debug, Default)]
pub struct SingleRank;

impl Transport for SingleRank {
    fn rank(&self) -> usize {
        0
    }
    fn size(&self) -> usize {
        1
    }
    fn exchange(&self, send: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
        send
    }
    fn all_gather(&self, data: &[u8]) -> Vec<Vec<u8>> {
        vec![data.to_vec()]
    }
    fn abort(&self, message: &str) -> ! {
        panic!("{message}")
    }
}

/// Ranks as threads of one process, joined by channels (one per ordered pair of ranks, so
/// the messages of consecutive collectives never mix): the decomposition tested and
/// measured without an MPI installation. Each rank should run its simulation in a thread
/// pool of its own ([`crate::evolve::Settings::pool`]): a rank waiting in a collective
/// holds its thread.
pub struct LocalRanks {
    rank: usize,
    /// `to[d]`: the channel from this rank to rank `d`.
    to: Vec<Sender<Vec<u8>>>,
    /// `from[s]`: the channel from rank `s` to this rank.
    from: Vec<Mutex<Receiver<Vec<u8>>>>,
}

impl LocalRanks {
    /// Runs `f` on `n` ranks, each on a thread of its own with its transport, and returns
    /// the results in rank order. A panic on any rank is re-raised (the others, waiting
    /// for it, see their channels close and panic too).
    pub fn run<T: Send>(n: usize, f: impl Fn(Arc<dyn Transport>) -> T + Sync) -> Vec<T> {
        assert!(n > 0, "at least one rank");
        let mut to: Vec<Vec<Sender<Vec<u8>>>> = (0..n).map(|_| Vec::with_capacity(n)).collect();
        let mut from: Vec<Vec<Mutex<Receiver<Vec<u8>>>>> =
            (0..n).map(|_| Vec::with_capacity(n)).collect();
        for to_s in to.iter_mut() {
            for from_d in from.iter_mut() {
                let (tx, rx) = channel();
                to_s.push(tx);
                from_d.push(Mutex::new(rx));
            }
        }
        let ranks: Vec<LocalRanks> = to
            .into_iter()
            .zip(from)
            .enumerate()
            .map(|(rank, (to, from))| LocalRanks { rank, to, from })
            .collect();
        let f = &f;
        std::thread::scope(|s| {
            let handles: Vec<_> = ranks
                .into_iter()
                .map(|r| s.spawn(move || f(Arc::new(r) as Arc<dyn Transport>)))
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
                .collect()
        })
    }

    fn recv(&self, s: usize) -> Vec<u8> {
        let rx = self.from[s].lock().unwrap_or_else(|e| e.into_inner());
        rx.recv().unwrap_or_else(|_| panic!("rank {s} ended while rank {} waited", self.rank))
    }
}

impl Transport for LocalRanks {
    fn rank(&self) -> usize {
        self.rank
    }
    fn size(&self) -> usize {
        self.to.len()
    }
    fn exchange(&self, send: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
        assert_eq!(send.len(), self.size(), "one message per rank");
        for (tx, m) in self.to.iter().zip(send) {
            // A closed channel means the receiving rank ended; `recv` reports it there.
            let _ = tx.send(m);
        }
        (0..self.size()).map(|s| self.recv(s)).collect()
    }
    fn all_gather(&self, data: &[u8]) -> Vec<Vec<u8>> {
        self.exchange(vec![data.to_vec(); self.size()])
    }
    fn abort(&self, message: &str) -> ! {
        panic!("rank {}: {message}", self.rank)
    }
}

/// What a rank sent and waited for, cumulative over a run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct HaloStats {
    /// Ghost exchanges (value exchanges before sweeps, hand-overs after tile management,
    /// rebalancing moves).
    pub exchanges: u64,
    /// Non-empty messages this rank sent to other ranks in them.
    pub messages: u64,
    /// Bytes this rank sent to other ranks in them.
    pub bytes: u64,
    /// Seconds spent in them (packing, transfer, waiting for the other ranks, unpacking).
    pub seconds: f64,
    /// Reductions (Δt maxima, exact sums, votes) and their seconds (mostly waiting for the
    /// slowest rank).
    pub reductions: u64,
    pub reduction_seconds: f64,
    /// Rebalancing moves, and the tiles this rank sent to new owners in them.
    pub rebalances: u64,
    pub tiles_moved: u64,
}

impl HaloStats {
    /// The eight fields as little-endian words (floats as their bits).
    pub(crate) fn to_bytes(self) -> Vec<u8> {
        [
            self.exchanges,
            self.messages,
            self.bytes,
            self.seconds.to_bits(),
            self.reductions,
            self.reduction_seconds.to_bits(),
            self.rebalances,
            self.tiles_moved,
        ]
        .iter()
        .flat_map(|w| w.to_le_bytes())
        .collect()
    }

    /// The statistics [`HaloStats::to_bytes`] wrote (`None` for another length).
    pub(crate) fn from_bytes(b: &[u8]) -> Option<HaloStats> {
        if b.len() != 64 {
            return None;
        }
        let w = |i: usize| u64::from_le_bytes(b[8 * i..8 * i + 8].try_into().expect("8 bytes"));
        Some(HaloStats {
            exchanges: w(0),
            messages: w(1),
            bytes: w(2),
            seconds: f64::from_bits(w(3)),
            reductions: w(4),
            reduction_seconds: f64::from_bits(w(5)),
            rebalances: w(6),
            tiles_moved: w(7),
        })
    }
}

/// A rank's transport with its statistics.
pub(crate) struct Comm {
    t: Arc<dyn Transport>,
    stats: Mutex<HaloStats>,
}

impl Comm {
    pub fn new(t: Arc<dyn Transport>) -> Comm {
        Comm { t, stats: Mutex::new(HaloStats::default()) }
    }

    pub fn rank(&self) -> usize {
        self.t.rank()
    }

    pub fn size(&self) -> usize {
        self.t.size()
    }

    pub fn stats(&self) -> HaloStats {
        *self.stats.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn record(&self, f: impl FnOnce(&mut HaloStats)) {
        f(&mut self.stats.lock().unwrap_or_else(|e| e.into_inner()))
    }

    pub fn abort(&self, message: &str) -> ! {
        self.t.abort(message)
    }

    /// A ghost exchange, counted in the statistics.
    fn exchange(&self, send: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
        let me = self.rank();
        let (messages, bytes) = send
            .iter()
            .enumerate()
            .filter(|(d, m)| *d != me && !m.is_empty())
            .fold((0, 0), |(n, b), (_, m)| (n + 1, b + m.len() as u64));
        let t = Instant::now();
        let recv = self.t.exchange(send);
        let s = t.elapsed().as_secs_f64();
        self.record(|st| {
            st.exchanges += 1;
            st.messages += messages;
            st.bytes += bytes;
            st.seconds += s;
        });
        recv
    }

    /// Every rank's `data` (a reduction's operands).
    pub fn gather(&self, data: &[u8]) -> Vec<Vec<u8>> {
        let t = Instant::now();
        let all = self.t.all_gather(data);
        let s = t.elapsed().as_secs_f64();
        self.record(|st| {
            st.reductions += 1;
            st.reduction_seconds += s;
        });
        all
    }

    /// Element-wise maxima over the ranks (values are finite or +∞).
    pub fn max_f32<const N: usize>(&self, v: [f32; N]) -> [f32; N] {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let mut out = v;
        for other in self.gather(&bytes) {
            for (o, c) in out.iter_mut().zip(other.chunks_exact(4)) {
                *o = o.max(f32::from_le_bytes(c.try_into().expect("4 bytes")));
            }
        }
        out
    }

    /// Element-wise sums over the ranks; exact, so independent of the number of ranks.
    pub fn sum_exact<const N: usize>(&self, v: [ExactSum; N]) -> [ExactSum; N] {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_bits().to_le_bytes()).collect();
        let mut out = [ExactSum::default(); N];
        for other in self.gather(&bytes) {
            for (o, c) in out.iter_mut().zip(other.chunks_exact(16)) {
                let x = i128::from_le_bytes(c.try_into().expect("16 bytes"));
                *o = o.merge(ExactSum::from_bits(x));
            }
        }
        out
    }

    /// Element-wise sums of counts over the ranks.
    pub fn sum_u64<const N: usize>(&self, v: [u64; N]) -> [u64; N] {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let mut out = [0u64; N];
        for other in self.gather(&bytes) {
            for (o, c) in out.iter_mut().zip(other.chunks_exact(8)) {
                *o += u64::from_le_bytes(c.try_into().expect("8 bytes"));
            }
        }
        out
    }

    /// Whether `b` holds on some rank.
    pub fn any(&self, b: bool) -> bool {
        self.gather(&[b as u8]).iter().any(|m| m.first() == Some(&1))
    }

    /// Every rank's count, in rank order.
    pub fn counts(&self, n: u64) -> Vec<u64> {
        self.gather(&n.to_le_bytes())
            .iter()
            .map(|m| u64::from_le_bytes(m[..8].try_into().expect("8 bytes")))
            .collect()
    }

    /// The first failure over the ranks, in rank order: `Ok` on every rank when all
    /// succeeded; otherwise the failing rank keeps its own error and the others get
    /// `(rank, message)` of the first that failed.
    pub fn agree<T, E: std::fmt::Display>(
        &self,
        r: Result<T, E>,
    ) -> Result<Result<T, E>, (usize, String)> {
        let msg = match &r {
            Ok(_) => Vec::new(),
            Err(e) => {
                let mut m = vec![1u8];
                m.extend_from_slice(e.to_string().as_bytes());
                m
            }
        };
        let all = self.gather(&msg);
        if r.is_err() {
            return Ok(r);
        }
        match all.iter().enumerate().find(|(_, m)| !m.is_empty()) {
            Some((rank, m)) => Err((rank, String::from_utf8_lossy(&m[1..]).into_owned())),
            None => Ok(r),
        }
    }

    /// Runs `f(rank)` on every rank in turn, passing a running state from rank to rank:
    /// what rank r returns is the state rank r + 1 starts from (a sequential fold over the
    /// ranks' parts, such as a hash of the band in [`Coord`] order). Returns the state
    /// after the last rank, on every rank.
    pub fn chain(&self, mut state: u64, mut f: impl FnMut(u64) -> u64) -> u64 {
        for r in 0..self.size() {
            let mine = if r == self.rank() { f(state) } else { 0 };
            let all = self.gather(&mine.to_le_bytes());
            state = u64::from_le_bytes(all[r][..8].try_into().expect("8 bytes"));
        }
        state
    }
}

/// Cuts that balance the tile counts: `slabs` lists (tile z, tiles) for every non-empty
/// slab, sorted by z. Rank r gets the slabs `cuts[r] ≤ tz < cuts[r + 1]`; `cuts[0]` is
/// `i32::MIN` and `cuts[ranks]` is `i32::MAX`, so every slab has an owner. Each inner cut
/// sits at the slab boundary whose prefix count is nearest to r/ranks of the total (the
/// first such boundary, and never before the previous cut).
pub fn balanced_cuts(slabs: &[(i32, u64)], ranks: usize) -> Vec<i32> {
    assert!(ranks > 0, "at least one rank");
    let total: u64 = slabs.iter().map(|s| s.1).sum();
    // prefix[i]: tiles in slabs[..i].
    let mut prefix = Vec::with_capacity(slabs.len() + 1);
    prefix.push(0u64);
    for s in slabs {
        prefix.push(prefix.last().copied().unwrap_or(0) + s.1);
    }
    let mut cuts = vec![i32::MIN; ranks + 1];
    cuts[ranks] = i32::MAX;
    let mut i = 0;
    for (r, cut) in cuts.iter_mut().enumerate().take(ranks).skip(1) {
        let target = total as u128 * r as u128;
        // |ranks · prefix[i] − total · r|, compared without division.
        let dev = |i: usize| (prefix[i] as u128 * ranks as u128).abs_diff(target);
        while i < slabs.len() && dev(i + 1) < dev(i) {
            i += 1;
        }
        *cut = if i < slabs.len() {
            slabs[i].0
        } else {
            slabs.last().map_or(i32::MIN, |s| s.0.saturating_add(1))
        };
    }
    cuts
}

/// The rank that owns tile z `tz` under `cuts`.
pub fn owner(cuts: &[i32], tz: i32) -> usize {
    cuts.partition_point(|&c| c <= tz).saturating_sub(1).min(cuts.len() - 2)
}

/// The tile z range `[lo, hi)` rank `r` stores under `cuts`: its slabs and [`GHOST`]
/// slabs on either side.
fn stored_z(cuts: &[i32], r: usize) -> (i32, i32) {
    (cuts[r].saturating_sub(GHOST), cuts[r + 1].saturating_add(GHOST))
}

/// The positions of `coords` (sorted) with tile z in `[lo, hi)`.
fn z_range(coords: &[Coord], lo: i32, hi: i32) -> Range<usize> {
    coords.partition_point(|c| c.z < lo)..coords.partition_point(|c| c.z < hi)
}

/// The positions of `owned` (a rank's own tiles in its list `coords`) that rank `d`
/// stores under `cuts`: what this rank sends it.
fn stored_by(coords: &[Coord], owned: &Range<usize>, cuts: &[i32], d: usize) -> Range<usize> {
    let (lo, hi) = stored_z(cuts, d);
    let s = z_range(&coords[owned.clone()], lo, hi);
    owned.start + s.start..owned.start + s.end
}

/// Bytes of one tile in a hand-over: coordinate, border and activity flags, 64 values.
const TILE_RECORD: usize = 12 + 4 + 4 + std::mem::size_of::<Tile>();

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
fn pack_tiles(grid: &TileGrid, range: Range<usize>) -> Vec<u8> {
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
struct TileParts {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cuts_balance_and_cover_every_slab() {
        let slabs: Vec<(i32, u64)> = (0..10).map(|z| (z, 10)).collect();
        let cuts = balanced_cuts(&slabs, 2);
        assert_eq!(cuts, vec![i32::MIN, 5, i32::MAX]);
        let cuts = balanced_cuts(&slabs, 3);
        assert_eq!(cuts, vec![i32::MIN, 3, 7, i32::MAX]);
        assert_eq!(owner(&cuts, -100), 0);
        assert_eq!(owner(&cuts, 3), 1);
        assert_eq!(owner(&cuts, 7), 2);
        assert_eq!(owner(&cuts, i32::MAX - 1), 2);
        // More ranks than slabs: some ranks own nothing, cuts never decrease.
        let cuts = balanced_cuts(&[(4, 5)], 3);
        assert!(cuts.windows(2).all(|w| w[0] <= w[1]), "{cuts:?}");
        assert_eq!(balanced_cuts(&[], 2), vec![i32::MIN, i32::MIN, i32::MAX]);
        // Uneven slabs: the cut lands where the prefix is nearest half.
        let cuts = balanced_cuts(&[(0, 1), (1, 1), (2, 10), (3, 1)], 2);
        assert_eq!(cuts[1], 2);
    }

    #[test]
    fn local_ranks_exchange_and_reduce() {
        let out = LocalRanks::run(3, |t| {
            let c = Comm::new(t.clone());
            let me = t.rank();
            let recv = t.exchange((0..3).map(|d| vec![me as u8, d as u8]).collect());
            for (s, m) in recv.iter().enumerate() {
                assert_eq!(m, &vec![s as u8, me as u8]);
            }
            let m = c.max_f32([me as f32, -(me as f32)]);
            let s = c.sum_u64([me as u64 + 1]);
            let h = c.chain(0, |h| h * 10 + me as u64 + 1);
            let agreed = c.agree(if me == 1 { Err("bad") } else { Ok(()) });
            (m, s, h, agreed.map(|r| r.is_err()))
        });
        for (rank, (m, s, h, agreed)) in out.into_iter().enumerate() {
            assert_eq!(m, [2.0, 0.0]);
            assert_eq!(s, [6]);
            assert_eq!(h, 123);
            match rank {
                1 => assert_eq!(agreed, Ok(true)),
                _ => assert_eq!(agreed, Err((1, "bad".to_string()))),
            }
        }
    }
}
