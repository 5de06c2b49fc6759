//! Benchmarks of the foundation: the geodesic fan, the log map, the region check.
//!
//! `cargo bench --bench foundation`. A plain timing harness (no extra dependencies): each case
//! is warmed up, then timed over repeated runs; the median and the minimum are printed. Figures
//! are recorded in BENCHMARKS.md.

use std::f64::consts::PI;
mod common;

use std::hint::black_box;
use std::time::Duration;

use nalgebra::DVector;
use springfit::geodesic::label::{LogTable, LogValue};
use springfit::geodesic::logmap::LogSettings;
use springfit::geodesic::region::check_region;
use springfit::geodesic::{Fan, FanSpec, GeodesicSettings, LogMap, Region, Stop};
use springfit::model::Chain;
use springfit::numerics::ode::OdeSettings;

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

use common::{ms, time};

fn main() {
    let chain = Chain::paper_double_pendulum();
    let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
    let ode = OdeSettings::default();
    println!("springfit foundation benchmarks (median / min over repeats)");
    println!("ode tolerances rtol = atol = {:e}", ode.rtol);

    // Fan of 360 geodesics to s = 3, samples every 0.03.
    let spec = FanSpec { count: 360, phase: 0.0, stop: Stop::Arc(3.0), spacing: 0.03 };
    let mut fan_times = Vec::new();
    for threads in [1, 2] {
        let p = pool(threads);
        let (med, min) = time(20, || {
            p.install(|| black_box(Fan::trace(&chain, &q_eq, spec, ode).unwrap()));
        });
        println!("fan 360 geodesics to s = 3, {threads} thread(s): {:.2} ms / {:.2} ms", ms(med), ms(min));
        fan_times.push(med);
    }
    println!("fan speed-up 2 threads vs 1: {:.2}x", fan_times[0].as_secs_f64() / fan_times[1].as_secs_f64());

    // Log map: cold starts (second-order guess) over the ball of radius 2, and warm starts along
    // a sweep (each point starts from its neighbour's solution, as when tabulating a grid).
    let log = LogMap::new(&chain, &q_eq, ode, LogSettings::default());
    let fan =
        Fan::trace(&chain, &q_eq, FanSpec { count: 50, phase: 0.37, stop: Stop::Arc(2.0), spacing: 0.1 }, ode).unwrap();
    let points: Vec<DVector<f64>> = fan
        .geodesics
        .iter()
        .flat_map(|g| (0..g.len()).map(|i| DVector::from_column_slice(g.q(i))).collect::<Vec<_>>())
        .collect();
    let mut shooter = log.shooter();
    let (med, min) = time(5, || {
        for q in &points {
            black_box(log.solve(&mut shooter, q, None).unwrap());
        }
    });
    let per = |d: Duration| d.as_secs_f64() * 1e6 / points.len() as f64;
    println!(
        "log map, cold start, {} points in the ball r ≤ 2: {:.1} µs / {:.1} µs per point",
        points.len(),
        per(med),
        per(min)
    );
    let (med, min) = time(5, || {
        for g in &fan.geodesics {
            let mut guess: Option<DVector<f64>> = None;
            for i in 0..g.len() {
                let q = DVector::from_column_slice(g.q(i));
                let p = log.solve(&mut shooter, &q, guess.as_ref()).unwrap();
                // Warm start for the next point from this one: v + (d exp)⁻¹ Δq.
                if i + 1 < g.len() {
                    let dq = DVector::from_column_slice(g.q(i + 1)) - &q;
                    guess = p.jacobian.clone().lu().solve(&dq).map(|dv| &p.v + dv);
                }
                black_box(p);
            }
        }
    });
    println!("log map, warm start along sweeps: {:.1} µs / {:.1} µs per point", per(med), per(min));

    // Log map with Newton started from a tabulated guess (the table built once, as the
    // simulation builds it).
    let region_fan =
        Fan::trace(&chain, &q_eq, FanSpec { count: 72, phase: 0.0, stop: Stop::Arc(2.0), spacing: 0.05 }, ode).unwrap();
    let t0 = std::time::Instant::now();
    let mut table = LogTable::build(&chain, &q_eq, &region_fan, ode, 121, 121, 0.25).unwrap();
    let built = t0.elapsed();
    let mut out = LogValue::zeros(2);
    let (med, min) = time(5, || {
        for q in &points {
            table.exact(q.as_slice(), &mut out).unwrap();
            black_box(&out);
        }
    });
    println!(
        "log map, Newton from the tabulated guess: {:.1} µs / {:.1} µs per point (table of 121×121 nodes built once in {:.0} ms)",
        per(med),
        per(min),
        ms(built)
    );

    // Region check of the paper design.
    let settings = GeodesicSettings::default();
    let (med, min) = time(5, || {
        black_box(check_region(&chain, &q_eq, &Region::Ball { radius: 2.0 }, &settings).unwrap());
    });
    println!(
        "region check, paper design, {} directions: {:.1} ms / {:.1} ms",
        settings.check_directions,
        ms(med),
        ms(min)
    );
}
