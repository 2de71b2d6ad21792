//! How ranks talk ([`Transport`]): one rank, ranks as threads ([`LocalRanks`]), and the
//! statistics of what a rank sent and waited for ([`HaloStats`]).

use crate::exact::ExactSum;
use serde::Serialize;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// How ranks talk: the few collective operations the decomposition needs. Every rank
/// calls them in the same order.
///
/// Implementations: `Mpi` (crate `sparse-levelset-mpi`), [`LocalRanks`] (threads of one process) and
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

    pub(super) fn record(&self, f: impl FnOnce(&mut HaloStats)) {
        f(&mut self.stats.lock().unwrap_or_else(|e| e.into_inner()))
    }

    pub fn abort(&self, message: &str) -> ! {
        self.t.abort(message)
    }

    /// A ghost exchange, counted in the statistics.
    pub(super) fn exchange(&self, send: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
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
