//! Scalar images on a regular lattice: the input of segmentation ([`crate::segment`]).
//!
//! # Layout and geometry
//! An [`Image`] holds `nx · ny · nz` intensities, **x fastest** (`index = x + nx (y + ny
//! z)`, the memory order of a C-ordered NumPy array of shape `(nz, ny, nx)`), kept in
//! `f32` whatever the file's voxel type. Voxel `(i, j, k)` has its centre at the
//! *lattice position* `(i sx, j sy, k sz)` with the spacing `(sx, sy, sz)` in world units
//! (millimetres for a scan); the level sets of a segmentation live in this frame. The
//! image's placement in the scanner's world (origin and axis directions, for a NIfTI file
//! its `sform`/`qform`) is [`Image::to_world`]: meshes are written through it. A 2D
//! image is a volume with `nz = 1`.

/// A scalar image: intensities, spacing and placement in the world.
///
/// # Invariants
/// * every entry of `dims` is ≥ 1 and `data.len() == dims[0] · dims[1] · dims[2]`;
/// * every spacing is finite and > 0;
/// * every intensity is finite.
#[derive(Clone, Debug)]
pub struct Image {
    /// `[nx, ny, nz]`.
    pub dims: [usize; 3],
    /// World units per voxel along x, y, z.
    pub spacing: [f64; 3],
    /// Intensities, x fastest.
    pub data: Vec<f32>,
    /// Lattice position → world: `world = M · (p, 1)` with `M` a 3×4 matrix (rows x, y,
    /// z). The identity for images without a placement (`.npy`, PNG).
    pub to_world: [[f64; 4]; 3],
}

impl Image {
    /// The index of voxel `(x, y, z)` in [`Image::data`].
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether the image has no voxel (never, by the invariants).
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// A 2D image (one slice).
    pub fn is_2d(&self) -> bool {
        self.dims[2] == 1
    }

    /// Applies [`Image::to_world`] to a lattice position.
    pub fn world(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.to_world;
        std::array::from_fn(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3])
    }
}

/// The identity placement: world = lattice position.
pub const IDENTITY: [[f64; 4]; 3] =
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
