//! Simplicial isosurfacing (paper `simplicial-isosurfacing.txt`): closed, manifold,
//! oriented meshes of level sets on tiles, DT-Grid and dense fields, the n-dimensional
//! codimension-m construction, mesh files, and errors on bad input.

use sparse_levelset::build::{dtgrid_from_shape, tiles_from_shape, to_dense};
use sparse_levelset::dense::DenseField;
use sparse_levelset::grid::GridSpec;
use sparse_levelset::mesh::{
    cell_simplex_bound, isosurface_dense, isosurface_dtgrid, isosurface_nd, isosurface_tiles,
    MeshError, MeshFormat, NdField, TriangleMesh,
};
use sparse_levelset::shapes::Shape;
use sparse_levelset::Coord;
use std::f64::consts::PI;

mod common;

use common::{levelset, tmp};

/// Triangles as position bit patterns, each rotated to start at its smallest vertex
/// (orientation kept), sorted: equal sets ⇔ same triangles, whatever the vertex order.
fn canonical(m: &TriangleMesh) -> Vec<[[u64; 3]; 3]> {
    let mut out: Vec<[[u64; 3]; 3]> = m
        .triangles
        .iter()
        .map(|t| {
            let p = t.map(|v| m.positions[v as usize].map(f64::to_bits));
            let r = (0..3).min_by_key(|&i| p[i]).unwrap();
            [p[r], p[(r + 1) % 3], p[(r + 2) % 3]]
        })
        .collect();
    out.sort_unstable();
    out
}

/// Abs + rel tolerance check with the error printed.
fn close(what: &str, got: f64, exact: f64, rel: f64) {
    let err = (got - exact).abs() / exact.abs();
    println!("{what}: {got:.3} vs {exact:.3}, relative error {err:.3e}");
    assert!((got - exact).abs() <= 1e-9 + rel * exact.abs(), "{what}: error {err:.3e} > {rel}");
}

#[test]
fn sphere_r100_closed_manifold_area_volume() {
    let r = 100.0;
    let tiles = tiles_from_shape(
        &Shape::Sphere { center: [0.3, -0.2, 0.1], radius: r },
        GridSpec::default(),
    )
    .unwrap();
    let t0 = std::time::Instant::now();
    let m = isosurface_tiles(&tiles, 0.0).unwrap();
    println!(
        "sphere r=100: {} vertices, {} triangles from {} band voxels in {:.3} s",
        m.num_vertices(),
        m.num_triangles(),
        tiles.band_voxels(),
        t0.elapsed().as_secs_f64()
    );
    assert!(m.is_closed_manifold());
    assert_eq!(m.euler_characteristic(), 2);
    close("area", m.area(), 4.0 * PI * r * r, 5e-3);
    close("volume", m.enclosed_volume(), 4.0 / 3.0 * PI * r * r * r, 5e-3);
    // Vertices on the sphere, normals outward and unit.
    for (p, n) in m.positions.iter().zip(&m.normals) {
        let d = [p[0] - 0.3, p[1] + 0.2, p[2] - 0.1];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        assert!((len - r).abs() < 0.05, "vertex {p:?} at distance {len}");
        let nl = (n.iter().map(|&c| (c as f64).powi(2)).sum::<f64>()).sqrt();
        assert!((nl - 1.0).abs() < 1e-5);
        let cos = (0..3).map(|a| d[a] * n[a] as f64).sum::<f64>() / len;
        assert!(cos > 0.999, "normal {n:?} at {p:?}");
    }
}

#[test]
fn torus_has_euler_characteristic_0_and_sphere_2() {
    let spec = GridSpec::default();
    let torus = Shape::Torus { center: [1.5, -2.25, 0.7], major_radius: 24.0, minor_radius: 7.0 };
    let m = isosurface_tiles(&tiles_from_shape(&torus, spec).unwrap(), 0.0).unwrap();
    assert!(m.is_closed_manifold());
    assert_eq!(m.euler_characteristic(), 0);
    close("torus volume", m.enclosed_volume(), 2.0 * PI * PI * 24.0 * 49.0, 1e-2);
    let s = Shape::Sphere { center: [-40.2, 13.7, -7.1], radius: 9.5 };
    let m = isosurface_tiles(&tiles_from_shape(&s, spec).unwrap(), 0.0).unwrap();
    assert!(m.is_closed_manifold());
    assert_eq!(m.euler_characteristic(), 2);
}

#[test]
fn tiles_dense_and_dtgrid_give_the_same_mesh() {
    // Negative coordinates, not tile-aligned, a voxel size and origin that are not 1 and 0,
    // and exact zeros on the grid (a box with integer faces).
    let spec = GridSpec::new(0.5, [1.25, -3.0, 0.5], 3.0).unwrap();
    for shape in [
        Shape::Ellipsoid { center: [-7.3, 4.1, -9.9], radii: [9.0, 6.5, 5.0] },
        Shape::Box { center: [-6.25, 4.0, -10.5], half_extents: [5.0, 3.5, 4.0] },
    ] {
        let tiles = tiles_from_shape(&shape, spec).unwrap();
        let mt = isosurface_tiles(&tiles, 0.0).unwrap();
        assert!(mt.is_closed_manifold(), "{shape:?}");
        // The box's faces lie on voxel planes: φ = 0 exactly at voxels. The ε rule keeps
        // the mesh closed; its vertices sit a hair off those voxels (never on one), so
        // they stay distinct and no triangle has zero area.
        let off_voxel = |p: &[f64; 3]| {
            [0, 1, 2].map(|a| {
                let x = (p[a] - spec.origin[a]) / 0.5;
                (x - x.round()).abs()
            })
        };
        let exact = mt.positions.iter().filter(|p| off_voxel(p) == [0.0; 3]).count();
        let near = mt.positions.iter().filter(|p| off_voxel(p).iter().all(|&d| d < 1e-3)).count();
        assert_eq!(exact, 0, "{shape:?}: vertices on voxels");
        assert_eq!(near > 1000, matches!(shape, Shape::Box { .. }), "{shape:?}: {near}");
        assert_eq!(mt.degenerate_triangles(), 0, "{shape:?}");
        let (lo, hi) = tiles.bounding_box().unwrap();
        let origin = Coord::new(lo.x - 3, lo.y - 3, lo.z - 3);
        let dims = [hi.x - lo.x + 7, hi.y - lo.y + 7, hi.z - lo.z + 7].map(|d| d as usize);
        let dense = to_dense(&tiles, origin, dims).unwrap();
        let md = isosurface_dense(&dense, &spec, 0.0).unwrap();
        assert_eq!(canonical(&mt), canonical(&md), "{shape:?}: tiles vs dense");
        // Same key order in both, so even the vertex order and normals agree.
        assert_eq!(mt, md);
        let mg = isosurface_dtgrid(&dtgrid_from_shape(&shape, spec).unwrap(), 0.0).unwrap();
        assert_eq!(canonical(&mt), canonical(&mg), "{shape:?}: tiles vs DT-Grid");
    }
}

#[test]
fn same_bytes_for_one_and_two_threads() {
    let tiles =
        tiles_from_shape(&Shape::spiral_default([0.5, 0.0, -0.5], 30.0, 20.0), GridSpec::default())
            .unwrap();
    let mut files = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let m = pool.install(|| isosurface_tiles(&tiles, 0.0)).unwrap();
        assert!(m.is_closed_manifold());
        let p = tmp(&format!("spiral{threads}.ply"));
        m.write(&p, None).unwrap();
        files.push(std::fs::read(&p).unwrap());
    }
    assert_eq!(files[0], files[1]);
}

#[test]
fn level_set_near_the_i32_limit() {
    // Voxel coordinates near i32::MAX (the origin shifts the grid); the last tile's
    // neighbours are beyond the representable range and read as outside.
    let o = -(i32::MAX as f64) + 12.0;
    let spec = GridSpec::new(1.0, [o, o, 0.0], 3.0).unwrap();
    let tiles =
        tiles_from_shape(&Shape::Sphere { center: [0.0, 0.0, 0.0], radius: 6.0 }, spec).unwrap();
    let m = isosurface_tiles(&tiles, 0.0).unwrap();
    assert!(m.is_closed_manifold());
    assert_eq!(m.euler_characteristic(), 2);
}

/// Canonical triangle sets of the 3D fast path and of the general n-D code agree.
#[test]
fn fast_3d_path_matches_the_general_construction() {
    let dims = [23usize, 19, 21];
    let f = |x: f64, y: f64, z: f64| {
        let (a, b) = (((x - 11.2).powi(2) + (y - 9.1).powi(2)).sqrt() - 5.0, z - 10.3);
        (a * a + b * b).sqrt() - 2.6 + 0.3 * (0.7 * x).sin()
    };
    let dense = DenseField::from_fn(Coord::new(0, 0, 0), dims, |c| {
        f(c.x as f64, c.y as f64, c.z as f64) as f32
    })
    .unwrap();
    let fast = isosurface_dense(&dense, &GridSpec::default(), 0.0).unwrap();
    assert!(fast.is_closed_manifold());
    let nd = NdField::from_fn(&dims, 1, |x, out| {
        out[0] = dense.get(Coord::new(x[0] as i32, x[1] as i32, x[2] as i32)).unwrap() as f64;
    })
    .unwrap();
    let c = isosurface_nd(&nd).unwrap();
    assert!(c.is_closed() && c.is_consistently_oriented());
    let general = TriangleMesh {
        positions: (0..c.num_vertices())
            .map(|i| {
                let p = c.point(i);
                p[..3].iter().map(|&c| c as f32 as f64).collect::<Vec<_>>().try_into().unwrap()
            })
            .collect(),
        normals: vec![[0.0; 3]; c.num_vertices()],
        triangles: (0..c.num_simplices())
            .map(|s| {
                let t = c.simplex(s);
                [t[0], t[1], t[2]]
            })
            .collect(),
    };
    assert_eq!(canonical(&fast), canonical(&general));
    assert!(c.stats.max_simplices_per_cell <= cell_simplex_bound(3, 1));
}

/// Sec. 7.5: two spheres in R⁴ meet in the 2-sphere x² + y² + z² = 3/4, w = 0.
#[test]
fn two_spheres_in_r4_meet_in_a_closed_2_sphere() {
    let n = 24;
    let a = |i: usize| -1.3 + 2.6 * i as f64 / (n - 1) as f64;
    let f = NdField::from_fn(&[n; 4], 2, |x, out| {
        let r2 = a(x[0]).powi(2) + a(x[1]).powi(2) + a(x[2]).powi(2);
        out[0] = r2 + (a(x[3]) - 0.5).powi(2) - 1.0;
        out[1] = r2 + (a(x[3]) + 0.5).powi(2) - 1.0;
    })
    .unwrap();
    let c = isosurface_nd(&f).unwrap();
    println!(
        "R^4 spheres: {} vertices, {} triangles, {:?}",
        c.num_vertices(),
        c.num_simplices(),
        c.stats
    );
    assert_eq!(c.simplex_dim(), 2);
    assert!(c.num_simplices() > 100);
    assert!(c.is_closed() && c.is_consistently_oriented());
    assert_eq!(c.euler_characteristic(), 2);
    // Corollary 3.2 per Kuhn simplex: ≤ 3 (Table 3) × 2 (Table 2); per cell: 4! times that.
    assert!(c.stats.max_simplices_per_kuhn_simplex <= 6);
    assert!(c.stats.max_simplices_per_cell <= cell_simplex_bound(4, 2));
    assert_eq!(cell_simplex_bound(4, 2), 144);
    let h = 2.6 / (n - 1) as f64;
    for i in 0..c.num_vertices() {
        let p: Vec<f64> = c.point(i).iter().map(|&t| -1.3 + h * t).collect();
        let r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
        // Linear interpolation of quadratics: errors O(h²).
        assert!((r2 - 0.75).abs() < 1.0 * h * h && p[3].abs() < 1.0 * h * h, "{p:?}");
    }
}

/// Codimension 2 in 3D: a torus cut by a plane is two circles; every vertex has degree 2.
#[test]
fn codimension_2_curves_in_3d_are_closed() {
    let n = 40;
    let a = |i: usize| -1.5 + 3.0 * i as f64 / (n - 1) as f64;
    let f = NdField::from_fn(&[n; 3], 2, |x, out| {
        let (px, py, pz) = (a(x[0]), a(x[1]), a(x[2]));
        out[0] = ((px * px + py * py).sqrt() - 0.9).powi(2) + pz * pz - 0.3f64.powi(2);
        out[1] = px - 0.13 * pz - 0.05;
    })
    .unwrap();
    let c = isosurface_nd(&f).unwrap();
    assert_eq!(c.simplex_dim(), 1);
    assert!(c.is_closed() && c.is_consistently_oriented());
    let mut degree = vec![0; c.num_vertices()];
    for &v in &c.simplices {
        degree[v as usize] += 1;
    }
    assert!(degree.iter().all(|&d| d == 2));
    // Closed curves: V = E; two components.
    assert_eq!(c.euler_characteristic(), 0);
    assert_eq!(components(c.num_vertices(), &c.simplices, 2), 2);
    assert!(c.stats.max_simplices_per_kuhn_simplex <= 2);
    assert!(c.stats.max_simplices_per_cell <= cell_simplex_bound(3, 2));
}

fn components(nv: usize, simplices: &[u32], len: usize) -> usize {
    let mut parent: Vec<usize> = (0..nv).collect();
    fn find(p: &mut [usize], x: usize) -> usize {
        let mut r = x;
        while p[r] != r {
            r = p[r];
        }
        p[x] = r;
        r
    }
    for s in simplices.chunks(len) {
        for w in s.windows(2) {
            let (a, b) = (find(&mut parent, w[0] as usize), find(&mut parent, w[1] as usize));
            parent[a] = b;
        }
    }
    (0..nv).filter(|&v| find(&mut parent, v) == v).count()
}

/// A 3-sphere in R⁴ (m = 1, Table 3: tetrahedra that must conform across Kuhn simplices)
/// and a 2-sphere cut out of R⁵ by three functions (m = 3, Tables 4, 3, 2 in turn).
#[test]
fn higher_dimensions_are_closed() {
    let n = 10;
    let a = |i: usize| -1.3 + 2.6 * i as f64 / (n - 1) as f64;
    let f = NdField::from_fn(&[n; 4], 1, |x, out| {
        out[0] = x.iter().map(|&i| a(i).powi(2)).sum::<f64>() - 1.0;
    })
    .unwrap();
    let c = isosurface_nd(&f).unwrap();
    assert_eq!(c.simplex_dim(), 3);
    assert!(c.is_closed() && c.is_consistently_oriented());
    assert_eq!(c.euler_characteristic(), 0);
    assert!(c.stats.max_simplices_per_cell <= cell_simplex_bound(4, 1));

    let n = 11;
    let a = |i: usize| -1.3 + 2.6 * i as f64 / (n - 1) as f64 + 0.01;
    let f = NdField::from_fn(&[n; 5], 3, |x, out| {
        out[0] = x.iter().map(|&i| a(i).powi(2)).sum::<f64>() - 1.0;
        out[1] = a(x[3]) - 0.2 * a(x[0]) - 0.1;
        out[2] = a(x[4]) + 0.15 * a(x[1]);
    })
    .unwrap();
    let c = isosurface_nd(&f).unwrap();
    println!("R^5, m = 3: {} triangles, {:?}", c.num_simplices(), c.stats);
    assert_eq!(c.simplex_dim(), 2);
    assert!(c.is_closed() && c.is_consistently_oriented());
    assert_eq!(c.euler_characteristic(), 2);
    assert!(c.stats.max_simplices_per_kuhn_simplex <= 6 * 3 * 2);
    assert!(c.stats.max_simplices_per_cell <= cell_simplex_bound(5, 3));
}

#[test]
fn mesh_files() {
    let m = isosurface_tiles(
        &tiles_from_shape(&Shape::Sphere { center: [0.0; 3], radius: 5.0 }, GridSpec::default())
            .unwrap(),
        0.0,
    )
    .unwrap();
    let (nv, nf) = (m.num_vertices(), m.num_triangles());
    let header_end = |bytes: &[u8]| {
        let s = b"end_header\n";
        bytes.windows(s.len()).position(|w| w == s).unwrap() + s.len()
    };
    let p = tmp("s.ply");
    m.write(&p, None).unwrap();
    let b = std::fs::read(&p).unwrap();
    let h = header_end(&b);
    let head = std::str::from_utf8(&b[..h]).unwrap();
    assert!(
        head.contains("binary_little_endian")
            && head.contains(&format!("element vertex {nv}\n"))
            && head.contains("property float x\n")
    );
    assert_eq!(b.len() - h, nv * 24 + nf * 13);
    // First vertex round-trips bitwise.
    let x = f32::from_le_bytes(b[h..h + 4].try_into().unwrap());
    assert_eq!((x as f64).to_bits(), m.positions[0][0].to_bits());

    let p = tmp("s_ascii.ply");
    m.write(&p, Some(MeshFormat::from_path(&p, true).unwrap())).unwrap();
    let t = std::fs::read_to_string(&p).unwrap();
    let body: Vec<&str> = t.split("end_header\n").nth(1).unwrap().lines().collect();
    assert_eq!(body.len(), nv + nf);
    let first: Vec<f32> = body[0].split(' ').map(|s| s.parse().unwrap()).collect();
    assert_eq!(first[..3], m.positions[0].map(|c| c as f32)[..]);
    assert_eq!(first[3..], m.normals[0][..]);

    let p = tmp("s.OBJ");
    m.write(&p, None).unwrap();
    let t = std::fs::read_to_string(&p).unwrap();
    assert_eq!(t.lines().filter(|l| l.starts_with("v ")).count(), nv);
    assert_eq!(t.lines().filter(|l| l.starts_with("vn ")).count(), nv);
    let faces: Vec<&str> = t.lines().filter(|l| l.starts_with("f ")).collect();
    assert_eq!(faces.len(), nf);
    let t0 = m.triangles[0];
    assert_eq!(faces[0], format!("f {0}//{0} {1}//{1} {2}//{2}", t0[0] + 1, t0[1] + 1, t0[2] + 1));
}

#[test]
fn bad_input_is_an_error() {
    assert!(matches!(
        NdField::new(&[3, 3], 1, vec![0.0, 1.0, f64::NAN, 0., 0., 0., 0., 0., 0.]),
        Err(MeshError::NonFinite { index: 2 })
    ));
    assert!(NdField::new(&[3, 3], 1, vec![0.0; 8]).is_err(), "wrong length");
    assert!(NdField::new(&[2; 6], 1, vec![0.0; 64]).is_err(), "n = 6");
    assert!(NdField::new(&[2; 3], 3, vec![0.0; 24]).is_err(), "m = n");
    assert!(NdField::new(&[2, 0, 2], 1, vec![]).is_err(), "empty axis");
    assert!(NdField::from_fn(&[1 << 20, 1 << 20, 1 << 20], 1, |_, _| {}).is_err(), "too many");
    let spec = GridSpec::default();
    // ±∞ is a far-away distance (as read_npy accepts it), NaN an error.
    let mut d = DenseField::from_fn(Coord::new(-3, 0, 2), [9, 8, 9], |c| {
        let r = [c.x, c.y - 4, c.z - 6].map(|v| v as f32);
        (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt() - 2.5
    })
    .unwrap();
    d.set(Coord::new(0, 4, 6), f32::NEG_INFINITY).unwrap();
    d.set(Coord::new(-3, 0, 2), f32::INFINITY).unwrap();
    d.set(Coord::new(2, 4, 6), f32::INFINITY).unwrap();
    let m = isosurface_dense(&d, &spec, 0.0).unwrap();
    assert!(m.is_closed_manifold() && m.positions.iter().flatten().all(|c| c.is_finite()));
    d.set(Coord::new(-1, 1, 3), f32::NAN).unwrap();
    assert!(matches!(isosurface_dense(&d, &spec, 0.0), Err(MeshError::NaN { .. })));
    let tiles = tiles_from_shape(&Shape::Sphere { center: [0.0; 3], radius: 5.0 }, spec).unwrap();
    assert!(isosurface_tiles(&tiles, f64::NAN).is_err());
    assert!(isosurface_tiles(&tiles, 3.0).is_err(), "iso at γ");
    // Empty level sets give empty meshes, which are not closed manifolds.
    let m = isosurface_tiles(&sparse_levelset::tiles::TileGrid::new(spec), 0.0).unwrap();
    assert!(m.is_empty() && !m.is_closed_manifold());
    let m = isosurface_dense(
        &DenseField::new(Coord::new(0, 0, 0), [3, 3, 3], 2.0).unwrap(),
        &spec,
        0.0,
    )
    .unwrap();
    assert!(m.is_empty());
    let m = isosurface_tiles(&tiles, 0.0).unwrap();
    assert!(matches!(m.write(&tmp("x.stl"), None), Err(MeshError::UnknownFormat(_))));
    assert!(matches!(m.write(&tmp("noext"), None), Err(MeshError::UnknownFormat(_))));
    assert!(matches!(m.write(&tmp("no/such/dir/x.ply"), None), Err(MeshError::Io { .. })));
    // A corrupt mesh is refused before anything is written.
    let mut bad = m.clone();
    bad.triangles[0][1] = bad.positions.len() as u32;
    assert!(!bad.is_closed_manifold());
    assert!(bad.write(&tmp("bad.ply"), None).is_err());
    assert!(!tmp("bad.ply").exists());
}

#[test]
fn cli_meshes_shapes_and_npy_fields_and_refuses_bad_input() {
    let ok = |args: &[&str]| {
        let o = levelset(args);
        assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8(o.stdout).unwrap()
    };
    let fails = |args: &[&str], msg: &str| {
        let o = levelset(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("error:") && err.contains(msg), "{args:?}: {err}");
    };
    let out = tmp("cli_torus.obj");
    let s = ok(&[
        "mesh",
        "--shape",
        "torus",
        "--major-radius",
        "12",
        "--minor-radius",
        "4",
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(s.contains("closed manifold: yes") && s.contains("Euler characteristic 0"), "{s}");
    assert!(std::fs::metadata(&out).unwrap().len() > 0);

    // A ball in a dense field with voxel size 0.5: radius 4.5 world units.
    let ball = common::ball([24, 22, 23], [11.3, 10.6, 11.1], 9.0, 0.5);
    let npy = common::npy("ball.npy", &ball);
    let ply = tmp("ball.ply");
    let s = ok(&[
        "mesh",
        "--input",
        npy.to_str().unwrap(),
        "--voxel-size",
        "0.5",
        "-o",
        ply.to_str().unwrap(),
    ]);
    assert!(s.contains("closed manifold: yes") && s.contains("Euler characteristic 2"), "{s}");
    let m = isosurface_dense(&ball, &GridSpec::new(0.5, [0.0; 3], 3.0).unwrap(), 0.0).unwrap();
    assert!(s.contains(&format!("{} vertices, {} triangles", m.num_vertices(), m.num_triangles())));
    close("ball volume", m.enclosed_volume(), 4.0 / 3.0 * PI * 4.5f64.powi(3), 2e-2);

    let mut bad = ball.clone();
    bad.set(Coord::new(3, 4, 5), f32::NAN).unwrap();
    let nan = tmp("nan.npy");
    sparse_levelset::npy::write_npy(&nan, &bad).unwrap();
    fails(&["mesh", "--input", nan.to_str().unwrap(), "-o", ply.to_str().unwrap()], "NaN");
    let empty = tmp("empty.npy");
    sparse_levelset::npy::write_npy(
        &empty,
        &DenseField::new(Coord::new(0, 0, 0), [5, 5, 5], 1.0).unwrap(),
    )
    .unwrap();
    fails(&["mesh", "--input", empty.to_str().unwrap(), "-o", ply.to_str().unwrap()], "no surface");
    let trunc = tmp("trunc.npy");
    let bytes = std::fs::read(&npy).unwrap();
    std::fs::write(&trunc, &bytes[..bytes.len() / 2]).unwrap();
    fails(&["mesh", "--input", trunc.to_str().unwrap(), "-o", ply.to_str().unwrap()], "");
    fails(&["mesh", "-o", tmp("x.stl").to_str().unwrap()], "unknown mesh format");
    fails(&["mesh", "--radius=-5", "-o", ply.to_str().unwrap()], "");
    fails(
        &["mesh", "--radius", "10", "--iso", "3", "-o", ply.to_str().unwrap()],
        "outside the band",
    );
    fails(&["mesh", "--voxel-size", "0", "-o", ply.to_str().unwrap()], "voxel size");
    fails(&["mesh", "--center", "1,2", "-o", ply.to_str().unwrap()], "three comma-separated");
    let s = ok(&["mesh", "--center", "-5.5,2,-3", "--radius", "6", "-o", out.to_str().unwrap()]);
    assert!(s.contains("closed manifold: yes"), "{s}");
    // The failed runs left the earlier file alone.
    assert_eq!(std::fs::read(&ply).unwrap().len() as u64, std::fs::metadata(&ply).unwrap().len());
}
