//! `Controller::torque` on three and six joints with the fitted label (one polynomial, or cells
//! where one polynomial misses: `ur5_six`) and with the exact log map
//! (issue 47: ≤ 20 µs per call). `cargo bench --bench controller`; figures in BENCHMARKS.md.
//!
//! Each design's controller follows a direction target (the first axis of the metric frame) with
//! energy regulation and damping compensation on, believing the exact potential ½ω²r² (a fitted
//! bill of the six-joint arm takes minutes; the exact potential asks the label field once more
//! per call, for the energy, at the same point, which the fitted label answers from its last
//! value). The calls go through points of a held-out fan inside the region, each once per
//! repeat, so no call reuses its predecessor's point.

mod common;

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use nalgebra::DVector;
use springfit::design::Design;
use springfit::design::controllers::EnergyLaw;
use springfit::design::simulate::LabelKind;
use springfit::dynamics::control::{Controller, ElasticPotential, EnergyControl, ModeControl, ModeTarget};
use springfit::dynamics::scenario::{LabelSource, label_source};
use springfit::geodesic::{Fan, FanSpec, Stop};

use common::{ms, time};

fn main() {
    println!("Controller::torque benchmarks (median / min per call over repeats)");
    for name in ["ur5_pan_lift_elbow", "panda_three", "ur5_six"] {
        let d = Design::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("designs/{name}.toml"))).unwrap();
        let n = d.dof();
        let region = d.valid_region().unwrap();
        let stop = Stop::Region { region: &d.region, max_arc: d.geodesics.max_arc };
        let fan = Fan::trace(
            &d.chain,
            &d.q_eq,
            FanSpec { count: 40, phase: 0.25, stop, spacing: region.extent / 8.0 },
            d.geodesics.ode,
        )
        .unwrap();
        let points: Vec<(Vec<f64>, Vec<f64>)> = fan
            .geodesics
            .iter()
            .flat_map(|g| {
                (0..g.len())
                    .filter(move |&i| g.s(i) > 0.3 * region.extent)
                    .map(move |i| (g.q(i).to_vec(), g.qd(i).iter().map(|v| 0.5 * v).collect()))
            })
            .collect();
        let potential = ElasticPotential::Exact { omega: d.fit.frequency };
        for kind in [LabelKind::Table, LabelKind::Exact] {
            let settings = springfit::design::simulate::SimSettings { label: kind, ..d.simulate };
            let start = Instant::now();
            let (label, err) = label_source(&d, &settings).unwrap();
            let build = start.elapsed();
            let scheme = match &label {
                LabelSource::Fit(f) => match f.cells() {
                    Some(t) => format!(
                        "fitted by {} cells of degree {}{} ({:.1} MB)",
                        t.cells(),
                        t.degree(),
                        f.inner_radius()
                            .map_or(String::new(), |r| format!(", one polynomial inside {r} of the ball's radius")),
                        f.bytes() as f64 / 1e6
                    ),
                    None => format!("fitted, one polynomial of degree {}", f.degree()),
                },
                _ => "table".to_string(),
            };
            let mut c =
                Controller::new(&d.chain, &d.q_eq, &potential, d.controllers.clone(), Some(label.field())).unwrap();
            let mut u = DVector::zeros(n);
            u[0] = 1.0;
            c.set_mode(Some(ModeControl { schedule: vec![(0.0, ModeTarget::Direction(u))] }));
            c.set_energy(Some(EnergyControl {
                law: EnergyLaw::Energy,
                schedule: vec![(0.0, 0.5)],
                compensate_damping: true,
            }));
            c.set_damping(vec![0.1; n]);
            let calls = if kind == LabelKind::Exact { points.len().min(100) } else { points.len() };
            let (med, min) = time(if kind == LabelKind::Exact { 3 } else { 15 }, || {
                for (k, (q, qd)) in points.iter().take(calls).enumerate() {
                    black_box(c.torque(k as f64 * 1e-3, q, qd).unwrap());
                }
            });
            let per = |t: std::time::Duration| t.as_secs_f64() * 1e6 / calls as f64;
            match err {
                Some((e, count)) => println!(
                    "{name} ({n} joints), label {scheme} (built in {:.0} ms, largest label error {e:.2e}° on {count} held-out samples): {:.1} µs / {:.1} µs per call over {calls} points",
                    ms(build),
                    per(med),
                    per(min)
                ),
                None => println!(
                    "{name} ({n} joints), exact label (Newton shooting): {:.1} µs / {:.1} µs per call over {calls} points",
                    per(med),
                    per(min)
                ),
            }
        }
    }
}
