//! CSG against dense references: the pointwise min/max of the operands sampled on a dense
//! box, for overlapping, touching and disjoint operands, every operator, operands on tiles
//! and on the DT-Grid; the result's band, values and inside/outside regions must equal
//! the reference's bit for bit.

use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::{dtgrid_from, tiles_from_shape, to_dense};
use sparse_levelset::storage::dtgrid::DtGrid;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::TileGrid;
use sparse_levelset::tools::csg::{csg, Csg, CsgError, CsgOp};
use sparse_levelset::{Coord, LevelSet};

const OPS: [CsgOp; 3] = [CsgOp::Union, CsgOp::Intersection, CsgOp::Difference];

fn sphere(center: [f64; 3], radius: f64) -> Shape {
    Shape::Sphere { center, radius }
}

/// The inclusive box of both operands' bands, grown by 6 voxels.
fn common_box(a: &impl LevelSet, b: &impl LevelSet) -> (Coord, [usize; 3]) {
    let (la, ha) = a.band_bounding_box().expect("a has a band");
    let (lb, hb) = b.band_bounding_box().expect("b has a band");
    let lo = Coord::new(la.x.min(lb.x) - 6, la.y.min(lb.y) - 6, la.z.min(lb.z) - 6);
    let hi = Coord::new(ha.x.max(hb.x) + 6, ha.y.max(hb.y) + 6, ha.z.max(hb.z) + 6);
    let n = |a: i32, b: i32| (b - a + 1) as usize;
    (lo, [n(lo.x, hi.x), n(lo.y, hi.y), n(lo.z, hi.z)])
}

/// Checks `result` against the dense reference of `op` on `a` and `b`, and returns the
/// number of band voxels of the reference.
fn check(result: &impl LevelSet, a: &impl LevelSet, b: &impl LevelSet, op: CsgOp) -> usize {
    let (origin, dims) = common_box(a, b);
    let da = to_dense(a, origin, dims).unwrap();
    let db = to_dense(b, origin, dims).unwrap();
    let got = to_dense(result, origin, dims).unwrap();
    let gamma = a.spec().gamma();
    let mut band = 0;
    for (i, ((&x, &y), &g)) in da.data().iter().zip(db.data()).zip(got.data()).enumerate() {
        let want = op.apply(x, y);
        assert_eq!(g.to_bits(), want.to_bits(), "{} at element {i}: {g} vs {want}", op.name());
        band += (want.abs() < gamma) as usize;
    }
    assert_eq!(result.band_voxels(), band, "{}: band voxels", op.name());
    // Band voxels lie in the box, so the dense comparison covered all of them.
    let mut inside_box = 0;
    result.for_each_band_voxel(&mut |c, v| {
        assert!(v.abs() < gamma);
        assert_eq!(got.get(c).map(f32::to_bits), Some(v.to_bits()));
        inside_box += 1;
    });
    assert_eq!(inside_box, band);
    band
}

/// Two spheres of radius 10 whose centres are `d` voxels apart: overlapping, touching
/// and disjoint, each combination of grids, each operator.
#[test]
fn csg_equals_the_pointwise_min_max_of_dense_references() {
    let spec = GridSpec::default();
    for (d, case) in [(12.0, "overlapping"), (20.0, "touching"), (31.0, "disjoint")] {
        let sa = sphere([0.3, -0.2, 0.1], 10.0);
        let sb = sphere([0.3 + d, 0.5, -0.4], 10.0);
        let ta = tiles_from_shape(&sa, spec).unwrap();
        let tb = tiles_from_shape(&sb, spec).unwrap();
        let (da, db) = (dtgrid_from(&ta), dtgrid_from(&tb));
        for op in OPS {
            let r = csg(&ta, &tb, op).unwrap();
            r.check_invariants().unwrap();
            let band = check(&r, &ta, &tb, op);
            // Disjoint operands: the intersection is empty, the difference is A.
            if case == "disjoint" {
                match op {
                    CsgOp::Intersection => assert_eq!(band, 0),
                    CsgOp::Difference => assert_eq!(r.checksum(), ta.checksum()),
                    CsgOp::Union => assert_eq!(band, ta.band_voxels() + tb.band_voxels()),
                }
            } else {
                assert!(band > 0, "{case} {}", op.name());
            }
            // Any pair of grids, and either output grid, gives the same band.
            let from_dt: TileGrid = csg(&da, &db, op).unwrap();
            let mixed: TileGrid = csg(&ta, &db, op).unwrap();
            let as_dt: DtGrid = dtgrid_from(&Csg::new(&da, &tb, op).unwrap());
            for other in [from_dt.checksum(), mixed.checksum(), as_dt.checksum()] {
                assert_eq!(other, r.checksum(), "{case} {}", op.name());
            }
        }
    }
}

/// The operators' algebra on the stored results: A ∪ B = B ∪ A and A ∩ B = B ∩ A in
/// value (ties take the first operand, so only equal values can differ, and equal values
/// have equal bits unless they are zeros of opposite sign); A − A is empty.
#[test]
fn csg_algebra() {
    let spec = GridSpec::default();
    let a = tiles_from_shape(
        &Shape::Box { center: [0.2, 0.1, 0.0], half_extents: [9.0, 6.0, 7.5] },
        spec,
    )
    .unwrap();
    let b = tiles_from_shape(&sphere([5.0, 3.0, -2.0], 8.0), spec).unwrap();
    for op in [CsgOp::Union, CsgOp::Intersection] {
        let ab = csg(&a, &b, op).unwrap();
        let ba = csg(&b, &a, op).unwrap();
        let (origin, dims) = common_box(&a, &b);
        let x = to_dense(&ab, origin, dims).unwrap();
        let y = to_dense(&ba, origin, dims).unwrap();
        assert!(x.data().iter().zip(y.data()).all(|(p, q)| p == q), "{} commutes", op.name());
    }
    // A − A = max(φ, −φ) = |φ|: nothing is inside, and the band keeps its voxels.
    let none_inside = csg(&a, &a, CsgOp::Difference).unwrap();
    assert_eq!(none_inside.band_voxels(), a.band_voxels());
    none_inside.for_each_band_voxel(&mut |c, v| assert_eq!(v, a.value(c).abs()));
    let (origin, dims) = common_box(&a, &a);
    let d = to_dense(&none_inside, origin, dims).unwrap();
    assert!(d.data().iter().all(|&v| v >= 0.0), "A − A has an inside");
}

/// Operands on different lattices are refused before any work, with the difference named.
#[test]
fn csg_refuses_different_grids() {
    let a = tiles_from_shape(&sphere([0.0; 3], 6.0), GridSpec::default()).unwrap();
    for (spec, what) in [
        (GridSpec { voxel_size: 0.5, ..GridSpec::default() }, "voxel size"),
        (GridSpec { origin: [0.25, 0.0, 0.0], ..GridSpec::default() }, "origin"),
        (GridSpec { half_width: 4.0, ..GridSpec::default() }, "half-width"),
    ] {
        let b = tiles_from_shape(&sphere([0.0; 3], 6.0), spec).unwrap();
        let e = Csg::new(&a, &b, CsgOp::Union).err().expect("refused");
        assert!(matches!(e, CsgError::SpecMismatch { .. }));
        assert!(e.to_string().contains(what), "{e}");
    }
}

/// An empty operand: the union and difference are the other operand, the intersection
/// is empty (and so is anything combined with nothing).
#[test]
fn csg_with_an_empty_operand() {
    let spec = GridSpec::default();
    let a = tiles_from_shape(&sphere([1.0, 2.0, 3.0], 7.0), spec).unwrap();
    let none = TileGrid::new(spec);
    assert_eq!(csg(&a, &none, CsgOp::Union).unwrap().checksum(), a.checksum());
    assert_eq!(csg(&none, &a, CsgOp::Union).unwrap().checksum(), a.checksum());
    assert_eq!(csg(&a, &none, CsgOp::Difference).unwrap().checksum(), a.checksum());
    assert_eq!(csg(&a, &none, CsgOp::Intersection).unwrap().band_voxels(), 0);
    assert_eq!(csg(&none, &none, CsgOp::Union).unwrap().band_voxels(), 0);
}
