//! # levelset-kernels
//!
//! Stencil arithmetic for sparse-levelset (upwind, curvature, HJ-WENO5, TVD-RK3,
//! reinitialisation), written once over a sealed `Lane` type and instantiated for scalar
//! `f32` and `wide` vectors. The kernels know no grid type. The kernels themselves arrive
//! with the kernels issue; this crate currently holds only the workspace slot.
