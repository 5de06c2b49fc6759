//! Regions that fit a real arm: the URDF's joint limits read, the equilibrium, a box and a ball
//! checked against them, a ball clipped at them on request, and `springfit init` writing a design
//! that passes its own check.

mod util;

use std::path::{Path, PathBuf};
use std::process::Command;

use springfit::design::Design;
use springfit::geodesic::region::RegionFailure;
use springfit::geodesic::{Fan, FanSpec, Region, Stop};
use springfit::model::urdf::{self, JointRange};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn panda() -> PathBuf {
    root().join("robots/panda/panda.urdf")
}

/// The Panda's joints 2, 4 and 6 (parallel with 1, 3, 5 and 7 at zero) in gravity, written
/// into `robots/` so that the URDF path is relative to the design.
fn panda_design(q: &str, region: &str) -> String {
    format!(
        r#"
name = "panda_test"
[robot]
urdf = "panda/panda.urdf"
joints = ["panda_joint2", "panda_joint4", "panda_joint6"]
gravity = [0.0, 0.0, -9.81]
[equilibrium]
q = {q}
[region]
{region}
[fit]
frequency = 6.0
"#
    )
}

fn load(text: &str) -> springfit::Result<Design> {
    Design::parse(&root().join("robots/panda_test.toml"), text)
}

#[test]
fn the_moving_joints_limits_are_read() {
    let joints: Vec<String> = ["panda_joint2", "panda_joint4", "panda_joint6"].map(String::from).to_vec();
    let (_, ranges) = urdf::load_with_ranges(&panda(), &joints, &[], [0.0, 0.0, -9.81]).unwrap();
    assert_eq!(
        ranges,
        vec![
            JointRange::Limited { lower: -1.7628, upper: 1.7628 },
            JointRange::Limited { lower: -3.0718, upper: -0.0698 },
            JointRange::Limited { lower: -0.0175, upper: 3.7525 },
        ]
    );
}

#[test]
fn an_equilibrium_outside_a_limit_is_refused_naming_the_joint() {
    let e = load(&panda_design("[0.0, 0.0, 1.5]", "kind = \"ball\"\nradius = 0.1")).unwrap_err().to_string();
    assert!(e.contains("equilibrium.q[1]") && e.contains("panda_joint4") && e.contains("-3.0718"), "{e}");
}

#[test]
fn a_held_joint_outside_its_limits_is_refused() {
    // Joint 4 not moving is held at 0, outside its limits [-3.0718, -0.0698].
    let text = panda_design("[0.0, 1.5]", "kind = \"ball\"\nradius = 0.1").replace(
        r#"joints = ["panda_joint2", "panda_joint4", "panda_joint6"]"#,
        r#"joints = ["panda_joint2", "panda_joint6"]"#,
    );
    let e = load(&text).unwrap_err().to_string();
    assert!(e.contains("panda_joint4") && e.contains("outside its <limit>"), "{e}");
}

#[test]
fn a_box_beyond_a_limit_is_refused_or_clipped() {
    let region = "kind = \"box\"\nlower = [-0.5, -2.0, 0.5]\nupper = [0.5, -1.0, 4.0]";
    let e = load(&panda_design("[0.0, -1.5, 1.5]", region)).unwrap_err().to_string();
    assert!(e.contains("region.upper[2]") && e.contains("panda_joint6") && e.contains("within_joint_limits"), "{e}");
    let clipped = load(&panda_design("[0.0, -1.5, 1.5]", &format!("{region}\nwithin_joint_limits = true"))).unwrap();
    match clipped.region {
        Region::Box { upper, .. } => assert_eq!(upper[2], 3.7525),
        other => panic!("{other:?}"),
    }
}

/// A ball that swings the light wrist past its stop is refused, naming the joint and the radius
/// that fits; the same ball with `within_joint_limits` is valid and every fan stops at the limit.
#[test]
fn a_ball_past_a_limit_is_refused_and_clipped_on_request() {
    let design = load(&panda_design("[0.0, -1.5, 1.5]", "kind = \"ball\"\nradius = 0.6")).unwrap();
    let report = design.region_report().unwrap();
    assert!(!report.valid, "{}", report.reason);
    let Some(RegionFailure::JointLimit { joint, s, .. }) = &report.failure else { panic!("{:?}", report.failure) };
    assert!(joint.starts_with("panda_joint") && *s < 0.6, "{joint} {s}");
    let e = design.valid_region().unwrap_err().to_string();
    assert!(e.contains("region.radius") && e.contains(joint.as_str()) && e.contains("within_joint_limits"), "{e}");
    assert!(report.limited_by.iter().any(|f| f.kind() == "joint limit"));

    let clipped =
        load(&panda_design("[0.0, -1.5, 1.5]", "kind = \"ball\"\nradius = 0.6\nwithin_joint_limits = true")).unwrap();
    assert!(matches!(clipped.region, Region::Clipped { .. }));
    let report = clipped.region_report().unwrap();
    assert!(report.valid, "{}", report.reason);
    let limits = clipped.joint_limits().unwrap();
    let spec = FanSpec {
        count: 200,
        phase: 0.0,
        stop: Stop::Region { region: &clipped.region, max_arc: clipped.geodesics.max_arc },
        spacing: 0.02,
    };
    let fan = Fan::trace(&clipped.chain, &clipped.q_eq, spec, clipped.geodesics.ode).unwrap();
    let mut stopped = 0;
    for g in &fan.geodesics {
        for k in 0..g.len() {
            for (j, x) in g.q(k).iter().enumerate() {
                assert!(*x >= limits.lower[j] - 1e-9 && *x <= limits.upper[j] + 1e-9, "q{j} = {x}");
            }
        }
        assert!(g.length() <= 0.6 + 1e-12);
        stopped += usize::from(g.length() < 0.6 - 1e-9);
    }
    assert!(stopped > 0, "no geodesic reached a limit");
}

#[test]
fn a_moving_joint_without_limits_is_assumed_free_with_a_warning() {
    let dir = std::env::temp_dir().join(format!("springfit-limits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let urdf = util::UNLIMITED_J1_URDF;
    std::fs::write(dir.join("two.urdf"), urdf).unwrap();
    let text = r#"
name = "two"
[robot]
urdf = "two.urdf"
joints = ["j1", "j2"]
gravity = [0.0, 0.0, -9.81]
[equilibrium]
q = [0.5, 0.5]
[region]
kind = "ball"
radius = 0.3
"#;
    let design = Design::parse(&dir.join("two.toml"), text).unwrap();
    assert_eq!(design.joint_ranges[0], JointRange::Unstated);
    let validated = springfit::design::validate::validate(&design).unwrap();
    let warning = validated.warnings.iter().map(|w| w.to_string()).find(|w| w.contains("j1")).unwrap_or_default();
    assert!(warning.contains("robot.joints[0]") && warning.contains("turns without a stop"), "{warning}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `springfit init` on the Panda: a design inside the limits that passes `check`, which then
/// names what limits its region and gravity's figures.
#[test]
fn init_writes_a_design_that_checks() {
    let dir = std::env::temp_dir().join(format!("springfit-init-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("panda3.toml");
    let init = Command::new(env!("CARGO_BIN_EXE_springfit"))
        .args(["init", out.to_str().unwrap(), "--urdf", panda().to_str().unwrap()])
        .args(["--joints", "panda_joint2,panda_joint4,panda_joint6"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&init.stdout);
    assert!(init.status.success(), "{}{}", stdout, String::from_utf8_lossy(&init.stderr));
    assert!(stdout.contains("region.radius") && stdout.contains("fit.frequency"), "{stdout}");
    assert!(dir.join("panda3_catalog.toml").exists());
    let design = Design::load(&out).unwrap();
    // Joint 4's zero and joint 6's are at or next to their stops: both start in the middle.
    assert!((design.q_eq[1] - 0.5 * (-3.0718 - 0.0698)).abs() < 1e-12);
    assert!((design.q_eq[2] - 0.5 * (-0.0175 + 3.7525)).abs() < 1e-12);
    let check = Command::new(env!("CARGO_BIN_EXE_springfit")).arg("check").arg(&out).output().unwrap();
    let text = String::from_utf8_lossy(&check.stdout);
    assert!(check.status.success(), "{}{}", text, String::from_utf8_lossy(&check.stderr));
    assert!(text.contains("limited by the") && text.contains("suggested region.radius"), "{text}");
    assert!(text.contains("gravity at the equilibrium"), "{text}");
    // A second init does not replace the design.
    let again = Command::new(env!("CARGO_BIN_EXE_springfit"))
        .args(["init", out.to_str().unwrap(), "--urdf", panda().to_str().unwrap()])
        .args(["--joints", "panda_joint2,panda_joint4,panda_joint6"])
        .output()
        .unwrap();
    assert!(!again.status.success());
    std::fs::remove_dir_all(&dir).ok();
}
