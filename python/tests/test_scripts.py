"""The analysis scripts of scripts/ that BENCHMARKS.md and the docs quote: what they compute is
checked on small cases, and what they write loads and fits."""

import re
import subprocess
import sys
import tomllib


import springfit
from conftest import REPO

sys.path.insert(0, str(REPO / "scripts"))
import own_output  # noqa: E402
import radius_limit  # noqa: E402
import ur5_pursuit  # noqa: E402


def test_polynomial_potentials_converge_to_the_exact_one_on_a_small_ball():
    """scripts/radius_limit.py on the five-link pendulum, ball 0.05: the quadratic part alone (the
    equilibrium and the Hessian match) leaves an error that grows linearly from q_eq, as the
    missing cubic terms of ½ω²r² − U_g make it; each two more degrees cut the p99 by more than ten.
    A wrong gravity gradient, or a Hessian other than ω²M(q_eq) times a number (which only changes
    the frequency), leaves an error that does not vanish at q_eq (checked: 0.5 N·m/rad on one
    off-diagonal, or 1 % on the gradient, fails the band ratio)."""
    design = springfit.Design.load(str(REPO / "designs" / "pendulum5.toml"))
    r, per = 0.05, 8
    train = ur5_pursuit.Rows(design, *ur5_pursuit.samples(design, 120, per, seed=1, radius=r), omega=6.0)
    test = ur5_pursuit.Rows(design, *ur5_pursuit.samples(design, 120, per, seed=2, radius=r), omega=6.0)
    p99 = {}
    for degree in (2, 4, 6):
        free, p99[degree], bands = radius_limit.fit_and_judge(design, 6.0, r, degree, train, test)
        if degree == 2:
            assert free == 0
            assert 3.0 < bands[3] / bands[0] < 5.0, bands  # linear in s: quarters 1…4
    assert p99[2] > 5.0, p99
    assert p99[4] < p99[2] / 10 and p99[6] < p99[4] / 10, p99
    assert p99[6] < 0.05, p99


def test_the_cam_catalogue_script_writes_catalogues_that_fit(tmp_path):
    """scripts/cam_catalogue.py: every joint, every q_i ± q_j and every run of three or more, then
    distinct random couplings; a two-joint catalogue fits the double pendulum's ball."""
    out = tmp_path / "cams5.toml"
    subprocess.run([sys.executable, str(REPO / "scripts" / "cam_catalogue.py"), "--joints", "5", "--random", "12",
                    "--seed", "3", "--entries", "2", "--out", str(out)], check=True, capture_output=True)
    family = tomllib.loads(out.read_text())["family"][0]
    couplings = [tuple(c) for c in family["couplings"]]
    assert family["profile"] == "cam" and len(couplings) == 5 + 20 + 6 + 12
    assert len(set(couplings)) == len(couplings)
    for c in couplings[31:]:
        assert sum(x != 0 for x in c) >= 2 and next(x for x in c if x) > 0 and max(map(abs, c)) <= 2
    two = tmp_path / "cams2.toml"
    subprocess.run([sys.executable, str(REPO / "scripts" / "cam_catalogue.py"), "--joints", "2", "--out", str(two)],
                   check=True, capture_output=True)
    text = (REPO / "designs" / "double_pendulum_cams4.toml").read_text()
    text = re.sub(r"(?m)^catalog = .*$", f'catalog = "{two.as_posix()}"', text)
    summary = springfit.Design.from_toml(text, path=str(REPO / "designs" / "cams2.toml")).fit().summary
    assert summary["used"] == 4 and summary["residual_deg"]["p99_abs"] < 2.0, summary["residual_deg"]
    # Its own output it rewrites; a file of the user's it leaves alone.
    again = subprocess.run([sys.executable, str(REPO / "scripts" / "cam_catalogue.py"), "--joints", "3", "--out",
                            str(two)], capture_output=True, text=True)
    assert again.returncode == 0 and "--joints 3" in two.read_text()
    mine = tmp_path / "mine.toml"
    mine.write_text("# my catalogue\n")
    refused = subprocess.run([sys.executable, str(REPO / "scripts" / "cam_catalogue.py"), "--joints", "2", "--out",
                              str(mine)], capture_output=True, text=True)
    assert refused.returncode == 2 and "not written by this script" in refused.stderr
    assert mine.read_text() == "# my catalogue\n"


def test_the_scripts_rewrite_their_own_catalogues_and_no_others(tmp_path):
    """The catalogues ur5_pursuit.py and ur5_couplings.py regenerate are theirs to rewrite; a file
    of the user's under their --out is refused before any work (exit 2, the file unchanged)."""
    assert not own_output.foreign(str(REPO / "catalogs" / "ur5_cams_pursuit.toml"), ur5_pursuit.MARKER)
    assert not own_output.foreign(str(REPO / "catalogs" / "ur5_cams.toml"), "# Written by scripts/ur5_couplings.py")
    assert own_output.foreign(str(REPO / "catalogs" / "ur5_cams.toml"), ur5_pursuit.MARKER)
    assert not own_output.foreign(str(tmp_path / "absent.toml"), ur5_pursuit.MARKER)
    mine = tmp_path / "mine.toml"
    mine.write_text("# my catalogue\n")
    for script, flag in (("ur5_pursuit.py", "--out"), ("ur5_couplings.py", "--write-catalogue")):
        args = [sys.executable, str(REPO / "scripts" / script), flag, str(mine), "--out", str(tmp_path / "o")]
        refused = subprocess.run(args if script == "ur5_couplings.py" else args[:4], capture_output=True, text=True)
        assert refused.returncode == 2 and "not written by this script" in refused.stderr, (script, refused.stderr)
    assert mine.read_text() == "# my catalogue\n" and not (tmp_path / "o").exists()


def test_radius_limit_sets_fit_keys_in_the_fit_table_only():
    """radius_limit.py's catalogue fit sets [fit] builds and max_elements whether the design sets
    them or not, and leaves [sweep] builds alone; the result parses."""
    text = (REPO / "designs" / "double_pendulum_paper_window_built.toml").read_text()
    assert len(re.findall(r"(?m)^builds = ", text)) >= 1
    edited = radius_limit.fit_key(radius_limit.fit_key(text, "max_elements", "0"), "builds", "0")
    fit = tomllib.loads(edited)["fit"]
    assert fit["builds"] == 0 and fit["max_elements"] == 0
    plain = (REPO / "designs" / "double_pendulum.toml").read_text()
    parsed = tomllib.loads(radius_limit.fit_key(plain, "builds", "0"))
    assert parsed["fit"]["builds"] == 0 and parsed["sweep"]["builds"] == tomllib.loads(plain)["sweep"]["builds"]
    assert tomllib.loads(radius_limit.fit_key("name = 'x'\n", "builds", "0"))["fit"]["builds"] == 0
