//! The documentation stands alone and keeps up with the code: every key a design file or a
//! catalogue accepts is documented in its section of `docs/design-file.md` or
//! `docs/catalogue.md`, and nothing points outside the repository: the links of README.md and
//! every `docs/*.md` resolve, anchors included.
//!
//! The keys are read from the settings types themselves (serialising their defaults, or a
//! minimal parsed example), so a field added to a settings struct without a line in the docs
//! fails here.

use std::path::{Path, PathBuf};

use springfit::design::DesignFile;
use springfit::design::controllers::ControllerSettings;
use springfit::design::fit::FitSettings;
use springfit::design::scenario::ScenarioSpec;
use springfit::design::simulate::SimSettings;
use springfit::design::sweep::SweepSettings;
use springfit::elements::catalog::CatalogFile;
use springfit::geodesic::GeodesicSettings;
use springfit::numerics::ode::OdeSettings;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &str) -> String {
    std::fs::read_to_string(repo().join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The keys of a value that serialises to a JSON object.
fn keys<T: serde::Serialize>(value: &T) -> Vec<String> {
    match serde_json::to_value(value).expect("settings serialise") {
        serde_json::Value::Object(map) => map.keys().cloned().collect(),
        other => panic!("expected an object, got {other}"),
    }
}

/// The text of the level-2 section whose heading contains `heading`, up to the next level-2
/// heading (its `###` subsections included).
fn section<'a>(doc: &'a str, heading: &str) -> &'a str {
    let start = doc
        .match_indices("\n## ")
        .map(|(i, _)| i + 1)
        .find(|&i| doc[i..].lines().next().is_some_and(|l| l.contains(heading)))
        .unwrap_or_else(|| panic!("no `## …{heading}…` section"));
    let end = doc[start + 3..].find("\n## ").map_or(doc.len(), |i| start + 3 + i);
    &doc[start..end]
}

/// Asserts each key has a table row (`| \`key\` |`) in the section.
fn documented(file: &str, doc: &str, heading: &str, keys: &[String]) {
    let text = section(doc, heading);
    let missing: Vec<&String> = keys.iter().filter(|k| !text.contains(&format!("| `{k}` |"))).collect();
    assert!(missing.is_empty(), "{file}, section {heading}: no table row for {missing:?}");
}

#[test]
fn every_design_key_is_documented_in_its_section() {
    let file = "docs/design-file.md";
    let doc = read(file);
    // Top-level keys: a row in "Top level", or a section of their own (`## \`[fit]\``).
    let top_level = section(&doc, "Top level");
    for key in keys(&DesignFile::default()) {
        let heading = doc.lines().any(|l| {
            l.starts_with("## ") && (l.contains(&format!("`[{key}]`")) || l.contains(&format!("`[[{key}]]`")))
        });
        assert!(
            heading || top_level.contains(&format!("| `{key}` |")),
            "{file}: top-level key `{key}` is undocumented"
        );
    }
    documented(file, &doc, "`[robot]`", &keys(&springfit::design::RobotSpec::default()));
    let link = serde_json::json!({ "mass": 1.0, "length": 1.0, "com": 0.5, "inertia": 0.1 });
    let link: springfit::design::LinkSpec = serde_json::from_value(link).expect("a link");
    documented(file, &doc, "`[robot]`", &keys(&link));
    documented(file, &doc, "`[equilibrium]`", &keys(&springfit::design::EquilibriumSpec::default()));
    let region: springfit::design::RegionSpec = toml::from_str("kind = \"ball\"").expect("a minimal region");
    documented(file, &doc, "`[region]`", &keys(&region));
    documented(file, &doc, "`[geodesics]`", &keys(&GeodesicSettings::default()));
    documented(file, &doc, "`[geodesics]`", &keys(&OdeSettings::default()));
    documented(file, &doc, "`[fit]`", &keys(&FitSettings::default()));
    documented(file, &doc, "`[simulate]`", &keys(&SimSettings::default()));
    documented(file, &doc, "`[controllers]`", &keys(&ControllerSettings::default()));
    documented(file, &doc, "`[sweep]`", &keys(&SweepSettings::default()));
    documented(file, &doc, "`[identify]`", &keys(&springfit::design::identify::IdentifySettings::default()));
    documented(file, &doc, "`[parts]`", &keys(&springfit::design::parts::PartsSettings::default()));
    let envelope: springfit::design::parts::ElementEnvelope = toml::from_str("id = \"S01\"").expect("an envelope");
    documented(file, &doc, "`[parts]`", &keys(&envelope));
    let scenario: ScenarioSpec = toml::from_str("name = \"s\"\nkind = \"free\"").expect("a minimal scenario");
    documented(file, &doc, "`[[scenario]]`", &keys(&scenario));
}

#[test]
fn every_catalogue_key_is_documented_in_its_section() {
    let file = "docs/catalogue.md";
    let doc = read(file);
    documented(file, &doc, "Top level", &keys(&CatalogFile::default()));
    let catalog: CatalogFile = toml::from_str(
        "[[family]]\nname = \"f\"\nprofile = \"linear\"\ncouplings = \"joints\"\noffsets = \"equilibrium\"",
    )
    .expect("a minimal catalogue");
    documented(file, &doc, "`[[family]]`", &keys(&catalog.family[0]));
    for written in
        ["\"joints\"", "pairs =", "all_pairs =", "\"equilibrium\"", "grid = N", "equilibrium = true", "phases = N"]
    {
        assert!(doc.contains(written), "{file} does not show `{written}`");
    }
}

/// Every column of `parts.csv` and of a stock list is named (in backquotes) in its table of
/// `docs/outputs.md` and `docs/parts.md`.
#[test]
fn every_parts_column_is_documented() {
    let outputs = read("docs/outputs.md");
    let start = outputs.find("### `parts.csv`").expect("docs/outputs.md has a `parts.csv` section");
    let table = &outputs[start..outputs[start..].find("\n## ").map_or(outputs.len(), |i| start + i)];
    let missing: Vec<&str> =
        springfit::files::parts::HEADER.split(',').filter(|c| !table.contains(&format!("`{c}`"))).collect();
    assert!(missing.is_empty(), "docs/outputs.md, `parts.csv`: undocumented columns {missing:?}");
    let parts = read("docs/parts.md");
    assert!(parts.contains(springfit::files::stock::HEADER), "docs/parts.md does not show the stock list's header");
}

/// README.md and every page under docs/ (read from the directory, so a new page is covered).
fn documentation_files() -> Vec<String> {
    let mut pages: Vec<String> = std::fs::read_dir(repo().join("docs"))
        .expect("docs/ is readable")
        .map(|entry| entry.expect("a docs/ entry").path())
        .filter(|path| path.extension().is_some_and(|e| e == "md"))
        .map(|path| format!("docs/{}", path.file_name().expect("a file name").to_string_lossy()))
        .collect();
    pages.sort();
    assert!(pages.len() >= 7, "docs/ has only {pages:?}");
    std::iter::once("README.md".to_string()).chain(pages).collect()
}

/// The anchors GitHub gives a page's headings: lower case, spaces to hyphens, punctuation other
/// than `-` and `_` dropped (`## What \`fit\` does` is `#what-fit-does`). Headings inside fenced
/// blocks do not count.
fn anchors(text: &str) -> Vec<String> {
    let mut fenced = false;
    let mut out = Vec::new();
    for line in text.lines() {
        if line.starts_with("```") {
            fenced = !fenced;
        }
        let level = line.chars().take_while(|&c| c == '#').count();
        if fenced || level == 0 || level > 6 || !line[level..].starts_with(' ') {
            continue;
        }
        let slug: String = line[level..]
            .trim()
            .to_lowercase()
            .chars()
            .filter(|&c| c.is_alphanumeric() || c == '-' || c == '_' || c == ' ')
            .map(|c| if c == ' ' { '-' } else { c })
            .collect();
        out.push(slug);
    }
    out
}

#[test]
fn documentation_stands_alone() {
    for file in documentation_files() {
        let file = file.as_str();
        let text = read(file);
        assert!(!text.contains("../shared") && !text.contains("DESIGN.md"), "{file} points outside the repository");
        // Relative Markdown links resolve inside the repository, and so do their anchors.
        let base = repo().join(file).parent().map(Path::to_path_buf).unwrap_or_else(repo);
        for (i, _) in text.match_indices("](") {
            let target = &text[i + 2..];
            let Some(end) = target.find(')') else { continue };
            let (link, anchor) = target[..end].split_once('#').unwrap_or((&target[..end], ""));
            if link.contains("://") {
                continue;
            }
            let page = if link.is_empty() { repo().join(file) } else { base.join(link) };
            assert!(page.exists(), "{file}: link `{link}` does not resolve");
            if !anchor.is_empty() && page.extension().is_some_and(|e| e == "md") {
                let headings = anchors(&std::fs::read_to_string(&page).expect("a linked page"));
                assert!(headings.iter().any(|a| a == anchor), "{file}: link `{link}#{anchor}`: no such heading");
            }
        }
    }
}

/// Every limit of `src/limits.rs` is listed in `docs/limits.md`.
#[test]
fn every_limit_is_documented() {
    let code = read("src/limits.rs");
    let doc = read("docs/limits.md");
    // `pub(crate)`: the module is private, the limits the command line checks are re-exported.
    let names: Vec<&str> = code
        .lines()
        .filter_map(|l| l.strip_prefix("pub const ").or_else(|| l.strip_prefix("pub(crate) const ")))
        .filter_map(|l| l.split(':').next())
        .collect();
    assert!(names.len() >= 10, "limits found: {names:?}");
    for name in names {
        assert!(doc.contains(&format!("`{name}`")), "docs/limits.md does not list `{name}`");
    }
}
