//! Benchmarks of the fit: the library call per design and `springfit fit` end to end.
//!
//! `cargo bench --bench fit`. Figures are recorded in BENCHMARKS.md.

mod common;

use std::hint::black_box;
use std::path::Path;
use std::process::Command;

use springfit::catalog::Catalog;
use springfit::design::Design;
use springfit::fit::run::fit;

use common::{ms, time};

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    println!("springfit fit benchmarks (median / min over repeats)");
    for name in ["double_pendulum", "double_pendulum_dense", "double_pendulum_workshop", "double_pendulum_paper_window"]
    {
        let design = Design::load(&root.join(format!("designs/{name}.toml"))).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let mut last = None;
        let (med, min) = time(5, || {
            last = Some(black_box(fit(&design, &catalog, &design.fit, &|_| {}).unwrap()));
        });
        let o = last.unwrap();
        let t = o.timings;
        println!(
            "fit {name}: {:.0} ms / {:.0} ms (geodesics {:.0}, assemble {:.0}, solve {:.0}, evaluate {:.0} ms); {} springs, p99 {:.4}°, max {:.4}°",
            ms(med),
            ms(min),
            t.geodesics * 1e3,
            t.assemble * 1e3,
            t.solve * 1e3,
            t.evaluate * 1e3,
            o.used(),
            o.metrics.stats.p99_abs,
            o.metrics.stats.max_abs
        );
    }
    // The main job as a user runs it: process start, fit, plots and files.
    let out = std::env::temp_dir().join(format!("springfit-bench-{}", std::process::id()));
    let (med, min) = time(5, || {
        let status = Command::new(env!("CARGO_BIN_EXE_springfit"))
            .args(["--quiet", "fit", "--out"])
            .arg(&out)
            .current_dir(root)
            .status()
            .unwrap();
        assert!(status.success());
    });
    println!("springfit fit (default design, end to end with outputs): {:.0} ms / {:.0} ms", ms(med), ms(min));
    // The same with the as-built figures: the default design at ±5 % (200 builds, trimmed too).
    let text = std::fs::read_to_string(root.join("designs/double_pendulum.toml")).unwrap();
    let catalog = root.join("catalogs/paper.toml");
    let text = text
        .replace("\"../catalogs/paper.toml\"", &format!("{:?}", catalog.display().to_string()))
        .replace("\n[fit]\n", "\n[fit]\ntolerance = 0.05\nbuilds = 200\n");
    // (A design that already states its tolerance keeps its own.)
    let text =
        if text.matches("\ntolerance = ").count() > 1 { text.replacen("tolerance = 0.05\n", "", 1) } else { text };
    let design_file = std::env::temp_dir().join(format!("springfit-bench-{}.toml", std::process::id()));
    std::fs::write(&design_file, text).unwrap();
    let (med, min) = time(5, || {
        let status = Command::new(env!("CARGO_BIN_EXE_springfit"))
            .args(["--quiet", "fit"])
            .arg(&design_file)
            .arg("--out")
            .arg(&out)
            .status()
            .unwrap();
        assert!(status.success());
    });
    println!(
        "springfit fit (default design at ±5 %, 200 as-built builds, end to end): {:.0} ms / {:.0} ms",
        ms(med),
        ms(min)
    );
    let _ = std::fs::remove_file(&design_file);
    let _ = std::fs::remove_dir_all(&out);
}
