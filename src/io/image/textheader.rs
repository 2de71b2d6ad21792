//! What the two formats with text headers, MetaImage ([`super::meta`]) and NRRD
//! ([`super::nrrd`]), share: header lines read within [`MAX_HEADER_LEN`] bytes, the voxel
//! data located (after the header or in a data file), checked against the file's length
//! and the machine's memory, then decoded (raw, gzip or zlib); and on the way out, the
//! placement a header is written with, numbers that read back exactly, and the pair of
//! files of a detached header.

use super::voxels::{self, Scalar};
use super::WorldFrame;
use super::{check_finite, check_memory, check_spacing, ImageError, LoadedImage, Payload};
use flate2::bufread::{MultiGzDecoder, ZlibDecoder};
use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The longest header read (all its lines, in bytes): longer ones are refused before
/// anything is allocated from what they say.
pub(super) const MAX_HEADER_LEN: usize = 64 << 10;

/// The lines of a text header, read from `r` within [`MAX_HEADER_LEN`] bytes in all.
pub(super) struct Lines<R> {
    pub r: R,
    /// Bytes consumed from `r` so far.
    pub consumed: u64,
    /// Lines read so far (for messages).
    pub number: usize,
}

impl<R: BufRead> Lines<R> {
    pub fn new(r: R) -> Self {
        Lines { r, consumed: 0, number: 0 }
    }

    /// The next line without its end (`\n`, `\r\n`), `None` at the end of the file.
    /// Bytes that are not UTF-8 are replaced (they can only be in values that are not
    /// read, such as comments).
    pub fn next_line(
        &mut self,
        path: &Path,
        format: &'static str,
    ) -> Result<Option<String>, ImageError> {
        let left = (MAX_HEADER_LEN as u64).saturating_sub(self.consumed);
        let mut buf = Vec::new();
        let n = (&mut self.r)
            .take(left + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|e| voxels::stream_error(path, None, e))?;
        if n == 0 {
            return Ok(None);
        }
        self.consumed += n as u64;
        self.number += 1;
        if self.consumed > MAX_HEADER_LEN as u64 {
            return Err(ImageError::Corrupt {
                path: path.to_path_buf(),
                format,
                reason: format!(
                    "the header is longer than {} KiB (or its end is missing)",
                    MAX_HEADER_LEN >> 10
                ),
            });
        }
        if buf.last() == Some(&b'\n') {
            buf.pop();
            if buf.last() == Some(&b'\r') {
                buf.pop();
            }
        }
        Ok(Some(String::from_utf8_lossy(&buf).into_owned()))
    }
}

/// Opens a file for reading: an I/O error on `path` (missing file, a directory), else the
/// file and its length when it is a regular file.
pub(super) fn open(path: &Path) -> Result<(File, Option<u64>), io::Error> {
    let file = File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_dir() {
        return Err(io::Error::new(io::ErrorKind::IsADirectory, "it is a directory"));
    }
    Ok((file, meta.is_file().then_some(meta.len())))
}

/// Opens the data file `name` a header names, relative to the header's directory unless
/// absolute; a failure is [`ImageError::DataFile`] (naming the header).
pub(super) fn open_data_file(
    header: &Path,
    name: &str,
) -> Result<(PathBuf, BufReader<File>, Option<u64>), ImageError> {
    let dir = header.parent().unwrap_or(Path::new(""));
    let data = dir.join(name);
    match open(&data) {
        Ok((file, len)) => Ok((data, BufReader::with_capacity(1 << 16, file), len)),
        Err(source) => Err(ImageError::DataFile { path: header.to_path_buf(), data, source }),
    }
}

/// How the voxel data are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Codec {
    Raw,
    /// gzip (one or more members).
    Gzip,
    /// zlib, or gzip when the stream starts with gzip's magic bytes (MetaIO reads both).
    Zlib,
}

/// Where the data start, from the current position of the reader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Skip {
    /// So many bytes of the file, then the data (compressed or not).
    File(u64),
    /// So many bytes of the decompressed stream (NRRD's `byte skip` with gzip).
    Decoded(u64),
    /// The data are the last bytes of the file (uncompressed only).
    ToEnd,
}

/// The voxel data a header announces.
pub(super) struct Data<'a> {
    pub format: &'static str,
    /// The voxel type, with its name in the header for messages.
    pub kind: Scalar,
    pub type_name: &'a str,
    pub big_endian: bool,
    pub dims: [usize; 3],
    pub codec: Codec,
    /// Lines of the file skipped first (NRRD's `line skip`).
    pub line_skip: u64,
    pub skip: Skip,
    /// Bytes of compressed data, when the header says (MetaImage's `CompressedDataSize`).
    pub compressed_len: Option<u64>,
    /// The data file, when the data are not after the header (for messages).
    pub data_file: Option<&'a Path>,
}

/// Reads and decodes the voxels from `r`, which has consumed `consumed` bytes of a file
/// of `file_len` bytes (when it is a regular file). Every size is checked against the
/// file and the machine before the intensities are allocated.
pub(super) fn read_data(
    path: &Path,
    mut r: impl BufRead,
    mut consumed: u64,
    file_len: Option<u64>,
    d: &Data,
) -> Result<Vec<f32>, ImageError> {
    let p = || path.to_path_buf();
    let corrupt = |reason: String| ImageError::Corrupt { path: p(), format: d.format, reason };
    let in_file = match d.data_file {
        Some(f) => format!("the data file {}", f.display()),
        None => "the file".to_string(),
    };
    let [nx, ny, nz] = d.dims;
    let what = format!("{nx}×{ny}×{nz} voxels of {}", d.type_name);
    let sizes = (nx as u64)
        .checked_mul(ny as u64)
        .and_then(|n| n.checked_mul(nz as u64))
        .and_then(|n| Some((usize::try_from(n).ok()?, n.checked_mul(d.kind.size() as u64)?)));
    let Some((n, bytes)) = sizes else {
        return Err(ImageError::TooLarge {
            path: p(),
            what,
            needed: u64::MAX,
            limit: crate::memory::limit(),
        });
    };
    let raw_err = |e| voxels::stream_error(path, None, e);

    // Lines to skip, then bytes of the file.
    for line in 0..d.line_skip {
        if !skip_line(&mut r, &mut consumed).map_err(raw_err)? {
            return Err(ImageError::Truncated {
                path: p(),
                detail: format!(
                    "{in_file} ends after {line} of the {} lines to skip before the data",
                    d.line_skip
                ),
            });
        }
    }
    let skip = match d.skip {
        Skip::File(k) => k,
        Skip::Decoded(_) => 0,
        Skip::ToEnd => {
            if d.codec != Codec::Raw {
                return Err(corrupt(
                    "compressed data cannot be located from the end of the file (a skip of \
                     -1)"
                    .to_string(),
                ));
            }
            let Some(len) = file_len else {
                return Err(corrupt(format!(
                    "data located from the end of the file (a skip of -1) need a regular \
                     file, and {in_file} is not one"
                )));
            };
            match len.checked_sub(bytes) {
                Some(start) if start >= consumed => start - consumed,
                _ => {
                    return Err(ImageError::Truncated {
                        path: p(),
                        detail: format!(
                            "the header announces {bytes} bytes of voxel data ({what}) at the \
                             end of {in_file}, which holds {len} bytes, {consumed} of them \
                             before the data"
                        ),
                    })
                }
            }
        }
    };
    let start = consumed.saturating_add(skip);
    if let Some(len) = file_len {
        let need = match (d.codec, d.compressed_len) {
            (Codec::Raw, _) => Some((bytes, "voxel data")),
            (_, Some(c)) => Some((c, "compressed data")),
            _ => None,
        };
        if let Some((need, kind)) = need {
            if len < start.saturating_add(need) {
                return Err(ImageError::Truncated {
                    path: p(),
                    detail: format!(
                        "the header announces {need} bytes of {kind} ({what}) from byte \
                         {start} of {in_file}, which holds {len} bytes"
                    ),
                });
            }
        } else if len < start {
            return Err(ImageError::Truncated {
                path: p(),
                detail: format!(
                    "the data start at byte {start} of {in_file}, which holds {len} bytes"
                ),
            });
        }
    }
    check_memory(
        path,
        Some(n as u64 * 4 + 3 * voxels::CHUNK as u64),
        &format!("its {nx}×{ny}×{nz} intensities"),
    )?;
    let skipped = io::copy(&mut (&mut r).take(skip), &mut io::sink()).map_err(raw_err)?;
    if skipped < skip {
        return Err(ImageError::Truncated {
            path: p(),
            detail: format!("{in_file} ends before its data, at byte {}", consumed + skipped),
        });
    }

    // The data.
    let decoded_skip = if let Skip::Decoded(k) = d.skip { k } else { 0 };
    let mut data = Vec::with_capacity(n);
    let mut limited;
    let r: &mut dyn BufRead = match d.compressed_len {
        Some(c) if d.codec != Codec::Raw => {
            limited = (&mut r).take(c);
            &mut limited
        }
        _ => &mut r,
    };
    match d.codec {
        Codec::Raw => decode(r, path, None, d, n, 0, &mut data)?,
        Codec::Gzip => {
            decode(&mut MultiGzDecoder::new(r), path, Some("gzip"), d, n, decoded_skip, &mut data)?
        }
        Codec::Zlib => {
            let head = r.fill_buf().map_err(raw_err)?;
            if head.starts_with(&[0x1f, 0x8b]) {
                decode(
                    &mut MultiGzDecoder::new(r),
                    path,
                    Some("gzip"),
                    d,
                    n,
                    decoded_skip,
                    &mut data,
                )?
            } else {
                decode(&mut ZlibDecoder::new(r), path, Some("zlib"), d, n, decoded_skip, &mut data)?
            }
        }
    }
    check_finite(path, d.dims, &data)?;
    Ok(data)
}

/// Consumes one line (up to and including `\n`) without keeping it; `false` at the end
/// of the file.
fn skip_line(r: &mut impl BufRead, consumed: &mut u64) -> io::Result<bool> {
    loop {
        let buf = match r.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if buf.is_empty() {
            return Ok(false);
        }
        match buf.iter().position(|&b| b == b'\n') {
            Some(i) => {
                r.consume(i + 1);
                *consumed += i as u64 + 1;
                return Ok(true);
            }
            None => {
                let k = buf.len();
                r.consume(k);
                *consumed += k as u64;
            }
        }
    }
}

/// Skips `skip` bytes of the (decoded) stream, reads the `n` voxels into `data`, and for
/// a compressed stream reads on to its end, so that its checksum is verified.
fn decode<R: Read + ?Sized>(
    mut r: &mut R,
    path: &Path,
    codec: Option<&'static str>,
    d: &Data,
    n: usize,
    skip: u64,
    data: &mut Vec<f32>,
) -> Result<(), ImageError> {
    let err = |e| voxels::stream_error(path, codec, e);
    let skipped = io::copy(&mut (&mut r).take(skip), &mut io::sink()).map_err(err)?;
    if skipped < skip {
        return Err(ImageError::Truncated {
            path: path.to_path_buf(),
            detail: format!(
                "the decompressed data end within the {skip} bytes to skip before the voxels"
            ),
        });
    }
    voxels::read_voxels(&mut r, d.kind, d.big_endian, None, n, path, &err, |_, chunk| {
        data.extend_from_slice(chunk)
    })?;
    if codec.is_some() {
        io::copy(r, &mut io::sink()).map_err(err)?;
    }
    Ok(())
}

/// `v` as whitespace-separated numbers, exactly `count` of them: `Err(Some(n))` when it
/// holds `n` numbers, `Err(None)` when a word is not a number.
pub(super) fn numbers<T: std::str::FromStr>(
    v: &str,
    count: usize,
) -> Result<Vec<T>, Option<usize>> {
    let parsed: Result<Vec<T>, _> = v.split_whitespace().map(str::parse).collect();
    match parsed {
        Ok(x) if x.len() == count => Ok(x),
        Ok(x) => Err(Some(x.len())),
        Err(_) => Err(None),
    }
}

/// A number as written in a header: the shortest text that reads back as the same `f64`.
pub(super) fn num(v: f64) -> String {
    let plain = format!("{v}");
    if plain.len() <= 24 {
        plain
    } else {
        format!("{v:e}")
    }
}

/// `v` as numbers separated by `sep`.
pub(super) fn nums(v: &[f64], sep: &str) -> String {
    v.iter().map(|&x| num(x)).collect::<Vec<_>>().join(sep)
}

/// The placement a MetaImage or NRRD header is written with for an image that did not
/// come from a file of that format: the image's spacing, the directions of its axes (the
/// columns of [`super::Image::to_world`]) and its origin, converted to the frame `to`
/// when both frames are anatomical.
#[derive(Clone, Debug)]
pub(super) struct Placement {
    /// 2 when written as a 2-D image (a 2-D input lying in the plane z = 0), else 3.
    pub ndim: usize,
    pub spacing: [f64; 3],
    /// `axes[i]` is the world direction of voxel axis i.
    pub axes: [[f64; 3]; 3],
    pub origin: [f64; 3],
}

/// The [`Placement`] of `like` in the frame `to` (see there).
pub(super) fn placement_of(
    path: &Path,
    like: &LoadedImage,
    to: WorldFrame,
    format: &'static str,
) -> Result<Placement, ImageError> {
    let im = &like.image;
    check_spacing(path, im.spacing, "the image's spacing")?;
    let m = like.world_frame().convert(im.to_world, to);
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err(ImageError::CannotWrite {
            path: path.to_path_buf(),
            what: format,
            reason: format!("its placement {:?} is not finite", im.to_world),
        });
    }
    let plain_2d = m[2] == [0.0, 0.0, 1.0, 0.0] && m[0][2] == 0.0 && m[1][2] == 0.0;
    let ndim = if like.is_2d_source() && im.dims[2] == 1 && plain_2d { 2 } else { 3 };
    Ok(Placement {
        ndim,
        spacing: im.spacing,
        axes: std::array::from_fn(|i| std::array::from_fn(|r| m[r][i])),
        origin: std::array::from_fn(|r| m[r][3]),
    })
}

/// Refuses to write `like` with the header of its input when its dimensions changed since
/// it was read.
pub(super) fn check_source_dims(
    path: &Path,
    like: &LoadedImage,
    dims: [usize; 3],
    what: &'static str,
) -> Result<(), ImageError> {
    if dims == like.image.dims {
        return Ok(());
    }
    Err(ImageError::CannotWrite {
        path: path.to_path_buf(),
        what,
        reason: format!(
            "the image has {:?} voxels (x, y, z) but its input's header says {dims:?}",
            like.image.dims
        ),
    })
}

/// The name of the data file written beside the detached header `path`: its stem (the
/// name without the extension `ext_len` bytes long) and `suffix`, e.g. `ct.raw` for
/// `ct.mhd`; refused when the name cannot be written in a header.
pub(super) fn data_file_name(
    path: &Path,
    ext_len: usize,
    suffix: &str,
) -> Result<String, ImageError> {
    let name = path.file_name().and_then(|n| n.to_str());
    match name {
        Some(n)
            if !n.contains(['\n', '\r', '%'])
                && n.len() > ext_len
                && n.is_char_boundary(n.len() - ext_len) =>
        {
            Ok(format!("{}{suffix}", &n[..n.len() - ext_len]))
        }
        _ => Err(ImageError::CannotWrite {
            path: path.to_path_buf(),
            what: "a detached header",
            reason: "its file name must be UTF-8 without line breaks or '%' to be named in \
                     the header"
                .to_string(),
        }),
    }
}

/// Counts the bytes written through it.
struct Counting<W> {
    w: W,
    n: u64,
}

impl<W: Write> Write for Counting<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let k = self.w.write(buf)?;
        self.n += k as u64;
        Ok(k)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.w.flush()
    }
}

/// Writes the voxels, compressed by `codec`, to `w`; returns the bytes written.
fn write_data(w: &mut dyn Write, data: Payload<'_>, codec: Codec) -> io::Result<u64> {
    let mut w = Counting { w, n: 0 };
    match codec {
        Codec::Raw => data.write_to(&mut w)?,
        Codec::Gzip => {
            let mut z = flate2::write::GzEncoder::new(&mut w, flate2::Compression::default());
            data.write_to(&mut z)?;
            z.finish()?;
        }
        Codec::Zlib => {
            let mut z = flate2::write::ZlibEncoder::new(&mut w, flate2::Compression::default());
            data.write_to(&mut z)?;
            z.finish()?;
        }
    }
    Ok(w.n)
}

/// What a header says for a data length it does not know yet (20 digits, as wide as any
/// length): [`write_files`] writes it over with the length, padded with spaces.
pub(super) const UNKNOWN_LEN: u64 = u64::MAX;

/// Writes the header `header(len)` (`len`: bytes of data as written, compressed or not)
/// then the data to `path`, or, when `data_file` is given, the data to that file in
/// `path`'s directory and then the header to `path`. Each file is written atomically
/// ([`crate::io::fsutil::write_atomic`]), the data first, so that a header never names data
/// that are not complete. In one file, the header is written with [`UNKNOWN_LEN`], which
/// is written over with the length once the data are written.
pub(super) fn write_files(
    path: &Path,
    header: &dyn Fn(u64) -> String,
    data_file: Option<&str>,
    data: Payload<'_>,
    codec: Codec,
) -> Result<(), ImageError> {
    let io_err = |p: &Path| {
        let p = p.to_path_buf();
        move |source| ImageError::Io { path: p, source }
    };
    match data_file {
        None => crate::io::fsutil::write_atomic(path, |w| {
            let text = header(UNKNOWN_LEN);
            w.write_all(text.as_bytes())?;
            let len = write_data(w, data, codec)?;
            if let Some(at) = text.rfind(&UNKNOWN_LEN.to_string()) {
                w.seek(SeekFrom::Start(at as u64))?;
                w.write_all(format!("{len:<20}").as_bytes())?;
                w.seek(SeekFrom::End(0))?;
            }
            Ok(())
        })
        .map_err(io_err(path)),
        Some(name) => {
            let dir = path.parent().unwrap_or(Path::new(""));
            let data_path = dir.join(name);
            let mut len = 0;
            crate::io::fsutil::write_atomic(&data_path, |w| {
                len = write_data(w, data, codec)?;
                Ok(())
            })
            .map_err(io_err(&data_path))?;
            crate::io::fsutil::write_atomic(path, |w| w.write_all(header(len).as_bytes()))
                .map_err(io_err(path))
        }
    }
}

/// The determinant of the 3×3 matrix whose columns (or rows: the same) are `a[0]`,
/// `a[1]`, `a[2]`.
pub(super) fn det(a: &[[f64; 3]; 3]) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}
