//! The README's commands and every code block of `docs/` run as written, in a fresh copy of the
//! repository (its tracked files, `out/` empty) with `springfit` on `PATH`.
//!
//! Each fenced block has an info string: `text` is output or a listing and is not run; `sh` runs
//! through `bash -e` (the binary this build made first on `PATH`); `python` runs with `python3`
//! (a page's Python blocks in one session, in order, as a reader types them); `toml` is parsed as
//! a design (it has `[robot]`) or a catalogue (it has `[[family]]`). The line right before a block
//! may be an HTML comment the extractor honours:
//!
//! - `<!-- docs-test: fragment -->`: a TOML excerpt, not a whole file (not parsed);
//! - `<!-- docs-test: slow -->`: run by `cargo test --release --locked -- --ignored` only (full
//!   fits, sweeps, MuJoCo), not by the default suite, which must stay fast;
//! - `<!-- docs-test: skip REASON -->`: never run (it installs software or builds the project,
//!   which the suite itself does), with the reason.
//!
//! A block without an info string or with another one fails here, so a new block is classified
//! when it is written (`docs/development.md`).

mod util;

use std::path::{Path, PathBuf};
use std::process::Command;

use util::repo;

/// How a block is run.
#[derive(Debug, Clone, PartialEq)]
enum Mark {
    Run,
    Fragment,
    Slow,
    Skip(String),
}

/// A fenced code block.
#[derive(Debug, Clone)]
struct Block {
    file: String,
    line: usize,
    info: String,
    mark: Mark,
    text: String,
}

impl Block {
    fn at(&self) -> String {
        format!("{}:{}", self.file, self.line)
    }
}

/// README.md and every `docs/*.md`.
fn pages() -> Vec<String> {
    let mut pages = vec!["README.md".to_string()];
    let mut docs: Vec<String> = std::fs::read_dir(repo().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
}

/// The fenced blocks of `file` (relative to the repository), with their marks.
fn blocks(file: &str) -> Vec<Block> {
    let text = std::fs::read_to_string(repo().join(file)).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let Some(info) = lines[i].strip_prefix("```") else {
            i += 1;
            continue;
        };
        let end = (i + 1..lines.len()).find(|&j| lines[j].starts_with("```")).unwrap_or_else(|| {
            panic!("{file}:{}: a code block that is never closed", i + 1);
        });
        let before = if i > 0 { lines[i - 1].trim() } else { "" };
        let mark = match before.strip_prefix("<!-- docs-test:").and_then(|m| m.strip_suffix("-->")).map(str::trim) {
            None => Mark::Run,
            Some("fragment") => Mark::Fragment,
            Some("slow") => Mark::Slow,
            Some(m) if m.starts_with("skip ") => Mark::Skip(m["skip ".len()..].to_string()),
            Some(m) => panic!("{file}:{i}: `<!-- docs-test: {m} -->` is none of fragment, slow, skip REASON"),
        };
        out.push(Block {
            file: file.to_string(),
            line: i + 1,
            info: info.trim().to_string(),
            mark,
            text: lines[i + 1..end].join("\n") + "\n",
        });
        i = end + 1;
    }
    out
}

fn all_blocks() -> Vec<Block> {
    pages().iter().flat_map(|p| blocks(p)).collect()
}

/// A fresh copy of the repository's tracked files (as they are in the working tree, so the
/// docs being edited are the ones tested) in a new temporary folder.
fn fresh_copy(name: &str) -> PathBuf {
    let dir = util::temp_dir(name);
    let listed = Command::new("git").args(["ls-files", "-z"]).current_dir(repo()).output().expect("git ls-files");
    assert!(listed.status.success(), "git ls-files: {}", String::from_utf8_lossy(&listed.stderr));
    for path in listed.stdout.split(|b| *b == 0).filter(|p| !p.is_empty()) {
        let path = String::from_utf8_lossy(path).into_owned();
        let from = repo().join(&path);
        if !from.is_file() {
            continue; // deleted in the working tree
        }
        let to = dir.join(&path);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(&from, &to).unwrap();
    }
    dir
}

/// `PATH` with this build's `springfit` first.
fn path_with_springfit() -> std::ffi::OsString {
    let bin = Path::new(env!("CARGO_BIN_EXE_springfit")).parent().unwrap().to_path_buf();
    let mut paths = vec![bin];
    paths.extend(std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()));
    std::env::join_paths(paths).unwrap()
}

/// Runs `program args` in `dir` with `springfit` on `PATH`, on two worker threads.
fn run_in(dir: &Path, program: &str, args: &[&str]) -> std::process::Output {
    Command::new(program)
        .args(args)
        .current_dir(dir)
        .env("PATH", path_with_springfit())
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .unwrap_or_else(|e| panic!("run {program}: {e}"))
}

fn run_sh(block: &Block, dir: &Path) {
    let out = run_in(dir, "bash", &["-e", "-c", &block.text]);
    assert!(
        out.status.success(),
        "{}: the block failed ({:?})\n{}\n--- stdout\n{}\n--- stderr\n{}",
        block.at(),
        out.status.code(),
        block.text,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs a page's Python blocks as one session (a later block uses what an earlier one defined).
fn run_python(page: &[&Block], dir: &Path) {
    let probe = Command::new("python3").args(["-c", "import springfit, numpy"]).output();
    if !probe.as_ref().is_ok_and(|o| o.status.success()) {
        assert!(std::env::var_os("CI").is_none(), "CI must run the docs' Python blocks: springfit is not importable");
        assert!(
            std::env::var_os("SPRINGFIT_SKIP_PYTHON").is_some_and(|v| v == "1"),
            "the docs' Python blocks cannot run: python3 cannot import springfit and numpy; install them with \
             `python3 -m pip install ./python`, or set SPRINGFIT_SKIP_PYTHON=1 to skip them (never under CI)"
        );
        eprintln!("SKIPPED (SPRINGFIT_SKIP_PYTHON=1): the Python blocks of {}", page[0].file);
        return;
    }
    let code: String = page.iter().map(|b| b.text.as_str()).collect();
    let out = run_in(dir, "python3", &["-c", &code]);
    assert!(
        out.status.success(),
        "{}: the page's Python blocks failed\n{code}\n--- stderr\n{}",
        page[0].at(),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn every_block_is_classified() {
    let mut bad = Vec::new();
    for b in all_blocks() {
        if !["text", "sh", "python", "toml"].contains(&b.info.as_str()) {
            bad.push(format!("{}: info string `{}`: give text, sh, python or toml", b.at(), b.info));
        }
        if b.mark == Mark::Fragment && b.info != "toml" {
            bad.push(format!("{}: only TOML blocks are fragments (a {} block is text or runs)", b.at(), b.info));
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// TOML blocks that are whole files parse as what they are, relative paths from `designs/` or
/// `catalogs/` as if the file were there.
#[test]
fn toml_blocks_are_designs_and_catalogues_that_load() {
    let mut n = 0;
    for b in all_blocks().into_iter().filter(|b| b.info == "toml" && b.mark == Mark::Run) {
        if b.text.contains("[robot]") {
            let path = repo().join("designs/docs_block.toml");
            let design = springfit::design::Design::parse(&path, &b.text).unwrap_or_else(|e| panic!("{}: {e}", b.at()));
            springfit::design::validate::validate(&design).unwrap_or_else(|e| panic!("{}: {e}", b.at()));
        } else if b.text.contains("[[family]]") {
            let path = repo().join("catalogs/docs_block.toml");
            springfit::elements::catalog::Catalog::parse(&path, &b.text, 2)
                .unwrap_or_else(|e| panic!("{}: {e}", b.at()));
        } else {
            panic!(
                "{}: a TOML block that is neither a design nor a catalogue: mark it `<!-- docs-test: fragment -->`",
                b.at()
            );
        }
        n += 1;
    }
    assert!(n >= 2, "expected the docs' whole designs and catalogues, found {n}");
}

/// The quick shell and Python blocks (those not marked slow or skipped).
#[test]
fn quick_blocks_run_as_written() {
    run_blocks(|m| *m == Mark::Run);
}

/// The slow ones: whole fits, sweeps, MuJoCo, the first session in Python.
#[test]
#[ignore = "the docs' slow blocks (full fits, sweeps, MuJoCo), with the full matrix"]
fn slow_blocks_run_as_written() {
    run_blocks(|m| *m == Mark::Slow);
}

fn run_blocks(chosen: impl Fn(&Mark) -> bool) {
    let blocks: Vec<Block> =
        all_blocks().into_iter().filter(|b| (b.info == "sh" || b.info == "python") && chosen(&b.mark)).collect();
    if blocks.is_empty() {
        return;
    }
    let dir = fresh_copy("docs-run");
    for b in blocks.iter().filter(|b| b.info == "sh") {
        run_sh(b, &dir);
    }
    for page in pages() {
        let python: Vec<&Block> = blocks.iter().filter(|b| b.info == "python" && b.file == page).collect();
        if !python.is_empty() {
            run_python(&python, &dir);
        }
    }
}
