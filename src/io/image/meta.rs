//! MetaImage (ITK's MetaIO): a text header of `Key = Value` lines ending with
//! `ElementDataFile`, followed by the voxels (`ElementDataFile = LOCAL`, usually `.mha`)
//! or naming the file that holds them (usually `.mhd` with a `.raw`). Parsed here by a
//! strict reader: each key once, every size checked before the voxels are read
//! ([`super::textheader`]). Written like ITK writes it (`TransformMatrix`, `Offset`,
//! little-endian voxels), without `AnatomicalOrientation` (ITK derives it and does not
//! read it back).

use super::textheader::{self, Codec, Data, Lines, Skip};
use super::voxels::Scalar;
use super::{
    check_dims, check_spacing, Image, ImageError, LoadedImage, MetaSource, Payload, Source,
    WorldFrame,
};
use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::Path;

const FORMAT: &str = "MetaImage";
/// The element types [`read`] decodes, for messages.
const SUPPORTED: &str = "MET_UCHAR, MET_CHAR, MET_USHORT, MET_SHORT, MET_UINT, MET_INT, \
                         MET_ULONG, MET_LONG, MET_ULONG_LONG, MET_LONG_LONG, MET_FLOAT, \
                         MET_DOUBLE";

/// An `ElementType` and its name. MetaIO's `MET_LONG` and `MET_ULONG` are 4 bytes.
fn scalar_of(name: &str) -> Option<(Scalar, &'static str)> {
    Some(match name {
        "MET_UCHAR" => (Scalar::U8, "MET_UCHAR"),
        "MET_CHAR" => (Scalar::I8, "MET_CHAR"),
        "MET_USHORT" => (Scalar::U16, "MET_USHORT"),
        "MET_SHORT" => (Scalar::I16, "MET_SHORT"),
        "MET_UINT" => (Scalar::U32, "MET_UINT"),
        "MET_INT" => (Scalar::I32, "MET_INT"),
        "MET_ULONG" => (Scalar::U32, "MET_ULONG"),
        "MET_LONG" => (Scalar::I32, "MET_LONG"),
        "MET_ULONG_LONG" => (Scalar::U64, "MET_ULONG_LONG"),
        "MET_LONG_LONG" => (Scalar::I64, "MET_LONG_LONG"),
        "MET_FLOAT" => (Scalar::F32, "MET_FLOAT"),
        "MET_DOUBLE" => (Scalar::F64, "MET_DOUBLE"),
        _ => return None,
    })
}

/// At most `max` characters of `s`, for messages.
pub(super) fn clip(s: &str, max: usize) -> String {
    match s.char_indices().nth(max) {
        Some((i, _)) => format!("{}…", &s[..i]),
        None => s.to_string(),
    }
}

/// The header's keys and values, with what turns them into numbers.
struct Header<'a> {
    fields: BTreeMap<String, String>,
    path: &'a Path,
}

impl Header<'_> {
    fn corrupt(&self, reason: String) -> ImageError {
        ImageError::Corrupt { path: self.path.to_path_buf(), format: FORMAT, reason }
    }

    fn get(&self, key: &str) -> Option<&str> {
        self.fields.get(key).map(String::as_str)
    }

    fn required(&self, key: &str) -> Result<&str, ImageError> {
        self.get(key).ok_or_else(|| self.corrupt(format!("the header has no {key}")))
    }

    /// The value of `key` as `count` numbers (integers when `T` is).
    fn numbers<T: std::str::FromStr>(
        &self,
        key: &str,
        count: usize,
    ) -> Result<Option<Vec<T>>, ImageError> {
        let Some(v) = self.get(key) else { return Ok(None) };
        match textheader::numbers(v, count) {
            Ok(x) => Ok(Some(x)),
            Err(Some(n)) => {
                Err(self
                    .corrupt(format!("{key} = {} holds {n} values, {count} expected", clip(v, 80))))
            }
            Err(None) => {
                Err(self.corrupt(format!("{key} = {} is not a list of numbers", clip(v, 80))))
            }
        }
    }

    /// A `True`/`False` value (MetaIO also writes `1`/`0`).
    fn flag(&self, key: &str) -> Result<Option<bool>, ImageError> {
        match self.get(key).map(str::to_ascii_lowercase).as_deref() {
            None => Ok(None),
            Some("true" | "1") => Ok(Some(true)),
            Some("false" | "0") => Ok(Some(false)),
            Some(other) => Err(self.corrupt(format!("{key} = {other} is neither True nor False"))),
        }
    }

    /// The value of the first of `keys` present, all others present being equal to it
    /// (MetaIO's synonyms, such as `Offset`, `Position` and `Origin`).
    fn synonyms(
        &self,
        keys: &[&str],
        count: usize,
    ) -> Result<Option<(String, Vec<f64>)>, ImageError> {
        let mut found: Option<(String, Vec<f64>)> = None;
        for &k in keys {
            if let Some(v) = self.numbers::<f64>(k, count)? {
                match &found {
                    Some((first, w)) if *w != v => {
                        return Err(self.corrupt(format!("{first} and {k} disagree")))
                    }
                    Some(_) => {}
                    None => found = Some((k.to_string(), v)),
                }
            }
        }
        Ok(found)
    }
}

/// Reads a MetaImage (see the module docs of [`super`]).
pub(super) fn read(path: &Path, spacing_arg: Option<[f64; 3]>) -> Result<LoadedImage, ImageError> {
    let p = || path.to_path_buf();
    let (file, file_len) =
        textheader::open(path).map_err(|source| ImageError::Io { path: p(), source })?;
    let mut lines = Lines::new(BufReader::with_capacity(1 << 16, file));

    // The header, up to and including ElementDataFile.
    let mut h = Header { fields: BTreeMap::new(), path };
    loop {
        let Some(line) = lines.next_line(path, FORMAT)? else {
            return Err(h.corrupt(if h.fields.is_empty() {
                "the file is empty".to_string()
            } else {
                "the header ends without ElementDataFile (which must be its last line)".to_string()
            }));
        };
        if line.trim().is_empty() {
            continue;
        }
        let Some(at) = line.find(['=', ':']) else {
            return Err(h.corrupt(format!(
                "line {} is not \"Key = Value\": {:?}",
                lines.number,
                clip(&line, 60)
            )));
        };
        let (key, value) = (line[..at].trim(), line[at + 1..].trim());
        if key.is_empty() {
            return Err(h.corrupt(format!(
                "line {} has no key: {:?}",
                lines.number,
                clip(&line, 60)
            )));
        }
        if h.fields.insert(key.to_string(), value.to_string()).is_some() {
            return Err(h.corrupt(format!("{} appears twice in the header", clip(key, 40))));
        }
        if key == "ElementDataFile" {
            break;
        }
    }

    // What the header says.
    if let Some(t) = h.get("ObjectType")
        && t != "Image"
    {
        return Err(ImageError::Unsupported {
            path: p(),
            what: format!("a MetaImage of ObjectType {} (not Image) is", clip(t, 40)),
        });
    }
    if let Some(v) = h.get("FileFormatVersion")
        && v != "0"
    {
        return Err(ImageError::Unsupported {
            path: p(),
            what: format!(
                "MetaImage FileFormatVersion {} (ElementOrigin, ElementDirection) is",
                clip(v, 20)
            ),
        });
    }
    let ndims = h.required("NDims")?;
    let ndim = match ndims.parse::<i64>() {
        Ok(n @ (2 | 3)) => n as usize,
        Ok(n) => {
            return Err(ImageError::BadDimensions {
                path: p(),
                reason: format!("NDims = {n}: a 2-D or 3-D image is required"),
            })
        }
        Err(_) => return Err(h.corrupt(format!("NDims = {} is not an integer", clip(ndims, 40)))),
    };
    h.required("DimSize")?;
    let sizes = h.numbers::<i64>("DimSize", ndim)?.unwrap_or_default();
    let size_text = format!("DimSize = {}", h.get("DimSize").unwrap_or_default());
    if sizes.iter().any(|&s| s < 1) {
        return Err(ImageError::BadDimensions {
            path: p(),
            reason: format!("{size_text}: every size must be ≥ 1"),
        });
    }
    let size = |i: usize| sizes.get(i).map_or(1, |&s| s as u64);
    let dims = check_dims(path, [size(0), size(1), size(2)], &size_text)?;
    if let Some(c) = h.numbers::<i64>("ElementNumberOfChannels", 1)?
        && c[0] != 1
    {
        return Err(ImageError::Unsupported {
            path: p(),
            what: format!(
                "ElementNumberOfChannels = {} (a vector or colour image; only scalar images \
                     are read) is",
                c[0]
            ),
        });
    }
    if h.flag("BinaryData")? == Some(false) {
        return Err(ImageError::Unsupported {
            path: p(),
            what: "voxels written as text (BinaryData = False) are".to_string(),
        });
    }
    let compressed = h.flag("CompressedData")?.unwrap_or(false);
    let big = match (h.flag("BinaryDataByteOrderMSB")?, h.flag("ElementByteOrderMSB")?) {
        (Some(a), Some(b)) if a != b => {
            return Err(h.corrupt("BinaryDataByteOrderMSB and ElementByteOrderMSB disagree".into()))
        }
        (a, b) => a.or(b).unwrap_or(false),
    };
    let type_text = h.required("ElementType")?;
    let Some((kind, element_type)) = scalar_of(type_text) else {
        return Err(ImageError::UnsupportedVoxelType {
            path: p(),
            found: clip(type_text, 40),
            supported: SUPPORTED,
        });
    };

    // Geometry: spacing, direction of each axis, origin.
    let mut spacing = [1.0; 3];
    if let Some((key, s)) =
        h.synonyms(&["ElementSpacing"], ndim)?.or(h.synonyms(&["ElementSize"], ndim)?)
    {
        spacing[..ndim].copy_from_slice(&s);
        check_spacing(path, spacing, &format!("{key} of the header"))?;
    }
    let mut origin = [0.0; 3];
    if let Some((key, o)) = h.synonyms(&["Offset", "Position", "Origin"], ndim)? {
        origin[..ndim].copy_from_slice(&o);
        if o.iter().any(|v| !v.is_finite()) {
            return Err(ImageError::BadTransform {
                path: p(),
                which: "Offset",
                reason: format!("{key} has an entry that is not finite: {o:?}"),
            });
        }
    }
    let mut axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    if let Some((key, t)) =
        h.synonyms(&["TransformMatrix", "Rotation", "Orientation"], ndim * ndim)?
    {
        // MetaIO lists the direction of axis 0, then of axis 1, ...
        for (i, axis) in axes.iter_mut().enumerate().take(ndim) {
            axis[..ndim].copy_from_slice(&t[i * ndim..(i + 1) * ndim]);
        }
        let bad = |reason: String| ImageError::BadTransform {
            path: p(),
            which: "TransformMatrix",
            reason,
        };
        if t.iter().any(|v| !v.is_finite()) {
            return Err(bad(format!("{key} has an entry that is not finite: {t:?}")));
        }
        if textheader::det(&axes) == 0.0 {
            return Err(bad(format!("{key} is singular (determinant 0): {t:?}")));
        }
    }
    let spacing_used = spacing_arg.unwrap_or(spacing);
    // to_world = A · diag(1/s) with A = [axes · spacing | origin]; exact without a
    // spacing argument.
    let factor: [f64; 3] = std::array::from_fn(|i| {
        if spacing[i] == spacing_used[i] {
            1.0
        } else {
            spacing[i] / spacing_used[i]
        }
    });
    let to_world: [[f64; 4]; 3] = std::array::from_fn(|r| {
        [axes[0][r] * factor[0], axes[1][r] * factor[1], axes[2][r] * factor[2], origin[r]]
    });

    // The voxels.
    let header_size = match h.numbers::<i64>("HeaderSize", 1)? {
        None => 0,
        Some(v) if v[0] >= -1 => v[0],
        Some(v) => return Err(h.corrupt(format!("HeaderSize = {} (it must be -1 or more)", v[0]))),
    };
    let compressed_len = match h.numbers::<u64>("CompressedDataSize", 1)? {
        Some(v) if compressed && v[0] > 0 => Some(v[0]),
        _ => None,
    };
    let data_name = h.required("ElementDataFile")?;
    if data_name.starts_with("LIST") || data_name.contains('%') {
        return Err(ImageError::Unsupported {
            path: p(),
            what: format!(
                "voxels in a list of files (ElementDataFile = {}) are",
                clip(data_name, 60)
            ),
        });
    }
    let codec = if compressed { Codec::Zlib } else { Codec::Raw };
    let mut data_spec = Data {
        format: FORMAT,
        kind,
        type_name: element_type,
        big_endian: big,
        dims,
        codec,
        line_skip: 0,
        skip: Skip::File(0),
        compressed_len,
        data_file: None,
    };
    let data = if data_name.eq_ignore_ascii_case("LOCAL") {
        // HeaderSize counts from the start of the file, as MetaIO reads it.
        let consumed = lines.consumed;
        data_spec.skip = match header_size {
            -1 => Skip::ToEnd,
            0 => Skip::File(0),
            k if k as u64 >= consumed => Skip::File(k as u64 - consumed),
            k => {
                return Err(h.corrupt(format!(
                    "HeaderSize = {k} puts the voxels inside the {consumed}-byte header"
                )))
            }
        };
        textheader::read_data(path, lines.r, consumed, file_len, &data_spec)?
    } else {
        let (data_path, r, len) = textheader::open_data_file(path, data_name)?;
        data_spec.skip =
            if header_size == -1 { Skip::ToEnd } else { Skip::File(header_size as u64) };
        data_spec.data_file = Some(&data_path);
        textheader::read_data(path, r, 0, len, &data_spec)?
    };
    let image = Image { dims, spacing: spacing_used, data, to_world };
    let source = Source::MetaImage(MetaSource {
        ndim,
        dims,
        spacing,
        axes,
        origin,
        compressed,
        element_type,
    });
    Ok(LoadedImage { image, source })
}

/// Writes `data` like `like` as a MetaImage: one file (`.mha`), or when `detached` a
/// header (`.mhd`) and a data file beside it (`.raw`, `.zraw` when compressed). The
/// geometry is the input's header's for a MetaImage input, else the image's in LPS.
pub(super) fn write(
    path: &Path,
    like: &LoadedImage,
    detached: bool,
    data: Payload<'_>,
) -> Result<(), ImageError> {
    let (ndim, dims, spacing, axes, origin, compressed) = match &like.source {
        Source::MetaImage(m) => {
            let what = "the image with its input's MetaImage header";
            textheader::check_source_dims(path, like, m.dims, what)?;
            (m.ndim, m.dims, m.spacing, m.axes, m.origin, m.compressed)
        }
        _ => {
            let pl =
                textheader::placement_of(path, like, WorldFrame::Lps, "the image as MetaImage")?;
            (pl.ndim, like.image.dims, pl.spacing, pl.axes, pl.origin, false)
        }
    };
    let codec = if compressed { Codec::Zlib } else { Codec::Raw };
    let data_file = match detached {
        true => {
            Some(textheader::data_file_name(path, 4, if compressed { ".zraw" } else { ".raw" })?)
        }
        false => None,
    };
    let element_type = match data {
        Payload::Mask(_) => "MET_UCHAR",
        Payload::Float(_) => "MET_FLOAT",
    };
    let n = ndim;
    let matrix: Vec<f64> = (0..n).flat_map(|i| axes[i][..n].to_vec()).collect();
    let dim_size = dims[..n].iter().map(usize::to_string).collect::<Vec<_>>().join(" ");
    let header = |len: u64| {
        let mut h = vec![
            "ObjectType = Image".to_string(),
            format!("NDims = {n}"),
            "BinaryData = True".to_string(),
            "BinaryDataByteOrderMSB = False".to_string(),
        ];
        if compressed {
            // ITK does not read compressed data in one file without their size.
            h.push("CompressedData = True".to_string());
            h.push(format!("CompressedDataSize = {len}"));
        } else {
            h.push("CompressedData = False".to_string());
        }
        h.extend([
            format!("TransformMatrix = {}", textheader::nums(&matrix, " ")),
            format!("Offset = {}", textheader::nums(&origin[..n], " ")),
            format!("CenterOfRotation = {}", textheader::nums(&[0.0; 3][..n], " ")),
            format!("ElementSpacing = {}", textheader::nums(&spacing[..n], " ")),
            format!("DimSize = {dim_size}"),
            format!("ElementType = {element_type}"),
            format!("ElementDataFile = {}", data_file.as_deref().unwrap_or("LOCAL")),
        ]);
        h.join("\n") + "\n"
    };
    textheader::write_files(path, &header, data_file.as_deref(), data, codec)
}
