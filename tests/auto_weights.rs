//! `[fit]` weights set to `"auto"`: chosen by `springfit fit` from measured candidates
//! (`fit::auto`), deterministic whatever the thread count; a design that sets its weights is
//! fitted as it is.

mod util;

use util::{design_variant, springfit, springfit_threads, temp_dir};

/// The default design on small fans with few builds and the tolerance weight left to springfit
/// (three candidates): a quick case of the whole choice.
fn quick_auto(dir: &std::path::Path) -> std::path::PathBuf {
    let int = toml::Value::Integer;
    design_variant(
        dir,
        "double_pendulum",
        &[
            ("fit.tolerance_weight", toml::Value::String("auto".into())),
            ("fit.auto_budget", int(3)),
            ("fit.builds", int(100)),
            ("fit.training_directions", int(36)),
            ("fit.training_samples", int(20)),
            ("fit.evaluation_directions", int(36)),
            ("fit.evaluation_samples", int(20)),
        ],
    )
}

fn summary(dir: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn the_automatic_choice_is_reported_and_the_same_on_one_and_two_threads() {
    let dir = temp_dir("auto-threads");
    let design = quick_auto(&dir);
    let d = design.to_str().unwrap();
    let one = springfit_threads(&dir, &["fit", d, "--out", "one"], 1).ok();
    springfit_threads(&dir, &["fit", d, "--out", "two"], 2).ok();
    let read = |f: &str| std::fs::read(dir.join(f)).unwrap();
    assert_eq!(read("one/bom.csv"), read("two/bom.csv"), "the chosen bill differs between thread counts");
    let (a, b) = (summary(&dir.join("one")), summary(&dir.join("two")));
    let auto = &a["auto_weights"];
    assert_eq!(auto, &b["auto_weights"], "the candidates' figures differ between thread counts");
    // The three first rungs of the tolerance ladder, the design's trimmed weight and restarts kept.
    let tried = auto["tried"].as_array().unwrap();
    let weights: Vec<f64> = tried.iter().map(|t| t["weights"]["tolerance_weight"].as_f64().unwrap()).collect();
    assert_eq!(weights, [0.03, 0.1, 0.3], "{auto:#}");
    for t in tried {
        assert_eq!(t["weights"]["trimmed_weight"].as_f64(), Some(0.22));
        assert_eq!(t["weights"]["restarts"].as_u64(), Some(16));
        assert!(t["figures"]["built_p95_deg"].as_f64().is_some_and(f64::is_finite), "{t:#}");
    }
    let chosen = auto["chosen"].as_u64().unwrap() as usize;
    assert_eq!(a["residual_deg"]["p99_abs"], tried[chosen]["figures"]["p99_deg"], "the bill is the chosen one's");
    assert!(one.stdout().contains("weights chosen by springfit (3 candidates"), "{}", one.report());
    let report = std::fs::read_to_string(dir.join("one/report.md")).unwrap();
    assert!(report.contains("## Weights chosen by springfit"), "{report}");
    // `simulate` fits the design itself: the same choice, so the springs `fit` wrote.
    springfit(&dir, &["simulate", d, "--scenario", "free", "--out", "sim"]).ok();
    let sim: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sim/sim_free.json")).unwrap()).unwrap();
    assert_eq!(sim["spring_set"], a["spring_set"], "simulate fitted other springs than fit");
}

#[test]
fn a_design_that_sets_its_weights_is_fitted_as_it_is() {
    let dir = temp_dir("auto-explicit");
    let int = toml::Value::Integer;
    let design = design_variant(
        &dir,
        "double_pendulum",
        &[
            ("fit.builds", int(0)),
            ("fit.training_directions", int(36)),
            ("fit.training_samples", int(20)),
            ("fit.evaluation_directions", int(36)),
            ("fit.evaluation_samples", int(20)),
        ],
    );
    let run = springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "out"]).ok();
    assert!(!run.stdout().contains("weights chosen"), "{}", run.report());
    assert!(summary(&dir.join("out")).get("auto_weights").is_none());
}

#[test]
fn a_weight_is_a_number_or_auto() {
    let dir = temp_dir("auto-word");
    let design = design_variant(&dir, "double_pendulum", &[("fit.mass_weight", toml::Value::String("heavy".into()))]);
    springfit(&dir, &["check", design.to_str().unwrap()]).fails(2, &["mass_weight", "auto"]);
}

/// The default design on small fans with its `tolerance_weight` and `restarts` left out and an
/// aim on the untrimmed builds: those two weights are chosen (the trimmed weight the design sets
/// is kept), and the search stops at the first candidate that meets the aim.
#[test]
fn aims_choose_the_weights_left_out_and_end_the_search_once_met() {
    let dir = temp_dir("auto-aims");
    let int = toml::Value::Integer;
    let quick = |aim: f64| {
        let path = design_variant(
            &dir,
            "double_pendulum",
            &[
                ("fit.aim_untrimmed_p95_deg", toml::Value::Float(aim)),
                ("fit.auto_budget", int(3)),
                ("fit.builds", int(100)),
                ("fit.training_directions", int(36)),
                ("fit.training_samples", int(20)),
                ("fit.evaluation_directions", int(36)),
                ("fit.evaluation_samples", int(20)),
            ],
        );
        let mut table: toml::Table = toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let fit = table.get_mut("fit").and_then(|f| f.as_table_mut()).unwrap();
        fit.remove("tolerance_weight");
        fit.remove("restarts");
        std::fs::write(&path, toml::to_string(&table).unwrap()).unwrap();
        path
    };
    // An aim every candidate meets: one candidate, the first rung, chosen.
    let design = quick(90.0);
    let run = springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "met"]).ok();
    let auto = summary(&dir.join("met"))["auto_weights"].clone();
    let tried = auto["tried"].as_array().unwrap();
    assert_eq!(tried.len(), 1, "{auto:#}");
    assert_eq!(tried[0]["weights"]["tolerance_weight"].as_f64(), Some(0.03), "{auto:#}");
    assert_eq!(tried[0]["weights"]["trimmed_weight"].as_f64(), Some(0.22), "{auto:#}");
    assert_eq!(tried[0]["weights"]["restarts"].as_u64(), Some(16), "{auto:#}");
    assert_eq!(auto["aims_met"], serde_json::Value::Bool(true), "{auto:#}");
    assert_eq!(auto["aims"]["untrimmed_p95_deg"].as_f64(), Some(90.0), "{auto:#}");
    assert!(run.stdout().contains("the lightest meeting the design's aims untrimmed p95 ≤ 90°"), "{}", run.report());
    // An aim no candidate meets: the budget spent, the slack rule's winner, and said so.
    let design = quick(0.001);
    let run = springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "missed"]).ok();
    let auto = summary(&dir.join("missed"))["auto_weights"].clone();
    assert_eq!(auto["tried"].as_array().unwrap().len(), 3, "{auto:#}");
    assert_eq!(auto["aims_met"], serde_json::Value::Bool(false), "{auto:#}");
    assert!(run.stdout().contains("no candidate met the design's aims"), "{}", run.report());
}
