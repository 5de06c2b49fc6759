//! Test harness for the `springfit` binary: runs it in a fresh temporary folder and, when an
//! expectation fails, reports the command, its output and the folder's listing.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The repository root (designs and catalogues live there).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A shipped design (`designs/<name>.toml`) and its catalogue, loaded through the library.
pub fn shipped(name: &str) -> (springfit::design::Design, springfit::elements::catalog::Catalog) {
    let design = springfit::design::Design::load(&repo().join(format!("designs/{name}.toml"))).unwrap();
    let catalog = springfit::elements::catalog::Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
    (design, catalog)
}

/// The names of the shipped designs (`designs/<name>.toml`), sorted.
pub fn shipped_names() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(repo().join("designs"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A fresh empty folder under the target directory, unique per test.
pub fn temp_dir(name: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "springfit-test-{}-{}-{}",
        name,
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::SeqCst)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// One run of the binary.
pub struct Run {
    pub args: Vec<String>,
    pub dir: PathBuf,
    pub output: Output,
}

impl Run {
    pub fn stdout(&self) -> String {
        String::from_utf8_lossy(&self.output.stdout).into_owned()
    }

    pub fn stderr(&self) -> String {
        String::from_utf8_lossy(&self.output.stderr).into_owned()
    }

    pub fn code(&self) -> i32 {
        self.output.status.code().unwrap_or(-1)
    }

    /// Everything a failure message needs.
    pub fn report(&self) -> String {
        let listing = walk(&self.dir)
            .into_iter()
            .map(|p| format!("  {}", p.strip_prefix(&self.dir).unwrap_or(&p).display()))
            .collect::<Vec<_>>()
            .join("\n");
        format!(
            "command: springfit {}\nin: {}\nexit: {}\n--- stdout\n{}\n--- stderr\n{}\n--- files\n{}",
            self.args.join(" "),
            self.dir.display(),
            self.code(),
            self.stdout(),
            self.stderr(),
            listing
        )
    }

    /// Asserts success.
    pub fn ok(self) -> Self {
        assert_eq!(self.code(), 0, "expected success\n{}", self.report());
        self
    }

    /// Asserts exit code `code` with exactly one error line containing every `needle`.
    pub fn fails(self, code: i32, needles: &[&str]) -> Self {
        assert_eq!(self.code(), code, "expected exit code {code}\n{}", self.report());
        let err = self.stderr();
        let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("springfit: error:")).collect();
        assert_eq!(lines.len(), 1, "expected one error line\n{}", self.report());
        for n in needles {
            assert!(lines[0].contains(n), "expected `{n}` in the error line\n{}", self.report());
        }
        assert!(!err.contains("panicked"), "panic\n{}", self.report());
        self
    }
}

/// Runs `springfit ARGS` in `dir` (on two worker threads).
pub fn springfit(dir: &Path, args: &[&str]) -> Run {
    springfit_threads(dir, args, 2)
}

/// Runs `springfit ARGS` in `dir` with `RAYON_NUM_THREADS = threads`.
pub fn springfit_threads(dir: &Path, args: &[&str], threads: usize) -> Run {
    let output = Command::new(env!("CARGO_BIN_EXE_springfit"))
        .args(args)
        .current_dir(dir)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .expect("run springfit");
    Run { args: args.iter().map(|s| s.to_string()).collect(), dir: dir.to_path_buf(), output }
}

/// All files under a folder, sorted.
pub fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                out.extend(walk(&p));
            } else {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Writes a file under `dir` and returns its path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    if let Some(parent) = p.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    std::fs::write(&p, text).unwrap();
    p
}

/// A shipped design's text.
pub fn design_text(name: &str) -> String {
    std::fs::read_to_string(repo().join("designs").join(name)).unwrap()
}

/// A shipped design's text with its catalogue path made absolute, so the design can be written
/// into a test's temporary folder and still find its catalogue.
pub fn design_text_anywhere(name: &str) -> String {
    let catalogs = repo().join("catalogs");
    design_text(name).replace("\"../catalogs/", &format!("\"{}/", catalogs.display()))
}

/// The shipped design `name` (`designs/<name>.toml`) written into `dir` as `<name>.toml`, its
/// catalogue and URDF paths made absolute, with the keys `settings` set (added or replaced), each
/// named with its table (`fit.builds`): the same arm, region and catalogue run with other settings
/// (fewer samples, builds or restarts for a quick fit).
pub fn design_variant(dir: &Path, name: &str, settings: &[(&str, toml::Value)]) -> PathBuf {
    let designs = repo().join("designs");
    let mut table: toml::Table = toml::from_str(&design_text(&format!("{name}.toml"))).unwrap();
    let absolute = |v: &mut toml::Value| {
        if let Some(p) = v.as_str() {
            *v = toml::Value::String(designs.join(p).display().to_string());
        }
    };
    if let Some(catalog) = table.get_mut("catalog") {
        absolute(catalog);
    }
    if let Some(urdf) = table.get_mut("robot").and_then(|r| r.get_mut("urdf")) {
        absolute(urdf);
    }
    for (path, value) in settings {
        let (section, key) = path.split_once('.').expect("a key named with its table");
        let section = table.entry(section).or_insert_with(|| toml::Value::Table(toml::Table::new()));
        section.as_table_mut().unwrap().insert(key.to_string(), value.clone());
    }
    write(dir, &format!("{name}.toml"), &toml::to_string(&table).unwrap())
}

/// The shipped design `name` as [`design_variant`] writes it with `builds` Monte Carlo builds
/// behind the as-built figures instead of the design's (1,000 builds are 70 % of the default
/// design's `fit`): for a test about anything but those figures.
pub fn with_builds(dir: &Path, name: &str, builds: i64) -> PathBuf {
    design_variant(dir, name, &[("fit.builds", toml::Value::Integer(builds))])
}

/// A two-link URDF arm whose first joint `j1` states no limits (the second is ±1 rad): the
/// assumption springfit states for it is what `init`'s and the model's tests check.
pub const UNLIMITED_J1_URDF: &str = r#"<robot name="two">
  <link name="base"/>
  <link name="a"><inertial><mass value="1"/><origin xyz="0.5 0 0"/><inertia ixx="0.01" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="b"><inertial><mass value="1"/><origin xyz="0.5 0 0"/><inertia ixx="0.01" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 1 0"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="1 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"#;
