//! [`Transport`] over MPI (the `mpi` crate, rsmpi, on the system's MPI library), for the
//! distributed simulations of sparse-levelset
//! ([`Simulation::distributed`](sparse_levelset::evolve::Simulation::distributed); the
//! decomposition is described in [`sparse_levelset::distributed`]).
//!
//! Every process `mpirun` starts makes one transport and runs the same calls:
//! ```no_run
//! use sparse_levelset::distributed::Transport;
//! use sparse_levelset_mpi::Mpi;
//! use std::sync::Arc;
//!
//! let transport: Arc<dyn Transport> = Arc::new(Mpi::init()?);
//! println!("rank {} of {}", transport.rank(), transport.size());
//! # Ok::<(), String>(())
//! ```
//! The library does not depend on MPI: this crate is its one MPI transport, kept apart so
//! that the library builds without an MPI library.

use mpi::datatype::{Partition, PartitionMut};
use mpi::environment::Universe;
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::traits::*;
use mpi::Threading;
use sparse_levelset::distributed::Transport;
use std::sync::Mutex;

/// The ranks of `MPI_COMM_WORLD`. MPI is initialised with `MPI_THREAD_SERIALIZED`: a
/// simulation's step runs on a thread of its rayon pool, not always the main one, and
/// every MPI call goes through one lock. Finalised when dropped (drop it on the thread
/// that created it, after the last simulation that uses it).
pub struct Mpi {
    rank: usize,
    size: usize,
    inner: Mutex<Inner>,
}

struct Inner {
    world: SimpleCommunicator,
    /// Dropping it finalises MPI; dropped after `world`.
    _universe: Universe,
}

// SAFETY: MPI is initialised with MPI_THREAD_SERIALIZED (checked in `Mpi::init`), which
// allows calls from any thread as long as no two run at once; `Inner` is reached only
// through `Mpi::inner`'s lock, so its handles are used by one thread at a time.
unsafe impl Send for Inner {}

impl Mpi {
    /// Initialises MPI (once per process). Fails when MPI was initialised already or the
    /// library does not offer `MPI_THREAD_SERIALIZED`.
    pub fn init() -> Result<Mpi, String> {
        let (universe, level) = mpi::initialize_with_threading(Threading::Serialized)
            .ok_or("MPI was initialised already in this process")?;
        if level < Threading::Serialized {
            return Err(format!(
                "the MPI library offers thread level {level:?}; the simulation needs \
                 Serialized (its steps run on worker threads)"
            ));
        }
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        Ok(Mpi { rank, size, inner: Mutex::new(Inner { world, _universe: universe }) })
    }

    fn world<T>(&self, f: impl FnOnce(&SimpleCommunicator) -> T) -> T {
        let inner = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        f(&inner.world)
    }

    /// Counts and displacements (MPI's `int`s) of `lens`, or `None` when they do not fit.
    fn layout(lens: impl Iterator<Item = usize>) -> Option<(Vec<i32>, Vec<i32>, usize)> {
        let (mut counts, mut displs, mut total) = (Vec::new(), Vec::new(), 0usize);
        for l in lens {
            displs.push(i32::try_from(total).ok()?);
            counts.push(i32::try_from(l).ok()?);
            total = total.checked_add(l)?;
        }
        i32::try_from(total).ok()?;
        Some((counts, displs, total))
    }

    /// A buffer of `n` bytes whose address is a real allocation even when `n` is 0: the
    /// empty `Vec`'s dangling address 0x1 is OpenMPI's `MPI_IN_PLACE`.
    fn buffer(mut v: Vec<u8>) -> Vec<u8> {
        if v.capacity() == 0 {
            v.reserve(1);
        }
        v
    }

    fn split(buf: &[u8], counts: &[i32], displs: &[i32]) -> Vec<Vec<u8>> {
        counts
            .iter()
            .zip(displs)
            .map(|(&c, &d)| buf[d as usize..(d + c) as usize].to_vec())
            .collect()
    }
}

impl Transport for Mpi {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn exchange(&self, send: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
        assert_eq!(send.len(), self.size, "one message per rank");
        let Some((scounts, sdispls, _)) = Mpi::layout(send.iter().map(Vec::len)) else {
            self.abort("an exchange of 2 GiB or more (MPI counts are 32-bit)")
        };
        let flat = Mpi::buffer(send.concat());
        self.world(|w| {
            let mut rcounts = vec![0i32; self.size];
            w.all_to_all_into(&scounts[..], &mut rcounts[..]);
            let Some((rcounts, rdispls, total)) =
                Mpi::layout(rcounts.iter().map(|&c| c.max(0) as usize))
            else {
                self.abort("an exchange of 2 GiB or more (MPI counts are 32-bit)")
            };
            let mut recv = Mpi::buffer(vec![0u8; total]);
            {
                let s = Partition::new(&flat[..], &scounts[..], &sdispls[..]);
                let mut r = PartitionMut::new(&mut recv[..], &rcounts[..], &rdispls[..]);
                w.all_to_all_varcount_into(&s, &mut r);
            }
            Mpi::split(&recv, &rcounts, &rdispls)
        })
    }

    fn all_gather(&self, data: &[u8]) -> Vec<Vec<u8>> {
        let Ok(n) = i32::try_from(data.len()) else {
            self.abort("a reduction of 2 GiB or more (MPI counts are 32-bit)")
        };
        self.world(|w| {
            let mut lens = vec![0i32; self.size];
            w.all_gather_into(&n, &mut lens[..]);
            let Some((counts, displs, total)) =
                Mpi::layout(lens.iter().map(|&c| c.max(0) as usize))
            else {
                self.abort("a reduction of 2 GiB or more (MPI counts are 32-bit)")
            };
            let mut recv = Mpi::buffer(vec![0u8; total]);
            let data = Mpi::buffer(data.to_vec());
            {
                let mut r = PartitionMut::new(&mut recv[..], &counts[..], &displs[..]);
                w.all_gather_varcount_into(&data[..], &mut r);
            }
            Mpi::split(&recv, &counts, &displs)
        })
    }

    fn abort(&self, message: &str) -> ! {
        eprintln!("rank {} of {}: {message}; aborting the job", self.rank, self.size);
        // The lock may be held by this very thread (an abort inside an exchange): use a
        // fresh handle of the world communicator instead.
        SimpleCommunicator::world().abort(1)
    }
}
