//! Triangle meshes of 3D level sets on the sparse grids and on dense fields: the n = 3,
//! m = 1 case of [`super::isosurface_nd`] (Kuhn triangulation of each cell into six
//! tetrahedra, Sec. 2.1; Table 2 via [`super::tables`]), in two parallel passes over the
//! sorted tile list that write every vertex and triangle once, into its final place.
//!
//! # Which cells, which tile
//! A tile processes the cells whose lower corner lies in the tile or one voxel before it.
//! A cell belongs to the tile holding its first corner (corner order x, y, z bits) that
//! lies in a stored tile, so every cell with a stored corner is meshed exactly once,
//! including cells that straddle tiles or touch absent tiles (which read ±γ). The cells
//! one voxel before the tile are its own only where the tile before them is absent, so
//! when all seven "before" neighbours are stored (almost always) only the 64 cells from
//! the tile's voxels are looked at. Cells with no stored corner are not meshed: their
//! corners read ±γ, and a sign change between absent tiles would need band voxels there,
//! which a valid band has. Each tile reads its 8³ neighbourhood (the cells' corners plus
//! one voxel for the central-difference normals) from its 26 neighbour tiles, found by
//! the list walk of Algorithm 1 ([`NeighbourCursor`]).
//!
//! # Welding: one vertex per Kuhn edge, owned by the tile of its lower voxel
//! A vertex lies on a Kuhn edge from a voxel v to v + d, d ∈ {0,1}³ \ {0}, whose ends lie
//! on both sides of iso. It belongs to the tile that holds v, and that tile alone
//! computes it: so there is one vertex per cut edge and nothing to merge. A cut edge from
//! a stored voxel is used by the cells around it (they have a stored corner), so a
//! tile's vertices are exactly its cut edges, which the sign bits give for the whole tile
//! at once ([`super::cells::edge_masks`]: seven 64-bit masks, one per direction).
//! Numbering them by tile, then direction, then voxel turns the lookup of a vertex into
//! a rank query: the index of the vertex on edge (voxel l of tile T, d) is
//! `base[T][d] + popcount(mask[T][d] & ((1 << l) − 1))`, O(1) for any tile that needs
//! a neighbour's vertex. The rare cut edge that starts in an *absent* tile (only where a
//! cut cell touches an absent tile, which a valid band never has) is an orphan: the tiles
//! that use it list it, the lists are sorted and deduplicated once, and its vertices
//! follow all others in key order.
//!
//! # Two passes
//! 1. *Count*, chunks of tiles in parallel: a tile's block of values, its sign bits
//!    ([`super::cells::signs`]), the cut-edge masks, and the triangles of its cut cells,
//!    one table lookup per cell sign pattern ([`super::cells::cell_cases`]); tiles
//!    whose neighbourhood lies on one side of iso are skipped after the signs. Also the
//!    bounds of the edges' ends (which fix the output precision) and the orphans.
//! 2. Prefix sums give every tile its vertex and triangle ranges (the count-then-fill of
//!    a parallel scan); *fill*, chunks in parallel again: each tile with work reads its
//!    block again, computes its vertices together ([`super::cells::VertexBatch`], one
//!    vectorised loop) and writes them into its range, then writes its cells' triangles
//!    with vertex indices from the rank queries. No vertex is computed twice, nothing is
//!    sorted, and every output element is written exactly once (the buffers are not
//!    zeroed first).
//!
//! Everything a tile writes depends on its own neighbourhood only, and the numbering on
//! the tile order, so the mesh is the same bits for any thread count (tested on 1–4
//! threads). Tiles, DT-Grid (through [`crate::storage::convert::tiles_from`]) and a dense array
//! ([`isosurface_dense`], whose tiles are those its surface crosses) give the same
//! vertices and triangles in the same order; the arithmetic of a vertex depends on its
//! edge and the values around it alone.
//!
//! # Cell rules and cell ranges (dense arrays)
//! [`super::isosurface_dense_with`] restricts the cells (a mask, an open border) through
//! [`Source::meshed_cells`]: a bit per cell of the tile's block, in the layout of the
//! cut-cell masks, ANDed with them in both passes, so counts and writes agree. The
//! vertices stay those of the cut edges; the ones no admitted cell uses are dropped
//! afterwards, in order. Pass 2 can also write, per vertex, scikit-image's `values`: the
//! largest value range (largest minus smallest corner value) of the admitted cells around
//! the vertex's edge, −1 for a vertex no admitted cell uses ([`vertex_value`]). Without a
//! rule every cell is admitted and nothing else changes.
//!
//! # Speed
//! On the r = 100 sphere (753 990 band voxels, 563 606 vertices, 1 127 208 triangles;
//! `cargo bench --bench mesh`, 2-core AMD EPYC with AVX-512, quiet moment): 41 ms on one
//! thread and 21 ms on two (18 and 35 M band voxels/s), against 181 ms and 130 ms for
//! the previous construction (every tile computing all vertices of its cells, the copies
//! merged by a parallel sort on the edge key) and OpenVDB 10's `volumeToMesh` at 59 ms
//! and 31 ms on the same band. Of the 41 ms, about 28 ms is the meshing itself (CPU time
//! where the allocator reuses memory); the rest is the 34 MB of fresh output paging in
//! and out (see [`crate::memory::advise_huge_pages`]). Measured and dropped: computing the signs of
//! pass 1 while gathering only the rows it reads (no gain); a block gather driven by a
//! table of rows (the compiler turned it into AVX-512 gathers, 25 % slower); chunks of
//! 128 tiles instead of 64 (within noise).
//!
//! # Exact zeros: vertices kept off the voxels
//! A value exactly equal to iso counts as outside (the ε rule of Sec. 3): the mesh is
//! that of the field with +ε there, whose connectivity is always a closed 2-manifold. Its
//! vertices on the edges from such a voxel lie at parameter 1 − O(ε), i.e. *on* the voxel
//! once ε → 0: up to 14 vertices at one point and the triangles between them of zero
//! area (1 668 of them on the r = 100 sphere). A reader that welds coincident vertices
//! then sees a non-manifold mesh. Two ways out:
//!
//! * **Collapse** the vertices at a voxel into one and drop the triangles that degenerate.
//!   That is a contraction of the mesh patch around the voxel, which is a manifold only
//!   when the patch is a disk. At a saddle it is not: two balls touching at one voxel,
//!   a double cone with its apex on a voxel, two wedges meeting along a line of voxels
//!   (`tests/mesh.rs`) collapse to a pinch, a non-manifold vertex (χ = 3 instead of 4).
//! * **Keep the ε-perturbation's connectivity and take ε small but finite** (chosen
//!   here): every vertex's edge parameter t is clamped to `[δ, 1 − δ]`. The connectivity
//!   (which edges are cut, which triangles join them) depends only on the signs, so the
//!   mesh stays the closed manifold of the ε rule, and an exact zero now gives vertices a
//!   distance δ·|edge| off the voxel, along distinct edges.
//!
//! Why any clamped parameters give a valid, embedded surface: a triangle has its vertices
//! on three edges of one Kuhn tetrahedron. In the one-vs-three case those are the edges
//! e₁, e₂, e₃ from one tetrahedron vertex q, linearly independent (|det| = 1), so the
//! points q + tᵢeᵢ (tᵢ > 0) are never collinear; in the two-vs-two case (negatives a, b,
//! positives c, d, vertices P₁ ∈ ac, P₂ ∈ ad, P₃ ∈ bd, P₄ ∈ bc in barycentric coordinates)
//! the affine function g = t₁λ_a − t₃λ_b + (t₁ − 1)λ_c + (1 − t₃)λ_d vanishes at P₁ and P₃
//! and is > 0 at P₂, < 0 at P₄ for every t ∈ (0, 1)⁴, so the quad's two triangles lie on
//! opposite sides of a plane through their common diagonal (for the other diagonal swap
//! c and d). Pieces of neighbouring tetrahedra share their vertices on shared edges, and
//! no triangle reaches a grid vertex, so the surface is embedded whatever the parameters
//! in (0, 1).
//!
//! Bounds that survive rounding (h = 1): two vertices on edges from one voxel are at
//! least δ apart (the edge vectors are distinct vectors in {−1, 0, 1}³ with entries of one
//! sign, so some coordinate differs by at least δ); vertices on disjoint edges are a
//! fixed fraction of a voxel apart; and every triangle's smallest height is at least
//! 0.7 δ (the unit test below checks both over every tetrahedron, sign pattern and piece,
//! with parameters at every combination of δ and 1 − δ and at random in between).
//! Rounding moves a point by at most √3/2 ulp, so distinct positions and nonzero areas
//! survive whenever δh exceeds about 2.5 ulp; the placement keeps a factor of ten more.
//!
//! # Precision
//! Vertices take δ = 32 ulp / h ([`super::cells::OFFSET_ULPS`]), with the ulp of the
//! output precision at the largest coordinate of the edge's end points (a vertex 100
//! voxels from the origin keeps 2.4·10⁻⁴ voxels off a voxel in f32; one at 2³¹ voxels in
//! f64, 7.6·10⁻⁶), and [`Placer::new`] picks the precision from the largest coordinate X
//! of the mesh: f32 when ulp_f32(X) ≤ h/4096 ([`MAX_ULP_IN_VOXELS`]; rounding error
//! ≤ 1/8192 voxel, X < 4096 h for h a power of two), else f64 when ulp_f64(X) ≤ h/4096, else
//! [`MeshError::Precision`]. f32 positions are rounded to f32 values in the mesh itself,
//! so the file (`float` exactly then, `double` otherwise) holds the very positions the
//! checks measure. Voxel positions are origin + h·voxel in f64, and a vertex is
//! interpolated from the nearer end of its edge, so its offset from that voxel is
//! accurate to an ulp of the coordinate.
//!
//! Cost in accuracy: only parameters within δ of an edge's end move, by at most
//! δ·|edge|. A face on grid planes (a box) moves inwards by δh: for a box of 200 voxels
//! centred on the origin the volume changes by 8.6·10⁻⁶ (relative). On the r = 100
//! sphere centred on a voxel the area changes by 1.2·10⁻⁷ and the volume by 4·10⁻⁹
//! (errors −2.572·10⁻⁵ → −2.561·10⁻⁵ and −5.0011·10⁻⁵ → −5.0015·10⁻⁵).

use super::cells::{
    bidx, cell_cases, cell_tiles, cut_cells, edge_masks, f32_threshold, owns_cell, pattern, signs,
    tile_and_local, uniform, Placement, VertexBatch, BEFORE, BLOCK, CELL_EDGES, CELL_XY,
    TILE_VERTS, TILE_XY,
};
use super::{MeshError, MeshOptions, TriangleMesh};
use crate::coord::{direction_index, NEIGHBOURHOOD};
use crate::grid::GridSpec;
use crate::progress::{Cancelled, Ticker};
use crate::storage::dense::DenseField;
use crate::storage::levelset::LevelSet;
use crate::storage::tiles::{NeighbourCursor, Neighbours, Tile, TileGrid, TILE_MAX, TILE_MIN};
use crate::Coord;
use rayon::prelude::*;

/// Tiles per parallel work item.
const CHUNK: usize = 64;

/// A sorted list of tiles with values around them, as the two passes read it: the tile
/// grid itself ([`GridSource`]) or the tiles of a dense array that the surface crosses
/// ([`DenseSource`]).
trait Source: Sync {
    /// Origin and voxel size of the placement.
    fn spec(&self) -> &GridSpec;
    /// The tiles to mesh (slots), strictly increasing.
    fn coords(&self) -> &[Coord];
    /// Fills the 8³ block of slot `nb.pos` (neighbours among the slots: `nb`) and returns
    /// which of its 27 neighbour tiles (index of [`NEIGHBOURHOOD`]) are *stored*, i.e.
    /// own their cells (see the module docs, "Which cells, which tile").
    fn gather(&self, nb: &Neighbours, values: &mut [f32; BLOCK]) -> u32;
    /// φ at a voxel, exactly as [`Source::gather`] reads it (for vertices on edges that
    /// start in a tile without a slot).
    fn value(&self, v: [i64; 3]) -> f32;
    /// Which cells of the block of tile `t` may be meshed, in the layout of
    /// [`super::cells::cut_cells`] (bit `x + 8 y` of layer `z`: the cell whose lower
    /// corner is block voxel `(x, y, z)`). All of them unless a source restricts them
    /// (a dense array's mask or open border); the two passes read the same bits.
    #[inline(always)]
    fn meshed_cells(&self, _t: Coord) -> [u64; 8] {
        [!0; 8]
    }
}

/// A tile grid: slots are its tiles; absent tiles read ±γ with the sign the grid records
/// for them ([`TileGrid::value`]), tiles beyond the representable range +γ.
struct GridSource<'a> {
    grid: &'a TileGrid,
    /// `[+γ; 64]` and `[−γ; 64]`.
    dummy: [Tile; 2],
}

impl<'a> GridSource<'a> {
    fn new(grid: &'a TileGrid) -> Self {
        let g = grid.gamma();
        GridSource { grid, dummy: [Tile::splat(g), Tile::splat(-g)] }
    }
}

impl GridSource<'_> {
    /// Whether the absent neighbour `n` of the tile `nb` is inside, as
    /// [`TileGrid::value`] reads it: by the border flag of the nearest tile of the same
    /// tile row before it (+x flag) or after it (−x flag) — found among the neighbours
    /// when the row has one there, by the grid's search otherwise; outside beyond the
    /// representable tiles.
    #[inline(always)]
    fn absent_inside(&self, nb: &Neighbours, n: usize) -> bool {
        let t = nb.coord;
        let o = NEIGHBOURHOOD[n];
        let nt = [t.x as i64 + o.x as i64, t.y as i64 + o.y as i64, t.z as i64 + o.z as i64];
        if !nt.iter().all(|&c| (TILE_MIN as i64..=TILE_MAX as i64).contains(&c)) {
            return false;
        }
        let (row, dx) = (n - n % 3, n % 3);
        let border = |p: usize, d: usize| self.grid.border_flags(p) & (1 << d) != 0;
        // The nearest present tile of the row before the absent one: it is the list entry
        // just before the absent tile's place.
        if let Some(p) = (row..row + dx).rev().find_map(|m| nb.get(m)) {
            return border(p, PLUS_X);
        }
        // The nearest one after it: the absent tile's place in the list; the entry
        // before that may still be a tile of the same row further back.
        if let Some(p) = (row + dx + 1..row + 3).find_map(|m| nb.get(m)) {
            let coords = self.grid.tile_coords();
            let c = coords[p];
            return if p > 0 && coords[p - 1].z == c.z && coords[p - 1].y == c.y {
                border(p - 1, PLUS_X)
            } else {
                border(p, MINUS_X)
            };
        }
        self.grid.value(Coord::new(4 * nt[0] as i32, 4 * nt[1] as i32, 4 * nt[2] as i32)) < 0.0
    }
}

const PLUS_X: usize = direction_index(1, 0, 0);
const MINUS_X: usize = direction_index(-1, 0, 0);

impl Source for GridSource<'_> {
    fn spec(&self) -> &GridSpec {
        self.grid.spec()
    }

    fn coords(&self) -> &[Coord] {
        self.grid.tile_coords()
    }

    #[inline(always)]
    fn gather(&self, nb: &Neighbours, values: &mut [f32; BLOCK]) -> u32 {
        let parts: [&[f32; 64]; 27] = std::array::from_fn(|n| match nb.get(n) {
            Some(p) => &self.grid.tile(p).0,
            None => &self.dummy[self.absent_inside(nb, n) as usize].0,
        });
        copy_rows(&parts, values);
        nb.matched
    }

    fn value(&self, v: [i64; 3]) -> f32 {
        let ok = |c: i64| (i32::MIN as i64..=i32::MAX as i64).contains(&c);
        if v.iter().all(|&c| ok(c)) {
            self.grid.value(Coord::new(v[0] as i32, v[1] as i32, v[2] as i32))
        } else {
            self.grid.gamma()
        }
    }
}

/// Block coordinate along one axis → (neighbour tile offset + 1, local coordinate).
#[inline(always)]
const fn axis_split(b: usize) -> (usize, usize) {
    let c = b as i64 - 2;
    ((c.div_euclid(4) + 1) as usize, c.rem_euclid(4) as usize)
}

/// Fills a block row by row from the 27 tiles around it: each row of 8 is the last two
/// values of a row of the −x neighbour, a whole tile row and the first two of the +x
/// neighbour.
#[inline(always)]
fn copy_rows(parts: &[&[f32; 64]; 27], values: &mut [f32; BLOCK]) {
    for (z, slab) in values.chunks_exact_mut(64).enumerate() {
        let (pz, lz) = axis_split(z);
        for (y, row) in slab.chunks_exact_mut(8).enumerate() {
            let (py, ly) = axis_split(y);
            let n = 3 * py + 9 * pz;
            let src = 4 * ly + 16 * lz;
            let part = |k: usize| -> &[f32; 4] {
                parts[n + k][src..src + 4].try_into().expect("a tile row has 4 values")
            };
            let (a, b, c) = (part(0), part(1), part(2));
            row.copy_from_slice(&[a[2], a[3], b[0], b[1], b[2], b[3], c[0], c[1]]);
        }
    }
}

/// A dense array: slots are the tiles whose block the surface crosses, stored are all
/// tiles that meet the array or the voxel layer before it; values beyond the array read
/// `iso + γ` (for an open border the linear extrapolation of
/// [`DenseSource::beyond`]), ±∞ as `iso ± γ`.
struct DenseSource<'a> {
    field: &'a DenseField,
    spec: GridSpec,
    coords: Vec<Coord>,
    /// Tile range of the stored tiles.
    tlo: [i64; 3],
    thi: [i64; 3],
    outside: f32,
    inside: f32,
    /// Which cells are meshed; `None`: all.
    cells: Option<CellRule<'a>>,
    /// −1 to mesh the negated array (without a negated copy), else 1.
    sign: f32,
}

impl DenseSource<'_> {
    /// Whether voxels beyond the array read an extrapolation of the array (an open
    /// border, see [`DenseSource::beyond`]) rather than `iso + γ`.
    fn clamps(&self) -> bool {
        self.cells.is_some_and(|r| r.open)
    }
}

/// The cells of a dense array that may be meshed (see [`super::DenseMeshOptions`]).
#[derive(Clone, Copy)]
pub(super) struct CellRule<'a> {
    /// Only cells with all eight corners in the array; voxels beyond the array read a
    /// linear extrapolation of the array (so the normals at the border come from
    /// one-sided differences).
    pub open: bool,
    /// Only cells whose upper corner (lower corner + (1, 1, 1)) is in the array and true
    /// in this mask (array order, x fastest).
    pub mask: Option<&'a [bool]>,
}

impl DenseSource<'_> {
    /// The cells of tile `t`'s block that the rule admits (see [`Source::meshed_cells`]).
    fn rule_cells(&self, rule: &CellRule, t: Coord) -> [u64; 8] {
        let o = self.field.origin();
        let (o, dims) = ([o.x as i64, o.y as i64, o.z as i64], self.field.dims());
        let n = dims.map(|d| d as i64);
        let lo = [t.x as i64, t.y as i64, t.z as i64].map(|c| 4 * c - 2);
        let mut out = [0u64; 8];
        // A block whose cells (lower corners at block 0..8 in x and y, 0..7 in z) all
        // have their eight corners in the array, without a mask: every cell.
        let r = [0, 1, 2].map(|a| lo[a] - o[a]);
        if rule.mask.is_none() && r.iter().all(|&r| r >= 0) && (0..3).all(|a| r[a] + 8 < n[a]) {
            out[..7].fill(!0);
            return out;
        }
        for (z, layer) in out.iter_mut().enumerate().take(7) {
            for y in 0..8 {
                for x in 0..8 {
                    // The cell's lower corner, relative to the array's first voxel.
                    let r =
                        [lo[0] + x as i64 - o[0], lo[1] + y as i64 - o[1], lo[2] + z as i64 - o[2]];
                    let in_array = |a: usize, c: i64| (0..n[a]).contains(&c);
                    if rule.open && !(0..3).all(|a| in_array(a, r[a]) && in_array(a, r[a] + 1)) {
                        continue;
                    }
                    if let Some(mask) = rule.mask {
                        let u = r.map(|c| c + 1);
                        if !(0..3).all(|a| in_array(a, u[a])) {
                            continue;
                        }
                        let i = u[0] as usize + dims[0] * (u[1] as usize + dims[1] * u[2] as usize);
                        if !mask[i] {
                            continue;
                        }
                    }
                    *layer |= 1 << (x + 8 * y);
                }
            }
        }
        out
    }

    #[inline(always)]
    fn stored(&self, t: [i64; 3]) -> bool {
        (0..3).all(|a| (self.tlo[a]..=self.thi[a]).contains(&t[a]))
    }

    /// The value of the array voxel `p` (inside the array), ±∞ read as far distances.
    #[inline(always)]
    fn at(&self, p: [i64; 3]) -> f32 {
        let o = self.field.origin();
        let [nx, ny, _] = self.field.dims();
        let r = [p[0] - o.x as i64, p[1] - o.y as i64, p[2] - o.z as i64].map(|v| v as usize);
        self.read(self.field.data()[r[0] + nx * (r[1] + ny * r[2])])
    }

    /// An array value as the surface reads it: times [`DenseSource::sign`], ±∞ as far
    /// distances.
    #[inline(always)]
    fn read(&self, x: f32) -> f32 {
        let x = self.sign * x;
        if x == f32::INFINITY {
            self.outside
        } else if x == f32::NEG_INFINITY {
            self.inside
        } else {
            x
        }
    }

    /// [`Source::value`] of a voxel `c` beyond the array, `p` the nearest array voxel:
    /// `iso + γ` for a closed border; for an open one the value at p plus, along each
    /// axis on which `c` lies beyond, the distance times the one-sided difference at p
    /// toward the outside (zero where the array is one voxel thick), so the central
    /// differences at the array's border voxels are one-sided differences of the same
    /// scale.
    #[inline]
    fn beyond(&self, c: [i64; 3], p: [i64; 3]) -> f32 {
        if !self.clamps() {
            return self.outside;
        }
        let (lo, hi) = (self.field.origin(), self.field.max_coord());
        let (lo, hi) =
            ([lo.x as i64, lo.y as i64, lo.z as i64], [hi.x as i64, hi.y as i64, hi.z as i64]);
        let base = self.at(p) as f64;
        let mut v = base;
        for a in 0..3 {
            let beyond = c[a] - p[a];
            if beyond != 0 && lo[a] < hi[a] {
                let mut q = p;
                q[a] -= beyond.signum();
                v += beyond.abs() as f64 * (base - self.at(q) as f64);
            }
        }
        v as f32
    }

    /// The block of tile `tile` (voxels `4 t − 2 .. 4 t + 6` per axis), each voxel as
    /// [`Source::value`] reads it: the parts of rows inside the array copied, the voxels
    /// beyond it from [`DenseSource::beyond`].
    #[inline(always)]
    fn fill(&self, tile: [i64; 3], values: &mut [f32; BLOCK]) {
        let lo = tile.map(|t| 4 * t - 2);
        let o = self.field.origin();
        let (o, dims) = ([o.x as i64, o.y as i64, o.z as i64], self.field.dims());
        let data = self.field.data();
        let (nx, ny) = (dims[0], dims[1]);
        let hi = [0, 1, 2].map(|a| o[a] + dims[a] as i64 - 1);
        // A block inside the array (almost every crossed tile): whole rows of eight, a
        // fixed length the compiler turns into vector loads and selects.
        if (0..3).all(|a| lo[a] >= o[a] && lo[a] + 7 <= hi[a]) {
            for (r, row) in values.chunks_exact_mut(8).enumerate() {
                let (y, z) = (lo[1] + (r % 8) as i64, lo[2] + (r / 8) as i64);
                let i =
                    (lo[0] - o[0]) as usize + nx * ((y - o[1]) as usize + ny * (z - o[2]) as usize);
                let src: &[f32; 8] = data[i..i + 8].try_into().expect("a row of eight");
                if finite(src) {
                    // `read` of a finite value is the product with the sign.
                    for (v, &x) in row.iter_mut().zip(src) {
                        *v = self.sign * x;
                    }
                } else {
                    for (v, &x) in row.iter_mut().zip(src) {
                        *v = self.read(x);
                    }
                }
            }
            return;
        }
        // The block's x range inside the array: local x in xa..xb.
        let xa = (o[0] - lo[0]).clamp(0, 8) as usize;
        let xb = (hi[0] + 1 - lo[0]).clamp(0, 8) as usize;
        for (r, row) in values.chunks_exact_mut(8).enumerate() {
            let (y, z) = (lo[1] + (r % 8) as i64, lo[2] + (r / 8) as i64);
            let (py, pz) = (y.clamp(o[1], hi[1]), z.clamp(o[2], hi[2]));
            let row_in = py == y && pz == z;
            if row_in && xa < xb {
                let i = (lo[0] + xa as i64 - o[0]) as usize
                    + nx * ((y - o[1]) as usize + ny * (z - o[2]) as usize);
                for (v, &x) in row[xa..xb].iter_mut().zip(&data[i..i + (xb - xa)]) {
                    *v = self.read(x);
                }
            }
            for (x, v) in row.iter_mut().enumerate() {
                if row_in && (xa..xb).contains(&x) {
                    continue;
                }
                let c = [lo[0] + x as i64, y, z];
                *v = self.beyond(c, [c[0].clamp(o[0], hi[0]), py, pz]);
            }
        }
    }
}

/// Whether no value is infinite: one vectorised pass (a NaN counts as finite here; the
/// arrays were checked for NaN before). Rows that pass are read with the product by the
/// sign, in loops the compiler vectorises (per-value `read` compiled to scalar branches);
/// with the fill's whole rows of eight this took `sl.isosurface` of the sphere of
/// docs/python_bench.py from 7.4 to 6.1 ms at 96³ and from 23 to 18 ms at 160³ (fastest
/// of 30, two runs; 2-core AMD EPYC, 2026-11-28).
#[inline(always)]
fn finite(v: &[f32]) -> bool {
    !v.iter().fold(false, |a, x| a | (x.abs() == f32::INFINITY))
}

impl DenseSource<'_> {
    /// The stored tiles whose reach (block voxels 1..=6 along each axis, `4 t − 1 ..=
    /// 4 t + 4`: what [`uniform`] looks at) holds voxels on both sides of iso, in
    /// [`Coord`] order: the tiles whose filled block is not [`uniform`], found without
    /// filling blocks (each voxel's side is read once, then the windows are merged one
    /// axis at a time: along x per voxel row, along y per tile column, along z per tile).
    ///
    /// With an open border only the array's voxels count: a meshed cell has its eight
    /// corners in the array, so the tiles that own it or a vertex of it have both sides
    /// among the array's voxels of their reach, and a tile crossed only beyond the array
    /// (by the extrapolation) would hold vertices that no triangle uses, which are dropped.
    /// The mesh is the same; the extrapolation is read for the normals only ([`Self::fill`]).
    fn crossed_tiles(&self, below: f32) -> Vec<Coord> {
        let (tlo, thi) = (self.tlo, self.thi);
        let tn = [0, 1, 2].map(|a| (thi[a] - tlo[a] + 1).max(0) as usize);
        if tn.contains(&0) {
            return Vec::new();
        }
        let vlo = tlo.map(|t| 4 * t - 1);
        let vn = tn.map(|n| 4 * n + 2);
        let o = self.field.origin();
        let (o, dims) = ([o.x as i64, o.y as i64, o.z as i64], self.field.dims());
        let hi = [0, 1, 2].map(|a| o[a] + dims[a] as i64 - 1);
        let data = self.field.data();
        let (nx, ny) = (dims[0], dims[1]);
        let open = self.clamps();
        // Sides along x: per voxel row (y, z) and tile x, bit 0 = a voxel below iso in the
        // tile's window, bit 1 = one not below.
        let mut fx = vec![0u8; vn[2] * vn[1] * tn[0]];
        fx.par_chunks_mut(vn[1] * tn[0]).enumerate().for_each(|(zi, plane)| {
            let z = vlo[2] + zi as i64;
            let mut side = vec![0u8; vn[0]];
            for (yi, row) in plane.chunks_exact_mut(tn[0]).enumerate() {
                let y = vlo[1] + yi as i64;
                let (py, pz) = (y.clamp(o[1], hi[1]), z.clamp(o[2], hi[2]));
                let row_in = py == y && pz == z;
                // The voxels of the row within the array's x range, when the row is in it.
                let (xa, xb) = (o[0] - vlo[0], hi[0] + 1 - vlo[0]);
                let (xa, xb) =
                    (xa.clamp(0, vn[0] as i64) as usize, xb.clamp(0, vn[0] as i64) as usize);
                let (xa, xb) = if row_in { (xa, xb) } else { (0, 0) };
                if xa < xb {
                    let i = (vlo[0] + xa as i64 - o[0]) as usize
                        + nx * ((y - o[1]) as usize + ny * (z - o[2]) as usize);
                    let base = &data[i..i + (xb - xa)];
                    // A loop the compiler vectorises when the row has no infinite value
                    // (`read` is then the product with the sign).
                    let sides = side[xa..xb].iter_mut().zip(base);
                    if finite(base) {
                        let sign = self.sign;
                        sides.for_each(|(sd, &x)| *sd = 2 - u8::from(sign * x < below));
                    } else {
                        sides.for_each(|(sd, &x)| *sd = 2 - u8::from(self.read(x) < below));
                    }
                }
                // Beyond the array: no side with an open border, else the outside value's.
                let beyond = if open { 0 } else { 2 - u8::from(self.outside < below) };
                side[..xa].fill(beyond);
                side[xb.max(xa)..].fill(beyond);
                for (t, f) in row.iter_mut().enumerate() {
                    *f = side[4 * t..4 * t + 6].iter().fold(0, |a, &b| a | b);
                }
            }
        });
        // Along y: per voxel z and tile (x, y).
        let mut fy = vec![0u8; vn[2] * tn[1] * tn[0]];
        fy.par_chunks_mut(tn[1] * tn[0]).enumerate().for_each(|(zi, plane)| {
            let src = &fx[zi * vn[1] * tn[0]..(zi + 1) * vn[1] * tn[0]];
            for (ty, row) in plane.chunks_exact_mut(tn[0]).enumerate() {
                for yi in 4 * ty..4 * ty + 6 {
                    for (f, &g) in row.iter_mut().zip(&src[yi * tn[0]..(yi + 1) * tn[0]]) {
                        *f |= g;
                    }
                }
            }
        });
        // Along z: per tile; the crossed ones in (z, y, x) order.
        (0..tn[2])
            .into_par_iter()
            .flat_map_iter(|tz| {
                let mut plane = vec![0u8; tn[1] * tn[0]];
                for zi in 4 * tz..4 * tz + 6 {
                    let src = &fy[zi * tn[1] * tn[0]..(zi + 1) * tn[1] * tn[0]];
                    for (f, &g) in plane.iter_mut().zip(src) {
                        *f |= g;
                    }
                }
                let (tz, tlo) = (tz as i64 + tlo[2], tlo);
                plane.into_iter().enumerate().filter(|&(_, f)| f == 3).map(move |(k, _)| {
                    let (tx, ty) = ((k % tn[0]) as i64 + tlo[0], (k / tn[0]) as i64 + tlo[1]);
                    Coord::new(tx as i32, ty as i32, tz as i32)
                })
            })
            .collect()
    }
}

impl Source for DenseSource<'_> {
    fn spec(&self) -> &GridSpec {
        &self.spec
    }

    fn coords(&self) -> &[Coord] {
        &self.coords
    }

    #[inline(always)]
    fn gather(&self, nb: &Neighbours, values: &mut [f32; BLOCK]) -> u32 {
        let t = [nb.coord.x as i64, nb.coord.y as i64, nb.coord.z as i64];
        self.fill(t, values);
        (0..27)
            .filter(|&n| {
                let o = NEIGHBOURHOOD[n];
                self.stored([t[0] + o.x as i64, t[1] + o.y as i64, t[2] + o.z as i64])
            })
            .fold(0, |m, n| m | 1 << n)
    }

    fn value(&self, c: [i64; 3]) -> f32 {
        let (lo, hi) = (self.field.origin(), self.field.max_coord());
        let (lo, hi) =
            ([lo.x as i64, lo.y as i64, lo.z as i64], [hi.x as i64, hi.y as i64, hi.z as i64]);
        let p = [0, 1, 2].map(|a| c[a].clamp(lo[a], hi[a]));
        if p == c {
            self.at(p)
        } else {
            self.beyond(c, p)
        }
    }

    fn meshed_cells(&self, t: Coord) -> [u64; 8] {
        match &self.cells {
            None => [!0; 8],
            Some(rule) => self.rule_cells(rule, t),
        }
    }
}

/// Per slot: its cut Kuhn edges and the index of their first vertex.
///
/// The vertices of a slot are numbered consecutively, by direction and then by voxel:
/// the vertex on the edge (local voxel `l`, direction `d`) has index
/// `base[d − 1] + popcount(edges[d − 1] & ((1 << l) − 1))`, an O(1) rank query that any
/// tile can make for its neighbours' vertices.
#[derive(Clone, Copy, Debug, Default)]
struct SlotInfo {
    /// Bit `l` of `edges[d − 1]`: the Kuhn edge from local voxel `l` in direction `d`
    /// (bit mask over x, y, z) is cut.
    edges: [u64; 7],
    /// Index of the slot's first vertex of each direction.
    base: [u32; 7],
}

/// A vertex on an edge that starts in a tile without a slot (only where absent tiles
/// reach a cut cell, which a valid band never has): (lower voxel as (z, y, x), direction).
type Orphan = ([i64; 3], u8);

/// What the counting pass finds in one chunk of slots besides the per-slot results.
#[derive(Default)]
struct ChunkCount {
    /// The slots with vertices or triangles and their neighbours (pass 2 needs no list
    /// walk then).
    active: Vec<Neighbours>,
    orphans: Vec<Orphan>,
    /// Bounds of the voxels at the ends of the chunk's cut edges.
    bounds: Option<([i64; 3], [i64; 3])>,
}

fn union(a: Option<([i64; 3], [i64; 3])>, b: ([i64; 3], [i64; 3])) -> Option<([i64; 3], [i64; 3])> {
    Some(match a {
        None => b,
        Some(a) => ([0, 1, 2].map(|i| a.0[i].min(b.0[i])), [0, 1, 2].map(|i| a.1[i].max(b.1[i]))),
    })
}

/// Smallest and largest local coordinate of the set bits of a tile mask (bit
/// `x + 4 y + 16 z`) along each axis; `m` must not be 0.
#[inline(always)]
fn mask_bounds(m: u64) -> ([i64; 3], [i64; 3]) {
    const X: u64 = 0x1111_1111_1111_1111;
    const Y: u64 = 0x000F_000F_000F_000F;
    const Z: u64 = 0xFFFF;
    let planes =
        [[X, X << 1, X << 2, X << 3], [Y, Y << 4, Y << 8, Y << 12], [Z, Z << 16, Z << 32, Z << 48]];
    let lo = planes.map(|p| p.iter().position(|&q| m & q != 0).unwrap_or(0) as i64);
    let hi = planes.map(|p| p.iter().rposition(|&q| m & q != 0).unwrap_or(0) as i64);
    (lo, hi)
}

/// Bounds of the end voxels of a tile's cut edges, in voxel coordinates.
#[inline(always)]
fn edge_bounds(tile: Coord, edges: &[u64; 7]) -> ([i64; 3], [i64; 3]) {
    let base = [4 * tile.x as i64, 4 * tile.y as i64, 4 * tile.z as i64];
    let all = edges.iter().fold(0, |a, &e| a | e);
    let (lo, _) = mask_bounds(all);
    let mut hi = [i64::MIN; 3];
    for (k, &e) in edges.iter().enumerate() {
        if e != 0 {
            let d = k + 1;
            let (_, h) = mask_bounds(e);
            for a in 0..3 {
                hi[a] = hi[a].max(h[a] + ((d >> a) & 1) as i64);
            }
        }
    }
    ([0, 1, 2].map(|a| base[a] + lo[a]), [0, 1, 2].map(|a| base[a] + hi[a]))
}

/// The cells a slot owns with a sign change that `meshed` admits (layout of
/// [`Source::meshed_cells`]), in (z, y, x) order of their lower corners (block
/// coordinates): `(x, y, z, pattern)` for each. An iterator rather than a function taking
/// a closure, so that the loop's body is compiled with the function it is written in
/// ([`fill_chunk_avx2`]: a closure is compiled for the instructions of the function that
/// defines it, and this one was not inlined).
struct CutCells<'a> {
    s: &'a [u64; 8],
    stored: u32,
    meshed: &'a [u64; 8],
    /// The cells of each layer that the slot may own.
    xy: u64,
    /// The layer of `cut`, and its cut cells not visited yet.
    z: usize,
    cut: u64,
}

impl<'a> CutCells<'a> {
    #[inline(always)]
    fn new(s: &'a [u64; 8], stored: u32, meshed: &'a [u64; 8]) -> CutCells<'a> {
        // The cells one voxel before the tile belong to the tile before them when that one
        // is stored (always, in a band whose absent tiles keep a voxel off the surface).
        let (zs, xy) = if stored & BEFORE == BEFORE { (2, TILE_XY) } else { (1, CELL_XY) };
        CutCells { s, stored, meshed, xy, z: zs - 1, cut: 0 }
    }
}

impl Iterator for CutCells<'_> {
    type Item = (usize, usize, usize, usize);

    #[inline(always)]
    fn next(&mut self) -> Option<Self::Item> {
        loop {
            while self.cut == 0 {
                self.z += 1;
                if self.z >= 6 {
                    return None;
                }
                self.cut = cut_cells(self.s, self.z) & self.xy & self.meshed[self.z];
            }
            let b = self.cut.trailing_zeros() as usize;
            self.cut &= self.cut - 1;
            let (x, y, z) = (b & 7, b >> 3, self.z);
            if (x < 2 || y < 2 || z < 2) && !owns_cell(self.stored, x, y, z) {
                continue;
            }
            return Some((x, y, z, pattern(self.s, x, y, z)));
        }
    }
}

/// The orphan key of the edge from block voxel `v` of tile `t` in direction `d`.
#[inline(always)]
fn orphan_key(t: Coord, v: [usize; 3], d: u8) -> Orphan {
    let w = |a: usize, c: i32| 4 * c as i64 + v[a] as i64 - 2;
    ([w(2, t.z), w(1, t.y), w(0, t.x)], d)
}

/// One work item of [`run`]'s first pass: slots `start..start + info.len()` and their
/// results.
struct CountPart<'a> {
    start: usize,
    info: &'a mut [SlotInfo],
    tri_count: &'a mut [u32],
}

/// Pass 1 of [`run`] over one chunk of slots: each slot's cut edges and triangle count,
/// and the chunk's orphans, bounds and active slots. Inlined into both [`run`] and
/// [`count_chunk_avx2`], and so compiled for each.
#[inline(always)]
fn count_chunk<S: Source>(
    src: &S,
    below: f32,
    part: CountPart<'_>,
    values: &mut [f32; BLOCK],
) -> ChunkCount {
    let CountPart { start, info, tri_count } = part;
    let (coords, cases) = (src.coords(), cell_cases());
    let mut out = ChunkCount::default();
    for nb in NeighbourCursor::new(coords, start, start + info.len()) {
        let k = nb.pos - start;
        let stored = src.gather(&nb, values);
        let s = signs(values, below);
        if uniform(&s) {
            continue;
        }
        let meshed = src.meshed_cells(nb.coord);
        let edges = edge_masks(&s);
        if edges != [0; 7] {
            out.bounds = union(out.bounds, edge_bounds(nb.coord, &edges));
        }
        info[k].edges = edges;
        let mut tris = 0u32;
        for (x, y, z, p) in CutCells::new(&s, stored, &meshed) {
            let case = &cases[p];
            tris += case.n_tris as u32;
            if cell_tiles(x, y, z) & !nb.matched == 0 {
                continue;
            }
            for &e in &case.edges[..case.n_edges as usize] {
                let (lo, d) = ((e & 7) as usize, e >> 3);
                let v = [x + (lo & 1), y + ((lo >> 1) & 1), z + (lo >> 2)];
                if nb.matched & (1 << tile_and_local(v[0], v[1], v[2]).0) == 0 {
                    out.orphans.push(orphan_key(nb.coord, v, d));
                }
            }
        }
        tri_count[k] = tris;
        if tris > 0 || edges != [0; 7] {
            out.active.push(nb);
        }
    }
    out
}

/// [`count_chunk`] compiled for AVX2, POPCNT and BMI1 (the same operations, so the same
/// results).
///
/// # Safety
/// The CPU must have AVX2, POPCNT and BMI1 ([`avx2`]).
#[cfg_attr(target_arch = "x86_64", target_feature(enable = "avx2,popcnt,bmi1"))]
unsafe fn count_chunk_avx2<S: Source>(
    src: &S,
    below: f32,
    part: CountPart<'_>,
    values: &mut [f32; BLOCK],
) -> ChunkCount {
    count_chunk(src, below, part, values)
}

/// Whether the two passes run compiled for AVX2, POPCNT and BMI1 ([`count_chunk_avx2`],
/// [`fill_chunk_avx2`]): where the CPU has them and [`crate::level`] (the variable
/// `LEVELSET_SIMD`) does not force the baseline. The operations are the same, so the mesh
/// is the same to the bit (a test compares the two); a build for the x86-64 baseline
/// (SSE2) otherwise runs the passes' `f64` arithmetic two lanes wide and counts bits
/// without `popcnt`. `isosurface` of a 96³ array from Python: 4.1–5.4 ms instead of
/// 4.9–6.7 ms (decision 0056).
fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use crate::level::Level;
        use std::arch::is_x86_feature_detected as has;
        if Level::active() >= Level::Avx2 && has!("popcnt") && has!("bmi1") {
            return true;
        }
    }
    false
}

/// The mesh of a source in two passes over its slots (see the module docs). With
/// `values`, also per vertex its [`vertex_value`]; otherwise an empty vector. `avx2`
/// ([`avx2`]) only where the CPU has what it needs.
fn run<S: Source>(
    src: &S,
    iso: f64,
    ticker: &Ticker,
    values: bool,
    avx2: bool,
) -> Result<(TriangleMesh, Vec<f32>), MeshError> {
    let coords = src.coords();
    let n = coords.len();
    let below = f32_threshold(iso);

    // Pass 1: which edges are cut, how many triangles, orphans and bounds.
    let mut info = vec![SlotInfo::default(); n];
    let mut tri_count = vec![0u32; n];
    let chunks: Vec<ChunkCount> = info
        .par_chunks_mut(CHUNK)
        .zip(tri_count.par_chunks_mut(CHUNK))
        .enumerate()
        .map_init(
            || Box::new([0f32; BLOCK]),
            |values, (ci, (info, tri_count))| {
                ticker.check()?;
                let part = CountPart { start: ci * CHUNK, info, tri_count };
                Ok(if avx2 {
                    // SAFETY: `avx2` is set only where the CPU has AVX2, POPCNT and BMI1
                    // (`run`'s callers take it from `avx2()`, which detects them).
                    unsafe { count_chunk_avx2(src, below, part, values) }
                } else {
                    count_chunk(src, below, part, values)
                })
            },
        )
        .collect::<Result<_, Cancelled>>()?;
    let mut bounds = None;
    let mut orphans = Vec::new();
    let mut active = Vec::with_capacity(chunks.len());
    for c in chunks {
        if let Some(b) = c.bounds {
            bounds = union(bounds, b);
        }
        orphans.extend(c.orphans);
        active.push(c.active);
    }
    orphans.sort_unstable();
    orphans.dedup();
    for &(v, d) in &orphans {
        let lo = [v[2], v[1], v[0]];
        let hi = [0, 1, 2].map(|a| lo[a] + ((d >> a) & 1) as i64);
        bounds = union(bounds, (lo, hi));
    }
    let Some((vmin, vmax)) = bounds else {
        return Ok((TriangleMesh::default(), Vec::new()));
    };

    // Numbering: slot vertices in slot order, then the orphans; triangles in slot order.
    let mut next = 0u64;
    for s in info.iter_mut() {
        for d in 0..7 {
            s.base[d] = next as u32;
            next += s.edges[d].count_ones() as u64;
        }
        if next > u32::MAX as u64 {
            return Err(MeshError::TooLarge(format!("more than {} vertices", u32::MAX)));
        }
    }
    let slot_verts = next as usize;
    let verts = slot_verts + orphans.len();
    if verts > u32::MAX as usize {
        return Err(MeshError::TooLarge(format!("{verts} vertices")));
    }
    let mut tri_start = Vec::with_capacity(n + 1);
    let mut t = 0usize;
    for &c in &tri_count {
        tri_start.push(t);
        t += c as usize;
    }
    tri_start.push(t);
    let counted = Counted { info, tri_start, orphans, slot_verts, active };

    let placer = Placer::new(src.spec(), vmin, vmax)?;
    // The precision is decided once, outside the loops.
    match placer.precision {
        Precision::F32 => fill::<S, true>(src, iso, ticker, &counted, &placer, values, avx2),
        Precision::F64 => fill::<S, false>(src, iso, ticker, &counted, &placer, values, avx2),
    }
}

/// The results of pass 1 with the numbering of vertices and triangles.
struct Counted {
    info: Vec<SlotInfo>,
    /// Per chunk of [`CHUNK`] slots, its slots with work and their neighbours.
    active: Vec<Vec<Neighbours>>,
    /// Index of each slot's first triangle, and the number of triangles at the end.
    tri_start: Vec<usize>,
    orphans: Vec<Orphan>,
    /// Vertices of the slots (the orphans follow them).
    slot_verts: usize,
}

impl Counted {
    /// Triangles of slot `s`.
    fn tri_count(&self, s: usize) -> usize {
        self.tri_start[s + 1] - self.tri_start[s]
    }

    /// Index of slot `s`'s first vertex (the number of slot vertices for `s` = slots).
    fn vertex_start(&self, s: usize) -> usize {
        match self.info.get(s) {
            Some(i) => i.base[0] as usize,
            None => self.slot_verts,
        }
    }
}

/// Pass 2: every slot writes its vertices and triangles into its own ranges of the mesh,
/// chunks in parallel; then the orphans. `F32`: the placer's precision. `want_values`:
/// also each vertex's [`vertex_value`].
fn fill<S: Source, const F32: bool>(
    src: &S,
    iso: f64,
    ticker: &Ticker,
    c: &Counted,
    placer: &Placer,
    want_values: bool,
    avx2: bool,
) -> Result<(TriangleMesh, Vec<f32>), MeshError> {
    let n = src.coords().len();
    let (tri_start, slot_verts) = (&c.tri_start, c.slot_verts);
    let verts = slot_verts + c.orphans.len();
    let tris = tri_start[n];
    // Every element is written exactly once below (checked before the lengths are set),
    // so the buffers are not zeroed first: zeroing cost 1 ms of 28 (one thread, r = 100
    // sphere, where the allocator reuses memory; three alternated runs of 15, minima).
    // The buffers are fresh, so huge pages are asked for before the first write.
    let mut positions: Vec<[f64; 3]> = Vec::with_capacity(verts);
    let mut normals: Vec<[f32; 3]> = Vec::with_capacity(verts);
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(tris);
    crate::memory::advise_huge_pages(&mut positions);
    crate::memory::advise_huge_pages(&mut normals);
    crate::memory::advise_huge_pages(&mut triangles);
    let (slot_pos, orphan_pos) = positions.spare_capacity_mut()[..verts].split_at_mut(slot_verts);
    let (slot_nrm, orphan_nrm) = normals.spare_capacity_mut()[..verts].split_at_mut(slot_verts);
    // Values per vertex, when asked for (zeroed: a plain, safe buffer).
    let mut vvalues = vec![0f32; if want_values { verts } else { 0 }];
    let (slot_val, orphan_val) = vvalues.split_at_mut(if want_values { slot_verts } else { 0 });
    let mut work = Vec::with_capacity(n.div_ceil(CHUNK));
    {
        let (mut p, mut q, mut r, mut g) =
            (slot_pos, slot_nrm, &mut triangles.spare_capacity_mut()[..tris], slot_val);
        for start in (0..n).step_by(CHUNK) {
            let end = (start + CHUNK).min(n);
            let nv = c.vertex_start(end) - c.vertex_start(start);
            let nt = tri_start[end] - tri_start[start];
            let (p0, p1) = p.split_at_mut(nv);
            let (q0, q1) = q.split_at_mut(nv);
            let (r0, r1) = r.split_at_mut(nt);
            let (g0, g1) = g.split_at_mut(if want_values { nv } else { 0 });
            work.push((end, FillPart { start, pos: p0, nrm: q0, tri: r0, val: g0 }));
            (p, q, r, g) = (p1, q1, r1, g1);
        }
    }
    let inputs = FillInputs { src, iso, below: f32_threshold(iso), c, placer, want_values };
    let missing: Vec<bool> = work
        .into_par_iter()
        .map_init(
            || (Box::new([0f32; BLOCK]), VertexBatch::new(), Box::new([0f32; BLOCK])),
            |(values, batch, ranges), (end, part)| {
                ticker.check()?;
                let slots = (end - part.start) as u64;
                let scratch = (&mut **values, &mut **batch, &mut **ranges);
                let missing = if avx2 {
                    // SAFETY: as in `run`'s first pass.
                    unsafe { fill_chunk_avx2::<S, F32>(&inputs, part, scratch) }
                } else {
                    fill_chunk::<S, F32>(&inputs, part, scratch)
                };
                ticker.advance(slots)?;
                Ok(missing)
            },
        )
        .collect::<Result<_, Cancelled>>()?;
    let mut missing = missing.contains(&true);
    let mut batch = VertexBatch::new();
    for (k, group) in c.orphans.chunks(TILE_VERTS).enumerate() {
        batch.clear();
        for &(v, d) in group {
            let lo = [v[2], v[1], v[0]];
            batch.push(lo, d as usize, iso, |a, b, c| {
                src.value([lo[0] + a as i64, lo[1] + b as i64, lo[2] + c as i64])
            });
        }
        let at = k * TILE_VERTS;
        if want_values {
            for (&(v, d), val) in group.iter().zip(&mut orphan_val[at..]) {
                *val = orphan_value(src, [v[2], v[1], v[0]], d as usize);
            }
        }
        missing |=
            batch.finish::<F32>(&placer.placement(), &mut orphan_pos[at..], &mut orphan_nrm[at..]);
    }
    // SAFETY: the chunks partition `0..slot_verts` and `0..tris` (ranges from the
    // counts of pass 1); within a chunk every slot with work wrote its own disjoint range
    // front to back to its end, and the written totals equal the chunk's range lengths
    // (all asserted above, in release builds too), so every element below the new
    // lengths is initialised; the orphan loop wrote `slot_verts..verts`.
    unsafe {
        positions.set_len(verts);
        normals.set_len(verts);
        triangles.set_len(tris);
    }
    let mut mesh = TriangleMesh { positions, normals, triangles };
    if missing {
        mesh.fill_missing_normals();
    }
    Ok((mesh, vvalues))
}

/// One work item of [`fill`]'s second pass: the slots of the active list from `start`'s
/// chunk, and the parts of the buffers their vertices, triangles and values go to.
struct FillPart<'a> {
    start: usize,
    pos: &'a mut [std::mem::MaybeUninit<[f64; 3]>],
    nrm: &'a mut [std::mem::MaybeUninit<[f32; 3]>],
    tri: &'a mut [std::mem::MaybeUninit<[u32; 3]>],
    val: &'a mut [f32],
}

/// What every work item of [`fill`]'s second pass reads.
struct FillInputs<'a, S> {
    src: &'a S,
    iso: f64,
    /// [`f32_threshold`] of `iso`.
    below: f32,
    c: &'a Counted,
    placer: &'a Placer,
    want_values: bool,
}

/// A task's scratch for [`fill_chunk`]: the block, the vertex batch, the cell ranges.
type FillScratch<'a> = (&'a mut [f32; BLOCK], &'a mut VertexBatch, &'a mut [f32; BLOCK]);

/// The second pass of [`fill`] over one work item: every vertex and triangle of its
/// slots, written in place; whether a normal is missing. Inlined into both [`fill`] and
/// [`fill_chunk_avx2`], and so compiled for each.
#[inline(always)]
fn fill_chunk<S: Source, const F32: bool>(
    inputs: &FillInputs<'_, S>,
    part: FillPart<'_>,
    (values, batch, ranges): FillScratch<'_>,
) -> bool {
    let &FillInputs { src, iso, below, c, placer, want_values } = inputs;
    let FillPart { start, pos, nrm, tri, val } = part;
    let (info, tri_start, slot_verts) = (&c.info, &c.tri_start, c.slot_verts);
    let cases = cell_cases();
    let orphan_index = |key: Orphan| -> u32 {
        let i = c.orphans.binary_search(&key).expect("orphan edges were collected in pass 1");
        (slot_verts + i) as u32
    };
    let mut missing = false;
    let (v0, t0) = (c.vertex_start(start), tri_start[start]);
    let (mut wrote_v, mut wrote_t) = (0, 0);
    for nb in &c.active[start / CHUNK] {
        let me = &info[nb.pos];
        let stored = src.gather(nb, values);
        let s = signs(values, below);
        // Vertices, by direction then voxel (the rank order of `SlotInfo`).
        let w = me.base[0] as usize - v0;
        let t = nb.coord;
        let tile = [4 * t.x as i64, 4 * t.y as i64, 4 * t.z as i64];
        let meshed = src.meshed_cells(t);
        if want_values {
            cell_ranges(values, &meshed, ranges);
        }
        batch.clear();
        for (k, &e) in me.edges.iter().enumerate() {
            let mut m = e;
            while m != 0 {
                let l = m.trailing_zeros() as usize;
                m &= m - 1;
                let (lx, ly, lz) = (l & 3, (l >> 2) & 3, l >> 4);
                if want_values {
                    let v = [lx + 2, ly + 2, lz + 2];
                    val[w + batch.len()] = vertex_value(ranges, v, k + 1);
                }
                let at = bidx(lx + 2, ly + 2, lz + 2) as i32;
                let lo = [tile[0] + lx as i64, tile[1] + ly as i64, tile[2] + lz as i64];
                batch.push(lo, k + 1, iso, |a, b, c| values[(at + a + 8 * b + 64 * c) as usize]);
            }
        }
        let w = w + batch.len();
        missing |= batch.finish::<F32>(
            &placer.placement(),
            &mut pos[w - batch.len()..],
            &mut nrm[w - batch.len()..],
        );
        assert_eq!(w, c.vertex_start(nb.pos + 1) - v0, "every vertex written once");
        wrote_v += batch.len();
        // Triangles of the owned cut cells.
        let nbr: [Option<&SlotInfo>; 27] = std::array::from_fn(|k| nb.get(k).map(|p| &info[p]));
        let mut w = tri_start[nb.pos] - t0;
        let mut idx = [0u32; CELL_EDGES];
        for (x, y, z, p) in CutCells::new(&s, stored, &meshed) {
            let case = &cases[p];
            for (i, &e) in idx.iter_mut().zip(&case.edges[..case.n_edges as usize]) {
                let (lo, d) = ((e & 7) as usize, e >> 3);
                let v = [x + (lo & 1), y + ((lo >> 1) & 1), z + (lo >> 2)];
                let (tn, l) = tile_and_local(v[0], v[1], v[2]);
                *i = match nbr[tn] {
                    Some(si) => {
                        let dk = d as usize - 1;
                        debug_assert!(si.edges[dk] >> l & 1 == 1, "uncounted vertex");
                        si.base[dk] + (si.edges[dk] & ((1u64 << l) - 1)).count_ones()
                    }
                    None => orphan_index(orphan_key(t, v, d)),
                };
            }
            for tr in &case.tris[..case.n_tris as usize] {
                tri[w].write(tr.map(|k| idx[k as usize]));
                w += 1;
            }
        }
        assert_eq!(w, tri_start[nb.pos + 1] - t0, "every triangle written once");
        wrote_t += c.tri_count(nb.pos);
    }
    // The slots' ranges are disjoint and each was written to its end, so
    // these totals mean the chunk's ranges are written whole.
    assert!(wrote_v == pos.len() && wrote_t == tri.len(), "a slot with work skipped");
    missing
}

/// [`fill_chunk`] compiled for AVX2, POPCNT and BMI1 (the same operations, so the same
/// results).
///
/// # Safety
/// The CPU must have AVX2, POPCNT and BMI1 ([`avx2`]).
#[cfg_attr(target_arch = "x86_64", target_feature(enable = "avx2,popcnt,bmi1"))]
unsafe fn fill_chunk_avx2<S: Source, const F32: bool>(
    inputs: &FillInputs<'_, S>,
    part: FillPart<'_>,
    scratch: FillScratch<'_>,
) -> bool {
    fill_chunk::<S, F32>(inputs, part, scratch)
}

/// Per direction `d` (bit mask over x, y, z) of a Kuhn edge, the cells that hold the edge,
/// as the axes (bit mask) along which their lower corner lies one voxel below the edge's
/// lower voxel: the 2^(3 − |d|) subsets of the axes outside `d` (the Kuhn edges of a cube
/// are those from a corner to a corner above it). Unused entries repeat 0 (the same cell
/// again, which leaves a maximum unchanged).
const EDGE_CELLS: [[usize; 4]; 8] = {
    let mut t = [[0; 4]; 8];
    let mut d = 1;
    while d < 8 {
        let free = 7 & !d;
        let (mut u, mut k) = (free, 0);
        loop {
            t[d][k] = u;
            k += 1;
            if u == 0 {
                break;
            }
            u = (u - 1) & free;
        }
        d += 1;
    }
    t
};

/// [`EDGE_CELLS`] as block index offsets (down from the edge's lower voxel).
const EDGE_CELL_OFFSETS: [[usize; 4]; 8] = {
    let mut t = [[0; 4]; 8];
    let mut d = 0;
    while d < 8 {
        let mut k = 0;
        while k < 4 {
            let u = EDGE_CELLS[d][k];
            t[d][k] = bidx(u & 1, (u >> 1) & 1, u >> 2);
            k += 1;
        }
        d += 1;
    }
    t
};

/// scikit-image's `values` of the vertex on the Kuhn edge from block voxel `v` in
/// direction `d`: the largest of the [`cell_ranges`] of the cells that hold the edge
/// ([`EDGE_CELLS`]), −1 when the rule admits none of them (the vertex is then on no
/// triangle). Each admitted one has a triangle on the vertex (every tetrahedron of the
/// cell with a cut edge has a polygon with a vertex on that edge), so this is the largest
/// range over the triangles that use the vertex, computed per vertex rather than
/// scattered from the triangles.
#[inline(always)]
fn vertex_value(ranges: &[f32; BLOCK], v: [usize; 3], d: usize) -> f32 {
    let i = bidx(v[0], v[1], v[2]);
    EDGE_CELL_OFFSETS[d].iter().fold(-1f32, |m, &o| m.max(ranges[i - o]))
}

/// [`vertex_value`] of a vertex on an edge that starts in a tile without a slot (lower
/// voxel `lo`, direction `d`), from [`Source::value`] and the rule of each cell's owner.
fn orphan_value<S: Source>(src: &S, lo: [i64; 3], d: usize) -> f32 {
    EDGE_CELLS[d].iter().fold(-1f32, |best, &u| {
        let c = [0, 1, 2].map(|a| lo[a] - ((u >> a) & 1) as i64);
        let t = c.map(|c| c.div_euclid(4));
        let b = [0, 1, 2].map(|a| (c[a] - 4 * t[a] + 2) as usize);
        let owner = Coord::new(t[0] as i32, t[1] as i32, t[2] as i32);
        if src.meshed_cells(owner)[b[2]] >> (b[0] + 8 * b[1]) & 1 == 0 {
            return best;
        }
        let (mut l, mut h) = (f32::INFINITY, f32::NEG_INFINITY);
        for k in 0..8 {
            let x = src.value([0, 1, 2].map(|a| c[a] + ((k >> a) & 1) as i64));
            (l, h) = (l.min(x), h.max(x));
        }
        best.max(h - l)
    })
}

/// Per cell of the block, the largest minus the smallest value at its eight corners, at
/// the index of its lower corner (block voxel `(x, y, z)`, [`bidx`]; valid for x, y, z < 7),
/// or −1 where `meshed` does not admit the cell. The minima and maxima are taken one axis
/// at a time over the whole block, in loops the compiler vectorises (by comparisons: the
/// values hold no NaN, so these are `f32::min` and `max`). The difference in f32 is the
/// f64 difference rounded to f32 (53 ≥ 2 · 24 + 2 bits: a double rounding of a sum is the
/// single one).
#[inline(always)]
fn cell_ranges(values: &[f32; BLOCK], meshed: &[u64; 8], out: &mut [f32; BLOCK]) {
    /// `lo`, `hi` ← the smaller and the larger of `a` at i and at i + `step`.
    #[inline(always)]
    fn pair(a: &[f32], b: &[f32], step: usize, lo: &mut [f32; BLOCK], hi: &mut [f32; BLOCK]) {
        let n = BLOCK - step;
        for (o, (&x, &y)) in lo[..n].iter_mut().zip(a[..n].iter().zip(&a[step..])) {
            *o = if y < x { y } else { x };
        }
        for (o, (&x, &y)) in hi[..n].iter_mut().zip(b[..n].iter().zip(&b[step..])) {
            *o = if y > x { y } else { x };
        }
    }
    let (mut lo, mut hi) = ([0f32; BLOCK], [0f32; BLOCK]);
    let (mut lo2, mut hi2) = ([0f32; BLOCK], [0f32; BLOCK]);
    pair(values, values, bidx(1, 0, 0), &mut lo, &mut hi);
    pair(&lo, &hi, bidx(0, 1, 0), &mut lo2, &mut hi2);
    pair(&lo2, &hi2, bidx(0, 0, 1), &mut lo, &mut hi);
    for ((o, &h), &l) in out.iter_mut().zip(&hi).zip(&lo) {
        *o = h - l;
    }
    for (z, &m) in meshed.iter().enumerate() {
        if m != !0 {
            for (b, o) in out[bidx(0, 0, z)..bidx(0, 0, z + 1)].iter_mut().enumerate() {
                if m >> b & 1 == 0 {
                    *o = -1.0;
                }
            }
        }
    }
}

/// Floating-point precision of a mesh's positions (see the module docs, "Precision").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Precision {
    F32,
    F64,
}

impl Precision {
    /// Spacing of the representable values at magnitude `m` (≥ 0): the ulp of `m`, or of
    /// the next binade when `m` rounds up to a power of two; infinite beyond the range.
    #[inline]
    fn ulp(self, m: f64) -> f64 {
        match self {
            Precision::F32 => {
                let x = m as f32;
                let up = x.next_up();
                if up.is_finite() {
                    (up - x) as f64
                } else {
                    f64::INFINITY
                }
            }
            Precision::F64 => {
                let up = m.next_up();
                if up.is_finite() {
                    up - m
                } else {
                    f64::INFINITY
                }
            }
        }
    }
}

/// A precision may hold a mesh when its ulp at the mesh's largest coordinate is at most
/// this fraction of a voxel (rounding error ≤ 1/8192 voxel).
const MAX_ULP_IN_VOXELS: f64 = 1.0 / 4096.0;

/// Places vertices: world positions from an edge and its parameter, in the precision
/// the whole mesh needs.
struct Placer {
    origin: [f64; 3],
    h: f64,
    precision: Precision,
}

impl Placer {
    /// The placement of a mesh whose edges' end voxels lie in `vmin..=vmax`: f32 when its
    /// ulp at the largest coordinate is at most [`MAX_ULP_IN_VOXELS`] voxels, else f64
    /// under the same rule, else [`MeshError::Precision`]. (|origin + h·v| is convex in v,
    /// so the largest coordinate is reached at the bounds.)
    fn new(spec: &GridSpec, vmin: [i64; 3], vmax: [i64; 3]) -> Result<Placer, MeshError> {
        let h = spec.voxel_size as f64;
        let p = Placer { origin: spec.origin, h, precision: Precision::F32 };
        let extent = magnitude(p.world(vmin), p.world(vmax));
        let precision = [Precision::F32, Precision::F64]
            .into_iter()
            .find(|p| p.ulp(extent) <= MAX_ULP_IN_VOXELS * h)
            .ok_or(MeshError::Precision { extent, voxel_size: h })?;
        Ok(Placer { precision, ..p })
    }

    #[inline(always)]
    fn world(&self, v: [i64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.origin[a] + self.h * v[a] as f64)
    }

    fn placement(&self) -> Placement {
        Placement { origin: self.origin, h: self.h }
    }
}

/// The largest |coordinate| of two points.
#[inline(always)]
fn magnitude(a: [f64; 3], b: [f64; 3]) -> f64 {
    a.iter().chain(&b).fold(0f64, |m, &c| m.max(c.abs()))
}

fn check_iso(iso: f64) -> Result<(), MeshError> {
    if iso.is_finite() {
        Ok(())
    } else {
        Err(MeshError::InvalidParameter(format!("iso value must be finite, got {iso}")))
    }
}

/// The isosurface φ = `opts.iso` of any level set as one welded, outward-oriented
/// triangle mesh in world coordinates (see the module docs for the cells, welding and
/// determinism). Values exactly equal to the iso value count as outside (the ε rule of
/// Sec. 3), so the mesh of a level set inside the band is closed and manifold; the iso
/// value must lie strictly inside (−γ, γ), where the band carries the surface. An empty
/// level set gives an empty mesh. A tile grid is meshed as it is; any other storage
/// through [`crate::storage::convert::tiles_from`] (same values, so the same mesh). With
/// `opts.coarsen` = k > 1 the mesh is that of φ sampled at every k-th voxel
/// ([`MeshOptions::coarsen`]). Progress counts tiles.
pub fn isosurface<G: LevelSet + ?Sized>(
    grid: &G,
    opts: &MeshOptions,
) -> Result<TriangleMesh, MeshError> {
    let iso = opts.iso;
    check_iso(iso)?;
    let g = grid.spec().gamma() as f64;
    if iso.abs() >= g {
        return Err(MeshError::InvalidParameter(format!(
            "iso value {iso} is outside the band (-{g}, {g}) that carries the level set"
        )));
    }
    if opts.coarsen == 0 {
        return Err(MeshError::InvalidParameter(
            "coarsen must be at least 1 (1: every voxel)".into(),
        ));
    }
    let converted;
    let grid = match crate::storage::tiles::TileGrid::of(grid) {
        Some(t) => t,
        None => {
            converted = crate::storage::convert::tiles_from(grid);
            &converted
        }
    };
    let coarse;
    let grid = if opts.coarsen > 1 {
        coarse = super::coarse::sample(grid, opts.coarsen)?;
        &coarse
    } else {
        grid
    };
    let ticker = opts.progress.start(grid.len() as u64);
    Ok(run(&GridSource::new(grid), iso, &ticker, false, avx2())?.0)
}

/// The isosurface φ = `iso` of a dense field, voxel size and origin from `spec` (the
/// field's own origin places it on the voxel grid). Values beyond the array read as
/// `iso + γ` (outside; for iso = 0 the `+γ` of [`crate::storage::convert::tiles_from_dense`]), so a
/// surface that reaches the array's boundary is closed along it. ±∞ is a far-away
/// distance (as in [`crate::io::npy::read_npy`]) and reads as `iso ± γ`. On the same values
/// the mesh is the one [`isosurface`] makes (same cells, same arithmetic, same vertex
/// and triangle order). Errors on NaN or a non-finite iso.
pub fn isosurface_dense(
    field: &DenseField,
    spec: &GridSpec,
    iso: f64,
) -> Result<TriangleMesh, MeshError> {
    check_nan(field)?;
    let none = crate::progress::Progress::none();
    Ok(dense_mesh(field, false, spec, iso, None, false, &none)?.0)
}

/// [`MeshError::NaN`] at the first NaN of the field.
pub(super) fn check_nan(field: &DenseField) -> Result<(), MeshError> {
    match crate::storage::dense::first_position(field.data(), |v| v.is_nan()) {
        Some(i) => Err(MeshError::NaN { coord: field.coord_of(i).expect("index in range") }),
        None => Ok(()),
    }
}

/// [`isosurface_dense`] with only the cells `cells` admits (all for `None`), each
/// vertex's [`vertex_value`] when `values` (see [`run`]), and progress in tiles. The
/// caller has checked that the field holds no NaN ([`check_nan`]). `negate`: mesh `−field`
/// (the same bits as a negated copy, without the copy).
pub(super) fn dense_mesh(
    field: &DenseField,
    negate: bool,
    spec: &GridSpec,
    iso: f64,
    cells: Option<CellRule>,
    values: bool,
    progress: &crate::progress::Progress,
) -> Result<(TriangleMesh, Vec<f32>), MeshError> {
    check_iso(iso)?;
    let src = dense_source(field, negate, spec, iso, cells);
    let ticker = progress.start(src.coords.len() as u64);
    run(&src, iso, &ticker, values, avx2())
}

/// The source of [`dense_mesh`]: the array's tiles that the surface crosses.
fn dense_source<'a>(
    field: &'a DenseField,
    negate: bool,
    spec: &GridSpec,
    iso: f64,
    cells: Option<CellRule<'a>>,
) -> DenseSource<'a> {
    let o = field.origin();
    let hi = field.max_coord();
    let lo = [o.x as i64 - 1, o.y as i64 - 1, o.z as i64 - 1];
    let hi = [hi.x as i64, hi.y as i64, hi.z as i64];
    // Tiles below the representable range would hold only voxels below i32::MIN, which
    // read as outside; the cells that reach up from there belong to the first tile.
    let mut src = DenseSource {
        field,
        spec: *spec,
        coords: Vec::new(),
        tlo: lo.map(|c| c.div_euclid(4).max(TILE_MIN as i64)),
        thi: hi.map(|c| c.div_euclid(4)),
        outside: (iso + spec.gamma() as f64) as f32,
        inside: (iso - spec.gamma() as f64) as f32,
        cells,
        sign: if negate { -1.0 } else { 1.0 },
    };
    // The slots: the stored tiles whose block the surface crosses (any other tile has no
    // cut edge and no cut cell).
    let coords = src.crossed_tiles(f32_threshold(iso));
    src.coords = coords;
    src
}

#[cfg(test)]
mod tests {
    use super::super::cells::KUHN;
    use super::super::tables::pieces;
    use super::*;

    /// The passes compiled for AVX2 give the baseline's mesh to the bit: positions,
    /// normals, triangles and values, from a dense array (open and closed borders, a
    /// mask, negated reads, f32 and f64 placement) and from a tile grid.
    #[test]
    fn the_avx2_passes_give_the_baseline_mesh() {
        if !avx2() {
            eprintln!("no AVX2 on this CPU (or LEVELSET_SIMD=baseline): nothing to compare");
            return;
        }
        let none = crate::progress::Progress::none();
        let same = |a: &(TriangleMesh, Vec<f32>), b: &(TriangleMesh, Vec<f32>), what: &str| {
            let bits = |m: &TriangleMesh| -> Vec<u64> {
                m.positions.iter().flatten().map(|v| v.to_bits()).collect()
            };
            let nbits = |m: &TriangleMesh| -> Vec<u32> {
                m.normals.iter().flatten().map(|v| v.to_bits()).collect()
            };
            assert!(!a.0.triangles.is_empty(), "{what}: an empty mesh shows nothing");
            assert_eq!(bits(&a.0), bits(&b.0), "{what}: positions");
            assert_eq!(nbits(&a.0), nbits(&b.0), "{what}: normals");
            assert_eq!(a.0.triangles, b.0.triangles, "{what}: triangles");
            let v = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(v(&a.1), v(&b.1), "{what}: values");
        };
        // A sphere with a little noise of its own per voxel (a hash of the coordinates).
        let field = DenseField::from_fn(Coord::new(-7, 3, 5), [37, 29, 33], |c| {
            let p = [c.x as f32 + 0.3, c.y as f32 - 17.1, c.z as f32 - 21.7];
            let h = (c.x.wrapping_mul(73_856_093) ^ c.y.wrapping_mul(19_349_663))
                ^ c.z.wrapping_mul(83_492_791);
            let noise = (h & 1023) as f32 / 1023.0;
            (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 12.0 + 0.4 * noise
        })
        .unwrap();
        let mask: Vec<bool> = (0..field.data().len()).map(|i| i % 7 != 3).collect();
        for (spec, negate, open, masked) in [
            (GridSpec::default(), false, false, false),
            (GridSpec::default(), true, true, false),
            (GridSpec::default(), false, true, true),
            // Far from the origin: the placer keeps f64 positions.
            (GridSpec::new(0.5, [3.0e7, -2.0e7, 1.0e7], 3.0).unwrap(), false, false, false),
        ] {
            let iso = if negate { -0.25 } else { 0.25 };
            let cells =
                (open || masked).then(|| CellRule { open, mask: masked.then_some(&mask[..]) });
            let src = dense_source(&field, negate, &spec, iso, cells);
            let ticker = none.start(src.coords.len() as u64);
            let base = run(&src, iso, &ticker, true, false).unwrap();
            let wide = run(&src, iso, &ticker, true, true).unwrap();
            same(&base, &wide, &format!("dense, open {open}, masked {masked}, {spec:?}"));
        }
        let shape = crate::storage::shapes::Shape::Torus {
            center: [0.5, -1.0, 2.0],
            major_radius: 14.0,
            minor_radius: 4.5,
        };
        let grid = crate::storage::convert::tiles_from_shape(&shape, GridSpec::default()).unwrap();
        let src = GridSource::new(&grid);
        let ticker = none.start(src.coords().len() as u64);
        let base = run(&src, 0.0, &ticker, true, false).unwrap();
        let wide = run(&src, 0.0, &ticker, true, true).unwrap();
        same(&base, &wide, "tile grid");
    }

    /// The gather's shortcut for absent neighbours (the border flags of the nearest tile
    /// of the row among the neighbours) reads what random access reads, for every absent
    /// neighbour of every tile of bands with holes in their rows.
    #[test]
    fn absent_neighbours_read_as_random_access_does() {
        use crate::storage::shapes::Shape;
        let spec = GridSpec::default();
        for shape in [
            Shape::Torus { center: [0.5, -1.0, 2.0], major_radius: 14.0, minor_radius: 4.5 },
            Shape::Sphere { center: [-3.0, 2.0, 0.5], radius: 11.0 },
        ] {
            let grid = crate::storage::convert::tiles_from_shape(&shape, spec).unwrap();
            let src = GridSource::new(&grid);
            let coords = grid.tile_coords();
            let mut checked = 0;
            for nb in NeighbourCursor::new(coords, 0, coords.len()) {
                for n in (0..27).filter(|&n| nb.get(n).is_none()) {
                    let o = NEIGHBOURHOOD[n];
                    let t = nb.coord.wrapping_add(o);
                    let v = grid.value(Coord::new(4 * t.x, 4 * t.y, 4 * t.z));
                    assert_eq!(src.absent_inside(&nb, n), v < 0.0, "{shape:?}: {t:?}");
                    checked += 1;
                }
            }
            assert!(checked > 1000, "{checked}");
        }
    }

    /// A dense array's crossed tiles, found separably, are the tiles whose filled block is
    /// not uniform (the scan over every block) at a closed border, and at an open one the
    /// tiles with both sides among the array's voxels of their reach; with ±∞, negated
    /// reads and arrays one voxel thick along an axis.
    #[test]
    fn crossed_tiles_are_the_tiles_with_a_mixed_block() {
        let mut rng = fastrand::Rng::with_seed(5);
        for (k, dims) in [[13, 11, 9], [9, 1, 12], [17, 14, 6]].into_iter().enumerate() {
            let o = Coord::new(-3 + k as i32, 2, -5);
            let mut field = DenseField::from_fn(o, dims, |c| {
                let p = [c.x as f32 + 0.3, c.y as f32 - 4.1, c.z as f32 + 1.7];
                (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 5.0
            })
            .unwrap();
            for _ in 0..6 {
                let i = rng.usize(..field.data().len());
                field.data_mut()[i] = if rng.bool() { f32::INFINITY } else { f32::NEG_INFINITY };
            }
            let (lo, hi) = (field.origin(), field.max_coord());
            let (lo, hi) = ([lo.x, lo.y, lo.z].map(|c| c as i64 - 1), [hi.x, hi.y, hi.z]);
            for open in [false, true] {
                for negate in [false, true] {
                    let iso = if negate { -0.5 } else { 0.5 };
                    let src = DenseSource {
                        field: &field,
                        spec: GridSpec::default(),
                        coords: Vec::new(),
                        tlo: lo.map(|c| c.div_euclid(4)),
                        thi: hi.map(|c| (c as i64).div_euclid(4)),
                        outside: iso + 3.0,
                        inside: iso - 3.0,
                        cells: open.then_some(CellRule { open, mask: None }),
                        sign: if negate { -1.0 } else { 1.0 },
                    };
                    let below = f32_threshold(iso as f64);
                    let mut scan = Vec::new();
                    let mut values = Box::new([0f32; BLOCK]);
                    // With an open border, the tiles with both sides among the array's
                    // voxels of their reach (4 t − 1 ..= 4 t + 4).
                    let (flo, fhi) = (field.origin(), field.max_coord());
                    let (flo, fhi) = (
                        [flo.x, flo.y, flo.z].map(i64::from),
                        [fhi.x, fhi.y, fhi.z].map(i64::from),
                    );
                    let in_array_mixed = |t: [i64; 3]| {
                        let r = |a: usize| (4 * t[a] - 1).max(flo[a])..=(4 * t[a] + 4).min(fhi[a]);
                        let mut sides = 0;
                        for z in r(2) {
                            for y in r(1) {
                                for x in r(0) {
                                    sides |= if src.at([x, y, z]) < below { 1 } else { 2 };
                                }
                            }
                        }
                        sides == 3
                    };
                    for z in src.tlo[2]..=src.thi[2] {
                        for y in src.tlo[1]..=src.thi[1] {
                            for x in src.tlo[0]..=src.thi[0] {
                                let crossed = if open {
                                    in_array_mixed([x, y, z])
                                } else {
                                    src.fill([x, y, z], &mut values);
                                    !uniform(&signs(&values, below))
                                };
                                if crossed {
                                    scan.push(Coord::new(x as i32, y as i32, z as i32));
                                }
                            }
                        }
                    }
                    assert!(scan.len() > 3, "{dims:?}");
                    assert_eq!(src.crossed_tiles(below), scan, "{dims:?} open {open} {negate}");
                }
            }
        }
    }

    /// The bounds the module docs rely on, at h = 1 for every Kuhn tetrahedron, sign
    /// pattern and piece, with edge parameters at every combination of δ and 1 − δ and at
    /// random values in between: every triangle's smallest height is at least δ/6, and
    /// vertices on two edges from one voxel are at least δ apart.
    #[test]
    fn clamped_parameters_keep_vertices_apart_and_triangles_thick() {
        let delta = 1e-3;
        let corner = |c: u8| [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64];
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let norm = |a: [f64; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        let cross = |u: [f64; 3], v: [f64; 3]| {
            [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        };
        let mut rng = fastrand::Rng::with_seed(3);
        let mut worst = f64::INFINITY;
        for (tet, _) in KUHN {
            for mask in 1..15u32 {
                for trial in 0..64 + 200 {
                    // Parameter of tetrahedron edge (i, j), i < j, from its lower-numbered end.
                    let param = |i: usize, j: usize, rng: &mut fastrand::Rng| {
                        let e = [0, 0, 1, 2, 0, 0, 3, 4, 0, 0, 0, 5][4 * i.min(j) + i.max(j) - 1];
                        let s = if trial < 64 {
                            if (trial >> e) & 1 == 0 {
                                delta
                            } else {
                                1.0 - delta
                            }
                        } else {
                            delta + rng.f64() * (1.0 - 2.0 * delta)
                        };
                        if i < j {
                            s
                        } else {
                            1.0 - s
                        }
                    };
                    for piece in pieces(3, mask) {
                        let p: Vec<[f64; 3]> = piece
                            .pairs
                            .iter()
                            .map(|&(i, j)| {
                                let (a, b) = (corner(tet[i as usize]), corner(tet[j as usize]));
                                let s = param(i as usize, j as usize, &mut rng);
                                [0, 1, 2].map(|k| a[k] + s * (b[k] - a[k]))
                            })
                            .collect();
                        let area2 = norm(cross(sub(p[1], p[0]), sub(p[2], p[0])));
                        let longest =
                            (0..3).map(|k| norm(sub(p[(k + 1) % 3], p[k]))).fold(0.0, f64::max);
                        worst = worst.min(area2 / longest / delta);
                    }
                }
            }
        }
        println!("smallest height / δ: {worst:.4}");
        assert!(worst >= 1.0 / 6.0, "{worst}");
        // Two edges from one voxel: directions in {0,1}³ \ 0 and their negatives.
        let dirs: Vec<[f64; 3]> =
            (1..8u8).flat_map(|c| [corner(c), corner(c).map(|x| -x)]).collect();
        let ts = [delta, 0.5, 1.0 - delta];
        let mut closest = f64::INFINITY;
        for (k, &d1) in dirs.iter().enumerate() {
            for &d2 in &dirs[k + 1..] {
                for &t1 in &ts {
                    for &t2 in &ts {
                        closest = closest.min(norm(sub(d1.map(|x| t1 * x), d2.map(|x| t2 * x))));
                    }
                }
            }
        }
        assert!(closest >= delta * (1.0 - 1e-9), "{closest}");
    }
}
