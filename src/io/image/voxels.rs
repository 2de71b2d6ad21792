//! Voxel types of image files and their decoding into `f32`, shared by the NIfTI,
//! `.npy`, MetaImage and NRRD readers: the data are read in chunks of [`CHUNK`] bytes and
//! decoded chunk by chunk, so that reading never holds more than the `f32` intensities and
//! one chunk.

use super::ImageError;
use std::io::{self, Read};
use std::path::Path;

/// Bytes read and decoded at a time (a multiple of every element size).
pub(crate) const CHUNK: usize = 1 << 20;

/// A scalar voxel type of a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    /// NumPy `bool` (one byte, 0 or 1).
    Bool,
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

impl Scalar {
    /// Bytes per element.
    pub(crate) fn size(self) -> usize {
        match self {
            Scalar::Bool | Scalar::U8 | Scalar::I8 => 1,
            Scalar::U16 | Scalar::I16 => 2,
            Scalar::U32 | Scalar::I32 | Scalar::F32 => 4,
            Scalar::U64 | Scalar::I64 | Scalar::F64 => 8,
        }
    }
}

/// Linear rescaling `v · slope + inter` of decoded values (NIfTI's `scl_slope`,
/// `scl_inter`), computed in `f64` and rounded once to `f32`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Rescale {
    pub slope: f64,
    pub inter: f64,
}

/// An element type as stored in a file.
trait Elem: Copy {
    const N: usize;
    fn read<const BIG: bool>(b: &[u8]) -> Self;
    /// The value rounded once to `f32`.
    fn to_f32(self) -> f32;
    fn to_f64(self) -> f64;
}

macro_rules! elem {
    ($($t:ty),*) => {$(
        impl Elem for $t {
            const N: usize = std::mem::size_of::<$t>();
            #[inline(always)]
            fn read<const BIG: bool>(b: &[u8]) -> Self {
                let a: [u8; std::mem::size_of::<$t>()] = b.try_into().expect("element size");
                if BIG { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) }
            }
            #[inline(always)]
            fn to_f32(self) -> f32 {
                self as f32
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
        }
    )*};
}
elem!(u8, i8, u16, i16, u32, i32, u64, i64, f32, f64);

/// Decodes whole elements of `bytes` into `out` (cleared first). The byte order and the
/// rescaling are decided here, once per chunk, not per voxel.
pub(crate) fn decode(
    kind: Scalar,
    big_endian: bool,
    rescale: Option<Rescale>,
    bytes: &[u8],
    out: &mut Vec<f32>,
) {
    debug_assert_eq!(bytes.len() % kind.size(), 0);
    out.clear();
    fn go<T: Elem>(big: bool, rescale: Option<Rescale>, bytes: &[u8], out: &mut Vec<f32>) {
        match (big, rescale) {
            (false, None) => run::<T, false>(bytes, out, T::to_f32),
            (true, None) => run::<T, true>(bytes, out, T::to_f32),
            (false, Some(Rescale { slope, inter })) => {
                run::<T, false>(bytes, out, |v| (v.to_f64() * slope + inter) as f32)
            }
            (true, Some(Rescale { slope, inter })) => {
                run::<T, true>(bytes, out, |v| (v.to_f64() * slope + inter) as f32)
            }
        }
    }
    fn run<T: Elem, const BIG: bool>(bytes: &[u8], out: &mut Vec<f32>, f: impl Fn(T) -> f32) {
        out.extend(bytes.chunks_exact(T::N).map(|b| f(T::read::<BIG>(b))));
    }
    match kind {
        // A NumPy bool is one byte holding 0 or 1; any other byte reads as true (NumPy
        // itself treats non-zero bytes as true).
        Scalar::Bool => out.extend(bytes.iter().map(|&b| (b != 0) as u8 as f32)),
        Scalar::U8 => go::<u8>(big_endian, rescale, bytes, out),
        Scalar::I8 => go::<i8>(big_endian, rescale, bytes, out),
        Scalar::U16 => go::<u16>(big_endian, rescale, bytes, out),
        Scalar::I16 => go::<i16>(big_endian, rescale, bytes, out),
        Scalar::U32 => go::<u32>(big_endian, rescale, bytes, out),
        Scalar::I32 => go::<i32>(big_endian, rescale, bytes, out),
        Scalar::U64 => go::<u64>(big_endian, rescale, bytes, out),
        Scalar::I64 => go::<i64>(big_endian, rescale, bytes, out),
        Scalar::F32 => go::<f32>(big_endian, rescale, bytes, out),
        Scalar::F64 => go::<f64>(big_endian, rescale, bytes, out),
    }
}

/// Maps a read failure: in a compressed stream (`codec`, e.g. "gzip"), bad data are
/// [`ImageError::Corrupt`]; an early end is [`ImageError::Truncated`]; anything else is
/// [`ImageError::Io`].
pub(crate) fn stream_error(path: &Path, codec: Option<&'static str>, e: io::Error) -> ImageError {
    let path = path.to_path_buf();
    match (e.kind(), codec) {
        (io::ErrorKind::UnexpectedEof, _) => {
            ImageError::Truncated { path, detail: format!("the stream ends early ({e})") }
        }
        (io::ErrorKind::InvalidInput | io::ErrorKind::InvalidData, Some(format)) => {
            ImageError::Corrupt { path, format, reason: e.to_string() }
        }
        _ => ImageError::Io { path, source: e },
    }
}

/// Reads as many bytes as `r` gives, up to `buf.len()`; returns how many were read.
pub(crate) fn read_full(r: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Reads `count` elements of `kind` from `r` and hands them, decoded, to `sink` in
/// chunks, with the index of each chunk's first element. A stream that ends early is
/// [`ImageError::Truncated`]; other read failures go through `io_error`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn read_voxels(
    r: &mut impl Read,
    kind: Scalar,
    big_endian: bool,
    rescale: Option<Rescale>,
    count: usize,
    path: &Path,
    io_error: &dyn Fn(io::Error) -> ImageError,
    mut sink: impl FnMut(usize, &[f32]),
) -> Result<(), ImageError> {
    let size = kind.size();
    let total = count as u64 * size as u64;
    let mut buf = vec![0u8; CHUNK.min(count.saturating_mul(size))];
    let mut decoded = Vec::with_capacity(buf.len() / size);
    let mut done = 0usize;
    while done < count {
        let n = (count - done).min(CHUNK / size);
        let got = read_full(r, &mut buf[..n * size]).map_err(io_error)?;
        if got < n * size {
            return Err(ImageError::Truncated {
                path: path.to_path_buf(),
                detail: format!(
                    "the header announces {total} bytes of voxel data, only {} follow",
                    done as u64 * size as u64 + got as u64
                ),
            });
        }
        decode(kind, big_endian, rescale, &buf[..n * size], &mut decoded);
        sink(done, &decoded);
        done += n;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decodes_every_type_in_both_byte_orders() {
        let mut out = Vec::new();
        let v: i16 = -12345;
        decode(Scalar::I16, false, None, &v.to_le_bytes(), &mut out);
        assert_eq!(out, [-12345.0]);
        decode(Scalar::I16, true, None, &v.to_be_bytes(), &mut out);
        assert_eq!(out, [-12345.0]);
        let f = 1.5f64;
        let r = Some(Rescale { slope: 2.0, inter: -1.0 });
        decode(Scalar::F64, true, r, &f.to_be_bytes(), &mut out);
        assert_eq!(out, [2.0]);
        decode(Scalar::U64, false, None, &u64::MAX.to_le_bytes(), &mut out);
        assert_eq!(out, [u64::MAX as f32]);
        decode(Scalar::Bool, false, None, &[0, 1, 7], &mut out);
        assert_eq!(out, [0.0, 1.0, 1.0]);
        decode(Scalar::I8, false, None, &[0xff], &mut out);
        assert_eq!(out, [-1.0]);
    }
}
