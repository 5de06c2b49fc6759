//! `springfit simulate` through the binary.

mod util;

use util::{repo, springfit, temp_dir};

#[test]
fn swingup_writes_metrics_per_variant_and_plots() {
    let dir = temp_dir("sim-swingup");
    let design = util::with_builds(&dir, "double_pendulum", 0);
    // Fit first (without the Monte Carlo builds), then simulate the springs of its bill of
    // materials.
    springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "fit"]).ok();
    let run = springfit(
        &dir,
        &["simulate", design.to_str().unwrap(), "--scenario", "swingup", "--bom", "fit/bom.csv", "--out", "sim"],
    )
    .ok();
    let out = dir.join("sim");
    for f in ["sim_swingup.csv", "sim_swingup.json"] {
        assert!(out.join(f).is_file(), "missing {f}\n{}", run.report());
    }
    for plot in ["configuration", "q", "torques", "label", "power", "energy"] {
        for ext in ["svg", "png"] {
            assert!(out.join(format!("sim_swingup_{plot}.{ext}")).is_file(), "missing {plot}.{ext}");
        }
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sim_swingup.json")).unwrap()).unwrap();
    for variant in ["energy", "negative_damping", "energy_compensated"] {
        let m = &json["runs"][variant];
        for key in ["energy_rel_error_last5s", "flux", "actuator_share", "peak_torque_nm"] {
            assert!(m.get(key).is_some(), "{variant} lacks {key}: {m}");
        }
        for src in ["potential", "mode", "energy", "damping"] {
            assert!(m["flux"][src].as_f64().is_some(), "{variant} flux lacks {src}");
        }
    }
    assert!(json["runs"]["energy_compensated"]["energy_rel_error_last5s"].as_f64().unwrap() < 0.02);
    let csv = std::fs::read_to_string(out.join("sim_swingup.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(header.starts_with("run,t,q1,q2,qd1,qd2,tau_spring1"), "{header}");
    assert!(header.ends_with("E,label,label_target,geodesic_deviation"), "{header}");
    assert!(json["potential"].as_str().unwrap().contains("bom.csv"));
}

#[test]
fn an_unknown_scenario_is_named() {
    let dir = temp_dir("sim-unknown");
    let design = repo().join("designs/double_pendulum.toml");
    springfit(&dir, &["simulate", design.to_str().unwrap(), "--scenario", "moonwalk", "--exact"])
        .fails(2, &["moonwalk", "free, switch, swingup"]);
    assert!(!dir.join("out").exists());
}

/// An energy the springs cannot reach depends on the springs, not on the input (`check` passes
/// the design): the release is not met (exit 1, its error named), and the other releases still
/// run and are written.
#[test]
fn a_release_the_springs_cannot_reach_is_not_met_and_the_others_still_run() {
    let dir = temp_dir("sim-unreached");
    let text = util::design_text_anywhere("double_pendulum.toml").replace(
        "duration = 20.0\nreleases = [\n  { mode = 0.0, energy = 10.0 },\n  { mode = \"pi/3\", energy = 10.0 },",
        "duration = 1.0\nreleases = [\n  { mode = 0.0, energy = 10.0 },\n  { mode = \"pi/3\", energy = 1000.0 },",
    );
    assert!(text.contains("energy = 1000.0"));
    let design = util::write(&dir, "far.toml", &text);
    let d = design.to_str().unwrap();
    springfit(&dir, &["check", d]).ok();
    let run = springfit(&dir, &["simulate", d, "--exact", "--scenario", "free", "--out", "sim"])
        .fails(1, &["cannot reach", "scenario[0].releases[1].energy", "1000 J is out of reach"]);
    let csv = std::fs::read_to_string(dir.join("sim/sim_free.csv")).unwrap_or_else(|e| panic!("{e}\n{}", run.report()));
    assert!(csv.lines().any(|l| l.starts_with("release_1,")), "release_1 ran");
    assert!(csv.lines().any(|l| l.starts_with("release_3,")), "release_3 ran");
    assert!(!csv.lines().any(|l| l.starts_with("release_2,")), "release_2 cannot run");
}
