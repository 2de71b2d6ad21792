//! Criterion benchmark of simplicial isosurfacing on tiles: the sphere of radius 100
//! voxels (half-width 3), on one thread, two threads and every thread. Throughput is in
//! band voxels (|φ| < γ), the unit of OpenVDB's `volumeToMesh` comparison in
//! `docs/mesh.md`; the benchmark ids also carry the triangle and vertex counts.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::tiles_from_shape;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::tools::mesh::{isosurface, MeshOptions};

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
    let mut g = c.benchmark_group("mesh/sphere_r100_hw3_tiles");
    g.sample_size(10);
    g.throughput(Throughput::Elements(tiles.band_voxels() as u64));
    let mut counts = vec![1, 2, rayon::current_num_threads()];
    counts.sort_unstable();
    counts.dedup();
    for threads in counts {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        g.bench_function(BenchmarkId::new(format!("{threads}threads"), &label), |b| {
            b.iter(|| pool.install(|| isosurface(&tiles, &MeshOptions::default()).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(benches, mesh);
criterion_main!(benches);
