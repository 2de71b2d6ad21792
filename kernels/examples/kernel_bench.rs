//! Prints the pure-kernel throughput table and the JSON of `levelset-speedup --kernels`.
//!
//! ```sh
//! cargo run --release -p levelset-kernels --example kernel_bench [-- nx ny nz seconds]
//! ```

use levelset_kernels::bench::{run_kernel_bench, KernelBenchConfig, KERNELS, LANES};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut cfg = KernelBenchConfig::default();
    if args.len() >= 3 {
        for (d, a) in cfg.dims.iter_mut().zip(&args) {
            *d = a.parse()?;
        }
    }
    if let Some(s) = args.get(3) {
        cfg.seconds = s.parse()?;
    }
    let report = run_kernel_bench(&cfg)?;
    println!("block {:?}, target features {:?}", cfg.dims, report.target_features);
    println!("{:<18} {:>8} {:>14} {:>9}", "kernel", "lanes", "Mvoxel-upd/s", "vs f32");
    for k in KERNELS {
        let base = report.get(k, "f32").unwrap_or(f64::NAN);
        for l in LANES {
            let v = report.get(k, l).unwrap_or(f64::NAN);
            println!("{:<18} {:>8} {:>14.1} {:>8.2}x", k, l, v / 1e6, v / base);
        }
    }
    println!("{}", report.to_json());
    Ok(())
}
