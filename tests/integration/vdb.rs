//! OpenVDB `.vdb` files: fixtures written by OpenVDB 10 itself (`tests/data/vdb/`, made by
//! `make_fixtures.py`) read bit for bit; our files read back with the same band and spec;
//! hostile files refused without a panic or a huge allocation.

use crate::common;
use npyz::WriterBuilder;
use sparse_levelset::io::vdb::{self, VdbCompression, VdbError, VdbOptions};
use sparse_levelset::storage::convert::tiles_from_shape;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::{voxel_of, Tile, TileGrid};
use sparse_levelset::{Coord, GridSpec, LevelSet};
use std::path::PathBuf;

/// The error of a refused file (without printing a whole grid when it was read).
fn refused<T>(r: Result<T, VdbError>) -> VdbError {
    match r {
        Ok(_) => panic!("accepted"),
        Err(e) => e,
    }
}

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/vdb").join(name)
}

/// OpenVDB's dump of a fixture's active voxels: (x, y, z, value bits), sorted by (x, y, z).
fn dump(name: &str) -> Vec<([i32; 3], u32)> {
    let bytes = std::fs::read(data(&format!("{name}.npy"))).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    assert_eq!(npy.shape()[1], 4);
    let flat: Vec<i32> = npy.into_vec().unwrap();
    flat.chunks_exact(4).map(|r| ([r[0], r[1], r[2]], r[3] as u32)).collect()
}

fn band(grid: &TileGrid) -> Vec<([i32; 3], u32)> {
    let mut out = Vec::new();
    grid.for_each_band_voxel(&mut |c, v| out.push(([c.x, c.y, c.z], v.to_bits())));
    out.sort_unstable();
    out
}

/// With `VDB_CHECK_DIR` set, writes `NAME.vdb` and `NAME.npy` (the band as the fixtures'
/// dumps: x, y, z, value bits) there, for `check_with_openvdb.py` to compare by hand.
fn for_openvdb(name: &str, grid: &TileGrid, bytes: &[u8]) {
    let Some(dir) = std::env::var_os("VDB_CHECK_DIR") else { return };
    let dir = PathBuf::from(dir);
    std::fs::write(dir.join(format!("{name}.vdb")), bytes).unwrap();
    let rows: Vec<i32> =
        band(grid).iter().flat_map(|(c, v)| [c[0], c[1], c[2], *v as i32]).collect();
    let mut out = Vec::new();
    let mut w = npyz::WriteOptions::<i32>::new()
        .default_dtype()
        .shape(&[rows.len() as u64 / 4, 4])
        .writer(&mut out)
        .begin_nd()
        .unwrap();
    w.extend(rows).unwrap();
    w.finish().unwrap();
    std::fs::write(dir.join(format!("{name}.npy")), out).unwrap();
}

struct Fixture {
    name: &'static str,
    grid: Option<&'static str>,
    voxel_size: f64,
    origin: [f64; 3],
    /// Sphere centre (world) and radius, for the sign of the voxels outside the band.
    centre: [f64; 3],
    radius: f64,
    half_width: f32,
    compression: &'static str,
    half_float: bool,
}

const FIXTURES: [Fixture; 6] = [
    Fixture {
        name: "sphere_blosc",
        grid: None,
        voxel_size: 1.0,
        origin: [0.0; 3],
        centre: [3.5; 3],
        radius: 11.0,
        half_width: 3.0,
        compression: "blosc + active values",
        half_float: false,
    },
    Fixture {
        name: "sphere_none",
        grid: None,
        voxel_size: 0.37,
        origin: [0.25, -0.5, 1.0],
        centre: [10.25, 10.5, 13.0],
        radius: 2.0,
        half_width: 3.0,
        compression: "none",
        half_float: false,
    },
    Fixture {
        name: "sphere_active",
        grid: None,
        voxel_size: 1.0,
        origin: [0.0; 3],
        centre: [-20.0, 30.0, -40.0],
        radius: 5.0,
        half_width: 3.0,
        compression: "active values",
        half_float: false,
    },
    Fixture {
        name: "sphere_zip",
        grid: Some("sphere"),
        voxel_size: 1.0,
        origin: [0.0; 3],
        centre: [-20.5, 30.0, 40.0],
        radius: 5.0,
        half_width: 3.0,
        compression: "zip + active values",
        half_float: false,
    },
    Fixture {
        name: "sphere_half",
        grid: None,
        voxel_size: 1.0,
        origin: [0.0; 3],
        centre: [0.3, -0.2, 0.1],
        radius: 6.0,
        half_width: 3.0,
        compression: "blosc + active values",
        half_float: true,
    },
    Fixture {
        name: "two_grids",
        grid: None,
        voxel_size: 1.0,
        origin: [0.0; 3],
        centre: [8.0; 3],
        radius: 4.0,
        half_width: 2.0,
        compression: "blosc + active values",
        half_float: false,
    },
];

#[test]
fn openvdb_fixtures_read_bit_for_bit_with_the_sign_of_every_other_voxel() {
    for f in &FIXTURES {
        let path = data(&format!("{}.vdb", f.name));
        let (grid, info) = match f.grid {
            Some(name) => vdb::load_grid(&path, name).unwrap(),
            None => vdb::load(&path).unwrap(),
        };
        grid.check_invariants().unwrap();
        let spec = grid.spec();
        assert_eq!(spec.voxel_size as f64, f.voxel_size as f32 as f64, "{}", f.name);
        assert_eq!(info.voxel_size as f32, f.voxel_size as f32, "{}", f.name);
        for a in 0..3 {
            assert!((spec.origin[a] - f.origin[a]).abs() < 1e-12, "{}: {:?}", f.name, spec.origin);
        }
        assert_eq!(spec.half_width, f.half_width, "{}", f.name);
        assert_eq!(spec.gamma(), info.background, "{}", f.name);
        assert_eq!(info.compression, f.compression, "{}", f.name);
        assert_eq!(info.half_float, f.half_float, "{}", f.name);
        assert_eq!(info.file_version, 224);
        let g = spec.gamma();
        // Every active voxel OpenVDB dumped lies in the band, and the band is exactly them,
        // bit for bit.
        let expected = dump(f.name);
        assert!(!expected.is_empty());
        assert!(expected.iter().all(|(_, v)| f32::from_bits(*v).abs() < g), "{}", f.name);
        assert_eq!(info.active_voxels, expected.len() as u64, "{}", f.name);
        let got = band(&grid);
        assert_eq!(got.len(), expected.len(), "{}", f.name);
        assert!(got == expected, "{}: band values differ", f.name);
        // Every other voxel around the sphere reads ±γ by its side.
        let (lo, hi) = grid.bounding_box().unwrap();
        let mut inside = 0;
        for z in lo.z - 4..=hi.z + 4 {
            for y in lo.y - 4..=hi.y + 4 {
                for x in lo.x - 4..=hi.x + 4 {
                    let c = Coord::new(x, y, z);
                    let v = grid.value(c);
                    if v.abs() < g {
                        continue;
                    }
                    let p = spec.world(c);
                    let d = (0..3).map(|a| (p[a] - f.centre[a]).powi(2)).sum::<f64>().sqrt();
                    let want = if d < f.radius { -g } else { g };
                    assert_eq!(v, want, "{} at {c}: distance {d}", f.name);
                    inside += (v < 0.0) as usize;
                }
            }
        }
        assert!(inside > 0, "{}: no inside voxel checked", f.name);
    }
}

#[test]
fn the_interior_of_whole_leaves_is_an_inactive_tile_read_as_inside() {
    // sphere_blosc: the leaf [0, 8)³ lies inside (|x - 3.5| ≤ 4.5√3 < 11 - 3) and is a
    // tile of its lower node, not a leaf.
    let (grid, _) = vdb::load(&data("sphere_blosc.vdb")).unwrap();
    for c in [Coord::new(0, 0, 0), Coord::new(3, 3, 3), Coord::new(7, 7, 7)] {
        assert_eq!(grid.value(c), -3.0, "{c}");
    }
    assert_eq!(grid.value(Coord::new(100, -100, 5)), 3.0);
}

#[test]
fn grid_choice_and_class() {
    // The first level set is chosen over a fog volume; naming the fog volume is refused.
    let (_, info) = vdb::load(&data("two_grids.vdb")).unwrap();
    assert_eq!(info.grid_name, "surface");
    assert_eq!(info.grids.len(), 2, "{:?}", info.grids);
    let err = refused(vdb::load_grid(&data("two_grids.vdb"), "density"));
    assert!(err.to_string().contains("fog volume"), "{err}");
    let err = refused(vdb::load_grid(&data("two_grids.vdb"), "nothing"));
    assert!(
        err.to_string().contains("\"density\"") && err.to_string().contains("surface"),
        "{err}"
    );
    // A grid of class unknown is read only by name.
    let err = refused(vdb::load(&data("sphere_zip.vdb")));
    let msg = err.to_string();
    assert!(msg.contains("sphere_zip.vdb") && msg.contains("class unknown"), "{msg}");
}

fn shapes() -> Vec<(&'static str, Shape, GridSpec)> {
    let unit = GridSpec::default();
    let odd = GridSpec::new(0.37, [1.5, -2.25, 1e3], 2.5).unwrap();
    // Voxel coordinates near the i32 limits: the band stays inside the tile range.
    let far = 2_147_480_000.0;
    vec![
        ("sphere", Shape::Sphere { center: [0.3, 0.1, -0.2], radius: 14.5 }, unit),
        (
            "torus",
            Shape::Torus { center: [-3.0, 2.0, 1.0], major_radius: 12.0, minor_radius: 4.0 },
            unit,
        ),
        ("odd spec", Shape::Sphere { center: [1003.0, 1.0, 1001.0], radius: 3.3 }, odd),
        ("negative", Shape::Sphere { center: [-300.0, -4100.0, -20.0], radius: 9.0 }, unit),
        ("far +", Shape::Sphere { center: [far, far, far], radius: 8.0 }, unit),
        ("far -", Shape::Sphere { center: [-far, -far, 5.0], radius: 8.0 }, unit),
    ]
}

#[test]
fn round_trips_keep_the_band_and_the_spec() {
    for (name, shape, spec) in shapes() {
        let tiles = tiles_from_shape(&shape, spec).unwrap();
        for compression in [VdbCompression::None, VdbCompression::Zip] {
            let opts = VdbOptions { grid_name: "surface".into(), compression };
            let bytes = vdb::encode(&tiles, &opts).unwrap();
            let (back, info) = vdb::decode(&bytes).unwrap();
            back.check_invariants().unwrap();
            assert_eq!(back.spec(), tiles.spec(), "{name}");
            assert_eq!(back.checksum(), tiles.checksum(), "{name} {compression:?}");
            assert_eq!(info.grid_name, "surface");
            assert_eq!(info.active_voxels, tiles.band_voxels() as u64);
            // Every voxel reads the same, band or not.
            let (lo, hi) = tiles.bounding_box().unwrap();
            for z in (lo.z - 2..=hi.z + 2).step_by(3) {
                for y in lo.y - 2..=hi.y + 2 {
                    for x in lo.x - 2..=hi.x + 2 {
                        let c = Coord::new(x, y, z);
                        assert_eq!(back.value(c), tiles.value(c), "{name} at {c}");
                    }
                }
            }
            for_openvdb(&format!("{name}_{compression:?}").replace(' ', "_"), &tiles, &bytes);
            // Equal level sets give equal files.
            assert_eq!(vdb::encode(&back, &opts).unwrap(), bytes, "{name}");
        }
    }
    // Other storages write the same file.
    let (_, shape, spec) = shapes().remove(1);
    let tiles = tiles_from_shape(&shape, spec).unwrap();
    let dt = sparse_levelset::storage::convert::dtgrid_from(&tiles);
    let opts = VdbOptions::default();
    assert_eq!(vdb::encode(&dt, &opts).unwrap(), vdb::encode(&tiles, &opts).unwrap());
}

/// A slab inside between the planes x = 1.5 and x = 12001.5 over the 16 × 16 rows
/// y, z ∈ [0, 16): the band is two small patches 12000 voxels apart, and the rows between
/// them are inside, across a 4096³ root region (a root tile), 128³ regions (upper-node
/// tiles) and 8³ regions (lower-node tiles). (The band does not close the slab in y and
/// z, so a region holding both these rows and others has no one sign; the writer takes
/// the sign of its first voxel, (4096, 0, 0) for the root tile, which is inside.)
fn slab() -> TileGrid {
    let spec = GridSpec::default();
    let g = spec.gamma();
    let phi = |c: Coord| ((1.5 - c.x as f32).max(c.x as f32 - 12001.5)).clamp(-g, g);
    let mut tiles = Vec::new();
    for tz in 0..4 {
        for ty in 0..4 {
            for tx in [-1, 0, 1, 2999, 3000, 3001] {
                let t = Coord::new(tx, ty, tz);
                let mut tile = Tile::splat(0.0);
                for (l, v) in tile.0.iter_mut().enumerate() {
                    *v = phi(voxel_of(t, l));
                }
                tiles.push((t, tile));
            }
        }
    }
    tiles.sort_by_key(|t| t.0);
    TileGrid::from_sorted_tiles(spec, tiles, |t| phi(voxel_of(t, 0)) < 0.0).unwrap()
}

#[test]
fn inside_regions_of_every_size_become_tiles_of_the_right_sign() {
    let tiles = slab();
    let bytes = vdb::encode(&tiles, &VdbOptions::default()).unwrap();
    let (back, _) = vdb::decode(&bytes).unwrap();
    back.check_invariants().unwrap();
    assert_eq!(back.checksum(), tiles.checksum());
    for x in
        [-20, 0, 1, 2, 3, 8, 100, 200, 4095, 4096, 6000, 8191, 8192, 11990, 12001, 12002, 13000]
    {
        for (y, z) in [(0, 0), (15, 15), (7, 0), (16, 0), (0, -1), (5000, 5000)] {
            let c = Coord::new(x, y, z);
            assert_eq!(back.value(c), tiles.value(c), "{c}");
        }
    }
    assert_eq!(back.value(Coord::new(6000, 0, 0)), -3.0);
    // One root tile, at (4096, 0, 0), −γ, inactive: after the transform, the buffer
    // count and the background come the tile and child counts, then the tiles.
    let map = bytes.windows(15).position(|w| w == b"UniformScaleMap").unwrap();
    let root = map + 15 + 5 * 24 + 4;
    let word = |k: usize| bytes[root + 4 * k..root + 4 * k + 4].try_into().unwrap();
    assert_eq!(f32::from_le_bytes(word(0)), 3.0);
    assert_eq!([u32::from_le_bytes(word(1)), u32::from_le_bytes(word(2))], [1, 3]);
    let tile: Vec<i32> = (3..6).map(|k| i32::from_le_bytes(word(k))).collect();
    assert_eq!(tile, [4096, 0, 0]);
    assert_eq!(f32::from_le_bytes(word(6)), -3.0);
    assert_eq!(bytes[root + 28], 0);
    for_openvdb("slab", &tiles, &bytes);
}

#[test]
fn writing_refuses_an_empty_level_set_and_bad_names() {
    let empty = TileGrid::new(GridSpec::default());
    assert!(matches!(vdb::encode(&empty, &VdbOptions::default()), Err(VdbError::Empty)));
    let tiles =
        tiles_from_shape(&Shape::Sphere { center: [0.0; 3], radius: 4.0 }, GridSpec::default())
            .unwrap();
    let bad = VdbOptions { grid_name: String::new(), ..VdbOptions::default() };
    assert!(matches!(vdb::encode(&tiles, &bad), Err(VdbError::Option(_))));
    // An unwritable path leaves nothing behind and names the file.
    let path = common::tmp("vdb-missing-dir").join("nested/out.vdb");
    let err = refused(vdb::save(&path, &tiles, &VdbOptions::default()));
    assert!(err.to_string().contains("out.vdb"), "{err}");
    let err = refused(vdb::save(&common::tmp("empty.vdb"), &empty, &VdbOptions::default()));
    assert!(err.to_string().contains("empty.vdb") && err.to_string().contains("no band voxel"));
    assert!(!common::tmp("empty.vdb").exists());
}

// ---------------------------------------------------------------------------------------
// Hostile files

fn sample() -> (TileGrid, Vec<u8>, Vec<u8>) {
    let tiles = tiles_from_shape(
        &Shape::Sphere { center: [0.3, -0.2, 0.1], radius: 5.5 },
        GridSpec::default(),
    )
    .unwrap();
    let zip =
        vdb::encode(&tiles, &VdbOptions { compression: VdbCompression::Zip, ..Default::default() })
            .unwrap();
    let raw = vdb::encode(
        &tiles,
        &VdbOptions { compression: VdbCompression::None, ..Default::default() },
    )
    .unwrap();
    (tiles, zip, raw)
}

/// The file decodes to a valid level set or is refused; never a panic.
fn survives(bytes: &[u8]) -> bool {
    match vdb::decode(bytes) {
        Ok((g, _)) => {
            g.check_invariants().unwrap();
            true
        }
        Err(e) => {
            assert!(!e.to_string().is_empty());
            false
        }
    }
}

#[test]
fn every_truncation_is_refused() {
    let (_, zip, raw) = sample();
    let openvdb = std::fs::read(data("sphere_blosc.vdb")).unwrap();
    for bytes in [&zip, &raw, &openvdb] {
        for cut in 0..bytes.len() {
            // Every cut point of our small files; a stride over OpenVDB's.
            if bytes.len() > 50_000 && cut % 7 != 0 && cut > 4096 {
                continue;
            }
            let err = vdb::decode(&bytes[..cut]).err();
            assert!(err.is_some(), "a file cut at {cut} of {} was read", bytes.len());
        }
    }
    assert!(matches!(vdb::decode(&zip[..20]), Err(VdbError::Truncated(_))));
    assert!(matches!(vdb::decode(b"not a vdb file at all"), Err(VdbError::NotVdb)));
}

#[test]
fn flipped_bytes_are_refused_or_read_as_valid_level_sets() {
    let (_, zip, raw) = sample();
    let openvdb = std::fs::read(data("sphere_active.vdb")).unwrap();
    // Blosc frames of half floats.
    let blosc = std::fs::read(data("sphere_half.vdb")).unwrap();
    let mut rng = fastrand::Rng::with_seed(7);
    for bytes in [&zip, &raw, &openvdb, &blosc] {
        let stride = if bytes.len() > 50_000 { 41 } else { 13 };
        // Every byte of the header, metadata, transform and root; a stride after.
        for i in (0..bytes.len()).filter(|&i| i < 1024 || i % stride == 0) {
            let mut b = bytes.clone();
            b[i] ^= 1 << rng.u8(0..8);
            survives(&b);
        }
        for _ in 0..200 {
            let mut b = bytes.clone();
            for _ in 0..4 {
                let i = rng.usize(0..b.len());
                b[i] = rng.u8(..);
            }
            survives(&b);
        }
    }
}

/// Offsets of the fields of a file this library wrote with the grid name "level_set".
fn header_end() -> usize {
    8 + 4 + 8 + 1 + 36 + 4 + 4 + (4 + 9) + (4 + 16) + 4 + 24
}

#[test]
fn hostile_counts_versions_and_values_are_refused_with_clear_errors() {
    let (_, zip, raw) = sample();
    // Version.
    let mut b = zip.clone();
    b[8..12].copy_from_slice(&221u32.to_le_bytes());
    let err = refused(vdb::decode(&b));
    assert!(matches!(err, VdbError::Version(221)) && err.to_string().contains("222 to 224"));
    // A grid count of 2^31 - 1.
    let mut b = zip.clone();
    let at = 8 + 4 + 8 + 1 + 36 + 4;
    b[at..at + 4].copy_from_slice(&i32::MAX.to_le_bytes());
    let err = refused(vdb::decode(&b));
    assert!(err.to_string().contains("announces 2147483647 grids"), "{err}");
    // A metadata count of 2^32 - 1 in the grid.
    let mut b = zip.clone();
    let meta = header_end() + 4;
    b[meta..meta + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = refused(vdb::decode(&b));
    assert!(err.to_string().contains("metadata entries"), "{err}");
    // Root tile and child counts of 2^32 - 1: find them after the background γ = 3.
    let bg = raw.windows(12).position(|w| w == [0, 0, 0x40, 0x40, 0, 0, 0, 0, 8, 0, 0, 0]).unwrap();
    for (k, what) in [(4, "root tiles"), (8, "root children")] {
        let mut b = raw.clone();
        b[bg + k..bg + k + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = refused(vdb::decode(&b));
        assert!(err.to_string().contains(&format!("announces 4294967295 {what}")), "{err}");
    }
    // A grid name of 2^32 - 1 bytes, grid offsets past the end, a compressed block of
    // 2^40 bytes, a NaN or infinite background.
    let mut b = zip.clone();
    let name = 8 + 4 + 8 + 1 + 36 + 4 + 4;
    b[name..name + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(refused(vdb::decode(&b)), VdbError::Truncated(_)));
    let mut b = zip.clone();
    let end = header_end() - 8;
    b[end..end + 8].copy_from_slice(&(1i64 << 40).to_le_bytes());
    let err = refused(vdb::decode(&b));
    assert!(err.to_string().contains("outside the file"), "{err}");
    let mut b = zip.clone();
    let block = i64::from_le_bytes(b[header_end() - 16..header_end() - 8].try_into().unwrap());
    let size = block as usize + 64 + 1 + if b[block as usize + 64] == 3 { 64 } else { 0 };
    b[size..size + 8].copy_from_slice(&(1i64 << 40).to_le_bytes());
    let err = refused(vdb::decode(&b));
    assert!(err.to_string().contains("announces 1099511627776 compressed bytes"), "{err}");
    for (v, what) in [(f32::NAN, "NaN"), (f32::INFINITY, "positive")] {
        let mut b = raw.clone();
        b[bg..bg + 4].copy_from_slice(&v.to_le_bytes());
        let err = refused(vdb::decode(&b));
        assert!(err.to_string().contains(what), "{err}");
    }
    // A NaN value, in the raw file's first leaf buffer: its active values follow the
    // leaf's mask and the compression byte.
    let (grid, _) = vdb::decode(&raw).unwrap();
    let mut b = raw.clone();
    let block =
        i64::from_le_bytes(b[header_end() - 16..header_end() - 8].try_into().unwrap()) as usize;
    // Mask, compression byte, and the selection mask of a leaf holding both signs.
    let first = block + 64 + 1 + if b[block + 64] == 3 { 64 } else { 0 };
    b[first..first + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let err = refused(vdb::decode(&b));
    assert!(matches!(err, VdbError::NaN { .. }), "{err}");
    assert!(err.to_string().contains("NaN at voxel"), "{err}");
    // ±∞ are clamped to ±γ: no longer band voxels.
    let mut b = raw.clone();
    b[first..first + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
    let (inf, _) = vdb::decode(&b).unwrap();
    assert_eq!(inf.band_voxels() + 1, grid.band_voxels());
    // A background of one voxel is not a level set's band.
    let mut b = raw.clone();
    b[bg..bg + 4].copy_from_slice(&1.0f32.to_le_bytes());
    let err = refused(vdb::decode(&b));
    assert!(err.to_string().contains("half-width must exceed 1"), "{err}");
    // A non-uniform scale.
    let mut b = raw.clone();
    let map = header_end()
        + raw[header_end()..].windows(15).position(|w| w == b"UniformScaleMap").unwrap();
    let sy = map + 15 + 8;
    b[sy..sy + 8].copy_from_slice(&2.0f64.to_le_bytes());
    let err = refused(vdb::decode(&b));
    assert!(err.to_string().contains("uniform scale"), "{err}");
    // No active voxel: every leaf mask cleared (topology and buffers).
    let mut b = raw.clone();
    let masks: Vec<usize> = {
        let (tiles, _) = vdb::decode(&raw).unwrap();
        assert!(tiles.band_voxels() > 0);
        let mut at = block;
        let mut v = Vec::new();
        while at < raw.len() {
            let active: u32 = (0..8)
                .map(|w| {
                    u64::from_le_bytes(raw[at + 8 * w..at + 8 * w + 8].try_into().unwrap())
                        .count_ones()
                })
                .sum();
            v.push(at);
            let selection = if (3..=5).contains(&raw[at + 64]) { 64 } else { 0 };
            at += 64 + 1 + selection + 4 * active as usize;
        }
        v
    };
    for &at in &masks {
        b[at..at + 64].fill(0);
        b[at + 64] = 0; // the compression byte: all values +γ
    }
    // The buffers shrank: rebuild the leaf section without values.
    let mut shrunk = b[..block].to_vec();
    for _ in &masks {
        shrunk.extend_from_slice(&[0u8; 64]);
        shrunk.push(0);
    }
    let end = shrunk.len() as i64;
    let e = header_end() - 8;
    shrunk[e..e + 8].copy_from_slice(&end.to_le_bytes());
    let err = refused(vdb::decode(&shrunk));
    assert!(matches!(err, VdbError::NoInterface), "{err}");
    assert!(err.to_string().contains("no interface"), "{err}");
}

/// A vector grid written by OpenVDB (`Vec3s`, Blosc, behind a float grid, with an active
/// tile) reads as the dense box OpenVDB's own `copyToArray` gives, value for value, placed
/// by its transform.
#[test]
fn openvdb_vector_grid_reads_as_openvdb_does() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/vdb");
    let g = sparse_levelset::io::vdb::load_vector_grid(&dir.join("velocity.vdb"), None).unwrap();
    let want = sparse_levelset::io::npy::read_npy_vector(&dir.join("velocity.npy")).unwrap();
    assert_eq!(g.name, "velocity");
    assert_eq!((g.voxel_size, g.origin), (0.5, [0.25, -0.5, 1.0]));
    for (got, want) in g.components.iter().zip(&want) {
        assert_eq!(got.origin(), Coord::new(-4, 0, 0));
        assert_eq!(got.dims(), want.dims());
        assert_eq!(got.data(), want.data());
    }
    // The tile's value, and a voxel of the rotation: u(x, y, z) = (−0.3 (y − 8), 0.3 (x − 4), 0.05 z + 0.125).
    let at = |c: Coord| g.components.each_ref().map(|f| f.get(c).unwrap());
    assert_eq!(at(Coord::new(20, 3, 5)), [1.0, 2.0, 3.0]);
    assert_eq!(at(Coord::new(1, 10, 4)), [-0.3 * 2.0, 0.3 * -3.0, 0.05 * 4.0 + 0.125]);
    // By name; a float grid is not a vector grid.
    assert!(sparse_levelset::io::vdb::load_vector_grid(
        &dir.join("velocity.vdb"),
        Some("velocity")
    )
    .is_ok());
    let e = sparse_levelset::io::vdb::load_vector_grid(&dir.join("velocity.vdb"), Some("density"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a vector grid"), "{e}");
    let e = sparse_levelset::io::vdb::load_vector_grid(&dir.join("sphere_blosc.vdb"), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no vector grid (type Tree_vec3s_5_4_3) in the file"), "{e}");
    // Every prefix of the file is refused, never a panic.
    let bytes = std::fs::read(dir.join("velocity.vdb")).unwrap();
    for cut in (0..bytes.len()).step_by(97) {
        assert!(sparse_levelset::io::vdb::decode_vector_grid(&bytes[..cut], None).is_err());
    }
}

/// Random corruption of an OpenVDB-written vector grid (bytes flipped anywhere: counts,
/// masks, compressed blocks, values) is refused or read, never a panic, and never an
/// allocation beyond what the machine can give.
#[test]
fn corrupted_vector_grids_never_panic() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/vdb");
    let full = std::fs::read(dir.join("velocity.vdb")).unwrap();
    let mut rng = fastrand::Rng::with_seed(29);
    for _ in 0..1500 {
        let mut b = full.clone();
        for _ in 0..rng.usize(1..5) {
            let i = rng.usize(0..b.len());
            b[i] = rng.u8(..);
        }
        let r = std::panic::catch_unwind(|| vdb::decode_vector_grid(&b, None).map(|_| ()));
        assert!(r.is_ok(), "a corrupted vector grid panicked");
    }
}
