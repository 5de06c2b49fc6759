//! Benchmark of `identify`: the default design's bill identified from 60 s of simulated swings
//! at 1 kHz read by a 17-bit encoder (five releases of 12 s). `cargo bench --bench identify`;
//! figures in BENCHMARKS.md.

mod common;

use std::hint::black_box;
use std::path::{Path, PathBuf};

use springfit::design::Design;
use springfit::identify::identify;
use springfit::identify::log::{Log, Run};
use springfit::identify::swing::{Drive, encoder_reading, swing};
use springfit::numerics::rng::SplitMix64;

use common::{ms, time};

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let design = Design::load(&root.join("designs/double_pendulum.toml")).unwrap();
    let bom_path = root.join("tests/data/double_pendulum_bom.csv");
    let bom = springfit::files::bom::read(&bom_path).unwrap();
    let plan = springfit::identify::plan::plan(&design, &bom_path, &bom).unwrap();
    let mut rng = SplitMix64::stream(3, 0);
    let factors: Vec<f64> = bom
        .iter()
        .map(|r| if r.adjust.trim_range.is_some() { 1.0 } else { 1.0 + 0.05 * (2.0 * rng.uniform() - 1.0) })
        .collect();
    let built = springfit::fit::bill::spring_set(&bom).scaled(&factors);
    let drive = Drive { damping: &[0.05, 0.05], friction: &[0.02, 0.02], torque: None };
    let runs: Vec<Run> = (0..5)
        .map(|i| {
            let q0 = &plan.releases[i % plan.releases.len()].q0;
            let mut run =
                encoder_reading(&swing(&design, &built, &drive, q0, 12.0, 1000.0).unwrap(), 17, 1.0, &mut rng);
            run.name = format!("release {}", i + 1);
            run
        })
        .collect();
    let logs = [Log { path: PathBuf::from("swings.csv"), dof: 2, runs }];
    println!("springfit identify benchmark (median / min over repeats)");
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let (mut identified, mut parts) = (0, 0);
        let (med, min) = time(5, || {
            let id = pool.install(|| identify(&design, &bom_path, &bom, &logs, &design.identify).unwrap());
            (identified, parts) = (id.identified_count(), id.rates.len());
            black_box(id);
        });
        println!(
            "identify, default design, 60 s at 1 kHz (5 releases × 12 s), {threads} thread(s): {:.0} ms / {:.0} ms; \
             {identified} of {parts} parts identified",
            ms(med),
            ms(min)
        );
    }
}
