//! The API's error paths, the benchmark report and the build information.

use crate::common;

use levelset_kernels::bench::{run_kernel_bench, Fixture, KernelBenchConfig, KERNELS, LANES};
use levelset_kernels::{
    BoxStarWindow, BoxWindow, DenseBlock, Eq3Rate, Euler, KernelError, Lane, Rk3, StarWindow,
    TileBlock, Upwind1, Weno5,
};

#[test]
fn blocks_and_windows_check_lengths() {
    assert_eq!(
        TileBlock::<1>::new(&[0.0; 431]).unwrap_err(),
        KernelError::BlockLength { expected: 432, got: 431 }
    );
    // 12 (x: three tile rows) × 10 × 10.
    assert!(TileBlock::<3>::new(&[0.0; 1200]).is_ok());
    assert!(TileBlock::<3>::new(&[0.0; 1000]).is_err());
    assert_eq!(
        DenseBlock::<1>::new(&[0.0; 10], [1, 1, 1]).unwrap_err(),
        KernelError::BlockLength { expected: 27, got: 10 }
    );
    assert_eq!(DenseBlock::<1>::padded_len([usize::MAX, 1, 1]), None);
    assert_eq!(
        DenseBlock::<1>::new(&[], [usize::MAX, 1, 1]).unwrap_err(),
        KernelError::BlockTooLarge
    );
    assert_eq!(
        BoxWindow::from_slice(&[0.0; 26]).unwrap_err(),
        KernelError::StencilLength { expected: 27, got: 26 }
    );
    assert_eq!(
        StarWindow::from_slice(&[0.0; 20]).unwrap_err(),
        KernelError::StencilLength { expected: 19, got: 20 }
    );
    assert!(BoxStarWindow::from_slices(&[0.0; 27], &[0.0; 19]).is_ok());
    // An empty dense block is fine (nothing to do).
    let data = vec![0.0; DenseBlock::<1>::padded_len([0, 3, 3]).unwrap()];
    let k = Euler { rate: Eq3Rate::<Upwind1, f32>::new(1.0, 1.0, 0.0, 1.0), dt: 0.1, gamma: 3.0 };
    DenseBlock::<1>::new(&data, [0, 3, 3]).unwrap().apply::<f32, _>(&k, &mut []).unwrap();
}

#[test]
fn sweeps_check_outputs_and_fields() {
    let dims = [5, 4, 3];
    let data = vec![0.5; DenseBlock::<3>::padded_len(dims).unwrap()];
    let block = DenseBlock::<3>::new(&data, dims).unwrap();
    let k = Euler { rate: Eq3Rate::<Upwind1, f32>::new(1.0, 1.0, 0.0, 1.0), dt: 0.1, gamma: 3.0 };
    let mut out = vec![0.0; 59];
    assert_eq!(
        block.apply::<f32, _>(&k, &mut out).unwrap_err(),
        KernelError::OutputLength { expected: 60, got: 59 }
    );
    let speed = vec![1.0; 59];
    let kf = Eq3Rate::<Weno5, &[f32]>::new(1.0, &speed, 0.0, 1.0);
    let mut out = vec![0.0; 60];
    assert_eq!(
        block.apply::<f32, _>(&kf, &mut out).unwrap_err(),
        KernelError::FieldLength { expected: 60, got: 59 }
    );
    // RK3 reads φⁿ from stage 2 on.
    let rate = Eq3Rate::<Weno5, f32>::new(1.0, 1.0, 0.0, 1.0);
    let s1 = Rk3::<_, 1> { rate, dt: 0.1, gamma: 3.0, phi_n: &[] };
    assert!(block.apply::<f32, _>(&s1, &mut out).is_ok());
    let s2 = Rk3::<_, 2> { rate, dt: 0.1, gamma: 3.0, phi_n: &[] };
    assert_eq!(
        block.apply::<f32, _>(&s2, &mut out).unwrap_err(),
        KernelError::FieldLength { expected: 60, got: 0 }
    );
    let tile = vec![0.0; TileBlock::<3>::LEN];
    let mut t = [0.0; 64];
    let short = vec![0.0; 63];
    let ks = Eq3Rate::<Upwind1, &[f32]>::new(1.0, &short, 0.0, 1.0);
    assert!(TileBlock::<3>::new(&tile).unwrap().apply::<f32, _>(&ks, &mut t).is_err());
    assert!(!KernelError::FieldLength { expected: 1, got: 0 }.to_string().is_empty());
}

#[test]
fn tile_lane_groups_follow_the_tile_layout() {
    // Lane k of a group is the voxel with tile index first + k, for every lane type.
    let mut tile = vec![0.0; TileBlock::<1>::LEN];
    for z in -1..5 {
        for y in -1..5 {
            for x in -1..5 {
                tile[TileBlock::<1>::index(x, y, z)] = (x + 4 * y + 16 * z) as f32;
            }
        }
    }
    let block = TileBlock::<1>::new(&tile).unwrap();
    common::for_lanes!(|L| {
        let mut seen = 0;
        block.for_each::<L>(|first, w| {
            use levelset_kernels::Window;
            let mut v = vec![0.0; L::LANES];
            w.centre().store(&mut v);
            for (k, &x) in v.iter().enumerate() {
                assert_eq!(x, (first + k) as f32, "{} group at {first}", L::NAME);
            }
            let mut up = vec![0.0; L::LANES];
            w.at::<0, 1, 0>().store(&mut up);
            assert_eq!(up[0], (first + 4) as f32);
            seen += L::LANES;
        });
        assert_eq!(seen, 64);
    });
}

#[test]
fn kernel_bench_reports_every_pair() {
    let cfg = KernelBenchConfig { dims: [20, 4, 3], seconds: 0.01, samples: 2 };
    let r = run_kernel_bench(&cfg).unwrap();
    assert_eq!(r.kernels.len(), KERNELS.len() * LANES.len());
    for k in KERNELS {
        for l in LANES {
            let v = r.get(k, l).unwrap();
            assert!(v.is_finite() && v > 0.0, "{k} {l}: {v}");
        }
    }
    let json = r.to_json();
    assert!(json.starts_with(
        "{\"kernels\":[{\"kernel\":\"upwind_curvature\",\"lanes\":\"f32\",\"voxel_updates_per_s\":"
    ));
    assert!(json.contains("\"target_features\":["));
    assert_eq!(r.target_features, levelset_kernels::target_features());
    // Every lane type computes the same numbers in the benchmark too.
    let fx = Fixture::new([19, 3, 2]).unwrap();
    for k in KERNELS {
        let mut reference = fx.output();
        assert!(fx.run(k, "f32", &mut reference).unwrap());
        for l in LANES {
            let mut out = fx.output();
            assert!(fx.run(k, l, &mut out).unwrap());
            assert!(out.iter().zip(&reference).all(|(a, b)| common::same_bits(*a, *b)), "{k} {l}");
        }
    }
    assert!(!fx.run("nope", "f32", &mut fx.output()).unwrap());
    assert_eq!(Fixture::new([0, 1, 1]).err(), Some(KernelError::EmptyBlock));
}

#[test]
fn point_layout_tables() {
    use levelset_kernels::{
        box27_index, box_far39_index, star19_index, BOX27_OFFSETS, BOX_FAR39_OFFSETS,
        STAR19_OFFSETS,
    };
    for (i, o) in BOX27_OFFSETS.iter().enumerate() {
        assert_eq!(box27_index(o[0], o[1], o[2]), i);
    }
    assert_eq!(BOX27_OFFSETS[13], [0, 0, 0]);
    for (i, o) in STAR19_OFFSETS.iter().enumerate() {
        assert_eq!(star19_index(o[0], o[1], o[2]), i);
        assert!(o.iter().filter(|&&c| c != 0).count() <= 1);
    }
    // The DT-Grid's order: centre, then per axis x, y, z the steps -3, -2, -1, 1, 2, 3.
    assert_eq!(STAR19_OFFSETS[0], [0, 0, 0]);
    assert_eq!(STAR19_OFFSETS[1], [-3, 0, 0]);
    assert_eq!(STAR19_OFFSETS[4], [1, 0, 0]);
    assert_eq!(STAR19_OFFSETS[18], [0, 0, 3]);
    let mut seen = std::collections::HashSet::new();
    for (i, o) in BOX_FAR39_OFFSETS.iter().enumerate() {
        assert_eq!(box_far39_index(o[0], o[1], o[2]), i);
        assert!(seen.insert(*o));
    }
}

#[test]
fn lane_kinds_dispatch_once() {
    use levelset_kernels::{with_lane, LaneKind};
    for k in LaneKind::ALL {
        assert_eq!(LaneKind::from_name(k.name()), Some(k));
        let (n, name) = with_lane!(k, |L| (<L as Lane>::LANES, <L as Lane>::NAME));
        assert_eq!((n, name), (k.lanes(), k.name()));
    }
    assert_eq!(LaneKind::from_name("f64"), None);
    assert_eq!(LaneKind::DEFAULT.lanes(), <levelset_kernels::DefaultLane as Lane>::LANES);
    // Every level's lane types carry the kind's name and width.
    struct Names;
    impl levelset_kernels::LaneFn for Names {
        type Output = (usize, &'static str);
        fn call<L: Lane>(self) -> Self::Output {
            (L::LANES, L::NAME)
        }
    }
    for level in levelset_kernels::Level::ALL.into_iter().filter(|l| l.available()) {
        for k in LaneKind::ALL {
            let got = levelset_kernels::dispatch_at(level, k, Names).unwrap();
            assert_eq!(got, (k.lanes(), k.name()), "{level}");
        }
    }
    assert_eq!(LANES, LaneKind::ALL.map(LaneKind::name));
}

#[test]
fn build_information() {
    let f = levelset_kernels::target_features();
    if cfg!(target_arch = "x86_64") {
        assert!(f.contains(&"sse2"));
    }
    // The default lane type follows the `simd` feature.
    let lanes = <levelset_kernels::DefaultLane as Lane>::LANES;
    if cfg!(feature = "simd") {
        assert!(lanes >= 8);
    } else {
        assert_eq!(lanes, 1);
    }
    // So does the default kind of every level: the widest register, or `f32`.
    for level in levelset_kernels::Level::ALL {
        let kind = level.default_lanes();
        if cfg!(feature = "simd") {
            assert!(kind.lanes() >= 8, "{level}: {kind:?}");
        } else {
            assert_eq!(kind, levelset_kernels::LaneKind::F32, "{level}");
        }
    }
    if cfg!(target_arch = "x86_64") {
        assert_eq!(levelset_kernels::FUSED_MUL_ADD, cfg!(target_feature = "fma"));
    }
}
