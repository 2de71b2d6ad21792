//! The storage benchmark behind `levelset bench`: the same stencil arithmetic, random
//! access and band maintenance on the Sorted Tile List and on the DT-Grid, timed in one
//! run so the ratio is meaningful on a shared machine.
//!
//! Both grids run identical scalar arithmetic (`smooth7`, `star19`), so the ratio measures
//! the data structures: tile traversal with a padded block (tile paper Sec. 4.4, 4.7)
//! against the DT-Grid stencil iterator (DT-Grid paper Sec. 3.3). The PDE kernels and the
//! full scenarios arrive with the kernels and evolution work.

use crate::build::{dtgrid_from_tiles, tiles_from_shape};
use crate::coord::Coord;
use crate::dtgrid::{DtGrid, Stencil, StencilIter};
use crate::grid::{GridError, GridSpec};
use crate::info::human_bytes;
use crate::shapes::Shape;
use crate::tiles::{tile_of, NeighbourCursor, PaddedBlock, Tile, TileGrid};
use serde::Serialize;
use std::time::Instant;

/// One explicit diffusion step of the 7-point Laplacian, clamped to the band.
/// `v` is the 7-point star `[centre, -x, +x, -y, +y, -z, +z]`.
#[inline(always)]
fn smooth7(v: [f32; 7], g: f32) -> f32 {
    let [c, xm, xp, ym, yp, zm, zp] = v;
    (c + 0.1 * ((xm + xp) + (ym + yp) + (zm + zp) - 6.0 * c)).clamp(-g, g)
}

/// Weights of the 19-point star (centre, then ±1..±3 per axis): a read pattern like
/// HJ-WENO5's.
const STAR_W: [f32; 4] = [0.4, 0.06, 0.03, 0.01];

#[inline(always)]
fn star19(c: f32, axis: [[f32; 6]; 3]) -> f32 {
    let mut s = STAR_W[0] * c;
    for a in axis {
        s += STAR_W[1] * (a[2] + a[3]) + STAR_W[2] * (a[1] + a[4]) + STAR_W[3] * (a[0] + a[5]);
    }
    s
}

/// `smooth7` over every tile: gather a 1-voxel halo, update 64 voxels. Output in list order.
pub fn tiles_smooth7(grid: &TileGrid, out: &mut Vec<Tile>) {
    // The PaddedBlock<1> layout: rows of 12 (x from -4), 6 rows per slice.
    const SY: usize = 12;
    const SZ: usize = 12 * 6;
    out.clear();
    out.reserve(grid.len());
    let g = grid.gamma();
    let mut block = PaddedBlock::<1>::new();
    let mut cur = NeighbourCursor::new(grid.tile_coords(), 0, grid.len());
    while let Some(nb) = cur.next() {
        block.gather(grid, &nb);
        let d = block.data();
        let mut t = Tile::splat(0.0);
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4 {
                    let i = (x + 4) + SY * (y + 1) + SZ * (z + 1);
                    let star =
                        [d[i], d[i - 1], d[i + 1], d[i - SY], d[i + SY], d[i - SZ], d[i + SZ]];
                    t.0[x + 4 * y + 16 * z] = smooth7(star, g);
                }
            }
        }
        out.push(t);
    }
}

/// `smooth7` over every DT-Grid point with the 7-point stencil iterator.
pub fn dtgrid_smooth7(grid: &DtGrid, out: &mut Vec<f32>) {
    out.clear();
    out.resize(grid.len(), 0.0);
    let g = grid.gamma();
    let mut it = StencilIter::new(grid, &Stencil::star7());
    while it.advance() {
        let v = it.values();
        out[it.center_index()] = smooth7(v.try_into().expect("7-point star"), g);
    }
}

/// `star19` over every tile with a 3-voxel halo.
pub fn tiles_star19(grid: &TileGrid, out: &mut Vec<Tile>) {
    // The PaddedBlock<3> layout: rows of 12 (x from -4), 10 rows per slice, 10 slices.
    const SY: usize = 12;
    const SZ: usize = 12 * 10;
    out.clear();
    out.reserve(grid.len());
    let mut block = PaddedBlock::<3>::new();
    let mut cur = NeighbourCursor::new(grid.tile_coords(), 0, grid.len());
    while let Some(nb) = cur.next() {
        block.gather(grid, &nb);
        let d: &[f32; SZ * 10] = block.data().try_into().expect("12×10×10 block");
        let mut t = Tile::splat(0.0);
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4 {
                    let i = (x + 4) + SY * (y + 3) + SZ * (z + 3);
                    let ax = |s: usize| {
                        [d[i - 3 * s], d[i - 2 * s], d[i - s], d[i + s], d[i + 2 * s], d[i + 3 * s]]
                    };
                    t.0[x + 4 * y + 16 * z] = star19(d[i], [ax(1), ax(SY), ax(SZ)]);
                }
            }
        }
        out.push(t);
    }
}

/// `star19` over every DT-Grid point with the WENO5 stencil iterator.
pub fn dtgrid_star19(grid: &DtGrid, out: &mut Vec<f32>) {
    out.clear();
    out.resize(grid.len(), 0.0);
    let mut it = StencilIter::new(grid, &Stencil::weno5());
    while it.advance() {
        let v = it.values();
        let mut axis = [[0.0f32; 6]; 3];
        for (a, ax) in axis.iter_mut().enumerate() {
            ax.copy_from_slice(&v[1 + 6 * a..7 + 6 * a]);
        }
        out[it.center_index()] = star19(v[0], axis);
    }
}

/// Largest |difference| between a tile result and a DT-Grid result over the DT-Grid's
/// points (the band voxels both grids store).
pub fn max_abs_diff(tiles: &TileGrid, tile_out: &[Tile], dt: &DtGrid, dt_out: &[f32]) -> f32 {
    let mut m = 0.0f32;
    let mut pos = 0usize;
    for (i, (c, _)) in dt.iter().enumerate() {
        let (t, l) = tile_of(c);
        // DT-Grid points come in lexicographic order, tiles are not visited in that order:
        // find the tile (near the last one) by binary search.
        if tiles.tile_coords().get(pos) != Some(&t) {
            pos = tiles.find_tile(t).expect("every band voxel lies in a tile");
        }
        m = m.max((tile_out[pos].0[l] - dt_out[i]).abs());
    }
    m
}

/// Timing of one operation on both grids.
#[derive(Clone, Debug, Serialize)]
pub struct OpResult {
    pub op: &'static str,
    pub dtgrid_seconds: f64,
    pub tiles_seconds: f64,
    /// Updated voxels per second: DT-Grid points / tiles × 64.
    pub dtgrid_voxel_updates_per_s: f64,
    pub tiles_voxel_updates_per_s: f64,
    /// Band voxels per second, the useful work: the same numerator for both grids.
    pub dtgrid_band_voxels_per_s: f64,
    pub tiles_band_voxels_per_s: f64,
    /// DT-Grid seconds / tile seconds.
    pub speedup_vs_dtgrid: f64,
    /// Largest |tiles − DT-Grid| over the band voxels, where the op produces values.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_abs_diff: Option<f32>,
}

/// All operations on one shape.
#[derive(Clone, Debug, Serialize)]
pub struct ScenarioResult {
    pub name: String,
    pub shape: Shape,
    pub band_voxels: usize,
    pub dtgrid_points: usize,
    pub tiles: usize,
    pub dtgrid_bytes: usize,
    pub tiles_bytes: usize,
    pub ops: Vec<OpResult>,
}

/// The whole benchmark report: the storage operations and the pure-kernel throughput.
#[derive(Clone, Debug, Serialize)]
pub struct StorageBench {
    pub cpu: String,
    pub target_features: Vec<&'static str>,
    pub profile: &'static str,
    pub threads: usize,
    pub repetitions: usize,
    pub scenarios: Vec<ScenarioResult>,
    /// Voxel updates/s of the kernels on a dense in-cache block, per lane type.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub kernels: Vec<levelset_kernels::bench::KernelResult>,
}

/// The kernel section as text: one row per kernel, one column per lane type, with the
/// speed-up over scalar `f32`.
pub fn kernels_text(rows: &[levelset_kernels::bench::KernelResult]) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "kernels on a dense in-cache 32³ block, one thread (Mvoxel-updates/s, speed-up over f32):"
    );
    for k in levelset_kernels::bench::KERNELS {
        let scalar = rows.iter().find(|r| r.kernel == k && r.lanes == "f32");
        let _ = write!(s, "  {k:<17}");
        for r in rows.iter().filter(|r| r.kernel == k) {
            let up = scalar.map_or(0.0, |b| r.voxel_updates_per_s / b.voxel_updates_per_s);
            let _ =
                write!(s, " {:>6}: {:>7.1} ({:>4.1}x)", r.lanes, r.voxel_updates_per_s / 1e6, up);
        }
        s.push('\n');
    }
    s
}

/// Wall time of one call of `f`.
pub fn timed(f: impl FnOnce()) -> f64 {
    let t = Instant::now();
    f();
    t.elapsed().as_secs_f64()
}

/// Best times of two competitors over `reps` rounds, after one warm-up round. The runs
/// alternate (a, b, a, b, ...) so a burst of load on the shared machine hits both, and the
/// ratio stays meaningful. Each closure returns the seconds of its measured part, so it
/// can keep set-up work out of the timing.
pub fn time_pair(
    reps: usize,
    mut a: impl FnMut() -> f64,
    mut b: impl FnMut() -> f64,
) -> (f64, f64) {
    a();
    b();
    let (mut ta, mut tb) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..reps.max(1) {
        ta = ta.min(a());
        tb = tb.min(b());
    }
    (ta, tb)
}

/// `"debug"` or `"release"`: whether this binary was built with debug assertions.
pub fn build_profile() -> &'static str {
    if cfg!(debug_assertions) {
        "debug"
    } else {
        "release"
    }
}

/// The CPU model from /proc/cpuinfo, or "unknown".
pub fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}

/// Deterministic pseudo-random voxels around the band (splitmix64), for random access.
fn probe_points(dt: &DtGrid, n: usize) -> Vec<Coord> {
    let pts: Vec<Coord> = dt.iter().map(|(c, _)| c).collect();
    if pts.is_empty() {
        return Vec::new();
    }
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    (0..n)
        .map(|_| {
            let r = next();
            let p = pts[(r % pts.len() as u64) as usize];
            let o = |k: u32| ((r >> k) & 7) as i32 - 3;
            p.wrapping_add(Coord::new(o(40), o(44), o(48)))
        })
        .collect()
}

/// Runs every operation on one shape; `progress` is told each finished operation.
pub fn run_scenario(
    name: &str,
    shape: &Shape,
    spec: GridSpec,
    reps: usize,
    mut progress: impl FnMut(&str),
) -> Result<ScenarioResult, GridError> {
    let mut tiles = tiles_from_shape(shape, spec)?;
    tiles.shrink_to_fit();
    let mut dt = dtgrid_from_tiles(&tiles);
    dt.shrink_to_fit();
    let band = dt.band_voxels();
    let pts = dt.len() as f64;
    let tvox = (tiles.len() * 64) as f64;
    let mut ops = Vec::new();
    let op = |op: &'static str, dts: f64, ts: f64, diff: Option<f32>| OpResult {
        op,
        dtgrid_seconds: dts,
        tiles_seconds: ts,
        dtgrid_voxel_updates_per_s: pts / dts,
        tiles_voxel_updates_per_s: tvox / ts,
        dtgrid_band_voxels_per_s: band as f64 / dts,
        tiles_band_voxels_per_s: band as f64 / ts,
        speedup_vs_dtgrid: dts / ts,
        max_abs_diff: diff,
    };

    let (mut tout, mut dout) = (Vec::new(), Vec::new());
    let (dts, ts) = time_pair(
        reps,
        || timed(|| dtgrid_smooth7(&dt, &mut dout)),
        || timed(|| tiles_smooth7(&tiles, &mut tout)),
    );
    ops.push(op("smooth7", dts, ts, Some(max_abs_diff(&tiles, &tout, &dt, &dout))));
    progress("smooth7");

    let (dts, ts) = time_pair(
        reps,
        || timed(|| dtgrid_star19(&dt, &mut dout)),
        || timed(|| tiles_star19(&tiles, &mut tout)),
    );
    ops.push(op("star19", dts, ts, Some(max_abs_diff(&tiles, &tout, &dt, &dout))));
    progress("star19");

    let probes = probe_points(&dt, 1 << 20);
    let (dts, ts) = time_pair(
        reps,
        || {
            timed(|| {
                std::hint::black_box(probes.iter().map(|&c| dt.value(c)).sum::<f32>());
            })
        },
        || {
            timed(|| {
                std::hint::black_box(probes.iter().map(|&c| tiles.value(c)).sum::<f32>());
            })
        },
    );
    let mut r = op("random_access", dts, ts, None);
    let n = probes.len() as f64;
    (r.dtgrid_voxel_updates_per_s, r.tiles_voxel_updates_per_s) = (n / dts, n / ts);
    (r.dtgrid_band_voxels_per_s, r.tiles_band_voxels_per_s) = (n / dts, n / ts);
    ops.push(r);
    progress("random_access");

    // Growing the band by one step: DT-Grid rebuild by dilation (Sec. 3.6.2) against tile
    // management from the current activity (Alg. 2-3). Each keeps the values it had.
    // The tile grid is cloned outside the timed part (management works in place).
    let (dts, ts) = time_pair(
        reps,
        || {
            timed(|| {
                std::hint::black_box(dt.rebuild(spec.gamma(), 1).expect("in range"));
            })
        },
        || {
            let mut t = tiles.clone();
            let s = timed(|| {
                std::hint::black_box(t.manage_tiles().expect("in range"));
            });
            drop(t);
            s
        },
    );
    ops.push(op("rebuild", dts, ts, None));
    progress("rebuild");

    Ok(ScenarioResult {
        name: name.into(),
        shape: shape.clone(),
        band_voxels: band,
        dtgrid_points: dt.len(),
        tiles: tiles.len(),
        dtgrid_bytes: dt.memory().total(),
        tiles_bytes: tiles.memory().total(),
        ops,
    })
}

impl StorageBench {
    /// The report as text.
    pub fn to_text(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "storage benchmark — cpu: {} | features: {} | profile: {} | threads: {} | best of {}",
            self.cpu,
            self.target_features.join(","),
            self.profile,
            self.threads,
            self.repetitions
        );
        for sc in &self.scenarios {
            let _ = writeln!(
                s,
                "\n{}: {} band voxels; DT-Grid {} points, {}; tiles {} ({} voxels), {} ({:.2}x)",
                sc.name,
                sc.band_voxels,
                sc.dtgrid_points,
                human_bytes(sc.dtgrid_bytes),
                sc.tiles,
                sc.tiles * 64,
                human_bytes(sc.tiles_bytes),
                sc.tiles_bytes as f64 / sc.dtgrid_bytes.max(1) as f64
            );
            let _ = writeln!(
                s,
                "  {:<14} {:>10} {:>10} {:>14} {:>14} {:>9} {:>10}",
                "op",
                "dtgrid s",
                "tiles s",
                "dtgrid Mvox/s",
                "tiles Mvox/s",
                "speedup",
                "max|diff|"
            );
            for o in &sc.ops {
                let _ = writeln!(
                    s,
                    "  {:<14} {:>10.4} {:>10.4} {:>14.1} {:>14.1} {:>8.2}x {:>10}",
                    o.op,
                    o.dtgrid_seconds,
                    o.tiles_seconds,
                    o.dtgrid_voxel_updates_per_s / 1e6,
                    o.tiles_voxel_updates_per_s / 1e6,
                    o.speedup_vs_dtgrid,
                    o.max_abs_diff.map_or("-".into(), |d| format!("{d:.1e}"))
                );
            }
        }
        if !self.kernels.is_empty() {
            s.push('\n');
            s.push_str(&kernels_text(&self.kernels));
        }
        s.push_str(
            "\nMvox/s counts updated voxels (DT-Grid points, tiles x 64); both grids run the same \
             scalar arithmetic. random_access: lookups/s. rebuild: DT-Grid dilation by one voxel vs \
             tile management.\n",
        );
        s
    }
}
