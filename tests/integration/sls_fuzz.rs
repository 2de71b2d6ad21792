//! Fuzzing the `.sls` reader: flipped, truncated, spliced, inserted and deleted bytes, with
//! and without a re-computed checksum (so the structure checks are reached, not only the
//! CRC). The reader must never panic, never return an invalid grid, and never make an
//! allocation much larger than the file (the test binary's allocator records the largest
//! request of this test's thread; the reader runs on it alone).

use crate::common::alloc::largest_allocation;
use crate::common::crc32;
use sparse_levelset::io::sls::{self, SlsError, Source};
use sparse_levelset::storage::convert::tiles_from_shape;
use sparse_levelset::storage::hrle::HrleGrid;
use sparse_levelset::storage::shapes::Shape;
use sparse_levelset::{Coord, GridSpec};

#[test]
fn mutated_files_are_refused_or_valid_never_a_panic_or_a_huge_allocation() {
    let sphere = Shape::Sphere { center: [0.3, 0.1, -0.2], radius: 6.5 };
    let tiles = tiles_from_shape(&sphere, GridSpec::default()).unwrap();
    let mut h = HrleGrid::from_level_set(&tiles).unwrap();
    let open = h.clip(Coord::new(-9, -9, -9), Coord::new(1, 9, 9)).unwrap();
    h.add_scalar_field("s", |c, _| c.x as f32).unwrap();
    let files = [sls::encode(&h, Source::Hrle), sls::encode(&open, Source::Tiles)];
    let mut rng = fastrand::Rng::with_seed(2026);
    let mut counts = std::collections::BTreeMap::<&str, usize>::new();
    let rounds = 20_000;
    for round in 0..rounds {
        let base = &files[round % 2];
        let mut b = base.clone();
        let op = rng.u8(0..5);
        match op {
            0 => {
                for _ in 0..rng.usize(1..8) {
                    let k = rng.usize(0..b.len());
                    b[k] ^= 1 << rng.u8(0..8);
                }
            }
            1 => b.truncate(rng.usize(0..b.len())),
            2 => {
                let other = &files[(round + 1) % 2];
                let (a, n) = (rng.usize(0..other.len()), rng.usize(1..64));
                let chunk = &other[a..(a + n).min(other.len())];
                let at = rng.usize(0..b.len());
                let end = (at + chunk.len()).min(b.len());
                b[at..end].copy_from_slice(&chunk[..end - at]);
            }
            3 => {
                let at = rng.usize(0..b.len());
                for _ in 0..rng.usize(1..16) {
                    b.insert(at, rng.u8(..));
                }
            }
            _ => {
                let at = rng.usize(0..b.len());
                let n = rng.usize(1..16).min(b.len() - at);
                b.drain(at..at + n);
            }
        }
        // Half the mutants get a valid checksum, so the parser itself is exercised.
        let resealed = round % 4 >= 2 && b.len() >= 4;
        if resealed {
            let n = b.len() - 4;
            let crc = crc32(&b[..n]);
            b[n..].copy_from_slice(&crc.to_le_bytes());
        }
        let (r, largest) = largest_allocation(|| sls::decode(&b));
        assert!(
            largest <= 8 * base.len() + 4096,
            "round {round}: an allocation of {largest} bytes for a {}-byte file",
            b.len()
        );
        let kind = match r {
            Ok((g, _)) => {
                g.check_invariants().unwrap();
                "accepted (still a valid level set)"
            }
            Err(SlsError::Checksum { .. }) => "refused: checksum",
            Err(SlsError::Truncated(_)) => "refused: truncated",
            Err(SlsError::NotSls) => "refused: not .sls",
            Err(SlsError::Version(_)) => "refused: version",
            Err(SlsError::Corrupt(_)) => "refused: corrupt structure",
            Err(e) => panic!("unexpected error kind: {e}"),
        };
        *counts.entry(kind).or_default() += 1;
    }
    eprintln!("sls fuzz, {rounds} mutants: {counts:?}");
    assert!(counts.get("refused: corrupt structure").copied().unwrap_or(0) > rounds / 10);
    assert!(counts.get("refused: checksum").copied().unwrap_or(0) > rounds / 10);
}
