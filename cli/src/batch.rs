//! Batch commands over a folder of inputs (`levelset segment DIR`, `levelset voxelize
//! DIR`): the inputs spread across MPI ranks and, within a rank, across worker threads;
//! the per-input records gathered to rank 0, which writes the one summary.
//!
//! Every rank lists the same inputs in the same (sorted) order; rank `r` of `N` runs the
//! inputs whose index `i` has `i % N == r`, so ranks never write the same file. A failed
//! input is a record like any other: every rank reaches the gather, and no rank waits
//! for one that gave up.

use serde::de::DeserializeOwned;
use serde::Serialize;
use sparse_levelset::distributed::Transport;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// This rank and the number of ranks (`(0, 1)` without a transport).
pub fn rank_size(transport: Option<&dyn Transport>) -> (usize, usize) {
    transport.map_or((0, 1), |t| (t.rank(), t.size()))
}

/// Whether this process writes the summary: rank 0, or the only process.
pub fn is_lead(transport: Option<&dyn Transport>) -> bool {
    rank_size(transport).0 == 0
}

/// `"rank R: "` on more than one rank, to tell the ranks' interleaved lines apart;
/// empty otherwise.
pub fn line_prefix(transport: Option<&dyn Transport>) -> String {
    match rank_size(transport) {
        (_, 1) => String::new(),
        (r, _) => format!("rank {r}: "),
    }
}

/// Refuses a single `input` (a `what`: "mesh", "image") when MPI started more than one
/// rank: every rank would run it into the same files. A directory of them is what
/// spreads over the ranks.
pub fn refuse_one_input_on_ranks(input: &std::path::Path, what: &str) -> Result<(), String> {
    if crate::ranks::launched_ranks().is_some_and(|n| n > 1) {
        return Err(format!(
            "{}: not a directory, and one {what} runs in one process: start it without \
             mpirun (a directory of {what}s is spread over the ranks)",
            input.display()
        ));
    }
    Ok(())
}

/// The checks before any work, agreed on by every rank: every rank passes its own
/// result (its error, or what it found, such as the sorted list of inputs) and gets an
/// error when any rank failed or found something other than rank 0 did. Collective.
///
/// A rank that returned alone would leave the others waiting for it in the gather of
/// [`spread`], so a failure on one rank (a file system that differs between nodes, an
/// output directory one node cannot create) must end every rank's command.
pub fn agree<T: Serialize>(
    transport: Option<&dyn Transport>,
    checked: Result<T, String>,
) -> Result<T, String> {
    let Some(t) = transport else { return checked };
    // Serialising a value of a plain data type does not fail; if it does, the message
    // travels instead.
    let own = match &checked {
        Ok(v) => serde_json::to_vec(&Ok::<&T, String>(v)),
        Err(e) => serde_json::to_vec(&Err::<&T, &String>(e)),
    }
    .unwrap_or_else(|e| {
        serde_json::to_vec(&Err::<(), String>(format!("cannot send the checks: {e}")))
            .unwrap_or_default()
    });
    let all = t.all_gather(&own);
    let checked = checked?;
    for (r, m) in all.iter().enumerate() {
        match serde_json::from_slice::<Result<serde_json::Value, String>>(m) {
            Ok(Err(e)) => return Err(format!("rank {r}: {e}")),
            Err(e) => return Err(format!("rank {r}: its checks cannot be read: {e}")),
            Ok(Ok(_)) if m != &all[0] => {
                return Err(format!(
                    "rank {r} found other inputs than rank 0 (is the directory on a file \
                     system every rank sees?)"
                ))
            }
            Ok(Ok(_)) => {}
        }
    }
    Ok(checked)
}

/// Runs `run(item, threads)` for every item on `threads` threads and returns the
/// results in item order. With at least as many items as threads, `threads` workers take
/// the next item, each item on one thread; with fewer, the items run one after another,
/// each with all the threads.
pub fn run_items<I: Sync, T: Send>(
    items: &[&I],
    threads: usize,
    run: impl Fn(&I, usize) -> T + Sync,
) -> Vec<T> {
    let threads = threads.max(1);
    if items.len() < threads {
        return items.iter().map(|i| run(i, threads)).collect();
    }
    // Workers of our own rather than a rayon parallel loop: a rayon worker waiting inside
    // an item would start another item, running more items at once than threads.
    let next = AtomicUsize::new(0);
    let done = Mutex::new(Vec::with_capacity(items.len()));
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(i) else { break };
                let r = run(item, 1);
                done.lock().unwrap_or_else(|e| e.into_inner()).push((i, r));
            });
        }
    });
    let mut done = done.into_inner().unwrap_or_else(|e| e.into_inner());
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}

/// Runs this rank's share of `items` (the indices `i` with `i % ranks == rank`) with
/// [`run_items`] and gathers every rank's records to rank 0 (JSON through
/// [`Transport::all_gather`]). Returns all the records in item order on rank 0 (and
/// without a transport), `None` on the other ranks. Collective: every rank calls it with
/// the same items (see [`agree`]).
///
/// An error means a rank's records could not be read (rank 0 only).
pub fn spread<I: Sync, T: Serialize + DeserializeOwned + Send>(
    transport: Option<&dyn Transport>,
    items: &[I],
    threads: usize,
    run: impl Fn(&I, usize) -> T + Sync,
) -> Result<Option<Vec<T>>, String> {
    let (rank, size) = rank_size(transport);
    let mine: Vec<&I> = items.iter().skip(rank).step_by(size).collect();
    let records = run_items(&mine, threads, run);
    let Some(t) = transport else { return Ok(Some(records)) };
    // A failure to serialise still reaches the gather, as a message for rank 0.
    let bytes = serde_json::to_vec(&Ok::<&Vec<T>, String>(&records)).unwrap_or_else(|e| {
        serde_json::to_vec(&Err::<(), String>(format!("cannot send its records: {e}")))
            .unwrap_or_default()
    });
    let all = t.all_gather(&bytes);
    if rank != 0 {
        return Ok(None);
    }
    let mut parts = Vec::with_capacity(size);
    for (r, m) in all.iter().enumerate() {
        let part: Vec<T> = serde_json::from_slice::<Result<Vec<T>, String>>(m)
            .map_err(|e| format!("rank {r}: its records cannot be read: {e}"))?
            .map_err(|e| format!("rank {r}: {e}"))?;
        let expected = items.len().saturating_sub(r).div_ceil(size);
        if part.len() != expected {
            return Err(format!("rank {r} sent {} records for its {expected} inputs", part.len()));
        }
        parts.push(part.into_iter());
    }
    // Item i is the (i / size)-th record of rank i % size.
    let mut out = Vec::with_capacity(items.len());
    for i in 0..items.len() {
        match parts[i % size].next() {
            Some(rec) => out.push(rec),
            None => return Err(format!("rank {}: a record is missing", i % size)),
        }
    }
    Ok(Some(out))
}

/// Lists the files of `dir` that `keep` accepts, by name: every rank lists the same inputs
/// in the same order.
pub fn list_files(
    dir: &std::path::Path,
    keep: impl Fn(&std::path::Path) -> bool,
) -> Result<Vec<std::path::PathBuf>, String> {
    let mut out = Vec::new();
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for e in entries {
        let p = e.map_err(|e| format!("{}: {e}", dir.display()))?.path();
        if p.is_file() && keep(&p) {
            out.push(p);
        }
    }
    out.sort();
    Ok(out)
}

/// The end of a folder batch on the lead rank: `dir/summary.json` holds `fields` (the
/// command's counts, in order), then the ranks, threads, wall time and one record an input.
/// Returns the summary and how the batch ran, for the last line ("2.05 s on 2 ranks × 2
/// threads").
pub fn write_summary(
    dir: &std::path::Path,
    fields: Vec<(&str, serde_json::Value)>,
    records: Vec<serde_json::Value>,
    transport: Option<&dyn Transport>,
    threads: usize,
    start: std::time::Instant,
) -> Result<(serde_json::Value, String), String> {
    let ranks = rank_size(transport).1;
    let seconds = start.elapsed().as_secs_f64();
    let mut summary = serde_json::Map::new();
    for (k, v) in fields {
        summary.insert(k.to_string(), v);
    }
    summary.insert("ranks".into(), ranks.into());
    summary.insert("threads".into(), threads.into());
    summary.insert("wall_seconds".into(), seconds.into());
    summary.insert("records".into(), records.into());
    let summary = serde_json::Value::Object(summary);
    crate::output::write_json(&dir.join("summary.json"), &summary)?;
    let how = format!(
        "{seconds:.2} s on {}{threads} thread{}",
        if ranks > 1 { format!("{ranks} ranks × ") } else { String::new() },
        if threads == 1 { "" } else { "s" }
    );
    Ok((summary, how))
}

#[cfg(test)]
mod tests {
    use super::*;
    use sparse_levelset::distributed::LocalRanks;

    #[test]
    fn records_come_back_in_item_order_on_rank_zero() {
        let items: Vec<u32> = (0..7).collect();
        for ranks in 1..=3 {
            let out = LocalRanks::run(ranks, |t| {
                let checked = agree(Some(&*t), Ok(items.clone())).unwrap();
                let r = spread(Some(&*t), &checked, 2, |&i, _| (i, t.rank())).unwrap();
                (t.rank(), r)
            });
            for (rank, r) in out {
                match r {
                    Some(r) => {
                        assert_eq!(rank, 0);
                        let want: Vec<(u32, usize)> =
                            (0..7).map(|i| (i, i as usize % ranks)).collect();
                        assert_eq!(r, want, "{ranks} ranks");
                    }
                    None => assert_ne!(rank, 0),
                }
            }
        }
        let alone = spread(None, &items, 3, |&i, threads| (i, threads)).unwrap();
        assert_eq!(alone, Some((0..7).map(|i| (i, 1)).collect()));
        // Fewer items than threads: one after another, each with every thread.
        assert_eq!(spread(None, &[5], 3, |&i, threads| (i, threads)).unwrap(), Some(vec![(5, 3)]));
    }

    #[test]
    fn a_failed_check_or_another_list_on_one_rank_fails_every_rank() {
        let out = LocalRanks::run(3, |t| {
            let mine = if t.rank() == 2 { Err("no such directory".to_string()) } else { Ok(1) };
            agree(Some(&*t), mine)
        });
        for r in &out {
            let e = r.as_ref().unwrap_err();
            assert!(e.contains("no such directory"), "{e}");
        }
        let out = LocalRanks::run(2, |t| agree(Some(&*t), Ok(vec![t.rank()])));
        for r in &out {
            assert!(r.as_ref().unwrap_err().contains("other inputs"), "{r:?}");
        }
    }
}
