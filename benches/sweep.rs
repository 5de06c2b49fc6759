//! Benchmark of `springfit sweep` end to end. `cargo bench --bench sweep`; figures in
//! BENCHMARKS.md.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

fn run(threads: usize, builds: usize, out: &Path) -> Duration {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let start = Instant::now();
    let status = Command::new(env!("CARGO_BIN_EXE_springfit"))
        .args(["--quiet", "--threads", &threads.to_string(), "sweep", "--builds", &builds.to_string(), "--out"])
        .arg(out)
        .current_dir(root)
        .status()
        .unwrap();
    assert!(status.success());
    start.elapsed()
}

fn main() {
    let out = std::env::temp_dir().join(format!("springfit-bench-sweep-{}", std::process::id()));
    println!("springfit sweep benchmarks (default design; each run includes the fit and the label table)");
    for (builds, what) in [
        (100, "6 ε + 2 levels × 100 builds (the first 72 of each also tuned) = 206 items"),
        (200, "6 ε + 2 levels × 200 builds (the first 72 of each also tuned) = 406 items (the design's default)"),
    ] {
        let mut t = Vec::new();
        for threads in [1, 2] {
            let best = (0..2).map(|_| run(threads, builds, &out)).min().unwrap();
            println!("{what}, {threads} thread(s): {:.2} s (best of 2)", best.as_secs_f64());
            t.push(best);
        }
        println!("  speed-up 2 threads vs 1: {:.2}x", t[0].as_secs_f64() / t[1].as_secs_f64());
    }
    let _ = std::fs::remove_dir_all(&out);
}
