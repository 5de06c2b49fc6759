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

/// The default design's switch scenario reports what the springs save against the arm without
/// them, and the figures match a hand computation from `sim_switch.csv` (rigid torque = actuator
/// + spring torque, integrals as left sums over the samples) to 3 digits.
#[test]
fn switch_savings_match_a_hand_computation_from_the_csv() {
    let dir = temp_dir("sim-savings");
    let design = util::with_builds(&dir, "double_pendulum", 0);
    springfit(&dir, &["simulate", design.to_str().unwrap(), "--scenario", "switch", "--out", "sim"]).ok();
    let out = dir.join("sim");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sim_switch.json")).unwrap()).unwrap();
    let savings = &json["runs"]["switch"]["savings"];
    let csv = std::fs::read_to_string(out.join("sim_switch.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let rows: Vec<Vec<f64>> =
        lines.map(|l| l.split(',').skip(1).map(|v| v.parse::<f64>().unwrap_or(f64::NAN)).collect()).collect();
    // Column indices without the leading `run`.
    let c = |name: &str| col(name) - 1;
    let (mut with, mut without, mut copper_with, mut copper_without) = (0.0, 0.0, 0.0, 0.0);
    let (mut peak_with, mut peak_without) = (0.0f64, 0.0f64);
    for k in 0..rows.len() {
        let r = &rows[k];
        let act: Vec<f64> = (1..=2)
            .map(|i| {
                r[c(&format!("tau_mode{i}"))] + r[c(&format!("tau_energy{i}"))] + r[c(&format!("tau_compensation{i}"))]
            })
            .collect();
        let rigid: Vec<f64> = (1..=2).map(|i| act[i - 1] + r[c(&format!("tau_spring{i}"))]).collect();
        for i in 0..2 {
            peak_with = peak_with.max(act[i].abs());
            peak_without = peak_without.max(rigid[i].abs());
        }
        if k + 1 == rows.len() {
            break;
        }
        let dt = rows[k + 1][c("t")] - r[c("t")];
        let qd = [r[c("qd1")], r[c("qd2")]];
        with += (act[0] * qd[0] + act[1] * qd[1]).abs() * dt;
        without += (rigid[0] * qd[0] + rigid[1] * qd[1]).abs() * dt;
        copper_with += (act[0] * act[0] + act[1] * act[1]) * dt;
        copper_without += (rigid[0] * rigid[0] + rigid[1] * rigid[1]) * dt;
    }
    let close = |a: f64, b: f64, what: &str| {
        assert!((a - b).abs() <= 5e-4 * b.abs().max(1e-12), "{what}: report {a} vs hand {b}");
    };
    close(savings["with_springs"]["energy_j"].as_f64().unwrap(), with, "energy with springs");
    close(savings["without_springs"]["energy_j"].as_f64().unwrap(), without, "energy without springs");
    close(savings["energy_saved"].as_f64().unwrap(), 1.0 - with / without, "energy saved");
    close(savings["without_springs"]["peak_torque_nm"].as_f64().unwrap(), peak_without, "peak without springs");
    close(savings["with_springs"]["peak_torque_nm"].as_f64().unwrap(), peak_with, "peak with springs");
    // Default motor constants: 1 N·m/√W on each joint.
    close(savings["copper_loss_saved"].as_f64().unwrap(), 1.0 - copper_with / copper_without, "copper saved");
    let saved = savings["energy_saved"].as_f64().unwrap();
    assert!(saved > 0.9, "the springs carry the motion: {saved}");
    println!("energy saved {:.2} % ({with:.3} J vs {without:.3} J)", 100.0 * saved);
}

/// A three-joint arm under gravity switches through five mode directions with `modes`: every step
/// settles (mode error below 3° for the rest of the step), the actuator share stays below 5 % and
/// the torques within `max_torque`.
#[test]
fn a_three_joint_switch_through_five_modes_settles() {
    let dir = temp_dir("sim-switch3");
    let mut text = std::fs::read_to_string(repo().join("designs/triple_pendulum.toml")).unwrap();
    text = text.replace("../catalogs/", &format!("{}/catalogs/", repo().display()));
    text = text.replace("beta_e = 1.0", "beta_e = 1.0\nmax_torque = [40.0, 20.0, 8.0]");
    text.push_str(
        "\n[[scenario]]\nname = \"switch\"\nkind = \"switch\"\nenergy = 2.0\nevery = 10.0\n\
         modes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, -1.0, 0.5], [0.3, 0.5, -1.0]]\n",
    );
    let design = dir.join("triple_switch.toml");
    std::fs::write(&design, text).unwrap();
    let run = springfit(&dir, &["simulate", design.to_str().unwrap(), "--scenario", "switch", "--out", "sim"]).ok();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sim/sim_switch.json")).unwrap()).unwrap();
    let m = &json["runs"]["switch"];
    let settling: Vec<Option<f64>> = m["settling_s"].as_array().unwrap().iter().map(|v| v.as_f64()).collect();
    assert_eq!(settling.len(), 5, "{m}");
    assert!(settling.iter().all(|s| s.is_some_and(|s| s < 10.0)), "{settling:?}\n{}", run.report());
    assert!(m["actuator_share"].as_f64().unwrap() < 0.05, "{m}");
    assert!(m["peak_actuator_torque_nm"].as_f64().unwrap() <= 40.0 + 1e-9, "{m}");
    println!("settling {settling:?}, share {}", m["actuator_share"]);
}

/// A three-joint URDF arm under gravity with the gains left to the arm (`panda_three`, which
/// ships no scenario, with the URDF's effort limits and a switch through five directions added):
/// every step settles within its 5 s, the actuator share stays below 5 %, every joint's motor
/// torque within its limit, and `sim_switch.json` names the four gains derived from the arm.
#[test]
fn a_urdf_arm_with_gains_from_the_arm_switches_through_five_modes() {
    let dir = temp_dir("sim-switch-urdf");
    let mut text = std::fs::read_to_string(repo().join("designs/panda_three.toml")).unwrap();
    text = text.replace("\"../", &format!("\"{}/", repo().display()));
    text.push_str(
        "\n[controllers]\nmax_torque = [87.0, 87.0, 12.0]\n\n[[scenario]]\nname = \"switch\"\nkind = \"switch\"\n\
         energy = 1.0\nevery = 5.0\nmodes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, -1.0, 0.5], [0.3, 0.5, -1.0]]\n",
    );
    let design = dir.join("panda_switch.toml");
    std::fs::write(&design, text).unwrap();
    let run = springfit(&dir, &["simulate", design.to_str().unwrap(), "--scenario", "switch", "--out", "sim"]).ok();
    assert!(run.stdout().contains("k_θ = ") && run.stdout().contains("(from the arm)"), "{}", run.report());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sim/sim_switch.json")).unwrap()).unwrap();
    let from: Vec<&str> = json["gains"]["from_arm"].as_array().unwrap().iter().filter_map(|v| v.as_str()).collect();
    assert_eq!(from, ["k_theta", "epsilon", "beta_e", "beta_nd"], "{}", json["gains"]);
    let m = &json["runs"]["switch"];
    let settling: Vec<Option<f64>> = m["settling_s"].as_array().unwrap().iter().map(|v| v.as_f64()).collect();
    assert_eq!(settling.len(), 5, "{m}");
    assert!(settling.iter().all(|s| s.is_some_and(|s| s < 5.0)), "{settling:?}\n{}", run.report());
    let share = m["actuator_share"].as_f64().unwrap();
    assert!(share <= 0.05, "{m}");
    // Every joint within its own limit, on every output sample (the saturation holds them at every
    // stage; the samples are what a user can check by hand).
    let limits = [87.0, 87.0, 12.0];
    let csv = std::fs::read_to_string(dir.join("sim/sim_switch.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let mut peak = [0.0f64; 3];
    for line in lines {
        let r: Vec<f64> = line.split(',').map(|v| v.parse::<f64>().unwrap_or(f64::NAN)).collect();
        for (i, p) in peak.iter_mut().enumerate() {
            let j = i + 1;
            let tau = r[col(&format!("tau_mode{j}"))]
                + r[col(&format!("tau_energy{j}"))]
                + r[col(&format!("tau_compensation{j}"))];
            *p = p.max(tau.abs());
        }
    }
    assert!(peak.iter().zip(limits).all(|(p, l)| *p <= l + 1e-9), "{peak:?} against {limits:?}");
    assert!(m["peak_actuator_torque_nm"].as_f64().unwrap() <= 87.0 + 1e-9, "{m}");
    println!("gains {}; settling {settling:?}, share {share}, peak per joint {peak:?}", json["gains"]);
}

/// Bad `modes`: one clear error naming the scenario and the field.
#[test]
fn bad_modes_are_named_with_their_scenario_and_field() {
    let dir = temp_dir("sim-badmodes");
    let base = std::fs::read_to_string(repo().join("designs/triple_pendulum.toml"))
        .unwrap()
        .replace("../catalogs/", &format!("{}/catalogs/", repo().display()));
    let cases = [
        ("modes = [[1.0, 0.0, 0.0], [1.0, 0.0]]", "scenario[3].modes[1]", "has 2 entries"),
        ("modes = [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]", "scenario[3].modes[1]", "non-zero"),
        ("mode = [1.0, 0.0, 0.0]", "scenario[3].modes", "needs modes"),
    ];
    for (k, (line, field, reason)) in cases.iter().enumerate() {
        let design = dir.join(format!("bad{k}.toml"));
        std::fs::write(&design, format!("{base}\n[[scenario]]\nname = \"hop\"\nkind = \"switch\"\n{line}\n")).unwrap();
        springfit(&dir, &["check", design.to_str().unwrap()]).fails(2, &[field, reason, "scenario `hop`"]);
    }
}
