//! What is done with a level set once it exists: fast marching ([`fmm`]: distances,
//! reinitialisation, arrival times), meshing ([`mesh`]), ray tracing ([`render`]),
//! constructive solid geometry ([`csg`]), voxelization of triangle meshes ([`voxelize`]) and
//! measures ([`measure`]).

pub mod csg;
pub mod filter;
pub mod fmm;
pub mod measure;
pub mod mesh;
pub mod render;
pub mod voxelize;
