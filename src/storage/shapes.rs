//! Analytic signed distance functions: the initial interfaces of tests and benchmarks.
//!
//! # Conventions
//! * φ < 0 inside, φ > 0 outside, φ = 0 on the surface;
//! * positions and distances in **world units** (the same units as
//!   [`crate::grid::GridSpec::origin`] and [`crate::grid::GridSpec::voxel_size`]);
//! * every primitive returns the **exact** Euclidean signed distance, so
//!   [`Shape::lipschitz`] is 1 and the culling of [`crate::storage::sample`] is valid. A
//!   [`Shape::Union`] is the minimum of its members: exact outside, and inside a
//!   1-Lipschitz lower bound of the distance magnitude where members overlap (the sign
//!   and the zero set stay exact).
//!
//! ```
//! use sparse_levelset::storage::shapes::Shape;
//!
//! let s = Shape::Sphere { center: [1.0, 2.0, 3.0], radius: 2.0 };
//! assert_eq!(s.sdf([1.0, 2.0, 3.0]), -2.0);
//! assert_eq!(s.sdf([4.0, 2.0, 3.0]), 1.0);
//! s.validate().unwrap();
//!
//! // The benchmark spiral of Nielsen & Museth 2006 and van der Laan et al. 2011 (128³).
//! let spiral = Shape::spiral_default([64.0; 3], 50.0, 40.0);
//! spiral.validate().unwrap();
//! assert!(spiral.sdf([64.0 + 50.0, 64.0, 64.0]).abs() < 1e-12);
//! ```

use crate::grid::GridError;
use serde::{Deserialize, Serialize};

/// An analytic shape with an exact signed distance function (φ < 0 inside, world units).
///
/// Values built directly (or deserialized) are not checked: call [`Shape::validate`]
/// before use.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Shape {
    /// Ball `|p − center| ≤ radius`.
    Sphere { center: [f64; 3], radius: f64 },
    /// Torus around the z axis through `center`: the points at distance `minor_radius`
    /// from the circle of radius `major_radius` in the plane `z = center.z`.
    /// Requires `0 < minor_radius < major_radius`.
    Torus { center: [f64; 3], major_radius: f64, minor_radius: f64 },
    /// Axis-aligned box `|p_i − center_i| ≤ half_extents_i`.
    Box { center: [f64; 3], half_extents: [f64; 3] },
    /// Axis-aligned ellipsoid `Σ ((p_i − center_i) / radii_i)² ≤ 1`; the distance is the
    /// exact Euclidean one (Eberly's robust bisection for the closest point).
    Ellipsoid { center: [f64; 3], radii: [f64; 3] },
    /// The extruded spiral of the benchmarks (Nielsen & Museth 2006, Sec. 4.1;
    /// van der Laan et al. 2011, Sec. 5.2: radius 50 and depth 40 on a 128³ grid).
    ///
    /// # Definition
    /// In the plane, a centre curve made of `n = 2·turns` half circles of radius
    /// `c, 2c, …, n·c`, alternately the upper half of a circle around
    /// `center + (−c/2, 0)` and the lower half of a circle around `center + (c/2, 0)`.
    /// Consecutive half circles share an end point on the x axis with a common vertical
    /// tangent, so the curve is a C¹ spiral winding counter-clockwise outwards whose arms
    /// are `2c` apart. It meets the Archimedean spiral `r = c (θ/π + 1/2)` at every half
    /// turn and stays close to it in between (the classic two-centre construction of a
    /// spiral from half circles), but unlike it has a closed-form distance. The arm is
    /// the set of points within `thickness / 2` of the curve (round caps at both ends),
    /// extruded along z over `center.z ± depth / 2` with flat caps. The benchmark's
    /// curvature is therefore piecewise constant along the arm (1/(k c) on half circle k).
    ///
    /// `c = (radius − thickness/2) / (n + 1/2)`, so the arm reaches exactly `radius` from
    /// `center` in the xy plane. Requires `turns` to be a positive multiple of ½ and the
    /// arms not to touch: `2c > thickness`, i.e. `radius > thickness · (turns + 3/4)`.
    ///
    /// # Exactness
    /// The distance to a half circle is closed-form, so the distance to the curve is
    /// exact; the curvature radius (≥ c) and the arm spacing (2c) both exceed
    /// `thickness / 2`, so "distance to the curve − thickness/2" is the exact 2D signed
    /// distance, and the extrusion formula keeps it exact in 3D. Cost: `n` square roots.
    Spiral { center: [f64; 3], radius: f64, depth: f64, turns: f64, thickness: f64 },
    /// Union of shapes: `min` of their distances (see the module docs for exactness).
    Union(Vec<Shape>),
}

/// Largest number of half circles of a [`Shape::Spiral`] (`2 · turns`).
const MAX_SPIRAL_ARCS: f64 = 4096.0;

impl Shape {
    /// The benchmark spiral with the defaults used throughout the project: **2 turns**
    /// and **thickness = radius / 5**. Then the half-circle radius step is
    /// `c = radius / 5` as well, so arms and the gaps between them are equally wide
    /// (10 voxels each for the papers' radius 50) and the innermost half circle has
    /// radius `radius / 5`.
    pub fn spiral_default(center: [f64; 3], radius: f64, depth: f64) -> Shape {
        Shape::Spiral { center, radius, depth, turns: 2.0, thickness: radius / 5.0 }
    }

    /// Signed distance (φ < 0 inside) from world position `p`, in world units.
    pub fn sdf(&self, p: [f64; 3]) -> f64 {
        match self {
            Shape::Sphere { center, radius } => norm3(sub(p, *center)) - radius,
            Shape::Torus { center, major_radius, minor_radius } => {
                let q = sub(p, *center);
                let ring = (q[0] * q[0] + q[1] * q[1]).sqrt() - major_radius;
                (ring * ring + q[2] * q[2]).sqrt() - minor_radius
            }
            Shape::Box { center, half_extents } => {
                let q = sub(p, *center);
                let d = [
                    q[0].abs() - half_extents[0],
                    q[1].abs() - half_extents[1],
                    q[2].abs() - half_extents[2],
                ];
                let outside = norm3([d[0].max(0.0), d[1].max(0.0), d[2].max(0.0)]);
                let inside = d[0].max(d[1]).max(d[2]).min(0.0);
                outside + inside
            }
            Shape::Ellipsoid { center, radii } => ellipsoid_sdf(*radii, sub(p, *center)),
            Shape::Spiral { center, radius, depth, turns, thickness } => {
                let q = sub(p, *center);
                let arcs = (2.0 * turns).round() as usize;
                let d2 =
                    spiral_curve_distance(q[0], q[1], *radius, *thickness, arcs) - 0.5 * thickness;
                let dz = q[2].abs() - 0.5 * depth;
                extrude(d2, dz)
            }
            Shape::Union(shapes) => shapes.iter().map(|s| s.sdf(p)).fold(f64::INFINITY, f64::min),
        }
    }

    /// World-space axis-aligned box `(min, max)` containing the interior (φ ≤ 0).
    ///
    /// For an empty [`Shape::Union`] (rejected by [`Shape::validate`]) this is the empty
    /// box `(+∞, −∞)`.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let around = |c: [f64; 3], h: [f64; 3]| {
            ([c[0] - h[0], c[1] - h[1], c[2] - h[2]], [c[0] + h[0], c[1] + h[1], c[2] + h[2]])
        };
        match self {
            Shape::Sphere { center, radius } => around(*center, [*radius; 3]),
            Shape::Torus { center, major_radius, minor_radius } => {
                let r = major_radius + minor_radius;
                around(*center, [r, r, *minor_radius])
            }
            Shape::Box { center, half_extents } => around(*center, *half_extents),
            Shape::Ellipsoid { center, radii } => around(*center, *radii),
            Shape::Spiral { center, radius, depth, .. } => {
                around(*center, [*radius, *radius, 0.5 * depth])
            }
            Shape::Union(shapes) => {
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for s in shapes {
                    let (a, b) = s.bounds();
                    for i in 0..3 {
                        lo[i] = lo[i].min(a[i]);
                        hi[i] = hi[i].max(b[i]);
                    }
                }
                (lo, hi)
            }
        }
    }

    /// The surface area, in world units squared: exact for the sphere, the torus, the box
    /// and the spiral (its arm's outline times the depth plus both flat caps); Knud
    /// Thomsen's approximation for the ellipsoid; the sum of the
    /// parts' areas for a union (an upper bound where they overlap). What memory estimates
    /// of a band scale with.
    pub fn area(&self) -> f64 {
        use std::f64::consts::PI;
        match self {
            Shape::Sphere { radius, .. } => 4.0 * PI * radius * radius,
            Shape::Torus { major_radius, minor_radius, .. } => {
                4.0 * PI * PI * major_radius * minor_radius
            }
            Shape::Box { half_extents: [a, b, c], .. } => 8.0 * (a * b + b * c + c * a),
            Shape::Ellipsoid { radii: [a, b, c], .. } => {
                const P: f64 = 1.6075;
                let (a, b, c) = (a.powf(P), b.powf(P), c.powf(P));
                4.0 * PI * ((a * b + a * c + b * c) / 3.0).powf(1.0 / P)
            }
            Shape::Spiral { radius, depth, turns, thickness, .. } => {
                // Half circles of radii c, 2c, …, n·c (see the variant's definition).
                let n = 2.0 * turns;
                let c = (radius - 0.5 * thickness) / (n + 0.5);
                let centre_line = PI * c * n * (n + 1.0) / 2.0;
                let outline = 2.0 * centre_line + PI * thickness;
                let section = centre_line * thickness + PI * thickness * thickness / 4.0;
                outline * depth + 2.0 * section
            }
            Shape::Union(shapes) => shapes.iter().map(Shape::area).sum(),
        }
    }

    /// Lipschitz constant of [`Shape::sdf`] with respect to world distance:
    /// `|sdf(p) − sdf(q)| ≤ L |p − q|`.
    ///
    /// It is 1 for every shape: each primitive is an exact Euclidean distance, and a
    /// minimum of 1-Lipschitz functions is 1-Lipschitz.
    pub fn lipschitz(&self) -> f64 {
        1.0
    }

    /// Checks that every parameter is finite and in its domain; the message of the
    /// [`GridError::InvalidParameter`] names the shape and the parameter.
    pub fn validate(&self) -> Result<(), GridError> {
        let bad = |msg: String| Err(GridError::InvalidParameter(msg));
        let finite = |name: &str, what: &str, v: &[f64]| {
            if v.iter().all(|x| x.is_finite()) {
                Ok(())
            } else {
                Err(GridError::InvalidParameter(format!(
                    "{name}: {what} must be finite, got {v:?}"
                )))
            }
        };
        let positive = |name: &str, what: &str, v: &[f64]| {
            finite(name, what, v)?;
            if v.iter().all(|&x| x > 0.0) {
                Ok(())
            } else {
                Err(GridError::InvalidParameter(format!("{name}: {what} must be > 0, got {v:?}")))
            }
        };
        match self {
            Shape::Sphere { center, radius } => {
                finite("sphere", "center", center)?;
                positive("sphere", "radius", &[*radius])
            }
            Shape::Torus { center, major_radius, minor_radius } => {
                finite("torus", "center", center)?;
                positive("torus", "major radius", &[*major_radius])?;
                positive("torus", "minor radius", &[*minor_radius])?;
                if minor_radius >= major_radius {
                    return bad(format!(
                        "torus: minor radius ({minor_radius}) must be smaller than the major \
                         radius ({major_radius})"
                    ));
                }
                Ok(())
            }
            Shape::Box { center, half_extents } => {
                finite("box", "center", center)?;
                positive("box", "half extents", half_extents)
            }
            Shape::Ellipsoid { center, radii } => {
                finite("ellipsoid", "center", center)?;
                positive("ellipsoid", "radii", radii)
            }
            Shape::Spiral { center, radius, depth, turns, thickness } => {
                finite("spiral", "center", center)?;
                positive("spiral", "radius", &[*radius])?;
                positive("spiral", "depth", &[*depth])?;
                positive("spiral", "thickness", &[*thickness])?;
                positive("spiral", "turns", &[*turns])?;
                let arcs = 2.0 * turns;
                if arcs != arcs.round() || arcs > MAX_SPIRAL_ARCS {
                    return bad(format!(
                        "spiral: turns must be a multiple of 0.5 between 0.5 and {}, got {turns}",
                        MAX_SPIRAL_ARCS / 2.0
                    ));
                }
                let step = (radius - 0.5 * thickness) / (arcs + 0.5);
                if 2.0 * step <= *thickness {
                    return bad(format!(
                        "spiral: arms of thickness {thickness} would touch; with {turns} turns \
                         the radius must exceed thickness · (turns + 3/4) = {}, got {radius}",
                        thickness * (turns + 0.75)
                    ));
                }
                Ok(())
            }
            Shape::Union(shapes) => {
                if shapes.is_empty() {
                    return bad("union: needs at least one shape".to_string());
                }
                shapes.iter().try_for_each(Shape::validate)
            }
        }
    }
}

#[inline(always)]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn norm3(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Exact extrusion of a 2D signed distance `d2` along an axis where `dz` is the signed
/// distance to the slab (Quilez's formula): exact whenever `d2` is.
#[inline(always)]
fn extrude(d2: f64, dz: f64) -> f64 {
    let a = d2.max(0.0);
    let b = dz.max(0.0);
    d2.max(dz).min(0.0) + (a * a + b * b).sqrt()
}

/// Unsigned distance from `(x, y)` (relative to the spiral's centre) to the centre curve
/// of a [`Shape::Spiral`] made of `arcs` half circles (see its docs).
#[inline]
fn spiral_curve_distance(x: f64, y: f64, radius: f64, thickness: f64, arcs: usize) -> f64 {
    let step = (radius - 0.5 * thickness) / (arcs as f64 + 0.5);
    let mut best = f64::INFINITY;
    for k in 0..arcs {
        let r = step * (k + 1) as f64;
        // Even: upper half around (-c/2, 0); odd: lower half around (c/2, 0).
        let (qx, on_side) =
            if k % 2 == 0 { (x + 0.5 * step, y >= 0.0) } else { (x - 0.5 * step, y <= 0.0) };
        let d2 = if on_side {
            // The nearest point of the full circle lies on this half.
            let d = (qx * qx + y * y).sqrt() - r;
            d * d
        } else {
            // The nearest point of the half circle is one of its ends (±r, 0).
            let dx = qx.abs() - r;
            dx * dx + y * y
        };
        best = best.min(d2);
    }
    best.sqrt()
}

/// Exact signed distance to the axis-aligned ellipsoid with semi-axes `radii` centred at
/// the origin, from `q`.
fn ellipsoid_sdf(radii: [f64; 3], q: [f64; 3]) -> f64 {
    // Sort the axes so that e0 ≥ e1 ≥ e2 and work in the first octant (Eberly's setting).
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| radii[b].total_cmp(&radii[a]));
    let e = [radii[axes[0]], radii[axes[1]], radii[axes[2]]];
    let y = [q[axes[0]].abs(), q[axes[1]].abs(), q[axes[2]].abs()];
    let d = distance_point_ellipsoid(e, y);
    let g = (y[0] / e[0]).powi(2) + (y[1] / e[1]).powi(2) + (y[2] / e[2]).powi(2);
    if g < 1.0 {
        -d
    } else {
        d
    }
}

/// Iteration cap of the root finder: bisection alone reaches adjacent doubles from any
/// bracket within 1100 steps (Eberly uses digits − min_exponent = 1074 for f64).
const MAX_ROOT_STEPS: usize = 1100;

/// `|v|` without overflow or destructive underflow.
#[inline]
fn robust_length(v: &[f64]) -> f64 {
    let m = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if m == 0.0 {
        return 0.0;
    }
    m * v.iter().map(|x| (x / m) * (x / m)).sum::<f64>().sqrt()
}

/// Root of `F(s) = Σ (n_i / (s + r_i))² − 1` for `terms = [(n_i, r_i)]`, `n_i ≥ 0`,
/// `r_i ≥ 1`, not all `n_i` zero, in the bracket `[lo, hi]` (with `F(lo) ≥ 0 ≥ F(hi)`).
///
/// Eberly ("Distance from a Point to an Ellipse, an Ellipsoid, or a Hyperellipsoid")
/// bisects Eberly's bracket, 50–100 steps. Here Newton's method is applied to
/// `G(s) = 1/‖q(s)‖ − 1` with `q_i = n_i / (s + r_i)`, which has the same root, is
/// increasing and concave (Moré & Sorensen's trick for the trust-region secular
/// equation) and is exactly linear when one term dominates. Newton from the left of the
/// root of a concave increasing function never overshoots, so the iterates climb
/// monotonically; the bracket is kept and bisection takes over if rounding ever sends
/// a step outside it. About 5 steps on average, 15 at most in tests, as accurate as
/// bisection (to a few ulps of `s`).
fn secular_root<const N: usize>(terms: [(f64, f64); N], hi: f64) -> f64 {
    // Lower bounds of the root: each term is ≤ 1 there (s ≥ n_i − r_i), and
    // Σ n_i² / (s + r_max)² ≤ 1 (s ≥ |n| − r_max). F ≥ 0 at the largest of them.
    let r_max = terms.iter().fold(0.0f64, |m, t| m.max(t.1));
    let norm = robust_length(&terms.map(|t| t.0));
    let mut lo = terms.iter().fold(norm - r_max, |m, &(n, r)| m.max(n - r));
    let mut hi = hi.max(lo);
    let eval = |s: f64| {
        let (mut sum, mut d) = (0.0, 0.0);
        for (n, r) in terms {
            let inv = 1.0 / (s + r);
            let q2 = (n * inv) * (n * inv);
            sum += q2;
            d += q2 * inv;
        }
        let inv = 1.0 / sum.sqrt();
        (inv - 1.0, d * inv * inv * inv)
    };
    let mut s = lo;
    for _ in 0..MAX_ROOT_STEPS {
        let (g, dg) = eval(s);
        if g < 0.0 {
            lo = s;
        } else if g > 0.0 {
            hi = s;
        } else {
            return s;
        }
        let newton = s - g / dg;
        if newton == s {
            return s; // the step is below one ulp of s
        }
        let next = if newton > lo && newton < hi { newton } else { 0.5 * (lo + hi) };
        if next <= lo || next >= hi {
            return s; // the bracket is two adjacent doubles
        }
        s = next;
    }
    s
}

/// 2D case: root of `(r0 z0 / (s + r0))² + (z1 / (s + 1))² − 1` (`g` is its value at 0,
/// which gives Eberly's upper bound of the root).
fn ellipse_root(r0: f64, z0: f64, z1: f64, g: f64) -> f64 {
    let n0 = r0 * z0;
    let hi = if g < 0.0 { 0.0 } else { robust_length(&[n0, z1]) - 1.0 };
    secular_root([(n0, r0), (z1, 1.0)], hi)
}

/// 3D case: root of `Σ (r_i z_i / (s + r_i))² − 1` with `r2 = 1` (`g` is its value at 0).
fn ellipsoid_root(r0: f64, r1: f64, z: [f64; 3], g: f64) -> f64 {
    let n0 = r0 * z[0];
    let n1 = r1 * z[1];
    let hi = if g < 0.0 { 0.0 } else { robust_length(&[n0, n1, z[2]]) - 1.0 };
    secular_root([(n0, r0), (n1, r1), (z[2], 1.0)], hi)
}

/// Distance from `(y0, y1)`, `y_i ≥ 0`, to the ellipse with semi-axes `e0 ≥ e1 > 0`.
fn distance_point_ellipse(e0: f64, e1: f64, y0: f64, y1: f64) -> f64 {
    if y1 > 0.0 {
        if y0 > 0.0 {
            let z0 = y0 / e0;
            let z1 = y1 / e1;
            let g = z0 * z0 + z1 * z1 - 1.0;
            if g != 0.0 {
                let r0 = (e0 / e1) * (e0 / e1);
                let s = ellipse_root(r0, z0, z1, g);
                let x0 = r0 * y0 / (s + r0);
                let x1 = y1 / (s + 1.0);
                ((x0 - y0) * (x0 - y0) + (x1 - y1) * (x1 - y1)).sqrt()
            } else {
                0.0
            }
        } else {
            (y1 - e1).abs()
        }
    } else {
        let numer0 = e0 * y0;
        let denom0 = e0 * e0 - e1 * e1;
        if numer0 < denom0 {
            let xde0 = numer0 / denom0;
            let x0 = e0 * xde0;
            let x1 = e1 * (1.0 - xde0 * xde0).sqrt();
            ((x0 - y0) * (x0 - y0) + x1 * x1).sqrt()
        } else {
            (y0 - e0).abs()
        }
    }
}

/// Distance from `y`, `y_i ≥ 0`, to the ellipsoid with semi-axes `e0 ≥ e1 ≥ e2 > 0`
/// (Eberly's case analysis; valid inside and outside).
fn distance_point_ellipsoid(e: [f64; 3], y: [f64; 3]) -> f64 {
    if y[2] > 0.0 {
        if y[1] > 0.0 {
            if y[0] > 0.0 {
                let z = [y[0] / e[0], y[1] / e[1], y[2] / e[2]];
                let g = z[0] * z[0] + z[1] * z[1] + z[2] * z[2] - 1.0;
                if g != 0.0 {
                    let r0 = (e[0] / e[2]) * (e[0] / e[2]);
                    let r1 = (e[1] / e[2]) * (e[1] / e[2]);
                    let s = ellipsoid_root(r0, r1, z, g);
                    let x = [r0 * y[0] / (s + r0), r1 * y[1] / (s + r1), y[2] / (s + 1.0)];
                    norm3(sub(x, y))
                } else {
                    0.0
                }
            } else {
                distance_point_ellipse(e[1], e[2], y[1], y[2])
            }
        } else if y[0] > 0.0 {
            distance_point_ellipse(e[0], e[2], y[0], y[2])
        } else {
            (y[2] - e[2]).abs()
        }
    } else {
        // y2 = 0: the closest point may leave the plane (interior points near it).
        let denom = [e[0] * e[0] - e[2] * e[2], e[1] * e[1] - e[2] * e[2]];
        let ey = [e[0] * y[0], e[1] * y[1]];
        // The strict comparisons also guard the divisions when e_i == e2.
        if ey[0] < denom[0] && ey[1] < denom[1] {
            let xde = [ey[0] / denom[0], ey[1] / denom[1]];
            let discr = 1.0 - xde[0] * xde[0] - xde[1] * xde[1];
            if discr > 0.0 {
                let x = [e[0] * xde[0], e[1] * xde[1], e[2] * discr.sqrt()];
                return ((x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2) + x[2] * x[2]).sqrt();
            }
        }
        distance_point_ellipse(e[0], e[1], y[0], y[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOL: f64 = 1e-12;

    fn close(a: f64, b: f64, abs: f64) -> bool {
        (a - b).abs() <= abs + 1e-12 * b.abs()
    }

    fn rand_in(rng: &mut fastrand::Rng, lo: [f64; 3], hi: [f64; 3]) -> [f64; 3] {
        [
            lo[0] + (hi[0] - lo[0]) * rng.f64(),
            lo[1] + (hi[1] - lo[1]) * rng.f64(),
            lo[2] + (hi[2] - lo[2]) * rng.f64(),
        ]
    }

    fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
    }

    fn test_shapes() -> Vec<Shape> {
        vec![
            Shape::Sphere { center: [1.0, -2.0, 3.0], radius: 4.0 },
            Shape::Torus { center: [-1.0, 0.5, 2.0], major_radius: 5.0, minor_radius: 1.5 },
            Shape::Box { center: [0.5, 1.0, -1.0], half_extents: [3.0, 2.0, 1.0] },
            Shape::Ellipsoid { center: [2.0, 0.0, -3.0], radii: [5.0, 2.0, 3.0] },
            Shape::Ellipsoid { center: [0.0; 3], radii: [2.0, 2.0, 1.0] },
            Shape::spiral_default([3.0, -4.0, 1.0], 50.0, 40.0),
            Shape::Spiral {
                center: [0.0; 3],
                radius: 20.0,
                depth: 6.0,
                turns: 1.5,
                thickness: 3.0,
            },
            Shape::Union(vec![
                Shape::Sphere { center: [0.0; 3], radius: 2.0 },
                Shape::Box { center: [6.0, 0.0, 0.0], half_extents: [1.0, 1.0, 1.0] },
            ]),
        ]
    }

    #[test]
    fn all_test_shapes_validate() {
        for s in test_shapes() {
            s.validate().unwrap_or_else(|e| panic!("{s:?}: {e}"));
            assert_eq!(s.lipschitz(), 1.0);
        }
    }

    #[test]
    fn validation_rejects_bad_parameters() {
        let bad = [
            Shape::Sphere { center: [0.0; 3], radius: 0.0 },
            Shape::Sphere { center: [f64::NAN, 0.0, 0.0], radius: 1.0 },
            Shape::Sphere { center: [0.0; 3], radius: f64::INFINITY },
            Shape::Torus { center: [0.0; 3], major_radius: 1.0, minor_radius: 1.0 },
            Shape::Torus { center: [0.0; 3], major_radius: 1.0, minor_radius: -0.5 },
            Shape::Box { center: [0.0; 3], half_extents: [1.0, 0.0, 1.0] },
            Shape::Ellipsoid { center: [0.0; 3], radii: [1.0, 2.0, f64::NAN] },
            Shape::Spiral {
                center: [0.0; 3],
                radius: 50.0,
                depth: 40.0,
                turns: 1.3,
                thickness: 10.0,
            },
            Shape::Spiral {
                center: [0.0; 3],
                radius: 50.0,
                depth: 40.0,
                turns: 2.0,
                thickness: 20.0,
            },
            Shape::Spiral {
                center: [0.0; 3],
                radius: 50.0,
                depth: 0.0,
                turns: 2.0,
                thickness: 10.0,
            },
            Shape::Spiral {
                center: [0.0; 3],
                radius: 50.0,
                depth: 1.0,
                turns: 1e9,
                thickness: 1e-9,
            },
            Shape::Union(vec![]),
            Shape::Union(vec![Shape::Sphere { center: [0.0; 3], radius: -1.0 }]),
        ];
        for s in bad {
            match s.validate() {
                Err(GridError::InvalidParameter(msg)) => assert!(!msg.is_empty()),
                other => panic!("{s:?} gave {other:?}"),
            }
        }
    }

    #[test]
    fn sphere_torus_box_known_values() {
        let s = Shape::Sphere { center: [1.0, 2.0, 3.0], radius: 2.0 };
        assert!(close(s.sdf([1.0, 2.0, 3.0]), -2.0, TOL));
        assert!(close(s.sdf([1.0, 4.0, 3.0]), 0.0, TOL));
        assert!(close(s.sdf([1.0, 2.0, 103.0]), 98.0, TOL));

        let t = Shape::Torus { center: [0.0, 0.0, 1.0], major_radius: 4.0, minor_radius: 1.0 };
        assert!(close(t.sdf([0.0, 0.0, 1.0]), 3.0, TOL)); // hole centre
        assert!(close(t.sdf([4.0, 0.0, 1.0]), -1.0, TOL)); // tube centre
        assert!(close(t.sdf([0.0, -5.0, 1.0]), 0.0, TOL));
        assert!(close(t.sdf([0.0, 4.0, 3.0]), 1.0, TOL)); // above the tube
        assert!(close(t.sdf([3.0, 4.0, 1.0]), 0.0, TOL)); // |(3,4)| = 5
        assert!(close(t.sdf([0.0, 0.0, 11.0]), (16.0f64 + 100.0).sqrt() - 1.0, TOL));

        let b = Shape::Box { center: [1.0, 0.0, 0.0], half_extents: [1.0, 2.0, 3.0] };
        assert!(close(b.sdf([1.0, 0.0, 0.0]), -1.0, TOL));
        assert!(close(b.sdf([2.0, 0.5, 0.5]), 0.0, TOL));
        assert!(close(b.sdf([4.0, 0.0, 0.0]), 2.0, TOL));
        assert!(close(b.sdf([3.0, 3.0, 3.0]), 2f64.sqrt(), TOL)); // edge region
        assert!(close(b.sdf([3.0, 3.0, 4.0]), 3f64.sqrt(), TOL)); // corner region
        assert!(close(b.sdf([1.5, 0.0, 2.8]), -0.2, TOL));
    }

    #[test]
    fn ellipsoid_known_values() {
        let e = Shape::Ellipsoid { center: [1.0, 1.0, 1.0], radii: [3.0, 2.0, 1.0] };
        assert!(close(e.sdf([1.0, 1.0, 1.0]), -1.0, TOL)); // nearest along the shortest axis
        assert!(close(e.sdf([4.0, 1.0, 1.0]), 0.0, TOL));
        assert!(close(e.sdf([1.0, -1.0, 1.0]), 0.0, TOL));
        assert!(close(e.sdf([1.0, 1.0, 0.0]), 0.0, TOL));
        assert!(close(e.sdf([11.0, 1.0, 1.0]), 7.0, TOL)); // along an axis outside
        assert!(close(e.sdf([1.0, 1.0, 5.0]), 3.0, TOL));
        // Surface points in every octant.
        for (u, v) in [(0.3, 0.4), (1.2, -2.0), (2.5, 2.9), (-0.7, 0.1)] {
            let p = [
                1.0 + 3.0 * f64::cos(u) * f64::cos(v),
                1.0 + 2.0 * f64::cos(u) * f64::sin(v),
                1.0 + f64::sin(u),
            ];
            assert!(e.sdf(p).abs() < 1e-12, "{p:?}: {}", e.sdf(p));
        }
        // Degenerate: a sphere written as an ellipsoid, and axes in any order.
        let s = Shape::Ellipsoid { center: [0.0; 3], radii: [2.0; 3] };
        let sphere = Shape::Sphere { center: [0.0; 3], radius: 2.0 };
        let mut rng = fastrand::Rng::with_seed(3);
        for _ in 0..200 {
            let p = rand_in(&mut rng, [-5.0; 3], [5.0; 3]);
            assert!(close(s.sdf(p), sphere.sdf(p), 1e-12));
            let a = Shape::Ellipsoid { center: [0.0; 3], radii: [1.0, 2.0, 3.0] };
            let b = Shape::Ellipsoid { center: [0.0; 3], radii: [3.0, 1.0, 2.0] };
            assert!(close(a.sdf(p), b.sdf([p[2], p[0], p[1]]), 1e-12));
        }
        // Points on the symmetry planes and axes take the special branches.
        assert!(close(s.sdf([0.0, 0.0, 0.0]), -2.0, TOL));
        let flat = Shape::Ellipsoid { center: [0.0; 3], radii: [2.0, 2.0, 1.0] };
        assert!(close(flat.sdf([0.0; 3]), -1.0, TOL));
        assert!(close(flat.sdf([1.5, 0.0, 0.0]), -0.5, TOL));
    }

    /// The ellipsoid against a brute-force closest point on a dense surface sampling.
    #[test]
    fn ellipsoid_matches_brute_force() {
        let radii = [3.0, 1.5, 2.0];
        let e = Shape::Ellipsoid { center: [0.0; 3], radii };
        let (nu, nv) = (600usize, 1200usize);
        let mut pts = Vec::with_capacity((nu + 1) * nv);
        for i in 0..=nu {
            let u = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * i as f64 / nu as f64;
            for j in 0..nv {
                let v = std::f64::consts::TAU * j as f64 / nv as f64;
                pts.push([
                    radii[0] * u.cos() * v.cos(),
                    radii[1] * u.cos() * v.sin(),
                    radii[2] * u.sin(),
                ]);
            }
        }
        // Largest gap between neighbouring samples bounds the brute-force error.
        let spacing =
            3.0 * std::f64::consts::TAU / nv as f64 + 3.0 * std::f64::consts::PI / nu as f64;
        let mut rng = fastrand::Rng::with_seed(11);
        for n in 0..40 {
            let p = if n % 2 == 0 {
                rand_in(&mut rng, [-6.0; 3], [6.0; 3])
            } else {
                rand_in(&mut rng, [-2.5, -1.2, -1.6], [2.5, 1.2, 1.6])
            };
            let brute = pts.iter().map(|&q| norm3(sub(p, q))).fold(f64::INFINITY, f64::min);
            let exact = e.sdf(p);
            assert!(brute >= exact.abs() - 1e-9, "{p:?}: brute {brute} < exact {exact}");
            assert!(brute - exact.abs() <= spacing, "{p:?}: brute {brute}, exact {exact}");
            let g =
                (p[0] / radii[0]).powi(2) + (p[1] / radii[1]).powi(2) + (p[2] / radii[2]).powi(2);
            assert_eq!(exact < 0.0, g < 1.0);
        }
    }

    #[test]
    fn spiral_zero_set_is_where_expected() {
        let c = [64.0, 64.0, 64.0];
        let s = Shape::spiral_default(c, 50.0, 40.0);
        // Defaults: step c = 10, thickness 10, half circles of radius 10, 20, 30, 40.
        let at = |x: f64, y: f64, z: f64| s.sdf(add(c, [x, y, z]));
        // Outer end cap of the last (lower) half circle, around (5, 0), radius 40.
        assert!(at(50.0, 0.0, 0.0).abs() < 1e-12);
        assert!(close(at(45.0, 0.0, 0.0), -5.0, TOL));
        // Bottom of the last half circle: centre line at y = -40, edges at -35 and -45.
        assert!(close(at(5.0, -40.0, 0.0), -5.0, TOL));
        assert!(at(5.0, -45.0, 0.0).abs() < 1e-12);
        assert!(at(5.0, -35.0, 0.0).abs() < 1e-12);
        // Gap between the two lower half circles (radius 20 and 40 around (5, 0)).
        assert!(close(at(5.0, -30.0, 0.0), 5.0, TOL));
        // Top of the upper half circles around (-5, 0): radius 10, 30.
        assert!(close(at(-5.0, 10.0, 0.0), -5.0, TOL));
        assert!(close(at(-5.0, 30.0, 0.0), -5.0, TOL));
        assert!(close(at(-5.0, 20.0, 0.0), 5.0, TOL));
        // Inner start cap at (5, 0): the curve starts at (-5 + 10, 0).
        assert!(close(at(5.0, 0.0, 0.0), -5.0, TOL));
        // Flat caps at z = ±20.
        assert!(at(-5.0, 30.0, 20.0).abs() < 1e-12);
        assert!(at(-5.0, 30.0, -20.0).abs() < 1e-12);
        assert!(close(at(-5.0, 30.0, 23.0), 3.0, TOL));
        assert!(close(at(-5.0, 30.0, 19.0), -1.0, TOL));
        // Outside the cap edge: distance to the rim.
        assert!(close(at(-5.0, 38.0, 24.0), 5.0, TOL));
        // Far away, and the bounds contain the interior.
        assert!(close(at(200.0, 0.0, 0.0), 150.0, TOL));
        let (lo, hi) = s.bounds();
        assert_eq!((lo, hi), ([14.0, 14.0, 44.0], [114.0, 114.0, 84.0]));
        let mut rng = fastrand::Rng::with_seed(5);
        let mut inside = 0;
        for _ in 0..20000 {
            let p = rand_in(&mut rng, [0.0; 3], [128.0; 3]);
            if s.sdf(p) <= 0.0 {
                inside += 1;
                assert!((0..3).all(|i| p[i] >= lo[i] && p[i] <= hi[i]), "{p:?}");
            }
        }
        assert!(inside > 500, "{inside}");
    }

    /// The spiral's curve distance against a dense sampling of its half circles.
    #[test]
    fn spiral_curve_distance_matches_brute_force() {
        let (radius, thickness, arcs) = (20.0, 3.0, 3usize);
        let step = (radius - 0.5 * thickness) / (arcs as f64 + 0.5);
        let mut pts = Vec::new();
        let n = 20000;
        for k in 0..arcs {
            let r = step * (k + 1) as f64;
            // Even: upper half around (-c/2, 0), angles 0..π; odd: lower half around
            // (c/2, 0), angles π..2π (counter-clockwise).
            let (ox, t0) =
                if k % 2 == 0 { (-0.5 * step, 0.0) } else { (0.5 * step, std::f64::consts::PI) };
            for i in 0..=n {
                let t = t0 + std::f64::consts::PI * i as f64 / n as f64;
                pts.push((ox + r * t.cos(), r * t.sin()));
            }
        }
        // The curve is C⁰: consecutive half circles share end points.
        for k in 0..arcs - 1 {
            let end = pts[k * (n + 1) + n];
            let start = pts[(k + 1) * (n + 1)];
            assert!((end.0 - start.0).abs() < 1e-12 && (end.1 - start.1).abs() < 1e-12);
        }
        let spacing = std::f64::consts::PI * radius / n as f64;
        let mut rng = fastrand::Rng::with_seed(7);
        for _ in 0..300 {
            let (x, y) = (rng.f64() * 50.0 - 25.0, rng.f64() * 50.0 - 25.0);
            let brute = pts
                .iter()
                .map(|&(a, b)| ((x - a).powi(2) + (y - b).powi(2)).sqrt())
                .fold(f64::INFINITY, f64::min);
            let d = spiral_curve_distance(x, y, radius, thickness, arcs);
            assert!(brute >= d - 1e-9 && brute - d <= spacing, "({x}, {y}): {brute} vs {d}");
        }
    }

    /// |∇φ| = 1 wherever φ is differentiable, and φ is 1-Lipschitz everywhere.
    #[test]
    fn gradient_norm_is_one_and_lipschitz_holds() {
        let mut rng = fastrand::Rng::with_seed(42);
        for s in test_shapes() {
            let (lo, hi) = s.bounds();
            let lo = [lo[0] - 3.0, lo[1] - 3.0, lo[2] - 3.0];
            let hi = [hi[0] + 3.0, hi[1] + 3.0, hi[2] + 3.0];
            let h = 1e-5;
            let (mut used, mut total) = (0, 0);
            for _ in 0..2000 {
                let p = rand_in(&mut rng, lo, hi);
                total += 1;
                let f0 = s.sdf(p);
                let mut g = [0.0; 3];
                let mut smooth = true;
                for i in 0..3 {
                    let mut a = p;
                    let mut b = p;
                    a[i] += h;
                    b[i] -= h;
                    let (fa, fb) = (s.sdf(a), s.sdf(b));
                    // One-sided slopes disagree near the medial axis (a kink): skip.
                    if ((fa - f0) - (f0 - fb)).abs() > 1e-3 * h {
                        smooth = false;
                    }
                    g[i] = (fa - fb) / (2.0 * h);
                }
                let n = norm3(g);
                assert!(n <= 1.0 + 1e-5, "{s:?} at {p:?}: |grad| = {n}");
                if smooth {
                    used += 1;
                    assert!((n - 1.0).abs() < 1e-5, "{s:?} at {p:?}: |grad| = {n}");
                }
                // Lipschitz against a nearby and a far point.
                for scale in [0.5, 20.0] {
                    let q = add(p, rand_in(&mut rng, [-scale; 3], [scale; 3]));
                    let d = norm3(sub(p, q));
                    assert!(
                        (s.sdf(p) - s.sdf(q)).abs() <= d * (1.0 + 1e-12) + 1e-12,
                        "{s:?}: {p:?} {q:?}"
                    );
                }
            }
            assert!(used * 10 >= total * 8, "{s:?}: only {used} of {total} points were smooth");
        }
    }

    #[test]
    fn union_is_min_and_bounds_cover() {
        let a = Shape::Sphere { center: [0.0; 3], radius: 1.0 };
        let b = Shape::Sphere { center: [5.0, 0.0, 0.0], radius: 2.0 };
        let u = Shape::Union(vec![a.clone(), b.clone()]);
        for p in [[0.0; 3], [2.5, 0.0, 0.0], [5.0, 3.0, 0.0], [-4.0, 1.0, 2.0]] {
            assert_eq!(u.sdf(p), a.sdf(p).min(b.sdf(p)));
        }
        assert_eq!(u.bounds(), ([-1.0, -2.0, -2.0], [7.0, 2.0, 2.0]));
        assert_eq!(Shape::Union(vec![]).sdf([0.0; 3]), f64::INFINITY);
    }

    #[test]
    fn bounds_contain_the_interior() {
        let mut rng = fastrand::Rng::with_seed(9);
        for s in test_shapes() {
            let (lo, hi) = s.bounds();
            let pad = [(hi[0] - lo[0]) * 0.2, (hi[1] - lo[1]) * 0.2, (hi[2] - lo[2]) * 0.2];
            let (plo, phi) = (sub(lo, pad), add(hi, pad));
            let mut inside = 0;
            for _ in 0..5000 {
                let p = rand_in(&mut rng, plo, phi);
                if s.sdf(p) <= 0.0 {
                    inside += 1;
                    assert!((0..3).all(|i| p[i] >= lo[i] && p[i] <= hi[i]), "{s:?}: {p:?}");
                }
            }
            assert!(inside > 0, "{s:?}");
        }
    }

    #[test]
    fn serde_round_trip() {
        let s = Shape::Union(test_shapes());
        let json = serde_json::to_string(&s).unwrap();
        let back: Shape = serde_json::from_str(&json).unwrap();
        assert_eq!(s, back);
    }
}
