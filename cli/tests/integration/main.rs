//! The tests of the `levelset` command (and of the speed-up report's binary), one test
//! binary with a module a subject: it runs the built binaries as a user would. Run one subject
//! with `cargo test -p levelset-cli --test integration SUBJECT::`. The runs under `mpirun`
//! are in `tests/distributed/`.

mod common;

mod batch;
mod cli;
mod levels;
mod limits;
mod outputs;
mod segment;
mod sls;
mod vdb;
mod voxelize;
