//! Does the plan predict what its releases give? `identify --plan` told the arm's damping and
//! friction (`expected_damping`, `expected_friction`) predicts how many parts its releases
//! identify; a build of the arm (every spring ±5 %, the trims too) swung from those releases with
//! that damping and friction, read by a 17-bit encoder with other noise, identifies within ±2 of
//! that count: on the default design and on the three-joint UR5 arm (pan, lift, elbow; URDF,
//! gravity).

use std::path::{Path, PathBuf};

use springfit::design::Design;
use springfit::identify::identify;
use springfit::identify::log::{Log, Run};
use springfit::identify::swing::{Drive, encoder_reading, swing};
use springfit::numerics::rng::SplitMix64;

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// (predicted, found) identified parts of `design` with bill `bom`.
fn predicted_and_found(design: &str, bom: &str, damping: f64, friction: f64) -> (usize, usize, usize) {
    let mut design = Design::load(&repo(design)).unwrap();
    design.identify.expected_damping = damping;
    design.identify.expected_friction = friction;
    let path = repo(bom);
    let bom = springfit::files::bom::read(&path).unwrap();
    let plan = springfit::identify::plan::plan(&design, &path, &bom).unwrap();
    let predicted = plan.predicted.identified_count();
    let mut rng = SplitMix64::stream(17, 3);
    let factors: Vec<f64> = bom.iter().map(|_| 1.0 + 0.05 * (2.0 * rng.uniform() - 1.0)).collect();
    let built = springfit::fit::bill::spring_set(&bom).scaled(&factors);
    let n = design.dof();
    let (d, f) = (vec![damping; n], vec![friction; n]);
    let drive = Drive { damping: &d, friction: &f, torque: None };
    let mut runs: Vec<Run> = Vec::new();
    for r in &plan.releases {
        for _ in 0..r.releases {
            let run = swing(&design, &built, &drive, &r.q0, r.seconds, plan.rate_hz).unwrap();
            let mut run = encoder_reading(&run, plan.encoder_bits, plan.encoder_noise_counts, &mut rng);
            run.name = format!("release {}", runs.len() + 1);
            runs.push(run);
        }
    }
    let log = Log { path: PathBuf::from("simulated.csv"), dof: n, runs };
    let found = identify(&design, &path, &bom, &[log], &design.identify).unwrap().identified_count();
    (predicted, found, bom.len())
}

/// The plan's count and its releases' within ±2, printed.
fn check(design: &str, bom: &str) {
    let (predicted, found, parts) = predicted_and_found(design, bom, 0.05, 0.02);
    println!("{design}: the plan predicts {predicted} of {parts} parts identified, its releases identify {found}");
    assert!(predicted.abs_diff(found) <= 2, "{design}: predicted {predicted}, found {found}");
}

#[test]
fn the_plan_predicts_the_default_designs_identified_count() {
    check("designs/double_pendulum.toml", "tests/data/double_pendulum_bom.csv");
}

#[test]
fn the_plan_predicts_a_three_joint_arms_identified_count() {
    check("designs/ur5_pan_lift_elbow.toml", "tests/data/ur5_pan_lift_elbow_bom.csv");
}
