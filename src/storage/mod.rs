//! The storages of a narrow band and what builds them: the Sorted Tile List ([`tiles`]),
//! the DT-Grid reference ([`dtgrid`]), the H-RLE grid of files and CSG ([`hrle`]), dense
//! fields ([`dense`]); the one read interface they share ([`levelset::LevelSet`]); analytic
//! solids ([`shapes`]), culled sampling ([`sample`]) and the conversions between them all
//! ([`convert`]).

pub mod convert;
pub mod dense;
pub mod dtgrid;
pub mod hrle;
pub mod interpolate;
pub mod levelset;
pub mod sample;
pub mod shapes;
pub mod tiles;
