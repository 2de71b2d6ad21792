//! Dilation (paper Sec. 3.6.1, Appendices E and F) and rebuild (Sec. 3.6.2).

use super::iter::{ColCursor, Cursor, Step};
use super::{DtGrid, IndexPair, MAX_POINTS};
use crate::grid::GridError;

/// Appends component `[s, e]` to a level under construction (`acc` keeps its sentinel).
#[inline]
fn emit(nc: &mut Vec<i32>, acc: &mut Vec<u32>, s: i64, e: i64) -> Result<(), GridError> {
    let total = acc[acc.len() - 1] as u64 + (e - s + 1) as u64;
    if total > MAX_POINTS as u64 {
        return Err(GridError::InvalidParameter(format!(
            "the dilated DT-Grid would exceed {MAX_POINTS} points"
        )));
    }
    // The caller checked the dilated bounding box, so s and e fit in i32.
    nc.push(s as i32);
    nc.push(e as i32);
    acc.push(total as u32);
    Ok(())
}

/// The Column Union of Appendix F: `runs` holds the components of every p-column touched
/// by the box, each column's components sorted but the columns concatenated. Each
/// component is widened by `h` on both sides; their union (adjacent runs merged) is
/// appended to a new p-column.
///
/// The paper merges the columns by scanning them simultaneously, counting open
/// components. We sort the gathered list by start instead and sweep once: with n
/// components from k columns that is O(n log n) against the scan's O(n k), and since a
/// band's p-columns hold one or two components, n is about k and the sort stays in its
/// small-input regime (O(n) for input that is already sorted, e.g. a single column).
#[inline]
fn union_into(
    runs: &mut [[i32; 2]],
    h: i64,
    nc: &mut Vec<i32>,
    acc: &mut Vec<u32>,
) -> Result<(), GridError> {
    debug_assert!(!runs.is_empty());
    runs.sort_unstable_by_key(|r| r[0]);
    let (mut s, mut e) = (runs[0][0] as i64, runs[0][1] as i64);
    for r in &runs[1..] {
        let (rs, re) = (r[0] as i64, r[1] as i64);
        // Widened: [rs - h, re + h] joins [s - h, e + h] when rs - h <= e + h + 1.
        if rs <= e + 2 * h + 1 {
            e = e.max(re);
        } else {
            emit(nc, acc, s - h, e + h)?;
            (s, e) = (rs, re);
        }
    }
    emit(nc, acc, s - h, e + h)
}

/// Position in one p-column of a lower level, moved forward to coordinate targets.
#[derive(Clone, Copy, Debug)]
struct RunCursor {
    c: usize,
    hi: usize,
}

impl RunCursor {
    /// Value index of the first point of the column at or after coordinate `t`
    /// (the column's end index when there is none). Monotone in `t`.
    #[inline]
    fn seek(&mut self, nc: &[i32], acc: &[u32], t: i64) -> usize {
        while self.c < self.hi && (nc[self.c + 1] as i64) < t {
            self.c += 2;
        }
        let first = acc[self.c / 2] as usize;
        if self.c < self.hi {
            first + (t - nc[self.c] as i64).max(0) as usize
        } else {
            first
        }
    }
}

/// The window of one original z column during the 3D allocation: points with y in
/// `[y - h, y + h]` lie between the two cursors (the "entering" and "exiting" iterators
/// of Appendix F, step 3).
#[derive(Clone, Copy, Debug)]
struct Slot {
    enter: RunCursor,
    exit: RunCursor,
}

impl DtGrid {
    /// The grid dilated by `h` voxels with a (2h+1)³ box (Sec. 3.6.1): every voxel within
    /// Chebyshev distance `h` of a stored point. Stored points keep their values; new
    /// points read `±γ` by the sign rule of the [module docs](super), evaluated on this
    /// grid while copying. O(C) allocation + O(M) copy.
    ///
    /// [`GridError::OutOfRange`] (naming a stored point whose box leaves i32) when a
    /// coordinate would leave i32; [`GridError::InvalidParameter`] beyond
    /// [`MAX_POINTS`].
    pub fn dilate(&self, h: u32) -> Result<DtGrid, GridError> {
        let mut out = DtGrid::new(self.spec);
        self.dilate_into(h, &mut out)?;
        Ok(out)
    }

    /// [`DtGrid::dilate`] into `out`, reusing its allocations. `out` takes this grid's
    /// spec; on error it is left empty.
    pub fn dilate_into(&self, h: u32, out: &mut DtGrid) -> Result<(), GridError> {
        out.clear();
        out.spec = self.spec;
        out.gamma = self.gamma;
        if self.is_empty() {
            return Ok(());
        }
        self.check_dilation_range(h)?;
        if let Err(e) = self.allocate_dilated(h as i64, out) {
            out.clear();
            return Err(e);
        }
        self.copy_into_dilated(out);
        debug_assert_eq!(out.check_invariants(), Ok(()));
        Ok(())
    }

    /// Rebuild (Sec. 3.6.2): keep the points with `|φ| < keep_below` (step 1), dilate them
    /// by `h` (step 2); every point the dilation adds reads `±γ` (step 3; the paper uses
    /// `±δ`, we keep the grid's one background magnitude), including points of this grid
    /// that step 1 dropped. Signs come from the sign rule evaluated on the kept points,
    /// which is exact on a signed distance field when `keep_below` exceeds the voxel
    /// size. O(M). Errors as [`DtGrid::dilate`], and [`GridError::InvalidParameter`] for
    /// a NaN `keep_below`.
    pub fn rebuild(&self, keep_below: f32, h: u32) -> Result<DtGrid, GridError> {
        let mut kept = DtGrid::new(self.spec);
        let mut out = DtGrid::new(self.spec);
        self.rebuild_into(keep_below, h, &mut kept, &mut out)?;
        Ok(out)
    }

    /// [`DtGrid::rebuild`] reusing two grids: `kept` receives the intermediate grid of
    /// step 1, `out` the result.
    pub fn rebuild_into(
        &self,
        keep_below: f32,
        h: u32,
        kept: &mut DtGrid,
        out: &mut DtGrid,
    ) -> Result<(), GridError> {
        if keep_below.is_nan() {
            return Err(GridError::InvalidParameter("keep_below is NaN".into()));
        }
        self.retain_into(keep_below, kept);
        kept.dilate_into(h, out)
    }

    /// Step 1 of Sec. 3.6.2: copies the points with `|φ| < keep_below` into `out`.
    fn retain_into(&self, keep_below: f32, out: &mut DtGrid) {
        out.clear();
        out.spec = self.spec;
        out.gamma = self.gamma;
        let Some(mut cur) = Cursor::first(self) else { return };
        let vals = &self.l3.value;
        loop {
            let v = vals[cur.iv];
            if v.abs() < keep_below {
                out.push_sorted(cur.coord(), v);
            }
            if cur.advance(self) == Step::End {
                break;
            }
        }
    }

    /// Fails when the bounding box widened by `h` leaves i32.
    fn check_dilation_range(&self, h: u32) -> Result<(), GridError> {
        let Some((lo, hi)) = self.bounding_box() else { return Ok(()) };
        let h = h as i64;
        let fits = |c: crate::Coord| {
            [c.x, c.y, c.z]
                .iter()
                .all(|&v| v as i64 - h >= i32::MIN as i64 && v as i64 + h <= i32::MAX as i64)
        };
        if fits(lo) && fits(hi) {
            return Ok(());
        }
        let bad = self.iter().map(|(c, _)| c).find(|&c| !fits(c)).unwrap_or(lo);
        Err(GridError::OutOfRange { coord: bad })
    }

    /// The allocation step (Appendices E and F): builds the `ncoord`, `acc` and
    /// `IndexPair` arrays of all three levels of `out`, from components only.
    fn allocate_dilated(&self, h: i64, out: &mut DtGrid) -> Result<(), GridError> {
        let (o1, o2, o3) = (&self.l1, &self.l2, &self.l3);
        // `out` is cleared: drop its empty-grid sentinels, the pairs are rebuilt below.
        out.l1.value.clear();
        out.l2.value.clear();

        // Appendix E: widen the z components by h and merge those that touch.
        {
            let nc = &o1.ncoord;
            let (mut s, mut e) = (nc[0] as i64 - h, nc[1] as i64 + h);
            for r in nc[2..].as_chunks::<2>().0 {
                let (rs, re) = (r[0] as i64 - h, r[1] as i64 + h);
                if rs <= e + 1 {
                    e = re;
                } else {
                    emit(&mut out.l1.ncoord, &mut out.l1.acc, s, e)?;
                    (s, e) = (rs, re);
                }
            }
            emit(&mut out.l1.ncoord, &mut out.l1.acc, s, e)?;
        }
        out.l1.value.reserve(out.l1.points() + 1);

        // Appendix F for the 2D and the 3D level, interleaved per new z: the new z column
        // of the 2D level is the union of the original z columns z-h..=z+h (a contiguous
        // run of the original 1D points, between two cursors); then each new p-column
        // (z, y) is the union of the original p-columns in the (2h+1)² window, found per
        // original z column by a pair of cursors over its y components.
        let mut runs: Vec<[i32; 2]> = Vec::new();
        let mut slots: Vec<Slot> = Vec::new();
        let mut z_enter = RunCursor { c: 0, hi: o1.ncoord.len() };
        let mut z_exit = z_enter;
        let n1 = out.l1.ncoord.len();
        for kz in (0..n1).step_by(2) {
            let (zs, ze) = (out.l1.ncoord[kz], out.l1.ncoord[kz + 1]);
            for z in zs..=ze {
                let z = z as i64;
                let a = z_enter.seek(&o1.ncoord, &o1.acc, z - h);
                let b = z_exit.seek(&o1.ncoord, &o1.acc, z + h + 1);
                debug_assert!(a < b);
                out.l1
                    .value
                    .push(IndexPair { iv: out.l2.points() as u32, ic: out.l2.ncoord.len() as u32 });
                // 2D: the original z columns a..b occupy one contiguous ncoord range.
                let (r0, r1) = (o1.value[a].ic as usize, o1.value[b].ic as usize);
                runs.clear();
                runs.extend_from_slice(o2.ncoord[r0..r1].as_chunks::<2>().0);
                let first_new = out.l2.ncoord.len();
                union_into(&mut runs, h, &mut out.l2.ncoord, &mut out.l2.acc)?;

                // 3D: one slot per original z column in the window.
                slots.clear();
                slots.extend((a..b).map(|i| {
                    let cur =
                        RunCursor { c: o1.value[i].ic as usize, hi: o1.value[i + 1].ic as usize };
                    Slot { enter: cur, exit: cur }
                }));
                for ky in (first_new..out.l2.ncoord.len()).step_by(2) {
                    let (ys, ye) = (out.l2.ncoord[ky], out.l2.ncoord[ky + 1]);
                    for y in ys..=ye {
                        let y = y as i64;
                        out.l2.value.push(IndexPair {
                            iv: out.l3.points() as u32,
                            ic: out.l3.ncoord.len() as u32,
                        });
                        runs.clear();
                        for slot in &mut slots {
                            let a2 = slot.enter.seek(&o2.ncoord, &o2.acc, y - h);
                            let b2 = slot.exit.seek(&o2.ncoord, &o2.acc, y + h + 1);
                            if a2 < b2 {
                                // The p-columns a2..b2 occupy one contiguous ncoord range.
                                let (r0, r1) = (o2.value[a2].ic as usize, o2.value[b2].ic as usize);
                                runs.extend_from_slice(o3.ncoord[r0..r1].as_chunks::<2>().0);
                            }
                        }
                        union_into(&mut runs, h, &mut out.l3.ncoord, &mut out.l3.acc)?;
                    }
                }
            }
        }
        out.l1.value.push(IndexPair { iv: out.l2.points() as u32, ic: out.l2.ncoord.len() as u32 });
        out.l2.value.push(IndexPair { iv: out.l3.points() as u32, ic: out.l3.ncoord.len() as u32 });
        Ok(())
    }

    /// The copy step: walks the new p-columns in order next to the original ones (a
    /// subset of them). Original runs are copied; the voxels around them are filled with
    /// `±γ` by the sign rule (the column's first value before its first run, else the
    /// last value of the run before); new p-columns are filled with `+γ`. O(M).
    fn copy_into_dilated(&self, out: &mut DtGrid) {
        let mut vals = std::mem::take(&mut out.l3.value);
        vals.clear();
        vals.reserve_exact(out.l3.points());
        let gamma = self.gamma;
        let bg = |v: f32| if v < 0.0 { -gamma } else { gamma };
        let (onc, oacc, ovals) = (&self.l3.ncoord, &self.l3.acc, &self.l3.value);
        let (nnc, nacc) = (&out.l3.ncoord, &out.l3.acc);
        let mut old = ColCursor::first(self);
        let mut new = ColCursor::first(out).expect("a dilated non-empty grid is non-empty");
        loop {
            let (lo, hi) = (out.l2.value[new.i2].ic as usize, out.l2.value[new.i2 + 1].ic as usize);
            match old.as_mut() {
                Some(o) if o.z == new.z && o.y == new.y => {
                    let (olo, ohi) =
                        (self.l2.value[o.i2].ic as usize, self.l2.value[o.i2 + 1].ic as usize);
                    let mut k = olo;
                    let mut fill = bg(ovals[oacc[olo / 2] as usize]);
                    for kn in (lo..hi).step_by(2) {
                        let (s, e) = (nnc[kn] as i64, nnc[kn + 1] as i64);
                        let mut x = s;
                        // Every original run lies inside exactly one new run.
                        while k < ohi && onc[k] as i64 <= e {
                            let (a, b) = (oacc[k / 2] as usize, oacc[k / 2 + 1] as usize);
                            vals.resize(vals.len() + (onc[k] as i64 - x) as usize, fill);
                            vals.extend_from_slice(&ovals[a..b]);
                            fill = bg(ovals[b - 1]);
                            x = onc[k + 1] as i64 + 1;
                            k += 2;
                        }
                        vals.resize(vals.len() + (e + 1 - x) as usize, fill);
                    }
                    if !o.advance(self) {
                        old = None;
                    }
                }
                _ => {
                    let n = (nacc[hi / 2] - nacc[lo / 2]) as usize;
                    vals.resize(vals.len() + n, gamma);
                }
            }
            if !new.advance(out) {
                break;
            }
        }
        debug_assert_eq!(vals.len(), out.l3.points());
        out.l3.value = vals;
    }
}
