//! `springfit sweep` through the binary: shards merge into the full run's tables, bit for bit.

mod util;

use util::{design_text, repo, springfit, temp_dir, write};

/// The paper's design with a shorter, smaller sweep (the mechanics are the same).
fn small_design(dir: &std::path::Path) -> std::path::PathBuf {
    let catalog = repo().join("catalogs/workshop.toml");
    let text = design_text("double_pendulum_workshop.toml")
        .replace("../catalogs/workshop.toml", catalog.to_str().unwrap())
        .replace("epsilons = [0.0, 0.01, 0.05, 0.1, 0.5, 1.0]", "epsilons = [0.0, 0.1, 1.0]")
        .replace("builds = 200", "builds = 5")
        .replace(
            "name = \"sensitivity\"\nkind = \"swingup\"\nduration = 20.0",
            "name = \"sensitivity\"\nkind = \"swingup\"\nduration = 4.0",
        );
    assert!(text.contains("duration = 4.0") && text.contains("builds = 5"));
    write(dir, "small.toml", &text)
}

#[test]
fn shards_merge_into_the_same_tables_and_threads_do_not_matter() {
    let dir = temp_dir("sweep-shards");
    let design = small_design(&dir);
    let d = design.to_str().unwrap();
    let full = springfit(&dir, &["sweep", d, "--out", "full"]).ok();
    assert!(full.stdout().contains("stock rates"), "{}", full.report());
    springfit(&dir, &["--threads", "1", "sweep", d, "--out", "one"]).ok();
    springfit(&dir, &["sweep", d, "--shard", "1/2", "--out", "s1"]).ok();
    springfit(&dir, &["sweep", d, "--shard", "2/2", "--out", "s2"]).ok();
    springfit(&dir, &["sweep", d, "--merge", "s1", "s2", "--out", "merged"]).ok();
    let read = |p: &str| std::fs::read_to_string(dir.join(p)).unwrap();
    for f in ["sweep.json", "sweep.csv", "tolerance.md", "bom_stock.csv"] {
        assert_eq!(read(&format!("full/{f}")), read(&format!("merged/{f}")), "{f} differs after merging");
        assert_eq!(read(&format!("full/{f}")), read(&format!("one/{f}")), "{f} differs with one thread");
    }
    let json: serde_json::Value = serde_json::from_str(&read("full/sweep.json")).unwrap();
    let rows = json["parasitic"].as_array().unwrap();
    assert_eq!(rows.len(), 3);
    let shares: Vec<f64> = rows.iter().map(|r| r["actuator_share"].as_f64().unwrap()).collect();
    assert!(shares[0] < shares[1] && shares[1] < shares[2], "actuator share should rise with ε: {shares:?}");
    for key in ["builds", "actuator_share_p50", "actuator_share_p95", "residual_p99_deg_p50", "residual_p99_deg_p95"] {
        assert!(json["tolerance"].get(key).is_some(), "tolerance lacks {key}");
    }
    for key in ["residual_p99_deg_before", "residual_p99_deg_after"] {
        assert!(json["stock"][key].as_f64().is_some(), "stock lacks {key}");
    }
    // An incomplete merge is refused.
    springfit(&dir, &["sweep", d, "--merge", "s1", "--out", "partial"]).fails(2, &["missing", "merge every shard"]);
    springfit(&dir, &["sweep", d, "--shard", "3/2"]).fails(2, &["--shard", "i/N"]);
    // A folder that is no shard is named before the fit's seconds of work.
    let run = springfit(&dir, &["sweep", d, "--merge", "s1", "nosuch", "--out", "partial"])
        .fails(2, &["--merge", "nosuch holds no sweep_shard.json"]);
    assert!(!run.stderr().contains("fitting the springs"), "{}", run.report());
}

/// stderr is no terminal here, so progress comes as plain lines (`--progress lines`): one per
/// step, and for the sweep's counted items the count with the time left, the last item's always.
/// `--quiet` and `--progress none` print none; `--progress bars` draws nothing off a terminal.
#[test]
fn progress_off_a_terminal_is_plain_lines_with_the_time_left() {
    let dir = temp_dir("sweep-progress");
    let design = small_design(&dir);
    let d = design.to_str().unwrap();
    let run = springfit(&dir, &["sweep", d, "--shard", "1/2", "--out", "s1"]).ok();
    let err = run.stderr();
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("springfit: ") && !l.contains("warning")).collect();
    assert!(lines.iter().any(|l| l.starts_with("springfit: fitting the springs")), "{}", run.report());
    let counts: Vec<&&str> = lines.iter().filter(|l| l.contains(" done, ") && l.contains(" left")).collect();
    let last = counts.last().unwrap_or_else(|| panic!("no count line\n{}", run.report()));
    let (done, total) =
        last.split(": ").nth(2).and_then(|c| c.split(" done").next()).and_then(|c| c.split_once(" of ")).unwrap();
    assert_eq!(done, total, "the last item's line: {last}");
    assert!(last.ends_with("about 0 s left"), "{last}");
    for quiet in [&["--quiet"][..], &["--progress", "none"], &["--progress", "bars"]] {
        let args: Vec<&str> = quiet.iter().copied().chain(["sweep", d, "--shard", "1/2", "--out", "s1"]).collect();
        let run = springfit(&dir, &args).ok();
        assert!(!run.stderr().contains(" done, "), "{quiet:?}\n{}", run.report());
        assert!(!run.stderr().contains("fitting the springs"), "{quiet:?}\n{}", run.report());
    }
}

/// The shipped design has trim springs and adjustable offsets: every build is reported as built
/// (untuned), the first `tuned_builds` also tuned after assembly as `springfit tune` would tune
/// them, on stdout and in every file. Tuned builds rest at q_eq again and need less of the
/// actuators than untuned ones.
#[test]
fn builds_are_reported_untuned_and_tuned() {
    let dir = temp_dir("sweep-tuned");
    let text = util::design_text_anywhere("double_pendulum.toml")
        .replace("epsilons = [0.0, 0.01, 0.05, 0.1, 0.5, 1.0]", "epsilons = [0.0]")
        .replace("builds = 200", "builds = 4")
        .replace("tolerances = [0.05, 0.1]", "tolerances = [0.1]\ntuned_builds = 3")
        .replace(
            "name = \"sensitivity\"\nkind = \"swingup\"\nduration = 20.0",
            "name = \"sensitivity\"\nkind = \"swingup\"\nduration = 6.0",
        );
    assert!(text.contains("duration = 6.0") && text.contains("builds = 4") && text.contains("[0.1]"));
    let design = write(&dir, "d.toml", &text);
    let run = springfit(&dir, &["sweep", design.to_str().unwrap(), "--out", "s"]).ok();
    let out = run.stdout();
    assert!(out.contains("as built (untuned)") && out.contains("tuned after the build"), "{}", run.report());
    let read = |p: &str| std::fs::read_to_string(dir.join(p)).unwrap();
    let json: serde_json::Value = serde_json::from_str(&read("s/sweep.json")).unwrap();
    let level = &json["tolerance_levels"][0];
    let tuned = &level["tuned"];
    let share = |v: &serde_json::Value| v.as_f64().unwrap();
    assert_eq!(tuned["builds"], 3, "{tuned}");
    assert!(share(&tuned["equilibrium_shift_rad"]["p95"]) < 1e-6, "{tuned}");
    assert!(share(&level["equilibrium_shift_rad_p50"]) > 1e-3, "{level}");
    assert!(share(&tuned["actuator_share"]["p50"]) < share(&level["actuator_share_p50"]), "{level}");
    assert!(read("s/tolerance.md").contains("tuned actuator share"));
    let csv = read("s/sweep.csv");
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "actuator_share_tuned").unwrap();
    let builds: Vec<&str> = csv.lines().filter(|l| l.split(',').nth(1) == Some("build")).collect();
    assert_eq!(builds.len(), 4);
    for (i, b) in builds.iter().enumerate() {
        let cell = b.split(',').nth(col).unwrap();
        if i < 3 {
            let v: f64 = cell.parse().unwrap();
            assert!(v.is_finite() && v >= 0.0, "{b}");
        } else {
            assert!(cell.is_empty(), "build {i} is past tuned_builds = 3 and should not be tuned: {b}");
        }
    }
}
