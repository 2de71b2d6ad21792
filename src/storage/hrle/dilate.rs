//! Rebuilding the H-RLE level set (Sec. 5.4): pruning voxels far from the interface,
//! dilation in linear time, and clipping to a box (Sec. 6.5, Fig. 9). Each returns a new
//! grid and leaves `self` as it was; fields follow their voxels.

use super::build::LevelSetSigns;
use super::stencil::RunCursor;
use super::{in_box, Builder, HrleGrid, COORD_RANGE, POS};
use crate::coord::Coord;
use crate::grid::GridError;

/// Sorts half-open intervals and merges the overlapping or touching ones.
fn merge(iv: &mut Vec<(i64, i64)>) {
    iv.sort_unstable();
    let mut out = 0;
    for k in 0..iv.len() {
        if out > 0 && iv[k].0 <= iv[out - 1].1 {
            iv[out - 1].1 = iv[out - 1].1.max(iv[k].1);
        } else {
            iv[out] = iv[k];
            out += 1;
        }
    }
    iv.truncate(out);
}

/// Pushes the defined runs of segment `s` of `block`, widened by `n` on each side.
fn widened_runs(block: &super::Block, s: usize, n: i64, out: &mut Vec<(i64, i64)>) {
    let (codes, breaks) = block.segment(s);
    for r in 1..codes.len().saturating_sub(1) {
        if codes[r] < POS {
            out.push((breaks[r - 1] as i64 - n, breaks[r] as i64 + n));
        }
    }
}

impl HrleGrid {
    /// A new grid over voxels `emit` produces in [`Coord`] order (with the index of the
    /// same voxel in `self`, if stored), signed by `self` and read at `rep` for columns
    /// and planes without stored voxels.
    fn derive(
        &self,
        rep: Coord,
        domain: Option<(Coord, Coord)>,
        emit: impl FnOnce(
            &mut dyn FnMut(Coord, f32, Option<u32>) -> Result<(), GridError>,
        ) -> Result<(), GridError>,
    ) -> Result<HrleGrid, GridError> {
        let mut b =
            Builder::with_capacity(self.spec, LevelSetSigns::of_hrle(self, rep), self.values.len());
        let keep_map = !self.fields.is_empty();
        let mut map: Vec<Option<u32>> = Vec::new();
        emit(&mut |c, v, old| {
            b.push(c, v)?;
            if keep_map {
                map.push(old);
            }
            Ok(())
        })?;
        let fields = self.fields.iter().map(|f| f.gather(&map)).collect();
        Ok(b.finish_with(domain, fields))
    }

    fn rep(&self) -> Coord {
        self.bbox.map(|b| b.0).or(self.domain.map(|d| d.0)).unwrap_or_default()
    }

    /// Keeps the stored voxels with `−inner < φ < outer` (world units): the first step of
    /// a rebuild (Sec. 5.4), and an asymmetric band when `inner ≠ outer`. Both widths
    /// must be at least one voxel so that every zero crossing keeps its voxels.
    pub fn prune(&self, inner: f32, outer: f32) -> Result<HrleGrid, GridError> {
        let h = self.spec.voxel_size;
        for (name, w) in [("inner", inner), ("outer", outer)] {
            if !(w.is_finite() && w >= h) {
                return Err(GridError::InvalidParameter(format!(
                    "the {name} band width must be finite and at least one voxel ({h}), got {w}"
                )));
            }
        }
        self.derive(self.rep(), self.domain, |push| {
            let mut r = Ok(());
            self.for_each_defined(|c, i| {
                let v = self.values[i];
                if r.is_ok() && -inner < v && v < outer {
                    r = push(c, v, Some(i as u32));
                }
            });
            r
        })
    }

    /// Adds every voxel within `n` voxels (in the max norm: the hypercube stencil of
    /// Sec. 5.4) of a stored one, inside the domain; new voxels hold `±γ` with the sign
    /// this grid reads there, ready for a reinitialisation. O(D) for a fixed `n`: each
    /// output column is the union of the widened runs of the (2n + 1)² input columns
    /// around it, and each output plane the union of the widened y-runs of the 2n + 1
    /// input planes around it (Sec. 5.4, steps 1–3).
    pub fn dilate(&self, n: u32) -> Result<HrleGrid, GridError> {
        if n == 0 {
            return Ok(self.clone());
        }
        let n = n as i64;
        let [bz, by, _] = &self.blocks;
        let mut planes: Vec<(i64, usize)> = Vec::new();
        super::for_each_element(bz, 0, |z, ys| planes.push((z as i64, ys as usize)));
        let (dlo, dhi) = self.domain.map_or(([i64::MIN / 4; 3], [i64::MAX / 4; 3]), |(lo, hi)| {
            ([lo.x as i64, lo.y as i64, lo.z as i64], [hi.x as i64, hi.y as i64, hi.z as i64])
        });
        let range_err = |x: i64, y: i64, z: i64| {
            let clamp = |v: i64| v.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
            GridError::OutOfRange { coord: Coord::new(clamp(x), clamp(y), clamp(z)) }
        };
        let mut zint: Vec<(i64, i64)> = planes.iter().map(|&(z, _)| (z - n, z + 1 + n)).collect();
        merge(&mut zint);
        self.derive(self.rep(), self.domain, |push| {
            let mut yint = Vec::new();
            let mut xint = Vec::new();
            let mut first = 0usize; // first plane with z ≥ current z − n
            let mut scratch = 0u32;
            for &(za, zb) in &zint {
                for z in za.max(dlo[2])..zb.min(dhi[2] + 1) {
                    if !COORD_RANGE.contains(&(z as i32)) || z != z as i32 as i64 {
                        return Err(range_err(0, 0, z));
                    }
                    while first < planes.len() && planes[first].0 < z - n {
                        first += 1;
                    }
                    let window = planes[first..].iter().take_while(|p| p.0 <= z + n);
                    yint.clear();
                    for &(_, ys) in window.clone() {
                        widened_runs(by, ys, n, &mut yint);
                    }
                    merge(&mut yint);
                    for &(ya, yb) in &yint {
                        for y in ya.max(dlo[1])..yb.min(dhi[1] + 1) {
                            if !COORD_RANGE.contains(&(y as i32)) || y != y as i32 as i64 {
                                return Err(range_err(0, y, z));
                            }
                            xint.clear();
                            for &(_, ys) in window.clone() {
                                for dy in -n..=n {
                                    let q = y + dy;
                                    if q < i32::MIN as i64 || q > i32::MAX as i64 {
                                        continue;
                                    }
                                    let xs = by.lookup(ys, q as i32);
                                    if xs < POS {
                                        widened_runs(&self.blocks[2], xs as usize, n, &mut xint);
                                    }
                                }
                            }
                            merge(&mut xint);
                            let (zi, yi) = (z as i32, y as i32);
                            let mut cur: RunCursor = self.column_cursor(zi, yi, &mut scratch);
                            for &(xa, xb) in &xint {
                                let (xa, xb) = (xa.max(dlo[0]), xb.min(dhi[0] + 1));
                                if xa < *COORD_RANGE.start() as i64
                                    || xb > *COORD_RANGE.end() as i64 + 1
                                {
                                    return Err(range_err(xa.min(xb), y, z));
                                }
                                for x in xa as i32..xb as i32 {
                                    let code = cur.at(x);
                                    let old = (code < POS).then_some(code);
                                    push(Coord::new(x, yi, zi), self.read(code), old)?;
                                }
                            }
                        }
                    }
                }
            }
            Ok(())
        })
    }

    /// Rebuilds the band after the interface moved (Sec. 5.4): [`HrleGrid::prune`] to
    /// `(−inner, outer)`, then [`HrleGrid::dilate`] by one voxel.
    pub fn rebuild(&self, inner: f32, outer: f32) -> Result<HrleGrid, GridError> {
        self.prune(inner, outer)?.dilate(1)
    }

    /// The level set restricted to the inclusive box `lo..=hi` (Sec. 6.5, Fig. 9): the
    /// stored voxels inside it are kept, and every voxel outside it reads `+γ`. The
    /// surface stays open along the box: no voxel is added on the cut.
    pub fn clip(&self, lo: Coord, hi: Coord) -> Result<HrleGrid, GridError> {
        let (lo, hi) = match self.domain {
            None => (lo, hi),
            Some((a, b)) => (
                Coord::new(lo.x.max(a.x), lo.y.max(a.y), lo.z.max(a.z)),
                Coord::new(hi.x.min(b.x), hi.y.min(b.y), hi.z.min(b.z)),
            ),
        };
        if lo.x > hi.x || lo.y > hi.y || lo.z > hi.z {
            return Err(GridError::InvalidParameter(format!("the clip box {lo}..{hi} is empty")));
        }
        self.derive(lo, Some((lo, hi)), |push| {
            let mut r = Ok(());
            self.for_each_defined(|c, i| {
                if r.is_ok() && in_box(c, lo, hi) {
                    r = push(c, self.values[i], Some(i as u32));
                }
            });
            r
        })
    }
}
