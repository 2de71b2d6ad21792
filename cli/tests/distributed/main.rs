//! The `levelset` command under `mpirun` (feature `mpi`): distributed runs on 2 and 3 ranks
//! and batches on 2. Without the feature this binary holds no test.

#[path = "../integration/common/mod.rs"]
mod common;

mod batch_mpi;
mod mpi;

/// `mpirun -n RANKS --oversubscribe levelset` (as root too, in containers), with a session
/// directory of its own: OpenMPI's default one is shared by every `mpirun` of a user on
/// the machine, and the tests run several at once, so one finishing could remove it while
/// another was creating its own inside (`orte_init` failed: "A call to mkdir was unable to
/// create the desired directory", seen in CI).
#[cfg(feature = "mpi")]
fn mpirun(ranks: usize) -> std::process::Command {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static LAUNCHES: AtomicUsize = AtomicUsize::new(0);
    let k = LAUNCHES.fetch_add(1, Ordering::Relaxed);
    let session = std::env::temp_dir()
        .join(format!("levelset-test-ompi-{}", std::process::id()))
        .join(k.to_string());
    std::fs::create_dir_all(&session).expect("a session directory for mpirun");
    let mut c = std::process::Command::new("mpirun");
    c.env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_orte_tmpdir_base", &session)
        .env("PRTE_MCA_prte_tmpdir_base", &session)
        .args(["-n", &ranks.to_string(), "--oversubscribe", env!("CARGO_BIN_EXE_levelset")]);
    c
}
