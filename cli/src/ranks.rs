//! The ranks a command runs on: the MPI ranks when `mpirun` (or another MPI launcher)
//! started the process and the binary was built with the `mpi` feature, one otherwise.

use sparse_levelset::distributed::Transport;
use std::sync::Arc;

/// The number of ranks an MPI launcher started, from the variables OpenMPI, MPICH and
/// PMIx set (`None`: not started by one).
pub fn launched_ranks() -> Option<usize> {
    ["OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "PMI_SIZE"]
        .iter()
        .find_map(|v| std::env::var(v).ok())
        .and_then(|s| s.trim().parse().ok())
}

/// The transport of a process an MPI launcher started (`None` when none did). MPI is
/// finalised when the last clone is dropped: keep it on the main thread until the command
/// ends. Without the `mpi` feature, a launch on more than one rank is an error (each rank
/// would run the whole job and write the same files).
pub fn transport() -> Result<Option<Arc<dyn Transport>>, String> {
    let Some(n) = launched_ranks() else { return Ok(None) };
    #[cfg(feature = "mpi")]
    {
        let _ = n;
        let mpi = sparse_levelset_mpi::Mpi::init()?;
        Ok(Some(Arc::new(mpi)))
    }
    #[cfg(not(feature = "mpi"))]
    {
        if n > 1 {
            return Err(format!(
                "started on {n} MPI ranks, but this levelset was built without MPI: build it \
                 with `cargo build --release --features mpi` (needs libopenmpi-dev and \
                 libclang-dev)"
            ));
        }
        Ok(None)
    }
}
