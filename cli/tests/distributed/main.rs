//! The `levelset` command under `mpirun` (feature `mpi`): distributed runs on 2 and 3 ranks
//! and batches on 2. Without the feature this binary holds no test.

#[path = "../integration/common/mod.rs"]
mod common;

mod batch_mpi;
mod mpi;
