"""Shared fixtures: the repository's default design, one fit of it from Python, and the command
line's own outputs for the same inputs (the binary from SPRINGFIT_BIN, which tests/python_package.rs
sets, else target/release/springfit)."""

import os
import pathlib
import subprocess

import pytest

import springfit

REPO = pathlib.Path(__file__).resolve().parents[2]
DEFAULT = REPO / "designs" / "double_pendulum.toml"


def springfit_bin():
    path = os.environ.get("SPRINGFIT_BIN") or str(REPO / "target" / "release" / "springfit")
    if not pathlib.Path(path).exists():
        pytest.fail(f"the springfit binary {path} is missing: build it with `cargo build --release` or set SPRINGFIT_BIN")
    return path


def cli(*args, cwd):
    """Runs `springfit -q ARGS` in `cwd`; returns the completed process."""
    return subprocess.run([springfit_bin(), "-q", *map(str, args)], cwd=cwd, capture_output=True, text=True)


def cli_error(*args, cwd):
    """The message the command line prints after `springfit: error: ` for ARGS."""
    p = cli(*args, cwd=cwd)
    assert p.returncode != 0, p.stdout
    line = [l for l in p.stderr.splitlines() if l.startswith("springfit: error: ")][-1]
    return line[len("springfit: error: "):]


def pytest_configure(config):
    # `slow`: left out of the README's test command (tests/python_package.rs runs `-m "not slow"`)
    # and run by the full matrix (`cargo test --release --locked -- --ignored`).
    config.addinivalue_line("markers", "slow: minutes of work; run by the --ignored matrix, not by the default suite")


@pytest.fixture(scope="session")
def design():
    return springfit.Design.load(DEFAULT)


@pytest.fixture(scope="session")
def fit(design):
    return design.fit()


@pytest.fixture(scope="session")
def cli_fit(tmp_path_factory):
    """`springfit fit` of the default design: its output folder."""
    out = tmp_path_factory.mktemp("cli") / "fit"
    p = cli("fit", DEFAULT, "--out", out, cwd=REPO)
    assert p.returncode == 0, p.stderr
    return out
