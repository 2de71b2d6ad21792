//! NRRD (teem's "nearly raw raster data"): a text header of `field: description` lines
//! after the magic `NRRD000x`, ended by a blank line and followed by the voxels, or naming
//! the file that holds them (`data file`, usually in a `.nhdr`). Parsed here by a strict
//! reader: each field once, every size checked before the voxels are read
//! ([`super::textheader`]). Written like ITK writes it (`NRRD0004`, `space directions`,
//! `space origin`).

use super::meta::clip;
use super::textheader::{self, Codec, Data, Lines, Skip};
use super::voxels::Scalar;
use super::{
    check_dims, check_spacing, Image, ImageError, LoadedImage, NrrdSource, Payload, Source,
    WorldFrame,
};
use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::Path;

const FORMAT: &str = "NRRD";
/// The types [`read`] decodes, for messages.
const SUPPORTED: &str = "int8, uint8, int16, uint16, int32, uint32, int64, uint64, float, \
                         double (and their C names: signed char, unsigned short, long long, ...)";

/// The fields [`read`] interprets; others (`content`, `units`, `axis mins`, `centerings`,
/// `measurement frame`, ...) are not needed and skipped. Names are compared without case
/// and spaces (`data file` and `datafile` are one field).
const FIELDS: &[&str] = &[
    "type",
    "dimension",
    "sizes",
    "endian",
    "encoding",
    "spacings",
    "space",
    "spacedimension",
    "spacedirections",
    "spaceorigin",
    "kinds",
    "datafile",
    "lineskip",
    "byteskip",
];

/// A `type` (any of teem's spellings) and its standard name.
fn scalar_of(name: &str) -> Option<(Scalar, &'static str)> {
    let name = name.split_whitespace().collect::<Vec<_>>().join(" ").to_ascii_lowercase();
    Some(match name.as_str() {
        "signed char" | "int8" | "int8_t" => (Scalar::I8, "int8"),
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => (Scalar::U8, "uint8"),
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            (Scalar::I16, "int16")
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
            (Scalar::U16, "uint16")
        }
        "int" | "signed int" | "int32" | "int32_t" => (Scalar::I32, "int32"),
        "uint" | "unsigned int" | "uint32" | "uint32_t" => (Scalar::U32, "uint32"),
        "longlong"
        | "long long"
        | "long long int"
        | "signed long long"
        | "signed long long int"
        | "int64"
        | "int64_t" => (Scalar::I64, "int64"),
        "ulonglong" | "unsigned long long" | "unsigned long long int" | "uint64" | "uint64_t" => {
            (Scalar::U64, "uint64")
        }
        "float" => (Scalar::F32, "float"),
        "double" => (Scalar::F64, "double"),
        _ => return None,
    })
}

/// A `space`: its full name, dimension and frame; `Err(true)` for a space with time (not
/// read), `Err(false)` for an unknown name.
fn space_of(name: &str) -> Result<(&'static str, WorldFrame), bool> {
    Ok(match name.trim().to_ascii_lowercase().as_str() {
        "right-anterior-superior" | "ras" => ("right-anterior-superior", WorldFrame::Ras),
        "left-anterior-superior" | "las" => ("left-anterior-superior", WorldFrame::Las),
        "left-posterior-superior" | "lps" => ("left-posterior-superior", WorldFrame::Lps),
        "scanner-xyz" => ("scanner-xyz", WorldFrame::Unspecified),
        "3d-right-handed" => ("3D-right-handed", WorldFrame::Unspecified),
        "3d-left-handed" => ("3D-left-handed", WorldFrame::Unspecified),
        "right-anterior-superior-time"
        | "rast"
        | "left-anterior-superior-time"
        | "last"
        | "left-posterior-superior-time"
        | "lpst"
        | "scanner-xyz-time"
        | "3d-right-handed-time"
        | "3d-left-handed-time" => return Err(true),
        _ => return Err(false),
    })
}

/// The space name written for a frame.
fn space_name(frame: WorldFrame) -> Option<&'static str> {
    match frame {
        WorldFrame::Ras => Some("right-anterior-superior"),
        WorldFrame::Las => Some("left-anterior-superior"),
        WorldFrame::Lps => Some("left-posterior-superior"),
        WorldFrame::Unspecified => None,
    }
}

/// Vectors `(a,b,c)` or `none`, separated by spaces (`space directions`, `space origin`).
fn vectors(s: &str) -> Result<Vec<Option<Vec<f64>>>, String> {
    let mut out = Vec::new();
    let mut rest = s.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix('(') {
            let end = r.find(')').ok_or("a '(' without ')'")?;
            let v: Result<Vec<f64>, _> = r[..end].split(',').map(|c| c.trim().parse()).collect();
            out.push(Some(
                v.map_err(|_| format!("({}) is not a vector of numbers", clip(&r[..end], 60)))?,
            ));
            rest = r[end + 1..].trim_start();
        } else if rest.len() >= 4
            && rest.is_char_boundary(4)
            && rest[..4].eq_ignore_ascii_case("none")
        {
            out.push(None);
            rest = rest[4..].trim_start();
        } else {
            return Err(format!("{} is neither a vector (x,y,z) nor none", clip(rest, 40)));
        }
    }
    Ok(out)
}

/// Kinds of axes that are positions in space (`???` and `none`: unknown, taken as such).
fn spatial_kind(kind: &str) -> bool {
    matches!(kind.to_ascii_lowercase().as_str(), "domain" | "space" | "???" | "none")
}

/// The header's fields, with what turns them into values.
struct Header<'a> {
    fields: BTreeMap<&'static str, String>,
    path: &'a Path,
}

impl Header<'_> {
    fn corrupt(&self, reason: String) -> ImageError {
        ImageError::Corrupt { path: self.path.to_path_buf(), format: FORMAT, reason }
    }

    fn get(&self, key: &str) -> Option<&str> {
        self.fields.get(key).map(String::as_str)
    }

    /// A field by its name as written in headers (`data file`).
    fn required(&self, name: &str) -> Result<&str, ImageError> {
        let key: String = name.chars().filter(|c| *c != ' ').collect();
        self.get(&key).ok_or_else(|| self.corrupt(format!("the header has no \"{name}\" field")))
    }

    /// `count` values of a field, one per axis.
    fn per_axis<T: std::str::FromStr>(
        &self,
        key: &str,
        name: &str,
        count: usize,
    ) -> Result<Option<Vec<T>>, ImageError> {
        let Some(v) = self.get(key) else { return Ok(None) };
        match textheader::numbers(v, count) {
            Ok(x) => Ok(Some(x)),
            Err(Some(n)) => {
                Err(self
                    .corrupt(format!("{name}: {} holds {n} values for {count} axes", clip(v, 80))))
            }
            Err(None) => {
                Err(self.corrupt(format!("{name}: {} is not a list of numbers", clip(v, 80))))
            }
        }
    }

    fn integer(&self, key: &str, name: &str) -> Result<Option<i64>, ImageError> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => v
                .trim()
                .parse()
                .map(Some)
                .map_err(|_| self.corrupt(format!("{name}: {} is not an integer", clip(v, 40)))),
        }
    }
}

/// Reads a NRRD image (see the module docs of [`super`]).
pub(super) fn read(path: &Path, spacing_arg: Option<[f64; 3]>) -> Result<LoadedImage, ImageError> {
    let p = || path.to_path_buf();
    let (file, file_len) =
        textheader::open(path).map_err(|source| ImageError::Io { path: p(), source })?;
    let mut lines = Lines::new(BufReader::with_capacity(1 << 16, file));
    let mut h = Header { fields: BTreeMap::new(), path };

    // The magic, then fields up to a blank line (or the end of a detached header).
    let magic = lines.next_line(path, FORMAT)?.unwrap_or_default();
    let version = magic.strip_prefix("NRRD000").and_then(|v| v.parse::<u8>().ok());
    match version {
        Some(1..=5) => {}
        _ if magic.starts_with("NRRD") => {
            return Err(ImageError::Unsupported {
                path: p(),
                what: format!(
                    "NRRD format {} (NRRD0001 to NRRD0005 are read) is",
                    clip(&magic, 20)
                ),
            })
        }
        _ => return Err(h.corrupt("it does not start with the magic NRRD0001 to NRRD0005".into())),
    }
    let mut blank_line = false;
    while let Some(line) = lines.next_line(path, FORMAT)? {
        if line.is_empty() {
            blank_line = true;
            break;
        }
        if line.starts_with('#') {
            continue;
        }
        let field_end = line.find(": ").or_else(|| line.strip_suffix(':').map(str::len));
        let kv = line.find(":=");
        match (field_end, kv) {
            (_, Some(k)) if field_end.is_none_or(|f| k < f) => continue, // key:=value
            (Some(f), _) => {
                let name = &line[..f];
                let key: String =
                    name.chars().filter(|c| *c != ' ').collect::<String>().to_ascii_lowercase();
                let Some(&known) = FIELDS.iter().find(|&&k| k == key) else { continue };
                let value = line[f + 1..].trim().to_string();
                if h.fields.insert(known, value).is_some() {
                    return Err(
                        h.corrupt(format!("the field \"{}\" appears twice", clip(name, 40)))
                    );
                }
            }
            _ => {
                return Err(h.corrupt(format!(
                    "line {} is neither \"field: description\" nor \"key:=value\": {:?}",
                    lines.number,
                    clip(&line, 60)
                )))
            }
        }
    }

    // Type, encoding, byte order.
    let type_text = h.required("type")?;
    let Some((kind, type_name)) = scalar_of(type_text) else {
        return Err(ImageError::UnsupportedVoxelType {
            path: p(),
            found: clip(type_text, 40),
            supported: SUPPORTED,
        });
    };
    let encoding = h.required("encoding")?;
    let codec = match encoding.to_ascii_lowercase().as_str() {
        "raw" => Codec::Raw,
        "gzip" | "gz" => Codec::Gzip,
        e @ ("txt" | "text" | "ascii" | "hex" | "bzip2" | "bz2" | "zrl" | "zstd") => {
            return Err(ImageError::Unsupported {
                path: p(),
                what: format!("the NRRD encoding {e} (raw and gzip are read) is"),
            })
        }
        other => return Err(h.corrupt(format!("unknown encoding {}", clip(other, 40)))),
    };
    let big = match h.get("endian").map(str::to_ascii_lowercase).as_deref() {
        Some("little") => false,
        Some("big") => true,
        Some(other) => {
            return Err(h.corrupt(format!("endian: {} is neither little nor big", clip(other, 40))))
        }
        None if kind.size() > 1 => {
            return Err(
                h.corrupt(format!("the header has no \"endian\" field for {type_name} data"))
            )
        }
        None => false,
    };

    // Axes: a 2-D or 3-D image, possibly after one non-spatial axis of size 1.
    let dim_text = h.required("dimension")?;
    let dim = match dim_text.trim().parse::<i64>() {
        Ok(d @ 2..=4) => d as usize,
        Ok(d) => {
            return Err(ImageError::BadDimensions {
                path: p(),
                reason: format!(
                    "dimension: {d}: a 2-D or 3-D image is required (after at most one \
                     non-spatial axis of size 1)"
                ),
            })
        }
        Err(_) => {
            return Err(h.corrupt(format!("dimension: {} is not an integer", clip(dim_text, 40))))
        }
    };
    h.required("sizes")?;
    let sizes = h.per_axis::<i64>("sizes", "sizes", dim)?.unwrap_or_default();
    let sizes_text = format!("sizes: {}", h.get("sizes").unwrap_or_default());
    if sizes.iter().any(|&s| s < 1) {
        return Err(ImageError::BadDimensions {
            path: p(),
            reason: format!("{sizes_text}: every size must be ≥ 1"),
        });
    }
    let (space, space_dim, frame) = match (h.get("space"), h.get("spacedimension")) {
        (Some(_), Some(_)) => {
            return Err(h.corrupt("both \"space\" and \"space dimension\" are given".into()))
        }
        (Some(s), None) => match space_of(s) {
            Ok((name, frame)) => (Some(name), 3, frame),
            Err(true) => {
                return Err(ImageError::Unsupported {
                    path: p(),
                    what: format!("the space {} (with time) is", clip(s, 40)),
                })
            }
            Err(false) => return Err(h.corrupt(format!("unknown space {}", clip(s, 40)))),
        },
        (None, Some(d)) => match d.trim().parse::<i64>() {
            Ok(d @ (2 | 3)) => (None, d as usize, WorldFrame::Unspecified),
            _ => {
                return Err(ImageError::Unsupported {
                    path: p(),
                    what: format!("space dimension {} (2 or 3 are read) is", clip(d, 20)),
                })
            }
        },
        (None, None) => (None, 0, WorldFrame::Unspecified),
    };
    let directions = match h.get("spacedirections") {
        None => None,
        Some(_) if space_dim == 0 => {
            return Err(h.corrupt("space directions without a space or space dimension".into()))
        }
        Some(v) => {
            let d = vectors(v).map_err(|e| h.corrupt(format!("space directions: {e}")))?;
            if d.len() != dim {
                return Err(
                    h.corrupt(format!("space directions: {} vectors for {dim} axes", d.len()))
                );
            }
            if let Some(bad) = d.iter().flatten().find(|v| v.len() != space_dim) {
                return Err(h.corrupt(format!(
                    "space directions: a vector of {} components in a space of dimension \
                     {space_dim}",
                    bad.len()
                )));
            }
            Some(d)
        }
    };
    let kinds: Option<Vec<&str>> = h.get("kinds").map(|k| k.split_whitespace().collect());
    if kinds.as_ref().is_some_and(|k| k.len() != dim) {
        return Err(
            h.corrupt(format!("kinds: {} kinds for {dim} axes", kinds.unwrap_or_default().len()))
        );
    }
    let spacings = h.per_axis::<f64>("spacings", "spacings", dim)?;
    let nonspatial = |i: usize| {
        directions.as_ref().is_some_and(|d| d[i].is_none())
            || kinds.as_ref().is_some_and(|k| !spatial_kind(k[i]))
    };
    let kind_of = |i: usize| match &kinds {
        Some(k) => format!(" (kind {})", clip(k[i], 20)),
        None => String::new(),
    };
    if let Some(i) = (1..dim).find(|&i| nonspatial(i)) {
        return Err(ImageError::Unsupported {
            path: p(),
            what: format!(
                "a non-spatial axis after the first (axis {i} of {sizes_text}{}) is; only scalar \
                 images, with at most a leading non-spatial axis of size 1,",
                kind_of(i)
            ),
        });
    }
    let lead = nonspatial(0) || dim == 4;
    if lead && sizes[0] != 1 {
        return Err(ImageError::Unsupported {
            path: p(),
            what: format!(
                "a non-spatial axis of {} samples (axis 0 of {sizes_text}{}: a vector, colour or \
                 time series image; only scalar images are read) is",
                sizes[0],
                kind_of(0)
            ),
        });
    }
    let first = lead as usize;
    let ndim = dim - first;
    if ndim < 2 {
        return Err(ImageError::BadDimensions {
            path: p(),
            reason: format!("{sizes_text}: a 2-D or 3-D image is required"),
        });
    }
    if lead && directions.as_ref().is_some_and(|d| d[0].is_some()) {
        return Err(ImageError::Unsupported {
            path: p(),
            what: "a 4-D image with a space direction for each axis is".to_string(),
        });
    }
    let size = |i: usize| if i < ndim { sizes[first + i] as u64 } else { 1 };
    let dims = check_dims(path, [size(0), size(1), size(2)], &sizes_text)?;

    // Geometry.
    let bad = |which, reason: String| ImageError::BadTransform { path: p(), which, reason };
    let mut spacing = [1.0; 3];
    let mut stored_spacings = None;
    let mut stored_directions = None;
    // A: voxel index → world, as columns (one per axis) and the origin.
    let mut columns = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    if let Some(d) = &directions {
        if spacings.as_ref().is_some_and(|s| (first..dim).any(|i| !s[i].is_nan())) {
            return Err(h.corrupt("both spacings and space directions are given".into()));
        }
        let mut vs = [[0.0; 3]; 3];
        for (i, v) in vs.iter_mut().enumerate().take(ndim) {
            let src = d[first + i].as_deref().unwrap_or_default();
            v[..space_dim].copy_from_slice(src);
        }
        if vs.iter().flatten().any(|v| !v.is_finite()) {
            return Err(bad("space directions", format!("an entry is not finite: {vs:?}")));
        }
        for (i, v) in vs.iter().enumerate().take(ndim) {
            spacing[i] = v.iter().map(|c| c * c).sum::<f64>().sqrt();
            columns[i] = *v;
        }
        check_spacing(path, spacing, "the lengths of the space directions")?;
        if ndim == 2 {
            // The third axis: the unit normal of the image's plane.
            let [a, b] = [vs[0], vs[1]];
            let n =
                [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
            let len = n.iter().map(|c| c * c).sum::<f64>().sqrt();
            columns[2] = if space_dim == 2 { [0.0, 0.0, 1.0] } else { n.map(|c| c / len) };
        }
        if !(textheader::det(&columns) != 0.0 && columns.iter().flatten().all(|v| v.is_finite())) {
            return Err(bad("space directions", format!("the axes are parallel: {vs:?}")));
        }
        stored_directions = Some(vs);
    } else if let Some(s) = &spacings {
        let mut kept = [f64::NAN; 3];
        for i in 0..ndim {
            kept[i] = s[first + i];
            // An unknown spacing (nan) is 1, as ITK reads it.
            spacing[i] = if s[first + i].is_nan() { 1.0 } else { s[first + i] };
        }
        check_spacing(path, spacing, "spacings of the header")?;
        for (i, c) in columns.iter_mut().enumerate() {
            c[i] = spacing[i];
        }
        stored_spacings = Some(kept);
    }
    let origin = match h.get("spaceorigin") {
        None => None,
        Some(_) if space_dim == 0 => {
            return Err(h.corrupt("space origin without a space or space dimension".into()))
        }
        Some(v) => {
            let o = vectors(v).map_err(|e| h.corrupt(format!("space origin: {e}")))?;
            match o.as_slice() {
                [Some(o)] if o.len() == space_dim => {
                    if o.iter().any(|c| !c.is_finite()) {
                        return Err(bad("space origin", format!("an entry is not finite: {o:?}")));
                    }
                    let mut x = [0.0; 3];
                    x[..space_dim].copy_from_slice(o);
                    Some(x)
                }
                _ => {
                    return Err(h.corrupt(format!(
                        "space origin: {} is not one vector of {space_dim} components",
                        clip(v, 60)
                    )))
                }
            }
        }
    };
    let o = origin.unwrap_or([0.0; 3]);
    let spacing_used = spacing_arg.unwrap_or(spacing);
    // to_world = A · diag(1/s).
    let to_world: [[f64; 4]; 3] = std::array::from_fn(|r| {
        [
            columns[0][r] / spacing_used[0],
            columns[1][r] / spacing_used[1],
            columns[2][r] / spacing_used[2],
            o[r],
        ]
    });

    // The voxels.
    let line_skip = match h.integer("lineskip", "line skip")? {
        None => 0,
        Some(k) if k >= 0 => k as u64,
        Some(k) => return Err(h.corrupt(format!("line skip: {k} is negative"))),
    };
    let skip = match (h.integer("byteskip", "byte skip")?, codec) {
        (None, _) => Skip::File(0),
        (Some(-1), _) => Skip::ToEnd,
        (Some(k), Codec::Raw) if k >= 0 => Skip::File(k as u64),
        (Some(k), _) if k >= 0 => Skip::Decoded(k as u64),
        (Some(k), _) => return Err(h.corrupt(format!("byte skip: {k} (it must be -1 or more)"))),
    };
    let mut data_spec = Data {
        format: FORMAT,
        kind,
        type_name,
        big_endian: big,
        dims,
        codec,
        line_skip,
        skip,
        compressed_len: None,
        data_file: None,
    };
    let data = match h.get("datafile") {
        Some(name) => {
            if name.starts_with("LIST") || name.contains('%') {
                return Err(ImageError::Unsupported {
                    path: p(),
                    what: format!("voxels in a list of files (data file: {}) are", clip(name, 60)),
                });
            }
            let (data_path, r, len) = textheader::open_data_file(path, name)?;
            data_spec.data_file = Some(&data_path);
            textheader::read_data(path, r, 0, len, &data_spec)?
        }
        None if !blank_line => {
            return Err(ImageError::Truncated {
                path: p(),
                detail: "the header has no data file and no blank line before the data".to_string(),
            })
        }
        None => textheader::read_data(path, lines.r, lines.consumed, file_len, &data_spec)?,
    };
    let image = Image { dims, spacing: spacing_used, data, to_world };
    let source = Source::Nrrd(NrrdSource {
        ndim,
        dims,
        space,
        space_dim,
        directions: stored_directions,
        origin,
        spacings: stored_spacings,
        gzip: codec == Codec::Gzip,
        type_name,
        frame,
    });
    Ok(LoadedImage { image, source })
}

/// `(a,b,c)` of the first `n` components.
fn vector(v: &[f64; 3], n: usize) -> String {
    format!("({})", textheader::nums(&v[..n], ","))
}

/// Writes `data` like `like` as NRRD: one file (`.nrrd`), or when `detached` a header
/// (`.nhdr`) and a data file beside it (`.raw`, `.raw.gz` when compressed). The geometry
/// is the input's header's for a NRRD input, else the image's, in its own frame (space
/// `right-anterior-superior` for a NIfTI input, `left-posterior-superior` for a
/// MetaImage; only a `space dimension` for an image without an anatomical frame and for
/// a 2-D image, as ITK writes those).
pub(super) fn write(
    path: &Path,
    like: &LoadedImage,
    detached: bool,
    data: Payload<'_>,
) -> Result<(), ImageError> {
    let src = match &like.source {
        Source::Nrrd(n) => {
            let what = "the image with its input's NRRD header";
            textheader::check_source_dims(path, like, n.dims, what)?;
            n.clone()
        }
        _ => {
            let frame = like.world_frame();
            let pl = textheader::placement_of(path, like, frame, "the image as NRRD")?;
            // A 2-D image lying in the plane z = 0 is written in a space of dimension 2, as
            // ITK writes it (ITK does not read two axes in a named 3-D space).
            let space = if pl.ndim == 2 { None } else { space_name(frame) };
            NrrdSource {
                ndim: pl.ndim,
                dims: like.image.dims,
                space,
                space_dim: if space.is_some() { 3 } else { pl.ndim },
                directions: Some(std::array::from_fn(|i| pl.axes[i].map(|c| c * pl.spacing[i]))),
                origin: Some(pl.origin),
                spacings: None,
                gzip: false,
                type_name: "", // not written: the output's type is the payload's
                frame,
            }
        }
    };
    let codec = if src.gzip { Codec::Gzip } else { Codec::Raw };
    let data_file = match detached {
        true => {
            Some(textheader::data_file_name(path, 5, if src.gzip { ".raw.gz" } else { ".raw" })?)
        }
        false => None,
    };
    let n = src.ndim;
    let mut h = vec![
        "NRRD0004".to_string(),
        "# Complete NRRD file format specification at:".to_string(),
        "# http://teem.sourceforge.net/nrrd/format.html".to_string(),
        format!("type: {}", if matches!(data, Payload::Mask(_)) { "uint8" } else { "float" }),
        format!("dimension: {n}"),
    ];
    match src.space {
        Some(s) => h.push(format!("space: {s}")),
        None if src.space_dim > 0 => h.push(format!("space dimension: {}", src.space_dim)),
        None => {}
    }
    h.push(format!(
        "sizes: {}",
        src.dims[..n].iter().map(usize::to_string).collect::<Vec<_>>().join(" ")
    ));
    if let Some(d) = &src.directions {
        let v: Vec<String> = d[..n].iter().map(|v| vector(v, src.space_dim)).collect();
        h.push(format!("space directions: {}", v.join(" ")));
    }
    if let Some(s) = &src.spacings {
        let v: Vec<String> = s[..n]
            .iter()
            .map(|&x| if x.is_nan() { "nan".into() } else { textheader::num(x) })
            .collect();
        h.push(format!("spacings: {}", v.join(" ")));
    }
    h.push(format!("kinds: {}", vec!["domain"; n].join(" ")));
    if matches!(data, Payload::Float(_)) {
        h.push("endian: little".to_string());
    }
    h.push(format!("encoding: {}", if src.gzip { "gzip" } else { "raw" }));
    if let Some(o) = &src.origin {
        h.push(format!("space origin: {}", vector(o, src.space_dim)));
    }
    if let Some(f) = &data_file {
        h.push(format!("data file: {f}"));
    }
    let header = h.join("\n") + "\n\n";
    textheader::write_files(path, &|_| header.clone(), data_file.as_deref(), data, codec)
}
