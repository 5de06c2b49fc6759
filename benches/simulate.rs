//! Benchmarks of the closed-loop simulation. `cargo bench --bench simulate`; figures in
//! BENCHMARKS.md.

mod common;

use std::hint::black_box;
use std::path::Path;

use springfit::design::Design;
use springfit::dynamics::scenario::{label_source, run_scenario};
use springfit::dynamics::simulate::ElasticPotential;
use springfit::elements::catalog::Catalog;
use springfit::fit::run::fit;

use common::{ms, time};

fn main() {
    let d = Design::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/double_pendulum.toml")).unwrap();
    let catalog = Catalog::load(d.catalog.as_ref().unwrap(), d.dof()).unwrap();
    let pot =
        ElasticPotential::Springs(fit(&d, &catalog, &d.fit, springfit::progress::Progress::none()).unwrap().springs);
    println!("springfit simulation benchmarks (median / min over repeats)");
    let mut err = None;
    let (med, min) = time(3, || {
        let (_, e) = black_box(label_source(&d, &d.simulate).unwrap());
        err = e;
    });
    println!(
        "label table {}×{} nodes: {:.0} ms / {:.0} ms; largest label error {:.2e}° on {} held-out samples",
        d.simulate.table_nodes,
        d.simulate.table_nodes,
        ms(med),
        ms(min),
        err.unwrap().0,
        err.unwrap().1
    );
    let (label, _) = label_source(&d, &d.simulate).unwrap();
    let switch = d.scenarios.iter().position(|s| s.name == "switch").unwrap();
    let (med, min) = time(5, || {
        black_box(run_scenario(&d, &pot, &label, &d.simulate, &d.controllers, switch).unwrap());
    });
    println!(
        "switch scenario: 100 s at 1 kHz, RK4, springs + mode controller with the tabulated label: {:.0} ms / {:.0} ms",
        ms(med),
        ms(min)
    );
    let sens = d.scenarios.iter().position(|s| s.name == "sensitivity").unwrap();
    let (med, min) = time(10, || {
        black_box(run_scenario(&d, &pot, &label, &d.simulate, &d.controllers, sens).unwrap());
    });
    println!("sensitivity run (20 s at 1 kHz, both controllers): {:.1} ms / {:.1} ms", ms(med), ms(min));
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let swing = d.scenarios.iter().position(|s| s.name == "swingup").unwrap();
        let (med, min) = time(5, || {
            pool.install(|| black_box(run_scenario(&d, &pot, &label, &d.simulate, &d.controllers, swing).unwrap()));
        });
        println!(
            "swing-up scenario (3 variants × 20 s at 1 kHz), {threads} thread(s): {:.0} ms / {:.0} ms",
            ms(med),
            ms(min)
        );
    }
}
