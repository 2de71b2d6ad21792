//! Level-set filters against analytic answers: offsets of a sphere, the opening and closing
//! of a box, motion by mean curvature (r² = r₀² − 2t), and the band filters.

use sparse_levelset::storage::convert::tiles_from_shape;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::TileGrid;
use sparse_levelset::tools::filter::{filter, Filter, FilterError};
use sparse_levelset::tools::measure::measure;
use sparse_levelset::{GridSpec, LevelSet};

/// The largest |φ − exact| over the band voxels of `grid`.
fn worst(grid: &TileGrid, exact: impl Fn([f64; 3]) -> f64) -> f64 {
    errors(grid, exact).0
}

/// The largest and the mean |φ − exact| over the band voxels of `grid`.
fn errors(grid: &TileGrid, exact: impl Fn([f64; 3]) -> f64) -> (f64, f64) {
    let spec = *grid.spec();
    let (mut w, mut sum, mut n) = (0f64, 0f64, 0usize);
    grid.for_each_band_voxel(&mut |c, v| {
        let e = (v as f64 - exact(spec.world(c))).abs();
        w = w.max(e);
        sum += e;
        n += 1;
    });
    (w, sum / n as f64)
}

fn box_sdf(p: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [p[0].abs() - b[0], p[1].abs() - b[1], p[2].abs() - b[2]];
    let out = d.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>().sqrt();
    out + d[0].max(d[1]).max(d[2]).min(0.0)
}

#[test]
fn offsets_move_a_sphere_by_the_distance() {
    let spec = GridSpec::new(0.5, [0.0; 3], 3.0).unwrap();
    let sphere = Shape::Sphere { center: [0.3, -0.2, 0.1], radius: 8.0 };
    let tiles = tiles_from_shape(&sphere, spec).unwrap();
    for d in [2.5, -3.0, 0.75] {
        let out = filter(&tiles, &[Filter::Offset(d)]).unwrap();
        let exact = Shape::Sphere { center: [0.3, -0.2, 0.1], radius: 8.0 + d };
        let e = worst(&out, |p| exact.sdf(p));
        assert!(e < 0.05, "offset {d}: largest error {e} (voxel 0.5)");
        assert_eq!(out.spec(), tiles.spec());
    }
    // Dilate and erode are offsets.
    let a = filter(&tiles, &[Filter::Dilate(1.5)]).unwrap();
    let b = filter(&tiles, &[Filter::Offset(1.5)]).unwrap();
    assert_eq!(a.checksum(), b.checksum());
    let a = filter(&tiles, &[Filter::Erode(1.5)]).unwrap();
    let b = filter(&tiles, &[Filter::Offset(-1.5)]).unwrap();
    assert_eq!(a.checksum(), b.checksum());
}

#[test]
fn opening_rounds_a_box_by_the_radius_and_closing_keeps_it() {
    let spec = GridSpec::new(0.5, [0.0; 3], 3.0).unwrap();
    let b = [8.0, 6.0, 5.0];
    let tiles = tiles_from_shape(&Shape::Box { center: [0.0; 3], half_extents: b }, spec).unwrap();
    let r = 2.0;
    // Fast marching re-estimates the values at a sharp corner or edge from its axis
    // neighbours (about one voxel off there: measured 1.05 h at most, 0.16 h on average
    // over the band); on smooth parts the offsets are within 0.1 h (the sphere's).
    let h = 0.5;
    let opened = filter(&tiles, &[Filter::Open(r)]).unwrap();
    let rounded = |p: [f64; 3]| box_sdf(p, [b[0] - r, b[1] - r, b[2] - r]) - r;
    let (max, mean) = errors(&opened, rounded);
    assert!(max < 1.1 * h && mean < 0.2 * h, "opening: errors {max}, mean {mean}");
    // The corner is cut by the radius: the box's corner is now (√3 − 1) r outside.
    let corner = sparse_levelset::Coord::new(16, 12, 10);
    assert_eq!(box_sdf(spec.world(corner), b), 0.0);
    let want = (3f64.sqrt() - 1.0) * r;
    assert!((opened.value(corner) as f64 - want).abs() < h, "{}", opened.value(corner));
    let closed = filter(&tiles, &[Filter::Close(r)]).unwrap();
    let (max, mean) = errors(&closed, |p| box_sdf(p, b));
    assert!(max < 1.1 * h && mean < 0.2 * h, "closing a convex box: errors {max}, mean {mean}");
}

#[test]
fn mean_curvature_motion_shrinks_a_sphere_as_r2_minus_2t() {
    let spec = GridSpec::new(0.5, [0.0; 3], 3.0).unwrap();
    let r0 = 10.0f64;
    let tiles = tiles_from_shape(&Shape::Sphere { center: [0.0; 3], radius: r0 }, spec).unwrap();
    let t = 18.0;
    let out = filter(&tiles, &[Filter::MeanCurvature(t)]).unwrap();
    let v = measure(&out, &Default::default()).unwrap().volume;
    let r = (3.0 * v / (4.0 * std::f64::consts::PI)).cbrt();
    let want = (r0 * r0 - 2.0 * t).sqrt();
    assert!((r - want).abs() < 0.02 * want, "radius {r}, r² = r₀² − 2t gives {want}");
}

#[test]
fn band_filters_smooth_corners_and_keep_a_sphere() {
    let spec = GridSpec::new(0.5, [0.0; 3], 3.0).unwrap();
    let sphere = Shape::Sphere { center: [0.0; 3], radius: 7.0 };
    let tiles = tiles_from_shape(&sphere, spec).unwrap();
    for f in [Filter::Median(1), Filter::Mean(1), Filter::Gaussian(2)] {
        let out = filter(&tiles, &[f]).unwrap();
        let e = worst(&out, |p| sphere.sdf(p));
        assert!(e < 0.2, "{f:?} on a sphere: largest error {e}");
    }
    let b = [6.0, 5.0, 4.0];
    let tiles = tiles_from_shape(&Shape::Box { center: [0.0; 3], half_extents: b }, spec).unwrap();
    let corner = sparse_levelset::Coord::new(12, 10, 8); // the box's corner, world (6, 5, 4)
    let before = tiles.value(corner);
    let after = filter(&tiles, &[Filter::Gaussian(2), Filter::Renormalize]).unwrap();
    assert!(after.value(corner) > before + 0.1, "{before} → {}", after.value(corner));
}

#[test]
fn bad_filters_are_refused_and_an_erosion_that_removes_everything_says_so() {
    let spec = GridSpec::default();
    let tiles = tiles_from_shape(&Shape::Sphere { center: [0.0; 3], radius: 4.0 }, spec).unwrap();
    for f in [Filter::Offset(f64::NAN), Filter::Open(-1.0), Filter::Median(0), Filter::Mean(9)] {
        assert!(matches!(filter(&tiles, &[f]), Err(FilterError::InvalidParameter(_))), "{f:?}");
    }
    assert!(matches!(filter(&tiles, &[Filter::Erode(6.0)]), Err(FilterError::Empty)));
}
