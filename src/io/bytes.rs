//! Bounds-checked little-endian reading of a file held in memory: the readers of the
//! `.sls` ([`crate::io::sls`]) and `.vdb` ([`crate::io::vdb`]) formats share it, each turning a
//! [`ReadError`] into its own error type (and wording).

/// Why a read stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ReadError {
    /// The bytes ended inside the named part.
    Truncated(&'static str),
    /// A count of `n` items of `what` that the `left` bytes cannot hold.
    TooMany { n: u64, what: &'static str, left: usize },
    /// A variable-length number in the named part runs past 64 bits.
    Overlong(&'static str),
}

/// A cursor over bytes: every read checks the bytes left first.
pub(crate) struct ByteReader<'a> {
    pub b: &'a [u8],
    pub at: usize,
}

type Res<T> = Result<T, ReadError>;

impl<'a> ByteReader<'a> {
    pub fn left(&self) -> usize {
        self.b.len() - self.at
    }

    pub fn take(&mut self, n: usize, what: &'static str) -> Res<&'a [u8]> {
        if self.left() < n {
            return Err(ReadError::Truncated(what));
        }
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }

    pub fn arr<const N: usize>(&mut self, what: &'static str) -> Res<[u8; N]> {
        Ok(self.take(N, what)?.try_into().expect("N bytes"))
    }

    pub fn u8(&mut self, what: &'static str) -> Res<u8> {
        Ok(self.take(1, what)?[0])
    }

    pub fn u32(&mut self, what: &'static str) -> Res<u32> {
        Ok(u32::from_le_bytes(self.arr(what)?))
    }

    pub fn u64(&mut self, what: &'static str) -> Res<u64> {
        Ok(u64::from_le_bytes(self.arr(what)?))
    }

    pub fn i32(&mut self, what: &'static str) -> Res<i32> {
        Ok(i32::from_le_bytes(self.arr(what)?))
    }

    pub fn i64(&mut self, what: &'static str) -> Res<i64> {
        Ok(i64::from_le_bytes(self.arr(what)?))
    }

    pub fn f32(&mut self, what: &'static str) -> Res<f32> {
        Ok(f32::from_le_bytes(self.arr(what)?))
    }

    pub fn f64(&mut self, what: &'static str) -> Res<f64> {
        Ok(f64::from_le_bytes(self.arr(what)?))
    }

    pub fn vec3d(&mut self, what: &'static str) -> Res<[f64; 3]> {
        Ok([self.f64(what)?, self.f64(what)?, self.f64(what)?])
    }

    /// A string of a u32 length and that many bytes (invalid UTF-8 replaced).
    pub fn string(&mut self, what: &'static str) -> Res<String> {
        let n = self.u32(what)? as usize;
        Ok(String::from_utf8_lossy(self.take(n, what)?).into_owned())
    }

    /// A bit mask of `bits` bits (a multiple of 64) as u64 words.
    pub fn mask(&mut self, bits: usize, what: &'static str) -> Res<Vec<u64>> {
        let raw = self.take(bits / 8, what)?;
        Ok(raw.chunks_exact(8).map(|c| u64::from_le_bytes(c.try_into().expect("8"))).collect())
    }

    /// An unsigned LEB128 number (at most 10 bytes, 64 bits).
    pub fn varint(&mut self, what: &'static str) -> Res<u64> {
        let mut v = 0u64;
        for i in 0..10 {
            let byte = self.u8(what)?;
            if i == 9 && byte > 1 {
                break;
            }
            v |= ((byte & 0x7f) as u64) << (7 * i);
            if byte & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(ReadError::Overlong(what))
    }

    /// A count of items of at least `min_bytes` bytes each, checked against the bytes
    /// left before anything is sized by it.
    pub fn count(&self, n: u64, min_bytes: u64, what: &'static str) -> Res<usize> {
        if n.checked_mul(min_bytes).is_none_or(|b| b > self.left() as u64) {
            return Err(ReadError::TooMany { n, what, left: self.left() });
        }
        Ok(n as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_stop_at_the_end_and_counts_are_bounded_by_the_bytes_left() {
        let bytes = [1, 0, 0, 0, 0xff, 0x01, 7];
        let mut r = ByteReader { b: &bytes, at: 0 };
        assert_eq!(r.u32("a"), Ok(1));
        assert_eq!(r.varint("b"), Ok(255));
        assert_eq!(r.count(1, 1, "c"), Ok(1));
        assert_eq!(r.count(2, 1, "c"), Err(ReadError::TooMany { n: 2, what: "c", left: 1 }));
        assert_eq!(
            r.count(u64::MAX, 2, "c"),
            Err(ReadError::TooMany { n: u64::MAX, what: "c", left: 1 })
        );
        assert_eq!(r.u32("d"), Err(ReadError::Truncated("d")));
        assert_eq!(r.u8("e"), Ok(7));
        let long = [0x80u8; 11];
        assert_eq!(ByteReader { b: &long, at: 0 }.varint("f"), Err(ReadError::Overlong("f")));
    }
}
