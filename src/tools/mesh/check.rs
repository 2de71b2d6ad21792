//! Checks and measures of a [`TriangleMesh`]: closedness, manifoldness, orientation,
//! Euler characteristic, area and enclosed volume (all sums in f64).

use super::TriangleMesh;

/// (b − a) × (c − a) of triangle `t`: its normal scaled by twice its area.
pub(super) fn face_normal(m: &TriangleMesh, t: &[u32; 3]) -> [f64; 3] {
    let p = |i: u32| m.positions[i as usize];
    let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
}

impl TriangleMesh {
    /// Directed edges (from, to) of every triangle, sorted.
    fn directed_edges(&self) -> Vec<(u32, u32)> {
        let mut e: Vec<(u32, u32)> = self
            .triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .collect();
        e.sort_unstable();
        e
    }

    /// Whether the mesh is a closed, consistently oriented 2-manifold: indices in range,
    /// no triangle repeats a vertex, every edge lies in exactly two triangles that run
    /// along it in opposite directions, and the triangles around each vertex form one
    /// single fan (the vertex's link is one cycle). An empty mesh is not.
    pub fn is_closed_manifold(&self) -> bool {
        let nv = self.positions.len() as u64;
        if self.triangles.is_empty()
            || self.triangles.iter().any(|t| {
                t.iter().any(|&v| v as u64 >= nv) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]
            })
        {
            return false;
        }
        let e = self.directed_edges();
        // Each directed edge once, and its reverse present: with the reverse present for
        // all, every undirected edge has exactly two triangles of opposite direction.
        if e.windows(2).any(|w| w[0] == w[1]) {
            return false;
        }
        if e.iter().any(|&(a, b)| e.binary_search(&(b, a)).is_err()) {
            return false;
        }
        // Link of each vertex v: triangle (v, b, c) contributes b → c; the map is a
        // permutation of the link vertices (directed edges are unique) and must be one cycle.
        let mut link: Vec<(u32, u32, u32)> = self
            .triangles
            .iter()
            .flat_map(|t| [(t[0], t[1], t[2]), (t[1], t[2], t[0]), (t[2], t[0], t[1])])
            .collect();
        link.sort_unstable();
        link.chunk_by(|a, b| a.0 == b.0).all(|fan| {
            let next = |b: u32| fan.binary_search_by(|x| x.1.cmp(&b)).ok().map(|i| fan[i].2);
            let start = fan[0].1;
            let mut cur = start;
            for step in 1..=fan.len() {
                match next(cur) {
                    Some(n) if n == start => return step == fan.len(),
                    Some(n) => cur = n,
                    None => return false,
                }
            }
            false
        })
    }

    /// V − E + F over the vertices used by triangles (2 for a sphere, 0 for a torus).
    pub fn euler_characteristic(&self) -> i64 {
        let mut used: Vec<u32> = self.triangles.iter().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        let mut edges: Vec<(u32, u32)> =
            self.directed_edges().into_iter().map(|(a, b)| (a.min(b), a.max(b))).collect();
        edges.sort_unstable();
        edges.dedup();
        used.len() as i64 - edges.len() as i64 + self.triangles.len() as i64
    }

    /// Total triangle area (world units²).
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let n = face_normal(self, t);
                0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
            })
            .sum()
    }

    /// Signed enclosed volume (divergence theorem, Σ a · (b × c) / 6): positive for a
    /// closed mesh oriented outward, the volume of φ < iso.
    pub fn enclosed_volume(&self) -> f64 {
        // Relative to a vertex of the mesh, so that far-from-origin meshes keep precision.
        let r = self.positions.first().copied().unwrap_or([0.0; 3]);
        self.triangles
            .iter()
            .map(|t| {
                let p = |i: u32| {
                    let q = self.positions[i as usize];
                    [q[0] - r[0], q[1] - r[1], q[2] - r[2]]
                };
                let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
                let bc = [
                    b[1] * c[2] - b[2] * c[1],
                    b[2] * c[0] - b[0] * c[2],
                    b[0] * c[1] - b[1] * c[0],
                ];
                (a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2]) / 6.0
            })
            .sum()
    }

    /// Triangles whose area, computed in f64 from the stored positions, is exactly zero
    /// (two equal positions or three collinear ones). For positions that are f32 values
    /// the computation is exact: differences of nearby f32 values and their products are
    /// exact in f64, so zero means truly degenerate.
    pub fn degenerate_triangles(&self) -> usize {
        self.triangles.iter().filter(|t| face_normal(self, t) == [0.0; 3]).count()
    }

    /// The mesh as a reader that welds coincident vertices sees it (trimesh's
    /// `merge_vertices`, MeshLab's "merge close vertices" at distance 0): vertices at
    /// equal positions (`0.0 == -0.0`) become one, numbered in order of first
    /// appearance, keeping the first one's normal; triangles are kept as they are, even
    /// where they now repeat a vertex (which [`TriangleMesh::is_closed_manifold`] refuses);
    /// an index out of range becomes `u32::MAX`.
    pub fn weld_coincident(&self) -> TriangleMesh {
        // + 0.0 turns -0.0 into 0.0, so equal positions have equal bits.
        let bits = |i: usize| self.positions[i].map(|c| (c + 0.0).to_bits());
        let mut order: Vec<usize> = (0..self.positions.len()).collect();
        order.sort_by_key(|&i| (bits(i), i));
        let mut first = vec![0usize; self.positions.len()];
        for run in order.chunk_by(|&a, &b| bits(a) == bits(b)) {
            for &i in run {
                first[i] = run[0];
            }
        }
        let mut index = vec![u32::MAX; self.positions.len()];
        let mut out = TriangleMesh::default();
        for i in 0..self.positions.len() {
            if first[i] == i {
                index[i] = out.positions.len() as u32;
                out.positions.push(self.positions[i]);
                out.normals.push(self.normals.get(i).copied().unwrap_or([0.0; 3]));
            }
        }
        out.triangles = self
            .triangles
            .iter()
            .map(|t| t.map(|v| first.get(v as usize).map_or(u32::MAX, |&f| index[f])))
            .collect();
        out
    }
}
