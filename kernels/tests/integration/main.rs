//! The kernels' integration tests, one test binary with a module a subject: the stencils
//! against analytic solutions, the public API, every lane width against the scalar lane, and
//! the renormalisation.

mod common;

mod analytic;
mod api;
mod lanes;
mod levels;
mod renorm;
