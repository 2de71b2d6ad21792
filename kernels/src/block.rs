//! Padded blocks and the sweeps over them: the loops that feed windows to kernels.
//!
//! Bounds are checked once when a block is created; the windows then load without
//! checks (see the `# Invariants` of [`TileWindow`] and [`DenseWindow`]).
//!
//! With `f32` lanes the sweeps pass each voxel's centre index through
//! `core::hint::black_box`, so that LLVM cannot auto-vectorise the voxel loop: the `f32`
//! instantiation is the one-voxel-at-a-time scalar reference (what the DT-Grid runs),
//! and the benchmark's SIMD speed-up is measured against genuinely scalar code.

use crate::error::KernelError;
use crate::kernel::VoxelKernel;
use crate::lane::Lane;
use crate::level::LaneFn;
use crate::window::{DenseWindow, TileWindow};

/// The identity, but opaque to the optimiser when `L` is `f32`.
///
/// The `f32` instantiation of a kernel is the *scalar* reference: one voxel at a time, as
/// a point-by-point grid (the DT-Grid) runs it. Left alone, LLVM's loop vectoriser turns
/// the dense and tile sweeps of the cheaper kernels into SIMD code over consecutive
/// voxels, which would make the scalar baseline of the benchmark a vector code path of
/// its own. Hiding the centre index of each voxel from the optimiser prevents that at the
/// cost of one register spill per voxel; SIMD lane types are untouched.
#[inline(always)]
fn scalar_barrier<L: Lane>(centre: usize) -> usize {
    if L::LANES == 1 {
        core::hint::black_box(centre)
    } else {
        centre
    }
}

/// Compile-time check that windows of reach `r` serve kernel `K`.
struct Fits<K, const R: usize>(K);
impl<K: VoxelKernel, const R: usize> Fits<K, R> {
    const OK: () = assert!(
        K::AXIS_REACH <= R as i32 && K::BOX_REACH <= R as i32,
        "the block's halo is smaller than the kernel's stencil"
    );
    /// A tile block serves the 3×3×3 box and the axes to `R` ([`TileWindow`]).
    const TILE_OK: () = assert!(
        K::AXIS_REACH <= R as i32 && K::BOX_REACH <= 1,
        "the tile block serves the 3x3x3 box and axis offsets up to its halo"
    );
}

/// A 4³ tile padded by an `R`-voxel halo along y and z and whole neighbour rows along x,
/// x fastest: `data[(x+4) + SX (y+R) + SX W (z+R)]` for local `x` in `-4..8` and `y, z` in
/// `-R..4+R`, `SX = 12`, `W = 4 + 2R` (the layout of the root crate's `PaddedBlock<R>`).
/// `R = 1` serves first-order upwind and curvature (the 3×3×3 box with diagonals), `R = 3`
/// HJ-WENO5 as well.
///
/// Kernels read the 3×3×3 box and the axis offsets up to `R` and nothing else (no kernel
/// reads a diagonal offset beyond the box: curvature needs box reach 1, HJ-WENO5 only the
/// ±2, ±3 axis points), so a [`TileWindow`] serves exactly those ([`crate::Window::BOX_REACH`] is
/// 1 for every `R`) and only the rows they touch need to hold values: the padded rows
/// with `y, z` in `-1..5` (all 12 values) and the centre 4 values of the rows with `y` in
/// `-R..4+R`, `z` in `0..4` or `z` in `-R..4+R`, `y` in `0..4` (the star). The root
/// crate's `PaddedBlock::gather_star_row` fills exactly those; other entries are never
/// read.
///
/// The x halo is a whole tile row on each side whatever `R`: a padded row is then the
/// same x-row of three tiles (left neighbour, tile, right neighbour), three aligned copies
/// of 4 values, where an `R`-voxel x halo needs copies of odd lengths at odd offsets.
/// Kernels read at most `R` voxels of it.
///
/// Sweeps visit lane groups in tile order; see [`TileWindow`] for the groups of each lane
/// type. Voxel order for per-voxel inputs and outputs: tile order `x + 4y + 16z`.
#[derive(Clone, Copy, Debug)]
pub struct TileBlock<'a, const R: usize> {
    data: &'a [f32],
}

impl<'a, const R: usize> TileBlock<'a, R> {
    /// Row length of the padded block (x extent: three tile rows).
    pub const SX: usize = 12;
    /// Extent of the padded block along y and z.
    pub const W: usize = 4 + 2 * R;
    /// Number of values in the padded block.
    pub const LEN: usize = Self::SX * Self::W * Self::W;
    const HALO_OK: () =
        assert!(R >= 1 && R <= 4, "a tile block needs a halo of one to four voxels");

    /// A view of `data`, which must hold exactly [`Self::LEN`] values.
    pub fn new(data: &'a [f32]) -> Result<Self, KernelError> {
        #[allow(clippy::let_unit_value)]
        let () = Self::HALO_OK;
        if data.len() != Self::LEN {
            return Err(KernelError::BlockLength { expected: Self::LEN, got: data.len() });
        }
        Ok(TileBlock { data })
    }

    /// Padded index of local coordinates (`x` in `-4..8`, `y, z` in `-R..4+R`).
    #[inline]
    pub fn index(x: i32, y: i32, z: i32) -> usize {
        let (r, sx, w) = (R as i32, Self::SX as i32, Self::W as i32);
        ((x + 4) + sx * (y + r) + sx * w * (z + r)) as usize
    }

    /// The window of lane group `g` of `L` (`g < 64 / L::LANES`, in tile order) and the
    /// tile index of its first voxel. Loops that must inline into the caller (the
    /// instruction-set levels' functions, see [`crate::level`]) call this instead of
    /// [`TileBlock::for_each`], whose closure the compiler may keep out of line.
    ///
    /// # Panics
    /// If `g` is not a lane group of the tile.
    #[inline(always)]
    pub fn group<L: Lane>(&self, g: usize) -> (usize, TileWindow<'a, L, R>) {
        assert!(g < 64 / L::LANES, "a tile has {} lane groups of {}", 64 / L::LANES, L::NAME);
        let (sx, w) = (Self::SX, Self::W);
        let first = g * L::LANES;
        let (x, y, z) = (first % 4, (first / 4) % 4, first / 16);
        let centre = scalar_barrier::<L>((x + 4) + sx * (y + R) + sx * w * (z + R));
        // SAFETY: `data.len() == LEN` (checked in `new`), and `first` starts a lane group
        // of `L` (a voxel, a row, two rows or a slice of the tile).
        (first, unsafe { TileWindow::new_unchecked(self.data, centre) })
    }

    /// Calls `f(first, window)` for every lane group of `L`, in tile order; `first` is the
    /// tile index of the group's first voxel.
    #[inline(always)]
    pub fn for_each<L: Lane>(&self, mut f: impl FnMut(usize, &TileWindow<'a, L, R>)) {
        for g in 0..64 / L::LANES {
            let (first, win) = self.group::<L>(g);
            f(first, &win);
        }
    }

    /// Evaluates `kernel` for all 64 voxels into `out` (tile order), with lane type `L`.
    #[inline(always)]
    pub fn apply<L: Lane, K: VoxelKernel>(
        &self,
        kernel: &K,
        out: &mut [f32; 64],
    ) -> Result<(), KernelError> {
        self.apply_slices::<L, K>(kernel, out, false)
    }

    /// [`TileBlock::apply`], or with `first_slice_only` the 16 voxels of the slice z = 0
    /// only, copied into the slices z = 1, 2, 3: a planar lattice's level set, extruded
    /// along z, at a quarter of the evaluations. One loop with a bound chosen at run time,
    /// so that a sweep holds one copy of the kernel's code for both.
    #[inline(always)]
    pub fn apply_slices<L: Lane, K: VoxelKernel>(
        &self,
        kernel: &K,
        out: &mut [f32; 64],
        first_slice_only: bool,
    ) -> Result<(), KernelError> {
        #[allow(clippy::let_unit_value)]
        let () = Fits::<K, R>::TILE_OK;
        kernel.check(64)?;
        // A lane group lies within one slice (at most 16 lanes; a constant condition).
        assert!(L::LANES <= 16, "a lane group of {} spans two slices", L::NAME);
        let groups = if first_slice_only { 16 / L::LANES } else { 64 / L::LANES };
        // A plain loop, not `for_each`: see `group`.
        for g in 0..groups {
            let (first, w) = self.group::<L>(g);
            kernel.eval(&w, first).store(&mut out[first..]);
        }
        if first_slice_only {
            let (slice, rest) = out.split_at_mut(16);
            for copy in rest.chunks_exact_mut(16) {
                copy.copy_from_slice(slice);
            }
        }
        Ok(())
    }
}

/// A dense `nx × ny × nz` block padded by an `R`-voxel halo on every side, x fastest:
/// `data[(x+R) + sy (y+R) + sz (z+R)]`, `sy = nx + 2R`, `sz = sy (ny + 2R)`, for `x` in
/// `-R..nx+R` etc. Any dimensions (not only multiples of the lane width).
///
/// Lane groups are `L::LANES` consecutive voxels along x; the rest of a row that does not
/// fill a group runs with its one-voxel type [`Lane::Scalar`] (the same kernel, the same
/// arithmetic). Voxel order
/// for per-voxel inputs and outputs: interior x fastest, `x + nx (y + ny z)`.
#[derive(Clone, Copy, Debug)]
pub struct DenseBlock<'a, const R: usize> {
    data: &'a [f32],
    dims: [usize; 3],
}

impl<'a, const R: usize> DenseBlock<'a, R> {
    const HALO_OK: () = assert!(R >= 1, "a dense block needs a halo of at least one voxel");

    /// The padded length for interior dimensions `dims`, `None` on overflow.
    pub fn padded_len(dims: [usize; 3]) -> Option<usize> {
        let p = |n: usize| n.checked_add(2 * R);
        p(dims[0])?.checked_mul(p(dims[1])?)?.checked_mul(p(dims[2])?)
    }

    /// A view of `data` as a block with interior `dims` (`data.len()` must be
    /// [`Self::padded_len`]).
    pub fn new(data: &'a [f32], dims: [usize; 3]) -> Result<Self, KernelError> {
        #[allow(clippy::let_unit_value)]
        let () = Self::HALO_OK;
        let expected = Self::padded_len(dims).ok_or(KernelError::BlockTooLarge)?;
        if data.len() != expected {
            return Err(KernelError::BlockLength { expected, got: data.len() });
        }
        Ok(DenseBlock { data, dims })
    }

    /// Interior dimensions.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Number of interior voxels.
    pub fn voxels(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Padded index of interior-relative coordinates (each in `-R..n+R`), for filling a
    /// block; `dims` are the interior dimensions.
    #[inline]
    pub fn index(dims: [usize; 3], x: isize, y: isize, z: isize) -> usize {
        let r = R as isize;
        let sy = dims[0] as isize + 2 * r;
        let sz = sy * (dims[1] as isize + 2 * r);
        ((x + r) + sy * (y + r) + sz * (z + r)) as usize
    }

    /// Calls `f(row_first, row_centre, sy, sz)` for every interior row (y, z): the
    /// interior index and the padded index of its voxel x = 0, and the strides.
    #[inline(always)]
    fn rows(&self, mut f: impl FnMut(usize, usize, usize, usize)) {
        let [nx, ny, nz] = self.dims;
        let sy = nx + 2 * R;
        let sz = sy * (ny + 2 * R);
        for z in 0..nz {
            for y in 0..ny {
                f(nx * (y + ny * z), R + sy * (y + R) + sz * (z + R), sy, sz);
            }
        }
    }

    /// Calls `full(first, window)` for every full lane group of `L` and
    /// `rest(first, window)` for each voxel left over at the end of a row, row by row;
    /// `first` is the interior index of the group's first voxel.
    #[inline(always)]
    pub fn for_each<L: Lane>(
        &self,
        mut full: impl FnMut(usize, &DenseWindow<'a, L, R>),
        mut rest: impl FnMut(usize, &DenseWindow<'a, L::Scalar, R>),
    ) {
        let nx = self.dims[0];
        let data = self.data;
        self.rows(|row_first, row_centre, sy, sz| {
            let mut x = 0;
            while x + L::LANES <= nx {
                // SAFETY: `data.len()` is the padded length (checked in `new`) and voxels
                // x .. x + LANES of this row are interior.
                let w = unsafe { DenseWindow::new_unchecked(data, row_centre + x, sy, sz) };
                full(row_first + x, &w);
                x += L::LANES;
            }
            while x < nx {
                // SAFETY: as above, for the single interior voxel x.
                let w = unsafe { DenseWindow::new_unchecked(data, row_centre + x, sy, sz) };
                rest(row_first + x, &w);
                x += 1;
            }
        });
    }

    /// Evaluates `kernel` for every interior voxel into `out` (interior order), with lane
    /// type `L` (and its one-voxel type [`Lane::Scalar`] for the ends of rows that do not
    /// fill a group).
    #[inline(always)]
    pub fn apply<L: Lane, K: VoxelKernel>(
        &self,
        kernel: &K,
        out: &mut [f32],
    ) -> Result<(), KernelError> {
        #[allow(clippy::let_unit_value)]
        let () = Fits::<K, R>::OK;
        let n = self.voxels();
        if out.len() != n {
            return Err(KernelError::OutputLength { expected: n, got: out.len() });
        }
        kernel.check(n)?;
        // Plain loops, not `rows` with a closure: they must inline into the caller (the
        // instruction-set levels' functions, see `crate::level`).
        let [nx, ny, nz] = self.dims;
        let data = self.data;
        let sy = nx + 2 * R;
        let sz = sy * (ny + 2 * R);
        for z in 0..nz {
            for y in 0..ny {
                let row_first = nx * (y + ny * z);
                let row_centre = R + sy * (y + R) + sz * (z + R);
                let out = &mut out[row_first..row_first + nx];
                let mut x = 0;
                while x + L::LANES <= nx {
                    let c = scalar_barrier::<L>(row_centre + x);
                    // SAFETY: `data.len()` is the padded length (checked in `new`) and
                    // voxels x .. x + LANES of this row are interior.
                    let w = unsafe { DenseWindow::<L, R>::new_unchecked(data, c, sy, sz) };
                    kernel.eval(&w, row_first + x).store(&mut out[x..]);
                    x += L::LANES;
                }
                while x < nx {
                    let c = scalar_barrier::<L::Scalar>(row_centre + x);
                    // SAFETY: as above, for the single interior voxel x.
                    let w = unsafe { DenseWindow::<L::Scalar, R>::new_unchecked(data, c, sy, sz) };
                    kernel.eval(&w, row_first + x).store(&mut out[x..]);
                    x += 1;
                }
            }
        }
        Ok(())
    }
}

/// [`DenseBlock::apply`] as a [`LaneFn`]: what [`DenseBlock::apply_one`] dispatches.
struct DenseApply<'a, 'k, K, const R: usize> {
    block: DenseBlock<'a, R>,
    kernel: &'k K,
    out: &'k mut [f32],
}

impl<K: VoxelKernel, const R: usize> LaneFn for DenseApply<'_, '_, K, R> {
    type Output = Result<(), KernelError>;
    #[inline(always)]
    fn call<L: Lane>(self) -> Self::Output {
        self.block.apply::<L, K>(self.kernel, self.out)
    }
}

impl<const R: usize> DenseBlock<'_, R> {
    /// [`DenseBlock::apply`] one voxel at a time at the CPU's instruction-set level
    /// ([`crate::dispatch_one`]): the dense reference's arithmetic, with the bits of every
    /// other sweep at that level.
    pub fn apply_one<K: VoxelKernel>(
        &self,
        kernel: &K,
        out: &mut [f32],
    ) -> Result<(), KernelError> {
        crate::dispatch_one(DenseApply { block: *self, kernel, out })
    }
}
