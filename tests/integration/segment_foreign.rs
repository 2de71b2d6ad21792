//! Segmentation on images that `levelset phantom` did not make, with the conventions of
//! other tools: intensities 0–1 with blurred edges (and the same image scaled and offset),
//! open threshold windows, leaks, shrinking from a larger region, a feature image of the
//! user's own, a placement that flips an axis, and anisotropic spacing. The images come
//! from a generator of this file: an indicator on the voxel centres, blurred by the
//! binomial kernel [1, 2, 1]/4 along each axis, plus Gaussian noise from `fastrand`, every
//! intensity rounded to a multiple of 1/1024 so that 1000·I − 500 is exact in `f32`.

use sparse_levelset::io::image::{Image, IDENTITY};
use sparse_levelset::segment::metrics::dice;
use sparse_levelset::segment::{segment, Init, Method, Params, Seed, Segmentation, Stop};
use sparse_levelset::tools::measure::measure;
use std::sync::Arc;

/// A blurred, noisy image of `inside` (world positions) on `dims` voxels of `spacing`.
fn image(
    dims: [usize; 3],
    spacing: [f64; 3],
    sigma_noise: f64,
    seed: u64,
    inside: impl Fn([f64; 3]) -> bool,
) -> (Image, Vec<u8>) {
    let [nx, ny, nz] = dims;
    let idx = |x: usize, y: usize, z: usize| x + nx * (y + ny * z);
    let mut truth = vec![0u8; nx * ny * nz];
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let p = [x as f64 * spacing[0], y as f64 * spacing[1], z as f64 * spacing[2]];
                truth[idx(x, y, z)] = inside(p) as u8;
            }
        }
    }
    let mut v: Vec<f64> = truth.iter().map(|&t| t as f64).collect();
    for (axis, stride) in [(0, 1), (1, nx), (2, nx * ny)] {
        let n = dims[axis];
        let old = v.clone();
        for (i, out) in v.iter_mut().enumerate() {
            let k = (i / stride) % n;
            let lo = if k > 0 { old[i - stride] } else { old[i] };
            let hi = if k + 1 < n { old[i + stride] } else { old[i] };
            *out = 0.25 * lo + 0.5 * old[i] + 0.25 * hi;
        }
    }
    let mut rng = fastrand::Rng::with_seed(seed);
    let data = v
        .iter()
        .map(|&c| {
            let (u1, u2) = (rng.f64().max(1e-300), rng.f64());
            let n = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            ((c + sigma_noise * n) * 1024.0).round() as f32 / 1024.0
        })
        .collect();
    (Image { dims, spacing, data, to_world: IDENTITY }, truth)
}

/// An n³ image of unit voxels whose clean intensity and truth `f` gives at each voxel
/// centre, plus uniform noise of width `noise` (no blur).
fn piecewise(
    n: usize,
    noise: f64,
    seed: u64,
    f: impl Fn([f64; 3]) -> (f64, bool),
) -> (Image, Vec<u8>) {
    let mut rng = fastrand::Rng::with_seed(seed);
    let (mut data, mut truth) = (Vec::with_capacity(n * n * n), Vec::with_capacity(n * n * n));
    for i in 0..n * n * n {
        let (clean, inside) = f([(i % n) as f64, ((i / n) % n) as f64, (i / (n * n)) as f64]);
        truth.push(inside as u8);
        data.push((clean + noise * (rng.f64() - 0.5)) as f32);
    }
    (Image { dims: [n; 3], spacing: [1.0; 3], data, to_world: IDENTITY }, truth)
}

fn ball(c: [f64; 3], r: f64) -> impl Fn([f64; 3]) -> bool {
    move |p| (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>() <= r * r
}

fn seeds(list: &[([f64; 3], f64)]) -> Init {
    Init::Seeds {
        seeds: list.iter().map(|&(center, radius)| Seed { center, radius }).collect(),
        world: false,
    }
}

fn run(im: &Image, init: &Init, params: &Params) -> Segmentation {
    segment(im, init, params, &mut |_| true).unwrap()
}

fn scaled(im: &Image) -> Image {
    Image { data: im.data.iter().map(|&v| 1000.0 * v - 500.0).collect(), ..im.clone() }
}

#[test]
fn a_scaled_and_offset_image_gives_the_same_mask() {
    let (im, truth) = image([40, 40, 40], [1.0; 3], 0.3, 1, ball([20.0, 19.0, 21.0], 11.0));
    let big = scaled(&im);
    let init = seeds(&[([20.0, 19.0, 21.0], 3.0)]);
    for (m, m_big) in [
        (
            Method::Threshold { lower: 0.5, upper: f32::INFINITY },
            Method::Threshold { lower: 0.0, upper: f32::INFINITY },
        ),
        (Method::Gac, Method::Gac),
        (Method::chan_vese(), Method::chan_vese()),
    ] {
        let a = run(&im, &init, &Params::new(m));
        let b = run(&big, &init, &Params::new(m_big));
        let d = dice(&a.mask, &truth).unwrap();
        assert!(d > 0.95, "{}: Dice {d} ({:?})", m.name(), a.report.stop);
        assert!(a.mask == b.mask, "{}: the masks of I and 1000 I − 500 differ", m.name());
        assert_eq!(a.report.iterations, b.report.iterations);
        // The defaults are reported in the image's own units.
        let (n, n_big) = (a.report.params.noise, b.report.params.noise);
        assert!((n_big / n - 1000.0).abs() < 1e-6 * 1000.0, "noise {n} vs {n_big}");
        assert!((n - 0.3).abs() < 0.03, "noise estimate {n}, generated 0.3");
    }
}

#[test]
fn an_open_window_segments_the_object() {
    let (im, truth) = image([40, 40, 40], [1.0; 3], 0.25, 2, ball([20.0, 20.0, 20.0], 12.0));
    let init = seeds(&[([20.0, 20.0, 20.0], 3.0)]);
    let open =
        run(&im, &init, &Params::new(Method::Threshold { lower: 0.5, upper: f32::INFINITY }));
    let far = run(&im, &init, &Params::new(Method::Threshold { lower: 0.5, upper: 1e6 }));
    let d = dice(&open.mask, &truth).unwrap();
    assert!(
        d > 0.95,
        "open window: Dice {d}, {} voxels ({:?})",
        open.report.voxels,
        open.report.stop
    );
    assert!(open.mask == far.mask, "an upper bound far beyond the data acts as an open one");
    // Open below: the dark background around the object, seeded in a corner.
    let dark = run(
        &im,
        &seeds(&[([3.0, 3.0, 3.0], 2.0)]),
        &Params {
            leak_guard: false,
            ..Params::new(Method::Threshold { lower: f32::NEG_INFINITY, upper: 0.5 })
        },
    );
    let outside: Vec<u8> = truth.iter().map(|&t| 1 - t).collect();
    let d = dice(&dark.mask, &outside).unwrap();
    assert!(d > 0.98, "window open below: Dice {d}");
    // Both ends open is no window.
    let both = Method::Threshold { lower: f32::NEG_INFINITY, upper: f32::INFINITY };
    assert!(segment(&im, &init, &Params::new(both), &mut |_| true).is_err());
}

/// A bright shell with a hole, seeded in its dark cavity: every flow leaves through the
/// hole, and the run must say so.
#[test]
fn a_front_through_a_gap_is_reported_as_leaked() {
    let c = [24.0; 3];
    let shell = move |p: [f64; 3]| {
        let r = (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>().sqrt();
        let hole = p[0] > c[0] && (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2) < 25.0;
        (15.0..=18.0).contains(&r) && !hole
    };
    let (im, _) = image([48, 48, 48], [1.0; 3], 0.25, 3, shell);
    let init = seeds(&[(c, 4.0)]);
    let s = run(&im, &init, &Params::new(Method::Gac));
    assert_eq!(s.report.stop, Stop::Leaked, "{} voxels", s.report.voxels);
    let why = s.report.leak.clone().unwrap();
    assert!(why.contains("face"), "{why}");
    // With the guard off, the run goes on and fills the cavity's outside too.
    let off = run(
        &im,
        &init,
        &Params { leak_guard: false, max_iterations: 300, ..Params::new(Method::Gac) },
    );
    assert_ne!(off.report.stop, Stop::Leaked);
    assert!(off.report.voxels > s.report.voxels);
    // Chan–Vese in the cavity: its region has the background's intensity; it leaks out
    // or ends without telling anything apart, and the report says so either way.
    let cv = run(&im, &init, &Params::new(Method::chan_vese()));
    assert!(
        cv.report.stop == Stop::Leaked || cv.report.weak_contrast.is_some(),
        "{:?} {:?}",
        cv.report.stop,
        cv.report.means
    );
    // Closed and noisier (SNR 2): no way out, and the region's mean ends within a noise
    // level or two of the outside's.
    let closed = move |p: [f64; 3]| {
        let r = (0..3).map(|a| (p[a] - 32.0).powi(2)).sum::<f64>().sqrt();
        (20.0..=24.0).contains(&r)
    };
    let (im, _) = image([64, 64, 64], [1.0; 3], 0.5, 3, closed);
    let cv = run(&im, &seeds(&[([32.0; 3], 4.0)]), &Params::new(Method::chan_vese()));
    assert_ne!(cv.report.stop, Stop::Leaked);
    assert!(cv.report.weak_contrast.is_some(), "{:?}", cv.report.means);
}

/// A stretch of edge too gradual for the edge potential, as between white matter and
/// the deep grey nuclei of a brain: a ball of 1 on 0 whose edge, inside a square channel
/// to the image's +x face, falls over 8 voxels to a plateau of 0.3. ITK's plain balloon
/// runs down the ramp and along the channel to the face; the default balloon turns at the
/// first edge's level (0.5) and stops there.
#[test]
fn gac_stops_at_the_first_edges_level_where_the_edge_is_weak() {
    let (c, r) = (20.0f64, 10.0f64);
    let (im, truth) = piecewise(48, 0.05, 9, |[px, py, pz]| {
        let rho2 = (py - c).powi(2) + (pz - c).powi(2);
        let in_channel = px > c && (py - c).abs() < 5.0 && (pz - c).abs() < 5.0;
        let clean = if (px - c).powi(2) + rho2 <= r * r {
            1.0
        } else if in_channel {
            let surface = c + (r * r - rho2).max(0.0).sqrt();
            (1.0 - 0.7 * (px - surface) / 8.0).max(0.3)
        } else {
            0.0
        };
        (clean, clean > 0.5)
    });
    let init = seeds(&[([c; 3], 4.0)]);
    let plain = run(&im, &init, &Params { first_edge: false, ..Params::new(Method::Gac) });
    assert_eq!(plain.report.stop, Stop::Leaked, "{} voxels", plain.report.voxels);
    let s = run(&im, &init, &Params::new(Method::Gac));
    assert_ne!(s.report.stop, Stop::Leaked);
    let level = s.report.params.edge_level.unwrap();
    assert!((level - 0.5).abs() < 0.1, "edge level {level}");
    let d = dice(&s.mask, &truth).unwrap();
    assert!(d > 0.95, "Dice {d}, {} voxels, {:?}", s.report.voxels, s.report.stop);
}

/// Three tissues, as white matter, grey matter and the rest of a head: a bright ball (1)
/// in a shell of 0.6 on a dark background (0). The textbook Chan–Vese from seeds in the
/// ball takes ball and shell (the whole outside's mean is near 0); by default its outside
/// mean is the neighbouring tissue's, and it takes the ball.
#[test]
fn chan_vese_competes_with_the_neighbouring_tissue() {
    let c = 24.0f64;
    let (im, truth) = piecewise(48, 0.1, 5, |p| {
        let r = p.iter().map(|&q| (q - c).powi(2)).sum::<f64>().sqrt();
        let clean = if r <= 9.0 {
            1.0
        } else if r <= 15.0 {
            0.6
        } else {
            0.0
        };
        (clean, r <= 9.0)
    });
    let init = seeds(&[([c; 3], 3.0)]);
    let textbook =
        run(&im, &init, &Params { first_edge: false, ..Params::new(Method::chan_vese()) });
    let d = dice(&textbook.mask, &truth).unwrap();
    assert!(d < 0.6, "the textbook Chan–Vese: Dice {d}");
    let s = run(&im, &init, &Params::new(Method::chan_vese()));
    let d = dice(&s.mask, &truth).unwrap();
    assert!(d > 0.97, "Dice {d}, {} voxels, {:?}", s.report.voxels, s.report.stop);
    assert_eq!(s.report.weak_contrast, None);
}

/// ITK's negative propagation: a large initial region shrinks onto the object.
#[test]
fn a_negative_propagation_shrinks_onto_the_object() {
    let (im, truth) = image([40, 40, 40], [1.0; 3], 0.2, 4, ball([20.0, 20.0, 20.0], 9.0));
    let [nx, ny, _] = im.dims;
    let mask: Vec<u8> = (0..im.len())
        .map(|i| {
            let p = [i % nx, (i / nx) % ny, i / (nx * ny)];
            p.iter().all(|&q| (4..36).contains(&q)) as u8
        })
        .collect();
    let params = Params { propagation: Some(-1.0), ..Params::new(Method::Gac) };
    let s = run(&im, &Init::Mask(mask.clone()), &params);
    let d = dice(&s.mask, &truth).unwrap();
    assert!(
        d > 0.9,
        "Dice {d} after {} steps ({:?}), {} voxels",
        s.report.iterations,
        s.report.stop,
        s.report.voxels
    );
    // The fast start sweeps the region's flat part first: the same mask in fewer steps.
    let inside = mask.iter().filter(|&&m| m != 0).count() as u64;
    let start = s.report.params.start_voxels.expect("a shrinking fast start");
    assert!(start < inside / 2, "the start keeps {start} of {inside} voxels");
    let slow = run(&im, &Init::Mask(mask), &Params { fast_start: false, ..params.clone() });
    let d_slow = dice(&slow.mask, &truth).unwrap();
    assert!((d - d_slow).abs() < 0.01, "Dice {d} from the fast start, {d_slow} without");
    assert!(
        s.report.iterations * 4 < slow.report.iterations * 3,
        "{} steps from the fast start, {} without",
        s.report.iterations,
        slow.report.iterations
    );
    let cv = Params { propagation: Some(-1.0), ..Params::new(Method::chan_vese()) };
    assert!(segment(&im, &seeds(&[([20.0; 3], 3.0)]), &cv, &mut |_| true).is_err());
}

#[test]
fn a_feature_image_replaces_the_intensities() {
    let (im, _) = image([32, 32, 32], [1.0; 3], 0.2, 5, ball([16.0; 3], 9.0));
    let init = seeds(&[([16.0; 3], 3.0)]);
    let m = Method::Threshold { lower: 0.5, upper: f32::INFINITY };
    let plain = run(&im, &init, &Params { sigma: Some(0.0), ..Params::new(m) });
    let feature = Arc::new(im.clone());
    let flat = Image { data: vec![0.0; im.len()], ..im.clone() };
    let with =
        run(&flat, &init, &Params { sigma: Some(0.0), feature: Some(feature), ..Params::new(m) });
    assert!(plain.mask == with.mask);
    // GAC's feature is the edge potential itself: g = 1 everywhere but a wall at x = 20.
    let wall = Image {
        data: (0..im.len())
            .map(|i| if (19..=21).contains(&(i % 32)) { 0.0 } else { 1.0 })
            .collect(),
        ..im.clone()
    };
    let params = Params {
        feature: Some(Arc::new(wall)),
        leak_guard: false,
        max_iterations: 400,
        ..Params::new(Method::Gac)
    };
    let s = run(&flat, &seeds(&[([10.0, 16.0, 16.0], 3.0)]), &params);
    let beyond = (0..im.len()).filter(|&i| i % 32 > 22 && s.mask[i] == 1).count();
    assert_eq!(beyond, 0, "the front crossed the user's wall");
    assert!(s.report.voxels > 5000, "{} voxels", s.report.voxels);
}

/// NIfTI files often flip an axis (a negative determinant): the mesh must stay outward
/// with a positive volume, in world millimetres.
#[test]
fn a_flipped_placement_gives_an_outward_mesh_in_world_coordinates() {
    let (mut im, truth) = image([36, 36, 36], [1.0; 3], 0.2, 6, ball([15.0, 18.0, 19.0], 9.0));
    im.to_world = [[-1.0, 0.0, 0.0, 100.0], [0.0, 1.0, 0.0, -20.0], [0.0, 0.0, 1.0, 5.0]];
    let s = run(&im, &seeds(&[([15.0, 18.0, 19.0], 3.0)]), &Params::new(Method::chan_vese()));
    assert!(dice(&s.mask, &truth).unwrap() > 0.95);
    let mesh = s.mesh(&im).unwrap();
    let mut volume = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        volume += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))
            / 6.0;
    }
    let want = 4.0 / 3.0 * std::f64::consts::PI * 729.0;
    assert!(
        volume > 0.0 && (volume / want - 1.0).abs() < 0.06,
        "signed volume {volume}, ball {want}"
    );
    let n = mesh.positions.len() as f64;
    let centroid: [f64; 3] =
        std::array::from_fn(|a| mesh.positions.iter().map(|p| p[a]).sum::<f64>() / n);
    let world = [100.0 - 15.0, 18.0 - 20.0, 19.0 + 5.0];
    for a in 0..3 {
        assert!((centroid[a] - world[a]).abs() < 0.3, "centroid {centroid:?}, world {world:?}");
    }
    let outward = mesh
        .positions
        .iter()
        .zip(&mesh.normals)
        .filter(|(p, nrm)| (0..3).map(|a| (p[a] - centroid[a]) * nrm[a] as f64).sum::<f64>() > 0.0)
        .count();
    assert_eq!(outward, mesh.positions.len(), "every normal points away from the centre");
}

#[test]
fn an_anisotropic_level_set_measures_the_world_volume() {
    let spacing = [1.0, 1.0, 2.5];
    let ellipsoid = |p: [f64; 3]| {
        ((p[0] - 20.0) / 12.0).powi(2)
            + ((p[1] - 20.0) / 9.0).powi(2)
            + ((p[2] - 30.0) / 18.0).powi(2)
            <= 1.0
    };
    let (im, truth) = image([40, 40, 24], spacing, 0.2, 7, ellipsoid);
    let s = run(&im, &seeds(&[([20.0, 20.0, 12.0], 3.0)]), &Params::new(Method::chan_vese()));
    assert!(dice(&s.mask, &truth).unwrap() > 0.95);
    let mask_volume = s.mask.iter().map(|&m| m as f64).sum::<f64>() * 2.5;
    let ls = s.level_set(&im).unwrap();
    assert_eq!(ls.spec().voxel_size, 1.0);
    let m = measure(&ls, &Default::default()).unwrap();
    assert!(
        (m.volume / mask_volume - 1.0).abs() < 0.01,
        "level set {} mm³, mask {mask_volume} mm³",
        m.volume
    );
}

/// The fast start (on by default) gives the region that the seeds' balls give, in fewer
/// steps: a blurred, noisy torus seeded at one point of its ring, and a ball joined to a
/// second one by a channel of three voxels, narrower than GAC's fill passes. Threshold
/// and GAC obey the comparison principle; Chan–Vese (whose means move) is held to the
/// same tolerance.
#[test]
fn the_fast_start_gives_the_seeds_region_in_fewer_steps() {
    let torus = |p: [f64; 3]| {
        let rho = ((p[0] - 24.0).powi(2) + (p[1] - 24.0).powi(2)).sqrt() - 14.0;
        rho * rho + (p[2] - 24.0).powi(2) <= 49.0
    };
    let (ring, ring_truth) = image([48, 48, 48], [1.0; 3], 0.25, 21, torus);
    let dumbbell = |p: [f64; 3]| {
        let channel = (p[1] - 24.0).abs() <= 1.0 && (p[2] - 24.0).abs() <= 1.0;
        ball([14.0, 24.0, 24.0], 8.0)(p)
            || ball([34.0, 24.0, 24.0], 8.0)(p)
            || (channel && (14.0..=34.0).contains(&p[0]))
    };
    let (pair, pair_truth) = image([48, 48, 48], [1.0; 3], 0.1, 22, dumbbell);
    let cases = [
        (&ring, &ring_truth, seeds(&[([38.0, 24.0, 24.0], 3.0)])),
        (&pair, &pair_truth, seeds(&[([14.0, 24.0, 24.0], 3.0)])),
    ];
    let threshold = Method::Threshold { lower: 0.5, upper: f32::INFINITY };
    for (case, (im, truth, init)) in cases.iter().enumerate() {
        for method in [threshold, Method::Gac, Method::chan_vese()] {
            let fast = run(im, init, &Params::new(method));
            let balls = run(im, init, &Params { fast_start: false, ..Params::new(method) });
            let what = format!("case {case}, {}", method.name());
            let start = fast.report.params.start_voxels.unwrap_or(0);
            assert!(balls.report.params.start_voxels.is_none(), "{what}");
            // More than the seed's ball (113 voxels), less than the answer.
            assert!(start > 500 && start < fast.report.voxels, "{what}: start {start}");
            let differ = fast.mask.iter().zip(&balls.mask).filter(|(a, b)| a != b).count();
            let object = truth.iter().filter(|&&t| t != 0).count();
            assert!(differ * 200 <= object, "{what}: {differ} voxels differ of {object}");
            let (d_fast, d_balls) =
                (dice(&fast.mask, truth).unwrap(), dice(&balls.mask, truth).unwrap());
            assert!((d_fast - d_balls).abs() <= 0.003, "{what}: Dice {d_fast} against {d_balls}");
            let far_ball = fast.mask[34 + 48 * (24 + 48 * 24)];
            match (case, method) {
                // Around the ring from one point against a few voxels out from its core.
                (0, _) => assert!(
                    d_fast > 0.98 && 3 * fast.report.iterations <= balls.report.iterations,
                    "{what}: Dice {d_fast}, {} steps against {}",
                    fast.report.iterations,
                    balls.report.iterations
                ),
                // GAC's curvature closes the channel, from either start.
                (_, Method::Gac) => assert_eq!(far_ball, 0, "{what}"),
                // The others cross it, from either start.
                _ => assert!(far_ball == 1 && d_fast > 0.98, "{what}: Dice {d_fast}"),
            }
        }
    }
}

/// An initial region that meets the image's faces (a mask from another tool, cut at the
/// image's edge) is closed there: nothing beyond the image is inside at the start, so the
/// run ends where the same start a voxel inside the image ends, and the region's volume and
/// mean, which the stopping test and Chan–Vese's force read every step, count the inside
/// up to the faces. In 2-D (two discs; the mask a rectangle from x = 0 around the first,
/// the whole rows 30–89 across both, or the whole image) and 3-D (a ball, the mask a slab from the x = 0
/// face), on one thread and two: Dice at least 0.98 against the objects the start holds,
/// and at least 0.99 against the result of the start without its voxels on the faces.
/// Without the closing, the region went on beyond the face and held the rows it crossed
/// there: the first start took the second disc as well (Dice 0.80 against the start a voxel
/// in).
#[test]
fn an_initial_region_that_meets_the_faces_segments_the_object() {
    let first = ball([40.0, 60.0, 0.0], 35.0);
    let second = ball([120.0, 60.0, 0.0], 25.0);
    let (flat, both) = image([160, 120, 1], [1.0; 3], 0.3, 11, |p| first(p) || second(p));
    let disc: Vec<u8> =
        (0..flat.len()).map(|i| first([(i % 160) as f64, (i / 160) as f64, 0.0]) as u8).collect();
    let (vol, vol_truth) = image([48, 40, 36], [1.0; 3], 0.3, 12, ball([20.0, 20.0, 18.0], 12.0));
    let box_mask = |im: &Image, lo: [usize; 3], hi: [usize; 3]| -> Vec<u8> {
        let [nx, ny, _] = im.dims;
        (0..im.len())
            .map(|i| {
                let p = [i % nx, (i / nx) % ny, i / (nx * ny)];
                (0..3).all(|a| (lo[a]..hi[a]).contains(&p[a])) as u8
            })
            .collect()
    };
    // (name, image, the objects the start holds, the start, the start a voxel in)
    let cases = [
        (
            "2-D, from x = 0",
            &flat,
            &disc,
            box_mask(&flat, [0, 30, 0], [60, 90, 1]),
            box_mask(&flat, [1, 30, 0], [60, 90, 1]),
        ),
        (
            "2-D, whole rows",
            &flat,
            &both,
            box_mask(&flat, [0, 30, 0], [160, 90, 1]),
            box_mask(&flat, [1, 30, 0], [159, 90, 1]),
        ),
        (
            "2-D, the whole image",
            &flat,
            &both,
            box_mask(&flat, [0, 0, 0], [160, 120, 1]),
            box_mask(&flat, [1, 1, 0], [159, 119, 1]),
        ),
        (
            "3-D, from x = 0",
            &vol,
            &vol_truth,
            box_mask(&vol, [0, 10, 8], [30, 30, 28]),
            box_mask(&vol, [1, 10, 8], [30, 30, 28]),
        ),
    ];
    for (name, im, truth, mask, inward) in cases {
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let params = Params {
                leak_guard: false,
                pool: Some(Arc::new(pool)),
                ..Params::new(Method::chan_vese())
            };
            let s = run(im, &Init::Mask(mask.clone()), &params);
            let d = dice(&s.mask, truth).unwrap();
            assert!(d >= 0.98, "{name}, {threads} threads: Dice {d} ({:?})", s.report.stop);
            let t = run(im, &Init::Mask(inward.clone()), &params);
            let d = dice(&s.mask, &t.mask).unwrap();
            assert!(d >= 0.99, "{name}, {threads} threads: Dice {d} against the start a voxel in");
        }
    }
    // GAC shrinking from the whole image (scikit-image's `init_level_set=np.ones(...)`),
    // which was refused (every tile was interior), ends where it ends from a voxel in, with
    // both discs (the first edge inward holds the balloon at them).
    let params = Params { propagation: Some(-1.0), ..Params::new(Method::Gac) };
    let s = run(&flat, &Init::Mask(vec![1u8; flat.len()]), &params);
    let t = run(&flat, &Init::Mask(box_mask(&flat, [1, 1, 0], [159, 119, 1])), &params);
    let d = dice(&s.mask, &t.mask).unwrap();
    let found = dice(&s.mask, &both).unwrap();
    assert!(
        d >= 0.99 && found >= 0.98,
        "GAC from the whole image: Dice {d} against a voxel in, {found} against the discs"
    );
}

/// GAC shrinking from a start that cuts a flat object (scikit-image's `coins` recipe: a
/// rectangle some pixels in, or the whole image, where the object meets the image's edge):
/// rays from the start's boundary find the first edge inward, and beyond its level the
/// balloon turns outward, so the front that starts inside the object holds there instead of
/// eating the object from within. An ellipse cut by the x = 0 face and a disc, in noise of
/// σ = 0.4 for unit contrast, from the rectangle 5 pixels in: Dice at least 0.88 (ITK's
/// plain balloon, `first_edge: false`, ends at 0.39 on this image: it ate the ellipse), and
/// from the whole image, whose boundary in array order is two voxels a row (the rays' origins
/// must not all fall on one side). The ellipse reaches the face x = 0, where the start does
/// not: the region reaching it is no leak.
#[test]
fn a_shrinking_front_does_not_eat_an_object_its_start_cuts() {
    let ellipse =
        |p: [f64; 3]| ((p[0] - 20.0) / 50.0).powi(2) + ((p[1] - 50.0) / 30.0).powi(2) < 1.0;
    let disc = ball([105.0, 50.0, 0.0], 15.0);
    let (im, truth) = image([140, 100, 1], [1.0; 3], 0.4, 21, |p| ellipse(p) || disc(p));
    shrinks_from_boxes(&im, &truth, &[5, 0], 0.88);
}

/// A noisy 3-D phantom (contrast 1, noise σ = 0.4) shrunk onto from the whole image and from
/// a box 3 voxels in: three objects of a few per cent of the view each, a rod among them
/// through the face x = 0. The rays from the start's boundary estimate the smoothing, the
/// sigmoid and the first edge (Dice 0.962 and 0.951; from the start's deepest voxel, in the
/// background, they found no edge, and both runs ended at 0.881).
#[test]
fn a_noisy_volume_shrinks_onto_its_objects() {
    let ellipsoid = |p: [f64; 3]| {
        ((p[0] - 44.0) / 12.0).powi(2)
            + ((p[1] - 22.0) / 7.0).powi(2)
            + ((p[2] - 30.0) / 9.0).powi(2)
            < 1.0
    };
    let rod = |p: [f64; 3]| p[0] < 30.0 && (p[1] - 50.0).powi(2) + (p[2] - 14.0).powi(2) < 16.0;
    let ball = ball([20.0, 40.0, 36.0], 10.0);
    let (im, truth) = image([64; 3], [1.0; 3], 0.4, 7, |p| ball(p) || ellipsoid(p) || rod(p));
    shrinks_from_boxes(&im, &truth, &[0, 3], 0.95);
}

/// GAC with β = −1 from the box `inset` voxels in from every face (of the axes with more
/// than one voxel), for each inset: Dice at least `min_dice`, and no leak.
fn shrinks_from_boxes(im: &Image, truth: &[u8], insets: &[usize], min_dice: f64) {
    let [nx, ny, nz] = im.dims;
    for &inset in insets {
        let within = |q: usize, n: usize| n == 1 || (inset..n - inset).contains(&q);
        let start: Vec<u8> = (0..im.len())
            .map(|i| {
                let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
                (within(x, nx) && within(y, ny) && within(z, nz)) as u8
            })
            .collect();
        let params = Params { propagation: Some(-1.0), ..Params::new(Method::Gac) };
        let s = run(im, &Init::Mask(start), &params);
        let d = dice(&s.mask, truth).unwrap();
        assert!(
            d >= min_dice && s.report.leak.is_none(),
            "inset {inset}: Dice {d} ({:?}, edge level {:?})",
            s.report.stop,
            s.report.params.edge_level
        );
    }
}
