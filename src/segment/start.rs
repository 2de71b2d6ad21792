//! The fast start ([`super::Params::fast_start`]): the part of the image that the front
//! from the seeds is sure to cover, found by a flood fill, so that the level set starts
//! there instead of in the seeds' balls and evolves only across the last voxels.
//!
//! Threshold propagation and geodesic active contours are geometric flows that obey the
//! comparison principle (Evans & Spruck, "Motion of level sets by mean curvature I",
//! J. Differential Geom. 33 (1991); Chen, Giga & Goto, "Uniqueness and existence of
//! viscosity solutions of generalized mean curvature flow equations", ibid.): a region
//! that starts inside another stays inside it. A start C between the seeds S and the
//! flow's steady state S∞ from them (S ⊂ C ⊂ S∞) therefore evolves to S∞ itself, squeezed
//! between the runs from S and from S∞. The fill keeps C inside S∞ by three margins: it
//! only enters voxels where the method's own speed is clearly outward (`confident`); it
//! only passes through openings at least 2r + 1 voxels wide (a morphological opening by
//! reconstruction: Vincent, "Morphological grayscale reconstruction in image analysis",
//! IEEE Trans. Image Process. 2 (1993)), where curvature cannot hold the front; and it
//! stops one voxel short of where the confident voxels end. The stopping tests then end
//! the run as they would from the seeds: a front that still creeps into a thin branch the
//! fill did not enter can meet the volume test sooner than from the seeds (a smaller
//! `volume_change` waits for it).

use rayon::prelude::*;
use std::collections::VecDeque;

/// The opening's least radius r (voxels): the fill passes openings of 2r + 1 voxels and more.
pub(super) const OPENING: usize = 1;

/// The start region (1 inside): the seeds, and every `confident` voxel that the seeds
/// reach through openings of 2r + 1 confident voxels (r ≥ [`OPENING`]), less one voxel at the
/// confident region's edge. `dims` are the image's (an axis of one voxel is not eroded).
pub(super) fn fill(confident: &[u8], seeds: &[u8], dims: [usize; 3], r: usize) -> Vec<u8> {
    let core = morph(confident, dims, r, Op::Erode);
    let mut region = flood(&core, seeds, dims);
    // Back out to the confident region's edge, through the confident voxels only.
    for _ in 0..r {
        region = morph(&region, dims, 1, Op::Dilate);
        region.par_iter_mut().zip(confident).for_each(|(r, &c)| *r &= c);
    }
    let mut start = morph(&region, dims, 1, Op::Erode);
    start.par_iter_mut().zip(seeds).for_each(|(r, &s)| *r |= s);
    start
}

#[derive(Clone, Copy)]
enum Op {
    Erode,
    Dilate,
}

/// Erosion (minimum) or dilation (maximum) over the cube of radius `r` voxels, one axis
/// after another; beyond the image a voxel counts as 0.
fn morph(src: &[u8], dims: [usize; 3], r: usize, op: Op) -> Vec<u8> {
    let mut cur: Option<Vec<u8>> = None;
    for axis in 0..3 {
        if dims[axis] > 1 {
            cur = Some(along(cur.as_deref().unwrap_or(src), dims, r, axis, op));
        }
    }
    cur.unwrap_or_else(|| src.to_vec())
}

fn along(src: &[u8], dims: [usize; 3], r: usize, axis: usize, op: Op) -> Vec<u8> {
    // One instance per operation, so that the loops below compile to vector minima and
    // maxima: with the operation chosen per voxel, this function took 11 % of the samples
    // of a one-step GAC segmentation of a 128³ image on one thread (`perf record` of the
    // whole command, 2-core AMD EPYC, 2026-11-28).
    match op {
        Op::Erode => along_by(src, dims, r, axis, op, u8::min),
        Op::Dilate => along_by(src, dims, r, axis, op, u8::max),
    }
}

fn along_by(
    src: &[u8],
    dims: [usize; 3],
    r: usize,
    axis: usize,
    op: Op,
    combine: impl Fn(u8, u8) -> u8 + Sync,
) -> Vec<u8> {
    let [nx, ny, nz] = dims;
    let mut out = vec![0u8; src.len()];
    out.par_chunks_mut(nx).enumerate().take(ny * nz).for_each(|(row, dst)| {
        let (y, z) = (row % ny, row / ny);
        if axis == 0 {
            // The window as shifted copies of the row, which vectorise.
            let line = &src[row * nx..(row + 1) * nx];
            dst.copy_from_slice(line);
            for o in 1..=r.min(nx.saturating_sub(1)) {
                for (d, &v) in dst[o..].iter_mut().zip(line) {
                    *d = combine(*d, v);
                }
                for (d, &v) in dst.iter_mut().zip(&line[o..]) {
                    *d = combine(*d, v);
                }
            }
            if matches!(op, Op::Erode) {
                // Beyond the image counts as 0: where the window reaches beyond it.
                let edge = r.min(nx);
                dst[..edge].fill(0);
                dst[nx - edge..].fill(0);
            }
            return;
        }
        let (at, n) = if axis == 1 { (y, ny) } else { (z, nz) };
        if matches!(op, Op::Erode) && (at < r || at + r >= n) {
            return; // all 0: the window reaches beyond the image
        }
        let line = |k: usize| {
            let (yy, zz) = if axis == 1 { (k, z) } else { (y, k) };
            let start = nx * (yy + ny * zz);
            &src[start..start + nx]
        };
        dst.copy_from_slice(line(at));
        for k in at.saturating_sub(r)..(at + r + 1).min(n) {
            for (d, &v) in dst.iter_mut().zip(line(k)) {
                *d = combine(*d, v);
            }
        }
    });
    out
}

/// The voxels of `set` 6-connected within it to a voxel of `seeds`.
fn flood(set: &[u8], seeds: &[u8], dims: [usize; 3]) -> Vec<u8> {
    let mut out = vec![0u8; set.len()];
    // The seeds in the set, found in parallel (in index order).
    let first: Vec<usize> = seeds
        .par_iter()
        .zip(set)
        .enumerate()
        .filter(|&(_, (&s, &m))| s != 0 && m != 0)
        .map(|(i, _)| i)
        .collect();
    for &i in &first {
        out[i] = 1;
    }
    let mut queue: VecDeque<usize> = first.into();
    while let Some(i) = queue.pop_front() {
        for j in face_neighbours(i, dims) {
            if set[j] != 0 && out[j] == 0 {
                out[j] = 1;
                queue.push_back(j);
            }
        }
    }
    out
}

/// The voxels that share a face with voxel `i` (x fastest) inside `dims`.
fn face_neighbours(i: usize, dims: [usize; 3]) -> impl Iterator<Item = usize> {
    let [nx, ny, nz] = dims;
    let (x, y, z, plane) = (i % nx, (i / nx) % ny, i / (nx * ny), nx * ny);
    [
        (x > 0, i.wrapping_sub(1)),
        (x + 1 < nx, i + 1),
        (y > 0, i.wrapping_sub(nx)),
        (y + 1 < ny, i + nx),
        (z > 0, i.wrapping_sub(plane)),
        (z + 1 < nz, i + plane),
    ]
    .into_iter()
    .filter_map(|(inside, j)| inside.then_some(j))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(dims: [usize; 3], f: impl Fn(usize, usize, usize) -> bool) -> Vec<u8> {
        let mut v = vec![0u8; dims[0] * dims[1] * dims[2]];
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    v[x + dims[0] * (y + dims[1] * z)] = f(x, y, z) as u8;
                }
            }
        }
        v
    }

    #[test]
    fn every_axis_takes_the_extremum_of_its_window() {
        let dims = [13, 7, 5];
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let src: Vec<u8> = (0..dims.iter().product::<usize>())
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                !state.is_multiple_of(3) as u8
            })
            .collect();
        for axis in 0..3 {
            for r in 0..15 {
                for op in [Op::Erode, Op::Dilate] {
                    let got = along(&src, dims, r, axis, op);
                    let want = cube(dims, |x, y, z| {
                        let p = [x, y, z];
                        let (at, n) = (p[axis], dims[axis]);
                        let window = (at.saturating_sub(r)..(at + r + 1).min(n)).map(|k| {
                            let mut q = p;
                            q[axis] = k;
                            src[q[0] + dims[0] * (q[1] + dims[1] * q[2])]
                        });
                        match op {
                            // Beyond the image counts as 0.
                            Op::Erode => at >= r && at + r < n && window.min() == Some(1),
                            Op::Dilate => window.max() == Some(1),
                        }
                    });
                    assert_eq!(got, want, "axis {axis}, r {r}");
                }
            }
        }
    }

    #[test]
    fn the_fill_stops_at_a_narrow_opening_and_short_of_the_edge() {
        let dims = [40, 20, 20];
        // Two boxes joined by a 3-voxel-wide channel: the fill stays in the seeded box.
        let confident = cube(dims, |x, y, z| {
            let inner = (2..18).contains(&y) && (2..18).contains(&z);
            let channel = (9..12).contains(&y) && (9..12).contains(&z);
            inner && ((2..18).contains(&x) || (22..38).contains(&x) || channel)
        });
        let seeds = cube(dims, |x, y, z| x == 10 && y == 10 && z == 10);
        let start = fill(&confident, &seeds, dims, 2);
        let at = |x: usize, y: usize, z: usize| start[x + 40 * (y + 20 * z)];
        assert_eq!(at(5, 5, 5), 1);
        assert_eq!(at(30, 10, 10), 0, "the fill passed a 3-voxel channel at r = 2");
        assert_eq!(fill(&confident, &seeds, dims, 1)[30 + 40 * (10 + 20 * 10)], 1);
        // One voxel short of the confident region's edge, nothing outside it.
        assert_eq!(at(3, 10, 10), 1);
        assert_eq!(at(2, 10, 10), 0);
        assert!(start.iter().zip(&confident).all(|(&s, &c)| s <= c || s == 0));
        // A 5-voxel channel is wide enough at r = 2.
        let wide = cube(dims, |x, y, z| {
            let inner = (2..18).contains(&y) && (2..18).contains(&z);
            let channel = (8..13).contains(&y) && (8..13).contains(&z);
            inner && ((2..18).contains(&x) || (22..38).contains(&x) || channel)
        });
        assert_eq!(fill(&wide, &seeds, dims, 2)[30 + 40 * (10 + 20 * 10)], 1);
    }

    #[test]
    fn seeds_outside_the_confident_voxels_are_kept_and_fill_nothing() {
        let dims = [16, 16, 1];
        let confident = vec![0u8; 256];
        let seeds = cube(dims, |x, y, _| x == 8 && y == 8);
        assert_eq!(fill(&confident, &seeds, dims, OPENING), seeds);
    }
}
