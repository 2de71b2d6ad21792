//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod alloc;
pub mod meshes;

use sparse_levelset::storage::dense::DenseField;
use sparse_levelset::Coord;
use std::path::PathBuf;

/// A path in this test process's own temporary directory.
pub fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("levelset-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A dense field `scale · (|x − centre| − radius)` over `0..dims` (voxel coordinates):
/// a ball, as a user's `.npy` level set would hold it.
pub fn ball(dims: [usize; 3], centre: [f64; 3], radius: f64, scale: f64) -> DenseField {
    DenseField::from_fn(Coord::new(0, 0, 0), dims, |c| {
        let d = [c.x as f64 - centre[0], c.y as f64 - centre[1], c.z as f64 - centre[2]];
        (scale * ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - radius)) as f32
    })
    .unwrap()
}

/// Writes `field` to the temporary `.npy` file `name` and returns its path.
pub fn npy(name: &str, field: &DenseField) -> PathBuf {
    let path = tmp(name);
    sparse_levelset::io::npy::write_npy(&path, field).unwrap();
    path
}

/// Bitwise CRC-32 (IEEE 802.3, zlib's), independent of the crate the library uses: the
/// `.sls` tests re-seal mutated files with it.
pub fn crc32(b: &[u8]) -> u32 {
    let mut c = !0u32;
    for &x in b {
        c ^= x as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { (c >> 1) ^ 0xEDB8_8320 } else { c >> 1 };
        }
    }
    !c
}

/// A fresh directory under the system temp dir, removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let dir = std::env::temp_dir().join(format!(
            "sparse-levelset-{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    pub fn file(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.path(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    /// The names of the directory's entries, sorted.
    pub fn names(&self) -> Vec<String> {
        let mut v: Vec<_> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
