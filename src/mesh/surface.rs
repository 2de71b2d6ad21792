//! Triangle meshes of 3D level sets on the sparse grids and on dense fields: the n = 3,
//! m = 1 case of [`super::isosurface_nd`] (Kuhn triangulation of each cell into six
//! tetrahedra, Sec. 2.1; Table 2 via [`super::tables`]), run tile by tile in parallel.
//!
//! # Which cells, which tile
//! A tile processes the cells whose lower corner lies in the tile or one voxel before it
//! (125 cells). A cell belongs to the tile holding its first corner (corner order
//! x, y, z bits) that lies in a stored tile, so every cell with a stored corner is meshed
//! exactly once, including cells that straddle tiles or touch absent tiles (which read
//! ±γ). Cells with no stored corner are not meshed: their corners read ±γ, and a sign
//! change between absent tiles would need band voxels there, which a valid band has. Each
//! tile gathers the values of its 8³ neighbourhood (the cells' corners plus one voxel for
//! the central-difference normals) from its 26 neighbour tiles, found by the list walk of
//! Algorithm 1.
//!
//! # Welding and determinism
//! A vertex lies on a Kuhn edge from a voxel to voxel + d, d ∈ {0,1}³ \ {0}; its key is
//! (voxel, d). Every tile that computes a vertex computes it from the same values with
//! the same arithmetic, so copies are bitwise equal; the merged vertex list is sorted by
//! key ((z, y, x) of the voxel, then d), so the mesh is the same for any thread count.
//! Positions are placed after the merge, from the key and the edge parameter alone
//! ([`place`]), so they too are the same for tiles, DT-Grid and dense input and for any
//! thread count.
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
//! survive whenever δh exceeds about 2.5 ulp; [`place`] keeps a factor of ten more.
//!
//! # Precision
//! [`place`] takes δ = 32 ulp / h ([`OFFSET_ULPS`]), with the ulp of the output precision
//! at the largest coordinate of the edge's end points (a vertex 100 voxels from the
//! origin keeps 2.4·10⁻⁴ voxels off a voxel in f32; one at 2³¹ voxels in f64, 7.6·10⁻⁶),
//! and picks the precision from the largest coordinate X of the mesh: f32 when
//! ulp_f32(X) ≤ h/4096 ([`MAX_ULP_IN_VOXELS`]; rounding error ≤ 1/8192 voxel, X < 4096 h
//! for h a power of two), else f64 when ulp_f64(X) ≤ h/4096, else
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

use super::tables::pieces;
use super::{MeshError, MeshOptions, TriangleMesh};
use crate::dense::DenseField;
use crate::grid::GridSpec;
use crate::levelset::LevelSet;
use crate::progress::Cancelled;
use crate::tiles::{NeighbourCursor, Neighbours, Tile, TileGrid, TILE_MAX, TILE_MIN};
use crate::Coord;
use rayon::prelude::*;

/// Side of the gathered block: a tile (4) plus 2 voxels before and after.
const B: usize = 8;
const BLOCK: usize = B * B * B;

/// The six Kuhn tetrahedra of a cell: corner bit masks v₀ ⊂ v₁ ⊂ v₂ ⊂ v₃ (bit 0 = +x,
/// 1 = +y, 2 = +z) and the sign of the permutation, i.e. the orientation of that vertex
/// order (Sec. 2.1).
const KUHN: [([u8; 4], i8); 6] = {
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

/// Offset in the block along one axis → (neighbour tile step −1..=1, local index).
const fn axis_split(o: usize) -> (i64, usize) {
    let c = o as i64 - 2;
    (c.div_euclid(4), c.rem_euclid(4) as usize)
}

#[inline(always)]
fn bidx(x: usize, y: usize, z: usize) -> usize {
    x + B * (y + B * z)
}

/// Neighbour index of a block offset triple in the 3×3×3 tile neighbourhood.
#[inline(always)]
fn nbr_of(x: usize, y: usize, z: usize) -> usize {
    let d = |o: usize| (axis_split(o).0 + 1) as usize;
    d(x) + 3 * d(y) + 9 * d(z)
}

const BIAS: i64 = 1 << 33;

/// Sort key of a Kuhn edge: voxel (z, y, x) then direction bits.
#[inline]
fn edge_key(v: [i64; 3], dir: u8) -> u128 {
    let f = |c: i64| (c + BIAS) as u128;
    (f(v[2]) << 73) | (f(v[1]) << 38) | (f(v[0]) << 3) | dir as u128
}

/// The Kuhn edge of a key: its lower voxel and its direction bits.
#[inline]
fn edge_of_key(key: u128) -> ([i64; 3], u8) {
    let f = |shift: u32| ((key >> shift) & ((1u128 << 35) - 1)) as i64 - BIAS;
    ([f(3), f(38), f(73)], (key & 7) as u8)
}

/// A vertex as a tile computes it: its edge key, the unclamped parameter t of eq. (2)
/// measured from the edge's lower voxel, and its normal. Positions are placed after the
/// merge ([`place`]), once the mesh's precision is known.
type EdgeVertex = (u128, f64, [f32; 3]);

/// What one tile produced: its vertices and its triangles in local vertex indices.
#[derive(Default)]
struct Part {
    verts: Vec<EdgeVertex>,
    tris: Vec<[u32; 3]>,
}

/// The neighbourhood of one tile: 8³ values and which of the 27 tiles are "stored"
/// (own cells).
struct Block {
    tile: [i64; 3],
    values: [f32; BLOCK],
    stored: [bool; 27],
}

/// Scratch reused across the tiles one worker handles.
struct Scratch {
    /// Local vertex index of (edge lower corner offset − 1, direction), or `u32::MAX`.
    slot: Vec<u32>,
    used: Vec<usize>,
}

impl Scratch {
    fn new() -> Self {
        Scratch { slot: vec![u32::MAX; 6 * 6 * 6 * 8], used: Vec::new() }
    }
}

/// Meshes the cells a block owns into `part`. `iso` is subtracted from every value.
fn mesh_block(b: &Block, iso: f64, scratch: &mut Scratch, part: &mut Part) {
    // Early out: no sign change anywhere in the block.
    let first = (b.values[0] as f64) < iso;
    if b.values.iter().all(|&v| ((v as f64) < iso) == first) {
        return;
    }
    let base = [4 * b.tile[0] - 2, 4 * b.tile[1] - 2, 4 * b.tile[2] - 2];
    let corner_off = |c: u8| [(c & 1) as usize, ((c >> 1) & 1) as usize, ((c >> 2) & 1) as usize];
    for oz in 1..6 {
        for oy in 1..6 {
            for ox in 1..6 {
                let mut v = [0f64; 8];
                let mut neg = 0u8;
                for c in 0..8u8 {
                    let d = corner_off(c);
                    v[c as usize] = b.values[bidx(ox + d[0], oy + d[1], oz + d[2])] as f64 - iso;
                    neg |= ((v[c as usize] < 0.0) as u8) << c;
                }
                if neg == 0 || neg == 0xff {
                    continue;
                }
                if ox == 1 || oy == 1 || oz == 1 {
                    let owner = (0..8u8)
                        .map(|c| {
                            let d = corner_off(c);
                            nbr_of(ox + d[0], oy + d[1], oz + d[2])
                        })
                        .find(|&n| b.stored[n]);
                    if owner != Some(13) {
                        continue;
                    }
                }
                for (tet, sign) in KUHN {
                    let mask = (0..4).fold(0u32, |m, i| m | (((neg >> tet[i]) & 1) as u32) << i);
                    for piece in pieces(3, mask) {
                        let mut tri = [0u32; 3];
                        for (w, &(i, j)) in tri.iter_mut().zip(&piece.pairs) {
                            let (cn, cp) = (tet[i as usize], tet[j as usize]);
                            let (lo, hi) = if i < j { (cn, cp) } else { (cp, cn) };
                            let dl = corner_off(lo);
                            let (lx, ly, lz) = (ox + dl[0], oy + dl[1], oz + dl[2]);
                            let dir = hi ^ lo;
                            let s = (((lz - 1) * 6 + (ly - 1)) * 6 + (lx - 1)) * 8 + dir as usize;
                            if scratch.slot[s] == u32::MAX {
                                scratch.slot[s] = part.verts.len() as u32;
                                scratch.used.push(s);
                                let dn = corner_off(cn);
                                let dp = corner_off(cp);
                                let pn = [ox + dn[0], oy + dn[1], oz + dn[2]];
                                let pp = [ox + dp[0], oy + dp[1], oz + dp[2]];
                                part.verts.push(edge_vertex(b, base, pn, pp, iso, dir));
                            }
                            *w = scratch.slot[s];
                        }
                        if (sign < 0) != piece.flip {
                            tri.swap(0, 1);
                        }
                        part.tris.push(tri);
                    }
                }
            }
        }
    }
    for &s in &scratch.used {
        scratch.slot[s] = u32::MAX;
    }
    scratch.used.clear();
}

/// The vertex of eq. (2) on the edge from block offset `pn` (φ < iso) to `pp` (φ ≥ iso):
/// its key, its parameter from the edge's lower voxel (unclamped; [`place`] clamps it)
/// and its normal, the central-difference gradient at both ends interpolated, unit.
#[inline]
fn edge_vertex(
    b: &Block,
    base: [i64; 3],
    pn: [usize; 3],
    pp: [usize; 3],
    iso: f64,
    dir: u8,
) -> EdgeVertex {
    let val = |p: [usize; 3]| b.values[bidx(p[0], p[1], p[2])] as f64;
    let (vn, vp) = (val(pn) - iso, val(pp) - iso);
    // vn < 0 ≤ vp, so both quotients lie in [0, 1]; t_lo is computed from the lower end
    // directly rather than as 1 − t.
    let t = vn / (vn - vp);
    let pn_lower = pn.iter().zip(&pp).all(|(a, b)| a <= b);
    let t_lo = if pn_lower { t } else { vp / (vp - vn) };
    let grad = |p: [usize; 3]| -> [f64; 3] {
        let mut g = [0.0; 3];
        for (a, ga) in g.iter_mut().enumerate() {
            let (mut lo, mut hi) = (p, p);
            lo[a] -= 1;
            hi[a] += 1;
            *ga = val(hi) - val(lo);
        }
        g
    };
    let (gn, gp) = (grad(pn), grad(pp));
    let mut nrm = [0f64; 3];
    for a in 0..3 {
        nrm[a] = gn[a] + t * (gp[a] - gn[a]);
    }
    let len = (nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]).sqrt();
    let nrm = if len > 0.0 && len.is_finite() { nrm.map(|c| (c / len) as f32) } else { [0.0; 3] };
    let lower = if pn_lower { pn } else { pp };
    let lower = [0, 1, 2].map(|a| base[a] + lower[a] as i64);
    (edge_key(lower, dir), t_lo, nrm)
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

/// A vertex keeps at least this many ulps (of the chosen precision, at the magnitude of
/// its edge's end points) times the edge length away from both ends of its edge.
const OFFSET_ULPS: f64 = 32.0;

/// Places the merged vertices: picks the precision from the largest coordinate of the
/// edges' end points, clamps each parameter to `[δ, 1 − δ]` with
/// `δ = OFFSET_ULPS · ulp / h` and interpolates between the end points' world positions
/// from the nearer end; with f32 precision the positions are rounded to f32 values.
fn place(verts: &[EdgeVertex], spec: &GridSpec) -> Result<Vec<[f64; 3]>, MeshError> {
    let h = spec.voxel_size as f64;
    let world = |v: [i64; 3]| [0, 1, 2].map(|a| spec.origin[a] + h * v[a] as f64);
    let magnitude =
        |a: [f64; 3], b: [f64; 3]| a.iter().chain(&b).fold(0f64, |m, &c| m.max(c.abs()));
    // The largest coordinate of any end point: |origin + h·v| is convex in v, so it is
    // reached at the voxel bounds of the end points.
    let Some((vmin, vmax)) = verts
        .par_iter()
        .map(|v| {
            let (lo, dir) = edge_of_key(v.0);
            (lo, [0, 1, 2].map(|a| lo[a] + ((dir >> a) & 1) as i64))
        })
        .reduce_with(|a, b| {
            ([0, 1, 2].map(|i| a.0[i].min(b.0[i])), [0, 1, 2].map(|i| a.1[i].max(b.1[i])))
        })
    else {
        return Ok(Vec::new());
    };
    let extent = magnitude(world(vmin), world(vmax));
    let precision = [Precision::F32, Precision::F64]
        .into_iter()
        .find(|p| p.ulp(extent) <= MAX_ULP_IN_VOXELS * h)
        .ok_or(MeshError::Precision { extent, voxel_size: h })?;
    Ok(verts
        .par_iter()
        .map(|&(key, t, _)| {
            let (lo, dir) = edge_of_key(key);
            let a = world(lo);
            let b = world([0, 1, 2].map(|i| lo[i] + ((dir >> i) & 1) as i64));
            let delta = OFFSET_ULPS * precision.ulp(magnitude(a, b)) / h;
            let t = t.clamp(delta, 1.0 - delta);
            let p = if t <= 0.5 {
                [0, 1, 2].map(|i| a[i] + t * (b[i] - a[i]))
            } else {
                [0, 1, 2].map(|i| b[i] + (1.0 - t) * (a[i] - b[i]))
            };
            match precision {
                Precision::F32 => p.map(|c| c as f32 as f64),
                Precision::F64 => p,
            }
        })
        .collect())
}

/// Merges the tiles' parts in tile order into one welded mesh: all vertex copies sorted
/// by key (copies of one key are bitwise equal), numbered in key order, and every part's
/// local indices mapped through that numbering.
fn merge(parts: Vec<Part>, spec: &GridSpec) -> Result<TriangleMesh, MeshError> {
    let mut offsets = Vec::with_capacity(parts.len() + 1);
    offsets.push(0usize);
    for p in &parts {
        offsets.push(offsets.last().unwrap() + p.verts.len());
    }
    let copies = *offsets.last().unwrap();
    if copies > u32::MAX as usize {
        return Err(MeshError::TooLarge(format!("{copies} vertex copies")));
    }
    // (key, index of the copy in part order)
    let mut order: Vec<(u128, u32)> = parts
        .iter()
        .zip(&offsets)
        .flat_map(|(p, &o)| p.verts.iter().enumerate().map(move |(i, v)| (v.0, (o + i) as u32)))
        .collect();
    order.par_sort_unstable_by_key(|e| e.0);
    let copy = |i: u32| {
        let p = offsets.partition_point(|&o| o <= i as usize) - 1;
        &parts[p].verts[i as usize - offsets[p]]
    };
    let mut remap = vec![0u32; copies];
    let mut verts: Vec<EdgeVertex> = Vec::with_capacity(copies);
    for &(key, i) in &order {
        let v = copy(i);
        match verts.last() {
            Some(last) if last.0 == key => {
                let bits = |v: &EdgeVertex| (v.1.to_bits(), v.2.map(f32::to_bits));
                debug_assert_eq!(bits(v), bits(last), "copies of a vertex differ");
            }
            _ => verts.push(*v),
        }
        remap[i as usize] = (verts.len() - 1) as u32;
    }
    let positions = place(&verts, spec)?;
    let normals = verts.iter().map(|v| v.2).collect();
    let triangles: Vec<[u32; 3]> = parts
        .par_iter()
        .zip(&offsets[..parts.len()])
        .flat_map_iter(|(p, &o)| {
            let remap = &remap;
            p.tris.iter().map(move |t| t.map(|l| remap[o + l as usize]))
        })
        .collect();
    let mut mesh = TriangleMesh { positions, normals, triangles };
    mesh.fill_missing_normals();
    Ok(mesh)
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
/// through [`crate::build::tiles_from`] (same values, so the same mesh). Progress counts
/// tiles.
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
    let converted;
    let grid = match grid.as_tiles() {
        Some(t) => t,
        None => {
            converted = crate::build::tiles_from(grid);
            &converted
        }
    };
    let spec = *grid.spec();
    let coords = grid.tile_coords();
    let ticker = opts.progress.start(coords.len() as u64);
    const CHUNK: usize = 64;
    let parts: Vec<Part> = coords
        .par_chunks(CHUNK)
        .enumerate()
        .map_init(Scratch::new, |scratch, (ci, chunk)| {
            ticker.check()?;
            let mut part = Part::default();
            let start = ci * CHUNK;
            let cursor = NeighbourCursor::new(coords, start, start + chunk.len());
            for nbrs in cursor {
                let block = gather_tiles(grid, &nbrs);
                mesh_block(&block, iso, scratch, &mut part);
            }
            ticker.advance(chunk.len() as u64)?;
            Ok(part)
        })
        .collect::<Result<_, Cancelled>>()?;
    merge(parts, &spec)
}

/// The block of the tile at `nbrs.pos`, its neighbours found by the list walk of
/// Algorithm 1 ([`NeighbourCursor`]) rather than by a search each.
fn gather_tiles(grid: &TileGrid, nbrs: &Neighbours) -> Block {
    let t = nbrs.coord;
    let tile = [t.x as i64, t.y as i64, t.z as i64];
    let mut stored = [false; 27];
    let mut src: [Option<&Tile>; 27] = [None; 27];
    // Beyond the representable tiles the grid is outside.
    let mut bg = [grid.gamma(); 27];
    for n in 0..27 {
        if let Some(p) = nbrs.get(n) {
            stored[n] = true;
            src[n] = Some(grid.tile(p));
            continue;
        }
        let d = [(n % 3) as i64 - 1, ((n / 3) % 3) as i64 - 1, (n / 9) as i64 - 1];
        let nt = [tile[0] + d[0], tile[1] + d[1], tile[2] + d[2]];
        if nt.iter().all(|&c| (TILE_MIN as i64..=TILE_MAX as i64).contains(&c)) {
            // An absent tile reads ±γ with the sign the grid records for it.
            let c = Coord::new(4 * nt[0] as i32, 4 * nt[1] as i32, 4 * nt[2] as i32);
            bg[n] = grid.value(c);
        }
    }
    let split: [(i64, usize); B] = std::array::from_fn(axis_split);
    let mut values = [0f32; BLOCK];
    for z in 0..B {
        for y in 0..B {
            for x in 0..B {
                let n = ((split[x].0 + 1) + 3 * (split[y].0 + 1) + 9 * (split[z].0 + 1)) as usize;
                values[bidx(x, y, z)] = match src[n] {
                    Some(tile) => tile.0[split[x].1 + 4 * split[y].1 + 16 * split[z].1],
                    None => bg[n],
                };
            }
        }
    }
    Block { tile, values, stored }
}

/// The isosurface φ = `iso` of a dense field, voxel size and origin from `spec` (the
/// field's own origin places it on the voxel grid). Values beyond the array read as
/// `iso + γ` (outside; for iso = 0 the `+γ` of [`crate::build::tiles_from_dense`]), so a
/// surface that reaches the array's boundary is closed along it. ±∞ is a far-away
/// distance (as in [`crate::npy::read_npy`]) and reads as `iso ± γ`. On the same values
/// the mesh is the one [`isosurface`] makes (same cells, same arithmetic). Errors
/// on NaN or a non-finite iso.
pub fn isosurface_dense(
    field: &DenseField,
    spec: &GridSpec,
    iso: f64,
) -> Result<TriangleMesh, MeshError> {
    check_iso(iso)?;
    if let Some(i) = field.data().iter().position(|v| v.is_nan()) {
        return Err(MeshError::NaN { coord: field.coord_of(i).expect("index in range") });
    }
    let outside = (iso + spec.gamma() as f64) as f32;
    let inside = (iso - spec.gamma() as f64) as f32;
    let o = field.origin();
    let hi = field.max_coord();
    let lo = [o.x as i64 - 1, o.y as i64 - 1, o.z as i64 - 1];
    let hi = [hi.x as i64, hi.y as i64, hi.z as i64];
    let tlo = lo.map(|c| c.div_euclid(4));
    let thi = hi.map(|c| c.div_euclid(4));
    let in_range = |t: [i64; 3]| (0..3).all(|a| (tlo[a]..=thi[a]).contains(&t[a]));
    let tiles: Vec<[i64; 3]> = (tlo[2]..=thi[2])
        .flat_map(|z| {
            (tlo[1]..=thi[1]).flat_map(move |y| (tlo[0]..=thi[0]).map(move |x| [x, y, z]))
        })
        .collect();
    let value = |c: [i64; 3]| -> f32 {
        let ok = |v: i64| (i32::MIN as i64..=i32::MAX as i64).contains(&v);
        if c.iter().all(|&v| ok(v)) {
            match field.get(Coord::new(c[0] as i32, c[1] as i32, c[2] as i32)) {
                Some(v) if v == f32::INFINITY => outside,
                Some(v) if v == f32::NEG_INFINITY => inside,
                Some(v) => v,
                None => outside,
            }
        } else {
            outside
        }
    };
    let parts: Vec<Part> = tiles
        .par_iter()
        .map_init(Scratch::new, |scratch, &tile| {
            let mut stored = [false; 27];
            for (n, s) in stored.iter_mut().enumerate() {
                let d = [(n % 3) as i64 - 1, ((n / 3) % 3) as i64 - 1, (n / 9) as i64 - 1];
                *s = in_range([tile[0] + d[0], tile[1] + d[1], tile[2] + d[2]]);
            }
            let mut values = [0f32; BLOCK];
            for z in 0..B {
                for y in 0..B {
                    for x in 0..B {
                        let c = [
                            4 * tile[0] - 2 + x as i64,
                            4 * tile[1] - 2 + y as i64,
                            4 * tile[2] - 2 + z as i64,
                        ];
                        values[bidx(x, y, z)] = value(c);
                    }
                }
            }
            let mut part = Part::default();
            mesh_block(&Block { tile, values, stored }, iso, scratch, &mut part);
            part
        })
        .collect();
    merge(parts, spec)
}

#[cfg(test)]
mod tests {
    use super::*;

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
