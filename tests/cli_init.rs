//! `springfit init` as a new user runs it: bad input refused with one clear message, exit 2 and
//! no file written (a region outside the joint limits, an equilibrium or a held joint outside
//! them), a URDF joint without limits written with the assumption stated, and init plus fit on
//! a planar three-link arm in gravity (the acceptance of issue 46).

mod util;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn panda() -> PathBuf {
    root().join("robots/panda/panda.urdf")
}

/// `springfit init arm.toml` on the Panda with these joints moving and the extra arguments.
fn init_panda(dir: &Path, joints: &str, extra: &[&str]) -> Output {
    let urdf = panda();
    let mut args = vec!["init", "arm.toml", "--urdf", urdf.to_str().unwrap(), "--joints", joints];
    args.extend_from_slice(extra);
    springfit(dir, &args)
}

/// A fresh folder of its own for one test.
fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("springfit-cli-init-{name}-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn springfit(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_springfit")).current_dir(dir).args(args).output().unwrap()
}

/// The run failed with exit 2 and one error line containing every `words`; the folder holds
/// only `keep`.
fn refused(out: &Output, dir: &Path, words: &[&str], keep: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.contains("error")).collect();
    assert_eq!(errors.len(), 1, "one message: {stderr}");
    for w in words {
        assert!(errors[0].contains(w), "`{w}` missing from: {}", errors[0]);
    }
    let mut left: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    left.sort();
    assert_eq!(left, keep, "files written: {left:?}");
}

#[test]
fn an_equilibrium_outside_the_limits_is_refused_naming_q_and_the_joint() {
    let dir = folder("q");
    // Joint 4's limits are [-3.0718, -0.0698]: 0 is beyond its upper stop.
    let out = init_panda(&dir, "panda_joint2,panda_joint4,panda_joint6", &["--q", "0,0,1.5"]);
    refused(&out, &dir, &["--q", "panda_joint4", "-3.0718", "-0.0698"], &[]);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_held_joint_outside_its_limits_is_refused() {
    let dir = folder("lock");
    let out = init_panda(&dir, "panda_joint2,panda_joint6", &["--lock", "panda_joint4=0"]);
    refused(&out, &dir, &["panda_joint4", "outside its <limit>", "-3.0718"], &[]);
    std::fs::remove_dir_all(&dir).ok();
}

/// init chooses a ball inside the limits; a user who widens it past a joint limit is told by
/// `check` and `fit`, naming the joint and the radius that fits, and `fit` writes nothing.
#[test]
fn a_region_edited_past_a_joint_limit_is_refused_by_check_and_fit() {
    let dir = folder("region");
    let out = init_panda(&dir, "panda_joint2,panda_joint4,panda_joint6", &[]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(dir.join("arm.toml")).unwrap();
    let radius = text.lines().find(|l| l.starts_with("radius = ")).unwrap().to_string();
    std::fs::write(dir.join("arm.toml"), text.replace(&radius, "radius = 2.0")).unwrap();
    for command in ["check", "fit"] {
        let out = springfit(&dir, &[command, "arm.toml", "--out", "out"][..if command == "fit" { 4 } else { 2 }]);
        refused(&out, &dir, &["region.radius", "limit"], &["arm.toml", "arm_catalog.toml"]);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A moving revolute joint whose URDF gives no range: init goes on, assuming it turns freely,
/// and says so on stdout and in the design.
#[test]
fn a_urdf_joint_without_limits_is_written_with_the_assumption_stated() {
    let dir = folder("unlimited");
    let urdf = util::UNLIMITED_J1_URDF;
    std::fs::write(dir.join("two.urdf"), urdf).unwrap();
    let out = springfit(&dir, &["init", "two.toml", "--urdf", "two.urdf", "--joints", "j1,j2"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}{}", String::from_utf8_lossy(&out.stderr));
    let stated = "assumed: joint `j1` turns freely";
    assert!(stdout.contains(stated), "{stdout}");
    assert!(!stdout.contains("joint `j2` turns freely"), "{stdout}");
    assert!(std::fs::read_to_string(dir.join("two.toml")).unwrap().contains(stated));
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 46's acceptance on a planar three-link arm in gravity, as a new user writes it (a
/// human-like arm: upper arm, forearm, hand, uniform rods): `init` then `fit`, nothing edited,
/// reach p99 ≤ 2° as drawn, and the as-built and trimmed figures are numbers (builds without
/// an equilibrium counted as a share and "beyond", never NaN).
#[test]
#[ignore = "a whole fit with its parts, 1,000 builds untrimmed and trimmed: 30–40 s of CPU, minutes on a loaded machine"]
fn init_then_fit_on_a_planar_three_link_arm_in_gravity() {
    let dir = folder("planar");
    let links = "1.5,0.3,0.15,0.01125;1.2,0.25,0.125,0.00625;0.5,0.15,0.075,0.0009375";
    let out = springfit(&dir, &["--quiet", "init", "arm.toml", "--links", links]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let catalogue = std::fs::read_to_string(dir.join("arm_catalog.toml")).unwrap();
    assert_eq!(catalogue.matches("trim = true").count(), 6, "three joints: six trims span the Hessian");
    let out = springfit(&dir, &["--quiet", "fit", "arm.toml", "--out", "out"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(dir.join("out/summary.json")).unwrap();
    let summary: serde_json::Value = serde_json::from_str(&text).unwrap();
    let p99 = summary["residual_deg"]["p99_abs"].as_f64().unwrap();
    assert!(p99 <= 2.0, "drawn p99 {p99}°");
    // init writes trim_sized: this arm's builds need trims stiffer than the target stiffness,
    // the fit around them is far worse (17.4° drawn), so the first fit and its ranges stand.
    assert_eq!(catalogue.lines().filter(|l| *l == "trim_sized = true").count(), 6);
    let sizing = &summary["trim_sizing"];
    let refit = &sizing["refit"];
    let [first, again] = ["first_p99_deg", "refit_p99_deg"].map(|k| refit[k][0].as_f64().unwrap());
    assert!(again > first, "{refit}");
    assert_eq!(refit["kept"], false, "{refit}");
    assert_eq!(sizing["refitted"], false, "{sizing}");
    assert_eq!(p99, first, "the bill is the first fit's");
    // The fit says why: the trim whose builds need most against the target stiffness along it.
    let stderr = String::from_utf8_lossy(&out.stderr);
    let reason = stderr.lines().find(|l| l.contains("the trims keep the ranges the catalogue writes")).expect(&stderr);
    assert!(reason.contains("× the target stiffness ω²/(aᵀM⁻¹a)"), "{reason}");
    assert!(reason.contains("more than the other springs can leave room for"), "{reason}");
    assert!(reason.contains("(now ±5.0 %)"), "{reason}");
    let built = &summary["as_built"];
    for figures in [&built["p99_deg"], &built["trimmed"]["p99_deg"]] {
        for key in ["p50", "p95"] {
            assert!(figures[key].as_f64().is_some_and(f64::is_finite), "{key}: {figures}");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
