//! Issue 45's acceptance on the shipped default and triple-pendulum designs: every spring's rate
//! from its own geometry (a torsion spring's legs included, EN 13906-3) within 1.5 % of what its
//! element needs (`realise::accuracy`), no static-grade wire for 10⁴ swings or more, and every
//! part that passes within its fatigue checks; the masses printed for the closing note.
//!
//! Each design is fitted as shipped (minutes under load): run with
//! `cargo test --release --locked --test standards_rates -- --ignored --nocapture`.

mod util;

use springfit::jobs::fit::{FitJob, FitRequest};
use springfit::realise::accuracy::{RATE_ACCURACY, rate_error};

/// Fits `name` as shipped and checks its parts; prints one line per part and the totals.
fn check(name: &str) {
    let (design, catalog) = util::shipped(name);
    let job = FitJob::new(&design, Some(&catalog), FitRequest::default()).expect("the shipped design's settings");
    let run = job.run(springfit::progress::Progress::none()).expect("the shipped design fits");
    let parts = run.parts.expect("a fit of springs has parts");
    let (mut mass, mut worst, mut listed) = (0.0, 0.0f64, Vec::new());
    println!("{name}: wire {} ({})", design.parts.material_key(), design.parts.material_choice());
    for e in &parts.elements {
        let Ok(p) = &e.part else {
            println!("{name} {}: no part", e.id);
            continue;
        };
        mass += p.mass;
        let err = rate_error(p, e.stiffness, e.duty.at_eq);
        let from = e.stock.as_ref().map_or("wound".to_string(), |s| format!("stock {}", s.part_number));
        println!(
            "{name} {} {:?} {} {}: rate from geometry {}, worst check {:.3}, {:.4} kg",
            e.id,
            p.mechanism,
            p.spring.material(),
            from,
            err.map_or("n/a (set on the arm or a cam)".to_string(), |x| format!("{:+.4} %", 100.0 * x)),
            p.worst(),
            p.mass
        );
        // A static grade is never chosen for many swings (a listed spring carries its own wire).
        if design.parts.cycles >= springfit::design::parts::DYNAMIC_FROM_CYCLES && e.stock.is_none() {
            assert_ne!(
                p.spring.material(),
                "EN10270-1-SM",
                "{name} {}: static grade at {} swings",
                e.id,
                design.parts.cycles
            );
        }
        // Every fatigue check of a part that passes is within its limit (Zimmerli-Goodman for
        // the body and loops of helical springs, Goodman on Table 10-10 for torsion springs).
        if p.worst() <= 1.0 {
            for c in p.checks.iter().filter(|c| c.name.starts_with("fatigue") || c.name.starts_with("hook fatigue")) {
                assert!(c.ratio() <= 1.0, "{name} {}: {} at {}", e.id, c.name, c.ratio());
            }
        }
        if let Some(x) = err {
            worst = worst.max(x.abs());
            // A listed spring counts too: its rate from its own geometry (music wire's moduli by
            // size, Shigley's Table 10-5, as the list computed them) realises its element.
            if let Some(s) = &e.stock {
                listed.push(format!("{} ({}, {:+.3} %)", e.id, s.part_number, 100.0 * x));
            }
            assert!(x.abs() <= RATE_ACCURACY, "{name} {} ({from}): rate off by {:.3} %", e.id, 100.0 * x);
        }
    }
    println!(
        "{name}: {} parts, springs {mass:.3} kg; largest rate error from geometry {:.4} % (limit {} %); listed parts: {}",
        parts.elements.iter().filter(|e| e.part.is_ok()).count(),
        100.0 * worst,
        100.0 * RATE_ACCURACY,
        if listed.is_empty() { "none".to_string() } else { listed.join(", ") }
    );
}

#[test]
#[ignore = "fits two shipped designs (minutes): run with --ignored"]
fn the_default_design_meets_the_standards() {
    check("double_pendulum");
}

#[test]
#[ignore = "fits two shipped designs (minutes): run with --ignored"]
fn the_triple_pendulum_meets_the_standards() {
    check("triple_pendulum");
}
