//! Meshes of level sets by simplicial isosurfacing (Min 2003, "Simplicial isosurfacing in
//! arbitrary dimension and codimension").
//!
//! * [`isosurface`] (any level set), [`isosurface_dense`]: the φ = iso
//!   surface of a 3D level set as one welded, outward-oriented [`TriangleMesh`] in world
//!   coordinates with per-vertex normals from ∇φ, tile by tile in parallel and the same
//!   bits for any thread count; with [`MeshOptions::coarsen`] = k, the surface of φ
//!   sampled at every k-th voxel (about k² fewer triangles, the same guarantees);
//! * [`isosurface_dense_with`]: the dense case with scikit-image's choices (iso value
//!   defaulting to the middle of the data range, which side is inside, a lattice step, a
//!   mask, a surface left open or closed at the array's border) and per-vertex values;
//! * [`isosurface_nd`]: the zero set of a dense φ: Zⁿ → Rᵐ, n ≤ 5, m < n, as a
//!   [`SimplicialComplex`] of dimension n − m (successive hyperplane cuts, Sec. 4);
//! * [`crate::io::mesh::save_mesh`]: binary or ASCII PLY, OBJ and binary STL, written
//!   atomically; mesh checks ([`TriangleMesh::is_closed_manifold`], [`TriangleMesh::euler_characteristic`],
//!   [`TriangleMesh::area`], [`TriangleMesh::enclosed_volume`]).
//!
//! The surface is the zero set of the piecewise-linear interpolant on the Kuhn
//! triangulation (Sec. 2): every cell splits into n! simplices along its main diagonal,
//! so neighbouring cells agree on shared faces and the surface has no ambiguous cases.
//!
//! # Exact zeros and precision
//! A value exactly equal to iso counts as outside (the ε rule of Sec. 3), so the mesh is
//! the closed manifold of the field perturbed by +ε there. Taken literally (ε → 0) the
//! vertices on the edges from such a voxel all land on the voxel: zero-area triangles,
//! and a mesh that is no manifold once a reader welds coincident vertices. Instead every
//! vertex keeps a distance of at least δ·|edge| from both ends of its Kuhn edge, with
//! δ = 32 ulp / h (the ulp of the output precision at the edge's coordinates, about
//! 2.4·10⁻⁴ voxels at 100 voxels from the origin in f32): the connectivity is exactly the
//! ε rule's, positions are distinct and no triangle has zero area, in the file as in
//! memory. Collapsing the vertices at each voxel into one was rejected: at saddles (two
//! balls touching at a voxel, a double cone's apex) it pinches the surface.
//!
//! Positions are computed in f64 and stored as f32 values when f32 resolves 1/4096 of a
//! voxel at the mesh's largest coordinate (X < 4096 h for the usual voxel sizes), f64
//! otherwise; a mesh beyond even f64's reach is a [`MeshError::Precision`]. Files are
//! written without loss (`float` or `double` PLY properties, enough digits in text), so
//! the checks below measure what is written.
//!
//! ```
//! use sparse_levelset::{storage::convert, grid::GridSpec, tools::mesh, storage::shapes::Shape};
//!
//! let sphere = Shape::Sphere { center: [0.0; 3], radius: 10.0 };
//! let tiles = convert::tiles_from_shape(&sphere, GridSpec::default()).unwrap();
//! let m = mesh::isosurface(&tiles, &Default::default()).unwrap();
//! assert!(m.is_closed_manifold());
//! assert_eq!(m.euler_characteristic(), 2);
//! let exact = 4.0 / 3.0 * std::f64::consts::PI * 1000.0;
//! assert!((m.enclosed_volume() - exact).abs() < 0.02 * exact);
//! ```

mod cells;
mod check;
mod coarse;
mod dense;
mod simplicial;
mod surface;
pub mod tables;

pub use dense::{isosurface_dense_with, Border, DenseMeshOptions, DenseSurface, Inside};
pub use simplicial::{cell_simplex_bound, isosurface_nd, ComplexStats, NdField, SimplicialComplex};
pub use surface::{isosurface, isosurface_dense};

use crate::Coord;
use std::path::PathBuf;

/// An indexed triangle mesh: vertex positions (world units), unit normals (∇φ direction,
/// pointing out of φ < 0), and triangles counter-clockwise seen from outside.
///
/// Positions are f64. The isosurface functions store f32 values in them whenever f32
/// holds the mesh (see [the module docs](crate::tools::mesh#exact-zeros-and-precision)), and
/// [`crate::io::mesh::save_mesh`] writes `float` exactly when every coordinate is an f32 value,
/// `double` otherwise: a file holds exactly these positions, so the checks
/// ([`TriangleMesh::area`], [`TriangleMesh::is_closed_manifold`], …) measure what is
/// written.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    pub positions: Vec<[f64; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// Options of [`isosurface`]. `MeshOptions::default()`: the zero set at full resolution
/// without progress reports.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshOptions {
    /// The iso value φ = iso of the surface (world units, strictly inside (−γ, γ)).
    pub iso: f64,
    /// Progress (tiles done) and cancellation.
    pub progress: crate::progress::Progress,
    /// Mesh φ sampled at every k-th voxel (k ≥ 1; 1, the default, is every voxel): the
    /// same surface from cells of k voxels, about k² times fewer triangles, still one
    /// welded closed manifold (see `src/mesh/coarse.rs` and `docs/mesh.md`).
    pub coarsen: u32,
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions { iso: 0.0, progress: Default::default(), coarsen: 1 }
    }
}

/// Errors of meshing and mesh output.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// A parameter outside its documented domain.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// A NaN or infinite value in an n-dimensional field (index of the grid point).
    #[error("value at grid point {index} is not finite")]
    NonFinite { index: usize },
    /// A NaN in a dense 3D field.
    #[error("the value at voxel {coord} is NaN")]
    NaN { coord: Coord },
    /// Coordinates so large for the voxel size that not even f64 resolves a small
    /// fraction of a voxel there (see the surface module docs, "Precision").
    #[error(
        "coordinates up to {extent:e} with voxel size {voxel_size:e}: not even f64 resolves \
         1/4096 of a voxel there (move the grid's origin closer to the level set)"
    )]
    Precision { extent: f64, voxel_size: f64 },
    /// Cancelled through [`MeshOptions::progress`].
    #[error("meshing was cancelled")]
    Cancelled(#[from] crate::progress::Cancelled),
    /// More vertices or triangles than a format or index type holds.
    #[error("mesh too large: {0}")]
    TooLarge(String),
    /// The file extension names no mesh format.
    #[error("{0}: unknown mesh format (use .ply or .obj)")]
    UnknownFormat(PathBuf),
    /// Writing failed.
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
}

impl crate::error::Error for MeshError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            MeshError::InvalidParameter(_) => InvalidInput,
            MeshError::NonFinite { .. } | MeshError::NaN { .. } | MeshError::Precision { .. } => {
                InvalidData
            }
            MeshError::Cancelled(_) => Cancelled,
            MeshError::TooLarge(_) => OutOfMemory,
            MeshError::UnknownFormat(_) => UnknownFormat,
            MeshError::Io { source, .. } => crate::error::io_kind(source),
        }
    }
}

impl TriangleMesh {
    pub fn num_vertices(&self) -> usize {
        self.positions.len()
    }

    pub fn num_triangles(&self) -> usize {
        self.triangles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Area-weighted vertex normals from the triangles alone (the sum of the cross products
    /// of the faces around each vertex, normalised; zero where they cancel): for meshes read
    /// from files without normals. Outward for counter-clockwise faces.
    pub fn area_weighted_normals(&self) -> Vec<[f32; 3]> {
        let mut acc = vec![[0f64; 3]; self.positions.len()];
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let n =
                [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            for &i in t {
                for d in 0..3 {
                    acc[i as usize][d] += n[d];
                }
            }
        }
        acc.iter()
            .map(|n| {
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if len > 0.0 {
                    n.map(|c| (c / len) as f32)
                } else {
                    [0.0; 3]
                }
            })
            .collect()
    }

    /// Vertices whose normal is zero (∇φ vanished there) take the area-weighted mean of
    /// their triangles' normals.
    fn fill_missing_normals(&mut self) {
        let missing: Vec<bool> = self.normals.iter().map(|n| *n == [0.0; 3]).collect();
        if !missing.contains(&true) {
            return;
        }
        let mut acc = vec![[0f64; 3]; self.positions.len()];
        for t in &self.triangles {
            let n = check::face_normal(self, t);
            for &v in t {
                if missing[v as usize] {
                    for a in 0..3 {
                        acc[v as usize][a] += n[a];
                    }
                }
            }
        }
        for (i, a) in acc.iter().enumerate() {
            if missing[i] {
                let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
                if l > 0.0 {
                    self.normals[i] = a.map(|c| (c / l) as f32);
                }
            }
        }
    }
}
