//! # levelset-cli
//!
//! The application around the `sparse-levelset` library: the papers' evolution scenarios as
//! command-line presets, the speed-up report (tiles against the DT-Grid), the storage
//! benchmark, the `info` report, the batch commands' spreading over ranks and threads,
//! progress bars, worker pinning and the output helpers of the two binaries, `levelset`
//! (one module per subcommand) and `levelset-speedup` (the report, what
//! `cargo run --release` runs). It adds no numerics: every computation and
//! every input check is the library's ([`sparse_levelset::io::input`] is the one loader).
//!
//! ```
//! use levelset_cli::scenario::{Scenario, ScenarioKind, ScenarioOptions};
//!
//! let mut o = ScenarioOptions::new(ScenarioKind::Sphere);
//! (o.size, o.steps) = (Some(24), Some(2));
//! let (summary, _) = Scenario::resolve(o).unwrap().run(|_| {}).unwrap();
//! assert_eq!(summary.steps_taken, 2);
//! ```

pub mod batch;
pub mod info;
pub mod memtable;
pub mod output;
pub mod pin;
pub mod progress;
pub mod ranks;
pub mod scenario;
pub mod segbench;
pub mod solution;
pub mod speedup;
pub mod storage;
