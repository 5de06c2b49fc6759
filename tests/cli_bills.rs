//! Bills of materials a command reads (`simulate --bom`, `parts --bom`, `export --bom`,
//! `tune --measured`, `identify --bom`): one whose springs do not hold the design's equilibrium
//! (an offset typed in degrees) is refused before any work, naming the bill, the miss and
//! `[equilibrium] bill_tolerance`, which lets it through when raised.

mod util;

use util::{repo, springfit, temp_dir, write};

/// The shipped test bill with crank S01's offset typed in degrees (30 for 30°, i.e. π/6 rad).
fn bill_in_degrees() -> String {
    let bom = std::fs::read_to_string(repo().join("tests/data/double_pendulum_bom.csv")).unwrap();
    let row = bom.lines().nth(1).unwrap();
    let mut f = springfit::files::split_csv_line(row).unwrap();
    assert_eq!(f[5], "0.5235987755982988", "S01's offset is π/6 rad: {row}");
    f[5] = "30".into();
    bom.replacen(row, &f.join(","), 1)
}

/// `text` with an empty `measured_stiffness` column (rates as designed), as `tune` reads it.
fn with_measured_column(text: &str) -> String {
    text.lines()
        .enumerate()
        .map(|(i, l)| if i == 0 { format!("{l},measured_stiffness\n") } else { format!("{l},\n") })
        .collect()
}

#[test]
fn a_bill_that_does_not_hold_the_equilibrium_is_refused_by_every_command_that_reads_one() {
    let dir = temp_dir("bill-equilibrium");
    let d = repo().join("designs/double_pendulum.toml");
    let d = d.to_str().unwrap();
    write(&dir, "degrees.csv", &bill_in_degrees());
    write(&dir, "degrees_measured.csv", &with_measured_column(&bill_in_degrees()));
    let needles = ["degrees", "offset_rad", "|∇U(q_eq)|", "equilibrium.bill_tolerance = 1e-3 rad", "typed in degrees"];
    let commands: [&[&str]; 6] = [
        &["simulate", d, "--bom", "degrees.csv", "--scenario", "free", "--out", "o"],
        &["parts", d, "--bom", "degrees.csv", "--out", "o"],
        &["export", d, "--bom", "degrees.csv", "--mujoco", "--out", "o"],
        &["tune", d, "--measured", "degrees_measured.csv", "--out", "o"],
        &["identify", d, "--bom", "degrees.csv", "--plan", "--out", "o"],
        &["identify", d, "--bom", "degrees.csv", "--log", "nosuch.csv", "--out", "o"],
    ];
    for args in commands {
        let needles: Vec<&str> = needles.iter().map(|n| if *n == "degrees" { "degrees.csv" } else { n }).collect();
        let needles: Vec<&str> = if args[0] == "tune" {
            needles.iter().map(|n| if *n == "degrees.csv" { "degrees_measured.csv" } else { n }).collect()
        } else {
            needles
        };
        springfit(&dir, args).fails(2, &needles);
        assert!(!dir.join("o").exists(), "{args:?} wrote its folder");
    }
    // The setting lets a bill through: the export then runs.
    let design =
        util::design_variant(&dir, "double_pendulum", &[("equilibrium.bill_tolerance", toml::Value::Float(10.0))]);
    springfit(&dir, &["export", design.to_str().unwrap(), "--bom", "degrees.csv", "--mujoco", "--out", "o"]).ok();
    // And the shipped bill passes as it is.
    let good = repo().join("tests/data/double_pendulum_bom.csv");
    springfit(&dir, &["export", d, "--bom", good.to_str().unwrap(), "--mujoco", "--out", "good"]).ok();
}

#[test]
fn a_bill_tolerance_that_is_not_a_positive_angle_is_refused() {
    let dir = temp_dir("bill-tolerance");
    let design =
        util::design_variant(&dir, "double_pendulum", &[("equilibrium.bill_tolerance", toml::Value::Float(0.0))]);
    springfit(&dir, &["check", design.to_str().unwrap()]).fails(2, &["equilibrium.bill_tolerance", "positive"]);
}
