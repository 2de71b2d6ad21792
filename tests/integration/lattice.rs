//! Flows on an anisotropic lattice (an image's voxels) and with a curvature weight that
//! varies in space: exact answers in world units, and every representation computing the
//! same bits.

use sparse_levelset::evolve::{
    Flow, GridKind, Lanes, Lattice, Renormalization, ScalarFn, Settings, Simulation, Speed,
    VectorClosure, Velocity,
};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::tiles_from_dense;
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::tiles::TileGrid;
use sparse_levelset::Coord;
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::sync::Arc;

/// The tile grid of `sdf` (world position → signed distance) sampled at the lattice
/// positions (i sx, j sy, k sz) of the box `origin + [0, dims)`, the band half-width
/// `half` of the largest spacing.
fn lattice_grid(
    spacing: [f32; 3],
    origin: Coord,
    dims: [usize; 3],
    sdf: impl Fn([f64; 3]) -> f64 + Sync,
) -> TileGrid {
    let h = spacing.iter().fold(0.0f32, |m, &s| m.max(s));
    let spec = GridSpec::new(h, [0.0; 3], 3.0).unwrap();
    let g = spec.gamma();
    let field = DenseField::from_fn(origin, dims, |c| {
        let p = [
            c.x as f64 * spacing[0] as f64,
            c.y as f64 * spacing[1] as f64,
            c.z as f64 * spacing[2] as f64,
        ];
        (sdf(p) as f32).clamp(-g, g)
    })
    .unwrap();
    tiles_from_dense(&field, spec).unwrap()
}

/// The signed distance to the sphere of centre `c` and radius `r`.
fn sphere_sdf(c: [f64; 3], r: f64) -> impl Fn([f64; 3]) -> f64 + Sync {
    move |p| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt() - r
}

/// The signed distance in the xy-plane to the circle of centre `c` and radius `r` (a disc
/// extruded along z).
fn disc_sdf(c: [f64; 2], r: f64) -> impl Fn([f64; 3]) -> f64 + Sync {
    move |p| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2)).sqrt() - r
}

fn coupled() -> Settings {
    Settings { renormalization: Renormalization::Coupled { weight: 1.0 }, ..Settings::default() }
}

/// Mean curvature flow (ε = 1) of `grid` on `lattice`, tiles with SIMD lanes.
fn curvature_flow(grid: TileGrid, lattice: Lattice) -> Simulation {
    let settings = Settings { lattice: Some(lattice), ..coupled() };
    let kind = GridKind::Tiles(Lanes::Simd);
    Simulation::from_tile_grid(kind, grid, Flow::mean_curvature(1.0), settings).unwrap()
}

fn band(sim: &Simulation) -> BTreeMap<Coord, u32> {
    let mut m = BTreeMap::new();
    sim.for_each_band_voxel(|c, v| {
        m.insert(c, v.to_bits());
    });
    m
}

/// Mean curvature flow of a sphere that is round in world units, on a lattice with 2.5×
/// the spacing along z: r² = r₀² − 2εt, measured by the enclosed volume.
#[test]
fn anisotropic_sphere_shrinks_by_mean_curvature_in_world_units() {
    let spacing = [1.0, 1.0, 2.5];
    let (r0, c) = (14.0, [24.0, 24.0, 25.0]);
    let sphere = sphere_sdf(c, r0);
    let grid = lattice_grid(spacing, Coord::new(0, 0, 0), [48, 48, 20], sphere);
    let mut sim = curvature_flow(grid, Lattice { spacing, planar: false });
    let v0 = sim.measure().unwrap().volume;
    let r_start = (3.0 * v0 / (4.0 * PI)).cbrt();
    assert!((r_start - r0).abs() < 0.05 * r0, "start radius {r_start}");
    let t_end = 40.0;
    sim.run_until(t_end, 10_000, |_, _| {}).unwrap();
    let m = sim.measure().unwrap();
    assert!(m.area.is_nan(), "the area is not computed on a lattice");
    let r = (3.0 * m.volume / (4.0 * PI)).cbrt();
    let exact = (r_start * r_start - 2.0 * t_end).sqrt();
    assert!((r - exact).abs() < 0.02 * exact + 0.1, "r = {r}, exact {exact}");
    // Round in world units: the extent along z in voxels is 1/2.5 of that along x.
    let (lo, hi) = sim.band_bounding_box().unwrap();
    let (ex, ez) = ((hi.x - lo.x) as f64, (hi.z - lo.z) as f64 * 2.5);
    assert!((ex - ez).abs() < 6.0, "extent x {ex}, z {ez} (world units)");
}

/// A lattice of equal spacings runs the image route with the same geometry as the
/// isotropic grid: the shrinking sphere agrees with the exact radius there too.
#[test]
fn isotropic_lattice_matches_the_exact_radius() {
    let spacing = [0.5, 0.5, 0.5];
    let (r0, c) = (6.0, [10.0, 10.0, 10.0]);
    let sphere = sphere_sdf(c, r0);
    let grid = lattice_grid(spacing, Coord::new(0, 0, 0), [40, 40, 40], sphere);
    let mut sim = curvature_flow(grid, Lattice { spacing, planar: false });
    let r_start = (3.0 * sim.measure().unwrap().volume / (4.0 * PI)).cbrt();
    sim.run_until(8.0, 10_000, |_, _| {}).unwrap();
    let r = (3.0 * sim.measure().unwrap().volume / (4.0 * PI)).cbrt();
    let exact = (r_start * r_start - 16.0).sqrt();
    assert!((r - exact).abs() < 0.02 * exact + 0.05, "r = {r}, exact {exact}");
}

/// A disc on a planar lattice (a one-slice image, extruded over one tile layer) shrinks
/// by the curvature of its circle, 1/r: r² = r₀² − 2εt — a cylinder's ½∇·n would give
/// r² = r₀² − εt.
#[test]
fn planar_disc_shrinks_by_the_curvature_of_its_circle() {
    let spacing = [1.0, 1.0, 1.0];
    let grid = lattice_grid(spacing, Coord::new(0, 0, 0), [48, 48, 4], disc_sdf([24.0; 2], 16.0));
    let mut sim = curvature_flow(grid, Lattice { spacing, planar: true });
    let area = |sim: &Simulation| {
        let d = sim.to_dense(Coord::new(0, 0, 0), [48, 48, 1]).unwrap();
        d.data().iter().map(|&v| (0.5 - v as f64).clamp(0.0, 1.0)).sum::<f64>()
    };
    let r_start = (area(&sim) / PI).sqrt();
    let t_end = 60.0;
    sim.run_until(t_end, 10_000, |_, _| {}).unwrap();
    let r = (area(&sim) / PI).sqrt();
    let exact = (r_start * r_start - 2.0 * t_end).sqrt();
    assert!(
        (r - exact).abs() < 0.03 * exact,
        "r = {r}, exact {exact} (cylinder: {})",
        (r_start * r_start - t_end).sqrt()
    );
    // Every slice of the layer holds the same disc.
    let d = sim.to_dense(Coord::new(0, 0, 0), [48, 48, 4]).unwrap();
    let n = 48 * 48;
    for k in 1..4 {
        assert_eq!(&d.data()[..n], &d.data()[k * n..(k + 1) * n], "slice {k}");
    }
}

/// Tiles (scalar and SIMD lanes, 1 and 2 threads), the DT-Grid and the dense reference
/// compute the same bits on a lattice with a curvature field, a speed field and advection.
#[test]
fn every_representation_agrees_on_a_lattice_bit_for_bit() {
    let spacing = [0.8, 1.0, 1.7];
    let grid = lattice_grid(
        spacing,
        Coord::new(0, 0, 0),
        [36, 32, 20],
        sphere_sdf([14.0, 15.0, 17.0], 8.0),
    );
    let z = |p: [f64; 3]| 1.0 + 0.5 * (0.3 * p[0]).sin() * (0.2 * p[2]).cos();
    let u = |p: [f64; 3]| [0.2 * (0.1 * p[2]).sin() as f32, -0.1, 0.15];
    let band = assert_representations_agree(grid, Lattice { spacing, planar: false }, z, u, 12);
    assert!(band.len() > 1000, "{} band voxels", band.len());
}

/// The same on a planar lattice (a one-slice image), where the tiles compute each tile's
/// first z-slice and copy it into the other three, and the DT-Grid and the dense reference
/// compute every voxel of the extruded layer: the fields do not vary along z, as an
/// image's do not.
#[test]
fn every_representation_agrees_on_a_planar_lattice_bit_for_bit() {
    let spacing = [0.8, 1.0, 1.0];
    let grid = lattice_grid(spacing, Coord::new(0, 0, 0), [36, 32, 4], disc_sdf([14.0, 15.0], 9.0));
    let z = |p: [f64; 3]| 1.0 + 0.5 * (0.3 * p[0]).sin() * (0.2 * p[1]).cos();
    let u = |p: [f64; 3]| [0.2 * (0.1 * p[1]).sin() as f32, -0.1, 0.0];
    let band = assert_representations_agree(grid, Lattice { spacing, planar: true }, z, u, 40);
    assert!(band.len() > 300, "{} band voxels", band.len());
    // The band stays in the layer it started in: no tiles above or below it evolve a
    // front of their own.
    assert!(band.keys().all(|c| (0..4).contains(&c.z)), "band voxels outside the layer");
}

/// A front that travels across a planar lattice for many steps (a disc carried along x
/// and y while it shrinks): the tiles and the DT-Grid compute the same bits, and the band
/// stays in its tile layer. (Tile management once created tiles above and below the
/// layer, filled with ±γ by the side their neighbour faced them with when it was made;
/// as the front moved on, those layers held an interface of their own, which the image
/// forces moved, the time step read and the band counted.)
#[test]
fn a_travelling_front_on_a_planar_lattice_stays_in_its_layer() {
    let spacing = [1.0, 1.0, 1.0];
    let grid =
        lattice_grid(spacing, Coord::new(0, 0, 0), [64, 48, 4], disc_sdf([18.0, 16.0], 11.0));
    let flow = Flow::mean_curvature(0.5).with_velocity(Velocity::Field(Arc::new(VectorClosure(
        |_p: [f64; 3], _t: f64| [0.6f32, 0.35, 0.0],
    ))));
    let settings = Settings { lattice: Some(Lattice { spacing, planar: true }), ..coupled() };
    let mut bands = Vec::new();
    for (kind, s) in dtgrid_and_tiles(settings) {
        let mut sim = Simulation::from_tile_grid(kind, grid.clone(), flow.clone(), s).unwrap();
        sim.run_until(40.0, 10_000, |_, _| {}).unwrap();
        let b = band(&sim);
        assert!(b.keys().all(|c| (0..4).contains(&c.z)), "{kind:?}: band voxels outside the layer");
        if let Some(t) = sim.tiles() {
            assert!(t.tile_coords().iter().all(|c| c.z == 0), "{kind:?}: tiles outside the layer");
        }
        bands.push((kind, sim.time(), sim.steps(), b));
    }
    let (_, t0, steps, reference) = &bands[0];
    assert!(*steps > 50, "{steps} steps");
    for (kind, t, _, b) in &bands[1..] {
        assert_eq!(t, t0, "{kind:?}: time");
        assert!(b == reference, "{kind:?}: the band differs from the DT-Grid's");
    }
}

/// The DT-Grid, then tiles with scalar lanes on one thread and SIMD lanes on two, each
/// with `settings`.
fn dtgrid_and_tiles(settings: Settings) -> [(GridKind, Settings); 3] {
    let pool = |n| Some(Arc::new(rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap()));
    [
        (GridKind::DtGrid, settings.clone()),
        (GridKind::Tiles(Lanes::Scalar), Settings { pool: pool(1), ..settings.clone() }),
        (GridKind::Tiles(Lanes::Simd), Settings { pool: pool(2), ..settings }),
    ]
}

/// A field of the position alone (as an image's is): sampled again only where the layout
/// has changed.
struct Static<F>(F);

impl<F: Fn([f64; 3]) -> f32 + Send + Sync> ScalarFn for Static<F> {
    fn fill_run(&self, spec: &GridSpec, start: Coord, _t: f64, out: &mut [f32]) {
        for (i, o) in out.iter_mut().enumerate() {
            let c = Coord::new(start.x + i as i32, start.y, start.z);
            *o = (self.0)(spec.world(c));
        }
    }
    fn time_dependent(&self) -> bool {
        false
    }
}

/// A front carried across many tiles by fields that do not change with time (speed,
/// curvature weight and velocity, as segmentation's), in 3-D and on a planar lattice: the
/// tiles, which keep such samples while their tile list stays and sample anew when it
/// changes, compute the DT-Grid's bits, which samples every step.
#[test]
fn static_fields_follow_a_moving_tile_list() {
    type Sdf = Box<dyn Fn([f64; 3]) -> f64 + Sync>;
    let cases: [(_, _, _, Sdf); 2] = [
        ([1.0, 1.0, 1.0], [56, 40, 36], false, Box::new(sphere_sdf([15.0, 14.0, 16.0], 8.0))),
        ([1.0, 1.0, 1.0], [64, 48, 4], true, Box::new(disc_sdf([18.0, 16.0], 11.0))),
    ];
    for (spacing, dims, planar, sdf) in cases {
        let grid = lattice_grid(spacing, Coord::new(0, 0, 0), dims, sdf);
        let speed = Static(|p: [f64; 3]| (0.2 + 0.15 * (0.3 * p[0]).sin()) as f32);
        let z = Static(|p: [f64; 3]| (1.0 + 0.5 * (0.2 * p[1]).cos()) as f32);
        let flow = Flow::normal_speed(Speed::Field(Arc::new(speed)))
            .with_curvature_field(0.4, Arc::new(z))
            .with_velocity(Velocity::Field(Arc::new(VectorClosure(|_p: [f64; 3], _t: f64| {
                [0.5f32, 0.3, 0.0]
            }))));
        let settings = Settings { lattice: Some(Lattice { spacing, planar }), ..coupled() };
        let mut bands = Vec::new();
        for (kind, s) in dtgrid_and_tiles(settings) {
            let mut sim = Simulation::from_tile_grid(kind, grid.clone(), flow.clone(), s).unwrap();
            let mut lists = std::collections::BTreeSet::new();
            sim.run_until(25.0, 10_000, |sim, _| {
                if let Some(t) = sim.tiles() {
                    lists.insert(t.tile_coords().to_vec());
                }
            })
            .unwrap();
            if sim.tiles().is_some() {
                assert!(lists.len() > 10, "{kind:?}: {} tile lists", lists.len());
            }
            bands.push((kind, sim.time(), sim.steps(), band(&sim)));
        }
        let (_, t0, steps, reference) = &bands[0];
        assert!(*steps > 40, "{steps} steps");
        for (kind, t, _, b) in &bands[1..] {
            assert_eq!(t, t0, "{kind:?}, planar {planar}: time");
            assert!(
                b == reference,
                "{kind:?}, planar {planar}: the band differs from the DT-Grid's"
            );
        }
    }
}

/// `steps` steps of a flow with a speed field, the curvature field `z` and the advecting
/// field `u` on `grid` and `lattice`, by the dense reference, tiles (scalar lanes on one
/// thread, SIMD on two) and the DT-Grid: the same time and the same band bits. Returns
/// the band.
fn assert_representations_agree(
    grid: TileGrid,
    lattice: Lattice,
    z: impl Fn([f64; 3]) -> f64 + Send + Sync + 'static,
    u: impl Fn([f64; 3]) -> [f32; 3] + Send + Sync + 'static,
    steps: usize,
) -> BTreeMap<Coord, u32> {
    let z =
        Arc::new(sparse_levelset::evolve::ScalarClosure(move |p: [f64; 3], _t: f64| z(p) as f32));
    let flow = Flow::normal_speed(Speed::from_fn(|p, _| (0.4 + 0.3 * (0.25 * p[1]).cos()) as f32))
        .with_curvature_field(0.3, z)
        .with_velocity(Velocity::Field(Arc::new(VectorClosure(move |p: [f64; 3], _t: f64| u(p)))));
    let settings = Settings { lattice: Some(lattice), ..coupled() };
    let runs =
        std::iter::once((GridKind::Dense, settings.clone())).chain(dtgrid_and_tiles(settings));
    let mut bands = Vec::new();
    for (kind, s) in runs {
        let mut sim = Simulation::from_tile_grid(kind, grid.clone(), flow.clone(), s).unwrap();
        for _ in 0..steps {
            sim.step().unwrap();
        }
        bands.push((kind, sim.time(), band(&sim)));
    }
    let (_, t0, reference) = &bands[0];
    for (kind, t, b) in &bands[1..] {
        assert_eq!(t, t0, "{kind:?}: time");
        assert!(b == reference, "{kind:?}: the band differs from the dense reference");
    }
    bands.swap_remove(0).2
}

/// What a lattice does not support is refused before anything runs.
#[test]
fn lattice_refuses_isotropic_tools() {
    let grid = lattice_grid([1.0, 1.0, 2.0], Coord::new(0, 0, 0), [16, 16, 8], |p| {
        ((p[0] - 8.0).powi(2) + (p[1] - 8.0).powi(2) + (p[2] - 8.0).powi(2)).sqrt() - 4.0
    });
    let lattice = Some(Lattice { spacing: [1.0, 1.0, 2.0], planar: false });
    let kind = GridKind::Tiles(Lanes::Simd);
    let sweeps = Settings { lattice, ..Settings::default() };
    let e = Simulation::from_tile_grid(kind, grid.clone(), Flow::mean_curvature(1.0), sweeps)
        .err()
        .unwrap();
    assert!(e.to_string().contains("isotropic"), "{e}");
    let bad = Settings {
        lattice: Some(Lattice { spacing: [1.0, 0.0, 1.0], planar: false }),
        ..coupled()
    };
    let e = Simulation::from_tile_grid(kind, grid.clone(), Flow::mean_curvature(1.0), bad)
        .err()
        .unwrap();
    assert!(e.to_string().contains("spacing"), "{e}");
    let vc = Settings { lattice, ..coupled() };
    let e = Simulation::from_tile_grid(kind, grid, Flow::volume_conserving(1.0), vc).err().unwrap();
    assert!(e.to_string().contains("volume-conserving"), "{e}");
}
