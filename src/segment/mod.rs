//! Image segmentation by level sets on the tile engine: threshold-based propagation,
//! geodesic active contours and Chan–Vese, the flows of ITK's level-set filters, with one
//! sign convention and defaults taken from the image.
//!
//! # Convention
//! **φ < 0 inside**, in world units (the image's spacing), everywhere: the initial level
//! sets, the result, the speeds (F > 0 moves the front outward, into the background). A
//! voxel belongs to the segmentation when φ ≤ 0 at its centre (a centre exactly on the
//! interface counts as inside). ITK's filters differ among themselves (its threshold
//! filter's speed is positive inside the intensity window and its examples seed with a
//! positive-inside level set); here one rule holds for every method.
//!
//! # The flows
//! The level set lives on the image's voxels ([`crate::evolve::Lattice`]: every
//! derivative divided by that axis's spacing, so anisotropic scans need no resampling; a
//! 2D image evolves as a curve) and moves by
//!
//! ```text
//! φ_t = −β P(x)|∇φ| + ε Z(x) κ|∇φ| − α A(x)·∇φ + sgn(φ)(1 − |∇φ|)
//! ```
//!
//! (ITK's `SegmentationLevelSetFunction` with propagation, curvature and advection
//! weights β, ε, α; the last term keeps φ a distance, [`crate::evolve::Renormalization::Coupled`]).
//! With Ĩ = G_σ ∗ I the smoothed image:
//!
//! * [`Method::Threshold`] (ITK's `ThresholdSegmentationLevelSetImageFilter`): P =
//!   min(Ĩ − L, U − Ĩ)/w clamped to [−1, 1]: 1 well inside [L, U], 0 at its ends, negative
//!   outside, with w the window's half-width but at most twice the noise left in Ĩ, so that
//!   a window open at one end (L = −∞ or U = +∞) works as a closed one; Z = 1, no advection.
//! * [`Method::Gac`] (geodesic active contours, Caselles, Kimmel & Sapiro, IJCV 22 (1997);
//!   ITK's `GeodesicActiveContourLevelSetImageFilter`): P = Z = g, A = −∇g with the edge
//!   potential g = 1/(1 + exp((|∇Ĩ| − β)/α)) (the sigmoid form ITK's guide uses, with
//!   α, β from the edges that rays from the seeds meet) or g = 1/(1 + |∇Ĩ|/K)
//!   ([`features::edge_potential`]), or the user's own g ([`Params::feature`]).
//! * [`Method::ChanVese`] (Chan & Vese, IEEE TIP 10 (2001)): P the region force
//!   (λ₂(Ĩ − c₂)² − λ₁(Ĩ − c₁)²)/(c₁ − c₂)² − ν with c₁, c₂ the means of Ĩ inside and
//!   outside, recomputed before every step from exact integer sums over the whole image;
//!   Z = 1 (ε is Chan–Vese's μ); grows from seeds.
//!
//! Any weighted sum of the three is a flow too ([`Params::terms`]: e.g. GAC with half a
//! Chan–Vese region force). Beyond the image the propagation term is −β: the front stays
//! within the image.
//!
//! # Defaults
//! Every default comes from robust statistics of the image, none from an intensity scale:
//! the flows see the image normalised by order statistics ((I − median) / (p99 − p1)), so
//! the mask of a·I + b (a > 0) is the mask of I; the noise σ is the median absolute second
//! difference over 0.6745 √6; the smoothing is the smallest (for the threshold method and
//! Chan–Vese possibly none) that puts the noise far below the contrast that matters (the
//! distance to the nearer threshold; the contrast of the first edge that rays cast from the
//! seeds cross); GAC's sigmoid follows the ITK Software Guide's rule with K₁ measured
//! inside the seeds and K₂ on those rays; GAC's weights are (β, ε, α) = (1, 1.5 h, 3).
//! That first edge also shapes the flows ([`Params::first_edge`]): GAC's balloon turns
//! back beyond its intensity level, and Chan–Vese competes with the tissue beyond it.
//! GAC shrinking a start onto the objects (a negative propagation from a mask or a level
//! set) measures all of these where its front starts: rays from voxels spread over the
//! start's boundary, K₁ over the boundary, and its balloon turns outward at the first edge
//! inward, so that it does not eat an object the start cuts.
//! [`Report::params`] holds every value chosen.
//!
//! # The fast start
//! From seeds, the level set does not start in the seeds' balls but in the part of the
//! image the front from them is sure to cover ([`Params::fast_start`], on by default):
//! a flood fill from the seeds through the voxels where the method's speed is clearly
//! outward (for the threshold method Ĩ half a threshold scale inside the window; for GAC
//! and Chan–Vese Ĩ a threshold scale on the seeds' side of their first edge's level),
//! through openings wide enough that curvature cannot close them (a morphological opening
//! by reconstruction of radius r ≥ 1 voxel with ε/r at most half the speed there),
//! stopping a voxel short of where those voxels end. The flows obey the comparison
//! principle (Evans & Spruck, J. Differential Geom. 33 (1991); Chen, Giga & Goto, ibid.):
//! a start between the seeds and the steady state they reach evolves to that same steady
//! state, so the answer is the same and only the steps across the object's bulk are
//! saved. [`Report::params`] gives the start's voxels (`start_voxels`); the leak guard
//! compares with the seeds' region, so a fill that runs out of the object is reported
//! after one step.
//!
//! GAC shrinking a larger initial region (a mask and a negative propagation) starts the
//! same way mirrored: without the region's voxels that the front from outside is sure to
//! sweep, those reached from outside through openings of voxels away from the edges
//! (g ≥ ½, the balloon at least at half strength), less one voxel at their edge.
//!
//! # Stopping
//! After every step: the RMS over the voxels next to the interface (|φ| < the smallest
//! spacing) of the change of φ *per unit time* (the adaptive Δt cannot hide motion), and
//! the relative change of the segmented volume over the last [`Params::window`] steps.
//! The run stops when the RMS falls below [`Params::rms`] or the volume changed by less
//! than [`Params::volume_change`] over the window, or after [`Params::max_iterations`]
//! steps; [`Report::stop`] says which. The leak guard ([`Params::leak_guard`], on by
//! default) stops a region that covers part of a face of the image (0.5 %, at least 16
//! voxels) that its initial region did not touch, or grows past half the image (a start
//! shrinking onto the objects, β < 0 from a mask: that grows past itself), as
//! [`Stop::Leaked`]: a wrong answer is never returned as a normal stop.

pub mod features;
pub mod metrics;
pub mod phantom;
mod run;
mod speed;
mod start;
mod stats;

pub use run::{segment, Segmentation};

use crate::evolve::EvolveError;
use crate::grid::GridError;
use serde::Serialize;
use std::sync::Arc;

/// A seed: a ball that starts the segmentation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Seed {
    /// Centre: voxel indices along the image's x, y, z axes (fractional allowed), or world
    /// coordinates ([`Init::Seeds`]' `world`).
    pub center: [f64; 3],
    /// Radius in voxels of the smallest spacing (world units with `world`).
    pub radius: f64,
}

/// Where the segmentation starts.
#[derive(Clone, Debug)]
pub enum Init {
    /// Balls around seed points (their union).
    Seeds {
        seeds: Vec<Seed>,
        /// Centres and radii in the image's world coordinates ([`crate::io::image::Image::to_world`]).
        world: bool,
    },
    /// A mask of the image's size (x fastest), nonzero inside.
    Mask(Vec<u8>),
    /// A level set of the image's size (x fastest, φ < 0 inside). Only its zero level is
    /// read: the run starts from the signed distance to it (fast marching on the image's
    /// lattice), whatever the field's units or steepness.
    LevelSet(Vec<f32>),
}

/// A segmentation method and its own parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "kebab-case", tag = "name")]
pub enum Method {
    /// Propagation where the smoothed intensity lies in `[lower, upper]`.
    Threshold { lower: f32, upper: f32 },
    /// Geodesic active contours.
    Gac,
    /// Chan–Vese, with its data weights λ₁ (inside), λ₂ (outside) and area term ν.
    ChanVese { lambda1: f32, lambda2: f32, nu: f32 },
}

impl Method {
    /// Chan–Vese with λ₁ = λ₂ = 1, ν = 0.
    pub fn chan_vese() -> Method {
        Method::ChanVese { lambda1: 1.0, lambda2: 1.0, nu: 0.0 }
    }

    /// `"threshold"`, `"gac"` or `"chan-vese"`.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Threshold { .. } => "threshold",
            Method::Gac => "gac",
            Method::ChanVese { .. } => "chan-vese",
        }
    }
}

/// Parameters of a segmentation; `None` takes the default chosen from the image (printed
/// in [`Report::params`]).
#[derive(Clone, Debug)]
pub struct Params {
    pub method: Method,
    /// σ of the Gaussian smoothing, world units, the same along every axis (0: none).
    /// Default: chosen per axis in voxels from the image's noise (module docs, "Defaults").
    pub sigma: Option<f64>,
    /// β, ITK's `PropagationScaling`. Default 1; negative to shrink onto the object from
    /// a larger initial region (not with Chan–Vese, whose β scales its data weights).
    pub propagation: Option<f32>,
    /// ε, ITK's `CurvatureScaling` (Chan–Vese's μ), world units. Default: 1.5 times the
    /// smallest spacing for GAC, a fifth of it for the others.
    pub curvature: Option<f32>,
    /// α, ITK's `AdvectionScaling` (GAC only). Default 3.
    pub advection: Option<f32>,
    /// K of the rational edge potential g = 1/(1 + |∇Ĩ|/K) (GAC only); when given, it
    /// replaces the sigmoid.
    pub edge_scale: Option<f64>,
    /// (α, β) of the sigmoid edge potential g = 1/(1 + exp((|∇Ĩ| − β)/α)) (GAC only; ITK's
    /// `SigmoidImageFilter` with a negative α). Default: from the gradient statistics.
    pub sigmoid: Option<(f64, f64)>,
    /// Stop when the RMS change of φ per unit time near the interface falls below this
    /// (world units per unit time).
    pub rms: f64,
    /// Stop when the segmented volume changed by less than this fraction over the last
    /// `window` steps.
    pub volume_change: f64,
    /// Steps of the volume criterion's window.
    pub window: u64,
    /// At most this many steps.
    pub max_iterations: u64,
    /// Threads: the pool the features and the evolution run in (the global pool when
    /// `None`).
    pub pool: Option<Arc<rayon::ThreadPool>>,
    /// More methods added to `method` with these weights: the flow is the weighted sum of
    /// the methods' terms (their speeds β Pᵢ, curvature weights εᵢ Zᵢ and advection, each
    /// times its weight; `method` has weight 1), e.g. GAC plus half a Chan–Vese region
    /// force. Each method at most once; the parameters above apply to each.
    pub terms: Vec<(Method, f32)>,
    /// A feature image of the image's size, the user's own, as ITK's filters take one: for
    /// GAC alone, the edge potential g itself (1 in flat regions, near 0 on edges; no
    /// sigmoid, no smoothing); for the threshold and Chan–Vese methods, the intensities
    /// they compare in place of the image (smoothed only when `sigma` is given).
    pub feature: Option<Arc<crate::io::image::Image>>,
    /// Stop a run that leaks ([`Stop::Leaked`]): one whose region covers 0.5 % (at least
    /// 16 voxels) of a face of the image that the initial region did not touch, or grows
    /// past half the image; a start that shrinks onto the objects (β < 0 from a mask or a
    /// level set) leaks when it grows past itself. On by default; turn it off for objects
    /// that fill the image or cross its border.
    pub leak_guard: bool,
    /// The first edge that rays from the seeds cross shapes the flows (on by default, for
    /// a positive propagation): GAC's balloon turns inward beyond its intensity level
    /// ([`Resolved::edge_level`]), and Chan–Vese's outside mean is no farther from the
    /// inside's than the intensity beyond it (the neighbouring tissue, not the whole
    /// outside). `false` gives ITK's plain balloon and the textbook Chan–Vese.
    pub first_edge: bool,
    /// Start the level set from the part of the image the front from the seeds is sure to
    /// cover (a flood fill through the voxels where the method's speed is clearly outward,
    /// by openings wider than curvature can close; [module docs](crate::segment#the-fast-start))
    /// instead of the seeds' balls: the same answer in fewer steps, by the flows'
    /// comparison principle. Seeds, a positive propagation and one method (no weighted
    /// terms); or GAC shrinking an initial mask (a negative propagation), without the part
    /// of the mask the front from outside is sure to sweep. On by default.
    pub fast_start: bool,
}

impl Params {
    /// The defaults for `method`.
    pub fn new(method: Method) -> Params {
        Params {
            method,
            sigma: None,
            propagation: None,
            curvature: None,
            advection: None,
            edge_scale: None,
            sigmoid: None,
            rms: 0.01,
            volume_change: 2e-4,
            window: 10,
            max_iterations: 2000,
            pool: None,
            terms: Vec::new(),
            feature: None,
            leak_guard: true,
            first_edge: true,
            fast_start: true,
        }
    }
}

/// The parameters a run used, defaults filled in.
#[derive(Clone, Debug, Serialize)]
pub struct Resolved {
    pub method: Method,
    /// The methods added with their weights ([`Params::terms`]).
    pub terms: Vec<(Method, f32)>,
    /// σ of the smoothing per axis, world units.
    pub sigma: [f64; 3],
    pub propagation: f32,
    pub curvature: f32,
    pub advection: f32,
    /// K of the rational edge potential (GAC).
    pub edge_scale: Option<f64>,
    /// (α, β) of the sigmoid edge potential (GAC), in the image's intensity units per
    /// voxel step.
    pub sigmoid: Option<(f64, f64)>,
    /// The contrast of the first edge the rays from the seeds crossed (GAC; median over
    /// the rays), intensity units.
    pub edge_contrast: Option<f64>,
    /// The intensity level of the first edge that rays from the seeds cross (the median
    /// intensity at its gradient peaks), where GAC's balloon turns, intensity units; `None`
    /// when not used ([`Params::first_edge`]) or when the rays found no one edge.
    pub edge_level: Option<f64>,
    /// The image voxels of the fast start's region ([`Params::fast_start`]); `None` when
    /// the level set started from the initial region as given.
    pub start_voxels: Option<u64>,
    /// The intensity over which the threshold speed goes from 0 to 1 (threshold method).
    pub threshold_scale: Option<f64>,
    /// The image's noise σ (intensity units), and what is left of it after smoothing.
    pub noise: f64,
    pub noise_smoothed: f64,
    /// The intensity normalisation (center, scale): the flows see (I − center) / scale.
    pub normalization: [f64; 2],
    pub leak_guard: bool,
    /// A feature image was given.
    pub feature: bool,
    pub spacing: [f64; 3],
    pub planar: bool,
    /// The time integration (`"euler"` or `"rk3"` in the report): forward Euler when the
    /// flow has a curvature term, TVD-RK3 when it has none; HJ-WENO5 in space either way.
    pub integrator: crate::evolve::Integrator,
}

/// Why a segmentation stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stop {
    /// The RMS change per unit time fell below [`Params::rms`].
    Rms,
    /// The volume changed by less than [`Params::volume_change`] over the window.
    Volume,
    /// [`Params::max_iterations`] steps were taken.
    MaxIterations,
    /// Nothing is left inside: the segmentation vanished (the mask is empty; any run that
    /// was not cancelled and ends so reports this).
    Vanished,
    /// The monitor asked to stop.
    Cancelled,
    /// The leak guard stopped a region that reached a face of the image the initial
    /// region did not touch, or grew past half the image (a shrinking start: past itself;
    /// [`Report::leak`] says which):
    /// the mask is not a segmentation of the seeded object.
    Leaked,
}

/// The figures of a run.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub params: Resolved,
    pub stop: Stop,
    pub iterations: u64,
    /// Pseudo-time reached.
    pub time: f64,
    /// RMS change of φ per unit time near the interface in the last step.
    pub rms: f64,
    /// Voxels segmented and their world volume.
    pub voxels: u64,
    pub volume: f64,
    /// Region means c₁ (inside), c₂ (outside) of the smoothed image at the end (Chan–Vese).
    pub means: Option<[f64; 2]>,
    /// Why the leak guard stopped the run ([`Stop::Leaked`]).
    pub leak: Option<String>,
    /// Why Chan–Vese's region is not told apart from its surroundings, if it is not: its
    /// mean lies within four noise levels of the outside's. The mask is then no
    /// segmentation of anything, though the run stopped normally.
    pub weak_contrast: Option<String>,
    /// Band voxels at the end (of a 2-D image: its pixels).
    pub band_voxels: usize,
    /// Σ over steps of the stored voxels times the stages (the voxels the kernels updated;
    /// of a 2-D image, one z-slice of each tile).
    pub voxel_updates: f64,
    /// Seconds for the feature images, the evolution, and in all.
    pub seconds_features: f64,
    pub seconds_evolution: f64,
    /// The part of the evolution spent in the level-set steps (the rest: region sums,
    /// RMS and volume tests).
    pub seconds_steps: f64,
    pub seconds: f64,
}

/// What one step reports to a monitor.
#[derive(Clone, Copy, Debug)]
pub struct StepInfo {
    pub iteration: u64,
    pub max_iterations: u64,
    pub rms: f64,
    pub band_voxels: usize,
    pub voxels: u64,
}

/// Why a segmentation could not run.
#[derive(Debug, thiserror::Error)]
pub enum SegmentError {
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    #[error("initialisation: {0}")]
    Init(String),
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error(transparent)]
    Evolve(#[from] EvolveError),
}

impl crate::error::Error for SegmentError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            SegmentError::InvalidParameter(_) | SegmentError::Init(_) => InvalidInput,
            SegmentError::Grid(e) => e.kind(),
            SegmentError::Evolve(e) => e.kind(),
        }
    }
}
