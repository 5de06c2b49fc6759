"""Bad input raises springfit.Error subclasses with the command line's message, never a crash."""

import math
from pathlib import Path

import numpy as np
import pytest

import springfit
from conftest import DEFAULT, REPO, cli_error


def test_a_missing_file_is_the_commands_message(tmp_path):
    with pytest.raises(springfit.FileError) as e:
        springfit.Design.load("no/such/design.toml")
    assert str(e.value) == cli_error("check", "no/such/design.toml", cwd=REPO)
    assert e.value.file == "no/such/design.toml" and isinstance(e.value, springfit.BadInputError)


def test_an_invalid_value_names_the_file_and_field(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(DEFAULT.read_text().replace("mass = 1.0", "mass = -1.0", 1).replace(
        '"../catalogs/', f'"{REPO}/catalogs/'))
    with pytest.raises(springfit.InvalidError) as e:
        springfit.Design.load(bad)
    assert str(e.value) == cli_error("check", bad, cwd=tmp_path)
    assert e.value.field == "robot.links[0].mass" and e.value.file == str(bad)


def test_an_unknown_key_in_a_file_and_in_the_overrides(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(DEFAULT.read_text().replace("[fit]", "[fit]\nmax_element = 3", 1).replace(
        '"../catalogs/', f'"{REPO}/catalogs/'))
    with pytest.raises(springfit.ParseError) as e:
        springfit.Design.load(bad)
    assert str(e.value) == cli_error("check", bad, cwd=tmp_path)
    with pytest.raises(springfit.SettingError) as e:
        springfit.Design.load(DEFAULT, max_element=3)
    # The reason is the one the file gets for the same key.
    assert "unknown field `max_element`" in str(e.value) and e.value.field == "max_element"
    with pytest.raises(springfit.InvalidError) as e:
        springfit.Design.load(DEFAULT, radius=-1.0)
    assert e.value.field == "region.radius"


def test_arrays_of_the_wrong_shape_or_with_nan(design):
    with pytest.raises(springfit.SettingError) as e:
        design.log(np.zeros((4, 3)))
    assert str(e.value) == "setting `q`: must have shape (2,) or (N, 2) for the robot's 2 joints, got (4, 3)"
    with pytest.raises(springfit.SettingError) as e:
        design.mass_matrix([[0.1, 0.2], [math.nan, 0.0]])
    assert str(e.value) == "setting `q[1, 0]`: must be finite, got NaN"
    with pytest.raises(springfit.SettingError):
        design.exp("not numbers")
    with pytest.raises(springfit.SettingError):
        design.acceleration(np.zeros((3, 2)), np.zeros((2, 2)), np.zeros((3, 2)))


def test_controller_inputs_are_checked(design, fit):
    c = springfit.Controller(design, fit)
    with pytest.raises(springfit.SettingError) as e:
        c.torque([0.1, 0.2, 0.3], [0.0, 0.0], 0.0)
    assert e.value.field == "q"
    with pytest.raises(springfit.SettingError):
        c.torque([0.1, math.inf], [0.0, 0.0], 0.0)
    with pytest.raises(springfit.SettingError):
        springfit.Controller(design, fit, scenario="nope")
    with pytest.raises(springfit.SettingError):
        springfit.Controller(design, object())
    with pytest.raises(springfit.SettingError):
        c.theta_d = math.nan


def test_an_infeasible_fit_is_the_commands_message(tmp_path):
    # Springs on single joints only: their Hessian at q_eq is diagonal, but ω² M(q_eq) is not.
    (tmp_path / "catalogs").mkdir()
    (tmp_path / "designs").mkdir()
    (tmp_path / "catalogs" / "joints.toml").write_text(
        'name = "joint springs only"\n[[family]]\nname = "torsion"\nprofile = "linear"\n'
        'couplings = "joints"\noffsets = "equilibrium"\n')
    path = tmp_path / "designs" / "infeasible.toml"
    # No trims in that catalogue, so no trimmed builds to weigh.
    path.write_text(DEFAULT.read_text().replace("../catalogs/paper_trim.toml", "../catalogs/joints.toml")
                    .replace("trimmed_weight = 0.22", "trimmed_weight = 0.0"))
    with pytest.raises(springfit.InfeasibleError) as e:
        springfit.Design.load(path).fit()
    assert str(e.value) == cli_error("fit", path, "--out", tmp_path / "out", cwd=tmp_path)
    assert isinstance(e.value, springfit.NotMetError) and e.value.file == str(path)


def test_every_error_is_a_springfit_error():
    for cls in [springfit.FileError, springfit.ParseError, springfit.InvalidError, springfit.SettingError,
                springfit.PlotError, springfit.InfeasibleError, springfit.NumericalError, springfit.NoPartError]:
        assert issubclass(cls, springfit.Error)


def test_a_bill_that_does_not_hold_the_equilibrium_is_refused_as_by_the_commands(tmp_path):
    # Crank S01's offset typed in degrees (30 for π/6 rad): its springs no longer hold q_eq.
    bom = (REPO / "tests" / "data" / "double_pendulum_bom.csv").read_text()
    bad = tmp_path / "degrees.csv"
    bad.write_text(bom.replace(",0.5235987755982988,", ",30,", 1))
    design = springfit.Design.load(DEFAULT)
    with pytest.raises(springfit.InvalidError) as e:
        springfit.Potential.from_bom(design, bad)
    assert e.value.field == "offset_rad" and "equilibrium.bill_tolerance" in str(e.value)
    assert str(e.value) == cli_error("export", DEFAULT, "--bom", bad, "--mujoco", "--out", tmp_path / "o", cwd=tmp_path)


def test_a_refused_folder_names_the_python_argument_not_the_flag(fit, tmp_path):
    # Issue 42 item 11: an edited file in the folder is refused in a Python caller's words.
    folder = Path(fit.write(tmp_path / "out"))
    (folder / "report.md").write_text("edited by hand\n")
    with pytest.raises(springfit.FileError) as e:
        fit.write(folder)
    message = str(e.value)
    assert "overwrite_edits=True" in message and "--overwrite-edits" not in message, message
    assert "--out" not in message, message
    fit.write(folder, overwrite_edits=True)
    assert (folder / "report.md").read_text() != "edited by hand\n"


def test_a_wrong_type_names_its_argument_in_a_note():
    # Issue 42 item 11: a wrong Python type is Python's TypeError; the argument's name comes as a
    # PEP 678 note, which tracebacks print under the message.
    with pytest.raises(TypeError) as e:
        springfit.Design.load(3)
    assert "while processing 'path'" in getattr(e.value, "__notes__", []), e.value
    with pytest.raises(TypeError) as e:
        springfit.Design.from_toml(3)
    assert "while processing 'text'" in getattr(e.value, "__notes__", []), e.value
