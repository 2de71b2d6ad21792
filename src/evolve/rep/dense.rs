//! The dense reference: every voxel of a box, the same kernels over a padded copy, the
//! band mask of [`BandMasked`]. For tests on small grids.

use super::{growth_bytes, vec_bytes, KappaBarTerm, MemoryBudget, Representation, Undo};
use crate::coord::Coord;
use crate::evolve::dispatch::{
    dispatch, dispatch_anchor, dispatch_renorm, Halo, RenormParams, StageParams, Sweep,
};
use crate::evolve::field::{ScalarFn, VectorFn};
use crate::evolve::{EvolveError, SpatialScheme, StepKeeps};
use crate::exact::ExactSum;
use crate::grid::GridSpec;
use crate::storage::dense::DenseField;
use levelset_kernels::{BandMasked, BoxMinAbs, DenseBlock, VoxelKernel};
use std::ops::Range;

/// Band voxels must stay this far from the dense box's faces.
const DENSE_MARGIN: usize = 4;

/// The dense reference. The box must keep a margin of four voxels around the band
/// ([`EvolveError::DenseBoxTooSmall`] otherwise); it never grows.
///
/// # Invariants
/// While a step is in progress, `undo` names the buffer holding φⁿ.
#[derive(Clone)]
pub(crate) struct DenseRep {
    pub field: DenseField,
    pub spec: GridSpec,
    phi_n: Vec<f32>,
    out: Vec<f32>,
    box_min: Vec<f32>,
    /// The renormalisation's anchors of φ⁰.
    anchor: Vec<f32>,
    padded: Vec<f32>,
    undo: Undo,
}

impl DenseRep {
    pub fn new(field: DenseField, spec: GridSpec) -> Result<Self, EvolveError> {
        let rep = DenseRep {
            field,
            spec,
            phi_n: Vec::new(),
            out: Vec::new(),
            box_min: Vec::new(),
            anchor: Vec::new(),
            padded: Vec::new(),
            undo: Undo::Nothing,
        };
        rep.check_margin()?;
        Ok(rep)
    }

    fn check_margin(&self) -> Result<(), EvolveError> {
        let g = self.spec.gamma();
        let [nx, ny, nz] = self.field.dims();
        let o = self.field.origin();
        let near = |v: usize, n: usize| v < DENSE_MARGIN || v + DENSE_MARGIN >= n;
        for (i, &v) in self.field.data().iter().enumerate() {
            if v.abs() < g {
                let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
                if near(x, nx) || near(y, ny) || near(z, nz) {
                    return Err(EvolveError::DenseBoxTooSmall {
                        voxel: Coord::new(o.x + x as i32, o.y + y as i32, o.z + z as i32),
                    });
                }
            }
        }
        Ok(())
    }
}

/// Copies `field` into `padded` with an `R`-voxel halo that repeats the faces (the far
/// field beyond the box keeps the sign and value of the box's face).
fn pad_into<const R: usize>(field: &DenseField, padded: &mut Vec<f32>) {
    let [nx, ny, nz] = field.dims();
    let len = DenseBlock::<R>::padded_len([nx, ny, nz]).expect("the dense field fits in memory");
    padded.resize(len, 0.0);
    let d = field.data();
    let r = R as isize;
    let clamp = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
    for z in -r..nz as isize + r {
        for y in -r..ny as isize + r {
            for x in -r..nx as isize + r {
                let src = clamp(x, nx) + nx * (clamp(y, ny) + ny * clamp(z, nz));
                padded[DenseBlock::<R>::index([nx, ny, nz], x, y, z)] = d[src];
            }
        }
    }
}

struct DenseSweep<'a> {
    rep: &'a mut DenseRep,
    compute_mask: bool,
}

impl Sweep for DenseSweep<'_> {
    fn run<K, M, const R: usize>(self, make: M) -> Result<(), EvolveError>
    where
        K: VoxelKernel,
        M: Fn(Range<usize>) -> K + Sync,
        Halo<R>: crate::evolve::dispatch::Reach,
    {
        let rep = self.rep;
        let dims = rep.field.dims();
        let n = rep.field.data().len();
        if self.compute_mask {
            pad_into::<1>(&rep.field, &mut rep.padded);
            rep.box_min.resize(n, 0.0);
            DenseBlock::<1>::new(&rep.padded, dims)?.apply_one(&BoxMinAbs, &mut rep.box_min)?;
        }
        pad_into::<R>(&rep.field, &mut rep.padded);
        let k = BandMasked { step: make(0..n), box_min: &rep.box_min, gamma: rep.spec.gamma() };
        rep.out.resize(n, 0.0);
        DenseBlock::<R>::new(&rep.padded, dims)?.apply_one(&k, &mut rep.out)?;
        Ok(())
    }
}

impl Representation for DenseRep {
    fn spec(&self) -> GridSpec {
        self.spec
    }

    fn flat(&self) -> &[f32] {
        self.field.data()
    }

    fn fill_scalar(&self, f: &dyn ScalarFn, t: f64, _planar: bool, out: &mut [f32]) {
        let nx = self.field.dims()[0];
        let o = self.field.origin();
        for (row, chunk) in out.chunks_mut(nx).enumerate() {
            let c = self.field.coord_of(row * nx).expect("row inside the box");
            debug_assert_eq!(c.x, o.x);
            f.fill_run(&self.spec, c, t, chunk);
        }
    }

    fn fill_vector(&self, f: &dyn VectorFn, t: f64, out: [&mut [f32]; 3]) {
        let nx = self.field.dims()[0];
        let [u, v, w] = out;
        for (row, ((u, v), w)) in
            u.chunks_mut(nx).zip(v.chunks_mut(nx)).zip(w.chunks_mut(nx)).enumerate()
        {
            let c = self.field.coord_of(row * nx).expect("row inside the box");
            f.fill_run(&self.spec, c, t, [u, v, w]);
        }
    }

    fn stage(
        &mut self,
        p: &StageParams,
        scheme: SpatialScheme,
        last: bool,
    ) -> Result<(), EvolveError> {
        let phi_n = std::mem::take(&mut self.phi_n);
        let stage = p.stage;
        let p = StageParams { phi_n: if stage == 1 { &[] } else { &phi_n }, ..*p };
        let r = dispatch(&p, scheme, DenseSweep { rep: self, compute_mask: stage == 1 });
        self.phi_n = phi_n;
        r?;
        // `out` takes the previous values (the double buffer; no copy is lost).
        self.field.data_mut().swap_with_slice(&mut self.out);
        if stage == 1 {
            self.undo = Undo::after_stage1(last, &mut self.phi_n, &mut self.out);
        }
        Ok(())
    }

    fn renormalize(&mut self, p: &RenormParams, fresh: bool) -> Result<(), EvolveError> {
        // One sweep evaluates its anchors in place: no anchor pass.
        let anchored = p.anchored();
        if anchored {
            self.undo.vacate_out(&mut self.phi_n, &mut self.out);
            // The sweep writes `out`; the anchors take it (a swap).
            dispatch_anchor(p.h, DenseSweep { rep: self, compute_mask: fresh })?;
            std::mem::swap(&mut self.anchor, &mut self.out);
        }
        for s in 0..p.sweeps {
            self.undo.vacate_out(&mut self.phi_n, &mut self.out);
            let anchor = std::mem::take(&mut self.anchor);
            let a = anchored.then_some(&anchor[..]);
            // At rest, the single sweep computes the band mask of φ⁰ itself.
            let compute_mask = fresh && !anchored && s == 0;
            let r = dispatch_renorm(p, a, DenseSweep { rep: self, compute_mask });
            self.anchor = anchor;
            r?;
            self.field.data_mut().swap_with_slice(&mut self.out);
            if self.undo == Undo::Nothing {
                self.undo = Undo::Out;
            }
        }
        Ok(())
    }

    fn finish_step(&mut self, _budget: &MemoryBudget) -> Result<(), EvolveError> {
        // The box never grows: nothing to admit.
        self.check_margin()
    }

    fn for_each_owned_step_start(&self, f: &mut dyn FnMut(&[f32])) {
        f(self.undo.held(&self.phi_n, &self.out))
    }

    fn undo_step(&mut self) {
        if self.undo == Undo::Nothing {
            return;
        }
        let values = self.undo.held(&self.phi_n, &self.out);
        self.field.data_mut().copy_from_slice(values);
        self.undo = Undo::Nothing;
    }

    fn commit_step(&mut self) {
        self.undo = Undo::Nothing;
    }

    fn kappa_bar_sums(&self, width: f32) -> Result<(ExactSum, ExactSum), EvolveError> {
        let inv_h = 1.0 / self.spec.voxel_size;
        let mut padded = Vec::new();
        pad_into::<1>(&self.field, &mut padded);
        let block = DenseBlock::<1>::new(&padded, self.field.dims())?;
        let mut a = vec![0.0; self.field.data().len()];
        let mut b = a.clone();
        block.apply_one(&KappaBarTerm::<true> { inv_h, width }, &mut a)?;
        block.apply_one(&KappaBarTerm::<false> { inv_h, width }, &mut b)?;
        let (mut num, mut den) = (ExactSum::default(), ExactSum::default());
        num.add_all(&a);
        den.add_all(&b);
        Ok((num, den))
    }

    fn for_each_unstored_inside_run(&self, _f: &mut dyn FnMut(Coord, u32)) {}

    fn for_each_band_voxel(&self, f: &mut dyn FnMut(Coord, f32)) {
        let g = self.spec.gamma();
        self.field.for_each(|c, v| {
            if v.abs() < g {
                f(c, v)
            }
        });
    }

    fn any_voxel(&self, f: &mut dyn FnMut(Coord, f32) -> bool) -> bool {
        let field = &self.field;
        field
            .data()
            .iter()
            .enumerate()
            .any(|(i, &v)| f(field.coord_of(i).expect("index inside the box"), v))
    }

    fn value(&self, c: Coord) -> f32 {
        self.field.get(c).unwrap_or(self.spec.gamma())
    }

    fn units(&self) -> usize {
        self.field.data().len()
    }

    fn bytes(&self) -> usize {
        self.field.data().len() * 4
    }

    fn work_bytes(&self) -> usize {
        vec_bytes(&self.phi_n)
            + vec_bytes(&self.out)
            + vec_bytes(&self.box_min)
            + vec_bytes(&self.anchor)
            + vec_bytes(&self.padded)
    }

    fn step_bytes(&self, keeps: StepKeeps) -> u64 {
        let StepKeeps { phi_n: keeps_phi_n, anchors, .. } = keeps;
        // The double buffer, the band mask, φⁿ and the padded copy (3-voxel halo, the
        // reach of HJ-WENO5).
        let n = self.field.data().len();
        let padded = DenseBlock::<3>::padded_len(self.field.dims()).unwrap_or(usize::MAX);
        (self.bytes() + self.work_bytes()) as u64
            + growth_bytes(&self.out, n)
            + growth_bytes(&self.box_min, n)
            + growth_bytes(&self.padded, padded)
            + if keeps_phi_n { growth_bytes(&self.phi_n, n) } else { 0 }
            + if anchors { growth_bytes(&self.anchor, n) } else { 0 }
    }
}
