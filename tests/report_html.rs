//! `report.html` in the output folders: every figure of the folder inlined, tables rendered,
//! nothing loaded from elsewhere; rendered in headless Chromium when it is installed.

mod util;

use std::path::Path;
use std::process::Command;

use util::{repo, springfit, temp_dir};

/// Checks the page against the folder and, where Chromium exists, in the browser.
fn check_report(folder: &Path, must_contain: &[&str]) {
    let html = std::fs::read_to_string(folder.join("report.html"))
        .unwrap_or_else(|e| panic!("{}: no report.html: {e}", folder.display()));
    // The folder's figures and its cams' drawings (parts.md shows `cams/<id>.svg`).
    let mut svgs: Vec<String> = std::fs::read_dir(folder)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".svg"))
        .collect();
    if let Ok(cams) = std::fs::read_dir(folder.join("cams")) {
        svgs.extend(
            cams.flatten().map(|e| format!("cams/{}", e.file_name().to_string_lossy())).filter(|n| n.ends_with(".svg")),
        );
    }
    assert!(!svgs.is_empty(), "{}: no figures to check", folder.display());
    for s in &svgs {
        assert_eq!(html.matches(&format!("data-file=\"{s}\"")).count(), 1, "{s} not inlined exactly once");
    }
    assert!(html.contains(&format!("<meta name=\"springfit-figures\" content=\"{}\">", svgs.len())));
    assert_eq!(html.matches("<figure class=\"sf-figure\"").count(), svgs.len());
    assert!(html.contains("<table>"), "no table rendered");
    assert!(!html.contains("<script") && !html.contains("<img") && !html.contains("<link"), "not self-contained");
    for needle in must_contain {
        assert!(html.contains(needle), "{}: report.html lacks `{needle}`", folder.display());
    }
    let chromium = ["chromium", "chromium-browser"]
        .into_iter()
        .find(|b| Command::new(b).arg("--version").output().is_ok_and(|o| o.status.success()));
    let Some(_) = chromium else {
        eprintln!("SKIPPED browser check of {}: no chromium (Debian: apt-get install -y chromium)", folder.display());
        return;
    };
    let shot = folder.with_extension("png");
    let out = Command::new("bash")
        .arg(repo().join("scripts/render_report.sh"))
        .arg(folder)
        .arg(&shot)
        .output()
        .expect("run render_report.sh");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "browser check failed\n{text}");
    assert!(text.contains(&format!("{0} of {0} figures rendered", svgs.len())), "{text}");
}

#[test]
fn fit_simulate_and_compare_write_a_report_page() {
    let dir = temp_dir("html");
    // 64 Monte Carlo builds instead of 1,000: the page shows the same as-built section.
    let design = util::with_builds(&dir, "double_pendulum", 64);
    let d = design.to_str().unwrap();
    springfit(&dir, &["fit", d, "--out", "fit"]).ok();
    check_report(&dir.join("fit"), &["Residual angles on held-out geodesics", "Bill of materials", "Catalogue paper"]);
    springfit(&dir, &["simulate", d, "--scenario", "free", "--bom", "fit/bom.csv", "--out", "sim"]).ok();
    check_report(&dir.join("sim"), &["Scenario free", "release_6", "sim_free.csv"]);
    springfit(&dir, &["compare", "fit", "--out", "cmp"]).ok();
    check_report(&dir.join("cmp"), &["springfit compare"]);
}

#[test]
fn a_design_description_with_markup_is_shown_as_text() {
    let dir = temp_dir("html-escape");
    let text = util::design_text("double_pendulum.toml")
        .replace("description = \"Paper's double pendulum", "description = \"<b>bold</b> & <script>x</script> pendulum")
        .replace("../catalogs/paper_trim.toml", &repo().join("catalogs/paper_trim.toml").display().to_string());
    let design = util::write(&dir, "d.toml", &text.replace("[fit]", "[fit]\nbuilds = 0"));
    springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "fit", "--max-elements", "6"]).ok();
    let html = std::fs::read_to_string(dir.join("fit/report.html")).unwrap();
    assert!(html.contains("&lt;b&gt;bold&lt;/b&gt; &amp; &lt;script&gt;x&lt;/script&gt;"), "{html}");
    assert!(!html.contains("<script>"));
}
