"""The analysis scripts of scripts/ that BENCHMARKS.md and the docs quote: what they compute is
checked on small cases, and what they write loads and fits."""

import re
import subprocess
import sys
import tomllib


import springfit
from conftest import REPO

sys.path.insert(0, str(REPO / "scripts"))
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
