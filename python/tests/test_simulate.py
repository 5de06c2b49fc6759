"""Design.simulate() and export_mujoco() write the command's files."""

import json

import numpy as np

import springfit
from conftest import DEFAULT, cli


def test_simulate_free_writes_the_commands_files(design, fit, cli_fit, tmp_path):
    sim = design.simulate(scenario="free", springs=cli_fit / "bom.csv")
    folder = sim.write(tmp_path / "py")
    out = tmp_path / "cli"
    p = cli("simulate", DEFAULT, "--bom", cli_fit / "bom.csv", "--scenario", "free", "--out", out, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert (folder / "sim_free.csv").read_bytes() == (out / "sim_free.csv").read_bytes()
    want = json.loads((out / "sim_free.json").read_text())
    got = json.loads((folder / "sim_free.json").read_text())
    # The potential is named after the bill's path as given, which differs between the two runs.
    want.pop("potential"), got.pop("potential")
    assert got == want
    runs = sim.runs("free")
    assert len(runs) == 6 and runs[0]["q"].shape[1] == 2 and set(runs[0]["tau"]) >= {"spring", "mode"}
    assert runs[0]["metrics"] == want["runs"][runs[0]["name"]]
    assert sim.summary("free")["runs"] == want["runs"]


def test_export_mujoco_writes_the_commands_model(design, fit, cli_fit, tmp_path):
    xml = design.export_mujoco(tmp_path / "py", springs=cli_fit / "bom.csv")
    out = tmp_path / "cli"
    p = cli("export", DEFAULT, "--bom", cli_fit / "bom.csv", "--mujoco", "--out", out, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert xml.read_bytes() == (out / "double_pendulum.xml").read_bytes()
    assert (xml.parent / "bom.csv").read_bytes() == (out / "bom.csv").read_bytes()


def test_the_settling_rule_is_the_simulators(design, fit):
    sim = design.simulate(scenario="switch", springs=fit)
    run = sim.runs("switch")[0]
    c = springfit.Controller(design, fit, scenario="switch")
    got = springfit.settling_times(run["t"], run["label"], run["label_target"], run["in_ball"], c.mode_steps, 100.0)
    assert got == run["metrics"]["settling_s"]
    assert np.isfinite(run["energy"]).all()
    # The savings beside the actuator share, and the gains the design sets (none from the arm).
    savings = sim.savings("switch")["switch"]
    assert savings["actuator_share"] == run["metrics"]["actuator_share"]
    assert {k: v for k, v in savings.items() if k != "actuator_share"} == run["metrics"]["savings"]
    assert 0.9 < savings["energy_saved"] < 1.0
    assert sim.gains["from_arm"] == [] and sim.gains["k_theta"] == 1.0
    assert sim.gains == sim.summary("switch")["gains"]


def test_sweep_writes_the_commands_tables(design, tmp_path):
    sweep = design.sweep(builds=4, seed=3)
    folder = sweep.write(tmp_path / "py")
    out = tmp_path / "cli"
    p = cli("sweep", DEFAULT, "--builds", 4, "--seed", 3, "--out", out, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    for name in ["sweep.csv", "sweep.json", "tolerance.md"]:
        assert (folder / name).read_bytes() == (out / name).read_bytes(), name
    assert sweep.tables == json.loads((out / "sweep.json").read_text())
    assert len(sweep.items) == len((out / "sweep.csv").read_text().splitlines()) - 1


def test_compare_writes_the_commands_table(design, fit, cli_fit, tmp_path):
    c = springfit.compare([fit, cli_fit], exact=design)
    folder = c.write(tmp_path / "py")
    out = tmp_path / "cli"
    p = cli("compare", cli_fit, cli_fit, "--exact", "--out", out, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert len(c.table) == 3 and c.table[-1]["design"] == "exact ½ω²r²"
    assert (folder / "compare.md").exists() and (folder / "compare.svg").exists()
    # The same fits give the same rows (the labels name their sources, which differ).
    want = (out / "compare.csv").read_text().splitlines()
    got = c.csv.splitlines()
    assert want[0] == got[0] and len(want) == len(got)
