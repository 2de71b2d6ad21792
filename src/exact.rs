//! Order-independent sums: every reduction of the evolution (κ̄ of eq. (6), volume, area)
//! adds f32 terms as fixed-point integers, so the result does not depend on the order of
//! the terms — not on the representation (tiles, DT-Grid, dense), not on the number of
//! threads or how the work was cut into chunks.

/// Fixed-point scale: a term `v` counts as `v · 2³²` rounded to the nearest integer (ties
/// to even), an i64. Exact for every f32 term of magnitude ≥ 2⁻⁸ (its 24 mantissa bits
/// then lie above the 32nd binary place); smaller terms are rounded to 2⁻³² ≈ 2.3·10⁻¹⁰,
/// identically wherever they are added.
const SCALE: f64 = 4_294_967_296.0; // 2^32

/// Largest term magnitude counted as such: larger terms saturate to ±2²⁴ (and NaN counts
/// as 0). Then 64 fixed-point terms sum to less than 2⁶³ in an i64, so a block of 64
/// terms is added in i64 lanes (vectorised: the conversion, rounding and sum compile to
/// packed instructions) before it joins the i128 total, which holds 2⁶⁴ such blocks.
const LIMIT: f64 = 16_777_216.0 * SCALE; // 2^24 · 2^32

/// Terms per i64 block.
const BLOCK: usize = 64;

/// 2⁵²: every f64 of at least this magnitude is an integer.
const TWO_52: f64 = 4_503_599_627_370_496.0;

/// `x` rounded to the nearest integer, ties to even: the same value as
/// [`f64::round_ties_even`] (for NaN, a NaN). Adding and removing 2⁵² (with `x`'s sign)
/// leaves no fraction bit, and the default rounding mode rounds that sum to even (the sign
/// is `x`'s, as `round_ties_even` keeps it for a zero result), so this
/// compiles to packed additions and a blend at every instruction-set level, where
/// `round_ties_even` is a call to the C library's `rint` per term when the build's
/// baseline lacks SSE4.1's rounding instructions.
#[inline(always)]
fn round_even(x: f64) -> f64 {
    let c = TWO_52.copysign(x);
    if x.abs() < TWO_52 {
        ((x + c) - c).copysign(x)
    } else {
        x
    }
}

/// A sum of f32 terms that is exact up to the fixed-point rounding of each term, hence
/// associative and commutative.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExactSum(i128);

/// The fixed-point value of one term (saturated, NaN → 0).
#[inline(always)]
fn fixed(v: f32) -> i64 {
    let x = round_even(v as f64 * SCALE);
    // `max`/`min` of f64 return the other operand for NaN: NaN becomes −LIMIT here, so
    // test it first.
    if x.is_nan() {
        0
    } else {
        // SAFETY: |x| ≤ 2⁵⁶ after clamping, an integer-valued f64 that fits an i64.
        unsafe { x.clamp(-LIMIT, LIMIT).to_int_unchecked::<i64>() }
    }
}

impl ExactSum {
    /// Adds one term. A huge term (|v| > 2²⁴) saturates and NaN counts as 0; the
    /// evolution's terms are bounded by the band's values and the kernels' bounded
    /// outputs.
    #[inline]
    pub fn add(&mut self, v: f32) {
        self.0 += fixed(v) as i128;
    }

    /// Adds every value of a slice (the same total as adding them one by one).
    #[inline]
    pub fn add_all(&mut self, vs: &[f32]) {
        let mut blocks = vs.chunks_exact(BLOCK);
        for b in &mut blocks {
            // ≤ 64 terms of magnitude ≤ 2⁵⁶: the i64 sum cannot overflow.
            let s: i64 = b.iter().map(|&v| fixed(v)).sum();
            self.0 += s as i128;
        }
        for &v in blocks.remainder() {
            self.add(v);
        }
    }

    /// Adds another sum.
    #[inline]
    pub fn merge(self, other: ExactSum) -> ExactSum {
        ExactSum(self.0 + other.0)
    }

    /// The fixed-point total (units of 2⁻³²): what ranks exchange to add their sums.
    pub fn to_bits(self) -> i128 {
        self.0
    }

    /// A sum from its fixed-point total ([`ExactSum::to_bits`]).
    pub fn from_bits(bits: i128) -> ExactSum {
        ExactSum(bits)
    }

    /// The sum as f64.
    pub fn value(self) -> f64 {
        self.0 as f64 / SCALE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_even_is_round_ties_even() {
        let mut rng = fastrand::Rng::with_seed(3);
        let mut xs: Vec<f64> =
            vec![0.0, -0.0, 0.5, 1.5, 2.5, -0.5, -1.5, -2.5, 0.49999999999999994];
        for e in [52, 53, 60] {
            let t = 2f64.powi(e);
            xs.extend([t, -t, t - 0.5, t + 1.0, -(t - 0.5), t - 1.5, f64::MAX, f64::INFINITY]);
        }
        xs.extend((0..100_000).map(|_| (rng.f64() - 0.5) * 2f64.powi(rng.i32(-4..58))));
        // Every tie at the 2⁻³² grid of an f32 term.
        xs.extend((0..1000).map(|k| (k as f64 - 500.0) + 0.5));
        for x in xs {
            for x in [x, -x] {
                assert_eq!(round_even(x).to_bits(), x.round_ties_even().to_bits(), "{x:e}");
            }
        }
        assert!(round_even(f64::NAN).is_nan());
    }

    #[test]
    fn order_does_not_matter() {
        let mut rng = fastrand::Rng::with_seed(7);
        let terms: Vec<f32> =
            (0..10_000).map(|_| (rng.f32() - 0.5) * 10f32.powi(rng.i32(-3..4))).collect();
        let mut a = ExactSum::default();
        a.add_all(&terms);
        let mut b = ExactSum::default();
        for &t in terms.iter().rev() {
            b.add(t);
        }
        let (mut c1, mut c2) = (ExactSum::default(), ExactSum::default());
        c1.add_all(&terms[..3333]);
        c2.add_all(&terms[3333..]);
        assert_eq!(a, b);
        assert_eq!(a, c2.merge(c1));
        let naive: f64 = terms.iter().map(|&t| t as f64).sum();
        assert!((a.value() - naive).abs() <= 1e-9 * (1.0 + naive.abs()));
    }

    #[test]
    fn blocks_equal_single_terms_with_nan_huge_and_ties() {
        let mut rng = fastrand::Rng::with_seed(11);
        let mut terms: Vec<f32> = (0..1000).map(|_| (rng.f32() - 0.5) * 1e-3).collect();
        // A tie at the 2⁻³² grid (rounds to even), NaN, ±∞ and terms beyond the 2²⁴ limit.
        terms.extend([3.0 * 2f32.powi(-33), f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 3e7, -3e7]);
        rng.shuffle(&mut terms);
        let mut a = ExactSum::default();
        a.add_all(&terms);
        let mut b = ExactSum::default();
        for &t in &terms {
            b.add(t);
        }
        assert_eq!(a, b);
        let mut tie = ExactSum::default();
        tie.add(3.0 * 2f32.powi(-33)); // 1.5 units of 2⁻³²: ties to 2
        assert_eq!(tie.0, 2);
        let mut sat = ExactSum::default();
        sat.add_all(&[f32::INFINITY, 1.0, f32::NAN]);
        assert_eq!(sat.value(), 16_777_217.0);
    }
}
