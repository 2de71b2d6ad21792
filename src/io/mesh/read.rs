//! Mesh files in ([`load_mesh`]): Wavefront OBJ (`tobj`), PLY, ASCII or binary
//! (`ply-rs-bw`), and STL, ASCII or binary (`stl_io`), chosen by the extension (`.obj`,
//! `.ply`, `.stl`, any case).
//!
//! One loader, one verdict: every file goes through [`load_mesh`], which returns a
//! [`TriangleMesh`] with polygons split into triangle fans and no normals, or a
//! [`MeshInError`] that names the file. Bad input is an error, never a panic, and nothing
//! is allocated beyond what the file's size can justify:
//!
//! * the file's size is checked against the memory budget ([`crate::memory::check`])
//!   before it is read;
//! * element counts that a header claims (binary STL's triangle count in bytes 80..84,
//!   PLY's `element` lines) are checked against the bytes that follow the header before
//!   the crate reading the payload sees them: each element needs at least a known number
//!   of bytes (binary: the sizes of its scalar properties and list counts; ASCII: one
//!   character and one separator per property);
//! * then the mesh itself: every coordinate finite ([`MeshInError::NonFinite`]), every
//!   index in range ([`MeshInError::IndexOutOfRange`]), at least one triangle
//!   ([`MeshInError::Empty`]).
//!
//! Whether the coordinates fit the voxel grid is the voxelizer's check, once it knows the
//! voxel size ([`crate::tools::voxelize`]).
//!
//! ```
//! use sparse_levelset::io::mesh::load_mesh;
//!
//! let path = std::env::temp_dir().join(format!("read-doc-{}.obj", std::process::id()));
//! std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
//! let mesh = load_mesh(&path).unwrap();
//! assert_eq!(mesh.triangles, [[0, 1, 2], [0, 2, 3]]); // the quad as a fan
//! assert!(mesh.normals.is_empty());
//! std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n").unwrap();
//! let err = load_mesh(&path).unwrap_err().to_string();
//! assert!(err.contains("not finite") && err.contains("read-doc"), "{err}");
//! std::fs::remove_file(&path).unwrap();
//! ```

use super::MeshFormat;
use crate::tools::mesh::TriangleMesh;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{Encoding, Header, Property, PropertyAccess, PropertyType, ScalarType};
use std::path::{Path, PathBuf};

/// Why a mesh file was refused; every message starts with the file's path.
#[derive(Debug, thiserror::Error)]
pub enum MeshInError {
    /// The extension names no format [`load_mesh`] reads.
    #[error("{}: unknown mesh format (use .obj, .ply or .stl)", .path.display())]
    UnknownFormat { path: PathBuf },
    /// The file cannot be opened or read.
    #[error("{}: {source}", .path.display())]
    Io { path: PathBuf, source: std::io::Error },
    /// The file is not a well-formed file of its format (truncated, garbage, not UTF-8
    /// where text is expected, ...); `message` is the reader's.
    #[error("{}: not a valid {format} file: {message}", .path.display())]
    Parse { path: PathBuf, format: &'static str, message: String },
    /// A header claims more elements than the rest of the file can hold.
    #[error(
        "{}: the header claims {claimed} {what}, which need at least {needed} bytes, but only \
         {available} bytes follow it (truncated or corrupt file)",
        .path.display()
    )]
    Truncated { path: PathBuf, what: String, claimed: u64, needed: u128, available: u64 },
    /// A vertex coordinate is NaN or infinite.
    #[error("{}: vertex {vertex} has a coordinate that is not finite: {value}", .path.display())]
    NonFinite { path: PathBuf, vertex: usize, value: f64 },
    /// A face refers to a vertex that does not exist.
    #[error(
        "{}: face {face} refers to vertex {index}, but the file has {vertices} vertices \
         (numbered from {base})",
        .path.display()
    )]
    IndexOutOfRange { path: PathBuf, face: usize, index: i64, vertices: usize, base: u8 },
    /// No triangle (no face with three or more vertices).
    #[error("{}: the mesh has no triangles", .path.display())]
    Empty { path: PathBuf },
    /// More vertices than 32-bit indices address, or a file larger than the memory budget.
    #[error("{}: {message}", .path.display())]
    TooLarge { path: PathBuf, message: String },
}

impl crate::error::Error for MeshInError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            MeshInError::UnknownFormat { .. } => UnknownFormat,
            MeshInError::Io { source, .. } => crate::error::io_kind(source),
            MeshInError::Parse { .. }
            | MeshInError::Truncated { .. }
            | MeshInError::IndexOutOfRange { .. } => CorruptFile,
            MeshInError::NonFinite { .. } | MeshInError::Empty { .. } => InvalidData,
            MeshInError::TooLarge { .. } => OutOfMemory,
        }
    }
}

/// Reads a triangle mesh from an OBJ, PLY or STL file, chosen by the extension (see the
/// [module docs](crate::io::mesh) for the checks). Polygons become triangle fans `(v0, vi, vi+1)`;
/// faces of fewer than three vertices are skipped; normals are left empty. Vertices are
/// kept as the file has them (STL's are merged where their bits are equal).
pub fn load_mesh(path: &Path) -> Result<TriangleMesh, MeshInError> {
    let format = MeshFormat::from_path(path)
        .ok_or_else(|| MeshInError::UnknownFormat { path: path.to_path_buf() })?;
    let io = |source| MeshInError::Io { path: path.to_path_buf(), source };
    let len = std::fs::metadata(path).map_err(io)?.len();
    // The file is read whole (into memory once, parsed from there): its size is the budget.
    crate::memory::check(len as f64 * 2.0, "the mesh file and its parse")
        .map_err(|e| MeshInError::TooLarge { path: path.to_path_buf(), message: e.to_string() })?;
    let bytes = std::fs::read(path).map_err(io)?;
    let mesh = match format {
        MeshFormat::Obj => read_obj(path, &bytes)?,
        MeshFormat::Ply { .. } => read_ply(path, &bytes)?,
        MeshFormat::Stl => read_stl(path, bytes)?,
    };
    check_mesh(path, mesh)
}

/// A mesh under construction: positions and faces with indices as the file gives them
/// (0-based), checked by [`check_mesh`].
struct RawMesh {
    positions: Vec<[f64; 3]>,
    /// Polygons, each as a range of `indices`.
    faces: Vec<(usize, usize)>,
    indices: Vec<i64>,
    /// How the file numbers its vertices (OBJ: 1), for messages.
    base: u8,
}

impl RawMesh {
    fn new(base: u8) -> Self {
        RawMesh { positions: Vec::new(), faces: Vec::new(), indices: Vec::new(), base }
    }

    fn push_face(&mut self, face: impl IntoIterator<Item = i64>) {
        let start = self.indices.len();
        self.indices.extend(face);
        self.faces.push((start, self.indices.len()));
    }
}

/// The mesh checks of the module docs, then the fan triangulation.
fn check_mesh(path: &Path, raw: RawMesh) -> Result<TriangleMesh, MeshInError> {
    let n = raw.positions.len();
    if n > u32::MAX as usize {
        return Err(MeshInError::TooLarge {
            path: path.to_path_buf(),
            message: format!("{n} vertices: more than 32-bit indices address"),
        });
    }
    for (vertex, p) in raw.positions.iter().enumerate() {
        if let Some(&value) = p.iter().find(|c| !c.is_finite()) {
            return Err(MeshInError::NonFinite { path: path.to_path_buf(), vertex, value });
        }
    }
    let mut triangles = Vec::with_capacity(raw.faces.len());
    for (face, &(s, e)) in raw.faces.iter().enumerate() {
        let f = &raw.indices[s..e];
        if let Some(&index) = f.iter().find(|&&i| i < 0 || i as u64 >= n as u64) {
            let index = index + raw.base as i64;
            return Err(MeshInError::IndexOutOfRange {
                path: path.to_path_buf(),
                face,
                index,
                vertices: n,
                base: raw.base,
            });
        }
        for i in 1..f.len().saturating_sub(1) {
            triangles.push([f[0] as u32, f[i] as u32, f[i + 1] as u32]);
        }
    }
    if triangles.is_empty() {
        return Err(MeshInError::Empty { path: path.to_path_buf() });
    }
    Ok(TriangleMesh { positions: raw.positions, normals: Vec::new(), triangles })
}

fn parse_error(path: &Path, format: &'static str, message: impl ToString) -> MeshInError {
    MeshInError::Parse { path: path.to_path_buf(), format, message: message.to_string() }
}

/// OBJ through `tobj`: positions in f64, polygons kept (split into fans by
/// [`check_mesh`]), points and lines ignored, material libraries not loaded. `tobj`
/// checks the face indices against the positions read so far (relative indices
/// included).
fn read_obj(path: &Path, bytes: &[u8]) -> Result<RawMesh, MeshInError> {
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) =
        tobj::load_obj_buf(&mut &bytes[..], &options, |_| Err(tobj::LoadError::OpenFileFailed))
            .map_err(|e| parse_error(path, "OBJ", e))?;
    let mut raw = RawMesh::new(1);
    for model in &models {
        let m = &model.mesh;
        let offset = raw.positions.len() as i64;
        raw.positions.extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        if m.face_arities.is_empty() {
            for t in m.indices.chunks_exact(3) {
                raw.push_face(t.iter().map(|&i| i as i64 + offset));
            }
        } else {
            let mut s = 0usize;
            for &arity in &m.face_arities {
                let e = (s + arity as usize).min(m.indices.len());
                raw.push_face(m.indices[s..e].iter().map(|&i| i as i64 + offset));
                s = e;
            }
        }
    }
    Ok(raw)
}

/// A PLY vertex: `x`, `y`, `z` of any numeric type; other properties ignored.
#[derive(Default)]
struct PlyVertex([f64; 3]);

/// A PLY face: its `vertex_indices` (or `vertex_index`) list of any integer type.
#[derive(Default)]
struct PlyFace(Option<Result<Vec<i64>, &'static str>>);

/// Any other PLY element: read (the payload is sequential) and dropped.
struct PlyIgnored;

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

impl PropertyAccess for PlyVertex {
    fn new() -> Self {
        PlyVertex::default()
    }
    fn set_property(
        &mut self,
        name: &str,
        property: Property,
    ) -> ply_rs_bw::ply::PropertyAccessResult {
        use ply_rs_bw::ply::PropertyAccessResult as R;
        let axis = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return R::Ignored,
        };
        match scalar(&property) {
            Some(v) => {
                self.0[axis] = v;
                R::Set
            }
            None => R::UnsupportedType,
        }
    }
}

impl PropertyAccess for PlyFace {
    fn new() -> Self {
        PlyFace::default()
    }
    fn set_property(
        &mut self,
        name: &str,
        property: Property,
    ) -> ply_rs_bw::ply::PropertyAccessResult {
        use ply_rs_bw::ply::PropertyAccessResult as R;
        if name != "vertex_indices" && name != "vertex_index" {
            return R::Ignored;
        }
        let list: Vec<i64> = match property {
            Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
            _ => {
                self.0 = Some(Err("face vertex indices must be a list of integers"));
                return R::Set;
            }
        };
        self.0 = Some(Ok(list));
        R::Set
    }
}

impl PropertyAccess for PlyIgnored {
    fn new() -> Self {
        PlyIgnored
    }
}

/// The fewest bytes one element of `props` takes in the payload: binary, the scalar
/// sizes and list counts (an empty list); ASCII, one character and one separator per
/// value. At least one byte, so that a count is always bounded by the file's size.
fn min_element_bytes(props: &[PropertyType], encoding: Encoding) -> u64 {
    let size = |t: &ScalarType| match t {
        ScalarType::Char | ScalarType::UChar => 1u64,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    };
    let n: u64 = match encoding {
        Encoding::Ascii => 2 * props.len() as u64,
        _ => props
            .iter()
            .map(|p| match p {
                PropertyType::Scalar(t) => size(t),
                PropertyType::List(count, _) => size(count),
            })
            .sum(),
    };
    n.max(1)
}

/// PLY through `ply-rs-bw`: the header first, then the element counts checked against the
/// bytes after it, then the payload element by element.
fn read_ply(path: &Path, bytes: &[u8]) -> Result<RawMesh, MeshInError> {
    let perr = |e: ply_rs_bw::parser::ParseError| parse_error(path, "PLY", e);
    let mut reader = Reader::new(bytes);
    let header: Header = Parser::<PlyIgnored>::new().read_header(&mut reader).map_err(perr)?;
    let available = reader.get_ref().len() as u64;
    let mut needed: u128 = 0;
    for (name, def) in &header.elements {
        let props: Vec<PropertyType> =
            def.properties.values().map(|p| p.data_type.clone()).collect();
        let per = min_element_bytes(&props, header.encoding) as u128;
        needed += def.count as u128 * per;
        if needed > available as u128 {
            return Err(MeshInError::Truncated {
                path: path.to_path_buf(),
                what: format!("'{name}' elements"),
                claimed: def.count as u64,
                needed,
                available,
            });
        }
    }
    if !header.elements.contains_key("vertex") || !header.elements.contains_key("face") {
        return Err(parse_error(path, "PLY", "it needs a 'vertex' and a 'face' element"));
    }
    let mut raw = RawMesh::new(0);
    for (name, def) in &header.elements {
        match name.as_str() {
            "vertex" => {
                for axis in ["x", "y", "z"] {
                    if !def.properties.contains_key(axis) {
                        return Err(parse_error(
                            path,
                            "PLY",
                            format!("the 'vertex' element has no property '{axis}'"),
                        ));
                    }
                }
                let v = Parser::<PlyVertex>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(perr)?;
                raw.positions = v.into_iter().map(|v| v.0).collect();
            }
            "face" => {
                let faces = Parser::<PlyFace>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(perr)?;
                for (i, f) in faces.into_iter().enumerate() {
                    match f.0 {
                        Some(Ok(list)) => raw.push_face(list),
                        Some(Err(msg)) => return Err(parse_error(path, "PLY", msg)),
                        None => {
                            return Err(parse_error(
                                path,
                                "PLY",
                                format!("face {i} has no 'vertex_indices' list"),
                            ))
                        }
                    }
                }
            }
            _ => {
                Parser::<PlyIgnored>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(perr)?;
            }
        }
    }
    Ok(raw)
}

/// Bytes of a binary STL header (80) and triangle count (4), and of one triangle record.
const STL_HEADER: u64 = 84;
const STL_TRIANGLE: u64 = 50;

/// STL through `stl_io`. A file whose size is exactly `84 + 50 n` for the count `n` in
/// bytes 80..84 is binary (some binary files begin with "solid" too: their header is
/// blanked before `stl_io`, which would take them for ASCII, sees it); any other file
/// beginning with "solid" is ASCII; anything else is binary, and its count must fit in
/// the file.
fn read_stl(path: &Path, mut bytes: Vec<u8>) -> Result<RawMesh, MeshInError> {
    let len = bytes.len() as u64;
    let count = bytes.get(80..84).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64);
    let exact_binary = count.is_some_and(|n| STL_HEADER + STL_TRIANGLE * n == len);
    let solid = bytes.starts_with(b"solid");
    if exact_binary && solid {
        bytes[..5].fill(b' ');
    } else if solid {
        // `stl_io` wants "solid " with a blank: a bare "solid" line is fine too.
        if bytes.get(5).is_some_and(|&c| c == b'\n' || c == b'\r') {
            bytes.insert(5, b' ');
        }
    } else {
        let Some(n) = count else {
            return Err(parse_error(
                path,
                "STL",
                format!("{len} bytes: shorter than a binary STL header (84 bytes)"),
            ));
        };
        let needed = STL_HEADER as u128 + STL_TRIANGLE as u128 * n as u128;
        if needed > len as u128 {
            return Err(MeshInError::Truncated {
                path: path.to_path_buf(),
                what: "triangles".into(),
                claimed: n,
                needed,
                available: len,
            });
        }
    }
    let stl = stl_io::read_stl(&mut std::io::Cursor::new(bytes))
        .map_err(|e| parse_error(path, "STL", e))?;
    let mut raw = RawMesh::new(0);
    raw.positions = stl.vertices.iter().map(|v| v.0.map(|c| c as f64)).collect();
    for f in &stl.faces {
        raw.push_face(f.vertices.iter().map(|&i| i as i64));
    }
    Ok(raw)
}
