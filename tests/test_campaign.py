"""`tdem campaign` end to end with YADE on a tiny bed (200 spheres, two pressures, laws pipe and
bob), and its resumption after an interruption.

Asserted: one results.csv row per pressure x law with finite, positive gamma inside its interval
and close to the steady ETC (25 %: the profile fit and the steady heat flow measure the same
conductivity in two ways, but this 200-sphere bed is only 4.5 radii wide and ~6 of its ~12
top-layer spheres touch the plate; measured 6-10 %, against 3-8 % on the 7,500 bed); gamma
grows with pressure (contact radii grow as F^(1/3)); pipe > bob
(003 eq. 40 vs 34: 1.033 for equal spheres); the report names both laws; a second run reuses the
packings and every case; a campaign killed after its second case resumes with the two finished
cases kept and ends with the same table; --repost post-processes the kept runs to the same table.
"""
import shutil
import subprocess
import sys

import pandas as pd
import pytest

from bed_scene import BED_THERMAL
from tdem.yade import yade_environment

pytestmark = [pytest.mark.yade,
              pytest.mark.skipif(shutil.which("yade", path=yade_environment()["PATH"]) is None,
                                 reason="Debian's yade is not installed")]

CAMPAIGN = '''[campaign]
laws = ["pipe", "bob"]
n_bins = 5

[pack]
generator = "bed"
n_particles = 200
cylinder_radius_m = 0.009
pressures_pa = [2.8e4, 1.6e6]
seed = 7

''' + BED_THERMAL + '''

[solver]
method = "implicit"
theta = 0.5
dt = 0.5
end_time = 1000.0
output_times = [2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 1000.0]
'''


def campaign(path, out, *extra):
    return subprocess.run([sys.executable, "-m", "tdem.cli", "campaign", str(path), "--out",
                           str(out), "--quiet", *extra], capture_output=True, text=True,
                          timeout=1200)


def test_campaign_runs_and_resumes(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(CAMPAIGN)
    out = tmp_path / "out"
    first = campaign(path, out)
    assert first.returncode == 0, first.stdout[-3000:] + first.stderr[-3000:]
    table = pd.read_csv(out / "results.csv")
    assert len(table) == 4
    assert set(table.law) == {"pipe", "bob"}
    assert (table.gamma > 0).all()
    assert ((table.gamma_ci95_low < table.gamma) & (table.gamma < table.gamma_ci95_high)).all()
    assert ((table.gamma / table.gamma_steady - 1).abs() < 0.25).all()
    for law, g in table.groupby("law"):
        g = g.sort_values("pressure_pa")
        assert g.gamma.iloc[1] > g.gamma.iloc[0], law
    by = table.set_index(["law", "pressure_pa"]).gamma
    for p in table.pressure_pa.unique():
        assert by[("pipe", p)] > by[("bob", p)]
    report = (out / "report.md").read_text()
    assert "pipe" in report and "bob" in report and "paper" in report
    assert (out / "gamma_p.png").exists() and (out / "tau_p.png").exists()

    again = campaign(path, out)
    assert again.returncode == 0
    assert "reusing the 2 packings" in again.stdout
    assert again.stdout.count("done before") == 4

    # a real interruption: a second campaign in another folder is killed as soon as its second
    # case is reported; the next run keeps both finished cases, computes the other two, and gives
    # the same table (the packings are bit-identical for the seed: YADE runs single-threaded)
    out2 = tmp_path / "out2"
    proc = subprocess.Popen([sys.executable, "-m", "tdem.cli", "campaign", str(path), "--out",
                             str(out2), "--quiet"], stdout=subprocess.PIPE, text=True)
    for line in proc.stdout:
        if line.startswith("[2/4]"):
            proc.kill()
            break
    proc.wait(timeout=60)
    assert proc.returncode != 0 and not (out2 / "results.csv").exists()
    third = campaign(path, out2)
    assert third.returncode == 0
    assert "reusing the 2 packings" in third.stdout
    assert third.stdout.count("done before") == 2
    assert not list(out2.rglob("*.tmp"))
    resumed = pd.read_csv(out2 / "results.csv")
    pd.testing.assert_series_equal(resumed.gamma, table.gamma, rtol=1e-12)

    # --repost keeps the thermal runs and post-processes them again: same numbers
    fourth = campaign(path, out, "--repost")
    assert fourth.returncode == 0
    assert fourth.stdout.count("post-processed again") == 4
    pd.testing.assert_frame_equal(pd.read_csv(out / "results.csv"), table, rtol=1e-12)


def test_bad_campaign_is_one_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(CAMPAIGN.replace('laws = ["pipe", "bob"]', 'laws = ["pipe", "bobby"]'))
    proc = campaign(path, tmp_path / "out")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "campaign.laws" in proc.stderr
    assert "Traceback" not in proc.stderr
