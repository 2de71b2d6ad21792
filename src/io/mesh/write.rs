//! Mesh files out ([`save_mesh`]): PLY (binary little-endian or ASCII, normals as `float`, faces as
//! `list uchar int`) and Wavefront OBJ (`v`, `vn`, `f a//a b//b c//c`) and binary STL. Every file is
//! written atomically through [`crate::io::fsutil::write_atomic`].
//!
//! Positions are written without loss: as `float` when every coordinate is an f32 value
//! (what the isosurface functions store whenever f32 holds the mesh), as `double`
//! otherwise; in text (ASCII PLY, OBJ) as the shortest decimal that reads back as the
//! same f32 or f64 value.

use super::MeshFormat;
use crate::tools::mesh::{MeshError, TriangleMesh};
use std::io::{self, Write};
use std::path::Path;

/// Writes `mesh` to `path` in `format`, or in the format of the path's extension (binary
/// PLY for `.ply`) when `None`. The file appears complete or not at all.
pub fn save_mesh(
    path: &Path,
    mesh: &TriangleMesh,
    format: Option<MeshFormat>,
) -> Result<(), MeshError> {
    mesh.write(path, format)
}

impl TriangleMesh {
    fn write(&self, path: &Path, format: Option<MeshFormat>) -> Result<(), MeshError> {
        let format = match format {
            Some(f) => f,
            None => MeshFormat::from_path(path)
                .ok_or_else(|| MeshError::UnknownFormat(path.to_path_buf()))?,
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
        crate::io::fsutil::write_atomic(path, |w| match format {
            MeshFormat::Ply { ascii } => self.write_ply(w, ascii),
            MeshFormat::Obj => self.write_obj(w),
            MeshFormat::Stl => self.write_stl(w),
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

    /// Binary STL: a face normal from the triangle's corners, positions as f32 (the format
    /// has no other precision).
    fn write_stl(&self, w: &mut impl Write) -> io::Result<()> {
        let f32s = |p: [f64; 3]| stl_io::Vector::new(p.map(|c| c as f32));
        let triangles = self.triangles.iter().map(|t| {
            let [a, b, c] = t.map(|v| self.positions[v as usize]);
            let (u, v) = ([0, 1, 2].map(|k| b[k] - a[k]), [0, 1, 2].map(|k| c[k] - a[k]));
            let n =
                [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let n = if len > 0.0 { n.map(|x| x / len) } else { [0.0; 3] };
            stl_io::Triangle { normal: f32s(n), vertices: [f32s(a), f32s(b), f32s(c)] }
        });
        stl_io::write_stl(w, triangles)
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
