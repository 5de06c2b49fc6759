//! Tests of `output`.

use super::*;

/// A plan that may write any file.
fn any(command: &str) -> Plan {
    Plan::new(command, ["*"])
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("springfit-output-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn a_new_folder_is_created_whole_with_its_manifest() {
    let root = scratch("new");
    let target = root.join("out");
    let out = OutputDir::create(&target, &any("fit")).unwrap();
    out.write("new.txt", "new").unwrap();
    assert!(!target.exists(), "nothing visible before commit");
    out.commit().unwrap();
    assert_eq!(std::fs::read_to_string(target.join("new.txt")).unwrap(), "new");
    let m = Manifest::read(&target).unwrap().unwrap();
    assert_eq!((m.command.as_str(), m.files.clone()), ("fit", vec!["new.txt".to_string()]));
    assert_eq!(listing(&root), vec!["out"], "no staging or backup folder left");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_rerun_replaces_only_its_own_files() {
    let root = scratch("rerun");
    let target = root.join("out");
    let out = OutputDir::create(&target, &any("fit")).unwrap();
    out.write("a.txt", "1").unwrap();
    out.write("stale.txt", "1").unwrap();
    out.commit().unwrap();
    std::fs::write(target.join("mine.txt"), "user").unwrap();
    std::fs::create_dir(target.join("notes")).unwrap();
    std::fs::write(target.join("notes/n.txt"), "user").unwrap();
    let out = OutputDir::create(&target, &Plan::new("fit", ["a.txt", "stale.txt"])).unwrap();
    out.write("a.txt", "2").unwrap();
    out.commit().unwrap();
    assert_eq!(std::fs::read_to_string(target.join("a.txt")).unwrap(), "2");
    assert!(!target.join("stale.txt").exists(), "listed in the old manifest, no longer written");
    assert_eq!(std::fs::read_to_string(target.join("mine.txt")).unwrap(), "user");
    assert_eq!(std::fs::read_to_string(target.join("notes/n.txt")).unwrap(), "user");
    assert_eq!(Manifest::read(&target).unwrap().unwrap().files, vec!["a.txt"]);
    assert_eq!(listing(&root), vec!["out"]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn foreign_folders_are_refused_before_anything_is_written() {
    let root = scratch("foreign");
    let user = root.join("documents");
    std::fs::create_dir(&user).unwrap();
    std::fs::write(user.join("thesis.tex"), "precious").unwrap();
    let err = OutputDir::create(&user, &any("fit")).unwrap_err().to_string();
    assert!(err.contains("not empty") && err.contains("choose another --out"), "{err}");
    let sim = root.join("sim");
    OutputDir::create(&sim, &any("simulate")).unwrap().commit().unwrap();
    let err = check(&sim, &any("fit")).unwrap_err().to_string();
    assert!(err.contains("`springfit simulate`"), "{err}");
    std::fs::write(sim.join(MANIFEST), r#"{"springfit":"0","command":"simulate","files":["../x"]}"#).unwrap();
    let err = check(&sim, &any("simulate")).unwrap_err().to_string();
    assert!(err.contains("not a path inside"), "{err}");
    assert_eq!(listing(&root), vec!["documents", "sim"]);
    assert_eq!(listing(&user), vec!["thesis.tex"]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn an_empty_folder_may_be_used_and_keeps_its_other_contents_later() {
    let root = scratch("empty");
    let target = root.join("out");
    std::fs::create_dir(&target).unwrap();
    let out = OutputDir::create(&target, &any("sweep")).unwrap();
    out.write("sub/x.txt", "x").unwrap();
    out.commit().unwrap();
    assert_eq!(std::fs::read_to_string(target.join("sub/x.txt")).unwrap(), "x");
    let m = Manifest::read(&target).unwrap().unwrap();
    assert_eq!((m.files, m.folders), (vec!["sub/x.txt".to_string()], vec!["sub".to_string()]));
    // A rerun that no longer writes the subfolder removes it (it is springfit's and empty).
    let out = OutputDir::create(&target, &any("sweep")).unwrap();
    out.write("y.txt", "y").unwrap();
    out.commit().unwrap();
    assert_eq!(listing(&target), vec![MANIFEST, "y.txt"]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_file_the_user_put_where_springfit_writes_is_refused_before_the_run() {
    let root = scratch("clash");
    let target = root.join("out");
    let plan = Plan::new("fit", ["bom.csv", "cams/*"]);
    OutputDir::create(&target, &plan).unwrap().commit().unwrap();
    std::fs::write(target.join("bom.csv"), "user's").unwrap();
    std::fs::write(target.join("notes.csv"), "user's, not in the plan").unwrap();
    let err = check(&target, &plan).unwrap_err().to_string();
    assert!(err.contains("`bom.csv`") && err.contains("did not write"), "{err}");
    std::fs::remove_file(target.join("bom.csv")).unwrap();
    std::fs::create_dir(target.join("cams")).unwrap();
    std::fs::write(target.join("cams/C01.toml"), "user's").unwrap();
    let err = check(&target, &plan).unwrap_err().to_string();
    assert!(err.contains("`cams/C01.toml`"), "{err}");
    std::fs::remove_dir_all(target.join("cams")).unwrap();
    drop(check(&target, &plan).unwrap());
    // A file that appears while the command works is still caught when the files are swapped in.
    let out = OutputDir::create(&target, &plan).unwrap();
    std::fs::write(target.join("bom.csv"), "user's, written during the run").unwrap();
    out.write("bom.csv", "ours").unwrap();
    let err = out.commit().unwrap_err().to_string();
    assert!(err.contains("bom.csv") && err.contains("did not write"), "{err}");
    assert_eq!(std::fs::read_to_string(target.join("bom.csv")).unwrap(), "user's, written during the run");
    assert_eq!(std::fs::read_to_string(target.join("notes.csv")).unwrap(), "user's, not in the plan");
    assert_eq!(listing(&root), vec!["out"]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn an_edited_file_is_refused_unless_the_edits_may_go() {
    let root = scratch("edited");
    let target = root.join("out");
    let plan = Plan::new("fit", ["bom.csv", "summary.json", "stale.txt"]);
    let out = OutputDir::create(&target, &plan).unwrap();
    out.write("bom.csv", "id,stiffness\nS01,3\n").unwrap();
    out.write("summary.json", "{}").unwrap();
    out.write("stale.txt", "old").unwrap();
    out.commit().unwrap();
    let m = Manifest::read(&target).unwrap().unwrap();
    assert_eq!(m.stamps["bom.csv"], Stamp::of(b"id,stiffness\nS01,3\n"));
    // Rewriting a file with the same bytes is no edit; the same size with other bytes is one.
    std::fs::write(target.join("bom.csv"), "id,stiffness\nS01,3\n").unwrap();
    drop(check(&target, &plan).unwrap());
    std::fs::write(target.join("bom.csv"), "id,stiffness\nS01,4\n").unwrap();
    std::fs::write(target.join("stale.txt"), "mine now").unwrap();
    let err = check(&target, &plan).unwrap_err().to_string();
    assert!(
        err.contains("`bom.csv` and `stale.txt` changed since `springfit fit` wrote them")
            && err.contains("--overwrite-edits"),
        "{err}"
    );
    let err = OutputDir::create(&target, &plan).unwrap_err().to_string();
    assert!(err.contains("--overwrite-edits"), "{err}");
    assert_eq!(std::fs::read_to_string(target.join("bom.csv")).unwrap(), "id,stiffness\nS01,4\n");
    // A removed file is no loss.
    std::fs::remove_file(target.join("stale.txt")).unwrap();
    assert!(check(&target, &plan).unwrap_err().to_string().contains("`bom.csv` changed"));
    // With the edits given up, the run replaces them.
    let out = OutputDir::create(&target, &plan.clone().with_edits(Edits::Overwrite)).unwrap();
    out.write("bom.csv", "id,stiffness\nS01,5\n").unwrap();
    out.commit().unwrap();
    assert_eq!(std::fs::read_to_string(target.join("bom.csv")).unwrap(), "id,stiffness\nS01,5\n");
    drop(check(&target, &plan).unwrap());
    assert_eq!(listing(&root), vec!["out"]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_manifest_without_stamps_judges_files_by_their_time() {
    let root = scratch("legacy");
    let target = root.join("out");
    std::fs::create_dir_all(&target).unwrap();
    std::fs::write(target.join("bom.csv"), "old").unwrap();
    std::thread::sleep(std::time::Duration::from_millis(20));
    std::fs::write(target.join(MANIFEST), r#"{"springfit":"0.1.0","command":"fit","files":["bom.csv"]}"#).unwrap();
    let plan = Plan::new("fit", ["bom.csv"]);
    drop(check(&target, &plan).unwrap());
    std::thread::sleep(std::time::Duration::from_millis(20));
    std::fs::write(target.join("bom.csv"), "edited after the manifest").unwrap();
    assert!(check(&target, &plan).unwrap_err().to_string().contains("`bom.csv` changed"));
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_file_outside_the_plan_is_not_committed() {
    let root = scratch("unplanned");
    let target = root.join("out");
    let out = OutputDir::create(&target, &Plan::new("fit", ["bom.csv"])).unwrap();
    out.write("bom.csv", "x").unwrap();
    out.write("surprise.csv", "x").unwrap();
    let err = out.commit().unwrap_err().to_string();
    assert!(err.contains("surprise.csv") && err.contains("without having announced it"), "{err}");
    assert_eq!(listing(&root), Vec::<String>::new());
    assert!(glob(b"sim_a_*", b"sim_a_q.png") && glob(b"cams/*", b"cams/C01.toml") && !glob(b"sim_a_*", b"sim_ab.csv"));
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_failed_run_leaves_the_previous_results() {
    let root = scratch("fail");
    let target = root.join("out");
    let out = OutputDir::create(&target, &any("fit")).unwrap();
    out.write("bom.csv", "previous").unwrap();
    out.commit().unwrap();
    {
        let out = OutputDir::create(&target, &any("fit")).unwrap();
        out.write("bom.csv", "half").unwrap();
        // Dropped without commit: the run failed.
    }
    assert_eq!(std::fs::read_to_string(target.join("bom.csv")).unwrap(), "previous");
    assert_eq!(listing(&root), vec!["out"]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn keep_previous_copies_only_listed_files() {
    let root = scratch("keep");
    let target = root.join("out");
    let out = OutputDir::create(&target, &any("simulate")).unwrap();
    out.write("sim_a.csv", "a1").unwrap();
    out.write("sim_b.csv", "b1").unwrap();
    out.commit().unwrap();
    std::fs::write(target.join("sim_user.csv"), "user").unwrap();
    let mut out = OutputDir::create(&target, &Plan::new("simulate", ["sim_a.csv"])).unwrap();
    out.keep_previous(|n| n != "sim_a.csv").unwrap();
    out.write("sim_a.csv", "a2").unwrap();
    out.commit().unwrap();
    assert_eq!(std::fs::read_to_string(target.join("sim_a.csv")).unwrap(), "a2");
    assert_eq!(std::fs::read_to_string(target.join("sim_b.csv")).unwrap(), "b1");
    assert_eq!(std::fs::read_to_string(target.join("sim_user.csv")).unwrap(), "user");
    assert_eq!(Manifest::read(&target).unwrap().unwrap().files, vec!["sim_a.csv", "sim_b.csv"]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn an_unwritable_place_names_the_path() {
    let root = scratch("unwritable");
    let file = root.join("plain-file");
    std::fs::write(&file, "x").unwrap();
    let err = OutputDir::create(&file.join("out"), &any("fit")).unwrap_err().to_string();
    assert!(err.contains("plain-file"), "{err}");
    let err = OutputDir::create(&file, &any("fit")).unwrap_err().to_string();
    assert!(err.contains("not a folder"), "{err}");
    let _ = std::fs::remove_dir_all(&root);
}

/// `plan` for a run of the design file `path` whose text has the fingerprint `fnv1a64`.
fn of_design(plan: Plan, path: &str, fnv1a64: &str) -> Plan {
    Plan { design: Some(DesignRecord { path: path.into(), fnv1a64: fnv1a64.into() }), ..plan }
}

#[test]
fn another_design_does_not_replace_a_designs_results() {
    let root = scratch("design");
    let target = root.join("out");
    let original = of_design(any("fit"), "/d/double_pendulum.toml", "00000000000000aa");
    let out = OutputDir::create(&target, &original).unwrap();
    out.write("bom.csv", "original").unwrap();
    out.commit().unwrap();
    let m = Manifest::read(&target).unwrap().unwrap();
    assert_eq!(m.design.as_ref().map(|d| d.path.as_str()), Some("/d/double_pendulum.toml"));
    // A copy with one key changed: another file, other contents.
    let copy = of_design(any("fit"), "/d/mine.toml", "00000000000000bb");
    let err = OutputDir::create(&target, &copy).unwrap_err().to_string();
    assert!(
        err.contains("results of the design /d/double_pendulum.toml")
            && err.contains("this run is of /d/mine.toml")
            && err.contains("--out"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(target.join("bom.csv")).unwrap(), "original");
    // The same file edited (the usual way to iterate), and a copy with the same text, may.
    for plan in [
        of_design(any("fit"), "/d/double_pendulum.toml", "00000000000000cc"),
        of_design(any("fit"), "/elsewhere/renamed.toml", "00000000000000cc"),
    ] {
        let out = OutputDir::create(&target, &plan).unwrap();
        out.write("bom.csv", "iterated").unwrap();
        out.commit().unwrap();
    }
    // The manifest records the last run's design: the original's text is no longer it.
    let err = check(&target, &original).unwrap_err().to_string();
    assert!(err.contains("results of the design /elsewhere/renamed.toml"), "{err}");
    // A folder written before manifests named designs is taken as it is.
    std::fs::write(target.join(MANIFEST), r#"{"springfit":"0.1.0","command":"fit","files":["bom.csv"]}"#).unwrap();
    drop(check(&target, &copy).unwrap());
    assert_eq!(listing(&root), vec!["out"]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_second_run_into_a_claimed_folder_stops_at_once() {
    let root = scratch("lock");
    let target = root.join("nested/out");
    let claim = check(&target, &any("fit")).unwrap();
    // The folders above the target are made to hold the lock, the target itself not yet.
    assert!(root.join("nested").is_dir() && !target.exists());
    let err = check(&target, &any("fit")).unwrap_err().to_string();
    assert!(
        err.contains("another springfit run is writing this folder")
            && err.contains(&format!("process {}", std::process::id())),
        "{err}"
    );
    assert!(OutputDir::create(&target, &any("fit")).is_err());
    // A claim given up without writing leaves nothing behind, not even the folders it made.
    drop(claim);
    assert_eq!(listing(&root), Vec::<String>::new());
    // Held by the open folder until it is committed, then free again.
    let out = check(&target, &any("fit")).unwrap().open().unwrap();
    out.write("a.txt", "1").unwrap();
    assert!(check(&target, &any("fit")).is_err());
    out.commit().unwrap();
    drop(check(&target, &any("fit")).unwrap());
    assert_eq!(listing(&root.join("nested")), vec!["out"], "no lock file left");
    // A lock file left on disk by a killed run holds nothing: the system released its lock.
    std::fs::write(root.join("nested/.out.springfit-lock"), "process 1, `springfit fit`").unwrap();
    let out = OutputDir::create(&target, &any("fit")).unwrap();
    out.write("a.txt", "2").unwrap();
    out.commit().unwrap();
    assert_eq!(std::fs::read_to_string(target.join("a.txt")).unwrap(), "2");
    let _ = std::fs::remove_dir_all(&root);
}
