//! `levelset convert` and `.sls` files through the command line.

use crate::common::{ball, levelset, npy, stderr, stdout, tmp};

#[test]
fn convert_round_trips_and_every_tool_reads_sls() {
    let b = ball([24, 24, 24], [11.5; 3], 7.0, 1.0);
    let f = npy("conv-ball.npy", &b);
    let (sls, back, ply) = (tmp("conv-ball.sls"), tmp("conv-back.npy"), tmp("conv-ball.ply"));
    let o = levelset(&["convert", f.to_str().unwrap(), sls.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = levelset(&["info", sls.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let grids = j["grids"].as_array().unwrap();
    let band: Vec<u64> = grids.iter().map(|g| g["band_voxels"].as_u64().unwrap()).collect();
    assert!(band[0] > 1000 && band.iter().all(|&n| n == band[0]), "{band:?}");
    let file = std::fs::metadata(&sls).unwrap().len();
    assert_eq!(j["sls_bytes"].as_u64().unwrap(), file);
    // .sls back to dense: the band voxels keep their values bit for bit.
    let o = levelset(&[
        "convert",
        sls.to_str().unwrap(),
        back.to_str().unwrap(),
        "--margin",
        "0",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let d = sparse_levelset::io::npy::read_npy(&back).unwrap();
    // The array starts at the band's lowest corner (margin 0).
    let mut o0 = sparse_levelset::Coord::new(i32::MAX, i32::MAX, i32::MAX);
    for z in 0..24 {
        for y in 0..24 {
            for x in 0..24 {
                if b.get(sparse_levelset::Coord::new(x, y, z)).unwrap().abs() < 3.0 {
                    o0 = sparse_levelset::Coord::new(o0.x.min(x), o0.y.min(y), o0.z.min(z));
                }
            }
        }
    }
    assert_eq!(d.origin(), sparse_levelset::Coord::new(0, 0, 0));
    let mut checked = 0;
    for z in 0..24 {
        for y in 0..24 {
            for x in 0..24 {
                let c = sparse_levelset::Coord::new(x, y, z);
                let v = b.get(c).unwrap();
                if v.abs() < 3.0 {
                    let local = sparse_levelset::Coord::new(x - o0.x, y - o0.y, z - o0.z);
                    assert_eq!(d.get(local).unwrap().to_bits(), v.to_bits(), "{c}");
                    checked += 1;
                }
            }
        }
    }
    assert_eq!(checked as u64, band[0]);
    // Meshing and rendering read the file too.
    let o = levelset(&["convert", sls.to_str().unwrap(), ply.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = levelset(&["mesh", sls.to_str().unwrap(), "-o", ply.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success() && stdout(&o).contains("closed manifold: yes"), "{}", stdout(&o));
}

#[test]
fn a_corrupt_sls_file_gets_one_message_from_every_tool() {
    let b = ball([16, 16, 16], [7.5; 3], 4.5, 1.0);
    let f = npy("corrupt-ball.npy", &b);
    let sls = tmp("corrupt.sls");
    assert!(levelset(&["convert", f.to_str().unwrap(), sls.to_str().unwrap(), "--quiet"])
        .status
        .success());
    let mut bytes = std::fs::read(&sls).unwrap();
    let k = bytes.len() / 2;
    bytes[k] ^= 4;
    std::fs::write(&sls, &bytes).unwrap();
    let s = sls.to_str().unwrap();
    let out = tmp("corrupt-out.npy");
    let ply = tmp("corrupt-out.ply");
    for (tool, o) in [
        ("info", levelset(&["info", s])),
        ("convert", levelset(&["convert", s, out.to_str().unwrap(), "--quiet"])),
        ("mesh", levelset(&["mesh", s, "-o", ply.to_str().unwrap(), "--quiet"])),
    ] {
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{tool}: {e}");
        assert!(e.contains(s) && e.contains("checksum"), "{tool}: {e}");
        assert!(!e.contains("panicked"), "{tool}: {e}");
    }
    assert!(!out.exists() && !ply.exists());
    let e = stderr(&levelset(&["convert", s, "x.vtk"]));
    assert!(e.contains("unknown output type"), "{e}");
}

#[test]
fn memory_table_rows_compare_the_three_grids() {
    let rows = levelset_cli::memtable::analytic_rows(24.0, |_| {}).unwrap();
    assert_eq!(rows.len(), 3);
    for r in &rows[..2] {
        // A closed band: the H-RLE within 15 % of the DT-Grid (Table II: 5–7 %), the file
        // smaller than either in memory.
        assert!(r.hrle_over_dtgrid > 1.0 && r.hrle_over_dtgrid < 1.15, "{r:?}");
        assert!(r.sls_bytes < r.dtgrid_bytes && r.tiles_bytes > r.dtgrid_bytes, "{r:?}");
    }
    // Unenclosed: the open hemisphere costs less than the closed one in a DT-Grid.
    let open = &rows[2];
    assert!(open.hrle_over_dtgrid < 0.9, "{open:?}");
    assert!(2 * open.band_voxels < rows[1].band_voxels + 4000);
}
