//! Mesh files: PLY (binary little-endian or ASCII, normals as `float`, faces as
//! `list uchar int`) and Wavefront OBJ (`v`, `vn`, `f a//a b//b c//c`). Every file is
//! written atomically through [`crate::fsutil::write_atomic`].
//!
//! Positions are written without loss: as `float` when every coordinate is an f32 value
//! (what the isosurface functions store whenever f32 holds the mesh), as `double`
//! otherwise; in text (ASCII PLY, OBJ) as the shortest decimal that reads back as the
//! same f32 or f64 value.

use super::{MeshError, TriangleMesh};
use std::io::{self, Write};
use std::path::Path;

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    PlyBinary,
    PlyAscii,
    Obj,
}

impl MeshFormat {
    /// The format a path's extension names (`.ply`, `.obj`, any case); `ascii` selects
    /// ASCII PLY (OBJ is always text).
    pub fn from_path(path: &Path, ascii: bool) -> Result<MeshFormat, MeshError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("ply") if ascii => Ok(MeshFormat::PlyAscii),
            Some("ply") => Ok(MeshFormat::PlyBinary),
            Some("obj") => Ok(MeshFormat::Obj),
            _ => Err(MeshError::UnknownFormat(path.to_path_buf())),
        }
    }
}

impl TriangleMesh {
    /// Writes the mesh to `path` in `format`, or in the format of the path's extension
    /// (binary PLY for `.ply`) when `None`. The file appears complete or not at all.
    pub fn write(&self, path: &Path, format: Option<MeshFormat>) -> Result<(), MeshError> {
        let format = match format {
            Some(f) => f,
            None => MeshFormat::from_path(path, false)?,
        };
        if self.normals.len() != self.positions.len() {
            return Err(MeshError::InvalidParameter(format!(
                "{} normals for {} vertices",
                self.normals.len(),
                self.positions.len()
            )));
        }
        if let Some(t) =
            self.triangles.iter().find(|t| t.iter().any(|&v| v as usize >= self.positions.len()))
        {
            return Err(MeshError::InvalidParameter(format!(
                "triangle {t:?} indexes beyond {} vertices",
                self.positions.len()
            )));
        }
        if self.positions.len() > i32::MAX as usize {
            return Err(MeshError::TooLarge(format!(
                "{} vertices: PLY indices are 32-bit signed",
                self.positions.len()
            )));
        }
        let io_err = |source| MeshError::Io { path: path.to_path_buf(), source };
        crate::fsutil::write_atomic(path, |w| match format {
            MeshFormat::PlyBinary => self.write_ply(w, false),
            MeshFormat::PlyAscii => self.write_ply(w, true),
            MeshFormat::Obj => self.write_obj(w),
        })
        .map_err(io_err)
    }

    /// Whether every coordinate is an f32 value, so that `float` holds the positions
    /// exactly (NaN and ±∞ convert exactly too).
    pub fn positions_are_f32(&self) -> bool {
        self.positions.iter().flatten().all(|&c| c.is_nan() || c as f32 as f64 == c)
    }

    fn write_ply(&self, w: &mut impl Write, ascii: bool) -> io::Result<()> {
        let fmt = if ascii { "ascii" } else { "binary_little_endian" };
        let single = self.positions_are_f32();
        let ty = if single { "float" } else { "double" };
        write!(
            w,
            "ply\nformat {fmt} 1.0\ncomment sparse-levelset simplicial isosurface\n\
             element vertex {}\nproperty {ty} x\nproperty {ty} y\nproperty {ty} z\n\
             property float nx\nproperty float ny\nproperty float nz\n\
             element face {}\nproperty list uchar int vertex_indices\nend_header\n",
            self.positions.len(),
            self.triangles.len()
        )?;
        if ascii {
            for (p, n) in self.positions.iter().zip(&self.normals) {
                if single {
                    let q = p.map(|c| c as f32);
                    write!(w, "{} {} {}", q[0], q[1], q[2])?;
                } else {
                    write!(w, "{} {} {}", p[0], p[1], p[2])?;
                }
                writeln!(w, " {} {} {}", n[0], n[1], n[2])?;
            }
            for t in &self.triangles {
                writeln!(w, "3 {} {} {}", t[0], t[1], t[2])?;
            }
        } else {
            for (p, n) in self.positions.iter().zip(&self.normals) {
                for &c in p {
                    if single {
                        w.write_all(&(c as f32).to_le_bytes())?;
                    } else {
                        w.write_all(&c.to_le_bytes())?;
                    }
                }
                for c in n {
                    w.write_all(&c.to_le_bytes())?;
                }
            }
            for t in &self.triangles {
                w.write_all(&[3])?;
                for &v in t {
                    w.write_all(&(v as i32).to_le_bytes())?;
                }
            }
        }
        Ok(())
    }

    fn write_obj(&self, w: &mut impl Write) -> io::Result<()> {
        writeln!(w, "# sparse-levelset simplicial isosurface")?;
        let single = self.positions_are_f32();
        for p in &self.positions {
            if single {
                let q = p.map(|c| c as f32);
                writeln!(w, "v {} {} {}", q[0], q[1], q[2])?;
            } else {
                writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
            }
        }
        for n in &self.normals {
            writeln!(w, "vn {} {} {}", n[0], n[1], n[2])?;
        }
        for t in &self.triangles {
            let (a, b, c) = (t[0] + 1, t[1] + 1, t[2] + 1);
            writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
        }
        Ok(())
    }
}
