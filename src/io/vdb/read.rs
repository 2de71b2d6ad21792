//! The reader: header, grid descriptors, the chosen grid's metadata, transform, topology
//! and leaf buffers, then the band as 4³ tiles (see the [module docs](super)).

use super::write::{bit, node_origin, slot, slot_offset};
use super::write::{LEAF_LOG2, LEAF_TOTAL, LOWER_LOG2, LOWER_TOTAL, UPPER_LOG2, UPPER_TOTAL};
use super::MIN_FILE_VERSION;
use super::{blosc, compression_name, spec_from, VdbError, VdbInfo};
use super::{COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC, COMPRESS_ZIP, FILE_VERSION, MAGIC};
use crate::coord::Coord;
use crate::io::bytes::{ByteReader as Reader, ReadError};
use crate::storage::dense::DenseField;
use crate::storage::tiles::{voxel_of, Tile, TileGrid};
use rayon::prelude::*;
use std::collections::HashMap;
use std::io::Read;

type Res<T> = Result<T, VdbError>;

fn corrupt<T>(m: impl Into<String>) -> Res<T> {
    Err(VdbError::Corrupt(m.into()))
}

impl From<ReadError> for VdbError {
    fn from(e: ReadError) -> VdbError {
        match e {
            ReadError::Truncated(what) => VdbError::Truncated(what),
            ReadError::TooMany { n, what, left } => VdbError::Corrupt(format!(
                "the file announces {n} {what}, more than the {left} bytes left can hold"
            )),
            ReadError::Overlong(what) => {
                VdbError::Corrupt(format!("an over-long number in {what}"))
            }
        }
    }
}

/// One entry of the file's grid list.
struct GridEntry {
    name: String,
    type_name: String,
    class: String,
    parent: String,
    /// Where the grid's compression flags start, and where it ends (0 when the file has
    /// no offsets).
    pos: usize,
    end: usize,
}

impl GridEntry {
    fn describe(&self) -> String {
        format!("{:?} ({}, class {})", self.name, self.type_name, self.class)
    }
}

/// The grid metadata read: class, name, half floats; every other entry is skipped.
struct Meta {
    class: String,
    name: Option<String>,
}

fn read_meta(r: &mut Reader) -> Res<Meta> {
    let n = r.u32("the metadata")?;
    let n = r.count(n as u64, 12, "metadata entries")?;
    let mut meta = Meta { class: "unknown".into(), name: None };
    for _ in 0..n {
        let name = r.string("a metadata name")?;
        let type_name = r.string("a metadata type")?;
        let size = r.u32("a metadata value")? as usize;
        let value = r.take(size, "a metadata value")?;
        if type_name == "string" {
            let s = String::from_utf8_lossy(value).into_owned();
            match name.as_str() {
                "class" => meta.class = s,
                "name" => meta.name = Some(s),
                _ => {}
            }
        }
    }
    Ok(meta)
}

/// The state a grid's values are read with.
struct Ctx {
    flags: u32,
    half: bool,
    /// The background value: its first `comps` entries (1 for a float grid, 3 for a
    /// vector grid).
    background: [f32; 3],
    comps: usize,
}

fn half_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as u32;
    let man = (h & 0x3ff) as u32;
    match exp {
        // Zero and subnormals: man × 2⁻²⁴, exact in f32.
        0 => sign * man as f32 * f32::from_bits(0x3380_0000),
        31 => f32::from_bits(((h as u32 & 0x8000) << 16) | 0x7f80_0000 | (man << 13)),
        _ => f32::from_bits(((h as u32 & 0x8000) << 16) | ((exp + 112) << 23) | (man << 13)),
    }
}

/// OpenVDB's `readData`: `count` values (of `ctx.comps` numbers each), raw, zlib- or
/// Blosc-compressed (each compressed chunk after its `i64` size, negative for a chunk
/// stored raw).
fn read_data(r: &mut Reader, ctx: &Ctx, count: usize) -> Res<Vec<f32>> {
    // Half floats: OpenVDB writes nothing at all for an empty buffer.
    if count == 0 && ctx.half {
        return Ok(Vec::new());
    }
    let elem = if ctx.half { 2 } else { 4 };
    let bytes = count * ctx.comps * elem;
    let owned;
    let raw: &[u8] = if ctx.flags & (COMPRESS_BLOSC | COMPRESS_ZIP) != 0 {
        let size = r.i64("a compressed block's size")?;
        if size <= 0 {
            if size.unsigned_abs() != bytes as u64 {
                return corrupt(format!(
                    "a stored block of {} bytes where {bytes} were expected",
                    size.unsigned_abs()
                ));
            }
            r.take(bytes, "a node's values")?
        } else {
            let n = r.count(size as u64, 1, "compressed bytes")?;
            let chunk = r.take(n, "a node's values")?;
            owned = if ctx.flags & COMPRESS_BLOSC != 0 {
                blosc::decompress(chunk, bytes).map_err(VdbError::Corrupt)?
            } else {
                let mut out = Vec::with_capacity(bytes);
                let ok = flate2::read::ZlibDecoder::new(chunk)
                    .take(bytes as u64 + 1)
                    .read_to_end(&mut out)
                    .is_ok();
                if !ok || out.len() != bytes {
                    return corrupt(format!(
                        "a zlib block that does not decode to the {bytes} bytes of its node"
                    ));
                }
                out
            };
            &owned
        }
    } else {
        r.take(bytes, "a node's values")?
    };
    Ok(if ctx.half {
        raw.chunks_exact(2).map(|c| half_to_f32(u16::from_le_bytes([c[0], c[1]]))).collect()
    } else {
        raw.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("4"))).collect()
    })
}

/// OpenVDB's `readCompressedValues`: the mask-compression byte, the inactive values and
/// selection mask it announces, the stored values, and the node's `n` values rebuilt
/// (`n · ctx.comps` numbers, the components of a value adjacent).
fn read_values(r: &mut Reader, ctx: &Ctx, n: usize, active: &[u64]) -> Res<Vec<f32>> {
    let metadata = r.u8("a node's compression byte")?;
    if metadata > 6 {
        return corrupt(format!("unknown mask compression {metadata}"));
    }
    let k = ctx.comps;
    let bg = ctx.background;
    let mut inactive = [if metadata == 0 { bg } else { bg.map(|v| -v) }, bg];
    if matches!(metadata, 2 | 4 | 5) {
        for v in &mut inactive[0][..k] {
            *v = r.f32("a node's inactive value")?;
        }
        if metadata == 5 {
            for v in &mut inactive[1][..k] {
                *v = r.f32("a node's inactive value")?;
            }
        }
    }
    let selection =
        if matches!(metadata, 3..=5) { r.mask(n, "a selection mask")? } else { vec![0; n / 64] };
    let masked = ctx.flags & COMPRESS_ACTIVE_MASK != 0 && metadata != 6;
    let count = if masked { active.iter().map(|w| w.count_ones() as usize).sum() } else { n };
    let stored = read_data(r, ctx, count)?;
    if count == n {
        return Ok(stored);
    }
    if k == 1 {
        // A float grid: one number a value.
        let mut it = stored.into_iter();
        return Ok((0..n)
            .map(|i| {
                if bit(active, i) {
                    it.next().expect("one stored value per active bit")
                } else {
                    inactive[bit(&selection, i) as usize][0]
                }
            })
            .collect());
    }
    let mut it = stored.chunks_exact(k);
    let mut out = Vec::with_capacity(n * k);
    for i in 0..n {
        if bit(active, i) {
            out.extend_from_slice(it.next().expect("one stored value per active bit"));
        } else {
            out.extend_from_slice(&inactive[bit(&selection, i) as usize][..k]);
        }
    }
    Ok(out)
}

/// An internal node as the reader keeps it: which slots hold children, and which of the
/// others are inside (negative).
struct Internal {
    inside: Vec<u64>,
}

struct Tree {
    root_tiles: HashMap<[i32; 3], bool>,
    uppers: HashMap<[i32; 3], Internal>,
    lowers: HashMap<[i32; 3], Internal>,
    /// Leaves in file order: origin and value mask (values come with the buffers).
    leaves: Vec<([i32; 3], Vec<u64>)>,
}

#[inline]
fn add(o: [i32; 3], d: [i32; 3]) -> [i32; 3] {
    [o[0] + d[0], o[1] + d[1], o[2] + d[2]]
}

fn coord(c: [i32; 3]) -> Coord {
    Coord::new(c[0], c[1], c[2])
}

/// Refuses a NaN, and an active tile whose value lies inside the band. `at` gives the
/// tile's origin, asked for only to name it in an error: a node's tiles are checked in a
/// loop over its 32³ or 16³ slots.
fn check_tile(
    v: f32,
    active: bool,
    at: impl FnOnce() -> [i32; 3],
    ctx: &Ctx,
    span: u32,
) -> Res<()> {
    if v.is_nan() {
        return Err(VdbError::NaN { coord: coord(at()) });
    }
    if active && v.abs() < ctx.background[0] {
        let (n, at) = (1u64 << span, at());
        return Err(VdbError::Unsupported(format!(
            "an active tile of {n}³ voxels at {} with the value {v} inside the band: a level \
             set keeps its band in leaf voxels (convert it with OpenVDB's \
             tools::sdfToSdf or voxelize its active tiles first)",
            coord(at)
        )));
    }
    Ok(())
}

/// An internal node's topology (masks, slot values, then its children's topology).
fn read_internal(
    r: &mut Reader,
    ctx: &Ctx,
    tree: &mut Tree,
    origin: [i32; 3],
    upper: bool,
) -> Res<()> {
    let (log2, child_total) =
        if upper { (UPPER_LOG2, LOWER_TOTAL) } else { (LOWER_LOG2, LEAF_TOTAL) };
    let n = 1usize << (3 * log2);
    let child = r.mask(n, "an internal node's child mask")?;
    let active = r.mask(n, "an internal node's value mask")?;
    let values = read_values(r, ctx, n, &active)?;
    let mut inside = vec![0u64; n / 64];
    for (i, &v) in values.iter().enumerate() {
        let at = || add(origin, slot_offset(i, log2, child_total));
        if bit(&child, i) {
            if bit(&active, i) {
                return corrupt(format!(
                    "a slot at {} is both a child and an active tile",
                    coord(at())
                ));
            }
            continue;
        }
        check_tile(v, bit(&active, i), at, ctx, child_total)?;
        if v < 0.0 {
            inside[i >> 6] |= 1 << (i & 63);
        }
    }
    for i in 0..n {
        if !bit(&child, i) {
            continue;
        }
        let at = add(origin, slot_offset(i, log2, child_total));
        if upper {
            // A lower node takes at least its two masks and a compression byte.
            r.count(1, 2 * 512 + 1, "internal nodes")?;
            read_internal(r, ctx, tree, at, false)?;
        } else {
            let mask = r.mask(512, "a leaf's value mask")?;
            tree.leaves.push((at, mask));
        }
    }
    let node = Internal { inside };
    if upper {
        tree.uppers.insert(origin, node);
    } else {
        tree.lowers.insert(origin, node);
    }
    Ok(())
}

fn list(grids: &[GridEntry]) -> String {
    if grids.is_empty() {
        return "it holds no grid".into();
    }
    let names: Vec<String> = grids.iter().map(GridEntry::describe).collect();
    format!("its grids: {}", names.join(", "))
}

/// A grid of the file opened: the reader at the start of its tree, and what came before.
struct Opened<'a> {
    r: Reader<'a>,
    grids: Vec<GridEntry>,
    /// Index of the chosen grid in `grids`.
    chosen: usize,
    offsets: bool,
    version: u32,
    library_version: (u32, u32),
    flags: u32,
    half: bool,
    meta: Meta,
    translation: [f64; 3],
    scale: f64,
}

/// Reads the header and the grid list, lets `choose` pick a grid (its index, or the error
/// that none fits), and reads that grid's flags, metadata and transform.
fn open_grid<'a>(
    bytes: &'a [u8],
    choose: impl FnOnce(&[GridEntry]) -> Res<usize>,
) -> Res<Opened<'a>> {
    let mut r = Reader { b: bytes, at: 0 };
    if bytes.len() < 8 || i64::from_le_bytes(bytes[..8].try_into().expect("8")) != MAGIC {
        return Err(VdbError::NotVdb);
    }
    r.at = 8;
    let version = r.u32("the header")?;
    if !(MIN_FILE_VERSION..=FILE_VERSION).contains(&version) {
        return Err(VdbError::Version(version));
    }
    let library_version = (r.u32("the header")?, r.u32("the header")?);
    let offsets = r.u8("the header")? != 0;
    r.take(36, "the header's UUID")?;
    read_meta(&mut r)?; // file metadata: nothing needed
    let ngrids = r.i32("the grid count")?;
    if ngrids < 0 {
        return corrupt(format!("a negative grid count {ngrids}"));
    }
    let ngrids = r.count(ngrids as u64, 12, "grids")?;
    let mut grids = Vec::with_capacity(ngrids);
    for _ in 0..ngrids {
        let unique = r.string("a grid descriptor")?;
        let type_name = r.string("a grid descriptor")?;
        let parent = r.string("a grid descriptor")?;
        // A duplicate name carries a suffix after U+001E.
        let name = unique.split('\x1e').next().unwrap_or("").to_string();
        let mut e = GridEntry { name, type_name, class: "unknown".into(), parent, pos: 0, end: 0 };
        if !offsets {
            // A stream: the grid follows its descriptor and cannot be skipped.
            e.pos = r.at;
            let mut m = Reader { b: bytes, at: e.pos };
            m.u32("a grid's compression flags")?;
            e.class = read_meta(&mut m)?.class;
            grids.push(e);
            break;
        }
        let (pos, block, end) =
            (r.i64("a grid descriptor")?, r.i64("a grid descriptor")?, r.i64("a grid descriptor")?);
        let len = bytes.len() as i64;
        if !((r.at as i64) <= pos && pos <= block && block <= end && end <= len) {
            return corrupt(format!(
                "grid {:?}: offsets {pos}, {block}, {end} outside the file's {len} bytes",
                e.name
            ));
        }
        (e.pos, e.end) = (pos as usize, end as usize);
        if e.parent.is_empty() {
            let mut m = Reader { b: bytes, at: e.pos };
            m.u32("a grid's compression flags")?;
            e.class = read_meta(&mut m)?.class;
        }
        grids.push(e);
        r.at = end as usize;
    }
    let index = choose(&grids)?;
    let chosen = &grids[index];
    if !chosen.parent.is_empty() {
        return Err(VdbError::Unsupported(format!(
            "grid {:?} is an instance of grid {:?} (shares its tree): read that grid instead",
            chosen.name, chosen.parent
        )));
    }
    let half = chosen.type_name.ends_with("_HalfFloat");
    let mut r = Reader { b: bytes, at: chosen.pos };
    let flags = r.u32("a grid's compression flags")?;
    if flags & !(COMPRESS_ZIP | COMPRESS_ACTIVE_MASK | COMPRESS_BLOSC) != 0 {
        return Err(VdbError::Unsupported(format!("unknown compression flags {flags:#x}")));
    }
    let meta = read_meta(&mut r)?;
    // Transform.
    let map = r.string("the transform")?;
    let (translation, scale) = match map.as_str() {
        "UniformScaleMap" | "ScaleMap" => ([0.0; 3], r.vec3d("the transform")?),
        "UniformScaleTranslateMap" | "ScaleTranslateMap" => {
            (r.vec3d("the transform")?, r.vec3d("the transform")?)
        }
        "TranslationMap" => (r.vec3d("the transform")?, [1.0; 3]),
        other => {
            return Err(VdbError::Unsupported(format!(
                "the grid's transform is a {other}; only uniform scale and translation maps \
                 (axis-aligned cubic voxels) can be read: resample the grid with OpenVDB first"
            )))
        }
    };
    if map.contains("Scale") {
        r.take(4 * 24, "the transform")?; // voxel size, inverse scale, 1/s², 1/(2s)
    }
    let s = scale[0];
    if !(s.is_finite() && s > 0.0) || scale.iter().any(|&t| (t - s).abs() > 1e-9 * s) {
        return Err(VdbError::Unsupported(format!(
            "voxel size {scale:?}: voxels must be cubes with a positive edge (a uniform scale)"
        )));
    }
    if translation.iter().any(|t| !t.is_finite()) {
        return corrupt(format!("a transform translation {translation:?}"));
    }
    Ok(Opened {
        r,
        chosen: index,
        offsets,
        version,
        library_version,
        flags,
        half,
        meta,
        translation,
        scale: s,
        grids,
    })
}

/// The grid named `want` or the first one `fits`, refused with `what` (a description of
/// the grids wanted) when it does not fit.
fn choose_grid(
    grids: &[GridEntry],
    want: Option<&str>,
    fits: impl Fn(&GridEntry) -> bool,
    what: &str,
) -> Res<usize> {
    match want {
        Some(name) => {
            let Some(i) = grids.iter().position(|e| e.name == name) else {
                return Err(VdbError::NoGrid(format!(
                    "no grid named {name:?} in the file ({})",
                    list(grids)
                )));
            };
            if !fits(&grids[i]) {
                return Err(VdbError::NoGrid(format!(
                    "grid {} is not a {what}",
                    grids[i].describe()
                )));
            }
            Ok(i)
        }
        None => grids
            .iter()
            .position(&fits)
            .ok_or_else(|| VdbError::NoGrid(format!("no {what} in the file ({})", list(grids)))),
    }
}

pub(super) fn decode(bytes: &[u8], want: Option<&str>) -> Res<(TileGrid, VdbInfo)> {
    let is_float = |e: &GridEntry| {
        e.type_name == "Tree_float_5_4_3" || e.type_name == "Tree_float_5_4_3_HalfFloat"
    };
    let level_set = |e: &GridEntry| is_float(e) && e.class == "level set";
    let named = |e: &GridEntry| is_float(e) && (e.class == "level set" || e.class == "unknown");
    let Opened {
        mut r,
        grids,
        chosen,
        offsets,
        version,
        library_version,
        flags,
        half,
        meta,
        translation,
        scale,
    } = match want {
        Some(_) => open_grid(bytes, |g| {
            choose_grid(
                g,
                want,
                named,
                "float level set (type Tree_float_5_4_3, class level set or unknown)",
            )
        })?,
        None => open_grid(bytes, |g| {
            choose_grid(g, None, level_set, "float grid of class \"level set\"").map_err(|e| match e {
                VdbError::NoGrid(m) => VdbError::NoGrid(format!(
                    "{m}; a level set written without its class can be read by name (vdb::load_grid)"
                )),
                e => e,
            })
        })?,
    };
    let chosen = &grids[chosen];
    let s = scale;
    // Topology.
    let buffers = r.i32("the tree")?;
    if buffers != 1 {
        return Err(VdbError::Unsupported(format!(
            "{buffers} buffers per leaf (OpenVDB writes 1)"
        )));
    }
    let background = r.f32("the tree")?;
    if background.is_nan() {
        return corrupt("the background value is NaN");
    }
    if !(background > 0.0 && background.is_finite()) {
        return Err(VdbError::Unsupported(format!(
            "the background value {background}: a level set's background (its band's half-width \
             in world units) is positive"
        )));
    }
    let voxel_size = s as f32;
    let spec = spec_from(voxel_size, translation, background)?;
    let g = spec.gamma();
    let ctx = Ctx { flags, half, background: [background, 0.0, 0.0], comps: 1 };
    let ntiles = r.u32("the tree")?;
    let nchildren = r.u32("the tree")?;
    let ntiles = r.count(ntiles as u64, 17, "root tiles")?;
    let nchildren = r.count(nchildren as u64, 12 + 2 * 4096 + 1, "root children")?;
    let mut tree = Tree {
        root_tiles: HashMap::new(),
        uppers: HashMap::new(),
        lowers: HashMap::new(),
        leaves: Vec::new(),
    };
    let aligned = |o: [i32; 3]| o == node_origin(o, UPPER_TOTAL);
    for _ in 0..ntiles {
        let o = [r.i32("a root tile")?, r.i32("a root tile")?, r.i32("a root tile")?];
        let v = r.f32("a root tile")?;
        let active = r.u8("a root tile")? != 0;
        if !aligned(o) {
            return corrupt(format!("a root tile at {} off the 4096-voxel grid", coord(o)));
        }
        check_tile(v, active, || o, &ctx, UPPER_TOTAL)?;
        if tree.root_tiles.insert(o, v < 0.0).is_some() {
            return corrupt(format!("two root tiles at {}", coord(o)));
        }
    }
    for _ in 0..nchildren {
        let o = [r.i32("a root child")?, r.i32("a root child")?, r.i32("a root child")?];
        if !aligned(o) {
            return corrupt(format!("a root child at {} off the 4096-voxel grid", coord(o)));
        }
        if tree.uppers.contains_key(&o) || tree.root_tiles.contains_key(&o) {
            return corrupt(format!("two root entries at {}", coord(o)));
        }
        read_internal(&mut r, &ctx, &mut tree, o, true)?;
    }
    // Buffers: each leaf's mask again, then its values.
    let mut values: Vec<Vec<f32>> = Vec::with_capacity(tree.leaves.len());
    for (_, mask) in tree.leaves.iter_mut() {
        *mask = r.mask(512, "a leaf's value mask")?;
        values.push(read_values(&mut r, &ctx, 512, mask)?);
    }
    if offsets && r.at != chosen.end {
        return corrupt(format!(
            "the grid ends at byte {} but its descriptor says {}",
            r.at, chosen.end
        ));
    }

    // Leaf values: NaN refused, clamped, ±γ outside the band (active and |φ| < γ).
    let leaf_index: HashMap<[i32; 3], usize> =
        tree.leaves.iter().enumerate().map(|(i, (o, _))| (*o, i)).collect();
    let mut active_voxels = 0u64;
    for ((o, mask), vals) in tree.leaves.iter().zip(values.iter_mut()) {
        active_voxels += mask.iter().map(|w| w.count_ones() as u64).sum::<u64>();
        for (n, v) in vals.iter_mut().enumerate() {
            if v.is_nan() {
                return Err(VdbError::NaN { coord: coord(add(*o, slot_offset(n, LEAF_LOG2, 0))) });
            }
            let band = bit(mask, n) && v.abs() < g;
            if !band {
                *v = if *v < 0.0 { -g } else { g };
            }
        }
    }
    let mut tiles: Vec<(Coord, Tile)> = tree
        .leaves
        .par_iter()
        .zip(values.par_iter())
        .flat_map_iter(|((o, _), vals)| {
            (0..8).filter_map(move |s| {
                let t = Coord::new(
                    (o[0] >> 2) + (s & 1),
                    (o[1] >> 2) + ((s >> 1) & 1),
                    (o[2] >> 2) + (s >> 2),
                );
                let mut tile = Tile::splat(0.0);
                let mut band = false;
                for (l, v) in tile.0.iter_mut().enumerate() {
                    let c = voxel_of(t, l);
                    *v = vals[slot([c.x, c.y, c.z], LEAF_LOG2, 0)];
                    band |= v.abs() < g;
                }
                band.then_some((t, tile))
            })
        })
        .collect();
    if tiles.is_empty() {
        return Err(VdbError::NoInterface);
    }
    tiles.par_sort_unstable_by_key(|t| t.0);
    let inside = |t: Coord| -> bool {
        let c = voxel_of(t, 0);
        let c = [c.x, c.y, c.z];
        if let Some(&i) = leaf_index.get(&node_origin(c, LEAF_TOTAL)) {
            return values[i][slot(c, LEAF_LOG2, 0)] < 0.0;
        }
        if let Some(n) = tree.lowers.get(&node_origin(c, LOWER_TOTAL)) {
            return bit(&n.inside, slot(c, LOWER_LOG2, LEAF_TOTAL));
        }
        if let Some(n) = tree.uppers.get(&node_origin(c, UPPER_TOTAL)) {
            return bit(&n.inside, slot(c, UPPER_LOG2, LOWER_TOTAL));
        }
        tree.root_tiles.get(&node_origin(c, UPPER_TOTAL)).copied().unwrap_or(false)
    };
    let grid = TileGrid::from_sorted_tiles(spec, tiles, inside)?;
    let info = VdbInfo {
        grid_name: meta.name.unwrap_or_else(|| chosen.name.clone()),
        grid_class: meta.class,
        voxel_size: s,
        origin: translation,
        background,
        half_width: spec.half_width,
        compression: compression_name(flags),
        half_float: half,
        file_version: version,
        library_version,
        active_voxels,
        grids: grids.iter().map(GridEntry::describe).collect(),
    };
    Ok((grid, info))
}

/// A slot of an internal node or the root holding one value for its region: origin, log2
/// of its edge in voxels, value, active.
type VecTile = ([i32; 3], u32, [f32; 3], bool);

/// An internal node's topology in a vector grid: its tiles that differ from the background
/// or are active, and its leaves (origin and value mask).
fn read_internal_vec(
    r: &mut Reader,
    ctx: &Ctx,
    origin: [i32; 3],
    upper: bool,
    tiles: &mut Vec<VecTile>,
    leaves: &mut Vec<([i32; 3], Vec<u64>)>,
) -> Res<()> {
    let (log2, child_total) =
        if upper { (UPPER_LOG2, LOWER_TOTAL) } else { (LOWER_LOG2, LEAF_TOTAL) };
    let n = 1usize << (3 * log2);
    let child = r.mask(n, "an internal node's child mask")?;
    let active = r.mask(n, "an internal node's value mask")?;
    let values = read_values(r, ctx, n, &active)?;
    for i in 0..n {
        let at = add(origin, slot_offset(i, log2, child_total));
        if bit(&child, i) {
            if bit(&active, i) {
                return corrupt(format!(
                    "a slot at {} is both a child and an active tile",
                    coord(at)
                ));
            }
            continue;
        }
        let v = [values[3 * i], values[3 * i + 1], values[3 * i + 2]];
        if bit(&active, i) || v != ctx.background {
            tiles.push((at, child_total, v, bit(&active, i)));
        }
    }
    for i in 0..n {
        if !bit(&child, i) {
            continue;
        }
        let at = add(origin, slot_offset(i, log2, child_total));
        if upper {
            r.count(1, 2 * 512 + 1, "internal nodes")?;
            read_internal_vec(r, ctx, at, false, tiles, leaves)?;
        } else {
            leaves.push((at, r.mask(512, "a leaf's value mask")?));
        }
    }
    Ok(())
}

/// A `Vec3s` grid (a velocity field, say) as three dense components over the box of its
/// active values (active voxels and tiles, as OpenVDB's `evalActiveVoxelBoundingBox`);
/// inactive tiles and leaf values inside the box keep their stored values, regions
/// without a node the background.
pub(super) fn decode_vector(bytes: &[u8], want: Option<&str>) -> Res<super::VdbVectorGrid> {
    let is_vec = |e: &GridEntry| {
        e.type_name == "Tree_vec3s_5_4_3" || e.type_name == "Tree_vec3s_5_4_3_HalfFloat"
    };
    let Opened { mut r, grids, chosen, offsets, flags, half, meta, translation, scale, .. } =
        open_grid(bytes, |g| choose_grid(g, want, is_vec, "vector grid (type Tree_vec3s_5_4_3)"))?;
    let chosen = &grids[chosen];
    let buffers = r.i32("the tree")?;
    if buffers != 1 {
        return Err(VdbError::Unsupported(format!(
            "{buffers} buffers per leaf (OpenVDB writes 1)"
        )));
    }
    let background = [r.f32("the tree")?, r.f32("the tree")?, r.f32("the tree")?];
    if background.iter().any(|v| !v.is_finite()) {
        return corrupt(format!("the background value {background:?} is not finite"));
    }
    let ctx = Ctx { flags, half, background, comps: 3 };
    let ntiles = r.u32("the tree")?;
    let nchildren = r.u32("the tree")?;
    let ntiles = r.count(ntiles as u64, 25, "root tiles")?;
    let nchildren = r.count(nchildren as u64, 12 + 2 * 4096 + 1, "root children")?;
    let aligned = |o: [i32; 3]| o == node_origin(o, UPPER_TOTAL);
    let mut tiles: Vec<VecTile> = Vec::new();
    let mut leaves = Vec::new();
    let mut roots = std::collections::HashSet::new();
    for _ in 0..ntiles {
        let o = [r.i32("a root tile")?, r.i32("a root tile")?, r.i32("a root tile")?];
        let v = [r.f32("a root tile")?, r.f32("a root tile")?, r.f32("a root tile")?];
        let active = r.u8("a root tile")? != 0;
        if !aligned(o) || !roots.insert(o) {
            return corrupt(format!("a root tile at {} off the grid or repeated", coord(o)));
        }
        tiles.push((o, UPPER_TOTAL, v, active));
    }
    for _ in 0..nchildren {
        let o = [r.i32("a root child")?, r.i32("a root child")?, r.i32("a root child")?];
        if !aligned(o) || !roots.insert(o) {
            return corrupt(format!("a root child at {} off the grid or repeated", coord(o)));
        }
        read_internal_vec(&mut r, &ctx, o, true, &mut tiles, &mut leaves)?;
    }
    let mut values = Vec::with_capacity(leaves.len());
    for (_, mask) in leaves.iter_mut() {
        *mask = r.mask(512, "a leaf's value mask")?;
        values.push(read_values(&mut r, &ctx, 512, mask)?);
    }
    if offsets && r.at != chosen.end {
        return corrupt(format!(
            "the grid ends at byte {} but its descriptor says {}",
            r.at, chosen.end
        ));
    }
    for ((o, _), vals) in leaves.iter().zip(&values) {
        if let Some(n) = vals.iter().position(|v| v.is_nan()) {
            return Err(VdbError::NaN { coord: coord(add(*o, slot_offset(n / 3, LEAF_LOG2, 0))) });
        }
    }
    if let Some(t) = tiles.iter().find(|t| t.2.iter().any(|v| v.is_nan())) {
        return Err(VdbError::NaN { coord: coord(t.0) });
    }
    // The box of the active values (i64: a tile's far corner may pass i32::MAX).
    let mut lo = [i64::MAX; 3];
    let mut hi = [i64::MIN; 3];
    let mut grow = |o: [i32; 3], log2: u32| {
        for a in 0..3 {
            lo[a] = lo[a].min(o[a] as i64);
            hi[a] = hi[a].max(o[a] as i64 + (1i64 << log2));
        }
    };
    for (o, mask) in &leaves {
        for n in (0..512).filter(|&n| bit(mask, n)) {
            grow(add(*o, slot_offset(n, LEAF_LOG2, 0)), 0);
        }
    }
    for t in tiles.iter().filter(|t| t.3) {
        grow(t.0, t.1);
    }
    if lo[0] > hi[0] {
        return Err(VdbError::NoGrid(format!("grid {} has no active value", chosen.describe())));
    }
    let dims = std::array::from_fn(|a| (hi[a] - lo[a]) as usize);
    let origin = Coord::new(lo[0] as i32, lo[1] as i32, lo[2] as i32);
    let mut fields = [
        DenseField::new(origin, dims, background[0])?,
        DenseField::new(origin, dims, background[1])?,
        DenseField::new(origin, dims, background[2])?,
    ];
    // Tiles first (the larger first), then the leaves over them.
    tiles.sort_by_key(|t| std::cmp::Reverse(t.1));
    for (o, log2, v, _) in &tiles {
        let (a, b): (Vec<i64>, Vec<i64>) = (0..3)
            .map(|k| (lo[k].max(o[k] as i64), hi[k].min(o[k] as i64 + (1i64 << log2))))
            .unzip();
        for z in a[2]..b[2] {
            for y in a[1]..b[1] {
                for x in a[0]..b[0] {
                    let c = Coord::new(x as i32, y as i32, z as i32);
                    for (f, val) in fields.iter_mut().zip(v) {
                        f.set(c, *val)?;
                    }
                }
            }
        }
    }
    for ((o, _), vals) in leaves.iter().zip(&values) {
        for n in 0..512 {
            let c = coord(add(*o, slot_offset(n, LEAF_LOG2, 0)));
            if fields[0].get(c).is_some() {
                for (k, f) in fields.iter_mut().enumerate() {
                    f.set(c, vals[3 * n + k])?;
                }
            }
        }
    }
    Ok(super::VdbVectorGrid {
        components: fields,
        voxel_size: scale,
        origin: translation,
        name: meta.name.unwrap_or_else(|| chosen.name.clone()),
    })
}
