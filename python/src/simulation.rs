//! `Simulation`: a level set moved by a flow (normal speed, mean curvature, advection).

use crate::levelset::LevelSet;
use numpy::{PyReadonlyArray3, PyReadonlyArray4, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sparse_levelset::evolve::{
    Flow, GridKind, Integrator, Lanes, Renormalization, SampledField, SampledVelocity, Settings,
    Simulation as Sim, SpatialScheme, Speed, StepReport, Sweeps, TimeStep, Velocity,
};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert;
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::Coord;
use std::sync::Arc;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Simulation>()
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
        let scheme = match scheme {
            "weno5" => SpatialScheme::Weno5,
            "upwind1" => SpatialScheme::Upwind1,
            s => {
                return Err(crate::value_error(format!(
                    "scheme must be \"weno5\" or \"upwind1\", got {s:?}"
                )))
            }
        };
        let integrator = match integrator {
            "rk3" => Integrator::Rk3,
            "euler" => Integrator::Euler,
            s => {
                return Err(crate::value_error(format!(
                    "integrator must be \"rk3\" or \"euler\", got {s:?}"
                )))
            }
        };
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
