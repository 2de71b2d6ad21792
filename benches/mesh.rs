//! Criterion benchmark of simplicial isosurfacing on tiles: the sphere of radius 100
//! voxels (half-width 3), on one thread and on every thread. The benchmark ids carry the
//! band voxel and triangle counts, so times convert to band voxels/s and triangles/s.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use sparse_levelset::build::tiles_from_shape;
use sparse_levelset::grid::GridSpec;
use sparse_levelset::mesh::{isosurface, MeshOptions};
use sparse_levelset::shapes::Shape;

fn mesh(c: &mut Criterion) {
    let sphere = Shape::Sphere { center: [0.0; 3], radius: 100.0 };
    let tiles = tiles_from_shape(&sphere, GridSpec::default()).unwrap();
    let mesh = isosurface(&tiles, &MeshOptions::default()).unwrap();
    let label = format!(
        "{}band_vox_{}tiles_{}tri_{}vert",
        tiles.band_voxels(),
        tiles.len(),
        mesh.num_triangles(),
        mesh.num_vertices()
    );
    let mut g = c.benchmark_group("mesh/sphere_r100_tiles");
    g.sample_size(10);
    let all = rayon::current_num_threads();
    for threads in [1, all] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        g.bench_function(BenchmarkId::new(format!("{threads}threads"), &label), |b| {
            b.iter(|| pool.install(|| isosurface(&tiles, &MeshOptions::default()).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(benches, mesh);
criterion_main!(benches);
