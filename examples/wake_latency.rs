//! What a second thread can gain on this machine for work split into short parallel
//! regions, whatever the library does: how long a sleeping thread takes to wake, and what a
//! two-thread region gains over one thread when its helper has to be woken first.
//!
//! ```sh
//! cargo run --release --example wake_latency
//! ```
//!
//! Part 1 wakes a thread blocked on a condition variable after it has slept for a while and
//! times the notification until that thread has run (percentiles of 400 wakes). Part 2 runs
//! a region of fixed work (two halves of about 0.5 ms, and of 10 ms) split in two by `rayon::join` in a pool of one and of two threads,
//! straight after another region (the helper still spinning) and after a serial gap of
//! 2 ms on the calling thread (by then rayon's idle worker is asleep and must be woken), and
//! prints the medians and the ratio one thread ÷ two threads. A ratio near 2 in both rows
//! means short regions scale on this machine; a much lower one after the gap means every
//! region that follows a serial stretch pays the wake-up.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// Busy work on the calling thread for about `d` (a spin on the clock, as serial code).
fn spin_for(d: Duration) {
    let t = Instant::now();
    while t.elapsed() < d {
        std::hint::spin_loop();
    }
}

/// A fixed amount of floating-point work (a dependent chain: no memory traffic).
fn work(n: u32) -> f64 {
    let mut x = 1.0f64;
    for _ in 0..n {
        x = std::hint::black_box(x * 1.000_000_1 + 1e-9);
    }
    x
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    percentile(&v, 0.5)
}

/// Part 1: microseconds from a notification to the woken thread running, `n` times, each
/// after the thread has waited `gap`.
fn wake_latencies(n: usize, gap: Duration) -> Vec<f64> {
    let state = Arc::new((Mutex::new(false), Condvar::new()));
    let ran = Arc::new(AtomicBool::new(false));
    let stop = Arc::new(AtomicBool::new(false));
    let waiter = {
        let (state, ran, stop) = (state.clone(), ran.clone(), stop.clone());
        std::thread::spawn(move || {
            let (lock, cv) = &*state;
            loop {
                let mut go = lock.lock().expect("the lock");
                while !*go {
                    go = cv.wait(go).expect("the lock");
                }
                *go = false;
                drop(go);
                if stop.load(Ordering::Acquire) {
                    return;
                }
                ran.store(true, Ordering::Release);
            }
        })
    };
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        spin_for(gap);
        ran.store(false, Ordering::Release);
        let t = Instant::now();
        *state.0.lock().expect("the lock") = true;
        state.1.notify_one();
        while !ran.load(Ordering::Acquire) {
            std::hint::spin_loop();
        }
        out.push(t.elapsed().as_secs_f64() * 1e6);
    }
    stop.store(true, Ordering::Release);
    *state.0.lock().expect("the lock") = true;
    state.1.notify_one();
    waiter.join().expect("the waiting thread");
    out.sort_by(f64::total_cmp);
    out
}

/// Part 2: milliseconds of a region of two halves of `n` iterations each (`rayon::join`)
/// in a pool of `threads`, `reps` times, each after a serial `gap`.
fn region_ms(threads: usize, gap: Duration, n: u32, reps: usize) -> Vec<f64> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a pool");
    pool.install(|| {
        (0..reps)
            .map(|_| {
                spin_for(gap);
                let t = Instant::now();
                let (a, b) = rayon::join(|| work(n), || work(n));
                std::hint::black_box(a + b);
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect()
    })
}

fn main() {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("{cpus} CPUs available");
    for gap_ms in [0.2, 2.0] {
        let l = wake_latencies(400, Duration::from_secs_f64(gap_ms * 1e-3));
        println!(
            "wake-up after {gap_ms} ms asleep, µs: min {:.1}, median {:.1}, 90th percentile {:.1}, \
             99th {:.1}, max {:.1}",
            l[0],
            percentile(&l, 0.5),
            percentile(&l, 0.9),
            percentile(&l, 0.99),
            l[l.len() - 1]
        );
    }
    // Halves of about 0.5 ms (calibrated here): a short region, as one pass over a 128³
    // image on one of two threads.
    let pilot = Instant::now();
    std::hint::black_box(work(100_000));
    let n = (100_000.0 * 0.5e-3 / pilot.elapsed().as_secs_f64()).clamp(1e3, 1e8) as u32;
    let rows = [
        ("0.5-ms halves, straight after another region", 0.0, 1, 200),
        ("0.5-ms halves, after a 2 ms serial gap", 2.0, 1, 200),
        ("10-ms halves, after a 2 ms serial gap", 2.0, 20, 20),
    ];
    for (label, gap, times, reps) in rows {
        let gap = Duration::from_secs_f64(gap * 1e-3);
        let one = median(region_ms(1, gap, n * times, reps));
        let two = median(region_ms(2, gap, n * times, reps));
        println!(
            "a region of two {label}: 1 thread {one:.3} ms, 2 threads {two:.3} ms (medians of \
             {reps}), 1 thread / 2 threads {:.2}",
            one / two
        );
    }
}
