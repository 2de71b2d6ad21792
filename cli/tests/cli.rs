//! The `levelset` command as a user meets it: `info` on shapes and `.npy` fields, JSON
//! output, and clear errors with a non-zero exit on bad input.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

use common::{levelset, stderr, tmp};

fn json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "failed: {}", stderr(o));
    serde_json::from_slice(&o.stdout).expect("valid JSON")
}

/// A .npy v1.0 file with the given dtype descriptor, shape and raw little-endian data.
fn write_npy(path: &Path, descr: &str, shape: &[usize], data: &[u8]) {
    let shape_s = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!("({})", shape.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", ")),
    };
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_s}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(data);
    std::fs::write(path, bytes).unwrap();
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
    let o = levelset(&["bench", "--kernels", "--quick", "--json", k.to_str().unwrap()]);
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
    let o = levelset(&["bench", "--storage", "--quick", "--json", s.to_str().unwrap()]);
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
    let o = levelset(&["bench", "--reps", "0"]);
    assert!(!o.status.success());
}

#[test]
fn bench_reports_the_speedup_over_dtgrid() {
    let s = tmp("speedup.json");
    let o = levelset(&["bench", "--quick", "--threads", "2", "--json", s.to_str().unwrap()]);
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
        "rescale",
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
    let f = sparse_levelset::npy::read_npy(&dir.join("final.npy")).unwrap();
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

    // An --init field holding inf: error, exit 1, no panic.
    let path = tmp("inf.npy");
    let mut data = sphere_f32(12, 3.0);
    data[4 * 100..4 * 101].copy_from_slice(&f32::INFINITY.to_le_bytes());
    write_npy(&path, "<f4", &[12, 12, 12], &data);
    let o = run_from(&path, "sphere", "o1");
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).starts_with("error:") && stderr(&o).contains("not finite"),
        "{}",
        stderr(&o)
    );

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
        assert_eq!(
            o.status.code(),
            Some(if args.contains(&"--threads") { 2 } else { 1 }),
            "{args:?}: {}",
            stderr(&o)
        );
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
