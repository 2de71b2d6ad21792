//! The per-tile arithmetic of 3D simplicial isosurfacing, free of any grid type: an 8³
//! block of values around one 4³ tile, its sign bits, which cells and Kuhn edges of the
//! tile are cut, the cut edges' vertices (eq. (2)) and the cells' triangles from one
//! table per sign pattern (Sec. 2.1 and Table 2 via [`super::tables`]).
//!
//! # Layout
//! Block coordinates `b` run over `0..8` along each axis, local tile coordinate `b − 2`
//! (two voxels before the tile, two after), x fastest: `values[x + 8 y + 64 z]`. The sign
//! bits are one `u64` per z slice, bit `x + 8 y` set where the value lies below the iso
//! value ([`signs`]). Shifting a slice right by 1, 8 or 9 moves the +x, +y or +xy
//! neighbour of every voxel onto it, and the next slice is the +z neighbour, so the cut
//! cells and cut edges of a whole slice come out of a few word operations
//! ([`cut_cells`], [`edge_masks`]) instead of a loop over voxels.
//!
//! # One table per cell sign pattern
//! A cell's six Kuhn tetrahedra and the pieces of Sec. 3 depend only on the cell's eight
//! corner signs, so [`cell_cases`] tabulates, for each of the 256 patterns, the cut Kuhn
//! edges of the cell (lower corner, direction) and its triangles as triples of those
//! edges, oriented outward: a cut cell costs one table lookup, not six tetrahedron cases.
//! The triangles come in the order of the tetrahedra ([`KUHN`]) and of their pieces.

use super::tables::pieces;
use std::sync::OnceLock;

/// Side of the block: a tile (4) plus 2 voxels before and after.
pub(super) const B: usize = 8;
/// Values in a block.
pub(super) const BLOCK: usize = B * B * B;

/// The six Kuhn tetrahedra of a cell: corner bit masks v₀ ⊂ v₁ ⊂ v₂ ⊂ v₃ (bit 0 = +x,
/// 1 = +y, 2 = +z) and the sign of the permutation, i.e. the orientation of that vertex
/// order (Sec. 2.1).
pub(super) const KUHN: [([u8; 4], i8); 6] = {
    // Permutations of the axes in lexicographic order with their signs.
    const PERMS: [([u8; 3], i8); 6] = [
        ([0, 1, 2], 1),
        ([0, 2, 1], -1),
        ([1, 0, 2], -1),
        ([1, 2, 0], 1),
        ([2, 0, 1], 1),
        ([2, 1, 0], -1),
    ];
    let mut out = [([0u8; 4], 0i8); 6];
    let mut i = 0;
    while i < 6 {
        let (p, s) = PERMS[i];
        let a = 1u8 << p[0];
        let b = a | 1 << p[1];
        out[i] = ([0, a, b, 7], s);
        i += 1;
    }
    out
};

/// Kuhn edges of a cell: 12 cube edges, 6 face diagonals, 1 main diagonal.
pub(super) const CELL_EDGES: usize = 19;
/// Triangles of a cell at most: two per tetrahedron.
pub(super) const CELL_TRIS: usize = 12;

/// The part of the surface in one cell with a given corner sign pattern.
#[derive(Clone, Copy, Debug)]
pub(super) struct CellCase {
    /// The cut Kuhn edges, `lower corner | direction << 3` (corner and direction as bit
    /// masks over x, y, z; the direction is a non-empty mask disjoint from the corner).
    pub edges: [u8; CELL_EDGES],
    pub n_edges: u8,
    /// Triangles as indices into `edges`, counter-clockwise seen from outside (φ > iso).
    pub tris: [[u8; 3]; CELL_TRIS],
    pub n_tris: u8,
}

/// The 256 cell cases, indexed by the sign pattern (bit `c` set ⇔ corner `c` below iso).
pub(super) fn cell_cases() -> &'static [CellCase; 256] {
    static T: OnceLock<Box<[CellCase; 256]>> = OnceLock::new();
    T.get_or_init(|| {
        let empty =
            CellCase { edges: [0; CELL_EDGES], n_edges: 0, tris: [[0; 3]; CELL_TRIS], n_tris: 0 };
        let mut out = Box::new([empty; 256]);
        for (pattern, case) in out.iter_mut().enumerate() {
            for (tet, sign) in KUHN {
                let mask = (0..4).fold(0u32, |m, i| m | ((pattern as u32 >> tet[i]) & 1) << i);
                for piece in pieces(3, mask) {
                    let mut tri = [0u8; 3];
                    for (w, &(i, j)) in tri.iter_mut().zip(&piece.pairs) {
                        // Tetrahedron vertices are ordered by inclusion, so the one with
                        // the smaller index is the edge's lower corner.
                        let (a, b) = (tet[i as usize], tet[j as usize]);
                        let (lo, hi) = if i < j { (a, b) } else { (b, a) };
                        let code = lo | (hi ^ lo) << 3;
                        let n = case.n_edges as usize;
                        *w = match case.edges[..n].iter().position(|&e| e == code) {
                            Some(k) => k as u8,
                            None => {
                                case.edges[n] = code;
                                case.n_edges += 1;
                                n as u8
                            }
                        };
                    }
                    if (sign < 0) != piece.flip {
                        tri.swap(0, 1);
                    }
                    case.tris[case.n_tris as usize] = tri;
                    case.n_tris += 1;
                }
            }
        }
        out
    })
}

/// Index of block coordinates.
#[inline(always)]
pub(super) const fn bidx(x: usize, y: usize, z: usize) -> usize {
    x + B * (y + B * z)
}

/// The sign bits of a block: bit `x + 8 y` of slice `z` is set where the value is below
/// `below`. For the rule "φ < iso" with an f64 iso value, `below` is the smallest f32 not
/// below iso ([`f32_threshold`]).
#[inline(always)]
pub(super) fn signs(values: &[f32; BLOCK], below: f32) -> [u64; B] {
    let mut s = [0u64; B];
    for (z, slice) in s.iter_mut().enumerate() {
        let vals = &values[64 * z..64 * z + 64];
        let mut m = 0u64;
        for (i, &v) in vals.iter().enumerate() {
            m |= ((v < below) as u64) << i;
        }
        *slice = m;
    }
    s
}

/// The smallest f32 not below `iso`, so that for every f32 `v`: `v < t ⇔ (v as f64) < iso`.
pub(super) fn f32_threshold(iso: f64) -> f32 {
    let t = iso as f32;
    if (t as f64) < iso {
        t.next_up()
    } else {
        t
    }
}

/// Bits `x + 8 y` with `x, y` in `lo..hi`.
const fn xy_mask(lo: usize, hi: usize) -> u64 {
    let mut m = 0u64;
    let mut y = lo;
    while y < hi {
        let mut x = lo;
        while x < hi {
            m |= 1 << (x + 8 * y);
            x += 1;
        }
        y += 1;
    }
    m
}

/// Cells whose lower corner lies in the tile (block coordinates 2..6).
pub(super) const TILE_XY: u64 = xy_mask(2, 6);
/// Cells whose lower corner lies in the tile or one voxel before it (block 1..6).
pub(super) const CELL_XY: u64 = xy_mask(1, 6);
/// Voxels that some cell of [`CELL_XY`] or some Kuhn edge from the tile reaches
/// (block 1..7).
pub(super) const REACH_XY: u64 = xy_mask(1, 7);

/// Whether the voxels of block coordinates 1..7 along each axis (the corners of every
/// cell a tile may own and the ends of its Kuhn edges) all lie on one side of iso.
#[inline(always)]
pub(super) fn uniform(s: &[u64; B]) -> bool {
    let (mut any, mut all) = (0u64, REACH_XY);
    for &slice in &s[1..7] {
        any |= slice & REACH_XY;
        all &= slice;
    }
    any == 0 || all & REACH_XY == REACH_XY
}

/// The cells of lower-corner slice `z` (in 0..7) with corners on both sides of iso: bit
/// `x + 8 y`, valid for `x, y` in 0..7 (mask with [`TILE_XY`] or [`CELL_XY`]).
#[inline(always)]
pub(super) fn cut_cells(s: &[u64; B], z: usize) -> u64 {
    let (a, b) = (s[z], s[z + 1]);
    let any = a | a >> 1 | a >> 8 | a >> 9 | b | b >> 1 | b >> 8 | b >> 9;
    let all = a & a >> 1 & a >> 8 & a >> 9 & b & b >> 1 & b >> 8 & b >> 9;
    any & !all
}

/// The sign pattern of the cell with lower corner at block `(x, y, z)`: bit `c` for
/// corner `c` (bit 0 = +x, 1 = +y, 2 = +z).
#[inline(always)]
pub(super) fn pattern(s: &[u64; B], x: usize, y: usize, z: usize) -> usize {
    let p = x + 8 * y;
    let (a, b) = (s[z] >> p, s[z + 1] >> p);
    ((a & 3) | ((a >> 8) & 3) << 2 | (b & 3) << 4 | ((b >> 8) & 3) << 6) as usize
}

/// The 4 × 4 bits of a slice at block `x, y` in 2..6, as bits `x' + 4 y'` (local).
#[inline(always)]
fn tile_bits(m: u64) -> u64 {
    ((m >> 18) & 0xF) | ((m >> 22) & 0xF0) | ((m >> 26) & 0xF00) | ((m >> 30) & 0xF000)
}

/// The cut Kuhn edges that start at the tile's voxels: `out[d − 1]` has bit
/// `x + 4 y + 16 z` (local) set when the values at that voxel and at voxel + d lie on
/// different sides of iso, for the directions `d` in 1..8 (bit masks over x, y, z).
#[inline(always)]
pub(super) fn edge_masks(s: &[u64; B]) -> [u64; 7] {
    let mut out = [0u64; 7];
    for (k, o) in out.iter_mut().enumerate() {
        let d = k + 1;
        let (dx, dy, dz) = (d & 1, (d >> 1) & 1, d >> 2);
        let shift = dx + 8 * dy;
        let mut m = 0u64;
        for z in 0..4 {
            let here = s[z + 2];
            let there = s[z + 2 + dz] >> shift;
            m |= tile_bits(here ^ there) << (16 * z);
        }
        *o = m;
    }
    out
}

/// Per axis, the neighbour tile offsets (bit 0: −1, bit 1: 0, bit 2: +1) of the two
/// corner coordinates `b, b + 1` of a cell with lower block coordinate `b`.
const fn axis_tiles(b: usize) -> u32 {
    (1 << axis_tile(b)) | (1 << axis_tile(b + 1))
}

/// The neighbour tile offset + 1 (0, 1, 2) of block coordinate `b` along one axis.
#[inline(always)]
const fn axis_tile(b: usize) -> usize {
    (((b as i32 - 2) >> 2) + 1) as usize
}

/// `CELL_TILES[a][b]`: the 27-bit set of neighbour tiles (index `ox + 3 oy + 9 oz`, each
/// offset + 1) whose offset along axis `a` is one of [`axis_tiles`]`(b)`.
const CELL_TILES: [[u32; 7]; 3] = {
    let mut out = [[0u32; 7]; 3];
    let mut a = 0;
    while a < 3 {
        let mut b = 0;
        while b < 7 {
            let set = axis_tiles(b);
            let mut n = 0;
            while n < 27 {
                let o = [n % 3, (n / 3) % 3, n / 9];
                if set & (1 << o[a]) != 0 {
                    out[a][b] |= 1 << n;
                }
                n += 1;
            }
            b += 1;
        }
        a += 1;
    }
    out
};

/// The neighbour tiles (27-bit set) that the corners of the cell with lower block
/// corner `(x, y, z)` lie in.
#[inline(always)]
pub(super) fn cell_tiles(x: usize, y: usize, z: usize) -> u32 {
    CELL_TILES[0][x] & CELL_TILES[1][y] & CELL_TILES[2][z]
}

/// Neighbour tile (index `ox + 3 oy + 9 oz`, offsets + 1) and local voxel index
/// (`x + 4 y + 16 z`) of block coordinates.
#[inline(always)]
pub(super) fn tile_and_local(x: usize, y: usize, z: usize) -> (usize, u32) {
    let l = |c: usize| ((c + 2) & 3) as u32;
    (axis_tile(x) + 3 * axis_tile(y) + 9 * axis_tile(z), l(x) + 4 * l(y) + 16 * l(z))
}

/// Whether a cell with lower block corner `(x, y, z)` in 1..6 belongs to the tile: the
/// tile of its first corner (corner order) that lies in a stored tile must be the tile
/// itself (`stored`: the 27-bit set of stored neighbour tiles).
#[inline(always)]
pub(super) fn owns_cell(stored: u32, x: usize, y: usize, z: usize) -> bool {
    (0..8)
        .map(|c| tile_and_local(x + (c & 1), y + ((c >> 1) & 1), z + (c >> 2)).0)
        .find(|&n| stored & (1 << n) != 0)
        == Some(13)
}

/// The neighbour tiles whose offsets are all ≤ 0 except the tile itself: the tiles that
/// own the cells one voxel before the tile when they are stored.
pub(super) const BEFORE: u32 = {
    let mut m = 0u32;
    let mut n = 0;
    while n < 27 {
        if n % 3 <= 1 && (n / 3) % 3 <= 1 && n / 9 <= 1 && n != 13 {
            m |= 1 << n;
        }
        n += 1;
    }
    m
};

/// Most vertices a tile owns: 7 Kuhn edges from each of its 64 voxels.
pub(super) const TILE_VERTS: usize = 7 * 64;

/// The vertices of one tile (or any batch of up to [`TILE_VERTS`]), gathered one by one
/// ([`VertexBatch::push`]) and finished together ([`VertexBatch::finish`]): the
/// arithmetic runs over arrays without branches, so the compiler vectorises it.
///
/// A vertex lies on the Kuhn edge from voxel `lo` in direction `d` at the parameter t of
/// eq. (2), measured from `lo`; its normal is the central-difference gradient at both
/// ends, interpolated at t and normalised (zero where it vanishes). Its position is
/// `t` clamped to `[δ, 1 − δ]` with `δ = OFFSET_ULPS · ulp / h` (the ulp of the output
/// precision at the largest coordinate of the edge's ends), interpolated from the nearer
/// end and, for f32 output, rounded to an f32 value (see the surface module docs,
/// "Exact zeros" and "Precision").
pub(super) struct VertexBatch {
    len: usize,
    /// φ − iso at the lower and the upper end.
    a: [f64; TILE_VERTS],
    b: [f64; TILE_VERTS],
    /// Gradients (central differences, one voxel each way) at both ends, per axis.
    g0: [[f64; TILE_VERTS]; 3],
    g1: [[f64; TILE_VERTS]; 3],
    /// The lower voxel and the direction, per axis.
    lo: [[f64; TILE_VERTS]; 3],
    d: [[f64; TILE_VERTS]; 3],
    /// Results, per axis.
    out_p: [[f64; TILE_VERTS]; 3],
    out_n: [[f32; TILE_VERTS]; 3],
}

/// A vertex keeps at least this many ulps (of the chosen precision, at the magnitude of
/// its edge's end points) times the edge length away from both ends of its edge.
pub(super) const OFFSET_ULPS: f64 = 32.0;

/// Where vertices go: origin and voxel size of the grid.
#[derive(Clone, Copy, Debug)]
pub(super) struct Placement {
    pub origin: [f64; 3],
    pub h: f64,
}

impl VertexBatch {
    pub fn new() -> Box<VertexBatch> {
        Box::new(VertexBatch {
            len: 0,
            a: [0.0; TILE_VERTS],
            b: [0.0; TILE_VERTS],
            g0: [[0.0; TILE_VERTS]; 3],
            g1: [[0.0; TILE_VERTS]; 3],
            lo: [[0.0; TILE_VERTS]; 3],
            d: [[0.0; TILE_VERTS]; 3],
            out_p: [[0.0; TILE_VERTS]; 3],
            out_n: [[0.0; TILE_VERTS]; 3],
        })
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Adds the vertex on the edge from voxel `lo` in direction `d` (a bit mask over x,
    /// y, z), whose ends lie on both sides of iso. `val(x, y, z)` reads φ at `lo` + the
    /// offset (−1..=2 per axis).
    #[inline(always)]
    pub fn push(&mut self, lo: [i64; 3], d: usize, iso: f64, val: impl Fn(i32, i32, i32) -> f32) {
        let i = self.len;
        let dv = [(d & 1) as i32, ((d >> 1) & 1) as i32, (d >> 2) as i32];
        let v = |x: i32, y: i32, z: i32| val(x, y, z) as f64;
        self.a[i] = v(0, 0, 0) - iso;
        self.b[i] = v(dv[0], dv[1], dv[2]) - iso;
        let (x, y, z) = (dv[0], dv[1], dv[2]);
        self.g0[0][i] = v(1, 0, 0) - v(-1, 0, 0);
        self.g0[1][i] = v(0, 1, 0) - v(0, -1, 0);
        self.g0[2][i] = v(0, 0, 1) - v(0, 0, -1);
        self.g1[0][i] = v(x + 1, y, z) - v(x - 1, y, z);
        self.g1[1][i] = v(x, y + 1, z) - v(x, y - 1, z);
        self.g1[2][i] = v(x, y, z + 1) - v(x, y, z - 1);
        for k in 0..3 {
            // Exact: voxel coordinates are far below 2⁵³.
            self.lo[k][i] = lo[k] as f64;
            self.d[k][i] = dv[k] as f64;
        }
        self.len = i + 1;
    }

    /// Positions and normals of the batch's vertices, in the order they were pushed,
    /// for output precision f32 (`F32`) or f64. `place` must be the placement whose
    /// precision rule chose `F32` for coordinates up to the batch's (so the ulps are
    /// finite). Returns whether some normal is zero.
    #[inline(always)]
    pub fn finish<const F32: bool>(
        &mut self,
        place: &Placement,
        pos: &mut [std::mem::MaybeUninit<[f64; 3]>],
        nrm: &mut [std::mem::MaybeUninit<[f32; 3]>],
    ) -> bool {
        let n = self.len;
        let (o, h) = (place.origin, place.h);
        // Whole vectors: the lanes past `n` compute garbage from stale entries (harmless,
        // nothing reads it), and no scalar remainder loop runs.
        let n = n.next_multiple_of(8);
        {
            let (a, b) = (&self.a[..n], &self.b[..n]);
            let [g0x, g0y, g0z] = &self.g0;
            let [g1x, g1y, g1z] = &self.g1;
            let (g0x, g0y, g0z, g1x, g1y, g1z) =
                (&g0x[..n], &g0y[..n], &g0z[..n], &g1x[..n], &g1y[..n], &g1z[..n]);
            let [lx, ly, lz] = &self.lo;
            let [dx, dy, dz] = &self.d;
            let (lx, ly, lz, dx, dy, dz) =
                (&lx[..n], &ly[..n], &lz[..n], &dx[..n], &dy[..n], &dz[..n]);
            let [px, py, pz] = &mut self.out_p;
            let [nx, ny, nz] = &mut self.out_n;
            let (px, py, pz, nx, ny, nz) = (
                &mut px[..n],
                &mut py[..n],
                &mut pz[..n],
                &mut nx[..n],
                &mut ny[..n],
                &mut nz[..n],
            );
            for i in 0..n {
                // a and b lie on both sides of 0 (one may be 0), so t lies in [0, 1].
                let t = a[i] / (a[i] - b[i]);
                let gx = g0x[i] + t * (g1x[i] - g0x[i]);
                let gy = g0y[i] + t * (g1y[i] - g0y[i]);
                let gz = g0z[i] + t * (g1z[i] - g0z[i]);
                let len = (gx * gx + gy * gy + gz * gz).sqrt();
                let ok = len > 0.0 && len < f64::INFINITY;
                let inv = 1.0 / len;
                nx[i] = if ok { (gx * inv) as f32 } else { 0.0 };
                ny[i] = if ok { (gy * inv) as f32 } else { 0.0 };
                nz[i] = if ok { (gz * inv) as f32 } else { 0.0 };
                let (ax, ay, az) = (o[0] + h * lx[i], o[1] + h * ly[i], o[2] + h * lz[i]);
                let (bx, by, bz) = (
                    o[0] + h * (lx[i] + dx[i]),
                    o[1] + h * (ly[i] + dy[i]),
                    o[2] + h * (lz[i] + dz[i]),
                );
                let m =
                    ax.abs().max(ay.abs()).max(az.abs()).max(bx.abs()).max(by.abs()).max(bz.abs());
                // The next representable value minus the value (finite by the precision
                // rule).
                let ulp = if F32 {
                    let x = m as f32;
                    (f32::from_bits(x.to_bits() + 1) - x) as f64
                } else {
                    f64::from_bits(m.to_bits() + 1) - m
                };
                let delta = OFFSET_ULPS * ulp / h;
                let t = t.max(delta).min(1.0 - delta);
                // From the nearer end (1 − t is exact for t ≥ 1/2).
                let near = t <= 0.5;
                let s = if near { t } else { 1.0 - t };
                let (fx, fy, fz) = if near { (ax, ay, az) } else { (bx, by, bz) };
                let (tx, ty, tz) = if near { (bx, by, bz) } else { (ax, ay, az) };
                let (qx, qy, qz) = (fx + s * (tx - fx), fy + s * (ty - fy), fz + s * (tz - fz));
                if F32 {
                    px[i] = qx as f32 as f64;
                    py[i] = qy as f32 as f64;
                    pz[i] = qz as f32 as f64;
                } else {
                    px[i] = qx;
                    py[i] = qy;
                    pz[i] = qz;
                }
            }
        }
        let n = self.len;
        let [px, py, pz] = &self.out_p;
        let [nx, ny, nz] = &self.out_n;
        let mut zero = false;
        for (i, (p, q)) in pos[..n].iter_mut().zip(&mut nrm[..n]).enumerate() {
            p.write([px[i], py[i], pz[i]]);
            let v = [nx[i], ny[i], nz[i]];
            // A unit normal has a component of at least 1/√3: zero only where the
            // gradient vanished.
            zero |= v == [0.0; 3];
            q.write(v);
        }
        zero
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cell table against the construction it replaces: every pattern's triangles,
    /// tetrahedron by tetrahedron and piece by piece, as (lower corner, direction) triples.
    #[test]
    fn cell_cases_list_the_tetrahedra_pieces() {
        let cases = cell_cases();
        let mut most = 0;
        for (pattern, case) in cases.iter().enumerate() {
            let mut expect = Vec::new();
            for (tet, sign) in KUHN {
                let mask = (0..4).fold(0u32, |m, i| m | ((pattern as u32 >> tet[i]) & 1) << i);
                for piece in pieces(3, mask) {
                    let mut tri: Vec<(u8, u8)> = piece
                        .pairs
                        .iter()
                        .map(|&(i, j)| {
                            let (a, b) = (tet[i as usize], tet[j as usize]);
                            let (lo, hi) = if i < j { (a, b) } else { (b, a) };
                            (lo, hi ^ lo)
                        })
                        .collect();
                    if (sign < 0) != piece.flip {
                        tri.swap(0, 1);
                    }
                    expect.push(tri);
                }
            }
            let got: Vec<Vec<(u8, u8)>> = case.tris[..case.n_tris as usize]
                .iter()
                .map(|t| {
                    t.iter().map(|&k| case.edges[k as usize]).map(|e| (e & 7, e >> 3)).collect()
                })
                .collect();
            assert_eq!(got, expect, "pattern {pattern:08b}");
            assert_eq!(case.n_tris == 0, pattern == 0 || pattern == 255);
            most = most.max(case.n_tris);
            // Only cut edges, each once.
            for &e in &case.edges[..case.n_edges as usize] {
                let (lo, d) = (e & 7, e >> 3);
                assert!(d != 0 && lo & d == 0);
                assert_ne!((pattern >> lo) & 1, (pattern >> (lo | d)) & 1);
            }
        }
        assert!(most as usize <= CELL_TRIS);
    }

    /// The word operations against plain loops over random sign blocks.
    #[test]
    fn bit_tricks_match_loops() {
        let mut rng = fastrand::Rng::with_seed(11);
        let bit = |s: &[u64; B], x: usize, y: usize, z: usize| (s[z] >> (x + 8 * y)) & 1;
        for _ in 0..200 {
            // Sparse and dense sign blocks.
            let p = rng.f64();
            let s: [u64; B] = std::array::from_fn(|_| {
                (0..64).fold(0u64, |m, i| m | ((rng.f64() < p) as u64) << i)
            });
            for z in 0..7 {
                let cut = cut_cells(&s, z);
                for y in 0..7 {
                    for x in 0..7 {
                        let pat = (0..8)
                            .map(|c| bit(&s, x + (c & 1), y + ((c >> 1) & 1), z + (c >> 2)) << c)
                            .sum::<u64>() as usize;
                        assert_eq!(pattern(&s, x, y, z), pat);
                        let want = pat != 0 && pat != 255;
                        assert_eq!((cut >> (x + 8 * y)) & 1 == 1, want, "{x} {y} {z}");
                    }
                }
            }
            let e = edge_masks(&s);
            for d in 1..8 {
                for l in 0..64 {
                    let (x, y, z) = (2 + (l & 3), 2 + ((l >> 2) & 3), 2 + (l >> 4));
                    let w = bit(&s, x + (d & 1), y + ((d >> 1) & 1), z + (d >> 2));
                    assert_eq!((e[d - 1] >> l) & 1, bit(&s, x, y, z) ^ w, "d {d} l {l}");
                }
            }
            let reach =
                (1..7).flat_map(|z| (1..7).flat_map(move |y| (1..7).map(move |x| (x, y, z))));
            let first = bit(&s, 1, 1, 1);
            assert_eq!(uniform(&s), reach.clone().all(|(x, y, z)| bit(&s, x, y, z) == first));
        }
    }

    /// The vectorised batch against the same formulas one vertex at a time (scalar
    /// reference, lane by lane, bit for bit), for both output precisions, random values
    /// with exact zeros and ±γ ends, random edges near the origin and far from it.
    #[test]
    fn vertex_batch_matches_the_scalar_formulas() {
        let mut rng = fastrand::Rng::with_seed(17);
        let mut batch = VertexBatch::new();
        for round in 0..200 {
            let f32_out = round % 2 == 0;
            let far = if f32_out { 100.0 } else { 1e9 };
            let place = Placement {
                origin: [0, 1, 2].map(|_| (rng.f64() - 0.5) * far),
                h: [0.25, 0.5, 1.0, 0.1][rng.usize(..4)],
            };
            let iso = [0.0, 0.3, -0.7][rng.usize(..3)];
            let n = rng.usize(1..=TILE_VERTS);
            batch.clear();
            let mut inputs = Vec::new();
            for _ in 0..n {
                let lo = [0, 1, 2].map(|_| rng.i64(-300..300));
                let d = rng.usize(1..8);
                // φ at the 4 × 4 × 4 offsets −1..=2 around the lower voxel; the two ends
                // on both sides of iso (the lower one sometimes exactly iso).
                let mut vals = [0f32; 64];
                for v in &mut vals {
                    *v = (rng.f32() - 0.5) * 6.0;
                }
                let at = |x: i32, y: i32, z: i32| ((x + 1) + 4 * (y + 1) + 16 * (z + 1)) as usize;
                let dv = [(d & 1) as i32, ((d >> 1) & 1) as i32, (d >> 2) as i32];
                let (a, b) = (at(0, 0, 0), at(dv[0], dv[1], dv[2]));
                vals[a] = if rng.bool() { iso as f32 } else { iso as f32 - rng.f32() * 3.0 };
                vals[b] = iso as f32 + rng.f32() * 3.0 + 1e-3;
                if rng.bool() {
                    vals.swap(a, b);
                }
                batch.push(lo, d, iso, |x, y, z| vals[at(x, y, z)]);
                inputs.push((lo, d, vals));
            }
            let mut pos = vec![std::mem::MaybeUninit::uninit(); n];
            let mut nrm = vec![std::mem::MaybeUninit::uninit(); n];
            if f32_out {
                batch.finish::<true>(&place, &mut pos, &mut nrm);
            } else {
                batch.finish::<false>(&place, &mut pos, &mut nrm);
            }
            for (i, (lo, d, vals)) in inputs.iter().enumerate() {
                let at = |x: i32, y: i32, z: i32| ((x + 1) + 4 * (y + 1) + 16 * (z + 1)) as usize;
                let v = |x: i32, y: i32, z: i32| vals[at(x, y, z)] as f64;
                let dv = [(d & 1) as i32, ((d >> 1) & 1) as i32, (d >> 2) as i32];
                let (a, b) = (v(0, 0, 0) - iso, v(dv[0], dv[1], dv[2]) - iso);
                let t = a / (a - b);
                let grad = |x: i32, y: i32, z: i32| {
                    [
                        v(x + 1, y, z) - v(x - 1, y, z),
                        v(x, y + 1, z) - v(x, y - 1, z),
                        v(x, y, z + 1) - v(x, y, z - 1),
                    ]
                };
                let (g0, g1) = (grad(0, 0, 0), grad(dv[0], dv[1], dv[2]));
                let g: Vec<f64> = (0..3).map(|k| g0[k] + t * (g1[k] - g0[k])).collect();
                let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
                let want_n: Vec<f32> = if len > 0.0 && len.is_finite() {
                    g.iter().map(|&c| (c * (1.0 / len)) as f32).collect()
                } else {
                    vec![0.0; 3]
                };
                let pa: Vec<f64> =
                    (0..3).map(|k| place.origin[k] + place.h * lo[k] as f64).collect();
                let pb: Vec<f64> = (0..3)
                    .map(|k| place.origin[k] + place.h * (lo[k] + dv[k] as i64) as f64)
                    .collect();
                let m = pa.iter().chain(&pb).fold(0f64, |m, &c| m.max(c.abs()));
                let ulp = if f32_out {
                    ((m as f32).next_up() - m as f32) as f64
                } else {
                    m.next_up() - m
                };
                let delta = OFFSET_ULPS * ulp / place.h;
                let t = t.clamp(delta, 1.0 - delta);
                let want_p: Vec<f64> = (0..3)
                    .map(|k| {
                        let c = if t <= 0.5 {
                            pa[k] + t * (pb[k] - pa[k])
                        } else {
                            pb[k] + (1.0 - t) * (pa[k] - pb[k])
                        };
                        if f32_out {
                            c as f32 as f64
                        } else {
                            c
                        }
                    })
                    .collect();
                // SAFETY: `finish` wrote the first `n` entries.
                let (p, q) = unsafe { (pos[i].assume_init(), nrm[i].assume_init()) };
                assert_eq!(
                    p.map(f64::to_bits).to_vec(),
                    want_p.iter().map(|c| c.to_bits()).collect::<Vec<_>>()
                );
                assert_eq!(
                    q.map(f32::to_bits).to_vec(),
                    want_n.iter().map(|c| c.to_bits()).collect::<Vec<_>>()
                );
            }
        }
    }

    #[test]
    fn threshold_matches_the_f64_comparison() {
        let mut rng = fastrand::Rng::with_seed(5);
        for _ in 0..10_000 {
            let iso = (rng.f64() - 0.5) * 10f64.powi(rng.i32(-40..40));
            let t = f32_threshold(iso);
            for v in [t, t.next_down(), t.next_up(), iso as f32, 0.0, -0.0] {
                assert_eq!(v < t, (v as f64) < iso, "iso {iso:e} v {v:e}");
            }
        }
    }
}
