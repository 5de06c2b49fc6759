//! `springfit check` and bad designs through the binary: one clear error line, the right exit
//! code.

mod util;

use util::{design_text, design_text_anywhere, repo, springfit, temp_dir, write};

#[test]
fn shipped_designs_pass_the_check() {
    let dir = temp_dir("check-ok");
    for name in
        ["double_pendulum.toml", "double_pendulum_straight.toml", "double_pendulum_folded.toml", "triple_pendulum.toml"]
    {
        let design = repo().join("designs").join(name);
        let run = springfit(&dir, &["check", design.to_str().unwrap()]).ok();
        assert!(run.stdout().contains("largest valid geodesic-ball radius"), "{}", run.report());
        // The triple pendulum's ball (0.6) reaches 79 % of its conjugate limit (0.7613): the
        // check says what that costs. The double pendulum's limit is only the probe: nothing.
        let near = run.stdout().contains("the region reaches 79 % of the largest valid radius");
        assert_eq!(near, name == "triple_pendulum.toml", "{}", run.report());
        // The margin to what limits the region, as a share of its radius: 0.6 / 0.7613 = 79 %.
        let margin = run.stdout().lines().find(|l| l.starts_with("margin to the")).map(str::to_string);
        match name {
            "triple_pendulum.toml" => assert_eq!(
                margin.as_deref(),
                Some(
                    "margin to the conjugate point: the region reaches 0.6000, 79 % of its radius 0.7613 (21 % short of it)"
                ),
                "{}",
                run.report()
            ),
            "double_pendulum.toml" => assert_eq!(margin, None, "only the probe limits it\n{}", run.report()),
            _ => {}
        }
    }
}

#[test]
fn each_bad_design_gets_its_own_clear_error() {
    let dir = temp_dir("check-bad");
    let good = design_text("double_pendulum.toml");
    let malformed = good.replace("[equilibrium]", "[equilibrium");
    let line = malformed.lines().position(|l| l.starts_with("[equilibrium")).unwrap() + 1;
    let malformed_at = format!("malformed.toml:{line}:13");
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        ("malformed.toml", malformed.clone(), vec![malformed_at.as_str(), "unclosed table"]),
        (
            "unknown.toml",
            good.replace("radius = 2.0 ", "radius = 2.0\nspeed = 1 "),
            vec!["unknown.toml:", "unknown field `speed`"],
        ),
        (
            "negative_mass.toml",
            good.replacen("mass = 1.0 ", "mass = -1.0 ", 1),
            vec!["negative_mass.toml", "robot.links[0].mass", "positive"],
        ),
        (
            "outside.toml",
            good.replace("kind = \"ball\"\nradius = 2.0 ", "kind = \"box\"\nlower = [-1.0, 2.0]\nupper = [1.0, 3.0]"),
            vec!["outside.toml", "equilibrium.q[1]", "outside the region"],
        ),
        (
            "dimension.toml",
            good.replace("q = [0.0, \"pi/2\"]", "q = [0.0, 1.0, 2.0]"),
            vec!["dimension.toml", "equilibrium.q", "3 angles", "2 joints"],
        ),
        (
            "wrong_type.toml",
            good.replace("length = 2.0    # m", "length = \"long\"    # m"),
            vec!["wrong_type.toml:", "length"],
        ),
        (
            "nan.toml",
            good.replacen("inertia = 1.0", "inertia = nan", 1),
            vec!["nan.toml", "robot.links[0].inertia", "finite"],
        ),
    ];
    for (name, text, needles) in cases {
        assert_ne!(text, good, "case {name} did not change the design");
        let path = write(&dir, name, &text);
        springfit(&dir, &["check", path.to_str().unwrap()]).fails(2, &needles);
    }
    springfit(&dir, &["check", "missing.toml"]).fails(2, &["missing.toml"]);
}

#[test]
fn a_region_past_the_largest_valid_radius_is_rejected_with_the_radius_that_works() {
    let dir = temp_dir("check-region");
    let text = design_text_anywhere("double_pendulum_straight.toml").replace("radius = 2.0 ", "radius = 7.0 ");
    let path = write(&dir, "too_big.toml", &text);
    let run = springfit(&dir, &["check", path.to_str().unwrap()])
        .fails(2, &["region.radius", "largest valid geodesic-ball radius is"]);
    assert!(run.stderr().contains("conjugate point") || run.stderr().contains("cross"), "{}", run.report());
}

#[test]
fn check_rejects_what_later_commands_would() {
    let dir = temp_dir("check-upfront");
    let good = design_text_anywhere("double_pendulum.toml");
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "no_catalogue.toml",
            design_text("double_pendulum.toml"),
            vec!["no_catalogue.toml", "field `catalog`", "../catalogs/paper_trim.toml", "names no file"],
        ),
        (
            "every.toml",
            good.replace("every = 15.0", "every = 0.0"),
            vec!["every.toml", "scenario[1].every", "positive"],
        ),
        (
            "duration.toml",
            good.replacen("duration = 20.0", "duration = 0.0", 1),
            vec!["duration.toml", "scenario[0].duration", "positive"],
        ),
        (
            "sweep.toml",
            good.replace("scenario = \"sensitivity\"", "scenario = \"sensitivty\""),
            vec!["sweep.toml", "sweep.scenario", "`sensitivty`", "free, switch, swingup, sensitivity"],
        ),
        (
            "gravity.toml",
            good.replace("gravity = [0.0, 0.0]", "gravity = [0.0, -9.81, 0.0]"),
            vec!["gravity.toml", "robot.gravity", "a planar arm takes 2", "has 3 numbers"],
        ),
        (
            "radius.toml",
            good.replace("radius = 2.0 ", "radius = 1e300 "),
            vec!["radius.toml", "region.radius", "1e300", "geodesics.max_arc"],
        ),
        (
            // Trimmed builds weighed with a catalogue that has no trim springs.
            "trimmed.toml",
            good.replace("paper_trim.toml", "paper.toml"),
            vec!["trimmed.toml", "fit.trimmed_weight", "paper.toml", "no trim springs"],
        ),
    ];
    for (name, text, needles) in cases {
        assert_ne!(text, good, "case {name} did not change the design");
        let path = write(&dir, name, &text);
        let p = path.to_str().unwrap();
        springfit(&dir, &["check", p]).fails(2, &needles);
        // The same error from a command that would otherwise have done work first, and no output.
        springfit(&dir, &["fit", p, "--out", "out"]).fails(2, &needles);
        springfit(&dir, &["simulate", p, "--scenario", "swingup", "--exact", "--out", "out"]).fails(2, &needles);
        assert!(!dir.join("out").exists());
    }
}

#[test]
fn suspicious_input_is_warned_about() {
    let dir = temp_dir("check-warn");
    let text = design_text_anywhere("double_pendulum.toml").replace("q = [0.0, \"pi/2\"]", "q = [0.0, 90.0]").replacen(
        "com = 1.0 ",
        "com = 5.0 ",
        1,
    );
    let path = write(&dir, "warn.toml", &text);
    let run = springfit(&dir, &["check", path.to_str().unwrap()]);
    let err = run.stderr();
    let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("springfit: warning: ")).collect();
    assert!(warnings.iter().any(|w| w.contains("equilibrium.q[1]") && w.contains("turns")), "{}", run.report());
    assert!(warnings.iter().any(|w| w.contains("robot.links[0].com") && w.contains("beyond")), "{}", run.report());
}

#[test]
fn implausible_units_are_warned_about() {
    let dir = temp_dir("check-units");
    let text = design_text_anywhere("double_pendulum.toml")
        .replacen("mass = 1.0      # kg", "mass = 1000.0      # kg", 1)
        .replacen("inertia = 1.0\n", "inertia = 40.0\n", 1);
    let path = write(&dir, "units.toml", &text);
    let run = springfit(&dir, &["check", path.to_str().unwrap()]).ok();
    let err = run.stderr();
    let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("springfit: warning: ")).collect();
    assert!(
        warnings.iter().any(|w| w.contains("robot.links[0].mass") && w.contains("500 kg per metre")),
        "{}",
        run.report()
    );
    assert!(
        warnings.iter().any(|w| w.contains("robot.links[1].inertia") && w.contains("m·L² = 4")),
        "{}",
        run.report()
    );
    // A URDF arm without `gravity` runs in zero gravity: said, not silent.
    let urdf = design_text_anywhere("ur5_lift_elbow.toml");
    let line = urdf.lines().find(|l| l.starts_with("gravity")).unwrap().to_string();
    let urdf =
        urdf.replace(&line, "").replace("urdf = \"", &format!("urdf = \"{}/", util::repo().join("designs").display()));
    let path = write(&dir, "ur5.toml", &urdf);
    let run = springfit(&dir, &["check", path.to_str().unwrap()]);
    assert!(run.stderr().contains("field `robot.gravity`: is missing or zero"), "{}", run.report());
}
