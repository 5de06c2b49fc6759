//! `springfit export --mujoco` and the MuJoCo verification script (`scripts/verify_mujoco.py`).
//!
//! The MuJoCo runs need Python with `mujoco` (≥ 3.7) and `numpy`; `.ci/run` installs them. On a
//! machine without them those tests say why they skipped and pass.

mod util;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use util::{repo, springfit, temp_dir};

/// Why MuJoCo cannot be run here, or None when it can.
fn mujoco_missing() -> Option<String> {
    match Command::new("python3").args(["-c", "import mujoco, numpy"]).output() {
        Err(e) => Some(format!("python3 cannot be started ({e})")),
        Ok(o) if !o.status.success() => Some(format!(
            "python3 cannot import mujoco and numpy ({}); install them with `python3 -m pip install 'mujoco>=3.7' numpy`",
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("").trim()
        )),
        Ok(_) => None,
    }
}

fn verify(dir: &Path, xml: &Path, csv: &str) -> (i32, String) {
    let out = Command::new("python3")
        .arg(repo().join("scripts/verify_mujoco.py"))
        .arg(xml)
        .arg(csv)
        .current_dir(dir)
        .output()
        .expect("run python3");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    (out.status.code().unwrap_or(-1), text)
}

/// The bill of materials `springfit fit` writes for the shipped design `name` (`name.toml`),
/// fitted once for all the tests of this file, without the Monte Carlo builds (they change no
/// spring): each test copies it.
fn fitted_bom(name: &str) -> PathBuf {
    static FITS: Mutex<BTreeMap<String, PathBuf>> = Mutex::new(BTreeMap::new());
    let mut fits = FITS.lock().unwrap();
    let bom = fits.entry(name.to_string()).or_insert_with(|| {
        let dir = temp_dir("mujoco-fit");
        let stem = name.trim_end_matches(".toml");
        let design = util::with_builds(&dir, stem, 0);
        springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "fit"]).ok();
        dir.join("fit/bom.csv")
    });
    bom.clone()
}

/// Fits, exports and simulates the free releases of a design with one bill of materials, then
/// replays them in MuJoCo; returns the script's output.
fn fit_export_verify(design: &str) -> Option<(String, String)> {
    fit_export_verify_with(design, "")
}

/// As [`fit_export_verify`], with `extra` rows appended to the fitted bill of materials.
fn fit_export_verify_with(design: &str, extra: &str) -> Option<(String, String)> {
    if let Some(why) = mujoco_missing() {
        eprintln!("SKIPPED: MuJoCo verification of {design}: {why}");
        return None;
    }
    let dir = temp_dir("mujoco");
    let name = design.trim_end_matches(".toml");
    // Extra elements move the springs' equilibrium off q_eq on purpose: the design lets such a
    // bill through (`[equilibrium] bill_tolerance`).
    let d = if extra.is_empty() {
        repo().join("designs").join(design)
    } else {
        util::design_variant(&dir, name, &[("equilibrium.bill_tolerance", toml::Value::Float(10.0))])
    };
    let d = d.to_str().unwrap();
    let bom = std::fs::read_to_string(fitted_bom(design)).unwrap();
    util::write(&dir, "fit/bom.csv", &(bom + extra));
    let run = springfit(&dir, &["export", d, "--bom", "fit/bom.csv", "--mujoco", "--out", "mj"]).ok();
    springfit(&dir, &["simulate", d, "--bom", "fit/bom.csv", "--scenario", "free", "--out", "sim"]).ok();
    let xml = dir.join("mj").join(format!("{name}.xml"));
    let (code, text) = verify(&dir, &xml, "sim/sim_free.csv");
    println!("{text}");
    assert_eq!(code, 0, "MuJoCo disagrees with springfit\n{text}\n{}", run.report());
    let last = text.lines().find(|l| l.starts_with("PASS")).expect("a PASS line").to_string();
    // The script's tolerance is 1e-4 / 1e-3 rad; the two RK4 runs should agree to rounding.
    let largest: f64 = last.split("largest difference ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert!(largest < 1e-9, "{last}");
    Some((text, std::fs::read_to_string(dir.join("mj/elements.md")).unwrap()))
}

/// Exports and simulates the free releases of a URDF design with its fitted bill of materials
/// kept in `tests/data/<design>_bom.csv` (what `springfit fit` wrote for it: the test is about the
/// export, so it does not refit), replays them in MuJoCo and returns the script's output and
/// `elements.md`.
fn export_verify_fitted(design: &str) -> Option<(String, String)> {
    if let Some(why) = mujoco_missing() {
        eprintln!("SKIPPED: MuJoCo verification of {design}: {why}");
        return None;
    }
    let dir = temp_dir("mujoco-urdf");
    let d = repo().join("designs").join(format!("{design}.toml"));
    let d = d.to_str().unwrap();
    let bom = repo().join("tests/data").join(format!("{design}_bom.csv"));
    let bom = bom.to_str().unwrap();
    let run = springfit(&dir, &["export", d, "--bom", bom, "--mujoco", "--out", "mj"]).ok();
    springfit(&dir, &["simulate", d, "--bom", bom, "--scenario", "free", "--out", "sim"]).ok();
    let (code, text) = verify(&dir, &dir.join("mj").join(format!("{design}.xml")), "sim/sim_free.csv");
    println!("{text}");
    assert_eq!(code, 0, "MuJoCo disagrees with springfit\n{text}\n{}", run.report());
    let last = text.lines().find(|l| l.starts_with("PASS")).expect("a PASS line").to_string();
    let largest: f64 = last.split("largest difference ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert!(largest < 1e-9, "{last}");
    Some((text, std::fs::read_to_string(dir.join("mj/elements.md")).unwrap()))
}

#[test]
fn mujoco_reproduces_the_ur5_in_a_vertical_plane() {
    // Two joints of the URDF moving, four held (wrist 1 at −π/2): joint springs, tendons, cranks
    // as spatial tendons about the URDF's axes, dead bands and callbacks.
    let Some((text, md)) = export_verify_fitted("ur5_lift_elbow") else { return };
    assert!(text.contains("2 joints") && text.contains("3 runs over 5"), "{text}");
    assert!(md.contains("`q1` = `shoulder_lift_joint`") && md.contains("spatial tendon"), "{md}");
    assert!(md.contains("dead band") && md.contains("callback |"), "{md}");
}

#[test]
fn mujoco_reproduces_the_ur5_in_space() {
    // Three joints with non-parallel axes (the pan axis vertical, lift and elbow horizontal).
    let Some((text, md)) = export_verify_fitted("ur5_pan_lift_elbow") else { return };
    assert!(text.contains("3 joints") && text.contains("3 runs over 5"), "{text}");
    assert!(md.contains("`q1` = `shoulder_pan_joint`"), "{md}");
}

#[test]
fn mujoco_reproduces_the_five_link_pendulum_on_tendons() {
    // designs/pendulum5_tendons.toml as fitted (its bill in tests/data): five joints, every
    // coupling of two to five consecutive joints a fixed tendon whose coefficients are its pulley
    // radii, the springs on its joints and tendons exact, its cranks by callback.
    let Some((text, md)) = export_verify_fitted("pendulum5_tendons") else { return };
    assert!(text.contains("5 joints") && text.contains("3 runs over 5"), "{text}");
    let tendons = md.lines().filter(|l| l.contains("tendon over pulleys: fixed tendon")).count();
    assert!(tendons > 100, "{tendons} fixed tendons\n{md}");
}

#[test]
fn mujoco_reproduces_the_default_design() {
    let Some((text, md)) = fit_export_verify("double_pendulum.toml") else { return };
    assert!(text.contains("6 runs over 5"), "{text}");
    assert!(md.contains("exact") && md.contains("callback"), "{md}");
}

/// 193 springs of every profile (13 s of CPU): with the full matrix, `-- --ignored`. Every
/// profile is replayed in the default suite by the default design and
/// `offsets_of_minus_one_are_not_read_as_mujocos_default`.
#[test]
#[ignore = "the dense design's 193 springs in MuJoCo, with the full matrix"]
fn mujoco_reproduces_the_dense_design() {
    let Some((text, _)) = fit_export_verify("double_pendulum_dense.toml") else { return };
    assert!(text.contains("6 runs over 5"), "{text}");
}

#[test]
fn offsets_of_minus_one_are_not_read_as_mujocos_default() {
    // MuJoCo reads a single springlength of exactly -1 as "the length at qpos_spring": the
    // export negates such tendons. Every kind of element at x0 = -1, added to the fitted springs.
    let extra = "X1,extra,linear,,1;-2,-1,0.5,N*m/rad,0,0,,0,,,,,,\n\
X2,extra,cubic,,1;1,-1,0.5,N*m/rad^3,0,0,,0,,,,,,\n\
X3,extra,compression,+,0;1,-1,0.5,N*m/rad,0,0,,0,,,,,,\n\
X4,extra,compression,-,1;0,-1,0.5,N*m/rad,0,0,,0,,,,,,\n\
X5,extra,crank,,1;0,-1,0.5,N*m,0,0,,0,,,,,,\n";
    let Some((_, md)) = fit_export_verify_with("double_pendulum.toml", extra) else { return };
    assert!(md.contains("| X1 |") && md.contains("coef = −a"), "{md}");
}

#[test]
fn mujoco_reproduces_tendon_couplings() {
    // Couplings only a tendon makes (1 : 0.7 and 0.3 : 1 are no bevel ratios): fixed tendons whose
    // coefficients are the pulley radii, linear, cubic and both dead bands, added to the fitted
    // springs, replayed to 1e-9 rad like every exact element.
    let extra = "T1,extra,linear,,1;0.7,0.3,0.5,N*m/rad,0,0,,0,,,,,,\n\
T2,extra,cubic,,0.3;-1,0.2,0.5,N*m/rad^3,0,0,,0,,,,,,\n\
T3,extra,compression,+,1;0.7,-0.1,0.5,N*m/rad,0,0,,0,,,,,,\n\
T4,extra,compression,-,0.3;-1,0.2,0.5,N*m/rad,0,0,,0,,,,,,\n";
    let Some((_, md)) = fit_export_verify_with("double_pendulum.toml", extra) else { return };
    for id in ["T1", "T2", "T3", "T4"] {
        let line = md.lines().find(|l| l.starts_with(&format!("| {id} |"))).unwrap_or_else(|| panic!("{id}: {md}"));
        assert!(line.contains("tendon over pulleys") && line.contains("ρ = 40 mm"), "{line}");
    }
}

#[test]
fn the_script_fails_when_the_callbacks_are_left_out() {
    if let Some(why) = mujoco_missing() {
        eprintln!("SKIPPED: {why}");
        return;
    }
    let dir = temp_dir("mujoco-wrong");
    let d = repo().join("designs/double_pendulum.toml");
    let d = d.to_str().unwrap();
    std::fs::create_dir_all(dir.join("fit")).unwrap();
    std::fs::copy(fitted_bom("double_pendulum.toml"), dir.join("fit/bom.csv")).unwrap();
    springfit(&dir, &["export", d, "--bom", "fit/bom.csv", "--mujoco", "--out", "mj"]).ok();
    springfit(&dir, &["simulate", d, "--bom", "fit/bom.csv", "--scenario", "free", "--out", "sim"]).ok();
    let xml = std::fs::read_to_string(dir.join("mj/double_pendulum.xml")).unwrap();
    let (a, b) =
        (xml.find("<custom>").expect("the default design has callback cranks"), xml.find("</custom>").unwrap());
    let wrong = format!("{}{}", &xml[..a], &xml[b + "</custom>".len()..]);
    std::fs::write(dir.join("wrong.xml"), wrong).unwrap();
    let (code, text) = verify(&dir, &dir.join("wrong.xml"), "sim/sim_free.csv");
    assert_eq!(code, 1, "a model without its crank callbacks must fail\n{text}");
    assert!(text.contains("FAIL"), "{text}");
}

#[test]
fn export_fits_when_no_bill_is_given_and_writes_its_springs() {
    let dir = temp_dir("export-fit");
    let d = repo().join("designs/double_pendulum.toml");
    let d = d.to_str().unwrap();
    let run = springfit(&dir, &["export", d, "--mujoco", "--out", "mj"]).ok();
    for f in ["double_pendulum.xml", "elements.md", "bom.csv"] {
        assert!(dir.join("mj").join(f).is_file(), "missing {f}\n{}", run.report());
    }
    // The fit is deterministic: the exported springs are those `springfit fit` writes.
    assert_eq!(
        std::fs::read_to_string(dir.join("mj/bom.csv")).unwrap(),
        std::fs::read_to_string(fitted_bom("double_pendulum.toml")).unwrap()
    );
    // Twelve fitted springs and the three trims at their mid-range rate (the drawing).
    assert!(run.stdout().contains("15 springs for MuJoCo"), "{}", run.report());
    let md = std::fs::read_to_string(dir.join("mj/elements.md")).unwrap();
    assert_eq!(md.matches("| S").count(), 15, "{md}");
}

#[test]
fn export_refuses_a_bill_for_another_arm_and_needs_a_format() {
    let dir = temp_dir("export-bad");
    util::write(
        &dir,
        "bom3.csv",
        &format!("{}\nS01,f,linear,,1;0;0,0,1,N*m/rad,0,0,,0,,,,,,\n", springfit::files::bom::HEADER),
    );
    let d = repo().join("designs/double_pendulum.toml");
    let d = d.to_str().unwrap();
    springfit(&dir, &["export", d, "--bom", "bom3.csv", "--mujoco", "--out", "mj"]).fails(2, &["bom3.csv", "3 joints"]);
    assert!(!dir.join("mj").exists());
    let run = springfit(&dir, &["export", d, "--out", "mj"]);
    assert_eq!(run.code(), 2, "{}", run.report());
    assert!(run.stderr().contains("--mujoco"), "{}", run.report());
}
