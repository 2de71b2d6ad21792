//! Decoding of Blosc 1 frames as OpenVDB writes them (`io::bloscToStream`: LZ4, byte
//! shuffle, one block): the 16-byte header (format version, codec version, flags, type
//! size, uncompressed size, block size, compressed size), then either the raw bytes
//! ("memcpyed") or one start offset per block and, per block, one or `typesize` LZ4
//! streams (the block "split" by byte position) each prefixed by its compressed size; a
//! stream whose compressed size equals its plain size is stored raw. Shuffled blocks hold
//! byte 0 of every element, then byte 1, ...: unshuffled here.

/// Bytes of the frame header.
const HEADER: usize = 16;
const DOSHUFFLE: u8 = 0x1;
const MEMCPYED: u8 = 0x2;
const BITSHUFFLE: u8 = 0x4;
const FUTURE: u8 = 0x8;
const DONT_SPLIT: u8 = 0x10;
/// Blosc splits a block into `typesize` streams only up to this type size ...
const MAX_SPLITS: usize = 16;
/// ... and when each stream would hold at least this many bytes.
const MIN_BUFFERSIZE: usize = 128;
/// The codec number (flags >> 5) of LZ4.
const CODEC_LZ4: u8 = 1;

fn u32_at(b: &[u8], at: usize) -> Option<usize> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?) as usize)
}

/// Decompresses the frame `src` into exactly `expected` bytes; `Err` says what is wrong.
pub(super) fn decompress(src: &[u8], expected: usize) -> Result<Vec<u8>, String> {
    if src.len() < HEADER {
        return Err("a Blosc frame shorter than its header".into());
    }
    let (version, flags, typesize) = (src[0], src[2], src[3] as usize);
    let nbytes = u32_at(src, 4).unwrap_or(0);
    let blocksize = u32_at(src, 8).unwrap_or(0);
    let cbytes = u32_at(src, 12).unwrap_or(0);
    if version == 0 || version > 3 || flags & FUTURE != 0 {
        return Err(format!(
            "a Blosc frame of an unknown format (version {version}, flags {flags:#x})"
        ));
    }
    if nbytes != expected {
        return Err(format!("a Blosc frame of {nbytes} bytes where {expected} were expected"));
    }
    if cbytes != src.len() {
        return Err(format!(
            "a Blosc frame announcing {cbytes} bytes in a {}-byte chunk",
            src.len()
        ));
    }
    if nbytes == 0 {
        return Ok(Vec::new());
    }
    if flags & MEMCPYED != 0 {
        if src.len() != HEADER + nbytes {
            return Err("a stored Blosc frame of the wrong size".into());
        }
        return Ok(src[HEADER..].to_vec());
    }
    let codec = flags >> 5;
    if codec != CODEC_LZ4 {
        let name = ["BloscLZ", "LZ4", "Snappy", "zlib", "Zstd"].get(codec as usize).unwrap_or(&"?");
        return Err(format!(
            "Blosc with the {name} codec (only LZ4, OpenVDB's choice, is read): re-save the file \
             with OpenVDB"
        ));
    }
    if flags & BITSHUFFLE != 0 {
        return Err("Blosc with bit shuffle (OpenVDB writes byte shuffle)".into());
    }
    if typesize == 0 || blocksize == 0 || blocksize > nbytes {
        return Err(format!("a Blosc frame with type size {typesize} and block size {blocksize}"));
    }
    let nblocks = nbytes.div_ceil(blocksize);
    if nblocks > (src.len() - HEADER) / 4 {
        return Err("more Blosc blocks than the frame can hold".into());
    }
    let shuffle = flags & DOSHUFFLE != 0 && typesize > 1;
    let mut out = vec![0u8; nbytes];
    let mut tmp = vec![0u8; blocksize];
    for j in 0..nblocks {
        let bsize = blocksize.min(nbytes - j * blocksize);
        let leftover = bsize < blocksize;
        let split = flags & DONT_SPLIT == 0
            && typesize <= MAX_SPLITS
            && blocksize / typesize >= MIN_BUFFERSIZE
            && !leftover;
        let nsplits = if split { typesize } else { 1 };
        let neblock = bsize / nsplits;
        let mut at = u32_at(src, HEADER + 4 * j).ok_or("a Blosc block start past the frame")?;
        let dest = if shuffle { &mut tmp[..bsize] } else { &mut out[j * blocksize..][..bsize] };
        for s in 0..nsplits {
            let csize = u32_at(src, at).ok_or("a Blosc stream past the frame")?;
            at += 4;
            let stream =
                src.get(at..at.saturating_add(csize)).ok_or("a Blosc stream past the frame")?;
            at += csize;
            let part = &mut dest[s * neblock..(s + 1) * neblock];
            if csize == neblock {
                part.copy_from_slice(stream);
            } else {
                match lz4_flex::block::decompress_into(stream, part) {
                    Ok(n) if n == neblock => {}
                    _ => return Err("an LZ4 stream that does not decode to its block".into()),
                }
            }
        }
        if shuffle {
            let n = bsize / typesize;
            let block = &mut out[j * blocksize..][..bsize];
            for (i, e) in block[..n * typesize].chunks_exact_mut(typesize).enumerate() {
                for (b, v) in e.iter_mut().enumerate() {
                    *v = tmp[b * n + i];
                }
            }
            block[n * typesize..].copy_from_slice(&tmp[n * typesize..bsize]);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(flags: u8, nbytes: usize, blocksize: usize, cbytes: usize) -> Vec<u8> {
        let mut h = vec![2, 1, flags, 4];
        for v in [nbytes, blocksize, cbytes] {
            h.extend_from_slice(&(v as u32).to_le_bytes());
        }
        h
    }

    /// A shuffled frame of two blocks: the first split into 4 raw streams (one per byte
    /// of a float), the second a short leftover block, one stream, unshuffled tail.
    #[test]
    fn split_shuffled_blocks_and_leftovers_come_back() {
        let data: Vec<u8> = (0..1030u32).map(|i| (i * 7 + i / 5) as u8).collect();
        let (bs, n) = (1024, 256);
        let mut body = Vec::new();
        let mut starts = Vec::new();
        let first = 16 + 8;
        starts.push(first);
        for b in 0..4 {
            body.extend_from_slice(&(n as u32).to_le_bytes());
            body.extend((0..n).map(|i| data[i * 4 + b]));
        }
        starts.push(first + body.len());
        // The leftover 6 bytes: one element shuffled (4 bytes by position) + 2 tail bytes.
        body.extend_from_slice(&6u32.to_le_bytes());
        body.extend_from_slice(&data[1024..1030]);
        let cbytes = first + body.len();
        let mut frame = header(DOSHUFFLE | (CODEC_LZ4 << 5), data.len(), bs, cbytes);
        for s in &starts {
            frame.extend_from_slice(&(*s as u32).to_le_bytes());
        }
        frame.extend_from_slice(&body);
        assert_eq!(decompress(&frame, data.len()).unwrap(), data);
        // The wrong expected size, a cut frame, an unknown codec: refused.
        assert!(decompress(&frame, data.len() - 4).is_err());
        assert!(decompress(&frame[..frame.len() - 1], data.len()).is_err());
        let mut zstd = frame.clone();
        zstd[2] = DOSHUFFLE | (4 << 5);
        assert!(decompress(&zstd, data.len()).unwrap_err().contains("Zstd"));
    }

    #[test]
    fn stored_frames_are_copied() {
        let data: Vec<u8> = (0..100u8).collect();
        let mut frame = header(MEMCPYED | DOSHUFFLE | (CODEC_LZ4 << 5), 100, 100, 116);
        frame.extend_from_slice(&data);
        assert_eq!(decompress(&frame, 100).unwrap(), data);
        assert!(decompress(&frame[..115], 100).is_err());
    }
}
