//! The `.sls` format: round trips bit for bit between every grid, atomic writes, refusals.

use crate::common::crc32;
use sparse_levelset::io::sls::{self, SlsError, Source, HEADER_BYTES, MAGIC};
use sparse_levelset::storage::convert::{dtgrid_from, tiles_from, tiles_from_shape};
use sparse_levelset::storage::hrle::{FieldData, HrleGrid};
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::{Accessor, Coord, GridSpec, LevelSet};

fn torus() -> sparse_levelset::storage::tiles::TileGrid {
    let spec = GridSpec::new(0.5, [1.0, -2.0, 0.25], 3.0).unwrap();
    let t = Shape::Torus { center: [1.2, -1.9, 0.4], major_radius: 6.0, minor_radius: 2.2 };
    tiles_from_shape(&t, spec).unwrap()
}

fn same_everywhere(a: &impl LevelSet, b: &impl LevelSet) {
    assert_eq!(a.spec(), b.spec());
    assert_eq!(a.checksum(), b.checksum());
    let (lo, hi) = a.band_bounding_box().unwrap();
    let mut acc = b.accessor();
    for z in lo.z - 3..=hi.z + 3 {
        for y in lo.y - 3..=hi.y + 3 {
            for x in lo.x - 3..=hi.x + 3 {
                let c = Coord::new(x, y, z);
                assert_eq!(a.value(c).to_bits(), acc.value(c).to_bits(), "{c}");
            }
        }
    }
}

#[test]
fn every_grid_round_trips_through_sls_into_every_grid() {
    let tiles = torus();
    let dt = dtgrid_from(&tiles);
    let h = HrleGrid::from_level_set(&tiles).unwrap();
    for (bytes, source) in [
        (sls::encode_level_set(&tiles).unwrap(), Source::Tiles),
        (sls::encode_level_set(&dt).unwrap(), Source::DtGrid),
        (sls::encode_level_set(&h).unwrap(), Source::Hrle),
    ] {
        let (back, header) = sls::decode(&bytes).unwrap();
        assert_eq!(header.source, source);
        assert_eq!(back, h);
        same_everywhere(&back, &tiles);
        same_everywhere(&tiles_from(&back), &tiles);
        same_everywhere(&dtgrid_from(&back), &dt);
    }
    // The file is smaller than the DT-Grid in memory.
    let bytes = sls::encode(&h, Source::Hrle);
    assert!(bytes.len() < dt.memory().used(), "{} bytes", bytes.len());
}

#[test]
fn clipped_grids_and_fields_survive_a_file() {
    let tiles = torus();
    let mut h = HrleGrid::from_level_set(&tiles)
        .unwrap()
        .clip(Coord::new(-100, -100, -100), Coord::new(3, 100, 100))
        .unwrap();
    h.add_scalar_field("temperature", |c, v| c.x as f32 * 0.5 + v).unwrap();
    h.add_vector_field("velocity", |c, _| [c.y as f32, -1.5, f32::MIN_POSITIVE]).unwrap();
    let dir = std::env::temp_dir().join(format!("sls-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("clipped.sls");
    sls::save(&path, &h).unwrap();
    let (back, header) = sls::load(&path).unwrap();
    assert_eq!(back, h);
    assert_eq!(header.domain, h.domain());
    assert_eq!(header.fields, 2);
    assert!(
        matches!(&back.field("velocity").unwrap().data, FieldData::Vector(v) if v.len() == h.len())
    );
    // A failed write leaves the old file as it was.
    let before = std::fs::read(&path).unwrap();
    let e = sls::save(&dir.join("missing-dir").join("x.sls"), &h).unwrap_err();
    assert!(matches!(e, SlsError::Io { .. }));
    assert_eq!(std::fs::read(&path).unwrap(), before);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A header with valid checksum claiming `values` voxels, and nothing else.
fn hostile(values: u64, runs: [u64; 3]) -> Vec<u8> {
    let h = HrleGrid::new(GridSpec::default());
    let mut b = sls::encode(&h, Source::Hrle);
    b.truncate(HEADER_BYTES);
    let at = HEADER_BYTES - 4 - 24 - 8;
    b[at..at + 8].copy_from_slice(&values.to_le_bytes());
    for k in 0..3 {
        b[at + 8 + 8 * k..at + 16 + 8 * k].copy_from_slice(&runs[k].to_le_bytes());
    }
    b.extend_from_slice(&[0, 1]);
    let crc = crc32(&b);
    b.extend_from_slice(&crc.to_le_bytes());
    b
}

#[test]
fn a_tiny_file_claiming_a_huge_band_is_refused_before_allocating() {
    for (values, runs) in
        [(1u64 << 40, [1, 1, 1]), (0, [u64::MAX, 1, 1]), (1 << 20, [1 << 30, 3, 3])]
    {
        let b = hostile(values, runs);
        assert!(b.len() < 150);
        let e = sls::decode(&b).unwrap_err();
        assert!(matches!(e, SlsError::Corrupt(ref m) if m.contains("announces")), "{e}");
    }
    // The same layout with honest counts is an empty level set.
    let (g, _) = sls::decode(&hostile(0, [1, 0, 0])).unwrap();
    assert!(g.is_empty());
}

#[test]
fn each_kind_of_bad_file_has_its_message() {
    let h = HrleGrid::from_level_set(&torus()).unwrap();
    let good = sls::encode(&h, Source::Hrle);
    assert!(matches!(sls::decode(b"P6\n"), Err(SlsError::NotSls)));
    assert!(matches!(sls::decode(&good[..5]), Err(SlsError::NotSls)));
    assert!(matches!(sls::decode(&good[..20]), Err(SlsError::Truncated(_))));
    let mut v2 = good.clone();
    v2[8] = 2;
    assert!(matches!(sls::decode(&v2), Err(SlsError::Version(2))));
    let mut flip = good.clone();
    let k = good.len() / 2;
    flip[k] ^= 0x10;
    assert!(matches!(sls::decode(&flip), Err(SlsError::Checksum { .. })));
    assert!(matches!(sls::decode(&good[..good.len() - 9]), Err(SlsError::Checksum { .. })));
    // A NaN value with a valid checksum is refused by the structure check.
    let mut nan = good[..good.len() - 4].to_vec();
    let first_value = nan.len() - 4 * h.len();
    nan[first_value..first_value + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let crc = crc32(&nan);
    nan.extend_from_slice(&crc.to_le_bytes());
    let e = sls::decode(&nan).unwrap_err();
    assert!(matches!(e, SlsError::Corrupt(ref m) if m.contains("NaN")), "{e}");
    // A missing file names itself.
    let e = sls::load(std::path::Path::new("/nonexistent/x.sls")).unwrap_err();
    assert!(e.to_string().contains("/nonexistent/x.sls"));
    assert_eq!(&good[..8], &MAGIC);
}
