//! Reading and writing dense `float32` volumes as NumPy `.npy` files.
//!
//! # Conventions
//! * A volume is the **logical** 3-D array `arr[z, y, x]` of shape `(nz, ny, nx)`, so
//!   x is fastest in C order, as everywhere in this crate (see [`Coord`]). Element
//!   `arr[z, y, x]` is voxel `(x, y, z)`; the field read has origin `(0, 0, 0)`.
//! * Only little-endian `float32` (`'<f4'`) is read or written.
//! * Fortran-ordered files (`fortran_order: True`, e.g. `np.save(f, a.T)` or
//!   `np.asfortranarray`) are **accepted**: the logical array is the same, `arr[z, y, x]`
//!   still means voxel `(x, y, z)`, and the data are transposed into x-fastest order while
//!   reading (a strided pass; C order avoids it).
//! * `NaN` is rejected, naming the first offending voxel in [`Coord`] order. `±inf` is
//!   accepted: it is a far-away distance, and level-set consumers clamp values to `±γ`.
//! * Bytes after the array data are an error ([`NpyError::TrailingBytes`]): the format
//!   allows none, and extra bytes usually mean the header's shape or dtype does not
//!   describe the data.
//! * The header is parsed here (a strict parser for the small Python-literal dict of the
//!   format, versions 1.0, 2.0 and 3.0) rather than by `npyz`, so that hostile headers
//!   (overflowing shape products, huge header lengths, deep nesting) are rejected before
//!   anything is allocated; `npyz` writes the header.
//!
//! ```
//! use sparse_levelset::{storage::dense::DenseField, io::npy, Coord};
//!
//! let dir = std::env::temp_dir().join(format!("npy-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let path = dir.join("phi.npy");
//! let field = DenseField::from_fn(Coord::new(0, 0, 0), [4, 3, 2], |c| c.x as f32 - 1.5).unwrap();
//! npy::write_npy(&path, &field).unwrap(); // np.load gives shape (2, 3, 4)
//! assert_eq!(npy::read_npy(&path).unwrap(), field);
//! std::fs::remove_dir_all(&dir).unwrap();
//! ```

use crate::coord::Coord;
use crate::storage::dense::{checked_len, DenseField};
use npyz::WriterBuilder;
use rayon::prelude::*;
use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

/// Errors of [`read_npy`] and [`write_npy`]; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum NpyError {
    /// The operating system refused (missing file, permissions, disk full, ...).
    #[error("{}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    /// The file does not start with the `.npy` magic bytes.
    #[error("{}: not a .npy file (it does not start with the magic bytes \\x93NUMPY)", .path.display())]
    NotNpy { path: PathBuf },
    /// A format version other than 1.0, 2.0 or 3.0.
    #[error("{}: unsupported .npy format version {major}.{minor} (supported: 1.0, 2.0, 3.0)", .path.display())]
    UnsupportedVersion { path: PathBuf, major: u8, minor: u8 },
    /// The header is cut short or is not the dict the format prescribes.
    #[error("{}: malformed .npy header: {reason}", .path.display())]
    BadHeader { path: PathBuf, reason: String },
    /// The dtype is not little-endian float32.
    #[error(
        "{}: array has dtype {found}, but a little-endian float32 ('<f4') array is required; \
         convert it in NumPy with `arr.astype(np.float32)` before saving",
        .path.display()
    )]
    WrongDtype { path: PathBuf, found: String },
    /// The array does not have exactly three dimensions.
    #[error("{}: expected a 3-D array of shape (nz, ny, nx), found shape {}", .path.display(), py_shape(.shape))]
    NotThreeD { path: PathBuf, shape: Vec<u64> },
    /// A vector field ([`read_npy_vector`]) whose shape is not `(nz, ny, nx, 3)`.
    #[error("{}: expected a vector field of shape (nz, ny, nx, 3), found shape {}", .path.display(), py_shape(.shape))]
    NotVectorField { path: PathBuf, shape: Vec<u64> },
    /// A dimension is 0.
    #[error("{}: array of shape {} has an empty dimension", .path.display(), py_shape(.shape))]
    EmptyDimension { path: PathBuf, shape: Vec<u64> },
    /// The shape describes more data than can be held or addressed.
    #[error("{}: array of shape {} is too large: {reason}", .path.display(), py_shape(.shape))]
    TooLarge { path: PathBuf, shape: Vec<u64>, reason: String },
    /// Fewer data bytes than the header declares.
    #[error(
        "{}: file is truncated: the header declares {expected} bytes of data but only {found} follow it",
        .path.display()
    )]
    Truncated { path: PathBuf, expected: u64, found: u64 },
    /// More data bytes than the header declares.
    #[error(
        "{}: {} unexpected bytes after the data (the header declares {expected} bytes of data, \
         the file holds {found}); the header's shape or dtype does not describe the data",
        .path.display(), found - expected
    )]
    TrailingBytes { path: PathBuf, expected: u64, found: u64 },
    /// A NaN value; `(x, y, z)` is the first such voxel in [`Coord`] order.
    #[error(
        "{}: NaN at voxel (x, y, z) = ({x}, {y}, {z}), i.e. arr[{z}, {y}, {x}]; level-set values \
         must be numbers (±inf is accepted as a far-away distance)",
        .path.display()
    )]
    NaN { path: PathBuf, x: u64, y: u64, z: u64 },
    /// The array needs more memory than the machine can give ([`crate::memory::check`]),
    /// refused before anything is allocated.
    #[error("{}: {source}", .path.display())]
    OutOfMemory {
        path: PathBuf,
        #[source]
        source: crate::grid::GridError,
    },
}

impl crate::error::Error for NpyError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            NpyError::Io { source, .. } => crate::error::io_kind(source),
            NpyError::NotNpy { .. }
            | NpyError::BadHeader { .. }
            | NpyError::Truncated { .. }
            | NpyError::TrailingBytes { .. } => CorruptFile,
            NpyError::UnsupportedVersion { .. }
            | NpyError::WrongDtype { .. }
            | NpyError::NotThreeD { .. }
            | NpyError::NotVectorField { .. } => Unsupported,
            NpyError::EmptyDimension { .. } | NpyError::NaN { .. } => InvalidData,
            NpyError::TooLarge { .. } | NpyError::OutOfMemory { .. } => OutOfMemory,
        }
    }
}

/// A shape as NumPy prints it: `(2, 3, 4)`, `(5,)`, `()`.
fn py_shape(shape: &[u64]) -> String {
    match shape {
        [d] => format!("({d},)"),
        _ => format!("({})", shape.iter().map(u64::to_string).collect::<Vec<_>>().join(", ")),
    }
}

const MAGIC: &[u8; 6] = b"\x93NUMPY";
/// Headers longer than this are rejected before allocating (ours are < 128 bytes;
/// NumPy itself refuses more than 10 000 by default).
const MAX_HEADER_LEN: u64 = 1 << 16;
/// Nesting limit of header values (NumPy's headers nest at most 2 deep for our dtypes).
const MAX_DEPTH: usize = 8;

/// What a `.npy` header declares, checked against the file's size ([`inspect_npy`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NpyInfo {
    /// `[nx, ny, nz]` for shape `(nz, ny, nx)`.
    pub dims: [usize; 3],
    /// Whether the data are in Fortran order (read with one transposing pass).
    pub fortran_order: bool,
}

impl NpyInfo {
    /// Number of values, `nx · ny · nz`.
    pub fn len(&self) -> usize {
        self.dims.iter().product()
    }

    /// Whether the array holds no value (never true for a checked header).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes [`read_npy`] allocates at its peak: the data, and a second copy while a
    /// Fortran-ordered file is transposed.
    pub fn read_bytes(&self) -> f64 {
        crate::memory::bytes_of(self.len() as u128, 4) * if self.fortran_order { 2.0 } else { 1.0 }
    }
}

/// Reads and checks the header of a `.npy` file without reading its data: the same checks
/// as [`read_npy`] (dtype, three dimensions, sizes, the file's length against the
/// header), except for NaN values and memory. Lets a tool size its work before reading.
pub fn inspect_npy(path: &Path) -> Result<NpyInfo, NpyError> {
    let io_err = |source| NpyError::Io { path: path.to_path_buf(), source };
    let mut file = File::open(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    if meta.is_file() {
        Ok(read_header(&mut file, meta.len(), path, 1)?.info)
    } else {
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).map_err(io_err)?;
        Ok(read_header(&mut &bytes[..], bytes.len() as u64, path, 1)?.info)
    }
}

/// Reads a 3-D little-endian float32 `.npy` file into a [`DenseField`] with origin
/// `(0, 0, 0)` and `dims = [nx, ny, nz]` for shape `(nz, ny, nx)`.
///
/// See the module docs for orders, `inf`, `NaN` and trailing bytes. The header is checked
/// against the file size, and the memory the data need against what the machine can give
/// ([`NpyError::OutOfMemory`]), before the data are allocated, so neither a hostile header
/// nor a huge file can make this allocate more than the file holds or the machine has.
pub fn read_npy(path: &Path) -> Result<DenseField, NpyError> {
    let io_err = |source| NpyError::Io { path: path.to_path_buf(), source };
    let mut file = File::open(path).map_err(io_err)?;
    let [field] = read_fields::<1>(&mut file, path)?;
    Ok(field)
}

/// Reads a vector field, a little-endian float32 `.npy` array of shape `(nz, ny, nx, 3)`
/// (NumPy's layout for one 3-vector per voxel: `arr[z, y, x]` is the vector at voxel
/// `(x, y, z)`), as its three components `[u_x, u_y, u_z]`, each a [`DenseField`] with
/// origin `(0, 0, 0)` and `dims = [nx, ny, nz]`. The checks of [`read_npy`] apply (orders,
/// NaN refused, sizes and memory checked before the data are allocated).
pub fn read_npy_vector(path: &Path) -> Result<[DenseField; 3], NpyError> {
    let io_err = |source| NpyError::Io { path: path.to_path_buf(), source };
    let mut file = File::open(path).map_err(io_err)?;
    read_fields::<3>(&mut file, path)
}

/// The `C` component fields of an open `.npy` file (a regular file, or a pipe read whole).
fn read_fields<const C: usize>(file: &mut File, path: &Path) -> Result<[DenseField; C], NpyError> {
    let io_err = |source| NpyError::Io { path: path.to_path_buf(), source };
    let meta = file.metadata().map_err(io_err)?;
    if meta.is_file() {
        let len = meta.len();
        read_from::<C>(file, len, path)
    } else {
        // A pipe or device: its size is unknown in advance, so read what it holds.
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).map_err(io_err)?;
        read_from::<C>(&mut &bytes[..], bytes.len() as u64, path)
    }
}

/// A checked header: what it declares and the data bytes that must follow it.
struct Checked {
    info: NpyInfo,
    expected: u64,
}

/// Parses and checks the preamble and header of a `.npy` stream of `total` bytes, leaving
/// `r` at the first data byte; `path` only names it in errors. `components` is 1 for a
/// volume of shape `(nz, ny, nx)`, 3 for a vector field of shape `(nz, ny, nx, 3)`.
fn read_header(
    r: &mut impl Read,
    total: u64,
    path: &Path,
    components: u64,
) -> Result<Checked, NpyError> {
    let p = || path.to_path_buf();
    let io_err = |source| NpyError::Io { path: path.to_path_buf(), source };
    let bad = |reason: String| NpyError::BadHeader { path: path.to_path_buf(), reason };

    // Preamble: magic, version, header length.
    if total < 8 {
        let mut head = vec![0u8; total as usize];
        r.read_exact(&mut head).map_err(io_err)?;
        return Err(if MAGIC.starts_with(&head) && head.len() >= MAGIC.len() {
            bad("the file ends inside the format version".into())
        } else {
            NpyError::NotNpy { path: p() }
        });
    }
    let mut pre = [0u8; 8];
    read_exact(r, &mut pre, path)?;
    if &pre[..6] != MAGIC {
        return Err(NpyError::NotNpy { path: p() });
    }
    let (major, minor) = (pre[6], pre[7]);
    let len_bytes = match (major, minor) {
        (1, 0) => 2,
        (2, 0) | (3, 0) => 4,
        _ => return Err(NpyError::UnsupportedVersion { path: p(), major, minor }),
    };
    let preamble = 8 + len_bytes as u64;
    if total < preamble {
        return Err(bad(format!("the file ends inside the header length ({total} bytes in all)")));
    }
    let mut lb = [0u8; 4];
    read_exact(r, &mut lb[..len_bytes], path)?;
    let header_len = u32::from_le_bytes(lb) as u64;
    if header_len > MAX_HEADER_LEN {
        return Err(bad(format!("header length {header_len} bytes is implausibly large")));
    }
    if total - preamble < header_len {
        return Err(bad(format!(
            "the file ends inside the header: it declares {header_len} header bytes, only {} follow",
            total - preamble
        )));
    }
    let mut text = vec![0u8; header_len as usize];
    read_exact(r, &mut text, path)?;
    let header = parse_header(&text).map_err(bad)?;

    if header.descr != "<f4" {
        return Err(NpyError::WrongDtype { path: p(), found: header.descr_text });
    }
    let shape = header.shape;
    if components == 1 && shape.len() != 3 {
        return Err(NpyError::NotThreeD { path: p(), shape });
    }
    if components > 1 && (shape.len() != 4 || shape[3] != components) {
        return Err(NpyError::NotVectorField { path: p(), shape });
    }
    if shape.contains(&0) {
        return Err(NpyError::EmptyDimension { path: p(), shape });
    }
    // Checked before any allocation: the element count, the bytes, the coordinates.
    let too_large = |reason: String| NpyError::TooLarge {
        path: path.to_path_buf(),
        shape: shape.clone(),
        reason,
    };
    let expected = shape
        .iter()
        .try_fold(4u64, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| too_large("its size in bytes overflows 64 bits".into()))?;
    let (nz, ny, nx) = (shape[0], shape[1], shape[2]);
    let dims = [nx, ny, nz].map(|d| usize::try_from(d).unwrap_or(usize::MAX));
    checked_len(Coord::new(0, 0, 0), dims).map_err(|e| too_large(e.to_string()))?;
    let found = total - preamble - header_len;
    if found < expected {
        return Err(NpyError::Truncated { path: p(), expected, found });
    }
    if found > expected {
        return Err(NpyError::TrailingBytes { path: p(), expected, found });
    }
    Ok(Checked { info: NpyInfo { dims, fortran_order: header.fortran_order }, expected })
}

/// Parses a `.npy` stream of `total` bytes holding `C` values per voxel (the last axis);
/// `path` only names it in errors.
fn read_from<const C: usize>(
    r: &mut impl Read,
    total: u64,
    path: &Path,
) -> Result<[DenseField; C], NpyError> {
    let p = || path.to_path_buf();
    let Checked { info, expected } = read_header(r, total, path, C as u64)?;
    let dims = info.dims;
    let len = info.len();
    let too_large = |reason: String| NpyError::TooLarge {
        path: path.to_path_buf(),
        shape: vec![dims[2] as u64, dims[1] as u64, dims[0] as u64],
        reason,
    };
    // A vector field holds the file's values and, while they are split, the components.
    let bytes = if C == 1 { info.read_bytes() } else { 2.0 * C as f64 * info.read_bytes() };
    crate::memory::check(bytes, "the array's data")
        .map_err(|source| NpyError::OutOfMemory { path: p(), source })?;

    // The data: read straight into the f32 buffer (the file holds exactly C · len · 4 bytes).
    let mut data = vec![0.0f32; C * len];
    read_exact(r, bytemuck::cast_slice_mut(&mut data), path).map_err(|e| match e {
        // The file shrank while being read.
        NpyError::Truncated { .. } => NpyError::Truncated { path: p(), expected, found: 0 },
        e => e,
    })?;
    if cfg!(target_endian = "big") {
        for v in &mut data {
            *v = f32::from_bits(u32::from_le(v.to_bits()));
        }
    }
    let (nx, ny, nz) = (dims[0], dims[1], dims[2]);
    let mut parts: Vec<Vec<f32>> = if info.fortran_order {
        // File offset of arr[z, y, x, c] is z + nz (y + ny (x + nx c)); ours is
        // x + nx (y + ny z) in component c's field.
        data.chunks_exact(len)
            .map(|file| {
                let mut ours = vec![0.0f32; len];
                ours.par_chunks_mut(nx * ny).enumerate().for_each(|(z, slice)| {
                    for (y, row) in slice.chunks_exact_mut(nx).enumerate() {
                        for (x, v) in row.iter_mut().enumerate() {
                            *v = file[z + nz * (y + ny * x)];
                        }
                    }
                });
                ours
            })
            .collect()
    } else if C == 1 {
        vec![data]
    } else {
        // C order: the components of a voxel are adjacent.
        (0..C).map(|c| data.iter().skip(c).step_by(C).copied().collect()).collect()
    };
    // The first NaN in voxel order, then component order.
    let nan = parts.iter().filter_map(|d| d.iter().position(|v| v.is_nan())).min();
    if let Some(i) = nan {
        let (x, rest) = (i % nx, i / nx);
        let (y, z) = (rest % ny, rest / ny);
        return Err(NpyError::NaN { path: p(), x: x as u64, y: y as u64, z: z as u64 });
    }
    // Cannot fail: the dimensions were checked above.
    let fields = parts
        .drain(..)
        .map(|d| DenseField::from_vec(Coord::new(0, 0, 0), dims, d))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| too_large(e.to_string()))?;
    Ok(fields.try_into().expect("C fields"))
}

/// `read_exact` with end-of-file reported as [`NpyError::Truncated`] (callers that know
/// the expected and found sizes fill them in) and other failures as [`NpyError::Io`].
fn read_exact(r: &mut impl Read, buf: &mut [u8], path: &Path) -> Result<(), NpyError> {
    r.read_exact(buf).map_err(|source| {
        if source.kind() == io::ErrorKind::UnexpectedEof {
            NpyError::Truncated { path: path.to_path_buf(), expected: buf.len() as u64, found: 0 }
        } else {
            NpyError::Io { path: path.to_path_buf(), source }
        }
    })
}

/// The three entries of a `.npy` header.
#[derive(Debug, PartialEq)]
pub(crate) struct Header {
    /// The dtype string if `descr` is a string, else empty.
    pub descr: String,
    /// `descr` as written, for error messages.
    pub descr_text: String,
    pub fortran_order: bool,
    pub shape: Vec<u64>,
}

/// A Python literal of the subset that `.npy` headers use.
#[derive(Debug, PartialEq)]
enum Value {
    Str(String),
    Bool(bool),
    Int(Option<u64>), // None: does not fit in u64
    Seq(Vec<Value>),
    Dict(Vec<(Value, Value)>),
    None,
}

/// Parses the header dict `{'descr': ..., 'fortran_order': ..., 'shape': (...)}`.
pub(crate) fn parse_header(text: &[u8]) -> Result<Header, String> {
    let mut p = Parser { s: text, i: 0 };
    let start = p.i;
    let v = p.value(0)?;
    p.skip_ws();
    if p.i != text.len() {
        return Err(format!("unexpected {} after the header dict", p.describe()));
    }
    let Value::Dict(entries) = v else {
        return Err(format!("the header must be a dict, found {}", show(&text[start..])));
    };
    let (mut descr, mut fortran, mut shape) = (None, None, None);
    for (k, v) in entries {
        let Value::Str(k) = k else {
            return Err("header keys must be strings".into());
        };
        let slot = match k.as_str() {
            "descr" => &mut descr,
            "fortran_order" => &mut fortran,
            "shape" => &mut shape,
            other => {
                return Err(format!(
                    "unexpected key {other:?} (expected 'descr', 'fortran_order', 'shape')"
                ))
            }
        };
        if slot.replace(v).is_some() {
            return Err(format!("key {k:?} appears twice"));
        }
    }
    let descr = descr.ok_or("missing key 'descr'")?;
    let fortran_order = match fortran.ok_or("missing key 'fortran_order'")? {
        Value::Bool(b) => b,
        other => return Err(format!("'fortran_order' must be True or False, found {other:?}")),
    };
    let shape = match shape.ok_or("missing key 'shape'")? {
        Value::Seq(items) => items
            .into_iter()
            .map(|d| match d {
                Value::Int(Some(n)) => Ok(n),
                Value::Int(None) => {
                    Err("a dimension of 'shape' does not fit in 64 bits".to_string())
                }
                other => Err(format!("'shape' must hold non-negative integers, found {other:?}")),
            })
            .collect::<Result<Vec<u64>, String>>()?,
        other => return Err(format!("'shape' must be a tuple, found {other:?}")),
    };
    let (descr, descr_text) = match descr {
        Value::Str(s) => (s.clone(), format!("'{s}'")),
        other => (String::new(), format!("{other:?} (a structured dtype)")),
    };
    Ok(Header { descr, descr_text, fortran_order, shape })
}

/// Up to 40 bytes of header text, printable.
fn show(b: &[u8]) -> String {
    let s = String::from_utf8_lossy(&b[..b.len().min(40)]).into_owned();
    format!("{s:?}")
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
}

impl Parser<'_> {
    fn peek(&self) -> Option<u8> {
        self.s.get(self.i).copied()
    }

    fn describe(&self) -> String {
        match self.peek() {
            None => "end of header".into(),
            Some(_) => format!("text {} at byte {}", show(&self.s[self.i..]), self.i),
        }
    }

    fn skip_ws(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.i += 1;
        }
    }

    fn expect(&mut self, c: u8) -> Result<(), String> {
        self.skip_ws();
        if self.peek() == Some(c) {
            self.i += 1;
            Ok(())
        } else {
            Err(format!("expected '{}', found {}", c as char, self.describe()))
        }
    }

    /// A comma-separated list of items up to `close`, allowing a trailing comma.
    fn items<T>(
        &mut self,
        close: u8,
        mut item: impl FnMut(&mut Self) -> Result<T, String>,
    ) -> Result<Vec<T>, String> {
        let mut out = Vec::new();
        loop {
            self.skip_ws();
            if self.peek() == Some(close) {
                self.i += 1;
                return Ok(out);
            }
            out.push(item(self)?);
            self.skip_ws();
            match self.peek() {
                Some(b',') => self.i += 1,
                Some(c) if c == close => {}
                _ => {
                    return Err(format!(
                        "expected ',' or '{}', found {}",
                        close as char,
                        self.describe()
                    ))
                }
            }
        }
    }

    fn value(&mut self, depth: usize) -> Result<Value, String> {
        if depth > MAX_DEPTH {
            return Err("header values are nested too deeply".into());
        }
        self.skip_ws();
        match self.peek() {
            Some(b'{') => {
                self.i += 1;
                let entries = self.items(b'}', |p| {
                    let k = p.value(depth + 1)?;
                    p.expect(b':')?;
                    let v = p.value(depth + 1)?;
                    Ok((k, v))
                })?;
                Ok(Value::Dict(entries))
            }
            Some(open @ (b'(' | b'[')) => {
                self.i += 1;
                let close = if open == b'(' { b')' } else { b']' };
                Ok(Value::Seq(self.items(close, |p| p.value(depth + 1))?))
            }
            Some(q @ (b'\'' | b'"')) => {
                self.i += 1;
                let start = self.i;
                while let Some(c) = self.peek() {
                    if c == q {
                        let s = String::from_utf8_lossy(&self.s[start..self.i]).into_owned();
                        self.i += 1;
                        return Ok(Value::Str(s));
                    }
                    if c == b'\\' || c == b'\n' {
                        return Err(
                            "escapes and line breaks in header strings are not supported".into()
                        );
                    }
                    self.i += 1;
                }
                Err("unterminated string in the header".into())
            }
            Some(b'0'..=b'9') => {
                let mut n: Option<u64> = Some(0);
                while let Some(d @ b'0'..=b'9') = self.peek() {
                    n = n
                        .and_then(|n| n.checked_mul(10))
                        .and_then(|n| n.checked_add((d - b'0') as u64));
                    self.i += 1;
                }
                // Python 2 wrote long integers with an L suffix.
                if self.peek() == Some(b'L') {
                    self.i += 1;
                }
                Ok(Value::Int(n))
            }
            Some(b'T' | b'F' | b'N') => {
                for (word, v) in [
                    ("True", Value::Bool(true)),
                    ("False", Value::Bool(false)),
                    ("None", Value::None),
                ] {
                    if self.s[self.i..].starts_with(word.as_bytes()) {
                        self.i += word.len();
                        return Ok(v);
                    }
                }
                Err(format!("unexpected {}", self.describe()))
            }
            _ => Err(format!("unexpected {}", self.describe())),
        }
    }
}

/// Writes `field` as a C-ordered little-endian float32 `.npy` file of shape
/// `(nz, ny, nx)` (version 1.0, readable by `np.load`). The field's origin is not stored.
///
/// The file is written to a temporary file in the same directory, flushed to disk
/// (`fsync`) and renamed over `path`, so `path` never holds a partial file; on error the
/// temporary file is removed and `path` is untouched.
pub fn write_npy(path: &Path, field: &DenseField) -> Result<(), NpyError> {
    crate::io::fsutil::write_atomic(path, |w| {
        let [nx, ny, nz] = field.dims();
        let dtype = npyz::DType::Plain("<f4".parse().expect("valid type string"));
        npyz::WriteOptions::<f32>::new()
            .dtype(dtype)
            .shape(&[nz as u64, ny as u64, nx as u64])
            .writer(&mut *w)
            .write_header_only()?;
        let mut buf = Vec::with_capacity(1 << 16);
        for chunk in field.data().chunks(1 << 14) {
            buf.clear();
            buf.extend(chunk.iter().flat_map(|v| v.to_le_bytes()));
            w.write_all(&buf)?;
        }
        Ok(())
    })
    .map_err(|source| NpyError::Io { path: path.to_path_buf(), source })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;
    use std::sync::atomic::{AtomicU64, Ordering};

    /// A fresh directory under the system temp dir, removed on drop.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new(tag: &str) -> Self {
            static N: AtomicU64 = AtomicU64::new(0);
            let nanos = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_nanos())
                .unwrap_or(0);
            let dir = std::env::temp_dir().join(format!(
                "sparse-levelset-npy-{tag}-{}-{nanos}-{}",
                std::process::id(),
                N.fetch_add(1, Ordering::Relaxed)
            ));
            fs::create_dir_all(&dir).unwrap();
            TempDir(dir)
        }

        fn file(&self, name: &str, bytes: &[u8]) -> PathBuf {
            let p = self.0.join(name);
            fs::write(&p, bytes).unwrap();
            p
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    /// A `.npy` file by hand: version, header dict text (padded like NumPy), data.
    fn npy_bytes(version: (u8, u8), dict: &str, data: &[u8]) -> Vec<u8> {
        let len_bytes = if version.0 == 1 { 2 } else { 4 };
        let mut header = dict.as_bytes().to_vec();
        while !(10 + len_bytes - 2 + header.len() + 1).is_multiple_of(64) {
            header.push(b' ');
        }
        header.push(b'\n');
        let mut out = b"\x93NUMPY".to_vec();
        out.extend([version.0, version.1]);
        out.extend(&(header.len() as u32).to_le_bytes()[..len_bytes]);
        out.extend(header);
        out.extend(data);
        out
    }

    fn f32_bytes(v: &[f32]) -> Vec<u8> {
        v.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    fn c_dict(shape: &str) -> String {
        format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}")
    }

    fn sample_field() -> DenseField {
        DenseField::from_fn(Coord::new(0, 0, 0), [4, 3, 2], |c| {
            (c.x + 10 * c.y + 100 * c.z) as f32 - 0.5
        })
        .unwrap()
    }

    #[test]
    fn arrays_beyond_memory_are_refused_before_allocating() {
        // Header and file size agree on a (4096, 2048, 2048) float32 array (64 GiB): a
        // sparse file, so no disk is used; reading must refuse it, not abort.
        let dir = TempDir::new("oom");
        let path = dir.file("huge.npy", &npy_bytes((1, 0), &c_dict("(4096, 2048, 2048)"), &[]));
        let header = fs::metadata(&path).unwrap().len();
        fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .unwrap()
            .set_len(header + (1 << 36))
            .unwrap();
        let info = inspect_npy(&path).unwrap();
        assert_eq!(info, NpyInfo { dims: [2048, 2048, 4096], fortran_order: false });
        assert_eq!(info.read_bytes(), (1u64 << 36) as f64);
        if crate::memory::limit() < 1 << 36 {
            let e = read_npy(&path).unwrap_err();
            assert!(matches!(e, NpyError::OutOfMemory { .. }), "{e}");
            let msg = e.to_string();
            assert!(msg.contains("huge.npy") && msg.contains("64.0 GiB"), "{msg}");
        }
    }

    #[test]
    fn round_trip_and_layout() {
        let dir = TempDir::new("rt");
        let path = dir.0.join("a.npy");
        let mut f = sample_field();
        f.set(Coord::new(1, 2, 1), f32::INFINITY).unwrap();
        f.set(Coord::new(2, 2, 1), f32::NEG_INFINITY).unwrap();
        f.set(Coord::new(3, 2, 1), -0.0).unwrap();
        write_npy(&path, &f).unwrap();
        let bytes = fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
        let hl = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + hl) % 64, 0, "NumPy aligns the data to 64 bytes");
        let text = std::str::from_utf8(&bytes[10..10 + hl]).unwrap();
        let h = parse_header(text.as_bytes()).unwrap();
        assert_eq!(
            (h.descr.as_str(), h.fortran_order, &h.shape[..]),
            ("<f4", false, &[2u64, 3, 4][..]),
            "{text}"
        );
        // Data in C order of (nz, ny, nx): x fastest.
        assert_eq!(&bytes[10 + hl..], &f32_bytes(f.data())[..]);
        let back = read_npy(&path).unwrap();
        assert_eq!(back.dims(), [4, 3, 2]);
        assert_eq!(back.origin(), Coord::new(0, 0, 0));
        let bits = |d: &DenseField| d.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back), bits(&f));
        // Overwriting in place, and the field origin is not stored.
        let g = DenseField::from_fn(Coord::new(-7, 3, 9), [1, 5, 1], |c| c.y as f32).unwrap();
        write_npy(&path, &g).unwrap();
        let back = read_npy(&path).unwrap();
        assert_eq!(back.dims(), [1, 5, 1]);
        assert_eq!(back.data(), g.data());
        // Only the target remains in the directory: no temporary files.
        assert_eq!(fs::read_dir(&dir.0).unwrap().count(), 1);
    }

    #[test]
    fn reads_numpy_style_headers_and_versions() {
        let dir = TempDir::new("versions");
        let f = sample_field();
        let data = f32_bytes(f.data());
        let dicts = [
            c_dict("(2, 3, 4)"),
            "{'descr':'<f4','fortran_order':False,'shape':(2,3,4)}".to_string(),
            "{\"shape\": (2L, 3L, 4L), \"fortran_order\": False, \"descr\": \"<f4\"}".to_string(),
            "{'descr': '<f4', 'fortran_order': False, 'shape': [2, 3, 4]}".to_string(),
        ];
        for (n, dict) in dicts.iter().enumerate() {
            for version in [(1, 0), (2, 0), (3, 0)] {
                let p =
                    dir.file(&format!("v{n}-{}.npy", version.0), &npy_bytes(version, dict, &data));
                assert_eq!(read_npy(&p).unwrap(), f, "{dict} {version:?}");
            }
        }
    }

    /// Fortran order keeps the logical array: arr[z, y, x] is voxel (x, y, z).
    #[test]
    fn fortran_order_is_transposed() {
        let dir = TempDir::new("fortran");
        let f = sample_field();
        let [nx, ny, nz] = f.dims();
        // Fortran order of the logical (nz, ny, nx) array: z fastest, then y, then x.
        let mut data = Vec::new();
        for x in 0..nx {
            for y in 0..ny {
                for z in 0..nz {
                    data.push(f.get(Coord::new(x as i32, y as i32, z as i32)).unwrap());
                }
            }
        }
        let dict = "{'descr': '<f4', 'fortran_order': True, 'shape': (2, 3, 4), }";
        let p = dir.file("f.npy", &npy_bytes((1, 0), dict, &f32_bytes(&data)));
        assert_eq!(read_npy(&p).unwrap(), f);
        // A NaN is reported at its logical voxel.
        data[1 + nz * (2 + ny * 3)] = f32::NAN; // z = 1, y = 2, x = 3
        let p = dir.file("fnan.npy", &npy_bytes((1, 0), dict, &f32_bytes(&data)));
        match read_npy(&p) {
            Err(NpyError::NaN { x: 3, y: 2, z: 1, .. }) => {}
            other => panic!("{other:?}"),
        }
    }

    /// A (nz, ny, nx, 3) field in C and Fortran order gives the same three components;
    /// a volume is not a vector field and a vector field is not a volume; a NaN is found
    /// in any component.
    #[test]
    fn vector_fields_in_either_order() {
        let dir = TempDir::new("vec");
        let comp = |c: usize| {
            DenseField::from_fn(Coord::new(0, 0, 0), [4, 3, 2], move |v| {
                (v.x + 10 * v.y + 100 * v.z) as f32 + 0.25 * c as f32
            })
            .unwrap()
        };
        let want = [comp(0), comp(1), comp(2)];
        let (nx, ny, nz) = (4, 3, 2);
        let at = |x, y, z, c: usize| want[c].get(Coord::new(x, y, z)).unwrap();
        let mut c_data = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    c_data.extend((0..3).map(|c| at(x, y, z, c)));
                }
            }
        }
        let mut f_data = Vec::new();
        for c in 0..3 {
            for x in 0..nx {
                for y in 0..ny {
                    for z in 0..nz {
                        f_data.push(at(x, y, z, c));
                    }
                }
            }
        }
        let f_dict = "{'descr': '<f4', 'fortran_order': True, 'shape': (2, 3, 4, 3), }";
        let pc =
            dir.file("c.npy", &npy_bytes((1, 0), &c_dict("(2, 3, 4, 3)"), &f32_bytes(&c_data)));
        let pf = dir.file("f.npy", &npy_bytes((1, 0), f_dict, &f32_bytes(&f_data)));
        assert_eq!(read_npy_vector(&pc).unwrap(), want);
        assert_eq!(read_npy_vector(&pf).unwrap(), want);
        assert!(matches!(read_npy(&pc), Err(NpyError::NotThreeD { .. })));
        let vol =
            dir.file("v.npy", &npy_bytes((1, 0), &c_dict("(2, 3, 4)"), &f32_bytes(want[0].data())));
        assert!(matches!(read_npy_vector(&vol), Err(NpyError::NotVectorField { .. })));
        let two = dir.file(
            "two.npy",
            &npy_bytes((1, 0), &c_dict("(2, 3, 4, 2)"), &f32_bytes(&c_data[..48])),
        );
        assert!(matches!(read_npy_vector(&two), Err(NpyError::NotVectorField { .. })));
        // u_z of voxel (3, 2, 1) is NaN.
        c_data[3 * (3 + nx as usize * (2 + ny as usize)) + 2] = f32::NAN;
        let pn =
            dir.file("n.npy", &npy_bytes((1, 0), &c_dict("(2, 3, 4, 3)"), &f32_bytes(&c_data)));
        assert!(matches!(read_npy_vector(&pn), Err(NpyError::NaN { x: 3, y: 2, z: 1, .. })));
    }

    #[test]
    fn each_bad_input_gives_its_error() {
        let dir = TempDir::new("bad");
        let good = f32_bytes(sample_field().data());
        let check = |name: &str, bytes: Vec<u8>, pred: &dyn Fn(&NpyError) -> bool| {
            let p = dir.file(name, &bytes);
            match read_npy(&p) {
                Err(e) => {
                    assert!(pred(&e), "{name}: wrong error {e:?}");
                    let msg = e.to_string();
                    assert!(msg.contains(name), "{name}: message does not name the file: {msg}");
                }
                Ok(_) => panic!("{name}: accepted"),
            }
        };
        check("empty.npy", vec![], &|e| matches!(e, NpyError::NotNpy { .. }));
        check("text.npy", b"hello world, this is not numpy".to_vec(), &|e| {
            matches!(e, NpyError::NotNpy { .. })
        });
        check("version.npy", npy_bytes((4, 0), &c_dict("(2, 3, 4)"), &good), &|e| {
            matches!(e, NpyError::UnsupportedVersion { major: 4, minor: 0, .. })
        });
        check("minor.npy", npy_bytes((1, 1), &c_dict("(2, 3, 4)"), &good), &|e| {
            matches!(e, NpyError::UnsupportedVersion { .. })
        });
        let f8 = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3, 4), }";
        check(
            "f8.npy",
            npy_bytes((1, 0), f8, &[good.clone(), good.clone()].concat()),
            &|e| match e {
                NpyError::WrongDtype { found, .. } => {
                    found == "'<f8'" && e.to_string().contains("astype(np.float32)")
                }
                _ => false,
            },
        );
        let be = "{'descr': '>f4', 'fortran_order': False, 'shape': (2, 3, 4), }";
        check("be.npy", npy_bytes((1, 0), be, &good), &|e| {
            matches!(e, NpyError::WrongDtype { .. })
        });
        let rec = "{'descr': [('a', '<f4')], 'fortran_order': False, 'shape': (2, 3, 4), }";
        check("rec.npy", npy_bytes((1, 0), rec, &good), &|e| {
            matches!(e, NpyError::WrongDtype { .. })
        });
        check(
            "2d.npy",
            npy_bytes((1, 0), &c_dict("(6, 4)"), &good),
            &|e| matches!(e, NpyError::NotThreeD { shape, .. } if shape == &[6, 4]),
        );
        check("4d.npy", npy_bytes((1, 0), &c_dict("(1, 2, 3, 4)"), &good), &|e| {
            matches!(e, NpyError::NotThreeD { .. })
        });
        check("0d.npy", npy_bytes((1, 0), &c_dict("()"), &good[..4]), &|e| {
            matches!(e, NpyError::NotThreeD { .. })
        });
        check("emptydim.npy", npy_bytes((1, 0), &c_dict("(2, 0, 4)"), &[]), &|e| {
            matches!(e, NpyError::EmptyDimension { .. })
        });
        check(
            "trunc.npy",
            npy_bytes((1, 0), &c_dict("(2, 3, 4)"), &good[..good.len() - 3]),
            &|e| matches!(e, NpyError::Truncated { expected: 96, found: 93, .. }),
        );
        check(
            "trailing.npy",
            npy_bytes((1, 0), &c_dict("(2, 3, 4)"), &[&good[..], b"xyz"].concat()),
            &|e| matches!(e, NpyError::TrailingBytes { expected: 96, found: 99, .. }),
        );
        // Hostile shapes: products overflowing 64 bits, or far beyond the file size.
        check(
            "overflow.npy",
            npy_bytes((1, 0), &c_dict("(4294967296, 4294967296, 4294967296)"), &good),
            &|e| matches!(e, NpyError::TooLarge { .. }),
        );
        check("huge.npy", npy_bytes((1, 0), &c_dict("(100000, 100000, 100000)"), &good), &|e| {
            matches!(e, NpyError::Truncated { expected: 4_000_000_000_000_000, found: 96, .. })
        });
        check(
            "dim64.npy",
            npy_bytes((1, 0), &c_dict("(99999999999999999999, 1, 1)"), &good),
            &|e| matches!(e, NpyError::BadHeader { .. }),
        );
        check("negative.npy", npy_bytes((1, 0), &c_dict("(-2, 3, 4)"), &good), &|e| {
            matches!(e, NpyError::BadHeader { .. })
        });
        // nx = 2^31 + 1 voxels: x coordinates would leave i32 (checked before the size).
        check("wide.npy", npy_bytes((1, 0), &c_dict("(1, 1, 2147483649)"), &good), &|e| {
            matches!(e, NpyError::TooLarge { .. })
        });
        // Malformed headers.
        let bad_dicts = [
            "{'descr': '<f4', 'fortran_order': False}",
            "{'descr': '<f4', 'fortran_order': 0, 'shape': (2, 3, 4)}",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4), 'extra': 1}",
            "{'descr': '<f4', 'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4)}",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4)",
            "['descr', '<f4']",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4)} junk",
            "{'descr': '<f4, 'fortran_order': False, 'shape': (2, 3, 4)}",
            "{'descr': '<f4', 'fortran_order': False, 'shape': 24}",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2.0, 3, 4)}",
            "{'descr': '<f4', 'fortran_order': Fals, 'shape': (2, 3, 4)}",
            "",
            "\u{e9}\u{e9}",
            &format!(
                "{{'descr': '<f4', 'fortran_order': False, 'shape': {}2{}}}",
                "(".repeat(50),
                ")".repeat(50)
            ),
        ];
        for (n, d) in bad_dicts.iter().enumerate() {
            check(&format!("header{n}.npy"), npy_bytes((1, 0), d, &good), &|e| {
                matches!(e, NpyError::BadHeader { .. })
            });
        }
        // Header length beyond the file, and implausibly large.
        let mut b = npy_bytes((2, 0), &c_dict("(2, 3, 4)"), &good);
        b[8..12].copy_from_slice(&5000u32.to_le_bytes());
        check("hlen.npy", b.clone(), &|e| matches!(e, NpyError::BadHeader { .. }));
        b[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
        check("hlenmax.npy", b, &|e| matches!(e, NpyError::BadHeader { .. }));
        // NaN names the first voxel in (x, y, z) order.
        let mut data = sample_field().into_data();
        data[3 + 4 * 4] = f32::NAN; // (3, 1, 1): 3 + nx (1 + ny 1)
        data[4 * 3 * 2 - 1] = f32::NAN; // (3, 2, 1), later
        check("nan.npy", npy_bytes((1, 0), &c_dict("(2, 3, 4)"), &f32_bytes(&data)), &|e| {
            matches!(e, NpyError::NaN { x: 3, y: 1, z: 1, .. })
                && e.to_string().contains("arr[1, 1, 3]")
        });
        // A missing file is an I/O error naming the path.
        let missing = dir.0.join("missing.npy");
        match read_npy(&missing) {
            Err(e @ NpyError::Io { .. }) => assert!(e.to_string().contains("missing.npy")),
            other => panic!("{other:?}"),
        }
    }

    /// Every prefix of a valid file is rejected, without panicking.
    #[test]
    fn truncation_at_every_offset_never_panics() {
        let dir = TempDir::new("trunc");
        let full = npy_bytes((1, 0), &c_dict("(2, 3, 4)"), &f32_bytes(sample_field().data()));
        let full3 = npy_bytes((3, 0), &c_dict("(2, 3, 4)"), &f32_bytes(sample_field().data()));
        for bytes in [full, full3] {
            let path = dir.0.join("t.npy");
            for cut in 0..bytes.len() {
                fs::write(&path, &bytes[..cut]).unwrap();
                let r = std::panic::catch_unwind(|| read_npy(&path));
                match r {
                    Ok(Err(_)) => {}
                    Ok(Ok(_)) => panic!("prefix of {cut} bytes accepted"),
                    Err(_) => panic!("prefix of {cut} bytes panicked"),
                }
                // The in-memory path (pipes) behaves the same.
                assert!(read_from::<1>(&mut &bytes[..cut], cut as u64, &path).is_err());
            }
            fs::write(&path, &bytes).unwrap();
            assert_eq!(read_npy(&path).unwrap(), sample_field());
        }
    }

    /// Random byte corruption of the header never panics.
    #[test]
    fn corrupted_headers_never_panic() {
        let full = npy_bytes((1, 0), &c_dict("(2, 3, 4)"), &f32_bytes(sample_field().data()));
        let mut rng = fastrand::Rng::with_seed(99);
        for _ in 0..5000 {
            let mut b = full.clone();
            for _ in 0..rng.usize(1..4) {
                let i = rng.usize(0..128);
                b[i] = rng.u8(..);
            }
            let path = Path::new("corrupt.npy");
            let r = std::panic::catch_unwind(|| read_from::<1>(&mut &b[..], b.len() as u64, path));
            assert!(r.is_ok(), "panicked on {:?}", String::from_utf8_lossy(&b[..128]));
            let r = std::panic::catch_unwind(|| read_from::<3>(&mut &b[..], b.len() as u64, path));
            assert!(r.is_ok(), "panicked on {:?}", String::from_utf8_lossy(&b[..128]));
        }
    }

    #[test]
    fn failed_writes_leave_nothing_behind() {
        let dir = TempDir::new("wfail");
        let f = sample_field();
        // Target is an existing directory: the rename fails, the temp file is removed.
        let target = dir.0.join("adir");
        fs::create_dir(&target).unwrap();
        fs::write(target.join("keep"), b"x").unwrap();
        assert!(matches!(write_npy(&target, &f), Err(NpyError::Io { .. })));
        let names: Vec<_> = fs::read_dir(&dir.0).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("adir")]);
        // Missing directory.
        let e = write_npy(&dir.0.join("no/such/dir/a.npy"), &f).unwrap_err();
        assert!(e.to_string().contains("a.npy"), "{e}");
        // Existing target file is replaced whole.
        let p = dir.file("b.npy", b"old contents");
        write_npy(&p, &f).unwrap();
        assert_eq!(read_npy(&p).unwrap(), f);
    }
}
