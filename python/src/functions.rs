//! Functions on dense arrays: `distance` (scikit-fmm's), `isosurface` (scikit-image's
//! `marching_cubes`), and mesh files.

use crate::arrays::{rows3, to_rows, FacesArrays, IsoArrays, Volume};
use crate::watch;
use numpy::ndarray::{Array2, Array3, ShapeBuilder};
use numpy::{
    IntoPyArray, PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use rayon::prelude::*;
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::tools::fmm::{self, Order};
use sparse_levelset::tools::mesh::{self, TriangleMesh};
use sparse_levelset::Coord;
use std::path::PathBuf;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(distance, m)?)?;
    m.add_function(wrap_pyfunction!(travel_time, m)?)?;
    m.add_function(wrap_pyfunction!(extension_velocities, m)?)?;
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

/// The values of `a`, an array of the input's shape and memory order (C or Fortran, as
/// read into `vol`), in `vol`'s lattice order.
fn like_phi<T: numpy::Element + Copy>(
    a: &PyReadonlyArray3<'_, T>,
    vol: &Volume,
    what: &str,
) -> PyResult<Vec<T>> {
    let s = a.shape();
    if s != vol.shape {
        return Err(crate::value_error(format!(
            "{what} must have the input array's shape {:?}, got {s:?}",
            vol.shape
        )));
    }
    let fortran = !a.is_c_contiguous() && a.is_fortran_contiguous();
    match a.as_slice() {
        Ok(d) if fortran == vol.fortran => Ok(d.to_vec()),
        _ => Err(crate::value_error(format!(
            "{what} must be contiguous in the input array's order (C or Fortran)"
        ))),
    }
}

/// Lattice-ordered data as an array of `vol`'s shape and order.
fn to_array<'py, T: numpy::Element>(
    py: Python<'py>,
    vol: &Volume,
    data: Vec<T>,
) -> PyResult<Bound<'py, PyArray3<T>>> {
    let [a, b, c] = vol.shape;
    let arr = if vol.fortran {
        Array3::from_shape_vec((a, b, c).f(), data)
    } else {
        Array3::from_shape_vec((a, b, c), data)
    }
    .map_err(crate::value_error)?;
    Ok(arr.into_pyarray(py))
}

/// `(values, reached)` as arrays of the input's shape.
type Marched<'py> = (Bound<'py, PyArray3<f32>>, Bound<'py, PyArray3<bool>>);

/// `(distance, reached, extension)` as arrays of the input's shape.
type Extended<'py> =
    (Bound<'py, PyArray3<f32>>, Bound<'py, PyArray3<bool>>, Bound<'py, PyArray3<f32>>);

/// `phi` read, the dense grid (with `dx` and `periodic` given per array axis), the
/// options' order.
fn dense_setup(
    phi: &PyReadonlyArray3<'_, f32>,
    dx: [f64; 3],
    periodic: [bool; 3],
    order: u8,
) -> PyResult<(Volume, fmm::DenseGrid, Order)> {
    let order = order_of(order)?;
    let vol = Volume::from_array(phi)?;
    let axis = vol.axis_of();
    let grid = fmm::DenseGrid {
        dims: vol.dims,
        spacing: axis.map(|a| dx[a]),
        periodic: axis.map(|a| periodic[a]),
    };
    Ok((vol, grid, order))
}

fn mask_of(
    mask: Option<PyReadonlyArray3<'_, bool>>,
    vol: &Volume,
    what: &str,
) -> PyResult<Option<Vec<bool>>> {
    mask.map(|m| like_phi(&m, vol, what)).transpose()
}

/// Signed distance to the zero contour of `phi` by fast marching (see the Python docs):
/// `(distance, reached)`.
#[pyfunction]
#[pyo3(signature = (phi, dx, order, narrow, periodic, mask=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn distance<'py>(
    py: Python<'py>,
    phi: PyReadonlyArray3<'py, f32>,
    dx: [f64; 3],
    order: u8,
    narrow: Option<f64>,
    periodic: [bool; 3],
    mask: Option<PyReadonlyArray3<'py, bool>>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Marched<'py>> {
    let (vol, grid, order) = dense_setup(&phi, dx, periodic, order)?;
    let mask = mask_of(mask, &vol, "mask")?;
    let out = watch::run(py, progress.as_ref(), "distance", |w8| {
        let opts = fmm::DenseOptions { order, narrow, progress: w8.progress() };
        fmm::dense_distance(&vol.data, &grid, mask.as_deref(), &opts)
    })?
    .map_err(crate::lib_error)?;
    Ok((vol.to_py(py, out.values)?, to_array(py, &vol, out.reached)?))
}

/// Travel time from the zero contour of `phi` with speed `speed` (scikit-fmm's
/// `travel_time`; see the Python docs): `(time, reached)`.
#[pyfunction]
#[pyo3(signature = (phi, speed, dx, order, narrow, periodic, mask=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn travel_time<'py>(
    py: Python<'py>,
    phi: PyReadonlyArray3<'py, f32>,
    speed: PyReadonlyArray3<'py, f32>,
    dx: [f64; 3],
    order: u8,
    narrow: Option<f64>,
    periodic: [bool; 3],
    mask: Option<PyReadonlyArray3<'py, bool>>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Marched<'py>> {
    let (vol, grid, order) = dense_setup(&phi, dx, periodic, order)?;
    let speed = like_phi(&speed, &vol, "speed")?;
    let mask = mask_of(mask, &vol, "mask")?;
    let out = watch::run(py, progress.as_ref(), "travel_time", |w8| {
        let opts = fmm::DenseOptions { order, narrow, progress: w8.progress() };
        fmm::dense_travel_time(&vol.data, &speed, &grid, mask.as_deref(), &opts)
    })?
    .map_err(crate::lib_error)?;
    Ok((vol.to_py(py, out.values)?, to_array(py, &vol, out.reached)?))
}

/// Signed distance and `speed` extended from the zero contour of `phi` (scikit-fmm's
/// `extension_velocities`; see the Python docs): `(distance, reached, extension)`.
#[pyfunction]
#[pyo3(signature = (phi, speed, dx, order, narrow, periodic, mask=None, ext_mask=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn extension_velocities<'py>(
    py: Python<'py>,
    phi: PyReadonlyArray3<'py, f32>,
    speed: PyReadonlyArray3<'py, f32>,
    dx: [f64; 3],
    order: u8,
    narrow: Option<f64>,
    periodic: [bool; 3],
    mask: Option<PyReadonlyArray3<'py, bool>>,
    ext_mask: Option<PyReadonlyArray3<'py, bool>>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Extended<'py>> {
    let (vol, grid, order) = dense_setup(&phi, dx, periodic, order)?;
    let speed = like_phi(&speed, &vol, "speed")?;
    let mask = mask_of(mask, &vol, "mask")?;
    let ext_mask = mask_of(ext_mask, &vol, "ext_mask")?;
    let out = watch::run(py, progress.as_ref(), "extension_velocities", |w8| {
        let opts = fmm::DenseOptions { order, narrow, progress: w8.progress() };
        fmm::dense_extension_velocities(
            &vol.data,
            &speed,
            ext_mask.as_deref(),
            &grid,
            mask.as_deref(),
            &opts,
        )
    })?
    .map_err(crate::lib_error)?;
    Ok((
        vol.to_py(py, out.distance.values)?,
        to_array(py, &vol, out.distance.reached)?,
        to_array(py, &vol, out.extension)?,
    ))
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
    let mut vol = Volume::from_array(&volume)?;
    let flags = mask_of(mask, &vol, "mask")?;
    let field = DenseField::from_vec(Coord::new(0, 0, 0), vol.dims, std::mem::take(&mut vol.data))
        .map_err(crate::lib_error)?;
    if let Some(level) = level {
        if !level.is_finite() {
            return Err(crate::value_error(format!("level must be finite, got {level}")));
        }
        // The smallest and largest value that is not NaN (f32::min and max skip NaN), on
        // all threads.
        let (lo, hi) = field
            .data()
            .par_chunks(1 << 16)
            .map(|c| {
                c.iter()
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)))
            })
            .reduce(|| (f32::INFINITY, f32::NEG_INFINITY), |a, b| (a.0.min(b.0), a.1.max(b.1)));
        let (lo, hi) = (lo as f64, hi as f64);
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
            mask: flags.as_deref(),
            border: if closed { mesh::Border::Closed } else { mesh::Border::Open },
            drop_degenerate: !allow_degenerate,
            progress: w8.progress(),
        };
        mesh::isosurface_dense_with(&field, &spec, &opts)
    })?
    .map_err(crate::lib_error)?;
    // Lattice (x, y, z) → array axes; reversing the axes (C order) mirrors the mesh, so the
    // triangles are reversed to keep their orientation (and once more for `reverse`).
    let mesh = s.mesh;
    let (verts, normals) = to_array_axes(&mesh.positions, &mesh.normals, vol.fortran, spacing);
    let nv = mesh.positions.len();
    drop(mesh.positions);
    drop(mesh.normals);
    // The faces as int32 (scikit-image's dtype; a mesh of 2³¹ vertices or more is refused
    // below), in place: the same allocation reinterpreted by an in-place `collect`, and
    // handed to NumPy without a copy.
    if nv > i32::MAX as usize {
        return Err(crate::value_error(format!(
            "the mesh has {nv} vertices, more than int32 faces can index"
        )));
    }
    let swap = vol.fortran == reverse;
    let faces: Vec<[i32; 3]> = mesh
        .triangles
        .into_iter()
        .map(|t| if swap { [t[0], t[2], t[1]] } else { t }.map(|v| v as i32))
        .collect();
    let nf = faces.len();
    let rows = |n: usize, flat: Vec<f32>| -> PyResult<Bound<'py, PyArray2<f32>>> {
        Ok(Array2::from_shape_vec((n, 3), flat).map_err(crate::value_error)?.into_pyarray(py))
    };
    let faces =
        Array2::from_shape_vec((nf, 3), faces.into_flattened()).map_err(crate::value_error)?;
    let values = numpy::PyArray1::from_vec(py, s.values);
    Ok((rows(nv, verts)?, faces.into_pyarray(py), rows(nv, normals)?, values))
}

/// Vertices per chunk of [`to_array_axes`]'s threads.
const AXES_CHUNK: usize = 1 << 14;

/// Lattice positions and normals (x, y, z) as rows in array-axis order (x is the last
/// axis of a C-ordered array, the first of a Fortran-ordered one), flattened: positions
/// times `spacing`, normals divided by it and renormalised (in f64, rounded to f32; a zero
/// normal stays zero). On all threads, per chunk of [`AXES_CHUNK`] vertices.
fn to_array_axes(
    positions: &[[f64; 3]],
    normals: &[[f32; 3]],
    fortran: bool,
    spacing: [f64; 3],
) -> (Vec<f32>, Vec<f32>) {
    let mut verts = vec![0f32; 3 * positions.len()];
    let mut nrm = vec![0f32; 3 * positions.len()];
    verts
        .par_chunks_mut(3 * AXES_CHUNK)
        .zip(nrm.par_chunks_mut(3 * AXES_CHUNK))
        .zip(positions.par_chunks(AXES_CHUNK).zip(normals.par_chunks(AXES_CHUNK)))
        .for_each(|((v, n), (p, q))| {
            if fortran {
                axes_chunk::<false>(p, q, spacing, v, n)
            } else {
                axes_chunk::<true>(p, q, spacing, v, n)
            }
        });
    (verts, nrm)
}

/// [`to_array_axes`] on one chunk, the axis order fixed at compile time (`REVERSE`: array
/// axis a holds lattice axis 2 − a). The arithmetic of every vertex is that of the plain
/// per-vertex loop (the same operations in the same order, so the same bits), laid out
/// over eight vertices at a time so that the divisions and square roots run on vector
/// lanes: they were 15 % of the time of `isosurface` at 96³ one vertex at a time (`perf
/// record` on `sl.isosurface` of the sphere of docs/python_bench.py, 2-core AMD EPYC,
/// 2026-11-28). With this and the faces written as int32 in place (no flattening copy, no
/// `astype` in Python) the call went from 9.2 to 7.4–8.2 ms at 96³ and from 27 to 23 ms
/// at 160³ (fastest of 20, three runs).
fn axes_chunk<const REVERSE: bool>(
    p: &[[f64; 3]],
    q: &[[f32; 3]],
    spacing: [f64; 3],
    v: &mut [f32],
    n: &mut [f32],
) {
    const W: usize = 8;
    let lattice = |a: usize| if REVERSE { 2 - a } else { a };
    let mut at = 0;
    while at < p.len() {
        let k = W.min(p.len() - at);
        let mut c = [[0f64; W]; 3];
        for (a, c) in c.iter_mut().enumerate() {
            let (d, s) = (lattice(a), spacing[a]);
            for (c, q) in c.iter_mut().zip(&q[at..at + k]) {
                *c = q[d] as f64 / s;
            }
        }
        let mut len = [0f64; W];
        for (i, l) in len.iter_mut().enumerate() {
            *l = (c[0][i] * c[0][i] + c[1][i] * c[1][i] + c[2][i] * c[2][i]).sqrt();
        }
        let mut u = [[0f32; W]; 3];
        for (u, c) in u.iter_mut().zip(&c) {
            for ((u, &c), &l) in u.iter_mut().zip(c).zip(&len) {
                *u = if l > 0.0 { (c / l) as f32 } else { 0.0 };
            }
        }
        for (i, (v, n)) in v[3 * at..3 * (at + k)]
            .chunks_exact_mut(3)
            .zip(n[3 * at..3 * (at + k)].chunks_exact_mut(3))
            .enumerate()
        {
            let pi = &p[at + i];
            for a in 0..3 {
                v[a] = (pi[lattice(a)] * spacing[a]) as f32;
                n[a] = u[a][i];
            }
        }
        at += k;
    }
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
