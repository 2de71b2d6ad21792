//! Criterion benchmark of the ray tracer (Houston et al. 2006, Sec. 6.3) on both grids: one
//! 320×240 image with 2×2 rays per pixel, ground and shadows. The ids carry the ray count
//! (primary rays; shadow rays come on top) so times convert to rays per second.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::{dtgrid_from, tiles_from_shape};
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::tools::render::{self, RenderOptions};

fn render(c: &mut Criterion) {
    let opts = RenderOptions { width: 320, height: 240, samples: 2, ..Default::default() };
    let rays = (opts.width * opts.height * opts.samples * opts.samples) as u64;
    for (name, shape) in [
        ("torus_80_20", Shape::Torus { center: [0.0; 3], major_radius: 80.0, minor_radius: 20.0 }),
        ("spiral_r50", Shape::spiral_default([0.0; 3], 50.0, 40.0)),
    ] {
        let tiles = tiles_from_shape(&shape, GridSpec::default()).unwrap();
        let dt = dtgrid_from(&tiles);
        let mut g = c.benchmark_group(format!("render/{name}"));
        g.sample_size(10);
        g.throughput(Throughput::Elements(rays));
        g.bench_function(BenchmarkId::new("tiles", format!("{rays}rays")), |b| {
            b.iter(|| render::render(&tiles, &opts).unwrap())
        });
        g.bench_function(BenchmarkId::new("dtgrid", format!("{rays}rays")), |b| {
            b.iter(|| render::render(&dt, &opts).unwrap())
        });
        g.finish();
    }
}

criterion_group!(benches, render);
criterion_main!(benches);
