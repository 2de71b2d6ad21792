//! The DT-Grid engine: the stencil iterator (Nielsen & Museth 2006, Sec. 3.3) feeds the kernels
//! point by point, scalar and on one thread; after each step the grid is rebuilt
//! (Sec. 3.6.2) to the voxels within one voxel of the band, so it needs no band mask.

use super::{
    growth_bytes, kappa_terms, resize_exact, vec_bytes, MemoryBudget, Representation, Undo,
};
use crate::coord::Coord;
use crate::evolve::dispatch::{
    dispatch, dispatch_anchor, dispatch_renorm, one_value, Halo, PointWindow, Reach, RenormParams,
    StageParams, Sweep,
};
use crate::evolve::field::{ScalarFn, VectorFn};
use crate::evolve::{EvolveError, SpatialScheme, StepKeeps};
use crate::exact::ExactSum;
use crate::grid::GridSpec;
use crate::storage::dtgrid::{DtGrid, Stencil, StencilIter};
use levelset_kernels::{BoxWindow, Lane, LaneFn, VoxelKernel, BOX27_OFFSETS, BOX_FAR39_OFFSETS};
use std::ops::Range;

/// The DT-Grid engine.
///
/// # Invariants
/// While a step is in progress, `undo` names the buffer holding φⁿ (in the point order of
/// the grid before the step), and `next` holds that grid when `rebuilt` is set (the
/// rebuild swapped it out).
#[derive(Clone)]
pub(crate) struct DtRep {
    pub grid: DtGrid,
    phi_n: Vec<f32>,
    out: Vec<f32>,
    /// The renormalisation's anchors of φ⁰.
    anchor: Vec<f32>,
    kept: DtGrid,
    next: DtGrid,
    box27: Stencil,
    box_far39: Stencil,
    undo: Undo,
    rebuilt: bool,
}

fn stencil_of(offsets: &[[i32; 3]]) -> Stencil {
    Stencil::new(offsets.iter().map(|o| Coord::new(o[0], o[1], o[2])).collect())
        .expect("non-empty stencil")
}

impl DtRep {
    /// Bytes the value buffers (double buffer, and φⁿ with `keeps_phi_n`) have to allocate
    /// to serve `points` points.
    fn buffer_growth(&self, points: usize, keeps_phi_n: bool, anchors: bool) -> u64 {
        growth_bytes(&self.out, points)
            + if keeps_phi_n { growth_bytes(&self.phi_n, points) } else { 0 }
            + if anchors { growth_bytes(&self.anchor, points) } else { 0 }
    }

    pub fn new(grid: DtGrid) -> Self {
        let spec = grid.spec();
        DtRep {
            grid,
            phi_n: Vec::new(),
            out: Vec::new(),
            anchor: Vec::new(),
            kept: DtGrid::new(spec),
            next: DtGrid::new(spec),
            box27: stencil_of(&BOX27_OFFSETS),
            box_far39: stencil_of(&BOX_FAR39_OFFSETS),
            undo: Undo::Nothing,
            rebuilt: false,
        }
    }
}

struct DtSweep<'a> {
    rep: &'a DtRep,
    out: &'a mut Vec<f32>,
}

impl Sweep for DtSweep<'_> {
    fn run<K, M, const R: usize>(self, make: M) -> Result<(), EvolveError>
    where
        K: VoxelKernel,
        M: Fn(Range<usize>) -> K + Sync,
        Halo<R>: Reach,
    {
        let n = self.rep.grid.len();
        let k = make(0..n);
        k.check(n)?;
        self.out.clear();
        resize_exact(self.out, n, 0.0);
        let out = &mut self.out[..];
        let stencil = match <Halo<R> as Reach>::WINDOW {
            PointWindow::Box27 => &self.rep.box27,
            PointWindow::BoxFar39 => &self.rep.box_far39,
        };
        let sweep = DtLoop::<K, R> { grid: &self.rep.grid, stencil, kernel: &k, out };
        levelset_kernels::dispatch_one(sweep);
        Ok(())
    }
}

/// The DT-Grid's voxel loop, run at the CPU's level with its one-voxel lane type.
struct DtLoop<'a, K, const R: usize> {
    grid: &'a DtGrid,
    stencil: &'a Stencil,
    kernel: &'a K,
    out: &'a mut [f32],
}

impl<K: VoxelKernel, const R: usize> LaneFn for DtLoop<'_, K, R>
where
    Halo<R>: Reach,
{
    type Output = ();
    #[inline(always)]
    fn call<L: Lane>(self) {
        let mut it = StencilIter::new(self.grid, self.stencil);
        while it.advance() {
            let i = it.center_index();
            self.out[i] = <Halo<R> as Reach>::eval::<L, K>(self.kernel, it.values(), i);
        }
    }
}

/// The DT-Grid's κ̄ integrands, summed, at the CPU's level.
struct DtKappa<'a> {
    grid: &'a DtGrid,
    box27: &'a Stencil,
    inv_h: f32,
    width: f32,
}

impl LaneFn for DtKappa<'_> {
    type Output = (ExactSum, ExactSum);
    #[inline(always)]
    fn call<L: Lane>(self) -> (ExactSum, ExactSum) {
        let (mut num, mut den) = (ExactSum::default(), ExactSum::default());
        let mut it = StencilIter::new(self.grid, self.box27);
        while it.advance() {
            let v: &[f32; 27] = it.values().try_into().expect("27 values");
            let (a, b) = kappa_terms::<L, _>(&BoxWindow::new(v), self.inv_h, self.width);
            num.add(one_value(a));
            den.add(one_value(b));
        }
        (num, den)
    }
}

/// Calls `f(first point index, first voxel, length)` for every x-run of consecutive
/// points of a DT-Grid (its connected components, Sec. 2.1).
fn for_each_run(g: &DtGrid, mut f: impl FnMut(usize, Coord, usize)) {
    let mut run: Option<(usize, Coord, usize)> = None;
    for (i, (c, _)) in g.iter().enumerate() {
        match &mut run {
            Some((_, s, len))
                if s.z == c.z && s.y == c.y && s.x as i64 + *len as i64 == c.x as i64 =>
            {
                *len += 1
            }
            _ => {
                if let Some((i0, s, len)) = run {
                    f(i0, s, len);
                }
                run = Some((i, c, 1));
            }
        }
    }
    if let Some((i0, s, len)) = run {
        f(i0, s, len);
    }
}

impl Representation for DtRep {
    fn spec(&self) -> GridSpec {
        self.grid.spec()
    }

    fn flat(&self) -> &[f32] {
        self.grid.values()
    }

    fn fill_scalar(&self, f: &dyn ScalarFn, t: f64, _planar: bool, out: &mut [f32]) {
        let spec = self.spec();
        for_each_run(&self.grid, |i, start, len| f.fill_run(&spec, start, t, &mut out[i..i + len]));
    }

    fn fill_vector(&self, f: &dyn VectorFn, t: f64, out: [&mut [f32]; 3]) {
        let spec = self.spec();
        let [u, v, w] = out;
        for_each_run(&self.grid, |i, start, len| {
            let r = i..i + len;
            f.fill_run(&spec, start, t, [&mut u[r.clone()], &mut v[r.clone()], &mut w[r]]);
        });
    }

    fn stage(
        &mut self,
        p: &StageParams,
        scheme: SpatialScheme,
        last: bool,
    ) -> Result<(), EvolveError> {
        let mut out = std::mem::take(&mut self.out);
        let phi_n = std::mem::take(&mut self.phi_n);
        let stage = p.stage;
        let p = StageParams { phi_n: if stage == 1 { &[] } else { &phi_n }, ..*p };
        let r = dispatch(&p, scheme, DtSweep { rep: self, out: &mut out });
        self.phi_n = phi_n;
        let r = r.and_then(|()| Ok(self.grid.swap_values(&mut out)?));
        // On success `out` holds the previous values.
        self.out = out;
        r?;
        if stage == 1 {
            self.undo = Undo::after_stage1(last, &mut self.phi_n, &mut self.out);
        }
        Ok(())
    }

    fn renormalize(&mut self, p: &RenormParams, _fresh: bool) -> Result<(), EvolveError> {
        // The grid stores exactly the band mask (of φⁿ within a step, of φ⁰ at rest).
        // One sweep evaluates its anchors in place: no anchor pass.
        let anchored = p.anchored();
        if anchored {
            self.undo.vacate_out(&mut self.phi_n, &mut self.out);
            let mut anchor = std::mem::take(&mut self.anchor);
            let r = dispatch_anchor(p.h, DtSweep { rep: self, out: &mut anchor });
            self.anchor = anchor;
            r?;
        }
        for _ in 0..p.sweeps {
            self.undo.vacate_out(&mut self.phi_n, &mut self.out);
            let mut out = std::mem::take(&mut self.out);
            let anchor = std::mem::take(&mut self.anchor);
            let a = anchored.then_some(&anchor[..]);
            let r = dispatch_renorm(p, a, DtSweep { rep: self, out: &mut out });
            self.anchor = anchor;
            let r = r.and_then(|()| Ok(self.grid.swap_values(&mut out)?));
            self.out = out;
            r?;
            if self.undo == Undo::Nothing {
                self.undo = Undo::Out;
            }
        }
        Ok(())
    }

    fn finish_step(&mut self, budget: &MemoryBudget) -> Result<(), EvolveError> {
        let current = (self.bytes() + self.work_bytes()) as u64;
        // Sec. 3.6.2: keep the band (|φ| < γ), dilate it by one voxel; new points read ±γ.
        // The rebuild is built in the scratch grids (`DtGrid::rebuild_into` has no hook to
        // admit it before it allocates, so the DT-Grid may exceed the budget by one rebuilt
        // grid for a moment); it replaces the current grid only once admitted, and a
        // refused one is freed.
        self.grid.rebuild_into(self.grid.gamma(), 1, &mut self.kept, &mut self.next)?;
        // All three grids stay allocated (the current one becomes the next scratch grid,
        // or the undo of a step in progress); the value buffers grow to the new points in
        // the next step, which admits them before its first stage.
        let needed = (self.grid.memory().total() + self.kept.memory().total()) as u64
            + self.next.memory().total() as u64
            + (vec_bytes(&self.out) + vec_bytes(&self.phi_n)) as u64;
        if let Err(e) = budget.admit(needed, current, "the band's points") {
            // Give the refused rebuild's memory back.
            let spec = self.grid.spec();
            (self.kept, self.next) = (DtGrid::new(spec), DtGrid::new(spec));
            return Err(e.into());
        }
        let keep_prev = self.undo != Undo::Nothing;
        std::mem::swap(&mut self.grid, &mut self.next);
        self.rebuilt = keep_prev;
        Ok(())
    }

    fn for_each_owned_step_start(&self, f: &mut dyn FnMut(&[f32])) {
        f(self.undo.held(&self.phi_n, &self.out))
    }

    fn undo_step(&mut self) {
        if self.rebuilt {
            std::mem::swap(&mut self.grid, &mut self.next);
            self.rebuilt = false;
        }
        let values = match self.undo {
            Undo::Nothing => return,
            Undo::Out => &mut self.out,
            Undo::PhiN => &mut self.phi_n,
        };
        self.undo = Undo::Nothing;
        self.grid.swap_values(values).expect("φⁿ matches the grid before the step");
    }

    fn commit_step(&mut self) {
        self.undo = Undo::Nothing;
        self.rebuilt = false;
    }

    fn kappa_bar_sums(&self, width: f32) -> Result<(ExactSum, ExactSum), EvolveError> {
        let inv_h = 1.0 / self.grid.spec().voxel_size;
        let sums = DtKappa { grid: &self.grid, box27: &self.box27, inv_h, width };
        Ok(levelset_kernels::dispatch_one(sums))
    }

    fn for_each_unstored_inside_run(&self, f: &mut dyn FnMut(Coord, u32)) {
        let mut prev: Option<(Coord, f32)> = None;
        for (c, v) in self.grid.iter() {
            if let Some((p, pv)) = prev
                && p.z == c.z
                && p.y == c.y
                && c.x > p.x + 1
                && pv < 0.0
            {
                f(Coord::new(p.x + 1, p.y, p.z), (c.x as i64 - p.x as i64 - 1) as u32);
            }
            prev = Some((c, v));
        }
    }

    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        crate::storage::levelset::LevelSet::for_each_band_voxel(&self.grid, f)
    }

    fn any_voxel(&self, f: &mut dyn FnMut(Coord, f32) -> bool) -> bool {
        self.grid.iter().any(|(c, v)| f(c, v))
    }

    fn value(&self, c: Coord) -> f32 {
        self.grid.value(c)
    }

    fn units(&self) -> usize {
        self.grid.len()
    }

    fn bytes(&self) -> usize {
        self.grid.memory().used()
    }

    fn work_bytes(&self) -> usize {
        self.grid.memory().slack
            + vec_bytes(&self.phi_n)
            + vec_bytes(&self.out)
            + vec_bytes(&self.anchor)
            + self.kept.memory().total()
            + self.next.memory().total()
    }

    fn step_bytes(&self, keeps: StepKeeps) -> u64 {
        (self.bytes() + self.work_bytes()) as u64
            + self.buffer_growth(self.grid.len(), keeps.phi_n, keeps.anchors)
    }
}
