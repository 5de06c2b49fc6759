//! The Python package (`python/`): its pytest suite, run against this build's `springfit`
//! binary (the tests compare the package's results with the command's files).
//!
//! The package must be installed first (`pip install ./python`, which `.ci/run` does). A check
//! that was not made must not count as passed: on a machine without it the test fails with one
//! line saying what to install, unless `SPRINGFIT_SKIP_PYTHON=1` asks to skip it (then it says
//! `SKIPPED` and why); under CI (`CI` set) it never skips, whatever that variable says.

mod util;

use std::process::Command;

use util::repo;

/// The environment variable that lets the test skip where the package cannot be installed
/// (`docs/development.md`).
const SKIP: &str = "SPRINGFIT_SKIP_PYTHON";

/// Why the package's tests cannot run here, or None when they can.
fn missing() -> Option<String> {
    match Command::new("python3").args(["-c", "import springfit, pytest, numpy"]).output() {
        Err(e) => Some(format!(
            "python3 cannot be started ({e}); install Python 3, then `python3 -m pip install ./python pytest`"
        )),
        Ok(o) if !o.status.success() => Some(format!(
            "python3 cannot import springfit, pytest and numpy ({}); install them with `python3 -m pip install ./python pytest`",
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("").trim()
        )),
        Ok(_) => None,
    }
}

/// Runs the package's tests that pytest's `-m` expression `marks` selects.
fn pytest(marks: &str) {
    if let Some(why) = missing() {
        assert!(std::env::var_os("CI").is_none(), "CI must run the Python package's tests: {why}");
        assert!(
            std::env::var_os(SKIP).is_some_and(|v| v == "1"),
            "the Python package's tests cannot run: {why}; or set {SKIP}=1 to skip them (never under CI)"
        );
        eprintln!("SKIPPED ({SKIP}=1): the Python package's tests: {why}");
        return;
    }
    let out = Command::new("python3")
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", marks, "python/tests"])
        .env("SPRINGFIT_BIN", env!("CARGO_BIN_EXE_springfit"))
        .current_dir(repo())
        .output()
        .expect("run pytest");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    println!("{text}");
    assert!(out.status.success(), "pytest failed:\n{text}");
    assert!(text.contains(" passed"), "pytest ran no test:\n{text}");
}

#[test]
fn the_python_package_passes_its_tests() {
    pytest("not slow");
}

/// The tests marked `slow` (an example driving MuJoCo through the 100 s switch scenario): the
/// full matrix, `cargo test --release --locked -- --ignored`.
#[test]
#[ignore = "the Python package's slow tests, with the full matrix"]
fn the_python_packages_slow_tests_pass() {
    pytest("slow");
}
