//! `report.html`: one self-contained page per output folder, readable offline.
//!
//! Engineers would rather look at one page than at a folder of files. Each command calls its
//! entry point ([`write_fit`], [`write_simulate`], [`write_sweep`], [`write_compare`],
//! [`write_pareto`]) after writing its other files and before committing the folder. The page
//! is built from what the folder already holds: the command's markdown reports (rendered with
//! `pulldown-cmark`, tables included), every SVG figure inlined where the markdown shows it or,
//! failing that, in a closing "Figures" section (so figures added later, such as as-built ones,
//! appear without changes here), and a summary of the design and its catalogue. Nothing is
//! fetched at view time: no scripts, no external styles, no images by reference.
//!
//! Each inlined figure is a `<figure class="sf-figure" data-file="NAME.svg">` around the `<svg>`,
//! and `<meta name="springfit-figures" content="N">` states how many there are, so a browser
//! check (`scripts/render_report.sh`) can count what was drawn against what was meant.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use pulldown_cmark::{Event, Options, Parser, Tag, TagEnd, html};
use serde_json::Value;

use super::output::OutputDir;
use crate::design::Design;
use crate::elements::catalog::{Catalog, OffsetSpec};
use crate::error::{Error, Result};
use crate::model::Chain;

/// The file name.
pub const FILE: &str = "report.html";

const STYLE: &str = "body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{border-bottom:2px solid #446;padding-bottom:.2em}h2{border-bottom:1px solid #ccd;margin-top:2em}
table{border-collapse:collapse;margin:1em 0;font-size:.9em;display:block;max-width:100%;overflow-x:auto}th,td{border:1px solid #ccd;padding:.25em .6em}
th{background:#eef}tr:nth-child(even) td{background:#f8f8fc}code{background:#f2f2f6;padding:0 .2em}
figure.sf-figure{margin:1.5em 0;overflow-x:auto}figure.sf-figure svg{height:auto;display:block}
figcaption{font-size:.8em;color:#666}nav ul{columns:3;font-size:.9em}.note{color:#555;font-size:.9em}a,code{overflow-wrap:anywhere}
@media (max-width:700px){nav ul{columns:1}}";

/// A page under construction, over the files in `dir`.
struct Page {
    /// The folder holding the command's files (the output folder's staging folder).
    dir: PathBuf,
    /// The output folder, for error messages.
    target: PathBuf,
    title: String,
    body: String,
    /// SVG files already inlined.
    inlined: BTreeSet<String>,
}

/// Names of the visible files in `dir`, sorted.
fn staged(dir: &Path, target: &Path) -> Result<Vec<String>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(target, e))?;
    let mut names: Vec<String> = entries
        .flatten()
        .filter(|e| e.path().is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !n.starts_with('.'))
        .collect();
    names.sort();
    Ok(names)
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

impl Page {
    fn new(out: &OutputDir, title: String) -> Self {
        Page::in_folder(&out.path("."), out.target(), title)
    }

    fn in_folder(dir: &Path, target: &Path, title: String) -> Self {
        Page {
            dir: dir.to_path_buf(),
            target: target.to_path_buf(),
            title,
            body: String::new(),
            inlined: BTreeSet::new(),
        }
    }

    /// Reads a text file of the folder.
    fn read(&self, name: &str) -> Result<String> {
        std::fs::read_to_string(self.dir.join(name)).map_err(|e| Error::io(self.target.join(name), e))
    }

    /// The `<figure>` of a staged SVG file, or None when there is no such file.
    fn figure(&mut self, name: &str) -> Result<Option<String>> {
        if !self.dir.join(name).is_file() {
            return Ok(None);
        }
        let text = self.read(name)?;
        // Drop an XML declaration or doctype: inline SVG starts at its element.
        let svg = match text.find("<svg") {
            Some(i) => &text[i..],
            None => return Ok(None),
        };
        self.inlined.insert(name.to_string());
        let png = name.strip_suffix(".svg").map(|s| format!("{s}.png")).filter(|p| self.dir.join(p).is_file());
        let caption = match png {
            Some(p) => format!("{} (also <a href=\"{}\">{}</a>)", escape(name), escape(&p), escape(&p)),
            None => escape(name),
        };
        Ok(Some(format!(
            "<figure class=\"sf-figure\" data-file=\"{}\">\n{}\n<figcaption>{caption}</figcaption></figure>\n",
            escape(name),
            svg.trim_end()
        )))
    }

    /// Renders markdown, inlining images of staged SVG files (in the folder or a subfolder of
    /// it, such as parts.md's `cams/<id>.svg`).
    fn markdown(&mut self, md: &str) -> Result<()> {
        let mut events = Vec::new();
        let mut skip_to_image_end = false;
        for ev in Parser::new_ext(md, Options::ENABLE_TABLES | Options::ENABLE_STRIKETHROUGH) {
            if skip_to_image_end {
                if matches!(ev, Event::End(TagEnd::Image)) {
                    skip_to_image_end = false;
                }
                continue;
            }
            // Names and descriptions come from user files: raw HTML in them is shown as text.
            let ev = match ev {
                Event::Html(t) | Event::InlineHtml(t) => Event::Text(t),
                other => other,
            };
            if let Event::Start(Tag::Image { dest_url, .. }) = &ev {
                let dest = dest_url.to_string();
                if local_svg(&dest)
                    && let Some(fig) = self.figure(&dest)?
                {
                    events.push(Event::Html(fig.into()));
                    skip_to_image_end = true;
                    continue;
                }
            }
            events.push(ev);
        }
        html::push_html(&mut self.body, events.into_iter());
        Ok(())
    }

    /// Renders a staged markdown file if it exists; its first heading is demoted to a section.
    fn markdown_file(&mut self, name: &str) -> Result<bool> {
        if !self.dir.join(name).is_file() {
            return Ok(false);
        }
        let text = self.read(name)?;
        // The page has one h1; every file's headings move one level down, and a file's title that
        // repeats the page's is dropped.
        let mut lines = text.lines().peekable();
        if lines.peek().is_some_and(|l| l.strip_prefix("# ").is_some_and(|t| t.trim() == self.title)) {
            lines.next();
        }
        let demoted: String =
            lines.map(|l| if l.starts_with('#') { format!("#{l}\n") } else { format!("{l}\n") }).collect();
        let _ = writeln!(self.body, "<section data-source=\"{}\">", escape(name));
        self.markdown(&demoted)?;
        self.body.push_str("</section>\n");
        Ok(true)
    }

    /// Every staged SVG not shown yet, whose name `filter` accepts, under `heading`.
    fn remaining_figures(&mut self, heading: &str, filter: impl Fn(&str) -> bool) -> Result<()> {
        let rest: Vec<String> = staged(&self.dir, &self.target)?
            .into_iter()
            .filter(|n| n.ends_with(".svg") && !self.inlined.contains(n) && filter(n))
            .collect();
        if rest.is_empty() {
            return Ok(());
        }
        let _ = writeln!(self.body, "<h2>{}</h2>", escape(heading));
        for name in rest {
            if let Some(fig) = self.figure(&name)? {
                self.body.push_str(&fig);
            }
        }
        Ok(())
    }

    /// The design and its catalogue in a few lines and two tables.
    fn design(&mut self, design: &Design) -> Result<()> {
        let mut md = String::from("## Design\n\n");
        if !design.description.is_empty() {
            let _ = writeln!(md, "{}\n", design.description);
        }
        let q: Vec<String> = design.q_eq.iter().map(|x| format!("{x:.4}")).collect();
        let gravity = match &design.chain {
            Chain::Planar(c) => format!("({}, {})", c.gravity()[0], c.gravity()[1]),
            Chain::Spatial(c) => format!("({}, {}, {})", c.gravity()[0], c.gravity()[1], c.gravity()[2]),
        };
        let _ = writeln!(
            md,
            "- file: `{}`\n- equilibrium q_eq = ({}) rad; region: {}\n- gravity {gravity} m/s²; fit: ω = {} rad/s, solver {}, element budget {}\n",
            design.path.display(),
            q.join(", "),
            design.region.describe(),
            design.fit.frequency,
            design.fit.solver.name(),
            if design.fit.max_elements == 0 { "none".to_string() } else { design.fit.max_elements.to_string() }
        );
        if let Chain::Planar(c) = &design.chain {
            md.push_str("| link | mass (kg) | length (m) | centre of mass (m) | inertia (kg·m²) |\n| ---: | ---: | ---: | ---: | ---: |\n");
            for (i, l) in c.links().iter().enumerate() {
                let _ = writeln!(md, "| {} | {} | {} | {} | {} |", i + 1, l.mass, l.length, l.com, l.inertia);
            }
        } else {
            let _ = writeln!(md, "- joints: {}", design.chain.joint_names().join(", "));
        }
        if let Some(path) = &design.catalog {
            md.push('\n');
            match Catalog::load_for(path, &design.chain.joint_names()) {
                Ok(c) => {
                    let _ = writeln!(
                        md,
                        "### Catalogue {}\n\n`{}`: {} families.\n\n| family | profiles | couplings | offsets | max stiffness | stock rates | tolerance |\n| --- | --- | ---: | --- | ---: | ---: | ---: |",
                        c.name,
                        path.display(),
                        c.families.len()
                    );
                    for f in &c.families {
                        let profiles: Vec<String> =
                            f.profiles.iter().map(|p| format!("{}{}", p.name(), p.side())).collect();
                        let offsets = match &f.offsets {
                            OffsetSpec::Equilibrium => "equilibrium".to_string(),
                            OffsetSpec::Grid { count, .. } => format!("grid of {count}"),
                            OffsetSpec::Phases { count } => format!("{count} phases"),
                            OffsetSpec::List(v) => format!("{} listed", v.len()),
                        };
                        let _ = writeln!(
                            md,
                            "| {} | {} | {} | {} | {} | {} | {} |",
                            f.name,
                            profiles.join(", "),
                            f.couplings.len(),
                            offsets,
                            f.max_stiffness.map(|k| k.to_string()).unwrap_or_else(|| "–".into()),
                            if f.stock_rates.is_empty() { "–".to_string() } else { f.stock_rates.len().to_string() },
                            if f.tolerance > 0.0 {
                                format!("±{} %", crate::elements::fmt_number(100.0 * f.tolerance))
                            } else {
                                "–".to_string()
                            }
                        );
                    }
                }
                Err(e) => {
                    let _ = writeln!(md, "Catalogue `{}` could not be read for this summary: {e}", path.display());
                }
            }
        }
        self.markdown(&md)
    }

    /// Writes `report.html` into the staging folder.
    fn finish(self) -> Result<()> {
        let files = staged(&self.dir, &self.target)?;
        let mut nav = String::from("<nav><h2>Files in this folder</h2><ul>\n");
        for f in files.iter().filter(|f| f.as_str() != FILE) {
            let _ = writeln!(nav, "<li><a href=\"{0}\">{0}</a></li>", escape(f));
        }
        nav.push_str("</ul></nav>\n");
        let figures = self.body.matches("<figure class=\"sf-figure\"").count();
        let page = format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<meta name=\"generator\" content=\"springfit {}\">\n<meta name=\"springfit-figures\" content=\"{figures}\">\n<title>{}</title>\n<style>\n{STYLE}\n</style>\n</head>\n<body>\n<h1>{}</h1>\n{}{nav}</body>\n</html>\n",
            env!("CARGO_PKG_VERSION"),
            escape(&self.title),
            escape(&self.title),
            self.body
        );
        std::fs::write(self.dir.join(FILE), page).map_err(|e| Error::io(self.target.join(FILE), e))
    }
}

/// `report.html` of `springfit fit`: the fit report, the bill of materials, the design.
pub fn write_fit(out: &OutputDir, design: &Design) -> Result<()> {
    let mut p = Page::new(out, format!("springfit fit: {}", design.name));
    p.markdown_file("report.md")?;
    p.markdown_file("bom.md")?;
    p.markdown_file("parts.md")?;
    p.remaining_figures("Figures", |_| true)?;
    p.design(design)?;
    p.finish()
}

/// One scenario's metrics, from its `sim_<name>.json`, as markdown.
fn scenario_md(json: &Value) -> String {
    let s = |v: &Value| v.as_str().unwrap_or("").to_string();
    let mut md = format!(
        "## Scenario {} ({})\n\nPotential: {}; mode label: {}",
        s(&json["scenario"]),
        s(&json["kind"]),
        s(&json["potential"]),
        s(&json["label"])
    );
    if let Some(e) = json["label_error_deg"].as_f64() {
        let _ = write!(md, " (largest error {e:.2e}°)");
    }
    // The geodesic deviation leads: it measures how far the motion left its mode, while the
    // label drift spikes where the motion passes near the ε-ball (the label of a point a little
    // off the mode turns fast there), so a drift of 178° can head a release that stays within 9 %
    // of r₀ of its geodesic (issue 42 item 9).
    md.push_str(".\n\nThe geodesic deviation is how far the arm left its mode (largest metric distance to the mode's geodesic, and its ratio to the start's r₀); the label drift is a secondary figure: it spikes where the motion passes close to q_eq, inside or near the ε-ball, where the label of a point a little off the mode turns fast (docs/simulation.md).\n\n| run | geodesic deviation (max, of r₀) | label drift (cumulative, wrapped) | actuator share | last 5 s | energy error, last 5 s | slowest settling |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    let pct = |v: &Value| v.as_f64().map(|x| format!("{:.3} %", 100.0 * x)).unwrap_or_else(|| "–".into());
    if let Some(runs) = json["runs"].as_object() {
        for (name, m) in runs {
            let drift = match (m["mode_drift_deg"].as_f64(), m["mode_drift_wrapped_deg"].as_f64()) {
                (Some(d), Some(w)) => format!("{d:.3}°, {w:.3}°"),
                (Some(d), None) => format!("{d:.3}°"),
                _ => "–".into(),
            };
            let deviation = match (m["geodesic_deviation"]["max"].as_f64(), m["geodesic_deviation"]["max_rel"].as_f64())
            {
                (Some(d), Some(r)) => format!("{d:.2e} ({:.1} %)", 100.0 * r),
                _ => "–".into(),
            };
            let energy = m
                .get("energy_signed_error_last5s")
                .or_else(|| m.get("energy_rel_error_last5s"))
                .and_then(Value::as_f64)
                .map(|e| format!("{:+.2} %", 100.0 * e))
                .unwrap_or_else(|| "–".into());
            let settle = m["settling_s"]
                .as_array()
                .filter(|a| !a.is_empty())
                .map(|a| {
                    let worst = a.iter().map(|v| v.as_f64().unwrap_or(f64::INFINITY)).fold(0.0, f64::max);
                    if worst.is_finite() { format!("{worst:.2} s") } else { "never".into() }
                })
                .unwrap_or_else(|| "–".into());
            let _ = writeln!(
                md,
                "| {name} | {deviation} | {drift} | {} | {} | {energy} | {settle} |",
                pct(&m["actuator_share"]),
                pct(&m["actuator_share_last5s"])
            );
        }
        md.push_str(&savings_md(runs));
    }
    md.push_str(&gains_md(&json["gains"]));
    md
}

/// The savings of a scenario's runs with control against the arm without springs (`savings` in
/// `sim_<name>.json`), as a markdown table; empty when no run has control (free releases, whose
/// actuators do nothing).
fn savings_md(runs: &serde_json::Map<String, Value>) -> String {
    let controlled = |m: &Value| {
        ["mode", "energy", "compensation"].iter().map(|k| m["flux"][k].as_f64().unwrap_or(0.0)).sum::<f64>() > 0.0
    };
    let num = |v: &Value, digits: usize| v.as_f64().map(|x| format!("{x:.digits$}")).unwrap_or_else(|| "–".into());
    let pct = |v: &Value| v.as_f64().map(|x| format!("{:.1} %", 100.0 * x)).unwrap_or_else(|| "–".into());
    let mut md = String::new();
    for (name, m) in runs.iter().filter(|(_, m)| controlled(m) && m["savings"].is_object()) {
        if md.is_empty() {
            md.push_str("\nAgainst the arm without springs (the same motion driven by the actuators alone):\n\n| run | energy with / without (J) | saved | peak torque with / without (N·m) | saved | RMS torque with / without (N·m) | saved | copper losses with / without (J) | saved |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
        }
        let (v, a, b) = (&m["savings"], &m["savings"]["with_springs"], &m["savings"]["without_springs"]);
        let _ = writeln!(
            md,
            "| {name} | {} / {} | {} | {} / {} | {} | {} / {} | {} | {} / {} | {} |",
            num(&a["energy_j"], 3),
            num(&b["energy_j"], 3),
            pct(&v["energy_saved"]),
            num(&a["peak_torque_nm"], 2),
            num(&b["peak_torque_nm"], 2),
            pct(&v["peak_torque_saved"]),
            num(&a["rms_torque_nm"], 3),
            num(&b["rms_torque_nm"], 3),
            pct(&v["rms_torque_saved"]),
            num(&a["copper_loss_j"], 4),
            num(&b["copper_loss_j"], 4),
            pct(&v["copper_loss_saved"])
        );
    }
    md
}

/// The controllers' gains of `sim_<name>.json` (`gains`) in one line, naming those derived from
/// the arm; empty for a file without them.
fn gains_md(g: &Value) -> String {
    if !g.is_object() {
        return String::new();
    }
    let num = |k: &str| g[k].as_f64().map(|x| format!("{x:.4}")).unwrap_or_else(|| "–".into());
    let from: Vec<&str> =
        g["from_arm"].as_array().map(|a| a.iter().filter_map(Value::as_str).collect()).unwrap_or_default();
    let mut md = format!(
        "\nGains: k_θ = {} N·m/rad, ζ = {}, ε = {} rad, β_E = {} 1/(J·s), β_nD = {}",
        num("k_theta"),
        num("zeta"),
        num("epsilon"),
        num("beta_e"),
        num("beta_nd")
    );
    if from.is_empty() {
        md.push_str(" (as the design sets them).\n");
    } else {
        let _ = writeln!(
            md,
            "; from the arm: {} (sized for E = {} J at ω = {} rad/s).",
            from.join(", "),
            g["basis"]["energy_j"].as_f64().map_or("?".into(), |e| e.to_string()),
            g["basis"]["omega"].as_f64().map_or("?".into(), |e| e.to_string())
        );
    }
    md
}

/// `report.html` of `springfit simulate`: per scenario its metrics and its five figures.
pub fn write_simulate(out: &OutputDir, design: &Design) -> Result<()> {
    let mut p = Page::new(out, format!("springfit simulate: {}", design.name));
    for name in staged(&p.dir, &p.target)? {
        let Some(scenario) = name.strip_prefix("sim_").and_then(|n| n.strip_suffix(".json")) else { continue };
        let text = p.read(&name)?;
        let json: Value =
            serde_json::from_str(&text).map_err(|e| Error::invalid(p.target.join(&name), "json", e.to_string()))?;
        p.markdown(&scenario_md(&json))?;
        let _ = writeln!(
            p.body,
            "<p class=\"note\">Samples: <a href=\"sim_{0}.csv\">sim_{0}.csv</a>.</p>",
            escape(scenario)
        );
        for plot in ["phase", "q", "torques", "label", "power"] {
            if let Some(fig) = p.figure(&format!("sim_{scenario}_{plot}.svg"))? {
                p.body.push_str(&fig);
            }
        }
    }
    p.markdown_file(super::simulate::BACKBONE)?;
    p.remaining_figures("Other figures", |_| true)?;
    p.design(design)?;
    p.finish()
}

/// `report.html` of `springfit sweep`: the tolerance tables, the figures, the design.
pub fn write_sweep(out: &OutputDir, design: &Design) -> Result<()> {
    let mut p = Page::new(out, format!("springfit sweep: {}", design.name));
    p.markdown_file("tolerance.md")?;
    p.remaining_figures("Figures", |_| true)?;
    p.design(design)?;
    p.finish()
}

/// `report.html` of `springfit identify` (and `identify --plan`): the report, the figures, the
/// design.
pub fn write_identify(out: &OutputDir, design: &Design) -> Result<()> {
    let mut p = Page::new(out, format!("springfit identify: {}", design.name));
    p.markdown_file("identify.md")?;
    p.markdown_file("plan.md")?;
    p.remaining_figures("Figures", |_| true)?;
    p.design(design)?;
    p.finish()
}

/// `report.html` of `springfit compare`: the table and the figures.
pub fn write_compare(out: &OutputDir) -> Result<()> {
    let mut p = Page::new(out, "springfit compare".to_string());
    p.markdown_file("compare.md")?;
    p.remaining_figures("Figures", |_| true)?;
    p.finish()
}

/// `report.html` of `springfit pareto`: the curves, the figures, the design.
pub fn write_pareto(out: &OutputDir, design: &Design) -> Result<()> {
    let mut p = Page::new(out, format!("springfit pareto: {}", design.name));
    p.markdown_file("pareto.md")?;
    p.remaining_figures("Figures", |_| true)?;
    p.design(design)?;
    p.finish()
}

/// Whether an image reference names an SVG file inside the output folder: a relative path of
/// plain names (no `..`, no root, no drive), so inlining never reads outside the folder.
fn local_svg(dest: &str) -> bool {
    dest.ends_with(".svg")
        && !dest.contains('\\')
        && std::path::Path::new(dest).components().all(|c| matches!(c, std::path::Component::Normal(_)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("springfit-html-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    const SVG: &str = "<svg width=\"10\" height=\"10\" viewBox=\"0 0 10 10\" xmlns=\"http://www.w3.org/2000/svg\"><rect width=\"10\" height=\"10\"/></svg>\n";

    #[test]
    fn markdown_tables_render_and_figures_are_inlined_once() {
        let root = scratch("inline");
        let w = |name: &str, text: &str| std::fs::write(root.join(name), text).unwrap();
        w("a.svg", &format!("<?xml version=\"1.0\"?>\n{SVG}"));
        w("a.png", "png");
        w("b.svg", SVG);
        std::fs::create_dir_all(root.join("cams")).unwrap();
        w("cams/c.svg", SVG);
        w(".hidden", "not listed");
        w(
            "report.md",
            "# Title <x>\n\n| k | v |\n| --- | ---: |\n| 1 | a & b |\n\n![a](a.svg)\n\n![gone](missing.svg)\n\n![c](cams/c.svg)\n\n![up](../a.svg)\n",
        );
        let mut p = Page::in_folder(&root, &root, "t".into());
        p.markdown_file("report.md").unwrap();
        p.remaining_figures("Figures", |_| true).unwrap();
        p.finish().unwrap();
        let html = std::fs::read_to_string(root.join(FILE)).unwrap();
        assert!(html.contains("<h2>Title &lt;x&gt;</h2>"), "headings demoted and escaped: {html}");
        assert!(html.contains("<table>") && html.contains("<td style=\"text-align: right\">a &amp; b</td>"), "{html}");
        // a.svg and cams/c.svg where the markdown put them (without the XML declaration), b.svg
        // at the end; ../a.svg (outside the folder) is left a reference.
        assert_eq!(html.matches("<svg").count(), 3);
        assert!(html.contains("data-file=\"cams/c.svg\"") && html.contains("src=\"../a.svg\""));
        assert!(!html.contains("<?xml"));
        assert!(html.find("data-file=\"a.svg\"").unwrap() < html.find("<h2>Figures</h2>").unwrap());
        assert!(html.find("data-file=\"b.svg\"").unwrap() > html.find("<h2>Figures</h2>").unwrap());
        assert!(html.contains("<meta name=\"springfit-figures\" content=\"3\">"));
        // A missing image stays a plain reference, not counted as a figure.
        assert!(html.contains("src=\"missing.svg\""));
        assert!(html.contains("href=\"a.png\""));
        // Self-contained: nothing loaded from elsewhere.
        assert!(!html.contains("<script") && !html.contains("<link") && !html.contains("src=\"http"));
        assert!(!html.contains(".hidden"));
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn scenario_tables_read_the_metrics() {
        let json: Value = serde_json::from_str(
            r#"{"scenario":"free","kind":"free","potential":"springs (fit)","label":"table","label_error_deg":1e-5,
                "runs":{"release_1":{"mode_drift_deg":0.5,"actuator_share":0.0,"actuator_share_last5s":0.0,"settling_s":[]},
                        "step":{"actuator_share":0.0076,"actuator_share_last5s":0.001,"settling_s":[1.5,null]}}}"#,
        )
        .unwrap();
        let md = scenario_md(&json);
        assert!(md.contains("| release_1 | – | 0.500° | 0.000 % | 0.000 % | – | – |"), "{md}");
        assert!(md.contains("| step | – | – | 0.760 % | 0.100 % | – | never |"), "{md}");
    }

    /// Issue 42 item 9: a three-joint release whose label drift spikes to 178° near the ε-ball
    /// while it stays within 9 % of r₀ of its geodesic is headed by the deviation, not the drift.
    #[test]
    fn the_geodesic_deviation_leads_the_label_drift() {
        let json: Value = serde_json::from_str(
            r#"{"scenario":"free","kind":"free","potential":"springs (fit)","label":"table",
                "runs":{"release_1":{"geodesic_deviation":{"start_radius":2.0,"max":0.18,"max_rel":0.09,"per_swing":[]},
                "mode_drift_deg":178.0,"mode_drift_wrapped_deg":178.0,"actuator_share":0.0,"actuator_share_last5s":0.0,"settling_s":[]}}}"#,
        )
        .unwrap();
        let md = scenario_md(&json);
        assert!(md.contains("| release_1 | 1.80e-1 (9.0 %) | 178.000°, 178.000° |"), "{md}");
        let header = md.lines().find(|l| l.starts_with("| run |")).unwrap();
        assert!(header.find("geodesic deviation").unwrap() < header.find("label drift").unwrap(), "{header}");
    }
}
