//! The tile engine on several ranks: a domain decomposition of the Sorted Tile List.
//!
//! A distributed [`Simulation`](crate::evolve::Simulation) (built by
//! [`Simulation::distributed`](crate::evolve::Simulation::distributed)) runs one part of
//! the band on every rank of a [`Transport`] — MPI processes (`Mpi` of the crate
//! `sparse-levelset-mpi`) or threads of one process ([`LocalRanks`], for tests and experiments). The
//! result is the single-process result bit for bit, for any number of ranks and threads.
//!
//! # Decomposition
//! The tile list is sorted z first ([`crate::coord::Coord`] order), so a range of tile z coordinates (a
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
//!   ([`crate::exact::ExactSum`], associative and commutative), counts.
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
//! transport with `Arc::new(sparse_levelset_mpi::Mpi::init()?)` and runs the closure's body.
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

/// Ghost slabs of tiles on either side of a rank's slabs: one tile (4 voxels) covers the
/// widest stencil (HJ-WENO5's 3 voxels).
pub const GHOST: i32 = 1;

mod cuts;
mod part;
mod transport;

pub use cuts::{balanced_cuts, owner};
pub(crate) use part::{slab_counts, RankPart};
pub(crate) use transport::Comm;
pub use transport::{HaloStats, LocalRanks, SingleRank, Transport};

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
