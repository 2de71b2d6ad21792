//! NumPy arrays in and out. A 3-D array maps onto the library's voxel lattice (x fastest)
//! without reordering: a C-ordered array `a[i, j, k]` has voxel x = k (its last axis
//! varies fastest), a Fortran-ordered one x = i. [`Volume::axis_of_x`] says which.

use numpy::ndarray::{Array2, Array3, ShapeBuilder};
use numpy::{
    IntoPyArray, PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

/// A triangle mesh as NumPy arrays: vertices, triangles, normals.
pub type MeshArrays<'py> =
    (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<u32>>, Bound<'py, PyArray2<f32>>);

/// An isosurface of an array: vertices (float32, array axes), triangles (int32, as
/// scikit-image's), normals, values.
pub type IsoArrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<i32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, numpy::PyArray1<f32>>,
);

/// A mesh read from a file: vertices and triangles.
pub type FacesArrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<u32>>);

/// Band voxels: coordinates and values.
pub type Band<'py> = (Bound<'py, PyArray2<i32>>, Bound<'py, numpy::PyArray1<f32>>);

/// A 3-D float32 array's values in x-fastest order with the lattice's dimensions.
pub struct Volume {
    /// `[nx, ny, nz]` of the lattice.
    pub dims: [usize; 3],
    pub data: Vec<f32>,
    /// The array was Fortran-ordered (x = its first axis); otherwise C-ordered (x = its last
    /// axis).
    pub fortran: bool,
    /// The array's shape.
    pub shape: [usize; 3],
}

impl Volume {
    /// Copies a contiguous array (the Python layer makes non-contiguous ones C-ordered).
    pub fn from_array(a: &PyReadonlyArray3<'_, f32>) -> PyResult<Volume> {
        let s = a.shape();
        let shape = [s[0], s[1], s[2]];
        let fortran = !a.is_c_contiguous() && a.is_fortran_contiguous();
        let data = a.as_slice().map_err(crate::value_error)?.to_vec();
        let dims = if fortran { shape } else { [shape[2], shape[1], shape[0]] };
        Ok(Volume { dims, data, fortran, shape })
    }

    /// The array axis that holds the lattice's x, y, z.
    pub fn axis_of(&self) -> [usize; 3] {
        if self.fortran {
            [0, 1, 2]
        } else {
            [2, 1, 0]
        }
    }

    /// `data` (x fastest, this volume's lattice) as an array of the input's shape and order.
    pub fn to_py<'py>(
        &self,
        py: Python<'py>,
        data: Vec<f32>,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let [a, b, c] = self.shape;
        let arr = if self.fortran {
            Array3::from_shape_vec((a, b, c).f(), data)
        } else {
            Array3::from_shape_vec((a, b, c), data)
        }
        .map_err(crate::value_error)?;
        Ok(arr.into_pyarray(py))
    }
}

/// An `(n, 3)` float64 array's rows.
pub fn rows3(a: &PyReadonlyArray2<'_, f64>, what: &str) -> PyResult<Vec<[f64; 3]>> {
    let v = a.as_array();
    if v.ncols() != 3 {
        return Err(crate::value_error(format!(
            "{what} must have shape (n, 3), got {:?}",
            v.shape()
        )));
    }
    Ok(v.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

/// Rows of three as an `(n, 3)` array.
pub fn to_rows<'py, T: numpy::Element + Copy>(
    py: Python<'py>,
    rows: &[[T; 3]],
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let flat: Vec<T> = rows.iter().flatten().copied().collect();
    Ok(Array2::from_shape_vec((rows.len(), 3), flat).map_err(crate::value_error)?.into_pyarray(py))
}
