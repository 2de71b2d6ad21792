//! PNG images (one slice) through the `png` crate: its header is read and the memory the
//! pixels need is checked before the pixels are decoded.

use super::{check_memory, Image, ImageError, LoadedImage, Source, IDENTITY};
use ::png::{BitDepth, ColorType, DecodingError, Transformations};
use std::fs::File;
use std::io::{self, BufReader};
use std::path::Path;

fn decoding_error(path: &Path, e: DecodingError) -> ImageError {
    let path = path.to_path_buf();
    match e {
        DecodingError::IoError(e) if e.kind() == io::ErrorKind::UnexpectedEof => {
            ImageError::Truncated { path, detail: "the PNG stream ends early".to_string() }
        }
        DecodingError::IoError(source) => ImageError::Io { path, source },
        DecodingError::LimitsExceeded => ImageError::Unsupported {
            path,
            what: "a PNG beyond the decoder's size limits is".to_string(),
        },
        e => ImageError::Corrupt { path, format: "PNG", reason: e.to_string() },
    }
}

/// Reads a PNG as a one-slice image (see the module docs of [`super`]).
pub(super) fn read(path: &Path, spacing: Option<[f64; 3]>) -> Result<LoadedImage, ImageError> {
    let io_err = |source| ImageError::Io { path: path.to_path_buf(), source };
    let file = File::open(path).map_err(io_err)?;
    if file.metadata().map_err(io_err)?.is_dir() {
        return Err(io_err(io::Error::new(io::ErrorKind::IsADirectory, "it is a directory")));
    }
    let mut decoder = ::png::Decoder::new(BufReader::with_capacity(1 << 16, file));
    // Palette → RGB, 1/2/4 bits → 8 bits (scaled to 0..255), tRNS → alpha; 16 bits kept.
    decoder.set_transformations(Transformations::EXPAND);
    let (w, h) = {
        let info = decoder.read_header_info().map_err(|e| decoding_error(path, e))?;
        (info.width as usize, info.height as usize)
    };
    // The pixels (up to 8 bytes each, 16-bit RGBA) and the intensities, before decoding.
    let n = w as u64 * h as u64;
    check_memory(path, n.checked_mul(12), &format!("its {w}×{h} pixels"))?;
    let mut reader = decoder.read_info().map_err(|e| decoding_error(path, e))?;
    let bit_depth = reader.info().bit_depth as u8;
    let (color, depth) = reader.output_color_type();
    let size = reader.output_buffer_size().ok_or_else(|| ImageError::TooLarge {
        path: path.to_path_buf(),
        what: format!("its {w}×{h} pixels"),
        needed: u64::MAX,
        limit: crate::memory::limit(),
    })?;
    let mut buf = vec![0u8; size];
    let frame = reader.next_frame(&mut buf).map_err(|e| decoding_error(path, e))?;
    // To the end of the file (IEND), so that a truncated file is refused even when its
    // pixels are complete.
    reader.finish().map_err(|e| decoding_error(path, e))?;
    let line = frame.line_size;
    let channels = color.samples();
    let wide = depth == BitDepth::Sixteen;
    let sample = |row: &[u8], x: usize, c: usize| -> u16 {
        let i = x * channels + c;
        if wide {
            u16::from_be_bytes([row[2 * i], row[2 * i + 1]])
        } else {
            row[i] as u16
        }
    };
    let mut data = Vec::with_capacity(w * h);
    for y in 0..h {
        let row = &buf[y * line..(y + 1) * line];
        match color {
            ColorType::Grayscale | ColorType::GrayscaleAlpha => {
                data.extend((0..w).map(|x| sample(row, x, 0) as f32));
            }
            ColorType::Rgb | ColorType::Rgba => {
                for x in 0..w {
                    let rgb = [sample(row, x, 0), sample(row, x, 1), sample(row, x, 2)];
                    if rgb[0] != rgb[1] || rgb[1] != rgb[2] {
                        return Err(ImageError::NotGreyscale {
                            path: path.to_path_buf(),
                            x,
                            y,
                            rgb,
                        });
                    }
                    data.push(rgb[0] as f32);
                }
            }
            ColorType::Indexed => unreachable!("EXPAND turns palettes into RGB"),
        }
    }
    let image =
        Image { dims: [w, h, 1], spacing: spacing.unwrap_or([1.0; 3]), data, to_world: IDENTITY };
    Ok(LoadedImage { image, source: Source::Png { bit_depth } })
}

/// Writes a mask (0/1, checked by the caller; `nz = 1`) as an 8-bit greyscale PNG with
/// 0 and 255, atomically.
pub(super) fn write_mask(path: &Path, like: &LoadedImage, mask: &[u8]) -> Result<(), ImageError> {
    let [nx, ny, _] = like.image.dims;
    let pixels: Vec<u8> = mask.iter().map(|&v| v * 255).collect();
    crate::io::fsutil::write_atomic(path, |w| {
        let mut enc = ::png::Encoder::new(w, nx as u32, ny as u32);
        enc.set_color(ColorType::Grayscale);
        enc.set_depth(BitDepth::Eight);
        enc.set_compression(::png::Compression::High);
        let mut writer = enc.write_header()?;
        writer.write_image_data(&pixels)?;
        writer.finish()?;
        Ok(())
    })
    .map_err(|source| ImageError::Io { path: path.to_path_buf(), source })
}
