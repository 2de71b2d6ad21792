//! The `levelset` command and the speed-up report as a user meets them: every subcommand
//! on shapes and `.npy` fields, JSON output, and clear errors with a non-zero exit on bad
//! input — before any work, never a panic or an abort, nothing written.

use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::tools::mesh::isosurface_dense;
use sparse_levelset::Coord;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common;

use crate::common::{levelset, speedup, stderr, stdout, tmp, write_npy};

fn json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "failed: {}", stderr(o));
    serde_json::from_slice(&o.stdout).expect("valid JSON")
}

/// A sphere's signed distance sampled on an n³ array, radius r, centred.
fn sphere_f32(n: usize, r: f32) -> Vec<u8> {
    let c = (n as f32 - 1.0) / 2.0;
    let mut out = Vec::with_capacity(n * n * n * 4);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let d = ((x as f32 - c).powi(2) + (y as f32 - c).powi(2) + (z as f32 - c).powi(2))
                    .sqrt()
                    - r;
                out.extend_from_slice(&d.to_le_bytes());
            }
        }
    }
    out
}

/// `got` within `rel` (relative) of `exact`.
fn close(what: &str, got: f64, exact: f64, rel: f64) {
    let err = (got - exact).abs() / exact.abs();
    assert!((got - exact).abs() <= 1e-9 + rel * exact.abs(), "{what}: error {err:.3e} > {rel}");
}

fn grid<'a>(v: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    v["grids"].as_array().unwrap().iter().find(|g| g["grid"] == name).unwrap()
}

#[test]
fn info_sphere_json_has_both_grids_and_every_part() {
    let v = json(&levelset(&["info", "--shape", "sphere", "--radius", "40", "--json"]));
    for name in ["dtgrid", "tiles"] {
        let g = grid(&v, name);
        let b = &g["bytes"];
        let parts: u64 =
            ["values", "indices", "flags", "slack"].iter().map(|k| b[k].as_u64().unwrap()).sum();
        assert_eq!(parts, b["total"].as_u64().unwrap());
        assert!(g["band_voxels"].as_u64().unwrap() > 0);
        assert!(g["stored_voxels"].as_u64().unwrap() >= g["band_voxels"].as_u64().unwrap());
    }
    let dt = grid(&v, "dtgrid");
    let tiles = grid(&v, "tiles");
    // Both grids hold the same band.
    assert_eq!(dt["band_voxels"], tiles["band_voxels"]);
    assert_eq!(dt["band_voxels"], dt["stored_voxels"]);
    assert_eq!(tiles["stored_voxels"].as_u64().unwrap(), 64 * tiles["tiles"].as_u64().unwrap());
    // A sphere of radius 40 and γ = 3: about 4πr²·2γ band voxels.
    let band = dt["band_voxels"].as_f64().unwrap();
    let est = 4.0 * std::f64::consts::PI * 40.0 * 40.0 * 6.0;
    assert!((band / est - 1.0).abs() < 0.05, "band {band} vs {est}");
}

#[test]
fn info_every_shape_builds() {
    for shape in ["sphere", "torus", "box", "ellipsoid", "spiral"] {
        let v = json(&levelset(&["info", "--shape", shape, "--radius", "30", "--json"]));
        assert!(grid(&v, "tiles")["band_voxels"].as_u64().unwrap() > 1000, "{shape}");
        assert_eq!(grid(&v, "tiles")["band_voxels"], grid(&v, "dtgrid")["band_voxels"], "{shape}");
    }
    let text =
        levelset(&["info", "--shape", "torus", "--major-radius", "30", "--minor-radius", "8"]);
    assert!(text.status.success());
    let s = String::from_utf8_lossy(&text.stdout);
    assert!(s.contains("dtgrid") && s.contains("tiles") && s.contains("total / values"));
}

#[test]
fn info_npy_matches_the_same_shape() {
    let p = tmp("sphere.npy");
    write_npy(&p, "<f4", &[40, 40, 40], &sphere_f32(40, 12.0));
    let v = json(&levelset(&["info", p.to_str().unwrap(), "--voxel-size", "1", "--json"]));
    let band = grid(&v, "dtgrid")["band_voxels"].as_f64().unwrap();
    let est = 4.0 * std::f64::consts::PI * 12.0 * 12.0 * 6.0;
    assert!((band / est - 1.0).abs() < 0.1, "band {band} vs {est}");
    assert_eq!(grid(&v, "tiles")["band_voxels"], grid(&v, "dtgrid")["band_voxels"]);
    assert!(v["warnings"].as_array().unwrap().is_empty(), "{v}");
}

#[test]
fn bad_npy_files_give_clear_errors() {
    let good = sphere_f32(8, 2.0);
    type MakeFile<'a> = Box<dyn Fn(&Path) + 'a>;
    let cases: Vec<(&str, MakeFile, &str)> = vec![
        (
            "f64.npy",
            Box::new(|p: &Path| write_npy(p, "<f8", &[8, 8, 8], &[0u8; 8 * 512])),
            "float32",
        ),
        (
            "short.npy",
            Box::new(|p: &Path| write_npy(p, "<f4", &[8, 8, 8], &good[..1000])),
            "truncat",
        ),
        (
            "nan.npy",
            Box::new(|p: &Path| {
                let mut d = good.clone();
                d[4 * 77..4 * 78].copy_from_slice(&f32::NAN.to_le_bytes());
                write_npy(p, "<f4", &[8, 8, 8], &d)
            }),
            "NaN",
        ),
        ("flat.npy", Box::new(|p: &Path| write_npy(p, "<f4", &[64], &good[..256])), "3"),
        ("garbage.npy", Box::new(|p: &Path| std::fs::write(p, b"hello world").unwrap()), "npy"),
        (
            "huge.npy",
            Box::new(|p: &Path| write_npy(p, "<f4", &[1 << 20, 1 << 20, 1 << 20], &good)),
            "",
        ),
    ];
    for (name, make, needle) in cases {
        let p = tmp(name);
        make(&p);
        let o = levelset(&["info", p.to_str().unwrap()]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{name} was accepted");
        assert_eq!(o.status.code(), Some(1), "{name}: {e}");
        assert!(e.starts_with("error:"), "{name}: {e}");
        assert!(e.contains(needle), "{name}: expected '{needle}' in: {e}");
        assert!(!e.contains("panicked"), "{name}: {e}");
    }
    let o = levelset(&["info", tmp("missing.npy").to_str().unwrap()]);
    assert!(!o.status.success() && stderr(&o).contains("missing.npy"));
}

#[test]
fn nonsense_arguments_are_refused() {
    let cases: &[&[&str]] = &[
        &["info", "--shape", "sphere", "--radius", "-3"],
        &["info", "--shape", "sphere", "--radius", "nan"],
        &["info", "--shape", "sphere", "--half-width", "0"],
        &["info", "--shape", "sphere", "--half-width", "1"],
        &["info", "--shape", "sphere", "--voxel-size", "0"],
        &["info", "--shape", "torus", "--major-radius", "5", "--minor-radius", "9"],
        &["info", "--shape", "sphere", "--radius", "1e12"],
        &["info", "--shape", "sphere", "--center", "3e9,0,0", "--radius", "10"],
        &["info", "--shape", "blob"],
        &["info", "--shape", "ellipsoid", "--radii", "1,2"],
        &["frobnicate"],
    ];
    for args in cases {
        let o = levelset(args);
        let e = stderr(&o);
        assert!(!o.status.success(), "{args:?} was accepted");
        assert!(!e.contains("panicked"), "{args:?}: {e}");
        assert!(e.contains("error"), "{args:?}: {e}");
    }
}

#[test]
fn bench_quick_reports_both_grids_and_the_kernels() {
    let k = tmp("kernels.json");
    let o = speedup(&["--kernels", "--quick", "--json", k.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&k).unwrap()).unwrap();
    let rows = v["kernels"].as_array().unwrap();
    assert_eq!(rows.len(), 8);
    for r in rows {
        assert!(["upwind_curvature", "weno5_rk3"].contains(&r["kernel"].as_str().unwrap()));
        assert!(["f32", "f32x4", "f32x8", "f32x16"].contains(&r["lanes"].as_str().unwrap()));
        assert!(r["voxel_updates_per_s"].as_f64().unwrap() > 0.0);
    }
    assert!(v["target_features"].is_array());

    let s = tmp("bench.json");
    let o = speedup(&["--storage", "--quick", "--json", s.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&s).unwrap()).unwrap();
    let scenarios = v["scenarios"].as_array().unwrap();
    assert_eq!(scenarios.len(), 2);
    for sc in scenarios {
        for op in sc["ops"].as_array().unwrap() {
            assert!(op["speedup_vs_dtgrid"].as_f64().unwrap() > 0.0);
            // Identical arithmetic on both grids gives identical band values.
            if let Some(d) = op["max_abs_diff"].as_f64() {
                assert_eq!(d, 0.0, "{}", op["op"]);
            }
        }
    }
    assert_eq!(v["kernels"].as_array().unwrap().len(), 8);
    let o = speedup(&["--reps", "0"]);
    assert!(!o.status.success());
}

#[test]
fn bench_reports_the_speedup_over_dtgrid() {
    let s = tmp("speedup.json");
    let o = speedup(&["--quick", "--threads", "2", "--json", s.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("CPU:") && text.contains("target features") && text.contains("build"));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&s).unwrap()).unwrap();
    for key in ["cpu", "target_features", "profile"] {
        assert!(!v[key].is_null(), "{key}");
    }
    let scenarios = v["scenarios"].as_array().unwrap();
    let names: Vec<&str> = scenarios.iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["sphere", "spiral", "enright"]);
    for sc in scenarios {
        assert!(sc["kernel_voxel_updates_per_s"].as_f64().unwrap() > 0.0);
        // Every representation computes the same band.
        assert_eq!(sc["max_abs_diff"].as_f64().unwrap(), 0.0, "{}", sc["name"]);
        let runs = sc["runs"].as_array().unwrap();
        let kinds: Vec<(String, String, u64)> = runs
            .iter()
            .map(|r| {
                (
                    r["grid"].as_str().unwrap().into(),
                    r["lanes"].as_str().unwrap().into(),
                    r["threads"].as_u64().unwrap(),
                )
            })
            .collect();
        assert_eq!(
            kinds,
            [
                ("dtgrid".into(), "scalar".into(), 1),
                ("tiles".into(), "scalar".into(), 1),
                ("tiles".into(), "simd".into(), 1),
                ("tiles".into(), "simd".into(), 2)
            ]
        );
        let sum = &runs[0]["checksum"];
        for r in runs {
            assert_eq!(&r["checksum"], sum, "{}: checksums differ", sc["name"]);
            for key in ["seconds", "voxel_updates_per_s", "bytes", "speedup_vs_dtgrid"] {
                assert!(r[key].as_f64().unwrap() > 0.0, "{key}");
            }
        }
    }
}

fn read_summary(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("summary.json")).expect("summary.json written"))
        .expect("valid JSON")
}

/// `levelset run ARGS --quiet --out TMP/OUT`, which must succeed: its output and the
/// directory holding `summary.json`.
fn run_ok(args: &[&str], out: &str) -> (Output, PathBuf) {
    let dir = tmp(out);
    let mut all = vec!["run"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--quiet", "--out", dir.to_str().unwrap()]);
    let o = levelset(&all);
    assert!(o.status.success(), "{all:?}: {}", stderr(&o));
    (o, dir)
}

#[test]
fn run_writes_the_summary_the_issue_asks_for() {
    let (_, dir) = run_ok(
        &[
            "sphere",
            "--size",
            "40",
            "--steps",
            "12",
            "--record-every",
            "5",
            "--threads",
            "2",
            "--export-npy",
        ],
        "run-sphere",
    );
    let s = read_summary(&dir);
    let p = &s["params"];
    for key in [
        "radius",
        "epsilon",
        "speed",
        "half_width",
        "voxel_size",
        "scheme",
        "integrator",
        "grid",
        "lanes",
        "threads",
        "renormalization",
        "size",
        "cfl",
    ] {
        assert!(!p[key].is_null(), "params.{key} missing: {p}");
    }
    assert_eq!(p["scheme"], "upwind1");
    assert_eq!(p["grid"], "tiles");
    assert_eq!(p["threads"], 2);
    let records = s["records"].as_array().unwrap();
    // Step 0, every 5th step and the last.
    let steps: Vec<u64> = records.iter().map(|r| r["step"].as_u64().unwrap()).collect();
    assert_eq!(steps, [0, 5, 10, 12]);
    for r in records {
        for key in
            ["step", "time", "dt", "band_voxels", "tiles", "volume", "area", "bytes", "seconds"]
        {
            assert!(r[key].is_number(), "record.{key} missing: {r}");
        }
    }
    assert_eq!(s["steps_taken"], 12);
    assert_eq!(s["collapsed"], false);
    assert_eq!(s["checksum"].as_str().unwrap().len(), 16);
    // The exported field reads back and holds the shrunken sphere.
    let f = sparse_levelset::io::npy::read_npy(&dir.join("final.npy")).unwrap();
    assert!(f.data().iter().any(|&v| v < 0.0) && f.data().iter().any(|&v| v > 0.0));

    // The same run on the DT-Grid and on one thread ends with the same checksum.
    let (_, dir2) =
        run_ok(&["sphere", "--size", "40", "--steps", "12", "--grid", "dtgrid"], "run-sphere-dt");
    assert_eq!(read_summary(&dir2)["checksum"], s["checksum"]);
}

/// `levelset run SCENARIO --init FIELD --out TMP/OUT`.
fn run_from(field: &Path, scenario: &str, out: &str) -> Output {
    levelset(&[
        "run",
        scenario,
        "--init",
        field.to_str().unwrap(),
        "--out",
        tmp(out).to_str().unwrap(),
    ])
}

#[test]
fn run_ends_cleanly_on_collapse_and_bad_input() {
    // A small sphere under strong curvature flow collapses: a message, exit 0.
    let (o, dir) =
        run_ok(&["sphere", "--size", "32", "--radius", "4", "--steps", "100000"], "run-collapse");
    assert!(String::from_utf8_lossy(&o.stdout).contains("collapsed"));
    assert_eq!(read_summary(&dir)["collapsed"], true);

    // An --init field holding +inf far from the sphere: one rule everywhere, ±inf is a
    // far-away distance (clamped to ±γ), so the run starts and ends cleanly. (This case
    // used to be refused as "not finite" by `run` alone while `info`, `mesh` and `render`
    // accepted the same file.)
    let path = tmp("inf.npy");
    let mut data = sphere_f32(12, 3.0);
    data[4 * 100..4 * 101].copy_from_slice(&f32::INFINITY.to_le_bytes());
    write_npy(&path, "<f4", &[12, 12, 12], &data);
    let o = run_from(&path, "sphere", "o1");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));

    // An --init field without an interface: error, exit 1.
    let path = tmp("outside.npy");
    let data: Vec<u8> = (0..8 * 8 * 8).flat_map(|_| 5.0f32.to_le_bytes()).collect();
    write_npy(&path, "<f4", &[8, 8, 8], &data);
    let o = run_from(&path, "morph", "o2");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("empty"), "{}", stderr(&o));

    // Nonsense arguments.
    for args in [
        &["run", "sphere", "--cfl", "3"][..],
        &["run", "sphere", "--epsilon=-1"],
        &["run", "enright", "--period", "0"],
        &["run", "sphere", "--size", "0"],
        &["run", "sphere", "--threads", "0"],
        &["run", "sphere", "--half-width", "0.5"],
        &["run", "sphere", "--grid", "dense", "--size", "64", "--radius", "2000"],
        &["run", "sphere", "--half-width", "1000000"],
        &["run", "enright", "--size", "65536"],
    ] {
        let o = levelset(args);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn run_starts_from_an_npy_field() {
    let path = tmp("init.npy");
    write_npy(&path, "<f4", &[24, 24, 24], &sphere_f32(24, 6.0));
    let (_, dir) =
        run_ok(&["expand", "--init", path.to_str().unwrap(), "--steps", "5"], "run-init");
    let s = read_summary(&dir);
    assert_eq!(s["params"]["init"], path.to_str().unwrap());
    assert!(s["volume_ratio"].as_f64().unwrap() > 1.0, "the sphere grows");
}

#[test]
fn run_reinitialises_by_fast_marching_on_both_grids() {
    let args = ["sphere", "--size", "48", "--steps", "9", "--reinit", "fmm2", "--every", "3"];
    let (_, tiles) = run_ok(&args, "run-reinit-tiles");
    let mut dt_args = args.to_vec();
    dt_args.extend_from_slice(&["--grid", "dtgrid"]);
    let (_, dt) = run_ok(&dt_args, "run-reinit-dtgrid");
    let (a, b) = (read_summary(&tiles), read_summary(&dt));
    assert_eq!(a["params"]["reinit"], "fmm2 every 3");
    assert_eq!(a["checksum"], b["checksum"]);
    // Without reinitialisation the result differs (the option does something).
    let (_, plain) = run_ok(&args[..5], "run-reinit-none");
    assert_ne!(read_summary(&plain)["checksum"], a["checksum"]);
    // Nonsense: a zero interval, the dense reference.
    let o = levelset(&["run", "sphere", "--reinit", "fmm", "--every", "0", "--quiet"]);
    assert!(!o.status.success());
    let dir = tmp("run-reinit-dense");
    let o = levelset(&[
        "run",
        "sphere",
        "--size",
        "32",
        "--steps",
        "2",
        "--grid",
        "dense",
        "--reinit",
        "fmm",
        "--quiet",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("sparse grids"), "{}", stderr(&o));
}

#[test]
fn run_writes_render_and_mesh_frames() {
    let (o, dir) = run_ok(
        &["sphere", "--size", "32", "--steps", "4", "--render-every", "2", "--mesh-every", "4"],
        "run-render-frames",
    );
    for step in [0, 2, 4] {
        let f = dir.join(format!("render-{step:06}.png"));
        let bytes = std::fs::read(&f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    }
    for step in [0, 4] {
        let f = dir.join(format!("mesh-{step:06}.ply"));
        let bytes = std::fs::read(&f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    }
    assert!(!dir.join("render-000001.png").exists());
    assert!(!dir.join("mesh-000002.ply").exists());
    assert!(String::from_utf8_lossy(&o.stdout).contains("wrote 5 frame file(s)"));
    let o = levelset(&["run", "sphere", "--grid", "dense", "--render-every", "1", "--quiet"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("sparse grid"), "{}", stderr(&o));
}

#[test]
fn shape_vectors_take_comma_separated_negative_numbers() {
    let o = levelset(&[
        "info",
        "--shape",
        "box",
        "--center",
        "-5.5,2,-3",
        "--half-extents",
        "10,8,6",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = levelset(&["info", "--shape", "ellipsoid", "--radii", "1,2"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("three comma-separated numbers"), "{}", stderr(&o));
}

#[test]
fn distance_command() {
    use sparse_levelset::io::npy;
    let input = tmp("in.npy");
    let f = DenseField::from_fn(Coord::new(0, 0, 0), [24, 20, 22], |c| {
        let d = ((c.x as f32 - 11.5).powi(2)
            + (c.y as f32 - 9.3).powi(2)
            + (c.z as f32 - 10.0).powi(2))
        .sqrt();
        2.0 * (d - 6.0)
    })
    .unwrap();
    npy::write_npy(&input, &f).unwrap();
    let out = tmp("out.npy");
    let o = levelset(&[
        "distance",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--order",
        "1",
        "--half-width",
        "4",
        "--voxel-size",
        "0.5",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let d = npy::read_npy(&out).unwrap();
    assert_eq!(d.dims(), [24, 20, 22]);
    assert!(d.data().iter().all(|v| v.abs() <= 2.0));
    // Next to the surface: the distance within 0.05 voxel (first order).
    let exact = 0.5 * ((5.5f32 * 5.5 + 0.3 * 0.3).sqrt() - 6.0);
    let got = d.get(Coord::new(17, 9, 10)).unwrap();
    assert!((got - exact).abs() < 0.5 * 0.05, "{got} vs {exact}");
    assert!(String::from_utf8_lossy(&o.stdout).contains("band voxels"));

    let fail = |args: &[&str], what: &str| {
        let o = levelset(args);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(what), "{args:?}: {e}");
    };
    let outs = out.to_str().unwrap();
    let ins = input.to_str().unwrap();
    fail(&["distance", ins, "-o", outs, "--half-width", "0.5"], "half-width");
    fail(&["distance", ins, "-o", outs, "--voxel-size=-1"], "voxel size");
    let mut flat = f.clone();
    flat.data_mut().iter_mut().for_each(|v| *v = 1.0);
    let flat_path = tmp("distance-flat.npy");
    npy::write_npy(&flat_path, &flat).unwrap();
    fail(&["distance", flat_path.to_str().unwrap(), "-o", outs], "no zero crossing");
    let mut nan = f.clone();
    nan.data_mut()[17] = f32::NAN;
    let nan_path = tmp("distance-nan.npy");
    npy::write_npy(&nan_path, &nan).unwrap();
    fail(&["distance", nan_path.to_str().unwrap(), "-o", outs], "NaN");
    fail(&["distance", "/nonexistent/x.npy", "-o", outs], "error:");
    let o = levelset(&["distance", ins, "-o", outs, "--order", "3"]);
    assert_eq!(o.status.code(), Some(1), "clap rejects --order 3");
}

/// `levelset csg`: each operator on two balls of different array sizes equals the
/// pointwise operator on the inputs (clamped to ±γ; +γ beyond an array), over the box of
/// both arrays; different voxel lattices are refused.
#[test]
fn csg_command() {
    use sparse_levelset::io::npy;
    use sparse_levelset::tools::csg::CsgOp;
    let a = common::ball([20, 20, 20], [8.5, 9.0, 10.2], 6.0, 1.0);
    let b = common::ball([26, 18, 22], [14.0, 9.5, 10.0], 5.0, 1.0);
    let (pa, pb) = (common::npy("csg-a.npy", &a), common::npy("csg-b.npy", &b));
    let gamma = 3.0f32;
    let read = |f: &DenseField, c: Coord| f.get(c).map_or(gamma, |v| v.clamp(-gamma, gamma));
    for (op, name) in [
        (CsgOp::Union, "union"),
        (CsgOp::Intersection, "intersection"),
        (CsgOp::Difference, "difference"),
    ] {
        let out = tmp(&format!("csg-{name}.npy"));
        let o = levelset(&[
            "csg",
            pa.to_str().unwrap(),
            pb.to_str().unwrap(),
            "--op",
            name,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(String::from_utf8_lossy(&o.stdout).contains("band voxels"));
        let got = npy::read_npy(&out).unwrap();
        assert_eq!(got.dims(), [26, 20, 22]);
        let mut band = 0;
        for z in 0..22 {
            for y in 0..20 {
                for x in 0..26 {
                    let c = Coord::new(x, y, z);
                    let want = op.apply(read(&a, c), read(&b, c));
                    assert_eq!(got.get(c).unwrap(), want, "{name} at {c:?}");
                    band += (want.abs() < gamma) as usize;
                }
            }
        }
        assert!(band > 0, "{name}");
    }
    let out = tmp("csg-refused.npy");
    let o = levelset(&[
        "csg",
        pa.to_str().unwrap(),
        pb.to_str().unwrap(),
        "--op",
        "nonsense",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!out.exists());
}

/// `csg` reads every level-set format and writes the sparse result: the same operands as
/// `.npy`, `.sls` and `.vdb` (converted by `levelset convert`; the OpenVDB files that
/// OpenVDB itself wrote are read in `tests/integration/vdb.rs`) give the same band.
#[test]
fn csg_takes_every_format_and_gives_the_same_band() {
    use sparse_levelset::LevelSet;
    let a = common::ball([20, 20, 20], [8.5, 9.0, 10.2], 6.0, 1.0);
    let b = common::ball([26, 18, 22], [14.0, 9.5, 10.0], 5.0, 1.0);
    let (pa, pb) = (common::npy("csgf-a.npy", &a), common::npy("csgf-b.npy", &b));
    let mut inputs = vec![(pa.clone(), pb.clone())];
    for ext in ["sls", "vdb"] {
        let (qa, qb) = (tmp(&format!("csgf-a.{ext}")), tmp(&format!("csgf-b.{ext}")));
        for (from, to) in [(&pa, &qa), (&pb, &qb)] {
            let o = levelset(&["convert", from.to_str().unwrap(), to.to_str().unwrap(), "--quiet"]);
            assert!(o.status.success(), "{}", stderr(&o));
        }
        inputs.push((qa, qb));
    }
    // Mixed formats too: a .vdb with a .npy.
    inputs.push((inputs[2].0.clone(), pb.clone()));
    let mut sums = Vec::new();
    for (i, (x, y)) in inputs.iter().enumerate() {
        let out = tmp(&format!("csgf-out-{i}.sls"));
        let o = levelset(&[
            "csg",
            x.to_str().unwrap(),
            y.to_str().unwrap(),
            "--op",
            "union",
            "-o",
            out.to_str().unwrap(),
            "--threads",
            "2",
        ]);
        assert!(o.status.success(), "{x:?} {y:?}: {}", stderr(&o));
        let (grid, _) = sparse_levelset::io::sls::load(&out).unwrap();
        assert!(grid.band_voxels() > 0);
        sums.push(grid.checksum());
    }
    assert!(sums.iter().all(|&s| s == sums[0]), "{sums:x?}");
}

/// `npy` and the same level set converted by `levelset convert` to `.sls` and `.vdb`
/// (`STEM.sls`, `STEM.vdb`).
fn every_format(npy: &Path, stem: &str) -> Vec<PathBuf> {
    let mut inputs = vec![npy.to_path_buf()];
    for ext in ["sls", "vdb"] {
        let p = tmp(&format!("{stem}.{ext}"));
        let o = levelset(&["convert", npy.to_str().unwrap(), p.to_str().unwrap(), "--quiet"]);
        assert!(o.status.success(), "{}", stderr(&o));
        inputs.push(p);
    }
    inputs
}

/// Every command that takes a level set gives the same answer from the same band in every
/// format: a sphere written by OpenVDB itself (`pyopenvdb`, Blosc, its default), and our
/// `.npy`, `.sls` and `.vdb` of it. A level-set output is compared as the `.npy` of its band's
/// box (a `.npy` input's first element is voxel (0, 0, 0), so its band sits elsewhere in the
/// lattice: the box makes the comparison independent of that), a mesh by its counts, area
/// and volume, an image byte for byte, `info` by its band voxels.
#[test]
fn every_command_reads_openvdbs_file_and_ours_alike() {
    let openvdb =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data/vdb/sphere_blosc.vdb");
    let npy = tmp("allfmt.npy");
    let o = levelset(&["convert", openvdb.to_str().unwrap(), npy.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut inputs = vec![openvdb.clone()];
    inputs.extend(every_format(&npy, "allfmt"));
    // The .sls and .vdb made from the .npy sit at the .npy's place: make them from the
    // OpenVDB file instead, so that three of the four share its lattice.
    for (i, ext) in [(2, "sls"), (3, "vdb")] {
        let o = levelset(&[
            "convert",
            openvdb.to_str().unwrap(),
            inputs[i].to_str().unwrap(),
            "--quiet",
        ]);
        assert!(o.status.success(), "{ext}: {}", stderr(&o));
    }
    let mut answers: Vec<Vec<String>> = Vec::new();
    for (k, input) in inputs.iter().enumerate() {
        let i = input.to_str().unwrap();
        let out = |name: &str| tmp(&format!("allfmt-{k}-{name}"));
        let run = |args: &[&str]| {
            let o = levelset(args);
            assert!(o.status.success(), "{args:?}: {}", stderr(&o));
            stdout(&o)
        };
        let digest = |p: &Path| format!("{:08x}", common::crc32(&std::fs::read(p).unwrap()));
        let mut a = Vec::new();
        for (name, args) in [
            ("convert.npy", vec!["convert", i]),
            ("csg.sls", vec!["csg", i, i, "--op", "union", "--quiet", "-o"]),
            ("distance.npy", vec!["distance", i, "--half-width", "5", "--quiet", "-o"]),
            (
                "filter.npy",
                vec!["filter", i, "--op", "dilate:1", "--op", "median:1", "--quiet", "-o"],
            ),
            ("evolve.npy", vec!["evolve", i, "--curvature", "1", "--steps", "5", "--quiet", "-o"]),
            ("render.png", vec!["render", i, "--width", "64", "--height", "48", "--quiet", "-o"]),
        ] {
            let mut p = out(name);
            let mut args = args.clone();
            args.push(p.to_str().unwrap());
            run(&args);
            if name.ends_with(".sls") {
                // A dense operand's .npy result spans its array: compare the band's box.
                let box_npy = out(&format!("{name}.npy"));
                run(&["convert", p.to_str().unwrap(), box_npy.to_str().unwrap(), "--quiet"]);
                p = box_npy;
            }
            a.push(format!("{name} {}", digest(&p)));
        }
        let mesh = run(&["mesh", i, "-o", out("mesh.obj").to_str().unwrap()]);
        let summary = mesh.lines().next().unwrap();
        a.push(summary.split_once(": ").unwrap().1.split(" (").next().unwrap().to_string());
        let info = json(&levelset(&["info", i, "--json"]));
        a.push(format!("info {}", info["grids"][0]["band_voxels"]));
        answers.push(a);
    }
    for (k, a) in answers.iter().enumerate().skip(1) {
        assert_eq!(a, &answers[0], "{:?} against {:?}", inputs[k], inputs[0]);
    }
    assert!(answers[0][6].contains("13704 triangles"), "{:?}", answers[0]);
}

/// `distance` reads every level-set format: a ball as `.npy`, `.sls` and `.vdb` gives the
/// same band of half-width 6 (the dense march of the array and the sparse reinitialisation
/// of the files agree voxel for voxel).
#[test]
fn distance_takes_every_format_and_gives_the_same_band() {
    use sparse_levelset::LevelSet;
    let f =
        common::npy("distf-ball.npy", &common::ball([24, 24, 24], [11.5, 11.2, 12.1], 7.0, 1.0));
    let inputs = every_format(&f, "distf-ball");
    let mut grids = Vec::new();
    for (i, input) in inputs.iter().enumerate() {
        let out = tmp(&format!("distf-out-{i}.sls"));
        let o = levelset(&[
            "distance",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--half-width",
            "6",
            "--threads",
            "2",
        ]);
        assert!(o.status.success(), "{input:?}: {}", stderr(&o));
        grids.push(sparse_levelset::io::sls::load(&out).unwrap().0);
    }
    assert_eq!(grids[1].checksum(), grids[2].checksum(), ".sls and .vdb inputs");
    let (a, b) = (&grids[0], &grids[1]);
    assert_eq!(a.spec().half_width, 6.0);
    let mut worst = 0f32;
    let mut n = 0;
    a.for_each_band_voxel(&mut |c, v| {
        worst = worst.max((v - b.value(c)).abs());
        n += 1;
    });
    assert!(n > 1000 && worst < 1e-5, "{n} voxels, largest difference {worst}");
}

/// `filter` on every format: the same operations on a ball as `.npy`, `.sls` and `.vdb`
/// give the same band, and that band is the library's `filter` of the same level set.
#[test]
fn filter_takes_every_format_and_equals_the_library() {
    use sparse_levelset::tools::filter::{filter, Filter};
    use sparse_levelset::LevelSet;
    let f = common::npy("filt-ball.npy", &common::ball([28, 28, 28], [13.5, 13.2, 14.1], 7.0, 1.0));
    let inputs = every_format(&f, "filt-ball");
    let mut sums = Vec::new();
    for (i, input) in inputs.iter().enumerate() {
        let out = tmp(&format!("filt-out-{i}.sls"));
        let o = levelset(&[
            "filter",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--op",
            "dilate:1.5",
            "--op",
            "median:1",
            "--op",
            "offset:-0.5",
            "--quiet",
        ]);
        assert!(o.status.success(), "{input:?}: {}", stderr(&o));
        sums.push(sparse_levelset::io::sls::load(&out).unwrap().0.checksum());
    }
    assert!(sums.iter().all(|&s| s == sums[0]), "{sums:x?}");
    let (grid, _) = sparse_levelset::io::sls::load(&inputs[1]).unwrap();
    let ops = [Filter::Dilate(1.5), Filter::Median(1), Filter::Offset(-0.5)];
    assert_eq!(filter(&grid, &ops).unwrap().checksum(), sums[0]);
    // Bad operations are refused before any work.
    let out = tmp("filt-bad.sls");
    for (op, msg) in
        [("shrink:2", "unknown filter"), ("median:0", "half-width"), ("open:x", "not a number")]
    {
        let o = levelset(&["filter", f.to_str().unwrap(), "-o", out.to_str().unwrap(), "--op", op]);
        assert_eq!(o.status.code(), Some(1), "{op}: {}", stderr(&o));
        assert!(stderr(&o).contains(msg), "{op}: {}", stderr(&o));
        assert!(!out.exists());
    }
}

/// `evolve` of a user's level set: a `.sls` sphere under mean-curvature motion and a
/// normal speed equals the library's simulation bit for bit, from `.npy`, `.sls` and `.vdb`
/// alike, and the summary comes with the output.
#[test]
fn evolve_equals_the_library_from_every_format() {
    use sparse_levelset::evolve::{Flow, GridKind, Lanes, Settings, Simulation, Speed};
    use sparse_levelset::LevelSet;
    let f = common::npy("evo-ball.npy", &common::ball([32, 32, 32], [15.5, 15.2, 16.1], 9.0, 1.0));
    let inputs = every_format(&f, "evo-ball");
    let (grid, _) = sparse_levelset::io::sls::load(&inputs[1]).unwrap();
    let flow = Flow { speed: Speed::Constant(0.25), ..Flow::mean_curvature(1.0) };
    let tiles = sparse_levelset::storage::convert::tiles_from(&grid);
    let mut sim =
        Simulation::from_tile_grid(GridKind::Tiles(Lanes::Simd), tiles, flow, Settings::default())
            .unwrap();
    sim.run_until(f64::INFINITY, 25, |_, _| {}).unwrap();
    let want = sim.checksum();
    for (i, input) in inputs.iter().enumerate() {
        let out = tmp(&format!("evo-out-{i}.sls"));
        let summary = tmp(&format!("evo-out-{i}.json"));
        let o = levelset(&[
            "evolve",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--curvature",
            "1",
            "--speed",
            "0.25",
            "--steps",
            "25",
            "--summary",
            summary.to_str().unwrap(),
            "--quiet",
        ]);
        assert!(o.status.success(), "{input:?}: {}", stderr(&o));
        let (got, _) = sparse_levelset::io::sls::load(&out).unwrap();
        assert_eq!(got.checksum(), want, "{input:?}");
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
        assert_eq!(s["steps"], 25);
        assert_eq!(s["checksum"], format!("{want:016x}"));
        // The memory it was admitted with and held (a small ball whose band grows by a
        // third over the steps: the estimate is the band's at the start, so only the order
        // of magnitude is checked here; `storage::convert`'s unit tests check the rule);
        // the staged summary's temporary name is not announced.
        let m = &s["memory"];
        let (est, held) =
            (m["estimated_bytes"].as_f64().unwrap(), m["held_bytes"].as_f64().unwrap());
        assert!((0.5..2.0).contains(&(est / held)), "{input:?}: estimate {est}, held {held}");
        assert!(!stdout(&o).contains("/."), "{}", stdout(&o));
    }
    let o = levelset(&["evolve", f.to_str().unwrap(), "-o", tmp("evo-bad.sls").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--time T"), "{}", stderr(&o));
}

/// `levelset evolve IN -o OUT ARGS…`.
fn evolve(input: &str, output: &str, args: &[&str]) -> Output {
    let mut all = vec!["evolve", input, "-o", output];
    all.extend_from_slice(args);
    levelset(&all)
}

/// A float32 `.npy` of shape (nz, ny, nx, 3) (C order): `u(x, y, z)`.
fn vector_npy(name: &str, dims: [usize; 3], u: impl Fn([usize; 3]) -> [f32; 3]) -> PathBuf {
    let [nx, ny, nz] = dims;
    let mut data = Vec::with_capacity(12 * nx * ny * nz);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                data.extend(u([x, y, z]).iter().flat_map(|v| v.to_le_bytes()));
            }
        }
    }
    let p = tmp(name);
    write_npy(&p, "<f4", &[nz, ny, nx, 3], &data);
    p
}

/// `evolve --velocity`: a `.sls` sphere advected by a rotation read from a (nz, ny, nx, 3)
/// `.npy`, plus a normal speed, equals the library's simulation with the same field bit for
/// bit; a uniform field moves the sphere's centre by u·t; a field of the wrong shape or with
/// a NaN is refused before any work.
#[test]
fn evolve_by_a_velocity_field_file_equals_the_library() {
    use sparse_levelset::evolve::{
        Flow, GridKind, Lanes, SampledVelocity, Settings, Simulation, Speed, Velocity,
    };
    use sparse_levelset::LevelSet;
    let f = common::npy("evov-ball.npy", &common::ball([32, 32, 32], [15.5, 15.2, 16.1], 8.0, 1.0));
    let sls = every_format(&f, "evov-ball")[1].clone();
    // A rotation about the axis x = 14, y = 17 (off the ball's centre), given on voxels
    // 2..30 of each axis (element [0, 0, 0] at voxel (2, 2, 2)).
    let rot = |p: [usize; 3]| {
        let (x, y) = (p[0] as f32 + 2.0 - 14.0, p[1] as f32 + 2.0 - 17.0);
        [-0.3 * y, 0.3 * x, 0.05]
    };
    let field = vector_npy("evov-rot.npy", [28, 28, 28], rot);
    let (grid, _) = sparse_levelset::io::sls::load(&sls).unwrap();
    let tiles = sparse_levelset::storage::convert::tiles_from(&grid);
    let comps = sparse_levelset::io::npy::read_npy_vector(&field)
        .unwrap()
        .map(|c| c.with_origin(Coord::new(2, 2, 2)).unwrap());
    let u = SampledVelocity::new(comps, *tiles.spec()).unwrap();
    let flow = Flow {
        speed: Speed::Constant(0.1),
        velocity: Some(Velocity::Field(std::sync::Arc::new(u))),
        ..Flow::rest()
    };
    let mut sim =
        Simulation::from_tile_grid(GridKind::Tiles(Lanes::Simd), tiles, flow, Settings::default())
            .unwrap();
    sim.run_until(f64::INFINITY, 20, |_, _| {}).unwrap();
    let out = tmp("evov-out.sls");
    let o = evolve(
        sls.to_str().unwrap(),
        out.to_str().unwrap(),
        &[
            "--velocity",
            field.to_str().unwrap(),
            "--velocity-origin",
            "2,2,2",
            "--speed",
            "0.1",
            "--steps",
            "20",
            "--threads",
            "2",
            "--quiet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(sparse_levelset::io::sls::load(&out).unwrap().0.checksum(), sim.checksum());

    // A uniform u = (1, −0.5, 0.25) for t = 4 moves the centre by (4, −2, 1): the mean of
    // the interface voxels (|φ| < 1) moves so, within 0.25 voxels.
    let uni = vector_npy("evov-uni.npy", [32, 32, 32], |_| [1.0, -0.5, 0.25]);
    let moved = tmp("evov-moved.sls");
    let o = evolve(
        sls.to_str().unwrap(),
        moved.to_str().unwrap(),
        &["--velocity", uni.to_str().unwrap(), "--time", "4", "--quiet"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    fn centre(g: &impl LevelSet) -> [f64; 3] {
        let (mut sum, mut n) = ([0f64; 3], 0f64);
        g.for_each_band_voxel(&mut |c, v| {
            if v.abs() < 1.0 {
                for (s, x) in sum.iter_mut().zip([c.x, c.y, c.z]) {
                    *s += x as f64;
                }
                n += 1.0;
            }
        });
        sum.map(|s| s / n)
    }
    let (a, b) = (centre(&grid), centre(&sparse_levelset::io::sls::load(&moved).unwrap().0));
    for (d, want) in [4.0, -2.0, 1.0].iter().enumerate() {
        assert!((b[d] - a[d] - want).abs() < 0.25, "axis {d}: {a:?} -> {b:?}");
    }

    // Refusals before any work: a volume where a vector field is expected, a NaN.
    let bad_out = tmp("evov-bad.sls");
    let nan = vector_npy("evov-nan.npy", [4, 4, 4], |p| {
        if p == [1, 2, 3] {
            [0.0, f32::NAN, 0.0]
        } else {
            [0.0; 3]
        }
    });
    for (file, msg) in [(&f, "(nz, ny, nx, 3)"), (&nan, "NaN at voxel (x, y, z) = (1, 2, 3)")] {
        let o = evolve(
            sls.to_str().unwrap(),
            bad_out.to_str().unwrap(),
            &["--velocity", file.to_str().unwrap(), "--steps", "1"],
        );
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(msg), "{}", stderr(&o));
        assert!(!bad_out.exists());
    }
}

/// `evolve --velocity FILE.vdb`: a ball (voxel size 0.5) advected by the vector grid OpenVDB
/// wrote (voxel size 0.5, its own translation), sampled in world space, equals the library's
/// simulation with the same field bit for bit, and moves.
#[test]
fn evolve_by_an_openvdb_vector_grid_equals_the_library() {
    use sparse_levelset::evolve::{
        Flow, GridKind, Lanes, SampledVelocity, Settings, Simulation, Velocity,
    };
    use sparse_levelset::io::{self, input::Expect};
    use sparse_levelset::LevelSet;
    let vdb = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data/vdb/velocity.vdb");
    let f = common::npy("evovdb-ball.npy", &common::ball([24, 20, 24], [6.0, 7.0, 10.0], 4.0, 0.5));
    let spec = GridSpec::new(0.5, [0.0; 3], 3.0).unwrap();
    let loaded = io::load_level_set(&f, &Expect::new(spec)).unwrap();
    let io::AnyLevelSet::Tiles(tiles) = loaded.level_set else { panic!("a .npy gives tiles") };
    let before = tiles.checksum();
    let field = io::load_vector_field(&vdb, &spec, Coord::new(0, 0, 0)).unwrap();
    assert_eq!(field.spec.voxel_size, 0.5);
    let u = SampledVelocity::new(field.components, field.spec).unwrap();
    let flow = Flow { velocity: Some(Velocity::Field(std::sync::Arc::new(u))), ..Flow::rest() };
    let mut sim =
        Simulation::from_tile_grid(GridKind::Tiles(Lanes::Simd), tiles, flow, Settings::default())
            .unwrap();
    sim.run_until(f64::INFINITY, 15, |_, _| {}).unwrap();
    assert_ne!(sim.checksum(), before);
    let out = tmp("evovdb-out.sls");
    let o = levelset(&[
        "evolve",
        f.to_str().unwrap(),
        "--voxel-size",
        "0.5",
        "-o",
        out.to_str().unwrap(),
        "--velocity",
        vdb.to_str().unwrap(),
        "--steps",
        "15",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(sparse_levelset::io::sls::load(&out).unwrap().0.checksum(), sim.checksum());
    // A level-set .vdb is not a vector field; nor is a mesh.
    let sphere =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data/vdb/sphere_blosc.vdb");
    let obj = tmp("evovdb.obj");
    std::fs::write(&obj, "v 0 0 0\n").unwrap();
    for (file, msg) in [(&sphere, "no vector grid"), (&obj, "unknown vector-field file type")] {
        let o = evolve(
            f.to_str().unwrap(),
            tmp("evovdb-bad.sls").to_str().unwrap(),
            &["--velocity", file.to_str().unwrap(), "--steps", "1"],
        );
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(msg), "{}", stderr(&o));
    }
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
    let s =
        ok(&["mesh", npy.to_str().unwrap(), "--voxel-size", "0.5", "-o", ply.to_str().unwrap()]);
    assert!(s.contains("closed manifold: yes") && s.contains("Euler characteristic 2"), "{s}");
    let m = isosurface_dense(&ball, &GridSpec::new(0.5, [0.0; 3], 3.0).unwrap(), 0.0).unwrap();
    assert!(s.contains(&format!("{} vertices, {} triangles", m.num_vertices(), m.num_triangles())));
    close("ball volume", m.enclosed_volume(), 4.0 / 3.0 * PI * 4.5f64.powi(3), 2e-2);

    let mut bad = ball.clone();
    bad.set(Coord::new(3, 4, 5), f32::NAN).unwrap();
    let nan = tmp("mesh-nan.npy");
    sparse_levelset::io::npy::write_npy(&nan, &bad).unwrap();
    fails(&["mesh", nan.to_str().unwrap(), "-o", ply.to_str().unwrap()], "NaN");
    let empty = tmp("empty.npy");
    sparse_levelset::io::npy::write_npy(
        &empty,
        &DenseField::new(Coord::new(0, 0, 0), [5, 5, 5], 1.0).unwrap(),
    )
    .unwrap();
    fails(&["mesh", empty.to_str().unwrap(), "-o", ply.to_str().unwrap()], "no surface");
    let trunc = tmp("trunc.npy");
    let bytes = std::fs::read(&npy).unwrap();
    std::fs::write(&trunc, &bytes[..bytes.len() / 2]).unwrap();
    fails(&["mesh", trunc.to_str().unwrap(), "-o", ply.to_str().unwrap()], "");
    fails(&["mesh", "-o", tmp("x.xyz").to_str().unwrap()], "unknown mesh format");
    // Binary STL out, read back by the library's mesh reader.
    let stl = tmp("cli-sphere.stl");
    ok(&["mesh", "--shape", "sphere", "--radius", "6", "-o", stl.to_str().unwrap()]);
    let back = sparse_levelset::io::mesh::load_mesh(&stl).unwrap();
    assert!(back.triangles.len() > 100 && back.is_closed_manifold());
    fails(&["mesh", "--radius=-5", "-o", ply.to_str().unwrap()], "");
    fails(
        &["mesh", "--radius", "10", "--iso", "3", "-o", ply.to_str().unwrap()],
        "outside the band",
    );
    fails(&["mesh", "--voxel-size", "0", "-o", ply.to_str().unwrap()], "voxel size");
    fails(&["mesh", "--center", "1,2", "-o", ply.to_str().unwrap()], "three comma-separated");
    let s = ok(&["mesh", "--center", "-5.5,2,-3", "--radius", "6", "-o", out.to_str().unwrap()]);
    assert!(s.contains("closed manifold: yes"), "{s}");
    // A coarser mesh: every second voxel, a quarter of the triangles, from a shape and
    // from a field.
    let triangles = |s: &str| -> usize {
        let w: Vec<&str> = s.split_whitespace().collect();
        let i = w.iter().position(|&x| x == "triangles,").unwrap();
        w[i - 1].parse().unwrap()
    };
    let args = ["mesh", "--radius", "20", "-o", out.to_str().unwrap(), "--quiet"];
    let full = triangles(&ok(&args));
    let s = ok(&[&args[..], &["--coarsen", "2"]].concat());
    assert!(s.contains("closed manifold: yes") && s.contains("Euler characteristic 2"), "{s}");
    let ratio = full as f64 / triangles(&s) as f64;
    assert!((3.2..4.8).contains(&ratio), "{s}: {ratio}");
    let s = ok(&[
        "mesh",
        npy.to_str().unwrap(),
        "--voxel-size",
        "0.5",
        "--coarsen",
        "2",
        "-o",
        ply.to_str().unwrap(),
    ]);
    assert!(s.contains("closed manifold: yes") && s.contains("Euler characteristic 2"), "{s}");
    let o = levelset(&["mesh", "--coarsen", "0", "-o", ply.to_str().unwrap()]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--coarsen"));
    // The failed runs left the earlier file alone.
    assert_eq!(std::fs::read(&ply).unwrap().len() as u64, std::fs::metadata(&ply).unwrap().len());
}

#[test]
fn cli_renders_shapes_and_fields_and_rejects_bad_input() {
    let out = tmp("cli-torus.png");
    let o = levelset(&[
        "render",
        "--shape",
        "torus",
        "--major-radius",
        "12",
        "--minor-radius",
        "4",
        "-o",
        out.to_str().unwrap(),
        "--width",
        "48",
        "--height",
        "36",
        "--quiet",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(summary["hit_pixels"].as_u64().unwrap() > 100);
    assert!(summary["render_seconds"].as_f64().unwrap() >= 0.0);
    let file = std::io::BufReader::new(std::fs::File::open(&out).unwrap());
    let reader = png::Decoder::new(file).read_info().unwrap();
    assert_eq!((reader.info().width, reader.info().height), (48, 36));

    // A dense field: a sphere of radius 6 sampled on a 20³ box, as the positional FIELD.
    let field = common::ball([20, 20, 20], [9.5; 3], 6.0, 1.0);
    let npy = common::npy("ball.npy", &field);
    let out2 = tmp("cli-ball.png");
    let o = levelset(&[
        "render",
        npy.to_str().unwrap(),
        "--voxel-size",
        "0.5",
        "-o",
        out2.to_str().unwrap(),
        "--width",
        "40",
        "--height",
        "30",
        "--grid",
        "dtgrid",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out2.exists());

    let mut nan = field.clone();
    nan.set(Coord::new(3, 4, 5), f32::NAN).unwrap();
    let nan_npy = tmp("render-nan.npy");
    sparse_levelset::io::npy::write_npy(&nan_npy, &nan).unwrap();
    let flat = DenseField::new(Coord::new(0, 0, 0), [6, 6, 6], 1.0).unwrap();
    let flat_npy = tmp("render-flat.npy");
    sparse_levelset::io::npy::write_npy(&flat_npy, &flat).unwrap();
    let o_png = tmp("x.png");
    let o_png = o_png.to_str().unwrap();
    let bad_dir = tmp("no/such/dir/x.png");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec![nan_npy.to_str().unwrap(), "-o", o_png], "NaN"),
        (vec![flat_npy.to_str().unwrap(), "-o", o_png], "empty"),
        (vec!["/no/such/file.npy", "-o", o_png], "file.npy"),
        (vec!["--shape", "sphere", "--radius", "10", "--width", "0", "-o", o_png], "width"),
        (
            vec!["--shape", "sphere", "--radius", "10", "--elevation", "95", "-o", o_png],
            "elevation",
        ),
        (vec!["--shape", "sphere", "--radius=-3", "-o", o_png], "radius"),
        (vec!["--shape", "sphere", "--radius", "10", "-o", bad_dir.to_str().unwrap()], "x.png"),
        (vec!["--shape", "sphere", "--radius", "10", "--grid", "dense", "-o", o_png], "dense"),
    ];
    for (args, needle) in cases {
        let mut all = vec!["render", "--quiet"];
        all.extend(args.iter());
        let o = levelset(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{all:?}: {err}");
        assert!(err.starts_with("error:") && err.contains(needle), "{all:?}: {err}");
    }
    assert!(!std::path::Path::new(o_png).exists(), "no image written on error");
}

// ---------------------------------------------------------------------------------------
// One front door: the same input gets the same verdict from every subcommand, before any
// work, and nothing is written on error.

/// Runs every subcommand that reads a dense field on `field` (`mesh` at isovalue `iso`) and
/// returns (command, output, path it would write).
fn every_tool(field: &Path, tag: &str, iso: &str) -> Vec<(&'static str, Output, PathBuf)> {
    let f = field.to_str().unwrap();
    let (ply, png, npy, dir) = (
        tmp(&format!("{tag}-out.ply")),
        tmp(&format!("{tag}-out.png")),
        tmp(&format!("{tag}-out.npy")),
        tmp(&format!("{tag}-run")),
    );
    let (ply_s, png_s, npy_s, dir_s) = (
        ply.to_str().unwrap(),
        png.to_str().unwrap(),
        npy.to_str().unwrap(),
        dir.to_str().unwrap(),
    );
    let csg = tmp(&format!("{tag}-csg.npy"));
    let csg_s = csg.to_str().unwrap();
    let sls = tmp(&format!("{tag}-out.sls"));
    let sls_s = sls.to_str().unwrap();
    vec![
        ("info", levelset(&["info", f]), PathBuf::new()),
        ("distance", levelset(&["distance", f, "-o", npy_s]), npy.clone()),
        ("mesh", levelset(&["mesh", f, "--iso", iso, "-o", ply_s, "--quiet"]), ply.clone()),
        (
            "render",
            levelset(&["render", f, "-o", png_s, "--width", "32", "--height", "24", "--quiet"]),
            png.clone(),
        ),
        (
            "run",
            levelset(&["run", "expand", "--init", f, "--steps", "2", "--quiet", "--out", dir_s]),
            dir.clone(),
        ),
        ("csg", levelset(&["csg", f, f, "--op", "union", "-o", csg_s]), csg.clone()),
        ("convert", levelset(&["convert", f, sls_s, "--quiet"]), sls.clone()),
    ]
}

/// Every tool in `tools` fails with exit code 1 and `needle` in a one-line message, and
/// wrote nothing.
fn all_refuse(runs: &[(&str, Output, PathBuf)], tools: &[&str], needle: &str) {
    for (tool, o, out) in runs.iter().filter(|(t, ..)| tools.contains(t)) {
        let e = stderr(o);
        assert_eq!(o.status.code(), Some(1), "{tool}: {e}");
        assert!(
            e.starts_with("error:") && e.contains(needle),
            "{tool}: expected '{needle}' in: {e}"
        );
        assert!(!e.contains("panicked"), "{tool}: {e}");
        assert!(out.as_os_str().is_empty() || !out.exists(), "{tool} wrote {}", out.display());
    }
}

#[test]
fn one_loader_one_verdict_for_every_subcommand() {
    let all = ["info", "distance", "mesh", "render", "run", "csg", "convert"];
    let ball = common::ball([20, 20, 20], [9.5; 3], 6.0, 1.0);

    // NaN: refused everywhere with one message.
    let mut nan = ball.clone();
    nan.set(Coord::new(3, 4, 5), f32::NAN).unwrap();
    let runs = every_tool(&common::npy("v-nan.npy", &nan), "v-nan", "0");
    all_refuse(&runs, &all, "NaN at voxel (x, y, z) = (3, 4, 5)");

    // No interface: inside everywhere (mesh used to write a box around the array and exit
    // 0), or zeros, which count as outside (`run --init` used to report "collapsed").
    for (value, tag, side) in [(-5.0, "v-inside", "inside"), (0.0, "v-zeros", "outside")] {
        let flat = DenseField::new(Coord::new(0, 0, 0), [8, 8, 8], value).unwrap();
        let runs = every_tool(&common::npy(&format!("{tag}.npy"), &flat), tag, "0");
        all_refuse(&runs, &all, &format!("no interface: every voxel is {side}"));
    }

    // Not a distance field: 1000 φ. `render` and `run --init` used to say "the level set is
    // empty"; now every tool that builds a band gives info's diagnosis, and `distance`,
    // which makes distance fields, accepts it.
    let steep = common::ball([20, 20, 20], [9.5; 3], 6.0, 1000.0);
    let runs = every_tool(&common::npy("v-steep.npy", &steep), "v-steep", "0");
    all_refuse(&runs, &["info", "mesh", "render", "run", "csg"], "not a signed distance field");
    let (_, o, out) = runs.iter().find(|(t, ..)| *t == "distance").unwrap();
    assert!(o.status.success() && out.exists(), "{}", stderr(o));

    // ±inf: a far-away distance everywhere (distance used to refuse it).
    let mut inf = ball.clone();
    inf.set(Coord::new(0, 0, 0), f32::INFINITY).unwrap();
    inf.set(Coord::new(19, 19, 19), f32::INFINITY).unwrap();
    for (tool, o, _) in every_tool(&common::npy("v-inf.npy", &inf), "v-inf", "0") {
        assert!(o.status.success(), "{tool}: {}", stderr(&o));
    }

    // An isovalue outside the band: mesh used to write a box and exit 0.
    let runs = every_tool(&common::npy("v-iso.npy", &ball), "v-iso", "100");
    all_refuse(&runs, &["mesh"], "outside the band");
    let runs = every_tool(&common::npy("v-iso2.npy", &ball), "v-iso2", "-3");
    all_refuse(&runs, &["mesh"], "outside the band");
}

#[test]
fn negative_numbers_are_flag_values_with_a_clear_range_message() {
    let field = common::npy("neg.npy", &common::ball([12, 12, 12], [5.5; 3], 3.0, 1.0));
    let f = field.to_str().unwrap();
    let out = tmp("neg-out.npy");
    let o_s = out.to_str().unwrap();
    let png = tmp("neg.png");
    let png_s = png.to_str().unwrap();
    let ply = tmp("neg.ply");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["render", "--radius", "10", "--fov", "-10", "-o", png_s], "field of view"),
        (vec!["render", "--radius", "10", "--azimuth", "-inf", "-o", png_s], "azimuth"),
        (vec!["run", "sphere", "--time", "-1"], "time must be finite and > 0"),
        (vec!["run", "sphere", "--cfl", "-0.5"], "cfl"),
        (vec!["distance", f, "-o", o_s, "--voxel-size", "-inf"], "voxel size"),
        (vec!["distance", f, "-o", o_s, "--half-width", "-3"], "half-width"),
        (vec!["mesh", "--radius", "-5", "-o", ply.to_str().unwrap()], "radius"),
        (vec!["info", "--shape", "torus", "--minor-radius", "-2"], "minor radius"),
        (vec!["info", f, "--voxel-size", "-1"], "voxel size"),
    ];
    for (args, needle) in cases {
        let o = levelset(&args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert!(!e.contains("unexpected argument"), "{args:?}: {e}");
        assert!(e.to_lowercase().contains(needle), "{args:?}: expected '{needle}' in: {e}");
    }
    assert!(!out.exists() && !png.exists());
    // Integer flags: clap's range message.
    let o = levelset(&["run", "sphere", "--threads", "-1"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("-1 is not in 1..=1024"), "{}", stderr(&o));
}

#[test]
fn what_the_computation_cannot_represent_is_refused_before_any_work() {
    let field = common::npy("repr.npy", &common::ball([12, 12, 12], [5.5; 3], 3.0, 1.0));
    let f = field.to_str().unwrap();
    let out = tmp("repr-out.npy");
    let ply = tmp("repr.ply");
    let cases: Vec<(Vec<&str>, &str, &Path)> = vec![
        // γ = 3e38: used to exit 0 with ±inf in the output.
        (vec!["distance", f, "-o", out.to_str().unwrap(), "--voxel-size", "1e38"], "γ²", &out),
        (vec!["info", "--radius", "10", "--voxel-size", "1e-30"], "too small", &out),
        (
            vec!["info", "--shape", "sphere", "--radius", "10", "--center", "2147483640,0,0"],
            "i32",
            &out,
        ),
    ];
    for (args, needle, written) in cases {
        let o = levelset(&args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert!(
            e.starts_with("error:") && e.contains(needle),
            "{args:?}: expected '{needle}' in {e}"
        );
        assert!(!written.exists(), "{args:?} wrote {}", written.display());
    }
    // Voxels inside the i32 range where f32 vertices would be 128 units apart (this used to
    // exit 0 with a flattened mesh of area 627): the mesh is written with double
    // positions, closed, with the sphere's area.
    for x in ["16777216", "2147483000"] {
        let center = format!("{x},0,0");
        let o =
            levelset(&["mesh", "--radius", "10", "--center", &center, "-o", ply.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        let s = String::from_utf8(o.stdout).unwrap();
        assert!(s.contains("closed manifold: yes, Euler characteristic 2"), "{s}");
        let area: f64 =
            s.split("area ").nth(1).unwrap().split(',').next().unwrap().parse().unwrap();
        let exact = 4.0 * std::f64::consts::PI * 100.0;
        assert!((area - exact).abs() <= 5e-3 * exact, "area {area} at x = {x}");
        let bytes = std::fs::read(&ply).unwrap();
        let header = String::from_utf8_lossy(&bytes[..bytes.len().min(400)]).to_string();
        assert!(header.contains("property double x"), "{header}");
    }
}

/// A `.npy` whose header and file size both claim a (4096, 2048, 2048) float32 array
/// (64 GiB): a sparse file, so no disk is used.
fn huge_sparse_npy() -> PathBuf {
    let p = tmp("huge-sparse.npy");
    write_npy(&p, "<f4", &[4096, 2048, 2048], &[]);
    let header = std::fs::metadata(&p).unwrap().len();
    std::fs::OpenOptions::new().write(true).open(&p).unwrap().set_len(header + (1 << 36)).unwrap();
    p
}

#[test]
fn memory_is_checked_before_any_large_allocation() {
    if sparse_levelset::memory::limit() >= 1 << 36 {
        eprintln!("skipped: this machine may hold a 64 GiB array");
        return;
    }
    // Used to abort with "memory allocation of 68719476736 bytes failed".
    let huge = huge_sparse_npy();
    let runs = every_tool(&huge, "huge", "0");
    all_refuse(&runs, &["info", "distance", "mesh", "render", "run"], "GiB");
    for (tool, o, _) in &runs {
        assert!(stderr(o).contains("memory"), "{tool}: {}", stderr(o));
    }
    // The dense reference of a 2048³ box (17.6 GB a copy) used to be allocated unchecked.
    let start = std::time::Instant::now();
    let dir = tmp("dense-2048");
    let o = levelset(&[
        "run",
        "sphere",
        "--grid",
        "dense",
        "--size",
        "2048",
        "--quiet",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("dense reference") && stderr(&o).contains("GiB"), "{}", stderr(&o));
    assert!(start.elapsed().as_secs_f64() < 30.0, "refused before the work");
    assert!(!dir.exists(), "nothing written");
}

#[test]
fn output_paths_are_checked_before_the_work_starts() {
    // A short sphere run writing into `out`.
    let small_run = |out: &dyn AsRef<std::path::Path>| {
        let out = out.as_ref().to_str().unwrap();
        levelset(&["run", "sphere", "--size", "32", "--steps", "3", "--quiet", "--out", out])
    };
    // --json into a missing directory: used to run the whole report and fail on writing.
    let missing = tmp("no-such-dir/x.json");
    let o = speedup(&["--kernels", "--quick", "--json", missing.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("x.json") && stderr(&o).contains("cannot write"), "{}", stderr(&o));
    assert!(stdout(&o).is_empty(), "no work was done: {}", stdout(&o));

    // run --out DIR where DIR/summary.json cannot be written (a directory is in the way):
    // used to evolve, then fail.
    let dir = tmp("out-blocked");
    std::fs::create_dir_all(dir.join("summary.json")).unwrap();
    let o = small_run(&dir);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("summary.json"), "{}", stderr(&o));
    assert!(stdout(&o).is_empty(), "no work was done: {}", stdout(&o));

    // --out below a regular file: nothing is created.
    let file = tmp("a-regular-file");
    std::fs::write(&file, b"x").unwrap();
    let o = small_run(&file.join("sub"));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("cannot write"), "{}", stderr(&o));

    // distance, mesh and render: the output's directory must exist before the input is read.
    let field = common::npy("out-ball.npy", &common::ball([12, 12, 12], [5.5; 3], 3.0, 1.0));
    let f = field.to_str().unwrap();
    for args in [
        vec!["distance", f, "-o", "/no/such/dir/d.npy"],
        vec!["mesh", f, "-o", "/no/such/dir/m.ply"],
        vec!["render", f, "-o", "/no/such/dir/r.png"],
    ] {
        let o = levelset(&args);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("cannot write the output here"), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn bare_levelset_prints_help_at_once() {
    // Used to start the 1.5-minute speed-up report silently.
    let start = std::time::Instant::now();
    let o = levelset(&[]);
    assert!(start.elapsed().as_secs_f64() < 10.0, "{:?}", start.elapsed());
    assert_eq!(o.status.code(), Some(1));
    let text = stdout(&o) + &stderr(&o);
    assert!(text.contains("Usage: levelset <COMMAND>"), "{text}");
    for sub in ["info", "run", "distance", "render", "mesh", "levelset-speedup"] {
        assert!(text.contains(sub), "{sub} missing from: {text}");
    }
    // `levelset bench` is gone: the report is its own binary.
    assert_eq!(levelset(&["bench"]).status.code(), Some(1));
}

#[test]
fn cargo_run_runs_the_speedup_report() {
    // `cargo run` at the root: the cli crate is a default member and its default binary
    // is the report.
    let cli = env!("CARGO_MANIFEST_DIR");
    let manifest = std::fs::read_to_string(Path::new(cli).join("Cargo.toml")).unwrap();
    assert!(manifest.contains("default-run = \"levelset-speedup\""), "{manifest}");
    let root = std::fs::read_to_string(Path::new(cli).join("../Cargo.toml")).unwrap();
    let members = root.lines().find(|l| l.starts_with("default-members")).expect("default-members");
    assert!(members.contains("\"cli\""), "{members}");
    assert!(!root.contains("[[bin]]"), "the library has no binary");
    let o = speedup(&["--help"]);
    assert!(o.status.success());
    for flag in ["--json", "--full", "--threads", "--storage", "--kernels", "--pin", "--quick"] {
        assert!(stdout(&o).contains(flag), "{flag}: {}", stdout(&o));
    }
}

#[test]
fn speedup_reports_the_time_to_solution() {
    let s = tmp("solution.json");
    let args = ["--solution", "--solution-scale", "0.125", "--solution-enright-size", "24"];
    let o = speedup(&[&args[..], &["--threads", "2", "--json", s.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("Time to solution"), "{}", stdout(&o));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&s).unwrap()).unwrap();
    // The section alone: no speed-up scenarios, no operators.
    assert_eq!(v["scenarios"].as_array().unwrap().len(), 0);
    assert_eq!(v["tools"].as_array().unwrap().len(), 0);
    let runs = v["time_to_solution"].as_array().unwrap();
    let rows: Vec<(&str, &str, u64, u64)> = runs
        .iter()
        .map(|r| {
            (
                r["case"].as_str().unwrap(),
                r["scenario"].as_str().unwrap(),
                r["size"].as_u64().unwrap(),
                r["threads"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        rows,
        [
            ("sphere", "sphere", 32, 1),
            ("sphere", "sphere", 32, 2),
            ("sphere-small", "sphere", 8, 1),
            ("sphere-small", "sphere", 8, 2),
            ("enright", "enright", 24, 1),
            ("enright", "enright", 24, 2),
            ("spiral", "spiral", 16, 1),
            ("spiral", "spiral", 16, 2),
        ]
    );
    let f = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap_or_else(|| panic!("{k}: {r}"));
    for pair in runs.chunks(2) {
        // One band on every thread count.
        assert_eq!(pair[0]["checksum"], pair[1]["checksum"], "{}", pair[0]["case"]);
        assert_eq!(pair[0]["steps"], pair[1]["steps"]);
    }
    for r in runs {
        let p = &r["params"];
        assert_eq!(p["threads"], r["threads"]);
        assert_eq!(p["lanes"], "simd");
        for k in ["scheme", "integrator"] {
            assert!(p[k].is_string(), "{k}: {p}");
        }
        assert!(f(p, "cfl") > 0.0);
        assert!(
            r["steps"].as_u64().unwrap() > 0 && f(r, "seconds") > 0.0 && f(r, "final_time") > 0.0
        );
        assert_eq!(r["checksum"].as_str().unwrap().len(), 16);
        let (measured, exact, error) = (f(r, "measured"), f(r, "exact"), f(r, "error"));
        let want = match r["case"].as_str().unwrap() {
            "sphere" | "sphere-small" => {
                // √(r₀² − 2εt) at the final time, the error in voxels.
                let (r0, eps) = (f(p, "radius"), f(p, "epsilon"));
                close(
                    "exact radius",
                    exact,
                    (r0 * r0 - 2.0 * eps * f(r, "final_time")).sqrt(),
                    1e-12,
                );
                assert_eq!(r["error_kind"], "voxels");
                (measured - exact).abs() / f(p, "voxel_size")
            }
            "enright" => {
                assert_eq!(exact, 1.0);
                1.0 - measured
            }
            _ => {
                assert_eq!(exact, 1.0);
                (measured - 1.0).abs()
            }
        };
        assert!((error - want).abs() <= 1e-12, "{r}");
        close("relative error", f(r, "relative_error"), (measured - exact).abs() / exact, 1e-12);
    }
    // The small sphere runs to half its collapse time, r₀²/4.
    let small = &runs[2];
    let r0 = f(&small["params"], "radius");
    close("small sphere's end", f(small, "final_time"), r0 * r0 / 4.0, 1e-12);

    for bad in [
        &["--solution-scale", "0"][..],
        &["--solution-scale", "-1"],
        &["--solution-scale", "2"],
        &["--solution-scale", "x"],
        &["--solution-enright-size", "4"],
        &["--solution-enright-size", "-8"],
        &["--solution", "--storage"],
        &["--solution", "--kernels"],
    ] {
        let o = speedup(bad);
        assert!(!o.status.success(), "{bad:?}");
        assert!(stderr(&o).contains("error"), "{bad:?}: {}", stderr(&o));
    }
    let help = stdout(&speedup(&["--help"]));
    for flag in ["--solution", "--solution-enright-size", "--solution-scale"] {
        assert!(help.contains(flag), "{flag}: {help}");
    }
}
