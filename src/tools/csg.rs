//! Constructive solid geometry on narrow-band level sets: union, intersection and
//! difference of any two grids as a merge of their sorted bands, without a dense pass
//! (the CSG operators on augmented level sets of Houston et al. 2006, Sec. 5, "union, subtraction,
//! and intersection"; φ < 0 inside).
//!
//! With φ < 0 inside, the union is min(φ_A, φ_B), the intersection max(φ_A, φ_B) and the
//! difference A − B is max(φ_A, −φ_B). [`Csg`] is the result as a [`LevelSet`] of its own:
//! its value at a voxel is the operator applied to the operands' values there, and its
//! band (|φ| < γ) lies inside the union of the operands' bands, since outside both every
//! operand reads ±γ and so does the result. Converting it with
//! [`crate::storage::convert::tiles_from`] or [`crate::storage::convert::dtgrid_from`] (or [`csg`], which does
//! the former) stores the result's band at the operands' half-width.
//!
//! The values are the operator's exactly: near the intersection curve of the two
//! surfaces (a crease) they are not a distance, as with every min/max CSG of signed
//! distances; a renormalisation afterwards restores |∇φ| = 1 there if a flow needs it.

use crate::coord::Coord;
use crate::grid::{GridError, GridSpec, MemoryReport};
use crate::storage::levelset::{Accessor, LevelSet};
use crate::storage::tiles::TileGrid;

/// A CSG operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CsgOp {
    /// A ∪ B: min(φ_A, φ_B).
    Union,
    /// A ∩ B: max(φ_A, φ_B).
    Intersection,
    /// A − B: max(φ_A, −φ_B).
    Difference,
}

impl CsgOp {
    /// The operator on two values. Written with one comparison each (not `f32::min`,
    /// whose choice between +0 and −0 is unspecified), so the result's bits depend on the
    /// operands' bits alone: of two equal values the first operand's is taken.
    #[inline]
    pub fn apply(self, a: f32, b: f32) -> f32 {
        match self {
            CsgOp::Union => {
                if b < a {
                    b
                } else {
                    a
                }
            }
            CsgOp::Intersection => {
                if b > a {
                    b
                } else {
                    a
                }
            }
            CsgOp::Difference => {
                let nb = -b;
                if nb > a {
                    nb
                } else {
                    a
                }
            }
        }
    }

    /// The operator's name as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            CsgOp::Union => "union",
            CsgOp::Intersection => "intersection",
            CsgOp::Difference => "difference",
        }
    }
}

/// Why two grids cannot be combined.
#[derive(Debug, thiserror::Error)]
pub enum CsgError {
    /// The operands do not share a voxel lattice and band: CSG combines values voxel by
    /// voxel, so voxel size, origin and half-width must be equal.
    #[error(
        "the operands' grids differ ({what}: {a} against {b}); CSG needs the same voxel \
         size, origin and half-width"
    )]
    SpecMismatch { what: &'static str, a: String, b: String },
    /// The merge's working memory is more than the machine can give.
    #[error(transparent)]
    Grid(#[from] GridError),
}

impl crate::error::Error for CsgError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            CsgError::SpecMismatch { .. } => InvalidInput,
            CsgError::Grid(e) => e.kind(),
        }
    }
}

/// `op` applied to `a` and `b`, read as a level set (no values are stored: each is
/// computed from the operands when read). See the [module documentation](self).
pub struct Csg<'a, A: ?Sized, B: ?Sized> {
    a: &'a A,
    b: &'a B,
    op: CsgOp,
    /// `a.band_voxels()`: the size of the merge's buffer, admitted in [`Csg::new`].
    a_band: usize,
}

impl<'a, A: LevelSet + ?Sized, B: LevelSet + ?Sized> Csg<'a, A, B> {
    /// The combination of `a` and `b` by `op`; an error, before any work, when their
    /// grids differ or when the merge's buffer (the coordinates of `a`'s band) does not
    /// fit in memory.
    pub fn new(a: &'a A, b: &'a B, op: CsgOp) -> Result<Self, CsgError> {
        let (sa, sb) = (a.spec(), b.spec());
        let differ = |what, x: String, y: String| {
            if x == y {
                Ok(())
            } else {
                Err(CsgError::SpecMismatch { what, a: x, b: y })
            }
        };
        // Compared bit for bit: a lattice shifted by any amount is another lattice.
        differ("voxel size", sa.voxel_size.to_string(), sb.voxel_size.to_string())?;
        differ("origin", format!("{:?}", sa.origin), format!("{:?}", sb.origin))?;
        differ("half-width", sa.half_width.to_string(), sb.half_width.to_string())?;
        let a_band = a.band_voxels();
        let buffer = crate::memory::bytes_of(a_band as u128, size_of::<Coord>());
        crate::memory::check(buffer, "the CSG merge's coordinates")?;
        Ok(Csg { a, b, op, a_band })
    }

    /// The operator.
    pub fn op(&self) -> CsgOp {
        self.op
    }
}

/// The union, intersection or difference of `a` and `b` as a Sorted Tile List.
pub fn csg<A: LevelSet + ?Sized, B: LevelSet + ?Sized>(
    a: &A,
    b: &B,
    op: CsgOp,
) -> Result<TileGrid, CsgError> {
    Ok(crate::storage::convert::tiles_from(&Csg::new(a, b, op)?))
}

/// The result's accessor: one accessor per operand.
struct CsgAccessor<P, Q> {
    a: P,
    b: Q,
    op: CsgOp,
}

impl<P: Accessor, Q: Accessor> Accessor for CsgAccessor<P, Q> {
    fn value(&mut self, voxel: Coord) -> f32 {
        self.op.apply(self.a.value(voxel), self.b.value(voxel))
    }
}

impl<A: LevelSet + ?Sized, B: LevelSet + ?Sized> LevelSet for Csg<'_, A, B> {
    fn spec(&self) -> GridSpec {
        self.a.spec()
    }

    fn value(&self, voxel: Coord) -> f32 {
        self.op.apply(self.a.value(voxel), self.b.value(voxel))
    }

    fn accessor(&self) -> impl Accessor + '_ {
        CsgAccessor { a: self.a.accessor(), b: self.b.accessor(), op: self.op }
    }

    /// Merges the two sorted bands (the coordinates of `a`'s collected first, then `b`'s
    /// streamed past them) and reports each voxel of either once, if the result is in the
    /// band there.
    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        let mut first = Vec::with_capacity(self.a_band);
        self.a.for_each_band_voxel(&mut |c, _| first.push(c));
        let gamma = self.spec().gamma();
        let (mut acc_a, mut acc_b) = (self.a.accessor(), self.b.accessor());
        let op = self.op;
        let mut emit = |c: Coord, acc_a: &mut dyn Accessor, acc_b: &mut dyn Accessor| {
            let v = op.apply(acc_a.value(c), acc_b.value(c));
            if v.abs() < gamma {
                f(c, v);
            }
        };
        let mut i = 0;
        self.b.for_each_band_voxel(&mut |c, _| {
            while i < first.len() && first[i] < c {
                emit(first[i], &mut acc_a, &mut acc_b);
                i += 1;
            }
            if i < first.len() && first[i] == c {
                i += 1;
            }
            emit(c, &mut acc_a, &mut acc_b);
        });
        for &c in &first[i..] {
            emit(c, &mut acc_a, &mut acc_b);
        }
    }

    fn band_voxels(&self) -> usize {
        let mut n = 0;
        self.for_each_band_voxel(&mut |_, _| n += 1);
        n
    }

    /// The box of both operands' boxes (the result's band lies in their bands).
    fn bounding_box(&self) -> Option<(Coord, Coord)> {
        match (self.a.bounding_box(), self.b.bounding_box()) {
            (None, x) | (x, None) => x,
            (Some((l1, h1)), Some((l2, h2))) => Some((
                Coord::new(l1.x.min(l2.x), l1.y.min(l2.y), l1.z.min(l2.z)),
                Coord::new(h1.x.max(h2.x), h1.y.max(h2.y), h1.z.max(h2.z)),
            )),
        }
    }

    /// Nothing is stored: the result reads its operands.
    fn memory(&self) -> MemoryReport {
        MemoryReport::default()
    }
}
