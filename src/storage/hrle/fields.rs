//! Augmented fields (Sec. 6.1, Fig. 4): arrays of per-voxel data that share the level
//! set's encoding, one entry per stored value, so every access path of the grid reaches
//! them through the same value index.

use super::HrleGrid;
use crate::coord::Coord;
use crate::grid::{vec_bytes, GridError};

/// The data of an augmented field, one entry per stored voxel in [`Coord`] order.
#[derive(Clone, Debug, PartialEq)]
pub enum FieldData {
    /// A scalar per voxel (a grey value, a temperature).
    Scalar(Vec<f32>),
    /// A 3-vector per voxel (a colour, a velocity, texture coordinates).
    Vector(Vec<[f32; 3]>),
}

/// A named augmented field.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// Its name, unique in the grid.
    pub name: String,
    /// One entry per stored voxel.
    pub data: FieldData,
}

impl Field {
    /// Entries.
    pub fn len(&self) -> usize {
        match &self.data {
            FieldData::Scalar(v) => v.len(),
            FieldData::Vector(v) => v.len(),
        }
    }

    /// No entry.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub(crate) fn bytes(&self) -> (usize, usize) {
        match &self.data {
            FieldData::Scalar(v) => vec_bytes(v),
            FieldData::Vector(v) => vec_bytes(v),
        }
    }

    pub(crate) fn shrink_to_fit(&mut self) {
        match &mut self.data {
            FieldData::Scalar(v) => v.shrink_to_fit(),
            FieldData::Vector(v) => v.shrink_to_fit(),
        }
    }

    /// The field over another grid's voxels: entry `k` is this field's entry `from[k]`,
    /// or zero for `None` (a voxel a dilation added).
    pub(crate) fn gather(&self, from: &[Option<u32>]) -> Field {
        let data = match &self.data {
            FieldData::Scalar(v) => {
                FieldData::Scalar(from.iter().map(|i| i.map_or(0.0, |i| v[i as usize])).collect())
            }
            FieldData::Vector(v) => FieldData::Vector(
                from.iter().map(|i| i.map_or([0.0; 3], |i| v[i as usize])).collect(),
            ),
        };
        Field { name: self.name.clone(), data }
    }
}

impl HrleGrid {
    /// The augmented fields.
    pub fn fields(&self) -> &[Field] {
        &self.fields
    }

    /// The field called `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// Adds a field with one entry per stored voxel in [`Coord`] order. Refused, leaving
    /// the grid unchanged, when the name is taken or empty, the length differs or an
    /// entry is not finite.
    pub fn add_field(&mut self, name: &str, data: FieldData) -> Result<(), GridError> {
        let bad = |m: String| Err(GridError::InvalidParameter(m));
        if name.is_empty() || name.len() > u16::MAX as usize {
            return bad(format!("a field name must have 1 to {} bytes", u16::MAX));
        }
        if self.field(name).is_some() {
            return bad(format!("the grid already has a field called {name:?}"));
        }
        let field = Field { name: name.to_string(), data };
        if field.len() != self.values.len() {
            return bad(format!(
                "field {name:?} has {} entries for {} voxels",
                field.len(),
                self.values.len()
            ));
        }
        let finite = match &field.data {
            FieldData::Scalar(v) => v.iter().all(|x| x.is_finite()),
            FieldData::Vector(v) => v.iter().flatten().all(|x| x.is_finite()),
        };
        if !finite {
            return bad(format!("field {name:?} has a NaN or infinite entry"));
        }
        self.fields.push(field);
        Ok(())
    }

    /// Adds a scalar field `f(voxel, φ)` over the stored voxels.
    pub fn add_scalar_field(
        &mut self,
        name: &str,
        f: impl Fn(Coord, f32) -> f32,
    ) -> Result<(), GridError> {
        let mut v = Vec::with_capacity(self.values.len());
        self.for_each_defined(|c, i| v.push(f(c, self.values[i])));
        self.add_field(name, FieldData::Scalar(v))
    }

    /// Adds a vector field `f(voxel, φ)` over the stored voxels.
    pub fn add_vector_field(
        &mut self,
        name: &str,
        f: impl Fn(Coord, f32) -> [f32; 3],
    ) -> Result<(), GridError> {
        let mut v = Vec::with_capacity(self.values.len());
        self.for_each_defined(|c, i| v.push(f(c, self.values[i])));
        self.add_field(name, FieldData::Vector(v))
    }

    /// Removes the field called `name`, returning it.
    pub fn remove_field(&mut self, name: &str) -> Option<Field> {
        let i = self.fields.iter().position(|f| f.name == name)?;
        Some(self.fields.remove(i))
    }

    /// The scalar field `name` at voxel `c`: `None` when the field is absent, not scalar,
    /// or `c` is not stored.
    pub fn scalar_at(&self, name: &str, c: Coord) -> Option<f32> {
        match &self.field(name)?.data {
            FieldData::Scalar(v) => self.locate_index(c).ok().map(|i| v[i]),
            FieldData::Vector(_) => None,
        }
    }

    /// The vector field `name` at voxel `c`, as [`HrleGrid::scalar_at`].
    pub fn vector_at(&self, name: &str, c: Coord) -> Option<[f32; 3]> {
        match &self.field(name)?.data {
            FieldData::Vector(v) => self.locate_index(c).ok().map(|i| v[i]),
            FieldData::Scalar(_) => None,
        }
    }
}
