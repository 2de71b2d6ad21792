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

/// The opening's least radius r (voxels): the fill passes openings of 2r + 1 voxels and more.
pub(super) const OPENING: usize = 1;

/// The start region (1 inside): the seeds, and every `confident` voxel that the seeds
/// reach through openings of 2r + 1 confident voxels (r ≥ [`OPENING`]), less one voxel at the
/// confident region's edge. `dims` are the image's (an axis of one voxel is not eroded).
pub(super) fn fill(confident: &[u8], seeds: &[u8], dims: [usize; 3], r: usize) -> Vec<u8> {
    let mut masks = Masks { len: confident.len(), free: Vec::new() };
    let core = morph(confident, dims, r, Op::Erode, &mut masks);
    let mut region = masks.take();
    flood(&core, seeds, dims, &mut region);
    masks.give(core);
    // Back out to the confident region's edge, through the confident voxels only.
    for _ in 0..r {
        let wider = morph(&region, dims, 1, Op::Dilate, &mut masks);
        masks.give(std::mem::replace(&mut region, wider));
        region.par_iter_mut().zip(confident).for_each(|(r, &c)| *r &= c);
    }
    let mut start = morph(&region, dims, 1, Op::Erode, &mut masks);
    start.par_iter_mut().zip(seeds).for_each(|(r, &s)| *r |= s);
    start
}

/// Masks of the image's length, reused from pass to pass: a fresh one is faulted in by the
/// pass that fills it, and a 2 MiB mask (128³) in a transparent huge page is zeroed by the
/// one thread that touches it first. Every pass writes all of its output, so a reused mask
/// needs no clearing. With a fresh mask for each pass, and a queue of voxels for the flood,
/// the fill took 8.9 ms on one thread and 7.6 ms on two; this way, with [`flood`]'s runs,
/// 7.7 and 5.9 ms (second generator's blobs 128³, threshold method; medians of 10
/// alternated runs of each build, phase timers in a scratch build; on its torus 10.7 / 7.3
/// against 9.7 / 5.3 ms in 6 runs; the same masks; 2-core Intel Xeon VM, 2026-12-03).
struct Masks {
    len: usize,
    free: Vec<Vec<u8>>,
}

impl Masks {
    fn take(&mut self) -> Vec<u8> {
        self.free.pop().unwrap_or_else(|| vec![0; self.len])
    }

    fn give(&mut self, mask: Vec<u8>) {
        self.free.push(mask);
    }
}

#[derive(Clone, Copy)]
enum Op {
    Erode,
    Dilate,
}

/// Binary erosion (dilation) of `src` by a cube of radius `r` voxels, one axis at a time;
/// beyond the image counts as 0. Axes of one voxel are left alone.
fn morph(src: &[u8], dims: [usize; 3], r: usize, op: Op, masks: &mut Masks) -> Vec<u8> {
    let mut cur: Option<Vec<u8>> = None;
    for axis in 0..3 {
        if dims[axis] > 1 {
            let mut out = masks.take();
            along(cur.as_deref().unwrap_or(src), &mut out, dims, r, axis, op);
            if let Some(used) = cur.replace(out) {
                masks.give(used);
            }
        }
    }
    cur.unwrap_or_else(|| {
        let mut copy = masks.take();
        copy.copy_from_slice(src);
        copy
    })
}

/// The window's minimum (erosion) or maximum (dilation) along `axis`, into `out` (every
/// value written).
fn along(src: &[u8], out: &mut [u8], dims: [usize; 3], r: usize, axis: usize, op: Op) {
    // One instance per operation, so that the loops below compile to vector minima and
    // maxima: with the operation chosen per voxel, this function took 11 % of the samples
    // of a one-step GAC segmentation of a 128³ image on one thread (`perf record` of the
    // whole command, 2-core AMD EPYC, 2026-11-28).
    match op {
        Op::Erode => along_by(src, out, dims, r, axis, op, u8::min),
        Op::Dilate => along_by(src, out, dims, r, axis, op, u8::max),
    }
}

fn along_by(
    src: &[u8],
    out: &mut [u8],
    dims: [usize; 3],
    r: usize,
    axis: usize,
    op: Op,
    combine: impl Fn(u8, u8) -> u8 + Sync,
) {
    let [nx, ny, nz] = dims;
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
            dst.fill(0); // the window reaches beyond the image
            return;
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
}

/// The voxels of `set` connected to a seed voxel in `set` through faces, as 1 in `out`
/// (every value written). The component does not depend on the order it is found in: it is
/// filled a run along x at a time, from a stack of voxels to start runs at, and each run
/// pushes the first open voxel of every open run beside it in the rows next along y and z
/// (no division per voxel).
fn flood(set: &[u8], seeds: &[u8], dims: [usize; 3], out: &mut [u8]) {
    let [nx, ny, nz] = dims;
    out.par_iter_mut().for_each(|v| *v = 0);
    // The seeds in the set, found in parallel (in index order).
    let mut stack: Vec<usize> = seeds
        .par_iter()
        .zip(set)
        .enumerate()
        .filter(|&(_, (&s, &m))| s != 0 && m != 0)
        .map(|(i, _)| i)
        .collect();
    let open = |out: &[u8], i: usize| set[i] != 0 && out[i] == 0;
    let plane = nx * ny;
    while let Some(i) = stack.pop() {
        if !open(out, i) {
            continue;
        }
        let row = i / nx;
        let (first, end) = (row * nx, (row + 1) * nx);
        let (mut a, mut b) = (i, i + 1);
        while a > first && open(out, a - 1) {
            a -= 1;
        }
        while b < end && open(out, b) {
            b += 1;
        }
        out[a..b].fill(1);
        let (y, z) = (row % ny, row / ny);
        let beside = [
            (y > 0).then(|| a - nx),
            (y + 1 < ny).then(|| a + nx),
            (z > 0).then(|| a - plane),
            (z + 1 < nz).then(|| a + plane),
        ];
        for start in beside.into_iter().flatten() {
            let mut inside = false;
            for j in start..start + (b - a) {
                let o = open(out, j);
                if o && !inside {
                    stack.push(j);
                }
                inside = o;
            }
        }
    }
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
                    // A used mask: every value must be written.
                    let mut got = vec![7u8; src.len()];
                    along(&src, &mut got, dims, r, axis, op);
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

    /// The face-connected component of `set` from the seeds in it, a voxel at a time from
    /// a queue: the reference the run-by-run flood must equal.
    fn flood_by_voxels(set: &[u8], seeds: &[u8], dims: [usize; 3]) -> Vec<u8> {
        let [nx, ny, _] = dims;
        let mut out = vec![0u8; set.len()];
        let mut queue = std::collections::VecDeque::new();
        for i in 0..set.len() {
            if seeds[i] != 0 && set[i] != 0 {
                out[i] = 1;
                queue.push_back(i);
            }
        }
        while let Some(i) = queue.pop_front() {
            let at = [i % nx, (i / nx) % ny, i / (nx * ny)];
            for (axis, stride) in [(0, 1), (1, nx), (2, nx * ny)] {
                let below = (at[axis] > 0).then(|| i - stride);
                let above = (at[axis] + 1 < dims[axis]).then_some(i + stride);
                for j in below.into_iter().chain(above) {
                    if set[j] != 0 && out[j] == 0 {
                        out[j] = 1;
                        queue.push_back(j);
                    }
                }
            }
        }
        out
    }

    #[test]
    fn the_flood_is_the_seeds_face_connected_component() {
        let mut rng = fastrand::Rng::with_seed(0x2545_f491);
        for dims in [[13, 7, 5], [1, 9, 9], [9, 1, 9], [20, 1, 1], [6, 6, 6], [31, 17, 3]] {
            let n = dims.iter().product::<usize>();
            // Dense sets (long runs that join), sparse ones (many small pieces), all or none.
            for fill_in in [0u32, 3, 5, 7, 9, 10] {
                let set: Vec<u8> = (0..n).map(|_| (rng.u32(0..10) < fill_in) as u8).collect();
                let seeds: Vec<u8> = (0..n).map(|_| (rng.u32(0..23) == 0) as u8).collect();
                let mut got = vec![9u8; n];
                flood(&set, &seeds, dims, &mut got);
                assert_eq!(got, flood_by_voxels(&set, &seeds, dims), "{dims:?}, {fill_in}/10");
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
