//! The sparse voxel store of a march: values, states and heap handles of the voxels the
//! march has touched, in 4³ blocks found through a hash map of block coordinates.
//!
//! # Why a hash of 4³ blocks
//! The march visits voxels in the order of their arrival time, i.e. all over the band,
//! and discovers new voxels (trial) next to frozen ones as it goes. A hash map from block
//! coordinate to block index gives O(1) random access to any voxel and O(1) insertion of
//! a new block, in any order — a sorted list (tiles, DT-Grid) would need an O(N)
//! insertion for every new block. Blocks of 4³ (the tile size, `coord >> 2`) keep the
//! six neighbours of a voxel mostly in the same block, so a one-entry cache of the last
//! block answers most lookups without hashing, and the map holds 64× fewer keys than a
//! per-voxel map. Memory is proportional to the voxels touched (the band plus one
//! voxel-layer of trial voxels, rounded up to whole blocks): no array ever spans the
//! bounding box.

use crate::coord::Coord;
use crate::storage::tiles::{tile_of, TILE_LEN};
use std::cell::Cell;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// State of a voxel (Sec. 2.1): not yet reached, in the narrow band (trial), or frozen.
pub(crate) const FAR: u8 = 0;
pub(crate) const TRIAL: u8 = 1;
pub(crate) const FROZEN: u8 = 2;
/// Flag bit: the voxel lies on the inside (φ < 0); its arrival time is −φ.
pub(crate) const INSIDE: u8 = 4;
/// Flag bit: the voxel belongs to the initial frozen set (the interface layer).
pub(crate) const INITIAL: u8 = 8;
const STATE_MASK: u8 = 3;
/// No block.
const NONE: u32 = u32::MAX;
use crate::coord::FACE_OFFSETS as FACES;

/// FxHash-style hasher for block coordinates (three `i32` writes); the hash needs no
/// resistance against adversarial keys, only speed.
#[derive(Default, Clone, Copy)]
pub(crate) struct CoordHasher(u64);

impl Hasher for CoordHasher {
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    #[inline]
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    #[inline]
    fn write_i32(&mut self, v: i32) {
        self.write_u64(v as u32 as u64);
    }
}

/// One voxel of the store.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Voxel {
    /// The signed value in march units (φ / h for distances, T for arrival times); set
    /// when the voxel is frozen.
    pub value: f64,
    /// The voxel's heap handle while trial.
    pub handle: u32,
    /// [`FAR`] / [`TRIAL`] / [`FROZEN`], plus [`INSIDE`].
    pub state: u8,
}

const FAR_VOXEL: Voxel = Voxel { value: 0.0, handle: u32::MAX, state: FAR };

type BlockMap = HashMap<Coord, u32, BuildHasherDefault<CoordHasher>>;

/// Voxels touched by a march (see the module docs). A voxel id is `block · 64 + local`.
pub(crate) struct Store {
    blocks: BlockMap,
    /// Block coordinate of each block, in creation order.
    block_coords: Vec<Coord>,
    /// Per block: the index of the face-neighbour block in directions −x, +x, −y, +y,
    /// −z, +z ([`NONE`] while absent), kept up to date when blocks are created, so a
    /// step across a block face needs no hash lookup.
    links: Vec<[u32; 6]>,
    /// Per voxel: value, state and heap handle together (an update reads the state and
    /// value of a neighbour: one cache line, not two).
    pub(crate) vox: Vec<Voxel>,
    /// The last block looked up: (block coordinate, block index).
    cache: Cell<(Coord, u32)>,
}

impl Store {
    pub(crate) fn new() -> Store {
        Store {
            blocks: BlockMap::default(),
            block_coords: Vec::new(),
            links: Vec::new(),
            vox: Vec::new(),
            cache: Cell::new((Coord::new(i32::MIN, i32::MIN, i32::MIN), u32::MAX)),
        }
    }

    /// Blocks allocated so far.
    pub(crate) fn num_blocks(&self) -> usize {
        self.block_coords.len()
    }

    /// Bytes per block of the per-voxel arrays (for memory checks).
    pub(crate) const BLOCK_BYTES: usize = TILE_LEN * std::mem::size_of::<Voxel>() + 56;

    #[inline]
    fn block(&self, t: Coord) -> Option<u32> {
        let (ct, cb) = self.cache.get();
        if ct == t && cb != u32::MAX {
            return Some(cb);
        }
        let b = *self.blocks.get(&t)?;
        self.cache.set((t, b));
        Some(b)
    }

    /// Voxel id of `c`, if its block exists.
    #[inline]
    pub(crate) fn find(&self, c: Coord) -> Option<u32> {
        let (t, l) = tile_of(c);
        self.block(t).map(|b| b * TILE_LEN as u32 + l as u32)
    }

    /// Voxel id of `c`, creating its block (all voxels [`FAR`]) when needed.
    #[inline]
    pub(crate) fn find_or_insert(&mut self, c: Coord) -> u32 {
        let (t, l) = tile_of(c);
        let b = match self.block(t) {
            Some(b) => b,
            None => {
                let b = u32::try_from(self.block_coords.len())
                    .ok()
                    .filter(|&b| (b as u64 + 1) * TILE_LEN as u64 <= u32::MAX as u64)
                    .expect("fewer than 2^26 blocks (callers check the memory budget first)");
                self.blocks.insert(t, b);
                self.block_coords.push(t);
                let mut links = [NONE; 6];
                for (f, o) in FACES.iter().enumerate() {
                    // Block coordinates are voxel >> 2, so ±1 never overflows.
                    if let Some(&nb) = self.blocks.get(&t.wrapping_add(*o)) {
                        links[f] = nb;
                        self.links[nb as usize][f ^ 1] = b;
                    }
                }
                self.links.push(links);
                let n = self.vox.len() + TILE_LEN;
                self.vox.resize(n, FAR_VOXEL);
                self.cache.set((t, b));
                b
            }
        };
        b * TILE_LEN as u32 + l as u32
    }

    /// Voxel id of the voxel `d` steps (|d| ≤ 4) along `axis` from voxel `id`, if its
    /// block exists: within the block by index arithmetic, across a face through the
    /// block's links. The caller checks that the target is a representable coordinate.
    #[inline(always)]
    pub(crate) fn step(&self, id: u32, axis: usize, d: i32) -> Option<u32> {
        let b = id >> 6;
        let l = (id & 63) as i32;
        let shift = 2 * axis as i32;
        let lc = ((l >> shift) & 3) + d;
        let base = l & !(3 << shift);
        if (0..4).contains(&lc) {
            return Some((b << 6) | (base | (lc << shift)) as u32);
        }
        let nb = self.links[b as usize][2 * axis + (d > 0) as usize];
        (nb != NONE).then(|| (nb << 6) | (base | ((lc & 3) << shift)) as u32)
    }

    /// [`Store::step`], creating the target block when needed (`n` is the target's
    /// coordinate).
    #[inline]
    pub(crate) fn step_or_insert(&mut self, id: u32, axis: usize, d: i32, n: Coord) -> u32 {
        match self.step(id, axis, d) {
            Some(nid) => nid,
            None => self.find_or_insert(n),
        }
    }

    /// The value and full state of the voxel `d` steps along `axis` from voxel `id`, if
    /// it is frozen.
    #[inline(always)]
    pub(crate) fn frozen_step(&self, id: u32, axis: usize, d: i32) -> Option<(f64, u8)> {
        let nid = self.step(id, axis, d)?;
        let v = &self.vox[nid as usize];
        (v.state & STATE_MASK == FROZEN).then_some((v.value, v.state))
    }

    /// Block coordinates sorted in [`Coord`] order, with their block indices.
    pub(crate) fn sorted_blocks(&self) -> Vec<(Coord, u32)> {
        let mut v: Vec<(Coord, u32)> =
            self.block_coords.iter().enumerate().map(|(b, &t)| (t, b as u32)).collect();
        v.sort_unstable_by_key(|&(t, _)| t);
        v
    }
}
