//! The one read interface: every tool takes the tile grid, the DT-Grid and a simulation's
//! state through the same function and gives the same result; the interface's contract
//! (band voxels in order, accessors equal to random access); progress and cancellation.

use sparse_levelset::evolve::{Flow, GridKind, Lanes, Settings, Simulation};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::progress::Progress;
use sparse_levelset::storage::convert::{
    dtgrid_from, export_npy, tiles_from, tiles_from_shape, to_dense,
};
use sparse_levelset::storage::dtgrid::DtGrid;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::TileGrid;
use sparse_levelset::tools::fmm::{self, FmmError, FmmOptions, Order};
use sparse_levelset::tools::measure::{measure, MeasureError, MeasureOptions};
use sparse_levelset::tools::render::{render, RenderError, RenderOptions};
use sparse_levelset::{Accessor, Coord, LevelSet};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// A torus off the origin at negative coordinates, with a voxel size and origin that are
/// not 1 and 0: the three storages of its band.
fn storages() -> (TileGrid, DtGrid, Simulation) {
    let spec = GridSpec::new(0.5, [0.25, -0.5, 1.0], 3.0).unwrap();
    let torus = Shape::Torus { center: [-3.1, 2.2, -5.3], major_radius: 6.0, minor_radius: 2.2 };
    let tiles = tiles_from_shape(&torus, spec).unwrap();
    let dt = dtgrid_from(&tiles);
    // A simulation at rest: its state is the same band, on the DT-Grid engine.
    let sim =
        Simulation::from_dtgrid(dt.clone(), Flow::mean_curvature(0.0), Settings::paper_upwind1())
            .unwrap();
    (tiles, dt, sim)
}

/// Every band voxel with its value, in the order the level set gives them.
fn band<G: LevelSet>(g: &G) -> Vec<(Coord, u32)> {
    let mut v = Vec::new();
    g.for_each_band_voxel(&mut |c, x| v.push((c, x.to_bits())));
    v
}

#[test]
fn the_contract_holds_for_every_storage() {
    let (tiles, dt, sim) = storages();
    let reference = band(&tiles);
    assert!(reference.len() > 1000);
    assert!(reference.windows(2).all(|w| w[0].0 < w[1].0), "band voxels in Coord order");
    let g = tiles.spec().gamma();
    assert!(reference.iter().all(|&(_, v)| f32::from_bits(v).abs() < g));
    assert_eq!(reference, band(&dt));
    assert_eq!(reference, band(&sim));
    let lookups: [&dyn Fn(Coord) -> f32; 3] =
        [&|c| tiles.value(c), &|c| dt.value(c), &|c| sim.value(c)];
    for ls in lookups {
        for &(c, v) in reference.iter().step_by(17) {
            assert_eq!(ls(c).to_bits(), v);
        }
    }
    assert_eq!(tiles.band_voxels(), reference.len());
    assert_eq!(LevelSet::band_voxels(&dt), reference.len());
    assert_eq!(LevelSet::band_voxels(&sim), reference.len());
    assert_eq!(tiles.checksum(), dt.checksum());
    assert_eq!(tiles.checksum(), LevelSet::checksum(&sim));
    let tight = tiles.band_bounding_box().unwrap();
    assert_eq!(Some(tight), dt.band_bounding_box());
    for (lo, hi) in [tiles.bounding_box().unwrap(), LevelSet::bounding_box(&dt).unwrap()] {
        assert!(lo.x <= tight.0.x && lo.y <= tight.0.y && lo.z <= tight.0.z);
        assert!(hi.x >= tight.1.x && hi.y >= tight.1.y && hi.z >= tight.1.z);
    }
    assert!(tiles.memory().total() > 0 && LevelSet::memory(&dt).total() > 0);
}

#[test]
fn accessors_equal_random_access_everywhere() {
    let (tiles, dt, sim) = storages();
    let (lo, hi) = tiles.bounding_box().unwrap();
    let mut rng = fastrand::Rng::with_seed(7);
    let mut at = tiles.accessor();
    let mut ad = dt.accessor();
    let mut as_ = sim.accessor();
    // Random probes, then a walk (the accessor's cache is hit and evicted).
    let mut probes: Vec<Coord> = (0..20_000)
        .map(|_| {
            Coord::new(
                rng.i32(lo.x - 6..=hi.x + 6),
                rng.i32(lo.y - 6..=hi.y + 6),
                rng.i32(lo.z - 6..=hi.z + 6),
            )
        })
        .collect();
    probes.extend((lo.x - 6..=hi.x + 6).map(|x| Coord::new(x, (lo.y + hi.y) / 2, lo.z + 5)));
    probes.extend([Coord::new(i32::MAX, i32::MIN, 0), Coord::new(i32::MIN, 0, i32::MAX)]);
    for c in probes {
        let v = tiles.value(c);
        assert_eq!(at.value(c).to_bits(), v.to_bits(), "{c}");
        assert_eq!(ad.value(c).to_bits(), v.to_bits(), "{c}");
        assert_eq!(as_.value(c).to_bits(), v.to_bits(), "{c}");
        assert_eq!(dt.value(c).to_bits(), v.to_bits(), "{c}");
    }
}

#[test]
fn every_tool_gives_the_same_result_on_every_storage() {
    let (tiles, dt, sim) = storages();
    // Conversions: tiles → DT-Grid → tiles is the identity on the band.
    assert_eq!(band(&tiles_from(&dt)), band(&tiles));
    assert_eq!(band(&tiles_from(&sim)), band(&tiles));
    // Render.
    let ro = RenderOptions { width: 48, height: 36, samples: 1, ..Default::default() };
    let image = render(&tiles, &ro).unwrap();
    assert!(image.rgb().iter().any(|&b| b != image.rgb()[0]));
    assert_eq!(image.rgb(), render(&dt, &ro).unwrap().rgb());
    assert_eq!(image.rgb(), render(&sim, &ro).unwrap().rgb());
    // Fast marching.
    let fo = FmmOptions { order: Order::Second, half_width: Some(4.5), ..Default::default() };
    let reinit = band(&fmm::reinitialize(&tiles, &fo).unwrap());
    assert_eq!(reinit, band(&fmm::reinitialize(&dt, &fo).unwrap()));
    assert_eq!(reinit, band(&fmm::reinitialize(&sim, &fo).unwrap()));
    // Dense fields.
    let (lo, hi) = tiles.band_bounding_box().unwrap();
    let origin = Coord::new(lo.x - 2, lo.y - 3, lo.z - 1);
    let dims = [(hi.x - lo.x + 5) as usize, (hi.y - lo.y + 6) as usize, (hi.z - lo.z + 3) as usize];
    let dense = to_dense(&tiles, origin, dims).unwrap();
    assert_eq!(dense.data(), to_dense(&dt, origin, dims).unwrap().data());
    assert_eq!(dense.data(), to_dense(&sim, origin, dims).unwrap().data());
    let dir = std::env::temp_dir().join(format!("levelset-iface-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (a, b) = (dir.join("a.npy"), dir.join("b.npy"));
    let oa = export_npy(&dt, &a, 2).unwrap();
    let ob = export_npy(&sim, &b, 2).unwrap();
    assert_eq!(oa, ob);
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    std::fs::remove_dir_all(&dir).unwrap();
    // Measures.
    let m = measure(&tiles, &MeasureOptions::default()).unwrap();
    assert_eq!(m, measure(&dt, &MeasureOptions::default()).unwrap());
    assert_eq!(m, measure(&sim, &MeasureOptions::default()).unwrap());
}

#[test]
fn measures_match_the_analytic_shape_and_the_evolution() {
    let spec = GridSpec::new(0.75, [1.0, 2.0, -3.0], 3.0).unwrap();
    let r = 17.3;
    let sphere = Shape::Sphere { center: [2.1, -4.3, 7.7], radius: r };
    let tiles = tiles_from_shape(&sphere, spec).unwrap();
    let m = measure(&tiles, &MeasureOptions::default()).unwrap();
    let (v, a) = (4.0 / 3.0 * std::f64::consts::PI * r.powi(3), 4.0 * std::f64::consts::PI * r * r);
    assert!((m.volume - v).abs() <= 1e-3 * v, "volume {} vs {v}", m.volume);
    assert!((m.area - a).abs() <= 5e-3 * a, "area {} vs {a}", m.area);
    // The evolution's own measures (exact sums over its stored voxels) agree bit for bit.
    for kind in [GridKind::Tiles(Lanes::Scalar), GridKind::Tiles(Lanes::Simd), GridKind::DtGrid] {
        let sim = Simulation::from_tile_grid(
            kind,
            tiles.clone(),
            Flow::mean_curvature(0.0),
            Settings::paper_upwind1(),
        )
        .unwrap();
        let e = sim.measure().unwrap();
        assert_eq!(e.volume.to_bits(), m.volume.to_bits(), "{kind:?}");
        assert_eq!(e.area.to_bits(), m.area.to_bits(), "{kind:?}");
        assert_eq!(e.band_voxels, m.band_voxels, "{kind:?}");
    }
    // A wider delta than the band is refused, not silently storage-dependent.
    let wide = MeasureOptions { delta_width: 3.5, ..Default::default() };
    assert!(matches!(measure(&tiles, &wide), Err(MeasureError::InvalidOption(_))));
}

/// A progress callback that cancels after `after` reports and counts the reports.
fn cancelling(after: u64) -> (Progress, Arc<AtomicU64>) {
    let calls = Arc::new(AtomicU64::new(0));
    let c = calls.clone();
    let p = Progress::new(move |done, total| {
        assert!(done <= total);
        c.fetch_add(1, Ordering::Relaxed) < after
    });
    (p, calls)
}

#[test]
fn progress_is_reported_and_cancellation_stops_every_tool() {
    let sphere = Shape::Sphere { center: [0.0; 3], radius: 60.0 };
    let tiles = tiles_from_shape(&sphere, GridSpec::default()).unwrap();
    // Reported: rows of an image, all of them.
    let last = Arc::new(AtomicU64::new(0));
    let l = last.clone();
    let ro = RenderOptions {
        width: 16,
        height: 12,
        samples: 1,
        progress: Progress::new(move |done, total| {
            assert_eq!(total, 12);
            l.fetch_max(done, Ordering::Relaxed);
            true
        }),
        ..Default::default()
    };
    render(&tiles, &ro).unwrap();
    assert_eq!(last.load(Ordering::Relaxed), 12);
    // Cancelled.
    let (p, calls) = cancelling(2);
    let ro = RenderOptions { width: 16, height: 64, samples: 1, progress: p, ..Default::default() };
    assert!(matches!(render(&tiles, &ro), Err(RenderError::Cancelled(_))));
    assert!(calls.load(Ordering::Relaxed) < 64);
    let (p, _) = cancelling(0);
    let fo = FmmOptions { half_width: Some(12.0), progress: p, ..Default::default() };
    assert!(matches!(fmm::reinitialize(&tiles, &fo), Err(FmmError::Cancelled(_))));
    let (p, _) = cancelling(0);
    let mo = MeasureOptions { progress: p, ..Default::default() };
    assert!(matches!(measure(&tiles, &mo), Err(MeasureError::Cancelled(_))));
}
