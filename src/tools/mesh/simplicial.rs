//! Isosurfaces of dense vector fields φ: Zⁿ → Rᵐ in any dimension n ≤ 5 and codimension
//! m < n (paper Secs. 2–4): the zero set of the simplicial interpolant on the Kuhn
//! triangulation, as a welded simplicial complex of dimension n − m.
//!
//! Each grid cell splits into n! Kuhn simplices (Sec. 2.1); each simplex is cut by the
//! hyperplane of φ₁ with the tables of Sec. 3 ([`super::tables`]), the pieces by the
//! hyperplane of φ₂, and so on (successive hyperplane intersection, Sec. 4). Vertices are
//! welded by construction: a vertex of the first cut is keyed by the Kuhn edge it lies
//! on, a vertex of cut s by the pair of cut-(s−1) vertices it lies between, and each
//! vertex is computed once, so neighbouring cells and simplices share it bit for bit.
//!
//! ```
//! use sparse_levelset::tools::mesh::{isosurface_nd, NdField};
//!
//! // The unit circle in R² (n = 2, m = 1) sampled on a 21 × 21 grid over [-1.5, 1.5]².
//! let h = 3.0 / 20.0;
//! let f = NdField::from_fn(&[21, 21], 1, |x, out| {
//!     let (a, b) = (-1.5 + h * x[0] as f64, -1.5 + h * x[1] as f64);
//!     out[0] = a * a + b * b - 1.0;
//! })
//! .unwrap();
//! let curve = isosurface_nd(&f).unwrap();
//! assert_eq!(curve.simplex_dim(), 1);
//! assert!(curve.is_closed() && curve.is_consistently_oriented());
//! ```

use super::tables::{max_pieces, pieces, MAX_K};
use super::MeshError;
use std::collections::HashMap;

/// A dense field of m components on the grid {0..d₀−1} × … × {0..dₙ₋₁−1}.
///
/// Layout: point-major with the first axis fastest, components innermost:
/// `values[(x₀ + d₀ (x₁ + d₁ (…))) · m + r]`.
#[derive(Clone, Debug)]
pub struct NdField {
    dims: Vec<usize>,
    components: usize,
    values: Vec<f64>,
}

impl NdField {
    /// A checked field: 2 ≤ n ≤ 5 axes, each of ≥ 1 point, 1 ≤ m < n components, every
    /// value finite, `values.len()` = m · ∏ dims.
    pub fn new(dims: &[usize], components: usize, values: Vec<f64>) -> Result<Self, MeshError> {
        let n = dims.len();
        if !(2..=MAX_K).contains(&n) {
            return Err(MeshError::InvalidParameter(format!(
                "dimension n = {n}: supported are 2..={MAX_K} (the paper's tables)"
            )));
        }
        if !(1..n).contains(&components) {
            return Err(MeshError::InvalidParameter(format!(
                "codimension m = {components}: needs 1 <= m < n = {n}"
            )));
        }
        let points = dims
            .iter()
            .try_fold(1usize, |a, &d| if d == 0 { None } else { a.checked_mul(d) })
            .and_then(|p| p.checked_mul(components))
            .filter(|&len| len <= u32::MAX as usize)
            .ok_or_else(|| {
                MeshError::InvalidParameter(format!(
                    "dims {dims:?}: every axis needs >= 1 point and the field at most 2^32 values"
                ))
            })?;
        if values.len() != points {
            return Err(MeshError::InvalidParameter(format!(
                "{} values for dims {dims:?} with {components} components ({points} expected)",
                values.len()
            )));
        }
        if let Some(i) = crate::storage::dense::first_position(&values, |v| !v.is_finite()) {
            return Err(MeshError::NonFinite { index: i / components });
        }
        Ok(NdField { dims: dims.to_vec(), components, values })
    }

    /// A field from `f(point, out)`, which writes the m components at grid point `point`.
    pub fn from_fn(
        dims: &[usize],
        components: usize,
        mut f: impl FnMut(&[usize], &mut [f64]),
    ) -> Result<Self, MeshError> {
        let total = dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
        let len = total.and_then(|t| t.checked_mul(components)).filter(|&l| l <= u32::MAX as usize);
        let Some(len) = len else {
            return Err(MeshError::InvalidParameter(format!(
                "dims {dims:?} with {components} components: more than 2^32 values"
            )));
        };
        let mut values = vec![0.0; len];
        let mut x = vec![0usize; dims.len()];
        for chunk in values.chunks_exact_mut(components.max(1)) {
            f(&x, chunk);
            for (xi, &d) in x.iter_mut().zip(dims) {
                *xi += 1;
                if *xi < d {
                    break;
                }
                *xi = 0;
            }
        }
        NdField::new(dims, components, values)
    }

    /// n.
    pub fn dim(&self) -> usize {
        self.dims.len()
    }

    /// m.
    pub fn components(&self) -> usize {
        self.components
    }

    pub fn dims(&self) -> &[usize] {
        &self.dims
    }
}

/// A simplicial complex of dimension k = n − m in Rⁿ (grid index coordinates).
#[derive(Clone, Debug, Default)]
pub struct SimplicialComplex {
    /// n.
    pub ambient_dim: usize,
    /// Vertex coordinates, `ambient_dim` per vertex, in grid index units.
    pub points: Vec<f64>,
    /// Simplices, k + 1 vertex indices each, oriented (see [`isosurface_nd`]).
    pub simplices: Vec<u32>,
    /// k + 1.
    pub simplex_len: usize,
    /// Statistics of the construction.
    pub stats: ComplexStats,
}

/// Counts gathered while cutting, for checking Corollary 3.2 and Sec. 4's bounds.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ComplexStats {
    /// Cells where every component changes sign.
    pub cells_cut: usize,
    /// Most (n−m)-simplices produced in one cell.
    pub max_simplices_per_cell: usize,
    /// Most (n−m)-simplices produced from one Kuhn simplex.
    pub max_simplices_per_kuhn_simplex: usize,
}

impl SimplicialComplex {
    /// k, the dimension of the simplices.
    pub fn simplex_dim(&self) -> usize {
        self.simplex_len.saturating_sub(1)
    }

    pub fn num_vertices(&self) -> usize {
        self.points.len().checked_div(self.ambient_dim).unwrap_or(0)
    }

    pub fn num_simplices(&self) -> usize {
        self.simplices.len().checked_div(self.simplex_len).unwrap_or(0)
    }

    /// Vertex `i`'s coordinates.
    pub fn point(&self, i: usize) -> &[f64] {
        &self.points[i * self.ambient_dim..(i + 1) * self.ambient_dim]
    }

    /// Simplex `i`'s vertex indices.
    pub fn simplex(&self, i: usize) -> &[u32] {
        &self.simplices[i * self.simplex_len..(i + 1) * self.simplex_len]
    }

    /// The (k−1)-faces with the orientation each simplex induces on them: face j of
    /// (v₀ … v_k) drops v_j with sign (−1)^j; a face is stored sorted with the sign of
    /// the sorting permutation folded in.
    fn faces(&self) -> Vec<(Vec<u32>, i8)> {
        let mut out = Vec::with_capacity(self.num_simplices() * self.simplex_len);
        for s in 0..self.num_simplices() {
            let v = self.simplex(s);
            for j in 0..v.len() {
                let mut f: Vec<u32> =
                    v.iter().enumerate().filter(|&(i, _)| i != j).map(|(_, &x)| x).collect();
                let mut sign: i8 = if j % 2 == 0 { 1 } else { -1 };
                // Insertion sort, counting swaps.
                for a in 1..f.len() {
                    let mut b = a;
                    while b > 0 && f[b - 1] > f[b] {
                        f.swap(b - 1, b);
                        sign = -sign;
                        b -= 1;
                    }
                }
                out.push((f, sign));
            }
        }
        out.sort();
        out
    }

    /// Whether the complex is closed: every (k−1)-face lies in exactly two k-simplices
    /// (for k = 1: every vertex has degree 2), and no simplex repeats a vertex.
    pub fn is_closed(&self) -> bool {
        if (0..self.num_simplices()).any(|s| {
            let v = self.simplex(s);
            (0..v.len()).any(|i| v[i + 1..].contains(&v[i]))
        }) {
            return false;
        }
        let faces = self.faces();
        let mut i = 0;
        while i < faces.len() {
            let mut j = i;
            while j < faces.len() && faces[j].0 == faces[i].0 {
                j += 1;
            }
            if j - i != 2 {
                return false;
            }
            i = j;
        }
        true
    }

    /// Whether neighbouring simplices are coherently oriented: every (k−1)-face shared by
    /// two simplices receives opposite orientations from them.
    pub fn is_consistently_oriented(&self) -> bool {
        let faces = self.faces();
        faces.chunk_by(|a, b| a.0 == b.0).all(|g| g.len() != 2 || g[0].1 != g[1].1)
    }

    /// Euler characteristic Σ_d (−1)^d (number of d-faces), all faces of all simplices.
    pub fn euler_characteristic(&self) -> i64 {
        let mut chi = 0i64;
        let k1 = self.simplex_len;
        for size in 1..=k1 {
            let mut faces: Vec<Vec<u32>> = Vec::new();
            for s in 0..self.num_simplices() {
                let mut v = self.simplex(s).to_vec();
                v.sort_unstable();
                for bits in 0u32..1 << k1 {
                    if bits.count_ones() as usize == size {
                        faces.push(
                            (0..k1).filter(|&i| bits & (1 << i) != 0).map(|i| v[i]).collect(),
                        );
                    }
                }
            }
            faces.sort_unstable();
            faces.dedup();
            let sign = if size % 2 == 1 { 1 } else { -1 };
            chi += sign * faces.len() as i64;
        }
        chi
    }
}

/// A bound from Sec. 4 and Corollary 3.2 on the simplices one cell can produce: n! Kuhn
/// simplices, each cut into at most `max_pieces(n) · max_pieces(n−1) · … ·
/// max_pieces(n−m+1)` pieces (e.g. 6 × 3 × 2 for n = 5, m = 3).
pub fn cell_simplex_bound(n: usize, m: usize) -> usize {
    let per_simplex: usize = (n - m + 1..=n).map(max_pieces).product();
    (1..=n).product::<usize>() * per_simplex
}

/// The permutations of 0..n with their signs, in lexicographic order.
pub(crate) fn permutations(n: usize) -> Vec<(Vec<usize>, i8)> {
    fn rec(cur: &mut Vec<usize>, used: &mut [bool], out: &mut Vec<(Vec<usize>, i8)>) {
        let n = used.len();
        if cur.len() == n {
            let inversions = (0..n)
                .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
                .filter(|&(i, j)| cur[i] > cur[j]);
            let sign = if inversions.count() % 2 == 0 { 1 } else { -1 };
            out.push((cur.clone(), sign));
            return;
        }
        for i in 0..n {
            if !used[i] {
                used[i] = true;
                cur.push(i);
                rec(cur, used, out);
                cur.pop();
                used[i] = false;
            }
        }
    }
    let mut out = Vec::new();
    rec(&mut Vec::new(), &mut vec![false; n], &mut out);
    out
}

/// Node store: every grid point and cut point used, each computed once.
struct Nodes {
    n: usize,
    m: usize,
    pos: Vec<f64>,
    val: Vec<f64>,
    ids: HashMap<(u64, u64), u32>,
}

const GRID: u64 = u64::MAX;

impl Nodes {
    fn grid(&mut self, field: &NdField, index: usize) -> u32 {
        let key = (GRID, index as u64);
        if let Some(&id) = self.ids.get(&key) {
            return id;
        }
        let id = (self.pos.len() / self.n) as u32;
        let mut rest = index;
        for &d in &field.dims {
            self.pos.push((rest % d) as f64);
            rest /= d;
        }
        self.val.extend_from_slice(&field.values[index * self.m..(index + 1) * self.m]);
        self.ids.insert(key, id);
        id
    }

    fn value(&self, id: u32, r: usize) -> f64 {
        self.val[id as usize * self.m + r]
    }

    /// The point of eq. (2) on the segment from node `a` (ψ_r < 0) to node `b` (ψ_r ≥ 0).
    fn cut(&mut self, a: u32, b: u32, r: usize) -> u32 {
        let key = (a.min(b) as u64, a.max(b) as u64);
        if let Some(&id) = self.ids.get(&key) {
            return id;
        }
        let id = (self.pos.len() / self.n) as u32;
        let (va, vb) = (self.value(a, r), self.value(b, r));
        let t = va / (va - vb);
        let (ia, ib) = (a as usize, b as usize);
        for c in 0..self.n {
            let (pa, pb) = (self.pos[ia * self.n + c], self.pos[ib * self.n + c]);
            self.pos.push(pa + t * (pb - pa));
        }
        for s in 0..self.m {
            let v = if s == r {
                0.0
            } else {
                let (xa, xb) = (self.val[ia * self.m + s], self.val[ib * self.m + s]);
                xa + t * (xb - xa)
            };
            self.val.push(v);
        }
        self.ids.insert(key, id);
        id
    }
}

/// The isosurface {φ̂ = 0} of a field φ: Zⁿ → Rᵐ (Sec. 4, eq. (4)), a complex of
/// (n−m)-simplices in grid index coordinates.
///
/// Sign convention: a value of exactly 0 counts as positive (the ε-perturbation of
/// Sec. 3), so every vertex lies on an edge with a strictly negative and a non-negative
/// end and the output is a closed pseudo-manifold wherever the field's zero set stays
/// inside the grid; vertices may coincide where values are exactly 0 (zero-volume
/// simplices), but they stay distinct and the combinatorics stay manifold.
///
/// Orientation: for m = 1 each simplex's edge vectors followed by ∇φ are positively
/// oriented in Rⁿ (for n = 3: triangle normals point to φ > 0); for m > 1 the rule applies
/// cut by cut inside each piece of the previous cut.
pub fn isosurface_nd(field: &NdField) -> Result<SimplicialComplex, MeshError> {
    let n = field.dim();
    let m = field.components;
    let corners = 1usize << n;
    let mut strides = vec![1usize; n];
    for i in 1..n {
        strides[i] = strides[i - 1] * field.dims[i - 1];
    }
    let corner_offset: Vec<usize> = (0..corners)
        .map(|c| (0..n).filter(|&i| c & (1 << i) != 0).map(|i| strides[i]).sum())
        .collect();
    let perms = permutations(n);
    let mut nodes = Nodes { n, m, pos: Vec::new(), val: Vec::new(), ids: HashMap::new() };
    let mut stats = ComplexStats::default();
    let mut out: Vec<(Vec<u32>, i8)> = Vec::new();
    let cells: Vec<usize> = field.dims.iter().map(|&d| d.saturating_sub(1)).collect();
    if cells.contains(&0) {
        return Ok(SimplicialComplex {
            ambient_dim: n,
            simplex_len: n - m + 1,
            ..Default::default()
        });
    }
    let mut a = vec![0usize; n];
    let mut current: Vec<(Vec<u32>, i8)> = Vec::new();
    let mut next: Vec<(Vec<u32>, i8)> = Vec::new();
    'cells: loop {
        let base: usize = a.iter().zip(&strides).map(|(x, s)| x * s).sum();
        // A cell is cut only if every component changes sign over its corners.
        let crosses = (0..m).all(|r| {
            let neg =
                corner_offset.iter().filter(|&&o| field.values[(base + o) * m + r] < 0.0).count();
            neg != 0 && neg != corners
        });
        if crosses {
            stats.cells_cut += 1;
            let mut in_cell = 0;
            for (perm, sign) in &perms {
                // Kuhn simplex C_J^a: v₀ = a, v_i = v_{i−1} + e_{J(i)} (Sec. 2.1); its
                // orientation in that order is sign(J).
                let mut corner = 0usize;
                let mut verts = vec![nodes.grid(field, base)];
                for &axis in perm {
                    corner |= 1 << axis;
                    verts.push(nodes.grid(field, base + corner_offset[corner]));
                }
                current.clear();
                current.push((verts, *sign));
                for r in 0..m {
                    next.clear();
                    for (s, sign) in &current {
                        let k = s.len() - 1;
                        let mask = s
                            .iter()
                            .enumerate()
                            .filter(|&(_, &v)| nodes.value(v, r) < 0.0)
                            .fold(0u32, |acc, (i, _)| acc | 1 << i);
                        for piece in pieces(k, mask) {
                            let verts: Vec<u32> = piece
                                .pairs
                                .iter()
                                .map(|&(i, j)| nodes.cut(s[i as usize], s[j as usize], r))
                                .collect();
                            next.push((verts, if piece.flip { -sign } else { *sign }));
                        }
                    }
                    std::mem::swap(&mut current, &mut next);
                }
                stats.max_simplices_per_kuhn_simplex =
                    stats.max_simplices_per_kuhn_simplex.max(current.len());
                in_cell += current.len();
                out.append(&mut current);
            }
            stats.max_simplices_per_cell = stats.max_simplices_per_cell.max(in_cell);
            // Node ids are u32; a cell adds at most a few thousand nodes.
            if nodes.pos.len() / n > (u32::MAX - (1 << 20)) as usize {
                return Err(MeshError::TooLarge(format!("more than {} vertices", u32::MAX)));
            }
        }
        for (xi, &d) in a.iter_mut().zip(&cells) {
            *xi += 1;
            if *xi < d {
                continue 'cells;
            }
            *xi = 0;
        }
        break;
    }
    // Renumber the final vertices in order of first use.
    let mut index: HashMap<u32, u32> = HashMap::new();
    let mut points = Vec::new();
    let mut simplices = Vec::with_capacity(out.len() * (n - m + 1));
    for (mut s, sign) in out {
        if sign < 0 {
            s.swap(0, 1);
        }
        for v in s {
            let next_id = index.len() as u32;
            let id = *index.entry(v).or_insert_with(|| {
                points.extend_from_slice(&nodes.pos[v as usize * n..(v as usize + 1) * n]);
                next_id
            });
            simplices.push(id);
        }
    }
    Ok(SimplicialComplex { ambient_dim: n, points, simplices, simplex_len: n - m + 1, stats })
}
