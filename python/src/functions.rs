//! Functions on dense arrays: `distance` (scikit-fmm's), `isosurface` (scikit-image's
//! `marching_cubes`), and mesh files.

use crate::arrays::{rows3, to_rows, FacesArrays, IsoArrays, Volume};
use crate::watch;
use numpy::{PyArray3, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::tools::fmm::{self, FmmOptions, Order};
use sparse_levelset::tools::mesh::{self, TriangleMesh};
use sparse_levelset::Coord;
use std::path::PathBuf;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(distance, m)?)?;
    m.add_function(wrap_pyfunction!(isosurface, m)?)?;
    m.add_function(wrap_pyfunction!(save_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(load_mesh, m)?)?;
    Ok(())
}

pub(crate) fn order_of(order: u8) -> PyResult<Order> {
    match order {
        1 => Ok(Order::First),
        2 => Ok(Order::Second),
        o => Err(crate::value_error(format!("order must be 1 or 2, got {o}"))),
    }
}

/// Signed distance to the zero contour of `phi` by fast marching (see the Python docs).
#[pyfunction]
#[pyo3(signature = (phi, dx, order, half_width, progress=None))]
fn distance<'py>(
    py: Python<'py>,
    phi: PyReadonlyArray3<'py, f32>,
    dx: f32,
    order: u8,
    half_width: Option<f32>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let order = order_of(order)?;
    let mut vol = Volume::from_array(&phi)?;
    // Without a narrow band every voxel of the array is marched: the diagonal bounds any
    // distance inside it.
    let w = match half_width {
        Some(w) => w,
        None => (vol.dims.iter().map(|&d| (d * d) as f64).sum::<f64>().sqrt() + 2.0) as f32,
    };
    let field = DenseField::from_vec(Coord::new(0, 0, 0), vol.dims, std::mem::take(&mut vol.data))
        .map_err(crate::lib_error)?;
    let out = watch::run(py, progress.as_ref(), "distance", |w8| {
        let opts = FmmOptions { order, half_width: Some(w), progress: w8.progress() };
        fmm::distance_dense(&field, dx, &opts)
    })?
    .map_err(crate::lib_error)?;
    vol.to_py(py, out.into_data())
}

/// The isosurface of a 3-D array, scikit-image's `marching_cubes` (see the Python docs):
/// vertices in the array's axis order times `spacing`, faces, normals, values.
/// `level = None`: the middle of the data range. `inside`: "above" (scikit-image's
/// normals, −∇volume) or "below". `reverse`: faces clockwise seen from where the normals
/// point (scikit-image's `gradient_direction="descent"`).
#[pyfunction]
#[pyo3(signature = (volume, level, spacing, inside, reverse, step=1, mask=None, closed=false, allow_degenerate=true, progress=None))]
#[allow(clippy::too_many_arguments)]
fn isosurface<'py>(
    py: Python<'py>,
    volume: PyReadonlyArray3<'py, f32>,
    level: Option<f64>,
    spacing: [f64; 3],
    inside: &str,
    reverse: bool,
    step: u32,
    mask: Option<PyReadonlyArray3<'py, bool>>,
    closed: bool,
    allow_degenerate: bool,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<IsoArrays<'py>> {
    if spacing.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(crate::value_error(format!("spacing must be finite and > 0, got {spacing:?}")));
    }
    let inside = match inside {
        "below" => mesh::Inside::Below,
        "above" => mesh::Inside::Above,
        o => {
            return Err(crate::value_error(format!(
                r#"inside must be "below" or "above", got {o:?}"#
            )))
        }
    };
    if step == 0 {
        return Err(crate::value_error("step_size must be at least 1"));
    }
    use numpy::PyUntypedArrayMethods;
    let mut vol = Volume::from_array(&volume)?;
    let flags = match &mask {
        None => None,
        Some(m) => {
            let s = m.shape();
            let fortran = !m.is_c_contiguous() && m.is_fortran_contiguous();
            if [s[0], s[1], s[2]] != vol.shape || fortran != vol.fortran {
                return Err(crate::value_error(format!(
                    "mask must have the volume's shape {:?} and memory order, got {s:?}",
                    vol.shape
                )));
            }
            Some(m.as_slice().map_err(crate::value_error)?)
        }
    };
    let field = DenseField::from_vec(Coord::new(0, 0, 0), vol.dims, std::mem::take(&mut vol.data))
        .map_err(crate::lib_error)?;
    if let Some(level) = level {
        if !level.is_finite() {
            return Err(crate::value_error(format!("level must be finite, got {level}")));
        }
        let (lo, hi) = field
            .data()
            .iter()
            .filter(|v| !v.is_nan())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v as f64), hi.max(v as f64))
            });
        if !(lo < level && level < hi) && field.data().iter().all(|v| !v.is_nan()) {
            return Err(crate::value_error(format!(
                "surface level {level} must be strictly within the volume's data range [{lo}, {hi}]"
            )));
        }
    }
    let spec = GridSpec::default();
    let s = watch::run(py, progress.as_ref(), "isosurface", |w8| {
        let opts = mesh::DenseMeshOptions {
            iso: level,
            inside,
            step,
            mask: flags,
            border: if closed { mesh::Border::Closed } else { mesh::Border::Open },
            drop_degenerate: !allow_degenerate,
            progress: w8.progress(),
        };
        mesh::isosurface_dense_with(&field, &spec, &opts)
    })?
    .map_err(crate::lib_error)?;
    let m = &s.mesh;
    // Lattice (x, y, z) → array axes; reversing the axes (C order) mirrors the mesh, so the
    // triangles are reversed to keep their orientation (and once more for `reverse`).
    let axis = vol.axis_of();
    let mut verts = vec![[0f32; 3]; m.positions.len()];
    let mut normals = vec![[0f32; 3]; m.positions.len()];
    for (i, (p, n)) in m.positions.iter().zip(&m.normals).enumerate() {
        let mut q = [0f64; 3];
        for d in 0..3 {
            let a = axis[d];
            verts[i][a] = (p[d] * spacing[a]) as f32;
            q[a] = n[d] as f64 / spacing[a];
        }
        let len = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
        normals[i] = if len > 0.0 { q.map(|c| (c / len) as f32) } else { [0.0; 3] };
    }
    let faces: Vec<[u32; 3]> = if vol.fortran != reverse {
        s.mesh.triangles
    } else {
        s.mesh.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect()
    };
    let values = numpy::PyArray1::from_vec(py, s.values);
    Ok((to_rows(py, &verts)?, to_rows(py, &faces)?, to_rows(py, &normals)?, values))
}

/// A mesh from NumPy arrays, checked: finite vertices, faces indexing them.
pub(crate) fn mesh_from_arrays(
    verts: &PyReadonlyArray2<'_, f64>,
    faces: &PyReadonlyArray2<'_, i64>,
    normals: Option<&PyReadonlyArray2<'_, f64>>,
) -> PyResult<TriangleMesh> {
    let positions = rows3(verts, "verts")?;
    if let Some(i) = positions.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(crate::value_error(format!("vertex {i} is not finite: {:?}", positions[i])));
    }
    let f = faces.as_array();
    if f.ncols() != 3 {
        return Err(crate::value_error(format!(
            "faces must have shape (m, 3), got {:?}",
            f.shape()
        )));
    }
    let n = positions.len() as i64;
    let mut triangles = Vec::with_capacity(f.nrows());
    for (i, r) in f.rows().into_iter().enumerate() {
        if r.iter().any(|&v| v < 0 || v >= n) {
            return Err(crate::value_error(format!(
                "face {i} = {:?} indexes past the {n} vertices",
                r.to_vec()
            )));
        }
        triangles.push([r[0] as u32, r[1] as u32, r[2] as u32]);
    }
    let mut m = TriangleMesh { positions, normals: Vec::new(), triangles };
    m.normals = match normals {
        Some(a) => {
            let rows = rows3(a, "normals")?;
            if rows.len() != m.positions.len() {
                return Err(crate::value_error(format!(
                    "{} normals for {} vertices",
                    rows.len(),
                    m.positions.len()
                )));
            }
            rows.iter().map(|r| r.map(|c| c as f32)).collect()
        }
        None => m.area_weighted_normals(),
    };
    Ok(m)
}

/// Writes a triangle mesh (`.ply` binary, `.obj` or binary `.stl`, by the extension;
/// atomic).
#[pyfunction]
#[pyo3(signature = (path, verts, faces, normals=None))]
fn save_mesh(
    path: PathBuf,
    verts: PyReadonlyArray2<'_, f64>,
    faces: PyReadonlyArray2<'_, i64>,
    normals: Option<PyReadonlyArray2<'_, f64>>,
) -> PyResult<()> {
    let m = mesh_from_arrays(&verts, &faces, normals.as_ref())?;
    if m.triangles.is_empty() {
        return Err(crate::value_error("the mesh has no triangles"));
    }
    sparse_levelset::io::mesh::save_mesh(&path, &m, None).map_err(crate::lib_error)
}

/// Reads a triangle mesh (`.obj`, `.ply`, `.stl`): `(verts, faces)`.
#[pyfunction]
fn load_mesh<'py>(py: Python<'py>, path: PathBuf) -> PyResult<FacesArrays<'py>> {
    let m = sparse_levelset::io::mesh::load_mesh(&path).map_err(crate::lib_error)?;
    Ok((to_rows(py, &m.positions)?, to_rows(py, &m.triangles)?))
}
