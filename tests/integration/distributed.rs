//! The decomposition of the tile list over ranks (threads of this process, joined by
//! `distributed::LocalRanks`): every number of ranks computes the single-process band bit
//! for bit, with the same Δt, volume and area after every step, and rebalancing keeps the
//! ranks' tile counts close. (The same over MPI processes: `cli/tests/mpi.rs`.)

use sparse_levelset::distributed::LocalRanks;
use sparse_levelset::evolve::{
    EnrightVelocity, EvolveError, Flow, GridKind, Lanes, Reinit, Renormalization, Settings,
    Simulation, SpatialScheme, Speed, Sweeps, Velocity,
};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::tiles_from_shape;
use sparse_levelset::storage::shapes::Shape;
use std::sync::Arc;

/// What one run ends with: per step (Δt, κ̄ bits), then checksum, band voxels, volume and
/// area bits.
#[derive(Debug, PartialEq)]
struct Outcome {
    dts: Vec<(u32, Option<u64>)>,
    checksum: u64,
    band: usize,
    volume: u64,
    area: u64,
}

fn pool(threads: usize) -> Option<Arc<rayon::ThreadPool>> {
    Some(Arc::new(rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()))
}

fn finish(sim: &Simulation, dts: Vec<(u32, Option<u64>)>) -> Outcome {
    let m = sim.measure().unwrap();
    Outcome {
        dts,
        checksum: sim.checksum(),
        band: sim.band_voxels(),
        volume: m.volume.to_bits(),
        area: m.area.to_bits(),
    }
}

/// Takes `steps` steps and returns the outcome.
fn run(sim: &mut Simulation, steps: usize) -> Outcome {
    let mut dts = Vec::new();
    for _ in 0..steps {
        let r = sim.step().unwrap();
        dts.push((r.dt.to_bits(), r.kappa_bar.map(f64::to_bits)));
    }
    finish(sim, dts)
}

fn single(
    shape: &Shape,
    spec: GridSpec,
    flow: &Flow,
    settings: &Settings,
    steps: usize,
) -> Outcome {
    let settings = Settings { pool: pool(2), ..settings.clone() };
    let mut sim =
        Simulation::from_shape(GridKind::Tiles(Lanes::Simd), shape, spec, flow.clone(), settings)
            .unwrap();
    run(&mut sim, steps)
}

/// The same run on `ranks` ranks with `threads` threads each, rebalancing at
/// `rebalance`; every rank's outcome.
fn distributed(
    (ranks, threads, rebalance): (usize, usize, Option<f64>),
    shape: &Shape,
    spec: GridSpec,
    flow: &Flow,
    settings: &Settings,
    steps: usize,
) -> Vec<Outcome> {
    LocalRanks::run(ranks, |t| {
        let tiles = tiles_from_shape(shape, spec).unwrap();
        let settings = Settings { pool: pool(threads), ..settings.clone() };
        let mut sim =
            Simulation::distributed(t, tiles, Lanes::Simd, flow.clone(), settings, rebalance)
                .unwrap();
        run(&mut sim, steps)
    })
}

fn agree(shape: &Shape, spec: GridSpec, flow: Flow, settings: Settings, steps: usize) {
    let reference = single(shape, spec, &flow, &settings, steps);
    for layout in [(1, 1, None), (2, 1, Some(0.05)), (3, 2, Some(0.0)), (5, 1, None)] {
        let outcomes = distributed(layout, shape, spec, &flow, &settings, steps);
        for (rank, o) in outcomes.into_iter().enumerate() {
            assert_eq!(o, reference, "(ranks, threads, rebalance) {layout:?}, rank {rank}");
        }
    }
}

#[test]
fn mean_curvature_flow_matches_one_process() {
    // The papers' first-order route (its stage double-buffered and in place) and the
    // defaults (HJ-WENO5, TVD-RK3, a sweep).
    let shape = Shape::Torus { center: [1.3, -2.2, 0.4], major_radius: 14.0, minor_radius: 5.5 };
    let in_place = Settings { double_buffer_bytes: 0, ..Settings::paper_upwind1() };
    for settings in [Settings::paper_upwind1(), in_place, Settings::default()] {
        agree(&shape, GridSpec::default(), Flow::mean_curvature(1.0), settings, 40);
    }
}

#[test]
fn spiral_under_volume_conserving_flow_matches_one_process() {
    // κ̄ is a reduction in every stage.
    let shape = Shape::spiral_default([0.0; 3], 20.0, 14.0);
    agree(
        &shape,
        GridSpec::default(),
        Flow::volume_conserving(1.0),
        Settings::paper_weno5_rk3(),
        30,
    );
}

#[test]
fn enright_matches_one_process() {
    // Advection: tiles created and removed across the cuts as the sphere is carried.
    let enright = Velocity::Field(Arc::new(EnrightVelocity { period: 1.0 }));
    let spec = GridSpec::new(1.0 / 48.0, [0.0; 3], 3.0).unwrap();
    let shape = Shape::Sphere { center: [0.35; 3], radius: 0.15 };
    let sweeps = Sweeps { every: 2, sweeps: 2, scheme: SpatialScheme::Weno5, cfl: 0.9 };
    let settings =
        Settings { renormalization: Renormalization::Sweeps(sweeps), ..Settings::default() };
    agree(&shape, spec, Flow::advection(enright), settings, 40);
}

#[test]
fn rebalancing_keeps_a_growing_sphere_balanced() {
    // A sphere grows while it drifts upwards: its tiles move into the upper slabs, across
    // the cuts the first balance placed.
    let shape = Shape::Sphere { center: [0.0, 0.0, -10.0], radius: 40.0 };
    let flow =
        Flow::normal_speed(Speed::Constant(0.5)).with_velocity(Velocity::Constant([0.0, 0.0, 1.0]));
    let settings = Settings::default();
    let spec = GridSpec::default();
    let steps = 40;
    let reference = single(&shape, spec, &flow, &settings, steps);
    for ranks in [2, 3] {
        let out = LocalRanks::run(ranks, |t| {
            let tiles = tiles_from_shape(&shape, spec).unwrap();
            let s = Settings { pool: pool(1), ..settings.clone() };
            let mut sim =
                Simulation::distributed(t, tiles, Lanes::Simd, flow.clone(), s, Some(0.1)).unwrap();
            let mut worst: f64 = 1.0;
            let mut dts = Vec::new();
            for _ in 0..steps {
                let r = sim.step().unwrap();
                dts.push((r.dt.to_bits(), r.kappa_bar.map(f64::to_bits)));
                let counts = sim.distribution().unwrap().tiles_per_rank();
                let (lo, hi) = (*counts.iter().min().unwrap(), *counts.iter().max().unwrap());
                worst = worst.max(hi as f64 / lo as f64);
            }
            let moves = sim.distribution().unwrap().halo_stats().unwrap().rebalances;
            (finish(&sim, dts), worst, moves)
        });
        for (rank, (o, worst, moves)) in out.into_iter().enumerate() {
            assert_eq!(o, reference, "{ranks} ranks, rank {rank}");
            assert!(worst <= 1.2, "{ranks} ranks: tile counts {worst}× apart");
            assert!(moves > 0, "{ranks} ranks: the cuts never moved");
        }
    }
}

#[test]
fn a_failure_before_the_step_is_agreed_by_every_rank() {
    // Stage 1's speed is NaN only where rank 1's slabs are: every rank refuses the step,
    // rank 1 with the cause, the others naming rank 1, and none changes.
    let shape = Shape::Sphere { center: [0.0; 3], radius: 12.0 };
    let speed = Speed::from_fn(|p, _| if p[2] > 6.0 { f32::NAN } else { 1.0 });
    let out = LocalRanks::run(2, |t| {
        let tiles = tiles_from_shape(&shape, GridSpec::default()).unwrap();
        let s = Settings { pool: pool(1), ..Settings::default() };
        let mut sim = Simulation::distributed(
            t,
            tiles,
            Lanes::Simd,
            Flow::normal_speed(speed.clone()),
            s,
            None,
        )
        .unwrap();
        let before = sim.checksum();
        let e = sim.step().unwrap_err();
        (e, before == sim.checksum() && sim.steps() == 0)
    });
    assert!(matches!(out[0].0, EvolveError::OtherRank { rank: 1, .. }), "{:?}", out[0].0);
    assert!(matches!(out[1].0, EvolveError::NonFiniteField { .. }), "{:?}", out[1].0);
    assert!(out.iter().all(|o| o.1), "a rank changed");
}

#[test]
fn bad_distributed_settings_are_errors() {
    let shape = Shape::Sphere { center: [0.0; 3], radius: 8.0 };
    let out = LocalRanks::run(2, |t| {
        let tiles = tiles_from_shape(&shape, GridSpec::default()).unwrap();
        let reinit = Settings {
            reinit: Some(Reinit { order: sparse_levelset::tools::fmm::Order::First, every: 5 }),
            ..Settings::default()
        };
        let flow = Flow::mean_curvature(1.0);
        let a = Simulation::distributed(
            t.clone(),
            tiles.clone(),
            Lanes::Simd,
            flow.clone(),
            reinit,
            None,
        )
        .err();
        let b = Simulation::distributed(
            t,
            tiles,
            Lanes::Simd,
            flow,
            Settings::default(),
            Some(f64::NAN),
        )
        .err();
        (a, b)
    });
    for (a, b) in out {
        assert!(matches!(a, Some(EvolveError::InvalidParameter(_))), "{a:?}");
        assert!(matches!(b, Some(EvolveError::InvalidParameter(_))), "{b:?}");
    }
}
