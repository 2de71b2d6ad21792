//! Triangle-mesh files, in ([`load_mesh`]: OBJ, PLY, STL) and out ([`save_mesh`]: PLY, OBJ,
//! binary STL), with one format enum chosen by the file's extension.

mod read;
mod write;

pub use read::{load_mesh, MeshInError};
pub use write::save_mesh;

use std::path::Path;

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (read: `v` and `f` lines, other records ignored; written with `vn`).
    Obj,
    /// PLY: read ASCII or binary (a `vertex` element with `x y z`, a `face` element with a
    /// `vertex_indices` or `vertex_index` list); written binary little-endian, or ASCII when
    /// `ascii`.
    Ply {
        /// Write ASCII PLY (reading tells the encoding from the header).
        ascii: bool,
    },
    /// STL: read ASCII or binary (told apart by the size of a binary file); written binary.
    Stl,
}

impl MeshFormat {
    /// The extensions of mesh files, for messages.
    pub const EXTENSIONS: &'static str = ".obj, .ply, .stl";

    /// The format's name, for messages (`"binary PLY"`, `"OBJ"`, ...).
    pub fn name(self) -> &'static str {
        match self {
            MeshFormat::Obj => "OBJ",
            MeshFormat::Ply { ascii: false } => "binary PLY",
            MeshFormat::Ply { ascii: true } => "ASCII PLY",
            MeshFormat::Stl => "binary STL",
        }
    }

    /// The format a path's extension names (`.obj`, `.ply`, `.stl`, any case); PLY as
    /// binary.
    pub fn from_path(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(MeshFormat::Obj),
            "ply" => Some(MeshFormat::Ply { ascii: false }),
            "stl" => Some(MeshFormat::Stl),
            _ => None,
        }
    }
}
