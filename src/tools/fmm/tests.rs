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
