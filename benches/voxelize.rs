//! Criterion benchmark of mesh-to-level-set conversion (`voxelize`): a UV torus of 102,400
//! triangles (320 × 160 segments, major radius 108, tube radius 27 voxels) at voxel size 1
//! and half-width 3, about 690k band voxels, on one and two threads. This is the anchor
//! OpenVDB quotes for its `meshToLevelSet` (1.19 s on one thread, 0.61 s on two). The id
//! carries the band voxel and triangle counts, so times convert to band voxels/s.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use sparse_levelset::tools::voxelize::{voxelize, VoxelizeOptions};

#[path = "../tests/integration/common/meshes.rs"]
mod meshes;

fn torus(c: &mut Criterion) {
    let mesh = meshes::uv_torus([0.0; 3], 108.0, 27.0, 320, 160);
    let opts = VoxelizeOptions { voxel_size: Some(1.0), ..Default::default() };
    let grid = voxelize(&mesh, &opts).unwrap();
    let label = format!("{}band_vox_{}tri", grid.band_voxels(), mesh.triangles.len());
    let mut g = c.benchmark_group("voxelize/torus_102k_tri");
    g.sample_size(10);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        g.bench_function(BenchmarkId::new(format!("{threads}threads"), &label), |b| {
            b.iter(|| pool.install(|| voxelize(&mesh, &opts).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(benches, torus);
criterion_main!(benches);
