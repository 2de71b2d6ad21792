//! Construction and conversion of both grids against each other and against the analytic
//! field: shapes, dense fields, round trips, far coordinates.

use sparse_levelset::grid::{GridError, GridSpec};
use sparse_levelset::storage::convert::{
    dense_box, dtgrid_from, dtgrid_from_dense, dtgrid_from_shape, tiles_from, tiles_from_dense,
    tiles_from_shape, to_dense,
};
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::Coord;
use sparse_levelset::LevelSet;

/// Every voxel of a box, visited in order.
fn for_box(lo: Coord, hi: Coord, mut f: impl FnMut(Coord)) {
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                f(Coord::new(x, y, z));
            }
        }
    }
}

/// Asserts that two grids read the same value at every voxel of their bounding box grown
/// by `margin`.
fn assert_same<A: LevelSet, B: LevelSet>(a: &A, b: &B, margin: u32) {
    let (lo, dims) = dense_box(a, margin).expect("non-empty");
    let hi =
        Coord::new(lo.x + dims[0] as i32 - 1, lo.y + dims[1] as i32 - 1, lo.z + dims[2] as i32 - 1);
    for_box(lo, hi, |c| assert_eq!(a.value(c), b.value(c), "at {c:?}"));
}

/// Asserts that a grid holds the analytic field: the clamped signed distance in the band,
/// ±γ with the right sign outside, at every voxel of its box grown by 2.
fn assert_analytic<G: LevelSet>(g: &G, shape: &Shape) {
    let spec = g.spec();
    let gamma = spec.gamma();
    let (lo, dims) = dense_box(g, 2).expect("non-empty");
    let hi =
        Coord::new(lo.x + dims[0] as i32 - 1, lo.y + dims[1] as i32 - 1, lo.z + dims[2] as i32 - 1);
    let mut band = 0;
    for_box(lo, hi, |c| {
        let want = (shape.sdf(spec.world(c)) as f32).clamp(-gamma, gamma);
        let got = g.value(c);
        if want.abs() < gamma {
            assert_eq!(got, want, "band voxel {c:?}");
            band += 1;
        } else {
            assert!(got.abs() == gamma && (got < 0.0) == (want < 0.0), "{c:?}: {got} vs {want}");
        }
    });
    assert_eq!(band, g.band_voxels());
}

fn shapes() -> Vec<Shape> {
    vec![
        Shape::Sphere { center: [-13.3, 7.1, -40.2], radius: 11.7 },
        Shape::Torus { center: [5.0, -9.0, 3.5], major_radius: 13.0, minor_radius: 4.1 },
        Shape::Box { center: [-3.0, 2.5, 1.0], half_extents: [9.5, 6.2, 3.3] },
        Shape::Ellipsoid { center: [1.0, 2.0, -3.0], radii: [14.0, 9.0, 6.5] },
        Shape::spiral_default([-20.0, 30.0, -10.0], 25.0, 14.0),
        Shape::Union(vec![
            Shape::Sphere { center: [0.0, 0.0, 0.0], radius: 6.0 },
            Shape::Box { center: [7.0, 1.0, -2.0], half_extents: [4.0, 3.0, 5.0] },
        ]),
    ]
}

#[test]
fn shapes_build_both_grids_holding_the_analytic_field() {
    for (i, shape) in shapes().iter().enumerate() {
        let spec =
            GridSpec::new([1.0, 0.5, 0.75][i % 3], [0.25 * i as f64, -3.0, 1.5], [3.0, 2.0][i % 2])
                .unwrap();
        let tiles = tiles_from_shape(shape, spec).unwrap();
        let dt = dtgrid_from_shape(shape, spec).unwrap();
        tiles.check_invariants().unwrap();
        dt.check_invariants().unwrap();
        assert!(tiles.band_voxels() > 500, "{shape:?}");
        assert_eq!(tiles.band_voxels(), dt.len());
        assert_analytic(&tiles, shape);
        assert_analytic(&dt, shape);
    }
}

#[test]
fn conversions_round_trip() {
    let spec = GridSpec::default();
    for shape in shapes() {
        let tiles = tiles_from_shape(&shape, spec).unwrap();
        let dt = dtgrid_from(&tiles);
        let back = tiles_from(&dt);
        back.check_invariants().unwrap();
        assert_eq!(back.tile_coords(), tiles.tile_coords());
        for p in 0..tiles.len() {
            assert_eq!(back.tile(p), tiles.tile(p));
        }
        assert_same(&tiles, &back, 3);
        assert_same(&dt, &back, 3);
        let dt2 = dtgrid_from(&back);
        assert_eq!(dt2.values(), dt.values());
    }
}

#[test]
fn dense_fields_build_the_same_grids_and_export_back() {
    let spec = GridSpec::new(1.0, [0.0; 3], 3.0).unwrap();
    for shape in shapes() {
        let tiles = tiles_from_shape(&shape, spec).unwrap();
        // A dense box that holds the band, with an origin that is not tile aligned.
        let (lo, dims) = dense_box(&tiles, 3).unwrap();
        let lo = Coord::new(lo.x - 1, lo.y - 2, lo.z - 3);
        let dims = [dims[0] + 3, dims[1] + 5, dims[2] + 4];
        let field = DenseField::from_fn(lo, dims, |c| shape.sdf(spec.world(c)) as f32).unwrap();
        assert!(!field.boundary_touches(spec.gamma()));
        let t2 = tiles_from_dense(&field, spec).unwrap();
        let d2 = dtgrid_from_dense(&field, spec).unwrap();
        assert_eq!(t2.tile_coords(), tiles.tile_coords());
        assert_same(&tiles, &t2, 4);
        assert_same(&tiles, &d2, 4);
        // Export to dense equals the field clamped to ±γ.
        let g = spec.gamma();
        for out in [to_dense(&t2, lo, dims).unwrap(), to_dense(&d2, lo, dims).unwrap()] {
            for (a, b) in out.data().iter().zip(field.data()) {
                assert_eq!(*a, b.clamp(-g, g));
            }
        }
    }
}

#[test]
fn dense_input_nan_is_an_error_and_infinity_clamps() {
    let spec = GridSpec::default();
    let mut field = DenseField::from_fn(Coord::new(-5, -5, -5), [11, 11, 11], |c| {
        ((c.x * c.x + c.y * c.y + c.z * c.z) as f32).sqrt() - 3.0
    })
    .unwrap();
    field.set(Coord::new(5, 5, 5), f32::INFINITY).unwrap();
    field.set(Coord::new(0, 0, 0), f32::NEG_INFINITY).unwrap();
    let t = tiles_from_dense(&field, spec).unwrap();
    let d = dtgrid_from_dense(&field, spec).unwrap();
    assert_eq!(t.value(Coord::new(0, 0, 0)), -3.0);
    assert_eq!(d.value(Coord::new(0, 0, 0)), -3.0);
    assert_same(&t, &d, 2);
    field.set(Coord::new(1, -2, 3), f32::NAN).unwrap();
    let want = GridError::NaN { coord: Coord::new(1, -2, 3) };
    assert_eq!(tiles_from_dense(&field, spec).unwrap_err(), want);
    assert_eq!(dtgrid_from_dense(&field, spec).unwrap_err(), want);
}

#[test]
fn far_coordinates_work_and_beyond_i32_is_an_error() {
    let spec = GridSpec::default();
    for c in [2_147_483_600.0, -2_147_483_600.0] {
        let shape = Shape::Sphere { center: [c, -c, c], radius: 9.5 };
        let tiles = tiles_from_shape(&shape, spec).unwrap();
        let dt = dtgrid_from(&tiles);
        assert!(tiles.band_voxels() > 1000);
        assert_analytic(&tiles, &shape);
        assert_analytic(&dt, &shape);
        // Dilating the DT-Grid by a few voxels stays in range; the tile grid at the very
        // edge cannot grow further and says so.
        assert!(dt.dilate(2).is_ok());
    }
    let edge = Shape::Sphere { center: [2_147_483_640.0, 0.0, 0.0], radius: 4.0 };
    match tiles_from_shape(&edge, spec) {
        Err(GridError::InvalidParameter(_)) | Err(GridError::OutOfRange { .. }) => {}
        other => panic!("a band past i32::MAX must be refused, got {other:?}"),
    }
    let beyond = Shape::Sphere { center: [3e9, 0.0, 0.0], radius: 4.0 };
    assert!(tiles_from_shape(&beyond, spec).is_err());
    assert!(dtgrid_from_shape(&beyond, spec).is_err());
}

#[test]
fn empty_shapes_give_empty_grids() {
    // A sphere smaller than a voxel between voxel centres still has band voxels; a grid
    // of a shape far thinner than γ exists too. An empty dense field gives empty grids.
    let spec = GridSpec::default();
    let field = DenseField::new(Coord::new(0, 0, 0), [5, 6, 7], 10.0).unwrap();
    let t = tiles_from_dense(&field, spec).unwrap();
    let d = dtgrid_from_dense(&field, spec).unwrap();
    assert!(t.is_empty() && d.is_empty());
    assert_eq!(t.value(Coord::new(2, 2, 2)), 3.0);
    assert_eq!(d.value(Coord::new(2, 2, 2)), 3.0);
    assert!(dense_box(&t, 1).is_none());
    let tiny = Shape::Sphere { center: [0.5, 0.5, 0.5], radius: 0.01 };
    let tiles = tiles_from_shape(&tiny, spec).unwrap();
    assert_analytic(&tiles, &tiny);
}

#[test]
fn export_npy_round_trips_through_the_dense_reader() {
    let spec = GridSpec::default();
    let shape = Shape::Torus { center: [-4.0, 3.0, 2.0], major_radius: 9.0, minor_radius: 3.0 };
    let tiles = tiles_from_shape(&shape, spec).unwrap();
    let path = std::env::temp_dir().join(format!("levelset-export-{}.npy", std::process::id()));
    let origin = sparse_levelset::storage::convert::export_npy(&tiles, &path, 2).unwrap();
    let mut field = sparse_levelset::io::npy::read_npy(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    field = DenseField::from_vec(origin, field.dims(), field.into_data()).unwrap();
    let back = tiles_from_dense(&field, spec).unwrap();
    assert_eq!(back.tile_coords(), tiles.tile_coords());
    assert_same(&tiles, &back, 3);
    let empty = tiles_from_dense(&DenseField::new(origin, [2, 2, 2], 9.0).unwrap(), spec).unwrap();
    assert!(sparse_levelset::storage::convert::export_npy(&empty, &path, 0).is_err());
    assert!(!path.exists());
}

#[test]
fn closures_build_the_same_tiles_as_shapes() {
    let spec = GridSpec::new(0.5, [1.0, -2.0, 0.25], 3.0).unwrap();
    let shape = Shape::Ellipsoid { center: [-3.0, 4.0, 1.0], radii: [9.0, 6.0, 4.5] };
    let from_shape = tiles_from_shape(&shape, spec).unwrap();
    let (lo, dims) = dense_box(&from_shape, 4).unwrap();
    let hi =
        Coord::new(lo.x + dims[0] as i32 - 1, lo.y + dims[1] as i32 - 1, lo.z + dims[2] as i32 - 1);
    let from_closure =
        sparse_levelset::storage::convert::tiles_from_sdf(|p| shape.sdf(p), 1.0, lo, hi, spec)
            .unwrap();
    assert_eq!(from_closure.tile_coords(), from_shape.tile_coords());
    assert_same(&from_shape, &from_closure, 3);
    let nan = sparse_levelset::storage::convert::tiles_from_sdf(|_| f64::NAN, 1.0, lo, hi, spec);
    assert!(matches!(nan, Err(GridError::NaN { .. })));
}

/// Asserts that two grids read the same value at every voxel of `lo..=hi`.
fn assert_same_box<A: LevelSet, B: LevelSet>(a: &A, b: &B, lo: Coord, hi: Coord, what: &str) {
    for_box(lo, hi, |c| assert_eq!(a.value(c), b.value(c), "{what}: at {c:?}"));
}

/// The array box of a dense field grown by `m` voxels on every side.
fn grown_box(field: &DenseField, m: i32) -> (Coord, Coord) {
    let (o, hi) = (field.origin(), field.max_coord());
    (Coord::new(o.x - m, o.y - m, o.z - m), Coord::new(hi.x + m, hi.y + m, hi.z + m))
}

#[test]
fn dense_interior_touching_the_array_edge_is_closed_on_both_grids() {
    // A 4³ block of −1 (h = 1, half-width 3): the interior fills the array. Beyond it the
    // tile grid reads outside (+γ); the DT-Grid's closing layer makes it read the same.
    let spec = GridSpec::default();
    let block = DenseField::new(Coord::new(0, 0, 0), [4, 4, 4], -1.0).unwrap();
    let t = tiles_from_dense(&block, spec).unwrap();
    let d = dtgrid_from_dense(&block, spec).unwrap();
    d.check_invariants().unwrap();
    for c in [Coord::new(10, 1, 1), Coord::new(-5, 1, 1), Coord::new(4, 3, 0), Coord::new(-1, 0, 3)]
    {
        assert_eq!(t.value(c), 3.0, "tiles at {c:?}");
        assert_eq!(d.value(c), 3.0, "DT-Grid at {c:?}");
    }
    assert_eq!(d.value(Coord::new(2, 1, 3)), -1.0);
    assert_eq!(d.band_voxels(), 64);
    let (lo, hi) = grown_box(&block, 6);
    assert_same_box(&t, &d, lo, hi, "4³ block");

    // Random fields: unions of balls cut by the array (interior and band on several
    // faces), sizes that are not multiples of 4, negative origins, some values far
    // beyond γ inside.
    let mut rng = fastrand::Rng::with_seed(7);
    for case in 0..8 {
        let origin = Coord::new(rng.i32(-23..3), rng.i32(-23..3), rng.i32(-23..3));
        let dims = [rng.usize(5..23), rng.usize(5..23), rng.usize(5..23)];
        let balls: Vec<([f64; 3], f64)> = (0..rng.usize(1..4))
            .map(|_| {
                // Centres anywhere in the array or up to 3 voxels beyond it.
                let c = [0, 1, 2].map(|a| {
                    let o = [origin.x, origin.y, origin.z][a] as f64;
                    o - 3.0 + rng.f64() * (dims[a] as f64 + 6.0)
                });
                (c, 2.0 + rng.f64() * 9.0)
            })
            .collect();
        let scale = [1.0, 1.0, 2.5, 0.7][case % 4];
        let field = DenseField::from_fn(origin, dims, |c| {
            let p = [c.x as f64, c.y as f64, c.z as f64];
            let d = balls
                .iter()
                .map(|(q, r)| {
                    let v = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - r
                })
                .fold(f64::INFINITY, f64::min);
            (scale * d) as f32
        })
        .unwrap();
        let t = tiles_from_dense(&field, spec).unwrap();
        let d = dtgrid_from_dense(&field, spec).unwrap();
        d.check_invariants().unwrap();
        t.check_invariants().unwrap();
        assert_eq!(t.band_voxels(), d.band_voxels(), "case {case}");
        let (lo, hi) = grown_box(&field, 6);
        assert_same_box(&t, &d, lo, hi, &format!("case {case}: {origin:?} {dims:?}"));
        println!(
            "case {case}: origin {origin:?}, dims {dims:?}, touches: {}, {} band voxels, \
             {} closing voxels",
            field.boundary_touches(0.0),
            d.band_voxels(),
            d.len() - d.band_voxels()
        );
    }
}
