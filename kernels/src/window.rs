//! Stencil windows: how a kernel reads φ around the lane group it is computing.
//!
//! A [`Window`] answers one question: the lane group at offset `(DX, DY, DZ)` voxels from
//! the current centre group. Kernels are written against this trait only, so the two
//! grids feed the same arithmetic:
//!
//! * the Sorted Tile List through [`TileWindow`] (a 4³ tile with an `R`-voxel halo, see
//!   [`crate::TileBlock`]; van der Laan et al. 2011, Sec. 4.4/4.7: stencil access with neighbour
//!   and dummy tiles);
//! * the DT-Grid through the point windows [`BoxWindow`], [`StarWindow`],
//!   [`BoxStarWindow`] and [`BoxFarWindow`] over the stencil values its stencil iterator
//!   collects for one voxel (Nielsen & Museth 2006, Sec. 3.3); their lane type is a
//!   one-voxel type (`f32`, or the scalar of an x86 level);
//! * dense arrays through [`DenseWindow`] (see [`crate::DenseBlock`]), used by the
//!   benchmark and the tests.
//!
//! Offsets are const generic parameters. Every window states what it can serve
//! ([`Window::AXIS_REACH`], [`Window::BOX_REACH`]) and asking for anything else is a
//! compile-time error, which is what makes the unchecked loads of the block windows sound.
//!
//! ```
//! use levelset_kernels::{box27_index, BoxWindow, Window};
//! let mut v = [0.0f32; 27];
//! v[box27_index(1, -1, 0)] = 2.5;
//! let w = BoxWindow::new(&v);
//! let v: f32 = w.at::<1, -1, 0>();
//! assert_eq!(v, 2.5);
//! ```
//!
//! A WENO5 kernel on a DT-Grid box stencil does not compile (the box has no ±3 offsets):
//!
//! ```compile_fail
//! use levelset_kernels::{BoxWindow, Weno5, Scheme};
//! let v = [0.0f32; 27];
//! let _ = Weno5::norms::<f32, _>(&BoxWindow::new(&v), 1.0);
//! ```

use crate::error::KernelError;
use crate::lane::Lane;
use core::marker::PhantomData;

/// Read access to φ around the current lane group.
pub trait Window<L: Lane> {
    /// The largest `|s|` for which the axis offsets `(s,0,0)`, `(0,s,0)`, `(0,0,s)` are
    /// served.
    const AXIS_REACH: i32;
    /// The largest max-norm of offsets with two or three non-zero components that is
    /// served (`0`: only axis offsets, a star stencil).
    const BOX_REACH: i32;

    /// The values at offset `(DX, DY, DZ)` from the centre, one per lane, in the lane
    /// order of the centre group. An offset the window does not serve does not compile.
    fn at<const DX: i32, const DY: i32, const DZ: i32>(&self) -> L;

    /// The values at the centre.
    #[inline(always)]
    fn centre(&self) -> L {
        self.at::<0, 0, 0>()
    }
}

/// Whether a window with the given reaches serves `(dx, dy, dz)`.
pub const fn serves(axis_reach: i32, box_reach: i32, dx: i32, dy: i32, dz: i32) -> bool {
    let nonzero = (dx != 0) as i32 + (dy != 0) as i32 + (dz != 0) as i32;
    let m = max_abs(dx, dy, dz);
    if nonzero <= 1 {
        m <= axis_reach
    } else {
        m <= box_reach
    }
}

const fn max_abs(dx: i32, dy: i32, dz: i32) -> i32 {
    let (a, b, c) = (dx.abs(), dy.abs(), dz.abs());
    let ab = if a > b { a } else { b };
    if ab > c {
        ab
    } else {
        c
    }
}

/// Index of `(dx, dy, dz)` (each in `-1..=1`) in the 3×3×3 box order
/// `9 (dz+1) + 3 (dy+1) + (dx+1)` (centre 13), the order of the DT-Grid's `Stencil::box27`.
pub const fn box27_index(dx: i32, dy: i32, dz: i32) -> usize {
    (9 * (dz + 1) + 3 * (dy + 1) + (dx + 1)) as usize
}

/// Index of an axis offset in the 19-point WENO5 star: centre 0, then for axis `a`
/// (x, y, z) the steps -3, -2, -1, +1, +2, +3 at `1 + 6a + (s+3)` (`s < 0`) and
/// `6a + (s+3)` (`s > 0`), the order of the DT-Grid's `Stencil::weno5`. Returns 0 for the
/// centre and for offsets that are not in the star (callers check [`serves`] first).
pub const fn star19_index(dx: i32, dy: i32, dz: i32) -> usize {
    let (a, s) = if dx != 0 {
        (0, dx)
    } else if dy != 0 {
        (1, dy)
    } else {
        (2, dz)
    };
    if s == 0 || s < -3 || s > 3 {
        0
    } else if s < 0 {
        (1 + 6 * a + (s + 3)) as usize
    } else {
        (6 * a + (s + 3)) as usize
    }
}

/// The offsets `[dx, dy, dz]` of a point layout in index order, so that a grid builds its
/// stencil from the same table the windows index (one source of truth for the order).
const fn offsets<const N: usize>(layout: u8, axis_reach: i32, box_reach: i32) -> [[i32; 3]; N] {
    let mut out = [[0; 3]; N];
    let mut dz = -3;
    while dz <= 3 {
        let mut dy = -3;
        while dy <= 3 {
            let mut dx = -3;
            while dx <= 3 {
                if serves(axis_reach, box_reach, dx, dy, dz) {
                    let i = match layout {
                        0 => box27_index(dx, dy, dz),
                        1 => star19_index(dx, dy, dz),
                        _ => box_far39_index(dx, dy, dz),
                    };
                    out[i] = [dx, dy, dz];
                }
                dx += 1;
            }
            dy += 1;
        }
        dz += 1;
    }
    out
}

/// The 3×3×3 box offsets in [`box27_index`] order.
pub const BOX27_OFFSETS: [[i32; 3]; 27] = offsets(0, 1, 1);
/// The 19-point WENO5 star offsets in [`star19_index`] order.
pub const STAR19_OFFSETS: [[i32; 3]; 19] = offsets(1, 3, 0);
/// The 39-point box + far-star offsets in [`box_far39_index`] order.
pub const BOX_FAR39_OFFSETS: [[i32; 3]; 39] = offsets(2, 3, 1);

// ---------------------------------------------------------------------------------------
// Point windows (DT-Grid): one voxel, lane type f32.

/// A point window over one stencil array of `$n` values in the order of `$index`.
macro_rules! point_window {
    ($(#[$doc:meta])* $name:ident, $n:literal, axis $ar:literal, box $br:literal, $index:ident, $what:literal) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug)]
        pub struct $name<'a> {
            v: &'a [f32; $n],
        }

        impl<'a> $name<'a> {
            #[inline(always)]
            pub fn new(values: &'a [f32; $n]) -> Self {
                $name { v: values }
            }

            #[doc = concat!("From a slice of exactly ", stringify!($n), " values.")]
            #[inline]
            pub fn from_slice(values: &'a [f32]) -> Result<Self, KernelError> {
                let v = values
                    .try_into()
                    .map_err(|_| KernelError::StencilLength { expected: $n, got: values.len() })?;
                Ok($name { v })
            }
        }

        impl<L: Lane> Window<L> for $name<'_> {
            const AXIS_REACH: i32 = $ar;
            const BOX_REACH: i32 = $br;
            #[inline(always)]
            fn at<const DX: i32, const DY: i32, const DZ: i32>(&self) -> L {
                let i = const {
                    assert!(L::LANES == 1, "a point window serves one voxel");
                    assert!(serves($ar, $br, DX, DY, DZ), $what);
                    $index(DX, DY, DZ)
                };
                L::splat(self.v[i])
            }
        }
    };
}

point_window!(
    /// The 3×3×3 box around one voxel, in [`box27_index`] order (centre at 13): first-order
    /// upwind differences and curvature (van der Laan et al. 2011, Sec. 4.7, eq. (4)). Lane
    /// type `f32`.
    BoxWindow, 27, axis 1, box 1, box27_index, "offset outside the 3x3x3 box"
);

point_window!(
    /// The 19-point WENO5 star around one voxel, in [`star19_index`] order (centre at 0):
    /// HJ-WENO5 one-sided derivatives (Nielsen & Museth 2006, Sec. 4.1). One-voxel lane types.
    StarWindow, 19, axis 3, box 0, star19_index, "offset outside the 19-point WENO5 star"
);

/// The box and the star of one voxel together: what a kernel with HJ-WENO5 hyperbolic
/// terms *and* a central curvature term reads (van der Laan et al. 2011, Sec. 5.2, eq. (5);
/// Nielsen & Museth 2006, Sec. 4.1). Offsets with max-norm ≤ 1 come from the box, the rest from the
/// star (the choice is made at compile time). One-voxel lane types.
#[derive(Clone, Copy, Debug)]
pub struct BoxStarWindow<'a> {
    b: &'a [f32; 27],
    s: &'a [f32; 19],
}

impl<'a> BoxStarWindow<'a> {
    /// The two stencils of the same voxel. Their shared points (centre and ±1 along each
    /// axis) are read from `box27`.
    #[inline(always)]
    pub fn new(box27: &'a [f32; 27], star19: &'a [f32; 19]) -> Self {
        BoxStarWindow { b: box27, s: star19 }
    }

    /// From slices of exactly 27 and 19 values.
    #[inline]
    pub fn from_slices(box27: &'a [f32], star19: &'a [f32]) -> Result<Self, KernelError> {
        Ok(BoxStarWindow {
            b: BoxWindow::from_slice(box27)?.v,
            s: StarWindow::from_slice(star19)?.v,
        })
    }
}

impl<L: Lane> Window<L> for BoxStarWindow<'_> {
    const AXIS_REACH: i32 = 3;
    const BOX_REACH: i32 = 1;
    #[inline(always)]
    fn at<const DX: i32, const DY: i32, const DZ: i32>(&self) -> L {
        let (in_box, i) = const {
            assert!(L::LANES == 1, "a point window serves one voxel");
            assert!(serves(3, 1, DX, DY, DZ), "offset outside box27 + WENO5 star");
            if max_abs(DX, DY, DZ) <= 1 {
                (true, box27_index(DX, DY, DZ))
            } else {
                (false, star19_index(DX, DY, DZ))
            }
        };
        L::splat(if in_box { self.b[i] } else { self.s[i] })
    }
}

/// Index of an offset in the 39-point "box + far star" order: the 3×3×3 box in
/// [`box27_index`] order (0..27), then for axis x, y, z the steps -3, -2, +2, +3 at
/// `27 + 4a + k` (k = 0..3). One DT-Grid stencil that serves every kernel of this crate.
/// Returns 0 for offsets outside it (callers check [`serves`] first).
pub const fn box_far39_index(dx: i32, dy: i32, dz: i32) -> usize {
    if max_abs(dx, dy, dz) <= 1 {
        return box27_index(dx, dy, dz);
    }
    let (a, s) = if dx != 0 {
        (0, dx)
    } else if dy != 0 {
        (1, dy)
    } else {
        (2, dz)
    };
    let k = match s {
        -3 => 0,
        -2 => 1,
        2 => 2,
        3 => 3,
        _ => return 0,
    };
    27 + 4 * a + k
}

point_window!(
    /// The 39-point stencil of one voxel in [`box_far39_index`] order: the 3×3×3 box plus
    /// the ±2, ±3 axis points, i.e. box and WENO5 star in one array (what
    /// [`BoxStarWindow`] reads from two). One-voxel lane types.
    BoxFarWindow, 39, axis 3, box 1, box_far39_index, "offset outside box27 + far star"
);

// ---------------------------------------------------------------------------------------
// Block windows: created only by `TileBlock` / `DenseBlock`, which check bounds once.

/// A lane group inside a 4³ tile padded by an `R`-voxel halo (see [`crate::TileBlock`]).
///
/// Lane groups (x fastest, the tile layout): `f32` = one voxel, `f32x4` = one x-row of 4,
/// `f32x8` = two consecutive y-rows (4×2), `f32x16` = a whole 4×4 z-slice. Lane `k` of a
/// group is the voxel with tile-local index `first + k`.
///
/// It serves the 3×3×3 box and the axis offsets up to `R` (`BOX_REACH = 1` for every
/// `R`): the rows of the padded block a star gather fills (see [`crate::TileBlock`]).
///
/// # Invariants
/// `data.len() == 12 (4 + 2R)²` (the [`crate::TileBlock`] layout) and `centre` is the
/// padded index of the first voxel of a lane group of `L` (so every offset with max-norm
/// ≤ `R` stays inside `data`).
#[derive(Clone, Copy, Debug)]
pub struct TileWindow<'a, L, const R: usize> {
    data: &'a [f32],
    centre: usize,
    _lane: PhantomData<L>,
}

impl<'a, L: Lane, const R: usize> TileWindow<'a, L, R> {
    /// Row stride (y step) of the padded block.
    pub(crate) const SX: usize = 12;
    /// Slice stride (z step) of the padded block.
    pub(crate) const SXY: usize = 12 * (4 + 2 * R);

    /// # Safety
    /// The type's invariants must hold.
    #[inline(always)]
    pub(crate) unsafe fn new_unchecked(data: &'a [f32], centre: usize) -> Self {
        TileWindow { data, centre, _lane: PhantomData }
    }
}

impl<L: Lane, const R: usize> Window<L> for TileWindow<'_, L, R> {
    const AXIS_REACH: i32 = R as i32;
    const BOX_REACH: i32 = 1;
    #[inline(always)]
    fn at<const DX: i32, const DY: i32, const DZ: i32>(&self) -> L {
        let off = const {
            assert!(serves(R as i32, 1, DX, DY, DZ), "offset beyond the tile halo");
            DX as isize + DY as isize * Self::SX as isize + DZ as isize * Self::SXY as isize
        };
        let sx = Self::SX;
        let p = self.centre.wrapping_add_signed(off);
        debug_assert!(
            p + (L::LANES / L::LANES.min(4) - 1) * sx + L::LANES.min(4) <= self.data.len()
        );
        // SAFETY: by the invariants the group's voxels lie in the tile and |offset| ≤ R
        // per component, so all `LANES / ROW` rows of `ROW` values are inside the padded
        // block of length 12 (4 + 2R)².
        unsafe { L::load_rows4(self.data.as_ptr().add(p), sx) }
    }
}

/// `L::LANES` consecutive voxels along x inside a dense block with an `R`-voxel halo (see
/// [`crate::DenseBlock`]).
///
/// # Invariants
/// `centre` is the padded index of an interior voxel `(x, y, z)` with `x + LANES ≤ nx`,
/// the strides are those of the block, and `data` is the whole padded block.
#[derive(Clone, Copy, Debug)]
pub struct DenseWindow<'a, L, const R: usize> {
    data: &'a [f32],
    centre: usize,
    sy: usize,
    sz: usize,
    _lane: PhantomData<L>,
}

impl<'a, L: Lane, const R: usize> DenseWindow<'a, L, R> {
    /// # Safety
    /// The type's invariants must hold.
    #[inline(always)]
    pub(crate) unsafe fn new_unchecked(
        data: &'a [f32],
        centre: usize,
        sy: usize,
        sz: usize,
    ) -> Self {
        DenseWindow { data, centre, sy, sz, _lane: PhantomData }
    }
}

impl<L: Lane, const R: usize> Window<L> for DenseWindow<'_, L, R> {
    const AXIS_REACH: i32 = R as i32;
    const BOX_REACH: i32 = R as i32;
    #[inline(always)]
    fn at<const DX: i32, const DY: i32, const DZ: i32>(&self) -> L {
        const { assert!(serves(R as i32, R as i32, DX, DY, DZ), "offset beyond the block halo") };
        let off = DX as isize + DY as isize * self.sy as isize + DZ as isize * self.sz as isize;
        let p = self.centre.wrapping_add_signed(off);
        debug_assert!(p + L::LANES <= self.data.len());
        // SAFETY: by the invariants the `LANES` voxels from the centre are interior and
        // |offset| ≤ R per component, so they stay inside the padded block.
        // Measured (`levelset-speedup --kernels`): a checked `L::load(&data[p..])` here costs
        // 25–35 % of the kernel throughput (f32x16 upwind 652 vs 866 Mvox/s).
        unsafe { L::load_ptr(self.data.as_ptr().add(p)) }
    }
}
