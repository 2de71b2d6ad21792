//! Border flags (van der Laan et al. 2011, Sec. 4.1) and activity flags with their guard-band
//! regions (Sec. 4.7, Fig. 5), and the `neighbour_trigger` masks of Algorithm 3 (Fig. 4).
//!
//! **Border flags** (`u32` per tile): bit `d` (a direction of
//! [`crate::coord::NEIGHBOURHOOD`], never [`crate::coord::MID`]) is set when the absent
//! neighbour in direction `d` is inside (reads `-γ`); clear means outside (`+γ`). Bits of
//! directions whose neighbour is present are meaningless.
//!
//! **Activity flags** (`u32` per tile): bits 0..27 are the 27 guard-band regions of the
//! tile; region `9 rz + 3 ry + rx` where along each axis the region is 0 for local
//! coordinate 0, 1 for 1..=2 and 2 for 3 (Fig. 5 in 3D). A region's bit is set when a
//! voxel in it is in the band (`|φ| < γ`). Bit [`INSIDE`] classifies a tile without
//! activity as inside (filled with `-γ`); it is never set together with a region bit.

use super::{Tile, TILE_LEN};

/// Bits of the 27 guard-band regions.
pub const ACTIVE_MASK: u32 = (1 << 27) - 1;
/// Classification of an inactive tile as inside.
pub const INSIDE: u32 = 1 << 27;
/// All 26 border-flag bits (direction 13, the tile itself, excluded).
pub const BORDER_MASK: u32 = ACTIVE_MASK & !(1 << crate::coord::MID);

const fn region_axis(l: usize) -> usize {
    match l {
        0 => 0,
        3 => 2,
        _ => 1,
    }
}

/// Guard-band region of a local voxel index.
pub const fn region_of_local(local: usize) -> usize {
    9 * region_axis(local >> 4) + 3 * region_axis((local >> 2) & 3) + region_axis(local & 3)
}

const REGION_OF: [u8; TILE_LEN] = {
    let mut r = [0u8; TILE_LEN];
    let mut i = 0;
    while i < TILE_LEN {
        r[i] = region_of_local(i) as u8;
        i += 1;
    }
    r
};

/// `NEIGHBOUR_TRIGGER[d]`: the regions of the tile at offset `d` from a tile `T` that lie
/// within one voxel of `T` (all regions for `d` = the centre). Activity there means the
/// interface may reach `T` within one CFL-limited step, so `T` must exist (Fig. 4).
pub const NEIGHBOUR_TRIGGER: [u32; 27] = {
    let mut out = [0u32; 27];
    let mut d = 0;
    while d < 27 {
        let off = [(d % 3) as i32 - 1, ((d / 3) % 3) as i32 - 1, (d / 9) as i32 - 1];
        let mut r = 0;
        while r < 27 {
            let reg = [r % 3, (r / 3) % 3, r / 9];
            let mut ok = true;
            let mut a = 0;
            while a < 3 {
                // The neighbour lies on the + side along this axis: its low face (region 0)
                // touches T; on the - side its high face (region 2).
                if (off[a] == 1 && reg[a] != 0) || (off[a] == -1 && reg[a] != 2) {
                    ok = false;
                }
                a += 1;
            }
            if ok {
                out[d] |= 1 << r;
            }
            r += 1;
        }
        d += 1;
    }
    out
};

/// Activity flags of a tile's values (Sec. 4.7): region bits of band voxels, or
/// [`INSIDE`] when there are none and the tile is inside.
#[inline(always)]
pub fn compute_activity(tile: &Tile, gamma: f32) -> u32 {
    let mut bits = 0u32;
    for (i, &v) in tile.0.iter().enumerate() {
        bits |= ((v.abs() < gamma) as u32) << REGION_OF[i];
    }
    if bits == 0 && tile.0[0] < 0.0 {
        INSIDE
    } else {
        bits
    }
}
