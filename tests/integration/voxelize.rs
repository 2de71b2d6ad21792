//! Meshes in: `voxelize` against brute force and analytic distances, open and
//! self-intersecting meshes, determinism, the default voxel size, and the mesh readers
//! (round trips and every kind of bad file).
//!
//! Tolerances: "exact" means equal to a brute-force f64 signed distance up to the f32
//! rounding of the stored value (4 ulp of γ, absolute); the analytic shapes are meshed finely
//! enough (chord error below 0.01 voxel, stated at each mesh) that the mesh's distance is
//! within 0.05 voxel of the shape's.

use crate::common;

use crate::common::meshes::{cube, icosphere, join, uv_sphere, uv_torus};
use sparse_levelset::io::mesh::{load_mesh as read_mesh, MeshInError};
use sparse_levelset::storage::tiles::TileGrid;
use sparse_levelset::tools::mesh::TriangleMesh;
use sparse_levelset::tools::voxelize::{
    default_voxel_size, voxelize, SignMethod, VoxelizeError, VoxelizeOptions,
};
use sparse_levelset::{Coord, GridError, LevelSet};
use std::path::{Path, PathBuf};

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Distance from p to a triangle, by a route other than the library's: the plane when the
/// projection falls inside the triangle, else the nearest of the three edges.
fn tri_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let seg = |a: [f64; 3], b: [f64; 3]| {
        let d = sub(b, a);
        let t = (dot(sub(p, a), d) / dot(d, d)).clamp(0.0, 1.0);
        norm(sub(p, [a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]]))
    };
    let edges = seg(a, b).min(seg(b, c)).min(seg(c, a));
    let n = cross(sub(b, a), sub(c, a));
    let side = |a: [f64; 3], b: [f64; 3]| dot(cross(sub(b, a), sub(p, a)), n) >= 0.0;
    if side(a, b) && side(b, c) && side(c, a) {
        return (dot(n, sub(p, a)).abs() / norm(n)).min(edges);
    }
    edges
}

/// Generalised winding number (Jacobson et al. 2013): the solid angles of the triangles
/// seen from p over 4π (Van Oosterom–Strackee); an integer for a closed mesh.
fn winding(mesh: &TriangleMesh, p: [f64; 3]) -> f64 {
    let mut w = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| sub(mesh.positions[i as usize], p));
        let (la, lb, lc) = (norm(a), norm(b), norm(c));
        let num = dot(a, cross(b, c));
        let den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
        w += 2.0 * num.atan2(den);
    }
    w / (4.0 * std::f64::consts::PI)
}

/// The brute-force signed distance of a closed mesh at voxel `c`, clamped to ±γ: the
/// least distance to every triangle, inside where the winding number is not 0.
fn brute_force(mesh: &TriangleMesh, grid: &TileGrid, c: Coord) -> f64 {
    let spec = grid.spec();
    let p = spec.world(c);
    let d = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, cc] = t.map(|i| mesh.positions[i as usize]);
            tri_distance(p, a, b, cc)
        })
        .fold(f64::INFINITY, f64::min);
    let g = spec.gamma() as f64;
    let inside = winding(mesh, p).abs() > 0.5;
    let d = d.min(g);
    if inside {
        -d
    } else {
        d
    }
}

/// Every voxel of the grid's tile box grown by `margin` voxels.
fn voxels_around(grid: &TileGrid, margin: i32) -> Vec<Coord> {
    let (lo, hi) = grid.bounding_box().expect("a band");
    let mut out = Vec::new();
    for z in lo.z - margin..=hi.z + margin {
        for y in lo.y - margin..=hi.y + margin {
            for x in lo.x - margin..=hi.x + margin {
                out.push(Coord::new(x, y, z));
            }
        }
    }
    out
}

fn opts(h: f32) -> VoxelizeOptions {
    VoxelizeOptions { voxel_size: Some(h), ..Default::default() }
}

/// Compares a closed mesh's grid with brute force at every voxel around the band: values
/// within 4 ulp of γ (signs not compared where the distance is below that).
fn assert_exact(name: &str, mesh: &TriangleMesh, grid: &TileGrid) {
    let g = grid.spec().gamma();
    let tol = 4.0 * f32::EPSILON as f64 * g as f64;
    let mut band = 0;
    for c in voxels_around(grid, 2) {
        let want = brute_force(mesh, grid, c);
        let got = grid.value(c) as f64;
        band += (want.abs() < g as f64) as usize;
        let ok = if want.abs() <= tol { got.abs() <= 2.0 * tol } else { (got - want).abs() <= tol };
        assert!(ok, "{name}: voxel {c}: got {got}, brute force {want}");
    }
    assert!(band > 0);
    assert_eq!(grid.band_voxels(), band, "{name}: band voxels");
    grid.check_invariants().unwrap();
}

#[test]
fn closed_clean_meshes_are_exactly_the_signed_distance() {
    // Vertices off the voxel lattice, a voxel size that is not 1.
    let sphere = icosphere([0.37, -0.21, 0.13], 2.3, 2);
    for sign in [SignMethod::Rays, SignMethod::SingleRay] {
        let o = VoxelizeOptions { voxel_size: Some(0.37), sign, ..Default::default() };
        assert_exact("icosphere", &sphere, &voxelize(&sphere, &o).unwrap());
    }
    // Integer vertices on voxel centres, faces, edges and vertices on voxel-centre lines:
    // every crossing through an edge or a vertex must be counted exactly once.
    let octahedron = TriangleMesh {
        positions: vec![
            [4.0, 0.0, 0.0],
            [-4.0, 0.0, 0.0],
            [0.0, 4.0, 0.0],
            [0.0, -4.0, 0.0],
            [0.0, 0.0, 4.0],
            [0.0, 0.0, -4.0],
        ],
        normals: vec![],
        triangles: vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ],
    };
    let boxy = cube([-4.0, -3.0, -2.0], [3.0, 4.0, 5.0]);
    let skew = TriangleMesh {
        // A tetrahedron whose faces cut the lattice at odd angles through lattice points.
        positions: vec![[-3.0, -2.0, -4.0], [5.0, -1.0, -3.0], [0.0, 6.0, -2.0], [1.0, 1.0, 4.0]],
        normals: vec![],
        triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    };
    // An x-line through an edge whose projection on (y, z) is horizontal, (y, z) = (2, 0),
    // entering on that edge and leaving through the midpoint of the opposite edge: a tie
    // rule that counts both triangles of an edge (or neither) gets every voxel after it
    // wrong on that line (the single-ray sign sees it).
    let wedge = TriangleMesh {
        positions: vec![[0.0, 0.0, 0.0], [2.0, 4.0, 0.0], [6.0, 2.0, 3.0], [6.0, 2.0, -3.0]],
        normals: vec![],
        triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    };
    let meshes =
        [("octahedron", &octahedron), ("box", &boxy), ("tetrahedron", &skew), ("wedge", &wedge)];
    for (name, mesh) in meshes {
        assert!(mesh.enclosed_volume() > 0.0, "{name} is outward oriented");
        for sign in [SignMethod::Rays, SignMethod::SingleRay] {
            for h in [1.0, 0.5] {
                let o = VoxelizeOptions { voxel_size: Some(h), sign, ..Default::default() };
                assert_exact(name, mesh, &voxelize(mesh, &o).unwrap());
            }
        }
    }
}

/// Signed distance to a sphere and to a torus around the z axis.
fn sphere_sdf(p: [f64; 3], c: [f64; 3], r: f64) -> f64 {
    norm(sub(p, c)) - r
}
fn torus_sdf(p: [f64; 3], c: [f64; 3], major: f64, minor: f64) -> f64 {
    let q = sub(p, c);
    let ring = (q[0] * q[0] + q[1] * q[1]).sqrt() - major;
    (ring * ring + q[2] * q[2]).sqrt() - minor
}

/// Band values within `tol` voxels of the analytic distance, the right band voxels, and
/// the right sign at every voxel around the band whose distance exceeds `tol`.
fn assert_analytic(name: &str, grid: &TileGrid, sdf: impl Fn([f64; 3]) -> f64, tol: f64) {
    let spec = grid.spec();
    let (h, g) = (spec.voxel_size as f64, spec.gamma() as f64);
    let (mut worst, mut band) = (0f64, 0usize);
    for c in voxels_around(grid, 3) {
        let want = sdf(spec.world(c));
        let got = grid.value(c) as f64;
        if want.abs() < g - tol * h {
            assert!(got.abs() < g, "{name}: {c} (φ = {want}) is not a band voxel: {got}");
            worst = worst.max((got - want).abs() / h);
            band += 1;
        } else if want.abs() > g + tol * h {
            assert_eq!(got.abs(), g, "{name}: {c} (φ = {want}) is a band voxel: {got}");
        }
        if want.abs() > tol * h {
            assert_eq!(got < 0.0, want < 0.0, "{name}: sign at {c}: got {got}, φ = {want}");
        }
    }
    assert!(worst <= tol, "{name}: worst band error {worst} voxels");
    assert!(band > 1000, "{name}: {band} band voxels");
}

#[test]
fn sphere_and_torus_meshes_match_the_analytic_distance() {
    // Icosphere of radius 20 voxels, 5 subdivisions (20,480 triangles, edges ≈ 0.66
    // voxel): the flat triangles lie within 0.004 voxel of the sphere.
    let c = [0.3, -0.45, 0.2];
    let sphere = icosphere(c, 20.0, 5);
    let grid = voxelize(&sphere, &opts(1.0)).unwrap();
    assert_analytic("icosphere", &grid, |p| sphere_sdf(p, c, 20.0), 0.05);
    // The same at voxel size 0.5 around a UV sphere of radius 9 (128 × 256 segments,
    // chord error ≤ 9 (1 − cos(π/256)) ≈ 0.0007 = 0.0014 voxel).
    let uv = uv_sphere(c, 9.0, 128, 256);
    let grid = voxelize(&uv, &opts(0.5)).unwrap();
    assert_analytic("uv sphere", &grid, |p| sphere_sdf(p, c, 9.0), 0.05);
    // UV torus, radii 24 and 8 voxels, 160 × 64 segments (20,480 triangles): chord errors
    // 32 (1 − cos(π/160)) ≈ 0.006 and 8 (1 − cos(π/64)) ≈ 0.0096 voxel.
    let c = [-0.2, 0.15, 0.4];
    let torus = uv_torus(c, 24.0, 8.0, 160, 64);
    let grid = voxelize(&torus, &opts(1.0)).unwrap();
    assert_analytic("torus", &grid, |p| torus_sdf(p, c, 24.0, 8.0), 0.05);
    assert_contract("torus", &grid);
}

/// Every pair of face neighbours with different signs has both voxels in the band: the
/// band separates inside from outside, as every grid assumes.
fn assert_closed(name: &str, grid: &TileGrid) {
    let g = grid.spec().gamma();
    for c in voxels_around(grid, 1) {
        let v = grid.value(c);
        for d in [Coord::new(1, 0, 0), Coord::new(0, 1, 0), Coord::new(0, 0, 1)] {
            let w = grid.value(c.wrapping_add(d));
            if (v < 0.0) != (w < 0.0) {
                assert!(
                    v.abs() < g && w.abs() < g,
                    "{name}: sign change without band at {c}+{d}: {v}, {w}"
                );
            }
        }
    }
}

/// The grid keeps the `LevelSet` contract: its tile invariants hold, and the DT-Grid of
/// its band reads the same value at every voxel around it (the two storages' rules for
/// unstored voxels agree only when the band separates inside from outside).
fn assert_contract(name: &str, grid: &TileGrid) {
    grid.check_invariants().unwrap();
    let dt = sparse_levelset::storage::convert::dtgrid_from(grid);
    assert_eq!(dt.band_voxels(), grid.band_voxels(), "{name}");
    for c in voxels_around(grid, 2) {
        assert_eq!(dt.value(c), grid.value(c), "{name}: {c}");
    }
}

/// Distance from p to the nearest of the given triangles' vertices.
fn near_faces(mesh: &TriangleMesh, faces: &[usize], p: [f64; 3]) -> f64 {
    faces
        .iter()
        .flat_map(|&f| mesh.triangles[f])
        .map(|i| norm(sub(mesh.positions[i as usize], p)))
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn open_meshes_give_closed_level_sets_that_differ_only_near_the_holes() {
    // Icosphere of radius 16 voxels, 4 subdivisions (5,120 triangles, edges ≈ 1.1 voxel),
    // with six faces removed far apart from each other: small holes.
    let full = icosphere([0.21, 0.33, -0.17], 16.0, 4);
    let closed = voxelize(&full, &opts(1.0)).unwrap();
    let removed: Vec<usize> = (0..6).map(|i| 17 + i * 853).collect();
    let mut open = full.clone();
    open.triangles = (0..full.triangles.len())
        .filter(|f| !removed.contains(f))
        .map(|f| full.triangles[f])
        .collect();
    {
        let grid = voxelize(&open, &opts(1.0)).unwrap();
        assert_closed("open icosphere", &grid);
        assert_contract("open icosphere", &grid);
        let mut differ = 0;
        for c in voxels_around(&closed, 4) {
            if (grid.value(c) < 0.0) != (closed.value(c) < 0.0) {
                differ += 1;
                let d = near_faces(&full, &removed, closed.spec().world(c));
                assert!(d < 3.0, "sign differs at {c}, {d} voxels from the removed faces");
            }
        }
        // Far from the holes the band is the closed sphere's, value for value.
        let spec = *closed.spec();
        closed.for_each_band_voxel(&mut |c, v| {
            if near_faces(&full, &removed, spec.world(c)) > 6.0 {
                assert_eq!(grid.value(c), v, "{c}");
            }
        });
        assert!(differ < 200, "{differ} voxels differ");
    }
    // The single ray has no vote to spare: its sign flips along whole lines through the
    // holes, far from them (which is what the check above would catch).
    let single = voxelize(&open, &VoxelizeOptions { sign: SignMethod::SingleRay, ..opts(1.0) });
    let single = single.unwrap();
    let far_off = voxels_around(&closed, 4)
        .into_iter()
        .filter(|&c| (single.value(c) < 0.0) != (closed.value(c) < 0.0))
        .filter(|&c| near_faces(&full, &removed, closed.spec().world(c)) > 6.0)
        .count();
    assert!(far_off > 10, "{far_off}");
    assert_closed("open icosphere, single ray", &single);

    // A hole much wider than the band: the cap z > 10 of a sphere of radius 16 removed
    // (a disc of radius 12.5 voxels). The vote's sign change across the opening has no
    // band of its own: it is closed with ±h/2 voxels, and the rest is the sphere's.
    let cap: Vec<usize> = (0..full.triangles.len())
        .filter(|&f| full.triangles[f].iter().all(|&i| full.positions[i as usize][2] > 10.0))
        .collect();
    let mut cup = full.clone();
    cup.triangles =
        (0..full.triangles.len()).filter(|f| !cap.contains(f)).map(|f| full.triangles[f]).collect();
    let grid = voxelize(&cup, &opts(1.0)).unwrap();
    assert_closed("cup", &grid);
    assert_contract("cup", &grid);
    for c in voxels_around(&closed, 4) {
        if (grid.value(c) < 0.0) != (closed.value(c) < 0.0) {
            let p = closed.spec().world(c);
            assert!(p[2] > 8.0, "sign differs at {c} (z = {}), below the opening", p[2]);
        }
    }
    // The opening is closed: the centre of the disc is in the band, inside below it,
    // outside above it.
    let at = |x: i32, y: i32, z: i32| grid.value(Coord::new(x, y, z));
    assert!(at(0, 0, 0) < 0.0 && at(0, 0, 8) < 0.0 && at(0, 0, 14) > 0.0);
    let column: Vec<f32> = (6..16).map(|z| at(0, 0, z)).collect();
    assert!(column.iter().any(|v| v.abs() < 3.0), "no band across the opening: {column:?}");
}

#[test]
fn overlapping_closed_parts_give_their_union() {
    // Two icospheres (4 subdivisions) overlapping, in one mesh: the surfaces cross.
    let (ca, ra, cb, rb) = ([0.1, 0.2, 0.3], 10.0, [9.4, 1.7, -0.6], 8.0);
    let both = join(&icosphere(ca, ra, 4), &icosphere(cb, rb, 4));
    for sign in [SignMethod::Rays, SignMethod::SingleRay] {
        let grid = voxelize(&both, &VoxelizeOptions { sign, ..opts(1.0) }).unwrap();
        assert_closed("union", &grid);
        assert_contract("union", &grid);
        let spec = *grid.spec();
        let mut inside = 0;
        for c in voxels_around(&grid, 3) {
            let p = spec.world(c);
            let want = sphere_sdf(p, ca, ra).min(sphere_sdf(p, cb, rb));
            if want.abs() > 0.1 {
                assert_eq!(grid.value(c) < 0.0, want < 0.0, "{sign:?} {c}: union φ = {want}");
            }
            inside += (want < -0.1) as usize;
        }
        assert!(inside > 5000);
    }
}

#[test]
fn bitwise_identical_for_any_thread_count() {
    // An open mesh (the closing runs too) and a torus.
    let mut cup = icosphere([0.21, 0.33, -0.17], 16.0, 4);
    let keep: Vec<[u32; 3]> = cup
        .triangles
        .iter()
        .copied()
        .filter(|t| !t.iter().all(|&i| cup.positions[i as usize][2] > 10.0))
        .collect();
    cup.triangles = keep;
    let torus = uv_torus([0.5, -0.25, 0.125], 20.0, 6.0, 96, 48);
    for mesh in [&cup, &torus] {
        let runs: Vec<TileGrid> = [1, 2, 3]
            .iter()
            .map(|&n| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
                pool.install(|| voxelize(mesh, &opts(0.75)).unwrap())
            })
            .collect();
        for r in &runs[1..] {
            assert_eq!(r.tile_coords(), runs[0].tile_coords());
            let bits = |g: &TileGrid| -> Vec<u32> {
                g.values().iter().flat_map(|t| t.0.map(f32::to_bits)).collect()
            };
            assert_eq!(bits(r), bits(&runs[0]));
            assert_eq!(r.checksum(), runs[0].checksum());
            for p in 0..r.len() {
                assert_eq!(r.border_flags(p), runs[0].border_flags(p));
            }
        }
    }
}

#[test]
fn default_voxel_size_follows_the_median_edge_within_64_to_1024_voxels() {
    // The median edge when it gives 64..1024 voxels along the longest side.
    let torus = uv_torus([0.0; 3], 24.0, 8.0, 160, 64);
    let mut edges: Vec<f64> = torus
        .triangles
        .iter()
        .flat_map(|t| {
            let p = t.map(|i| torus.positions[i as usize]);
            [norm(sub(p[0], p[1])), norm(sub(p[1], p[2])), norm(sub(p[2], p[0]))]
        })
        .collect();
    edges.sort_by(f64::total_cmp);
    let median = edges[edges.len() / 2];
    let h = default_voxel_size(&torus).unwrap();
    assert_eq!(h, median as f32);
    let span = 64.0 / h as f64; // the torus is 64 wide
    assert!((64.0..=1024.0).contains(&span), "{span}");
    // voxelize uses it.
    let grid = voxelize(&torus, &VoxelizeOptions::default()).unwrap();
    assert_eq!(grid.spec().voxel_size, h);
    assert_eq!(grid.spec().half_width, 3.0);

    // A coarse mesh (a box of 12 triangles, edges 8 and 11.3): 64 voxels across.
    assert_eq!(default_voxel_size(&cube([0.0; 3], [8.0, 4.0, 2.0])).unwrap(), 8.0 / 64.0);
    // A fine strip 10 long of triangles 0.001 wide: 1024 voxels along it.
    let n = 10_000;
    let strip = TriangleMesh {
        positions: (0..=n)
            .flat_map(|i| [[i as f64 * 1e-3, 0.0, 0.0], [i as f64 * 1e-3, 1e-3, 0.0]])
            .collect(),
        normals: vec![],
        triangles: (0..n as u32)
            .flat_map(|i| [[2 * i, 2 * i + 2, 2 * i + 3], [2 * i, 2 * i + 3, 2 * i + 1]])
            .collect(),
    };
    assert_eq!(default_voxel_size(&strip).unwrap(), (10.0f64 / 1024.0) as f32);
    // A mesh whose vertices coincide has no size of its own.
    let point =
        TriangleMesh { positions: vec![[1.0; 3]; 3], normals: vec![], triangles: vec![[0, 1, 2]] };
    assert!(matches!(default_voxel_size(&point), Err(VoxelizeError::ZeroExtent)));
    // ... but voxelizes with a given one (a degenerate triangle is a point).
    let grid = voxelize(&point, &opts(1.0)).unwrap();
    assert_eq!(grid.value(Coord::new(1, 1, 1)), 0.0);
    assert_eq!(grid.value(Coord::new(2, 1, 1)), 1.0);
}

#[test]
fn bad_meshes_are_refused_before_any_work() {
    let good = icosphere([0.0; 3], 5.0, 1);
    let mut empty = good.clone();
    empty.triangles.clear();
    assert!(matches!(voxelize(&empty, &opts(1.0)), Err(VoxelizeError::Empty)));
    let mut nan = good.clone();
    nan.positions[7][1] = f64::NAN;
    let e = voxelize(&nan, &opts(1.0)).unwrap_err();
    assert!(matches!(e, VoxelizeError::NonFinite { vertex: 7, .. }), "{e}");
    let mut inf = good.clone();
    inf.positions[3][2] = f64::NEG_INFINITY;
    assert!(matches!(voxelize(&inf, &opts(1.0)), Err(VoxelizeError::NonFinite { vertex: 3, .. })));
    let mut index = good.clone();
    index.triangles[5][2] = 1000;
    let e = voxelize(&index, &opts(1.0)).unwrap_err();
    assert!(matches!(e, VoxelizeError::IndexOutOfRange { triangle: 5, index: 1000, .. }), "{e}");
    // Voxel indices beyond i32 at the chosen voxel size.
    let far = icosphere([3e9, 0.0, 0.0], 5.0, 1);
    let e = voxelize(&far, &opts(1.0)).unwrap_err();
    assert!(matches!(e, VoxelizeError::Grid(GridError::InvalidParameter(_))), "{e}");
    assert!(e.to_string().contains("i32"), "{e}");
    assert!(voxelize(&far, &opts(100.0)).is_ok(), "fits at a coarser voxel size");
    // A band larger than the machine: a box 10⁶ voxels wide.
    let huge = cube([0.0; 3], [1e6; 3]);
    let e = voxelize(&huge, &opts(1.0)).unwrap_err();
    assert!(matches!(e, VoxelizeError::Grid(GridError::OutOfMemory { .. })), "{e}");
    // Invalid grid parameters.
    for o in [opts(0.0), opts(f32::NAN), VoxelizeOptions { half_width: 1.0, ..opts(1.0) }] {
        let e = voxelize(&good, &o).unwrap_err();
        assert!(matches!(e, VoxelizeError::Grid(GridError::InvalidParameter(_))), "{e}");
    }
    // Cancelled through the progress callback.
    let o = VoxelizeOptions {
        progress: sparse_levelset::progress::Progress::new(|_, _| false),
        ..opts(0.5)
    };
    assert!(matches!(voxelize(&good, &o), Err(VoxelizeError::Cancelled(_))));
}

/// A square pyramid: base 2 × 2 at z = 0 (a quad, split into a fan), apex (1, 1, 1.5);
/// outward counter-clockwise; vertices 0..4 as in every file below.
const PYRAMID: [[f64; 3]; 5] =
    [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0], [1.0, 1.0, 1.5]];
const PYRAMID_FACES: [&[u32]; 5] = [&[0, 3, 2, 1], &[0, 1, 4], &[1, 2, 4], &[2, 3, 4], &[3, 0, 4]];

/// The triangles as sorted position triples, each turned to start at its least vertex
/// (orientation kept), whatever the vertex numbering.
fn soup(m: &TriangleMesh) -> Vec<[[f64; 3]; 3]> {
    let mut s: Vec<[[f64; 3]; 3]> = m
        .triangles
        .iter()
        .map(|t| {
            let p = t.map(|i| m.positions[i as usize]);
            let k = (0..3).min_by(|&a, &b| p[a].partial_cmp(&p[b]).unwrap()).unwrap();
            [p[k], p[(k + 1) % 3], p[(k + 2) % 3]]
        })
        .collect();
    s.sort_by(|a, b| a.partial_cmp(b).unwrap());
    s
}

fn pyramid() -> TriangleMesh {
    let mut triangles = Vec::new();
    for f in PYRAMID_FACES {
        for i in 1..f.len() - 1 {
            triangles.push([f[0], f[i], f[i + 1]]);
        }
    }
    TriangleMesh { positions: PYRAMID.to_vec(), normals: vec![], triangles }
}

fn file(name: &str, bytes: &[u8]) -> PathBuf {
    let p = common::tmp(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

const OBJ: &str = "# a pyramid\nmtllib no-such.mtl\no pyramid\nv 0 0 0\nv 2 0 0\nv 2 2 0\n\
                   v 0 2 0\nv 1 1 1.5\nvn 0 0 -1\nvt 0 0\nf 1/1/1 4/1/1 3/1/1 2/1/1\n\
                   f 1 2 5\nf 2//1 3//1 5//1\nf -2 -1 -3\nf 4 1 5\nl 1 2\n";

fn ascii_ply(vertices: &str, faces: &str) -> String {
    format!(
        "ply\nformat ascii 1.0\ncomment hand written\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nproperty uchar red\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n{vertices}{faces}",
        vertices.lines().count(),
        faces.lines().count()
    )
}

const PLY_VERTICES: &str = "0 0 0 255\n2 0 0 255\n2 2 0 255\n0 2 0 255\n1 1 1.5 0\n";
const PLY_FACES: &str = "4 0 3 2 1\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4\n";

/// Binary PLY of the pyramid: `double` coordinates, an `edge` element in between, faces
/// as `list uchar uint vertex_index`.
fn binary_ply(big_endian: bool) -> Vec<u8> {
    let fmt = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
    let mut b = format!(
        "ply\nformat {fmt} 1.0\nelement vertex 5\nproperty double x\nproperty double y\n\
         property double z\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n\
         element face 5\nproperty list uchar uint vertex_index\nend_header\n"
    )
    .into_bytes();
    let f64b = |v: f64| if big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
    let u32b = |v: u32| if big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
    for p in PYRAMID {
        for c in p {
            b.extend(f64b(c));
        }
    }
    b.extend(u32b(0));
    b.extend(u32b(1));
    for f in PYRAMID_FACES {
        b.push(f.len() as u8);
        for &i in f {
            b.extend(u32b(i));
        }
    }
    b
}

fn stl_binary(mesh: &TriangleMesh) -> Vec<u8> {
    let tris: Vec<stl_io::Triangle> = soup(mesh)
        .iter()
        .map(|t| stl_io::Triangle {
            normal: stl_io::Normal::new([0.0; 3]),
            vertices: t.map(|p| stl_io::Vertex::new(p.map(|c| c as f32))),
        })
        .collect();
    let mut out = Vec::new();
    stl_io::write_stl(&mut out, tris.iter()).unwrap();
    out
}

fn stl_ascii(mesh: &TriangleMesh) -> String {
    let mut s = String::from("solid pyramid\n");
    for t in soup(mesh) {
        s += "  facet normal 0 0 0\n    outer loop\n";
        for p in t {
            s += &format!("      vertex {} {} {}\n", p[0], p[1], p[2]);
        }
        s += "    endloop\n  endfacet\n";
    }
    s + "endsolid pyramid\n"
}

#[test]
fn every_reader_round_trips_a_small_mesh() {
    let want = soup(&pyramid());
    assert_eq!(want.len(), 6);
    let mut solid_header = stl_binary(&pyramid());
    solid_header[..14].copy_from_slice(b"solid exported");
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("pyramid.obj", OBJ.into()),
        ("PYRAMID.OBJ", OBJ.into()),
        ("pyramid.ply", ascii_ply(PLY_VERTICES, PLY_FACES).into_bytes()),
        ("pyramid-le.ply", binary_ply(false)),
        ("pyramid-be.Ply", binary_ply(true)),
        ("pyramid.stl", stl_binary(&pyramid())),
        ("pyramid-solid.stl", solid_header),
        ("pyramid-ascii.STL", stl_ascii(&pyramid()).into_bytes()),
        (
            "pyramid-bare.stl",
            stl_ascii(&pyramid()).replacen("solid pyramid", "solid", 1).into_bytes(),
        ),
    ];
    for (name, bytes) in cases {
        let m = read_mesh(&file(name, &bytes)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(soup(&m), want, "{name}");
        assert!(m.normals.is_empty(), "{name}");
        // And it voxelizes: the pyramid's apex region is inside.
        let grid = voxelize(&m, &opts(0.25)).unwrap();
        assert!(grid.value(Coord::new(4, 4, 2)) < 0.0, "{name}");
    }
}

fn refused(name: &str, bytes: &[u8]) -> MeshInError {
    let path = file(name, bytes);
    let e = read_mesh(&path).expect_err(name);
    let msg = e.to_string();
    assert!(msg.starts_with(&path.display().to_string()), "{name}: {msg}");
    e
}

#[test]
fn bad_mesh_files_give_their_errors_not_panics() {
    use MeshInError as E;
    let garbage: Vec<u8> = (0..100u32).map(|i| (i * 97 + 13) as u8 | 0x80).collect();
    // OBJ.
    let cut = OBJ.find("v 2 2 0").unwrap() + 3;
    assert!(matches!(refused("cut.obj", &OBJ.as_bytes()[..cut]), E::Parse { .. }));
    assert!(matches!(refused("garbage.obj", &garbage), E::Parse { .. }));
    let e = refused("nan.obj", b"v 0 0 0\nv 1 0 0\nv 0 NaN 0\nf 1 2 3\n");
    assert!(matches!(e, E::NonFinite { vertex: 2, .. }), "{e}");
    assert!(matches!(
        refused("inf.obj", b"v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n"),
        E::NonFinite { .. }
    ));
    let e = refused("index.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    assert!(matches!(&e, E::Parse { message, .. } if message.contains("out of bounds")), "{e}");
    assert!(matches!(
        refused("zero.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
        E::Parse { .. }
    ));
    assert!(matches!(refused("points.obj", b"v 0 0 0\nv 1 0 0\nf 1 2\n"), E::Empty { .. }));
    assert!(matches!(refused("empty.obj", b""), E::Empty { .. }));
    // PLY.
    let ply = ascii_ply(PLY_VERTICES, PLY_FACES);
    assert!(matches!(refused("cut.ply", &ply.as_bytes()[..ply.len() - 12]), E::Parse { .. }));
    assert!(matches!(refused("cut-header.ply", &ply.as_bytes()[..60]), E::Parse { .. }));
    let bin = binary_ply(false);
    assert!(matches!(
        refused("cut-binary.ply", &bin[..bin.len() - 30]),
        E::Truncated { .. } | E::Parse { .. }
    ));
    assert!(matches!(refused("garbage.ply", &garbage), E::Parse { .. }));
    // ASCII PLY has no spelling for NaN (the reader refuses the word); an overflowing
    // number reads as infinite, and binary PLY can hold a NaN.
    let e = refused("nan.ply", ascii_ply("0 0 0 1\n1 0 0 1\n0 nan 0 1\n", "3 0 1 2\n").as_bytes());
    assert!(matches!(e, E::Parse { .. }), "{e}");
    let e = refused("inf.ply", ascii_ply("0 0 0 1\n1 0 0 1\n0 1e99 0 1\n", "3 0 1 2\n").as_bytes());
    assert!(matches!(e, E::NonFinite { vertex: 2, .. }), "{e}");
    let mut nan = binary_ply(false);
    let at = nan.windows(11).position(|w| w == b"end_header\n").unwrap() + 11 + 3 * 24 + 8;
    nan[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    let e = refused("nan-binary.ply", &nan);
    assert!(matches!(e, E::NonFinite { vertex: 3, .. }), "{e}");
    let e = refused("index.ply", ascii_ply(PLY_VERTICES, "3 0 1 7\n").as_bytes());
    assert!(matches!(e, E::IndexOutOfRange { face: 0, index: 7, vertices: 5, .. }), "{e}");
    let e = refused("negative.ply", ascii_ply(PLY_VERTICES, "3 0 1 2\n3 0 -1 2\n").as_bytes());
    assert!(matches!(e, E::IndexOutOfRange { face: 1, index: -1, .. }), "{e}");
    assert!(matches!(
        refused("no-faces.ply", ascii_ply(PLY_VERTICES, "").as_bytes()),
        E::Empty { .. }
    ));
    let float_list = ply.replace("list uchar int", "list uchar float");
    assert!(matches!(refused("float-index.ply", float_list.as_bytes()), E::Parse { .. }));
    let no_z = ply.replace("property float z\n", "").replace(" 255\n", "\n").replace(" 0\n", "\n");
    assert!(matches!(refused("no-z.ply", no_z.as_bytes()), E::Parse { .. }));
    // A header claiming 10¹² elements in a file of about 100 bytes: refused from the
    // header, before the payload is read.
    for (fmt, name) in [("ascii", "huge-ascii.ply"), ("binary_little_endian", "huge.ply")] {
        let huge = format!(
            "ply\nformat {fmt} 1.0\nelement vertex 1000000000000\nproperty float x\n\
             property float y\nproperty float z\nelement face 1\n\
             property list uchar int vertex_indices\nend_header\n0 0 0\n"
        );
        let e = refused(name, huge.as_bytes());
        assert!(matches!(e, E::Truncated { claimed: 1_000_000_000_000, .. }), "{e}");
    }
    // STL.
    let stl = stl_binary(&pyramid());
    let e = refused("cut.stl", &stl[..stl.len() - 20]);
    assert!(matches!(e, E::Truncated { claimed: 6, .. }), "{e}");
    let mut huge = stl[..100].to_vec();
    huge[80..84].copy_from_slice(&1_000_000_000u32.to_le_bytes());
    assert!(matches!(refused("huge.stl", &huge), E::Truncated { claimed: 1_000_000_000, .. }));
    assert!(matches!(refused("short.stl", &stl[..50]), E::Parse { .. }));
    let mut nan = stl.clone();
    nan[84 + 16..84 + 20].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(matches!(refused("nan.stl", &nan), E::NonFinite { .. }));
    let mut none = stl[..84].to_vec();
    none[80..84].copy_from_slice(&0u32.to_le_bytes());
    assert!(matches!(refused("none.stl", &none), E::Empty { .. }));
    let ascii = stl_ascii(&pyramid());
    assert!(matches!(refused("cut-ascii.stl", &ascii.as_bytes()[..200]), E::Parse { .. }));
    let bad = ascii.replacen("vertex 0 0 0", "vertex 0 zero 0", 1);
    assert!(matches!(refused("word.stl", bad.as_bytes()), E::Parse { .. }));
    let e = refused("garbage.stl", &garbage);
    assert!(matches!(e, E::Truncated { .. } | E::Parse { .. }), "{e}");
    // Neither a known extension nor a file.
    assert!(matches!(refused("pyramid.off", OBJ.as_bytes()), E::UnknownFormat { .. }));
    assert!(matches!(refused("pyramid", OBJ.as_bytes()), E::UnknownFormat { .. }));
    let e = read_mesh(Path::new("/no/such/dir/mesh.obj")).unwrap_err();
    assert!(matches!(e, E::Io { .. }) && e.to_string().contains("mesh.obj"), "{e}");
}

#[test]
fn damaged_files_never_panic() {
    // Prefixes of each valid file and a few hundred damaged copies: the readers return a
    // mesh or an error, and a mesh they return is valid (triangles, indices in range,
    // finite coordinates).
    let files: Vec<(&str, Vec<u8>)> = vec![
        ("fuzz.obj", OBJ.into()),
        ("fuzz.ply", ascii_ply(PLY_VERTICES, PLY_FACES).into_bytes()),
        ("fuzz-le.ply", binary_ply(false)),
        ("fuzz.stl", stl_binary(&pyramid())),
        ("fuzz-ascii.stl", stl_ascii(&pyramid()).into_bytes()),
    ];
    let mut rng = fastrand::Rng::with_seed(13);
    for (name, bytes) in files {
        let path = common::tmp(name);
        let mut tries: Vec<Vec<u8>> =
            (0..bytes.len()).step_by(7).map(|n| bytes[..n].to_vec()).collect();
        for _ in 0..150 {
            let mut b = bytes.clone();
            for _ in 0..rng.usize(1..4) {
                let i = rng.usize(..b.len());
                b[i] = match rng.u8(..4) {
                    0 => rng.u8(..),
                    1 => b'9',
                    2 => b'-',
                    _ => b'\n',
                };
            }
            tries.push(b);
        }
        for b in tries {
            std::fs::write(&path, &b).unwrap();
            if let Ok(m) = read_mesh(&path) {
                assert!(!m.triangles.is_empty(), "{name}");
                assert!(m.triangles.iter().flatten().all(|&i| (i as usize) < m.positions.len()));
                assert!(m.positions.iter().flatten().all(|c| c.is_finite()), "{name}");
            }
        }
    }
}
