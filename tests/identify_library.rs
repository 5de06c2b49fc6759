//! Identification on the paper's arm with the default design's bill (`tests/data/
//! double_pendulum_bom.csv`: its twelve springs and three trims as `springfit fit` wrote them):
//! swings simulated by `identify::swing` with known rate errors, damping and friction, read
//! through a 17-bit encoder, identified, and tuned. (`tests/identify_mujoco.rs` does the same with
//! MuJoCo playing the arm, on a short log.)

use std::path::{Path, PathBuf};

use springfit::asbuilt;
use springfit::design::Design;
use springfit::fit::bill::BomRow;
use springfit::identify::log::{Log, Run};
use springfit::identify::swing::{Drive, encoder_reading, swing};
use springfit::identify::{Identification, Status, identify};
use springfit::numerics::rng::SplitMix64;
use springfit::potential::SpringSet;

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn setup() -> (Design, PathBuf, Vec<BomRow>) {
    let design = Design::load(&repo("designs/double_pendulum.toml")).unwrap();
    let path = repo("tests/data/double_pendulum_bom.csv");
    let bom = springfit::files::bom::read(&path).unwrap();
    (design, path, bom)
}

/// Rate factors 1 + δ, δ uniform in ±5 % for every row but the trims (set by the builder).
fn build(bom: &[BomRow], seed: u64) -> Vec<f64> {
    let mut rng = SplitMix64::stream(seed, 0);
    bom.iter()
        .map(|r| if r.adjust.trim_range.is_some() { 1.0 } else { 1.0 + 0.05 * (2.0 * rng.uniform() - 1.0) })
        .collect()
}

/// Releases from rest at metric distance `r` along `count` directions over half a turn.
fn releases(design: &Design, r: f64, count: usize) -> Vec<Vec<f64>> {
    let frame = springfit::geodesic::MetricFrame::new(&design.chain.mass_matrix(&design.q_eq)).unwrap();
    let mut shooter = springfit::geodesic::Shooter::new(&design.chain, &design.q_eq, design.geodesics.ode);
    (0..count)
        .map(|i| {
            let a = std::f64::consts::PI * (i as f64 + 0.25) / count as f64;
            let v = frame.to_joint(&nalgebra::DVector::from_vec(vec![a.cos(), a.sin()])) * r;
            shooter.exp(&v).unwrap().iter().copied().collect()
        })
        .collect()
}

/// The built arm's swings from `starts`, `seconds` each at 1 kHz, read by a 17-bit encoder
/// (`noise` counts rms) unless `noise` is None (exact angles).
fn log(
    design: &Design,
    built: &SpringSet,
    drive: &Drive,
    starts: &[Vec<f64>],
    seconds: f64,
    noise: Option<f64>,
) -> Log {
    let mut rng = SplitMix64::stream(99, 0);
    let runs: Vec<Run> = starts
        .iter()
        .enumerate()
        .map(|(i, q0)| {
            let run = swing(design, built, drive, q0, seconds, 1000.0).unwrap();
            let mut run = match noise {
                Some(n) => encoder_reading(&run, 17, n, &mut rng),
                None => run,
            };
            run.name = format!("release {}", i + 1);
            run
        })
        .collect();
    Log { path: PathBuf::from("simulated.csv"), dof: 2, runs }
}

fn truth_of<'a>(
    id: &'a Identification,
    factors: &'a [f64],
) -> impl Iterator<Item = (&'a springfit::identify::RateEstimate, f64)> {
    id.rates.iter().map(move |r| (r, factors[r.rows[0]] - 1.0))
}

/// Exact angles of a known build: what is left is the discretisation of the derivatives (fourth
/// order) and of the simulation, so every identified δ comes back within 10⁻⁴ of its rate and
/// within 3 of the standard errors that residual gives it (the nearly collinear S07–S09 have the
/// largest, a few 10⁻⁵), the damping to 2·10⁻⁵.
#[test]
fn exact_angles_give_back_the_build_exactly() {
    let (design, path, bom) = setup();
    let factors = build(&bom, 5);
    let built = springfit::fit::bill::spring_set(&bom).scaled(&factors);
    let drive = Drive { damping: &[0.05, 0.05], friction: &[0.0, 0.0], torque: None };
    let logs = [log(&design, &built, &drive, &releases(&design, 1.8, 3), 8.0, None)];
    let settings = springfit::design::identify::IdentifySettings { friction: false, ..design.identify.clone() };
    let id = identify(&design, &path, &bom, &logs, &settings).unwrap();
    let mut checked = 0;
    for (r, truth) in truth_of(&id, &factors) {
        if r.status == Status::Identified {
            let error = r.delta - truth;
            assert!(
                error.abs() < 1e-4 && error.abs() <= 3.0 * r.standard_error,
                "{}: δ {} ± {:.2e} against {truth}",
                r.id,
                r.delta,
                r.standard_error
            );
            checked += 1;
        }
    }
    assert!(checked >= 8, "{checked} identified");
    // What the logs fix of the others, exactly: every group combination within 10⁻⁴ of the
    // truth and 3 of its standard errors (weights orthogonal to Φ's exact null space).
    let truth = |part: &str| {
        let r = id.rates.iter().find(|r| r.id == part).unwrap();
        factors[r.rows[0]] - 1.0
    };
    for g in &id.groups {
        for c in &g.identified {
            let t: f64 = c.weights.iter().map(|(p, w)| w * truth(p)).sum();
            assert!((c.value - t).abs() < 1e-4 && (c.value - t).abs() <= 3.0 * c.standard_error, "{c:?}: truth {t}");
        }
    }
    for j in &id.joints {
        let d = j.damping.unwrap().value;
        assert!((d - 0.05).abs() < 2e-5, "{}: damping {d}", j.joint);
    }
}

/// A build with rate errors of ±5 %, damping 0.05 and friction 0.02, swung from the releases
/// the plan proposes and read by a 17-bit encoder: every identified δ within 0.5 % rms and 3
/// standard errors, damping within 10 %, friction within 3 standard errors; tuned from the
/// identified rates the true arm rests within 4e-3 rad of q_eq with a p99 within 10 % of tuning
/// from the true rates.
#[test]
fn a_build_is_identified_from_the_planned_releases_and_tuned() {
    let (mut design, path, bom) = setup();
    design.identify.expected_damping = 0.05;
    design.identify.expected_friction = 0.02;
    let plan = springfit::identify::plan::plan(&design, &path, &bom).unwrap();
    // The region holds no release that tells every rate apart (the trims among them): the plan
    // says so, and identify reports them as a group (checked below by skipping what is not
    // identified).
    assert!(!plan.complete && plan.predicted.groups.len() == 1, "{:?}", plan.predicted.groups);
    // Six releases: the plan's, each as often as it says, its first ones again if fewer.
    let planned: Vec<Vec<f64>> =
        plan.releases.iter().flat_map(|r| std::iter::repeat_n(r.q0.clone(), r.releases)).collect();
    let starts: Vec<Vec<f64>> = (0..6).map(|i| planned[i % planned.len()].clone()).collect();
    let factors = build(&bom, 3);
    let built = springfit::fit::bill::spring_set(&bom).scaled(&factors);
    let drive = Drive { damping: &[0.05, 0.05], friction: &[0.02, 0.02], torque: None };
    let logs = [log(&design, &built, &drive, &starts, 10.0, Some(1.0))];
    let id = identify(&design, &path, &bom, &logs, &design.identify).unwrap();
    let mut square = 0.0;
    let mut count = 0;
    for (r, truth) in truth_of(&id, &factors) {
        if r.status != Status::Identified {
            continue;
        }
        let z = (r.delta - truth) / r.standard_error;
        assert!(z.abs() <= 3.0, "{}: δ {} ± {} against {truth}", r.id, r.delta, r.standard_error);
        square += (r.delta - truth).powi(2);
        count += 1;
    }
    let rms = (square / count as f64).sqrt();
    assert!(count >= 5 && rms < 0.005, "{count} identified, rms error {rms}");
    for j in &id.joints {
        let d = j.damping.unwrap();
        assert!((d.value / 0.05 - 1.0).abs() < 0.1, "{}: damping {d:?}", j.joint);
        // Friction is the weakest column (a sign, felt only through L): within 3 of its
        // standard errors rather than a fixed share.
        let f = j.friction.unwrap();
        assert!((f.value - 0.02).abs() <= 3.0 * f.standard_error, "{}: friction {f:?}", j.joint);
    }
    // Tuned from the identified rates, and the true arm with those settings.
    let tuned = springfit::asbuilt::tune::tune(&design, &bom, &id.measured).unwrap();
    let true_rates: Vec<Option<f64>> = bom.iter().zip(&factors).map(|(r, f)| Some(r.stiffness * f)).collect();
    let ideal = springfit::asbuilt::tune::tune(&design, &bom, &true_rates).unwrap();
    let mut arm = springfit::fit::bill::spring_set(&tuned.bom);
    for (j, r) in bom.iter().enumerate() {
        if r.adjust.trim_range.is_none() {
            arm.stiffness[j] = r.stiffness * factors[j];
        }
    }
    let extent = design.valid_region().unwrap().extent;
    let (p99, shift) =
        asbuilt::residual_about_own_equilibrium(&design, extent, asbuilt::DIRECTIONS, asbuilt::SAMPLES, &arm).unwrap();
    // With every spring an unknown, five or six parts come out on their own from six releases
    // and the rest through their group's combinations: this build's true arm, tuned from them,
    // rests 2.6e-3 rad from q_eq (the MuJoCo build of docs/identify.md: 8.5e-4), short of the
    // issue's 1e-3; the bound here is what the releases alone give, not the goal.
    println!("shift {shift:.2e} rad, p99 {p99:.4}° against {:.4}° from the true rates", ideal.after.p99_deg);
    assert!(shift <= 4e-3, "shift {shift}");
    assert!((p99 / ideal.after.p99_deg - 1.0).abs() <= 0.1, "p99 {p99} vs {}", ideal.after.p99_deg);
}

/// A small swing never engages the compression springs far from q_eq: identify says which and
/// why, and leaves them as designed in the measured rates.
#[test]
fn a_log_that_cannot_identify_an_element_says_which_and_why() {
    let (design, path, bom) = setup();
    let built = springfit::fit::bill::spring_set(&bom);
    let drive = Drive { damping: &[0.0, 0.0], friction: &[0.0, 0.0], torque: None };
    let logs = [log(&design, &built, &drive, &releases(&design, 0.3, 1), 6.0, Some(1.0))];
    let id = identify(&design, &path, &bom, &logs, &design.identify).unwrap();
    let s12 = id.rates.iter().find(|r| r.id == "S12").unwrap();
    let Status::Group(g) = s12.status else { panic!("S12 cannot be identified from a small swing: {s12:?}") };
    assert!(id.groups[g].reason.contains("never engage"), "{}", id.groups[g].reason);
    assert_eq!(s12.torque_rms_nm, 0.0);
    assert!(id.measured[s12.rows[0]].is_none(), "an element never engaged keeps its design rate");
    // Elements that act alike over the swing are grouped, with the combinations the log fixes.
    assert!(id.groups.iter().any(|g| g.members.len() > 1 && !g.identified.is_empty()), "{:?}", id.groups);
    assert!(id.identified_count() < id.rates.len());
}
