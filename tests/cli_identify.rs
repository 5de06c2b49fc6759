//! `springfit identify` from the command line: a simulated log of the default design's built arm
//! identified and tuned from, every key it writes documented, and every kind of bad input refused
//! with one error naming the file, the line and the field, exit 2 and nothing written.

mod util;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use springfit::design::Design;
use springfit::identify::swing::{Drive, encoder_reading, swing};
use springfit::numerics::rng::SplitMix64;
use util::{repo, springfit, temp_dir, write};

fn design_path() -> PathBuf {
    repo().join("designs/double_pendulum.toml")
}

fn bom_path() -> PathBuf {
    repo().join("tests/data/double_pendulum_bom.csv")
}

/// A log (CSV text, with a `run` column) of the built arm, every rate (the trims' too) off by +3 % and damping
/// 0.05 N·m·s/rad, released from rest at `starts` for `seconds` each at 1 kHz, read by a 17-bit
/// encoder with one count of noise.
fn log_text(design: &Design, starts: &[Vec<f64>], seconds: f64) -> String {
    let bom = springfit::files::bom::read(&bom_path()).unwrap();
    let factors: Vec<f64> = vec![1.03; bom.len()];
    let built = springfit::fit::bill::spring_set(&bom).scaled(&factors);
    let drive = Drive { damping: &[0.05, 0.05], friction: &[0.0, 0.0], torque: None };
    let mut rng = SplitMix64::stream(7, 0);
    let mut text = String::from("run,t,q1,q2\n");
    for (k, q0) in starts.iter().enumerate() {
        let run = encoder_reading(&swing(design, &built, &drive, q0, seconds, 1000.0).unwrap(), 17, 1.0, &mut rng);
        for (i, t) in run.t.iter().enumerate() {
            let _ = writeln!(text, "r{k},{t},{},{}", run.q[2 * i], run.q[2 * i + 1]);
        }
    }
    text
}

/// Every key of a JSON value, objects inside arrays and objects included.
fn json_keys(value: &serde_json::Value, out: &mut Vec<String>) {
    match value {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                out.push(k.clone());
                json_keys(v, out);
            }
        }
        serde_json::Value::Array(items) => items.iter().for_each(|v| json_keys(v, out)),
        _ => {}
    }
}

/// The `## \`springfit identify\`` section of docs/outputs.md.
fn outputs_section() -> String {
    let doc = std::fs::read_to_string(repo().join("docs/outputs.md")).unwrap();
    let start = doc.find("## `springfit identify`").expect("docs/outputs.md has a `springfit identify` section");
    let rest = &doc[start + 3..];
    rest[..rest.find("\n## ").unwrap_or(rest.len())].to_string()
}

fn assert_documented(file: &Path) {
    let value: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(file).unwrap()).unwrap();
    let mut keys = Vec::new();
    json_keys(&value, &mut keys);
    let section = outputs_section();
    let missing: Vec<&String> = keys
        .iter()
        .filter(|k| !section.contains(&format!("`{k}`")) && !section.contains(&format!("\"{k}\"")))
        .collect();
    assert!(missing.is_empty(), "{}: keys not in docs/outputs.md: {missing:?}", file.display());
}

#[test]
fn a_logged_swing_is_identified_and_tuned_from() {
    let dir = temp_dir("identify");
    let design = Design::load(&design_path()).unwrap();
    let (d, b) = (design_path(), bom_path());
    let (d, b) = (d.to_str().unwrap(), b.to_str().unwrap());
    // The plan first: its releases are the ones logged.
    let plan = springfit(&dir, &["identify", d, "--bom", b, "--plan", "--out", "plan"]).ok();
    assert!(plan.stdout().contains("plan: ") && dir.join("plan/plan.md").exists(), "{}", plan.report());
    assert_documented(&dir.join("plan/plan.json"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("plan/plan.json")).unwrap()).unwrap();
    let starts: Vec<Vec<f64>> = json["releases"]
        .as_array()
        .unwrap()
        .iter()
        .take(3)
        .map(|r| r["q0"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect())
        .collect();
    write(&dir, "swings.csv", &log_text(&design, &starts, 8.0));
    let run = springfit(&dir, &["identify", d, "--bom", b, "--log", "swings.csv", "--out", "id"]).ok();
    for f in
        ["identify.md", "identify.json", "identified.csv", "identified_parts.csv", "identify_torque.svg", "report.html"]
    {
        assert!(dir.join("id").join(f).exists(), "{f} missing\n{}", run.report());
    }
    assert_documented(&dir.join("id/identify.json"));
    // What the command printed is what it wrote: an identified part's δ is the built +3 %.
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("id/identify.json")).unwrap()).unwrap();
    let identified: Vec<&serde_json::Value> =
        json["rates"].as_array().unwrap().iter().filter(|r| r["status"] == "identified").collect();
    assert!(identified.len() >= 2, "{}", run.stdout());
    for r in identified {
        let (delta, se) = (r["delta"].as_f64().unwrap(), r["standard_error"].as_f64().unwrap());
        assert!((delta - 0.03).abs() <= 4.0 * se, "{}: δ {delta} ± {se}", r["id"]);
    }
    // Every rate is +3 %, so a group's combination Σ wᵢ δᵢ is 0.03 Σ wᵢ.
    for g in json["groups"].as_array().unwrap() {
        for c in g["identified"].as_array().unwrap() {
            let sum: f64 = c["weights"].as_array().unwrap().iter().map(|w| w[1].as_f64().unwrap()).sum();
            let (value, se) = (c["value"].as_f64().unwrap(), c["standard_error"].as_f64().unwrap());
            assert!((value - 0.03 * sum).abs() <= 4.0 * se, "{c}: against {}", 0.03 * sum);
        }
    }
    let damping = json["joints"][0]["damping"]["value"].as_f64().unwrap();
    assert!((damping / 0.05 - 1.0).abs() < 0.1, "damping {damping}");
    assert!(run.stdout().contains("next: springfit tune"), "{}", run.stdout());
    // identified.csv is what tune reads.
    springfit(&dir, &["tune", d, "--measured", "id/identified.csv", "--out", "tune"]).ok();
    assert!(dir.join("tune/bom_tuned.csv").exists());
}

#[test]
fn bad_logs_and_bills_are_refused_before_anything_is_written() {
    let dir = temp_dir("identify-bad");
    let design = Design::load(&design_path()).unwrap();
    let (d, b) = (design_path(), bom_path());
    let (d, b) = (d.to_str().unwrap(), b.to_str().unwrap());
    let q = design.q_eq.as_slice();
    // 40 samples at rest at q_eq, then edited.
    let lines: Vec<String> = (0..40).map(|i| format!("{},{},{}", i as f64 * 0.001, q[0], q[1])).collect();
    let with = |k: usize, line: &str| {
        let mut l = lines.clone();
        l[k] = line.to_string();
        format!("t,q1,q2\n{}\n", l.join("\n"))
    };
    // Long enough for the filters, so that the region is what refuses it.
    let degrees: String =
        (0..1500).map(|i| format!("{},{},{}\n", i as f64 * 0.001, q[0].to_degrees(), q[1].to_degrees())).collect();
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "missing.csv",
            format!("t,q1\n{}\n", lines.iter().map(|l| l.rsplit_once(',').unwrap().0).collect::<Vec<_>>().join("\n")),
            vec!["missing.csv", "line 1: header", "no column `q2`"],
        ),
        ("back.csv", with(20, &format!("0.005,{},{}", q[0], q[1])), vec!["back.csv", "line 22: t", "goes back"]),
        ("nan.csv", with(9, &format!("0.009,NaN,{}", q[1])), vec!["nan.csv", "line 11: q1", "not a finite number"]),
        (
            "joints.csv",
            format!("t,q1,q2,q3\n{}\n", lines.iter().map(|l| format!("{l},0")).collect::<Vec<_>>().join("\n")),
            vec!["joints.csv", "line 1: header", "3 joints", "has 2"],
        ),
        (
            "gap.csv",
            format!(
                "t,q1,q2\n{}\n",
                lines
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| !(15..18).contains(i))
                    .map(|(_, l)| l.clone())
                    .collect::<Vec<_>>()
                    .join("\n")
            ),
            vec!["gap.csv", "line 17: t", "a gap of"],
        ),
        ("degrees.csv", format!("t,q1,q2\n{degrees}"), vec!["degrees.csv", "line 2: q", "degrees"]),
    ];
    for (name, text, needles) in cases {
        write(&dir, name, &text);
        springfit(&dir, &["identify", d, "--bom", b, "--log", name, "--out", "id"]).fails(2, &needles);
        assert!(!dir.join("id").exists(), "{name}: nothing is written");
    }
    // A bill that does not hold the design's equilibrium (one crank three times as stiff).
    let bom = std::fs::read_to_string(bom_path()).unwrap();
    let row = bom.lines().nth(1).unwrap();
    let mut f = springfit::files::split_csv_line(row).unwrap();
    f[6] = format!("{}", 3.0 * f[6].parse::<f64>().unwrap());
    write(&dir, "other_bom.csv", &bom.replacen(row, &f.join(","), 1));
    write(&dir, "long.csv", &log_text(&design, &[design.q_eq.iter().map(|x| x + 0.05).collect()], 3.0));
    springfit(&dir, &["identify", d, "--bom", "other_bom.csv", "--log", "long.csv", "--out", "id"])
        .fails(2, &["other_bom.csv", "stiffness", "equilibrium"]);
    assert!(!dir.join("id").exists());
    // The output folder is checked before any log is read: a plain file there is named even
    // with a bad log.
    write(&dir, "plainfile", "not a folder");
    springfit(&dir, &["identify", d, "--bom", b, "--log", "nan.csv", "--out", "plainfile"])
        .fails(2, &["plainfile", "not a folder"]);
}
