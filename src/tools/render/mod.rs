//! Ray-traced images of the zero level set of a sparse grid (Houston et al. 2006, Sec. 6.3,
//! "Direct Ray Tracing"): no mesh is extracted; rays query the grid by random access, read
//! ±γ outside the band as the paper prescribes, and step by the level-set value.
//!
//! * [`render`] traces one primary ray per sub-pixel through a
//!   [`Camera`] that frames the level set (or a given [`FrameBox`]); see the `trace`
//!   module docs in the source for the marching (empty-space skipping over an occupancy
//!   pyramid of the band, sphere tracing with steps of ½|φ|, root refinement).
//! * The default camera frames the box of the voxels inside the level set (grown by one
//!   voxel), i.e. the surface's box rather than the band's, which is γ wider.
//! * Shading: one directional light (Lambert, a Blinn–Phong highlight, ambient), a ground
//!   plane under the object with shadow rays, a sky gradient behind. Normals are central
//!   differences of the trilinear interpolant.
//! * Rows are traced in parallel with rayon; every pixel is a pure function of the grid
//!   values and the options, so the image is bitwise identical for any thread count, and
//!   identical for every storage of the same band (they read the same values).
//!
//! ```
//! use sparse_levelset::{storage::convert, grid::GridSpec, tools::render, storage::shapes::Shape};
//!
//! let shape = Shape::Sphere { center: [0.0; 3], radius: 10.0 };
//! let tiles = convert::tiles_from_shape(&shape, GridSpec::default()).unwrap();
//! let opts = render::RenderOptions { width: 64, height: 48, ..Default::default() };
//! let image = render::render(&tiles, &opts).unwrap();
//! // The ray through the image centre hits the sphere, about one camera distance minus r away.
//! let (x, y) = (32, 24);
//! let eye = image.camera().eye;
//! let d = (eye[0] * eye[0] + eye[1] * eye[1] + eye[2] * eye[2]).sqrt();
//! assert!((image.depth(x, y).unwrap() - (d - 10.0)).abs() < 0.5);
//! # let path = std::env::temp_dir().join(format!("render-doc-{}.png", std::process::id()));
//! image.write_png(&path).unwrap();
//! # std::fs::remove_file(&path).unwrap();
//! ```

mod trace;

use crate::progress::{Cancelled, Progress};
use crate::storage::interpolate::{Trilinear as Sampler, Units};
use crate::storage::levelset::{Accessor, LevelSet};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use trace::{normalize, summarise, trace, Occupancy};

/// Errors of rendering and of writing an image.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The grid holds no band voxel, or its band has no zero crossing (all band values
    /// of one sign): there is no surface to render.
    #[error("the level set is empty: {0}")]
    Empty(&'static str),
    /// An option outside its documented range.
    #[error("invalid render option: {0}")]
    InvalidOption(String),
    /// Cancelled through [`RenderOptions::progress`].
    #[error("rendering was cancelled")]
    Cancelled(#[from] Cancelled),
    /// Writing the PNG failed.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl crate::error::Error for RenderError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            RenderError::Empty(_) => InvalidData,
            RenderError::InvalidOption(_) => InvalidInput,
            RenderError::Cancelled(_) => Cancelled,
            RenderError::Io { source, .. } => crate::error::io_kind(source),
        }
    }
}

/// An axis-aligned box in world units for the camera to frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameBox {
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

/// What to render and how. Angles are in degrees; z is up.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image width in pixels (1..=16384).
    pub width: u32,
    /// Image height in pixels (1..=16384); at most 2^25 pixels in all.
    pub height: u32,
    /// Direction of the camera seen from the target, counter-clockwise from +x in the
    /// xy plane.
    pub azimuth_deg: f64,
    /// Height of the camera above the xy plane of the target, in (−90, 90).
    pub elevation_deg: f64,
    /// Vertical field of view, in (0, 170).
    pub fov_deg: f64,
    /// Rays per pixel along each axis (1..=8; `samples²` rays per pixel, on a regular
    /// grid inside the pixel, averaged in linear colour).
    pub samples: u32,
    /// Direction of the light relative to the camera's azimuth.
    pub light_azimuth_deg: f64,
    /// Elevation of the light above the horizon, in (0, 90].
    pub light_elevation_deg: f64,
    /// A ground plane under the object (at the lowest point of the surface, or at the
    /// bottom of [`RenderOptions::frame`]).
    pub ground: bool,
    /// Shadow rays towards the light from the object and the ground.
    pub shadows: bool,
    /// The world box to frame; `None`: the box of the voxels inside the level set (within
    /// one voxel). Give a fixed box to render the frames of an evolution from one
    /// viewpoint.
    pub frame: Option<FrameBox>,
    /// Progress (image rows done) and cancellation.
    pub progress: Progress,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 640,
            height: 480,
            azimuth_deg: -60.0,
            elevation_deg: 30.0,
            fov_deg: 35.0,
            samples: 2,
            light_azimuth_deg: 50.0,
            light_elevation_deg: 55.0,
            ground: true,
            shadows: true,
            frame: None,
            progress: Progress::none(),
        }
    }
}

/// Largest image edge and pixel count.
const MAX_EDGE: u32 = 16384;
const MAX_PIXELS: u64 = 1 << 25;

impl RenderOptions {
    /// Checks every option against its documented range.
    pub fn validate(&self) -> Result<(), RenderError> {
        let bad = |m: String| Err(RenderError::InvalidOption(m));
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 || v > MAX_EDGE {
                return bad(format!("{name} must be in 1..={MAX_EDGE}, got {v}"));
            }
        }
        if self.width as u64 * self.height as u64 > MAX_PIXELS {
            return bad(format!(
                "{}×{} pixels exceed the limit of {MAX_PIXELS}",
                self.width, self.height
            ));
        }
        if !(1..=8).contains(&self.samples) {
            return bad(format!("samples must be in 1..=8, got {}", self.samples));
        }
        let ranges = [
            ("azimuth", self.azimuth_deg, f64::NEG_INFINITY, f64::INFINITY),
            ("elevation", self.elevation_deg, -90.0, 90.0),
            ("field of view", self.fov_deg, 0.0, 170.0),
            ("light azimuth", self.light_azimuth_deg, f64::NEG_INFINITY, f64::INFINITY),
            ("light elevation", self.light_elevation_deg, 0.0, 90.000_001),
        ];
        for (name, v, lo, hi) in ranges {
            if !(v.is_finite() && v > lo && v < hi) {
                return bad(format!("{name} must be finite and in ({lo}, {hi}) degrees, got {v}"));
            }
        }
        if let Some(f) = &self.frame
            && (f.lo.iter().chain(&f.hi).any(|v| !v.is_finite())
                || (0..3).any(|a| f.lo[a] > f.hi[a]))
        {
            return bad(format!("frame box must be finite with lo ≤ hi, got {f:?}"));
        }
        Ok(())
    }
}

/// A pinhole camera in world units: the ray through image point `(px, py)` (pixels from
/// the top-left corner; pixel `(x, y)` has its centre at `(x + ½, y + ½)`) starts at `eye`
/// in direction `forward + sx·right + sy·up`, normalised, with
/// `sx = (2 px / width − 1) · tan(fov/2) · width/height` and
/// `sy = (1 − 2 py / height) · tan(fov/2)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: [f64; 3],
    /// Unit viewing direction.
    pub forward: [f64; 3],
    /// Unit vector to the right of the image.
    pub right: [f64; 3],
    /// Unit vector up the image.
    pub up: [f64; 3],
    /// tan of half the vertical field of view.
    pub tan_half_fov: f64,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    /// Unit direction of the ray through image point `(px, py)`.
    pub fn ray(&self, px: f64, py: f64) -> [f64; 3] {
        let t = self.tan_half_fov;
        let sx = (2.0 * px / self.width as f64 - 1.0) * t * self.width as f64 / self.height as f64;
        let sy = (1.0 - 2.0 * py / self.height as f64) * t;
        let d = add(self.forward, add(scale(self.right, sx), scale(self.up, sy)));
        normalize(d).expect("forward is a unit vector orthogonal to right and up")
    }

    /// The camera at `azimuth`/`elevation` (degrees) around the centre of `frame` at the
    /// smallest distance that shows every corner of the box with 8 % margin.
    fn framing(o: &RenderOptions, frame: &FrameBox) -> Camera {
        let (az, el) = (o.azimuth_deg.to_radians(), o.elevation_deg.to_radians());
        let back = [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()];
        let forward = scale(back, -1.0);
        // |back| = 1 and |el| < 90°, so back is never parallel to z.
        let right = normalize(cross(forward, [0.0, 0.0, 1.0])).expect("elevation below 90°");
        let up = cross(right, forward);
        let tan_half_fov = (o.fov_deg.to_radians() / 2.0).tan();
        let aspect = o.width as f64 / o.height as f64;
        let c = scale(add(frame.lo, frame.hi), 0.5);
        let margin = 0.92;
        let mut dist: f64 = 0.0;
        let mut radius: f64 = 0.0;
        for k in 0..8 {
            let corner = [
                if k & 1 == 0 { frame.lo[0] } else { frame.hi[0] },
                if k & 2 == 0 { frame.lo[1] } else { frame.hi[1] },
                if k & 4 == 0 { frame.lo[2] } else { frame.hi[2] },
            ];
            let r = sub(corner, c);
            radius = radius.max(dot(r, r).sqrt());
            // In front of the eye at distance D + z, the image half-extents are
            // (D + z)·tan·aspect and (D + z)·tan.
            let z = dot(r, forward);
            dist = dist.max(dot(r, right).abs() / (tan_half_fov * aspect * margin) - z);
            dist = dist.max(dot(r, up).abs() / (tan_half_fov * margin) - z);
        }
        // Keep the eye outside the box's bounding sphere (and away from a point box).
        let dist = dist.max(1.05 * radius).max(1e-6);
        Camera {
            eye: add(c, scale(back, dist)),
            forward,
            right,
            up,
            tan_half_fov,
            width: o.width,
            height: o.height,
        }
    }
}

/// An 8-bit sRGB image with the hit distance of every pixel's centre ray.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
    depth: Vec<f64>,
    camera: Camera,
}

impl Image {
    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// Pixels row by row from the top, 3 bytes (R, G, B) each.
    pub fn rgb(&self) -> &[u8] {
        &self.rgb
    }

    /// The colour of pixel `(x, y)` (from the top-left corner).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// World distance from the eye to the level set along the ray through the centre of
    /// pixel `(x, y)` ([`Camera::ray`] at `(x + ½, y + ½)`), `None` if it misses (the
    /// ground does not count).
    pub fn depth(&self, x: u32, y: u32) -> Option<f64> {
        let d = self.depth[y as usize * self.width as usize + x as usize];
        d.is_finite().then_some(d)
    }

    /// The camera the image was taken with.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Writes the image as an 8-bit RGB PNG, atomically (temporary file, then rename).
    pub fn write_png(&self, path: &Path) -> Result<(), RenderError> {
        crate::io::fsutil::write_atomic(path, |w| {
            let mut enc = png::Encoder::new(w, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_compression(png::Compression::High);
            let mut writer = enc.write_header()?;
            writer.write_image_data(&self.rgb)?;
            writer.finish()?;
            Ok(())
        })
        .map_err(|source| RenderError::Io { path: path.to_path_buf(), source })
    }
}

/// Linear-RGB colours of the scene.
const OBJECT: [f64; 3] = [0.80, 0.42, 0.18];
const GROUND: [f64; 3] = [0.62, 0.62, 0.60];
const SKY_HORIZON: [f64; 3] = [0.78, 0.82, 0.88];
const SKY_ZENITH: [f64; 3] = [0.22, 0.38, 0.62];
const AMBIENT: f64 = 0.16;
const SPECULAR: f64 = 0.25;
const SHININESS: i32 = 48;
/// Offset in voxels along the normal where shadow rays start, clear of the surface they
/// leave (a ray started on the surface could find its own zero: shadow acne).
const SHADOW_OFFSET: f64 = 0.5;

/// Everything a pixel needs, in voxel space (see `trace`).
struct Scene {
    occ: Occupancy,
    /// Eye in voxel space.
    eye: [f64; 3],
    camera: Camera,
    /// Unit direction towards the light.
    light: [f64; 3],
    /// Height of the ground plane in voxel space.
    ground: Option<f64>,
    /// World units per voxel.
    h: f64,
    /// Distance over which the ground fades into the horizon, in voxels.
    fade: f64,
    shadows: bool,
}

/// Renders the zero level set of any level set (see the [module docs](self)): the same
/// image for every storage of the same band. Progress counts image rows;
/// [`RenderError::Cancelled`] when the callback stops it.
pub fn render<G: LevelSet + ?Sized>(grid: &G, opts: &RenderOptions) -> Result<Image, RenderError> {
    opts.validate()?;
    let summary = summarise(grid).ok_or(RenderError::Empty("the grid stores no band voxel"))?;
    let Some((ilo, ihi)) = summary.inside.filter(|_| summary.any_outside) else {
        return Err(RenderError::Empty("every band value has the same sign: no zero crossing"));
    };
    let spec = grid.spec();
    let h = spec.voxel_size as f64;
    let world = |v: [f64; 3]| {
        [spec.origin[0] + h * v[0], spec.origin[1] + h * v[1], spec.origin[2] + h * v[2]]
    };
    let frame = opts.frame.unwrap_or_else(|| FrameBox {
        lo: world([ilo[0] as f64 - 1.0, ilo[1] as f64 - 1.0, ilo[2] as f64 - 1.0]),
        hi: world([ihi[0] as f64 + 1.0, ihi[1] as f64 + 1.0, ihi[2] as f64 + 1.0]),
    });
    let camera = Camera::framing(opts, &frame);
    let to_voxel = |p: [f64; 3]| {
        [(p[0] - spec.origin[0]) / h, (p[1] - spec.origin[1]) / h, (p[2] - spec.origin[2]) / h]
    };
    let ground = opts.ground.then(|| match opts.frame {
        Some(f) => (f.lo[2] - spec.origin[2]) / h,
        None => summary.bottom_z,
    });
    let (laz, lel) = (
        (opts.azimuth_deg + opts.light_azimuth_deg).to_radians(),
        opts.light_elevation_deg.to_radians(),
    );
    let diag = dot(sub(frame.hi, frame.lo), sub(frame.hi, frame.lo)).sqrt() / h;
    let scene = Scene {
        occ: Occupancy::build(grid, &summary),
        eye: to_voxel(camera.eye),
        camera,
        light: [lel.cos() * laz.cos(), lel.cos() * laz.sin(), lel.sin()],
        ground,
        h,
        fade: 4.0 * diag.max(1.0),
        shadows: opts.shadows,
    };
    let (w, ht) = (opts.width as usize, opts.height as usize);
    let mut rgb = vec![0u8; 3 * w * ht];
    let mut depth = vec![f64::INFINITY; w * ht];
    let ticker = opts.progress.start(ht as u64);
    rgb.par_chunks_mut(3 * w).zip(depth.par_chunks_mut(w)).enumerate().try_for_each(
        |(y, (row, drow))| {
            ticker.check()?;
            let mut s = Sampler::new(grid.accessor(), &spec, Units::Voxels);
            scene.row(&mut s, y as u32, opts.samples, row, drow);
            ticker.advance(1)
        },
    )?;
    Ok(Image { width: opts.width, height: opts.height, rgb, depth, camera })
}

impl Scene {
    /// One image row: colours (averaged over `n²` sub-pixel rays) and centre-ray depths.
    fn row<A: Accessor>(
        &self,
        s: &mut Sampler<A>,
        y: u32,
        n: u32,
        rgb: &mut [u8],
        depth: &mut [f64],
    ) {
        for x in 0..self.camera.width {
            let mut sum = [0.0; 3];
            let mut centre = None;
            for j in 0..n {
                for i in 0..n {
                    let px = x as f64 + (i as f64 + 0.5) / n as f64;
                    let py = y as f64 + (j as f64 + 0.5) / n as f64;
                    let d = self.camera.ray(px, py);
                    let (c, hit) = self.shade(s, d);
                    sum = add(sum, c);
                    if 2 * i + 1 == n && 2 * j + 1 == n {
                        centre = Some(hit);
                    }
                }
            }
            let hit = centre.unwrap_or_else(|| {
                let d = self.camera.ray(x as f64 + 0.5, y as f64 + 0.5);
                trace(&self.occ, s, self.eye, d, 0.0, f64::INFINITY)
            });
            depth[x as usize] = hit.map_or(f64::INFINITY, |t| t * self.h);
            let k = 1.0 / (n * n) as f64;
            for (out, c) in rgb[3 * x as usize..3 * x as usize + 3].iter_mut().zip(sum) {
                *out = encode_srgb(c * k);
            }
        }
    }

    /// Linear colour seen along the primary ray `d` from the eye, and the distance to the
    /// level set in voxels if it hits it.
    fn shade<A: Accessor>(&self, s: &mut Sampler<A>, d: [f64; 3]) -> ([f64; 3], Option<f64>) {
        let o = self.eye;
        let t_ground = match self.ground {
            Some(z) if d[2] < 0.0 && o[2] > z => (z - o[2]) / d[2],
            _ => f64::INFINITY,
        };
        let hit = trace(&self.occ, s, o, d, 0.0, f64::INFINITY);
        match hit {
            Some(t) if t < t_ground => {
                let p = at(o, d, t);
                let mut n = s.normal(p).unwrap_or(scale(d, -1.0));
                if dot(n, d) > 0.0 {
                    n = scale(n, -1.0);
                }
                let ndl = dot(n, self.light);
                let lit = ndl > 0.0 && self.visible(s, add(p, scale(n, SHADOW_OFFSET)));
                let sky = 0.5 + 0.5 * n[2];
                let mut c = scale(OBJECT, AMBIENT * (0.6 + 0.4 * sky));
                if lit {
                    c = add(c, scale(OBJECT, 0.9 * ndl));
                    let half = normalize(sub(self.light, d)).unwrap_or(n);
                    c = add(c, [SPECULAR * dot(n, half).max(0.0).powi(SHININESS); 3]);
                }
                (c, Some(t))
            }
            _ if t_ground.is_finite() => {
                let p = at(o, d, t_ground);
                let lit = self.light[2] > 0.0 && self.visible(s, p);
                let mut c = scale(GROUND, AMBIENT + if lit { 0.9 * self.light[2] } else { 0.0 });
                // Fade into the horizon with distance from the eye.
                let f = (-t_ground / self.fade).exp();
                c = add(scale(c, f), scale(SKY_HORIZON, 1.0 - f));
                (c, hit)
            }
            _ => {
                let u = d[2].clamp(0.0, 1.0).sqrt();
                (add(scale(SKY_HORIZON, 1.0 - u), scale(SKY_ZENITH, u)), hit)
            }
        }
    }

    /// Whether the light reaches voxel-space point `p` (no level set in between).
    fn visible<A: Accessor>(&self, s: &mut Sampler<A>, p: [f64; 3]) -> bool {
        !self.shadows || trace(&self.occ, s, p, self.light, 0.0, f64::INFINITY).is_none()
    }
}

/// sRGB encoding of a linear value in [0, 1] (clamped), rounded to 8 bits.
fn encode_srgb(v: f64) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0).round() as u8
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: [f64; 3], k: f64) -> [f64; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn at(o: [f64; 3], d: [f64; 3], t: f64) -> [f64; 3] {
    add(o, scale(d, t))
}
