//! Criterion benchmarks of fast marching: reinitialising a sphere band (r = 60 voxels,
//! half-width 3) on both grids, first and second order. Ids carry the band voxel count
//! so times convert to band voxels per second (criterion prints that as elem/s).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::{dtgrid_from, tiles_from_shape};
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::tools::fmm::{reinitialize, FmmOptions, Order};

fn fmm(c: &mut Criterion) {
    let spec = GridSpec::default();
    let shape = Shape::Sphere { center: [0.3, -0.2, 0.1], radius: 60.0 };
    let tiles = tiles_from_shape(&shape, spec).unwrap();
    let dt = dtgrid_from(&tiles);
    let band = dt.len() as u64;
    let mut g = c.benchmark_group("fmm_reinit/sphere_r60");
    g.throughput(Throughput::Elements(band));
    g.sample_size(10);
    for (name, order) in [("first", Order::First), ("second", Order::Second)] {
        let opts = FmmOptions { order, half_width: None, ..Default::default() };
        g.bench_function(BenchmarkId::new(format!("tiles_{name}"), format!("{band}vox")), |b| {
            b.iter(|| reinitialize(&tiles, &opts).unwrap())
        });
        g.bench_function(BenchmarkId::new(format!("dtgrid_{name}"), format!("{band}vox")), |b| {
            b.iter(|| reinitialize(&dt, &opts).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, fmm);
criterion_main!(benches);
