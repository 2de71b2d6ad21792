//! Unit tests of the heap, the quadratic solver and the interface initialisation.

use super::heap::IndexedHeap;
use super::march::{solve_terms, Term};
use super::source::interface_distance;
use crate::coord::Coord;

#[test]
fn heap_pops_in_key_then_coordinate_order_with_updates() {
    let mut rng = fastrand::Rng::with_seed(7);
    let mut heap = IndexedHeap::new();
    let mut live: Vec<(u32, f64, Coord)> = Vec::new();
    for i in 0..2000 {
        // Few distinct keys, so ties (broken by coordinate) are common.
        let key = rng.u32(0..50) as f64 * 0.25;
        let c = Coord::new(rng.i32(-9..9), rng.i32(-9..9), i);
        let h = heap.push(key, c, i as u32);
        live.push((h, key, c));
        if i % 3 == 0 {
            let k = rng.usize(0..live.len());
            let nk = rng.u32(0..50) as f64 * 0.25;
            heap.update(live[k].0, nk);
            live[k].1 = nk;
        }
        heap.check().unwrap();
    }
    live.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.2.cmp(&b.2)));
    assert_eq!(heap.len(), live.len());
    for &(_, k, c) in &live {
        let (pk, pc, _) = heap.pop().unwrap();
        assert_eq!((pk, pc), (k, c));
    }
    assert!(heap.is_empty() && heap.pop().is_none());
}

#[test]
fn first_and_second_order_updates_are_exact_for_a_plane_front() {
    // T(x) = n · x with |n| = 1: every one-sided difference of a linear function is exact.
    let n = [0.48f64, 0.6, 0.64];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let n = n.map(|v| v / len);
    let t0 = 7.25;
    let first: Vec<Term> = n.iter().map(|&a| Term { a: 1.0, k: t0 - a }).collect();
    let second: Vec<Term> =
        n.iter().map(|&a| Term { a: 2.25, k: (4.0 * (t0 - a) - (t0 - 2.0 * a)) / 3.0 }).collect();
    for mut terms in [first, second] {
        let t = solve_terms(&mut terms, 1.0);
        assert!((t - t0).abs() < 1e-12 * (1.0 + t0), "{t} vs {t0}");
    }
}

#[test]
fn the_solver_drops_directions_that_would_not_be_upwind() {
    // Neighbour values 0 and 5 along two axes: with both, Σ (T − k)² = 1 has no root
    // (discriminant < 0); dropping the larger gives T = 1.
    let mut terms = [Term { a: 1.0, k: 5.0 }, Term { a: 1.0, k: 0.0 }];
    assert_eq!(solve_terms(&mut terms, 1.0), 1.0);
    // 0 and 0.9: the two-term root 0.45 + √(2 − 0.81)/2 ≈ 0.995 is ≥ 0.9, so both stay.
    let mut terms = [Term { a: 1.0, k: 0.9 }, Term { a: 1.0, k: 0.0 }];
    let t = solve_terms(&mut terms, 1.0);
    assert!((t - (0.45 + (2.0f64 - 0.81).sqrt() / 2.0)).abs() < 1e-15, "{t}");
    // Classic diagonal case of Fig. 6: both neighbours at 1 → 1 + √½.
    let mut terms = [Term { a: 1.0, k: 1.0 }, Term { a: 1.0, k: 1.0 }];
    assert!((solve_terms(&mut terms, 1.0) - (1.0 + 0.5f64.sqrt())).abs() < 1e-15);
    // Large arrival times keep their precision (solved relative to the smallest k).
    let mut terms = [Term { a: 1.0, k: 1e9 }, Term { a: 1.0, k: 1e9 + 0.5 }];
    let t = solve_terms(&mut terms, 1.0);
    let exact = 1e9 + 0.25 + (2.0f64 - 0.25).sqrt() / 2.0;
    assert!((t - exact).abs() < 1e-6, "{t} vs {exact}");
}

/// The six axis neighbours of the origin, −x, +x, −y, +y, −z, +z, of `phi`.
fn star_of(phi: impl Fn(f64, f64, f64) -> f32) -> [Option<f32>; 6] {
    [
        Some(phi(-1.0, 0.0, 0.0)),
        Some(phi(1.0, 0.0, 0.0)),
        Some(phi(0.0, -1.0, 0.0)),
        Some(phi(0.0, 1.0, 0.0)),
        Some(phi(0.0, 0.0, -1.0)),
        Some(phi(0.0, 0.0, 1.0)),
    ]
}

#[test]
fn interface_distance_is_exact_for_a_linear_field_and_ignores_scaling() {
    // φ = s · (n · x − 0.3) at the origin, n a unit vector not aligned with the axes.
    let n = [0.36f32, 0.48, 0.8];
    for s in [1.0f32, 3.0, 0.2] {
        let phi = |x: f64, y: f64, z: f64| {
            s * (n[0] * x as f32 + n[1] * y as f32 + n[2] * z as f32 - 0.3)
        };
        let star = star_of(phi);
        let d = interface_distance(phi(0.0, 0.0, 0.0), &star, f32::INFINITY, [1.0; 3]).unwrap();
        assert!((d - 0.3).abs() < 1e-6, "scale {s}: {d}");
    }
    // No sign change: not an interface voxel.
    assert_eq!(interface_distance(0.5, &[Some(0.7); 6], 3.0, [1.0; 3]), None);
    // Clamped neighbours are not used for the gradient; the edge crossing caps the result.
    let star = [Some(-0.2), Some(3.0), Some(3.0), Some(3.0), Some(3.0), Some(3.0)];
    let d = interface_distance(0.6, &star, 3.0, [1.0; 3]).unwrap();
    assert!((d - 0.75).abs() < 1e-6, "{d}");
}

#[test]
fn interface_distance_with_per_axis_spacing() {
    // φ = n · x − 0.3 in world units on spacings (0.5, 1, 2), measured in units of the
    // smallest spacing h₀ = 0.5: ratios h₀ / hₐ = (1, 0.5, 0.25).
    let n = [0.36f64, 0.48, 0.8];
    let h = [0.5f64, 1.0, 2.0];
    let phi =
        |i: f64, j: f64, k: f64| (n[0] * i * h[0] + n[1] * j * h[1] + n[2] * k * h[2] - 0.3) as f32;
    let star = star_of(phi);
    let d = interface_distance(phi(0.0, 0.0, 0.0), &star, f32::INFINITY, [1.0, 0.5, 0.25]).unwrap();
    // 0.3 world units = 0.6 units of h₀.
    assert!((d - 0.6).abs() < 1e-6, "{d}");
}

#[test]
fn lattice_steps_wrap_periodic_axes_and_stop_at_obstacles() {
    use super::march::Lattice;
    let mut blocked = vec![false; 4 * 3 * 2];
    blocked[1 + 4] = true; // voxel (1, 1, 0)
    let l = Lattice {
        lo: Coord::new(0, 0, 0),
        dims: [4, 3, 2],
        ratios: [1.0; 3],
        periodic: [true, false, false],
        blocked: Some(blocked),
    };
    assert_eq!(l.step(Coord::new(3, 0, 0), 0, 1), Some(Coord::new(0, 0, 0)));
    assert_eq!(l.step(Coord::new(0, 2, 1), 0, -1), Some(Coord::new(3, 2, 1)));
    assert_eq!(l.step(Coord::new(0, 2, 1), 0, -2), Some(Coord::new(2, 2, 1)));
    assert_eq!(l.step(Coord::new(0, 2, 1), 1, 1), None);
    assert_eq!(l.step(Coord::new(0, 0, 0), 2, -1), None);
    assert_eq!(l.step(Coord::new(0, 1, 0), 0, 1), None, "an obstacle");
    assert_eq!(l.step(Coord::new(1, 0, 0), 1, 1), None, "an obstacle");
    assert_eq!(l.index(Coord::new(3, 2, 1)), 23);
}

/// The flat march of `dense_distance` gives the sparse march's values bit for bit (and
/// the same reached voxels): 1-D, 2-D and 3-D arrays, per-axis spacing, obstacles, ±∞,
/// exact zeros, plateaus of equal times (ties broken by coordinate), both orders, with
/// and without a limit; and the flat march gives the same values on 1 and 3 threads.
#[test]
fn the_flat_march_equals_the_sparse_one_bit_for_bit() {
    use super::dense::{checked_lattice, sparse_distance, DenseGrid};
    use crate::progress::Progress;
    let mut rng = fastrand::Rng::with_seed(11);
    let cases: Vec<([usize; 3], [f64; 3])> = vec![
        ([40, 1, 1], [1.0; 3]),
        ([31, 26, 1], [1.0, 0.5, 1.0]),
        ([1, 23, 17], [1.0, 1.0, 2.0]),
        ([18, 15, 13], [1.0; 3]),
        ([14, 17, 12], [0.7, 1.0, 1.3]),
    ];
    for (k, (dims, spacing)) in cases.into_iter().enumerate() {
        let n: usize = dims.iter().product();
        let c = dims.map(|d| (d as f64 - 1.0) / 2.0 + 0.3);
        let r = 0.3 * dims.iter().copied().filter(|&d| d > 1).min().unwrap() as f64;
        let mut phi: Vec<f32> = (0..n)
            .map(|i| {
                let p = [i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1])];
                let d2: f64 = (0..3).map(|a| ((p[a] as f64 - c[a]) * spacing[a]).powi(2)).sum();
                let wobble = 1.0 + 0.4 * (p[0] as f64 * 0.7).sin() * (p[1] as f64 * 0.5).cos();
                ((d2.sqrt() - r) * wobble) as f32
            })
            .collect();
        if k == 3 {
            // Plateaus: a plane front with many equal times, a zero and infinities.
            for (i, v) in phi.iter_mut().enumerate() {
                *v = (i % dims[0]) as f32 - 6.0;
            }
            phi[5] = f32::INFINITY;
            phi[n - 1] = f32::NEG_INFINITY;
        }
        let mask: Option<Vec<bool>> = (k == 4).then(|| (0..n).map(|_| rng.u8(..) < 20).collect());
        let grid = DenseGrid { dims, spacing, periodic: [false; 3] };
        for second in [false, true] {
            for narrow in [None, Some(2.5)] {
                let (lattice, h0) =
                    checked_lattice(&phi, &grid, mask.as_deref(), narrow, None).unwrap();
                let limit = narrow.map_or(f64::INFINITY, |w| w / h0);
                let sparse =
                    sparse_distance(&phi, lattice.clone(), h0, second, limit, &Progress::none())
                        .unwrap();
                let scale = |v: f64| (v * h0) as f32;
                let flat =
                    super::flat::distance(&phi, &lattice, second, limit, &Progress::none(), scale)
                        .unwrap()
                        .unwrap();
                // One thread (the two sides one after the other) and three: the same bits.
                for threads in [1, 3] {
                    let pool =
                        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                    let other = pool
                        .install(|| {
                            super::flat::distance(
                                &phi,
                                &lattice,
                                second,
                                limit,
                                &Progress::none(),
                                scale,
                            )
                        })
                        .unwrap()
                        .unwrap();
                    assert_eq!(other, flat, "case {k}, {second}, {narrow:?}, {threads} threads");
                }
                let (values, reached) = (flat.values, flat.reached);
                assert_eq!(reached, sparse.reached, "case {k}, second {second}, {narrow:?}");
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&values), bits(&sparse.values), "case {k}, {second}, {narrow:?}");
                assert!(reached.iter().filter(|&&r| r).count() > 8, "case {k}");
            }
        }
    }
}
