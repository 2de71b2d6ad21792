//! Atomic steps: every error inside `step` / `step_until` / `run_until` leaves the
//! simulation exactly as before the failed step — values, band, stored tiles or points,
//! memory, time, step count and the collapsed flag — on every representation where the
//! error can happen. One test per error path.

use sparse_levelset::evolve::{
    EvolveError, Flow, GridKind, Lanes, Reinit, Settings, Simulation, Speed, TimeStep, VectorFn,
    Velocity,
};
use sparse_levelset::grid::{GridError, GridSpec};
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::tools::fmm::Order;
use sparse_levelset::Coord;
use std::sync::Arc;

const SPARSE: [GridKind; 3] =
    [GridKind::Tiles(Lanes::Scalar), GridKind::Tiles(Lanes::Simd), GridKind::DtGrid];

/// Everything a failed step must leave as it was.
#[derive(Debug, PartialEq)]
struct Snapshot {
    checksum: u64,
    band_voxels: usize,
    stored_voxels: usize,
    stored: usize,
    bytes: usize,
    time_bits: u64,
    steps: u64,
    collapsed: bool,
    /// The band's bounding box grown by `MARGIN`, and the value bits over it.
    region: Option<(Coord, Coord)>,
    values: Vec<u32>,
    /// The tiles' activity flags (tile management reads them in the next step).
    flags: Vec<u32>,
}

/// Voxels around the band's bounding box whose values are compared.
const MARGIN: i32 = 3;

fn snapshot(sim: &Simulation) -> Snapshot {
    let m = sim.measure().unwrap();
    let region = sim.band_bounding_box().map(|(lo, hi)| {
        let grow = |c: Coord, m: i32| {
            Coord::new(c.x.saturating_add(m), c.y.saturating_add(m), c.z.saturating_add(m))
        };
        (grow(lo, -MARGIN), grow(hi, MARGIN))
    });
    let mut values = Vec::new();
    if let Some((lo, hi)) = region {
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    values.push(sim.value(Coord::new(x, y, z)).to_bits());
                }
            }
        }
    }
    let mut flags = Vec::new();
    if let Some(t) = sim.tiles() {
        t.check_invariants().unwrap();
        flags = (0..t.len()).map(|p| t.activity_flags(p)).collect();
    }
    Snapshot {
        checksum: sim.checksum(),
        band_voxels: sim.band_voxels(),
        stored_voxels: sim.stored_voxels(),
        stored: m.stored,
        bytes: m.bytes,
        time_bits: sim.time().to_bits(),
        steps: sim.steps(),
        collapsed: sim.collapsed(),
        region,
        values,
        flags,
    }
}

/// Steps until a step fails; returns the error and checks that the failed step changed
/// nothing (and that at least `min_good` steps succeeded before it).
fn run_to_failure(sim: &mut Simulation, min_good: u64, max_steps: u64) -> EvolveError {
    for _ in 0..max_steps {
        let before = snapshot(sim);
        match sim.step() {
            Ok(_) => continue,
            Err(e) => {
                assert_eq!(
                    snapshot(sim),
                    before,
                    "{:?}: the failed step changed the state",
                    sim.kind()
                );
                assert!(
                    sim.steps() >= min_good,
                    "{:?}: failed after {} steps: {e}",
                    sim.kind(),
                    sim.steps()
                );
                // Failing again changes nothing either.
                assert!(sim.step().is_err());
                assert_eq!(snapshot(sim), before);
                return e;
            }
        }
    }
    panic!("{:?}: no step failed in {max_steps} steps", sim.kind());
}

fn kinds_all() -> Vec<GridKind> {
    let mut k = SPARSE.to_vec();
    k.push(GridKind::Dense);
    k
}

/// The routes the atomic-step tests take: forward Euler double-buffered (φⁿ whole, the
/// default on these small bands) and in place (φⁿ packed, as on bands beyond
/// `Settings::double_buffer_bytes`), and TVD-RK3.
fn routes() -> [Settings; 3] {
    let euler = Settings::paper_upwind1();
    [euler.clone(), Settings { double_buffer_bytes: 0, ..euler }, Settings::paper_weno5_rk3()]
}

/// A speed field that is finite except at times in `bad` (stage times of TVD-RK3 with a
/// fixed Δt: stage 1 at t_n, stage 2 at t_n + Δt, stage 3 at t_n + Δt/2).
fn speed_nan_in(bad: std::ops::Range<f64>) -> Speed {
    Speed::from_fn(move |_, t| if bad.contains(&t) { f32::NAN } else { 1.0 })
}

/// TVD-RK3 stage 2 (or stage 3) reads a NaN speed in step 4: stage 1 already wrote φ⁽¹⁾
/// (and φ⁽²⁾ for stage 3), and the step is undone.
#[test]
fn a_later_rk_stage_failing_undoes_the_step() {
    let dt = 0.05f32;
    let d = dt as f64;
    let shape = Shape::Sphere { center: [0.3, -0.2, 0.1], radius: 6.0 };
    let settings = Settings { time_step: TimeStep::Fixed(dt), ..Settings::paper_weno5_rk3() };
    // Step 4 starts at t = 3Δt: stage 2 at 4Δt fails; stage 3 at 3.5Δt fails.
    for (stage, bad) in [(2, 3.9 * d..4.1 * d), (3, 3.4 * d..3.6 * d)] {
        for kind in kinds_all() {
            let flow = Flow::normal_speed(speed_nan_in(bad.clone())).with_curvature(0.3);
            let mut sim =
                Simulation::from_shape(kind, &shape, GridSpec::default(), flow, settings.clone())
                    .unwrap();
            let e = run_to_failure(&mut sim, 3, 10);
            assert!(matches!(e, EvolveError::NonFiniteField { .. }), "stage {stage}: {e}");
            assert_eq!(sim.steps(), 3, "{kind:?} stage {stage}");
        }
    }
}

/// A sphere growing next to the largest voxel coordinate (2³¹ − 1): tile management
/// would create tiles beyond `i32::MAX >> 2` (`GridError::OutOfRange`), the DT-Grid's
/// rebuild would dilate past i32. Both grids fail in the same step, and change nothing.
#[test]
fn growth_past_the_coordinate_range_undoes_the_step() {
    let edge = i32::MAX as f64;
    let shape = Shape::Sphere { center: [edge - 14.0, 0.25, -0.5], radius: 4.0 };
    let mut failed_at = Vec::new();
    for settings in &routes()[..2] {
        for kind in SPARSE {
            let flow = Flow::normal_speed(Speed::Constant(1.0));
            let mut sim =
                Simulation::from_shape(kind, &shape, GridSpec::default(), flow, settings.clone())
                    .unwrap();
            let e = run_to_failure(&mut sim, 3, 200);
            assert!(matches!(e, EvolveError::Grid(GridError::OutOfRange { .. })), "{kind:?}: {e}");
            failed_at.push((sim.steps(), sim.checksum()));
        }
    }
    assert!(failed_at.windows(2).all(|w| w[0] == w[1]), "{failed_at:?}");
}

/// The dense reference started from a small box around a growing sphere: the band comes
/// within four voxels of the box (`DenseBoxTooSmall`) and the step is undone.
#[test]
fn a_dense_box_too_small_undoes_the_step() {
    let spec = GridSpec::default();
    let (c, r) = ([13.2, 12.7, 13.1], 4.0);
    let field = DenseField::from_fn(Coord::new(0, 0, 0), [26, 26, 26], |v| {
        let d = [v.x as f64 - c[0], v.y as f64 - c[1], v.z as f64 - c[2]];
        ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - r) as f32
    })
    .unwrap();
    for settings in routes() {
        let flow = Flow::normal_speed(Speed::Constant(1.0));
        let mut sim =
            Simulation::from_dense(GridKind::Dense, &field, spec, flow, settings).unwrap();
        let e = run_to_failure(&mut sim, 1, 100);
        assert!(matches!(e, EvolveError::DenseBoxTooSmall { .. }), "{e}");
    }
}

/// Bytes of the representation and its buffers.
fn total_bytes(sim: &Simulation) -> u64 {
    let m = sim.measure().unwrap();
    (m.bytes + m.work_bytes) as u64
}

/// The periodic reinitialisation fails (its marched band exceeds the memory limit, which
/// the steps themselves fit): the step it belongs to is undone — including the tile
/// management or DT-Grid rebuild that had already replaced the stored set — and reported
/// as `ReinitFailed`.
#[test]
fn a_failed_reinitialisation_undoes_its_step() {
    let shape = Shape::Sphere { center: [0.4, 0.1, -0.3], radius: 9.0 };
    let spec = GridSpec::default();
    // A growing sphere: the stored set changes in every step.
    let flow = Flow::normal_speed(Speed::Constant(1.0));
    for settings in routes() {
        for kind in SPARSE {
            // The footprint of the steps without a limit...
            let mut probe =
                Simulation::from_shape(kind, &shape, spec, flow.clone(), settings.clone()).unwrap();
            let (mut total, mut bytes, mut stored) = (0, 0, Vec::new());
            for _ in 0..3 {
                probe.step().unwrap();
                total = total.max(total_bytes(&probe));
                bytes = bytes.max(probe.measure().unwrap().bytes as u64);
                stored.push(probe.measure().unwrap().stored);
            }
            assert_ne!(stored[1], stored[2], "{kind:?}: step 3 keeps the stored set");
            // ... fits (and so does a new tile list next to the current one); the
            // reinitialisation's marched band and grid (about twice the grid) do not.
            let s = Settings {
                reinit: Some(Reinit { order: Order::First, every: 3 }),
                memory_limit: Some(total + bytes * 3 / 2),
                ..settings.clone()
            };
            let mut sim = Simulation::from_shape(kind, &shape, spec, flow.clone(), s).unwrap();
            let e = run_to_failure(&mut sim, 2, 5);
            match &e {
                EvolveError::ReinitFailed { step, reason } => {
                    assert_eq!(*step, 3, "{kind:?}");
                    assert!(reason.contains("reinitialised band"), "{kind:?}: {reason}");
                }
                e => panic!("{kind:?}: {e}"),
            }
            assert_eq!(sim.steps(), 2, "{kind:?}");
            // The state is the probe's after two steps.
            let mut again =
                Simulation::from_shape(kind, &shape, spec, flow.clone(), settings.clone()).unwrap();
            again.step().unwrap();
            again.step().unwrap();
            assert_eq!(snapshot(&again), snapshot(&sim), "{kind:?}");
        }
    }
}

/// A growing sphere under a memory limit: the step whose band would outgrow it fails with
/// `OutOfMemory` before it allocates, and the simulation keeps the state of the last step
/// that fitted (the same as an unlimited run after as many steps).
#[test]
fn outgrowing_the_memory_limit_keeps_the_last_state() {
    let shape = Shape::Sphere { center: [0.3, 0.6, -0.2], radius: 6.0 };
    let spec = GridSpec::default();
    for settings in routes() {
        for kind in SPARSE {
            let flow = Flow::normal_speed(Speed::Constant(1.0));
            let mut free =
                Simulation::from_shape(kind, &shape, spec, flow.clone(), settings.clone()).unwrap();
            free.step().unwrap();
            // Room for the band to grow for a few steps: tile management allocates the new
            // list and its neighbour table next to everything the steps hold.
            let limit = total_bytes(&free) * 2;
            let s = Settings { memory_limit: Some(limit), ..settings.clone() };
            let mut sim = Simulation::from_shape(kind, &shape, spec, flow, s).unwrap();
            let e = run_to_failure(&mut sim, 2, 400);
            match e {
                EvolveError::Grid(GridError::OutOfMemory { needed, limit: l, .. }) => {
                    assert_eq!(l, limit);
                    assert!(needed > limit);
                }
                e => panic!("{kind:?}: {e}"),
            }
            assert!(total_bytes(&sim) <= limit, "{kind:?}");
            while free.steps() < sim.steps() {
                free.step().unwrap();
            }
            assert_eq!(free.checksum(), sim.checksum(), "{kind:?}");
            assert_eq!(free.time(), sim.time(), "{kind:?}");
        }
    }
    // The dense box never grows; its step buffers are admitted before the first step.
    let dense = Settings { memory_limit: Some(1024), ..Settings::paper_upwind1() };
    let flow = Flow::normal_speed(Speed::Constant(1.0));
    let mut sim = Simulation::from_shape(GridKind::Dense, &shape, spec, flow, dense).unwrap();
    let e = run_to_failure(&mut sim, 0, 1);
    assert!(matches!(e, EvolveError::Grid(GridError::OutOfMemory { .. })), "{e}");
}

/// The errors decided before anything changes — a fixed Δt beyond the CFL limit, a
/// non-finite speed in stage 1, stepping a collapsed interface — leave the state too.
#[test]
fn errors_before_the_first_stage_change_nothing() {
    let shape = Shape::Sphere { center: [0.1, 0.2, 0.3], radius: 5.0 };
    let spec = GridSpec::default();
    for kind in kinds_all() {
        let fixed = Settings { time_step: TimeStep::Fixed(10.0), ..Settings::paper_upwind1() };
        let mut sim =
            Simulation::from_shape(kind, &shape, spec, Flow::mean_curvature(1.0), fixed).unwrap();
        let e = run_to_failure(&mut sim, 0, 1);
        assert!(matches!(e, EvolveError::CflViolated { .. }), "{kind:?}: {e}");

        let flow = Flow::normal_speed(speed_nan_in(0.3..f64::INFINITY));
        let mut sim =
            Simulation::from_shape(kind, &shape, spec, flow, Settings::paper_upwind1()).unwrap();
        let e = run_to_failure(&mut sim, 1, 100);
        assert!(matches!(e, EvolveError::NonFiniteField { .. }), "{kind:?}: {e}");

        let flow = Flow::mean_curvature(1.0);
        let mut sim =
            Simulation::from_shape(kind, &shape, spec, flow, Settings::paper_upwind1()).unwrap();
        sim.run_until(f64::INFINITY, 10_000, |_, _| {}).unwrap();
        assert!(sim.collapsed(), "{kind:?}");
        let e = run_to_failure(&mut sim, 1, 1);
        assert!(matches!(e, EvolveError::Collapsed { .. }), "{kind:?}: {e}");
    }
}

/// `run_until` stops at the failed step with the state of the last good one.
#[test]
fn run_until_keeps_the_last_good_step() {
    let dt = 0.05f32;
    let settings = Settings { time_step: TimeStep::Fixed(dt), ..Settings::paper_weno5_rk3() };
    let shape = Shape::Sphere { center: [0.0; 3], radius: 6.0 };
    for kind in kinds_all() {
        let flow = Flow::normal_speed(speed_nan_in(0.39..0.41));
        let mut sim =
            Simulation::from_shape(kind, &shape, GridSpec::default(), flow, settings.clone())
                .unwrap();
        let mut last = None;
        let r = sim.run_until(10.0, u64::MAX, |s, _| last = Some(snapshot(s)));
        assert!(matches!(r, Err(EvolveError::NonFiniteField { .. })), "{kind:?}: {r:?}");
        assert_eq!(Some(snapshot(&sim)), last, "{kind:?}");
        assert_eq!(sim.steps(), 7, "{kind:?}");
    }
}

/// A time-separable field u = s(t) u₀(x) whose u₀ is NaN beyond x = 14: its samples are
/// kept from step to step, and only tiles new to the band are sampled.
struct DriftUntil;

impl VectorFn for DriftUntil {
    fn fill_run(&self, spec: &GridSpec, start: Coord, _t: f64, out: [&mut [f32]; 3]) {
        let [u, v, w] = out;
        for i in 0..u.len() {
            let x = spec.world(Coord::new(start.x + i as i32, start.y, start.z))[0];
            (u[i], v[i], w[i]) = (if x > 14.0 { f32::NAN } else { 1.0 }, 0.25, 0.0);
        }
    }
    fn time_scale(&self, _t: f64) -> Option<f32> {
        Some(1.0)
    }
}

/// The band drifts into the region where the kept samples' field is NaN: the step that
/// first stores a voxel there fails and changes nothing, and so does its retry (a sample
/// found non-finite is not kept as checked). (The dense box samples its whole box and
/// fails in the first step.)
#[test]
fn a_kept_velocity_sample_found_non_finite_fails_every_retry() {
    let shape = Shape::Sphere { center: [0.1, 0.2, 0.3], radius: 5.0 };
    let flow = Flow::advection(Velocity::Field(Arc::new(DriftUntil)));
    for kind in SPARSE {
        let mut sim = Simulation::from_shape(
            kind,
            &shape,
            GridSpec::default(),
            flow.clone(),
            Settings::default(),
        )
        .unwrap();
        let e = run_to_failure(&mut sim, 2, 100);
        assert!(matches!(e, EvolveError::NonFiniteField { .. }), "{kind:?}: {e}");
        let e = run_to_failure(&mut sim, 0, 1);
        assert!(matches!(e, EvolveError::NonFiniteField { .. }), "{kind:?} retry: {e}");
    }
}
