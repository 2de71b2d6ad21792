//! The segmentation driver: feature images, the initial level set, the flow on the tile
//! engine, the region means and the stopping tests (see the [module docs](super)).

use super::features;
use super::speed::{CurvatureSum, Lookup, RegionForce, SumField, VoxelField, VoxelVector};
use super::stats::{self, Normalization};
use super::{Init, Method, Params, Report, Resolved, SegmentError, StepInfo, Stop};
use crate::coord::Coord;
use crate::evolve::{
    Flow, GridKind, Integrator, Lanes, Lattice, Renormalization, ScalarFn, Settings, Simulation,
    Speed, Velocity,
};
use crate::exact::ExactSum;
use crate::grid::{GridError, GridSpec};
use crate::io::image::Image;
use crate::progress::Progress;
use crate::storage::convert::{map_tile_rows, tiles_from_dense};
use crate::storage::dense::DenseField;
use crate::storage::tiles::{TileGrid, SLICE_LEN, TILE_DIM, TILE_LEN};
use crate::tools::fmm;
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// Band half-width in voxels of the largest spacing.
const HALF_WIDTH: f32 = 3.0;

/// A finished segmentation: the mask, the level set and the run's figures.
pub struct Segmentation {
    /// 1 inside (φ ≤ 0), 0 outside, per image voxel (x fastest).
    pub mask: Vec<u8>,
    /// The final level set on the image lattice (its voxel size is the largest spacing;
    /// voxel (i, j, k) is image voxel (i, j, k); a 2D image's level set is extruded over
    /// z = 0..3).
    pub simulation: Simulation,
    pub report: Report,
}

impl Segmentation {
    /// The surface of the segmentation (φ = 0, simplicial isosurfacing of the final level
    /// set, [`crate::tools::mesh::isosurface`]) in `image`'s world coordinates
    /// ([`Image::to_world`]): vertices are placed on the lattice and mapped through the
    /// placement, normals through its inverse transpose. A 2D image has no surface.
    pub fn mesh(&self, image: &Image) -> Result<crate::tools::mesh::TriangleMesh, SegmentError> {
        if image.is_2d() {
            return Err(SegmentError::InvalidParameter(
                "a 2D image's segmentation is a region, not a surface".into(),
            ));
        }
        let tiles = self.simulation.tiles().ok_or_else(|| {
            SegmentError::InvalidParameter("the segmentation holds no tile grid".into())
        })?;
        let mut mesh =
            crate::tools::mesh::isosurface(tiles, &crate::tools::mesh::MeshOptions::default())
                .map_err(|e| SegmentError::InvalidParameter(e.to_string()))?;
        let h = tiles.spec().voxel_size as f64;
        let s = image.spacing;
        let m = &image.to_world;
        // Lattice position → world is M·diag(s)/h on the grid's world positions.
        let a: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| m[r][c] * s[c] / h));
        for p in &mut mesh.positions {
            let q = *p;
            *p =
                std::array::from_fn(|r| a[r][0] * q[0] + a[r][1] * q[1] + a[r][2] * q[2] + m[r][3]);
        }
        // A placement that flips an odd number of axes (negative determinant, as many
        // NIfTI files have) mirrors the surface: reverse every triangle so that it stays
        // counter-clockwise seen from outside.
        if det3(a) < 0.0 {
            mesh.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        }
        // Normals: (A⁻¹)ᵀ n, renormalised.
        let inv = invert3(a);
        for n in &mut mesh.normals {
            let q = n.map(|v| v as f64);
            let t: [f64; 3] =
                std::array::from_fn(|r| inv[0][r] * q[0] + inv[1][r] * q[1] + inv[2][r] * q[2]);
            let len = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
            if len > 0.0 {
                *n = t.map(|v| (v / len) as f32);
            }
        }
        Ok(mesh)
    }

    /// The final level set as a band of cubic voxels of the image's **smallest** spacing in
    /// the lattice frame (world units along the image's axes, voxel (0, 0, 0)'s centre at
    /// the origin), so that its measures ([`crate::tools::measure::measure`]) are the world
    /// volume and area of the segmentation whatever the spacing. An isotropic image's is
    /// the evolved band itself; an anisotropic one's is resampled from it by trilinear
    /// interpolation of φ (a distance in world units, so no rescaling), at the cost of
    /// (largest / smallest spacing) times the voxels. A 2D image's stays extruded over
    /// four layers along z.
    pub fn level_set(&self, image: &Image) -> Result<TileGrid, SegmentError> {
        let tiles = self.simulation.tiles().ok_or_else(|| {
            SegmentError::InvalidParameter("the segmentation holds no tile grid".into())
        })?;
        let s = image.spacing;
        let planar = image.is_2d();
        let axes = if planar { 2 } else { 3 };
        let h = s[..axes].iter().copied().fold(f64::INFINITY, f64::min);
        if s[..axes].iter().all(|&v| v == h) && tiles.spec().voxel_size as f64 == h {
            return Ok(tiles.clone());
        }
        let gamma = tiles.spec().gamma();
        let [nx, ny, nz] = image.dims;
        let layers = if planar { TILE_DIM as usize } else { nz };
        let old = self.simulation.to_dense(Coord::new(0, 0, 0), [nx, ny, layers])?;
        let old = old.data();
        // New voxels per axis: positions 0, h, 2h, … up to the last image voxel's centre.
        let n: [usize; 3] = std::array::from_fn(|a| {
            if a == 2 && planar {
                TILE_DIM as usize
            } else {
                ((image.dims[a] - 1) as f64 * s[a] / h + 1e-9).floor() as usize + 1
            }
        });
        let count = n[0] as u128 * n[1] as u128 * n[2] as u128;
        crate::memory::check(crate::memory::bytes_of(count, 4), "the resampled level set")?;
        let mut data = vec![0.0f32; count as usize];
        let dims_old = [nx, ny, layers];
        data.par_chunks_mut(n[0] * n[1]).enumerate().for_each(|(k, slice)| {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let q = [i, j, k];
                    // Voxel coordinates in the old lattice.
                    let p: [f64; 3] = std::array::from_fn(|a| {
                        if a == 2 && planar {
                            k as f64
                        } else {
                            q[a] as f64 * h / s[a]
                        }
                    });
                    let mut i0 = [0usize; 3];
                    let mut f = [0.0f64; 3];
                    for a in 0..3 {
                        let m = dims_old[a];
                        let b = (p[a].floor() as usize).min(m.saturating_sub(2));
                        i0[a] = b;
                        f[a] = if m > 1 { (p[a] - b as f64).clamp(0.0, 1.0) } else { 0.0 };
                    }
                    let mut v = 0.0f64;
                    for corner in 0..8usize {
                        let mut w = 1.0;
                        let mut idx = [0usize; 3];
                        for a in 0..3 {
                            let bit = (corner >> a) & 1;
                            w *= if bit == 1 { f[a] } else { 1.0 - f[a] };
                            idx[a] = (i0[a] + bit).min(dims_old[a] - 1);
                        }
                        if w != 0.0 {
                            v += w * old[idx[0] + nx * (idx[1] + ny * idx[2])] as f64;
                        }
                    }
                    slice[i + n[0] * j] = (v as f32).clamp(-gamma, gamma);
                }
            }
        });
        let field = DenseField::from_vec(Coord::new(0, 0, 0), n, data)?;
        Ok(tiles_from_dense(&field, GridSpec::new(h as f32, [0.0; 3], HALF_WIDTH)?)?)
    }
}

/// The determinant of a 3×3 matrix.
fn det3(a: [[f64; 3]; 3]) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

/// The inverse of a 3×3 matrix (the placement is invertible: NIfTI's sform/qform are).
fn invert3(a: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = det3(a);
    let c =
        |r0: usize, c0: usize, r1: usize, c1: usize| a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0];
    [
        [c(1, 1, 2, 2) / det, -c(0, 1, 2, 2) / det, c(0, 1, 1, 2) / det],
        [-c(1, 0, 2, 2) / det, c(0, 0, 2, 2) / det, -c(0, 0, 1, 2) / det],
        [c(1, 0, 2, 1) / det, -c(0, 0, 2, 1) / det, c(0, 0, 1, 1) / det],
    ]
}

/// Segments `image` from `init` with `params`; `monitor` sees every step and returns
/// `false` to stop early (the result so far is returned, [`Stop::Cancelled`]).
pub fn segment(
    image: &Image,
    init: &Init,
    params: &Params,
    monitor: &mut (dyn FnMut(&StepInfo) -> bool + Send),
) -> Result<Segmentation, SegmentError> {
    validate(image, init, params)?;
    let mut run = move || segment_in_pool(image, init, params, monitor);
    match &params.pool {
        Some(pool) => pool.install(run),
        None => run(),
    }
}

fn validate(image: &Image, init: &Init, params: &Params) -> Result<(), SegmentError> {
    let invalid = |m: String| Err(SegmentError::InvalidParameter(m));
    if image.data.len() != image.dims.iter().product::<usize>() || image.data.is_empty() {
        return invalid(format!("image data does not match its dimensions {:?}", image.dims));
    }
    if image.spacing.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return invalid(format!("image spacing must be finite and > 0, got {:?}", image.spacing));
    }
    // One voxel along x or y: a sheet or a line, not a volume the front can enclose (its
    // band would collapse at once: the run would end "vanished" with an empty mask). A 2-D
    // image has its one voxel along z.
    if image.dims[0] == 1 || image.dims[1] == 1 {
        return invalid(format!(
            "the image has one voxel along x or y (dimensions x, y, z = {:?}): a segmentation \
             needs at least two along x and y, and a 2-D image has its one voxel along z \
             (transpose or squeeze the array)",
            image.dims
        ));
    }
    let finite_pos = |name: &str, v: Option<f64>| match v {
        Some(v) if !(v.is_finite() && v >= 0.0) => {
            Err(SegmentError::InvalidParameter(format!("{name} must be finite and >= 0, got {v}")))
        }
        _ => Ok(()),
    };
    finite_pos("sigma", params.sigma)?;
    if let Some(b) = params.propagation {
        if !b.is_finite() {
            return invalid(format!("propagation must be finite, got {b}"));
        }
        let methods = std::iter::once(params.method).chain(params.terms.iter().map(|t| t.0));
        if b < 0.0 && methods.clone().any(|m| matches!(m, Method::ChanVese { .. })) {
            return invalid(format!(
                "a negative propagation ({b}) would flip Chan–Vese's data terms; \
                 it is for threshold and GAC"
            ));
        }
    }
    if let Some(f) = &params.feature {
        if f.dims != image.dims || f.data.len() != image.data.len() {
            return invalid(format!(
                "the feature image has dimensions {:?}, the image {:?}",
                f.dims, image.dims
            ));
        }
        if let Some(i) = crate::storage::dense::first_position(&f.data, |v| !v.is_finite()) {
            return invalid(format!("the feature image's value {i} is {}", f.data[i]));
        }
    }
    finite_pos("curvature", params.curvature.map(f64::from))?;
    finite_pos("advection", params.advection.map(f64::from))?;
    finite_pos("RMS tolerance", Some(params.rms))?;
    finite_pos("volume-change tolerance", Some(params.volume_change))?;
    if let Some(k) = params.edge_scale
        && !(k.is_finite() && k > 0.0)
    {
        return invalid(format!("edge scale K must be finite and > 0, got {k}"));
    }
    if params.window == 0 {
        return invalid("the volume window must be at least 1 step".into());
    }
    let mut names = vec![params.method.name()];
    for &(m, w) in &params.terms {
        if !(w.is_finite() && w >= 0.0) {
            return invalid(format!("the weight of {} must be finite and >= 0, got {w}", m.name()));
        }
        if names.contains(&m.name()) {
            return invalid(format!("{} appears twice in the sum of methods", m.name()));
        }
        names.push(m.name());
    }
    for method in std::iter::once(params.method).chain(params.terms.iter().map(|t| t.0)) {
        check_method(method)?;
    }
    let n = image.data.len();
    match init {
        Init::Seeds { seeds, .. } => {
            if seeds.is_empty() {
                return Err(SegmentError::Init("no seed given".into()));
            }
            for s in seeds {
                if !(s.center.iter().all(|c| c.is_finite())
                    && s.radius.is_finite()
                    && s.radius > 0.0)
                {
                    return Err(SegmentError::Init(format!(
                        "a seed needs a finite centre and a radius > 0, got {:?} radius {}",
                        s.center, s.radius
                    )));
                }
            }
        }
        Init::Mask(m) if m.len() != n => {
            return Err(SegmentError::Init(format!(
                "the initial mask has {} voxels, the image {n}",
                m.len()
            )))
        }
        Init::LevelSet(v) if v.len() != n => {
            return Err(SegmentError::Init(format!(
                "the initial level set has {} voxels, the image {n}",
                v.len()
            )))
        }
        Init::LevelSet(v) if v.iter().any(|x| x.is_nan()) => {
            return Err(SegmentError::Init("the initial level set holds NaN".into()))
        }
        _ => {}
    }
    Ok(())
}

/// The parameters of one method.
fn check_method(method: Method) -> Result<(), SegmentError> {
    let invalid = |m: String| Err(SegmentError::InvalidParameter(m));
    match method {
        Method::Threshold { lower, upper }
            if lower.is_nan()
                || upper.is_nan()
                || lower >= upper
                || lower == f32::INFINITY
                || upper == f32::NEG_INFINITY
                || (lower.is_infinite() && upper.is_infinite()) =>
        {
            invalid(format!(
                "thresholds need lower < upper with at least one end finite (an open end is \
                 ±inf), got {lower}, {upper}"
            ))
        }
        Method::ChanVese { lambda1, lambda2, nu }
            if ![lambda1, lambda2, nu].iter().all(|v| v.is_finite())
                || lambda1 < 0.0
                || lambda2 < 0.0 =>
        {
            invalid(format!(
                "Chan–Vese weights must be finite with λ ≥ 0, got λ₁ {lambda1}, λ₂ {lambda2}, ν {nu}"
            ))
        }
        _ => Ok(()),
    }
}

/// The lattice of `image`: spacing as f32, planar for one slice.
fn lattice_of(image: &Image) -> Lattice {
    Lattice { spacing: image.spacing.map(|s| s as f32), planar: image.is_2d() }
}

fn segment_in_pool(
    image: &Image,
    init: &Init,
    params: &Params,
    monitor: &mut (dyn FnMut(&StepInfo) -> bool + Send),
) -> Result<Segmentation, SegmentError> {
    let start = Instant::now();
    let lattice = lattice_of(image);
    let h_min = lattice.min_spacing() as f64;
    let h_max = lattice.spacing.iter().fold(0.0f32, |m, &s| m.max(s));
    let spec = GridSpec::new(h_max, [0.0; 3], HALF_WIDTH)?;
    let field = initial_field(image, init, &lattice, spec.gamma())?;
    let prepared = prepare(image, init, params, &field)?;
    let Prepared { smoothed, norm, g, gate, mut resolved } = prepared;
    let lookup = Lookup { dims: image.dims };
    let inputs = MethodInputs {
        params,
        smoothed: &smoothed,
        g: g.as_ref(),
        lookup,
        h_min,
        noise_smoothed: resolved.noise_smoothed / norm.scale,
        gate,
    };
    let (mut flow, mut region) = method_flow(params.method, 1.0, &inputs, &norm, &mut resolved)?;
    if !params.terms.is_empty() {
        let mut flows = vec![flow];
        for &(method, weight) in &params.terms {
            let mut scratch = resolved.clone();
            let (f, r) = method_flow(method, weight, &inputs, &norm, &mut scratch)?;
            if matches!(method, Method::Gac) {
                (resolved.sigmoid, resolved.edge_scale) = (scratch.sigmoid, scratch.edge_scale);
                resolved.advection = scratch.advection;
            }
            flows.push(f);
            region = region.or(r);
        }
        flow = sum_of_flows(flows);
    }
    // The leak guard's reference is the seeds' region, whatever the start.
    let seeds: Vec<u8> =
        field.data()[..image.len()].par_iter().map(|&p| (p <= 0.0) as u8).collect();
    let (seed_voxels, seed_faces) = mask_faces(&seeds, image.dims);
    let field = match start_region(image, init, params, &inputs, &seeds, &resolved, &norm) {
        Some(start) => {
            resolved.start_voxels = Some(par_count(&start));
            initial_field(image, &Init::Mask(start), &lattice, spec.gamma())?
        }
        None => field,
    };
    let seconds_features = start.elapsed().as_secs_f64();

    // The initial level set on the lattice, its region closed at the image's faces.
    let tiles = match closed_at_faces(&field, image, spec.gamma())? {
        Some(closed) => tiles_from_dense(&closed, spec)?,
        None => tiles_from_dense(&field, spec)?,
    };
    drop(field);
    if tiles.band_voxels() == 0 {
        return Err(SegmentError::Init(
            "the initial level set has no interface in the image".into(),
        ));
    }
    // HJ-WENO5 in space (first-order upwinding lost 0.21 of Dice on thin tubes and 0.019
    // on the MNI white matter), forward Euler in time when the flow has a curvature term:
    // the same masks as TVD-RK3 to 6·10⁻⁴ of Dice at a third of the sweeps. The parabolic
    // term damps the slow growth that forward Euler allows HJ-WENO5's purely hyperbolic
    // modes, so a flow without one keeps TVD-RK3 (decision 0037).
    resolved.integrator =
        if resolved.curvature > 0.0 { Integrator::Euler } else { Integrator::Rk3 };
    let settings = Settings {
        integrator: resolved.integrator,
        renormalization: Renormalization::Coupled { weight: 1.0 },
        lattice: Some(lattice),
        pool: params.pool.clone(),
        ..Settings::default()
    };
    let stages = resolved.integrator.stages();
    let planar = lattice.planar;
    // A 2-D image's level set is extruded over the z-slices of one tile layer, and the
    // sweeps compute the first and copy it: what is computed and reported is one slice.
    let layers = if planar { TILE_DIM as usize } else { 1 };
    let mut sim = Simulation::from_tile_grid(GridKind::Tiles(Lanes::Simd), tiles, flow, settings)?;

    // Region sums on a fixed-point copy of Ĩ: exact integer sums, the same bits in any
    // order (every representation and thread count gives the same means).
    let sums = region.as_ref().map(|_| FixedPoint::new(&smoothed.data));
    let evolution = Instant::now();
    let voxel_volume = lattice.voxel_volume();
    let mut volumes: Vec<u64> = Vec::new();
    let mut updates = 0f64;
    let mut rms = f64::NAN;
    let mut means = None;
    let (mut voxels, mut inside_sum, _) = inside(&sim, image.dims, sums.as_ref());
    let (initial_voxels, first_faces) = (seed_voxels, seed_faces);
    let image_voxels = image.len() as u64;
    let mut leak = None;
    // A start that shrinks onto the objects (β < 0 from a mask or a level set) may reach
    // the image's faces where the objects it cuts do (the first edge inward turns the
    // balloon outward in them); it leaks only by outgrowing itself.
    let shrinking = shrinks_onto_objects(params, init);
    volumes.push(voxels);
    let mut seconds_steps = 0.0;
    let mut near = change_since(tiles_of(&sim), &Near::default(), 1.0, h_min, planar).2;
    let stop = loop {
        if sim.steps() >= params.max_iterations {
            break Stop::MaxIterations;
        }
        if voxels == 0 {
            break Stop::Vanished;
        }
        if let (Some(force), Some(fp)) = (&region, &sums) {
            let n = image.data.len() as u64;
            let c1 = fp.mean(inside_sum, voxels);
            let mut c2 = fp.mean(fp.total - inside_sum, n - voxels);
            // The outside's competitor is the intensity beyond the seeds' first edge when
            // that lies on the outside mean's side and clearly nearer (a neighbouring
            // tissue, not the same background measured along a few rays).
            if let Some(far) = gate.map(|g| g.far as f64)
                && (far - c1) * (c2 - c1) > 0.0
                && (far - c1).abs() < NEIGHBOUR * (c2 - c1).abs()
            {
                c2 = far;
            }
            force.set_means(c1, c2);
            means = Some([norm.back(c1), norm.back(c2)]);
        }
        updates += (sim.stored_voxels() / layers * stages) as f64;
        let t_step = Instant::now();
        let report = match sim.step() {
            Ok(r) => r,
            Err(crate::evolve::EvolveError::Collapsed { .. }) => break Stop::Vanished,
            Err(e) => return Err(e.into()),
        };
        seconds_steps += t_step.elapsed().as_secs_f64();
        // RMS of (φⁿ⁺¹ − φⁿ)/Δt over the voxels with |φⁿ| < h.
        let (sq, band_voxels, next) =
            change_since(tiles_of(&sim), &near, report.dt as f64, h_min, planar);
        rms = if near.is_empty() { 0.0 } else { (sq / near.len() as f64).sqrt() };
        near = next;
        let faces;
        (voxels, inside_sum, faces) = inside(&sim, image.dims, sums.as_ref());
        volumes.push(voxels);
        let info = StepInfo {
            iteration: sim.steps(),
            max_iterations: params.max_iterations,
            rms,
            band_voxels,
            voxels,
        };
        if !monitor(&info) {
            break Stop::Cancelled;
        }
        if report.collapsed {
            break Stop::Vanished;
        }
        if params.leak_guard {
            let sizes = [voxels, initial_voxels, image_voxels];
            leak = leak_of(&faces, &first_faces, image.dims, sizes, shrinking);
            if leak.is_some() {
                break Stop::Leaked;
            }
        }
        if rms < params.rms {
            break Stop::Rms;
        }
        let w = params.window as usize;
        if volumes.len() > w {
            let then = volumes[volumes.len() - 1 - w] as f64;
            let now = voxels as f64;
            if now > 0.0 && (now - then).abs() / now < params.volume_change {
                break Stop::Volume;
            }
        }
    };
    let seconds_evolution = evolution.elapsed().as_secs_f64();
    let mask = mask_of(&sim, image.dims)?;
    let voxels = par_count(&mask);
    // An empty mask segments no object, whatever else ended the run in the step that
    // emptied it (the step limit, the RMS test); a cancelled run says it was cancelled.
    let stop = if voxels == 0 && stop != Stop::Cancelled { Stop::Vanished } else { stop };
    let weak_contrast = means.and_then(|[c1, c2]| weak_contrast(c1, c2, resolved.noise_smoothed));
    let report = Report {
        params: resolved,
        stop,
        iterations: sim.steps(),
        time: sim.time(),
        rms,
        voxels,
        volume: voxels as f64 * voxel_volume,
        means,
        leak,
        weak_contrast,
        band_voxels: sim.band_voxels() / layers,
        voxel_updates: updates,
        seconds_features,
        seconds_evolution,
        seconds_steps,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok(Segmentation { mask, simulation: sim, report })
}

/// Why Chan–Vese's region is not told apart from its surroundings, if it is not: its
/// mean c₁ lies within [`CONTRAST_NOISE`] noise levels (left after smoothing) of the
/// outside's c₂, so that the two classes overlap and a voxel's side is a coin toss (the
/// seeds lie in a region of the background's intensity, or the object has no contrast).
fn weak_contrast(c1: f64, c2: f64, noise_smoothed: f64) -> Option<String> {
    let d = (c1 - c2).abs();
    (d < CONTRAST_NOISE * noise_smoothed).then(|| {
        format!(
            "the region's mean {c1:.4} is within {:.1} noise levels ({noise_smoothed:.3}) of \
             the outside's {c2:.4}: the region is not told apart from its surroundings (do \
             the seeds lie in a region of the background's intensity?)",
            d / noise_smoothed.max(f64::MIN_POSITIVE)
        )
    })
}

/// What every method's flow is built from.
struct MethodInputs<'a> {
    params: &'a Params,
    /// The intensities the methods compare, normalised ([`Normalization`]) and smoothed.
    smoothed: &'a Image,
    /// GAC's edge potential g, when GAC is one of the methods.
    g: Option<&'a Image>,
    lookup: Lookup,
    h_min: f64,
    /// The noise σ left in `smoothed`, normalised units.
    noise_smoothed: f64,
    /// The seeds' first edge ([`Params::first_edge`]).
    gate: Option<Gate>,
}

/// The flow of one method with its weight (β, ε and α scaled by it), and its region
/// force (Chan–Vese). `resolved` gets the method's parameters.
fn method_flow(
    method: Method,
    weight: f32,
    inputs: &MethodInputs<'_>,
    norm: &Normalization,
    resolved: &mut Resolved,
) -> Result<(Flow, Option<Arc<RegionForce>>), SegmentError> {
    let MethodInputs { params, smoothed, g, lookup, h_min, noise_smoothed, gate } = *inputs;
    let beta = params.propagation.unwrap_or(1.0);
    let propagation = weight * beta;
    // Beyond the image the front is pushed back, whichever way it propagates.
    let outside = -propagation.abs();
    let mut region: Option<Arc<RegionForce>> = None;
    let flow = match method {
        Method::Threshold { lower, upper } => {
            let (lo, hi) = (norm.threshold(lower), norm.threshold(upper));
            let scale = threshold_scale(lo, hi, noise_smoothed);
            resolved.threshold_scale = Some(scale * norm.scale);
            let inv = 1.0 / scale;
            let speed: Vec<f32> = smoothed
                .data
                .par_iter()
                .map(|&v| {
                    // Distance into the window from its nearer end (∞ − v = ∞ for an open
                    // end), in units of the scale: 1 well inside, 0 on a threshold.
                    let p = ((v as f64 - lo as f64).min(hi as f64 - v as f64) * inv) as f32;
                    propagation * p.clamp(-1.0, 1.0)
                })
                .collect();
            resolved.curvature = params.curvature.unwrap_or(0.2 * h_min as f32);
            let field = VoxelField { lookup, data: Arc::new(speed), outside };
            Flow::normal_speed(Speed::Field(Arc::new(field)))
                .with_curvature(weight * resolved.curvature)
        }
        Method::Gac => {
            let g = g.ok_or_else(|| {
                SegmentError::InvalidParameter("GAC without its edge potential".into())
            })?;
            resolved.curvature = params.curvature.unwrap_or(GAC_CURVATURE * h_min as f32);
            resolved.advection = params.advection.unwrap_or(GAC_ADVECTION);
            let alpha = weight * resolved.advection;
            let gg = features::gradient(g)?.map(|c| c.data);
            let speed: Vec<f32> = match gate {
                // Growing, the balloon pushes outward up to the first edge's level and,
                // weakening, for two threshold scales w beyond it; then inward, in full 4w
                // past it. Shrinking, it turns at the level itself: inward in full w before
                // it, outward in full w past it (into an object the start cuts, whose
                // intensity may lie less than 2w beyond the level in a noisy image).
                Some(Gate { level, side, shrinking, .. }) => {
                    let inv = (1.0 / threshold_scale(level, f32::INFINITY, noise_smoothed)) as f32;
                    let (gain, offset) = if shrinking { (1.0, 0.0) } else { (0.5, 1.0) };
                    g.data
                        .par_iter()
                        .zip(smoothed.data.par_iter())
                        .map(|(&v, &i)| {
                            let turn = gain * side * (i - level) * inv + offset;
                            propagation * v * turn.clamp(-1.0, 1.0)
                        })
                        .collect()
                }
                None => g.data.par_iter().map(|&v| propagation * v).collect(),
            };
            let velocity = gg.map(|mut c| {
                c.par_iter_mut().for_each(|v| *v *= -alpha);
                Arc::new(c)
            });
            let z = VoxelField { lookup, data: Arc::new(par_copy(&g.data)), outside: 1.0 };
            let f = VoxelField { lookup, data: Arc::new(speed), outside };
            let mut flow = Flow::normal_speed(Speed::Field(Arc::new(f)))
                .with_curvature_field(weight * resolved.curvature, Arc::new(z));
            if alpha > 0.0 {
                flow = flow.with_velocity(Velocity::Field(Arc::new(VoxelVector {
                    lookup,
                    data: velocity,
                })));
            }
            flow
        }
        Method::ChanVese { lambda1, lambda2, nu } => {
            resolved.curvature = params.curvature.unwrap_or(0.2 * h_min as f32);
            let force = Arc::new(RegionForce::new(
                lookup,
                Arc::new(par_copy(&smoothed.data)),
                [lambda1 * beta, lambda2 * beta, nu],
                weight,
            ));
            region = Some(force.clone());
            Flow::normal_speed(Speed::Field(force)).with_curvature(weight * resolved.curvature)
        }
    };
    Ok((flow, region))
}

/// The intensity over which the threshold speed goes from 0 (on a threshold) to ±1:
/// the window's half-width when both ends are finite, but at most twice the noise left in
/// the smoothed image (a window far wider than the noise would otherwise make the speed
/// small everywhere, and an open window, zero); for a noise-free image with an open
/// window, 5 % of the image's robust range (normalised units: 0.05).
fn threshold_scale(lo: f32, hi: f32, noise: f64) -> f64 {
    let half = 0.5 * (hi as f64 - lo as f64);
    let by_noise = 2.0 * noise;
    let scale = match (half.is_finite(), by_noise > 0.0) {
        (true, true) => half.min(by_noise),
        (true, false) => half,
        (false, true) => by_noise,
        (false, false) => 0.05,
    };
    scale.max(1e-9)
}

/// The images and figures the flows are built from.
struct Prepared {
    /// The intensities the methods compare (the image, or a feature image given for the
    /// threshold and Chan–Vese methods), normalised and smoothed.
    smoothed: Image,
    norm: Normalization,
    /// GAC's edge potential.
    g: Option<Image>,
    /// The seeds' first edge ([`Params::first_edge`]).
    gate: Option<Gate>,
    resolved: Resolved,
}

/// The first edge that the rays from the seeds cross ([`Params::first_edge`]), in
/// normalised units: where GAC's balloon turns, what Chan–Vese's outside competes with,
/// and on which side the seeds lie.
#[derive(Clone, Copy, Debug)]
struct Gate {
    level: f32,
    /// The intensity beyond the edge (the neighbouring tissue).
    far: f32,
    /// +1 when the seeds are brighter than `level`, −1 when darker.
    side: f32,
    /// Seen from a start that shrinks onto the objects ([`shrinking_gate`]).
    shrinking: bool,
}

/// The first edge from the rays: the median intensity at the edges' gradient peaks (and
/// twice as far from the seeds' median m, beyond), when at least a quarter of the rays met an edge and three quarters of those
/// agree on its side (a seed between a darker and a brighter neighbour has no one level).
fn first_edge(probe: &stats::EdgeProbe, m: f64) -> Option<Gate> {
    if !probe.crossed() {
        return None;
    }
    let n = probe.contrasts.len();
    let darker = probe.contrasts.iter().filter(|&&c| c < 0.0).count();
    let side = if darker * 4 >= n * 3 {
        1.0
    } else if (n - darker) * 4 >= n * 3 {
        -1.0
    } else {
        return None;
    };
    let same: Vec<f64> =
        probe.contrasts.iter().copied().filter(|&c| (c < 0.0) == (side > 0.0)).collect();
    let c = stats::quantile(&same, 0.5)?;
    Some(Gate { level: (m + 0.5 * c) as f32, far: (m + c) as f32, side, shrinking: false })
}

/// The defaults of a run from the image's own statistics (module docs, "Defaults").
fn prepare(
    image: &Image,
    init: &Init,
    params: &Params,
    field: &DenseField,
) -> Result<Prepared, SegmentError> {
    let methods: Vec<Method> =
        std::iter::once(params.method).chain(params.terms.iter().map(|t| t.0)).collect();
    let has_gac = methods.iter().any(|m| matches!(m, Method::Gac));
    let only_gac = methods.len() == 1 && has_gac;
    // A feature image replaces the intensities the threshold and Chan–Vese methods compare
    // (used as given: no smoothing unless σ is given); for GAC it is the edge potential.
    let feature = params.feature.as_deref();
    let source = match feature {
        Some(f) if !only_gac => f,
        _ => image,
    };
    let norm = Normalization::of(&source.data)?;
    let normed = norm.image(source);
    let noise = stats::noise_sigma(&normed)?;
    let axes = image.dims.iter().filter(|&&n| n > 1).count().max(1);
    let m_in = inside_quantile(&normed, field, 0.5)?;
    let planar = image.is_2d();
    // GAC shrinking a start onto the objects estimates from the start's boundary, where the
    // front starts, what a growing front estimates from its seeds.
    let shrinks = only_gac && feature.is_none() && shrinks_onto_objects(params, init);
    let boundary = if shrinks { StartBoundary::of(image, field)? } else { None };
    let site = match &boundary {
        Some(b) => Site::Boundary(b),
        None => Site::Seeds(init),
    };
    let smooth = |v: f64| -> Result<Image, GridError> {
        if v <= 0.0 {
            return Ok(par_clone(&normed));
        }
        let mut s = image.spacing.map(|h| v * h);
        if planar {
            s[2] = 0.0;
        }
        features::gaussian(&normed, s)
    };
    let mut resolved = Resolved {
        method: params.method,
        terms: params.terms.clone(),
        sigma: [0.0; 3],
        propagation: params.propagation.unwrap_or(1.0),
        curvature: 0.0,
        advection: 0.0,
        edge_scale: None,
        sigmoid: None,
        edge_contrast: None,
        edge_level: None,
        start_voxels: None,
        threshold_scale: None,
        noise: noise * norm.scale,
        noise_smoothed: 0.0,
        normalization: [norm.center, norm.scale],
        leak_guard: params.leak_guard,
        feature: feature.is_some(),
        spacing: image.spacing,
        planar,
        // Chosen with the flow's curvature weight (`segment_in_pool`).
        integrator: Integrator::Rk3,
    };
    // σ in voxels of each axis (the default), or world units (given).
    // The rays' pilot at one voxel of smoothing, kept when that is the smoothing chosen.
    let mut pilot: Option<(Image, Image, stats::EdgeProbe, f64)> = None;
    let voxels = match (params.sigma, params.method) {
        (Some(_), _) => None,
        (None, _) if feature.is_some() && !only_gac => Some(0.0),
        (None, Method::Threshold { lower, upper }) => {
            // The decision level is the nearer threshold.
            let (lo, hi) = (norm.threshold(lower) as f64, norm.threshold(upper) as f64);
            Some(margin_smoothing(noise, (m_in - lo).min(hi - m_in), axes))
        }
        (None, Method::Gac) => {
            let probe = gac_probe(image, &site, field, &smooth, 1.0, noise, axes)?;
            let contrast = probe.2.contrast();
            let v = match contrast {
                Some(c) if noise > 0.0 => {
                    // Edge gradient over the noise's gradient ≥ 10, for an edge of contrast
                    // c blurred over a voxel: c / (√(2π) √(v² + 1)) against
                    // σ_n (∫G²)^½ / (√2 v).
                    stats::smoothing_voxels(0.5, 3.0, |v| {
                        let edge = c / ((std::f64::consts::TAU).sqrt() * (v * v + 1.0).sqrt());
                        let noise_grad =
                            noise * stats::noise_factor(v, axes) / (std::f64::consts::SQRT_2 * v);
                        edge >= 10.0 * noise_grad
                    })
                }
                _ => 1.0,
            };
            resolved.edge_contrast = contrast.map(|c| c * norm.scale);
            if v == 1.0 {
                pilot = Some(probe);
            }
            Some(v)
        }
        (None, Method::ChanVese { .. }) => {
            // As for the threshold method, with the decision level midway between the
            // seeds' intensity and the first edge's far side; one voxel when the rays
            // found no edge.
            let probe = gac_probe(image, &site, field, &smooth, 1.0, noise, axes)?;
            let v = match probe.2.contrast() {
                Some(c) if c > 0.0 => margin_smoothing(noise, 0.5 * c, axes),
                _ => 1.0,
            };
            if v == 1.0 {
                pilot = Some(probe);
            }
            Some(v)
        }
    };
    let sigmas = match (params.sigma, voxels) {
        (Some(s), _) => [s; 3],
        (None, Some(v)) => image.spacing.map(|h| v * h),
        (None, None) => [0.0; 3],
    };
    resolved.sigma = if planar { [sigmas[0], sigmas[1], 0.0] } else { sigmas };
    let sigma_max = resolved.sigma.iter().fold(0.0f64, |m, &v| m.max(v));
    // The pilot's Ĩ when it ran at the smoothing chosen (the same call: the same bits),
    // and its gradient and edges for below.
    let (piloted, mut pilot) = match pilot {
        Some((smoothed, grad, probe, m)) => (Some(smoothed), Some((grad, probe, m))),
        None => (None, None),
    };
    let smoothed = match piloted {
        Some(s) => s,
        None if sigma_max > 0.0 => features::gaussian(&normed, resolved.sigma)?,
        None => par_clone(&normed),
    };
    // The noise left after smoothing.
    resolved.noise_smoothed = noise * resolved_factor(&resolved, image, axes) * norm.scale;
    // The rays' edges through Ĩ as smoothed (the pilot's when it ran at this smoothing),
    // for GAC's sigmoid and the first edge.
    let use_first_edge = params.first_edge && params.propagation.unwrap_or(1.0) > 0.0;
    let gac_edges = has_gac && !(feature.is_some() && only_gac) && params.edge_scale.is_none();
    let has_cv = methods.iter().any(|m| matches!(m, Method::ChanVese { .. }));
    let mut edges = if gac_edges || (use_first_edge && has_cv) {
        Some(match pilot.take() {
            Some(edges) => edges,
            None => {
                let factor = resolved_factor(&resolved, image, axes);
                probe_of(image, &site, field, &smoothed, noise * factor)?
            }
        })
    } else {
        None
    };
    let gate = if use_first_edge {
        edges.as_ref().and_then(|(_, p, m)| first_edge(p, *m))
    } else if params.first_edge && boundary.is_some() {
        // The first edge inward from the start's boundary (`shrinking_gate`): the same
        // rays as the sigmoid's, or, with the sigmoid given, their own.
        let own;
        let (_, probe, m) = match &edges {
            Some(e) => e,
            None => {
                let factor = resolved_factor(&resolved, image, axes);
                own = probe_of(image, &site, field, &smoothed, noise * factor)?;
                &own
            }
        };
        shrinking_gate(probe, *m)
    } else {
        None
    };
    resolved.edge_level = gate.map(|g| g.level as f64 * norm.scale + norm.center);
    let g = if has_gac {
        Some(match (feature, params.edge_scale, params.sigmoid) {
            (Some(f), _, _) if only_gac => f.clone(),
            (_, Some(k), _) => {
                resolved.edge_scale = Some(k);
                let grad = voxel_gradient(&smoothed)?;
                features::edge_potential(&grad, k / norm.scale)?
            }
            (_, None, given) => {
                let (grad, probe, _) = edges.take().ok_or_else(|| {
                    SegmentError::InvalidParameter("GAC without the rays' edges".into())
                })?;
                let (alpha, beta) = match given {
                    Some((a, b)) => (a / norm.scale, b / norm.scale),
                    None => {
                        let f = resolved_factor(&resolved, image, axes);
                        let v = smoothing_voxels_of(&resolved, image).unwrap_or(0.5);
                        let s = noise * f / (std::f64::consts::SQRT_2 * v);
                        let chi999 = if axes >= 3 { 4.03 } else { 3.72 };
                        sigmoid_from_edges(&grad, &site, field, Some(&probe), chi999 * s)?
                    }
                };
                resolved.sigmoid = Some((alpha * norm.scale, beta * norm.scale));
                // Decreasing in |∇Ĩ|: 1 in flat regions, 0 on edges.
                features::sigmoid(&grad, -alpha, beta, 0.0, 1.0)?
            }
        })
    } else {
        None
    };
    Ok(Prepared { smoothed, norm, g, gate, resolved })
}

/// The smallest σ (voxels) that puts the noise left in Ĩ [`THRESHOLD_MARGIN`] times below
/// `margin`, the distance from the seeds' intensity to the decision level; none when the
/// image's own noise already is (smoothing would only round thin parts off).
fn margin_smoothing(noise: f64, margin: f64, axes: usize) -> f64 {
    if margin > 0.0 && THRESHOLD_MARGIN * noise <= margin {
        0.0
    } else if noise == 0.0 {
        0.5
    } else if margin > 0.0 {
        stats::smoothing_voxels(0.5, 2.0, |v| {
            THRESHOLD_MARGIN * noise * stats::noise_factor(v, axes) <= margin
        })
    } else {
        1.0
    }
}

/// The smoothing `resolved` holds, in voxels of the axis it smooths least (axes of one
/// voxel aside); `None` without smoothing.
fn smoothing_voxels_of(resolved: &Resolved, image: &Image) -> Option<f64> {
    let v = (0..3)
        .filter(|&a| image.dims[a] > 1)
        .map(|a| resolved.sigma[a] / image.spacing[a])
        .fold(f64::INFINITY, f64::min);
    (v.is_finite() && v > 0.0).then_some(v)
}

/// The factor by which the smoothing `resolved` holds divides white noise (1 without).
fn resolved_factor(resolved: &Resolved, image: &Image, axes: usize) -> f64 {
    smoothing_voxels_of(resolved, image).map_or(1.0, |v| stats::noise_factor(v, axes).min(1.0))
}

/// How far (normalised units) the smoothed intensity must depart from the seeds' for a
/// ray to have met an edge: five times the noise left after smoothing, and at least 5 %
/// of the image's robust range.
fn edge_departure(noise_left: f64) -> f64 {
    (5.0 * noise_left).max(0.05)
}

/// |∇Ĩ| per voxel step (unit spacing): a step between two slices 2.5 mm apart is as much
/// an edge as one between two pixels; in world units it would read 2.5× weaker and the
/// front would leak through the poles of a thick-sliced volume.
fn voxel_gradient(smoothed: &Image) -> Result<Image, GridError> {
    features::voxel_gradient_magnitude(smoothed)
}

/// GAC's pilot: Ĩ at `v` voxels, its gradient and the rays' edges.
fn gac_probe(
    image: &Image,
    site: &Site<'_>,
    field: &DenseField,
    smooth: &dyn Fn(f64) -> Result<Image, GridError>,
    v: f64,
    noise: f64,
    axes: usize,
) -> Result<(Image, Image, stats::EdgeProbe, f64), GridError> {
    let smoothed = smooth(v)?;
    let (grad, probe, m) =
        probe_of(image, site, field, &smoothed, noise * stats::noise_factor(v, axes).min(1.0))?;
    Ok((smoothed, grad, probe, m))
}

/// Whether the run starts from a region larger than the objects and shrinks onto them: a
/// negative propagation from a mask or a level set.
fn shrinks_onto_objects(params: &Params, init: &Init) -> bool {
    params.propagation.unwrap_or(1.0) < 0.0 && !matches!(init, Init::Seeds { .. })
}

/// The voxel coordinates of the voxel at array index `k` of an image of `dims`.
fn voxel_position(k: usize, dims: [usize; 3]) -> [f64; 3] {
    let [nx, ny, _] = dims;
    [(k % nx) as f64, ((k / nx) % ny) as f64, (k / (nx * ny)) as f64]
}

/// Where the rays that estimate a run's edges start, and whose intensity they depart from.
enum Site<'a> {
    /// The seeds' centres, or the deepest voxel of an initial mask or level set; m is the
    /// median of Ĩ over the initial region.
    Seeds(&'a Init),
    /// The boundary of a start that shrinks onto the objects.
    Boundary(&'a StartBoundary),
}

/// The boundary voxels of an initial region (inside, with a 6-neighbour outside the region
/// or the image), where a front that shrinks onto the objects starts, and a sample of up
/// to [`SHRINK_ORIGINS`] of them spread over it, the rays' origins.
struct StartBoundary {
    voxels: Vec<usize>,
    origins: Vec<[f64; 3]>,
}

impl StartBoundary {
    /// The boundary of `field`'s region (φ ≤ 0) over the image; `None` when it is empty.
    /// Refused before it is collected when the machine cannot hold it (with the copy of
    /// the image's values over it that [`StartBoundary::quantile`] takes): a start whose
    /// every other voxel is boundary (a checkerboard) holds half the image's voxels.
    fn of(image: &Image, field: &DenseField) -> Result<Option<Self>, GridError> {
        let [nx, ny, nz] = image.dims;
        let phi = &field.data()[..image.len()];
        let on_boundary = |k: usize| {
            if phi[k] > 0.0 {
                return false;
            }
            let (x, y, z) = (k % nx, (k / nx) % ny, k / (nx * ny));
            let out = |d: usize, n: usize, stride: usize| {
                n > 1 && (d == 0 || d == n - 1 || phi[k - stride] > 0.0 || phi[k + stride] > 0.0)
            };
            out(x, nx, 1) || out(y, ny, nx) || out(z, nz, nx * ny)
        };
        let count = (0..image.len()).into_par_iter().filter(|&k| on_boundary(k)).count();
        if count == 0 {
            return Ok(None);
        }
        let per_voxel = std::mem::size_of::<usize>() + std::mem::size_of::<f32>();
        crate::memory::check(
            crate::memory::bytes_of(count as u128, per_voxel),
            "the initial region's boundary voxels",
        )?;
        let voxels: Vec<usize> =
            (0..image.len()).into_par_iter().filter(|&k| on_boundary(k)).collect();
        // A sample spread over the whole boundary: the voxels of the smallest hashes of
        // their indices. (Every n-th voxel in array order aliases with the rows: on a
        // rectangle, with two boundary voxels a row, an even step took the left side alone.)
        // Kept to the smallest few per chunk as it goes: the same set, whatever the chunks.
        let smallest = |mut v: Vec<(u64, usize)>| {
            if v.len() > SHRINK_ORIGINS {
                v.select_nth_unstable(SHRINK_ORIGINS);
                v.truncate(SHRINK_ORIGINS);
            }
            v
        };
        let mut sample = voxels
            .par_iter()
            .fold(Vec::new, |mut acc, &k| {
                acc.push((super::phantom::mix64(k as u64), k));
                if acc.len() >= 4 * SHRINK_ORIGINS {
                    acc = smallest(acc);
                }
                acc
            })
            .map(smallest)
            .reduce(Vec::new, |mut a, b| {
                a.extend(b);
                smallest(a)
            });
        sample.sort_unstable();
        let origins = sample.iter().map(|&(_, k)| voxel_position(k, image.dims)).collect();
        Ok(Some(StartBoundary { voxels, origins }))
    }

    /// The `q`-quantile (lower order statistic) of `values` over the boundary voxels.
    fn quantile(&self, values: &Image, q: f64) -> f64 {
        let v: Vec<f32> = self.voxels.par_iter().map(|&k| values.data[k]).collect();
        let k = (q * (v.len() - 1) as f64).floor() as usize;
        stats::order_statistics(&v, [k])[0] as f64
    }
}

/// At most this many boundary voxels start the rays from a shrinking start.
const SHRINK_ORIGINS: usize = 256;

/// |∇Ĩ|, the rays' edges through `smoothed` (Ĩ, holding `noise_left`) from `site`, and the
/// intensity m they depart from.
///
/// From a start's boundary, m is the median of Ĩ over all of its voxels (the background the
/// front starts in), and about half of a boundary voxel's directions point out of the
/// start and leave it (at a face, the image) at once: an edge is found when a sixteenth of
/// the other half crossed one.
fn probe_of(
    image: &Image,
    site: &Site<'_>,
    field: &DenseField,
    smoothed: &Image,
    noise_left: f64,
) -> Result<(Image, stats::EdgeProbe, f64), GridError> {
    let grad = voxel_gradient(smoothed)?;
    let tau = edge_departure(noise_left);
    let reach = 3.0 * image.spacing.iter().fold(0.0f64, |a, &b| a.max(b));
    let (probe, m) = match site {
        Site::Seeds(init) => {
            let m = inside_quantile(smoothed, field, 0.5)?;
            let origins = ray_origins(image, init, field);
            (stats::probe_edges(smoothed, &grad, &origins, m, tau, reach), m)
        }
        Site::Boundary(b) => {
            let m = b.quantile(smoothed, 0.5);
            let mut probe = stats::probe_edges(smoothed, &grad, &b.origins, m, tau, reach);
            // Half of the rays point out of the start and leave it at once. Of the inward
            // half, the objects fill only part of the view: seen from a box's faces, a ball
            // a fifth of the box wide fills about a sixth. So a sixteenth of them, not the
            // quarter asked of rays from inside an object, must cross an edge.
            probe.rays = probe.rays.div_ceil(2);
            probe.share = 16;
            (probe, m)
        }
    };
    Ok((grad, probe, m))
}

/// The first edge inward from a shrinking start (GAC with β < 0 from a mask or a level set),
/// from the rays of [`probe_of`] from the start's boundary: beyond the edge's level the
/// balloon turns outward ([`first_edge`]; the same rule as a growing front's, seen from the
/// other side, turning at the level itself), so that a front that starts inside an object
/// the start cuts holds there instead of eating the object from within.
fn shrinking_gate(probe: &stats::EdgeProbe, m: f64) -> Option<Gate> {
    first_edge(probe, m).map(|g| Gate { shrinking: true, ..g })
}

/// Where rays start, in voxel coordinates: the seeds' centres, or the deepest voxel of an
/// initial mask or level set.
fn ray_origins(image: &Image, init: &Init, field: &DenseField) -> Vec<[f64; 3]> {
    let s = image.spacing;
    match init {
        Init::Seeds { seeds, world } => seeds
            .iter()
            .map(|sd| {
                if *world {
                    let p = lattice_position(image, sd.center);
                    std::array::from_fn(|a| p[a] / s[a])
                } else {
                    sd.center
                }
            })
            .collect(),
        _ => {
            let n = image.len();
            let (k, _) = field.data()[..n].iter().enumerate().fold(
                (0, f32::INFINITY),
                |(bk, bv), (k, &v)| if v < bv { (k, v) } else { (bk, bv) },
            );
            vec![voxel_position(k, image.dims)]
        }
    }
}

/// The sigmoid edge potential's (α, β) by the rule of ITK's guide (Software Guide,
/// "Geodesic Active Contours Segmentation": K₁ a gradient typical of the object's inside,
/// K₂ one typical of its edges, α = (K₂ − K₁)/6, β = (K₁ + K₂)/2, so that g = 0.95 at K₁
/// and 0.05 at K₂), with both measured without a truth:
///
/// * K₁ = t, the 90th percentile of |∇Ĩ| inside the initial region (the seeds lie in the
///   object); from a start that shrinks onto the objects, over the start's boundary (the
///   region the front crosses first, where the initial region holds the objects too);
/// * K₂ = e, the 10th percentile of the peak gradients of the first edge that the rays
///   from the seeds (or the start's boundary) cross ([`stats::probe_edges`]): the guide's
///   "minimum value along the contour", robustly, when at least a quarter of the rays met
///   an edge.
///
/// When no such edge stands 1.5 K₁ above the inside (thin objects, whose seeds lie partly
/// on their edge), β comes from the noise instead: β = max(n, min(t, e/2)), α = β/8
/// (g = 0.95 at 0.63 β, 0.05 at 1.37 β), with n the 99.9th percentile of the gradient that
/// the image's noise alone leaves after smoothing (`noise_gradient`), and e the 99th
/// percentile of |∇Ĩ| over the image when the rays found no edge.
fn sigmoid_from_edges(
    grad: &Image,
    site: &Site<'_>,
    initial: &DenseField,
    probe: Option<&stats::EdgeProbe>,
    noise_gradient: f64,
) -> Result<(f64, f64), GridError> {
    let texture = match site {
        Site::Seeds(_) => inside_quantile(grad, initial, 0.9)?,
        Site::Boundary(b) => b.quantile(grad, 0.9),
    };
    let edge = probe.filter(|p| p.crossed()).and_then(|p| stats::quantile(&p.peaks, EDGE_QUANTILE));
    if let Some(k2) = edge.filter(|&k2| k2 > 1.5 * texture) {
        return Ok(((k2 - texture) / 6.0, 0.5 * (texture + k2)));
    }
    let e = match edge {
        Some(e) => e,
        None => features::percentile(&grad.data, 0.99)? as f64,
    };
    let beta = noise_gradient.max(texture.min(0.5 * e));
    let beta = if beta > 0.0 { beta } else { f64::MIN_POSITIVE };
    Ok((beta / 8.0, beta))
}

/// The `q`-quantile of `values` over the initial region (φ ≤ 0 on the image's voxels), 0
/// when the region holds no image voxel.
fn inside_quantile(values: &Image, initial: &DenseField, q: f64) -> Result<f64, GridError> {
    let n = values.data.len();
    // The inside values part by part (one per thread), in parallel; the quantile is exact,
    // whatever the parts.
    let part = features::part_len(n);
    let parts: Vec<Vec<f32>> = values
        .data
        .par_chunks(part)
        .zip(initial.data()[..n].par_chunks(part))
        .map(|(v, phi)| v.iter().zip(phi).filter(|&(_, &p)| p <= 0.0).map(|(&v, _)| v).collect())
        .collect();
    let parts: Vec<&[f32]> = parts.iter().map(Vec::as_slice).filter(|p| !p.is_empty()).collect();
    Ok(if parts.is_empty() { 0.0 } else { features::percentile_of_parts(&parts, q)? as f64 })
}

/// Image voxels per parallel part of the whole-image passes (masks, counts, copies).
const PART_VOXELS: usize = 1 << 16;

/// A copy of `data`, made in parallel (the first touch of a fresh image-sized buffer is
/// the cost, not the copy).
fn par_copy(data: &[f32]) -> Vec<f32> {
    data.par_iter().copied().collect()
}

/// A copy of `image`, its data copied in parallel ([`par_copy`]).
fn par_clone(image: &Image) -> Image {
    let (dims, spacing, to_world) = (image.dims, image.spacing, image.to_world);
    Image { dims, spacing, data: par_copy(&image.data), to_world }
}

/// The voxels of a 0/1 mask, counted in parallel (an integer: any split).
fn par_count(mask: &[u8]) -> u64 {
    mask.par_chunks(PART_VOXELS).map(|c| c.iter().map(|&v| v as u64).sum::<u64>()).sum()
}

/// Why a run leaked, if it did: the region covers at least [`LEAK_FACE_FRACTION`] of a
/// face of the image (and 16 voxels) that the initial region did not touch (a thin spur
/// that brushes a face is not a leak; a front running into the background covers faces
/// within a few steps), or it grew past half the image. A `shrinking` run (a start larger
/// than the objects, β < 0) leaks when it grows past its start. `sizes`: the region's,
/// the initial region's and the image's voxels.
fn leak_of(
    faces: &[u64; 6],
    first: &[u64; 6],
    dims: [usize; 3],
    sizes: [u64; 3],
    shrinking: bool,
) -> Option<String> {
    let [voxels, initial, image] = sizes;
    if shrinking {
        return (voxels > initial)
            .then(|| format!("the region grew past its start, to {voxels} voxels from {initial}"));
    }
    const NAMES: [&str; 6] = ["x = 0", "x = max", "y = 0", "y = max", "z = 0", "z = max"];
    let area = |f: usize| -> u64 {
        let [nx, ny, nz] = dims.map(|n| n as u64);
        [ny * nz, ny * nz, nx * nz, nx * nz, nx * ny, nx * ny][f]
    };
    let reached: Vec<String> = (0..6)
        .filter(|&f| {
            first[f] == 0 && faces[f] >= 16u64.max((area(f) as f64 * LEAK_FACE_FRACTION) as u64)
        })
        .map(|f| format!("{} ({} voxels)", NAMES[f], faces[f]))
        .collect();
    if !reached.is_empty() {
        return Some(format!(
            "the region reached the image's {} face{} where the initial region did not touch it",
            reached.join(", "),
            if reached.len() > 1 { "s" } else { "" }
        ));
    }
    if voxels > initial && 2 * voxels > image {
        return Some(format!(
            "the region grew to {voxels} of the image's {image} voxels, more than half"
        ));
    }
    None
}

/// The part of an image face a region must cover, beyond 16 voxels, for the leak guard
/// to call its contact with the face a leak.
const LEAK_FACE_FRACTION: f64 = 0.005;

/// The weighted sum of the methods' flows ([`Params::terms`]): their speeds add, their
/// curvature weights add as one field Σ εᵢ Zᵢ(x), and the one advecting term (GAC) keeps
/// its velocity.
fn sum_of_flows(flows: Vec<Flow>) -> Flow {
    let mut speeds: Vec<Arc<dyn ScalarFn>> = Vec::new();
    let mut curvatures: Vec<(f32, Option<Arc<dyn ScalarFn>>)> = Vec::new();
    let mut velocity = None;
    for f in flows {
        if let Speed::Field(s) = f.speed {
            speeds.push(s);
        }
        curvatures.push((f.curvature, f.curvature_field));
        velocity = velocity.or(f.velocity);
    }
    let mut flow = Flow::normal_speed(Speed::Field(Arc::new(SumField { terms: speeds })))
        .with_curvature_field(1.0, Arc::new(CurvatureSum { terms: curvatures }));
    flow.velocity = velocity;
    flow
}

/// The band voxels near the interface before a step, in the parts of the tile list that
/// [`change_since`] found them in (none empty; in tile order across the parts): per tile
/// its coordinate, the mask of its near voxels (bit `l` for voxel `l`) and where their
/// values (φⁿ, in voxel order) start in the part's `values`. Kept in parts, so that no
/// step copies them into one list.
#[derive(Default)]
struct Near {
    parts: Vec<NearPart>,
}

#[derive(Default)]
struct NearPart {
    tiles: Vec<(Coord, u64, u32)>,
    values: Vec<f32>,
}

/// A place in a [`Near`]: (part, tile within it); past the end at `(parts, 0)`.
type NearAt = (usize, usize);

impl Near {
    /// Near voxels.
    fn len(&self) -> usize {
        self.parts.iter().map(|p| p.values.len()).sum()
    }

    /// Whether there are none.
    fn is_empty(&self) -> bool {
        self.parts.is_empty()
    }

    /// The place of the first tile at or after coordinate `c`.
    fn position(&self, c: Coord) -> NearAt {
        let p = self.parts.partition_point(|q| q.tiles.last().is_some_and(|t| t.0 < c));
        match self.parts.get(p) {
            Some(q) => (p, q.tiles.partition_point(|t| t.0 < c)),
            None => (p, 0),
        }
    }

    /// The tile at `at` (before the end): its coordinate, mask and values.
    fn tile(&self, (p, i): NearAt) -> (Coord, u64, &[f32]) {
        let q = &self.parts[p];
        let (c, mask, start) = q.tiles[i];
        (c, mask, &q.values[start as usize..start as usize + mask.count_ones() as usize])
    }

    /// The place after `at`.
    fn next(&self, (p, i): NearAt) -> NearAt {
        if i + 1 < self.parts[p].tiles.len() {
            (p, i + 1)
        } else {
            (p + 1, 0)
        }
    }
}

/// Tiles per part of [`change_since`]: small, for load balance (its sum is exact, so the
/// split does not change it).
const CHANGE_CHUNK: usize = 64;

/// The segmentation's tile grid (it always runs on tiles).
fn tiles_of(sim: &Simulation) -> &TileGrid {
    sim.tiles().expect("a segmentation evolves on tiles")
}

/// The step's change at the voxels `near` held before it: the sum over them of
/// ((φⁿ⁺¹ − φⁿ)/Δt)², where a voxel that left the band reads ±γ; the band voxels after
/// it; and its own band voxels with |φ| < `h` (the next step's `near`). The old and new
/// tiles are merged in parts of the new list, in parallel; a part takes the old tiles
/// from its first tile up to the next part's (before the first part: all from the
/// start), so every old voxel is met once.
///
/// On a planar lattice (`planar`) only each tile's first z-slice is read: the image's
/// voxels, of which the other three slices are copies (the sweep copies them, see
/// `TileBlock::apply_slices`), so the RMS is the same and the band counts the image's
/// pixels.
///
/// The sum is exact ([`ExactSum`]: each term ((φⁿ⁺¹ − φⁿ)/h)², in voxels of `h`, rounded
/// once to f32 and to the sum's fixed point, then scaled by (h/Δt)²), so it is the same
/// whatever the parts and the thread count, as the engine's reductions are. The fixed
/// point resolves 2⁻³² ≈ 2·10⁻¹⁰ voxel² a term; at the default stopping RMS (0.01) a term
/// is about 10⁻⁶ voxel² (Δt of 0.1–0.25 h on the 128³ phantoms).
fn change_since(grid: &TileGrid, near: &Near, dt: f64, h: f64, planar: bool) -> (f64, usize, Near) {
    let coords = grid.tile_coords();
    let image_voxels = if planar { SLICE_LEN } else { TILE_LEN };
    let values = grid.values();
    let gamma = grid.gamma();
    let parts = coords.len().div_ceil(CHANGE_CHUNK).max(1);
    let end = (near.parts.len(), 0);
    let start_of = |part: usize| match part {
        0 => (0, 0),
        _ if part * CHANGE_CHUNK >= coords.len() => end,
        _ => near.position(coords[part * CHANGE_CHUNK]),
    };
    let inv_h = 1.0 / h;
    let results: Vec<(ExactSum, usize, NearPart)> = (0..parts)
        .into_par_iter()
        .map(|part| {
            let tiles = part * CHANGE_CHUNK..((part + 1) * CHANGE_CHUNK).min(coords.len());
            let (mut k, stop) = (start_of(part), start_of(part + 1));
            let mut band = 0usize;
            let mut next = NearPart {
                tiles: Vec::with_capacity(tiles.len()),
                values: Vec::with_capacity(tiles.len() * 8),
            };
            // Terms gathered in blocks for the sum's vectorised addition.
            let mut sq = ExactSum::default();
            let (mut terms, mut held) = ([0.0f32; 64], 0);
            let mut diff = |old: f32, new: f32| {
                let d = (new - old) as f64 * inv_h;
                terms[held] = (d * d) as f32;
                held += 1;
                if held == terms.len() {
                    sq.add_all(&terms);
                    held = 0;
                }
            };
            // Old tile `k` against the new values of its tile, or none when it left the
            // band (its voxels then read ±γ).
            let mut old_tile = |k: NearAt, now: Option<&[f32]>| {
                let (_, mask, old) = near.tile(k);
                let mut bits = mask;
                for &o in old {
                    let v = now.map_or(gamma, |vals| vals[bits.trailing_zeros() as usize]);
                    diff(o, if v.abs() < gamma { v } else { sim_value_left(o, gamma) });
                    bits &= bits - 1;
                }
            };
            for p in tiles {
                let tc = coords[p];
                let vals = &values[p].0[..image_voxels];
                // The old tiles up to this one: those before it left the band.
                while k < stop && near.tile(k).0 <= tc {
                    old_tile(k, (near.tile(k).0 == tc).then_some(vals));
                    k = near.next(k);
                }
                // The band voxels and those within h as bits (branch-free).
                let (in_band, near_bits) =
                    vals.iter().enumerate().fold((0u64, 0u64), |(b, n), (l, &v)| {
                        let in_band = v.abs() < gamma;
                        let near = in_band & ((v.abs() as f64) < h);
                        (b | (in_band as u64) << l, n | (near as u64) << l)
                    });
                band += in_band.count_ones() as usize;
                if near_bits != 0 {
                    let start =
                        u32::try_from(next.values.len()).expect("fewer near voxels than 2^32");
                    next.tiles.push((tc, near_bits, start));
                    let mut bits = near_bits;
                    while bits != 0 {
                        next.values.push(vals[bits.trailing_zeros() as usize]);
                        bits &= bits - 1;
                    }
                }
            }
            while k < stop {
                old_tile(k, None);
                k = near.next(k);
            }
            sq.add_all(&terms[..held]);
            (sq, band, next)
        })
        .collect();
    let (mut sq, mut band) = (ExactSum::default(), 0);
    let mut next = Near { parts: Vec::with_capacity(results.len()) };
    for (s, b, n) in results {
        sq = sq.merge(s);
        band += b;
        if !n.tiles.is_empty() {
            next.parts.push(n);
        }
    }
    (sq.value() * (h / dt) * (h / dt), band, next)
}

/// The value of a voxel that left the band in a step, whose value before was `old`: the
/// band's ±γ on the side it was on (a voxel within h of the interface cannot cross it and
/// leave the band in one CFL-limited step).
fn sim_value_left(old: f32, gamma: f32) -> f32 {
    if old < 0.0 {
        -gamma
    } else {
        gamma
    }
}

/// The intensities as integers: q = round((v − min) · scale) < 2³¹, so that sums over any
/// set of up to 2³² voxels are exact in an i64 and independent of their order.
struct FixedPoint {
    q: Vec<u32>,
    min: f64,
    scale: f64,
    total: i64,
}

impl FixedPoint {
    fn new(data: &[f32]) -> FixedPoint {
        // Least and greatest values (in any order: ±0 compare equal and give the same q).
        let (lo, hi) = data
            .par_chunks(PART_VOXELS)
            .map(|c| {
                c.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)))
            })
            .reduce(|| (f32::INFINITY, f32::NEG_INFINITY), |(a, b), (c, d)| (a.min(c), b.max(d)));
        let range = (hi - lo) as f64;
        let scale = if range > 0.0 { ((1u64 << 31) - 1) as f64 / range } else { 0.0 };
        let min = lo as f64;
        let q: Vec<u32> =
            data.par_iter().map(|&v| ((v as f64 - min) * scale).round() as u32).collect();
        let total = q.par_chunks(1 << 16).map(|c| c.iter().map(|&v| v as i64).sum::<i64>()).sum();
        FixedPoint { q, min, scale, total }
    }

    /// The mean intensity of `count` voxels whose integer sum is `sum`.
    fn mean(&self, sum: i64, count: u64) -> f64 {
        if count == 0 || self.scale == 0.0 {
            return self.min;
        }
        self.min + sum as f64 / count as f64 / self.scale
    }
}

/// Image voxels inside (φ ≤ 0), with `sums` the integer sum of their intensities, and
/// how many of them lie on each face of the image (x = 0, x = max, y = 0, y = max, z = 0,
/// z = max; an axis of one voxel has no faces).
fn inside(sim: &Simulation, dims: [usize; 3], sums: Option<&FixedPoint>) -> (u64, i64, [u64; 6]) {
    let lookup = Lookup { dims };
    let [nx, ny, nz] = dims;
    // Integer counts and sums: the same in any split over the threads and any order.
    let visit = |acc: &mut (u64, i64, [u64; 6]), c: Coord, len: u32| {
        // A 2D image's level set is extruded over z = 0..3: slice 0 is the image.
        if c.y < 0
            || c.y as usize >= ny
            || c.z < 0
            || c.z as usize >= nz.max(1)
            || (nz == 1 && c.z != 0)
        {
            return;
        }
        let x0 = c.x.max(0) as i64;
        let x1 = (c.x as i64 + len as i64).min(nx as i64);
        if x1 <= x0 {
            return;
        }
        acc.0 += (x1 - x0) as u64;
        add_run_faces(&mut acc.2, x0 as usize, x1 as usize, c.y as usize, c.z as usize, dims);
        if let Some(fp) = sums {
            let first = lookup.index(Coord::new(x0 as i32, c.y, c.z)).expect("inside the image");
            acc.1 += fp.q[first..first + (x1 - x0) as usize].iter().map(|&v| v as i64).sum::<i64>();
        }
    };
    let combine = |a: (u64, i64, [u64; 6]), b: (u64, i64, [u64; 6])| {
        (a.0 + b.0, a.1 + b.1, std::array::from_fn(|i| a.2[i] + b.2[i]))
    };
    // Whether the tile whose first voxel has coordinate `c` along an axis of `n` voxels
    // lies in the image off its faces. A 2-D image's tiles give their first z-slice only,
    // the image's.
    let off_faces = |c: i32, n: usize| c >= 1 && c as i64 + (TILE_DIM as i64) < n as i64;
    let off_z = |c: i32| if nz == 1 { c == 0 } else { off_faces(c, nz) };
    let tile = |acc: &mut (u64, i64, [u64; 6]), c: Coord, mask: u64| {
        if off_faces(c.x, nx) && off_faces(c.y, ny) && off_z(c.z) {
            // No face and no clipping: the count, and the sum voxel by voxel.
            acc.0 += mask.count_ones() as u64;
            if let Some(fp) = sums {
                let first = lookup.index(c).expect("inside the image");
                let mut bits = mask;
                while bits != 0 {
                    let l = bits.trailing_zeros() as usize;
                    let d = TILE_DIM as usize;
                    let (x, y, z) = (l % d, l / d % d, l / SLICE_LEN);
                    acc.1 += fp.q[first + x + nx * (y + ny * z)] as i64;
                    bits &= bits - 1;
                }
            }
            return;
        }
        // Otherwise the runs along each row of four voxels, clipped to the image.
        for row in 0..TILE_DIM * TILE_DIM {
            let mut nibble = (mask >> (TILE_DIM * row)) & 0xF;
            while nibble != 0 {
                let x0 = nibble.trailing_zeros();
                let len = (nibble >> x0).trailing_ones();
                let at = Coord::new(c.x + x0 as i32, c.y + row % TILE_DIM, c.z + row / TILE_DIM);
                visit(acc, at, len);
                nibble &= !(((1u64 << len) - 1) << x0);
            }
        }
    };
    let span = 0..i32::try_from(nx).expect("an image row in the i32 range");
    sim.fold_inside(span, || (0, 0, [0; 6]), tile, visit, combine)
}

/// Adds to `faces` (x = 0, x = max, y = 0, y = max, z = 0, z = max) the voxels of the run
/// x0..x1 of row (y, z) that lie on each face of an image of `dims` (an axis of one voxel
/// has no faces).
fn add_run_faces(faces: &mut [u64; 6], x0: usize, x1: usize, y: usize, z: usize, dims: [usize; 3]) {
    let [nx, ny, nz] = dims;
    let run = (x1 - x0) as u64;
    if nx > 1 {
        faces[0] += (x0 == 0) as u64;
        faces[1] += (x1 == nx) as u64;
    }
    if ny > 1 {
        faces[2] += run * (y == 0) as u64;
        faces[3] += run * (y == ny - 1) as u64;
    }
    if nz > 1 {
        faces[4] += run * (z == 0) as u64;
        faces[5] += run * (z == nz - 1) as u64;
    }
}

/// The voxels of a mask of the image (x fastest) and how many lie on each face of the
/// image, as [`inside`] counts a simulation's.
fn mask_faces(mask: &[u8], dims: [usize; 3]) -> (u64, [u64; 6]) {
    let nx = dims[0];
    let rows = (PART_VOXELS / nx).max(1);
    // Integer counts per part of rows, added in any order: the same in any split.
    mask.par_chunks(nx * rows)
        .enumerate()
        .map(|(part, lines)| {
            let (mut count, mut faces) = (0u64, [0u64; 6]);
            for (r, line) in lines.chunks(nx).enumerate() {
                let row = part * rows + r;
                let (y, z) = (row % dims[1], row / dims[1]);
                let mut x = 0;
                while x < nx {
                    if line[x] == 0 {
                        x += 1;
                        continue;
                    }
                    let x0 = x;
                    while x < nx && line[x] != 0 {
                        x += 1;
                    }
                    count += (x - x0) as u64;
                    add_run_faces(&mut faces, x0, x, y, z, dims);
                }
            }
            (count, faces)
        })
        .reduce(|| (0, [0; 6]), |a, b| (a.0 + b.0, std::array::from_fn(|i| a.1[i] + b.1[i])))
}

/// The fast start's region ([`Params::fast_start`], [`super::start`]), when it applies:
/// seeds, an outward flow of one method (no weighted terms), and a rule for the voxels
/// where that method's speed is clearly outward:
/// * threshold: Ĩ at least half a threshold scale inside the window (speed ≥ ½);
/// * GAC and Chan–Vese, with the seeds' first edge: Ĩ at least a threshold scale on the
///   seeds' side of the edge's level (GAC's balloon at its full strength; Chan–Vese's
///   force outward while the outside's mean is the tissue beyond the edge).
fn start_region(
    image: &Image,
    init: &Init,
    params: &Params,
    inputs: &MethodInputs<'_>,
    seeds: &[u8],
    resolved: &Resolved,
    norm: &Normalization,
) -> Option<Vec<u8>> {
    if !params.fast_start || params.terms.iter().any(|t| t.1 != 0.0) {
        return None;
    }
    let propagation = params.propagation.unwrap_or(1.0);
    if propagation < 0.0 && matches!(init, Init::Mask(_)) {
        return shrinking_start(image, params, inputs, seeds, resolved);
    }
    if !matches!(init, Init::Seeds { .. }) || propagation <= 0.0 {
        return None;
    }
    let smoothed = &inputs.smoothed.data;
    let confident: Vec<u8> = match (params.method, inputs.gate) {
        (Method::Threshold { lower, upper }, _) => {
            let (lo, hi) = (norm.threshold(lower) as f64, norm.threshold(upper) as f64);
            let half = 0.5 * threshold_scale(lo as f32, hi as f32, inputs.noise_smoothed);
            smoothed
                .par_iter()
                .map(|&v| ((v as f64 - lo).min(hi - v as f64) >= half) as u8)
                .collect()
        }
        (Method::Gac | Method::ChanVese { .. }, Some(Gate { level, side, .. })) => {
            let w = threshold_scale(level, f32::INFINITY, inputs.noise_smoothed) as f32;
            smoothed.par_iter().map(|&v| (side * (v - level) >= w) as u8).collect()
        }
        _ => return None,
    };
    // The speed per unit of β in the confident voxels: ½ for the threshold speed, 1 for
    // GAC's balloon (g scales both terms) and Chan–Vese.
    let s = if matches!(params.method, Method::Threshold { .. }) { 0.5 } else { 1.0 };
    Some(super::start::fill(&confident, seeds, image.dims, opening_radius(inputs, resolved, s)))
}

/// The fill's least opening radius r (voxels): channels of radius r + ½ voxels, whose
/// curvature (below 1/r) holds back at most half of the confident voxels' speed,
/// ε/r ≤ ½ |β| s, with ε the flow's curvature weight in voxels and `s` the speed there
/// per unit of β; at least [`super::start::OPENING`].
fn opening_radius(inputs: &MethodInputs<'_>, resolved: &Resolved, s: f32) -> usize {
    let eps = resolved.curvature / inputs.h_min as f32;
    ((2.0 * eps / (resolved.propagation.abs() * s)).ceil() as usize).max(super::start::OPENING)
}

/// The fast start of GAC shrinking a larger initial region (`region`, 1 inside) onto the
/// object (a negative propagation, as scikit-image's balloon −1): the fill of
/// [`super::start::fill`] mirrored. The front from outside is sure to sweep the voxels of
/// the region where the balloon pulls it inward at least at half strength (g ≥ ½, away
/// from edges), reached from outside through openings of 2r + 1 such voxels, less one
/// voxel at their edge; the start is the region without them. By the comparison principle
/// (see `super::start`) a start between the region and the steady state the region
/// shrinks to evolves to that same steady state. `None` for other methods, or when the
/// fill would sweep the whole region (no edge holds the front: the run from the region
/// itself shows that).
fn shrinking_start(
    image: &Image,
    params: &Params,
    inputs: &MethodInputs<'_>,
    region: &[u8],
    resolved: &Resolved,
) -> Option<Vec<u8>> {
    let g = match (params.method, inputs.g) {
        (Method::Gac, Some(g)) => &g.data,
        _ => return None,
    };
    // Outside the region counts as swept already: the fill starts there. With a first edge
    // inward, only voxels on the start's side of its level are swept (where the balloon
    // pushes inward in full), not an object's that the start cuts.
    let smoothed = &inputs.smoothed.data;
    let background = |i: f32| match inputs.gate {
        Some(Gate { level, side, .. }) => side * (i - level) >= 0.0,
        None => true,
    };
    let confident: Vec<u8> = g
        .par_iter()
        .zip(region)
        .zip(smoothed.par_iter())
        .map(|((&v, &r), &i)| (r == 0 || (v >= 0.5 && background(i))) as u8)
        .collect();
    let outside: Vec<u8> = region.par_iter().map(|&r| (r == 0) as u8).collect();
    // GAC's balloon: s = 1 where g is 1, as for growing.
    let swept =
        super::start::fill(&confident, &outside, image.dims, opening_radius(inputs, resolved, 1.0));
    let start: Vec<u8> = region.par_iter().zip(&swept).map(|(&r, &s)| r & (s ^ 1)).collect();
    (par_count(&start) > 0).then_some(start)
}

/// The mask φ ≤ 0 at the image's voxels.
///
/// Read row by row from the tile grid ([`map_tile_rows`]) rather than through a dense
/// copy of φ (an image-sized buffer of `f32` more to fault in and fill; see
/// [`crate::storage::convert::tile_row_values`] for the times).
fn mask_of(sim: &Simulation, dims: [usize; 3]) -> Result<Vec<u8>, SegmentError> {
    let len = dims.iter().product::<usize>();
    crate::memory::check(crate::memory::bytes_of(len as u128, 1), "the mask")?;
    let mut mask = vec![0u8; len];
    map_tile_rows(tiles_of(sim), Coord::new(0, 0, 0), dims, &mut mask, |v| (v <= 0.0) as u8);
    Ok(mask)
}

/// The initial level set as a dense field over the image (a 2D image's over z = 0..3),
/// clamped to ±γ.
fn initial_field(
    image: &Image,
    init: &Init,
    lattice: &Lattice,
    gamma: f32,
) -> Result<DenseField, SegmentError> {
    let [nx, ny, nz] = image.dims;
    let layers = if image.is_2d() { 4 } else { nz };
    let s = image.spacing;
    let slice = nx * ny;
    // Filled in parallel: the first touch of the buffer's pages is most of the cost.
    let mut phi = vec![0.0f32; slice * layers];
    phi.par_chunks_mut(PART_VOXELS).for_each(|c| c.fill(gamma));
    match init {
        Init::Seeds { seeds, world } => {
            let h_min = lattice.min_spacing() as f64;
            // Centres as lattice positions (world units along the image axes), radii in
            // world units.
            let balls: Vec<([f64; 3], f64)> = seeds
                .iter()
                .map(|sd| {
                    if *world {
                        (lattice_position(image, sd.center), sd.radius)
                    } else {
                        (
                            [sd.center[0] * s[0], sd.center[1] * s[1], sd.center[2] * s[2]],
                            sd.radius * h_min,
                        )
                    }
                })
                .collect();
            // Beyond r + γ of every centre along some axis a voxel's distance exceeds γ from
            // every ball, and it keeps the γ it was filled with: only the voxels of the
            // balls' boxes are computed (the same values).
            let boxes: Vec<[std::ops::Range<usize>; 3]> = balls
                .iter()
                .map(|(c, r)| {
                    std::array::from_fn(|a| {
                        if a == 2 && image.is_2d() {
                            return 0..1;
                        }
                        let (lo, hi) = ((c[a] - r) - gamma as f64, (c[a] + r) + gamma as f64);
                        let n = image.dims[a];
                        let first = (lo / s[a]).floor().max(0.0).min(n as f64) as usize;
                        let end = ((hi / s[a]).ceil() + 1.0).max(0.0).min(n as f64) as usize;
                        first..end.max(first)
                    })
                })
                .collect();
            phi.par_chunks_mut(slice).enumerate().take(nz).for_each(|(z, out)| {
                let in_z: Vec<&[std::ops::Range<usize>; 3]> =
                    boxes.iter().filter(|b| b[2].contains(&z)).collect();
                for y in 0..ny {
                    let (x_lo, x_hi) = in_z
                        .iter()
                        .filter(|b| b[1].contains(&y))
                        .fold((nx, 0), |(lo, hi), b| (lo.min(b[0].start), hi.max(b[0].end)));
                    for x in x_lo..x_hi {
                        let p = [x as f64 * s[0], y as f64 * s[1], z as f64 * s[2]];
                        let d = balls
                            .iter()
                            .map(|(c, r)| {
                                let dz = if image.is_2d() { 0.0 } else { p[2] - c[2] };
                                ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + dz * dz).sqrt() - r
                            })
                            .fold(f64::INFINITY, f64::min);
                        out[x + nx * y] = (d as f32).clamp(-gamma, gamma);
                    }
                }
            });
        }
        Init::Mask(mask) => distance_from_labels(image, mask, gamma, &mut phi),
        Init::LevelSet(values) => contour_distance(image, values, gamma, &mut phi)?,
    }
    if image.is_2d() {
        let (first, rest) = phi.split_at_mut(slice);
        rest.par_chunks_mut(slice).for_each(|c| c.copy_from_slice(first));
    }
    if !phi.par_iter().any(|&v| v <= 0.0) {
        return Err(SegmentError::Init(
            "the initial region is empty (nothing inside the image)".into(),
        ));
    }
    Ok(DenseField::from_vec(Coord::new(0, 0, 0), [nx, ny, layers], phi)?)
}

/// The initial level set `field` (the image's voxels; a 2-D image's four copies of its one
/// slice) closed at the image's faces, when its region holds a voxel on one of them; `None`
/// when it holds none (the field as it is).
///
/// Beyond the image nothing is inside at the start: on a box grown beyond the faces by the
/// band's reach (along x and y, and along z for a 3-D image), each voxel takes `max(φ, d)`, where `φ` is
/// the value of the image's nearest voxel and `d` the signed distance to the image's box,
/// whose faces lie half a voxel beyond its first and last voxels (negative inside): the
/// level set of the intersection of the region with the box. Without it the tiles kept the
/// region's sign beyond a face (an interior run reaches as far as the band lets it), and a
/// start on the face evolved unlike the same start a voxel inside: `camera()` by
/// Chan–Vese from a rectangle at column 0 ended at Dice 0.68, from column 1 at 0.95.
/// scikit-image's morphological snakes likewise treat what lies beyond the array as outside
/// (their erosions' border value).
fn closed_at_faces(
    field: &DenseField,
    image: &Image,
    gamma: f32,
) -> Result<Option<DenseField>, GridError> {
    let dims = field.dims();
    let s = image.spacing;
    let active: [bool; 3] = std::array::from_fn(|a| dims[a] > 1 && !(a == 2 && image.is_2d()));
    let data = field.data();
    let at = |x: usize, y: usize, z: usize| data[x + dims[0] * (y + dims[1] * z)];
    let inside_on = |a: usize, i: usize| -> bool {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        (0..dims[c]).into_par_iter().any(|k| {
            (0..dims[b]).any(|j| {
                let mut p = [0usize; 3];
                (p[a], p[b], p[c]) = (i, j, k);
                at(p[0], p[1], p[2]) <= 0.0
            })
        })
    };
    let meets = (0..3).any(|a| active[a] && (inside_on(a, 0) || inside_on(a, dims[a] - 1)));
    if !meets {
        return Ok(None);
    }
    // The band's reach along each axis, in voxels, and a voxel more.
    let reach = |a: usize| (gamma as f64 / s[a]).ceil() as usize + 1;
    let pad: [usize; 3] = std::array::from_fn(|a| if active[a] { reach(a) } else { 0 });
    let out_dims: [usize; 3] = std::array::from_fn(|a| dims[a] + 2 * pad[a]);
    let slice = out_dims[0] * out_dims[1];
    let count = out_dims.iter().map(|&n| n as u128).product::<u128>();
    crate::memory::check(crate::memory::bytes_of(count, 4), "the initial level set")?;
    let mut out = vec![0.0f32; slice * out_dims[2]];
    out.par_chunks_mut(slice).enumerate().for_each(|(k, plane)| {
        for (j, row) in plane.chunks_exact_mut(out_dims[0]).enumerate() {
            for (i, v) in row.iter_mut().enumerate() {
                let q = [i, j, k];
                let mut near = [0usize; 3];
                let (mut outside, mut inner) = (0.0f64, f64::NEG_INFINITY);
                for a in 0..3 {
                    // The position along the axis, in voxels of the image (negative before
                    // it), and how far beyond the box's nearer face it lies.
                    let p = q[a] as i64 - pad[a] as i64;
                    near[a] = p.clamp(0, dims[a] as i64 - 1) as usize;
                    if active[a] {
                        let n = dims[a] as f64;
                        let beyond = (-0.5 - p as f64).max(p as f64 - (n - 0.5)) * s[a];
                        outside += beyond.max(0.0).powi(2);
                        inner = inner.max(beyond);
                    }
                }
                let d = if outside > 0.0 { outside.sqrt() } else { inner };
                *v = at(near[0], near[1], near[2]).max(d as f32).clamp(-gamma, gamma);
            }
        }
    });
    let origin = Coord::new(-(pad[0] as i32), -(pad[1] as i32), -(pad[2] as i32));
    Ok(Some(DenseField::from_vec(origin, out_dims, out)?))
}

/// The band of a user's initial level set `values`, from its zero level alone
/// ([`fmm::dense_band`] on the image's lattice): taken as it was, a steep field left a few
/// band voxels, and the run stopped at once.
fn contour_distance(
    image: &Image,
    values: &[f32],
    gamma: f32,
    phi: &mut [f32],
) -> Result<(), SegmentError> {
    let grid = fmm::DenseGrid { dims: image.dims, spacing: image.spacing, periodic: [false; 3] };
    let band = fmm::dense_band(values, &grid, gamma, Progress::none()).map_err(|e| match e {
        fmm::FmmError::NoInterface => SegmentError::Init(
            "the initial level set has no zero crossing: no voxel has a neighbour of the other \
             sign"
                .into(),
        ),
        e => SegmentError::Init(format!("the initial level set: {e}")),
    })?;
    phi[..values.len()].copy_from_slice(&band);
    Ok(())
}

/// The lattice position (world units along the image axes) of a world point: the inverse
/// of [`Image::to_world`].
fn lattice_position(image: &Image, p: [f64; 3]) -> [f64; 3] {
    let m = &image.to_world;
    let inv = invert3(std::array::from_fn(|r| [m[r][0], m[r][1], m[r][2]]));
    let b = [p[0] - m[0][3], p[1] - m[1][3], p[2] - m[2][3]];
    std::array::from_fn(|r| inv[r][0] * b[0] + inv[r][1] * b[1] + inv[r][2] * b[2])
}

/// A signed distance (world units, clamped to ±γ) to the faces between the voxels of
/// `mask` (nonzero inside) and the others: each voxel takes its distance to the nearest
/// midpoint of such a face within γ (an upper bound of the true distance, by at most half
/// a voxel's diagonal), negative inside. O(boundary faces × (γ/h)³).
fn distance_from_labels(image: &Image, mask: &[u8], gamma: f32, phi: &mut [f32]) {
    let [nx, ny, nz] = image.dims;
    let s = image.spacing;
    let reach: [i64; 3] = std::array::from_fn(|a| {
        if image.dims[a] == 1 {
            0
        } else {
            (gamma as f64 / s[a]).ceil() as i64 + 1
        }
    });
    let row = |y: usize, z: usize| &mask[nx * (y + ny * z)..nx * (y + ny * z + 1)];
    // Face midpoints between differently labelled neighbours, in lattice positions, by
    // the slice of their lower voxel (in any order: each voxel takes their minimum). Row by
    // row against the next voxel along x and the rows next along y and z, a row that agrees
    // with its neighbour throughout skipped in one comparison.
    let mids: Vec<Vec<[f64; 3]>> = (0..nz)
        .into_par_iter()
        .map(|z| {
            let mut out = Vec::new();
            for y in 0..ny {
                let here = row(y, z);
                let first = here[0] != 0;
                if !here.iter().all(|&v| (v != 0) == first) {
                    for x in 0..nx - 1 {
                        if (here[x] != 0) != (here[x + 1] != 0) {
                            out.push([
                                (2 * x + 1) as f64 * 0.5 * s[0],
                                y as f64 * s[1],
                                z as f64 * s[2],
                            ]);
                        }
                    }
                }
                let mut across = |next: &[u8], axis: usize| {
                    if next != here {
                        for x in 0..nx {
                            if (here[x] != 0) != (next[x] != 0) {
                                let mut p = [x as f64 * s[0], y as f64 * s[1], z as f64 * s[2]];
                                let k = [x, y, z][axis];
                                p[axis] = (2 * k + 1) as f64 * 0.5 * s[axis];
                                out.push(p);
                            }
                        }
                    }
                };
                if y + 1 < ny {
                    across(row(y + 1, z), 1);
                }
                if z + 1 < nz {
                    across(row(y, z + 1), 2);
                }
            }
            out
        })
        .collect();
    // Each slice takes the nearest midpoint within reach (a midpoint of slice z rounds to
    // slice z or z + 1).
    // Squared distances: the root of the least is the least root, to the bit.
    let g2 = gamma as f64 * gamma as f64;
    let slices = phi[..nx * ny * nz].par_chunks_mut(nx * ny).enumerate();
    // One buffer of squared distances per task, reused slice after slice.
    slices.for_each_init(Vec::new, |dist: &mut Vec<f64>, (z, out)| {
        let labels = &mask[nx * ny * z..nx * ny * (z + 1)];
        let first = (z as i64 - reach[2] - 1).max(0) as usize;
        let last = (z as i64 + reach[2]).min(nz as i64 - 1).max(0) as usize;
        if mids[first..=last].iter().all(Vec::is_empty) {
            // No face within reach: ±γ by the label.
            for (p, &l) in out.iter_mut().zip(labels) {
                *p = if l != 0 { -gamma } else { gamma };
            }
            return;
        }
        dist.clear();
        dist.resize(nx * ny, f64::INFINITY);
        for m in mids[first..=last].iter().flatten() {
            let c: [i64; 3] = std::array::from_fn(|a| (m[a] / s[a]).round() as i64);
            if (c[2] - z as i64).abs() > reach[2] {
                continue;
            }
            let lo: [i64; 2] = std::array::from_fn(|a| (c[a] - reach[a]).max(0));
            let hi: [i64; 2] =
                std::array::from_fn(|a| (c[a] + reach[a]).min(image.dims[a] as i64 - 1));
            let dz = z as f64 * s[2] - m[2];
            if dz * dz >= g2 {
                continue;
            }
            for y in lo[1]..=hi[1] {
                let dy = y as f64 * s[1] - m[1];
                let rest = g2 - (dy * dy + dz * dz);
                if rest <= 0.0 {
                    continue;
                }
                // Only the voxels of the row within γ: floor and ceil take in at least
                // every x with dx² < rest (the others would clamp to γ anyway).
                let r = rest.sqrt();
                let x_lo = lo[0].max(((m[0] - r) / s[0]).floor() as i64);
                let x_hi = hi[0].min(((m[0] + r) / s[0]).ceil() as i64);
                for x in x_lo..=x_hi {
                    let dx = x as f64 * s[0] - m[0];
                    let k = x as usize + nx * y as usize;
                    dist[k] = dist[k].min(dx * dx + dy * dy + dz * dz);
                }
            }
        }
        for ((p, &d2), &l) in out.iter_mut().zip(dist.iter()).zip(labels) {
            // At least γ² the root is at least γ (γ² is exact in f64): no root to take.
            let d = if d2 < g2 { (d2.sqrt() as f32).min(gamma) } else { gamma };
            *p = if l != 0 { -d } else { d };
        }
    });
}

/// GAC's default curvature weight ε, in units of the smallest spacing, and advection
/// weight α, against a propagation weight β = 1. ITK's guide uses (ε, α) = (1, 1) and
/// ITK-SNAP (0.2, 2); on the validation phantoms (docs/segmentation.md) both let the front
/// out where touching objects meet (a crease has no edge) and at SNR 2, while (1.5, 3)
/// holds every object whose boundary is an edge everywhere: the edge's attraction must
/// outweigh the balloon on the edge's outer flank, and curvature closes the noise's holes
/// in it.
const GAC_CURVATURE: f32 = 1.5;
const GAC_ADVECTION: f32 = 3.0;

/// The quantile of the rays' edge peaks taken as the edge's gradient K₂: a robust
/// minimum, as the ITK guide's "minimum value along the contour".
const EDGE_QUANTILE: f64 = 0.1;
/// Chan–Vese's inside and outside means closer than this many noise levels are reported
/// ([`Report::weak_contrast`]): the classes overlap by about Φ(−2), 2 % of voxels either way.
const CONTRAST_NOISE: f64 = 4.0;
/// Chan–Vese competes with the tissue beyond the seeds' first edge when that is nearer
/// the inside than this fraction of the outside mean's distance.
const NEIGHBOUR: f64 = 0.75;

/// The threshold method's default smoothing puts the noise left in Ĩ this many times
/// below the distance from the seeds' intensity to the nearer threshold.
const THRESHOLD_MARGIN: f64 = 5.0;

#[cfg(test)]
mod tests {
    use super::*;

    /// A level set on the lattice of an image of `dims` (planar when `dims[2]` is 1, as
    /// a segmentation extrudes it over one tile layer): distance-like values of a few
    /// balls, with pseudo-random bumps, the band of the segmentation's half-width.
    fn level_set(dims: [usize; 3], shift: f64) -> (Image, TileGrid) {
        let planar = dims[2] == 1;
        let image = Image {
            dims,
            spacing: [1.0; 3],
            data: (0..dims.iter().product::<usize>())
                .map(|i| ((i * 7919) % 1000) as f32 * 0.37 - 40.0)
                .collect(),
            to_world: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
        };
        let layers = if planar { TILE_DIM as usize } else { dims[2] };
        let balls = [([0.3, 0.4, 0.5], 0.3), ([0.75, 0.7, 0.4], 0.2), ([0.0, 1.0, 0.9], 0.35)];
        let scale = dims.iter().fold(0, |m, &n| m.max(n)) as f64;
        let mut phi = Vec::with_capacity(dims[0] * dims[1] * layers);
        for z in 0..layers {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let p = [x, y, if planar { 0 } else { z }];
                    let d = balls
                        .iter()
                        .map(|(c, r)| {
                            let q: f64 =
                                (0..3).map(|a| (p[a] as f64 - c[a] * dims[a] as f64).powi(2)).sum();
                            q.sqrt() - r * scale + shift
                        })
                        .fold(f64::INFINITY, f64::min);
                    let bump = 0.3 * ((x * 13 + y * 7 + z * 3) % 5) as f64 / 5.0;
                    phi.push((d + bump) as f32);
                }
            }
        }
        let field = DenseField::from_vec(Coord::new(0, 0, 0), [dims[0], dims[1], layers], phi)
            .expect("a field");
        let spec = GridSpec::new(1.0, [0.0; 3], HALF_WIDTH).expect("a spec");
        (image, tiles_from_dense(&field, spec).expect("tiles"))
    }

    /// `closed_at_faces` leaves a field whose region meets no face as it is, and closes one
    /// that meets a face: beyond it the distance to the image's box, at it at most minus
    /// that distance, elsewhere the field; in 3-D along every axis, in 2-D not along z; with
    /// anisotropic spacing, the reach of the band along each axis in its own voxels.
    #[test]
    fn a_start_on_a_face_is_closed_there() {
        let gamma = 3.0f32;
        for (dims, spacing) in [([12, 10, 1], [1.0, 1.0, 1.0]), ([16, 8, 7], [0.5, 1.0, 2.0])] {
            let image = Image {
                dims,
                spacing,
                data: vec![0.0; dims.iter().product()],
                to_world: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
            };
            let layers = if image.is_2d() { TILE_DIM as usize } else { dims[2] };
            // A ball about voxel (cx, 4, 3) of radius 2.5 world units.
            let field = |cx: f64| {
                let mut phi = Vec::new();
                for z in 0..layers {
                    for y in 0..dims[1] {
                        for x in 0..dims[0] {
                            let z = if image.is_2d() { 3.0 } else { z as f64 };
                            let q = [x as f64 - cx, y as f64 - 4.0, z - 3.0];
                            let d = (0..3).map(|a| (q[a] * spacing[a]).powi(2)).sum::<f64>();
                            phi.push((d.sqrt() - 2.5).clamp(-3.0, 3.0) as f32);
                        }
                    }
                }
                DenseField::from_vec(Coord::new(0, 0, 0), [dims[0], dims[1], layers], phi).unwrap()
            };
            let away = field(8.0);
            assert!(closed_at_faces(&away, &image, gamma).unwrap().is_none(), "{dims:?}");
            let open = field(0.0);
            let closed = closed_at_faces(&open, &image, gamma).unwrap().expect("closed");
            let pad: [i32; 3] = std::array::from_fn(|a| {
                if a == 2 && image.is_2d() {
                    0
                } else {
                    (gamma as f64 / spacing[a]).ceil() as i32 + 1
                }
            });
            assert_eq!(closed.origin(), Coord::new(-pad[0], -pad[1], -pad[2]));
            let n: [i32; 3] = std::array::from_fn(|a| closed.dims()[a] as i32);
            for z in 0..n[2] {
                for y in 0..n[1] {
                    for x in 0..n[0] {
                        let c = Coord::new(x - pad[0], y - pad[1], z - pad[2]);
                        let v = closed.get(c).unwrap();
                        let p = [c.x, c.y, c.z];
                        let beyond: [f64; 3] = std::array::from_fn(|a| {
                            let m = if a == 2 { layers } else { dims[a] } as f64;
                            if a == 2 && image.is_2d() {
                                return f64::NEG_INFINITY;
                            }
                            (-0.5 - p[a] as f64).max(p[a] as f64 - (m - 0.5)) * spacing[a]
                        });
                        let out: f64 = beyond.iter().map(|b| b.max(0.0).powi(2)).sum();
                        let near = Coord::new(
                            c.x.clamp(0, dims[0] as i32 - 1),
                            c.y.clamp(0, dims[1] as i32 - 1),
                            c.z.clamp(0, layers as i32 - 1),
                        );
                        let phi = open.get(near).unwrap();
                        if out > 0.0 {
                            let want = (out.sqrt() as f32).max(phi).min(gamma);
                            assert_eq!(v, want, "{c} {dims:?}");
                            assert!(v > 0.0, "{c}");
                        } else {
                            let inner = beyond.iter().fold(f64::NEG_INFINITY, |m, &b| m.max(b));
                            assert_eq!(v, phi.max(inner as f32).max(-gamma), "{c} {dims:?}");
                        }
                    }
                }
            }
            // The ball's voxel on the x = 0 face, inside, is half a voxel from the box's face.
            let face = closed.get(Coord::new(0, 4, 3)).unwrap();
            assert_eq!(face, -0.5 * spacing[0] as f32, "{dims:?}");
        }
    }

    /// The count, integer sum and face counts of `inside` (whole tiles as masks, clipped
    /// tiles and tiles on a face as runs, the interior between tiles as runs) equal those
    /// of the mask read back from the tiles, on images whose sizes are not multiples of
    /// the tile's and whose objects cross every face, in 3-D and on a planar lattice, on
    /// one thread and on three.
    #[test]
    fn inside_counts_what_the_mask_holds() {
        for dims in [[37, 29, 18], [45, 33, 1], [8, 8, 8], [1, 30, 21], [26, 1, 19], [31, 2, 1]] {
            let (image, tiles) = level_set(dims, 0.0);
            let lattice = lattice_of(&image);
            let settings = Settings {
                lattice: Some(lattice),
                renormalization: Renormalization::Coupled { weight: 1.0 },
                ..Settings::default()
            };
            let sim = Simulation::from_tile_grid(
                GridKind::Tiles(Lanes::Simd),
                tiles,
                Flow::rest(),
                settings,
            )
            .expect("a simulation");
            let mask = mask_of(&sim, dims).expect("the mask");
            let (count, faces) = mask_faces(&mask, dims);
            let fp = FixedPoint::new(&image.data);
            let sum: i64 = mask.iter().zip(&fp.q).map(|(&m, &q)| m as i64 * q as i64).sum();
            assert!(count > 0 && (count as usize) < mask.len(), "{dims:?}: {count}");
            assert!(faces.iter().filter(|&&f| f > 0).count() >= 2, "{dims:?}: {faces:?}");
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let with_sums = pool.install(|| inside(&sim, dims, Some(&fp)));
                assert_eq!(with_sums, (count, sum, faces), "{dims:?}, {threads} threads");
                let without = pool.install(|| inside(&sim, dims, None));
                assert_eq!(without, (count, 0, faces), "{dims:?}, {threads} threads");
            }
        }
    }

    /// `change_since` against a voxel-by-voxel reference: the near voxels of the grid
    /// before (|φ| < h, the first slice on a planar lattice), each against its value after
    /// (±γ on its side when it left the band), and the band after; with tiles added and
    /// removed between the two, in parts on one thread and three; and the near set it
    /// returns is the next step's.
    #[test]
    fn change_since_equals_a_voxel_by_voxel_reference() {
        for dims in [[37, 29, 18], [45, 33, 1]] {
            let planar = dims[2] == 1;
            let read = if planar { SLICE_LEN } else { TILE_LEN };
            let (_, before) = level_set(dims, 0.0);
            let (_, after) = level_set(dims, -2.6);
            let gamma = after.gamma();
            let (h, dt) = (1.0, 0.25);
            let voxels = |g: &TileGrid| -> Vec<(Coord, usize, f32)> {
                let mut out = Vec::new();
                for (p, &c) in g.tile_coords().iter().enumerate() {
                    for (l, &v) in g.values()[p].0[..read].iter().enumerate() {
                        out.push((c, l, v));
                    }
                }
                out
            };
            let after_at: std::collections::HashMap<(Coord, usize), f32> =
                voxels(&after).into_iter().map(|(c, l, v)| ((c, l), v)).collect();
            let near: Vec<(Coord, usize, f32)> = voxels(&before)
                .into_iter()
                .filter(|&(_, _, v)| v.abs() < gamma && (v.abs() as f64) < h)
                .collect();
            let sq: f64 = near
                .iter()
                .map(|&(c, l, o)| {
                    let v = after_at.get(&(c, l)).copied().unwrap_or(gamma);
                    let new = if v.abs() < gamma { v } else { sim_value_left(o, gamma) };
                    let d = (new - o) as f64 / h;
                    ((d * d) as f32) as f64
                })
                .sum::<f64>()
                * (h / dt)
                * (h / dt);
            let band = voxels(&after).iter().filter(|v| v.2.abs() < gamma).count();
            let removed = before.tile_coords().iter().filter(|c| !after_at.contains_key(&(**c, 0)));
            assert!(removed.count() > 0, "{dims:?}: tiles leave the band");
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let first = pool.install(|| change_since(&before, &Near::default(), dt, h, planar));
                assert_eq!(first.0, 0.0);
                assert_eq!(first.2.len(), near.len(), "{dims:?}");
                let (got, got_band, next) =
                    pool.install(|| change_since(&after, &first.2, dt, h, planar));
                assert!((got - sq).abs() <= 1e-9 * sq, "{dims:?}: {got} against {sq}");
                assert_eq!(got_band, band, "{dims:?}");
                let near_after = voxels(&after)
                    .iter()
                    .filter(|v| v.2.abs() < gamma && (v.2.abs() as f64) < h)
                    .count();
                assert_eq!(next.len(), near_after, "{dims:?}");
            }
        }
    }
}
