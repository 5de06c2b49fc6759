//! The timing harness shared by the benchmarks (plain std, no extra dependencies).

#![allow(dead_code)]

use std::time::{Duration, Instant};

/// Times `f` `reps` times after one warm-up run; returns (median, min).
pub fn time<F: FnMut()>(reps: usize, mut f: F) -> (Duration, Duration) {
    f();
    let mut t: Vec<Duration> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed()
        })
        .collect();
    t.sort();
    (t[t.len() / 2], t[0])
}

/// Milliseconds.
pub fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}
