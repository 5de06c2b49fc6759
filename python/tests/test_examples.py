"""The scripts in examples/ run as documented (docs/python.md): each is run as a user runs it."""

import importlib.metadata
import subprocess
import sys

import pytest

from conftest import REPO


def run(script, *args, cwd):
    p = subprocess.run([sys.executable, str(REPO / "examples" / script), *map(str, args)], cwd=cwd,
                       capture_output=True, text=True)
    print(p.stdout, p.stderr)
    return p


def test_fit_histogram(tmp_path):
    pytest.importorskip("matplotlib", reason="examples/fit_histogram.py needs matplotlib (.ci/run installs it)")
    p = run("fit_histogram.py", "--out", tmp_path / "fit", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "fit" / "residuals_matplotlib.png").stat().st_size > 10_000
    assert (tmp_path / "fit" / "bom.csv").exists()


@pytest.mark.slow  # 100 s of the switch scenario in MuJoCo driven from Python: 20 s of CPU
def test_mujoco_switch_settles_every_step_as_simulate_does(tmp_path):
    pytest.importorskip("mujoco", reason="examples/mujoco_switch.py needs mujoco >= 3.7 (.ci/run installs it)")
    p = run("mujoco_switch.py", "--out", tmp_path / "mj", cwd=tmp_path)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "PASS: every step settles yes, largest settling-time difference" in p.stdout


def test_urdf_robot_from_example_robot_data(tmp_path):
    try:
        importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip("examples/urdf_robot.py needs `pip install example-robot-data` (131 MB; not installed by .ci/run)")
    p = run("urdf_robot.py", "--out", tmp_path / "ur5", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert "fit: 12 springs" in p.stdout
