//! `LevelSet`: a narrow-band level set held by the Sorted Tile List, with the library's
//! tools as methods.

use crate::arrays::{rows3, to_rows, Band, MeshArrays};
use crate::functions::{mesh_from_arrays, order_of};
use crate::watch;
use numpy::ndarray::Array3;
use numpy::{
    IntoPyArray, PyArray1, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use sparse_levelset::grid::GridSpec;
use sparse_levelset::io::input::{self, Expect};
use sparse_levelset::io::{self, vdb, AnyLevelSet};
use sparse_levelset::storage::convert;
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::interpolate::{Trilinear, Units};
use sparse_levelset::storage::levelset::LevelSet as _;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::TileGrid;
use sparse_levelset::tools::csg::{self, CsgOp};
use sparse_levelset::tools::fmm::{self, FmmOptions};
use sparse_levelset::tools::measure::{self, MeasureOptions};
use sparse_levelset::tools::mesh::{self, MeshOptions};
use sparse_levelset::tools::render::{self, RenderOptions};
use sparse_levelset::tools::voxelize::{voxelize, VoxelizeOptions};
use sparse_levelset::Coord;
use std::path::PathBuf;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<LevelSet>()
}

/// A narrow-band level set (φ < 0 inside, world units) on the Sorted Tile List.
#[pyclass(frozen, module = "sparse_levelset")]
pub struct LevelSet {
    pub grid: TileGrid,
}

fn spec(voxel_size: f32, origin: [f64; 3], half_width: f32) -> PyResult<GridSpec> {
    GridSpec::new(voxel_size, origin, half_width).map_err(crate::value_error)
}

impl LevelSet {
    pub fn new(grid: TileGrid) -> PyResult<LevelSet> {
        if grid.band_voxels() == 0 {
            return Err(crate::value_error(
                "the level set is empty: no voxel has |φ| < γ, so there is no interface",
            ));
        }
        Ok(LevelSet { grid })
    }

    fn combine(&self, other: &LevelSet, op: CsgOp) -> PyResult<LevelSet> {
        let view = csg::csg(&self.grid, &other.grid, op).map_err(crate::value_error)?;
        LevelSet::new(convert::tiles_from(&view))
    }
}

#[pymethods]
impl LevelSet {
    /// From a dense signed distance field `phi[z, y, x]` (C order, float32).
    #[staticmethod]
    #[pyo3(signature = (phi, voxel_size, origin, half_width))]
    fn from_dense(
        py: Python<'_>,
        phi: PyReadonlyArray3<'_, f32>,
        voxel_size: f32,
        origin: [f64; 3],
        half_width: f32,
    ) -> PyResult<LevelSet> {
        let spec = spec(voxel_size, origin, half_width)?;
        let s = phi.shape();
        let dims = [s[2], s[1], s[0]];
        let data = phi.as_slice().map_err(crate::value_error)?.to_vec();
        let mut field =
            DenseField::from_vec(Coord::new(0, 0, 0), dims, data).map_err(crate::lib_error)?;
        let grid = py.detach(|| -> Result<TileGrid, PyErr> {
            input::check_field("phi", &mut field, &Expect { copies: 2.0, ..Expect::new(spec) })
                .map_err(crate::lib_error)?;
            convert::tiles_from_dense(&field, spec).map_err(crate::lib_error)
        })?;
        LevelSet::new(grid)
    }

    /// Voxelises a closed triangle mesh (vertices in world x, y, z).
    #[staticmethod]
    #[pyo3(signature = (verts, faces, voxel_size, half_width, progress=None))]
    fn from_mesh(
        py: Python<'_>,
        verts: PyReadonlyArray2<'_, f64>,
        faces: PyReadonlyArray2<'_, i64>,
        voxel_size: Option<f32>,
        half_width: f32,
        progress: Option<Bound<'_, PyAny>>,
    ) -> PyResult<LevelSet> {
        let m = mesh_from_arrays(&verts, &faces, None)?;
        let grid = watch::run(py, progress.as_ref(), "from_mesh", |w| {
            let opts = VoxelizeOptions {
                voxel_size,
                half_width,
                progress: w.progress(),
                ..Default::default()
            };
            voxelize(&m, &opts)
        })?
        .map_err(crate::lib_error)?;
        LevelSet::new(grid)
    }

    /// An analytic shape's exact signed distance band: `kind` is "sphere" (radius),
    /// "torus" (radius = major, minor_radius), "box" (half_extents) or "ellipsoid" (radii).
    #[staticmethod]
    #[pyo3(signature = (kind, center, voxel_size, half_width, radius=None, minor_radius=None, sizes=None))]
    #[allow(clippy::too_many_arguments)]
    fn shape(
        py: Python<'_>,
        kind: &str,
        center: [f64; 3],
        voxel_size: f32,
        half_width: f32,
        radius: Option<f64>,
        minor_radius: Option<f64>,
        sizes: Option<[f64; 3]>,
    ) -> PyResult<LevelSet> {
        let need = |v: Option<f64>, what: &str| {
            v.ok_or_else(|| crate::value_error(format!("a {kind} needs {what}")))
        };
        let shape = match kind {
            "sphere" => Shape::Sphere { center, radius: need(radius, "a radius")? },
            "torus" => Shape::Torus {
                center,
                major_radius: need(radius, "a radius (the major radius)")?,
                minor_radius: need(minor_radius, "a minor_radius")?,
            },
            "box" => Shape::Box {
                center,
                half_extents: sizes
                    .ok_or_else(|| crate::value_error("a box needs half_extents"))?,
            },
            "ellipsoid" => Shape::Ellipsoid {
                center,
                radii: sizes.ok_or_else(|| crate::value_error("an ellipsoid needs radii"))?,
            },
            k => {
                return Err(crate::value_error(format!(
                    "unknown shape {k:?}: sphere, torus, box or ellipsoid"
                )))
            }
        };
        let spec = spec(voxel_size, [0.0; 3], half_width)?;
        input::check_shape(kind, &shape, &Expect::new(spec)).map_err(crate::lib_error)?;
        let grid =
            py.detach(|| convert::tiles_from_shape(&shape, spec)).map_err(crate::lib_error)?;
        LevelSet::new(grid)
    }

    /// Reads `.sls`, `.vdb` or a dense `.npy` (with the given voxel size and half-width).
    #[staticmethod]
    #[pyo3(signature = (path, voxel_size, origin, half_width))]
    fn load(
        py: Python<'_>,
        path: PathBuf,
        voxel_size: f32,
        origin: [f64; 3],
        half_width: f32,
    ) -> PyResult<LevelSet> {
        let spec = spec(voxel_size, origin, half_width)?;
        let grid = py.detach(|| -> PyResult<TileGrid> {
            // A dense field and the tiles built from it are held at once.
            let expect = Expect { copies: 2.0, ..Expect::new(spec) };
            let loaded = io::load_level_set(&path, &expect).map_err(crate::lib_error)?;
            Ok(match loaded.level_set {
                AnyLevelSet::Tiles(tiles) => tiles,
                AnyLevelSet::Hrle(h) => convert::tiles_from(&h),
            })
        })?;
        LevelSet::new(grid)
    }

    /// Writes `.sls`, `.vdb` or a dense `.npy` (the band's box grown by `margin` voxels),
    /// atomically.
    #[pyo3(signature = (path, margin, compression))]
    fn save(&self, py: Python<'_>, path: PathBuf, margin: u32, compression: &str) -> PyResult<()> {
        let compression = match compression {
            "zip" => vdb::VdbCompression::Zip,
            "none" => vdb::VdbCompression::None,
            c => {
                return Err(crate::value_error(format!(
                    "compression must be \"zip\" or \"none\", got {c:?}"
                )))
            }
        };
        let opts =
            io::SaveOptions { margin, vdb: vdb::VdbOptions { compression, ..Default::default() } };
        py.detach(|| io::save_level_set(&path, &self.grid, &opts))
            .map(|_| ())
            .map_err(crate::lib_error)
    }

    /// φ on the inclusive voxel box `lo`–`hi` (x, y, z) as an array `[z, y, x]`.
    fn to_dense<'py>(
        &self,
        py: Python<'py>,
        lo: [i32; 3],
        hi: [i32; 3],
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let mut dims = [0usize; 3];
        for d in 0..3 {
            if hi[d] < lo[d] {
                return Err(crate::value_error(format!("empty box: {lo:?} to {hi:?}")));
            }
            dims[d] = (hi[d] as i64 - lo[d] as i64 + 1) as usize;
        }
        let f = py
            .detach(|| convert::to_dense(&self.grid, Coord::new(lo[0], lo[1], lo[2]), dims))
            .map_err(crate::lib_error)?;
        let arr = Array3::from_shape_vec((dims[2], dims[1], dims[0]), f.into_data())
            .map_err(crate::value_error)?;
        Ok(arr.into_pyarray(py))
    }

    /// φ at world points `(n, 3)` (x, y, z), trilinear between voxel centres.
    fn value<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let pts = rows3(&points, "points")?;
        if let Some(i) = pts.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(crate::value_error(format!("point {i} is not finite: {:?}", pts[i])));
        }
        let spec = *self.grid.spec();
        let g = &self.grid;
        let out: Vec<f32> = py.detach(|| {
            pts.par_chunks(4096)
                .flat_map_iter(|chunk| {
                    let mut s = Trilinear::new(g.accessor(), &spec, Units::World);
                    chunk.iter().map(move |p| s.at_world(*p) as f32).collect::<Vec<_>>()
                })
                .collect()
        });
        Ok(PyArray1::from_vec(py, out))
    }

    /// Band voxels, volume and area (world units), with the smoothed δ of width
    /// `delta_width` voxels.
    #[pyo3(signature = (delta_width=1.5))]
    fn measure<'py>(&self, py: Python<'py>, delta_width: f32) -> PyResult<Bound<'py, PyDict>> {
        let opts = MeasureOptions { delta_width, ..Default::default() };
        let m = py.detach(|| measure::measure(&self.grid, &opts)).map_err(crate::value_error)?;
        let d = PyDict::new(py);
        d.set_item("band_voxels", m.band_voxels)?;
        d.set_item("volume", m.volume)?;
        d.set_item("area", m.area)?;
        Ok(d)
    }

    fn union(&self, other: &LevelSet) -> PyResult<LevelSet> {
        self.combine(other, CsgOp::Union)
    }

    fn intersection(&self, other: &LevelSet) -> PyResult<LevelSet> {
        self.combine(other, CsgOp::Intersection)
    }

    fn difference(&self, other: &LevelSet) -> PyResult<LevelSet> {
        self.combine(other, CsgOp::Difference)
    }

    fn __or__(&self, other: &LevelSet) -> PyResult<LevelSet> {
        self.union(other)
    }

    fn __and__(&self, other: &LevelSet) -> PyResult<LevelSet> {
        self.intersection(other)
    }

    fn __sub__(&self, other: &LevelSet) -> PyResult<LevelSet> {
        self.difference(other)
    }

    /// The surface φ = level: `(verts (n, 3) world x, y, z, faces (m, 3), normals (n, 3))`.
    #[pyo3(signature = (level=0.0, coarsen=1, progress=None))]
    fn mesh<'py>(
        &self,
        py: Python<'py>,
        level: f64,
        coarsen: u32,
        progress: Option<Bound<'py, PyAny>>,
    ) -> PyResult<MeshArrays<'py>> {
        let m = watch::run(py, progress.as_ref(), "mesh", |w| {
            let opts = MeshOptions { iso: level, coarsen, progress: w.progress() };
            mesh::isosurface(&self.grid, &opts)
        })?
        .map_err(crate::lib_error)?;
        Ok((to_rows(py, &m.positions)?, to_rows(py, &m.triangles)?, to_rows(py, &m.normals)?))
    }

    /// A ray-traced image `(height, width, 3)` uint8.
    #[pyo3(signature = (width, height, azimuth, elevation, fov, samples, ground, shadows, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: u32,
        height: u32,
        azimuth: f64,
        elevation: f64,
        fov: f64,
        samples: u32,
        ground: bool,
        shadows: bool,
        progress: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let img = watch::run(py, progress.as_ref(), "render", |w| {
            let opts = RenderOptions {
                width,
                height,
                azimuth_deg: azimuth,
                elevation_deg: elevation,
                fov_deg: fov,
                samples,
                ground,
                shadows,
                progress: w.progress(),
                ..Default::default()
            };
            render::render(&self.grid, &opts)
        })?
        .map_err(crate::lib_error)?;
        let arr = Array3::from_shape_vec(
            (img.height() as usize, img.width() as usize, 3),
            img.rgb().to_vec(),
        )
        .map_err(crate::value_error)?;
        Ok(arr.into_pyarray(py))
    }

    /// The filters `ops` (`"dilate:1.5"`, `"median:1"`, ... as `levelset filter --op`
    /// takes them) applied in order.
    fn filter(&self, py: Python<'_>, ops: Vec<String>) -> PyResult<LevelSet> {
        let filters = ops
            .iter()
            .map(|s| s.parse::<sparse_levelset::tools::filter::Filter>())
            .collect::<Result<Vec<_>, _>>()
            .map_err(crate::lib_error)?;
        let g = py
            .detach(|| sparse_levelset::tools::filter::filter(&self.grid, &filters))
            .map_err(crate::lib_error)?;
        LevelSet::new(g)
    }

    /// A signed distance band again (fast marching from the interface), with a new
    /// half-width if given.
    #[pyo3(signature = (order=2, half_width=None, progress=None))]
    fn reinitialize(
        &self,
        py: Python<'_>,
        order: u8,
        half_width: Option<f32>,
        progress: Option<Bound<'_, PyAny>>,
    ) -> PyResult<LevelSet> {
        let order = order_of(order)?;
        let g = watch::run(py, progress.as_ref(), "reinitialize", |w| {
            fmm::reinitialize(&self.grid, &FmmOptions { order, half_width, progress: w.progress() })
        })?
        .map_err(crate::lib_error)?;
        LevelSet::new(g)
    }

    #[getter]
    fn voxel_size(&self) -> f32 {
        self.grid.spec().voxel_size
    }

    #[getter]
    fn origin(&self) -> [f64; 3] {
        self.grid.spec().origin
    }

    #[getter]
    fn half_width(&self) -> f32 {
        self.grid.spec().half_width
    }

    /// γ: the value of unstored voxels outside (−γ inside).
    #[getter]
    fn background(&self) -> f32 {
        self.grid.spec().gamma()
    }

    #[getter]
    fn band_voxels(&self) -> usize {
        self.grid.band_voxels()
    }

    /// The tight inclusive voxel box of the band, `((x0, y0, z0), (x1, y1, z1))`.
    #[getter]
    fn bbox(&self) -> ([i32; 3], [i32; 3]) {
        let (lo, hi) = self.grid.band_bounding_box().expect("a LevelSet is never empty");
        ([lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z])
    }

    /// Bytes the tiles use.
    #[getter]
    fn memory(&self) -> usize {
        self.grid.memory().used()
    }

    /// FNV-1a of the band voxels' coordinates and value bits: equal bands, equal checksums.
    #[getter]
    fn checksum(&self) -> u64 {
        self.grid.checksum()
    }

    /// The band voxels `(coords (n, 3) int32 x, y, z, values (n,) float32)` in x-y-z order
    /// (z slowest).
    fn band<'py>(&self, py: Python<'py>) -> PyResult<Band<'py>> {
        let mut coords = Vec::with_capacity(self.grid.band_voxels());
        let mut values = Vec::with_capacity(self.grid.band_voxels());
        self.grid.for_each_band_voxel(&mut |c, v| {
            coords.push([c.x, c.y, c.z]);
            values.push(v);
        });
        Ok((to_rows(py, &coords)?, PyArray1::from_vec(py, values)))
    }

    fn __repr__(&self) -> String {
        let s = self.grid.spec();
        format!(
            "LevelSet(band_voxels={}, voxel_size={}, origin={:?}, half_width={})",
            self.grid.band_voxels(),
            s.voxel_size,
            s.origin,
            s.half_width
        )
    }
}
