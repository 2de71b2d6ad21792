//! Layer 2 of the test plan: the kernels against analytic fields — convergence orders,
//! |∇φ| and curvature on spheres, sign conventions of eq. (3), TVD-RK3 order.
//!
//! Values are computed in f64 and rounded to f32 once, as a grid would store them. To keep
//! f32 rounding (~6e-8 relative) below the truncation errors being measured, convergence
//! tests subtract the centre value (φ − φ(p₀) has the same derivatives but entries of size
//! O(h)).

use crate::common::{close, Rng};
use levelset_kernels::curvature::{curvature_speed, mean_curvature};
use levelset_kernels::diff::central_norm;
use levelset_kernels::rk::{
    cfl_dt_advection, cfl_dt_curvature, cfl_dt_eq3, cfl_dt_normal, rk3_combine,
};
use levelset_kernels::speed::smoothed_delta;
use levelset_kernels::weno::hj_weno5;
use levelset_kernels::{
    box27_index, star19_index, AdvectionRate, BoxStarWindow, BoxWindow, Eq3Rate, Euler, Scheme,
    StarWindow, Upwind1, VoxelKernel, Weno5,
};

/// The box and star stencils of `f` around `p` with voxel size `h`, minus `shift`.
fn stencils(
    f: &dyn Fn([f64; 3]) -> f64,
    p: [f64; 3],
    h: f64,
    shift: f64,
) -> ([f32; 27], [f32; 19]) {
    let at = |o: [i32; 3]| {
        (f([p[0] + o[0] as f64 * h, p[1] + o[1] as f64 * h, p[2] + o[2] as f64 * h]) - shift) as f32
    };
    let mut b = [0.0; 27];
    for dz in -1..=1 {
        for dy in -1..=1 {
            for dx in -1..=1 {
                b[box27_index(dx, dy, dz)] = at([dx, dy, dz]);
            }
        }
    }
    let mut s = [0.0; 19];
    s[0] = at([0, 0, 0]);
    for a in 0..3 {
        for st in [-3, -2, -1, 1, 2, 3] {
            let mut o = [0; 3];
            o[a] = st;
            s[star19_index(o[0], o[1], o[2])] = at(o);
        }
    }
    (b, s)
}

/// Observed order between consecutive halvings of h.
fn orders(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect()
}

/// One-sided derivatives (minus, plus) along `axis` from a scheme on a star window.
fn one_sided<S: Scheme>(s: &[f32; 19], h: f32) -> ([f32; 3], [f32; 3]) {
    S::derivatives::<f32, _>(&StarWindow::new(s), 1.0 / h)
}

/// A smooth 1D profile along each axis in turn, with its derivative.
fn profile(t: f64) -> (f64, f64) {
    let v = (1.3 * t + 0.4).sin() + 0.5 * (0.7 * t).cos() + 0.2 * t * t;
    let d = 1.3 * (1.3 * t + 0.4).cos() - 0.35 * (0.7 * t).sin() + 0.4 * t;
    (v, d)
}

fn convergence<S: Scheme>(hs: &[f64]) -> Vec<Vec<f64>> {
    // For each axis and side: errors over hs, maximised over a few evaluation points.
    let mut all = Vec::new();
    for axis in 0..3 {
        for side in 0..2 {
            let mut errs = Vec::new();
            for &h in hs {
                let mut e: f64 = 0.0;
                for t0 in [0.37, -1.1, 2.3, 0.9] {
                    let f = |p: [f64; 3]| profile(p[axis]).0;
                    let mut p = [0.11, -0.2, 0.05];
                    p[axis] = t0;
                    let (_, s) = stencils(&f, p, h, f(p));
                    let (m, pl) = one_sided::<S>(&s, h as f32);
                    let got = if side == 0 { m[axis] } else { pl[axis] } as f64;
                    e = e.max((got - profile(t0).1).abs());
                }
                errs.push(e);
            }
            all.push(errs);
        }
    }
    all
}

#[test]
fn weno5_converges_at_fifth_order() {
    let hs = [0.4, 0.2, 0.1];
    for (k, errs) in convergence::<Weno5>(&hs).iter().enumerate() {
        let o = orders(errs);
        eprintln!("weno5 axis/side {k}: errors {errs:?} orders {o:.2?}");
        // Stays above the f32 floor (~1e-6 here) at the finest level.
        assert!(errs[2] > 1e-6, "axis/side {k}: errors {errs:?} reach f32 rounding");
        for &q in &o {
            assert!((4.5..6.5).contains(&q), "axis/side {k}: errors {errs:?}, orders {o:?}");
        }
    }
}

#[test]
fn first_order_upwind_converges_at_first_order() {
    let hs = [0.1, 0.05, 0.025, 0.0125];
    for (k, errs) in convergence::<Upwind1>(&hs).iter().enumerate() {
        let o = orders(errs);
        eprintln!("upwind1 axis/side {k}: errors {errs:?} orders {o:.2?}");
        for &q in &o {
            assert!((0.85..1.15).contains(&q), "axis/side {k}: errors {errs:?}, orders {o:?}");
        }
    }
}

/// The voxel centres (h = 1) with |φ| < band of a sphere of radius r centred at c, in one
/// octant plus its boundary (the field is symmetric up to the off-grid centre, so every
/// orientation of the normal is covered).
fn band_voxels(c: [f64; 3], r: f64, band: f64) -> Vec<[f64; 3]> {
    let mut v = Vec::new();
    let n = (r + band + 1.0).ceil() as i32;
    for z in 0..=n {
        for y in 0..=n {
            for x in 0..=n {
                let p = [x as f64 + c[0].round(), y as f64 + c[1].round(), z as f64 + c[2].round()];
                let rho =
                    ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
                if (rho - r).abs() < band {
                    v.push(p);
                }
            }
        }
    }
    v
}

fn sphere(c: [f64; 3], r: f64) -> impl Fn([f64; 3]) -> f64 {
    move |p: [f64; 3]| {
        ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt() - r
    }
}

const CENTRE: [f64; 3] = [0.31, -0.23, 0.17];

#[test]
fn curvature_of_spheres_is_one_over_r() {
    for r in [10.0, 12.7, 20.0, 33.3] {
        let f = sphere(CENTRE, r);
        let (mut sum, mut n, mut worst) = (0.0, 0, 0.0f64);
        for p in band_voxels(CENTRE, r, 1.0) {
            let (b, _) = stencils(&f, p, 1.0, 0.0);
            let w = BoxWindow::new(&b);
            let rho = f(p) + r; // the level set through p is a sphere of radius ρ
            let kappa = mean_curvature::<f32, _>(&w, 1.0) as f64;
            let kg = curvature_speed::<f32, _>(&w, 1.0) as f64;
            worst = worst.max((kappa * rho - 1.0).abs()).max((kg * rho - 1.0).abs());
            if f(p).abs() < 0.5 {
                sum += kappa;
                n += 1;
            }
        }
        eprintln!(
            "r = {r}: worst |κρ − 1| = {worst:.2e}, mean κ·r − 1 = {:.2e}",
            sum / n as f64 * r - 1.0
        );
        assert!(worst < 0.01, "r = {r}: worst relative error of κ against 1/ρ is {worst}");
        let mean = sum / n as f64;
        assert!((mean * r - 1.0).abs() < 0.01, "r = {r}: mean κ near the surface {mean} vs 1/r");
    }
}

#[test]
fn gradient_norm_of_sphere_distance_within_one_percent() {
    // Central and HJ-WENO5: radius 10 is enough (errors O(h²/ρ²) and O(h⁵)).
    for r in [10.0, 17.5] {
        let f = sphere(CENTRE, r);
        let mut worst = [0.0f64; 3];
        for p in band_voxels(CENTRE, r, 3.0) {
            let (b, s) = stencils(&f, p, 1.0, 0.0);
            let c = central_norm::<f32, _>(&BoxWindow::new(&b), 1.0) as f64;
            let (wp, wm) = Weno5::norms::<f32, _>(&StarWindow::new(&s), 1.0);
            for (k, v) in [c, wp as f64, wm as f64].into_iter().enumerate() {
                worst[k] = worst[k].max((v - 1.0).abs());
            }
        }
        eprintln!("r = {r}: worst ||∇φ| − 1| [central, weno+, weno−] = {worst:?}");
        assert!(
            worst.iter().all(|&e| e < 0.01),
            "r = {r}: |∇φ| − 1 worst [central, weno+, weno−] = {worst:?}"
        );
    }
    // First-order one-sided differences have error ≈ (h/2ρ)(Σ|nₐ| − Σ|nₐ|³) ≤ 0.58 h/ρ
    // (along a diagonal): 1% needs ρ ≳ 58 voxels; r = 80 keeps the band (ρ ≥ 77) inside.
    let mut by_radius = Vec::new();
    for r in [20.0, 40.0, 80.0] {
        let f = sphere(CENTRE, r);
        let mut worst = 0.0f64;
        for p in band_voxels(CENTRE, r, 3.0) {
            let (b, _) = stencils(&f, p, 1.0, 0.0);
            let (up, um) = Upwind1::norms::<f32, _>(&BoxWindow::new(&b), 1.0);
            worst = worst.max((up as f64 - 1.0).abs()).max((um as f64 - 1.0).abs());
        }
        by_radius.push(worst);
    }
    eprintln!("first-order upwind worst ||∇φ| − 1| at r = 20, 40, 80: {by_radius:?}");
    assert!(by_radius[2] < 0.01, "first order at r = 80: worst {by_radius:?}");
    // ... and the error halves with the curvature (first order in h/ρ).
    for k in 0..2 {
        let q = by_radius[k] / by_radius[k + 1];
        assert!((1.6..2.4).contains(&q), "first-order error vs radius {by_radius:?}");
    }
}

/// Signs of eq. (3): F > 0 expands (φ decreases), curvature shrinks a sphere (φ
/// increases by εκ), the rescaling term pulls |∇φ| back to 1, advection moves φ along u.
#[test]
fn eq3_terms_have_the_papers_signs() {
    let r = 12.0;
    let f = sphere(CENTRE, r);
    let g2 = |p: [f64; 3]| 2.0 * f(p); // |∇φ| = 2
    for p in band_voxels(CENTRE, r, 2.5).into_iter().step_by(7) {
        let (b, s) = stencils(&f, p, 1.0, 0.0);
        let w = BoxStarWindow::new(&b, &s);
        let rho = f(p) + r;
        // F = 1 only: S = −|∇φ| ≈ −1, both schemes.
        let s1 = Eq3Rate::<Upwind1, f32>::new(1.0, 1.0, 0.0, 0.0).eval::<f32, _>(&w, 0);
        let s5 = Eq3Rate::<Weno5, f32>::new(1.0, 1.0, 0.0, 0.0).eval::<f32, _>(&w, 0);
        assert!(close(s5 as f64, -1.0, 0.01, 0.0) && s1 < -0.9, "F term {s1} {s5}");
        // F = −1: S = +|∇φ|.
        let sm = Eq3Rate::<Weno5, f32>::new(1.0, -1.0, 0.0, 0.0).eval::<f32, _>(&w, 0);
        assert!(close(sm as f64, 1.0, 0.01, 0.0), "negative F {sm}");
        // ε = 0.5 only: S = εκ|∇φ| = 0.5/ρ.
        let sc = Eq3Rate::<Upwind1, f32>::new(1.0, 0.0, 0.5, 0.0).eval::<f32, _>(&w, 0);
        assert!(close(sc as f64, 0.5 / rho, 0.0, 0.01), "curvature term {sc} vs {}", 0.5 / rho);
        // Rescaling on a distance field: ≈ 0.
        let sr = Eq3Rate::<Weno5, f32>::new(1.0, 0.0, 0.0, 1.0).eval::<f32, _>(&w, 0);
        assert!(sr.abs() < 0.01, "rescaling of a distance field {sr}");
        // Rescaling of 2φ (|∇φ| = 2): S = s(1 − 2) — towards 0 from both sides.
        let (b2, s2) = stencils(&g2, p, 1.0, 0.0);
        let w2 = BoxStarWindow::new(&b2, &s2);
        let phi2 = g2(p) as f32;
        let sr2 = Eq3Rate::<Weno5, f32>::new(1.0, 0.0, 0.0, 1.0).eval::<f32, _>(&w2, 0);
        let sgn = phi2 / (phi2 * phi2 + 1.0).sqrt();
        assert!(close(sr2 as f64, -sgn as f64, 0.01, 0.01), "rescaling of 2φ: {sr2} vs {}", -sgn);
        // One Euler step with F = 1 moves φ by −Δt, clamped to ±γ.
        let step =
            Euler { rate: Eq3Rate::<Weno5, f32>::new(1.0, 1.0, 0.0, 0.0), dt: 0.25, gamma: 3.0 };
        let next = step.eval::<f32, _>(&w, 0);
        let expect = (f(p) - 0.25).clamp(-3.0, 3.0);
        assert!(close(next as f64, expect, 0.005, 0.0), "Euler step {next} vs {expect}");
    }
    // Advection of a linear field is exact with both schemes: −u·∇φ.
    let lin = |p: [f64; 3]| 0.3 * p[0] - 0.7 * p[1] + 0.2 * p[2];
    let (b, s) = stencils(&lin, [1.0, 2.0, 3.0], 0.5, lin([1.0, 2.0, 3.0]));
    let u = [1.5, 0.25, -2.0];
    let expect = -(1.5 * 0.3 - 0.25 * 0.7 - 2.0 * 0.2);
    let w = BoxStarWindow::new(&b, &s);
    let a1 = AdvectionRate::<Upwind1, [f32; 3]>::new(0.5, u).eval::<f32, _>(&w, 0);
    let a5 = AdvectionRate::<Weno5, [f32; 3]>::new(0.5, u).eval::<f32, _>(&w, 0);
    assert!(
        close(a1 as f64, expect, 1e-5, 1e-5) && close(a5 as f64, expect, 1e-5, 1e-5),
        "{a1} {a5} {expect}"
    );
}

/// TVD-RK3 stage combinations integrate y' = −y at third order.
#[test]
fn tvd_rk3_is_third_order() {
    let mut errs = Vec::new();
    for steps in [4, 8, 16] {
        let dt = 1.0 / steps as f32;
        let mut y = 1.0f32;
        for _ in 0..steps {
            let y1 = rk3_combine::<f32, 1>(y, y, dt, -y);
            let y2 = rk3_combine::<f32, 2>(y, y1, dt, -y1);
            y = rk3_combine::<f32, 3>(y, y2, dt, -y2);
        }
        errs.push((y as f64 - (-1.0f64).exp()).abs());
    }
    eprintln!("TVD-RK3 errors {errs:?} orders {:.2?}", orders(&errs));
    for q in orders(&errs) {
        assert!((2.7..3.3).contains(&q), "RK3 errors {errs:?}");
    }
}

#[test]
fn cfl_limits() {
    assert_eq!(cfl_dt_advection(0.0, 1.0, 0.5), f32::INFINITY);
    assert!(close(cfl_dt_advection(4.0, 0.5, 0.5) as f64, 0.0625, 1e-7, 1e-6));
    assert!(close(cfl_dt_normal(2.0, 1.0, 1.0) as f64, 1.0 / (2.0 * 3f64.sqrt()), 1e-7, 1e-6));
    assert!(close(cfl_dt_curvature(0.5, 2.0, 0.9) as f64, 0.9 * 4.0 / 1.5, 1e-7, 1e-6));
    let all = cfl_dt_eq3(2.0, 0.5, 1.0, 1.0, 0.9);
    assert!(all < cfl_dt_normal(3.0, 1.0, 0.9) && all < cfl_dt_curvature(0.5, 1.0, 0.9));
    assert_eq!(cfl_dt_eq3(0.0, 0.0, 0.0, 1.0, 0.9), f32::INFINITY);
}

/// The smoothed delta of eq. (7): zero outside |φ| < ε, integrates to 1, matches the
/// closed form.
#[test]
fn smoothed_delta_matches_eq7() {
    let eps = 1.5f32;
    let mut integral = 0.0f64;
    let n = 3000;
    for k in 0..n {
        let phi = -2.0 + 4.0 * (k as f64 + 0.5) / n as f64;
        let d = smoothed_delta::<f32>(phi as f32, eps) as f64;
        let exact = if phi.abs() < eps as f64 {
            (1.0 + (std::f64::consts::PI * phi / eps as f64).cos()) / (2.0 * eps as f64)
        } else {
            0.0
        };
        assert!(close(d, exact, 1e-6, 1e-5), "δ({phi}) = {d}, eq. (7) gives {exact}");
        integral += d * 4.0 / n as f64;
    }
    assert!(close(integral, 1.0, 1e-4, 0.0), "∫δ = {integral}");
}

/// The HJ-WENO5 weights against the textbook form (αₖ = γₖ/(ε + Sₖ)², ω = α/Σα,
/// ε = 10⁻⁶ max vₖ² + 10⁻⁹⁹) in f64, on random and on rough data.
#[test]
fn weno_matches_textbook_formula() {
    let mut rng = Rng(5);
    for k in 0..20000 {
        let scale = 10f64.powf(rng.range(-6.0, 6.0));
        let v: [f64; 5] = std::array::from_fn(|_| {
            if k % 3 == 0 {
                scale * rng.range(-1.0, 1.0) // rough
            } else {
                scale * (1.0 + 0.05 * rng.range(-1.0, 1.0)) // smooth
            }
        });
        let v32 = v.map(|x| x as f32);
        let got = hj_weno5::<f32>(v32) as f64;
        let w = v32.map(|x| x as f64);
        let p = [
            w[0] / 3.0 - 7.0 * w[1] / 6.0 + 11.0 * w[2] / 6.0,
            -w[1] / 6.0 + 5.0 * w[2] / 6.0 + w[3] / 3.0,
            w[2] / 3.0 + 5.0 * w[3] / 6.0 - w[4] / 6.0,
        ];
        let s = [
            13.0 / 12.0 * (w[0] - 2.0 * w[1] + w[2]).powi(2)
                + 0.25 * (w[0] - 4.0 * w[1] + 3.0 * w[2]).powi(2),
            13.0 / 12.0 * (w[1] - 2.0 * w[2] + w[3]).powi(2) + 0.25 * (w[1] - w[3]).powi(2),
            13.0 / 12.0 * (w[2] - 2.0 * w[3] + w[4]).powi(2)
                + 0.25 * (3.0 * w[2] - 4.0 * w[3] + w[4]).powi(2),
        ];
        let eps = 1e-6 * w.iter().map(|x| x * x).fold(0.0, f64::max) + 1e-99;
        let a =
            [0.1 / (eps + s[0]).powi(2), 0.6 / (eps + s[1]).powi(2), 0.3 / (eps + s[2]).powi(2)];
        let expect = (a[0] * p[0] + a[1] * p[1] + a[2] * p[2]) / (a[0] + a[1] + a[2]);
        let vmax = w.iter().map(|x| x.abs()).fold(0.0, f64::max);
        assert!(close(got, expect, 2e-6 * vmax, 1e-5), "v = {v32:?}: {got} vs textbook {expect}");
    }
    // Flat data: 0, no NaN.
    assert_eq!(hj_weno5::<f32>([0.0; 5]), 0.0);
}

/// Curvature and eq. (3) against the paper's formulas written out literally in f64 on
/// random perturbations of planes (|∇φ| ~ 1).
#[test]
fn curvature_and_speed_match_literal_formulas() {
    let mut rng = Rng(11);
    for _ in 0..5000 {
        let n = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)];
        let h = rng.range(0.3, 2.0);
        let mut b = [0.0f32; 27];
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let x = [dx as f64 * h, dy as f64 * h, dz as f64 * h];
                    let v =
                        n[0] * x[0] + n[1] * x[1] + n[2] * x[2] + 0.2 * h * rng.range(-1.0, 1.0);
                    b[box27_index(dx, dy, dz)] = v as f32;
                }
            }
        }
        let g = |dx: i32, dy: i32, dz: i32| b[box27_index(dx, dy, dz)] as f64;
        // Eq. (4) literally.
        let d = [
            (g(1, 0, 0) - g(-1, 0, 0)) / (2.0 * h),
            (g(0, 1, 0) - g(0, -1, 0)) / (2.0 * h),
            (g(0, 0, 1) - g(0, 0, -1)) / (2.0 * h),
        ];
        let c = g(0, 0, 0);
        let dd = |a: [i32; 3]| (g(a[0], a[1], a[2]) - 2.0 * c + g(-a[0], -a[1], -a[2])) / (h * h);
        let mixed = |a: [i32; 3], bb: [i32; 3]| {
            let at = |sa: i32, sb: i32| {
                g(sa * a[0] + sb * bb[0], sa * a[1] + sb * bb[1], sa * a[2] + sb * bb[2])
            };
            (at(1, 1) - at(1, -1) - at(-1, 1) + at(-1, -1)) / (4.0 * h * h)
        };
        let e = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
        let hess = |i: usize, j: usize| if i == j { dd(e[i]) } else { mixed(e[i], e[j]) };
        let n0 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let mut kappa = 0.0;
        for a in 0..3 {
            let inner: f64 = (0..3).map(|bb| d[bb] * hess(bb, a)).sum();
            kappa += hess(a, a) / n0 - d[a] / n0.powi(3) * inner;
        }
        kappa *= 0.5;
        let w = BoxWindow::new(&b);
        let got = mean_curvature::<f32, _>(&w, (1.0 / h) as f32) as f64;
        let scale = 1.0 / (h * n0.min(1.0)) + kappa.abs();
        assert!(
            close(got, kappa, 1e-5 * scale / n0.powi(2), 1e-4),
            "κ = {got}, eq. (4) gives {kappa}"
        );
        // Eq. (3) as printed in Sec. 4.7, with the smoothed sign.
        let (fspeed, eps) = (rng.range(-2.0, 2.0), rng.range(0.0, 1.0));
        let (dm, dp) = Upwind1::derivatives::<f32, _>(&w, (1.0 / h) as f32);
        let (dm, dp) = (dm.map(|x| x as f64), dp.map(|x| x as f64));
        let sq = |x: f64| x * x;
        let gp = (0..3).map(|a| sq(dm[a].max(0.0)) + sq(dp[a].min(0.0))).sum::<f64>().sqrt();
        let gm = (0..3).map(|a| sq(dp[a].max(0.0)) + sq(dm[a].min(0.0))).sum::<f64>().sqrt();
        let sgn = c / (c * c + h * h).sqrt();
        let s_lit = -(fspeed.max(0.0) * gp + fspeed.min(0.0) * gm)
            + eps * kappa * n0
            + sgn.max(0.0) * (1.0 - gp)
            + sgn.min(0.0) * (1.0 - gm);
        let rate = Eq3Rate::<Upwind1, f32>::new(h as f32, fspeed as f32, eps as f32, 1.0);
        let s_got = rate.eval::<f32, _>(&w, 0) as f64;
        assert!(
            close(s_got, s_lit, 1e-4 * (1.0 + fspeed.abs() + gp + gm), 1e-4),
            "S = {s_got}, Sec. 4.7 gives {s_lit}"
        );
    }
}

/// On a planar lattice (`inv_spacing` 0 along z) the image rate reads the slice alone: its
/// value does not change when every voxel off the slice is NaN, and its curvature term is
/// the three-axis one with the z-axis dropped.
#[test]
fn a_dropped_z_axis_is_not_read() {
    use levelset_kernels::curvature::{curvature_speed_aniso, curvature_speed_planar};
    use levelset_kernels::ImageRate;
    let mut rng = Rng(23);
    for _ in 0..5000 {
        let n = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)];
        let noise = rng.range(0.0, 0.5);
        let (mut b, mut s) =
            stencils(&|p: [f64; 3]| n[0] * p[0] + n[1] * p[1] + n[2] * p[2], [0.0; 3], 1.0, 0.0);
        for v in b.iter_mut().chain(s.iter_mut()) {
            *v += (noise * rng.range(-1.0, 1.0)) as f32;
        }
        // The star's shared points are read from the box.
        s[0] = b[box27_index(0, 0, 0)];
        let inv = [rng.range(0.5, 2.0) as f32, rng.range(0.5, 2.0) as f32, 0.0];
        let (speed, eps) = (rng.range(-2.0, 2.0) as f32, rng.range(0.0, 1.0) as f32);
        let u = [rng.range(-1.0, 1.0) as f32, rng.range(-1.0, 1.0) as f32, 0.0];
        let rate = ImageRate::<Weno5, f32, f32, [f32; 3]>::new(speed, eps, Some(u), 1.0, inv, 1.0);
        let w = BoxStarWindow::new(&b, &s);
        let full = rate.eval::<f32, _>(&w, 0);
        let k3 = curvature_speed_aniso::<f32, _>(&w, inv);
        let k2 = curvature_speed_planar::<f32, _>(&w, [inv[0], inv[1]]);
        assert!(k2 == k3, "planar curvature {k2} against {k3} with z dropped");
        for dz in [-1, 1] {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    b[box27_index(dx, dy, dz)] = f32::NAN;
                }
            }
        }
        for dz in [-3, -2, 2, 3] {
            s[star19_index(0, 0, dz)] = f32::NAN;
        }
        let sliced = rate.eval::<f32, _>(&BoxStarWindow::new(&b, &s), 0);
        assert!(full.is_finite() && full.to_bits() == sliced.to_bits(), "{full} against {sliced}");
    }
}
