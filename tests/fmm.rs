//! Fast marching (Bærentzen, `fast-marching-3d.txt`): the accuracy experiment of Table 1,
//! reinitialisation of both sparse grids, widening, arrival times, the CLI, bad input.
//! Run with `--nocapture` to see the errors and timings.

use sparse_levelset::build::{dense_box, dtgrid_from_tiles, tiles_from_sdf, tiles_from_shape, SparseGrid};
use sparse_levelset::dense::DenseField;
use sparse_levelset::fmm::{self, FmmError, FmmOptions, Order};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::shapes::Shape;
use sparse_levelset::tiles::TileGrid;
use sparse_levelset::Coord;
use std::time::Instant;

const AXES: [Coord; 3] = [Coord::new(1, 0, 0), Coord::new(0, 1, 0), Coord::new(0, 0, 1)];

fn add(a: Coord, b: Coord) -> Coord {
    Coord::new(a.x + b.x, a.y + b.y, a.z + b.z)
}
fn sub(a: Coord, b: Coord) -> Coord {
    Coord::new(a.x - b.x, a.y - b.y, a.z - b.z)
}

/// Every voxel of a grid's box grown by `margin`.
fn for_box<G: SparseGrid>(g: &G, margin: u32, mut f: impl FnMut(Coord)) {
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
fn interface_voxels<G: SparseGrid>(g: &G) -> Vec<(Coord, f32)> {
    let gamma = g.spec().gamma();
    let mut out = Vec::new();
    for_box(g, 1, |c| {
        let v = g.value(c);
        if v.abs() < gamma
            && AXES.iter().any(|&a| {
                [add(c, a), sub(c, a)].iter().any(|&n| (g.value(n) < 0.0) != (v < 0.0))
            })
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
}

/// Table 1: ellipsoid, exact distances at the voxels next to the surface, march, compare
/// with the exact distance over the band |d| < `band` voxels.
fn ellipsoid_errors(radii: [f64; 3], order: Order) -> (Errors, f64) {
    let center = [0.31, -0.17, 0.23];
    let shape = Shape::Ellipsoid { center, radii };
    let band = 2.5f32;
    // The exact field (Eberly's foot point) on a band wider than the march.
    let exact = tiles_from_shape(&shape, GridSpec::new(1.0, [0.0; 3], band + 1.5).unwrap()).unwrap();
    let frozen = interface_voxels(&exact);
    let spec = GridSpec::new(1.0, [0.0; 3], band).unwrap();
    let t = Instant::now();
    let out = fmm::tiles_from_interface(spec, &frozen, order, |c| shape.sdf(spec.world(c)) < 0.0)
        .unwrap();
    let secs = t.elapsed().as_secs_f64();
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
    (Errors { mean: sum / n as f64, max, mean_marched: sum_m / n_m as f64, voxels: n, marched: n_m }, secs)
}

#[test]
fn table1_ellipsoid_accuracy() {
    for radii in [[10.0, 40.0, 60.0], [20.0, 80.0, 120.0]] {
        for order in [Order::First, Order::Second] {
            let (e, s) = ellipsoid_errors(radii, order);
            println!(
                "ellipsoid semi-axes {radii:?} {order:?}: mean {:.6} max {:.6} (marched only: mean {:.6}; {} band voxels, {} marched) {:.3} s",
                e.mean, e.max, e.mean_marched, e.voxels, e.marched, s
            );
        }
    }
}
