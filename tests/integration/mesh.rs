//! Simplicial isosurfacing (Min 2003): closed, manifold,
//! oriented meshes of level sets on tiles, DT-Grid and dense fields, the n-dimensional
//! codimension-m construction, mesh files, and errors on bad input.

use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::{
    dtgrid_from_dense, dtgrid_from_shape, tiles_from_dense, tiles_from_shape, to_dense,
};
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::tools::mesh::{
    cell_simplex_bound, isosurface, isosurface_dense, isosurface_dense_with, isosurface_nd, Border,
    DenseMeshOptions, Inside, MeshError, MeshOptions, NdField, TriangleMesh,
};
use sparse_levelset::Coord;
use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::Path;

use crate::common::tmp;
use sparse_levelset::io::mesh::{load_mesh, save_mesh, MeshFormat};

/// Triangles as position bit patterns, each rotated to start at its smallest vertex
/// (orientation kept), sorted: equal sets ⇔ same triangles, whatever the vertex order.
/// The one isosurface function at `iso` (every storage goes through it).
fn mesh_at<G: sparse_levelset::LevelSet>(
    g: &G,
    iso: f64,
) -> Result<sparse_levelset::tools::mesh::TriangleMesh, sparse_levelset::tools::mesh::MeshError> {
    isosurface(g, &MeshOptions { iso, ..Default::default() })
}

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

/// A PLY file as `save_mesh` writes it, read back (binary little-endian or
/// ASCII; positions `float` or `double`, normals `float`, faces `list uchar int`), and
/// whether its positions were `double`.
fn read_ply(path: &Path) -> (TriangleMesh, bool) {
    let bytes = std::fs::read(path).unwrap();
    let end = b"end_header\n";
    let h = bytes.windows(end.len()).position(|w| w == end).unwrap() + end.len();
    let head = std::str::from_utf8(&bytes[..h]).unwrap();
    let count = |el: &str| -> usize {
        let l = head.lines().find(|l| l.starts_with(&format!("element {el} "))).unwrap();
        l.rsplit(' ').next().unwrap().parse().unwrap()
    };
    let (nv, nf) = (count("vertex"), count("face"));
    let double = head.contains("property double x\n");
    assert!(double || head.contains("property float x\n"), "{head}");
    let mut m = TriangleMesh::default();
    if head.contains("format ascii") {
        let body = std::str::from_utf8(&bytes[h..]).unwrap();
        let mut lines = body.lines();
        for _ in 0..nv {
            let w: Vec<&str> = lines.next().unwrap().split(' ').collect();
            let p = |s: &str| {
                if double {
                    s.parse().unwrap()
                } else {
                    s.parse::<f32>().unwrap() as f64
                }
            };
            m.positions.push([p(w[0]), p(w[1]), p(w[2])]);
            m.normals.push([3, 4, 5].map(|i| w[i].parse().unwrap()));
        }
        for _ in 0..nf {
            let w: Vec<u32> =
                lines.next().unwrap().split(' ').map(|s| s.parse().unwrap()).collect();
            assert_eq!(w[0], 3);
            m.triangles.push([w[1], w[2], w[3]]);
        }
    } else {
        let mut at = h;
        let mut take = |n: usize| {
            at += n;
            &bytes[at - n..at]
        };
        for _ in 0..nv {
            let mut p = [0f64; 3];
            for c in &mut p {
                *c = if double {
                    f64::from_le_bytes(take(8).try_into().unwrap())
                } else {
                    f32::from_le_bytes(take(4).try_into().unwrap()) as f64
                };
            }
            m.positions.push(p);
            m.normals.push([0; 3].map(|_| f32::from_le_bytes(take(4).try_into().unwrap())));
        }
        for _ in 0..nf {
            assert_eq!(take(1), [3]);
            m.triangles
                .push([0; 3].map(|_| i32::from_le_bytes(take(4).try_into().unwrap()) as u32));
        }
        assert_eq!(at, bytes.len());
    }
    (m, double)
}

/// Vertices at equal positions merged (exact equality, as trimesh's `merge_vertices`
/// does on the positions it read), written independently of `TriangleMesh::weld_coincident`.
fn weld(m: &TriangleMesh) -> TriangleMesh {
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let mut out = TriangleMesh::default();
    let remap: Vec<u32> = m
        .positions
        .iter()
        .map(|p| {
            *index.entry(p.map(|c| (c + 0.0).to_bits())).or_insert_with(|| {
                out.positions.push(*p);
                out.normals.push([0.0; 3]);
                out.positions.len() as u32 - 1
            })
        })
        .collect();
    out.triangles = m.triangles.iter().map(|t| t.map(|v| remap[v as usize])).collect();
    out
}

/// Triangles of zero area, from the cross product of the positions' differences.
fn zero_area(m: &TriangleMesh) -> usize {
    m.triangles
        .iter()
        .filter(|t| {
            let [a, b, c] = t.map(|v| m.positions[v as usize]);
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            u[1] * v[2] == u[2] * v[1] && u[2] * v[0] == u[0] * v[2] && u[0] * v[1] == u[1] * v[0]
        })
        .count()
}

/// The mesh is a closed manifold with Euler characteristic `chi` and no zero-area
/// triangle as it is, as written to binary and ASCII PLY and read back, and after
/// welding coincident positions of what was read. Returns whether it was written as
/// `double`.
fn check_as_written(m: &TriangleMesh, name: &str, chi: i64) -> bool {
    assert!(m.is_closed_manifold(), "{name}");
    assert_eq!(m.euler_characteristic(), chi, "{name}");
    assert_eq!(zero_area(m), 0, "{name}: zero-area triangles");
    assert_eq!(m.degenerate_triangles(), 0, "{name}");
    assert!(m.weld_coincident() == *m, "{name}: the library's weld merges vertices");
    let mut double = None;
    for format in [MeshFormat::Ply { ascii: false }, MeshFormat::Ply { ascii: true }] {
        let path = tmp(&format!("{name}-{format:?}.ply"));
        save_mesh(&path, m, Some(format)).unwrap();
        let (read, d) = read_ply(&path);
        std::fs::remove_file(&path).unwrap();
        assert_eq!(*double.get_or_insert(d), d);
        let bits =
            |m: &TriangleMesh| m.positions.iter().map(|p| p.map(f64::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&read), bits(m), "{name} {format:?}: positions as written");
        assert_eq!(read.triangles, m.triangles, "{name} {format:?}");
        let welded = weld(&read);
        assert_eq!(welded.num_vertices(), m.num_vertices(), "{name}: coincident vertices");
        assert!(welded.is_closed_manifold(), "{name} {format:?}: welded");
        assert_eq!(welded.euler_characteristic(), chi, "{name} {format:?}: welded");
        assert_eq!(zero_area(&welded), 0, "{name} {format:?}: welded");
    }
    double.unwrap()
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
    let m = mesh_at(&tiles, 0.0).unwrap();
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
    let m = mesh_at(&tiles_from_shape(&torus, spec).unwrap(), 0.0).unwrap();
    assert!(m.is_closed_manifold());
    assert_eq!(m.euler_characteristic(), 0);
    close("torus volume", m.enclosed_volume(), 2.0 * PI * PI * 24.0 * 49.0, 1e-2);
    let s = Shape::Sphere { center: [-40.2, 13.7, -7.1], radius: 9.5 };
    let m = mesh_at(&tiles_from_shape(&s, spec).unwrap(), 0.0).unwrap();
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
        let mt = mesh_at(&tiles, 0.0).unwrap();
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
        let mg = mesh_at(&dtgrid_from_shape(&shape, spec).unwrap(), 0.0).unwrap();
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
        let m = pool.install(|| mesh_at(&tiles, 0.0)).unwrap();
        assert!(m.is_closed_manifold());
        let p = tmp(&format!("spiral{threads}.ply"));
        save_mesh(&p, &m, None).unwrap();
        files.push(std::fs::read(&p).unwrap());
    }
    assert_eq!(files[0], files[1]);
}

/// A sphere of integer radius centred on a voxel has voxels exactly on it: values equal to
/// iso, which count as outside (the ε rule of Sec. 3). Meshed with vertices on those
/// voxels this sphere had 1 668 zero-area triangles and was no manifold once coincident
/// vertices were welded; now every vertex sits a hair off the voxel along its own edge.
#[test]
fn exact_zeros_give_no_zero_area_triangles_sphere_r100() {
    let r = 100.0;
    let tiles =
        tiles_from_shape(&Shape::Sphere { center: [0.0; 3], radius: r }, GridSpec::default())
            .unwrap();
    let zeros = tiles.values().iter().flat_map(|t| t.0).filter(|&v| v == 0.0).count();
    assert!(zeros > 100, "{zeros} exact zeros");
    let m = mesh_at(&tiles, 0.0).unwrap();
    println!(
        "sphere r=100 at a voxel: {zeros} exact zeros, {} vertices, {} triangles",
        m.num_vertices(),
        m.num_triangles()
    );
    assert!(!check_as_written(&m, "sphere100", 2), "f32 holds this mesh");
    close("area", m.area(), 4.0 * PI * r * r, 1e-4);
    close("volume", m.enclosed_volume(), 4.0 / 3.0 * PI * r * r * r, 1e-4);
}

/// A signed distance in world coordinates.
type Sdf = Box<dyn Fn([f64; 3]) -> f64 + Sync>;
/// Name, grid, field, dense array (origin, dims), Euler characteristic, least number of
/// exact zeros.
type ZeroCase = (&'static str, GridSpec, Sdf, Coord, [usize; 3], i64, usize);

/// Fields with many exact zeros at voxels: planes of voxels (a box, an oblique plane),
/// lattice points on a sphere, and saddles where the ε rule separates two pieces that
/// touch at voxels (two balls touching at one voxel, a double cone with its apex on a
/// voxel, two wedges |y| > |x| meeting along a line of voxels). Collapsing the vertices
/// at each voxel into one would pinch the last three (χ = 3); the ε rule keeps them
/// apart (χ = 4), and vertices kept off the voxels keep that true after welding.
#[test]
fn exact_zeros_on_tiles_dtgrid_and_dense_give_closed_manifolds() {
    let unit = GridSpec::default();
    let len = |p: [f64; 3]| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    let shift = |p: [f64; 3], c: [f64; 3]| [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
    let half = GridSpec::new(0.5, [1.25, -3.0, 0.5], 3.0).unwrap();
    let cube = Shape::Box { center: [-6.25, 4.0, -10.5], half_extents: [5.0, 3.5, 4.0] };
    let cases: Vec<ZeroCase> = vec![
        (
            "box",
            half,
            Box::new(move |p| cube.sdf(p)),
            Coord::new(-33, -1, -38),
            [37, 31, 33],
            2,
            1000,
        ),
        (
            "sphere",
            unit,
            Box::new(move |p| len(shift(p, [-3.0, 2.0, 5.0])) - 25.0),
            Coord::new(-36, -31, -28),
            [67; 3],
            2,
            100,
        ),
        (
            "plane",
            unit,
            Box::new(move |p| {
                ((p[0] + 2.0 * p[1] - 2.0 * p[2]) / 3.0).max(len(shift(p, [0.3, -0.2, 0.1])) - 18.0)
            }),
            Coord::new(-26, -26, -26),
            [53; 3],
            2,
            300,
        ),
        (
            "touching balls",
            unit,
            Box::new(move |p| {
                (len(shift(p, [-6.0, 0.0, 0.0])) - 6.0).min(len(shift(p, [6.0, 0.0, 0.0])) - 6.0)
            }),
            Coord::new(-20, -14, -14),
            [41, 29, 29],
            4,
            50,
        ),
        (
            "double cone",
            unit,
            Box::new(move |p| {
                (((p[0] * p[0] + p[1] * p[1]).sqrt() - p[2].abs()) / 2f64.sqrt()).max(len(p) - 15.0)
            }),
            Coord::new(-23, -23, -23),
            [47; 3],
            4,
            100,
        ),
        (
            "wedges",
            unit,
            Box::new(move |p| ((p[0].abs() - p[1].abs()) / 2f64.sqrt()).max(len(p) - 15.0)),
            Coord::new(-23, -23, -23),
            [47; 3],
            4,
            500,
        ),
    ];
    for (name, spec, sdf, lo, dims, chi, min_zeros) in cases {
        let field = DenseField::from_fn(lo, dims, |c| sdf(spec.world(c)) as f32).unwrap();
        assert!(!field.boundary_touches(spec.gamma()), "{name}: the array holds the band");
        let zeros = field.data().iter().filter(|&&v| v == 0.0).count();
        assert!(zeros >= min_zeros, "{name}: {zeros} exact zeros");
        let tiles = tiles_from_dense(&field, spec).unwrap();
        let mut files = Vec::new();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mt = pool.install(|| mesh_at(&tiles, 0.0)).unwrap();
            let md = pool.install(|| isosurface_dense(&field, &spec, 0.0)).unwrap();
            let dt = dtgrid_from_dense(&field, spec).unwrap();
            let mg = pool.install(|| mesh_at(&dt, 0.0)).unwrap();
            assert_eq!(mt, md, "{name}: tiles vs dense, {threads} threads");
            assert_eq!(mt, mg, "{name}: tiles vs DT-Grid, {threads} threads");
            let p = tmp(&format!("zeros-{threads}.ply"));
            save_mesh(&p, &mt, None).unwrap();
            files.push(std::fs::read(&p).unwrap());
            if threads == 1 {
                assert!(!check_as_written(&mt, name, chi), "{name}: f32 holds this mesh");
                let min_area = mt
                    .triangles
                    .iter()
                    .map(|t| {
                        let m1 = TriangleMesh {
                            positions: t.iter().map(|&v| mt.positions[v as usize]).collect(),
                            normals: vec![[0.0; 3]; 3],
                            triangles: vec![[0, 1, 2]],
                        };
                        m1.area()
                    })
                    .fold(f64::INFINITY, f64::min);
                println!(
                    "{name}: {zeros} exact zeros, {} vertices, {} triangles, χ = {chi}, \
                     smallest triangle area {min_area:.2e}",
                    mt.num_vertices(),
                    mt.num_triangles()
                );
            }
        }
        assert_eq!(files[0], files[1], "{name}: same bytes for 1 and 2 threads");
    }
}

/// Far from the origin f32 cannot hold a mesh (its ulp at 2³¹ is 256 voxels; at 2²⁴
/// it is 2): positions are f64 there and written as `double`, and the mesh is the one
/// at the origin moved by the centre, to a small fraction of a voxel.
#[test]
fn far_from_the_origin_positions_keep_voxel_accuracy() {
    let spec = GridSpec::default();
    let sphere = |x: f64| Shape::Sphere { center: [x, 0.0, 0.0], radius: 10.0 };
    let near = mesh_at(&tiles_from_shape(&sphere(0.0), spec).unwrap(), 0.0).unwrap();
    assert!(!check_as_written(&near, "near", 2));
    let exact_area = 4.0 * PI * 100.0;
    close("area near the origin", near.area(), exact_area, 5e-3);
    for x in [16_777_216.0, 2_147_483_000.0] {
        let far = mesh_at(&tiles_from_shape(&sphere(x), spec).unwrap(), 0.0).unwrap();
        assert!(check_as_written(&far, &format!("far{x}"), 2), "written as double");
        assert!(!far.positions_are_f32());
        // Same values (integer differences from the centre), same mesh moved by x: the
        // offsets of vertices on exact zeros differ by a few 10⁻⁵ voxels at most.
        assert_eq!(far.triangles, near.triangles);
        for (p, q) in far.positions.iter().zip(&near.positions) {
            let d = [p[0] - x - q[0], p[1] - q[1], p[2] - q[2]];
            assert!(d.iter().all(|c| c.abs() <= 1e-4), "{p:?} vs {q:?} + {x}");
        }
        close(&format!("area at {x}"), far.area(), near.area(), 1e-6);
        close(&format!("volume at {x}"), far.enclosed_volume(), near.enclosed_volume(), 1e-6);
        // OBJ text reads back to the same f64 values.
        let obj = tmp("far.obj");
        save_mesh(&obj, &far, None).unwrap();
        let text = std::fs::read_to_string(&obj).unwrap();
        let vs: Vec<[f64; 3]> = text
            .lines()
            .filter_map(|l| l.strip_prefix("v "))
            .map(|l| {
                let w: Vec<f64> = l.split(' ').map(|s| s.parse().unwrap()).collect();
                [w[0], w[1], w[2]]
            })
            .collect();
        assert_eq!(vs, far.positions);
    }
}

/// Where not even f64 resolves 1/4096 of a voxel, meshing refuses.
#[test]
fn coordinates_beyond_f64_precision_are_an_error() {
    let spec = GridSpec::new(1.0, [1e15, 0.0, 0.0], 3.0).unwrap();
    let tiles =
        tiles_from_shape(&Shape::Sphere { center: [1e15, 0.0, 0.0], radius: 5.0 }, spec).unwrap();
    let err = mesh_at(&tiles, 0.0).unwrap_err();
    assert!(matches!(err, MeshError::Precision { .. }), "{err}");
    assert!(err.to_string().contains("f64"), "{err}");
    // 2⁴⁰ voxels still work (f64 ulp 2⁻¹² there).
    let spec = GridSpec::new(1.0, [(1u64 << 39) as f64, 0.0, 0.0], 3.0).unwrap();
    let c = (1u64 << 39) as f64;
    let m = mesh_at(
        &tiles_from_shape(&Shape::Sphere { center: [c, 0.0, 0.0], radius: 5.0 }, spec).unwrap(),
        0.0,
    )
    .unwrap();
    assert!(check_as_written(&m, "2^39", 2));
}

#[test]
fn level_set_near_the_i32_limit() {
    // Voxel coordinates near i32::MAX (the origin shifts the grid); the last tile's
    // neighbours are beyond the representable range and read as outside.
    let o = -(i32::MAX as f64) + 12.0;
    let spec = GridSpec::new(1.0, [o, o, 0.0], 3.0).unwrap();
    let tiles =
        tiles_from_shape(&Shape::Sphere { center: [0.0, 0.0, 0.0], radius: 6.0 }, spec).unwrap();
    let m = mesh_at(&tiles, 0.0).unwrap();
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
    let m = mesh_at(
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
    save_mesh(&p, &m, None).unwrap();
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
    save_mesh(&p, &m, Some(MeshFormat::Ply { ascii: true })).unwrap();
    let t = std::fs::read_to_string(&p).unwrap();
    let body: Vec<&str> = t.split("end_header\n").nth(1).unwrap().lines().collect();
    assert_eq!(body.len(), nv + nf);
    let first: Vec<f32> = body[0].split(' ').map(|s| s.parse().unwrap()).collect();
    assert_eq!(first[..3], m.positions[0].map(|c| c as f32)[..]);
    assert_eq!(first[3..], m.normals[0][..]);

    let p = tmp("s.OBJ");
    save_mesh(&p, &m, None).unwrap();
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
    assert!(mesh_at(&tiles, f64::NAN).is_err());
    assert!(mesh_at(&tiles, 3.0).is_err(), "iso at γ");
    // Empty level sets give empty meshes, which are not closed manifolds.
    let m = mesh_at(&sparse_levelset::storage::tiles::TileGrid::new(spec), 0.0).unwrap();
    assert!(m.is_empty() && !m.is_closed_manifold());
    let m = isosurface_dense(
        &DenseField::new(Coord::new(0, 0, 0), [3, 3, 3], 2.0).unwrap(),
        &spec,
        0.0,
    )
    .unwrap();
    assert!(m.is_empty());
    let m = mesh_at(&tiles, 0.0).unwrap();
    assert!(matches!(save_mesh(&tmp("x.xyz"), &m, None), Err(MeshError::UnknownFormat(_))));
    // Binary STL: f32 positions (exact here), the triangles in order, read back as they were.
    save_mesh(&tmp("x.stl"), &m, None).unwrap();
    let back = load_mesh(&tmp("x.stl")).unwrap();
    assert_eq!(back.triangles.len(), m.triangles.len());
    let at = |mesh: &TriangleMesh, t: usize| mesh.triangles[t].map(|v| mesh.positions[v as usize]);
    assert!((0..m.triangles.len()).all(|t| at(&back, t) == at(&m, t)));
    assert!(matches!(save_mesh(&tmp("noext"), &m, None), Err(MeshError::UnknownFormat(_))));
    assert!(matches!(save_mesh(&tmp("no/such/dir/x.ply"), &m, None), Err(MeshError::Io { .. })));
    // A corrupt mesh is refused before anything is written.
    let mut bad = m.clone();
    bad.triangles[0][1] = bad.positions.len() as u32;
    assert!(!bad.is_closed_manifold());
    assert!(save_mesh(&tmp("bad.ply"), &bad, None).is_err());
    assert!(!tmp("bad.ply").exists());
}

/// A band with absent tiles next to the surface: sphere tiles that hold a sign change
/// removed (no two of them neighbours, each reading ±γ with the sign of the absent tiles
/// around it, or of its centre where it has none, so every cut cell keeps a stored
/// corner). Cells then start in absent tiles (owned by the first stored
/// corner's tile) and Kuhn edges start there (vertices no tile owns, welded on their
/// own): the mesh is still closed, the same for any thread count, and the same
/// triangles as the dense field of the values the grid reads.
#[test]
fn absent_tiles_next_to_the_surface_are_meshed_like_the_dense_field() {
    use sparse_levelset::storage::tiles::TileGrid;
    let spec = GridSpec::default();
    let (c, r) = ([0.6, -0.3, 0.2], 17.3);
    let phi = |p: [f64; 3]| {
        ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt() - r
    };
    let full = tiles_from_shape(&Shape::Sphere { center: c, radius: r }, spec).unwrap();
    let coords = full.tile_coords();
    let stored = |t: Coord| coords.binary_search(&t).is_ok();
    let neighbours = |t: Coord| {
        (-1..=1).flat_map(move |z| {
            (-1..=1).flat_map(move |y| (-1..=1).map(move |x| Coord::new(t.x + x, t.y + y, t.z + z)))
        })
    };
    let crosses = |p: usize| {
        let v = &full.tile(p).0;
        v.iter().any(|&x| x < 0.0) && v.iter().any(|&x| x >= 0.0)
    };
    let centre = |t: Coord| [t.x, t.y, t.z].map(|v| 4.0 * v as f64 + 1.5);
    // (tile, inside) of the removed tiles.
    let removed: Vec<(Coord, bool)> = (0..coords.len())
        .filter(|&p| {
            let t = coords[p];
            t.x % 2 == 0 && t.y % 2 == 0 && t.z % 2 == 0 && crosses(p)
        })
        .filter_map(|p| {
            let t = coords[p];
            let around: Vec<bool> =
                neighbours(t).filter(|&n| !stored(n)).map(|n| full.tile_inside(n)).collect();
            match around.first() {
                None => Some((t, phi(centre(t)) < 0.0)),
                Some(&s) if around.iter().all(|&x| x == s) => Some((t, s)),
                _ => None,
            }
        })
        .collect();
    assert!(removed.len() > 10, "{} tiles removed", removed.len());
    let gone = |t: Coord| removed.binary_search_by(|e| e.0.cmp(&t)).ok().map(|i| removed[i].1);
    let grid = TileGrid::from_sorted_tiles(
        spec,
        (0..coords.len())
            .filter(|&p| gone(coords[p]).is_none())
            .map(|p| (coords[p], *full.tile(p))),
        |t| gone(t).unwrap_or_else(|| full.tile_inside(t)),
    )
    .unwrap();
    let meshes: Vec<TriangleMesh> = [1, 2, 3]
        .iter()
        .map(|&n| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
            pool.install(|| mesh_at(&grid, 0.0)).unwrap()
        })
        .collect();
    assert_eq!(meshes[0], meshes[1], "1 and 2 threads");
    assert_eq!(meshes[0], meshes[2], "1 and 3 threads");
    let m = &meshes[0];
    assert!(!check_as_written(m, "holes", 2), "f32 holds this mesh");
    // The dense field of the same values meshes every cell (all tiles stored).
    let (lo, hi) = grid.bounding_box().unwrap();
    let origin = Coord::new(lo.x - 4, lo.y - 4, lo.z - 4);
    let dims = [hi.x - lo.x + 9, hi.y - lo.y + 9, hi.z - lo.z + 9].map(|d| d as usize);
    let dense = DenseField::from_fn(origin, dims, |v| grid.value(v)).unwrap();
    let md = isosurface_dense(&dense, &spec, 0.0).unwrap();
    assert_eq!(canonical(m), canonical(&md));
    let normals = |m: &TriangleMesh| {
        let mut v: Vec<_> = m
            .positions
            .iter()
            .zip(&m.normals)
            .map(|(p, n)| (p.map(f64::to_bits), n.map(f32::to_bits)))
            .collect();
        v.sort_unstable();
        v
    };
    assert_eq!(normals(m), normals(&md));
    // The removed tiles changed the surface, and it still encloses about the ball.
    let mf = mesh_at(&full, 0.0).unwrap();
    assert_ne!(canonical(m), canonical(&mf));
    close("volume", m.enclosed_volume(), 4.0 / 3.0 * PI * r * r * r, 0.1);
}

/// The same mesh, bit for bit, on 1, 2, 3 and 4 threads, at full resolution and
/// coarsened.
#[test]
fn same_mesh_for_any_thread_count() {
    let torus = Shape::Torus { center: [0.4, 1.1, -0.3], major_radius: 30.0, minor_radius: 9.0 };
    let tiles = tiles_from_shape(&torus, GridSpec::default()).unwrap();
    for coarsen in [1, 3] {
        let opts = MeshOptions { coarsen, ..Default::default() };
        let meshes: Vec<TriangleMesh> = [1, 2, 3, 4]
            .iter()
            .map(|&n| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
                pool.install(|| isosurface(&tiles, &opts)).unwrap()
            })
            .collect();
        for (k, m) in meshes.iter().enumerate().skip(1) {
            assert!(*m == meshes[0], "coarsen {coarsen}: {} threads differ from 1", k + 1);
        }
        assert!(meshes[0].is_closed_manifold());
    }
}

/// `coarsen` = k meshes φ at every k-th voxel: about k² fewer triangles, still a closed
/// manifold with the same Euler characteristic, and area and volume close to the fine
/// mesh's (tolerances relative, measured: see `docs/mesh.md`).
#[test]
fn coarser_meshes_keep_the_surface() {
    let spec = GridSpec::default();
    let (r, big, small) = (60.0, 40.0, 14.0);
    let cases = [
        (
            "sphere",
            Shape::Sphere { center: [0.3, -0.2, 0.1], radius: r },
            2,
            (4.0 * PI * r * r, 4.0 / 3.0 * PI * r * r * r),
        ),
        (
            "torus",
            Shape::Torus { center: [1.5, -2.25, 0.7], major_radius: big, minor_radius: small },
            0,
            (4.0 * PI * PI * big * small, 2.0 * PI * PI * big * small * small),
        ),
    ];
    for (name, shape, chi, exact) in cases {
        let tiles = tiles_from_shape(&shape, spec).unwrap();
        let fine = mesh_at(&tiles, 0.0).unwrap();
        println!(
            "{name} full: {} triangles, area {:+.2e}, volume {:+.2e} relative to the exact shape",
            fine.num_triangles(),
            fine.area() / exact.0 - 1.0,
            fine.enclosed_volume() / exact.1 - 1.0
        );
        let one = isosurface(&tiles, &MeshOptions { coarsen: 1, ..Default::default() }).unwrap();
        assert_eq!(one, fine, "{name}: coarsen 1 is the full mesh");
        for k in [2u32, 3, 4] {
            let m = isosurface(&tiles, &MeshOptions { coarsen: k, ..Default::default() }).unwrap();
            let ratio = fine.num_triangles() as f64 / m.num_triangles() as f64 / (k * k) as f64;
            let (da, dv) =
                (m.area() / fine.area() - 1.0, m.enclosed_volume() / fine.enclosed_volume() - 1.0);
            let (ea, ev) = (m.area() / exact.0 - 1.0, m.enclosed_volume() / exact.1 - 1.0);
            println!(
                "{name} coarsen {k}: {} triangles (fine/k² ratio {ratio:.3}), area {da:+.2e}, \
                 volume {dv:+.2e} relative to the fine mesh ({ea:+.2e}, {ev:+.2e} to the \
                 exact shape)",
                m.num_triangles()
            );
            assert!((0.8..1.25).contains(&ratio), "{name} k = {k}: ratio {ratio}");
            assert!(!check_as_written(&m, &format!("{name}-k{k}"), chi), "{name} k = {k}: f64");
            let tol = 2e-3 * (k * k) as f64;
            assert!(da.abs() < tol && dv.abs() < tol, "{name} k = {k}: {da:e} {dv:e} > {tol:e}");
        }
    }
    let tiles = tiles_from_shape(&Shape::Sphere { center: [0.0; 3], radius: 5.0 }, spec).unwrap();
    let err = isosurface(&tiles, &MeshOptions { coarsen: 0, ..Default::default() }).unwrap_err();
    assert!(matches!(err, MeshError::InvalidParameter(_)), "{err}");
}

/// A signed distance to a sphere sampled on an `n`³ array at the origin (voxel = index).
fn ball(n: usize, center: [f64; 3], r: f64) -> DenseField {
    DenseField::from_fn(Coord::new(0, 0, 0), [n; 3], |c| {
        let d = [c.x as f64 - center[0], c.y as f64 - center[1], c.z as f64 - center[2]];
        ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - r) as f32
    })
    .unwrap()
}

/// Undirected edges used by one triangle only (the boundary of an open mesh).
fn boundary_edges(m: &TriangleMesh) -> Vec<(u32, u32)> {
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut out: Vec<_> = count.into_iter().filter(|&(_, c)| c == 1).map(|(e, _)| e).collect();
    out.sort_unstable();
    out
}

/// The default options give `isosurface_dense`'s mesh, and the values are the cells'
/// ranges: on the ramp φ = x − 3.5 every cell's corners span exactly 1 (2 with step 2).
#[test]
fn dense_options_default_to_isosurface_dense_and_values_are_cell_ranges() {
    let spec = GridSpec::default();
    let f = ball(24, [11.3, 12.1, 10.7], 7.2);
    let plain = isosurface_dense(&f, &spec, 0.0).unwrap();
    let s = isosurface_dense_with(&f, &spec, &DenseMeshOptions::default()).unwrap();
    assert_eq!(s.mesh, plain);
    assert_eq!(s.values.len(), plain.num_vertices());
    assert!(s.values.iter().all(|&v| v > 0.0 && v <= 3f32.sqrt() + 1e-5), "distance: ranges ≤ √3");
    let ramp = DenseField::from_fn(Coord::new(0, 0, 0), [9, 8, 7], |c| c.x as f32 - 3.5).unwrap();
    for step in [1u32, 2] {
        let opts = DenseMeshOptions { step, border: Border::Open, ..Default::default() };
        let s = isosurface_dense_with(&ramp, &spec, &opts).unwrap();
        assert!(!s.mesh.is_empty());
        assert!(s.values.iter().all(|&v| v == step as f32), "step {step}: {:?}", &s.values[..4]);
        // The plane x = 3.5 across the whole array: area 7 × 6 (the array's y, z extent
        // to the last full step), exact for a plane up to rounding.
        let extent = [7.0, 6.0].map(|e: f64| (e / step as f64).floor() * step as f64);
        close(&format!("ramp plane, step {step}"), s.mesh.area(), extent[0] * extent[1], 1e-6);
    }
    // An open border extrapolates the array linearly, so on a tilted plane (a linear
    // field) every normal is the plane's, also at the border (within f32 rounding).
    let tilted = DenseField::from_fn(Coord::new(2, -1, 0), [8, 9, 6], |c| {
        c.x as f32 + 0.5 * c.y as f32 - 0.25 * c.z as f32 - 4.3
    })
    .unwrap();
    let opts = DenseMeshOptions { border: Border::Open, ..Default::default() };
    let s = isosurface_dense_with(&tilted, &spec, &opts).unwrap();
    let len = (1.0f64 + 0.25 + 0.0625).sqrt();
    let exact = [1.0 / len, 0.5 / len, -0.25 / len];
    let worst = s
        .mesh
        .normals
        .iter()
        .fold(0f64, |w, n| (0..3).fold(w, |w, a| w.max((n[a] as f64 - exact[a]).abs())));
    println!("tilted plane: {} vertices, largest normal error {worst:.1e}", s.mesh.num_vertices());
    assert!(worst < 1e-6, "{worst}");
    // level = None: the middle of the finite values (−3.5 and 4.5: 0.5), the plane x = 4
    // through voxels (moved off them by less than 10⁻³ voxel, see the module docs).
    let opts = DenseMeshOptions { iso: None, border: Border::Open, ..Default::default() };
    let s = isosurface_dense_with(&ramp, &spec, &opts).unwrap();
    assert_eq!(s.iso, 0.5);
    assert!(s.mesh.positions.iter().all(|p| (p[0] - 4.0).abs() < 1e-3), "plane at x = 4");
}

/// An open border: a ball cut by the array's faces x = 0 and y = n − 1 gives a mesh
/// whose boundary edges all lie on those faces, no vertex outside the array, and exactly
/// the triangles of the closed mesh that lie in cells inside the array (same positions,
/// bit for bit). The closed mesh is a closed manifold.
#[test]
fn open_border_ends_the_surface_on_the_array_faces() {
    let spec = GridSpec::default();
    let n = 20;
    let f = ball(n, [2.4, 16.8, 9.6], 7.3);
    let closed = isosurface_dense(&f, &spec, 0.0).unwrap();
    assert!(closed.is_closed_manifold());
    let opts = DenseMeshOptions { border: Border::Open, ..Default::default() };
    let open = isosurface_dense_with(&f, &spec, &opts).unwrap().mesh;
    let top = (n - 1) as f64;
    assert!(open.positions.iter().all(|p| p.iter().all(|&c| (0.0..=top).contains(&c))));
    let edges = boundary_edges(&open);
    println!(
        "open: {} triangles, {} boundary edges; closed: {} triangles",
        open.num_triangles(),
        edges.len(),
        closed.num_triangles()
    );
    assert!(edges.len() > 50, "{}", edges.len());
    for &(a, b) in &edges {
        let (p, q) = (open.positions[a as usize], open.positions[b as usize]);
        let on = |c: usize, v: f64| p[c] == v && q[c] == v;
        assert!(on(0, 0.0) || on(1, top), "boundary edge {p:?} {q:?} off the cut faces");
    }
    // No other boundary: the faces the ball does not reach carry none.
    let closed_set = canonical(&closed);
    let open_set = canonical(&open);
    assert!(open_set.iter().all(|t| closed_set.binary_search(t).is_ok()), "open ⊄ closed");
    // Closed minus open: the triangles in the cells that reach beyond the array (the
    // caps), all with a vertex outside [0, n − 1]³.
    let caps = closed_set.len() - open_set.len();
    let outside = closed
        .triangles
        .iter()
        .filter(|t| {
            t.iter()
                .any(|&v| closed.positions[v as usize].iter().any(|&c| !(0.0..=top).contains(&c)))
        })
        .count();
    assert_eq!(caps, outside);
    // Orientation is kept: every interior edge is used once each way.
    let mut directed: Vec<(u32, u32)> =
        open.triangles.iter().flat_map(|t| (0..3).map(move |k| (t[k], t[(k + 1) % 3]))).collect();
    directed.sort_unstable();
    assert!(directed.windows(2).all(|w| w[0] != w[1]), "an edge used twice the same way");
}

/// A mask meshes the cells whose upper corner it holds (scikit-image's rule): the
/// meshes of a mask and of its complement split the full mesh's triangles between them,
/// and the mask x ≥ 12 ends the surface on the plane x = 11.
#[test]
fn mask_meshes_the_cells_whose_upper_corner_it_holds() {
    let spec = GridSpec::default();
    let n = 24;
    let f = ball(n, [11.3, 12.1, 10.7], 7.2);
    let full = isosurface_dense(&f, &spec, 0.0).unwrap();
    let mask: Vec<bool> = (0..n * n * n).map(|i| i % n >= 12).collect();
    let rest: Vec<bool> = mask.iter().map(|m| !m).collect();
    let mesh = |m: &[bool]| {
        let opts = DenseMeshOptions { mask: Some(m), ..Default::default() };
        isosurface_dense_with(&f, &spec, &opts).unwrap().mesh
    };
    let (a, b) = (mesh(&mask), mesh(&rest));
    println!(
        "mask x ≥ 12: {} triangles, complement {}, full {}",
        a.num_triangles(),
        b.num_triangles(),
        full.num_triangles()
    );
    let mut both = canonical(&a);
    both.extend(canonical(&b));
    both.sort_unstable();
    assert_eq!(both, canonical(&full), "mask and complement partition the triangles");
    assert!(a.positions.iter().all(|p| p[0] >= 11.0));
    assert!(b.positions.iter().all(|p| p[0] <= 11.0));
    let edges = boundary_edges(&a);
    assert!(!edges.is_empty());
    for &(u, v) in &edges {
        let (p, q) = (a.positions[u as usize], a.positions[v as usize]);
        assert!(p[0] == 11.0 && q[0] == 11.0, "boundary edge {p:?} {q:?} off x = 11");
    }
    let bad = DenseMeshOptions { mask: Some(&mask[1..]), ..Default::default() };
    assert!(matches!(isosurface_dense_with(&f, &spec, &bad), Err(MeshError::InvalidParameter(_))));
}

/// `step` = k meshes the lattice of every k-th voxel: the mesh of the sampled array with
/// voxel size k, bit for bit; about k² fewer triangles and the sphere's area within 2 %.
#[test]
fn step_meshes_every_kth_voxel() {
    let spec = GridSpec::default();
    let (n, c, r) = (41, [20.3, 19.6, 20.9], 14.2);
    let f = ball(n, c, r);
    let fine = isosurface_dense(&f, &spec, 0.0).unwrap();
    for k in [2usize, 3] {
        let opts = DenseMeshOptions { step: k as u32, ..Default::default() };
        let s = isosurface_dense_with(&f, &spec, &opts).unwrap();
        let m = (n - 1) / k + 1;
        let sampled = DenseField::from_fn(Coord::new(0, 0, 0), [m; 3], |v| {
            f.get(Coord::new(k as i32 * v.x, k as i32 * v.y, k as i32 * v.z)).unwrap()
        })
        .unwrap();
        let coarse_spec = GridSpec { voxel_size: k as f32, ..spec };
        assert_eq!(s.mesh, isosurface_dense(&sampled, &coarse_spec, 0.0).unwrap(), "step {k}");
        let ratio = fine.num_triangles() as f64 / s.mesh.num_triangles() as f64 / (k * k) as f64;
        println!("step {k}: {} triangles, fine/k² ratio {ratio:.3}", s.mesh.num_triangles());
        assert!((0.7..1.4).contains(&ratio), "{ratio}");
        close(&format!("area, step {k}"), s.mesh.area(), 4.0 * PI * r * r, 0.02);
        assert!(s.mesh.is_closed_manifold());
    }
    let bad = DenseMeshOptions { step: 0, ..Default::default() };
    assert!(matches!(isosurface_dense_with(&f, &spec, &bad), Err(MeshError::InvalidParameter(_))));
}

/// `Inside::Above` is the mesh of the negated array at the negated iso value (normals
/// along −∇φ, triangles reversed), and every option gives the same bits on 1 to 3
/// threads; dropping zero-area triangles changes nothing on exact zeros.
#[test]
fn inside_above_threads_and_degenerate_triangles() {
    let spec = GridSpec::default();
    let n = 22;
    // A bright blob with exact iso values on voxels (integer values, level 4).
    let f = DenseField::from_fn(Coord::new(-3, 2, 0), [n; 3], |c| {
        let d = [c.x as f64 - 7.0, c.y as f64 - 12.0, c.z as f64 - 10.0];
        (12.0 - (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()).round() as f32
    })
    .unwrap();
    let neg = DenseField::from_fn(f.origin(), f.dims(), |c| -f.get(c).unwrap()).unwrap();
    let opts = DenseMeshOptions { iso: Some(4.0), inside: Inside::Above, ..Default::default() };
    let s = isosurface_dense_with(&f, &spec, &opts).unwrap();
    assert_eq!(s.mesh, isosurface_dense(&neg, &spec, -4.0).unwrap());
    assert!(s.mesh.is_closed_manifold() && s.mesh.enclosed_volume() > 0.0);
    assert_eq!(s.mesh.degenerate_triangles(), 0);
    let kept = DenseMeshOptions { drop_degenerate: true, ..opts.clone() };
    assert_eq!(isosurface_dense_with(&f, &spec, &kept).unwrap(), s);
    let mask: Vec<bool> = (0..n * n * n).map(|i| (i / n) % n < 15).collect();
    let all = DenseMeshOptions { step: 2, mask: Some(&mask), border: Border::Open, ..opts.clone() };
    let runs: Vec<_> = [1, 2, 3]
        .iter()
        .map(|&t| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap();
            pool.install(|| isosurface_dense_with(&f, &spec, &all)).unwrap()
        })
        .collect();
    assert!(!runs[0].mesh.is_empty());
    assert!(runs.iter().all(|r| *r == runs[0]), "thread counts differ");
}

/// The per-vertex values are scikit-image's: for every vertex the largest, over the
/// triangles that use it, of the value range (in f64, rounded to f32) of the eight corners
/// of the triangle's cell, the cell found from the triangle's centroid and read from the
/// array here (beyond a closed border: the outside value `iso ± γ` of the side meshed as
/// outside, γ that of the lattice of `step`). On a busy field (several crossings per
/// cell, values that are not distances), for every combination of border, mask, side and
/// step; vertices with a triangle whose centroid lies on a cell face (its cell ambiguous)
/// are not compared.
#[test]
fn values_are_the_largest_cell_range_of_the_triangles_on_each_vertex() {
    let spec = GridSpec::default();
    let dims = [19usize, 17, 15];
    let f = DenseField::from_fn(Coord::new(-4, 3, 1), dims, |c| {
        let (x, y, z) = (c.x as f64, c.y as f64, c.z as f64);
        (40.0 * (0.61 * x).sin() * (0.47 * y + 0.3).cos() + 13.0 * (0.83 * z).sin() + 3.0 * x)
            as f32
    })
    .unwrap();
    let o = f.origin();
    let mask: Vec<bool> = (0..f.data().len()).map(|i| (i * 7919) % 11 < 8).collect();
    let mut compared = 0;
    for (border, use_mask, inside, step) in [
        (Border::Closed, false, Inside::Below, 1u32),
        (Border::Open, false, Inside::Above, 1),
        (Border::Closed, true, Inside::Above, 1),
        (Border::Open, true, Inside::Below, 2),
        (Border::Closed, false, Inside::Above, 3),
    ] {
        let iso = 7.25;
        let opts = DenseMeshOptions {
            iso: Some(iso),
            inside,
            step,
            mask: use_mask.then_some(&mask[..]),
            border,
            ..Default::default()
        };
        let s = isosurface_dense_with(&f, &spec, &opts).unwrap();
        assert!(s.mesh.num_triangles() > 100, "{border:?} {step}");
        // In the frame the surface is computed in (negated for `Above`).
        let sign = if inside == Inside::Above { -1.0 } else { 1.0 };
        // γ of the sampled lattice, whose voxels are `step` wide.
        let outside = (sign * iso + step as f64 * spec.gamma() as f64) as f32;
        let k = step as i64;
        let read = |c: [i64; 3]| {
            let p = Coord::new(
                (o.x as i64 + k * c[0]) as i32,
                (o.y as i64 + k * c[1]) as i32,
                (o.z as i64 + k * c[2]) as i32,
            );
            f.get(p).map_or(outside, |v| sign as f32 * v)
        };
        let mut expected = vec![f32::NEG_INFINITY; s.mesh.num_vertices()];
        let mut ambiguous = vec![false; s.mesh.num_vertices()];
        for t in &s.mesh.triangles {
            let p = t.map(|v| s.mesh.positions[v as usize]);
            // Lattice coordinates of the centroid, relative to the array's first voxel.
            let at = |a: usize, c: i32| ((p[0][a] + p[1][a] + p[2][a]) / 3.0 - c as f64) / k as f64;
            let g = [at(0, o.x), at(1, o.y), at(2, o.z)];
            if g.iter().any(|g| (g - g.round()).abs() < 1e-6) {
                t.iter().for_each(|&v| ambiguous[v as usize] = true);
                continue;
            }
            let lo = g.map(|g| g.floor() as i64);
            let (mut l, mut h) = (f32::INFINITY, f32::NEG_INFINITY);
            for c in 0..8 {
                let v = read([lo[0] + (c & 1), lo[1] + ((c >> 1) & 1), lo[2] + (c >> 2)]);
                (l, h) = (l.min(v), h.max(v));
            }
            let range = (h as f64 - l as f64) as f32;
            for &v in t {
                expected[v as usize] = expected[v as usize].max(range);
            }
        }
        let mut n = 0;
        for (i, (&e, &got)) in expected.iter().zip(&s.values).enumerate() {
            if !ambiguous[i] {
                assert_eq!(
                    got, e,
                    "vertex {i} ({border:?}, mask {use_mask}, {inside:?}, step {step})"
                );
                n += 1;
            }
        }
        println!(
            "{border:?}, mask {use_mask}, {inside:?}, step {step}: {n} of {} vertices compared",
            expected.len()
        );
        assert!(n * 10 >= 9 * expected.len(), "too few vertices compared: {n}");
        compared += n;
    }
    assert!(compared > 1000);
}
