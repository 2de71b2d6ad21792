//! `Simulation`: a level set moved by a flow (normal speed, mean curvature, advection).

use crate::levelset::LevelSet;
use numpy::{
    IntoPyArray, PyArray2, PyReadonlyArray2, PyReadonlyArray3, PyReadonlyArray4,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sparse_levelset::evolve::{
    Flow, GridKind, Integrator, Lanes, Lattice, Renormalization, SampledField, SampledVelocity,
    Settings, Simulation as Sim, SpatialScheme, Speed, StepReport, Sweeps, TimeStep, Velocity,
};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::progress::Progress;
use sparse_levelset::storage::convert;
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::tiles::TILE_DIM;
use sparse_levelset::tools::fmm;
use sparse_levelset::Coord;
use std::sync::Arc;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Simulation>()?;
    m.add_function(wrap_pyfunction!(evolve2d, m)?)
}

/// A field on the level set's voxels, array `[z, y, x]` with element `[0, 0, 0]` at voxel
/// `origin` (x, y, z).
fn sampled(
    a: &[f32],
    shape: [usize; 3],
    origin: [i32; 3],
    spec: GridSpec,
) -> PyResult<SampledField> {
    let dims = [shape[2], shape[1], shape[0]];
    let f = DenseField::from_vec(Coord::new(origin[0], origin[1], origin[2]), dims, a.to_vec())
        .map_err(crate::lib_error)?;
    SampledField::new(f, spec).map_err(crate::value_error)
}

/// A level set moved by φ_t + u·∇φ + F|∇φ| = ε κ|∇φ| on the tile engine (or the DT-Grid).
#[pyclass(module = "sparse_levelset")]
pub struct Simulation {
    sim: Sim,
}

#[pymethods]
impl Simulation {
    #[new]
    #[pyo3(signature = (
        levelset, *, speed=0.0, speed_field=None, curvature=0.0, velocity=None,
        velocity_field=None, field_origin=[0, 0, 0], volume_conserving=false, scheme="weno5",
        integrator="rk3", cfl=1.0, dt=None, renormalization="sweeps", renormalization_sweeps=1,
        grid="tiles", threads=None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        levelset: &LevelSet,
        speed: f32,
        speed_field: Option<PyReadonlyArray3<'_, f32>>,
        curvature: f32,
        velocity: Option<[f32; 3]>,
        velocity_field: Option<PyReadonlyArray4<'_, f32>>,
        field_origin: [i32; 3],
        volume_conserving: bool,
        scheme: &str,
        integrator: &str,
        cfl: f32,
        dt: Option<f32>,
        renormalization: &str,
        renormalization_sweeps: u32,
        grid: &str,
        threads: Option<usize>,
    ) -> PyResult<Simulation> {
        let spec = *levelset.grid.spec();
        let mut flow = if volume_conserving {
            Flow::volume_conserving(curvature)
        } else {
            Flow::mean_curvature(curvature)
        };
        flow.speed = match speed_field {
            Some(a) => {
                let s = a.shape();
                let data = a.as_slice().map_err(crate::value_error)?;
                Speed::Field(Arc::new(sampled(data, [s[0], s[1], s[2]], field_origin, spec)?))
            }
            None => Speed::Constant(speed),
        };
        flow.velocity = match (velocity_field, velocity) {
            (Some(a), _) => {
                let s = a.shape();
                if s[3] != 3 {
                    return Err(crate::value_error(format!(
                        "velocity_field must have shape (nz, ny, nx, 3), got {s:?}"
                    )));
                }
                let v = a.as_array();
                let comp = |c: usize| -> PyResult<SampledField> {
                    let data: Vec<f32> =
                        v.index_axis(numpy::ndarray::Axis(3), c).iter().copied().collect();
                    sampled(&data, [s[0], s[1], s[2]], field_origin, spec)
                };
                Some(Velocity::Field(Arc::new(SampledVelocity([comp(0)?, comp(1)?, comp(2)?]))))
            }
            (None, Some(u)) => Some(Velocity::Constant(u)),
            (None, None) => None,
        };
        let (scheme, integrator) = (scheme_of(scheme)?, integrator_of(integrator)?);
        let renormalization = match renormalization {
            "sweeps" => Renormalization::Sweeps(Sweeps {
                sweeps: renormalization_sweeps,
                ..Sweeps::default()
            }),
            "coupled" => Renormalization::paper(),
            "off" => Renormalization::Off,
            s => {
                return Err(crate::value_error(format!(
                    "renormalization must be \"sweeps\", \"coupled\" or \"off\", got {s:?}"
                )))
            }
        };
        let kind = match grid {
            "tiles" => GridKind::Tiles(Lanes::Simd),
            "tiles-scalar" => GridKind::Tiles(Lanes::Scalar),
            "dtgrid" => GridKind::DtGrid,
            s => {
                return Err(crate::value_error(format!(
                    "grid must be \"tiles\", \"tiles-scalar\" or \"dtgrid\", got {s:?}"
                )))
            }
        };
        let settings = Settings {
            scheme,
            integrator,
            time_step: match dt {
                Some(dt) => TimeStep::Fixed(dt),
                None => TimeStep::Cfl(cfl),
            },
            renormalization,
            pool: crate::pool(threads)?,
            ..Settings::default()
        };
        let tiles = levelset.grid.clone();
        let sim = py
            .detach(|| Sim::from_tile_grid(kind, tiles, flow, settings))
            .map_err(crate::lib_error)?;
        Ok(Simulation { sim })
    }

    /// One step (the CFL-limited Δt, or the fixed one); returns its report.
    fn step<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let sim = &mut self.sim;
        let r = py.detach(|| sim.step()).map_err(crate::lib_error)?;
        report(py, &r)
    }

    /// Steps until time `t` (the last step lands on it), the interface collapses or
    /// `max_steps` steps were taken. `callback(sim, report)` after every step; returning
    /// False stops. Ctrl-C stops between steps (KeyboardInterrupt; the state is the last
    /// completed step). Returns the number of steps taken.
    #[pyo3(signature = (t, callback=None, max_steps=u64::MAX))]
    fn run_until(
        slf: &Bound<'_, Self>,
        t: f64,
        callback: Option<Bound<'_, PyAny>>,
        max_steps: u64,
    ) -> PyResult<u64> {
        let py = slf.py();
        if !t.is_finite() {
            return Err(crate::value_error(format!("t must be finite, got {t}")));
        }
        let mut n = 0;
        loop {
            {
                let s = slf.borrow();
                if s.sim.time() >= t || n >= max_steps || s.sim.collapsed() {
                    return Ok(n);
                }
            }
            let r = {
                let mut s = slf.borrow_mut();
                let sim = &mut s.sim;
                py.detach(|| sim.step_until(t)).map_err(crate::lib_error)?
            };
            n += 1;
            py.check_signals()?;
            if let Some(cb) = &callback {
                let go = cb.call1((slf, report(py, &r)?))?;
                if !go.is_none() && !go.is_truthy()? {
                    return Ok(n);
                }
            }
        }
    }

    #[getter]
    fn time(&self) -> f64 {
        self.sim.time()
    }

    #[getter]
    fn steps(&self) -> u64 {
        self.sim.steps()
    }

    /// No interface is left (e.g. a shape that vanished under curvature flow).
    #[getter]
    fn collapsed(&self) -> bool {
        self.sim.collapsed()
    }

    /// The current state as a `LevelSet` (a copy).
    #[getter]
    fn levelset(&self, py: Python<'_>) -> PyResult<LevelSet> {
        let sim = &self.sim;
        LevelSet::new(py.detach(|| match sim.tiles() {
            Some(t) => t.clone(),
            None => convert::tiles_from(sim),
        }))
    }

    /// Band voxels, stored, volume, area, bytes, work_bytes.
    fn measure<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let sim = &self.sim;
        let m = py.detach(|| sim.measure()).map_err(crate::lib_error)?;
        let d = PyDict::new(py);
        d.set_item("band_voxels", m.band_voxels)?;
        d.set_item("stored", m.stored)?;
        d.set_item("volume", m.volume)?;
        d.set_item("area", m.area)?;
        d.set_item("bytes", m.bytes)?;
        d.set_item("work_bytes", m.work_bytes)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "Simulation(grid={}, time={}, steps={}, band_voxels={})",
            self.sim.kind().name(),
            self.sim.time(),
            self.sim.steps(),
            self.sim.band_voxels()
        )
    }
}

fn report<'py>(py: Python<'py>, r: &StepReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("step", r.step)?;
    d.set_item("time", r.time)?;
    d.set_item("dt", r.dt)?;
    d.set_item("kappa_bar", r.kappa_bar)?;
    d.set_item("collapsed", r.collapsed)?;
    Ok(d)
}

fn scheme_of(scheme: &str) -> PyResult<SpatialScheme> {
    match scheme {
        "weno5" => Ok(SpatialScheme::Weno5),
        "upwind1" => Ok(SpatialScheme::Upwind1),
        s => Err(crate::value_error(format!("scheme must be \"weno5\" or \"upwind1\", got {s:?}"))),
    }
}

fn integrator_of(integrator: &str) -> PyResult<Integrator> {
    match integrator {
        "rk3" => Ok(Integrator::Rk3),
        "euler" => Ok(Integrator::Euler),
        s => Err(crate::value_error(format!("integrator must be \"rk3\" or \"euler\", got {s:?}"))),
    }
}

/// Slices of the extruded layer a 2-D level set is held in (one tile layer).
const LAYER: usize = TILE_DIM as usize;

/// A `[ny, nx]` array (C order) as the dense field `[nx, ny, LAYER]` at the origin: the
/// same values in every slice.
fn extruded(data: &[f32], nx: usize, ny: usize) -> PyResult<DenseField> {
    let mut v = Vec::with_capacity(nx * ny * LAYER);
    for _ in 0..LAYER {
        v.extend_from_slice(data);
    }
    DenseField::from_vec(Coord::new(0, 0, 0), [nx, ny, LAYER], v).map_err(crate::lib_error)
}

/// A 2-D level set moved by φ_t + u·∇φ + F|∇φ| = ε κ|∇φ| (κ the curve's curvature) until
/// time `t`, on a planar lattice of the tile engine (one tile layer; HJ-WENO5 or first-order
/// upwinding, TVD-RK3 or forward Euler, the coupled rescaling term). Returns the band's
/// values (±γ = ±3 dx beyond it) and the run's report.
#[pyfunction]
#[pyo3(signature = (
    phi, t, *, dx=1.0, speed=0.0, speed_field=None, curvature=0.0, velocity=None,
    velocity_field=None, scheme="weno5", integrator="rk3", cfl=1.0, threads=None,
    max_steps=u64::MAX, progress=None
))]
#[allow(clippy::too_many_arguments)]
fn evolve2d<'py>(
    py: Python<'py>,
    phi: PyReadonlyArray2<'py, f32>,
    t: f64,
    dx: f32,
    speed: f32,
    speed_field: Option<PyReadonlyArray2<'py, f32>>,
    curvature: f32,
    velocity: Option<[f32; 2]>,
    velocity_field: Option<PyReadonlyArray3<'py, f32>>,
    scheme: &str,
    integrator: &str,
    cfl: f32,
    threads: Option<usize>,
    max_steps: u64,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyArray2<f32>>, Bound<'py, PyDict>)> {
    let [ny, nx] = [phi.shape()[0], phi.shape()[1]];
    if nx == 0 || ny == 0 {
        return Err(crate::value_error(format!("phi is empty (shape {:?})", phi.shape())));
    }
    if !(t.is_finite() && t >= 0.0) {
        return Err(crate::value_error(format!("t must be finite and >= 0, got {t}")));
    }
    if !(speed.is_finite() && curvature.is_finite() && curvature >= 0.0) {
        return Err(crate::value_error(format!(
            "speed must be finite and curvature finite and >= 0, got {speed} and {curvature}"
        )));
    }
    if !(dx.is_finite() && dx > 0.0) {
        return Err(crate::value_error(format!("dx must be finite and > 0, got {dx}")));
    }
    let (scheme, integrator) = (scheme_of(scheme)?, integrator_of(integrator)?);
    let spec = GridSpec::new(dx, [0.0; 3], 3.0).map_err(crate::lib_error)?;
    let gamma = spec.gamma();
    // The input-sized arrays held at once, in floats per pixel: the marched distance, its
    // start and the extruded layer (with the marched flags, about 6), the speed's layer and
    // the velocity's three, each extruded.
    let fields = LAYER * (speed_field.is_some() as usize + 3 * velocity_field.is_some() as usize);
    let floats = (nx * ny) as u128 * (6 + fields) as u128;
    sparse_levelset::memory::check(
        sparse_levelset::memory::bytes_of(floats, 4),
        "evolve2d's arrays",
    )
    .map_err(crate::lib_error)?;
    let values = phi.as_slice().map_err(crate::value_error)?;
    if let Some(i) = values.iter().position(|v| v.is_nan()) {
        return Err(crate::value_error(format!("phi holds NaN at index {:?}", [i / nx, i % nx])));
    }
    for (sign, side) in [(-1.0f32, "< 0 (inside)"), (1.0, "> 0 (outside)")] {
        if !values.iter().any(|&v| v * sign > 0.0) {
            return Err(crate::value_error(format!(
                "phi has no zero contour to move: no value is {side}"
            )));
        }
    }
    let same_shape = |s: &[usize], what: &str| -> PyResult<()> {
        if s[..2] != [ny, nx] {
            return Err(crate::value_error(format!(
                "{what} must have phi's shape {:?} first, got {s:?}",
                [ny, nx]
            )));
        }
        Ok(())
    };
    let mut flow = Flow::mean_curvature(curvature);
    flow.speed = match speed_field {
        Some(a) => {
            same_shape(a.shape(), "speed_field")?;
            let f = extruded(a.as_slice().map_err(crate::value_error)?, nx, ny)?;
            Speed::Field(Arc::new(SampledField::new(f, spec).map_err(crate::value_error)?))
        }
        None => Speed::Constant(speed),
    };
    flow.velocity = match (velocity_field, velocity) {
        (Some(a), _) => {
            same_shape(a.shape(), "velocity_field")?;
            if a.shape()[2] != 2 {
                return Err(crate::value_error(format!(
                    "velocity_field must have shape (ny, nx, 2), got {:?}",
                    a.shape()
                )));
            }
            let v = a.as_array();
            let comp = |c: usize| -> PyResult<SampledField> {
                let data: Vec<f32> = match c {
                    2 => vec![0.0; nx * ny],
                    c => v.index_axis(numpy::ndarray::Axis(2), c).iter().copied().collect(),
                };
                let f = extruded(&data, nx, ny)?;
                SampledField::new(f, spec).map_err(crate::value_error)
            };
            Some(Velocity::Field(Arc::new(SampledVelocity([comp(0)?, comp(1)?, comp(2)?]))))
        }
        (None, Some([ux, uy])) => Some(Velocity::Constant([ux, uy, 0.0])),
        (None, None) => None,
    };
    let settings = Settings {
        scheme,
        integrator,
        time_step: TimeStep::Cfl(cfl),
        renormalization: Renormalization::Coupled { weight: 1.0 },
        lattice: Some(Lattice { spacing: [dx; 3], planar: true }),
        pool: crate::pool(threads)?,
        ..Settings::default()
    };
    // Every parameter refused before the march.
    Sim::check(&flow, &settings).map_err(crate::lib_error)?;
    // Only the contour is read (`dense_band`): a mask, a steep or a shallow function start
    // the same front as its signed distance would.
    let grid = fmm::DenseGrid::new([nx, ny, 1], dx as f64);
    let start = py
        .detach(|| fmm::dense_band(values, &grid, gamma, Progress::none()))
        .map_err(crate::lib_error)?;
    let field = extruded(&start, nx, ny)?;
    let tiles = convert::tiles_from_dense(&field, spec).map_err(crate::lib_error)?;
    drop(field);
    let kind = GridKind::Tiles(Lanes::Simd);
    let mut sim =
        py.detach(|| Sim::from_tile_grid(kind, tiles, flow, settings)).map_err(crate::lib_error)?;
    // Step by step on the calling thread: Ctrl-C and the callback between steps.
    while sim.time() < t && sim.steps() < max_steps && !sim.collapsed() {
        let r = py.detach(|| sim.step_until(t)).map_err(crate::lib_error)?;
        py.check_signals()?;
        if let Some(cb) = &progress {
            let d = PyDict::new(py);
            d.set_item("done", r.time)?;
            d.set_item("total", t)?;
            d.set_item("step", r.step)?;
            cb.call1((d,))?;
        }
    }
    let out =
        py.detach(|| sim.to_dense(Coord::new(0, 0, 0), [nx, ny, 1])).map_err(crate::lib_error)?;
    let d = PyDict::new(py);
    d.set_item("steps", sim.steps())?;
    d.set_item("time", sim.time())?;
    d.set_item("collapsed", sim.collapsed())?;
    d.set_item("band_voxels", sim.band_voxels() / LAYER)?;
    let arr = numpy::ndarray::Array2::from_shape_vec((ny, nx), out.data().to_vec())
        .map_err(crate::value_error)?;
    Ok((arr.into_pyarray(py), d))
}
