//! Images and segmentation: `Image` (`load_image`, or an array with its spacing),
//! `segment`, and its result `Segmentation`.

use crate::arrays::{to_rows, MeshArrays};
use crate::levelset::LevelSet;
use crate::watch;
use numpy::ndarray::{Array3, ShapeBuilder};
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use sparse_levelset::io::image::{self, Image as LibImage, LoadedImage, IDENTITY};
use sparse_levelset::segment::{
    self as seglib, Init, Method, Params, Seed, Segmentation as LibSeg,
};
use std::path::PathBuf;
use std::sync::Arc;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Image>()?;
    m.add_class::<Segmentation>()?;
    m.add_function(wrap_pyfunction!(load_image, m)?)?;
    m.add_function(wrap_pyfunction!(segment, m)?)?;
    Ok(())
}

/// A 3-D intensity image: voxels indexed `[i, j, k]` along the lattice axes x, y, z,
/// their spacing, and the placement in world space (a NIfTI file's affine).
#[pyclass(frozen, module = "sparse_levelset")]
pub struct Image {
    pub loaded: Arc<LoadedImage>,
}

#[pymethods]
impl Image {
    /// An image from a Fortran-ordered float32 array `[i, j, k]` and its spacing (world
    /// units per voxel along each axis); world = index × spacing.
    #[new]
    #[pyo3(signature = (array, spacing))]
    fn new(array: PyReadonlyArray3<'_, f32>, spacing: [f64; 3]) -> PyResult<Image> {
        if !array.is_fortran_contiguous() {
            return Err(crate::value_error("the image array must be Fortran-ordered (x fastest)"));
        }
        if spacing.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(crate::value_error(format!(
                "spacing must be finite and > 0, got {spacing:?}"
            )));
        }
        let s = array.shape();
        let dims = [s[0], s[1], s[2]];
        if dims.contains(&0) {
            return Err(crate::value_error(format!("the image is empty: shape {dims:?}")));
        }
        let data = array.as_slice().map_err(crate::value_error)?.to_vec();
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            let (x, y, z) = (i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1]));
            return Err(crate::value_error(format!(
                "the image value at [{x}, {y}, {z}] is {}: intensities must be finite",
                data[i]
            )));
        }
        let image = LibImage { dims, spacing, data, to_world: IDENTITY };
        Ok(Image { loaded: Arc::new(LoadedImage::from_image(image)) })
    }

    /// The voxels, `[i, j, k]` (a Fortran-ordered copy).
    #[getter]
    fn array<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let im = &self.loaded.image;
        let [a, b, c] = im.dims;
        Ok(Array3::from_shape_vec((a, b, c).f(), im.data.clone())
            .map_err(crate::value_error)?
            .into_pyarray(py))
    }

    #[getter]
    fn shape(&self) -> [usize; 3] {
        self.loaded.image.dims
    }

    #[getter]
    fn spacing(&self) -> [f64; 3] {
        self.loaded.image.spacing
    }

    /// Voxel index `(i, j, k, 1)` → world `(x, y, z, 1)`, 4×4 (nibabel's `affine`).
    #[getter]
    fn affine(&self) -> [[f64; 4]; 4] {
        let im = &self.loaded.image;
        let m = &im.to_world;
        let s = im.spacing;
        let mut a = [[0.0; 4]; 4];
        for r in 0..3 {
            for c in 0..3 {
                a[r][c] = m[r][c] * s[c];
            }
            a[r][3] = m[r][3];
        }
        a[3][3] = 1.0;
        a
    }

    fn __repr__(&self) -> String {
        let im = &self.loaded.image;
        format!("Image(shape={:?}, spacing={:?})", im.dims, im.spacing)
    }
}

/// Reads a NIfTI (`.nii`, `.nii.gz`), MetaImage (`.mha`, `.mhd`), NRRD (`.nrrd`, `.nhdr`),
/// `.npy` or grey PNG image.
#[pyfunction]
#[pyo3(signature = (path, spacing=None))]
fn load_image(py: Python<'_>, path: PathBuf, spacing: Option<[f64; 3]>) -> PyResult<Image> {
    let loaded = py.detach(|| image::load(&path, spacing)).map_err(crate::lib_error)?;
    Ok(Image { loaded: Arc::new(loaded) })
}

/// The result of `segment`.
#[pyclass(frozen, module = "sparse_levelset")]
pub struct Segmentation {
    seg: LibSeg,
    image: Arc<LoadedImage>,
    report_json: String,
}

#[pymethods]
impl Segmentation {
    /// 1 inside, 0 outside, `[i, j, k]` like the image (Fortran-ordered).
    #[getter]
    fn mask<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let [a, b, c] = self.image.image.dims;
        Ok(Array3::from_shape_vec((a, b, c).f(), self.seg.mask.clone())
            .map_err(crate::value_error)?
            .into_pyarray(py))
    }

    /// The final level set in the lattice frame (world units along the image's axes,
    /// voxel [0, 0, 0] at the origin), in cubic voxels of the smallest spacing, so that
    /// its measures are the segmentation's world volume and area.
    #[getter]
    fn levelset(&self, py: Python<'_>) -> PyResult<LevelSet> {
        let tiles =
            py.detach(|| self.seg.level_set(&self.image.image)).map_err(crate::lib_error)?;
        LevelSet::new(tiles)
    }

    /// Whether the leak guard stopped the run.
    #[getter]
    fn leaked(&self) -> bool {
        self.seg.report.stop == seglib::Stop::Leaked
    }

    /// Whether the run ended with nothing inside (an empty mask).
    #[getter]
    fn vanished(&self) -> bool {
        self.seg.report.stop == seglib::Stop::Vanished
    }

    /// The run's figures as JSON (the Python layer returns a dict).
    #[getter]
    fn report_json(&self) -> &str {
        &self.report_json
    }

    /// The surface in the image's world coordinates: `(verts, faces, normals)`.
    fn mesh<'py>(&self, py: Python<'py>) -> PyResult<MeshArrays<'py>> {
        let m = py.detach(|| self.seg.mesh(&self.image.image)).map_err(crate::lib_error)?;
        Ok((to_rows(py, &m.positions)?, to_rows(py, &m.triangles)?, to_rows(py, &m.normals)?))
    }

    /// Writes the mask like the image (`.nii`/`.nii.gz` with its header, `.npy`, `.png`).
    fn save_mask(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| {
            image::check_output(&path, &self.image, image::Output::Mask)?;
            image::save_mask(&path, &self.seg.mask, &self.image)
        })
        .map_err(crate::lib_error)
    }
}

fn method_of(
    name: &str,
    lower: Option<f32>,
    upper: Option<f32>,
    l1: f32,
    l2: f32,
    nu: f32,
) -> PyResult<Method> {
    match name {
        // A window open at one end: that threshold None (or ±inf).
        "threshold" => match (lower, upper) {
            (None, None) => Err(crate::value_error(
                "the threshold method needs lower_threshold or upper_threshold (or both)",
            )),
            (l, u) => Ok(Method::Threshold {
                lower: l.unwrap_or(f32::NEG_INFINITY),
                upper: u.unwrap_or(f32::INFINITY),
            }),
        },
        "gac" | "geodesic" => Ok(Method::Gac),
        "chan-vese" | "chan_vese" => Ok(Method::ChanVese { lambda1: l1, lambda2: l2, nu }),
        m => Err(crate::value_error(format!("unknown method {m:?}: threshold, gac or chan-vese"))),
    }
}

/// Segments `image` (see the Python docs for the parameters).
#[pyfunction]
#[pyo3(signature = (
    image, method, seeds, world, init_mask, init_levelset, lower_threshold, upper_threshold,
    sigma, propagation_scaling, curvature_scaling, advection_scaling, edge_scale, sigmoid,
    lambda1, lambda2, nu, maximum_rms_error, volume_change, window, number_of_iterations,
    terms, threads, progress=None, feature=None, leak_guard=true,
    first_edge=true, fast_start=true
))]
#[allow(clippy::too_many_arguments)]
fn segment(
    py: Python<'_>,
    image: &Image,
    method: &str,
    seeds: Vec<Vec<f64>>,
    world: bool,
    init_mask: Option<PyReadonlyArray3<'_, u8>>,
    init_levelset: Option<PyReadonlyArray3<'_, f32>>,
    lower_threshold: Option<f32>,
    upper_threshold: Option<f32>,
    sigma: Option<f64>,
    propagation_scaling: Option<f32>,
    curvature_scaling: Option<f32>,
    advection_scaling: Option<f32>,
    edge_scale: Option<f64>,
    sigmoid: Option<(f64, f64)>,
    lambda1: f32,
    lambda2: f32,
    nu: f32,
    maximum_rms_error: f64,
    volume_change: f64,
    window: u64,
    number_of_iterations: u64,
    terms: Vec<(String, f32)>,
    threads: Option<usize>,
    progress: Option<Bound<'_, PyAny>>,
    feature: Option<PyReadonlyArray3<'_, f32>>,
    leak_guard: bool,
    first_edge: bool,
    fast_start: bool,
) -> PyResult<Segmentation> {
    let loaded = Arc::clone(&image.loaded);
    let dims = loaded.image.dims;
    let feature = match feature {
        Some(f) => {
            if f.shape() != dims {
                return Err(crate::value_error(format!(
                    "feature has shape {:?}, the image {dims:?}",
                    f.shape()
                )));
            }
            if !f.is_fortran_contiguous() {
                return Err(crate::value_error("feature must be Fortran-ordered like the image"));
            }
            let data = f.as_slice().map_err(crate::value_error)?.to_vec();
            Some(Arc::new(LibImage { data, ..loaded.image.clone() }))
        }
        None => None,
    };
    let same_shape = |what: &str, s: &[usize]| -> PyResult<()> {
        if s != dims {
            return Err(crate::value_error(format!("{what} has shape {s:?}, the image {dims:?}")));
        }
        Ok(())
    };
    let init = if let Some(m) = init_mask {
        same_shape("init_mask", m.shape())?;
        if !m.is_fortran_contiguous() {
            return Err(crate::value_error("init_mask must be Fortran-ordered like the image"));
        }
        Init::Mask(m.as_slice().map_err(crate::value_error)?.to_vec())
    } else if let Some(l) = init_levelset {
        same_shape("init_levelset", l.shape())?;
        if !l.is_fortran_contiguous() {
            return Err(crate::value_error("init_levelset must be Fortran-ordered like the image"));
        }
        Init::LevelSet(l.as_slice().map_err(crate::value_error)?.to_vec())
    } else {
        let mut list = Vec::with_capacity(seeds.len());
        for s in &seeds {
            match s.as_slice() {
                [i, j, k] => list.push(Seed { center: [*i, *j, *k], radius: 3.0 }),
                [i, j, k, r] => list.push(Seed { center: [*i, *j, *k], radius: *r }),
                _ => {
                    return Err(crate::value_error(format!(
                        "a seed is (i, j, k) or (i, j, k, radius), got {s:?}"
                    )))
                }
            }
        }
        Init::Seeds { seeds: list, world }
    };
    let method = method_of(method, lower_threshold, upper_threshold, lambda1, lambda2, nu)?;
    let mut terms_list = Vec::with_capacity(terms.len());
    for (name, w) in &terms {
        terms_list
            .push((method_of(name, lower_threshold, upper_threshold, lambda1, lambda2, nu)?, *w));
    }
    let params = Params {
        sigma,
        propagation: propagation_scaling,
        curvature: curvature_scaling,
        advection: advection_scaling,
        edge_scale,
        sigmoid,
        rms: maximum_rms_error,
        volume_change,
        window,
        max_iterations: number_of_iterations,
        pool: crate::pool(threads)?,
        terms: terms_list,
        feature,
        leak_guard,
        first_edge,
        fast_start,
        ..Params::new(method)
    };
    let seg = watch::run(py, progress.as_ref(), "segment", |w| {
        let mut monitor = |s: &seglib::StepInfo| {
            w.report(vec![
                ("iteration", s.iteration as f64),
                ("max_iterations", s.max_iterations as f64),
                ("rms", s.rms),
                ("band_voxels", s.band_voxels as f64),
                ("voxels", s.voxels as f64),
            ])
        };
        seglib::segment(&loaded.image, &init, &params, &mut monitor)
    })?
    .map_err(crate::lib_error)?;
    if seg.report.stop == seglib::Stop::Cancelled {
        return Err(pyo3::exceptions::PyKeyboardInterrupt::new_err("segmentation cancelled"));
    }
    let report_json = serde_json::to_string(&seg.report).map_err(crate::value_error)?;
    Ok(Segmentation { seg, image: loaded, report_json })
}
