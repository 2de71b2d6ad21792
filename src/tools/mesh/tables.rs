//! Triangulation tables of the intersection of a k-simplex with a hyperplane (paper
//! Sec. 3, Tables 1–4), generated once for k = 2..=5 and every sign pattern.
//!
//! # What a table entry is
//! A k-simplex has vertices `0..=k` listed in a fixed order (the Kuhn order of Sec. 2.1,
//! or the order inherited from the previous cut, see below). For a hyperplane ψ = 0 whose
//! sign pattern is `mask` (bit `i` set ⇔ ψ(vertex i) < 0; a value of exactly 0 counts as
//! positive, the paper's "perturb ψ(v_i) = ε" of Sec. 3), a section of type (p, q) is the
//! product of simplices Δ_{p−1} × Δ_{q−1} (proof of Corollary 3.2) and its vertices are
//! the points v_ij (eq. (2)) on the edges from a negative vertex i to a positive vertex j.
//! An entry lists the (k−1)-simplices of the section as sequences of such (i, j) pairs.
//!
//! # Which triangulation
//! Every piece is a *staircase*: a monotone path through the p × q grid of pairs with the
//! negative vertices in ascending and the positive vertices in descending list order. For
//! k ≤ 4 this is exactly Tables 1–3, and for k = 5 the (5,1) and (4,2) rows of Table 4
//! (checked by a test against transcriptions of the tables). For the (3,3) row of Table 4
//! the paper prints a Delaunay triangulation instead; the staircase has the same count
//! (Corollary 3.2: 6) and is used here because a staircase triangulation restricts to every
//! face as the staircase triangulation of that face, and the paper's row does not fit with
//! its neighbours: with it in place (negatives, then positives, each in list order) the
//! R⁵, m = 3 complex of `tests/mesh.rs` is not closed. Two simplices sharing a face therefore
//! cut it identically, which is what makes welded output conforming and closed — also for
//! codimension m ≥ 2, where the pieces of one cut are cut again (Sec. 4) and the path
//! order of the pieces' vertices is the list order of the next cut. The path order is
//! consistent across simplices because it only depends on the order of the original
//! vertices, which is global (Kuhn vertices are ordered by coordinate sum).
//!
//! # Orientation
//! Each piece carries `flip`: whether its path order is negatively oriented in the
//! convention "edge vectors of the piece followed by ∇ψ have the orientation of the
//! parent simplex's list order". The sign is computed once in the canonical section
//! (ψ = ±1, midpoints; all sections of one type are isomorphic, Sec. 3).

use std::sync::OnceLock;

/// Largest simplex dimension with a table (the paper's tables stop at 5, and so do we).
pub const MAX_K: usize = 5;

/// One simplex of a section.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Piece {
    /// Its vertices as (negative vertex, positive vertex) pairs, in path order.
    pub pairs: Vec<(u8, u8)>,
    /// Whether the path order is negatively oriented (see the module docs).
    pub flip: bool,
}

/// `tables[k][mask]`: the pieces of a k-simplex with sign pattern `mask`.
type Tables = Vec<Vec<Vec<Piece>>>;

fn tables() -> &'static Tables {
    static T: OnceLock<Tables> = OnceLock::new();
    T.get_or_init(|| {
        (0..=MAX_K)
            .map(|k| {
                if k < 2 {
                    Vec::new()
                } else {
                    (0..1u32 << (k + 1)).map(|mask| build(k, mask)).collect()
                }
            })
            .collect()
    })
}

/// The pieces of the section of a k-simplex (2 ≤ k ≤ 5) with sign pattern `mask`
/// (bit i ⇔ ψ(vertex i) < 0). Empty when all vertices have one sign.
#[inline]
pub fn pieces(k: usize, mask: u32) -> &'static [Piece] {
    &tables()[k][mask as usize]
}

/// Corollary 3.2: every triangulation of a (p, q)-type section uses
/// (p+q−2)! / ((p−1)! (q−1)!) simplices.
pub fn corollary_3_2(p: usize, q: usize) -> usize {
    assert!(p >= 1 && q >= 1);
    binomial(p + q - 2, p - 1)
}

/// The most pieces any section of a k-simplex has (the largest row of its table).
pub fn max_pieces(k: usize) -> usize {
    (1..=k).map(|p| corollary_3_2(p, k + 1 - p)).max().unwrap_or(0)
}

fn binomial(n: usize, r: usize) -> usize {
    (0..r).fold(1usize, |acc, i| acc * (n - i) / (i + 1))
}

fn build(k: usize, mask: u32) -> Vec<Piece> {
    let neg: Vec<u8> = (0..=k as u8).filter(|&i| mask & (1 << i) != 0).collect();
    let mut pos: Vec<u8> = (0..=k as u8).filter(|&i| mask & (1 << i) == 0).collect();
    if neg.is_empty() || pos.is_empty() {
        return Vec::new();
    }
    pos.reverse();
    let (p, q) = (neg.len(), pos.len());
    let mut out = Vec::with_capacity(corollary_3_2(p, q));
    // A path is the set of steps (of p−1 + q−1) that advance the positive index; walk all
    // subsets of size q−1 in lexicographic order of the step sequence.
    let steps = p + q - 2;
    for bits in 0u32..1 << steps {
        if bits.count_ones() as usize != q - 1 {
            continue;
        }
        let (mut a, mut b) = (0, 0);
        let mut pairs = vec![(neg[0], pos[0])];
        for s in 0..steps {
            if bits & (1 << s) != 0 {
                b += 1;
            } else {
                a += 1;
            }
            pairs.push((neg[a], pos[b]));
        }
        let flip = orientation(k, mask, &pairs) < 0.0;
        out.push(Piece { pairs, flip });
    }
    out
}

/// det[w_1 − w_0, …, w_{k−1} − w_0, ∇ψ] in the canonical section: vertex 0 at the origin,
/// vertex i at e_i, ψ = −1 on negative and +1 on positive vertices, w = edge midpoints.
fn orientation(k: usize, mask: u32, pairs: &[(u8, u8)]) -> f64 {
    let vertex = |i: u8| -> Vec<f64> {
        let mut v = vec![0.0; k];
        if i > 0 {
            v[i as usize - 1] = 1.0;
        }
        v
    };
    let psi = |i: u8| if mask & (1 << i) != 0 { -1.0 } else { 1.0 };
    let mid = |&(i, j): &(u8, u8)| -> Vec<f64> {
        vertex(i).iter().zip(vertex(j)).map(|(a, b)| 0.5 * (a + b)).collect()
    };
    let w: Vec<Vec<f64>> = pairs.iter().map(mid).collect();
    let mut m: Vec<Vec<f64>> =
        w[1..].iter().map(|wi| wi.iter().zip(&w[0]).map(|(a, b)| a - b).collect()).collect();
    m.push((1..=k as u8).map(|i| psi(i) - psi(0)).collect());
    determinant(m)
}

/// Determinant by Gaussian elimination with partial pivoting (small matrices only).
pub(crate) fn determinant(mut m: Vec<Vec<f64>>) -> f64 {
    let n = m.len();
    let mut det = 1.0;
    for c in 0..n {
        let piv = (c..n)
            .max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs()))
            .expect("non-empty range");
        if m[piv][c] == 0.0 {
            return 0.0;
        }
        if piv != c {
            m.swap(piv, c);
            det = -det;
        }
        det *= m[c][c];
        let (top, rest) = m.split_at_mut(c + 1);
        let pivot = &top[c];
        for row in rest {
            let f = row[c] / pivot[c];
            for (x, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                *x -= f * p;
            }
        }
    }
    det
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// A table row as printed in the paper (1-based vertex numbers, negatives first).
    type Row = &'static [&'static [(u8, u8)]];

    /// Tables 1–4 transcribed: (p, q, pieces). Table 4's (3,3) row is the paper's Delaunay
    /// choice and is checked only for its count and validity, not equality.
    const PAPER: &[(usize, usize, Row)] = &[
        (2, 1, &[&[(1, 3), (2, 3)]]),
        (3, 1, &[&[(1, 4), (2, 4), (3, 4)]]),
        (2, 2, &[&[(1, 3), (2, 3), (1, 4)], &[(1, 4), (2, 3), (2, 4)]]),
        (4, 1, &[&[(1, 5), (2, 5), (3, 5), (4, 5)]]),
        (
            3,
            2,
            &[
                &[(1, 4), (1, 5), (3, 4), (2, 4)],
                &[(1, 5), (2, 4), (2, 5), (3, 4)],
                &[(1, 5), (2, 5), (3, 5), (3, 4)],
            ],
        ),
        (5, 1, &[&[(1, 6), (2, 6), (3, 6), (5, 6), (4, 6)]]),
        (
            4,
            2,
            &[
                &[(1, 5), (1, 6), (2, 5), (4, 5), (3, 5)],
                &[(1, 6), (2, 5), (2, 6), (3, 5), (4, 5)],
                &[(1, 6), (2, 6), (3, 5), (4, 5), (3, 6)],
                &[(1, 6), (2, 6), (3, 6), (4, 5), (4, 6)],
            ],
        ),
        (
            3,
            3,
            &[
                &[(1, 4), (1, 5), (1, 6), (3, 6), (2, 5)],
                &[(1, 4), (1, 5), (2, 5), (3, 6), (3, 5)],
                &[(1, 4), (1, 6), (2, 5), (2, 6), (3, 6)],
                &[(1, 4), (2, 4), (2, 5), (3, 4), (2, 6)],
                &[(1, 4), (2, 5), (2, 6), (3, 6), (3, 4)],
                &[(1, 4), (2, 5), (3, 4), (3, 6), (3, 5)],
            ],
        ),
    ];

    fn as_sets(pieces: &[Vec<(u8, u8)>]) -> BTreeSet<BTreeSet<(u8, u8)>> {
        pieces.iter().map(|p| p.iter().copied().collect()).collect()
    }

    /// Signed volume of a piece in the canonical section (k−1 edge vectors and ∇ψ).
    fn volume(k: usize, mask: u32, pairs: &[(u8, u8)]) -> f64 {
        orientation(k, mask, pairs)
    }

    /// Table rows use negatives 1..=p (0-based 0..p) and positives after them.
    fn paper_pieces(p: usize, q: usize, rows: Row) -> (usize, u32, Vec<Vec<(u8, u8)>>) {
        let k = p + q - 1;
        let mask = (1u32 << p) - 1;
        let pieces =
            rows.iter().map(|r| r.iter().map(|&(i, j)| (i - 1, j - 1)).collect()).collect();
        (k, mask, pieces)
    }

    #[test]
    fn staircase_matches_tables_1_to_4() {
        for &(p, q, rows) in PAPER {
            let (k, mask, paper) = paper_pieces(p, q, rows);
            let ours: Vec<Vec<(u8, u8)>> =
                pieces(k, mask).iter().map(|x| x.pairs.clone()).collect();
            assert_eq!(ours.len(), corollary_3_2(p, q), "({p},{q})");
            assert_eq!(paper.len(), corollary_3_2(p, q), "paper ({p},{q})");
            // Both triangulate the section: pieces are non-degenerate and their volumes add
            // up to the same total.
            let total = |ps: &[Vec<(u8, u8)>]| -> f64 {
                ps.iter()
                    .map(|x| {
                        let v = volume(k, mask, x).abs();
                        assert!(v > 1e-12, "degenerate piece {x:?} in ({p},{q})");
                        v
                    })
                    .sum()
            };
            let (a, b) = (total(&ours), total(&paper));
            assert!((a - b).abs() <= 1e-12 * (1.0 + a), "({p},{q}): {a} vs {b}");
            if (p, q) != (3, 3) {
                assert_eq!(as_sets(&ours), as_sets(&paper), "({p},{q})");
            }
        }
    }

    #[test]
    fn every_pattern_has_the_corollary_3_2_count_and_valid_orientation() {
        for k in 2..=MAX_K {
            for mask in 0..1u32 << (k + 1) {
                let p = mask.count_ones() as usize;
                let q = k + 1 - p;
                let ps = pieces(k, mask);
                if p == 0 || q == 0 {
                    assert!(ps.is_empty());
                    continue;
                }
                assert_eq!(ps.len(), corollary_3_2(p, q), "k={k} mask={mask:b}");
                for x in ps {
                    assert_eq!(x.pairs.len(), k);
                    let d = orientation(k, mask, &x.pairs);
                    assert!(d.abs() > 1e-12 && (d < 0.0) == x.flip);
                    for &(i, j) in &x.pairs {
                        assert!(mask & (1 << i) != 0 && mask & (1 << j) == 0);
                    }
                }
            }
        }
        assert_eq!([max_pieces(2), max_pieces(3), max_pieces(4), max_pieces(5)], [1, 2, 3, 6]);
    }
}
