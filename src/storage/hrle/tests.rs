use super::*;
use crate::storage::convert::{dtgrid_from, tiles_from, tiles_from_shape};
use crate::storage::dtgrid::DtGrid;
use crate::storage::shapes::Shape;
use crate::storage::tiles::TileGrid;

fn sphere(r: f64, c: [f64; 3]) -> TileGrid {
    tiles_from_shape(&Shape::Sphere { center: c, radius: r }, GridSpec::default()).unwrap()
}

fn torus() -> TileGrid {
    let t = Shape::Torus { center: [0.5, -0.25, 0.125], major_radius: 14.0, minor_radius: 5.0 };
    tiles_from_shape(&t, GridSpec::default()).unwrap()
}

/// Every voxel of the band's box grown by `m`.
fn each_voxel(ls: &impl LevelSet, m: i32, mut f: impl FnMut(Coord)) {
    let (lo, hi) = ls.band_bounding_box().unwrap();
    for z in lo.z - m..=hi.z + m {
        for y in lo.y - m..=hi.y + m {
            for x in lo.x - m..=hi.x + m {
                f(Coord::new(x, y, z));
            }
        }
    }
}

fn same_everywhere(a: &impl LevelSet, b: &impl LevelSet, m: i32) {
    assert_eq!(a.checksum(), b.checksum());
    assert_eq!(a.band_voxels(), b.band_voxels());
    let mut acc = b.accessor();
    each_voxel(a, m, |c| {
        let (u, v) = (a.value(c), acc.value(c));
        assert_eq!(u.to_bits(), v.to_bits(), "{c}: {u} vs {v}");
    });
}

#[test]
fn round_trips_through_tiles_and_dtgrid_bit_for_bit() {
    for t in [sphere(12.3, [0.3, -0.2, 0.1]), torus(), sphere(3.5, [-40.0, 7.0, 100.0])] {
        let h = HrleGrid::from_level_set(&t).unwrap();
        h.check_invariants().unwrap();
        same_everywhere(&h, &t, 4);
        let d = dtgrid_from(&t);
        let hd = HrleGrid::from_level_set(&d).unwrap();
        assert_eq!(hd, h, "from tiles and from the DT-Grid: one encoding");
        same_everywhere(&hd, &d, 4);
        let back = tiles_from(&h);
        same_everywhere(&back, &t, 4);
        same_everywhere(&dtgrid_from(&h), &d, 4);
        assert_eq!(h.bounding_box(), t.band_bounding_box());
    }
}

#[test]
fn random_cached_and_neighbour_access_agree() {
    let t = torus();
    let h = HrleGrid::from_level_set(&t).unwrap();
    let mut acc = h.accessor();
    let mut rng = fastrand::Rng::with_seed(7);
    let (lo, hi) = h.bounding_box().unwrap();
    for _ in 0..20_000 {
        let c = Coord::new(
            rng.i32(lo.x - 3..=hi.x + 3),
            rng.i32(lo.y - 3..=hi.y + 3),
            rng.i32(lo.z - 3..=hi.z + 3),
        );
        let v = t.value(c);
        assert_eq!(h.value(c).to_bits(), v.to_bits(), "{c}");
        assert_eq!(acc.value(c).to_bits(), v.to_bits(), "{c}");
        let loc = h.locate(c);
        assert_eq!(h.value_at(&loc).to_bits(), v.to_bits());
        for axis in 0..3 {
            for step in [-1, 1] {
                let n = h.neighbour(&loc, axis, step);
                let mut e = [0; 3];
                e[axis] = step;
                let nc = Coord::new(c.x + e[0], c.y + e[1], c.z + e[2]);
                assert_eq!(n.coord, nc);
                assert_eq!(h.value_at(&n).to_bits(), t.value(nc).to_bits(), "{nc}");
                // Walking on along x stays O(1) and right.
                let nn = h.neighbour(&n, 0, step);
                assert_eq!(h.value_at(&nn).to_bits(), t.value(nn.coord).to_bits());
            }
        }
    }
}

#[test]
fn stencil_iterator_reads_the_six_neighbours() {
    let t = sphere(9.7, [0.2, 0.4, -0.3]);
    let h = HrleGrid::from_level_set(&t).unwrap();
    let mut n = 0;
    h.for_each_star(|c, i, s| {
        assert_eq!(s[0], h.values()[i]);
        let nb = [(-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)];
        for (k, (dx, dy, dz)) in nb.into_iter().enumerate() {
            let q = Coord::new(c.x + dx, c.y + dy, c.z + dz);
            assert_eq!(s[k + 1].to_bits(), t.value(q).to_bits(), "{c} neighbour {q}");
        }
        n += 1;
    });
    assert_eq!(n, h.len());
}

#[test]
fn dilation_and_rebuild_match_the_dtgrid() {
    let t = torus();
    let h = HrleGrid::from_level_set(&t).unwrap();
    let d = dtgrid_from(&t);
    for n in [1, 2] {
        let hd = h.dilate(n).unwrap();
        hd.check_invariants().unwrap();
        let dd = d.dilate(n).unwrap();
        assert_eq!(hd.len(), dd.len(), "n = {n}");
        let mut stored = Vec::new();
        hd.for_each_defined(|c, i| stored.push((c, hd.values()[i].to_bits())));
        let theirs: Vec<_> = dd.iter().map(|(c, v)| (c, v.to_bits())).collect();
        assert_eq!(stored, theirs, "n = {n}");
        same_everywhere(&hd, &dd, 3);
    }
    let w = 1.5;
    let hr = h.rebuild(w, w).unwrap();
    let dr = d.rebuild(w, 1).unwrap();
    let mut stored = Vec::new();
    hr.for_each_defined(|c, i| stored.push((c, hr.values()[i].to_bits())));
    assert_eq!(stored, dr.iter().map(|(c, v)| (c, v.to_bits())).collect::<Vec<_>>());
    same_everywhere(&hr, &dr, 3);
}

#[test]
fn asymmetric_prune_keeps_the_sign_everywhere() {
    let t = sphere(11.2, [0.1, 0.2, 0.3]);
    let h = HrleGrid::from_level_set(&t).unwrap();
    let p = h.prune(1.0, 2.5).unwrap();
    p.check_invariants().unwrap();
    let mut kept = 0;
    h.for_each_defined(|c, i| {
        let v = h.values()[i];
        if -1.0 < v && v < 2.5 {
            kept += 1;
            assert_eq!(p.value(c), v);
        } else {
            assert_eq!(p.value(c), if v < 0.0 { -3.0 } else { 3.0 }, "{c}");
        }
    });
    assert_eq!(p.len(), kept);
    assert!(p.len() < h.len());
    each_voxel(&t, 3, |c| assert_eq!(p.value(c) < 0.0, t.value(c) < 0.0, "{c}"));
    for bad in [(0.5, 2.0), (2.0, f32::NAN), (f32::INFINITY, 2.0)] {
        assert!(h.prune(bad.0, bad.1).is_err());
    }
}

#[test]
fn clipping_leaves_the_surface_open_and_costs_less_than_closing_it() {
    let t = sphere(20.0, [0.25, 0.5, -0.5]);
    let h = HrleGrid::from_level_set(&t).unwrap();
    let (lo, hi) = (Coord::new(-100, -100, -100), Coord::new(0, 100, 100));
    let open = h.clip(lo, hi).unwrap();
    open.check_invariants().unwrap();
    each_voxel(&t, 3, |c| {
        let want = if c.x <= 0 { t.value(c) } else { 3.0 };
        assert_eq!(open.value(c), want, "{c}");
    });
    // The closed hemisphere (sphere ∩ {x ≤ 0}) stored by the DT-Grid needs a band on the
    // cut; the open one does not.
    let half = crate::storage::convert::tiles_from_sdf(
        |p| {
            (((p[0] - 0.25).powi(2) + (p[1] - 0.5).powi(2) + (p[2] + 0.5).powi(2)).sqrt() - 20.0)
                .max(p[0])
        },
        1.0,
        Coord::new(-30, -30, -30),
        Coord::new(30, 30, 30),
        GridSpec::default(),
    )
    .unwrap();
    let closed = dtgrid_from(&half);
    assert!(open.band_voxels() + 2000 < closed.band_voxels());
    assert!(open.memory().used() < closed.memory().used());
    // Dilating keeps the domain.
    let dil = open.dilate(1).unwrap();
    assert!(dil.bounding_box().unwrap().1.x <= 0);
    assert_eq!(dil.value(Coord::new(1, 0, 0)), 3.0);
    assert!(h.clip(Coord::new(1, 0, 0), Coord::new(0, 5, 5)).is_err());
}

#[test]
fn fields_share_the_encoding_and_follow_their_voxels() {
    let t = sphere(8.4, [0.0; 3]);
    let mut h = HrleGrid::from_level_set(&t).unwrap();
    h.add_scalar_field("height", |c, _| c.z as f32).unwrap();
    h.add_vector_field("velocity", |c, v| [c.x as f32, c.y as f32, v]).unwrap();
    assert!(h.add_scalar_field("height", |_, _| 0.0).is_err());
    assert!(h.add_field("short", FieldData::Scalar(vec![1.0])).is_err());
    assert!(h.add_scalar_field("nan", |_, _| f32::NAN).is_err());
    assert_eq!(h.fields().len(), 2);
    let c = Coord::new(8, 0, 1);
    assert_eq!(h.scalar_at("height", c), Some(1.0));
    assert_eq!(h.vector_at("velocity", c), Some([8.0, 0.0, h.value(c)]));
    assert_eq!(h.scalar_at("velocity", c), None);
    let d = h.dilate(1).unwrap();
    d.check_invariants().unwrap();
    d.for_each_defined(|c, i| {
        let v = d.values()[i];
        let was_stored = h.locate_index(c).is_ok();
        let want = if was_stored { c.z as f32 } else { 0.0 };
        assert_eq!(d.scalar_at("height", c), Some(want), "{c} {v}");
    });
    let p = h.prune(1.0, 1.0).unwrap();
    p.for_each_defined(|c, _| assert_eq!(p.vector_at("velocity", c).unwrap()[0], c.x as f32));
    assert!(h.memory().values > 4 * 4 * h.len() - 1);
}

struct Signs(bool);
impl SignOracle for Signs {
    fn inside(&mut self, _: Coord) -> bool {
        self.0
    }
    fn column_inside(&mut self, _: i32, _: i32) -> bool {
        self.0
    }
    fn plane_inside(&mut self, _: i32) -> bool {
        self.0
    }
}

#[test]
fn builder_refuses_bad_voxels_and_changes_nothing() {
    let spec = GridSpec::default();
    let mut b = Builder::new(spec, Signs(false));
    b.push(Coord::new(0, 0, 0), 0.5).unwrap();
    let e = |r: Result<(), GridError>| r.unwrap_err();
    assert!(matches!(e(b.push(Coord::new(0, 0, 0), 0.1)), GridError::NotSorted { .. }));
    assert!(matches!(e(b.push(Coord::new(5, 0, 0), f32::NAN)), GridError::NaN { .. }));
    assert!(matches!(e(b.push(Coord::new(5, 0, 0), 3.5)), GridError::InvalidParameter(_)));
    assert!(matches!(e(b.push(Coord::new(i32::MAX, 0, 0), 0.0)), GridError::OutOfRange { .. }));
    b.push(Coord::new(i32::MAX - 1, 0, 0), -0.25).unwrap();
    b.push(Coord::new(0, i32::MIN + 1, 5), 3.0).unwrap();
    let g = b.finish();
    g.check_invariants().unwrap();
    assert_eq!(g.len(), 3);
    assert_eq!(g.band_voxels(), 2);
    assert_eq!(g.value(Coord::new(i32::MAX - 1, 0, 0)), -0.25);
    assert_eq!(g.value(Coord::new(i32::MAX, 0, 0)), 3.0);
    assert_eq!(g.value(Coord::new(0, i32::MIN + 1, 5)), 3.0);
    // Dilating past the representable range is refused.
    assert!(matches!(g.dilate(1), Err(GridError::OutOfRange { .. })));
    // Empty grids, all outside or all inside.
    let empty = Builder::new(spec, Signs(true)).finish();
    empty.check_invariants().unwrap();
    assert_eq!(empty.value(Coord::new(4, 5, 6)), -3.0);
    assert_eq!(HrleGrid::new(spec).value(Coord::new(4, 5, 6)), 3.0);
    assert!(HrleGrid::from_level_set(&DtGrid::new(spec)).unwrap().is_empty());
}

#[test]
fn invariant_check_finds_broken_grids() {
    let t = sphere(6.0, [0.0; 3]);
    let h = HrleGrid::from_level_set(&t).unwrap();
    let mut bad = h.clone();
    bad.values[3] = f32::NAN;
    assert!(bad.check_invariants().unwrap_err().contains("NaN"));
    let mut bad = h.clone();
    let b = bad.blocks[2].breaks.len() / 2;
    bad.blocks[2].breaks.swap(b, b + 1);
    assert!(bad.check_invariants().is_err());
    let mut bad = h.clone();
    let k = bad.blocks[1].codes.iter().position(|&c| c < POS && c > 0).unwrap();
    bad.blocks[1].codes[k] += 1;
    assert!(bad.check_invariants().is_err());
    let mut bad = h;
    bad.band += 1;
    assert!(bad.check_invariants().is_err());
}

#[test]
fn memory_is_close_to_the_dtgrid_for_a_closed_band() {
    let t = sphere(40.0, [0.5; 3]);
    let h = HrleGrid::from_level_set(&t).unwrap();
    let d = dtgrid_from(&t);
    let (a, b) = (h.memory().used() as f64, d.memory().used() as f64);
    assert!(a > b && a < 1.15 * b, "H-RLE {a} bytes, DT-Grid {b}");
}

#[test]
fn smoothing_reads_the_same_stencils_as_the_dtgrid() {
    let t = torus();
    let h = HrleGrid::from_level_set(&t).unwrap();
    let d = dtgrid_from(&t);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    crate::bench::hrle_smooth7(&h, &mut a);
    crate::bench::dtgrid_smooth7(&d, &mut b);
    assert_eq!(a.len(), b.len());
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
}
