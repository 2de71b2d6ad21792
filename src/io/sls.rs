//! The `.sls` file: a sparse level set stored as its H-RLE encoding ([`crate::storage::hrle`]),
//! written from any grid and read into any. The byte layout is specified in
//! `docs/sls-format.md`; in short: a fixed header (magic, version, spec, domain, counts),
//! the three RLE blocks with each run as one LEB128 varint of (start delta, kind) — the
//! defined runs' targets are implied by their order, as the encoding assigns them —,
//! the raw `f32` values, the augmented fields, and a CRC-32 of everything before it.
//!
//! # Reading hostile files
//! [`decode`] never panics and never allocates more than the file justifies: the file is
//! checked against the memory limit before it is read, the checksum is verified before
//! anything is parsed, every count is checked against the bytes left before a vector is
//! sized by it, and the decoded grid must pass [`HrleGrid::check_invariants`] (so values
//! are finite and inside `[−γ, γ]`, runs ordered, counts consistent) before it is returned.
//!
//! ```
//! use sparse_levelset::{storage::convert, storage::shapes::Shape, io::sls, GridSpec, LevelSet};
//!
//! let sphere = Shape::Sphere { center: [0.0; 3], radius: 10.0 };
//! let tiles = convert::tiles_from_shape(&sphere, GridSpec::default()).unwrap();
//! let bytes = sls::encode_level_set(&tiles).unwrap();
//! let (grid, header) = sls::decode(&bytes).unwrap();
//! assert_eq!(grid.checksum(), tiles.checksum());
//! assert_eq!(header.source, sls::Source::Tiles);
//! assert!(sls::decode(&bytes[..bytes.len() - 1]).is_err());
//! ```

use crate::coord::Coord;
use crate::grid::{GridError, GridSpec};
use crate::io::bytes::{ByteReader as Reader, ReadError};
use crate::storage::hrle::{Block, FieldData, HrleGrid, NEG, POS};
use crate::storage::levelset::LevelSet;
use std::io::Write;
use std::path::Path;

/// The first eight bytes: a non-ASCII byte, the name, and CR LF SUB LF to catch text-mode
/// transfers (the PNG convention).
pub const MAGIC: [u8; 8] = *b"\x89SLS\r\n\x1a\n";
/// The version this library writes and reads.
pub const VERSION: u32 = 1;
/// Bytes of the fixed header (magic to field count).
pub const HEADER_BYTES: usize = 8 + 4 + 4 + 4 + 24 + 4 + 4 + 24 + 8 + 24 + 4;

const FLAG_DOMAIN: u32 = 1;

/// The grid a file was written from (informative: every file reads into every grid).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// An H-RLE level set.
    Hrle,
    /// A Sorted Tile List.
    Tiles,
    /// A DT-Grid.
    DtGrid,
    /// Another [`LevelSet`] (a simulation's state, a CSG view).
    Other,
}

impl Source {
    fn code(self) -> u32 {
        self as u32
    }
    fn from_code(c: u32) -> Option<Source> {
        [Source::Hrle, Source::Tiles, Source::DtGrid, Source::Other].get(c as usize).copied()
    }
}

/// What the header of a `.sls` file says.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Format version.
    pub version: u32,
    /// Voxel size, origin, half-width.
    pub spec: GridSpec,
    /// The grid the file was written from.
    pub source: Source,
    /// The domain of an unenclosed (clipped) level set.
    pub domain: Option<(Coord, Coord)>,
    /// Stored voxels.
    pub values: u64,
    /// Runs of the z, y and x blocks.
    pub runs: [u64; 3],
    /// Augmented fields.
    pub fields: u32,
}

/// Why a `.sls` file was refused or could not be written.
#[derive(Debug, thiserror::Error)]
pub enum SlsError {
    /// Reading or writing the file failed.
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    /// The file does not start with the `.sls` magic.
    #[error("not a sparse level set (.sls) file: it does not start with the .sls signature")]
    NotSls,
    /// A version this library cannot read.
    #[error("written in .sls version {0}; this library reads version {VERSION}")]
    Version(u32),
    /// The file ends before what its header announces.
    #[error("truncated: the file ends inside {0}")]
    Truncated(&'static str),
    /// The stored CRC-32 does not match the bytes.
    #[error("corrupt: checksum {stored:08x} stored, {computed:08x} computed")]
    Checksum { stored: u32, computed: u32 },
    /// The bytes are well formed but do not describe a valid level set.
    #[error("corrupt: {0}")]
    Corrupt(String),
    /// The file or the grid does not fit in memory, or a grid could not be made.
    #[error(transparent)]
    Grid(#[from] GridError),
}

impl crate::error::Error for SlsError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            SlsError::Io { source, .. } => crate::error::io_kind(source),
            SlsError::NotSls
            | SlsError::Truncated(_)
            | SlsError::Checksum { .. }
            | SlsError::Corrupt(_) => CorruptFile,
            SlsError::Version(_) => Unsupported,
            SlsError::Grid(e) => e.kind(),
        }
    }
}

impl SlsError {
    /// The error with the file's path in front (one message per kind of problem).
    fn at(self, path: &Path) -> SlsError {
        match self {
            SlsError::Io { .. } => self,
            e => SlsError::Io {
                path: path.display().to_string(),
                source: std::io::Error::new(std::io::ErrorKind::InvalidData, e.to_string()),
            },
        }
    }
}

// ---------------------------------------------------------------------------------------
// Writing

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn zigzag(v: i32) -> u64 {
    ((v << 1) ^ (v >> 31)) as u32 as u64
}

fn unzigzag(v: u32) -> i32 {
    ((v >> 1) as i32) ^ -((v & 1) as i32)
}

fn kind(code: u32) -> u64 {
    match code {
        NEG => 0,
        POS => 1,
        _ => 2,
    }
}

/// The bytes of `g` (source recorded as `source`).
pub fn encode(g: &HrleGrid, source: Source) -> Vec<u8> {
    let spec = g.spec();
    let mut out = Vec::with_capacity(HEADER_BYTES + 4 * g.len() + 3 * g.runs()[2] + 64);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    let flags = if g.domain().is_some() { FLAG_DOMAIN } else { 0 };
    out.extend_from_slice(&flags.to_le_bytes());
    out.extend_from_slice(&spec.voxel_size.to_le_bytes());
    for o in spec.origin {
        out.extend_from_slice(&o.to_le_bytes());
    }
    out.extend_from_slice(&spec.half_width.to_le_bytes());
    out.extend_from_slice(&source.code().to_le_bytes());
    let (lo, hi) = g.domain().unwrap_or_default();
    for q in [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z] {
        out.extend_from_slice(&q.to_le_bytes());
    }
    out.extend_from_slice(&(g.len() as u64).to_le_bytes());
    for r in g.runs() {
        out.extend_from_slice(&(r as u64).to_le_bytes());
    }
    out.extend_from_slice(&(g.fields().len() as u32).to_le_bytes());
    debug_assert_eq!(out.len(), HEADER_BYTES);
    for b in &g.blocks {
        for s in 0..b.segments() {
            let (codes, breaks) = b.segment(s);
            put_varint(&mut out, codes.len() as u64 - 1);
            out.push(kind(codes[0]) as u8);
            for r in 1..codes.len() {
                let delta = if r == 1 {
                    zigzag(breaks[0])
                } else {
                    (breaks[r - 1] as i64 - breaks[r - 2] as i64 - 1) as u64
                };
                put_varint(&mut out, delta << 2 | kind(codes[r]));
            }
        }
    }
    for v in g.values() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for f in g.fields() {
        out.extend_from_slice(&(f.name.len() as u16).to_le_bytes());
        out.extend_from_slice(f.name.as_bytes());
        match &f.data {
            FieldData::Scalar(v) => {
                out.push(0);
                v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
            }
            FieldData::Vector(v) => {
                out.push(1);
                v.iter().flatten().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
            }
        }
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// The bytes of any level set: an [`HrleGrid`] as it is (domain and fields included),
/// any other grid through [`HrleGrid::from_level_set`].
pub fn encode_level_set<G: LevelSet + ?Sized>(ls: &G) -> Result<Vec<u8>, SlsError> {
    if let Some(h) = HrleGrid::of(ls) {
        return Ok(encode(h, Source::Hrle));
    }
    let source = if crate::storage::tiles::TileGrid::of(ls).is_some() {
        Source::Tiles
    } else if crate::storage::dtgrid::DtGrid::of(ls).is_some() {
        Source::DtGrid
    } else {
        Source::Other
    };
    Ok(encode(&HrleGrid::from_level_set(ls)?, source))
}

/// Writes `ls` to `path` atomically (a temporary file renamed into place: on any error
/// `path` is left as it was).
pub fn save<G: LevelSet + ?Sized>(path: &Path, ls: &G) -> Result<(), SlsError> {
    let bytes = encode_level_set(ls)?;
    crate::io::fsutil::write_atomic(path, |w| w.write_all(&bytes))
        .map_err(|source| SlsError::Io { path: path.display().to_string(), source })
}

// ---------------------------------------------------------------------------------------
// Reading

impl From<ReadError> for SlsError {
    fn from(e: ReadError) -> SlsError {
        match e {
            ReadError::Truncated(what) => SlsError::Truncated(what),
            ReadError::TooMany { n, what, left } => SlsError::Corrupt(format!(
                "the header announces {n} {what}, more than the {left} bytes left can hold"
            )),
            ReadError::Overlong(what) => {
                SlsError::Corrupt(format!("an over-long number in {what}"))
            }
        }
    }
}

fn corrupt<T>(m: impl Into<String>) -> Result<T, SlsError> {
    Err(SlsError::Corrupt(m.into()))
}

/// Reads the header of `bytes` (magic, version, spec, counts) without the checksum or
/// the body.
pub fn decode_header(bytes: &[u8]) -> Result<Header, SlsError> {
    let mut r = Reader { b: bytes, at: 0 };
    if bytes.len() < 8 || bytes[..8] != MAGIC {
        return Err(SlsError::NotSls);
    }
    r.at = 8;
    let version = r.u32("the header")?;
    if version != VERSION {
        return Err(SlsError::Version(version));
    }
    let flags = r.u32("the header")?;
    if flags & !FLAG_DOMAIN != 0 {
        return corrupt(format!("unknown header flags {flags:#x}"));
    }
    let voxel_size = r.f32("the header")?;
    let origin = [r.f64("the header")?, r.f64("the header")?, r.f64("the header")?];
    let half_width = r.f32("the header")?;
    let spec = GridSpec::new(voxel_size, origin, half_width)
        .map_err(|e| SlsError::Corrupt(format!("grid: {e}")))?;
    let source = Source::from_code(r.u32("the header")?)
        .ok_or_else(|| SlsError::Corrupt("unknown source grid".into()))?;
    let mut d = [0i32; 6];
    for q in &mut d {
        *q = r.u32("the header")? as i32;
    }
    let domain = if flags & FLAG_DOMAIN != 0 {
        let (lo, hi) = (Coord::new(d[0], d[1], d[2]), Coord::new(d[3], d[4], d[5]));
        if lo.x > hi.x || lo.y > hi.y || lo.z > hi.z {
            return corrupt(format!("empty domain {lo}..{hi}"));
        }
        Some((lo, hi))
    } else {
        if d != [0; 6] {
            return corrupt("a domain without the domain flag");
        }
        None
    };
    let values = r.u64("the header")?;
    let runs = [r.u64("the header")?, r.u64("the header")?, r.u64("the header")?];
    let fields = r.u32("the header")?;
    Ok(Header { version, spec, source, domain, values, runs, fields })
}

/// Decodes a whole file's bytes into an H-RLE level set (see the [module docs](self) for
/// the checks).
pub fn decode(bytes: &[u8]) -> Result<(HrleGrid, Header), SlsError> {
    let header = decode_header(bytes)?;
    if bytes.len() < HEADER_BYTES + 4 {
        return Err(SlsError::Truncated("the header"));
    }
    let body = &bytes[..bytes.len() - 4];
    let stored = u32::from_le_bytes(bytes[bytes.len() - 4..].try_into().unwrap());
    let computed = crc32fast::hash(body);
    if stored != computed {
        return Err(SlsError::Checksum { stored, computed });
    }
    let mut r = Reader { b: body, at: HEADER_BYTES };
    // Every run takes at least one byte, every value four.
    let nvalues = r.count(header.values, 4, "values")?;
    let mut nruns = [0usize; 3];
    for (n, &claimed) in nruns.iter_mut().zip(&header.runs) {
        *n = r.count(claimed, 1, "runs")?;
    }
    let mut blocks: [Block; 3] = Default::default();
    let mut segments = 1u64;
    for (k, block) in blocks.iter_mut().enumerate() {
        let nseg = r.count(segments, 2, "segments")?;
        block.seg = Vec::with_capacity(nseg + 1);
        block.seg.push(0);
        block.codes = Vec::with_capacity(nruns[k]);
        block.breaks = Vec::with_capacity(nruns[k].saturating_sub(nseg));
        let mut next = 0u64; // targets handed out so far
        for _ in 0..nseg {
            let more = r.varint("a segment")?;
            if more.saturating_add(1) > nruns[k].saturating_sub(block.codes.len()) as u64 {
                return corrupt(format!("block {k}: more runs than the header announces"));
            }
            let first = r.u8("a segment")? as u64;
            if first > 1 {
                return corrupt(format!("block {k}: a segment starts with a defined run"));
            }
            block.codes.push(if first == 0 { NEG } else { POS });
            let mut prev: i64 = i32::MIN as i64;
            for j in 0..more {
                let v = r.varint("a run")?;
                let (delta, kind) = (v >> 2, v & 3);
                let start = if j == 0 {
                    if delta > u32::MAX as u64 {
                        return corrupt(format!("block {k}: a run starts outside the i32 range"));
                    }
                    unzigzag(delta as u32) as i64
                } else {
                    prev + 1 + delta as i64
                };
                if start > i32::MAX as i64 || delta > u32::MAX as u64 {
                    return corrupt(format!("block {k}: a run starts outside the i32 range"));
                }
                // A defined run ends where the next run starts.
                if block.codes.last().is_some_and(|&c| c < POS) {
                    next += (start - prev) as u64;
                }
                let code = match kind {
                    0 => NEG,
                    1 => POS,
                    2 => {
                        if next >= POS as u64 {
                            return corrupt(format!("block {k}: too many defined elements"));
                        }
                        next as u32
                    }
                    _ => return corrupt(format!("block {k}: unknown run kind 3")),
                };
                block.codes.push(code);
                block.breaks.push(start as i32);
                prev = start;
            }
            if block.codes.last().is_some_and(|&c| c < POS) {
                return corrupt(format!("block {k}: a segment ends with a defined run"));
            }
            block.seg.push(block.codes.len() as u32);
        }
        if block.codes.len() != nruns[k] {
            return corrupt(format!(
                "block {k}: {} runs, the header announces {}",
                block.codes.len(),
                nruns[k]
            ));
        }
        segments = next;
    }
    if segments != nvalues as u64 {
        return corrupt(format!(
            "{segments} defined voxels, the header announces {nvalues} values"
        ));
    }
    let raw = r.take(4 * nvalues, "the values")?;
    let values: Vec<f32> =
        raw.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    let mut fields = Vec::new();
    for _ in 0..header.fields {
        let len = u16::from_le_bytes(r.take(2, "a field")?.try_into().unwrap()) as usize;
        let name = std::str::from_utf8(r.take(len, "a field name")?)
            .map_err(|_| SlsError::Corrupt("a field name is not UTF-8".into()))?
            .to_string();
        let width = match r.u8("a field")? {
            0 => 1,
            1 => 3,
            k => return corrupt(format!("field {name:?}: unknown kind {k}")),
        };
        let raw = r.take(4 * width * nvalues, "a field's data")?;
        let mut it = raw.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap()));
        let data = if width == 1 {
            FieldData::Scalar(it.collect())
        } else {
            FieldData::Vector((0..nvalues).map(|_| [0; 3].map(|_| it.next().unwrap())).collect())
        };
        fields.push((name, data));
    }
    if r.left() != 0 {
        return corrupt(format!("{} bytes after the last field", r.left()));
    }
    let mut g = HrleGrid::from_parts(header.spec, blocks, values, header.domain)
        .map_err(SlsError::Corrupt)?;
    for (name, data) in fields {
        g.add_field(&name, data).map_err(|e| SlsError::Corrupt(format!("field: {e}")))?;
    }
    Ok((g, header))
}

/// Reads a `.sls` file into an H-RLE level set (convert it with
/// [`crate::storage::convert::tiles_from`] or [`crate::storage::convert::dtgrid_from`]); errors name the file.
pub fn load(path: &Path) -> Result<(HrleGrid, Header), SlsError> {
    let io = |source| SlsError::Io { path: path.display().to_string(), source };
    let len = std::fs::metadata(path).map_err(io)?.len();
    // The bytes, the values again and the blocks' vectors: at most about three copies.
    crate::memory::check(3.0 * len as f64, "reading the .sls file")
        .map_err(|e| SlsError::from(e).at(path))?;
    let bytes = std::fs::read(path).map_err(io)?;
    decode(&bytes).map_err(|e| e.at(path))
}
