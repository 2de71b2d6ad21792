//! Fast marching (Bærentzen 2001): the accuracy experiment of Table 1,
//! reinitialisation of both sparse grids, widening, arrival times, the CLI, bad input;
//! the dense marches of scikit-fmm's functions (per-axis spacing, periodic axes,
//! obstacles, travel times, extension velocities).
//! Run with `--nocapture` to see the errors and timings.

use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::{dense_box, dtgrid_from, tiles_from_sdf, tiles_from_shape};
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::TileGrid;
use sparse_levelset::tools::fmm::{self, FmmError, FmmOptions, Order};
use sparse_levelset::Coord;
use sparse_levelset::LevelSet;
use std::time::Instant;

const AXES: [Coord; 3] = [Coord::new(1, 0, 0), Coord::new(0, 1, 0), Coord::new(0, 0, 1)];

fn add(a: Coord, b: Coord) -> Coord {
    Coord::new(a.x + b.x, a.y + b.y, a.z + b.z)
}
fn sub(a: Coord, b: Coord) -> Coord {
    Coord::new(a.x - b.x, a.y - b.y, a.z - b.z)
}

/// The DT-Grid reinitialised through the one generic function, back as a DT-Grid.
fn reinit_dt(
    dt: &sparse_levelset::storage::dtgrid::DtGrid,
    o: &FmmOptions,
) -> Result<sparse_levelset::storage::dtgrid::DtGrid, FmmError> {
    fmm::reinitialize(dt, o).map(|g| dtgrid_from(&g))
}

/// Every voxel of a grid's box grown by `margin`.
fn for_box<G: LevelSet>(g: &G, margin: u32, mut f: impl FnMut(Coord)) {
    let (lo, dims) = dense_box(g, margin).expect("non-empty");
    for z in 0..dims[2] as i32 {
        for y in 0..dims[1] as i32 {
            for x in 0..dims[0] as i32 {
                f(Coord::new(lo.x + x, lo.y + y, lo.z + z));
            }
        }
    }
}

/// Band voxels of a grid with a 6-neighbour of the other sign.
fn interface_voxels<G: LevelSet>(g: &G) -> Vec<(Coord, f32)> {
    let gamma = g.spec().gamma();
    let mut out = Vec::new();
    for_box(g, 1, |c| {
        let v = g.value(c);
        if v.abs() < gamma
            && AXES
                .iter()
                .any(|&a| [add(c, a), sub(c, a)].iter().any(|&n| (g.value(n) < 0.0) != (v < 0.0)))
        {
            out.push((c, v));
        }
    });
    out
}

struct Errors {
    mean: f64,
    max: f64,
    mean_marched: f64,
    voxels: usize,
    marched: usize,
    seconds: f64,
}

/// Table 1: the paper's ellipsoid (semi-axes 20, 80, 120 voxels: "principal axes of
/// length" 20, 80, 120 with the curvature that reproduces Table 1; centred on a voxel),
/// exact distances (Eberly's foot point, as the paper's Hartmann foot point) at the voxels
/// with a 6-neighbour on the other side, FMM over the rest of the band of 2.5 voxels,
/// errors against the exact distance over every voxel with |d| < 2.5.
fn ellipsoid_errors(order: Order) -> Errors {
    let shape = Shape::Ellipsoid { center: [0.0; 3], radii: [20.0, 80.0, 120.0] };
    let band = 2.5f32;
    // The exact field on a band wider than the march.
    let exact =
        tiles_from_shape(&shape, GridSpec::new(1.0, [0.0; 3], band + 1.5).unwrap()).unwrap();
    let frozen = interface_voxels(&exact);
    let spec = GridSpec::new(1.0, [0.0; 3], band).unwrap();
    let t = Instant::now();
    let out = fmm::tiles_from_interface(spec, &frozen, order, |c| shape.sdf(spec.world(c)) < 0.0)
        .unwrap();
    let seconds = t.elapsed().as_secs_f64();
    out.check_invariants().unwrap();
    let frozen_set: std::collections::HashSet<Coord> = frozen.iter().map(|f| f.0).collect();
    let (mut sum, mut max, mut n, mut sum_m, mut n_m) = (0.0, 0.0f64, 0, 0.0, 0);
    for_box(&exact, 0, |c| {
        let e = exact.value(c);
        if e.abs() < band {
            let err = (out.value(c) - e).abs() as f64;
            sum += err;
            max = max.max(err);
            n += 1;
            if !frozen_set.contains(&c) {
                sum_m += err;
                n_m += 1;
            }
        }
    });
    Errors {
        mean: sum / n as f64,
        max,
        mean_marched: sum_m / n_m as f64,
        voxels: n,
        marched: n_m,
        seconds,
    }
}

#[test]
fn table1_ellipsoid_accuracy() {
    // (order, the paper's Table 1 mean and max in voxels, our bound on the mean and max).
    // The bounds are the paper's figures + 2 % (relative): Table 1 rounded down to
    // 0.0047 / 0.027 would be below the paper's own 0.00468 + ε and 0.02708.
    let rows = [
        (Order::First, 0.00467565, 0.120639, 0.00467565 * 1.02, 0.12),
        (Order::Second, 0.000496425, 0.0270829, 0.0005, 0.0270829 * 1.02),
    ];
    for (order, paper_mean, paper_max, mean_bound, max_bound) in rows {
        let e = ellipsoid_errors(order);
        println!(
            "Table 1, {order:?} order: mean {:.6} vu, max {:.6} vu (paper {paper_mean} / {paper_max}); \
             marched voxels only: mean {:.6}; {} band voxels, {} marched; march {:.3} s",
            e.mean, e.max, e.mean_marched, e.voxels, e.marched, e.seconds
        );
        assert!(e.mean <= mean_bound, "{order:?}: mean {} > {mean_bound}", e.mean);
        assert!(e.max <= max_bound, "{order:?}: max {} > {max_bound}", e.max);
    }
}

/// A sphere band and its reinitialisation on both grids; returns (input, tiles out).
fn sphere_reinit(order: Order, scale: f64) -> (TileGrid, TileGrid) {
    let spec = GridSpec::default();
    let shape = Shape::Sphere { center: [0.3, -0.2, 0.1], radius: 20.0 };
    let lo = Coord::new(-30, -30, -30);
    let hi = Coord::new(30, 30, 30);
    let input = tiles_from_sdf(|p| scale * shape.sdf(p), scale.max(1.0), lo, hi, spec).unwrap();
    let opts = FmmOptions { order, half_width: None, ..Default::default() };
    let out = fmm::reinitialize(&input, &opts).unwrap();
    out.check_invariants().unwrap();
    (input, out)
}

#[test]
fn reinitialisation_keeps_zero_crossings_in_place() {
    for order in [Order::First, Order::Second] {
        let (input, out) = sphere_reinit(order, 1.0);
        let (mut max_shift, mut edges) = (0.0f64, 0);
        for_box(&input, 1, |c| {
            let a = input.value(c) as f64;
            for ax in AXES {
                let n = add(c, ax);
                let b = input.value(n) as f64;
                if (a < 0.0) != (b < 0.0) {
                    let (oa, ob) = (out.value(c) as f64, out.value(n) as f64);
                    assert!((oa < 0.0) == (a < 0.0) && (ob < 0.0) == (b < 0.0), "sign at {c:?}");
                    let shift = (a / (a - b) - oa / (oa - ob)).abs();
                    max_shift = max_shift.max(shift);
                    edges += 1;
                }
            }
        });
        println!("sphere r = 20, {order:?} order: {edges} crossing edges, max shift {max_shift:.5} voxel");
        assert!(edges > 1000);
        assert!(max_shift < 0.01, "{order:?}: a zero crossing moved by {max_shift} voxel");
    }
}

#[test]
fn a_badly_scaled_field_comes_back_to_unit_gradient() {
    for order in [Order::First, Order::Second] {
        let (input, out) = sphere_reinit(order, 3.0);
        let g = out.gamma();
        let (mut max_dev, mut sum, mut n) = (0.0f64, 0.0, 0usize);
        let (mut in_dev, mut in_n) = (0.0f64, 0usize);
        for_box(&out, 0, |c| {
            let v = out.value(c);
            // Central differences where the whole 7-point star is inside the band.
            let nb: Vec<f32> =
                AXES.iter().flat_map(|&a| [out.value(add(c, a)), out.value(sub(c, a))]).collect();
            if v.abs() < g && nb.iter().all(|x| x.abs() < g) {
                let gr: f64 = (0..3)
                    .map(|i| ((nb[2 * i] - nb[2 * i + 1]) as f64 / 2.0).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let dev = (gr - 1.0).abs();
                max_dev = max_dev.max(dev);
                sum += dev;
                n += 1;
            }
            let iv = input.value(c) as f64;
            let gi = input.gamma() as f64;
            if iv.abs() < gi * 0.5 && v.abs() < g {
                in_dev = in_dev.max(iv.abs());
                in_n += 1;
            }
        });
        println!(
            "3·φ sphere, {order:?} order: | |∇φ| − 1 | mean {:.5}, max {max_dev:.5} over {n} voxels",
            sum / n as f64
        );
        assert!(n > 5000 && in_n > 0 && in_dev > 0.0);
        // Second order: every voxel within 2 %; first order (O(h) errors) on average.
        let dev = if order == Order::Second { max_dev } else { sum / n as f64 };
        assert!(dev <= 0.02, "{order:?}: |∇φ| deviates from 1 by {dev}");
    }
}

/// Asserts that two grids read bit-identical values over `a`'s box grown by 2.
fn assert_bitwise<A: LevelSet, B: LevelSet>(a: &A, b: &B) {
    assert_eq!(a.band_voxels(), b.band_voxels());
    for_box(a, 2, |c| assert_eq!(a.value(c).to_bits(), b.value(c).to_bits(), "at {c:?}"));
}

#[test]
fn tiles_and_dtgrid_give_identical_results_at_any_width() {
    let shapes = [
        Shape::Torus { center: [-31.3, 12.2, -7.9], major_radius: 11.0, minor_radius: 3.7 },
        Shape::Box { center: [5.0, -3.5, 40.2], half_extents: [7.5, 5.2, 3.3] },
        Shape::Union(vec![
            Shape::Sphere { center: [0.0, 0.0, 0.0], radius: 6.0 },
            Shape::Sphere { center: [7.0, 1.0, -2.0], radius: 5.0 },
        ]),
    ];
    for shape in &shapes {
        let tiles = tiles_from_shape(shape, GridSpec::default()).unwrap();
        let dt = dtgrid_from(&tiles);
        for order in [Order::First, Order::Second] {
            for half_width in [None, Some(1.5), Some(5.5)] {
                let opts = FmmOptions { order, half_width, ..Default::default() };
                let t = fmm::reinitialize(&tiles, &opts).unwrap();
                let d = reinit_dt(&dt, &opts).unwrap();
                t.check_invariants().unwrap();
                d.check_invariants().unwrap();
                assert_eq!(t.spec().half_width, half_width.unwrap_or(3.0));
                assert_bitwise(&t, &d);
                // Beyond the band: ±W·voxel with the sign of the shape.
                let g = t.gamma();
                for_box(&t, 3, |c| {
                    let v = t.value(c);
                    let exact = shape.sdf(t.spec().world(c));
                    if exact.abs() > g as f64 + 1.0 {
                        assert_eq!(v, if exact < 0.0 { -g } else { g }, "at {c:?}");
                    }
                    // First-order FMM overestimates distances from corners (a point source
                    // in Sec. 4 is off by up to 7 %): a margin of 20 % + 0.5 voxel.
                    // (A union's sdf is a distance only outside.)
                    let is_distance = !matches!(shape, Shape::Union(_)) || exact >= 0.0;
                    if is_distance && exact.abs() < 0.8 * g as f64 - 0.5 {
                        assert!(v.abs() < g, "band voxel {c:?} missing: {v} vs {exact}");
                    }
                });
            }
        }
    }
}

#[test]
fn widening_the_band_matches_the_exact_distance() {
    // A band of half-width 3 widened to 8 voxels, voxel size 0.5, sphere of radius 10.
    let spec = GridSpec::new(0.5, [0.25, -0.5, 0.0], 3.0).unwrap();
    let shape = Shape::Sphere { center: [0.1, 0.2, -0.3], radius: 10.0 };
    let tiles = tiles_from_shape(&shape, spec).unwrap();
    let opts = FmmOptions { order: Order::Second, half_width: Some(8.0), ..Default::default() };
    let t0 = Instant::now();
    let out = fmm::reinitialize(&tiles, &opts).unwrap();
    let secs = t0.elapsed().as_secs_f64();
    let g = out.gamma();
    assert_eq!(g, 4.0);
    let (mut max, mut n) = (0.0f64, 0);
    for_box(&out, 1, |c| {
        let exact = shape.sdf(out.spec().world(c));
        if exact.abs() < g as f64 - 0.5 {
            max = max.max((out.value(c) as f64 - exact).abs());
            n += 1;
        }
    });
    println!("widened to W = 8: {n} voxels, max error {:.4} voxel, {secs:.3} s", max / 0.5);
    // Second-order FMM on a sphere of radius 20 voxels: a few hundredths of a voxel.
    assert!(max / 0.5 < 0.05, "max error {} voxel", max / 0.5);
    assert!(n > 50_000);
}

/// The march is sequential; its determinism comes from breaking heap ties by coordinate.
/// The same frozen set given in another order (and a reinitialisation in a 1- and a
/// 2-thread pool) gives the same bits.
#[test]
fn results_do_not_depend_on_input_order_or_threads() {
    let shape = Shape::spiral_default([0.0; 3], 20.0, 12.0);
    let tiles = tiles_from_shape(&shape, GridSpec::default()).unwrap();
    let same = |a: &TileGrid, b: &TileGrid| {
        assert_eq!(a.tile_coords(), b.tile_coords());
        for p in 0..a.len() {
            assert_eq!(a.tile(p).0.map(f32::to_bits), b.tile(p).0.map(f32::to_bits), "tile {p}");
        }
    };
    let frozen = interface_voxels(&tiles);
    let mut shuffled = frozen.clone();
    fastrand::Rng::with_seed(5).shuffle(&mut shuffled);
    shuffled.reverse();
    assert_ne!(frozen, shuffled);
    let spec = GridSpec::new(1.0, [0.0; 3], 4.0).unwrap();
    for order in [Order::First, Order::Second] {
        let inside = |c: Coord| shape.sdf(spec.world(c)) < 0.0;
        let a = fmm::tiles_from_interface(spec, &frozen, order, inside).unwrap();
        let b = fmm::tiles_from_interface(spec, &shuffled, order, inside).unwrap();
        same(&a, &b);
    }
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            fmm::reinitialize(
                &tiles,
                &FmmOptions { order: Order::Second, half_width: Some(4.0), ..Default::default() },
            )
            .unwrap()
        })
    };
    same(&run(1), &run(2));
}

#[test]
fn arrival_times_from_a_plane_and_a_point() {
    let spec = GridSpec::new(0.25, [0.0; 3], 3.0).unwrap();
    // A plane of seeds at z = 0 (x, y in 0..16) with F = 2: T = z·h / 2 exactly.
    let seeds: Vec<(Coord, f64)> =
        (0..16).flat_map(|y| (0..16).map(move |x| (Coord::new(x, y, 0), 0.0))).collect();
    for order in [Order::First, Order::Second] {
        let at = fmm::arrival_times(&spec, &seeds, |_| 2.0, 1.0, order).unwrap();
        let t = at.time(Coord::new(7, 8, 6)).unwrap();
        assert!((t - 6.0 * 0.25 / 2.0).abs() < 1e-12, "{t}");
        assert!(at.iter().all(|(_, t)| (0.0..=1.0).contains(&t)));
        assert_eq!(at.time(Coord::new(7, 8, 9)), None); // T = 1.125 > max_time
    }
    // A point source with speed 1 vs 2: times halve (up to rounding).
    let seed = [(Coord::new(-5, 3, 1000), 0.5)];
    let a = fmm::arrival_times(&spec, &seed, |_| 1.0, 2.5, Order::Second).unwrap();
    let b = fmm::arrival_times(&spec, &seed, |_| 2.0, 1.5, Order::Second).unwrap();
    let mut n = 0;
    for (c, ta) in a.iter() {
        let tb = b.time(c).expect("reached by the faster front");
        assert!(((ta - 0.5) - 2.0 * (tb - 0.5)).abs() < 1e-12 * (1.0 + ta), "{c:?}: {ta} {tb}");
        // Within a few tenths of a voxel of the Euclidean distance (the paper's point
        // source errors are of this size, Sec. 4).
        let d = spec.world(c);
        let o = spec.world(seed[0].0);
        let r = ((d[0] - o[0]).powi(2) + (d[1] - o[1]).powi(2) + (d[2] - o[2]).powi(2)).sqrt();
        assert!((ta - 0.5 - r).abs() < 0.4 * 0.25 + 0.1 * r, "{c:?}: {ta} vs {r}");
        n += 1;
    }
    assert!(n > 1000 && b.len() >= a.len());
    // Seeds near the end of the i32 range: the march stops there, no overflow.
    let edge = [(Coord::new(i32::MAX, i32::MIN, i32::MAX), 0.0)];
    // One voxel costs h / F = 0.25: the seed and its three neighbours inside the range.
    let e = fmm::arrival_times(&spec, &edge, |_| 1.0, 0.3, Order::First).unwrap();
    assert_eq!(e.len(), 4);
    // A voxel seeded twice starts at its smallest time, in either order.
    let c = Coord::new(2, 2, 2);
    for seeds in [[(c, 0.7), (c, 0.2)], [(c, 0.2), (c, 0.7)]] {
        let t = fmm::arrival_times(&spec, &seeds, |_| 1.0, 0.5, Order::First).unwrap();
        assert_eq!(t.time(c), Some(0.2));
    }
}

#[test]
fn distance_of_a_dense_field() {
    // 3·φ of a sphere on a 40³ box with voxel size 0.5, like scikit-fmm's distance.
    let h = 0.5f32;
    let c = [10.1f64, 9.7, 10.3];
    let field = DenseField::from_fn(Coord::new(0, 0, 0), [40, 41, 39], |v| {
        let p = [v.x as f64 * h as f64, v.y as f64 * h as f64, v.z as f64 * h as f64];
        let r = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
        (3.0 * (r - 6.0)) as f32
    })
    .unwrap();
    let opts = FmmOptions { order: Order::Second, half_width: Some(4.0), ..Default::default() };
    let out = fmm::distance_dense(&field, h, &opts).unwrap();
    let g = 4.0 * h;
    let mut max = 0.0f64;
    for (v, (f, o)) in field.iter().zip(out.data()).enumerate() {
        let exact = f.1 as f64 / 3.0;
        assert_eq!((*o < 0.0), (f.1 < 0.0), "sign at {v}");
        if exact.abs() < g as f64 - h as f64 {
            max = max.max((*o as f64 - exact).abs());
        } else if exact.abs() > g as f64 + h as f64 {
            assert_eq!(o.abs(), g);
        }
    }
    println!("dense 3·φ sphere, second order: max error {:.4} voxel", max / h as f64);
    assert!(max < 0.05 * h as f64, "max error {max}");
}

#[test]
fn bad_input_is_an_error() {
    let f = DenseField::from_fn(Coord::new(0, 0, 0), [8, 8, 8], |c| c.x as f32 - 3.5).unwrap();
    let o = FmmOptions::default();
    let mut nan = f.clone();
    nan.set(Coord::new(1, 2, 3), f32::NAN).unwrap();
    assert!(matches!(fmm::distance_dense(&nan, 1.0, &o), Err(FmmError::NonFinite { .. })));
    // ±∞ is a far-away distance, as everywhere else: far from the interface it changes
    // nothing, bit for bit; next to it the crossing lies at the finite neighbour.
    let mut inf = f.clone();
    for c in [Coord::new(7, 7, 7), Coord::new(0, 3, 1)] {
        inf.set(c, if c.x > 3 { f32::INFINITY } else { f32::NEG_INFINITY }).unwrap();
    }
    assert_eq!(
        fmm::distance_dense(&inf, 1.0, &o).unwrap(),
        fmm::distance_dense(&f, 1.0, &o).unwrap()
    );
    let mut edge = f.clone();
    edge.set(Coord::new(4, 2, 2), f32::INFINITY).unwrap();
    let d = fmm::distance_dense(&edge, 1.0, &o).unwrap();
    assert_eq!(d.get(Coord::new(3, 2, 2)), Some(-0.0));
    assert_eq!(d.get(Coord::new(4, 2, 2)), Some(1.0));
    assert!(d.data().iter().all(|v| v.is_finite()));
    let flat = DenseField::new(Coord::new(0, 0, 0), [5, 5, 5], 2.0).unwrap();
    assert_eq!(fmm::distance_dense(&flat, 1.0, &o), Err(FmmError::NoInterface));
    assert!(fmm::distance_dense(&f, 0.0, &o).is_err());
    assert!(
        fmm::distance_dense(&f, 1.0, &FmmOptions { half_width: Some(1.0), ..o.clone() }).is_err()
    );
    assert!(fmm::distance_dense(&f, 1.0, &FmmOptions { half_width: Some(f32::NAN), ..o.clone() })
        .is_err());
    // A plane: exact in the first and second order.
    let d = fmm::distance_dense(&f, 1.0, &o).unwrap();
    assert_eq!(d.get(Coord::new(5, 4, 4)), Some(1.5));
    // Empty grids.
    let empty = TileGrid::new(GridSpec::default());
    assert_eq!(fmm::reinitialize(&empty, &o).unwrap_err(), FmmError::NoInterface);
    let empty_dt = dtgrid_from(&empty);
    assert_eq!(reinit_dt(&empty_dt, &o).unwrap_err(), FmmError::NoInterface);
    // Speeds.
    let spec = GridSpec::default();
    let seed = [(Coord::new(0, 0, 0), 0.0)];
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let r = fmm::arrival_times(
            &spec,
            &seed,
            |p| if p[0] > 2.5 { bad } else { 1.0 },
            10.0,
            Order::First,
        );
        assert!(matches!(r, Err(FmmError::BadSpeed { .. })), "{bad}: {:?}", r.err());
    }
    assert_eq!(
        fmm::arrival_times(&spec, &[], |_| 1.0, 1.0, Order::First).err(),
        Some(FmmError::NoSeeds)
    );
    assert!(fmm::arrival_times(&spec, &seed, |_| 1.0, f64::NAN, Order::First).is_err());
    assert!(fmm::arrival_times(
        &spec,
        &[(Coord::new(0, 0, 0), f64::NAN)],
        |_| 1.0,
        1.0,
        Order::First
    )
    .is_err());
}

#[test]
fn bands_near_the_end_of_the_coordinate_range() {
    // A sphere next to the end of the i32 range (which the tiles cover exactly): the march
    // stops at the last representable voxel, never wraps around or panics.
    let top = (i32::MAX >> 2) as f64 * 4.0;
    let shape = Shape::Sphere { center: [top - 12.0, 0.0, -top + 12.0], radius: 4.0 };
    let tiles = tiles_from_shape(&shape, GridSpec::default()).unwrap();
    let dt = dtgrid_from(&tiles);
    let o = FmmOptions { order: Order::Second, half_width: None, ..Default::default() };
    let t = fmm::reinitialize(&tiles, &o).unwrap();
    assert_bitwise(&t, &reinit_dt(&dt, &o).unwrap());
    let wide = FmmOptions { order: Order::Second, half_width: Some(20.0), ..Default::default() };
    let tw = fmm::reinitialize(&tiles, &wide).unwrap();
    let d = reinit_dt(&dt, &wide).unwrap();
    d.check_invariants().unwrap();
    assert_bitwise(&tw, &d);
    let (_, hi) = d.bounding_box().unwrap();
    assert_eq!((hi.x, tw.value(Coord::new(i32::MAX, 0, -(top as i32) + 12))), (i32::MAX, 11.0));
}

#[test]
fn reinitialised_grids_feed_the_evolution_engine() {
    use sparse_levelset::evolve::{Flow, GridKind, Lanes, Settings, Simulation};
    // A widened, reinitialised band from either grid evolves under mean curvature flow
    // to the same band, bit for bit (the engine checks flags and values as it runs).
    let shape = Shape::Torus { center: [0.4, -0.3, 0.2], major_radius: 12.0, minor_radius: 4.0 };
    let tiles = tiles_from_shape(&shape, GridSpec::default()).unwrap();
    let dt = dtgrid_from(&tiles);
    let opts = FmmOptions { order: Order::Second, half_width: Some(4.0), ..Default::default() };
    let t = fmm::reinitialize(&tiles, &opts).unwrap();
    let d = reinit_dt(&dt, &opts).unwrap();
    let flow = Flow::mean_curvature(1.0);
    let mut a = Simulation::from_tile_grid(
        GridKind::Tiles(Lanes::Simd),
        t,
        flow.clone(),
        Settings::paper_upwind1(),
    )
    .unwrap();
    let mut b = Simulation::from_dtgrid(d, flow, Settings::paper_upwind1()).unwrap();
    for _ in 0..5 {
        a.step().unwrap();
        b.step().unwrap();
    }
    assert_eq!(a.checksum(), b.checksum());
}

#[test]
fn noisy_fields_give_the_same_result_on_every_representation() {
    // Many small components and sign changes everywhere: no panic, and tiles = DT-Grid
    // = the dense path. A shell of +2.5 around the noise keeps the band valid (every
    // voxel a grid does not store is outside on both grids).
    use sparse_levelset::storage::convert::{dtgrid_from_dense, tiles_from_dense};
    let mut rng = fastrand::Rng::with_seed(11);
    let lo = Coord::new(-9, 4, -13);
    let dims = [19, 14, 17];
    let mut field = DenseField::new(lo, dims, 2.5).unwrap();
    for z in 2..dims[2] as i32 - 2 {
        for y in 2..dims[1] as i32 - 2 {
            for x in 2..dims[0] as i32 - 2 {
                let c = Coord::new(lo.x + x, lo.y + y, lo.z + z);
                field.set(c, rng.f32() * 4.0 - 2.0).unwrap();
            }
        }
    }
    let spec = GridSpec::default();
    let tiles = tiles_from_dense(&field, spec).unwrap();
    let dt = dtgrid_from_dense(&field, spec).unwrap();
    for order in [Order::First, Order::Second] {
        let o = FmmOptions { order, half_width: Some(2.5), ..Default::default() };
        let t = fmm::reinitialize(&tiles, &o).unwrap();
        let d = reinit_dt(&dt, &o).unwrap();
        t.check_invariants().unwrap();
        assert_bitwise(&t, &d);
        let dense = fmm::distance_dense(&field, 1.0, &o).unwrap();
        assert!(dense.data().iter().all(|v| v.is_finite() && v.abs() <= 2.5));
    }
    // Without the shell the DT-Grid reads whole half-rows beyond the noise as inside
    // (its sign rule follows the columns' end values): sign changes between voxels it
    // does not store, which the interface layer cannot see. The march must still stay
    // within the half-width of the voxels it starts from.
    let mut raw = DenseField::new(lo, dims, 0.0).unwrap();
    raw.data_mut().iter_mut().for_each(|v| *v = rng.f32() * 4.0 - 2.0);
    let dt = dtgrid_from_dense(&raw, spec).unwrap();
    let d = reinit_dt(
        &dt,
        &FmmOptions { order: Order::Second, half_width: Some(2.5), ..Default::default() },
    )
    .unwrap();
    let (blo, bhi) = d.bounding_box().unwrap();
    assert!(blo.x >= lo.x - 4 && bhi.x <= lo.x + dims[0] as i32 + 3, "{blo:?} {bhi:?}");
}

/// A march's progress reaches its total, also when the array runs out of voxels before the
/// band's width (a small array).
#[test]
fn progress_reaches_its_total() {
    use sparse_levelset::progress::Progress;
    use std::sync::{Arc, Mutex};
    let field = DenseField::from_fn(Coord::new(0, 0, 0), [12, 12, 12], |c| {
        ((c.x - 6) * (c.x - 6) + (c.y - 6) * (c.y - 6) + (c.z - 6) * (c.z - 6)) as f32 - 9.0
    })
    .unwrap();
    let last = Arc::new(Mutex::new((0u64, 0u64)));
    let seen = last.clone();
    let progress = Progress::new(move |done, total| {
        *seen.lock().unwrap() = (done, total);
        true
    });
    let opts = FmmOptions { half_width: Some(40.0), progress, ..Default::default() };
    fmm::distance_dense(&field, 1.0, &opts).unwrap();
    let (done, total) = *last.lock().unwrap();
    assert!(total > 0 && done == total, "{done} of {total}");
}

// ---------------------------------------------------------------------------------------
// Dense arrays with per-axis spacing, periodic axes, obstacles, speeds and extension
// (scikit-fmm's functions).

use fmm::{DenseGrid, DenseOptions};
use sparse_levelset::error::{Error, ErrorKind};

/// `f` at every voxel of `dims` (x fastest), with the voxel's world position `i · h`.
fn dense_field(dims: [usize; 3], h: [f64; 3], f: impl Fn([f64; 3]) -> f64) -> Vec<f32> {
    let mut out = Vec::with_capacity(dims.iter().product());
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                out.push(f([x as f64 * h[0], y as f64 * h[1], z as f64 * h[2]]) as f32);
            }
        }
    }
    out
}

fn positions(dims: [usize; 3], h: [f64; 3]) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                out.push([x as f64 * h[0], y as f64 * h[1], z as f64 * h[2]]);
            }
        }
    }
    out
}

fn norm(p: [f64; 3], c: [f64; 3]) -> f64 {
    ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt()
}

fn opts(order: Order) -> DenseOptions {
    DenseOptions { order, ..Default::default() }
}

#[test]
fn dense_anisotropic_distance_to_a_sphere() {
    // Spacing 0.5, 0.7, 0.9 along x, y, z; φ = 2·(r − 5), not a distance.
    let dims = [36, 26, 20];
    let h = [0.5, 0.7, 0.9];
    let c = [8.9, 9.1, 8.6];
    let phi = dense_field(dims, h, |p| 2.0 * (norm(p, c) - 5.0));
    let grid = DenseGrid { dims, spacing: h, periodic: [false; 3] };
    for (order, near_tol, all_tol) in [(Order::First, 0.25, 0.6), (Order::Second, 0.06, 0.2)] {
        let out = fmm::dense_distance(&phi, &grid, None, &opts(order)).unwrap();
        assert!(out.reached.iter().all(|&r| r));
        let (mut near, mut all) = (0.0f64, 0.0f64);
        for (p, d) in positions(dims, h).iter().zip(&out.values) {
            let e = (*d as f64 - (norm(*p, c) - 5.0)).abs();
            all = all.max(e);
            if (norm(*p, c) - 5.0).abs() < 2.0 {
                near = near.max(e);
            }
        }
        println!("anisotropic sphere, {order:?}: max error {near:.4} near, {all:.4} everywhere");
        assert!(near < near_tol && all < all_tol, "{order:?}: {near} near, {all} all");
    }
}

#[test]
fn dense_isotropic_distance_is_bitwise_the_sparse_march() {
    // The dense API on an isotropic, non-periodic grid without obstacles gives the values
    // of `distance_dense` (the march of the sparse grids) bit for bit.
    let dims = [30, 27, 25];
    let c = [7.3, 6.9, 6.1];
    let phi = dense_field(dims, [0.4; 3], |p| 3.0 * (norm(p, c) - 4.0) + 0.2 * p[0].sin());
    let field = DenseField::from_vec(Coord::new(0, 0, 0), dims, phi.clone()).unwrap();
    for order in [Order::First, Order::Second] {
        // The voxel size as the f32 that `distance_dense` takes.
        let h = 0.4f32 as f64;
        let dense = fmm::dense_distance(&phi, &DenseGrid::new(dims, h), None, &opts(order));
        let o = FmmOptions { order, half_width: Some(100.0), ..Default::default() };
        let sparse = fmm::distance_dense(&field, 0.4, &o).unwrap();
        let dense = dense.unwrap();
        for (a, b) in dense.values.iter().zip(sparse.data()) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
    }
}

#[test]
fn dense_periodic_axes_wrap() {
    // A slab inside 2.5 < x < 6.5 on a periodic x axis of 32 voxels: the distance of
    // voxel x is the distance to the nearest copy of the slab.
    let dims = [32, 6, 1];
    let phi = dense_field(dims, [1.0; 3], |p| (p[0] - 4.5).abs() - 2.0);
    let periodic = DenseGrid { dims, spacing: [1.0; 3], periodic: [true, false, false] };
    let plain = DenseGrid::new(dims, 1.0);
    let exact = |x: f64, wrap: bool| {
        let d = (x - 4.5).abs();
        let d = if wrap { d.min(32.0 - d) } else { d };
        d - 2.0
    };
    for order in [Order::First, Order::Second] {
        let a = fmm::dense_distance(&phi, &periodic, None, &opts(order)).unwrap();
        let b = fmm::dense_distance(&phi, &plain, None, &opts(order)).unwrap();
        for (i, p) in positions(dims, [1.0; 3]).iter().enumerate() {
            assert!((a.values[i] as f64 - exact(p[0], true)).abs() < 1e-5, "{p:?} {}", a.values[i]);
            assert!((b.values[i] as f64 - exact(p[0], false)).abs() < 1e-5, "{p:?}");
        }
    }
    // Rolling the array along the periodic axis rolls the result.
    let dims = [24, 20, 1];
    // A circle centred at (3.2, 9.7) on the periodic 24 x 20 array: the distance to the
    // nearest of its periodic copies.
    let circle = |p: [f64; 3]| {
        let dx = (p[0] - 3.2).abs();
        let dy = (p[1] - 9.7).abs();
        dx.min(24.0 - dx).hypot(dy.min(20.0 - dy)) - 5.0
    };
    let phi = dense_field(dims, [1.0; 3], circle);
    let grid = DenseGrid { dims, spacing: [1.0; 3], periodic: [true, true, false] };
    let out = fmm::dense_distance(&phi, &grid, None, &opts(Order::Second)).unwrap();
    let roll = |v: &[f32], k: usize| {
        let mut r = v.to_vec();
        for y in 0..20 {
            for x in 0..24 {
                r[y * 24 + (x + k) % 24] = v[y * 24 + x];
            }
        }
        r
    };
    let rolled = fmm::dense_distance(&roll(&phi, 7), &grid, None, &opts(Order::Second)).unwrap();
    for (a, b) in roll(&out.values, 7).iter().zip(&rolled.values) {
        assert!((a - b).abs() < 1e-5, "{a} vs {b}");
    }
    // The circle crosses the x = 0 face: voxels at the far end are close to it.
    let far = 23 + 10 * 24;
    let exact = norm([-1.0, 10.0, 0.0], [3.2, 9.7, 0.0]) - 5.0;
    assert!((out.values[far] as f64 - exact).abs() < 0.05, "{}", out.values[far]);
}

#[test]
fn dense_obstacles_are_not_crossed() {
    // A source line at x = 0.5 (φ = x − 0.5), a wall of obstacles at x = 10 for y < 15:
    // behind the wall the front comes round its end at (10, 15).
    let dims = [30, 30, 1];
    let phi = dense_field(dims, [1.0; 3], |p| p[0] - 0.5);
    // ... and the walls x = 25 and y = 25 of the corner x, y ≥ 25, whose inside is cut off.
    let mask: Vec<bool> = positions(dims, [1.0; 3])
        .iter()
        .map(|p| {
            let wall = p[0] == 10.0 && p[1] < 15.0;
            let corner = p[0] >= 25.0 && p[1] >= 25.0 && (p[0] == 25.0 || p[1] == 25.0);
            wall || corner
        })
        .collect();
    let grid = DenseGrid::new(dims, 1.0);
    let out = fmm::dense_distance(&phi, &grid, Some(&mask), &opts(Order::Second)).unwrap();
    let mut worst = 0.0f64;
    for (i, p) in positions(dims, [1.0; 3]).iter().enumerate() {
        if mask[i] || (p[0] > 25.0 && p[1] > 25.0) {
            assert!(!out.reached[i] && out.values[i] == 0.0, "{p:?} reached");
            continue;
        }
        assert!(out.reached[i], "{p:?} not reached");
        if p[0] > 10.0 && p[1] < 15.0 {
            // The geodesic distance round the wall's end (10, 15): never shorter (the
            // front does not cross the wall; the obstacle voxels end between y = 14 and
            // 15, hence 0.6 voxel of slack), and at most 1.2 voxels longer (the fan of
            // characteristics round a corner is where the march is least accurate; along
            // the wall the update has a single direction). Straight behind the wall, the
            // geodesic is more than twice the distance without the wall.
            let geo = 9.5 + ((p[0] - 10.0).powi(2) + (p[1] - 15.0).powi(2)).sqrt();
            let d = out.values[i] as f64;
            assert!(d > geo - 0.6 && d < geo + 1.2, "{p:?}: {d} vs {geo}");
            worst = worst.max(d - geo);
        }
    }
    println!("round the wall: distance up to {worst:.3} voxel longer than the geodesic");
}

#[test]
fn dense_travel_time_constant_and_two_speed_media() {
    // Constant speed 2: the travel time is the distance over 2.
    let dims = [24, 22, 20];
    let h = [0.6, 0.5, 0.7];
    let c = [7.0, 5.3, 6.6];
    let phi = dense_field(dims, h, |p| norm(p, c) - 3.0);
    let grid = DenseGrid { dims, spacing: h, periodic: [false; 3] };
    let two = vec![2.0f32; phi.len()];
    for order in [Order::First, Order::Second] {
        let t = fmm::dense_travel_time(&phi, &two, &grid, None, &opts(order)).unwrap();
        let d = fmm::dense_distance(&phi, &grid, None, &opts(order)).unwrap();
        let mut max = 0.0f32;
        for (t, d) in t.values.iter().zip(&d.values) {
            max = max.max((t - d.abs() / 2.0).abs());
        }
        // The same march, up to rounding (which may flip a choice between nearly equal
        // neighbours): a hundredth of a voxel (0.5) in time (/ 2).
        println!("travel time at speed 2 vs distance / 2, {order:?}: max difference {max:.2e}");
        assert!(max <= 0.01 * 0.5 / 2.0, "{order:?}: {max}");
    }
    // A plane front from x = 0.25 through speed 1 for x < 10.25 and 3 beyond: T is
    // piecewise linear, and every one-sided difference of it is exact.
    let dims = [40, 5, 5];
    let phi = dense_field(dims, [0.5; 3], |p| p[0] - 0.25);
    let speed = dense_field(dims, [0.5; 3], |p| if p[0] < 10.25 { 1.0 } else { 3.0 });
    let grid = DenseGrid::new(dims, 0.5);
    let first = fmm::dense_travel_time(&phi, &speed, &grid, None, &opts(Order::First)).unwrap();
    let second = fmm::dense_travel_time(&phi, &speed, &grid, None, &opts(Order::Second)).unwrap();
    let mut max = 0.0f64;
    for (i, p) in positions(dims, [0.5; 3]).iter().enumerate() {
        let x = p[0];
        // First order: each voxel adds h / F at the voxel (the cost of its own speed).
        let discrete = if x < 10.25 { (x - 0.25).abs() } else { 9.75 + (x - 10.0) / 3.0 };
        let t = first.values[i] as f64;
        assert!((t - discrete).abs() < 1e-5, "first order, x = {x}: {t} vs {discrete}");
        // Second order against the continuous solution with the jump midway between
        // the voxels of speeds 1 and 3.
        let exact = if x < 10.25 { (x - 0.25).abs() } else { 10.0 + (x - 10.25) / 3.0 };
        max = max.max((second.values[i] as f64 - exact).abs());
    }
    println!("two-speed medium, second order: max error {max:.4}");
    assert!(max < 0.1, "{max}");
}

#[test]
fn dense_travel_time_speed_zero_is_an_obstacle() {
    // scikit-fmm's doctest: speed 0 masks the element.
    let grid = DenseGrid::new([5, 1, 1], 1.0);
    let phi = [-1.0, -1.0, 0.0, 1.0, 1.0];
    let t =
        fmm::dense_travel_time(&phi, &[1.0, 1.0, 1.0, 1.0, 0.0], &grid, None, &opts(Order::Second))
            .unwrap();
    assert_eq!(t.values, [2.0, 1.0, 0.0, 1.0, 0.0]);
    assert_eq!(t.reached, [true, true, true, true, false]);
    // Speeds below MIN_SPEED too.
    let t2 = fmm::dense_travel_time(
        &phi,
        &[1.0, 1.0, 1.0, 1.0, 1e-30],
        &grid,
        None,
        &opts(Order::Second),
    )
    .unwrap();
    assert_eq!(t2.reached, t.reached);
}

#[test]
fn dense_extension_is_constant_along_normals() {
    // F = 2 + cos(angle) around a circle of radius 8: constant along the normals, so the
    // extension of F from the circle is F itself (away from the centre).
    let dims = [48, 44, 1];
    let c = [23.3, 21.6, 0.0];
    let h = [0.9, 1.0, 1.0];
    let phi = dense_field(dims, h, |p| norm(p, c) - 8.0);
    let f = |p: [f64; 3]| 2.0 + ((p[1] - c[1]).atan2(p[0] - c[0])).cos();
    let speed = dense_field(dims, h, f);
    let grid = DenseGrid { dims, spacing: h, periodic: [false; 3] };
    for order in [Order::First, Order::Second] {
        let out =
            fmm::dense_extension_velocities(&phi, &speed, None, &grid, None, &opts(order)).unwrap();
        let d = fmm::dense_distance(&phi, &grid, None, &opts(order)).unwrap();
        assert_eq!(out.distance, d, "the distance of the extension is the plain distance");
        let (mut near, mut far) = (0.0f64, 0.0f64);
        for (i, p) in positions(dims, h).iter().enumerate() {
            let r = norm(*p, c);
            let e = (out.extension[i] as f64 - f(*p)).abs();
            if (r - 8.0).abs() < 1.5 {
                near = near.max(e);
            } else if r > 4.0 {
                far = far.max(e);
            }
        }
        println!("extension of 2 + cos θ, {order:?}: max error {near:.4} near, {far:.4} at r > 4");
        assert!(near < 0.08 && far < 0.06, "{order:?}: {near} near, {far} far");
    }
    // A uniform speed stays uniform; scikit-fmm's 1-D doctests.
    let u = fmm::dense_extension_velocities(
        &phi,
        &vec![1.5; phi.len()],
        None,
        &grid,
        None,
        &opts(Order::Second),
    )
    .unwrap();
    assert!(u.extension.iter().all(|&v| v == 1.5));
    let g6 = DenseGrid::new([6, 1, 1], 1.0);
    let phi6 = [1.0, -1.0, 1.0, 1.0, 1.0, 1.0];
    let sp6 = [4.0, 1.0, 2.0, 2.0, 2.0, 2.0];
    let e = fmm::dense_extension_velocities(&phi6, &sp6, None, &g6, None, &opts(Order::Second))
        .unwrap();
    assert_eq!(e.extension, [2.5, 2.5, 1.5, 1.5, 1.5, 1.5]);
    let g6p = DenseGrid { periodic: [true, false, false], ..g6 };
    let e = fmm::dense_extension_velocities(&phi6, &sp6, None, &g6p, None, &opts(Order::Second))
        .unwrap();
    assert_eq!(e.extension, [2.5, 2.5, 1.5, 1.5, 1.5, 2.5]);
}

#[test]
fn dense_bad_input_is_an_error_before_any_work() {
    let grid = DenseGrid::new([4, 4, 1], 1.0);
    let phi: Vec<f32> = (0..16).map(|i| (i % 4) as f32 - 1.5).collect();
    let o = opts(Order::Second);
    let kind = |r: Result<fmm::DenseMarch, FmmError>| r.unwrap_err().kind();
    let mut nan = phi.clone();
    nan[5] = f32::NAN;
    assert_eq!(kind(fmm::dense_distance(&nan, &grid, None, &o)), ErrorKind::InvalidData);
    // NaN under an obstacle is not read.
    let mut mask = vec![false; 16];
    mask[5] = true;
    assert!(fmm::dense_distance(&nan, &grid, Some(&mask), &o).is_ok());
    assert_eq!(kind(fmm::dense_distance(&phi[..15], &grid, None, &o)), ErrorKind::InvalidInput);
    assert_eq!(
        kind(fmm::dense_distance(&phi, &grid, Some(&mask[..3]), &o)),
        ErrorKind::InvalidInput
    );
    for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let g = DenseGrid { spacing: [1.0, h, 1.0], ..grid.clone() };
        assert_eq!(kind(fmm::dense_distance(&phi, &g, None, &o)), ErrorKind::InvalidInput);
    }
    for w in [0.0, -1.0, f64::NAN] {
        let o = DenseOptions { narrow: Some(w), ..Default::default() };
        assert_eq!(kind(fmm::dense_distance(&phi, &grid, None, &o)), ErrorKind::InvalidInput);
    }
    let empty = DenseGrid::new([0, 4, 1], 1.0);
    assert_eq!(kind(fmm::dense_distance(&[], &empty, None, &o)), ErrorKind::InvalidInput);
    assert!(matches!(fmm::dense_distance(&[1.0; 16], &grid, None, &o), Err(FmmError::NoInterface)));
    for bad in [-1.0, f32::NAN, f32::INFINITY] {
        let mut s = vec![1.0f32; 16];
        s[3] = bad;
        let r = fmm::dense_travel_time(&phi, &s, &grid, None, &o);
        assert!(matches!(r, Err(FmmError::BadSpeed { .. })), "{bad}: {r:?}");
    }
    assert_eq!(
        kind(fmm::dense_travel_time(&phi, &[1.0; 15], &grid, None, &o)),
        ErrorKind::InvalidInput
    );
    let r = fmm::dense_extension_velocities(&phi, &[1.0; 16], Some(&[false; 3]), &grid, None, &o);
    assert_eq!(r.unwrap_err().kind(), ErrorKind::InvalidInput);
    // Exact zeros are on the zero level set, with or without a sign change.
    let z = fmm::dense_distance(&[0.0, 1.0, 1.0, 1.0], &DenseGrid::new([4, 1, 1], 0.5), None, &o)
        .unwrap();
    assert_eq!(z.values, [0.0, 0.5, 1.0, 1.5]);
}

#[test]
fn dense_progress_counts_voxels_and_cancels() {
    use sparse_levelset::progress::Progress;
    use std::sync::{Arc, Mutex};
    // 40 x 40 x 24 voxels: reports every 2^14 frozen voxels, as a share of the array.
    let dims = [40, 40, 24];
    let phi = dense_field(dims, [1.0; 3], |p| norm(p, [20.0, 20.0, 12.0]) - 6.0);
    let grid = DenseGrid::new(dims, 1.0);
    let seen = Arc::new(Mutex::new(Vec::new()));
    let s = seen.clone();
    let progress = Progress::new(move |done, total| {
        s.lock().unwrap().push((done, total));
        true
    });
    let o = DenseOptions { progress, ..Default::default() };
    fmm::dense_distance(&phi, &grid, None, &o).unwrap();
    let seen = seen.lock().unwrap().clone();
    assert!(seen.len() >= 2, "{seen:?}");
    assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0), "{seen:?}");
    let (done, total) = *seen.last().unwrap();
    assert!(total > 0 && done == total && seen[0].0 < total, "{seen:?}");
    // A callback that answers false stops the march.
    let o = DenseOptions { progress: Progress::new(|_, _| false), ..Default::default() };
    let r = fmm::dense_travel_time(&phi, &vec![1.0; phi.len()], &grid, None, &o);
    assert!(matches!(r, Err(FmmError::Cancelled(_))), "{r:?}");
}
