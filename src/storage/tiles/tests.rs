//! Tests of the Sorted Tile List against brute force and a dense ground truth.

use super::*;
use crate::coord::{Coord, MID, NEIGHBOURHOOD};
use crate::grid::{GridError, GridSpec};
use std::collections::{BTreeMap, BTreeSet};

/// A random union of spheres and boxes: exact signed distance (union = min).
struct RandomShape {
    spheres: Vec<([f64; 3], f64)>,
    boxes: Vec<([f64; 3], [f64; 3])>,
}

impl RandomShape {
    fn new(rng: &mut fastrand::Rng, around: [f64; 3]) -> Self {
        let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.f64();
        let ns = 1 + (r(0.0, 3.0) as usize);
        let nb = r(0.0, 2.5) as usize;
        let spheres = (0..ns)
            .map(|_| {
                (
                    [around[0] + r(-9.0, 9.0), around[1] + r(-9.0, 9.0), around[2] + r(-9.0, 9.0)],
                    r(2.5, 9.7),
                )
            })
            .collect();
        let boxes = (0..nb)
            .map(|_| {
                (
                    [around[0] + r(-8.0, 8.0), around[1] + r(-8.0, 8.0), around[2] + r(-8.0, 8.0)],
                    [r(1.5, 7.3), r(1.5, 6.1), r(1.5, 5.9)],
                )
            })
            .collect();
        RandomShape { spheres, boxes }
    }

    fn sdf(&self, p: [f64; 3]) -> f64 {
        let mut d = f64::INFINITY;
        for (c, r) in &self.spheres {
            let v =
                ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt() - r;
            d = d.min(v);
        }
        for (c, h) in &self.boxes {
            let q: Vec<f64> = (0..3).map(|a| (p[a] - c[a]).abs() - h[a]).collect();
            let outside = q.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>().sqrt();
            let inside = q[0].max(q[1]).max(q[2]).min(0.0);
            d = d.min(outside + inside);
        }
        d
    }
}

/// The clamped ground-truth value of a voxel.
fn truth(shape: &RandomShape, spec: &GridSpec, v: Coord) -> f32 {
    let g = spec.gamma();
    (shape.sdf(spec.world(v)) as f32).clamp(-g, g)
}

/// Builds a tile grid by brute force over a box that holds the band: every tile with a
/// band voxel, border flags from the truth.
fn build(shape: &RandomShape, spec: GridSpec, lo: Coord, hi: Coord) -> TileGrid {
    let (tlo, _) = tile_of(lo);
    let (thi, _) = tile_of(hi);
    let g = spec.gamma();
    let mut tiles = Vec::new();
    for tz in tlo.z..=thi.z {
        for ty in tlo.y..=thi.y {
            for tx in tlo.x..=thi.x {
                let t = Coord::new(tx, ty, tz);
                let mut tile = Tile::splat(0.0);
                for l in 0..TILE_LEN {
                    tile.0[l] = truth(shape, &spec, voxel_of(t, l));
                }
                if tile.0.iter().any(|v| v.abs() < g) {
                    tiles.push((t, tile));
                }
            }
        }
    }
    TileGrid::from_sorted_tiles(spec, tiles, |t| truth(shape, &spec, voxel_of(t, 0)) < 0.0).unwrap()
}

struct Case {
    shape: RandomShape,
    spec: GridSpec,
    lo: Coord,
    hi: Coord,
}

fn cases(seed: u64, n: usize) -> Vec<Case> {
    let mut rng = fastrand::Rng::with_seed(seed);
    (0..n)
        .map(|i| {
            let voxel_size = if i % 2 == 0 { 1.0 } else { 0.5 };
            let half_width = if i % 3 == 0 { 2.0 } else { 3.0 };
            let spec = GridSpec::new(voxel_size, [0.0; 3], half_width).unwrap();
            let around =
                [rng.f64() * 80.0 - 40.0, rng.f64() * 80.0 - 40.0, rng.f64() * 80.0 - 40.0];
            let shape = RandomShape::new(&mut rng, around);
            // A voxel box that holds the band: shapes reach at most ~19 units from `around`.
            let reach = 20.0 + spec.gamma() as f64 + 2.0;
            let to_v = |w: f64| (w / voxel_size as f64).round() as i32;
            let lo = Coord::new(
                to_v(around[0] - reach),
                to_v(around[1] - reach),
                to_v(around[2] - reach),
            );
            let hi = Coord::new(
                to_v(around[0] + reach) + 3,
                to_v(around[1] + reach) + 1,
                to_v(around[2] + reach) + 2,
            );
            Case { shape, spec, lo, hi }
        })
        .collect()
}

fn for_box(lo: Coord, hi: Coord, mut f: impl FnMut(Coord)) {
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                f(Coord::new(x, y, z));
            }
        }
    }
}

#[test]
fn random_access_equals_dense_truth() {
    for case in cases(11, 6) {
        let grid = build(&case.shape, case.spec, case.lo, case.hi);
        grid.check_invariants().unwrap();
        assert!(!grid.is_empty());
        let (blo, bhi) = grid.bounding_box().unwrap();
        let m = Coord::new(2, 2, 2);
        let mut checked = 0;
        for_box(blo.wrapping_sub(m), bhi.wrapping_add(m), |v| {
            let want = truth(&case.shape, &case.spec, v);
            let got = grid.value(v);
            let g = case.spec.gamma();
            if want.abs() < g {
                assert_eq!(got, want, "band voxel {v:?}");
            } else {
                // Outside the band a grid reads exactly ±γ with the truth's sign.
                assert!(
                    got.abs() == g && got.signum() == want.signum(),
                    "voxel {v:?}: {got} vs {want}"
                );
            }
            checked += 1;
        });
        assert!(checked > 10_000);
        assert_eq!(grid.band_voxels(), {
            let mut n = 0;
            for_box(case.lo, case.hi, |v| {
                n += (truth(&case.shape, &case.spec, v).abs() < case.spec.gamma()) as usize
            });
            n
        });
    }
}

#[test]
fn sorted_traversal_visits_stored_voxels_in_order() {
    for case in cases(12, 3) {
        let grid = build(&case.shape, case.spec, case.lo, case.hi);
        let mut prev: Option<Coord> = None;
        let mut n = 0;
        grid.for_each_voxel_sorted(|c, v| {
            if let Some(p) = prev {
                assert!(p < c, "{p:?} then {c:?}");
            }
            prev = Some(c);
            assert_eq!(v, grid.value(c));
            n += 1;
        });
        assert_eq!(n, grid.stored_voxels());
    }
}

fn brute_neighbours(coords: &[Coord], pos: usize) -> (u32, [usize; 27]) {
    let mut m = 0;
    let mut ptr = [0; 27];
    for d in 0..27 {
        if let Ok(p) = coords.binary_search(&coords[pos].wrapping_add(NEIGHBOURHOOD[d])) {
            m |= 1 << d;
            ptr[d] = p;
        }
    }
    (m, ptr)
}

#[test]
fn neighbour_tracking_equals_brute_force_from_any_start() {
    let mut rng = fastrand::Rng::with_seed(5);
    for case in cases(13, 3) {
        let grid = build(&case.shape, case.spec, case.lo, case.hi);
        let coords = grid.tile_coords();
        let n = coords.len();
        let mut starts = vec![(0, n)];
        for _ in 0..8 {
            let a = rng.usize(0..n);
            starts.push((a, rng.usize(a..=n)));
        }
        for (a, b) in starts {
            let mut cur = NeighbourCursor::new(coords, a, b);
            let mut visited = 0;
            while let Some(nb) = cur.next() {
                assert_eq!(nb.pos, a + visited);
                let (m, ptr) = brute_neighbours(coords, nb.pos);
                assert_eq!(nb.matched, m, "tile {}", nb.pos);
                for (d, &p) in ptr.iter().enumerate() {
                    assert_eq!(nb.get(d), (m & (1 << d) != 0).then_some(p));
                }
                visited += 1;
            }
            assert_eq!(visited, b - a);
        }
    }
}

#[test]
fn neighbour_table_equals_brute_force_for_any_thread_count() {
    for case in cases(16, 3) {
        let grid = build(&case.shape, case.spec, case.lo, case.hi);
        let coords = grid.tile_coords();
        let tables: Vec<NeighbourTable> = [1, 3]
            .iter()
            .map(|&threads| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let mut t = NeighbourTable::default();
                pool.install(|| t.rebuild(coords));
                t
            })
            .collect();
        assert_eq!(tables[0].len(), coords.len());
        for (p, c) in coords.iter().enumerate() {
            let (a, b) = (tables[0].row(p), tables[1].row(p));
            assert_eq!(a, b);
            for (d, off) in NEIGHBOURHOOD.iter().enumerate() {
                let there = coords.binary_search(&c.wrapping_add(*off)).ok();
                assert_eq!(a.get(d), there, "tile {p} direction {d}");
            }
        }
    }
    let mut empty = NeighbourTable::default();
    empty.rebuild(&[]);
    assert!(empty.is_empty());
}

fn brute_dilation(coords: &[Coord]) -> BTreeSet<Coord> {
    coords.iter().flat_map(|c| NEIGHBOURHOOD.iter().map(move |d| c.wrapping_add(*d))).collect()
}

#[test]
fn dilation_stream_equals_brute_force() {
    for case in cases(14, 3) {
        let grid = build(&case.shape, case.spec, case.lo, case.hi);
        let coords = grid.tile_coords();
        let want = brute_dilation(coords);
        let got: Vec<_> = DilationStream::new(coords).collect();
        assert_eq!(got.len(), want.len());
        for (nb, w) in got.iter().zip(&want) {
            assert_eq!(nb.coord, *w);
            for (d, off) in NEIGHBOURHOOD.iter().enumerate() {
                let there = coords.binary_search(&nb.coord.wrapping_add(*off));
                assert_eq!(nb.matched & (1 << d) != 0, there.is_ok());
                if let Ok(p) = there {
                    assert_eq!(nb.ptr[d], p);
                }
            }
        }
    }
    assert_eq!(DilationStream::new(&[]).count(), 0);
}

#[test]
fn dilate_equals_brute_force_with_signed_fill() {
    for case in cases(15, 4) {
        let mut grid = build(&case.shape, case.spec, case.lo, case.hi);
        let before = grid.clone();
        let want = brute_dilation(grid.tile_coords());
        let stats = grid.dilate().unwrap();
        grid.check_invariants().unwrap();
        assert_eq!(grid.tile_coords().iter().copied().collect::<BTreeSet<_>>(), want);
        assert_eq!(stats.kept, before.len());
        assert_eq!(stats.created, want.len() - before.len());
        let g = case.spec.gamma();
        for (p, &t) in grid.tile_coords().iter().enumerate() {
            match before.find_tile(t) {
                Ok(q) => assert_eq!(grid.tile(p), before.tile(q)),
                Err(_) => {
                    let inside = truth(&case.shape, &case.spec, voxel_of(t, 0)) < 0.0;
                    assert_eq!(
                        grid.tile(p),
                        &Tile::splat(if inside { -g } else { g }),
                        "new tile {t:?}"
                    );
                }
            }
        }
    }
}

/// Brute-force Algorithm 3 trigger set: positions whose tile or a neighbour has activity in
/// the regions facing the position.
fn brute_triggered(grid: &TileGrid) -> BTreeSet<Coord> {
    let mut out = BTreeSet::new();
    for c in brute_dilation(grid.tile_coords()) {
        for (d, off) in NEIGHBOURHOOD.iter().enumerate() {
            if let Ok(p) = grid.find_tile(c.wrapping_add(*off))
                && grid.activity_flags(p) & NEIGHBOUR_TRIGGER[d] != 0
            {
                out.insert(c);
            }
        }
    }
    out
}

/// Random activity flags: none, inside, one region, the previous flags, or any regions.
fn randomize_activity(grid: &mut TileGrid, rng: &mut fastrand::Rng) {
    for p in 0..grid.len() {
        let f = match rng.u32(0..5) {
            0 => 0,
            1 => INSIDE,
            2 => 1 << rng.u32(0..27),
            3 => grid.activity_flags(p),
            _ => rng.u32(..) & ACTIVE_MASK,
        };
        grid.set_activity_flags(p, f);
    }
}

#[test]
fn management_with_random_activity_keeps_list_valid() {
    let mut rng = fastrand::Rng::with_seed(99);
    for case in cases(16, 3) {
        let mut grid = build(&case.shape, case.spec, case.lo, case.hi);
        for _round in 0..6 {
            randomize_activity(&mut grid, &mut rng);
            let want = brute_triggered(&grid);
            let before = grid.clone();
            let stats = grid.manage_tiles().unwrap();
            grid.check_invariants().unwrap();
            let got: BTreeSet<Coord> = grid.tile_coords().iter().copied().collect();
            assert_eq!(got, want);
            assert_eq!(stats.kept + stats.removed, before.len());
            assert_eq!(stats.kept + stats.created, grid.len());
            // Kept tiles keep their data and flags.
            for (p, &t) in grid.tile_coords().iter().enumerate() {
                if let Ok(q) = before.find_tile(t) {
                    assert_eq!(grid.tile(p), before.tile(q));
                    assert_eq!(grid.activity_flags(p), before.activity_flags(q));
                }
            }
            if grid.is_empty() {
                break;
            }
        }
    }
}

/// Two grids hold the same list, values and flags.
fn assert_same_grid(a: &TileGrid, b: &TileGrid) {
    assert_eq!(a.tile_coords(), b.tile_coords());
    assert_eq!(a.values(), b.values());
    for p in 0..a.len() {
        assert_eq!(a.border_flags(p), b.border_flags(p), "border of {p}");
        assert_eq!(a.activity_flags(p), b.activity_flags(p), "activity of {p}");
    }
}

/// Management that is refused before it allocates leaves the grid as it was; management
/// that changes the list hands back the previous grid, which puts the state back exactly
/// (the evolution's undo); swapping values and activity twice is the identity.
#[test]
fn management_admission_and_undo_restore_the_grid() {
    let mut rng = fastrand::Rng::with_seed(5);
    for case in cases(31, 3) {
        let mut grid = build(&case.shape, case.spec, case.lo, case.hi);
        randomize_activity(&mut grid, &mut rng);
        let before = grid.clone();
        let refuse = |_: usize| Err(GridError::InvalidParameter("refused".into()));
        assert!(grid.manage_tiles_checked(None, refuse, &mut Vec::new(), true, false).is_err());
        grid.check_invariants().unwrap();
        assert_same_grid(&grid, &before);
        let mut asked = None;
        let (stats, prev) = grid
            .manage_tiles_checked(
                None,
                |n| {
                    asked = Some(n);
                    Ok(())
                },
                &mut Vec::new(),
                false,
                false,
            )
            .unwrap();
        grid.check_invariants().unwrap();
        let changed = stats.removed + stats.created > 0;
        assert_eq!(prev.is_some(), changed);
        assert_eq!(asked, changed.then_some(grid.len()));
        if let Some(prev) = prev {
            assert_same_grid(&prev, &before);
        }
        // The double buffer: values and activity swap in and back out unchanged.
        let mut values: Vec<Tile> = grid.values().iter().map(|t| Tile(t.0.map(|v| -v))).collect();
        let g = grid.gamma();
        let mut activity: Vec<u32> = values.iter().map(|t| compute_activity(t, g)).collect();
        let (want_values, want_activity) = (values.clone(), activity.clone());
        let kept = grid.clone();
        grid.swap_values(&mut values, &mut activity).unwrap();
        assert_eq!(grid.values(), &want_values[..]);
        for (p, &a) in want_activity.iter().enumerate() {
            assert_eq!(grid.activity_flags(p), a);
        }
        grid.swap_values(&mut values, &mut activity).unwrap();
        assert_same_grid(&grid, &kept);
        assert_eq!(values, want_values);
        assert_eq!(activity, want_activity);
    }
}

/// The parallel management equals the paper's streamed Algorithms 2 + 3 in every list,
/// value and flag, for any number of threads, and the neighbour table it is given follows
/// the list to the rows a rebuild gives.
#[test]
fn parallel_management_equals_streamed() {
    let mut rng = fastrand::Rng::with_seed(7);
    let pools: Vec<rayon::ThreadPool> = [1, 2, 5]
        .iter()
        .map(|&t| rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap())
        .collect();
    for case in cases(23, 4) {
        let mut grid = build(&case.shape, case.spec, case.lo, case.hi);
        for _round in 0..5 {
            randomize_activity(&mut grid, &mut rng);
            let mut want = grid.clone();
            let want_stats = want.manage_tiles_streamed().unwrap();
            let mut table = NeighbourTable::default();
            table.rebuild(grid.tile_coords());
            // Each pool, finding the neighbours itself and reading them from a table, with
            // new memory, a spare buffer of garbage, or the values moved in place.
            let runs = pools.iter().flat_map(|p| [(p, false), (p, true)]);
            let modes = [(false, false), (true, false), (false, true)];
            for ((pool, with_table), (recycle, in_place)) in
                runs.flat_map(|r| modes.map(|m| (r, m)))
            {
                let mut got = grid.clone();
                let mut spare = if recycle {
                    vec![Tile::splat(f32::NAN); 2 * grid.len() + 64]
                } else {
                    Vec::new()
                };
                let mut followed = table.clone();
                let (stats, prev) = pool
                    .install(|| {
                        got.manage_tiles_checked(
                            with_table.then_some(&mut followed),
                            |_| Ok(()),
                            &mut spare,
                            in_place,
                            false,
                        )
                    })
                    .unwrap();
                if with_table {
                    // The table followed the list: the rows a rebuild gives.
                    let mut rebuilt = NeighbourTable::default();
                    rebuilt.rebuild(got.tile_coords());
                    assert_eq!(followed.len(), rebuilt.len());
                    for p in 0..got.len() {
                        assert_eq!(followed.row(p), rebuilt.row(p), "row {p}");
                    }
                }
                if let Some(prev) = prev {
                    // Recycled: the new values live in the spare's memory, and the previous
                    // grid's values (the list's before) were lent to it. In place: they
                    // were moved into the new list.
                    if !in_place {
                        let lent = if recycle { &spare } else { &prev.arena };
                        assert_eq!(lent, &grid.arena);
                    }
                    assert_eq!(prev.arena.is_empty(), recycle || in_place);
                    assert_eq!(prev.tile_coords(), grid.tile_coords());
                }
                assert_eq!(stats, want_stats);
                assert_eq!(got.tile_coords(), want.tile_coords());
                for p in 0..got.len() {
                    assert_eq!(got.tile(p), want.tile(p));
                    assert_eq!(got.border_flags(p), want.border_flags(p), "border of {p}");
                    assert_eq!(got.activity_flags(p), want.activity_flags(p));
                }
            }
            grid = want;
            if grid.is_empty() {
                break;
            }
        }
    }
}

fn grid_from(spec: GridSpec, tiles: &[(Coord, f32)], inside: impl Fn(Coord) -> bool) -> TileGrid {
    let mut v: Vec<_> = tiles.iter().map(|&(c, x)| (c, Tile::splat(x))).collect();
    v.sort_by_key(|t| t.0);
    TileGrid::from_sorted_tiles(spec, v, inside).unwrap()
}

#[test]
fn management_hand_made_growth_removal_creation() {
    let spec = GridSpec::default();
    let g = spec.gamma();
    // One active tile at the origin, its +x neighbour outside and present, everything
    // else absent; the surroundings are outside except the tile at -x, which is inside.
    let mut grid = grid_from(spec, &[(Coord::new(0, 0, 0), 0.5), (Coord::new(1, 0, 0), g)], |t| {
        t == Coord::new(-1, 0, 0)
    });
    assert_eq!(grid.value(Coord::new(-1, 0, 0)), -g);
    assert_eq!(grid.value(Coord::new(-9, 1, 1)), -g, "row gap before an inside-flagged border");
    assert_eq!(grid.value(Coord::new(9, 1, 1)), g);
    // Activity only in the centre region of tile 0 triggers nothing around it: the +x
    // tile (no activity) is removed and tells tile 0 it was outside.
    let centre_region = 1 << 13;
    grid.set_activity_flags(0, centre_region);
    grid.set_activity_flags(1, 0);
    let s = grid.manage_tiles().unwrap();
    assert_eq!(s, ManageStats { kept: 1, removed: 1, created: 0 });
    assert_eq!(grid.tile_coords(), &[Coord::new(0, 0, 0)]);
    assert_eq!(grid.border_flags(0) & (1 << crate::coord::direction_index(1, 0, 0)), 0);
    assert_eq!(grid.value(Coord::new(5, 2, 2)), g);

    // Growth: activity in the low-x face region of tile 0 creates the -x neighbours
    // (face, edges, corners: 9 tiles) and they are inside, from tile 0's border flags.
    grid.set_activity_flags(0, 1 << 12); // region (rx=0, ry=1, rz=1)
    let s = grid.manage_tiles().unwrap();
    assert_eq!(s, ManageStats { kept: 1, removed: 0, created: 1 });
    assert_eq!(grid.tile_coords(), &[Coord::new(-1, 0, 0), Coord::new(0, 0, 0)]);
    assert_eq!(grid.tile(0), &Tile::splat(-g));
    assert_eq!(grid.activity_flags(0), INSIDE);
    assert_eq!(grid.border_flags(0), BORDER_MASK);

    // A corner region triggers all 7 tiles around that corner, created outside.
    grid.set_activity_flags(1, 1 << 26); // region (2,2,2): the +x+y+z corner
    grid.set_activity_flags(0, INSIDE);
    let s = grid.manage_tiles().unwrap();
    // The inside tile at -x has no activity and no trigger: removed, telling tile 0.
    assert_eq!(s, ManageStats { kept: 1, removed: 1, created: 7 });
    let want: BTreeSet<Coord> = (0..8).map(|i| Coord::new(i & 1, (i >> 1) & 1, i >> 2)).collect();
    assert_eq!(grid.tile_coords().iter().copied().collect::<BTreeSet<_>>(), want);
    // New tiles take their sign from the border flags their neighbours hold towards them
    // (Alg. 3 lines 22-27): those touching the inside tile at -x (whose flags all say
    // inside) are inside, the others outside. In a distance field a tile within one
    // diagonal of a -γ tile is indeed inside.
    for (p, &t) in grid.tile_coords().iter().enumerate() {
        if t == Coord::new(0, 0, 0) {
            continue;
        }
        let want = if t.x == 0 { -g } else { g };
        assert_eq!(grid.tile(p), &Tile::splat(want), "created tile {t:?}");
    }
    let origin = grid.find_tile(Coord::new(0, 0, 0)).unwrap();
    assert_ne!(grid.border_flags(origin) & (1 << crate::coord::direction_index(-1, 0, 0)), 0);
    assert_eq!(grid.value(Coord::new(-1, 1, 1)), -g, "removed inside tile reads -γ");

    // Everything inactive: the list empties and random access reads outside.
    for p in 0..grid.len() {
        grid.set_activity_flags(p, 0);
    }
    grid.manage_tiles().unwrap();
    assert!(grid.is_empty());
    assert_eq!(grid.value(Coord::new(0, 0, 0)), g);
}

#[test]
fn growth_past_the_i32_range_is_an_error_and_leaves_the_grid() {
    let spec = GridSpec::default();
    let edge = Coord::new(TILE_MAX, 0, TILE_MIN);
    let mut grid = grid_from(spec, &[(edge, 0.0)], |_| false);
    assert_eq!(grid.value(voxel_of(edge, 63)), 0.0);
    assert_eq!(voxel_of(edge, 63).x, i32::MAX);
    let before = grid.clone();
    assert!(matches!(grid.dilate(), Err(GridError::OutOfRange { .. })));
    assert_eq!(grid.tile_coords(), before.tile_coords());
    assert_eq!(grid.border_flags(0), before.border_flags(0));
    // Activity in the middle of the low-x face grows only towards -x, inside the range.
    grid.set_activity_flags(0, 1 << 12);
    assert_eq!(grid.manage_tiles().unwrap(), ManageStats { kept: 1, removed: 0, created: 1 });
    // Activity at the low-z face of the tile at z = TILE_MIN would leave the range.
    let p = grid.find_tile(edge).unwrap();
    grid.set_activity_flags(p, 1 << 4); // region (rx=1, ry=1, rz=0)
    let before = grid.clone();
    assert!(matches!(grid.manage_tiles(), Err(GridError::OutOfRange { .. })));
    assert_eq!(grid.tile_coords(), before.tile_coords());
}

#[test]
fn append_rejects_bad_input() {
    let spec = GridSpec::default();
    let mut grid = TileGrid::new(spec);
    assert_eq!(grid.value(Coord::new(i32::MIN, i32::MAX, 0)), spec.gamma());
    grid.append(Coord::new(0, 0, 0), &Tile::splat(10.0), 0).unwrap();
    assert_eq!(grid.tile(0), &Tile::splat(3.0), "values are clamped to γ");
    assert!(matches!(
        grid.append(Coord::new(0, 0, 0), &Tile::splat(0.0), 0),
        Err(GridError::NotSorted { .. })
    ));
    assert!(matches!(
        grid.append(Coord::new(5, -1, 0), &Tile::splat(0.0), 0),
        Err(GridError::NotSorted { .. })
    ));
    assert!(matches!(
        grid.append(Coord::new(0, 0, TILE_MAX + 1), &Tile::splat(0.0), 0),
        Err(GridError::OutOfRange { .. })
    ));
    let mut nan = Tile::splat(0.0);
    nan.0[17] = f32::NAN;
    assert_eq!(
        grid.append(Coord::new(1, 0, 0), &nan, 0),
        Err(GridError::NaN { coord: Coord::new(5, 0, 1) })
    );
    assert_eq!(grid.len(), 1);
    grid.check_invariants().unwrap();
}

#[test]
fn trigger_masks_match_fig4() {
    // Centre: all regions. Face: 9 regions. Edge: 3. Corner: 1.
    for d in 0..27 {
        let o = NEIGHBOURHOOD[d];
        let axes_off = (o.x != 0) as u32 + (o.y != 0) as u32 + (o.z != 0) as u32;
        assert_eq!(NEIGHBOUR_TRIGGER[d].count_ones(), [27, 9, 3, 1][axes_off as usize]);
    }
    assert_eq!(NEIGHBOUR_TRIGGER[MID], ACTIVE_MASK);
    // Every local voxel maps to the region its coordinates say.
    let mut per_region = BTreeMap::new();
    for l in 0..TILE_LEN {
        *per_region.entry(region_of_local(l)).or_insert(0) += 1;
    }
    assert_eq!(per_region.len(), 27);
    assert_eq!(per_region[&13], 8, "centre region is 2x2x2");
    assert_eq!(per_region[&0], 1, "corner region is one voxel");
}

#[test]
fn memory_reports_every_part() {
    let case = &cases(17, 1)[0];
    let grid = build(&case.shape, case.spec, case.lo, case.hi);
    let m = grid.memory();
    assert_eq!(m.values, grid.len() * 256);
    // The list (a 12-byte coordinate per tile, no id: the arena is in list order) plus the
    // row directory.
    assert!(m.indices >= grid.len() * 12 && m.indices < grid.len() * 12 + grid.len() * 8 + 4096);
    assert_eq!(m.flags, grid.len() * 8);
    assert_eq!(m.total(), m.values + m.indices + m.flags + m.slack);
}

fn check_block<const R: usize>(grid: &TileGrid) {
    let mut block = PaddedBlock::<R>::new();
    let mut cur = NeighbourCursor::new(grid.tile_coords(), 0, grid.len());
    let r = R as i32;
    while let Some(nb) = cur.next() {
        block.gather(grid, &nb);
        let base = voxel_of(nb.coord, 0);
        for z in -r..4 + r {
            for y in -r..4 + r {
                for x in -r..4 + r {
                    let v = base.wrapping_add(Coord::new(x, y, z));
                    assert_eq!(
                        block.get(x, y, z),
                        grid.value(v),
                        "tile {:?} voxel {v:?}",
                        nb.coord
                    );
                }
            }
        }
    }
}

/// The star gather fills the box rows and the axis rows (what a `TileWindow` reads) with
/// the grid's values, and the separable box minimum equals the 3×3×3 minimum of |φ|.
fn check_star_block<const R: usize>(grid: &TileGrid) {
    let mut block = PaddedBlock::<R>::new();
    let mut table = NeighbourTable::default();
    table.rebuild(grid.tile_coords());
    let r = R as i32;
    let g = grid.gamma();
    for pos in 0..grid.len() {
        block.gather_star_row(grid, pos, table.row(pos));
        let base = voxel_of(grid.tile_coords()[pos], 0);
        let read = |x: i32, y: i32, z: i32| grid.value(base.wrapping_add(Coord::new(x, y, z)));
        for z in -r..4 + r {
            for y in -r..4 + r {
                for x in -r..4 + r {
                    let inner = |v: i32| (0..4).contains(&v);
                    let boxed = [x, y, z].iter().all(|v| (-1..5).contains(v));
                    let axis = [inner(x) && inner(y), inner(x) && inner(z), inner(y) && inner(z)];
                    if boxed || axis.iter().any(|&a| a) {
                        assert_eq!(block.get(x, y, z), read(x, y, z), "tile {pos} at {x},{y},{z}");
                    }
                }
            }
        }
        let mut m = [0.0f32; 64];
        let any = block.box_min_abs(g, &mut m);
        for (l, &v) in m.iter().enumerate() {
            let (x, y, z) = ((l % 4) as i32, ((l / 4) % 4) as i32, (l / 16) as i32);
            let mut want = f32::INFINITY;
            for d in NEIGHBOURHOOD {
                want = want.min(read(x + d.x, y + d.y, z + d.z).abs());
            }
            assert_eq!(v.to_bits(), want.to_bits(), "box minimum of tile {pos} voxel {l}");
        }
        assert_eq!(any, m.iter().any(|&v| v < g));
    }
}

#[test]
fn star_block_equals_random_access() {
    for case in cases(18, 3) {
        let grid = build(&case.shape, case.spec, case.lo, case.hi);
        check_star_block::<1>(&grid);
        check_star_block::<3>(&grid);
        check_star_block::<4>(&grid);
    }
}

/// The tiles of one tile layer of `case`'s band (the middle tile's) as a grid of their own,
/// and that layer's z; with `extrude`, every tile's four z-slices copies of its first, as
/// a planar lattice keeps them.
fn one_layer(case: &Case, extrude: bool) -> (TileGrid, i32) {
    let full = build(&case.shape, case.spec, case.lo, case.hi);
    let layer = full.tile_coords()[full.len() / 2].z;
    let tiles: Vec<(Coord, Tile)> = full
        .tile_coords()
        .iter()
        .zip(full.values())
        .filter(|(c, _)| c.z == layer)
        .map(|(&c, &t)| {
            let mut t = t;
            if extrude {
                let first: [f32; 16] = t.0[..16].try_into().unwrap();
                t.0.chunks_exact_mut(16).for_each(|s| s.copy_from_slice(&first));
            }
            (c, t)
        })
        .collect();
    let inside = |t: Coord| truth(&case.shape, &case.spec, voxel_of(t, 0)) < 0.0;
    (TileGrid::from_sorted_tiles(case.spec, tiles, inside).unwrap(), layer)
}

/// On one tile layer extruded along z (every tile's slices copies of its first, as a
/// planar lattice keeps them), the planar gathers fill every entry that the first slice's
/// stencil reads on a planar lattice (the slice's own values: no kernel reads along z
/// there) with what the full gathers put there, and the planar box minima (over the slice's
/// squares) are the full ones (over the 3×3×3 boxes), bit for bit, in all four slices.
fn check_planar_block<const R: usize>(grid: &TileGrid) {
    let (mut full, mut planar) = (PaddedBlock::<R>::new(), PaddedBlock::<R>::new());
    let mut table = NeighbourTable::default();
    table.rebuild(grid.tile_coords());
    let (r, g) = (R as i32, grid.gamma());
    let inner = |v: i32| (0..4).contains(&v);
    for pos in 0..grid.len() {
        for axes in [false, true] {
            if axes {
                full.gather_axes_row(grid, pos, table.row(pos));
                planar.gather_axes_row_planar(grid, pos, table.row(pos));
            } else {
                full.gather_star_row(grid, pos, table.row(pos));
                planar.gather_star_row_planar(grid, pos, table.row(pos));
            }
            for z in -r..=r {
                for y in -r..4 + r {
                    for x in -r..4 + r {
                        let boxed = !axes && [x, y].iter().all(|v| (-1..5).contains(v)) && z == 0;
                        let along = [inner(y) && z == 0, inner(x) && z == 0];
                        if boxed || along.iter().any(|&a| a) {
                            let (a, b) = (planar.get(x, y, z), full.get(x, y, z));
                            assert_eq!(a.to_bits(), b.to_bits(), "tile {pos} at {x},{y},{z}");
                        }
                    }
                }
            }
        }
        full.gather_star_row(grid, pos, table.row(pos));
        planar.gather_star_row_planar(grid, pos, table.row(pos));
        let (mut a, mut b) = ([0.0f32; 64], [0.0f32; 64]);
        assert_eq!(planar.box_min_abs_planar(g, &mut a), full.box_min_abs(g, &mut b));
        assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "box minima of tile {pos}");
    }
}

#[test]
fn planar_block_equals_the_full_block_where_the_first_slice_reads() {
    for case in cases(23, 3) {
        let (grid, _) = one_layer(&case, true);
        check_planar_block::<1>(&grid);
        check_planar_block::<3>(&grid);
        check_planar_block::<4>(&grid);
    }
}

#[test]
fn padded_block_equals_random_access() {
    for case in cases(18, 3) {
        let grid = build(&case.shape, case.spec, case.lo, case.hi);
        check_block::<1>(&grid);
        check_block::<3>(&grid);
        check_block::<4>(&grid);
    }
}

#[test]
fn lower_bound_equals_partition_point() {
    let mut rng = fastrand::Rng::with_seed(3);
    for n in [0usize, 1, 2, 3, 7, 64, 1000] {
        let mut v: Vec<Coord> = (0..n)
            .map(|_| {
                let r = |rng: &mut fastrand::Rng| match rng.u8(0..4) {
                    0 => TILE_MIN,
                    1 => TILE_MAX,
                    _ => rng.i32(-5..5),
                };
                Coord::new(r(&mut rng), r(&mut rng), r(&mut rng))
            })
            .collect();
        v.sort();
        v.dedup();
        for _ in 0..200 {
            let c = Coord::new(rng.i32(-6..6), rng.i32(-6..6), rng.i32(-6..6));
            for q in [c, Coord::new(TILE_MIN, c.y, TILE_MAX), Coord::new(i32::MIN, i32::MAX, c.z)] {
                assert_eq!(lower_bound(&v, q), v.partition_point(|&x| x < q), "{q:?} in {v:?}");
            }
        }
    }
}

#[test]
fn row_directory_and_plain_search_agree() {
    for case in cases(19, 4) {
        let grid = build(&case.shape, case.spec, case.lo, case.hi);
        // Appending drops the directory: the copy answers by the plain binary search.
        let mut plain = grid.clone();
        let far = Coord::new(0, 0, TILE_MAX);
        plain.append(far, &Tile::splat(case.spec.gamma()), 0).unwrap();
        let (blo, bhi) = grid.bounding_box().unwrap();
        let m = Coord::new(5, 5, 5);
        for_box(blo.wrapping_sub(m), bhi.wrapping_add(m), |v| {
            assert_eq!(grid.value(v), plain.value(v), "{v:?}");
            let t = tile_of(v).0;
            assert_eq!(grid.tile_inside(t), plain.tile_inside(t), "{t:?}");
        });
        plain.build_directory();
        plain.check_invariants().unwrap();
        assert_eq!(plain.value(voxel_of(far, 5)), case.spec.gamma());
    }
    // A sparse layout (two tiles far apart) keeps no directory and still answers.
    let spec = GridSpec::default();
    let g = grid_from(
        spec,
        &[(Coord::new(0, 0, -1000), -1.0), (Coord::new(7, 900, 1000), 1.0)],
        |_| false,
    );
    g.check_invariants().unwrap();
    assert_eq!(g.value(Coord::new(1, 1, -3999)), -1.0);
    assert_eq!(g.value(Coord::new(29, 3601, 4001)), 1.0);
    assert_eq!(g.value(Coord::new(29, 3601, 0)), 3.0);
}

/// A planar band (one tile layer) managed as planar keeps to its layer: the same list as
/// the 3-D management without the tiles it creates above and below, the same values and
/// flags, for random activity.
#[test]
fn planar_management_creates_no_tile_outside_the_layer() {
    let mut rng = fastrand::Rng::with_seed(11);
    let mut outside = 0;
    for case in cases(41, 4) {
        let (mut grid, layer) = one_layer(&case, false);
        for _round in 0..4 {
            randomize_activity(&mut grid, &mut rng);
            let mut spatial = grid.clone();
            spatial.manage_tiles().unwrap();
            grid.manage_tiles_checked(None, |_| Ok(()), &mut Vec::new(), true, true).unwrap();
            grid.check_invariants().unwrap();
            assert!(grid.tile_coords().iter().all(|c| c.z == layer), "a tile left the layer");
            let in_layer: Vec<usize> =
                (0..spatial.len()).filter(|&p| spatial.tile_coords()[p].z == layer).collect();
            outside += spatial.len() - in_layer.len();
            assert_eq!(grid.len(), in_layer.len());
            for (p, &q) in in_layer.iter().enumerate() {
                assert_eq!(grid.tile_coords()[p], spatial.tile_coords()[q]);
                assert_eq!(grid.values()[p], spatial.values()[q], "values of {p}");
                assert_eq!(grid.border_flags(p), spatial.border_flags(q), "border of {p}");
                assert_eq!(grid.activity_flags(p), spatial.activity_flags(q), "activity of {p}");
            }
        }
    }
    // The 3-D management did create tiles above and below.
    assert!(outside > 0);
}
