//! The writer: band voxels gathered into 8³ leaves, the 5-4-3 tree above them, and the
//! bytes of OpenVDB's layout (see the [module docs](super)).

use super::{compression_name, VdbError, VdbOptions, COMPRESS_ZIP};
use super::{FILE_VERSION, MAGIC};
use crate::coord::Coord;
use crate::storage::levelset::{Accessor, LevelSet};
use rayon::prelude::*;
use std::collections::HashMap;
use std::io::Write;

/// Log2 of the node sizes: leaves 8³, lower internal nodes 16³ slots of leaves, upper
/// internal nodes 32³ slots of lower nodes.
pub(super) const LEAF_LOG2: u32 = 3;
pub(super) const LOWER_LOG2: u32 = 4;
pub(super) const UPPER_LOG2: u32 = 5;
/// Voxels spanned by a leaf, a lower node and an upper node (log2).
pub(super) const LEAF_TOTAL: u32 = LEAF_LOG2;
pub(super) const LOWER_TOTAL: u32 = LEAF_TOTAL + LOWER_LOG2;
pub(super) const UPPER_TOTAL: u32 = LOWER_TOTAL + UPPER_LOG2;

/// The slot of voxel `c` in a node of `log2` slots per axis over children spanning
/// `child_total` (log2 voxels): x slowest, z fastest, as OpenVDB indexes its nodes.
pub(super) fn slot(c: [i32; 3], log2: u32, child_total: u32) -> usize {
    let m = (1i32 << log2) - 1;
    let s = |v: i32| ((v >> child_total) & m) as usize;
    (s(c[0]) << (2 * log2)) | (s(c[1]) << log2) | s(c[2])
}

/// The voxel offset of slot `n` (inverse of [`slot`]) from its node's origin.
#[inline]
pub(super) fn slot_offset(n: usize, log2: u32, child_total: u32) -> [i32; 3] {
    let m = (1usize << log2) - 1;
    let axis = |shift: u32| (((n >> shift) & m) as i32) << child_total;
    [axis(2 * log2), axis(log2), axis(0)]
}

/// The origin of the node spanning `total` (log2 voxels) that holds `c`.
pub(super) fn node_origin(c: [i32; 3], total: u32) -> [i32; 3] {
    let m = !((1i32 << total) - 1);
    [c[0] & m, c[1] & m, c[2] & m]
}

#[inline]
pub(super) fn bit(mask: &[u64], i: usize) -> bool {
    mask[i >> 6] >> (i & 63) & 1 != 0
}

fn set_bit(mask: &mut [u64], i: usize) {
    mask[i >> 6] |= 1 << (i & 63);
}

struct Leaf {
    origin: [i32; 3],
    mask: [u64; 8],
    values: Box<[f32; 512]>,
}

/// The sort key of a leaf: depth-first tree order (root key, upper slot, lower slot).
fn tree_key(o: [i32; 3]) -> ([i32; 3], usize, usize) {
    (node_origin(o, UPPER_TOTAL), slot(o, UPPER_LOG2, LOWER_TOTAL), slot(o, LOWER_LOG2, LEAF_TOTAL))
}

struct Out {
    b: Vec<u8>,
    flags: u32,
    background: f32,
}

impl Out {
    fn u32(&mut self, v: u32) {
        self.b.extend_from_slice(&v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.b.extend_from_slice(&v.to_le_bytes());
    }
    fn i64(&mut self, v: i64) {
        self.b.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.b.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.b.extend_from_slice(&v.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.b.extend_from_slice(s.as_bytes());
    }
    fn mask(&mut self, m: &[u64]) {
        for w in m {
            self.b.extend_from_slice(&w.to_le_bytes());
        }
    }
    fn meta(&mut self, name: &str, type_name: &str, value: &[u8]) {
        self.string(name);
        self.string(type_name);
        self.u32(value.len() as u32);
        self.b.extend_from_slice(value);
    }

    /// OpenVDB's `writeCompressedValues`: the mask-compression byte, the inactive values
    /// and selection mask it needs, then the active values (all values when more than two
    /// distinct inactive values occur), zlib-compressed under `COMPRESS_ZIP`. Slots whose
    /// `child` bit is set are not values (they hold 0, as OpenVDB writes them).
    fn values(&mut self, values: &[f32], active: &[u64], child: Option<&[u64]>) {
        let is_child = |i: usize| child.is_some_and(|m| bit(m, i));
        let bg = self.background;
        let eq = |a: f32, b: f32| a == b;
        let mut inactive = [bg, bg];
        let mut unique = 0;
        for (i, &v) in values.iter().enumerate() {
            if unique >= 3 {
                break;
            }
            if bit(active, i) || is_child(i) {
                continue;
            }
            let seen = (unique > 0 && eq(v, inactive[0])) || (unique > 1 && eq(v, inactive[1]));
            if !seen {
                if unique < 2 {
                    inactive[unique] = v;
                }
                unique += 1;
            }
        }
        let metadata: u8 = match unique {
            0 => 0,
            1 if eq(inactive[0], bg) => 0,
            1 if eq(inactive[0], -bg) => 1,
            1 => 2,
            2 if !eq(inactive[0], bg) && !eq(inactive[1], bg) => 5,
            2 if eq(inactive[1], bg) => {
                if eq(inactive[0], -bg) {
                    3
                } else {
                    4
                }
            }
            2 => {
                inactive.swap(0, 1);
                if eq(inactive[0], -bg) {
                    3
                } else {
                    4
                }
            }
            _ => 6,
        };
        self.b.push(metadata);
        if matches!(metadata, 2 | 4 | 5) {
            self.f32(inactive[0]);
            if metadata == 5 {
                self.f32(inactive[1]);
            }
        }
        let kept: Vec<f32> = if metadata == 6 {
            values.to_vec()
        } else {
            if matches!(metadata, 3..=5) {
                let mut selection = vec![0u64; values.len() / 64];
                for (i, &v) in values.iter().enumerate() {
                    let v = if is_child(i) { 0.0 } else { v };
                    if !bit(active, i) && eq(v, inactive[1]) {
                        set_bit(&mut selection, i);
                    }
                }
                self.mask(&selection);
            }
            values.iter().enumerate().filter(|&(i, _)| bit(active, i)).map(|(_, &v)| v).collect()
        };
        let raw: Vec<u8> = kept.iter().flat_map(|v| v.to_le_bytes()).collect();
        if self.flags & COMPRESS_ZIP != 0 {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(&raw).expect("writing to memory");
            let zipped = z.finish().expect("writing to memory");
            if zipped.len() < raw.len() {
                self.i64(zipped.len() as i64);
                self.b.extend_from_slice(&zipped);
            } else {
                self.i64(-(raw.len() as i64));
                self.b.extend_from_slice(&raw);
            }
        } else {
            self.b.extend_from_slice(&raw);
        }
    }
}

/// FNV-1a over `bytes` from `seed`.
fn fnv(bytes: &[u8], seed: u64) -> u64 {
    bytes.iter().fold(seed, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

/// A version-4-shaped UUID made from the grid's bytes (equal grids, equal files).
fn uuid_of(bytes: &[u8]) -> String {
    let a = fnv(bytes, 0xcbf2_9ce4_8422_2325);
    let b = fnv(bytes, 0x6c62_272e_07bb_0142);
    let b = (b & !0xc000_0000_0000_0000) | 0x8000_0000_0000_0000;
    let a = (a & !0xf000) | 0x4000;
    format!(
        "{:08x}-{:04x}-{:04x}-{:04x}-{:012x}",
        a >> 32,
        (a >> 16) & 0xffff,
        a & 0xffff,
        b >> 48,
        b & 0xffff_ffff_ffff
    )
}

pub(super) fn encode<G: LevelSet + ?Sized>(ls: &G, opts: &VdbOptions) -> Result<Vec<u8>, VdbError> {
    if opts.grid_name.is_empty() || opts.grid_name.contains('\x1e') {
        return Err(VdbError::Option(format!(
            "grid name {:?}: it must be non-empty and without the character U+001E",
            opts.grid_name
        )));
    }
    let spec = ls.spec();
    let g = spec.gamma();
    // Band voxels into 8³ leaves. A leaf takes about 2.2 KB here and again in the file's
    // bytes; the memory is checked every 4096 leaves, and the rest of the band skipped
    // once it does not fit.
    const LEAF_BYTES: f64 = 2.0 * (2048.0 + 64.0 + 64.0);
    let mut too_big = None;
    let mut index: HashMap<[i32; 3], usize> = HashMap::new();
    let mut leaves: Vec<Leaf> = Vec::new();
    let (mut lo, mut hi) = ([i32::MAX; 3], [i32::MIN; 3]);
    let mut count = 0u64;
    ls.for_each_band_voxel(&mut |c, v| {
        let p = [c.x, c.y, c.z];
        let o = node_origin(p, LEAF_TOTAL);
        if too_big.is_some() {
            return;
        }
        if !index.contains_key(&o) && leaves.len().is_multiple_of(4096) {
            let need = (leaves.len() + 4096) as f64 * LEAF_BYTES;
            if let Err(e) = crate::memory::check(need, "the OpenVDB leaves and file") {
                too_big = Some(e);
                return;
            }
        }
        let k = *index.entry(o).or_insert_with(|| {
            leaves.push(Leaf { origin: o, mask: [0; 8], values: Box::new([f32::NAN; 512]) });
            leaves.len() - 1
        });
        let n = slot(p, LEAF_LOG2, 0);
        set_bit(&mut leaves[k].mask, n);
        leaves[k].values[n] = v;
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
        count += 1;
    });
    drop(index);
    if let Some(e) = too_big {
        return Err(e.into());
    }
    if leaves.is_empty() {
        return Err(VdbError::Empty);
    }
    leaves.par_sort_unstable_by_key(|l| tree_key(l.origin));
    // Inactive voxels: ±γ by their side.
    leaves.par_iter_mut().for_each_init(
        || ls.accessor(),
        |acc, leaf| {
            for n in 0..512 {
                if !bit(&leaf.mask, n) {
                    let d = slot_offset(n, LEAF_LOG2, 0);
                    let o = leaf.origin;
                    let v = acc.value(Coord::new(o[0] + d[0], o[1] + d[1], o[2] + d[2]));
                    leaf.values[n] = if v < 0.0 { -g } else { g };
                }
            }
        },
    );

    // The tree above the leaves: runs of leaves sharing a lower node, of lower nodes
    // sharing an upper node.
    let side = |c: [i32; 3]| -> f32 {
        if ls.value(Coord::new(c[0], c[1], c[2])) < 0.0 {
            -g
        } else {
            g
        }
    };
    let uppers = group(&leaves, UPPER_TOTAL);
    let root_tiles = inside_root_tiles(&uppers, &leaves, &side);

    let flags = opts.compression.flags();
    let mut out = Out { b: Vec::with_capacity(leaves.len() * 1200 + 4096), flags, background: g };
    // Header.
    out.i64(MAGIC);
    out.u32(FILE_VERSION);
    out.u32(10);
    out.u32(0);
    out.b.push(1);
    let uuid_at = out.b.len();
    out.b.extend_from_slice(&[b'0'; 36]);
    out.u32(0); // file metadata entries
    out.u32(1); // grids
                // Grid descriptor.
    out.string(&opts.grid_name);
    out.string("Tree_float_5_4_3");
    out.string("");
    let offsets_at = out.b.len();
    out.b.extend_from_slice(&[0; 24]);
    let grid_pos = out.b.len();
    out.u32(flags);
    // Metadata, sorted by name.
    let lowers = leaves.chunk_by(|a, b| same_node(a.origin, b.origin, LOWER_TOTAL)).count();
    let mem = 64
        + 48 * (uppers.len() + root_tiles.len())
        + uppers.len() * (32768 * 8 + 2 * 4096 + 16)
        + lowers * (4096 * 8 + 2 * 512 + 16)
        + leaves.len() * (2048 + 64 + 32);
    let vec3i = |v: [i32; 3]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
    out.u32(7);
    out.meta("class", "string", b"level set");
    out.meta("file_bbox_max", "vec3i", &vec3i(hi));
    out.meta("file_bbox_min", "vec3i", &vec3i(lo));
    out.meta("file_compression", "string", compression_name(flags).as_bytes());
    out.meta("file_mem_bytes", "int64", &(mem as i64).to_le_bytes());
    out.meta("file_voxel_count", "int64", &(count as i64).to_le_bytes());
    out.meta("name", "string", opts.grid_name.as_bytes());
    // Transform.
    let h = spec.voxel_size as f64;
    if spec.origin == [0.0; 3] {
        out.string("UniformScaleMap");
    } else {
        out.string("UniformScaleTranslateMap");
        spec.origin.iter().for_each(|&t| out.f64(t));
    }
    for v in [h, h, 1.0 / h, 1.0 / (h * h), 0.5 / h] {
        (0..3).for_each(|_| out.f64(v));
    }
    // Topology.
    out.i32(1); // buffers per leaf
    out.f32(g);
    out.u32(root_tiles.len() as u32);
    out.u32(uppers.len() as u32);
    for t in &root_tiles {
        t.iter().for_each(|&q| out.i32(q));
        out.f32(-g);
        out.b.push(0);
    }
    for run in &uppers {
        let uo = node_origin(leaves[run.start].origin, UPPER_TOTAL);
        uo.iter().for_each(|&q| out.i32(q));
        let upper = &leaves[run.clone()];
        let lower_runs = group_in(upper, run.start, LOWER_TOTAL);
        write_internal(&mut out, uo, UPPER_LOG2, LOWER_TOTAL, &lower_runs, &leaves, &side);
        for lr in &lower_runs {
            let lo_origin = node_origin(leaves[lr.start].origin, LOWER_TOTAL);
            let leaf_runs: Vec<std::ops::Range<usize>> = lr.clone().map(|i| i..i + 1).collect();
            write_internal(&mut out, lo_origin, LOWER_LOG2, LEAF_TOTAL, &leaf_runs, &leaves, &side);
            for leaf in &leaves[lr.clone()] {
                out.mask(&leaf.mask);
            }
        }
    }
    let block_pos = out.b.len();
    for leaf in &leaves {
        out.mask(&leaf.mask);
        out.values(&leaf.values[..], &leaf.mask, None);
    }
    let end_pos = out.b.len();
    for (k, p) in [grid_pos, block_pos, end_pos].into_iter().enumerate() {
        out.b[offsets_at + 8 * k..][..8].copy_from_slice(&(p as i64).to_le_bytes());
    }
    let uuid = uuid_of(&out.b[grid_pos..]);
    out.b[uuid_at..uuid_at + 36].copy_from_slice(uuid.as_bytes());
    Ok(out.b)
}

fn same_node(a: [i32; 3], b: [i32; 3], total: u32) -> bool {
    node_origin(a, total) == node_origin(b, total)
}

/// Ranges of `leaves` (in tree order) sharing a node spanning `total` (log2 voxels).
fn group(leaves: &[Leaf], total: u32) -> Vec<std::ops::Range<usize>> {
    group_in(leaves, 0, total)
}

fn group_in(leaves: &[Leaf], base: usize, total: u32) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..=leaves.len() {
        if i == leaves.len() || !same_node(leaves[i].origin, leaves[start].origin, total) {
            out.push(base + start..base + i);
            start = i;
        }
    }
    out
}

/// An internal node's topology: child mask, value mask (empty), the slot values (±γ by
/// the side of each slot's region, 0 under a child).
fn write_internal(
    out: &mut Out,
    origin: [i32; 3],
    log2: u32,
    child_total: u32,
    children: &[std::ops::Range<usize>],
    leaves: &[Leaf],
    side: &(dyn Fn([i32; 3]) -> f32 + Sync),
) {
    let n = 1usize << (3 * log2);
    let mut child = vec![0u64; n / 64];
    for r in children {
        set_bit(&mut child, slot(leaves[r.start].origin, log2, child_total));
    }
    let values: Vec<f32> = (0..n)
        .into_par_iter()
        .map(|i| {
            if bit(&child, i) {
                0.0
            } else {
                let d = slot_offset(i, log2, child_total);
                side([origin[0] + d[0], origin[1] + d[1], origin[2] + d[2]])
            }
        })
        .collect();
    out.mask(&child);
    out.mask(&vec![0u64; n / 64]);
    out.values(&values, &vec![0u64; n / 64], Some(&child));
}

/// Root tiles (origins) for the 4096³ regions inside the surface without a child: along
/// each row of root regions (fixed y, z), the regions between two children share one
/// sign (a sign change needs band voxels); rows without children are outside.
fn inside_root_tiles(
    uppers: &[std::ops::Range<usize>],
    leaves: &[Leaf],
    side: &(dyn Fn([i32; 3]) -> f32 + Sync),
) -> Vec<[i32; 3]> {
    let mut origins: Vec<[i32; 3]> =
        uppers.iter().map(|r| node_origin(leaves[r.start].origin, UPPER_TOTAL)).collect();
    // Rows: sorted by (y, z), then x.
    origins.sort_unstable_by_key(|o| (o[1], o[2], o[0]));
    let step = 1i64 << UPPER_TOTAL;
    let mut tiles = Vec::new();
    for w in origins.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a[1] != b[1] || a[2] != b[2] || b[0] as i64 - a[0] as i64 == step {
            continue;
        }
        let first = [(a[0] as i64 + step) as i32, a[1], a[2]];
        if side(first) < 0.0 {
            let mut x = first[0] as i64;
            while x < b[0] as i64 {
                tiles.push([x as i32, a[1], a[2]]);
                x += step;
            }
        }
    }
    tiles.sort_unstable();
    tiles
}
