//! # sparse-levelset
//!
//! Level-set interface tracking on sparse grids. Two storage engines hold a narrow band
//! of a signed distance field (φ < 0 inside):
//!
//! * [`storage::tiles::TileGrid`], the Sorted Tile List: 4³ tiles behind a lexicographically sorted
//!   coordinate list (the fast engine);
//! * [`storage::dtgrid::DtGrid`], the Dynamic Tubular Grid: the reference every speed and
//!   correctness claim is measured against.
//!
//! ```
//! use sparse_levelset::{storage::convert, storage::shapes::Shape, grid::GridSpec};
//!
//! let spec = GridSpec::default(); // voxel size 1, half-width 3
//! let sphere = Shape::Sphere { center: [0.0; 3], radius: 20.0 };
//! let tiles = convert::tiles_from_shape(&sphere, spec).unwrap();
//! let dt = convert::dtgrid_from_shape(&sphere, spec).unwrap();
//! // Both grids agree with each other and with the analytic field inside the band.
//! let c = sparse_levelset::Coord::new(20, 0, 0);
//! assert!(tiles.value(c).abs() < 1e-6 && dt.value(c).abs() < 1e-6);
//! // Far away, a grid reads ±γ.
//! assert_eq!(tiles.value(sparse_levelset::Coord::new(0, 0, 0)), -3.0);
//! ```

pub mod alloc;
pub mod bench;
pub mod coord;
pub mod distributed;
pub mod error;
pub mod evolve;
pub mod exact;
pub mod grid;
pub mod io;
pub mod memory;
pub mod progress;
pub mod segment;
pub mod storage;
pub mod tools;

/// The README's code is compiled and run as a test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
mod readme {}

pub use coord::Coord;
pub use error::{Error, ErrorKind};
pub use grid::{GridError, GridSpec, MemoryReport};
/// The instruction-set level the kernels run at: detected once per process (AVX-512,
/// AVX2 + FMA or the build's baseline), forced by the environment variable
/// `LEVELSET_SIMD` (`baseline`, `avx2`, `avx512`). `level::Level::active()` tells which.
pub use levelset_kernels::level;
pub use storage::levelset::{Accessor, LevelSet};
