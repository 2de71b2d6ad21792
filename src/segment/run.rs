//! The segmentation driver: feature images, the initial level set, the flow on the tile
//! engine, the region means and the stopping tests (see the [module docs](super)).

use super::features;
use super::speed::{CurvatureSum, Lookup, RegionForce, SumField, VoxelField, VoxelVector};
use super::{Init, Method, Params, Report, Resolved, SegmentError, StepInfo, Stop};
use crate::build::tiles_from_dense;
use crate::coord::Coord;
use crate::dense::DenseField;
use crate::evolve::{
    Flow, GridKind, Lanes, Lattice, Renormalization, ScalarFn, Settings, Simulation, Speed,
    Velocity,
};
use crate::grid::{GridError, GridSpec};
use crate::image::Image;
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
    /// set, [`crate::mesh::isosurface`]) in `image`'s world coordinates
    /// ([`Image::to_world`]): vertices are placed on the lattice and mapped through the
    /// placement, normals through its inverse transpose. A 2D image has no surface.
    pub fn mesh(&self, image: &Image) -> Result<crate::mesh::TriangleMesh, SegmentError> {
        if image.is_2d() {
            return Err(SegmentError::InvalidParameter(
                "a 2D image's segmentation is a region, not a surface".into(),
            ));
        }
        let tiles = self.simulation.tiles().ok_or_else(|| {
            SegmentError::InvalidParameter("the segmentation holds no tile grid".into())
        })?;
        let mut mesh = crate::mesh::isosurface(tiles, &crate::mesh::MeshOptions::default())
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
}

/// The inverse of a 3×3 matrix (the placement is invertible: NIfTI's sform/qform are).
fn invert3(a: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
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
    let finite_pos = |name: &str, v: Option<f64>| match v {
        Some(v) if !(v.is_finite() && v >= 0.0) => {
            Err(SegmentError::InvalidParameter(format!("{name} must be finite and >= 0, got {v}")))
        }
        _ => Ok(()),
    };
    finite_pos("sigma", params.sigma)?;
    finite_pos("propagation", params.propagation.map(f64::from))?;
    finite_pos("curvature", params.curvature.map(f64::from))?;
    finite_pos("advection", params.advection.map(f64::from))?;
    finite_pos("RMS tolerance", Some(params.rms))?;
    finite_pos("volume-change tolerance", Some(params.volume_change))?;
    if let Some(k) = params.edge_scale {
        if !(k.is_finite() && k > 0.0) {
            return invalid(format!("edge scale K must be finite and > 0, got {k}"));
        }
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
            if !(lower.is_finite() && upper.is_finite() && lower < upper) =>
        {
            invalid(format!("thresholds must be finite with lower < upper, got {lower}, {upper}"))
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
    // Given: the same σ along every axis; default: one voxel along each axis, half a
    // voxel for the threshold method (its front stops where Ĩ crosses a threshold, and
    // smoothing moves that level inward on curved objects by about σ²/r: a σ of one voxel
    // cost the 5-voxel blobs of a 64³ phantom 2–3 % of Dice).
    let voxels = if matches!(params.method, Method::Threshold { .. }) { 0.5 } else { 1.0 };
    let sigmas = match params.sigma {
        Some(s) => [s; 3],
        None => image.spacing.map(|h| voxels * h),
    };
    let sigma = sigmas.iter().fold(0.0f64, |m, &v| m.max(v));
    let smoothed = if sigma > 0.0 {
        let s = if image.is_2d() { [sigmas[0], sigmas[1], 0.0] } else { sigmas };
        features::gaussian(image, s)?
    } else {
        image.clone()
    };
    let lookup = Lookup { dims: image.dims };
    let propagation = params.propagation.unwrap_or(1.0);
    let mut resolved = Resolved {
        method: params.method,
        terms: params.terms.clone(),
        sigma: sigmas,
        propagation,
        curvature: 0.0,
        advection: 0.0,
        edge_scale: None,
        sigmoid: None,
        spacing: image.spacing,
        planar: image.is_2d(),
    };
    let inputs = MethodInputs { params, smoothed: &smoothed, initial: &field, lookup, h_min };
    let (mut flow, mut region) = method_flow(params.method, 1.0, &inputs, &mut resolved)?;
    if !params.terms.is_empty() {
        let mut flows = vec![flow];
        for &(method, weight) in &params.terms {
            let mut scratch = resolved.clone();
            let (f, r) = method_flow(method, weight, &inputs, &mut scratch)?;
            flows.push(f);
            region = region.or(r);
        }
        flow = sum_of_flows(flows);
    }
    let seconds_features = start.elapsed().as_secs_f64();

    // The initial level set on the lattice.
    let tiles = tiles_from_dense(&field, spec)?;
    drop(field);
    if tiles.band_voxels() == 0 {
        return Err(SegmentError::Init(
            "the initial level set has no interface in the image".into(),
        ));
    }
    let settings = Settings {
        renormalization: Renormalization::Coupled { weight: 1.0 },
        lattice: Some(lattice),
        pool: params.pool.clone(),
        ..Settings::default()
    };
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
    let (mut voxels, mut inside_sum) = inside(&sim, image.dims, sums.as_ref());
    volumes.push(voxels);
    let gamma = sim.spec().gamma();
    let mut seconds_steps = 0.0;
    let mut near: Vec<(Coord, f32)> = Vec::new();
    sim.for_each_band_voxel(|c, phi| {
        if (phi.abs() as f64) < h_min {
            near.push((c, phi));
        }
    });
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
            let c2 = fp.mean(fp.total - inside_sum, n - voxels);
            force.set_means(c1, c2);
            means = Some([c1, c2]);
        }
        updates += (sim.stored_voxels() * 3) as f64;
        let t_step = Instant::now();
        let report = match sim.step() {
            Ok(r) => r,
            Err(crate::evolve::EvolveError::Collapsed { .. }) => break Stop::Vanished,
            Err(e) => return Err(e.into()),
        };
        seconds_steps += t_step.elapsed().as_secs_f64();
        // RMS of (φⁿ⁺¹ − φⁿ)/Δt over the voxels with |φⁿ| < h: a merge of the two bands
        // (both in Coord order); a voxel that left the band reads ±γ.
        let dt = report.dt as f64;
        let mut next = Vec::with_capacity(near.len());
        let (mut sq, mut k) = (0.0f64, 0usize);
        let mut diff = |old: f32, new: f32| {
            let d = (new - old) as f64 / dt;
            sq += d * d;
        };
        let mut band_voxels = 0usize;
        sim.for_each_band_voxel(|c, phi| {
            band_voxels += 1;
            while k < near.len() && near[k].0 < c {
                diff(near[k].1, sim_value_left(near[k].1, gamma));
                k += 1;
            }
            if k < near.len() && near[k].0 == c {
                diff(near[k].1, phi);
                k += 1;
            }
            if (phi.abs() as f64) < h_min {
                next.push((c, phi));
            }
        });
        for &(_, old) in &near[k..] {
            diff(old, sim_value_left(old, gamma));
        }
        rms = if near.is_empty() { 0.0 } else { (sq / near.len() as f64).sqrt() };
        near = next;
        (voxels, inside_sum) = inside(&sim, image.dims, sums.as_ref());
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
    let voxels = mask.iter().map(|&m| m as u64).sum::<u64>();
    let report = Report {
        params: resolved,
        stop,
        iterations: sim.steps(),
        time: sim.time(),
        rms,
        voxels,
        volume: voxels as f64 * voxel_volume,
        means,
        band_voxels: sim.band_voxels(),
        voxel_updates: updates,
        seconds_features,
        seconds_evolution,
        seconds_steps,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok(Segmentation { mask, simulation: sim, report })
}

/// What every method's flow is built from.
struct MethodInputs<'a> {
    params: &'a Params,
    smoothed: &'a Image,
    initial: &'a DenseField,
    lookup: Lookup,
    h_min: f64,
}

/// The flow of one method with its weight (β, ε and α scaled by it), and its region
/// force (Chan–Vese). `resolved` gets the method's parameters.
fn method_flow(
    method: Method,
    weight: f32,
    inputs: &MethodInputs<'_>,
    resolved: &mut Resolved,
) -> Result<(Flow, Option<Arc<RegionForce>>), SegmentError> {
    let MethodInputs { params, smoothed, initial: field, lookup, h_min } = *inputs;
    let propagation = weight * params.propagation.unwrap_or(1.0);
    let mut region: Option<Arc<RegionForce>> = None;
    let flow = match method {
        Method::Threshold { lower, upper } => {
            let (mid, half) = (0.5 * (lower + upper), 0.5 * (upper - lower));
            let speed: Vec<f32> = smoothed
                .data
                .par_iter()
                .map(|&v| {
                    let p = if v < mid { v - lower } else { upper - v };
                    propagation * (p / half).clamp(-1.0, 1.0)
                })
                .collect();
            resolved.curvature = params.curvature.unwrap_or(0.2 * h_min as f32);
            let field = VoxelField { lookup, data: Arc::new(speed), outside: -propagation };
            Flow::normal_speed(Speed::Field(Arc::new(field)))
                .with_curvature(weight * resolved.curvature)
        }
        Method::Gac => {
            // Edges per voxel step (a unit spacing): a step between two slices 2.5 mm apart
            // is as much an edge as one between two pixels; in world units it would read
            // 2.5× weaker and the front would leak through the poles of a thick-sliced
            // volume.
            let grad =
                features::gradient_magnitude(&Image { spacing: [1.0; 3], ..smoothed.clone() })?;
            let g = match (params.edge_scale, params.sigmoid) {
                (Some(k), _) => {
                    resolved.edge_scale = Some(k);
                    features::edge_potential(&grad, k)?
                }
                (None, given) => {
                    let (alpha, beta) = match given {
                        Some(g) => g,
                        None => default_sigmoid(&grad, field)?,
                    };
                    resolved.sigmoid = Some((alpha, beta));
                    // Decreasing in |∇Ĩ|: 1 in flat regions, 0 on edges.
                    features::sigmoid(&grad, -alpha, beta, 0.0, 1.0)?
                }
            };
            resolved.curvature = params.curvature.unwrap_or(h_min as f32);
            resolved.advection = params.advection.unwrap_or(1.0);
            let alpha = weight * resolved.advection;
            let gg = features::gradient(&g)?.map(|c| c.data);
            let speed: Vec<f32> = g.data.par_iter().map(|&v| propagation * v).collect();
            let g = Arc::new(g.data);
            let velocity =
                gg.map(|c| Arc::new(c.into_iter().map(|v| -alpha * v).collect::<Vec<f32>>()));
            let z = VoxelField { lookup, data: g, outside: 1.0 };
            let f = VoxelField { lookup, data: Arc::new(speed), outside: -propagation };
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
            let beta = params.propagation.unwrap_or(1.0);
            let force = Arc::new(RegionForce::new(
                lookup,
                Arc::new(smoothed.data.clone()),
                [lambda1 * beta, lambda2 * beta, nu],
                weight,
            ));
            region = Some(force.clone());
            Flow::normal_speed(Speed::Field(force)).with_curvature(weight * resolved.curvature)
        }
    };
    Ok((flow, region))
}

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

/// The sigmoid edge potential's (α, β) from the gradient statistics, by the rule of ITK's
/// guide (Software Guide, "Geodesic Active Contours Segmentation": K₁ a gradient typical
/// of the object's inside, K₂ one typical of its edges, α = (K₂ − K₁)/6, β = (K₁ + K₂)/2),
/// with K₁ the 90th percentile of |∇Ĩ| inside the initial region (the seeds lie in the
/// object) and K₂ the 99th percentile over the image, at least 3 K₁ (edges are a small
/// part of a volume; when they are too few to reach the 99th percentile, the noise's tail
/// is taken as three times the inside's).
fn default_sigmoid(grad: &Image, initial: &DenseField) -> Result<(f64, f64), GridError> {
    let n = grad.data.len();
    let inside: Vec<f32> = grad
        .data
        .iter()
        .zip(&initial.data()[..n])
        .filter(|(_, &phi)| phi <= 0.0)
        .map(|(&g, _)| g)
        .collect();
    let k1 = if inside.is_empty() { 0.0 } else { features::percentile(&inside, 0.9)? as f64 };
    let k2 = (features::percentile(&grad.data, 0.99)? as f64).max(3.0 * k1);
    let k2 = if k2 > 0.0 { k2 } else { f64::MIN_POSITIVE };
    Ok(((k2 - k1).max(k2 * 1e-3) / 12.0, k1 + (k2 - k1) / 3.0))
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
        let (lo, hi) =
            data.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
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

/// Image voxels inside (φ ≤ 0) and, with `sums`, the integer sum of their intensities.
fn inside(sim: &Simulation, dims: [usize; 3], sums: Option<&FixedPoint>) -> (u64, i64) {
    let lookup = Lookup { dims };
    let [nx, ny, nz] = dims;
    let (mut count, mut sum) = (0u64, 0i64);
    sim.for_each_inside_run(|c, len| {
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
        count += (x1 - x0) as u64;
        if let Some(fp) = sums {
            let first = lookup.index(Coord::new(x0 as i32, c.y, c.z)).expect("inside the image");
            sum += fp.q[first..first + (x1 - x0) as usize].iter().map(|&v| v as i64).sum::<i64>();
        }
    });
    (count, sum)
}

/// The mask φ ≤ 0 at the image's voxels.
fn mask_of(sim: &Simulation, dims: [usize; 3]) -> Result<Vec<u8>, SegmentError> {
    let phi = sim.to_dense(Coord::new(0, 0, 0), dims)?;
    Ok(phi.data().par_iter().map(|&v| (v <= 0.0) as u8).collect())
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
    let mut phi = vec![gamma; slice * layers];
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
            phi.par_chunks_mut(slice).enumerate().take(nz).for_each(|(z, out)| {
                for y in 0..ny {
                    for x in 0..nx {
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
        Init::Mask(mask) => distance_from_labels(image, |i| mask[i] != 0, gamma, &mut phi),
        Init::LevelSet(values) => {
            phi[..values.len()]
                .par_iter_mut()
                .zip(values)
                .for_each(|(p, &v)| *p = v.clamp(-gamma, gamma));
        }
    }
    if image.is_2d() {
        let (first, rest) = phi.split_at_mut(slice);
        rest.par_chunks_mut(slice).for_each(|c| c.copy_from_slice(first));
    }
    if !phi.iter().any(|&v| v <= 0.0) {
        return Err(SegmentError::Init(
            "the initial region is empty (nothing inside the image)".into(),
        ));
    }
    Ok(DenseField::from_vec(Coord::new(0, 0, 0), [nx, ny, layers], phi)?)
}

/// The lattice position (world units along the image axes) of a world point: the inverse
/// of [`Image::to_world`].
fn lattice_position(image: &Image, p: [f64; 3]) -> [f64; 3] {
    let m = &image.to_world;
    let inv = invert3(std::array::from_fn(|r| [m[r][0], m[r][1], m[r][2]]));
    let b = [p[0] - m[0][3], p[1] - m[1][3], p[2] - m[2][3]];
    std::array::from_fn(|r| inv[r][0] * b[0] + inv[r][1] * b[1] + inv[r][2] * b[2])
}

/// A signed distance (world units, clamped to ±γ) to the faces between voxels labelled
/// inside and outside: each voxel takes its distance to the nearest midpoint of such a
/// face within γ (an upper bound of the true distance, by at most half a voxel's
/// diagonal), negative inside. O(boundary faces × (γ/h)³).
fn distance_from_labels(
    image: &Image,
    inside: impl Fn(usize) -> bool + Sync,
    gamma: f32,
    phi: &mut [f32],
) {
    let [nx, ny, nz] = image.dims;
    let s = image.spacing;
    let idx = |x: usize, y: usize, z: usize| x + nx * (y + ny * z);
    let reach: [i64; 3] = std::array::from_fn(|a| {
        if image.dims[a] == 1 {
            0
        } else {
            (gamma as f64 / s[a]).ceil() as i64 + 1
        }
    });
    // Face midpoints between differently labelled neighbours, in lattice positions.
    let mut mids: Vec<[f64; 3]> = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let a = inside(idx(x, y, z));
                let mut check = |x2: usize, y2: usize, z2: usize| {
                    if inside(idx(x2, y2, z2)) != a {
                        mids.push([
                            (x + x2) as f64 * 0.5 * s[0],
                            (y + y2) as f64 * 0.5 * s[1],
                            (z + z2) as f64 * 0.5 * s[2],
                        ]);
                    }
                };
                if x + 1 < nx {
                    check(x + 1, y, z);
                }
                if y + 1 < ny {
                    check(x, y + 1, z);
                }
                if z + 1 < nz {
                    check(x, y, z + 1);
                }
            }
        }
    }
    let mut dist = vec![gamma; nx * ny * nz];
    for m in &mids {
        let c: [i64; 3] = std::array::from_fn(|a| (m[a] / s[a]).round() as i64);
        let lo: [i64; 3] = std::array::from_fn(|a| (c[a] - reach[a]).max(0));
        let hi: [i64; 3] = std::array::from_fn(|a| (c[a] + reach[a]).min(image.dims[a] as i64 - 1));
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let p = [x as f64 * s[0], y as f64 * s[1], z as f64 * s[2]];
                    let d = ((p[0] - m[0]).powi(2) + (p[1] - m[1]).powi(2) + (p[2] - m[2]).powi(2))
                        .sqrt() as f32;
                    let k = idx(x as usize, y as usize, z as usize);
                    dist[k] = dist[k].min(d);
                }
            }
        }
    }
    for (i, d) in dist.iter().enumerate() {
        phi[i] = if inside(i) { -d } else { *d };
    }
}
