//! Where the ranks' slabs begin: cuts that balance the tile counts, and the ranges of the
//! sorted tile list each rank owns and stores.

use super::GHOST;
use crate::coord::Coord;
use std::ops::Range;

/// Cuts that balance the tile counts: `slabs` lists (tile z, tiles) for every non-empty
/// slab, sorted by z. Rank r gets the slabs `cuts[r] ≤ tz < cuts[r + 1]`; `cuts[0]` is
/// `i32::MIN` and `cuts[ranks]` is `i32::MAX`, so every slab has an owner. Each inner cut
/// sits at the slab boundary whose prefix count is nearest to r/ranks of the total (the
/// first such boundary, and never before the previous cut).
pub fn balanced_cuts(slabs: &[(i32, u64)], ranks: usize) -> Vec<i32> {
    assert!(ranks > 0, "at least one rank");
    let total: u64 = slabs.iter().map(|s| s.1).sum();
    // prefix[i]: tiles in slabs[..i].
    let mut prefix = Vec::with_capacity(slabs.len() + 1);
    prefix.push(0u64);
    for s in slabs {
        prefix.push(prefix.last().copied().unwrap_or(0) + s.1);
    }
    let mut cuts = vec![i32::MIN; ranks + 1];
    cuts[ranks] = i32::MAX;
    let mut i = 0;
    for (r, cut) in cuts.iter_mut().enumerate().take(ranks).skip(1) {
        let target = total as u128 * r as u128;
        // |ranks · prefix[i] − total · r|, compared without division.
        let dev = |i: usize| (prefix[i] as u128 * ranks as u128).abs_diff(target);
        while i < slabs.len() && dev(i + 1) < dev(i) {
            i += 1;
        }
        *cut = if i < slabs.len() {
            slabs[i].0
        } else {
            slabs.last().map_or(i32::MIN, |s| s.0.saturating_add(1))
        };
    }
    cuts
}

/// The rank that owns tile z `tz` under `cuts`.
pub fn owner(cuts: &[i32], tz: i32) -> usize {
    cuts.partition_point(|&c| c <= tz).saturating_sub(1).min(cuts.len() - 2)
}

/// The tile z range `[lo, hi)` rank `r` stores under `cuts`: its slabs and [`GHOST`]
/// slabs on either side.
pub(super) fn stored_z(cuts: &[i32], r: usize) -> (i32, i32) {
    (cuts[r].saturating_sub(GHOST), cuts[r + 1].saturating_add(GHOST))
}

/// The positions of `coords` (sorted) with tile z in `[lo, hi)`.
pub(super) fn z_range(coords: &[Coord], lo: i32, hi: i32) -> Range<usize> {
    coords.partition_point(|c| c.z < lo)..coords.partition_point(|c| c.z < hi)
}

/// The positions of `owned` (a rank's own tiles in its list `coords`) that rank `d`
/// stores under `cuts`: what this rank sends it.
pub(super) fn stored_by(
    coords: &[Coord],
    owned: &Range<usize>,
    cuts: &[i32],
    d: usize,
) -> Range<usize> {
    let (lo, hi) = stored_z(cuts, d);
    let s = z_range(&coords[owned.clone()], lo, hi);
    owned.start + s.start..owned.start + s.end
}
