//! Output folders through the binary: springfit never deletes or overwrites a file it did not
//! write. A command writes into a new or empty folder, or into its own earlier output folder
//! (recognised by its manifest), and then replaces only the files that manifest lists.

mod util;

use std::path::{Path, PathBuf};

use util::{repo, springfit, temp_dir, walk, write};

const MANIFEST: &str = ".springfit-manifest.json";

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    walk(dir).into_iter().map(|p| (p.clone(), std::fs::read(&p).unwrap())).collect()
}

fn manifest_files(dir: &Path) -> Vec<String> {
    let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join(MANIFEST)).unwrap()).unwrap();
    m["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap().to_string()).collect()
}

/// No staging or backup folder left next to the outputs.
fn no_leftovers(dir: &Path) {
    let hidden: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".springfit-"))
        .collect();
    assert!(hidden.is_empty(), "staging or backup folders left behind: {hidden:?}");
}

/// The default design with 24 × 10 held-out samples and no Monte Carlo builds, written into
/// `dir`: these tests are about the files, and its `fit` and `fit --exact` take a tenth of the
/// shipped design's time.
fn quick(dir: &Path) -> PathBuf {
    util::design_variant(
        dir,
        "double_pendulum",
        &[
            ("fit.evaluation_directions", toml::Value::Integer(24)),
            ("fit.evaluation_samples", toml::Value::Integer(10)),
            ("fit.builds", toml::Value::Integer(0)),
        ],
    )
}

#[test]
fn a_folder_of_user_files_is_refused_by_every_command_and_left_untouched() {
    let dir = temp_dir("safety-user");
    write(&dir, "documents/thesis.tex", "\\documentclass{article} precious");
    write(&dir, "documents/figures/plot.png", "nested user file");
    write(&dir, "documents/figures/deeper/data.csv", "1,2,3");
    let before = snapshot(&dir.join("documents"));
    let design = repo().join("designs/double_pendulum.toml");
    let d = design.to_str().unwrap();
    let runs: Vec<Vec<&str>> = vec![
        vec!["fit", d, "--out", "documents"],
        vec!["fit", d, "--exact", "--out", "documents"],
        vec!["geodesics", d, "--out", "documents"],
        vec!["simulate", d, "--exact", "--scenario", "sensitivity", "--out", "documents"],
        vec!["sweep", d, "--builds", "1", "--out", "documents"],
        vec!["sweep", d, "--shard", "1/2", "--out", "documents"],
        vec!["compare", d, "--out", "documents"],
        vec!["pareto", d, "--k-max", "3", "--radii", "1", "--out", "documents"],
        vec!["parts", d, "--out", "documents"],
    ];
    for args in runs {
        let run = springfit(&dir, &args)
            .fails(2, &["documents", "not empty", "no springfit manifest", "choose another --out"]);
        assert_eq!(snapshot(&dir.join("documents")), before, "user files changed\n{}", run.report());
        // Refused before any work: nothing was fitted or simulated.
        assert!(!run.stdout().contains("wrote"), "{}", run.report());
        no_leftovers(&dir);
    }
}

#[test]
fn a_rerun_replaces_only_its_own_files_and_removes_its_stale_ones() {
    let dir = temp_dir("safety-rerun");
    let design = quick(&dir);
    let d = design.to_str().unwrap();
    springfit(&dir, &["fit", d, "--out", "run"]).ok();
    let first = manifest_files(&dir.join("run"));
    assert!(first.contains(&"bom.csv".to_string()) && first.contains(&"summary.json".to_string()), "{first:?}");
    for f in &first {
        assert!(dir.join("run").join(f).is_file(), "{f} listed but not written");
    }
    // The user keeps notes and a subfolder of their own in the output folder.
    write(&dir, "run/notes.txt", "my notes");
    write(&dir, "run/mine/measurements.csv", "k,0.5");
    write(&dir, "run/mine/deeper/photo.jpg", "jpeg");
    let summary_before = std::fs::read_to_string(dir.join("run/summary.json")).unwrap();
    // The same command again, now writing fewer files: its stale bill of materials goes.
    let run = springfit(&dir, &["fit", d, "--exact", "--out", "run"]).ok();
    assert!(!dir.join("run/bom.csv").exists() && !dir.join("run/bom.md").exists(), "{}", run.report());
    assert_ne!(std::fs::read_to_string(dir.join("run/summary.json")).unwrap(), summary_before);
    assert_eq!(std::fs::read_to_string(dir.join("run/notes.txt")).unwrap(), "my notes");
    assert_eq!(std::fs::read_to_string(dir.join("run/mine/measurements.csv")).unwrap(), "k,0.5");
    assert_eq!(std::fs::read_to_string(dir.join("run/mine/deeper/photo.jpg")).unwrap(), "jpeg");
    let second = manifest_files(&dir.join("run"));
    assert!(!second.iter().any(|f| f.starts_with("bom") || f.contains("notes") || f.contains("mine")), "{second:?}");
    no_leftovers(&dir);
    // Another command does not write into a fit folder.
    let before = snapshot(&dir.join("run"));
    springfit(&dir, &["geodesics", d, "--out", "run"]).fails(2, &["run", "`springfit fit`", "choose another --out"]);
    assert_eq!(snapshot(&dir.join("run")), before);
    // An empty folder may be used.
    std::fs::create_dir(dir.join("empty")).unwrap();
    springfit(&dir, &["geodesics", d, "--out", "empty"]).ok();
    assert!(dir.join("empty/geodesics.csv").is_file());
}

#[test]
fn a_stale_file_is_removed_only_when_the_old_manifest_lists_it() {
    let dir = temp_dir("safety-stale");
    let design = quick(&dir);
    let d = design.to_str().unwrap();
    springfit(&dir, &["fit", d, "--out", "run"]).ok();
    // Take bom.md off the manifest: to springfit it is now a file someone else put there.
    let path = dir.join("run").join(MANIFEST);
    let text = std::fs::read_to_string(&path).unwrap();
    let edited = text.replace("\"bom.md\",", "");
    assert_ne!(edited, text);
    std::fs::write(&path, edited).unwrap();
    let bom_md = std::fs::read_to_string(dir.join("run/bom.md")).unwrap();
    springfit(&dir, &["fit", d, "--exact", "--out", "run"]).ok();
    assert!(!dir.join("run/bom.csv").exists(), "listed and no longer written: removed");
    assert_eq!(std::fs::read_to_string(dir.join("run/bom.md")).unwrap(), bom_md, "unlisted: kept");
    // A run that would now write over that file refuses, and leaves the previous results.
    let before = snapshot(&dir.join("run"));
    springfit(&dir, &["fit", d, "--out", "run"]).fails(2, &["run", "bom.md", "did not write"]);
    assert_eq!(snapshot(&dir.join("run")), before);
    no_leftovers(&dir);
}

#[test]
fn a_partial_simulate_rerun_keeps_the_other_scenarios_files() {
    let dir = temp_dir("safety-partial");
    let design = quick(&dir);
    let d = design.to_str().unwrap();
    springfit(&dir, &["simulate", d, "--exact", "--scenario", "sensitivity", "--out", "sim"]).ok();
    springfit(&dir, &["simulate", d, "--exact", "--scenario", "swingup", "--out", "sim"]).ok();
    write(&dir, "sim/sim_mine.csv", "a user file named like ours");
    let files = manifest_files(&dir.join("sim"));
    for f in ["sim_sensitivity.json", "sim_sensitivity.csv", "sim_swingup.json", "sim_swingup_q.png"] {
        assert!(files.contains(&f.to_string()), "{f} missing from {files:?}");
        assert!(dir.join("sim").join(f).is_file());
    }
    let swingup = std::fs::read(dir.join("sim/sim_swingup.json")).unwrap();
    springfit(&dir, &["simulate", d, "--exact", "--scenario", "sensitivity", "--out", "sim"]).ok();
    assert_eq!(std::fs::read(dir.join("sim/sim_swingup.json")).unwrap(), swingup);
    assert_eq!(manifest_files(&dir.join("sim")), files);
    assert_eq!(std::fs::read_to_string(dir.join("sim/sim_mine.csv")).unwrap(), "a user file named like ours");
    no_leftovers(&dir);
}

#[test]
fn compare_names_the_command_that_wrote_a_folder_and_suggests_no_overwrite() {
    let dir = temp_dir("safety-compare");
    write(&dir, "sw/sweep.csv", "x");
    write(&dir, &format!("sw/{MANIFEST}"), r#"{"springfit": "0.1.0", "command": "sweep", "files": ["sweep.csv"]}"#);
    let run = springfit(&dir, &["compare", "sw", "--out", "cmp"])
        .fails(2, &["sw", "not an output folder of `springfit fit`", "`springfit sweep`"]);
    assert!(!run.stderr().contains("--out sw"), "must not suggest fitting into the sweep folder\n{}", run.report());
}

/// The bill of materials `fit` wrote, with a measured rate filled in for the first spring, as
/// `tune` asks a builder to do.
fn with_measured_rate(bom: &str) -> String {
    let mut lines = bom.lines();
    let mut s = format!("{},measured_stiffness\n", lines.next().unwrap());
    for (i, l) in lines.enumerate() {
        let rate = if i == 0 {
            format!("{}", l.split(',').nth(6).unwrap().parse::<f64>().unwrap() * 1.03)
        } else {
            String::new()
        };
        s.push_str(&format!("{l},{rate}\n"));
    }
    s
}

#[test]
fn a_users_edits_to_springfits_files_survive_a_rerun_of_fit_tune_and_sweep() {
    let dir = temp_dir("safety-edits");
    let design = quick(&dir);
    let d = design.to_str().unwrap();
    springfit(&dir, &["fit", d, "--out", "A", "--threads", "2"]).ok();
    let fitted = std::fs::read_to_string(dir.join("A/bom.csv")).unwrap();
    let measured = with_measured_rate(&fitted);
    std::fs::write(dir.join("A/bom.csv"), &measured).unwrap();
    // The same fit again would replace the edited bill: refused before any work, the edits kept.
    let run = springfit(&dir, &["fit", d, "--out", "A", "--threads", "2"])
        .fails(2, &["A", "`bom.csv` changed since `springfit fit` wrote it", "another --out", "--overwrite-edits"]);
    assert!(run.stdout().is_empty(), "refused before any work\n{}", run.report());
    assert_eq!(std::fs::read_to_string(dir.join("A/bom.csv")).unwrap(), measured);
    no_leftovers(&dir);

    // tune reads the edited bill from the fit's folder and writes its own; an edit there is kept too.
    springfit(&dir, &["tune", d, "--measured", "A/bom.csv", "--out", "T"]).ok();
    let note = "\n\nbuilt 2026-12-01, trims set by hand\n";
    let tuned = std::fs::read_to_string(dir.join("T/tune.md")).unwrap() + note;
    std::fs::write(dir.join("T/tune.md"), &tuned).unwrap();
    let run = springfit(&dir, &["tune", d, "--measured", "A/bom.csv", "--out", "T"])
        .fails(2, &["`tune.md` changed since `springfit tune` wrote it", "--overwrite-edits"]);
    assert!(run.stdout().is_empty(), "{}", run.report());
    assert_eq!(std::fs::read_to_string(dir.join("T/tune.md")).unwrap(), tuned);
    springfit(&dir, &["--overwrite-edits", "tune", d, "--measured", "A/bom.csv", "--out", "T"]).ok();
    assert!(!std::fs::read_to_string(dir.join("T/tune.md")).unwrap().contains("trims set by hand"));

    // sweep: an edited table is refused before the builds, and kept.
    springfit(&dir, &["sweep", d, "--builds", "1", "--out", "S", "--threads", "2"]).ok();
    let table = std::fs::read_to_string(dir.join("S/tolerance.md")).unwrap().replace("tolerance", "TOLERANCE");
    std::fs::write(dir.join("S/tolerance.md"), &table).unwrap();
    let run = springfit(&dir, &["sweep", d, "--builds", "1", "--out", "S"])
        .fails(2, &["`tolerance.md` changed since `springfit sweep` wrote it"]);
    assert!(run.stdout().is_empty(), "{}", run.report());
    assert_eq!(std::fs::read_to_string(dir.join("S/tolerance.md")).unwrap(), table);

    // Removing a file of springfit's loses nothing: the rerun goes ahead. With the flag, the
    // edited bill is replaced by the fit's own.
    std::fs::remove_file(dir.join("S/tolerance.md")).unwrap();
    springfit(&dir, &["--overwrite-edits", "fit", d, "--out", "A", "--threads", "2"]).ok();
    assert_eq!(std::fs::read_to_string(dir.join("A/bom.csv")).unwrap(), fitted);
    no_leftovers(&dir);
}

#[test]
fn every_command_refuses_a_users_file_in_the_way_before_any_work() {
    let dir = temp_dir("safety-in-the-way");
    let design = repo().join("designs/double_pendulum.toml");
    let d = design.to_str().unwrap();
    let bom = repo().join("tests/data/double_pendulum_nominal_bom.csv");
    let b = bom.to_str().unwrap();
    // (command line, the command's name, a file the run would write)
    let cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (vec!["fit", d], "fit", "bom.csv"),
        (vec!["fit", d, "--exact"], "fit", "summary.json"),
        (vec!["geodesics", d], "geodesics", "region.json"),
        (vec!["simulate", d, "--exact"], "simulate", "sim_switch_q.png"),
        (vec!["simulate", d, "--bom", b, "--scenario", "free"], "simulate", "sim_free.json"),
        (vec!["sweep", d, "--builds", "1"], "sweep", "sweep.csv"),
        (vec!["sweep", d, "--shard", "1/2"], "sweep", "sweep_shard.json"),
        (vec!["compare", d], "compare", "compare.md"),
        (vec!["pareto", d, "--k-max", "3", "--radii", "1"], "pareto", "pareto.csv"),
        (vec!["tune", d, "--measured", b], "tune", "tune.md"),
        (vec!["export", d, "--bom", b, "--mujoco"], "export", "double_pendulum.xml"),
    ];
    for (i, (args, command, file)) in cases.into_iter().enumerate() {
        let out = format!("out{i}");
        // An output folder of the command (its manifest lists nothing yet) with the user's file
        // where the run would write.
        write(
            &dir,
            &format!("{out}/{MANIFEST}"),
            &format!(r#"{{"springfit": "0.1.0", "command": "{command}", "files": []}}"#),
        );
        write(&dir, &format!("{out}/{file}"), "the user's own file");
        let mut args = args.clone();
        args.extend(["--out", out.as_str()]);
        let run = springfit(&dir, &args)
            .fails(2, &[&out, &format!("`{file}`"), "did not write", "move that file away first"]);
        assert!(run.stdout().is_empty(), "refused before any work\n{}", run.report());
        assert_eq!(std::fs::read_to_string(dir.join(&out).join(file)).unwrap(), "the user's own file");
        no_leftovers(&dir);
    }
}

#[test]
fn a_copy_of_a_design_that_kept_its_name_does_not_replace_the_originals_results() {
    let dir = temp_dir("safety-copy");
    let original = quick(&dir);
    let text = std::fs::read_to_string(&original).unwrap();
    // The newcomer's first move: a copy with one key changed and the same `name`.
    let changed = text.replacen("frequency = 4.0", "frequency = 3.0", 1);
    assert_ne!(changed, text, "the design sets frequency = 4.0");
    write(&dir, "mine.toml", &changed);
    springfit(&dir, &["fit", "double_pendulum.toml", "--exact"]).ok();
    let folder = dir.join("out/double_pendulum_exact");
    let before = snapshot(&folder);
    let run = springfit(&dir, &["fit", "mine.toml", "--exact"]).fails(
        2,
        &["out/double_pendulum_exact", "results of the design", "double_pendulum.toml", "mine.toml", "--out"],
    );
    assert!(!run.stdout().contains("wrote"), "refused before any work\n{}", run.report());
    assert_eq!(snapshot(&folder), before, "the original's results changed");
    // Its own folder is fine; the original, edited and run again, replaces its own results.
    springfit(&dir, &["fit", "mine.toml", "--exact", "--out", "out/mine"]).ok();
    std::fs::write(&original, text.replacen("frequency = 4.0", "frequency = 4.5", 1)).unwrap();
    springfit(&dir, &["fit", "double_pendulum.toml", "--exact"]).ok();
    let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(folder.join(MANIFEST)).unwrap()).unwrap();
    assert!(m["design"]["path"].as_str().unwrap().ends_with("double_pendulum.toml"), "{m}");
    assert_eq!(m["design"]["fnv1a64"].as_str().unwrap().len(), 16, "{m}");
    no_leftovers(&dir.join("out"));
}

#[test]
fn a_run_into_a_folder_another_run_is_writing_stops_at_once() {
    let dir = temp_dir("safety-lock");
    let design = quick(&dir);
    let d = design.to_str().unwrap();
    // Another run (here the library, as a second process would) holds the folder.
    let plan = springfit::report::output::Plan::new("fit", ["*"]);
    let claim = springfit::report::output::check(&dir.join("run"), &plan).unwrap();
    let run = springfit(&dir, &["fit", d, "--exact", "--out", "run"])
        .fails(2, &["run", "another springfit run is writing this folder", "choose another --out"]);
    assert!(!run.stdout().contains("wrote"), "{}", run.report());
    assert!(!dir.join("run").exists());
    drop(claim);
    springfit(&dir, &["fit", d, "--exact", "--out", "run"]).ok();
    no_leftovers(&dir);
}
