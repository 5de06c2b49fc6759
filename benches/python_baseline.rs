//! The Rust side of the Python package's benchmarks (`python/benches/bench.py`): the per-point
//! costs its vectorised calls are held against, on the same points of the default design.
//!
//! `cargo bench --bench python_baseline`; figures in BENCHMARKS.md.
//!
//! * the log map, one `LogMap::log` per point (what `Design.log` runs for each row), on the
//!   10 000 points of the benchmark: φₖ = k·π(3 − √5), sₖ = 1.9·√((k + ½)/N), qₖ = exp(sₖ uₖ) with
//!   uₖ the metric unit vector of direction φₖ — one thread;
//! * `Controller::torque` per call on the switch scenario's controller (what
//!   `springfit.Controller.torque` runs), at states along the start of that run.

mod common;

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use nalgebra::DVector;
use springfit::design::Design;
use springfit::dynamics::control::{Controller, ElasticPotential};
use springfit::dynamics::scenario::{label_source, resolve_scenario};
use springfit::elements::catalog::Catalog;
use springfit::fit::run::fit;
use springfit::geodesic::Shooter;
use springfit::geodesic::logmap::{LogMap, LogSettings};

use common::time;

/// The benchmark's points (see the module docs).
fn points(d: &Design, count: usize) -> Vec<DVector<f64>> {
    let m = d.chain.mass_matrix(&d.q_eq);
    let mut shooter = Shooter::new(&d.chain, &d.q_eq, d.geodesics.ode);
    (0..count)
        .map(|k| {
            let phi = k as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let s = 1.9 * ((k as f64 + 0.5) / count as f64).sqrt();
            let u = DVector::from_vec(vec![phi.cos(), phi.sin()]);
            let u = &u / u.dot(&(&m * &u)).sqrt();
            shooter.exp(&(u * s)).unwrap()
        })
        .collect()
}

fn main() {
    let d = Design::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/double_pendulum.toml")).unwrap();
    println!("springfit: the Rust baselines of the Python benchmarks (median / min over repeats)");
    let q = points(&d, 10_000);
    let log = LogMap::new(&d.chain, &d.q_eq, d.geodesics.ode, LogSettings::default());
    let (med, min) = time(3, || {
        for p in &q {
            black_box(log.log(p).unwrap());
        }
    });
    let per = |t: std::time::Duration| t.as_secs_f64() * 1e6 / q.len() as f64;
    println!(
        "log map, LogMap::log per point, 10 000 points, 1 thread: {:.2} µs / {:.2} µs per point",
        per(med),
        per(min)
    );

    let catalog = Catalog::load(d.catalog.as_ref().unwrap(), d.dof()).unwrap();
    let pot =
        ElasticPotential::Springs(fit(&d, &catalog, &d.fit, springfit::progress::Progress::none()).unwrap().springs);
    let (label, _) = label_source(&d, &d.simulate).unwrap();
    let switch = d.scenarios.iter().position(|s| s.name == "switch").unwrap();
    let run = resolve_scenario(&d, &pot, &label, switch).unwrap().runs.remove(0);
    let mut c = Controller::new(&d.chain, &d.q_eq, &pot, d.controllers.clone(), Some(label.field())).unwrap();
    c.set_mode(run.mode.clone());
    c.set_energy(run.energy.clone());
    c.set_damping(run.damping.clone());
    let calls = 100_000;
    let states: Vec<(Vec<f64>, Vec<f64>)> = (0..1000)
        .map(|k| {
            let a = k as f64 * 0.01;
            (vec![run.q0[0] * a.cos(), run.q0[1] + 0.3 * a.sin()], vec![0.5 * a.sin(), -0.4 * a.cos()])
        })
        .collect();
    let mut best = f64::INFINITY;
    let mut all = Vec::new();
    for _ in 0..5 {
        let t0 = Instant::now();
        for k in 0..calls {
            let (q, qd) = &states[k % states.len()];
            black_box(c.torque(k as f64 * 1e-3, q, qd).unwrap());
        }
        let us = t0.elapsed().as_secs_f64() * 1e6 / calls as f64;
        best = best.min(us);
        all.push(us);
    }
    all.sort_by(f64::total_cmp);
    println!(
        "Controller::torque (switch scenario, tabulated label), {calls} calls: {:.2} µs / {:.2} µs per call",
        all[2], best
    );
}
