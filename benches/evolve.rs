//! Criterion benchmarks of one evolution step on each representation: the sphere under
//! mean curvature flow (first-order upwind + Euler, van der Laan et al. 2011,
//! Sec. 4.7) and the spiral under volume-conserving flow (HJ-WENO5 + TVD-RK3, Sec. 5.2). Benchmark
//! ids carry the stored voxel counts so times convert to throughput; every run computes the same
//! band.

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};
use sparse_levelset::evolve::{Flow, GridKind, Lanes, Settings, Simulation};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::shapes::Shape;
use std::sync::Arc;

fn steps(c: &mut Criterion) {
    let one = Arc::new(rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap());
    let spec = GridSpec::default();
    let cases = [
        (
            "sphere_r60_mcf_upwind_euler",
            Shape::Sphere { center: [0.0; 3], radius: 60.0 },
            Flow::mean_curvature(1.0),
            Settings::paper_upwind1(),
        ),
        (
            "spiral_r50_vcmcf_weno5_rk3",
            Shape::spiral_default([0.0; 3], 50.0, 40.0),
            Flow::volume_conserving(1.0),
            Settings::paper_weno5_rk3(),
        ),
    ];
    for (name, shape, flow, settings) in cases {
        let mut g = c.benchmark_group(format!("step/{name}"));
        for (label, kind) in [
            ("dtgrid", GridKind::DtGrid),
            ("tiles_scalar_1thread", GridKind::Tiles(Lanes::Scalar)),
            ("tiles_simd_1thread", GridKind::Tiles(Lanes::Simd)),
        ] {
            let s = Settings { pool: Some(one.clone()), ..settings.clone() };
            let sim = Simulation::from_shape(kind, &shape, spec, flow.clone(), s).unwrap();
            let id = BenchmarkId::new(label, format!("{}vox", sim.stored_voxels()));
            g.bench_function(id, |b| {
                b.iter_batched(|| sim.clone(), |mut s| s.step().unwrap(), BatchSize::LargeInput)
            });
        }
        g.finish();
    }
    let tiles = sparse_levelset::storage::convert::tiles_from_shape(
        &Shape::Sphere { center: [0.0; 3], radius: 60.0 },
        spec,
    )
    .unwrap();
    let mut g = c.benchmark_group("manage/sphere_r60");
    g.bench_function(
        BenchmarkId::new("streamed_alg2_alg3", format!("{}tiles", tiles.len())),
        |b| {
            b.iter_batched(
                || tiles.clone(),
                |mut t| t.manage_tiles_streamed().unwrap(),
                BatchSize::LargeInput,
            )
        },
    );
    g.bench_function(BenchmarkId::new("parallel_1thread", format!("{}tiles", tiles.len())), |b| {
        b.iter_batched(
            || tiles.clone(),
            |mut t| one.install(|| t.manage_tiles().unwrap()),
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).warm_up_time(std::time::Duration::from_millis(500));
    targets = steps
}
criterion_main!(benches);
