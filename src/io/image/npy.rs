//! `.npy` images of any integer, bool or float dtype, 2-D or 3-D. [`crate::io::npy`] reads
//! only 3-D `float32` level sets and keeps its header parser private, so the header is
//! parsed here, with the same strictness: nothing is allocated from what the header says
//! before its sizes are checked against the file and the machine.

use super::voxels::{self, Scalar};
use super::{
    check_dims, check_finite, check_memory, Image, ImageError, LoadedImage, Payload, Source,
    IDENTITY,
};
use npyz::WriterBuilder;
use std::fs::File;
use std::io::{self, BufReader};
use std::path::Path;

const FORMAT: &str = ".npy";
const MAGIC: &[u8; 6] = b"\x93NUMPY";
/// Headers longer than this are refused before allocating (NumPy refuses more than
/// 10 000 bytes by default).
const MAX_HEADER_LEN: usize = 1 << 16;
const SUPPORTED: &str = "bool, u1, i1, u2, i2, u4, i4, u8, i8 (either byte order), f4, f8";

/// The header dict.
struct Header {
    descr: String,
    fortran_order: bool,
    shape: Vec<u64>,
}

/// The element type of a `descr` such as `'<i2'`: the type and whether it is big-endian.
fn scalar_of(descr: &str) -> Option<(Scalar, bool)> {
    let b = descr.as_bytes();
    if b.len() < 3 {
        return None;
    }
    let big = match b[0] {
        b'<' => false,
        b'>' => true,
        b'|' | b'=' => cfg!(target_endian = "big"),
        _ => return None,
    };
    let kind = match &descr[1..] {
        "b1" => Scalar::Bool,
        "u1" => Scalar::U8,
        "i1" => Scalar::I8,
        "u2" => Scalar::U16,
        "i2" => Scalar::I16,
        "u4" => Scalar::U32,
        "i4" => Scalar::I32,
        "u8" => Scalar::U64,
        "i8" => Scalar::I64,
        "f4" => Scalar::F32,
        "f8" => Scalar::F64,
        _ => return None,
    };
    // '|' (no byte order) only for one-byte types, as NumPy writes them.
    if b[0] == b'|' && kind.size() != 1 {
        return None;
    }
    Some((kind, big))
}

/// Reads a `.npy` image (see the module docs of [`super`]).
pub(super) fn read(path: &Path, spacing: Option<[f64; 3]>) -> Result<LoadedImage, ImageError> {
    let p = || path.to_path_buf();
    let io_err = |source: io::Error| {
        if source.kind() == io::ErrorKind::UnexpectedEof {
            ImageError::Truncated { path: p(), detail: format!("the file ends early ({source})") }
        } else {
            ImageError::Io { path: p(), source }
        }
    };
    let corrupt = |reason: String| ImageError::Corrupt { path: p(), format: FORMAT, reason };
    let file = File::open(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    if meta.is_dir() {
        return Err(io_err(io::Error::new(io::ErrorKind::IsADirectory, "it is a directory")));
    }
    let file_len = meta.is_file().then_some(meta.len());
    let mut r = BufReader::with_capacity(1 << 16, file);

    // Preamble: magic, version, header length.
    let mut pre = [0u8; 12];
    let got = voxels::read_full(&mut r, &mut pre[..8]).map_err(io_err)?;
    if got < 6 || &pre[..6] != MAGIC {
        return Err(corrupt("it does not start with the magic bytes \\x93NUMPY".to_string()));
    }
    if got < 8 {
        return Err(ImageError::Truncated {
            path: p(),
            detail: "the file ends inside the format version".to_string(),
        });
    }
    let len_bytes = match (pre[6], pre[7]) {
        (1, 0) => 2,
        (2, 0) | (3, 0) => 4,
        (major, minor) => {
            return Err(ImageError::Unsupported {
                path: p(),
                what: format!(".npy format version {major}.{minor} (1.0, 2.0 and 3.0 are read) is"),
            })
        }
    };
    let got = voxels::read_full(&mut r, &mut pre[8..8 + len_bytes]).map_err(io_err)?;
    if got < len_bytes {
        return Err(ImageError::Truncated {
            path: p(),
            detail: "the file ends inside the header length".to_string(),
        });
    }
    let mut lb = [0u8; 4];
    lb[..len_bytes].copy_from_slice(&pre[8..8 + len_bytes]);
    let header_len = u32::from_le_bytes(lb) as usize;
    if header_len > MAX_HEADER_LEN {
        return Err(corrupt(format!("header length {header_len} bytes is implausibly large")));
    }
    let preamble = 8 + len_bytes as u64;
    if let Some(len) = file_len
        && len < preamble + header_len as u64
    {
        return Err(ImageError::Truncated {
            path: p(),
            detail: format!(
                "the file ends inside the header: it announces {header_len} header bytes, \
                     {} follow",
                len - preamble
            ),
        });
    }
    let mut text = vec![0u8; header_len];
    let got = voxels::read_full(&mut r, &mut text).map_err(io_err)?;
    if got < header_len {
        return Err(ImageError::Truncated {
            path: p(),
            detail: format!(
                "the file ends inside the header: it announces {header_len} header bytes, {got} \
                 follow"
            ),
        });
    }
    let header = parse_header(&text).map_err(|e| corrupt(format!("malformed header: {e}")))?;

    // The dtype and the shape.
    let Some((kind, big)) = scalar_of(&header.descr) else {
        return Err(ImageError::UnsupportedVoxelType {
            path: p(),
            found: format!("'{}'", header.descr),
            supported: SUPPORTED,
        });
    };
    let shape = &header.shape;
    let shape_text = format!(
        "shape ({})",
        shape.iter().map(u64::to_string).collect::<Vec<_>>().join(", ")
            + if shape.len() == 1 { "," } else { "" }
    );
    let (ndim, dims) = match shape[..] {
        [ny, nx] => (2, [nx, ny, 1]),
        [nz, ny, nx] => (3, [nx, ny, nz]),
        _ => {
            return Err(ImageError::BadDimensions {
                path: p(),
                reason: format!(
                    "an array of {shape_text}: a 2-D (ny, nx) or 3-D (nz, ny, nx) array is \
                     required"
                ),
            })
        }
    };
    let dims = check_dims(path, dims, &format!("the array of {shape_text}"))?;
    let n = dims[0] as u64 * dims[1] as u64; // each < 2^31: no overflow
    let (n, bytes) = match n.checked_mul(dims[2] as u64).and_then(|n| {
        let bytes = n.checked_mul(kind.size() as u64)?;
        Some((usize::try_from(n).ok()?, bytes))
    }) {
        Some(nb) => nb,
        None => {
            return Err(ImageError::TooLarge {
                path: p(),
                what: format!("the array of {shape_text}"),
                needed: u64::MAX,
                limit: crate::memory::limit(),
            })
        }
    };
    if let Some(len) = file_len {
        let found = len - preamble - header_len as u64;
        if found < bytes {
            return Err(ImageError::Truncated {
                path: p(),
                detail: format!(
                    "the header announces {bytes} bytes of data ({shape_text}, '{}'), {found} \
                     follow",
                    header.descr
                ),
            });
        }
        if found > bytes {
            return Err(corrupt(format!(
                "{} unexpected bytes after the data (the header announces {bytes} bytes, the \
                 file holds {found}); the header's shape or dtype does not describe the data",
                found - bytes
            )));
        }
    }
    check_memory(
        path,
        Some(n as u64 * 4 + 3 * voxels::CHUNK as u64),
        &format!("its {}×{}×{} intensities", dims[0], dims[1], dims[2]),
    )?;

    // The data, scattered into x-fastest order when Fortran-ordered.
    let [nx, ny, nz] = dims;
    let data = if header.fortran_order {
        // File element f is arr[z, y, x] with f = z + nz (y + ny x).
        let mut data = vec![0.0f32; n];
        voxels::read_voxels(&mut r, kind, big, None, n, path, &io_err, |start, chunk| {
            for (k, &v) in chunk.iter().enumerate() {
                let f = start + k;
                let (z, rest) = (f % nz, f / nz);
                let (y, x) = (rest % ny, rest / ny);
                data[x + nx * (y + ny * z)] = v;
            }
        })?;
        data
    } else {
        let mut data = Vec::with_capacity(n);
        voxels::read_voxels(&mut r, kind, big, None, n, path, &io_err, |_, chunk| {
            data.extend_from_slice(chunk)
        })?;
        data
    };
    check_finite(path, dims, &data)?;
    let image = Image { dims, spacing: spacing.unwrap_or([1.0; 3]), data, to_world: IDENTITY };
    let source = Source::Npy {
        ndim,
        dtype: format!("'{}'", header.descr),
        fortran_order: header.fortran_order,
    };
    Ok(LoadedImage { image, source })
}

/// Writes `data` like `like` as a C-ordered `.npy` of the input's 2-D or 3-D shape,
/// atomically.
pub(super) fn write(path: &Path, like: &LoadedImage, data: Payload<'_>) -> Result<(), ImageError> {
    let [nx, ny, nz] = like.image.dims.map(|d| d as u64);
    let shape: &[u64] = if like.is_2d_source() && nz == 1 { &[ny, nx] } else { &[nz, ny, nx] };
    crate::io::fsutil::write_atomic(path, |w| {
        let header = |descr: &str| npyz::DType::Plain(descr.parse().expect("valid type string"));
        match data {
            Payload::Mask(_) => npyz::WriteOptions::<u8>::new()
                .dtype(header("|u1"))
                .shape(shape)
                .writer(&mut *w)
                .write_header_only()?,
            Payload::Float(_) => npyz::WriteOptions::<f32>::new()
                .dtype(header("<f4"))
                .shape(shape)
                .writer(&mut *w)
                .write_header_only()?,
        };
        data.write_to(&mut *w)
    })
    .map_err(|source| ImageError::Io { path: path.to_path_buf(), source })
}

/// Parses the header dict with the library's `.npy` header parser
/// ([`crate::io::npy`]'s: keys in any order, single or double quotes, an optional trailing
/// comma, Python 2's `L` suffix); a structured dtype (a list) is refused as no image.
fn parse_header(text: &[u8]) -> Result<Header, String> {
    let h = crate::io::npy::parse_header(text)?;
    if h.descr.is_empty() {
        return Err(format!("a structured dtype {} is not an image", h.descr_text));
    }
    Ok(Header { descr: h.descr, fortran_order: h.fortran_order, shape: h.shape })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_numpy_writes_parse() {
        for (text, descr, fortran, shape) in [
            (
                "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4), }",
                "<f4",
                false,
                &[2, 3, 4][..],
            ),
            ("{'descr': '|u1', 'fortran_order': True, 'shape': (5,), }  \n", "|u1", true, &[5][..]),
            (
                "{\"shape\": [2L, 3L], \"fortran_order\": False, \"descr\": \">i2\"}",
                ">i2",
                false,
                &[2, 3][..],
            ),
            ("{'descr':'<f8','fortran_order':False,'shape':()}", "<f8", false, &[][..]),
        ] {
            let h = parse_header(text.as_bytes()).unwrap_or_else(|e| panic!("{text}: {e}"));
            assert_eq!((h.descr.as_str(), h.fortran_order, &h.shape[..]), (descr, fortran, shape));
        }
        for bad in [
            "",
            "{'descr': '<f4', 'fortran_order': False}",
            "{'descr': '<f4', 'descr': '<f4', 'fortran_order': False, 'shape': (2,)}",
            "{'descr': [('a', '<f4')], 'fortran_order': False, 'shape': (2,)}",
            "{'descr': '<f4', 'fortran_order': 0, 'shape': (2,)}",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (-2,)}",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999,)}",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2,)} junk",
            "{'descr': '<f4', 'fortran_order': False, 'shape': ((2,),)}",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3",
        ] {
            assert!(parse_header(bad.as_bytes()).is_err(), "{bad}");
        }
    }

    #[test]
    fn dtypes() {
        assert_eq!(scalar_of("<f4"), Some((Scalar::F32, false)));
        assert_eq!(scalar_of(">i2"), Some((Scalar::I16, true)));
        assert_eq!(scalar_of("|b1").map(|s| s.0), Some(Scalar::Bool));
        for bad in ["<f2", "|f4", "<c8", "<U3", "f4", "<f4 ", "O"] {
            assert_eq!(scalar_of(bad), None, "{bad}");
        }
    }
}
