//! Ray-traced images of level sets (Houston et al. 2006, Sec. 6.3): the silhouette and depth of a
//! sphere against the analytic sphere, bitwise identity across thread counts and between
//! the two grids, the PNG round trip, and errors on bad input (library and CLI).

use sparse_levelset::grid::GridSpec;
use sparse_levelset::storage::convert::{dtgrid_from, tiles_from_dense, tiles_from_shape};
use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::storage::tiles::TileGrid;
use sparse_levelset::tools::render::{self, FrameBox, Image, RenderError, RenderOptions};
use sparse_levelset::Coord;

use crate::common::tmp;

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
}

/// A sphere off the grid's axes and origin, at negative coordinates, with voxel size 0.5:
/// primary rays through the pixel centres hit the rendered level set exactly where they
/// hit the analytic sphere, except in a thin ring around the analytic silhouette, and
/// the hit distances agree to 0.05 voxel.
#[test]
fn sphere_silhouette_and_depth_match_the_analytic_sphere() {
    let h = 0.5;
    let spec = GridSpec::new(h as f32, [0.25, -0.5, 1.0], 3.0).unwrap();
    let (c, r) = ([-3.3, 2.1, -1.7], 9.7);
    let tiles = tiles_from_shape(&Shape::Sphere { center: c, radius: r }, spec).unwrap();
    let opts = RenderOptions {
        width: 160,
        height: 120,
        samples: 1,
        ground: false,
        shadows: false,
        azimuth_deg: 23.0,
        elevation_deg: 17.0,
        ..Default::default()
    };
    let image = render::render(&tiles, &opts).unwrap();
    let cam = *image.camera();
    // The trilinear interpolant of the sampled distance deviates from the sphere by about
    // h²/(8 r) per voxel² of curvature (< 0.01 voxel here); allow 0.02 voxel absolute plus
    // 1e-6 relative to the distance from the eye.
    let ring = 0.02 * h;
    let (mut hits, mut mismatched, mut in_ring, mut max_depth_err) = (0, 0, 0, 0.0f64);
    for y in 0..opts.height {
        for x in 0..opts.width {
            let d = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
            let oc = sub(c, cam.eye);
            let along = dot(oc, d);
            let miss2 = (dot(oc, oc) - along * along).max(0.0);
            let dist = miss2.sqrt();
            let analytic = dist < r;
            let tol = ring + 1e-6 * along;
            in_ring += ((dist - r).abs() <= tol) as usize;
            let got = image.depth(x, y);
            if got.is_some() != analytic {
                mismatched += 1;
                assert!(
                    (dist - r).abs() <= tol,
                    "pixel ({x}, {y}) misclassified {:.4} voxel from the silhouette",
                    (dist - r) / h
                );
            }
            if let (Some(t), true) = (got, dist < 0.9 * r) {
                hits += 1;
                let exact = along - (r * r - miss2).sqrt();
                max_depth_err = max_depth_err.max((t - exact).abs() / h);
            }
        }
    }
    assert!(hits > 2000, "the sphere covers a good part of the image: {hits} pixels");
    assert!(mismatched <= in_ring, "{mismatched} mismatches, {in_ring} pixels in the ring");
    assert!(max_depth_err < 0.05, "depth error {max_depth_err} voxel away from the rim");
    // The centre pixel in particular.
    let (x, y) = (opts.width / 2, opts.height / 2);
    let d = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
    let oc = sub(c, cam.eye);
    let along = dot(oc, d);
    let exact = along - (r * r - (dot(oc, oc) - along * along)).sqrt();
    let err = (image.depth(x, y).expect("the centre ray hits") - exact).abs() / h;
    assert!(err < 0.05, "centre depth off by {err} voxel");
    eprintln!("sphere: {mismatched} mismatched pixels, max depth error {max_depth_err:.5} voxel");
}

fn torus_tiles() -> TileGrid {
    let shape = Shape::Torus { center: [1.5, -2.0, 0.5], major_radius: 14.0, minor_radius: 4.5 };
    tiles_from_shape(&shape, GridSpec::default()).unwrap()
}

/// Full shading (ground, shadows, 2×2 sub-pixels): one thread and two threads give the
/// same bytes, and so do the tiles and the DT-Grid of the same band.
#[test]
fn images_are_bitwise_identical_across_threads_and_grids() {
    let tiles = torus_tiles();
    let dt = dtgrid_from(&tiles);
    let opts = RenderOptions { width: 120, height: 90, ..Default::default() };
    let one = in_pool(1, || render::render(&tiles, &opts).unwrap());
    let two = in_pool(2, || render::render(&tiles, &opts).unwrap());
    let dt2 = in_pool(2, || render::render(&dt, &opts).unwrap());
    assert!(one.rgb() == two.rgb(), "1 vs 2 threads");
    assert!(one.rgb() == dt2.rgb(), "tiles vs DT-Grid");
    // Depths too, bit for bit.
    for y in 0..opts.height {
        for x in 0..opts.width {
            let bits = |i: &Image| i.depth(x, y).map(f64::to_bits);
            assert_eq!(bits(&one), bits(&two));
            assert_eq!(bits(&one), bits(&dt2));
        }
    }
    // The image is not trivial: sky, ground, lit and shadowed parts give many colours.
    let mut colours: Vec<[u8; 3]> = one.rgb().chunks(3).map(|p| [p[0], p[1], p[2]]).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() > 100, "{} distinct colours", colours.len());
}

/// A fixed frame box keeps the camera where it is whatever the level set: the same box
/// gives the same camera for two different grids.
#[test]
fn a_frame_box_fixes_the_camera() {
    let frame = FrameBox { lo: [-20.0, -20.0, -10.0], hi: [20.0, 20.0, 10.0] };
    let opts = RenderOptions {
        width: 40,
        height: 30,
        samples: 1,
        frame: Some(frame),
        ..Default::default()
    };
    let a = render::render(&torus_tiles(), &opts).unwrap();
    let small = Shape::Sphere { center: [0.0; 3], radius: 5.0 };
    let b = render::render(&tiles_from_shape(&small, GridSpec::default()).unwrap(), &opts).unwrap();
    assert_eq!(a.camera(), b.camera());
    assert_ne!(a.rgb(), b.rgb());
}

/// The written PNG decodes (png crate) to the same size and pixels, and no temporary file
/// is left next to it.
#[test]
fn png_round_trip() {
    let opts = RenderOptions { width: 33, height: 21, ..Default::default() };
    let image = render::render(&torus_tiles(), &opts).unwrap();
    let dir = tmp("png");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("torus.png");
    image.write_png(&path).unwrap();
    let file = std::io::BufReader::new(std::fs::File::open(&path).unwrap());
    let mut reader = png::Decoder::new(file).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (33, 21));
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    assert_eq!(&buf[..info.buffer_size()], image.rgb());
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, vec![std::ffi::OsString::from("torus.png")]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_is_an_error() {
    let tiles = torus_tiles();
    let ok = RenderOptions { width: 8, height: 6, samples: 1, ..Default::default() };
    let bad = [
        RenderOptions { width: 0, ..ok.clone() },
        RenderOptions { height: 0, ..ok.clone() },
        RenderOptions { width: 16385, ..ok.clone() },
        RenderOptions { width: 16384, height: 16384, ..ok.clone() },
        RenderOptions { samples: 0, ..ok.clone() },
        RenderOptions { samples: 9, ..ok.clone() },
        RenderOptions { azimuth_deg: f64::NAN, ..ok.clone() },
        RenderOptions { elevation_deg: 90.0, ..ok.clone() },
        RenderOptions { elevation_deg: f64::INFINITY, ..ok.clone() },
        RenderOptions { fov_deg: 0.0, ..ok.clone() },
        RenderOptions { fov_deg: 180.0, ..ok.clone() },
        RenderOptions { light_elevation_deg: -5.0, ..ok.clone() },
        RenderOptions {
            frame: Some(FrameBox { lo: [0.0; 3], hi: [f64::NAN, 1.0, 1.0] }),
            ..ok.clone()
        },
        RenderOptions { frame: Some(FrameBox { lo: [1.0; 3], hi: [0.0; 3] }), ..ok.clone() },
    ];
    for o in &bad {
        assert!(matches!(render::render(&tiles, o), Err(RenderError::InvalidOption(_))), "{o:?}");
    }
    render::render(&tiles, &ok).unwrap();
    // No band voxel at all.
    let empty = TileGrid::new(GridSpec::default());
    assert!(matches!(render::render(&empty, &ok), Err(RenderError::Empty(_))));
    // A band without a zero crossing: every value positive but inside the band.
    let field = DenseField::new(Coord::new(-3, 4, 0), [5, 6, 7], 1.5).unwrap();
    let no_zero = tiles_from_dense(&field, GridSpec::default()).unwrap();
    assert!(no_zero.band_voxels() > 0);
    assert!(matches!(render::render(&no_zero, &ok), Err(RenderError::Empty(_))));
    let dt = dtgrid_from(&no_zero);
    assert!(matches!(render::render(&dt, &ok), Err(RenderError::Empty(_))));
    // A path that cannot be written.
    let image = render::render(&tiles, &ok).unwrap();
    let err = image.write_png(&tmp("no/such/dir/x.png")).unwrap_err();
    assert!(matches!(err, RenderError::Io { .. }), "{err}");
}

/// A shape near the i32 limit renders (cell corners beyond the range read as outside).
#[test]
fn renders_near_the_coordinate_limit() {
    let far = (i32::MAX - 12) as f64;
    let shape = Shape::Sphere { center: [far, -far, 0.0], radius: 8.0 };
    let tiles = tiles_from_shape(&shape, GridSpec::default()).unwrap();
    let opts = RenderOptions { width: 32, height: 24, samples: 1, ..Default::default() };
    let image = render::render(&tiles, &opts).unwrap();
    assert!(image.depth(16, 12).is_some());
}

/// Two small spheres 2^29 voxels apart along every axis: empty space between them is skipped level by
/// level (a walk over it would take hours), and a frame box around one of them shows it
/// where the analytic sphere is.
#[test]
fn far_apart_parts_render_quickly() {
    let far = (1 << 28) as f64;
    let (a, b) = ([-far, 3.0 - far, 0.5 - far], [far, far - 2.0, far + 1.5]);
    let r = 6.0;
    let shape = Shape::Union(vec![
        Shape::Sphere { center: a, radius: r },
        Shape::Sphere { center: b, radius: r },
    ]);
    let tiles = tiles_from_shape(&shape, GridSpec::default()).unwrap();
    let frame = FrameBox { lo: [b[0] - r, b[1] - r, b[2] - r], hi: [b[0] + r, b[1] + r, b[2] + r] };
    let opts = RenderOptions {
        width: 48,
        height: 36,
        samples: 1,
        frame: Some(frame),
        ..Default::default()
    };
    let start = std::time::Instant::now();
    let image = render::render(&tiles, &opts).unwrap();
    let cam = *image.camera();
    let d = cam.ray(24.5, 18.5);
    let oc = sub(b, cam.eye);
    let along = dot(oc, d);
    let exact = along - (r * r - (dot(oc, oc) - along * along)).sqrt();
    let err = (image.depth(24, 18).expect("the centre ray hits sphere b") - exact).abs();
    assert!(err < 0.05, "centre depth off by {err} voxel");
    // Far from a measurement: a guard against walking the empty space (hours).
    assert!(start.elapsed().as_secs_f64() < 20.0, "{:?}", start.elapsed());
}
