//! Spatial chains read from URDF: against Pinocchio, against the planar closed forms, and the
//! errors bad URDFs and joint lists give.

use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::{DMatrix, DVector};
use springfit::design::Design;
use springfit::model::urdf;
use springfit::model::{Chain, PlanarChain, SpatialChain};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn ur5() -> PathBuf {
    root().join("robots/ur5/ur5_robot.urdf")
}

fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0_f64, |m, x| m.max(x.abs())).max(1e-300);
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale
}

/// Mass matrix, gravity torque and Coriolis term of the UR5 with two, three, three (other) and all
/// six joints moving, at random configurations, agree with Pinocchio to 1e-9 relative.
#[test]
fn ur5_matches_pinocchio() {
    let text = std::fs::read_to_string(root().join("tests/fixtures/ur5_pinocchio.json")).unwrap();
    let fixtures: serde_json::Value = serde_json::from_str(&text).unwrap();
    let g: Vec<f64> = serde_json::from_value(fixtures["gravity"].clone()).unwrap();
    let mut compared = 0;
    for case in fixtures["cases"].as_array().unwrap() {
        let joints: Vec<String> = serde_json::from_value(case["joints"].clone()).unwrap();
        let locked: Vec<(String, f64)> =
            case["locked"].as_object().unwrap().iter().map(|(k, v)| (k.clone(), v.as_f64().unwrap())).collect();
        let chain = urdf::load(&ur5(), &joints, &locked, [g[0], g[1], g[2]]).unwrap();
        let n = joints.len();
        for p in case["points"].as_array().unwrap() {
            let q: Vec<f64> = serde_json::from_value(p["q"].clone()).unwrap();
            let v: Vec<f64> = serde_json::from_value(p["v"].clone()).unwrap();
            let rows: Vec<Vec<f64>> = serde_json::from_value(p["mass_matrix"].clone()).unwrap();
            let reference = DMatrix::from_fn(n, n, |i, j| rows[i][j]);
            let m = chain.mass_matrix(&DVector::from_vec(q.clone()));
            let e = rel_err(m.as_slice(), reference.as_slice());
            assert!(e < 1e-9, "{joints:?} M at {q:?}: relative error {e:e}\n{m}\nvs\n{reference}");
            let gt: Vec<f64> = serde_json::from_value(p["gravity_torque"].clone()).unwrap();
            let e = rel_err(chain.gravity_gradient(&q).as_slice(), &gt);
            assert!(e < 1e-9, "{joints:?} gravity torque at {q:?}: relative error {e:e}");
            let h: Vec<f64> = serde_json::from_value(p["coriolis"].clone()).unwrap();
            let e = rel_err(chain.coriolis(&DVector::from_vec(q.clone()), &DVector::from_vec(v)).as_slice(), &h);
            assert!(e < 1e-9, "{joints:?} Coriolis at {q:?}: relative error {e:e}");
            compared += 1;
        }
    }
    assert_eq!(compared, 32);
}

/// The paper's double pendulum as a URDF: link 2 is split in two halves joined by a fixed joint
/// turned by 90° (merging must put them back together), a massless tool frame hangs at the tip,
/// and a held joint with value 0 sits before the base.
const DOUBLE_PENDULUM: &str = r#"<?xml version="1.0"?>
<robot name="double_pendulum">
  <link name="world"/>
  <link name="stand">
    <inertial><mass value="5"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
  </link>
  <joint name="stand_turn" type="revolute">
    <parent link="world"/><child link="stand"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <link name="link1">
    <inertial>
      <origin xyz="1 0 0"/><mass value="1"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.9" iyz="0" izz="1"/>
    </inertial>
  </link>
  <joint name="joint1" type="continuous">
    <parent link="stand"/><child link="link1"/><axis xyz="0 0 1"/>
  </joint>
  <link name="link2a">
    <inertial>
      <origin xyz="0.5 0 0"/><mass value="0.5"/>
      <inertia ixx="0.075" ixy="0" ixz="0" iyy="0.3" iyz="0" izz="0.375"/>
    </inertial>
  </link>
  <joint name="joint2" type="revolute">
    <origin xyz="2 0 0"/>
    <parent link="link1"/><child link="link2a"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <link name="link2b">
    <inertial>
      <origin xyz="0 -0.5 0"/><mass value="0.5"/>
      <inertia ixx="0.3" ixy="0" ixz="0" iyy="0.075" iyz="0" izz="0.375"/>
    </inertial>
  </link>
  <joint name="split" type="fixed">
    <origin xyz="1 0 0" rpy="0 0 1.5707963267948966"/>
    <parent link="link2a"/><child link="link2b"/>
  </joint>
  <link name="tool"/>
  <joint name="tool_joint" type="fixed">
    <origin xyz="2 0 0"/><parent link="link2a"/><child link="tool"/>
  </joint>
</robot>
"#;

fn double_pendulum(gravity: [f64; 3]) -> SpatialChain {
    let joints = ["joint1".to_string(), "joint2".to_string()];
    urdf::parse(Path::new("double_pendulum.urdf"), DOUBLE_PENDULUM, &joints, &[], gravity).unwrap()
}

fn points(n: usize, count: usize) -> Vec<DVector<f64>> {
    let mut state = 0x2545_F491_4F6C_DD1D_u64;
    (0..count)
        .map(|_| {
            DVector::from_fn(n, |_, _| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state as f64 / u64::MAX as f64) * 6.0 - 3.0
            })
        })
        .collect()
}

#[test]
fn double_pendulum_urdf_equals_the_toml_model() {
    let design = Design::load(&root().join("designs/double_pendulum.toml")).unwrap();
    let Chain::Planar(planar) = &design.chain else { panic!("the paper's design is planar") };
    // Both take gravity as the physical acceleration: the same arm in a vertical plane with y up
    // is (0, −9.81) planar and (0, −9.81, 0) from the URDF.
    let with_gravity = PlanarChain::new(planar.links().to_vec(), [0.0, -9.81]);
    for (planar, spatial) in [(planar, double_pendulum([0.0; 3])), (&with_gravity, double_pendulum([0.0, -9.81, 0.0]))]
    {
        for pair in points(2, 20).chunks(2) {
            let (q, qd) = (&pair[0], &pair[1]);
            assert!((planar.mass_matrix(q) - spatial.mass_matrix(q)).amax() < 1e-12);
            for (a, b) in planar.christoffel(q).iter().zip(spatial.christoffel(q)) {
                assert!((a - b).amax() < 1e-12);
            }
            assert!((planar.coriolis(q, qd) - spatial.coriolis(q, qd)).amax() < 1e-12);
            let qs = q.as_slice();
            assert!((planar.gravity_potential(qs) - spatial.gravity_potential(qs)).abs() < 1e-12);
            assert!((planar.gravity_gradient(qs) - spatial.gravity_gradient(qs)).amax() < 1e-12);
            assert!((planar.gravity_hessian(qs) - spatial.gravity_hessian(qs)).amax() < 1e-12);
        }
    }
    // The tool frame is the tip that is drawn.
    let tip = double_pendulum([0.0; 3]).joint_positions(&[0.0, std::f64::consts::FRAC_PI_2]);
    let last = tip[tip.len() - 1];
    assert!((last[0] - 2.0).abs() < 1e-12 && (last[1] - 2.0).abs() < 1e-12, "{last:?}");
}

/// The shipped designs load, their mass matrices are symmetric positive definite on random
/// configurations, and the springs must carry the arm's weight (gravity torque at q_eq).
#[test]
fn shipped_ur5_designs_load() {
    for (name, n) in [("ur5_lift_elbow", 2), ("ur5_pan_lift_elbow", 3)] {
        let design = Design::load(&root().join(format!("designs/{name}.toml"))).unwrap();
        assert_eq!(design.dof(), n);
        assert!(design.chain.spatial().is_some());
        for q in points(n, 20) {
            let m = design.chain.mass_matrix(&q);
            assert!((&m - m.transpose()).amax() < 1e-15);
            assert!(m.symmetric_eigen().eigenvalues.min() > 0.0);
        }
        assert!(design.chain.gravity_gradient(design.q_eq.as_slice()).amax() > 10.0);
    }
}

/// Writes a design naming `urdf_text` (saved beside it) and returns the error text.
fn design_error(tag: &str, urdf_text: &str, robot: &str, q: &str) -> String {
    let dir = std::env::temp_dir().join(format!("springfit-urdf-{}-{tag}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("arm.urdf"), urdf_text).unwrap();
    let text = format!(
        "[robot]\nurdf = \"arm.urdf\"\n{robot}\n[equilibrium]\nq = {q}\n[region]\nkind = \"ball\"\nradius = 0.5\n"
    );
    let path = dir.join("design.toml");
    std::fs::write(&path, &text).unwrap();
    let err = Design::load(&path).err().map(|e| e.to_string()).unwrap_or_else(|| "loaded".into());
    std::fs::remove_dir_all(&dir).unwrap();
    err
}

#[test]
fn bad_urdfs_and_joint_lists_give_one_clear_error_each() {
    let dp = DOUBLE_PENDULUM;
    let two = "joints = [\"joint1\", \"joint2\"]";
    let prismatic =
        dp.replace("<joint name=\"joint2\" type=\"revolute\">", "<joint name=\"joint2\" type=\"prismatic\">");
    let no_inertial = dp.replacen(
        "<inertial>\n      <origin xyz=\"1 0 0\"/><mass value=\"1\"/>\n      <inertia ixx=\"0.1\" ixy=\"0\" ixz=\"0\" iyy=\"0.9\" iyz=\"0\" izz=\"1\"/>\n    </inertial>",
        "",
        1,
    );
    let mimic = dp.replace(
        "<limit lower=\"-3\" upper=\"3\" effort=\"1\" velocity=\"1\"/>",
        "<limit lower=\"-3\" upper=\"3\" effort=\"1\" velocity=\"1\"/><mimic joint=\"joint1\" multiplier=\"1\"/>",
    );
    let branch = dp
        .replace("<parent link=\"link2a\"/><child link=\"tool\"/>", "<parent link=\"link1\"/><child link=\"tool\"/>")
        .replace(
            "<joint name=\"tool_joint\" type=\"fixed\">",
            "<joint name=\"tool_joint\" type=\"continuous\"><axis xyz=\"0 0 1\"/>",
        );
    let cycle = dp.replace(
        "</robot>",
        "<link name=\"c1\"/><link name=\"c2\"/>\
         <joint name=\"jc1\" type=\"continuous\"><parent link=\"c1\"/><child link=\"c2\"/><axis xyz=\"0 0 1\"/></joint>\
         <joint name=\"jc2\" type=\"continuous\"><parent link=\"c2\"/><child link=\"c1\"/><axis xyz=\"0 0 1\"/></joint>\
         </robot>",
    );
    let cases: Vec<(&str, String, String, &str, &str)> = vec![
        ("loop", cycle, "joints = [\"jc1\"]".into(), "<joint name=\"jc1\">", "cannot be reached"),
        ("missing", dp.into(), "joints = [\"joint1\", \"elbow\"]".into(), "<joint name=\"elbow\">", "no such joint"),
        ("prismatic", prismatic, two.into(), "<joint name=\"joint2\">", "is prismatic"),
        ("fixed", dp.into(), "joints = [\"joint1\", \"split\"]".into(), "<joint name=\"split\">", "only revolute"),
        ("order", dp.into(), "joints = [\"joint2\", \"joint1\"]".into(), "not one chain", "joint"),
        (
            "branch",
            branch,
            "joints = [\"joint1\", \"joint2\", \"tool_joint\"]".into(),
            "<joint name=\"tool_joint\">",
            "not one chain",
        ),
        ("inertial", no_inertial, two.into(), "<link name=\"link1\">", "no inertial data"),
        ("mimic", mimic, two.into(), "<joint name=\"joint2\">", "mimic"),
        ("locked", dp.into(), format!("{two}\nlocked = {{ wrist = 0.0 }}"), "<joint name=\"wrist\">", "no such joint"),
        ("both", dp.into(), format!("{two}\nlocked = {{ joint1 = 0.0 }}"), "<joint name=\"joint1\">", "both chosen"),
        ("syntax", dp.replace("</robot>", ""), two.into(), "arm.urdf", "cannot be read as a URDF"),
        ("gravity", dp.into(), format!("{two}\ngravity = [0.0, -9.81]"), "robot.gravity", "3 numbers"),
        (
            "links",
            dp.into(),
            format!("{two}\n[[robot.links]]\nmass = 1.0\nlength = 1.0\ncom = 0.5\ninertia = 0.1"),
            "robot.links",
            "not both",
        ),
        ("count", dp.into(), two.into(), "equilibrium.q", "names 2 joints"),
    ];
    for (tag, urdf_text, robot, element, reason) in cases {
        let q = if tag == "count" {
            "[0.0]"
        } else if robot.contains("tool_joint") {
            "[0.0, 0.5, 0.0]"
        } else {
            "[0.0, 0.5]"
        };
        let err = design_error(tag, &urdf_text, &robot, q);
        assert!(err.contains(element) && err.contains(reason), "{tag}: expected {element} / {reason} in: {err}");
        let file = if ["gravity", "links", "count"].contains(&tag) { "design.toml" } else { "arm.urdf" };
        assert!(err.contains(file), "{tag}: the error must name {file}: {err}");
    }
    // The good file with the same template loads.
    assert_eq!(design_error("good", dp, two, "[0.0, 0.5]"), "loaded");
}

/// `springfit check --json` prints one object with the model at the equilibrium.
#[test]
fn check_json_prints_the_model() {
    let out = Command::new(env!("CARGO_BIN_EXE_springfit"))
        .args(["check", "designs/ur5_lift_elbow.toml", "--json"])
        .current_dir(root())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["dof"], 2);
    assert_eq!(v["joints"], serde_json::json!(["shoulder_lift_joint", "elbow_joint"]));
    let design = Design::load(&root().join("designs/ur5_lift_elbow.toml")).unwrap();
    let m = design.chain.mass_matrix(&design.q_eq);
    let g = design.chain.gravity_gradient(design.q_eq.as_slice());
    for i in 0..2 {
        assert_eq!(v["q_eq"][i].as_f64().unwrap(), design.q_eq[i]);
        assert_eq!(v["gravity_torque"][i].as_f64().unwrap(), g[i]);
        for j in 0..2 {
            assert_eq!(v["mass_matrix"][i][j].as_f64().unwrap(), m[(i, j)]);
        }
    }
    assert_eq!(v["region"]["valid"], true);
}
