//! The instruction-set levels: every level this CPU has, every lane kind at each, against
//! each other bit for bit (`dispatch_at`), and the baseline against the fused levels.
//!
//! On a CPU without AVX2 only the baseline runs here; CI's machines have AVX2 and FMA
//! (most also AVX-512), so the comparisons between levels run there.

use levelset_kernels::bench::Fixture;
use levelset_kernels::{dispatch_at, Lane, LaneFn, LaneKind, Level};

/// Both benchmark kernels over a 24³ sphere block with lane type `L`: the Euler step of
/// eq. (3) with upwind differences and curvature, and a TVD-RK3 stage with HJ-WENO5.
struct Kernels<'a> {
    fx: &'a Fixture,
}

impl LaneFn for Kernels<'_> {
    type Output = (Vec<f32>, Vec<f32>);
    #[inline(always)]
    fn call<L: Lane>(self) -> Self::Output {
        let (mut a, mut b) = (self.fx.output(), self.fx.output());
        self.fx.upwind_curvature::<L>(&mut a).unwrap();
        self.fx.weno5_rk3::<L>(&mut b).unwrap();
        (a, b)
    }
}

/// Every operation of [`Lane`] on a lane group of awkward values, one result per
/// operation and lane.
struct Ops<'a> {
    a: &'a [f32],
    b: &'a [f32],
}

impl LaneFn for Ops<'_> {
    type Output = Vec<f32>;
    #[inline(always)]
    fn call<L: Lane>(self) -> Vec<f32> {
        let mut out = Vec::new();
        for first in (0..self.a.len()).step_by(L::LANES) {
            let (a, b) = (L::load(&self.a[first..]), L::load(&self.b[first..]));
            let c = L::splat(0.75);
            let results = [
                a + b,
                a - b,
                a * b,
                a / b,
                -a,
                a.mul_add(b, c),
                Lane::min(a, b),
                Lane::max(a, b),
                Lane::abs(a),
                Lane::sqrt(a),
                a.select_gt(b, c, a),
                L::splat(if a.any_gt(b) { 1.0 } else { 0.0 }),
            ];
            let mut buf = vec![0.0f32; L::LANES];
            for r in results {
                r.store(&mut buf);
                out.extend_from_slice(&buf);
            }
        }
        out
    }
}

fn levels() -> Vec<Level> {
    Level::ALL.into_iter().filter(|l| l.available()).collect()
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// NaN payloads are not specified: every NaN compares as one pattern.
fn canonical(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| if x.is_nan() { u32::MAX } else { x.to_bits() }).collect()
}

#[test]
fn every_lane_kind_gives_the_same_bits_as_the_levels_scalar() {
    let fx = Fixture::new([24, 24, 24]).unwrap();
    for level in levels() {
        let scalar = dispatch_at(level, LaneKind::F32, Kernels { fx: &fx }).unwrap();
        for kind in LaneKind::ALL {
            let v = dispatch_at(level, kind, Kernels { fx: &fx }).unwrap();
            assert_eq!(bits(&v.0), bits(&scalar.0), "{level}, {}: upwind", kind.name());
            assert_eq!(bits(&v.1), bits(&scalar.1), "{level}, {}: WENO5", kind.name());
        }
    }
}

#[test]
fn every_level_with_fma_gives_the_same_bits() {
    let fx = Fixture::new([24, 24, 24]).unwrap();
    let fused: Vec<Level> = levels().into_iter().filter(|l| l.fused()).collect();
    let Some(&first) = fused.first() else { return };
    let reference = dispatch_at(first, LaneKind::F32x16, Kernels { fx: &fx }).unwrap();
    for &level in &fused[1..] {
        let v = dispatch_at(level, LaneKind::F32x16, Kernels { fx: &fx }).unwrap();
        assert_eq!(bits(&v.0), bits(&reference.0), "{level} against {first}: upwind");
        assert_eq!(bits(&v.1), bits(&reference.1), "{level} against {first}: WENO5");
    }
}

/// What a CPU without FMA gets: the baseline level of a build without FMA rounds
/// `mul_add` twice. Its results then differ from the fused levels' in some voxels, by
/// rounding only (the same accuracy); with FMA compiled in, they are the same bits.
#[test]
fn the_baseline_without_fma_differs_from_the_fused_levels_by_rounding_only() {
    let fx = Fixture::new([24, 24, 24]).unwrap();
    let base = dispatch_at(Level::Baseline, LaneKind::F32x8, Kernels { fx: &fx }).unwrap();
    let Some(fused) = levels().into_iter().rev().find(|l| l.fused() && *l != Level::Baseline)
    else {
        return;
    };
    let f = dispatch_at(fused, LaneKind::F32x8, Kernels { fx: &fx }).unwrap();
    for (name, b, f) in [("upwind", &base.0, &f.0), ("WENO5", &base.1, &f.1)] {
        let differing = b.iter().zip(f).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
        if Level::Baseline.fused() {
            assert_eq!(differing, 0, "{name}: a build with FMA fuses at the baseline too");
        } else {
            assert!(differing > 0, "{name}: unfused and fused rounding never differed");
        }
        // Values of order 1 (a distance field in voxels, clamped to the band γ = 3):
        // rounding differences of a few ulps, nothing more.
        for (x, y) in b.iter().zip(f) {
            assert!((x - y).abs() <= 1e-5 + 1e-5 * y.abs(), "{name}: {x} against {y}");
        }
    }
}

#[test]
fn every_operation_follows_the_lane_rules_at_every_level() {
    let specials = [
        0.0,
        -0.0,
        1.5,
        -2.25,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1e-38,
        3.0e38,
        -7.0,
        0.1,
        2.0,
        -0.0,
        5.0,
        f32::MIN_POSITIVE,
        9.0,
    ];
    // Every pair of the specials, in 16-lane groups.
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for x in specials {
        for y in specials {
            a.push(x);
            b.push(y);
        }
    }
    for level in levels() {
        let scalar = dispatch_at(level, LaneKind::F32, Ops { a: &a, b: &b }).unwrap();
        // Per lane, the scalar results of a group: re-ordered to compare with the wider
        // kinds, whose results come lane group by lane group.
        for kind in LaneKind::ALL {
            let n = kind.lanes();
            let v = dispatch_at(level, kind, Ops { a: &a, b: &b }).unwrap();
            let mut expect = Vec::with_capacity(v.len());
            for g in 0..a.len() / n {
                for op in 0..12 {
                    for lane in 0..n {
                        expect.push(scalar[(g * n + lane) * 12 + op]);
                    }
                }
            }
            // `any_gt` is per group, not per lane.
            let ops_but_any = |v: &[f32]| -> Vec<u32> {
                canonical(v)
                    .chunks(n)
                    .enumerate()
                    .filter(|(i, _)| i % 12 != 11)
                    .flat_map(|(_, c)| c.to_vec())
                    .collect()
            };
            assert_eq!(ops_but_any(&v), ops_but_any(&expect), "{level}, {}", kind.name());
        }
        // The documented NaN rule of min and max: the second operand.
        let i = specials.len() * 4; // a = NaN, b = 0.0
        assert_eq!(scalar[i * 12 + 6].to_bits(), 0.0f32.to_bits(), "{level}: min(NaN, 0)");
        assert_eq!(scalar[i * 12 + 7].to_bits(), 0.0f32.to_bits(), "{level}: max(NaN, 0)");
        // Fused at the levels with FMA: (1 + 2⁻¹²)² − (1 + 2⁻¹¹) is 2⁻²⁴ rounded once and
        // 0 rounded twice (the product's 2⁻²⁴ is half an ulp, rounded to even).
        let (x, z) = (1.0 + 2f32.powi(-12), -(1.0 + 2f32.powi(-11)));
        for kind in LaneKind::ALL {
            let got = dispatch_at(level, kind, Fma { a: x, b: x, c: z }).unwrap();
            let want = if level.fused() { 2f32.powi(-24) } else { 0.0 };
            assert_eq!(got.to_bits(), want.to_bits(), "{level}, {}: mul_add", kind.name());
        }
    }
}

/// `a × b + c` with [`Lane::mul_add`], from every lane of a group (all must agree).
struct Fma {
    a: f32,
    b: f32,
    c: f32,
}

impl LaneFn for Fma {
    type Output = f32;
    #[inline(always)]
    fn call<L: Lane>(self) -> f32 {
        let r = L::splat(self.a).mul_add(L::splat(self.b), L::splat(self.c));
        let mut buf = vec![0.0f32; L::LANES];
        r.store(&mut buf);
        assert!(buf.iter().all(|v| v.to_bits() == buf[0].to_bits()), "lanes differ");
        buf[0]
    }
}

#[test]
fn levels_have_names_and_the_detected_one_is_available() {
    for l in Level::ALL {
        assert_eq!(Level::from_name(l.name()), Some(l));
        assert!(l.describe().starts_with(l.name()));
    }
    assert_eq!(Level::from_name("sse9"), None);
    assert!(Level::detected().available());
    assert!(Level::Baseline.available());
    assert!(Level::active().available());
    // An unavailable level is refused, not run at another.
    for l in Level::ALL.into_iter().filter(|l| !l.available()) {
        assert!(dispatch_at(l, LaneKind::F32, Kernels { fx: &Fixture::new([8, 8, 8]).unwrap() })
            .is_none());
    }
}
