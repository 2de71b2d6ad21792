//! `levelset voxelize`: a mesh file to a dense `.npy` signed distance field, and its
//! refusals (bad meshes, unwritable outputs, nonsense flags).

#[allow(unused_imports)] // the shared helpers re-export more than these tests use
use crate::common;

use crate::common::{levelset, stderr, stdout, tmp};
use std::path::PathBuf;

/// An axis-aligned box 0..4 × 0..3 × 0..2 as an OBJ file (12 triangles, outward).
fn box_obj(name: &str) -> PathBuf {
    let mut s = String::new();
    for i in 0..8 {
        let (x, y, z) = (4 * (i & 1), 3 * (i >> 1 & 1), 2 * (i >> 2));
        s += &format!("v {x} {y} {z}\n");
    }
    for f in [
        [1, 3, 4, 2], // z = 0, as quads
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        s += &format!("f {} {} {} {}\n", f[0], f[1], f[2], f[3]);
    }
    let path = tmp(name);
    std::fs::write(&path, s).unwrap();
    path
}

#[test]
fn voxelize_writes_the_signed_distance_of_a_mesh() {
    let mesh = box_obj("box.obj");
    let out = tmp("box.npy");
    let o = levelset(&[
        "voxelize",
        mesh.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--voxel-size",
        "0.5",
        "--threads",
        "2",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("12 triangles") && text.contains("voxel size 0.5 (given)"), "{text}");
    assert!(text.contains("band voxels") && text.contains(" s on 2 threads"), "{text}");
    // The box spans voxels 0..=8 × 0..=6 × 0..=4; the band (|φ| < γ = 1.5, 3 voxels)
    // starts at voxel -2, and the array one voxel before it.
    assert!(text.contains("element [0, 0, 0] is voxel (-3, -3, -3)"), "{text}");
    let field = sparse_levelset::io::npy::read_npy(&out).unwrap();
    let data = field.data();
    let g = 1.5f32;
    // The box is 2 units thick: no voxel is deeper than 1 (< γ).
    assert_eq!(data.iter().cloned().fold(f32::INFINITY, f32::min), -1.0, "the deepest");
    assert_eq!(data.iter().cloned().fold(f32::NEG_INFINITY, f32::max), g, "far outside: +γ");
    // The centre of the box (2, 1.5, 1) world = voxel (4, 3, 2) is 1 world unit inside
    // (the nearest faces are z = 0 and z = 2).
    let [nx, ny, nz] = field.dims();
    assert_eq!([nx, ny, nz], [15, 13, 11]);
    let at = |x: i64, y: i64, z: i64| {
        let (x, y, z) = ((x + 3) as usize, (y + 3) as usize, (z + 3) as usize);
        data[x + nx * (y + ny * z)]
    };
    assert_eq!(at(4, 3, 2), -1.0);
    assert_eq!(at(4, 3, -1), 0.5, "half a unit below the base");
    assert_eq!(at(0, 0, 0), 0.0, "a corner");

    // Without a voxel size, one is chosen from the mesh (64 voxels along the longest side).
    let o = levelset(&["voxelize", mesh.to_str().unwrap(), "-o", out.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("voxel size 0.0625 (chosen from the mesh)"), "{}", stdout(&o));
}

#[test]
fn voxelize_refuses_bad_meshes_and_outputs_before_the_work() {
    let out = tmp("refused.npy");
    let o_s = out.to_str().unwrap();
    let nan = tmp("nan.obj");
    std::fs::write(&nan, "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n").unwrap();
    let empty = tmp("empty.stl");
    std::fs::write(&empty, [0u8; 84]).unwrap();
    let huge = tmp("huge.ply");
    std::fs::write(
        &huge,
        "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n\
         property float x\nproperty float y\nproperty float z\nelement face 0\n\
         property list uchar int vertex_indices\nend_header\n",
    )
    .unwrap();
    let off = tmp("mesh.off");
    std::fs::write(&off, "OFF\n").unwrap();
    let good = box_obj("good.obj");
    let vtk = tmp("out.vtk");
    let cases: [(Vec<&str>, &str); 7] = [
        (vec![nan.to_str().unwrap(), "-o", o_s], "not finite"),
        (vec![empty.to_str().unwrap(), "-o", o_s], "no triangles"),
        (vec![huge.to_str().unwrap(), "-o", o_s], "claims 1000000000000"),
        (vec![off.to_str().unwrap(), "-o", o_s], "unknown mesh format"),
        (vec!["/no/such/mesh.obj", "-o", o_s], "/no/such/mesh.obj"),
        (vec![good.to_str().unwrap(), "-o", "/no/such/dir/out.npy"], "cannot write the output"),
        (vec![good.to_str().unwrap(), "-o", vtk.to_str().unwrap()], "unknown output format"),
    ];
    for (args, needle) in cases {
        let mut all = vec!["voxelize"];
        all.extend(&args);
        all.push("--quiet");
        let o = levelset(&all);
        assert!(!o.status.success(), "{args:?} succeeded");
        let err = stderr(&o);
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(!out.exists(), "nothing written");
    // Coordinates whose voxels leave the i32 range at the chosen voxel size.
    let far = tmp("far.obj");
    std::fs::write(&far, "v 0 0 0\nv 1e10 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let o =
        levelset(&["voxelize", far.to_str().unwrap(), "-o", o_s, "--voxel-size", "1", "--quiet"]);
    assert!(!o.status.success() && stderr(&o).contains("i32"), "{}", stderr(&o));
}

#[test]
fn voxelize_refuses_nonsense_flags() {
    let good = box_obj("flags.obj");
    let g = good.to_str().unwrap();
    let out = tmp("flags.npy");
    let o_s = out.to_str().unwrap();
    for (args, needle) in [
        (vec![g, "-o", o_s, "--sign", "parity"], "--sign"),
        (vec![g, "-o", o_s, "--threads", "0"], "--threads"),
        (vec![g, "-o", o_s, "--voxel-size", "-1"], "voxel size"),
        (vec![g, "-o", o_s, "--half-width", "1"], "half-width"),
        (vec![g, "-o", o_s, "--frobnicate"], "--frobnicate"),
        (vec![g], "--output"),
    ] {
        let mut all = vec!["voxelize"];
        all.extend(&args);
        let o = levelset(&all);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(stderr(&o).contains(needle), "{args:?}: {}", stderr(&o));
    }
    assert!(!out.exists());
}
