//! The isosurface of a dense array with the choices of scikit-image's `marching_cubes`:
//! an iso value defaulting to the middle of the data range, which side is inside, a
//! lattice step, a mask, an open or closed border, per-vertex values and the removal of
//! zero-area triangles ([`isosurface_dense_with`]).
//!
//! Everything but the cell rule (mask, open border) and the values happens before or
//! after the two passes of the surface module: the step samples the array,
//! `Inside::Above` negates it (as it is read, without a copy when the step is 1), and the
//! removal of zero-area triangles and of the vertices no triangle uses run over the
//! finished mesh, in order. The values are computed per vertex in the parallel second
//! pass, from the cells around the vertex's edge (a maximum, exact in any order), not by a
//! pass over the finished triangles on one thread (docs/decisions/0053). So the result is
//! the same bits for any thread count, like the mesh itself.

use super::surface::{dense_mesh, CellRule};
use super::{MeshError, TriangleMesh};
use crate::grid::GridSpec;
use crate::progress::Progress;
use crate::storage::dense::DenseField;
use crate::Coord;
use rayon::prelude::*;

/// Which side of the surface is the inside: the normals point out of it and the
/// triangles are counter-clockwise seen from outside.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Inside {
    /// Values below the iso value are inside (a signed distance, φ < 0 inside); normals
    /// along ∇φ. A value equal to the iso value counts as outside.
    #[default]
    Below,
    /// Values above the iso value are inside (a bright object in an image); normals
    /// along −∇φ, scikit-image's normals. A value equal to the iso value counts as
    /// outside, i.e. with the values below it, as in scikit-image.
    Above,
}

/// What the surface does where the object reaches the array's border.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Border {
    /// Values beyond the array read as outside (`iso + γ` on the outside side), so the
    /// surface is closed along the array's faces: a watertight mesh, whose
    /// [`TriangleMesh::enclosed_volume`] and area measure the object within the array.
    #[default]
    Closed,
    /// Only cells with all eight corners in the array are meshed, as scikit-image does:
    /// the surface ends on the array's outer faces (its boundary edges lie on them) and
    /// no part of the array's box is meshed. Voxels beyond the array read the linear
    /// extrapolation of the array along each axis, so the normals at the border come from
    /// one-sided differences of the same scale as the central ones inside.
    Open,
}

/// Options of [`isosurface_dense_with`]. `DenseMeshOptions::default()` gives the mesh of
/// [`super::isosurface_dense`] at iso value 0.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseMeshOptions<'a> {
    /// The iso value; `None`: the midpoint of the smallest and the largest finite value
    /// of the array (scikit-image's default).
    pub iso: Option<f64>,
    /// Which side is inside (orientation of normals and triangles, and the side a value
    /// equal to the iso value belongs to).
    pub inside: Inside,
    /// Mesh the lattice of every `step`-th voxel (≥ 1) along each axis from the array's
    /// first voxel, as scikit-image's `step_size`: cells of `step` voxels, about step²
    /// fewer triangles. Voxels past the last full step are not read.
    pub step: u32,
    /// One flag per voxel of the array (array order, x fastest): a cell (of the
    /// lattice of `step`) is meshed only when the flag at its upper corner, the corner
    /// with the largest coordinates, is set. This is scikit-image's rule (its
    /// `mask[z + s, y + s, x + s]` for the cell at `(z, y, x)`); so a mask that is set on
    /// a region R meshes the cells whose upper corner lies in R. Cells whose upper corner
    /// lies beyond the array are not meshed when a mask is given.
    pub mask: Option<&'a [bool]>,
    /// Open or closed at the array's border.
    pub border: Border,
    /// Remove triangles of zero area (and the vertices only they use). The simplicial
    /// surface keeps its vertices apart (see [the module docs](super#exact-zeros-and-precision)),
    /// so there are none unless positions collapse in rounding; the check costs one pass.
    pub drop_degenerate: bool,
    /// Progress (tiles done) and cancellation.
    pub progress: Progress,
}

impl Default for DenseMeshOptions<'_> {
    fn default() -> Self {
        DenseMeshOptions {
            iso: Some(0.0),
            inside: Inside::Below,
            step: 1,
            mask: None,
            border: Border::Closed,
            drop_degenerate: false,
            progress: Progress::none(),
        }
    }
}

/// A mesh of [`isosurface_dense_with`] with its per-vertex values.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DenseSurface {
    pub mesh: TriangleMesh,
    /// Per vertex, scikit-image's `values`: the largest, over the cells whose triangles
    /// use the vertex, of the cell's value range (largest minus smallest of its eight
    /// corner values, on the lattice of `step`; beyond a closed border the corners read
    /// `iso ± γ`).
    pub values: Vec<f32>,
    /// The iso value used (the one given, or the midpoint of the data range).
    pub iso: f64,
}

/// The midpoint of the smallest and the largest finite value.
fn mid_range(field: &DenseField) -> Result<f64, MeshError> {
    let (lo, hi) = field
        .data()
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v as f64), hi.max(v as f64))
        });
    if lo > hi {
        return Err(MeshError::InvalidParameter(
            "the array has no finite value to take the middle of its range from".into(),
        ));
    }
    Ok(0.5 * (lo + hi))
}

/// The isosurface of a dense field with the options of scikit-image's `marching_cubes`
/// (see [`DenseMeshOptions`]), as one welded mesh in world coordinates (voxel size and
/// origin from `spec`, the field's own origin placing it on the voxel grid) with its
/// per-vertex values.
///
/// The surface is the simplicial one of [`super::isosurface_dense`] (cubes split into
/// six tetrahedra: C. Min, "Simplicial isosurfacing in arbitrary dimension and
/// codimension", 2003), on the lattice of every `step`-th voxel and restricted to
/// the cells the mask and the border admit; with the default options it is the mesh of
/// [`super::isosurface_dense`], vertex for vertex. Vertices that no meshed cell uses are
/// dropped and the others keep their order. Same bits for any thread count.
///
/// Errors: NaN in the array, a non-finite iso value, `step` = 0, a mask whose length is
/// not the array's, an array without finite values when the iso value is the default.
///
/// ```
/// use sparse_levelset::{grid::GridSpec, storage::dense::DenseField, tools::mesh, Coord};
/// use mesh::{Border, DenseMeshOptions, Inside};
///
/// // A bright ball (100 at the centre, falling off by 10 per voxel) cut by the face x = 0.
/// let image = DenseField::from_fn(Coord::new(0, 0, 0), [24; 3], |c| {
///     let d = [c.x as f32 - 2.5, c.y as f32 - 11.5, c.z as f32 - 12.0];
///     100.0 - 10.0 * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
/// })
/// .unwrap();
/// let opts = DenseMeshOptions { iso: Some(20.0), inside: Inside::Above, ..Default::default() };
/// let closed = mesh::isosurface_dense_with(&image, &GridSpec::default(), &opts).unwrap();
/// assert!(closed.mesh.is_closed_manifold() && closed.mesh.enclosed_volume() > 0.0);
/// let open = DenseMeshOptions { border: Border::Open, ..opts };
/// let open = mesh::isosurface_dense_with(&image, &GridSpec::default(), &open).unwrap();
/// assert!(!open.mesh.is_closed_manifold() && open.mesh.area() < closed.mesh.area());
/// assert_eq!(open.values.len(), open.mesh.num_vertices());
/// ```
pub fn isosurface_dense_with(
    field: &DenseField,
    spec: &GridSpec,
    opts: &DenseMeshOptions,
) -> Result<DenseSurface, MeshError> {
    if opts.step == 0 {
        return Err(MeshError::InvalidParameter("step must be at least 1 (1: every voxel)".into()));
    }
    if let Some(m) = opts.mask
        && m.len() != field.data().len()
    {
        return Err(MeshError::InvalidParameter(format!(
            "the mask has {} flags for an array of {} voxels {:?} (x, y, z)",
            m.len(),
            field.data().len(),
            field.dims()
        )));
    }
    super::surface::check_nan(field)?;
    let iso = match opts.iso {
        Some(iso) => iso,
        None => mid_range(field)?,
    };
    if !iso.is_finite() {
        return Err(MeshError::InvalidParameter(format!("iso value must be finite, got {iso}")));
    }
    let step = opts.step as usize;
    let above = opts.inside == Inside::Above;
    let sampled;
    let sampled_mask;
    let sampled_spec;
    // Every step-th voxel, negated for `Above`; with step 1 the array itself, negated as
    // it is read.
    let (f, spec, mask) = if step > 1 {
        let dims = field.dims();
        let sd = dims.map(|d| (d - 1) / step + 1);
        let src =
            |x: usize, y: usize, z: usize| step * x + dims[0] * (step * y + dims[1] * step * z);
        let mut data = Vec::with_capacity(sd[0] * sd[1] * sd[2]);
        let mut flags = Vec::with_capacity(if opts.mask.is_some() { data.capacity() } else { 0 });
        let sign = if above { -1.0 } else { 1.0 };
        for z in 0..sd[2] {
            for y in 0..sd[1] {
                for x in 0..sd[0] {
                    let i = src(x, y, z);
                    data.push(sign * field.data()[i]);
                    if let Some(m) = opts.mask {
                        flags.push(m[i]);
                    }
                }
            }
        }
        let o = field.origin();
        let h = spec.voxel_size as f64;
        sampled_spec = GridSpec {
            voxel_size: spec.voxel_size * opts.step as f32,
            origin: [
                spec.origin[0] + h * o.x as f64,
                spec.origin[1] + h * o.y as f64,
                spec.origin[2] + h * o.z as f64,
            ],
            half_width: spec.half_width,
        };
        sampled = DenseField::from_vec(Coord::new(0, 0, 0), sd, data).map_err(|e| {
            MeshError::InvalidParameter(format!("sampling the array every {step} voxels: {e}"))
        })?;
        sampled_mask = flags;
        (&sampled, &sampled_spec, opts.mask.map(|_| &sampled_mask[..]))
    } else {
        (field, spec, opts.mask)
    };
    let open = opts.border == Border::Open;
    let rule = (open || mask.is_some()).then_some(CellRule { open, mask });
    let (mesh, values) = dense_mesh(
        f,
        above && step == 1,
        spec,
        if above { -iso } else { iso },
        rule,
        true,
        &opts.progress,
    )?;
    // A vertex is on a triangle exactly when some admitted cell holds its edge, i.e. when
    // its value is not −1 (see the surface module's `vertex_value`).
    let mut used: Vec<bool> = values.par_iter().map(|&v| v >= 0.0).collect();
    let mut out = DenseSurface { mesh, values, iso };
    if opts.drop_degenerate {
        let m = &out.mesh;
        let keep: Vec<bool> =
            m.triangles.iter().map(|t| super::check::face_normal(m, t) != [0.0; 3]).collect();
        if keep.contains(&false) {
            let mut k = keep.iter();
            out.mesh.triangles.retain(|_| *k.next().expect("one flag per triangle"));
            used.fill(false);
            for t in &out.mesh.triangles {
                for &v in t {
                    used[v as usize] = true;
                }
            }
        }
    }
    drop_unused_vertices(&mut out, &used);
    Ok(out)
}

/// Removes the vertices not `used` (no triangle uses them), keeping the others in order.
fn drop_unused_vertices(s: &mut DenseSurface, used: &[bool]) {
    let m = &mut s.mesh;
    if !used.contains(&false) {
        return;
    }
    let mut new_index = vec![u32::MAX; used.len()];
    let mut next = 0u32;
    for (i, &u) in used.iter().enumerate() {
        if u {
            new_index[i] = next;
            m.positions[next as usize] = m.positions[i];
            m.normals[next as usize] = m.normals[i];
            s.values[next as usize] = s.values[i];
            next += 1;
        }
    }
    let n = next as usize;
    m.positions.truncate(n);
    m.normals.truncate(n);
    s.values.truncate(n);
    for t in &mut m.triangles {
        *t = t.map(|v| new_index[v as usize]);
    }
}
