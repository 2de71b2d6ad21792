//! # sparse-levelset
//!
//! Level-set interface tracking on sparse grids. Two storage engines hold a narrow band
//! of a signed distance field (φ < 0 inside):
//!
//! * [`tiles::TileGrid`], the Sorted Tile List: 4³ tiles behind a lexicographically sorted
//!   coordinate list (the fast engine);
//! * [`dtgrid::DtGrid`], the Dynamic Tubular Grid: the reference every speed and
//!   correctness claim is measured against.
//!
//! ```
//! use sparse_levelset::{build, shapes::Shape, grid::GridSpec};
//!
//! let spec = GridSpec::default(); // voxel size 1, half-width 3
//! let sphere = Shape::Sphere { center: [0.0; 3], radius: 20.0 };
//! let tiles = build::tiles_from_shape(&sphere, spec).unwrap();
//! let dt = build::dtgrid_from_shape(&sphere, spec).unwrap();
//! // Both grids agree with each other and with the analytic field inside the band.
//! let c = sparse_levelset::Coord::new(20, 0, 0);
//! assert!(tiles.value(c).abs() < 1e-6 && dt.value(c).abs() < 1e-6);
//! // Far away, a grid reads ±γ.
//! assert_eq!(tiles.value(sparse_levelset::Coord::new(0, 0, 0)), -3.0);
//! ```

pub mod bench;
pub mod build;
mod bytes;
pub mod coord;
pub mod csg;
pub mod dense;
pub mod distributed;
pub mod dtgrid;
pub mod error;
pub mod evolve;
pub mod fmm;
pub mod fsutil;
pub mod grid;
pub mod hrle;
pub mod image;
pub mod input;
pub mod levelset;
pub mod measure;
pub mod memory;
pub mod mesh;
pub mod npy;
pub mod progress;
pub mod render;
pub mod sample;
pub mod segment;
pub mod shapes;
pub mod sls;
pub mod tiles;
pub mod vdb;
pub mod voxelize;

/// The README's code is compiled and run as a test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
mod readme {}

pub use coord::Coord;
pub use error::{Error, ErrorKind};
pub use grid::{GridError, GridSpec, MemoryReport};
pub use levelset::{Accessor, LevelSet};
