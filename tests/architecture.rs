//! The layers of `src/`, enforced: a module imports only from its own layer or the layers below
//! it, and no two files import from each other, directly or round a circle.
//!
//! The layer table lives in one place, `docs/architecture.md` (between the `layers` markers);
//! this test reads it. Imports are the `crate::…` paths of every file (use lines and inline
//! paths; comments and string literals skipped) and its top-level `use super::…` lines, each
//! mapped to the file that defines it (`src/a/b.rs`, `src/a/b/mod.rs`, `src/a.rs`, …). A
//! reference from inside a folder to that folder's own `mod.rs` is structure, not an import.
//! The binary's files (`src/main.rs`, `src/cli/`) are the top layer; their `springfit::…` paths
//! are imports from the library.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path: `["fit", "run"]` for `src/fit/run.rs`; the binary's files start with `bin`.
type Module = Vec<String>;

/// Imports between files: importer → imported → the names.
type Edges = BTreeMap<Module, BTreeMap<Module, BTreeSet<String>>>;

/// The layers of docs/architecture.md, bottom first: each the top-level modules it holds.
fn layers(doc: &str) -> Vec<(String, Vec<String>)> {
    let start = doc.find("<!-- layers -->").expect("docs/architecture.md has a <!-- layers --> marker");
    let end = doc.find("<!-- /layers -->").expect("docs/architecture.md has a <!-- /layers --> marker");
    let mut out = Vec::new();
    for line in doc[start..end].lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 4 || !cells[1].chars().next().is_some_and(|c| c.is_ascii_digit()) {
            continue;
        }
        let modules: Vec<String> =
            cells[2].split('`').skip(1).step_by(2).map(|m| m.trim_end_matches('/').to_string()).collect();
        out.push((cells[1].to_string(), modules));
    }
    out
}

/// The code without comments, string and character literals.
fn strip(text: &str) -> String {
    let b = text.as_bytes();
    let (mut out, mut i) = (String::with_capacity(b.len()), 0);
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            let mut depth = 0;
            while i < b.len() {
                if b[i..].starts_with(b"/*") {
                    depth += 1;
                    i += 2;
                } else if b[i..].starts_with(b"*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if b[i] == b'r'
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'))
            && raw_string(&b[i..]).is_some()
        {
            i += raw_string(&b[i..]).unwrap_or(1);
            out.push_str("\"\"");
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if b[i] == b'\'' && char_literal(&b[i..]).is_some() {
            i += char_literal(&b[i..]).unwrap_or(1);
            out.push_str("' '");
        } else {
            // Copy one UTF-8 character.
            let len = text[i..].chars().next().map_or(1, char::len_utf8);
            out.push_str(&text[i..i + len]);
            i += len;
        }
    }
    out
}

/// The length of a raw string literal `r#"…"#` at the start of `b`.
fn raw_string(b: &[u8]) -> Option<usize> {
    let hashes = b[1..].iter().take_while(|&&c| c == b'#').count();
    if b.get(1 + hashes) != Some(&b'"') {
        return None;
    }
    let close: Vec<u8> = std::iter::once(b'"').chain(std::iter::repeat_n(b'#', hashes)).collect();
    let body = 2 + hashes;
    let end = b[body..].windows(close.len()).position(|w| w == close.as_slice())?;
    Some(body + end + close.len())
}

/// The length of a character literal (`'a'`, `'\n'`, `'\u{2212}'`) at the start of `b`; None for
/// a lifetime.
fn char_literal(b: &[u8]) -> Option<usize> {
    if b.get(1) == Some(&b'\\') {
        let end = b[2..].iter().position(|&c| c == b'\'')?;
        return (end < 10).then_some(end + 3);
    }
    let s =
        std::str::from_utf8(&b[1..b.len().min(6)]).ok().or_else(|| std::str::from_utf8(&b[1..b.len().min(5)]).ok())?;
    let c = s.chars().next()?;
    (b.get(1 + c.len_utf8()) == Some(&b'\'')).then_some(2 + c.len_utf8())
}

/// `{a::{b, c}, d}` → [[a, b], [a, c], [d]].
fn expand_use(prefix: &[String], body: &str, out: &mut Vec<Vec<String>>) {
    let body = body.trim();
    let (mut depth, mut start, mut items) = (0, 0, Vec::new());
    for (i, c) in body.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&body[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&body[start..]);
    for item in items {
        let item = item.trim();
        if item.is_empty() {
            continue;
        }
        if let Some((head, rest)) = item.split_once('{') {
            let mut p = prefix.to_vec();
            p.extend(head.split("::").filter(|s| !s.is_empty()).map(String::from));
            expand_use(&p, rest.rsplit_once('}').map_or(rest, |r| r.0), out);
        } else {
            let name = item.split(" as ").next().unwrap_or(item).trim();
            let mut p = prefix.to_vec();
            p.extend(name.split("::").filter(|s| !s.is_empty() && *s != "self").map(String::from));
            out.push(p);
        }
    }
}

/// Every `.rs` file under `src` with its module path.
fn files(src: &Path) -> BTreeMap<Module, PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut paths = Vec::new();
    walk(src, &mut paths);
    let mut out = BTreeMap::new();
    for p in paths {
        let rel = p.strip_prefix(src).unwrap().with_extension("");
        let mut parts: Vec<String> = rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
        let bin = parts[0] == "main" || parts[0] == "cli";
        if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
            parts.pop();
        }
        if bin {
            parts.insert(0, "bin".into());
        }
        out.insert(parts, p);
    }
    out
}

/// The longest prefix of `segments` that names a file's module.
fn resolve(segments: &[String], files: &BTreeMap<Module, PathBuf>) -> Option<Module> {
    (1..=segments.len()).rev().map(|n| segments[..n].to_vec()).find(|m| files.contains_key(m))
}

/// The imports between the files under `src`.
fn imports(src: &Path) -> (BTreeMap<Module, PathBuf>, Edges) {
    let files = files(src);
    let mut edges: Edges = BTreeMap::new();
    for (module, path) in &files {
        let text = strip(&std::fs::read_to_string(path).unwrap());
        let bin = module.first().is_some_and(|m| m == "bin");
        // (crate-relative segments) of every reference.
        let mut refs: Vec<Vec<String>> = Vec::new();
        let crate_root: Vec<String> = if bin { vec!["bin".into()] } else { Vec::new() };
        let roots: Vec<(&str, Vec<String>)> = if bin {
            vec![("crate::", crate_root.clone()), ("springfit::", Vec::new())]
        } else {
            vec![("crate::", Vec::new())]
        };
        for (root, base) in &roots {
            let mut at = 0;
            while let Some(i) = text[at..].find(root) {
                let i = at + i;
                at = i + root.len();
                if i > 0 && text[..i].chars().next_back().is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                    continue;
                }
                let rest = &text[at..];
                let is_use = text[..i].trim_end().ends_with("use");
                if is_use && rest.starts_with('{') {
                    let end = rest.find(';').unwrap_or(rest.len());
                    expand_use(base, rest[1..end].trim_end().trim_end_matches('}'), &mut refs);
                    continue;
                }
                let path: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':').collect();
                let mut segs: Vec<String> = base.clone();
                segs.extend(path.split("::").filter(|s| !s.is_empty()).map(String::from));
                if is_use && rest[path.len()..].starts_with('{') {
                    let end = rest.find(';').unwrap_or(rest.len());
                    let inner = &rest[path.len() + 1..end];
                    expand_use(&segs, inner.trim_end().trim_end_matches('}'), &mut refs);
                } else {
                    refs.push(segs);
                }
            }
        }
        // Top-level `use super::…` of a file: relative to its parent module.
        for line in text.lines() {
            let line = line.strip_prefix("pub ").unwrap_or(line);
            let Some(rest) = line.strip_prefix("use super::") else { continue };
            // `src/a/b.rs` (module a::b) and `src/a/b/mod.rs` (module a::b) both have a as parent.
            let mut parent = module.clone();
            parent.pop();
            let rest = rest.trim_end_matches(';');
            if let Some((head, body)) = rest.split_once('{') {
                let mut p = parent.clone();
                p.extend(head.split("::").filter(|s| !s.is_empty()).map(String::from));
                expand_use(&p, body.trim_end_matches('}'), &mut refs);
            } else {
                expand_use(&parent, rest, &mut refs);
            }
        }
        for segs in refs {
            let Some(target) = resolve(&segs, &files) else { continue };
            if &target == module || target.is_empty() || module.starts_with(&target) {
                continue;
            }
            let name = segs.get(target.len()).or(segs.last()).cloned().unwrap_or_default();
            edges.entry(module.clone()).or_default().entry(target).or_default().insert(name);
        }
    }
    (files, edges)
}

/// Strongly connected components with more than one file (Tarjan).
fn circles(nodes: &[Module], edges: &Edges) -> Vec<Vec<Module>> {
    struct State<'a> {
        edges: &'a Edges,
        index: BTreeMap<Module, usize>,
        low: BTreeMap<Module, usize>,
        stack: Vec<Module>,
        on: BTreeSet<Module>,
        out: Vec<Vec<Module>>,
    }
    fn visit(s: &mut State<'_>, v: &Module) {
        let i = s.index.len();
        s.index.insert(v.clone(), i);
        s.low.insert(v.clone(), i);
        s.stack.push(v.clone());
        s.on.insert(v.clone());
        let next: Vec<Module> = s.edges.get(v).map(|m| m.keys().cloned().collect()).unwrap_or_default();
        for w in next {
            if !s.index.contains_key(&w) {
                visit(s, &w);
                let lw = s.low[&w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if s.on.contains(&w) {
                let iw = s.index[&w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on.remove(&w);
                let done = &w == v;
                comp.push(w);
                if done {
                    break;
                }
            }
            if comp.len() > 1 {
                s.out.push(comp);
            }
        }
    }
    let mut s = State {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in nodes {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.out
}

/// Every breach of the layers and every import circle under `src`, one line each.
fn breaches(src: &Path, table: &[(String, Vec<String>)]) -> Vec<String> {
    let (files, edges) = imports(src);
    let name = |m: &Module| files[m].strip_prefix(src.parent().unwrap()).unwrap().display().to_string();
    let layer_of = |m: &Module| -> Option<usize> {
        let top = if m.first().is_some_and(|s| s == "bin") { "cli" } else { m.first().map_or("", String::as_str) };
        table.iter().position(|(_, mods)| mods.iter().any(|x| x == top))
    };
    let mut out = Vec::new();
    for m in files.keys() {
        if !m.is_empty() && m != &vec!["bin".to_string()] && layer_of(m).is_none() {
            out.push(format!("{}: module `{}` is in no layer of docs/architecture.md", name(m), m[0]));
        }
    }
    for (a, targets) in &edges {
        for (b, names) in targets {
            let (Some(la), Some(lb)) = (layer_of(a), layer_of(b)) else { continue };
            if lb > la {
                out.push(format!(
                    "{} (layer {}) imports {} from {} (layer {}), a higher layer",
                    name(a),
                    table[la].0,
                    names.iter().cloned().collect::<Vec<_>>().join(", "),
                    name(b),
                    table[lb].0
                ));
            }
        }
    }
    let nodes: Vec<Module> = files.keys().cloned().collect();
    for comp in circles(&nodes, &edges) {
        let set: BTreeSet<&Module> = comp.iter().collect();
        let mut ties = Vec::new();
        for a in &comp {
            for (b, names) in edges.get(a).into_iter().flatten() {
                if set.contains(b) {
                    ties.push(format!(
                        "{} -> {}: {}",
                        name(a),
                        name(b),
                        names.iter().cloned().collect::<Vec<_>>().join(", ")
                    ));
                }
            }
        }
        ties.sort();
        out.push(format!("import circle of {} files: {}", comp.len(), ties.join("; ")));
    }
    out
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn src_keeps_to_its_layers_and_has_no_import_circle() {
    let doc = std::fs::read_to_string(repo().join("docs/architecture.md")).unwrap();
    let table = layers(&doc);
    assert!(table.len() >= 10, "docs/architecture.md lists {} layers: {table:?}", table.len());
    let found = breaches(&repo().join("src"), &table);
    assert!(found.is_empty(), "{} breaches of docs/architecture.md:\n{}", found.len(), found.join("\n"));
}

/// The files of `src/` the per-folder list of docs/architecture.md misses: a file `src/a/b/c.rs`
/// must be named `` `b/c.rs` `` in the bullet that starts with `` `a/` ``; a file directly in
/// `src/` in the bullet that starts with `base`.
fn unnamed_files(src: &Path, doc: &str) -> Vec<String> {
    let section = doc.split("## What each folder does").nth(1).unwrap_or_default();
    let section = section.split("\n## ").next().unwrap_or_default();
    // Bullets, joined across their wrapped lines, keyed by their first word.
    let mut bullets: BTreeMap<String, String> = BTreeMap::new();
    let mut current = None;
    for line in section.lines() {
        if let Some(rest) = line.strip_prefix("- ") {
            let key = rest.split([' ', ':']).next().unwrap_or_default().trim_matches('`').to_string();
            bullets.insert(key.clone(), rest.to_string());
            current = Some(key);
        } else if line.starts_with("  ")
            && let Some(k) = &current
        {
            bullets.get_mut(k).unwrap().push_str(line);
        } else {
            current = None;
        }
    }
    let mut missing = Vec::new();
    for path in files(src).into_values().chain([src.join("lib.rs"), src.join("main.rs")]) {
        let rel = path.strip_prefix(src).unwrap().to_string_lossy().replace('\\', "/");
        let (folder, name) = match rel.split_once('/') {
            Some((folder, name)) => (format!("{folder}/"), name.to_string()),
            None => ("base".to_string(), rel.clone()),
        };
        let named = bullets.get(&folder).is_some_and(|b| b.contains(&format!("`{name}`")));
        if !named {
            missing.push(format!("src/{rel} (not named `{name}` in the `{folder}` bullet)"));
        }
    }
    missing.sort();
    missing.dedup();
    missing
}

#[test]
fn every_source_file_is_named_in_its_folders_bullet() {
    let doc = std::fs::read_to_string(repo().join("docs/architecture.md")).unwrap();
    let missing = unnamed_files(&repo().join("src"), &doc);
    assert!(missing.is_empty(), "docs/architecture.md does not name {} files:\n{}", missing.len(), missing.join("\n"));
    // The check can fail: a bullet without one of its files is caught.
    let cut = doc.replace("`ode853.rs`", "`ode8.rs`");
    assert_eq!(
        unnamed_files(&repo().join("src"), &cut),
        ["src/numerics/ode853.rs (not named `ode853.rs` in the `numerics/` bullet)"]
    );
}

/// The check itself: a small tree with an upward import and a circle is caught, naming the two
/// files and the imported names; the same tree without them passes.
#[test]
fn an_upward_import_and_a_circle_are_caught() {
    let dir = std::env::temp_dir().join(format!("springfit-architecture-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let src = dir.join("src");
    let write = |p: &str, text: &str| {
        let p = src.join(p);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    };
    let table = vec![
        ("1 low".to_string(), vec!["low".to_string()]),
        ("2 high".to_string(), vec!["high".to_string()]),
        ("3 cli".to_string(), vec!["cli".to_string()]),
    ];
    write("lib.rs", "pub mod high;\npub mod low;\n");
    write("low/mod.rs", "pub mod a;\npub mod b;\n");
    write(
        "low/a.rs",
        "use crate::low::b::Thing; // crate::high::Big in a comment\npub fn f() -> &'static str { \"crate::high::Big\" }\n",
    );
    write("low/b.rs", "pub struct Thing;\n");
    write("high/mod.rs", "pub mod top;\nuse crate::low::{a::f, b::Thing};\npub struct Big;\n");
    write("high/top.rs", "pub struct Top;\n");
    write("main.rs", "mod cli;\n");
    write("cli/mod.rs", "use springfit::high::Big;\n");
    assert_eq!(breaches(&src, &table), Vec::<String>::new());

    // An upward import, deliberately added: named with both files and the name.
    write("low/b.rs", "pub struct Thing;\npub fn g() { let _ = crate::high::top::Top; }\n");
    let found = breaches(&src, &table);
    assert_eq!(
        found,
        vec!["src/low/b.rs (layer 1 low) imports Top from src/high/top.rs (layer 2 high), a higher layer"]
    );

    // A circle inside one layer.
    write("low/b.rs", "use super::a::f;\npub struct Thing;\n");
    let found = breaches(&src, &table);
    assert_eq!(
        found,
        vec!["import circle of 2 files: src/low/a.rs -> src/low/b.rs: Thing; src/low/b.rs -> src/low/a.rs: f"]
    );

    // A new folder outside the table.
    write("low/b.rs", "pub struct Thing;\n");
    write("extra.rs", "");
    assert_eq!(breaches(&src, &table), vec!["src/extra.rs: module `extra` is in no layer of docs/architecture.md"]);
    let _ = std::fs::remove_dir_all(&dir);
}
