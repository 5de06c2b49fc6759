"""Design.fit(): the bill of materials, the residuals and the summary equal the command's files."""

import json

import numpy as np

import springfit
from conftest import DEFAULT


def test_write_gives_the_commands_bom_csv_byte_for_byte(fit, cli_fit, tmp_path):
    folder = fit.write(tmp_path / "py")
    assert (tmp_path / "py" / "bom.csv").read_bytes() == (cli_fit / "bom.csv").read_bytes()
    assert fit.bom_csv.encode() == (cli_fit / "bom.csv").read_bytes()
    # The same files, and the same bytes for every file without timings or absolute paths.
    names = sorted(p.relative_to(cli_fit).as_posix() for p in cli_fit.rglob("*") if p.is_file())
    assert sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()) == names
    for name in ["bom.md", "residuals.csv", "histogram.svg", "potential.svg"]:
        assert (folder / name).read_bytes() == (cli_fit / name).read_bytes(), name


def test_summary_residuals_and_records_match_the_files(fit, cli_fit):
    want = json.loads((cli_fit / "summary.json").read_text())
    got = fit.summary
    assert list(got) == list(want)
    for key in want:
        if key not in ("timings_s",):
            assert got[key] == want[key], key
    lines = (cli_fit / "residuals.csv").read_text().splitlines()
    angles = np.array([float(l.split(",")[-1]) for l in lines[1:]])
    assert fit.residuals.shape == angles.shape
    assert np.array_equal(fit.residuals, angles)
    samples = fit.residual_samples
    assert samples["q"].shape == (len(angles), 2) and samples["direction"].dtype.kind == "i"
    rows = (cli_fit / "bom.csv").read_text().splitlines()
    assert len(fit.bom) == len(rows) - 1
    assert list(fit.bom[0]) == rows[0].split(",")
    arr = fit.bom_array
    assert arr.shape == (len(rows) - 1,)
    assert arr.dtype["stiffness"] == np.float64
    assert np.allclose(arr["stiffness"], [r["stiffness"] for r in fit.bom])
    assert fit.as_built is not None and fit.as_built == got["as_built"]


def test_overrides_replace_fit_and_region_keys(tmp_path):
    d = springfit.Design.load(DEFAULT, max_elements=6, radius=1.5)
    f = d.fit()
    # The three trim springs, set after assembly, come on top of the budget.
    assert f.summary["max_elements"] == 6 and f.used <= 6 + 3
    assert f.summary["region"]["extent"] == 1.5
    text = DEFAULT.read_text()
    same = springfit.Design.from_toml(text, path=DEFAULT, max_elements=6, radius=1.5)
    assert same.fit().bom_csv == f.bom_csv


def test_progress_callback_sees_the_stages(design):
    stages = []
    design.fit(max_elements=8, progress=stages.append)
    assert stages and "as-built Monte Carlo builds" in stages


def test_exact_reference_has_no_bill(design, tmp_path):
    f = design.fit(exact=True)
    assert f.summary["solver"] == "exact"
    folder = f.write(tmp_path / "exact")
    assert not (folder / "bom.csv").exists() and (folder / "summary.json").exists()
