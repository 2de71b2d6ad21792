//! Meshes in: `voxelize` against brute force and analytic distances, open and
//! self-intersecting meshes, determinism, the default voxel size, and the mesh readers
//! (round trips and every kind of bad file).
//!
//! Tolerances: "exact" means equal to a brute-force f64 signed distance up to the f32
//! rounding of the stored value (4 ulp of γ, absolute); the analytic shapes are meshed finely
//! enough (chord error below 0.01 voxel, stated at each mesh) that the mesh's distance is
//! within 0.05 voxel of the shape's.

mod common;
#[path = "common/meshes.rs"]
mod meshes;

use meshes::{cube, icosphere, join, uv_sphere, uv_torus};
use sparse_levelset::mesh::TriangleMesh;
use sparse_levelset::tiles::TileGrid;
use sparse_levelset::voxelize::{
    default_voxel_size, read_mesh, voxelize, MeshInError, SignMethod, VoxelizeError,
    VoxelizeOptions,
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
