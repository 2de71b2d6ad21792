//! Meshes in: triangle meshes to narrow-band level sets (scan conversion, Houston et al.
//! 2006, Sec. 6.2), and the mesh file readers ([`crate::io::mesh::load_mesh`]).
//!
//! [`voxelize`] turns a [`TriangleMesh`] into a [`TileGrid`] whose band holds the signed
//! distance to the mesh:
//!
//! * **Magnitude: exact distances.** Every voxel within γ of the mesh gets its distance to
//!   the nearest triangle, computed in f64 by the closest point on that triangle (Ericson)
//!   and stored as f32. This is Sec. 6.2.1's result ("accurate to within machine
//!   precision") reached by binning instead of characteristic polyhedra: each triangle is
//!   listed with the 4³ tiles whose centre lies within γ + the tile's half-diagonal of it
//!   (a tile–triangle distance bound, scanned over the slab around the triangle's plane and
//!   tested sixteen candidate tiles at a time), the (tile, triangle) pairs are sorted by
//!   tile (a counting sort over the tiles' box), and the tiles are computed in parallel.
//!   A tile takes two passes: every listed triangle against all 64 voxels in f32,
//!   relative to the tile, without branches (vectors of the widest registers the CPU has,
//!   chosen at run time), which finds each voxel's nearest triangle; then that triangle's
//!   distance in f64. Triangles that tie within the f32 rounding at a shared edge or
//!   vertex give the same distance; different nearest points closer than that rounding
//!   (the medial axis) may be taken in either order, an error of the f32 rounding
//!   relative to the triangle's size (below 10⁻⁵ voxel for triangles ten voxels across).
//!   Memory is O(band + triangles + pairs), as the paper's subvolume scheme is; nothing is
//!   dense.
//! * **Sign: ray votes** ([`SignMethod::Rays`], Sec. 6.2.2 after Houston et al. 2003):
//!   axis-aligned rays along the voxel-centre lines of x, y and z accumulate the oriented
//!   crossings of the triangles (the winding count along the ray), each line giving a vote
//!   per direction; a voxel is inside when at least four of its six votes say so. Crossings
//!   through shared edges and vertices count exactly once (exact, watertight
//!   rasterisation), so a closed, consistently oriented mesh gets its exact winding sign
//!   everywhere; holes cost a vote only on the lines through them, and self-intersecting
//!   closed parts add up to their union. Only the lines the band's tiles and their
//!   neighbours need are queried; the crossings cost O(triangles + crossings).
//! * **Closing** (Sec. 6.2.2, "regions of opposite sign being immediately adjacent, with no
//!   defined narrowband in between"): a hole wider than the band leaves the vote's sign
//!   change across it without band voxels. Every absent tile next to the band is checked
//!   (its 64 signs must agree, and agree with the voxels it touches across its faces); one
//!   that fails becomes a band tile, and the check floods on from it. Then each voxel
//!   beyond the band with a face neighbour of the other sign gets ±h/2: the zero level
//!   passes half-way between them. Every sign change that meets the band is closed this
//!   way (an opening's does, at its rim), so the band separates inside from outside; a
//!   change floating free of the band (where lines through three different holes cross)
//!   is not searched for. Values are distances everywhere except on the closing patches,
//!   where [`crate::tools::fmm::reinitialize`] can smooth them.
//!
//! For a closed, clean mesh the band is exactly the signed distance (tested against brute
//! force); the results are bitwise identical for any number of threads.
//!
//! # Grid and defaults
//! Voxel `(i, j, k)` is centred at `origin + h (i, j, k)`. Without a voxel size,
//! [`default_voxel_size`] takes the median triangle edge length (so that the voxels resolve
//! the mesh's own detail), clamped so that the mesh's longest bounding-box side spans
//! between 64 and 1024 voxels (a coarse mesh still gets a useful grid; a very fine one
//! does not ask for billions of voxels). The half-width defaults to the crate's (3).
//!
//! ```
//! use sparse_levelset::tools::mesh::TriangleMesh;
//! use sparse_levelset::tools::voxelize::{voxelize, VoxelizeOptions};
//! use sparse_levelset::{Coord, LevelSet};
//!
//! // A tetrahedron, counter-clockwise seen from outside.
//! let mesh = TriangleMesh {
//!     positions: vec![[0.0, 0.0, 0.0], [8.0, 0.0, 0.0], [0.0, 8.0, 0.0], [0.0, 0.0, 8.0]],
//!     normals: vec![],
//!     triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
//! };
//! let opts = VoxelizeOptions { voxel_size: Some(0.5), ..Default::default() };
//! let grid = voxelize(&mesh, &opts).unwrap();
//! assert_eq!(grid.value(Coord::new(2, 2, 2)), -1.0); // (1, 1, 1) is 1 inside each face
//! assert_eq!(grid.value(Coord::new(2, 2, -2)), 1.0); // 1 below the base
//! assert_eq!(grid.value(Coord::new(100, 0, 0)), 1.5); // +γ far away
//! ```

mod distance;
mod sign;

use crate::coord::Coord;
use crate::grid::{GridError, GridSpec};
use crate::progress::{Cancelled, Progress};
use crate::storage::tiles::{tile_in_range, Tile, TileGrid, TILE_LEN, TILE_MAX, TILE_MIN};
use crate::tools::mesh::TriangleMesh;
use distance::{LocalTri, Tri};
use rayon::prelude::*;
use sign::{Rays, Votes};

/// How [`voxelize`] decides inside from outside.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SignMethod {
    /// Ray votes along x, y and z (two per axis, one per direction; inside when at least
    /// four of six agree). The default: exact for closed, consistently oriented meshes,
    /// and robust to holes (a hole only sways the lines through it) and to overlapping or
    /// self-intersecting closed parts (windings add up to their union). About three times
    /// the sign work of [`SignMethod::SingleRay`], which is small against the distances.
    #[default]
    Rays,
    /// The winding count along +x alone (from −∞ to the voxel): exact for closed,
    /// consistently oriented meshes, and a third of the sign work, but one hole flips the
    /// sign along every line through it.
    SingleRay,
}

/// Options of [`voxelize`].
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelizeOptions {
    /// Voxel edge length in world units; `None` chooses [`default_voxel_size`].
    pub voxel_size: Option<f32>,
    /// Band half-width in voxels (> 1).
    pub half_width: f32,
    /// World position of the centre of voxel (0, 0, 0).
    pub origin: [f64; 3],
    /// Inside/outside decision.
    pub sign: SignMethod,
    /// Progress (tiles done) and cancellation.
    pub progress: Progress,
}

impl Default for VoxelizeOptions {
    fn default() -> Self {
        VoxelizeOptions {
            voxel_size: None,
            half_width: GridSpec::default().half_width,
            origin: [0.0; 3],
            sign: SignMethod::default(),
            progress: Progress::default(),
        }
    }
}

/// Why [`voxelize`] refused a mesh or stopped; checked before any work except
/// [`VoxelizeError::Cancelled`].
#[derive(Debug, thiserror::Error)]
pub enum VoxelizeError {
    /// No triangles.
    #[error("the mesh has no triangles")]
    Empty,
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a coordinate that is not finite: {value}")]
    NonFinite { vertex: usize, value: f64 },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {index}, but the mesh has {vertices} vertices")]
    IndexOutOfRange { triangle: usize, index: u32, vertices: usize },
    /// Every vertex of the triangles is one point: no voxel size follows from the mesh.
    #[error("the mesh has zero extent (all its vertices coincide): give a voxel size")]
    ZeroExtent,
    /// An invalid voxel size or half-width, a band leaving the `i32` voxel range, or a band
    /// larger than the memory the machine can give.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// Cancelled through [`VoxelizeOptions::progress`].
    #[error("voxelizing was cancelled")]
    Cancelled(#[from] Cancelled),
}

impl crate::error::Error for VoxelizeError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            VoxelizeError::Empty
            | VoxelizeError::NonFinite { .. }
            | VoxelizeError::IndexOutOfRange { .. }
            | VoxelizeError::ZeroExtent => InvalidData,
            VoxelizeError::Grid(e) => e.kind(),
            VoxelizeError::Cancelled(_) => Cancelled,
        }
    }
}

/// Half-diagonal of a tile's voxel-centre box (3 voxels a side), in voxels.
const TILE_RADIUS: f64 = 1.5 * 1.732_050_807_568_877_2;

/// Checks a mesh (non-empty, indices in range, coordinates finite) and returns the box of
/// the vertices its triangles use.
fn check_mesh(mesh: &TriangleMesh) -> Result<([f64; 3], [f64; 3]), VoxelizeError> {
    if mesh.triangles.is_empty() {
        return Err(VoxelizeError::Empty);
    }
    let n = mesh.positions.len();
    for (vertex, p) in mesh.positions.iter().enumerate() {
        if let Some(&value) = p.iter().find(|c| !c.is_finite()) {
            return Err(VoxelizeError::NonFinite { vertex, value });
        }
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for (triangle, t) in mesh.triangles.iter().enumerate() {
        for &index in t {
            let Some(p) = mesh.positions.get(index as usize) else {
                return Err(VoxelizeError::IndexOutOfRange { triangle, index, vertices: n });
            };
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
    }
    Ok((lo, hi))
}

/// The voxel size [`voxelize`] uses when none is given: the median length of the
/// triangles' edges, clamped so that the longest side of the mesh's bounding box spans
/// between 64 and 1024 voxels. The median follows the mesh's own resolution (a voxel per
/// typical edge resolves what the mesh resolves) and, unlike the mean, ignores a few
/// long or degenerate edges; the clamp keeps a coarse mesh from a uselessly coarse grid
/// and a fine one from billions of voxels. Errors as [`voxelize`]'s mesh checks, and
/// [`VoxelizeError::ZeroExtent`].
pub fn default_voxel_size(mesh: &TriangleMesh) -> Result<f32, VoxelizeError> {
    let (lo, hi) = check_mesh(mesh)?;
    default_size(mesh, lo, hi)
}

fn default_size(mesh: &TriangleMesh, lo: [f64; 3], hi: [f64; 3]) -> Result<f32, VoxelizeError> {
    let longest = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    if longest <= 0.0 {
        return Err(VoxelizeError::ZeroExtent);
    }
    let p = &mesh.positions;
    let len = |i: u32, j: u32| {
        let (a, b) = (p[i as usize], p[j as usize]);
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let mut edges: Vec<f64> = mesh
        .triangles
        .iter()
        .flat_map(|t| [len(t[0], t[1]), len(t[1], t[2]), len(t[2], t[0])])
        .collect();
    let mid = edges.len() / 2;
    let median = *edges.select_nth_unstable_by(mid, f64::total_cmp).1;
    Ok(median.clamp(longest / 1024.0, longest / 64.0) as f32)
}

/// One computed tile: values, and masks (bit = local index) of the voxels inside and of
/// those beyond the band (distance ≥ γ).
#[derive(Clone)]
struct TileOut {
    coord: Coord,
    values: [f32; 64],
    inside: u64,
    far: u64,
}

/// The signed distance to a triangle mesh on a narrow band (see the [module docs](self)):
/// exact distances within γ = half-width × voxel size, signs by [`VoxelizeOptions::sign`],
/// as a [`TileGrid`] (which reads −γ inside and +γ outside beyond the band). Bitwise the
/// same for any number of threads.
///
/// # Errors
/// Checked before any work: [`VoxelizeError::Empty`], [`VoxelizeError::NonFinite`],
/// [`VoxelizeError::IndexOutOfRange`], [`VoxelizeError::ZeroExtent`] (no voxel size given
/// and none follows from the mesh), and [`VoxelizeError::Grid`] for an invalid voxel size or
/// half-width, a band that leaves the `i32` voxel range, or an estimate of the memory (band
/// tiles, the (tile, triangle) pairs, the ray crossings) the machine cannot give
/// ([`crate::memory::check`]). [`VoxelizeError::Cancelled`] when the progress callback
/// asks to stop.
pub fn voxelize(mesh: &TriangleMesh, opts: &VoxelizeOptions) -> Result<TileGrid, VoxelizeError> {
    let (lo, hi) = check_mesh(mesh)?;
    let h = match opts.voxel_size {
        Some(h) => h,
        None => default_size(mesh, lo, hi)?,
    };
    let spec = GridSpec::new(h, opts.origin, opts.half_width)?;
    crate::storage::sample::band_voxel_box(lo, hi, &spec)?;
    let hf = h as f64;
    let o = spec.origin;
    let votes = match opts.sign {
        SignMethod::Rays => Votes::Majority,
        SignMethod::SingleRay => Votes::Single,
    };
    check_memory(mesh, hf, spec.half_width as f64, votes)?;

    let to_voxels = |i: u32| {
        let p = mesh.positions[i as usize];
        [(p[0] - o[0]) / hf, (p[1] - o[1]) / hf, (p[2] - o[2]) / hf]
    };
    // The triangles (and their f32 shapes below) fill fresh memory: huge pages first.
    let mut tris: Vec<Tri> = Vec::with_capacity(mesh.triangles.len());
    crate::memory::advise_huge_pages(&mut tris);
    tris.par_extend(
        mesh.triangles
            .par_iter()
            .map(|t| Tri::new(to_voxels(t[0]), to_voxels(t[1]), to_voxels(t[2]))),
    );
    let gamma_v = spec.half_width as f64;
    let rays = Rays::new(&tris, votes);
    let bins = bin_triangles(&tris, gamma_v);
    let mut shapes: Vec<LocalTri> = Vec::with_capacity(tris.len());
    crate::memory::advise_huge_pages(&mut shapes);
    shapes.par_extend(tris.par_iter().map(Tri::shape));

    let ticker = opts.progress.start(bins.tiles.len() as u64);
    let g = spec.gamma();
    let chunks: Vec<Result<Vec<TileOut>, Cancelled>> = bins
        .tiles
        .par_chunks(64)
        .map(|chunk| {
            let (tris, shapes) = (&tris[..], &shapes[..]);
            let tiles = TileChunk { tris, shapes, bins: &bins.tris, runs: chunk, gamma_v, hf, g };
            let mut out = levelset_kernels::dispatch_one(tiles);
            // Signs of the tiles with band voxels (a tile without stays absent; its signs
            // come later, if a band tile neighbours it).
            for t in &mut out {
                t.inside = rays.tile_inside(t.coord);
                for (l, v) in t.values.iter_mut().enumerate() {
                    if t.inside >> l & 1 == 1 {
                        *v = -*v;
                    }
                }
            }
            ticker.advance(chunk.len() as u64)?;
            Ok(out)
        })
        .collect();
    drop(bins);
    let mut present =
        Vec::with_capacity(chunks.iter().map(|c| c.as_ref().map_or(0, Vec::len)).sum());
    for c in chunks {
        present.extend(c?);
    }
    let absent = close(&rays, &mut present, g, (hf / 2.0) as f32);
    let grid = TileGrid::from_sorted_tiles(
        spec,
        present.into_iter().map(|t| (t.coord, Tile(t.values))),
        |t| match absent.binary_search_by(|a| a.0.cmp(&t)) {
            Ok(i) => absent[i].1 != 0,
            Err(_) => rays.tile_inside(t) & 1 == 1,
        },
    )?;
    Ok(grid)
}

/// Refuses a mesh whose band, bins and crossings would not fit in memory (estimates from
/// the triangles' areas and perimeters, in voxel units `h`).
fn check_memory(
    mesh: &TriangleMesh,
    h: f64,
    half_width: f64,
    votes: Votes,
) -> Result<(), GridError> {
    let p = &mesh.positions;
    let r = half_width + TILE_RADIUS;
    let (area, perimeter, pairs) = mesh
        .triangles
        .par_iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| p[i as usize].map(|x| x / h));
            let tri = Tri::new(a, b, c);
            let (ar, pe) = (tri.double_area() / 2.0, tri.perimeter());
            // Tiles around the triangle: its r-neighbourhood's volume (Steiner) over a tile's.
            let vol = 2.0 * r * ar
                + std::f64::consts::PI / 2.0 * r * r * pe
                + 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
            (ar, pe, 1.5 * vol / 64.0 + 1.0)
        })
        .reduce(|| (0.0, 0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1, x.2 + y.2));
    let band = area * 2.0 * half_width;
    let axes = if votes == Votes::Majority { 3.0 } else { 1.0 };
    let bytes = band * 4.0 * 2.5 // tiles, about 40 % of their voxels in the band
        + pairs * 28.0 // (tile, triangle) pairs, then their triangles by tile and the counts
        + axes * (area + perimeter) * 2.0 * 24.0 // crossings, twice while sorted
        + mesh.triangles.len() as f64 * (std::mem::size_of::<Tri>() as f64 + 24.0);
    crate::memory::check(bytes, "voxelizing the mesh (band tiles, triangle bins, ray crossings)")
}

/// The triangles binned to each tile: the tiles in [`Coord`] order, each with the run of
/// its triangles (in triangle order) in `tris`.
struct Bins {
    tris: Vec<u32>,
    /// A tile and the start and end of its run.
    tiles: Vec<(Coord, usize, usize)>,
}

/// Every (tile, triangle) pair whose tile centre lies within γ + [`TILE_RADIUS`] of the
/// triangle (so that any voxel of the tile within γ is found), by tile in [`Coord`]
/// order, then triangle.
fn bin_triangles(tris: &[Tri], gamma: f64) -> Bins {
    let chunks: Vec<Vec<(Coord, u32)>> = tris
        .par_chunks(1024)
        .enumerate()
        .map(|(ci, chunk)| {
            levelset_kernels::dispatch_one(BinChunk { tris: chunk, first: ci * 1024, gamma })
        })
        .collect();
    sort_pairs(chunks)
}

/// The (tile, triangle) pairs of a chunk of triangles (the first numbered `first`), run
/// at the CPU's instruction-set level ([`levelset_kernels::dispatch_one`]): each
/// triangle's candidate tiles (its bounding box grown by the reach, along the axis of
/// its dominant normal component only the tiles whose centre is within the reach of its
/// plane) are tested in f32, relative to a lattice point next to the triangle, sixteen at
/// a time, with a slack far above the f32 rounding, which grows with the triangle's size
/// (a pair too many costs a little time, never a value). The test: with v = the tile's
/// centre minus the triangle's nearest point, every voxel of the tile (a box of half-side
/// 1.5 around the centre) is at least |v| − 1.5 (|vₓ| + |v_y| + |v_z|)/|v| from the
/// triangle, since the triangle lies beyond the plane through its nearest point normal
/// to v (it is convex) and the box reaches that far towards it along v.
struct BinChunk<'a> {
    tris: &'a [Tri],
    first: usize,
    gamma: f64,
}

/// Candidate tiles tested together in [`BinChunk`].
const BIN_BATCH: usize = 16;

impl levelset_kernels::LaneFn for BinChunk<'_> {
    type Output = Vec<(Coord, u32)>;
    #[inline(always)]
    fn call<L: levelset_kernels::Lane>(self) -> Vec<(Coord, u32)> {
        let BinChunk { tris, first, gamma } = self;
        let reach = gamma + TILE_RADIUS;
        // Room for a small triangle's pairs (about a dozen with the band's defaults), so
        // that the list rarely moves while it grows.
        let mut out = Vec::with_capacity(16 * tris.len());
        let mut cand: Vec<[i64; 3]> = Vec::new();
        for (k, tri) in tris.iter().enumerate() {
            let id = (first + k) as u32;
            let v = tri.vertices();
            let mut tlo = [0i64; 3];
            let mut thi = [0i64; 3];
            for a in 0..3 {
                let lo = v.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min);
                let hi = v.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max);
                let vlo = (lo - gamma).ceil() as i64;
                let vhi = (hi + gamma).floor() as i64;
                tlo[a] = vlo.div_euclid(4).max(TILE_MIN as i64);
                thi[a] = vhi.div_euclid(4).min(TILE_MAX as i64);
            }
            let n = tri.normal();
            let nn = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            // Scan the two axes across the dominant normal component; along it, only
            // the tiles whose centre is within `reach` of the plane.
            let m = (0..3).max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs())).unwrap_or(0);
            let (u, w) = ((m + 1) % 3, (m + 2) % 3);
            let slab = nn > 0.0 && n[m].abs() > 1e-6 * nn;
            let nd = n[0] * v[0][0] + n[1] * v[0][1] + n[2] * v[0][2];
            cand.clear();
            for tu in tlo[u]..=thi[u] {
                for tw in tlo[w]..=thi[w] {
                    let (cu, cw) = (4.0 * tu as f64 + 1.5, 4.0 * tw as f64 + 1.5);
                    let (mut m0, mut m1) = (tlo[m], thi[m]);
                    if slab {
                        let base = (nd - n[u] * cu - n[w] * cw) / n[m];
                        let half = reach * nn / n[m].abs() * (1.0 + 1e-4);
                        m0 = m0.max(((base - half - 1.5) / 4.0).ceil() as i64);
                        m1 = m1.min(((base + half - 1.5) / 4.0).floor() as i64);
                    }
                    for tm in m0..=m1 {
                        let mut c = [0i64; 3];
                        (c[m], c[u], c[w]) = (tm, tu, tw);
                        cand.push(c);
                    }
                }
            }
            let base = v[0].map(f64::floor);
            let local = tri.local(base);
            // The slack covers the f32 rounding of points up to `span` voxels from the
            // base (a few units of 10⁻⁷ × span) many times over.
            let span = (0..3).map(|a| (thi[a] - tlo[a] + 2) as f64 * 4.0).fold(0.0, f64::max);
            let slack = 1e-3 + 1e-5 * span;
            let reach2 = ((reach + slack) * (reach + slack)) as f32;
            let gamma_s = (gamma + slack) as f32;
            for batch in cand.chunks(BIN_BATCH) {
                let mut near = [false; BIN_BATCH];
                for (near, c) in near.iter_mut().zip(batch) {
                    let p: [f32; 3] =
                        std::array::from_fn(|a| (4.0 * c[a] as f64 + 1.5 - base[a]) as f32);
                    // With v = centre − nearest point, the tile's voxels are at least
                    // |v| − 1.5 (|vₓ| + |v_y| + |v_z|)/|v| from the triangle (see above):
                    // a voxel within γ needs |v|² − 1.5 |v|₁ ≤ γ |v|.
                    let v = local.offset(p);
                    let d2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                    let l1 = v[0].abs() + v[1].abs() + v[2].abs();
                    *near = d2 < reach2 && d2 - 1.5 * l1 <= gamma_s * d2.sqrt();
                }
                for (near, c) in near.iter().zip(batch) {
                    if *near {
                        out.push((Coord::new(c[0] as i32, c[1] as i32, c[2] as i32), id));
                    }
                }
            }
        }
        out
    }
}

/// The items of `chunks`, in order, sorted stably by `cell(item)` (each below `cells`)
/// and kept as `keep(item)`: the sorted items and the start of each cell's run (`cells +
/// 1` offsets). Linear in the items and cells, one pass to count and one to place; at
/// most `u32::MAX` items (the caller's check), so the offsets are 32-bit, the counts
/// doubling as the cursors of the placing pass.
pub(super) fn counting_sort<T, U: Copy + Default>(
    chunks: &[Vec<T>],
    cells: usize,
    cell: impl Fn(&T) -> usize,
    keep: impl Fn(&T) -> U,
) -> (Vec<U>, Vec<u32>) {
    let n: usize = chunks.iter().map(Vec::len).sum();
    debug_assert!(n <= u32::MAX as usize, "{n} items");
    let mut start = vec![0u32; cells + 1];
    for p in chunks.iter().flatten() {
        start[cell(p) + 1] += 1;
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut out = Vec::with_capacity(n);
    crate::memory::advise_huge_pages(&mut out);
    out.resize(n, U::default());
    // Each cell's start is its cursor: after placing, it holds the next cell's start.
    for p in chunks.iter().flatten() {
        let k = &mut start[cell(p)];
        out[*k as usize] = keep(p);
        *k += 1;
    }
    start.copy_within(0..cells, 1);
    start[0] = 0;
    (out, start)
}

/// The pairs of `chunks` (each in triangle order, the chunks in triangle order) as the
/// triangles of each tile, tiles in [`Coord`] order. Where the tiles' bounding box has at
/// most two cells per pair (a surface's bins), a counting sort by cell, stable, so the
/// triangle order within a tile is kept; else a comparison sort.
fn sort_pairs(chunks: Vec<Vec<(Coord, u32)>>) -> Bins {
    let n: usize = chunks.iter().map(Vec::len).sum();
    let b = CoordBox::of(chunks.iter().flatten().map(|p| p.0));
    match b.cells() {
        Some(cells) if cells <= 2 * n as u64 && n <= u32::MAX as usize => {
            let cell = |p: &(Coord, u32)| b.cell_of(p.0).expect("in the box");
            let (tris, start) = counting_sort(&chunks, cells as usize, cell, |p| p.1);
            drop(chunks);
            let tiles = (0..cells as usize)
                .filter(|&c| start[c] < start[c + 1])
                .map(|c| (b.coord_of(c), start[c] as usize, start[c + 1] as usize))
                .collect();
            Bins { tris, tiles }
        }
        _ => {
            let mut pairs: Vec<(Coord, u32)> = chunks.into_iter().flatten().collect();
            pairs.par_sort_unstable_by_key(|p| (p.0.key(), p.1));
            let mut tiles: Vec<(Coord, usize, usize)> = Vec::new();
            for (i, p) in pairs.iter().enumerate() {
                match tiles.last_mut() {
                    Some(t) if t.0 == p.0 => t.2 = i + 1,
                    _ => tiles.push((p.0, i, i + 1)),
                }
            }
            Bins { tris: pairs.into_iter().map(|p| p.1).collect(), tiles }
        }
    }
}

/// The unsigned distances of a chunk of tiles (runs of pairs with one tile), those with
/// band voxels, run at the CPU's instruction-set level ([`levelset_kernels::dispatch_one`]).
struct TileChunk<'a> {
    tris: &'a [Tri],
    /// [`Tri::shape`] of each triangle.
    shapes: &'a [LocalTri],
    /// [`Bins::tris`], and a chunk of [`Bins::tiles`].
    bins: &'a [u32],
    runs: &'a [(Coord, usize, usize)],
    gamma_v: f64,
    hf: f64,
    g: f32,
}

impl levelset_kernels::LaneFn for TileChunk<'_> {
    type Output = Vec<TileOut>;
    #[inline(always)]
    fn call<L: levelset_kernels::Lane>(self) -> Vec<TileOut> {
        let TileChunk { tris, shapes, bins, runs, gamma_v, hf, g } = self;
        let mut out = Vec::with_capacity(runs.len());
        for &(t, s, e) in runs {
            let d2 = tile_distances(tris, shapes, &bins[s..e], t, gamma_v);
            let mut values = [0f32; 64];
            let mut far = 0u64;
            for (l, v) in values.iter_mut().enumerate() {
                *v = ((d2[l].sqrt() * hf) as f32).min(g);
                far |= ((*v >= g) as u64) << l;
            }
            if far != u64::MAX {
                out.push(TileOut { coord: t, values, inside: 0, far });
            }
        }
        out
    }
}

/// Squared distances (voxel units) of the 64 voxels of tile `t` to the nearest of the
/// triangles `near`, capped at γ². Two passes: every triangle against all 64 voxels
/// in f32, relative to the tile ([`Tri::local`], from the triangle's `shape` moved to the
/// tile; [`LocalTri::search_tile`]), which finds
/// each voxel's nearest triangle; then that triangle's distance in f64 ([`Tri::dist2`]).
/// Where triangles tie within the f32 rounding at a shared edge or vertex, either gives
/// the same distance; two triangles whose nearest points differ but whose distances
/// differ by less than the f32 rounding (a voxel on the medial axis) may be taken in
/// either order, an error of that rounding: below 10⁻⁶ × the distance from the tile to
/// the triangle's first vertex (10⁻⁵ voxel for triangles ten voxels across).
#[inline(always)]
fn tile_distances(
    tris: &[Tri],
    shapes: &[LocalTri],
    near: &[u32],
    t: Coord,
    gamma: f64,
) -> [f64; 64] {
    let base = [4.0 * t.x as f64, 4.0 * t.y as f64, 4.0 * t.z as f64];
    // Candidates a little beyond γ in f32, so that none within γ in f64 is lost.
    let mut best = [(gamma * gamma * (1.0 + 1e-4)) as f32; TILE_LEN];
    let mut arg = [u32::MAX; TILE_LEN];
    let mut layer_max = [best[0]; 4];
    for &i in near {
        let i = i as usize;
        let local = shapes[i].at(tris[i].local_a(base));
        local.search_tile(i as u32, &mut best, &mut arg, &mut layer_max);
    }
    let mut d2 = [gamma * gamma; 64];
    for (l, (d, &i)) in d2.iter_mut().zip(&arg).enumerate() {
        if i != u32::MAX {
            let p = [
                base[0] + (l & 3) as f64,
                base[1] + (l >> 2 & 3) as f64,
                base[2] + (l >> 4) as f64,
            ];
            *d = tris[i as usize].dist2(p).min(*d);
        }
    }
    d2
}

/// The six face directions: (axis, ±1).
const FACES: [(usize, i32); 6] = [(0, 1), (0, -1), (1, 1), (1, -1), (2, 1), (2, -1)];

/// The neighbour of tile (or voxel) `c` one step along axis `a` in direction `d`.
fn step(c: Coord, a: usize, d: i32) -> Coord {
    let mut n = [c.x, c.y, c.z];
    n[a] = n[a].wrapping_add(d);
    Coord::new(n[0], n[1], n[2])
}

/// The bounding box of some coordinates and the cells' order in it (x fastest, so cell
/// order is [`Coord`] order): what the counting sort and the tile table index by.
struct CoordBox {
    lo: [i64; 3],
    /// Cells a side; all 0 for no coordinates.
    dims: [u64; 3],
}

impl CoordBox {
    fn of(coords: impl Iterator<Item = Coord>) -> CoordBox {
        let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
        for c in coords {
            for (a, v) in [c.x, c.y, c.z].into_iter().enumerate() {
                (lo[a], hi[a]) = (lo[a].min(v as i64), hi[a].max(v as i64));
            }
        }
        if lo[0] > hi[0] {
            return CoordBox { lo: [0; 3], dims: [0; 3] };
        }
        CoordBox { lo, dims: std::array::from_fn(|a| (hi[a] - lo[a] + 1) as u64) }
    }

    /// Cells in the box, `None` on overflow.
    fn cells(&self) -> Option<u64> {
        self.dims.iter().try_fold(1u64, |p, &d| p.checked_mul(d))
    }

    /// The coordinate of cell `i` of the box (the inverse of [`CoordBox::cell_of`]).
    fn coord_of(&self, i: usize) -> Coord {
        let i = i as u64;
        let (x, y, z) =
            (i % self.dims[0], i / self.dims[0] % self.dims[1], i / self.dims[0] / self.dims[1]);
        let c = [x as i64 + self.lo[0], y as i64 + self.lo[1], z as i64 + self.lo[2]];
        Coord::new(c[0] as i32, c[1] as i32, c[2] as i32)
    }

    #[inline]
    fn cell_of(&self, c: Coord) -> Option<usize> {
        let r = [c.x as i64 - self.lo[0], c.y as i64 - self.lo[1], c.z as i64 - self.lo[2]];
        if (0..3).any(|a| r[a] < 0 || r[a] as u64 >= self.dims[a]) {
            return None;
        }
        let r = r.map(|v| v as u64);
        Some(((r[2] * self.dims[1] + r[1]) * self.dims[0] + r[0]) as usize)
    }
}

/// Positions of the tiles of a sorted list: a table over the tiles' bounding box when it
/// has at most eight cells per tile (one step a lookup), else binary search.
struct TileIndex {
    b: CoordBox,
    /// Position + 1 per cell of the box, 0 where no tile is; empty: binary search.
    cell: Vec<u32>,
}

impl TileIndex {
    fn new(present: &[TileOut]) -> TileIndex {
        let b = CoordBox::of(present.iter().map(|t| t.coord));
        let mut cell = Vec::new();
        match b.cells() {
            Some(n) if n <= 8 * present.len() as u64 && present.len() < u32::MAX as usize => {
                cell = vec![0; n as usize];
                for (i, t) in present.iter().enumerate() {
                    cell[b.cell_of(t.coord).expect("in the box")] = i as u32 + 1;
                }
            }
            _ => {}
        }
        TileIndex { b, cell }
    }

    /// The position of tile `c` in `present` (the list this index was made from).
    #[inline]
    fn get(&self, present: &[TileOut], c: Coord) -> Option<usize> {
        if self.cell.is_empty() {
            return present.binary_search_by(|t| t.coord.cmp(&c)).ok();
        }
        let i = self.cell[self.b.cell_of(c)?];
        (i != 0).then(|| i as usize - 1)
    }
}

/// Whether the absent tile `c` with sign mask `mask` cannot stay absent: its signs differ
/// inside it, or one of its face voxels differs from the voxel it touches in a present
/// tile (a sign change needs band voxels on both sides).
fn fails(present: &[TileOut], index: &TileIndex, c: Coord, mask: u64) -> bool {
    if mask != 0 && mask != u64::MAX {
        return true;
    }
    FACES.iter().any(|&(a, d)| {
        let Some(p) = index.get(present, step(c, a, d)) else {
            return false;
        };
        let p = &present[p];
        // The present tile's face towards this tile, and this tile's face towards it.
        let (pl, al) = if d > 0 { (0, 3) } else { (3, 0) };
        face_voxels(a, pl)
            .iter()
            .zip(&face_voxels(a, al))
            .any(|(&vp, &va)| (p.inside >> vp & 1) != (mask >> va & 1))
    })
}

/// Per axis, the masks of a tile's two faces across it: the voxels with that coordinate
/// 0, and 3.
const FACE_MASKS: [[u64; 2]; 3] = {
    let mut out = [[0u64; 2]; 3];
    let mut l = 0;
    while l < 64 {
        let xyz = [l & 3, l >> 2 & 3, l >> 4];
        let mut a = 0;
        while a < 3 {
            if xyz[a] == 0 {
                out[a][0] |= 1 << l;
            }
            if xyz[a] == 3 {
                out[a][1] |= 1 << l;
            }
            a += 1;
        }
        l += 1;
    }
    out
};

/// Local indices of the 16 voxels of a tile's face: axis `a`, layer `layer` (0 or 3).
fn face_voxels(a: usize, layer: usize) -> [usize; 16] {
    let stride = [1, 4, 16];
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    let mut out = [0; 16];
    for (i, o) in out.iter_mut().enumerate() {
        *o = layer * stride[a] + (i & 3) * stride[b] + (i >> 2) * stride[c];
    }
    out
}

/// The closing of the module docs. `present` (sorted, every tile with a band voxel) grows
/// by the absent tiles that fail the check; returns the sign masks of every absent tile
/// next to a present one (sorted), all uniform.
fn close(
    rays: &Rays,
    present: &mut Vec<TileOut>,
    gamma: f32,
    half_voxel: f32,
) -> Vec<(Coord, u64)> {
    let mut absent: Vec<(Coord, u64)> = Vec::new();
    let mut fresh: Vec<Coord> = present.iter().map(|t| t.coord).collect();
    loop {
        let index = TileIndex::new(present);
        // Absent neighbours of the new tiles whose signs are not known yet.
        let mut todo: Vec<Coord> = fresh
            .par_iter()
            .flat_map_iter(|&t| {
                crate::coord::NEIGHBOURHOOD.iter().filter_map(move |&d| {
                    let n = Coord::new(
                        t.x.wrapping_add(d.x),
                        t.y.wrapping_add(d.y),
                        t.z.wrapping_add(d.z),
                    );
                    (d != Coord::new(0, 0, 0) && tile_in_range(n)).then_some(n)
                })
            })
            .filter(|&n| index.get(present, n).is_none())
            .collect();
        todo.par_sort_unstable();
        todo.dedup();
        todo.retain(|c| absent.binary_search_by(|a| a.0.cmp(c)).is_err());
        let masks: Vec<(Coord, u64)> = todo.par_iter().map(|&c| (c, rays.tile_inside(c))).collect();
        absent.extend(masks);
        absent.par_sort_unstable_by(|a, b| a.0.cmp(&b.0));
        // Absent tiles that must become band tiles. Only a tile whose signs are new, or
        // whose face neighbour just became a band tile, can fail now.
        let mut suspects: Vec<Coord> = fresh
            .iter()
            .flat_map(|&t| FACES.iter().map(move |&(a, d)| step(t, a, d)))
            .chain(todo.iter().copied())
            .collect();
        suspects.par_sort_unstable();
        suspects.dedup();
        let failed: Vec<(Coord, u64)> = suspects
            .par_iter()
            .filter_map(|&c| {
                let mask = absent[absent.binary_search_by(|a| a.0.cmp(&c)).ok()?].1;
                fails(present, &index, c, mask).then_some((c, mask))
            })
            .collect();
        if failed.is_empty() {
            break;
        }
        absent.retain(|a| failed.binary_search_by(|f| f.0.cmp(&a.0)).is_err());
        fresh = failed.iter().map(|f| f.0).collect();
        present.extend(failed.iter().map(|&(coord, inside)| TileOut {
            coord,
            values: [0.0; 64], // set below from the masks
            inside,
            far: u64::MAX,
        }));
        present.par_sort_unstable_by(|a, b| a.coord.cmp(&b.coord));
    }
    // Values of the added tiles: ±γ by sign.
    for t in present.iter_mut().filter(|t| t.far == u64::MAX) {
        for (l, v) in t.values.iter_mut().enumerate() {
            *v = if t.inside >> l & 1 == 1 { -gamma } else { gamma };
        }
    }
    // Then ±h/2 on every voxel beyond the band with a face neighbour of the other sign.
    let index = TileIndex::new(present);
    let lookup = |c: Coord| -> Option<u64> {
        if let Some(i) = index.get(present, c) {
            return Some(present[i].inside);
        }
        absent.binary_search_by(|a| a.0.cmp(&c)).ok().map(|i| absent[i].1)
    };
    let changes: Vec<u64> = present
        .par_iter()
        .map(|t| {
            if t.far == 0 {
                return 0;
            }
            // The signs of the six face neighbours of every voxel, as masks over the tile:
            // inside the tile the mask shifted by the axis's stride, across a face the
            // neighbour tile's opposite face; without a neighbour tile known, the voxel's
            // own sign (no change counts there).
            let m = t.inside;
            let mut diff = 0u64;
            for (a, stride) in [(0usize, 1u32), (1, 4), (2, 16)] {
                let (lo, hi) = (FACE_MASKS[a][0], FACE_MASKS[a][1]);
                let across = 3 * stride;
                let plus = lookup(step(t.coord, a, 1)).map_or(m & hi, |n| (n & lo) << across);
                let minus = lookup(step(t.coord, a, -1)).map_or(m & lo, |n| (n & hi) >> across);
                let up = ((m >> stride) & !hi) | plus;
                let down = ((m << stride) & !lo) | minus;
                diff |= (m ^ up) | (m ^ down);
            }
            t.far & diff
        })
        .collect();
    for (t, mut change) in present.iter_mut().zip(changes) {
        while change != 0 {
            let l = change.trailing_zeros() as usize;
            change &= change - 1;
            t.values[l] = if t.inside >> l & 1 == 1 { -half_voxel } else { half_voxel };
        }
    }
    absent
}
