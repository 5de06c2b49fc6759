//! An element no part realises leaves the bill (issue 46): the fit is solved again without it,
//! the verdict judges the realised design of what is left, and `summary.json` names the element
//! dropped; a fit whose every element has a part is what it was.

mod util;

use util::{repo, springfit_threads, temp_dir};

fn summary(dir: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

/// A random planar arm of two joints (`random_arm.py --seed 4 --joints 2`) on the chain
/// catalogue without its triples: its fit has one crank of 0.0004 N·m peak torque, S26, whose
/// rate no wire winds in the envelope. It is left out, the fit solved again without it, and the
/// bill, the parts and the verdict are those of the elements that can be built; the same on one
/// thread and on two.
#[test]
fn a_tiny_element_without_a_part_leaves_the_bill() {
    let data = repo().join("tests/data/tiny_crank");
    let dir = temp_dir("unbuildable");
    for f in ["arm.toml", "pair.toml"] {
        std::fs::copy(data.join(f), dir.join(f)).unwrap();
    }
    let run = springfit_threads(&dir, &["fit", "arm.toml", "--out", "one"], 1).ok();
    let out = run.stdout();
    assert!(out.contains("1 element without a part left out of the bill"), "{}", run.report());
    assert!(out.contains("verdict: acceptable (realised design p99"), "{}", run.report());
    let s = summary(&dir.join("one"));
    let d = &s["dropped_without_part"];
    assert_eq!(d["rounds"], 1, "{d}");
    assert!(d["kept"].is_null(), "{d}");
    let dropped = d["elements"].as_array().unwrap();
    assert_eq!(dropped.len(), 1, "{d}");
    assert_eq!(dropped[0]["id"], "S26");
    assert_eq!(dropped[0]["element"], "crank (1;-1) @ -1.838");
    assert!(dropped[0]["max_torque_nm"].as_f64().unwrap() < 1e-3, "{d}");
    assert!(dropped[0]["reason"].as_str().unwrap().contains("no wire size"), "{d}");
    // The verdict judges the realised design of the buildable elements: every one has a part.
    assert_eq!(s["verdict"], "acceptable");
    assert_eq!(s["verdict_judges"], "realised");
    assert!(!s["verdict_reason"].as_str().unwrap().contains("without a part"), "{}", s["verdict_reason"]);
    assert_eq!(s["realised"]["missing"].as_array().map(Vec::len), Some(0), "{}", s["realised"]);
    let realised = s["realised"]["residual_deg"]["p99_abs"].as_f64().unwrap();
    assert_eq!(d["realised_p99_deg_after"].as_f64(), Some(realised));
    assert_eq!(d["p99_deg_after"].as_f64(), s["residual_deg"]["p99_abs"].as_f64());
    // The bill holds no crank on 1;-1 at that offset (the refit may bring in another element).
    let bom = std::fs::read_to_string(dir.join("one/bom.csv")).unwrap();
    assert!(!bom.lines().any(|l| l.contains(",crank,,1;-1,-1.83779")), "{bom}");
    // The same bill on two threads.
    springfit_threads(&dir, &["fit", "arm.toml", "--out", "two"], 2).ok();
    let two = std::fs::read_to_string(dir.join("two/bom.csv")).unwrap();
    assert!(bom == two, "the bill differs between one and two threads");
    assert_eq!(summary(&dir.join("two"))["dropped_without_part"], *d);
}

/// A fit whose every element has a part (the paper's design on small fans) is not refitted: the
/// bill with its parts is the bare fit's, bit for bit, and nothing is recorded as dropped.
#[test]
fn a_bill_whose_every_element_has_a_part_is_unchanged() {
    let (design, catalog) = util::shipped("double_pendulum");
    let mut settings = design.fit;
    settings.training_directions = 36;
    settings.training_samples = 20;
    settings.evaluation_directions = 36;
    settings.evaluation_samples = 20;
    settings.builds = 0;
    settings.restarts = 0;
    settings.pair_swaps = false;
    settings.tolerance = springfit::design::tolerance::ToleranceSpec::None;
    let none = springfit::progress::Progress::none();
    let bare = springfit::fit::fit(&design, &catalog, &settings, none).unwrap();
    let (with_parts, parts) = springfit::parts::fit_with_parts(&design, &catalog, &settings, &[], none).unwrap();
    assert_eq!(parts.missing().count(), 0);
    assert!(with_parts.dropped_without_part.is_none());
    assert_eq!(with_parts.bom, bare.bom);
    assert_eq!(with_parts.metrics, bare.metrics);
}
