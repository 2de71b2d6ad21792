//! Criterion benchmarks of the storage layer: stencil traversal, random access and band
//! maintenance on the Sorted Tile List and on the DT-Grid, with identical arithmetic.
//! Benchmark ids carry the voxel counts so times convert to throughput.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use sparse_levelset::bench::{
    dtgrid_smooth7, dtgrid_star19, hrle_smooth7, tiles_smooth7, tiles_star19,
};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::{dtgrid_from, tiles_from_shape};
use sparse_levelset::storage::hrle::HrleGrid;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::{NeighbourTable, PaddedBlock, TileGrid};
use sparse_levelset::tools::csg::{csg, CsgOp};
use sparse_levelset::Coord;

fn grids(c: &mut Criterion) {
    let spec = GridSpec::default();
    for (name, shape) in [
        ("sphere_r60", Shape::Sphere { center: [0.0; 3], radius: 60.0 }),
        ("spiral_r50", Shape::spiral_default([0.0; 3], 50.0, 40.0)),
    ] {
        let tiles = tiles_from_shape(&shape, spec).unwrap();
        let dt = dtgrid_from(&tiles);
        let band = dt.len() as u64;
        let tvox = tiles.stored_voxels() as u64;

        let mut g = c.benchmark_group(format!("stencil/{name}"));
        g.throughput(Throughput::Elements(band));
        let (mut tout, mut dout) = (Vec::new(), Vec::new());
        g.bench_function(BenchmarkId::new("dtgrid_smooth7", format!("{band}pts")), |b| {
            b.iter(|| dtgrid_smooth7(&dt, &mut dout))
        });
        g.bench_function(BenchmarkId::new("tiles_smooth7", format!("{tvox}vox")), |b| {
            b.iter(|| tiles_smooth7(&tiles, &mut tout))
        });
        g.bench_function(BenchmarkId::new("dtgrid_star19", format!("{band}pts")), |b| {
            b.iter(|| dtgrid_star19(&dt, &mut dout))
        });
        g.bench_function(BenchmarkId::new("tiles_star19", format!("{tvox}vox")), |b| {
            b.iter(|| tiles_star19(&tiles, &mut tout))
        });
        g.finish();

        let probes: Vec<Coord> = dt.iter().step_by(7).map(|(c, _)| c).collect();
        let mut g = c.benchmark_group(format!("random_access/{name}"));
        g.throughput(Throughput::Elements(probes.len() as u64));
        g.bench_function("dtgrid", |b| b.iter(|| probes.iter().map(|&p| dt.value(p)).sum::<f32>()));
        g.bench_function("tiles", |b| {
            b.iter(|| probes.iter().map(|&p| tiles.value(p)).sum::<f32>())
        });
        g.finish();

        let mut g = c.benchmark_group(format!("rebuild/{name}"));
        g.throughput(Throughput::Elements(band));
        g.bench_function("dtgrid_dilate1", |b| b.iter(|| dt.dilate(1).unwrap()));
        g.bench_function("tiles_manage", |b| {
            b.iter_batched(
                || tiles.clone(),
                |mut t| t.manage_tiles().unwrap(),
                criterion::BatchSize::LargeInput,
            )
        });
        g.finish();

        // The per-tile work of the tile engine around its kernels: the star gather of
        // every tile (first order and HJ-WENO5 halos) and the neighbour table rebuilt
        // after tile management.
        let mut table = NeighbourTable::default();
        table.rebuild(tiles.tile_coords());
        let mut g = c.benchmark_group(format!("engine/{name}"));
        g.throughput(Throughput::Elements(tiles.len() as u64));
        g.bench_function(
            BenchmarkId::new("star_gather_r1", format!("{}tiles", tiles.len())),
            |b| b.iter(|| star_gather::<1>(&tiles, &table)),
        );
        g.bench_function(
            BenchmarkId::new("star_gather_r3", format!("{}tiles", tiles.len())),
            |b| b.iter(|| star_gather::<3>(&tiles, &table)),
        );
        g.bench_function(
            BenchmarkId::new("neighbour_table", format!("{}tiles", tiles.len())),
            |b| b.iter(|| table.rebuild(tiles.tile_coords())),
        );
        g.finish();
    }
}

/// Gathers every tile's star block; returns one value of each so that none is skipped.
fn star_gather<const R: usize>(grid: &TileGrid, table: &NeighbourTable) -> f32 {
    let mut block = PaddedBlock::<R>::new();
    let mut acc = 0.0;
    for pos in 0..grid.len() {
        block.gather_star_row(grid, pos, table.row(pos));
        acc += block.get(0, 0, 0);
    }
    acc
}

/// CSG of two overlapping spheres of radius 60 (a third of a radius apart) on tiles:
/// the merge of the bands and the stored result, per band voxel of both operands.
/// The H-RLE against the DT-Grid it is compared with in the paper (Table I): the same
/// 7-point smoothing through each one's stencil iterator, random access, dilation.
fn hrle_bench(c: &mut Criterion) {
    let spec = GridSpec::default();
    let tiles = tiles_from_shape(&Shape::Sphere { center: [0.0; 3], radius: 60.0 }, spec).unwrap();
    let dt = dtgrid_from(&tiles);
    let h = HrleGrid::from_level_set(&tiles).unwrap();
    let band = dt.len() as u64;
    let mut g = c.benchmark_group("hrle/sphere_r60");
    g.throughput(Throughput::Elements(band));
    let mut out = Vec::new();
    g.bench_function(BenchmarkId::new("hrle_smooth7", format!("{band}pts")), |b| {
        b.iter(|| hrle_smooth7(&h, &mut out))
    });
    g.bench_function(BenchmarkId::new("dtgrid_smooth7", format!("{band}pts")), |b| {
        b.iter(|| dtgrid_smooth7(&dt, &mut out))
    });
    g.bench_function(BenchmarkId::new("hrle_dilate1", format!("{band}pts")), |b| {
        b.iter(|| h.dilate(1).unwrap())
    });
    g.bench_function(BenchmarkId::new("dtgrid_dilate1", format!("{band}pts")), |b| {
        b.iter(|| dt.dilate(1).unwrap())
    });
    g.bench_function(BenchmarkId::new("from_tiles", format!("{band}pts")), |b| {
        b.iter(|| HrleGrid::from_level_set(&tiles).unwrap())
    });
    let probes: Vec<Coord> = (0..band as i32)
        .map(|i| Coord::new((i * 7919) % 131 - 65, (i * 104_729) % 131 - 65, (i * 1299) % 131 - 65))
        .collect();
    g.bench_function(BenchmarkId::new("hrle_random", format!("{band}pts")), |b| {
        b.iter(|| probes.iter().map(|&p| h.value(p)).sum::<f32>())
    });
    g.bench_function(BenchmarkId::new("dtgrid_random", format!("{band}pts")), |b| {
        b.iter(|| probes.iter().map(|&p| dt.value(p)).sum::<f32>())
    });
    g.finish();
}

fn csg_bench(c: &mut Criterion) {
    let spec = GridSpec::default();
    let a = tiles_from_shape(&Shape::Sphere { center: [0.0; 3], radius: 60.0 }, spec).unwrap();
    let b =
        tiles_from_shape(&Shape::Sphere { center: [20.0, 0.0, 0.0], radius: 60.0 }, spec).unwrap();
    let band = (a.band_voxels() + b.band_voxels()) as u64;
    let mut g = c.benchmark_group("csg/spheres_r60");
    g.throughput(Throughput::Elements(band));
    for op in [CsgOp::Union, CsgOp::Intersection, CsgOp::Difference] {
        g.bench_function(BenchmarkId::new(op.name(), format!("{band}pts")), |bench| {
            bench.iter(|| csg(&a, &b, op).unwrap())
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(500));
    targets = grids, csg_bench, hrle_bench
}
criterion_main!(benches);
