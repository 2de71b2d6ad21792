//! `levelset convert` to and from OpenVDB `.vdb` files through the command line.

use crate::common::{ball, levelset, npy, stderr, stdout, tmp};
use sparse_levelset::{io::sls, io::vdb, LevelSet};
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data/vdb").join(name)
}

#[test]
fn convert_writes_and_reads_vdb_with_the_same_band() {
    let b = ball([24, 24, 24], [11.5; 3], 7.0, 1.0);
    let f = npy("vdb-ball.npy", &b);
    let (direct, via, out) = (tmp("vdb-direct.sls"), tmp("vdb-via.sls"), tmp("vdb-ball.vdb"));
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    let o = levelset(&["convert", &s(&f), &s(&direct), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for codec in ["zip", "none"] {
        let o = levelset(&["convert", &s(&f), &s(&out), "--vdb-compression", codec, "--quiet"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let (grid, info) = vdb::load(&out).unwrap();
        assert_eq!(info.grid_name, "level_set");
        assert_eq!(
            info.compression,
            if codec == "zip" { "zip + active values" } else { "active values" }
        );
        let o = levelset(&["convert", &s(&out), &s(&via), "--quiet"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let (a, _) = sls::load(&direct).unwrap();
        let (c, _) = sls::load(&via).unwrap();
        assert_eq!(a.checksum(), c.checksum(), "{codec}");
        assert_eq!(grid.checksum(), a.checksum(), "{codec}");
    }
    // The grid name is an option.
    let o = levelset(&["convert", &s(&f), &s(&out), "--vdb-grid-name", "ball", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(vdb::load(&out).unwrap().1.grid_name, "ball");
}

#[test]
fn convert_reads_openvdb_files_into_every_output() {
    let src = fixture("sphere_blosc.vdb");
    let (sls_out, ply, dense) = (tmp("ovdb.sls"), tmp("ovdb.ply"), tmp("ovdb.npy"));
    for out in [&sls_out, &ply, &dense] {
        let o = levelset(&["convert", src.to_str().unwrap(), out.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stdout(&o).contains("sphere_blosc.vdb ->"), "{}", stdout(&o));
    }
    let (tiles, _) = vdb::load(&src).unwrap();
    assert_eq!(sls::load(&sls_out).unwrap().0.checksum(), tiles.checksum());
    assert!(std::fs::metadata(&ply).unwrap().len() > 1000);
}

#[test]
fn every_tool_reads_vdb() {
    let src = fixture("sphere_blosc.vdb");
    let s = src.to_str().unwrap();
    let o = levelset(&["info", s, "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let band: Vec<u64> =
        j["grids"].as_array().unwrap().iter().map(|g| g["band_voxels"].as_u64().unwrap()).collect();
    assert!(band.iter().all(|&n| n == 9360), "{band:?}");
    let (ply, png) = (tmp("ovdb-mesh.ply"), tmp("ovdb.png"));
    let o = levelset(&["mesh", s, "-o", ply.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o =
        levelset(&["render", s, "-o", png.to_str().unwrap(), "--width", "32", "--height", "32"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(png.exists() && ply.exists());
}

#[test]
fn bad_vdb_inputs_and_options_get_one_clear_message() {
    let bad = tmp("bad.vdb");
    std::fs::write(&bad, b"VDB? not really").unwrap();
    let out = tmp("bad-out.sls");
    let e = stderr(&levelset(&["convert", bad.to_str().unwrap(), out.to_str().unwrap()]));
    assert!(e.contains("bad.vdb") && e.contains("not an OpenVDB"), "{e}");
    assert!(!out.exists());
    // A level set without its class is read only by name, which convert does not do.
    let e = stderr(&levelset(&[
        "convert",
        fixture("sphere_zip.vdb").to_str().unwrap(),
        out.to_str().unwrap(),
    ]));
    assert!(e.contains("sphere_zip.vdb") && e.contains("class unknown"), "{e}");
    let f = npy("vdb-opt.npy", &ball([12, 12, 12], [5.5; 3], 3.0, 1.0));
    let e = stderr(&levelset(&[
        "convert",
        f.to_str().unwrap(),
        tmp("x.vdb").to_str().unwrap(),
        "--vdb-compression",
        "blosc",
    ]));
    assert!(e.contains("blosc") && e.contains("zip"), "{e}");
    let e = stderr(&levelset(&["convert", f.to_str().unwrap(), "out.vtk"]));
    assert!(e.contains(".vdb"), "{e}");
}
