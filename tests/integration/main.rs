//! The library's integration tests, one test binary with a module a subject (as large Rust
//! projects do): the workspace's test configurations each compile and link it once. Run one
//! subject with `cargo test --test integration SUBJECT::` (for example `fmm::`). The tests
//! of the `levelset` command live with it, in `cli/tests/`.

mod common;

mod csg;
mod distributed;
mod evolve;
mod evolve_atomic;
mod evolve_collapse;
mod filter;
mod fmm;
mod grids;
mod image;
mod image_formats;
mod lattice;
mod levelset;
mod mesh;
mod render;
mod renorm;
mod segment;
mod segment_features;
mod segment_foreign;
mod sls;
mod sls_fuzz;
mod vdb;
mod voxelize;
