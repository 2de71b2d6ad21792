//! The front door: one loader and one set of checks for the level sets every tool reads — a
//! dense `.npy` field or an analytic shape — so that the same input gets the same verdict,
//! with the same message, from every tool (the `levelset` subcommands, the Python package),
//! and bad input is refused before any work.
//!
//! # The rules
//! 1. **File**: a 3-D little-endian float32 `.npy` ([`crate::io::npy`]; every problem is an
//!    [`InputError::File`] naming the file).
//! 2. **Memory**: the data and the tool's working copies ([`Expect::copies`]) must fit
//!    ([`crate::memory::check`]); checked from the header, before the data are read.
//! 3. **Values**: NaN is refused ([`InputError::NaN`]); `±∞` is a far-away distance and is
//!    clamped to `±γ` (γ = half-width × voxel size), as the sparse grids store it.
//! 4. **Isovalue**: finite and inside the band, `|iso| < γ` ([`InputError::IsoOutsideBand`]).
//! 5. **Interface**: some voxel inside (φ < iso) and some outside (φ ≥ iso; a value equal
//!    to the isovalue counts as outside, as in meshing), else [`InputError::NoInterface`].
//! 6. **Distance field** (every tool but the one that makes distance fields): no two
//!    neighbouring voxels change sign while both lie outside the band (|φ| ≥ γ); the band
//!    would lose those crossings ([`InputError::NotDistance`]). Nor may φ change by less than a
//!    quarter of a voxel across most of its crossings, where a distance changes by about
//!    a voxel: volumes, areas, speeds and ray steps would be off by the field's scale
//!    ([`InputError::Shallow`]). Both from one pass over the neighbouring pairs
//!    ([`crate::storage::convert::dense_pairs`]).
//! 7. **Positions**: the voxels, band included, lie in the `i32` coordinate range. (Meshes
//!    far from the origin are written with `f64` positions; see [`crate::tools::mesh`].)
//!
//! Sparse files (`.sls`: [`load_sls`]; OpenVDB `.vdb`: [`load_vdb`]) carry their own spec
//! and follow rules 2 and 4, their readers the rest (NaN refused, values within ±γ).
//!
//! Shapes ([`check_shape`]) follow rules 2, 4 and 7 and have their parameters checked
//! ([`Shape::validate`]).
//!
//! ```
//! use sparse_levelset::{storage::dense::DenseField, grid::GridSpec, io::input, Coord};
//!
//! let spec = GridSpec::default(); // γ = 3
//! let expect = input::Expect::new(spec);
//! // A plane x = 4.5 as a signed distance, with a far-away +∞ in a corner.
//! let mut f = DenseField::from_fn(Coord::new(0, 0, 0), [10, 4, 4], |c| c.x as f32 - 4.5).unwrap();
//! f.set(Coord::new(9, 3, 3), f32::INFINITY).unwrap();
//! input::check_field("plane", &mut f, &expect).unwrap();
//! assert_eq!(f.get(Coord::new(9, 3, 3)), Some(3.0)); // clamped to γ
//! // 1000 φ is not a distance field at γ = 3; φ everywhere −5 has no interface.
//! let mut steep = DenseField::from_fn(Coord::new(0, 0, 0), [10, 4, 4], |c| 1e3 * (c.x as f32 - 4.5)).unwrap();
//! assert!(matches!(input::check_field("steep", &mut steep, &expect), Err(input::InputError::NotDistance { .. })));
//! let mut inside = DenseField::new(Coord::new(0, 0, 0), [4, 4, 4], -5.0).unwrap();
//! assert!(matches!(input::check_field("inside", &mut inside, &expect), Err(input::InputError::NoInterface { .. })));
//! ```

use crate::coord::Coord;
use crate::grid::{GridError, GridSpec};
use crate::io::npy::{self, NpyError};
use crate::storage::convert::{check_band_fits, dense_pairs};
use crate::storage::dense::DenseField;
use crate::storage::sample::band_voxel_box;
use crate::storage::shapes::Shape;
use rayon::prelude::*;
use std::path::Path;

/// What a tool expects of its input level set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Expect {
    /// Voxel size, origin and band half-width (γ = half-width × voxel size).
    pub spec: GridSpec,
    /// The level of the interface, in world units (`|iso| < γ`).
    pub iso: f64,
    /// The input must be a signed distance field at the spec's half-width (rule 6 of the
    /// module docs): true for every tool that builds a band from it, false for one that
    /// computes distances from any level set (`levelset distance`).
    pub distance_field: bool,
    /// Arrays the size of the input (dense fields) or of its band (shapes) that the tool
    /// holds at once, the input included (≥ 1); sizes the memory check.
    pub copies: f64,
}

impl Expect {
    /// A signed distance field on `spec` with its interface at 0, one copy in memory.
    pub fn new(spec: GridSpec) -> Expect {
        Expect { spec, iso: 0.0, distance_field: true, copies: 1.0 }
    }
}

/// Why an input level set is refused; every message names the input (a file's path, a
/// shape's name) and says what to change.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The file's extension names no level-set format.
    #[error("{input}: unknown level-set file type; use {}", crate::io::LevelSetFormat::EXTENSIONS)]
    UnknownFormat { input: String },
    /// The file cannot be read as a 3-D float32 `.npy` volume.
    #[error(transparent)]
    File(NpyError),
    /// A NaN value at `coord`, the first in [`Coord`] order.
    #[error(
        "{input}: NaN at voxel (x, y, z) = ({x}, {y}, {z}), i.e. arr[{z}, {y}, {x}]; level-set \
         values must be numbers (±inf is accepted as a far-away distance)",
        x = .coord.x, y = .coord.y, z = .coord.z
    )]
    NaN { input: String, coord: Coord },
    /// The input and the tool's working copies need more memory than the machine can give.
    #[error("{input}: {error}")]
    OutOfMemory { input: String, error: GridError },
    /// The isovalue is not inside the band (or not finite).
    #[error(
        "{input}: the isovalue {iso} is outside the band (-γ, γ) = (-{gamma}, {gamma}) world \
         units; choose |iso| < γ, or widen the band (--half-width)"
    )]
    IsoOutsideBand { input: String, iso: f64, gamma: f32 },
    /// No voxel is inside (`inside` = false) or none is outside (`inside` = true).
    #[error(
        "{input}: no interface: every voxel is {} (φ {} {iso} everywhere), so the level set is \
         empty: no zero crossing, no surface",
        if *.inside { "inside" } else { "outside" },
        if *.inside { "<" } else { "≥" }
    )]
    NoInterface { input: String, iso: f64, inside: bool },
    /// Neighbouring voxels change sign with both values outside the band.
    #[error(
        "{input}: not a signed distance field at half-width {half_width} (γ = {gamma}): {pairs} \
         neighbouring voxel pairs change sign with both |φ| ≥ γ, so the band would lose those \
         crossings; check --voxel-size, or turn the field into a distance field with \
         `levelset distance`"
    )]
    NotDistance { input: String, pairs: usize, gamma: f32, half_width: f32 },
    /// Across most of its crossings φ changes by less than a quarter of a voxel.
    #[error(
        "{input}: not a signed distance field: across {shallow} of its {crossings} neighbouring \
         voxel pairs that change sign, φ changes by less than a quarter of a voxel ({step} \
         world units), where a distance changes by about a voxel; give φ in world units, or \
         turn the field into a distance field with `levelset distance`"
    )]
    Shallow { input: String, shallow: usize, crossings: usize, step: f64 },
    /// A parameter outside its domain (a shape's, or a band leaving the `i32` range).
    #[error(transparent)]
    Grid(#[from] GridError),
    /// The file cannot be read as a `.sls` sparse level set ([`crate::io::sls`]).
    #[error(transparent)]
    Sls(#[from] crate::io::sls::SlsError),
    /// The file cannot be read as an OpenVDB level set ([`crate::io::vdb`]).
    #[error(transparent)]
    Vdb(#[from] crate::io::vdb::VdbError),
}

impl crate::error::Error for InputError {
    fn kind(&self) -> crate::error::ErrorKind {
        use crate::error::ErrorKind::*;
        match self {
            InputError::UnknownFormat { .. } => UnknownFormat,
            InputError::File(e) => e.kind(),
            InputError::NaN { .. }
            | InputError::NoInterface { .. }
            | InputError::NotDistance { .. }
            | InputError::Shallow { .. } => InvalidData,
            InputError::OutOfMemory { .. } => OutOfMemory,
            InputError::IsoOutsideBand { .. } => InvalidInput,
            InputError::Grid(e) => e.kind(),
            InputError::Sls(e) => e.kind(),
            InputError::Vdb(e) => e.kind(),
        }
    }
}

/// Loads a dense level set from a `.npy` file and checks it against `expect` (every rule
/// of the module docs): the one loader of every tool. `±∞` come back clamped to `±γ`.
pub fn load_npy(path: &Path, expect: &Expect) -> Result<DenseField, InputError> {
    let name = path.display().to_string();
    check_iso(&name, expect)?;
    let info = npy::inspect_npy(path).map_err(InputError::File)?;
    let field_bytes = crate::memory::bytes_of(info.len() as u128, 4);
    let needed = info.read_bytes() + (expect.copies.max(1.0) - 1.0) * field_bytes;
    crate::memory::check(needed, "the field with the tool's working copies")
        .map_err(|error| InputError::OutOfMemory { input: name.clone(), error })?;
    let mut field = npy::read_npy(path).map_err(|e| match e {
        NpyError::NaN { x, y, z, .. } => {
            InputError::NaN { input: name.clone(), coord: Coord::new(x as i32, y as i32, z as i32) }
        }
        e => InputError::File(e),
    })?;
    check_field(&name, &mut field, expect)?;
    Ok(field)
}

/// Loads a sparse level set from a `.sls` file ([`crate::io::sls::load`]: memory, checksum and
/// every invariant checked before it is returned). Its own voxel size, origin and
/// half-width replace `expect.spec`; the isovalue must lie inside its band.
pub fn load_sls(
    path: &Path,
    expect: &Expect,
) -> Result<(crate::storage::hrle::HrleGrid, crate::io::sls::Header), InputError> {
    let (grid, header) = crate::io::sls::load(path)?;
    let name = path.display().to_string();
    check_iso(&name, &Expect { spec: header.spec, ..*expect })?;
    let needed = (expect.copies.max(1.0) - 1.0) * grid.memory().used() as f64;
    crate::memory::check(needed, "the level set with the tool's working copies")
        .map_err(|error| InputError::OutOfMemory { input: name, error })?;
    Ok((grid, header))
}

/// Loads a level set from an OpenVDB `.vdb` file ([`crate::io::vdb::load`]: its first `float`
/// grid of class `level set`; memory and every count checked before anything is sized by
/// it). Its own voxel size, origin and half-width (background / voxel size) replace
/// `expect.spec`; the isovalue must lie inside its band.
pub fn load_vdb(
    path: &Path,
    expect: &Expect,
) -> Result<(crate::storage::tiles::TileGrid, crate::io::vdb::VdbInfo), InputError> {
    let (grid, info) = crate::io::vdb::load(path)?;
    let name = path.display().to_string();
    check_iso(&name, &Expect { spec: *grid.spec(), ..*expect })?;
    let needed = (expect.copies.max(1.0) - 1.0) * grid.memory().used() as f64;
    crate::memory::check(needed, "the level set with the tool's working copies")
        .map_err(|error| InputError::OutOfMemory { input: name, error })?;
    Ok((grid, info))
}

/// Checks a dense level set against `expect` (rules 3 to 7 of the module docs; `input`
/// names it in errors) and clamps its `±∞` to `±γ`. On error the field is unchanged.
pub fn check_field(input: &str, field: &mut DenseField, expect: &Expect) -> Result<(), InputError> {
    check_iso(input, expect)?;
    let data = field.data();
    if let Some(i) = crate::storage::dense::first_position(data, |v| v.is_nan()) {
        let coord = field.coord_of(i).expect("index in range");
        return Err(InputError::NaN { input: input.to_string(), coord });
    }
    let iso = expect.iso;
    let (inside, outside) = data
        .par_iter()
        .fold(|| (false, false), |(i, o), &v| ((v as f64) < iso || i, (v as f64) >= iso || o))
        .reduce(|| (false, false), |a, b| (a.0 || b.0, a.1 || b.1));
    if !(inside && outside) {
        return Err(InputError::NoInterface { input: input.to_string(), iso, inside });
    }
    let spec = &expect.spec;
    let g = spec.gamma();
    if expect.distance_field {
        // ±∞ count as |φ| ≥ γ, as they will once clamped.
        let step = 0.25 * spec.voxel_size as f64;
        let pairs = dense_pairs(field, g, iso, step);
        if pairs.jumps > 0 {
            return Err(InputError::NotDistance {
                input: input.to_string(),
                pairs: pairs.jumps,
                gamma: g,
                half_width: spec.half_width,
            });
        }
        if 2 * pairs.shallow > pairs.crossings {
            let (shallow, crossings) = (pairs.shallow, pairs.crossings);
            return Err(InputError::Shallow { input: input.to_string(), shallow, crossings, step });
        }
    }
    field.data_mut().par_iter_mut().for_each(|v| {
        if v.is_infinite() {
            *v = v.signum() * g;
        }
    });
    Ok(())
}

/// Checks an analytic shape against `expect` before anything is built: its parameters
/// ([`Shape::validate`]), the isovalue, its band within the `i32` voxel range, and the memory of
/// [`Expect::copies`] bands ([`check_band_fits`]). `input` names it in errors.
pub fn check_shape(input: &str, shape: &Shape, expect: &Expect) -> Result<(), InputError> {
    shape.validate()?;
    check_iso(input, expect)?;
    let spec = &expect.spec;
    let (lo, hi) = shape.bounds();
    band_voxel_box(lo, hi, spec)?;
    check_band_fits(shape, spec, expect.copies)
        .map_err(|error| InputError::OutOfMemory { input: input.to_string(), error })
}

fn check_iso(input: &str, expect: &Expect) -> Result<(), InputError> {
    let g = expect.spec.gamma();
    if expect.iso.is_finite() && expect.iso.abs() < g as f64 {
        Ok(())
    } else {
        Err(InputError::IsoOutsideBand { input: input.to_string(), iso: expect.iso, gamma: g })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(scale: f32) -> DenseField {
        DenseField::from_fn(Coord::new(0, 0, 0), [12, 5, 6], |c| scale * (c.x as f32 - 5.5))
            .unwrap()
    }

    fn expect() -> Expect {
        Expect::new(GridSpec::default())
    }

    #[test]
    fn one_verdict_per_kind_of_field() {
        let e = expect();
        let mut ok = plane(1.0);
        check_field("ok", &mut ok, &e).unwrap();
        assert_eq!(ok, plane(1.0), "a distance field passes unchanged");

        // ±∞ are far distances, clamped to ±γ.
        let mut inf = plane(1.0);
        inf.set(Coord::new(0, 0, 0), f32::NEG_INFINITY).unwrap();
        inf.set(Coord::new(11, 4, 5), f32::INFINITY).unwrap();
        check_field("inf", &mut inf, &e).unwrap();
        assert_eq!(inf.get(Coord::new(0, 0, 0)), Some(-3.0));
        assert_eq!(inf.get(Coord::new(11, 4, 5)), Some(3.0));

        let mut nan = plane(1.0);
        nan.set(Coord::new(3, 2, 1), f32::NAN).unwrap();
        let err = check_field("nan", &mut nan, &e).unwrap_err();
        assert!(matches!(err, InputError::NaN { coord, .. } if coord == Coord::new(3, 2, 1)));
        assert!(err.to_string().contains("arr[1, 2, 3]"), "{err}");

        for (value, inside) in [(-5.0, true), (0.0, false), (7.0, false)] {
            let mut f = DenseField::new(Coord::new(0, 0, 0), [4, 4, 4], value).unwrap();
            let err = check_field("flat", &mut f, &e).unwrap_err();
            assert!(
                matches!(err, InputError::NoInterface { inside: i, .. } if i == inside),
                "{err}"
            );
            let msg = err.to_string();
            assert!(msg.contains("no interface") && msg.contains("empty"), "{msg}");
        }

        let mut steep = plane(1000.0);
        let err = check_field("steep", &mut steep, &e).unwrap_err();
        assert!(matches!(err, InputError::NotDistance { pairs: 30, .. }), "{err}");
        assert!(err.to_string().contains("levelset distance"), "{err}");
        // ... which is any level set to a tool that makes distance fields.
        let mut steep = plane(1000.0);
        check_field("steep", &mut steep, &Expect { distance_field: false, ..e }).unwrap();
        // A neighbouring +∞ / −∞ pair is a sign change outside the band too.
        let mut jump = plane(1.0);
        jump.set(Coord::new(5, 0, 0), f32::NEG_INFINITY).unwrap();
        jump.set(Coord::new(6, 0, 0), f32::INFINITY).unwrap();
        assert!(matches!(
            check_field("jump", &mut jump, &e),
            Err(InputError::NotDistance { pairs: 1, .. })
        ));
        // A shallow field: the distance × 0.1 changes by 0.1 voxel across its 30 crossings
        // (volumes, areas and speeds would be off tenfold); × 0.2 still by less than a
        // quarter of a voxel; × 0.5, a mask's ±1 and a tool that makes distances pass.
        for scale in [0.1, 0.2] {
            let err = check_field("shallow", &mut plane(scale), &e).unwrap_err();
            assert!(matches!(err, InputError::Shallow { shallow: 30, crossings: 30, .. }), "{err}");
            assert!(err.to_string().contains("levelset distance"), "{err}");
        }
        check_field("half", &mut plane(0.5), &e).unwrap();
        let mut mask =
            DenseField::from_fn(
                Coord::new(0, 0, 0),
                [12, 5, 6],
                |c| {
                    if c.x < 6 {
                        -1.0
                    } else {
                        1.0
                    }
                },
            )
            .unwrap();
        check_field("mask", &mut mask, &e).unwrap();
        check_field("shallow", &mut plane(0.1), &Expect { distance_field: false, ..e }).unwrap();
    }

    #[test]
    fn the_isovalue_lies_in_the_band_and_finds_an_interface() {
        let e = expect();
        for iso in [3.0, -3.0, 100.0, f64::NAN, f64::INFINITY] {
            let err = check_field("p", &mut plane(1.0), &Expect { iso, ..e }).unwrap_err();
            assert!(matches!(err, InputError::IsoOutsideBand { .. }), "{iso}: {err}");
            assert!(err.to_string().contains("outside the band"), "{err}");
        }
        check_field("p", &mut plane(1.0), &Expect { iso: 2.5, ..e }).unwrap();
        // φ ∈ [-0.55, 0.55]: no voxel is inside the level -1.5; and a value equal to the
        // isovalue counts as outside.
        let mut narrow = plane(0.1);
        let err = check_field("n", &mut narrow, &Expect { iso: -1.5, ..e }).unwrap_err();
        assert!(matches!(err, InputError::NoInterface { inside: false, .. }), "{err}");
        let mut zeros = DenseField::new(Coord::new(0, 0, 0), [3, 3, 3], 0.0).unwrap();
        assert!(check_field("z", &mut zeros, &e).is_err());
    }

    #[test]
    fn shapes_are_checked_before_anything_is_built() {
        let e = expect();
        let sphere = |center, radius| Shape::Sphere { center, radius };
        check_shape("sphere", &sphere([0.0; 3], 10.0), &e).unwrap();
        let err = check_shape("sphere", &sphere([0.0; 3], -1.0), &e).unwrap_err();
        assert!(err.to_string().contains("radius"), "{err}");
        let err = check_shape("sphere", &sphere([0.0; 3], 10.0), &Expect { iso: 3.0, ..e });
        assert!(matches!(err, Err(InputError::IsoOutsideBand { .. })));
        let err = check_shape("sphere", &sphere([2147483640.0, 0.0, 0.0], 10.0), &e).unwrap_err();
        assert!(err.to_string().contains("i32"), "{err}");
        let err = check_shape("sphere", &sphere([0.0; 3], 1e8), &e).unwrap_err();
        assert!(matches!(err, InputError::OutOfMemory { .. }), "{err}");
        // In the i32 range: accepted (meshes there are written with f64 positions).
        check_shape("far", &sphere([2147483000.0, 0.0, 0.0], 10.0), &e).unwrap();
    }

    #[test]
    fn files_are_sized_before_they_are_read() {
        let dir = std::env::temp_dir().join(format!("levelset-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plane.npy");
        npy::write_npy(&path, &plane(1.0)).unwrap();
        assert_eq!(load_npy(&path, &expect()).unwrap(), plane(1.0));
        let mut nan = plane(1.0);
        nan.set(Coord::new(3, 2, 1), f32::NAN).unwrap();
        npy::write_npy(&path, &nan).unwrap();
        let err = load_npy(&path, &expect()).unwrap_err();
        assert!(matches!(err, InputError::NaN { .. }), "{err}");
        assert!(err.to_string().starts_with(&path.display().to_string()), "{err}");
        // Working copies that cannot fit are refused before the data are read.
        let err = load_npy(&path, &Expect { copies: 1e15, ..expect() }).unwrap_err();
        assert!(matches!(err, InputError::OutOfMemory { .. }), "{err}");
        let err = load_npy(&dir.join("missing.npy"), &expect()).unwrap_err();
        assert!(matches!(err, InputError::File(NpyError::Io { .. })), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn vdb_files_carry_their_spec_and_name_themselves_in_errors() {
        let dir = std::env::temp_dir().join(format!("levelset-input-vdb-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("ball.vdb");
        let spec = GridSpec::new(0.5, [1.0, 2.0, 3.0], 2.5).unwrap();
        let ball = Shape::Sphere { center: [1.0, 2.0, 3.0], radius: 4.0 };
        let tiles = crate::storage::convert::tiles_from_shape(&ball, spec).unwrap();
        crate::io::vdb::save(&path, &tiles, &Default::default()).unwrap();
        let (grid, info) = load_vdb(&path, &expect()).unwrap();
        assert_eq!(*grid.spec(), spec, "the file's spec replaces the expected one");
        assert_eq!(info.half_width, 2.5);
        // γ = 1.25 here: an isovalue of 2 is outside the file's band.
        let err = load_vdb(&path, &Expect { iso: 2.0, ..expect() }).unwrap_err();
        assert!(matches!(err, InputError::IsoOutsideBand { .. }), "{err}");
        let err = load_vdb(&path, &Expect { copies: 1e15, ..expect() }).unwrap_err();
        assert!(matches!(err, InputError::OutOfMemory { .. }), "{err}");
        std::fs::write(&path, b"VDB? no").unwrap();
        let err = load_vdb(&path, &expect()).unwrap_err();
        assert!(matches!(err, InputError::Vdb(_)), "{err}");
        assert!(err.to_string().starts_with(&path.display().to_string()), "{err}");
        assert!(err.to_string().contains("not an OpenVDB"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
