//! Triangle meshes of analytic shapes for the voxelizer's tests and benchmark: closed,
//! consistently oriented (counter-clockwise seen from outside), vertices shared.
#![allow(dead_code)]

use sparse_levelset::tools::mesh::TriangleMesh;
use std::f64::consts::PI;

/// A UV torus around the z axis: `n_major` segments along the centre circle of radius
/// `major`, `n_minor` around the tube of radius `minor`; `2 n_major n_minor` triangles.
pub fn uv_torus(
    center: [f64; 3],
    major: f64,
    minor: f64,
    n_major: usize,
    n_minor: usize,
) -> TriangleMesh {
    let mut positions = Vec::with_capacity(n_major * n_minor);
    for i in 0..n_major {
        let u = 2.0 * PI * i as f64 / n_major as f64;
        for j in 0..n_minor {
            let v = 2.0 * PI * j as f64 / n_minor as f64;
            let r = major + minor * v.cos();
            positions.push([
                center[0] + r * u.cos(),
                center[1] + r * u.sin(),
                center[2] + minor * v.sin(),
            ]);
        }
    }
    let id = |i: usize, j: usize| ((i % n_major) * n_minor + j % n_minor) as u32;
    let mut triangles = Vec::with_capacity(2 * n_major * n_minor);
    for i in 0..n_major {
        for j in 0..n_minor {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    TriangleMesh { positions, normals: Vec::new(), triangles }
}

/// A UV sphere: `n_lat` bands from pole to pole, `n_lon` segments around the z axis.
pub fn uv_sphere(center: [f64; 3], radius: f64, n_lat: usize, n_lon: usize) -> TriangleMesh {
    let mut positions = vec![[center[0], center[1], center[2] - radius]];
    for i in 1..n_lat {
        let theta = PI * i as f64 / n_lat as f64;
        let (z, r) = (-radius * theta.cos(), radius * theta.sin());
        for j in 0..n_lon {
            let phi = 2.0 * PI * j as f64 / n_lon as f64;
            positions.push([center[0] + r * phi.cos(), center[1] + r * phi.sin(), center[2] + z]);
        }
    }
    positions.push([center[0], center[1], center[2] + radius]);
    let top = positions.len() as u32 - 1;
    let ring = |i: usize, j: usize| (1 + (i - 1) * n_lon + j % n_lon) as u32;
    let mut triangles = Vec::new();
    for j in 0..n_lon {
        triangles.push([0, ring(1, j + 1), ring(1, j)]);
        triangles.push([top, ring(n_lat - 1, j), ring(n_lat - 1, j + 1)]);
    }
    for i in 1..n_lat - 1 {
        for j in 0..n_lon {
            let (a, b, c, d) = (ring(i, j), ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    TriangleMesh { positions, normals: Vec::new(), triangles }
}

/// An icosphere: the icosahedron subdivided `levels` times (20·4^levels triangles), its
/// vertices projected onto the sphere.
pub fn icosphere(center: [f64; 3], radius: f64, levels: u32) -> TriangleMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut unit: Vec<[f64; 3]> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| normalize(p))
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        let mut midpoint = |a: u32, b: u32, unit: &mut Vec<[f64; 3]>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (unit[a as usize], unit[b as usize]);
                unit.push(normalize([p[0] + q[0], p[1] + q[1], p[2] + q[2]]));
                unit.len() as u32 - 1
            })
        };
        for &[a, b, c] in &tris {
            let ab = midpoint(a, b, &mut unit);
            let bc = midpoint(b, c, &mut unit);
            let ca = midpoint(c, a, &mut unit);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    let positions = unit
        .iter()
        .map(|p| [center[0] + radius * p[0], center[1] + radius * p[1], center[2] + radius * p[2]])
        .collect();
    TriangleMesh { positions, normals: Vec::new(), triangles: tris }
}

/// The axis-aligned box `lo..hi` as 12 triangles.
pub fn cube(lo: [f64; 3], hi: [f64; 3]) -> TriangleMesh {
    let positions = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ]
        })
        .collect();
    let triangles = vec![
        [0, 2, 3],
        [0, 3, 1], // z = lo
        [4, 5, 7],
        [4, 7, 6], // z = hi
        [0, 1, 5],
        [0, 5, 4], // y = lo
        [2, 6, 7],
        [2, 7, 3], // y = hi
        [0, 4, 6],
        [0, 6, 2], // x = lo
        [1, 3, 7],
        [1, 7, 5], // x = hi
    ];
    TriangleMesh { positions, normals: Vec::new(), triangles }
}

/// Two meshes in one (the second's indices shifted).
pub fn join(a: &TriangleMesh, b: &TriangleMesh) -> TriangleMesh {
    let mut m = a.clone();
    let n = m.positions.len() as u32;
    m.positions.extend_from_slice(&b.positions);
    m.triangles.extend(b.triangles.iter().map(|t| t.map(|i| i + n)));
    m
}

fn normalize(p: [f64; 3]) -> [f64; 3] {
    let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    [p[0] / l, p[1] / l, p[2] / l]
}
