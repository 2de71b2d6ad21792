//! Shared test helpers: the every-width macro, a deterministic RNG, comparisons, fills.
#![allow(dead_code, unused_macros, unused_imports)]

/// Runs `$body` once per SIMD lane type (not `f32`).
macro_rules! for_simd_lanes {
    (|$L:ident| $body:block) => {{
        {
            type $L = ::levelset_kernels::wide::f32x4;
            $body
        }
        {
            type $L = ::levelset_kernels::wide::f32x8;
            $body
        }
        {
            type $L = ::levelset_kernels::wide::f32x16;
            $body
        }
    }};
}
pub(crate) use for_simd_lanes;

/// Runs `$body` once per lane type with `$L` bound to it, like wide's `for_simd_types!`.
macro_rules! for_lanes {
    (|$L:ident| $body:block) => {{
        {
            type $L = f32;
            $body
        }
        $crate::common::for_simd_lanes!(|$L| $body);
    }};
}
pub(crate) use for_lanes;

/// SplitMix64: small, deterministic, good enough for test data.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

pub const GAMMA: f32 = 3.0;

/// The edge values every lane test mixes in: signed zeros, the band limits ±γ, tiny and
/// subnormal magnitudes, huge magnitudes, and non-finite values.
pub const EDGE: &[f32] = &[
    0.0,
    -0.0,
    GAMMA,
    -GAMMA,
    1e-30,
    -1e-30,
    1e-40, // subnormal
    -1e-40,
    f32::MIN_POSITIVE,
    1e15,
    -1e15,
    1e30,
    -1e30,
    f32::MAX,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::NAN,
    0.5,
    -0.5,
    1.0,
];

/// Bitwise equality, except that any NaN equals any NaN (wide does not specify payloads).
pub fn same_bits(a: f32, b: f32) -> bool {
    (a.is_nan() && b.is_nan()) || a.to_bits() == b.to_bits()
}

/// |a − b| ≤ abs + rel · |b| (both NaN or equal infinities also pass).
pub fn close(a: f64, b: f64, abs: f64, rel: f64) -> bool {
    if a.is_nan() || b.is_nan() {
        return a.is_nan() && b.is_nan();
    }
    if a.is_infinite() || b.is_infinite() {
        return a == b;
    }
    (a - b).abs() <= abs + rel * b.abs()
}

/// The kind of data a block is filled with.
#[derive(Clone, Copy, Debug)]
pub enum Fill {
    /// Random band values in (−γ, γ) with a sprinkling of edge values.
    Mixed,
    /// Only values from `EDGE` (incl. NaN, ±∞).
    Edge,
    /// A clamped sphere distance with flat ±γ regions.
    Sphere,
    /// Random values in ±1e-30 (tiny).
    Tiny,
    /// Random values in ±1e15 (huge but with finite squares).
    Huge,
    /// Constant (flat) region.
    Flat,
}

pub fn value(fill: Fill, rng: &mut Rng, p: [f64; 3]) -> f32 {
    match fill {
        Fill::Mixed => {
            if rng.below(8) == 0 {
                EDGE[rng.below(EDGE.len())]
            } else {
                rng.range(-GAMMA as f64, GAMMA as f64) as f32
            }
        }
        Fill::Edge => EDGE[rng.below(EDGE.len())],
        Fill::Sphere => {
            let d =
                ((p[0] - 3.3).powi(2) + (p[1] - 2.1).powi(2) + (p[2] - 1.7).powi(2)).sqrt() - 4.2;
            d.clamp(-GAMMA as f64, GAMMA as f64) as f32
        }
        Fill::Tiny => rng.range(-1e-30, 1e-30) as f32,
        Fill::Huge => rng.range(-1e15, 1e15) as f32,
        Fill::Flat => -GAMMA,
    }
}

pub const FILLS: [Fill; 6] =
    [Fill::Mixed, Fill::Edge, Fill::Sphere, Fill::Tiny, Fill::Huge, Fill::Flat];
