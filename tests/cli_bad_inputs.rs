//! Inputs that used to pass (or fail with the system's words) and must not: each gets one error
//! naming the file, the field and the reason, exit code 2, and no output folder. Table-driven:
//! one row per input, most of them refused by `check` before any work.

mod util;

use std::path::Path;

use util::{design_text_anywhere, repo, springfit, temp_dir, write};

/// A bad input: the files it writes (name, text), the command line and what the error says.
struct Case {
    name: &'static str,
    files: Vec<(&'static str, String)>,
    args: Vec<String>,
    needles: Vec<&'static str>,
}

fn case(name: &'static str, files: Vec<(&'static str, String)>, args: &[&str], needles: &[&'static str]) -> Case {
    Case { name, files, args: args.iter().map(|s| s.to_string()).collect(), needles: needles.to_vec() }
}

/// The default design, with its catalogue found from anywhere and one substitution.
fn design_with(from: &str, to: &str) -> String {
    let text = design_text_anywhere("double_pendulum.toml");
    assert!(text.contains(from), "`{from}` is not in the default design");
    text.replacen(from, to, 1)
}

/// The UR5 design reading `robot.urdf` beside it, and the UR5 URDF with one substitution.
fn urdf_with(from: &str, to: &str) -> Vec<(&'static str, String)> {
    let urdf = std::fs::read_to_string(repo().join("robots/ur5/ur5_robot.urdf")).unwrap();
    assert!(urdf.contains(from), "`{from}` is not in the UR5 URDF");
    let design =
        design_text_anywhere("ur5_lift_elbow.toml").replace("\"../robots/ur5/ur5_robot.urdf\"", "\"robot.urdf\"");
    vec![("design.toml", design), ("robot.urdf", urdf.replacen(from, to, 1))]
}

/// The paper catalogue with one substitution, and the default design reading it.
fn catalog_with(from: &str, to: &str) -> Vec<(&'static str, String)> {
    let catalog = std::fs::read_to_string(repo().join("catalogs/paper_trim.toml")).unwrap();
    assert!(catalog.contains(from), "`{from}` is not in the catalogue");
    let design = design_text_anywhere("double_pendulum.toml");
    let design = design
        .lines()
        .map(|l| if l.starts_with("catalog =") { "catalog = \"catalog.toml\"".to_string() } else { l.to_string() })
        .collect::<Vec<_>>()
        .join("\n");
    vec![("design.toml", design), ("catalog.toml", catalog.replacen(from, to, 1))]
}

/// The default design's bill of materials (as `fit` writes it) with its data lines edited.
fn bom_with(edit: impl Fn(&mut Vec<Vec<String>>)) -> Vec<(&'static str, String)> {
    let text = std::fs::read_to_string(repo().join("tests/data/double_pendulum_nominal_bom.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let mut rows: Vec<Vec<String>> = lines.map(|l| springfit::files::split_csv_line(l).unwrap()).collect();
    edit(&mut rows);
    let body: Vec<String> = rows.iter().map(|r| r.join(",")).collect();
    vec![
        ("design.toml", design_text_anywhere("double_pendulum.toml")),
        ("bom.csv", format!("{header}\n{}\n", body.join("\n"))),
    ]
}

#[test]
fn inputs_that_passed_are_refused_with_the_file_the_field_and_the_reason() {
    let check = ["check", "design.toml"];
    let export = ["export", "design.toml", "--bom", "bom.csv", "--mujoco", "--out", "out"];
    let cases = vec![
        case(
            "equilibrium angle of 1e300 rad",
            vec![("design.toml", design_with("q = [0.0, \"pi/2\"]", "q = [0.0, 1e300]"))],
            &check,
            &["design.toml", "equilibrium.q", "1e300", "1000 rad"],
        ),
        case(
            "an actuator limit of 0 N·m",
            vec![("design.toml", design_with("max_torque = [10.0, 10.0]", "max_torque = [10.0, 0.0]"))],
            &check,
            &["design.toml", "controllers.max_torque[1]", "> 0 N·m, got 0"],
        ),
        case(
            "one actuator limit for two joints",
            vec![("design.toml", design_with("max_torque = [10.0, 10.0]", "max_torque = [10.0]"))],
            &check,
            &["design.toml", "controllers.max_torque", "1 entries but the robot has 2 joints"],
        ),
        case(
            "actuator limits that cannot hold the arm against gravity",
            vec![("design.toml", design_with("gravity = [0.0, 0.0]", "gravity = [0.0, -9.81]"))],
            &check,
            &["design.toml", "controllers.max_torque[0]", "cannot hold the arm against gravity", "needs 29.430 N·m"],
        ),
        case(
            "a link of 1e200 kg (was: \"singular\")",
            vec![("design.toml", design_with("mass = 1.0", "mass = 1e200"))],
            &check,
            &["design.toml", "robot.links[0].mass", "1e200", "1e6 kg"],
        ),
        case(
            "a catalogue that is a folder (was: \"does not exist\")",
            vec![(
                "design.toml",
                design_text_anywhere("double_pendulum.toml")
                    .lines()
                    .map(|l| {
                        if l.starts_with("catalog =") {
                            format!("catalog = \"{}\"", repo().join("catalogs").display())
                        } else {
                            l.to_string()
                        }
                    })
                    .collect::<Vec<_>>()
                    .join("\n"),
            )],
            &check,
            &["design.toml", "catalog", "is a folder"],
        ),
        case(
            "a URDF inertia with ixx = -5",
            urdf_with("ixx=\"0.22689067591\"", "ixx=\"-5\""),
            &check,
            &["robot.urdf", "<link name=\"upper_arm_link\">", "not positive semi-definite"],
        ),
        case(
            "a URDF link of 1e300 kg",
            urdf_with("<mass value=\"8.393\"/>", "<mass value=\"1e300\"/>"),
            &check,
            &["robot.urdf", "<link name=\"upper_arm_link\">", "1e300", "1e6 kg"],
        ),
        case(
            "a URDF inertia breaking the triangle inequality",
            urdf_with("izz=\"0.0151074\"", "izz=\"0.9\""),
            &check,
            &["robot.urdf", "<link name=\"upper_arm_link\">", "triangle inequality"],
        ),
        case(
            "a coupling family naming a joint the arm does not have",
            catalog_with(
                "couplings = [[1, 0], [0, 1], [1, 1], [1, -1], [1, 2], [2, -1], [2, 1], [1, -2]]",
                "couplings = { all_pairs = [[1, 1]], on = [\"q1\", \"q3\"] }",
            ),
            &check,
            &["catalog.toml", "family[0].couplings.on[1]", "`q3` is not a joint of the arm", "q1, q2"],
        ),
        case(
            "a URDF whose held joint is out of its limits (wrist 1 held at -pi/2, lower limit -1)",
            urdf_with("<limit effort=\"28.0\" lower=\"-6.28318530718\"", "<limit effort=\"28.0\" lower=\"-1.0\""),
            &check,
            &[
                "robot.urdf",
                "<joint name=\"wrist_1_joint\">",
                "-1.5707963267948966 rad",
                "[-1, 6.28318530718]",
                "robot.locked",
            ],
        ),
        case(
            "a URDF with a link defined twice",
            urdf_with("<link name=\"ee_link\">", "<link name=\"forearm_link\"/>\n  <link name=\"ee_link\">"),
            &check,
            &["robot.urdf", "<link name=\"forearm_link\">", "defined twice"],
        ),
        case(
            "a URDF cut short (was: the parser's \"No elements found\")",
            {
                let mut files = urdf_with("<robot", "<robot");
                files[1].1.truncate(3000);
                files
            },
            &check,
            &["robot.urdf", "cannot be read as a URDF", "cut short"],
        ),
        case(
            "a catalogue coupling of 1e308",
            catalog_with("couplings = [[1, 0], [0, 1], [1, 1]", "couplings = [[1e308, 0], [0, 1], [1, 1]"),
            &check,
            &["catalog.toml", "family[0].couplings[0]", "1e308"],
        ),
        case(
            "a trim range up to 1e300",
            catalog_with("trim_range = [", "trim_range = [0.0, 1e300]\n# was: ["),
            &check,
            &["catalog.toml", "trim_range", "1e300"],
        ),
        case(
            "two families of one name",
            catalog_with("name = \"hardening spring\"", "name = \"torsion spring\""),
            &check,
            &["catalog.toml", "family[1].name", "also the name of family[0]"],
        ),
        case(
            "a bill with a row copied twice",
            bom_with(|rows| {
                let first = rows[0].clone();
                rows.insert(1, first);
            }),
            &export,
            &["bom.csv", "line 3: id", "also the id of line 2"],
        ),
        case(
            "a bill with a stiffness of 1e300",
            bom_with(|rows| rows[0][6] = "1e300".into()),
            &export,
            &["bom.csv", "line 2: stiffness", "1e300"],
        ),
        case(
            "a bill whose bad coupling is on line 2 (was: reported on line 3)",
            bom_with(|rows| rows[0][4] = "1;1;1".into()),
            &export,
            &["bom.csv", "line 2: coupling", "3 entries", "other rows have 2"],
        ),
        case(
            "100000 threads (was: thousands of threads and a machine brought down)",
            vec![("design.toml", design_text_anywhere("double_pendulum.toml"))],
            &["--threads", "100000", "check", "design.toml"],
            &["--threads", "at most"],
        ),
    ];
    let dir = temp_dir("bad-inputs");
    for (i, c) in cases.iter().enumerate() {
        let here = dir.join(format!("case{i}"));
        for (name, text) in &c.files {
            write(&here, name, text);
        }
        let args: Vec<&str> = c.args.iter().map(String::as_str).collect();
        let run = springfit(&here, &args);
        eprintln!("{}: {}", c.name, run.stderr().trim());
        let run = run.fails(2, &c.needles);
        assert!(!here.join("out").exists(), "{}: an output folder was written", c.name);
        // Huge numbers in scientific notation, not hundreds of digits.
        let longest = run.stderr().split(|ch: char| !ch.is_ascii_digit()).map(str::len).max().unwrap_or(0);
        assert!(longest < 20, "{}: a number written out in {longest} digits\n{}", c.name, run.report());
    }
}

#[test]
fn output_folders_the_system_refuses_are_named_before_any_work() {
    let dir = temp_dir("bad-out");
    let design = repo().join("designs/double_pendulum.toml");
    let d = design.to_str().unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink("/nonexistent/springfit", dir.join("dangling")).unwrap();
    for (out, needles) in [
        ("dangling", vec!["dangling", "symbolic link", "does not exist"]),
        ("/proc/springfit-out", vec!["/proc/springfit-out", "cannot be created", "choose another --out"]),
    ] {
        if !cfg!(unix) || (out.starts_with("/proc") && !Path::new("/proc/self").exists()) {
            continue;
        }
        let run = springfit(&dir, &["geodesics", d, "--out", out]).fails(2, &needles);
        assert!(run.stdout().is_empty(), "refused before any work\n{}", run.report());
    }
}
