//! Bad input, atomic outputs and determinism across every command.

mod util;

use util::{design_text, repo, springfit, springfit_threads, temp_dir, write};

#[test]
fn an_unwritable_output_folder_is_named() {
    let dir = temp_dir("unwritable");
    write(&dir, "plainfile", "not a folder");
    let design = repo().join("designs/double_pendulum_workshop.toml");
    springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "plainfile/out"]).fails(2, &["plainfile"]);
    springfit(&dir, &["geodesics", design.to_str().unwrap(), "--out", "plainfile"])
        .fails(2, &["plainfile", "not a folder"]);
}

#[test]
fn a_bill_of_materials_edited_into_nonsense_is_refused() {
    let dir = temp_dir("bad-bom");
    let design = repo().join("designs/double_pendulum_workshop.toml");
    springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "fit"]).ok();
    let good = std::fs::read_to_string(dir.join("fit/bom.csv")).unwrap();
    let second = good.lines().nth(1).unwrap().to_string();
    // Row 2 with field `i` replaced.
    let edit = |i: usize, value: &str| {
        let mut f = springfit::files::split_csv_line(&second).unwrap();
        f[i] = value.to_string();
        good.replacen(&second, &f.join(","), 1)
    };
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        ("negative.csv", edit(6, "-5"), vec!["negative.csv", "line 2: stiffness", "≥ 0"]),
        ("letters.csv", edit(2, "springy"), vec!["letters.csv", "line 2: profile", "unknown profile"]),
        ("short.csv", good.replacen(&second, "S01,oops", 1), vec!["short.csv", "line 2: row", "fields"]),
        ("joints.csv", edit(4, "1;1;1"), vec!["joints.csv", "coupling"]),
        ("nan.csv", edit(5, "NaN"), vec!["nan.csv", "line 2: offset_rad", "finite"]),
    ];
    for (name, text, needles) in cases {
        assert_ne!(text, good, "case {name} did not change the file");
        write(&dir, name, &text);
        springfit(
            &dir,
            &["simulate", design.to_str().unwrap(), "--bom", name, "--scenario", "swingup", "--out", "sim"],
        )
        .fails(2, &needles);
        assert!(!dir.join("sim").exists());
    }
}

#[test]
fn a_run_failing_midway_leaves_the_previous_results() {
    let dir = temp_dir("midway");
    let catalog = repo().join("catalogs/workshop.toml");
    let text =
        design_text("double_pendulum_workshop.toml").replace("../catalogs/workshop.toml", catalog.to_str().unwrap());
    let design = write(&dir, "design.toml", &text);
    let d = design.to_str().unwrap();
    write(&dir, "sim/sim_swingup.json", "previous");
    // The folder is a previous output of `simulate` (its manifest says so), so it may be replaced.
    write(
        &dir,
        "sim/.springfit-manifest.json",
        r#"{"springfit": "0.1.0", "command": "simulate", "files": ["sim_swingup.json"]}"#,
    );
    // The folder is claimed, then the run fails: a bill whose springs do not hold q_eq (crank
    // S01's offset typed in degrees).
    let bom = std::fs::read_to_string(repo().join("tests/data/double_pendulum_bom.csv")).unwrap();
    write(&dir, "degrees.csv", &bom.replacen(",0.5235987755982988,", ",30,", 1));
    let run = springfit(&dir, &["simulate", d, "--bom", "degrees.csv", "--out", "sim"])
        .fails(2, &["degrees.csv", "offset_rad", "bill_tolerance"]);
    assert_eq!(std::fs::read_to_string(dir.join("sim/sim_swingup.json")).unwrap(), "previous", "{}", run.report());
    let staged: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert!(staged.is_empty(), "staging folders left behind: {staged:?}");
    // A scenario whose energy the springs cannot reach is not met (exit 1), not a failure: the
    // other scenarios run and replace the previous results (issue 42, item 3).
    let text = format!(
        "{text}\n[[scenario]]\nname = \"too_high\"\nkind = \"swingup\"\nduration = 1.0\ne0 = 5.0\ned = 5000.0\n"
    );
    let design = write(&dir, "design.toml", &text);
    let run = springfit(&dir, &["simulate", design.to_str().unwrap(), "--exact", "--out", "sim"])
        .fails(1, &["scenario[", "ed", "out of reach"]);
    assert_ne!(std::fs::read_to_string(dir.join("sim/sim_swingup.json")).unwrap(), "previous", "{}", run.report());
    assert!(!dir.join("sim/sim_too_high.json").exists(), "{}", run.report());
}

/// The default design as shipped but with 64 Monte Carlo builds instead of 1,000: the selection's
/// restarts and the builds both run in parallel, and 64 builds spread over two threads as 1,000 do.
#[test]
fn outputs_are_byte_identical_across_runs_and_thread_counts() {
    let dir = temp_dir("determinism");
    let design = util::with_builds(&dir, "double_pendulum", 64);
    let d = design.to_str().unwrap();
    springfit_threads(&dir, &["fit", d, "--out", "a"], 1).ok();
    springfit_threads(&dir, &["fit", d, "--out", "b"], 2).ok();
    springfit_threads(&dir, &["fit", d, "--out", "c"], 2).ok();
    let read = |p: &str| std::fs::read_to_string(dir.join(p)).unwrap();
    let without_timings = |s: String| -> serde_json::Value {
        let mut v: serde_json::Value = serde_json::from_str(&s).unwrap();
        v.as_object_mut().unwrap().remove("timings_s");
        v
    };
    for other in ["b", "c"] {
        assert_eq!(read("a/bom.csv"), read(&format!("{other}/bom.csv")));
        assert_eq!(read("a/residuals.csv"), read(&format!("{other}/residuals.csv")));
        assert_eq!(without_timings(read("a/summary.json")), without_timings(read(&format!("{other}/summary.json"))));
    }
    // Nothing non-finite reaches an output file.
    for f in ["a/bom.csv", "a/summary.json", "a/residuals.csv"] {
        let text = read(f).to_lowercase();
        assert!(!text.contains("nan") && !text.contains("inf"), "{f} holds a non-finite number");
    }
}

#[test]
fn absurd_settings_are_refused_before_any_work() {
    let dir = temp_dir("absurd");
    let catalog = repo().join("catalogs/workshop.toml");
    let base =
        design_text("double_pendulum_workshop.toml").replace("../catalogs/workshop.toml", catalog.to_str().unwrap());
    let every = write(&dir, "every.toml", &base.replace("every = 15.0", "every = 1e-300"));
    springfit(&dir, &["simulate", every.to_str().unwrap(), "--exact", "--scenario", "switch", "--out", "s"])
        .fails(2, &["every.toml", "scenario[1].every", "at most 10000"]);
    let dirs = write(&dir, "dirs.toml", &base.replace("[fit]", "[geodesics]\ndirections = 1000000000000\n\n[fit]"));
    springfit(&dir, &["check", dirs.to_str().unwrap()]).fails(2, &["dirs.toml", "geodesics.directions", "8 to 100000"]);
}

#[test]
fn usage_errors_are_one_line_too() {
    let dir = temp_dir("usage");
    springfit(&dir, &["fit", "--bogus"]).fails(2, &["--bogus"]);
    let run = springfit(&dir, &["sweep", "--builds", "abc"]).fails(2, &["--builds", "expected a whole number"]);
    assert!(!run.stderr().contains("usize"), "{}", run.report());
    let design = repo().join("designs/double_pendulum.toml");
    springfit(&dir, &["sweep", design.to_str().unwrap(), "--builds", "0"]).fails(2, &["--builds", "at least 1"]);
    springfit(&dir, &["pareto", "--radii", "1,x"]).fails(2, &["--radii", "expected a number"]);
}
