//! A dependent of sparse-levelset: which instruction-set level the library runs at, and a
//! sphere under mean curvature flow on both grids, the same bits.
//!
//! `cargo run --release` here; `LEVELSET_SIMD=avx2` (or `baseline`, `avx512`) forces a level.

use sparse_levelset::evolve::{Flow, GridKind, Lanes, Settings, Simulation};
use sparse_levelset::grid::GridSpec;
use sparse_levelset::level::{self, Level};
use sparse_levelset::storage::shapes::Shape;
use std::process::ExitCode;
use std::time::Instant;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    level::check_env()?;
    let active = Level::active();
    println!("instruction-set level: {} (detected: {})", active.describe(), Level::detected());
    let compiled = if cfg!(target_feature = "avx2") { "with AVX2" } else { "without AVX2" };
    println!("this example was compiled {compiled}; the library's kernels chose at run time");

    // r(t)² = r₀² − 2εt for κ = 1/r (the library's ½∇·n).
    let (r0, steps) = (16.0f64, 30);
    let shape = Shape::Sphere { center: [0.0; 3], radius: r0 };
    let (spec, flow) = (GridSpec::default(), Flow::mean_curvature(1.0));
    let mut tiles = Simulation::from_shape(
        GridKind::Tiles(Lanes::Simd),
        &shape,
        spec,
        flow.clone(),
        Settings::default(),
    )?;
    let mut dtgrid =
        Simulation::from_shape(GridKind::DtGrid, &shape, spec, flow, Settings::default())?;
    let t0 = Instant::now();
    for _ in 0..steps {
        tiles.step()?;
    }
    let tiles_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    for _ in 0..steps {
        dtgrid.step()?;
    }
    let dtgrid_s = t0.elapsed().as_secs_f64();
    let r = (3.0 * tiles.measure()?.volume / (4.0 * std::f64::consts::PI)).cbrt();
    let exact = (r0 * r0 - 2.0 * tiles.time()).sqrt();
    println!(
        "sphere r0 = {r0} under mean curvature flow, {steps} steps to t = {:.3}: r = {r:.4} \
         (exact {exact:.4})",
        tiles.time()
    );
    println!(
        "tiles ({} lanes) {tiles_s:.3} s, DT-Grid {dtgrid_s:.3} s; checksums {:016x} and {:016x}",
        Lanes::Simd.kind().name(),
        tiles.checksum(),
        dtgrid.checksum()
    );
    if tiles.checksum() != dtgrid.checksum() {
        return Err("the two grids disagree".into());
    }
    if (r - exact).abs() > 0.1 {
        return Err(format!("radius {r} is not {exact} within 0.1").into());
    }
    Ok(())
}
